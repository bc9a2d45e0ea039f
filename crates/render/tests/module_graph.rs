//! No import cycles among a crate's modules: reads every crate's `src/` as text, draws an
//! arrow from each module to each module it names in a path (`crate::a::b`, `super::a`,
//! `use child::...`, the groups of `use` lists), following re-exports (`pub use`) to the
//! module that defines the name, and asserts that the arrows form no circle. Test modules
//! (`#[cfg(test)] mod tests`) and the crate root (which declares and re-exports) are left out.
//!
//! Run it alone with `cargo test -p pathlight-render --test module_graph`; on failure it
//! prints each circle with the names that tie it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module's path (`frame::restir::pool`; the root is empty).
type Module = Vec<String>;

/// One crate's modules: their source (comments and test modules removed) by module path.
fn modules(src: &Path) -> BTreeMap<Module, String> {
    let mut out = BTreeMap::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            let rel: Vec<String> = path
                .strip_prefix(src)
                .unwrap()
                .with_extension("")
                .iter()
                .map(|c| c.to_string_lossy().into_owned())
                .collect();
            let mut module = rel.clone();
            if matches!(
                module.last().map(String::as_str),
                Some("mod" | "lib" | "main")
            ) {
                module.pop();
            }
            if module.last().is_some_and(|m| m == "tests") {
                continue;
            }
            let text = std::fs::read_to_string(&path).unwrap();
            out.insert(module, code_of(&text));
        }
    }
    out
}

/// `text` without comments, string literals and its test module.
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => &text[..i],
        None => text,
    };
    let mut out = String::with_capacity(text.len());
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            i += 2;
            while i < b.len() && !b[i..].starts_with(b"*/") {
                i += 1;
            }
            i += 2;
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else if b[i] == b'\'' && i + 2 < b.len() && (b[i + 2] == b'\'' || b[i + 1] == b'\\') {
            // A character literal ('"', '\n'); lifetimes have no closing quote.
            let end = b[i + 1..].iter().position(|&c| c == b'\'').unwrap_or(0);
            i += end + 2;
            out.push_str("' '");
        } else {
            out.push(b[i] as char);
            i += 1;
        }
    }
    out
}

/// The paths a module's code names, each as its segments from the module it starts at
/// (`crate`, `super`, `self` or a first segment), with `use` groups expanded.
fn paths(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let b = code.as_bytes();
    let word = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut i = 0;
    while i < b.len() {
        let starts = (i == 0 || !word(b[i - 1]) && b[i - 1] != b':')
            && ["crate::", "super::", "self::", "use "]
                .iter()
                .any(|p| code[i..].starts_with(p));
        if !starts {
            i += 1;
            continue;
        }
        let is_use = code[i..].starts_with("use ");
        let start = if is_use { i + 4 } else { i };
        // The path, up to what cannot continue it (a group is taken whole).
        let mut end = start;
        let mut depth = 0;
        while end < b.len() {
            let c = b[end];
            if c == b'{' {
                depth += 1;
            } else if c == b'}' {
                if depth == 0 {
                    break;
                }
                depth -= 1;
            } else if depth == 0 && !(word(c) || c == b':') {
                break;
            }
            end += 1;
        }
        expand(&code[start..end], &mut Vec::new(), &mut out);
        i = end.max(i + 1);
    }
    out
}

/// Expands `path` (which may end in a `{...}` group) under `prefix` into `out`.
fn expand(path: &str, prefix: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    let path = path.trim();
    if let Some(open) = path.find('{') {
        let head: Vec<String> = segments(&path[..open]);
        let inner = &path[open + 1..path.rfind('}').unwrap_or(path.len())];
        let n = prefix.len();
        prefix.extend(head);
        let mut depth = 0;
        let mut from = 0;
        for (k, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    expand(&inner[from..k], prefix, out);
                    from = k + 1;
                }
                _ => {}
            }
        }
        expand(&inner[from..], prefix, out);
        prefix.truncate(n);
    } else {
        let mut p = prefix.clone();
        p.extend(segments(path));
        if !p.is_empty() {
            out.push(p);
        }
    }
}

fn segments(path: &str) -> Vec<String> {
    path.split("::")
        .map(|s| s.split_whitespace().next().unwrap_or("").to_owned())
        .filter(|s| !s.is_empty())
        .collect()
}

/// The module a path names from module `at` (the longest prefix that is a module), and the
/// name after it, if any.
fn resolve(
    at: &Module,
    path: &[String],
    known: &BTreeMap<Module, String>,
) -> Option<(Module, Option<String>)> {
    let mut base: Module = match path.first()?.as_str() {
        "crate" => Vec::new(),
        "self" => at.clone(),
        "super" => at[..at.len().checked_sub(1)?].to_vec(),
        _ => at.clone(),
    };
    let mut rest = match path[0].as_str() {
        "crate" | "self" | "super" => &path[1..],
        _ => path,
    };
    while rest.first().is_some_and(|s| s == "super") {
        base.pop();
        rest = &rest[1..];
    }
    let mut module = base;
    let mut k = 0;
    while k < rest.len() {
        let mut next = module.clone();
        next.push(rest[k].clone());
        if !known.contains_key(&next) {
            break;
        }
        module = next;
        k += 1;
    }
    // A bare first segment that is no child module is a crate or an item: not ours.
    if k == 0 && !matches!(path[0].as_str(), "crate" | "self" | "super") {
        return None;
    }
    Some((module, rest.get(k).cloned()))
}

/// The arrows between one crate's modules: (from, to) with the names that tie them.
fn arrows(src: &Path) -> BTreeMap<(Module, Module), BTreeSet<String>> {
    let known = modules(src);
    // Re-exports: (module, name) -> the path it re-exports.
    let mut reexports: BTreeMap<(Module, String), Vec<String>> = BTreeMap::new();
    for (m, code) in &known {
        for stmt in code.split(';') {
            let stmt = stmt.trim();
            if let Some(rest) = stmt.strip_prefix("pub use ") {
                let mut found = Vec::new();
                expand(rest, &mut Vec::new(), &mut found);
                for p in found {
                    let name = p.last().unwrap().clone();
                    reexports.insert((m.clone(), name), p);
                }
            }
        }
    }
    let mut out: BTreeMap<(Module, Module), BTreeSet<String>> = BTreeMap::new();
    for (m, code) in &known {
        if m.is_empty() {
            continue;
        }
        for p in paths(code) {
            let Some((mut target, mut name)) = resolve(m, &p, &known) else {
                continue;
            };
            // Follow re-exports to the module that defines the name.
            for _ in 0..8 {
                let Some(n) = &name else { break };
                let Some(path) = reexports.get(&(target.clone(), n.clone())) else {
                    break;
                };
                if path.len() == 1 {
                    break;
                }
                match resolve(&target, path, &known) {
                    Some((t, n2)) if t != target => (target, name) = (t, n2),
                    _ => break,
                }
            }
            if target == *m || target.is_empty() || m.starts_with(&target) && name.is_none() {
                continue;
            }
            out.entry((m.clone(), target))
                .or_default()
                .insert(name.unwrap_or_default());
        }
    }
    out
}

/// The circles (strongly connected components of more than one module) among the arrows.
fn circles(arrows: &BTreeMap<(Module, Module), BTreeSet<String>>) -> Vec<Vec<Module>> {
    let nodes: BTreeSet<&Module> = arrows.keys().flat_map(|(a, b)| [a, b]).collect();
    let reach = |from: &Module| {
        let mut seen = BTreeSet::new();
        let mut stack = vec![from.clone()];
        while let Some(n) = stack.pop() {
            for (a, b) in arrows.keys() {
                if *a == n && seen.insert(b.clone()) {
                    stack.push(b.clone());
                }
            }
        }
        seen
    };
    let reaches: BTreeMap<&Module, BTreeSet<Module>> =
        nodes.iter().map(|n| (*n, reach(n))).collect();
    let mut done = BTreeSet::new();
    let mut out = Vec::new();
    for n in &nodes {
        if done.contains(*n) {
            continue;
        }
        let circle: Vec<Module> = nodes
            .iter()
            .filter(|m| reaches[*n].contains(**m) && reaches[**m].contains(*n))
            .map(|m| (*m).clone())
            .collect();
        if circle.len() > 1 {
            done.extend(circle.iter().cloned());
            out.push(circle);
        }
    }
    out
}

fn crates_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn no_crate_has_an_import_circle() {
    let mut found = Vec::new();
    let mut counted = 0;
    for entry in std::fs::read_dir(crates_dir()).unwrap() {
        let src = entry.unwrap().path().join("src");
        if !src.is_dir() {
            continue;
        }
        let arrows = arrows(&src);
        counted += arrows.len();
        for circle in circles(&arrows) {
            let ties: Vec<String> = arrows
                .iter()
                .filter(|((a, b), _)| circle.contains(a) && circle.contains(b))
                .map(|((a, b), names)| {
                    let names: Vec<&str> = names.iter().map(String::as_str).collect();
                    format!(
                        "  {} -> {}: {}",
                        a.join("::"),
                        b.join("::"),
                        names.join(", ")
                    )
                })
                .collect();
            found.push(format!("{}:\n{}", src.display(), ties.join("\n")));
        }
    }
    // The graph is not empty (the reading works): the render crate alone has over a hundred
    // arrows.
    assert!(counted > 100, "{counted} arrows");
    assert!(found.is_empty(), "import circles:\n{}", found.join("\n"));
}

/// The reading finds a circle where there is one.
#[test]
fn a_circle_is_found() {
    let dir = std::env::temp_dir().join(format!("pathlight-graph-{}", std::process::id()));
    let src = dir.join("src");
    std::fs::create_dir_all(src.join("frame")).unwrap();
    std::fs::write(src.join("lib.rs"), "pub mod a;\npub mod frame;\n").unwrap();
    std::fs::write(src.join("a.rs"), "use crate::frame::b::B;\npub struct A;\n").unwrap();
    std::fs::write(src.join("frame/mod.rs"), "pub mod b;\npub use b::B;\n").unwrap();
    std::fs::write(
        src.join("frame/b.rs"),
        "// crate::nothing here\nuse super::super::a::A;\npub struct B(A);\n",
    )
    .unwrap();
    let arrows = arrows(&src);
    let c = circles(&arrows);
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(c.len(), 1, "{arrows:?}");
    assert_eq!(c[0].len(), 2);
}
