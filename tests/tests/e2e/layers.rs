//! The modules of each crate form layers: no import cycle between two modules of one folder
//! (a module and its own submodules, which name each other as `super`, are one node). A cycle
//! makes every module on it depend on all the others: a cell's key on the sweep orchestrator,
//! the report on the running engine. The check reads the sources alone (std only), so anyone
//! can run it: `cargo test -p vpm-tests --test e2e layers::`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const CRATES: [&str; 13] = [
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
];

/// The crates whose modules a cell run reaches besides the numeric ones (`world`, `nn`,
/// `baselines` and `learning`, which `NUMERIC_SOURCES` lists whole).
const CELL_CRATES: [&str; 4] = ["stats", "plan", "store", "engine"];

/// A crate's modules by path (`store::tables`), each with its file (relative to `src`) and
/// its source, test modules left out.
fn modules(src: &Path) -> BTreeMap<Vec<String>, (PathBuf, String)> {
    let mut found = BTreeMap::new();
    let mut pending = vec![src.to_owned()];
    while let Some(folder) = pending.pop() {
        for entry in std::fs::read_dir(&folder).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                pending.push(path);
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            let relative = path.strip_prefix(src).unwrap().with_extension("");
            let mut segments: Vec<String> = relative
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            if matches!(
                segments.last().map(String::as_str),
                Some("mod" | "lib" | "main")
            ) {
                segments.pop();
            }
            let text = std::fs::read_to_string(&path).unwrap();
            let code = match text.find("#[cfg(test)]\nmod tests") {
                Some(at) => text[..at].to_owned(),
                None => text,
            };
            found.insert(segments, (path.strip_prefix(src).unwrap().to_owned(), code));
        }
    }
    found
}

/// The module paths `code` names from the crate's root: `crate::a::b`, and `super::` and
/// `self::` paths relative to `module`, with grouped imports (`crate::a::{b, c::d}`) spread.
fn named_paths(module: &[String], code: &str) -> Vec<Vec<String>> {
    let mut paths = Vec::new();
    let bytes = code.as_bytes();
    let starts = ["crate::", "super::", "self::"];
    let mut i = 0;
    while i < code.len() {
        let here = &bytes[i..];
        let Some(start) = starts.iter().find(|s| here.starts_with(s.as_bytes())) else {
            i += 1;
            continue;
        };
        let before_ok = i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_');
        if !before_ok {
            i += 1;
            continue;
        }
        let mut base: Vec<String> = match *start {
            "crate::" => Vec::new(),
            "self::" => module.to_vec(),
            _ => module[..module.len().saturating_sub(1)].to_vec(),
        };
        let mut j = i + start.len();
        while code[j..].starts_with("super::") {
            base.pop();
            j += "super::".len();
        }
        let (tree, end) = use_tree(&code[j..]);
        for tail in tree {
            let mut path = base.clone();
            path.extend(tail);
            paths.push(path);
        }
        i = j + end.max(1);
    }
    // `use child::...` names a child module relative to this one (2018 paths).
    for line in code.lines() {
        let line = line.trim_start();
        let line = line
            .strip_prefix("pub(crate) ")
            .or_else(|| line.strip_prefix("pub "))
            .unwrap_or(line);
        let Some(tree) = line.strip_prefix("use ") else {
            continue;
        };
        if starts.iter().any(|start| tree.starts_with(start)) {
            continue;
        }
        for tail in use_tree(tree).0 {
            let mut path = module.to_vec();
            path.extend(tail);
            paths.push(path);
        }
    }
    paths
}

/// The paths of a use tree at the start of `text` (`a::b`, `a::{b, c::d}`), and where it ends.
fn use_tree(text: &str) -> (Vec<Vec<String>>, usize) {
    let mut prefix = Vec::new();
    let mut i = 0;
    let bytes = text.as_bytes();
    loop {
        let start = i;
        while i < text.len() && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_') {
            i += 1;
        }
        if i > start {
            prefix.push(text[start..i].to_owned());
        }
        let group = match (i == start, &text[i..]) {
            (true, rest) if rest.starts_with('{') => Some(1),
            (_, rest) if rest.starts_with("::{") => Some(3),
            _ => None,
        };
        if let Some(skip) = group {
            i += skip;
            let mut paths = Vec::new();
            loop {
                while i < text.len() && (bytes[i] == b' ' || bytes[i] == b'\n' || bytes[i] == b',')
                {
                    i += 1;
                }
                if i >= text.len() || bytes[i] == b'}' {
                    return (paths, i + 1);
                }
                let (inner, end) = use_tree(&text[i..]);
                for tail in inner {
                    let mut path = prefix.clone();
                    path.extend(tail);
                    paths.push(path);
                }
                i += end.max(1);
            }
        }
        if text[i..].starts_with("::") {
            i += 2;
            continue;
        }
        return (vec![prefix], i);
    }
}

/// The module a path names: its longest prefix that is a module of the crate.
fn resolve<'a>(path: &[String], known: &'a BTreeSet<Vec<String>>) -> Option<&'a Vec<String>> {
    (1..=path.len()).rev().find_map(|n| known.get(&path[..n]))
}

/// Strongly connected components of more than one node, by reachability (simple enough for
/// a few dozen nodes: a node's component is the nodes it reaches that reach it back).
fn cycles(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<BTreeSet<String>> {
    let reach = |from: &String| {
        let mut seen = BTreeSet::new();
        let mut pending = vec![from.clone()];
        while let Some(node) = pending.pop() {
            for next in edges.get(&node).into_iter().flatten() {
                if seen.insert(next.clone()) {
                    pending.push(next.clone());
                }
            }
        }
        seen
    };
    let reached: BTreeMap<&String, BTreeSet<String>> =
        edges.keys().map(|node| (node, reach(node))).collect();
    let mut found: Vec<BTreeSet<String>> = Vec::new();
    for (node, from_node) in &reached {
        let component: BTreeSet<String> = from_node
            .iter()
            .filter(|other| reached.get(other).is_some_and(|r| r.contains(*node)))
            .cloned()
            .collect();
        if component.len() > 1 && !found.contains(&component) {
            found.push(component);
        }
    }
    found
}

fn crate_src(crate_name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(crate_name)
        .join("src")
}

/// Each folder's links on cycles: the edges between its child modules (each with its
/// submodules) that lie on one.
fn folder_cycles(crate_name: &str) -> Vec<String> {
    let modules = modules(&crate_src(crate_name));
    let known: BTreeSet<Vec<String>> = modules.keys().cloned().collect();
    let folders: BTreeSet<Vec<String>> = known
        .iter()
        .filter(|m| {
            known
                .iter()
                .any(|o| o.len() == m.len() + 1 && o.starts_with(m))
        })
        .cloned()
        .collect();
    let mut problems = Vec::new();
    for folder in &folders {
        let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (module, (_, code)) in &modules {
            if module.len() <= folder.len() || !module.starts_with(folder) {
                continue;
            }
            let from = module[folder.len()].clone();
            for path in named_paths(module, code) {
                let Some(target) = resolve(&path, &known) else {
                    continue;
                };
                if target.len() > folder.len() && target.starts_with(folder) {
                    let to = target[folder.len()].clone();
                    if to != from {
                        edges.entry(from.clone()).or_default().insert(to);
                    }
                }
            }
            edges.entry(from).or_default();
        }
        for cycle in cycles(&edges) {
            let place = match folder.is_empty() {
                true => crate_name.to_owned(),
                false => format!("{crate_name}::{}", folder.join("::")),
            };
            for from in &cycle {
                for to in edges[from].iter().filter(|to| cycle.contains(*to)) {
                    problems.push(format!("{place}: {from} -> {to}"));
                }
            }
        }
    }
    problems
}

#[test]
fn no_crate_has_an_import_cycle_between_modules() {
    let found: Vec<String> = CRATES.iter().flat_map(|c| folder_cycles(c)).collect();
    assert!(
        found.is_empty(),
        "modules that import each other in a cycle (take it apart: move what both need below \
         them):\n{found:#?}"
    );
}

/// The checker itself finds a cycle, resolves grouped, `super` and `self` paths, and leaves
/// test modules out.
#[test]
fn the_checker_reads_paths_as_rust_resolves_them() {
    let module = vec!["store".to_owned(), "tables".to_owned()];
    let code = "use crate::{cell::CellConfig, scenario::{Output, cost::Cost}};\n\
                use super::columns::strings;\nfn f() { self::helper(); }\n";
    let paths = named_paths(&module, code);
    let text: Vec<String> = paths.iter().map(|p| p.join("::")).collect();
    assert_eq!(
        text,
        [
            "cell::CellConfig",
            "scenario::Output",
            "scenario::cost::Cost",
            "store::columns::strings",
            "store::tables::helper",
        ]
    );
    let edges: BTreeMap<String, BTreeSet<String>> = [("a", "b"), ("b", "c"), ("c", "a")]
        .iter()
        .map(|(f, t)| (f.to_string(), BTreeSet::from([t.to_string()])))
        .chain([("d".to_owned(), BTreeSet::from(["a".to_owned()]))])
        .collect();
    let found = cycles(&edges);
    assert_eq!(found.len(), 1);
    assert_eq!(found[0], BTreeSet::from(["a", "b", "c"].map(String::from)));
}

/// The paths `code` names in crate `name` (`plan::cell::SweepCell`, grouped imports spread),
/// from that crate's root; comments left out, where one crate names another's modules to say
/// where a thing is done.
fn paths_into(name: &str, code: &str) -> Vec<Vec<String>> {
    let code: String = code
        .lines()
        .filter(|line| !line.trim_start().starts_with("//"))
        .map(|line| format!("{line}\n"))
        .collect();
    let start = format!("{name}::");
    let bytes = code.as_bytes();
    let mut paths = Vec::new();
    for (i, _) in code.match_indices(&start) {
        let before = i.checked_sub(1).map(|b| bytes[b]);
        if before.is_some_and(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b':') {
            continue;
        }
        paths.extend(use_tree(&code[i + start.len()..]).0);
    }
    paths
}

/// The provenance hash of a cell (`harness::source_hash`) covers every module of the plan and
/// the engine that running a cell reaches through its imports, from `engine::execution` on: a
/// module left out could change a cell's numbers without changing the hash its record keeps.
#[test]
fn the_numeric_sources_cover_every_module_a_cell_run_reaches() {
    let crates: BTreeMap<&str, _> = CELL_CRATES
        .iter()
        .map(|name| (*name, modules(&crate_src(name))))
        .collect();
    let known: BTreeMap<&str, BTreeSet<Vec<String>>> = crates
        .iter()
        .map(|(name, modules)| (*name, modules.keys().cloned().collect()))
        .collect();
    let start = ("engine", vec!["execution".to_owned()]);
    let mut reached = BTreeSet::from([start.clone()]);
    let mut pending = vec![start];
    while let Some((name, module)) = pending.pop() {
        let code = &crates[name][&module].1;
        let own = named_paths(&module, code)
            .into_iter()
            .map(|path| (name, path));
        let other = CELL_CRATES.iter().flat_map(|other| {
            paths_into(other, code)
                .into_iter()
                .map(|path| (*other, path))
        });
        for (target_crate, path) in own.chain(other).collect::<Vec<_>>() {
            let modules = &known[target_crate];
            // The module named and every folder above it (whose mod.rs is compiled with it).
            let Some(target) = resolve(&path, modules) else {
                continue;
            };
            for n in 1..=target.len() {
                let step = (target_crate, target[..n].to_vec());
                if modules.contains(&step.1) && reached.insert(step.clone()) {
                    pending.push(step);
                }
            }
        }
    }
    assert!(
        reached.iter().any(|(name, _)| *name == "plan"),
        "a cell run reaches the plan (its configuration): the walk lost its way"
    );
    let listed = harness::source_hash::NUMERIC_SOURCES;
    let uncovered: Vec<String> = reached
        .iter()
        .map(|(name, module)| format!("{name}/src/{}", crates[name][module].0.display()))
        .filter(|file| {
            !listed
                .iter()
                .any(|source| file == source || file.starts_with(&format!("{source}/")))
        })
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
        .filter(|name| crate_src(name).join("../build.rs").exists())
        .copied()
        .collect();
    assert_eq!(scripts, ["harness"]);
}

/// The workspace crates a crate's `[dependencies]` names in its Cargo.toml.
fn workspace_dependencies(crate_name: &str) -> BTreeSet<String> {
    let manifest = crate_src(crate_name).join("../Cargo.toml");
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

/// The crates point one way, and each may name only the layers below it: the baselines no
/// network library (they plan from the map alone), the network library not even the world, the plan no store
/// and no engine (a key cannot depend on how cells run), the store no engine, the report
/// nothing that runs a cell (the binary hands it the engine's replay), the Python package the
/// world alone. Cargo enforces what the manifests say; this pins what they may say.
#[test]
fn each_crate_depends_only_on_the_layers_below_it() {
    let below: [(&str, &[&str]); 12] = [
        ("world", &[]),
        ("nn", &[]),
        ("baselines", &["world"]),
        ("learning", &["world", "nn"]),
        ("stats", &["world"]),
        ("plan", &["world", "baselines", "learning"]),
        ("store", &["world", "nn", "learning", "plan"]),
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
    ];
    for (crate_name, allowed) in below {
        let found = workspace_dependencies(crate_name);
        let beyond: Vec<&String> = (found.iter())
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
