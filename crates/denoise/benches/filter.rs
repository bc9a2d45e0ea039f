//! The data-driven filter's time per frame on a synthetic frame (two walls, texture patches,
//! noisy light), with all the machine's threads: kernels 7, 15, 21, 25 and 55, with and without
//! holes, at 320x240, 640x360 and 1280x720, and kernel 1 (the fixed cost: the planes) at 640x360.
//!
//! SVGF (5 a-trous passes, a still camera) at 640x360 and 1280x720, vectorised and scalar.
//!
//! `cargo bench -p pathlight-denoise --bench filter [-- svgf]`

use criterion::{criterion_group, criterion_main, Criterion};
use glam::{Vec2, Vec3};
use pathlight_core::rng::Rng;
use pathlight_denoise::{
    ColourWeights, DataDriven, DataDrivenConfig, ErrorPair, Features, Svgf, SvgfFrame, SvgfParams,
};

fn vec3(rng: &mut Rng, scale: f32) -> Vec3 {
    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale
}

fn bench(c: &mut Criterion) {
    for (w, h, kernels) in [
        (640, 360, &[1, 7, 15, 21, 25, 55][..]),
        (320, 240, &[7, 15, 21, 25, 55][..]),
        (1280, 720, &[7, 15, 21, 25, 55][..]),
    ] {
        size(c, w, h, kernels);
    }
}

/// A synthetic frame: two walls at an angle, texture patches, noisy light.
struct Synthetic {
    depth: Vec<f32>,
    normal: Vec<Vec3>,
    albedo: Vec<Vec3>,
    direct: Vec<Vec3>,
    indirect: Vec<Vec3>,
    variance: Vec<[f32; 5]>,
    light_variance: Vec<[f32; 2]>,
}

impl Synthetic {
    fn new(w: usize, h: usize) -> Self {
        let mut rng = Rng::new(1, 0);
        let n = w * h;
        let (mut depth, mut normal, mut albedo) =
            (vec![0.0; n], vec![Vec3::Z; n], vec![Vec3::ZERO; n]);
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let right = x > w / 2;
                depth[i] = if right { 3.0 + 0.01 * y as f32 } else { 1.5 };
                normal[i] = if right {
                    Vec3::new(0.6, 0.0, 0.8)
                } else {
                    Vec3::Z
                };
                albedo[i] = if (x / 16 + y / 16) % 2 == 0 {
                    Vec3::splat(0.7)
                } else {
                    Vec3::splat(0.3)
                };
            }
        }
        let direct = (0..n).map(|_| vec3(&mut rng, 1.0)).collect();
        let indirect = (0..n).map(|_| vec3(&mut rng, 0.3)).collect();
        let variance = (0..n)
            .map(|_| [rng.next_f32() * 0.01, rng.next_f32() * 0.1, 0.0, 0.5, 0.0])
            .collect();
        Self {
            depth,
            normal,
            albedo,
            direct,
            indirect,
            variance,
            light_variance: vec![[0.01f32, 0.001]; n],
        }
    }
}

fn size(c: &mut Criterion, w: usize, h: usize, kernels: &[u32]) {
    let s = Synthetic::new(w, h);
    let n = w * h;
    // Half the pixels metallic and glossy.
    let roughness = vec![0.3; n];
    let metallic: Vec<f32> = (0..n).map(|i| (i / w % 2) as f32).collect();
    let features = Features {
        width: w,
        height: h,
        direct: &s.direct,
        indirect: &s.indirect,
        depth: &s.depth,
        normal: &s.normal,
        albedo: &s.albedo,
        texture2: &s.albedo,
        variance: &s.variance,
        light_variance: &s.light_variance,
        roughness: &roughness,
        metallic: &metallic,
    };
    let mut filter = DataDriven::new();
    let mut out = vec![Vec3::ZERO; n];
    let mut group = c.benchmark_group(format!("data-driven {w}x{h}"));
    group.sample_size(20);
    for &kernel in kernels {
        for holes in [false, true] {
            let config = DataDrivenConfig {
                kernel,
                holes,
                ..DataDrivenConfig::default()
            };
            let name = format!("kernel {kernel}{}", if holes { " holes" } else { "" });
            group.bench_function(name, |b| {
                b.iter(|| filter.filter(&features, &config, &mut out).unwrap())
            });
        }
    }
    // The filter before 2026-11-26 (the errors' product in the colour test, sigma 4, the
    // texture2 test), the SURE blend (`sure`, radius 3), the colour test's channels alike
    // (`colour_weights = "equal"`, the default until 2026-11-28), and the narrower lanes
    // where the processor has wider ones (21x21 with holes only).
    if kernels.contains(&21) {
        let holes = DataDrivenConfig {
            kernel: 21,
            holes: true,
            ..DataDrivenConfig::default()
        };
        let before = DataDrivenConfig {
            error_pair: ErrorPair::Product,
            sigma_direct: 4.0,
            sigma_indirect: 4.0,
            texture2_test: true,
            ..holes
        };
        let sure = DataDrivenConfig {
            sure: true,
            ..holes
        };
        let equal = DataDrivenConfig {
            colour_weights: ColourWeights::Equal,
            ..holes
        };
        for (name, config, lanes) in [
            ("product", before, "widest"),
            ("sure", sure, "widest"),
            ("equal", equal, "widest"),
            ("avx2", holes, "avx2"),
            ("portable", holes, "portable"),
        ] {
            let mut filter = DataDriven::new();
            filter.set_lanes(lanes);
            group.bench_function(format!("kernel 21 holes {name}"), |b| {
                b.iter(|| filter.filter(&features, &config, &mut out).unwrap())
            });
        }
    }
    group.finish();
}

/// SVGF on a still camera (the history at its full length), 5 a-trous passes: the vectorised
/// passes and the scalar ones.
fn svgf(c: &mut Criterion) {
    for (w, h) in [(640, 360), (1280, 720)] {
        let s = Synthetic::new(w, h);
        let n = w * h;
        let (motion, emitter) = (vec![Vec2::ZERO; n], vec![false; n]);
        let frame = SvgfFrame {
            width: w,
            height: h,
            direct: &s.direct,
            indirect: &s.indirect,
            albedo: &s.albedo,
            normal: &s.normal,
            depth: &s.depth,
            motion: &motion,
            emitter: &emitter,
        };
        let mut out = vec![Vec3::ZERO; n];
        let mut group = c.benchmark_group(format!("svgf {w}x{h}"));
        group.sample_size(20);
        for (scalar, kernel, split, lanes) in [
            (false, 5, true, "widest"),
            (true, 5, true, "widest"),
            (false, 3, true, "widest"),
            (false, 3, false, "widest"),
            (false, 3, true, "avx2"),
            (false, 3, true, "portable"),
        ] {
            let mut svgf = Svgf::new();
            svgf.set_scalar(scalar);
            svgf.set_lanes(lanes);
            let name = match (scalar, kernel, split, lanes) {
                (true, ..) => "scalar".to_owned(),
                (false, 5, _, _) => "vectorised".to_owned(),
                (false, _, true, "widest") => "vectorised 3x3".to_owned(),
                (false, _, true, lanes) => format!("vectorised 3x3 {lanes}"),
                _ => "vectorised 3x3 one signal".to_owned(),
            };
            let p = SvgfParams {
                iterations: 5,
                kernel,
                split,
                ..SvgfParams::default()
            };
            // The history brought to its full length when the benchmark runs (not for the
            // variants a filter leaves out: the scalar ones take seconds at 1280x720).
            let mut warm = false;
            group.bench_function(name, |b| {
                if !warm {
                    for _ in 0..40 {
                        svgf.filter(&frame, &p, &mut out).unwrap();
                    }
                    warm = true;
                }
                b.iter(|| svgf.filter(&frame, &p, &mut out).unwrap())
            });
        }
        group.finish();
    }
}

criterion_group!(benches, bench, svgf);
criterion_main!(benches);
