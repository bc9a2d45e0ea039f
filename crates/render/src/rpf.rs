//! Random Parameter Filtering's input and run: the reference path tracer's samples as the
//! per-sample vectors RPF reads (seed 001's thesis, Table 5.1), then the filter
//! ([`pathlight_denoise::rpf`]).
//!
//! Each sample's vector: its film position (2, pixels); the random parameters lens u and v, the
//! first bounce's direction (x, y, z) and the first hit's three light-sampling numbers (which
//! light, where on it): the thesis's six less time (the path tracer has no motion blur), plus
//! the light sample's, without which the noise of soft shadows and direct light depends on no
//! random parameter RPF sees (the paper counts every random number of the path as a random
//! parameter; the thesis kept the lens, time and direction); the features of the first two vertices: world position (3) and shading normal
//! (3) of each, the first hit's base colour (3); the colour (3). A first bounce that leaves the
//! scene has its second vertex at a scene's diagonal along its direction, its normal facing
//! back (the paper is silent; the origin, as before 2026-11-26, made every reflection of the
//! environment one feature value); a camera ray that leaves it marks the sample as the sky's
//! ([`SampleSet::sky`]). Samples are exactly
//! [`crate::renderer`]'s, so the unfiltered mean of the set is `pathlight render`'s image at
//! the same settings.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use glam::Vec3;
use pathlight_denoise::rpf::{self, FeatureKind, SampleSet};
use pathlight_denoise::FilterError;
use rayon::prelude::*;

use crate::camera::Camera;
use crate::config::Config;
use crate::path::{CameraSample, PathTracer};
use crate::world::World;

/// Random parameters per sample vector.
pub const RANDOM: usize = 8;

/// The index of the first hit's base colour among the features.
const ALBEDO: usize = 12;

/// The feature kinds of the vector: positions and normals of two vertices, a base colour.
pub fn feature_kinds() -> Vec<FeatureKind> {
    use FeatureKind::{Other, Position};
    [Position; 3]
        .into_iter()
        .chain([Other; 3])
        .chain([Position; 3])
        .chain([Other; 3])
        .chain([Other; 3])
        .collect()
}

/// Traces `config.spp` samples of every pixel into RPF's vectors, in parallel over rows;
/// `progress` gets the samples each row added. None when `cancel` is raised.
pub fn trace(
    world: &World,
    camera: &Camera,
    config: &Config,
    cancel: &AtomicBool,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Option<SampleSet>, FilterError> {
    let (w, h, spp) = (
        config.width as usize,
        config.height as usize,
        config.spp as usize,
    );
    let mut set = SampleSet::new(w, h, spp, RANDOM, feature_kinds())?;
    set.albedo = Some(ALBEDO);
    let tracer = PathTracer {
        world,
        camera,
        settings: config.path_settings(),
    };
    let bounds = world.scene.bounds();
    let far = if bounds.is_empty() {
        1.0
    } else {
        bounds.diagonal().length().max(1e-3)
    };
    let stride = set.stride();
    set.sky = vec![false; w * h * spp];
    set.data
        .par_chunks_mut(w * spp * stride)
        .zip(set.sky.par_chunks_mut(w * spp))
        .enumerate()
        .for_each(|(y, (row, sky))| {
            if cancel.load(Ordering::Relaxed) {
                return;
            }
            for (i, (v, sky)) in row.chunks_exact_mut(stride).zip(sky).enumerate() {
                let (x, s) = ((i / spp) as u32, (i % spp) as u32);
                *sky = fill(&tracer, far, x, y as u32, s, v);
            }
            progress((w * spp) as u64);
        });
    Ok((!cancel.load(Ordering::Relaxed)).then_some(set))
}

/// Sample `index` of pixel (`x`, `y`), as [`PathTracer::sample_pixel`] traces it, into `v`;
/// whether it is of the sky (its camera ray hit nothing). A first bounce that leaves the
/// scene has its second vertex `far` along its direction, facing back (where the environment
/// it sees is; not the origin, which would make every reflection of the sky one feature).
fn fill(tracer: &PathTracer, far: f32, x: u32, y: u32, index: u32, v: &mut [f32]) -> bool {
    let CameraSample {
        ray,
        film,
        lens,
        sampler,
        mut rng,
    } = tracer.camera_sample(x, y, index);
    // The first vertex's light sample (`trace_lit`'s first draws, where the camera's end).
    let mut light_sampler = sampler.clone();
    let light = light_sampler.next_1d();
    let point = light_sampler.next_2d();
    let mut rays = 0;
    let first = tracer.intersect(ray, &mut rng, &mut rays);
    let sample = tracer.trace_from::<false>(ray, first.as_ref(), sampler, rng);
    let p1 = first.as_ref().map_or(Vec3::ZERO, |f| f.surface.p);
    let b = &sample.bounce;
    let (p2, n2) = if first.is_some() && b.normal == Vec3::ZERO && b.direction != Vec3::ZERO {
        (p1 + far * b.direction, -b.direction)
    } else {
        (b.position, b.normal)
    };
    let values = [film.x, film.y, lens.x, lens.y]
        .into_iter()
        .chain(b.direction.to_array())
        .chain([light, point.x, point.y])
        .chain(p1.to_array())
        .chain(sample.normal.to_array())
        .chain(p2.to_array())
        .chain(n2.to_array())
        .chain(sample.albedo.to_array())
        .chain(sample.radiance().to_array());
    for (o, value) in v.iter_mut().zip(values) {
        *o = value;
    }
    first.is_none()
}

/// Traces the samples and filters them: the filtered image and the unfiltered one (the mean of
/// the same samples), row-major; `progress` gets the fraction done (tracing counts as the
/// first tenth). None when cancelled while tracing; when cancelled while filtering, the
/// unfiltered image alone (`filtered` none).
pub fn render(
    world: &World,
    camera: &Camera,
    config: &Config,
    cancel: &AtomicBool,
    progress: &(dyn Fn(f32) + Sync),
) -> Result<Option<Rendered>, FilterError> {
    let total = config.width as f64 * config.height as f64 * config.spp as f64;
    let traced = AtomicU64::new(0);
    let t = std::time::Instant::now();
    let Some(set) = trace(world, camera, config, cancel, &|n| {
        let d = traced.fetch_add(n, Ordering::Relaxed) + n;
        progress((0.1 * d as f64 / total) as f32);
    })?
    else {
        return Ok(None);
    };
    let trace_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = std::time::Instant::now();
    let params = config.frame.filter.rpf_params(config.seed);
    let filtered = rpf::filter(&set, &params, cancel, &|f| progress(0.1 + 0.9 * f))?;
    let to_vec3 = |v: Vec<[f32; 3]>| v.into_iter().map(Vec3::from_array).collect();
    Ok(Some(Rendered {
        filtered: filtered.map(to_vec3),
        unfiltered: to_vec3(set.mean_image()),
        trace_ms,
        filter_ms: t.elapsed().as_secs_f64() * 1e3,
    }))
}

/// What [`render`] made.
pub struct Rendered {
    /// None when the filter was stopped.
    pub filtered: Option<Vec<Vec3>>,
    pub unfiltered: Vec<Vec3>,
    /// Wall-clock time of the tracing and of the filter.
    pub trace_ms: f64,
    pub filter_ms: f64,
}
