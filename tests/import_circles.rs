//! No two source files import each other, directly or around a circle,
//! and none is over 1,000 lines.
//!
//! Every crate of the repository is read with `syn`, from its root
//! (lib.rs, main.rs) down its `mod` declarations. A file depends on another
//! when one of its paths (a `use` or an inline `crate::…`, `super::…`,
//! `self::…` or child-module path) names an item of the other; a name that a
//! `mod.rs` only re-exports (`pub use child::Item`) counts as the child's.
//! Declaring a child module (`mod x;`) is not a dependency, and neither is
//! code under `#[cfg(test)]` (a unit test may build its fixture with
//! `synth`, which depends on the module under test). Tarjan's
//! strongly connected components of that graph must all be single files.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

use syn::visit::Visit;

/// One source file: its module path from the crate root and what it holds.
struct ModFile {
    path: PathBuf,
    module: Vec<String>,
    ast: syn::File,
    /// Child modules declared in this file (file-backed or inline).
    children: BTreeSet<String>,
}

fn parse(path: &Path) -> syn::File {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    syn::parse_file(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Walk a crate from its root file down its `mod` declarations.
fn crate_files(root: &Path) -> Vec<ModFile> {
    let mut out = Vec::new();
    let dir = root.parent().unwrap().to_path_buf();
    walk(root, &dir, Vec::new(), &mut out);
    out
}

fn walk(file: &Path, dir: &Path, module: Vec<String>, out: &mut Vec<ModFile>) {
    let ast = parse(file);
    let mut children = BTreeSet::new();
    let mut file_children = Vec::new();
    for item in &ast.items {
        if let syn::Item::Mod(m) = item {
            let name = m.ident.to_string();
            children.insert(name.clone());
            if m.content.is_none() {
                file_children.push(name);
            }
        }
    }
    out.push(ModFile {
        path: file.to_path_buf(),
        module: module.clone(),
        ast,
        children,
    });
    for name in file_children {
        let flat = dir.join(format!("{name}.rs"));
        let nested = dir.join(&name).join("mod.rs");
        let child = if flat.exists() { flat } else { nested };
        assert!(child.exists(), "{}: mod {name} has no file", file.display());
        let mut m = module.clone();
        m.push(name.clone());
        walk(&child, &dir.join(&name), m, out);
    }
}

/// Every path a file names, as written, relative to the module it sits in
/// (inline `mod` blocks push their name).
#[derive(Default)]
struct Paths {
    scope: Vec<String>,
    found: Vec<(Vec<String>, Vec<String>)>,
}

impl Paths {
    fn use_tree(&mut self, prefix: &mut Vec<String>, tree: &syn::UseTree) {
        match tree {
            syn::UseTree::Path(p) => {
                prefix.push(p.ident.to_string());
                self.use_tree(prefix, &p.tree);
                prefix.pop();
            }
            syn::UseTree::Name(n) => {
                let mut p = prefix.clone();
                if n.ident != "self" {
                    p.push(n.ident.to_string());
                }
                self.found.push((self.scope.clone(), p));
            }
            syn::UseTree::Rename(r) => {
                let mut p = prefix.clone();
                p.push(r.ident.to_string());
                self.found.push((self.scope.clone(), p));
            }
            syn::UseTree::Glob(_) => self.found.push((self.scope.clone(), prefix.clone())),
            syn::UseTree::Group(g) => {
                for t in &g.items {
                    self.use_tree(prefix, t);
                }
            }
        }
    }
}

/// Whether an item is compiled only for tests (`#[cfg(test)]`, or `test`
/// inside `cfg(all(...))`).
fn test_only(attrs: &[syn::Attribute]) -> bool {
    attrs.iter().any(|a| {
        let args = match &a.meta {
            syn::Meta::List(l) if a.path().is_ident("cfg") => l.tokens.to_string(),
            _ => return false,
        };
        // `cfg(test)` or `cfg(all(test, ...))`.
        args == "test"
            || (args.starts_with("all")
                && args
                    .split(|c: char| !c.is_alphanumeric() && c != '_')
                    .any(|w| w == "test"))
    })
}

fn item_attrs(item: &syn::Item) -> &[syn::Attribute] {
    match item {
        syn::Item::Const(i) => &i.attrs,
        syn::Item::Enum(i) => &i.attrs,
        syn::Item::Fn(i) => &i.attrs,
        syn::Item::Impl(i) => &i.attrs,
        syn::Item::Mod(i) => &i.attrs,
        syn::Item::Static(i) => &i.attrs,
        syn::Item::Struct(i) => &i.attrs,
        syn::Item::Trait(i) => &i.attrs,
        syn::Item::Type(i) => &i.attrs,
        syn::Item::Use(i) => &i.attrs,
        _ => &[],
    }
}

impl<'ast> Visit<'ast> for Paths {
    fn visit_item(&mut self, item: &'ast syn::Item) {
        if !test_only(item_attrs(item)) {
            syn::visit::visit_item(self, item);
        }
    }
    fn visit_item_use(&mut self, u: &'ast syn::ItemUse) {
        self.use_tree(&mut Vec::new(), &u.tree);
    }
    fn visit_item_mod(&mut self, m: &'ast syn::ItemMod) {
        self.scope.push(m.ident.to_string());
        syn::visit::visit_item_mod(self, m);
        self.scope.pop();
    }
    /// Paths inside attribute arguments (`#[error("{}", fit::message(.0))]`)
    /// are tokens, not parsed paths: read `a :: b` runs from the text.
    fn visit_attribute(&mut self, a: &'ast syn::Attribute) {
        let syn::Meta::List(list) = &a.meta else {
            return;
        };
        if ["derive", "cfg", "cfg_attr", "allow", "doc"]
            .iter()
            .any(|n| a.path().is_ident(n))
        {
            return;
        }
        let text = list.tokens.to_string().replace(" :: ", "::");
        for word in text.split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':')) {
            let segs: Vec<String> = word.split("::").map(str::to_string).collect();
            if segs.len() > 1 && segs.iter().all(|s| !s.is_empty()) {
                self.found.push((self.scope.clone(), segs));
            }
        }
    }
    fn visit_path(&mut self, p: &'ast syn::Path) {
        if p.segments.len() > 1 {
            let segs = p.segments.iter().map(|s| s.ident.to_string()).collect();
            self.found.push((self.scope.clone(), segs));
        }
        syn::visit::visit_path(self, p);
    }
}

/// The crate's files and, per module path, the file index and its
/// re-exports (`pub use` name -> absolute path).
struct Crate {
    files: Vec<ModFile>,
    by_module: HashMap<Vec<String>, usize>,
    reexports: HashMap<Vec<String>, HashMap<String, Vec<String>>>,
}

/// Turn a path written in module `here` into an absolute module path, or
/// None when it leaves the crate (std, other crates, local names).
fn absolute(c: &Crate, here: &[String], path: &[String]) -> Option<Vec<String>> {
    let first = path.first()?;
    let mut base: Vec<String> = here.to_vec();
    let mut rest = path;
    match first.as_str() {
        "crate" => {
            base.clear();
            rest = &path[1..];
        }
        "self" => rest = &path[1..],
        "super" => {
            while rest.first().map(String::as_str) == Some("super") {
                base.pop()?;
                rest = &rest[1..];
            }
        }
        name => {
            // A path through a child module of this scope (`child::item`).
            let scope_file = c.by_module.get(&base[..]).map(|&i| &c.files[i]);
            let is_child = scope_file.is_some_and(|f| f.children.contains(name));
            if !is_child {
                return None;
            }
        }
    }
    base.extend(rest.iter().cloned());
    Some(base)
}

/// The file an absolute path lands in: its longest module-file prefix,
/// following `pub use` re-exports of the next segment.
fn target(c: &Crate, abs: &[String], depth: usize) -> Option<usize> {
    let mut k = abs.len();
    while !c.by_module.contains_key(&abs[..k]) {
        k = k.checked_sub(1)?;
    }
    if depth < 8 && k < abs.len() {
        if let Some(to) = c.reexports.get(&abs[..k]).and_then(|r| r.get(&abs[k])) {
            let mut full = to.clone();
            full.extend(abs[k + 1..].iter().cloned());
            if full != abs {
                return target(c, &full, depth + 1);
            }
        }
    }
    Some(c.by_module[&abs[..k]])
}

fn load(root: &Path) -> Crate {
    let files = crate_files(root);
    let by_module: HashMap<_, _> = files
        .iter()
        .enumerate()
        .map(|(i, f)| (f.module.clone(), i))
        .collect();
    let mut c = Crate {
        files,
        by_module,
        reexports: HashMap::new(),
    };
    let mut reexports = HashMap::new();
    for f in &c.files {
        let mut r = HashMap::new();
        for item in &f.ast.items {
            if let syn::Item::Use(u) = item {
                if matches!(u.vis, syn::Visibility::Inherited) {
                    continue;
                }
                let mut p = Paths::default();
                p.use_tree(&mut Vec::new(), &u.tree);
                for (_, path) in p.found {
                    if let (Some(name), Some(abs)) = (path.last(), absolute(&c, &f.module, &path)) {
                        r.insert(name.clone(), abs);
                    }
                }
            }
        }
        reexports.insert(f.module.clone(), r);
    }
    c.reexports = reexports;
    c
}

/// Edges file -> files it names, each with one path that shows why.
fn edges(c: &Crate) -> Vec<BTreeMap<usize, String>> {
    c.files
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let mut p = Paths::default();
            p.visit_file(&f.ast);
            let mut out = BTreeMap::new();
            for (scope, path) in p.found {
                let mut here = f.module.clone();
                here.extend(scope);
                let Some(abs) = absolute(c, &here, &path) else {
                    continue;
                };
                let Some(t) = target(c, &abs, 0) else {
                    continue;
                };
                if t != i {
                    out.entry(t).or_insert_with(|| path.join("::"));
                }
            }
            out
        })
        .collect()
}

/// Tarjan's strongly connected components (iterative enough for a crate).
fn components(n: usize, adj: &[Vec<usize>]) -> Vec<Vec<usize>> {
    struct T<'a> {
        adj: &'a [Vec<usize>],
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        on: Vec<bool>,
        stack: Vec<usize>,
        next: usize,
        out: Vec<Vec<usize>>,
    }
    fn visit(t: &mut T, v: usize) {
        t.index[v] = Some(t.next);
        t.low[v] = t.next;
        t.next += 1;
        t.stack.push(v);
        t.on[v] = true;
        for &w in t.adj[v].iter() {
            match t.index[w] {
                None => {
                    visit(t, w);
                    t.low[v] = t.low[v].min(t.low[w]);
                }
                Some(iw) if t.on[w] => t.low[v] = t.low[v].min(iw),
                _ => {}
            }
        }
        if Some(t.low[v]) == t.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on[w] = false;
                comp.push(w);
                if w == v {
                    break;
                }
            }
            t.out.push(comp);
        }
    }
    let mut t = T {
        adj,
        index: vec![None; n],
        low: vec![0; n],
        on: vec![false; n],
        stack: Vec::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in 0..n {
        if t.index[v].is_none() {
            visit(&mut t, v);
        }
    }
    t.out
}

/// The circles of one crate, each as lines "a.rs -> b.rs (via path)".
fn circles(root: &Path) -> Vec<String> {
    let c = load(root);
    let e = edges(&c);
    let adj: Vec<Vec<usize>> = e.iter().map(|m| m.keys().copied().collect()).collect();
    let base = Path::new(env!("CARGO_MANIFEST_DIR"));
    let name = |i: usize| {
        c.files[i]
            .path
            .strip_prefix(base)
            .unwrap_or(&c.files[i].path)
            .display()
            .to_string()
    };
    let mut out = Vec::new();
    for comp in components(c.files.len(), &adj) {
        if comp.len() < 2 {
            continue;
        }
        let set: BTreeSet<usize> = comp.iter().copied().collect();
        let mut lines = vec![format!("circle of {} files:", comp.len())];
        for &a in &set {
            for (&b, why) in &e[a] {
                if set.contains(&b) {
                    lines.push(format!("  {} -> {} (via {why})", name(a), name(b)));
                }
            }
        }
        out.push(lines.join("\n"));
    }
    out
}

fn roots() -> Vec<PathBuf> {
    let base = Path::new(env!("CARGO_MANIFEST_DIR"));
    [
        "src/lib.rs",
        "src/main.rs",
        "data-loaders/src/lib.rs",
        "python/src/lib.rs",
    ]
    .iter()
    .map(|r| base.join(r))
    .filter(|p| p.exists())
    .collect()
}

/// Most lines a source file may have: past it, a file holds more than one
/// concept and is split by concept (docs/architecture.md).
const MAX_LINES: usize = 1000;

/// Every Rust file of the repository (sources, tests, benches, examples,
/// fuzz targets) is at most [`MAX_LINES`] long.
#[test]
fn no_source_file_is_over_the_line_limit() {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let p = e.path();
            let name = e.file_name();
            if p.is_dir() && name != "target" && !name.to_string_lossy().starts_with('.') {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let base = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for d in [
        "src",
        "data-loaders",
        "python/src",
        "tests",
        "benches",
        "examples",
        "fuzz",
    ] {
        walk(&base.join(d), &mut files);
    }
    assert!(files.len() > 100, "found only {} files", files.len());
    let long: Vec<String> = files
        .iter()
        .filter_map(|f| {
            let n = std::fs::read_to_string(f).ok()?.lines().count();
            (n > MAX_LINES)
                .then(|| format!("{}: {n} lines", f.strip_prefix(base).unwrap_or(f).display()))
        })
        .collect();
    assert!(
        long.is_empty(),
        "files over {MAX_LINES} lines:\n{}",
        long.join("\n")
    );
}

#[test]
fn no_source_file_is_in_an_import_circle() {
    let mut all = Vec::new();
    for root in roots() {
        all.extend(circles(&root));
    }
    assert!(all.is_empty(), "import circles:\n{}", all.join("\n"));
}

/// The checker itself sees a circle when there is one: two modules of a
/// small crate written here that name each other, one through a parent's
/// re-export, and two through an attribute's arguments; a test-only use
/// makes none.
#[test]
fn the_checker_finds_a_planted_circle() {
    let dir = tempfile::tempdir().unwrap();
    let w = |p: &str, s: &str| {
        let path = dir.path().join(p);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, s).unwrap();
    };
    w(
        "lib.rs",
        "pub mod a;\npub mod b;\npub mod c;\npub mod d;\npub mod e;\npub mod f;\n",
    );
    w("a/mod.rs", "mod inner;\npub use inner::Thing;\n");
    w("a/inner.rs", "pub struct Thing(crate::b::Other);\n");
    w(
        "b.rs",
        "use crate::a::Thing;\npub struct Other;\npub fn f(_: Thing) {}\n",
    );
    // e names f only inside an attribute's arguments, f names e: a circle.
    w(
        "e.rs",
        "#[doc = \"x\"]\n#[error(\"{}\", crate::f::message(.0))]\npub struct E(pub u8);\n",
    );
    w(
        "f.rs",
        "pub fn message(_: &u8) -> String { let _ = crate::e::E(0); String::new() }\n",
    );
    w(
        "c.rs",
        "pub fn g() -> crate::b::Other { crate::d::h(); crate::b::Other }\n",
    );
    // d names c only in its tests: no circle.
    w(
        "d.rs",
        "pub fn h() {}\n#[cfg(test)]\nmod tests {\n    use crate::c::g;\n}\n",
    );
    let found = circles(&dir.path().join("lib.rs"));
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(
        found.iter().all(|c| c.contains("circle of 2 files")),
        "{found:?}"
    );
    assert!(
        found
            .iter()
            .any(|c| c.contains("inner.rs") && c.contains("b.rs")),
        "{found:?}"
    );
    assert!(
        found
            .iter()
            .any(|c| c.contains("e.rs") && c.contains("f.rs")),
        "{found:?}"
    );
}
