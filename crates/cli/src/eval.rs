//! `pathlight eval SPEC.toml --out DIR`: runs an experiment (see `experiments/README.md`) with a
//! progress bar and writes `results.json`, plots, images and `report.html` into DIR. Ctrl-C
//! stops it, keeping the reference's checkpoint and writing what was measured.
//!
//! References can come from elsewhere: `--missing-references` lists those the cache lacks with
//! the `pathlight render` arguments and configuration that render them, `--import-references`
//! merges the parts of one (`render --samples A..B`) into the cache, checking their settings
//! hash against the listed one, and `--cluster` has the `pathlight-farm` driver do both over a
//! Dask cluster before the run.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Mutex;

use anyhow::{bail, Context, Result};
use clap::Args;
use pathlight_eval::experiment::{spec_dir, NeededReference, Progress, Runner, Setup};
use pathlight_eval::publish::publish;
use pathlight_eval::reference::ReferenceCache;
use pathlight_eval::spec::Spec;
use pathlight_render::checkpoint::Header;
use pathlight_render::part;

use crate::terminal::{ctrl_c_flag, progress_bar, thread_pool};
use crate::SceneArgs;

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Experiment spec (TOML); its paths are relative to its folder.
    #[arg(value_name = "SPEC")]
    pub spec: PathBuf,

    /// Output folder: results.json, plots/, images/ and report.html (needed unless only
    /// listing or importing references).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,

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

    /// Render the references the cache lacks on a Dask cluster first (the scheduler's address,
    /// e.g. tcp://HOST:8786, or `local` for a local cluster), through the `pathlight-farm`
    /// driver (python/pathlight_farm; found on PATH or in $PATHLIGHT_FARM), then run the
    /// experiment here. Workers need the scene files at the same paths.
    #[arg(long, value_name = "ADDRESS")]
    pub cluster: Option<String>,

    /// With --cluster: sample ranges (tasks) per reference.
    #[arg(long, value_name = "K", default_value_t = 16)]
    pub cluster_chunks: u32,

    /// Print the references the cache lacks as JSON (for each: its key, the `pathlight render`
    /// arguments and configuration that render it, and the settings hash of its parts), then
    /// stop.
    #[arg(long, conflicts_with_all = ["import_references", "cluster"])]
    pub missing_references: bool,

    /// Merge these partial renders (`render --samples A..B` of one reference listed by
    /// --missing-references) into the reference cache, then stop.
    #[arg(long, value_name = "PART", num_args = 1.., conflicts_with = "cluster")]
    pub import_references: Vec<PathBuf>,

    /// With --import-references: the time the reference took to render, in seconds (kept in
    /// its description).
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0)]
    pub render_seconds: f64,
}

pub fn run(args: &EvalArgs) -> Result<()> {
    let spec = Spec::load(&args.spec)?;
    let entries = selected_entries(args, &spec)?;
    if args.missing_references {
        let listed = entries
            .iter()
            .map(|(name, spec)| missing_references(args, name.as_deref(), spec))
            .collect::<Result<Vec<_>>>()?;
        let json = serde_json::json!({"references": listed.concat()});
        println!("{json}");
        return Ok(());
    }
    if !args.import_references.is_empty() {
        return import_references(args, &entries);
    }
    let Some(out_dir) = &args.out else {
        bail!(
            "{}: give the output folder with --out DIR",
            args.spec.display()
        );
    };
    if let Some(address) = &args.cluster {
        render_on_cluster(args, address)?;
    }
    let mut runs = Vec::new();
    for (name, spec) in &entries {
        let out = match name {
            Some(n) => out_dir.join(n),
            None => out_dir.clone(),
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

/// The spec's experiments (its `[[scenes]]` entries, or itself), `--only` applied.
fn selected_entries(args: &EvalArgs, spec: &Spec) -> Result<Vec<(Option<String>, Spec)>> {
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
    Ok(entries
        .into_iter()
        .filter(|(name, _)| {
            args.only.is_empty() || args.only.contains(name.as_ref().expect("named"))
        })
        .collect())
}

/// A runner of `spec` without progress output.
fn quiet_runner<'a>(args: &EvalArgs, spec: &'a Spec, cancel: &'a AtomicBool) -> Runner<'a> {
    Runner {
        spec,
        spec_dir: spec_dir(&args.spec),
        cache: ReferenceCache::new(&args.cache),
        progress: &|_| {},
        cancel,
    }
}

/// A reference of the experiment, as `pathlight render` renders it.
struct Planned {
    reference: NeededReference,
    /// `pathlight render` arguments that load the scene (absolute paths).
    scene_args: Vec<String>,
    /// The settings hash of its partial renders.
    settings: String,
}

/// The references of one experiment.
fn planned(args: &EvalArgs, spec: &Spec) -> Result<(Setup, Vec<Planned>)> {
    let cancel = AtomicBool::new(false);
    let runner = quiet_runner(args, spec, &cancel);
    let setup = runner.setup()?;
    let absolute = |p: PathBuf| {
        std::fs::canonicalize(&p).with_context(|| format!("{}: resolving the path", p.display()))
    };
    let mut options = spec.load_options(&runner.spec_dir);
    options.environment = options.environment.map(absolute).transpose()?;
    let scene = spec
        .scene_path(&runner.spec_dir)
        .map(absolute)
        .transpose()?;
    let scene_args = SceneArgs::new(scene, &options);
    let planned = runner
        .references(&setup)
        .into_iter()
        .map(|reference| {
            // What `pathlight render` puts in the header of each part of this reference.
            let header = Header {
                config: reference.config.clone(),
                scene: scene_args.identity(&setup.world),
                width: reference.config.width,
                height: reference.config.height,
                samples: None,
            };
            Planned {
                settings: part::settings_hash(&header),
                scene_args: scene_args.to_args(),
                reference,
            }
        })
        .collect();
    Ok((setup, planned))
}

/// `--missing-references`: one JSON object per reference the cache lacks.
fn missing_references(
    args: &EvalArgs,
    entry: Option<&str>,
    spec: &Spec,
) -> Result<Vec<serde_json::Value>> {
    let (_, planned) = planned(args, spec)?;
    planned
        .into_iter()
        .filter(|m| !m.reference.cached)
        .map(|m| {
            Ok(serde_json::json!({
                "entry": entry,
                "view": m.reference.view,
                "key": m.reference.key,
                "spp": m.reference.config.spp,
                "settings": m.settings,
                "render_args": m.scene_args,
                "config": toml::to_string(&m.reference.config)?,
            }))
        })
        .collect()
}

/// `--import-references`: merges the parts and stores them as the reference they belong to.
fn import_references(args: &EvalArgs, entries: &[(Option<String>, Spec)]) -> Result<()> {
    let mut settings = Vec::new();
    for path in &args.import_references {
        settings.push(part::load_header(path)?.settings);
    }
    let first = &args.import_references[0];
    if let Some(other) = settings.iter().position(|s| *s != settings[0]) {
        bail!(
            "{}: a part of another render than {} (settings {} and {}): import one reference at a time",
            args.import_references[other].display(),
            first.display(),
            settings[other],
            settings[0]
        );
    }
    for (_, spec) in entries {
        let (setup, planned) = planned(args, spec)?;
        let Some(m) = planned.iter().find(|m| m.settings == settings[0]) else {
            continue;
        };
        if m.reference.cached {
            eprintln!(
                "{}: reference {} is already in the cache",
                args.spec.display(),
                m.reference.key
            );
            return Ok(());
        }
        let (_, film) = part::merge(&args.import_references)?;
        ReferenceCache::new(&args.cache).store(
            &m.reference.key,
            &setup.identity,
            &m.reference.config,
            &film,
            args.render_seconds,
            spec.layer,
        )?;
        eprintln!(
            "{}: reference {} (view {}, {} spp) from {} parts",
            args.spec.display(),
            m.reference.key,
            m.reference.view + 1,
            m.reference.config.spp,
            args.import_references.len()
        );
        return Ok(());
    }
    bail!(
        "{}: not a part of any reference of {} (settings {}; see --missing-references)",
        first.display(),
        args.spec.display(),
        settings[0]
    )
}

/// `--cluster`: the `pathlight-farm` driver renders the missing references into the cache.
fn render_on_cluster(args: &EvalArgs, address: &str) -> Result<()> {
    let farm = std::env::var_os("PATHLIGHT_FARM").unwrap_or_else(|| "pathlight-farm".into());
    let binary = std::env::current_exe().context("finding the pathlight binary")?;
    let mut command = std::process::Command::new(&farm);
    command
        .arg("eval-references")
        .arg(&args.spec)
        .arg("--cache")
        .arg(&args.cache)
        .arg("--chunks")
        .arg(args.cluster_chunks.to_string())
        .arg("--binary")
        .arg(&binary);
    if address != "local" {
        command.arg("--scheduler").arg(address);
    }
    for name in &args.only {
        command.arg("--only").arg(name);
    }
    let status = match command.status() {
        Ok(status) => status,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => bail!(
            "--cluster: the {} driver is not installed (pip install python/pathlight_farm, or set PATHLIGHT_FARM to it)",
            farm.to_string_lossy()
        ),
        Err(e) => return Err(e).context(format!("running {}", farm.to_string_lossy())),
    };
    if !status.success() {
        bail!(
            "--cluster {address}: {} eval-references failed ({status})",
            farm.to_string_lossy()
        );
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
