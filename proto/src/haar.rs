//! The integer Haar transform that turns four children into a parent plus three details
//! (paper 000, section 3.2.3), and the quantised static-error code.
//!
//! Heights travel and are stored as integers in units of the terrain's z quantum. The paper's
//! real-valued Haar step (average plus three differences over 4) is replaced by its lossless
//! integer form, the 2D S-transform: a lifting step `lo = b + floor((a - b) / 2)`, `d = a - b`
//! along rows, then along columns. The parent is the children's mean rounded down, and from the
//! parent and the three details the four children come back *exactly*, so the client's mirror
//! holds bit for bit the heights the server holds, and no error accumulates down the tree.
//!
//! Border nodes with fewer than four children treat a missing child as a copy of its neighbour
//! across the missing row or column: the matching details are then 0 and the parent is the mean
//! of the children that exist, as the node's horizontal position is.

/// Child order as in [`crate::tree::NodeId::child`]: NW, NE, SW, SE.
pub type Quad = [i32; 4];

/// Which of the four children exist: `east` when the NE/SE column exists, `south` likewise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Presence {
    /// Whether the east column of children (NE, SE) exists.
    pub east: bool,
    /// Whether the south row of children (SW, SE) exists.
    pub south: bool,
}

impl Presence {
    /// All four children exist.
    pub const FULL: Presence = Presence {
        east: true,
        south: true,
    };
}

fn lift(a: i32, b: i32) -> (i32, i32) {
    let d = a.wrapping_sub(b);
    (b.wrapping_add(d >> 1), d)
}

fn unlift(lo: i32, d: i32) -> (i32, i32) {
    let b = lo.wrapping_sub(d >> 1);
    (b.wrapping_add(d), b)
}

/// Forward step: the parent height and the three details of four children heights.
/// Children that do not exist (per `p`) are ignored.
pub fn forward(c: Quad, p: Presence) -> (i32, [i32; 3]) {
    let ne = if p.east { c[1] } else { c[0] };
    let sw = if p.south { c[2] } else { c[0] };
    let se = match (p.east, p.south) {
        (true, true) => c[3],
        (true, false) => ne,
        (false, _) => sw,
    };
    let (top, dt) = lift(c[0], ne);
    let (bottom, db) = lift(sw, se);
    let (parent, dv) = lift(top, bottom);
    let (dh, dd) = lift(dt, db);
    (parent, [dv, dh, dd])
}

/// Inverse step: the four children heights from the parent and its details. Entries for
/// children that do not exist are copies of a neighbour and carry no meaning.
pub fn inverse(parent: i32, details: [i32; 3]) -> Quad {
    let [dv, dh, dd] = details;
    let (top, bottom) = unlift(parent, dv);
    let (dt, db) = unlift(dh, dd);
    let (nw, ne) = unlift(top, dt);
    let (sw, se) = unlift(bottom, db);
    [nw, ne, sw, se]
}

/// Static errors are sent as one byte: code 0 is 0 m, code `k > 0` is
/// `ERROR_BASE_M * 2^((k - 1) / 11)` metres, a 6.5 % step from 1 cm up to about 89 km.
pub const ERROR_BASE_M: f32 = 0.01;
const STEPS_PER_OCTAVE: usize = 11;

/// `2^(j / 11)` for `j` in `0..11`, as exact `f32` bit patterns (the `f64` power rounded to
/// `f32`). Constants rather than `exp2` calls, whose last bits vary with the platform's maths
/// library: both ends must agree on every code's value to the bit.
const OCTAVE_STEPS: [u32; 11] = [
    0x3f80_0000,
    0x3f88_5344,
    0x3f91_3127,
    0x3f9a_a2ad,
    0x3fa4_b16f,
    0x3faf_67a9,
    0x3fba_d03e,
    0x3fc6_f6c9,
    0x3fd3_e7a4,
    0x3fe1_aff7,
    0x3ff0_5dc7,
];

fn table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|k| {
            if k == 0 {
                0.0
            } else {
                // One rounded product, then an exact scaling by a power of two.
                let (octave, step) = ((k - 1) / STEPS_PER_OCTAVE, (k - 1) % STEPS_PER_OCTAVE);
                ERROR_BASE_M * f32::from_bits(OCTAVE_STEPS[step]) * (1u32 << octave) as f32
            }
        })
    })
}

/// The metres that error code `code` stands for.
pub fn error_value(code: u8) -> f32 {
    table()[code as usize]
}

/// The smallest code whose value is at least `metres` (rounding up keeps the bound
/// conservative); saturates at 255.
pub fn error_code(metres: f32) -> u8 {
    if metres.is_nan() || metres <= 0.0 {
        return 0;
    }
    // The search starts from the code of the smallest float with the same exponent and top
    // three mantissa bits: every code before it is below `metres` too, and such a bucket (an
    // eighth of an octave) holds at most two codes (an eleventh of an octave apart), so a few
    // steps end it. The same answer as a binary search over the table, faster.
    let t = table();
    let mut k = code_hints()[(metres.to_bits() >> 20) as usize] as usize;
    while k < 255 && t[k] < metres {
        k += 1;
    }
    k as u8
}

/// For each bucket of positive floats by their top 12 bits (exponent and three mantissa bits),
/// the first code whose value is not below the bucket's smallest float.
fn code_hints() -> &'static [u8; 2048] {
    static HINTS: std::sync::OnceLock<[u8; 2048]> = std::sync::OnceLock::new();
    HINTS.get_or_init(|| {
        let t = table();
        std::array::from_fn(|b| {
            let low = f32::from_bits((b as u32) << 20);
            t.partition_point(|&v| v < low).min(255) as u8
        })
    })
}

#[cfg(test)]
mod tests {

    #[test]
    fn error_codes_are_the_first_code_not_below() {
        let t = table();
        let slow = |m: f32| t.partition_point(|&v| v < m).min(255) as u8;
        // Every code's value, its neighbouring floats, and a sweep of the whole positive range.
        let mut probes: Vec<f32> = t
            .iter()
            .flat_map(|&v| {
                [
                    v,
                    f32::from_bits(v.to_bits() + 1),
                    f32::from_bits(v.to_bits().saturating_sub(1)),
                ]
            })
            .collect();
        probes.extend((0..1u32 << 16).map(|i| f32::from_bits(i << 15)));
        probes.extend([f32::MIN_POSITIVE, 1e-30, 1e30, f32::MAX, f32::INFINITY]);
        for m in probes.into_iter().filter(|m| *m > 0.0) {
            assert_eq!(error_code(m), slow(m), "{m:e}");
        }
    }

    #[test]
    fn error_table_is_exact_octaves_of_its_formula() {
        for k in 1..=255usize {
            let want = 0.01f64 * 2f64.powf((k - 1) as f64 / 11.0);
            let got = error_value(k as u8) as f64;
            assert!((got / want - 1.0).abs() < 1e-6, "code {k}: {got} vs {want}");
            if k + 11 <= 255 {
                assert_eq!(error_value((k + 11) as u8), 2.0 * error_value(k as u8));
            }
        }
        // Pinned bits (docs/protocol.md, appendix A): a platform's maths library must not matter.
        assert_eq!(error_value(5).to_bits(), 0x3c52_cea2);
        assert_eq!(error_value(255).to_bits(), 0x47ae_7f0f);
    }

    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn full_quad_round_trips(c in proptest::array::uniform4(-2_000_000i32..2_000_000)) {
            let (p, d) = forward(c, Presence::FULL);
            prop_assert_eq!(inverse(p, d), c);
            let mean = c.iter().map(|&v| v as i64).sum::<i64>() as f64 / 4.0;
            prop_assert!((p as f64 - mean).abs() <= 1.0);
        }

        #[test]
        fn partial_quads_round_trip(c in proptest::array::uniform4(-100_000i32..100_000),
                                    east in any::<bool>(), south in any::<bool>()) {
            let p = Presence { east, south };
            let (parent, d) = forward(c, p);
            let back = inverse(parent, d);
            prop_assert_eq!(back[0], c[0]);
            if east { prop_assert_eq!(back[1], c[1]); } else { prop_assert_eq!(d[1], 0); }
            if south { prop_assert_eq!(back[2], c[2]); } else { prop_assert_eq!(d[0], 0); }
            if east && south { prop_assert_eq!(back[3], c[3]); }
            if !east && !south { prop_assert_eq!(parent, c[0]); }
        }

        #[test]
        fn error_code_is_tight_and_conservative(m in 0.0f32..15_000.0) {
            let k = error_code(m);
            prop_assert!(error_value(k) >= m);
            if k > 1 { prop_assert!(error_value(k - 1) < m); }
        }
    }

    #[test]
    fn error_code_edges() {
        assert_eq!(error_code(0.0), 0);
        assert_eq!(error_code(f32::NAN), 0);
        assert_eq!(error_code(1e9), 255);
        assert_eq!(error_value(error_code(ERROR_BASE_M)), ERROR_BASE_M);
    }
}
