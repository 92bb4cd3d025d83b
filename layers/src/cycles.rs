//! Import cycles between the modules of one folder. In a folder (a crate's `src/`, or a
//! module with children) each child module, with everything below it, is one node, and so is
//! the folder's own file (`lib.rs`, `mod.rs`), which declares the children: a child that
//! imports what the folder's own file defines closes a loop through it. A cycle makes every
//! module on it depend on all the others.

use std::collections::{BTreeMap, BTreeSet};

use crate::module_tree::{CrateModules, ModulePath};

/// The node of a folder's own file in `folder_cycles`' messages.
const OWN_FILE: &str = "(its own file)";

/// Every edge on a cycle in any folder of `modules`, as `crate::folder: from -> to`.
pub fn folder_cycles(modules: &CrateModules) -> Vec<String> {
    let edges = modules.edges();
    let folders = modules
        .modules
        .iter()
        .filter(|(_, m)| !m.children.is_empty());
    let mut found = Vec::new();
    for (folder, _) in folders {
        let graph = folder_graph(modules, folder, &edges);
        let place = match folder.is_empty() {
            true => modules.name.clone(),
            false => format!("{}::{}", modules.name, folder.join("::")),
        };
        for cycle in components(&graph) {
            for from in &cycle {
                for to in graph[from].iter().filter(|to| cycle.contains(*to)) {
                    found.push(format!("{place}: {from} -> {to}"));
                }
            }
        }
    }
    found
}

/// The edges between the nodes of `folder`: its children and its own file. A child written
/// inline in the folder's own file (`mod avx2 { ... }`, code for one instruction set) is part
/// of that file's node: a file is read, changed and reviewed whole.
fn folder_graph(
    modules: &CrateModules,
    folder: &ModulePath,
    edges: &BTreeMap<&ModulePath, BTreeSet<ModulePath>>,
) -> BTreeMap<String, BTreeSet<String>> {
    let own_file = &modules.modules[folder].file;
    let inline = |child: &String| {
        let path = [folder.as_slice(), std::slice::from_ref(child)].concat();
        modules
            .modules
            .get(&path)
            .is_some_and(|m| m.file == *own_file)
    };
    let node = |module: &ModulePath| match module.get(folder.len()) {
        _ if !module.starts_with(folder) => None,
        Some(child) if !inline(child) => Some(child.clone()),
        _ => Some(OWN_FILE.to_owned()),
    };
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (from, targets) in edges {
        let Some(from) = node(from) else { continue };
        let targets: BTreeSet<String> = targets
            .iter()
            .filter_map(node)
            .filter(|to| *to != from)
            .collect();
        graph.entry(from).or_default().extend(targets);
    }
    graph
}

/// Strongly connected components of more than one node, by reachability (simple enough for
/// a few dozen nodes: a node's component is the nodes it reaches that reach it back).
pub fn components(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<BTreeSet<String>> {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A crate written into a scratch folder, removed when dropped.
    struct Scratch(std::path::PathBuf);

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn scratch_crate(name: &str, files: &[(&str, &str)]) -> (Scratch, CrateModules) {
        let dir = std::env::temp_dir().join(format!("layers-{name}-{}", std::process::id()));
        for (file, text) in files {
            let path = dir.join(file);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, text).unwrap();
        }
        let modules = CrateModules::read(name, &dir).unwrap();
        (Scratch(dir), modules)
    }

    #[test]
    fn a_child_importing_what_its_root_defines_closes_a_cycle_through_the_root() {
        let (_dir, modules) = scratch_crate(
            "toolbox",
            &[
                (
                    "lib.rs",
                    "mod section;\npub struct Writer;\npub fn write() { section::run() }\n",
                ),
                (
                    "section.rs",
                    "use crate::Writer;\npub fn run() { let _w: Option<Writer> = None; }\n",
                ),
            ],
        );
        let found = folder_cycles(&modules);
        assert_eq!(
            found,
            [
                "toolbox: (its own file) -> section",
                "toolbox: section -> (its own file)"
            ]
        );
    }

    #[test]
    fn a_path_through_a_root_re_export_counts_for_the_defining_module() {
        let (_dir, modules) = scratch_crate(
            "facade",
            &[
                ("lib.rs", "mod a;\nmod b;\npub use a::Thing;\n"),
                ("a.rs", "pub struct Thing;\n"),
                ("b.rs", "use crate::Thing;\npub fn f(_: Thing) {}\n"),
            ],
        );
        assert!(folder_cycles(&modules).is_empty());
        let edges = modules.edges();
        assert!(edges[&vec!["b".to_owned()]].contains(&vec!["a".to_owned()]));
    }

    #[test]
    fn a_path_among_an_attributes_arguments_is_an_import() {
        let (_dir, modules) = scratch_crate(
            "attributes",
            &[
                ("lib.rs", "mod error;\nmod grid;\npub use grid::MAX;\n"),
                (
                    "error.rs",
                    "#[derive(Debug, thiserror::Error)]\npub enum E {\n    \
                     #[error(\"at most {max}\", max = super::MAX)]\n    Large,\n}\n",
                ),
                (
                    "grid.rs",
                    "pub const MAX: usize = 8;\npub fn f() -> crate::error::E { todo!() }\n",
                ),
            ],
        );
        let edges = modules.edges();
        assert!(edges[&vec!["error".to_owned()]].contains(&vec!["grid".to_owned()]));
        assert_eq!(
            folder_cycles(&modules),
            ["attributes: error -> grid", "attributes: grid -> error"]
        );
    }

    #[test]
    fn comments_strings_and_test_modules_are_not_code() {
        let (_dir, modules) = scratch_crate(
            "quiet",
            &[
                ("lib.rs", "mod a;\nmod b;\n"),
                (
                    "a.rs",
                    "// use crate::b::B;\npub const TEXT: &str = \"#[cfg(test)]\\nmod tests crate::b::B\";\n\
                     pub fn f() -> u8 { crate::b::value() }\n#[cfg(test)]\nmod tests { use crate::b::B; }\n",
                ),
                (
                    "b.rs",
                    "pub struct B;\npub fn value() -> u8 { 1 }\n#[cfg(test)]\nmod tests { use crate::a::f; }\n\
                     #[test]\nfn t() { crate::a::f(); }\n",
                ),
            ],
        );
        assert!(
            folder_cycles(&modules).is_empty(),
            "{:?}",
            folder_cycles(&modules)
        );
        let edges = modules.edges();
        assert!(
            edges[&vec!["a".to_owned()]].contains(&vec!["b".to_owned()]),
            "{edges:?}"
        );
    }

    #[test]
    fn a_re_export_of_another_crate_is_no_edge_to_the_root() {
        let (_dir, modules) = scratch_crate(
            "reexport",
            &[
                ("lib.rs", "pub use engine::cpu_clock;\nmod bench;\n"),
                (
                    "bench.rs",
                    "use crate::cpu_clock::thread_cpu_time;\npub fn f() { thread_cpu_time(); }\n",
                ),
            ],
        );
        assert!(
            folder_cycles(&modules).is_empty(),
            "{:?}",
            folder_cycles(&modules)
        );
    }

    #[test]
    fn a_child_written_inline_is_part_of_its_file() {
        let (_dir, modules) = scratch_crate(
            "inline",
            &[(
                "lib.rs",
                "pub struct Tile;\nmod avx2 { pub fn multiply(_: &super::Tile) {} }\n\
                 pub fn multiply(t: &Tile) { avx2::multiply(t) }\n",
            )],
        );
        assert!(
            folder_cycles(&modules).is_empty(),
            "{:?}",
            folder_cycles(&modules)
        );
    }

    #[test]
    fn a_cycle_inside_a_folder_is_named_with_the_folder() {
        let (_dir, modules) = scratch_crate(
            "nested",
            &[
                ("lib.rs", "pub mod chart;\n"),
                ("chart/mod.rs", "mod axis;\nmod style;\n"),
                (
                    "chart/axis.rs",
                    "use super::style::Style;\npub struct Axis(Style);\n",
                ),
                (
                    "chart/style.rs",
                    "pub struct Style;\npub fn of(_: &super::axis::Axis) {}\n",
                ),
            ],
        );
        assert_eq!(
            folder_cycles(&modules),
            [
                "nested::chart: axis -> style",
                "nested::chart: style -> axis"
            ]
        );
    }
}
