//! Alpha cut-outs and blending, and normal mapping, checked against values worked out by hand.

mod common;

use common::{config, quad, scene, world};
use glam::{Vec3, Vec4};
use pathlight_accel::Ray;
use pathlight_render::renderer::render;
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
    let film = render(&w, &cfg.render_camera(&w), &cfg);
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
    let film = render(&w, &cfg.render_camera(&w), &cfg);
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
    w.surface(&ray, &hit).ns
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

/// `World` shades each material without textures once and keeps its BSDFs: a hit on such a
/// material must get exactly what `shade_material` and `Bsdf::new` give there, with either
/// microfacet distribution; a textured material must still see its texture; and parameters
/// that are not the material's own must not get its precomputed BSDF.
#[test]
fn precomputed_materials_shade_as_the_material_at_the_hit() {
    use glam::Vec2;
    use pathlight_render::bsdf::{Bsdf, Microfacet};
    use pathlight_render::surface::shade_material;
    use pathlight_scene::material::Volume;

    let materials = vec![
        Material::lambertian("white", Vec3::splat(0.8)),
        // The glTF default: a rough metal.
        Material::default(),
        Material {
            metallic: 0.0,
            roughness: 0.3,
            ior: 1.7,
            specular_color: Vec3::new(1.0, 0.5, 0.2),
            ..Material::lambertian("glossy", Vec3::new(0.2, 0.4, 0.6))
        },
        Material {
            metallic: 0.0,
            roughness: 0.0,
            specular: 1.0,
            transmission: 0.9,
            volume: Some(Volume {
                thickness: 1.0,
                thickness_texture: None,
                attenuation_distance: 2.0,
                attenuation_color: Vec3::new(0.9, 0.5, 0.1),
            }),
            ..Material::lambertian("glass", Vec3::ONE)
        },
        Material {
            base_color_texture: Some(TextureRef::new(0)),
            ..Material::lambertian("textured", Vec3::splat(0.5))
        },
    ];
    let directions = [
        (Vec3::new(0.3, -0.2, 0.93), Vec3::new(-0.5, 0.1, 0.86)),
        (Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.6, 0.0, 0.8)),
        (Vec3::new(0.3, -0.2, 0.93), Vec3::new(0.2, 0.1, -0.97)),
    ];
    // A quad of material `m` (the texture is a constant tint) and a ray that hits it.
    let quad_hit = |m: usize| {
        let mut s = scene(
            vec![quad(m as u32, 1.0, 0.0)],
            materials.clone(),
            None,
            Vec3::new(0.0, 0.0, 3.0),
        );
        s.textures.push(Texture::constant(
            "tint",
            Vec4::new(0.5, 0.25, 1.0, 1.0),
            ColorSpace::Linear,
        ));
        let w = world(s);
        let ray = Ray::new(Vec3::new(0.2, -0.1, 3.0), -Vec3::Z);
        let hit = w.accel.intersect(&ray).expect("the quad is hit");
        (w, ray, hit)
    };
    for (m, mat) in materials.iter().enumerate() {
        let (w, ray, hit) = quad_hit(m);
        for d in [Microfacet::Ggx, Microfacet::Beckmann] {
            let (surface, got) = w.shaded(&ray, &hit, d);
            // The constant texture makes the texture coordinates irrelevant.
            let want = shade_material(&w.scene, mat, [Vec2::ZERO; 2], Vec4::ONE, d);
            assert_eq!(got.params, want.params, "{}", mat.name);
            assert_eq!(
                (got.alpha, got.volume, got.sigma_a),
                (want.alpha, want.volume, want.sigma_a),
                "{}",
                mat.name
            );
            let (cached, fresh) = (
                w.bsdf(surface.material, &got.params),
                Bsdf::new(&got.params),
            );
            for (wo, wi) in directions.map(|(a, b)| (a.normalize(), b.normalize())) {
                assert_eq!(
                    cached.eval_pdf(wo, wi),
                    fresh.eval_pdf(wo, wi),
                    "{}",
                    mat.name
                );
                let u = Vec2::new(0.3, 0.7);
                assert_eq!(cached.sample(wo, 0.4, u), fresh.sample(wo, 0.4, u));
            }
            let other = pathlight_render::bsdf::BsdfParams {
                roughness: 0.55,
                ..got.params
            };
            assert_eq!(w.bsdf(surface.material, &other).params(), &other);
        }
    }
    // The texture is applied: 0.5 x (0.5, 0.25, 1), up to the texture's 8 bits.
    let (w, ray, hit) = quad_hit(4);
    let (_, shading) = w.shaded(&ray, &hit, Microfacet::Ggx);
    let want = Vec3::new(0.25, 0.125, 0.5);
    assert!(
        shading.params.base_color.abs_diff_eq(want, 0.002),
        "{}",
        shading.params.base_color
    );
}
