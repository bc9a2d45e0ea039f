//! Seed 002's texture-space cache in the frame pipeline: every block shaded once per frame on
//! two threads (counted against the table), frames independent of the thread count, a white
//! furnace that converges through the cache, the Cornell box converging to the reference path
//! tracer's image within a bound set by the texel size, a cache too small for the frame that
//! evicts and shades without it but never mixes cells' light, the cache's switch off
//! leaving every frame as it was, and its per-world tables made before the first frame
//! changing none.

mod common;

use common::{ball_and_floor, config, cornell, in_pool, scene, world};
use glam::Vec3;
use pathlight_render::camera_path::{CameraPath, PathKind};
use pathlight_render::frame::texture_cache::{CacheFilter, CacheReport, CachedTerms};
use pathlight_render::frame::Pipeline;
use pathlight_render::renderer::render;
use pathlight_render::{Config, World};
use pathlight_scene::Material;

/// `base` with the cache on, its filter and terms.
fn cached(base: &Config, filter: CacheFilter, terms: CachedTerms) -> Config {
    let mut c = base.clone();
    let t = &mut c.frame.texture_cache;
    t.enabled = true;
    t.filter = filter;
    t.terms = terms;
    c.validate().unwrap();
    c
}

/// What `frames` frames of `cfg` gave (the camera moving along a short orbit when `moving`):
/// every frame's image, the cache's reports, and the sample blocks the table holds as shaded
/// at each frame.
fn run(
    world: &World,
    cfg: &Config,
    frames: usize,
    moving: bool,
) -> (Vec<Vec<Vec3>>, Vec<CacheReport>, Vec<usize>) {
    let views = if moving {
        orbit(world, 6.0, frames as u32)
    } else {
        vec![cfg.camera.clone(); frames]
    };
    let mut pipeline = Pipeline::new(cfg.clone());
    let (mut images, mut reports, mut blocks) = (Vec::new(), Vec::new(), Vec::new());
    for view in views.into_iter().take(frames) {
        let c = Config {
            camera: view,
            ..cfg.clone()
        };
        pipeline.set_config(&c);
        let report = pipeline.render_frame(world);
        images.push(pipeline.image());
        reports.push(report.texture_cache.expect("the cache is on"));
        blocks.push(pipeline.stages.texture_cache.blocks_at_current_frame());
    }
    (images, reports, blocks)
}

/// An image's values, bit for bit.
fn bits(image: &[Vec3]) -> Vec<u32> {
    (image.iter())
        .flat_map(|v| v.to_array().map(f32::to_bits))
        .collect()
}

/// The views of an orbit of `degrees` in `steps` steps about `world`'s camera.
fn orbit(world: &World, degrees: f32, steps: u32) -> Vec<pathlight_render::config::CameraConfig> {
    let path = CameraPath {
        path: PathKind::Orbit,
        degrees,
        steps,
        frames_per_view: 1,
        ..CameraPath::default()
    };
    world.path_views(&path)
}

#[test]
fn every_block_is_shaded_once_per_frame_and_frames_do_not_depend_on_the_thread_count() {
    let world = cornell();
    let base = Config {
        max_bounces: Some(2),
        ..config(48, 32, 1)
    };
    for filter in [CacheFilter::None, CacheFilter::Gaussian] {
        for terms in [CachedTerms::Indirect, CachedTerms::All, CachedTerms::Sky] {
            for moving in [false, true] {
                let cfg = cached(&base, filter, terms);
                let one = in_pool(1, || run(&world, &cfg, 4, moving));
                let two = in_pool(2, || run(&world, &cfg, 4, moving));
                let name = format!("{filter:?} {terms:?} moving {moving}");
                for (f, (report, blocks)) in two.1.iter().zip(&two.2).enumerate() {
                    assert!(report.cells_shaded > 0, "{name}: frame {f} shaded nothing");
                    assert_eq!(report.uncached, 0, "{name}: frame {f}");
                    assert_eq!(
                        report.blocks_shaded as usize, *blocks,
                        "{name}: frame {f}: blocks shaded against blocks in the table"
                    );
                }
                assert_eq!(one.1, two.1, "{name}: the reports");
                for (f, (a, b)) in one.0.iter().zip(&two.0).enumerate() {
                    assert!(a == b, "{name}: frame {f} differs between 1 and 2 threads");
                    assert!(a.iter().all(|p| p.is_finite()), "{name}: frame {f}");
                }
            }
        }
    }
}

/// A white sphere above a white floor under a uniform sky of radiance 1: every pixel's
/// expected value is 1, also through the cache (its texels hold the same light everywhere).
#[test]
fn the_white_furnace_converges_through_the_cache() {
    let white = Material::lambertian("white", Vec3::ONE);
    let world = world(scene(
        ball_and_floor(),
        vec![white],
        Some(Vec3::ONE),
        Vec3::new(0.0, 0.5, 4.0),
    ));
    let base = Config {
        max_bounces: None,
        ..config(32, 32, 1)
    };
    // The sky's light at a cell is next event estimation alone (no sun here: the whole sky),
    // a uniform sphere's samples for a uniform sky (variance 5/3 per sample against 0 for the
    // cosine-weighted BSDF ray that multiple importance sampling adds in `all`): more frames.
    // With the clamp (at what a white surface lit directly reflects, 4 here), and young cells
    // brought up to 16 samples: the furnace's light is the same.
    for (filter, terms, frames, clamp) in [
        (CacheFilter::None, CachedTerms::Indirect, 64, 0.0),
        (CacheFilter::None, CachedTerms::All, 64, 0.0),
        (CacheFilter::Gaussian, CachedTerms::All, 64, 0.0),
        (CacheFilter::Gaussian, CachedTerms::Sky, 256, 0.0),
        (CacheFilter::Gaussian, CachedTerms::Sky, 256, 1.0),
    ] {
        let mut cfg = cached(&base, filter, terms);
        cfg.frame.texture_cache.clamp = clamp;
        cfg.frame.texture_cache.fresh_spp = if clamp > 0.0 { 16 } else { 1 };
        let (images, _, _) = run(&world, &cfg, frames, false);
        let last = images.last().unwrap();
        let mean = last.iter().map(|p| p.element_sum() / 3.0).sum::<f32>() / last.len() as f32;
        // 4x4-pixel blocks' means.
        let worst = (0..64)
            .map(|b| {
                let (bx, by) = (b % 8, b / 8);
                let s = (0..16)
                    .map(|k| last[(by * 4 + k / 4) * 32 + bx * 4 + k % 4].element_sum() / 3.0)
                    .sum::<f32>();
                (s / 16.0 - 1.0).abs()
            })
            .fold(0.0f32, f32::max);
        eprintln!("{filter:?} {terms:?} clamp {clamp}: mean {mean}, worst 4x4 block {worst}");
        assert!(
            (mean - 1.0).abs() < 0.01,
            "{filter:?} {terms:?} clamp {clamp}: mean {mean}"
        );
        assert!(
            worst < 0.1,
            "{filter:?} {terms:?} clamp {clamp}: worst block {worst}"
        );
    }
}

/// Still frames through the cache (no filter) converge to the reference path tracer's image:
/// the image's mean within 1%, and each 8x8 block within a bound set by the texel size
/// (light varies within a texel near corners and contact shadows).
#[test]
fn the_cached_cornell_box_converges_to_the_reference() {
    let world = cornell();
    let base = Config {
        max_bounces: Some(2),
        ..config(48, 48, 1)
    };
    let reference = reference(&world, &base, 512);
    let mut plain = base.clone();
    plain.frame.texture_cache.enabled = false;
    for terms in [
        None,
        Some(CachedTerms::Indirect),
        Some(CachedTerms::All),
        Some(CachedTerms::Sky),
    ] {
        let cfg = match terms {
            Some(terms) => {
                // Every cell shaded at every frame: the cache's own convergence.
                let mut c = cached(&base, CacheFilter::None, terms);
                c.frame.texture_cache.reshade = 0.0;
                c
            }
            None => plain.clone(),
        };
        let mut pipeline = Pipeline::new(cfg.clone());
        for _ in 0..192 {
            pipeline.render_frame(&world);
        }
        let (ratio, worst) = mean_and_worst_block(&pipeline.image(), &reference, 48);
        // (The plain pipeline's own frames: its noise at 192 samples.)
        eprintln!("{terms:?}: mean ratio {ratio}, worst 8x8 block {worst}");
        assert!((ratio - 1.0).abs() < 0.01, "{terms:?}: ratio {ratio}");
        assert!(worst < 0.12, "{terms:?}: worst block {worst}");
    }
}

/// The reference path tracer's image of `world` with `base`'s settings at `spp` samples per
/// pixel (another seed than the frames').
fn reference(world: &World, base: &Config, spp: u32) -> Vec<Vec3> {
    let cfg = Config {
        spp,
        seed: 77,
        ..base.clone()
    };
    let film = render(world, &cfg.render_camera(world), &cfg);
    film.pixels.iter().map(|p| p.mean).collect()
}

/// The mean of `image`'s pixels (all channels), and the worst relative difference of an 8x8
/// block's mean from `reference`'s (images `w` pixels wide).
fn mean_and_worst_block(image: &[Vec3], reference: &[Vec3], w: usize) -> (f32, f32) {
    let sum = |v: &[Vec3]| v.iter().map(|p| p.element_sum()).sum::<f32>();
    let ratio = sum(image) / sum(reference);
    let h = image.len() / w;
    let mut worst = 0.0f32;
    for by in 0..h / 8 {
        for bx in 0..w / 8 {
            let block = |v: &[Vec3]| {
                (0..64)
                    .map(|k| v[(by * 8 + k / 8) * w + bx * 8 + k % 8].element_sum())
                    .sum::<f32>()
            };
            let (a, b) = (block(image), block(reference));
            worst = worst.max((a - b).abs() / b.max(1e-3));
        }
    }
    (ratio, worst)
}

/// A white ball above a white floor under a blue sky with a sun (three texels 10,000 times
/// as bright, 40 degrees up): the ball's shadow is sharp.
fn sunny_ball_and_floor() -> World {
    world(sunny_scene([Vec3::splat(4000.0); 3]))
}

/// [`sunny_ball_and_floor`]'s scene, its sun's three texels of radiance `sun`.
fn sunny_scene(sun: [Vec3; 3]) -> pathlight_scene::Scene {
    let white = Material::lambertian("white", Vec3::splat(0.8));
    let mut s = scene(
        ball_and_floor(),
        vec![white],
        Some(Vec3::ONE),
        Vec3::new(0.0, 0.5, 4.0),
    );
    let env = s.environment.as_mut().unwrap();
    let (w, h) = (256usize, 128usize);
    env.width = w as u32;
    env.height = h as u32;
    env.texels = vec![Vec3::new(0.3, 0.4, 0.6); w * h];
    for (i, l) in [36 * w + 100, 36 * w + 101, 37 * w + 100]
        .into_iter()
        .zip(sun)
    {
        env.texels[i] = l;
    }
    s
}

/// Under a sun whose texels differ in colour, each pixel's sun by the ratio estimator
/// (`sun_ratio`, its irradiance worked out over the texels, the sample deciding the shadow)
/// changes from frame to frame far less than the sample's own estimate, whose colour is the
/// texel it drew, and has the same mean: frames on their own (no accumulation) at a still
/// view, the cache warmed up first.
#[test]
fn the_suns_ratio_estimator_keeps_its_colour_still() {
    let world = world(sunny_scene([
        Vec3::new(6000.0, 3000.0, 1000.0),
        Vec3::new(1000.0, 3000.0, 6000.0),
        Vec3::new(3000.0, 4000.0, 3000.0),
    ]));
    let mut base = Config {
        max_bounces: Some(2),
        ..config(32, 32, 1)
    };
    base.frame.accumulate = false;
    let mut stats = Vec::new();
    for ratio in [false, true] {
        let mut cfg = cached(&base, CacheFilter::Gaussian, CachedTerms::Sky);
        cfg.frame.texture_cache.sun_ratio = ratio;
        let mut pipeline = Pipeline::new(cfg);
        for _ in 0..32 {
            pipeline.render_frame(&world);
        }
        let frames: Vec<Vec<Vec3>> = (0..16)
            .map(|_| {
                pipeline.render_frame(&world);
                pipeline.image()
            })
            .collect();
        let n = frames.len() as f32;
        let pixels = frames[0].len();
        let mean: Vec<Vec3> = (0..pixels)
            .map(|i| frames.iter().map(|f| f[i]).sum::<Vec3>() / n)
            .collect();
        // The mean over pixels of each pixel's deviation over the frames, per channel.
        let deviation = (0..pixels)
            .map(|i| {
                let var = frames
                    .iter()
                    .map(|f| (f[i] - mean[i]).powf(2.0))
                    .sum::<Vec3>()
                    / n;
                var.x.sqrt() + var.y.sqrt() + var.z.sqrt()
            })
            .sum::<f32>()
            / pixels as f32;
        let total = mean.iter().map(|m| m.element_sum()).sum::<f32>() / pixels as f32;
        eprintln!("sun_ratio {ratio}: deviation {deviation}, mean {total}");
        stats.push((deviation, total));
    }
    let ((sample, sample_mean), (ratio, ratio_mean)) = (stats[0], stats[1]);
    assert!(ratio < 0.5 * sample, "{ratio} against {sample}");
    assert!(
        (ratio_mean / sample_mean - 1.0).abs() < 0.02,
        "{ratio_mean} against {sample_mean}"
    );
}

/// Still frames through the cache holding the sky's light (each pixel lit by the sun at its
/// own point) converge to the reference path tracer's image under a sun, through a Gaussian
/// filter: the mean within 1%, each 8x8 block within 8%; holding the sun's light too (`all`),
/// its shadow's edge spreads over the filtered texels (blocks 14% off): per pixel, the image
/// is further from the reference (the relative L2 distance, sqrt(sum (a - b)^2 / sum b^2):
/// 0.019 against 0.034).
#[test]
fn the_sun_lights_each_pixel_and_the_cache_holds_the_sky() {
    let world = sunny_ball_and_floor();
    let base = Config {
        max_bounces: Some(2),
        ..config(48, 48, 1)
    };
    let split = pathlight_render::light::sun::SunAndSky::new(&world.lights);
    assert!(split.has_sun() && split.sun_share > 0.5, "{split:?}");
    let reference = reference(&world, &base, 1024);
    let mut l2 = Vec::new();
    for terms in [CachedTerms::Sky, CachedTerms::All] {
        let mut cfg = cached(&base, CacheFilter::Gaussian, terms);
        let t = &mut cfg.frame.texture_cache;
        // (A window of 9 squares narrowing with the samples: the defaults' 13 squares, about
        // 26 pixels, are half this 48-pixel image and blur the ball's contact shadow.)
        (t.reshade, t.kernel, t.shrink) = (0.0, 9, 0.5);
        let mut pipeline = Pipeline::new(cfg);
        for _ in 0..128 {
            pipeline.render_frame(&world);
        }
        let image = pipeline.image();
        let (ratio, worst) = mean_and_worst_block(&image, &reference, 48);
        let d2 = |a: &[Vec3], b: &[Vec3]| -> f32 {
            a.iter()
                .zip(b)
                .map(|(a, b)| (*a - *b).length_squared())
                .sum()
        };
        let zero = vec![Vec3::ZERO; reference.len()];
        let distance = (d2(&image, &reference) / d2(&reference, &zero)).sqrt();
        eprintln!("{terms:?}: mean ratio {ratio}, worst 8x8 block {worst}, L2 {distance}");
        assert!((ratio - 1.0).abs() < 0.01, "{terms:?}: ratio {ratio}");
        if terms == CachedTerms::Sky {
            assert!(worst < 0.08, "{terms:?}: worst block {worst}");
        }
        l2.push(distance);
    }
    assert!(
        l2[0] < 0.75 * l2[1],
        "the sun per pixel ({}) against the sun in the cache ({})",
        l2[0],
        l2[1]
    );
}

/// With ReSTIR (seed 004), a cached pixel's direct light is its reservoir's, whatever the cache
/// holds: the image's mean stays ReSTIR's without the cache (the cache holding direct light
/// once dropped it, a quarter of the Cornell box's light).
#[test]
fn restir_lights_the_cached_pixels() {
    let world = cornell();
    let mut base = Config {
        max_bounces: Some(2),
        ..config(48, 48, 1)
    };
    base.frame.restir.enabled = true;
    let mean_of = |cfg: &Config| {
        let mut pipeline = Pipeline::new(cfg.clone());
        for _ in 0..48 {
            pipeline.render_frame(&world);
        }
        let image = pipeline.image();
        image.iter().map(|p| p.element_sum()).sum::<f32>() / image.len() as f32
    };
    let alone = mean_of(&base);
    for terms in [CachedTerms::Indirect, CachedTerms::All, CachedTerms::Sky] {
        let mean = mean_of(&cached(&base, CacheFilter::Gaussian, terms));
        eprintln!("{terms:?}: {mean} against ReSTIR alone {alone}");
        assert!(
            (mean / alone - 1.0).abs() < 0.02,
            "{terms:?}: {mean} against {alone}"
        );
    }
}

/// A cache of 1 MB for a frame that needs more: blocks are shaded without it (counted), and
/// the image stays what a large cache gives, within noise: no cell reads another's light.
#[test]
fn a_small_cache_evicts_but_never_mixes_cells() {
    let world = cornell();
    let base = Config {
        max_bounces: Some(2),
        ..config(320, 240, 1)
    };
    let mut small = cached(&base, CacheFilter::None, CachedTerms::All);
    small.frame.texture_cache.budget_mb = 1.0;
    small.frame.texture_cache.lod_bias = -2.0;
    // (The cells shaded once each frame: young cells' samples would count apart.)
    small.frame.texture_cache.fresh_spp = 1;
    let mut large = small.clone();
    large.frame.texture_cache.budget_mb = 256.0;
    let (a, ra, _) = run(&world, &small, 6, false);
    let (b, rb, _) = run(&world, &large, 6, false);
    // The small cache evicts (its blocks are shaded again), the large one does not.
    let cells = |r: &[CacheReport]| r.iter().map(|r| r.cells_shaded).sum::<u64>();
    assert!(cells(&ra) > cells(&rb), "{ra:?} against {rb:?}");
    assert!(rb.iter().all(|r| r.uncached == 0), "{rb:?}");
    let mean = |v: &[Vec3]| v.iter().map(|p| p.element_sum()).sum::<f32>() / v.len() as f32;
    let (ma, mb) = (mean(a.last().unwrap()), mean(b.last().unwrap()));
    eprintln!(
        "small {ma}, large {mb}, uncached {:?}",
        ra.iter().map(|r| r.uncached).collect::<Vec<_>>()
    );
    assert!((ma / mb - 1.0).abs() < 0.02, "small {ma}, large {mb}");
}

/// The cache's settings are checked.
/// With the cache's switch off, none of its other settings changes a frame, still or moving,
/// nor the frames' reports: every frame is bit for bit the plain pipeline's.
#[test]
fn the_switch_off_leaves_every_frame_as_it_was() {
    let world = cornell();
    let base = config(24, 16, 1);
    let frames = |cfg: &Config, moving: bool| {
        let views = match moving {
            true => orbit(&world, 6.0, 4),
            false => vec![cfg.camera.clone(); 4],
        };
        let mut pipeline = Pipeline::new(cfg.clone());
        let mut out = Vec::new();
        for view in views {
            pipeline.set_config(&Config {
                camera: view,
                ..cfg.clone()
            });
            let report = pipeline.render_frame(&world);
            assert!(report.texture_cache.is_none());
            out.push((bits(&pipeline.image()), report.rays, report.samples));
        }
        out
    };
    let off = base
        .with_toml(
            "[frame.texture_cache]\nenabled = false\nterms = \"all\"\nkernel = 3\n\
             edge_spp = 8\nfresh_spp = 2\nfresh_budget = 4.0\nlod_bias = -1.0\n\
             min_roughness = 0.0\nbudget_mb = 1.0\n",
        )
        .unwrap();
    off.validate().unwrap();
    for moving in [false, true] {
        assert!(
            frames(&base, moving) == frames(&off, moving),
            "moving {moving}"
        );
    }
}

/// Making the cache's per-world tables before the first frame (as `view`, `play` and `bench
/// frame` do) changes no frame: the images and reports of a first frame that makes them.
#[test]
fn preparing_the_world_beforehand_changes_no_frame() {
    let world = cornell();
    let cfg = cached(
        &config(24, 16, 1),
        CacheFilter::Gaussian,
        CachedTerms::Indirect,
    );
    let frames = |prepared: bool| {
        in_pool(2, || {
            let mut pipeline = Pipeline::new(cfg.clone());
            if prepared {
                pipeline.prepare_world(&world);
            }
            (0..3)
                .map(|_| {
                    let report = pipeline.render_frame(&world);
                    let cells = report.texture_cache.expect("on").cells_shaded;
                    (bits(&pipeline.image()), cells)
                })
                .collect::<Vec<_>>()
        })
    };
    let (made_by_the_frame, made_before) = (frames(false), frames(true));
    assert!(made_by_the_frame[0].1 > 0);
    assert!(made_by_the_frame == made_before);
}

#[test]
fn bad_cache_settings_are_refused() {
    for toml in [
        "[frame.texture_cache]\nkernel = 4\n",
        "[frame.texture_cache]\nkernel = 99\n",
        "[frame.texture_cache]\nbudget_mb = 0\n",
        "[frame.texture_cache]\nreshade = -1\n",
        "[frame.texture_cache]\nshrink = 3\n",
        "[frame.texture_cache]\ntemporal_alpha = 1.0\n",
        "[frame.texture_cache]\nlod_bias = nan\n",
        "[frame.texture_cache]\nmax_count = 0\n",
        "[frame.texture_cache]\nmin_roughness = 2.0\n",
        "[frame.texture_cache]\nfresh_spp = 0\n",
        "[frame.texture_cache]\nfresh_spp = 1000\n",
        "[frame.texture_cache]\nfresh_budget = -1\n",
        "[frame.texture_cache]\nfresh_budget = nan\n",
        "[frame.texture_cache]\ncold_budget = -1\n",
        "[frame.texture_cache]\ncold_budget = 65\n",
    ] {
        let c = Config::default().with_toml(toml).unwrap();
        let e = c.validate().unwrap_err();
        assert!(e.to_string().contains("texture_cache"), "{toml}: {e}");
    }
    assert!(Config::default()
        .with_toml("[frame.texture_cache]\nfilter = \"bilateral\"\n")
        .is_err());
}

/// With the cache on, its views show it: texels of many colours, cells shaded, texels found
/// and filtered, the cached light.
#[test]
fn the_cache_views_show_the_cache() {
    use pathlight_render::frame::display::DisplayMode;
    let world = cornell();
    let cfg = cached(
        &config(40, 30, 1),
        CacheFilter::Gaussian,
        CachedTerms::Indirect,
    );
    let mut pipeline = Pipeline::new(cfg.clone());
    pipeline.render_frame(&world);
    for (name, least) in [
        ("cache-light", 8),
        ("cache-texels", 50),
        ("cache-level", 2),
        ("cache-hits", 2),
        ("cache-shaded", 2),
    ] {
        let mut rgba = Vec::new();
        pipeline.rgba8(&DisplayMode::named(name), &cfg.display, &mut rgba);
        let distinct: std::collections::HashSet<&[u8]> = rgba.chunks(4).collect();
        assert!(
            distinct.len() >= least,
            "{name}: {} colours",
            distinct.len()
        );
    }
}

/// With `edge_spp`, a pixel whose first hit and a neighbour's lie on different surfaces takes
/// that many camera samples, every other pixel one (read here from the G-buffer's views: a
/// neighbour at a normal's cosine under 0.8 or a fifth nearer or further is on another
/// surface; all four on one plane, the same normal within a depth of a fifth, are not); the
/// frame's sample count adds up, and such pixels are a minority of the Cornell box's.
#[test]
fn pixels_on_edges_take_more_samples() {
    use pathlight_render::frame::display::DisplayMode;
    let world = cornell();
    let (w, h) = (48usize, 48usize);
    let mut cfg = cached(
        &config(w as u32, h as u32, 1),
        CacheFilter::Gaussian,
        CachedTerms::Sky,
    );
    cfg.frame.texture_cache.edge_spp = 4;
    cfg.validate().unwrap();
    let mut p = Pipeline::new(cfg);
    let report = p.render_frame(&world);
    let view = |name: &'static str, i: usize| p.value(&DisplayMode::named(name), i);
    let (mut edges, mut clear, mut flat) = (0, 0, 0);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = y * w + x;
            let (d, n) = (view("depth", i).x, view("normal", i));
            let around =
                [i - 1, i + 1, i - w, i + w].map(|j| (view("depth", j).x, view("normal", j)));
            let apart =
                |&(dj, nj): &(f32, glam::Vec3)| n.dot(nj) < 0.8 || dj > 1.2 * d || d > 1.2 * dj;
            let samples = view("samples", i).x;
            if around.iter().any(apart) {
                assert_eq!(samples, 4.0, "pixel ({x}, {y}) is on an edge");
                clear += 1;
            } else if around
                .iter()
                .all(|&(dj, nj)| n.dot(nj) > 0.9999 && (dj / d - 1.0).abs() < 0.2)
            {
                assert_eq!(samples, 1.0, "pixel ({x}, {y}) is on a plane");
                flat += 1;
            }
        }
    }
    for i in 0..w * h {
        let samples = view("samples", i).x;
        assert!(samples == 1.0 || samples == 4.0, "{samples}");
        edges += usize::from(samples == 4.0);
    }
    assert_eq!(report.samples as usize, w * h + 3 * edges);
    assert!(
        clear > 0 && flat > w * h / 2,
        "{clear} pixels on clear edges, {flat} on planes"
    );
    assert!(edges < w * h / 4, "{edges} pixels on edges");
    // The option refuses what it cannot do.
    let mut bad = config(8, 8, 1);
    bad.frame.texture_cache.edge_spp = 0;
    assert!(bad.validate().is_err());
}

/// Young cells brought up to `fresh_spp` after the lighting pass: the first frame's cells are
/// shaded `fresh_spp` times each (the lighting pass's once and the top-up's `fresh_spp - 1`),
/// the frames do not depend on the thread count, and the next frame, reading them, is less
/// noisy than without; a budget caps the top-up's paths per frame (`cold_budget` at the
/// empty cache's first frame, `fresh_budget` at the others).
#[test]
fn young_cells_are_brought_up_to_fresh_spp_within_the_budget() {
    let world = cornell();
    let base = Config {
        max_bounces: Some(2),
        ..config(48, 48, 1)
    };
    let with = |fresh: u32, budget: f32| {
        let mut c = cached(&base, CacheFilter::None, CachedTerms::All);
        c.frame.texture_cache.fresh_spp = fresh;
        c.frame.texture_cache.fresh_budget = budget;
        // The first frame's budget twice the others' (within its bound).
        c.frame.texture_cache.cold_budget = (2.0 * budget).min(64.0);
        // Each frame on its own (the cache keeps its cells).
        c.frame.accumulate = false;
        c.validate().unwrap();
        c
    };
    let (plain, plain_reports, _) = in_pool(2, || run(&world, &with(1, 0.5), 2, false));
    let (images, reports, _) = in_pool(2, || run(&world, &with(8, 64.0), 2, false));
    let (single, single_reports, _) = in_pool(1, || run(&world, &with(8, 64.0), 2, false));
    let lit = plain_reports[0].cells_shaded;
    assert_eq!(plain_reports[0].topped_up, 0);
    assert_eq!(reports[0].topped_up, 7 * lit, "every young cell up to 8");
    assert_eq!(reports[0].cells_shaded, 8 * lit);
    assert_eq!(reports, single_reports);
    assert!(images == single, "frames differ between 1 and 2 threads");
    assert!(
        plain[0] == images[0],
        "the first frame reads the cells before the top-up"
    );
    // The next frame's noise: its difference from the same frame of another seed (twice the
    // variance, whatever the texels' bias), over 4x4 blocks of pixels, clamped to 1 as
    // displayed (a single sample's edges, the lamp's above all, would be the most of it).
    let noise = |fresh: u32| {
        let frame = |seed: u64| {
            let c = Config {
                seed,
                ..with(fresh, 64.0)
            };
            in_pool(2, || run(&world, &c, 2, false))
                .0
                .pop()
                .expect("two frames")
        };
        let (a, b) = (frame(1), frame(2));
        let block = |v: &[Vec3], k: usize| {
            let (bx, by) = (k % 12, k / 12);
            (0..16)
                .map(|i| v[(by * 4 + i / 4) * 48 + bx * 4 + i % 4].min(Vec3::ONE))
                .sum::<Vec3>()
                / 16.0
        };
        let d: f32 = (0..144)
            .map(|k| (block(&a, k) - block(&b, k)).length_squared())
            .sum();
        d / 144.0
    };
    let (young, topped) = (noise(1), noise(8));
    assert!(topped < 0.6 * young, "frame 1: {topped} against {young}");
    // A budget of a twentieth of a path per pixel along an orbit (a tenth at the empty
    // cache's first frame): every frame takes at most its budget's paths, the cells it leaves
    // waiting for later frames.
    let capped = in_pool(2, || {
        let cfg = with(8, 0.05);
        let mut pipeline = Pipeline::new(cfg.clone());
        (orbit(&world, 60.0, 5).into_iter())
            .map(|camera| {
                pipeline.set_config(&Config {
                    camera,
                    ..cfg.clone()
                });
                pipeline.render_frame(&world).texture_cache.expect("on")
            })
            .collect::<Vec<_>>()
    });
    let cap = (0.05 * 48.0 * 48.0) as u64;
    for (f, r) in capped.iter().enumerate().skip(1) {
        assert!(r.topped_up <= cap, "frame {f}: {} paths", r.topped_up);
    }
    assert!(capped[0].topped_up <= 2 * cap, "{capped:?}");
    assert!(capped[0].topped_up > cap, "{capped:?}");
    assert!(
        capped[1..].iter().any(|r| r.topped_up > cap / 2),
        "{capped:?}"
    );
}

/// A cold cache's top-up spread over frames by its budget converges to the image of the
/// top-up all at once: at a still view (one epoch: a cell's samples are keyed by the cell,
/// their count and the epoch, not by the frame that takes them) with `max_count = fresh_spp`
/// and `reshade = 0` (cells stop at the same count either way), once the budget has brought
/// every cell up, each frame's cached light is bit for bit that of a cache that took all its
/// cells' samples at its first frame, and no frame shaded more than the budget allows.
#[test]
fn a_cold_cache_spreads_its_top_up_and_converges_to_the_same_image() {
    use pathlight_render::frame::stage::Stage;
    let world = cornell();
    let base = Config {
        max_bounces: Some(2),
        ..config(48, 48, 1)
    };
    let frames = 40;
    // Each frame's report and cached light (the `cache-light` view).
    let run = |budget: f32| {
        let mut c = cached(&base, CacheFilter::Gaussian, CachedTerms::All);
        let t = &mut c.frame.texture_cache;
        t.fresh_spp = 8;
        t.max_count = 8;
        // Every block seen shaded at every frame until its cells are full, not at random.
        t.reshade = 0.0;
        t.fresh_budget = budget;
        t.cold_budget = budget;
        c.validate().unwrap();
        in_pool(2, || {
            let mut pipeline = Pipeline::new(c.clone());
            (0..frames)
                .map(|_| {
                    pipeline.set_config(&c);
                    let report = pipeline.render_frame(&world).texture_cache.expect("on");
                    let tc = &pipeline.stages.texture_cache;
                    let light: Vec<Vec3> = (0..48 * 48)
                        .map(|i| tc.value(&pipeline.frame, 0, i))
                        .collect();
                    (report, light)
                })
                .collect::<Vec<_>>()
        })
    };
    let (at_once, spread) = (run(64.0), run(0.25));
    let cap = (0.25 * 48.0 * 48.0) as u64;
    assert!(at_once[0].0.topped_up > 4 * cap, "{:?}", at_once[0].0);
    for (f, (r, _)) in spread.iter().enumerate() {
        assert!(r.topped_up <= cap, "frame {f}: {} paths", r.topped_up);
    }
    // Settled: nothing left to top up or to shade at the last frame (a block the jittered
    // samples first reach late is topped up when they do).
    let settled = |r: &CacheReport| r.topped_up == 0 && r.cells_shaded == 0;
    let last = (&at_once[frames - 1].0, &spread[frames - 1].0);
    assert!(settled(last.0) && settled(last.1), "{last:?}");
    // The first frame reads its cells before either top-up; the second reads them topped up
    // all at once in one, in part in the other.
    assert!(spread[0].1 == at_once[0].1, "the first frames differ");
    assert!(
        spread[1].1 != at_once[1].1,
        "the second frames are the same"
    );
    assert!(
        spread[frames - 1].1 == at_once[frames - 1].1,
        "the settled frames differ"
    );
}
