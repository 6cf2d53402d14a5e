//! The runtime's files form a graph without cycles: no file names a file
//! that names it back, directly or through others (the reader in
//! `reader.rs` says what counts as naming).
//! `cargo test -p lagrangian-runtime --test integration module_graph:: -- --nocapture`
//! prints the graph.

mod reader;

use std::collections::BTreeSet;
use std::path::Path;

use reader::{Graph, Module, assert_acyclic, cycle, name, paths_named};

fn names(paths: Vec<Module>) -> Vec<String> {
    paths.iter().map(name).collect()
}

#[test]
fn the_reader_sees_every_form_of_path() {
    let text = "mod child;\nuse super::{a, b::{c, d as e}};\nuse crate::x::y;\n\
                // use crate::commented;\nfn f() { child::g(); self::h::i(); crate::j::k(); super::super::l::m(); }\n\
                #[cfg(test)]\nmod tests { use crate::tested; }\n";
    let module = vec!["p".to_string(), "q".to_string()];
    let found = names(paths_named(&module, text));
    for expected in ["p::a", "p::b::c", "p::b::d", "x::y", "p::q::child::g", "p::q::h::i", "j::k", "l::m"] {
        assert!(found.iter().any(|f| f == expected), "{expected} not in {found:?}");
    }
    assert!(!found.iter().any(|f| f.contains("commented") || f.contains("tested")), "{found:?}");
}

#[test]
fn a_cycle_is_found() {
    let m = |s: &str| s.split("::").map(String::from).collect::<Module>();
    let mut graph = Graph::new();
    graph.insert(m("a"), [m("b")].into());
    graph.insert(m("b"), [m("c")].into());
    graph.insert(m("c"), [m("a")].into());
    assert_eq!(cycle(&graph).unwrap(), ["a", "b", "c", "a"]);
    graph.insert(m("c"), BTreeSet::new());
    assert_eq!(cycle(&graph), None);
}

#[test]
fn the_runtime_files_have_no_cycle() {
    let graph = assert_acyclic(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"));
    // The files the graph must have read, and one edge each kind of path gives.
    let m = |s: &str| s.split("::").map(String::from).collect::<Module>();
    assert!(graph[&m("integrator::tape_step::implicit")].contains(&m("real")), "a `crate::` path in a grouped `use`");
    assert!(graph[&m("integrator::sparse")].contains(&m("integrator::tape_step")), "a `super::` path");
    assert!(
        graph[&m("system")].iter().all(|d| d == &m("symmetry") || d == &m("structure")),
        "{:?}",
        graph[&m("system")]
    );
}
