//! `f32` lanes behind one trait, so the traversal and the triangle test are written once and
//! compiled for AVX2, SSE (x86_64) or plain scalar code (any target): four lanes for a ray
//! against four triangles, eight for a node's children or for eight rays against one triangle.
//!
//! `min` and `max` follow the SSE rule: when either operand is NaN the *second* operand is
//! returned. The slab test relies on it (a NaN slab distance, from `0 * inf` when a ray with a
//! zero direction component starts exactly on a slab plane, is then ignored).
//!
//! Every implementation rounds every operation as IEEE 754 single precision does, with no
//! fused multiply-add, so a lane computes the same bits whatever its width or instruction set.

/// `f32` lanes and their comparison masks.
pub(crate) trait Lanes: Copy {
    type Mask: Copy;
    /// `[f32; N]` for `N` lanes.
    type Array: Copy;
    /// Every lane's bit set.
    const ALL: u32;

    fn splat(x: f32) -> Self;
    fn load(a: &Self::Array) -> Self;
    fn to_array(self) -> Self::Array;

    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn div(self, o: Self) -> Self;
    /// `self < o ? self : o` per lane (NaN in either lane gives `o`).
    fn min(self, o: Self) -> Self;
    /// `self > o ? self : o` per lane (NaN in either lane gives `o`).
    fn max(self, o: Self) -> Self;
    fn abs(self) -> Self;

    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    fn eq(self, o: Self) -> Self::Mask;
    /// `!(self >= o)`: true where `self < o` or either is NaN.
    fn not_ge(self, o: Self) -> Self::Mask;
    /// `!(self <= o)`: true where `self > o` or either is NaN.
    fn not_le(self, o: Self) -> Self::Mask;

    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// `!a & b`.
    fn andnot(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Bit `i` set when lane `i` is true.
    fn bits(m: Self::Mask) -> u32;
    /// The mask whose lane `i` is bit `i` of `bits`.
    fn mask(bits: u32) -> Self::Mask;
    /// Per lane, `a` where `m` is true and `b` elsewhere (bit for bit, NaNs included).
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
}

/// The indices of the set bits of a lane mask, lowest first.
#[derive(Clone, Copy)]
pub(crate) struct SetBits(pub u32);

impl Iterator for SetBits {
    type Item = usize;

    #[inline(always)]
    fn next(&mut self) -> Option<usize> {
        if self.0 == 0 {
            return None;
        }
        let i = self.0.trailing_zeros() as usize;
        self.0 &= self.0 - 1;
        Some(i)
    }
}

/// Four lanes: one ray against the four triangles of a packet.
pub(crate) trait F32x4: Lanes<Array = [f32; 4]> {}

impl<S: Lanes<Array = [f32; 4]>> F32x4 for S {}

/// `W` lanes for the box tests of a `W`-wide node (and for `W` rays at once).
pub(crate) trait BoxLanes<const W: usize>: Lanes<Array = [f32; W]> {
    /// Bit `i` set where lane `i` of `self <= o` (bits `0..W` only).
    #[inline(always)]
    fn le_bits(self, o: Self) -> u32 {
        Self::bits(self.le(o))
    }
}

impl<const W: usize, L: Lanes<Array = [f32; W]>> BoxLanes<W> for L {}

/// The portable fallback: four scalars.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Scalar4(pub [f32; 4]);

impl Scalar4 {
    #[inline(always)]
    fn map2(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        Scalar4([
            f(self.0[0], o.0[0]),
            f(self.0[1], o.0[1]),
            f(self.0[2], o.0[2]),
            f(self.0[3], o.0[3]),
        ])
    }

    #[inline(always)]
    fn cmp(self, o: Self, f: impl Fn(f32, f32) -> bool) -> u32 {
        (f(self.0[0], o.0[0]) as u32)
            | (f(self.0[1], o.0[1]) as u32) << 1
            | (f(self.0[2], o.0[2]) as u32) << 2
            | (f(self.0[3], o.0[3]) as u32) << 3
    }
}

impl Lanes for Scalar4 {
    type Mask = u32;
    type Array = [f32; 4];
    const ALL: u32 = 0xf;

    #[inline(always)]
    fn splat(x: f32) -> Self {
        Scalar4([x; 4])
    }
    #[inline(always)]
    fn load(a: &[f32; 4]) -> Self {
        Scalar4(*a)
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 4] {
        self.0
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self.map2(o, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self.map2(o, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.map2(o, |a, b| a * b)
    }
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        self.map2(o, |a, b| a / b)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        self.map2(o, |a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        self.map2(o, |a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Scalar4(self.0.map(f32::abs))
    }
    #[inline(always)]
    fn lt(self, o: Self) -> u32 {
        self.cmp(o, |a, b| a < b)
    }
    #[inline(always)]
    fn le(self, o: Self) -> u32 {
        self.cmp(o, |a, b| a <= b)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> u32 {
        self.cmp(o, |a, b| a > b)
    }
    #[inline(always)]
    fn ge(self, o: Self) -> u32 {
        self.cmp(o, |a, b| a >= b)
    }
    #[inline(always)]
    fn eq(self, o: Self) -> u32 {
        self.cmp(o, |a, b| a == b)
    }
    #[inline(always)]
    #[allow(clippy::neg_cmp_op_on_partial_ord)] // deliberately true for NaN
    fn not_ge(self, o: Self) -> u32 {
        self.cmp(o, |a, b| !(a >= b))
    }
    #[inline(always)]
    #[allow(clippy::neg_cmp_op_on_partial_ord)] // deliberately true for NaN
    fn not_le(self, o: Self) -> u32 {
        self.cmp(o, |a, b| !(a <= b))
    }
    #[inline(always)]
    fn and(a: u32, b: u32) -> u32 {
        a & b
    }
    #[inline(always)]
    fn or(a: u32, b: u32) -> u32 {
        a | b
    }
    #[inline(always)]
    fn andnot(a: u32, b: u32) -> u32 {
        !a & b & 0xf
    }
    #[inline(always)]
    fn bits(m: u32) -> u32 {
        m
    }
    #[inline(always)]
    fn mask(bits: u32) -> u32 {
        bits & 0xf
    }
    #[inline(always)]
    fn select(m: u32, a: Self, b: Self) -> Self {
        Scalar4(std::array::from_fn(|i| {
            if m >> i & 1 != 0 {
                a.0[i]
            } else {
                b.0[i]
            }
        }))
    }
}

/// Eight lanes in two four-lane halves.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pair<S>(pub S, pub S);

impl<S: F32x4> Lanes for Pair<S> {
    type Mask = (S::Mask, S::Mask);
    type Array = [f32; 8];
    const ALL: u32 = 0xff;

    #[inline(always)]
    fn splat(x: f32) -> Self {
        Pair(S::splat(x), S::splat(x))
    }
    #[inline(always)]
    fn load(a: &[f32; 8]) -> Self {
        let (lo, hi) = a.split_at(4);
        Pair(
            S::load(lo.try_into().unwrap()),
            S::load(hi.try_into().unwrap()),
        )
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        let (lo, hi) = (self.0.to_array(), self.1.to_array());
        [lo[0], lo[1], lo[2], lo[3], hi[0], hi[1], hi[2], hi[3]]
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Pair(self.0.add(o.0), self.1.add(o.1))
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Pair(self.0.sub(o.0), self.1.sub(o.1))
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Pair(self.0.mul(o.0), self.1.mul(o.1))
    }
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        Pair(self.0.div(o.0), self.1.div(o.1))
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        Pair(self.0.min(o.0), self.1.min(o.1))
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        Pair(self.0.max(o.0), self.1.max(o.1))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Pair(self.0.abs(), self.1.abs())
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self::Mask {
        (self.0.lt(o.0), self.1.lt(o.1))
    }
    #[inline(always)]
    fn le(self, o: Self) -> Self::Mask {
        (self.0.le(o.0), self.1.le(o.1))
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self::Mask {
        (self.0.gt(o.0), self.1.gt(o.1))
    }
    #[inline(always)]
    fn ge(self, o: Self) -> Self::Mask {
        (self.0.ge(o.0), self.1.ge(o.1))
    }
    #[inline(always)]
    fn eq(self, o: Self) -> Self::Mask {
        (self.0.eq(o.0), self.1.eq(o.1))
    }
    #[inline(always)]
    fn not_ge(self, o: Self) -> Self::Mask {
        (self.0.not_ge(o.0), self.1.not_ge(o.1))
    }
    #[inline(always)]
    fn not_le(self, o: Self) -> Self::Mask {
        (self.0.not_le(o.0), self.1.not_le(o.1))
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        (S::and(a.0, b.0), S::and(a.1, b.1))
    }
    #[inline(always)]
    fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        (S::or(a.0, b.0), S::or(a.1, b.1))
    }
    #[inline(always)]
    fn andnot(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        (S::andnot(a.0, b.0), S::andnot(a.1, b.1))
    }
    #[inline(always)]
    fn bits(m: Self::Mask) -> u32 {
        (S::bits(m.0) & 0xf) | (S::bits(m.1) & 0xf) << 4
    }
    #[inline(always)]
    fn mask(bits: u32) -> Self::Mask {
        (S::mask(bits & 0xf), S::mask(bits >> 4 & 0xf))
    }
    #[inline(always)]
    fn select(m: Self::Mask, a: Self, b: Self) -> Self {
        Pair(S::select(m.0, a.0, b.0), S::select(m.1, a.1, b.1))
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx::Avx8;

#[cfg(target_arch = "x86_64")]
mod avx {
    use std::arch::x86_64::*;

    use super::Lanes;

    /// Eight lanes in an AVX register.
    ///
    /// Only for code compiled with `#[target_feature(enable = "avx2")]` and run after AVX2 was
    /// detected (the native backend's `Isa::Avx2` path): the methods are plain
    /// `#[inline(always)]` functions so that they inline into such code, and they use AVX and
    /// AVX2 instructions without checking.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx8(__m256);

    impl Lanes for Avx8 {
        type Mask = __m256;
        type Array = [f32; 8];
        const ALL: u32 = 0xff;

        #[inline(always)]
        fn splat(x: f32) -> Self {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            Avx8(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        fn load(a: &[f32; 8]) -> Self {
            // SAFETY: `a` is 32 readable bytes and `loadu` needs no alignment; aVX and AVX2 are available wherever `Avx8` is used.
            Avx8(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 8] {
            let mut out = [0.0f32; 8];
            // SAFETY: `out` is 32 writable bytes and `storeu` needs no alignment; aVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) };
            out
        }
        #[inline(always)]
        fn add(self, o: Self) -> Self {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            Avx8(unsafe { _mm256_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn sub(self, o: Self) -> Self {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            Avx8(unsafe { _mm256_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn mul(self, o: Self) -> Self {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            Avx8(unsafe { _mm256_mul_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn div(self, o: Self) -> Self {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            Avx8(unsafe { _mm256_div_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            Avx8(unsafe { _mm256_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            Avx8(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            Avx8(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        fn lt(self, o: Self) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn le(self, o: Self) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn gt(self, o: Self) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn ge(self, o: Self) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_cmp_ps::<_CMP_GE_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn eq(self, o: Self) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn not_ge(self, o: Self) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_cmp_ps::<_CMP_NGE_UQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn not_le(self, o: Self) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_cmp_ps::<_CMP_NLE_UQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn and(a: __m256, b: __m256) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_and_ps(a, b) }
        }
        #[inline(always)]
        fn or(a: __m256, b: __m256) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_or_ps(a, b) }
        }
        #[inline(always)]
        fn andnot(a: __m256, b: __m256) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_andnot_ps(a, b) }
        }
        #[inline(always)]
        fn bits(m: __m256) -> u32 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe { _mm256_movemask_ps(m) as u32 }
        }
        #[inline(always)]
        fn mask(bits: u32) -> __m256 {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            unsafe {
                let lane = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
                let b = _mm256_and_si256(_mm256_set1_epi32(bits as i32), lane);
                _mm256_castsi256_ps(_mm256_cmpeq_epi32(b, lane))
            }
        }
        #[inline(always)]
        fn select(m: __m256, a: Self, b: Self) -> Self {
            // SAFETY: AVX and AVX2 are available wherever `Avx8` is used.
            Avx8(unsafe { _mm256_blendv_ps(b.0, a.0, m) })
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use sse::Sse4;

#[cfg(target_arch = "x86_64")]
mod sse {
    use std::arch::x86_64::*;

    use super::Lanes;

    /// Four lanes in an SSE register (SSE2 is part of the x86_64 baseline).
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Sse4(__m128);

    impl Lanes for Sse4 {
        type Mask = __m128;
        type Array = [f32; 4];
        const ALL: u32 = 0xf;

        #[inline(always)]
        fn splat(x: f32) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_set1_ps(x) })
        }
        #[inline(always)]
        fn load(a: &[f32; 4]) -> Self {
            // SAFETY: `a` is 16 readable bytes and `loadu` needs no alignment; sSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 4] {
            let mut out = [0.0f32; 4];
            // SAFETY: `out` is 16 writable bytes and `storeu` needs no alignment; sSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_storeu_ps(out.as_mut_ptr(), self.0) };
            out
        }
        #[inline(always)]
        fn add(self, o: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn sub(self, o: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn mul(self, o: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_mul_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn div(self, o: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_div_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_andnot_ps(_mm_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        fn lt(self, o: Self) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_cmplt_ps(self.0, o.0) }
        }
        #[inline(always)]
        fn le(self, o: Self) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_cmple_ps(self.0, o.0) }
        }
        #[inline(always)]
        fn gt(self, o: Self) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_cmpgt_ps(self.0, o.0) }
        }
        #[inline(always)]
        fn ge(self, o: Self) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_cmpge_ps(self.0, o.0) }
        }
        #[inline(always)]
        fn eq(self, o: Self) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_cmpeq_ps(self.0, o.0) }
        }
        #[inline(always)]
        fn not_ge(self, o: Self) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_cmpnge_ps(self.0, o.0) }
        }
        #[inline(always)]
        fn not_le(self, o: Self) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_cmpnle_ps(self.0, o.0) }
        }
        #[inline(always)]
        fn and(a: __m128, b: __m128) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_and_ps(a, b) }
        }
        #[inline(always)]
        fn or(a: __m128, b: __m128) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_or_ps(a, b) }
        }
        #[inline(always)]
        fn andnot(a: __m128, b: __m128) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_andnot_ps(a, b) }
        }
        #[inline(always)]
        fn bits(m: __m128) -> u32 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe { _mm_movemask_ps(m) as u32 }
        }
        #[inline(always)]
        fn mask(bits: u32) -> __m128 {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            unsafe {
                let lane = _mm_setr_epi32(1, 2, 4, 8);
                let b = _mm_and_si128(_mm_set1_epi32(bits as i32), lane);
                _mm_castsi128_ps(_mm_cmpeq_epi32(b, lane))
            }
        }
        #[inline(always)]
        fn select(m: __m128, a: Self, b: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_or_ps(_mm_and_ps(m, a.0), _mm_andnot_ps(m, b.0)) })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check<S: F32x4>() {
        let a = S::load(&[1.0, -2.0, f32::NAN, 0.0]);
        let b = S::splat(0.5);
        assert_eq!(
            a.max(b).to_array()[2],
            0.5,
            "NaN first operand yields the second"
        );
        assert_eq!(a.min(b).to_array()[2], 0.5);
        assert_eq!(S::bits(a.lt(b)), 0b1010);
        assert_eq!(S::bits(a.not_ge(b)), 0b1110);
        assert_eq!(S::bits(a.eq(S::splat(0.0))), 0b1000);
        assert_eq!(S::bits(S::andnot(a.lt(b), a.le(S::splat(1.0)))), 0b0001);
        assert_eq!(a.abs().to_array()[1], 2.0);
        assert_eq!(a.mul(b).add(b).sub(b).div(b).to_array()[0], 1.0);
    }

    #[test]
    fn scalar_semantics() {
        check::<Scalar4>();
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn sse_semantics() {
        check::<Sse4>();
    }

    fn check_box<const W: usize, B: BoxLanes<W>>() {
        let mut a = [0.0f32; W];
        for (i, x) in a.iter_mut().enumerate() {
            *x = i as f32 - 2.0;
        }
        a[1] = f32::NAN;
        let a = B::load(&a);
        let b = B::splat(0.5);
        let m = a.max(b).to_array();
        assert_eq!(m[1], 0.5, "NaN first operand yields the second");
        assert_eq!(a.min(b).to_array()[1], 0.5);
        assert_eq!(m[0], 0.5);
        assert_eq!(a.min(b).to_array()[0], -2.0);
        // Lanes 0, 2 (values -2, 0) are <= 0.5; lane 1 is NaN.
        assert_eq!(a.le_bits(b), 0b101);
        assert_eq!(b.le_bits(b), (1 << W) - 1);
        assert_eq!(a.sub(b).mul(b).to_array()[W - 1], (W as f32 - 3.5) * 0.5);
    }

    /// Every operation of `L`, lane by lane, against plain `f32` arithmetic (bit for bit, on
    /// values with NaN, infinities, signed zeros and integer bit patterns), and `select` with
    /// `mask` for every mask.
    fn check_lanes<const W: usize, L: BoxLanes<W>>() {
        let values = [
            1.5,
            -2.25,
            f32::NAN,
            0.0,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::from_bits(7),
            3.0e-39,
            1.0e30,
            -7.0,
        ];
        let pick = |k: usize| -> [f32; W] { std::array::from_fn(|i| values[(i * 3 + k) % 11]) };
        for k in 0..11 {
            let (x, y) = (pick(k), pick(k + 5));
            let (a, b) = (L::load(&x), L::load(&y));
            let same = |got: [f32; W], f: &dyn Fn(f32, f32) -> f32| {
                for i in 0..W {
                    let want = f(x[i], y[i]);
                    let ok =
                        got[i].to_bits() == want.to_bits() || (got[i].is_nan() && want.is_nan());
                    assert!(
                        ok,
                        "lane {i}: {} {} gave {}, want {want}",
                        x[i], y[i], got[i]
                    );
                }
            };
            same(a.add(b).to_array(), &|p, q| p + q);
            same(a.sub(b).to_array(), &|p, q| p - q);
            same(a.mul(b).to_array(), &|p, q| p * q);
            same(a.div(b).to_array(), &|p, q| p / q);
            same(a.min(b).to_array(), &|p, q| if p < q { p } else { q });
            same(a.max(b).to_array(), &|p, q| if p > q { p } else { q });
            same(a.abs().to_array(), &|p, _| p.abs());
            let bits = |f: &dyn Fn(f32, f32) -> bool| -> u32 {
                (0..W).map(|i| u32::from(f(x[i], y[i])) << i).sum()
            };
            assert_eq!(L::bits(a.lt(b)), bits(&|p, q| p < q));
            assert_eq!(L::bits(a.le(b)), bits(&|p, q| p <= q));
            assert_eq!(L::bits(a.gt(b)), bits(&|p, q| p > q));
            assert_eq!(L::bits(a.ge(b)), bits(&|p, q| p >= q));
            assert_eq!(L::bits(a.eq(b)), bits(&|p, q| p == q));
            #[allow(clippy::neg_cmp_op_on_partial_ord)] // deliberately true for NaN
            {
                assert_eq!(L::bits(a.not_ge(b)), bits(&|p, q| !(p >= q)));
                assert_eq!(L::bits(a.not_le(b)), bits(&|p, q| !(p <= q)));
            }
        }
        let (x, y) = (pick(0), pick(1));
        for m in 0..1u32 << W {
            assert_eq!(L::bits(L::mask(m)), m);
            let got = L::select(L::mask(m), L::load(&x), L::load(&y)).to_array();
            for i in 0..W {
                let want = if m >> i & 1 != 0 { x[i] } else { y[i] };
                assert_eq!(got[i].to_bits(), want.to_bits(), "mask {m:b} lane {i}");
            }
        }
        assert_eq!(L::ALL, (1 << W) - 1);
    }

    #[test]
    fn lanes_are_ieee_single_precision_lane_by_lane() {
        check_lanes::<4, Scalar4>();
        check_lanes::<8, Pair<Scalar4>>();
        #[cfg(target_arch = "x86_64")]
        {
            check_lanes::<4, Sse4>();
            check_lanes::<8, Pair<Sse4>>();
            if is_x86_feature_detected!("avx2") {
                check_lanes::<8, Avx8>();
            }
        }
    }

    #[test]
    fn box_lanes_semantics() {
        check_box::<8, Pair<Scalar4>>();
        #[cfg(target_arch = "x86_64")]
        {
            check_box::<8, Pair<Sse4>>();
            if is_x86_feature_detected!("avx2") {
                check_box::<8, Avx8>();
            }
        }
    }
}
