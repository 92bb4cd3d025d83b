//! How much a scenario asks of the machine, from its numbers alone, before a single cell is
//! made: a file's counts multiply (maps x policies x N_train x repetitions x N_test x episodes
//! x steps), and a typo of a few digits would otherwise fill the memory while the cells are
//! listed, long before the first one runs.

use std::path::Path;

use learning::ppo::TrainingConfig;
use serde_saphyr::Spanned;

use super::error::ScenarioError;
use super::format::ScenarioFile;
use super::{Output, Scenario};
use crate::scenario::cost::Cost;

/// What a scenario may ask for. The defaults are what a 2-core, 24 GB machine survives, and
/// the paper's budgets on a cluster stay well below them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    pub cells: u64,
    test_episodes: u64,
    cpu_seconds: f64,
    pub memory_bytes: u64,
}

impl Limits {
    pub const DEFAULT: Limits = Limits {
        cells: 100_000,
        test_episodes: 10_000_000,
        // A CPU-year: every paper-budget scenario takes a few CPU-months.
        cpu_seconds: 365.0 * 86_400.0,
        memory_bytes: 16 << 30,
    };
    /// No limit: the user has checked the numbers.
    pub const NONE: Limits = Limits {
        cells: u64::MAX,
        test_episodes: u64::MAX,
        cpu_seconds: f64::INFINITY,
        memory_bytes: u64::MAX,
    };
}

/// A scenario's size.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Size {
    pub cells: u64,
    pub cost: Cost,
    /// The sweep's tables in memory, every map's world (its visibility windows), and the
    /// two largest cells' working memory at once (a training run, or a tour's planning).
    pub memory_bytes: u64,
    /// The part of `memory_bytes` that the maps' size makes: their worlds and plans.
    map_bytes: u64,
}

/// Bytes of an `episodes` row in memory (its key, names and a dozen numbers).
const EPISODE_ROW_BYTES: u64 = 256;
/// Bytes of a `trajectories` row (one agent at one step).
const TRAJECTORY_ROW_BYTES: u64 = 64;
/// A training run's rollout buffer, the update's gathered minibatches and the network's
/// workspaces: about three copies of the observations.
const ROLLOUT_COPIES: u64 = 3;
/// A world's memory per map cell besides its visibility windows (penalties, occupancy, a
/// search's distances).
const WORLD_BYTES_PER_CELL: u64 = 32;
/// Planning a tour or posts (TSPC, partitioned tours, static coverage) per map cell: a free
/// index, the greedy's bits and gains, the searches between viewpoints. Measured: TSPC on an
/// open 1024 x 1024 map peaked at 258 MB, 210 MB of them its visibility windows, so about
/// 46 bytes a cell; 64 leaves room.
const PLANNING_BYTES_PER_CELL: u64 = 64;

impl Scenario {
    /// The size of the sweep of this scenario, computed without listing its cells.
    pub fn size(&self) -> Size {
        let mut size = Size::default();
        let mut runs = Vec::new();
        for (map_index, policy, n_train, training) in self.runs() {
            let learned = policy.learned();
            let cell = Cost::of_cell(
                &self.world,
                learned,
                n_train,
                &self.test_agents,
                crate::scenario::cost::test_plays(self.test_episodes, self.disturbances.len()),
            );
            size.cost = size.cost + cell.times(u64::from(self.repetitions));
            size.cells = size.cells.saturating_add(u64::from(self.repetitions));
            match (training, n_train) {
                (Some(training), Some(n)) => {
                    runs.push((self.rollout_bytes(map_index, training, n), 0))
                }
                _ => runs.push((0, self.planning_bytes(map_index, policy))),
            }
        }
        runs.sort_unstable_by_key(|&(training, planning)| std::cmp::Reverse(training + planning));
        let (training, planning) = runs.iter().take(2).fold((0u64, 0u64), |(t, p), &(a, b)| {
            (t.saturating_add(a), p.saturating_add(b))
        });
        size.map_bytes = self.world_bytes().saturating_add(planning);
        size.memory_bytes = (self.table_bytes(size))
            .saturating_add(training)
            .saturating_add(size.map_bytes);
        size
    }

    /// Every map's world at once (a sweep builds each once and shares it between cells).
    fn world_bytes(&self) -> u64 {
        let fov = self.world.fov;
        self.maps.iter().fold(0u64, |sum, m| {
            let cells = m.map.width() * m.map.height();
            let world = world::Visibility::bytes_for(cells, fov)
                .saturating_add((cells as u64).saturating_mul(WORLD_BYTES_PER_CELL));
            sum.saturating_add(world)
        })
    }

    /// The planning memory of a baseline's cell on map `map_index` (none for one that does not
    /// plan).
    fn planning_bytes(&self, map_index: usize, policy: &super::ScenarioPolicy) -> u64 {
        let plans = match policy {
            super::ScenarioPolicy::Baseline(baseline) => baseline.plans_from_the_map(),
            super::ScenarioPolicy::Learned(_) => false,
        };
        let map = &self.maps[map_index].map;
        match plans {
            true => (map.width() * map.height()) as u64 * PLANNING_BYTES_PER_CELL,
            false => 0,
        }
    }

    /// The memory of the training run `config` with `n` agents on map `map_index`.
    fn rollout_bytes(&self, map_index: usize, config: &TrainingConfig, n: u32) -> u64 {
        let map = &self.maps[map_index].map;
        let geometry = world::ImageGeometry::new(map, self.world.fov, config.mini_map_block);
        let image = (geometry.side * geometry.side) as u64;
        (u64::from(self.world.train_steps) + 1)
            .saturating_mul(u64::from(n))
            .saturating_mul(config.environments as u64)
            .saturating_mul(config.channels.count() as u64 * image * 4)
            .saturating_mul(ROLLOUT_COPIES)
    }

    /// The memory of the sweep's tables: every test episode's row, and the recorded first
    /// test episode at every N_test of each repetition-0 cell.
    fn table_bytes(&self, size: Size) -> u64 {
        let episodes = size.cost.test_episodes.saturating_mul(EPISODE_ROW_BYTES);
        if !self.outputs.contains(&Output::Trajectories) {
            return episodes;
        }
        let per_cell = self.test_agents.iter().fold(0u64, |sum, &n| {
            sum.saturating_add(u64::from(n) * (u64::from(self.world.test_steps) + 1))
        });
        let first_cells = size.cells / u64::from(self.repetitions.max(1));
        let recorded = per_cell
            .saturating_mul(first_cells)
            .saturating_mul(TRAJECTORY_ROW_BYTES);
        episodes.saturating_add(recorded)
    }
}

/// Fails when `scenario` exceeds `limits`, naming the field that weighs most in the product
/// that went over.
pub(super) fn check_size(
    scenario: &Scenario,
    spec: &ScenarioFile,
    limits: &Limits,
    file: &Path,
) -> Result<(), ScenarioError> {
    let size = scenario.size();
    let counts = format!(
        "{} maps, {} policies, N_train {:?}, {} repetitions, N_test {:?}, {} test episodes, \
         T = {} / {}",
        scenario.maps.len(),
        scenario.policies.len(),
        scenario.train_agents,
        scenario.repetitions,
        scenario.test_agents,
        scenario.test_episodes,
        scenario.world.train_steps,
        scenario.world.test_steps,
    );
    let over = |what: String, drivers: &[(&str, &Spanned<u32>)]| {
        let (field, value) = drivers
            .iter()
            .max_by_key(|(_, value)| value.value)
            .expect("every limit has a driver");
        let problem =
            format!("{what} ({counts}); check the numbers, or pass --no-limits to run it anyway");
        ScenarioError::at(file, value, field, problem)
    };
    let repetitions = ("repetitions", &spec.repetitions);
    let test_episodes = ("test_episodes", &spec.test_episodes);
    let train_steps = ("world.train_steps", &spec.world.train_steps);
    let test_steps = ("world.test_steps", &spec.world.test_steps);
    if size.cells > limits.cells {
        let what = format!(
            "the scenario expands to {} cells, above the limit of {}",
            size.cells, limits.cells
        );
        return Err(over(what, &[repetitions]));
    }
    if size.cost.test_episodes > limits.test_episodes {
        let what = format!(
            "the scenario plays {} test episodes, above the limit of {}",
            size.cost.test_episodes, limits.test_episodes
        );
        return Err(over(what, &[test_episodes, repetitions]));
    }
    let cpu = size.cost.cpu_seconds();
    if cpu > limits.cpu_seconds {
        let what = format!(
            "the scenario needs about {:.0} CPU-days ({} environment steps), above the limit of \
             {:.0}",
            cpu / 86_400.0,
            size.cost.env_steps,
            limits.cpu_seconds / 86_400.0
        );
        return Err(over(
            what,
            &[train_steps, test_steps, test_episodes, repetitions],
        ));
    }
    if size.memory_bytes > limits.memory_bytes {
        let what = format!(
            "the sweep would hold about {:.1} GB in memory (its tables, its maps' worlds and \
             two cells' training runs or plans), above the limit of {:.1} GB",
            size.memory_bytes as f64 / 1e9,
            limits.memory_bytes as f64 / 1e9
        );
        if size.map_bytes > size.memory_bytes / 2 {
            let problem = format!(
                "{what}, most of it for the maps' size ({:.1} GB); check the maps, or pass \
                 --no-limits to run it anyway",
                size.map_bytes as f64 / 1e9
            );
            return Err(ScenarioError::at(file, &spec.maps, "maps", problem));
        }
        return Err(over(
            what,
            &[train_steps, test_steps, test_episodes, repetitions],
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENARIO: &str = "name: unit\nseed: 3\nmaps:\n  - inline:\n      name: a\n      grid: |\n        ......\n        ..#...\n        ......\nworld: {fov: 3, test_steps: 20, train_steps: 10}\npolicies:\n  - baseline: {name: random}\n  - ma-ppo: {profile: fast-v1, episodes: 5, set: {network: compact}}\nagents: {train: [2, 3], test: [1, 2]}\nrepetitions: 2\ntest_episodes: 4\n";

    fn error(edits: &[(&str, &str)]) -> String {
        let text = edits.iter().fold(SCENARIO.to_owned(), |text, (from, to)| {
            text.replace(from, to)
        });
        Scenario::parse(&text, Path::new("unit.yaml"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn the_size_is_the_cells_product_and_listing_them_agrees() {
        let scenario = Scenario::parse(SCENARIO, Path::new("unit.yaml")).unwrap();
        let size = scenario.size();
        let cells = scenario.cells();
        assert_eq!(size.cells, cells.len() as u64);
        let listed = cells
            .iter()
            .fold(Cost::default(), |sum, cell| sum + cell.config.cost());
        assert_eq!(size.cost, listed);
        assert!(size.memory_bytes > 0);
    }

    #[test]
    fn maps_whose_worlds_pass_the_memory_limit_fail_at_maps() {
        let row = format!("        {}\n", ".".repeat(1024));
        let grid = row.repeat(1024);
        let text = format!(
            "name: big\nseed: 1\nmaps:\n  - inline:\n      name: a\n      grid: |\n{grid}  \
             - inline:\n      name: b\n      grid: |\n{grid}world: {{fov: 255, test_steps: 5}}\n\
             policies:\n  - baseline: {{name: tspc}}\nagents: {{test: [2]}}\ntest_episodes: 1\n"
        );
        let error = Scenario::parse(&text, Path::new("big.yaml"))
            .unwrap_err()
            .to_string();
        assert!(
            error.starts_with("big.yaml:4: maps: the sweep would hold about 17.3 GB"),
            "{error}"
        );
        assert!(error.contains("most of it for the maps' size"), "{error}");
        let one = text
            .split("  - inline:\n      name: b")
            .next()
            .unwrap()
            .to_owned()
            + "world: {fov: 255, test_steps: 5}\npolicies:\n  - baseline: {name: tspc}\nagents: {test: [2]}\ntest_episodes: 1\n";
        let size = Scenario::parse(&one, Path::new("big.yaml")).unwrap().size();
        // One map: its windows (8.6 GB) and world, and the plan of one TSPC cell.
        assert_eq!(size.map_bytes, (1 << 20) * (255 * 4 * 8 + 32 + 64));
    }

    #[test]
    fn numbers_past_the_limits_fail_at_their_field_before_any_cell_exists() {
        let cells = error(&[("repetitions: 2", "repetitions: 100000000")]);
        assert!(
            cells.starts_with("unit.yaml:15: repetitions: the scenario expands to 300000000 cells"),
            "{cells}"
        );
        assert!(cells.contains("--no-limits"), "{cells}");
        let episodes = error(&[("test_episodes: 4", "test_episodes: 4000000")]);
        assert!(
            episodes.contains("test_episodes: the scenario plays 48000000 test episodes"),
            "{episodes}"
        );
        let cpu = error(&[
            ("test_steps: 20", "test_steps: 4000000000"),
            ("test_episodes: 4", "test_episodes: 100"),
        ]);
        assert!(
            cpu.contains("world.test_steps: the scenario needs about"),
            "{cpu}"
        );
        // A few CPU-days, but rollouts of 5 million steps of 8 environments.
        let memory = error(&[("train_steps: 10", "train_steps: 5000000")]);
        assert!(
            memory.contains("world.train_steps: the sweep would hold about"),
            "{memory}"
        );
        // The largest T a file can hold overflows nothing.
        let longest = error(&[("train_steps: 10", "train_steps: 4294967295")]);
        assert!(longest.contains("world.train_steps: "), "{longest}");
        let text = SCENARIO.replace("repetitions: 2", "repetitions: 200000");
        let unbounded = Scenario::parse_within(&text, Path::new("unit.yaml"), &Limits::NONE);
        assert_eq!(unbounded.unwrap().repetitions, 200_000);
    }
}
