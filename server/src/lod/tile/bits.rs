//! A set of tiles as one bit per tile of the pyramid: membership in one load, iteration in
//! ascending dense index, differences by whole words. A 4097 x 4097 DEM's pyramid of 64-cell
//! tiles has 5,461 tiles: 688 bytes a set.

/// A set of dense tile indices below a fixed count.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TileBits {
    /// Bit `i % 64` of word `i / 64` is set when tile `i` is in the set.
    words: Vec<u64>,
}

impl TileBits {
    /// An empty set for tiles `0..n`.
    pub fn new(n: u32) -> TileBits {
        TileBits {
            words: vec![0; (n as usize).div_ceil(64)],
        }
    }

    /// Whether `i` is in the set.
    pub fn contains(&self, i: u32) -> bool {
        self.words
            .get(i as usize / 64)
            .is_some_and(|w| w >> (i % 64) & 1 == 1)
    }

    /// Adds `i`; true when it was not there.
    pub fn insert(&mut self, i: u32) -> bool {
        let w = &mut self.words[i as usize / 64];
        let bit = 1u64 << (i % 64);
        let new = *w & bit == 0;
        *w |= bit;
        new
    }

    /// Removes `i`.
    pub fn remove(&mut self, i: u32) {
        self.words[i as usize / 64] &= !(1u64 << (i % 64));
    }

    /// Number of tiles in the set.
    pub fn len(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.words.iter().all(|&w| w == 0)
    }

    /// The tiles, ascending.
    pub fn iter(&self) -> impl Iterator<Item = u32> + '_ {
        ones(self.words.iter().copied())
    }

    /// Tiles in `self` but not in `other`, ascending.
    pub fn minus<'a>(&'a self, other: &'a TileBits) -> impl Iterator<Item = u32> + 'a {
        ones(
            self.words
                .iter()
                .zip(other.words.iter().chain(std::iter::repeat(&0)))
                .map(|(a, b)| a & !b),
        )
    }

    /// Tiles in both.
    pub fn and(&self, other: &TileBits) -> TileBits {
        TileBits {
            words: self
                .words
                .iter()
                .zip(other.words.iter().chain(std::iter::repeat(&0)))
                .map(|(a, b)| a & b)
                .collect(),
        }
    }

    /// Bytes of memory the set holds.
    pub fn memory_bytes(&self) -> usize {
        self.words.capacity() * 8
    }
}

/// The indices of the set bits of consecutive words.
fn ones(words: impl Iterator<Item = u64>) -> impl Iterator<Item = u32> {
    words.enumerate().flat_map(|(k, mut w)| {
        std::iter::from_fn(move || {
            if w == 0 {
                return None;
            }
            let b = w.trailing_zeros();
            w &= w - 1;
            Some(k as u32 * 64 + b)
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_iterate_ascending_and_subtract() {
        let mut a = TileBits::new(200);
        let mut b = TileBits::new(200);
        for i in [3, 64, 65, 199] {
            assert!(a.insert(i));
        }
        assert!(!a.insert(3));
        b.insert(64);
        b.insert(7);
        assert_eq!(a.iter().collect::<Vec<_>>(), vec![3, 64, 65, 199]);
        assert_eq!(a.minus(&b).collect::<Vec<_>>(), vec![3, 65, 199]);
        assert_eq!(a.and(&b).iter().collect::<Vec<_>>(), vec![64]);
        assert_eq!(
            (a.len(), a.contains(199), a.contains(198)),
            (4, true, false)
        );
        a.remove(199);
        assert!(!a.contains(199) && !a.is_empty());
    }
}
