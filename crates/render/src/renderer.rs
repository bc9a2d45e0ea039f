//! Runs the path tracer over a film in passes of samples, in parallel over bands of rows.
//! Each pixel's samples are taken in index order and depend only on (seed, pixel, index), so
//! the film is the same whatever the thread count, and a render stopped between (or during)
//! passes continues exactly where it stopped.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use crate::camera::Camera;
use crate::config::Config;
use crate::film::Film;
use crate::path::PathTracer;
use crate::world::World;

/// Rows per parallel task.
const BAND_ROWS: usize = 4;

/// Brings every pixel of `film` up to `target` samples (pixels already there are left alone).
/// Checks `cancel` before each band of rows; calls `progress` with the samples each band added.
/// Returns false when cancelled (some bands then have fewer samples than `target`).
pub fn render_pass(
    world: &World,
    camera: &Camera,
    config: &Config,
    film: &mut Film,
    target: u32,
    cancel: &AtomicBool,
    progress: &(dyn Fn(u64) + Sync),
) -> bool {
    render_range_pass(world, camera, config, film, 0, target, cancel, progress)
}

/// As [`render_pass`] for a film that holds sample indices from `first` on (a partial render,
/// [`crate::part`]): a pixel's `k`-th sample is sample index `first + k`.
#[allow(clippy::too_many_arguments)]
pub fn render_range_pass(
    world: &World,
    camera: &Camera,
    config: &Config,
    film: &mut Film,
    first: u32,
    target: u32,
    cancel: &AtomicBool,
    progress: &(dyn Fn(u64) + Sync),
) -> bool {
    let tracer = PathTracer {
        world,
        camera,
        settings: config.path_settings(),
    };
    let width = film.width as usize;
    film.pixels
        .par_chunks_mut(width * BAND_ROWS)
        .enumerate()
        .for_each(|(band, pixels)| {
            if cancel.load(Ordering::Relaxed) {
                return;
            }
            let mut added = 0u64;
            for (i, pixel) in pixels.iter_mut().enumerate() {
                let x = (i % width) as u32;
                let y = (band * BAND_ROWS + i / width) as u32;
                while pixel.n < target {
                    pixel.add(&tracer.sample_pixel(x, y, first + pixel.n));
                    added += 1;
                }
            }
            progress(added);
        });
    !cancel.load(Ordering::Relaxed)
}

/// Renders a whole image at `config.spp` without progress reports.
pub fn render(world: &World, camera: &Camera, config: &Config) -> Film {
    let mut film = Film::new(config.width, config.height);
    render_pass(
        world,
        camera,
        config,
        &mut film,
        config.spp,
        &AtomicBool::new(false),
        &|_| {},
    );
    film
}

/// Sample counts for successive passes up to `spp`: small passes first (a quick preview and
/// fine-grained checkpoints), then steps of at most `max_step` samples.
pub fn pass_targets(start: u32, spp: u32, max_step: u32) -> Vec<u32> {
    let mut out = Vec::new();
    let mut n = start;
    let mut step = 1;
    while n < spp {
        n = (n + step).min(spp);
        out.push(n);
        step = (step * 2).min(max_step.max(1));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pass_targets_grow_and_end_at_spp() {
        assert_eq!(pass_targets(0, 20, 8), vec![1, 3, 7, 15, 20]);
        assert_eq!(pass_targets(5, 5, 8), Vec::<u32>::new());
        assert_eq!(pass_targets(0, 1, 8), vec![1]);
    }
}
