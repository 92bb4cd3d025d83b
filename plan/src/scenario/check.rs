//! The checks a scenario passes once, at load: every problem is reported with file, line and
//! field before anything runs or any output folder is touched.

use std::collections::HashSet;
use std::path::Path;

use learning::ppo::TrainingConfig;
use serde_saphyr::Spanned;
use world::{Map, MapError, WorldParams};

use super::disturbance::check_disturbances;
use super::earlier::check_earlier;
use super::error::ScenarioError;
use super::format::{MapSpec, PolicySpec, ProfileName, ScenarioFile, WorldSpec};
use super::size::{Limits, check_size};
use super::{Scenario, ScenarioMap, ScenarioPolicy, WorldConfig};
use crate::scenario::claims::{ClaimContext, check_claims};

pub(crate) fn check(
    spec: ScenarioFile,
    file: &Path,
    limits: &Limits,
) -> Result<Scenario, ScenarioError> {
    let name = check_name(&spec.name, file)?;
    let maps = load_maps(&spec.maps, file)?;
    let policies = check_policies(&spec.policies, file)?;
    let learned = policies.iter().any(|p| p.learned().is_some());
    let world = check_world(&spec.world, learned, file)?;
    let train_agents = if learned {
        agent_counts(&spec.agents.train, "agents.train", &maps, file)?
    } else {
        Vec::new()
    };
    let trainings = check_training(
        &spec.policies,
        &policies,
        &world,
        &train_agents,
        &maps,
        file,
    )?;
    let test_agents = agent_counts(&spec.agents.test, "agents.test", &maps, file)?;
    let repetitions = positive(&spec.repetitions, "repetitions", file)?;
    let test_episodes = positive(&spec.test_episodes, "test_episodes", file)?;
    let outputs = non_empty(&spec.outputs, "outputs", file)?.clone();
    let disturbances =
        check_disturbances(&spec.disturbances, world.test_steps, &test_agents, file)?;
    let context = ClaimContext {
        policies: policies
            .iter()
            .map(|p| (p.label(), p.learned().is_some()))
            .collect(),
        maps: maps.iter().map(|m| m.map.name().to_owned()).collect(),
        train_agents: train_agents.clone(),
        test_agents: test_agents.clone(),
        disturbances: disturbances
            .iter()
            .map(|d| (d.name.clone(), d.robots_lost()))
            .collect(),
    };
    let claims = check_claims(&spec.claims, Some(&context), file)?;
    check_earlier(spec.earlier.as_ref(), file)?;
    let scenario = Scenario {
        name,
        maps,
        world,
        policies,
        train_agents,
        trainings,
        test_agents,
        seed: spec.seed,
        repetitions,
        test_episodes,
        outputs,
        disturbances,
        claims,
    };
    check_size(&scenario, &spec, limits, file)?;
    Ok(scenario)
}

/// The name becomes a folder name, so it keeps to letters, digits, `-` and `_`.
fn check_name(name: &Spanned<String>, file: &Path) -> Result<String, ScenarioError> {
    let valid = !name.value.is_empty()
        && name
            .value
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if !valid {
        let problem = format!(
            "{:?} is not a usable name (letters, digits, '-' and '_' only)",
            name.value
        );
        return Err(ScenarioError::at(file, name, "name", problem));
    }
    Ok(name.value.clone())
}

fn load_maps(
    maps: &Spanned<Vec<Spanned<MapSpec>>>,
    file: &Path,
) -> Result<Vec<ScenarioMap>, ScenarioError> {
    let mut loaded: Vec<ScenarioMap> = Vec::new();
    for (i, spec) in non_empty(maps, "maps", file)?.iter().enumerate() {
        let field = format!("maps[{i}]");
        let map = load_map(&spec.value, file)
            .map_err(|problem| ScenarioError::at(file, spec, &field, problem))?;
        if loaded.iter().any(|m| m.map.name() == map.map.name()) {
            let problem = format!("a second map named {:?}", map.map.name());
            return Err(ScenarioError::at(file, spec, &field, problem));
        }
        loaded.push(map);
    }
    Ok(loaded)
}

fn load_map(spec: &MapSpec, file: &Path) -> Result<ScenarioMap, String> {
    match spec {
        MapSpec::File(written) => {
            let folder = file.parent().unwrap_or(Path::new(""));
            let full = folder.join(written).display().to_string();
            let map = Map::load(&full).map_err(|e| e.to_string())?;
            Ok(ScenarioMap::new(map, written.clone()))
        }
        MapSpec::Inline { name, grid } => {
            let map = Map::parse_text(name, grid, Path::new("grid"))
                .map_err(|e: MapError| format!("inline {e}"))?;
            Ok(ScenarioMap::new(map, "inline".to_owned()))
        }
    }
}

fn check_world(spec: &WorldSpec, learned: bool, file: &Path) -> Result<WorldConfig, ScenarioError> {
    let fov = spec.fov.value;
    if let Err(e) = WorldParams::new(fov, 1.0, 1.0) {
        return Err(ScenarioError::at(file, &spec.fov, "world.fov", e));
    }
    if let Err(e) = WorldParams::new(fov, spec.decay.value, 1.0) {
        return Err(ScenarioError::at(file, &spec.decay, "world.decay", e));
    }
    if let Err(e) = WorldParams::new(fov, spec.decay.value, spec.rmax.value) {
        return Err(ScenarioError::at(file, &spec.rmax, "world.rmax", e));
    }
    let train_steps = if learned {
        positive(&spec.train_steps, "world.train_steps", file)?
    } else {
        spec.train_steps.value
    };
    Ok(WorldConfig {
        fov,
        decay: spec.decay.value,
        rmax: spec.rmax.value,
        train_steps,
        test_steps: positive(&spec.test_steps, "world.test_steps", file)?,
    })
}

fn check_policies(
    policies: &Spanned<Vec<Spanned<PolicySpec<ProfileName>>>>,
    file: &Path,
) -> Result<Vec<ScenarioPolicy>, ScenarioError> {
    let mut checked: Vec<ScenarioPolicy> = Vec::new();
    for (i, spec) in non_empty(policies, "policies", file)?.iter().enumerate() {
        let field = format!("policies[{i}]");
        let fail = |problem: String| ScenarioError::at(file, spec, &field, problem);
        let policy = ScenarioPolicy::try_from(spec.value.clone().resolved())
            .map_err(|e| fail(e.to_string()))?;
        let label = policy.label();
        if checked.iter().any(|p| p.label() == label) {
            return Err(fail(format!("policy {label:?} is listed twice")));
        }
        checked.push(policy);
    }
    Ok(checked)
}

/// Resolves every learned policy's training run for every N_train and map, so that a bad
/// `set` or a network that does not fit a map's images fails now, not hours into a sweep.
/// The resolved runs are the scenario's: its cells carry them, and nothing resolves them
/// again.
fn check_training(
    specs: &Spanned<Vec<Spanned<PolicySpec<ProfileName>>>>,
    policies: &[ScenarioPolicy],
    world: &WorldConfig,
    train_agents: &[u32],
    maps: &[ScenarioMap],
    file: &Path,
) -> Result<Vec<Vec<TrainingConfig>>, ScenarioError> {
    let mut trainings = Vec::with_capacity(policies.len());
    for (i, (spec, policy)) in specs.value.iter().zip(policies).enumerate() {
        let field = format!("policies[{i}]");
        let fail = |problem: String| ScenarioError::at(file, spec, &field, problem);
        let Some(learned) = policy.learned() else {
            trainings.push(Vec::new());
            continue;
        };
        let mut per_count = Vec::with_capacity(train_agents.len());
        for &n_train in train_agents {
            let config = learned
                .training_config(world, n_train)
                .map_err(|e| fail(e.to_string()))?;
            for map in maps {
                let side =
                    world::ImageGeometry::new(&map.map, world.fov, config.mini_map_block).side;
                config
                    .model_config(side)
                    .map_err(|e| fail(format!("map {:?}: {e}", map.map.name())))?;
            }
            per_count.push(config);
        }
        trainings.push(per_count);
    }
    Ok(trainings)
}

/// Agent counts: at least one, each at least 1, no repeats, and room for them on every map.
fn agent_counts(
    counts: &Spanned<Vec<Spanned<u32>>>,
    field: &str,
    maps: &[ScenarioMap],
    file: &Path,
) -> Result<Vec<u32>, ScenarioError> {
    let mut seen = HashSet::new();
    for (i, count) in non_empty(counts, field, file)?.iter().enumerate() {
        let field = format!("{field}[{i}]");
        let n = count.value;
        let fail = |problem: String| ScenarioError::at(file, count, &field, problem);
        if n == 0 {
            return Err(fail("an agent count must be at least 1".to_owned()));
        }
        if !seen.insert(n) {
            return Err(fail(format!("{n} agents listed twice")));
        }
        for map in maps {
            let free = map.map.free_cells().len();
            if n as usize > free {
                let name = map.map.name();
                return Err(fail(format!(
                    "{n} agents do not fit on map {name:?} ({free} free cells)"
                )));
            }
        }
    }
    Ok(counts.value.iter().map(|c| c.value).collect())
}

fn positive(value: &Spanned<u32>, field: &str, file: &Path) -> Result<u32, ScenarioError> {
    if value.value == 0 {
        return Err(ScenarioError::at(file, value, field, "must be at least 1"));
    }
    Ok(value.value)
}

fn non_empty<'a, T>(
    list: &'a Spanned<Vec<T>>,
    field: &str,
    file: &Path,
) -> Result<&'a Vec<T>, ScenarioError> {
    if list.value.is_empty() {
        return Err(ScenarioError::at(file, list, field, "the list is empty"));
    }
    Ok(&list.value)
}
