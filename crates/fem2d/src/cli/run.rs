//! `fem2d run`: one scene (a built-in case or a scene file) under one energy and solver; writes
//! `summary.json`, `probes.csv`, `frames.jsonl`, `mesh.json` and `scene.toml` into `--out`, and
//! on request `final.png`, `animation.gif` and VTK files (`vtk/run.pvd`).

use std::path::PathBuf;

use clap::Args;
use fem_cases::files::load_any;
use fem_cases::outdir::OutDir;
use fem_cases::pictures::{
    FieldKind, FramePicture, GifOptions, overlay_pressure, shared_range, style, time_label,
    write_gif,
};
use fem_cases::run::{RunOptions, run_scene_with};
use fem_scene::drag::DragTrajectory;
use fem_scene::run::Progress;
use fem_scene::solid::{AnyScene, LoadedScene3};
use fem_solvers::Clock;

/// Options shared by every command that loads a scene.
#[derive(Debug, Args, Clone)]
pub struct SceneArgs {
    /// A built-in case (case-a, case-b, case-c, case-d, lower-leg) or a scene file (.toml).
    pub scene: String,
    /// Override a scene value: the key is its path in the scene file
    /// (`--set material.youngs_modulus=2000`, `--set obstacles.0.mass=50`). Repeatable; applied
    /// after --energy, --solver, --dt and --steps.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

/// Flags of `fem2d run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Energy: stvk, corotational, neo-hookean, stable-neo-hookean, linear (default: the scene's).
    #[arg(long)]
    pub energy: Option<String>,
    /// Solver: explicit, pbd, xpbd, implicit, static, vbd, pd, quasi-newton, linear-implicit
    /// (default: the scene's). `static` solves for
    /// equilibrium in `solver.load_steps` load increments (dt and steps do not apply); see
    /// docs/solvers.md.
    #[arg(long)]
    pub solver: Option<String>,
    /// Time step, s (default: the scene's). A negative value is read as a number, so that
    /// `--dt -1` is rejected by the scene's validation with a one-line error.
    #[arg(long, allow_negative_numbers = true)]
    pub dt: Option<f64>,
    /// Number of steps (default: the scene's).
    #[arg(long)]
    pub steps: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// No progress bar.
    #[arg(long, short = 'q')]
    pub quiet: bool,
    /// Also write `final.png`: the last frame coloured by --field.
    #[arg(long)]
    pub png: bool,
    /// Also write `animation.gif`: the recorded frames (every --gif-every-th) coloured by
    /// --field, on one colour scale and one window for the whole run.
    #[arg(long)]
    pub gif: bool,
    /// Put every N-th recorded frame in the GIF (default: as many as keep it under 120 frames;
    /// frames are recorded every `output.frame_every` steps).
    #[arg(long, value_name = "N")]
    pub gif_every: Option<usize>,
    /// Delay between GIF frames, milliseconds (rounded to hundredths of a second).
    #[arg(long, value_name = "MS", default_value_t = 50)]
    pub gif_delay_ms: u32,
    /// Field of --png and --gif: von-mises (kPa, per element), displacement (mm, per vertex),
    /// det-f (per element).
    #[arg(long, default_value = "von-mises")]
    pub field: String,
    /// Draw the triangles' edges over the colours in --png and --gif.
    #[arg(long)]
    pub wireframe: bool,
    /// Also write the recorded frames as VTK for ParaView: `vtk/run.pvd` and one
    /// `vtk/run_NNNNNN.vtu` per frame (displacement and velocity per vertex, von Mises and
    /// det F per element).
    #[arg(long)]
    pub vtk: bool,
    /// Replay a recorded drag (the JSON the interactive app saves: grab, move and release at
    /// simulated times; docs/interactive.md) into the run.
    #[arg(long, value_name = "FILE")]
    pub drag: Option<PathBuf>,
    /// Von Mises stress threshold, kPa: each material region reports the fraction of its area
    /// above it (summary `regions`, `regions.csv`). Default: the scene's
    /// `output.stress_threshold` (32 kPa unless set).
    #[arg(long, value_name = "KPA", allow_negative_numbers = true)]
    pub stress_threshold: Option<f64>,
}

/// The overrides of the common flags, then the user's `--set`s.
pub fn overrides(
    energy: Option<&str>,
    solver: Option<&str>,
    dt: Option<f64>,
    steps: Option<u64>,
    set: &[String],
) -> Vec<String> {
    let mut o = Vec::new();
    if let Some(e) = energy {
        o.push(format!("energy=\"{e}\""));
    }
    if let Some(s) = solver {
        o.push(format!("solver.kind=\"{s}\""));
    }
    if let Some(dt) = dt {
        o.push(format!("solver.dt={dt:e}"));
    }
    if let Some(n) = steps {
        o.push(format!("solver.steps={n}"));
    }
    o.extend(set.iter().cloned());
    o
}

/// `--dt` must be a finite number (a finite value that is not > 0 reaches the scene's
/// validation as `solver.dt`, which a later `--set solver.dt` may still replace): a NaN or an
/// infinity would otherwise reach the scene as a string.
pub fn check_dt(dt: Option<f64>) -> Result<(), String> {
    match dt {
        Some(dt) if !dt.is_finite() => Err(format!("--dt {dt}: must be a finite number > 0 (s)")),
        _ => Ok(()),
    }
}

/// Runs `fem2d run`.
pub fn run(args: &RunArgs) -> Result<(), String> {
    check_dt(args.dt)?;
    if let Some(kpa) = args.stress_threshold
        && !(kpa.is_finite() && (0.0..=1e305).contains(&kpa))
    {
        return Err(format!(
            "--stress-threshold {}: must be a finite number >= 0 (kPa), at most 1e305",
            fem_core::math::readable(kpa)
        ));
    }
    let mut overrides = overrides(
        args.energy.as_deref(),
        args.solver.as_deref(),
        args.dt,
        args.steps,
        &args.scene.set,
    );
    if let Some(kpa) = args.stress_threshold {
        // Before the user's --set, which may still override it.
        let at = overrides.len() - args.scene.set.len();
        overrides.insert(at, format!("output.stress_threshold={:e}", kpa * 1e3));
    }
    let field: FieldKind = args.field.parse().map_err(|e| format!("--field: {e}"))?;
    if args.gif_every == Some(0) {
        return Err("--gif-every 0: must be >= 1".into());
    }
    let delay = (args.gif_delay_ms as f64 / 10.0).round();
    if args.gif && !(1.0..=65535.0).contains(&delay) {
        return Err(format!(
            "--gif-delay-ms {}: must be between 10 and 655350",
            args.gif_delay_ms
        ));
    }
    let scene = match load_any(&args.scene.scene, &overrides).map_err(|e| e.to_string())? {
        AnyScene::Two(scene) => *scene,
        AnyScene::Three(scene) => return run_3d(args, &scene),
    };
    let drag = match &args.drag {
        None => None,
        Some(path) => {
            let name = path.display().to_string();
            let text = read_drag_file(path, &name)?;
            Some(DragTrajectory::parse(&text, &name).map_err(|e| e.to_string())?)
        }
    };
    let s = &scene.scene;
    let recorded = s.planned_frames();
    let gif_every = args
        .gif_every
        .unwrap_or_else(|| recorded.div_ceil(120).max(1) as usize);
    // Every GIF frame is kept in memory until the run ends, then drawn and encoded.
    let gif_frames = (recorded as usize).div_ceil(gif_every);
    if args.gif && gif_frames > MAX_GIF_FRAMES {
        return Err(format!(
            "--gif-every {gif_every}: the animation would have {gif_frames} frames; at most {MAX_GIF_FRAMES} (raise --gif-every)"
        ));
    }
    let snapshot_every = if args.gif {
        Some(gif_every)
    } else if args.png {
        Some(usize::MAX)
    } else {
        None
    };
    // Everything goes into a staging directory that replaces --out only once complete.
    let out = OutDir::begin(&args.out).map_err(|e| e.to_string())?;
    let dir = out.path().to_path_buf();
    let mut bar = ProgressBar::default();
    let result = run_scene_with(
        &scene,
        &RunOptions {
            out_dir: Some(dir.clone()),
            threads: args.threads,
            snapshot_every,
            vtk: args.vtk,
            drag,
        },
        if args.quiet { None } else { Some(&mut bar) },
    )
    .map_err(|e| e.to_string())?;
    let mut pictures = Vec::new();
    let title = format!(
        "{}: {} / {}",
        result.summary.scene, result.summary.energy, result.summary.solver
    );
    let drawable = !result.summary.blew_up;
    let ground = scene.scene.ground.as_ref().and_then(|g| g.height);
    if args.png && drawable {
        let last = result
            .snapshots
            .last()
            .ok_or("the run recorded no frame to draw")?;
        let picture = FramePicture::new(&result, last, field, "")
            .with_ground(ground)
            .with_contact_pressure();
        let mut st = style(field, &title, 720, 400);
        st.range = shared_range(&[&picture], field);
        st.time_label = Some(time_label(&result, last.time));
        st.wireframe = args.wireframe;
        let path = dir.join("final.png");
        let mut rendered = fem_render::frame::render(&[picture.view()], &st)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        overlay_pressure(&mut rendered, &[&picture], None).map_err(|e| e.to_string())?;
        rendered
            .image
            .write_png(&path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        pictures.push("final.png".to_owned());
    }
    if args.gif && drawable {
        let frames = write_gif(
            &result,
            &dir.join("animation.gif"),
            &GifOptions {
                field,
                delay_centiseconds: delay as u16,
                title: title.clone(),
                ground,
                wireframe: args.wireframe,
                ..GifOptions::default()
            },
        )
        .map_err(|e| e.to_string())?;
        pictures.push(format!("animation.gif ({frames} frames)"));
    }
    if args.vtk {
        pictures.push(format!("vtk/run.pvd ({} frames)", result.frame_times.len()));
    }
    out.commit().map_err(|e| e.to_string())?;
    let s = &result.summary;
    if let Some(w) = &s.time_step_warning {
        eprintln!("warning: {w}");
    }
    let caps = s.solver.capabilities();
    if caps.clock == Clock::LoadFactor {
        println!(
            "{}: {} / {}, {} triangles, {} load increments in {:.3} s",
            s.scene, s.energy, s.solver, s.triangles, s.steps_completed, s.step_seconds,
        );
    } else {
        println!(
            "{}: {} / {}, {} triangles, {} steps of {:e} s in {:.3} s ({:.3e} element-steps/s, real-time factor {:.2})",
            s.scene,
            s.energy,
            s.solver,
            s.triangles,
            s.steps_completed,
            s.dt,
            s.step_seconds,
            s.element_steps_per_second,
            s.real_time_factor
        );
    }
    if caps.implicit {
        println!(
            "Newton: {} iterations, final residual {}",
            s.newton_iterations,
            s.final_residual
                .map_or_else(|| "-".to_owned(), |r| format!("{r:.3e} N"))
        );
    }
    if let Some(gap) = s.contact_min_gap {
        println!(
            "contact: smallest gap {gap:.3e} m{}, peak contact force {:.4e} N, {} contacts at the end carrying [{:.4e}, {:.4e}] N",
            if gap < 0.0 { " (penetration)" } else { "" },
            s.contact_peak_force,
            s.final_contacts,
            s.final_contact_force[0],
            s.final_contact_force[1]
        );
        let at = s.contact_peak_pressure_at.map_or_else(
            || "-".to_owned(),
            |p| format!("[{}, {}] m", fixed(p[0], 3), fixed(p[1], 3)),
        );
        println!(
            "contact pressure: peak {:.4} kPa (step {}, at {at}), {:.4} kPa at the end over a contact length of {:.4} m, impulse {:.4e} N s",
            s.contact_peak_pressure * 1e-3,
            s.contact_peak_pressure_step,
            s.final_contact_pressure_peak * 1e-3,
            s.final_contact_length,
            s.contact_impulse
        );
    }
    println!(
        "max von Mises {:.4e} Pa (step {}, element {} at [{}, {}] m), min det F {}, inverted elements {}",
        s.max_von_mises,
        s.max_von_mises_step,
        s.max_von_mises_element,
        fixed(s.max_von_mises_at[0], 3),
        fixed(s.max_von_mises_at[1], 3),
        fixed(s.min_det_f, 4),
        s.inverted_elements
    );
    for r in &s.regions {
        println!(
            "region {}: peak von Mises {:.2} kPa (step {}, at [{}, {}] m), mean {:.2} kPa at the end, largest compressive strain {:.4}, {:.2} % of its area above {:.1} kPa at the end (peak {:.2} %)",
            r.name,
            r.peak_von_mises * 1e-3,
            r.peak_von_mises_step,
            fixed(r.peak_von_mises_at[0], 3),
            fixed(r.peak_von_mises_at[1], 3),
            r.last.mean_von_mises * 1e-3,
            r.max_compressive_strain,
            100.0 * r.last.area_above_threshold,
            s.stress_threshold * 1e-3,
            100.0 * r.peak_area_above_threshold,
        );
    }
    for p in &s.probes {
        println!(
            "probe {}: vertex {} at [{}, {}], final displacement [{}, {}] m",
            p.name,
            p.vertex,
            p.rest[0],
            p.rest[1],
            fixed(p.final_displacement[0], 6),
            fixed(p.final_displacement[1], 6)
        );
    }
    println!(
        "wrote summary.json, probes.csv, regions.csv, mesh.json, stress.json, scene.toml{}{} in {}",
        if scene.scene.output.frames {
            ", frames.jsonl"
        } else {
            ""
        },
        pictures
            .iter()
            .map(|p| format!(", {p}"))
            .collect::<String>(),
        args.out.display()
    );
    match &s.blow_up_message {
        Some(m) => Err(format!(
            "the run blew up: {m} (outputs up to that point are in {})",
            args.out.display()
        )),
        None => Ok(()),
    }
}

/// The text of the drag file at `path` (named `name`), refused unread when it is larger than
/// any drag of `fem_scene::drag::MAX_DRAG_EVENTS` events needs.
fn read_drag_file(path: &std::path::Path, name: &str) -> Result<String, String> {
    use fem_scene::drag::{MAX_DRAG_EVENTS, MAX_DRAG_FILE_BYTES};
    use std::io::Read;
    let cannot = |e: std::io::Error| format!("{name}: cannot read the drag file: {e}");
    let too_large = |size: String| {
        format!(
            "{name}: size = {size}: must be at most {MAX_DRAG_FILE_BYTES} bytes (fem_scene::drag::MAX_DRAG_FILE_BYTES, 256 per event of at most {MAX_DRAG_EVENTS})"
        )
    };
    let file = std::fs::File::open(path).map_err(cannot)?;
    if let Ok(meta) = file.metadata()
        && meta.len() > MAX_DRAG_FILE_BYTES
    {
        return Err(too_large(format!("{} bytes", meta.len())));
    }
    // One byte more than the bound tells a stream (a pipe) over it.
    let mut bytes = Vec::new();
    file.take(MAX_DRAG_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(cannot)?;
    if bytes.len() as u64 > MAX_DRAG_FILE_BYTES {
        return Err(too_large(format!("more than {MAX_DRAG_FILE_BYTES} bytes")));
    }
    String::from_utf8(bytes).map_err(|e| format!("{name}: cannot read the drag file: {e}"))
}

/// Most frames of an animated GIF (`--gif`): about 20 s at the default 50 ms per frame.
pub const MAX_GIF_FRAMES: usize = 400;

/// `x` with `digits` decimals, or in scientific notation when it is too large for that to be
/// readable (a blown-up run's numbers have a hundred digits).
fn fixed(x: f64, digits: usize) -> String {
    if x.abs() < 1e6 || !x.is_finite() {
        format!("{x:.digits$}")
    } else {
        format!("{x:.digits$e}")
    }
}

/// A progress bar on standard error (indicatif draws nothing when it is not a terminal), for
/// runs of 1000 steps or more.
#[derive(Default)]
struct ProgressBar(Option<indicatif::ProgressBar>);

impl Progress for ProgressBar {
    fn start(&mut self, total: u64) {
        if total < 1000 {
            return;
        }
        let bar = indicatif::ProgressBar::with_draw_target(
            Some(total),
            indicatif::ProgressDrawTarget::stderr(),
        );
        if let Ok(style) = indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} steps ({per_sec}, eta {eta})",
        ) {
            bar.set_style(style.progress_chars("=> "));
        }
        self.0 = Some(bar);
    }

    fn advance(&mut self, done: u64) {
        if let Some(b) = &self.0 {
            b.set_position(done);
        }
    }

    fn finish(&mut self) {
        if let Some(b) = self.0.take() {
            b.finish_and_clear();
        }
    }
}

/// `fem2d run` on a 3D scene (`dim = 3`): `summary.json`, `probes.csv` and `scene.toml`, with
/// `--png` the surface from an oblique view (`final.png`) and with `--vtk` the tetrahedra.
/// The 2D-only flags are refused in one line.
fn run_3d(args: &RunArgs, scene: &LoadedScene3) -> Result<(), String> {
    let two_d_only = [
        (args.gif, "--gif"),
        (args.wireframe, "--wireframe"),
        (args.drag.is_some(), "--drag"),
        (args.stress_threshold.is_some(), "--stress-threshold"),
        (args.field != "von-mises", "--field"),
    ];
    if let Some((_, flag)) = two_d_only.iter().find(|(given, _)| *given) {
        return Err(format!(
            "{flag}: not available for a 3D scene ({}, dim = 3)",
            scene.origin
        ));
    }
    let out = OutDir::begin(&args.out).map_err(|e| e.to_string())?;
    let dir = out.path().to_path_buf();
    let mut bar = ProgressBar::default();
    let result = fem_cases::solid::run_scene3(
        scene,
        &fem_cases::solid::RunOptions3 {
            out_dir: Some(dir),
            threads: args.threads,
            keep_frames: false,
            vtk: args.vtk,
            png: args.png,
        },
        if args.quiet { None } else { Some(&mut bar) },
    )
    .map_err(|e| e.to_string())?;
    out.commit().map_err(|e| e.to_string())?;
    let s = &result.summary;
    if s.solver.capabilities().clock == Clock::LoadFactor {
        println!(
            "{}: {} / {} (3D), {} tetrahedra, {} load increments in {:.3} s",
            s.scene, s.energy, s.solver, s.tetrahedra, s.steps_completed, s.step_seconds
        );
    } else {
        println!(
            "{}: {} / {} (3D), {} tetrahedra, {} steps of {:e} s in {:.3} s ({:.3e} element-steps/s, real-time factor {:.2})",
            s.scene,
            s.energy,
            s.solver,
            s.tetrahedra,
            s.steps_completed,
            s.dt,
            s.step_seconds,
            s.element_steps_per_second,
            s.real_time_factor
        );
    }
    println!(
        "max von Mises {:.4e} Pa (step {}, element {}), min det F {:.4}, inverted elements {}",
        s.max_von_mises,
        s.max_von_mises_step,
        s.max_von_mises_element,
        s.min_det_f,
        s.inverted_elements
    );
    for p in &s.probes {
        println!(
            "probe {}: final displacement [{:.4e}, {:.4e}, {:.4e}] m",
            p.name, p.final_displacement[0], p.final_displacement[1], p.final_displacement[2]
        );
    }
    println!(
        "wrote summary.json, probes.csv, scene.toml{}{} to {}",
        if args.png && !s.blew_up {
            ", final.png"
        } else {
            ""
        },
        if args.vtk { ", vtk/run.pvd" } else { "" },
        args.out.display()
    );
    match &s.blow_up_message {
        Some(m) => Err(format!(
            "the run blew up: {m} (outputs up to that point are in {})",
            args.out.display()
        )),
        None => Ok(()),
    }
}
