//! Paths as written (`super::a::B`, `crate::c`, `plan::cell::X`) and what they name: a path
//! from this crate's root, or into another crate. Rust 2018 resolves a path's first segment
//! in the module's own scope first (its child modules, its items, its imports), then among
//! the crates; `normalise` does the same with what the module tree knows.

use std::collections::{BTreeMap, BTreeSet};

/// What a path names.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Target {
    /// Segments from this crate's root.
    Local(Vec<String>),
    /// A crate's name and the segments from its root (std, a dependency, a workspace crate).
    Extern(String, Vec<String>),
}

impl Target {
    /// This target with `rest` appended.
    pub(crate) fn joined(&self, rest: &[String]) -> Target {
        let extend = |segments: &Vec<String>| [segments.as_slice(), rest].concat();
        match self {
            Target::Local(segments) => Target::Local(extend(segments)),
            Target::Extern(name, segments) => Target::Extern(name.clone(), extend(segments)),
        }
    }
}

/// A path as written in a module.
#[derive(Clone, Debug)]
pub(crate) struct WrittenPath {
    pub leading_colon: bool,
    pub segments: Vec<String>,
}

/// The names a module's own scope holds, against which a path's first segment is resolved.
pub(crate) struct Scope<'a> {
    pub here: &'a [String],
    pub children: &'a BTreeSet<String>,
    pub items: &'a BTreeSet<String>,
    pub imports: &'a BTreeMap<String, Target>,
}

/// What `path` names from the module `scope.here`, or `None` for what names nothing of a
/// crate (`Self`, a local variable or a type parameter of one segment).
pub(crate) fn normalise(path: &WrittenPath, scope: &Scope) -> Option<Target> {
    let (first, rest) = path.segments.split_first()?;
    if path.leading_colon {
        return Some(Target::Extern(first.clone(), rest.to_vec()));
    }
    let local = |base: &[String], rest: &[String]| Some(Target::Local([base, rest].concat()));
    match first.as_str() {
        "crate" => local(&[], rest),
        "self" => local(scope.here, rest),
        "super" => {
            let ups = 1 + rest.iter().take_while(|s| *s == "super").count();
            let base = &scope.here[..scope.here.len().saturating_sub(ups)];
            local(base, &rest[ups - 1..])
        }
        "Self" => None,
        _ if scope.children.contains(first) || scope.items.contains(first) => {
            local(scope.here, &path.segments)
        }
        _ => match scope.imports.get(first) {
            Some(target) => Some(target.joined(rest)),
            None if rest.is_empty() => None,
            None => Some(Target::Extern(first.clone(), rest.to_vec())),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn written(text: &str) -> WrittenPath {
        WrittenPath {
            leading_colon: text.starts_with("::"),
            segments: text
                .trim_start_matches("::")
                .split("::")
                .map(String::from)
                .collect(),
        }
    }

    fn strings(text: &str) -> Vec<String> {
        text.split("::")
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect()
    }

    #[test]
    fn a_first_segment_resolves_in_the_module_scope_before_the_crates() {
        let here = strings("report::header");
        let children = BTreeSet::from(["rows".to_owned()]);
        let items = BTreeSet::from(["Header".to_owned()]);
        let imports =
            BTreeMap::from([("tables".to_owned(), Target::Local(strings("store_tables")))]);
        let scope = Scope {
            here: &here,
            children: &children,
            items: &items,
            imports: &imports,
        };
        let local = |text: &str| Some(Target::Local(strings(text)));
        assert_eq!(normalise(&written("crate::a::B"), &scope), local("a::B"));
        assert_eq!(normalise(&written("super::a"), &scope), local("report::a"));
        assert_eq!(normalise(&written("super::super::a"), &scope), local("a"));
        assert_eq!(
            normalise(&written("self::rows::R"), &scope),
            local("report::header::rows::R")
        );
        assert_eq!(
            normalise(&written("rows::R"), &scope),
            local("report::header::rows::R")
        );
        assert_eq!(
            normalise(&written("Header::new"), &scope),
            local("report::header::Header::new")
        );
        assert_eq!(
            normalise(&written("tables::T"), &scope),
            local("store_tables::T")
        );
        assert_eq!(
            normalise(&written("plan::cell::X"), &scope),
            Some(Target::Extern("plan".into(), strings("cell::X")))
        );
        assert_eq!(
            normalise(&written("::rows::R"), &scope),
            Some(Target::Extern("rows".into(), strings("R")))
        );
        assert_eq!(normalise(&written("Self::new"), &scope), None);
        assert_eq!(normalise(&written("value"), &scope), None);
    }
}
