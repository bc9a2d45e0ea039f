//! The Cornell box against an independent renderer: Mitsuba 3 (`scalar_rgb`, `path` with
//! unlimited depth, box filter, two-sided diffuse BSDFs from the MTL's Kd, a one-sided area
//! emitter from Ke) at 4096 spp, rendered by `tools/mitsuba/cornell.py` (see its README) and
//! stored in `tests/data/cornell-mitsuba-256.exr`.

mod common;

use std::path::Path;

use glam::Vec3;
use pathlight_render::output::read_exr_rgb;
use pathlight_render::renderer::render;
use pathlight_render::{Config, World};

const SIZE: u32 = 256;

#[test]
fn cornell_box_agrees_with_mitsuba() {
    let reference =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cornell-mitsuba-256.exr");
    let (w, h, mitsuba) = read_exr_rgb(&reference).unwrap();
    assert_eq!((w, h), (SIZE, SIZE));

    // The built-in Cornell box is CornellBox-Original.obj/.mtl compiled in, with the camera
    // of the issue: from (0, 1, 3.5) toward (0, 1, 0), vertical field of view 40.107 degrees.
    let scene = pathlight_scene::load(None, &Default::default()).unwrap();
    let world = World::new(scene, Default::default());
    let spp = 32;
    let config = Config {
        width: SIZE,
        height: SIZE,
        spp,
        ..Config::default()
    };
    let camera = config.render_camera(&world);
    let film = render(&world, &camera, &config);
    let ours: Vec<Vec3> = film.layer(|p| p.mean);

    // 1. Mean per channel: BENCHMARKS claims agreement within 0.02% at 64-1024 spp. At 32
    //    spp the image mean's own noise is larger: within four standard errors of our mean
    //    (from the pixels' sample variances; Mitsuba's at 4096 spp is about 11x smaller) plus
    //    0.02%.
    let mean = |img: &[Vec3]| img.iter().copied().sum::<Vec3>() / img.len() as f32;
    let (a, b) = (mean(&ours), mean(&mitsuba));
    let n = ours.len() as f32;
    let se = (film.pixels.iter())
        .map(|px| px.variance() / px.n as f32)
        .sum::<Vec3>()
        .map(f32::sqrt)
        / n;
    let rel = (a - b) / b;
    eprintln!(
        "means: pathlight {a}, mitsuba {b}, relative difference {rel}, standard error {}",
        se / b
    );
    assert!(
        ((a - b).abs() - (4.0 * se + 0.0002 * b)).max_element() < 0.0,
        "{rel} against {}",
        (4.0 * se + 0.0002 * b) / b
    );

    // 2. relMSE (seed 002's definition, epsilon 0.001) at the level of Monte Carlo noise:
    // Mitsuba's own 64 spp render against its 4096 spp one gives 0.0088, i.e. about
    // 0.56 / N; a correct 32 spp render is expected near 0.018 (less with Sobol points).
    let relmse = ours
        .iter()
        .zip(&mitsuba)
        .map(|(a, b)| ((*a - *b) * (*a - *b) / (*b * *b + Vec3::splat(1e-3))).element_sum() / 3.0)
        .sum::<f32>()
        / ours.len() as f32;
    eprintln!("relMSE at {spp} spp: {relmse}");
    assert!(relmse < 0.56 / spp as f32 * 1.5, "{relmse}");

    // 3. No region is biased: the mean of every 32x32 block agrees with Mitsuba within five
    //    standard errors of our estimate (from the per-pixel sample variances; Mitsuba's own
    //    error at 4096 spp is ~10x smaller) plus 0.5%. Biases that cancel over the image, e.g.
    //    shadow rays hitting the light's own quad (the box tops went dark), fail here.
    let mut worst = (0.0f32, 0, 0);
    for by in 0..SIZE / 32 {
        for bx in 0..SIZE / 32 {
            let (mut p, mut m, mut var) = (0.0f32, 0.0f32, 0.0f32);
            for y in by * 32..(by + 1) * 32 {
                for x in bx * 32..(bx + 1) * 32 {
                    let i = (y * SIZE + x) as usize;
                    p += ours[i].element_sum();
                    m += mitsuba[i].element_sum();
                    let px = &film.pixels[i];
                    var += px.variance().element_sum() / px.n as f32;
                }
            }
            let z = (p - m).abs() / (5.0 * var.sqrt() + 0.005 * m);
            if z > worst.0 {
                worst = (z, bx, by);
            }
        }
    }
    eprintln!("worst 32x32 block, as a fraction of its tolerance: {worst:?}");
    assert!(worst.0 < 1.0, "block {worst:?}");
}
