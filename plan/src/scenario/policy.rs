//! A scenario's policies once checked: a baseline that exists, or a learned architecture with
//! its channels in canonical form. Cells carry these, and nothing after the load reads the
//! file's `PolicySpec` again.
//!
//! A cell's key is the JSON of its config, so a checked policy is written and read as the
//! file's spec: the keys of cells computed when cells held the spec itself stay valid, and a
//! stored record is checked again as it is read back.

use std::collections::BTreeMap;

use baselines::{Baseline, UnknownBaseline};
use learning::ActionChoice;
use learning::ppo::{AgentCount, ArchitectureName, ConfigError, Profile, TrainingConfig};
use serde::{Deserialize, Serialize};
use world::Channels;

use super::WorldConfig;
use super::format::{BaselineSpec, Channel, LearnedSpec, PolicySpec, TestActions};
use super::stopping::{StoppingError, StoppingRule, Until};

/// One policy of a sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(into = "PolicySpec", try_from = "PolicySpec")]
pub enum ScenarioPolicy {
    Baseline(Baseline),
    Learned(Learned),
}

/// A learned policy: its architecture and what its training starts from.
#[derive(Clone, Debug, PartialEq)]
pub struct Learned {
    pub(crate) architecture: ArchitectureName,
    /// The name in tables, when the scenario gives one.
    name: Option<String>,
    profile: Profile,
    channels: Channels,
    pub(crate) episodes: u32,
    /// Training fields beyond the profile, none of them a field the scenario sets itself;
    /// checked against every N_train and map when the scenario is loaded.
    set: BTreeMap<String, serde_json::Value>,
    pub test_actions: ActionChoice,
    /// Training episodes between two plays of the test episodes (`test_curve`), if any.
    pub evaluate_every: Option<u32>,
    /// Train until converged by this rule, `episodes` being the cap; `None`: train exactly
    /// `episodes`.
    pub stopping: Option<StoppingRule>,
}

#[derive(Debug, thiserror::Error)]
pub(crate) enum PolicyError {
    #[error(transparent)]
    UnknownBaseline(#[from] UnknownBaseline),
    #[error("episodes must be at least 1")]
    NoEpisodes,
    #[error("evaluate_every must be at least 1 (leave it out for no test curve)")]
    NoEvaluation,
    #[error("channels is empty (use [local, mini], [local] or [mini])")]
    NoChannels,
    #[error("channels lists one channel twice")]
    ChannelTwice,
    #[error("stopping is given but until is not `converged`")]
    StoppingUnused,
    #[error(transparent)]
    Stopping(#[from] StoppingError),
    #[error(
        "set.anneal_learning_rate: a run until converged keeps its learning rate constant (a \
         schedule over the cap would make the run depend on its cap)"
    )]
    AnnealedUntilConverged,
    #[error(
        "set.{0}: the scenario sets this itself (agents.train, episodes, world.train_steps, \
         channels, the policy's kind and profile)"
    )]
    OwnField(String),
    /// A play due between two updates: a run trains in rounds of `environments` episodes
    /// and stops only between them, so the play would fall at the round's end instead.
    #[error(
        "{field}: {every} is not a multiple of the {environments} episodes a round trains \
         (the profile's environments, or set.environments): plays fall between rounds, so \
         they would be at other episodes than asked"
    )]
    OffRound {
        field: &'static str,
        every: u32,
        environments: u64,
    },
}

/// The training field that `until: converged` sets to false.
const ANNEAL: &str = "anneal_learning_rate";

/// The training fields a scenario sets through its own keys, which `set` may not name.
const OWN_FIELDS: [&str; 6] = [
    "architecture",
    "channels",
    "episodes",
    "steps_per_episode",
    "agents",
    "profile",
];

impl ScenarioPolicy {
    /// The name in tables: the baseline's name, or the architecture with its non-default
    /// channels and profile (`ma-g-ppo`, `ma-g-ppo[mini]`, `ma-ppo@fast`), or the name given.
    pub fn label(&self) -> String {
        match self {
            ScenarioPolicy::Baseline(baseline) => baseline.name().to_owned(),
            ScenarioPolicy::Learned(learned) => learned.label(),
        }
    }

    pub fn learned(&self) -> Option<&Learned> {
        match self {
            ScenarioPolicy::Baseline(_) => None,
            ScenarioPolicy::Learned(learned) => Some(learned),
        }
    }
}

impl Learned {
    fn label(&self) -> String {
        if let Some(name) = &self.name {
            return name.clone();
        }
        let mut label = match self.architecture {
            ArchitectureName::MaGPpo => "ma-g-ppo",
            ArchitectureName::MaPpo => "ma-ppo",
        }
        .to_owned();
        label += match self.channels {
            Channels::Both => "",
            Channels::Local => "[local]",
            Channels::Mini => "[mini]",
        };
        // As the key writes the profile (fast-v1 is `@fast`): a cell's files hold its label,
        // so a label may never change once cells were computed.
        if self.profile != Profile::PaperV1 {
            label = format!("{label}@{}", self.profile.written());
        }
        label
    }

    /// The training run with `n_train` agents: the profile, then `set`, then the fields the
    /// scenario owns (architecture, channels, N_train, episodes, T).
    pub(crate) fn training_config(
        &self,
        world: &WorldConfig,
        n_train: u32,
    ) -> Result<TrainingConfig, ConfigError> {
        let owned = [
            ("architecture", serde_json::to_value(self.architecture)),
            ("channels", serde_json::to_value(self.channels)),
            ("episodes", serde_json::to_value(self.episodes)),
            ("steps_per_episode", serde_json::to_value(world.train_steps)),
            (
                "agents",
                serde_json::to_value(AgentCount::fixed(n_train as usize)),
            ),
        ]
        .map(|(field, value)| (field.to_owned(), value.expect("plain values serialise")));
        // Under the stopping rule the learning rate does not anneal (`scenario::stopping`).
        let constant = self
            .stopping
            .map(|_| (ANNEAL.to_owned(), serde_json::Value::Bool(false)));
        let given = self.set.iter().map(|(k, v)| (k.clone(), v.clone()));
        TrainingConfig::profile(self.profile).with_values(given.chain(owned).chain(constant))
    }
}

impl TryFrom<PolicySpec> for ScenarioPolicy {
    type Error = PolicyError;

    fn try_from(spec: PolicySpec) -> Result<Self, PolicyError> {
        let (architecture, learned) = match spec {
            PolicySpec::Baseline(baseline) => {
                return Ok(ScenarioPolicy::Baseline(baseline.name.parse()?));
            }
            PolicySpec::MaGPpo(learned) => (ArchitectureName::MaGPpo, learned),
            PolicySpec::MaPpo(learned) => (ArchitectureName::MaPpo, learned),
        };
        if learned.episodes == 0 {
            return Err(PolicyError::NoEpisodes);
        }
        if learned.evaluate_every == Some(0) {
            return Err(PolicyError::NoEvaluation);
        }
        let stopping = match (learned.until, learned.stopping) {
            (Until::Converged, rule) => Some(rule.unwrap_or_default()),
            (Until::Episodes, None) => None,
            (Until::Episodes, Some(_)) => return Err(PolicyError::StoppingUnused),
        };
        if let Some(rule) = &stopping {
            rule.check()?;
            if learned.set.contains_key(ANNEAL) {
                return Err(PolicyError::AnnealedUntilConverged);
            }
        }
        if let Some(key) = learned
            .set
            .keys()
            .find(|k| OWN_FIELDS.contains(&k.as_str()))
        {
            return Err(PolicyError::OwnField(key.clone()));
        }
        check_rounds(&learned, stopping.as_ref())?;
        Ok(ScenarioPolicy::Learned(Learned {
            architecture,
            name: learned.name,
            profile: learned.profile,
            channels: channels(&learned.channels)?,
            episodes: learned.episodes,
            set: learned.set,
            test_actions: match learned.test_actions {
                TestActions::Sampled => ActionChoice::Sampled,
                TestActions::Greedy => ActionChoice::Greedy,
            },
            evaluate_every: learned.evaluate_every,
            stopping,
        }))
    }
}

/// Refuses a test curve or validation every so many episodes that is not a whole number of
/// the run's rounds. An `environments` that is not a count is left to the training
/// configuration's own check.
fn check_rounds(learned: &LearnedSpec, stopping: Option<&StoppingRule>) -> Result<(), PolicyError> {
    let environments = match learned.set.get("environments") {
        Some(value) => match value.as_u64() {
            Some(n) if n > 0 => n,
            _ => return Ok(()),
        },
        None => TrainingConfig::profile(learned.profile).environments as u64,
    };
    let plays = [
        ("evaluate_every", learned.evaluate_every),
        (
            "stopping.validate_every",
            stopping.map(|r| r.validate_every),
        ),
    ];
    for (field, every) in plays {
        if let Some(every) = every
            && u64::from(every) % environments != 0
        {
            return Err(PolicyError::OffRound {
                field,
                every,
                environments,
            });
        }
    }
    Ok(())
}

/// The set of channels a list names, in whatever order it names them.
fn channels(listed: &[Channel]) -> Result<Channels, PolicyError> {
    match listed {
        [] => Err(PolicyError::NoChannels),
        [Channel::Local] => Ok(Channels::Local),
        [Channel::Mini] => Ok(Channels::Mini),
        [a, b] if a != b => Ok(Channels::Both),
        _ => Err(PolicyError::ChannelTwice),
    }
}

impl From<ScenarioPolicy> for PolicySpec {
    fn from(policy: ScenarioPolicy) -> Self {
        let learned = match policy {
            ScenarioPolicy::Baseline(baseline) => {
                let name = baseline.name().to_owned();
                return PolicySpec::Baseline(BaselineSpec { name });
            }
            ScenarioPolicy::Learned(learned) => learned,
        };
        let spec = LearnedSpec {
            name: learned.name,
            profile: learned.profile,
            channels: match learned.channels {
                Channels::Both => vec![Channel::Local, Channel::Mini],
                Channels::Local => vec![Channel::Local],
                Channels::Mini => vec![Channel::Mini],
            },
            episodes: learned.episodes,
            set: learned.set,
            test_actions: match learned.test_actions {
                ActionChoice::Sampled => TestActions::Sampled,
                ActionChoice::Greedy => TestActions::Greedy,
            },
            evaluate_every: learned.evaluate_every,
            until: match learned.stopping {
                Some(_) => Until::Converged,
                None => Until::Episodes,
            },
            stopping: learned.stopping,
        };
        match learned.architecture {
            ArchitectureName::MaGPpo => PolicySpec::MaGPpo(spec),
            ArchitectureName::MaPpo => PolicySpec::MaPpo(spec),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use super::super::format::ProfileName;

    fn from_file(yaml: &str) -> Result<ScenarioPolicy, String> {
        let spec: PolicySpec<ProfileName> =
            serde_saphyr::from_str(yaml).map_err(|e| e.to_string())?;
        ScenarioPolicy::try_from(spec.resolved()).map_err(|e| e.to_string())
    }

    fn learned(channels: &str) -> ScenarioPolicy {
        from_file(&format!(
            "ma-g-ppo: {{profile: fast-v1, episodes: 5, channels: {channels}}}"
        ))
        .unwrap()
    }

    #[test]
    fn a_profile_by_its_own_name_keeps_the_key_it_had_and_fast_names_the_default() {
        let key_of = |profile: &str| {
            let yaml = format!("ma-g-ppo: {{profile: {profile}, episodes: 5}}");
            serde_json::to_string(&from_file(&yaml).unwrap()).unwrap()
        };
        // fast-v1's cells were keyed when it was called fast: its key still says so.
        assert!(key_of("fast-v1").contains(r#""profile":"fast""#));
        // So were paper-v1's, when it was called paper; `paper` is the released training now.
        assert!(key_of("paper-v1").contains(r#""profile":"paper""#));
        assert!(key_of("paper").contains(r#""profile":"paper-v2""#));
        let default = from_file("ma-g-ppo: {profile: fast, episodes: 5}").unwrap();
        assert_eq!(default.learned().unwrap().profile, Profile::FAST);
        let unknown = from_file("ma-g-ppo: {profile: fastest, episodes: 5}").unwrap_err();
        assert!(
            unknown.contains(
                "unknown profile `fastest` (known: paper, paper-v1, paper-v2, fast, fast-v1, \
                 fast-v2, fast-v3)"
            ),
            "{unknown}"
        );
    }

    #[test]
    fn plays_that_fall_between_rounds_are_refused_naming_the_field() {
        let curve = "ma-g-ppo: {profile: fast-v1, episodes: 80, evaluate_every: 12";
        let off = from_file(&format!("{curve}}}")).unwrap_err();
        assert!(
            off.contains("evaluate_every: 12 is not a multiple of the 8 episodes a round"),
            "{off}"
        );
        from_file(&format!("{curve}, set: {{environments: 4}}}}")).unwrap();
        let converged = "episodes: 80, until: converged, stopping: {validate_every: 3}}";
        let off = from_file(&format!("ma-g-ppo: {{profile: fast-v1, {converged}")).unwrap_err();
        assert!(off.contains("stopping.validate_every: 3 is not"), "{off}");
        from_file(&format!("ma-g-ppo: {{profile: fast-v2, {converged}")).unwrap();
    }

    #[test]
    fn channels_in_either_order_are_one_policy_with_one_form() {
        let (written, reversed) = (learned("[local, mini]"), learned("[mini, local]"));
        assert_eq!(written, reversed);
        assert_eq!(reversed.label(), "ma-g-ppo@fast");
        let json = serde_json::to_string(&reversed).unwrap();
        assert!(json.contains(r#""channels":["local","mini"]"#), "{json}");
        assert_eq!(learned("[mini]").label(), "ma-g-ppo[mini]@fast");
    }

    #[test]
    fn the_stored_form_is_the_files_and_reads_back_checked() {
        let gcs = ScenarioPolicy::Baseline(Baseline::Gcs);
        assert_eq!(
            serde_json::to_string(&gcs).unwrap(),
            r#"{"baseline":{"name":"gcs"}}"#
        );
        let policy = learned("[local]");
        let json = serde_json::to_string(&policy).unwrap();
        assert_eq!(
            json,
            r#"{"ma-g-ppo":{"name":null,"profile":"fast","channels":["local"],"episodes":5,"set":{},"test_actions":"sampled"}}"#
        );
        assert_eq!(
            serde_json::from_str::<ScenarioPolicy>(&json).unwrap(),
            policy
        );
        let unknown = serde_json::from_str::<ScenarioPolicy>(r#"{"baseline":{"name":"gsc"}}"#);
        assert!(unknown.unwrap_err().to_string().contains("gsc"));
    }
}
