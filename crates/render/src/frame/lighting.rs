//! The lighting pass: path tracing from the G-buffer. Each pixel's first sample continues from
//! its G-buffer surface (next event estimation at every vertex, multiple importance sampling,
//! the configuration's bounce limit); further samples of the frame trace whole paths. Direct
//! and indirect light are kept apart (seed 001's split), with their running statistics over
//! the frame's samples, and the first sample's first bounce.

use glam::Vec3;

use crate::path::{Bounce, PathTracer};

use super::accumulation::PixelStats;
use super::gbuffer::PrimaryHit;

/// One pixel's lighting in one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LightSample {
    /// Statistics of the frame's samples of this pixel.
    pub stats: PixelStats,
    /// The first bounce of the frame's first sample.
    pub bounce: Bounce,
}

/// The lighting pass for one pixel: `spp` samples, indices `index..index + spp`; sample
/// `index` continues from `hit` (the primary pass's, same index). Returns the pixel's lighting
/// and the rays traced. `ALONG_FIRST_BOUNCE`: the first sample measures the radiance along
/// its first bounce ([`crate::path::Bounce::radiance`]). `first_direct`: that sample's direct
/// light at its first hit, given (ReSTIR's, [`PathTracer::trace_lit`]).
#[inline(always)]
pub fn lighting<const ALONG_FIRST_BOUNCE: bool>(
    tracer: &PathTracer,
    x: u32,
    y: u32,
    hit: &PrimaryHit,
    index: u32,
    spp: u32,
    first_direct: Option<Vec3>,
) -> (LightSample, u64) {
    let s = tracer.trace_lit::<ALONG_FIRST_BOUNCE>(
        hit.ray,
        hit.first.as_ref(),
        hit.sampler.clone(),
        hit.rng.clone(),
        first_direct,
    );
    let mut stats = PixelStats::one(s.direct, s.indirect);
    let mut rays = s.rays as u64;
    for k in 1..spp {
        let more = tracer.sample_pixel(x, y, index + k);
        stats.add(more.direct, more.indirect);
        rays += more.rays as u64;
    }
    (
        LightSample {
            stats,
            bounce: s.bounce,
        },
        rays,
    )
}

/// [`lighting`] with the first sample's radiance along its first bounce measured or not
/// (`along`), and no samples (an empty lighting) when `spp` is 0.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn light(
    tracer: &PathTracer,
    x: u32,
    y: u32,
    hit: &PrimaryHit,
    index: u32,
    spp: u32,
    along: bool,
    direct: Option<Vec3>,
) -> (LightSample, u64) {
    if spp == 0 {
        (LightSample::default(), 0)
    } else if along {
        lighting::<true>(tracer, x, y, hit, index, spp, direct)
    } else {
        lighting::<false>(tracer, x, y, hit, index, spp, direct)
    }
}
