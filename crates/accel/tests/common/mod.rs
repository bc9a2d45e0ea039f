//! Helpers shared by the backend tests (`native.rs`, `embree.rs`): a seeded generator, random
//! triangle soups and rays, the agreement check against the brute-force reference, and the
//! shared scenes.

#![allow(dead_code)]

use glam::{Mat3, Vec3};
use pathlight_accel::{Accel, BruteForce, Ray, SceneTriangles};

/// SplitMix64.
pub struct Rng(pub u64);

impl Rng {
    pub fn u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn f(&mut self) -> f32 {
        (self.u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f()
    }
    pub fn vec(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
    pub fn unit(&mut self) -> Vec3 {
        loop {
            let v = self.vec(-1.0, 1.0);
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.u64() % n as u64) as usize
    }
}

pub fn soup(tris: Vec<[Vec3; 3]>) -> SceneTriangles {
    let ids = (0..tris.len() as u32).map(|i| (i / 7, i)).collect();
    SceneTriangles { corners: tris, ids }
}

/// `n` random triangles of size up to `size` in the cube [-1, 1]^3.
pub fn random_soup(rng: &mut Rng, n: usize, size: f32) -> Vec<[Vec3; 3]> {
    (0..n)
        .map(|_| {
            let c = rng.vec(-1.0, 1.0);
            [c, c + rng.unit() * size, c + rng.unit() * size]
        })
        .collect()
}

/// A random point inside triangle `t`.
pub fn point_in(rng: &mut Rng, t: &[Vec3; 3]) -> Vec3 {
    let (mut a, mut b) = (rng.f(), rng.f());
    if a + b > 1.0 {
        a = 1.0 - a;
        b = 1.0 - b;
    }
    t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b
}

/// Rays from around the soup: half in random directions, half aimed at a random triangle.
pub fn random_rays(rng: &mut Rng, tris: &[[Vec3; 3]], n: usize, extent: f32) -> Vec<Ray> {
    (0..n)
        .map(|i| {
            let o = rng.vec(-extent, extent);
            let d = if i % 2 == 0 || tris.is_empty() {
                rng.unit()
            } else {
                let k = rng.below(tris.len());
                point_in(rng, &tris[k]) - o
            };
            let mut r = Ray::new(o, d);
            if i % 5 == 1 {
                r.t_max = rng.range(0.0, 2.0);
            }
            if i % 7 == 2 {
                r.t_min = rng.range(0.0, 0.5);
            }
            r
        })
        .collect()
}

#[derive(Default, Debug)]
pub struct Tally {
    pub rays: usize,
    pub hits: usize,
    /// One hit and the other missed.
    pub miss_mismatch: usize,
    /// Different triangles at clearly different distances.
    pub wrong: usize,
}

pub fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-4 * a.abs().max(1.0)
}

/// |cos| of the angle between the ray and the triangle's normal, in f64.
pub fn cosine(ray: &Ray, t: &[Vec3; 3]) -> f64 {
    let [a, b, c] = t.map(|p| p.as_dvec3());
    let n = (b - a).cross(c - a).normalize();
    n.dot(ray.direction.as_dvec3().normalize()).abs()
}

/// `close`, widened for grazing rays: the distance to a triangle seen at a grazing angle is
/// ill-conditioned (a relative change of 1e-7 in a corner moves it by about 1e-7 / cos), so the
/// f32 test and the f64 reference may differ by that much.
pub fn close_conditioned(a: f32, b: f32, cos: f64) -> bool {
    let tol = a.abs().max(1.0) as f64 * (1e-4 + 4e-7 / cos.max(1e-9));
    ((a - b).abs() as f64) <= tol
}

/// Where each (instance, triangle) id is in a `SceneTriangles`.
pub struct Corners<'a> {
    tris: &'a SceneTriangles,
    index: std::collections::HashMap<(u32, u32), usize>,
}

impl<'a> Corners<'a> {
    pub fn new(tris: &'a SceneTriangles) -> Self {
        let index = tris
            .ids
            .iter()
            .enumerate()
            .map(|(i, &id)| (id, i))
            .collect();
        Self { tris, index }
    }
    pub fn of(&self, h: &pathlight_accel::Hit) -> &[Vec3; 3] {
        &self.tris.corners[self.index[&(h.instance, h.triangle)]]
    }
}

/// Compares one ray of `native` (the backend under test) with the brute-force reference;
/// counts wrong hits and miss mismatches.
pub fn compare(
    native: &dyn Accel,
    brute: &BruteForce,
    corners: &Corners,
    ray: &Ray,
    tally: &mut Tally,
) {
    let n = native.intersect(ray);
    let b = brute.intersect(ray);
    let occ = native.occluded(ray);
    tally.rays += 1;
    assert_eq!(
        occ,
        n.is_some(),
        "occluded() disagrees with intersect() for {ray:?}"
    );
    if let Some(h) = n {
        assert!(
            h.t >= ray.t_min && h.t <= ray.t_max,
            "t out of range: {h:?} {ray:?}"
        );
    }
    match (n, b) {
        (None, None) => {}
        (Some(x), Some(y)) => {
            tally.hits += 1;
            let same = (x.instance, x.triangle) == (y.instance, y.triangle);
            let cos = cosine(ray, corners.of(&x)).min(cosine(ray, corners.of(&y)));
            if !close_conditioned(x.t, y.t, cos) {
                eprintln!("wrong hit: {} {x:?} brute {y:?} for {ray:?}", native.name());
                tally.wrong += 1;
            } else if same && cos > 1e-2 {
                assert!(
                    (x.u - y.u).abs() < 1e-3 && (x.v - y.v).abs() < 1e-3,
                    "barycentrics: {} {x:?} brute {y:?}",
                    native.name()
                );
            }
        }
        _ => {
            tally.miss_mismatch += 1;
            if tally.miss_mismatch <= 3 {
                eprintln!(
                    "miss mismatch: {} {n:?} brute {b:?} for {ray:?}",
                    native.name()
                );
            }
        }
    }
}

/// A flat `n x n` grid of unit squares in the plane z = 0, two triangles each, with every
/// corner at integer coordinates: rays can pass exactly through its edges and vertices.
pub fn flat_grid(n: usize) -> Vec<[Vec3; 3]> {
    let mut grid = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f32, j as f32);
            let a = Vec3::new(x, y, 0.0);
            let b = Vec3::new(x + 1.0, y, 0.0);
            let c = Vec3::new(x, y + 1.0, 0.0);
            let d = Vec3::new(x + 1.0, y + 1.0, 0.0);
            grid.push([a, b, d]);
            grid.push([a, d, c]);
        }
    }
    grid
}

/// A height field of `n x n` quads (two triangles each) sharing every edge, rotated to a
/// generic orientation, with its rotation.
pub fn height_field(rng: &mut Rng, n: usize, jitter: f32, bump: f32) -> (Vec<[Vec3; 3]>, Mat3) {
    let rot = Mat3::from_axis_angle(rng.unit(), rng.range(0.0, 3.0));
    let mut v = vec![Vec3::ZERO; (n + 1) * (n + 1)];
    for j in 0..=n {
        for i in 0..=n {
            let p = Vec3::new(
                i as f32 + rng.range(-jitter, jitter),
                j as f32 + rng.range(-jitter, jitter),
                rng.range(-bump, bump),
            );
            v[j * (n + 1) + i] = rot * p;
        }
    }
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = v[j * (n + 1) + i];
            let b = v[j * (n + 1) + i + 1];
            let c = v[(j + 1) * (n + 1) + i];
            let d = v[(j + 1) * (n + 1) + i + 1];
            if (i + j) % 2 == 0 {
                tris.push([a, b, d]);
                tris.push([a, d, c]);
            } else {
                tris.push([a, b, c]);
                tris.push([b, d, c]);
            }
        }
    }
    (tris, rot)
}

/// A scene of the shared pack (`None`: skipped off CI, see [`pathlight_core::shared_data`]).
pub fn load_shared(rel: &str) -> Option<SceneTriangles> {
    let path = pathlight_core::shared_data::dir(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(rel);
    if !pathlight_core::shared_data::present(&path) {
        return None;
    }
    let scene = pathlight_scene::load_file(&path, &pathlight_scene::Limits::default())
        .unwrap_or_else(|e| panic!("{e}"));
    Some(SceneTriangles::from_scene(&scene))
}

/// Checks every backend `configurations` builds against the brute force on `rays`: no wrong hit
/// for any of them; returns the summed tally (hits and miss disagreements) for the caller to bound.
pub fn check_backends<C: std::fmt::Debug>(
    tris: &SceneTriangles,
    rays: &[Ray],
    configurations: impl IntoIterator<Item = C>,
    build: impl Fn(&SceneTriangles, &C) -> Box<dyn Accel>,
) -> Tally {
    let brute = BruteForce::new(tris.clone());
    let corners = Corners::new(tris);
    let mut total = Tally::default();
    for config in configurations {
        let accel = build(tris, &config);
        let mut tally = Tally::default();
        for r in rays {
            compare(accel.as_ref(), &brute, &corners, r, &mut tally);
        }
        assert_eq!(tally.wrong, 0, "{config:?}: {tally:?}");
        total.rays += tally.rays;
        total.hits += tally.hits;
        total.miss_mismatch += tally.miss_mismatch;
    }
    total
}
