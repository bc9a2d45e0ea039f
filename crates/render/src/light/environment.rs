//! The environment map as the path tracer samples it and looks it up, laid out for a hot loop.
//!
//! - **One record per texel** ([`Texel`]): its radiance (times the map's intensity) and the
//!   solid-angle density with which sampling picks a direction in it, side by side: a ray that
//!   escapes, or a light sample, reads one record, 16 bytes, where it read a texel, a row's CDF
//!   and the marginal CDF before.
//! - **Sampling in two levels** ([`TexelSampler`]): blocks of [`BLOCK`] x [`BLOCK`] texels
//!   chosen by inverting a 2D CDF over the blocks (with guide tables; a 1K map's is 130 KB and
//!   stays in the L2 cache), then a texel within the block by inverting its own small CDF of
//!   16-bit cuts (32 bytes per block). The inversion is monotone in each coordinate, as
//!   before, so stratified and low-discrepancy inputs stay spread over the blocks.
//! - **Uniform in solid angle within a texel**: the azimuth uniform across the texel's columns
//!   and the cosine of the polar angle uniform across its row, so a texel's density is
//!   constant, `P(texel) / Omega(texel)`, with texels weighed by luminance times their exact
//!   solid angle: the density is proportional to luminance over the whole sphere, at the
//!   poles and on maps of a few texels as well (no extra rows for small maps). The direction
//!   comes from per-column sines and cosines and per-row cosines, turned by the offset within
//!   the texel (a short polynomial where texels are narrow).
//!
//! The density is defined by the stored tables themselves, as [`Distribution2D`]'s is: a
//! texel's probability is its block's (from the block CDF) times its row's and its column's
//! shares in the block (from the 16-bit cuts), so it is exactly the frequency with which
//! sampling lands in it. A direction's texel is found as [`Environment::direction_to_uv`]
//! and [`Environment::radiance_at_uv`] find it; a sample's density and radiance are those of
//! the texel its direction is found in, so that they agree bit for bit with what a ray
//! escaping in that direction reads.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};
use pathlight_core::prefetch::prefetch;
use pathlight_scene::Environment;

use crate::alias::ONE_MINUS_EPSILON;
use crate::distribution::Distribution2D;

/// Luminance of a colour as a sampling or selection weight (0 for anything negative or not
/// finite).
pub fn weight(power: Vec3) -> f32 {
    let l = pathlight_core::color::luminance(power.max(Vec3::ZERO));
    if l.is_finite() {
        l
    } else {
        0.0
    }
}

/// Texels per side of a block of the sampler's first level.
pub const BLOCK: usize = 4;
/// The 16-bit cuts' total: a row's or a column's share of a block is its cut interval over it.
const CUT_TOTAL: f32 = 65535.0;

/// A texel as a lookup reads it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Texel {
    /// Radiance, times the map's intensity.
    pub radiance: Vec3,
    /// Solid-angle density of sampling a direction in the texel (0 where it is never sampled).
    pub pdf: f32,
}

/// Where a texel's directions lie: the lat-long grid's column azimuths and row cosines, and
/// the map's rotation (the same mapping as [`Environment`]'s).
#[derive(Debug, Clone)]
pub struct TexelGrid {
    width: usize,
    height: usize,
    rotation: f32,
    /// Per column, the sine and cosine of the azimuth of its left edge.
    columns: Vec<[f32; 2]>,
    /// Per row edge (`height + 1`), the cosine of its polar angle: 1 at the top, -1 at the
    /// bottom.
    rows: Vec<f32>,
    /// A column's width in radians.
    delta_phi: f32,
    /// Per row, its texels' solid angle (double precision: near the poles a row's cosines
    /// differ in their last bits in single precision).
    solid_angles: Vec<f64>,
}

impl TexelGrid {
    pub fn new(env: &Environment) -> Self {
        let (width, height) = (env.width.max(1) as usize, env.height.max(1) as usize);
        let delta_phi = 2.0 * PI / width as f32;
        let columns = (0..width)
            .map(|x| {
                let phi =
                    (x as f64 / width as f64 - 0.5) * std::f64::consts::TAU + env.rotation as f64;
                let (s, c) = phi.sin_cos();
                [s as f32, c as f32]
            })
            .collect();
        // The row edges' cosines in double precision, for both the edges and the solid angles.
        let cosines: Vec<f64> = (0..=height)
            .map(|y| (std::f64::consts::PI * y as f64 / height as f64).cos())
            .collect();
        let rows = cosines.iter().map(|&c| c as f32).collect();
        let solid_angles = (cosines.windows(2))
            .map(|c| (std::f64::consts::TAU / width as f64) * (c[0] - c[1]))
            .collect();
        Self {
            width,
            height,
            rotation: env.rotation,
            columns,
            rows,
            delta_phi,
            solid_angles,
        }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The solid angle of a texel of row `y`, in double precision.
    #[inline]
    pub fn solid_angle(&self, y: usize) -> f64 {
        self.solid_angles[y]
    }

    /// The direction at offset (`ox`, `oy`) in [0, 1)^2 within texel (`x`, `y`): the azimuth
    /// `ox` of the way across its columns, the cosine of the polar angle `oy` of the way down
    /// its row (uniform offsets give directions uniform in solid angle over the texel).
    #[inline]
    pub fn direction(&self, x: usize, y: usize, ox: f32, oy: f32) -> Vec3 {
        let [s0, c0] = self.columns[x];
        let (sd, cd) = small_sin_cos(ox * self.delta_phi, self.delta_phi);
        let (sin_phi, cos_phi) = (s0 * cd + c0 * sd, c0 * cd - s0 * sd);
        let (top, bottom) = (self.rows[y], self.rows[y + 1]);
        let cos_theta = top + oy * (bottom - top);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        Vec3::new(sin_theta * sin_phi, cos_theta, -sin_theta * cos_phi)
    }

    /// The texel (row-major index) that direction `dir` (unit length) falls in, found as
    /// [`Environment::direction_to_uv`] then [`Environment::radiance_at_uv`] find it.
    #[inline]
    pub fn texel(&self, dir: Vec3) -> usize {
        let phi = pathlight_core::math::fast_atan2(dir.x, -dir.z) - self.rotation;
        let theta = pathlight_core::math::fast_acos(dir.y);
        let u = (0.5 + phi / (2.0 * PI)).rem_euclid(1.0);
        let v = theta / PI;
        let x = ((u * self.width as f32) as usize).min(self.width - 1);
        let y = ((v * self.height as f32) as usize).min(self.height - 1);
        y * self.width + x
    }
}

/// `(sin d, cos d)` for `d` in [0, `max`]: a Taylor polynomial where `max` is small (texels of
/// maps at least 64 wide: error below 1e-10), the library's otherwise.
#[inline]
fn small_sin_cos(d: f32, max: f32) -> (f32, f32) {
    if max <= 0.1 {
        let d2 = d * d;
        let s = d * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0)));
        let c = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0)));
        (s, c)
    } else {
        d.sin_cos()
    }
}

/// A block's second level: the cuts of its rows' shares (3), then for each of its rows the
/// cuts of its columns' shares (4 x 3), out of [`CUT_TOTAL`]; the last entry unused.
#[derive(Debug, Clone, Copy, Default)]
struct Cuts([u16; 16]);

impl Cuts {
    /// Row `k`'s cuts (`None`: the rows').
    #[inline]
    fn of(&self, row: Option<usize>) -> [u16; 3] {
        let at = row.map_or(0, |k| 3 + 3 * k);
        [self.0[at], self.0[at + 1], self.0[at + 2]]
    }
}

/// Which of the four intervals `cuts` make of [0, [`CUT_TOTAL`]] holds `u` * total (never one
/// of zero length), its share, and the offset in [0, 1) within it.
#[inline]
fn pick(cuts: [u16; 3], u: f32) -> (usize, f32, f32) {
    let v = u * CUT_TOTAL;
    let c = cuts.map(f32::from);
    let k = (v >= c[0]) as usize + (v >= c[1]) as usize + (v >= c[2]) as usize;
    let (lo, hi) = interval(c, k);
    let offset = ((v - lo) / (hi - lo)).clamp(0.0, ONE_MINUS_EPSILON);
    (k, (hi - lo) / CUT_TOTAL, offset)
}

/// Interval `k` of the four `cuts` make.
#[inline]
fn interval(c: [f32; 3], k: usize) -> (f32, f32) {
    let lo = if k == 0 { 0.0 } else { c[k - 1] };
    let hi = if k == 3 { CUT_TOTAL } else { c[k] };
    (lo, hi)
}

/// Interval `k`'s share of the total.
#[inline]
fn share(cuts: [u16; 3], k: usize) -> f32 {
    let (lo, hi) = interval(cuts.map(f32::from), k);
    (hi - lo) / CUT_TOTAL
}

/// The cuts of four weights' shares: each positive weight gets at least one unit of
/// [`CUT_TOTAL`], zero weights none; all zero: equal shares (never used).
fn quantize(w: [f64; 4]) -> [u16; 3] {
    let total: f64 = w.iter().sum();
    let mut counts = [0i64; 4];
    if total > 0.0 {
        for (c, &x) in counts.iter_mut().zip(&w) {
            if x > 0.0 {
                *c = ((x / total * CUT_TOTAL as f64) as i64).max(1);
            }
        }
    } else {
        counts = [16384, 16384, 16384, 16383];
    }
    let missing = CUT_TOTAL as i64 - counts.iter().sum::<i64>();
    let largest = (0..4).max_by_key(|&k| counts[k]).unwrap_or(0);
    counts[largest] += missing;
    let mut cuts = [0u16; 3];
    let mut running = 0i64;
    for k in 0..3 {
        running += counts[k];
        cuts[k] = running as u16;
    }
    cuts
}

/// Picks texels of a grid in proportion to weights: a block by a 2D CDF over blocks, then a
/// row and a column within it by their 16-bit cuts (the module doc).
#[derive(Debug, Clone)]
pub struct TexelSampler {
    width: usize,
    height: usize,
    blocks: Distribution2D,
    /// Per block, row-major over the blocks.
    cuts: Vec<Cuts>,
}

impl TexelSampler {
    /// A sampler of the `width` x `height` texels in proportion to `weights` (row-major;
    /// negative and non-finite weights count as 0); `None` when none is positive.
    pub fn new(weights: &[f64], width: usize, height: usize) -> Option<Self> {
        assert_eq!(weights.len(), width * height);
        let clean = |x: f64| if x.is_finite() && x > 0.0 { x } else { 0.0 };
        let weight = |x: usize, y: usize| match x < width && y < height {
            true => clean(weights[y * width + x]),
            false => 0.0,
        };
        let (bw, bh) = (width.div_ceil(BLOCK), height.div_ceil(BLOCK));
        let mut block_weights = vec![0.0f32; bw * bh];
        let mut cuts = vec![Cuts::default(); bw * bh];
        for by in 0..bh {
            for bx in 0..bw {
                let w: [[f64; 4]; 4] = std::array::from_fn(|ky| {
                    std::array::from_fn(|kx| weight(bx * BLOCK + kx, by * BLOCK + ky))
                });
                let rows = w.map(|r| r.iter().sum::<f64>());
                let c = &mut cuts[by * bw + bx].0;
                c[..3].copy_from_slice(&quantize(rows));
                for (k, r) in w.iter().enumerate() {
                    c[3 + 3 * k..6 + 3 * k].copy_from_slice(&quantize(*r));
                }
                block_weights[by * bw + bx] = rows.iter().sum::<f64>() as f32;
            }
        }
        Some(Self {
            width,
            height,
            blocks: Distribution2D::new(&block_weights, bw, bh)?,
            cuts,
        })
    }

    /// A texel (column, row), the offset in [0, 1)^2 within it, from `u` in [0, 1)^2 (clamped
    /// into it): the sampled texel always has a positive [`probability`](Self::probability).
    #[inline]
    pub fn sample(&self, u: Vec2) -> (usize, usize, Vec2) {
        let ((bx, by), o, _) = self.blocks.sample_cell(u);
        let cuts = &self.cuts[by * self.blocks.width() + bx];
        let (ky, _, oy) = pick(cuts.of(None), o.y);
        let (kx, _, ox) = pick(cuts.of(Some(ky)), o.x);
        (bx * BLOCK + kx, by * BLOCK + ky, Vec2::new(ox, oy))
    }

    /// The probability that [`sample`](Self::sample) picks texel (`x`, `y`).
    pub fn probability(&self, x: usize, y: usize) -> f32 {
        if x >= self.width || y >= self.height {
            return 0.0;
        }
        let (bx, by, kx, ky) = (x / BLOCK, y / BLOCK, x % BLOCK, y % BLOCK);
        let cuts = &self.cuts[by * self.blocks.width() + bx];
        self.blocks.cell_probability(bx, by)
            * share(cuts.of(None), ky)
            * share(cuts.of(Some(ky)), kx)
    }

    /// The solid-angle density of directions toward texel `i` (row-major) of `grid`: its
    /// probability over its solid angle.
    pub fn density(&self, grid: &TexelGrid, i: usize) -> f32 {
        let (x, y) = (i % grid.width, i / grid.width);
        (self.probability(x, y) as f64 / grid.solid_angle(y)) as f32
    }

    /// Heap bytes.
    pub fn bytes(&self) -> usize {
        self.cuts.len() * std::mem::size_of::<Cuts>() + self.blocks.bytes()
    }
}

/// The environment light's map: its texels' records, where their directions lie, and the
/// sampler of its texels in proportion to luminance times solid angle.
#[derive(Debug, Clone)]
pub struct EnvironmentMap {
    pub grid: TexelGrid,
    texels: Vec<Texel>,
    /// `None` when every texel is black.
    sampler: Option<TexelSampler>,
    /// Its luminance over the whole sphere (the most irradiance it gives a surface).
    pub integral: f64,
}

impl EnvironmentMap {
    pub fn new(env: &Environment) -> Self {
        let grid = TexelGrid::new(env);
        let mut map = Self {
            texels: (env.texels.iter())
                .map(|&t| Texel {
                    radiance: t * env.intensity,
                    pdf: 0.0,
                })
                .collect(),
            grid,
            sampler: None,
            integral: 0.0,
        };
        let (weights, integral) = map.weights(|_| true);
        map.integral = integral;
        map.sampler = TexelSampler::new(&weights, map.grid.width, map.grid.height);
        if let Some(s) = &map.sampler {
            for (i, t) in map.texels.iter_mut().enumerate() {
                t.pdf = s.density(&map.grid, i);
            }
        }
        map
    }

    /// The sampling weight of each texel `keep` accepts (by row-major index; the others weigh
    /// 0): its luminance times its solid angle; and the sum of those weights (the luminance
    /// over the sphere of the texels kept).
    pub fn weights(&self, keep: impl Fn(usize) -> bool) -> (Vec<f64>, f64) {
        let w = self.grid.width;
        let weights: Vec<f64> = (self.texels.iter().enumerate())
            .map(|(i, t)| match keep(i) {
                true => weight(t.radiance) as f64 * self.grid.solid_angle(i / w),
                false => 0.0,
            })
            .collect();
        let integral = weights.iter().sum();
        (weights, integral)
    }

    /// Whether some texel is sampled.
    pub fn is_lit(&self) -> bool {
        self.sampler.is_some()
    }

    /// The texel direction `dir` (unit length) falls in.
    #[inline]
    pub fn lookup(&self, dir: Vec3) -> &Texel {
        &self.texels[self.grid.texel(dir)]
    }

    /// The texel of row-major index `i`.
    pub fn texel(&self, i: usize) -> &Texel {
        &self.texels[i]
    }

    /// A direction drawn in proportion to luminance (`None` for a black map).
    #[inline]
    pub fn sample(&self, u: Vec2) -> Option<Vec3> {
        self.sample_with(self.sampler.as_ref()?, u)
    }

    /// A direction toward a texel that `sampler` (over this map's grid) picks.
    #[inline]
    pub fn sample_with(&self, sampler: &TexelSampler, u: Vec2) -> Option<Vec3> {
        let (x, y, o) = sampler.sample(u);
        // The caller reads the texel's record next (the one the direction falls in): its
        // miss, the slowest read of a sample, overlaps the direction's trigonometry.
        prefetch(&self.texels[y * self.grid.width + x]);
        Some(self.grid.direction(x, y, o.x, o.y))
    }

    /// Heap bytes.
    pub fn bytes(&self) -> usize {
        self.texels.len() * std::mem::size_of::<Texel>()
            + self.sampler.as_ref().map_or(0, |s| s.bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::alias::{chi2, chi2_critical};
    use pathlight_core::rng::Rng;

    /// A map of `w` x `h` texels of random brightness, some black, with a bright spot.
    fn random_map(w: u32, h: u32, seed: u64) -> Environment {
        let mut rng = Rng::new(seed, 3);
        let mut env = Environment::constant(Vec3::ONE);
        env.width = w;
        env.height = h;
        env.rotation = 0.7;
        env.texels = (0..w * h)
            .map(|i| match i % 11 {
                4 => Vec3::ZERO,
                7 if i % 77 == 7 => Vec3::splat(5000.0),
                _ => Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 3.0,
            })
            .collect();
        env
    }

    /// The grid's directions fall in the texel they were made in, and directions spread over a
    /// texel by uniform offsets cover its solid angle uniformly (the mean of their cosine of
    /// the polar angle is the middle of the row's cosines).
    #[test]
    fn directions_fall_in_their_texel() {
        for (w, h) in [(1, 1), (3, 2), (16, 8), (1024, 512)] {
            let env = random_map(w, h, 1);
            let grid = TexelGrid::new(&env);
            let mut rng = Rng::new(4, w as u64);
            let mut misplaced = 0;
            for _ in 0..20_000 {
                let (x, y) = (
                    rng.next_u32() as usize % grid.width,
                    rng.next_u32() as usize % grid.height,
                );
                let (ox, oy) = (rng.next_f32(), rng.next_f32());
                let d = grid.direction(x, y, ox, oy);
                assert!((d.length() - 1.0).abs() < 1e-5, "{d}");
                // Away from the texel's edges (by more than the lookup's 2e-6 radians).
                let inside = (0.001..0.999).contains(&ox) && (0.001..0.999).contains(&oy);
                if inside && grid.texel(d) != y * grid.width + x {
                    misplaced += 1;
                }
                // The same texel as the scene's own lookup.
                let uv = env.direction_to_uv(d);
                let tx = ((uv.x * w as f32) as usize).min(w as usize - 1);
                let ty = ((uv.y * h as f32) as usize).min(h as usize - 1);
                assert_eq!(grid.texel(d), ty * w as usize + tx);
            }
            assert_eq!(misplaced, 0, "{w}x{h}");
        }
    }

    /// The sampler's frequencies are its probabilities (chi-square), its probabilities are the
    /// weights' shares to the cuts' precision, and they sum to 1.
    #[test]
    fn texels_are_picked_with_their_probability() {
        let (w, h) = (23usize, 10usize);
        let mut rng = Rng::new(7, 1);
        let weights: Vec<f64> = (0..w * h)
            .map(|i| match i % 5 {
                2 => 0.0,
                _ => (rng.next_f32() as f64).powi(3) * 10.0,
            })
            .collect();
        let s = TexelSampler::new(&weights, w, h).unwrap();
        let total: f64 = weights.iter().sum();
        let mut sum = 0.0f64;
        for y in 0..h {
            for x in 0..w {
                let p = s.probability(x, y) as f64;
                let want = weights[y * w + x] / total;
                assert!(
                    (p - want).abs() <= 1e-3 * want + 1e-6,
                    "{x},{y}: {p} against {want}"
                );
                assert_eq!(p == 0.0, want == 0.0);
                sum += p;
            }
        }
        assert!((sum - 1.0).abs() < 1e-5, "{sum}");
        let n = 400_000;
        let mut counts = vec![0u64; w * h];
        for _ in 0..n {
            let (x, y, o) = s.sample(Vec2::new(rng.next_f32(), rng.next_f32()));
            assert!(o.x >= 0.0 && o.x < 1.0 && o.y >= 0.0 && o.y < 1.0);
            assert!(s.probability(x, y) > 0.0);
            counts[y * w + x] += 1;
        }
        let expected: Vec<f64> = (0..w * h)
            .map(|i| s.probability(i % w, i / w) as f64 * n as f64)
            .collect();
        let (stat, dof) = chi2(&counts, &expected);
        assert!(stat < chi2_critical(dof, 3.09), "chi2 {stat} dof {dof}");
        for u in [
            Vec2::ZERO,
            Vec2::splat(ONE_MINUS_EPSILON),
            Vec2::splat(1.0),
            Vec2::NAN,
        ] {
            let (x, y, _) = s.sample(u);
            assert!(s.probability(x, y) > 0.0, "{u}");
        }
        assert!(TexelSampler::new(&[0.0; 6], 3, 2).is_none());
    }

    /// The map's density integrates to 1 over the sphere and is, texel by texel, proportional
    /// to luminance (its radiance over its density is the same everywhere it is lit); the
    /// radiance over the density of sampled directions estimates the integral of the radiance
    /// over the sphere, against quadrature over the texels.
    #[test]
    fn the_density_follows_luminance_and_integrates_to_one() {
        // Texels between 0.3 and 3 (or black), so that every share of a block is large and
        // the cuts round it by less than 1e-3.
        let mut env = random_map(40, 20, 2);
        for t in &mut env.texels {
            *t =
                t.clamp(Vec3::splat(0.3), Vec3::splat(3.0)) * (t.max_element() > 0.0) as u32 as f32;
        }
        let map = EnvironmentMap::new(&env);
        let grid = &map.grid;
        let (w, h) = (grid.width, grid.height);
        let mut total = 0.0f64;
        let mut exact = glam::DVec3::ZERO;
        for y in 0..h {
            for x in 0..w {
                let t = map.texel(y * w + x);
                total += t.pdf as f64 * grid.solid_angle(y);
                exact += t.radiance.as_dvec3() * grid.solid_angle(y);
                let lum = pathlight_core::color::luminance(t.radiance) as f64;
                if lum > 0.0 {
                    let ratio = lum / t.pdf as f64;
                    assert!(
                        (ratio - map.integral).abs() < 2e-3 * map.integral,
                        "{ratio}"
                    );
                } else {
                    assert_eq!(t.pdf, 0.0);
                }
            }
        }
        assert!((total - 1.0).abs() < 1e-5, "{total}");
        let mut rng = Rng::new(3, 3);
        let n = 400_000;
        let mut sum = glam::DVec3::ZERO;
        for _ in 0..n {
            let d = map
                .sample(Vec2::new(rng.next_f32(), rng.next_f32()))
                .unwrap();
            let t = map.lookup(d);
            if t.pdf > 0.0 {
                sum += (t.radiance / t.pdf).as_dvec3();
            }
        }
        let estimate = sum / n as f64;
        let rel = ((estimate - exact).abs() / exact).max_element();
        assert!(rel < 0.01, "{estimate} against {exact}");
    }
}
