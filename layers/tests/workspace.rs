//! The workspace in layers: crates that point one way, no import cycle between the modules of
//! any folder (its own file included), one build script, and a provenance hash that covers
//! every module a cell run reaches. Read from the sources alone: `cargo test -p layers`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use layers::{CrateModules, ModulePath, Target, folder_cycles};

const CRATES: [&str; 14] = [
    "world",
    "nn",
    "baselines",
    "learning",
    "stats",
    "plan",
    "store",
    "engine",
    "report",
    "record",
    "bench",
    "harness",
    "python",
    "layers",
];

/// The crates whose modules a cell run reaches besides the numeric ones (`world`, `nn`,
/// `baselines` and `learning`, which `NUMERIC_SOURCES` lists whole).
const CELL_CRATES: [&str; 4] = ["stats", "plan", "store", "engine"];

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_owned()
}

fn modules_of(crate_name: &str) -> CrateModules {
    let src = workspace().join(crate_name).join("src");
    CrateModules::read(crate_name, &src).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn no_folder_has_an_import_cycle_between_its_modules() {
    let found: Vec<String> = CRATES
        .iter()
        .flat_map(|c| folder_cycles(&modules_of(c)))
        .collect();
    assert!(
        found.is_empty(),
        "modules that import each other in a cycle (take it apart: what the others need goes \
         into a leaf module of its own, below them; a folder's own file only declares and \
         re-exports):\n{found:#?}"
    );
}

/// `NUMERIC_SOURCES` as `harness/src/source_hash.rs` lists them.
fn numeric_sources() -> Vec<String> {
    let file = workspace().join("harness/src/source_hash.rs");
    let parsed = syn::parse_file(&std::fs::read_to_string(file).unwrap()).unwrap();
    let list = parsed.items.iter().find_map(|item| match item {
        syn::Item::Const(c) if c.ident == "NUMERIC_SOURCES" => Some(&c.expr),
        _ => None,
    });
    let Some(syn::Expr::Array(list)) = list.map(Box::as_ref) else {
        panic!("harness/src/source_hash.rs has no NUMERIC_SOURCES array");
    };
    list.elems
        .iter()
        .filter_map(|e| match e {
            syn::Expr::Lit(syn::ExprLit {
                lit: syn::Lit::Str(s),
                ..
            }) => Some(s.value()),
            _ => None,
        })
        .collect()
}

/// The modules a path names, with the folders above it (compiled with it), in whichever of
/// the cell crates it lands.
fn reached_by(
    target: &Target,
    here: &str,
    crates: &BTreeMap<&str, CrateModules>,
) -> Vec<(String, ModulePath)> {
    let (name, segments) = match target {
        Target::Local(segments) => (here, segments),
        Target::Extern(name, segments) if crates.contains_key(name.as_str()) => {
            (name.as_str(), segments)
        }
        Target::Extern(..) => return Vec::new(),
    };
    let Some(module) = crates[name].defining_module(segments) else {
        return Vec::new();
    };
    (0..=module.len())
        .map(|n| (name.to_owned(), module[..n].to_vec()))
        .collect()
}

/// The provenance hash of a cell (`harness/src/source_hash.rs`) covers every module of the plan and
/// the engine that running a cell reaches through its imports, from `engine::execution` on: a
/// module left out could change a cell's numbers without changing the hash its record keeps.
#[test]
fn the_numeric_sources_cover_every_module_a_cell_run_reaches() {
    let crates: BTreeMap<&str, CrateModules> = CELL_CRATES
        .iter()
        .map(|name| (*name, modules_of(name)))
        .collect();
    let start = ("engine".to_owned(), vec!["execution".to_owned()]);
    let mut reached = BTreeSet::from([start.clone()]);
    let mut pending = vec![start];
    while let Some((name, module)) = pending.pop() {
        for target in &crates[name.as_str()].modules[&module].refs {
            for step in reached_by(target, &name, &crates) {
                if reached.insert(step.clone()) {
                    pending.push(step);
                }
            }
        }
    }
    assert!(
        reached.iter().any(|(name, _)| name == "plan"),
        "a cell run reaches the plan (its configuration): the walk lost its way"
    );
    let listed = numeric_sources();
    let root = workspace();
    let uncovered: Vec<String> = reached
        .iter()
        .map(|(name, module)| crates[name.as_str()].modules[module].file.clone())
        .map(|file| {
            file.strip_prefix(&root)
                .unwrap()
                .to_string_lossy()
                .into_owned()
        })
        .filter(|file| {
            !listed
                .iter()
                .any(|source| file == source || file.starts_with(&format!("{source}/")))
        })
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    assert!(
        uncovered.is_empty(),
        "running a cell reaches these, which NUMERIC_SOURCES leaves out:\n{uncovered:#?}"
    );
}

/// Only the binary's crate has a build script: it alone watches the repository (the commit,
/// the numeric sources) and hands what it finds down at run time, so a commit or a change in a
/// layer rebuilds the binary and what depends on that layer, never the layers below.
#[test]
fn only_the_binary_has_a_build_script() {
    let scripts: Vec<&str> = CRATES
        .iter()
        .filter(|name| workspace().join(name).join("build.rs").exists())
        .copied()
        .collect();
    assert_eq!(scripts, ["harness"]);
}

/// The workspace crates a crate's `[dependencies]` names in its Cargo.toml.
fn workspace_dependencies(crate_name: &str) -> BTreeSet<String> {
    let manifest = workspace().join(crate_name).join("Cargo.toml");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let section = text
        .split("\n[")
        .find(|part| part.starts_with("dependencies]"))
        .unwrap_or_default();
    section
        .lines()
        .filter_map(|line| line.split([' ', '.', '=']).next())
        .filter(|name| CRATES.contains(name))
        .map(str::to_owned)
        .collect()
}

/// The crates point one way, and each may name only the layers below it: the network library
/// not even the world, the baselines no network library (they plan from the map alone), the
/// plan no store and no engine (a key cannot depend on how cells run), the store no engine,
/// the report nothing that runs a cell (the binary hands it the engine's replay), the Python
/// package the world alone, this checker nothing of the workspace. Cargo enforces what the
/// manifests say; this pins what they may say.
#[test]
fn each_crate_depends_only_on_the_layers_below_it() {
    let below: [(&str, &[&str]); 13] = [
        ("world", &[]),
        ("nn", &[]),
        ("baselines", &["world"]),
        ("learning", &["world", "nn"]),
        ("stats", &["world"]),
        ("plan", &["world", "baselines", "learning"]),
        ("store", &["world", "learning", "plan"]),
        (
            "engine",
            &[
                "world",
                "nn",
                "baselines",
                "learning",
                "plan",
                "store",
                "stats",
            ],
        ),
        ("report", &["world", "plan", "store", "stats"]),
        ("record", &["world", "plan", "store", "engine"]),
        ("bench", &["world", "nn", "baselines", "learning", "engine"]),
        ("python", &["world"]),
        ("layers", &[]),
    ];
    for (crate_name, allowed) in below {
        let found = workspace_dependencies(crate_name);
        let beyond: Vec<&String> = found
            .iter()
            .filter(|d| !allowed.contains(&d.as_str()))
            .collect();
        assert!(
            beyond.is_empty(),
            "{crate_name} depends on {beyond:?}, above or beside it"
        );
    }
    assert!(
        workspace_dependencies("engine").contains("store"),
        "the check reads the manifests"
    );
}
