//! White furnace tests of the whole path tracer: under a uniform environment of radiance 1,
//! objects that neither absorb nor emit are invisible (every pixel has expected value 1,
//! whatever the geometry and however many bounces the light takes).

mod common;

use common::{ball_and_floor, config, scene, sphere, world};
use glam::Vec3;
use pathlight_render::renderer::render;
use pathlight_scene::{Material, Volume};

/// Renders and returns (mean over the image, its standard error from the pixels' sample
/// variances, largest deviation from 1 of a 4x4-pixel block mean).
fn furnace(
    materials: Vec<Material>,
    meshes: Vec<pathlight_scene::Mesh>,
    spp: u32,
) -> (f32, f32, f32) {
    let world = world(scene(
        meshes,
        materials,
        Some(Vec3::ONE),
        Vec3::new(0.0, 0.5, 4.0),
    ));
    let cfg = config(48, 48, spp);
    let camera = cfg.render_camera(&world);
    let film = render(&world, &camera, &cfg);
    let mean = film
        .pixels
        .iter()
        .map(|p| p.mean.element_sum() / 3.0)
        .sum::<f32>()
        / film.pixels.len() as f32;
    let mut worst = 0.0f32;
    for by in 0..12 {
        for bx in 0..12 {
            let mut s = 0.0;
            for y in 0..4 {
                for x in 0..4 {
                    s += film.pixels[(by * 4 + y) * 48 + bx * 4 + x]
                        .mean
                        .element_sum()
                        / 3.0;
                }
            }
            worst = worst.max((s / 16.0 - 1.0).abs());
        }
    }
    let se = film
        .pixels
        .iter()
        .map(|p| p.variance().element_sum() / 3.0 / p.n as f32)
        .sum::<f32>()
        .sqrt()
        / film.pixels.len() as f32;
    eprintln!("furnace: mean {mean} (standard error {se}), worst block {worst}");
    (mean, se, worst)
}

#[test]
fn white_lambertian_sphere_and_open_box_vanish() {
    // A white sphere above a white quad, and a second quad closing a corner: light bounces
    // between them many times (no Russian roulette while the throughput stays 1).
    let white = Material::lambertian("white", Vec3::ONE);
    let (mean, se, worst) = furnace(vec![white], ball_and_floor(), 256);
    assert!(
        (mean - 1.0).abs() < 4.0 * se + 1e-4,
        "mean {mean}, standard error {se}"
    );
    assert!(worst < 0.02, "worst block {worst}");
}

#[test]
fn smooth_glass_sphere_vanishes() {
    // Reflection + refraction of a lossless dielectric sum to 1 (the 1/eta^2 radiance scaling
    // cancels on the way in and out), including total internal reflection.
    let glass = Material {
        name: "glass".into(),
        base_color: glam::Vec4::ONE,
        metallic: 0.0,
        roughness: 0.0,
        transmission: 1.0,
        volume: Some(Volume {
            thickness: 1.0,
            thickness_texture: None,
            attenuation_distance: f32::INFINITY,
            attenuation_color: Vec3::ONE,
        }),
        double_sided: true,
        ..Material::default()
    };
    // Flat shading: with exact geometry every path's weight is exactly 1 (Fresnel reflection
    // and refraction are chosen in proportion to their weights), so the image is 1 to float
    // precision. (Interpolated normals lose ~0.06% here, as in any renderer that uses them.)
    let mut ball = sphere(0, 4);
    ball.normals = None;
    let (mean, _, worst) = furnace(vec![glass], vec![ball], 64);
    assert!((mean - 1.0).abs() < 1e-5, "mean {mean}");
    assert!(worst < 1e-4, "worst block {worst}");
}

#[test]
fn grey_lambertian_sphere_matches_the_geometric_series() {
    // A convex object reflects each ray once: a sphere of albedo a under radiance 1 looks
    // exactly a (no inter-reflection), the background 1.
    let grey = Material::lambertian("grey", Vec3::splat(0.5));
    let world = world(scene(
        vec![sphere(0, 4)],
        vec![grey],
        Some(Vec3::ONE),
        Vec3::new(0.0, 0.0, 4.0),
    ));
    let cfg = config(32, 32, 32);
    let camera = cfg.render_camera(&world);
    let film = render(&world, &camera, &cfg);
    // The centre pixels see the sphere.
    for (x, y) in [(15, 15), (16, 16), (14, 17)] {
        let v = film.pixels[y * 32 + x].mean;
        assert!((v - Vec3::splat(0.5)).abs().max_element() < 0.03, "{v}");
    }
    // A corner sees the environment.
    assert!((film.pixels[0].mean - Vec3::ONE).abs().max_element() < 1e-5);
}
