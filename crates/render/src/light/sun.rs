//! The environment's sun apart from its sky: two sampling distributions over the environment
//! map, one over the sun's texels and one over the rest, so that a caller can light a point by
//! the sun alone (sharp shadows, evaluated where they fall) and by the sky alone (broad light
//! that a cache can hold and filter: seed 002's `terms = "sky"`).
//!
//! The sun: the texels at least [`SUN_FRACTION`] as bright as the brightest (luminance),
//! if together they cover at most [`MAX_SUN_SOLID_ANGLE`]; a map whose bright texels cover
//! more (an overcast sky, a studio's soft boxes) has no sun and is all sky. The two parts
//! partition the texels, so the sun's and the sky's light add up to the environment's.
//! [`SunAndSky::sample_with`] samples the scene's other lights with either part in the
//! environment's place.
//!
//! [`SunAndSky::sun_irradiance`] works out the sun's unshadowed irradiance of a normal over
//! its texels, per channel: with it a caller can light a point by the sun with a ratio
//! estimator (Heitz et al. 2018, "Combining analytic direct illumination and stochastic
//! shadows"), whose one sample decides only the visibility and the BSDF's variation across
//! the sun, not the sun's colour or its cosine.

use glam::{Vec2, Vec3};

use super::environment::{weight, EnvironmentMap, TexelSampler};
use super::{LightSample, Lights};

/// A texel belongs to the sun if its luminance is at least this fraction of the brightest's.
pub const SUN_FRACTION: f32 = 0.01;
/// The sun's texels cover at most this solid angle (sr; the sun's disk is 6.8e-5 sr, and
/// 1K maps blur it over a few hundred times that at most).
pub const MAX_SUN_SOLID_ANGLE: f32 = 0.01;

/// Which part of the environment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    Sun,
    Sky,
}

/// The environment of a [`Lights`] split into its sun and its sky.
#[derive(Debug, Clone, Default)]
pub struct SunAndSky {
    sun: Option<TexelSampler>,
    sky: Option<TexelSampler>,
    /// The sun's texels.
    pub sun_texels: usize,
    /// The sun's share of the environment's power (luminance over the sphere).
    pub sun_share: f32,
    /// The sun's texels' radiance-weighted directions ([`Self::sun_irradiance`]).
    moments: SunMoments,
}

/// The sun's texels as sums of their directions weighted by their radiance and solid angle:
/// what the sun's irradiance of a normal needs.
#[derive(Debug, Clone, Default)]
struct SunMoments {
    /// Per channel (r, g, b), the sum over the sun's texels of `L_c w dOmega`: channel c's
    /// irradiance of a unit normal `n` that sees every texel is `n . sum[c]`.
    sum: [Vec3; 3],
    /// Every texel's direction `w` (its centre's) and `L dOmega`, for a normal that sees only
    /// part of the sun.
    texels: Vec<(Vec3, Vec3)>,
    /// The texels' luminance-weighted mean direction.
    axis: Vec3,
    /// The sine of the widest angle between `axis` and a texel's direction: a normal `n` with
    /// `n . axis > sin` sees every texel (1: no texel, or none within 90 degrees of `axis`).
    sin_spread: f32,
}

impl SunMoments {
    /// The moments of the texels `sun` accepts (by index, row-major) of `map`.
    fn new(map: &EnvironmentMap, sun: &[bool]) -> Self {
        let grid = &map.grid;
        let w = grid.width();
        let mut m = Self::default();
        let mut axis = Vec3::ZERO;
        for i in (0..sun.len()).filter(|&i| sun[i]) {
            let (x, y) = (i % w, i / w);
            let dir = grid.direction(x, y, 0.5, 0.5);
            let l = map.texel(i).radiance.max(Vec3::ZERO) * grid.solid_angle(y) as f32;
            if !l.is_finite() {
                continue;
            }
            for c in 0..3 {
                m.sum[c] += dir * l[c];
            }
            axis += dir * weight(l);
            m.texels.push((dir, l));
        }
        m.axis = axis.normalize_or_zero();
        let min_cos = m
            .texels
            .iter()
            .map(|(d, _)| d.dot(m.axis))
            .fold(1.0f32, f32::min);
        m.sin_spread = match min_cos > 0.0 && m.axis != Vec3::ZERO {
            true => (1.0 - min_cos * min_cos).max(0.0).sqrt(),
            false => 1.0,
        };
        m
    }

    /// Channel by channel, the irradiance of unit normal `n` by the texels, each as a point
    /// at its centre: `sum_t L_t max(0, n . w_t) dOmega_t`.
    fn irradiance(&self, n: Vec3) -> Vec3 {
        if n.dot(self.axis) > self.sin_spread {
            return Vec3::new(n.dot(self.sum[0]), n.dot(self.sum[1]), n.dot(self.sum[2]));
        }
        self.texels
            .iter()
            .map(|&(d, l)| l * n.dot(d).max(0.0))
            .sum()
    }
}

impl SunAndSky {
    /// The split of `lights`' environment: no sun and no sky without one.
    pub fn new(lights: &Lights) -> Self {
        let Some(light) = &lights.environment else {
            return Self::default();
        };
        let map = &light.map;
        let grid = &map.grid;
        let (w, h) = (grid.width(), grid.height());
        let lum: Vec<f32> = (0..w * h).map(|i| weight(map.texel(i).radiance)).collect();
        let brightest = lum.iter().copied().fold(0.0f32, f32::max);
        // The texels bright enough, if they are few enough to be a sun.
        let mut sun: Vec<bool> = lum
            .iter()
            .map(|&l| brightest > 0.0 && l >= SUN_FRACTION * brightest)
            .collect();
        let solid_angle: f64 = (0..lum.len())
            .filter(|&i| sun[i])
            .map(|i| grid.solid_angle(i / w))
            .sum();
        if solid_angle > MAX_SUN_SOLID_ANGLE as f64 {
            sun.fill(false);
        }
        let (sun_weights, sun_power) = map.weights(|i| sun[i]);
        let (sky_weights, sky_power) = map.weights(|i| !sun[i]);
        let total = sun_power + sky_power;
        Self {
            sun: TexelSampler::new(&sun_weights, w, h),
            sky: TexelSampler::new(&sky_weights, w, h),
            sun_texels: sun.iter().filter(|&&s| s).count(),
            moments: SunMoments::new(map, &sun),
            sun_share: if total > 0.0 {
                (sun_power / total) as f32
            } else {
                0.0
            },
        }
    }

    /// As [`Lights::sample`] at `p`, with the environment's `part` in the environment's place
    /// (picked with the environment's probability): next event estimation of every light but
    /// the environment's other part.
    pub fn sample_with(
        &self,
        lights: &Lights,
        part: Part,
        p: Vec3,
        u_select: f32,
        u: Vec2,
    ) -> Option<LightSample> {
        let (index, select) = lights.choose(u_select)?;
        if lights.environment.is_some() && index + 1 == lights.count {
            let ls = self.sample(lights, part, u)?;
            return Some(LightSample {
                pdf: ls.pdf * select,
                ..ls
            });
        }
        let (ls, _) = lights.evaluate_selected(p, &lights.sample_point(index, u)?, select)?;
        Some(ls)
    }

    /// The irradiance of a surface of unit normal `n` by the sun alone, unshadowed, per
    /// channel: its texels' radiance times their cosine (0 below the horizon) and solid angle,
    /// summed (exactly `n . S`, `S` the texels' radiance-weighted directions, where `n` sees
    /// the whole sun; texel by texel where the sun straddles `n`'s horizon). Zero without a
    /// sun.
    pub fn sun_irradiance(&self, n: Vec3) -> Vec3 {
        self.moments.irradiance(n)
    }

    /// Whether the environment has a sun.
    pub fn has_sun(&self) -> bool {
        self.sun.is_some()
    }

    /// A direction toward `part` of `lights`' environment (the one this split was made from)
    /// drawn in proportion to its luminance: its radiance and solid-angle density.
    /// `None` when the part is black or absent.
    pub fn sample(&self, lights: &Lights, part: Part, u: Vec2) -> Option<LightSample> {
        let d = match part {
            Part::Sun => self.sun.as_ref()?,
            Part::Sky => self.sky.as_ref()?,
        };
        let map = &lights.environment.as_ref()?.map;
        let wi = map.sample_with(d, u)?;
        // The density and radiance of the direction itself (the texel it falls in), as the
        // environment's own sampling finds them.
        let texel = map.grid.texel(wi);
        let pdf = d.density(&map.grid, texel);
        let radiance = map.texel(texel).radiance;
        (pdf > 0.0 && pdf.is_finite() && radiance != Vec3::ZERO).then_some(LightSample {
            wi,
            distance: f32::INFINITY,
            radiance,
            pdf,
            delta: false,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::tests::sunny;
    use crate::light::LightSelection;
    use pathlight_scene::{Environment, Scene};

    fn lights_of(env: Environment) -> Lights {
        let scene = Scene {
            environment: Some(env),
            ..Scene::default()
        };
        Lights::new(&scene, LightSelection::Power)
    }

    /// The irradiance of unit normal `n`, per channel, by the sun's texels of `env` (those
    /// over 1000 in red) or, `sun` false, by the others: the integral of `L max(0, n . w)` by
    /// the midpoint rule on 4x4 directions per texel, each with its own cosine and solid angle
    /// (independent of the distributions and of the texels' centres).
    fn brute_force_irradiance(env: &Environment, n: Vec3, sun: bool) -> Vec3 {
        let (w, h) = (env.width as usize, env.height as usize);
        let sub = 4;
        let mut e = glam::DVec3::ZERO;
        for y in 0..h * sub {
            for x in 0..w * sub {
                let uv = Vec2::new(
                    (x as f32 + 0.5) / (w * sub) as f32,
                    (y as f32 + 0.5) / (h * sub) as f32,
                );
                let texel = (uv.y * h as f32) as usize * w + (uv.x * w as f32) as usize;
                if (env.texels[texel].x > 1000.0) != sun {
                    continue;
                }
                let theta = uv.y * std::f32::consts::PI;
                let d_omega = (2.0 * std::f32::consts::PI / (w * sub) as f32)
                    * (std::f32::consts::PI / (h * sub) as f32)
                    * theta.sin();
                let cos = n.dot(env.uv_to_direction(uv)).max(0.0);
                e += (env.radiance_at_uv(uv) * cos * d_omega).as_dvec3();
            }
        }
        e.as_vec3()
    }

    /// The sun's and the sky's estimates of the irradiance of an upward-facing point add up to
    /// the environment's, found by brute force over the sphere's texels (independent of the
    /// distributions); the sun is the three bright texels.
    #[test]
    fn sun_and_sky_add_up_to_the_environment() {
        let env = sunny(256, 128);
        let lights = lights_of(env.clone());
        let split = SunAndSky::new(&lights);
        assert!(split.has_sun());
        assert_eq!(split.sun_texels, 3);
        assert!(
            split.sun_share > 0.5 && split.sun_share < 1.0,
            "{}",
            split.sun_share
        );
        // Irradiance at a point facing +Y, of the sun's texels and of the sky's.
        let exact =
            [true, false].map(|sun| f64::from(brute_force_irradiance(&env, Vec3::Y, sun).y));
        for (k, part) in [Part::Sun, Part::Sky].into_iter().enumerate() {
            let n = 200_000;
            let mut rng = pathlight_core::rng::Rng::new(5, k as u64);
            let mut sum = 0.0f64;
            for _ in 0..n {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                if let Some(ls) = split.sample(&lights, part, u) {
                    sum += (ls.radiance.y * ls.wi.y.max(0.0) / ls.pdf) as f64;
                }
            }
            let estimate = sum / n as f64;
            let rel = (estimate - exact[k]).abs() / exact[k];
            assert!(rel < 0.01, "{part:?}: {estimate} against {}", exact[k]);
        }
        // Nothing sampled from one part falls in the other.
        let mut rng = pathlight_core::rng::Rng::new(9, 0);
        for _ in 0..10_000 {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let sun = split.sample(&lights, Part::Sun, u).unwrap();
            assert!(sun.radiance.x > 1000.0);
            let sky = split.sample(&lights, Part::Sky, u).unwrap();
            assert!(sky.radiance.x < 1.0);
        }
    }

    /// The sun's irradiance of a normal against brute force over the map, for normals that
    /// see all of the sun, part of it and none of it.
    #[test]
    fn the_suns_irradiance_matches_brute_force() {
        let env = sunny(256, 128);
        let split = SunAndSky::new(&lights_of(env.clone()));
        let brute = |n: Vec3| brute_force_irradiance(&env, n, true);
        let full = brute(Vec3::Y);
        assert!(full.y > 0.0);
        let axis = split.moments.axis;
        let side = axis.cross(Vec3::X).normalize();
        for (n, what) in [
            (Vec3::Y, "facing up"),
            ((axis + side).normalize(), "at 45 degrees"),
            ((side + axis * 0.01).normalize(), "at the horizon"),
            (-axis, "facing away"),
        ] {
            let got = split.sun_irradiance(n);
            let want = brute(n);
            assert!(
                (got - want).abs().max_element() <= 0.02 * full.y,
                "{what}: {got} against {want} (facing up {full})"
            );
        }
        assert_eq!(split.sun_irradiance(-axis), Vec3::ZERO);
    }

    /// A map without a concentrated bright spot (its bright texels cover a wide solid angle)
    /// has no sun: the sky is the whole environment.
    #[test]
    fn an_overcast_map_has_no_sun() {
        let mut env = sunny(256, 128);
        for t in env.texels.iter_mut().take(256 * 32) {
            *t = Vec3::splat(3.0);
        }
        env.texels[5] = Vec3::splat(20.0);
        let lights = lights_of(env);
        let split = SunAndSky::new(&lights);
        assert!(!split.has_sun());
        assert_eq!(split.sun_share, 0.0);
        assert!(split
            .sample(&lights, Part::Sky, Vec2::new(0.3, 0.1))
            .is_some());
        assert!(
            SunAndSky::new(&Lights::new(&Scene::default(), LightSelection::Power))
                .sample(&lights, Part::Sky, Vec2::splat(0.5))
                .is_none()
        );
    }
}
