//! The scenario file as written: YAML mapped onto these types by serde, unknown keys refused.
//!
//! Values that need a check beyond their type carry their location (`Spanned`), so that the
//! checks in `scenario::check` can name the line. Defaults are the paper's values.

use std::collections::BTreeMap;

use learning::ppo::Profile;
use serde::{Deserialize, Serialize};
use serde_saphyr::{Location, Spanned};

use super::stopping::{StoppingRule, Until};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ScenarioFile {
    /// Names the sweep: the default output folder and the `scenario` column.
    pub(crate) name: Spanned<String>,
    /// Checked as text and otherwise unread here: the store's copy of the file is read for it.
    #[serde(default, rename = "description")]
    _description: String,
    pub(crate) maps: Spanned<Vec<Spanned<MapSpec>>>,
    #[serde(default)]
    pub(crate) world: WorldSpec,
    pub(crate) policies: Spanned<Vec<Spanned<PolicySpec<ProfileName>>>>,
    pub(crate) agents: AgentsSpec,
    /// Root of the scenario's seed tree.
    pub(crate) seed: u64,
    /// Training runs per (map, policy, N_train), each with its own training seed.
    #[serde(default = "one")]
    pub(crate) repetitions: Spanned<u32>,
    /// Test episodes per (cell, N_test).
    pub(crate) test_episodes: Spanned<u32>,
    /// The sweep-level tables to build; the per-cell results are always kept.
    #[serde(default = "Output::all")]
    pub(crate) outputs: Spanned<Vec<Output>>,
    /// Disturbances every cell's test episodes are also played under (`crate::disturbance`).
    #[serde(default = "nothing")]
    pub(crate) disturbances: Spanned<Vec<Spanned<DisturbanceSpec>>>,
    /// The paper's statements this experiment tests (`claims::format::ClaimSpec`).
    #[serde(default)]
    pub(crate) claims: Vec<Spanned<crate::scenario::claims::format::ClaimSpec>>,
    /// The verdicts of an earlier answer to the question (`scenario::earlier`).
    #[serde(default)]
    pub(crate) earlier: Option<Spanned<crate::scenario::earlier::EarlierSpec>>,
}

/// A map by file (relative to the scenario file; `FILE#NAME` picks a polygon map) or inline.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
pub(crate) enum MapSpec {
    File(String),
    Inline { name: String, grid: String },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct WorldSpec {
    /// Side L of the field of view.
    #[serde(default = "paper_fov")]
    pub(crate) fov: Spanned<usize>,
    #[serde(default = "paper_decay")]
    pub(crate) decay: Spanned<f32>,
    #[serde(default = "paper_rmax")]
    pub(crate) rmax: Spanned<f32>,
    /// Steps per training episode (T = 1000 in the paper).
    #[serde(default = "paper_train_steps")]
    pub(crate) train_steps: Spanned<u32>,
    /// Steps per test episode (T = 2000 in the paper).
    #[serde(default = "paper_test_steps")]
    pub(crate) test_steps: Spanned<u32>,
}

impl Default for WorldSpec {
    fn default() -> Self {
        Self {
            fov: paper_fov(),
            decay: paper_decay(),
            rmax: paper_rmax(),
            train_steps: paper_train_steps(),
            test_steps: paper_test_steps(),
        }
    }
}

/// Agent counts: every learned policy is trained with each `train` count and every cell is
/// tested with each `test` count. Baselines do not train, so `train` may be left out when
/// there is no learned policy.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct AgentsSpec {
    #[serde(default = "nothing")]
    pub(crate) train: Spanned<Vec<Spanned<u32>>>,
    pub(crate) test: Spanned<Vec<Spanned<u32>>>,
}

/// A disturbance by name: robots lost after a step, links cut, or both.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct DisturbanceSpec {
    pub(crate) name: Spanned<String>,
    #[serde(default)]
    pub(crate) lose: Option<Spanned<LoseSpec>>,
    #[serde(default)]
    pub(crate) links: Option<Spanned<LinksSpec>>,
}

/// `robots` (how many, drawn per episode) or `which` (by index), lost after step `at`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LoseSpec {
    #[serde(default)]
    pub(crate) robots: Option<Spanned<u32>>,
    #[serde(default)]
    pub(crate) which: Option<Spanned<Vec<u32>>>,
    pub(crate) at: Spanned<u32>,
}

/// Messages only within `radius` cells, and/or each link down with probability `drop` per
/// step.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LinksSpec {
    #[serde(default)]
    pub(crate) radius: Option<Spanned<f64>>,
    #[serde(default)]
    pub(crate) drop: Option<Spanned<f64>>,
}

/// One policy of the sweep: a baseline by name, or a learned architecture with its training.
///
/// `P` is how the profile is written: by the user's name in a scenario file
/// ([`ProfileName`]), by its own serialised form in a cell's key ([`Profile`]), since `fast`
/// in a file means today's default while `"fast"` in a key is the profile it was.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(
    deny_unknown_fields,
    rename_all = "kebab-case",
    bound(deserialize = "P: Deserialize<'de> + Default")
)]
pub(crate) enum PolicySpec<P = Profile> {
    Baseline(BaselineSpec),
    #[serde(rename = "ma-g-ppo")]
    MaGPpo(LearnedSpec<P>),
    MaPpo(LearnedSpec<P>),
}

/// A profile as a scenario file names it: `paper` (the default), `fast`, `fast-v1` or `fast-v2`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct ProfileName(Profile);

impl<'de> Deserialize<'de> for ProfileName {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        Profile::named(&name)
            .map(ProfileName)
            .map_err(serde::de::Error::custom)
    }
}

impl PolicySpec<ProfileName> {
    /// The policy as its cells' keys write it.
    pub(crate) fn resolved(self) -> PolicySpec {
        let resolve = |spec: LearnedSpec<ProfileName>| LearnedSpec {
            profile: spec.profile.0,
            name: spec.name,
            channels: spec.channels,
            episodes: spec.episodes,
            set: spec.set,
            test_actions: spec.test_actions,
            evaluate_every: spec.evaluate_every,
            until: spec.until,
            stopping: spec.stopping,
        };
        match self {
            PolicySpec::Baseline(baseline) => PolicySpec::Baseline(baseline),
            PolicySpec::MaGPpo(spec) => PolicySpec::MaGPpo(resolve(spec)),
            PolicySpec::MaPpo(spec) => PolicySpec::MaPpo(resolve(spec)),
        }
    }
}

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct BaselineSpec {
    pub(crate) name: String,
}

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LearnedSpec<P = Profile> {
    /// The policy's name in tables, when the default (the architecture with its non-default
    /// channels and profile) does not tell two of a scenario's policies apart.
    #[serde(default)]
    pub(crate) name: Option<String>,
    /// The named set of training hyper-parameters the run starts from: `paper` (the released
    /// code's), `fast` (our default), `fast-v1` (our first) or `fast-v2` (one episode per
    /// update, the profile study's winner).
    #[serde(default)]
    pub(crate) profile: P,
    /// The images the policy sees: `[local, mini]` (the paper's full model), `[local]` or
    /// `[mini]` (RQ2).
    #[serde(default = "both_channels")]
    pub(crate) channels: Vec<Channel>,
    /// Training episodes.
    pub(crate) episodes: u32,
    /// Any other field of the training configuration (as `harness train --set`), e.g.
    /// `{learning_rate: 1.0e-4, network: compact}`; the scenario's own fields (agents,
    /// episodes, steps, channels, architecture) are set elsewhere.
    #[serde(default)]
    pub(crate) set: BTreeMap<String, serde_json::Value>,
    /// How test episodes pick actions: `sampled` (the paper) or `greedy`.
    #[serde(default)]
    pub(crate) test_actions: TestActions,
    /// Play the cell's test episodes at N_train before training and after every this many
    /// training episodes (and at the end): the learning curve in test units, the table
    /// `test_curve`. Absent (the default, and left out of the key): no curve.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) evaluate_every: Option<u32>,
    /// `converged`: train until the validation penalty stops improving (`stopping`), with
    /// `episodes` as the cap; `episodes` (the default, left out of the key): exactly
    /// `episodes`.
    #[serde(default, skip_serializing_if = "Until::is_episodes")]
    pub(crate) until: Until,
    /// The stopping rule's values under `until: converged` (`scenario::stopping`); the
    /// defaults where left out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) stopping: Option<StoppingRule>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum TestActions {
    #[default]
    Sampled,
    Greedy,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum Channel {
    Local,
    Mini,
}

/// The sweep-level tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Output {
    Episodes,
    Training,
    Cells,
    Summary,
    Trajectories,
    Snapshots,
    /// Only cells with disturbances have these.
    Disturbed,
    DisturbedSteps,
    /// Only learned cells with `evaluate_every` have it.
    TestCurve,
    /// Only learned cells trained `until: converged` have these.
    Validation,
    Convergence,
    Checkpoints,
}

impl Output {
    pub const ALL: [Output; 12] = [
        Output::Episodes,
        Output::Training,
        Output::Cells,
        Output::Summary,
        Output::Trajectories,
        Output::Snapshots,
        Output::Disturbed,
        Output::DisturbedSteps,
        Output::TestCurve,
        Output::Validation,
        Output::Convergence,
        Output::Checkpoints,
    ];

    /// The table's file name, without extension.
    pub fn name(self) -> &'static str {
        match self {
            Output::Episodes => "episodes",
            Output::Training => "training",
            Output::Cells => "cells",
            Output::Summary => "summary",
            Output::Trajectories => "trajectories",
            Output::Snapshots => "snapshots",
            Output::Disturbed => "disturbed",
            Output::DisturbedSteps => "disturbed_steps",
            Output::TestCurve => "test_curve",
            Output::Validation => "validation",
            Output::Convergence => "convergence",
            Output::Checkpoints => "checkpoints",
        }
    }

    fn all() -> Spanned<Vec<Output>> {
        unplaced(Self::ALL.to_vec())
    }
}

/// A default value, which has no place in the file.
fn unplaced<T>(value: T) -> Spanned<T> {
    Spanned::new(value, Location::UNKNOWN, Location::UNKNOWN)
}

fn one() -> Spanned<u32> {
    unplaced(1)
}

fn nothing<T>() -> Spanned<Vec<T>> {
    unplaced(Vec::new())
}

fn paper_fov() -> Spanned<usize> {
    unplaced(world::params::PAPER_FOV)
}

fn paper_decay() -> Spanned<f32> {
    unplaced(world::params::PAPER_DECAY)
}

fn paper_rmax() -> Spanned<f32> {
    unplaced(world::params::PAPER_RMAX)
}

fn paper_train_steps() -> Spanned<u32> {
    unplaced(1000)
}

fn paper_test_steps() -> Spanned<u32> {
    unplaced(2000)
}

fn both_channels() -> Vec<Channel> {
    vec![Channel::Local, Channel::Mini]
}
