//! `pathlight`: the command-line front end of the path tracer.
//!
//! One subcommand per job: `info`, `render`, `view`, `play`, `eval` and `bench`, each
//! flattening the shared [`SceneArgs`] (so that every command loads scenes the same way) and,
//! where it renders, [`config_args::ConfigArgs`] (one configuration type for all).
//!
//! Exit codes: 0 on success, 2 on any error (a usage error reported by clap, or a failed command,
//! printed to stderr as `error: <message>`).

mod bench;
mod config_args;
mod eval;
mod info;
mod memory;
mod merge;
mod play;
mod render;
mod scene_args;
mod terminal;
mod view;

use std::io::Write;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub use scene_args::SceneArgs;

/// pathlight: a real-time CPU path tracer.
#[derive(Debug, Parser)]
#[command(name = "pathlight", version, about, propagate_version = true)]
pub struct Cli {
    /// More log output on stderr: -v for info, -vv for debug, -vvv for trace (warnings are
    /// always shown; RUST_LOG overrides this).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,

    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Load a scene and print its statistics (counts, bounds, load time, peak memory).
    Info(info::InfoArgs),
    /// Render an image with the reference path tracer (the built-in Cornell box without a
    /// scene).
    Render(render::RenderArgs),
    /// Combine the partial renders of one render (`render --samples A..B --out PART.part`)
    /// into its image, exactly.
    Merge(merge::MergeArgs),
    /// Run an experiment (TOML spec): error against references over samples and time, with
    /// plots and an HTML report.
    Eval(eval::EvalArgs),
    /// Open the interactive viewer: the real-time pipeline live, with a toggle and parameters
    /// for every pass (the built-in Cornell box without a scene).
    View(view::ViewArgs),
    /// Render a scripted camera path frame by frame through the real-time pipeline (the
    /// viewer's headless twin): frames and per-pass timings.
    Play(play::PlayArgs),
    /// Measure: `bench rays` times the ray tracing backends on fixed ray sets; `bench frame`
    /// times the real-time frame pipeline.
    Bench(bench::BenchArgs),
}

fn init_logging(verbose: u8) {
    let level = match verbose {
        0 => "warn",
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    let show_target = verbose >= 2;
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(level))
        .format(move |buf, record| {
            let level = match record.level() {
                log::Level::Error => "error",
                log::Level::Warn => "warning",
                log::Level::Info => "info",
                log::Level::Debug => "debug",
                log::Level::Trace => "trace",
            };
            if show_target {
                writeln!(buf, "{level} [{}]: {}", record.target(), record.args())
            } else {
                writeln!(buf, "{level}: {}", record.args())
            }
        })
        .init();
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Info(args) => info::run(&args),
        Command::Bench(args) => bench::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Merge(args) => merge::run(&args),
        Command::Eval(args) => eval::run(&args),
        Command::Play(args) => play::run(&args),
        Command::View(args) => view::run(&args),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.verbose);
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // `{:#}` prints the whole context chain on one line; a SceneError already names the
            // file at fault.
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn verbose_is_global() {
        let cli = Cli::try_parse_from(["pathlight", "info", "-vv", "--json"]).unwrap();
        assert_eq!(cli.verbose, 2);
        let Command::Info(args) = cli.command else {
            panic!("not info")
        };
        assert!(args.json);
        assert!(args.scene.scene.is_none());
    }

    #[test]
    fn bench_rays_options() {
        let cli = Cli::try_parse_from([
            "pathlight",
            "bench",
            "rays",
            "room.glb",
            "--backend",
            "native",
            "--threads",
            "2",
            "--width",
            "64",
            "--repeat",
            "3",
            "--json",
        ])
        .unwrap();
        let Command::Bench(b) = cli.command else {
            panic!("not bench")
        };
        let bench::BenchCommand::Rays(r) = b.command else {
            panic!("not bench rays")
        };
        assert_eq!(r.backend, bench::BackendChoice::Native);
        assert_eq!(
            (r.threads, r.width, r.height, r.repeat),
            (Some(2), 64, 1024, 3)
        );
        assert!(r.json);
        assert_eq!(
            r.scene.scene.as_deref(),
            Some(std::path::Path::new("room.glb"))
        );
    }
}
