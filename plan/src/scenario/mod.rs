//! Scenarios: one YAML file describes an experiment, checked once when loaded and expanded
//! into the grid of cells a sweep runs.

mod check;
mod checked;
pub mod claims;
pub mod cost;
mod disturbance;
pub mod earlier;
mod error;
mod format;
mod policy;
mod size;
pub mod stopping;
mod world_config;
pub(crate) mod yaml;

use std::path::Path;

use serde::Deserialize;

pub use checked::{Scenario, ScenarioMap, map_hash};
pub use error::ScenarioError;
pub use format::Output;
pub use policy::{Learned, ScenarioPolicy};
pub use size::{Limits, Size};
pub(crate) use world_config::WorldConfig;

/// The largest scenario file read. A scenario may hold its maps inline, each up to a text
/// map's limit ([`world::map::MAX_TEXT_MAP_BYTES`], a little over 1 MiB) plus indentation;
/// 8 MiB leaves room for several maps of the largest side, and keeps a wrong path (a device,
/// a huge file) from filling memory. Larger maps belong in map files.
pub const MAX_SCENARIO_BYTES: u64 = 8 << 20;

/// The text of the scenario file `path`: a regular file of at most [`MAX_SCENARIO_BYTES`].
pub fn read_scenario_text(path: &Path) -> Result<String, ScenarioError> {
    world::read_bounded_text(path, MAX_SCENARIO_BYTES, "a scenario")
        .map_err(|e| ScenarioError::new(&e.path, None, "", e.problem))
}

/// The `description` of a scenario's text (empty when it has none): the store's copy of a
/// scenario, whose report opens with what the experiment is.
pub fn description_of_text(text: &str, file: &Path) -> Result<String, ScenarioError> {
    /// A scenario file read for its description alone.
    #[derive(Deserialize)]
    struct DescriptionOnly {
        #[serde(default)]
        description: String,
    }
    let spec: DescriptionOnly = yaml::from_yaml(text, file)?;
    Ok(spec.description)
}

impl Scenario {
    /// Reads and checks a scenario file; map files are relative to its folder.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        Self::load_within(path, &Limits::DEFAULT)
    }

    /// [`Scenario::load`], refusing a scenario larger than `limits`.
    pub fn load_within(path: &Path, limits: &Limits) -> Result<Self, ScenarioError> {
        let text = read_scenario_text(path)?;
        Self::parse_within(&text, path, limits)
    }

    /// Checks a scenario held in memory; `file` names it in errors and anchors map paths.
    pub fn parse(text: &str, file: &Path) -> Result<Self, ScenarioError> {
        Self::parse_within(text, file, &Limits::DEFAULT)
    }

    /// [`Scenario::parse`], refusing a scenario larger than `limits`.
    pub fn parse_within(text: &str, file: &Path, limits: &Limits) -> Result<Self, ScenarioError> {
        let spec: format::ScenarioFile = yaml::from_yaml(text, file)?;
        check::check(spec, file, limits)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GRID: &str = "      grid: |\n        ......\n        ..#...\n        ......\n";

    fn scenario(extra_policies: &str, maps: &str) -> String {
        format!(
            "name: unit\nseed: 3\nmaps:\n{maps}world: {{fov: 3, test_steps: 20, train_steps: 10}}\n\
             policies:\n  - baseline: {{name: random}}\n{extra_policies}\
             agents: {{train: [2, 3], test: [1, 2]}}\nrepetitions: 2\ntest_episodes: 4\n"
        )
    }

    fn inline(name: &str) -> String {
        format!("  - inline:\n      name: {name}\n{GRID}")
    }

    fn parse(text: &str) -> Result<Scenario, ScenarioError> {
        Scenario::parse(text, Path::new("unit.yaml"))
    }

    #[test]
    fn the_description_is_read_from_the_text_alone() {
        let file = Path::new("unit.yaml");
        let text = format!(
            "description: Random on one map.\n{}",
            scenario("", &inline("a"))
        );
        assert!(parse(&text).is_ok());
        assert_eq!(
            description_of_text(&text, file).unwrap(),
            "Random on one map."
        );
        // The store's copy is read for its description even where its maps would not resolve.
        let unresolved = "name: x\nmaps:\n  - file: gone.txt\n";
        assert_eq!(description_of_text(unresolved, file).unwrap(), "");
        assert!(description_of_text("description: [a, b]\n", file).is_err());
    }

    #[test]
    fn expands_baselines_once_and_learned_policies_per_training_count() {
        let learned = "  - ma-ppo: {profile: fast-v1, episodes: 5, set: {network: compact}}\n";
        let s = parse(&scenario(learned, &inline("a"))).unwrap();
        let cells = s.cells();
        // random: 2 repetitions; ma-ppo: 2 training counts x 2 repetitions.
        assert_eq!(cells.len(), 2 + 4);
        assert_eq!(cells[0].config.n_train, None);
        assert_eq!(cells[2].config.n_train, Some(2));
        assert_eq!(cells[2].config.policy.label(), "ma-ppo@fast");
        let training = cells[2].config.training().unwrap();
        assert_eq!(training.agents, learning::ppo::AgentCount::fixed(2));
        assert_eq!((training.episodes, training.steps_per_episode), (5, 10));
        assert_eq!(training.network, learning::ppo::Network::Compact);
        assert!(cells[0].config.training().is_none());
        let keys: std::collections::HashSet<_> = cells.iter().map(|c| &c.key).collect();
        assert_eq!(keys.len(), cells.len());
        let cost: crate::scenario::cost::Cost = cells
            .iter()
            .fold(Default::default(), |a, c| a + c.config.cost());
        assert_eq!(cost.training_episodes, 4 * 5);
        assert_eq!(cost.test_episodes, 6 * 2 * 4);
        assert_eq!(cost.env_steps, 4 * 5 * 10 + 6 * 2 * 4 * 20);
        // Per agent and step: training weighs most (MA-PPO's rate), then learned and baseline
        // test steps.
        use crate::scenario::cost::work::{BASELINE_STEP, INDEPENDENT_TRAINING_STEP, LEARNED_STEP};
        let test_agent_steps = (1 + 2) * 4 * 20;
        let training = 2 * (5 * 10) * (2 + 3) * INDEPENDENT_TRAINING_STEP;
        let tests = 2 * test_agent_steps * BASELINE_STEP + 4 * test_agent_steps * LEARNED_STEP;
        assert_eq!(cost.work, training + tests);
    }

    #[test]
    fn learned_policies_are_checked_against_every_map_and_training_count() {
        let cases = [
            (
                "  - ma-ppo: {episodes: 5}\n",
                "unit.yaml:13: policies[1]: map \"a\": training configuration: network",
            ),
            (
                "  - ma-ppo: {episodes: 5, set: {network: compact, episodes: 3}}\n",
                "policies[1]: set.episodes: the scenario sets this itself",
            ),
            (
                "  - ma-ppo: {episodes: 5, set: {network: compact, gamma: 2}}\n",
                "policies[1]: training configuration: gamma: 2 is not in [0, 1)",
            ),
            (
                "  - ma-ppo: {episodes: 5, set: {netwrk: compact}}\n",
                "unknown field `netwrk`",
            ),
            (
                "  - ma-ppo: {episodes: 5, set: {network: compact, grad_clip_per_network: 10}}\n",
                "training configuration: grad_clip_per_network: invalid type",
            ),
            (
                "  - ma-ppo: {episodes: 5, set: {network: compact, value_normalisation: {beta: 1}}}\n",
                "training configuration: value_normalisation: beta 1 is not in [0, 1)",
            ),
            (
                "  - ma-ppo: {profile: slow, episodes: 5}\n",
                "policies[1].ma-ppo.profile: unknown profile `slow` (known: paper, paper-v1, paper-v2, fast, fast-v1, fast-v2, fast-v3)",
            ),
            (
                "  - ma-g-ppo: {episodes: 0, set: {network: compact}}\n",
                "policies[1]: episodes must be at least 1",
            ),
        ];
        for (learned, expected) in cases {
            let error = parse(&scenario(learned, &inline("a")))
                .unwrap_err()
                .to_string();
            assert!(error.contains(expected), "{error}\n  expected: {expected}");
        }
    }

    #[test]
    fn a_cell_does_not_change_when_the_scenario_grows() {
        let one = parse(&scenario("", &inline("a"))).unwrap().cells();
        let maps = format!("{}{}", inline("b"), inline("a"));
        let two = parse(&scenario("", &maps)).unwrap().cells();
        assert_eq!(two.len(), 2 * one.len());
        assert_eq!(one[0].key, two[2].key, "same map, policy and repetition");
        assert_ne!(one[0].key, one[1].key, "repetitions differ");
    }

    #[test]
    fn bad_values_name_file_line_and_field() {
        let cases = [
            (
                scenario("", &inline("a")).replace("fov: 3", "fov: 4"),
                "unit.yaml:10: world.fov: fov (L) must be odd",
            ),
            (
                scenario("", &inline("a")).replace("test: [1, 2]", "test: [1, 19]"),
                "agents.test[1]: 19 agents do not fit on map \"a\" (17 free cells)",
            ),
            (
                scenario("", &inline("a")).replace("test: [1, 2]", "test: []"),
                "agents.test: the list is empty",
            ),
            (
                scenario("", &inline("a")).replace("test: [1, 2]", "test: [0, 2]"),
                "agents.test[0]: an agent count must be at least 1",
            ),
            (
                scenario("", &inline("a")).replace("test_episodes: 4", "test_episodes: 0"),
                "unit.yaml:15: test_episodes: must be at least 1",
            ),
            (
                scenario("", &inline("a")).replace("name: random", "name: nope"),
                "unit.yaml:12: policies[0]: unknown policy \"nope\"",
            ),
            (
                scenario("  - baseline: {name: random}\n", &inline("a")),
                "unit.yaml:13: policies[1]: policy \"random\" is listed twice",
            ),
            (
                scenario("", &format!("{}{}", inline("a"), inline("a"))),
                "unit.yaml:10: maps[1]: a second map named \"a\"",
            ),
        ];
        for (text, expected) in cases {
            let error = parse(&text).unwrap_err().to_string();
            assert!(error.contains(expected), "{error}\n  expected: {expected}");
        }
    }

    #[test]
    fn disturbances_are_checked_against_the_episode_and_the_teams() {
        let with = |disturbances: &str| {
            format!(
                "{}disturbances:\n{disturbances}",
                scenario("", &inline("a"))
            )
        };
        let good = "  - name: lose\n    lose: {robots: 1, at: 10}\n  \
                    - name: cut\n    links: {radius: 4.5, drop: 0.5}\n";
        let teams = |text: String| text.replace("test: [1, 2]", "test: [2, 3]");
        let s = parse(&teams(with(good))).unwrap();
        assert_eq!(s.disturbances.len(), 2);
        assert_eq!(s.disturbances[0].robots_lost(), Some(1));
        let cells = s.cells();
        assert_eq!(cells[0].config.disturbances, s.disturbances);
        let plain = parse(&teams(scenario("", &inline("a")))).unwrap().cells();
        assert_ne!(
            cells[0].key, plain[0].key,
            "a disturbance is part of a cell's key"
        );
        assert_eq!(
            cells[0].config.cost().test_episodes,
            3 * plain[0].config.cost().test_episodes,
            "every test episode is played undisturbed and under both"
        );
        let cases = [
            (
                "  - name: x\n    lose: {robots: 1, at: 20}\n",
                "unit.yaml:18: disturbances[0].lose.at: step 20 is not inside the test episode (1 to 19",
            ),
            (
                "  - name: x\n    lose: {robots: 1, at: 0}\n",
                "disturbances[0].lose.at: step 0 is not inside",
            ),
            (
                "  - name: x\n    lose: {robots: 1, at: 5}\n",
                "disturbances[0].lose.robots: 1 robots: lose at least 1 and fewer than the smallest test team (1)",
            ),
            (
                "  - name: x\n    lose: {which: [0, 0], at: 5}\n",
                "disturbances[0].lose.which: a robot is listed twice",
            ),
            (
                "  - name: x\n    lose: {robots: 1, which: [0], at: 5}\n",
                "disturbances[0].lose: give robots (how many) or which (by index), not both",
            ),
            (
                "  - name: x\n    links: {drop: 1.5}\n",
                "unit.yaml:18: disturbances[0].links.drop: a link's drop probability must be between 0 and 1, got 1.5",
            ),
            (
                "  - name: x\n    links: {radius: -2}\n",
                "disturbances[0].links.radius: a link radius must be finite and >= 0, got -2",
            ),
            (
                "  - name: x\n    links: {}\n",
                "disturbances[0].links: give radius, drop or both",
            ),
            ("  - name: x\n", "disturbances[0]: give lose, links or both"),
            (
                "  - name: none\n    links: {drop: 0.1}\n",
                "disturbances[0].name: \"none\" is not a usable name",
            ),
            (
                "  - name: x\n    links: {drop: 0.1}\n  - name: x\n    links: {drop: 0.2}\n",
                "disturbances[1].name: a second disturbance named \"x\"",
            ),
            ("  - name: x\n    los: {}\n", "unknown field `los`"),
        ];
        for (disturbances, expected) in cases {
            let text = with(disturbances);
            let text = if expected.contains("smallest test team (1)") {
                text
            } else {
                teams(text)
            };
            let error = parse(&text).unwrap_err().to_string();
            assert!(error.contains(expected), "{error}\n  expected: {expected}");
        }
    }

    #[test]
    fn claims_take_a_column_a_scale_a_budget_or_a_reason() {
        let learned = "  - ma-ppo: {profile: fast-v1, episodes: 5, set: {network: compact}}\n";
        let with = |claims: &str| format!("{}claims:\n{claims}", scenario(learned, &inline("a")));
        let good = "  - id: column\n    budget: 30000\n    \
                    gap_grows: {a: ma-ppo@fast, b: random, maps: [a], n_test: 1, n: [2, 3]}\n  \
                    - id: scaled\n    not_worse: {a: ma-ppo@fast, b: random, maps: [a], n: [2], \
                    tolerance: 0.05, scale: random}\n  \
                    - id: rooms\n    not_tested: rooms are not measured\n  \
                    - id: ratio\n    \
                    gap_grows: {a: ma-ppo@fast, b: random, maps: [a], n: [1, 2], n_train: 2, scale: b}\n";
        let s = parse(&with(good)).unwrap();
        use crate::scenario::claims::{ClaimTest, Scale};
        let ClaimTest::GapGrows { pair, scale } = &s.claims[0].test else {
            panic!("{:?}", s.claims[0]);
        };
        assert_eq!(
            *scale,
            Scale::Absolute,
            "gaps as they are unless a scale is given"
        );
        assert!(
            matches!(
                &s.claims[3].test,
                ClaimTest::GapGrows {
                    scale: Scale::B,
                    ..
                }
            ),
            "{:?}",
            s.claims[3]
        );
        let points: Vec<(u32, u32)> = pair.points.iter().map(|p| (p.n_test, p.n_train)).collect();
        assert_eq!(
            points,
            [(1, 2), (1, 3)],
            "one N_test column, N_train along n"
        );
        assert_eq!(s.claims[0].budget, Some(30000));
        let ClaimTest::NotWorse { tolerance, .. } = &s.claims[1].test else {
            panic!("{:?}", s.claims[1]);
        };
        assert_eq!((tolerance.value, tolerance.scale), (0.05, Scale::Random));
        assert_eq!(s.claims[1].budget, None);
        assert!(
            matches!(&s.claims[2].test, ClaimTest::NotTested { reason } if reason == "rooms are not measured")
        );
        let cases = [
            (
                "  - id: x\n    within: {a: ma-ppo@fast, b: random, maps: [a], n: [2], tolerance: 0.1, scale: c}\n",
                "claims[0].within.scale: unknown scale \"c\" (one of b, random, absolute)",
            ),
            (
                "  - id: x\n    gap_grows: {a: ma-ppo@fast, b: random, maps: [a], n_test: 3, n: [2, 3]}\n",
                "claims[0].gap_grows.n_test: N = 3 is not in agents.test [1, 2]",
            ),
            (
                "  - id: x\n    gap_grows: {a: ma-ppo@fast, b: random, maps: [a], n_test: 1, n: [1, 2]}\n",
                "claims[0].gap_grows.n[0]: N = 1 is not in agents.train [2, 3]",
            ),
            (
                "  - id: x\n    lower: {a: ma-ppo@fast, b: random, maps: [a], n_test: 1, n: [2], n_train: 2}\n",
                "claims[0].lower.n_train: give n_test (a column, n listing N_train) or n_train",
            ),
            (
                "  - id: x\n    gap_grows: {a: ma-ppo@fast, b: random, maps: [a], n: [1, 2], n_train: 2, scale: random}\n",
                "claims[0].gap_grows.scale: a gap is scaled by b or absolute, not \"random\"",
            ),
            (
                "  - id: x\n    budget: 0\n    lower: {a: ma-ppo@fast, b: random, maps: [a], n: [2]}\n",
                "claims[0].budget: must be > 0 episodes",
            ),
            (
                "  - id: x\n    not_tested: \" \"\n",
                "claims[0].not_tested: say why the statement is not tested",
            ),
        ];
        for (claims, expected) in cases {
            let error = parse(&with(claims)).unwrap_err().to_string();
            assert!(error.contains(expected), "{error}\n  expected: {expected}");
        }
        let no_random = format!(
            "{}claims:\n  - id: x\n    within: {{a: ma-ppo@fast, b: tspc, maps: [a], n: [2], tolerance: 0.1, scale: random}}\n",
            scenario(learned, &inline("a")).replace("{name: random}", "{name: tspc}")
        );
        let error = parse(&no_random).unwrap_err().to_string();
        assert!(
            error.contains("scale random needs the random baseline"),
            "{error}"
        );
    }

    #[test]
    fn claims_name_the_scenarios_own_policies_maps_and_counts() {
        let learned = "  - ma-ppo: {profile: fast-v1, episodes: 5, set: {network: compact}}\n";
        let with = |claims: &str| format!("{}claims:\n{claims}", scenario(learned, &inline("a")));
        let good = "  - id: beats\n    paper: MA-PPO beats Random\n    \
                    lower: {a: ma-ppo@fast, b: random, maps: [a], n: [2]}\n  \
                    - id: transfer\n    lower: {a: ma-ppo@fast, b: random, maps: [a], n: [1], n_train: 3}\n";
        let s = parse(&with(good)).unwrap();
        let crate::scenario::claims::ClaimTest::Lower { pair } = &s.claims[1].test else {
            panic!("{:?}", s.claims[1]);
        };
        assert_eq!((pair.points[0].n_test, pair.points[0].n_train), (1, 3));
        let cases = [
            (
                "  - id: x\n    lower: {a: ma-ppo, b: random, maps: [a], n: [2]}\n",
                "unit.yaml:19: claims[0].lower.a: no policy \"ma-ppo\" in this scenario (its policies: random, ma-ppo@fast)",
            ),
            (
                "  - id: x\n    lower: {a: ma-ppo@fast, b: random, maps: [b], n: [2]}\n",
                "unit.yaml:19: claims[0].lower.maps[0]: no map \"b\"",
            ),
            (
                "  - id: x\n    lower: {a: ma-ppo@fast, b: random, maps: [a], n: [1]}\n",
                "claims[0].lower.n[0]: N = 1 is not in agents.train [2, 3]",
            ),
            (
                "  - id: x\n    lower: {a: ma-ppo@fast, b: random, maps: [a], n: [3]}\n",
                "claims[0].lower.n[0]: N = 3 is not in agents.test [1, 2]",
            ),
            (
                "  - id: x\n    within: {a: ma-ppo@fast, b: random, maps: [a], n: [2]}\n",
                "unit.yaml:18: claims[0].within: needs a tolerance",
            ),
            (
                "  - id: x\n    diagonal_best: {policy: random, map: a, n: [2, 3]}\n",
                "claims[0].diagonal_best.policy: \"random\" is a baseline",
            ),
            (
                "  - id: x\n    gap_grows: {a: ma-ppo@fast, b: random, maps: [a], n: [2]}\n",
                "claims[0].gap_grows.n: needs at least 2 agent count(s)",
            ),
            (
                "  - id: x\n    gap_grows: {a: ma-ppo@fast, b: random, maps: [a, a], n: [1, 2]}\n",
                "claims[0].gap_grows.maps: a gap grows along N on one map",
            ),
            (
                "  - id: x\n    curve_below: {a: ma-ppo@fast, b: ma-ppo@fast, map: a, n_train: 2, episodes: [5, 1]}\n",
                "claims[0].curve_below.episodes: [5, 1] is not a range of episodes",
            ),
            (
                "  - id: x\n",
                "unit.yaml:18: claims[0]: give exactly one of lower, within",
            ),
            ("  - id: x\n    lowr: {}\n", "unknown field `lowr`"),
            (
                "  - id: x\n    behaviour: {policy: random, map: a, n_test: 2}\n",
                "claims[0].behaviour: give at least one of stationary, touring, periodic, centred",
            ),
            (
                "  - id: x\n    behaviour: {policy: random, map: a, n_test: 2, touring: 0, centred: true}\n",
                "claims[0].behaviour: centred: true needs a stationary and a touring agent",
            ),
            (
                "  - id: x\n    behaviour: {policy: random, map: a, n_test: 2, stationary: 1, touring: 2}\n",
                "claims[0].behaviour: 3 agents counted, but N_test is 2",
            ),
            (
                "  - id: x\n    behaviour: {policy: ma-ppo@fast, map: a, n_test: 1, periodic: true}\n",
                "claims[0].behaviour.n_test: N = 1 is not in agents.train [2, 3]",
            ),
            (
                "  - id: x\n    lower: {a: random, b: random, b_under: cut, maps: [a], n: [2]}\n",
                "claims[0].lower.b_under: no disturbance \"cut\" in this scenario (its disturbances: )",
            ),
            (
                "  - id: x\n    lower: {a: random, b: random, maps: [a], n: [2]}\n",
                "claims[0].lower.b: a and b are the same policy under the same conditions",
            ),
            (
                "  - id: x\n    adapts_better: {a: ma-ppo@fast, b: random, disturbance: cut, maps: [a], n: [2]}\n",
                "claims[0].adapts_better.disturbance: no disturbance \"cut\"",
            ),
            (
                &good.replace("transfer", "beats"),
                "claims[1].id: a second claim with id \"beats\"",
            ),
        ];
        for (claims, expected) in cases {
            let error = parse(&with(claims)).unwrap_err().to_string();
            assert!(error.contains(expected), "{error}\n  expected: {expected}");
        }
        // `@fast` is the first fast's label; a scenario's `profile: fast` is today's.
        let today = format!(
            "{}claims:\n{good}",
            scenario(&learned.replace("fast-v1", "fast"), &inline("a"))
        );
        let error = parse(&today).unwrap_err().to_string();
        let expected = "no policy \"ma-ppo@fast\" in this scenario (its policies: random, \
                        ma-ppo@fast-v3); `@fast` labels the profile fast-v1 (the first `fast`), \
                        while `profile: fast` trains fast-v3 today, labelled \"ma-ppo@fast-v3\"";
        assert!(error.contains(expected), "{error}");
    }

    #[test]
    fn unknown_keys_and_wrong_types_are_placed() {
        let unknown = scenario("", &inline("a")).replace("seed: 3", "seed: 3\nseeds: 4");
        let error = parse(&unknown).unwrap_err();
        assert_eq!(error.line, Some(3), "{error}");
        assert!(error.to_string().contains("seeds"), "{error}");
        let wrong = scenario("", &inline("a")).replace("repetitions: 2", "repetitions: two");
        let error = parse(&wrong).unwrap_err();
        assert_eq!(error.line, Some(14), "{error}");
        assert!(
            error
                .to_string()
                .starts_with("unit.yaml:14: repetitions: invalid u32: expected a whole number"),
            "{error}"
        );
    }
}
