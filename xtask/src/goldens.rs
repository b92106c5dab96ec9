//! `cargo xtask goldens`: regenerate `fixtures/goldens/case-{a,b,c,d}.json`, the deterministic
//! results of each built-in case that `crates/fem-cases/tests/suite/goldens.rs` checks.
//!
//! For each case: `fem2d run CASE --threads 1 -q --out TMP` (the full scene, no overrides),
//! then a small JSON of the summary's deterministic quantities (no timings) with the tolerance
//! the test applies and why. The "why" quotes a measurement made here: the same case run again
//! with Young's modulus changed in its last bits, which shows how much the case amplifies
//! rounding differences.

use serde_json::{Map, Value, json};

use crate::util::{Fem2d, TempDir, array, read_json, root, text, write_atomic};

/// The cases.
pub const CASES: [&str; 4] = ["case-a", "case-b", "case-c", "case-d"];

/// Relative tolerance of every real value.
pub const RELATIVE: f64 = 1e-6;
/// Absolute floor for lengths (m), for values near zero.
pub const ABSOLUTE_M: f64 = 1e-9;
/// Absolute floor for stresses (Pa), for values near zero.
pub const ABSOLUTE_PA: f64 = 1e-6;

/// Summary fields kept, and their units (`1`: dimensionless, `count` and `bool`: exact).
pub const FIELDS: [(&str, &str); 10] = [
    ("steps_completed", "count"),
    ("vertices", "count"),
    ("triangles", "count"),
    ("blew_up", "bool"),
    ("inverted_elements", "count"),
    ("min_det_f", "1"),
    ("max_von_mises", "Pa"),
    ("final_max_von_mises", "Pa"),
    ("final_max_vertex_von_mises", "Pa"),
    ("final_max_displacement", "m"),
];

/// The golden values of a `summary.json`: [`FIELDS`], then per probe its final displacement
/// and its vertical displacement range (m).
pub fn values(summary: &Value) -> Result<Value, String> {
    let mut v = Map::new();
    for (field, _) in FIELDS {
        let x = &summary[field];
        if x.is_null() {
            return Err(format!("summary.json has no `{field}`"));
        }
        v.insert(field.to_owned(), x.clone());
    }
    let mut probes = Map::new();
    for p in array(summary, "probes")? {
        probes.insert(
            text(p, "name")?.to_owned(),
            json!({
                "final_displacement": p["final_displacement"],
                "uy_range": p["uy_range"],
            }),
        );
    }
    v.insert("probes".into(), Value::Object(probes));
    Ok(Value::Object(v))
}

/// Every real number of `a` and `b` (same layout) with its unit: `(path, unit, a, b)`.
fn reals(a: &Value, b: &Value) -> Vec<(String, &'static str, f64, f64)> {
    let mut out = Vec::new();
    for (field, unit) in FIELDS {
        if let (Some(x), Some(y)) = (a[field].as_f64(), b[field].as_f64())
            && (unit == "1" || unit == "Pa" || unit == "m")
        {
            out.push((field.to_owned(), unit, x, y));
        }
    }
    if let Some(probes) = a["probes"].as_object() {
        for (name, p) in probes {
            for key in ["final_displacement", "uy_range"] {
                for k in 0..2 {
                    if let (Some(x), Some(y)) =
                        (p[key][k].as_f64(), b["probes"][name][key][k].as_f64())
                    {
                        out.push((format!("probes.{name}.{key}[{k}]"), "m", x, y));
                    }
                }
            }
        }
    }
    out
}

fn run_case(fem2d: &Fem2d, case: &str, sets: &[String]) -> Result<(Value, String), String> {
    let dir = TempDir::new("goldens")?;
    let out = dir.arg();
    let mut args = vec![case, "--threads", "1", "-q", "--out", &out];
    for s in sets {
        args.push("--set");
        args.push(s);
    }
    let mut full = vec!["run"];
    full.extend(args);
    // `fem2d run` exits non-zero when the run blows up but still writes summary.json; a blow-up
    // is a result the golden records.
    let output = fem2d.output(&full)?;
    let summary_path = dir.path().join("summary.json");
    if !summary_path.exists() {
        return Err(format!(
            "`fem2d {}` wrote no summary.json: {}",
            full.join(" "),
            output.stderr.trim()
        ));
    }
    let summary = read_json(&summary_path)?;
    let scene = std::fs::read_to_string(dir.path().join("scene.toml")).unwrap_or_default();
    Ok((summary, scene))
}

/// Young's modulus from the `scene.toml` a run wrote (`youngs_modulus = ...` in `[material]`).
fn youngs_modulus(scene: &str) -> Result<f64, String> {
    scene
        .lines()
        .filter_map(|l| l.trim().strip_prefix("youngs_modulus"))
        .filter_map(|rest| rest.trim().strip_prefix('='))
        .find_map(|v| v.trim().parse::<f64>().ok())
        .ok_or_else(|| "scene.toml has no `youngs_modulus`".to_owned())
}

/// Entry point: `args` are what follows `goldens`.
pub fn run(args: &[&str]) -> Result<(), String> {
    if !args.is_empty() {
        return Err("usage: cargo xtask goldens".into());
    }
    let fem2d = Fem2d::build()?;
    for case in CASES {
        eprintln!("goldens: {case}");
        let (summary, scene) = run_case(&fem2d, case, &[])?;
        let golden = values(&summary)?;
        // The same case with E moved by 4 units in its last place: a stand-in for a compiler,
        // CPU or libm that rounds some operation differently.
        let e = youngs_modulus(&scene)?;
        let e2 = e * (1.0 + 4.0 * f64::EPSILON);
        let (perturbed, _) = run_case(&fem2d, case, &[format!("material.youngs_modulus={e2:?}")])?;
        let perturbed = values(&perturbed)?;
        let mut spread: f64 = 0.0;
        let mut spread_at = String::from("nothing");
        for (path, _unit, a, b) in reals(&golden, &perturbed) {
            // Relative change of every non-zero value (exact zeros, e.g. a pinned coordinate,
            // are covered by the absolute floors).
            if a == 0.0 {
                continue;
            }
            let r = (a - b).abs() / a.abs();
            if r > spread {
                spread = r;
                spread_at = path;
            }
        }
        let counts_equal = FIELDS
            .iter()
            .filter(|(_, u)| *u == "count" || *u == "bool")
            .all(|(f, _)| golden[f] == perturbed[f]);
        if spread > RELATIVE / 100.0 || !counts_equal {
            eprintln!(
                "warning: {case} amplifies a last-bit change of E to {spread:.1e} relative (at {spread_at}){}: the tolerance {RELATIVE:e} may be too tight across machines",
                if counts_equal {
                    ""
                } else {
                    " and changes a count"
                }
            );
        }
        let command = format!("fem2d run {case} --threads 1 -q --out DIR");
        let why = format!(
            "The run is deterministic for a given build (one thread; the parallel paths are bit-identical to the serial ones anyway), so on the machine that wrote this file the difference is zero. The tolerance absorbs last-bit floating-point differences between compilers, CPUs and libm: running this case with Young's modulus changed by about 4 units in the last place ({e:?} -> {e2:?}) moved these values by at most {spread:.1e} relative (at {spread_at}; measured by `cargo xtask goldens`), so a relative tolerance of {RELATIVE:e} leaves a wide margin, while a change of physics, mesh, solver or scene moves them by far more. The absolute floors ({ABSOLUTE_M:e} m, {ABSOLUTE_PA:e} Pa) matter only for values near zero. Counts and flags must match exactly. A value passes when |now - golden| <= absolute + relative x |golden|."
        );
        let file = json!({
            "case": case,
            "command": command,
            "tolerance": {
                "relative": RELATIVE,
                "absolute_m": ABSOLUTE_M,
                "absolute_pa": ABSOLUTE_PA,
            },
            "why": why,
            "units": FIELDS.iter().map(|(f, u)| (f.to_string(), Value::from(*u))).chain(std::iter::once(("probes".to_owned(), Value::from("m")))).collect::<Map<_, _>>(),
            "values": golden,
        });
        let text = serde_json::to_string_pretty(&file).map_err(|e| e.to_string())? + "\n";
        write_atomic(
            &root().join("fixtures/goldens").join(format!("{case}.json")),
            text.as_bytes(),
        )?;
    }
    Ok(())
}
