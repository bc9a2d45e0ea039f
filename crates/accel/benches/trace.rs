//! Native BVH benchmarks on the Stanford bunny (from `../shared/scenes`, skipped if absent):
//! build time, and single-thread Mrays/s (criterion's "elem/s") of `intersect` and `occluded`
//! for primary-like (coherent camera) rays and random (incoherent, bounce-like) rays.
//!
//! `cargo bench -p pathlight-accel --bench trace`

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use pathlight_accel::{Accel, NativeBvh, Ray, SceneTriangles};

fn shared_dir() -> PathBuf {
    pathlight_core::shared_data::dir(env!("CARGO_MANIFEST_DIR"))
}

fn load(rel: &str) -> Option<SceneTriangles> {
    let path = shared_dir().join("scenes").join(rel);
    if !path.exists() {
        eprintln!("skipping: {} not found", path.display());
        return None;
    }
    let scene = pathlight_scene::load_file(&path, &pathlight_scene::Limits::default()).ok()?;
    Some(SceneTriangles::from_scene(&scene))
}

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
    fn unit(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.next(), self.next(), self.next()) * 2.0 - 1.0;
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
}

fn bounds(t: &SceneTriangles) -> (Vec3, Vec3) {
    t.corners.iter().flatten().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    )
}

/// A 512 x 512 pinhole camera in front of the model, row by row.
fn primary_rays(lo: Vec3, hi: Vec3) -> Vec<Ray> {
    let c = (lo + hi) * 0.5;
    let r = (hi - lo).length() * 0.5;
    let eye = c + Vec3::new(0.0, 0.0, 2.2 * r);
    let n = 512;
    let mut rays = Vec::with_capacity(n * n);
    for y in 0..n {
        for x in 0..n {
            let px = (x as f32 + 0.5) / n as f32 * 2.0 - 1.0;
            let py = 1.0 - (y as f32 + 0.5) / n as f32 * 2.0;
            let d = Vec3::new(px * 0.45, py * 0.45, -1.0).normalize();
            rays.push(Ray::new(eye, d));
        }
    }
    rays
}

/// Rays from random points in the bounds in random directions.
fn random_rays(lo: Vec3, hi: Vec3, n: usize) -> Vec<Ray> {
    let mut rng = Rng(7);
    (0..n)
        .map(|_| {
            let o = lo + (hi - lo) * Vec3::new(rng.next(), rng.next(), rng.next());
            Ray::new(o, rng.unit())
        })
        .collect()
}

/// Shadow rays from the primary hits towards a point light above the model.
fn shadow_rays(bvh: &NativeBvh, primary: &[Ray], light: Vec3) -> Vec<Ray> {
    primary
        .iter()
        .filter_map(|r| {
            let h = bvh.intersect(r)?;
            let p = r.at(h.t);
            Some(Ray::segment(p, light - p, 1e-4, 1.0 - 1e-4))
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let Some(tris) = load("extras_meshopt/stanford-bunny.glb") else {
        return;
    };
    let bvh = NativeBvh::new(&tris);
    eprintln!("{}", bvh.stats());
    let (lo, hi) = bounds(&tris);

    let mut g = c.benchmark_group("build");
    g.sample_size(10);
    g.bench_function("bunny", |b| {
        b.iter(|| NativeBvh::new(black_box(&tris)).stats().nodes)
    });
    g.finish();

    let primary = primary_rays(lo, hi);
    let random = random_rays(lo, hi, 256 * 1024);
    let light = Vec3::new(lo.x, hi.y + (hi.y - lo.y), hi.z + (hi.z - lo.z));
    let shadow = shadow_rays(&bvh, &primary, light);
    let hit_rate = shadow.len() as f64 / primary.len() as f64;
    eprintln!(
        "primary hit rate {hit_rate:.2}, {} shadow rays",
        shadow.len()
    );

    for isa in pathlight_accel::Isa::supported() {
        let bvh = NativeBvh::with_isa(&tris, isa);
        for (name, rays) in [
            ("primary", &primary),
            ("random", &random),
            ("shadow", &shadow),
        ] {
            let mut g = c.benchmark_group(format!("{}/{name}", isa.name()));
            g.throughput(Throughput::Elements(rays.len() as u64));
            g.sample_size(10);
            g.bench_function("intersect", |b| {
                b.iter(|| rays.iter().filter(|r| bvh.intersect(r).is_some()).count())
            });
            g.bench_function("occluded", |b| {
                b.iter(|| rays.iter().filter(|r| bvh.occluded(r)).count())
            });
            g.finish();
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
