//! Deltas: the merges and splits that take a client's cut to the server's, and their compact
//! body (DESIGN.md section 3, "Delta").
//!
//! A split carries what the client needs to create the four children and to geomorph them: the
//! three integer Haar details (children heights come back exactly from the parent's, see
//! [`crate::haar`]) and the node's one-byte static-error code (its screen error drives the
//! children's geomorph and defines its bounding box, see [`crate::terrain`]).
//!
//! **Body layout** (a bit stream, most significant bit first; "EG(k)" is an order-k Exp-Golomb
//! code, signed values zigzag-mapped first):
//! 1. `n_merges`, `n_splits`: EG(0).
//! 2. Three 4-bit code orders: merge positions, split positions, error residuals.
//! 3. Merges, then splits, each sorted by level and then by Morton (Z-order) code within the level,
//!    so that parents come before children and nearby nodes have nearby codes. Each node is its
//!    level step from the previous node, EG(0), then its Morton code: if the level is unchanged,
//!    as the gap to the previous code minus one, else as is, EG(order).
//! 4. For each level that has splits, in order, a 4-bit order for that level's details.
//! 5. Per split, in the same order: its three details, EG(level's order), then the error code's
//!    residual against a prediction both ends compute from the details alone (the code of the
//!    largest child-to-parent offset, which the node's error can never be below).
//!
//! All orders are chosen per delta to minimise the body. Decoding checks every index against the
//! tree and every value against its range, and reserves room for at most [`RESERVE_MAX`] entries
//! up front: beyond that, lists grow only as their entries decode.
//!
//! [`SplitEntropy`] measures what a run's split payloads carry under this coder's model, for the
//! benchmark (issue 11, "Bytes").

mod entropy;

pub use entropy::SplitEntropy;

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
    /// Interior nodes that merge, in canonical order (ascending level). They are applied in
    /// reverse, deepest first: a node and its child may both merge (a delta between distant
    /// cuts), and each node's children are active by the time it merges.
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
    /// A position names no node of this terrain.
    #[error("delta names node {0:?}, which this terrain does not have")]
    UnknownNode(NodeId),
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
    /// Puts merges and splits in wire order: by level, then Morton code (parents before children).
    /// Each node's key is computed once.
    pub fn canonicalize(&mut self) {
        self.merges.sort_by_cached_key(|&n| wire_key(n));
        self.splits.sort_by_cached_key(|s| wire_key(s.node));
    }

    /// Whether the delta changes nothing.
    pub fn is_empty(&self) -> bool {
        self.merges.is_empty() && self.splits.is_empty()
    }

    /// Encodes merges and splits into the compact body. `quantum` is the terrain's z quantum.
    pub fn pack_body(&self, _shape: &TreeShape, quantum: f32) -> Vec<u8> {
        let mut merges: Vec<(u8, u64)> =
            self.merges.iter().map(|&n| (n.level, morton(n))).collect();
        merges.sort_unstable();
        let mut splits: Vec<(u8, u64, &Split)> = self
            .splits
            .iter()
            .map(|s| (s.node.level, morton(s.node), s))
            .collect();
        splits.sort_unstable_by_key(|&(l, m, _)| (l, m));
        let m_pos = positions(merges.iter().copied());
        let s_pos = positions(splits.iter().map(|&(l, m, _)| (l, m)));
        let residuals: Vec<u64> = splits
            .iter()
            .map(|(_, _, s)| zigzag(s.err_code as i64 - predicted_code(s.details, quantum) as i64))
            .collect();
        let orders = [
            best_order(m_pos.iter().map(|p| p.1), 15),
            best_order(s_pos.iter().map(|p| p.1), 15),
            best_order(residuals.iter().copied(), 15),
        ];
        let mut w = BitWriter::new();
        w.put_eg(merges.len() as u64, 0);
        w.put_eg(splits.len() as u64, 0);
        for k in orders {
            w.put(k, 4);
        }
        for (step, v) in &m_pos {
            w.put_eg(*step as u64, 0);
            w.put_eg(*v, orders[0]);
        }
        for (step, v) in &s_pos {
            w.put_eg(*step as u64, 0);
            w.put_eg(*v, orders[1]);
        }
        // One detail order per level present.
        let mut level_orders = Vec::new();
        let mut i = 0;
        while i < splits.len() {
            let level = splits[i].0;
            let j = i + splits[i..].iter().take_while(|s| s.0 == level).count();
            let vals = splits[i..j]
                .iter()
                .flat_map(|(_, _, s)| s.details.map(|d| zigzag(d as i64)));
            let k = best_order(vals, 15);
            w.put(k, 4);
            level_orders.extend(std::iter::repeat_n(k, j - i));
            i = j;
        }
        for (n, (_, _, s)) in splits.iter().enumerate() {
            for d in s.details {
                w.put_eg_signed(d as i64, level_orders[n]);
            }
            w.put_eg(residuals[n], orders[2]);
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
        let mut orders = [0u32; 3];
        for k in &mut orders {
            *k = r.get(4).ok_or(BodyError::Malformed)?;
        }
        let mut delta = Delta {
            seq,
            digest,
            merges: Vec::with_capacity(reserve(n_merges)),
            splits: Vec::with_capacity(reserve(n_splits)),
        };
        let mut prev = None;
        for _ in 0..n_merges {
            delta
                .merges
                .push(next_node(shape, &mut r, orders[0], &mut prev)?);
        }
        let mut nodes = Vec::with_capacity(reserve(n_splits));
        let mut prev = None;
        for _ in 0..n_splits {
            nodes.push(next_node(shape, &mut r, orders[1], &mut prev)?);
        }
        let mut level_orders = Vec::with_capacity(nodes.len());
        let mut last_level = None;
        let mut k = 0;
        for n in &nodes {
            if last_level != Some(n.level) {
                k = r.get(4).ok_or(BodyError::Malformed)?;
                last_level = Some(n.level);
            }
            level_orders.push(k);
        }
        for (i, &node) in nodes.iter().enumerate() {
            let mut details = [0i32; 3];
            for d in &mut details {
                let v = r
                    .get_eg_signed(level_orders[i])
                    .ok_or(BodyError::Malformed)?;
                *d = i32::try_from(v).map_err(|_| BodyError::OutOfRange("detail"))?;
            }
            let res = r.get_eg(orders[2]).ok_or(BodyError::Malformed)?;
            let code = predicted_code(details, quantum) as i64 + crate::bits::unzigzag(res);
            let err_code = u8::try_from(code).map_err(|_| BodyError::OutOfRange("error code"))?;
            delta.splits.push(Split {
                node,
                err_code,
                details,
            });
        }
        // Only the last byte's zero padding may follow: anything else is not this encoder's.
        let rest = r.remaining();
        if rest >= 8 || r.get(rest as u32) != Some(0) {
            return Err(BodyError::Malformed);
        }
        Ok(delta)
    }
}

/// The most entries [`Delta::unpack_body`] reserves room for before decoding them. A count that
/// passes the bit check can still claim one entry per bit of the body, and reserving for all of
/// them made a 1 MiB body of garbage take 335 MB before it was refused (issue 12).
pub const RESERVE_MAX: u64 = 1 << 12;

/// Room to reserve for a list whose count a body claims.
fn reserve(n: u64) -> usize {
    n.min(RESERVE_MAX) as usize
}

/// The Morton (Z-order) code of a node within its level: x and y bits interleaved.
/// A node's place in wire order as one integer: its level, then its Morton code within the level
/// (codes take at most 30 bits).
pub fn wire_key(n: NodeId) -> u64 {
    (n.level as u64) << 58 | morton(n)
}

pub(crate) fn morton(n: NodeId) -> u64 {
    spread(n.x) | (spread(n.y) << 1)
}

fn spread(v: u32) -> u64 {
    let mut x = v as u64 & 0xFFFF_FFFF;
    x = (x | (x << 16)) & 0x0000_FFFF_0000_FFFF;
    x = (x | (x << 8)) & 0x00FF_00FF_00FF_00FF;
    x = (x | (x << 4)) & 0x0F0F_0F0F_0F0F_0F0F;
    x = (x | (x << 2)) & 0x3333_3333_3333_3333;
    (x | (x << 1)) & 0x5555_5555_5555_5555
}

fn compact(v: u64) -> u32 {
    let mut x = v & 0x5555_5555_5555_5555;
    x = (x | (x >> 1)) & 0x3333_3333_3333_3333;
    x = (x | (x >> 2)) & 0x0F0F_0F0F_0F0F_0F0F;
    x = (x | (x >> 4)) & 0x00FF_00FF_00FF_00FF;
    x = (x | (x >> 8)) & 0x0000_FFFF_0000_FFFF;
    ((x | (x >> 16)) & 0xFFFF_FFFF) as u32
}

/// (level step, position value) per node of a (level, morton)-sorted list: the value is the gap to
/// the previous code minus one within a level, the code itself on a new level.
pub(crate) fn positions(sorted: impl Iterator<Item = (u8, u64)>) -> Vec<(u8, u64)> {
    let mut prev: Option<(u8, u64)> = None;
    sorted
        .map(|(l, m)| {
            let out = match prev {
                Some((pl, pm)) if pl == l => (0, m - pm - 1),
                Some((pl, _)) => (l - pl, m),
                None => (l, m),
            };
            prev = Some((l, m));
            out
        })
        .collect()
}

fn next_node(
    shape: &TreeShape,
    r: &mut BitReader<'_>,
    k: u32,
    prev: &mut Option<(u8, u64)>,
) -> Result<NodeId, BodyError> {
    let step = r.get_eg(0).ok_or(BodyError::Malformed)?;
    let v = r.get_eg(k).ok_or(BodyError::Malformed)?;
    let (level, code) = match *prev {
        Some((pl, pm)) if step == 0 => {
            (pl as u64, pm.checked_add(v).and_then(|c| c.checked_add(1)))
        }
        Some((pl, _)) => (pl as u64 + step, Some(v)),
        None => (step, Some(v)),
    };
    let code = code.ok_or(BodyError::Malformed)?;
    if level > shape.depth() as u64 || code >> 62 != 0 {
        return Err(BodyError::Malformed);
    }
    let node = NodeId {
        level: level as u8,
        x: compact(code),
        y: compact(code >> 1),
    };
    if !shape.contains(node) {
        return Err(BodyError::UnknownNode(node));
    }
    if shape.is_leaf(node) {
        return Err(BodyError::LeafNode(node));
    }
    *prev = Some((node.level, code));
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
            let mut d = d;
            d.canonicalize();
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

    /// Issue 12: a count that the bits could hold, in a body of garbage, reserved room for every
    /// claimed entry (a 1 MiB body, about 335 MB) before its second entry failed to decode.
    #[test]
    fn issue_12_lying_counts_reserve_little() {
        assert_eq!(reserve(u64::MAX), RESERVE_MAX as usize);
        assert_eq!(reserve(17), 17);
        let shape = TreeShape::new(65, 65).unwrap();
        let mut w = BitWriter::new();
        w.put_eg(0, 0);
        w.put_eg((8 << 20) - 1000, 0);
        w.put(0, 12);
        // All ones: the root, then the node after it on level 0, which does not exist.
        for _ in 0..(1 << 18) - 4 {
            w.put(u32::MAX, 32);
        }
        let body = w.finish();
        assert!(body.len() <= 1 << 20);
        assert_eq!(
            Delta::unpack_body(&shape, 0.25, 0, 0, &body),
            Err(BodyError::UnknownNode(NodeId {
                level: 0,
                x: 1,
                y: 0
            }))
        );
    }

    #[test]
    fn padding_must_be_zero_and_nothing_may_follow() {
        let shape = TreeShape::new(65, 65).unwrap();
        let d = Delta {
            seq: 1,
            digest: 2,
            merges: vec![],
            splits: vec![Split {
                node: NodeId::ROOT,
                err_code: predicted_code([3, -4, 5], 0.1),
                details: [3, -4, 5],
            }],
        };
        let body = d.pack_body(&shape, 0.1);
        assert_eq!(Delta::unpack_body(&shape, 0.1, 1, 2, &body).unwrap(), d);
        let mut longer = body.clone();
        longer.push(0);
        assert_eq!(
            Delta::unpack_body(&shape, 0.1, 1, 2, &longer),
            Err(BodyError::Malformed)
        );
        let mut dirty = body.clone();
        let last = dirty.len() - 1;
        dirty[last] |= 1;
        // Either the low bit was padding (refused) or data (the body changes or breaks).
        assert_ne!(Delta::unpack_body(&shape, 0.1, 1, 2, &dirty), Ok(d));
    }
}
