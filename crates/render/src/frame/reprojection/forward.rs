//! The reprojection pass: every state seen by the previous camera moved into the new view
//! (depth-tested claims, the occlusion ray, the view-dependency error).

use std::sync::atomic::Ordering;

use glam::Vec3;
use pathlight_accel::Ray;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::frame::accumulation::PixelStats;
use crate::frame::adaptive::NO_PROBABILITY;
use crate::world::World;

use super::slot::{view_error, Slot, CARRIED};
use super::{
    merged, quadrant, winner, Fate, Reprojection, ReprojectionConfig, ReprojectionReport, CHUNK,
    NO_CLAIM,
};

impl Reprojection {
    /// The reprojection pass: moves every state seen by `from` into the view of `to` (both for
    /// images of `width` x `height`, the size the states were made for) and rebuilds each
    /// pixel's `history` from its states; carries adaptive sampling's `probability` (a pixel
    /// takes the largest its states bring, [`NO_PROBABILITY`] when none brings one).
    #[allow(clippy::too_many_arguments)]
    pub fn reproject(
        &mut self,
        world: &World,
        from: &Camera,
        to: &Camera,
        width: u32,
        config: &ReprojectionConfig,
        history: &mut [PixelStats],
        probability: &mut [f32],
    ) -> ReprojectionReport {
        let height = history.len() / (width as usize).max(1);
        let mut report = self.claim(world, from, to, width as usize, height, config);
        let kept_states = self.take_claims(history, probability);
        self.slots.swap();
        report.collisions = report.kept - kept_states;
        report.kept = kept_states;
        report
    }

    /// The reprojection pass's first half: every state seen by `from` projected into the
    /// view of `to` (`w` x `h` pixels) and checked; a survivor claims its target (the
    /// nearest wins), the others mark it with their fate. Returns the counts.
    pub(super) fn claim(
        &self,
        world: &World,
        from: &Camera,
        to: &Camera,
        w: usize,
        h: usize,
        config: &ReprojectionConfig,
    ) -> ReprojectionReport {
        let k = self.samples;
        let (eye_from, eye_to) = (from.position(), to.position());
        let (claims, marks) = (&self.claims, &self.marks);
        let mark = |t: usize, fate: Fate| {
            marks[t].fetch_max(fate as u8, Ordering::Relaxed);
        };
        // Each state: its target and the checks; then the occlusion rays of a chunk's
        // survivors together (rays from one eye into neighbouring pixels: coherent packets);
        // then a claim on the target (nearest wins).
        let tolerance = config.occlusion_tolerance;
        let trace_rays = config.occlusion_rays && eye_from != eye_to;
        self.slots
            .current
            .par_chunks(CHUNK)
            .enumerate()
            .map_init(
                || {
                    (
                        Vec::with_capacity(CHUNK),
                        Vec::with_capacity(CHUNK),
                        Vec::new(),
                    )
                },
                |(candidates, rays, hits), (c, chunk)| {
                    let mut r = ReprojectionReport::default();
                    candidates.clear();
                    rays.clear();
                    for (i, s) in chunk.iter().enumerate() {
                        if s.stats.n == 0 {
                            continue;
                        }
                        r.states += 1;
                        let film = if s.is_sky() {
                            to.project_direction(s.point)
                        } else {
                            to.project(s.point)
                        };
                        let Some(f) = film.filter(|f| {
                            f.x >= 0.0 && f.y >= 0.0 && (f.x as usize) < w && (f.y as usize) < h
                        }) else {
                            r.out_of_view += 1;
                            continue;
                        };
                        let t = f.y as usize * w + f.x as usize;
                        if s.is_specular() {
                            mark(t, Fate::Specular);
                            r.specular += 1;
                            continue;
                        }
                        if s.is_mixed() {
                            mark(t, Fate::Mixed);
                            r.mixed += 1;
                            continue;
                        }
                        let error = view_error(s, eye_from, eye_to);
                        if error.is_nan() || error > config.max_error {
                            mark(t, Fate::ViewError);
                            r.view_error += 1;
                            continue;
                        }
                        let q = if k == 4 && !s.is_sky() {
                            quadrant(f)
                        } else {
                            0
                        };
                        let distance = if trace_rays {
                            let (ray, distance) = occlusion_ray(eye_to, s, tolerance);
                            rays.push(ray);
                            distance
                        } else {
                            eye_distance(eye_to, s)
                        };
                        candidates.push((c * CHUNK + i, t, q, distance));
                    }
                    hits.clear();
                    hits.resize(candidates.len(), None);
                    if trace_rays {
                        world.accel.intersect_batch(rays, hits);
                    }
                    for (&(j, t, q, distance), hit) in
                        candidates.iter().zip(hits.iter().map(Option::is_some))
                    {
                        if hit {
                            mark(t, Fate::Occluded);
                            r.occluded += 1;
                        } else {
                            let key = ((distance.to_bits() as u64) << 32) | j as u64;
                            claims[t * k + q].fetch_min(key, Ordering::Relaxed);
                            r.kept += 1;
                        }
                    }
                    r
                },
            )
            .reduce(ReprojectionReport::default, ReprojectionReport::add)
    }

    /// The reprojection pass's second half: each target takes its winning states (into the
    /// scratch buffer), rebuilds its `history` from them and takes the largest `probability`
    /// they bring. Returns the states kept.
    pub(super) fn take_claims(
        &mut self,
        history: &mut [PixelStats],
        probability: &mut [f32],
    ) -> u64 {
        let k = self.samples;
        // Each target takes its winning states, and the largest probability they bring. The
        // claims and marks are this pass's alone now: plain loads and stores, not locked swaps.
        self.probability.clear();
        self.probability.extend_from_slice(probability);
        let (source, before) = (&self.slots.current, &self.probability);
        self.slots
            .previous
            .par_chunks_mut(k * CHUNK)
            .zip(self.claims.par_chunks_mut(k * CHUNK))
            .zip(self.marks.par_chunks_mut(CHUNK))
            .zip(history.par_chunks_mut(CHUNK))
            .zip(probability.par_chunks_mut(CHUNK))
            .zip(self.fates.par_chunks_mut(CHUNK))
            .zip(self.kept.par_chunks_mut(CHUNK))
            .map(
                |((((((targets, claims), marks), hist), prob), fates), kept)| {
                    let mut count = 0;
                    let pixels = hist
                        .iter_mut()
                        .zip(prob.iter_mut())
                        .zip(fates.iter_mut().zip(kept))
                        .zip(marks.iter_mut().zip(claims.chunks_mut(k)));
                    for (slots, (((h, prob), (fate, kept)), (mark, claims))) in
                        targets.chunks_mut(k).zip(pixels)
                    {
                        let mut n = 0;
                        *prob = NO_PROBABILITY;
                        for (slot, claim) in slots.iter_mut().zip(claims) {
                            let claim = std::mem::replace(claim.get_mut(), NO_CLAIM);
                            *slot = match winner(claim) {
                                None => Slot::default(),
                                Some(j) => {
                                    n += 1;
                                    *prob = prob.max(before[j / k]);
                                    // Its point stays where it is: re-centred on the pixel it
                                    // landed in, a state would lose the fraction of a pixel it
                                    // moved at every step, and under small steps never move.
                                    let mut slot = source[j];
                                    slot.set(CARRIED, true);
                                    slot
                                }
                            };
                        }
                        let mark = std::mem::take(mark.get_mut());
                        *fate = if n > 0 { Fate::Kept as u8 } else { mark };
                        *kept = n;
                        *h = merged(slots.iter());
                        count += n as u64;
                    }
                    count
                },
            )
            .sum()
    }
}

/// The distance from a camera at `eye` to `slot`'s stored point (infinite for the sky): the
/// key by which the nearest of the states that land on one target wins.
#[inline]
fn eye_distance(eye: Vec3, slot: &Slot) -> f32 {
    if slot.is_sky() {
        return f32::INFINITY;
    }
    let distance = (slot.point - eye).length();
    // At the eye (or not finite): nearest of all.
    if distance > 0.0 {
        distance
    } else {
        0.0
    }
}

/// The ray from a camera at `eye` towards `slot`'s stored point (stopping `tolerance` of the
/// distance short of it; for the sky, unbounded in its direction), and the distance (infinite
/// for the sky). Anything it hits hides the point.
#[inline]
fn occlusion_ray(eye: Vec3, slot: &Slot, tolerance: f32) -> (Ray, f32) {
    let distance = eye_distance(eye, slot);
    if slot.is_sky() {
        return (Ray::new(eye, slot.point), distance);
    }
    if distance == 0.0 {
        // At the eye: nothing can hide it (an empty segment).
        return (Ray::segment(eye, Vec3::Z, 0.0, 0.0), 0.0);
    }
    let d = slot.point - eye;
    let ray = Ray::segment(eye, d / distance, 0.0, distance * (1.0 - tolerance));
    (ray, distance)
}
