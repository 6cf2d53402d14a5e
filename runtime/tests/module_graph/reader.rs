//! The file graph of a crate's sources: which file names which (with
//! `crate::…`, `super::…`, `self::…`, a grouped `use`, or a path through one
//! of its own child modules, outside comments and unit tests). A module's own
//! descendants do not count as its dependencies (declaring, re-exporting and
//! dispatching to its parts is what a parent module is for), and neither does
//! the crate root. Shared by the runtime's and the bench crate's tests.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// A module path, `["integrator", "one_point"]`; the crate root is empty.
pub(crate) type Module = Vec<String>;

/// `file → files it names`, keyed by module path.
pub(crate) type Graph = BTreeMap<Module, BTreeSet<Module>>;

/// Reads every `.rs` file under `root` (a crate's `src`).
pub(crate) fn graph(root: &Path) -> Graph {
    let mut files: BTreeMap<Module, String> = BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
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
            let rel = path.strip_prefix(root).unwrap().with_extension("");
            let mut module: Module = rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
            // `a/mod.rs` is the module `a`, and `lib.rs`/`main.rs` the root;
            // all three are directory modules whose children sit beside them.
            if matches!(module.last().map(String::as_str), Some("mod"))
                || (module.len() == 1 && matches!(module[0].as_str(), "lib" | "main"))
            {
                module.pop();
            }
            if module.last().is_some_and(|m| m == "tests") {
                continue;
            }
            files.insert(module, std::fs::read_to_string(&path).unwrap());
        }
    }
    let mut graph = Graph::new();
    for (module, text) in &files {
        let deps = graph.entry(module.clone()).or_default();
        for path in paths_named(module, text) {
            // The longest prefix that is a file is the file the path names.
            let target = (0..=path.len()).rev().map(|k| &path[..k]).find(|p| files.contains_key(*p));
            if let Some(target) = target
                && !target.is_empty()
                && !target.starts_with(module)
            {
                deps.insert(target.to_vec());
            }
        }
    }
    graph
}

/// Every path the code of one file names, made absolute from the crate root:
/// `crate::a::b`, `super::x`, `self::x`, each branch of a grouped `use`, and
/// `child::item` for a `mod child;` the file declares. Comment lines and the
/// unit tests at the end of the file are skipped.
pub(crate) fn paths_named(module: &[String], text: &str) -> Vec<Module> {
    let code = text.split("#[cfg(test)]").next().unwrap();
    let code: String = code.lines().filter(|l| !l.trim_start().starts_with("//")).map(|l| format!("{l}\n")).collect();
    let mut raw: Vec<String> = Vec::new();
    // `use` declarations (rustfmt starts each on its own line), grouped or not.
    let mut offset = 0;
    for line in code.lines() {
        let start = offset;
        offset += line.len() + 1;
        let trimmed = line.trim_start();
        let item =
            ["pub(crate) ", "pub(super) ", "pub "].iter().find_map(|p| trimmed.strip_prefix(p)).unwrap_or(trimmed);
        if let Some(tree) = item.strip_prefix("use ") {
            let from = start + (line.len() - tree.len());
            if let Some(end) = code[from..].find(';') {
                expand_use(&code[from..from + end], &mut raw);
            }
        }
    }
    // Paths in code.
    let children: BTreeSet<&str> = code
        .lines()
        .filter_map(|l| {
            let l = l.trim_start();
            let l = l.strip_prefix("pub(crate) ").or_else(|| l.strip_prefix("pub ")).unwrap_or(l);
            l.strip_prefix("mod ")?.strip_suffix(';').map(str::trim)
        })
        .collect();
    let bytes = code.as_bytes();
    let ident = |b: u8| b.is_ascii_alphanumeric() || b == b'_';
    let mut i = 0;
    while i < bytes.len() {
        if ident(bytes[i]) && (i == 0 || (!ident(bytes[i - 1]) && bytes[i - 1] != b':')) {
            let start = i;
            while i < bytes.len() && (ident(bytes[i]) || (bytes[i] == b':' && bytes.get(i + 1) == Some(&b':'))) {
                i += if bytes[i] == b':' { 2 } else { 1 };
            }
            let path = code[start..i].trim_end_matches(':');
            let head = path.split("::").next().unwrap();
            if path.contains("::") && (matches!(head, "crate" | "super" | "self") || children.contains(head)) {
                raw.push(if children.contains(head) { format!("self::{path}") } else { path.to_string() });
            }
        } else {
            i += 1;
        }
    }
    let mut out = Vec::new();
    for path in raw {
        let mut segments = path.split("::").map(|s| s.split(" as ").next().unwrap().trim()).filter(|s| !s.is_empty());
        let mut base: Module = match segments.next() {
            Some("crate") => Vec::new(),
            Some("self") => module.to_vec(),
            Some("super") => module[..module.len().saturating_sub(1)].to_vec(),
            _ => continue,
        };
        for s in segments {
            match s {
                "super" => {
                    base.pop();
                }
                "self" => {}
                s => base.push(s.to_string()),
            }
        }
        out.push(base);
    }
    out
}

/// `a::{b, c::{d, e}}` → `a::b`, `a::c::d`, `a::c::e`.
fn expand_use(tree: &str, out: &mut Vec<String>) {
    let tree = tree.trim();
    let Some(open) = tree.find('{') else {
        out.push(tree.to_string());
        return;
    };
    let prefix = &tree[..open];
    let close = tree.rfind('}').filter(|&c| c > open).unwrap_or(tree.len());
    let inner = &tree[open + 1..close];
    let (mut depth, mut start) = (0, 0);
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                push_branch(prefix, &inner[start..i], out);
                start = i + 1;
            }
            _ => {}
        }
    }
    push_branch(prefix, &inner[start..], out);
}

fn push_branch(prefix: &str, branch: &str, out: &mut Vec<String>) {
    let branch = branch.trim();
    if branch.is_empty() {
        return;
    }
    let mut expanded = Vec::new();
    expand_use(branch, &mut expanded);
    out.extend(expanded.into_iter().map(|b| format!("{prefix}{b}")));
}

/// A cycle of the graph, if it has one, as the files along it.
pub(crate) fn cycle(graph: &Graph) -> Option<Vec<String>> {
    fn visit<'a>(
        graph: &'a Graph,
        module: &'a Module,
        path: &mut Vec<&'a Module>,
        done: &mut BTreeSet<&'a Module>,
    ) -> Option<Vec<String>> {
        if let Some(start) = path.iter().position(|m| *m == module) {
            let mut names: Vec<String> = path[start..].iter().map(|m| name(m)).collect();
            names.push(name(module));
            return Some(names);
        }
        if !done.insert(module) {
            return None;
        }
        path.push(module);
        for dep in graph.get(module).into_iter().flatten() {
            if let Some(cycle) = visit(graph, dep, path, done) {
                return Some(cycle);
            }
        }
        path.pop();
        None
    }
    let mut done = BTreeSet::new();
    graph.keys().find_map(|m| visit(graph, m, &mut Vec::new(), &mut done))
}

/// `integrator::one_point`, or `crate` for the root.
pub(crate) fn name(module: &Module) -> String {
    if module.is_empty() { "crate".to_string() } else { module.join("::") }
}

/// Prints the graph and fails on a cycle.
pub(crate) fn assert_acyclic(root: &Path) -> Graph {
    let graph = graph(root);
    for (module, deps) in &graph {
        println!("{:>28} → {}", name(module), deps.iter().map(name).collect::<Vec<_>>().join(", "));
    }
    if let Some(cycle) = cycle(&graph) {
        panic!("file cycle: {}", cycle.join(" → "));
    }
    graph
}
