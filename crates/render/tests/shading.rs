//! Alpha cut-outs and blending, and normal mapping, checked against values worked out by hand.

mod common;

use common::{config, quad, scene, world};
use glam::{Vec3, Vec4};
use pathlight_accel::Ray;
use pathlight_render::renderer::render;
use pathlight_render::surface::Surface;
use pathlight_scene::{
    AlphaMode, ColorSpace, Material, PunctualKind, PunctualLight, Texture, TextureRef,
};

fn black(alpha: f32, mode: AlphaMode) -> Material {
    Material {
        base_color: Vec4::new(0.0, 0.0, 0.0, alpha),
        alpha_mode: mode,
        ..Material::lambertian("black", Vec3::ZERO)
    }
}

/// The mean of the centre 8x8 pixels of a 16x16 render of a black quad (with the given
/// alpha) filling the view in front of a uniform white environment.
fn seen_through(material: Material) -> f32 {
    let w = world(scene(
        vec![quad(0, 5.0, 0.0)],
        vec![material],
        Some(Vec3::ONE),
        Vec3::new(0.0, 0.0, 3.0),
    ));
    let cfg = config(16, 16, 256);
    let film = render(&w, &w.camera(&cfg), &cfg);
    let mut s = 0.0;
    for y in 4..12 {
        for x in 4..12 {
            s += film.pixels[y * 16 + x].mean.x;
        }
    }
    s / 64.0
}

#[test]
fn alpha_mask_cuts_below_the_cutoff_only() {
    assert_eq!(
        seen_through(black(0.3, AlphaMode::Mask { cutoff: 0.5 })),
        1.0
    );
    assert_eq!(
        seen_through(black(0.7, AlphaMode::Mask { cutoff: 0.5 })),
        0.0
    );
    assert_eq!(seen_through(black(0.3, AlphaMode::Opaque)), 0.0);
}

#[test]
fn alpha_blend_is_coverage() {
    // 64 pixels x 256 samples, each sees the sky with probability 0.75: standard error 0.0027.
    let v = seen_through(black(0.25, AlphaMode::Blend));
    assert!((v - 0.75).abs() < 0.015, "{v}");
}

#[test]
fn blended_occluders_let_one_minus_alpha_through_shadow_rays() {
    // A white Lambertian floor (z = 0) under a point light at height 2 of intensity 4 pi, so
    // that the floor below it has radiance I / d^2 / pi * albedo = 1. A black blended quad of
    // alpha 0.4 at height 1 lies between: the camera (above it) sees the floor through it
    // with probability 0.6, and the floor receives 0.6 of the light: expected 0.36.
    let mut floor = quad(0, 0.5, 0.0);
    floor.material = 0;
    let blocker = quad(1, 3.0, 1.0);
    let mut s = scene(
        vec![floor, blocker],
        vec![
            Material::lambertian("white", Vec3::ONE),
            black(0.4, AlphaMode::Blend),
        ],
        None,
        Vec3::new(0.0, 0.0, 3.0),
    );
    s.lights.push(PunctualLight {
        name: "bulb".into(),
        kind: PunctualKind::Point,
        position: Vec3::new(0.0, 0.0, 2.0),
        direction: Vec3::NEG_Z,
        intensity: Vec3::splat(4.0 * std::f32::consts::PI),
        range: None,
    });
    let w = world(s);
    let mut cfg = config(16, 16, 256);
    cfg.max_bounces = Some(1);
    cfg.camera.fov_y = Some(2.0);
    let film = render(&w, &w.camera(&cfg), &cfg);
    let centre = film.pixels[8 * 16 + 8].mean.x;
    assert!((centre - 0.36).abs() < 0.03, "{centre}");
}

/// The shading normal at the centre of a +Z quad whose normal map holds `n` (tangent space).
fn mapped_normal(n: Vec3, scale: f32) -> Vec3 {
    let texture = Texture::constant("n", ((n + Vec3::ONE) * 0.5).extend(1.0), ColorSpace::Linear);
    let mut s = scene(
        vec![quad(0, 1.0, 0.0)],
        vec![Material {
            normal_texture: Some(TextureRef::new(0)),
            normal_scale: scale,
            ..Material::lambertian("mapped", Vec3::ONE)
        }],
        None,
        Vec3::new(0.0, 0.0, 3.0),
    );
    s.textures.push(texture);
    let w = world(s);
    let ray = Ray::new(Vec3::new(0.1, 0.2, 2.0), Vec3::NEG_Z);
    let hit = w.accel.intersect(&ray).unwrap();
    Surface::new(&w, &ray, &hit).ns
}

#[test]
fn normal_maps_tilt_along_tangent_and_bitangent() {
    let (s, c) = 30f32.to_radians().sin_cos();
    // Texture +X follows the tangent (+X), texture +Y the bitangent N x T * w = +Y (glTF).
    let n = mapped_normal(Vec3::new(s, 0.0, c), 1.0);
    assert!((n - Vec3::new(s, 0.0, c)).length() < 0.01, "{n}");
    let n = mapped_normal(Vec3::new(0.0, s, c), 1.0);
    assert!((n - Vec3::new(0.0, s, c)).length() < 0.01, "{n}");
    // normal_scale 0 leaves the interpolated normal.
    let n = mapped_normal(Vec3::new(s, 0.0, c), 0.0);
    assert!((n - Vec3::Z).length() < 1e-5, "{n}");
}
