//! Helpers the tasks share: the workspace root, building and running the `fem2d` binary as a
//! subprocess (xtask depends on no workspace crate, see `ARCHITECTURE.md`), scratch
//! directories, atomic writes and JSON access.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};

use serde_json::Value;

/// The workspace root (xtask lives one level below it).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives one level below the root")
        .to_path_buf()
}

/// The cargo that runs us (`CARGO`), or `cargo` from the path.
pub fn cargo_program() -> String {
    std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned())
}

/// `cargo build --release ARGS` from the workspace root, and the executable of target `name`
/// that cargo reports (so `CARGO_TARGET_DIR` and `--target-dir` settings are honoured).
pub fn build_release(args: &[&str], name: &str) -> Result<PathBuf, String> {
    let cargo = cargo_program();
    let mut all = vec!["build", "--release"];
    all.extend(args);
    all.push("--message-format=json-render-diagnostics");
    eprintln!("$ cargo {}", all.join(" "));
    let out = Command::new(&cargo)
        .args(&all)
        .current_dir(root())
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| format!("cannot run {cargo}: {e}"))?;
    if !out.status.success() {
        return Err(format!("building {name} failed ({})", out.status));
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    stdout
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|m| m["reason"] == "compiler-artifact" && m["target"]["name"] == name)
        .find_map(|m| m["executable"].as_str().map(PathBuf::from))
        .ok_or_else(|| format!("cargo build did not report the {name} executable"))
}

/// The release `fem2d` binary, built once per xtask invocation.
pub struct Fem2d {
    /// The release executable.
    pub exe: PathBuf,
}

/// What a `fem2d` invocation produced.
pub struct Output {
    /// Whether it exited with status 0.
    pub success: bool,
    /// Standard output.
    pub stdout: String,
    /// Standard error.
    pub stderr: String,
}

impl Fem2d {
    /// `cargo build --release -p fem2d --bin fem2d`, then the executable cargo reports
    /// (so `CARGO_TARGET_DIR` and `--target-dir` settings are honoured).
    pub fn build() -> Result<Self, String> {
        let exe = build_release(&["-p", "fem2d", "--bin", "fem2d"], "fem2d")?;
        Ok(Fem2d { exe })
    }

    /// Run `fem2d ARGS` from the workspace root, whatever its exit status.
    pub fn output(&self, args: &[&str]) -> Result<Output, String> {
        let out = Command::new(&self.exe)
            .args(args)
            .current_dir(root())
            .output()
            .map_err(|e| format!("cannot run {}: {e}", self.exe.display()))?;
        Ok(Output {
            success: out.status.success(),
            stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        })
    }

    /// Run `fem2d ARGS`; its standard output, or an error naming the command and its message.
    pub fn run(&self, args: &[&str]) -> Result<String, String> {
        let out = self.output(args)?;
        if out.success {
            Ok(out.stdout)
        } else {
            Err(format!(
                "`fem2d {}` failed: {}",
                args.join(" "),
                out.stderr.trim()
            ))
        }
    }

    /// Run `fem2d ARGS` and parse its standard output as JSON.
    pub fn run_json(&self, args: &[&str]) -> Result<Value, String> {
        let text = self.run(args)?;
        serde_json::from_str(&text)
            .map_err(|e| format!("`fem2d {}` printed no JSON: {e}", args.join(" ")))
    }
}

/// A scratch directory under the system's temporary folder, removed on drop.
pub struct TempDir(PathBuf);

impl TempDir {
    /// A new, empty directory named after `tag`.
    pub fn new(tag: &str) -> Result<Self, String> {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let path = std::env::temp_dir().join(format!("xtask-{tag}-{}-{n}", std::process::id()));
        if path.exists() {
            std::fs::remove_dir_all(&path)
                .map_err(|e| format!("{}: cannot clear: {e}", path.display()))?;
        }
        std::fs::create_dir_all(&path)
            .map_err(|e| format!("{}: cannot create: {e}", path.display()))?;
        Ok(TempDir(path))
    }

    /// Its path.
    pub fn path(&self) -> &Path {
        &self.0
    }

    /// Its path as a string (for command lines).
    pub fn arg(&self) -> String {
        self.0.display().to_string()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Write `bytes` to `path` through a temporary file in the same folder and a rename, so the
/// file is either the old one or complete.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
    let name = path
        .file_name()
        .ok_or_else(|| format!("{}: not a file path", path.display()))?;
    let tmp = dir.join(format!(".{}.tmp", name.to_string_lossy()));
    std::fs::write(&tmp, bytes).map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("{}: {e}", path.display())
    })?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// Read and parse a JSON file.
pub fn read_json(path: &Path) -> Result<Value, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: not JSON: {e}", path.display()))
}

/// `v[key]` as a number (JSON `null`, which non-finite numbers become, reads as NaN).
pub fn num(v: &Value, key: &str) -> Result<f64, String> {
    match &v[key] {
        Value::Null => Ok(f64::NAN),
        x => x
            .as_f64()
            .ok_or_else(|| format!("`{key}` is not a number in {v}")),
    }
}

/// `v[key]` as a string.
pub fn text<'a>(v: &'a Value, key: &str) -> Result<&'a str, String> {
    v[key]
        .as_str()
        .ok_or_else(|| format!("`{key}` is not a string"))
}

/// `v[key]` as an array.
pub fn array<'a>(v: &'a Value, key: &str) -> Result<&'a Vec<Value>, String> {
    v[key]
        .as_array()
        .ok_or_else(|| format!("`{key}` is not an array"))
}

/// The standard output of a shell-level command, trimmed (`None` when it cannot run).
pub fn command_line(program: &str, args: &[&str]) -> Option<String> {
    let out = Command::new(program).args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

/// The CPU's model name (`/proc/cpuinfo`), where the system says it.
pub fn cpu_name() -> Option<String> {
    std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|t| {
        t.lines()
            .find(|l| l.starts_with("model name"))
            .and_then(|l| l.split_once(':'))
            .map(|(_, m)| m.trim().to_owned())
    })
}
