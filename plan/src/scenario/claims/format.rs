//! Claims as written in a scenario's `claims:` list. Each names one kind by its key; the
//! checks in `claims::check` make sure there is exactly one and that it names the scenario's
//! own maps, policies and agent counts.

use serde::Deserialize;
use serde_saphyr::Spanned;

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ClaimSpec {
    /// Names the claim in verdict tables.
    pub(crate) id: String,
    /// The paper's words (and numbers) that the claim tests, shown beside the verdict.
    #[serde(default)]
    pub(crate) paper: String,
    /// `a` has a lower mean penalty than `b` at every point.
    pub(crate) lower: Option<PairSpec>,
    /// `a`'s mean penalty is within `tolerance` (relative to `b`'s) of `b`'s at every point.
    pub(crate) within: Option<PairSpec>,
    /// `a`'s mean penalty is at most `tolerance` (relative to `b`'s) above `b`'s at every point.
    pub(crate) not_worse: Option<PairSpec>,
    /// Every training run of the learned `a` has a mean penalty below `b`'s at every point:
    /// no run diverged or learned nothing (with `b: random`).
    pub(crate) every_run_lower: Option<PairSpec>,
    /// `b`'s penalty minus `a`'s grows along the points in the order `n` lists them (one map).
    pub(crate) gap_grows: Option<PairSpec>,
    /// In every N_test column of `n`, the policy trained with N_train = N_test is the best.
    pub(crate) diagonal_best: Option<DiagonalSpec>,
    /// `a`'s training penalty is below `b`'s over a range of episodes.
    pub(crate) curve_below: Option<CurveSpec>,
    /// What the recorded test episode of one setting shows (RQ3).
    pub(crate) behaviour: Option<BehaviourSpec>,
    /// `a`'s adaptation ratio under a loss is lower than `b`'s at every point.
    pub(crate) adapts_better: Option<AdaptationSpec>,
    /// `a`'s training reaches `reference`'s test penalty in at most `ratio` times the CPU
    /// `b`'s takes, at every point (time to quality, from the runs' test curves).
    pub(crate) faster: Option<FasterSpec>,
    /// A statement of the paper the store cannot test, with the reason: it stays in the
    /// verdict table as "not tested".
    pub(crate) not_tested: Option<Spanned<String>>,
    /// The training episodes the statement assumes: the paper's 30,000 on every statement
    /// about its trained policies, since every result it reports comes from such policies.
    /// Runs that trained fewer and were not trained until converged make it "not tested at
    /// this budget".
    #[serde(default)]
    pub(crate) budget: Option<Spanned<u64>>,
}

impl ClaimSpec {
    /// Each claim kind by its field's name, and whether this entry gives it, in the order
    /// "give exactly one of" names them. The pattern names every field, so a kind added to
    /// the struct and left out here does not compile.
    pub(crate) fn kinds(&self) -> [(&'static str, bool); 11] {
        let ClaimSpec {
            id: _,
            paper: _,
            budget: _,
            lower,
            within,
            not_worse,
            every_run_lower,
            gap_grows,
            diagonal_best,
            curve_below,
            behaviour,
            adapts_better,
            faster,
            not_tested,
        } = self;
        [
            ("lower", lower.is_some()),
            ("within", within.is_some()),
            ("not_worse", not_worse.is_some()),
            ("gap_grows", gap_grows.is_some()),
            ("every_run_lower", every_run_lower.is_some()),
            ("diagonal_best", diagonal_best.is_some()),
            ("curve_below", curve_below.is_some()),
            ("behaviour", behaviour.is_some()),
            ("adapts_better", adapts_better.is_some()),
            ("faster", faster.is_some()),
            ("not_tested", not_tested.is_some()),
        ]
    }
}

/// Two policies compared at the points (map, N_test = n): a learned policy is taken at
/// N_train = `n_train` when given, else at N_train = N_test.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PairSpec {
    pub(crate) a: Spanned<String>,
    pub(crate) b: Spanned<String>,
    pub(crate) maps: Spanned<Vec<Spanned<String>>>,
    pub(crate) n: Spanned<Vec<Spanned<u32>>>,
    #[serde(default)]
    pub(crate) n_train: Option<Spanned<u32>>,
    /// One N_test column: `n` then lists the learned policies' N_train (RQ5's generalisation
    /// gap at a fixed team size).
    #[serde(default)]
    pub(crate) n_test: Option<Spanned<u32>>,
    /// For `within`: the largest |a - b| still called equal; for `not_worse`: the largest
    /// a - b still called not worse; both in units of `scale`.
    #[serde(default)]
    pub(crate) tolerance: Option<Spanned<f64>>,
    /// What the tolerance is relative to: `b` (b's mean, the default: for penalties far from
    /// 0), `random` (Random's mean at the point: where b is near 0) or `absolute` (10^6).
    /// For `gap_grows`, what each gap is divided by: `absolute` (the default) or `b`, so that
    /// a trend in the ratio a / b is not mistaken for the fall of every penalty with N.
    #[serde(default)]
    pub(crate) scale: Option<Spanned<String>>,
    /// Take `a`'s (`b`'s) test episodes as played under this disturbance of the scenario.
    #[serde(default)]
    pub(crate) a_under: Option<Spanned<String>>,
    #[serde(default)]
    pub(crate) b_under: Option<Spanned<String>>,
    /// Judge the learned policies after this many training episodes, from their test curves
    /// (`evaluate_every`; at each run's first point at or after it), not after their whole
    /// training. Baselines do not train: their test episodes serve as they are.
    #[serde(default)]
    pub(crate) at_episode: Option<Spanned<u64>>,
}

/// Two policies' adaptation ratios under a disturbance that loses robots, at (map, N): the
/// mean last-quarter penalty of the team of N that lost k, over that of the same policy (for
/// a learned one, the same training runs) playing undisturbed with N - k; lower is better.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct AdaptationSpec {
    pub(crate) a: Spanned<String>,
    pub(crate) b: Spanned<String>,
    pub(crate) disturbance: Spanned<String>,
    pub(crate) maps: Spanned<Vec<Spanned<String>>>,
    pub(crate) n: Spanned<Vec<Spanned<u32>>>,
}

/// Two learned policies' time to quality at (map, N): a training run's CPU-seconds until its
/// test curve (`evaluate_every`) first reaches the mean test penalty of the baseline
/// `reference` (`gcs` when left out) with N agents; the policies are trained with N_train = N
/// and their curves play N_test = N.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FasterSpec {
    pub(crate) a: Spanned<String>,
    pub(crate) b: Spanned<String>,
    #[serde(default)]
    pub(crate) reference: Option<Spanned<String>>,
    pub(crate) maps: Spanned<Vec<Spanned<String>>>,
    pub(crate) n: Spanned<Vec<Spanned<u32>>>,
    /// The largest ratio of the runs' median times (a over b) still called faster: 1 for
    /// "faster", 1/3 for "in a third of the CPU".
    pub(crate) ratio: Spanned<f64>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct DiagonalSpec {
    pub(crate) policy: Spanned<String>,
    pub(crate) map: Spanned<String>,
    pub(crate) n: Spanned<Vec<Spanned<u32>>>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CurveSpec {
    pub(crate) a: Spanned<String>,
    pub(crate) b: Spanned<String>,
    pub(crate) map: Spanned<String>,
    pub(crate) n_train: Spanned<u32>,
    /// `[first, last]`: training episodes as the training table numbers them (from 0), both
    /// included.
    pub(crate) episodes: Spanned<[u64; 2]>,
}

/// The test episodes of `policy` on `map` with `n_test` agents (trained with `n_train`,
/// default N_test): how many agents stay and how many tour (the report's roles), and whether
/// the touring agents share a period with stable phases.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct BehaviourSpec {
    pub(crate) policy: Spanned<String>,
    pub(crate) map: Spanned<String>,
    pub(crate) n_test: Spanned<u32>,
    #[serde(default)]
    pub(crate) n_train: Option<Spanned<u32>>,
    #[serde(default)]
    pub(crate) stationary: Option<usize>,
    #[serde(default)]
    pub(crate) touring: Option<usize>,
    #[serde(default)]
    pub(crate) periodic: Option<bool>,
    #[serde(default)]
    pub(crate) centred: Option<bool>,
}

/// A scenario file read for its claims alone (the store's copy, whose maps may not resolve).
#[derive(Debug, Deserialize)]
pub(crate) struct ClaimsOnly {
    #[serde(default)]
    pub(crate) claims: Vec<Spanned<ClaimSpec>>,
}
