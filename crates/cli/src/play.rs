//! `pathlight play [SCENE] --path PATH.toml`: the headless twin of the viewer. Renders a
//! scripted camera path frame by frame through the real-time frame pipeline and writes the
//! frames (PNG or EXR) and per-frame, per-pass timings (JSON).

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use pathlight_render::camera_path::{CameraPath, PathKind};
use pathlight_render::config::CameraConfig;
use pathlight_render::frame::{FrameReport, Pipeline};
use pathlight_render::output::{encode_rgba8_png, write_atomic, write_rgb};
use pathlight_render::{Config, World};
use serde::Serialize;

use crate::bench::Summary;
use crate::config_args::ConfigArgs;
use crate::terminal::{ctrl_c_flag, progress_bar, thread_pool};
use crate::SceneArgs;

/// Largest path file read.
const MAX_PATH_BYTES: u64 = 1 << 20;
/// Most frames one run renders.
const MAX_FRAMES: u64 = 1_000_000;

#[derive(Debug, Args)]
pub struct PlayArgs {
    #[command(flatten)]
    pub scene: SceneArgs,

    /// The camera path: a TOML file, or a built-in protocol: `rotation` (seed 000: 100 degrees
    /// in 5-degree steps, 32 frames at each), `translation` (a fifth of the scene's size to the
    /// right in 20 steps), `orbit` (a full turn in 120 steps) or `still` (64 frames).
    #[arg(long, value_name = "PATH.toml|NAME")]
    pub path: String,

    /// Frames to render [default: the path's own count]; past the path's end the last view
    /// stays (and accumulates).
    #[arg(long, value_name = "N")]
    pub frames: Option<u64>,

    /// Folder for the frames (`frame-00000.png` ...) and `frames.json`; without it nothing is
    /// written but the summary.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,

    /// Image format of the frames: png (the display mode as shown) or exr (its linear values).
    #[arg(long, value_enum, default_value_t = FrameFormat::Png)]
    pub format: FrameFormat,

    #[command(flatten)]
    pub settings: ConfigArgs,

    /// A stereo pair: each frame is rendered for a left and a right eye this far apart (scene
    /// units, along the camera's right; parallel eyes), one after the other through one
    /// pipeline, the right eye at the same instant as the left (the texture cache's texels
    /// shaded for the left eye serve the right). Frames are written as `frame-NNNNN-left` and
    /// `-right`; the summary gives the cells the right eye shaded as a share of the left's.
    #[arg(long, value_name = "D", default_value_t = 0.0)]
    pub eye_separation: f32,

    /// Worker threads [default: all cores]; the frames do not depend on it.
    #[arg(long, value_name = "T")]
    pub threads: Option<usize>,

    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,

    /// Print one JSON object (frames, median times per frame and per pass, the first frame's
    /// time and the slowest later one's against the median) as the last line.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FrameFormat {
    Png,
    Exr,
}

/// One frame in `frames.json`.
#[derive(Debug, Serialize)]
struct FrameRecord<'a> {
    /// Index along the run, from 0.
    index: u64,
    /// Index of the path's view.
    view: usize,
    /// With `--eye-separation`: `left` or `right`.
    #[serde(skip_serializing_if = "Option::is_none")]
    eye: Option<&'static str>,
    file: Option<String>,
    #[serde(flatten)]
    report: &'a FrameReport,
}

/// The built-in protocols and path files.
fn load_path(arg: &str, world: &World, config: &Config) -> Result<CameraPath> {
    let camera = CameraPath {
        look_from: config.camera.look_from,
        look_at: config.camera.look_at,
        up: config.camera.up,
        fov_y: config.camera.fov_y,
        ..CameraPath::default()
    };
    let path = match arg {
        "still" => CameraPath {
            frames_per_view: 64,
            ..camera
        },
        "rotation" => CameraPath {
            path: PathKind::Rotation,
            degrees: 100.0,
            step_degrees: 5.0,
            frames_per_view: 32,
            ..camera
        },
        "translation" => {
            let view = config.camera.apply(&world.scene_camera());
            let right = view.transform.x_axis.truncate().normalize_or_zero();
            let b = world.scene.bounds();
            let size = if b.is_empty() {
                1.0
            } else {
                b.diagonal().length()
            };
            CameraPath {
                path: PathKind::Translation,
                offset: (right * 0.2 * size).to_array(),
                steps: 20,
                ..camera
            }
        }
        "orbit" => CameraPath {
            path: PathKind::Orbit,
            degrees: 360.0,
            steps: 120,
            ..camera
        },
        file => {
            let p = Path::new(file);
            let meta = std::fs::metadata(p).with_context(|| file.to_string())?;
            if meta.len() > MAX_PATH_BYTES {
                bail!(
                    "{file}: {} bytes; a camera path is at most {MAX_PATH_BYTES}",
                    meta.len()
                );
            }
            let text = std::fs::read_to_string(p).with_context(|| file.to_string())?;
            let path: CameraPath =
                toml::from_str(&text).map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
            with_camera_flags(path, &camera).map_err(|e| anyhow::anyhow!("{file}: {e}"))?
        }
    };
    path.validate().map_err(|e| anyhow::anyhow!("{arg}: {e}"))?;
    Ok(path)
}

/// A path file's first view with the camera flags (`flags`' `look_from`, `look_at`, `up`,
/// `fov_y`) where the file leaves them unset. A flag that contradicts the file, or any flag
/// with keyframes (which set every view themselves), is an error naming the field.
fn with_camera_flags(mut path: CameraPath, flags: &CameraPath) -> Result<CameraPath, String> {
    let given = [
        ("look_from", "--look-from", flags.look_from.is_some()),
        ("look_at", "--look-at", flags.look_at.is_some()),
        ("up", "--up", flags.up.is_some()),
        ("fov_y", "--fov-y", flags.fov_y.is_some()),
    ];
    if path.path == PathKind::Keyframes {
        if let Some((_, flag, _)) = given.iter().find(|g| g.2) {
            return Err(format!(
                "{flag}: a keyframed path sets every view itself; leave out the camera flags"
            ));
        }
        return Ok(path);
    }
    fn fill<T: PartialEq + std::fmt::Debug + Copy>(
        file: &mut Option<T>,
        flag: Option<T>,
        field: &str,
        name: &str,
    ) -> Result<(), String> {
        match (*file, flag) {
            (Some(a), Some(b)) if a != b => Err(format!(
                "{field} = {a:?} in the file, but {name} gives {b:?}; set it in one place"
            )),
            (None, Some(b)) => {
                *file = Some(b);
                Ok(())
            }
            _ => Ok(()),
        }
    }
    fill(
        &mut path.look_from,
        flags.look_from,
        "look_from",
        "--look-from",
    )?;
    fill(&mut path.look_at, flags.look_at, "look_at", "--look-at")?;
    fill(&mut path.up, flags.up, "up", "--up")?;
    fill(&mut path.fov_y, flags.fov_y, "fov_y", "--fov-y")?;
    Ok(path)
}

pub fn run(args: &PlayArgs) -> Result<()> {
    let config = args.settings.apply(Config::realtime())?;
    let pool = thread_pool(args.threads)?;
    let world = pool.install(|| args.scene.load_world(config.light_selection))?;
    let (config, choice) = args.settings.for_scene(&world.lights)?;
    let path = load_path(&args.path, &world, &config)?;
    let views = world.path_views(&path);
    let per_view = path.frames_per_view.max(1) as u64;
    let frames = args.frames.unwrap_or(views.len() as u64 * per_view);
    if frames == 0 || frames > MAX_FRAMES {
        bail!("--frames {frames}: must be between 1 and {MAX_FRAMES}");
    }
    if !(args.eye_separation.is_finite() && args.eye_separation >= 0.0) {
        bail!(
            "--eye-separation {}: must be finite and at least 0",
            args.eye_separation
        );
    }
    let stereo = args.eye_separation > 0.0;
    // The eyes: none (one camera), or left and right of each view.
    let eyes: &[Option<(&'static str, f32)>] = if stereo {
        &[Some(("left", -0.5)), Some(("right", 0.5))]
    } else {
        &[None]
    };
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
    }
    let cancel = ctrl_c_flag();
    let bar = progress_bar(
        args.quiet || args.json,
        frames,
        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} frames {msg} ETA {eta}",
    );

    let with_view = |view: &CameraConfig| Config {
        camera: CameraConfig {
            lens_radius: config.camera.lens_radius,
            focus_distance: config.camera.focus_distance,
            ..view.clone()
        },
        ..config.clone()
    };
    // A view moved by `side` eye separations along its camera's right.
    let eye_view = |view: &CameraConfig, side: f32| {
        let c = view.apply(&world.scene_camera());
        let right = c.transform.x_axis.truncate().normalize_or_zero();
        let shift = right * (side * args.eye_separation);
        let from = c.position() + shift;
        CameraConfig {
            look_from: Some(from.to_array()),
            look_at: Some((from + c.forward()).to_array()),
            up: Some(c.transform.y_axis.truncate().to_array()),
            ..view.clone()
        }
    };
    let (mut shaded, mut texels) = ([0u64; 2], [0u64; 2]);
    let mut pipeline = Pipeline::new(with_view(&views[0]));
    // What the stages keep per world, made before the first frame as at a viewer's load.
    let prepared = std::time::Instant::now();
    pool.install(|| pipeline.prepare_world(&world));
    let prepare_ms = prepared.elapsed().as_secs_f64() * 1e3;
    let mut reports = Vec::new();
    let mut records = Vec::new();
    let mut linear = Vec::new();
    // Flicker: mean absolute difference of consecutive shown frames at the same view.
    let mut previous: Option<(usize, Vec<u8>)> = None;
    let mut flicker = Vec::new();
    for (index, eye) in (0..frames).flat_map(|i| eyes.iter().map(move |e| (i, *e))) {
        if cancel.load(Ordering::Relaxed) {
            break;
        }
        let view = ((index / per_view) as usize).min(views.len() - 1);
        let camera = match eye {
            Some((_, side)) => eye_view(&views[view], side),
            None => views[view].clone(),
        };
        pipeline.set_config(&with_view(&camera));
        // The right eye: the same instant as the left.
        pipeline.stages.texture_cache.same_instant = matches!(eye, Some(("right", _)));
        let mut report = pool.install(|| pipeline.render_frame(&world));
        pool.install(|| pipeline.display(&mut report));
        if let (Some(t), Some((name, _))) = (&report.texture_cache, eye) {
            shaded[usize::from(name == "right")] += t.cells_shaded;
            texels[usize::from(name == "right")] += t.texel_blocks;
        }
        if let (Some((v, before)), None) = (&previous, eye) {
            if *v == view {
                flicker.push(mean_abs_difference(before, &pipeline.rgba));
            }
        }
        previous = Some((view, pipeline.rgba.clone()));
        let file = match &args.out {
            Some(dir) => {
                let name = format!(
                    "frame-{index:05}{}.{}",
                    eye.map_or(String::new(), |(e, _)| format!("-{e}")),
                    match args.format {
                        FrameFormat::Png => "png",
                        FrameFormat::Exr => "exr",
                    }
                );
                let target = dir.join(&name);
                match args.format {
                    FrameFormat::Png => write_atomic(
                        &target,
                        &encode_rgba8_png(config.width, config.height, &pipeline.rgba),
                    )?,
                    FrameFormat::Exr => {
                        pool.install(|| {
                            linear = pipeline.linear(&config.display.mode);
                        });
                        write_rgb(
                            &target,
                            config.width,
                            config.height,
                            &linear,
                            &config.display,
                        )?
                    }
                }
                Some(name)
            }
            None => None,
        };
        bar.set_message(format!("{:.1} ms", report.ms));
        if eye.is_none_or(|(e, _)| e == "right") {
            bar.inc(1);
        }
        records.push((index, view, eye.map(|(e, _)| e), file));
        reports.push(report);
    }
    bar.finish_and_clear();
    let done = (reports.len() / eyes.len()) as u64;
    if let Some(dir) = &args.out {
        let list: Vec<FrameRecord> = records
            .iter()
            .zip(&reports)
            .map(|((index, view, eye, file), report)| FrameRecord {
                index: *index,
                view: *view,
                eye: *eye,
                file: file.clone(),
                report,
            })
            .collect();
        let json = serde_json::to_vec_pretty(&list).expect("frames serialise");
        write_atomic(&dir.join("frames.json"), &json)?;
    }
    let summary = Summary::of(&reports, pool.current_num_threads());
    if done < frames {
        bail!(
            "stopped after {done} of {frames} frames{}",
            args.out
                .as_ref()
                .map_or(String::new(), |d| format!(" (written to {})", d.display()))
        );
    }
    let flicker = (!flicker.is_empty()).then(|| flicker.iter().sum::<f64>() / flicker.len() as f64);
    if let Some(f) = flicker {
        eprintln!("flicker (mean |difference| of consecutive frames at one view, 0-1): {f:.5}");
    }
    let second_eye = (stereo && shaded[0] > 0).then(|| shaded[1] as f64 / shaded[0] as f64);
    let second_eye_texels = (stereo && texels[0] > 0).then(|| texels[1] as f64 / texels[0] as f64);
    if let Some(share) = second_eye {
        eprintln!(
            "stereo: the right eye shaded {} cells, {:.1}% of the left eye's {}, and filtered \
             {:.1}% of its texel blocks",
            shaded[1],
            100.0 * share,
            shaded[0],
            100.0 * second_eye_texels.unwrap_or(0.0)
        );
    }
    eprintln!(
        "{} frames of {}x{} ({} views), median {:.2} ms per frame ({:.1} fps): {}",
        done,
        config.width,
        config.height,
        views.len(),
        summary.ms_per_frame,
        1e3 / summary.ms_per_frame.max(1e-9),
        summary
            .passes
            .iter()
            .map(|(p, ms)| format!("{p} {ms:.2} ms"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let median = summary.ms_per_frame.max(1e-9);
    eprintln!(
        "the stages' per-world set-up {:.1} ms; first frame {:.1} ms ({:.2}x the median); \
         the slowest after it {:.1} ms ({:.2}x)",
        prepare_ms,
        summary.first_ms,
        summary.first_ms / median,
        summary.worst_later_ms,
        summary.worst_later_ms / median
    );
    let target = crate::bench::target(&reports, config.frame.target_ms);
    if let Some((line, _)) = &target {
        eprintln!("{line}");
    }
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "frames": done,
                "preset": crate::config_args::choice_json(&choice),
                "prepare_ms": prepare_ms,
                "first_frame_ms": summary.first_ms,
                "first_over_median": summary.first_ms / median,
                "worst_later_over_median": summary.worst_later_ms / median,
                "target": target.map(|t| t.1),
                "views": views.len(),
                "width": config.width,
                "height": config.height,
                "threads": summary.threads,
                "ms_per_frame": summary.ms_per_frame,
                "mrays_per_s": summary.mrays_per_s,
                "passes": summary.passes_json(),
                "flicker": flicker,
                "second_eye_shading": second_eye,
                "second_eye_texel_blocks": second_eye_texels,
                "out": args.out,
            })
        );
    }
    Ok(())
}

/// Mean absolute difference of the RGB channels of two RGBA8 images, in 0..1.
fn mean_abs_difference(a: &[u8], b: &[u8]) -> f64 {
    let (sum, count) = a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .flat_map(|(p, q)| (0..3).map(move |c| p[c].abs_diff(q[c]) as u64))
        .fold((0u64, 0u64), |(s, n), d| (s + d, n + 1));
    sum as f64 / (255.0 * count.max(1) as f64)
}
