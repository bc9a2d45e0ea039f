//! The frame's pool of light candidates (seed 004): light points drawn once per frame from
//! the lights' selection (power or uniform, then uniform on the light), in blocks of
//! [`LANES`] laid out as the SIMD lanes read them. A pixel's candidates are whole blocks
//! picked uniformly at random from the pool, so the draws (the alias table, the light's
//! data, a triangle's point and its emissive texture) are paid once per pool entry instead
//! of once per candidate, and a block's lights load as contiguous vectors instead of
//! scattered reads (the "light tiles" of Wyman and Panteleev, "Rearchitecting spatiotemporal
//! resampling for production", HPG 2021).
//!
//! The light choices are stratified: entry `i` of the `n` chooses its light with
//! `(s_i + u) / n`, `s` a random permutation of `0..n` and `u` uniform, so each light holds
//! its expected share of the pool to within one entry (independent draws would let a light's
//! share vary by `1 / sqrt(n p)` from frame to frame: 17% with 500 equal lights, a flicker of
//! the regions it lights). The point on the light is drawn independently.
//!
//! A uniformly chosen pool entry is distributed as the source density `p`, and the block a
//! pixel takes is independent of the entries, so each candidate is still distributed as `p`:
//! resampled importance sampling stays unbiased (its expectation is a sum over candidates of
//! `E[f(x_i) / p(x_i)]`, whatever their dependence). What the pool adds is correlation:
//! two pixels that pick the same block share its candidates (with 1,024 blocks of 16, a pair of
//! pixels shares one with probability about 1/256 at 32 candidates), and a pixel may pick the
//! same block twice.

use glam::{Vec2, Vec3};
use pathlight_core::rng::{hash, Rng};
use rayon::prelude::*;

use crate::light::{LaneLight, LightPoint, Lights};

/// Candidates per block (and lanes of the target's SIMD loop: one AVX-512 vector).
pub const LANES: usize = 16;
/// Blocks in a frame's pool: 16,384 candidates, 1 MB of blocks.
pub const POOL_BLOCKS: usize = 1024;
/// Blocks drawn by one task while the pool is built.
const BUILD_CHUNK: usize = 64;
/// Stream tag of the pool's random numbers.
const POOL_STREAM: u64 = 0x9001_b10c;

/// `N` light points (at most 16; [`LANES`] in the pool), structure of arrays. Point lights:
/// position `q`, intensity `e`, `inv_range`; triangles: the point `q`, its emission `e`, the
/// unit normal `n` and the sidedness; distant light (the environment, directional lights):
/// the unit direction toward it `q`, the radiance arriving along it `e`. A lane that holds
/// no candidate (a failed draw) has `inv_density` 0.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub struct Block<const N: usize = LANES> {
    pub q: [[f32; N]; 3],
    pub e: [[f32; N]; 3],
    pub n: [[f32; N]; 3],
    pub inv_range: [f32; N],
    /// 1 / the source density of the point, in its own measure ([`Lights::point_pdf`]).
    pub inv_density: [f32; N],
    pub triangle: [bool; N],
    pub two_sided: [bool; N],
    /// Bit `k`: lane `k` holds a distant light.
    pub distant: u16,
    /// Bit `k`: lane `k` holds a light the lanes do not compute (spot lights), evaluated one
    /// by one.
    pub scalar: u16,
}

impl<const N: usize> Default for Block<N> {
    fn default() -> Self {
        Self {
            q: [[0.0; N]; 3],
            e: [[0.0; N]; 3],
            n: [[0.0; N]; 3],
            inv_range: [0.0; N],
            inv_density: [0.0; N],
            triangle: [false; N],
            two_sided: [false; N],
            distant: 0,
            scalar: 0,
        }
    }
}

impl<const N: usize> Block<N> {
    #[inline(always)]
    fn set_vec(lanes: &mut [[f32; N]; 3], k: usize, v: Vec3) {
        (lanes[0][k], lanes[1][k], lanes[2][k]) = (v.x, v.y, v.z);
    }

    /// Lane `k` holds `point`, drawn with density `density`.
    fn set(&mut self, k: usize, lights: &Lights, point: &LightPoint, density: f32) {
        const { assert!(N <= 16, "`scalar` has a bit per lane") };
        self.inv_density[k] = 1.0 / density;
        match lights.lane_light(point) {
            Some(LaneLight::Point {
                position,
                intensity,
                inv_range,
            }) => {
                Self::set_vec(&mut self.q, k, position);
                Self::set_vec(&mut self.e, k, intensity);
                self.inv_range[k] = inv_range;
            }
            Some(LaneLight::Triangle {
                point,
                normal,
                two_sided,
                emission,
            }) => {
                Self::set_vec(&mut self.q, k, point);
                Self::set_vec(&mut self.e, k, emission);
                Self::set_vec(&mut self.n, k, normal);
                (self.triangle[k], self.two_sided[k]) = (true, two_sided);
            }
            Some(LaneLight::Distant { wi, radiance }) => {
                Self::set_vec(&mut self.q, k, wi);
                Self::set_vec(&mut self.e, k, radiance);
                self.distant |= 1 << k;
            }
            None => self.scalar |= 1 << k,
        }
    }
}

impl<const N: usize> Block<N> {
    /// The first `n` of `points` (their densities unknown: `inv_density` 1), e.g. the samples
    /// of a pixel's neighbours.
    #[inline]
    pub fn of(lights: &Lights, points: &[LightPoint; N], n: usize) -> Self {
        let mut block = Self::default();
        for (k, point) in points.iter().enumerate().take(n) {
            block.set(k, lights, point, 1.0);
        }
        block
    }
}

/// The frame's candidates ([module doc](self)).
#[derive(Debug, Default)]
pub struct LightPool {
    blocks: Vec<Block>,
    points: Vec<[LightPoint; LANES]>,
    /// Scratch: the entries' strata.
    strata: Vec<u32>,
}

impl LightPool {
    /// Draws `blocks` blocks (at least one) for sample index `index` of the frames seeded
    /// `seed`; the same pool whatever the thread count.
    pub fn build(&mut self, lights: &Lights, blocks: usize, seed: u64, index: u32) {
        let blocks = blocks.max(1);
        self.blocks.clear();
        self.blocks.resize(blocks, Block::default());
        self.points.clear();
        self.points.resize(blocks, [LightPoint::default(); LANES]);
        let stream = hash(&[seed, index as u64, POOL_STREAM]);
        // The entries' strata of the light choice, in a random order (Fisher-Yates).
        let n = blocks * LANES;
        self.strata.clear();
        self.strata.extend(0..n as u32);
        let mut rng = Rng::new(stream, u64::MAX);
        for i in (1..n).rev() {
            let j = ((rng.next_u32() as u64 * (i as u64 + 1)) >> 32) as usize;
            self.strata.swap(i, j);
        }
        let strata = &self.strata;
        self.blocks
            .par_chunks_mut(BUILD_CHUNK)
            .zip(self.points.par_chunks_mut(BUILD_CHUNK))
            .enumerate()
            .for_each(|(c, (blocks, points))| {
                let mut rng = Rng::new(stream, c as u64);
                for (b, (block, points)) in blocks.iter_mut().zip(points).enumerate() {
                    for (k, point) in points.iter_mut().enumerate() {
                        let stratum = strata[(c * BUILD_CHUNK + b) * LANES + k];
                        let u_select = (stratum as f32 + rng.next_f32()) / n as f32;
                        let u = Vec2::new(rng.next_f32(), rng.next_f32());
                        if let Some((p, density)) = lights.draw(u_select, u) {
                            if density > 0.0 && density.is_finite() {
                                *point = p;
                                block.set(k, lights, &p, density);
                            }
                        }
                    }
                }
            });
    }

    /// The block that the uniform 32-bit number `u` picks, and its light points.
    #[inline(always)]
    pub fn pick(&self, u: u32) -> (&Block, &[LightPoint; LANES]) {
        let b = ((u as u64 * self.blocks.len() as u64) >> 32) as usize;
        (&self.blocks[b], &self.points[b])
    }

    pub fn is_empty(&self) -> bool {
        self.blocks.is_empty()
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.blocks.capacity() * std::mem::size_of::<Block>()
            + self.points.capacity() * std::mem::size_of::<[LightPoint; LANES]>()
    }
}
