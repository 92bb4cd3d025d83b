//! A claim as checked: what it tests, at which points, against which tolerance; a leaf below
//! the check that builds claims from a scenario's text and the report that judges them.

/// One checked claim.
#[derive(Clone, Debug, PartialEq)]
pub struct Claim {
    pub id: String,
    /// The paper's words and numbers.
    pub paper: String,
    pub test: ClaimTest,
    /// The training episodes the statement assumes, when it names them: runs trained that
    /// many, or until converged, meet it.
    pub budget: Option<u64>,
}

/// What a claim asserts. Policies are table labels; points are (map, N_test) with an N_train
/// that applies to learned policies only (baselines have none).
#[derive(Clone, Debug, PartialEq)]
pub enum ClaimTest {
    Lower {
        pair: Pair,
    },
    Within {
        pair: Pair,
        tolerance: Tolerance,
    },
    NotWorse {
        pair: Pair,
        tolerance: Tolerance,
    },
    /// `scale`: the gaps are divided by b's mean at each point (`Scale::B`, a trend in the
    /// ratio a / b, for levels that fall with N), or taken as they are (`Scale::Absolute`).
    GapGrows {
        pair: Pair,
        scale: Scale,
    },
    /// Every run of the learned `a` below `b` (see `format::ClaimSpec::every_run_lower`).
    EveryRunLower {
        pair: Pair,
    },
    DiagonalBest {
        policy: String,
        map: String,
        n: Vec<u32>,
    },
    CurveBelow {
        a: String,
        b: String,
        map: String,
        n_train: u32,
        episodes: (u64, u64),
    },
    Behaviour {
        policy: String,
        point: Point,
        expected: Behaviour,
    },
    AdaptsBetter {
        a: String,
        b: String,
        disturbance: String,
        /// Robots the disturbance loses: each point's reference team has `n_test - lost`.
        lost: u32,
        points: Vec<Point>,
    },
    /// Time to quality (see `format::FasterSpec`); points are (map, N) with N_test = N_train.
    Faster {
        a: String,
        b: String,
        reference: String,
        points: Vec<Point>,
        ratio: f64,
    },
    /// The reason the store cannot test the statement.
    NotTested {
        reason: String,
    },
}

/// The label of the Random baseline, which `scale: random` measures tolerances by.
pub const RANDOM: &str = "random";

/// The label of the released GCS rule, the quality `faster` claims reach by default.
pub const GCS: &str = "gcs";

/// A tolerance and what it is relative to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    pub value: f64,
    pub scale: Scale,
}

/// What a tolerance is relative to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scale {
    /// b's mean penalty at the point.
    B,
    /// Random's mean penalty at the point (policy `random`): for a b near 0.
    Random,
    /// Penalty units (10^6).
    Absolute,
}

impl Scale {
    pub(crate) const NAMES: [&'static str; 3] = ["b", "random", "absolute"];

    pub(crate) fn parse(name: &str) -> Option<Scale> {
        match name {
            "b" => Some(Scale::B),
            "random" => Some(Scale::Random),
            "absolute" => Some(Scale::Absolute),
            _ => None,
        }
    }
}

/// What a behaviour claim expects; `None` leaves a feature untested.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Behaviour {
    pub stationary: Option<usize>,
    pub touring: Option<usize>,
    pub periodic: Option<bool>,
    /// Every stationary agent keeps nearer the map's centre than every touring one (the
    /// paper's "one agent at the centre ... the other three ... around the periphery").
    pub centred: Option<bool>,
}

impl ClaimTest {
    pub fn kind(&self) -> &'static str {
        match self {
            ClaimTest::Lower { .. } => "lower",
            ClaimTest::Within { .. } => "within",
            ClaimTest::NotWorse { .. } => "not_worse",
            ClaimTest::GapGrows { .. } => "gap_grows",
            ClaimTest::EveryRunLower { .. } => "every_run_lower",
            ClaimTest::DiagonalBest { .. } => "diagonal_best",
            ClaimTest::CurveBelow { .. } => "curve_below",
            ClaimTest::Behaviour { .. } => "behaviour",
            ClaimTest::AdaptsBetter { .. } => "adapts_better",
            ClaimTest::Faster { .. } => "faster",
            ClaimTest::NotTested { .. } => "not_tested",
        }
    }

    /// The policies (table labels) the claim compares, in the order written.
    pub fn policies(&self) -> Vec<&str> {
        match self {
            ClaimTest::Lower { pair }
            | ClaimTest::Within { pair, .. }
            | ClaimTest::NotWorse { pair, .. }
            | ClaimTest::GapGrows { pair, .. }
            | ClaimTest::EveryRunLower { pair } => vec![&pair.a, &pair.b],
            ClaimTest::DiagonalBest { policy, .. } | ClaimTest::Behaviour { policy, .. } => {
                vec![policy]
            }
            ClaimTest::CurveBelow { a, b, .. } | ClaimTest::AdaptsBetter { a, b, .. } => {
                vec![a, b]
            }
            ClaimTest::Faster {
                a, b, reference, ..
            } => vec![a, b, reference],
            ClaimTest::NotTested { .. } => Vec::new(),
        }
    }

    /// Where the claim's verdict rests on each policy's training: (policy, map, N_train) for
    /// every policy it compares at every point (a diagonal: at each N), policies in the order
    /// written. A `faster` claim's reference only sets the level, and is left out.
    pub fn trained_at(&self) -> Vec<(&str, &str, u32)> {
        match self {
            ClaimTest::Lower { pair }
            | ClaimTest::Within { pair, .. }
            | ClaimTest::NotWorse { pair, .. }
            | ClaimTest::GapGrows { pair, .. }
            | ClaimTest::EveryRunLower { pair } => policies_at([&pair.a, &pair.b], &pair.points),
            ClaimTest::AdaptsBetter { a, b, points, .. }
            | ClaimTest::Faster { a, b, points, .. } => policies_at([a, b], points),
            ClaimTest::DiagonalBest { policy, map, n } => {
                n.iter().map(|&n| (&**policy, &**map, n)).collect()
            }
            ClaimTest::CurveBelow {
                a, b, map, n_train, ..
            } => vec![(a, map, *n_train), (b, map, *n_train)],
            ClaimTest::Behaviour { policy, point, .. } => {
                vec![(policy, &point.map, point.n_train)]
            }
            ClaimTest::NotTested { .. } => Vec::new(),
        }
    }
}

/// Each of two policies at each point: (policy, map, N_train).
fn policies_at<'a>(policies: [&'a str; 2], points: &'a [Point]) -> Vec<(&'a str, &'a str, u32)> {
    (policies.iter())
        .flat_map(|&policy| points.iter().map(move |p| (policy, &*p.map, p.n_train)))
        .collect()
}

/// Two policies at a list of points, in the order written.
#[derive(Clone, Debug, PartialEq)]
pub struct Pair {
    pub a: String,
    pub b: String,
    /// The disturbance `a`'s (`b`'s) episodes were played under; `None`: undisturbed.
    pub a_under: Option<String>,
    pub b_under: Option<String>,
    pub points: Vec<Point>,
    /// The training episode the learned sides are taken at, from their test curves; `None`:
    /// after their whole training.
    pub at_episode: Option<u64>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Point {
    pub map: String,
    pub n_test: u32,
    /// N_train of a learned policy at this point: the claim's `n_train`, else N_test.
    pub n_train: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diagonal rests on its policy at every N, a curve on both policies at one N_train.
    #[test]
    fn a_claim_is_trained_at_each_policy_and_point_it_compares() {
        let diagonal = ClaimTest::DiagonalBest {
            policy: "g".into(),
            map: "open".into(),
            n: vec![2, 4, 10],
        };
        let at = diagonal.trained_at();
        assert_eq!(at, [("g", "open", 2), ("g", "open", 4), ("g", "open", 10)]);
        let curve = ClaimTest::CurveBelow {
            a: "g".into(),
            b: "p".into(),
            map: "four_room".into(),
            n_train: 2,
            episodes: (0, 400),
        };
        assert_eq!(
            curve.trained_at(),
            [("g", "four_room", 2), ("p", "four_room", 2)]
        );
        let not_tested = ClaimTest::NotTested {
            reason: "no store".into(),
        };
        assert!(not_tested.trained_at().is_empty());
    }
}
