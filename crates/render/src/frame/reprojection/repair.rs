//! The repair pass (`fresh_spp`): the samples a pixel without enough history lacks, traced
//! in the frame of a move and merged into its lighting.

use rayon::prelude::*;

use crate::camera::Camera;
use crate::frame::accumulation::PixelStats;
use crate::frame::gbuffer::{GBuffer, GPixel};
use crate::frame::lighting::LightSample;
use crate::frame::trace::{self, Plan};
use crate::path::PathTracer;

/// Reprojection with `fresh_spp`, between the lighting and accumulation passes: a pixel
/// sampled this frame (or any pixel in the frame of a move) whose states the accumulation
/// pass will drop (the aliasing test after a
/// move, a carried state its new sample disagrees with) would be left with this frame's
/// samples alone, one where a hole takes `fresh_spp` (the lighting pass counted the states
/// before the test, which needs the neighbours' G-buffer pixels). This pass traces the
/// samples such pixels lack and merges them into their lighting, so that they show
/// `fresh_spp` samples in this frame rather than in the next.
#[derive(Debug, Default)]
pub struct Repair {
    /// Samples each pixel lacks (0: none).
    need: Vec<u32>,
    gbuffer: GBuffer,
    lighting: Vec<LightSample>,
}

impl Repair {
    /// Counts the missing samples (`fresh` less each sampled pixel's samples and those its
    /// states keep, `kept(pixel)`), traces them and merges them into `lighting`; returns the
    /// rays traced.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn run(
        &mut self,
        kept: impl Fn(usize) -> u32 + Sync,
        history: &[PixelStats],
        lighting: &mut [LightSample],
        gbuffer: &GBuffer,
        fresh: u32,
        after_move: bool,
        previous: Option<&Camera>,
        tracer: &PathTracer,
    ) -> u64 {
        self.need.resize(lighting.len(), 0);
        let missing: u64 = self
            .need
            .par_iter_mut()
            .zip(lighting.par_iter())
            .enumerate()
            .map(|(p, (need, l))| {
                // A pixel not sampled has no G-buffer pixel of this frame to test, except in
                // the frame of a move, where every pixel is traced (the combination's carried
                // pixels wait then, and their states may be dropped all the same).
                *need = if l.stats.n == 0 && !after_move {
                    0
                } else {
                    fresh.saturating_sub(kept(p) + l.stats.n)
                };
                u64::from(*need)
            })
            .sum();
        if missing == 0 {
            return 0;
        }
        self.gbuffer.resize(gbuffer.width, gbuffer.height);
        self.lighting.resize(lighting.len(), LightSample::default());
        let plan = Missing {
            need: &self.need,
            history,
            lighting,
        };
        let rays = trace::fused(
            &mut self.gbuffer,
            &mut self.lighting,
            previous,
            tracer,
            &plan,
        )
        .rays;
        lighting
            .par_iter_mut()
            .zip(self.lighting.par_iter())
            .zip(self.need.par_iter())
            .for_each(|((l, extra), &need)| {
                if need > 0 {
                    l.stats.merge(&extra.stats);
                }
            });
        rays
    }

    pub(super) fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.need.capacity() * size_of::<u32>()
            + self.gbuffer.pixels.capacity() * size_of::<GPixel>()
            + self.lighting.capacity() * size_of::<LightSample>()
    }
}

/// [`Repair`]'s pixels: the samples they lack, continuing their sample sequences after this
/// frame's.
struct Missing<'a> {
    need: &'a [u32],
    history: &'a [PixelStats],
    lighting: &'a [LightSample],
}

impl Plan for Missing<'_> {
    #[inline]
    fn sample(&self, pixel: usize) -> Option<u32> {
        (self.need[pixel] > 0).then(|| self.history[pixel].n + self.lighting[pixel].stats.n)
    }

    #[inline]
    fn keep(&self, pixel: usize, _: &GPixel) -> u32 {
        self.need[pixel]
    }
}
