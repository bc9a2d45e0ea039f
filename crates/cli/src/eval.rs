//! `pathlight eval SPEC.toml --out DIR`: runs an experiment (see `experiments/README.md`) with a
//! progress bar and writes `results.json`, plots, images and `report.html` into DIR. Ctrl-C
//! stops it, keeping the reference's checkpoint and writing what was measured.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::{bail, Result};
use clap::Args;
use pathlight_eval::experiment::{spec_dir, Progress, Runner};
use pathlight_eval::publish::publish;
use pathlight_eval::reference::ReferenceCache;
use pathlight_eval::spec::Spec;

use crate::terminal::{ctrl_c_flag, progress_bar, thread_pool};

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Experiment spec (TOML); its paths are relative to its folder.
    #[arg(value_name = "SPEC")]
    pub spec: PathBuf,

    /// Output folder: results.json, plots/, images/ and report.html.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Where references are cached (and their checkpoints kept).
    #[arg(long, value_name = "DIR", default_value = ".pathlight-cache")]
    pub cache: PathBuf,

    /// Worker threads [default: all cores].
    #[arg(long, value_name = "T")]
    pub threads: Option<usize>,

    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,

    /// Print one JSON object with the output paths and the slopes as the last line.
    #[arg(long)]
    pub json: bool,

    /// With `[[scenes]]`: run only these entries (repeat, or separate with commas); each
    /// writes into DIR/NAME.
    #[arg(long, value_name = "NAME", value_delimiter = ',')]
    pub only: Vec<String>,
}

pub fn run(args: &EvalArgs) -> Result<()> {
    let spec = Spec::load(&args.spec)?;
    let entries = spec
        .entries()
        .map_err(|m| anyhow::anyhow!("{}: {m}", args.spec.display()))?;
    for name in &args.only {
        if !entries
            .iter()
            .any(|(n, _)| n.as_deref() == Some(name.as_str()))
        {
            let known: Vec<&str> = entries.iter().filter_map(|(n, _)| n.as_deref()).collect();
            bail!(
                "{}: --only {name:?}: no such [[scenes]] entry (there are: {})",
                args.spec.display(),
                if known.is_empty() {
                    "none".to_owned()
                } else {
                    known.join(", ")
                }
            );
        }
    }
    let mut runs = Vec::new();
    for (name, spec) in &entries {
        if !args.only.is_empty() && !args.only.contains(name.as_ref().expect("named")) {
            continue;
        }
        let out = match name {
            Some(n) => args.out.join(n),
            None => args.out.clone(),
        };
        let json = run_one(args, spec, &out)?;
        runs.push((name.clone(), out, json));
    }
    if args.json {
        let json = match runs.as_slice() {
            [(None, _, one)] => one.clone(),
            _ => serde_json::json!({
                "entries": runs
                    .iter()
                    .map(|(n, _, j)| serde_json::json!({"name": n, "result": j}))
                    .collect::<Vec<_>>(),
            }),
        };
        println!("{json}");
    }
    Ok(())
}

/// Runs one experiment of the spec into `out`; its JSON summary.
fn run_one(args: &EvalArgs, spec: &Spec, out: &Path) -> Result<serde_json::Value> {
    let pool = thread_pool(args.threads)?;
    let cancel = ctrl_c_flag();
    let bar = progress_bar(
        args.quiet || args.json,
        1,
        "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% {msg} ETA {eta}",
    );
    let task = Mutex::new(String::new());
    let progress = |p: &Progress| {
        let mut t = task.lock().expect("not poisoned");
        if *t != p.task {
            *t = p.task.to_owned();
            bar.reset();
            bar.set_message(p.task.to_owned());
        }
        bar.set_length(p.total.max(1));
        bar.set_position(p.done);
    };
    let runner = Runner {
        spec,
        spec_dir: spec_dir(&args.spec),
        cache: ReferenceCache::new(&args.cache),
        progress: &progress,
        cancel: &cancel,
    };
    let outcome = pool.install(|| runner.run())?;
    bar.finish_and_clear();
    let report = publish(&outcome, out)?;
    let results = &outcome.results;
    if !results.complete {
        bail!(
            "stopped: what was measured is in {} (a reference in progress continues from its checkpoint in {} next time)",
            out.display(),
            args.cache.display()
        );
    }
    eprintln!(
        "{}: {} measurements, report {}",
        spec.name,
        results.measurements.len(),
        report.display()
    );
    for s in &results.slopes {
        eprintln!(
            "  {:<24} {:<8} slope against {:<3} {:+.3}",
            s.configuration, s.metric, s.against, s.slope
        );
    }
    Ok(serde_json::json!({
        "results": out.join("results.json"),
        "report": report,
        "slopes": results.slopes,
    }))
}
