//! Scenes run with nothing of the host: no file system (mesh bytes from memory), no clock
//! (timings read zero), frames handed to a sink. The numbers must not depend on any of it.

use std::collections::BTreeMap;

use fem_scene::SceneError;
use fem_scene::build::MeshSource;
use fem_scene::cases::load_case;
use fem_scene::run::{Clock, Frame, FrameSink, Progress, RunEnv, run};
use fem_scene::scene::parse_scene;

/// Mesh files in memory, by name.
struct Memory(BTreeMap<String, Vec<u8>>);

impl MeshSource for Memory {
    fn read(&self, name: &str) -> Result<Vec<u8>, String> {
        self.0
            .get(name)
            .cloned()
            .ok_or_else(|| format!("no file named {name}"))
    }
}

/// Counts frames and keeps the last positions.
#[derive(Default)]
struct Counter {
    frames: Vec<(u64, f64)>,
    last_positions: Vec<[f64; 2]>,
    triangles: usize,
}

impl FrameSink for Counter {
    fn frame(&mut self, f: &Frame<'_>) -> Result<(), SceneError> {
        self.frames.push((f.step, f.time));
        self.last_positions = f.positions.iter().map(|p| [p.x, p.y]).collect();
        self.triangles = f.mesh.n_triangles();
        assert_eq!(f.von_mises.len(), f.mesh.n_triangles());
        assert_eq!(f.stress.len(), f.mesh.n_triangles());
        Ok(())
    }
}

/// A sink that fails at its third frame.
struct Failing(usize);

impl FrameSink for Failing {
    fn frame(&mut self, _: &Frame<'_>) -> Result<(), SceneError> {
        self.0 += 1;
        if self.0 == 3 {
            Err(SceneError::Io("sink full".into()))
        } else {
            Ok(())
        }
    }
}

/// Records what a progress report is told.
#[derive(Default)]
struct Steps {
    total: Option<u64>,
    done: Vec<u64>,
    finished: bool,
}

impl Progress for Steps {
    fn start(&mut self, total: u64) {
        self.total = Some(total);
    }
    fn advance(&mut self, done: u64) {
        self.done.push(done);
    }
    fn finish(&mut self) {
        self.finished = true;
    }
}

/// A clock that advances one second per reading.
struct Ticking(std::cell::Cell<f64>);

impl Clock for Ticking {
    fn seconds(&self) -> f64 {
        let t = self.0.get();
        self.0.set(t + 1.0);
        t
    }
}

#[test]
fn a_run_needs_no_clock_no_files_and_hands_every_frame_to_the_sinks() {
    let scene = load_case("case-a", &["solver.steps=100".into()]).unwrap();
    let mut sink = Counter::default();
    let mut steps = Steps::default();
    let result = {
        let mut env = RunEnv {
            progress: Some(&mut steps),
            sinks: vec![&mut sink],
            ..RunEnv::default()
        };
        run(&scene, &mut env).unwrap()
    };
    let s = &result.summary;
    assert!(!s.blew_up);
    assert_eq!(s.steps_completed, 100);
    // No clock: every timing is zero, and so are the rates derived from them.
    assert_eq!(
        (s.wall_seconds, s.step_seconds, s.element_steps_per_second),
        (0.0, 0.0, 0.0)
    );
    // Frames at step 0 and every 10 steps, the same in the sink and in the result.
    assert_eq!(sink.frames, result.frame_times);
    assert_eq!(sink.frames.len(), 11);
    assert_eq!(sink.frames.last().unwrap().0, 100);
    assert_eq!(sink.last_positions, result.final_positions);
    assert_eq!(sink.triangles, s.triangles);
    assert_eq!(steps.total, Some(100));
    assert_eq!(steps.done.last(), Some(&100));
    assert!(steps.finished);
    // After 0.1 s the tip has fallen about 1/2 g t^2 = 49 mm (Table 1, frame 10).
    let tip = result.probe("tip").unwrap().last().unwrap();
    assert!((tip[1] + 0.049).abs() < 0.003, "{tip:?}");
}

#[test]
fn timings_come_from_the_callers_clock() {
    let scene = load_case("case-a", &["solver.steps=20".into()]).unwrap();
    let clock = Ticking(std::cell::Cell::new(0.0));
    let mut env = RunEnv {
        clock: &clock,
        ..RunEnv::default()
    };
    let s = run(&scene, &mut env).unwrap().summary;
    // Two chunks of 10 steps, each timed by two readings one second apart.
    assert_eq!(s.step_seconds, 2.0);
    assert!(s.wall_seconds > s.step_seconds);
    assert_eq!(s.element_steps_per_second, 160.0 * 20.0 / 2.0);
}

#[test]
fn the_same_run_with_or_without_sinks_and_progress_gives_the_same_numbers() {
    let scene = load_case("case-c", &["solver.steps=50".into()]).unwrap();
    let bare = run(&scene, &mut RunEnv::default()).unwrap();
    let mut sink = Counter::default();
    let mut steps = Steps::default();
    let mut env = RunEnv {
        progress: Some(&mut steps),
        sinks: vec![&mut sink],
        snapshot_every: Some(2),
        ..RunEnv::default()
    };
    let full = run(&scene, &mut env).unwrap();
    assert_eq!(bare.final_positions, full.final_positions);
    assert_eq!(bare.probe_series, full.probe_series);
    assert_eq!(bare.summary.max_von_mises, full.summary.max_von_mises);
    // Every second frame is kept, and the last.
    assert_eq!(full.snapshots.len(), 4);
    assert_eq!(full.snapshots.last().unwrap().step, 50);
    assert!(bare.snapshots.is_empty());
}

const SQUARE: &str = r#"
name = "square"
[mesh]
kind = "file"
path = "meshes/square.json"
[material]
youngs_modulus = 1000.0
poisson_ratio = 0.3
total_mass = 1.0
[solver]
dt = 1e-3
steps = 20
[[pinned]]
min = [0.0, 1.0]
max = [1.0, 1.0]
"#;

const SQUARE_MESH: &str = r#"{"vertices": [[0, 0], [1, 0], [1, 1], [0, 1]],
 "triangles": [[0, 1, 2], [0, 2, 3]]}"#;

#[test]
fn mesh_files_come_from_the_callers_source_by_name() {
    let scene = parse_scene(SQUARE, "square.toml", std::path::Path::new("."), &[]).unwrap();
    let files = Memory(BTreeMap::from([(
        "meshes/square.json".to_owned(),
        SQUARE_MESH.as_bytes().to_vec(),
    )]));
    let mut env = RunEnv {
        files: &files,
        ..RunEnv::default()
    };
    let result = run(&scene, &mut env).unwrap();
    assert_eq!((result.summary.vertices, result.summary.triangles), (4, 2));
    assert!(!result.summary.blew_up);

    // Without the file: one line naming the scene, the field and the name.
    let e = run(&scene, &mut RunEnv::default()).unwrap_err().to_string();
    assert!(!e.contains('\n'), "{e}");
    assert!(
        e.starts_with("square.toml: mesh.path = meshes/square.json: "),
        "{e}"
    );
}

#[test]
fn a_sink_error_ends_the_run_with_it() {
    let scene = load_case("case-a", &["solver.steps=100".into()]).unwrap();
    let mut failing = Failing(0);
    let mut env = RunEnv {
        sinks: vec![&mut failing],
        ..RunEnv::default()
    };
    let e = run(&scene, &mut env).unwrap_err();
    assert_eq!(e, SceneError::Io("sink full".into()));
}
