//! Throughput of the steppers on the case A beam: element-steps per second of the explicit
//! stepper for every energy at 1k, 16k, 64k and 256k triangles, and the
//! time per constraint iteration of PBD and XPBD.
//!
//! Run (release; pin single-thread runs to one core):
//!
//! ```text
//! taskset -c 1 cargo run --release -p fem-solvers --example throughput -- --threads 1
//! cargo run --release -p fem-solvers --example throughput -- --threads 2
//! ```
//!
//! Options: `--threads N` (rayon pool size, default 1), `--sizes 1000,16000,...` (triangle
//! counts), `--seconds S` (target time per measurement, default 0.5), `--repeat R` (best of R,
//! default 3), `--skip-pbd`, `--energies neo-hookean,stvk,...` (explicit rows to run; default
//! all five), `--json` (also print one `RESULT {json}` line per explicit measurement, read by
//! `cargo xtask bench-peers`). The set-up matches the peer scripts: 5 m x 1 m beam numbered as
//! theirs (`NodeOrder::YFastest`), left edge pinned, gravity, E = 1000 Pa, nu = 0.3, 1 kg, symplectic Euler, damping 1/s, dt half the
//! critical step. The explicit force kernel runs under the instruction set picked at run time
//! (printed; `FEM2D_SIMD=baseline|avx2|avx512` caps it).

use std::time::Instant;

use fem_core::PlaneModel;
use fem_core::energy::{Corotational, Energy, Linear, NeoHookean, StableNeoHookean, Stvk};
use fem_core::material::Material;
use fem_solvers::testing::{
    self, BEAM_HEIGHT, BEAM_LENGTH, NodeOrder, RectangleParams, beam_cells_for, cantilever,
    rectangle,
};
use fem_solvers::{
    ExplicitParams, ExplicitStepper, Model, PbdParams, PbdStepper, State, Stepper, XpbdParams,
    XpbdStepper,
};

struct Options {
    threads: usize,
    sizes: Vec<usize>,
    seconds: f64,
    repeat: usize,
    pbd: bool,
    energies: Option<Vec<String>>,
    json: bool,
}

fn parse() -> Result<Options, String> {
    let mut o = Options {
        threads: 1,
        sizes: vec![1_000, 16_000, 64_000, 256_000],
        seconds: 0.5,
        repeat: 3,
        pbd: true,
        energies: None,
        json: false,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--threads" => o.threads = value()?.parse().map_err(|e| format!("--threads: {e}"))?,
            "--sizes" => {
                o.sizes = value()?
                    .split(',')
                    .map(|s| s.parse().map_err(|e| format!("--sizes: {e}")))
                    .collect::<Result<_, _>>()?
            }
            "--seconds" => o.seconds = value()?.parse().map_err(|e| format!("--seconds: {e}"))?,
            "--repeat" => o.repeat = value()?.parse().map_err(|e| format!("--repeat: {e}"))?,
            "--skip-pbd" => o.pbd = false,
            "--json" => o.json = true,
            "--energies" => o.energies = Some(value()?.split(',').map(str::to_owned).collect()),
            other => return Err(format!("unknown option `{other}`")),
        }
    }
    Ok(o)
}

/// The case A beam of about `triangles` triangles, numbered as the peer scripts number it
/// (y fastest, cells column by column), so both sides time the same memory layout.
fn model<E: Energy>(energy: E, triangles: usize) -> Model<E> {
    let (nx, ny) = beam_cells_for(triangles);
    let params = RectangleParams {
        order: NodeOrder::YFastest,
        ..RectangleParams::new(BEAM_LENGTH, BEAM_HEIGHT, nx, ny)
    };
    cantilever(rectangle(&params).expect("beam sizes are positive"), energy)
        .expect("the case A set-up is valid")
}

/// The beam stretched by 1% along x and at rest: every constraint is active from the first
/// step (at the rest state PBD/XPBD skip constraints below the rest threshold, which would
/// flatter their timings).
fn stretched<E: Energy>(model: &Model<E>) -> State {
    testing::stretched(model, 1.01).expect("stretched state matches the model")
}

/// Best-of-`repeat` seconds per step over about `seconds` of stepping from `start`.
fn time_per_step<E: Energy, S: Stepper + Clone>(
    model: &Model<E>,
    start: &State,
    stepper: &S,
    seconds: f64,
    repeat: usize,
) -> f64 {
    let mut s = stepper.clone();
    let mut state = start.clone();
    // Warm-up and calibration.
    let t0 = Instant::now();
    let mut calib = 0;
    while t0.elapsed().as_secs_f64() < 0.05 * seconds.max(0.01) || calib < 3 {
        s.step(model, &mut state).unwrap();
        calib += 1;
    }
    let per = t0.elapsed().as_secs_f64() / calib as f64;
    let steps = ((seconds / per) as usize).max(3);
    let mut best = f64::INFINITY;
    for _ in 0..repeat {
        let mut s = stepper.clone();
        let mut state = start.clone();
        let t = Instant::now();
        for _ in 0..steps {
            s.step(model, &mut state).unwrap();
        }
        best = best.min(t.elapsed().as_secs_f64() / steps as f64);
    }
    best
}

fn explicit_row<E: Energy>(energy: E, o: &Options) {
    let name = energy.name();
    if o.energies
        .as_ref()
        .is_some_and(|l| !l.iter().any(|n| n == name))
    {
        return;
    }
    print!("{name:<19}");
    let mut results = Vec::new();
    for &n in &o.sizes {
        let m = model(energy.clone(), n);
        let dt = 0.5 * m.check_time_step(1.0).critical();
        let s = ExplicitStepper::new(
            &m,
            ExplicitParams {
                dt,
                damping: 1.0,
                ..Default::default()
            },
        )
        .unwrap();
        let t = time_per_step(&m, &State::at_rest(&m), &s, o.seconds, o.repeat);
        let rate = m.mesh().n_triangles() as f64 / t;
        print!(" {rate:>10.3e}");
        results.push(format!(
            r#"RESULT {{"impl": "fem2d", "energy": "{name}", "elements": {}, "threads": {}, "isa": "{}", "elem_steps_per_s": {rate:.6e}}}"#,
            m.mesh().n_triangles(),
            o.threads,
            m.isa(),
        ));
    }
    println!();
    if o.json {
        results.iter().for_each(|r| println!("{r}"));
    }
}

fn main() {
    let o = match parse() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(o.threads)
        .build()
        .expect("thread pool");
    pool.install(|| {
        let lame = Material::new(1000.0, 0.3, 1.0)
            .unwrap()
            .lame(PlaneModel::PlaneStrain);
        println!(
            "explicit, element-steps per second, {} thread(s), best of {}, force kernel: {}",
            o.threads,
            o.repeat,
            fem_core::simd::Isa::detected()
        );
        print!("{:<19}", "triangles");
        for &n in &o.sizes {
            let (nx, ny) = beam_cells_for(n);
            print!(" {:>10}", 2 * nx * ny);
        }
        println!();
        explicit_row(NeoHookean::new(lame).unwrap(), &o);
        explicit_row(Stvk::new(lame).unwrap(), &o);
        explicit_row(Corotational::new(lame).unwrap(), &o);
        explicit_row(StableNeoHookean::new(lame).unwrap(), &o);
        explicit_row(Linear::new(lame).unwrap(), &o);
        if o.pbd {
            println!(
                "position-based (StVK, coloured Gauss-Seidel, 10 iterations, from a 1% stretch), time per iteration"
            );
            for &n in &o.sizes {
                let m = model(Stvk::new(lame).unwrap(), n);
                let p = PbdStepper::new(&m, PbdParams::default()).unwrap();
                let x = XpbdStepper::new(&m, XpbdParams::default()).unwrap();
                let it = PbdParams::default().iterations as f64;
                let start = stretched(&m);
                let tp = time_per_step(&m, &start, &p, o.seconds, o.repeat) / it;
                let tx = time_per_step(&m, &start, &x, o.seconds, o.repeat) / it;
                println!(
                    "  {:>7} triangles: pbd {:>9.3} ms/iteration ({:.3e} constraints/s), xpbd {:>9.3} ms/iteration ({:.3e} constraints/s)",
                    m.mesh().n_triangles(),
                    tp * 1e3,
                    m.mesh().n_triangles() as f64 / tp,
                    tx * 1e3,
                    m.mesh().n_triangles() as f64 / tx
                );
            }
        }
    });
}
