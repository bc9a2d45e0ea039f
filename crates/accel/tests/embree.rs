//! The Embree backend against the brute-force reference and the native BVH, with the same
//! agreement rule as `native.rs`: both miss, or the hits are at (nearly) the same distance
//! (`1e-4 * max(1, |t|)`, widened for grazing rays).

#![cfg(feature = "embree")]

mod common;

use common::*;
use glam::Vec3;
use pathlight_accel::embree3::BuildQuality;
use pathlight_accel::{
    Accel, BruteForce, EmbreeAccel, EmbreeOptions, Hit, NativeBvh, Ray, RayKind, RaySets,
    SceneTriangles,
};

/// Every build configuration the tests cover: the default (high quality, robust) and Embree's
/// own default (medium, not robust).
fn configurations() -> Vec<EmbreeOptions> {
    vec![
        EmbreeOptions::default(),
        EmbreeOptions {
            quality: BuildQuality::MEDIUM,
            robust: false,
            ..EmbreeOptions::default()
        },
    ]
}

fn check_all(tris: &SceneTriangles, rays: &[Ray]) -> Tally {
    check_backends(tris, rays, configurations(), |tris, options| {
        Box::new(EmbreeAccel::with_options(tris, *options).unwrap())
    })
}

#[test]
fn random_soups_agree_with_brute_force() {
    for (seed, n, size) in [
        (1u64, 1usize, 0.5f32),
        (2, 5, 0.5),
        (3, 37, 0.3),
        (4, 300, 0.2),
        (5, 3000, 0.05),
        (6, 2000, 1.5),
    ] {
        let mut rng = Rng(seed);
        let tris = random_soup(&mut rng, n, size);
        let rays = random_rays(&mut rng, &tris, 3000, 1.5);
        let tally = check_all(&soup(tris), &rays);
        assert_eq!(tally.miss_mismatch, 0, "seed {seed}: {tally:?}");
        assert!(tally.hits > 0, "seed {seed}: {tally:?}");
    }
}

#[test]
fn empty_scene_and_ids() {
    let embree = EmbreeAccel::new(&SceneTriangles::default()).unwrap();
    let r = Ray::new(Vec3::ZERO, Vec3::X);
    assert!(embree.intersect(&r).is_none() && !embree.occluded(&r));
    assert_eq!(embree.name(), "embree");

    // Ids map back through `SceneTriangles::ids`, not the flat index.
    let tris = SceneTriangles {
        corners: vec![
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [Vec3::Z, Vec3::Z + Vec3::X, Vec3::Z + Vec3::Y],
        ],
        ids: vec![(3, 9), (5, 2)],
    };
    let embree = EmbreeAccel::new(&tris).unwrap();
    let h = embree
        .intersect(&Ray::new(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z))
        .unwrap();
    assert_eq!((h.instance, h.triangle), (5, 2));
    assert!((h.t - 1.0).abs() < 1e-6);
    // Barycentrics as ours: the hit is (1 - u - v) p0 + u p1 + v p2.
    assert!(
        (h.u - 0.2).abs() < 1e-6 && (h.v - 0.3).abs() < 1e-6,
        "{h:?}"
    );
    let h = embree
        .intersect(&Ray::segment(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z, 0.0, 1.5))
        .map(|h| (h.instance, h.triangle));
    assert_eq!(h, Some((5, 2)));
    let short = Ray::segment(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z, 0.0, 0.5);
    assert!(embree.intersect(&short).is_none() && !embree.occluded(&short));
    let beyond = Ray::segment(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z, 1.5, f32::INFINITY);
    assert_eq!(embree.intersect(&beyond).map(|h| h.instance), Some(3));
    assert!(embree.memory_bytes() > 0);
}

#[test]
fn batches_match_single_rays() {
    let mut rng = Rng(20);
    let tris = random_soup(&mut rng, 2000, 0.1);
    let rays = random_rays(&mut rng, &tris, 5000, 1.5);
    let embree = EmbreeAccel::new(&soup(tris)).unwrap();
    let mut hits = vec![None; rays.len()];
    let mut occluded = vec![false; rays.len()];
    embree.intersect_batch(&rays, &mut hits);
    embree.occluded_batch(&rays, &mut occluded);
    for (i, r) in rays.iter().enumerate() {
        assert_eq!(hits[i], embree.intersect(r), "{r:?}");
        assert_eq!(occluded[i], embree.occluded(r), "{r:?}");
    }
    assert!(hits.iter().any(Option::is_some));
}

#[test]
fn robust_mode_rarely_slips_through_shared_edges_and_vertices() {
    let mut slips = [0usize; 2];
    let mut total = 0;
    for (seed, jitter, bump) in [(10u64, 0.0f32, 0.0f32), (11, 0.3, 0.0), (12, 0.3, 0.4)] {
        let mut rng = Rng(seed);
        let n = 24;
        let (tris, rot) = height_field(&mut rng, n, jitter, bump);
        let scene = soup(tris.clone());
        let up = rot * Vec3::Z;
        let backends: Vec<EmbreeAccel> = configurations()
            .into_iter()
            .map(|o| EmbreeAccel::with_options(&scene, o).unwrap())
            .collect();
        for k in 0..4000 {
            let t = &tris[(2 + rng.below(n - 4)) * 2 * n + 2 * (2 + rng.below(n - 4))];
            let target = match k % 3 {
                0 => t[rng.below(3)],
                1 => t[0].lerp(t[1], rng.f()),
                _ => t[1].lerp(t[2], rng.f()),
            };
            let side = if k % 2 == 0 { 1.0 } else { -1.0 };
            let mut dir_out = rng.unit();
            if dir_out.dot(up) * side < 0.2 {
                dir_out = (dir_out + up * side * 2.0).normalize();
            }
            let origin = target + dir_out * rng.range(0.5, 30.0);
            let ray = Ray::new(origin, target - origin);
            total += 1;
            for (b, slip) in backends.iter().zip(slips.iter_mut()) {
                if b.intersect(&ray).is_none() {
                    *slip += 1;
                }
            }
        }
    }
    eprintln!(
        "slipped through: robust {} of {total}, default {}",
        slips[0], slips[1]
    );
    // Embree 3.13.5 is not exactly watertight, even in robust mode (the native BVH is; see
    // native.rs): rays aimed exactly at shared vertices and edges occasionally slip through.
    // Measured: robust 37 of 12000, default (medium, not robust) 1368 of 12000.
    assert!(
        slips[0] * 100 <= total,
        "robust Embree: {} of {total}",
        slips[0]
    );
}

fn check_mesh(tris: &SceneTriangles, name: &str, rays: usize) {
    let embree = EmbreeAccel::new(tris).unwrap();
    let (lo, hi) = tris.corners.iter().flatten().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let c = (lo + hi) * 0.5;
    let r = (hi - lo).length() * 0.5;
    let mut rng = Rng(80);
    let brute = BruteForce::new(tris.clone());
    let corners = Corners::new(tris);
    let mut tally = Tally::default();
    for i in 0..rays {
        let ray = match i % 3 {
            0 => {
                let o = c + rng.unit() * r * 2.0;
                let t = &tris.corners[rng.below(tris.len())];
                Ray::new(o, point_in(&mut rng, t) - o)
            }
            1 => Ray::new(lo + (hi - lo) * rng.vec(0.0, 1.0), rng.unit()),
            _ => {
                let o = lo + (hi - lo) * rng.vec(0.0, 1.0);
                Ray::segment(o, rng.unit() * r, 1e-4, 1.0)
            }
        };
        compare(&embree, &brute, &corners, &ray, &mut tally);
    }
    eprintln!("{name}: {tally:?}");
    assert_eq!(tally.wrong, 0, "{name}: {tally:?}");
    assert!(tally.miss_mismatch <= rays / 1000, "{name}: {tally:?}");
}

#[test]
fn built_in_cornell_box_agrees_with_brute_force() {
    let scene = pathlight_scene::load(None, &Default::default()).unwrap();
    check_mesh(
        &SceneTriangles::from_scene(&scene),
        "built-in Cornell box",
        20_000,
    );
}

#[test]
fn cornell_box_agrees_with_brute_force() {
    if let Some(tris) = load_shared("CornellBox/CornellBox-Original.gltf") {
        check_mesh(&tris, "CornellBox-Original", 20_000);
    }
}

#[test]
fn stanford_bunny_agrees_with_brute_force() {
    if let Some(tris) = load_shared("extras_meshopt/stanford-bunny.glb") {
        check_mesh(&tris, "stanford-bunny", 1500);
    }
}

fn agree(a: Option<Hit>, b: Option<Hit>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(x), Some(y)) => {
            (x.instance, x.triangle) == (y.instance, y.triangle) || close(x.t, y.t)
        }
        _ => false,
    }
}

#[test]
fn ray_sets_agree_with_native_on_the_cornell_box() {
    let scene = pathlight_scene::load(None, &Default::default()).unwrap();
    let tris = SceneTriangles::from_scene(&scene);
    let native = NativeBvh::new(&tris);
    let embree = EmbreeAccel::new(&tris).unwrap();
    let sets = RaySets::generate(&scene, &native, 128, 128, 3);
    for kind in RayKind::ALL {
        let mut mismatches = 0;
        for r in sets.get(kind) {
            let ok = if kind.is_occlusion() {
                native.occluded(r) == embree.occluded(r)
            } else {
                agree(native.intersect(r), embree.intersect(r))
            };
            if !ok {
                mismatches += 1;
                eprintln!(
                    "{}: native {:?} embree {:?} for {r:?}",
                    kind.name(),
                    native.intersect(r),
                    embree.intersect(r)
                );
            }
        }
        assert_eq!(mismatches, 0, "{}", kind.name());
    }
}
