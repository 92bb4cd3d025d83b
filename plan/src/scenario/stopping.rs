//! Training until converged: the stopping rule a learned policy may name (`until: converged`),
//! and which of the run's two policies its tests and claims use.
//!
//! The rule watches **validation episodes**, played at N_train with their own branch of the
//! scenario's seed tree (never a test episode's seed), every `validate_every` training
//! episodes. A run stops when its best validation penalty has not improved by
//! `min_improvement` (relative) over the last `patience` validations, or at the cap (the
//! policy's `episodes`). The stop depends on validation penalties alone, never on time, so a
//! run stops at the same episode with the same bits on every machine.
//!
//! The learning rate does not anneal under this rule: a schedule over the cap (fast profiles
//! anneal linearly to 0 at `episodes`) would make every update depend on the cap, so a run
//! capped at 2,000 episodes would not be the first 2,000 episodes of one capped at 4,000,
//! and the cap would decide where the run converges. It is constant, or halves every
//! `learning_rate_half_life` episodes, a decay that does not know the cap.

use serde::{Deserialize, Serialize};

/// Which of a converged run's policies a cell tests for its claims. Both are tested; the
/// other is kept in the cell's `checkpoints` table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Checkpoint {
    /// The weights with the lowest validation penalty (the evaluation protocol of
    /// Gorsane et al. 2022, as marl-eval and Mava report it).
    #[default]
    Best,
    /// The weights at the stop.
    Final,
}

impl Checkpoint {
    pub const ALL: [Checkpoint; 2] = [Checkpoint::Best, Checkpoint::Final];

    pub fn name(self) -> &'static str {
        match self {
            Checkpoint::Best => "best",
            Checkpoint::Final => "final",
        }
    }
}

/// The stopping rule's values, each part of the cell's key (written in full, so that a
/// default changed later cannot give an old key new results).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoppingRule {
    /// Training episodes between two validations (one also before training).
    #[serde(default = "defaults::validate_every")]
    pub validate_every: u32,
    /// Episodes per validation, at N_train, each `test_steps` long.
    #[serde(default = "defaults::validation_episodes")]
    pub validation_episodes: u32,
    /// Validations without a large enough improvement before the run stops.
    #[serde(default = "defaults::patience")]
    pub patience: u32,
    /// The relative improvement of the best validation penalty that counts (0.02: 2 %).
    #[serde(default = "defaults::min_improvement")]
    pub min_improvement: f64,
    /// Whether the patience count waits for the run to learn: it starts only once a
    /// validation has improved on the first one (the untrained policy's) by
    /// `min_improvement`, so a run that never learns trains to its cap and is counted
    /// capped, instead of "converging" on its initial weights (one run of the profile
    /// study did, at its sixth validation). Left out of the key when false, the rule's
    /// first form, so that the keys of runs under it hold.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub wait_for_improvement: bool,
    /// The policy the cell's test episodes and claims use.
    #[serde(default)]
    pub tested: Checkpoint,
}

mod defaults {
    pub(super) fn validate_every() -> u32 {
        50
    }
    pub(super) fn validation_episodes() -> u32 {
        4
    }
    pub(super) fn patience() -> u32 {
        6
    }
    pub(super) fn min_improvement() -> f64 {
        0.02
    }
}

impl Default for StoppingRule {
    fn default() -> Self {
        StoppingRule {
            validate_every: defaults::validate_every(),
            validation_episodes: defaults::validation_episodes(),
            patience: defaults::patience(),
            min_improvement: defaults::min_improvement(),
            wait_for_improvement: false,
            tested: Checkpoint::Best,
        }
    }
}

/// A rule no run could follow, naming the field.
#[derive(Debug, thiserror::Error)]
#[error("stopping.{field}: {reason}")]
pub(crate) struct StoppingError {
    field: &'static str,
    reason: String,
}

impl StoppingRule {
    pub(crate) fn check(&self) -> Result<(), StoppingError> {
        let positive = [
            ("validate_every", self.validate_every),
            ("validation_episodes", self.validation_episodes),
            ("patience", self.patience),
        ];
        if let Some((field, _)) = positive.iter().find(|(_, value)| *value == 0) {
            let reason = "must be at least 1".to_owned();
            return Err(StoppingError { field, reason });
        }
        if !(0.0..1.0).contains(&self.min_improvement) {
            let reason = format!("{} is not in [0, 1)", self.min_improvement);
            let field = "min_improvement";
            return Err(StoppingError { field, reason });
        }
        Ok(())
    }
}

/// Whether a learned policy trains a fixed number of episodes or until converged.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum Until {
    /// Exactly `episodes` (the default, left out of the key).
    #[default]
    Episodes,
    /// Until the stopping rule says so, with `episodes` as the cap.
    Converged,
}

impl Until {
    pub(crate) fn is_episodes(&self) -> bool {
        *self == Until::Episodes
    }
}

/// How many rounds of evaluation a run of `episodes` training episodes plays, one every
/// `every` episodes (its test curve's, `test_curve`, or its validations): before training,
/// after every `every` episodes and at the end (at most; rounds may merge two).
pub fn plays(episodes: u64, every: u64) -> u64 {
    episodes.div_ceil(every.max(1)) + 1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rule_reads_with_defaults_and_refuses_what_no_run_could_follow() {
        let rule: StoppingRule = serde_json::from_str(r#"{"patience": 3}"#).unwrap();
        assert_eq!(
            rule,
            StoppingRule {
                patience: 3,
                ..StoppingRule::default()
            }
        );
        rule.check().unwrap();
        // The waiting is written only where it is asked for: the rule's first keys hold.
        assert!(!serde_json::to_string(&rule).unwrap().contains("wait"));
        let waiting: StoppingRule =
            serde_json::from_str(r#"{"wait_for_improvement": true}"#).unwrap();
        let written = serde_json::to_string(&waiting).unwrap();
        assert!(
            written.contains(r#""wait_for_improvement":true"#),
            "{written}"
        );
        let unknown = serde_json::from_str::<StoppingRule>(r#"{"patiense": 3}"#);
        assert!(unknown.unwrap_err().to_string().contains("patiense"));
        for (json, field) in [
            (r#"{"patience": 0}"#, "stopping.patience"),
            (r#"{"validate_every": 0}"#, "stopping.validate_every"),
            (r#"{"min_improvement": 1.5}"#, "stopping.min_improvement"),
            (r#"{"min_improvement": -0.1}"#, "stopping.min_improvement"),
        ] {
            let rule: StoppingRule = serde_json::from_str(json).unwrap();
            let error = rule.check().unwrap_err().to_string();
            assert!(error.starts_with(field), "{error}");
        }
        // At most: before training, at every multiple of validate_every, and at the cap.
        let every = u64::from(StoppingRule::default().validate_every);
        assert_eq!(plays(1000, every), 21);
    }
}
