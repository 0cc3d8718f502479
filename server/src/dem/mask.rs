//! [`VoidMask`]: which samples of a grid had no data in the source (DESIGN.md section 2: keep the
//! mask, so that stores and queries can tell measured ground from filled ground).

/// One bit per sample, row-major, 64 samples a word: set where the source had no data.
///
/// A bitmask rather than `Vec<bool>`: a 16385 x 16385 grid needs 32 MiB instead of 256 MiB.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VoidMask {
    /// The bits; bit `i % 64` of word `i / 64` is sample `i`.
    bits: Vec<u64>,
    /// Samples the mask covers, so that out-of-range indices are caught.
    len: usize,
    /// Set bits, kept so that reports and the fill's early exit cost nothing.
    count: u64,
}

impl VoidMask {
    /// A mask of `n` samples, none void.
    pub fn new(n: usize) -> VoidMask {
        VoidMask {
            bits: vec![0; n.div_ceil(64)],
            len: n,
            count: 0,
        }
    }

    /// Marks sample `i` void.
    ///
    /// # Panics
    /// If `i` is not below the length given to [`VoidMask::new`] (a caller bug, not bad input).
    pub fn set(&mut self, i: usize) {
        assert!(i < self.len, "void index {i} out of {}", self.len);
        let (w, b) = (i / 64, 1u64 << (i % 64));
        if self.bits[w] & b == 0 {
            self.bits[w] |= b;
            self.count += 1;
        }
    }

    /// Whether sample `i` is void (false past the end).
    pub fn get(&self, i: usize) -> bool {
        i < self.len && self.bits[i / 64] & (1 << (i % 64)) != 0
    }

    /// Number of void samples.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Number of samples the mask covers.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the mask covers no samples.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The mask as bytes, bit `i % 8` of byte `i / 8` for sample `i` (the store's `voids`
    /// section): the words themselves on a little-endian machine.
    pub fn to_le_bytes(&self) -> std::borrow::Cow<'_, [u8]> {
        let n = self.len.div_ceil(8);
        if cfg!(target_endian = "little") {
            std::borrow::Cow::Borrowed(&bytemuck::cast_slice(&self.bits)[..n])
        } else {
            let all: Vec<u8> = self.bits.iter().flat_map(|w| w.to_le_bytes()).collect();
            std::borrow::Cow::Owned(all[..n].to_vec())
        }
    }

    /// The void samples' indices, ascending; cheap on sparse masks (whole empty words are skipped).
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.bits.iter().enumerate().flat_map(|(w, &word)| {
            let mut rest = word;
            std::iter::from_fn(move || {
                (rest != 0).then(|| {
                    let b = rest.trailing_zeros() as usize;
                    rest &= rest - 1;
                    w * 64 + b
                })
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mask_counts_and_iterates() {
        let mut m = VoidMask::new(200);
        for i in [0, 63, 64, 130, 199, 64] {
            m.set(i);
        }
        assert_eq!(m.count(), 5);
        assert_eq!(m.iter().collect::<Vec<_>>(), vec![0, 63, 64, 130, 199]);
        assert!(m.get(130) && !m.get(131) && !m.get(10_000));
        assert_eq!(m.len(), 200);
    }
}
