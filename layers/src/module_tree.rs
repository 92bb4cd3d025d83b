//! A crate's modules as the compiler finds them: from its root file through every `mod`
//! declaration (files and inline blocks), test modules and items left out; per module its
//! children, the items it defines, what its `use`s bring in, and every path its code names.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use syn::visit::Visit;

use crate::paths::{Scope, Target, WrittenPath, normalise};

/// A module's path from its crate's root (`["scenario", "claims"]`; empty for the root).
pub type ModulePath = Vec<String>;

#[derive(Debug, thiserror::Error)]
pub enum LayersError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: cannot parse: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("{path}: declares `mod {name};` but neither {name}.rs nor {name}/mod.rs is there")]
    MissingModule { path: PathBuf, name: String },
}

/// One module: its file, and what it declares and names.
#[derive(Debug, Default)]
pub struct Module {
    /// The file it is in (an inline module shares its parent's).
    pub file: PathBuf,
    pub children: BTreeSet<String>,
    /// Names of the items it defines (types, functions, constants, traits, macros).
    pub items: BTreeSet<String>,
    /// What each name its `use`s bring in names (`pub use` re-exports included).
    pub imports: BTreeMap<String, Target>,
    /// The modules whose every public name a glob `use` brings in.
    pub globs: Vec<Target>,
    /// Every path its code names, `use`s included.
    pub refs: Vec<Target>,
}

/// A module while it is read: what its code writes, before its paths are resolved.
#[derive(Default)]
struct Written {
    uses: Vec<(Option<String>, WrittenPath)>,
    globs: Vec<WrittenPath>,
    paths: Vec<WrittenPath>,
}

/// Every module of one crate.
#[derive(Debug)]
pub struct CrateModules {
    pub name: String,
    pub modules: BTreeMap<ModulePath, Module>,
}

impl CrateModules {
    /// The modules of the crate whose sources are in `src` (its `lib.rs`, else `main.rs`).
    pub fn read(name: &str, src: &Path) -> Result<Self, LayersError> {
        let root = match src.join("lib.rs") {
            lib if lib.exists() => lib,
            _ => src.join("main.rs"),
        };
        let mut reader = Reader::default();
        reader.file(Vec::new(), &root, src.to_owned())?;
        let modules = reader.resolve();
        Ok(Self {
            name: name.to_owned(),
            modules,
        })
    }

    /// The module that defines what `segments` (from the crate's root) names: the module
    /// itself for a module, for an item the module that defines it, through every re-export
    /// (`pub use`) on the way; the last module reached for what it cannot follow further;
    /// `None` where a re-export leads into another crate.
    pub fn defining_module(&self, segments: &[String]) -> Option<ModulePath> {
        self.follow(segments, 0)
    }

    fn follow(&self, segments: &[String], depth: usize) -> Option<ModulePath> {
        let mut here: ModulePath = Vec::new();
        for (i, segment) in segments.iter().enumerate() {
            let Some(module) = self.modules.get(&here) else {
                break;
            };
            if module.children.contains(segment) {
                here.push(segment.clone());
                continue;
            }
            if module.items.contains(segment) || depth > 16 {
                return Some(here);
            }
            let rest = &segments[i + 1..];
            match module.imports.get(segment) {
                Some(Target::Local(to)) => {
                    return self.follow(&[to.as_slice(), rest].concat(), depth + 1);
                }
                Some(Target::Extern(..)) => return None,
                None => {}
            }
            let through_glob = module.globs.iter().find_map(|glob| match glob {
                Target::Local(to) => {
                    let path = [to.as_slice(), &segments[i..]].concat();
                    let found = self.follow(&path, depth + 1)?;
                    (found != *to).then_some(found)
                }
                Target::Extern(..) => None,
            });
            return Some(through_glob.unwrap_or(here));
        }
        Some(here)
    }

    /// Each module's imports of other modules of this crate: the children it declares and the
    /// defining module of every path it names.
    pub fn edges(&self) -> BTreeMap<&ModulePath, BTreeSet<ModulePath>> {
        let mut edges = BTreeMap::new();
        for (path, module) in &self.modules {
            let declared = module
                .children
                .iter()
                .map(|c| [path.as_slice(), std::slice::from_ref(c)].concat());
            let named = module.refs.iter().filter_map(|target| match target {
                Target::Local(segments) => self.defining_module(segments),
                Target::Extern(..) => None,
            });
            let targets: BTreeSet<ModulePath> =
                declared.chain(named).filter(|t| t != path).collect();
            edges.insert(path, targets);
        }
        edges
    }
}

#[derive(Default)]
struct Reader {
    modules: BTreeMap<ModulePath, (Module, Written)>,
}

impl Reader {
    /// Reads the module in `file`, whose `mod x;` children are files in `child_dir`.
    fn file(
        &mut self,
        path: ModulePath,
        file: &Path,
        child_dir: PathBuf,
    ) -> Result<(), LayersError> {
        let text = std::fs::read_to_string(file).map_err(|source| LayersError::Read {
            path: file.to_owned(),
            source,
        })?;
        let parsed = syn::parse_file(&text).map_err(|error| LayersError::Parse {
            path: file.to_owned(),
            message: error.to_string(),
        })?;
        self.items(path, file, &parsed.items, child_dir)
    }

    fn items(
        &mut self,
        path: ModulePath,
        file: &Path,
        items: &[syn::Item],
        child_dir: PathBuf,
    ) -> Result<(), LayersError> {
        let mut module = Module {
            file: file.to_owned(),
            ..Module::default()
        };
        let mut written = Written::default();
        let mut children = Vec::new();
        for item in items.iter().filter(|item| !is_test(attributes(item))) {
            match item {
                syn::Item::Mod(declared) => children.push(declared),
                syn::Item::Use(used) => {
                    let start = WrittenPath {
                        leading_colon: used.leading_colon.is_some(),
                        segments: Vec::new(),
                    };
                    flatten_use(&used.tree, start, &mut written);
                }
                other => {
                    module.items.extend(item_name(other));
                    let mut collector = PathCollector(&mut written.paths);
                    collector.visit_item(other);
                }
            }
        }
        for declared in children {
            let name = declared.ident.to_string();
            module.children.insert(name.clone());
            let child = [path.as_slice(), std::slice::from_ref(&name)].concat();
            match &declared.content {
                Some((_, inner)) => self.items(child, file, inner, child_dir.join(&name))?,
                None => {
                    let (child_file, grandchildren) = child_file(&child_dir, &name, declared)
                        .ok_or_else(|| LayersError::MissingModule {
                            path: file.to_owned(),
                            name: name.clone(),
                        })?;
                    self.file(child, &child_file, grandchildren)?;
                }
            }
        }
        self.modules.insert(path, (module, written));
        Ok(())
    }

    /// Every module with its paths resolved against its own scope.
    fn resolve(self) -> BTreeMap<ModulePath, Module> {
        self.modules
            .into_iter()
            .map(|(path, (mut module, written))| {
                resolve_module(&path, &mut module, written);
                (path, module)
            })
            .collect()
    }
}

fn resolve_module(path: &ModulePath, module: &mut Module, written: Written) {
    // A `use` may start from a name an earlier `use` brought in (`use crate::a; use a::B;`).
    for (name, used) in &written.uses {
        let scope = Scope {
            here: path,
            children: &module.children,
            items: &module.items,
            imports: &module.imports,
        };
        if let Some(target) = normalise(used, &scope) {
            module.refs.push(target.clone());
            if let Some(name) = name {
                module.imports.insert(name.clone(), target);
            }
        }
    }
    let scope = Scope {
        here: path,
        children: &module.children,
        items: &module.items,
        imports: &module.imports,
    };
    let globs: Vec<Target> = written
        .globs
        .iter()
        .filter_map(|g| normalise(g, &scope))
        .collect();
    let named: Vec<Target> = written
        .paths
        .iter()
        .filter_map(|p| normalise(p, &scope))
        .collect();
    module.refs.extend(globs.iter().cloned());
    module.refs.extend(named);
    module.globs = globs;
}

/// The file of `mod name;` declared in a module whose children live in `child_dir`, and the
/// folder of that file's own children.
fn child_file(child_dir: &Path, name: &str, declared: &syn::ItemMod) -> Option<(PathBuf, PathBuf)> {
    if let Some(file) = path_attribute(&declared.attrs) {
        let file = child_dir.join(file);
        let dir = file.parent()?.to_owned();
        return file.exists().then_some((file, dir));
    }
    let flat = child_dir.join(format!("{name}.rs"));
    let folder = child_dir.join(name).join("mod.rs");
    match (flat.exists(), folder.exists()) {
        (true, _) => Some((flat, child_dir.join(name))),
        (false, true) => Some((folder, child_dir.join(name))),
        _ => None,
    }
}

fn path_attribute(attributes: &[syn::Attribute]) -> Option<String> {
    attributes
        .iter()
        .find_map(|attribute| match &attribute.meta {
            syn::Meta::NameValue(pair) if pair.path.is_ident("path") => match &pair.value {
                syn::Expr::Lit(syn::ExprLit {
                    lit: syn::Lit::Str(text),
                    ..
                }) => Some(text.value()),
                _ => None,
            },
            _ => None,
        })
}

/// Whether an item is compiled for tests only (`#[cfg(test)]`, `#[test]`).
fn is_test(attributes: &[syn::Attribute]) -> bool {
    attributes.iter().any(|attribute| match &attribute.meta {
        syn::Meta::Path(path) => path.is_ident("test"),
        syn::Meta::List(list) if list.path.is_ident("cfg") => {
            let condition = list.tokens.to_string();
            !condition.starts_with("not")
                && (condition.split(|c: char| !c.is_alphanumeric() && c != '_'))
                    .any(|w| w == "test")
        }
        _ => false,
    })
}

fn attributes(item: &syn::Item) -> &[syn::Attribute] {
    match item {
        syn::Item::Const(i) => &i.attrs,
        syn::Item::Enum(i) => &i.attrs,
        syn::Item::ExternCrate(i) => &i.attrs,
        syn::Item::Fn(i) => &i.attrs,
        syn::Item::ForeignMod(i) => &i.attrs,
        syn::Item::Impl(i) => &i.attrs,
        syn::Item::Macro(i) => &i.attrs,
        syn::Item::Mod(i) => &i.attrs,
        syn::Item::Static(i) => &i.attrs,
        syn::Item::Struct(i) => &i.attrs,
        syn::Item::Trait(i) => &i.attrs,
        syn::Item::TraitAlias(i) => &i.attrs,
        syn::Item::Type(i) => &i.attrs,
        syn::Item::Union(i) => &i.attrs,
        syn::Item::Use(i) => &i.attrs,
        _ => &[],
    }
}

/// The name an item defines in its module, if any.
fn item_name(item: &syn::Item) -> Option<String> {
    let ident = match item {
        syn::Item::Const(i) => &i.ident,
        syn::Item::Enum(i) => &i.ident,
        syn::Item::Fn(i) => &i.sig.ident,
        syn::Item::Static(i) => &i.ident,
        syn::Item::Struct(i) => &i.ident,
        syn::Item::Trait(i) => &i.ident,
        syn::Item::TraitAlias(i) => &i.ident,
        syn::Item::Type(i) => &i.ident,
        syn::Item::Union(i) => &i.ident,
        syn::Item::Macro(i) => i.ident.as_ref()?,
        _ => return None,
    };
    Some(ident.to_string())
}

/// Each leaf of a use tree: the name it brings in (none for `_`) and its path; globs apart.
fn flatten_use(tree: &syn::UseTree, prefix: WrittenPath, written: &mut Written) {
    let with = |name: &syn::Ident| {
        let mut path = prefix.clone();
        if name != "self" {
            path.segments.push(name.to_string());
        }
        path
    };
    match tree {
        syn::UseTree::Path(step) => flatten_use(&step.tree, with(&step.ident), written),
        syn::UseTree::Name(leaf) => {
            let path = with(&leaf.ident);
            written.uses.push((path.segments.last().cloned(), path));
        }
        syn::UseTree::Rename(leaf) => {
            let name = (leaf.rename != "_").then(|| leaf.rename.to_string());
            written.uses.push((name, with(&leaf.ident)));
        }
        syn::UseTree::Glob(_) => written.globs.push(prefix),
        syn::UseTree::Group(group) => {
            for inner in &group.items {
                flatten_use(inner, prefix.clone(), written);
            }
        }
    }
}

/// Every path in an item's code, test items and inline modules left out (the reader takes
/// those as modules of their own).
struct PathCollector<'a>(&'a mut Vec<WrittenPath>);

impl<'ast> Visit<'ast> for PathCollector<'_> {
    fn visit_path(&mut self, path: &'ast syn::Path) {
        self.0.push(WrittenPath {
            leading_colon: path.leading_colon.is_some(),
            segments: path.segments.iter().map(|s| s.ident.to_string()).collect(),
        });
        syn::visit::visit_path(self, path);
    }

    fn visit_item(&mut self, item: &'ast syn::Item) {
        if !is_test(attributes(item)) && !matches!(item, syn::Item::Mod(_)) {
            syn::visit::visit_item(self, item);
        }
    }

    /// An attribute's arguments are tokens, not code, to syn; a path among them still names
    /// what it uses (`#[error("at most {max}", max = super::MAX_SIDE)]`).
    fn visit_attribute(&mut self, attribute: &'ast syn::Attribute) {
        if let syn::Meta::List(list) = &attribute.meta {
            token_paths(list.tokens.clone(), self.0);
        }
        syn::visit::visit_attribute(self, attribute);
    }

    /// `pub(crate)` and `pub(super)` say who may see an item, not what it uses.
    fn visit_visibility(&mut self, _: &'ast syn::Visibility) {}

    /// A `use` inside a function body names paths too, resolved in the module's scope.
    fn visit_item_use(&mut self, used: &'ast syn::ItemUse) {
        let mut written = Written::default();
        let start = WrittenPath {
            leading_colon: used.leading_colon.is_some(),
            segments: Vec::new(),
        };
        flatten_use(&used.tree, start, &mut written);
        self.0
            .extend(written.uses.into_iter().map(|(_, path)| path));
        self.0.extend(written.globs);
    }

    fn visit_impl_item_fn(&mut self, function: &'ast syn::ImplItemFn) {
        if !is_test(&function.attrs) {
            syn::visit::visit_impl_item_fn(self, function);
        }
    }
}

/// Every path of two segments or more among `tokens` (`a::b`, `::a::b`), groups included: a
/// path of one segment among an attribute's tokens is as likely a word of its own (`Debug`,
/// `transparent`) as an item.
fn token_paths(tokens: proc_macro2::TokenStream, found: &mut Vec<WrittenPath>) {
    use proc_macro2::TokenTree;
    let tokens: Vec<TokenTree> = tokens.into_iter().collect();
    let separator = |i: usize| {
        matches!((tokens.get(i), tokens.get(i + 1)),
            (Some(TokenTree::Punct(a)), Some(TokenTree::Punct(b))) if a.as_char() == ':' && b.as_char() == ':')
    };
    let mut i = 0;
    while i < tokens.len() {
        let leading_colon = separator(i) && matches!(tokens.get(i + 2), Some(TokenTree::Ident(_)));
        let start = if leading_colon { i + 2 } else { i };
        match &tokens[start] {
            TokenTree::Group(group) => token_paths(group.stream(), found),
            TokenTree::Ident(first) => {
                let mut segments = vec![first.to_string()];
                let mut end = start + 1;
                while separator(end) {
                    let Some(TokenTree::Ident(next)) = tokens.get(end + 2) else {
                        break;
                    };
                    segments.push(next.to_string());
                    end += 3;
                }
                if segments.len() > 1 || leading_colon {
                    found.push(WrittenPath {
                        leading_colon,
                        segments,
                    });
                }
                i = end;
                continue;
            }
            _ => {}
        }
        i = start + 1;
    }
}
