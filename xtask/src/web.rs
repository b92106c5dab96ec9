//! `cargo xtask web [--serve] [--port N] [--check] [--browser-test] [--screenshot PATH]`: build
//! the interactive app (`crates/fem-web`) for WebAssembly and put the page together in
//! `target/web/`; `--serve` then serves it on 127.0.0.1 and prints the URL; `--check` runs the
//! module under node on cases A and D and on case A under every solver of the registry, and
//! compares each state's fingerprint with the native build's (they must be equal, bit for
//! bit); `--browser-test` drives the page in headless Chromium
//! (`crates/fem-web/tests/browser/drag.mjs`), `--screenshot PATH` saves its pictures (PATH, case A
//! mid-drag; PATH with `-case-d` before `.png`, case D with its bones).
//!
//! Installs what it needs: the `wasm32-unknown-unknown` target (through rustup) when missing,
//! and for the browser test `puppeteer-core` from the npm registry into `target/web-test/`
//! (pointed at the system's Chromium; it downloads no browser).
//! The module is plain WebAssembly with exported functions, so no binding generator is needed;
//! the server is a few lines of `std::net` (a static file server, GET only).

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::util::{cargo_program, root};

pub const TARGET: &str = "wasm32-unknown-unknown";

/// The built-in cases the bit-identity check runs with their own settings, and steps (case D
/// with its rigid bones, the scene's default).
const CASES: &[(&str, u64)] = &[("case-a", 500), ("case-d", 200)];

/// Steps of case A under each solver of the registry (co-rotational, which every solver runs).
const SOLVER_STEPS: u64 = 40;

/// Steps of case D at dt = 1/90 s under each solver that handles contact.
const CONTACT_STEPS: u64 = 60;

/// Runs the task.
pub fn run(args: &[&str]) -> Result<(), String> {
    let mut serve = false;
    let mut check = false;
    let mut browser = false;
    let mut screenshot: Option<String> = None;
    let mut port: u16 = 8090;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match *a {
            "--serve" => serve = true,
            "--check" => check = true,
            "--browser-test" => browser = true,
            "--screenshot" => {
                screenshot = Some(
                    it.next()
                        .ok_or("--screenshot needs a file name (.png)")?
                        .to_string(),
                );
                browser = true;
            }
            "--port" => {
                port = it
                    .next()
                    .and_then(|p| p.parse().ok())
                    .ok_or("--port needs a number (1-65535)")?;
            }
            other => return Err(format!("web: unknown argument `{other}`")),
        }
    }
    let site = build()?;
    if check {
        check_against_native(&site)?;
    }
    if browser {
        browser_test(&site, screenshot.as_deref())?;
    }
    if serve {
        serve_dir(&site, port)?;
    }
    Ok(())
}

/// Install the `wasm32-unknown-unknown` target through rustup when it is missing.
pub fn install_target() -> Result<(), String> {
    let installed = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .map(|o| {
            String::from_utf8_lossy(&o.stdout)
                .lines()
                .any(|l| l == TARGET)
        })
        .unwrap_or(false);
    if !installed {
        eprintln!("$ rustup target add {TARGET}");
        let ok = Command::new("rustup")
            .args(["target", "add", TARGET])
            .status()
            .map(|s| s.success())
            .unwrap_or(false);
        if !ok {
            return Err(format!(
                "cannot install the {TARGET} target (rustup target add {TARGET})"
            ));
        }
    }
    Ok(())
}

/// Install the target if missing, build the module, copy the page: the site's directory.
fn build() -> Result<PathBuf, String> {
    install_target()?;
    // Without the `parallel` feature: the browser gives the module one thread, and rayon is
    // left out. The check below compares it with the native build on rayon's pool, so it also
    // shows that the feature changes no bit.
    let args = [
        "build",
        "--release",
        "-p",
        "fem-web",
        "--lib",
        "--no-default-features",
        "--target",
        TARGET,
    ];
    eprintln!("$ cargo {}", args.join(" "));
    // No debug information in the module the browser downloads.
    let status = Command::new(cargo_program())
        .args(args)
        .env("CARGO_PROFILE_RELEASE_DEBUG", "false")
        .env("CARGO_PROFILE_RELEASE_STRIP", "true")
        .current_dir(root())
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !status.success() {
        return Err(format!("`cargo {}` failed ({status})", args.join(" ")));
    }
    let target_dir = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target"));
    let module = target_dir.join(TARGET).join("release").join("fem_web.wasm");
    let site = target_dir.join("web");
    std::fs::create_dir_all(&site).map_err(|e| format!("{}: {e}", site.display()))?;
    copy(&module, &site.join("fem_web.wasm"))?;
    let www = root().join("crates/fem-web/www");
    for name in ["index.html", "app.js"] {
        copy(&www.join(name), &site.join(name))?;
    }
    let size = std::fs::metadata(site.join("fem_web.wasm"))
        .map(|m| m.len())
        .unwrap_or(0);
    eprintln!(
        "built {} (module {:.1} MB)",
        site.display(),
        size as f64 / 1e6
    );
    Ok(site)
}

fn copy(from: &Path, to: &Path) -> Result<(), String> {
    std::fs::copy(from, to)
        .map(|_| ())
        .map_err(|e| format!("cannot copy {} to {}: {e}", from.display(), to.display()))
}

/// Each check's fingerprint under node and natively; an error naming the first difference.
fn check_against_native(site: &Path) -> Result<(), String> {
    let node = std::env::var("NODE").unwrap_or_else(|_| "node".to_owned());
    let script = root().join("crates/fem-web/www/check.mjs");
    let module = site.join("fem_web.wasm");
    let native = |args: &[String]| -> Result<String, String> {
        let mut a = vec![
            "run".to_owned(),
            "--release".to_owned(),
            "-q".to_owned(),
            "-p".to_owned(),
            "fem-web".to_owned(),
            "--example".to_owned(),
            "state_hash".to_owned(),
            "--".to_owned(),
        ];
        a.extend_from_slice(args);
        output(Command::new(cargo_program()).args(&a).current_dir(root()))
    };
    // Every solver of the registry, as the native example lists them (none is named here).
    let solvers = native(&["--list-solvers".to_owned()])?;
    let mut checks: Vec<Vec<String>> = CASES
        .iter()
        .map(|(case, steps)| vec![case.to_string(), steps.to_string()])
        .collect();
    for solver in solvers.split_whitespace() {
        checks.push(vec![
            "case-a".into(),
            SOLVER_STEPS.to_string(),
            "energy=\"corotational\"".into(),
            format!("solver.kind=\"{solver}\""),
        ]);
    }
    // BDF2 under every solver that offers it (its history, targets and velocities).
    let bdf2 = native(&["--list-integrator-solvers".to_owned()])?;
    for solver in bdf2.split_whitespace() {
        checks.push(vec![
            "case-a".into(),
            SOLVER_STEPS.to_string(),
            "energy=\"corotational\"".into(),
            format!("solver.kind=\"{solver}\""),
            "solver.integrator=\"bdf2\"".into(),
        ]);
    }
    // The averaged nodal pressure triangle (nearly incompressible, two materials) under every
    // solver that supports it, and on case D (contact, rigid bones) under the scene's solver.
    let averaged = native(&["--list-averaged-pressure-solvers".to_owned()])?;
    for solver in averaged.split_whitespace() {
        checks.push(vec![
            "case-a".into(),
            SOLVER_STEPS.to_string(),
            "energy=\"neo-hookean\"".into(),
            "material.poisson_ratio=0.49".into(),
            "material.formulation=\"averaged-pressure\"".into(),
            format!("solver.kind=\"{solver}\""),
        ]);
    }
    checks.push(vec![
        "case-d".into(),
        CONTACT_STEPS.to_string(),
        "material.poisson_ratio=0.49".into(),
        "material.formulation=\"averaged-pressure\"".into(),
    ]);
    // Case D at a headset's frame step under every solver that handles contact (barrier
    // contact in implicit, static, VBD and quasi-Newton), so contact is bit-identical in
    // WebAssembly too.
    let contact = native(&["--list-contact-solvers".to_owned()])?;
    for solver in contact.split_whitespace() {
        checks.push(vec![
            "case-d".into(),
            CONTACT_STEPS.to_string(),
            format!("solver.kind=\"{solver}\""),
            format!("solver.dt={}", 1.0 / 90.0),
        ]);
    }
    // Case D's rigid bones under explicit at the soft tissue's own step (its rigid bodies
    // driven by the summed nodal forces), and its elastic bones under the scene's solver.
    checks.push(vec![
        "case-d".into(),
        "300".into(),
        "solver.kind=\"explicit\"".into(),
        "solver.dt=3.5e-5".into(),
    ]);
    checks.push(vec![
        "case-d".into(),
        CONTACT_STEPS.to_string(),
        "regions.0.rigid=false".into(),
    ]);
    for args in &checks {
        let wasm = output(
            Command::new(&node)
                .arg(&script)
                .arg(&module)
                .args(args)
                .current_dir(root()),
        )?;
        let here = native(args)?;
        let line = args.join(" ");
        if wasm != here {
            return Err(format!(
                "WebAssembly and native states differ: {line}: wasm {wasm}, native {here}"
            ));
        }
        eprintln!(
            "same state natively (parallel, {} threads) and in WebAssembly (sequential): {line}: {here}",
            std::thread::available_parallelism().map_or(1, |n| n.get())
        );
    }
    Ok(())
}

/// Run the browser test on the built site (installing puppeteer-core when missing).
fn browser_test(site: &Path, screenshot: Option<&str>) -> Result<(), String> {
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".to_owned());
    if !Path::new(&chromium).exists() {
        return Err(format!(
            "the browser test needs Chromium at {chromium} (apt-get install chromium, or set CHROMIUM)"
        ));
    }
    let target_dir = site.parent().unwrap_or(site);
    let dir = target_dir.join("web-test");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    if !dir
        .join("node_modules/puppeteer-core/package.json")
        .exists()
    {
        let args = [
            "install",
            "--silent",
            "--no-audit",
            "--no-fund",
            "--prefix",
            &dir.display().to_string(),
            PUPPETEER,
        ];
        eprintln!("$ npm {}", args.join(" "));
        let ok = Command::new("npm")
            .args(args)
            .env("PUPPETEER_SKIP_DOWNLOAD", "1")
            .status()
            .map(|s| s.success())
            .unwrap_or(false);
        if !ok {
            return Err(format!("cannot install {PUPPETEER} from the npm registry"));
        }
    }
    // Node resolves the package next to the script.
    let script = dir.join("drag.mjs");
    copy(
        &root().join("crates/fem-web/tests/browser/drag.mjs"),
        &script,
    )?;
    let mut cmd = Command::new(std::env::var("NODE").unwrap_or_else(|_| "node".to_owned()));
    cmd.arg(&script).arg(site).env("CHROMIUM", &chromium);
    if let Some(s) = screenshot {
        cmd.arg(root().join(s));
    }
    eprintln!("$ node {} {}", script.display(), site.display());
    let status = cmd
        .current_dir(root())
        .status()
        .map_err(|e| format!("cannot run node: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("the browser test failed ({status})"))
    }
}

/// The npm package the browser test drives Chromium with (no bundled browser).
const PUPPETEER: &str = "puppeteer-core@23";

/// A command's trimmed standard output, or an error with its standard error.
pub fn output(cmd: &mut Command) -> Result<String, String> {
    let out = cmd
        .output()
        .map_err(|e| format!("cannot run {:?}: {e}", cmd.get_program()))?;
    if !out.status.success() {
        return Err(format!(
            "{:?} failed: {}",
            cmd.get_program(),
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

/// Serve `dir` on 127.0.0.1:`port` until interrupted (GET of its files only).
fn serve_dir(dir: &Path, port: u16) -> Result<(), String> {
    let listener = TcpListener::bind(("127.0.0.1", port))
        .map_err(|e| format!("cannot listen on 127.0.0.1:{port}: {e} (try --port)"))?;
    println!("serving {} at http://127.0.0.1:{port}/", dir.display());
    let _ = std::io::stdout().flush();
    for stream in listener.incoming() {
        match stream {
            Ok(s) => {
                if let Err(e) = answer(s, dir) {
                    eprintln!("web: {e}");
                }
            }
            Err(e) => eprintln!("web: {e}"),
        }
    }
    Ok(())
}

fn answer(mut stream: TcpStream, dir: &Path) -> Result<(), String> {
    let mut line = String::new();
    let mut reader = BufReader::new(stream.try_clone().map_err(|e| e.to_string())?);
    reader.read_line(&mut line).map_err(|e| e.to_string())?;
    // Drain the headers.
    let mut header = String::new();
    while reader.read_line(&mut header).map_err(|e| e.to_string())? > 2 {
        header.clear();
    }
    let mut parts = line.split_whitespace();
    let (method, target) = (parts.next().unwrap_or(""), parts.next().unwrap_or("/"));
    let path = target.split(['?', '#']).next().unwrap_or("/");
    let name = if path == "/" {
        "index.html"
    } else {
        path.trim_start_matches('/')
    };
    // Only the site's own files: no directories, no climbing out.
    let known = ["index.html", "app.js", "fem_web.wasm"];
    let (status, body, kind) = if method != "GET" {
        ("405 Method Not Allowed", Vec::new(), "text/plain")
    } else if !known.contains(&name) {
        ("404 Not Found", b"not found".to_vec(), "text/plain")
    } else {
        let kind = match name.rsplit('.').next() {
            Some("html") => "text/html; charset=utf-8",
            Some("js") => "text/javascript",
            Some("wasm") => "application/wasm",
            _ => "application/octet-stream",
        };
        match std::fs::read(dir.join(name)) {
            Ok(b) => ("200 OK", b, kind),
            Err(_) => ("404 Not Found", b"not found".to_vec(), "text/plain"),
        }
    };
    let head = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    );
    stream
        .write_all(head.as_bytes())
        .and_then(|_| stream.write_all(&body))
        .map_err(|e| e.to_string())
}
