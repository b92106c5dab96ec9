//! Output directories written as a unit: two runs into one `--out` at once, runs interrupted
//! (SIGINT) and killed (SIGKILL) at many points, a directory fem2d did not write, locks of live
//! and dead processes. After each, `--out` holds one whole run or the previous one, and no
//! leftover survives the next run.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{arg, json, read, scratch};

/// `fem2d run case-a` with `energy` and `steps` on a 4000-triangle beam into `out`, started.
fn start(out: &Path, energy: &str, steps: u32) -> Child {
    Command::new(env!("CARGO_BIN_EXE_fem2d"))
        .args(["run", "case-a", "--energy", energy, "--steps"])
        .arg(steps.to_string())
        .args([
            "--set",
            "mesh.nx=100",
            "--set",
            "mesh.ny=20",
            "--dt",
            "2e-4",
        ])
        .args(["--threads", "1", "-q", "--out", arg(out)])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("fem2d starts")
}

/// What a complete run directory says about itself, after checking that its files belong to
/// one run: the energy and the step count of `summary.json`, `scene.toml`, `probes.csv` and
/// `frames.jsonl` agree.
fn whole_run(dir: &Path) -> (String, u64) {
    let summary = json(&dir.join("summary.json"));
    let energy = summary["energy"].as_str().unwrap().to_owned();
    let steps = summary["steps_completed"].as_u64().unwrap();
    let scene = read(&dir.join("scene.toml"));
    assert!(
        scene.contains(&format!("energy = \"{energy}\"")),
        "{}: scene.toml of another run:\n{scene}",
        dir.display()
    );
    assert!(scene.contains(&format!("steps = {steps}")), "{scene}");
    let probes = read(&dir.join("probes.csv"));
    let frames = read(&dir.join("frames.jsonl"));
    assert_eq!(probes.lines().count() - 1, frames.lines().count());
    let last: serde_json::Value = serde_json::from_str(frames.lines().last().unwrap()).unwrap();
    assert_eq!(
        last["step"].as_u64(),
        Some(steps),
        "frames.jsonl of another run"
    );
    (energy, steps)
}

/// The names beside `dir` that belong to it: only `dir` itself once nothing is being written.
fn beside(dir: &Path) -> Vec<String> {
    let name = dir.file_name().unwrap().to_string_lossy().into_owned();
    let mut v: Vec<String> = std::fs::read_dir(dir.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(&name))
        .collect();
    v.sort();
    v
}

#[test]
fn two_runs_into_one_out_at_once_never_mix_their_files() {
    let root = scratch("concurrent");
    let out = root.join("run");
    let mut refused = 0;
    for round in 0..5 {
        let mut a = start(&out, "stvk", 1500);
        let mut b = start(&out, "neo-hookean", 1400);
        let (ra, rb) = (a.wait().unwrap(), b.wait().unwrap());
        let err_b = std::io::read_to_string(b.stderr.take().unwrap()).unwrap();
        let err_a = std::io::read_to_string(a.stderr.take().unwrap()).unwrap();
        // Either one was refused, naming the other, or they did not overlap.
        for (ok, err) in [(ra.success(), &err_a), (rb.success(), &err_b)] {
            if !ok {
                refused += 1;
                assert!(
                    err.contains("another fem2d process (pid"),
                    "round {round}: {err}"
                );
                assert_eq!(err.lines().count(), 1, "{err}");
            }
        }
        assert!(
            ra.success() || rb.success(),
            "round {round}: {err_a} {err_b}"
        );
        whole_run(&out);
        assert_eq!(beside(&out), ["run"], "round {round}");
    }
    // The runs did overlap (started together, each about 0.1 s long).
    assert!(refused > 0, "no round overlapped");
}

/// A run is interrupted (SIGINT) at 50 points spread over its life, from before the lock to
/// after the commit: `--out` always holds one whole run (the previous one, or the new one when
/// the signal came after the commit), the message says so, and nothing is left beside it.
#[test]
fn an_interrupted_run_leaves_the_previous_run_or_the_new_one_whole() {
    let root = scratch("interrupted");
    let out = root.join("run");
    let first = start(&out, "stvk", 300).wait_with_output().unwrap();
    assert!(first.status.success());
    assert_eq!(whole_run(&out), ("stvk".into(), 300));
    // How long a full run takes, to spread the signals over it.
    let t = Instant::now();
    assert!(start(&out, "neo-hookean", 1200).wait().unwrap().success());
    let full = t.elapsed();
    let mut seen_new = 0;
    let mut seen_old = 0;
    let mut state = 0x2545_f491_u64;
    for k in 0..50 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let delay = full.mul_f64((state >> 11) as f64 / (1u64 << 53) as f64 * 1.1);
        // A step count of its own per point, so "previous" and "new" are told apart.
        let energy = if k % 2 == 0 { "corotational" } else { "linear" };
        let steps = 1000 + k;
        let before = whole_run(&out);
        let mut child = start(&out, energy, steps);
        std::thread::sleep(delay);
        let _ = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status();
        let status = child.wait().unwrap();
        let err = std::io::read_to_string(child.stderr.take().unwrap()).unwrap();
        let now = whole_run(&out);
        if now == before {
            seen_old += 1;
            // Exit 130 with the message, or killed by the signal before the handler was set
            // up (the first milliseconds of the process, before any file is touched).
            let early = std::os::unix::process::ExitStatusExt::signal(&status) == Some(2);
            assert!(
                early || (status.code() == Some(130) && err.starts_with("error: interrupted")),
                "point {k} ({delay:?}): {status} {err} before {before:?} now {now:?}"
            );
        } else {
            seen_new += 1;
            assert_eq!(now, (energy.to_owned(), u64::from(steps)), "point {k}");
        }
        assert_eq!(beside(&out), ["run"], "point {k} ({delay:?}): leftovers");
    }
    // The points covered both outcomes.
    assert!(
        seen_old > 5 && seen_new > 0,
        "old {seen_old}, new {seen_new}"
    );
}

/// A run killed outright (no chance to clean up) leaves at most a lock and a partial directory
/// beside `--out`, which still holds a whole run or nothing; the next run removes the leftovers
/// (and puts the previous run back if the kill fell inside a commit).
#[test]
fn a_killed_run_leaves_leftovers_that_the_next_run_removes() {
    let root = scratch("killed");
    let out = root.join("run");
    assert!(start(&out, "stvk", 300).wait().unwrap().success());
    for k in 0..10u32 {
        let mut child = start(&out, "neo-hookean", 1000);
        std::thread::sleep(Duration::from_millis(20 + 37 * u64::from(k)));
        let _ = child.kill();
        let _ = child.wait();
        if out.join("summary.json").exists() {
            whole_run(&out);
        }
        assert!(
            start(&out, "linear", 200).wait().unwrap().success(),
            "after kill {k}"
        );
        assert_eq!(whole_run(&out), ("linear".into(), 200));
        assert_eq!(beside(&out), ["run"], "after kill {k}");
    }
}

#[test]
fn out_is_never_a_directory_fem2d_did_not_write_and_live_locks_are_respected() {
    let root = scratch("foreign");
    let out = root.join("mine");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "keep me").unwrap();
    let r = start(&out, "stvk", 10).wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1));
    assert!(
        err.contains("holds files fem2d did not write (`notes.txt`)"),
        "{err}"
    );
    assert_eq!(read(&out.join("notes.txt")), "keep me");
    assert_eq!(beside(&out), ["mine"]);

    // A lock held by a live process (this test) is respected; a dead one is taken over.
    let out = root.join("locked");
    let lock = root.join(".locked.lock");
    std::fs::write(&lock, format!("{}\n", std::process::id())).unwrap();
    let r = start(&out, "stvk", 10).wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains(&format!(
            "another fem2d process (pid {})",
            std::process::id()
        )),
        "{err}"
    );
    assert!(!out.exists());
    std::fs::write(&lock, "4194305\n").unwrap(); // above Linux's largest pid
    assert!(start(&out, "stvk", 10).wait().unwrap().success());
    assert_eq!(whole_run(&out), ("stvk".into(), 10));
    assert!(!lock.exists());
}

/// Starts `fem2d ARGS` with stdout discarded and stderr kept.
fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_fem2d"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("fem2d starts")
}

/// `points` SIGINTs at pseudo-random times over one run of `args(k)` (`full` long): each ends
/// the process with exit 130 and "error: interrupted", or lets it finish, and `check` then
/// sees the directory `dir` of the outputs.
fn interrupt_many_times(
    points: u32,
    full: Duration,
    args: impl Fn(u32) -> Vec<String>,
    check: impl Fn(u32, &str),
) {
    let mut state = 0x9e37_79b9_u64;
    for k in 0..points {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let delay = full.mul_f64((state >> 11) as f64 / (1u64 << 53) as f64 * 1.1);
        let a = args(k);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let mut child = spawn(&a);
        std::thread::sleep(delay);
        let _ = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status();
        let status = child.wait().unwrap();
        let err = std::io::read_to_string(child.stderr.take().unwrap()).unwrap();
        let early = std::os::unix::process::ExitStatusExt::signal(&status) == Some(2);
        assert!(
            early || status.success() || status.code() == Some(130),
            "point {k} ({delay:?}): {status} {err}"
        );
        if status.code() == Some(130) {
            assert!(err.contains("error: interrupted"), "{err}");
        }
        check(k, &format!("point {k} ({delay:?}), {status}"));
    }
}

/// The names in `dir`, sorted (hidden ones included).
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// `fem2d mesh` with three outputs interrupted at 20 points: the three files always describe
/// one mesh (the previous one or the new one) and no temporary file is left.
#[test]
fn an_interrupted_mesh_leaves_its_three_outputs_of_one_mesh_and_no_temporary_file() {
    let dir = scratch("interrupted-mesh");
    let args = |k: u32| -> Vec<String> {
        // Alternating bounds on the area, so consecutive meshes differ in size.
        let area = if k.is_multiple_of(2) {
            "1e-6"
        } else {
            "1.3e-6"
        };
        [
            "mesh",
            "--builtin-body",
            "--max-steiner",
            "1000000",
            "--max-area",
            area,
            "-o",
            arg(&dir.join("m.json")),
            "--msh",
            arg(&dir.join("m.msh")),
            "--vtk",
            arg(&dir.join("m.vtk")),
        ]
        .map(String::from)
        .to_vec()
    };
    let one_mesh = |context: &str| {
        assert_eq!(names(&dir), ["m.json", "m.msh", "m.vtk"], "{context}");
        let vertices = json(&dir.join("m.json"))["vertices"]
            .as_array()
            .unwrap()
            .len();
        let msh = read(&dir.join("m.msh"));
        let nodes: usize = msh
            .lines()
            .skip_while(|l| *l != "$Nodes")
            .nth(1)
            .unwrap()
            .parse()
            .unwrap();
        let vtk = read(&dir.join("m.vtk"));
        let points: usize = vtk
            .lines()
            .find_map(|l| l.strip_prefix("POINTS "))
            .and_then(|l| l.split_whitespace().next())
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!((nodes, points), (vertices, vertices), "{context}");
    };
    let t = Instant::now();
    let a = args(1);
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    assert!(spawn(&a).wait().unwrap().success());
    let full = t.elapsed();
    one_mesh("first run");
    interrupt_many_times(20, full, args, |_, context| one_mesh(context));
}

/// `fem2d figures` and `fem2d report` interrupted at 5 and 3 points (each run takes seconds
/// in a test build; the run test above covers the report's kind of output directory 50
/// times): the figures directory holds the whole set (its other files untouched) and the
/// report directory a whole report, with nothing left beside or inside them.
#[test]
fn interrupted_figures_and_report_leave_whole_outputs_and_nothing_else() {
    let root = scratch("interrupted-figures");
    let figs = root.join("figures");
    std::fs::create_dir_all(&figs).unwrap();
    std::fs::write(figs.join("notes.txt"), "keep me").unwrap();
    let t = Instant::now();
    let figures_args = |_: u32| -> Vec<String> {
        ["figures", "--threads", "1", "--out", arg(&figs)]
            .map(String::from)
            .to_vec()
    };
    let a = figures_args(0);
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    assert!(spawn(&a).wait().unwrap().success());
    let full = t.elapsed();
    let all = names(&figs);
    assert!(
        all.len() > 10 && all.contains(&"notes.txt".to_owned()),
        "{all:?}"
    );
    interrupt_many_times(5, full, figures_args, |_, context| {
        assert_eq!(names(&figs), all, "{context}");
        assert_eq!(names(&root), ["figures"], "{context}");
    });
    assert_eq!(read(&figs.join("notes.txt")), "keep me");

    let report = root.join("report");
    let report_args = |_: u32| -> Vec<String> {
        [
            "report",
            "--threads",
            "1",
            "--no-budget",
            "--out",
            arg(&report),
        ]
        .map(String::from)
        .to_vec()
    };
    let t = Instant::now();
    let a = report_args(0);
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    assert!(spawn(&a).wait().unwrap().success());
    let full = t.elapsed();
    let all = names(&report);
    assert!(all.contains(&"index.html".to_owned()), "{all:?}");
    interrupt_many_times(3, full, report_args, |_, context| {
        assert_eq!(names(&report), all, "{context}");
        assert!(
            read(&report.join("index.html"))
                .trim_end()
                .ends_with("</html>")
        );
        assert_eq!(names(&root), ["figures", "report"], "{context}");
    });
}
