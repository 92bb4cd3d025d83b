//! Claims: the paper's statements written so that a sweep's store can test them. A scenario
//! lists them under `claims:`; they are checked at load against its maps, policies and agent
//! counts, and the report (`report::verdicts`, also behind `harness claims DIR`) gives each a
//! verdict with the numbers behind it.
//!
//! Verdicts rest on 95 % bootstrap intervals whose unit is a learned policy's training run
//! (`stats::resampling`): **supported** when every point's interval excludes the opposite of
//! the claim, **contradicted** when Holm's correction over the points finds one whose interval
//! excludes the claim, **inconclusive** otherwise, **not tested** where the statement names a
//! training budget (the paper's 30,000 episodes, for a statement about its trained policies)
//! that the runs neither trained nor were trained until converged.

mod check;
mod claim;
pub(crate) mod format;

use std::path::Path;

pub(crate) use check::{ClaimContext, check_claims};
pub use claim::{Behaviour, Claim, ClaimTest, GCS, Pair, Point, RANDOM, Scale, Tolerance};

use crate::scenario::ScenarioError;

/// The claims of a scenario's text, checked for their own shape only: the store's copy of a
/// scenario whose maps and policies were checked when the sweep loaded it.
pub fn claims_of_text(text: &str, file: &Path) -> Result<Vec<Claim>, ScenarioError> {
    let spec: format::ClaimsOnly = crate::scenario::yaml::from_yaml(text, file)?;
    check_claims(&spec.claims, None, file)
}
