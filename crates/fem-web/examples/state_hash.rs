//! The native side of the WebAssembly bit-identity check: load a built-in case in the app,
//! take `steps` steps and print the state's fingerprint (`cargo xtask web --check` compares it
//! with the one the WebAssembly module prints under node).
//!
//! `cargo run --release -p fem-web --example state_hash -- case-a 500 [KEY=VALUE ...]`
//! (each `KEY=VALUE` is set before stepping, as the page's controls do);
//! `state_hash --list-solvers` prints the registry's solver names, `--list-contact-solvers`
//! those that handle contact, `--list-integrator-solvers` those with a choice of time
//! integrator (BDF2), `--list-averaged-pressure-solvers` those with the averaged nodal pressure
//! triangle.

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let list = args.first().map(String::as_str);
    if let Some(
        which @ ("--list-solvers"
        | "--list-contact-solvers"
        | "--list-integrator-solvers"
        | "--list-averaged-pressure-solvers"),
    ) = list
    {
        let names: Vec<&str> = fem_solvers::SolverKind::ALL
            .iter()
            .filter(|k| match which {
                "--list-contact-solvers" => k.capabilities().contact,
                "--list-integrator-solvers" => k.default_params().integrator().is_some(),
                "--list-averaged-pressure-solvers" => k.capabilities().averaged_pressure,
                _ => true,
            })
            .map(|k| k.name())
            .collect();
        println!("{}", names.join(" "));
        return;
    }
    let case = args.first().map_or("case-a", String::as_str);
    let steps: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(500);
    let mut app = match fem_web::App::case(case) {
        Ok(app) => app,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    };
    for kv in args.iter().skip(2) {
        let (key, value) = kv.split_once('=').unwrap_or((kv, ""));
        if let Err(e) = app.set(key, value) {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    }
    if let Err(e) = app.step(steps) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
    println!("{:016x}", app.state().digest());
}
