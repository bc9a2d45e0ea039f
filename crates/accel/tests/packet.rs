//! Packets of eight rays (`NativeBvh::intersect_packet` and `intersect_batch`) against single
//! rays, on every instruction set this CPU has: each ray must get exactly, bit for bit, the hit
//! the single-ray traversal gives it, whether its batch was traced as packets or one ray at a
//! time. Where
//! several triangles are hit at the same distance (rays through shared edges and vertices),
//! the hit must be the one of smallest index, found by testing every triangle.

mod common;

use common::*;
use glam::Vec3;
use pathlight_accel::triangle::intersect_triangle;
use pathlight_accel::{Accel, Hit, Isa, NativeBvh, Ray, SceneTriangles, PACKET};

/// Eight rays from `origin` through a row of "pixels" `step` apart around `target`, as a
/// pinhole camera's neighbouring pixels: they share a packet.
fn fan(origin: Vec3, target: Vec3, across: Vec3, step: f32) -> [Ray; 8] {
    std::array::from_fn(|i| Ray::new(origin, target + across * (i as f32 - 3.5) * step - origin))
}

/// Traces `rays` in batches and one by one with every instruction set, and each group of eight
/// as a packet where it is coherent enough: at least the fraction `packets` of the groups must
/// be. Returns how many rays hit.
fn check(tris: &SceneTriangles, rays: &[Ray], packets: f64) -> usize {
    let mut hit = 0;
    for isa in Isa::supported() {
        let native = NativeBvh::with_isa(tris, isa);
        let mut batch = vec![None; rays.len()];
        native.intersect_batch(rays, &mut batch);
        let single: Vec<Option<Hit>> = rays.iter().map(|r| native.intersect(r)).collect();
        for (i, ray) in rays.iter().enumerate() {
            assert_eq!(batch[i], single[i], "{isa:?} {ray:?}");
        }
        let mut traced = 0;
        for (k, group) in rays.chunks_exact(PACKET).enumerate() {
            let group: &[Ray; PACKET] = group.try_into().unwrap();
            if let Some(packet) = native.intersect_packet(group) {
                assert_eq!(packet[..], single[k * PACKET..(k + 1) * PACKET], "{isa:?}");
                traced += 1;
            }
        }
        let groups = rays.len() / PACKET;
        assert!(
            traced as f64 >= packets * groups as f64,
            "{isa:?}: {traced} of {groups} groups traced as packets"
        );
        hit = single.iter().flatten().count();
    }
    hit
}

/// The hit every triangle's test gives, nearest first and then smallest index.
fn every_triangle(tris: &SceneTriangles, ray: &Ray) -> Option<(f32, u32)> {
    let mut best: Option<(f32, u32)> = None;
    for (k, t) in tris.corners.iter().enumerate() {
        if let Some((t, _, _)) = intersect_triangle(ray, t) {
            if best.is_none_or(|(bt, bk)| t < bt || (t == bt && (k as u32) < bk)) {
                best = Some((t, k as u32));
            }
        }
    }
    best
}

#[test]
fn camera_fans_match_single_rays() {
    for (seed, n, size) in [(1u64, 40usize, 0.4f32), (2, 3000, 0.05), (3, 500, 1.0)] {
        let mut rng = Rng(seed);
        let tris = random_soup(&mut rng, n, size);
        let mut rays = Vec::new();
        for _ in 0..300 {
            let origin = rng.unit() * rng.range(1.5, 4.0);
            let target = rng.vec(-0.8, 0.8);
            let across = (target - origin).cross(rng.unit()).normalize();
            rays.extend(fan(origin, target, across, rng.range(1e-4, 0.01)));
        }
        let hit = check(&soup(tris), &rays, 0.9);
        assert!(
            hit > rays.len() / 10,
            "seed {seed}: {hit} of {} hit",
            rays.len()
        );
    }
}

#[test]
fn the_built_in_cornell_box_from_its_camera() {
    let scene = pathlight_scene::cornell::cornell_box();
    let tris = SceneTriangles::from_scene(&scene);
    // glTF's convention: the camera looks down its -z axis, x to the right, y up.
    let to_world = scene.cameras[0].transform;
    let origin = to_world.transform_point3(Vec3::ZERO);
    let forward = to_world.transform_vector3(-Vec3::Z);
    let right = to_world.transform_vector3(Vec3::X);
    let up = to_world.transform_vector3(Vec3::Y);
    // Rows of a 64x48 image over the camera's view.
    let mut rays = Vec::new();
    for j in 0..48 {
        for i in 0..64 {
            let (x, y) = ((i as f32 + 0.5) / 32.0 - 1.0, 1.0 - (j as f32 + 0.5) / 24.0);
            let d = forward + right * x * 0.5 + up * y * 0.4;
            rays.push(Ray::new(origin, d));
        }
    }
    let hit = check(&tris, &rays, 0.9);
    assert!(
        hit > rays.len() * 3 / 4,
        "{hit} of {} hit the box",
        rays.len()
    );
}

#[test]
fn ties_at_shared_edges_and_vertices_go_to_the_smallest_index() {
    // A flat integer grid seen straight down and obliquely: fans whose rays pass through
    // vertices (shared by up to six triangles) and edges (two) at exactly equal distances.
    let tris = soup(flat_grid(8));
    let mut rays = Vec::new();
    for j in 1..15 {
        for i in 0..2 {
            // Eight parallel rays along -z through x = 0.5 * (8 i + k), y = 0.5 j.
            rays.extend((0..8).map(|k| {
                let o = Vec3::new(0.5 * (8 * i + k) as f32, 0.5 * j as f32, 2.0);
                Ray::new(o, -Vec3::Z)
            }));
            // A fan from one point through the same grid points.
            let o = Vec3::new(4.0, 3.5, 5.0);
            rays.extend((0..8).map(|k| {
                let p = Vec3::new(0.5 * (8 * i + k) as f32, 0.5 * j as f32, 0.0);
                Ray::new(o, p - o)
            }));
        }
    }
    assert_eq!(check(&tris, &rays, 1.0), rays.len());
    let native = NativeBvh::new(&tris);
    let mut ties = 0;
    for ray in &rays {
        let h: Hit = native.intersect(ray).expect("checked above");
        let want = every_triangle(&tris, ray).expect("the BVH found one");
        assert_eq!((h.t, h.triangle), want, "{ray:?}");
        let tied = tris
            .corners
            .iter()
            .filter(|t| intersect_triangle(ray, t).is_some_and(|(t, _, _)| t == h.t))
            .count();
        ties += usize::from(tied > 1);
    }
    assert!(ties > rays.len() / 2, "{ties} of {} rays tie", rays.len());
}

#[test]
fn incoherent_and_ragged_batches_match_single_rays() {
    // Random directions (mixed axis permutations and signs in a packet: traced one by one),
    // rays with zero and non-finite directions, and a batch whose length is not a multiple
    // of eight.
    let mut rng = Rng(7);
    let tris = random_soup(&mut rng, 400, 0.3);
    let mut rays = random_rays(&mut rng, &tris, 1001, 1.5);
    rays[3] = Ray::new(Vec3::ZERO, Vec3::ZERO);
    rays[9] = Ray::new(Vec3::ZERO, Vec3::new(f32::NAN, 1.0, 0.0));
    rays[17] = Ray::segment(Vec3::splat(-2.0), Vec3::ONE, 1.0, 3.0);
    check(&soup(tris), &rays, 0.0);
}
