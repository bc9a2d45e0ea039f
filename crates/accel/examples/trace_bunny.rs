//! Profiling driver: builds the native BVH on the Stanford bunny and traces a fixed set of rays
//! (camera primary rays framing the bunny, cosine bounce rays from the hits, shadow rays from
//! the hits towards a point light), single-threaded.
//!
//! `cargo run --release -p pathlight-accel --example trace_bunny -- [reps] [isa]`
//!
//! Under callgrind, `trace_primary`, `trace_bounce` and `trace_shadow` are separate
//! `#[inline(never)]` functions, so their inclusive instruction counts are per ray category.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

use glam::Vec3;
use pathlight_accel::{Accel, Isa, NativeBvh, Ray, SceneTriangles};

/// SplitMix64.
struct Rng(u64);
impl Rng {
    fn f(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn shared_dir() -> PathBuf {
    pathlight_core::shared_data::dir(env!("CARGO_MANIFEST_DIR"))
}

#[inline(never)]
fn trace_primary(bvh: &NativeBvh, rays: &[Ray]) -> usize {
    // Counts hits in front of the camera's near plane too, so that the compiler can't merge
    // this function with `trace_bounce` (callgrind then reports them apart).
    rays.iter()
        .filter(|r| bvh.intersect(r).is_some_and(|h| h.t >= 0.0))
        .count()
}

#[inline(never)]
fn trace_bounce(bvh: &NativeBvh, rays: &[Ray]) -> usize {
    rays.iter().filter(|r| bvh.intersect(r).is_some()).count()
}

#[inline(never)]
fn trace_shadow(bvh: &NativeBvh, rays: &[Ray]) -> usize {
    rays.iter().filter(|r| bvh.occluded(r)).count()
}

fn main() {
    let mut args = std::env::args().skip(1);
    let reps: usize = args.next().map_or(1, |a| a.parse().unwrap());
    let isa = match args.next().as_deref() {
        Some("scalar") => Isa::Scalar,
        Some("sse2") => Isa::Sse2,
        Some("avx2") => Isa::Avx2,
        _ => Isa::best(),
    };
    let path = shared_dir().join("scenes/extras_meshopt/stanford-bunny.glb");
    let scene = pathlight_scene::load_file(&path, &pathlight_scene::Limits::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let tris = SceneTriangles::from_scene(&scene);
    let bvh = NativeBvh::with_isa(&tris, isa);
    eprintln!("{}", bvh.stats());
    let index: HashMap<(u32, u32), usize> = tris
        .ids
        .iter()
        .enumerate()
        .map(|(i, &id)| (id, i))
        .collect();

    let (lo, hi) = tris.corners.iter().flatten().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let c = (lo + hi) * 0.5;
    let ext = hi - lo;
    let scale = ext.length();

    // Primary: a 320 x 320 camera looking down -z at the bunny, framing its x/y extent.
    let n = 320;
    let dist = 2.0 * scale;
    let eye = Vec3::new(c.x, c.y, hi.z + dist);
    let half = 0.5 * ext.x.max(ext.y) * 1.02 / (eye.z - c.z);
    let mut primary = Vec::with_capacity(n * n);
    for y in 0..n {
        for x in 0..n {
            let px = (x as f32 + 0.5) / n as f32 * 2.0 - 1.0;
            let py = 1.0 - (y as f32 + 0.5) / n as f32 * 2.0;
            let d = Vec3::new(px * half, py * half, -1.0).normalize();
            primary.push(Ray::new(eye, d));
        }
    }

    // Bounce and shadow rays from the primary hits.
    let light = Vec3::new(lo.x, hi.y + ext.y, hi.z + ext.z);
    let eps = 1e-5 * scale;
    let mut rng = Rng(1);
    let mut bounce = Vec::new();
    let mut shadow = Vec::new();
    for r in &primary {
        let Some(h) = bvh.intersect(r) else { continue };
        let t = &tris.corners[index[&(h.instance, h.triangle)]];
        let mut nrm = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
        if nrm.dot(r.direction) > 0.0 {
            nrm = -nrm;
        }
        let p = r.at(h.t);
        // Cosine-weighted direction around the normal.
        let (u1, u2) = (rng.f(), rng.f());
        let (rad, phi) = (u1.sqrt(), std::f32::consts::TAU * u2);
        let a = if nrm.x.abs() > 0.9 { Vec3::Y } else { Vec3::X };
        let tx = nrm.cross(a).normalize();
        let ty = nrm.cross(tx);
        let d = tx * (rad * phi.cos()) + ty * (rad * phi.sin()) + nrm * (1.0 - u1).max(0.0).sqrt();
        bounce.push(Ray::segment(p, d, eps, f32::INFINITY));
        shadow.push(Ray::segment(p, light - p, eps / scale, 1.0 - 1e-4));
    }
    let total = primary.len() + bounce.len() + shadow.len();
    eprintln!(
        "{} primary, {} bounce, {} shadow rays ({total} in all)",
        primary.len(),
        bounce.len(),
        shadow.len()
    );

    type Trace = fn(&NativeBvh, &[Ray]) -> usize;
    let sets: [(&str, &[Ray], Trace); 3] = [
        ("primary", &primary, trace_primary),
        ("bounce", &bounce, trace_bounce),
        ("shadow", &shadow, trace_shadow),
    ];
    for (name, rays, f) in sets {
        let mut times = Vec::new();
        let mut hits = 0;
        for _ in 0..reps {
            let start = Instant::now();
            hits = f(&bvh, rays);
            times.push(start.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        let med = times[times.len() / 2];
        let best = times[0];
        println!(
            "{:>7} {name:>8}: {:6} rays, {:5.1}% hit, median {:6.2} Mrays/s, best {:6.2} Mrays/s",
            isa.name(),
            rays.len(),
            100.0 * hits as f64 / rays.len() as f64,
            rays.len() as f64 / med / 1e6,
            rays.len() as f64 / best / 1e6,
        );
    }
}
