//! `f32` lanes as one value: sixteen in an AVX-512 register, eight in an AVX2 one, or sixteen
//! in a plain array (any other processor), behind one trait so that a filter's hot loop is
//! written once for [`F32xN::N`] pixels at a time.
//!
//! The filters first wrote their lanes as `[f32; 16]` arrays in loops the compiler vectorises;
//! that works while a loop's body is small, but in SVGF's a-trous taps LLVM kept the sums in
//! memory (a load, an add and a masked store per sum and tap). Values of these types are SSA
//! values the compiler keeps in registers.
//!
//! # Safety
//! The AVX-512 and AVX2 types call their instructions from methods compiled without the target
//! features (trait methods cannot carry them): they are sound only where the processor has
//! them. The types are private to this module, so no code outside it can name them: values of
//! them are made only by a [`Kernel`] that [`dispatch`] runs with them, inside a function
//! compiled for those features and called after the run-time check, and they never leave it.

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;
use std::ops::{Add, Div, Mul, Sub};

use glam::Vec3;
use pathlight_core::color::LUMINANCE;

/// The most lanes of one value (the width the filters' planes are padded for).
pub const LANES: usize = 16;

/// `N` `f32` lanes (at most [`LANES`]).
pub trait F32xN:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    /// The lanes.
    const N: usize;
    /// Per-lane truth values.
    type Mask: Copy;
    /// # Safety
    /// `p..p + N` is readable.
    unsafe fn load(p: *const f32) -> Self;
    /// # Safety
    /// `p..p + N` is writable.
    unsafe fn store(self, p: *mut f32);
    /// [`Self::store`] past the caches (a non-temporal store) where the processor has it:
    /// for buffers read again only after many more bytes have gone through the caches. The
    /// writing thread ends its stores with [`store_fence`] before another reads them.
    ///
    /// # Safety
    /// `p..p + N` is writable and aligned to its size (`4 N` bytes).
    #[inline(always)]
    unsafe fn stream(self, p: *mut f32) {
        // SAFETY: the caller's contract.
        unsafe { self.store(p) }
    }
    fn splat(x: f32) -> Self;
    /// The lanes in the first `N` values (the rest zero).
    fn to_array(self) -> [f32; LANES];
    /// `self * b + c`, fused where the processor has FMA.
    fn mul_add(self, b: Self, c: Self) -> Self;
    fn abs(self) -> Self;
    fn sqrt(self) -> Self;
    /// `self`, or `floor` in the lanes where `self` is below it or NaN (one instruction).
    fn at_least(self, floor: Self) -> Self;
    /// `1 / self`, a division correctly rounded in every implementation (the processors'
    /// estimates, `rcp_ps` and `rcp14_ps` refined by a Newton step, left the last bit to an
    /// estimate that differs between Intel's and AMD's processors, and so the frames: the
    /// filters take it once per pixel, not per tap, where a division's 16 cycles per register
    /// do not show).
    fn recip(self) -> Self;
    fn floor(self) -> Self;
    /// The lanes' bits shifted left by 23 (an integer operation on the float's bits: a whole
    /// number in the low mantissa bits moves into the exponent).
    fn shl_23(self) -> Self;
    /// `self * 2^i` for whole numbers `i` in `-126..=127` (exact, as the product of a float
    /// and a power of two is): the power from its exponent bits ([`F32xN::shl_23`]) and a
    /// product, or one instruction where the processor has it.
    #[inline(always)]
    fn mul_pow2(self, i: Self) -> Self {
        (i + Self::splat(127.0 + 8_388_608.0)).shl_23() * self
    }
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    fn ne(self, o: Self) -> Self::Mask;
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Some lane is true.
    fn any(m: Self::Mask) -> bool;
    /// Every lane is true.
    fn all(m: Self::Mask) -> bool;
    /// `a` where `m`, else `b`.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// The smallest lane (of lanes that are numbers).
    #[inline(always)]
    fn min_lane(self) -> f32 {
        let a = self.to_array();
        let mut m = a[0];
        for &x in &a[1..Self::N] {
            m = m.min(x);
        }
        m
    }
    /// The largest lane (of lanes that are numbers).
    #[inline(always)]
    fn max_lane(self) -> f32 {
        -(Self::splat(0.0) - self).min_lane()
    }
    /// `*base.add(index * stride)` in the lanes where `m`, 0 in the others (not read); the
    /// indices are whole numbers in `0..2^24` (exact in an `f32`).
    ///
    /// # Safety
    /// Every address of a lane where `m` is readable, and `index * stride` fits an `i32`.
    #[inline(always)]
    unsafe fn gather(base: *const f32, index: Self, stride: i32, m: Self::Mask) -> Self {
        // SAFETY: the caller's contract (rows of `stride`, column 0).
        unsafe { Self::gather_rows(base, index, Self::splat(0.0), stride, m) }
    }
    /// `*base.add(row * pitch + column)` in the lanes where `m`, 0 in the others (not read);
    /// `row` and `column` are whole numbers in `0..2^24`.
    ///
    /// # Safety
    /// Every address of a lane where `m` is readable, and `row * pitch + column` fits an
    /// `i32`.
    unsafe fn gather_rows(
        base: *const f32,
        row: Self,
        column: Self,
        pitch: i32,
        m: Self::Mask,
    ) -> Self;
    /// The `K` channels of the `N` records of `K` `f32`s from `p` on (`p[K * j + c]` in lane
    /// `j` of value `c`): one load per channel and shuffles where the processor has them (for
    /// `K` 2 and 3), gathers elsewhere.
    ///
    /// # Safety
    /// `p..p + K * N` is readable, and `K * N` fits an `i32`.
    #[inline(always)]
    unsafe fn load_interleaved<const K: usize>(p: *const f32) -> [Self; K] {
        // SAFETY: the caller's contract.
        unsafe { gather_interleaved(p) }
    }
    /// `p[index]` in each lane, `index` whole numbers in `0..2N`: the `2N` floats from `p` on
    /// loaded and permuted (two loads and one permutation where the processor has it; a
    /// gather reads the same). For a group's taps that fall within `2N` pixels of one row.
    ///
    /// # Safety
    /// `p..p + 2N` is readable.
    #[inline(always)]
    unsafe fn window(p: *const f32, index: Self) -> Self {
        let all = index.ge(Self::splat(0.0));
        // SAFETY: the caller's contract (every index is in `0..2N`).
        unsafe { Self::gather(p, index, 1, all) }
    }
}

/// How a group reads the fields of pixels `(qx, qy)` of a row-major layout (a previous frame
/// reprojected: taps that move with the camera): by loads where the lanes take consecutive
/// pixels of one row, by two loads permuted ([`F32xN::window`]) where they lie within `2N`
/// pixels of one row (a rotation's motion, which varies along the row: most of the taps that
/// are not consecutive), else by gathers.
#[derive(Clone, Copy)]
pub(crate) enum Fetch<V> {
    /// Lane 0's field 0 at this index, the others after it.
    Run(usize),
    /// The lanes' fields 0 at this index plus these offsets (in `0..2N`).
    Window(usize, V),
    /// Gathers.
    Gather,
}

impl<V: F32xN> Fetch<V> {
    /// For the pixels `(qx, qy)` of the lanes where `inside` (whole numbers inside the
    /// image), in a layout of `len` floats whose pixel `(x, y)` has its field 0 at `y pitch +
    /// x` and its last field `reach` floats further on.
    #[inline(always)]
    pub fn new(qx: V, qy: V, inside: V::Mask, pitch: usize, reach: usize, len: usize) -> Self {
        // The rows and columns of the lanes inside (the others count as the first's).
        let (inf, minf) = (V::splat(f32::INFINITY), V::splat(f32::NEG_INFINITY));
        let (row, last) = (
            V::select(inside, qy, inf).min_lane(),
            V::select(inside, qy, minf).max_lane(),
        );
        if row != last || !row.is_finite() {
            return Self::Gather;
        }
        let (low, high) = (
            V::select(inside, qx, inf).min_lane(),
            V::select(inside, qx, minf).max_lane(),
        );
        let at = row as usize * pitch + low as usize;
        if V::all(inside) && !V::any(qx.ne(V::splat(low) + iota::<V>())) {
            Self::Run(at)
        } else if high - low < (2 * V::N) as f32 && at + reach + 2 * V::N <= len {
            Self::Window(at, V::select(inside, qx - V::splat(low), V::splat(0.0)))
        } else {
            Self::Gather
        }
    }

    /// The field `offset` floats from field 0 of the pixels `(qx, qy)` in the lanes where `m`
    /// (some of those `Self::new` was given), 0 in the others.
    ///
    /// # Safety
    /// `planes` is the layout `Self::new` was given, `offset` at most its `reach`, `pitch`
    /// its, and `qy pitch + qx + offset` of each lane where `m` is in `planes` and fits an
    /// `i32`.
    #[inline(always)]
    pub unsafe fn read(
        self,
        planes: &[f32],
        offset: usize,
        qx: V,
        qy: V,
        pitch: usize,
        m: V::Mask,
    ) -> V {
        match self {
            Self::Run(at) => V::select(m, load_first(&planes[at + offset..]), V::splat(0.0)),
            Self::Window(at, index) => {
                assert!(at + offset + 2 * V::N <= planes.len());
                // SAFETY: the `2N` floats from `at + offset` on are in `planes` (just checked).
                let v = unsafe { V::window(planes.as_ptr().add(at + offset), index) };
                V::select(m, v, V::splat(0.0))
            }
            // SAFETY: the caller's contract.
            Self::Gather => unsafe {
                V::gather_rows(planes.as_ptr().add(offset), qy, qx, pitch as i32, m)
            },
        }
    }
}

/// [`F32xN::load_interleaved`] by gathers.
///
/// # Safety
/// As [`F32xN::load_interleaved`].
#[inline(always)]
unsafe fn gather_interleaved<V: F32xN, const K: usize>(p: *const f32) -> [V; K] {
    let lane = iota::<V>();
    let all = lane.ge(V::splat(0.0));
    // SAFETY: the caller's contract: lane j's channel c is `p[K j + c]`.
    std::array::from_fn(|c| unsafe { V::gather(p.add(c), lane, K as i32, all) })
}

/// The kinds of lanes, narrowest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
pub enum Isa {
    /// Plain arrays (any processor).
    Portable,
    /// An AVX2 register with FMA (8 lanes).
    Avx2,
    /// One AVX-512 register with FMA.
    #[default]
    Avx512,
}

impl Isa {
    /// `portable`, `avx2`, or anything else for the widest.
    pub fn named(name: &str) -> Self {
        match name {
            "portable" => Self::Portable,
            "avx2" => Self::Avx2,
            _ => Self::Avx512,
        }
    }
}

/// Runs `f` with the widest lanes this processor has, at most `cap` (narrower ones for tests;
/// the check reads a cached flag).
#[inline(always)]
pub fn dispatch<R>(cap: Isa, f: impl Kernel<R>) -> R {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("fma") {
        if cap >= Isa::Avx512 && std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the processor has AVX-512 and FMA (checked just above).
            return unsafe { run_avx512(f) };
        }
        if cap >= Isa::Avx2 && std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2 and FMA (checked just above).
            return unsafe { run_avx2(f) };
        }
    }
    f.run::<Portable>()
}

/// A computation over lanes of any width (a generic closure).
pub trait Kernel<R> {
    fn run<V: F32xN>(self) -> R;
}

/// A row's work in groups of lanes: run by [`ByGroups`], a [`Kernel`] that takes the row's
/// groups from left to right.
pub trait Groups {
    /// The row's pixels.
    fn width(&self) -> usize;
    /// The [`F32xN::N`] pixels from `x0` on (fewer at the row's end); a flag the row's groups
    /// add up with `or`.
    fn group<V: F32xN>(&mut self, x0: usize) -> bool;
}

/// Runs a [`Groups`] over its row; whether some group gave `true`.
pub struct ByGroups<G>(pub G);

impl<G: Groups> Kernel<bool> for ByGroups<G> {
    #[inline(always)]
    fn run<V: F32xN>(mut self) -> bool {
        let mut flag = false;
        let mut x0 = 0;
        while x0 < self.0.width() {
            flag |= self.0.group::<V>(x0);
            x0 += V::N;
        }
        flag
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,fma")]
unsafe fn run_avx512<R>(f: impl Kernel<R>) -> R {
    f.run::<Avx512>()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn run_avx2<R>(f: impl Kernel<R>) -> R {
    f.run::<Avx2>()
}

/// The lanes that are finite (not infinite, not NaN).
#[inline(always)]
pub fn finite<V: F32xN>(x: V) -> V::Mask {
    V::splat(f32::INFINITY).gt(x.abs())
}

/// The lanes where all three values are finite.
#[inline(always)]
pub fn finite3<V: F32xN>(c: [V; 3]) -> V::Mask {
    V::and(finite(c[0]), V::and(finite(c[1]), finite(c[2])))
}

/// Stores the first `n` lanes of `value` at the start of `out` (all of them in one store when
/// `n` is [`F32xN::N`]; the others are left alone).
#[inline(always)]
pub fn store_first<V: F32xN>(value: V, n: usize, out: &mut [f32]) {
    if n == V::N {
        assert!(V::N <= out.len());
        // SAFETY: checked just above.
        unsafe { value.store(out.as_mut_ptr()) }
    } else {
        out[..n].copy_from_slice(&value.to_array()[..n]);
    }
}

/// [`store_first`] past the caches ([`F32xN::stream`]) where all `N` lanes are stored and
/// `out` is aligned to their size, else as [`store_first`] does.
#[inline(always)]
pub fn stream_first<V: F32xN>(value: V, n: usize, out: &mut [f32]) {
    if n == V::N && out.as_ptr().cast::<u8>().align_offset(4 * V::N) == 0 {
        assert!(V::N <= out.len());
        // SAFETY: checked just above: in bounds, and aligned to the lanes' size.
        unsafe { value.stream(out.as_mut_ptr()) }
    } else {
        store_first(value, n, out);
    }
}

/// Copies `src` into `out` (of the same length) with [`stream_first`]'s stores, in lanes of
/// `isa` at most.
pub fn stream_copy(isa: Isa, out: &mut [f32], src: &[f32]) {
    struct Copy<'a> {
        out: &'a mut [f32],
        src: &'a [f32],
    }
    impl Kernel<()> for Copy<'_> {
        #[inline(always)]
        fn run<V: F32xN>(self) {
            for (out, src) in self.out.chunks_mut(V::N).zip(self.src.chunks(V::N)) {
                if out.len() == V::N {
                    stream_first(load_first::<V>(src), V::N, out);
                } else {
                    out.copy_from_slice(src);
                }
            }
        }
    }
    assert_eq!(out.len(), src.len());
    dispatch(isa, Copy { out, src });
}

/// Orders this thread's earlier [`F32xN::stream`] stores before its later stores (`sfence`),
/// so that another thread which synchronises with it afterwards reads them.
#[inline(always)]
pub fn store_fence() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE, which has `sfence`, is part of every x86-64 processor.
    unsafe {
        std::arch::x86_64::_mm_sfence()
    }
}

/// The lanes' positions: 0, 1, 2, ...
#[inline(always)]
pub fn iota<V: F32xN>() -> V {
    const IOTA: [f32; LANES] = {
        let mut a = [0.0; LANES];
        let mut j = 0;
        while j < LANES {
            a[j] = j as f32;
            j += 1;
        }
        a
    };
    // SAFETY: `IOTA` has `LANES` lanes.
    unsafe { V::load(IOTA.as_ptr()) }
}

/// The first [`F32xN::N`] values of `plane` (which has them).
#[inline(always)]
pub fn load_first<V: F32xN>(plane: &[f32]) -> V {
    assert!(V::N <= plane.len());
    // SAFETY: checked just above.
    unsafe { V::load(plane.as_ptr()) }
}

/// `f32::max` in lanes (a NaN lane gives the other one).
#[inline(always)]
pub fn max<V: F32xN>(a: V, b: V) -> V {
    let m = V::select(a.ge(b), a, b);
    V::select(m.ne(m), a, m)
}

/// `f32::min` in lanes (a NaN lane gives the other one).
#[inline(always)]
pub fn min<V: F32xN>(a: V, b: V) -> V {
    let m = V::select(a.ge(b), b, a);
    V::select(m.ne(m), b, m)
}

/// The three channels of `buffer`'s pixels `index` in the lanes where `m` (0 in the others).
///
/// # Safety
/// The lanes where `m` index pixels of `buffer` (whole numbers below its length).
#[inline(always)]
pub unsafe fn gather3<V: F32xN>(buffer: &[Vec3], index: V, m: V::Mask) -> [V; 3] {
    let base = buffer.as_ptr().cast::<f32>();
    let mut c = [V::splat(0.0); 3];
    for (k, c) in c.iter_mut().enumerate() {
        // SAFETY: the caller's (a `Vec3` is three `f32`s).
        *c = unsafe { V::gather(base.add(k), index, 3, m) };
    }
    c
}

/// A pixel's entry of `K` `f32`s and nothing else (for [`channels`]).
///
/// # Safety
/// The type is `K` `f32`s, without padding, aligned as an `f32`.
pub unsafe trait Floats<const K: usize>: Copy {}

// SAFETY: one `f32`; glam's `Vec2` and `Vec3` are `#[repr(C)]` structs of two and three.
unsafe impl Floats<1> for f32 {}
// SAFETY: as above.
unsafe impl Floats<2> for glam::Vec2 {}
// SAFETY: as above.
unsafe impl Floats<3> for Vec3 {}
// SAFETY: arrays of `f32` have no padding.
unsafe impl<const K: usize> Floats<K> for [f32; K] {}

/// The `K` channels of `buffer`'s entries `i0..i0 + n` (`n` at most [`F32xN::N`]) in lanes,
/// 0 in the lanes past `n`: loads and shuffles for a whole group
/// ([`F32xN::load_interleaved`]), gathers for a row's last one.
#[inline(always)]
pub fn channels<V: F32xN, T: Floats<K>, const K: usize>(
    buffer: &[T],
    i0: usize,
    n: usize,
) -> [V; K] {
    assert!(n <= V::N && i0 + n <= buffer.len());
    // SAFETY: entry `i0` is in `buffer` (or its end, with `n` 0).
    let base = unsafe { buffer.as_ptr().add(i0).cast::<f32>() };
    if n == V::N {
        // SAFETY: the `K N` floats from entry `i0` on are in `buffer` (checked above; an
        // entry is `K` floats: `Floats`).
        return unsafe { V::load_interleaved::<K>(base) };
    }
    let lane = iota::<V>();
    let valid = V::splat(n as f32).gt(lane);
    // SAFETY: the lanes where `valid` index entries `0..n` from `i0` on, in `buffer`.
    std::array::from_fn(|c| unsafe { V::gather(base.add(c), lane, K as i32, valid) })
}

/// [`pathlight_core::color::luminance`] in lanes (the same products and sums).
#[inline(always)]
pub fn luminance_lanes<V: F32xN>(c: [V; 3]) -> V {
    V::splat(LUMINANCE[0]) * c[0] + V::splat(LUMINANCE[1]) * c[1] + V::splat(LUMINANCE[2]) * c[2]
}

/// `e^x` of lanes the caller has kept within `LOWEST..=0` (not NaN): [`crate::exp::exp_neg`]'s
/// method and polynomial.
#[inline(always)]
pub fn exp_neg_in_range<V: F32xN>(x: V) -> V {
    exp2_neg_in_range(x * V::splat(std::f32::consts::LOG2_E))
}

/// `2^t` of lanes the caller has kept within `LOWEST log2(e)..=0` (not NaN), by the power of
/// two and polynomial of [`crate::exp::exp_neg`]: for callers whose exponents are in base 2
/// (their coefficients times `log2(e)`).
#[inline(always)]
pub fn exp2_neg_in_range<V: F32xN>(t: V) -> V {
    use crate::exp::EXP2_POLY;
    let i = t.floor();
    let f = t - i;
    // No closures in the lanes' code: the compiler compiles a closure apart, without the
    // processor features, and then may leave the instructions' wrappers as calls.
    let mut p = V::splat(EXP2_POLY[0]);
    for &c in &EXP2_POLY[1..] {
        p = p.mul_add(f, V::splat(c));
    }
    p.mul_pow2(i)
}

/// A plain array: any processor.
#[derive(Clone, Copy)]
struct Portable([f32; LANES]);

impl Portable {
    #[inline(always)]
    fn map(self, f: impl Fn(f32) -> f32) -> Self {
        Self(self.0.map(f))
    }

    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        Self(std::array::from_fn(|j| f(self.0[j], o.0[j])))
    }
}

macro_rules! portable_op {
    ($trait:ident, $method:ident, $op:tt) => {
        impl $trait for Portable {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: Self) -> Self {
                self.zip(o, |a, b| a $op b)
            }
        }
    };
}
portable_op!(Add, add, +);
portable_op!(Sub, sub, -);
portable_op!(Mul, mul, *);
portable_op!(Div, div, /);

impl F32xN for Portable {
    const N: usize = LANES;
    type Mask = [bool; LANES];
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        // SAFETY: the caller's contract; the read is unaligned.
        Self(unsafe { std::ptr::read_unaligned(p.cast()) })
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f32) {
        // SAFETY: the caller's contract; the write is unaligned.
        unsafe { std::ptr::write_unaligned(p.cast(), self.0) }
    }
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Self([x; LANES])
    }
    #[inline(always)]
    fn to_array(self) -> [f32; LANES] {
        self.0
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        self * b + c
    }
    #[inline(always)]
    fn abs(self) -> Self {
        self.map(f32::abs)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        self.map(f32::sqrt)
    }
    #[inline(always)]
    fn at_least(self, floor: Self) -> Self {
        self.zip(floor, |x, f| if x >= f { x } else { f })
    }
    #[inline(always)]
    fn recip(self) -> Self {
        self.map(|x| 1.0 / x)
    }
    #[inline(always)]
    fn floor(self) -> Self {
        self.map(f32::floor)
    }
    #[inline(always)]
    fn shl_23(self) -> Self {
        self.map(|x| f32::from_bits(x.to_bits() << 23))
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self::Mask {
        std::array::from_fn(|j| self.0[j] > o.0[j])
    }
    #[inline(always)]
    fn ge(self, o: Self) -> Self::Mask {
        std::array::from_fn(|j| self.0[j] >= o.0[j])
    }
    #[inline(always)]
    fn ne(self, o: Self) -> Self::Mask {
        std::array::from_fn(|j| self.0[j] != o.0[j])
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        std::array::from_fn(|j| a[j] && b[j])
    }
    #[inline(always)]
    fn any(m: Self::Mask) -> bool {
        m.contains(&true)
    }
    #[inline(always)]
    fn all(m: Self::Mask) -> bool {
        !m.contains(&false)
    }
    #[inline(always)]
    fn select(m: Self::Mask, a: Self, b: Self) -> Self {
        Self(std::array::from_fn(|j| if m[j] { a.0[j] } else { b.0[j] }))
    }
    #[inline(always)]
    unsafe fn gather_rows(
        base: *const f32,
        row: Self,
        column: Self,
        pitch: i32,
        m: Self::Mask,
    ) -> Self {
        Self(std::array::from_fn(|j| {
            if m[j] {
                let at = row.0[j] as isize * pitch as isize + column.0[j] as isize;
                // SAFETY: the caller's contract.
                unsafe { *base.offset(at) }
            } else {
                0.0
            }
        }))
    }
}

/// One AVX-512 register (see the module's safety note).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Avx512(__m512);

/// Runs an AVX-512 intrinsic.
#[cfg(target_arch = "x86_64")]
macro_rules! avx512 {
    ($e:expr) => {
        // SAFETY: `Avx512` values exist only in code run after the processor was found to
        // have AVX-512 and FMA (the module's safety note).
        unsafe { $e }
    };
}

#[cfg(target_arch = "x86_64")]
macro_rules! avx512_op {
    ($trait:ident, $method:ident, $intrinsic:ident) => {
        impl $trait for Avx512 {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: Self) -> Self {
                Self(avx512!($intrinsic(self.0, o.0)))
            }
        }
    };
}
#[cfg(target_arch = "x86_64")]
avx512_op!(Add, add, _mm512_add_ps);
#[cfg(target_arch = "x86_64")]
avx512_op!(Sub, sub, _mm512_sub_ps);
#[cfg(target_arch = "x86_64")]
avx512_op!(Mul, mul, _mm512_mul_ps);
#[cfg(target_arch = "x86_64")]
avx512_op!(Div, div, _mm512_div_ps);

#[cfg(target_arch = "x86_64")]
impl F32xN for Avx512 {
    const N: usize = 16;
    type Mask = __mmask16;
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        Self(avx512!(_mm512_loadu_ps(p)))
    }
    #[inline(always)]
    fn min_lane(self) -> f32 {
        avx512!(_mm512_reduce_min_ps(self.0))
    }
    #[inline(always)]
    fn max_lane(self) -> f32 {
        avx512!(_mm512_reduce_max_ps(self.0))
    }
    #[inline(always)]
    unsafe fn window(p: *const f32, index: Self) -> Self {
        // `vpermt2ps` takes each lane's index modulo 32.
        Self(avx512!(_mm512_permutex2var_ps(
            _mm512_loadu_ps(p),
            _mm512_cvttps_epi32(index.0),
            _mm512_loadu_ps(p.add(16))
        )))
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f32) {
        avx512!(_mm512_storeu_ps(p, self.0))
    }
    #[inline(always)]
    unsafe fn stream(self, p: *mut f32) {
        avx512!(_mm512_stream_ps(p, self.0))
    }
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Self(avx512!(_mm512_set1_ps(x)))
    }
    #[inline(always)]
    fn to_array(self) -> [f32; LANES] {
        let mut a = [0.0; LANES];
        avx512!(_mm512_storeu_ps(a.as_mut_ptr(), self.0));
        a
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        Self(avx512!(_mm512_fmadd_ps(self.0, b.0, c.0)))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Self(avx512!(_mm512_abs_ps(self.0)))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Self(avx512!(_mm512_sqrt_ps(self.0)))
    }
    #[inline(always)]
    fn at_least(self, floor: Self) -> Self {
        // `maxps` gives its second operand where either is NaN.
        Self(avx512!(_mm512_max_ps(self.0, floor.0)))
    }
    #[inline(always)]
    fn recip(self) -> Self {
        // A division, correctly rounded: the same bits on every processor (an estimate's
        // refinement, `rcp14` and a Newton step, left the last bit to the estimate).
        Self(avx512!(_mm512_div_ps(_mm512_set1_ps(1.0), self.0)))
    }
    #[inline(always)]
    fn floor(self) -> Self {
        Self(avx512!(_mm512_roundscale_ps::<
            { _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC },
        >(self.0)))
    }
    #[inline(always)]
    fn shl_23(self) -> Self {
        Self(avx512!(_mm512_castsi512_ps(_mm512_slli_epi32::<23>(
            _mm512_castps_si512(self.0)
        ))))
    }
    #[inline(always)]
    fn mul_pow2(self, i: Self) -> Self {
        // `vscalefps`: `self * 2^floor(i)`.
        Self(avx512!(_mm512_scalef_ps(self.0, i.0)))
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self::Mask {
        avx512!(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(self.0, o.0))
    }
    #[inline(always)]
    fn ge(self, o: Self) -> Self::Mask {
        avx512!(_mm512_cmp_ps_mask::<_CMP_GE_OQ>(self.0, o.0))
    }
    #[inline(always)]
    fn ne(self, o: Self) -> Self::Mask {
        avx512!(_mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(self.0, o.0))
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        a & b
    }
    #[inline(always)]
    fn any(m: Self::Mask) -> bool {
        m != 0
    }
    #[inline(always)]
    fn all(m: Self::Mask) -> bool {
        m == 0xffff
    }
    #[inline(always)]
    fn select(m: Self::Mask, a: Self, b: Self) -> Self {
        Self(avx512!(_mm512_mask_blend_ps(m, b.0, a.0)))
    }
    #[inline(always)]
    unsafe fn gather_rows(
        base: *const f32,
        row: Self,
        column: Self,
        pitch: i32,
        m: Self::Mask,
    ) -> Self {
        let offsets = avx512!(_mm512_add_epi32(
            _mm512_mullo_epi32(_mm512_cvttps_epi32(row.0), _mm512_set1_epi32(pitch)),
            _mm512_cvttps_epi32(column.0)
        ));
        Self(avx512!(_mm512_mask_i32gather_ps::<4>(
            _mm512_setzero_ps(),
            m,
            offsets,
            base
        )))
    }
    #[inline(always)]
    unsafe fn load_interleaved<const K: usize>(p: *const f32) -> [Self; K] {
        if !(K == 2 || K == 3) {
            // SAFETY: the caller's contract.
            return unsafe { gather_interleaved(p) };
        }
        // SAFETY: the caller's contract (`K` registers from `p`).
        let v: [__m512; K] = std::array::from_fn(|r| unsafe { _mm512_loadu_ps(p.add(16 * r)) });
        std::array::from_fn(|c| {
            // Lane j wants element `K j + c` of the `16 K`: register `(K j + c) / 16`. The
            // first shuffle takes those of registers 0 and 1 (bit 4 of an index picks the
            // second), a second one those of register 2 into the rest.
            let [first, second] = &INTERLEAVED[K - 2][c];
            let pair = avx512!(_mm512_permutex2var_ps(
                v[0],
                _mm512_loadu_si512(first.as_ptr().cast()),
                v[1]
            ));
            if K == 2 {
                return Self(pair);
            }
            Self(avx512!(_mm512_permutex2var_ps(
                pair,
                _mm512_loadu_si512(second.as_ptr().cast()),
                v[K - 1]
            )))
        })
    }
}

/// The indices of [`Avx512::load_interleaved`]'s shuffles for channel `c` of records of `k`
/// floats: the first (`second` false) takes lane j's element from registers 0 and 1 (index `e +
/// 16 r` for element `e` of register `r`); the second keeps the first's lanes (index j) but
/// for those in register 2 (index `16 + e`).
#[cfg(target_arch = "x86_64")]
const fn interleaved_indices(k: usize, c: usize, second: bool) -> [i32; 16] {
    let mut indices = [0; 16];
    let mut j = 0;
    while j < 16 {
        let g = k * j + c;
        let (r, e) = ((g / 16) as i32, (g % 16) as i32);
        indices[j] = match (second, r) {
            (false, 0 | 1) => e + 16 * r,
            (false, _) => 0,
            (true, 2) => 16 + e,
            (true, _) => j as i32,
        };
        j += 1;
    }
    indices
}

/// [`interleaved_indices`] of records of 2 and 3 floats, by channel and shuffle.
#[cfg(target_arch = "x86_64")]
const INTERLEAVED: [[[[i32; 16]; 2]; 3]; 2] = {
    let mut t = [[[[0; 16]; 2]; 3]; 2];
    let mut k = 2;
    while k <= 3 {
        let mut c = 0;
        while c < k {
            t[k - 2][c][0] = interleaved_indices(k, c, false);
            t[k - 2][c][1] = interleaved_indices(k, c, true);
            c += 1;
        }
        k += 1;
    }
    t
};

/// One AVX2 register, eight lanes (see the module's safety note).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Avx2(__m256);

/// Runs an AVX2 intrinsic.
#[cfg(target_arch = "x86_64")]
macro_rules! avx2 {
    ($e:expr) => {
        // SAFETY: `Avx2` values exist only in code run after the processor was found to have
        // AVX2 and FMA (the module's safety note).
        unsafe { $e }
    };
}

#[cfg(target_arch = "x86_64")]
macro_rules! avx2_op {
    ($trait:ident, $method:ident, $intrinsic:ident) => {
        impl $trait for Avx2 {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: Self) -> Self {
                Self(avx2!($intrinsic(self.0, o.0)))
            }
        }
    };
}
#[cfg(target_arch = "x86_64")]
avx2_op!(Add, add, _mm256_add_ps);
#[cfg(target_arch = "x86_64")]
avx2_op!(Sub, sub, _mm256_sub_ps);
#[cfg(target_arch = "x86_64")]
avx2_op!(Mul, mul, _mm256_mul_ps);
#[cfg(target_arch = "x86_64")]
avx2_op!(Div, div, _mm256_div_ps);

#[cfg(target_arch = "x86_64")]
impl F32xN for Avx2 {
    const N: usize = 8;
    type Mask = __m256;
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        Self(avx2!(_mm256_loadu_ps(p)))
    }
    #[inline(always)]
    unsafe fn window(p: *const f32, index: Self) -> Self {
        // Each half permuted by the index modulo 8, then the second half's where the index
        // is 8 or more.
        let i = avx2!(_mm256_cvttps_epi32(index.0));
        let (low, high) = (
            avx2!(_mm256_permutevar8x32_ps(_mm256_loadu_ps(p), i)),
            avx2!(_mm256_permutevar8x32_ps(_mm256_loadu_ps(p.add(8)), i)),
        );
        let upper = avx2!(_mm256_cmp_ps::<_CMP_GE_OQ>(index.0, _mm256_set1_ps(8.0)));
        Self(avx2!(_mm256_blendv_ps(low, high, upper)))
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f32) {
        avx2!(_mm256_storeu_ps(p, self.0))
    }
    #[inline(always)]
    unsafe fn stream(self, p: *mut f32) {
        avx2!(_mm256_stream_ps(p, self.0))
    }
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Self(avx2!(_mm256_set1_ps(x)))
    }
    #[inline(always)]
    fn to_array(self) -> [f32; LANES] {
        let mut a = [0.0; LANES];
        // SAFETY: `a` has room for 8 lanes.
        unsafe { self.store(a.as_mut_ptr()) };
        a
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        Self(avx2!(_mm256_fmadd_ps(self.0, b.0, c.0)))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Self(avx2!(_mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0)))
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Self(avx2!(_mm256_sqrt_ps(self.0)))
    }
    #[inline(always)]
    fn at_least(self, floor: Self) -> Self {
        // `maxps` gives its second operand where either is NaN.
        Self(avx2!(_mm256_max_ps(self.0, floor.0)))
    }
    #[inline(always)]
    fn recip(self) -> Self {
        // A division, correctly rounded: `rcp_ps`'s estimate differs between processors
        // (Intel's and AMD's give other bits), and a Newton step on it left its last bit to
        // the estimate, so that frames differed from one processor to another.
        Self(avx2!(_mm256_div_ps(_mm256_set1_ps(1.0), self.0)))
    }
    #[inline(always)]
    fn floor(self) -> Self {
        Self(avx2!(_mm256_floor_ps(self.0)))
    }
    #[inline(always)]
    fn shl_23(self) -> Self {
        Self(avx2!(_mm256_castsi256_ps(_mm256_slli_epi32::<23>(
            _mm256_castps_si256(self.0)
        ))))
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self::Mask {
        avx2!(_mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0))
    }
    #[inline(always)]
    fn ge(self, o: Self) -> Self::Mask {
        avx2!(_mm256_cmp_ps::<_CMP_GE_OQ>(self.0, o.0))
    }
    #[inline(always)]
    fn ne(self, o: Self) -> Self::Mask {
        avx2!(_mm256_cmp_ps::<_CMP_NEQ_UQ>(self.0, o.0))
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        avx2!(_mm256_and_ps(a, b))
    }
    #[inline(always)]
    fn any(m: Self::Mask) -> bool {
        avx2!(_mm256_movemask_ps(m)) != 0
    }
    #[inline(always)]
    fn all(m: Self::Mask) -> bool {
        avx2!(_mm256_movemask_ps(m)) == 0xff
    }
    #[inline(always)]
    fn select(m: Self::Mask, a: Self, b: Self) -> Self {
        Self(avx2!(_mm256_blendv_ps(b.0, a.0, m)))
    }
    #[inline(always)]
    unsafe fn gather_rows(
        base: *const f32,
        row: Self,
        column: Self,
        pitch: i32,
        m: Self::Mask,
    ) -> Self {
        let offsets = avx2!(_mm256_add_epi32(
            _mm256_mullo_epi32(_mm256_cvttps_epi32(row.0), _mm256_set1_epi32(pitch)),
            _mm256_cvttps_epi32(column.0)
        ));
        Self(avx2!(_mm256_mask_i32gather_ps::<4>(
            _mm256_setzero_ps(),
            base,
            offsets,
            m
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Streamed stores write what plain ones would, aligned or not, whole groups or a tail,
    /// with every kind of lanes, and nothing beside.
    #[test]
    fn streamed_stores_store() {
        let src: Vec<f32> = (0..200).map(|k| k as f32 * 0.5 - 7.0).collect();
        for isa in [Isa::Portable, Isa::Avx2, Isa::Avx512] {
            for offset in 0..17 {
                for len in [0, 1, 7, 15, 16, 17, 33, 100] {
                    let mut out = vec![-1.0f32; len + 40];
                    stream_copy(isa, &mut out[offset..offset + len], &src[..len]);
                    store_fence();
                    assert_eq!(
                        &out[offset..offset + len],
                        &src[..len],
                        "{isa:?} {offset} {len}"
                    );
                    assert!(out[..offset]
                        .iter()
                        .chain(&out[offset + len..])
                        .all(|&x| x == -1.0));
                }
            }
        }
    }

    /// Every operation of every type this processor has, against plain `f32` arithmetic.
    #[test]
    fn the_lane_types_agree_with_plain_arithmetic() {
        struct Check;
        impl Kernel<()> for Check {
            fn run<V: F32xN>(self) {
                let a: [f32; LANES] = std::array::from_fn(|j| j as f32 * 0.75 - 5.0);
                let b: [f32; LANES] = std::array::from_fn(|j| 2.5 - (j % 5) as f32);
                // SAFETY: the arrays have 16 lanes.
                let (va, vb) = unsafe { (V::load(a.as_ptr()), V::load(b.as_ptr())) };
                let same = |v: V, f: &dyn Fn(f32, f32) -> f32| {
                    let v = v.to_array();
                    assert!(v[V::N..].iter().all(|x| *x == 0.0), "beyond the lanes");
                    for j in 0..V::N {
                        let e = f(a[j], b[j]);
                        assert!(
                            v[j] == e || (v[j] - e).abs() <= 1e-6 * e.abs(),
                            "lane {j}: {} against {e}",
                            v[j]
                        );
                    }
                };
                same(va + vb, &|x, y| x + y);
                same(va - vb, &|x, y| x - y);
                same(va * vb, &|x, y| x * y);
                same(va / vb, &|x, y| x / y);
                same(va.mul_add(vb, va), &|x, y| x * y + x);
                same(va.abs().sqrt(), &|x, _| x.abs().sqrt());
                same(va.floor(), &|x, _| x.floor());
                same(va.at_least(vb), &|x, y| if x >= y { x } else { y });
                // The reciprocal (a division: exact to rounding), on values from 1e-30 to
                // 1e30, negative ones too.
                for scale in [1e-30, 1e-3, 1.0, 7.0e4, 1e30] {
                    let r = (va * V::splat(scale)).recip().to_array();
                    for (j, r) in r.iter().enumerate().take(V::N) {
                        let want = 1.0 / (a[j] as f64 * scale as f64);
                        let error = ((*r as f64 - want) / want).abs();
                        assert!(error < 2.5e-7, "1 / {} = {want}: {r}", a[j] * scale);
                    }
                }
                // A NaN lane takes the floor.
                let nan = V::select(va.gt(V::splat(0.0)), V::splat(f32::NAN), va);
                same(nan.at_least(vb), &|x, y| {
                    if x > 0.0 || x < y {
                        y
                    } else {
                        x
                    }
                });
                // Powers of two from 2^-126 to 2^127 (the whole lanes of `a` spread over them).
                let i = (va * V::splat(16.0)).floor();
                same(vb.mul_pow2(i), &|x, y| {
                    y * 2f32.powi((x * 16.0).floor() as i32)
                });
                same(V::splat(3.0).shl_23(), &|_, _| {
                    f32::from_bits(3f32.to_bits() << 23)
                });
                let m = V::and(va.gt(vb), va.ne(V::splat(-2.0)));
                same(V::select(m, va, vb), &|x, y| {
                    if x > y && x != -2.0 {
                        x
                    } else {
                        y
                    }
                });
                same(V::select(va.ge(vb), va, vb), &|x, y| {
                    if x >= y {
                        x
                    } else {
                        y
                    }
                });
                assert!(V::any(vb.gt(va)) && !V::any(va.gt(V::splat(100.0))));
                assert!(V::all(va.gt(V::splat(-6.0))) && !V::all(va.gt(V::splat(-4.0))));
                // Lanes j read row `j % 3`, column `j / 2` of a 3x8 table where `b` is at
                // least 0; 0 elsewhere.
                let table: [f32; 24] = std::array::from_fn(|k| k as f32 * 0.5 + 1.0);
                let rows = iota::<V>() - (iota::<V>() / V::splat(3.0)).floor() * V::splat(3.0);
                let columns = (iota::<V>() * V::splat(0.5)).floor();
                // SAFETY: the offsets are at most 2 * 8 + 7 < 24, the table's length.
                let g = unsafe {
                    V::gather_rows(table.as_ptr(), rows, columns, 8, vb.ge(V::splat(0.0)))
                };
                let g = g.to_array();
                for j in 0..V::N {
                    let want = if b[j] >= 0.0 {
                        table[(j % 3) * 8 + j / 2]
                    } else {
                        0.0
                    };
                    assert_eq!(g[j], want, "lane {j}");
                }
                // Lanes j read `a[15 - j]` where `b` is at least 0, stride 1; 0 elsewhere.
                let index = V::splat(15.0) - (va - V::splat(-5.0)) / V::splat(0.75);
                // SAFETY: the indices are 0..16 and `a` has 16 lanes.
                let g = unsafe { V::gather(a.as_ptr(), index, 1, vb.ge(V::splat(0.0))) };
                same(g, &|x, y| {
                    if y >= 0.0 {
                        a[15 - ((x + 5.0) / 0.75).round() as usize]
                    } else {
                        0.0
                    }
                });
                let mut out = [7.0; LANES];
                // SAFETY: `out` has 16 lanes.
                unsafe { (va * V::splat(2.0)).store(out.as_mut_ptr()) };
                for j in 0..LANES {
                    assert_eq!(out[j], if j < V::N { a[j] * 2.0 } else { 7.0 });
                }
                // `e^x`, floored at `LOWEST`.
                let exp_neg = |x: V| exp_neg_in_range(x.at_least(V::splat(crate::exp::LOWEST)));
                let e = exp_neg(V::splat(-1.5) * va.abs()).to_array();
                for j in 0..V::N {
                    let x = -1.5 * a[j].abs();
                    let scalar = crate::exp::exp_neg(x);
                    assert!((e[j] - scalar).abs() <= 1e-6 * scalar, "e^{x}: {}", e[j]);
                }
                for x in [f32::NAN, f32::NEG_INFINITY, -100.0] {
                    assert!(exp_neg(V::splat(x)).to_array()[0] < 1e-37, "e^{x}");
                }
                // Records of 2, 3 (shuffles on AVX-512) and 5 floats (gathers) split into
                // their channels.
                let records: Vec<f32> = (0..5 * LANES).map(|k| k as f32 * 1.5 - 7.0).collect();
                fn channels<V: F32xN, const K: usize>(records: &[f32]) {
                    assert!(records.len() >= K * V::N);
                    // SAFETY: checked just above.
                    let c = unsafe { V::load_interleaved::<K>(records.as_ptr()) };
                    for (k, c) in c.iter().enumerate() {
                        let c = c.to_array();
                        for j in 0..LANES {
                            let want = if j < V::N { records[K * j + k] } else { 0.0 };
                            assert_eq!(c[j], want, "channel {k} of {K}, lane {j}");
                        }
                    }
                }
                channels::<V, 2>(&records);
                channels::<V, 3>(&records);
                channels::<V, 5>(&records);
            }
        }
        for isa in [Isa::Portable, Isa::Avx2, Isa::Avx512] {
            dispatch(isa, Check);
        }
    }
}
