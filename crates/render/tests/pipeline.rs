//! The real-time frame pipeline: still frames accumulate to exactly the reference path
//! tracer's image, frames do not depend on the thread count, motion vectors match the
//! analytic image motion of a translating camera, changes reset the history (display settings
//! do not), and every display mode shows something.

mod common;

use common::{cornell, in_pool};
use glam::Vec2;
use pathlight_render::camera_path::{CameraPath, PathKind};
use pathlight_render::config::FrameConfig;
use pathlight_render::frame::display::DisplayMode;
use pathlight_render::frame::views;
use pathlight_render::frame::{Pipeline, ACCUMULATE, DISPLAY, LIGHTING, PRIMARY};
use pathlight_render::renderer::render;
use pathlight_render::{Config, World};

fn config() -> Config {
    Config {
        width: 40,
        height: 30,
        seed: 7,
        ..Config::default()
    }
}

/// N still frames of one sample are the reference render at N spp, bit for bit: the G-buffer
/// pass and the lighting pass together trace exactly the reference's paths.
/// The reference path tracer's image of `cfg` at `spp` samples per pixel.
fn reference(world: &World, cfg: &Config, spp: u32) -> pathlight_render::film::Film {
    render(
        world,
        &cfg.render_camera(world),
        &Config { spp, ..cfg.clone() },
    )
}

#[test]
fn still_frames_accumulate_to_the_reference_render() {
    let world = cornell();
    for max_bounces in [None, Some(2)] {
        let cfg = Config {
            max_bounces,
            ..config()
        };
        let mut pipeline = Pipeline::new(cfg.clone());
        for f in 1..=8 {
            let r = pipeline.render_frame(&world);
            assert_eq!((r.accumulated, r.spp, r.epoch), (f, f, 0));
            assert!(r.rays >= 40 * 30, "{} rays", r.rays);
        }
        let film = reference(&world, &cfg, 8);
        for (h, p) in pipeline.frame.history.iter().zip(&film.pixels) {
            assert_eq!(h.n, p.n);
            assert_eq!(h.direct.mean, p.direct, "{max_bounces:?}");
            assert_eq!(h.indirect.mean, p.indirect, "{max_bounces:?}");
            let var = h.variance();
            assert!(
                var.abs_diff_eq(p.variance(), 1e-4 * (1.0 + p.variance().max_element())),
                "{var} vs {}",
                p.variance()
            );
        }
        // Albedo, normal and depth of the G-buffer are the reference's first-hit features of
        // the last sample: their means agree with the film's over the whole image.
        let albedo: f32 = pipeline
            .frame
            .gbuffer
            .pixels
            .iter()
            .map(|g| g.albedo.x)
            .sum();
        let film_albedo: f32 = film.pixels.iter().map(|p| p.albedo.x).sum();
        assert!((albedo - film_albedo).abs() < 0.05 * film_albedo);
    }

    // Several samples per frame: 4 frames of 2 samples are the same samples as 8 spp (the
    // statistics merged by batches, so equal up to rounding).
    let cfg = Config { spp: 2, ..config() };
    let mut pipeline = Pipeline::new(cfg.clone());
    for _ in 0..4 {
        pipeline.render_frame(&world);
    }
    let film = reference(&world, &cfg, 8);
    for (h, p) in pipeline.frame.history.iter().zip(&film.pixels) {
        assert_eq!(h.n, 8);
        assert!(h
            .mean()
            .abs_diff_eq(p.mean, 1e-5 * (1.0 + p.mean.max_element())));
    }
}

/// Renders `frames` frames along a short orbit and returns every frame's display bytes and
/// the final history.
fn orbit_frames(world: &World, frames: u32) -> (Vec<Vec<u8>>, Vec<glam::Vec3>) {
    let path = CameraPath {
        path: PathKind::Orbit,
        degrees: 20.0,
        steps: frames - 1,
        ..CameraPath::default()
    };
    let views = world.path_views(&path);
    let mut pipeline = Pipeline::new(config());
    let mut shown = Vec::new();
    for view in views {
        pipeline.set_config(&Config {
            camera: view,
            ..config()
        });
        let mut r = pipeline.render_frame(world);
        pipeline.display(&mut r);
        shown.push(pipeline.rgba.clone());
    }
    (shown, pipeline.image())
}

#[test]
fn frames_do_not_depend_on_the_thread_count() {
    let world = cornell();
    let one = in_pool(1, || orbit_frames(&world, 4));
    let two = in_pool(2, || orbit_frames(&world, 4));
    assert!(one == two, "frames differ between 1 and 2 threads");
    // Each view has its own noise (a new epoch, a new seed).
    assert_ne!(one.0[0], one.0[1]);
}

/// A camera translated by `t` along its right axis: a surface point at depth `z` moves on the
/// film by `-t f / z` pixels (f = half the height over tan(fov / 2)), so its motion vector
/// (where it was minus where it is) is `+t f / z` in x and 0 in y.
#[test]
fn motion_vectors_match_a_translating_camera() {
    let world = cornell();
    let fov = 40.0f32;
    let at = |x: f32| Config {
        camera: pathlight_render::config::CameraConfig {
            look_from: Some([x, 1.0, 3.5]),
            look_at: Some([x, 1.0, 0.0]),
            up: Some([0.0, 1.0, 0.0]),
            fov_y: Some(fov),
            ..Default::default()
        },
        ..config()
    };
    let mut pipeline = Pipeline::new(at(0.0));
    let first = pipeline.render_frame(&world);
    assert!(pipeline
        .frame
        .gbuffer
        .pixels
        .iter()
        .all(|g| g.motion == Vec2::ZERO));
    let t = 0.1;
    pipeline.set_config(&at(t));
    let second = pipeline.render_frame(&world);
    assert_eq!(second.epoch, first.epoch + 1);
    let f = 0.5 * 30.0 / (0.5 * fov.to_radians()).tan();
    let mut checked = 0;
    for g in pipeline.frame.gbuffer.pixels.iter().filter(|g| !g.is_sky()) {
        let want = t * f / g.depth;
        assert!(
            (g.motion.x - want).abs() < 1e-3 && g.motion.y.abs() < 1e-3,
            "motion {} at depth {}, want ({want}, 0)",
            g.motion,
            g.depth
        );
        checked += 1;
    }
    assert!(checked > 900, "{checked} pixels checked");
}

#[test]
fn changes_reset_the_history_and_display_settings_do_not() {
    let world = cornell();
    let mut pipeline = Pipeline::new(config());
    for _ in 0..3 {
        pipeline.render_frame(&world);
    }
    assert_eq!(pipeline.accumulated(), 3);
    // Display settings and the frame limit leave the history alone.
    let mut c = config();
    c.display.exposure = 2.0;
    c.display.mode = DisplayMode::named("normal");
    c.frame.max_frames = 100;
    pipeline.set_config(&c);
    let r = pipeline.render_frame(&world);
    assert_eq!((r.accumulated, r.epoch), (4, 0));
    // Samples per frame do not.
    c.max_bounces = Some(1);
    pipeline.set_config(&c);
    let r = pipeline.render_frame(&world);
    assert_eq!((r.accumulated, r.epoch), (1, 1));
    // The frame limit stops tracing; the display pass still runs.
    c.frame.max_frames = 2;
    pipeline.set_config(&c);
    pipeline.render_frame(&world);
    let mut r = pipeline.render_frame(&world);
    assert!(!r.traced && r.rays == 0 && r.accumulated == 2);
    pipeline.display(&mut r);
    assert_eq!(r.passes.len(), 1);
    assert_eq!(r.passes[0].pass, DISPLAY);
    // Without accumulation every frame stands alone, with fresh noise.
    c.frame = FrameConfig {
        accumulate: false,
        max_frames: 0,
        ..FrameConfig::default()
    };
    pipeline.set_config(&c);
    let a = pipeline.render_frame(&world);
    let image_a = pipeline.image();
    let b = pipeline.render_frame(&world);
    assert_eq!((a.accumulated, b.accumulated), (1, 1));
    assert_eq!(b.epoch, a.epoch + 1);
    assert_ne!(image_a, pipeline.image());
    let names: Vec<&str> = b.passes.iter().map(|p| p.pass).collect();
    assert_eq!(names, [PRIMARY, LIGHTING, ACCUMULATE]);
}

#[test]
fn every_display_mode_shows_the_box() {
    let world = cornell();
    let mut pipeline = Pipeline::new(config());
    pipeline.render_frame(&world);
    pipeline.render_frame(&world);
    for name in views::names() {
        let mut c = config();
        c.display.mode = name.parse().unwrap();
        pipeline.set_config(&c);
        let mut r = pipeline.render_frame(&world);
        pipeline.display(&mut r);
        assert_eq!(pipeline.rgba.len(), 40 * 30 * 4);
        let distinct: std::collections::HashSet<&[u8]> = pipeline.rgba.chunks(4).collect();
        // Uniform here: samples (every pixel has as many), metallic (zero in the box), motion
        // (the camera is still), seed 000's, seed 004's, seed 001's and seed 002's modes and
        // temporal upsampling's (their techniques are off; see tests/reprojection.rs,
        // tests/restir.rs, tests/filter.rs, tests/texture_cache.rs and tests/upsample.rs).
        let uniform = [
            "samples",
            "metallic",
            "motion",
            "probability",
            "reprojected",
            "rejection",
            "reservoir-m",
            "reservoir-weight",
            "variance-depth",
            "variance-normal",
            "variance-texture",
            "variance-direction",
            "variance-texture2",
            "sure-share",
            "cache-light",
            "cache-texels",
            "cache-level",
            "cache-hits",
            "cache-shaded",
            "upsample-samples",
        ]
        .contains(&name);
        // Roughness: the walls' 1 and the open front's sky.
        let least = if name == "roughness" { 2 } else { 4 };
        assert!(
            uniform || distinct.len() >= least,
            "{name}: {} distinct colours",
            distinct.len()
        );
    }
    // The final image: the left wall is red, the right wall green.
    let mut c = config();
    c.display.mode = DisplayMode::FINAL;
    pipeline.set_config(&c);
    let mut r = pipeline.render_frame(&world);
    pipeline.display(&mut r);
    // Mean colour of a 3x9 block around (x, y) (one noisy pixel could mislead).
    let block = |x: usize, y: usize| {
        let mut sum = [0u32; 3];
        for yy in y - 4..=y + 4 {
            for xx in x - 1..=x + 1 {
                for (c, s) in sum.iter_mut().enumerate() {
                    *s += pipeline.rgba[(yy * 40 + xx) * 4 + c] as u32;
                }
            }
        }
        sum
    };
    let (left, right) = (block(3, 15), block(36, 15));
    assert!(left[0] > 2 * left[1], "left wall {left:?}");
    assert!(2 * right[1] > 3 * right[0], "right wall {right:?}");
}

/// Adaptive sampling's `skip_empty`: the schedule's iterations that sample no pixel cost no
/// frame, and the frames that remain are exactly those of the schedule without skipping
/// (same pixels, same samples, same probabilities), minus the empty ones.
#[test]
fn skipping_empty_iterations_keeps_the_schedules_decisions() {
    use pathlight_render::frame::adaptive::{AdaptiveConfig, Measure};
    let world = cornell();
    let run = |skip_empty: bool, frames: u32| {
        let cfg = Config {
            max_bounces: Some(2),
            frame: FrameConfig {
                adaptive: AdaptiveConfig {
                    enabled: true,
                    min_spp: 4,
                    max_spp: 32,
                    // Display-scaled V: small everywhere, so the threshold starts far above it.
                    measure: Measure::Tonemapped,
                    skip_empty,
                    // The thesis's frames of one iteration each.
                    budget: false,
                    cap: false,
                    ..AdaptiveConfig::default()
                },
                ..FrameConfig::default()
            },
            ..config()
        };
        let mut pipeline = Pipeline::new(cfg);
        let samples: Vec<u64> = (0..frames)
            .map(|_| pipeline.render_frame(&world).samples)
            .collect();
        (samples, pipeline)
    };
    let frames = 48;
    let (all, plain) = run(false, frames);
    let empty = all.iter().filter(|&&n| n == 0).count() as u32;
    assert!(empty >= 4, "{all:?}");
    let (busy, skipped) = run(true, frames - empty);
    assert!(busy.iter().all(|&n| n > 0), "{busy:?}");
    let nonempty: Vec<u64> = all.iter().copied().filter(|&n| n > 0).collect();
    assert_eq!(busy, nonempty);
    assert_eq!(skipped.frame.history, plain.frame.history);
    assert_eq!(
        skipped.stages.adaptive.probability,
        plain.stages.adaptive.probability
    );
}

/// Adaptive sampling's `budget`: every frame traces about a uniform frame's samples. During
/// the schedule a frame runs several iterations (so the schedule takes fewer frames than
/// `max_spp`, never more samples than the pixels in a frame of more than one iteration);
/// after it each pixel takes samples in proportion to its probability, one per pixel on
/// average.
#[test]
fn budget_frames_trace_a_uniform_frames_samples() {
    use pathlight_render::frame::adaptive::AdaptiveConfig;
    let world = cornell();
    let cfg = Config {
        max_bounces: Some(2),
        frame: FrameConfig {
            adaptive: AdaptiveConfig {
                enabled: true,
                min_spp: 4,
                max_spp: 32,
                budget: true,
                ..AdaptiveConfig::default()
            },
            ..FrameConfig::default()
        },
        ..config()
    };
    let pixels = 40 * 30;
    let mut pipeline = Pipeline::new(cfg);
    let mut schedule_frames = 0;
    while pipeline.stages.adaptive.iteration < 32 {
        let before = pipeline.stages.adaptive.iteration;
        let r = pipeline.render_frame(&world);
        let ran = pipeline.stages.adaptive.iteration - before;
        assert!(ran >= 1);
        assert!(ran == 1 || r.samples <= pixels, "{} samples", r.samples);
        schedule_frames += 1;
    }
    assert!(schedule_frames < 32, "{schedule_frames} frames");
    let p = pipeline.stages.adaptive.probability.clone();
    assert!(p.iter().all(|&p| (4.0 / 32.0..=1.0).contains(&p)));
    let start: Vec<u32> = pipeline.frame.history.iter().map(|h| h.n).collect();
    let frames = 40;
    let mut total = 0;
    for _ in 0..frames {
        let r = pipeline.render_frame(&world);
        // Each pixel's count is its integer part plus a draw of variance at most 1/4.
        let sd = (pixels as f64 * 0.25).sqrt();
        assert!(
            (r.samples as f64 - pixels as f64).abs() < 4.0 * sd,
            "{} samples",
            r.samples
        );
        total += r.samples;
    }
    assert!((total as f64 / (frames * pixels) as f64 - 1.0).abs() < 0.02);
    // The samples went in proportion to P: pixels of P = 1 took 1 / mean(P) per frame.
    let mean_p = p.iter().sum::<f32>() as f64 / pixels as f64;
    let (mut got, mut expected) = (0.0, 0.0);
    for ((h, &n0), &p) in pipeline.frame.history.iter().zip(&start).zip(&p) {
        if p == 1.0 {
            got += (h.n - n0) as f64;
            expected += frames as f64 / mean_p;
        }
    }
    assert!(expected > 0.0);
    assert!((got / expected - 1.0).abs() < 0.05, "{got} vs {expected}");
}

/// The list of views that parsing and the viewer's menu read names the pipeline's stages, in
/// the frame's order, each with its own views.
#[test]
fn the_stages_views_are_the_listed_ones() {
    let pipeline = Pipeline::new(config());
    let stages = pipeline.stages.all();
    let listed = pathlight_render::frame::stages::views();
    assert_eq!(stages.len(), listed.len());
    for (stage, (name, views)) in stages.iter().zip(listed) {
        assert_eq!(stage.name(), *name);
        assert_eq!(stage.views(), *views);
    }
    // Every pass a frame reports is listed.
    let mut config = config();
    config.frame.restir.enabled = true;
    config.frame.texture_cache.enabled = true;
    config.frame.filter.method = pathlight_render::denoise::Method::Svgf;
    let world = cornell();
    let mut pipeline = Pipeline::new(config);
    let mut report = pipeline.render_frame(&world);
    pipeline.display(&mut report);
    assert_eq!(report.passes.len(), 9, "{:?}", report.passes);
    for pass in &report.passes {
        assert!(
            pathlight_render::frame::passes().contains(&pass.pass),
            "{pass:?}"
        );
    }
}
