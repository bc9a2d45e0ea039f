//! The texel cache: each block of texels filtered once a frame from the sample cache's cells
//! around it ([`super::samples`]), within its triangle (the window narrowing as the cells
//! gather samples; a Gaussian, a box, or a linear regression over the squares' places), and
//! kept for the frame's other lookups; each thread remembers the last blocks it read.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use crate::path::PathTracer;

use super::samples::{block_mean, SampleFrame, Status, Work};
use super::settings::{CacheFilter, CHANNELS, MAX_KERNEL};
use super::table::{Block, Claim, Table, BLOCK, CELLS, SQUARES};

/// The texel cache across frames: its table, and what it holds this frame.
#[derive(Default)]
pub(super) struct TexelCache {
    pub(super) table: Table,
    /// What the table holds this frame, unique over every cache of the process and frame
    /// ([`GENERATIONS`]): the tag of the threads' [`TexelMemo`] entries.
    pub(super) generation: u64,
}

/// The texel cache as one frame's lighting pass reads and fills it, over its sample cache.
pub(super) struct TexelFrame<'a> {
    pub(super) samples: SampleFrame<'a>,
    pub(super) cache: &'a TexelCache,
}

/// The source of [`TexelCache::generation`] (0: no table).
pub(super) static GENERATIONS: AtomicU64 = AtomicU64::new(1);

/// Entries of a thread's [`TexelMemo`].
const MEMO: usize = 64;

/// A thread's last texel blocks read this frame, direct-mapped by key: a pixel's four
/// texels, and the next pixels' (a block covers a few pixels each way), are found without
/// the table's hash, probe and checks. An entry is the table's data for its block at its
/// generation, so what it gives is what the table would.
struct TexelMemo([(u64, u64, [f32; SQUARES * CHANNELS]); MEMO]);

thread_local! {
    static TEXEL_MEMO: std::cell::RefCell<TexelMemo> =
        const { std::cell::RefCell::new(TexelMemo([(0, 0, [0.0; SQUARES * CHANNELS]); MEMO])) };
}

impl TexelFrame<'_> {
    /// The filtered texels of `block`'s squares into `out` (channels per square): found
    /// filtered this frame, or filtered here (into the slot claimed, or without the cache when
    /// its set is full).
    pub(super) fn texel_block(
        &self,
        tracer: &PathTracer,
        block: &Block,
        out: &mut [f32; SQUARES * CHANNELS],
        work: &mut Work,
    ) -> Status {
        let (bkey, frame) = (block.key(), self.samples.frame);
        let generation = self.cache.generation;
        let slot = (bkey.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 58) as usize % MEMO;
        let remembered = TEXEL_MEMO.with_borrow(|m| {
            let (g, k, data) = &m.0[slot];
            let found = *g == generation && *k == bkey;
            if found {
                *out = *data;
            }
            found
        });
        if remembered {
            return Status::Hit;
        }
        let remember = |out: &[f32; SQUARES * CHANNELS]| {
            TEXEL_MEMO.with_borrow_mut(|m| m.0[slot] = (generation, bkey, *out));
        };
        let texels = &mut out[..SQUARES * self.samples.cfg.channels()];
        let table = &self.cache.table;
        loop {
            match table.claim(bkey, frame) {
                Claim::Ready(i, s) => {
                    table.read(i, texels);
                    if table.still(i, s, frame) {
                        remember(out);
                        return Status::Hit;
                    }
                }
                Claim::Busy => std::thread::yield_now(),
                claim => {
                    let t = Instant::now();
                    self.filter(tracer, block, texels, work);
                    self.samples.counters.time(t);
                    let Claim::Mine(i, _) = claim else {
                        return Status::Uncached;
                    };
                    table.write(i, texels);
                    table.publish(i, bkey, frame);
                    self.samples.counters.texels.fetch_add(1, Ordering::Relaxed);
                    remember(out);
                    return Status::Miss;
                }
            }
        }
    }

    /// The filtered texels of `block`'s squares into `out` (channels per square): the
    /// separable window over the squares of the blocks around it, each square the mean of its
    /// shaded halves, clipped to the triangle and renormalised. The window narrows with the
    /// block's own cells' samples (`shrink`), and only the blocks it reaches are read.
    /// Neighbouring blocks being shaded by other threads are deferred and read last.
    fn filter(&self, tracer: &PathTracer, block: &Block, out: &mut [f32], work: &mut Work) {
        let ch = self.samples.cfg.channels();
        let stride = 1 + ch;
        // The block's own cells first: their mean sample count narrows the window.
        let mut own = [0.0f32; CELLS * (1 + CHANNELS)];
        self.samples.sample_block(tracer, block, &mut own, work);
        let mut weights = [0.0f32; MAX_KERNEL as usize];
        let weights = self.weights(block_mean(block, &own, stride), &mut weights);
        let radius = (weights.len() / 2) as i32;
        let reach = (radius + BLOCK as i32 - 1) / BLOCK as i32;
        let side = (2 * reach + 1) as usize;
        // The squares of the (2 reach + 1)^2 blocks around: per square, channel sums and the
        // weight (halves shaded).
        let w = side * BLOCK as usize;
        // Per-thread scratch (the filter runs once per texel block and frame).
        let (mut grid, mut rows) = SCRATCH.with_borrow_mut(std::mem::take);
        grid.clear();
        grid.resize(w * w * (ch + 1), 0.0);
        let mut cells = [0.0f32; CELLS * (1 + CHANNELS)];
        let mut deferred = Vec::new();
        let gather = |b: &Block, cells: &[f32], grid: &mut [f32]| {
            let ox = (b.at.x as i32 - block.at.x as i32 + reach) as usize * BLOCK as usize;
            let oy = (b.at.y as i32 - block.at.y as i32 + reach) as usize * BLOCK as usize;
            for k in 0..CELLS {
                if b.cell(k).is_none() {
                    continue;
                }
                let d = &cells[k * stride..(k + 1) * stride];
                if d[0] <= 0.0 {
                    continue;
                }
                let sq = (k / 2) as u32;
                let (sx, sy) = ((sq % BLOCK) as usize, (sq / BLOCK) as usize);
                let g = &mut grid[((oy + sy) * w + ox + sx) * (ch + 1)..][..ch + 1];
                for c in 0..ch {
                    g[c] += d[1 + c];
                }
                g[ch] += 1.0;
            }
        };
        gather(block, &own, &mut grid);
        for dy in -reach..=reach {
            for dx in -reach..=reach {
                let Some(b) = block.beside(dx, dy).filter(|_| (dx, dy) != (0, 0)) else {
                    continue;
                };
                match self.samples.try_sample_block(tracer, &b, &mut cells, work) {
                    Some(_) => gather(&b, &cells, &mut grid),
                    None => deferred.push(b),
                }
            }
        }
        for b in deferred {
            self.samples.sample_block(tracer, &b, &mut cells, work);
            gather(&b, &cells, &mut grid);
        }
        let lo = reach as usize * BLOCK as usize;
        let order = match self.samples.cfg.filter {
            CacheFilter::Linear => 2,
            _ => 0,
        };
        convolve(&grid, w, lo, weights, ch, order, &mut rows, out);
        SCRATCH.with_borrow_mut(|s| *s = (grid, rows));
    }

    /// The filter's 1D weights over its window for cells of `n` samples on average: a box of
    /// radius `radius n^-shrink` or a Gaussian of deviation `kernel / 4 n^-shrink` (at least a
    /// tenth of a square) over two deviations each side; at most `kernel` wide.
    fn weights<'w>(&self, n: f32, out: &'w mut [f32; MAX_KERNEL as usize]) -> &'w [f32] {
        let radius = (self.samples.cfg.kernel / 2) as i32;
        let narrow = n.max(1.0).powf(-self.samples.cfg.shrink);
        let sigma = (self.samples.cfg.kernel as f32 / 4.0 * narrow).max(0.1);
        let reach = radius as f32 * narrow + 0.5;
        // The window's half-width narrows with it (the Gaussian's stays two deviations; the
        // box's is its reach), so that the blocks past it are not read.
        let half = match self.samples.cfg.filter {
            CacheFilter::Gaussian | CacheFilter::Linear => (2.0 * sigma).ceil() as i32,
            _ => (reach.max(1.0) - 1e-3).floor() as i32,
        }
        .clamp(0, radius);
        let out = &mut out[..(2 * half + 1) as usize];
        for (o, d) in out.iter_mut().zip(-half..=half) {
            *o = match self.samples.cfg.filter {
                CacheFilter::Gaussian | CacheFilter::Linear => {
                    (-(d * d) as f32 / (2.0 * sigma * sigma)).exp()
                }
                _ => f32::from((d.abs() as f32) < reach.max(1.0)),
            };
        }
        out
    }
}

/// The filter's window applied to `grid` (`w` x `w` squares, each its channels' sums and its
/// weight: `ch + 1` values) at the block's squares (`lo` squares from the grid's corner), into
/// `out` (`ch` values per square), separably: along x over the rows the block's squares need
/// (into `rows`), then along y. `order` 0: the window's weighted mean; 2: a weighted linear
/// regression over the squares' places, read at the square's own (the window's first and
/// second moments along each axis: a gradient across the window, or the window cut short by
/// its triangle's edge, no longer biases the texel toward the side that has more squares).
#[allow(clippy::too_many_arguments)]
pub(super) fn convolve(
    grid: &[f32],
    w: usize,
    lo: usize,
    weights: &[f32],
    ch: usize,
    order: usize,
    rows: &mut Vec<f32>,
    out: &mut [f32],
) {
    let b = BLOCK as usize;
    let radius = (weights.len() / 2) as i32;
    let g1 = ch + 1;
    // Per row and square: sum over x of weight * d^p * value, p = 0..=order.
    let record = (order + 1) * g1;
    rows.clear();
    rows.resize(w * b * record, 0.0);
    for y in 0..w {
        for x in 0..b {
            let o = &mut rows[(y * b + x) * record..][..record];
            for (t, &wt) in weights.iter().enumerate() {
                let sx = (lo + x) as i32 + t as i32 - radius;
                if sx < 0 || sx >= w as i32 {
                    continue;
                }
                let g = &grid[(y * w + sx as usize) * g1..][..g1];
                let d = (t as i32 - radius) as f32;
                let mut wd = wt;
                for p in 0..=order {
                    for c in 0..g1 {
                        o[p * g1 + c] += wd * g[c];
                    }
                    wd *= d;
                }
            }
        }
    }
    for sy in 0..b {
        for sx in 0..b {
            // m[q][p]: sum of weight * dx^p * dy^q * value, p + q <= order.
            let mut m = [[[0.0f32; 1 + CHANNELS]; 3]; 3];
            for (t, &wt) in weights.iter().enumerate() {
                let y = (lo + sy) as i32 + t as i32 - radius;
                if y < 0 || y >= w as i32 {
                    continue;
                }
                let r = &rows[(y as usize * b + sx) * record..][..record];
                let e = (t as i32 - radius) as f32;
                let mut we = wt;
                for (q, mq) in m.iter_mut().enumerate().take(order + 1) {
                    for (p, mp) in mq.iter_mut().enumerate().take(order + 1 - q) {
                        for (v, x) in mp.iter_mut().zip(&r[p * g1..(p + 1) * g1]) {
                            *v += we * x;
                        }
                    }
                    we *= e;
                }
            }
            let o = &mut out[(sy * b + sx) * ch..][..ch];
            let n = m[0][0][ch];
            if n <= 0.0 {
                o.fill(0.0);
                continue;
            }
            // The linear model's intercept by the first row of the normal equations' inverse
            // (cofactors), the slopes damped (ridge) so that a window of few squares, or of
            // squares along a line, falls back toward the mean.
            let solve = |m: &[[[f32; 1 + CHANNELS]; 3]; 3]| {
                let (a, bb, cc) = (n, m[0][1][ch], m[1][0][ch]);
                let (d, e, f) = (
                    m[0][2][ch] + RIDGE * n,
                    m[1][1][ch],
                    m[2][0][ch] + RIDGE * n,
                );
                let (c0, c1, c2) = (d * f - e * e, cc * e - bb * f, bb * e - cc * d);
                let det = a * c0 + bb * c1 + cc * c2;
                (det > 1e-6 * a * d * f).then(|| [c0 / det, c1 / det, c2 / det])
            };
            match (order == 2).then(|| solve(&m)).flatten() {
                Some(k) => {
                    for c in 0..ch {
                        o[c] = (k[0] * m[0][0][c] + k[1] * m[0][1][c] + k[2] * m[1][0][c]).max(0.0);
                    }
                }
                _ => {
                    let norm = 1.0 / n;
                    for c in 0..ch {
                        o[c] = m[0][0][c] * norm;
                    }
                }
            }
        }
    }
}

/// The linear regression's damping of its slopes: added to the window's second moments, in
/// squares squared times its weight.
const RIDGE: f32 = 0.25;

thread_local! {
    /// The filter's scratch, per thread: the window's squares, and its rows filtered along x.
    static SCRATCH: std::cell::RefCell<(Vec<f32>, Vec<f32>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}
