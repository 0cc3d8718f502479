//! Deltas: the merges and splits that take a client's cut to the server's, and their compact
//! body (DESIGN.md section 3, "Delta").
//!
//! A split carries what the client needs to create the four children and to geomorph them: the
//! three integer Haar details (children heights come back exactly from the parent's, see
//! [`crate::haar`]) and the node's one-byte static-error code (its screen error drives the
//! children's geomorph and defines its bounding box, see [`crate::node`]).
//!
//! **Body layout** (a bit stream, most significant bit first):
//! 1. `n_merges`, `n_splits`: order-0 Exp-Golomb.
//! 2. Four 4-bit code orders: merge gaps, split gaps, details, error residuals.
//! 3. Merges, by increasing dense index: the gap to the previous index (minus one).
//! 4. Splits, by increasing dense index (so parents come before children): the gap, then the three
//!    details (zigzag, signed Exp-Golomb), then the error code's residual against a prediction
//!    both ends compute from the details alone: the code of the largest child-to-parent offset,
//!    which the node's error can never be below.
//!
//! The orders are chosen per delta to minimise the body. Decoding checks every index against the
//! tree and every value against its range, and never allocates more entries than there are bits.

use crate::bits::{BitReader, BitWriter, best_order, zigzag};
use crate::haar::{error_code, inverse};
use crate::tree::{NodeId, TreeShape};

/// One split: an active node becomes interior and its children become active.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Split {
    /// The node that splits.
    pub node: NodeId,
    /// The node's quantised static error ([`crate::haar::error_value`]).
    pub err_code: u8,
    /// The node's three Haar details, in z quanta: its children's heights follow from its own.
    pub details: [i32; 3],
}

/// The change from one cut to the next, with the digest of the cut it produces.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Delta {
    /// Sequence number of the delta within its session.
    pub seq: u64,
    /// [`crate::cut::Cut::digest`] of the cut after this delta.
    pub digest: u64,
    /// Interior nodes that merge (all their children are active before the delta).
    pub merges: Vec<NodeId>,
    /// Active nodes that split, parents before children.
    pub splits: Vec<Split>,
}

/// A delta body that does not decode against this terrain.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum BodyError {
    /// The bit stream ended early or a code was malformed.
    #[error("delta body is truncated or malformed")]
    Malformed,
    /// An index names no node of this terrain.
    #[error("delta names node index {0}, beyond this terrain's {1} nodes")]
    UnknownNode(u64, u64),
    /// A leaf cannot split and cannot be merged.
    #[error("delta splits or merges leaf node {0:?}")]
    LeafNode(NodeId),
    /// A value is outside its range.
    #[error("delta holds an out-of-range {0}")]
    OutOfRange(&'static str),
}

/// The error code both ends predict from a split's details, in z quanta of `quantum` metres.
pub fn predicted_code(details: [i32; 3], quantum: f32) -> u8 {
    let offsets = inverse(0, details);
    let max = offsets.iter().map(|v| v.unsigned_abs()).max().unwrap_or(0);
    error_code(max as f32 * quantum)
}

impl Delta {
    /// Whether the delta changes nothing.
    pub fn is_empty(&self) -> bool {
        self.merges.is_empty() && self.splits.is_empty()
    }

    /// Encodes merges and splits into the compact body. `quantum` is the terrain's z quantum.
    pub fn pack_body(&self, shape: &TreeShape, quantum: f32) -> Vec<u8> {
        let mut merges: Vec<u64> = self.merges.iter().map(|&n| shape.index(n)).collect();
        merges.sort_unstable();
        let mut splits: Vec<(u64, &Split)> = self
            .splits
            .iter()
            .map(|s| (shape.index(s.node), s))
            .collect();
        splits.sort_unstable_by_key(|&(i, _)| i);
        let m_gaps = gaps(merges.iter().copied());
        let s_gaps = gaps(splits.iter().map(|&(i, _)| i));
        let details: Vec<u64> = splits
            .iter()
            .flat_map(|(_, s)| s.details.map(|d| zigzag(d as i64)))
            .collect();
        let residuals: Vec<u64> = splits
            .iter()
            .map(|(_, s)| zigzag(s.err_code as i64 - predicted_code(s.details, quantum) as i64))
            .collect();
        let orders = [
            best_order(m_gaps.iter().copied(), 15),
            best_order(s_gaps.iter().copied(), 15),
            best_order(details.iter().copied(), 15),
            best_order(residuals.iter().copied(), 15),
        ];
        let mut w = BitWriter::new();
        w.put_eg(merges.len() as u64, 0);
        w.put_eg(splits.len() as u64, 0);
        for k in orders {
            w.put(k, 4);
        }
        for g in &m_gaps {
            w.put_eg(*g, orders[0]);
        }
        for (i, g) in s_gaps.iter().enumerate() {
            w.put_eg(*g, orders[1]);
            for d in &details[3 * i..3 * i + 3] {
                w.put_eg(*d, orders[2]);
            }
            w.put_eg(residuals[i], orders[3]);
        }
        w.finish()
    }

    /// Decodes a body written by [`Delta::pack_body`] for the same terrain.
    pub fn unpack_body(
        shape: &TreeShape,
        quantum: f32,
        seq: u64,
        digest: u64,
        body: &[u8],
    ) -> Result<Delta, BodyError> {
        let mut r = BitReader::new(body);
        let n_merges = r.get_eg(0).ok_or(BodyError::Malformed)?;
        let n_splits = r.get_eg(0).ok_or(BodyError::Malformed)?;
        // Every entry takes at least one bit: a count beyond the bits left is a lie.
        if n_merges.saturating_add(n_splits) > r.remaining() {
            return Err(BodyError::Malformed);
        }
        let mut orders = [0u32; 4];
        for k in &mut orders {
            *k = r.get(4).ok_or(BodyError::Malformed)?;
        }
        let mut delta = Delta {
            seq,
            digest,
            merges: Vec::with_capacity(n_merges as usize),
            splits: Vec::with_capacity(n_splits as usize),
        };
        let mut prev = None;
        for _ in 0..n_merges {
            let node = next_node(shape, &mut r, orders[0], &mut prev)?;
            delta.merges.push(node);
        }
        let mut prev = None;
        for _ in 0..n_splits {
            let node = next_node(shape, &mut r, orders[1], &mut prev)?;
            let mut details = [0i32; 3];
            for d in &mut details {
                let v = r.get_eg_signed(orders[2]).ok_or(BodyError::Malformed)?;
                *d = i32::try_from(v).map_err(|_| BodyError::OutOfRange("detail"))?;
            }
            let res = r.get_eg_signed(orders[3]).ok_or(BodyError::Malformed)?;
            let code = predicted_code(details, quantum) as i64 + res;
            let err_code = u8::try_from(code).map_err(|_| BodyError::OutOfRange("error code"))?;
            delta.splits.push(Split {
                node,
                err_code,
                details,
            });
        }
        Ok(delta)
    }
}

/// Gaps between consecutive increasing values, minus one (the first is counted from 0).
fn gaps(sorted: impl Iterator<Item = u64>) -> Vec<u64> {
    let mut prev: Option<u64> = None;
    sorted
        .map(|i| {
            let g = match prev {
                None => i,
                Some(p) => i - p - 1,
            };
            prev = Some(i);
            g
        })
        .collect()
}

fn next_node(
    shape: &TreeShape,
    r: &mut BitReader<'_>,
    k: u32,
    prev: &mut Option<u64>,
) -> Result<NodeId, BodyError> {
    let gap = r.get_eg(k).ok_or(BodyError::Malformed)?;
    let index = match *prev {
        None => Some(gap),
        Some(p) => p.checked_add(gap).and_then(|v| v.checked_add(1)),
    }
    .ok_or(BodyError::Malformed)?;
    let node = shape
        .node(index)
        .ok_or(BodyError::UnknownNode(index, shape.node_count()))?;
    if shape.is_leaf(node) {
        return Err(BodyError::LeafNode(node));
    }
    *prev = Some(index);
    Ok(node)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arb_delta(shape: TreeShape) -> impl Strategy<Value = Delta> {
        let inner = shape.level_offset(shape.depth());
        let split = (
            0..inner,
            any::<u8>(),
            proptest::array::uniform3(-5000i32..5000),
        );
        (
            proptest::collection::btree_set(0..inner, 0..40),
            proptest::collection::btree_map(0..inner, split.prop_map(|(_, e, d)| (e, d)), 0..60),
            any::<u64>(),
        )
            .prop_map(move |(m, s, digest)| Delta {
                seq: 7,
                digest,
                merges: m.into_iter().map(|i| shape.node(i).unwrap()).collect(),
                splits: s
                    .into_iter()
                    .map(|(i, (err_code, details))| Split {
                        node: shape.node(i).unwrap(),
                        err_code,
                        details,
                    })
                    .collect(),
            })
    }

    proptest! {
        #[test]
        fn body_round_trips(d in arb_delta(TreeShape::new(300, 170).unwrap())) {
            let shape = TreeShape::new(300, 170).unwrap();
            let body = d.pack_body(&shape, 0.25);
            let back = Delta::unpack_body(&shape, 0.25, d.seq, d.digest, &body).unwrap();
            prop_assert_eq!(back, d);
        }

        #[test]
        fn random_bodies_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let shape = TreeShape::new(33, 20).unwrap();
            let _ = Delta::unpack_body(&shape, 0.25, 0, 0, &bytes);
        }
    }

    #[test]
    fn lying_counts_are_refused() {
        let shape = TreeShape::new(33, 20).unwrap();
        let mut w = BitWriter::new();
        w.put_eg(1 << 40, 0);
        w.put_eg(0, 0);
        let body = w.finish();
        assert_eq!(
            Delta::unpack_body(&shape, 0.25, 0, 0, &body),
            Err(BodyError::Malformed)
        );
    }
}
