//! `fem2d sweep` and `fem2d merge`: a parameter sweep split into shards that any batch
//! scheduler can run (a Slurm job array, GNU parallel), and the join of the shards' results.

use std::path::PathBuf;

use clap::Args;
use fem_cases::outdir::FilesInto;
use fem_cases::run::write_atomic;
use fem_cases::sweep::{load_sweep, merge, parse_shard, write_shard};

/// Flags of `fem2d sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// The sweep spec (TOML; see docs/sweeps.md).
    pub spec: PathBuf,
    /// Run shard i of n (jobs whose number is i modulo n), e.g. `--shard 3/16`.
    #[arg(long, default_value = "0/1")]
    pub shard: String,
    /// Worker threads per job (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Directory for the shard file `shard-I-of-N.json`.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Only list the jobs of this shard.
    #[arg(long)]
    pub list: bool,
}

/// Flags of `fem2d merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Shard files, or directories holding `shard-*.json` files.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Directory for sweep.json, sweep.csv and sweep.md.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

/// Runs `fem2d sweep`.
pub fn run_sweep(args: &SweepArgs) -> Result<(), String> {
    let (i, n) = parse_shard(&args.shard)?;
    let sweep = load_sweep(&args.spec).map_err(|e| e.to_string())?;
    let jobs = sweep.jobs();
    if args.list {
        for j in jobs.iter().filter(|j| j.index % n == i) {
            let params: Vec<String> = j.params.iter().map(|(k, v)| format!("{k}={v}")).collect();
            println!("{} {}", j.index, params.join(" "));
        }
        return Ok(());
    }
    let mine = jobs.iter().filter(|j| j.index % n == i).count();
    eprintln!(
        "sweep {} (digest {}): {} jobs in all, shard {i}/{n} runs {mine}",
        args.spec.display(),
        sweep.digest,
        jobs.len()
    );
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("{}: cannot create the directory: {e}", args.out.display()))?;
    let shard = sweep
        .run_shard(i, n, args.threads, |r| {
            let params: Vec<String> = r
                .job
                .params
                .iter()
                .map(|(k, v)| format!("{k}={v}"))
                .collect();
            let status = match (&r.summary, &r.error) {
                (Some(s), _) if s.blew_up => "blew up".to_owned(),
                (Some(s), _) => format!("ok ({:.3} s)", s.step_seconds),
                (None, Some(e)) => format!("error: {e}"),
                (None, None) => "?".to_owned(),
            };
            eprintln!("job {} {}: {status}", r.job.index, params.join(" "));
        })
        .map_err(|e| e.to_string())?;
    let path = args.out.join(format!("shard-{i}-of-{n}.json"));
    write_shard(&path, &shard).map_err(|e| e.to_string())?;
    println!("wrote {}", path.display());
    Ok(())
}

/// Runs `fem2d merge`.
pub fn run_merge(args: &MergeArgs) -> Result<(), String> {
    let mut files = Vec::new();
    for input in &args.inputs {
        if input.is_dir() {
            let mut found: Vec<PathBuf> = std::fs::read_dir(input)
                .map_err(|e| format!("{}: {e}", input.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.file_name()
                        .and_then(|n| n.to_str())
                        .is_some_and(|n| n.starts_with("shard-") && n.ends_with(".json"))
                })
                .collect();
            if found.is_empty() {
                return Err(format!(
                    "{}: no shard-*.json file in this directory",
                    input.display()
                ));
            }
            found.sort();
            files.extend(found);
        } else {
            files.push(input.clone());
        }
    }
    let merged = merge(&files).map_err(|e| e.to_string())?;
    // All three or none, sweep.json last (beside the shard files, which stay).
    let out = FilesInto::begin(&args.out).map_err(|e| e.to_string())?;
    let json = serde_json::to_string_pretty(&merged).map_err(|e| e.to_string())?;
    write_atomic(&out.path().join("sweep.json"), json.as_bytes()).map_err(|e| e.to_string())?;
    write_atomic(&out.path().join("sweep.csv"), merged.to_csv().as_bytes())
        .map_err(|e| e.to_string())?;
    let md = merged.to_markdown();
    write_atomic(&out.path().join("sweep.md"), md.as_bytes()).map_err(|e| e.to_string())?;
    out.commit(Some("sweep.json")).map_err(|e| e.to_string())?;
    print!("{md}");
    println!(
        "merged {} shard file(s), {} jobs; wrote sweep.json, sweep.csv, sweep.md in {}",
        files.len(),
        merged.results.len(),
        args.out.display()
    );
    Ok(())
}
