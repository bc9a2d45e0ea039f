//! The sample cache: blocks of cells of the surfaces' grids, each cell shaded by paths from
//! its centroid (a white Lambertian there: the light is demodulated) and kept across frames by
//! the temporal rule (`temporal`, `reshade`, `max_count`), and after the lighting pass the
//! young cells it shaded brought up to `fresh_spp` within the frame's budget. The layer the
//! texel cache ([`super::texels`]) filters.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use glam::Vec3;
use pathlight_core::rng::{hash, Rng};

use crate::bsdf::BsdfParams;
use crate::light::sun::{Part, SunAndSky};
use crate::path::{PathTracer, Vertex, CAMERA_DIMENSIONS};
use crate::sampler::PixelSampler;

use super::super::state::Times;
use super::settings::{CachedTerms, Temporal, TextureCacheConfig, CHANNELS, TEXTURE_CACHE};
use super::surface_grid::SurfaceGrids;
use super::table::{Block, Claim, Table, CELLS, READY};

/// What a camera sample's lookups cost: rays traced (its own and its cells'), cells shaded.
pub(super) struct Work {
    pub(super) rays: u64,
    pub(super) cells: u32,
}

/// The frame's counts, summed over threads.
#[derive(Debug, Default)]
pub(super) struct Counters {
    pub(super) cells: AtomicU64,
    pub(super) topped_up: AtomicU64,
    pub(super) blocks: AtomicU64,
    pub(super) texels: AtomicU64,
    pub(super) uncached: AtomicU64,
    /// The lookups' thread time.
    pub(super) nanos: AtomicU64,
}

impl Counters {
    /// Adds the time since `t` to the lookups' thread time.
    pub(super) fn time(&self, t: Instant) {
        let ns = t.elapsed().as_nanos() as u64;
        self.nanos.fetch_add(ns, Ordering::Relaxed);
    }
}

/// How a lookup met the cache (a pixel's first sample's, [`super::CachePixel::status`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Status {
    /// Not traced, or the sky.
    #[default]
    None,
    /// Its surface bypasses the cache (glossy, metallic, transmissive).
    Bypass,
    /// Its texel was filtered already this frame.
    Hit,
    /// It filtered its texel (or, without a filter, shaded its cell's block).
    Miss,
    /// Its block's set was full: shaded without the cache.
    Uncached,
}

/// The sample cache across frames: its table and the young blocks of the frame.
#[derive(Default)]
pub(super) struct SampleCache {
    pub(super) table: Table,
    /// The blocks shaded this frame whose cells hold fewer than `fresh_spp` samples, with
    /// their slots (brought up to it after the lighting pass: [`SampleFrame::top_up`]).
    pub(super) young: Mutex<Vec<(Block, usize)>>,
    /// The table was emptied since the last frame: the top-up takes `cold_budget`.
    pub(super) cold: bool,
    /// The young cells' paths this instant may still take, set by its first frame's top-up
    /// (`u64::MAX`: not yet): a stereo pair's second eye (the same instant) spends what the
    /// first left, so that the pair tops up what one frame would.
    pub(super) instant_budget: AtomicU64,
}

/// The sample cache as one frame's lighting pass reads and shades it.
pub(super) struct SampleFrame<'a> {
    pub(super) cache: &'a SampleCache,
    /// Frames the cache has served (its slots' frame stamps), this one included.
    pub(super) frame: u32,
    pub(super) counters: &'a Counters,
    pub(super) grids: &'a SurfaceGrids,
    /// The environment's sun and sky (`terms = "sky"`).
    pub(super) sun: &'a SunAndSky,
    pub(super) cfg: &'a TextureCacheConfig,
    /// The largest luminance of a cell's sample of indirect light (`clamp`; infinite: none).
    pub(super) clamp: f32,
    /// The sample streams' seed.
    pub(super) seed: u64,
}

impl SampleFrame<'_> {
    /// Sample block `block` shaded this frame, its cells' data (count, channels) into `out`:
    /// found, shaded here, waited for, or shaded without the cache.
    pub(super) fn sample_block(
        &self,
        tracer: &PathTracer,
        block: &Block,
        out: &mut [f32],
        work: &mut Work,
    ) -> Status {
        loop {
            if let Some(status) = self.try_sample_block(tracer, block, out, work) {
                return status;
            }
            std::thread::yield_now();
        }
    }

    /// As [`sample_block`](Self::sample_block) without waiting: `None` while another thread
    /// shades the block (or replaced it as it was read).
    pub(super) fn try_sample_block(
        &self,
        tracer: &PathTracer,
        block: &Block,
        out: &mut [f32],
        work: &mut Work,
    ) -> Option<Status> {
        let table = &self.cache.table;
        let frame = self.frame;
        let out = &mut out[..table.stride];
        match table.claim(block.key(), frame) {
            Claim::Ready(i, s) => {
                table.read(i, out);
                table.still(i, s, frame).then_some(Status::Hit)
            }
            Claim::Busy => None,
            Claim::Mine(i, fresh) => {
                self.shade_slot(tracer, block, i, fresh, out, work);
                Some(Status::Miss)
            }
            Claim::Full => {
                out.fill(0.0);
                self.shade(tracer, block, out, work, None);
                self.counters.uncached.fetch_add(1, Ordering::Relaxed);
                Some(Status::Uncached)
            }
        }
    }

    /// Shades sample block `block` into slot `i` of the sample cache, claimed for it (`fresh`:
    /// a new key, no history), its cells' data into `out`, and publishes it as shaded this
    /// frame.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn shade_slot(
        &self,
        tracer: &PathTracer,
        block: &Block,
        i: usize,
        fresh: bool,
        out: &mut [f32],
        work: &mut Work,
    ) {
        let table = &self.cache.table;
        if fresh {
            out.fill(0.0);
        } else {
            table.read(i, out);
        }
        self.shade(tracer, block, out, work, None);
        table.write(i, out);
        table.publish(i, block.key(), self.frame);
        self.counters.blocks.fetch_add(1, Ordering::Relaxed);
        if self.cfg.fresh_spp > 1
            && self.cfg.temporal == Temporal::Mean
            && block_mean(block, out, 1 + self.cfg.channels()) < self.cfg.fresh_spp as f32
        {
            self.cache
                .young
                .lock()
                .expect("not poisoned")
                .push((*block, i));
        }
    }

    /// After the frame's lighting pass: the young blocks it shaded (cells of fewer than
    /// `fresh_spp` samples) shaded again toward `fresh_spp` within `fresh_budget` paths per
    /// pixel of the frame (`pixels`), at a cold cache's first frame as at any other: every
    /// young cell up to the same level, the highest the budget pays for, then the youngest
    /// blocks (then by key: the same blocks whatever the thread count) one sample further.
    /// The rest wait for a frame that sees them again. Returns the rays traced.
    pub(super) fn top_up(&self, tracer: &PathTracer, pixels: usize, times: &mut Times) -> u64 {
        use rayon::prelude::*;
        let start = Instant::now();
        let mut young = std::mem::take(&mut *self.cache.young.lock().expect("not poisoned"));
        let (table, frame) = (&self.cache.table, self.frame);
        // (A block's words, a cell's.)
        let (words, stride) = (table.stride, 1 + self.cfg.channels());
        // Each block's data, read once, while its slot still holds it as shaded this frame
        // (nothing else writes the table until the next frame).
        let mut order: Vec<(f32, u64, usize, [f32; CELLS * (1 + CHANNELS)])> = (young.iter())
            .enumerate()
            .filter(|(_, &(b, i))| {
                table.states[i].load(Ordering::Acquire) == b.key() | READY
                    && table.frames[i].load(Ordering::Acquire) == frame
            })
            .map(|(k, &(b, i))| {
                let mut d = [0.0f32; CELLS * (1 + CHANNELS)];
                table.read(i, &mut d[..words]);
                (block_mean(&b, &d, stride), b.key(), k, d)
            })
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let per_pixel = match self.cache.cold {
            true => self.cfg.cold_budget,
            false => self.cfg.fresh_budget,
        };
        // The frame's budget, or at a second frame of the same instant what the first left.
        let own = (per_pixel as f64 * pixels as f64) as u64;
        let left = &self.cache.instant_budget;
        let budget = match left.load(Ordering::Relaxed) {
            u64::MAX => own,
            remaining => remaining,
        };
        let fresh = self.cfg.fresh_spp.min(self.cfg.max_count);
        // The samples that bring block `k`'s cells (data `d`) up to `t` each.
        let cost = |t: u32, k: usize, d: &[f32]| -> u64 {
            (0..CELLS)
                .filter(|&c| young[k].0.cell(c).is_some())
                .map(|c| t.saturating_sub(d[c * stride] as u32) as u64)
                .sum()
        };
        let total = |t: u32| -> u64 { order.iter().map(|(_, _, k, d)| cost(t, *k, d)).sum() };
        // Water-filling: every young cell up to the highest level the budget pays for (the
        // error of cells of n samples falls as 1/n: spread evenly, a budget's paths lower the
        // frame's error more than on a few cells brought all the way), then the youngest
        // blocks one sample further while the budget lasts.
        let (mut level, mut high) = (0, fresh);
        while level < high {
            let mid = (level + high).div_ceil(2);
            match total(mid) <= budget {
                true => level = mid,
                false => high = mid - 1,
            }
        }
        let mut spent = total(level);
        let mut targets: Vec<(u32, usize)> = Vec::with_capacity(order.len());
        for (i, (_, _, k, d)) in order.iter().enumerate() {
            let mut t = level;
            if level < fresh {
                let more = cost(level + 1, *k, d) - cost(level, *k, d);
                if spent + more <= budget {
                    spent += more;
                    t += 1;
                }
            }
            if cost(t, *k, d) > 0 {
                targets.push((t, i));
            }
        }
        left.store(budget - spent.min(budget), Ordering::Relaxed);
        let rays = targets
            .into_par_iter()
            .map(|(t, i)| {
                let (block, slot) = young[order[i].2];
                let mut d = order[i].3;
                let mut work = Work { rays: 0, cells: 0 };
                self.shade(tracer, &block, &mut d[..words], &mut work, Some(t));
                table.write(slot, &d[..words]);
                let topped = &self.counters.topped_up;
                topped.fetch_add(work.cells as u64, Ordering::Relaxed);
                work.rays
            })
            .sum();
        young.clear();
        *self.cache.young.lock().expect("not poisoned") = young;
        times.since(TEXTURE_CACHE, start);
        rays
    }

    /// Shades `block`'s cells into their data `data` (count, channels per cell) by the
    /// temporal rule, or (`target`) each cell up to that many samples.
    pub(super) fn shade(
        &self,
        tracer: &PathTracer,
        block: &Block,
        data: &mut [f32],
        work: &mut Work,
        target: Option<u32>,
    ) {
        let ch = self.cfg.channels();
        let stride = 1 + ch;
        let world = tracer.world;
        let mut cells = 0;
        if target.is_none() && self.cfg.temporal == Temporal::Mean && self.cfg.reshade > 0.0 {
            let mean = block_mean(block, data, stride);
            let u = (hash(&[block.key(), self.frame as u64, self.seed]) >> 40) as f32
                / (1u64 << 24) as f32;
            if mean > 0.0 && u * mean >= self.cfg.reshade {
                return;
            }
        }
        // Each cell once, or (`target`) as many times as it lacks.
        let rounds = target.unwrap_or(1);
        for k in (0..rounds).flat_map(|_| 0..CELLS) {
            let Some(cell) = block.cell(k) else { continue };
            let d = &mut data[k * stride..(k + 1) * stride];
            let count = d[0] as u32;
            let limit = target.map_or(self.cfg.max_count, |t| t.min(self.cfg.max_count));
            if (self.cfg.temporal == Temporal::Mean || target.is_some()) && count >= limit {
                continue;
            }
            let (ray, hit) = self.grids.probe(world, &cell);
            let (surface, mut shading) = world.shaded(&ray, &hit, tracer.settings.microfacet);
            shading.params = BsdfParams::lambertian(Vec3::ONE);
            shading.alpha = 1.0;
            shading.volume = false;
            let vertex = Vertex {
                hit,
                surface,
                shading,
            };
            let key = cell.key();
            let sampler = PixelSampler::with_kind(
                tracer.settings.sampler,
                self.seed,
                key as u32,
                (key >> 32) as u32,
                count,
            );
            let rng = Rng::new(hash(&[self.seed, key]), count as u64);
            // Every light but the sun (`sky`) by next event estimation alone, from the
            // dimensions the path's would have taken; then no next event estimation at the
            // cell (with `indirect` its direct light is the pixel's own).
            let sky = (self.cfg.terms == CachedTerms::Sky).then(|| {
                let mut s = sampler.clone();
                s.set_dimension(CAMERA_DIMENSIONS);
                let (u_select, u) = (s.next_1d(), s.next_2d());
                let ls =
                    self.sun
                        .sample_with(&world.lights, Part::Sky, vertex.surface.p, u_select, u);
                let bsdf = world.bsdf(vertex.surface.material, &vertex.shading.params);
                let mut r = 0;
                let l = ls.map_or(Vec3::ZERO, |ls| {
                    tracer.light_alone(&vertex, &bsdf, -ray.direction, &ls, &mut r)
                });
                work.rays += r as u64;
                l
            });
            let direct = (self.cfg.terms != CachedTerms::All).then_some(Vec3::ZERO);
            let s = tracer.trace_lit::<false>(ray, Some(&vertex), sampler, rng, direct);
            work.rays += s.rays as u64;
            cells += 1;
            let mut v = [0.0f32; CHANNELS];
            let lum = pathlight_core::color::luminance(s.indirect);
            let indirect = match lum > self.clamp {
                true => s.indirect * (self.clamp / lum),
                false => s.indirect,
            };
            v[ch - 3..ch].copy_from_slice(&indirect.to_array());
            if let Some(sky) = sky {
                v[..3].copy_from_slice(&sky.to_array());
            } else if ch == 6 {
                let le = world.lights.emitted(
                    &world.scene,
                    cell.instance,
                    cell.triangle,
                    surface.bary,
                    -ray.direction,
                );
                v[..3].copy_from_slice(&(s.direct - le).max(Vec3::ZERO).to_array());
            }
            let w = match self.cfg.temporal {
                _ if count == 0 => 1.0,
                Temporal::Mean => 1.0 / (count + 1) as f32,
                Temporal::Exponential => 1.0 - self.cfg.temporal_alpha,
                Temporal::None => 1.0,
            };
            for c in 0..ch {
                d[1 + c] += (v[c] - d[1 + c]) * w;
            }
            d[0] = (count + 1) as f32;
        }
        work.cells += cells;
        self.counters
            .cells
            .fetch_add(cells as u64, Ordering::Relaxed);
    }
}

/// The mean sample count of `block`'s cells (those in its triangle) in its data `data`
/// (`stride` values per cell, the count first).
pub(super) fn block_mean(block: &Block, data: &[f32], stride: usize) -> f32 {
    let (mut sum, mut n) = (0.0f32, 0u32);
    for k in (0..CELLS).filter(|&k| block.cell(k).is_some()) {
        sum += data[k * stride];
        n += 1;
    }
    sum / n.max(1) as f32
}
