//! The library's layering: the top-level modules' `use crate::…` lines form no cycle (a module
//! imports only modules below it), no module holds more than a quarter of the library's lines,
//! and the binary's `main.rs` is dispatch only. `cargo test --test module_graph -- --nocapture`
//! prints the graph.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files.extend(rust_files(&path));
        } else if path.extension().is_some_and(|e| e == "rs") {
            files.push(path);
        }
    }
    files
}

/// The library's top-level modules (`src/NAME.rs` or `src/NAME/`), each with its files.
fn modules(src: &Path) -> BTreeMap<String, Vec<PathBuf>> {
    let mut modules = BTreeMap::new();
    for entry in std::fs::read_dir(src).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        match (path.is_dir(), name.as_str()) {
            (true, "bin") | (false, "lib" | "main") => {}
            (true, _) => {
                modules.insert(name, rust_files(&path));
            }
            (false, _) if path.extension().is_some_and(|e| e == "rs") => {
                modules.entry(name).or_insert_with(Vec::new).push(path);
            }
            _ => {}
        }
    }
    modules
}

/// The top-level modules that `use crate::…` statements in `text` name, nested braces included.
fn imported(text: &str) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    let mut rest = text;
    while let Some(at) = rest.find("use crate::") {
        let starts_line = rest[..at].rsplit('\n').next().is_some_and(|before| {
            before.trim().is_empty()
                || before.trim().ends_with("pub")
                || before.trim().starts_with("pub(")
        });
        let statement = &rest[at + "use crate::".len()..];
        let end = statement.find(';').unwrap_or(statement.len());
        let statement = &statement[..end];
        rest = &rest[at + 1..];
        if !starts_line {
            continue;
        }
        let first = |s: &str| -> String {
            s.trim_start_matches(['{', ' ', '\n'])
                .split(|c: char| !(c.is_alphanumeric() || c == '_'))
                .next()
                .unwrap_or_default()
                .to_string()
        };
        match statement.strip_prefix('{') {
            Some(list) => names.extend(top_level_items(list).iter().map(|item| first(item))),
            None => {
                names.insert(first(statement));
            }
        }
    }
    names
}

/// The comma-separated items of a brace list, not splitting inside nested braces.
fn top_level_items(list: &str) -> Vec<&str> {
    let (mut items, mut depth, mut start) = (Vec::new(), 0, 0);
    for (i, c) in list.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => break,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&list[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items.push(&list[start..]);
    items.into_iter().filter(|s| !s.trim().is_empty()).collect()
}

/// `module → the modules it imports`, from the `use crate::` lines.
fn graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let modules = modules(src);
    modules
        .iter()
        .map(|(name, files)| {
            let used: BTreeSet<String> = (files.iter())
                .flat_map(|f| imported(&std::fs::read_to_string(f).unwrap()))
                .filter(|m| m != name && modules.contains_key(m))
                .collect();
            (name.clone(), used)
        })
        .collect()
}

/// A cycle of `graph`, if there is one (depth-first search).
fn cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|n| n == node) {
            return Some(path[at..].to_vec());
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in graph.get(node).into_iter().flatten() {
            if let Some(found) = visit(next, graph, path, done) {
                return Some(found);
            }
        }
        path.pop();
        done.insert(node.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|node| visit(node, graph, &mut Vec::new(), &mut done))
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn lines(files: &[PathBuf]) -> usize {
    files
        .iter()
        .map(|f| std::fs::read_to_string(f).unwrap().lines().count())
        .sum()
}

#[test]
fn the_modules_import_each_other_without_a_cycle() {
    let graph = graph(&src());
    for (module, used) in &graph {
        let used: Vec<&str> = used.iter().map(String::as_str).collect();
        println!("{module} -> {}", used.join(" "));
    }
    assert!(
        graph["flow"].contains("fem") && graph["run"].contains("load"),
        "{graph:?}"
    );
    assert_eq!(cycle(&graph), None);
    // The checker finds a cycle when there is one.
    let mut with_cycle = graph.clone();
    with_cycle.get_mut("mesh").unwrap().insert("flow".into());
    assert!(cycle(&with_cycle).is_some_and(|c| c.contains(&"mesh".to_string())));
}

#[test]
fn no_module_holds_a_quarter_of_the_library_and_main_is_dispatch() {
    let modules = modules(&src());
    let total: usize = modules.values().map(|files| lines(files)).sum();
    for (name, files) in &modules {
        let share = lines(files) as f64 / total as f64;
        println!("{name}: {:.1} %", 100.0 * share);
        assert!(
            share <= 0.25,
            "{name} holds {:.1} % of the library",
            100.0 * share
        );
    }
    let main = src().join("bin/meshflow/main.rs");
    assert!(lines(&[main]) <= 400);
}

#[test]
fn use_lines_are_read_with_their_braces() {
    let text = "use crate::flow::{A, B};\npub(crate) use crate::{mesh::Mesh, fem::{x, y}};\n\
                // use crate::render::View;\nlet a = \"use crate::io\";\n    use crate::load;\n";
    let names: Vec<String> = imported(text).into_iter().collect();
    assert_eq!(names, ["fem", "flow", "load", "mesh"]);
}
