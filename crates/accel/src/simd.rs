//! Four-lane `f32` vectors behind one trait, so the traversal and the triangle test are written
//! once and compiled for SSE (x86_64) or plain scalar code (any target).
//!
//! `min` and `max` follow the SSE rule: when either operand is NaN the *second* operand is
//! returned. The slab test relies on it (a NaN slab distance, from `0 * inf` when a ray with a
//! zero direction component starts exactly on a slab plane, is then ignored).

/// Four `f32` lanes and their comparison masks.
pub(crate) trait F32x4: Copy {
    type Mask: Copy;

    fn splat(x: f32) -> Self;
    fn load(a: &[f32; 4]) -> Self;
    fn to_array(self) -> [f32; 4];

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
}

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

impl F32x4 for Scalar4 {
    type Mask = u32;

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
}

#[cfg(target_arch = "x86_64")]
pub(crate) use sse::Sse4;

#[cfg(target_arch = "x86_64")]
mod sse {
    use std::arch::x86_64::*;

    use super::F32x4;

    /// Four lanes in an SSE register (SSE2 is part of the x86_64 baseline).
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Sse4(__m128);

    impl F32x4 for Sse4 {
        type Mask = __m128;

        #[inline(always)]
        fn splat(x: f32) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline.
            Sse4(unsafe { _mm_set1_ps(x) })
        }
        #[inline(always)]
        fn load(a: &[f32; 4]) -> Self {
            // SAFETY: `a` is a valid reference to 16 readable bytes; `loadu` has no alignment
            // requirement, and SSE is always available on x86_64.
            Sse4(unsafe { _mm_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 4] {
            let mut out = [0.0f32; 4];
            // SAFETY: `out` is 16 writable bytes; `storeu` has no alignment requirement.
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
}
