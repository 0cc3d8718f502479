//! The cut: which nodes of the vertex quadtree are active (paper 000, section 3.4).
//!
//! In the paper's words every node is a null-subtree root (active, drawn), a node inside a null
//! subtree, or a not-null node. The cut stores only the not-null nodes, here called *interior*:
//! a node is active when its parent is interior (or it is the root) and it is not interior itself.
//! Every interior node has all its existing children either interior or active, so the active
//! nodes tile the grid. Storing the interior set alone costs about a third of the active count.
//!
//! Both ends keep one: the server for each session, the client as the mirror it rebuilds from
//! deltas. The interior set is a paged bitset ([`NodeSet`]): a test is a bit test and the memory
//! follows the cut, not the terrain. The [`Cut::digest`] is an order-independent hash of the
//! active set, kept up to date on every split and merge, that each delta carries so that a desync
//! is detected, never silent.

use crate::nodeset::NodeSet;
use crate::tree::{NodeId, TreeShape};

/// A split or merge that the current cut does not allow.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum CutError {
    /// The node is not part of the tree.
    #[error("node {0:?} does not exist in this terrain")]
    UnknownNode(NodeId),
    /// Only an active, non-leaf node can split.
    #[error("node {0:?} cannot split: it is not an active inner node")]
    NotSplittable(NodeId),
    /// Only an interior node whose children are all active can merge.
    #[error("node {0:?} cannot merge: it is not an interior node with only active children")]
    NotMergeable(NodeId),
}

/// The set of interior nodes, plus the digest of the active set it implies.
#[derive(Clone, Debug, Default)]
pub struct Cut {
    /// The interior (split) nodes.
    interior: NodeSet,
    /// Sum of [`node_hash`] over the active nodes, wrapping; see [`Cut::digest`].
    digest: u64,
    /// Number of active nodes, kept so that sizes are reported without a walk.
    active: u64,
}

/// A 64-bit mix of a dense node index: the digest is the wrapping sum of these over the active set.
pub fn node_hash(index: u64) -> u64 {
    // splitmix64's finaliser: a bijection with good avalanche, so that sums rarely collide.
    let mut z = index.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The sum of the digest terms of an inner node's existing children, and their number: all four
/// hashed and the missing ones masked off, with no branch per child (whether a child exists
/// varies along the grid's borders, and the branch mispredicted).
#[inline]
fn children_terms(shape: &TreeShape, node: NodeId) -> (u64, u64) {
    let (indices, exists) = shape.children_indices(node);
    let mut terms = 0u64;
    for (k, &i) in indices.iter().enumerate() {
        let mask = 0u64.wrapping_sub(u64::from(exists >> k & 1));
        terms = terms.wrapping_add(node_hash(i) & mask);
    }
    (terms, u64::from(exists.count_ones()))
}

impl Cut {
    /// The coarsest cut: the root alone is active.
    pub fn root(shape: &TreeShape) -> Cut {
        Cut {
            interior: NodeSet::default(),
            digest: node_hash(shape.index(NodeId::ROOT)),
            active: 1,
        }
    }

    /// The same cut whose interior nodes carry a 4-bit tag each ([`Cut::tag`], all 0), for an
    /// owner's bookkeeping.
    pub fn tagged(&self, shape: &TreeShape) -> Cut {
        let mut interior = NodeSet::tagged();
        for n in self.interior.iter() {
            interior.insert(shape, n);
        }
        Cut {
            interior,
            digest: self.digest,
            active: self.active,
        }
    }

    /// The tag of interior node `node` in a [`Cut::tagged`] cut (0 otherwise).
    #[inline]
    pub fn tag(&self, node: NodeId) -> u8 {
        self.interior.tag(node)
    }

    /// The tag of `node` when it is interior (see [`Cut::tag`]), `None` when it is not.
    #[inline]
    pub fn interior_tag(&self, node: NodeId) -> Option<u8> {
        self.interior.member_tag(node)
    }

    /// Prefetches what [`Cut::interior_tag`] of `node` reads.
    #[inline(always)]
    pub fn prefetch_tag(&self, node: NodeId) {
        self.interior.prefetch(node)
    }

    /// Sets the tag of interior node `node` in a [`Cut::tagged`] cut (its low four bits).
    #[inline]
    pub fn set_tag(&mut self, node: NodeId, tag: u8) {
        self.interior.set_tag(node, tag)
    }

    /// Adds one (modulo 16) to the tag of interior node `node` in a [`Cut::tagged`] cut and
    /// returns it.
    #[inline]
    pub fn bump_tag(&mut self, node: NodeId) -> u8 {
        self.interior.bump_tag(node)
    }

    /// Order-independent digest of the active set.
    pub fn digest(&self) -> u64 {
        self.digest
    }

    /// Number of active nodes.
    pub fn active_count(&self) -> u64 {
        self.active
    }

    /// Number of interior nodes.
    pub fn interior_count(&self) -> usize {
        self.interior.len()
    }

    /// Bytes of memory the interior set holds.
    pub fn memory_bytes(&self) -> usize {
        self.interior.memory_bytes()
    }

    /// Whether `node` is interior (split). Nodes outside the tree are not.
    #[inline]
    pub fn is_interior(&self, _shape: &TreeShape, node: NodeId) -> bool {
        self.interior.contains(node)
    }

    /// Number of interior nodes of `level` whose Morton code lies in `lo .. hi`.
    pub fn interior_count_morton(&self, level: u8, lo: u64, hi: u64) -> u64 {
        self.interior.count_morton(level, lo, hi)
    }

    /// The Morton code of the interior node of `level` with exactly `k` interior nodes of that
    /// level from code `from` (inclusive) up to it, if there is one.
    pub fn interior_select_morton(&self, level: u8, from: u64, k: u64) -> Option<u64> {
        self.interior.select_morton(level, from, k)
    }

    /// Which of `node`'s children are interior: bit `k` for child `k` ([`NodeId::child`]).
    #[inline]
    pub fn interior_children(&self, node: NodeId) -> u8 {
        self.interior.children_mask(node)
    }

    /// Which of `node`'s grandchildren are interior: nibble `k` is
    /// [`Cut::interior_children`] of child `k`, from one look-up.
    #[inline]
    pub fn interior_grandchildren(&self, node: NodeId) -> u16 {
        self.interior.grandchildren_mask(node)
    }

    /// Whether `node` is active: its parent is interior (or it is the root) and it is not.
    pub fn is_active(&self, shape: &TreeShape, node: NodeId) -> bool {
        shape.contains(node)
            && !self.is_interior(shape, node)
            && node.parent().is_none_or(|p| self.is_interior(shape, p))
    }

    /// The active node whose block holds sample `(col, row)`.
    ///
    /// Along a sample's root path the interior nodes form a prefix (an interior node's parent is
    /// interior), so the active node is the first non-interior one: a binary search over the
    /// levels, about log2(depth) lookups.
    pub fn active_ancestor(&self, shape: &TreeShape, col: u32, row: u32) -> NodeId {
        let leaf = shape.leaf(col, row);
        // Invariant: levels < lo are interior; level hi is not (leaves never are).
        let (mut lo, mut hi) = (0u8, shape.depth());
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.is_interior(shape, leaf.ancestor_at(mid)) {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        leaf.ancestor_at(lo)
    }

    /// Splits active node `node` into its children.
    pub fn split(&mut self, shape: &TreeShape, node: NodeId) -> Result<(), CutError> {
        if !shape.contains(node) {
            return Err(CutError::UnknownNode(node));
        }
        if shape.is_leaf(node) || !self.is_active(shape, node) {
            return Err(CutError::NotSplittable(node));
        }
        self.split_active(shape, node);
        Ok(())
    }

    /// Merges interior node `node`, all of whose children must be active.
    pub fn merge(&mut self, shape: &TreeShape, node: NodeId) -> Result<(), CutError> {
        if !shape.contains(node) {
            return Err(CutError::UnknownNode(node));
        }
        // Children that do not exist are never interior: one read of the children's bits.
        if !self.is_interior(shape, node) || self.interior_children(node) != 0 {
            return Err(CutError::NotMergeable(node));
        }
        self.merge_interior(shape, node);
        Ok(())
    }

    /// Splits `node`, for a caller that knows `node` is an active inner node (the engines, which
    /// have just looked): one bit set instead of [`Cut::split`]'s checks. Called on anything else
    /// it corrupts the cut (checked in debug builds).
    pub fn split_active(&mut self, shape: &TreeShape, node: NodeId) {
        debug_assert!(shape.contains(node) && !shape.is_leaf(node) && self.is_active(shape, node));
        let index = shape.index(node);
        self.interior.insert(shape, node);
        let (terms, count) = children_terms(shape, node);
        self.digest = self
            .digest
            .wrapping_sub(node_hash(index))
            .wrapping_add(terms);
        self.active += count - 1;
    }

    /// Merges `node`, for a caller that knows it is interior with only active children: one
    /// bit cleared instead of [`Cut::merge`]'s checks. Called on anything else it corrupts
    /// the cut (checked in debug builds).
    pub fn merge_interior(&mut self, shape: &TreeShape, node: NodeId) {
        debug_assert!(
            self.is_interior(shape, node)
                && shape
                    .children(node)
                    .all(|(_, c)| !self.is_interior(shape, c))
        );
        let index = shape.index(node);
        self.interior.remove(node);
        let (terms, count) = children_terms(shape, node);
        self.digest = self
            .digest
            .wrapping_add(node_hash(index))
            .wrapping_sub(terms);
        self.active -= count - 1;
    }

    /// The interior nodes' dense indices, level by level, in no set order within a level.
    pub fn interior_indices(&self) -> impl Iterator<Item = u64> + '_ {
        self.interior.iter().map(|n| self.interior.dense_index(n))
    }

    /// The interior nodes, level by level (parents before children), in no set order within a
    /// level.
    pub fn interior_nodes(&self) -> impl Iterator<Item = NodeId> + '_ {
        self.interior.iter()
    }

    /// All active nodes, found by walking down from the root (for tests and snapshots).
    pub fn active_nodes(&self, shape: &TreeShape) -> Vec<NodeId> {
        let mut out = Vec::with_capacity(self.active as usize);
        let mut stack = vec![NodeId::ROOT];
        while let Some(n) = stack.pop() {
            if self.is_interior(shape, n) {
                stack.extend(shape.children(n).map(|(_, c)| c));
            } else {
                out.push(n);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_and_merge_keep_digest_consistent() {
        let shape = TreeShape::new(9, 6).unwrap();
        let mut cut = Cut::root(&shape);
        let d0 = cut.digest();
        cut.split(&shape, NodeId::ROOT).unwrap();
        let c = NodeId::ROOT.child(0);
        cut.split(&shape, c).unwrap();
        let recomputed: u64 = cut
            .active_nodes(&shape)
            .iter()
            .fold(0u64, |a, &n| a.wrapping_add(node_hash(shape.index(n))));
        assert_eq!(recomputed, cut.digest());
        assert_eq!(cut.active_count() as usize, cut.active_nodes(&shape).len());
        assert_eq!(
            cut.merge(&shape, NodeId::ROOT),
            Err(CutError::NotMergeable(NodeId::ROOT))
        );
        cut.merge(&shape, c).unwrap();
        cut.merge(&shape, NodeId::ROOT).unwrap();
        assert_eq!(cut.digest(), d0);
    }

    #[test]
    fn rejects_invalid_operations() {
        let shape = TreeShape::new(4, 4).unwrap();
        let mut cut = Cut::root(&shape);
        let far = NodeId {
            level: 1,
            x: 5,
            y: 0,
        };
        assert_eq!(cut.split(&shape, far), Err(CutError::UnknownNode(far)));
        let child = NodeId::ROOT.child(3);
        assert_eq!(
            cut.split(&shape, child),
            Err(CutError::NotSplittable(child))
        );
        cut.split(&shape, NodeId::ROOT).unwrap();
        cut.split(&shape, child).unwrap();
        let leaf = child.child(0);
        assert_eq!(cut.split(&shape, leaf), Err(CutError::NotSplittable(leaf)));
        assert_eq!(cut.active_ancestor(&shape, 3, 3), child.child(3));
        assert_eq!(cut.active_ancestor(&shape, 0, 0), NodeId::ROOT.child(0));
    }
}
