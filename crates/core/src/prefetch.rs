//! A hint to the processor to bring memory into the cache ahead of its use.

/// Asks the processor to bring `x` into the cache (a hint, without effect on the results):
/// issued where a read's address is known well before the read, the miss overlaps the work
/// between them.
#[inline(always)]
pub fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch reads nothing the program sees, and `x` is a valid reference.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>((x as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}
