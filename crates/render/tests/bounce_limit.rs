//! With a bounce limit, the last scattering vertex gathers light by next event estimation alone
//! (full weight, no continuation ray: see `path.rs`). These tests check that this estimator is
//! unbiased against analytic values: a convex object under a uniform environment, and a
//! Lambertian floor under a square area light (Lambert's polygon formula).

mod common;

use common::{config, quad, scene, sphere, world};
use glam::Vec3;
use pathlight_render::renderer::render;
use pathlight_scene::Material;

/// A grey sphere under radiance 1 reflects each ray once: it looks exactly its albedo, with
/// one bounce allowed or two.
#[test]
fn convex_object_under_uniform_light_with_a_bounce_limit() {
    let world = world(scene(
        vec![sphere(0, 4)],
        vec![Material::lambertian("grey", Vec3::splat(0.5))],
        Some(Vec3::ONE),
        Vec3::new(0.0, 0.0, 4.0),
    ));
    for bounces in [1, 2] {
        let mut cfg = config(32, 32, 256);
        cfg.max_bounces = Some(bounces);
        let film = render(&world, &cfg.render_camera(&world), &cfg);
        for (x, y) in [(15, 15), (16, 16), (14, 17)] {
            let v = film.pixels[y * 32 + x].mean;
            assert!(
                (v - Vec3::splat(0.5)).abs().max_element() < 0.01,
                "{bounces} bounces: {v}"
            );
        }
    }
}

/// Irradiance at `p` with normal `n` from a polygon of uniform radiance `l` (Lambert 1760:
/// E = l/2 * sum over edges of the angle the edge subtends times the cosine of its plane with
/// `n`).
fn polygon_irradiance(p: Vec3, n: Vec3, corners: &[Vec3], l: f32) -> f32 {
    let mut sum = 0.0;
    for i in 0..corners.len() {
        let a = (corners[i] - p).normalize();
        let b = (corners[(i + 1) % corners.len()] - p).normalize();
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        sum += theta * n.dot(a.cross(b).normalize());
    }
    0.5 * l * sum.abs()
}

#[test]
fn lambertian_floor_under_a_square_light_with_a_bounce_limit() {
    let albedo = 0.5;
    let radiance = 3.0;
    let (half, height) = (0.5, 1.0);
    let floor = quad(0, 4.0, 0.0);
    let light = quad(1, half, height);
    let emitter = Material {
        emissive: Vec3::splat(radiance),
        double_sided: true,
        emits_from_back: true,
        base_color: glam::Vec4::new(0.0, 0.0, 0.0, 1.0),
        ..Material::lambertian("light", Vec3::ZERO)
    };
    // The camera between the light and the floor, looking straight down at the floor's
    // centre through a narrow field of view.
    let mut s = scene(
        vec![floor, light],
        vec![Material::lambertian("floor", Vec3::splat(albedo)), emitter],
        None,
        Vec3::new(0.0, 0.0, 0.5),
    );
    s.cameras[0] = pathlight_scene::Camera::look_at(
        "down",
        Vec3::new(0.0, 0.0, 0.5),
        Vec3::ZERO,
        Vec3::Y,
        2.0,
    );
    s.collect_emissive_triangles();
    let w = world(s);
    let corners = [
        Vec3::new(-half, -half, height),
        Vec3::new(half, -half, height),
        Vec3::new(half, half, height),
        Vec3::new(-half, half, height),
    ];
    let e = polygon_irradiance(Vec3::ZERO, Vec3::Z, &corners, radiance);
    let want = albedo * e / std::f32::consts::PI;
    for bounces in [1, 2] {
        let mut cfg = config(8, 8, 1024);
        cfg.max_bounces = Some(bounces);
        let film = render(&w, &cfg.render_camera(&w), &cfg);
        let mean = film.pixels.iter().map(|p| p.mean.x).sum::<f32>() / 64.0;
        assert!(
            (mean - want).abs() < 0.01 * want,
            "{bounces} bounces: {mean}, analytic {want}"
        );
    }
}
