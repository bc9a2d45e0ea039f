//! Seed 001's reconstruction filter as a pass of the frame pipeline, on the Cornell box: it
//! leaves the history alone (the unfiltered image is bit for bit the plain pipeline's), brings
//! the image closer to a converged reference than the unfiltered one, its feature statistics
//! see the box's edges and not its flat walls, it does not restart the accumulation, and its
//! image does not depend on the thread count. RPF's sample vectors mark the sky and put an
//! escaped bounce's vertex where the environment it sees is.

mod common;

use common::{cornell, in_pool, quad, scene, world};
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
/// The reference path tracer's image of `c`'s view at 1024 spp (each pixel's mean).
fn reference(world: &World, c: &Config) -> Vec<glam::Vec3> {
    let film = render(
        world,
        &c.render_camera(world),
        &Config {
            spp: 1024,
            ..c.clone()
        },
    );
    film.pixels.iter().map(|p| p.mean).collect()
}

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
    for (a, b) in plain.frame.history.iter().zip(&filtered.frame.history) {
        assert_eq!(a, b);
    }
    assert_eq!(
        plain.image(),
        filtered.linear(&DisplayMode::named("accumulated"))
    );
    // Against the reference path tracer at 1024 spp, the filtered 8-spp image is much closer
    // than the unfiltered one (eval's 001-quality measures 0.11x at 320x180 with the 21-pixel
    // window; here 128x96 with a 9-pixel one, the same share of the image).
    let mut c = config(Method::None);
    (c.width, c.height) = (128, 96);
    let mut f = c.clone();
    f.frame.filter.method = Method::DataDriven;
    f.frame.filter.data_driven.kernel = 9;
    let (plain, filtered) = (frames(&world, &c, 8), frames(&world, &f, 8));
    let reference = reference(&world, &c);
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
        .map(|i| p.value(&DisplayMode::named("variance-normal"), i).x)
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
    c.frame.filter.data_driven.kernel = 7;
    p.set_config(&c);
    assert_eq!(p.render_frame(&world).accumulated, 5);
    c.frame.filter.method = Method::None;
    p.set_config(&c);
    let r = p.render_frame(&world);
    assert_eq!(r.accumulated, 6);
    // Off again: the image is the accumulated one.
    assert_eq!(p.image(), p.linear(&DisplayMode::named("accumulated")));
}

#[test]
fn the_filtered_image_does_not_depend_on_the_thread_count() {
    let world = cornell();
    let mut c = config(Method::DataDriven);
    c.frame.filter.data_driven.holes = true;
    let image = |threads| in_pool(threads, || frames(&world, &c, 4).image());
    let one = image(1);
    assert_eq!(one, image(2));
    assert_eq!(one, image(3));
}

/// The data-driven filter's SURE blend (`sure`) on a converging still view: with a colour test
/// far too loose (sigma 30 standard errors) the filter blurs the box's shading at 64 samples,
/// and the blend takes each pixel's own light back where the filter moved it further than its
/// noise explains: the image comes closer to the reference path tracer's. The shares it shows
/// (`sure-share`) are in [0, 1], and are forgotten when the filter stops.
#[test]
fn the_sure_blend_brings_an_overblurred_image_back_toward_the_reference() {
    let world = cornell();
    let mut loose = config(Method::DataDriven);
    loose.frame.filter.data_driven.sigma_direct = 30.0;
    loose.frame.filter.data_driven.sigma_indirect = 30.0;
    let mut sure = loose.clone();
    sure.frame.filter.data_driven.sure = true;
    let (blurred, blended) = (frames(&world, &loose, 64), frames(&world, &sure, 64));
    let plain = frames(&world, &config(Method::None), 64);
    let reference = reference(&world, &loose);
    let (unfiltered, before, after) = (
        relmse(&plain.image(), &reference),
        relmse(&blurred.image(), &reference),
        relmse(&blended.image(), &reference),
    );
    assert!(
        before > unfiltered && after < 0.8 * before,
        "relMSE {after:.3e} blended, {before:.3e} without, {unfiltered:.3e} unfiltered"
    );
    let n = 64 * 48;
    assert!(blurred.stages.filter.shares().is_empty());
    assert_eq!(blended.stages.filter.shares().len(), n);
    let mut valid = 0;
    for i in 0..n {
        let v = blended.value(&DisplayMode::named("sure-share"), i);
        if v.x.is_nan() {
            continue;
        }
        valid += 1;
        assert!(
            (0.0..=1.0).contains(&v.x) && (0.0..=1.0).contains(&v.y),
            "{v}"
        );
    }
    assert!(valid > n / 2, "{valid} blended pixels");
    let mut p = blended;
    let mut off = sure.clone();
    off.frame.filter.method = Method::None;
    p.set_config(&off);
    p.render_frame(&world);
    assert!(p.stages.filter.shares().is_empty());
    assert_eq!(
        p.value(&DisplayMode::named("sure-share"), 0),
        glam::Vec3::splat(-1.0)
    );
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
    let reference = reference(&world, &c);
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

/// Temporal antialiasing alone (`method = "taa"`): the first frame has no previous output and
/// is the unfiltered image bit for bit; over single-sample frames (no accumulation) it blends
/// each frame with its clamped history, closer to the reference than the frame alone, and the
/// same on one and two threads.
#[test]
fn temporal_antialiasing_alone_blends_frames_toward_the_reference() {
    let world = cornell();
    let mut c = config(Method::None);
    (c.width, c.height) = (128, 96);
    c.frame.accumulate = false;
    let mut t = c.clone();
    t.frame.filter.method = Method::Taa;
    assert_eq!(frames(&world, &t, 1).image(), frames(&world, &c, 1).image());
    let reference = reference(&world, &c);
    let plain = frames(&world, &c, 16).image();
    let run = |threads| in_pool(threads, || frames(&world, &t, 16).image());
    let blended = run(2);
    let (before, after) = (relmse(&plain, &reference), relmse(&blended, &reference));
    assert!(
        after < 0.7 * before,
        "relMSE {after:.3e} antialiased vs {before:.3e}"
    );
    assert_eq!(blended, run(1));
}

/// SVGF hands over to the data-driven filter after `svgf.still_handover` frames of a still
/// camera: before, its frames are SVGF's bit for bit, from then on the data-driven filter's of
/// the same accumulated image bit for bit. When the camera moves on, SVGF filters again with
/// the history it had when it stopped, the still view's: the frame is that of SVGF stopped
/// after the same still frames and moved the same way, bit for bit.
#[test]
fn svgf_hands_over_to_the_data_driven_filter_while_the_camera_is_still() {
    let world = cornell();
    let at = |x: f32, method: Method, handover: u32| {
        let mut c = Config {
            camera: pathlight_render::config::CameraConfig {
                look_from: Some([x, 1.0, 3.5]),
                look_at: Some([x, 1.0, 0.0]),
                up: Some([0.0, 1.0, 0.0]),
                fov_y: Some(40.0),
                ..Default::default()
            },
            ..config(method)
        };
        c.frame.filter.svgf.still_handover = handover;
        c
    };
    let mut svgf = Pipeline::new(at(0.0, Method::Svgf, 0));
    let mut data_driven = Pipeline::new(at(0.0, Method::DataDriven, 0));
    let mut handover = Pipeline::new(at(0.0, Method::Svgf, 4));
    for frame in 1..=3 {
        for p in [&mut svgf, &mut data_driven, &mut handover] {
            p.render_frame(&world);
        }
        assert!(handover.image() == svgf.image(), "frame {frame}");
    }
    for frame in 4..=6 {
        for p in [&mut data_driven, &mut handover] {
            p.render_frame(&world);
        }
        assert!(handover.image() == data_driven.image(), "frame {frame}");
    }
    // SVGF stopped after the frames before the handover, and both moved the same way.
    for p in [&mut svgf, &mut handover] {
        let c = at(
            0.05,
            Method::Svgf,
            p.config().frame.filter.svgf.still_handover,
        );
        p.set_config(&c);
        p.render_frame(&world);
    }
    assert!(handover.image() == svgf.image());
    assert!(handover.image() != data_driven.image());
}

/// `refresh_growth`: a still view's data-driven image is filtered again only once the
/// accumulated frames have grown by the factor (1.25: at frames 1, 2, 3, 4, 5, 7, 9, 12), and
/// is the filter's image of the frame it was last filtered at meanwhile, but for the light a
/// pixel shows as its own (here the light source, which passes through), which follows the
/// history; a new configuration or a camera move filters at once. At most 1, every frame is
/// filtered, as by default.
#[test]
fn a_still_view_is_filtered_again_as_its_frames_grow() {
    let world = cornell();
    let with = |growth: f32| {
        let mut c = config(Method::DataDriven);
        c.frame.filter.data_driven.refresh_growth = growth;
        c
    };
    let (mut every, mut once, mut grown) = (
        Pipeline::new(with(0.0)),
        Pipeline::new(with(1.0)),
        Pipeline::new(with(1.25)),
    );
    let (mut last, mut passed) = (Vec::new(), Vec::new());
    let mut through = 0;
    for frame in 1..=12u32 {
        for p in [&mut every, &mut once, &mut grown] {
            assert_eq!(p.render_frame(&world).accumulated, frame);
        }
        assert!(once.image() == every.image(), "frame {frame}");
        let (image, filtered) = (grown.image(), every.image());
        let accumulated = grown.linear(&DisplayMode::named("accumulated"));
        if [1, 2, 3, 4, 5, 7, 9, 12].contains(&frame) {
            assert!(image == filtered, "frame {frame}");
            // The pixels that passed through (the light source; the sky outside the box).
            passed = image
                .iter()
                .zip(&accumulated)
                .map(|(x, a)| x == a)
                .collect();
            last = image;
            continue;
        }
        assert!(image != filtered, "frame {frame}");
        for (i, (&x, &was)) in image.iter().zip(&last).enumerate() {
            if passed[i] {
                // Passed through at the refresh: the history's light now.
                let a = accumulated[i];
                assert!((x - a).abs().max_element() <= 1e-5 * a.max_element().max(1.0));
                through += 1;
            } else {
                assert_eq!(x, was, "frame {frame}, pixel {i}");
            }
        }
    }
    assert!(through > 0, "the light source passes through");
    // A new configuration filters at once, and so does a camera move (a new epoch).
    let mut c = with(1.25);
    c.frame.filter.data_driven.kernel = 7;
    let mut moved = c.clone();
    moved.camera.look_from = Some([0.05, 1.0, 3.5]);
    for (c, accumulated) in [(c, 13), (moved, 1)] {
        for p in [&mut every, &mut grown] {
            let growth = p.config().frame.filter.data_driven.refresh_growth;
            let mut c = c.clone();
            c.frame.filter.data_driven.refresh_growth = growth;
            p.set_config(&c);
            assert_eq!(p.render_frame(&world).accumulated, accumulated);
        }
        assert!(grown.image() == every.image());
    }
}

/// `refresh_growth` with the SURE blend: between refreshes each pixel shows the image of the
/// last refresh plus its shares of its own direct and indirect light (the blend's, `sure-share`)
/// times how far the history's light has moved since.
#[test]
fn between_refreshes_a_pixel_keeps_its_own_light_fresh() {
    let world = cornell();
    // Inside the box, so that no pixel's samples leave it (a silhouette against the sky is
    // shown as it was: its sky part is not the pixel's own light).
    let mut c = Config {
        camera: pathlight_render::config::CameraConfig {
            look_from: Some([0.0, 1.0, 0.5]),
            look_at: Some([0.0, 1.0, -1.0]),
            up: Some([0.0, 1.0, 0.0]),
            fov_y: Some(60.0),
            ..Default::default()
        },
        ..config(Method::DataDriven)
    };
    c.frame.filter.data_driven.sure = true;
    c.frame.filter.data_driven.refresh_growth = 1.25;
    // A colour test far too loose, so that the blend gives many pixels their own light back.
    (
        c.frame.filter.data_driven.sigma_direct,
        c.frame.filter.data_driven.sigma_indirect,
    ) = (30.0, 30.0);
    let mut p = Pipeline::new(c);
    let light = |p: &Pipeline| {
        (
            p.linear(&DisplayMode::named("direct")),
            p.linear(&DisplayMode::named("indirect")),
        )
    };
    let (mut last, mut shares, mut then) = (Vec::new(), Vec::new(), (Vec::new(), Vec::new()));
    let mut moved = 0;
    for frame in 1..=11u32 {
        p.render_frame(&world);
        if [1, 2, 3, 4, 5, 7, 9].contains(&frame) {
            (last, shares, then) = (p.image(), p.stages.filter.shares().to_vec(), light(&p));
            continue;
        }
        let (direct, indirect) = light(&p);
        for (i, &x) in p.image().iter().enumerate() {
            let [d, n] = shares[i];
            if !(d.is_finite() && n.is_finite()) {
                continue; // passed through
            }
            let expected = last[i] + (direct[i] - then.0[i]) * d + (indirect[i] - then.1[i]) * n;
            let scale = expected.abs().max_element().max(1.0);
            assert!(
                (x - expected).abs().max_element() <= 1e-4 * scale,
                "frame {frame}, pixel {i}: {x} against {expected}"
            );
            if d > 0.5 && x != last[i] {
                moved += 1;
            }
        }
    }
    assert!(
        moved > 0,
        "some pixel takes its own light back and keeps it fresh"
    );
}

/// RPF's vectors of a quad under a constant sky, seen from its front: a camera ray that misses
/// the quad is the sky's; every bounce off the quad leaves the scene, so its second vertex is
/// a scene's diagonal (here 2 sqrt 2) from the first along the bounce, its normal facing back.
#[test]
fn rpf_vectors_mark_the_sky_and_place_escaped_bounces_on_it() {
    use pathlight_render::camera::Camera;
    use pathlight_render::rpf::{trace, RANDOM};
    use std::sync::atomic::AtomicBool;

    let grey = pathlight_scene::Material {
        metallic: 0.0,
        ..Default::default()
    };
    let from = glam::Vec3::new(0.0, 0.0, 4.0);
    let world = world(scene(
        vec![quad(0, 1.0, 0.0)],
        vec![grey],
        Some(glam::Vec3::ONE),
        from,
    ));
    let c = Config {
        width: 24,
        height: 16,
        spp: 4,
        ..Config::default()
    };
    let camera = Camera::new(&world.scene.cameras[0], c.width, c.height);
    let set = trace(&world, &camera, &c, &AtomicBool::new(false), &|_| {})
        .unwrap()
        .unwrap();
    let far = 2.0 * 2f32.sqrt();
    let f = 2 + RANDOM;
    let (mut sky, mut ground, mut bounced) = (0, 0, 0);
    for (i, v) in set.data.chunks_exact(set.stride()).enumerate() {
        let at = |k: usize| glam::Vec3::from_slice(&v[k..k + 3]);
        let (direction, p1, p2, n2) = (at(4), at(f), at(f + 6), at(f + 9));
        if set.sky[i] {
            sky += 1;
            assert_eq!((p1, p2), (glam::Vec3::ZERO, glam::Vec3::ZERO), "sample {i}");
        } else {
            ground += 1;
            assert!(
                p1.x.abs() <= 1.0 + 1e-4 && p1.z.abs() < 1e-4,
                "sample {i}: {p1}"
            );
            if direction == glam::Vec3::ZERO {
                // No bounce (the path ended at the quad): no second vertex.
                assert_eq!((p2, n2), (glam::Vec3::ZERO, glam::Vec3::ZERO), "sample {i}");
                continue;
            }
            bounced += 1;
            assert!(direction.z > 0.0, "sample {i}: bounce {direction}");
            assert!(
                (p2 - (p1 + far * direction)).length() < 1e-4,
                "sample {i}: {p2}"
            );
            assert!((n2 + direction).length() < 1e-6, "sample {i}: {n2}");
        }
    }
    // The quad's 2 units at 4 units' distance fill 2 / (2 * 4 tan 20 deg) = 69% of the height
    // and 46% of the width (aspect 1.5): 31% of the image.
    let share = ground as f32 / (sky + ground) as f32;
    assert!(
        (share - 0.315).abs() < 0.03,
        "{sky} sky samples, {ground} others"
    );
    assert!(bounced > ground * 3 / 4, "{bounced} of {ground} bounced");
}
