//! The two-level [`InstancedBvh`] against the brute-force reference over the flattened
//! world-space triangles, on a hand-built scene where meshes are placed several times with
//! translations, rotations and non-uniform scales.

mod common;

use common::*;
use glam::{Mat4, Quat, Vec3};
use pathlight_accel::{build_accel, Accel, BruteForce, InstancedBvh, Ray, SceneTriangles};
use pathlight_scene::{Instance, Material, Mesh, Scene};

fn mesh_of(tris: &[[Vec3; 3]], name: &str) -> Mesh {
    Mesh {
        name: name.into(),
        positions: tris.iter().flatten().copied().collect(),
        indices: (0..tris.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect(),
        material: 0,
        ..Mesh::default()
    }
}

fn instance(mesh: u32, transform: Mat4) -> Instance {
    Instance {
        mesh,
        transform,
        name: String::new(),
    }
}

fn random_transform(rng: &mut Rng) -> Mat4 {
    Mat4::from_scale_rotation_translation(
        Vec3::new(
            rng.range(0.3, 2.5),
            rng.range(0.3, 2.5),
            rng.range(0.3, 2.5),
        ),
        Quat::from_axis_angle(rng.unit(), rng.range(0.0, 6.2)),
        rng.vec(-4.0, 4.0),
    )
}

/// A random soup placed `copies` times and a height field placed twice, all with random
/// transforms (the rotation comes before the non-uniform scale too, so instances shear).
fn instanced_scene(seed: u64, copies: usize) -> Scene {
    let mut rng = Rng(seed);
    let soup_tris = random_soup(&mut rng, 300, 0.3);
    let (grid, _) = height_field(&mut rng, 6, 0.2, 0.3);
    let mut scene = Scene {
        name: "instanced test".into(),
        meshes: vec![mesh_of(&soup_tris, "soup"), mesh_of(&grid, "grid")],
        materials: vec![Material::default()],
        ..Scene::default()
    };
    for _ in 0..copies {
        let t = random_transform(&mut rng);
        scene.instances.push(instance(0, t));
    }
    for _ in 0..2 {
        let t = random_transform(&mut rng) * random_transform(&mut rng);
        scene.instances.push(instance(1, t));
    }
    scene
}

/// Compares on `n` random rays; returns the tally and the number of near-tie hits on a
/// different (instance, triangle) than the reference.
fn check(scene: &Scene, n: usize, seed: u64) -> (Tally, usize) {
    let tris = SceneTriangles::from_scene(scene);
    let brute = BruteForce::new(tris.clone());
    let corners = Corners::new(&tris);
    let accel = InstancedBvh::new(scene);
    assert_eq!(accel.name(), "native-instanced");
    let mut rng = Rng(seed);
    let rays = random_rays(&mut rng, &tris.corners, n, 7.0);
    let mut tally = Tally::default();
    let mut ties = 0;
    for r in &rays {
        compare(&accel, &brute, &corners, r, &mut tally);
        if let (Some(a), Some(b)) = (accel.intersect(r), brute.intersect(r)) {
            if (a.instance, a.triangle) != (b.instance, b.triangle) {
                assert!(close(a.t, b.t), "{a:?} brute {b:?} for {r:?}");
                ties += 1;
            }
        }
    }
    (tally, ties)
}

#[test]
fn instanced_agrees_with_brute_force() {
    for (seed, copies) in [(11u64, 3usize), (12, 4), (13, 5)] {
        let scene = instanced_scene(seed, copies);
        let (tally, ties) = check(&scene, 4000, seed + 100);
        eprintln!("seed {seed}: {tally:?}, near-tie id differences {ties}");
        assert_eq!(tally.wrong, 0, "seed {seed}: {tally:?}");
        assert_eq!(tally.miss_mismatch, 0, "seed {seed}: {tally:?}");
        assert!(tally.hits > 1000, "seed {seed}: {tally:?}");
        assert_eq!(
            ties, 0,
            "seed {seed}: {ties} hits on another triangle at a near-tie"
        );
    }
}

#[test]
fn many_instances_and_a_flattened_one() {
    // 80 copies of the soup (a deeper top level), plus a height field squashed flat by a
    // singular transform, which the instanced structure traces in world space.
    let mut scene = instanced_scene(21, 80);
    let flat = Mat4::from_translation(Vec3::new(0.5, -1.0, 0.2))
        * Mat4::from_scale(Vec3::new(1.0, 1.0, 0.0))
        * Mat4::from_rotation_x(0.7);
    scene.instances.push(instance(1, flat));
    let (tally, ties) = check(&scene, 3000, 22);
    assert_eq!(ties, 0);
    assert_eq!(tally.wrong, 0, "{tally:?}");
    assert_eq!(tally.miss_mismatch, 0, "{tally:?}");
    assert!(tally.hits > 1000, "{tally:?}");
    // Rays aimed at the flattened instance find it.
    let last = scene.instances.len() as u32 - 1;
    let tris = SceneTriangles::from_scene(&scene);
    let accel = InstancedBvh::new(&scene);
    let mut rng = Rng(23);
    let flat_hits = (0..tris.len())
        .filter(|&k| tris.ids[k].0 == last)
        .filter(|&k| {
            let p = point_in(&mut rng, &tris.corners[k]);
            let o = p + Vec3::new(0.1, 0.2, 3.0);
            let h = accel.intersect(&Ray::new(o, p - o));
            h.is_some_and(|h| h.instance == last)
        })
        .count();
    assert!(flat_hits > 0);
}

#[test]
fn empty_and_unused() {
    let mut scene = instanced_scene(31, 0);
    scene.instances.clear();
    let accel = InstancedBvh::new(&scene);
    let r = Ray::new(Vec3::splat(-5.0), Vec3::ONE);
    assert!(accel.intersect(&r).is_none() && !accel.occluded(&r));
}

#[test]
fn build_accel_picks_the_instanced_path_only_for_shared_meshes() {
    let scene = instanced_scene(41, 3);
    let accel = build_accel(&scene);
    assert_eq!(accel.name(), "native-instanced");
    let cornell = pathlight_scene::cornell::cornell_box();
    assert_eq!(build_accel(&cornell).name(), "native");
    // The same Cornell box hits agree whichever path is taken.
    let inst = InstancedBvh::new(&cornell);
    let flat = build_accel(&cornell);
    let mut rng = Rng(42);
    let tris = SceneTriangles::from_scene(&cornell);
    let mut hits = 0;
    for r in random_rays(&mut rng, &tris.corners, 500, 1.0) {
        let (a, b) = (inst.intersect(&r), flat.intersect(&r));
        assert_eq!(a.is_some(), b.is_some(), "{r:?}");
        if let (Some(a), Some(b)) = (a, b) {
            assert!(close(a.t, b.t), "{a:?} {b:?}");
            hits += 1;
        }
    }
    assert!(hits > 100, "{hits}");
}
