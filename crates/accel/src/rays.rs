//! Fixed, deterministic ray sets for benchmarking and comparing backends: camera rays, one
//! diffuse bounce and one shadow ray per camera hit.
//!
//! The hits that seed the bounce and shadow rays come from one reference backend, so every
//! backend traces exactly the same rays. Everything is a pure function of the scene, the
//! resolution and the seed: each pixel draws from its own SplitMix64 stream, so the result does
//! not depend on the thread count.

use glam::{Mat4, Vec3};
use pathlight_scene::{Camera, Projection, PunctualKind, Scene};
use rayon::prelude::*;

use crate::ray::{Hit, Ray};
use crate::Accel;

/// The three kinds of rays in a [`RaySets`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RayKind {
    /// Pinhole camera rays through pixel centres (closest hit).
    Primary,
    /// Cosine-weighted diffuse bounces from the camera hits (closest hit).
    Bounce,
    /// Segments from the camera hits to points on lights (any hit).
    Shadow,
}

impl RayKind {
    pub const ALL: [RayKind; 3] = [RayKind::Primary, RayKind::Bounce, RayKind::Shadow];

    pub fn name(self) -> &'static str {
        match self {
            RayKind::Primary => "primary",
            RayKind::Bounce => "bounce",
            RayKind::Shadow => "shadow",
        }
    }

    /// True for kinds traced with `occluded` (any hit) rather than `intersect`.
    pub fn is_occlusion(self) -> bool {
        self == RayKind::Shadow
    }
}

/// Where the shadow rays aim.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LightSource {
    /// Points on emissive triangles, chosen by emitted power.
    EmissiveTriangles,
    /// The scene's punctual lights, chosen uniformly.
    PunctualLights,
    /// The scene has no lights: a point half a diagonal above the centre of its bounds.
    Fallback,
}

/// Camera, bounce and shadow rays of one scene at one resolution.
#[derive(Debug, Clone)]
pub struct RaySets {
    pub width: u32,
    pub height: u32,
    pub seed: u64,
    /// One per pixel, row by row from the top-left.
    pub primary: Vec<Ray>,
    /// One per primary ray that hit (in pixel order): unit directions, `t_min` =
    /// [`SECONDARY_T_MIN`] times the scene's diagonal.
    pub bounce: Vec<Ray>,
    /// One per primary ray that hit (in pixel order): the direction reaches the point on the
    /// light at `t = 1`; `t_max` = [`SHADOW_T_MAX`], so the segment stops just short of the
    /// light, and `t_min` is the bounce rays' start distance in this parameterisation.
    pub shadow: Vec<Ray>,
    /// The camera the primary rays came from (the scene's first, or one framing its bounds).
    pub camera: Camera,
    pub lights: LightSource,
}

/// End of the shadow segments: just short of the point on the light.
pub const SHADOW_T_MAX: f32 = 1.0 - 1e-4;

/// Bounce and shadow rays start at this distance times the scene's diagonal (besides the
/// offset of their origin). Where a hit lies on an edge where two surfaces meet (a room's
/// corner), the offset along one surface's normal can leave the origin exactly on the other
/// surface; with `t_min = 0` that surface is hit at `t = 0` or not depending on rounding, and
/// backends legitimately disagree. A tiny positive `t_min` takes those hits out.
pub const SECONDARY_T_MIN: f32 = 1e-6;

impl RaySets {
    /// Generates the three sets. `reference` finds the camera hits that seed the bounce and
    /// shadow rays; give it the native backend so every backend is measured on the same rays.
    pub fn generate(
        scene: &Scene,
        reference: &dyn Accel,
        width: u32,
        height: u32,
        seed: u64,
    ) -> RaySets {
        let camera = scene
            .cameras
            .first()
            .cloned()
            .unwrap_or_else(|| framing_camera(scene));
        let aspect = width as f32 / height.max(1) as f32;
        let primary: Vec<Ray> = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % width, i / width);
                camera_ray(&camera, aspect, x, y, width, height)
            })
            .collect();
        let hits: Vec<Option<Hit>> = primary.par_iter().map(|r| reference.intersect(r)).collect();

        let lights = LightSampler::new(scene);
        let bounds = scene.bounds();
        let diagonal = if bounds.is_empty() {
            1.0
        } else {
            bounds.diagonal().length().max(f32::MIN_POSITIVE)
        };
        let t_min = SECONDARY_T_MIN * diagonal;
        let pairs: Vec<(Ray, Ray)> = hits
            .par_iter()
            .enumerate()
            .filter_map(|(i, h)| h.map(|h| (i, h)))
            .map(|(i, hit)| {
                let mut rng = SplitMix64::for_index(seed, i as u64);
                let ray = &primary[i];
                let [p0, p1, p2] = scene.world_triangle(hit.instance, hit.triangle);
                let p = p0 * (1.0 - hit.u - hit.v) + p1 * hit.u + p2 * hit.v;
                let mut n = (p1 - p0).cross(p2 - p0).normalize_or_zero();
                if n == Vec3::ZERO {
                    // A triangle too small for f32 to find its normal: face the ray.
                    n = -ray.direction.normalize_or_zero();
                }
                if n.dot(ray.direction) > 0.0 {
                    n = -n;
                }
                let origin = offset_ray_origin(p, n);
                let d = cosine_direction(n, rng.f32(), rng.f32());
                let bounce = Ray::segment(origin, d, t_min, f32::INFINITY);
                let target = lights.sample(scene, origin, diagonal, &mut rng);
                let to_light = target - origin;
                let shadow_t_min = (t_min / to_light.length()).min(0.5 * SHADOW_T_MAX);
                let shadow = Ray::segment(origin, to_light, shadow_t_min, SHADOW_T_MAX);
                (bounce, shadow)
            })
            .collect();
        let (bounce, shadow) = pairs.into_iter().unzip();
        RaySets {
            width,
            height,
            seed,
            primary,
            bounce,
            shadow,
            camera,
            lights: lights.source,
        }
    }

    /// The set of one kind.
    pub fn get(&self, kind: RayKind) -> &[Ray] {
        match kind {
            RayKind::Primary => &self.primary,
            RayKind::Bounce => &self.bounce,
            RayKind::Shadow => &self.shadow,
        }
    }
}

/// A perspective camera, vertical field of view 45 degrees, looking at the centre of the
/// scene's bounds from a fixed diagonal direction, far enough to see the bounding sphere.
pub fn framing_camera(scene: &Scene) -> Camera {
    let bounds = scene.bounds();
    let (center, radius) = if bounds.is_empty() {
        (Vec3::ZERO, 1.0)
    } else {
        let r = 0.5 * bounds.diagonal().length();
        (bounds.center(), if r > 0.0 { r } else { 1.0 })
    };
    let yfov = 45.0f32;
    let dir = Vec3::new(1.0, 0.7, 1.3).normalize();
    let distance = radius / (0.5 * yfov.to_radians()).sin();
    Camera::look_at("framing", center + dir * distance, center, Vec3::Y, yfov)
}

/// The ray through the centre of pixel (x, y), (0, 0) being the top-left one. Perspective
/// directions are unit length.
fn camera_ray(camera: &Camera, aspect: f32, x: u32, y: u32, width: u32, height: u32) -> Ray {
    let sx = 2.0 * (x as f32 + 0.5) / width as f32 - 1.0;
    let sy = 1.0 - 2.0 * (y as f32 + 0.5) / height as f32;
    let m: &Mat4 = &camera.transform;
    let right = m.x_axis.truncate();
    let up = m.y_axis.truncate();
    let back = m.z_axis.truncate();
    let pos = m.w_axis.truncate();
    match camera.projection {
        Projection::Perspective { yfov, .. } => {
            let h = (0.5 * yfov).tan();
            let d = (right * (sx * h * aspect) + up * (sy * h) - back).normalize();
            Ray::new(pos, d)
        }
        Projection::Orthographic { xmag, ymag, .. } => {
            // Keep the vertical extent and follow the image's aspect, as for perspective.
            let _ = xmag;
            let o = pos + right * (sx * ymag * aspect) + up * (sy * ymag);
            Ray::new(o, -back.normalize())
        }
    }
}

/// Moves a surface point off the surface along `n` (unit, on the side the new ray leaves
/// from), by a few float ulps relative to its magnitude: Wächter and Binder, "A Fast and
/// Robust Method for Avoiding Self-Intersection", Ray Tracing Gems, chapter 6. Rays from the
/// result can start at `t_min = 0`.
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let mut out = [0.0f32; 3];
    for k in 0..3 {
        let of_i = (INT_SCALE * n[k]) as i32;
        let bits = p[k].to_bits() as i32;
        let moved = f32::from_bits(if p[k] < 0.0 {
            bits.wrapping_sub(of_i)
        } else {
            bits.wrapping_add(of_i)
        } as u32);
        out[k] = if p[k].abs() < ORIGIN {
            p[k] + FLOAT_SCALE * n[k]
        } else {
            moved
        };
    }
    Vec3::from_array(out)
}

/// A cosine-weighted unit direction about the unit normal `n`, from two uniform numbers.
fn cosine_direction(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    // Duff et al., "Building an Orthonormal Basis, Revisited".
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let bt = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    let r = u2.sqrt();
    let phi = std::f32::consts::TAU * u1;
    let z = (1.0 - u2).max(0.0).sqrt();
    (t * (r * phi.cos()) + bt * (r * phi.sin()) + n * z).normalize()
}

/// Picks points on the scene's lights.
struct LightSampler {
    source: LightSource,
    /// Cumulative emitted power (luminance) of the emissive triangles, normalised to end at 1.
    cdf: Vec<f32>,
}

impl LightSampler {
    fn new(scene: &Scene) -> Self {
        if !scene.emissive_triangles.is_empty() {
            let mut acc = 0.0f64;
            let mut cdf: Vec<f32> = scene
                .emissive_triangles
                .iter()
                .map(|t| {
                    let p = t.power;
                    acc += (0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z).max(0.0) as f64;
                    acc as f32
                })
                .collect();
            let total = cdf.last().copied().unwrap_or(0.0);
            if total > 0.0 && total.is_finite() {
                cdf.iter_mut().for_each(|c| *c /= total);
            } else {
                // No usable power: choose uniformly.
                let n = cdf.len() as f32;
                cdf.iter_mut()
                    .enumerate()
                    .for_each(|(i, c)| *c = (i + 1) as f32 / n);
            }
            return Self {
                source: LightSource::EmissiveTriangles,
                cdf,
            };
        }
        let source = if scene.lights.is_empty() {
            LightSource::Fallback
        } else {
            LightSource::PunctualLights
        };
        Self {
            source,
            cdf: Vec::new(),
        }
    }

    /// A point on a light, as seen from `from`.
    fn sample(&self, scene: &Scene, from: Vec3, diagonal: f32, rng: &mut SplitMix64) -> Vec3 {
        match self.source {
            LightSource::EmissiveTriangles => {
                let u = rng.f32();
                let k = self
                    .cdf
                    .partition_point(|&c| c <= u)
                    .min(self.cdf.len() - 1);
                let e = &scene.emissive_triangles[k];
                let [a, b, c] = scene.world_triangle(e.instance, e.triangle);
                let (r1, r2) = (rng.f32().sqrt(), rng.f32());
                a * (1.0 - r1) + b * (r1 * (1.0 - r2)) + c * (r1 * r2)
            }
            LightSource::PunctualLights => {
                let n = scene.lights.len();
                let light = &scene.lights[((rng.next() >> 11) % n as u64) as usize];
                match light.kind {
                    PunctualKind::Point | PunctualKind::Spot { .. } => light.position,
                    // Far along the direction the light comes from: beyond the scene.
                    PunctualKind::Directional => {
                        from - light.direction.normalize_or_zero() * (2.0 * diagonal)
                    }
                }
            }
            LightSource::Fallback => {
                let b = scene.bounds();
                let c = if b.is_empty() { Vec3::ZERO } else { b.center() };
                c + Vec3::Y * (0.5 * diagonal)
            }
        }
    }
}

/// SplitMix64 (Steele, Lea and Flood): a tiny, well-mixed generator for reproducible sets.
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// An independent stream for item `index` of a set made with `seed`.
    pub fn for_index(seed: u64, index: u64) -> Self {
        let mut s = SplitMix64(seed ^ 0x6a09_e667_f3bc_c909);
        let k = s.next() ^ index.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        let mut r = SplitMix64(k);
        r.next();
        r
    }

    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NativeBvh, SceneTriangles};

    fn cornell() -> Scene {
        pathlight_scene::load(None, &Default::default()).unwrap()
    }

    #[test]
    fn sets_are_deterministic_and_sized() {
        let scene = cornell();
        let bvh = NativeBvh::new(&SceneTriangles::from_scene(&scene));
        let a = RaySets::generate(&scene, &bvh, 40, 30, 7);
        let b = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| RaySets::generate(&scene, &bvh, 40, 30, 7));
        assert_eq!(a.primary.len(), 1200);
        assert_eq!(a.primary, b.primary);
        assert_eq!(a.bounce, b.bounce);
        assert_eq!(a.shadow, b.shadow);
        assert_eq!(a.bounce.len(), a.shadow.len());
        assert!(a.bounce.len() > 600, "{}", a.bounce.len());
        let c = RaySets::generate(&scene, &bvh, 40, 30, 8);
        assert_eq!(a.primary, c.primary);
        assert_ne!(a.bounce, c.bounce);
    }

    #[test]
    fn bounce_rays_leave_the_surface() {
        let scene = cornell();
        let bvh = NativeBvh::new(&SceneTriangles::from_scene(&scene));
        let sets = RaySets::generate(&scene, &bvh, 32, 32, 1);
        assert_eq!(sets.lights, LightSource::EmissiveTriangles);
        // The box is open only towards the camera: most bounces hit a wall, and never the
        // surface they left, at t ~ 0.
        let diag = scene.bounds().diagonal().length();
        let mut hits = 0;
        for r in &sets.bounce {
            if let Some(h) = bvh.intersect(r) {
                assert!(h.t > 1e-5 * diag, "self-intersection at t = {}", h.t);
                hits += 1;
            }
            assert!((r.direction.length() - 1.0).abs() < 1e-5);
        }
        assert!(
            hits * 2 > sets.bounce.len(),
            "{hits} of {}",
            sets.bounce.len()
        );
        for r in &sets.shadow {
            assert_eq!(r.t_max, SHADOW_T_MAX);
        }
    }

    #[test]
    fn offset_moves_along_the_normal() {
        for p in [Vec3::ZERO, Vec3::new(1e-3, -2.0, 1e4), Vec3::splat(-7.5)] {
            for n in [Vec3::X, -Vec3::Y, Vec3::new(0.6, 0.0, -0.8)] {
                let o = offset_ray_origin(p, n);
                assert!((o - p).dot(n) > 0.0, "{p} {n} -> {o}");
            }
        }
    }

    #[test]
    fn framing_camera_sees_the_scene() {
        let mut scene = cornell();
        scene.cameras.clear();
        let bvh = NativeBvh::new(&SceneTriangles::from_scene(&scene));
        let sets = RaySets::generate(&scene, &bvh, 16, 16, 0);
        let hits = sets.primary.iter().filter(|r| bvh.intersect(r).is_some());
        assert!(hits.count() > 64);
    }
}
