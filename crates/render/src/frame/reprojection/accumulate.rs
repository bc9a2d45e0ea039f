//! The accumulation pass of reprojected states: a frame's samples merged into the states and
//! the history, with the aliasing depth test on the frame after a move.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::frame::accumulation::PixelStats;
use crate::frame::adaptive::NO_PROBABILITY;
use crate::frame::gbuffer::{GBuffer, GPixel};
use crate::frame::lighting::LightSample;
use crate::world::World;

use super::slot::{Plane, Slot, MIXED};
use super::{merged, quadrant, Fate, Reprojection, CHUNK};

/// A carried state of a pixel sampled this frame that the sample disagrees with (`seen`:
/// its plane agrees with the new G-buffer pixel), or that was marked mixed: its old
/// footprint's surface is not all this pixel sees (a carried quarter's place in its new pixel
/// is only approximate). The accumulation pass drops it.
#[inline]
fn carried_disagrees(s: &Slot, seen: bool) -> bool {
    s.is_mixed() || !seen
}

impl Reprojection {
    /// The samples the states of pixel `pixel`, sampled this frame, keep through the
    /// accumulation pass (before its new samples are merged): what the aliasing test (on
    /// the frame after a move) and the disagreement of carried states leave. `pixels` is the
    /// frame's whole G-buffer, `w` its width.
    pub fn kept_by_sampled(
        &self,
        pixel: usize,
        pixels: &[GPixel],
        w: usize,
        tolerance: f32,
        after_move: bool,
    ) -> u32 {
        let k = self.samples;
        let g = &pixels[pixel];
        self.slots.current[pixel * k..pixel * k + k]
            .iter()
            .filter(|s| {
                if s.stats.n == 0 {
                    return false;
                }
                let plane = s.plane();
                let seen = plane.agrees(g, tolerance);
                if after_move && !(seen && inside(&plane, pixels, pixel, w, tolerance)) {
                    return false;
                }
                !(s.is_carried() && carried_disagrees(s, seen))
            })
            .map(|s| s.stats.n)
            .sum()
    }

    /// The statistics pixel `pixel` keeps after the aliasing depth test against its new
    /// G-buffer pixel `g` (what the accumulation pass will leave of its states).
    #[inline]
    pub fn surviving(&self, pixel: usize, g: &GPixel, tolerance: f32) -> PixelStats {
        let k = self.samples;
        merged(
            self.slots.current[pixel * k..pixel * k + k]
                .iter()
                .filter(|s| s.stats.n > 0 && s.plane().agrees(g, tolerance)),
        )
    }

    /// The fate of pixel `pixel` at the last move.
    pub fn fate(&self, pixel: usize) -> Fate {
        Fate::from_u8(self.fates.get(pixel).copied().unwrap_or(0))
    }

    /// The accumulation pass: on the frame after a move (`after_move`) first drops the
    /// states that fail the aliasing depth test (of tolerance `tolerance`), then merges each
    /// pixel's new samples into the state of the quadrant its first hit projects into
    /// (starting the state from this frame's G-buffer and first bounce when it was empty),
    /// and rebuilds the pixel's history. A pixel that loses all its states to the test loses
    /// the probability they brought too. A carried state that a later sample of its quadrant
    /// disagrees with is dropped too. Returns the states dropped.
    #[allow(clippy::too_many_arguments)]
    pub fn accumulate(
        &mut self,
        world: &World,
        camera: &Camera,
        gbuffer: &GBuffer,
        lighting: &[LightSample],
        tolerance: f32,
        after_move: bool,
        history: &mut [PixelStats],
        probability: &mut [f32],
    ) -> u64 {
        let k = self.samples;
        let w = gbuffer.width.max(1) as usize;
        let materials = &world.scene.materials;
        self.slots
            .current
            .par_chunks_mut(k * CHUNK)
            .zip(gbuffer.pixels.par_chunks(CHUNK))
            .zip(lighting.par_chunks(CHUNK))
            .zip(
                history
                    .par_chunks_mut(CHUNK)
                    .zip(probability.par_chunks_mut(CHUNK)),
            )
            .zip(
                self.fates
                    .par_chunks_mut(CHUNK)
                    .zip(self.kept.par_chunks_mut(CHUNK)),
            )
            .enumerate()
            .map(|(c, ((((slots, gs), ls), (hs, ps)), (fates, kept)))| {
                let mut dropped = 0;
                let pixels = gs
                    .iter()
                    .zip(ls)
                    .zip(hs.iter_mut().zip(ps))
                    .zip(fates.iter_mut().zip(kept));
                for (p, (slots, (((g, l), (h, prob)), (fate, kept)))) in
                    slots.chunks_mut(k).zip(pixels).enumerate()
                {
                    let t = c * CHUNK + p;
                    let sampled = l.stats.n > 0;
                    let q = if sampled && k == 4 && !g.is_sky() {
                        camera.project(g.position).map_or(0, quadrant)
                    } else {
                        0
                    };
                    for (i, s) in slots.iter_mut().enumerate() {
                        if s.stats.n == 0 {
                            continue;
                        }
                        let plane = s.plane();
                        let seen = plane.agrees(g, tolerance);
                        if after_move {
                            let edge = seen && !inside(&plane, &gbuffer.pixels, t, w, tolerance);
                            if edge && !sampled {
                                // Not sampled this frame (adaptive sampling): kept for now,
                                // dropped by the pixel's next sample.
                                s.set(MIXED, true);
                            } else if edge || !seen {
                                *s = Slot::default();
                                dropped += 1;
                                *kept -= 1;
                                if *kept == 0 {
                                    *fate = Fate::Aliasing as u8;
                                    *prob = NO_PROBABILITY;
                                }
                                continue;
                            }
                        }
                        if !sampled {
                            continue;
                        }
                        if s.is_carried() {
                            if carried_disagrees(s, seen) {
                                *s = Slot::default();
                                dropped += 1;
                            }
                        } else if i == q && !seen {
                            s.set(MIXED, true);
                        }
                    }
                    if sampled {
                        let s = &mut slots[q];
                        if s.stats.n == 0 {
                            let film = centre(t, w, q, k);
                            *s = Slot::start(g, &l.bounce, materials.get(g.material as usize));
                            s.point = if s.is_sky() {
                                camera.primary_ray(film, Vec2::splat(0.5)).direction
                            } else {
                                snap(camera, film, s.point, g.normal)
                            };
                        }
                        s.add(l);
                    }
                    *h = merged(slots.iter());
                }
                dropped
            })
            .sum()
    }
}

/// Whether the new camera rays through pixel `t` and its 8 neighbours (of `pixels`, `w`
/// wide) all see `plane`'s surface (the aliasing test's criterion). A state that lands on a
/// pixel next to another surface in the new view lies on one of its edges, where its
/// footprint's single surface is not all the pixel sees. (The diagonal neighbours count: a
/// surface that covers only a corner of the pixel reaches the diagonal neighbour's ray first.)
#[inline]
fn inside(plane: &Plane, pixels: &[GPixel], t: usize, w: usize, tolerance: f32) -> bool {
    let rows = pixels.len() / w;
    let (x, y) = (t % w, t / w);
    let (x0, x1) = (x.saturating_sub(1), (x + 1).min(w - 1));
    (y.saturating_sub(1)..=(y + 1).min(rows - 1)).all(|v| {
        pixels[v * w + x0..=v * w + x1]
            .iter()
            .all(|g| plane.agrees(g, tolerance))
    })
}

/// Where the camera ray through film position `film` meets the plane through `point` with
/// normal `normal`: a state's point as seen from its pixel's (or quadrant's) centre. `point`
/// itself where the ray grazes the plane or meets it far (a quarter of the distance) from it.
#[inline]
fn snap(camera: &Camera, film: Vec2, point: Vec3, normal: Vec3) -> Vec3 {
    let ray = camera.primary_ray(film, Vec2::splat(0.5));
    let to_point = point - ray.origin;
    let cos = normal.dot(ray.direction);
    if cos.is_nan() || cos.abs() <= 1e-3 {
        return point;
    }
    let t = normal.dot(to_point) / cos;
    let p = ray.origin + ray.direction * t;
    if t > 0.0 && (p - point).length_squared() <= 0.0625 * to_point.length_squared() {
        p
    } else {
        point
    }
}

/// The centre of quadrant `q` of pixel `t` (of an image `w` wide) with `k` states per pixel
/// (the pixel's centre with one).
#[inline]
fn centre(t: usize, w: usize, q: usize, k: usize) -> Vec2 {
    let pixel = Vec2::new((t % w) as f32, (t / w) as f32);
    if k == 4 {
        pixel + Vec2::new(0.25 + 0.5 * (q & 1) as f32, 0.25 + 0.5 * (q >> 1) as f32)
    } else {
        pixel + 0.5
    }
}
