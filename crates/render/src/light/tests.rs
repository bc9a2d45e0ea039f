//! Tests of light sampling against closed forms: Lambert's polygon irradiance for triangles,
//! texel quadrature for the environment, inverse-square and glTF falloffs for punctual lights.

use std::f32::consts::PI;

use glam::{Mat4, Quat, Vec2, Vec3, Vec4};
use pathlight_core::rng::Rng;
use pathlight_scene::material::uv_transform;
use pathlight_scene::{
    ColorSpace, Environment, Instance, Material, Mesh, PunctualKind, PunctualLight, Scene, Texture,
    TextureRef,
};

use super::{LightSelection, Lights};

pub(crate) fn emissive_material(emissive: Vec3, two_sided: bool) -> Material {
    Material {
        emissive,
        emits_from_back: two_sided,
        ..Material::lambertian("emitter", Vec3::splat(0.5))
    }
}

pub(crate) fn mesh(positions: Vec<Vec3>, indices: Vec<[u32; 3]>, material: u32) -> Mesh {
    Mesh {
        positions,
        indices,
        material,
        ..Mesh::default()
    }
}

/// A blue sky of `w` x `h` texels with a sun of 20,000 in three texels.
pub(crate) fn sunny(w: u32, h: u32) -> Environment {
    let mut env = Environment::constant(Vec3::splat(0.5));
    env.width = w;
    env.height = h;
    env.texels = vec![Vec3::new(0.4, 0.5, 0.7); (w * h) as usize];
    for (x, y) in [(10, 8), (11, 8), (10, 9)] {
        env.texels[(y * w + x) as usize] = Vec3::splat(20_000.0);
    }
    env
}

pub(crate) fn instance(mesh: u32, transform: Mat4) -> Instance {
    Instance {
        mesh,
        transform,
        name: String::new(),
    }
}

/// The front (emitting) normal of a scene triangle, by the normal matrix.
fn front_normal(scene: &Scene, instance: u32, triangle: u32) -> Vec3 {
    let inst = &scene.instances[instance as usize];
    let [a, b, c] = scene.meshes[inst.mesh as usize].triangle(triangle as usize);
    (inst.normal_matrix() * (b - a).cross(c - a)).normalize()
}

fn world_corners(scene: &Scene, instance: u32, triangle: u32) -> [Vec3; 3] {
    let inst = &scene.instances[instance as usize];
    scene.meshes[inst.mesh as usize]
        .triangle(triangle as usize)
        .map(|p| inst.transform.transform_point3(p))
}

/// Lambert's formula: the irradiance at `p` (normal `n`) from a polygon of unit radiance that
/// lies entirely above the tangent plane: (1/2) |sum_i angle_i (n . gamma_i)|.
pub(crate) fn polygon_irradiance(p: Vec3, n: Vec3, corners: &[Vec3]) -> f64 {
    let k = corners.len();
    let mut sum = 0.0f64;
    for i in 0..k {
        let a = (corners[i] - p).as_dvec3().normalize();
        let b = (corners[(i + 1) % k] - p).as_dvec3().normalize();
        let angle = a.dot(b).clamp(-1.0, 1.0).acos();
        sum += angle * a.cross(b).normalize().dot(n.as_dvec3());
    }
    0.5 * sum.abs()
}

/// Barycentrics (u, v) of `q` in triangle `t` and its distance from the triangle's plane.
fn barycentrics(t: [Vec3; 3], q: Vec3) -> (Vec2, f32) {
    let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], q - t[0]);
    let n = e1.cross(e2);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    let det = d11 * d22 - d12 * d12;
    let u = (d22 * d1 - d12 * d2) / det;
    let v = (d11 * d2 - d12 * d1) / det;
    (Vec2::new(u, v), d.dot(n).abs() / n.length())
}

/// The scene's emissive triangle (instance, triangle) that contains `q`.
fn find_triangle(scene: &Scene, q: Vec3) -> Option<(u32, u32, Vec2)> {
    scene.emissive_triangles.iter().find_map(|et| {
        let (b, off_plane) = barycentrics(world_corners(scene, et.instance, et.triangle), q);
        let tol = 1e-4;
        (off_plane < tol && b.x >= -tol && b.y >= -tol && b.x + b.y <= 1.0 + tol).then_some((
            et.instance,
            et.triangle,
            b,
        ))
    })
}

const DOWN: [Vec3; 3] = [
    Vec3::new(-0.5, 0.0, -0.5),
    Vec3::new(0.5, 0.0, -0.5),
    Vec3::new(0.0, 0.0, 0.5),
];
const UP: [Vec3; 3] = [
    Vec3::new(-0.5, 0.0, -0.5),
    Vec3::new(0.0, 0.0, 0.5),
    Vec3::new(0.5, 0.0, -0.5),
];

/// Emitters above the plane y = 0: one-sided triangles facing down (toward the origin) and up
/// (away), a two-sided quad, and mirrored instances of both one-sided meshes (a mirror flips
/// the world winding but not the front side); plus a non-emitter.
fn triangle_scene() -> Scene {
    let mirror = Vec3::new(-1.0, 1.0, 1.0);
    let mut scene = Scene {
        meshes: vec![
            mesh(DOWN.to_vec(), vec![[0, 1, 2]], 0),
            mesh(UP.to_vec(), vec![[0, 1, 2]], 0),
            mesh(
                vec![
                    Vec3::new(-0.5, 0.0, -0.5),
                    Vec3::new(0.5, 0.0, -0.5),
                    Vec3::new(0.5, 0.0, 0.5),
                    Vec3::new(-0.5, 0.0, 0.5),
                ],
                vec![[0, 1, 2], [0, 2, 3]],
                1,
            ),
            mesh(
                vec![Vec3::new(-3.0, -1.0, -3.0), Vec3::X, Vec3::Z],
                vec![[0, 1, 2]],
                2,
            ),
        ],
        instances: vec![
            // 0: faces the origin.
            instance(0, Mat4::from_translation(Vec3::new(0.0, 1.0, 0.0))),
            // 1: faces away.
            instance(1, Mat4::from_translation(Vec3::new(0.3, 1.5, 0.2))),
            // 2: two-sided, mirrored and turned.
            instance(
                2,
                Mat4::from_scale_rotation_translation(
                    mirror,
                    Quat::from_rotation_y(0.3),
                    Vec3::new(1.0, 2.0, 0.5),
                ),
            ),
            // 3: mirrored "up": its world winding faces the origin, its front does not.
            instance(
                1,
                Mat4::from_scale_rotation_translation(
                    mirror,
                    Quat::IDENTITY,
                    Vec3::new(-1.0, 2.0, 0.0),
                ),
            ),
            // 4: mirrored and tilted "down": its front faces the origin.
            instance(
                0,
                Mat4::from_scale_rotation_translation(
                    mirror,
                    Quat::from_rotation_x(0.4),
                    Vec3::new(-0.5, 2.5, 1.0),
                ),
            ),
            // 5: not a light.
            instance(3, Mat4::IDENTITY),
        ],
        materials: vec![
            emissive_material(Vec3::new(1.0, 0.5, 0.25), false),
            emissive_material(Vec3::new(0.3, 0.6, 0.9), true),
            Material::lambertian("grey", Vec3::splat(0.5)),
        ],
        ..Scene::default()
    };
    scene.collect_emissive_triangles();
    assert_eq!(scene.emissive_triangles.len(), 6);
    scene
}

/// Lambert's reference for the unoccluded integral of Le cos over the sphere at `p`.
fn reference_irradiance(scene: &Scene, p: Vec3, n: Vec3) -> Vec3 {
    let mut e = Vec3::ZERO;
    for et in &scene.emissive_triangles {
        let corners = world_corners(scene, et.instance, et.triangle);
        let front = front_normal(scene, et.instance, et.triangle);
        if !et.two_sided && front.dot(p - corners[0]) <= 0.0 {
            continue;
        }
        let mat = &scene.materials
            [scene.meshes[scene.instances[et.instance as usize].mesh as usize].material as usize];
        e += mat.emissive * polygon_irradiance(p, n, &corners) as f32;
    }
    e
}

/// Mean and standard error of `f` over `n` samples of the sampler's three numbers.
fn estimate(n: usize, seed: u64, mut f: impl FnMut(f32, Vec2) -> Vec3) -> (Vec3, Vec3) {
    let mut rng = Rng::new(seed, 17);
    let (mut sum, mut sum2) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    for _ in 0..n {
        let u_select = rng.next_f32();
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        let v = f(u_select, u).as_dvec3();
        sum += v;
        sum2 += v * v;
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(glam::DVec3::ZERO);
    (mean.as_vec3(), (var / n as f64).sqrt().as_vec3())
}

fn assert_close(estimate: Vec3, stderr: Vec3, reference: Vec3, what: &str) {
    for c in 0..3 {
        let tol = 4.5 * stderr[c] + 1e-4 * reference[c].abs() + 1e-6;
        assert!(
            (estimate[c] - reference[c]).abs() <= tol,
            "{what}: channel {c}: {estimate} vs {reference} (stderr {stderr})"
        );
    }
}

#[test]
fn triangle_light_sampling_matches_lambert_irradiance() {
    let scene = triangle_scene();
    for selection in [LightSelection::Power, LightSelection::Uniform] {
        let lights = Lights::new(&scene, selection);
        assert_eq!(lights.len(), 6);
        for (p, n) in [
            (Vec3::ZERO, Vec3::Y),
            (
                Vec3::new(0.3, -0.2, 0.1),
                Vec3::new(0.2, 1.0, -0.1).normalize(),
            ),
        ] {
            let reference = reference_irradiance(&scene, p, n);
            let mut checked = 0;
            let (mean, stderr) = estimate(200_000, 3, |u_select, u| {
                let Some(s) = lights.sample(p, u_select, u) else {
                    return Vec3::ZERO;
                };
                assert!(!s.delta && s.pdf > 0.0 && s.distance.is_finite());
                assert!((s.wi.length() - 1.0).abs() < 1e-5);
                if checked < 3000 {
                    checked += 1;
                    let q = p + s.wi * s.distance;
                    let (inst, tri, bary) = find_triangle(&scene, q).expect("on a light");
                    let front = front_normal(&scene, inst, tri);
                    let et = scene
                        .emissive_triangles
                        .iter()
                        .find(|e| (e.instance, e.triangle) == (inst, tri))
                        .unwrap();
                    assert!(et.two_sided || front.dot(-s.wi) > 0.0, "behind {inst}");
                    let pdf = lights.pdf_triangle(p, inst, tri, q);
                    assert!((pdf / s.pdf - 1.0).abs() < 1e-3, "{pdf} vs {}", s.pdf);
                    let le = lights.emitted(&scene, inst, tri, bary, -s.wi);
                    assert!((le - s.radiance).abs().max_element() < 1e-5);
                }
                s.radiance * n.dot(s.wi).max(0.0) / s.pdf
            });
            assert_close(mean, stderr, reference, &format!("{selection:?} at {p}"));
        }
    }
}

#[test]
fn one_sided_emitters_are_dark_from_behind() {
    let scene = triangle_scene();
    let lights = Lights::new(&scene, LightSelection::Power);
    let down = Vec3::NEG_Y;
    let bary = Vec2::new(0.2, 0.3);
    let one = Vec3::new(1.0, 0.5, 0.25);
    let two = Vec3::new(0.3, 0.6, 0.9);
    // (instance, front direction): 0 and 4 face down, 1 and 3 (mirrored) face up.
    for (inst, front) in [(0, down), (1, Vec3::Y), (3, Vec3::Y), (4, down)] {
        let wo = (front + Vec3::new(0.1, 0.0, 0.2)).normalize();
        assert_eq!(lights.emitted(&scene, inst, 0, bary, wo), one, "{inst}");
        assert_eq!(
            lights.emitted(&scene, inst, 0, bary, -wo),
            Vec3::ZERO,
            "{inst}"
        );
        // From a point behind, nothing can be sampled or has density.
        let corners = world_corners(&scene, inst, 0);
        let q = (corners[0] + corners[1] + corners[2]) / 3.0;
        assert_eq!(lights.pdf_triangle(q - front, inst, 0, q), 0.0);
        assert!(lights.pdf_triangle(q + front, inst, 0, q) > 0.0);
        assert!(lights.triangle_light(inst, 0).is_some());
    }
    for tri in 0..2 {
        assert_eq!(lights.emitted(&scene, 2, tri, bary, Vec3::Y), two);
        assert_eq!(lights.emitted(&scene, 2, tri, bary, down), two);
    }
    assert_eq!(lights.emitted(&scene, 5, 0, bary, Vec3::Y), Vec3::ZERO);
    assert_eq!(lights.pdf_triangle(Vec3::ZERO, 5, 0, Vec3::X), 0.0);
    assert_eq!(lights.triangle_light(5, 0), None);
    assert_eq!(lights.triangle_light(99, 0), None);
    // Only the facing lights are ever sampled from the origin's side... and from above all the
    // emitters (y = 10), only the two-sided quad and the up-facing ones.
    let mut rng = Rng::new(9, 9);
    for _ in 0..5000 {
        let p = Vec3::new(0.0, 10.0, 0.0);
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        if let Some(s) = lights.sample(p, rng.next_f32(), u) {
            let (inst, _, _) = find_triangle(&scene, p + s.wi * s.distance).unwrap();
            assert!(matches!(inst, 1..=3), "{inst}");
        }
    }
}

#[test]
fn textured_emission_uses_the_texture_at_the_point() {
    // A 2x2 sRGB texture read through uv1 with a uv transform.
    let texels = vec![
        [255, 0, 0, 255],
        [0, 255, 0, 255],
        [0, 0, 255, 255],
        [255, 255, 255, 255],
    ];
    let texture = Texture::new("e", 2, 2, texels, ColorSpace::Srgb);
    let mut tex = TextureRef::new(0);
    tex.texcoord = 1;
    tex.transform = uv_transform(Vec2::new(0.1, 0.05), 0.3, Vec2::new(0.8, 1.2));
    let emissive = Vec3::new(2.0, 1.0, 0.5);
    let mut m = mesh(
        vec![
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(0.0, 0.0, 1.0),
        ],
        vec![[0, 1, 2]],
        0,
    );
    m.uv0 = Some(vec![Vec2::ZERO; 3]);
    let uv1 = [
        Vec2::new(0.1, 0.2),
        Vec2::new(0.9, 0.3),
        Vec2::new(0.4, 0.8),
    ];
    m.uv1 = Some(uv1.to_vec());
    let mut scene = Scene {
        meshes: vec![m],
        instances: vec![instance(0, Mat4::from_translation(Vec3::Y))],
        materials: vec![Material {
            emissive_texture: Some(tex),
            ..emissive_material(emissive, false)
        }],
        textures: vec![texture.clone()],
        ..Scene::default()
    };
    scene.collect_emissive_triangles();
    let lights = Lights::new(&scene, LightSelection::Power);
    let expected = |bary: Vec2| {
        let uv = uv1[0] * (1.0 - bary.x - bary.y) + uv1[1] * bary.x + uv1[2] * bary.y;
        emissive * texture.sample(tex.apply(uv), &tex.sampler).truncate()
    };
    for bary in [Vec2::new(0.2, 0.3), Vec2::new(0.7, 0.1), Vec2::ZERO] {
        let le = lights.emitted(&scene, 0, 0, bary, Vec3::NEG_Y);
        assert_eq!(le, expected(bary));
        assert_eq!(lights.emitted(&scene, 0, 0, bary, Vec3::Y), Vec3::ZERO);
    }
    // Samples carry the texture at their own point.
    let mut rng = Rng::new(4, 4);
    let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
    for _ in 0..2000 {
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        let s = lights.sample(Vec3::ZERO, rng.next_f32(), u).unwrap();
        let (_, _, bary) = find_triangle(&scene, s.wi * s.distance).unwrap();
        assert!((s.radiance - expected(bary)).abs().max_element() < 2e-3);
        lo = lo.min(s.radiance.x);
        hi = hi.max(s.radiance.x);
    }
    assert!(hi - lo > 0.5, "{lo} {hi}");
    // The fallback path (an emissive triangle missing from the list) agrees.
    let mut bare = scene.clone();
    bare.emissive_triangles.clear();
    let none = Lights::new(&bare, LightSelection::Power);
    assert!(none.is_empty());
    assert!(none.sample(Vec3::ZERO, 0.5, Vec2::splat(0.5)).is_none());
    let bary = Vec2::new(0.2, 0.3);
    assert_eq!(none.emitted(&bare, 0, 0, bary, Vec3::NEG_Y), expected(bary));
    assert_eq!(none.emitted(&bare, 0, 0, bary, Vec3::Y), Vec3::ZERO);
    assert_eq!(none.pdf_triangle(Vec3::ZERO, 0, 0, Vec3::Y), 0.0);
}

fn random_environment(w: u32, h: u32, seed: u64) -> Environment {
    let mut rng = Rng::new(seed, 5);
    let texels = (0..w * h)
        .map(|i| {
            if i % 11 == 4 {
                Vec3::ZERO
            } else {
                let s = rng.next_f32().powi(4) * 20.0;
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * s
            }
        })
        .collect();
    Environment {
        name: "random".into(),
        width: w,
        height: h,
        texels,
        rotation: 0.7,
        intensity: 1.5,
    }
}

/// The integral of the environment's radiance over the sphere, texel by texel.
fn environment_integral(env: &Environment) -> Vec3 {
    let (w, h) = (env.width as usize, env.height as usize);
    let mut sum = glam::DVec3::ZERO;
    for y in 0..h {
        let (t0, t1) = (
            PI as f64 * y as f64 / h as f64,
            PI as f64 * (y + 1) as f64 / h as f64,
        );
        let solid_angle = 2.0 * PI as f64 / w as f64 * (t0.cos() - t1.cos());
        for x in 0..w {
            sum += (env.texels[y * w + x] * env.intensity).as_dvec3() * solid_angle;
        }
    }
    sum.as_vec3()
}

fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

#[test]
fn environment_sampling_is_consistent_and_unbiased() {
    let env = random_environment(16, 8, 1);
    let integral = environment_integral(&env);
    // With a point light too, the environment's selection probability is in every pdf.
    let scene = Scene {
        environment: Some(env.clone()),
        lights: vec![PunctualLight {
            name: "p".into(),
            kind: PunctualKind::Point,
            position: Vec3::new(0.0, 5.0, 0.0),
            direction: Vec3::NEG_Y,
            intensity: Vec3::splat(3.0),
            range: None,
        }],
        ..Scene::default()
    };
    let lights = Lights::new(&scene, LightSelection::Power);
    assert_eq!(lights.len(), 2);
    let select = lights.selection_pmf(1);
    // Power: pi r^2 (r = 1 without geometry) times the integral, against 4 pi I.
    let env_power = PI * pathlight_core::color::luminance(integral);
    let expected = env_power / (env_power + 4.0 * PI * 3.0);
    assert!((select - expected).abs() < 1e-4, "{select} vs {expected}");

    let mut env_samples = 0;
    let mut rng = Rng::new(2, 2);
    for _ in 0..20_000 {
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        let Some(s) = lights.sample(Vec3::ONE, rng.next_f32(), u) else {
            continue;
        };
        if s.delta {
            continue;
        }
        env_samples += 1;
        assert_eq!(s.distance, f32::INFINITY);
        assert_eq!(s.pdf, lights.pdf_environment(s.wi));
        assert_eq!(s.radiance, lights.environment_radiance(s.wi));
        assert!(s.radiance.max_element() > 0.0);
    }
    assert!(env_samples > 1000);

    // The density integrates to the selection probability: quadrature over the texels (8 x 8
    // points each, equally spaced in azimuth and in the cosine of the polar angle, so each
    // stands for an equal share of its texel's solid angle)...
    let (w, h, k) = (16usize, 8usize, 8usize);
    let mut total = 0.0f64;
    for y in 0..h {
        let (c0, c1) = (
            (PI * y as f32 / h as f32).cos(),
            (PI * (y + 1) as f32 / h as f32).cos(),
        );
        for j in 0..k {
            let cos_theta = c0 + (c1 - c0) * (j as f32 + 0.5) / k as f32;
            let v = cos_theta.clamp(-1.0, 1.0).acos() / PI;
            let solid_angle = (2.0 * PI / (w * k) as f32) * (c0 - c1) / k as f32;
            for i in 0..w * k {
                let dir = env.uv_to_direction(Vec2::new((i as f32 + 0.5) / (w * k) as f32, v));
                total += (lights.pdf_environment(dir) * solid_angle) as f64;
            }
        }
    }
    assert!(
        (total - select as f64).abs() < 1e-4 * select as f64,
        "{total} against {select}"
    );
    // ... and by Monte Carlo over uniform directions.
    let (mean, stderr) = estimate(400_000, 6, |_, u| {
        Vec3::splat(lights.pdf_environment(uniform_sphere(u)) * 4.0 * PI)
    });
    assert_close(mean, stderr, Vec3::splat(select), "integral of the pdf");

    // Radiance / pdf estimates the integral of the radiance over the sphere.
    let only = Scene {
        environment: Some(env.clone()),
        ..Scene::default()
    };
    let lights = Lights::new(&only, LightSelection::Power);
    assert_eq!(lights.selection_pmf(0), 1.0);
    let (mean, stderr) = estimate(200_000, 8, |u_select, u| {
        lights
            .sample(Vec3::ZERO, u_select, u)
            .map_or(Vec3::ZERO, |s| s.radiance / s.pdf)
    });
    assert_close(mean, stderr, integral, "integral of the radiance");
    // Black texels are never sampled and have zero density.
    let black = env.uv_to_direction(Vec2::new((4.5) / 16.0, 0.5 / 8.0));
    assert_eq!(lights.environment_radiance(black), Vec3::ZERO);
    assert_eq!(lights.pdf_environment(black), 0.0);
}

#[test]
fn constant_environment_is_sampled_uniformly() {
    let scene = Scene {
        environment: Some(Environment::constant(Vec3::new(1.0, 2.0, 3.0))),
        ..Scene::default()
    };
    let lights = Lights::new(&scene, LightSelection::Uniform);
    // 64 rows of density over one texel row: close to uniform away from the poles.
    for dir in [Vec3::X, Vec3::new(0.3, -0.8, 0.52).normalize(), Vec3::Z] {
        let pdf = lights.pdf_environment(dir);
        assert!((pdf * 4.0 * PI - 1.0).abs() < 0.05, "{dir}: {pdf}");
        assert_eq!(lights.environment_radiance(dir), Vec3::new(1.0, 2.0, 3.0));
    }
    let none = Lights::new(&Scene::default(), LightSelection::Power);
    assert!(none.is_empty());
    assert_eq!(none.pdf_environment(Vec3::Y), 0.0);
    assert_eq!(none.environment_radiance(Vec3::Y), Vec3::ZERO);
    assert!(none.sample(Vec3::ZERO, 0.3, Vec2::splat(0.3)).is_none());
}

fn punctual(kind: PunctualKind, position: Vec3, direction: Vec3, intensity: f32) -> PunctualLight {
    PunctualLight {
        name: String::new(),
        kind,
        position,
        direction,
        intensity: Vec3::new(1.0, 2.0, 3.0) * intensity,
        range: None,
    }
}

fn only_light(light: PunctualLight) -> Lights {
    let scene = Scene {
        lights: vec![light],
        ..Scene::default()
    };
    Lights::new(&scene, LightSelection::Power)
}

#[test]
fn point_light_follows_the_inverse_square_law() {
    let mut light = punctual(
        PunctualKind::Point,
        Vec3::new(0.0, 3.0, 0.0),
        Vec3::NEG_Y,
        10.0,
    );
    let intensity = light.intensity;
    let lights = only_light(light.clone());
    let s = lights.sample(Vec3::ZERO, 0.7, Vec2::splat(0.2)).unwrap();
    assert!(s.delta);
    assert_eq!(s.pdf, 1.0);
    assert!((s.wi - Vec3::Y).length() < 1e-6);
    assert!((s.distance - 3.0).abs() < 1e-6);
    assert!((s.radiance - intensity / 9.0).length() < 1e-5);
    // Irradiance on a surface tilted 60 degrees away: I cos / d^2.
    let n = Vec3::new(60f32.to_radians().sin(), 60f32.to_radians().cos(), 0.0);
    let e = s.radiance * n.dot(s.wi) / s.pdf;
    assert!((e - intensity * 0.5 / 9.0).length() < 1e-5);
    // glTF's range window.
    light.range = Some(6.0);
    let s = only_light(light.clone())
        .sample(Vec3::ZERO, 0.1, Vec2::ZERO)
        .unwrap();
    let window = (1.0f32 - 0.5f32.powi(4)).powi(2);
    assert!((s.radiance - intensity * window / 9.0).length() < 1e-5);
    light.range = Some(2.9);
    assert!(only_light(light)
        .sample(Vec3::ZERO, 0.1, Vec2::ZERO)
        .is_none());
}

#[test]
fn spot_light_falls_off_between_its_cones() {
    let (inner, outer) = (0.2f32, 0.4f32);
    let kind = PunctualKind::Spot {
        inner_cone: inner,
        outer_cone: outer,
    };
    let lights = only_light(punctual(kind, Vec3::new(0.0, 2.0, 0.0), Vec3::NEG_Y, 5.0));
    let intensity = Vec3::new(1.0, 2.0, 3.0) * 5.0;
    // A point on the ground seen from the spot at `angle` off its axis.
    let at = |angle: f32| {
        let p = Vec3::new(2.0 * angle.tan(), 0.0, 0.0);
        let d2 = (Vec3::new(0.0, 2.0, 0.0) - p).length_squared();
        (p, d2)
    };
    let falloff = |angle: f32| {
        let (p, d2) = at(angle);
        lights
            .sample(p, 0.5, Vec2::ZERO)
            .map_or(0.0, |s| (s.radiance * d2 / intensity).x)
    };
    assert!((falloff(0.0) - 1.0).abs() < 1e-5);
    assert!((falloff(inner - 1e-3) - 1.0).abs() < 1e-5);
    assert!((falloff(inner) - 1.0).abs() < 1e-3);
    let mid = 0.3f32;
    let expected = ((mid.cos() - outer.cos()) / (inner.cos() - outer.cos())).powi(2);
    assert!((falloff(mid) - expected).abs() < 1e-4, "{}", falloff(mid));
    assert!(falloff(outer - 1e-2) > 0.0 && falloff(outer - 1e-2) < 0.01);
    assert!(falloff(outer) < 1e-4);
    assert_eq!(falloff(outer + 1e-3), 0.0);
    let (p, _) = at(outer + 1e-3);
    assert!(lights.sample(p, 0.5, Vec2::ZERO).is_none());
}

#[test]
fn directional_light_gives_its_illuminance() {
    let dir = Vec3::new(1.0, -2.0, 0.5).normalize();
    let lights = only_light(punctual(PunctualKind::Directional, Vec3::ZERO, dir, 3.0));
    let s = lights
        .sample(Vec3::new(5.0, 1.0, -2.0), 0.9, Vec2::ONE)
        .unwrap();
    assert!(s.delta);
    assert_eq!(s.pdf, 1.0);
    assert_eq!(s.distance, f32::INFINITY);
    assert!((s.wi + dir).length() < 1e-6);
    assert_eq!(s.radiance, Vec3::new(3.0, 6.0, 9.0));
}

#[test]
fn selection_follows_power() {
    let (inner, outer) = (0.3f32, 0.6f32);
    // A unit cube of geometry: bounding-sphere radius sqrt(3) / 2.
    let cube = mesh(
        vec![Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::ONE],
        vec![[0, 1, 2]],
        0,
    );
    let mut scene = Scene {
        meshes: vec![cube],
        instances: vec![instance(0, Mat4::IDENTITY)],
        materials: vec![emissive_material(Vec3::splat(2.0), false)],
        lights: vec![
            punctual(PunctualKind::Point, Vec3::ZERO, Vec3::Y, 1.0),
            punctual(
                PunctualKind::Spot {
                    inner_cone: inner,
                    outer_cone: outer,
                },
                Vec3::ZERO,
                Vec3::Y,
                1.0,
            ),
            punctual(PunctualKind::Directional, Vec3::ZERO, Vec3::Y, 1.0),
            punctual(PunctualKind::Point, Vec3::ZERO, Vec3::Y, 0.0),
        ],
        ..Scene::default()
    };
    scene.collect_emissive_triangles();
    let lum = pathlight_core::color::luminance(Vec3::new(1.0, 2.0, 3.0));
    let r2 = 0.75f32;
    let powers = [
        pathlight_core::color::luminance(scene.emissive_triangles[0].power),
        4.0 * PI * lum,
        2.0 * PI * lum * (1.0 - 0.5 * (inner.cos() + outer.cos())),
        PI * r2 * lum,
        0.0,
    ];
    let total: f32 = powers.iter().sum();
    let lights = Lights::new(&scene, LightSelection::Power);
    assert_eq!(lights.len(), 5);
    for (i, p) in powers.iter().enumerate() {
        assert!((lights.selection_pmf(i) - p / total).abs() < 1e-5, "{i}");
    }
    let uniform = Lights::new(&scene, LightSelection::Uniform);
    for i in 0..4 {
        assert_eq!(uniform.selection_pmf(i), 0.25);
    }
    assert_eq!(uniform.selection_pmf(4), 0.0);
    // The punctual pdf is the selection probability.
    let mut rng = Rng::new(3, 3);
    for _ in 0..1000 {
        let p = Vec3::new(0.5, 3.0, 0.2);
        if let Some(s) = lights.sample(p, rng.next_f32(), Vec2::splat(0.3)) {
            if s.delta {
                assert!(powers[1..]
                    .iter()
                    .any(|&w| (s.pdf - w / total).abs() < 1e-6));
            }
        }
    }
}

#[test]
fn textures_are_cloned_once_per_texture() {
    let texture = Texture::constant("c", Vec4::ONE, ColorSpace::Srgb);
    let mut m = mesh(DOWN.to_vec(), vec![[0, 1, 2]], 0);
    m.uv0 = Some(vec![Vec2::ZERO; 3]);
    let mut scene = Scene {
        meshes: vec![m],
        instances: (0..3)
            .map(|i| instance(0, Mat4::from_translation(Vec3::Y * (i + 1) as f32)))
            .collect(),
        materials: vec![Material {
            emissive_texture: Some(TextureRef::new(0)),
            ..emissive_material(Vec3::ONE, false)
        }],
        textures: vec![texture],
        ..Scene::default()
    };
    scene.collect_emissive_triangles();
    let lights = Lights::new(&scene, LightSelection::Power);
    assert_eq!(lights.textures.len(), 1);
    assert_eq!(lights.emitters.len(), 1);
    assert_eq!(lights.uvs.len(), 3);
    assert_eq!(lights.len(), 3);
}

#[test]
fn cornell_box_light_shines_down_into_the_box() {
    let scene = pathlight_scene::cornell::cornell_box();
    let lights = Lights::new(&scene, LightSelection::Power);
    assert_eq!(lights.len(), 2);
    let (p, n) = (Vec3::new(0.1, 0.0, 0.2), Vec3::Y);
    let reference = reference_irradiance(&scene, p, n);
    assert!(reference.max_element() > 0.0);
    let (mean, stderr) = estimate(50_000, 12, |u_select, u| {
        lights
            .sample(p, u_select, u)
            .map_or(Vec3::ZERO, |s| s.radiance * n.dot(s.wi).max(0.0) / s.pdf)
    });
    assert_close(mean, stderr, reference, "Cornell box floor");
    // Above the ceiling light, nothing.
    assert!(lights
        .sample(Vec3::new(0.0, 3.0, 0.0), 0.5, Vec2::splat(0.5))
        .is_none());
}

/// Seed 004's split of light sampling: choosing a light, a point on it, and evaluating the
/// point from a shading point give exactly what `sample` gives, and `evaluate` finds the
/// density `sample` reports (pbrt-v4's light sampler test checks its PMF method this way).
#[test]
fn choose_sample_point_and_evaluate_agree_with_sample() {
    let mut scene = triangle_scene();
    scene.lights = vec![
        punctual(
            PunctualKind::Point,
            Vec3::new(0.5, 3.0, 0.0),
            Vec3::NEG_Y,
            2.0,
        ),
        punctual(
            PunctualKind::Spot {
                inner_cone: 0.3,
                outer_cone: 0.6,
            },
            Vec3::new(-0.5, 3.0, 0.5),
            Vec3::new(0.2, -1.0, 0.1),
            5.0,
        ),
        punctual(
            PunctualKind::Directional,
            Vec3::ZERO,
            Vec3::new(0.3, -1.0, 0.2),
            0.5,
        ),
    ];
    scene.environment = Some(random_environment(16, 8, 3));
    let mut kinds = [0usize; 3];
    for selection in [LightSelection::Power, LightSelection::Uniform] {
        let lights = Lights::new(&scene, selection);
        assert_eq!(lights.len(), 6 + 3 + 1);
        let mut rng = Rng::new(11, 0);
        for _ in 0..20_000 {
            let p = Vec3::new(rng.next_f32() - 0.5, -0.2, rng.next_f32() - 0.5);
            let (u_select, u) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
            let (index, pmf) = lights.choose(u_select).unwrap();
            assert_eq!(pmf, lights.selection_pmf(index));
            let point = lights.sample_point(index, u);
            let split = point.and_then(|point| lights.evaluate(p, &point));
            let whole = lights.sample(p, u_select, u);
            assert_eq!(split, whole, "light {index}");
            if let Some(s) = whole {
                kinds[if index < 6 {
                    0
                } else if index < 9 {
                    1
                } else {
                    2
                }] += 1;
                if !s.delta && index < 6 {
                    // The density `evaluate` reports for the point is the one `pdf_triangle` finds.
                    let et = &scene.emissive_triangles[index];
                    let q = p + s.wi * s.distance;
                    let pdf = lights.pdf_triangle(p, et.instance, et.triangle, q);
                    assert!((pdf - s.pdf).abs() <= 1e-3 * s.pdf, "{pdf} vs {}", s.pdf);
                }
                if index == 9 {
                    assert_eq!(s.pdf, lights.pdf_environment(s.wi));
                }
                // The point's own density over the solid-angle one is the geometry term:
                // cos_light / d^2 on triangles, 1 elsewhere.
                let g = lights.point_pdf(&point.unwrap()) / s.pdf;
                let expected = if index < 6 {
                    let et = &scene.emissive_triangles[index];
                    front_normal(&scene, et.instance, et.triangle)
                        .dot(s.wi)
                        .abs()
                        / (s.distance * s.distance)
                } else {
                    1.0
                };
                assert!((g - expected).abs() <= 1e-4 * expected, "{g} vs {expected}");
            }
        }
    }
    assert!(kinds.iter().all(|&k| k > 1000), "{kinds:?}");
    // Indices beyond the lights are refused, not a panic.
    let lights = Lights::new(&scene, LightSelection::Power);
    assert!(lights.sample_point(10, Vec2::splat(0.5)).is_none());
    let beyond = super::LightPoint {
        light: 10,
        ..Default::default()
    };
    assert!(lights.evaluate(Vec3::ZERO, &beyond).is_none());
}

/// What a white Lambertian surface lit directly can reflect: a uniform sky of luminance L gives
/// an irradiance of at most 4 pi L over the whole sphere (pi L over a hemisphere), so the bound
/// is 4 L; an emissive triangle adds its own luminance; a point light has none.
#[test]
fn the_reflected_bound_is_the_environments_irradiance_over_pi_and_the_brightest_emitter() {
    let sky = Vec3::new(1.0, 2.0, 3.0);
    let l = pathlight_core::color::luminance(sky);
    let scene = Scene {
        environment: Some(Environment::constant(sky)),
        ..Scene::default()
    };
    let bound = Lights::new(&scene, LightSelection::Power).reflected_bound();
    assert!(
        (bound - 4.0 * l).abs() < 1e-3 * l,
        "{bound} against {}",
        4.0 * l
    );
    let emission = Vec3::new(5.0, 4.0, 2.0);
    let mut lit = Scene {
        materials: vec![emissive_material(emission, false)],
        meshes: vec![mesh(DOWN.to_vec(), vec![[0, 1, 2]], 0)],
        instances: vec![instance(0, Mat4::IDENTITY)],
        ..scene
    };
    lit.collect_emissive_triangles();
    let bound = Lights::new(&lit, LightSelection::Power).reflected_bound();
    let want = 4.0 * l + pathlight_core::color::luminance(emission);
    assert!((bound - want).abs() < 1e-3 * want, "{bound} against {want}");
    let point = only_light(punctual(PunctualKind::Point, Vec3::Y, Vec3::NEG_Y, 1.0));
    assert_eq!(point.reflected_bound(), f32::INFINITY);
    assert_eq!(
        Lights::new(&Scene::default(), LightSelection::Power).reflected_bound(),
        0.0
    );
}
