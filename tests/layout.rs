//! The house rules a compiler does not check: no source file passes 600 lines, no
//! module imports from a module that imports it back, directly or around a longer
//! circle, and no folder of the library imports from a folder of its own or a higher
//! layer ([`LAYERS`]) — so that imports run down the layers.
//!
//! Imports are read from the code (not the docs) with `syn`: every path in a `use` and
//! every qualified path in an expression or a type that names a module of this crate
//! (`crate::…`, `super::…`, `self::…`, or a child module declared with `mod`). A path
//! stands for the deepest module file it reaches, so `crate::body::lattice::Lattice`
//! is an import of `src/body/lattice.rs`, and a re-export in a `mod.rs` is an import
//! of the file it re-exports. Test code (`#[cfg(test)]` items and modules) is left
//! out: a unit test may drive its module through the layers above it. The library,
//! with `systems/` mounted as `crate::systems`, and the `cleave` program are checked as
//! the two crates they are.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use syn::visit::Visit;

/// Longest source file the house allows, in lines.
const MAX_LINES: usize = 600;

/// One crate's module files: module path (e.g. `["body", "lattice"]`) → file.
struct Crate {
    files: BTreeMap<Vec<String>, PathBuf>,
}

impl Crate {
    /// Every module file below `root` (a `lib.rs` or `main.rs`), following `mod`
    /// declarations and `#[path]` attributes.
    fn load(root: &Path) -> Crate {
        let mut files = BTreeMap::new();
        let mut pending = vec![(Vec::new(), root.to_path_buf())];
        while let Some((module, file)) = pending.pop() {
            let source = read(&file);
            let parsed = syn::parse_file(&source).unwrap_or_else(|e| panic!("{file:?}: {e}"));
            let dir = if file.file_name().is_some_and(|n| n == "mod.rs")
                || Some(file.as_path()) == Some(root)
            {
                file.parent().expect("a folder").to_path_buf()
            } else {
                file.with_extension("")
            };
            for item in &parsed.items {
                let syn::Item::Mod(m) = item else { continue };
                if m.content.is_some() || is_test(&m.attrs) {
                    continue; // inline: part of this file; or test code
                }
                let name = m.ident.to_string();
                let child = path_attribute(&m.attrs)
                    .map(|p| file.parent().expect("a folder").join(p))
                    .unwrap_or_else(|| {
                        let flat = dir.join(format!("{name}.rs"));
                        if flat.exists() {
                            flat
                        } else {
                            dir.join(&name).join("mod.rs")
                        }
                    });
                let mut path = module.clone();
                path.push(name);
                pending.push((path, child));
            }
            files.insert(module, file);
        }
        Crate { files }
    }

    /// The module file a path from module `at` names (the deepest module file it
    /// reaches), if it names one of this crate's modules at all.
    fn resolve(&self, at: &[String], path: &[String]) -> Option<&Vec<String>> {
        let (mut base, rest): (Vec<String>, &[String]) = match path.first()?.as_str() {
            "crate" => (Vec::new(), &path[1..]),
            "self" => (at.to_vec(), &path[1..]),
            "super" => {
                let mut base = at.to_vec();
                let mut rest = path;
                while rest.first().is_some_and(|s| s == "super") {
                    base.pop()?;
                    rest = &rest[1..];
                }
                (base, rest)
            }
            // a child module of the current one, named without `self::`
            first => {
                let mut child = at.to_vec();
                child.push(first.to_string());
                if !self.files.contains_key(&child) {
                    return None;
                }
                (at.to_vec(), path)
            }
        };
        let mut deepest = self.files.get_key_value(&base).map(|(k, _)| k);
        for segment in rest {
            base.push(segment.clone());
            match self.files.get_key_value(&base) {
                Some((k, _)) => deepest = Some(k),
                None => break,
            }
        }
        deepest
    }

    /// Module → the modules it imports (itself left out).
    fn imports(&self) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
        let mut graph = BTreeMap::new();
        for (module, file) in &self.files {
            let parsed = syn::parse_file(&read(file)).expect("parsed once already");
            let mut paths = Paths {
                inline: Vec::new(),
                found: Vec::new(),
            };
            paths.visit_file(&parsed);
            let mut targets = BTreeSet::new();
            for (inline, path) in paths.found {
                // (`super` inside an inline module, `mod tests`, starts from it)
                let mut at = module.clone();
                at.extend(inline);
                if let Some(target) = self.resolve(&at, &path)
                    && target != module
                {
                    targets.insert(target.clone());
                }
            }
            graph.insert(module.clone(), targets);
        }
        graph
    }
}

/// Whether `attrs` hold `#[cfg(test)]`.
fn is_test(attrs: &[syn::Attribute]) -> bool {
    attrs.iter().any(|a| {
        a.path().is_ident("cfg") && a.parse_args::<syn::Ident>().is_ok_and(|arg| arg == "test")
    })
}

/// The value of a `#[path = "…"]` attribute.
fn path_attribute(attrs: &[syn::Attribute]) -> Option<String> {
    attrs.iter().find_map(|a| match &a.meta {
        syn::Meta::NameValue(nv) if nv.path.is_ident("path") => match &nv.value {
            syn::Expr::Lit(syn::ExprLit {
                lit: syn::Lit::Str(s),
                ..
            }) => Some(s.value()),
            _ => None,
        },
        _ => None,
    })
}

/// Collects every path in `use` trees, expressions, types and patterns, with the
/// inline modules it sits in.
struct Paths {
    inline: Vec<String>,
    found: Vec<(Vec<String>, Vec<String>)>,
}

impl Paths {
    fn push(&mut self, segments: Vec<String>) {
        if !segments.is_empty() {
            self.found.push((self.inline.clone(), segments));
        }
    }

    fn use_tree(&mut self, prefix: &mut Vec<String>, tree: &syn::UseTree) {
        match tree {
            syn::UseTree::Path(p) => {
                prefix.push(p.ident.to_string());
                self.use_tree(prefix, &p.tree);
                prefix.pop();
            }
            syn::UseTree::Name(n) => {
                let mut full = prefix.clone();
                full.push(n.ident.to_string());
                self.push(full);
            }
            syn::UseTree::Rename(r) => {
                let mut full = prefix.clone();
                full.push(r.ident.to_string());
                self.push(full);
            }
            syn::UseTree::Glob(_) => self.push(prefix.clone()),
            syn::UseTree::Group(g) => {
                for t in &g.items {
                    self.use_tree(prefix, t);
                }
            }
        }
    }
}

impl<'ast> Visit<'ast> for Paths {
    fn visit_item(&mut self, item: &'ast syn::Item) {
        let attrs = match item {
            syn::Item::Mod(i) => &i.attrs,
            syn::Item::Fn(i) => &i.attrs,
            syn::Item::Use(i) => &i.attrs,
            syn::Item::Impl(i) => &i.attrs,
            syn::Item::Struct(i) => &i.attrs,
            syn::Item::Const(i) => &i.attrs,
            _ => &Vec::new(),
        };
        if !is_test(attrs) {
            syn::visit::visit_item(self, item);
        }
    }

    fn visit_item_mod(&mut self, m: &'ast syn::ItemMod) {
        if let Some((_, items)) = &m.content {
            self.inline.push(m.ident.to_string());
            for item in items {
                self.visit_item(item);
            }
            self.inline.pop();
        }
    }

    fn visit_item_use(&mut self, u: &'ast syn::ItemUse) {
        self.use_tree(&mut Vec::new(), &u.tree);
    }

    fn visit_path(&mut self, p: &'ast syn::Path) {
        if p.segments.len() > 1 {
            self.push(p.segments.iter().map(|s| s.ident.to_string()).collect());
        }
        syn::visit::visit_path(self, p);
    }
}

fn read(file: &Path) -> String {
    std::fs::read_to_string(file).unwrap_or_else(|e| panic!("{file:?}: {e}"))
}

/// The circles of `graph`: its strongly connected components of more than one module
/// (Tarjan), each as its modules in order.
fn circles(graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Vec<Vec<Vec<String>>> {
    struct Tarjan<'g> {
        graph: &'g BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        index: BTreeMap<&'g Vec<String>, (usize, usize)>,
        stack: Vec<&'g Vec<String>>,
        on_stack: BTreeSet<&'g Vec<String>>,
        out: Vec<Vec<Vec<String>>>,
    }
    impl<'g> Tarjan<'g> {
        fn visit(&mut self, v: &'g Vec<String>) -> usize {
            let n = self.index.len();
            self.index.insert(v, (n, n));
            self.stack.push(v);
            self.on_stack.insert(v);
            let mut low = n;
            for w in self.graph.get(v).into_iter().flatten() {
                if !self.graph.contains_key(w) {
                    continue;
                }
                low = match self.index.get(w) {
                    None => low.min(self.visit(w)),
                    Some(&(i, _)) if self.on_stack.contains(w) => low.min(i),
                    Some(_) => low,
                };
            }
            self.index.insert(v, (n, low));
            if low == n {
                let mut component = Vec::new();
                while let Some(w) = self.stack.pop() {
                    self.on_stack.remove(w);
                    component.push(w.clone());
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    component.reverse();
                    self.out.push(component);
                }
            }
            low
        }
    }
    let mut t = Tarjan {
        graph,
        index: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in graph.keys() {
        if !t.index.contains_key(v) {
            t.visit(v);
        }
    }
    t.out
}

fn name(module: &[String]) -> String {
    if module.is_empty() {
        "crate".into()
    } else {
        module.join("::")
    }
}

fn check_crate(root: &str) -> Vec<String> {
    let krate = Crate::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(root));
    let graph = krate.imports();
    circles(&graph)
        .into_iter()
        .map(|component| {
            let members: BTreeSet<&Vec<String>> = component.iter().collect();
            let edges: Vec<String> = component
                .iter()
                .flat_map(|m| {
                    graph[m]
                        .iter()
                        .filter(|t| members.contains(t))
                        .map(move |t| format!("{} → {}", name(m), name(t)))
                })
                .collect();
            format!("{root}: circle {}", edges.join(", "))
        })
        .collect()
}

/// The library's folders by layer, lowest first (DESIGN.md's layout, as the code has
/// grown into it): a module may import from its own folder and from the folders of
/// lower layers, never from a higher layer or a neighbour of its own layer.
const LAYERS: &[&[&str]] = &[
    &["util", "math", "error"],
    &["geometry"],
    &["body"],
    &["config"],
    &["clusters", "cut", "deform", "surface"],
    &["reconstruct"],
    &["solver"],
    &["ecs"],
    &["systems"],
    &["io"],
    &["sim"],
    &["analysis"],
];

/// Every import of the library from one folder to another that [`LAYERS`] forbids, as
/// `from → to`.
fn upward_imports() -> Vec<String> {
    let layer = |folder: &str| LAYERS.iter().position(|l| l.contains(&folder));
    let krate = Crate::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs"));
    let mut found = Vec::new();
    for (module, targets) in krate.imports() {
        // (the crate root mounts and re-exports every folder)
        let Some(from) = module.first() else { continue };
        for target in targets {
            let Some(to) = target.first() else { continue };
            if from == to {
                continue;
            }
            let (a, b) = (layer(from), layer(to));
            assert!(a.is_some() && b.is_some(), "{from} or {to} has no layer");
            if a <= b {
                found.push(format!("{} → {}", name(&module), name(&target)));
            }
        }
    }
    found
}

#[test]
fn no_module_imports_from_a_higher_layer() {
    let found = upward_imports();
    assert!(found.is_empty(), "\n{}", found.join("\n"));
}

#[test]
fn no_module_imports_a_module_that_imports_it_back() {
    let mut problems = check_crate("src/lib.rs");
    problems.extend(check_crate("src/bin/cleave/main.rs"));
    assert!(problems.is_empty(), "\n{}", problems.join("\n"));
}

#[test]
fn the_checker_sees_a_circle_and_a_clean_chain() {
    let module = |s: &str| -> Vec<String> { s.split("::").map(String::from).collect() };
    let graph = |edges: &[(&str, &str)]| {
        let mut g: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
        for (a, b) in edges {
            g.entry(module(a)).or_default().insert(module(b));
            g.entry(module(b)).or_default();
        }
        g
    };
    assert!(circles(&graph(&[("a", "b"), ("b", "c"), ("a", "c")])).is_empty());
    let found = circles(&graph(&[("a", "b"), ("b", "c"), ("c", "a"), ("c", "d")]));
    assert_eq!(found.len(), 1);
    assert_eq!(found[0].len(), 3);
    // the resolver: a re-export and a `super` path each name the file they reach
    let krate = Crate::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs"));
    let at = module("body::graph");
    let segments = |s: &str| -> Vec<String> { s.split("::").map(String::from).collect() };
    assert_eq!(
        krate.resolve(&at, &segments("super::lattice::Lattice")),
        Some(&module("body::lattice"))
    );
    assert_eq!(
        krate.resolve(&at, &segments("crate::body::lattice::Lattice::new")),
        Some(&module("body::lattice"))
    );
    assert_eq!(krate.resolve(&at, &segments("glam::Vec3")), None);
}

/// Every `.rs` file below the `folders` of `top`, sorted.
fn rust_files(top: &Path, folders: &[&str]) -> Vec<PathBuf> {
    let mut folders: Vec<PathBuf> = folders.iter().map(|d| top.join(d)).collect();
    let mut files = Vec::new();
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).expect("a folder").flatten() {
            let path = entry.path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

#[test]
fn no_source_file_passes_600_lines() {
    let top = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut long = Vec::new();
    for path in rust_files(top, &["src", "systems", "tests", "benches"]) {
        let lines = read(&path).lines().count();
        if lines > MAX_LINES {
            long.push(format!("{} ({lines} lines)", path.display()));
        }
    }
    assert!(long.is_empty(), "over {MAX_LINES} lines: {long:?}");
}

/// Longest function the house allows, in lines.
const MAX_FUNCTION_LINES: usize = 120;

/// The functions of `source` (formatted by rustfmt, so a function's body closes on the
/// first line holding only `}` at the indent its `fn` line has), unit tests left out:
/// each one's name and length in lines.
fn function_lengths(source: &str) -> Vec<(String, usize)> {
    let lines: Vec<&str> = source.lines().collect();
    let indent = |l: &str| l.len() - l.trim_start().len();
    let close = |from: usize, at: usize| {
        (from..lines.len()).find(|&j| indent(lines[j]) == at && lines[j].trim() == "}")
    };
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i].trim_start();
        if line.starts_with("#[cfg(test)]") {
            // the test module (or item) that follows, whole
            let at = indent(lines[i]);
            i = close(i + 1, at).map_or(lines.len(), |j| j + 1);
            continue;
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        let fn_at = words.iter().position(|w| *w == "fn");
        let is_fn = fn_at.is_some_and(|k| {
            k + 1 < words.len()
                && words[..k].iter().all(|w| {
                    w.starts_with("pub") || ["const", "async", "unsafe", "extern"].contains(w)
                })
        });
        if let (true, Some(k)) = (is_fn, fn_at) {
            let name: String = words[k + 1]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            // a declaration without a body (in a trait) ends on its own line
            let header_end = (i..lines.len()).find(|&j| {
                let t = lines[j].trim_end();
                t.ends_with('{') || t.ends_with(';')
            });
            if let Some(h) = header_end
                && lines[h].trim_end().ends_with('{')
                && let Some(end) = close(h, indent(lines[i]))
            {
                out.push((name, end - i + 1));
            }
        }
        i += 1;
    }
    out
}

#[test]
fn no_function_passes_120_lines() {
    let top = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut long = Vec::new();
    let mut longest = (0, String::new());
    for path in rust_files(top, &["src", "systems"]) {
        for (name, lines) in function_lengths(&read(&path)) {
            let at = format!("{}: {name}", path.display());
            if lines >= MAX_FUNCTION_LINES {
                long.push(format!("{at} ({lines} lines)"));
            }
            if lines > longest.0 {
                longest = (lines, at);
            }
        }
    }
    assert!(
        long.is_empty(),
        "{MAX_FUNCTION_LINES} lines or more: {long:?}"
    );
    // (the check sees functions at all: the longest is a real one, and long enough)
    assert!(longest.0 > 60, "longest function found: {longest:?}");
    println!("longest function: {} ({} lines)", longest.1, longest.0);
}

#[test]
fn function_lengths_are_counted_to_the_closing_brace() {
    let source = "pub fn a(\n    x: u32,\n) -> u32 {\n    x\n}\n\nimpl T {\n    fn b(&self) {\n        if true {\n        }\n    }\n    fn c(&self);\n}\n\n#[cfg(test)]\nmod tests {\n    fn long() {\n    }\n}\n";
    assert_eq!(
        function_lengths(source),
        [("a".to_string(), 5), ("b".to_string(), 4)]
    );
}

/// A kind of term is reached by its type only by the solver, which owns the terms, and
/// by the generic seam that gives each kind its own ECS side (`TermOf<T>`, and the
/// systems generic over `T` that sync it); everything else names a kind by the term it
/// registers or reads what every term reports (`Terms::extent`, `Terms::seconds`).
#[test]
fn no_term_is_reached_by_its_type_outside_the_solver() {
    let top = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut found = Vec::new();
    for path in rust_files(top, &["src", "systems"]) {
        if path.starts_with(top.join("src/solver")) {
            continue;
        }
        for (n, line) in read(&path).lines().enumerate() {
            let typed = ["terms.get::<", "terms.get_mut::<"]
                .iter()
                .any(|call| line.contains(call));
            let generic = line.contains("::<T>()");
            if typed && !generic {
                found.push(format!("{}:{}: {}", path.display(), n + 1, line.trim()));
            }
        }
    }
    assert!(found.is_empty(), "a term reached by its type: {found:#?}");
}
