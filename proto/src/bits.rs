//! Bit-level writer and reader with Exp-Golomb codes, for the compact delta body.
//!
//! Reading never panics and never reads past the end: every read returns `Option`, `None` when
//! the input is exhausted or a code is longer than any value the format allows.

/// Appends bits, most significant first, to a byte vector.
#[derive(Default, Debug)]
pub struct BitWriter {
    /// Finished bytes.
    bytes: Vec<u8>,
    /// Bits waiting to fill the next byte, in the low `pending_len` bits.
    pending: u64,
    /// How many bits of `pending` are in use (always < 8 between calls).
    pending_len: u32,
}

impl BitWriter {
    /// An empty writer.
    pub fn new() -> BitWriter {
        BitWriter::default()
    }

    /// Writes the low `n` bits of `value` (n <= 32).
    pub fn put(&mut self, value: u32, n: u32) {
        debug_assert!(n <= 32);
        if n == 0 {
            return;
        }
        self.push_bits(value as u64 & ((1u64 << n) - 1), n);
    }

    /// Appends the `n` bits of `bits` (n <= 56: `pending` holds under 8 between calls) and
    /// moves every whole byte out.
    fn push_bits(&mut self, bits: u64, n: u32) {
        self.pending = (self.pending << n) | bits;
        self.pending_len += n;
        while self.pending_len >= 8 {
            self.pending_len -= 8;
            self.bytes.push((self.pending >> self.pending_len) as u8);
        }
        self.pending &= (1u64 << self.pending_len) - 1;
    }

    /// Writes `value` with an order-`k` Exp-Golomb code.
    pub fn put_eg(&mut self, value: u64, k: u32) {
        let v = value + (1u64 << k);
        let bits = 64 - v.leading_zeros();
        let prefix = bits - 1 - k;
        let len = prefix + bits;
        if len <= 56 {
            // Prefix and value in one go: the prefix is `v`'s leading zeros.
            self.push_bits(v, len);
            return;
        }
        for _ in 0..prefix {
            self.put(0, 1);
        }
        // `bits` may exceed 32: write in two parts.
        if bits > 32 {
            self.put((v >> 32) as u32, bits - 32);
            self.put(v as u32, 32);
        } else {
            self.put(v as u32, bits);
        }
    }

    /// Writes a signed value, zigzag-mapped, with an order-`k` Exp-Golomb code.
    pub fn put_eg_signed(&mut self, value: i64, k: u32) {
        self.put_eg(zigzag(value), k);
    }

    /// Pads the last byte with zeros and returns the bytes.
    pub fn finish(mut self) -> Vec<u8> {
        if self.pending_len > 0 {
            self.bytes
                .push((self.pending << (8 - self.pending_len)) as u8);
        }
        self.bytes
    }
}

/// Reads bits written by [`BitWriter`].
#[derive(Debug)]
pub struct BitReader<'a> {
    /// The input.
    bytes: &'a [u8],
    /// Position of the next bit, counted from the start.
    pos: u64,
}

impl<'a> BitReader<'a> {
    /// A reader over `bytes`.
    pub fn new(bytes: &'a [u8]) -> BitReader<'a> {
        BitReader { bytes, pos: 0 }
    }

    /// Bits not yet read.
    pub fn remaining(&self) -> u64 {
        self.bytes.len() as u64 * 8 - self.pos
    }

    /// The next 64 bits, most significant first, zeros past the end: at least 57 of them are
    /// the input's wherever the input has them.
    #[inline]
    fn peek64(&self) -> u64 {
        let at = (self.pos >> 3) as usize;
        let word = match self.bytes.get(at..at + 8) {
            Some(w) => <[u8; 8]>::try_from(w).unwrap_or_default(),
            None => {
                // The last few bytes.
                let mut word = [0u8; 8];
                let tail = self.bytes.get(at..).unwrap_or(&[]);
                let n = tail.len().min(8);
                word[..n].copy_from_slice(&tail[..n]);
                word
            }
        };
        u64::from_be_bytes(word) << (self.pos & 7)
    }

    /// Reads `n` bits (n <= 32).
    pub fn get(&mut self, n: u32) -> Option<u32> {
        if n as u64 > self.remaining() {
            return None;
        }
        if n == 0 {
            return Some(0);
        }
        let v = (self.peek64() >> (64 - n)) as u32;
        self.pos += n as u64;
        Some(v)
    }

    /// Reads an order-`k` Exp-Golomb code; `None` past the end or beyond 62 bits.
    pub fn get_eg(&mut self, k: u32) -> Option<u64> {
        // A code that lies whole in the next 57 bits is read from one word: its zeros are the
        // word's leading zeros, and the code is its top `2 prefix + k + 1` bits.
        let word = self.peek64();
        let prefix = word.leading_zeros();
        let len = 2 * prefix + k + 1;
        if len <= 57 && len as u64 <= self.remaining() {
            self.pos += len as u64;
            return Some((word >> (64 - len)) - (1u64 << k));
        }
        // Long codes, and codes that would run past the end: bit by bit.
        let mut prefix = 0;
        while self.get(1)? == 0 {
            prefix += 1;
            if prefix + k > 62 {
                return None;
            }
        }
        let rest = prefix + k;
        let mut v = 1u64;
        let mut left = rest;
        while left > 0 {
            let n = left.min(32);
            v = (v << n) | self.get(n)? as u64;
            left -= n;
        }
        Some(v - (1u64 << k))
    }

    /// Reads a zigzag-mapped signed Exp-Golomb code.
    pub fn get_eg_signed(&mut self, k: u32) -> Option<i64> {
        self.get_eg(k).map(unzigzag)
    }
}

/// Maps signed to unsigned so that small magnitudes get small codes: 0, -1, 1, -2, ...
pub fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

/// Inverse of [`zigzag`].
pub fn unzigzag(u: u64) -> i64 {
    ((u >> 1) as i64) ^ -((u & 1) as i64)
}

/// Length in bits of `value`'s order-`k` Exp-Golomb code.
pub fn eg_len(value: u64, k: u32) -> u64 {
    let v = value + (1u64 << k);
    let bits = 64 - v.leading_zeros() as u64;
    2 * bits - 1 - k as u64
}

/// The order `k` in `0..=max_k` that codes all of `values` in the fewest bits (the lowest such
/// `k` on a tie).
///
/// One pass over the values, not one per order. Order `k` codes `v` in `2 * L - 1 - k` bits,
/// where `L` is the bit length of `v + 2^k`. With `b` the bit length of `v` and `z` that of its
/// highest zero bit below `b` (0 when `v` is all ones), `L` is `k + 1` when `b <= k`, and
/// otherwise `b`, plus 1 when adding `2^k` carries out of the top, which is when bits `k..b` of
/// `v` are all ones: `z <= k`. So the cost of every order follows from a count of the values by
/// `b`, and a count of them by `b` and `z`, where `b` and `z` above `max_k` act alike.
pub fn best_order(values: impl Iterator<Item = u64>, max_k: u32) -> u32 {
    let top = max_k.min(63) as usize + 1;
    let mut by_len = [0u64; 65];
    // `by_len_zero[b * (top + 1) + z]`, `b` and `z` clamped to `top`.
    let mut by_len_zero = vec![0u64; (top + 1) * (top + 1)];
    for v in values {
        let b = (64 - v.leading_zeros()) as usize;
        let below = if b == 64 { !v } else { !v & ((1u64 << b) - 1) };
        let z = (64 - below.leading_zeros()) as usize;
        by_len[b] += 1;
        by_len_zero[b.min(top) * (top + 1) + z.min(top)] += 1;
    }
    let mut best = (u64::MAX, 0);
    for k in 0..top {
        let mut bits = 0u64;
        for (b, &n) in by_len.iter().enumerate() {
            bits += n * (2 * b.max(k + 1) as u64 - 1 - k as u64);
        }
        // The carries: b > k and z <= k.
        for b in k + 1..=top {
            for z in 0..=k {
                bits += 2 * by_len_zero[b * (top + 1) + z];
            }
        }
        if bits < best.0 {
            best = (bits, k as u32);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The reader as it was, one bit at a time: the reference for the word reads.
    struct SlowReader<'a> {
        bytes: &'a [u8],
        pos: u64,
    }

    impl SlowReader<'_> {
        fn get(&mut self, n: u32) -> Option<u32> {
            if n as u64 > self.bytes.len() as u64 * 8 - self.pos {
                return None;
            }
            let mut v = 0u32;
            for _ in 0..n {
                let byte = self.bytes[(self.pos >> 3) as usize];
                v = (v << 1) | ((byte >> (7 - (self.pos & 7))) & 1) as u32;
                self.pos += 1;
            }
            Some(v)
        }

        fn get_eg(&mut self, k: u32) -> Option<u64> {
            let mut prefix = 0;
            while self.get(1)? == 0 {
                prefix += 1;
                if prefix + k > 62 {
                    return None;
                }
            }
            let mut v = 1u64;
            let mut left = prefix + k;
            while left > 0 {
                let n = left.min(32);
                v = (v << n) | self.get(n)? as u64;
                left -= n;
            }
            Some(v - (1u64 << k))
        }
    }

    proptest! {
        #[test]
        fn codes_round_trip(vals in proptest::collection::vec((any::<i32>(), 0u32..12), 0..50)) {
            let mut w = BitWriter::new();
            for &(v, k) in &vals { w.put_eg_signed(v as i64, k); }
            let bytes = w.finish();
            let mut r = BitReader::new(&bytes);
            for &(v, k) in &vals { prop_assert_eq!(r.get_eg_signed(k), Some(v as i64)); }
            prop_assert!(r.remaining() < 8);
        }

        #[test]
        fn best_order_is_the_cheapest_order(
            vals in proptest::collection::vec(
                prop_oneof![0u64..64, 0u64..100_000, any::<u32>().prop_map(u64::from)],
                0..200,
            ),
            max_k in 0u32..20,
        ) {
            let slow = (0..=max_k)
                .min_by_key(|&k| vals.iter().map(|&v| eg_len(v, k)).sum::<u64>())
                .unwrap_or(0);
            prop_assert_eq!(best_order(vals.iter().copied(), max_k), slow);
        }

        #[test]
        fn eg_len_matches_writer(v in 0u64..(1 << 40), k in 0u32..16) {
            let mut w = BitWriter::new();
            w.put_eg(v, k);
            let n = w.finish().len() as u64;
            prop_assert_eq!(n, eg_len(v, k).div_ceil(8));
        }

        #[test]
        fn word_reads_match_bit_by_bit_reads(
            bytes in proptest::collection::vec(any::<u8>(), 0..40),
            ks in proptest::collection::vec(0u32..24, 1..40),
            skew in 0u32..8,
        ) {
            // Mostly zero bytes make long prefixes, so codes straddle the 57-bit window and
            // the input's end; `skew` starts the reads at every offset within a byte.
            let bytes: Vec<u8> = bytes.iter().map(|&b| if b < 160 { 0 } else { b }).collect();
            let mut fast = BitReader::new(&bytes);
            let mut slow = SlowReader { bytes: &bytes, pos: 0 };
            prop_assert_eq!(fast.get(skew), slow.get(skew));
            for &k in ks.iter().cycle().take(200) {
                let (a, b) = (fast.get_eg(k), slow.get_eg(k));
                prop_assert_eq!(a, b);
                if a.is_none() {
                    break;
                }
                prop_assert_eq!(fast.pos, slow.pos);
                prop_assert_eq!(fast.get(k % 33), slow.get(k % 33));
            }
        }

        #[test]
        fn long_codes_round_trip(v in any::<u64>(), k in 0u32..8, lead in 0u32..8) {
            // Values of up to 62 bits: codes longer than one word.
            let v = v >> (2 + k);
            let mut w = BitWriter::new();
            w.put(0, lead);
            w.put_eg(v, k);
            w.put_eg(v >> 20, k);
            let bytes = w.finish();
            let mut r = BitReader::new(&bytes);
            prop_assert_eq!(r.get(lead), Some(0));
            prop_assert_eq!(r.get_eg(k), Some(v));
            prop_assert_eq!(r.get_eg(k), Some(v >> 20));
        }

        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..64), k in 0u32..20) {
            let mut r = BitReader::new(&bytes);
            while r.get_eg(k).is_some() {}
        }
    }
}
