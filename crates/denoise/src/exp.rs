//! `e^x` for the filters' weights, in a form the compiler vectorises (no calls, no branches):
//! `2^(x log2 e)` split into an integer power (the float's exponent bits) and a polynomial of
//! the fraction. Relative error below 2e-5 (tested against `f32::exp`; the polynomial's is 3e-6,
//! the rest the rounding of `x log2 e` at large `|x|`). This is the scalar form (SVGF's
//! reference passes); [`crate::simd::exp_neg`] is the same in lanes.

const LOG2_E: f32 = std::f32::consts::LOG2_E;
/// Inputs below this give `e^-87` (about 1.6e-38): a weight that vanishes beside any weight
/// of order 1 in a sum, and keeps the exponent bits in range.
pub(crate) const LOWEST: f32 = -87.0;
/// `2^f` on `[0, 1)`: a degree-4 polynomial (highest power first), 1 at 0, fitted for the
/// least largest relative error (3e-6; Lawson's iteration on 20,001 points).
pub(crate) const EXP2_POLY: [f32; 5] =
    [0.013_426_607, 0.052_242_6, 0.241_280_15, 0.693_044_84, 1.0];

/// `e^x` for `x <= 0`. A NaN (a weight's `0 * inf`, from overflowing differences) counts as
/// minus infinity: the weight vanishes.
#[inline(always)]
pub fn exp_neg(x: f32) -> f32 {
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    let x = if !(x >= LOWEST) { LOWEST } else { x };
    let t = x * LOG2_E;
    let i = t.floor();
    let f = t - i;
    let p = EXP2_POLY[1..]
        .iter()
        .fold(EXP2_POLY[0], |acc, &c| acc * f + c);
    // 2^i from the exponent bits: i + 127 is a whole number in 1..=127 (x >= LOWEST), so
    // adding 2^23 puts it in the float's low mantissa bits, which the shift moves into the
    // exponent (the other bits shift out). No float-to-integer conversion: it vectorises.
    f32::from_bits((i + (127.0 + 8_388_608.0)).to_bits() << 23) * p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agrees_with_the_standard_exp() {
        let mut worst = 0.0f32;
        for k in 0..=870_000 {
            let x = -(k as f32) * 1e-4;
            let (a, b) = (exp_neg(x), x.exp());
            worst = worst.max(((a - b) / b).abs());
        }
        assert!(worst < 2e-5, "relative error {worst}");
        assert_eq!(exp_neg(0.0), 1.0);
        assert_eq!(exp_neg(-0.0), 1.0);
        assert!(exp_neg(f32::NEG_INFINITY) < 1e-37);
        assert!(exp_neg(f32::NAN) < 1e-37);
    }
}
