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
            || rel == "crates/fem-cases/src/budget.rs"
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
