//! Minimum and maximum of floats that are never NaN, one instruction each.
//!
//! `f32::min` and `f64::max` return the other operand when one is NaN (IEEE 754 minNum); on
//! x86-64 that is a compare, a mask and a blend around each `minss`. The screen-error terms and
//! the slacks of the vertex stream take thousands of them per update and never see a NaN (their
//! inputs are finite coordinates and positive constants), so a plain compare and select serves:
//! for operands that are not NaN it returns the same value. A debug build checks the operands.

/// [`Extremum::lesser`] and [`Extremum::greater`] for `f32` and `f64`.
pub trait Extremum: Copy + PartialOrd {
    /// The smaller of two operands, neither NaN.
    #[inline(always)]
    fn lesser(self, other: Self) -> Self {
        #[allow(clippy::eq_op)]
        {
            debug_assert!(self == self && other == other, "NaN operand");
        }
        if other < self { other } else { self }
    }

    /// The larger of two operands, neither NaN.
    #[inline(always)]
    fn greater(self, other: Self) -> Self {
        #[allow(clippy::eq_op)]
        {
            debug_assert!(self == self && other == other, "NaN operand");
        }
        if other > self { other } else { self }
    }
}

impl Extremum for f32 {}
impl Extremum for f64 {}

#[cfg(test)]
mod tests {
    use super::Extremum;

    #[test]
    fn agrees_with_min_and_max_off_nan() {
        let xs = [
            f64::NEG_INFINITY,
            -3.5,
            -1e-300,
            0.0,
            1e-300,
            2.0,
            7.25e10,
            f64::INFINITY,
        ];
        for &a in &xs {
            for &b in &xs {
                assert_eq!(a.lesser(b), a.min(b), "{a} {b}");
                assert_eq!(a.greater(b), a.max(b), "{a} {b}");
                let (a, b) = (a as f32, b as f32);
                assert_eq!(a.lesser(b), a.min(b), "{a} {b}");
                assert_eq!(a.greater(b), a.max(b), "{a} {b}");
            }
        }
    }
}
