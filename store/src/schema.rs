//! The column names of every store table, in one place: the writers (the store, the engine,
//! the report's behaviour replay) and the readers (the report, the audit, the marl-eval export,
//! the tests) name columns only through these constants, so a column renamed here is renamed
//! everywhere, and a constant removed is a compile error wherever a table still uses it.
//!
//! Each module is one table or one group of columns that several tables share, and its
//! `columns()` is the table's whole header in order (an end-to-end test holds every table a
//! sweep writes to it).

/// The columns that name a cell, first in every per-cell table; the summary keeps the map,
/// the policy and `n_train`.
pub mod cell {
    pub const KEY: &str = "cell_key";
    pub const MAP: &str = "map";
    /// The policy's label (`ma-g-ppo@fast-v2`, `gcs`).
    pub const POLICY: &str = "policy";
    /// The team size a learned policy trained with; null for a baseline.
    pub const N_TRAIN: &str = "n_train";
    pub const TRAINING_SEED: &str = "training_seed";

    pub const COLUMNS: [&str; 5] = [KEY, MAP, POLICY, N_TRAIN, TRAINING_SEED];
}

/// One test episode's columns: the `episodes` table is [`cell`] then these; the test curve and
/// the disturbed tables share its names.
pub mod episodes {
    pub const TABLE: &str = "episodes";
    /// The team size the episode was played with.
    pub const N_TEST: &str = "n_test";
    pub const EPISODE: &str = "episode";
    pub(crate) const TEST_SEED: &str = "test_seed";
    pub const CUMULATIVE_PENALTY: &str = "cumulative_penalty";
    pub const AVERAGE_IDLENESS: &str = "average_idleness";
    pub const WORST_IDLENESS: &str = "worst_idleness";
    pub const STEPS: &str = "steps";

    pub(crate) const EPISODE_COLUMNS: [&str; 7] = [
        N_TEST,
        EPISODE,
        TEST_SEED,
        CUMULATIVE_PENALTY,
        AVERAGE_IDLENESS,
        WORST_IDLENESS,
        STEPS,
    ];

    pub(crate) fn columns() -> Vec<&'static str> {
        [&super::cell::COLUMNS[..], &EPISODE_COLUMNS].concat()
    }
}

/// One row per finished cell: its resolved configuration, hashes and provenance.
pub mod cells {
    use super::cell;

    pub const TABLE: &str = "cells";
    pub(crate) const SCENARIO: &str = "scenario";
    pub(crate) const MAP_SOURCE: &str = "map_source";
    pub const MAP_HASH: &str = "map_hash";
    pub const REPETITION: &str = "repetition";
    /// The cell's configuration as JSON.
    pub const CONFIG: &str = "config";
    /// A learned cell's training configuration, resolved from profile and overrides, as JSON.
    pub const TRAINING_CONFIG: &str = "training_config";
    pub(crate) const EPISODES_HASH: &str = "episodes_hash";
    pub(crate) const WEIGHTS_HASH: &str = "weights_hash";
    pub(crate) const TRAINING_HASH: &str = "training_hash";
    pub(crate) const CODE_VERSION: &str = "code_version";
    pub const GIT_COMMIT: &str = "git_commit";
    pub(crate) const HOST: &str = "host";
    pub const CPU: &str = "cpu";
    pub const KERNELS: &str = "kernels";
    pub(crate) const STARTED: &str = "started";
    pub(crate) const FINISHED: &str = "finished";
    pub const WALL_SECONDS: &str = "wall_seconds";

    pub(crate) fn columns() -> Vec<&'static str> {
        vec![
            cell::KEY,
            SCENARIO,
            cell::MAP,
            MAP_SOURCE,
            MAP_HASH,
            cell::POLICY,
            cell::N_TRAIN,
            REPETITION,
            cell::TRAINING_SEED,
            CONFIG,
            TRAINING_CONFIG,
            EPISODES_HASH,
            WEIGHTS_HASH,
            TRAINING_HASH,
            CODE_VERSION,
            GIT_COMMIT,
            HOST,
            CPU,
            KERNELS,
            STARTED,
            FINISHED,
            WALL_SECONDS,
        ]
    }
}

/// A learned cell's training log, one row per training episode (the `training` table is
/// [`cell`] then [`training::LOG_COLUMNS`]).
pub mod training {
    pub const TABLE: &str = "training";
    pub const EPISODE: &str = "episode";
    /// The team size of the episode.
    pub const AGENTS: &str = "agents";
    /// The episode's cumulative penalty.
    pub const PENALTY: &str = "penalty";
    pub const LOSS: &str = "loss";
    pub const POLICY_LOSS: &str = "policy_loss";
    pub const VALUE_LOSS: &str = "value_loss";
    pub const ENTROPY: &str = "entropy";
    pub const ATTENTION_ENTROPY: &str = "attention_entropy";
    pub const APPROX_KL: &str = "approx_kl";
    pub const CLIP_FRACTION: &str = "clip_fraction";
    pub const GRAD_NORM: &str = "grad_norm";
    pub const LEARNING_RATE: &str = "learning_rate";
    pub const STEPS_PER_SECOND: &str = "steps_per_second";
    pub const ROLLOUT_SECONDS: &str = "rollout_seconds";
    pub const UPDATE_SECONDS: &str = "update_seconds";
    pub const WALL_SECONDS: &str = "wall_seconds";

    /// The columns that measure time: they differ between two runs of the same training,
    /// every other column is the same bit for bit.
    pub const TIMING_COLUMNS: [&str; 4] = [
        STEPS_PER_SECOND,
        ROLLOUT_SECONDS,
        UPDATE_SECONDS,
        WALL_SECONDS,
    ];

    pub const LOG_COLUMNS: [&str; 16] = [
        EPISODE,
        AGENTS,
        PENALTY,
        LOSS,
        POLICY_LOSS,
        VALUE_LOSS,
        ENTROPY,
        ATTENTION_ENTROPY,
        APPROX_KL,
        CLIP_FRACTION,
        GRAD_NORM,
        LEARNING_RATE,
        STEPS_PER_SECOND,
        ROLLOUT_SECONDS,
        UPDATE_SECONDS,
        WALL_SECONDS,
    ];

    pub(crate) fn columns() -> Vec<&'static str> {
        [&super::cell::COLUMNS[..], &LOG_COLUMNS].concat()
    }
}

/// The test curve: a learned cell's test episodes at every evaluation point of its training,
/// [`cell`], these, then [`episodes::EPISODE_COLUMNS`].
///
/// [`episodes::EPISODE_COLUMNS`]: super::episodes::EPISODE_COLUMNS
pub mod test_curve {
    pub const TABLE: &str = "test_curve";
    /// Training episodes done when the policy was tested.
    pub const TRAINING_EPISODE: &str = "training_episode";
    pub const CPU_SECONDS: &str = "cpu_seconds";
    pub const WALL_SECONDS: &str = "wall_seconds";

    const POINT_COLUMNS: [&str; 3] = [TRAINING_EPISODE, CPU_SECONDS, WALL_SECONDS];

    pub(crate) fn columns() -> Vec<&'static str> {
        [
            &super::cell::COLUMNS[..],
            &POINT_COLUMNS,
            &super::episodes::EPISODE_COLUMNS,
        ]
        .concat()
    }
}

/// The validation curve of a learned cell trained until converged: the mean penalty of its
/// validation episodes at every validation, [`cell`] then these.
pub mod validation {
    pub(crate) const TABLE: &str = "validation";
    pub use super::test_curve::{CPU_SECONDS, TRAINING_EPISODE, WALL_SECONDS};
    /// The mean cumulative penalty of the validation episodes.
    pub const VALIDATION_PENALTY: &str = "validation_penalty";

    const POINT_COLUMNS: [&str; 4] = [
        TRAINING_EPISODE,
        CPU_SECONDS,
        WALL_SECONDS,
        VALIDATION_PENALTY,
    ];

    pub(crate) fn columns() -> Vec<&'static str> {
        [&super::cell::COLUMNS[..], &POINT_COLUMNS].concat()
    }
}

/// Where a learned cell trained until converged stopped, and why: one row per cell,
/// [`cell`] then these.
pub mod convergence {
    pub const TABLE: &str = "convergence";
    /// Training episodes done at the stop.
    pub const STOP_EPISODE: &str = "stop_episode";
    /// `converged` (the rule stopped it) or `capped` (it reached its episodes first).
    pub const STOP: &str = "stop";
    pub const BEST_EPISODE: &str = "best_episode";
    pub const BEST_PENALTY: &str = "best_validation_penalty";
    pub const FINAL_PENALTY: &str = "final_validation_penalty";
    pub const VALIDATIONS: &str = "validations";
    /// Training CPU-seconds to the stop (validations not counted; `engine::test_curve`).
    pub const CPU_SECONDS: &str = "cpu_seconds";
    /// The checkpoint the cell's test episodes and claims use: `best` or `final`.
    pub const TESTED: &str = "tested";

    pub const CONVERGED: &str = "converged";
    pub const CAPPED: &str = "capped";

    const RUN_COLUMNS: [&str; 8] = [
        STOP_EPISODE,
        STOP,
        BEST_EPISODE,
        BEST_PENALTY,
        FINAL_PENALTY,
        VALIDATIONS,
        CPU_SECONDS,
        TESTED,
    ];

    pub(crate) fn columns() -> Vec<&'static str> {
        [&super::cell::COLUMNS[..], &RUN_COLUMNS].concat()
    }
}

/// Both policies of a learned cell trained until converged, tested on the cell's test
/// episodes: [`cell`], the checkpoint (`best` or `final`), then
/// [`episodes::EPISODE_COLUMNS`]. The tested one's rows are the episodes table's.
///
/// [`episodes::EPISODE_COLUMNS`]: super::episodes::EPISODE_COLUMNS
pub mod checkpoints {
    pub const TABLE: &str = "checkpoints";
    pub const CHECKPOINT: &str = "checkpoint";

    pub(crate) fn columns() -> Vec<&'static str> {
        [
            &super::cell::COLUMNS[..],
            &[CHECKPOINT],
            &super::episodes::EPISODE_COLUMNS,
        ]
        .concat()
    }
}

/// One row per (map, policy, N_train, N_test): the run-level statistics of the test episodes.
pub mod summary {
    use super::{cell, episodes};

    pub const TABLE: &str = "summary";
    /// Cells (training runs) in the group.
    pub const CELLS: &str = "cells";
    pub const EPISODES: &str = "episodes";
    pub const MEAN: &str = "mean";
    pub const STD: &str = "std";
    pub const MEDIAN: &str = "median";
    pub const IQM: &str = "iqm";
    pub const MEAN_CI_LOW: &str = "mean_ci_low";
    pub const MEAN_CI_HIGH: &str = "mean_ci_high";
    pub const IQM_CI_LOW: &str = "iqm_ci_low";
    pub const IQM_CI_HIGH: &str = "iqm_ci_high";
    pub const AVERAGE_IDLENESS_MEAN: &str = "average_idleness_mean";
    pub const AVERAGE_IDLENESS_CI_LOW: &str = "average_idleness_ci_low";
    pub const AVERAGE_IDLENESS_CI_HIGH: &str = "average_idleness_ci_high";
    pub const WORST_IDLENESS_MEAN: &str = "worst_idleness_mean";
    pub const WORST_IDLENESS_CI_LOW: &str = "worst_idleness_ci_low";
    pub const WORST_IDLENESS_CI_HIGH: &str = "worst_idleness_ci_high";

    pub(crate) fn columns() -> Vec<&'static str> {
        vec![
            cell::MAP,
            cell::POLICY,
            cell::N_TRAIN,
            episodes::N_TEST,
            CELLS,
            EPISODES,
            MEAN,
            STD,
            MEDIAN,
            IQM,
            MEAN_CI_LOW,
            MEAN_CI_HIGH,
            IQM_CI_LOW,
            IQM_CI_HIGH,
            AVERAGE_IDLENESS_MEAN,
            AVERAGE_IDLENESS_CI_LOW,
            AVERAGE_IDLENESS_CI_HIGH,
            WORST_IDLENESS_MEAN,
            WORST_IDLENESS_CI_LOW,
            WORST_IDLENESS_CI_HIGH,
        ]
    }
}

/// Every robot's cell at every step of the first test episodes of repetition 0.
pub mod trajectories {
    use super::{cell, episodes};

    pub const TABLE: &str = "trajectories";
    pub const STEP: &str = "step";
    pub const AGENT: &str = "agent";
    pub const X: &str = "x";
    pub const Y: &str = "y";
    /// The map's total penalty after the step.
    pub const PENALTY: &str = "penalty";

    pub(crate) fn columns() -> Vec<&'static str> {
        let own = [
            episodes::N_TEST,
            episodes::EPISODE,
            STEP,
            AGENT,
            X,
            Y,
            PENALTY,
        ];
        [&cell::COLUMNS[..], &own].concat()
    }
}

/// Maps seen at a few steps of the same episodes, one row per grid cell and layer.
pub mod snapshots {
    use super::{cell, episodes};

    pub const TABLE: &str = "snapshots";
    pub const STEP: &str = "step";
    /// One of [`layer`](super::layer).
    pub const LAYER: &str = "layer";
    pub const X: &str = "x";
    pub const Y: &str = "y";
    pub const VALUE: &str = "value";

    pub(crate) fn columns() -> Vec<&'static str> {
        let own = [
            episodes::N_TEST,
            episodes::EPISODE,
            STEP,
            LAYER,
            X,
            Y,
            VALUE,
        ];
        [&cell::COLUMNS[..], &own].concat()
    }
}

/// Layer names of the `snapshots` table.
pub mod layer {
    /// The whole map: a free cell's penalty (<= 0), obstacles 150.
    pub const PENALTY: &str = "penalty";
    /// Agent 0's local map, in the paper's codes (obstacle 150, agent 200).
    pub const LOCAL: &str = "local";
    /// Agent 0's mini-map, in the paper's codes.
    pub const MINI: &str = "mini";
}

/// A scenario with disturbances: one row per test episode, undisturbed (`none`) and under each
/// disturbance, with the adaptation measures.
pub mod disturbed {
    use super::{cell, episodes};

    pub const TABLE: &str = "disturbed";
    /// The disturbance's name, or `none` ([`plan::disturbance::UNDISTURBED`]).
    pub const DISTURBANCE: &str = "disturbance";
    /// The step after which robots were lost; null when none was.
    pub const EVENT: &str = "event";
    /// The lost robots' indices, space-separated.
    pub const LOST: &str = "lost";
    pub(crate) const PENALTY_BEFORE: &str = "penalty_before";
    pub(crate) const PENALTY_AFTER: &str = "penalty_after";
    pub const LAST_QUARTER: &str = "last_quarter";
    pub(crate) const SETTLE_STEPS: &str = "settle_steps";
    /// Robot cells `x,y` at the event and at the end, space-separated.
    pub const AT_EVENT: &str = "at_event";
    pub const AT_END: &str = "at_end";

    pub(crate) fn columns() -> Vec<&'static str> {
        let own = [
            episodes::N_TEST,
            episodes::EPISODE,
            episodes::TEST_SEED,
            DISTURBANCE,
            EVENT,
            LOST,
            episodes::CUMULATIVE_PENALTY,
            PENALTY_BEFORE,
            PENALTY_AFTER,
            LAST_QUARTER,
            SETTLE_STEPS,
            AT_EVENT,
            AT_END,
        ];
        [&cell::COLUMNS[..], &own].concat()
    }
}

/// Each disturbed-table episode's penalty curve, binned: one row per point.
pub mod disturbed_steps {
    use super::{cell, disturbed, episodes};

    pub const TABLE: &str = "disturbed_steps";
    pub const STEP: &str = "step";
    pub const PENALTY: &str = "penalty";

    pub(crate) fn columns() -> Vec<&'static str> {
        let own = [
            episodes::N_TEST,
            disturbed::DISTURBANCE,
            episodes::EPISODE,
            STEP,
            PENALTY,
        ];
        [&cell::COLUMNS[..], &own].concat()
    }
}

/// The columns that name a replayed test episode, first in every table of measures the
/// report's replay writes.
fn replayed_episode() -> [&'static str; 7] {
    [
        cell::MAP,
        cell::POLICY,
        cell::N_TRAIN,
        episodes::N_TEST,
        cell::KEY,
        cells::REPETITION,
        episodes::EPISODE,
    ]
}

/// The behaviour claims' measures of replayed test episodes (written by the report's replay).
pub mod behaviour_episodes {

    pub const TABLE: &str = "behaviour_episodes";
    /// The episode's stationary robots.
    pub const STATIONARY: &str = "stationary";
    /// The episode's touring robots.
    pub const TOURING: &str = "touring";
    /// Whether the team's motion is periodic.
    pub const PERIODIC: &str = "periodic";
    /// Whether every stationary robot kept nearer the map's centre than every touring one
    /// (on average over the episode); null without both roles, or in a table measured before
    /// the column existed.
    pub const CENTRED: &str = "centred";
    /// Which recorded episodes the roles were pooled with.
    pub const POOL: &str = "pool";

    pub(crate) fn columns() -> Vec<&'static str> {
        let own = [STATIONARY, TOURING, PERIODIC, CENTRED, POOL];
        [&super::replayed_episode()[..], &own].concat()
    }

    /// Columns that a table measured before they existed lacks (its reader reads them as
    /// null and writes them whole).
    pub(crate) fn added_later() -> Vec<&'static str> {
        vec![CENTRED]
    }
}

/// How long robots kept choosing a refused move in every learned run's test episodes at
/// N_test = N_train (written by the report's replay).
pub mod refusals {

    pub const TABLE: &str = "refusals";
    /// The most consecutive steps in which one robot's chosen move was refused by a wall (off
    /// the map or into an obstacle): a robot pressing against it.
    pub const LONGEST_WALL: &str = "longest_wall_refusal";
    /// Robot-steps whose move a wall refused, over the episode.
    pub const WALL_STEPS: &str = "wall_refused_steps";
    /// Robot-steps whose move another robot refused.
    pub const AGENT_STEPS: &str = "agent_refused_steps";
    /// The most consecutive steps in which one robot's chosen move was refused, by a wall or by
    /// another robot: a robot pressing against a wall, or two pressing against each other.
    pub const LONGEST_REFUSAL: &str = "longest_refusal";

    pub(crate) fn columns() -> Vec<&'static str> {
        let own = [LONGEST_WALL, WALL_STEPS, AGENT_STEPS, LONGEST_REFUSAL];
        [&super::replayed_episode()[..], &own].concat()
    }

    /// Measured after the table's first rows were committed.
    pub(crate) fn added_later() -> Vec<&'static str> {
        vec![LONGEST_REFUSAL]
    }
}

/// The columns of table `name` that a store written before they existed lacks: a reader takes
/// the table without them.
pub fn added_later(name: &str) -> Vec<&'static str> {
    match name {
        behaviour_episodes::TABLE => behaviour_episodes::added_later(),
        refusals::TABLE => refusals::added_later(),
        _ => Vec::new(),
    }
}

/// The header of the table stored as `NAME.parquet`; `None` for a name no table has.
pub fn columns_of(name: &str) -> Option<Vec<&'static str>> {
    Some(match name {
        cells::TABLE => cells::columns(),
        episodes::TABLE => episodes::columns(),
        training::TABLE => training::columns(),
        test_curve::TABLE => test_curve::columns(),
        validation::TABLE => validation::columns(),
        convergence::TABLE => convergence::columns(),
        checkpoints::TABLE => checkpoints::columns(),
        summary::TABLE => summary::columns(),
        trajectories::TABLE => trajectories::columns(),
        snapshots::TABLE => snapshots::columns(),
        disturbed::TABLE => disturbed::columns(),
        disturbed_steps::TABLE => disturbed_steps::columns(),
        behaviour_episodes::TABLE => behaviour_episodes::columns(),
        refusals::TABLE => refusals::columns(),
        _ => return None,
    })
}
