//! The budget rule: every result of the paper comes from policies trained its 30,000 episodes,
//! so a claim about them is tested on runs that trained that long, or until they converged
//! (the stopping rule says when a run has learned what it will). A run its cap ended before it
//! converged, short of the budget, has neither: its policy is short.
//!
//! A claim's verdict rests on the runs at its points' maps and team sizes, so those runs, and
//! only those, are held to the rule: one run capped at N_train = 10 leaves a claim about
//! N = 2 and 4 as its runs there judge it.

use std::collections::HashMap;
use store::schema::convergence as run;

use polars::prelude::*;

use super::ReportError;
use super::columns::{PolicyKey, distinct, f64s, strings, trained_keys};
use super::training::{Setting, episodes_per_run};
use plan::scenario::claims::{Claim, ClaimTest};

/// How the runs of one setting (a map and a learned policy with its N_train) trained: the fewest episodes any of them logged, and for runs
/// trained until converged, how many the stopping rule ended and how many their cap did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Runs {
    episodes: u64,
    until_converged: Option<Stops>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Stops {
    converged: usize,
    capped: usize,
    /// The episodes the longest capped run trained (its cap); 0 with none capped.
    capped_at: u64,
}

impl Stops {
    fn and(self, other: Stops) -> Stops {
        Stops {
            converged: self.converged + other.converged,
            capped: self.capped + other.capped,
            capped_at: self.capped_at.max(other.capped_at),
        }
    }
}

impl Runs {
    /// The runs of several settings together.
    fn and(self, other: Runs) -> Runs {
        let until_converged = match (self.until_converged, other.until_converged) {
            (Some(a), Some(b)) => Some(a.and(b)),
            (a, b) => a.or(b),
        };
        Runs {
            episodes: self.episodes.min(other.episodes),
            until_converged,
        }
    }
}

/// Each setting's `Runs`, from the training table and the convergence table's runs.
pub(crate) fn trained_runs(
    training: &DataFrame,
    convergence: Option<&DataFrame>,
) -> Result<HashMap<Setting, Runs>, ReportError> {
    let mut trained: HashMap<Setting, Runs> = HashMap::new();
    for (setting, episodes) in episodes_per_run(training)? {
        let run = Runs {
            episodes: episodes as u64,
            until_converged: None,
        };
        trained
            .entry(setting)
            .and_modify(|runs| runs.episodes = runs.episodes.min(run.episodes))
            .or_insert(run);
    }
    if let Some(table) = convergence {
        let stops = strings(table, run::STOP)?;
        let at = f64s(table, run::STOP_EPISODE)?;
        for ((setting, stop), at) in trained_keys(table)?.into_iter().zip(stops).zip(at) {
            let runs = trained.entry(setting).or_default();
            let counts = runs.until_converged.get_or_insert_with(Stops::default);
            match stop == run::CONVERGED {
                true => counts.converged += 1,
                false => {
                    counts.capped += 1;
                    counts.capped_at = counts.capped_at.max(at as u64);
                }
            }
        }
    }
    Ok(trained)
}

/// Whether the runs a claim rests on meet the training its statement assumes. `Ok` says how
/// each learned policy met it, `Err` which fell short and where; with no training table
/// nothing can tell.
pub(crate) fn trained_for(
    claim: &Claim,
    budget: u64,
    trained: &Option<HashMap<Setting, Runs>>,
) -> Result<String, String> {
    let Some(trained) = trained else {
        return Err(format!(
            "the statement assumes {budget} training episodes or convergence; the store keeps \
             no training table to tell how long the runs trained"
        ));
    };
    let settings = claim_settings(&claim.test);
    let mut met = Vec::new();
    let mut short = Vec::new();
    for policy in distinct(settings.iter().map(|(_, key)| key.policy.clone())) {
        let runs: Vec<(&Setting, Runs)> = (settings.iter())
            .filter(|(_, key)| key.policy == policy)
            .filter_map(|setting| Some((setting, *trained.get(setting)?)))
            .collect();
        let Some(all) = runs.iter().map(|(_, runs)| *runs).reduce(Runs::and) else {
            continue;
        };
        match all {
            Runs {
                until_converged: Some(stops),
                episodes,
            } if stops.capped == 0 || episodes >= budget => met.push(format!(
                "{policy} trained until converged: {} of {} runs converged, {} capped",
                stops.converged,
                stops.converged + stops.capped,
                stops.capped
            )),
            Runs {
                until_converged: Some(stops),
                ..
            } => short.push(format!(
                "{policy} trained until converged, but {} of {} runs reached their cap before \
                 converging ({})",
                stops.capped,
                stops.converged + stops.capped,
                where_capped(&runs)
            )),
            Runs { episodes, .. } if episodes >= budget => {
                met.push(format!("{policy} trained {episodes} episodes"))
            }
            Runs { episodes, .. } => {
                short.push(format!("{policy} trained {episodes}, not until converged"))
            }
        }
    }
    match short.is_empty() {
        true => Ok(met.join("; ")),
        false => Err(format!(
            "not tested at this budget: the statement assumes {budget} training episodes or \
             convergence; {}",
            short.join("; ")
        )),
    }
}

/// "1 at open N_train=10 after 2000 episodes; ...": where a policy's capped runs trained.
fn where_capped(runs: &[(&Setting, Runs)]) -> String {
    let capped = runs.iter().filter_map(|((map, key), runs)| {
        let stops = runs.until_converged.filter(|stops| stops.capped > 0)?;
        let n_train = key
            .n_train
            .map_or(String::new(), |n| format!(" N_train={n}"));
        Some(format!(
            "{} at {map}{n_train} after {} episodes",
            stops.capped, stops.capped_at
        ))
    });
    capped.collect::<Vec<_>>().join("; ")
}

/// The settings a claim's verdict rests on, each once, policies in the order the claim names
/// them (`ClaimTest::trained_at`). A baseline's have no runs.
fn claim_settings(test: &ClaimTest) -> Vec<Setting> {
    distinct(test.trained_at().into_iter().map(|(policy, map, n_train)| {
        let key = PolicyKey {
            policy: policy.to_owned(),
            n_train: Some(n_train),
        };
        (map.to_owned(), key)
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use plan::scenario::claims::{Pair, Point};

    fn lower(a: &str, b: &str, n: &[u32]) -> Claim {
        let points = (n.iter())
            .map(|&n| Point {
                map: "open".into(),
                n_test: n,
                n_train: n,
            })
            .collect();
        let pair = Pair {
            a: a.into(),
            b: b.into(),
            a_under: None,
            b_under: None,
            points,
            at_episode: None,
        };
        Claim {
            id: "after-30k".into(),
            paper: String::new(),
            test: ClaimTest::Lower { pair },
            budget: Some(30_000),
        }
    }

    fn setting(policy: &str, n_train: u32) -> Setting {
        let key = PolicyKey {
            policy: policy.into(),
            n_train: Some(n_train),
        };
        ("open".into(), key)
    }

    fn runs(at: &[(u32, Runs)]) -> Option<HashMap<Setting, Runs>> {
        Some(
            (at.iter())
                .map(|&(n, runs)| (setting("ma-g-ppo@fast", n), runs))
                .collect(),
        )
    }

    fn trained(episodes: u64, until_converged: Option<Stops>) -> Runs {
        Runs {
            episodes,
            until_converged,
        }
    }

    fn stops(converged: usize, capped: usize, capped_at: u64) -> Option<Stops> {
        Some(Stops {
            converged,
            capped,
            capped_at,
        })
    }

    #[test]
    fn a_claim_is_tested_on_runs_that_trained_the_budget_or_converged() {
        let claim = lower("gcs", "ma-g-ppo@fast", &[4]);
        let short = trained_for(&claim, 30_000, &runs(&[(4, trained(800, None))])).unwrap_err();
        assert!(
            short.contains("ma-g-ppo@fast trained 800, not until converged"),
            "{short}"
        );
        let long = trained_for(&claim, 30_000, &runs(&[(4, trained(30_000, None))]));
        assert_eq!(long.unwrap(), "ma-g-ppo@fast trained 30000 episodes");
        let converged = trained(900, stops(5, 0, 0));
        let converged = trained_for(&claim, 30_000, &runs(&[(4, converged)])).unwrap();
        assert!(converged.contains("until converged: 5 of 5 runs converged, 0 capped"));
        let one_capped = trained(900, stops(4, 1, 2_000));
        let capped = trained_for(&claim, 30_000, &runs(&[(4, one_capped)])).unwrap_err();
        assert!(
            capped.contains(
                "1 of 5 runs reached their cap before converging (1 at open N_train=4 after \
                 2000 episodes)"
            ),
            "a capped run short of the budget is neither: {capped}"
        );
        let at_budget = trained(30_000, stops(4, 1, 30_000));
        let capped_at_budget = trained_for(&claim, 30_000, &runs(&[(4, at_budget)]));
        assert!(
            capped_at_budget
                .unwrap()
                .contains("4 of 5 runs converged, 1 capped")
        );
        assert!(
            trained_for(&claim, 30_000, &None).is_err(),
            "no table: cannot tell"
        );
    }

    /// RQ4's table holds every team size's runs, and RQ1 judges N = 2 and 4 on them: a run
    /// capped at N = 10 must not make those claims untested, and must make N = 10's.
    #[test]
    fn only_the_runs_at_a_claims_points_are_held_to_the_budget() {
        let table = runs(&[
            (2, trained(500, stops(5, 0, 0))),
            (4, trained(600, stops(5, 0, 0))),
            (10, trained(600, stops(4, 1, 2_000))),
        ]);
        let small = trained_for(&lower("ma-g-ppo@fast", "gcs", &[2, 4]), 30_000, &table);
        assert_eq!(
            small.unwrap(),
            "ma-g-ppo@fast trained until converged: 10 of 10 runs converged, 0 capped"
        );
        let every_n = trained_for(&lower("ma-g-ppo@fast", "gcs", &[2, 4, 10]), 30_000, &table);
        let every_n = every_n.unwrap_err();
        assert!(
            every_n.contains(
                "1 of 15 runs reached their cap before converging (1 at open N_train=10 after \
                 2000 episodes)"
            ),
            "{every_n}"
        );
        let mut transfer = lower("ma-g-ppo@fast", "gcs", &[2, 4, 6]);
        if let ClaimTest::Lower { pair } = &mut transfer.test {
            pair.points.iter_mut().for_each(|p| p.n_train = 10);
        }
        let transfer = trained_for(&transfer, 30_000, &table).unwrap_err();
        assert!(
            transfer.contains("1 of 5 runs reached"),
            "three points trained with 10 are its 5 runs once: {transfer}"
        );
    }
}
