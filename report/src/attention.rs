//! Attention along training: MA-G-PPO's attention entropy, run by run, against the entropy of
//! even weights, ln N over N agents with self-loops (the released graph) and ln(N - 1) without.
//! Every run behind rq1, rq3, rq4 and rq5 kept it at that maximum throughout (their profile
//! rewarded it), so the table says of each run how far its attention settled below even; the
//! figure is drawn only where some run's attention moved, since a flat line at ln N says no
//! more than the table.

use std::collections::BTreeMap;

use polars::prelude::*;
use store::schema::{cell, training};

use super::columns::{distinct, f64s, group_rows, strings, trained_keys};
use super::training::{Measure, curves, curves_frame, figure, n_train_label};
use super::{ReportError, ReportWriter, file_stem};

/// The attention entropy, in nats.
const ATTENTION: Measure = Measure {
    column: training::ATTENTION_ENTROPY,
    title: "Attention entropy",
    name: "Attention entropy in training",
    y_label: "attention entropy (nats)",
    divisor: 1.0,
};

/// The share of the run's episodes, at its end, whose mean is its settled entropy.
const LATE_SHARE: f64 = 0.1;

/// A run's attention moved when its settled entropy is below this share of its first.
const MOVED: f64 = 0.9;

/// One training run's attention entropy: at its first episode and settled at its end.
struct RunEntropy {
    map: String,
    policy: String,
    n_train: Option<u32>,
    cell: String,
    agents: u32,
    first: f64,
    late: f64,
}

impl RunEntropy {
    fn moved(&self) -> bool {
        self.late < MOVED * self.first
    }
}

pub(crate) fn section(report: &mut ReportWriter, training: &DataFrame) -> Result<(), ReportError> {
    let runs = run_entropies(training)?;
    if runs.is_empty() {
        return Ok(());
    }
    report.heading(2, "Attention: did MA-G-PPO's attention move from even?");
    let moved = runs.iter().filter(|r| r.moved()).count();
    report.paragraph(&format!(
        "The attention entropy of each MA-G-PPO training run at its first episode and settled \
         (the mean of its last {:.0} % of episodes), beside ln N and ln(N - 1), the entropies of \
         even weights over N agents with self-loops and over the N - 1 others without (runs \
         whose entropy is 0 throughout are left out: MA-PPO's, and MA-G-PPO's with one \
         neighbour): {moved} of {} runs settled below {:.0} % of their first episode's entropy.",
        LATE_SHARE * 100.0,
        runs.len(),
        MOVED * 100.0
    ));
    report.table("attention", &frame(&runs)?)?;
    let settings = distinct(
        runs.iter()
            .filter(|r| r.moved())
            .map(|r| (&r.map, r.n_train)),
    );
    if settings.is_empty() {
        return Ok(());
    }
    let curves: Vec<_> = (curves(training, &ATTENTION)?.into_iter())
        .filter(|c| runs.iter().any(|r| r.policy == c.policy.policy))
        .collect();
    report.linked_table(
        "attention_curves",
        &curves_frame(&curves)?,
        "The attention curves (mean, lowest and highest run)",
    )?;
    for (map, n_train) in settings {
        let shown: Vec<_> = (curves.iter())
            .filter(|c| &c.map == map && c.policy.n_train == n_train)
            .collect();
        let n = n_train_label(n_train);
        let stem = file_stem(&["attention", map, &format!("train{n}")]);
        let setting = format!("on `{map}`, N_train = {n}");
        figure(report, &stem, &setting, &shown, &ATTENTION, |c| {
            c.policy.policy.clone()
        })?;
    }
    Ok(())
}

/// Every run with attention (an entropy other than 0 at some episode: MA-PPO's is 0), in the
/// table's order.
fn run_entropies(training: &DataFrame) -> Result<Vec<RunEntropy>, ReportError> {
    let cells = strings(training, cell::KEY)?;
    let keys = trained_keys(training)?;
    let episodes = f64s(training, training::EPISODE)?;
    let agents = f64s(training, training::AGENTS)?;
    let entropy = f64s(training, training::ATTENTION_ENTROPY)?;
    let mut runs = Vec::new();
    for (cell, rows) in group_rows(&cells) {
        let by_episode: BTreeMap<u64, f64> = rows
            .iter()
            .map(|&r| (episodes[r] as u64, entropy[r]))
            .collect();
        if by_episode.values().all(|&e| e == 0.0) {
            continue;
        }
        let values: Vec<f64> = by_episode.into_values().collect();
        let late = ((values.len() as f64 * LATE_SHARE).ceil() as usize).max(1);
        let tail = &values[values.len() - late..];
        let (map, policy) = &keys[rows[0]];
        runs.push(RunEntropy {
            map: map.clone(),
            policy: policy.policy.clone(),
            n_train: policy.n_train,
            cell,
            agents: agents[rows[0]] as u32,
            first: values[0],
            late: tail.iter().sum::<f64>() / tail.len() as f64,
        });
    }
    Ok(runs)
}

fn frame(runs: &[RunEntropy]) -> PolarsResult<DataFrame> {
    let ln = |n: u32| f64::from(n.max(1)).ln();
    df!(
        "map" => runs.iter().map(|r| r.map.clone()).collect::<Vec<_>>(),
        "policy" => runs.iter().map(|r| r.policy.clone()).collect::<Vec<_>>(),
        "n_train" => runs.iter().map(|r| r.n_train).collect::<Vec<_>>(),
        "cell_key" => runs.iter().map(|r| r.cell.clone()).collect::<Vec<_>>(),
        "ln_n" => runs.iter().map(|r| ln(r.agents)).collect::<Vec<_>>(),
        "ln_n_minus_1" => runs.iter().map(|r| ln(r.agents.saturating_sub(1))).collect::<Vec<_>>(),
        "first" => runs.iter().map(|r| r.first).collect::<Vec<_>>(),
        "settled" => runs.iter().map(|r| r.late).collect::<Vec<_>>(),
        "settled_over_first" => runs.iter().map(|r| r.late / r.first).collect::<Vec<_>>(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn training(entropies: &[(&str, &str, f64)]) -> DataFrame {
        let rows = entropies.len();
        df!(
            cell::KEY => entropies.iter().map(|e| e.0).collect::<Vec<_>>(),
            cell::MAP => vec!["open"; rows],
            cell::POLICY => entropies.iter().map(|e| e.1).collect::<Vec<_>>(),
            cell::N_TRAIN => vec![Some(4u32); rows],
            training::EPISODE => (0..rows).map(|e| e as f64).collect::<Vec<_>>(),
            training::AGENTS => vec![4.0; rows],
            training::ATTENTION_ENTROPY => entropies.iter().map(|e| e.2).collect::<Vec<_>>(),
        )
        .unwrap()
    }

    /// A run whose entropy fell to a tenth moved; one that stayed at ln 4 did not; MA-PPO's
    /// zeros are no run with attention.
    #[test]
    fn a_run_moved_when_it_settled_below_nine_tenths_of_its_first_entropy() {
        let even = 4f64.ln();
        let mut rows = vec![("a", "ma-g-ppo", even)];
        rows.extend(std::iter::repeat_n(("a", "ma-g-ppo", even / 10.0), 19));
        rows.extend(std::iter::repeat_n(("b", "uniform", even), 20));
        rows.extend(std::iter::repeat_n(("c", "ma-ppo", 0.0), 20));
        let runs = run_entropies(&training(&rows)).unwrap();
        assert_eq!(runs.len(), 2);
        assert!(runs[0].moved() && !runs[1].moved());
        assert!((runs[0].late - even / 10.0).abs() < 1e-12);
        let table = frame(&runs).unwrap();
        assert_eq!(
            table.column("ln_n").unwrap().f64().unwrap().get(0),
            Some(even)
        );
    }
}
