//! The bench crate's files form a graph without cycles: the catalogue of
//! methods, the problems, the peers and the code that runs a method on a
//! problem each name only what sits below them.

#[path = "../../runtime/tests/module_graph/reader.rs"]
mod reader;

use std::path::Path;

use reader::{Module, assert_acyclic};

#[test]
fn the_bench_files_have_no_cycle() {
    let graph = assert_acyclic(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"));
    let m = |s: &str| s.split("::").map(String::from).collect::<Module>();
    // The catalogue of methods and the outcome of a run name nothing: the
    // problems, the peers and the suite are built on them.
    assert!(graph[&m("methods")].is_empty(), "{:?}", graph[&m("methods")]);
    assert!(graph[&m("run")].is_empty(), "{:?}", graph[&m("run")]);
    assert!(graph[&m("integrate")].contains(&m("peers")), "the reader must see `crate::` paths");
}
