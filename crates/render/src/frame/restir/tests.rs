//! ReSTIR's reservoirs against closed forms: RIS's mean on a discrete sum and on Lambert's
//! polygon irradiance, the survivor's distribution after merging (chi-squared), and reuse
//! that never crosses a depth edge.

use glam::{Mat4, Vec2, Vec3};
use pathlight_core::rng::Rng;
use pathlight_scene::Scene;

use super::*;
use crate::bsdf::{Bsdf, BsdfParams};
use crate::config::Config;
use crate::light::tests::{emissive_material, instance, mesh, polygon_irradiance};
use crate::light::LightSelection;
use crate::surface::Surface;
use crate::world::World;
use pool::LANES;

fn point(light: u32) -> LightPoint {
    LightPoint {
        light,
        ..LightPoint::default()
    }
}

/// Mean and standard error of `n` draws.
fn mean_and_error(n: usize, mut draw: impl FnMut() -> Vec3) -> (Vec3, Vec3) {
    let (mut sum, mut sum2) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    for _ in 0..n {
        let v = draw().as_dvec3();
        sum += v;
        sum2 += v * v;
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(glam::DVec3::ZERO);
    (mean.as_vec3(), (var / n as f64).sqrt().as_vec3())
}

#[test]
fn ris_estimates_a_known_sum_for_any_candidate_count() {
    // f over 16 values; a uniform source; the target only an approximation of f (its square
    // root), positive wherever f is: the estimator f(y) W is unbiased for any M.
    let f: Vec<f32> = (0..16)
        .map(|i| 0.2 + ((i * 7) % 5) as f32 * (i as f32 * 0.3))
        .collect();
    let exact: f32 = f.iter().sum();
    for candidates in [1, 2, 8, 32] {
        let mut rng = Rng::new(candidates as u64, 1);
        let (mean, err) = mean_and_error(40_000, || {
            let r = Reservoir::resample(
                candidates,
                &mut rng,
                |rng| Some((point(((rng.next_f32() * 16.0) as u32).min(15)), 1.0 / 16.0)),
                |p| f[p.light as usize].sqrt(),
            );
            assert_eq!(r.m, candidates as f32);
            Vec3::splat(f[r.sample.light as usize] * r.weight)
        });
        assert!(
            (mean.x - exact).abs() <= 4.0 * err.x,
            "M = {candidates}: {} +- {} vs {exact}",
            mean.x,
            err.x
        );
    }
}

#[test]
fn merged_reservoirs_keep_a_candidate_in_proportion_to_its_weight() {
    // 32 candidates streamed into 4 reservoirs of 8, then the 4 merged (as reuse merges
    // reservoirs of one target): the survivor is candidate i with probability w_i / sum w.
    let w: Vec<f32> = (0..32).map(|i| 0.1 + ((i * 13) % 7) as f32).collect();
    let total: f32 = w.iter().sum();
    let trials = 200_000;
    let mut counts = [0u32; 32];
    let mut rng = Rng::new(5, 9);
    for _ in 0..trials {
        let mut parts = [Reservoir::default(); 4];
        for (j, part) in parts.iter_mut().enumerate() {
            for k in 0..8 {
                let i = j * 8 + k;
                part.update(point(i as u32), w[i], w[i], 1.0, rng.next_f32());
            }
        }
        let mut merged = Reservoir::default();
        for part in &parts {
            merged.update(part.sample, part.w_sum, part.target, part.m, rng.next_f32());
        }
        assert_eq!(merged.m, 32.0);
        counts[merged.sample.light as usize] += 1;
    }
    let chi2: f64 = counts
        .iter()
        .zip(&w)
        .map(|(&c, &wi)| {
            let e = trials as f64 * (wi / total) as f64;
            (c as f64 - e).powi(2) / e
        })
        .sum();
    // The chi-squared distribution's 0.999 quantile with 31 degrees of freedom.
    assert!(chi2 < 61.1, "chi2 = {chi2}");
}

const QUAD: [Vec3; 4] = [
    Vec3::new(-0.5, 0.0, -0.5),
    Vec3::new(0.5, 0.0, -0.5),
    Vec3::new(0.5, 0.0, 0.5),
    Vec3::new(-0.5, 0.0, 0.5),
];
/// Where the two emissive quads of [`lit_world`] are, and their radiance.
const LIGHTS: [(Vec3, Vec3); 2] = [
    (Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 0.5, 0.25)),
    (Vec3::new(1.6, 1.2, 0.3), Vec3::new(3.0, 4.0, 5.0)),
];

/// Two two-sided emissive quads above the origin, side by side (neither hides the other
/// from the origin).
fn lit_world() -> World {
    let mut scene = Scene {
        meshes: vec![
            mesh(QUAD.to_vec(), vec![[0, 1, 2], [0, 2, 3]], 0),
            mesh(QUAD.to_vec(), vec![[0, 1, 2], [0, 2, 3]], 1),
        ],
        instances: LIGHTS
            .iter()
            .enumerate()
            .map(|(i, (at, _))| instance(i as u32, Mat4::from_translation(*at)))
            .collect(),
        materials: LIGHTS
            .iter()
            .map(|(_, le)| emissive_material(*le, true))
            .collect(),
        ..Scene::default()
    };
    scene.collect_emissive_triangles();
    World::new(scene, LightSelection::Power)
}

/// A Lambertian receiver at the origin facing +y, seen from `wo`.
fn receiver(albedo: f32) -> Receiver {
    Receiver::with(
        Surface {
            p: Vec3::ZERO,
            ng: Vec3::Y,
            ns: Vec3::Y,
            t: Vec3::X,
            b: Vec3::NEG_Z,
            front: true,
            instance: u32::MAX,
            triangle: u32::MAX,
            bary: Vec2::ZERO,
            material: 0,
        },
        Bsdf::new(&BsdfParams::lambertian(Vec3::splat(albedo))),
        Vec3::new(0.3, 1.0, 0.2).normalize(),
        false,
    )
}

/// The default configuration and camera of `world`, for a [`tracer`].
fn view(world: &World) -> (Config, crate::camera::Camera) {
    let config = Config::default();
    let camera = config.render_camera(world);
    (config, camera)
}

fn tracer<'a>(
    world: &'a World,
    camera: &'a crate::camera::Camera,
    config: &'a Config,
) -> PathTracer<'a> {
    PathTracer {
        world,
        camera,
        settings: config.path_settings(),
    }
}

#[test]
fn ris_shading_matches_lambert_irradiance_for_any_candidate_count() {
    let world = lit_world();
    let (config, camera) = view(&world);
    let tracer = tracer(&world, &camera, &config);
    let albedo = 0.8;
    let rec = receiver(albedo);
    // Lambert: radiance = albedo / pi * sum of Le E.
    let expected: Vec3 = LIGHTS
        .iter()
        .map(|(at, le)| {
            let corners: Vec<Vec3> = QUAD.iter().map(|c| *c + *at).collect();
            *le * polygon_irradiance(Vec3::ZERO, Vec3::Y, &corners) as f32
        })
        .sum::<Vec3>()
        * (albedo / std::f32::consts::PI);
    // Each trial draws its own small pool (two blocks: a pixel's blocks often coincide), so
    // that the pool's randomness is part of the estimate.
    let mut pool = LightPool::default();
    for candidates in [1, 4, 32] {
        let mut rng = Rng::new(candidates as u64, 3);
        let mut trial = 0;
        let (mean, err) = mean_and_error(30_000, || {
            trial += 1;
            pool.build(&world.lights, 2, candidates as u64, trial);
            let r = rec.candidates(&pool, &world.lights, candidates, &mut rng);
            let mut rays = 0;
            rec.shade(&tracer, &r, &mut rays)
        });
        for c in 0..3 {
            assert!(
                (mean[c] - expected[c]).abs() <= 4.0 * err[c] + 1e-4 * expected[c],
                "M = {candidates}: {mean} +- {err} vs {expected}"
            );
        }
    }
}

/// A 16 x 4 frame split by a depth edge: the left half at depth 1 holds samples of the first
/// light (its triangles 0 and 1), the right half at depth 3 samples of the second (2 and 3).
fn edge(world: &World) -> (Restir, Vec<GPixel>) {
    let (w, h) = (16usize, 4usize);
    let rec = receiver(0.5);
    let lights = &world.lights;
    let mut restir = Restir::default();
    let mut gbuffer = Vec::new();
    for p in 0..w * h {
        let left = p % w < w / 2;
        gbuffer.push(GPixel {
            position: Vec3::new((p % w) as f32, 0.0, 0.0),
            normal: Vec3::Y,
            albedo: Vec3::splat(0.5),
            material: 0,
            depth: if left { 1.0 } else { 3.0 },
            ..GPixel::default()
        });
        let light = if left {
            (p % 2) as u32
        } else {
            2 + (p % 2) as u32
        };
        let sample = lights
            .sample_point(light as usize, Vec2::splat(0.3))
            .unwrap();
        let target = rec.target(lights, &sample);
        assert!(target > 0.0);
        restir.reservoirs.current.push(Reservoir {
            sample,
            w_sum: target,
            m: 1.0,
            target,
            weight: 1.0,
        });
        restir.receivers.current.push(Some(rec));
    }
    (restir, gbuffer)
}

#[test]
fn spatial_reuse_never_crosses_a_depth_edge() {
    let world = lit_world();
    let (config, camera) = view(&world);
    let tracer = tracer(&world, &camera, &config);
    for unbiased in [false, true] {
        let (mut restir, gbuffer) = edge(&world);
        let settings = RestirConfig {
            enabled: true,
            radius: 4.0,
            neighbours: 8,
            unbiased,
            ..RestirConfig::default()
        };
        for iteration in 0..2 {
            restir.spatial(&tracer, &settings, &gbuffer, 16, 0, iteration);
        }
        let mut reused = 0;
        for (p, r) in restir.reservoirs.current.iter().enumerate() {
            let left = p % 16 < 8;
            assert_eq!(r.sample.light < 2, left, "pixel {p}: {r:?}");
            reused += usize::from(r.m > 1.0);
        }
        // Reuse did happen within each side.
        assert!(reused > 48, "{reused} of 64 reservoirs reused");
    }
}

#[test]
fn temporal_reuse_never_takes_a_sample_across_a_depth_edge() {
    let world = lit_world();
    let (config, camera) = view(&world);
    let tracer = tracer(&world, &camera, &config);
    let (mut restir, gbuffer) = edge(&world);
    // Last frame: the same edge, with every reservoir's sample swapped to the other light,
    // and twice the candidates behind it.
    restir.reservoirs.previous = restir.reservoirs.current.clone();
    for (p, prev) in restir.reservoirs.previous.iter_mut().enumerate() {
        // Left pixels remember a right-half sample and vice versa.
        let other = restir.reservoirs.current[(p + 8) % 16 + (p / 16) * 16];
        *prev = Reservoir { m: 2.0, ..other };
    }
    restir.receivers.previous = restir.receivers.current.clone();
    restir.previous_gbuffer = gbuffer.clone();
    restir.valid = true;
    // This frame: the left half moved by 8 pixels (its previous pixel lies in the right half,
    // across the edge); the right half did not move (same surface).
    let mut moved = gbuffer.clone();
    for (p, g) in moved.iter_mut().enumerate() {
        if p % 16 < 8 {
            g.motion = Vec2::new(8.0, 0.0);
        }
    }
    let settings = RestirConfig {
        enabled: true,
        ..RestirConfig::default()
    };
    restir.temporal(&tracer, &settings, &moved, 16, 0);
    for (p, r) in restir.reservoirs.current.iter().enumerate() {
        if p % 16 < 8 {
            // Rejected: its own sample, alone.
            assert!(r.sample.light < 2 && r.m == 1.0, "pixel {p}: {r:?}");
        } else {
            // Accepted: the previous reservoir's candidates count (capped at 20 x 1).
            assert_eq!(r.m, 3.0, "pixel {p}: {r:?}");
        }
    }
}

/// `lit_world` with `n` random point lights besides its two emissive quads, a spot (not in
/// lanes: evaluated one by one among the others), a directional light and a random
/// environment map with black texels.
fn mixed_world(n: usize) -> World {
    use pathlight_scene::{PunctualKind, PunctualLight};
    let mut scene = lit_world().scene;
    scene.add_random_point_lights(n, 7, 1.0);
    scene.lights.push(PunctualLight {
        name: "spot".into(),
        kind: PunctualKind::Spot {
            inner_cone: 0.3,
            outer_cone: 0.8,
        },
        position: Vec3::new(0.5, 2.0, 0.5),
        direction: Vec3::NEG_Y,
        intensity: Vec3::splat(20.0),
        range: None,
    });
    scene.lights.push(PunctualLight {
        name: "sun".into(),
        kind: PunctualKind::Directional,
        position: Vec3::ZERO,
        direction: Vec3::new(0.2, -1.0, 0.1).normalize(),
        intensity: Vec3::splat(3.0),
        range: None,
    });
    let mut rng = Rng::new(3, 5);
    let (w, h) = (16, 8);
    scene.environment = Some(pathlight_scene::Environment {
        name: "random".into(),
        width: w,
        height: h,
        texels: (0..w * h)
            .map(|i| match i % 7 {
                3 => Vec3::ZERO,
                _ => Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0,
            })
            .collect(),
        rotation: 0.4,
        intensity: 1.0,
    });
    World::new(scene, LightSelection::Power)
}

#[test]
fn candidates_in_lanes_are_the_reference() {
    // In lanes (point lights, the quads' triangles, the directional light and the
    // environment in SIMD lanes, the spot one by one) against one at a time: the same
    // survivors, the same random numbers consumed, weights equal to rounding, for BSDFs with
    // lanes (Lambertian,
    // dielectric and metallic GGX) seen from above and at grazing angles.
    let world = mixed_world(40);
    let lights = &world.lights;
    let base = receiver(0.5);
    let mut glossy = BsdfParams::lambertian(Vec3::new(0.7, 0.4, 0.2));
    glossy.roughness = 0.3;
    glossy.specular = 0.5;
    let mut metal = glossy;
    metal.metallic = 1.0;
    metal.roughness = 0.15;
    let mut half = glossy;
    half.metallic = 0.5;
    half.roughness = 0.7;
    let bsdfs = [
        BsdfParams::lambertian(Vec3::splat(0.6)),
        glossy,
        metal,
        half,
    ];
    let mut pool = LightPool::default();
    pool.build(lights, 64, 5, 0);
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-5 * a.abs().max(b.abs());
    let (mut checked, mut scalar, mut distant) = (0, 0, 0);
    for params in &bsdfs {
        let bsdf = Bsdf::new(params);
        assert!(bsdf.has_lanes());
        for wo in [
            Vec3::new(0.3, 1.0, 0.2),
            Vec3::new(1.0, 0.02, -0.4),
            Vec3::new(-0.2, 0.5, 1.0),
        ] {
            for transmits in [false, true] {
                let rec = Receiver::with(base.surface, bsdf, wo.normalize(), transmits);
                for count in [1, 7, 16, 17, 32, 33] {
                    for seed in 0..20u64 {
                        let mut a = Rng::new(seed, count as u64);
                        let mut b = a.clone();
                        let mut c = a.clone();
                        let reference = rec.candidates_one_by_one(&pool, lights, count, &mut a);
                        // The baseline lanes and the dispatch (AVX-512 or AVX2 where the
                        // processor has them).
                        for r in [
                            rec.candidates_in_lanes(&pool, lights, count, &mut b),
                            rec.candidates(&pool, lights, count, &mut c),
                        ] {
                            assert_eq!(r.sample, reference.sample, "{params:?} {wo} M = {count}");
                            assert_eq!(r.m, reference.m);
                            assert!(close(r.w_sum, reference.w_sum), "{r:?} {reference:?}");
                            assert!(close(r.target, reference.target), "{r:?} {reference:?}");
                            assert!(close(r.weight, reference.weight), "{r:?} {reference:?}");
                        }
                        let next = a.next_f32();
                        assert_eq!((b.next_f32(), c.next_f32()), (next, next));
                        checked += usize::from(reference.weight > 0.0);
                        let lane = lights.lane_light(&reference.sample);
                        let lit = reference.weight > 0.0;
                        scalar += usize::from(lit && lane.is_none());
                        distant += usize::from(
                            lit && matches!(lane, Some(crate::light::LaneLight::Distant { .. })),
                        );
                    }
                }
            }
        }
    }
    assert!(checked > 1000, "{checked} reservoirs with a sample");
    assert!(
        scalar > 10,
        "{scalar} survivors on lights evaluated one by one"
    );
    assert!(distant > 100, "{distant} survivors on distant lights");
    // The neighbours' targets in lanes are `target` to rounding.
    let rec = Receiver::with(
        base.surface,
        Bsdf::new(&glossy),
        Vec3::new(0.3, 1.0, 0.2).normalize(),
        false,
    );
    let mut rng = Rng::new(9, 9);
    let mut distant_targets = 0;
    for n in 1..=LANES {
        let points: [LightPoint; LANES] = std::array::from_fn(|_| {
            let (p, _) = lights
                .draw(rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()))
                .unwrap();
            p
        });
        let t = rec.point_targets(lights, &points, n);
        for k in 0..LANES {
            let expected = if k < n {
                rec.target(lights, &points[k])
            } else {
                0.0
            };
            assert!(close(t[k], expected), "{k} of {n}: {} vs {expected}", t[k]);
            // Distant lights' targets are the scalar arithmetic, bit for bit (frames with
            // an environment do not change with the lanes).
            if k < n
                && matches!(
                    lights.lane_light(&points[k]),
                    Some(crate::light::LaneLight::Distant { .. })
                )
            {
                assert_eq!(t[k].to_bits(), expected.to_bits(), "{k}: {:?}", points[k]);
                distant_targets += 1;
            }
        }
    }
    assert!(distant_targets > 5, "{distant_targets} distant targets");
}
