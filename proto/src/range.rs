//! Adaptive binary range coding, for the vertex delta body (docs/protocol.md section 5).
//!
//! The coder is LZMA's (Igor Pavlov's range coder, as in the LZMA SDK and xz): a 32-bit range,
//! carries resolved through a cached byte, 12-bit probabilities here, with one difference stated
//! in the protocol: the encoder's first output byte, which is always 0, is not sent.
//! - **Adaptive bits** ([`Bit`]): the probability that the bit is 0, in 1/4096, the mean of two
//!   estimates that start at 1/2 and move towards each bit coded, one fast (1/8 of the way) and
//!   one slow (1/64): the fast one follows a session's changing statistics, the slow one keeps
//!   precision where they hold still (the mean stays within 35..=4061 by itself). On recorded
//!   streams this beat a single rate of 1/16 by 0.02 bytes a split (`docs/vertex-stream.md`,
//!   "Bytes per split").
//! - **Direct bits**: the range halves per bit, up to 16 bits in one step.
//! - **Values** ([`Value`]): an unsigned integer as its bucket `b` (the bit length of `v + 1`,
//!   minus one) in unary, one adaptive bit per unary position, then the `b` bits of `v + 1`
//!   below its leading one: the first two adaptive (per bucket, the second also per the first),
//!   the rest direct. This is an adaptive Exp-Golomb code: the model learns each bucket's
//!   frequency instead of a fixed order.
//!
//! A hand-written coder rather than a crate: the protocol must define the bit stream exactly for
//! clients written from its text alone, LZMA's coder is the well-known one to define it by, and
//! it is a few dozen lines. The crates that carry it keep it private (`lzma-rs`) or wrap it in a
//! general modelling framework whose stream is not a documented standard (`constriction`).
//!
//! Decoding never panics and never reads past the input: a missing byte reads as 0 and marks the
//! stream as overrun, which [`Decoder::finished`] and [`Decoder::overrun`] report.

/// Bits of probability precision.
const PROB_BITS: u32 = 12;
/// Probability 1, in units of `2^-PROB_BITS`.
const PROB_ONE: u16 = 1 << PROB_BITS;
/// How fast the fast estimate adapts: by `1/2^FAST_SHIFT` of the way per bit.
const FAST_SHIFT: u32 = 3;
/// How fast the slow estimate adapts.
const SLOW_SHIFT: u32 = 6;
/// The range is renormalised (shifted by a byte) whenever it falls below this.
const TOP: u32 = 1 << 24;
/// The largest bucket a [`Value`] codes: values are below `2^MAX_BUCKET - 1`. The delta body's
/// largest values are zigzag-mapped `i32` details (below `2^32`, bucket 32 at most), so 33
/// buckets are room enough, and a model is small enough (528 bytes) for a session to keep its
/// models.
pub const MAX_BUCKET: u32 = 33;
/// The largest value a [`Value`] codes.
pub const MAX_VALUE: u64 = (1 << MAX_BUCKET) - 2;

/// An adaptive bit: two estimates, in 1/4096, of the probability that the next bit is 0, a fast
/// one and a slow one; the bit is coded with their mean.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bit {
    fast: u16,
    slow: u16,
}

impl Default for Bit {
    fn default() -> Bit {
        Bit {
            fast: PROB_ONE / 2,
            slow: PROB_ONE / 2,
        }
    }
}

/// `p` moved `1/2^shift` of the way towards the bit (towards 0 for a 1, 4096 for a 0).
#[inline(always)]
fn adapt(p: u16, bit: bool, shift: u32) -> u16 {
    // `p + (t - p) >> shift` with an arithmetic shift (rounding towards minus infinity): for a
    // 0, `t = 4096` gives `p + (4096 - p) >> shift`; for a 1, `t = 2^shift - 1` gives exactly
    // `p - p >> shift` (with `p = q 2^shift + r`, `2^shift - 1 - p` floors to `-q`). One step
    // for both bits, and the target a select, not a branch: `if bit` was one, mispredicted
    // about one bit in three on the server.
    let mask = 0i32.wrapping_sub(bit as i32);
    let target = PROB_ONE as i32 ^ ((PROB_ONE as i32 ^ ((1 << shift) - 1)) & mask);
    (p as i32 + ((target - p as i32) >> shift)) as u16
}

impl Bit {
    /// Where the range splits for this bit.
    #[inline(always)]
    fn bound(self, range: u32) -> u32 {
        (range >> PROB_BITS) * ((self.fast as u32 + self.slow as u32) >> 1)
    }

    /// Both estimates after coding `bit` (branch-free: the bit is as good as random to a
    /// branch predictor).
    #[inline(always)]
    fn update(&mut self, bit: bool) {
        self.fast = adapt(self.fast, bit, FAST_SHIFT);
        self.slow = adapt(self.slow, bit, SLOW_SHIFT);
    }
}

/// The adaptive model of one context's values (see the module documentation).
#[derive(Clone, Debug)]
pub struct Value {
    /// The unary bucket code: position `i` says whether the bucket exceeds `i`.
    unary: [Bit; MAX_BUCKET as usize],
    /// Per bucket, the first bit below the leading one, then the second given the first.
    top: [[Bit; 3]; MAX_BUCKET as usize],
}

impl Default for Value {
    fn default() -> Value {
        Value {
            unary: [Bit::default(); MAX_BUCKET as usize],
            top: [[Bit::default(); 3]; MAX_BUCKET as usize],
        }
    }
}

/// Writes a range-coded stream.
#[derive(Debug)]
pub struct Encoder {
    /// The low end of the interval, with a carry in bit 32.
    low: u64,
    range: u32,
    /// The last byte not yet written (a carry may still add to it) and how many 0xFF bytes
    /// follow it, plus one.
    cache: u8,
    cache_size: u64,
    out: Vec<u8>,
}

impl Default for Encoder {
    fn default() -> Encoder {
        Encoder {
            low: 0,
            range: u32::MAX,
            cache: 0,
            cache_size: 1,
            out: Vec::new(),
        }
    }
}

impl Encoder {
    /// An empty stream.
    pub fn new() -> Encoder {
        Encoder::default()
    }

    #[inline(always)]
    fn normalize(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    fn shift_low(&mut self) {
        if (self.low as u32) < 0xFF00_0000 || (self.low >> 32) != 0 {
            let carry = (self.low >> 32) as u8;
            let mut byte = self.cache;
            loop {
                self.out.push(byte.wrapping_add(carry));
                byte = 0xFF;
                self.cache_size -= 1;
                if self.cache_size == 0 {
                    break;
                }
            }
            self.cache = (self.low >> 24) as u8;
        }
        self.cache_size += 1;
        self.low = (self.low & 0x00FF_FFFF) << 8;
    }

    /// Codes `bit` with the adaptive probability `model`, and adapts it.
    #[inline]
    pub fn bit(&mut self, model: &mut Bit, bit: bool) {
        // Without branches on the bit, as in the decoder.
        let bound = model.bound(self.range);
        let mask = 0u32.wrapping_sub(bit as u32);
        self.low += (bound & mask) as u64;
        self.range = bound ^ ((bound ^ self.range.wrapping_sub(bound)) & mask);
        model.update(bit);
        self.normalize();
    }

    /// Codes the low `n` bits of `value` (n <= 16) at probability 1/2 each, as one step.
    #[inline]
    pub fn direct(&mut self, value: u32, n: u32) {
        debug_assert!(n <= 16 && (n == 16 || value >> n == 0));
        self.range >>= n;
        self.low += value as u64 * self.range as u64;
        self.normalize();
    }

    /// Codes `v` (at most [`MAX_VALUE`]) with the adaptive model `model`.
    #[inline]
    pub fn value(&mut self, model: &mut Value, v: u64) {
        debug_assert!(v <= MAX_VALUE);
        let b = 63 - (v + 1).leading_zeros();
        for m in &mut model.unary[..b as usize] {
            self.bit(m, true);
        }
        self.bit(&mut model.unary[b as usize], false);
        let rest = v + 1 - (1 << b);
        let top = &mut model.top[b as usize];
        if b >= 1 {
            let first = (rest >> (b - 1)) & 1 == 1;
            self.bit(&mut top[0], first);
            if b >= 2 {
                self.bit(&mut top[1 + first as usize], (rest >> (b - 2)) & 1 == 1);
                let mut n = b - 2;
                while n > 0 {
                    let k = n.min(16);
                    n -= k;
                    self.direct(((rest >> n) & ((1 << k) - 1)) as u32, k);
                }
            }
        }
    }

    /// Flushes the interval and returns the stream (without the always-zero first byte).
    pub fn finish(mut self) -> Vec<u8> {
        for _ in 0..5 {
            self.shift_low();
        }
        debug_assert_eq!(self.out.first(), Some(&0));
        self.out.remove(0);
        self.out
    }
}

/// Reads a stream written by [`Encoder`].
#[derive(Debug)]
pub struct Decoder<'a> {
    bytes: &'a [u8],
    /// The next byte to read; past the end once the input ran out.
    pos: usize,
    range: u32,
    /// The coded value's offset from the interval's low end.
    code: u32,
}

impl<'a> Decoder<'a> {
    /// A decoder over `bytes`.
    pub fn new(bytes: &'a [u8]) -> Decoder<'a> {
        let mut d = Decoder {
            bytes,
            pos: 0,
            range: u32::MAX,
            code: 0,
        };
        for _ in 0..4 {
            d.code = (d.code << 8) | d.next_byte() as u32;
        }
        d
    }

    #[inline(always)]
    fn next_byte(&mut self) -> u8 {
        let b = self.bytes.get(self.pos).copied().unwrap_or(0);
        self.pos += 1;
        b
    }

    #[inline(always)]
    fn normalize(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.code = (self.code << 8) | self.next_byte() as u32;
        }
    }

    /// Whether the decoder needed bytes beyond the input: the stream is truncated or garbage.
    pub fn overrun(&self) -> bool {
        self.pos > self.bytes.len()
    }

    /// Whether the stream ended exactly where the encoder's did: every byte read, none missing,
    /// and the coded value at the interval's low end, where the encoder's flush leaves it.
    pub fn finished(&self) -> bool {
        self.pos == self.bytes.len() && self.code == 0
    }

    /// Decodes a bit with the adaptive probability `model`, and adapts it.
    #[inline]
    pub fn bit(&mut self, model: &mut Bit) -> bool {
        // Without branches on the bit: it is as good as random to a branch predictor.
        let bound = model.bound(self.range);
        let bit = self.code >= bound;
        let mask = 0u32.wrapping_sub(bit as u32);
        self.code -= bound & mask;
        self.range = bound ^ ((bound ^ self.range.wrapping_sub(bound)) & mask);
        model.update(bit);
        self.normalize();
        bit
    }

    /// Decodes `n` direct bits (n <= 16); `None` if the stream holds a value no encoder writes.
    #[inline]
    pub fn direct(&mut self, n: u32) -> Option<u32> {
        self.range >>= n;
        let v = self.code / self.range;
        if v >> n != 0 {
            return None;
        }
        self.code -= v * self.range;
        self.normalize();
        Some(v)
    }

    /// Decodes a value coded with the adaptive model `model`; `None` if its bucket is beyond
    /// [`MAX_BUCKET`] or its direct bits are impossible.
    #[inline]
    pub fn value(&mut self, model: &mut Value) -> Option<u64> {
        let mut b = 0;
        loop {
            if b == MAX_BUCKET {
                return None;
            }
            if !self.bit(&mut model.unary[b as usize]) {
                break;
            }
            b += 1;
        }
        let top = &mut model.top[b as usize];
        let mut rest = 0u64;
        if b >= 1 {
            let first = self.bit(&mut top[0]);
            rest = first as u64;
            if b >= 2 {
                rest = rest << 1 | self.bit(&mut top[1 + first as usize]) as u64;
                let mut n = b - 2;
                while n > 0 {
                    let k = n.min(16);
                    n -= k;
                    rest = rest << k | self.direct(k)? as u64;
                }
            }
        }
        Some((1 << b) + rest - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// What one test stream holds: adaptive bits in a few models, direct bits, values.
    #[derive(Clone, Debug)]
    enum Sym {
        Bit(usize, bool),
        Direct(u32, u32),
        Value(usize, u64),
    }

    fn arb_sym() -> impl Strategy<Value = Sym> {
        prop_oneof![
            (0usize..3, any::<bool>()).prop_map(|(m, b)| Sym::Bit(m, b)),
            (1u32..=16, any::<u32>()).prop_map(|(n, v)| Sym::Direct(v & ((1 << n) - 1), n)),
            (0usize..3, prop_oneof![0u64..20, 0u64..5000, 0..=MAX_VALUE])
                .prop_map(|(m, v)| Sym::Value(m, v)),
            // Long runs of one bit push a model to its limits.
            Just(Sym::Bit(0, true)),
        ]
    }

    fn encode(syms: &[Sym]) -> Vec<u8> {
        let (mut bits, mut values) = ([Bit::default(); 3], vec![Value::default(); 3]);
        let mut e = Encoder::new();
        for s in syms {
            match *s {
                Sym::Bit(m, b) => e.bit(&mut bits[m], b),
                Sym::Direct(v, n) => e.direct(v, n),
                Sym::Value(m, v) => e.value(&mut values[m], v),
            }
        }
        e.finish()
    }

    /// Decodes `syms` from `bytes`: the first one that differs, or a stream that does not end
    /// exactly after them, is an error.
    fn decode(bytes: &[u8], syms: &[Sym]) -> Result<(), String> {
        let (mut bits, mut values) = ([Bit::default(); 3], vec![Value::default(); 3]);
        let mut d = Decoder::new(bytes);
        for (i, s) in syms.iter().enumerate() {
            let ok = match *s {
                Sym::Bit(m, b) => d.bit(&mut bits[m]) == b,
                Sym::Direct(v, n) => d.direct(n) == Some(v),
                Sym::Value(m, v) => d.value(&mut values[m]) == Some(v),
            };
            if !ok {
                return Err(format!("symbol {i} ({s:?}) differs"));
            }
        }
        if d.overrun() || !d.finished() {
            return Err(format!(
                "{} of {} bytes, code {}",
                d.pos,
                bytes.len(),
                d.code
            ));
        }
        Ok(())
    }

    proptest! {
        #[test]
        fn streams_round_trip_and_end_exactly(syms in proptest::collection::vec(arb_sym(), 0..400)) {
            let bytes = encode(&syms);
            prop_assert_eq!(decode(&bytes, &syms), Ok(()));
        }

        #[test]
        fn garbage_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let mut d = Decoder::new(&bytes);
            let (mut bit, mut value) = (Bit::default(), Value::default());
            for i in 0..200 {
                match i % 3 {
                    0 => { d.bit(&mut bit); }
                    1 => { let _ = d.direct(1 + i % 16); }
                    _ => { let _ = d.value(&mut value); }
                }
            }
        }
    }

    /// The stream stays the one clients decode: a change for speed must not change a byte of
    /// it (these figures come from the coder before c384569 made its bits branch-free). 200,000
    /// symbols of every kind, with skewed bits; the stream decodes, and has 0xFF bytes for
    /// carries to ripple through.
    #[test]
    fn the_stream_is_the_one_pinned() {
        let mut rng = crate::rng::Rng::new(11);
        let mut syms = Vec::new();
        for _ in 0..200_000 {
            syms.push(match rng.below(8) {
                0 => Sym::Direct(rng.below(1 << 16) as u32, 16),
                1 => Sym::Direct(rng.below(8) as u32, 3),
                2 | 3 => Sym::Value(rng.below(3), rng.below(40) as u64),
                4 => Sym::Value(2, rng.next_u64() % (MAX_VALUE + 1)),
                _ => Sym::Bit(rng.below(3), rng.below(16) == 0),
            });
        }
        let bytes = encode(&syms);
        assert_eq!(decode(&bytes, &syms), Ok(()));
        // Bytes a carry may ripple through.
        let ff = bytes.iter().filter(|&&b| b == 0xFF).count();
        assert!(ff > 500, "{ff} bytes 0xFF");
        let fnv = bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
            (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
        });
        assert_eq!((bytes.len(), fnv), (206_666, 0x8098_5671_1772_41a8));
    }

    #[test]
    fn the_one_step_adaptation_is_the_two_sided_one() {
        // Every probability an estimate can hold, both bits, both rates: the protocol's
        // `p - p >> s` and `p + (4096 - p) >> s`.
        for shift in [FAST_SHIFT, SLOW_SHIFT] {
            for p in 0..=PROB_ONE {
                assert_eq!(adapt(p, true, shift), p - (p >> shift), "{p} {shift}");
                assert_eq!(
                    adapt(p, false, shift),
                    p + ((PROB_ONE - p) >> shift),
                    "{p} {shift}"
                );
            }
        }
    }

    #[test]
    fn a_model_adapts_and_stays_within_its_limits() {
        let mut m = Bit::default();
        for _ in 0..1000 {
            m.update(true);
        }
        assert_eq!((m.fast, m.slow), (7, 63));
        assert_eq!(m.bound(1 << 12), 35);
        for _ in 0..1000 {
            m.update(false);
        }
        assert_eq!((m.fast, m.slow), (4089, 4033));
        assert_eq!(m.bound(1 << 12), 4061);
        // A long run of a well-predicted bit costs little: 10,000 zeros in a few bytes.
        let mut e = Encoder::new();
        let mut m = Bit::default();
        for _ in 0..10_000 {
            e.bit(&mut m, false);
        }
        assert!(e.finish().len() < 30);
    }

    #[test]
    fn truncated_streams_overrun_and_extra_bytes_are_not_finished() {
        let syms: Vec<Sym> = (0..50u64).map(|v| Sym::Value(0, v * 977)).collect();
        let bytes = encode(&syms);
        let decode_all = |b: &[u8]| {
            let mut d = Decoder::new(b);
            let mut m = Value::default();
            for _ in 0..50 {
                d.value(&mut m);
            }
            (d.overrun(), d.finished())
        };
        assert_eq!(decode_all(&bytes), (false, true));
        assert!(decode_all(&bytes[..bytes.len() - 1]).0);
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(decode_all(&longer), (false, false));
    }
}
