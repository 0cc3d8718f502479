//! The greedy insertion's priority queue ([`super::tin`]; paper 003, section 3, step 3): each
//! triangle's worst sample, largest error first, in an indexed binary max-heap. A triangle's
//! entry is updated or removed in place when an insertion rewrites it, so the heap never holds
//! stale entries (a lazy-deletion heap grew to several times the live triangles and spent a
//! seventh of the time popping them).

use std::cmp::Reverse;

/// Not in the heap.
const NONE: u32 = u32::MAX;

/// A triangle's key: error bits (a non-negative `f64`'s bits order like its value), then the
/// sample's index reversed and the triangle's slot reversed, so that ties go to the smallest.
pub type Key = (u64, Reverse<u32>, Reverse<u32>);

/// An indexed max-heap of triangle slots.
#[derive(Debug, Default)]
pub struct Queue {
    /// Keys and their triangle slots, heap-ordered (keys inline, for locality).
    heap: Vec<(Key, u32)>,
    /// Each slot's index in `heap`, or `NONE`, to find an entry to update.
    at: Vec<u32>,
}

impl Queue {
    /// The slot with the largest key, and its sample's index.
    pub fn peek(&self) -> Option<(u32, u32)> {
        self.heap.first().map(|&(key, t)| (t, key.1.0))
    }

    /// Sets slot `t`'s worst sample (error and sample index), or removes it with `None`.
    pub fn set(&mut self, t: u32, entry: Option<(f64, u32)>) {
        let ti = t as usize;
        if self.at.len() <= ti {
            self.at.resize(ti + 1, NONE);
        }
        let i = self.at[ti];
        match (entry, i) {
            (None, NONE) => {}
            (None, i) => {
                let (i, last) = (i as usize, self.heap.len() - 1);
                self.swap(i, last);
                self.heap.pop();
                self.at[ti] = NONE;
                if i < self.heap.len() {
                    let i = self.down(i);
                    self.up(i);
                }
            }
            (Some((err, k)), i) => {
                let key = (err.to_bits(), Reverse(k), Reverse(t));
                let i = if i == NONE {
                    self.heap.push((key, t));
                    self.at[ti] = self.heap.len() as u32 - 1;
                    self.heap.len() - 1
                } else {
                    self.heap[i as usize].0 = key;
                    i as usize
                };
                let i = self.down(i);
                self.up(i);
            }
        }
    }

    /// Swaps two heap entries and their back-pointers.
    fn swap(&mut self, i: usize, j: usize) {
        self.heap.swap(i, j);
        self.at[self.heap[i].1 as usize] = i as u32;
        self.at[self.heap[j].1 as usize] = j as u32;
    }

    /// Moves entry `i` up while it beats its parent.
    fn up(&mut self, mut i: usize) {
        while i > 0 && self.heap[i].0 > self.heap[(i - 1) / 2].0 {
            self.swap(i, (i - 1) / 2);
            i = (i - 1) / 2;
        }
    }

    /// Moves entry `i` down while a child beats it; returns where it ends.
    fn down(&mut self, mut i: usize) -> usize {
        let n = self.heap.len();
        loop {
            let (l, r) = (2 * i + 1, 2 * i + 2);
            let mut m = i;
            if l < n && self.heap[l].0 > self.heap[m].0 {
                m = l;
            }
            if r < n && self.heap[r].0 > self.heap[m].0 {
                m = r;
            }
            if m == i {
                return i;
            }
            self.swap(i, m);
            i = m;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// After any sequence of sets and removals, the top is the largest live key.
        #[test]
        fn the_top_is_the_largest_live_key(
            ops in proptest::collection::vec((0u32..20, proptest::option::of((0u8..6, 0u32..4))), 1..200),
        ) {
            let mut q = Queue::default();
            let mut live: Vec<Option<(u8, u32)>> = vec![None; 20];
            for (t, e) in ops {
                q.set(t, e.map(|(err, k)| (f64::from(err), k)));
                live[t as usize] = e;
                let want = (0..20u32)
                    .filter_map(|t| live[t as usize].map(|(e, k)| ((e, Reverse(k), Reverse(t)), t)))
                    .max()
                    .map(|(key, t)| (t, key.1.0));
                prop_assert_eq!(q.peek(), want);
            }
        }
    }
}
