//! Import circles (issue 16), read from the source: between the library's top-level modules (a
//! module's imports are the `crate::NAME` paths in its files, `brdf_rig::NAME` in the binary's
//! `cli/`), and between files (the paths a file names through `crate::`, `super::`, `self::` or
//! `brdf_rig::`, resolved to the file that defines them). The circles that remain are listed
//! here with why; a new one, or an import of `sim` from a module that must not know it, fails.
//!
//! What counts as a file's import: every such path in its code (comments are left out), outside
//! its `#[cfg(test)]` module. A `mod.rs` naming its own children by their bare names (`mod x;`,
//! `x::f()`) is not counted: a module's face declares and calls its parts. A path to an item of
//! a `mod.rs` (`super::ReportError`) is an import of that `mod.rs`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Every source file's code (`code_of`), by its module path (`file_module`).
fn source_files() -> BTreeMap<Vec<String>, String> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = BTreeMap::new();
    let mut stack = vec![src.clone()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                let rel = p.strip_prefix(&src).unwrap();
                let text = code_of(&std::fs::read_to_string(&p).unwrap());
                files.insert(file_module(rel), text);
            }
        }
    }
    files
}

/// Top-level module -> the top-level modules its files name.
fn module_imports() -> BTreeMap<String, BTreeSet<String>> {
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (path, text) in source_files() {
        // the crate roots (lib.rs, main.rs) only declare the modules
        let Some(module) = path.first() else { continue };
        let deps = graph.entry(module.clone()).or_default();
        for prefix in ["crate::", "brdf_rig::"] {
            for (i, _) in text.match_indices(prefix) {
                // a path, not a word ending in "crate" (`my_crate::`)
                let before = text[..i].chars().next_back();
                if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
                    continue;
                }
                let name: String = text[i + prefix.len()..]
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() && &name != module {
                    deps.insert(name);
                }
            }
        }
    }
    graph
}

/// The strongly connected groups of more than one node, each sorted.
fn circles<T: Ord + Clone>(graph: &BTreeMap<T, BTreeSet<T>>) -> BTreeSet<Vec<T>> {
    let reach = |from: &T| {
        let mut seen = BTreeSet::new();
        let mut todo = vec![from.clone()];
        while let Some(m) = todo.pop() {
            for d in graph.get(&m).into_iter().flatten() {
                if seen.insert(d.clone()) {
                    todo.push(d.clone());
                }
            }
        }
        seen
    };
    let reaches: BTreeMap<&T, BTreeSet<T>> = graph.keys().map(|m| (m, reach(m))).collect();
    let mut out = BTreeSet::new();
    for m in graph.keys() {
        let group: Vec<T> = graph
            .keys()
            .filter(|o| *o == m || (reaches[m].contains(*o) && reaches[*o].contains(m)))
            .cloned()
            .collect();
        if group.len() > 1 {
            out.insert(group);
        }
    }
    out
}

/// A file's module path: `src/a/b.rs` -> `a::b`, `src/a/mod.rs` -> `a`; the crate roots
/// (`lib.rs`, `main.rs`) are the empty path.
fn file_module(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .with_extension("")
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts
        .last()
        .is_some_and(|p| p == "mod" || p == "lib" || p == "main")
    {
        parts.pop();
    }
    parts
}

/// The text a file's imports are read from: its code without comments, up to its
/// `#[cfg(test)]` module.
fn code_of(text: &str) -> String {
    let mut out = String::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let t = line.trim_start();
        if t.starts_with("#[cfg(test)]")
            && lines
                .clone()
                .find(|l| !l.trim_start().starts_with("#["))
                .is_some_and(|l| l.trim_start().starts_with("mod "))
        {
            break;
        }
        let code = match line.find("//") {
            Some(i) => &line[..i],
            None => line,
        };
        out.push_str(code);
        out.push('\n');
    }
    out
}

/// The paths a `use` tree or path expression starting at `s` names, each as the segments after
/// the head (`{a::X, b}` gives `[a, X]` and `[b]`; `self` inside braces names the prefix).
fn paths_at(s: &str, prefix: Vec<String>, out: &mut Vec<Vec<String>>) -> usize {
    let b = s.as_bytes();
    let mut i = 0;
    let mut cur = prefix;
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    loop {
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        if s[i..].starts_with("::") {
            i += 2;
            continue;
        }
        if i < b.len() && b[i] == b'{' {
            i += 1;
            loop {
                i += paths_at(&s[i..], cur.clone(), out);
                while i < b.len() && b[i].is_ascii_whitespace() {
                    i += 1;
                }
                match b.get(i) {
                    Some(b',') => i += 1,
                    Some(b'}') => return i + 1,
                    _ => return i,
                }
            }
        }
        let start = i;
        while i < b.len() && ident(b[i]) {
            i += 1;
        }
        if i == start {
            break;
        }
        let word = &s[start..i];
        if word != "self" || cur.is_empty() {
            cur.push(word.to_string());
        }
        // a path goes on only through `::`; `X as Y` ends it
        let rest = s[i..].trim_start();
        if !rest.starts_with("::") && !rest.starts_with('{') {
            i += s[i..].len() - rest.len();
            if let Some(alias) = rest.strip_prefix("as ") {
                let alias = alias.trim_start();
                i += rest.len() - alias.len();
                i += alias.bytes().take_while(|&c| ident(c)).count();
            }
            break;
        }
    }
    out.push(cur);
    i
}

/// File -> the files it imports (both crates' files; `cli/` is the binary's, the rest the
/// library's, and their module names do not overlap).
fn file_imports() -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    let texts = source_files();
    let resolve = |path: &[String]| -> Option<Vec<String>> {
        (1..=path.len())
            .rev()
            .map(|n| path[..n].to_vec())
            .find(|m| texts.contains_key(m))
    };
    let mut graph = BTreeMap::new();
    for (m, text) in &texts {
        let deps: &mut BTreeSet<Vec<String>> = graph.entry(m.clone()).or_default();
        for head in ["crate::", "brdf_rig::", "super::", "self::"] {
            for (i, _) in text.match_indices(head) {
                let before = text[..i].chars().next_back();
                if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                    continue;
                }
                let base: Vec<String> = match head {
                    "super::" => m[..m.len().saturating_sub(1)].to_vec(),
                    "self::" => m.clone(),
                    _ => Vec::new(),
                };
                let mut found = Vec::new();
                paths_at(&text[i + head.len()..], Vec::new(), &mut found);
                for rest in found {
                    let mut path = base.clone();
                    for seg in rest {
                        if seg == "super" {
                            path.pop();
                        } else {
                            path.push(seg);
                        }
                    }
                    if let Some(target) = resolve(&path)
                        && &target != m
                        && !target.is_empty()
                    {
                        deps.insert(target);
                    }
                }
            }
        }
    }
    graph
}

#[test]
fn no_new_import_circle_between_modules() {
    let graph = module_imports();
    // None remain (issue 16): any circle found is new.
    let known: BTreeSet<Vec<String>> = BTreeSet::new();
    let found = circles(&graph);
    let new: Vec<&Vec<String>> = found.difference(&known).collect();
    assert!(
        new.is_empty(),
        "new import circles: {new:?}\nall: {found:?}"
    );
}

#[test]
fn capture_devices_calib_and_reconstruct_import_nothing_from_sim() {
    let graph = module_imports();
    for m in ["capture", "devices", "calib", "reconstruct"] {
        assert!(!graph[m].contains("sim"), "{m} imports sim: {:?}", graph[m]);
    }
}

#[test]
fn the_reader_finds_imports_and_circles() {
    // an independent check of the two functions above on a graph whose answer is known
    let g: BTreeMap<String, BTreeSet<String>> = [
        ("a", vec!["b"]),
        ("b", vec!["c"]),
        ("c", vec!["a"]),
        ("d", vec!["a"]),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v.into_iter().map(String::from).collect()))
    .collect();
    let c = circles(&g);
    assert_eq!(c.len(), 1);
    assert!(c.contains(&vec!["a".to_string(), "b".into(), "c".into()]));
    let real = module_imports();
    assert!(real["capture"].contains("devices"), "{:?}", real["capture"]);
}

#[test]
fn no_new_import_circle_between_files() {
    // None remain (issue 16): the last three were broken by giving the shared piece a file of
    // its own (`geometry::reflect`, `capture::session_format`, `reconstruct::observation`).
    let known: BTreeSet<Vec<Vec<String>>> = BTreeSet::new();
    let found = circles(&file_imports());
    let new: Vec<String> = found
        .difference(&known)
        .map(|g| {
            g.iter()
                .map(|m| m.join("::"))
                .collect::<Vec<_>>()
                .join(" <-> ")
        })
        .collect();
    assert!(new.is_empty(), "new import circles between files: {new:#?}");
    // and the list shrinks when a circle is broken (this also shows the reader finds them)
    let gone: Vec<_> = known.difference(&found).collect();
    assert!(gone.is_empty(), "listed circles no longer found: {gone:?}");
}

#[test]
fn the_file_reader_resolves_use_trees_and_relative_paths() {
    let mut found = Vec::new();
    paths_at(
        "{a::X, b::{self, Y as Z}, c}; fn f() {}",
        Vec::new(),
        &mut found,
    );
    let want: Vec<Vec<String>> = [vec!["a", "X"], vec!["b"], vec!["b", "Y"], vec!["c"]]
        .into_iter()
        .map(|p| p.into_iter().map(String::from).collect())
        .collect();
    assert_eq!(found, want);
    let code =
        code_of("use x; // crate::nothing\nfn f() {}\n#[cfg(test)]\nmod tests {\n use y;\n}\n");
    assert!(code.contains("use x;") && !code.contains("nothing") && !code.contains("use y"));
    let files = file_imports();
    let of = |m: &str| &files[&m.split("::").map(String::from).collect::<Vec<_>>()];
    let name = |m: &str| m.split("::").map(String::from).collect::<Vec<_>>();
    // `use super::report_file::{...}` from a file, `crate::...` from a file, and an item of a
    // mod.rs through `super::`
    assert!(of("reconstruct::output").contains(&name("reconstruct::report_file")));
    assert!(of("report::gather").contains(&name("reconstruct::report_file")));
    assert!(of("report::gather").contains(&name("report")));
    // the binary's files name the library's through `brdf_rig::`
    assert!(of("cli::bench_reconstruct").contains(&name("eval::bench::reconstruct")));
}
