//! `pathlight render`: a converged image from the reference path tracer, with a progress bar,
//! Ctrl-C that keeps what is done, periodic checkpoints and `--resume`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::Args;
use pathlight_render::checkpoint::{self, Header};
use pathlight_render::denoise::Method;
use pathlight_render::output::{write_atomic, Channels};
use pathlight_render::output::{write_film, write_rgb, Format};
use pathlight_render::part::{self, PartHeader};
use pathlight_render::renderer::{pass_targets, render_range_pass};
use pathlight_render::{Camera, Config, Film, World};

use crate::config_args::{check, ConfigArgs};
use crate::memory::{peak_rss_bytes, peak_rss_text};
use crate::terminal::{ctrl_c_flag, progress_bar, thread_pool};
use crate::SceneArgs;

/// Most samples per pixel in one pass (checkpoint and Ctrl-C granularity).
const MAX_PASS: u32 = 16;

#[derive(Debug, Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,

    #[command(flatten)]
    pub settings: ConfigArgs,

    /// Output image: .png (tone-mapped sRGB) or .exr (linear HDR RGB).
    #[arg(long, value_name = "FILE", default_value = "render.png")]
    pub out: PathBuf,

    /// Worker threads [default: all cores].
    #[arg(long, value_name = "T")]
    pub threads: Option<usize>,

    /// With an .exr output: also write albedo, normal, depth, direct, indirect, variance and
    /// spp layers.
    #[arg(long)]
    pub aovs: bool,

    /// Checkpoint file [default: OUT with `.checkpoint` appended].
    #[arg(long, value_name = "FILE")]
    pub checkpoint: Option<PathBuf>,

    /// Seconds between checkpoints (0: only when stopped by Ctrl-C).
    #[arg(long, value_name = "SECONDS", default_value_t = 60.0)]
    pub checkpoint_every: f64,

    /// Continue from the checkpoint (same scene and settings; --spp may grow).
    #[arg(long)]
    pub resume: bool,

    /// Trace only sample indices A..B of every pixel (of the --spp of the whole render) and
    /// write a partial render to --out PART.part, for `pathlight merge` (renders split over
    /// machines).
    #[arg(long, value_name = "A..B")]
    pub samples: Option<SampleRange>,

    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,

    /// Print one JSON object with the timings and memory as the last line.
    #[arg(long)]
    pub json: bool,
}

/// `A..B`: sample indices A (included) to B (excluded).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleRange {
    pub start: u32,
    pub end: u32,
}

impl std::str::FromStr for SampleRange {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("{s:?}: expected A..B with whole numbers A < B, e.g. 0..64");
        let (a, b) = s.split_once("..").ok_or_else(bad)?;
        let (start, end) = (
            a.trim().parse().map_err(|_| bad())?,
            b.trim().parse().map_err(|_| bad())?,
        );
        if start >= end {
            return Err(bad());
        }
        Ok(Self { start, end })
    }
}

/// True for a `.part` output path.
fn is_part(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("part"))
}

impl RenderArgs {
    /// The render configuration for a scene whose camera has aspect ratio `aspect`: 512
    /// pixels wide, the height from the aspect ratio (square without one), 64 samples per
    /// pixel, unlimited bounces, unless the options say otherwise.
    fn config(&self, aspect: Option<f32>) -> Result<Config> {
        let base = Config {
            width: 512,
            height: 0,
            spp: 64,
            ..Config::default()
        };
        let frame_only = self.settings.frame_only_flags();
        if !frame_only.is_empty() {
            bail!(
                "{}: `render` is the reference path tracer and runs none of the frame pipeline's stages; these options are for view, play, bench frame and eval",
                frame_only.join(", ")
            );
        }
        let mut config = self.settings.apply(base)?;
        if config.frame.filter.method.in_frame() {
            bail!(
                "--filter {}: `render` is the reference path tracer; the real-time filters run in view, play, bench frame and eval (render filters with rpf only)",
                serde_json::to_value(config.frame.filter.method)?.as_str().unwrap_or("?")
            );
        }
        if config.height == 0 {
            let a = aspect.filter(|a| a.is_finite() && *a > 0.0).unwrap_or(1.0);
            config.height = ((config.width as f32 / a).round() as u32).max(1);
        }
        check(&config)?;
        Ok(config)
    }

    fn checkpoint_path(&self) -> PathBuf {
        self.checkpoint.clone().unwrap_or_else(|| {
            let mut s = self.out.clone().into_os_string();
            s.push(".checkpoint");
            PathBuf::from(s)
        })
    }
}

pub fn run(args: &RenderArgs) -> Result<()> {
    match (args.samples, is_part(&args.out)) {
        (Some(_), true) => {}
        (Some(_), false) => bail!(
            "{}: --samples writes a partial render: give --out a .part file (then `pathlight merge`)",
            args.out.display()
        ),
        (None, true) => bail!(
            "{}: a .part output is a partial render: give the sample range with --samples A..B",
            args.out.display()
        ),
        (None, false) => {
            pathlight_render::output::Format::from_path(&args.out)?;
        }
    }
    let pool = thread_pool(args.threads)?;
    pool.install(|| render(args))
}

fn render(args: &RenderArgs) -> Result<()> {
    let start = Instant::now();
    let scene = pathlight_scene::load(args.scene.scene.as_deref(), &args.scene.load_options())?;
    let aspect = scene.cameras.first().and_then(|c| match c.projection {
        pathlight_scene::Projection::Perspective { aspect, .. } => aspect,
        pathlight_scene::Projection::Orthographic { xmag, ymag, .. } => Some(xmag / ymag),
    });
    let config = args.config(aspect)?;
    let world = World::new(scene, config.light_selection);
    let setup_ms = start.elapsed().as_secs_f64() * 1e3;
    let camera = config.render_camera(&world);
    if config.frame.filter.method == Method::Rpf {
        return render_rpf(args, &world, &camera, &config, setup_ms);
    }
    let header = Header {
        config: config.clone(),
        scene: args.scene.identity(&world),
        width: config.width,
        height: config.height,
        samples: args.samples.map(|r| [r.start, r.end]),
    };
    let (first, count) = match args.samples {
        Some(r) if r.end > config.spp => bail!(
            "--samples {}..{}: the range ends past the render's --spp {}",
            r.start,
            r.end,
            config.spp
        ),
        Some(r) => (r.start, r.end - r.start),
        None => (0, config.spp),
    };
    let checkpoint_path = args.checkpoint_path();
    let mut film = if args.resume {
        let (old, film) = checkpoint::load(&checkpoint_path)?;
        if !old.compatible(&header) {
            bail!(
                "{}: the checkpoint belongs to another scene or other settings (only --spp may change)\n  checkpoint: {}\n  now:        {}",
                checkpoint_path.display(),
                serde_json::to_string(&old)?,
                serde_json::to_string(&header)?
            );
        }
        log::info!(
            "resuming from {} ({} samples done)",
            checkpoint_path.display(),
            film.samples()
        );
        film
    } else {
        Film::new(config.width, config.height)
    };

    // A second Ctrl-C while the output is written is ignored.
    let cancel = ctrl_c_flag();
    let total = config.width as u64 * config.height as u64 * count as u64;
    let bar = progress_bar(
        args.quiet || args.json,
        total,
        "{spinner} [{elapsed_precise}] {bar:40} {percent:>3}% {msg} ETA {eta}",
    );
    let done = AtomicU64::new(film.samples().min(total));
    bar.set_position(done.load(Ordering::Relaxed));
    let render_start = Instant::now();
    let mut last_checkpoint = Instant::now();
    let every = Duration::from_secs_f64(args.checkpoint_every.max(0.0));
    let mut complete = true;
    for target in pass_targets(film.min_samples(), count, MAX_PASS) {
        let progress = |n| {
            let d = done.fetch_add(n, Ordering::Relaxed) + n;
            bar.set_position(d);
        };
        let finished = render_range_pass(
            &world, &camera, &config, &mut film, first, target, &cancel, &progress,
        );
        bar.set_message(format!("{target}/{count} spp"));
        if !finished {
            complete = false;
            break;
        }
        if args.checkpoint_every > 0.0 && last_checkpoint.elapsed() >= every {
            checkpoint::save(&checkpoint_path, &header, &film)?;
            last_checkpoint = Instant::now();
        }
    }
    let render_s = render_start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    if args.samples.is_none() {
        write_film(&args.out, &film, args.aovs, &config.display)?;
    } else if complete {
        part::save(
            &args.out,
            &PartHeader::new(&header, first, first + count),
            &film,
        )?;
    }
    if !complete && args.samples.is_some() {
        checkpoint::save(&checkpoint_path, &header, &film)?;
        bail!(
            "stopped: no partial render written (a part holds its whole range); continue with --resume (checkpoint {})",
            checkpoint_path.display()
        );
    }
    if !complete {
        checkpoint::save(&checkpoint_path, &header, &film)?;
        bail!(
            "stopped: {} written with {} of {} samples per pixel on average; continue with --resume (checkpoint {})",
            args.out.display(),
            film.samples() / (config.width as u64 * config.height as u64),
            config.spp,
            checkpoint_path.display()
        );
    }
    if checkpoint_path.exists() && args.checkpoint.is_none() {
        // The render is complete: the default checkpoint has served its purpose.
        std::fs::remove_file(&checkpoint_path).with_context(|| {
            format!(
                "{}: removing the finished checkpoint",
                checkpoint_path.display()
            )
        })?;
    }
    let samples = film.samples();
    let peak = peak_rss_bytes();
    let what = match args.samples {
        Some(r) => format!("samples {}..{} of {} spp", r.start, r.end, config.spp),
        None => format!("{} spp", config.spp),
    };
    eprintln!(
        "{}: {}x{} at {what} in {:.2} s ({:.2} M samples/s), setup {:.0} ms, peak memory {}",
        args.out.display(),
        config.width,
        config.height,
        render_s,
        samples as f64 / render_s / 1e6,
        setup_ms,
        peak_rss_text(peak)
    );
    if args.json {
        let json = serde_json::json!({
            "out": args.out,
            "width": config.width,
            "height": config.height,
            "spp": config.spp,
            "seed": config.seed,
            "threads": rayon::current_num_threads(),
            "setup_ms": setup_ms,
            "render_s": render_s,
            "samples_per_s": samples as f64 / render_s,
            "peak_rss_bytes": peak,
        });
        println!("{json}");
    }
    Ok(())
}

/// `render --filter rpf`: traces every sample into RPF's vectors, filters them, writes the
/// filtered image (with --aovs and .exr, the unfiltered mean of the same samples as the layer
/// `unfiltered`). Ctrl-C while tracing writes nothing (RPF needs every sample); while
/// filtering, the unfiltered image of the traced samples. No checkpoints.
fn render_rpf(
    args: &RenderArgs,
    world: &World,
    camera: &Camera,
    config: &Config,
    setup_ms: f64,
) -> Result<()> {
    if args.samples.is_some() || args.resume {
        bail!("--filter rpf filters the whole render at once: no --samples or --resume");
    }
    if config.spp > pathlight_render::denoise::rpf::MAX_SPP {
        bail!(
            "--spp {}: RPF filters at most {} samples per pixel (the paper uses 8)",
            config.spp,
            pathlight_render::denoise::rpf::MAX_SPP
        );
    }
    let cancel = ctrl_c_flag();
    let bar = progress_bar(
        args.quiet || args.json,
        1000,
        "{spinner} [{elapsed_precise}] {bar:40} {percent:>3}% RPF {msg} ETA {eta}",
    );
    let progress = |f: f32| bar.set_position((f.clamp(0.0, 1.0) * 1000.0) as u64);
    let rendered = pathlight_render::rpf::render(world, camera, config, &cancel, &progress)?;
    bar.finish_and_clear();
    let Some(r) = rendered else {
        bail!("stopped while tracing: RPF needs every sample; nothing written");
    };
    let (w, h) = (config.width, config.height);
    let Some(filtered) = &r.filtered else {
        write_rgb(&args.out, w, h, &r.unfiltered, &config.display)?;
        bail!(
            "stopped while filtering: {} holds the unfiltered image of the {} samples per pixel (RPF cannot resume; run it again to filter)",
            args.out.display(),
            config.spp
        );
    };
    if args.aovs && Format::from_path(&args.out)? == Format::Exr {
        let mut ch = Channels::new(w, h);
        ch.add_rgb("", ["R", "G", "B"], filtered);
        ch.add_rgb("unfiltered", ["R", "G", "B"], &r.unfiltered);
        let bytes = ch
            .encode_exr()
            .map_err(|e| anyhow::anyhow!("{}: {e}", args.out.display()))?;
        write_atomic(&args.out, &bytes)?;
    } else {
        write_rgb(&args.out, w, h, filtered, &config.display)?;
    }
    let peak = peak_rss_bytes();
    eprintln!(
        "{}: {w}x{h} at {} spp, RPF: tracing {:.2} s, filter {:.2} s, setup {setup_ms:.0} ms, peak memory {}",
        args.out.display(),
        config.spp,
        r.trace_ms / 1e3,
        r.filter_ms / 1e3,
        peak_rss_text(peak)
    );
    if args.json {
        let json = serde_json::json!({
            "out": args.out,
            "width": w,
            "height": h,
            "spp": config.spp,
            "seed": config.seed,
            "threads": rayon::current_num_threads(),
            "setup_ms": setup_ms,
            "trace_ms": r.trace_ms,
            "filter_ms": r.filter_ms,
            "peak_rss_bytes": peak,
        });
        println!("{json}");
    }
    Ok(())
}
