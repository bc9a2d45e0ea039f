//! Temporal upsampling (issue 60): at scale 1 the stage stands aside and every frame is the
//! pipeline's own, bit for bit; a still view traced at half the output's size converges to
//! the reference path tracer's image at the output's size (an independent render); a moving
//! one gives finite output-sized images and views; its settings are checked.

mod common;

use common::cornell;
use glam::Vec3;
use pathlight_render::config::CameraConfig;
use pathlight_render::frame::display::DisplayMode;
use pathlight_render::frame::upsample::{render_size, UpsampleConfig};
use pathlight_render::frame::Pipeline;
use pathlight_render::renderer::render;
use pathlight_render::{Config, World};

fn config(scale: f32) -> Config {
    let mut c = Config {
        width: 40,
        height: 30,
        seed: 3,
        max_bounces: Some(2),
        ..Config::default()
    };
    c.frame.upsample.scale = scale;
    c
}

fn frames(world: &World, c: &Config, n: usize) -> Pipeline {
    let mut p = Pipeline::new(c.clone());
    for _ in 0..n {
        p.render_frame(world);
    }
    p
}

/// Relative MSE per pixel and channel, `(x - r)^2 / (r^2 + 0.01)`, averaged.
fn relmse(a: &[Vec3], reference: &[Vec3]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(reference)
        .map(|(x, r)| {
            let (x, r) = (x.as_dvec3(), r.as_dvec3());
            ((x - r) * (x - r) / (r * r + 0.01)).element_sum() / 3.0
        })
        .sum();
    sum / a.len() as f64
}

/// At scale 1 the upsampler's other settings change nothing: the frames, their views and
/// the display are the pipeline's own, bit for bit, still and after a move.
#[test]
fn scale_one_is_the_pipelines_own_frame() {
    let world = cornell();
    let plain = config(1.0);
    let mut other = config(1.0);
    other.frame.upsample = UpsampleConfig {
        scale: 1.0,
        alpha: 0.9,
        gamma: 3.0,
    };
    let (mut a, mut b) = (Pipeline::new(plain.clone()), Pipeline::new(other.clone()));
    for frame in 0..4 {
        if frame == 2 {
            let moved = |c: &Config| Config {
                camera: CameraConfig {
                    look_from: Some([0.3, 1.0, 3.5]),
                    look_at: Some([0.0, 1.0, 0.0]),
                    ..Default::default()
                },
                ..c.clone()
            };
            a.set_config(&moved(&plain));
            b.set_config(&moved(&other));
        }
        let (mut ra, mut rb) = (a.render_frame(&world), b.render_frame(&world));
        a.display(&mut ra);
        b.display(&mut rb);
        assert_eq!(a.image(), b.image(), "frame {frame}");
        assert_eq!(a.rgba, b.rgba, "frame {frame}");
        assert!(!b.stages.upsample.active());
    }
}

/// A still view traced at half the output's size (a quarter of its pixels a frame)
/// converges to the reference path tracer's image at the output's size: after 256 frames
/// (64 samples per output pixel on average) its error against a 2048-spp reference is that
/// of the output-size render at 64 spp within the spread of the pixels' sample counts.
#[test]
fn a_still_view_converges_to_the_output_size_image() {
    let world = cornell();
    let c = config(0.5);
    let render_at = |spp| -> Vec<Vec3> {
        let c = Config { spp, ..c.clone() };
        render(&world, &c.render_camera(&world), &c).layer(|p| p.mean)
    };
    let (truth, full) = (render_at(2048), render_at(64));
    let up = frames(&world, &c, 256);
    let image = up.image();
    assert_eq!(image.len(), 40 * 30);
    assert!(up.stages.upsample.active());
    let (got, want) = (relmse(&image, &truth), relmse(&full, &truth));
    assert!(
        got < 1.6 * want,
        "upsampled relMSE {got:.3e}, output-size render {want:.3e}"
    );
    // And it is not the render size's image blown up: at 20x15 the same samples give far more
    // error against the output's truth.
    let small = frames(
        &world,
        &Config {
            width: 20,
            height: 15,
            ..config(1.0)
        },
        64,
    );
    let blown: Vec<Vec3> = (0..40 * 30)
        .map(|i| small.image()[(i / 40 / 2) * 20 + (i % 40) / 2])
        .collect();
    assert!(
        relmse(&blown, &truth) > 3.0 * got,
        "{} vs {got}",
        relmse(&blown, &truth)
    );
}

/// Along a move the output is finite and output-sized, and so is every view.
#[test]
fn a_moving_view_gives_output_sized_frames_and_views() {
    let world = cornell();
    let c = config(0.5);
    let mut p = Pipeline::new(c.clone());
    for k in 0..6 {
        let x = 0.05 * k as f32;
        p.set_config(&Config {
            camera: CameraConfig {
                look_from: Some([x, 1.0, 3.5]),
                look_at: Some([x, 1.0, 0.0]),
                ..Default::default()
            },
            ..c.clone()
        });
        let mut report = p.render_frame(&world);
        p.display(&mut report);
        assert!(report.pass_ms("upsample") > 0.0);
        let image = p.image();
        assert_eq!(image.len(), 40 * 30);
        assert!(image
            .iter()
            .all(|v| v.is_finite() && v.min_element() >= 0.0));
        assert_eq!(p.rgba.len(), 40 * 30 * 4);
    }
    let counts = p.linear(&"upsample-samples".parse().unwrap());
    assert!(
        counts.iter().any(|c| c.x != counts[0].x),
        "the samples' view is uniform"
    );
    for view in ["albedo", "upsample-samples", "noisy"] {
        let mode: DisplayMode = view.parse().unwrap();
        assert_eq!(p.linear(&mode).len(), 40 * 30, "{view}");
    }
    // Back to scale 1: the frame is the pipeline's own again.
    p.set_config(&config(1.0));
    p.render_frame(&world);
    assert!(!p.stages.upsample.active());
    assert_eq!(p.image().len(), 40 * 30);
}

#[test]
fn settings_out_of_range_are_refused_by_name() {
    for (scale, alpha, gamma) in [
        (0.1, 0.2, 1.0),
        (1.5, 0.2, 1.0),
        (0.5, 0.0, 1.0),
        (0.5, 0.2, f32::NAN),
    ] {
        let mut c = config(scale);
        c.frame.upsample.alpha = alpha;
        c.frame.upsample.gamma = gamma;
        let e = c.validate().unwrap_err();
        assert!(e.field.starts_with("frame.upsample."), "{e}");
    }
    for target in [-1.0, f32::NAN, 1e9] {
        let mut c = config(1.0);
        c.frame.target_ms = target;
        assert_eq!(c.validate().unwrap_err().field, "frame.target_ms");
    }
    assert_eq!(render_size(0.5, 320, 180), (160, 90));
    assert_eq!(render_size(1.0, 321, 181), (321, 181));
}

/// The frame-time target: a frame that can never be fast enough (a target of a microsecond)
/// lowers the render scale step by step to the lowest, the output staying output-sized; a
/// target no frame misses raises it back to the output's size, where the frame is the
/// pipeline's own again.
#[test]
fn the_target_lowers_the_scale_and_raises_it_again() {
    use pathlight_render::frame::target::STEPS;
    let world = cornell();
    let mut c = config(1.0);
    c.frame.target_ms = 0.001;
    let mut p = Pipeline::new(c.clone());
    let mut scales = Vec::new();
    for _ in 0..40 {
        scales.push(p.render_frame(&world).scale);
    }
    assert_eq!(scales[0], 1.0);
    assert_eq!(
        *scales.last().unwrap(),
        *STEPS.last().unwrap(),
        "{scales:?}"
    );
    assert!(scales.windows(2).all(|w| w[1] <= w[0]), "{scales:?}");
    assert_eq!(p.image().len(), 40 * 30);
    c.frame.target_ms = 1e6;
    p.set_config(&c);
    let mut last = 0.0;
    for _ in 0..400 {
        last = p.render_frame(&world).scale;
    }
    assert_eq!(last, 1.0);
    assert!(!p.stages.upsample.active());
    assert_eq!(p.image().len(), 40 * 30);
}
