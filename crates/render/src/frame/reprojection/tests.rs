use super::slot::*;
use super::*;
use crate::frame::gbuffer::GPixel;
use crate::path::Bounce;
use pathlight_core::rng::Rng;
use pathlight_scene::Material;
use std::f32::consts::PI;

fn slot(f0: f32, f90: f32, alpha: f32) -> Slot {
    Slot {
        stats: PixelStats::one(Vec3::ONE, Vec3::ZERO),
        irradiance: Vec3::ONE,
        ..Slot::surface(
            Vec3::ZERO,
            Vec3::Z,
            Vec3::new(0.3, 0.0, 1.0).normalize(),
            Vec3::ONE,
            [alpha, f0, f90],
            0,
        )
    }
}

#[test]
fn packed_fields_read_back_within_their_precision() {
    let mut rng = Rng::new(11, 0);
    for _ in 0..10_000 {
        let v = Vec3::new(
            rng.next_f32() * 2.0 - 1.0,
            rng.next_f32() * 2.0 - 1.0,
            rng.next_f32() * 2.0 - 1.0,
        );
        if v.length() < 1e-3 {
            continue;
        }
        let v = v.normalize();
        let back = from_octahedral(octahedral(v));
        // 16 bits per coordinate: within 1e-4 radians.
        assert!((back - v).length() < 1e-4, "{v} read back as {back}");
        let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
        let s = Slot::surface(Vec3::ONE, v, -v, Vec3::from_array(u), u, 3);
        let (albedo, lobe) = (s.albedo().to_array(), s.lobe());
        for i in 0..3 {
            assert!((albedo[i] - u[i]).abs() <= 1.0 / 131_070.0 + 1e-7);
            assert!((lobe[i] - u[i]).abs() <= 1.0 / 131_070.0 + 1e-7);
        }
        assert!((s.direction() + v).length() < 1e-4);
    }
    // The axes and their opposites exactly; a path that ended keeps no direction.
    for v in [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z] {
        assert_eq!(from_octahedral(octahedral(v)), v);
    }
    let ended = Slot::surface(Vec3::ZERO, Vec3::Z, Vec3::ZERO, Vec3::ONE, [0.5; 3], 0);
    assert_eq!(ended.direction(), Vec3::ZERO);
    assert!(!ended.is_sky() && !ended.is_specular() && !ended.is_carried());
}

#[test]
fn reflection_at_normal_incidence_is_beckmanns_peak() {
    // i = o = n: h = n, D = 1 / (pi alpha^2), Lambda(n) = 0 so G = 1, F = f0.
    for (alpha, f0) in [(0.1, 0.04), (0.5, 1.0), (0.02, 0.5)] {
        let f = reflection(Vec3::Z, Vec3::Z, Vec3::Z, alpha, f0, 1.0);
        let expected = f0 / (4.0 * PI * alpha * alpha);
        assert!((f - expected).abs() < 1e-4 * expected, "{f} vs {expected}");
    }
}

#[test]
fn reflection_is_reciprocal_and_conserves_energy() {
    let mut rng = Rng::new(3, 0);
    let n = Vec3::Z;
    for _ in 0..100 {
        let mut dir = || {
            let (u, v) = (rng.next_f32(), rng.next_f32());
            let r = (1.0 - u * u).max(0.0).sqrt();
            Vec3::new(r * (2.0 * PI * v).cos(), r * (2.0 * PI * v).sin(), u)
        };
        let (i, o) = (dir(), dir());
        let (a, b) = (
            reflection(i, o, n, 0.3, 0.2, 1.0),
            reflection(o, i, n, 0.3, 0.2, 1.0),
        );
        assert!((a - b).abs() <= 1e-5 * a.max(1.0), "{a} vs {b}");
    }
    // Directional albedo at normal incidence of a perfect reflector (F = 1), by uniform
    // hemisphere sampling: at most 1, and close to it for a smooth surface (Smith's
    // masking loses a few percent at grazing angles only).
    let mut rng = Rng::new(5, 1);
    for (alpha, low) in [(0.2, 0.95), (0.5, 0.85)] {
        let count = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..count {
            let (u, v) = (rng.next_f32(), rng.next_f32());
            let r = (1.0 - u * u).max(0.0).sqrt();
            let o = Vec3::new(r * (2.0 * PI * v).cos(), r * (2.0 * PI * v).sin(), u);
            sum += f64::from(reflection(Vec3::Z, o, n, alpha, 1.0, 1.0) * u * 2.0 * PI);
        }
        let albedo = sum / count as f64;
        assert!(
            albedo > low && albedo < 1.01,
            "alpha {alpha}: albedo {albedo}"
        );
    }
}

#[test]
fn the_view_error_vanishes_without_a_move_a_lobe_or_a_surface() {
    let glossy = slot(0.04, 1.0, 0.1);
    let (a, b) = (Vec3::new(0.0, 0.0, 3.0), Vec3::new(1.0, 0.0, 3.0));
    assert_eq!(view_error(&glossy, a, a), 0.0);
    assert!(view_error(&glossy, a, b) > 1.0 / 256.0);
    // Lambertian (no specular layer): view independent.
    assert_eq!(view_error(&slot(0.0, 0.0, 0.1), a, b), 0.0);
    let mut sky = glossy;
    sky.set(SKY, true);
    assert_eq!(view_error(&sky, a, b), 0.0);
    // Scales with what arrives along L and the base colour.
    let dim = Slot {
        irradiance: Vec3::splat(0.5),
        ..glossy
    };
    let e = view_error(&glossy, a, b);
    assert!((view_error(&dim, a, b) - 0.5 * e).abs() < 1e-6 * e);
}

#[test]
fn only_smooth_lobes_and_transmission_count_as_specular() {
    let g = |roughness: f32, metallic: f32| GPixel {
        roughness,
        metallic,
        material: 0,
        ..GPixel::default()
    };
    let bounce = Bounce::default();
    let lambert = Material {
        roughness: 0.0,
        specular: 0.0,
        ..Material::default()
    };
    let plastic = Material {
        specular: 1.0,
        ..Material::default()
    };
    let glass = Material {
        transmission: 1.0,
        specular: 1.0,
        roughness: 0.5,
        ..Material::default()
    };
    assert!(!Slot::start(&g(0.0, 0.0), &bounce, Some(&lambert)).is_specular());
    assert!(
        Slot::start(&g(0.0, 1.0), &bounce, Some(&lambert)).is_specular(),
        "a mirror"
    );
    assert!(Slot::start(&g(0.05, 0.0), &bounce, Some(&plastic)).is_specular());
    assert!(!Slot::start(&g(0.2, 0.0), &bounce, Some(&plastic)).is_specular());
    assert!(Slot::start(&g(0.5, 0.0), &bounce, Some(&glass)).is_specular());
}
