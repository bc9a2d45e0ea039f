//! SVGF's a-trous passes ([`crate::svgf`]) over structure-of-arrays planes, 16 centre pixels at a
//! time in the lanes of [`crate::simd`] (one AVX-512 register, or 8 at a time in an AVX2 one,
//! with FMA, as the processor has them), one or two signals: the same weights and taps as the
//! scalar pass in `svgf.rs`, which stays as the reference (a test holds them together, for every
//! kind of lanes) and for passes too wide for the planes' padding.
//!
//! The planes carry a border of `pad` pixels (twice the widest hole) whose normal is zero, so a
//! tap that falls outside the image weighs exactly 0, as the scalar pass's bounds test gives;
//! the sky and light sources have a zero normal too (nobody's neighbour). Rows are
//! `[plane][pitch]` blocks, so each thread writes whole rows. A pass with holes of `step` rows
//! takes the rows of one class modulo `step` one after the other, so the rows its taps read stay
//! in the cache from one output row to the next (in image order, the holes of 8 and 16 rows
//! took a third longer than those of 1). Each 16-pixel group writes its result, the pixels that
//! pass through kept, and the luminances the next pass tests, in lanes (the last pass its light
//! alone: nothing reads its variance and luminance); the luminance test's
//! sigma (the blurred variance) is worked out in the group from the variance planes. A group
//! whose pixels all pass through does not run the kernel (an outdoor frame's sky).
//!
//! The passes are bound by their taps' dependency chains rather than by loads or arithmetic
//! (`llvm-mca` on the tap loop), so the loop is kept short: the taps' offsets, kernel weights
//! and distances are worked out once per pass ([`Tap`]); a weight's exponent is floored with
//! one `max` (the test of `MIN_WEIGHT` drops what the floor admits); and the group's
//! reciprocals (of the weights' sum, of the depth test's scales) are the processor's estimate
//! refined by a Newton step ([`F32xN::recip`]) instead of divisions, which one unit runs one
//! at a time. A tap's weight is one power of two, `2^(log2(h) + w_z + 128 log2(n.n') + w_l)`
//! (the kernel's weight `h`, the depth test's exponent and the luminance test's in base 2), so
//! the normal's `(n.n')^128` (seven squarings) and two products a signal become four fused
//! multiply-adds of `log2(1 - u)`'s series ([`log2_normal_weight_lanes`]; the scalar pass
//! keeps the paper's power; they agree to 1e-5 wherever a weight counts), and the 3x3
//! kernel's eight taps are written out, so their constants stay in registers (the a-trous
//! passes 15% faster together, measured at 9a555f4, 2026-11-28). So the lanes agree with the scalar
//! pass to rounding, not bit for bit.

use pathlight_core::color::LUMINANCE;
use rayon::prelude::*;
use std::f32::consts::LOG2_E;

use crate::simd::{dispatch, exp2_neg_in_range, iota, store_first, F32xN, Isa, Kernel, LANES};

/// Widest padding the planes take: holes up to 32 pixels with the 5x5 kernel (six passes), 64
/// with the 3x3 one (seven).
pub const MAX_PAD: usize = 64;

/// How far the a-trous kernel `kernel` pixels wide (3, else 5) reaches from its centre, in
/// holes: 1 or 2.
pub fn radius(kernel: u32) -> usize {
    if kernel == 3 {
        1
    } else {
        2
    }
}

/// The 1D weights at offsets 0, 1, 2 of the a-trous kernel `kernel` pixels wide: the B3
/// spline of the paper (5), or the linear B-spline `1/4, 1/2, 1/4` (3: a third of the taps, as
/// several real-time implementations use; not in the paper).
pub fn spline(kernel: u32) -> [f32; 3] {
    if kernel == 3 {
        [0.5, 0.25, 0.0]
    } else {
        [3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0]
    }
}

// Static planes (per frame).
const Z: usize = 0;
const NX: usize = 1;
const G: usize = 4;
/// 1 where the pixel passes through (the sky and light sources), else 0.
const THROUGH: usize = 5;
const STATIC: usize = 6;
// Dynamic planes (per pass) of `S` signals (direct and indirect light, or their sum): each
// signal's rgb, then each one's variance, then each one's luminance.
const L: usize = 0;
/// The first variance plane of `S` signals.
const fn v(signals: usize) -> usize {
    3 * signals
}
/// The first luminance plane of `S` signals.
const fn lum(signals: usize) -> usize {
    4 * signals
}
/// The dynamic planes of `S` signals.
const fn dynamic(signals: usize) -> usize {
    5 * signals
}

/// The variance blur's 3x3 taps (dx, dy, weight), row by row (the order both passes sum in).
pub const BLUR: [(i64, i64, f32); 9] = [
    (-1, -1, 0.0625),
    (0, -1, 0.125),
    (1, -1, 0.0625),
    (-1, 0, 0.125),
    (0, 0, 0.25),
    (1, 0, 0.125),
    (-1, 1, 0.0625),
    (0, 1, 0.125),
    (1, 1, 0.0625),
];

/// A padded plane layout.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Grid {
    width: usize,
    height: usize,
    pad: usize,
    pitch: usize,
    planes: usize,
}

impl Grid {
    fn new(width: usize, height: usize, pad: usize, planes: usize) -> Self {
        Self {
            width,
            height,
            pad,
            pitch: width + 2 * pad + LANES,
            planes,
        }
    }

    fn row(&self) -> usize {
        self.pitch * self.planes
    }

    fn len(&self) -> usize {
        self.row() * (self.height + 2 * self.pad)
    }

    /// Runs `f(y, row)` on every image row of `buffer` (a buffer of this layout), in parallel;
    /// the border's rows are left alone.
    fn for_rows(&self, buffer: &mut [f32], f: impl Fn(i64, &mut [f32]) + Sync) {
        self.for_rows_by(buffer, 1, f);
    }

    /// Runs `f(y, row)` on every image row of `buffer` (the border's rows left alone), in
    /// parallel, in the order a pass with holes of `step` rows reuses best: the rows of one
    /// class modulo `step` one after the other (so the rows a tap reads stay in the cache from
    /// one output row to the next, as with `step` 1), in tasks of a few rows.
    fn for_rows_by(&self, buffer: &mut [f32], step: usize, f: impl Fn(i64, &mut [f32]) + Sync) {
        const TASK: usize = 16;
        let (pad, h) = (self.pad, self.height);
        let mut classes: Vec<Vec<(i64, &mut [f32])>> = (0..step).map(|_| Vec::new()).collect();
        for (py, row) in buffer.chunks_mut(self.row()).enumerate() {
            if (pad..pad + h).contains(&py) {
                let y = py - pad;
                classes[y % step].push((y as i64, row));
            }
        }
        classes.par_iter_mut().for_each(|class| {
            class.par_chunks_mut(TASK).for_each(|rows| {
                for (y, row) in rows {
                    f(*y, row);
                }
            })
        });
    }

    /// Index of pixel (x, y) (image coordinates, may reach into the border) in plane `p`.
    #[inline(always)]
    fn at(&self, x: i64, y: i64, p: usize) -> usize {
        ((y + self.pad as i64) as usize) * self.row()
            + p * self.pitch
            + (x + self.pad as i64) as usize
    }
}

/// The planes of one frame's a-trous passes.
#[derive(Default)]
pub struct Planes {
    fixed: Grid,
    moving: Grid,
    /// Signals filtered (1 or 2): the first `signals` of [`Inputs::light`].
    signals: usize,
    /// The widest lanes the passes use (narrower ones for tests).
    pub isa: Isa,
    statics: Vec<f32>,
    current: Vec<f32>,
    next: Vec<f32>,
}

/// Where plane `p` of a padded row of `grid` lies in the row, from the image's first column
/// on, with [`LANES`] columns of padding at least past the image's last one (where a writer
/// writes only zeros: the padding stays zero).
fn plane(grid: &Grid, p: usize) -> std::ops::Range<usize> {
    p * grid.pitch + grid.pad..(p + 1) * grid.pitch
}

/// One image row of the light's planes, which [`Planes::load_light_rows`] gives to its caller.
pub struct LightRow<'a> {
    row: &'a mut [f32],
    grid: Grid,
    /// The signals laid out (1 or 2).
    pub signals: usize,
}

impl LightRow<'_> {
    fn plane(&mut self, p: usize) -> &mut [f32] {
        &mut self.row[plane(&self.grid, p)]
    }

    /// Channel `k` of signal `s`'s light.
    pub fn light(&mut self, s: usize, k: usize) -> &mut [f32] {
        self.plane(L + 3 * s + k)
    }

    /// Signal `s`'s luminance variance.
    pub fn variance(&mut self, s: usize) -> &mut [f32] {
        let p = v(self.signals) + s;
        self.plane(p)
    }

    /// Both signals' luminance variances (the second empty with one signal).
    pub fn variances(&mut self) -> [&mut [f32]; 2] {
        let (first, second) = (plane(&self.grid, v(self.signals)), v(self.signals) + 1);
        let (head, tail) = self.row.split_at_mut(second * self.grid.pitch);
        let second = if self.signals == 2 {
            &mut tail[self.grid.pad..self.grid.pitch]
        } else {
            &mut []
        };
        [&mut head[first], second]
    }

    /// Signal `s`'s luminance.
    pub fn luminance(&mut self, s: usize) -> &mut [f32] {
        let p = lum(self.signals) + s;
        self.plane(p)
    }
}

/// One image row of the features' planes, which [`Planes::load_statics_rows`] gives to its
/// caller.
pub struct StaticRow<'a> {
    row: &'a mut [f32],
    grid: Grid,
}

impl StaticRow<'_> {
    fn plane(&mut self, p: usize) -> &mut [f32] {
        &mut self.row[plane(&self.grid, p)]
    }

    /// Depth along the view axis.
    pub fn depth(&mut self) -> &mut [f32] {
        self.plane(Z)
    }

    /// |grad z|.
    pub fn gradient(&mut self) -> &mut [f32] {
        self.plane(G)
    }

    /// 1 where the pixel passes through (the sky and light sources: nobody's neighbour), else 0.
    pub fn through(&mut self) -> &mut [f32] {
        self.plane(THROUGH)
    }

    /// Component `k` of the normal (0 where the pixel passes through).
    pub fn normal(&mut self, k: usize) -> &mut [f32] {
        self.plane(NX + k)
    }
}

/// This frame's features' planes, read-only, which [`Planes::amend_variance`] gives to its
/// caller: an image row's plane from its first column on (with [`LANES`] columns at least
/// past its last).
#[derive(Clone, Copy)]
pub struct StaticsView<'a> {
    statics: &'a [f32],
    grid: Grid,
}

impl<'a> StaticsView<'a> {
    fn plane(&self, y: usize, p: usize) -> &'a [f32] {
        let g = &self.grid;
        &self.statics[(y + g.pad) * g.row()..][..g.row()][plane(g, p)]
    }

    /// Row `y`'s depth along the view axis.
    pub fn depth(&self, y: usize) -> &'a [f32] {
        self.plane(y, Z)
    }

    /// Component `k` of row `y`'s normal (0 where the pixel passes through).
    pub fn normal(&self, y: usize, k: usize) -> &'a [f32] {
        self.plane(y, NX + k)
    }

    /// 1 where row `y`'s pixel passes through, else 0.
    pub fn through(&self, y: usize) -> &'a [f32] {
        self.plane(y, THROUGH)
    }
}

/// One image row of the current light's planes and of the plane of the pixels that pass
/// through, which [`Planes::for_light_rows`] gives to its caller.
pub struct LightView<'a> {
    light: &'a [f32],
    statics: &'a [f32],
    grid: Grid,
    fixed: Grid,
    /// The signals laid out (1 or 2).
    pub signals: usize,
}

impl LightView<'_> {
    /// Channel `k` of signal `s`'s light.
    pub fn light(&self, s: usize, k: usize) -> &[f32] {
        &self.light[plane(&self.grid, L + 3 * s + k)]
    }

    /// 1 where the pixel passes through, else 0.
    pub fn through(&self) -> &[f32] {
        &self.statics[plane(&self.fixed, THROUGH)]
    }
}

impl Planes {
    /// Lays the planes out for a `width x height` image, passes whose taps reach up to `reach`
    /// pixels from their centre (the kernel's radius times the widest holes; at least 1, the
    /// variance blur's; at most [`MAX_PAD`]) and `signals` (1 or 2) signals. The padding is
    /// zeroed when the layout changes; the passes write the image's pixels only, so it stays
    /// zero.
    pub fn layout(&mut self, width: usize, height: usize, reach: usize, signals: usize) {
        let pad = reach.max(1);
        debug_assert!(pad <= MAX_PAD && (1..=2).contains(&signals));
        self.signals = signals;
        let (fixed, moving) = (
            Grid::new(width, height, pad, STATIC),
            Grid::new(width, height, pad, dynamic(signals)),
        );
        if (fixed, moving) != (self.fixed, self.moving) || self.statics.len() != fixed.len() {
            (self.fixed, self.moving) = (fixed, moving);
            self.statics.clear();
            self.statics.resize(fixed.len(), 0.0);
            for buffer in [&mut self.current, &mut self.next] {
                buffer.clear();
                buffer.resize(moving.len(), 0.0);
            }
        }
    }

    /// Lays out this frame's features row by row (after [`Self::layout`]): `f(y, row)` writes
    /// image row `y`'s.
    pub fn load_statics_rows(&mut self, f: impl Fn(usize, StaticRow) + Sync) {
        let fixed = self.fixed;
        fixed.for_rows(&mut self.statics, |y, row| {
            f(y as usize, StaticRow { row, grid: fixed })
        });
    }

    /// Lays out the light, its luminance variance and luminance row by row: `f(y, extra, row)`
    /// writes image row `y`'s (`extra` is the row's part of `extra`, as many entries a row);
    /// what it returns, row by row.
    pub fn load_light_rows<T: Send, R: Send>(
        &mut self,
        extra: &mut [T],
        f: impl Fn(usize, &mut [T], LightRow) -> R + Sync,
    ) -> Vec<R> {
        let g = self.moving;
        let (pad, signals) = (g.pad, self.signals);
        self.current[pad * g.row()..(pad + g.height) * g.row()]
            .par_chunks_mut(g.row())
            .zip(extra.par_chunks_mut(row_len(extra.len(), g.height)))
            .enumerate()
            .map(|(y, (row, extra))| {
                let row = LightRow {
                    row,
                    grid: g,
                    signals,
                };
                f(y, extra, row)
            })
            .collect()
    }

    /// Lets `amend(y, row, features)` amend the light's planes of the rows `y` where
    /// `rows[y]` (their variances, where the history is short; the other rows have none),
    /// with this frame's features' planes to read (after [`Self::load_statics_rows`]).
    pub fn amend_variance(
        &mut self,
        rows: &[bool],
        amend: impl Fn(usize, LightRow, StaticsView) + Sync,
    ) {
        let (g, signals) = (self.moving, self.signals);
        let features = StaticsView {
            statics: &self.statics,
            grid: self.fixed,
        };
        g.for_rows(&mut self.current, |y, row| {
            if rows[y as usize] {
                let row = LightRow {
                    row,
                    grid: g,
                    signals,
                };
                amend(y as usize, row, features);
            }
        });
    }

    /// `f(y, out_row, view)` of every image row `y`, the row's part of `out` (as many entries
    /// a row) and a view of its current light.
    pub fn for_light_rows<T: Send>(
        &self,
        out: &mut [T],
        f: impl Fn(usize, &mut [T], LightView) + Sync,
    ) {
        let (g, fixed) = (self.moving, self.fixed);
        out.par_chunks_mut(row_len(out.len(), g.height))
            .enumerate()
            .for_each(|(y, row)| {
                let (py, pf) = (
                    g.at(-(g.pad as i64), y as i64, 0),
                    fixed.at(-(g.pad as i64), y as i64, 0),
                );
                let view = LightView {
                    light: &self.current[py..py + g.row()],
                    statics: &self.statics[pf..pf + fixed.row()],
                    grid: g,
                    fixed,
                    signals: self.signals,
                };
                f(y, row, view)
            });
    }

    /// One pass of a kernel `kernel` pixels wide (3 or 5) with holes of `step` pixels:
    /// `current` filtered into `next`, then swapped. With `last`, only the light is written
    /// (the variance and the luminance that a next pass would test are left as they were).
    pub fn pass(&mut self, kernel: u32, step: usize, sigma_l: f32, sigma_z: f32, last: bool) {
        let g = self.moving;
        let reach = radius(kernel) * step;
        let r = radius(kernel) as i64;
        // What makes the passes' unchecked loads (`Pass::lanes`) safe: every tap of the
        // kernel with holes of `step` (and the variance blur's) lies within the padding.
        assert!(
            reach <= g.pad && g.pad == self.fixed.pad,
            "holes of {step} pixels need a padding of {reach}, the planes have {}",
            g.pad
        );
        let h = spline(kernel);
        let row = |g: &Grid, kx: i64, ky: i64| {
            (g.at(kx * step as i64, ky * step as i64, 0) as isize) - g.at(0, 0, 0) as isize
        };
        let taps: Vec<Tap> = (-r..=r)
            .flat_map(|ky| (-r..=r).map(move |kx| (kx, ky)))
            .filter(|&k| k != (0, 0))
            .map(|(kx, ky)| Tap {
                fixed: row(&self.fixed, kx, ky),
                moving: row(&g, kx, ky),
                log2_kernel: (h[kx.unsigned_abs() as usize] * h[ky.unsigned_abs() as usize]).log2(),
                distance: SQUARED_DISTANCES
                    .iter()
                    .position(|&d| d == kx * kx + ky * ky)
                    .expect("a 3x3 or 5x5 tap"),
            })
            .collect();
        // The 3x3 kernel's taps, row by row, at distances 1 (sides) and sqrt 2 (corners):
        // `Pass::sums` writes them out in this order.
        debug_assert!(kernel != 3 || taps.iter().map(|t| t.distance).eq([1, 0, 1, 0, 0, 1, 0, 1]));
        let pass = Pass {
            taps,
            fixed: self.fixed,
            moving: g,
            statics: &self.statics,
            sigma_l,
            current: &self.current,
            step: step as i64,
            sigma_z,
            wide: kernel != 3,
            signals: self.signals,
            variance: !last,
            isa: self.isa,
        };
        g.for_rows_by(&mut self.next, step, |y, row| pass.row(y, row));
        std::mem::swap(&mut self.current, &mut self.next);
    }
}

/// A row's part of a buffer of `len` entries for an image `height` rows high.
fn row_len(len: usize, height: usize) -> usize {
    assert!(
        len.is_multiple_of(height) && len > 0,
        "{len} entries for {height} rows"
    );
    len / height
}

struct Pass<'a> {
    fixed: Grid,
    moving: Grid,
    statics: &'a [f32],
    current: &'a [f32],
    step: i64,
    sigma_l: f32,
    sigma_z: f32,
    /// The 5x5 kernel (else 3x3).
    wide: bool,
    signals: usize,
    /// The variance and the luminance are written (not by the last pass, whose light alone is
    /// read): the taps' squared weights summed.
    variance: bool,
    /// The widest lanes to use.
    isa: Isa,
    /// The kernel's taps but the centre, row by row (the order the scalar pass sums in).
    taps: Vec<Tap>,
}

/// A tap of a pass, worked out once per pass: where it lies from the centre in each layout,
/// its kernel weight and its distance's depth term.
#[derive(Clone, Copy)]
struct Tap {
    fixed: isize,
    moving: isize,
    /// The kernel's weight, as a power of two.
    log2_kernel: f32,
    /// Index of the tap's distance in [`SQUARED_DISTANCES`] (and the depth terms).
    distance: usize,
}

/// The squared distances of a 3x3 kernel's taps from its centre (the first two) and a 5x5
/// one's, in holes: the depth test's term is worked out once per distance and group.
const SQUARED_DISTANCES: [i64; 5] = [1, 2, 4, 5, 8];

/// The weighted sums of [`LANES`] centre pixels for `S` signals.
struct Sums<V, const S: usize> {
    w: [V; S],
    light: [[V; 3]; S],
    var: [V; S],
}

/// One output row of a pass, run with lanes `V` ([`crate::simd::dispatch`]).
struct Row<'p, 'a> {
    pass: &'p Pass<'a>,
    y: i64,
    row: &'p mut [f32],
}

impl Kernel<()> for Row<'_, '_> {
    #[inline(always)]
    fn run<V: F32xN>(self) {
        let (p, y, row) = (self.pass, self.y, self.row);
        match (p.wide, p.signals, p.variance) {
            (true, 2, true) => p.row_lanes::<V, 2, 2, true>(y, row),
            (false, 2, true) => p.row_lanes::<V, 1, 2, true>(y, row),
            (true, _, true) => p.row_lanes::<V, 2, 1, true>(y, row),
            (false, _, true) => p.row_lanes::<V, 1, 1, true>(y, row),
            (true, 2, false) => p.row_lanes::<V, 2, 2, false>(y, row),
            (false, 2, false) => p.row_lanes::<V, 1, 2, false>(y, row),
            (true, _, false) => p.row_lanes::<V, 2, 1, false>(y, row),
            (false, _, false) => p.row_lanes::<V, 1, 1, false>(y, row),
        }
    }
}

impl Pass<'_> {
    /// Row `y` of the output into `row` (its `[plane][pitch]` block).
    fn row(&self, y: i64, row: &mut [f32]) {
        dispatch(self.isa, Row { pass: self, y, row });
    }

    #[inline(always)]
    fn row_lanes<V: F32xN, const R: i64, const S: usize, const VAR: bool>(
        &self,
        y: i64,
        row: &mut [f32],
    ) {
        for x0 in (0..self.moving.width).step_by(V::N) {
            self.group::<V, R, S, VAR>(x0 as i64, y, row);
        }
    }

    /// The [`LANES`] values of `buffer` from `at` on, without a bounds check: a pass reads its
    /// taps 14 times, and the checks (two per read) were a sixth of its instructions.
    ///
    /// # Safety
    /// `at + LANES <= buffer.len()`. [`Planes::pass`] asserts that the holes fit the
    /// padding, so every index [`Grid::at`] gives for a tap of a centre group (x in
    /// `0..width` by 16, y in `0..height`) is inside its plane's padded row.
    #[inline(always)]
    unsafe fn lanes<V: F32xN>(buffer: &[f32], at: usize) -> V {
        debug_assert!(at + LANES <= buffer.len());
        // SAFETY: the caller's contract.
        unsafe { V::load(buffer.as_ptr().add(at)) }
    }

    /// Plane `p` of the statics at the 16 pixels from (x, y) on.
    #[inline(always)]
    fn st<V: F32xN>(&self, p: usize, x: i64, y: i64) -> V {
        self.st_at(p, self.fixed.at(x, y, 0))
    }

    /// Plane `p` of the statics at the 16 pixels from index `at` (of plane 0) on: a pixel's
    /// [`Grid::at`], or a centre's plus a [`Tap`]'s offset.
    #[inline(always)]
    fn st_at<V: F32xN>(&self, p: usize, at: usize) -> V {
        // SAFETY: the taps lie within the padding (asserted by `Planes::pass`), the centre
        // group within the image.
        unsafe { Self::lanes(self.statics, at + p * self.fixed.pitch) }
    }

    /// Plane `p` of the current light, variance and luminance at the 16 pixels from (x, y) on.
    #[inline(always)]
    fn dy<V: F32xN>(&self, p: usize, x: i64, y: i64) -> V {
        self.dy_at(p, self.moving.at(x, y, 0))
    }

    /// [`Self::st_at`] for the current light, variance and luminance.
    #[inline(always)]
    fn dy_at<V: F32xN>(&self, p: usize, at: usize) -> V {
        // SAFETY: as in `st_at`.
        unsafe { Self::lanes(self.current, at + p * self.moving.pitch) }
    }

    /// The sum of the variance blur's weights ([`BLUR`]) over the pixels inside the image, at
    /// the [`LANES`] pixels from (x0, y) on: the blur is (1/4, 1/2, 1/4) across times the same
    /// down, so the sum is the product of the two's sums inside (exactly: sixteenths).
    #[inline(always)]
    fn blur_inside<V: F32xN>(&self, x0: i64, y: i64) -> V {
        let (w, h) = (self.moving.width, self.moving.height);
        let (zero, quarter) = (V::splat(0.0), V::splat(0.25));
        let x = V::splat(x0 as f32) + iota::<V>();
        let first = V::select(x.ne(zero), zero, quarter);
        let last = V::select(x.ne(V::splat((w - 1) as f32)), zero, quarter);
        let down =
            1.0 - if y == 0 { 0.25 } else { 0.0 } - if y + 1 == h as i64 { 0.25 } else { 0.0 };
        (V::splat(1.0) - first - last) * V::splat(down)
    }

    /// The [`LANES`] pixels from (x0, y) on filtered by a kernel of radius `R` (1: 3x3, 2: 5x5)
    /// over `S` signals into `row`: the weighted means, the pixels that pass through kept as
    /// they are, and (with `VAR`) the variances and the luminances of the result. (No closures
    /// here: see `simd::exp2_neg_in_range`.)
    #[inline(always)]
    fn group<V: F32xN, const R: i64, const S: usize, const VAR: bool>(
        &self,
        x0: i64,
        y: i64,
        row: &mut [f32],
    ) {
        let g = self.moving;
        let (v, lum) = (v(S), lum(S));
        let through_plane = self.st::<V>(THROUGH, x0, y);
        let through = through_plane.ne(V::splat(0.0));
        // A group whose pixels all pass through (the sky of an outdoor frame; lanes past the
        // row's end do not) keeps them without running the kernel (the sums are not used).
        let s = if V::any(through_plane.ne(V::splat(1.0))) {
            self.sums::<V, R, S, VAR>(x0, y)
        } else {
            let (one, zero) = (V::splat(1.0), V::splat(0.0));
            Sums {
                w: [one; S],
                light: [[zero; 3]; S],
                var: [zero; S],
            }
        };
        let n = V::N.min(g.width - x0 as usize);
        let [r, gr, b] = [
            V::splat(LUMINANCE[0]),
            V::splat(LUMINANCE[1]),
            V::splat(LUMINANCE[2]),
        ];
        for sig in 0..S {
            let mut c = [V::splat(0.0); 3];
            let mut out = [V::splat(0.0); 5];
            // The sum of weights is at least the centre's (9/64 or 1/4).
            let inv_w = s.w[sig].recip();
            for k in 0..3 {
                let p = L + 3 * sig + k;
                c[k] = V::select(through, self.dy(p, x0, y), s.light[sig][k] * inv_w);
                out[k] = c[k];
            }
            let l = L + 3 * sig;
            let planes = if VAR {
                let var = s.var[sig] * inv_w * inv_w;
                out[3] = V::select(through, self.dy(v + sig, x0, y), flush_variance_lanes(var));
                out[4] = c[0] * r + c[1] * gr + c[2] * b;
                5
            } else {
                3
            };
            for (value, p) in out
                .into_iter()
                .zip([l, l + 1, l + 2, v + sig, lum + sig])
                .take(planes)
            {
                // In the image's last group the lanes past its width are left alone (the
                // padding stays zero).
                store_first(value, n, &mut row[p * g.pitch + g.pad + x0 as usize..]);
            }
        }
    }

    /// The weighted sums of a kernel of radius `R` over the [`LANES`] pixels from (x0, y) on,
    /// for `S` signals (the variance's only with `VAR`).
    #[inline(always)]
    fn sums<V: F32xN, const R: i64, const S: usize, const VAR: bool>(
        &self,
        x0: i64,
        y: i64,
    ) -> Sums<V, S> {
        let h = spline(2 * R as u32 + 1);
        let (v, lum) = (v(S), lum(S));
        let splat = V::splat;
        let zc: V = self.st(Z, x0, y);
        let gz: V = self.st(G, x0, y);
        let nc: [V; 3] = [
            self.st(NX, x0, y),
            self.st(NX + 1, x0, y),
            self.st(NX + 2, x0, y),
        ];
        // The centre tap: the kernel's weight whatever the tests say.
        let kc = splat(h[0] * h[0]);
        let mut s = Sums {
            w: [kc; S],
            var: [kc; S],
            light: [[kc; 3]; S],
        };
        let mut lc = [kc; S];
        // The luminance test's `-log2(e) / (sigma_l sqrt(g(var)) + 1e-4)` (its exponent in
        // base 2), g the variance's 3x3
        // Gaussian over the pixels inside the image (the scalar pass's: the border's zeros add
        // nothing, and `blur_inside` is the same normalisation, summed in the same order).
        let mut minus_inv = [kc; S];
        let sum: V = self.blur_inside(x0, y);
        for sig in 0..S {
            lc[sig] = self.dy(lum + sig, x0, y);
            s.var[sig] = self.dy::<V>(v + sig, x0, y) * kc * kc;
            for k in 0..3 {
                s.light[sig][k] = self.dy::<V>(L + 3 * sig + k, x0, y) * kc;
            }
            let mut g = splat(0.0);
            for &(dx, dy, k) in &BLUR {
                g = self.dy::<V>(v + sig, x0 + dx, y + dy).mul_add(splat(k), g);
            }
            minus_inv[sig] =
                splat(-LOG2_E) / (splat(self.sigma_l) * (g / sum).sqrt() + splat(1e-4));
        }
        let step = self.step;
        // The depth test's `-log2(e) / (sigma_z |grad z| |p - q| + 1e-4 z)` (base 2) for the
        // distances the taps have (|k|^2 = 1, 2, and with the 5x5 kernel 4, 5, 8).
        let mut minus_rz = [kc; 5];
        for (d, rz) in minus_rz
            .iter_mut()
            .enumerate()
            .take(if R == 1 { 2 } else { 5 })
        {
            let distance = (SQUARED_DISTANCES[d] as f32).sqrt() * step as f32;
            // Finite and positive wherever the centre does not pass through (the others'
            // lanes are replaced by the centre's own values).
            *rz = (splat(self.sigma_z * distance) * gz + splat(1e-4) * zc).recip() * splat(-LOG2_E);
        }
        let cut = Cut {
            floor: splat(-30.0 * LOG2_E),
            min: splat(MIN_WEIGHT),
        };
        let (cf, cm) = (self.fixed.at(x0, y, 0), self.moving.at(x0, y, 0));
        let centre = Centre {
            zc,
            nc,
            lc,
            minus_inv,
            cf,
            cm,
        };
        if R == 1 {
            // The 3x3 kernel's eight taps written out: the distances' depth terms and the
            // kernel's weights stay in registers (as a loop they were reloaded, and the
            // sums spilled, at every tap).
            let [a, b, c, d, e, f, g, h]: &[Tap; 8] =
                self.taps[..].try_into().expect("a 3x3 kernel's taps");
            let (side, corner) = (minus_rz[0], minus_rz[1]);
            self.tap::<V, S, VAR>(&mut s, &centre, a, corner, &cut);
            self.tap::<V, S, VAR>(&mut s, &centre, b, side, &cut);
            self.tap::<V, S, VAR>(&mut s, &centre, c, corner, &cut);
            self.tap::<V, S, VAR>(&mut s, &centre, d, side, &cut);
            self.tap::<V, S, VAR>(&mut s, &centre, e, side, &cut);
            self.tap::<V, S, VAR>(&mut s, &centre, f, corner, &cut);
            self.tap::<V, S, VAR>(&mut s, &centre, g, side, &cut);
            self.tap::<V, S, VAR>(&mut s, &centre, h, corner, &cut);
        } else {
            for tap in &self.taps {
                self.tap::<V, S, VAR>(&mut s, &centre, tap, minus_rz[tap.distance], &cut);
            }
        }
        s
    }

    /// Adds `tap` of the centres `c` to the sums `s` of `S` signals (`minus_rz`: the depth
    /// test's term at the tap's distance).
    #[inline(always)]
    fn tap<V: F32xN, const S: usize, const VAR: bool>(
        &self,
        s: &mut Sums<V, S>,
        c: &Centre<V, S>,
        tap: &Tap,
        minus_rz: V,
        cut: &Cut<V>,
    ) {
        let (v, lum) = (v(S), lum(S));
        let (qf, qm) = (
            c.cf.wrapping_add_signed(tap.fixed),
            c.cm.wrapping_add_signed(tap.moving),
        );
        // The tap's weight but the luminance test's, as a power of two: the kernel's, the
        // depth test's and the normal's, `cos^128` = `2^(128 log2(cos))`.
        let z = (self.st_at::<V>(Z, qf) - c.zc).abs();
        let base = z.mul_add(minus_rz, V::splat(tap.log2_kernel));
        let cos = self.st_at::<V>(NX, qf) * c.nc[0];
        let cos = self.st_at::<V>(NX + 1, qf).mul_add(c.nc[1], cos);
        let cos = self.st_at::<V>(NX + 2, qf).mul_add(c.nc[2], cos);
        let g = log2_normal_weight_lanes(cos, base);
        for sig in 0..S {
            let lq: V = self.dy_at(lum + sig, qm);
            let e = (lq - c.lc[sig]).abs().mul_add(c.minus_inv[sig], g);
            // Every lane's product is worked out, so none may be subnormal: the exponent at
            // least -30 log2(e), a weight of 9.4e-14, under `MIN_WEIGHT`: 0, as the scalar
            // pass's `e > -30` test gives (a NaN exponent is floored too).
            let t = exp2_neg_in_range(e.at_least(cut.floor));
            let wq = V::select(t.ge(cut.min), t, V::splat(0.0));
            s.w[sig] = s.w[sig] + wq;
            for k in 0..3 {
                let l: V = self.dy_at(L + 3 * sig + k, qm);
                s.light[sig][k] = l.mul_add(wq, s.light[sig][k]);
            }
            if VAR {
                s.var[sig] = (self.dy_at::<V>(v + sig, qm) * wq).mul_add(wq, s.var[sig]);
            }
        }
    }
}

/// What a group's taps compare with: its centres' depth, normal, luminances and the
/// luminance test's scales, and where they lie in each layout.
struct Centre<V, const S: usize> {
    zc: V,
    nc: [V; 3],
    lc: [V; S],
    minus_inv: [V; S],
    cf: usize,
    cm: usize,
}

/// A tap's exponent's floor and the weight below which it counts for nothing, in lanes.
struct Cut<V> {
    floor: V,
    min: V,
}

/// A tap's weight below which it counts for nothing (the centre's is at least 9/64, so a
/// smaller weight changes no sum by more than its rounding). Products of smaller weights
/// (with the light, squared with the variance) could be subnormal numbers, whose arithmetic
/// is slow on many processors (a pass took up to 6x its time on an Intel Xeon of these
/// machines).
pub const MIN_WEIGHT: f32 = 1e-10;

// A tap whose exponent is at most -30 weighs at most e^-30 = 9.36e-14 (the kernel's and the
// normal's weights are at most 1): under `MIN_WEIGHT`, so the passes need not test the exponent
// apart.
const _: () = assert!(MIN_WEIGHT > 9.36e-14);

/// A luminance variance below which it is 0 (its root, 1e-8, is nothing beside the luminance
/// test's 1e-4): with [`MIN_WEIGHT`], no product of the passes is subnormal.
pub const MIN_VARIANCE: f32 = 1e-16;

/// `variance`, or 0 below [`MIN_VARIANCE`] (and for NaN).
#[inline(always)]
pub fn flush_variance(variance: f32) -> f32 {
    if variance >= MIN_VARIANCE {
        variance
    } else {
        0.0
    }
}

/// [`flush_variance`] in lanes.
#[inline(always)]
pub(crate) fn flush_variance_lanes<V: F32xN>(variance: V) -> V {
    V::select(variance.ge(V::splat(MIN_VARIANCE)), variance, V::splat(0.0))
}

/// Below this cosine the normal weight is 0 (`0.8^128` is 4e-13, under [`MIN_WEIGHT`]).
const MIN_COSINE: f32 = 0.8;

/// `base + 128 log2(cos)`, the normal weight's [`normal_weight`] exponent in base 2 added to
/// `base`, in lanes, `u = 1 - cos`: `log2(1 - u)` by its series to `u^4`. What it leaves out
/// is about `128 u^5 / 5` of the natural exponent, a weight's relative error of 8e-6 at `u =
/// 0.05` (where the weight is 1.4e-3 of an equal normal's), under the exponential's own 2e-5
/// wherever a weight counts. It needs no test of [`MIN_COSINE`]: below it the series is
/// under -41 (-41.19 at `u = 0.2`, falling as `u` grows), and a pass's `base` is at most -3
/// (the kernel's largest weight but the centre's, 1/8), so the tap's weight is under 2^-44,
/// below [`MIN_WEIGHT`]: 0, as the scalar pass's test gives (a NaN cosine gives a NaN exponent,
/// which the tap's floor makes a weight under [`MIN_WEIGHT`] too).
#[inline(always)]
pub(crate) fn log2_normal_weight_lanes<V: F32xN>(cos: V, base: V) -> V {
    const K: f32 = 128.0 * LOG2_E;
    let u = V::splat(1.0) - cos;
    // base + 128 log2(1 - u) = base - K (u + u^2 / 2 + u^3 / 3 + u^4 / 4), by Horner.
    let a = V::splat(-K / 4.0).mul_add(u, V::splat(-K / 3.0));
    let a = a.mul_add(u, V::splat(-K / 2.0));
    let a = a.mul_add(u, V::splat(-K));
    a.mul_add(u, base)
}

/// [`normal_weight`] in lanes.
#[inline(always)]
pub(crate) fn normal_weight_lanes<V: F32xN>(cos: V) -> V {
    let mut w = V::select(cos.ge(V::splat(MIN_COSINE)), cos, V::splat(0.0));
    for _ in 0..7 {
        w = w * w;
    }
    w
}

/// `max(0, cos)^128` by repeated squaring; 0 below a cosine of [`MIN_COSINE`] (and for NaN).
#[inline(always)]
pub fn normal_weight(cos: f32) -> f32 {
    let mut w = if cos >= MIN_COSINE { cos } else { 0.0 };
    for _ in 0..7 {
        w *= w;
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{dispatch, Isa, Kernel};

    /// Below [`MIN_COSINE`] (and for NaN) the normal's series, with the largest `base` a pass
    /// gives a tap (-3), floored as a tap floors it, is a weight under [`MIN_WEIGHT`]: the
    /// passes need no test of the cosine.
    #[test]
    fn the_normal_series_weighs_nothing_below_the_least_cosine() {
        struct Check;
        impl Kernel<()> for Check {
            fn run<V: F32xN>(self) {
                let floor = V::splat(-30.0 * LOG2_E);
                let cosines = (0..)
                    .map(|k| -1.0 + k as f32 * 1e-4)
                    .take_while(|&c| c < MIN_COSINE)
                    .chain([f32::NAN, f32::NEG_INFINITY, -1e30]);
                let mut largest = 0.0f32;
                for cos in cosines {
                    let e = log2_normal_weight_lanes(V::splat(cos), V::splat(-3.0));
                    let w = exp2_neg_in_range(e.at_least(floor)).to_array()[0];
                    largest = largest.max(w);
                }
                assert!(largest < MIN_WEIGHT, "a weight of {largest}");
                // And at the least cosine itself the series still counts.
                let e = log2_normal_weight_lanes(V::splat(MIN_COSINE), V::splat(0.0));
                let w = exp2_neg_in_range(e.at_least(floor)).to_array()[0];
                let exact = normal_weight(MIN_COSINE);
                assert!((w - exact).abs() < 0.01 * exact, "{w} against {exact}");
            }
        }
        for isa in [Isa::Portable, Isa::Avx2, Isa::Avx512] {
            dispatch(isa, Check);
        }
    }
}
