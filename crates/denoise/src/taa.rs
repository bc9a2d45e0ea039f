//! Temporal antialiasing of a filtered image, the last stage of SVGF's pipeline (the paper
//! applies it after remodulation; it is not part of the filter itself): each pixel's output
//! is blended with the previous output at the place its surface was (`motion`), the previous
//! value first clamped to the box of this frame's 3x3 neighbourhood (its mean plus and minus
//! half a standard deviation in YCoCg, "variance clipping"), so a disocclusion or a change of
//! light takes the new value instead of trailing the old one. The box and the blend are in
//! light compressed by its luminance (`c / (1 + Y)`, as real-time renderers' TAA does with
//! HDR input), so a light source's radiance is not smeared over its neighbours (in linear
//! light the Cornell box's relMSE along its orbit rose 19x).
//!
//! ```text
//! image, motion, last output -> image blended with its clamped history (alpha 0.3)
//! ```
//!
//! At one sample per pixel the frame's albedo and geometry are one point of the pixel, which
//! moves with the pixel's jitter: the blend averages those points over frames (antialiasing,
//! and a texture that no longer flickers), which remodulating with one frame's albedo cannot.
//! Choices: bilinear taps of the history (the paper's implementations use bilinear or
//! bicubic), the box at `gamma` 0.5 and `alpha` 0.3 (chosen on two orbits; a common TAA takes
//! 1 and 0.1, which blur more behind a moving camera: FLIP rose 10%); a pixel whose every tap
//! falls outside the image, or whose motion is not finite, takes this frame's value.
//!
//! The blend runs in lanes ([`F32xN`], 16 pixels at a time with AVX-512), the same
//! arithmetic in the same order as the scalar `pixel`, which stays the reference it is tested
//! against bit for bit (and runs for images of 2^24 pixels or more, whose indices an `f32`
//! lane does not hold). The box's sums along rows are planes, three rows of which a group
//! loads (they were records, gathered); the history keeps its three channels as planes a row
//! (SVGF's history's layout), whose taps a group reads as `simd::Fetch` says: loads
//! where they are consecutive pixels, two loads permuted where they lie on one row, gathers
//! elsewhere; each row's output replaces its input in place (no copy); a row's values in
//! YCoCg and their sums along it are worked out in one sweep. 3.3 -> 2.3 ms at 640x360
//! (measured at a102cf4, 2026-11-28).

use glam::{Vec2, Vec3};
use pathlight_core::color::luminance;
use rayon::prelude::*;

use crate::simd::{
    self, channels, dispatch, iota, load_first, luminance_lanes, max, min, ByGroups, F32xN, Fetch,
    Groups, Isa, LANES,
};

/// The sums of a pixel's 3x3 box: its values (compressed, in YCoCg), their squares, the count.
const SUMS: usize = 7;

/// The length of a plane of the rows' sums of an image `width` pixels wide.
fn pitch(width: usize) -> usize {
    width + LANES
}

/// The weight of this frame's value in the blend (chosen on the orbits of the Cornell box and
/// the garden among 0.1, 0.2 and 0.3 at fbe1294, 2026-11-27).
pub const ALPHA: f32 = 0.3;
/// The history is clamped to the neighbourhood's mean plus and minus `GAMMA` standard
/// deviations (chosen for SVGF's output among 0.35, 0.5, 0.75 and 1).
pub const GAMMA: f32 = 0.5;

/// The last output, kept across frames, and scratch.
#[derive(Default)]
pub struct Taa {
    width: usize,
    height: usize,
    /// Last frame's output (empty: none), its three channels a row after one another (row
    /// `y`'s channel `c` from `(3 y + c) width` on, as SVGF's history), then `2 LANES`
    /// floats that only the lanes a group leaves out read (whole loads past the last row).
    history: Vec<f32>,
    /// This frame's, for the next.
    next: Vec<f32>,
    /// Their sums along each row's 3 pixels: the values, their squares and the count, as
    /// seven planes a row, each [`pitch`] long (the tail read only by lanes past the row's
    /// end, whose sums are not used: whole loads of lanes).
    rows: Vec<f32>,
    /// The blend in scalar code (the reference the lanes are tested against).
    scalar: bool,
    /// The widest lanes the blend uses (narrower ones for tests).
    isa: Isa,
    /// This frame's weight in the blend, if not [`ALPHA`].
    alpha: Option<f32>,
    /// The box's half-width in standard deviations, if not [`GAMMA`].
    gamma: Option<f32>,
}

impl Taa {
    /// Forgets the history (the next frame is kept as it is).
    pub fn reset(&mut self) {
        self.history.clear();
    }

    /// This frame's weight in the blend, in (0, 1] (the default, 0.3, was chosen for SVGF's
    /// output: a higher weight trails less behind a moving camera and smooths less).
    pub fn set_alpha(&mut self, alpha: f32) {
        self.alpha = Some(alpha);
    }

    /// The clamping box's half-width in standard deviations of the neighbourhood, > 0 (the
    /// default, 0.5, was chosen for SVGF's output: a wider box keeps more of the history,
    /// smoothing more and trailing more behind a change).
    pub fn set_gamma(&mut self, gamma: f32) {
        self.gamma = Some(gamma);
    }

    /// Blends in scalar code instead of lanes (the same arithmetic; for tests).
    #[doc(hidden)]
    pub fn set_scalar(&mut self, scalar: bool) {
        self.scalar = scalar;
    }

    /// Caps the blend's lanes at AVX2 (`avx2`) or plain arrays (`portable`) (for tests).
    #[doc(hidden)]
    pub fn set_lanes(&mut self, lanes: &str) {
        self.isa = Isa::named(lanes);
    }

    /// Blends `image` (`width x height`, row-major) with the history through `motion` (where
    /// each pixel's surface was on the previous frame minus where it is, in pixels), then
    /// keeps the result as the next frame's history.
    pub fn apply(&mut self, image: &mut [Vec3], motion: &[Vec2], width: usize, height: usize) {
        let n = width * height;
        debug_assert!(image.len() == n && motion.len() == n);
        let len = 3 * n + 2 * LANES;
        if (self.width, self.height) != (width, height) || self.history.len() != len {
            (self.width, self.height) = (width, height);
            self.history.resize(len, 0.0);
            self.history[..3 * n]
                .par_chunks_mut(3 * width)
                .zip(image.par_chunks(width))
                .for_each(|(planes, row)| keep_row(row, planes));
            return;
        }
        self.next.resize(len, 0.0);
        let pitch = pitch(width);
        self.rows.resize(SUMS * pitch * height, 0.0);
        // Row by row: its pixels compressed and in YCoCg, and 1 (0 for a pixel that is not
        // finite: its four values are 0), then their sums along the row (one sweep: the values
        // stay in the cache).
        self.rows
            .par_chunks_mut(SUMS * pitch)
            .zip(image.par_chunks(width))
            .for_each_init(Vec::new, |values, (row, pixels)| {
                values.clear();
                values.extend(pixels.iter().map(|c| {
                    let y = ycocg(compress(*c));
                    if y.is_finite() {
                        [y.x, y.y, y.z, 1.0]
                    } else {
                        [0.0; 4]
                    }
                }));
                for x in 0..width {
                    // Three taps, the border's outside one weighing 0 (a fixed form that the
                    // compiler keeps in registers).
                    let (l, r) = (x.saturating_sub(1), (x + 1).min(width - 1));
                    let (wl, wr) = (
                        f32::from(u8::from(x > 0)),
                        f32::from(u8::from(x + 1 < width)),
                    );
                    let (a, c, b) = (values[l], values[x], values[r]);
                    let mut acc = [0.0f32; 7];
                    for k in 0..3 {
                        acc[k] = a[k] * wl + c[k] + b[k] * wr;
                        acc[3 + k] = a[k] * a[k] * wl + c[k] * c[k] + b[k] * b[k] * wr;
                    }
                    acc[6] = a[3] * wl + c[3] + b[3] * wr;
                    for (k, a) in acc.into_iter().enumerate() {
                        row[k * pitch + x] = a;
                    }
                }
            });
        let (history, rows) = (&self.history, &self.rows);
        // (In lanes the pixels' indices are `f32`s, exact below 2^24.)
        let (lanes, isa) = (!self.scalar && n < 1 << 24, self.isa);
        let size = (width, height);
        let alpha = self.alpha.unwrap_or(ALPHA);
        let gamma = self.gamma.unwrap_or(GAMMA);
        // Each row's output in place of its input (a pixel reads only its own value; its
        // neighbourhood is in `rows`), and kept for the next frame.
        image
            .par_chunks_mut(width)
            .zip(self.next[..3 * n].par_chunks_mut(3 * width))
            .enumerate()
            .for_each(|(y, (out, kept))| {
                if lanes {
                    let b = Blend {
                        history,
                        motion,
                        rows,
                        pitch,
                        size,
                        y,
                        alpha,
                        gamma,
                        out,
                    };
                    dispatch(isa, ByGroups(b));
                } else {
                    for (x, out) in out.iter_mut().enumerate() {
                        let mut sums = [0.0f32; 7];
                        for qy in y.saturating_sub(1)..(y + 2).min(height) {
                            for (k, s) in sums.iter_mut().enumerate() {
                                *s += rows[(qy * SUMS + k) * pitch + x];
                            }
                        }
                        *out = pixel(
                            *out,
                            &sums,
                            history,
                            motion[y * width + x],
                            (size, alpha, gamma),
                            (x, y),
                        );
                    }
                }
                keep_row(out, kept);
            });
        std::mem::swap(&mut self.history, &mut self.next);
    }
}

/// Image row `row` into its three planes `planes` of the history's layout.
fn keep_row(row: &[Vec3], planes: &mut [f32]) {
    let w = row.len();
    for (c, plane) in planes.chunks_exact_mut(w).enumerate() {
        for (p, v) in plane.iter_mut().zip(row) {
            *p = v[c];
        }
    }
}

/// The output of pixel `at` of an image of `size`, whose value is `c` and whose 3x3 neighbourhood's sums are
/// `sums` (the values compressed and in YCoCg, their squares, the count), blended with weight
/// `alpha`.
fn pixel(
    c: Vec3,
    sums: &[f32; 7],
    history: &[f32],
    motion: Vec2,
    (size, alpha, gamma): ((usize, usize), f32, f32),
    at: (usize, usize),
) -> Vec3 {
    if !c.is_finite() {
        return c;
    }
    let Some(h) = reproject(history, motion, size.0, size.1, at.0, at.1) else {
        return c;
    };
    // The neighbourhood's box (its finite values: the centre's at least).
    let inv = 1.0 / sums[6];
    let mean = Vec3::new(sums[0], sums[1], sums[2]) * inv;
    let square = Vec3::new(sums[3], sums[4], sums[5]) * inv;
    let sigma = (square - mean * mean).max(Vec3::ZERO).sqrt();
    let c = ycocg(compress(c));
    // The box stretched to hold this frame's value (a pixel beside an edge is not pulled
    // towards its neighbourhood's mean).
    let (low, high) = (mean - gamma * sigma, mean + gamma * sigma);
    let clamped = ycocg(compress(h)).clamp(low.min(c), high.max(c));
    // (A box's corner in YCoCg may lie a little outside the RGB cube.)
    expand(rgb(clamped + (c - clamped) * alpha).max(Vec3::ZERO))
}

/// Light compressed into [0, 1) by its luminance, `c / (1 + Y)`, in which the box and the
/// blend are worked out: a bright pixel (a light source, a firefly) then weighs as much as a
/// white one, not its radiance's worth, and is not smeared over its neighbours.
pub fn compress(c: Vec3) -> Vec3 {
    c * (1.0 / (1.0 + luminance(c).max(0.0)))
}

/// The inverse of [`compress`].
pub fn expand(c: Vec3) -> Vec3 {
    c * (1.0 / (1.0 - luminance(c).clamp(0.0, 0.999)))
}

/// [`pixel`] of row `y`'s pixels in lanes, [`F32xN::N`] at a time, into `out` (the row's):
/// the same arithmetic in the same order, so the same numbers. (No closures here: see
/// `simd::exp2_neg_in_range`.)
struct Blend<'a> {
    history: &'a [f32],
    motion: &'a [Vec2],
    rows: &'a [f32],
    pitch: usize,
    size: (usize, usize),
    y: usize,
    alpha: f32,
    gamma: f32,
    out: &'a mut [Vec3],
}

impl Groups for Blend<'_> {
    fn width(&self) -> usize {
        self.size.0
    }

    #[inline(always)]
    fn group<V: F32xN>(&mut self, x0: usize) -> bool {
        let ((w, h), y) = (self.size, self.y);
        let n = V::N.min(w - x0);
        let splat = V::splat;
        let (zero, one) = (splat(0.0), splat(1.0));
        let lane = iota::<V>();
        let valid = splat(n as f32).gt(lane);
        let xs = splat(x0 as f32) + lane;
        // The 3x3 box's sums: the rows' sums of the rows around.
        let pitch = self.pitch;
        let mut sums = [zero; SUMS];
        for qy in y.saturating_sub(1)..(y + 2).min(h) {
            let row = &self.rows[qy * SUMS * pitch..];
            for (k, s) in sums.iter_mut().enumerate() {
                // (Past the row's end the planes' tails are zeros.)
                *s = *s + load_first::<V>(&row[k * pitch + x0..]);
            }
        }
        let c: [V; 3] = channels(self.out, x0, n);
        let [mx, my] = channels(self.motion, y * w + x0, n);
        // The history's bilinear value ([`reproject`]).
        let (px, py) = (xs + mx, splat(y as f32) + my);
        let moves = V::and(valid, V::and(simd::finite(px), simd::finite(py)));
        let (x0f, y0f) = (px.floor(), py.floor());
        let (fx, fy) = (px - x0f, py - y0f);
        let mut sum = [zero; 3];
        let mut weight = zero;
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            let bx = if dx == 0.0 { one - fx } else { fx };
            let by = if dy == 0.0 { one - fy } else { fy };
            let wt = bx * by;
            let (qx, qy) = (x0f + splat(dx), y0f + splat(dy));
            let inside = V::and(
                V::and(V::and(moves, wt.gt(zero)), V::and(qx.ge(zero), qy.ge(zero))),
                V::and(splat(w as f32).gt(qx), splat(h as f32).gt(qy)),
            );
            if !V::any(inside) {
                continue;
            }
            let fetch = Fetch::new(qx, qy, inside, 3 * w, 2 * w, self.history.len());
            // SAFETY: the lanes where `inside` are pixels of the image (`qx` in `0..w`, `qy`
            // in `0..h`, whole numbers), whose three channels are in the history (as large as
            // the image's), at indices under 2^24 + 2^25.
            // (No closures here: see `simd::exp2_neg_in_range`.)
            let t: [V; 3] = unsafe {
                [
                    fetch.read(self.history, 0, qx, qy, 3 * w, inside),
                    fetch.read(self.history, w, qx, qy, 3 * w, inside),
                    fetch.read(self.history, 2 * w, qx, qy, 3 * w, inside),
                ]
            };
            let take = V::and(inside, simd::finite3(t));
            for (s, t) in sum.iter_mut().zip(t) {
                *s = V::select(take, *s + t * wt, *s);
            }
            weight = V::select(take, weight + wt, weight);
        }
        let blends = V::and(simd::finite3(c), weight.ge(splat(1e-3)));
        let r = one / weight;
        let past = [sum[0] * r, sum[1] * r, sum[2] * r];
        // The box and the blend ([`pixel`]).
        let inv = one / sums[6];
        let now = ycocg_lanes(compress_lanes(c));
        let past = ycocg_lanes(compress_lanes(past));
        let mut blend = [zero; 3];
        for k in 0..3 {
            let mean = sums[k] * inv;
            let square = sums[3 + k] * inv;
            let sigma = max(square - mean * mean, zero).sqrt();
            let (low, high) = (
                mean - splat(self.gamma) * sigma,
                mean + splat(self.gamma) * sigma,
            );
            let clamped = min(max(past[k], min(low, now[k])), max(high, now[k]));
            blend[k] = clamped + (now[k] - clamped) * splat(self.alpha);
        }
        let out = rgb_lanes(blend);
        let out = expand_lanes([max(out[0], zero), max(out[1], zero), max(out[2], zero)]);
        let o = [
            V::select(blends, out[0], c[0]).to_array(),
            V::select(blends, out[1], c[1]).to_array(),
            V::select(blends, out[2], c[2]).to_array(),
        ];
        for (j, out) in self.out[x0..x0 + n].iter_mut().enumerate() {
            *out = Vec3::new(o[0][j], o[1][j], o[2][j]);
        }
        false
    }
}

/// [`compress`] in lanes.
#[inline(always)]
fn compress_lanes<V: F32xN>(c: [V; 3]) -> [V; 3] {
    let s = V::splat(1.0) / (V::splat(1.0) + max(luminance_lanes(c), V::splat(0.0)));
    [c[0] * s, c[1] * s, c[2] * s]
}

/// [`expand`] in lanes (`f32::clamp`'s selects: a NaN stays NaN).
#[inline(always)]
fn expand_lanes<V: F32xN>(c: [V; 3]) -> [V; 3] {
    let l = luminance_lanes(c);
    let l = V::select(V::splat(0.0).gt(l), V::splat(0.0), l);
    let l = V::select(l.gt(V::splat(0.999)), V::splat(0.999), l);
    let s = V::splat(1.0) / (V::splat(1.0) - l);
    [c[0] * s, c[1] * s, c[2] * s]
}

/// [`ycocg`] in lanes.
#[inline(always)]
fn ycocg_lanes<V: F32xN>(c: [V; 3]) -> [V; 3] {
    let (a, b) = (V::splat(0.25), V::splat(0.5));
    [
        a * c[0] + b * c[1] + a * c[2],
        b * c[0] - b * c[2],
        V::splat(-0.25) * c[0] + b * c[1] - a * c[2],
    ]
}

/// [`rgb`] in lanes.
#[inline(always)]
fn rgb_lanes<V: F32xN>(c: [V; 3]) -> [V; 3] {
    [c[0] + c[1] - c[2], c[0] + c[2], c[0] - c[1] - c[2]]
}

/// The history's bilinear value at pixel `(x, y)`'s previous place, `None` where no tap lies
/// in the image (or the motion or the history there is not finite).
fn reproject(
    history: &[f32],
    motion: Vec2,
    width: usize,
    height: usize,
    x: usize,
    y: usize,
) -> Option<Vec3> {
    let p = Vec2::new(x as f32, y as f32) + motion;
    if !p.is_finite() {
        return None;
    }
    let (mut sum, mut weight) = (Vec3::ZERO, 0.0f32);
    for (qx, qy, w) in bilinear_taps(p, width, height) {
        let at = qy * 3 * width + qx;
        let h = Vec3::new(history[at], history[at + width], history[at + 2 * width]);
        if h.is_finite() {
            sum += h * w;
            weight += w;
        }
    }
    (weight >= 1e-3).then(|| sum * (1.0 / weight))
}

/// The bilinear taps of point `p` (pixels, 0 at the first pixel's centre) on an image of
/// `width` x `height`: each pixel's column, row and weight, those outside the image or of no
/// weight left out.
pub fn bilinear_taps(
    p: Vec2,
    width: usize,
    height: usize,
) -> impl Iterator<Item = (usize, usize, f32)> {
    let (x0, y0) = (p.x.floor(), p.y.floor());
    let (fx, fy) = (p.x - x0, p.y - y0);
    [
        (0.0, 0.0, (1.0 - fx) * (1.0 - fy)),
        (1.0, 0.0, fx * (1.0 - fy)),
        (0.0, 1.0, (1.0 - fx) * fy),
        (1.0, 1.0, fx * fy),
    ]
    .into_iter()
    .filter_map(move |(dx, dy, w)| {
        let (qx, qy) = (x0 + dx, y0 + dy);
        let outside = qx < 0.0 || qy < 0.0 || qx >= width as f32 || qy >= height as f32;
        (w > 0.0 && !outside).then_some((qx as usize, qy as usize, w))
    })
}

/// Linear RGB to YCoCg.
pub fn ycocg(c: Vec3) -> Vec3 {
    Vec3::new(
        0.25 * c.x + 0.5 * c.y + 0.25 * c.z,
        0.5 * c.x - 0.5 * c.z,
        -0.25 * c.x + 0.5 * c.y - 0.25 * c.z,
    )
}

/// YCoCg to linear RGB (the inverse of [`ycocg`]).
pub fn rgb(c: Vec3) -> Vec3 {
    Vec3::new(c.x + c.y - c.z, c.x + c.z, c.x - c.y - c.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pathlight_core::rng::Rng;

    const W: usize = 24;
    const H: usize = 16;

    fn run(taa: &mut Taa, image: &[Vec3], motion: Vec2) -> Vec<Vec3> {
        let mut out = image.to_vec();
        taa.apply(&mut out, &vec![motion; W * H], W, H);
        out
    }

    #[test]
    fn a_constant_image_stays_constant_and_a_change_is_taken_at_once() {
        let mut taa = Taa::default();
        for _ in 0..5 {
            for o in run(&mut taa, &[Vec3::splat(0.2); W * H], Vec2::ZERO) {
                assert!((o - Vec3::splat(0.2)).abs().max_element() < 1e-6, "{o}");
            }
        }
        // The whole image changes: the box is the new value alone (to the rounding of its
        // variance), so no ghost of the old.
        for o in run(&mut taa, &[Vec3::new(0.8, 0.4, 0.1); W * H], Vec2::ZERO) {
            assert!(
                (o - Vec3::new(0.8, 0.4, 0.1)).abs().max_element() < 1e-3,
                "{o}"
            );
        }
    }

    /// Column 12's input and output over 60 frames of an edge through it that each frame's
    /// sample sees at a random place of the pixel (a jittered sample): 0.2 or 0.1 at random,
    /// half the time each (dim enough that the compression hardly weighs).
    fn point_sampled_edge(taa: &mut Taa) -> (Vec<f32>, Vec<f32>) {
        let mut rng = Rng::new(7, 0);
        let (mut outs, mut ins) = (Vec::new(), Vec::new());
        for _ in 0..60 {
            let hit = rng.next_f32() < 0.5;
            let image: Vec<Vec3> = (0..W * H)
                .map(|i| match i % W {
                    x if x < 12 => Vec3::splat(0.2),
                    12 if hit => Vec3::splat(0.2),
                    _ => Vec3::splat(0.1),
                })
                .collect();
            ins.push(image[8 * W + 12].x);
            outs.push(run(taa, &image, Vec2::ZERO)[8 * W + 12].x);
        }
        (ins, outs)
    }

    fn flicker(v: &[f32]) -> f32 {
        v.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f32>()
    }

    #[test]
    fn a_point_sampled_edge_settles_at_its_coverage() {
        // The edge's output settles near the pixel's mean and flickers less than its input.
        let (ins, outs) = point_sampled_edge(&mut Taa::default());
        // (This seed's draws hit 20 times in 60: the input's own mean is the coverage seen.)
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        let (mi, mo) = (mean(&ins[20..]), mean(&outs[20..]));
        assert!((mo - mi).abs() < 0.01, "{mo} against {mi}");
        let (fi, fo) = (flicker(&ins[20..]), flicker(&outs[20..]));
        assert!(fo < 0.5 * fi, "flicker {fo} against {fi}");
    }

    #[test]
    fn a_wider_box_keeps_more_of_the_history() {
        // The same edge: its column's values lie outside the box of a narrow `gamma` more
        // often, so a wider box blends more of the history (less flicker), and both settle
        // near the same mean.
        let mut wide = Taa::default();
        wide.set_gamma(2.0);
        let (_, narrow) = point_sampled_edge(&mut Taa::default());
        let (_, wide) = point_sampled_edge(&mut wide);
        let (fn_, fw) = (flicker(&narrow[20..]), flicker(&wide[20..]));
        assert!(fw < 0.8 * fn_, "flicker {fw} (gamma 2) against {fn_} (0.5)");
        let mean = |v: &[f32]| v[20..].iter().sum::<f32>() / 40.0;
        assert!((mean(&wide) - mean(&narrow)).abs() < 0.01);
    }

    #[test]
    fn motion_vectors_carry_the_history_and_the_border_takes_the_frame() {
        // A step moving right by 2 pixels a frame, the motion vectors saying so: the output
        // follows it without trailing; the columns that entered the image take the frame's.
        let mut taa = Taa::default();
        let mut out = Vec::new();
        for k in 0..8 {
            let image: Vec<Vec3> = (0..W * H)
                .map(|i| Vec3::splat(if i % W >= 4 + 2 * k { 0.8 } else { 0.2 }))
                .collect();
            out = run(&mut taa, &image, Vec2::new(-2.0, 0.0));
        }
        // At frame 7 the step is at x = 18.
        for (x, expected) in [(0, 0.2), (15, 0.2), (17, 0.2), (18, 0.8), (21, 0.8)] {
            let v = out[5 * W + x].x;
            assert!((v - expected).abs() < 0.02, "x {x}: {v}");
        }
    }

    #[test]
    fn the_lanes_agree_with_the_scalar_blend() {
        // Random light (bright pixels among them), motion of up to 3 pixels (taps past the
        // border), a NaN and an infinite pixel and a NaN motion, a width that is no multiple
        // of the lanes; every kind of lanes against the scalar blend, bit for bit.
        let (w, h) = (37, 11);
        let frame = |k: u64| {
            let mut rng = Rng::new(0x7aa + k, 2);
            let mut image: Vec<Vec3> = (0..w * h)
                .map(|_| {
                    let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                    if rng.next_f32() < 0.05 {
                        c * 40.0
                    } else {
                        c
                    }
                })
                .collect();
            // Motion at random (taps on several rows: gathered), varying along the row but on
            // one row (loads permuted), and alike (loads).
            let mut motion: Vec<Vec2> = (0..w * h)
                .map(|i| match i / w {
                    0..4 => Vec2::new(6.0 * rng.next_f32() - 3.0, 6.0 * rng.next_f32() - 3.0),
                    4..8 => Vec2::new(0.4 + 0.9 * (i % 4) as f32, 1.0),
                    _ => Vec2::new(1.3, -0.6),
                })
                .collect();
            image[3 * w + 5] = Vec3::new(f32::NAN, 0.0, 0.0);
            image[4 * w + 9] = Vec3::splat(f32::INFINITY);
            motion[6 * w + 2] = Vec2::new(f32::NAN, 1.0);
            (image, motion)
        };
        for lanes in ["avx512", "avx2", "portable"] {
            let (mut fast, mut slow) = (Taa::default(), Taa::default());
            fast.set_lanes(lanes);
            slow.set_scalar(true);
            // (A box other than the default's in one of the runs.)
            if lanes == "avx2" {
                fast.set_gamma(1.7);
                slow.set_gamma(1.7);
            }
            for k in 0..4 {
                let (image, motion) = frame(k);
                let (mut a, mut b) = (image.clone(), image);
                fast.apply(&mut a, &motion, w, h);
                slow.apply(&mut b, &motion, w, h);
                for (i, (p, q)) in a.iter().zip(&b).enumerate() {
                    assert!(
                        p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits),
                        "{lanes}, frame {k}, pixel {i}: {p} against {q}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_nan_pixel_or_motion_does_not_spread() {
        let mut taa = Taa::default();
        let mut image = vec![Vec3::splat(0.5); W * H];
        run(&mut taa, &image, Vec2::ZERO);
        image[3 * W + 3] = Vec3::NAN;
        let mut motion = vec![Vec2::ZERO; W * H];
        motion[5 * W + 5] = Vec2::new(f32::NAN, 0.0);
        for _ in 0..3 {
            let mut out = image.clone();
            taa.apply(&mut out, &motion, W, H);
            for (i, o) in out.iter().enumerate() {
                if i != 3 * W + 3 {
                    assert!(
                        (*o - Vec3::splat(0.5)).abs().max_element() < 1e-6,
                        "{i}: {o}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_spaces_round_trip() {
        for c in [
            Vec3::new(0.2, 0.5, 0.9),
            Vec3::new(3.0, 0.0, 1.0),
            Vec3::ZERO,
        ] {
            assert!((rgb(ycocg(c)) - c).abs().max_element() < 1e-6);
            assert!((expand(compress(c)) - c).abs().max_element() < 1e-5);
        }
    }
}
