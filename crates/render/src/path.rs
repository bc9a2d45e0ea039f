//! The reference path tracer: next event estimation with multiple importance sampling (power
//! heuristic) for area, punctual and environment lights, Russian roulette, a bounce limit,
//! alpha cut-outs and Beer-Lambert absorption inside refracting volumes.
//!
//! Radiance is split as seed 001 splits it: `direct` is light that reaches the first visible
//! surface straight from an emitter (plus emitters seen directly), `indirect` everything that
//! bounced at least once more.

use glam::{Vec2, Vec3};
use pathlight_accel::{Hit, Ray};
use pathlight_core::rng::{hash, Rng};

use crate::bsdf::{Bsdf, Microfacet};
use crate::camera::Camera;
use crate::light::LightSample;
use crate::sampler::PixelSampler;
use crate::sampler::SamplerKind;
use crate::surface::{offset_origin, Shading, Surface};
use crate::world::World;

/// Sampler dimensions used by the camera (film jitter and lens).
pub(crate) const CAMERA_DIMENSIONS: u32 = 4;
/// Sampler dimensions used per path vertex: light choice, light point (2), lobe, direction (2),
/// Russian roulette, and one spare so that each vertex starts a fresh set of four.
const VERTEX_DIMENSIONS: u32 = 8;
/// Cut-out surfaces a ray may pass through before it counts as blocked.
const MAX_ALPHA_LAYERS: u32 = 64;

/// The film point (pixel (`x`, `y`) jittered uniformly) and lens point from a pixel's sampler
/// (its first [`CAMERA_DIMENSIONS`]).
#[inline(always)]
fn film_and_lens(sampler: &mut PixelSampler, x: u32, y: u32) -> (Vec2, Vec2) {
    let film = Vec2::new(x as f32, y as f32) + sampler.next_2d();
    (film, sampler.next_2d())
}

/// What one camera path brings back.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PathSample {
    pub direct: Vec3,
    pub indirect: Vec3,
    /// Base colour at the first hit (zero when the ray escapes).
    pub albedo: Vec3,
    /// World shading normal at the first hit, facing the camera (zero when the ray escapes).
    pub normal: Vec3,
    /// Distance from the camera along its view axis to the first hit (zero when the ray
    /// escapes).
    pub depth: f32,
    /// The first bounce: what the path did after the first hit.
    pub bounce: Bounce,
    /// Rays traced for this sample (closest-hit and shadow queries).
    pub rays: u32,
}

/// The first bounce of a path (seed 001's features and seed 000's reprojection data): the
/// direction chosen at the first hit and the vertex it led to. Zero where the path ended
/// before.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Bounce {
    /// Unit world direction sampled at the first hit.
    pub direction: Vec3,
    /// The second vertex's position and shading normal.
    pub position: Vec3,
    pub normal: Vec3,
    /// Base colour at the first non-specular vertex after the first hit, through mirror and
    /// glass chains (seed 001's "texture2").
    pub albedo: Vec3,
    /// Radiance that came back to the first hit along `direction` (seed 000's irradiance
    /// `I` along the first outgoing direction): what the path gathered beyond the first hit
    /// divided by the throughput of the first bounce. Emission reached there by BSDF sampling
    /// counts with its multiple importance sampling weight. Zero unless asked for
    /// ([`PathTracer::trace_from`]).
    pub radiance: Vec3,
}

/// A surface a ray hit, with its shading: the first vertex of a path.
#[derive(Debug, Clone, Copy)]
pub struct Vertex {
    pub hit: Hit,
    pub surface: Surface,
    pub shading: Shading,
}

impl Vertex {
    /// The vertex of `hit` on `ray`.
    #[inline(always)]
    pub fn new(world: &World, ray: &Ray, hit: Hit, microfacet: crate::bsdf::Microfacet) -> Self {
        let (surface, shading) = world.shaded(ray, &hit, microfacet);
        Self {
            hit,
            surface,
            shading,
        }
    }
}

/// The start of a camera path: its ray and the random streams the rest of it uses.
#[derive(Debug, Clone)]
pub struct CameraSample {
    pub ray: Ray,
    /// The point on the film (pixels) and on the lens ([0, 1)^2) the ray comes from.
    pub film: Vec2,
    pub lens: Vec2,
    pub sampler: PixelSampler,
    pub rng: Rng,
}

impl PathSample {
    pub fn radiance(&self) -> Vec3 {
        self.direct + self.indirect
    }
}

/// Safety stop for paths of unlimited depth (reached only by pathological scenes, e.g. a
/// white furnace inside a perfect mirror).
pub const MAX_PATH_VERTICES: u32 = 1024;

/// What the path tracer reads of the configuration (`Config::path_settings`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathSettings {
    /// Seeds every random decision of the image.
    pub seed: u64,
    /// Sample values: Owen-scrambled Sobol points or independent random numbers.
    pub sampler: SamplerKind,
    /// Maximum number of scattering events along a path; `None`: unlimited (Russian roulette
    /// ends paths, with a hard stop at [`MAX_PATH_VERTICES`]).
    pub max_bounces: Option<u32>,
    /// First bounce at which Russian roulette may end a path.
    pub rr_start: u32,
    pub microfacet: Microfacet,
    /// At the last scattering event the bounce limit allows, still trace the BSDF's ray for
    /// the emission it finds, combined with next event estimation by multiple importance
    /// sampling (false: next event estimation alone, no ray: cheaper, noisier under broad
    /// lights such as a sky). The texture cache's pixels, whose path ends at the first hit,
    /// turn it on.
    pub mis_at_last: bool,
}

impl Default for PathSettings {
    /// The configuration's defaults (`Config::default`).
    fn default() -> Self {
        Self {
            seed: 0,
            sampler: SamplerKind::Sobol,
            max_bounces: None,
            rr_start: 3,
            microfacet: Microfacet::Ggx,
            mis_at_last: false,
        }
    }
}

/// A path tracer over one world, camera and settings.
pub struct PathTracer<'a> {
    pub world: &'a World,
    pub camera: &'a Camera,
    pub settings: PathSettings,
}

#[inline]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2.is_infinite() {
        1.0
    } else if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// Adds radiance `l` that arrived at path vertex `vertex` straight from an emitter.
#[inline]
fn add(out: &mut PathSample, vertex: u32, l: Vec3) {
    let l = finite_or_zero(l);
    if vertex == 0 {
        out.direct += l;
    } else {
        out.indirect += l;
    }
}

/// Replaces NaN and infinite samples by zero (one bad sample must not ruin a reference).
#[inline]
fn finite_or_zero(v: Vec3) -> Vec3 {
    if v.is_finite() {
        v
    } else {
        Vec3::ZERO
    }
}

impl PathTracer<'_> {
    /// Sample `index` of pixel (`x`, `y`): a box-filtered (uniform jitter) camera path.
    pub fn sample_pixel(&self, x: u32, y: u32, index: u32) -> PathSample {
        let CameraSample {
            ray,
            sampler,
            mut rng,
            ..
        } = self.camera_sample(x, y, index);
        let mut rays = 0;
        let first = self.intersect(ray, &mut rng, &mut rays);
        let mut out = self.trace_from::<false>(ray, first.as_ref(), sampler, rng);
        out.rays += rays;
        out
    }

    /// The camera ray of sample `index` of pixel (`x`, `y`) (box filter: uniform jitter over
    /// the pixel) and the sampler and random stream of the rest of its path.
    #[inline(always)]
    pub fn camera_sample(&self, x: u32, y: u32, index: u32) -> CameraSample {
        let mut sampler = self.pixel_sampler(x, y, index);
        let (film, lens) = film_and_lens(&mut sampler, x, y);
        CameraSample {
            ray: self.camera.primary_ray(film, lens),
            film,
            lens,
            sampler,
            // Only cut-out (alpha) surfaces draw from this stream: without any, skip hashing.
            rng: if self.world.has_alpha {
                self.pixel_rng(x, y, index)
            } else {
                Rng::new(0, 0)
            },
        }
    }

    /// The film and lens points of sample `index` of pixel (`x`, `y`), as
    /// [`camera_sample`](Self::camera_sample) has them, without its ray.
    #[inline]
    pub fn film_lens(&self, x: u32, y: u32, index: u32) -> (Vec2, Vec2) {
        film_and_lens(&mut self.pixel_sampler(x, y, index), x, y)
    }

    /// The sampler of sample `index` of pixel (`x`, `y`).
    #[inline]
    pub fn pixel_sampler(&self, x: u32, y: u32, index: u32) -> PixelSampler {
        PixelSampler::with_kind(self.settings.sampler, self.settings.seed, x, y, index)
    }

    /// The random stream of sample `index` of pixel (`x`, `y`) (alpha cut-outs).
    #[inline]
    pub fn pixel_rng(&self, x: u32, y: u32, index: u32) -> Rng {
        Rng::new(
            hash(&[self.settings.seed, x as u64, y as u64]),
            index as u64,
        )
    }

    /// The closest surface along `ray` that is not cut away, with its shading; counts the
    /// rays traced into `rays`.
    #[inline(always)]
    pub fn intersect(&self, ray: Ray, rng: &mut Rng, rays: &mut u32) -> Option<Vertex> {
        self.intersect_from(ray, self.world.accel.intersect(&ray), rng, rays)
    }

    /// As [`intersect`](Self::intersect), given `hit`, the closest hit of `ray` (which the
    /// caller traced, e.g. as part of a batch).
    #[inline(always)]
    pub fn intersect_from(
        &self,
        mut ray: Ray,
        mut hit: Option<Hit>,
        rng: &mut Rng,
        rays: &mut u32,
    ) -> Option<Vertex> {
        let world = self.world;
        for layer in 0..MAX_ALPHA_LAYERS {
            if layer > 0 {
                hit = world.accel.intersect(&ray);
            }
            *rays += 1;
            let v = Vertex::new(world, &ray, hit?, self.settings.microfacet);
            let alpha = v.shading.alpha;
            if alpha >= 1.0 || (alpha > 0.0 && rng.next_f32() < alpha) {
                return Some(v);
            }
            let surface = v.surface;
            // Continue behind the cut-out; `t` stays measured from the original origin.
            let origin = offset_origin(surface.p, surface.ng, ray.direction);
            let skipped = (origin - ray.origin).dot(ray.direction);
            ray = Ray::segment(origin, ray.direction, 0.0, ray.t_max - skipped);
        }
        None
    }

    /// Light sample `ls` at a vertex (its surface, shading, BSDF, and the directions toward
    /// the viewer `wo`, in world and local space): the BSDF times the cosine toward the light,
    /// the transmittance to it (shadow rays counted in `rays`) and the BSDF's density of its
    /// direction; `None` when it adds nothing.
    #[inline(always)]
    pub(crate) fn toward_light(
        &self,
        (surface, shading, bsdf, wo, wo_local): (&Surface, &Shading, &Bsdf, Vec3, Vec3),
        ls: &LightSample,
        rays: &mut u32,
    ) -> Option<(Vec3, f32, f32)> {
        let wi_local = surface.to_local(ls.wi);
        // Reflection needs both directions on the same geometric side.
        let same_side = ls.wi.dot(surface.ng) * wo.dot(surface.ng) > 0.0;
        let (f, bsdf_pdf) = bsdf.eval_pdf(wo_local, wi_local);
        let f = f * wi_local.z.abs();
        if ls.pdf > 0.0 && f != Vec3::ZERO && (same_side || shading.params.transmission > 0.0) {
            let tr = self.transmittance(surface, ls.wi, ls.distance, rays);
            if tr > 0.0 {
                return Some((f, tr, bsdf_pdf));
            }
        }
        None
    }

    /// The light `ls` reflected toward `wo` at `v` (BSDF `bsdf`) by next event estimation
    /// alone (no other strategy finds it): shadow rays counted in `rays`.
    #[inline]
    pub(crate) fn light_alone(
        &self,
        v: &Vertex,
        bsdf: &Bsdf,
        wo: Vec3,
        ls: &LightSample,
        rays: &mut u32,
    ) -> Vec3 {
        let toward = (&v.surface, &v.shading, bsdf, wo, v.surface.to_local(wo));
        self.toward_light(toward, ls, rays)
            .map_or(Vec3::ZERO, |(f, tr, _)| f * ls.radiance * (tr / ls.pdf))
    }

    /// The fraction of light that passes from surface point `surface` along `dir` to a light
    /// `distance` away (1 or 0 for opaque scenes; blended surfaces let 1 - alpha through).
    pub(crate) fn transmittance(
        &self,
        surface: &Surface,
        dir: Vec3,
        distance: f32,
        rays: &mut u32,
    ) -> f32 {
        let world = self.world;
        let origin = surface.spawn_origin(dir);
        let t_max = if distance.is_finite() {
            // Stop short of the light's own surface by as much as the origin was lifted off
            // this one (and a relative margin), measured from the lifted origin.
            let q = surface.p + dir * distance;
            let lift = offset_origin(q, surface.ng, dir) - q;
            ((q - origin).dot(dir) - 2.0 * lift.length()) * (1.0 - 1e-4)
        } else {
            f32::MAX
        };
        if t_max <= 0.0 {
            return 1.0;
        }
        let mut ray = Ray::segment(origin, dir, 0.0, t_max);
        *rays += 1;
        if !world.has_alpha {
            return if world.accel.occluded(&ray) { 0.0 } else { 1.0 };
        }
        let mut tr = 1.0;
        for layer in 0..MAX_ALPHA_LAYERS {
            *rays += u32::from(layer > 0);
            let Some(hit) = world.accel.intersect(&ray) else {
                return tr;
            };
            let (surface, shading) = world.shaded(&ray, &hit, self.settings.microfacet);
            tr *= 1.0 - shading.alpha;
            if tr <= 0.0 {
                return 0.0;
            }
            let next = offset_origin(surface.p, surface.ng, dir);
            let travelled = (next - ray.origin).dot(dir);
            ray = Ray::segment(next, dir, 0.0, ray.t_max - travelled);
        }
        0.0
    }

    /// Follows one path from `ray`, whose first surface (`intersect` of `ray`) is `first`.
    /// `ALONG_FIRST_BOUNCE`: also measure [`Bounce::radiance`] (forward reprojection's `I`);
    /// the plain path tracer leaves it zero and does not pay for it.
    #[inline]
    pub fn trace_from<const ALONG_FIRST_BOUNCE: bool>(
        &self,
        ray: Ray,
        first: Option<&Vertex>,
        sampler: PixelSampler,
        rng: Rng,
    ) -> PathSample {
        self.trace_lit::<ALONG_FIRST_BOUNCE>(ray, first, sampler, rng, None)
    }

    /// As [`trace_from`](Self::trace_from); with `first_direct`, the direct light at the first
    /// hit is given (seed 004's reservoirs): next event estimation is skipped there, and the
    /// emission that BSDF sampling reaches from it through a non-delta lobe is left out
    /// (except from emitters that are not in the light list, which light sampling never
    /// finds). The sampler's dimensions are consumed as without it, so the rest of the path is
    /// the same.
    #[inline]
    pub fn trace_lit<const ALONG_FIRST_BOUNCE: bool>(
        &self,
        mut ray: Ray,
        first: Option<&Vertex>,
        mut sampler: PixelSampler,
        mut rng: Rng,
        first_direct: Option<Vec3>,
    ) -> PathSample {
        let world = self.world;
        let lights = &world.lights;
        let max_bounces = self.settings.max_bounces.unwrap_or(u32::MAX);
        let mut out = PathSample::default();
        let mut beta = Vec3::ONE;
        // Radiance scaling from refraction, undone for Russian roulette (pbrt-v4's etaScale).
        let mut eta_scale = 1.0f32;
        let mut specular_bounce = false;
        let mut prev_pdf = 0.0f32;
        let mut prev_p = ray.origin;
        // Absorption of the volume the ray travels through.
        let mut sigma_a = Vec3::ZERO;
        // The vertex found by the current bounce's ray (the first one is given).
        let mut next: Option<Vertex>;
        // The first non-specular vertex after the first hit has given its albedo.
        let mut bounce_albedo_found = false;
        // The throughput of the first bounce (what `beta` is after it), and the radiance
        // gathered by then (at the first hit).
        let mut first_beta = Vec3::ZERO;
        let mut at_first_hit = Vec3::ZERO;
        for bounce in 0..MAX_PATH_VERTICES {
            sampler.set_dimension(CAMERA_DIMENSIONS + bounce * VERTEX_DIMENSIONS);
            let found = if bounce == 0 {
                first
            } else {
                next = self.intersect(ray, &mut rng, &mut out.rays);
                next.as_ref()
            };
            let Some(&Vertex {
                hit,
                ref surface,
                ref shading,
            }) = found
            else {
                // Escaped: the environment.
                let (le, env_pdf) = lights.environment(ray.direction);
                if le != Vec3::ZERO {
                    let w = if bounce == 0 || specular_bounce {
                        1.0
                    } else if bounce == 1 && first_direct.is_some() {
                        if env_pdf > 0.0 {
                            0.0
                        } else {
                            1.0
                        }
                    } else {
                        power_heuristic(prev_pdf, env_pdf)
                    };
                    add(&mut out, bounce.saturating_sub(1), beta * le * w);
                }
                break;
            };
            if sigma_a != Vec3::ZERO {
                beta *= (-sigma_a * hit.t).exp();
            }
            let wo = -ray.direction;
            let bsdf = world.bsdf(surface.material, &shading.params);
            if bounce == 0 {
                out.albedo = shading.params.base_color;
                out.normal = surface.ns;
                out.depth = hit.t * ray.direction.dot(self.camera.forward());
            } else {
                if bounce == 1 {
                    out.bounce.position = surface.p;
                    out.bounce.normal = surface.ns;
                }
                if !bounce_albedo_found && !bsdf.is_delta() {
                    out.bounce.albedo = shading.params.base_color;
                    bounce_albedo_found = true;
                }
            }
            // Emission reached by BSDF sampling (or seen directly).
            let le = lights.emitted(
                &world.scene,
                surface.instance,
                surface.triangle,
                surface.bary,
                wo,
            );
            if le != Vec3::ZERO {
                let w = if bounce == 0 || specular_bounce {
                    1.0
                } else {
                    let light_pdf =
                        lights.pdf_triangle(prev_p, surface.instance, surface.triangle, surface.p);
                    if bounce == 1 && first_direct.is_some() {
                        if light_pdf > 0.0 {
                            0.0
                        } else {
                            1.0
                        }
                    } else {
                        power_heuristic(prev_pdf, light_pdf)
                    }
                };
                add(&mut out, bounce.saturating_sub(1), beta * le * w);
            }
            if bounce >= max_bounces {
                break;
            }
            let wo_local = surface.to_local(wo);
            // The last scattering event the bounce limit allows: the next vertex could only
            // add emission found by BSDF sampling. Without a delta lobe, next event
            // estimation alone finds the same light (every emitter is in the light sampler),
            // so it takes the whole weight and no continuation ray is traced.
            let last =
                bounce + 1 >= max_bounces && !bsdf.has_delta_lobe() && !self.settings.mis_at_last;
            // Next event estimation.
            let u_light = sampler.next_1d();
            let u_point = sampler.next_2d();
            if let (0, Some(direct)) = (bounce, first_direct) {
                add(&mut out, 0, direct);
            } else if !bsdf.is_delta() && !lights.is_empty() {
                if let Some(ls) = lights.sample(surface.p, u_light, u_point) {
                    let toward = (surface, shading, &bsdf, wo, wo_local);
                    if let Some((f, tr, bsdf_pdf)) = self.toward_light(toward, &ls, &mut out.rays) {
                        let w = if ls.delta || last {
                            1.0
                        } else {
                            power_heuristic(ls.pdf, bsdf_pdf)
                        };
                        add(&mut out, bounce, beta * f * ls.radiance * (tr * w / ls.pdf));
                    }
                }
            }
            if last {
                break;
            }
            // Continue the path.
            let u_lobe = sampler.next_1d();
            let u_dir = sampler.next_2d();
            let Some(bs) = bsdf.sample(wo_local, u_lobe, u_dir) else {
                break;
            };
            if bs.pdf <= 0.0 {
                break;
            }
            let wi = surface.to_world(bs.wi);
            if bounce == 0 {
                out.bounce.direction = wi;
            }
            let crosses = wi.dot(surface.ng) * wo.dot(surface.ng) < 0.0;
            if crosses != bs.transmitted {
                // The shading normal and the geometry disagree about the side: drop the path
                // rather than leak light through the surface.
                break;
            }
            beta *= bs.f * (bs.wi.z.abs() / bs.pdf);
            specular_bounce = bs.delta;
            prev_pdf = bs.pdf;
            prev_p = surface.p;
            if bs.transmitted && shading.volume {
                let entering = wo_local.z > 0.0;
                let eta = shading.params.ior;
                eta_scale *= if entering {
                    eta * eta
                } else {
                    1.0 / (eta * eta)
                };
                sigma_a = if entering {
                    shading.sigma_a
                } else {
                    Vec3::ZERO
                };
            }
            if beta == Vec3::ZERO || !beta.is_finite() {
                break;
            }
            ray = Ray::new(surface.spawn_origin(wi), wi);
            // Russian roulette.
            let u_rr = sampler.next_1d();
            if bounce + 1 >= self.settings.rr_start {
                let m = (beta * eta_scale).max_element();
                if m < 1.0 {
                    let q = (1.0 - m).max(0.0);
                    if u_rr < q {
                        break;
                    }
                    beta /= 1.0 - q;
                }
            }
            if ALONG_FIRST_BOUNCE && bounce == 0 {
                first_beta = beta;
                at_first_hit = out.direct;
            }
        }
        if ALONG_FIRST_BOUNCE {
            // What came back beyond the first hit, without the first bounce's throughput.
            let beyond = (out.direct + out.indirect - at_first_hit).max(Vec3::ZERO);
            out.bounce.radiance = Vec3::select(
                first_beta.cmpgt(Vec3::ZERO),
                beyond / first_beta,
                Vec3::ZERO,
            );
        }
        out
    }
}
