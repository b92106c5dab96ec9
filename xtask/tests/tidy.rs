//! Tidy: project rules that plain `cargo test` enforces.
//!
//! - The crate layering written in `ARCHITECTURE.md` (the block after `tidy:layering`) matches
//!   `cargo metadata`: every workspace crate is listed, every listed crate exists, and each
//!   crate depends (normally, for building, or for development) on exactly the workspace
//!   crates its line names.
//! - The README's crate diagram (the block after `tidy:crates`) names every workspace crate,
//!   each with exactly the workspace crates it depends on (`[deps: ...]`).
//! - No code outside `fem-solvers` names a solver: the solver list lives in its registry
//!   (scene fixtures, docs and tests may name solvers).
//! - Every path `ARCHITECTURE.md` names in backticks exists.
//! - Every Rust source file opens with a `//!` doc comment.
//! - In the crates laid out as layered folders (`LAYERED_CRATES`: fem-solvers), the
//!   top-level modules of `src/` (each folder, each file beside `lib.rs`) import each other
//!   without a circle: drawn from the `crate::...` paths of their code (comments and
//!   `#[cfg(test)] mod tests` left out; a name `lib.rs` re-exports counts as the module it
//!   comes from), the graph has no cycle, so the tree reads bottom up.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives one level below the root")
        .to_path_buf()
}

fn architecture() -> String {
    std::fs::read_to_string(root().join("ARCHITECTURE.md")).expect("ARCHITECTURE.md exists")
}

/// The layering block of ARCHITECTURE.md: `crate -> dep, dep` lines (`-> (none)` for none).
fn documented_layering() -> BTreeMap<String, BTreeSet<String>> {
    let text = architecture();
    let start = text
        .find("tidy:layering")
        .expect("ARCHITECTURE.md has a `tidy:layering` block");
    let block = text[start..]
        .split("```")
        .nth(1)
        .expect("the layering block is fenced with ```");
    let mut map = BTreeMap::new();
    for line in block.lines().map(str::trim).filter(|l| l.contains("->")) {
        let (krate, deps) = line.split_once("->").unwrap();
        let deps: BTreeSet<String> = deps
            .split(',')
            .map(str::trim)
            .filter(|d| !d.is_empty() && *d != "(none)")
            .map(str::to_owned)
            .collect();
        map.insert(krate.trim().to_owned(), deps);
    }
    map
}

/// Workspace crates and, for each, the workspace crates it depends on (any kind).
fn actual_layering() -> BTreeMap<String, BTreeSet<String>> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let out = Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .current_dir(root())
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("metadata is JSON");
    let packages = meta["packages"].as_array().expect("packages array");
    let names: BTreeSet<String> = packages
        .iter()
        .map(|p| p["name"].as_str().unwrap().to_owned())
        .collect();
    packages
        .iter()
        .map(|p| {
            let deps = p["dependencies"]
                .as_array()
                .unwrap()
                .iter()
                .map(|d| d["name"].as_str().unwrap().to_owned())
                .filter(|d| names.contains(d))
                .collect();
            (p["name"].as_str().unwrap().to_owned(), deps)
        })
        .collect()
}

#[test]
fn crate_layering_matches_architecture_md() {
    let documented = documented_layering();
    let actual = actual_layering();
    let doc_crates: BTreeSet<_> = documented.keys().collect();
    let real_crates: BTreeSet<_> = actual.keys().collect();
    assert_eq!(
        doc_crates, real_crates,
        "ARCHITECTURE.md's layering block must list exactly the workspace crates"
    );
    for (krate, deps) in &actual {
        let allowed = &documented[krate];
        let extra: Vec<_> = deps.difference(allowed).collect();
        assert!(
            extra.is_empty(),
            "{krate} depends on {extra:?}, which ARCHITECTURE.md's layering does not allow"
        );
        let missing: Vec<_> = allowed.difference(deps).collect();
        assert!(
            missing.is_empty(),
            "ARCHITECTURE.md says {krate} depends on {missing:?}, but it does not: keep it true"
        );
    }
}

/// The README's crate diagram: `crate ... [deps: a, b]` lines (`[deps: none]` for none).
fn readme_crates() -> BTreeMap<String, BTreeSet<String>> {
    let text = std::fs::read_to_string(root().join("README.md")).expect("README.md exists");
    let start = text
        .find("tidy:crates")
        .expect("README.md has a `tidy:crates` block");
    let block = text[start..]
        .split("```")
        .nth(1)
        .expect("the crate diagram is fenced with ```");
    let mut map = BTreeMap::new();
    for line in block.lines().filter(|l| l.contains("[deps:")) {
        let krate = line.split_whitespace().next().unwrap().to_owned();
        let deps = line
            .rsplit_once("[deps:")
            .unwrap()
            .1
            .trim_end()
            .trim_end_matches(']')
            .split(',')
            .map(str::trim)
            .filter(|d| !d.is_empty() && *d != "none")
            .map(str::to_owned)
            .collect();
        map.insert(krate, deps);
    }
    map
}

#[test]
fn readme_crate_diagram_matches_cargo_metadata() {
    let readme = readme_crates();
    let actual = actual_layering();
    assert_eq!(
        readme.keys().collect::<BTreeSet<_>>(),
        actual.keys().collect::<BTreeSet<_>>(),
        "README.md's crate diagram must list exactly the workspace crates"
    );
    for (krate, deps) in &actual {
        assert_eq!(
            &readme[krate], deps,
            "README.md's crate diagram gives {krate} other dependencies than cargo metadata"
        );
    }
}

/// The names of the solvers, from docs/solvers.md's capability table (first column).
fn solver_names() -> Vec<String> {
    let text =
        std::fs::read_to_string(root().join("docs/solvers.md")).expect("docs/solvers.md exists");
    let start = text
        .find("<!-- capabilities:begin -->")
        .expect("docs/solvers.md has the capability table");
    let end = text.find("<!-- capabilities:end -->").unwrap();
    text[start..end]
        .lines()
        .filter(|l| l.starts_with('|') && !l.starts_with("|---") && !l.starts_with("| solver"))
        .filter_map(|l| l.split('|').nth(1))
        .map(|c| c.trim().trim_matches('`').to_owned())
        .filter(|c| !c.is_empty())
        .collect()
}

#[test]
fn no_code_outside_fem_solvers_names_a_solver() {
    let names = solver_names();
    assert!(names.len() >= 5, "solvers in docs/solvers.md: {names:?}");
    let mut files = Vec::new();
    rust_files(&root().join("crates"), &mut files);
    rust_files(&root().join("xtask/src"), &mut files);
    let mut offenders = Vec::new();
    for f in files {
        let rel = f
            .strip_prefix(root())
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        // The registry's own crate, and tests, benches and examples, may name solvers; so may
        // xtask's forward-Euler scan, a study of the explicit solver's own `scheme` parameter,
        // and the frame budget, whose ladders climb each solver's own parameters.
        if rel.starts_with("crates/fem-solvers/")
            || rel == "xtask/src/table1.rs"
            || rel == "crates/fem-cases/src/budget/mod.rs"
            || rel.contains("/tests/")
            || rel.contains("/benches/")
            || rel.contains("/examples/")
        {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap();
        for (n, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            // An obstacle's motion is also called "static"; it is not a solver.
            if code.contains("Motion") {
                continue;
            }
            for name in &names {
                // A solver named in code: a string literal `"pbd"` ...
                let quoted = format!("\"{name}\"");
                let variant: String = name
                    .split('-')
                    .map(|w| {
                        let mut c = w.chars();
                        c.next()
                            .map(|f| f.to_uppercase().collect::<String>() + c.as_str())
                            .unwrap_or_default()
                    })
                    .collect();
                // ... or its registry variant or its own types (`SolverKind::Pbd`,
                // `PbdParams`, `PbdStepper`).
                let is_variant = ["SolverKind::", "SolverParams::", "AnyStepper::"]
                    .iter()
                    .any(|p| code.contains(&format!("{p}{variant}")))
                    || code.contains(&format!("{variant}Params"))
                    || code.contains(&format!("{variant}Stepper"));
                if code.contains(&quoted) || is_variant {
                    offenders.push(format!("{rel}:{}: {}", n + 1, line.trim()));
                }
            }
        }
    }
    assert!(
        offenders.is_empty(),
        "solvers are named outside fem-solvers (ask the registry instead):\n{}",
        offenders.join("\n")
    );
}

#[test]
fn paths_named_in_architecture_md_exist() {
    let text = architecture();
    let mut checked = 0;
    for (i, piece) in text.split('`').enumerate() {
        // Odd pieces are inside backticks.
        let looks_like_path = i % 2 == 1
            && !piece.contains(' ')
            && (piece.contains('/') || piece.ends_with(".md") || piece.ends_with(".toml"))
            && !piece.contains("::")
            && !piece.starts_with("http");
        if looks_like_path {
            let path = root().join(piece.trim_end_matches('/'));
            assert!(
                path.exists(),
                "ARCHITECTURE.md names `{piece}`, which does not exist"
            );
            checked += 1;
        }
    }
    assert!(
        checked >= 5,
        "expected ARCHITECTURE.md to name paths, found {checked}"
    );
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name();
        if path.is_dir() {
            if name != "target" && !name.to_string_lossy().starts_with('.') {
                rust_files(&path, out);
            }
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn every_rust_file_opens_with_a_module_doc() {
    let mut files = Vec::new();
    rust_files(&root().join("crates"), &mut files);
    rust_files(&root().join("xtask"), &mut files);
    assert!(files.len() > 10, "found only {} Rust files", files.len());
    let offenders: Vec<_> = files
        .iter()
        .filter(|f| {
            let text = std::fs::read_to_string(f).unwrap_or_default();
            !text.trim_start().starts_with("//!")
        })
        .map(|f| f.strip_prefix(root()).unwrap().display().to_string())
        .collect();
    assert!(
        offenders.is_empty(),
        "these files do not open with a `//!` doc comment: {offenders:?}"
    );
}

/// The workspace's `rust-version` is a true minimum: at least every dependency's own (a
/// consumer on an older compiler gets cargo's clear message, not a build failure deep in a
/// dependency).
#[test]
fn rust_version_is_at_least_every_dependencys() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let out = Command::new(cargo)
        .args(["metadata", "--format-version", "1"])
        .current_dir(root())
        .output()
        .expect("cargo metadata runs");
    assert!(out.status.success());
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("metadata is JSON");
    let parse = |v: &str| -> Vec<u32> {
        let mut p: Vec<u32> = v.split('.').map(|x| x.parse().unwrap_or(0)).collect();
        p.resize(3, 0);
        p
    };
    let members: BTreeSet<&str> = meta["workspace_members"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    let mut ours = None;
    let mut needed = (vec![0, 0, 0], String::new());
    for p in meta["packages"].as_array().unwrap() {
        let Some(rv) = p["rust_version"].as_str() else {
            continue;
        };
        if members.contains(p["id"].as_str().unwrap()) {
            ours = Some(parse(rv));
        } else if parse(rv) > needed.0 {
            needed = (
                parse(rv),
                format!(
                    "{} {}",
                    p["name"].as_str().unwrap_or("?"),
                    p["version"].as_str().unwrap_or("?")
                ),
            );
        }
    }
    let ours = ours.expect("the workspace declares a rust-version");
    assert!(
        ours >= needed.0,
        "rust-version {ours:?} is below {:?}, which {} needs",
        needed.0,
        needed.1
    );
}

/// The top-level modules of a crate's `src/`: its folders and the files beside `lib.rs` (or
/// `main.rs`), by name.
fn top_level_modules(src: &Path) -> BTreeSet<String> {
    let mut units = BTreeSet::new();
    for entry in std::fs::read_dir(src).expect("src/ is readable").flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if path.is_dir() {
            units.insert(name);
        } else if let Some(stem) = name.strip_suffix(".rs")
            && stem != "lib"
            && stem != "main"
        {
            units.insert(stem.to_owned());
        }
    }
    units
}

/// A Rust file's code: comment lines dropped, and everything from a trailing
/// `#[cfg(test)] mod tests` on (test code may reach anywhere).
fn code_of(text: &str) -> String {
    let mut code = String::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let t = line.trim_start();
        if t.starts_with("#[cfg(test)]")
            && lines
                .peek()
                .is_some_and(|next| next.trim_start().starts_with("mod tests"))
        {
            break;
        }
        if !t.starts_with("//") {
            code.push_str(line);
            code.push('\n');
        }
    }
    code
}

/// The first path segment after each `crate::` (or `$crate::`) in `code`.
fn crate_paths(code: &str) -> Vec<String> {
    code.match_indices("crate::")
        .map(|(i, m)| {
            code[i + m.len()..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect()
        })
        .filter(|s: &String| !s.is_empty())
        .collect()
}

/// The names `lib.rs` re-exports from a top-level module (`pub use model::{bc, Model};` maps
/// `bc` and `Model` to `model`).
fn root_reexports(lib: &str, units: &BTreeSet<String>) -> BTreeMap<String, String> {
    let mut names = BTreeMap::new();
    for statement in code_of(lib).split(';') {
        let Some(rest) = statement.trim().strip_prefix("pub use ") else {
            continue;
        };
        let rest = rest.trim().trim_start_matches("crate::");
        let Some((first, tail)) = rest.split_once("::") else {
            continue;
        };
        if !units.contains(first) {
            continue;
        }
        let list = tail
            .rsplit_once('{')
            .map_or(tail, |(_, inner)| inner.trim_end_matches('}'));
        for item in list.split(',') {
            let item = item.trim();
            let name = item.rsplit_once(" as ").map_or(item, |(_, alias)| alias);
            let name = name.rsplit("::").next().unwrap_or(name).trim();
            if !name.is_empty() {
                names.insert(name.to_owned(), first.to_owned());
            }
        }
    }
    names
}

/// The first cycle of a directed graph, as its nodes in order (the first repeated at the end).
fn find_cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        done: &mut BTreeSet<String>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|p| p == node) {
            let mut cycle = path[at..].to_vec();
            cycle.push(node.to_owned());
            return Some(cycle);
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_owned());
        for next in graph.get(node).into_iter().flatten() {
            if let Some(cycle) = visit(next, graph, done, path) {
                return Some(cycle);
            }
        }
        path.pop();
        done.insert(node.to_owned());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|node| visit(node, graph, &mut done, &mut Vec::new()))
}

/// The crates whose `src/` is laid out as folders that are layers (ARCHITECTURE.md's code
/// map); the flat crates' files may use each other freely.
const LAYERED_CRATES: [&str; 1] = ["fem-solvers"];

#[test]
fn top_level_modules_import_each_other_without_a_circle() {
    let crates: Vec<PathBuf> = LAYERED_CRATES
        .iter()
        .map(|c| root().join("crates").join(c).join("src"))
        .collect();
    let mut failures = Vec::new();
    for src in &crates {
        let units = top_level_modules(src);
        let lib = ["lib.rs", "main.rs"]
            .iter()
            .find_map(|f| std::fs::read_to_string(src.join(f)).ok())
            .unwrap_or_default();
        let reexports = root_reexports(&lib, &units);
        // unit -> (imported unit -> the first file that imports it)
        let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        let mut witness: BTreeMap<(String, String), String> = BTreeMap::new();
        for unit in &units {
            let mut files = Vec::new();
            let dir = src.join(unit);
            if dir.is_dir() {
                rust_files(&dir, &mut files);
            } else {
                files.push(src.join(format!("{unit}.rs")));
            }
            files.sort();
            for file in files {
                let text = std::fs::read_to_string(&file).expect("a source file is readable");
                for name in crate_paths(&code_of(&text)) {
                    let target = if units.contains(&name) {
                        Some(&name)
                    } else {
                        reexports.get(&name)
                    };
                    if let Some(target) = target.filter(|t| *t != unit) {
                        graph
                            .entry(unit.clone())
                            .or_default()
                            .insert(target.clone());
                        witness
                            .entry((unit.clone(), target.clone()))
                            .or_insert_with(|| {
                                file.strip_prefix(root()).unwrap().display().to_string()
                            });
                    }
                }
            }
        }
        if let Some(cycle) = find_cycle(&graph) {
            let steps: Vec<String> = cycle
                .windows(2)
                .map(|w| {
                    format!(
                        "{} -> {} ({})",
                        w[0],
                        w[1],
                        witness[&(w[0].clone(), w[1].clone())]
                    )
                })
                .collect();
            failures.push(format!(
                "{}: the top-level modules import each other in a circle: {}",
                src.parent().unwrap().display(),
                steps.join(", ")
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The checker itself: a circle through a re-exported name is found, test code is not read.
#[test]
fn the_module_circle_check_sees_reexports_and_skips_tests() {
    let units: BTreeSet<String> = ["model", "contact", "steppers"].map(String::from).into();
    let lib = "mod model;\npub use model::{bc, grab::Grab, Model};\npub use contact::Contact;\n";
    let names = root_reexports(lib, &units);
    assert_eq!(names["bc"], "model");
    assert_eq!(names["Grab"], "model");
    assert_eq!(names["Model"], "model");
    assert_eq!(names["Contact"], "contact");
    let code = code_of(
        "//! [`crate::steppers`]\nuse crate::Model;\n#[cfg(test)]\nmod tests {\n    use crate::steppers;\n}\n",
    );
    assert_eq!(crate_paths(&code), ["Model"]);
    let graph: BTreeMap<String, BTreeSet<String>> = [
        ("model".to_owned(), ["contact".to_owned()].into()),
        ("contact".to_owned(), ["model".to_owned()].into()),
    ]
    .into();
    assert_eq!(find_cycle(&graph).unwrap(), ["contact", "model", "contact"]);
    let dag: BTreeMap<String, BTreeSet<String>> =
        [("steppers".to_owned(), ["model".to_owned()].into())].into();
    assert!(find_cycle(&dag).is_none());
}
