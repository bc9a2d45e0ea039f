//! Seed 001's reconstruction filter as a pass of the frame pipeline, on the Cornell box: it
//! leaves the history alone (the unfiltered image is bit for bit the plain pipeline's), brings
//! the image closer to a converged reference than the unfiltered one, its feature statistics
//! see the box's edges and not its flat walls, it does not restart the accumulation, and its
//! image does not depend on the thread count.

mod common;

use common::{cornell, in_pool};
use pathlight_render::denoise::Method;
use pathlight_render::frame::display::DisplayMode;
use pathlight_render::frame::{Pipeline, FILTER};
use pathlight_render::renderer::render;
use pathlight_render::{Config, World};

fn config(method: Method) -> Config {
    let mut c = Config {
        width: 64,
        height: 48,
        seed: 3,
        ..Config::default()
    };
    c.frame.filter.method = method;
    c
}

fn frames(world: &World, c: &Config, n: u32) -> Pipeline {
    let mut p = Pipeline::new(c.clone());
    for _ in 0..n {
        let r = p.render_frame(world);
        assert_eq!(
            r.passes.iter().any(|p| p.pass == FILTER),
            c.frame.filter.method != Method::None
        );
    }
    p
}

/// Relative MSE: per pixel and channel (x - r)^2 / (r^2 + 0.01), averaged.
fn relmse(a: &[glam::Vec3], reference: &[glam::Vec3]) -> f64 {
    a.iter()
        .zip(reference)
        .map(|(x, r)| {
            let (x, r) = (x.as_dvec3(), r.as_dvec3());
            ((x - r) * (x - r) / (r * r + 0.01)).element_sum() / 3.0
        })
        .sum::<f64>()
        / a.len() as f64
}

#[test]
fn the_filter_keeps_the_history_and_lowers_the_error() {
    let world = cornell();
    let plain = frames(&world, &config(Method::None), 8);
    let filtered = frames(&world, &config(Method::DataDriven), 8);
    // The history, and so the unfiltered image, is the plain pipeline's, bit for bit.
    for (a, b) in plain.history.iter().zip(&filtered.history) {
        assert_eq!(a, b);
    }
    assert_eq!(
        plain.image(),
        filtered.sources().linear(DisplayMode::Accumulated)
    );
    // Against the reference path tracer at 1024 spp, the filtered 8-spp image is much closer
    // than the unfiltered one (eval's 001-quality measures 0.29x at 320x180 with the 21-pixel
    // window; here 128x96 with a 9-pixel one, the same share of the image).
    let mut c = config(Method::None);
    (c.width, c.height) = (128, 96);
    let mut f = c.clone();
    f.frame.filter.method = Method::DataDriven;
    f.frame.filter.kernel = 9;
    let (plain, filtered) = (frames(&world, &c, 8), frames(&world, &f, 8));
    let reference = render(&world, &world.camera(&c), &Config { spp: 1024, ..c });
    let reference: Vec<glam::Vec3> = reference.pixels.iter().map(|p| p.mean).collect();
    let (before, after) = (
        relmse(&plain.image(), &reference),
        relmse(&filtered.image(), &reference),
    );
    assert!(
        after < 0.5 * before,
        "relMSE {after:.3e} filtered vs {before:.3e}"
    );
}

#[test]
fn feature_statistics_see_edges_and_not_flat_walls() {
    let world = cornell();
    let p = frames(&world, &config(Method::DataDriven), 16);
    let normal_variance: Vec<f32> = (0..64 * 48)
        .map(|i| p.sources().value(DisplayMode::VarianceNormal, i).x)
        .collect();
    // Inside a flat wall every sample has the same normal, whatever the jitter: most pixels.
    let flat = normal_variance.iter().filter(|v| **v == 0.0).count();
    assert!(flat > 64 * 48 / 2, "{flat} pixels without normal variance");
    // Where two walls meet, a pixel's samples see both: a few pixels, along lines.
    let edges = normal_variance.iter().filter(|v| **v > 0.1).count();
    assert!((30..64 * 48 / 4).contains(&edges), "{edges} edge pixels");
}

#[test]
fn switching_the_filter_keeps_the_accumulation() {
    let world = cornell();
    let mut c = config(Method::None);
    let mut p = Pipeline::new(c.clone());
    for _ in 0..3 {
        p.render_frame(&world);
    }
    c.frame.filter.method = Method::DataDriven;
    p.set_config(&c);
    let r = p.render_frame(&world);
    assert_eq!((r.accumulated, r.epoch), (4, 0));
    assert!(r.passes.iter().any(|p| p.pass == FILTER));
    c.frame.filter.kernel = 7;
    p.set_config(&c);
    assert_eq!(p.render_frame(&world).accumulated, 5);
    c.frame.filter.method = Method::None;
    p.set_config(&c);
    let r = p.render_frame(&world);
    assert_eq!(r.accumulated, 6);
    // Off again: the image is the accumulated one.
    assert_eq!(p.image(), p.sources().linear(DisplayMode::Accumulated));
}

#[test]
fn the_filtered_image_does_not_depend_on_the_thread_count() {
    let world = cornell();
    let mut c = config(Method::DataDriven);
    c.frame.filter.holes = true;
    let image = |threads| in_pool(threads, || frames(&world, &c, 4).image());
    let one = image(1);
    assert_eq!(one, image(2));
    assert_eq!(one, image(3));
}

/// The spatio-temporal filter on single-sample frames of a still camera (no accumulation: each
/// frame stands alone): its history makes the 16th frame far closer to the reference than the
/// frame's own sample, and its image does not depend on the thread count.
#[test]
fn svgf_brings_single_sample_frames_close_to_the_reference() {
    let world = cornell();
    let mut c = config(Method::None);
    (c.width, c.height) = (128, 96);
    c.frame.accumulate = false;
    let mut s = c.clone();
    s.frame.filter.method = Method::Svgf;
    let reference = render(
        &world,
        &world.camera(&c),
        &Config {
            spp: 1024,
            ..c.clone()
        },
    );
    let reference: Vec<glam::Vec3> = reference.pixels.iter().map(|p| p.mean).collect();
    let plain = frames(&world, &c, 16);
    let run = |threads| in_pool(threads, || frames(&world, &s, 16).image());
    let filtered = run(2);
    let (before, after) = (
        relmse(&plain.image(), &reference),
        relmse(&filtered, &reference),
    );
    assert!(
        after < 0.3 * before,
        "relMSE {after:.3e} filtered vs {before:.3e}"
    );
    assert_eq!(filtered, run(1));
}
