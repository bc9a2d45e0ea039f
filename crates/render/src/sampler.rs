//! Low-discrepancy sample values: Owen-scrambled Sobol points (Burley 2020, crate
//! `sobol_burley`), decorrelated per pixel by the seed, consumed dimension by dimension.
//!
//! Every value depends only on (image seed, pixel, sample index, dimension), never on the thread
//! that asks, so images are the same whatever the thread count.
//!
//! [`SamplerKind::Independent`] replaces the Sobol points by independent uniform values (hashed
//! from the same coordinates): plain Monte Carlo, whose error falls exactly as 1/spp, which
//! experiments use as the textbook baseline.

use glam::Vec2;
use pathlight_core::rng::{hash, unit_f32};
use serde::{Deserialize, Serialize};

/// Where the sample values come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SamplerKind {
    /// Owen-scrambled Sobol points (stratified in every pair of consecutive dimensions).
    #[default]
    Sobol,
    /// Independent uniform values (plain Monte Carlo).
    Independent,
}

/// Samples per Sobol sequence in `sobol_burley`; later indices continue in a fresh,
/// independently scrambled sequence.
const SEQUENCE_LENGTH: u32 = 1 << 16;

/// `sobol_burley::sample_4d` computed faster, with the same values. The reversed-bit Sobol
/// integers are XOR-linear in the bits of the (shuffled) index, so a table per dimension set of
/// the integers of each 4-bit digit of the index replaces the loop over index bits (four
/// lookups; at 1 KiB per set the tables of a path's sets stay in the L1 cache), and the index
/// shuffle, which depends only on the sample, is done once per sampler instead of once per
/// set.
mod table {
    use std::sync::OnceLock;

    use sobol_burley::parts::{hash_int4, owen_scramble_int4_rev, sobol_int4_rev, Int4};

    /// Dimension sets with tables (every set of `sobol_burley`).
    pub const SETS: usize = sobol_burley::NUM_DIMENSION_SETS_4D as usize;

    /// The Sobol integers of each value of each 4-bit digit (digit `k` holds index bits
    /// `16 + 4 k ..`, as `sobol_int4_rev` sees the reversed shuffled index).
    pub struct SetTable {
        digits: [[Int4; 16]; 4],
    }

    fn table(set: u32) -> &'static SetTable {
        static TABLES: [OnceLock<Box<SetTable>>; SETS] = [const { OnceLock::new() }; SETS];
        TABLES[set as usize].get_or_init(|| {
            Box::new(SetTable {
                digits: std::array::from_fn(|k| {
                    std::array::from_fn(|b| sobol_int4_rev((b as u32) << (16 + 4 * k), set))
                }),
            })
        })
    }

    /// The top 16 bits of the reversed, shuffled sample index (what `sample_4d` computes
    /// first from `index` and `seed`).
    #[inline]
    pub fn shuffled(index: u32, seed: u32) -> u16 {
        let rev = sobol_burley::parts::owen_scramble_rev(
            index.reverse_bits(),
            sobol_burley::parts::hash(seed ^ 0x79c6_8e4a),
        );
        (rev >> 16) as u16
    }

    /// `sobol_burley::sample_4d(index, set, seed)` for `shuffled = shuffled(index, seed)`.
    #[inline]
    pub fn sample_4d(shuffled: u16, set: u32, seed: u32) -> [f32; 4] {
        let t = table(set);
        let s = shuffled as usize;
        let [d0, d1, d2, d3] = &t.digits;
        let sobol = (d0[s & 15] ^ d1[(s >> 4) & 15]) ^ (d2[(s >> 8) & 15] ^ d3[s >> 12]);
        let scramble = {
            let seed: Int4 = [seed.wrapping_mul(0x9c8f_2d3b); 4].into();
            let ds: Int4 = [set; 4].into();
            seed ^ ds ^ [0x912f_69ba, 0x174f_18ab, 0x691e_72ca, 0xb40c_c1b8].into()
        };
        owen_scramble_int4_rev(sobol, hash_int4(scramble))
            .reverse_bits()
            .to_f32_norm()
    }
}

/// The sample values of one pixel sample.
#[derive(Debug, Clone)]
pub struct PixelSampler {
    seed: u32,
    index: u32,
    /// The index as shuffled by the seed (see [`table::shuffled`]).
    shuffled: u16,
    dimension: u32,
    /// The values of dimensions `4 * cached_set .. 4 * cached_set + 4`, computed together
    /// (`sobol_burley::sample_4d` does four dimensions in one SIMD pass).
    cache: [f32; 4],
    cached_set: u32,
    independent: bool,
}

impl PixelSampler {
    /// The Sobol sampler of sample `sample_index` of pixel (`x`, `y`) of an image rendered with
    /// `seed`.
    #[inline]
    pub fn new(seed: u64, x: u32, y: u32, sample_index: u32) -> Self {
        Self::with_kind(SamplerKind::Sobol, seed, x, y, sample_index)
    }

    /// The sampler of the given kind for sample `sample_index` of pixel (`x`, `y`).
    #[inline]
    pub fn with_kind(kind: SamplerKind, seed: u64, x: u32, y: u32, sample_index: u32) -> Self {
        let sequence = sample_index / SEQUENCE_LENGTH;
        let h = hash(&[seed, x as u64, y as u64, sequence as u64]);
        let seed = (h ^ (h >> 32)) as u32;
        let index = sample_index % SEQUENCE_LENGTH;
        Self {
            seed,
            index,
            shuffled: table::shuffled(index, seed),
            dimension: 0,
            cache: [0.0; 4],
            cached_set: u32::MAX,
            independent: kind == SamplerKind::Independent,
        }
    }

    /// The next value in [0, 1).
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        let d = self.dimension;
        self.dimension += 1;
        if d < sobol_burley::NUM_DIMENSIONS && !self.independent {
            let set = d / 4;
            if set != self.cached_set {
                self.cache = table::sample_4d(self.shuffled, set, self.seed);
                self.cached_set = set;
            }
            self.cache[(d % 4) as usize]
        } else {
            // Independent values, or past the table: hashed values (deep path vertices, where
            // stratification no longer matters).
            let h = hash(&[self.seed as u64, self.index as u64, d as u64]);
            unit_f32((h >> 32) as u32)
        }
    }

    /// The next two values, from consecutive dimensions (stratified together).
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        let x = self.next_1d();
        Vec2::new(x, self.next_1d())
    }

    /// Skips to dimension `dimension` (so that each path vertex uses fixed dimensions).
    #[inline]
    pub fn set_dimension(&mut self, dimension: u32) {
        self.dimension = dimension;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 2D points of one pixel are stratified: with 2^k samples, each of the 2^k cells of a
    /// 2^(k/2) x 2^(k/2) grid holds exactly one point (Sobol's (0,2)-sequence property, kept by
    /// Owen scrambling).
    #[test]
    fn first_two_dimensions_are_stratified() {
        for (x, y) in [(0, 0), (17, 3)] {
            let n = 256;
            let mut cells = vec![0u32; n];
            for i in 0..n as u32 {
                let p = PixelSampler::new(7, x, y, i).next_2d();
                let c = (p.y * 16.0) as usize * 16 + (p.x * 16.0) as usize;
                cells[c] += 1;
            }
            assert!(cells.iter().all(|&c| c == 1), "{cells:?}");
        }
    }

    #[test]
    fn cached_sets_match_single_dimensions() {
        let mut s = PixelSampler::new(5, 3, 4, 77);
        s.set_dimension(6);
        let values: Vec<f32> = (0..9).map(|_| s.next_1d()).collect();
        let seed = PixelSampler::new(5, 3, 4, 77).seed;
        for (i, v) in values.iter().enumerate() {
            assert_eq!(*v, sobol_burley::sample(77, 6 + i as u32, seed));
        }
    }

    /// The tables give `sobol_burley::sample_4d`'s values exactly.
    #[test]
    fn tables_equal_sobol_burley() {
        let mut rng = pathlight_core::rng::Rng::new(3, 1);
        for _ in 0..20_000 {
            let index = rng.next_u32() & 0xffff;
            let seed = rng.next_u32();
            let set = rng.next_u32() % table::SETS as u32;
            let want = sobol_burley::sample_4d(index, set, seed);
            let got = table::sample_4d(table::shuffled(index, seed), set, seed);
            assert_eq!(got, want, "index {index} set {set} seed {seed}");
        }
    }

    #[test]
    fn pixels_are_decorrelated_and_values_are_deterministic() {
        let a = PixelSampler::new(1, 0, 0, 5).next_1d();
        let b = PixelSampler::new(1, 1, 0, 5).next_1d();
        assert_ne!(a, b);
        assert_eq!(a, PixelSampler::new(1, 0, 0, 5).next_1d());
        assert_ne!(a, PixelSampler::new(2, 0, 0, 5).next_1d());
    }

    /// Independent values are not stratified: over 256 samples some of the 256 cells of the
    /// 16 x 16 grid stay empty (expected 256 (1 - 1/256)^256, about 94), and the mean of each
    /// dimension is uniform's.
    #[test]
    fn independent_values_are_uniform_and_not_stratified() {
        let n = 256;
        let mut cells = vec![0u32; n];
        let mut sum = 0.0f64;
        for i in 0..n as u32 {
            let mut s = PixelSampler::with_kind(SamplerKind::Independent, 7, 3, 1, i);
            let p = s.next_2d();
            cells[(p.y * 16.0) as usize * 16 + (p.x * 16.0) as usize] += 1;
            sum += (p.x + p.y) as f64;
        }
        let empty = cells.iter().filter(|&&c| c == 0).count();
        assert!((60..130).contains(&empty), "{empty} empty cells");
        // Mean of 2n uniforms: standard deviation 1/sqrt(24 n) = 0.013.
        assert!((sum / (2 * n) as f64 - 0.5).abs() < 0.06);
    }

    #[test]
    fn dimensions_past_the_table_and_long_sequences_stay_uniform() {
        let mut sum = 0.0f64;
        let n = 20_000u32;
        for i in 0..n {
            let mut s = PixelSampler::new(3, 1, 2, i + 65_000);
            s.set_dimension(300);
            let v = s.next_1d();
            assert!((0.0..1.0).contains(&v));
            sum += v as f64;
        }
        // Mean of n uniforms: standard deviation 1/sqrt(12 n) = 0.002.
        assert!((sum / n as f64 - 0.5).abs() < 0.01);
    }
}
