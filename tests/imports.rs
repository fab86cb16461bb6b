//! Import circles between the library's top-level modules (issue 16), read from the source: a
//! module's imports are the `crate::NAME` paths in its files (`brdf_rig::NAME` in the binary's
//! `cli/`). The circles that remain are listed here with the issue that removes them; a new one,
//! or an import of `sim` from a module that must not know it, fails.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Top-level module -> the top-level modules its files name.
fn module_imports() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut stack = vec![src.clone()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
                continue;
            }
            if p.extension().is_none_or(|x| x != "rs") {
                continue;
            }
            let rel = p.strip_prefix(&src).unwrap();
            let first = rel
                .components()
                .next()
                .unwrap()
                .as_os_str()
                .to_string_lossy();
            let module = first.trim_end_matches(".rs").to_string();
            if module == "lib" || module == "main" {
                continue;
            }
            let text = std::fs::read_to_string(&p).unwrap();
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
                    if !name.is_empty() && name != module {
                        deps.insert(name);
                    }
                }
            }
        }
    }
    graph
}

/// The strongly connected groups of more than one module (Tarjan), each sorted.
fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> BTreeSet<Vec<String>> {
    let reach = |from: &str| {
        let mut seen = BTreeSet::new();
        let mut todo = vec![from.to_string()];
        while let Some(m) = todo.pop() {
            for d in graph.get(&m).into_iter().flatten() {
                if seen.insert(d.clone()) {
                    todo.push(d.clone());
                }
            }
        }
        seen
    };
    let reaches: BTreeMap<&String, BTreeSet<String>> =
        graph.keys().map(|m| (m, reach(m))).collect();
    let mut out = BTreeSet::new();
    for m in graph.keys() {
        let group: Vec<String> = graph
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

#[test]
fn no_new_import_circle_between_modules() {
    let graph = module_imports();
    // The circles that remain, to be broken (issue 16): geometry -> imageio -> render ->
    // geometry. Remove a group here when it is broken.
    let known: BTreeSet<Vec<String>> = [vec!["geometry", "imageio", "render"]]
        .into_iter()
        .map(|g| g.into_iter().map(String::from).collect())
        .collect();
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
