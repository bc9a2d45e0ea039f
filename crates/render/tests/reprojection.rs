//! Seed 000's forward reprojection against facts that do not come from its own code: a pure
//! rotation keeps every state's colour exactly and has no view-dependency error, mirrors and
//! glass are never carried, a point hidden by an occluder in the new view is dropped (checked
//! analytically), a translated diffuse view agrees with a fresh render of the new view within
//! the noise of as many samples, a still camera gives the plain pipeline's frames, and the
//! frames do not depend on the thread count.

mod common;

use common::{cornell, in_pool, quad};
use glam::{Vec3, Vec4};
use pathlight_render::camera_path::{CameraPath, PathKind};
use pathlight_render::config::{CameraConfig, FrameConfig};
use pathlight_render::frame::accumulation::PixelStats;
use pathlight_render::frame::adaptive::AdaptiveConfig;
use pathlight_render::frame::reprojection::{Fate, ReprojectionConfig, ReprojectionReport};
use pathlight_render::frame::Pipeline;
use pathlight_render::renderer::render;
use pathlight_render::{Config, World};
use pathlight_scene::{Material, Mesh};

fn config(width: u32, height: u32, samples: u32) -> Config {
    Config {
        width,
        height,
        seed: 11,
        frame: FrameConfig {
            reprojection: ReprojectionConfig {
                enabled: true,
                samples,
                ..ReprojectionConfig::default()
            },
            ..FrameConfig::default()
        },
        ..Config::default()
    }
}

fn with_view(cfg: &Config, view: CameraConfig) -> Config {
    Config {
        camera: view,
        ..cfg.clone()
    }
}

/// `frames` frames of `cfg` through the pipeline.
fn warm(world: &World, cfg: &Config, frames: u32) -> Pipeline {
    let mut pipeline = Pipeline::new(cfg.clone());
    for _ in 0..frames {
        pipeline.render_frame(world);
    }
    pipeline
}

/// Runs only the reprojection pass of a move to `to`: the history it leaves (before the next
/// frame's samples and the aliasing test) and its counts.
fn reproject(
    pipeline: &mut Pipeline,
    world: &World,
    to: &Config,
) -> (Vec<PixelStats>, ReprojectionReport) {
    let from = pipeline.camera().expect("warmed").clone();
    let camera = to.render_camera(world);
    let mut history = pipeline.frame.history.clone();
    let mut probability = pipeline.stages.adaptive.probability.clone();
    let report = pipeline.stages.reprojection.reproject(
        world,
        &from,
        &camera,
        to.width,
        &to.frame.reprojection,
        &mut history,
        &mut probability,
    );
    (history, report)
}

/// The views of a sideways move by `offset` in `steps` steps.
fn sideways(world: &World, offset: f32, steps: u32) -> Vec<CameraConfig> {
    views(
        world,
        CameraPath {
            path: PathKind::Translation,
            offset: [offset, 0.0, 0.0],
            steps,
            ..CameraPath::default()
        },
    )
}

/// The views of `path` (over [`CameraPath::default`]).
fn views(world: &World, path: CameraPath) -> Vec<CameraConfig> {
    world.path_views(&path)
}

#[test]
fn pure_rotation_keeps_every_colour_exactly_and_has_no_view_error() {
    let world = cornell();
    for samples in [1, 4] {
        let rotation = views(
            &world,
            CameraPath {
                path: PathKind::Rotation,
                degrees: 5.0,
                step_degrees: 5.0,
                ..CameraPath::default()
            },
        );
        let mut cfg = with_view(&config(48, 36, samples), rotation[0].clone());
        // The strictest Eq. 15: any error at all would reject.
        cfg.frame.reprojection.max_error = 0.0;
        let mut pipeline = warm(&world, &cfg, 6);
        let before: Vec<PixelStats> = pipeline
            .stages
            .reprojection
            .slots
            .current
            .iter()
            .map(|s| s.stats)
            .collect();
        let to = with_view(&cfg, rotation[1].clone());
        let (history, report) = reproject(&mut pipeline, &world, &to);
        assert_eq!(report.view_error, 0, "{report:?}");
        assert_eq!(report.specular, 0, "the Cornell box is diffuse: {report:?}");
        assert!(report.kept > report.states * 3 / 4, "{report:?}");
        // Every kept state is one of the old states, unchanged.
        let mut kept = 0;
        for s in &pipeline.stages.reprojection.slots.current {
            if s.stats.n > 0 {
                assert!(
                    before.contains(&s.stats),
                    "a state changed on the way: {:?}",
                    s.stats
                );
                kept += 1;
            }
        }
        assert_eq!(kept, report.kept);
        // A pixel's history is the merge of its states: with one state, the state itself.
        if samples == 1 {
            for (h, s) in history
                .iter()
                .zip(&pipeline.stages.reprojection.slots.current)
            {
                assert_eq!(*h, s.stats);
            }
        }
    }
}

/// A diffuse wall (z = 0) facing a camera at (0, 0, 5), with a mirror, a pane of glass, a
/// glossy patch and a small occluder (at z = 2.5, x in [0.7, 1.3]) in front of it, under a
/// constant sky.
fn wall_scene() -> World {
    let diffuse = Material {
        base_color: Vec4::new(0.7, 0.6, 0.5, 1.0),
        roughness: 1.0,
        ..Material::default()
    };
    let mirror = Material {
        base_color: Vec4::ONE,
        metallic: 1.0,
        roughness: 0.0,
        ..Material::default()
    };
    let glass = Material {
        base_color: Vec4::ONE,
        roughness: 0.0,
        transmission: 1.0,
        specular: 1.0,
        ..Material::default()
    };
    let glossy = Material {
        base_color: Vec4::new(0.2, 0.3, 0.8, 1.0),
        roughness: 0.3,
        specular: 1.0,
        ..Material::default()
    };
    let at = |m: Mesh, centre: Vec3| Mesh {
        positions: m.positions.iter().map(|p| *p + centre).collect(),
        ..m
    };
    let meshes = vec![
        quad(0, 2.0, 0.0),
        at(quad(1, 0.4, 0.0), Vec3::new(-1.2, 1.0, 0.01)),
        at(quad(2, 0.4, 0.0), Vec3::new(-1.2, -1.0, 0.01)),
        at(quad(3, 0.4, 0.0), Vec3::new(0.0, -1.2, 0.01)),
        at(quad(0, 0.3, 0.0), Vec3::new(1.0, 0.0, 2.5)),
    ];
    let scene = common::scene(
        meshes,
        vec![diffuse, mirror, glass, glossy],
        Some(Vec3::splat(0.8)),
        Vec3::new(0.0, 0.0, 5.0),
    );
    common::world(scene)
}

fn wall_view(x: f32) -> CameraConfig {
    CameraConfig {
        look_from: Some([x, 0.0, 5.0]),
        look_at: Some([x, 0.0, 0.0]),
        up: Some([0.0, 1.0, 0.0]),
        fov_y: Some(50.0),
        ..CameraConfig::default()
    }
}

/// Whether the segment from `eye` to `p` passes through the occluder of [`wall_scene`].
fn behind_occluder(eye: Vec3, p: Vec3) -> bool {
    let t = (2.5 - eye.z) / (p.z - eye.z);
    let q = eye + (p - eye) * t;
    (0.0..1.0).contains(&t) && (q.x - 1.0).abs() < 0.3 && q.y.abs() < 0.3
}

#[test]
fn mirrors_glass_hidden_points_and_view_dependent_gloss_are_not_carried() {
    let world = wall_scene();
    for samples in [1, 4] {
        let cfg = with_view(&config(64, 48, samples), wall_view(0.0));
        let mut pipeline = warm(&world, &cfg, 4);
        let specular_states = pipeline
            .stages
            .reprojection
            .slots
            .current
            .iter()
            .filter(|s| s.stats.n > 0 && s.is_specular())
            .count() as u64;
        assert!(
            specular_states > 50,
            "{specular_states} mirror and glass states"
        );

        // Translate to the right, where the occluder hides part of the wall that was seen.
        let to = with_view(&cfg, wall_view(1.0));
        let eye = to.render_camera(&world).position();
        let (_, report) = reproject(&mut pipeline, &world, &to);
        let slots = &pipeline.stages.reprojection.slots.current;
        assert!(
            report.specular > 0 && report.specular <= specular_states,
            "{report:?}"
        );
        assert!(
            slots.iter().all(|s| s.stats.n == 0 || !s.is_specular()),
            "a specular state was carried"
        );
        assert!(report.occluded > 10, "{report:?}");
        // (States on the wall: the occluder's own are in front of it.)
        for s in slots
            .iter()
            .filter(|s| s.stats.n > 0 && !s.is_sky() && s.point.z < 0.1)
        {
            assert!(
                !behind_occluder(eye, s.point),
                "a hidden state was carried: {:?}",
                s.point
            );
        }
        // The glossy patch changes with the view: with max_error 1/256 its states are refused,
        // with no bound they are carried (the diffuse wall's error is 0 either way).
        assert!(report.view_error > 10, "{report:?}");
        let mut pipeline = warm(&world, &cfg, 4);
        let mut lax = to.clone();
        lax.frame.reprojection.max_error = f32::INFINITY;
        let (_, report) = reproject(&mut pipeline, &world, &lax);
        assert_eq!(report.view_error, 0, "{report:?}");
    }
}

/// Mean squared error of `image` against `reference` over the pixels `keep` selects.
fn mse(image: &[Vec3], reference: &[Vec3], keep: &[bool]) -> f64 {
    let (mut sum, mut n) = (0.0, 0);
    for ((a, b), &k) in image.iter().zip(reference).zip(keep) {
        if k {
            sum += f64::from((*a - *b).length_squared()) / 3.0;
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// Pixels whose footprint sees more than one surface (mesh or plane): their corners' and
/// centre's camera rays, traced without the pipeline.
fn edges(world: &World, camera: &pathlight_render::Camera, width: u32, height: u32) -> Vec<bool> {
    let surface = |x: f32, y: f32| {
        let ray = camera.primary_ray(glam::Vec2::new(x, y), glam::Vec2::splat(0.5));
        world.accel.intersect(&ray).map(|hit| {
            let instance = &world.scene.instances[hit.instance as usize];
            let mesh = &world.scene.meshes[instance.mesh as usize];
            let [a, b, c] = mesh.indices[hit.triangle as usize].map(|i| mesh.positions[i as usize]);
            let n = (b - a).cross(c - a).normalize();
            (
                instance.mesh,
                (n * 100.0).round().as_ivec3(),
                (n.dot(a) * 100.0).round() as i32,
            )
        })
    };
    (0..height)
        .flat_map(|y| (0..width).map(move |x| (x as f32, y as f32)))
        .map(|(x, y)| {
            let centre = surface(x + 0.5, y + 0.5);
            [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                .iter()
                .any(|(dx, dy)| surface(x + dx, y + dy) != centre)
        })
        .collect()
}

#[test]
fn a_translated_diffuse_view_agrees_with_a_fresh_render() {
    let world = cornell();
    let path = sideways(&world, 0.1, 2);
    let frames = 64;
    for samples in [1, 4] {
        let cfg = with_view(&config(48, 36, samples), path[0].clone());
        let mut pipeline = warm(&world, &cfg, frames);
        let to = with_view(&cfg, path[2].clone());
        pipeline.set_config(&to);
        let r = pipeline.render_frame(&world);
        let report = r.reprojection.expect("a move");
        // At 48 x 36 a third of the Cornell box's pixels lie on an edge or next to one.
        assert!(report.kept > report.states / 2, "{report:?}");
        assert_eq!(report.specular, 0);

        let plain = Config {
            frame: FrameConfig::default(),
            ..to.clone()
        };
        let reference = render(
            &world,
            &plain.render_camera(&world),
            &Config {
                spp: 1024,
                seed: 99,
                ..plain.clone()
            },
        );
        let fresh = render(
            &world,
            &plain.render_camera(&world),
            &Config {
                spp: frames,
                seed: 5,
                ..plain.clone()
            },
        );
        let reference: Vec<Vec3> = reference.pixels.iter().map(|p| p.mean).collect();
        let fresh: Vec<Vec3> = fresh.pixels.iter().map(|p| p.mean).collect();
        let image = pipeline.image();
        // The pixels that kept (most of) their history, edges of the new view included:
        // a state that lands on a pixel whose footprint covers another surface too would
        // bring only part of the truth, and must have been refused there (module docs).
        let edges = edges(&world, &plain.render_camera(&world), 48, 36);
        let keep: Vec<bool> = pipeline
            .frame
            .history
            .iter()
            .map(|h| h.n > frames / 2)
            .collect();
        let kept_edges = keep.iter().zip(&edges).filter(|(&k, &e)| k && e).count();
        eprintln!("samples {samples}: {kept_edges} edge pixels kept their history");
        let kept = keep.iter().filter(|&&k| k).count();
        assert!(
            kept > keep.len() / 2,
            "{kept} of {} pixels kept",
            keep.len()
        );
        let (carried, fresh) = (
            mse(&image, &reference, &keep),
            mse(&fresh, &reference, &keep),
        );
        eprintln!(
            "samples {samples}: MSE {carried:.3e} carried vs {fresh:.3e} fresh over {kept} pixels"
        );
        assert!(
            carried < 1.5 * fresh,
            "samples {samples}: MSE {carried:.3e} carried vs {fresh:.3e} fresh at {frames} spp"
        );
    }
}

#[test]
fn fresh_spp_fills_the_holes_of_a_move_at_once() {
    let world = cornell();
    let path = sideways(&world, 0.2, 1);
    let frames = 16;
    let pixels = 40 * 30;
    let mut counts = Vec::new();
    for fresh_spp in [0, 8] {
        let mut cfg = with_view(&config(40, 30, 1), path[0].clone());
        cfg.frame.reprojection.fresh_spp = fresh_spp;
        let mut pipeline = warm(&world, &cfg, frames);
        pipeline.set_config(&with_view(&cfg, path[1].clone()));
        let report = pipeline.render_frame(&world);
        let kept = pipeline
            .frame
            .history
            .iter()
            .filter(|h| h.n > frames / 2)
            .count();
        let holes = pipeline.frame.history.iter().filter(|h| h.n <= 8).count();
        assert!(
            kept > pixels / 3 && holes > 20,
            "{kept} kept, {holes} holes"
        );
        let n: Vec<u32> = pipeline.frame.history.iter().map(|h| h.n).collect();
        let next = pipeline.render_frame(&world);
        let least = pipeline.frame.history.iter().map(|h| h.n).min().unwrap();
        if fresh_spp == 0 {
            // The thesis: one sample per pixel per frame, holes included.
            assert_eq!(n.iter().min(), Some(&1));
            assert_eq!(report.samples, pixels as u64);
            assert_eq!(next.samples, pixels as u64);
        } else {
            // Every hole took its 8 samples, the pixels with history one each. A pixel whose
            // states the edge test refused (it needs the neighbours' G-buffer pixels, so it
            // runs after the lighting pass has chosen the samples) takes the 7 it lacks in the
            // same frame too.
            assert!(n.iter().all(|&n| n >= 8), "{n:?}");
            let refused = (0..pixels)
                .filter(|&p| pipeline.stages.reprojection.fate(p) == Fate::Aliasing)
                .count();
            assert!(refused > 0, "no state refused by the aliasing test");
            let taken: u64 = n.iter().map(|&n| if n <= 8 { n } else { 1 } as u64).sum();
            assert_eq!(report.samples, taken);
            assert_eq!(next.samples, pixels as u64);
            assert_eq!(least, 9);
        }
        counts.push(pipeline.render_frame(&world).samples);
    }
    // Then one sample everywhere again.
    assert_eq!(counts, [pixels as u64; 2]);
}

#[test]
fn a_still_camera_gives_the_plain_frames() {
    let world = cornell();
    for samples in [1, 4] {
        let cfg = config(40, 30, samples);
        let plain = Config {
            frame: FrameConfig::default(),
            ..cfg.clone()
        };
        let a = warm(&world, &cfg, 8);
        let b = warm(&world, &plain, 8);
        for (x, y) in a.frame.history.iter().zip(&b.frame.history) {
            assert_eq!(x.n, y.n);
            assert!(
                x.mean()
                    .abs_diff_eq(y.mean(), 1e-6 * (1.0 + y.mean().max_element())),
                "{:?} vs {:?}",
                x.mean(),
                y.mean()
            );
        }
    }
}

#[test]
fn switches_off_keep_the_plain_frames_bit_for_bit() {
    // Technique parameters without their switches change nothing.
    let world = cornell();
    let path = views(
        &world,
        CameraPath {
            path: PathKind::Orbit,
            degrees: 20.0,
            steps: 3,
            ..CameraPath::default()
        },
    );
    let plain = Config {
        width: 32,
        height: 24,
        ..Config::default()
    };
    let mut tuned = plain.clone();
    tuned.frame.adaptive = AdaptiveConfig {
        enabled: false,
        min_spp: 2,
        max_spp: 8,
        keep_sampling: true,
        keep_sampling_after: 3,
        measure: pathlight_render::frame::adaptive::Measure::Error,
        budget: true,
        ..AdaptiveConfig::default()
    };
    tuned.frame.reprojection = ReprojectionConfig {
        enabled: false,
        samples: 4,
        max_error: 0.5,
        fresh_spp: 8,
        ..ReprojectionConfig::default()
    };
    tuned.frame.restir = pathlight_render::frame::restir::RestirConfig {
        enabled: false,
        candidates: 3,
        unbiased: true,
        iterations: 4,
        ..Default::default()
    };
    tuned.frame.filter = pathlight_denoise::FilterConfig {
        method: pathlight_denoise::Method::None,
        data_driven: pathlight_denoise::DataDrivenConfig {
            kernel: 7,
            holes: true,
            sigma_normal_lobe: 2.0,
            sky_coverage: false,
            sure: true,
            sure_radius: 5,
            refresh_growth: 1.25,
            colour_weights: pathlight_denoise::ColourWeights::Equal,
            ..Default::default()
        },
        svgf: pathlight_denoise::SvgfConfig {
            atrous_iterations: 3,
            atrous_kernel: 3,
            normal_width: 4.0,
            taa: true,
            converge: true,
            still_handover: 1,
            ..Default::default()
        },
        ..Default::default()
    };
    let run = |cfg: &Config| {
        let mut pipeline = Pipeline::new(cfg.clone());
        let mut images = Vec::new();
        for view in &path {
            pipeline.set_config(&with_view(cfg, view.clone()));
            for _ in 0..2 {
                pipeline.render_frame(&world);
            }
            images.push((
                pipeline.frame.history.clone(),
                pipeline.stages.filter.image.clone(),
            ));
        }
        images
    };
    assert!(run(&plain) == run(&tuned));
}

#[test]
fn reprojected_frames_do_not_depend_on_the_thread_count() {
    let world = cornell();
    let path = views(
        &world,
        CameraPath {
            path: PathKind::Rotation,
            degrees: 30.0,
            step_degrees: 10.0,
            ..CameraPath::default()
        },
    );
    let mut cfg = config(40, 30, 4);
    cfg.frame.adaptive = AdaptiveConfig {
        enabled: true,
        min_spp: 2,
        max_spp: 4,
        ..AdaptiveConfig::default()
    };
    let run = || {
        let mut pipeline = Pipeline::new(cfg.clone());
        let mut out = Vec::new();
        for view in &path {
            pipeline.set_config(&with_view(&cfg, view.clone()));
            for _ in 0..5 {
                let r = pipeline.render_frame(&world);
                out.push((r.samples, r.reprojection));
            }
        }
        (
            out,
            pipeline.frame.history.clone(),
            pipeline.stages.adaptive.probability.clone(),
        )
    };
    let one = in_pool(1, run);
    let two = in_pool(2, run);
    assert!(one == two, "frames differ between 1 and 2 threads");
}

#[test]
fn seed_000_display_modes_show_the_techniques() {
    use pathlight_render::frame::display::DisplayMode;
    let world = wall_scene();
    let mut cfg = with_view(&config(64, 48, 1), wall_view(0.0));
    cfg.frame.adaptive = AdaptiveConfig {
        enabled: true,
        min_spp: 1,
        max_spp: 4,
        // The thesis's Eq. 12 and frames of one iteration each.
        measure: pathlight_render::frame::adaptive::Measure::Luminance,
        budget: false,
        cap: false,
        ..AdaptiveConfig::default()
    };
    let mut pipeline = warm(&world, &cfg, 6);
    pipeline.set_config(&with_view(&cfg, wall_view(1.0)));
    pipeline.render_frame(&world);
    for mode in [
        DisplayMode::named("probability"),
        DisplayMode::named("reprojected"),
        DisplayMode::named("rejection"),
        DisplayMode::named("samples"),
    ] {
        let mut c = pipeline.config().clone();
        c.display.mode = mode.clone();
        pipeline.set_config(&c);
        let mut r = pipeline.render_frame(&world);
        pipeline.display(&mut r);
        let distinct: std::collections::HashSet<&[u8]> = pipeline.rgba.chunks(4).collect();
        // Reprojected with one state per pixel: kept or not.
        let least = if mode == DisplayMode::named("reprojected") {
            2
        } else {
            3
        };
        assert!(
            distinct.len() >= least,
            "{mode:?}: {} colours",
            distinct.len()
        );
    }
}

/// The combination with the `error` measure and frames of a budget: after a move the new
/// pixels (holes, a few samples each) take most of the frames' samples and the carried ones
/// (dozens each) few, where the thesis's Algorithm 2 gives each new pixel one per frame.
#[test]
fn the_error_measure_samples_the_new_pixels_after_a_move() {
    use pathlight_render::frame::adaptive::Measure;
    let world = cornell();
    let path = sideways(&world, 0.2, 1);
    let pixels = 40 * 30;
    let mut cfg = with_view(&config(40, 30, 1), path[0].clone());
    cfg.frame.reprojection.fresh_spp = 8;
    cfg.frame.adaptive = AdaptiveConfig {
        enabled: true,
        cap: true,
        measure: Measure::Error,
        budget: true,
        ..AdaptiveConfig::default()
    };
    let mut pipeline = warm(&world, &cfg, 48);
    pipeline.set_config(&with_view(&cfg, path[1].clone()));
    pipeline.render_frame(&world);
    let before: Vec<u32> = pipeline.frame.history.iter().map(|h| h.n).collect();
    let new: Vec<bool> = before.iter().map(|&n| n <= 8).collect();
    let (holes, carried) = (
        new.iter().filter(|&&b| b).count(),
        before.iter().filter(|&&n| n > 24).count(),
    );
    assert!(
        holes > 20 && carried > pixels / 3,
        "{holes} new, {carried} carried"
    );
    let mut traced = 0;
    for _ in 0..3 {
        traced += pipeline.render_frame(&world).samples;
    }
    // Frames of a budget: about one sample per pixel each (the budget counts the schedule's
    // samples; the repair of pixels whose states the edge test drops comes on top).
    let uniform = 3 * pixels as u64;
    assert!(
        traced <= uniform + uniform / 10 && traced >= uniform - uniform / 3,
        "{traced} samples in 3 frames"
    );
    // (A carried state a later sample disagrees with is dropped: its pixel starts again.)
    let added = |pick: &dyn Fn(usize) -> bool| {
        let (sum, count) = (0..pixels)
            .filter(|&p| pick(p) && pipeline.frame.history[p].n >= before[p])
            .fold((0u64, 0u64), |(s, c), p| {
                (
                    s + u64::from(pipeline.frame.history[p].n - before[p]),
                    c + 1,
                )
            });
        sum as f64 / count as f64
    };
    let (to_new, to_carried) = (added(&|p| new[p]), added(&|p| before[p] > 24));
    assert!(
        to_new > 3.0 && to_new > 4.0 * to_carried,
        "samples per new pixel {to_new}, per carried pixel {to_carried}"
    );
}
