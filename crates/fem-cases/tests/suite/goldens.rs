//! Golden results of the built-in cases A-D: each case runs through the library on one thread
//! (the full scene, no overrides) and its deterministic summary values (step and mesh counts,
//! blow-up, smallest det F, peak and final von Mises stress, largest displacement, each probe's
//! final displacement and vertical range) must match `fixtures/goldens/CASE.json` within the
//! tolerance stated in that file (its "why" says how it was chosen).
//!
//! The goldens are written by `cargo xtask goldens`, which runs
//! `fem2d run CASE --threads 1 -q --out DIR`; when a change of results is intended, run it and
//! commit the new files.

use std::path::PathBuf;

use fem_cases::run::{RunOptions, run_scene};
use fem_scene::cases::load_case;
use serde_json::Value;

fn golden(case: &str) -> Value {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/goldens")
        .join(format!("{case}.json"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e}; run `cargo xtask goldens` to create it",
            path.display()
        )
    });
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: not JSON: {e}", path.display()))
}

/// The summary as JSON, reshaped like the golden's "values" (probes keyed by name).
fn current(case: &str) -> Value {
    let scene = load_case(case, &[]).unwrap_or_else(|e| panic!("{case}: {e}"));
    let result = run_scene(
        &scene,
        &RunOptions {
            out_dir: None,
            threads: Some(1),
            ..RunOptions::default()
        },
    )
    .unwrap_or_else(|e| panic!("{case}: {e}"));
    let mut summary = serde_json::to_value(&result.summary).expect("the summary serialises");
    let probes: serde_json::Map<String, Value> = summary["probes"]
        .as_array()
        .expect("probes")
        .iter()
        .map(|p| (p["name"].as_str().expect("name").to_owned(), p.clone()))
        .collect();
    summary["probes"] = Value::Object(probes);
    summary
}

/// Compare `now` with `want` (a golden value) at `path`; mismatches are appended to `errors`.
fn compare(
    path: &str,
    want: &Value,
    now: &Value,
    unit: &str,
    tol: &Value,
    errors: &mut Vec<String>,
) {
    match want {
        Value::Object(map) => {
            for (k, w) in map {
                compare(&format!("{path}.{k}"), w, &now[k], unit, tol, errors);
            }
        }
        Value::Array(items) => {
            for (k, w) in items.iter().enumerate() {
                compare(&format!("{path}[{k}]"), w, &now[k], unit, tol, errors);
            }
        }
        Value::Number(n) if unit != "count" => {
            let (w, x) = (n.as_f64().expect("a number"), now.as_f64());
            let absolute = match unit {
                "m" => tol["absolute_m"].as_f64().expect("absolute_m"),
                "Pa" => tol["absolute_pa"].as_f64().expect("absolute_pa"),
                _ => 0.0,
            };
            let allowed = absolute + tol["relative"].as_f64().expect("relative") * w.abs();
            match x {
                Some(x) if (x - w).abs() <= allowed => {}
                Some(x) => errors.push(format!(
                    "{path}: {x:e} now, {w:e} in the golden (difference {:.3e} {unit}, allowed {allowed:.3e})",
                    (x - w).abs()
                )),
                None => errors.push(format!("{path}: {now} now, {w:e} in the golden")),
            }
        }
        _ => {
            if want != now {
                errors.push(format!("{path}: {now} now, {want} in the golden"));
            }
        }
    }
}

fn check(case: &str) {
    let golden = golden(case);
    assert_eq!(
        golden["case"], case,
        "the golden of {case} names another case"
    );
    let now = current(case);
    let tol = &golden["tolerance"];
    let units = &golden["units"];
    let mut errors = Vec::new();
    for (field, want) in golden["values"].as_object().expect("values") {
        let unit = units[field].as_str().unwrap_or("1");
        compare(field, want, &now[field], unit, tol, &mut errors);
    }
    assert!(
        errors.is_empty(),
        "{case} no longer matches fixtures/goldens/{case}.json:\n  {}\nIf the change is intended, run `cargo xtask goldens` and commit the new goldens.",
        errors.join("\n  ")
    );
}

#[test]
fn case_a_matches_its_golden() {
    check("case-a");
}

#[test]
fn case_b_matches_its_golden() {
    check("case-b");
}

#[test]
fn case_c_matches_its_golden() {
    check("case-c");
}

#[test]
fn case_d_matches_its_golden() {
    check("case-d");
}
