//! Source hygiene: no import cycle between modules of `src/`.
//!
//! Every `crate::a::b` and `super::a` path in every source file (code and unit tests,
//! comments left out) is resolved to the module file it names. Between siblings (the
//! children of one module, the top-level modules being the children of the crate root)
//! a use of anything inside a sibling counts as a use of that sibling, so `distance`
//! using `crate::io::matrix::X` is an edge `distance -> io`. A parent using its own
//! children, and a child using its ancestors, are containment, not cycles. Any strongly
//! connected set of two or more siblings is a cycle and fails the test, each edge named
//! with the file and the path that makes it.
//!
//! A path through a re-export counts as a use of the module that defines the item: when
//! `io/mod.rs` says `pub use saved::MatrixFileError`, `super::MatrixFileError` in
//! `io/npy.rs` is an edge `npy -> saved`, not a use of the parent (so a cycle hidden
//! behind a parent's `pub use` is found). Re-exports are followed through chains and
//! globs (`pub use api::*`, for a name the module does not define itself).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module path from the crate root: `["io", "matrix"]` for `src/io/matrix.rs`.
type ModPath = Vec<String>;

/// Every `.rs` file under `dir`, in path order.
pub(crate) fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("entry").path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The module a file under `src/` defines (`lib.rs` and `main.rs` are the roots).
fn module_of(rel: &Path) -> ModPath {
    let mut parts: Vec<String> = rel
        .iter()
        .map(|s| s.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().expect("file name");
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_string());
    }
    parts
}

/// The text without `//` comments (doc comments included), string contents kept out of
/// the way well enough for paths: a `//` inside a string literal ends nothing here
/// because only `//` at the start of a line or after whitespace starts a comment.
fn strip_comments(text: &str) -> String {
    text.lines()
        .map(|line| {
            let t = line.trim_start();
            if t.starts_with("//") {
                return "";
            }
            match line.find(" //") {
                Some(i) if !line[..i].contains('"') => &line[..i],
                _ => line,
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// The paths a `use` tree or path starting at `rest` (just after `crate::` or `super::`)
/// names, each as its segments: `{a::B, c::{d, e}}` gives `[a, B]`, `[c, d]`, `[c, e]`.
fn paths_at(rest: &str) -> Vec<Vec<String>> {
    let rest = rest.trim_start();
    if let Some(inner) = rest.strip_prefix('{') {
        // Split the group at depth-0 commas up to its closing brace.
        let (mut depth, mut start, mut items) = (0usize, 0usize, Vec::new());
        for (i, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    items.push(&inner[start..i]);
                    break;
                }
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    items.push(&inner[start..i]);
                    start = i + 1;
                }
                _ => {}
            }
        }
        return items
            .into_iter()
            .filter(|s| !s.trim().is_empty())
            .flat_map(paths_at)
            .collect();
    }
    let end = rest.find(|c: char| !is_ident(c)).unwrap_or(rest.len());
    let head = &rest[..end];
    if head.is_empty() {
        return vec![vec![]];
    }
    let after = &rest[end..];
    match after.trim_start().strip_prefix("::") {
        Some(tail) => paths_at(tail)
            .into_iter()
            .map(|mut p| {
                p.insert(0, head.to_string());
                p
            })
            .collect(),
        None => vec![vec![head.to_string()]],
    }
}

/// Every module path `code` in module `here` refers to through `crate::` or `super::`,
/// resolved against the known module files (the longest known prefix), with the path as
/// written.
fn references(
    code: &str,
    here: &ModPath,
    modules: &BTreeSet<ModPath>,
    reexports: &Reexports,
) -> Vec<(ModPath, String)> {
    let mut out = Vec::new();
    let inline = inline_modules(code);
    for key in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(i) = code[from..].find(key) {
            let at = from + i;
            from = at + key.len();
            if at > 0 && code[..at].ends_with(|c: char| is_ident(c) || c == ':') {
                continue; // `foo::crate::` or the second `super::` of `super::super::`
            }
            let (base, mut rest, lead) = if key == "crate::" {
                (Vec::new(), &code[from..], key.to_string())
            } else {
                // Inside an inline module (`mod tests { use super::x; }`) `super` is the
                // file's own module.
                let mut b = here.clone();
                b.extend(
                    inline
                        .iter()
                        .filter(|m| m.1.contains(&at))
                        .map(|m| m.0.clone()),
                );
                b.pop();
                let (mut r, mut lead) = (&code[from..], key.to_string());
                while let Some(t) = r.strip_prefix("super::") {
                    b.pop();
                    r = t;
                    lead.push_str(key);
                }
                (b, r, lead)
            };
            if rest.starts_with("self::") {
                rest = &rest["self::".len()..];
            }
            for p in paths_at(rest) {
                let mut full = base.clone();
                full.extend(p.iter().cloned());
                let m = reexports.resolve(known_prefix(&full, modules), &full);
                out.push((m, format!("{lead}{}", p.join("::"))));
            }
        }
    }
    out
}

/// The inline modules of `code` (`mod name { ... }`), each with the byte range of its body.
fn inline_modules(code: &str) -> Vec<(String, std::ops::Range<usize>)> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(i) = code[from..].find("mod ") {
        let at = from + i;
        from = at + 4;
        if at > 0 && !code[..at].ends_with(char::is_whitespace) {
            continue;
        }
        let rest = &code[from..];
        let end = rest.find(|c: char| !is_ident(c)).unwrap_or(rest.len());
        let name = &rest[..end];
        let Some(body) = rest[end..].trim_start().strip_prefix('{') else {
            continue; // `mod name;`
        };
        let open = code.len() - body.len();
        let mut depth = 1usize;
        let mut close = code.len();
        for (j, c) in body.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        close = open + j;
                        break;
                    }
                }
                _ => {}
            }
        }
        out.push((name.to_string(), open..close));
    }
    out
}

/// The longest prefix of `full` that is a known module.
/// The module path that stands for every other crate.
const EXTERN: &str = "<another crate>";

fn known_prefix(full: &[String], modules: &BTreeSet<ModPath>) -> ModPath {
    let mut m = full.to_vec();
    while !m.is_empty() && !modules.contains(&m) {
        m.pop();
    }
    m
}

/// The re-exports of every module: `(module, name) -> the module the name comes from`
/// (`"*"` for a glob), and the names each module defines itself.
#[derive(Default)]
struct Reexports {
    /// `(module, name) -> path`: a named re-export's item path, a glob's module path.
    names: BTreeMap<(ModPath, String), ModPath>,
    /// Each module's globs (`pub use a::*;`), their modules in order.
    globs: BTreeMap<ModPath, Vec<ModPath>>,
    modules: BTreeSet<ModPath>,
    defined: BTreeMap<ModPath, BTreeSet<String>>,
}

impl Reexports {
    /// Records the `pub use` (and `pub(crate) use`) statements and the item definitions of
    /// `code`, the text of module `here`.
    fn scan(&mut self, code: &str, here: &ModPath, modules: &BTreeSet<ModPath>) {
        if self.modules.is_empty() {
            self.modules = modules.clone();
        }
        for line in code.lines() {
            let t = line.trim_start();
            for kw in [
                "fn ",
                "struct ",
                "enum ",
                "type ",
                "const ",
                "static ",
                "trait ",
                "mod ",
                "union ",
                "macro_rules! ",
            ] {
                let t = t
                    .trim_start_matches("pub(crate) ")
                    .trim_start_matches("pub(super) ")
                    .trim_start_matches("pub ");
                if let Some(rest) = t.strip_prefix(kw) {
                    let end = rest.find(|c: char| !is_ident(c)).unwrap_or(rest.len());
                    if end > 0 {
                        let set = self.defined.entry(here.clone()).or_default();
                        set.insert(rest[..end].to_string());
                    }
                }
            }
        }
        for kw in ["pub use ", "pub(crate) use "] {
            let mut from = 0;
            while let Some(i) = code[from..].find(kw) {
                let at = from + i;
                from = at + kw.len();
                if at > 0 && !code[..at].ends_with(char::is_whitespace) {
                    continue;
                }
                let stmt = &code[from..from + code[from..].find(';').unwrap_or(0)];
                // `X as Y`: the name is the alias.
                let words: Vec<&str> = stmt
                    .split(|c: char| !is_ident(c))
                    .filter(|w| !w.is_empty())
                    .collect();
                let alias: BTreeMap<&str, &str> = words
                    .windows(3)
                    .filter(|w| w[1] == "as")
                    .map(|w| (w[0], w[2]))
                    .collect();
                let (mut base, mut rest) = (here.clone(), stmt.trim_start());
                // A path that starts with neither `crate`, `self`, `super` nor a child
                // module names another crate (`pub use brdf_basis_core::fit;`): its names
                // lead out of this crate, where no cycle can close.
                let first: String = rest.chars().take_while(|&c| is_ident(c)).collect();
                let local = ["crate", "self", "super"].contains(&first.as_str()) || {
                    let mut child = here.clone();
                    child.push(first.clone());
                    modules.contains(&child)
                };
                if !local {
                    let outside: ModPath = vec![EXTERN.to_string()];
                    let glob = rest.trim_end().ends_with("::*");
                    for p in paths_at(rest) {
                        let name = match p.last() {
                            None => continue,
                            Some(_) if glob => "*".to_string(),
                            Some(last) => alias
                                .get(last.as_str())
                                .unwrap_or(&last.as_str())
                                .to_string(),
                        };
                        self.insert(here, name, outside.clone());
                    }
                    continue;
                }
                if let Some(r) = rest.strip_prefix("crate::") {
                    base.clear();
                    rest = r;
                } else if let Some(r) = rest.strip_prefix("self::") {
                    rest = r;
                } else {
                    while let Some(r) = rest.strip_prefix("super::") {
                        base.pop();
                        rest = r;
                    }
                }
                let glob = rest.trim_end().ends_with('*');
                for p in paths_at(rest) {
                    let mut full = base.clone();
                    full.extend(p.iter().cloned());
                    let is_glob = glob && rest.trim_end().ends_with("::*");
                    if is_glob && full.last().is_some_and(|l| l == "*") {
                        full.pop();
                    }
                    let name = match p.last() {
                        None => continue,
                        Some(_) if is_glob => "*".to_string(),
                        Some(last) => alias
                            .get(last.as_str())
                            .unwrap_or(&last.as_str())
                            .to_string(),
                    };
                    // The item's whole path (a glob: its module), so that a path through
                    // a name that another re-export brings in (`crate::io::image::f`
                    // where the root re-exports `io` from another crate) is followed.
                    if known_prefix(&full, modules) != *here || full.len() > here.len() + 1 {
                        self.insert(here, name, full);
                    }
                }
            }
        }
    }

    /// Records that `here` re-exports `name` (`"*"`: a glob) from `path`.
    fn insert(&mut self, here: &ModPath, name: String, path: ModPath) {
        if name == "*" {
            self.globs.entry(here.clone()).or_default().push(path);
        } else {
            self.names.insert((here.clone(), name), path);
        }
    }

    /// Whether module `m` brings `name` into scope: defines it, re-exports it by name, or
    /// through one of its globs (at most `depth` deep).
    fn provides(&self, m: &ModPath, name: &str, depth: usize) -> bool {
        self.defines(m, name)
            || self.names.contains_key(&(m.clone(), name.to_string()))
            || (depth > 0
                && self
                    .globs
                    .get(m)
                    .is_some_and(|gs| gs.iter().any(|g| self.provides(g, name, depth - 1))))
    }

    /// The glob of module `m` that brings `name` in: the first whose module provides it,
    /// else the first (a name no glob provides leads where the only glob leads).
    fn glob_for(&self, m: &ModPath, name: &str, depth: usize) -> Option<&ModPath> {
        let gs = self.globs.get(m)?;
        gs.iter()
            .find(|g| self.provides(g, name, depth))
            .or_else(|| gs.first())
    }

    /// Whether module `m`'s own file defines `name`.
    fn defines(&self, m: &ModPath, name: &str) -> bool {
        self.defined.get(m).is_some_and(|d| d.contains(name))
    }

    /// The module that defines what `full` names, starting from its longest known module
    /// prefix `m`: through the re-exports of `m` (and of their targets, at most 8 deep).
    fn resolve(&self, m: ModPath, full: &[String]) -> ModPath {
        self.resolve_from(m, full, 8)
    }

    /// [`Self::resolve`] with a depth budget for chains of re-exports.
    fn resolve_from(&self, m: ModPath, full: &[String], depth: usize) -> ModPath {
        if depth == 0 {
            return m;
        }
        let Some(name) = full.get(m.len()) else {
            return m;
        };
        let own = self.defines(&m, name);
        let named = self.names.get(&(m.clone(), name.clone()));
        let glob = !own && named.is_none();
        let next = named.or_else(|| glob.then(|| self.glob_for(&m, name, depth)).flatten());
        match next {
            Some(t) if t.first().is_some_and(|f| f == EXTERN) => t.clone(),
            Some(t) => {
                // A named re-export's path ends with the item; a glob's with its module.
                let mut f = t.clone();
                let after = if glob { m.len() } else { m.len() + 1 };
                f.extend(full[after..].iter().cloned());
                let km = known_prefix(&f, &self.modules);
                if km == m && f == full {
                    return m;
                }
                self.resolve_from(km, &f, depth - 1)
            }
            _ => m,
        }
    }
}

/// Strongly connected components (Tarjan) of a small graph given as adjacency sets.
fn sccs(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct T<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(t: &mut T<'a>, v: &'a str) {
        let i = t.index.len();
        t.index.insert(v, i);
        t.low.insert(v, i);
        t.stack.push(v);
        t.on.insert(v);
        if let Some(next) = t.g.get(v) {
            for w in next {
                let w = w.as_str();
                if !t.index.contains_key(w) {
                    visit(t, w);
                    let lw = t.low[w];
                    let lv = t.low.get_mut(v).expect("v");
                    *lv = (*lv).min(lw);
                } else if t.on.contains(w) {
                    let iw = t.index[w];
                    let lv = t.low.get_mut(v).expect("v");
                    *lv = (*lv).min(iw);
                }
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = t.stack.pop().expect("stack");
                t.on.remove(w);
                comp.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                t.out.push(comp);
            }
        }
    }
    let mut t = T {
        g: graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    let nodes: BTreeSet<&str> = graph
        .iter()
        .flat_map(|(a, bs)| std::iter::once(a.as_str()).chain(bs.iter().map(|b| b.as_str())))
        .collect();
    for v in nodes {
        if !t.index.contains_key(v) {
            visit(&mut t, v);
        }
    }
    t.out
}

/// The cycles among the modules of the source tree at `src`, one line per cycle with the
/// uses that make it.
fn import_cycles(src: &Path) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let files: Vec<(PathBuf, ModPath)> = files
        .into_iter()
        .map(|p| {
            let m = module_of(p.strip_prefix(src).expect("under src"));
            (p, m)
        })
        .collect();
    let modules: BTreeSet<ModPath> = files.iter().map(|(_, m)| m.clone()).collect();
    let codes: Vec<String> = files
        .iter()
        .map(|(p, _)| strip_comments(&std::fs::read_to_string(p).expect("read")))
        .collect();
    let mut reexports = Reexports::default();
    for ((_, here), code) in files.iter().zip(&codes) {
        reexports.scan(code, here, &modules);
    }
    // Per parent module: sibling graph and the evidence for each edge.
    type Edges = BTreeMap<(String, String), BTreeSet<String>>;
    let mut by_parent: BTreeMap<ModPath, Edges> = BTreeMap::new();
    for ((path, here), code) in files.iter().zip(&codes) {
        for (target, written) in references(code, here, &modules, &reexports) {
            let common = here.iter().zip(&target).take_while(|(a, b)| a == b).count();
            if common == here.len() || common == target.len() {
                continue; // itself, an ancestor or a descendant
            }
            let parent = here[..common].to_vec();
            let (a, b) = (here[common].clone(), target[common].clone());
            let rel = path
                .strip_prefix(src)
                .expect("under src")
                .display()
                .to_string();
            by_parent
                .entry(parent)
                .or_default()
                .entry((a, b))
                .or_default()
                .insert(format!("src/{rel} uses {written}"));
        }
    }
    let mut cycles = Vec::new();
    for (parent, edges) in &by_parent {
        let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (a, b) in edges.keys() {
            graph.entry(a.clone()).or_default().insert(b.clone());
        }
        let prefix = if parent.is_empty() {
            String::new()
        } else {
            format!("{}::", parent.join("::"))
        };
        for comp in sccs(&graph) {
            let set: BTreeSet<&String> = comp.iter().collect();
            let mut why = Vec::new();
            for ((a, b), ev) in edges {
                if set.contains(a) && set.contains(b) {
                    let first: Vec<&str> = ev.iter().take(3).map(String::as_str).collect();
                    let more = ev.len().saturating_sub(3);
                    why.push(format!(
                        "{prefix}{a} -> {prefix}{b} ({}{})",
                        first.join("; "),
                        if more > 0 {
                            format!("; and {more} more")
                        } else {
                            String::new()
                        }
                    ));
                }
            }
            let names: Vec<String> = comp.iter().map(|m| format!("{prefix}{m}")).collect();
            cycles.push(format!(
                "cycle between {}:\n    {}",
                names.join(", "),
                why.join("\n    ")
            ));
        }
    }
    cycles
}

/// The source trees of the workspace's crates. Cargo refuses a cycle between crates, so
/// each crate's module graph is checked on its own.
const CRATE_SOURCES: [&str; 5] = [
    "src",
    "crates/core/src",
    "crates/gpu/src",
    "crates/cli/src",
    "python/src",
];

#[test]
fn the_module_graph_of_src_has_no_import_cycle() {
    for rel in CRATE_SOURCES {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join(rel);
        assert!(
            src.join("lib.rs").is_file() || src.join("main.rs").is_file(),
            "{} has no lib.rs or main.rs",
            src.display()
        );
        let cycles = import_cycles(&src);
        assert!(
            cycles.is_empty(),
            "{} import cycle(s) between modules of {rel}/:\n{}",
            cycles.len(),
            cycles.join("\n")
        );
    }
}

/// Writes `text` to `src/rel`, making its directories.
fn put_file(src: &Path, rel: &str, text: &str) {
    let p = src.join(rel);
    std::fs::create_dir_all(p.parent().expect("parent")).expect("mkdir");
    std::fs::write(&p, text).expect("write");
}

#[test]
fn the_cycle_check_finds_a_planted_cycle_and_ignores_containment() {
    let d = crate::common::tmp();
    let src = d.path();
    let put = |rel: &str, text: &str| put_file(src, rel, text);
    put("lib.rs", "pub mod a;\npub mod b;\npub mod c;\n");
    put(
        "a/mod.rs",
        "pub mod inner;\nuse crate::c::X;\n// crate::b::Commented is not a use\n",
    );
    put("a/inner.rs", "use super::super::b::Y;\nuse crate::a::Z;\n");
    put("b.rs", "pub fn f() {\n    crate::c::g();\n}\n");
    put("c.rs", "use crate::{b::K, a::{inner::L, M}};\n");
    let cycles = import_cycles(src);
    assert_eq!(cycles.len(), 1, "{cycles:?}");
    let c = &cycles[0];
    assert!(c.starts_with("cycle between a, b, c:"), "{c}");
    assert!(
        c.contains("a -> b (src/a/inner.rs uses super::super::b::Y)"),
        "{c}"
    );
    assert!(
        c.contains("c -> a (src/c.rs uses crate::a::M; src/c.rs uses crate::a::inner::L)"),
        "{c}"
    );
    assert!(!c.contains("Commented"), "{c}");
    // Without the edge back to `a`: no cycle (the child's use of its parent is not one).
    put("c.rs", "use crate::b::K;\n");
    let cycles = import_cycles(src);
    assert_eq!(cycles.len(), 1, "b <-> c remains: {cycles:?}");
    assert!(cycles[0].starts_with("cycle between b, c:"), "{cycles:?}");
    put("c.rs", "pub struct X;\n");
    assert!(import_cycles(src).is_empty());
}

#[test]
fn the_cycle_check_sees_through_a_parents_pub_use() {
    let d = crate::common::tmp();
    let src = d.path();
    let put = |rel: &str, text: &str| put_file(src, rel, text);
    // The shape of the old io::npy <-> io::saved cycle: the error type defined in one child
    // and re-exported by the parent, the other child using it through the parent.
    put("lib.rs", "mod api;\npub use api::*;\npub mod io;\n");
    put("api.rs", "pub type Result<T> = T;\n");
    put(
        "io/mod.rs",
        "pub mod npy;\npub mod saved;\npub use saved::MatrixFileError;\n",
    );
    put(
        "io/npy.rs",
        "use super::MatrixFileError;\npub fn read() {}\n",
    );
    put(
        "io/saved.rs",
        "use super::npy::read;\npub enum MatrixFileError {}\n",
    );
    let cycles = import_cycles(src);
    assert_eq!(cycles.len(), 1, "{cycles:?}");
    assert!(
        cycles[0].starts_with("cycle between io::npy, io::saved:"),
        "{cycles:?}"
    );
    assert!(
        cycles[0].contains("io::npy -> io::saved (src/io/npy.rs uses super::MatrixFileError)"),
        "{cycles:?}"
    );
    // The type moved to the parent: a child using its parent is no cycle. Nor is an
    // inline test module's `super::read` (the file's own module, which imports `read`
    // from its child), even with a glob re-export at the root and `api` using `io`.
    put(
        "io/mod.rs",
        "pub mod npy;\npub mod saved;\npub enum MatrixFileError {}\nuse npy::*;\n\
         #[cfg(test)]\nmod tests {\n    use super::read;\n}\n",
    );
    put("io/saved.rs", "use super::npy::read;\n");
    put(
        "api.rs",
        "pub type Result<T> = T;\nuse crate::io::npy::read;\n",
    );
    let cycles = import_cycles(src);
    assert!(cycles.is_empty(), "{cycles:?}");
    // Through a glob re-export at the root (`crate::Result` is `api`'s): io using it and
    // api using io is a cycle io <-> api.
    put(
        "io/saved.rs",
        "use super::npy::read;\nfn f() -> crate::Result<()> {}\n",
    );
    put(
        "api.rs",
        "pub type Result<T> = T;\nuse crate::io::npy::read;\n",
    );
    let cycles = import_cycles(src);
    assert_eq!(cycles.len(), 1, "{cycles:?}");
    assert!(
        cycles[0].starts_with("cycle between api, io:"),
        "{cycles:?}"
    );
}

#[test]
fn the_cycle_check_follows_each_name_through_the_glob_that_brings_it() {
    let d = crate::common::tmp();
    let src = d.path();
    let put = |rel: &str, text: &str| put_file(src, rel, text);
    // The core's flat layout: private children lifted by globs (`select`'s search,
    // swap, greedy). `crate::sel::Params` is `search`'s, whatever glob comes first.
    put(
        "lib.rs",
        "pub mod sel;
",
    );
    put(
        "sel/mod.rs",
        "mod greedy;
mod search;
mod swap;
pub use greedy::*;
pub use search::*;
pub use swap::*;
",
    );
    put(
        "sel/search.rs",
        "pub struct Params;
",
    );
    put(
        "sel/greedy.rs",
        "use crate::sel::Params;
pub fn greedy() {}
",
    );
    put(
        "sel/swap.rs",
        "use crate::sel::{greedy, Params};
pub fn swap() {}
",
    );
    assert!(import_cycles(src).is_empty(), "{:?}", import_cycles(src));
    // greedy using swap's item through the parent while swap uses greedy: a cycle.
    put(
        "sel/greedy.rs",
        "use crate::sel::{swap, Params};
pub fn greedy() {}
",
    );
    let cycles = import_cycles(src);
    assert_eq!(cycles.len(), 1, "{cycles:?}");
    assert!(
        cycles[0].starts_with("cycle between sel::greedy, sel::swap:"),
        "{cycles:?}"
    );
}

#[test]
fn the_cycle_check_sends_another_crates_modules_out_of_the_crate() {
    let d = crate::common::tmp();
    let src = d.path();
    let put = |rel: &str, text: &str| put_file(src, rel, text);
    // The facade's layout: the core's modules re-exported at the root beside a glob.
    put(
        "lib.rs",
        "mod api;\npub use api::*;\npub use core_crate::{fit, io};\npub mod plot;\n",
    );
    put("api.rs", "use crate::plot::Figure;\npub struct Error;\n");
    put(
        "plot.rs",
        "use crate::fit::Fit;\nuse crate::io::write;\npub struct Figure;\n",
    );
    assert!(import_cycles(src).is_empty(), "{:?}", import_cycles(src));
    // Without the external re-export the names fall to `api`'s glob: a cycle.
    put("lib.rs", "mod api;\npub use api::*;\npub mod plot;\n");
    let cycles = import_cycles(src);
    assert_eq!(cycles.len(), 1, "{cycles:?}");
    assert!(
        cycles[0].starts_with("cycle between api, plot:"),
        "{cycles:?}"
    );
}

/// Most lines a source file may have without a `// Long file:` comment saying why.
const FILE_LINES: usize = 820;
/// Most lines a function may have without a `Long function:` comment (its doc or a line
/// comment) within the ten lines above its `fn` saying why.
const FN_LINES: usize = 120;

/// `(name, first line (1-based), lines)` of every function with a body in `code`: from
/// its `fn` line to its closing brace, braces matched outside comments, strings and
/// character literals.
fn functions(code: &str) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = code.lines().collect();
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let t = line.trim_start();
        let t = ["pub(crate) ", "pub(super) ", "pub "]
            .iter()
            .fold(t, |t, p| t.strip_prefix(p).unwrap_or(t));
        let t = ["const ", "unsafe ", "extern \"C\" "]
            .iter()
            .fold(t, |t, p| t.strip_prefix(p).unwrap_or(t));
        let Some(rest) = t.strip_prefix("fn ") else {
            continue;
        };
        let name: String = rest.chars().take_while(|&c| is_ident(c)).collect();
        let (mut depth, mut started) = (0i64, false);
        for (j, l) in lines.iter().enumerate().skip(i) {
            let code_part = strip_comments(l);
            let mut chars = code_part.chars().peekable();
            let mut in_str = false;
            while let Some(c) = chars.next() {
                match c {
                    '\\' if in_str => {
                        chars.next();
                    }
                    '"' => in_str = !in_str,
                    '\'' if !in_str => {
                        // A character literal ('{', '\'') or a lifetime ('a).
                        let look: String = chars.clone().take(3).collect();
                        if look.starts_with('\\') {
                            chars.nth(2);
                        } else if look.chars().nth(1) == Some('\'') {
                            chars.nth(1);
                        }
                    }
                    '{' if !in_str => {
                        depth += 1;
                        started = true;
                    }
                    '}' if !in_str => depth -= 1,
                    _ => {}
                }
            }
            if started && depth == 0 {
                out.push((name.clone(), i + 1, j - i + 1));
                break;
            }
            if !started && code_part.trim_end().ends_with(';') {
                break;
            }
        }
    }
    out
}

/// Files over [`FILE_LINES`] and functions over [`FN_LINES`] lines that do not say why.
fn oversized(files: &[(String, String)]) -> Vec<String> {
    let mut bad = Vec::new();
    for (rel, text) in files {
        let n = text.lines().count();
        if n > FILE_LINES && !text.contains("// Long file:") {
            bad.push(format!("{rel}: {n} lines and no `// Long file:` reason"));
        }
        let lines: Vec<&str> = text.lines().collect();
        for (name, at, len) in functions(text) {
            if len <= FN_LINES {
                continue;
            }
            let above = &lines[at.saturating_sub(11)..at - 1];
            if !above.iter().any(|l| l.contains("Long function:")) {
                bad.push(format!(
                    "{rel}:{at}: fn {name} has {len} lines and no `Long function:` reason"
                ));
            }
        }
    }
    bad
}

#[test]
fn no_file_or_function_is_oversized_without_a_reason() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for rel in CRATE_SOURCES {
        let mut paths = Vec::new();
        rust_files(&root.join(rel), &mut paths);
        for p in paths {
            let text = std::fs::read_to_string(&p).expect("read");
            let rel = p
                .strip_prefix(root)
                .expect("under root")
                .display()
                .to_string();
            files.push((rel, text));
        }
    }
    assert!(files.len() > 100, "{} source files", files.len());
    let bad = oversized(&files);
    assert!(
        bad.is_empty(),
        "{} oversized without a reason:\n{}",
        bad.len(),
        bad.join("\n")
    );
}

#[test]
fn the_size_check_measures_functions_and_takes_reasons() {
    let body = |n: usize| "    let x = '{';\n    // }\n".repeat(n / 2);
    let long = format!("fn long() {{\n{}}}\n", body(130));
    let short = format!("pub(crate) fn short() {{\n{}}}\n", body(20));
    let f = functions(&format!("{long}{short}"));
    assert_eq!(f.len(), 2, "{f:?}");
    assert_eq!((f[0].0.as_str(), f[0].1, f[0].2), ("long", 1, 132));
    assert_eq!((f[1].0.as_str(), f[1].2), ("short", 22));
    let bad = oversized(&[("a.rs".into(), long.clone())]);
    assert_eq!(
        bad,
        vec!["a.rs:1: fn long has 132 lines and no `Long function:` reason"]
    );
    let why = format!("/// Long function: one pass that must stay one.\n{long}");
    assert!(oversized(&[("a.rs".into(), why)]).is_empty());
    let big = "// x\n".repeat(FILE_LINES + 1);
    assert_eq!(oversized(&[("b.rs".into(), big.clone())]).len(), 1);
    assert!(oversized(&[("b.rs".into(), format!("// Long file: tables.\n{big}"))]).is_empty());
}
