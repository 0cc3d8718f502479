//! Where a node's record lies in the store's `nodes` section: the four children of a node are
//! adjacent, so one evaluation of a node and its children reads one or two cache lines.
//!
//! Level `l >= 1` is stored as 2 x 2 quads in the row-major order of their parents: the children
//! of the node at `(x, y)` of level `l - 1` (row-major position `i = y * w + x` in that level)
//! occupy slots `base(l) + 4 i + k`, `k` as in [`NodeId::child`] (NW, NE, SW, SE). Children that
//! a border node lacks leave their slots zeroed, which costs under one row of quads per level.
//! The root is slot 0.
//!
//! A record is a `u32`: the node's height in z quanta in the high 24 bits (signed), its
//! static-error code in the low 8 (0 for leaves). Height, error code and so the whole box of
//! the node's screen error come from one load.

use relief_proto::tree::{NodeId, TreeShape};

/// Heights must fit the record's 24 signed bits.
pub const Z_LIMIT: i32 = (1 << 23) - 1;

/// The slot arithmetic of one tree shape.
#[derive(Clone, Debug, PartialEq)]
pub struct QuadLayout {
    /// First slot of each level.
    base: Vec<u64>,
    /// Nodes per row of each level.
    width: Vec<u32>,
    /// Slots in all.
    len: u64,
}

impl QuadLayout {
    /// The layout of `shape`'s nodes.
    pub fn new(shape: &TreeShape) -> QuadLayout {
        let mut base = vec![0u64];
        let mut width = Vec::new();
        let mut len = 1u64;
        for l in 0..=shape.depth() {
            let (w, h) = shape.level_dims(l);
            width.push(w);
            if l < shape.depth() {
                base.push(len);
                len += 4 * w as u64 * h as u64;
            }
        }
        QuadLayout { base, width, len }
    }

    /// Number of slots.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Whether there are no slots (never: the root has one).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Number of levels.
    pub fn levels(&self) -> usize {
        self.base.len()
    }

    /// The first slot of `level`'s records.
    pub fn level_start(&self, level: u8) -> u64 {
        self.base[level as usize]
    }

    /// The slot of `node`.
    #[inline]
    pub fn slot(&self, node: NodeId) -> usize {
        if node.level == 0 {
            return 0;
        }
        let l = node.level as usize;
        let parent = (node.y >> 1) as u64 * self.width[l - 1] as u64 + (node.x >> 1) as u64;
        (self.base[l] + 4 * parent) as usize + (node.x & 1) as usize + 2 * (node.y & 1) as usize
    }

    /// The slot of `node`'s child 0; children `k` follow at `+ k`.
    #[inline]
    pub fn children_slot(&self, node: NodeId) -> usize {
        let l = node.level as usize;
        (self.base[l + 1] + 4 * (node.y as u64 * self.width[l] as u64 + node.x as u64)) as usize
    }
}

/// A height in metres as a whole number of quanta (`inv` is one over the quantum), rounded
/// half away from zero without a libm call: the store's heights, in the tree and the tiles.
#[inline]
pub fn quantise(h: f32, inv: f32) -> i32 {
    let v = h * inv;
    (v + 0.5f32.copysign(v)) as i32
}

/// A record's height in z quanta.
#[inline]
pub fn rec_z(rec: u32) -> i32 {
    (rec as i32) >> 8
}

/// A record's static-error code.
#[inline]
pub fn rec_code(rec: u32) -> u8 {
    rec as u8
}

/// The record of a node of height `z` (within [`Z_LIMIT`]) and error code `code`.
pub fn record(z: i32, code: u8) -> u32 {
    ((z << 8) as u32) | code as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_node_has_its_own_slot_and_children_are_adjacent() {
        for (w, h) in [(2, 2), (5, 3), (13, 7), (64, 65)] {
            let shape = TreeShape::new(w, h).unwrap();
            let layout = QuadLayout::new(&shape);
            let mut seen = std::collections::HashSet::new();
            for i in 0..shape.node_count() {
                let n = shape.node(i).unwrap();
                let s = layout.slot(n);
                assert!((s as u64) < layout.len());
                assert!(seen.insert(s), "{n:?} shares slot {s}");
                for (k, c) in shape.children(n) {
                    assert_eq!(layout.slot(c), layout.children_slot(n) + k);
                }
            }
        }
    }

    #[test]
    fn records_round_trip() {
        for (z, c) in [(0, 0), (-1, 255), (Z_LIMIT, 7), (-Z_LIMIT, 1)] {
            assert_eq!((rec_z(record(z, c)), rec_code(record(z, c))), (z, c));
        }
    }
}
