//! Claims checked once, at load: exactly one kind each, ids unique, and (with the scenario at
//! hand) only the scenario's own policies, maps and agent counts, named by file, line and field.

use std::path::Path;

use serde_saphyr::Spanned;

use super::claim::{Behaviour, Claim, ClaimTest, GCS, Pair, Point, RANDOM, Scale, Tolerance};
use super::format::{
    AdaptationSpec, BehaviourSpec, ClaimSpec, CurveSpec, DiagonalSpec, FasterSpec, PairSpec,
};
use crate::scenario::ScenarioError;
use learning::ppo::Profile;

/// What a scenario offers claims to name.
pub(crate) struct ClaimContext {
    /// Every policy's table label, and whether it is learned.
    pub(crate) policies: Vec<(String, bool)>,
    pub(crate) maps: Vec<String>,
    pub(crate) train_agents: Vec<u32>,
    pub(crate) test_agents: Vec<u32>,
    /// Every disturbance's name, with the robots it loses (`None`: it loses none, or how many
    /// is not fixed).
    pub(crate) disturbances: Vec<(String, Option<u32>)>,
}

/// A failed check: the value it is about, its field, the problem.
type Failure = (Option<serde_saphyr::Location>, String, String);

pub(crate) fn check_claims(
    specs: &[Spanned<ClaimSpec>],
    context: Option<&ClaimContext>,
    file: &Path,
) -> Result<Vec<Claim>, ScenarioError> {
    let mut claims: Vec<Claim> = Vec::new();
    for (i, spec) in specs.iter().enumerate() {
        let field = format!("claims[{i}]");
        let place = |(location, sub, problem): Failure| {
            let line = location
                .or(Some(spec.referenced))
                .and_then(crate::scenario::error::line_of);
            ScenarioError::new(file, line, &format!("{field}{sub}"), problem)
        };
        let claim = check_claim(&spec.value, context).map_err(place)?;
        if claims.iter().any(|c| c.id == claim.id) {
            let problem = format!("a second claim with id {:?}", claim.id);
            return Err(place((None, ".id".into(), problem)));
        }
        claims.push(claim);
    }
    Ok(claims)
}

fn check_claim(spec: &ClaimSpec, context: Option<&ClaimContext>) -> Result<Claim, Failure> {
    if spec.id.trim().is_empty() {
        return Err((None, ".id".into(), "a claim needs an id".into()));
    }
    let kinds = spec.kinds();
    if kinds.iter().filter(|(_, given)| *given).count() != 1 {
        let names: Vec<&str> = kinds.iter().map(|(name, _)| *name).collect();
        let problem = format!("give exactly one of {}", names.join(", "));
        return Err((None, String::new(), problem));
    }
    let checker = Checker { context };
    let test = if let Some(pair) = &spec.lower {
        ClaimTest::Lower {
            pair: checker.pair(pair, ".lower", 1)?,
        }
    } else if let Some(pair) = &spec.within {
        let tolerance = checker.tolerance(pair, ".within")?;
        let pair = checker.pair(pair, ".within", 1)?;
        ClaimTest::Within { pair, tolerance }
    } else if let Some(pair) = &spec.not_worse {
        let tolerance = checker.tolerance(pair, ".not_worse")?;
        let pair = checker.pair(pair, ".not_worse", 1)?;
        ClaimTest::NotWorse { pair, tolerance }
    } else if let Some(pair) = &spec.gap_grows {
        if pair.maps.value.len() != 1 {
            let problem = "a gap grows along N on one map: write one claim per map".to_owned();
            return Err(fail(&pair.maps, ".gap_grows.maps".into(), problem));
        }
        ClaimTest::GapGrows {
            pair: checker.pair(pair, ".gap_grows", 2)?,
            scale: gap_scale(pair)?,
        }
    } else if let Some(pair) = &spec.every_run_lower {
        checker.policy(&pair.a, ".every_run_lower.a".into(), true)?;
        ClaimTest::EveryRunLower {
            pair: checker.pair(pair, ".every_run_lower", 1)?,
        }
    } else if let Some(diagonal) = &spec.diagonal_best {
        checker.diagonal(diagonal)?
    } else if let Some(behaviour) = &spec.behaviour {
        checker.behaviour(behaviour)?
    } else if let Some(adaptation) = &spec.adapts_better {
        checker.adaptation(adaptation)?
    } else if let Some(faster) = &spec.faster {
        checker.faster(faster)?
    } else if let Some(reason) = &spec.not_tested {
        if reason.value.trim().is_empty() {
            let problem = "say why the statement is not tested".to_owned();
            return Err(fail(reason, ".not_tested".into(), problem));
        }
        ClaimTest::NotTested {
            reason: reason.value.clone(),
        }
    } else {
        checker.curve(spec.curve_below.as_ref().expect("one kind is given"))?
    };
    if let Some(budget) = &spec.budget
        && budget.value == 0
    {
        return Err(fail(
            budget,
            ".budget".into(),
            "must be > 0 episodes".into(),
        ));
    }
    Ok(Claim {
        id: spec.id.clone(),
        paper: spec.paper.clone(),
        test,
        budget: spec.budget.as_ref().map(|b| b.value),
    })
}

/// Which of the scenario's agent counts a claim's counts must be among.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Lists {
    Test,
    Train,
    Both,
}

struct Checker<'a> {
    context: Option<&'a ClaimContext>,
}

/// Every (map, N_test) in the order written, maps first, with the N_train `n_train` gives.
fn points(maps: &[String], n: &[u32], n_train: impl Fn(u32) -> u32) -> Vec<Point> {
    let point = |map: &String, n_test: u32| Point {
        map: map.clone(),
        n_test,
        n_train: n_train(n_test),
    };
    maps.iter()
        .flat_map(|map| n.iter().map(|&n_test| point(map, n_test)))
        .collect()
}

/// What a `gap_grows` claim divides its gaps by: nothing (`absolute`, the default) or b's
/// mean at each point. Random's scale would measure the gap against a third policy, which no
/// statement of the paper does.
fn gap_scale(spec: &PairSpec) -> Result<Scale, Failure> {
    let Some(name) = &spec.scale else {
        return Ok(Scale::Absolute);
    };
    match Scale::parse(&name.value) {
        Some(scale @ (Scale::B | Scale::Absolute)) => Ok(scale),
        _ => {
            let problem = format!("a gap is scaled by b or absolute, not {:?}", name.value);
            Err(fail(name, ".gap_grows.scale".into(), problem))
        }
    }
}

fn fail<T>(value: &Spanned<T>, field: String, problem: String) -> Failure {
    (Some(value.referenced), field, problem)
}

impl Checker<'_> {
    fn pair(&self, spec: &PairSpec, field: &str, least: usize) -> Result<Pair, Failure> {
        self.policy(&spec.a, format!("{field}.a"), false)?;
        self.policy(&spec.b, format!("{field}.b"), false)?;
        let a_under = self.under(spec.a_under.as_ref(), format!("{field}.a_under"))?;
        let b_under = self.under(spec.b_under.as_ref(), format!("{field}.b_under"))?;
        if spec.a.value == spec.b.value && a_under == b_under {
            let problem = "a and b are the same policy under the same conditions".to_owned();
            return Err(fail(&spec.b, format!("{field}.b"), problem));
        }
        let maps = self.names(&spec.maps, &format!("{field}.maps"))?;
        let points = match &spec.n_test {
            Some(n_test) => self.column(spec, field, least, n_test, &maps)?,
            None => self.row(spec, field, least, &maps)?,
        };
        if let Some(at) = &spec.at_episode {
            // A test curve plays N_train agents, undisturbed.
            let problem = if a_under.is_some() || b_under.is_some() {
                Some("test curves are played undisturbed: leave out a_under and b_under")
            } else if points.iter().any(|p| p.n_test != p.n_train) {
                Some("test curves play N_test = N_train: leave out n_train and n_test")
            } else {
                None
            };
            if let Some(problem) = problem {
                return Err(fail(at, format!("{field}.at_episode"), problem.into()));
            }
        }
        Ok(Pair {
            a: spec.a.value.clone(),
            b: spec.b.value.clone(),
            a_under,
            b_under,
            points,
            at_episode: spec.at_episode.as_ref().map(|at| at.value),
        })
    }

    /// The points (map, N_test = n), a learned policy at N_train = `n_train` or N_test.
    fn row(
        &self,
        spec: &PairSpec,
        field: &str,
        least: usize,
        maps: &[String],
    ) -> Result<Vec<Point>, Failure> {
        let n = self.counts(&spec.n, &format!("{field}.n"), least, Lists::Test)?;
        if let Some(n_train) = &spec.n_train {
            self.count(n_train, format!("{field}.n_train"), true)?;
        } else if self.is_learned(&spec.a.value) || self.is_learned(&spec.b.value) {
            for (i, count) in spec.n.value.iter().enumerate() {
                self.count(count, format!("{field}.n[{i}]"), true)?;
            }
        }
        Ok(points(maps, &n, |n_test| {
            spec.n_train.as_ref().map_or(n_test, |n| n.value)
        }))
    }

    /// The points of one N_test column: `n` lists the learned policies' N_train.
    fn column(
        &self,
        spec: &PairSpec,
        field: &str,
        least: usize,
        n_test: &Spanned<u32>,
        maps: &[String],
    ) -> Result<Vec<Point>, Failure> {
        if let Some(n_train) = &spec.n_train {
            let problem = "give n_test (a column, n listing N_train) or n_train, not both";
            return Err(fail(n_train, format!("{field}.n_train"), problem.into()));
        }
        self.count(n_test, format!("{field}.n_test"), false)?;
        let n_trains = self.counts(&spec.n, &format!("{field}.n"), least, Lists::Train)?;
        Ok(maps
            .iter()
            .flat_map(|map| {
                n_trains.iter().map(|&n_train| Point {
                    map: map.clone(),
                    n_test: n_test.value,
                    n_train,
                })
            })
            .collect())
    }

    /// A disturbance of the scenario, by name.
    fn under(
        &self,
        name: Option<&Spanned<String>>,
        field: String,
    ) -> Result<Option<String>, Failure> {
        let Some(name) = name else {
            return Ok(None);
        };
        if let Some(context) = self.context
            && !context.disturbances.iter().any(|(d, _)| *d == name.value)
        {
            let known: Vec<&str> = context
                .disturbances
                .iter()
                .map(|(d, _)| d.as_str())
                .collect();
            let problem = format!(
                "no disturbance {:?} in this scenario (its disturbances: {})",
                name.value,
                known.join(", ")
            );
            return Err(fail(name, field, problem));
        }
        Ok(Some(name.value.clone()))
    }

    /// Both policies at every (map, N), each beside its reference team of N - k, which must be
    /// in the scenario's counts too.
    fn adaptation(&self, spec: &AdaptationSpec) -> Result<ClaimTest, Failure> {
        let field = ".adapts_better";
        self.policy(&spec.a, format!("{field}.a"), false)?;
        self.policy(&spec.b, format!("{field}.b"), false)?;
        if spec.a.value == spec.b.value {
            let problem = "a and b are the same policy".to_owned();
            return Err(fail(&spec.b, format!("{field}.b"), problem));
        }
        let maps = self.names(&spec.maps, &format!("{field}.maps"))?;
        let learned = self.is_learned(&spec.a.value) || self.is_learned(&spec.b.value);
        let lists = if learned { Lists::Both } else { Lists::Test };
        let n = self.counts(&spec.n, &format!("{field}.n"), 1, lists)?;
        self.under(Some(&spec.disturbance), format!("{field}.disturbance"))?;
        let lost = match self.context {
            None => 0,
            Some(context) => {
                let lost = context
                    .disturbances
                    .iter()
                    .find(|(d, _)| *d == spec.disturbance.value)
                    .and_then(|(_, lost)| *lost);
                let Some(lost) = lost else {
                    let problem = format!(
                        "{:?} loses no fixed number of robots: an adaptation ratio needs one",
                        spec.disturbance.value
                    );
                    return Err(fail(
                        &spec.disturbance,
                        format!("{field}.disturbance"),
                        problem,
                    ));
                };
                for (i, count) in spec.n.value.iter().enumerate() {
                    let reference = Spanned::new(
                        count.value.saturating_sub(lost),
                        count.referenced,
                        count.defined,
                    );
                    // The same policy (training runs trained with N) plays the survivors' team.
                    let field = format!("{field}.n[{i}] (its team of survivors)");
                    self.count(&reference, field, false)?;
                }
                lost
            }
        };
        let points = points(&maps, &n, |n_test| n_test);
        Ok(ClaimTest::AdaptsBetter {
            a: spec.a.value.clone(),
            b: spec.b.value.clone(),
            disturbance: spec.disturbance.value.clone(),
            lost,
            points,
        })
    }

    fn tolerance(&self, spec: &PairSpec, field: &str) -> Result<Tolerance, Failure> {
        let value = match &spec.tolerance {
            Some(t) if t.value > 0.0 && t.value.is_finite() => t.value,
            Some(t) => return Err(fail(t, format!("{field}.tolerance"), "must be > 0".into())),
            None => return Err((None, field.into(), "needs a tolerance".into())),
        };
        let scale = match &spec.scale {
            None => Scale::B,
            Some(name) => Scale::parse(&name.value).ok_or_else(|| {
                let problem = format!(
                    "unknown scale {:?} (one of {})",
                    name.value,
                    Scale::NAMES.join(", ")
                );
                fail(name, format!("{field}.scale"), problem)
            })?,
        };
        if scale == Scale::Random
            && let Some(context) = self.context
            && !context.policies.iter().any(|(l, _)| l == RANDOM)
        {
            let name = spec.scale.as_ref().expect("a scale was given");
            let problem = "scale random needs the random baseline in the scenario".to_owned();
            return Err(fail(name, format!("{field}.scale"), problem));
        }
        Ok(Tolerance { value, scale })
    }

    fn diagonal(&self, spec: &DiagonalSpec) -> Result<ClaimTest, Failure> {
        self.policy(&spec.policy, ".diagonal_best.policy".into(), true)?;
        self.map(&spec.map, ".diagonal_best.map".into())?;
        let n = self.counts(&spec.n, ".diagonal_best.n", 2, Lists::Both)?;
        Ok(ClaimTest::DiagonalBest {
            policy: spec.policy.value.clone(),
            map: spec.map.value.clone(),
            n,
        })
    }

    fn curve(&self, spec: &CurveSpec) -> Result<ClaimTest, Failure> {
        self.policy(&spec.a, ".curve_below.a".into(), true)?;
        self.policy(&spec.b, ".curve_below.b".into(), true)?;
        self.map(&spec.map, ".curve_below.map".into())?;
        self.count(&spec.n_train, ".curve_below.n_train".into(), true)?;
        let [first, last] = spec.episodes.value;
        if first > last {
            let problem = format!("[{first}, {last}] is not a range of episodes");
            return Err(fail(
                &spec.episodes,
                ".curve_below.episodes".into(),
                problem,
            ));
        }
        Ok(ClaimTest::CurveBelow {
            a: spec.a.value.clone(),
            b: spec.b.value.clone(),
            map: spec.map.value.clone(),
            n_train: spec.n_train.value,
            episodes: (first, last),
        })
    }

    fn faster(&self, spec: &FasterSpec) -> Result<ClaimTest, Failure> {
        self.policy(&spec.a, ".faster.a".into(), true)?;
        self.policy(&spec.b, ".faster.b".into(), true)?;
        let reference = match &spec.reference {
            Some(reference) => {
                self.policy(reference, ".faster.reference".into(), false)?;
                reference.value.clone()
            }
            None => GCS.to_owned(),
        };
        let maps = self.names(&spec.maps, ".faster.maps")?;
        let n = self.counts(&spec.n, ".faster.n", 1, Lists::Both)?;
        let ratio = spec.ratio.value;
        if !(ratio > 0.0 && ratio.is_finite()) {
            let problem = format!("{ratio} must be finite and > 0");
            return Err(fail(&spec.ratio, ".faster.ratio".into(), problem));
        }
        Ok(ClaimTest::Faster {
            a: spec.a.value.clone(),
            b: spec.b.value.clone(),
            reference,
            points: points(&maps, &n, |n| n),
            ratio,
        })
    }

    fn behaviour(&self, spec: &BehaviourSpec) -> Result<ClaimTest, Failure> {
        self.policy(&spec.policy, ".behaviour.policy".into(), false)?;
        self.map(&spec.map, ".behaviour.map".into())?;
        self.count(&spec.n_test, ".behaviour.n_test".into(), false)?;
        let n_train = match &spec.n_train {
            Some(n) => {
                self.count(n, ".behaviour.n_train".into(), true)?;
                n.value
            }
            None if self.is_learned(&spec.policy.value) => {
                self.count(&spec.n_test, ".behaviour.n_test".into(), true)?;
                spec.n_test.value
            }
            None => spec.n_test.value,
        };
        let expected = Behaviour {
            stationary: spec.stationary,
            touring: spec.touring,
            periodic: spec.periodic,
            centred: spec.centred,
        };
        let counted = expected.stationary.unwrap_or(0) + expected.touring.unwrap_or(0);
        let without_a_role = expected.stationary == Some(0) || expected.touring == Some(0);
        let problem = if expected == Behaviour::default() {
            Some("give at least one of stationary, touring, periodic, centred".to_owned())
        } else if expected.centred == Some(true) && without_a_role {
            Some("centred: true needs a stationary and a touring agent".to_owned())
        } else if counted > spec.n_test.value as usize {
            Some(format!(
                "{counted} agents counted, but N_test is {}",
                spec.n_test.value
            ))
        } else {
            None
        };
        if let Some(problem) = problem {
            return Err(fail(&spec.policy, ".behaviour".into(), problem));
        }
        Ok(ClaimTest::Behaviour {
            policy: spec.policy.value.clone(),
            point: Point {
                map: spec.map.value.clone(),
                n_test: spec.n_test.value,
                n_train,
            },
            expected,
        })
    }

    fn is_learned(&self, label: &str) -> bool {
        self.context
            .is_some_and(|c| c.policies.iter().any(|(l, learned)| l == label && *learned))
    }

    fn policy(&self, label: &Spanned<String>, field: String, learned: bool) -> Result<(), Failure> {
        let Some(context) = self.context else {
            return Ok(());
        };
        match context.policies.iter().find(|(l, _)| *l == label.value) {
            None => {
                let known: Vec<&str> = context.policies.iter().map(|(l, _)| l.as_str()).collect();
                let problem = format!(
                    "no policy {:?} in this scenario (its policies: {}){}",
                    label.value,
                    known.join(", "),
                    moved_profile_hint(&label.value, &known)
                );
                Err(fail(label, field, problem))
            }
            Some((_, false)) if learned => {
                let problem = format!("{:?} is a baseline: it has no training", label.value);
                Err(fail(label, field, problem))
            }
            Some(_) => Ok(()),
        }
    }

    fn map(&self, name: &Spanned<String>, field: String) -> Result<(), Failure> {
        match self.context {
            Some(context) if !context.maps.contains(&name.value) => {
                let problem = format!(
                    "no map {:?} in this scenario (its maps: {})",
                    name.value,
                    context.maps.join(", ")
                );
                Err(fail(name, field, problem))
            }
            _ => Ok(()),
        }
    }

    fn names(
        &self,
        names: &Spanned<Vec<Spanned<String>>>,
        field: &str,
    ) -> Result<Vec<String>, Failure> {
        if names.value.is_empty() {
            return Err(fail(names, field.into(), "the list is empty".into()));
        }
        for (i, name) in names.value.iter().enumerate() {
            self.map(name, format!("{field}[{i}]"))?;
        }
        Ok(names.value.iter().map(|n| n.value.clone()).collect())
    }

    /// Agent counts, at least `least` of them, each in the scenario's `lists`.
    fn counts(
        &self,
        counts: &Spanned<Vec<Spanned<u32>>>,
        field: &str,
        least: usize,
        lists: Lists,
    ) -> Result<Vec<u32>, Failure> {
        if counts.value.len() < least {
            let problem = format!("needs at least {least} agent count(s)");
            return Err(fail(counts, field.into(), problem));
        }
        for (i, count) in counts.value.iter().enumerate() {
            if lists != Lists::Train {
                self.count(count, format!("{field}[{i}]"), false)?;
            }
            if lists != Lists::Test {
                self.count(count, format!("{field}[{i}]"), true)?;
            }
        }
        Ok(counts.value.iter().map(|n| n.value).collect())
    }

    /// `count` among the scenario's test counts, or its training counts when `trained`.
    fn count(&self, count: &Spanned<u32>, field: String, trained: bool) -> Result<(), Failure> {
        let Some(context) = self.context else {
            return Ok(());
        };
        let (list, name) = if trained {
            (&context.train_agents, "agents.train")
        } else {
            (&context.test_agents, "agents.test")
        };
        if list.contains(&count.value) {
            return Ok(());
        }
        let problem = format!("N = {} is not in {name} {list:?}", count.value);
        Err(fail(count, field, problem))
    }
}

/// Tables label a learned policy by its profile as keys write it, so `@fast` names the first
/// `fast` (fast-v1) for good, while `profile: fast` trains today's. A claim naming `X@fast`
/// where the scenario trains `X` with today's `fast` gets told which label that is.
fn moved_profile_hint(label: &str, known: &[&str]) -> String {
    let (first, today) = (Profile::FastV1.written(), Profile::FAST.written());
    let today_label = label
        .strip_suffix(first)
        .filter(|policy| policy.ends_with('@') && first != today)
        .map(|policy| format!("{policy}{today}"));
    match today_label {
        Some(today_label) if known.contains(&today_label.as_str()) => format!(
            "; `@{first}` labels the profile {} (the first `fast`), while `profile: fast` \
             trains {} today, labelled {today_label:?}",
            Profile::FastV1.name(),
            Profile::FAST.name()
        ),
        _ => String::new(),
    }
}
