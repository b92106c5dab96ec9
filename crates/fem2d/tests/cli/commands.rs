//! `fem2d compare`, `budget`, `table1`, `sweep` and `merge` end to end: the files they write, shards that
//! cover a sweep exactly once, the merge's refusal of incomplete or mixed shards, and one-line
//! errors for bad input.

use crate::common::{arg, fem2d, scratch};
use std::path::Path;
use std::process::Output;

fn ok(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

fn one_line_error(out: &Output) -> String {
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    stderr
}

#[test]
fn compare_writes_markdown_csv_and_json_with_one_row_per_combination() {
    let dir = scratch("compare");
    let out = ok(&fem2d(&[
        "compare",
        "case-c",
        "--energies",
        "stvk,neo-hookean",
        "--solvers",
        "explicit,pbd,xpbd",
        "--iterations",
        "5,10",
        "--set",
        "solver.steps=100",
        "--threads",
        "1",
        "--out",
        arg(&dir),
    ]));
    assert!(out.contains("| stvk | pbd | 5 it |"), "{out}");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("compare.json")).unwrap()).unwrap();
    // Per energy: explicit, pbd x 2 iteration counts, xpbd x 2.
    assert_eq!(json["rows"].as_array().unwrap().len(), 2 * 5);
    let csv = std::fs::read_to_string(dir.join("compare.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 10);
    assert!(csv.starts_with("energy,solver,variant,stable,steps_completed,tip.ux"));
    // Every row's tip curve side by side: 100 steps at frame_every 10 give 11 frames.
    let curves = std::fs::read_to_string(dir.join("curves.csv")).unwrap();
    assert_eq!(curves.lines().count(), 1 + 11);
    let header: Vec<&str> = curves.lines().next().unwrap().split(',').collect();
    assert_eq!(header.len(), 2 + 10 * 2);
    assert_eq!(header[2], "stvk/explicit:tip.ux");
    assert!(
        header.contains(&"neo-hookean/pbd/10-it:tip.uy"),
        "{header:?}"
    );
    // Rows after the explicit one carry their distance from it.
    assert!(json["rows"][1]["probes"][0]["rms_vs_explicit"].is_number());
    assert!(
        std::fs::read_to_string(dir.join("compare.md")).unwrap()
            == out
                .lines()
                .take_while(|l| !l.starts_with("wrote"))
                .collect::<Vec<_>>()
                .join("\n")
                + "\n"
    );
}

#[test]
fn compare_rejects_unknown_names_in_one_line() {
    one_line_error(&fem2d(&["compare", "case-a", "--energies", "stvk,foo"]));
    one_line_error(&fem2d(&["compare", "case-a", "--solvers", "explicit,rk4"]));
    one_line_error(&fem2d(&["compare", "case-z"]));
}

#[test]
fn table1_json_has_three_energies_and_the_paper_values() {
    let out = ok(&fem2d(&[
        "table1",
        "--json",
        "--repeats",
        "1",
        "--threads",
        "1",
    ]));
    let t: serde_json::Value = serde_json::from_str(&out).unwrap();
    let rows = t["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 3);
    assert_eq!(rows[0]["energy"], "stvk");
    assert_eq!(rows[0]["paper_mm"][1], 1269.0);
    assert_eq!(
        t["ordering_matches"],
        serde_json::json!([true, true, true, true])
    );
}

const SPEC: &str = r#"
scene = "case-a"
set = ["solver.steps=40", "output.frame_every=20"]

[[axis]]
key = "energy"
values = ["stvk", "neo-hookean", "corotational"]

[[axis]]
key = "solver.dt"
values = [1e-3, 0.05]
"#;

#[test]
fn shards_cover_a_sweep_once_and_merge_joins_them() {
    let dir = scratch("sweep");
    let spec = dir.join("spec.toml");
    std::fs::write(&spec, SPEC).unwrap();
    let shards = dir.join("shards");
    for i in 0..4 {
        ok(&fem2d(&[
            "sweep",
            arg(&spec),
            "--shard",
            &format!("{i}/4"),
            "--threads",
            "1",
            "--out",
            arg(&shards),
        ]));
    }
    let merged = dir.join("merged");
    // A missing shard is named in one line and nothing is written.
    let partial = [0, 1, 2].map(|i| shards.join(format!("shard-{i}-of-4.json")));
    let mut args = vec!["merge"];
    args.extend(partial.iter().map(|p| arg(p)));
    args.extend(["--out", arg(&merged)]);
    let err = one_line_error(&fem2d(&args));
    assert!(err.contains("1 of 6 jobs are missing (first: 3)"), "{err}");
    assert!(!merged.join("sweep.json").exists());

    let out = ok(&fem2d(&["merge", arg(&shards), "--out", arg(&merged)]));
    assert!(out.contains("Largest stable time step"), "{out}");
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(merged.join("sweep.json")).unwrap()).unwrap();
    let results = m["results"].as_array().unwrap();
    assert_eq!(results.len(), 6);
    for (k, r) in results.iter().enumerate() {
        assert_eq!(r["job"]["index"], k);
    }
    // dt = 0.05 s is far beyond the explicit limit: every energy blows up there, and the
    // stability table says 1e-3 is the largest stable step.
    for r in results {
        let dt = &r["job"]["params"][1][1];
        assert_eq!(r["summary"]["blew_up"], dt == "0.05", "{r}");
    }
    assert!(out.contains("| stvk | 1e-3 | 5e-2 |"), "{out}");
    let csv = std::fs::read_to_string(merged.join("sweep.csv")).unwrap();
    assert_eq!(csv.lines().count(), 7);

    // Shards of a different spec are refused.
    let other = dir.join("other.toml");
    std::fs::write(&other, SPEC.replace("solver.steps=40", "solver.steps=30")).unwrap();
    let other_dir = dir.join("other");
    ok(&fem2d(&[
        "sweep",
        arg(&other),
        "--shard",
        "0/4",
        "--out",
        arg(&other_dir),
    ]));
    let mixed = other_dir.join("shard-0-of-4.json");
    let err = one_line_error(&fem2d(&[
        "merge",
        arg(&shards.join("shard-1-of-4.json")),
        arg(&mixed),
        "--out",
        arg(&dir.join("mixed")),
    ]));
    assert!(err.contains("different sweep spec"), "{err}");
}

/// A UTF-8 byte-order mark before a sweep spec or a shard file (an editor's) is skipped.
#[test]
fn a_byte_order_mark_before_a_sweep_spec_or_a_shard_is_skipped() {
    let dir = scratch("sweep-bom");
    let spec = dir.join("spec.toml");
    std::fs::write(
        &spec,
        "\u{feff}scene = \"case-a\"\nset = [\"solver.steps=10\"]\n\n[[axis]]\nkey = \"energy\"\nvalues = [\"stvk\"]\n",
    )
    .unwrap();
    let shards = dir.join("shards");
    ok(&fem2d(&[
        "sweep",
        arg(&spec),
        "--shard",
        "0/1",
        "--threads",
        "1",
        "--out",
        arg(&shards),
    ]));
    let shard = shards.join("shard-0-of-1.json");
    let text = std::fs::read(&shard).unwrap();
    std::fs::write(&shard, [b"\xEF\xBB\xBF".as_slice(), &text].concat()).unwrap();
    ok(&fem2d(&[
        "merge",
        arg(&shard),
        "--out",
        arg(&dir.join("merged")),
    ]));
    assert!(dir.join("merged/sweep.json").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn sweep_rejects_bad_specs_and_shards_in_one_line() {
    let dir = scratch("sweep-bad");
    let spec = dir.join("spec.toml");
    std::fs::write(&spec, SPEC).unwrap();
    let out = dir.join("out");
    one_line_error(&fem2d(&[
        "sweep",
        arg(&spec),
        "--shard",
        "4/4",
        "--out",
        arg(&out),
    ]));
    one_line_error(&fem2d(&[
        "sweep",
        arg(&spec),
        "--shard",
        "x",
        "--out",
        arg(&out),
    ]));
    std::fs::write(&spec, "scene = \"case-a\"\n").unwrap();
    one_line_error(&fem2d(&["sweep", arg(&spec), "--out", arg(&out)]));
    std::fs::write(&spec, "scene = \"case-a\"\n[[axis]]\nkeys = [\"mesh.nx\", \"mesh.ny\"]\nvalues = [[10, 2], [3]]\n").unwrap();
    let err = one_line_error(&fem2d(&["sweep", arg(&spec), "--out", arg(&out)]));
    assert!(err.contains("axis.0.values.1"), "{err}");
    one_line_error(&fem2d(&[
        "sweep",
        arg(&dir.join("missing.toml")),
        "--out",
        arg(&out),
    ]));
    assert!(!out.exists() || std::fs::read_dir(&out).unwrap().next().is_none());
}

#[test]
fn a_reference_gives_each_job_its_error_and_cost() {
    let dir = scratch("reference");
    let spec = dir.join("spec.toml");
    std::fs::write(
        &spec,
        r#"
scene = "case-a"
duration = 0.2

[reference]
set = ["solver.dt=1e-4"]
probe = "tip"

[[axis]]
key = "solver.dt"
values = [2e-3, 1e-3, 5e-4]
"#,
    )
    .unwrap();
    let out = dir.join("out");
    ok(&fem2d(&[
        "sweep",
        arg(&spec),
        "--threads",
        "1",
        "--out",
        arg(&out),
    ]));
    let md = ok(&fem2d(&["merge", arg(&out), "--out", arg(&out)]));
    assert!(md.contains("Accuracy against the reference"), "{md}");
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("sweep.json")).unwrap()).unwrap();
    let errors: Vec<f64> = m["results"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["reference_error"].as_f64().unwrap())
        .collect();
    // Symplectic Euler is first order: the error against the fine-dt reference shrinks as dt
    // does.
    assert!(errors[0] > errors[1] && errors[1] > errors[2], "{errors:?}");
    assert!(errors[2] > 0.0);
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    assert!(
        csv.lines()
            .next()
            .unwrap()
            .contains(",reference_error,cost_per_simulated_second,")
    );
}

/// Merge refuses every conflict: the same job with different results (timings aside), a spec
/// edited under its old digest, a job whose parameters are not the spec's. Sweep specs with a
/// key swept twice, too many jobs or an endless duration are refused; a reference naming a
/// solver that does not exist or a probe the scene lacks fails the job instead of reporting it.
#[test]
fn merge_refuses_conflicts_and_sweeps_refuse_bad_axes_and_references() {
    let dir = scratch("merge-conflicts");
    let spec = dir.join("spec.toml");
    std::fs::write(&spec, SPEC).unwrap();
    let shards = dir.join("shards");
    ok(&fem2d(&[
        "sweep",
        arg(&spec),
        "--shard",
        "1/2",
        "--threads",
        "1",
        "--out",
        arg(&shards),
    ]));
    let shard = shards.join("shard-1-of-2.json");
    let text = std::fs::read_to_string(&shard).unwrap();
    let original: serde_json::Value = serde_json::from_str(&text).unwrap();
    let tamper = |name: &str, edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v = original.clone();
        edit(&mut v);
        let path = dir.join(name);
        std::fs::write(&path, serde_json::to_string(&v).unwrap()).unwrap();
        path
    };
    let merge_err = |other: &Path| {
        one_line_error(&fem2d(&[
            "merge",
            arg(&shard),
            arg(other),
            "--out",
            arg(&dir.join("merged")),
        ]))
    };
    // A rerun whose timings differ merges (nothing else is compared for timing)...
    let rerun = tamper("rerun.json", &|v| {
        v["results"][0]["summary"]["wall_seconds"] = serde_json::json!(123.0);
    });
    let err = merge_err(&rerun);
    assert!(
        err.contains("jobs are missing"),
        "only shard 1 of 2 given: {err}"
    );
    // ...but a different peak stress does not.
    let differs = tamper("differs.json", &|v| {
        v["results"][0]["summary"]["max_von_mises"] = serde_json::json!(123.0);
    });
    let err = merge_err(&differs);
    assert!(
        err.contains("appears twice with different results (summary.max_von_mises differs)"),
        "{err}"
    );
    let edited = tamper("edited.json", &|v| {
        v["spec"]["set"][0] = serde_json::json!("solver.steps=41");
    });
    let err = merge_err(&edited);
    assert!(
        err.contains("does not match the spec in the file") && err.contains("edited"),
        "{err}"
    );
    let params = tamper("params.json", &|v| {
        v["results"][0]["job"]["params"][0][1] = serde_json::json!("\"linear\"");
    });
    let err = merge_err(&params);
    assert!(err.contains("are not the spec's"), "{err}");

    // Bad specs, each one line before anything runs.
    let out = dir.join("bad-out");
    let bad = |name: &str, text: String, want: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        let err = one_line_error(&fem2d(&["sweep", arg(&path), "--out", arg(&out)]));
        assert!(err.contains(want), "{name}: {err}");
    };
    bad(
        "twice.toml",
        format!("{SPEC}\n[[axis]]\nkey = \"energy\"\nvalues = [\"linear\"]\n"),
        "axis.2: key \"energy\" is already swept by axis.0",
    );
    let thousand: Vec<String> = (0..1000)
        .map(|k| format!("{}", 1e-4 + k as f64 * 1e-7))
        .collect();
    let axis = format!(
        "[[axis]]\nkey = \"solver.dt\"\nvalues = [{}]\n",
        thousand.join(", ")
    );
    bad(
        "huge.toml",
        format!(
            "scene = \"case-a\"\n{axis}[[axis]]\nkey = \"material.youngs_modulus\"\nvalues = [{}]\n[[axis]]\nkey = \"material.density\"\nvalues = [{}]\n",
            thousand.join(", "),
            thousand.join(", ")
        ),
        "1000 x 1000 x 1000 jobs is more than 1000000",
    );
    bad(
        "endless.toml",
        SPEC.replace("scene = \"case-a\"", "scene = \"case-a\"\nduration = 1e300"),
        "duration = 1e300: must be a finite number > 0 and at most 1e6",
    );
    assert!(!out.exists() || std::fs::read_dir(&out).unwrap().next().is_none());

    // References that cannot be made fail the job, naming why.
    for (name, reference, want) in [
        (
            "solver",
            "set = [\"solver.kind=bogus\"]\nprobe = \"tip\"",
            "reference: ",
        ),
        (
            "probe",
            "set = [\"solver.dt=1e-4\"]\nprobe = \"nose\"",
            "reference.probe = \"nose\": the scene has no such probe (it has tip",
        ),
    ] {
        let spec = dir.join(format!("ref-{name}.toml"));
        std::fs::write(
            &spec,
            format!("scene = \"case-a\"\nduration = 0.02\n\n[reference]\n{reference}\n\n[[axis]]\nkey = \"solver.dt\"\nvalues = [1e-3]\n"),
        )
        .unwrap();
        let out = dir.join(format!("ref-{name}"));
        ok(&fem2d(&[
            "sweep",
            arg(&spec),
            "--threads",
            "1",
            "--out",
            arg(&out),
        ]));
        ok(&fem2d(&["merge", arg(&out), "--out", arg(&out)]));
        let m: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("sweep.json")).unwrap()).unwrap();
        let error = m["results"][0]["error"]
            .as_str()
            .unwrap_or_default()
            .to_owned();
        assert!(error.contains(want), "{name}: {error}");
    }
}

#[test]
fn budget_writes_the_ranked_table_the_charts_and_the_trajectories() {
    let dir = scratch("budget");
    let out = dir.join("b");
    let stdout = ok(&fem2d(&[
        "budget",
        "case-a",
        "--energies",
        "neo-hookean",
        "--frameworks",
        "explicit,vbd,pd",
        "--duration",
        "0.2",
        "--out",
        arg(&out),
        "--trajectories",
    ]));
    assert!(
        stdout.contains(
            "neo-hookean at 90 Hz within 5 ms per frame, ranked by position RMS over the whole run (m): explicit"
        ),
        "{stdout}"
    );
    assert!(stdout.contains("cannot run: Projective Dynamics runs the co-rotational energy only"));
    for f in [
        "budget.md",
        "budget.csv",
        "budget.json",
        "pareto-neo-hookean.svg",
        "pareto-neo-hookean.png",
        "phases-neo-hookean.svg",
        "phases-neo-hookean.png",
        "trajectories.json",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // Without --trajectories the (large) trajectories are not written; --rank-by names the
    // quantity.
    let again = dir.join("c");
    let stdout = ok(&fem2d(&[
        "budget",
        "case-a",
        "--energies",
        "neo-hookean",
        "--frameworks",
        "implicit",
        "--duration",
        "0.1",
        "--rank-by",
        "stress",
        "--out",
        arg(&again),
    ]));
    assert!(!again.join("trajectories.json").exists());
    assert!(
        stdout.contains("ranked by the soft tissue's von Mises stress over the whole run"),
        "{stdout}"
    );
    let csv = std::fs::read_to_string(out.join("budget.csv")).unwrap();
    assert!(csv.lines().count() > 10, "{csv}");
    // The haptics preset: 1 kHz, 0.5 ms.
    let stdout = ok(&fem2d(&[
        "budget",
        "case-a",
        "--haptics",
        "--energies",
        "corotational",
        "--frameworks",
        "pd",
        "--duration",
        "0.05",
    ]));
    assert!(
        stdout.contains("at 1000 Hz, 0.500 ms per frame"),
        "{stdout}"
    );
}

#[test]
fn budget_rejects_bad_settings_in_one_line() {
    let e = one_line_error(&fem2d(&["budget", "case-a", "--fps", "0"]));
    assert!(e.contains("--fps 0: must be a finite number > 0"), "{e}");
    let e = one_line_error(&fem2d(&["budget", "case-a", "--budget-ms", "-1"]));
    assert!(e.contains("--budget-ms -1"), "{e}");
    let e = one_line_error(&fem2d(&["budget", "case-a", "--frameworks", "rk4"]));
    assert!(
        e.contains("unknown framework `rk4`") && e.contains("xpbd-small-steps"),
        "{e}"
    );
    let e = one_line_error(&fem2d(&["budget", "case-a", "--duration", "1e9"]));
    assert!(e.contains("at most 100000"), "{e}");
    let e = one_line_error(&fem2d(&["budget", "case-a", "--rank-by", "beauty"]));
    assert!(
        e.contains("--rank-by: unknown quantity `beauty`") && e.contains("stress-impact"),
        "{e}"
    );
    let e = one_line_error(&fem2d(&["budget", "case-a", "--settle", "1"]));
    assert!(
        e.contains("--settle 1: must be in the open interval (0, 1)"),
        "{e}"
    );
    let e = one_line_error(&fem2d(&["budget", "case-a", "--reference-steps", "1"]));
    assert!(
        e.contains("--reference-steps 1: must be an integer from 2 to 10000"),
        "{e}"
    );
    let e = one_line_error(&fem2d(&["budget", "case-a", "--criterion", "nan"]));
    assert!(
        e.contains("--criterion NaN: must be a finite number > 0"),
        "{e}"
    );
    // The scene's [budget] table is checked like every scene key.
    let e = one_line_error(&fem2d(&[
        "budget",
        "case-a",
        "--set",
        "budget.reference_steps=1",
    ]));
    assert!(
        e.contains("budget.reference_steps = 1: must be an integer from 2 to 10000"),
        "{e}"
    );
    let e = one_line_error(&fem2d(&["budget", "case-a", "--set", "budget.duration=-1"]));
    assert!(e.contains("budget.duration = -1"), "{e}");
    let e = one_line_error(&fem2d(&[
        "budget",
        "case-a",
        "--set",
        "budget.energies=[\"stvk\", \"stvk\"]",
    ]));
    assert!(
        e.contains("budget.energies = \"stvk\": is listed twice"),
        "{e}"
    );
}

/// Every numeric flag of `fem2d budget`, given NaN, infinity, 0, a negative, a subnormal and
/// 1e308, fails in one line naming the flag and the value as the user wrote them (`--fps
/// 1e-320: ...`, not the `solver.dt = inf` its frame step would give), before anything runs;
/// the integer flag is the parser's (exit 2), the others exit 1. `--max-minutes 1e308` is a
/// limit no estimate reaches, so it is not an error.
#[test]
fn budget_numeric_flags_name_themselves_for_every_bad_number() {
    let values = [
        ("nan", "NaN"),
        ("inf", "inf"),
        ("0", "0"),
        ("-1", "-1"),
        ("1e-320", "1e-320"),
        ("1e308", "1e308"),
    ];
    for flag in [
        "--fps",
        "--budget-ms",
        "--duration",
        "--settle",
        "--criterion",
        "--max-minutes",
        "--reference-steps",
    ] {
        for (value, shown) in values {
            if flag == "--max-minutes" && value == "1e308" {
                continue;
            }
            let out = fem2d(&["budget", "case-a", flag, value]);
            let e = one_line_error(&out);
            if flag == "--reference-steps" && value != "0" {
                assert_eq!(out.status.code(), Some(2), "{flag} {value}: {e}");
                assert!(e.contains(&format!("'{value}' for '{flag}")), "{e}");
                continue;
            }
            assert_eq!(out.status.code(), Some(1), "{flag} {value}: {e}");
            assert!(
                e.starts_with(&format!("error: {flag} {shown}: ")),
                "{flag} {value}: {e}"
            );
        }
    }
    let e = one_line_error(&fem2d(&["budget", "case-a", "--fps", "1e-320"]));
    assert!(
        e.contains("--fps 1e-320: its frame, 1/fps = inf s, is not a finite number of seconds"),
        "{e}"
    );
}

/// A duration shorter than one frame is refused, not stretched to a frame (at 0.001 frames
/// per second the scene's 2 s would have simulated 1000 s): the message names the flag the
/// user set and both values.
#[test]
fn budget_refuses_a_duration_shorter_than_one_frame() {
    let e = one_line_error(&fem2d(&["budget", "case-a", "--fps", "0.001"]));
    assert!(
        e.contains(
            "--fps 0.001: one frame (1000 s) is longer than the scene's duration (solver.steps x solver.dt = 2 s)"
        ),
        "{e}"
    );
    let e = one_line_error(&fem2d(&["budget", "case-a", "--duration", "0.005"]));
    assert!(
        e.contains("--duration 0.005: shorter than one frame at --fps 90 (0.011111111111111112 s)"),
        "{e}"
    );
    let e = one_line_error(&fem2d(&[
        "budget",
        "case-a",
        "--fps",
        "60",
        "--duration",
        "1e-3",
    ]));
    assert!(
        e.contains("--duration 0.001: shorter than one frame at --fps 60"),
        "{e}"
    );
}

/// A framework or an energy listed twice would give two rows both ranked first: refused,
/// naming the flag as written and the repeated name.
#[test]
fn budget_refuses_a_name_listed_twice() {
    let e = one_line_error(&fem2d(&[
        "budget",
        "case-a",
        "--frameworks",
        "implicit,implicit",
    ]));
    assert!(
        e.contains("--frameworks implicit,implicit: implicit is listed twice"),
        "{e}"
    );
    let e = one_line_error(&fem2d(&[
        "budget",
        "case-a",
        "--energies",
        "stvk,linear,stvk",
    ]));
    assert!(
        e.contains("--energies stvk,linear,stvk: stvk is listed twice"),
        "{e}"
    );
}

/// The time bound (`--max-minutes`, default 10): a run of hours is refused before anything
/// runs, from the step counts alone, so the refusal does not depend on this machine's
/// speed: `--haptics --duration 100` (100000 frames) at the default, and a short run under a
/// tiny limit. Nothing runs: no progress line precedes the error, and `--out` is not
/// written.
#[test]
fn budget_time_bound_refuses_before_anything_runs() {
    let e = one_line_error(&fem2d(&[
        "budget",
        "case-a",
        "--haptics",
        "--duration",
        "100",
    ]));
    assert!(
        e.starts_with("error: --max-minutes 10: the budget would take about ")
            && e.contains("estimated before running, from the step counts: 5 energies x (a reference of 10000000 steps")
            && e.contains("shorten --duration, choose fewer --frameworks or --energies, or raise --max-minutes"),
        "{e}"
    );
    let dir = scratch("budget-bound");
    let out = dir.join("b");
    let e = one_line_error(&fem2d(&[
        "budget",
        "case-a",
        "--energies",
        "corotational",
        "--duration",
        "0.5",
        "--max-minutes",
        "0.001",
        "--out",
        arg(&out),
    ]));
    assert!(e.starts_with("error: --max-minutes 0.001: "), "{e}");
    assert!(!out.join("budget.md").exists());
}

/// The budget finishes and writes on a body at rest (every error exactly 0: the table says
/// 0, the Pareto chart draws it at a floor its legend names), at the smallest Young's modulus
/// a scene allows, and with every rung stopped over the cost cap: no table carries a NaN or
/// an infinity.
#[test]
fn budget_writes_finite_tables_at_rest_at_the_smallest_modulus_and_over_the_cap() {
    let dir = scratch("budget-finite");
    let cases: [(&str, &[&str]); 3] = [
        (
            "rest",
            &[
                "--set",
                "gravity=[0,0]",
                "--energies",
                "neo-hookean",
                "--frameworks",
                "explicit,implicit",
            ],
        ),
        (
            "soft",
            &[
                "--set",
                "material.youngs_modulus=1e-290",
                "--energies",
                "neo-hookean",
                "--frameworks",
                "explicit,implicit",
            ],
        ),
        (
            "cap",
            &[
                "--energies",
                "corotational",
                "--frameworks",
                "pbd,pd",
                "--budget-ms",
                "1e-4",
            ],
        ),
    ];
    for (name, extra) in cases {
        let out = dir.join(name);
        let mut args = vec!["budget", "case-a", "--duration", "0.2", "--out", arg(&out)];
        args.extend_from_slice(extra);
        ok(&fem2d(&args));
        for file in ["budget.csv", "budget.md", "budget.json"] {
            let text = std::fs::read_to_string(out.join(file)).unwrap();
            for bad in ["NaN", "nan,", ",inf", "| inf"] {
                assert!(!text.contains(bad), "{name} {file} holds {bad}:\n{text}");
            }
        }
        let csv = std::fs::read_to_string(out.join("budget.csv")).unwrap();
        assert!(csv.lines().next().unwrap().ends_with(",status"), "{csv}");
        if name == "rest" {
            assert!(out.join("pareto-neo-hookean.png").is_file(), "{name}");
            let svg = std::fs::read_to_string(out.join("pareto-neo-hookean.svg")).unwrap();
            assert!(svg.contains("error 0, drawn at 1e-12"), "{svg}");
            let md = std::fs::read_to_string(out.join("budget.md")).unwrap();
            assert!(md.contains("is the most accurate, 0 m,"), "{md}");
        }
        if name == "cap" {
            assert!(
                csv.lines()
                    .skip(1)
                    .all(|l| l.contains(",true,,,") && l.ends_with("times the budget over the run")),
                "{csv}"
            );
        }
    }
}

/// A reader that goes away before the output is printed (`fem2d budget ... | true`): no panic
/// message, exit status 141 (as if killed by SIGPIPE), and nothing else on stderr but the
/// progress lines.
#[test]
fn a_reader_that_closes_the_pipe_ends_the_command_quietly() {
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_fem2d"))
        .args([
            "budget",
            "case-a",
            "--energies",
            "corotational",
            "--frameworks",
            "pd",
            "--duration",
            "0.05",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Close the reading end before anything is printed.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(141), "{stderr}");
    assert!(
        stderr.lines().all(|l| l.starts_with("budget: ")),
        "{stderr}"
    );
}

/// `fem2d budget` on a 3D scene: the built-in `case-a-3d` (coarsened), its outputs, the row of
/// a framework without a 3D path, and a bad flag refused in one line as in 2D.
#[test]
fn budget_runs_a_3d_scene_and_names_what_has_no_3d_path() {
    let dir = scratch("budget-3d");
    let out = dir.join("b");
    let stdout = ok(&fem2d(&[
        "budget",
        "case-a-3d",
        "--set",
        "mesh.nx=8",
        "--set",
        "mesh.ny=2",
        "--set",
        "mesh.nz=2",
        "--energies",
        "neo-hookean",
        "--frameworks",
        "explicit,xpbd,linear-implicit",
        "--duration",
        "0.1",
        "--reference-steps",
        "10",
        "--out",
        arg(&out),
        "--trajectories",
    ]));
    assert!(
        stdout.contains("# Frame budget: case-a-3d at 90 Hz"),
        "{stdout}"
    );
    assert!(
        stdout.contains("cannot run: linear-implicit has no 3D path yet"),
        "{stdout}"
    );
    for f in [
        "budget.md",
        "budget.csv",
        "budget.json",
        "pareto-neo-hookean.png",
        "trajectories.json",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let traj = std::fs::read_to_string(out.join("trajectories.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&traj).unwrap();
    // 192 tetrahedra (8 x 2 x 2 cubes of 6) of four vertices, points of three coordinates.
    assert_eq!(v["layout"]["cells"].as_array().unwrap().len(), 192);
    assert_eq!(v["layout"]["cells"][0].as_array().unwrap().len(), 4);
    assert_eq!(v["layout"]["rest"][0].as_array().unwrap().len(), 3);
    let e = one_line_error(&fem2d(&["budget", "case-a-3d", "--fps", "0"]));
    assert!(e.contains("--fps 0: must be a finite number > 0"), "{e}");
}

/// `fem2d scaling --quick`: the table, its growth exponents, and the chart and data files.
#[test]
fn scaling_writes_the_table_and_the_log_log_chart() {
    let dir = scratch("scaling");
    let out = dir.join("s");
    let stdout = ok(&fem2d(&["scaling", "--quick", "--out", arg(&out)]));
    for row in [
        "| 2D | implicit, velocity 1e-2 m/s | 20 x 4 | 160 | 210 |",
        "| 3D | vbd, 10 iterations | 20 x 4 x 4 | 1920 | 1575 |",
        "Growth exponent",
    ] {
        assert!(stdout.contains(row), "{row}\n{stdout}");
    }
    for f in ["scaling.md", "scaling.json", "scaling.svg", "scaling.png"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("scaling.json")).unwrap()).unwrap();
    // 3 solvers x (3 sizes in 2D + 2 in 3D), every one with a positive cost.
    let points = v["points"].as_array().unwrap();
    assert_eq!(points.len(), 15);
    assert!(
        points
            .iter()
            .all(|p| p["ms_per_frame"].as_f64().unwrap() > 0.0 && p["failure"].is_null())
    );
    let e = one_line_error(&fem2d(&["scaling", "--budget-ms", "0"]));
    assert!(
        e.contains("--budget-ms 0: must be a finite number > 0"),
        "{e}"
    );
}
