//! A level's nodes in Morton order: how many of the set lie in a range of Morton codes, and
//! which is the `k`-th from a code on. The delta body codes each merge as its rank among the
//! client's interior nodes of its level (docs/protocol.md section 5.2).
//!
//! Morton codes are split as the set is paged: a superpage is 2^16 consecutive codes (bits 16
//! and up are the superpage's column and row interleaved), a page 2^8 within it, a page's word
//! 2^6. A walk visits the superpages of the level in Morton order, skips the absent ones, then
//! the pages of each, whose tables are row-major, and counts whole words with `count_ones`:
//! its cost is the pages it passes, not the nodes.

use super::{NodeSet, SUPER_SHIFT};
use crate::delta::compact;

/// Bits of Morton code per superpage.
const SUPER_BITS: u32 = 2 * SUPER_SHIFT;

impl NodeSet {
    /// Number of nodes of `level` in the set whose Morton code lies in `lo .. hi`.
    pub fn count_morton(&self, level: u8, lo: u64, hi: u64) -> u64 {
        let mut n = 0;
        self.walk(level, lo, hi, |base, word| {
            let word = if hi - base < 64 {
                word & ((1u64 << (hi - base)) - 1)
            } else {
                word
            };
            n += u64::from(word.count_ones());
            true
        });
        n
    }

    /// The Morton code of the node of `level` in the set that has exactly `k` of the set's
    /// nodes of that level between code `from` (inclusive) and itself; `None` when the level
    /// has at most `k` of them from `from` on.
    pub fn select_morton(&self, level: u8, from: u64, k: u64) -> Option<u64> {
        let mut left = k;
        let mut found = None;
        self.walk(level, from, u64::MAX, |base, word| {
            let c = u64::from(word.count_ones());
            if left >= c {
                left -= c;
                return true;
            }
            let mut w = word;
            for _ in 0..left {
                w &= w - 1;
            }
            found = Some(base + u64::from(w.trailing_zeros()));
            false
        });
        found
    }

    /// Calls `f(base, word)` for each non-zero word of `level`'s bits whose codes (`base ..
    /// base + 64`) reach `from .. until`, in Morton order, with the codes below `from` cleared;
    /// stops when `f` returns false. Codes at or past `until` may be in the last word.
    fn walk(&self, level: u8, from: u64, until: u64, mut f: impl FnMut(u64, u64) -> bool) {
        let Some(lv) = self.levels.get(usize::from(level)) else {
            return;
        };
        if lv.dir.is_empty() || from >= until {
            return;
        }
        let (cols, rows) = (lv.cols, lv.dir.len() as u32 / lv.cols);
        let side = u64::from(cols.max(rows).next_power_of_two());
        let supers = side * side;
        let mut s = from >> SUPER_BITS;
        while s < supers && s << SUPER_BITS < until {
            let (sx, sy) = (compact(s), compact(s >> 1));
            let slot = if sx < cols && sy < rows {
                lv.dir[(sy * cols + sx) as usize]
            } else {
                0
            };
            if slot != 0 {
                let table = &self.supers[slot as usize];
                let sbase = s << SUPER_BITS;
                let first = if sbase < from { (from - sbase) >> 8 } else { 0 };
                for pm in first..256 {
                    let pbase = sbase | pm << 8;
                    if pbase >= until {
                        return;
                    }
                    let (px, py) = (compact(pm), compact(pm >> 1));
                    let page = table[(py << 4 | px) as usize] as usize;
                    if page == 0 {
                        continue;
                    }
                    for (wi, &word) in self.pages[page].iter().enumerate() {
                        let base = pbase | (wi as u64) << 6;
                        if base >= until {
                            return;
                        }
                        if base + 64 <= from {
                            continue;
                        }
                        let word = if base < from {
                            word & (!0u64 << (from - base))
                        } else {
                            word
                        };
                        if word != 0 && !f(base, word) {
                            return;
                        }
                    }
                }
            }
            s += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::{NodeId, TreeShape};
    use proptest::prelude::*;

    fn morton(n: NodeId) -> u64 {
        crate::delta::wire_key(n) & ((1 << crate::delta::KEY_LEVEL_SHIFT) - 1)
    }

    proptest! {
        /// Counts and selections against a sorted list of the level's codes, on grids whose
        /// finest levels span several superpages.
        #[test]
        fn ranks_are_those_of_the_sorted_codes(w in 2u32..1400, h in 2u32..1400,
                                               level_pick in any::<u8>(),
                                               nodes in proptest::collection::vec((any::<u32>(), any::<u32>()), 0..300),
                                               probes in proptest::collection::vec((any::<u64>(), any::<u64>(), 0u64..40), 1..40)) {
            let shape = TreeShape::new(w, h).unwrap();
            let level = level_pick % shape.depth();
            let (lw, lh) = shape.level_dims(level);
            let mut set = NodeSet::default();
            let mut codes = Vec::new();
            for (x, y) in nodes {
                let n = NodeId { level, x: x % lw, y: y % lh };
                if set.insert(&shape, n) {
                    codes.push(morton(n));
                }
            }
            // Another level's nodes must not count.
            if level + 1 < shape.depth() {
                set.insert(&shape, NodeId { level: level + 1, x: 0, y: 0 });
            }
            codes.sort_unstable();
            let top = morton(NodeId { level, x: lw - 1, y: lh - 1 }).next_power_of_two() * 4;
            for (a, b, k) in probes {
                let (lo, hi) = (a % top, b % top);
                let want = codes.iter().filter(|&&c| c >= lo && c < hi).count() as u64;
                prop_assert_eq!(set.count_morton(level, lo, hi), want);
                let after: Vec<u64> = codes.iter().copied().filter(|&c| c >= lo).collect();
                prop_assert_eq!(set.select_morton(level, lo, k), after.get(k as usize).copied());
            }
            for (i, &c) in codes.iter().enumerate() {
                prop_assert_eq!(set.count_morton(level, 0, c), i as u64);
                prop_assert_eq!(set.select_morton(level, 0, i as u64), Some(c));
            }
        }
    }

    #[test]
    fn an_empty_level_has_no_ranks() {
        let set = NodeSet::default();
        assert_eq!(set.count_morton(3, 0, u64::MAX), 0);
        assert_eq!(set.select_morton(3, 0, 0), None);
    }
}
