//! Behaviour claims judged over training runs: the share of runs, and of each run's test
//! episodes, that show the structure a claim names (roles and rhythm, RQ3), with the rule
//! that turns those shares into a verdict. A behaviour is a measurement of each episode, not a
//! mean with an interval, so these claims have a section and a rule of their own, apart from
//! the statistical claims.

use polars::prelude::*;

use super::behaviour_replay::EpisodeMeasure;
use super::judgement::{Verdict, at_point};
use super::{ReportError, ReportWriter};
use plan::scenario::claims::{Behaviour, Claim, ClaimTest, Point};

/// The verdict rule, as the report states it.
pub(crate) const RULE: &str = "An episode shows the structure when every feature the claim names \
     matches it: the number of stationary and of touring agents (2-means roles, pooled with the \
     map's recorded episodes), whether the touring agents keep a common period with steady \
     phase differences, and whether every stationary agent keeps nearer the map's centre than \
     every touring one (each agent's mean distance from it over the episode). A run (a training run; for a baseline, a repetition) shows the \
     structure when more than half of its test episodes show it, and lacks it when more than \
     half do not (at exactly half, neither). A claim is **supported** when at least two thirds \
     of the runs show the structure, **contradicted** when at least two thirds lack it, and \
     **inconclusive** otherwise; **no data** when no run's episodes were measured.";

/// Whether one measured episode shows what a claim expects.
fn holds(measure: &EpisodeMeasure, expected: Behaviour) -> bool {
    let roles = &measure.roles;
    expected
        .stationary
        .is_none_or(|k| k == roles.stationary as usize)
        && expected.touring.is_none_or(|m| m == roles.touring as usize)
        && expected.periodic.is_none_or(|p| p == roles.periodic)
        && expected.centred.is_none_or(|c| Some(c) == roles.centred)
}

/// One run's test episodes at a claim's point: how many, and how many show the structure.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct RunShare {
    cell_key: String,
    repetition: u32,
    episodes: usize,
    holding: usize,
}

impl RunShare {
    /// Whether the run shows the structure in most of its episodes (`Some(true)`), lacks it
    /// in most (`Some(false)`), or neither (exactly half).
    fn shows(&self) -> Option<bool> {
        match (2 * self.holding).cmp(&self.episodes) {
            std::cmp::Ordering::Greater => Some(true),
            std::cmp::Ordering::Less => Some(false),
            std::cmp::Ordering::Equal => None,
        }
    }
}

/// The runs of `policy` at `point` among `measures`, in order of repetition.
pub(crate) fn runs(
    measures: &[EpisodeMeasure],
    policy: &str,
    point: &Point,
    expected: Behaviour,
) -> Vec<RunShare> {
    let mut runs: Vec<RunShare> = Vec::new();
    for measure in measures
        .iter()
        .filter(|m| at_point(&m.group, policy, point))
    {
        let held = usize::from(holds(measure, expected));
        match runs.iter_mut().find(|r| r.cell_key == measure.cell_key) {
            Some(run) => {
                run.episodes += 1;
                run.holding += held;
            }
            None => runs.push(RunShare {
                cell_key: measure.cell_key.clone(),
                repetition: measure.repetition,
                episodes: 1,
                holding: held,
            }),
        }
    }
    runs.sort_by(|a, b| (a.repetition, &a.cell_key).cmp(&(b.repetition, &b.cell_key)));
    runs
}

/// The verdict of [`RULE`] over `runs`.
pub(crate) fn verdict(runs: &[RunShare]) -> Verdict {
    if runs.is_empty() {
        return Verdict::NoData;
    }
    let count = |shows: bool| runs.iter().filter(|r| r.shows() == Some(shows)).count();
    let at_least_two_thirds = |k: usize| 3 * k >= 2 * runs.len();
    if at_least_two_thirds(count(true)) {
        Verdict::Supported
    } else if at_least_two_thirds(count(false)) {
        Verdict::Contradicted
    } else {
        Verdict::Inconclusive
    }
}

/// The numbers behind a verdict, in words: what the claim expects, the runs showing it, and
/// each run's episodes.
pub(crate) fn describe(runs: &[RunShare], expected: Behaviour) -> String {
    let showing = runs.iter().filter(|r| r.shows() == Some(true)).count();
    let lacking = runs.iter().filter(|r| r.shows() == Some(false)).count();
    let (holding, episodes) = runs
        .iter()
        .fold((0, 0), |(h, e), r| (h + r.holding, e + r.episodes));
    format!(
        "{}: {showing} of {} runs show it in most of their test episodes, {lacking} lack it \
         in most; episodes showing it per run: {}; {holding} of {episodes} episodes in all",
        expectation(expected),
        runs.len(),
        shares(runs)
    )
}

/// Each run's episodes showing the structure, `holding/episodes`, in order.
fn shares(runs: &[RunShare]) -> String {
    let each: Vec<String> = runs
        .iter()
        .map(|r| format!("{}/{}", r.holding, r.episodes))
        .collect();
    each.join(", ")
}

/// What a claim expects, in words: "1 stationary, 3 touring, periodic".
fn expectation(expected: Behaviour) -> String {
    let mut parts = Vec::new();
    if let Some(k) = expected.stationary {
        parts.push(format!("{k} stationary"));
    }
    if let Some(m) = expected.touring {
        parts.push(format!("{m} touring"));
    }
    if let Some(p) = expected.periodic {
        parts.push(if p { "periodic" } else { "not periodic" }.to_owned());
    }
    if let Some(c) = expected.centred {
        let nearer = if c { "nearer" } else { "not nearer" };
        parts.push(format!(
            "the stationary {nearer} the centre than the touring"
        ));
    }
    parts.join(", ")
}

/// A behaviour claim of `claims` as its parts.
struct Judged<'a> {
    claim: &'a Claim,
    expected: Behaviour,
    runs: Vec<RunShare>,
    episodes: Vec<&'a EpisodeMeasure>,
}

fn judged<'a>(claims: &'a [Claim], measures: &'a [EpisodeMeasure]) -> Vec<Judged<'a>> {
    (claims.iter())
        .filter_map(|claim| match &claim.test {
            ClaimTest::Behaviour {
                policy,
                point,
                expected,
            } => Some(Judged {
                claim,
                expected: *expected,
                runs: runs(measures, policy, point, *expected),
                episodes: (measures.iter())
                    .filter(|m| at_point(&m.group, policy, point))
                    .collect(),
            }),
            _ => None,
        })
        .collect()
}

/// The detail under the behaviour claims' verdicts (`verdicts::section` prints them with
/// [`RULE`]): how their episodes were measured, every run's share of episodes showing the
/// structure, and every measured episode (linked). Nothing when `claims` has no behaviour
/// claim.
pub(crate) fn section(
    report: &mut ReportWriter,
    claims: &[Claim],
    measures: &[EpisodeMeasure],
) -> Result<(), ReportError> {
    let judged = judged(claims, measures);
    if judged.is_empty() {
        return Ok(());
    }
    report.paragraph(
        "Every test episode of every run at a claim's point is played again from its cell's \
         config and checkpoint, bit for bit as the episodes table holds it (the sweep records \
         one episode only), and measured as the section on emergent behaviour measures the \
         recorded ones; the store keeps the measures in its `behaviour_episodes` table. Each \
         run's test episodes showing the structure:",
    );
    report.table("behaviour_runs", &runs_frame(&judged)?)?;
    report.linked_table(
        "behaviour_claim_episodes",
        &episodes_frame(&judged)?,
        "Every measured test episode of every behaviour claim, with whether it shows the \
         structure",
    )
}

fn runs_frame(judged: &[Judged]) -> PolarsResult<DataFrame> {
    let rows: Vec<(&Judged, &RunShare)> = (judged.iter())
        .flat_map(|j| j.runs.iter().map(move |r| (j, r)))
        .collect();
    let shows = |r: &RunShare| match r.shows() {
        Some(true) => "shows",
        Some(false) => "lacks",
        None => "neither",
    };
    df!(
        "claim" => rows.iter().map(|(j, _)| j.claim.id.as_str()).collect::<Vec<_>>(),
        "cell_key" => rows.iter().map(|(_, r)| r.cell_key.as_str()).collect::<Vec<_>>(),
        "repetition" => rows.iter().map(|(_, r)| r.repetition).collect::<Vec<_>>(),
        "episodes" => rows.iter().map(|(_, r)| r.episodes as u32).collect::<Vec<_>>(),
        "showing" => rows.iter().map(|(_, r)| r.holding as u32).collect::<Vec<_>>(),
        "share" => rows.iter().map(|(_, r)| r.holding as f64 / r.episodes as f64).collect::<Vec<_>>(),
        "run" => rows.iter().map(|(_, r)| shows(r)).collect::<Vec<_>>(),
    )
}

fn episodes_frame(judged: &[Judged]) -> PolarsResult<DataFrame> {
    let rows: Vec<(&Judged, &EpisodeMeasure)> = (judged.iter())
        .flat_map(|j| j.episodes.iter().map(move |m| (j, *m)))
        .collect();
    let column =
        |f: fn(&EpisodeMeasure) -> u32| -> Vec<u32> { rows.iter().map(|(_, m)| f(m)).collect() };
    df!(
        "claim" => rows.iter().map(|(j, _)| j.claim.id.as_str()).collect::<Vec<_>>(),
        "cell_key" => rows.iter().map(|(_, m)| m.cell_key.as_str()).collect::<Vec<_>>(),
        "repetition" => column(|m| m.repetition),
        "episode" => column(|m| m.episode),
        "stationary" => column(|m| m.roles.stationary),
        "touring" => column(|m| m.roles.touring),
        "periodic" => rows.iter().map(|(_, m)| m.roles.periodic).collect::<Vec<_>>(),
        "centred" => rows.iter().map(|(_, m)| m.roles.centred).collect::<Vec<_>>(),
        "holds" => rows.iter().map(|(j, m)| holds(m, j.expected)).collect::<Vec<_>>(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs of 10 episodes each, `holding[i]` of run i showing the structure.
    fn runs_holding(holding: &[usize]) -> Vec<RunShare> {
        (holding.iter().enumerate())
            .map(|(i, &h)| RunShare {
                cell_key: format!("cell{i}"),
                repetition: i as u32,
                episodes: 10,
                holding: h,
            })
            .collect()
    }

    #[test]
    fn two_thirds_of_the_runs_decide() {
        use Verdict::*;
        assert_eq!(verdict(&runs_holding(&[10, 7, 6])), Supported, "all show");
        assert_eq!(
            verdict(&runs_holding(&[8, 9, 2])),
            Supported,
            "two of three"
        );
        assert_eq!(verdict(&runs_holding(&[8, 1, 0])), Contradicted, "two lack");
        assert_eq!(verdict(&runs_holding(&[0, 4, 3])), Contradicted, "all lack");
        assert_eq!(verdict(&runs_holding(&[8, 5, 2])), Inconclusive, "one tied");
        assert_eq!(verdict(&runs_holding(&[9, 5, 5])), Inconclusive, "two tied");
        assert_eq!(verdict(&runs_holding(&[9, 1])), Inconclusive, "one each");
        assert_eq!(verdict(&runs_holding(&[9, 6])), Supported);
        assert_eq!(verdict(&[]), NoData);
    }

    #[test]
    fn a_run_shows_a_structure_in_more_than_half_its_episodes() {
        let shows = |h| runs_holding(&[h])[0].shows();
        assert_eq!(
            (shows(6), shows(5), shows(4)),
            (Some(true), None, Some(false))
        );
        let expected = Behaviour {
            touring: Some(2),
            periodic: Some(true),
            ..Behaviour::default()
        };
        let text = describe(&runs_holding(&[8, 9, 2]), expected);
        assert!(
            text.starts_with("2 touring, periodic: 2 of 3 runs show it"),
            "{text}"
        );
        assert!(text.contains("8/10, 9/10, 2/10"), "{text}");
        assert!(text.ends_with("19 of 30 episodes in all"), "{text}");
    }

    #[test]
    fn episodes_count_by_run_and_every_named_feature() {
        use super::super::behaviour::EpisodeRoles;
        use super::super::columns::{GroupKey, PolicyKey};
        let point = Point {
            map: "open".into(),
            n_test: 4,
            n_train: 4,
        };
        let measure = |cell: &str, repetition, stationary, periodic, centred| EpisodeMeasure {
            group: GroupKey {
                map: "open".into(),
                policy: PolicyKey {
                    policy: "ma-g-ppo@fast".into(),
                    n_train: Some(4),
                },
                n_test: 4,
            },
            cell_key: cell.into(),
            repetition,
            episode: 0,
            roles: EpisodeRoles {
                stationary,
                touring: 4 - stationary,
                periodic,
                centred,
            },
            pool: String::new(),
        };
        let measures = [
            measure("b", 1, 1, true, Some(true)),
            measure("a", 0, 1, false, Some(true)),
            measure("b", 1, 0, true, None),
            measure("a", 0, 1, true, Some(false)),
        ];
        let expected = Behaviour {
            stationary: Some(1),
            periodic: Some(true),
            ..Behaviour::default()
        };
        let summary = |expected| -> Vec<(String, usize, usize)> {
            (runs(&measures, "ma-g-ppo@fast", &point, expected).iter())
                .map(|r| (r.cell_key.clone(), r.episodes, r.holding))
                .collect()
        };
        let counted = |a, b| vec![("a".to_owned(), 2, a), ("b".to_owned(), 2, b)];
        assert_eq!(summary(expected), counted(1, 1));
        assert!(runs(&measures, "ma-ppo@fast", &point, expected).is_empty());
        assert_eq!(expectation(expected), "1 stationary, periodic");
        let centred = Behaviour {
            centred: Some(true),
            ..expected
        };
        assert_eq!(
            summary(centred),
            counted(0, 1),
            "a: not centred; b: no stationary"
        );
        assert_eq!(
            expectation(centred),
            "1 stationary, periodic, the stationary nearer the centre than the touring"
        );
    }
}
