//! Cut snapshots (DESIGN.md section 6, "Resume"): a cut sent compactly, one bit per inner node
//! in a canonical traversal, so that a client can resume its session on any server replica and a
//! stateless client can name its base cut.
//!
//! **Encoding.** Walk the tree depth first from the root, children in [`NodeId::child`] order
//! (the order of [`TreeShape::children`]), and descend only into interior nodes. Every visited
//! node that is not a leaf of the tree gives one bit: 1 if it is interior, 0 if it is active.
//! Leaves of the tree can never split and give no bit. Bits fill bytes from the least
//! significant bit up; the unused high bits of the last byte are 0. The cut's
//! [`Cut::digest`] travels with the bits so that the receiver can check what it rebuilt.
//!
//! A snapshot of a cut with `i` interior nodes holds at most `4i + 1` bits: about 1.3 bits per
//! active node.

use crate::codec::{Decode, Encode};
use crate::cut::Cut;
use crate::tree::{NodeId, TreeShape};

/// A cut, compactly.
#[derive(Clone, Debug, PartialEq, Eq, Encode, Decode)]
pub struct Snapshot {
    /// [`Cut::digest`] of the cut, to check the rebuilt one against.
    pub digest: u64,
    /// One bit per visited inner node in the canonical traversal, least significant bit first.
    pub bits: Vec<u8>,
}

/// A snapshot that does not describe a cut of this terrain.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum SnapshotError {
    /// The bits end before the traversal does.
    #[error("snapshot is truncated: the traversal needs more bits than the {0} sent")]
    Truncated(usize),
    /// Bits or bytes remain after the traversal ends.
    #[error("snapshot has {0} bits after the end of the traversal")]
    Trailing(usize),
    /// More interior nodes than the receiver accepts.
    #[error("snapshot holds more than {0} interior nodes")]
    TooLarge(usize),
    /// The rebuilt cut's digest differs from the one sent.
    #[error(
        "snapshot digest mismatch: the bits give {ours:#018x}, the snapshot says {theirs:#018x}"
    )]
    Digest {
        /// Digest of the cut the bits describe.
        ours: u64,
        /// Digest the snapshot carries.
        theirs: u64,
    },
}

impl Snapshot {
    /// The snapshot of `cut`.
    pub fn of(shape: &TreeShape, cut: &Cut) -> Snapshot {
        let mut bits = Vec::with_capacity(cut.interior_count() / 2 + 1);
        let mut n_bits = 0usize;
        let mut stack = vec![NodeId::ROOT];
        while let Some(node) = stack.pop() {
            if shape.is_leaf(node) {
                continue;
            }
            let interior = cut.is_interior(shape, node);
            if n_bits.is_multiple_of(8) {
                bits.push(0);
            }
            if interior {
                bits[n_bits / 8] |= 1 << (n_bits % 8);
                // Reversed so that children pop in order.
                let children: Vec<NodeId> = shape.children(node).map(|(_, c)| c).collect();
                stack.extend(children.into_iter().rev());
            }
            n_bits += 1;
        }
        Snapshot {
            digest: cut.digest(),
            bits,
        }
    }

    /// Rebuilds the cut, refusing snapshots with more than `max_interior` interior nodes,
    /// malformed bit strings and digest mismatches.
    pub fn to_cut(&self, shape: &TreeShape, max_interior: usize) -> Result<Cut, SnapshotError> {
        let total = self.bits.len() * 8;
        let mut cut = Cut::root(shape);
        let mut at = 0usize;
        let mut interior = 0usize;
        let mut stack = vec![NodeId::ROOT];
        while let Some(node) = stack.pop() {
            if shape.is_leaf(node) {
                continue;
            }
            if at >= total {
                return Err(SnapshotError::Truncated(total));
            }
            let bit = self.bits[at / 8] >> (at % 8) & 1;
            at += 1;
            if bit == 1 {
                interior += 1;
                if interior > max_interior {
                    return Err(SnapshotError::TooLarge(max_interior));
                }
                // The traversal reaches only active, inner nodes: the split cannot fail.
                let _ = cut.split(shape, node);
                let children: Vec<NodeId> = shape.children(node).map(|(_, c)| c).collect();
                stack.extend(children.into_iter().rev());
            }
        }
        let rest = total - at;
        let padding_set = !at.is_multiple_of(8) && self.bits[at / 8] >> (at % 8) != 0;
        if rest >= 8 || padding_set {
            return Err(SnapshotError::Trailing(rest));
        }
        if cut.digest() != self.digest {
            return Err(SnapshotError::Digest {
                ours: cut.digest(),
                theirs: self.digest,
            });
        }
        Ok(cut)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A cut of `shape` grown by splitting the nodes that `picks` select, parents first.
    fn random_cut(shape: &TreeShape, picks: &[u16]) -> Cut {
        let mut cut = Cut::root(shape);
        let mut frontier = vec![NodeId::ROOT];
        for &p in picks {
            if frontier.is_empty() {
                break;
            }
            let node = frontier.swap_remove(p as usize % frontier.len());
            if cut.split(shape, node).is_ok() {
                frontier.extend(shape.children(node).map(|(_, c)| c));
            }
        }
        cut
    }

    proptest! {
        #[test]
        fn round_trips(w in 2u32..90, h in 2u32..90,
                       picks in proptest::collection::vec(any::<u16>(), 0..200)) {
            let shape = TreeShape::new(w, h).unwrap();
            let cut = random_cut(&shape, &picks);
            let snap = Snapshot::of(&shape, &cut);
            prop_assert!(snap.bits.len() * 8 <= 4 * cut.interior_count() + 8);
            let back = snap.to_cut(&shape, usize::MAX).unwrap();
            prop_assert_eq!(back.digest(), cut.digest());
            prop_assert_eq!(back.interior_count(), cut.interior_count());
        }

        #[test]
        fn garbage_never_panics(bits in proptest::collection::vec(any::<u8>(), 0..64),
                                digest in any::<u64>()) {
            let shape = TreeShape::new(65, 40).unwrap();
            let _ = Snapshot { digest, bits }.to_cut(&shape, 1000);
        }
    }

    #[test]
    fn malformed_snapshots_are_refused() {
        let shape = TreeShape::new(33, 33).unwrap();
        let cut = random_cut(&shape, &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9]);
        let snap = Snapshot::of(&shape, &cut);

        let mut truncated = snap.clone();
        truncated.bits.pop();
        assert!(matches!(
            truncated.to_cut(&shape, usize::MAX),
            Err(SnapshotError::Truncated(_)) | Err(SnapshotError::Trailing(_))
        ));

        let mut trailing = snap.clone();
        trailing.bits.push(0);
        assert!(matches!(
            trailing.to_cut(&shape, usize::MAX),
            Err(SnapshotError::Trailing(n)) if n >= 8
        ));

        let mut wrong = snap.clone();
        wrong.digest ^= 1;
        assert!(matches!(
            wrong.to_cut(&shape, usize::MAX),
            Err(SnapshotError::Digest { .. })
        ));

        // An interior-node cap below the cut's size refuses it.
        assert!(matches!(
            snap.to_cut(&shape, 3),
            Err(SnapshotError::TooLarge(3))
        ));

        // Every bit set: the traversal asks for more bits than a short string holds.
        let all = Snapshot {
            digest: 0,
            bits: vec![0xFF; 4],
        };
        assert!(matches!(
            all.to_cut(&shape, usize::MAX),
            Err(SnapshotError::Truncated(32))
        ));
    }
}
