//! A learned policy trained with N_train agents and tested with N_test (RQ4, RQ5), as the
//! N_train x N_test matrix of mean penalty, MA-G-PPO and MA-PPO side by side.

use polars::prelude::*;
use store::schema::summary;

use super::chart::heatmap::{HeatMaps, HeatPanel};
use super::columns::{GroupKey, distinct, f64s};
use super::{PENALTY_UNIT, ReportError, ReportWriter, file_stem};

pub(crate) fn section(report: &mut ReportWriter, summary: &DataFrame) -> Result<(), ReportError> {
    report.heading(2, "Trained with N_train agents, tested with N_test: does a policy carry over to other team sizes?");
    let groups = GroupKey::of_rows(summary)?;
    let means = f64s(summary, summary::MEAN)?;
    let learned: Vec<(GroupKey, f64)> = groups
        .into_iter()
        .zip(means)
        .filter_map(|(g, m)| g.policy.n_train.map(|_| (g, m / PENALTY_UNIT)))
        .collect();
    if learned.is_empty() {
        report.paragraph(
            "The sweep has no learned policies, so there is no N_train x N_test matrix.",
        );
        return Ok(());
    }
    for map in distinct(learned.iter().map(|(g, _)| g.map.clone())) {
        let rows: Vec<&(GroupKey, f64)> = learned.iter().filter(|(g, _)| g.map == map).collect();
        let frame = df!(
            "policy" => rows.iter().map(|(g, _)| g.policy.policy.clone()).collect::<Vec<_>>(),
            "n_train" => rows.iter().map(|(g, _)| g.policy.n_train).collect::<Vec<_>>(),
            "n_test" => rows.iter().map(|(g, _)| g.n_test).collect::<Vec<_>>(),
            "mean" => rows.iter().map(|(_, m)| *m).collect::<Vec<_>>(),
        )?;
        report.heading(3, &format!("Map `{map}`"));
        let maps = heat_maps(&frame)?;
        report.figure(
            &file_stem(&["transfer", &map]),
            &maps,
            &caption(&map, maps.logarithmic()),
        )?;
        report.table(&file_stem(&["transfer", &map]), &frame)?;
    }
    Ok(())
}

fn caption(map: &str, logarithmic: bool) -> String {
    let scale = match logarithmic {
        true => "a log scale",
        false => "a linear scale (a value at or below 0 has no logarithm)",
    };
    format!(
        "Mean cumulative penalty (10^6) on `{map}`: rows N_train, columns N_test; colour on \
         {scale} shared by the panels, from blue (lowest) to red (highest), as the colour bar \
         on the right gives it"
    )
}

/// One panel per learned policy, from the table's rows.
fn heat_maps(frame: &DataFrame) -> PolarsResult<HeatMaps> {
    let policies = super::columns::strings(frame, "policy")?;
    let n_trains = super::columns::u32s(frame, "n_train")?;
    let n_tests = super::columns::u32s(frame, "n_test")?;
    let means = f64s(frame, "mean")?;
    let mut train_axis = distinct(n_trains.iter().copied());
    let mut test_axis = distinct(n_tests.iter().copied());
    train_axis.sort_unstable();
    test_axis.sort_unstable();
    let panels = distinct(policies.iter().cloned())
        .into_iter()
        .map(|policy| HeatPanel {
            values: train_axis
                .iter()
                .map(|&train| {
                    test_axis
                        .iter()
                        .map(|&test| {
                            (0..means.len())
                                .find(|&i| {
                                    policies[i] == policy
                                        && n_trains[i] == train
                                        && n_tests[i] == test
                                })
                                .map(|i| means[i])
                        })
                        .collect()
                })
                .collect(),
            title: policy,
            rows: train_axis.iter().map(u32::to_string).collect(),
            columns: test_axis.iter().map(u32::to_string).collect(),
        })
        .collect();
    Ok(HeatMaps {
        row_label: "N_train".into(),
        column_label: "N_test".into(),
        panels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matrices_are_filled_from_the_table() {
        let frame = df!(
            "policy" => ["ma-g-ppo", "ma-g-ppo", "ma-ppo"],
            "n_train" => [4u32, 2, 4],
            "n_test" => [6u32, 4, 4],
            "mean" => [1.0, 2.0, 3.0],
        )
        .unwrap();
        let maps = heat_maps(&frame).unwrap();
        assert_eq!(maps.panels.len(), 2);
        let gppo = &maps.panels[0];
        assert_eq!(
            (gppo.rows.clone(), gppo.columns.clone()),
            (vec!["2".into(), "4".into()], vec!["4".into(), "6".into()])
        );
        assert_eq!(
            gppo.values,
            vec![vec![Some(2.0), None], vec![None, Some(1.0)]]
        );
        assert_eq!(
            maps.panels[1].values,
            vec![vec![None, None], vec![Some(3.0), None]],
            "ma-ppo: trained with 4, tested with 4"
        );
    }
}
