//! Parameter sweeps that any batch scheduler can spread over machines.
//!
//! A sweep spec (TOML) names a scene, fixed overrides and axes; the jobs are the Cartesian
//! product of the axes, numbered in row-major order (the first axis varies slowest). Shard
//! `i/n` runs the jobs whose number is `i` modulo `n` (round-robin, so cheap and expensive
//! corners of the grid spread evenly) and writes one shard file; [`merge`] joins the shard
//! files, checks that they come from the same spec and that every job is present exactly once,
//! and tabulates the results. When `solver.dt` is an axis, the merged table also gives the
//! largest stable time step for each combination of the other axes.
//!
//! ```toml
//! scene = "case-b"                  # a built-in case or a scene file (relative to the spec)
//! set = ["output.frames=false"]     # fixed overrides
//! duration = 1.5                    # optional: steps = ceil(duration / dt) for every job
//!
//! [[axis]]
//! key = "energy"
//! values = ["stvk", "neo-hookean"]
//!
//! [[axis]]                          # linked keys: one axis, several values per point
//! keys = ["mesh.nx", "mesh.ny"]
//! values = [[10, 2], [20, 4]]
//! ```

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::files::load_case_or_file;
use crate::run::{RunOptions, RunResult, Summary, run_scene, write_atomic};
use fem_scene::SceneError;

/// A sweep spec as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// A built-in case or a scene file (relative to the spec file).
    pub scene: String,
    /// Fixed overrides applied to every job before the axis values.
    #[serde(default)]
    pub set: Vec<String>,
    /// When given, each job runs `ceil(duration / dt)` steps (s), so runs at different time
    /// steps cover the same simulated time.
    pub duration: Option<f64>,
    /// The axes.
    #[serde(default, rename = "axis")]
    pub axes: Vec<Axis>,
    /// A reference run every job is compared with (accuracy maps).
    pub reference: Option<Reference>,
}

/// The reference of an accuracy sweep: each job's run with these overrides applied last (for
/// example a fine-dt implicit run: `set = ["solver.kind=\"implicit\"", "solver.dt=1e-5"]`).
/// Jobs whose parameters give the same reference share one reference run (per shard).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reference {
    /// Overrides applied after the job's own.
    pub set: Vec<String>,
    /// The probe compared (default: every probe).
    pub probe: Option<String>,
}

/// One axis: a key and its values, or linked keys and a tuple of values per point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Axis {
    /// A scene key (`material.youngs_modulus`).
    pub key: Option<String>,
    /// Linked keys varied together.
    pub keys: Option<Vec<String>>,
    /// The values (TOML values; arrays of the same length as `keys` for linked keys).
    pub values: Vec<toml::Value>,
}

/// A loaded spec with its origin.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// The spec.
    pub spec: SweepSpec,
    /// Where it came from (for messages).
    pub origin: String,
    /// Directory the scene path resolves against.
    pub base_dir: PathBuf,
    /// A digest of the spec's canonical form: shards of one sweep carry the same digest.
    pub digest: String,
}

/// One job: its number and its overrides per axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Job {
    /// Job number, row-major over the axes.
    pub index: usize,
    /// `(key, value)` per swept key, values as TOML text.
    pub params: Vec<(String, String)>,
}

/// The outcome of one job.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JobResult {
    /// The job.
    pub job: Job,
    /// The run's summary (present when the run started; `blew_up` says how it ended).
    pub summary: Option<Summary>,
    /// Why the job could not run (bad parameter combination), if so.
    pub error: Option<String>,
    /// With a reference: the RMS over the job's frames of the distance between the job's probe
    /// displacements and the reference's (linearly interpolated at the job's frame times), m.
    #[serde(default)]
    pub reference_error: Option<f64>,
}

/// A shard file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShardFile {
    /// Spec digest.
    pub digest: String,
    /// The spec.
    pub spec: SweepSpec,
    /// Total jobs of the sweep.
    pub total_jobs: usize,
    /// This shard `[i, n]`.
    pub shard: [usize; 2],
    /// Results, by job number.
    pub results: Vec<JobResult>,
}

/// Most jobs a sweep may have (the product of its axes' lengths).
pub const MAX_JOBS: usize = 1_000_000;
/// Longest simulated `duration` of a sweep job, s.
pub const MAX_DURATION: f64 = 1e6;

/// Parse a spec's text (a leading UTF-8 byte-order mark is skipped).
pub fn parse_sweep(text: &str, origin: &str, base_dir: &Path) -> Result<Sweep, SceneError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let spec: SweepSpec = toml::from_str(text).map_err(|e: toml::de::Error| {
        SceneError::Scene(format!(
            "{origin}: {}",
            e.message().trim().replace('\n', " ")
        ))
    })?;
    if spec.axes.is_empty() {
        return Err(SceneError::Scene(format!(
            "{origin}: axis: at least one [[axis]] is needed"
        )));
    }
    for (i, a) in spec.axes.iter().enumerate() {
        let keys =
            axis_keys(a).map_err(|m| SceneError::Scene(format!("{origin}: axis.{i}: {m}")))?;
        if a.values.is_empty() {
            return Err(SceneError::Scene(format!(
                "{origin}: axis.{i}.values: must not be empty"
            )));
        }
        if keys.len() > 1 {
            for (k, v) in a.values.iter().enumerate() {
                match v.as_array() {
                    Some(t) if t.len() == keys.len() => {}
                    _ => {
                        return Err(SceneError::Scene(format!(
                            "{origin}: axis.{i}.values.{k} = {v}: must be an array of {} values (one per key)",
                            keys.len()
                        )));
                    }
                }
            }
        }
    }
    // A key swept twice would run only its last value.
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    for (i, a) in spec.axes.iter().enumerate() {
        for key in axis_keys(a).unwrap_or_default() {
            if let Some(j) = seen.insert(key.clone(), i) {
                return Err(SceneError::Scene(format!(
                    "{origin}: axis.{i}: key {key:?} is already swept by axis.{j}"
                )));
            }
        }
    }
    let jobs = spec
        .axes
        .iter()
        .try_fold(1usize, |n, a| n.checked_mul(a.values.len()))
        .filter(|&n| n <= MAX_JOBS);
    if jobs.is_none() {
        let sizes: Vec<String> = spec
            .axes
            .iter()
            .map(|a| a.values.len().to_string())
            .collect();
        return Err(SceneError::Scene(format!(
            "{origin}: axis: {} jobs is more than {MAX_JOBS}; split the sweep",
            sizes.join(" x ")
        )));
    }
    if let Some(d) = spec.duration
        && !(d.is_finite() && d > 0.0 && d <= MAX_DURATION)
    {
        let shown = fem_core::math::readable(d);
        return Err(SceneError::Scene(format!(
            "{origin}: duration = {shown}: must be a finite number > 0 and at most {MAX_DURATION:e} (s)"
        )));
    }
    Ok(Sweep {
        digest: digest_of(&spec),
        spec,
        origin: origin.to_owned(),
        base_dir: base_dir.to_path_buf(),
    })
}

/// Read a spec file.
pub fn load_sweep(path: &Path) -> Result<Sweep, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        SceneError::Io(format!(
            "{}: cannot read the sweep spec: {e}",
            path.display()
        ))
    })?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    parse_sweep(&text, &path.display().to_string(), &base)
}

/// The digest of a spec's canonical form.
fn digest_of(spec: &SweepSpec) -> String {
    let canonical = toml::to_string(spec).unwrap_or_default();
    format!("{:016x}", fnv1a(canonical.as_bytes()))
}

/// The first field in which two results of the same job differ, timings aside (`None` when
/// they agree).
fn first_difference(a: &JobResult, b: &JobResult) -> Option<String> {
    const TIMINGS: [&str; 4] = [
        "wall_seconds",
        "step_seconds",
        "element_steps_per_second",
        "real_time_factor",
    ];
    let strip = |r: &JobResult| {
        let mut v = serde_json::to_value(r).unwrap_or_default();
        if let Some(s) = v.get_mut("summary").and_then(|s| s.as_object_mut()) {
            for t in TIMINGS {
                s.remove(t);
            }
        }
        v
    };
    let (va, vb) = (strip(a), strip(b));
    let (Some(oa), Some(ob)) = (va.as_object(), vb.as_object()) else {
        return (va != vb).then(|| "the result".to_owned());
    };
    for (k, x) in oa {
        let y = ob.get(k).unwrap_or(&serde_json::Value::Null);
        if x != y {
            if let (Some(sx), Some(sy)) = (x.as_object(), y.as_object())
                && let Some((kk, _)) = sx.iter().find(|(kk, xx)| sy.get(*kk) != Some(*xx))
            {
                return Some(format!("{k}.{kk}"));
            }
            return Some(k.clone());
        }
    }
    None
}

/// 64-bit FNV-1a: a stable digest to match shards (not for security; no dependency needed).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// A swept value for display (strings without their quotes).
fn shown(v: &str) -> &str {
    v.strip_prefix('"')
        .and_then(|v| v.strip_suffix('"'))
        .unwrap_or(v)
}

fn axis_keys(a: &Axis) -> Result<Vec<String>, String> {
    match (&a.key, &a.keys) {
        (Some(k), None) => Ok(vec![k.clone()]),
        (None, Some(ks)) if !ks.is_empty() => Ok(ks.clone()),
        _ => Err("give either key or a non-empty keys".into()),
    }
}

fn value_text(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => format!("{s:?}"),
        other => other.to_string(),
    }
}

impl Sweep {
    /// Every job, in order.
    pub fn jobs(&self) -> Vec<Job> {
        let axes: Vec<(Vec<String>, &Vec<toml::Value>)> = self
            .spec
            .axes
            .iter()
            .map(|a| (axis_keys(a).unwrap_or_default(), &a.values))
            .collect();
        let total: usize = axes.iter().map(|a| a.1.len()).product();
        (0..total)
            .map(|index| {
                let mut rest = index;
                let mut picks = vec![0; axes.len()];
                for (k, a) in axes.iter().enumerate().rev() {
                    picks[k] = rest % a.1.len();
                    rest /= a.1.len();
                }
                let mut params = Vec::new();
                for ((keys, values), &p) in axes.iter().zip(&picks) {
                    let v = &values[p];
                    if keys.len() == 1 {
                        params.push((keys[0].clone(), value_text(v)));
                    } else if let Some(t) = v.as_array() {
                        for (k, x) in keys.iter().zip(t) {
                            params.push((k.clone(), value_text(x)));
                        }
                    }
                }
                Job { index, params }
            })
            .collect()
    }

    fn scene_arg(&self) -> String {
        if fem_scene::cases::case_text(&self.spec.scene).is_some() {
            self.spec.scene.clone()
        } else {
            self.base_dir.join(&self.spec.scene).display().to_string()
        }
    }

    fn load(&self, overrides: &[String]) -> Result<fem_scene::scene::LoadedScene, SceneError> {
        load_case_or_file(&self.scene_arg(), overrides).map(|mut scene| {
            if let Some(d) = self.spec.duration {
                scene.scene.solver.steps = (d / scene.scene.solver.dt).ceil().max(1.0) as u64;
            }
            scene.scene.output.frames = false;
            scene
        })
    }

    fn run_with(
        &self,
        overrides: &[String],
        threads: Option<usize>,
    ) -> Result<RunResult, SceneError> {
        let scene = self.load(overrides)?;
        run_scene(
            &scene,
            &RunOptions {
                threads,
                ..RunOptions::default()
            },
        )
    }

    /// Run one job (without a reference comparison; see [`Sweep::run_shard`]).
    pub fn run_job(&self, job: &Job, threads: Option<usize>) -> JobResult {
        self.run_job_against(job, threads, &mut ReferenceCache::default())
    }

    fn run_job_against(
        &self,
        job: &Job,
        threads: Option<usize>,
        cache: &mut ReferenceCache,
    ) -> JobResult {
        let mut overrides = self.spec.set.clone();
        overrides.extend(job.params.iter().map(|(k, v)| format!("{k}={v}")));
        match self.run_with(&overrides, threads) {
            Ok(r) => {
                let reference_error = match &self.spec.reference {
                    Some(reference) if !r.summary.blew_up => {
                        let mut with_reference = overrides.clone();
                        with_reference.extend(reference.set.iter().cloned());
                        // Jobs whose reference scene is the same (e.g. differing only in the
                        // solver and dt the reference overrides) share one reference run.
                        let key = self
                            .load(&with_reference)
                            .ok()
                            .and_then(|scene| toml::to_string(&scene.scene).ok())
                            .unwrap_or_else(|| with_reference.join("\u{1f}"));
                        let entry = cache.runs.entry(key).or_insert_with(|| {
                            self.run_with(&with_reference, threads)
                                .map_err(|e| e.to_string())
                        });
                        match entry {
                            // The reference itself is bad (say a solver name that does not
                            // exist): the job fails, naming it.
                            Err(e) => return failed(job, &r, format!("reference: {e}")),
                            Ok(reference_run) if reference_run.summary.blew_up => None,
                            Ok(reference_run) => {
                                if let Some(name) = reference.probe.as_deref()
                                    && r.probe(name).is_none()
                                {
                                    let names: Vec<&str> =
                                        r.probes.iter().map(|p| p.name.as_str()).collect();
                                    return failed(
                                        job,
                                        &r,
                                        format!(
                                            "reference.probe = {name:?}: the scene has no such probe (it has {})",
                                            names.join(", ")
                                        ),
                                    );
                                }
                                compare_to_reference(&r, reference_run, reference.probe.as_deref())
                            }
                        }
                    }
                    _ => None,
                };
                JobResult {
                    job: job.clone(),
                    summary: Some(r.summary),
                    error: None,
                    reference_error,
                }
            }
            Err(e) => JobResult {
                job: job.clone(),
                summary: None,
                error: Some(e.to_string()),
                reference_error: None,
            },
        }
    }

    /// Run shard `i` of `n` (jobs `k` with `k % n == i`).
    pub fn run_shard(
        &self,
        shard: usize,
        of: usize,
        threads: Option<usize>,
        mut progress: impl FnMut(&JobResult),
    ) -> Result<ShardFile, SceneError> {
        if of == 0 || shard >= of {
            return Err(SceneError::Usage(format!(
                "--shard {shard}/{of}: expected i/n with 0 <= i < n"
            )));
        }
        let jobs = self.jobs();
        let total_jobs = jobs.len();
        let mut cache = ReferenceCache::default();
        let results = jobs
            .into_iter()
            .filter(|j| j.index % of == shard)
            .map(|j| {
                let r = self.run_job_against(&j, threads, &mut cache);
                progress(&r);
                r
            })
            .collect();
        Ok(ShardFile {
            digest: self.digest.clone(),
            spec: self.spec.clone(),
            total_jobs,
            shard: [shard, of],
            results,
        })
    }
}

/// Wall seconds of stepping per simulated second (`None` for runs that simulated no time).
pub fn cost_per_second(s: &Summary) -> Option<f64> {
    (s.simulated_seconds > 0.0).then(|| s.step_seconds / s.simulated_seconds)
}

/// Reference runs already made in this shard, by their override list.
#[derive(Default)]
struct ReferenceCache {
    runs: BTreeMap<String, Result<RunResult, String>>,
}

/// A job that ran but whose comparison could not be made.
fn failed(job: &Job, run: &RunResult, error: String) -> JobResult {
    JobResult {
        job: job.clone(),
        summary: Some(run.summary.clone()),
        error: Some(error),
        reference_error: None,
    }
}

/// RMS over `run`'s frames of the distance between its probe displacements and `reference`'s,
/// the reference interpolated linearly at the run's frame times (frames outside the reference's
/// time span are skipped). `None` when no frame or probe can be compared.
pub fn compare_to_reference(
    run: &RunResult,
    reference: &RunResult,
    probe: Option<&str>,
) -> Option<f64> {
    let times: Vec<f64> = reference.frame_times.iter().map(|f| f.1).collect();
    let (mut sum, mut count) = (0.0, 0usize);
    for (p, series) in run.probes.iter().zip(&run.probe_series) {
        if probe.is_some_and(|name| name != p.name) {
            continue;
        }
        let Some(reference_series) = reference.probe(&p.name) else {
            continue;
        };
        for (&(_, t), u) in run.frame_times.iter().zip(series) {
            let k = times.partition_point(|&s| s < t - 1e-12);
            let r = if k < times.len() && (times[k] - t).abs() <= 1e-12 {
                reference_series[k]
            } else if k == 0 || k >= times.len() {
                continue;
            } else {
                let w = (t - times[k - 1]) / (times[k] - times[k - 1]);
                let (a, b) = (reference_series[k - 1], reference_series[k]);
                [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])]
            };
            sum += (u[0] - r[0]).powi(2) + (u[1] - r[1]).powi(2);
            count += 1;
        }
    }
    (count > 0).then(|| (sum / count as f64).sqrt())
}

/// Parse `i/n`.
pub fn parse_shard(text: &str) -> Result<(usize, usize), String> {
    let (i, n) = text
        .split_once('/')
        .ok_or_else(|| format!("--shard {text:?}: expected i/n, e.g. 0/4"))?;
    let i: usize = i
        .trim()
        .parse()
        .map_err(|_| format!("--shard {text:?}: `{i}` is not a number"))?;
    let n: usize = n
        .trim()
        .parse()
        .map_err(|_| format!("--shard {text:?}: `{n}` is not a number"))?;
    if n == 0 || i >= n {
        return Err(format!("--shard {text:?}: expected 0 <= i < n"));
    }
    Ok((i, n))
}

/// The merged results of a sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Merged {
    /// Spec digest.
    pub digest: String,
    /// The spec.
    pub spec: SweepSpec,
    /// Every job's result, by job number.
    pub results: Vec<JobResult>,
}

/// Read shard files and join them. Fails (one line) on files from different specs, a job
/// present twice with different results, or missing jobs (listing the first few).
pub fn merge(paths: &[PathBuf]) -> Result<Merged, SceneError> {
    if paths.is_empty() {
        return Err(SceneError::Usage("merge: no shard files given".into()));
    }
    let mut first: Option<(String, SweepSpec, usize, PathBuf)> = None;
    let mut by_index: BTreeMap<usize, JobResult> = BTreeMap::new();
    for path in paths {
        let bytes = std::fs::read(path).map_err(|e| {
            SceneError::Io(format!(
                "{}: cannot read the shard file: {e}",
                path.display()
            ))
        })?;
        let shard: ShardFile =
            serde_json::from_slice(fem_mesh::io::strip_bom(&bytes)).map_err(|e| {
                SceneError::Scene(format!("{}: not a sweep shard file: {e}", path.display()))
            })?;
        // The digest is recomputed, not trusted: a spec edited in the file changes it.
        let recomputed = digest_of(&shard.spec);
        if recomputed != shard.digest {
            return Err(SceneError::Scene(format!(
                "{}: digest = {}: does not match the spec in the file (its digest is {recomputed}): the file was edited",
                path.display(),
                shard.digest
            )));
        }
        match &first {
            None => {
                first = Some((
                    shard.digest.clone(),
                    shard.spec.clone(),
                    shard.total_jobs,
                    path.clone(),
                ))
            }
            Some((digest, _, total, p0)) => {
                if *digest != shard.digest || *total != shard.total_jobs {
                    return Err(SceneError::Scene(format!(
                        "{}: digest = {}: comes from a different sweep spec than {} (digest {digest})",
                        path.display(),
                        shard.digest,
                        p0.display()
                    )));
                }
            }
        }
        let total = first.as_ref().map_or(0, |f| f.2);
        let expected = Sweep {
            digest: shard.digest.clone(),
            spec: shard.spec.clone(),
            origin: path.display().to_string(),
            base_dir: PathBuf::new(),
        }
        .jobs();
        if expected.len() != total {
            return Err(SceneError::Scene(format!(
                "{}: total_jobs = {}: the spec has {} jobs",
                path.display(),
                shard.total_jobs,
                expected.len()
            )));
        }
        for r in shard.results {
            if r.job.index >= total {
                return Err(SceneError::Scene(format!(
                    "{}: results.job.index = {}: out of range (the sweep has {total} jobs)",
                    path.display(),
                    r.job.index
                )));
            }
            if r.job != expected[r.job.index] {
                return Err(SceneError::Scene(format!(
                    "{}: job {}: parameters {:?} are not the spec's {:?}",
                    path.display(),
                    r.job.index,
                    r.job.params,
                    expected[r.job.index].params
                )));
            }
            if let Some(prev) = by_index.get(&r.job.index) {
                // The same job run twice (a shard run again) must agree in everything but
                // the timings.
                if let Some(field) = first_difference(prev, &r) {
                    return Err(SceneError::Scene(format!(
                        "{}: job {} appears twice with different results ({field} differs)",
                        path.display(),
                        r.job.index
                    )));
                }
                continue;
            }
            by_index.insert(r.job.index, r);
        }
    }
    let (digest, spec, total, _) = first.expect("at least one shard file");
    let missing: Vec<usize> = (0..total).filter(|i| !by_index.contains_key(i)).collect();
    if !missing.is_empty() {
        let shown: Vec<String> = missing.iter().take(10).map(|i| i.to_string()).collect();
        return Err(SceneError::Scene(format!(
            "merge: {} of {total} jobs are missing (first: {}); run the missing shards",
            missing.len(),
            shown.join(", ")
        )));
    }
    Ok(Merged {
        digest,
        spec,
        results: by_index.into_values().collect(),
    })
}

impl Merged {
    fn keys(&self) -> Vec<String> {
        self.results
            .first()
            .map(|r| r.job.params.iter().map(|p| p.0.clone()).collect())
            .unwrap_or_default()
    }

    /// CSV: job, swept keys, then the summary's main numbers and the probes' final
    /// displacements.
    pub fn to_csv(&self) -> String {
        let keys = self.keys();
        let probes: Vec<String> = self
            .results
            .iter()
            .find_map(|r| r.summary.as_ref())
            .map(|s| s.probes.iter().map(|p| p.name.clone()).collect())
            .unwrap_or_default();
        let mut out = String::from("job");
        for k in &keys {
            let _ = write!(out, ",{k}");
        }
        out.push_str(",stable,steps_completed,max_von_mises,min_det_f,inverted_elements,step_seconds,element_steps_per_second,real_time_factor");
        for p in &probes {
            let _ = write!(out, ",{p}.ux,{p}.uy");
        }
        out.push_str(",reference_error,cost_per_simulated_second,error\n");
        for r in &self.results {
            let _ = write!(out, "{}", r.job.index);
            for (_, v) in &r.job.params {
                let _ = write!(out, ",{}", shown(v).replace(',', ";"));
            }
            match &r.summary {
                Some(s) => {
                    let _ = write!(
                        out,
                        ",{},{},{},{},{},{},{},{}",
                        !s.blew_up,
                        s.steps_completed,
                        s.max_von_mises,
                        s.min_det_f,
                        s.inverted_elements,
                        s.step_seconds,
                        s.element_steps_per_second,
                        s.real_time_factor
                    );
                    for name in &probes {
                        match s.probes.iter().find(|p| &p.name == name) {
                            Some(p) => {
                                let _ = write!(
                                    out,
                                    ",{},{}",
                                    p.final_displacement[0], p.final_displacement[1]
                                );
                            }
                            None => out.push_str(",,"),
                        }
                    }
                    let _ = writeln!(
                        out,
                        ",{},{},\"{}\"",
                        r.reference_error.map(|e| e.to_string()).unwrap_or_default(),
                        cost_per_second(s)
                            .map(|c| c.to_string())
                            .unwrap_or_default(),
                        s.blow_up_message.as_deref().unwrap_or("").replace('"', "'")
                    );
                }
                None => {
                    out.push_str(&",".repeat(10 + 2 * probes.len()));
                    let _ = writeln!(
                        out,
                        ",\"{}\"",
                        r.error.as_deref().unwrap_or("").replace('"', "'")
                    );
                }
            }
        }
        out
    }

    /// When `solver.dt` is swept: for each combination of the other keys, the largest dt
    /// below which every swept dt stayed stable (`None` if even the smallest blew up), and
    /// the smallest that blew up.
    pub fn stability(&self) -> Option<Vec<StabilityRow>> {
        let keys = self.keys();
        let dt_pos = keys.iter().position(|k| k == "solver.dt")?;
        let mut groups: BTreeMap<Params, Vec<(f64, bool)>> = BTreeMap::new();
        for r in &self.results {
            let dt: f64 = r.job.params.get(dt_pos)?.1.parse().ok()?;
            let others: Vec<(String, String)> = r
                .job
                .params
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != dt_pos)
                .map(|(_, p)| p.clone())
                .collect();
            let stable = r.summary.as_ref().is_some_and(|s| !s.blew_up);
            groups.entry(others).or_default().push((dt, stable));
        }
        Some(
            groups
                .into_iter()
                .map(|(params, mut runs)| {
                    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let first_bad = runs.iter().position(|r| !r.1);
                    let stable_up_to = match first_bad {
                        Some(0) => None,
                        Some(k) => Some(runs[k - 1].0),
                        None => runs.last().map(|r| r.0),
                    };
                    StabilityRow {
                        params,
                        largest_stable_dt: stable_up_to,
                        smallest_unstable_dt: first_bad.map(|k| runs[k].0),
                    }
                })
                .collect(),
        )
    }

    /// Markdown: the table of jobs, and the stability table when `solver.dt` is swept.
    pub fn to_markdown(&self) -> String {
        let keys = self.keys();
        let mut out = format!(
            "Sweep of `{}` ({} jobs, spec digest {}).\n\n| job |",
            self.spec.scene,
            self.results.len(),
            self.digest
        );
        for k in &keys {
            let _ = write!(out, " {k} |");
        }
        out.push_str(" stable | steps | max von Mises (Pa) | min det F | element-steps/s |\n|");
        out.push_str(&"---|".repeat(keys.len() + 6));
        out.push('\n');
        for r in &self.results {
            let _ = write!(out, "| {} |", r.job.index);
            for (_, v) in &r.job.params {
                let _ = write!(out, " {} |", shown(v));
            }
            match &r.summary {
                Some(s) => {
                    let _ = writeln!(
                        out,
                        " {} | {} | {:.4e} | {:.4} | {:.3e} |",
                        if s.blew_up { "**no**" } else { "yes" },
                        s.steps_completed,
                        s.max_von_mises,
                        s.min_det_f,
                        s.element_steps_per_second
                    );
                }
                None => {
                    let _ = writeln!(
                        out,
                        " error: {} | | | | |",
                        r.error.as_deref().unwrap_or("")
                    );
                }
            }
        }
        if self.spec.reference.is_some() {
            out.push_str("\nAccuracy against the reference (");
            out.push_str(
                &self
                    .spec
                    .reference
                    .as_ref()
                    .map(|r| r.set.join(", "))
                    .unwrap_or_default(),
            );
            out.push_str("): RMS probe distance over the run's frames, and the cost of one simulated second.\n\n|");
            for k in &keys {
                let _ = write!(out, " {k} |");
            }
            out.push_str(" error (m) | wall s per simulated s |\n|");
            out.push_str(&"---|".repeat(keys.len() + 2));
            out.push('\n');
            for r in &self.results {
                out.push('|');
                for (_, v) in &r.job.params {
                    let _ = write!(out, " {} |", shown(v));
                }
                let e = r
                    .reference_error
                    .map_or("-".to_owned(), |e| format!("{e:.3e}"));
                let c = r
                    .summary
                    .as_ref()
                    .and_then(cost_per_second)
                    .map_or("-".to_owned(), |c| format!("{c:.3e}"));
                let _ = writeln!(out, " {e} | {c} |");
            }
        }
        if let Some(rows) = self.stability() {
            out.push_str(
                "\nLargest stable time step (every swept dt up to it stayed stable):\n\n|",
            );
            let others: Vec<&String> = keys.iter().filter(|k| *k != "solver.dt").collect();
            for k in &others {
                let _ = write!(out, " {k} |");
            }
            out.push_str(" largest stable dt (s) | smallest unstable dt (s) |\n|");
            out.push_str(&"---|".repeat(others.len() + 2));
            out.push('\n');
            for r in rows {
                out.push('|');
                for (_, v) in &r.params {
                    let _ = write!(out, " {} |", shown(v));
                }
                let f = |v: Option<f64>| v.map_or("-".to_owned(), |d| format!("{d:e}"));
                let _ = writeln!(
                    out,
                    " {} | {} |",
                    f(r.largest_stable_dt),
                    f(r.smallest_unstable_dt)
                );
            }
        }
        out
    }
}

/// Swept `(key, value)` pairs.
type Params = Vec<(String, String)>;

/// One row of the stability table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StabilityRow {
    /// The other swept keys and values.
    pub params: Vec<(String, String)>,
    /// Largest dt with every smaller swept dt stable, s.
    pub largest_stable_dt: Option<f64>,
    /// Smallest swept dt that blew up, s.
    pub smallest_unstable_dt: Option<f64>,
}

/// Write a shard file atomically.
pub fn write_shard(path: &Path, shard: &ShardFile) -> Result<(), SceneError> {
    let text = serde_json::to_string(shard)
        .map_err(|e| SceneError::Io(format!("{}: {e}", path.display())))?;
    write_atomic(path, text.as_bytes())
}
