//! `pathlight bench`: measurements. `bench rays` times the ray tracing backends on fixed ray
//! sets (camera, diffuse bounce and shadow rays) and checks that they agree ray by ray;
//! `bench frame` times the real-time frame pipeline along a short orbit, pass by pass.

use std::time::Instant;

use anyhow::{bail, Result};
use clap::{Args, Subcommand, ValueEnum};
use pathlight_accel::recorder::{Query, Recorder};
use pathlight_accel::{Accel, Hit, NativeBvh, Ray, RayKind, RaySets, SceneTriangles};
use rayon::prelude::*;
use serde_json::json;

use crate::config_args::ConfigArgs;
use crate::scene_args::SceneArgs;

#[derive(Debug, Clone, Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub command: BenchCommand,
}

#[derive(Debug, Clone, Subcommand)]
pub enum BenchCommand {
    /// Trace fixed ray sets (primary, bounce, shadow) with each backend: build time, memory,
    /// median Mrays/s, and ray-by-ray agreement between the backends.
    Rays(RaysArgs),
    /// Render frames along a short orbit with the real-time configuration: per-pass and
    /// per-frame times (medians) and Mrays/s.
    Frame(Box<FrameArgs>),
}

#[derive(Debug, Clone, Args)]
pub struct FrameArgs {
    #[command(flatten)]
    pub scene: SceneArgs,

    #[command(flatten)]
    pub settings: ConfigArgs,

    /// Frames measured (after two warm-up frames).
    #[arg(long, value_name = "N", default_value_t = 60)]
    pub frames: u32,

    /// Degrees the camera orbits over the measured frames (every frame is a new view, so
    /// nothing accumulates).
    #[arg(long, value_name = "DEGREES", default_value_t = 30.0)]
    pub orbit: f32,

    /// Worker threads [default: all cores].
    #[arg(long, value_name = "T")]
    pub threads: Option<usize>,

    /// Print one JSON object as the last line (`ms_per_frame`, `fps`, `mrays_per_s`,
    /// `passes`, `floor_ms`, `frame_over_floor`, ...).
    #[arg(long)]
    pub json: bool,

    /// Skip the floor: by default the orbit is rendered a second time with every ray
    /// recorded, and each frame's rays are traced again alone through the accelerator (by
    /// kind: primary, closest, shadow); their median time is the frame's floor.
    #[arg(long)]
    pub no_floor: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BackendChoice {
    /// pathlight's own BVH.
    Native,
    /// Intel Embree 3 (needs a build with the `embree` feature).
    Embree,
    /// Every backend compiled in.
    All,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EmbreeQuality {
    Low,
    Medium,
    High,
}

#[derive(Debug, Clone, Args)]
pub struct RaysArgs {
    #[command(flatten)]
    pub scene: SceneArgs,

    /// Which backend to measure.
    #[arg(long, value_enum, default_value_t = BackendChoice::All)]
    pub backend: BackendChoice,

    /// Threads tracing (and building): a pool of exactly this many [default: all cores].
    #[arg(long, value_name = "T")]
    pub threads: Option<usize>,

    /// Image width: one primary ray per pixel.
    #[arg(long, value_name = "W", default_value_t = 1024)]
    pub width: u32,

    /// Image height.
    #[arg(long, value_name = "H", default_value_t = 1024)]
    pub height: u32,

    /// Times each set is traced; the median is reported.
    #[arg(long, value_name = "R", default_value_t = 5)]
    pub repeat: usize,

    /// Seed of the bounce directions and light samples.
    #[arg(long, value_name = "S", default_value_t = 0)]
    pub seed: u64,

    /// Embree's build quality: low, medium (Embree's default) or high (spatial splits).
    #[arg(long, value_enum, value_name = "Q", default_value_t = EmbreeQuality::High)]
    pub embree_quality: EmbreeQuality,

    /// Build Embree without RTC_SCENE_FLAG_ROBUST (faster, not watertight; Embree's default).
    #[arg(long)]
    pub embree_no_robust: bool,

    /// Also trace each set through the backends' batch queries (`intersect_batch`,
    /// `occluded_batch`; chunks of 256 rays), reported as `BACKEND/batch`, side by side with the
    /// one-ray-per-call runs: the native BVH traces coherent closest-hit rays eight at a time
    /// as packets.
    #[arg(long)]
    pub batch: bool,

    /// Print one JSON object per (backend, kind) on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &BenchArgs) -> Result<()> {
    match &args.command {
        BenchCommand::Rays(a) => run_rays(a),
        BenchCommand::Frame(a) => run_frame(a),
    }
}

/// Backend names compiled into this binary.
pub fn compiled_backends() -> Vec<&'static str> {
    let mut v = vec!["native"];
    if cfg!(feature = "embree") {
        v.push("embree");
    }
    v
}

fn selected_backends(choice: BackendChoice) -> Result<Vec<&'static str>> {
    Ok(match choice {
        BackendChoice::Native => vec!["native"],
        BackendChoice::Embree => {
            if !cfg!(feature = "embree") {
                bail!(
                    "backend embree: pathlight was built without the embree feature \
                     (rebuild with `--features embree`; it needs libembree-dev)"
                );
            }
            vec!["embree"]
        }
        BackendChoice::All => compiled_backends(),
    })
}

/// Builds a backend other than the native one.
fn build_other(name: &str, tris: &SceneTriangles, args: &RaysArgs) -> Result<Box<dyn Accel>> {
    match name {
        #[cfg(feature = "embree")]
        "embree" => {
            use pathlight_accel::embree3::BuildQuality;
            let options = pathlight_accel::EmbreeOptions {
                quality: match args.embree_quality {
                    EmbreeQuality::Low => BuildQuality::LOW,
                    EmbreeQuality::Medium => BuildQuality::MEDIUM,
                    EmbreeQuality::High => BuildQuality::HIGH,
                },
                robust: !args.embree_no_robust,
                ..Default::default()
            };
            log::info!("embree: {}", options.describe());
            Ok(Box::new(pathlight_accel::EmbreeAccel::with_options(
                tris, options,
            )?))
        }
        _ => {
            let _ = (tris, args);
            bail!("unknown backend {name}")
        }
    }
}

/// Results of one set, for the agreement check.
enum Results {
    Hits(Vec<Option<Hit>>),
    Occluded(Vec<bool>),
}

/// Rays per work item handed to the pool.
const CHUNK: usize = 256;

/// Traces `rays` once on the current pool: one ray per backend call, or with `batch` a chunk
/// per call of the batch queries.
fn trace(accel: &dyn Accel, kind: RayKind, rays: &[Ray], out: &mut Results, batch: bool) {
    match out {
        Results::Hits(h) => h
            .par_chunks_mut(CHUNK)
            .zip(rays.par_chunks(CHUNK))
            .for_each(|(h, r)| {
                if batch {
                    accel.intersect_batch(r, h);
                } else {
                    for (h, r) in h.iter_mut().zip(r) {
                        *h = accel.intersect(r);
                    }
                }
            }),
        Results::Occluded(o) => o
            .par_chunks_mut(CHUNK)
            .zip(rays.par_chunks(CHUNK))
            .for_each(|(o, r)| {
                if batch {
                    accel.occluded_batch(r, o);
                } else {
                    for (o, r) in o.iter_mut().zip(r) {
                        *o = accel.occluded(r);
                    }
                }
            }),
    }
    debug_assert_eq!(kind.is_occlusion(), matches!(out, Results::Occluded(_)));
}

fn empty_results(kind: RayKind, n: usize) -> Results {
    if kind.is_occlusion() {
        Results::Occluded(vec![false; n])
    } else {
        Results::Hits(vec![None; n])
    }
}

pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Two closest-hit answers agree: both miss, the same triangle, or distances within
/// `1e-4 * max(1, |t|)` (near-ties between triangles).
pub fn hits_agree(a: &Option<Hit>, b: &Option<Hit>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(x), Some(y)) => {
            (x.instance, x.triangle) == (y.instance, y.triangle)
                || (x.t - y.t).abs() <= 1e-4 * x.t.abs().max(1.0)
        }
        _ => false,
    }
}

/// Counts the rays where `a` and `b` disagree; logs the first few at info level (`-v`).
fn mismatches(
    backend: &str,
    reference: &str,
    kind: RayKind,
    rays: &[Ray],
    a: &Results,
    b: &Results,
) -> usize {
    let bad: Vec<usize> = match (a, b) {
        (Results::Hits(a), Results::Hits(b)) => (0..rays.len())
            .filter(|&i| !hits_agree(&a[i], &b[i]))
            .collect(),
        (Results::Occluded(a), Results::Occluded(b)) => {
            (0..rays.len()).filter(|&i| a[i] != b[i]).collect()
        }
        _ => unreachable!("results of different kinds"),
    };
    for &i in bad.iter().take(5) {
        let (x, y) = match (a, b) {
            (Results::Hits(a), Results::Hits(b)) => (format!("{:?}", a[i]), format!("{:?}", b[i])),
            (Results::Occluded(a), Results::Occluded(b)) => {
                (format!("occluded {}", a[i]), format!("occluded {}", b[i]))
            }
            _ => unreachable!(),
        };
        log::info!(
            "{kind} ray {i} {:?}: {backend} {x}, {reference} {y}",
            rays[i],
            kind = kind.name()
        );
    }
    bad.len()
}

/// One (backend, kind) measurement.
struct Row {
    backend: String,
    kind: RayKind,
    rays: usize,
    mrays_per_s: f64,
    /// Slowest and fastest repeat, Mrays/s.
    range: (f64, f64),
    build_ms: f64,
    memory_bytes: usize,
    mismatches: usize,
}

fn run_rays(args: &RaysArgs) -> Result<()> {
    let backends = selected_backends(args.backend)?;
    let threads = match args.threads {
        Some(0) => bail!("--threads must be at least 1"),
        Some(t) => t,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    if args.width == 0 || args.height == 0 {
        bail!("--width and --height must be at least 1");
    }
    if args.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    let pool = crate::terminal::thread_pool(Some(threads))?;

    let options = args.scene.load_options();
    let path = args.scene.scene.as_deref();
    let start = Instant::now();
    let scene = pathlight_scene::load(path, &options)?;
    log::info!(
        "loaded {} in {:.0} ms",
        path.map_or("the built-in Cornell box".into(), |p| p
            .display()
            .to_string()),
        start.elapsed().as_secs_f64() * 1e3
    );
    let tris = SceneTriangles::from_scene(&scene);
    let mtri = tris.len() as f64 / 1e6;

    // The native BVH is the reference: it finds the hits the bounce and shadow rays start
    // from, and every other backend is checked against its answers.
    let start = Instant::now();
    let native = pool.install(|| NativeBvh::new(&tris));
    let native_build_ms = start.elapsed().as_secs_f64() * 1e3;
    log::info!("{}", native.stats());
    let start = Instant::now();
    let sets =
        pool.install(|| RaySets::generate(&scene, &native, args.width, args.height, args.seed));
    log::info!(
        "ray sets: {} primary, {} bounce, {} shadow ({:?} lights) in {:.0} ms",
        sets.primary.len(),
        sets.bounce.len(),
        sets.shadow.len(),
        sets.lights,
        start.elapsed().as_secs_f64() * 1e3
    );

    // Reference answers, traced once.
    let reference: Vec<Results> = RayKind::ALL
        .iter()
        .map(|&kind| {
            let rays = sets.get(kind);
            let mut out = empty_results(kind, rays.len());
            pool.install(|| trace(&native, kind, rays, &mut out, false));
            out
        })
        .collect();

    // Build every backend first, then trace the runs of the backends in turn (native, embree,
    // native, ...), so that a change in the machine's load hits them alike.
    // (name, the backend unless it is the native one, build ms)
    type Built = (&'static str, Option<Box<dyn Accel>>, f64);
    let mut built: Vec<Built> = Vec::new();
    for &name in &backends {
        if name == "native" {
            built.push((name, None, native_build_ms));
        } else {
            let start = Instant::now();
            let b = pool.install(|| build_other(name, &tris, args))?;
            let ms = start.elapsed().as_secs_f64() * 1e3;
            log::info!("{name}: built in {ms:.1} ms");
            built.push((name, Some(b), ms));
        }
    }
    // (label, backend, build ms, through the batch queries)
    let accels: Vec<(String, &dyn Accel, f64, bool)> = built
        .iter()
        .flat_map(|(name, b, ms)| {
            let accel = b.as_deref().unwrap_or(&native as &dyn Accel);
            let batch = args
                .batch
                .then(|| (format!("{name}/batch"), accel, *ms, true));
            std::iter::once((name.to_string(), accel, *ms, false)).chain(batch)
        })
        .collect();

    let mut rows = Vec::new();
    for (k, &kind) in RayKind::ALL.iter().enumerate() {
        let rays = sets.get(kind);
        let mut outs: Vec<Results> = accels
            .iter()
            .map(|_| empty_results(kind, rays.len()))
            .collect();
        let mut rates = vec![Vec::with_capacity(args.repeat); accels.len()];
        for _ in 0..args.repeat {
            for (i, &(_, accel, _, batch)) in accels.iter().enumerate() {
                let out = &mut outs[i];
                let start = Instant::now();
                pool.install(|| trace(accel, kind, rays, out, batch));
                let s = start.elapsed().as_secs_f64();
                rates[i].push(rays.len() as f64 / s.max(1e-12) / 1e6);
            }
        }
        for (i, (name, accel, build_ms, _)) in accels.iter().enumerate() {
            let r = &mut rates[i];
            let range = (
                r.iter().copied().fold(f64::INFINITY, f64::min),
                r.iter().copied().fold(0.0, f64::max),
            );
            let bad = mismatches(name, "native", kind, rays, &outs[i], &reference[k]);
            rows.push(Row {
                backend: name.clone(),
                kind,
                rays: rays.len(),
                mrays_per_s: median(r),
                range,
                build_ms: *build_ms,
                memory_bytes: accel.memory_bytes(),
                mismatches: bad,
            });
        }
    }
    // Rows by backend, then kind.
    rows.sort_by_key(|r| {
        let b = accels.iter().position(|a| a.0 == r.backend);
        let k = RayKind::ALL.iter().position(|&x| x == r.kind);
        (b, k)
    });

    if args.json {
        for r in &rows {
            println!(
                "{}",
                json!({
                    "backend": r.backend,
                    "kind": r.kind.name(),
                    "rays": r.rays,
                    "mrays_per_s": r.mrays_per_s,
                    "threads": threads,
                    "build_ms": r.build_ms,
                    "memory_bytes": r.memory_bytes,
                    "mismatches": r.mismatches,
                })
            );
        }
    } else {
        print!(
            "{}",
            table(&scene.name, tris.len(), mtri, args, threads, &sets, &rows)
        );
    }
    Ok(())
}

fn table(
    name: &str,
    triangles: usize,
    mtri: f64,
    args: &RaysArgs,
    threads: usize,
    sets: &RaySets,
    rows: &[Row],
) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let name = if name.is_empty() { "(unnamed)" } else { name };
    let _ = writeln!(
        s,
        "scene {name}: {triangles} triangles; {}x{} pixels, {} threads, median of {} runs; \
         lights: {:?}",
        args.width, args.height, threads, args.repeat, sets.lights
    );
    let _ = writeln!(
        s,
        "{:<12} {:<8} {:>9} {:>10} {:>17} {:>10} {:>11} {:>10} {:>10}",
        "backend", "kind", "rays", "Mrays/s", "(min-max)", "build ms", "ms/Mtri", "MiB", "mismatch"
    );
    for r in rows {
        let per_mtri = if mtri > 0.0 { r.build_ms / mtri } else { 0.0 };
        let _ = writeln!(
            s,
            "{:<12} {:<8} {:>9} {:>10.2} {:>17} {:>10.1} {:>11.1} {:>10.1} {:>10}",
            r.backend,
            r.kind.name(),
            r.rays,
            r.mrays_per_s,
            format!("({:.2}-{:.2})", r.range.0, r.range.1),
            r.build_ms,
            per_mtri,
            r.memory_bytes as f64 / (1024.0 * 1024.0),
            r.mismatches
        );
    }
    let find = |b: &str, k: RayKind| rows.iter().find(|r| r.backend == b && r.kind == k);
    let ratios: Vec<String> = RayKind::ALL
        .iter()
        .filter_map(|&k| {
            let (n, e) = (find("native", k)?, find("embree", k)?);
            Some(format!(
                "{} {:.2}x",
                k.name(),
                n.mrays_per_s / e.mrays_per_s.max(1e-12)
            ))
        })
        .collect();
    if !ratios.is_empty() {
        let _ = writeln!(s, "native / embree: {}", ratios.join(", "));
    }
    s
}

/// Frames rendered before measuring (lazy initialisation, caches).
const WARM_UP_FRAMES: u32 = 2;

fn run_frame(args: &FrameArgs) -> Result<()> {
    use pathlight_render::camera_path::{CameraPath, PathKind};
    use pathlight_render::{Config, World};

    if args.frames == 0 || args.frames > 100_000 {
        bail!("--frames {}: must be between 1 and 100000", args.frames);
    }
    if !args.orbit.is_finite() {
        bail!("--orbit {}: must be finite", args.orbit);
    }
    let config = args.settings.apply(Config::realtime())?;
    let pool = crate::terminal::thread_pool(args.threads)?;
    let setup = Instant::now();
    let path = args.scene.scene.as_deref();
    let scene = pathlight_scene::load(path, &args.scene.load_options())?;
    let name = scene.name.clone();
    let world = pool.install(|| World::new(scene, config.light_selection));
    let (config, choice) = args.settings.for_scene(&world.lights)?;
    let setup_ms = setup.elapsed().as_secs_f64() * 1e3;
    let total = args.frames + WARM_UP_FRAMES;
    let orbit = CameraPath {
        path: PathKind::Orbit,
        look_from: config.camera.look_from,
        look_at: config.camera.look_at,
        up: config.camera.up,
        fov_y: config.camera.fov_y,
        degrees: args.orbit * total as f32 / args.frames as f32,
        steps: total - 1,
        ..CameraPath::default()
    };
    let views = world.path_views(&orbit);
    let mut reports = Vec::with_capacity(args.frames as usize);
    let pipeline =
        pool.install(|| orbit_frames(&world, &config, &views, |report| reports.push(report)));
    // The floor: the same frames again, their rays recorded, then traced alone.
    let mut world = world;
    let floors = (!args.no_floor).then(|| {
        let mut floors = Vec::with_capacity(args.frames as usize);
        pool.install(|| {
            let tap = Recorder::install(&mut world.accel);
            orbit_frames(&world, &config, &views, |_| {
                let recording = tap.take();
                floors.push(Query::ALL.map(|q| recording.replay(tap.accel(), q)));
            });
        });
        Floor::of(&floors)
    });
    let summary = Summary::of(&reports, pool.current_num_threads());
    let pixels = (config.width as f64 * config.height as f64).max(1.0);
    let (plain_bytes, technique_bytes) = pipeline.bytes();
    let (plain_bpp, technique_bpp) = (plain_bytes as f64 / pixels, technique_bytes as f64 / pixels);
    let ms_per_frame = summary.ms_per_frame;
    let rays: u64 = reports.iter().map(|r| r.rays).sum();
    let threads = summary.threads;
    let bounces = config
        .max_bounces
        .map_or("unlimited".to_owned(), |b| b.to_string());
    if args.json {
        println!(
            "{}",
            json!({
                "scene": name,
                "preset": crate::config_args::choice_json(&choice),
                "width": config.width,
                "height": config.height,
                "spp": config.spp,
                "max_bounces": config.max_bounces,
                "frames": args.frames,
                "threads": threads,
                "setup_ms": setup_ms,
                "ms_per_frame": ms_per_frame,
                "fps": 1e3 / ms_per_frame,
                "mrays_per_s": summary.mrays_per_s,
                "rays_per_frame": rays as f64 / args.frames as f64,
                "passes": summary.passes_json(),
                "peak_rss_bytes": crate::memory::peak_rss_bytes(),
                "bytes_per_pixel": plain_bpp,
                "technique_bytes_per_pixel": technique_bpp,
                "samples_per_pixel": reports.iter().map(|r| r.samples as f64).sum::<f64>() / reports.len().max(1) as f64 / pixels,
                "floor_ms": floors.as_ref().map(|f| f.ms),
                "floor": floors.as_ref().map(Floor::by_kind_json),
                "frame_over_floor": floors.as_ref().map(|f| ms_per_frame / f.ms),
                "target": target(&reports, config.frame.target_ms).map(|t| t.1),
            })
        );
    } else {
        println!(
            "{name}: {}x{}, {} spp per frame, {bounces} bounces, {} frames along a {}-degree orbit, {threads} threads (setup {setup_ms:.0} ms)",
            config.width, config.height, config.spp, args.frames, args.orbit
        );
        println!("{:<12} {:>10}", "pass", "median ms");
        for (n, m) in &summary.passes {
            println!("{n:<12} {m:>10.2}");
        }
        println!(
            "{:<12} {:>10.2}   ({:.1} fps, {:.1} Mrays/s, {:.2} rays per pixel)",
            "frame",
            ms_per_frame,
            1e3 / ms_per_frame,
            summary.mrays_per_s,
            rays as f64 / args.frames as f64 / (config.width as f64 * config.height as f64)
        );
        if let Some(f) = &floors {
            let kinds: Vec<String> = (Query::ALL.iter().zip(f.by_kind))
                .map(|(q, ms)| format!("{} {ms:.2}", q.name()))
                .collect();
            println!(
                "{:<12} {:>10.2}   (its rays alone: {}; frame / floor {:.2})",
                "floor",
                f.ms,
                kinds.join(", "),
                ms_per_frame / f.ms
            );
        }
        println!("memory: {plain_bpp:.0} bytes per pixel, {technique_bpp:.0} more for the techniques that are on");
        if let Some((line, _)) = target(&reports, config.frame.target_ms) {
            println!("{line}");
        }
    }
    Ok(())
}

/// Renders the frames of `views` with a new pipeline for `config`, each view a new frame;
/// `measured` takes each report after the warm-up frames. Returns the pipeline.
fn orbit_frames(
    world: &pathlight_render::World,
    config: &pathlight_render::Config,
    views: &[pathlight_render::camera::CameraConfig],
    mut measured: impl FnMut(pathlight_render::frame::FrameReport),
) -> pathlight_render::frame::Pipeline {
    let mut pipeline = pathlight_render::frame::Pipeline::new(config.clone());
    pipeline.prepare_world(world);
    for (i, view) in views.iter().enumerate() {
        let mut c = config.clone();
        c.camera.look_from = view.look_from;
        c.camera.look_at = view.look_at;
        c.camera.up = view.up;
        c.camera.fov_y = view.fov_y;
        pipeline.set_config(&c);
        let mut report = pipeline.render_frame(world);
        pipeline.display(&mut report);
        if i >= WARM_UP_FRAMES as usize {
            measured(report);
        }
    }
    pipeline
}

/// A frame's floor: its rays traced alone, by kind of query (medians over the frames, in
/// milliseconds), and the median of their sums.
pub struct Floor {
    pub ms: f64,
    pub by_kind: [f64; 3],
}

impl Floor {
    fn of(frames: &[[f64; 3]]) -> Self {
        let mut sums: Vec<f64> = frames.iter().map(|f| f.iter().sum()).collect();
        let by_kind = std::array::from_fn(|k| {
            let mut v: Vec<f64> = frames.iter().map(|f| f[k]).collect();
            median(&mut v)
        });
        Self {
            ms: median(&mut sums),
            by_kind,
        }
    }

    fn by_kind_json(&self) -> serde_json::Value {
        (Query::ALL.iter().zip(self.by_kind))
            .map(|(q, ms)| (q.name().to_owned(), json!(ms)))
            .collect::<serde_json::Map<_, _>>()
            .into()
    }
}

/// The frame-time target over `reports` (`[frame] target_ms`; `None` without one): after the
/// first frame, how many took longer than the target and the 95th percentile of their times;
/// the render scale of the last frame and the lowest used. A line for the terminal and the
/// JSON object (`target`).
pub fn target(
    reports: &[pathlight_render::frame::FrameReport],
    target_ms: f32,
) -> Option<(String, serde_json::Value)> {
    if target_ms <= 0.0 || reports.len() < 2 {
        return None;
    }
    let later = &reports[1..];
    let over = later.iter().filter(|r| r.ms > target_ms as f64).count();
    let mut ms: Vec<f64> = later.iter().map(|r| r.ms).collect();
    ms.sort_by(f64::total_cmp);
    let p95 = ms[((ms.len() as f64 * 0.95).ceil() as usize).clamp(1, ms.len()) - 1];
    let last = later.last().map_or(1.0, |r| r.scale);
    let lowest = later.iter().map(|r| r.scale).fold(1.0f32, f32::min);
    let line = format!(
        "target {target_ms} ms: {over} of {} frames after the first over it, 95% within \
         {p95:.1} ms; render scale {last} at the end (lowest {lowest})",
        later.len()
    );
    let json = json!({
        "target_ms": target_ms,
        "frames_over_target": over,
        "frames": later.len(),
        "p95_ms": p95,
        "scale": last,
        "lowest_scale": lowest,
    });
    Some((line, json))
}

/// Medians over frames.
pub struct Summary {
    pub ms_per_frame: f64,
    /// The first frame's time, and the slowest of those after it, in ms (stalls).
    pub first_ms: f64,
    pub worst_later_ms: f64,
    pub mrays_per_s: f64,
    pub threads: usize,
    /// (pass, median ms) in pipeline order.
    pub passes: Vec<(String, f64)>,
}

impl Summary {
    /// The per-pass medians as a JSON object.
    pub fn passes_json(&self) -> serde_json::Value {
        self.passes
            .iter()
            .map(|(n, ms)| (n.clone(), json!(ms)))
            .collect::<serde_json::Map<_, _>>()
            .into()
    }

    pub fn of(reports: &[pathlight_render::frame::FrameReport], threads: usize) -> Self {
        let mut names: Vec<&str> = Vec::new();
        for r in reports {
            for p in &r.passes {
                if !names.contains(&p.pass) {
                    names.push(p.pass);
                }
            }
        }
        let passes = names
            .iter()
            .map(|n| {
                let mut v: Vec<f64> = reports.iter().map(|r| r.pass_ms(n)).collect();
                (n.to_string(), median(&mut v))
            })
            .collect();
        let mut ms: Vec<f64> = reports.iter().map(|r| r.ms).collect();
        let total_ms: f64 = reports.iter().map(|r| r.ms).sum();
        let rays: u64 = reports.iter().map(|r| r.rays).sum();
        let first_ms = ms.first().copied().unwrap_or(0.0);
        let worst_later_ms = ms.iter().skip(1).copied().fold(0.0, f64::max);
        Self {
            ms_per_frame: median(&mut ms),
            first_ms,
            worst_later_ms,
            mrays_per_s: rays as f64 / (total_ms * 1e3).max(1e-9),
            threads,
            passes,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hit(t: f32, triangle: u32) -> Option<Hit> {
        Some(Hit {
            t,
            u: 0.0,
            v: 0.0,
            instance: 0,
            triangle,
        })
    }

    #[test]
    fn agreement_rule() {
        assert!(hits_agree(&None, &None));
        assert!(!hits_agree(&None, &hit(1.0, 0)));
        assert!(hits_agree(&hit(1.0, 3), &hit(1.5, 3)));
        assert!(hits_agree(&hit(2.0, 3), &hit(2.00005, 4)));
        assert!(!hits_agree(&hit(2.0, 3), &hit(2.001, 4)));
        assert!(hits_agree(&hit(1e4, 3), &hit(1e4 + 0.5, 4)));
    }

    #[test]
    fn median_of_odd_and_even() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
    }

    #[test]
    fn embree_needs_the_feature() {
        let r = selected_backends(BackendChoice::Embree);
        if cfg!(feature = "embree") {
            assert_eq!(r.unwrap(), vec!["embree"]);
        } else {
            let e = r.unwrap_err().to_string();
            assert!(e.contains("built without the embree feature"), "{e}");
        }
        assert_eq!(
            selected_backends(BackendChoice::All).unwrap(),
            compiled_backends()
        );
    }
}
