//! SVGF's a-trous passes ([`crate::svgf`]) over structure-of-arrays planes, 16 centre pixels at a
//! time (one AVX-512 register, or two AVX2 ones, with FMA, as the processor has them): the same
//! weights, taps and order of sums as the scalar pass in `svgf.rs`, which stays as the reference
//! (a test holds them together) and for passes too wide for the planes' padding.
//!
//! The planes carry a border of `pad` pixels (twice the widest hole) whose normal is zero, so a
//! tap that falls outside the image weighs exactly 0, as the scalar pass's bounds test gives;
//! the sky and light sources have a zero normal too (nobody's neighbour). Rows are
//! `[plane][pitch]` blocks, so each thread writes whole rows. A pass with holes of `step` rows
//! takes the rows of one class modulo `step` one after the other, so the rows its taps read stay
//! in the cache from one output row to the next (in image order, the holes of 8 and 16 rows
//! took a third longer than those of 1). Each 16-pixel group writes its result, the pixels that
//! pass through kept, and the luminances the next pass tests, in lanes; the luminance test's
//! sigma (the blurred variance) is worked out in the group from the variance planes.

use glam::Vec3;
use pathlight_core::color::luminance;
use rayon::prelude::*;

use crate::exp::{exp_neg, MulAdd, Plain};

const LANES: usize = 16;
type Lanes = [f32; LANES];

/// Widest padding the planes take: holes up to 32 pixels (six passes).
pub const MAX_PAD: usize = 64;

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
/// The sum of the variance blur's weights over the pixels inside the image.
const SUM: usize = 5;
/// 1 where the pixel passes through (the sky and light sources), else 0.
const THROUGH: usize = 6;
const STATIC: usize = 7;
// Dynamic planes (per pass): direct rgb, indirect rgb, the two variances, the two luminances.
const L: usize = 0;
const V: usize = 6;
const LUM: usize = 8;
const DYNAMIC: usize = 10;

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
#[derive(Debug, Clone, Copy, Default)]
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
    statics: Vec<f32>,
    current: Vec<f32>,
    next: Vec<f32>,
}

/// One frame's per-pixel inputs to the passes (row-major, unpadded).
pub struct Inputs<'a> {
    pub width: usize,
    pub height: usize,
    pub depth: &'a [f32],
    pub normal: &'a [Vec3],
    pub gradient: &'a [f32],
    /// The sky and light sources: passed through, nobody's neighbour.
    pub through: &'a (dyn Fn(usize) -> bool + Sync),
    pub light: &'a [[Vec3; 2]],
    pub variance: &'a [[f32; 2]],
}

impl Planes {
    /// Lays out this frame's inputs for passes with holes up to `max_step` pixels (at most
    /// [`MAX_PAD`] / 2).
    pub fn load(&mut self, f: &Inputs, max_step: usize) {
        let (w, h) = (f.width, f.height);
        let pad = 2 * max_step;
        debug_assert!(pad <= MAX_PAD);
        self.fixed = Grid::new(w, h, pad, STATIC);
        self.moving = Grid::new(w, h, pad, DYNAMIC);
        let (fixed, moving) = (self.fixed, self.moving);
        self.statics.clear();
        self.statics.resize(fixed.len(), 0.0);
        fixed.for_rows(&mut self.statics, |y, row| {
            for x in 0..w {
                let i = y as usize * w + x;
                let at = |p: usize| p * fixed.pitch + pad + x;
                row[at(Z)] = f.depth[i];
                row[at(G)] = f.gradient[i];
                // The blur is (1/4, 1/2, 1/4) across times the same down: its weights inside
                // the image sum to the product of the two (exactly: sixteenths).
                let inside = |c: usize, n: usize| {
                    1.0 - if c == 0 { 0.25 } else { 0.0 } - if c + 1 == n { 0.25 } else { 0.0 }
                };
                row[at(SUM)] = inside(x, w) * inside(y as usize, h);
                let through = (f.through)(i);
                row[at(THROUGH)] = if through { 1.0 } else { 0.0 };
                let n = if through { Vec3::ZERO } else { f.normal[i] };
                for k in 0..3 {
                    row[at(NX + k)] = n[k];
                }
            }
        });
        for buffer in [&mut self.current, &mut self.next] {
            buffer.clear();
            buffer.resize(moving.len(), 0.0);
        }
        moving.for_rows(&mut self.current, |y, row| {
            for x in 0..w {
                let i = y as usize * w + x;
                let at = |p: usize| p * moving.pitch + pad + x;
                for s in 0..2 {
                    for k in 0..3 {
                        row[at(L + 3 * s + k)] = f.light[i][s][k];
                    }
                    row[at(V + s)] = f.variance[i][s];
                    row[at(LUM + s)] = luminance(f.light[i][s]);
                }
            }
        });
    }

    /// The current light of every pixel, row-major.
    pub fn light(&self, out: &mut Vec<[Vec3; 2]>) {
        out.resize(self.moving.width * self.moving.height, [Vec3::ZERO; 2]);
        self.map_light(out, |_, light| light);
    }

    /// `f(i, light)` of every pixel `i` (row-major) and its current light, into `out` (one
    /// entry a pixel).
    pub fn map_light<T: Send>(&self, out: &mut [T], f: impl Fn(usize, [Vec3; 2]) -> T + Sync) {
        let g = self.moving;
        out.par_chunks_mut(g.width)
            .enumerate()
            .for_each(|(y, row)| {
                let at = |p: usize| &self.current[g.at(0, y as i64, p)..][..g.width];
                let planes: [&[f32]; 6] = std::array::from_fn(|p| at(L + p));
                for (x, o) in row.iter_mut().enumerate() {
                    let c = |p: usize| planes[p][x];
                    *o = f(
                        y * g.width + x,
                        [Vec3::new(c(0), c(1), c(2)), Vec3::new(c(3), c(4), c(5))],
                    );
                }
            });
    }

    /// One pass of a kernel `kernel` pixels wide (3 or 5) with holes of `step` pixels:
    /// `current` filtered into `next`, then swapped.
    pub fn pass(&mut self, kernel: u32, step: usize, sigma_l: f32, sigma_z: f32) {
        let g = self.moving;
        // What makes the passes' unchecked loads (`Pass::lanes`) safe: every tap of a 5x5
        // kernel with holes of `step` lies within the padding.
        assert!(
            2 * step <= g.pad && g.pad == self.fixed.pad,
            "holes of {step} pixels need a padding of {}, the planes have {}",
            2 * step,
            g.pad
        );
        let pass = Pass {
            fixed: self.fixed,
            moving: g,
            statics: &self.statics,
            sigma_l,
            current: &self.current,
            step: step as i64,
            sigma_z,
            wide: kernel != 3,
        };
        g.for_rows_by(&mut self.next, step, |y, row| pass.row(y, row));
        std::mem::swap(&mut self.current, &mut self.next);
    }
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
}

/// The weighted sums of [`LANES`] centre pixels.
#[derive(Default)]
struct Sums {
    w: [Lanes; 2],
    light: [Lanes; 6],
    var: [Lanes; 2],
}

impl Pass<'_> {
    /// Row `y` of the output into `row` (its `[plane][pitch]` block).
    fn row(&self, y: i64, row: &mut [f32]) {
        for x0 in (0..self.moving.width).step_by(LANES) {
            self.group(x0 as i64, y, row);
        }
    }

    /// The [`LANES`] pixels from (x0, y) on, filtered into `row`.
    fn group(&self, x0: i64, y: i64, row: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("fma") {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the processor has AVX-512 and FMA (checked just above).
                return unsafe {
                    if self.wide {
                        self.group_avx512::<2>(x0, y, row)
                    } else {
                        self.group_avx512::<1>(x0, y, row)
                    }
                };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor has AVX2 and FMA (checked just above).
                return unsafe {
                    if self.wide {
                        self.group_avx2::<2>(x0, y, row)
                    } else {
                        self.group_avx2::<1>(x0, y, row)
                    }
                };
            }
        }
        if self.wide {
            self.group_lanes::<Plain, 2>(x0, y, row)
        } else {
            self.group_lanes::<Plain, 1>(x0, y, row)
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn group_avx2<const R: i64>(&self, x0: i64, y: i64, row: &mut [f32]) {
        self.group_lanes::<crate::exp::Fused, R>(x0, y, row)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma")]
    fn group_avx512<const R: i64>(&self, x0: i64, y: i64, row: &mut [f32]) {
        self.group_lanes::<crate::exp::Fused, R>(x0, y, row)
    }

    /// The [`LANES`] values of `buffer` from `at` on, without a bounds check: a pass reads its taps
    /// 14 times, and the checks (two per read) were a sixth of its instructions.
    ///
    /// # Safety
    /// `at + LANES <= buffer.len()`. [`Planes::pass`] asserts that the holes fit the
    /// padding, so every index [`Grid::at`] gives for a tap of a centre group (x in
    /// `0..width` by 8, y in `0..height`) is inside its plane's padded row.
    #[inline(always)]
    unsafe fn lanes(buffer: &[f32], at: usize) -> Lanes {
        debug_assert!(at + LANES <= buffer.len());
        // SAFETY: the caller's contract; `[f32; LANES]` has no alignment beyond f32's, and the
        // read is unaligned anyway.
        unsafe { std::ptr::read_unaligned(buffer.as_ptr().add(at).cast::<Lanes>()) }
    }

    /// The [`LANES`] pixels from (x0, y) on filtered by a kernel of radius `R` (1: 3x3, 2: 5x5)
    /// into `row`: the weighted means, the pixels that pass through kept as they are, and the
    /// luminances of the result.
    #[inline(always)]
    fn group_lanes<M: MulAdd, const R: i64>(&self, x0: i64, y: i64, row: &mut [f32]) {
        let s = self.sums::<M, R>(x0, y);
        let g = self.moving;
        // SAFETY: the centre group lies within the image.
        let through = unsafe { Self::lanes(self.statics, self.fixed.at(x0, y, THROUGH)) };
        let keep = |p: usize, value: Lanes| -> Lanes {
            // SAFETY: as above.
            let current = unsafe { Self::lanes(self.current, g.at(x0, y, p)) };
            std::array::from_fn(|j| {
                if through[j] != 0.0 {
                    current[j]
                } else {
                    value[j]
                }
            })
        };
        let n = LANES.min(g.width - x0 as usize);
        let mut put = |p: usize, value: &Lanes| {
            let at = p * g.pitch + g.pad + x0 as usize;
            row[at..at + n].copy_from_slice(&value[..n]);
        };
        for sig in 0..2 {
            let sw = s.w[sig];
            let c: [Lanes; 3] = std::array::from_fn(|k| {
                let light = &s.light[3 * sig + k];
                keep(L + 3 * sig + k, std::array::from_fn(|j| light[j] / sw[j]))
            });
            for (k, c) in c.iter().enumerate() {
                put(L + 3 * sig + k, c);
            }
            let var = &s.var[sig];
            put(
                V + sig,
                &keep(V + sig, std::array::from_fn(|j| var[j] / (sw[j] * sw[j]))),
            );
            put(
                LUM + sig,
                &std::array::from_fn(|j| luminance(Vec3::new(c[0][j], c[1][j], c[2][j]))),
            );
        }
    }

    /// The weighted sums of a kernel of radius `R` over the [`LANES`] pixels from (x0, y) on.
    #[inline(always)]
    fn sums<M: MulAdd, const R: i64>(&self, x0: i64, y: i64) -> Sums {
        let h = spline(2 * R as u32 + 1);
        let (fg, mg) = (self.fixed, self.moving);
        // SAFETY (both): the taps lie within the padding (asserted by `Planes::pass`), the
        // centre group within the image.
        let st = |p: usize, x: i64, y: i64| unsafe { Self::lanes(self.statics, fg.at(x, y, p)) };
        let dy = |p: usize, x: i64, y: i64| unsafe { Self::lanes(self.current, mg.at(x, y, p)) };
        let zc = st(Z, x0, y);
        let gz = st(G, x0, y);
        let nc = [st(NX, x0, y), st(NX + 1, x0, y), st(NX + 2, x0, y)];
        let lc = [dy(LUM, x0, y), dy(LUM + 1, x0, y)];
        // The luminance test's `1 / (sigma_l sqrt(g(var)) + 1e-4)`, g the variance's 3x3
        // Gaussian over the pixels inside the image (the scalar pass's: the border's zeros add
        // nothing, and plane `SUM` holds the same normalisation, summed in the same order).
        let sum = st(SUM, x0, y);
        let inv: [Lanes; 2] = [V, V + 1].map(|p| {
            let mut g = [0.0f32; LANES];
            for &(dx, dy_, k) in &BLUR {
                let v = dy(p, x0 + dx, y + dy_);
                for j in 0..LANES {
                    g[j] += v[j] * k;
                }
            }
            std::array::from_fn(|j| 1.0 / (self.sigma_l * (g[j] / sum[j]).sqrt() + 1e-4))
        });
        // The centre tap: the kernel's weight whatever the tests say.
        let kc = h[0] * h[0];
        let mut s = Sums::default();
        for sig in 0..2 {
            s.w[sig] = [kc; LANES];
            s.var[sig] = dy(V + sig, x0, y).map(|v| v * kc * kc);
            for k in 0..3 {
                s.light[3 * sig + k] = dy(L + 3 * sig + k, x0, y).map(|l| l * kc);
            }
        }
        let step = self.step;
        // The depth test's `1 / (sigma_z |grad z| |p - q| + 1e-4 z)` for the distances the
        // taps have (|k|^2 = 1, 2, and with the 5x5 kernel 4, 5, 8).
        let mut rz = [[0.0f32; LANES]; 5];
        for (d, rz) in rz.iter_mut().enumerate().take(if R == 1 { 2 } else { 5 }) {
            let distance = ([1.0f32, 2.0, 4.0, 5.0, 8.0][d]).sqrt() * step as f32;
            *rz = std::array::from_fn(|j| 1.0 / (self.sigma_z * gz[j] * distance + 1e-4 * zc[j]));
        }
        for ky in -R..=R {
            for kx in -R..=R {
                if kx == 0 && ky == 0 {
                    continue;
                }
                let rz = &rz[match kx * kx + ky * ky {
                    1 => 0,
                    2 => 1,
                    4 => 2,
                    5 => 3,
                    _ => 4,
                }];
                let (qx, qy) = (x0 + kx * step, y + ky * step);
                let kernel = h[kx.unsigned_abs() as usize] * h[ky.unsigned_abs() as usize];
                let zq = st(Z, qx, qy);
                let nq = [st(NX, qx, qy), st(NX + 1, qx, qy), st(NX + 2, qx, qy)];
                let lq = [dy(LUM, qx, qy), dy(LUM + 1, qx, qy)];
                let light: [Lanes; 6] = std::array::from_fn(|p| dy(L + p, qx, qy));
                let var = [dy(V, qx, qy), dy(V + 1, qx, qy)];
                for j in 0..LANES {
                    let wz = -(zq[j] - zc[j]).abs() * rz[j];
                    let cos = nq[0][j] * nc[0][j] + nq[1][j] * nc[1][j] + nq[2][j] * nc[2][j];
                    let wn = normal_weight(cos);
                    for sig in 0..2 {
                        let e = wz + -(lq[sig][j] - lc[sig][j]).abs() * inv[sig][j];
                        let wq = if wn > 0.0 && e > -30.0 {
                            kernel * wn * exp_neg::<M>(e)
                        } else {
                            0.0
                        };
                        s.w[sig][j] += wq;
                        for k in 0..3 {
                            s.light[3 * sig + k][j] += light[3 * sig + k][j] * wq;
                        }
                        s.var[sig][j] += var[sig][j] * wq * wq;
                    }
                }
            }
        }
        s
    }
}

/// `max(0, cos)^128` by repeated squaring; 0 below a cosine of 0.6 (and for NaN).
#[inline(always)]
pub fn normal_weight(cos: f32) -> f32 {
    let mut w = if cos >= 0.6 { cos } else { 0.0 };
    for _ in 0..7 {
        w *= w;
    }
    w
}
