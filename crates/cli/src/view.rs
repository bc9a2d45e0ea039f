//! `pathlight view [SCENE]`: the interactive viewer (see `pathlight_viewer`).

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;
use pathlight_render::Config;
use pathlight_viewer::ViewerOptions;

use crate::config_args::{parse_size, ConfigArgs};
use crate::SceneArgs;

#[derive(Debug, Args)]
pub struct ViewArgs {
    #[command(flatten)]
    pub scene: SceneArgs,

    #[command(flatten)]
    pub settings: ConfigArgs,

    /// Initial window size in logical pixels.
    #[arg(long, value_name = "WxH", value_parser = parse_size, default_value = "1280x720")]
    pub window: [u32; 2],

    /// Image resolution relative to the image area (0.1 to 2; 1 is a rendered pixel per
    /// screen pixel). The default, 0.5, renders a quarter of the pixels: interactive frame
    /// rates on two cores.
    #[arg(long, value_name = "X", default_value_t = 0.5, value_parser = parse_scale)]
    pub scale: f32,

    /// Worker threads [default: all cores].
    #[arg(long, value_name = "T")]
    pub threads: Option<usize>,

    /// Test hook: after this many frames, freeze the image, write --report and close a few
    /// seconds later.
    #[arg(long, value_name = "N", hide = true)]
    pub exit_after_frames: Option<u64>,

    /// Test hook: JSON file with the image's place in the window (and the frame as PNG beside
    /// it).
    #[arg(long, value_name = "FILE", hide = true)]
    pub report: Option<PathBuf>,

    /// Test hook: JSON file with the window's state, rewritten whenever it changes.
    #[arg(long, value_name = "FILE", hide = true)]
    pub state: Option<PathBuf>,

    /// Test hook: seconds the frozen window stays open.
    #[arg(long, value_name = "SECONDS", hide = true, default_value_t = 10.0)]
    pub close_after: f64,
}

/// A resolution scale, refused outside 0.1..=2 (the viewer's own range).
fn parse_scale(s: &str) -> std::result::Result<f32, String> {
    let x: f32 = s.parse().map_err(|_| format!("{s:?} is not a number"))?;
    match (0.1..=2.0).contains(&x) {
        true => Ok(x),
        false => Err(format!("{s}: the scale must be between 0.1 and 2")),
    }
}

pub fn run(args: &ViewArgs) -> Result<()> {
    let config = args.settings.apply(Config::realtime())?;
    if let Some(t) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()
            .context("starting the worker threads")?;
    }
    let world = args.scene.load_world(config.light_selection)?;
    let (config, choice) = args.settings.for_scene(&world.lights)?;
    let title = format!("pathlight: {}", world.scene.name);
    let options = ViewerOptions {
        title,
        window: [args.window[0] as f32, args.window[1] as f32],
        scale: args.scale,
        exit_after_frames: args.exit_after_frames,
        report: args.report.clone(),
        state: args.state.clone(),
        close_after: Duration::from_secs_f64(args.close_after.clamp(0.0, 3600.0)),
        choice,
    };
    pathlight_viewer::run(world, config, options)?;
    Ok(())
}
