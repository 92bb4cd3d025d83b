//! The folder of a `harness train` run, guarded so that one folder never mixes two runs: a
//! resume must ask for the run that was saved (else its weights would be trained, and saved,
//! under a configuration they were not built for), and a new run must not silently replace an
//! old one.
//!
//! The checkpoint records the training configuration and the seed; `world.json` beside it
//! records the world (the map as named and the hash of its content, L, D and Rmax), which the
//! checkpoint does not.

use std::path::Path;

use anyhow::Context;
use engine::checkpoint_dir;
use engine::training_run::LOG_FILE;
use learning::checkpoint::{METADATA_FILE, OPTIMIZER_FILE, WEIGHTS_FILE};
use learning::ppo::{Profile, TrainingConfig};
use plan::scenario::map_hash;
use serde_json::{Map, Value, json};
use store::atomic_file::write_atomic;
use world::World;

use crate::cli::world_args::WorldArgs;

/// The record of the world a run trained in.
const WORLD_FILE: &str = "world.json";

/// The files that make a folder a training run (`world.json` alone, left by a run stopped
/// before its first save, does not).
const RUN_FILES: [&str; 4] = [METADATA_FILE, WEIGHTS_FILE, OPTIMIZER_FILE, LOG_FILE];

/// A run's settings as one JSON object, field by field: the training configuration's fields,
/// `seed`, and the world record's fields when there is one.
type Settings = Map<String, Value>;

/// What a resuming command asks for besides its configuration overrides.
pub(crate) struct Asked<'a> {
    /// `key=value` overrides of the saved configuration (the named flags and `--set`).
    pub(crate) overrides: &'a [String],
    /// `--profile`, when given.
    pub(crate) profile: Option<Profile>,
    /// `--seed`, when given.
    pub(crate) seed: Option<u64>,
    /// The world the command loaded, as [`world_record`] gives it.
    pub(crate) world: &'a Settings,
}

/// The world record of a command's world: the map as named on the command line, the hash of
/// its content (the sweep's map hash), and the world parameters.
pub(crate) fn world_record(args: &WorldArgs, world: &World) -> Settings {
    let record = json!({
        "map": args.map.to_string_lossy(),
        "map_hash": map_hash(world.map()),
        "fov": args.fov,
        "decay": args.decay,
        "rmax": args.rmax,
    });
    match record {
        Value::Object(fields) => fields,
        _ => unreachable!("a JSON object literal"),
    }
}

/// Refuses a folder that holds a training run, unless `replace` says to replace it.
pub(crate) fn refuse_existing_run(folder: &Path, replace: bool) -> anyhow::Result<()> {
    let found = present(folder, &RUN_FILES);
    if found.is_empty() || replace {
        return Ok(());
    }
    anyhow::bail!(
        "{} already holds a training run ({}): continue it with --resume, or pass --replace \
         to train a new run in its place",
        folder.display(),
        found.join(", ")
    )
}

/// Makes `folder` the home of a new run: removes an old run's files (so that a new run
/// stopped before its first save leaves no old checkpoint under the new world record), then
/// writes the world record.
pub(crate) fn begin(folder: &Path, world: &Settings) -> anyhow::Result<()> {
    for name in present(folder, &[&RUN_FILES[..], &[WORLD_FILE]].concat()) {
        let path = folder.join(name);
        std::fs::remove_file(&path)
            .with_context(|| format!("cannot replace the run in {}", folder.display()))?;
    }
    std::fs::create_dir_all(folder)
        .with_context(|| format!("cannot create {}", folder.display()))?;
    let path = folder.join(WORLD_FILE);
    let text = serde_json::to_string_pretty(world)? + "\n";
    write_atomic(&path, text.as_bytes()).with_context(|| format!("cannot write {}", path.display()))
}

/// Refuses to resume the run in `folder` unless the command asks for the run that was saved,
/// naming every field that differs and both of its values. Reads only.
pub(crate) fn check_resume(folder: &Path, asked: &Asked) -> anyhow::Result<()> {
    let refused = || format!("cannot resume {}", folder.display());
    anyhow::ensure!(
        folder.join(METADATA_FILE).exists(),
        "{}: it holds no {METADATA_FILE} (start a run there without --resume)",
        refused()
    );
    let metadata = checkpoint_dir::read_metadata(folder).with_context(refused)?;
    let saved_world = read_world(folder).with_context(refused)?;
    let config = metadata
        .config
        .with_overrides(asked.overrides)
        .with_context(refused)?;
    let saved = settings(&metadata.config, metadata.seed, saved_world.as_ref());
    let mut wanted = settings(
        &config,
        asked.seed.unwrap_or(metadata.seed),
        saved_world.as_ref().map(|_| asked.world),
    );
    if let Some(profile) = asked.profile {
        // As the saved configuration writes it, which is not always the name given.
        let written = serde_json::to_value(profile).expect("a profile serialises");
        wanted.insert("profile".into(), written);
    }
    let clauses = differences(&saved, &wanted);
    anyhow::ensure!(clauses.is_empty(), "{}: {}", refused(), clauses.join("; "));
    if saved_world.is_none() {
        eprintln!(
            "warning: {} has no {WORLD_FILE} (it was written before runs recorded their world): \
             its map and world settings are not checked",
            folder.display()
        );
    }
    Ok(())
}

/// The saved world record, if the run has one.
fn read_world(folder: &Path) -> anyhow::Result<Option<Settings>> {
    let path = folder.join(WORLD_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let limit = store::MAX_FILE_BYTES;
    let text = world::read_bounded_text(&path, limit, "a store's file")?;
    serde_json::from_str(&text)
        .map(Some)
        .with_context(|| format!("{}: not a world record", path.display()))
}

fn settings(config: &TrainingConfig, seed: u64, world: Option<&Settings>) -> Settings {
    let Ok(Value::Object(mut fields)) = serde_json::to_value(config) else {
        unreachable!("a training configuration serialises as an object")
    };
    fields.insert("seed".into(), seed.into());
    fields.extend(
        world
            .into_iter()
            .flatten()
            .map(|(k, v)| (k.clone(), v.clone())),
    );
    fields
}

/// One clause per field whose asked value differs from the saved one and may not change.
fn differences(saved: &Settings, asked: &Settings) -> Vec<String> {
    let only_asked = asked.keys().filter(|field| !saved.contains_key(*field));
    saved
        .keys()
        .chain(only_asked)
        .filter(|field| saved.get(*field) != asked.get(*field) && !may_change(field, saved, asked))
        .map(|field| {
            let (before, after) = (
                shown(field, saved.get(field)),
                shown(field, asked.get(field)),
            );
            let note = match field.as_str() {
                "episodes" => {
                    " (a resume may raise episodes, not lower them; --until stops sooner)"
                }
                _ => "",
            };
            format!("it was saved with {field} {before}, this command asks for {after}{note}")
        })
        .collect()
}

/// What a resume may change: `episodes` may grow, since training longer is what resuming is
/// for; the map may be named by another path (a moved file, another working folder) when its
/// content is the one saved. The learning rate's annealing then runs to the new length.
fn may_change(field: &str, saved: &Settings, asked: &Settings) -> bool {
    match field {
        "episodes" => {
            let episodes = |settings: &Settings| settings.get("episodes").and_then(Value::as_u64);
            episodes(saved) <= episodes(asked)
        }
        "map" => saved.get("map_hash") == asked.get("map_hash"),
        _ => false,
    }
}

/// A value as a user would type it: the architecture as `--architecture` spells it, a
/// profile by its own name (`fast-v1`, which the file writes `fast`), a word bare, anything
/// else as JSON; a field left out of the file has its default.
fn shown(field: &str, value: Option<&Value>) -> String {
    match value {
        None => "the default".to_owned(),
        Some(Value::String(word)) if field == "architecture" => word.replace('_', "-"),
        Some(written) if field == "profile" => serde_json::from_value::<Profile>(written.clone())
            .map_or_else(|_| written.to_string(), |profile| profile.name().to_owned()),
        Some(Value::String(word)) => word.clone(),
        Some(other) => other.to_string(),
    }
}

/// The names in `names` that exist in `folder`.
fn present<'a>(folder: &Path, names: &[&'a str]) -> Vec<&'a str> {
    names
        .iter()
        .copied()
        .filter(|name| folder.join(name).exists())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(value: Value) -> Settings {
        match value {
            Value::Object(fields) => fields,
            _ => panic!("not an object"),
        }
    }

    fn saved() -> Settings {
        object(json!({
            "architecture": "ma_g_ppo", "episodes": 8, "seed": 3,
            "map": "maps/a.txt", "map_hash": "aaa", "fov": 7,
        }))
    }

    fn asked(changes: Value) -> Settings {
        let mut asked = saved();
        asked.extend(object(changes));
        asked
    }

    #[test]
    fn the_same_run_matches() {
        assert!(differences(&saved(), &saved()).is_empty());
    }

    #[test]
    fn another_architecture_is_named_as_the_command_line_spells_it() {
        let found = differences(&saved(), &asked(json!({"architecture": "ma_ppo"})));
        assert_eq!(
            found,
            ["it was saved with architecture ma-g-ppo, this command asks for ma-ppo"]
        );
    }

    #[test]
    fn a_profile_is_named_by_its_own_name_not_as_the_file_writes_it() {
        let mut first = saved();
        first.insert("profile".into(), json!("fast"));
        let found = differences(&first, &asked(json!({"profile": "fast-v2"})));
        assert_eq!(
            found,
            ["it was saved with profile fast-v1, this command asks for fast-v2"]
        );
    }

    #[test]
    fn episodes_may_grow_but_not_shrink() {
        assert!(differences(&saved(), &asked(json!({"episodes": 20}))).is_empty());
        let found = differences(&saved(), &asked(json!({"episodes": 4})));
        assert_eq!(found.len(), 1);
        assert!(found[0].starts_with("it was saved with episodes 8, this command asks for 4"));
    }

    #[test]
    fn a_map_may_move_but_not_change() {
        let moved = asked(json!({"map": "elsewhere/a.txt"}));
        assert!(differences(&saved(), &moved).is_empty());
        let other = asked(json!({"map": "maps/b.txt", "map_hash": "bbb"}));
        assert_eq!(
            differences(&saved(), &other),
            [
                "it was saved with map maps/a.txt, this command asks for maps/b.txt",
                "it was saved with map_hash aaa, this command asks for bbb",
            ]
        );
    }

    #[test]
    fn a_field_left_out_as_default_is_compared_too() {
        let found = differences(&saved(), &asked(json!({"loss_probability": 0.5, "fov": 9})));
        assert!(found.contains(&"it was saved with fov 7, this command asks for 9".to_owned()));
        assert!(found.contains(
            &"it was saved with loss_probability the default, this command asks for 0.5".to_owned()
        ));
    }
}
