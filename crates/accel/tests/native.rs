//! The native BVH against the brute-force reference, on every instruction set this CPU has.
//!
//! Agreement: both miss, or both hit the same triangle at (nearly) the same distance, or hit
//! different triangles at distances within `1e-4 * max(1, |t|)` (near-ties). Misses must agree
//! exactly on random rays; the grazing cases count their disagreements and bound them.

mod common;

use common::*;
use glam::Vec3;
use pathlight_accel::{Accel, BruteForce, Isa, NativeBvh, Ray, SceneTriangles};

fn check_all(tris: &SceneTriangles, rays: &[Ray]) -> Tally {
    check_backends(tris, rays, Isa::supported(), |tris, isa| {
        Box::new(NativeBvh::with_isa(tris, *isa))
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
fn empty_scene_and_zero_direction() {
    let native = NativeBvh::new(&SceneTriangles::default());
    let r = Ray::new(Vec3::ZERO, Vec3::X);
    assert!(native.intersect(&r).is_none() && !native.occluded(&r));
    assert_eq!(native.stats().triangles, 0);
    let one = soup(vec![[Vec3::ZERO, Vec3::X, Vec3::Y]]);
    let native = NativeBvh::new(&one);
    assert!(native
        .intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::ZERO))
        .is_none());
    let h = native
        .intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z))
        .unwrap();
    assert_eq!((h.instance, h.triangle), (0, 0));
}

#[test]
fn watertight_through_shared_edges_and_vertices() {
    let mut brute_slips = 0;
    let mut total = 0;
    for (seed, jitter, bump) in [(10u64, 0.0f32, 0.0f32), (11, 0.3, 0.0), (12, 0.3, 0.4)] {
        let mut rng = Rng(seed);
        let n = 24;
        let (tris, rot) = height_field(&mut rng, n, jitter, bump);
        let scene = soup(tris.clone());
        let brute = BruteForce::new(scene.clone());
        let up = rot * Vec3::Z;
        let natives: Vec<NativeBvh> = Isa::supported()
            .into_iter()
            .map(|isa| NativeBvh::with_isa(&scene, isa))
            .collect();
        for k in 0..4000 {
            // Interior vertices and points on interior edges (shared by two triangles).
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
            for native in &natives {
                let h = native.intersect(&ray);
                assert!(
                    h.is_some(),
                    "{:?} slipped through at {target} (seed {seed}, ray {ray:?})",
                    native.isa()
                );
                assert!(native.occluded(&ray));
            }
            total += 1;
            if brute.intersect(&ray).is_none() {
                brute_slips += 1;
            }
        }
    }
    eprintln!("brute force (f64 Moller-Trumbore) slipped through {brute_slips} of {total}");
}

#[test]
fn axis_aligned_rays_on_a_grid_hit_vertices_and_edges() {
    // A flat integer grid: rays along -z through vertices, edges and cells, and rays along
    // the other axes and diagonals at exact grid coordinates, with zero direction components.
    let scene = soup(flat_grid(8));
    let brute = BruteForce::new(scene.clone());
    for isa in Isa::supported() {
        let native = NativeBvh::with_isa(&scene, isa);
        for j in 0..=16 {
            for i in 0..=16 {
                let (x, y) = (i as f32 * 0.5, j as f32 * 0.5);
                for d in [-Vec3::Z, Vec3::Z] {
                    let ray = Ray::new(Vec3::new(x, y, -d.z * 3.0), d);
                    let h = native
                        .intersect(&ray)
                        .unwrap_or_else(|| panic!("{isa:?} {ray:?}"));
                    assert!((h.t - 3.0).abs() < 1e-6);
                    assert!(brute.intersect(&ray).is_some());
                }
                // Diagonal rays with a zero x component through grid points.
                let ray = Ray::new(Vec3::new(x, y - 1.0, 1.0), Vec3::new(0.0, 1.0, -1.0));
                let b = brute.intersect(&ray);
                let n = native.intersect(&ray);
                assert_eq!(n.is_some(), b.is_some(), "{isa:?} {ray:?}");
                // Rays in the grid's plane along x and y: both miss (zero determinant).
                for d in [Vec3::X, Vec3::Y, -Vec3::X, Vec3::new(1.0, 1.0, 0.0)] {
                    let ray = Ray::new(Vec3::new(x, y, 0.0) - d * 2.0, d);
                    assert_eq!(native.intersect(&ray), None, "{isa:?} {ray:?}");
                    assert_eq!(brute.intersect(&ray), None);
                    assert!(!native.occluded(&ray));
                }
            }
        }
    }
}

#[test]
fn boxes_grazed_along_axes() {
    // Unit cubes on an integer lattice, rays along the axes at integer and half-integer
    // coordinates: they graze faces, edges and box bounds exactly.
    let mut tris = Vec::new();
    for k in 0..3 {
        for j in 0..3 {
            for i in 0..3 {
                if (i + j + k) % 2 == 1 {
                    continue;
                }
                let o = Vec3::new(i as f32, j as f32, k as f32) * 2.0;
                for axis in 0..3 {
                    for side in [0.0, 1.0] {
                        let n = Vec3::AXES[axis];
                        let u = Vec3::AXES[(axis + 1) % 3];
                        let v = Vec3::AXES[(axis + 2) % 3];
                        let c = o + n * side;
                        tris.push([c, c + u, c + u + v]);
                        tris.push([c, c + u + v, c + v]);
                    }
                }
            }
        }
    }
    let scene = soup(tris);
    let mut rays = Vec::new();
    for a in 0..=12 {
        for b in 0..=12 {
            let (p, q) = (a as f32 * 0.5 - 0.5, b as f32 * 0.5 - 0.5);
            for (o, d) in [
                (Vec3::new(-3.0, p, q), Vec3::X),
                (Vec3::new(9.0, p, q), -Vec3::X),
                (Vec3::new(p, -3.0, q), Vec3::Y),
                (Vec3::new(p, q, 9.0), -Vec3::Z),
                (Vec3::new(p, q, -3.0), Vec3::new(0.0, 1.0, 1.0)),
            ] {
                rays.push(Ray::new(o, d));
            }
        }
    }
    let tally = check_all(&scene, &rays);
    eprintln!("grazing box rays: {tally:?}");
    // Rays exactly along faces are in-plane for those faces; both tests then decide by the
    // perpendicular faces' edges, where they may differ on a few rays.
    assert!(
        tally.miss_mismatch * 50 <= tally.rays,
        "too many grazing disagreements: {tally:?}"
    );
}

#[test]
fn origins_on_surfaces() {
    // Two parallel planes; origins exactly on the lower one.
    let mut tris = Vec::new();
    for z in [0.0f32, 1.0] {
        for j in 0..4 {
            for i in 0..4 {
                let (x, y) = (i as f32, j as f32);
                let a = Vec3::new(x, y, z);
                tris.push([a, a + Vec3::X, a + Vec3::X + Vec3::Y]);
                tris.push([a, a + Vec3::X + Vec3::Y, a + Vec3::Y]);
            }
        }
    }
    let scene = soup(tris);
    let brute = BruteForce::new(scene.clone());
    let mut rng = Rng(30);
    for isa in Isa::supported() {
        let native = NativeBvh::with_isa(&scene, isa);
        for _ in 0..500 {
            let o = Vec3::new(rng.range(0.5, 3.5), rng.range(0.5, 3.5), 0.0);
            let d = Vec3::new(rng.range(-0.3, 0.3), rng.range(-0.3, 0.3), 1.0);
            // t_min = 0: the surface under the origin, at t = 0.
            let h = native.intersect(&Ray::new(o, d)).unwrap();
            let b = brute.intersect(&Ray::new(o, d)).unwrap();
            assert_eq!(h.t, 0.0, "{isa:?}");
            assert_eq!(b.t, 0.0);
            // A small t_min skips it: the upper plane at t = 1.
            let r = Ray::segment(o, d, 1e-4, f32::INFINITY);
            let h = native.intersect(&r).unwrap();
            assert!((h.t - 1.0).abs() < 1e-6, "{isa:?} {h:?}");
            assert!(h.triangle >= 32);
            assert!(native.occluded(&r));
            assert!(!native.occluded(&Ray::segment(o, d, 1e-4, 0.999)));
        }
    }
    // Secondary rays from hit points of a random soup, with a small t_min.
    let mut rng = Rng(31);
    let tris = random_soup(&mut rng, 500, 0.3);
    let scene = soup(tris.clone());
    let native = NativeBvh::new(&scene);
    let mut rays = Vec::new();
    for r in random_rays(&mut rng, &tris, 3000, 1.5) {
        if let Some(h) = native.intersect(&r) {
            rays.push(Ray::segment(r.at(h.t), rng.unit(), 1e-3, f32::INFINITY));
        }
    }
    let tally = check_all(&scene, &rays);
    assert_eq!(tally.miss_mismatch, 0, "{tally:?}");
}

#[test]
fn zero_area_triangles_are_never_hit() {
    let mut rng = Rng(40);
    let good = random_soup(&mut rng, 400, 0.3);
    let mut all = good.clone();
    // Exactly representable (dyadic) corners, so the collinear ones are exactly collinear.
    let dyadic = |rng: &mut Rng| (rng.vec(-1.0, 1.0) * 64.0).round() / 64.0;
    for i in 0..400 {
        let a = dyadic(&mut rng);
        let b = dyadic(&mut rng);
        let d = Vec3::new(1.0, 2.0, -3.0) * (1 + rng.below(8)) as f32 / 8.0;
        all.push(match i % 3 {
            0 => [a, a, a],
            1 => [a, b, a],
            _ => [a, a + d, a + d * 2.0],
        });
    }
    let native = NativeBvh::new(&soup(all.clone()));
    assert_eq!(native.stats().triangles, 400);
    assert_eq!(native.stats().degenerate, 400);
    let reference = BruteForce::new(soup(good));
    for ray in random_rays(&mut rng, &all, 6000, 1.5) {
        let h = native.intersect(&ray);
        if let Some(h) = h {
            assert!(h.triangle < 400, "{h:?}");
        }
        // Rays aimed exactly along the degenerate ones: no crash, no hit on them.
        let deg = &all[400 + rng.below(400)];
        let along = Ray::new(deg[0] - (deg[1] - deg[0]), deg[1] - deg[0]);
        if let Some(h) = native.intersect(&along) {
            assert!(h.triangle < 400, "{h:?}");
        }
        let b = reference.intersect(&ray);
        if let (Some(x), Some(y)) = (h, b) {
            if x.triangle < 400 {
                assert!(close(x.t, y.t), "{x:?} {y:?}");
            }
        }
    }
}

#[test]
fn huge_and_tiny_coordinates() {
    for scale in [1e-20f32, 1e-10, 1e7, 1e15, 1e30] {
        let mut rng = Rng(50);
        let base = random_soup(&mut rng, 300, 0.3);
        let base_rays = random_rays(&mut rng, &base, 1000, 1.5);
        let tris: Vec<[Vec3; 3]> = base.iter().map(|t| t.map(|p| p * scale)).collect();
        let scene = soup(tris);
        let brute = BruteForce::new(scene.clone());
        for isa in Isa::supported() {
            let native = NativeBvh::with_isa(&scene, isa);
            let mut mismatch = 0;
            for r in &base_rays {
                // Direction unscaled, so t scales too; compare t / scale.
                let ray = Ray::segment(r.origin * scale, r.direction, 0.0, f32::INFINITY);
                let n = native.intersect(&ray);
                let b = brute.intersect(&ray);
                assert_eq!(native.occluded(&ray), n.is_some());
                match (n, b) {
                    (Some(x), Some(y)) => {
                        let cos = cosine(r, &base[x.triangle as usize])
                            .min(cosine(r, &base[y.triangle as usize]));
                        assert!(
                            close_conditioned(x.t / scale, y.t / scale, cos),
                            "{scale} {isa:?} {x:?} {y:?} cos {cos}"
                        )
                    }
                    (None, None) => {}
                    _ => mismatch += 1,
                }
            }
            assert_eq!(mismatch, 0, "scale {scale} {isa:?}");
        }
    }
}

#[test]
fn t_max_limits_and_axis_directions() {
    let mut rng = Rng(60);
    let tris = random_soup(&mut rng, 800, 0.2);
    let mut rays = Vec::new();
    for i in 0..3000 {
        let o = rng.vec(-1.5, 1.5);
        let mut d = Vec3::AXES[i % 3] * if i % 2 == 0 { 1.0 } else { -1.0 };
        if i % 4 == 3 {
            d[(i + 1) % 3] = rng.range(-1.0, 1.0);
        }
        let t_max = if i % 3 == 0 {
            f32::INFINITY
        } else {
            rng.range(0.0, 3.0)
        };
        rays.push(Ray::segment(o, d, 0.0, t_max));
        // Also with a -0.0 component.
        rays.push(Ray::segment(o, d * Vec3::new(-1.0, 1.0, 1.0), 0.0, t_max));
    }
    let scene = soup(tris);
    let tally = check_all(&scene, &rays);
    assert_eq!(tally.miss_mismatch, 0, "{tally:?}");
    assert!(tally.hits > 100, "{tally:?}");
    // Hits exactly at t_max count, just beyond don't.
    let native = NativeBvh::new(&scene);
    for r in &rays {
        if let Some(h) = native.intersect(r) {
            let below = Ray::segment(r.origin, r.direction, 0.0, h.t * (1.0 - 1e-4));
            if let Some(g) = native.intersect(&below) {
                assert!(g.t <= below.t_max && g.t < h.t);
            }
            assert!(native.occluded(&Ray::segment(r.origin, r.direction, 0.0, h.t)));
        }
    }
}

#[test]
fn build_is_deterministic_across_thread_counts() {
    let mut rng = Rng(70);
    let tris = soup(random_soup(&mut rng, 20_000, 0.05));
    let build = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| NativeBvh::new(&tris))
    };
    let (a, b) = (build(1), build(3));
    let (sa, sb) = (a.stats(), b.stats());
    assert_eq!(
        (sa.nodes, sa.leaves, sa.packets, sa.depth, sa.sah_cost),
        (sb.nodes, sb.leaves, sb.packets, sb.depth, sb.sah_cost)
    );
    for r in random_rays(&mut rng, &tris.corners, 2000, 1.5) {
        assert_eq!(a.intersect(&r), b.intersect(&r));
    }
}

fn check_mesh(rel: &str, rays: usize) {
    let Some(tris) = load_shared(rel) else { return };
    let native = NativeBvh::new(&tris);
    eprintln!("{rel}: {}", native.stats());
    let (lo, hi) = tris.corners.iter().flatten().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let c = (lo + hi) * 0.5;
    let r = (hi - lo).length() * 0.5;
    let mut rng = Rng(80);
    let mut list = Vec::new();
    for i in 0..rays {
        let ray = match i % 3 {
            // From outside, aimed at a random triangle.
            0 => {
                let o = c + rng.unit() * r * 2.0;
                let t = &tris.corners[rng.below(tris.len())];
                Ray::new(o, point_in(&mut rng, t) - o)
            }
            // From inside the bounds, random direction.
            1 => Ray::new(lo + (hi - lo) * rng.vec(0.0, 1.0), rng.unit()),
            // Shadow-ray-like segments.
            _ => {
                let o = lo + (hi - lo) * rng.vec(0.0, 1.0);
                Ray::segment(o, rng.unit() * r, 1e-4, 1.0)
            }
        };
        list.push(ray);
    }
    let brute = BruteForce::new(tris.clone());
    let corners = Corners::new(&tris);
    let mut tally = Tally::default();
    for ray in &list {
        compare(&native, &brute, &corners, ray, &mut tally);
    }
    eprintln!("{rel}: {tally:?}");
    assert_eq!(tally.wrong, 0, "{rel}: {tally:?}");
    assert!(tally.miss_mismatch <= rays / 1000, "{rel}: {tally:?}");
}

#[test]
fn stanford_bunny_agrees_with_brute_force() {
    check_mesh("extras_meshopt/stanford-bunny.glb", 1500);
}

#[test]
fn cornell_box_agrees_with_brute_force() {
    check_mesh("CornellBox/CornellBox-Original.gltf", 20_000);
}
