//! The prediction of a split's details from its parent's (protocol 5, docs/protocol.md section
//! 5.4).
//!
//! A node's three Haar details measure its block's slope across it (`dv` north minus south,
//! `dh` west minus east) and its twist (`dd`). On ground that is smooth at the node's scale the
//! slope across a child is half the slope across its parent and the twist a quarter, so each
//! split's details are sent as residuals against `[dv >> 1, dh >> 1, dd >> 2]` of its parent's
//! details (arithmetic shifts: floor). A component the split's block cannot have (the east or
//! south column of children missing on the grid's border makes `dh`, `dv` and `dd` structurally
//! 0, see [`crate::haar`]) is predicted as 0.
//!
//! Both ends know the parent's details: a parent that split in the same body was decoded before
//! its children (bodies list splits parents first); any other parent is interior in the
//! receiver's cut, whose mirror holds its children's heights, and the sender holds every node's.
//! [`Parents`] is that source; a body coded against [`NoParents`] stands alone.
//!
//! Measured on the standard path's recorded streams (600 poses, the connection's models):
//! detail bytes a split fell from 2.88 to 2.49 on synthetic:4097 and from 2.59 to 2.43 on
//! fuji_srtm3 (`docs/vertex-stream.md`).

use crate::bits::zigzag;
use crate::haar::{Presence, Quad, forward};
use crate::tree::{NodeId, TreeShape};

use super::{KEY_LEVEL_SHIFT, Split, key_of, wire_key};

/// Where a body's coder finds the details of a split's parent that did not split in the same
/// body: the client's mirror, the server's store.
pub trait Parents {
    /// The three Haar details of `node`'s children (as [`crate::haar::forward`] gives them), if
    /// `node` is interior for the receiver; `None` otherwise (the prediction is then 0, and a
    /// split under a node that is not interior does not apply anyway).
    fn details(&self, node: NodeId) -> Option<[i32; 3]>;
}

/// No parent known beyond the body: every split whose parent is not in the same body is
/// predicted as 0. For bodies that must decode alone (tests, fuzzing); both ends must agree.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoParents;

impl Parents for NoParents {
    fn details(&self, _: NodeId) -> Option<[i32; 3]> {
        None
    }
}

/// The details of a node whose children's heights are `quad` (as a mirror holds them).
pub fn quad_details(shape: &TreeShape, node: NodeId, quad: Quad) -> [i32; 3] {
    forward(quad, presence(shape, node)).1
}

/// Which of `node`'s children exist.
fn presence(shape: &TreeShape, node: NodeId) -> Presence {
    let (w, h) = shape.level_dims(node.level + 1);
    Presence {
        east: 2 * node.x + 1 < w,
        south: 2 * node.y + 1 < h,
    }
}

/// The wire key of the parent of the node whose wire key is `key` (not of level 0).
fn parent_key(key: u64) -> u64 {
    ((key >> KEY_LEVEL_SHIFT) - 1) << KEY_LEVEL_SHIFT | (key & ((1 << KEY_LEVEL_SHIFT) - 1)) >> 2
}

/// Predicts the splits of one body in order ([`Predictor::predict`]: `key_at(k)` is the wire key
/// of the body's `k`-th split and `details_at(k)`, for `k` before the one predicted, its details).
pub(super) struct Predictor<'p> {
    /// The source for parents outside the body.
    parents: &'p dyn Parents,
    /// The first split of the body whose key is not below the last parent key asked for.
    cursor: usize,
}

impl<'p> Predictor<'p> {
    pub(super) fn new(parents: &'p dyn Parents) -> Predictor<'p> {
        Predictor { parents, cursor: 0 }
    }

    /// The prediction for `node`, the body's `i`-th split, whose wire key is `key`
    /// ([`wire_key`]; `key_at(k)` is the `k`-th split's). Splits are met in the body's order
    /// (level, then Morton code), so their parents' keys never decrease and one cursor finds
    /// every parent that split earlier in the body. A parent's key is its child's, a level up
    /// and the Morton code shifted by two bits, so no key is computed here.
    pub(super) fn predict(
        &mut self,
        shape: &TreeShape,
        i: usize,
        (node, key): (NodeId, u64),
        mut key_at: impl FnMut(usize) -> u64,
        details_at: impl FnOnce(usize) -> [i32; 3],
    ) -> [i32; 3] {
        let Some(parent) = node.parent() else {
            return [0; 3];
        };
        let parent_key = parent_key(key);
        debug_assert_eq!(parent_key, wire_key(parent));
        while self.cursor < i && key_at(self.cursor) < parent_key {
            self.cursor += 1;
        }
        let pd = if self.cursor < i && key_at(self.cursor) == parent_key {
            details_at(self.cursor)
        } else {
            match self.parents.details(parent) {
                Some(d) => d,
                None => return [0; 3],
            }
        };
        let p = presence(shape, node);
        [
            if p.south { pd[0] >> 1 } else { 0 },
            if p.east { pd[1] >> 1 } else { 0 },
            if p.east && p.south { pd[2] >> 2 } else { 0 },
        ]
    }

    /// What the body sends for the details of `splits[i]`, splits in wire order with their
    /// levels and Morton codes (as the packer sorts them): each detail less its prediction
    /// (wrapping), zigzag-mapped.
    pub(super) fn residuals(
        &mut self,
        shape: &TreeShape,
        splits: &[(u8, u64, &Split)],
        i: usize,
    ) -> [u64; 3] {
        let key = |k: usize| key_of(splits[k].0, splits[k].1);
        let s = splits[i].2;
        let p = self.predict(shape, i, (s.node, key(i)), key, |k| splits[k].2.details);
        std::array::from_fn(|c| zigzag(i64::from(s.details[c].wrapping_sub(p[c]))))
    }
}
