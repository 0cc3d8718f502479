//! Deltas: the merges and splits that take a client's cut to the server's, and their compact
//! body (DESIGN.md section 3, "Delta").
//!
//! A split carries what the client needs to create the four children and to geomorph them: the
//! three integer Haar details (children heights come back exactly from the parent's, see
//! [`crate::haar`]) and the node's one-byte static-error code (its screen error drives the
//! children's geomorph and defines its bounding box, see [`crate::terrain`]).
//!
//! **Body layout**: one stream of the adaptive binary range coder of [`crate::range`], every
//! field an unsigned [`Value`] (signed ones zigzag-mapped first) in its own adaptive model. The
//! models ([`BodyModels`]) belong to the connection: fresh at its first delta, they carry over
//! from each body to the next, so that a session learns its statistics once rather than in every
//! body (fuji_srtm3: 4.09 -> 3.98 bytes a split). A one-shot delta (`POST /v1/lod`) starts from
//! fresh models: [`Delta::pack_body`] and [`Delta::unpack_body`].
//! 1. `n_merges`, `n_splits` (one model for both).
//! 2. Merges, then splits, each sorted by level and then by Morton (Z-order) code within the level,
//!    so that parents come before children and nearby nodes have nearby codes. Each node is its
//!    level step from the previous node, then its position (a step model and a position model
//!    for the merges, another two for the splits). A split's position is its Morton code: if the
//!    level is unchanged, as the gap to the previous code minus one, else as is. A merge's is its
//!    rank among the receiver's interior nodes of its level after the previous merge of that
//!    level (protocol 5, [`merge_positions`]): the receiver's cut before the delta, which the
//!    sender counts on its cut after it ([`Known`]).
//! 3. Per split, in the same order: its three details as residuals against a prediction from
//!    its parent's details (protocol 5, [`predict`]: half the parent's slopes, a quarter of its
//!    twist), each in the model of its level and component, then the error code's residual
//!    against a prediction both ends compute from the details alone (the code of the largest
//!    child-to-parent offset, which the node's error can never be below), in one model. A
//!    parent that splits in the same body is read from it; any other is the receiver's, so
//!    packing and unpacking take a [`Parents`]: the client's mirror, the server's store.
//!
//! A delta with neither merges nor splits has the empty body (no bytes).
//!
//! The models learn each context's statistics as the session goes, so a body costs close to the
//! entropy of its symbols in these contexts (`docs/vertex-stream.md`, "Bytes per split"). Decoding
//! checks every index against the tree and every value against its range, refuses counts beyond the
//! tree's inner nodes, stops at the first entry that needs bytes the body does not have, and
//! reserves room for at most [`RESERVE_MAX`] entries up front: beyond that, lists grow only as
//! their entries decode.
//!
//! [`SplitEntropy`] measures what a run's split payloads carry under this coder's model, for the
//! benchmark (`docs/vertex-stream.md`, "Bytes per split").

mod entropy;
mod order;
mod predict;

pub use entropy::SplitEntropy;
use predict::Predictor;
pub use predict::{NoParents, Parents, quad_details};

use crate::bits::{unzigzag, zigzag};
use crate::cut::Cut;
use crate::haar::{error_code, inverse};
use crate::range::{Decoder, Encoder, Value};
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
    /// A merge's rank names no interior node of the receiver's cut.
    #[error("delta merges past the last interior node of level {0}")]
    NoSuchMerge(u8),
}

/// What a body is coded against besides the connection's models: where the receiver's parents
/// come from ([`Parents`]) and a cut. Merges travel as ranks among the receiver's interior
/// nodes (docs/protocol.md section 5.2), so the packer needs the cut *after* the delta (the
/// sender's: the cut before it is that one less the delta's splits plus its merges) and the
/// unpacker the cut *before* it (the receiver's mirror).
#[derive(Clone, Copy)]
pub struct Known<'a> {
    /// The details of split nodes' parents that are not in the body.
    pub parents: &'a dyn Parents,
    /// The cut after the delta (packing) or before it (unpacking).
    pub cut: &'a Cut,
}

impl<'a> Known<'a> {
    /// What a client knows before applying a delta: its mirror.
    pub fn mirror(mirror: &'a crate::mirror::Mirror) -> Known<'a> {
        Known {
            parents: mirror,
            cut: mirror.cut(),
        }
    }
}

/// The error code both ends predict from a split's details, in z quanta of `quantum` metres.
pub fn predicted_code(details: [i32; 3], quantum: f32) -> u8 {
    let offsets = inverse(0, details);
    let max = offsets.iter().map(|v| v.unsigned_abs()).max().unwrap_or(0);
    error_code(max as f32 * quantum)
}

impl Delta {
    /// Puts merges and splits in wire order: by level, then Morton code (parents before children).
    /// Each node's key is computed once, and sorted by a radix sort (`delta/order.rs`).
    pub fn canonicalize(&mut self) {
        order::sort_by_wire_key(&mut self.merges, |&n| n);
        order::sort_by_wire_key(&mut self.splits, |s| s.node);
    }

    /// Whether the delta changes nothing.
    pub fn is_empty(&self) -> bool {
        self.merges.is_empty() && self.splits.is_empty()
    }

    /// Encodes merges and splits into a body with fresh models (a one-shot delta). `quantum` is
    /// the terrain's z quantum; `known` holds the parents and the cut after the delta
    /// ([`Known`]).
    pub fn pack_body(&self, shape: &TreeShape, quantum: f32, known: Known<'_>) -> Vec<u8> {
        self.pack_body_in(shape, &mut BodyModels::new(), quantum, known)
    }

    /// Encodes merges and splits into the compact body with a connection's `models`, which it
    /// adapts: the next body of the connection continues from them.
    pub fn pack_body_in(
        &self,
        shape: &TreeShape,
        models: &mut BodyModels,
        quantum: f32,
        known: Known<'_>,
    ) -> Vec<u8> {
        if self.is_empty() {
            return Vec::new();
        }
        let mut merges: Vec<(u8, u64)> =
            self.merges.iter().map(|&n| (n.level, morton(n))).collect();
        merges.sort_unstable();
        let mut splits: Vec<(u8, u64, &Split)> = self
            .splits
            .iter()
            .map(|s| (s.node.level, morton(s.node), s))
            .collect();
        splits.sort_unstable_by_key(|&(l, m, _)| (l, m));
        let mut e = Encoder::new();
        e.value(&mut models.counts, merges.len() as u64);
        e.value(&mut models.counts, splits.len() as u64);
        for (step, v) in merge_positions(&merges, &splits, known.cut) {
            e.value(&mut models.merge_step, step as u64);
            e.value(&mut models.merge_pos, v);
        }
        for (step, v) in positions(splits.iter().map(|&(l, m, _)| (l, m))) {
            e.value(&mut models.split_step, step as u64);
            e.value(&mut models.split_pos, v);
        }
        let mut predictor = Predictor::new(known.parents);
        for (i, &(level, _, s)) in splits.iter().enumerate() {
            let residuals = predictor.residuals(shape, &splits, i);
            for (r, model) in residuals.into_iter().zip(models.details(level)) {
                e.value(model, r);
            }
            let residual = s.err_code as i64 - predicted_code(s.details, quantum) as i64;
            e.value(&mut models.residual, zigzag(residual));
        }
        e.finish()
    }

    /// Decodes a body written by [`Delta::pack_body`] for the same terrain, against what the
    /// receiver holds before the delta (`known`: its parents and its cut, [`Known::mirror`]).
    pub fn unpack_body(
        shape: &TreeShape,
        quantum: f32,
        seq: u64,
        digest: u64,
        body: &[u8],
        known: Known<'_>,
    ) -> Result<Delta, BodyError> {
        Self::unpack_body_in(
            shape,
            quantum,
            seq,
            digest,
            body,
            &mut BodyModels::new(),
            known,
        )
    }

    /// Decodes the next body of a connection, written by [`Delta::pack_body_in`], with the
    /// connection's `models`, which it adapts as the encoder did. After an error the models are
    /// spoilt, as the cut is: the connection must end.
    pub fn unpack_body_in(
        shape: &TreeShape,
        quantum: f32,
        seq: u64,
        digest: u64,
        body: &[u8],
        models: &mut BodyModels,
        known: Known<'_>,
    ) -> Result<Delta, BodyError> {
        if body.is_empty() {
            return Ok(Delta {
                seq,
                digest,
                ..Delta::default()
            });
        }
        let mut r = Decoder::new(body);
        let n_merges = r.value(&mut models.counts).ok_or(BodyError::Malformed)?;
        let n_splits = r.value(&mut models.counts).ok_or(BodyError::Malformed)?;
        // Each list names distinct inner nodes: a count beyond the tree's inner nodes is a lie.
        let inner = shape.level_offset(shape.depth());
        if n_merges > inner || n_splits > inner || r.overrun() {
            return Err(BodyError::Malformed);
        }
        let mut delta = Delta {
            seq,
            digest,
            merges: Vec::with_capacity(reserve(n_merges, body.len())),
            splits: Vec::with_capacity(reserve(n_splits, body.len())),
        };
        let mut prev = None;
        for _ in 0..n_merges {
            let node = next_merge(shape, &mut r, models, known.cut, &mut prev)?;
            delta.merges.push(node);
        }
        // The splits' nodes and their wire keys (as decoded: no Morton code computed).
        let mut nodes = Vec::with_capacity(reserve(n_splits, body.len()));
        let mut prev = None;
        for _ in 0..n_splits {
            nodes.push(next_node(
                shape,
                &mut r,
                &mut models.split_step,
                &mut models.split_pos,
                &mut prev,
            )?);
        }
        let mut predictor = Predictor::new(known.parents);
        for (i, &(node, key)) in nodes.iter().enumerate() {
            let predicted = predictor.predict(
                shape,
                i,
                (node, key),
                |k| nodes[k].1,
                |k| delta.splits[k].details,
            );
            let mut details = [0i32; 3];
            for ((d, p), model) in details
                .iter_mut()
                .zip(predicted)
                .zip(models.details(node.level))
            {
                let v = r.value(model).ok_or(BodyError::Malformed)?;
                let residual =
                    i32::try_from(unzigzag(v)).map_err(|_| BodyError::OutOfRange("detail"))?;
                *d = p.wrapping_add(residual);
            }
            let res = r.value(&mut models.residual).ok_or(BodyError::Malformed)?;
            if r.overrun() {
                return Err(BodyError::Malformed);
            }
            let code = predicted_code(details, quantum) as i64 + unzigzag(res);
            let err_code = u8::try_from(code).map_err(|_| BodyError::OutOfRange("error code"))?;
            delta.splits.push(Split {
                node,
                err_code,
                details,
            });
        }
        // The stream must end where the encoder's did: nothing missing, nothing after.
        if !r.finished() {
            return Err(BodyError::Malformed);
        }
        Ok(delta)
    }
}

/// The adaptive models of a connection's delta bodies (docs/protocol.md section 5.2): fresh at
/// its first delta, then carried from each body to the next. About 27 KB, all in place: a
/// one-shot body, even one of garbage, allocates nothing but its entries.
#[derive(Clone, Debug)]
pub struct BodyModels {
    /// `n_merges` and `n_splits`.
    counts: Value,
    merge_step: Value,
    merge_pos: Value,
    split_step: Value,
    split_pos: Value,
    /// The details, per split level and component (`dv`, `dh`, `dd`).
    details: [[Value; 3]; MAX_INNER_LEVELS],
    /// The error codes' residuals: one model for all levels.
    residual: Value,
}

/// Inner levels a tree can have (levels `0 .. MAX_DEPTH`).
const MAX_INNER_LEVELS: usize = crate::tree::MAX_DEPTH as usize;

impl Default for BodyModels {
    fn default() -> BodyModels {
        BodyModels::new()
    }
}

impl BodyModels {
    /// Fresh models, as at a connection's first delta.
    pub fn new() -> BodyModels {
        BodyModels {
            counts: Value::default(),
            merge_step: Value::default(),
            merge_pos: Value::default(),
            split_step: Value::default(),
            split_pos: Value::default(),
            details: std::array::from_fn(|_| std::array::from_fn(|_| Value::default())),
            residual: Value::default(),
        }
    }

    /// The three detail models of splits at `level` (an inner level of the tree).
    fn details(&mut self, level: u8) -> &mut [Value; 3] {
        &mut self.details[level as usize]
    }
}

/// The most entries [`Delta::unpack_body`] reserves room for before decoding them. A count that
/// passes the bit check can still claim one entry per bit of the body, and reserving for all of
/// them made a 1 MiB body of garbage take 335 MB before it was refused.
pub const RESERVE_MAX: u64 = 1 << 12;

/// Room to reserve for a list whose count a body of `body_bytes` claims: no more than
/// [`RESERVE_MAX`], nor than one entry per bit of the body (a list that really holds more grows
/// as it decodes). Without the second bound, 8 bytes of garbage that claimed 154 splits
/// reserved 4,312 bytes (`codec_limits`' property test found it).
fn reserve(n: u64, body_bytes: usize) -> usize {
    n.min(RESERVE_MAX).min(8 * body_bytes as u64) as usize
}

/// A node's place in wire order as one integer: its level, then its Morton code within the level
/// (codes take at most 30 bits).
pub fn wire_key(n: NodeId) -> u64 {
    key_of(n.level, morton(n))
}

/// Where a wire key's level starts: below it, the Morton code.
pub(crate) const KEY_LEVEL_SHIFT: u32 = 58;

/// The wire key of the node of `level` whose Morton code is `code`.
pub(crate) fn key_of(level: u8, code: u64) -> u64 {
    (level as u64) << KEY_LEVEL_SHIFT | code
}

/// The Morton (Z-order) code of a node within its level: x and y bits interleaved.
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

/// The even bits of `v`, packed: x from a Morton code (`compact(code >> 1)` is y).
pub(crate) fn compact(v: u64) -> u32 {
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

/// The merges' level steps and position values (docs/protocol.md section 5.2): a merge's value
/// is the number of the receiver's interior nodes of its level between the previous merge of
/// that level (or the level's start) and itself. The receiver's cut before the delta is `after`
/// less the delta's splits plus its merges, and no merge lies between two consecutive ones, so
/// the count is `after`'s less the splits of that level in the range. `merges` and `splits` are
/// in wire order.
pub(crate) fn merge_positions(
    merges: &[(u8, u64)],
    splits: &[(u8, u64, &Split)],
    after: &Cut,
) -> Vec<(u8, u64)> {
    let mut prev: Option<(u8, u64)> = None;
    let mut j = 0;
    merges
        .iter()
        .map(|&(l, m)| {
            let lo = match prev {
                Some((pl, pm)) if pl == l => pm + 1,
                _ => 0,
            };
            while j < splits.len() && (splits[j].0, splits[j].1) < (l, lo) {
                j += 1;
            }
            let mut split_here = 0;
            while j < splits.len() && (splits[j].0, splits[j].1) < (l, m) {
                split_here += 1;
                j += 1;
            }
            let rank = after
                .interior_count_morton(l, lo, m)
                .saturating_sub(split_here);
            let step = match prev {
                Some((pl, _)) => l - pl,
                None => l,
            };
            prev = Some((l, m));
            (step, rank)
        })
        .collect()
}

/// The next merge of a body: its level step and its rank among `before`'s interior nodes of
/// its level after the previous merge of that level (see [`merge_positions`]).
fn next_merge(
    shape: &TreeShape,
    r: &mut Decoder<'_>,
    models: &mut BodyModels,
    before: &Cut,
    prev: &mut Option<(u8, u64)>,
) -> Result<NodeId, BodyError> {
    let step = r
        .value(&mut models.merge_step)
        .ok_or(BodyError::Malformed)?;
    let rank = r.value(&mut models.merge_pos).ok_or(BodyError::Malformed)?;
    if r.overrun() {
        return Err(BodyError::Malformed);
    }
    let (level, from) = match *prev {
        Some((pl, pm)) if step == 0 => (u64::from(pl), pm + 1),
        Some((pl, _)) => (u64::from(pl) + step, 0),
        None => (step, 0),
    };
    if level >= u64::from(shape.depth()) {
        return Err(BodyError::Malformed);
    }
    let level = level as u8;
    let code = before
        .interior_select_morton(level, from, rank)
        .ok_or(BodyError::NoSuchMerge(level))?;
    *prev = Some((level, code));
    Ok(NodeId {
        level,
        x: compact(code),
        y: compact(code >> 1),
    })
}

fn next_node(
    shape: &TreeShape,
    r: &mut Decoder<'_>,
    step_model: &mut Value,
    pos_model: &mut Value,
    prev: &mut Option<(u8, u64)>,
) -> Result<(NodeId, u64), BodyError> {
    let step = r.value(step_model).ok_or(BodyError::Malformed)?;
    let v = r.value(pos_model).ok_or(BodyError::Malformed)?;
    if r.overrun() {
        return Err(BodyError::Malformed);
    }
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
    Ok((node, key_of(node.level, code)))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    /// What a sender knows with no parents beyond the body: the cut alone.
    pub(crate) fn alone(cut: &Cut) -> Known<'_> {
        Known {
            parents: &NoParents,
            cut,
        }
    }

    /// The cut with every inner node interior (the full-resolution mesh).
    pub(crate) fn full_cut(shape: &TreeShape) -> Cut {
        let mut cut = Cut::root(shape);
        let mut stack = vec![NodeId::ROOT];
        while let Some(n) = stack.pop() {
            if !shape.is_leaf(n) {
                cut.split(shape, n).unwrap();
                stack.extend(shape.children(n).map(|(_, c)| c));
            }
        }
        cut
    }

    /// A delta in wire order from `shadow`'s cut, as deltas go: a few merges of nodes whose
    /// children are all active (and now and then the parent of one, when that leaves its
    /// children all active: a merge chain, as between distant cuts), then splits of active
    /// nodes that often go on down (all of a split node's children split too with probability
    /// `chain`, recursively, some of them otherwise), with details in -5000..5000; `shadow` is
    /// moved to the cut after it.
    pub(crate) fn random_delta(
        shape: &TreeShape,
        shadow: &mut Cut,
        rng: &mut crate::rng::Rng,
        chain: f64,
    ) -> Delta {
        let mergeable = |cut: &Cut, n: NodeId| {
            cut.is_interior(shape, n) && shape.children(n).all(|(_, c)| !cut.is_interior(shape, c))
        };
        let mut merges = Vec::new();
        let mut candidates: Vec<NodeId> = shadow
            .interior_indices()
            .filter_map(|i| shape.node(i))
            .filter(|&n| mergeable(shadow, n))
            .collect();
        candidates.sort_unstable_by_key(|&n| shape.index(n));
        for _ in 0..rng.below(5) {
            if candidates.is_empty() {
                break;
            }
            let n = candidates.swap_remove(rng.below(candidates.len()));
            shadow.merge(shape, n).unwrap();
            merges.push(n);
            if let Some(p) = n
                .parent()
                .filter(|&p| mergeable(shadow, p) && rng.below(3) == 0)
            {
                shadow.merge(shape, p).unwrap();
                merges.push(p);
                candidates.retain(|&c| c.parent() != Some(p));
            }
        }
        let mut splits = Vec::new();
        let mut active: Vec<NodeId> = shadow
            .active_nodes(shape)
            .into_iter()
            .filter(|&n| !shape.is_leaf(n) && !merges.contains(&n))
            .collect();
        let mut stack = Vec::new();
        for _ in 0..1 + rng.below(4) {
            if !active.is_empty() {
                stack.push(active.swap_remove(rng.below(active.len())));
            }
        }
        while let Some(n) = stack.pop() {
            if shape.is_leaf(n) {
                continue;
            }
            shadow.split(shape, n).unwrap();
            let detail = |r: &mut crate::rng::Rng| r.below(10_000) as i32 - 5000;
            splits.push(Split {
                node: n,
                err_code: rng.below(256) as u8,
                details: [detail(rng), detail(rng), detail(rng)],
            });
            let all = rng.unit() < chain;
            for (_, c) in shape.children(n) {
                if all || rng.below(4) == 0 {
                    stack.push(c);
                }
            }
        }
        let mut d = Delta {
            seq: 7,
            digest: shadow.digest(),
            merges,
            splits,
        };
        d.canonicalize();
        d
    }

    proptest! {
        /// One-shot bodies of valid deltas round-trip: packed against the cut after the delta,
        /// unpacked against the cut before it.
        #[test]
        fn body_round_trips(w in 2u32..300, h in 2u32..170, seed in any::<u64>(), chain in 0.0f64..0.8) {
            let shape = TreeShape::new(w, h).unwrap();
            let mut rng = crate::rng::Rng::new(seed);
            let mut cut = Cut::root(&shape);
            for _ in 0..6 {
                let before = cut.clone();
                let d = random_delta(&shape, &mut cut, &mut rng, chain);
                let body = d.pack_body(&shape, 0.25, alone(&cut));
                let back = Delta::unpack_body(&shape, 0.25, d.seq, d.digest, &body, alone(&before));
                prop_assert_eq!(back.unwrap(), d);
            }
        }

        /// A connection's bodies decode in order with the models carried over, an empty delta
        /// (empty body) among them leaving the models as they were; the client's mirror gives
        /// the parents.
        #[test]
        fn a_connection_of_bodies_round_trips(w in 2u32..300, h in 2u32..170, seed in any::<u64>(),
                                              empties in proptest::collection::vec(any::<bool>(), 1..8)) {
            let shape = TreeShape::new(w, h).unwrap();
            let geom = crate::terrain::TerrainGeometry::new(w, h, 1.0, 1.0, 0.25).unwrap();
            let mut rng = crate::rng::Rng::new(seed);
            let mut cut = Cut::root(&shape);
            let mut mirror = crate::mirror::Mirror::new(&geom, 0);
            let (mut server, mut client) = (BodyModels::new(), BodyModels::new());
            for empty in empties {
                let d = if empty {
                    Delta { seq: 7, digest: cut.digest(), ..Delta::default() }
                } else {
                    random_delta(&shape, &mut cut, &mut rng, 0.5)
                };
                let body = d.pack_body_in(&shape, &mut server, 0.25, Known { parents: &mirror, cut: &cut });
                prop_assert_eq!(body.is_empty(), d.is_empty());
                let back = Delta::unpack_body_in(&shape, 0.25, d.seq, d.digest, &body, &mut client,
                                                 Known::mirror(&mirror));
                prop_assert_eq!(back.as_ref(), Ok(&d));
                mirror.apply(&geom, &d, |_, _| {}).unwrap();
            }
        }

        #[test]
        fn random_bodies_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let shape = TreeShape::new(33, 20).unwrap();
            // Every inner node interior: merges of any rank select something.
            let full = full_cut(&shape);
            let _ = Delta::unpack_body(&shape, 0.25, 0, 0, &bytes, alone(&full));
            let _ = Delta::unpack_body(&shape, 0.25, 0, 0, &bytes, alone(&Cut::root(&shape)));
        }
    }

    /// A merge is sent as its rank among the receiver's interior nodes of its level, and one
    /// past the last is refused.
    #[test]
    fn merges_are_ranks_in_the_receivers_cut() {
        let shape = TreeShape::new(33, 33).unwrap();
        let mut before = Cut::root(&shape);
        before.split(&shape, NodeId::ROOT).unwrap();
        for k in 0..4 {
            before.split(&shape, NodeId::ROOT.child(k)).unwrap();
        }
        // Merge the last level-1 node: rank 3 among the four.
        let mut after = before.clone();
        after.merge(&shape, NodeId::ROOT.child(3)).unwrap();
        let d = Delta {
            merges: vec![NodeId::ROOT.child(3)],
            ..Delta::default()
        };
        let (mut e, mut counts, mut step, mut pos) = (
            Encoder::new(),
            Value::default(),
            Value::default(),
            Value::default(),
        );
        e.value(&mut counts, 1);
        e.value(&mut counts, 0);
        e.value(&mut step, 1);
        e.value(&mut pos, 3);
        assert_eq!(d.pack_body(&shape, 0.25, alone(&after)), e.finish());
        let body = d.pack_body(&shape, 0.25, alone(&after));
        assert_eq!(
            Delta::unpack_body(&shape, 0.25, 0, 0, &body, alone(&before)),
            Ok(d)
        );
        // Against a cut with three interior level-1 nodes, rank 3 names none.
        let mut three = before.clone();
        three.merge(&shape, NodeId::ROOT.child(0)).unwrap();
        assert_eq!(
            Delta::unpack_body(&shape, 0.25, 0, 0, &body, alone(&three)),
            Err(BodyError::NoSuchMerge(1))
        );
    }

    /// A session keeps its models for the connection's life: they must stay small (docs say
    /// 27 KB; session memory is counted per active node).
    #[test]
    fn a_connection_s_models_stay_small() {
        assert!(
            size_of::<BodyModels>() <= 27 * 1024,
            "{}",
            size_of::<BodyModels>()
        );
    }

    #[test]
    fn lying_counts_are_refused() {
        let shape = TreeShape::new(33, 20).unwrap();
        let mut e = Encoder::new();
        let mut counts = Value::default();
        e.value(&mut counts, shape.level_offset(shape.depth()) + 1);
        e.value(&mut counts, 0);
        let body = e.finish();
        assert_eq!(
            Delta::unpack_body(&shape, 0.25, 0, 0, &body, alone(&Cut::root(&shape))),
            Err(BodyError::Malformed)
        );
    }

    /// Hostile input: a count that the body could hold, in a body of garbage, reserved room for
    /// every claimed entry (a 1 MiB body, about 335 MB) before its second entry failed to decode.
    #[test]
    fn lying_counts_reserve_little() {
        assert_eq!(reserve(u64::MAX, 1 << 20), RESERVE_MAX as usize);
        assert_eq!(reserve(17, 1 << 20), 17);
        assert_eq!(reserve(154, 8), 64);
        let shape = TreeShape::new(8193, 8193).unwrap();
        let mut e = Encoder::new();
        let mut counts = Value::default();
        e.value(&mut counts, 0);
        e.value(&mut counts, (8 << 20) - 1000);
        // The root, then the node after it on level 0, which does not exist.
        let (mut step, mut pos) = (Value::default(), Value::default());
        e.value(&mut step, 0);
        e.value(&mut pos, 0);
        e.value(&mut step, 0);
        e.value(&mut pos, 0);
        let mut body = e.finish();
        body.resize(1 << 20, 0xA5);
        assert_eq!(
            Delta::unpack_body(&shape, 0.25, 0, 0, &body, alone(&Cut::root(&shape))),
            Err(BodyError::UnknownNode(NodeId {
                level: 0,
                x: 1,
                y: 0
            }))
        );
    }

    #[test]
    fn a_body_cut_short_is_refused() {
        let shape = TreeShape::new(65, 65).unwrap();
        let d = Delta {
            splits: (0..4)
                .map(|k| Split {
                    node: NodeId::ROOT.child(k),
                    err_code: 9,
                    details: [k as i32 * 100, -7, 300],
                })
                .collect(),
            ..Delta::default()
        };
        let body = d.pack_body(&shape, 0.1, alone(&Cut::root(&shape)));
        // (No bytes at all is the empty delta.)
        for n in 1..body.len() {
            assert_eq!(
                Delta::unpack_body(&shape, 0.1, 0, 0, &body[..n], alone(&Cut::root(&shape))),
                Err(BodyError::Malformed),
                "{n} of {} bytes",
                body.len()
            );
        }
    }

    #[test]
    fn nothing_may_follow_the_stream() {
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
        let body = d.pack_body(&shape, 0.1, alone(&Cut::root(&shape)));
        assert_eq!(
            Delta::unpack_body(&shape, 0.1, 1, 2, &body, alone(&Cut::root(&shape))).unwrap(),
            d
        );
        let mut longer = body.clone();
        longer.push(0);
        assert_eq!(
            Delta::unpack_body(&shape, 0.1, 1, 2, &longer, alone(&Cut::root(&shape))),
            Err(BodyError::Malformed)
        );
        let mut dirty = body.clone();
        let last = dirty.len() - 1;
        dirty[last] ^= 1;
        // The flush's bytes are part of the stream: a changed one changes or breaks the body.
        assert_ne!(
            Delta::unpack_body(&shape, 0.1, 1, 2, &dirty, alone(&Cut::root(&shape))),
            Ok(d)
        );
    }
}

/// The worked examples of `docs/protocol.md` section 14 ("Delta 1", "Delta 2" and "Other
/// bodies"), checked against the text, so that the document cannot drift from the code.
#[cfg(test)]
mod doc_examples {
    use super::*;

    fn hex(bytes: &[u8]) -> String {
        bytes
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect::<Vec<_>>()
            .join(" ")
    }

    fn node(level: u8, x: u32, y: u32) -> NodeId {
        NodeId { level, x, y }
    }

    /// The models after packing `first` (against `after`) from fresh ones.
    fn one_then(shape: &TreeShape, first: &Delta, after: &Cut, q: f32) -> BodyModels {
        let mut m = BodyModels::new();
        first.pack_body_in(shape, &mut m, q, super::tests::alone(after));
        m
    }

    #[test]
    fn the_protocol_doc_bodies_are_what_the_code_sends() {
        let shape = TreeShape::new(5, 3).unwrap();
        let q = 0.5;
        let geom = crate::terrain::TerrainGeometry::new(5, 3, 1.0, 1.0, q).unwrap();
        let root = Cut::root(&shape);
        let mut cut = root.clone();
        cut.split(&shape, NodeId::ROOT).unwrap();
        let mut cut2 = cut.clone();
        cut2.split(&shape, node(1, 0, 0)).unwrap();
        cut2.split(&shape, node(1, 1, 0)).unwrap();
        let one = Delta {
            digest: cut.digest(),
            splits: vec![Split {
                node: NodeId::ROOT,
                err_code: 92,
                details: [0, 10, 0],
            }],
            ..Delta::default()
        };
        let two = Delta {
            splits: vec![
                Split {
                    node: node(1, 0, 0),
                    err_code: 88,
                    details: [2, 5, 2],
                },
                Split {
                    node: node(1, 1, 0),
                    err_code: 64,
                    details: [2, 0, 0],
                },
            ],
            ..Delta::default()
        };
        let back = Delta {
            merges: vec![NodeId::ROOT, node(1, 0, 0), node(1, 1, 0)],
            ..Delta::default()
        };
        assert_eq!(predicted_code([0, 10, 0], q), 89);
        assert_eq!(predicted_code([2, 5, 2], q), 86);
        assert_eq!(predicted_code([2, 0, 0], q), 64);
        let doc = include_str!("../../../docs/protocol.md");
        assert!(
            Delta::default()
                .pack_body(&shape, q, super::tests::alone(&root))
                .is_empty()
        );
        assert!(doc.contains("The empty delta has the empty body (no bytes)."));
        // Deltas 1 and 2 are one connection's (its models carry over, and delta 2's details are
        // predicted from the root's, which the client holds after delta 1: both ends read them
        // from the mirror here); the merge back is a one-shot delta (fresh models).
        let mut mirror = crate::mirror::Mirror::new(&geom, 0);
        let mut models = [BodyModels::new(), BodyModels::new()];
        let mut decoders = [BodyModels::new(), BodyModels::new()];
        for (name, d, m, after) in [
            ("delta 1", &one, 0, &cut),
            ("delta 2", &two, 0, &cut2),
            ("merge back", &back, 1, &root),
        ] {
            let known = Known {
                parents: &mirror,
                cut: after,
            };
            let body = d.pack_body_in(&shape, &mut models[m], q, known);
            let want = format!("=> body {}", hex(&body));
            assert!(doc.contains(&want), "{name}: the document lacks {want:?}");
            let mut d = d.clone();
            d.canonicalize();
            let back = Delta::unpack_body_in(
                &shape,
                q,
                0,
                d.digest,
                &body,
                &mut decoders[m],
                Known::mirror(&mirror),
            );
            assert_eq!(back.unwrap(), d);
            if name != "merge back" {
                d.digest = after.digest();
                mirror.apply(&geom, &d, |_, _| {}).unwrap();
            }
        }
        // The root's details predict delta 2's: [0 >> 1, 10 >> 1, 0 >> 2] = [0, 5, 0] for both
        // level-1 nodes, so the first one's dh is sent as 0.
        assert_eq!(mirror.details(NodeId::ROOT), Some([0, 10, 0]));
        // Delta 2 alone, from fresh models and with no parents known, is another body: the
        // models did carry over.
        let alone = super::tests::alone(&cut2);
        let carried = two.pack_body_in(&shape, &mut one_then(&shape, &one, &cut, q), q, alone);
        assert_ne!(two.pack_body(&shape, q, alone), carried);
        // And predicting from the root's details changed it too.
        let known = Known {
            parents: &mirror,
            cut: &cut2,
        };
        let predicted = two.pack_body_in(&shape, &mut one_then(&shape, &one, &cut, q), q, known);
        assert_ne!(carried, predicted);
    }
}
