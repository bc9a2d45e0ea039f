//! The data-driven filter's time per frame on a synthetic frame (two walls, texture patches,
//! noisy light), with all the machine's threads: at 640x360 kernels 1 (the fixed cost: the
//! planes), 7, 15, 21, 25 and 55, with and without holes; at 320x240 and 1280x720 kernel 21.
//!
//! `cargo bench -p pathlight-denoise --bench filter`

use criterion::{criterion_group, criterion_main, Criterion};
use glam::Vec3;
use pathlight_denoise::{DataDriven, Features, FilterConfig, Method};

/// SplitMix64.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
    fn vec3(&mut self, scale: f32) -> Vec3 {
        Vec3::new(self.next(), self.next(), self.next()) * scale
    }
}

fn bench(c: &mut Criterion) {
    for (w, h, kernels) in [
        (640, 360, &[1, 7, 15, 21, 25, 55][..]),
        (320, 240, &[21][..]),
        (1280, 720, &[21][..]),
    ] {
        size(c, w, h, kernels);
    }
}

fn size(c: &mut Criterion, w: usize, h: usize, kernels: &[u32]) {
    let mut rng = Rng(1);
    let n = w * h;
    let (mut depth, mut normal, mut albedo) = (vec![0.0; n], vec![Vec3::Z; n], vec![Vec3::ZERO; n]);
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
    let direct: Vec<Vec3> = (0..n).map(|_| rng.vec3(1.0)).collect();
    let indirect: Vec<Vec3> = (0..n).map(|_| rng.vec3(0.3)).collect();
    let variance: Vec<[f32; 5]> = (0..n)
        .map(|_| [rng.next() * 0.01, rng.next() * 0.1, 0.0, 0.5, 0.0])
        .collect();
    let light_variance = vec![[0.01f32, 0.001]; n];
    let features = Features {
        width: w,
        height: h,
        direct: &direct,
        indirect: &indirect,
        depth: &depth,
        normal: &normal,
        albedo: &albedo,
        texture2: &albedo,
        variance: &variance,
        light_variance: &light_variance,
    };
    let mut filter = DataDriven::new();
    let mut out = vec![Vec3::ZERO; n];
    let mut group = c.benchmark_group(format!("data-driven {w}x{h}"));
    group.sample_size(20);
    for &kernel in kernels {
        for holes in [false, true] {
            let config = FilterConfig {
                method: Method::DataDriven,
                kernel,
                holes,
                ..FilterConfig::default()
            };
            let name = format!("kernel {kernel}{}", if holes { " holes" } else { "" });
            group.bench_function(name, |b| {
                b.iter(|| filter.filter(&features, &config, &mut out).unwrap())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
