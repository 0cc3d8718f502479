//! The bandwidth-budgeted update (DESIGN.md section 6, "Budget"): a delta carries the most
//! valuable splits first and stops at the budget, and the cut stays consistent.
//!
//! It is the paper's full top-down pass (paper 000, section 3.4; [`VertexEngine::update`]) with
//! its splits reordered:
//! 1. **Merges** are decided exactly as in the full pass (an interior node whose children are all
//!    active merges when its screen error is below `tau * merge_ratio`, one level per call). They
//!    are cheap on the wire and free the client's memory, so they are always applied.
//! 2. **Splits** come from a max-heap of the active inner nodes whose screen error exceeds tau.
//!    The heap pops the node that removes the most screen error per byte, splits it, and pushes its
//!    children that exceed tau, until the estimated body reaches the budget or the heap is empty.
//!
//! **Priority.** A split's value is its node's *excess* `e - tau`, not `e`: the budget's job is to
//! reach the cut that meets tau, so error under tau is worth nothing. The excess bounds what one
//! split takes off the cut's total violation, the sum of `max(0, e - tau)` over active nodes,
//! without evaluating the children first. A node barely over tau, which the next small camera
//! motion may settle either way, waits behind the large violations. The cost is an estimate of the
//! split's packed size (`split_bits`): a fixed allowance for its position, plus its three details
//! at their own best Exp-Golomb order, less the eighth that the body's adaptive range coder saves
//! on them, and its error residual.
//!
//! **Consistency.** A node enters the heap only once it is active, so a parent always splits
//! before its children and every prefix of the pop order is a valid cut. After packing, if the
//! real body exceeds the budget (the estimate is only that), the longest prefix that fits is found
//! by binary search and the rest of the splits are undone, children first. At least one split is
//! always kept when any is wanted, so that a tiny budget still makes progress.
//!
//! With an unlimited budget the delta is exactly [`VertexEngine::update`]'s. With a budget,
//! repeated calls for the same view reach the same cut: the deferred splits are all over tau and
//! never touch a merge's decision. Pure: no I/O, no async.

use super::{LodParams, VertexEngine};
use relief_proto::bits::{best_order, eg_len, zigzag};
use relief_proto::cut::Cut;
use relief_proto::delta::{BodyModels, Delta, Known, Split, predicted_code};
use relief_proto::tree::NodeId;
use relief_proto::view::ViewState;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Bits allowed for a split's position (level step and Morton gap), which depends on the other
/// splits of the delta. The range-coded body spends about 5 bits a split on positions over the
/// standard path; with this allowance and details at 7/8 of their Exp-Golomb length, budgeted
/// deltas of 2000 bytes fill 86 to 95 % of their budget in the tests (at 8 bits and the whole
/// length, made for the Exp-Golomb body of protocol 2, they filled 76 to 82 %).
const POSITION_BITS: u64 = 6;
/// Extra bits allowed for the first split of a level in the delta: its detail models start
/// fresh, so its first details cost more than the estimate.
const NEW_LEVEL_BITS: u64 = 4;

/// A budgeted update's result.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BudgetedDelta {
    /// The delta applied to the cut: the merges, then the splits that fit, canonicalized, with the
    /// cut's digest afterwards.
    pub delta: Delta,
    /// Whether the cut now is what the unbudgeted full pass would have produced for this view: no
    /// active node exceeds tau. When false, more deltas should follow without a new pose. (Later
    /// calls may still merge, one level per call, as the full pass's would.)
    pub complete: bool,
    /// Size of the delta's packed body ([`Delta::pack_body`]) in bytes, so that the caller can
    /// charge its budget without packing again.
    pub bytes: usize,
}

/// A node waiting in the heap.
struct Candidate {
    /// Excess screen error per estimated bit: the heap's key.
    priority: f32,
    /// Estimated packed bits of the split (without the level's order).
    bits: u64,
    /// What the client needs to split the node; also where the estimate comes from.
    split: Split,
}

impl Candidate {
    /// The node's level, row and column: ties go to the shallower node, then the lower one.
    fn key(&self) -> (u8, u32, u32) {
        (self.split.node.level, self.split.node.y, self.split.node.x)
    }
}

impl PartialEq for Candidate {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Candidate {}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> Ordering {
        self.priority
            .total_cmp(&other.priority)
            .then_with(|| other.key().cmp(&self.key()))
    }
}

/// Estimated bits of `s` in a packed body whose z quantum is `quantum` metres.
fn split_bits(s: &Split, quantum: f32) -> u64 {
    let details = s.details.map(|d| zigzag(d as i64));
    let k = best_order(details.iter().copied(), 15);
    let detail_bits: u64 = details.iter().map(|&v| eg_len(v, k)).sum();
    let residual = zigzag(s.err_code as i64 - predicted_code(s.details, quantum) as i64);
    POSITION_BITS + detail_bits * 7 / 8 + eg_len(residual, 0)
}

/// A split's priority: screen error over tau removed per estimated bit.
fn priority(e: f32, tau: f32, bits: u64) -> f32 {
    (e - tau) / bits.max(1) as f32
}

/// `node` as a heap entry if it is an inner node whose screen error exceeds tau.
fn candidate(
    engine: &VertexEngine<'_>,
    view: &ViewState,
    p: &LodParams,
    node: NodeId,
) -> Option<Candidate> {
    let geom = engine.geometry();
    if geom.shape.is_leaf(node) {
        return None;
    }
    let e = engine.screen_error(view, node);
    (e > p.tau).then(|| {
        let split = engine.split_payload(node);
        let bits = split_bits(&split, geom.z_quantum);
        Candidate {
            priority: priority(e, p.tau, bits),
            bits,
            split,
        }
    })
}

/// One update of `cut` for `view` whose packed body stays within `max_body_bytes`: the full
/// pass's merges, then the splits worth the most screen error per byte that fit. The body
/// exceeds the budget only when the merges and a single split do. `models` are the connection's
/// body models as they will pack this delta: sizes are measured with copies of them.
pub fn budgeted_update(
    engine: &VertexEngine<'_>,
    cut: &mut Cut,
    view: &ViewState,
    p: &LodParams,
    max_body_bytes: usize,
    models: &BodyModels,
    seq: u64,
) -> BudgetedDelta {
    let geom = engine.geometry();
    let shape = &geom.shape;
    let mut delta = Delta {
        seq,
        ..Delta::default()
    };
    // The full pass's walk: its merges, and the active nodes over tau as the heap's seeds.
    let mut heap = BinaryHeap::new();
    let mut stack = vec![NodeId::ROOT];
    while let Some(n) = stack.pop() {
        if cut.is_interior(shape, n) {
            let all_active = shape.children(n).all(|(_, c)| !cut.is_interior(shape, c));
            if all_active
                && engine.screen_error(view, n) < p.tau * p.merge_ratio
                && cut.merge(shape, n).is_ok()
            {
                delta.merges.push(n);
                continue;
            }
            stack.extend(shape.children(n).map(|(_, c)| c));
        } else if let Some(c) = candidate(engine, view, p, n) {
            heap.push(c);
        }
    }
    delta.canonicalize();

    // Greedy splits while the estimate fits; the first one regardless.
    let budget_bits = (max_body_bytes as u64).saturating_mul(8);
    // The cut holds the merges and no split yet: the cut after this delta.
    let known = Known {
        parents: engine,
        cut,
    };
    let mut bits = delta
        .pack_body_in(shape, &mut models.clone(), geom.z_quantum, known)
        .len() as u64
        * 8;
    let mut levels = 0u64;
    let mut taken: Vec<Split> = Vec::new();
    while let Some(top) = heap.peek() {
        let level = 1u64 << (top.split.node.level & 63);
        let new_level = if levels & level == 0 {
            NEW_LEVEL_BITS
        } else {
            0
        };
        let cost = top.bits + new_level;
        if !taken.is_empty() && bits.saturating_add(cost) > budget_bits {
            break;
        }
        let Some(c) = heap.pop() else { break };
        // The node is active (it is in the heap), so the split cannot fail.
        if cut.split(shape, c.split.node).is_err() {
            continue;
        }
        bits = bits.saturating_add(cost);
        levels |= level;
        heap.extend(
            shape
                .children(c.split.node)
                .filter_map(|(_, ch)| candidate(engine, view, p, ch)),
        );
        taken.push(c.split);
    }
    let mut complete = heap.is_empty();

    // The real size; past the budget, keep the longest prefix that fits (at least one split;
    // the body grows with the prefix, so a binary search finds it). A prefix's body is packed
    // against the cut after it (merges rank against it): the splits past the prefix are undone
    // for the measure, children first, and done again, parents first (`taken` is in the order
    // they were split).
    let packed = |delta: &mut Delta, cut: &mut Cut, taken: &[Split], k: usize| {
        for s in taken[k..].iter().rev() {
            let _ = cut.merge(shape, s.node);
        }
        delta.splits.clear();
        delta.splits.extend_from_slice(&taken[..k]);
        let known = Known {
            parents: engine,
            cut,
        };
        let n = delta
            .pack_body_in(shape, &mut models.clone(), geom.z_quantum, known)
            .len();
        for s in &taken[k..] {
            let _ = cut.split(shape, s.node);
        }
        n
    };
    let mut bytes = packed(&mut delta, cut, &taken, taken.len());
    if bytes > max_body_bytes && taken.len() > 1 {
        // Invariant: the prefix of `lo` splits is kept (it fits, or is the minimum of one);
        // the prefix of `hi` does not fit.
        let (mut lo, mut hi) = (1, taken.len());
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if packed(&mut delta, cut, &taken, mid) <= max_body_bytes {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        // Undo children before parents: a child was popped after its parent.
        for s in taken[lo..].iter().rev() {
            let _ = cut.merge(shape, s.node);
        }
        taken.truncate(lo);
        bytes = packed(&mut delta, cut, &taken, lo);
        complete = false;
    }
    delta.splits = taken;
    delta.canonicalize();
    delta.digest = cut.digest();
    BudgetedDelta {
        delta,
        complete,
        bytes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::vertex::UpdateStats;
    use crate::lod::vertex::tests::{camera, lens, pose, store};
    use crate::store::Store;
    use proptest::prelude::*;
    use relief_proto::mirror::Mirror;
    use relief_proto::msg::WireDelta;

    /// The unbudgeted full pass from `cut` for `view`, repeated until it changes nothing.
    fn settle(engine: &VertexEngine<'_>, mut cut: Cut, view: &ViewState, p: &LodParams) -> Cut {
        let mut st = UpdateStats::default();
        for seq in 0..100 {
            if engine.update(&mut cut, view, p, seq, &mut st).is_empty() {
                return cut;
            }
        }
        panic!("the full pass did not settle");
    }

    /// Budgeted calls for `view` until nothing changes, each checked: the real body size, the
    /// budget, and the mirror's digest after the wire round trip. Returns the cut and the count
    /// of incomplete calls.
    fn drain(
        engine: &VertexEngine<'_>,
        s: &Store,
        mut cut: Cut,
        view: &ViewState,
        p: &LodParams,
        budget: usize,
    ) -> (Cut, usize) {
        let geom = engine.geometry();
        let mut mirror = Mirror::new(geom, s.root_z());
        mirror
            .apply(geom, &engine.full_delta(&cut, 0), |_, _| {})
            .unwrap();
        let (mut incomplete, mut was_complete) = (0, false);
        let (mut server, mut client) = (BodyModels::new(), BodyModels::new());
        for seq in 1..20_000 {
            let b = budgeted_update(engine, &mut cut, view, p, budget, &server, seq);
            let known = Known {
                parents: engine,
                cut: &cut,
            };
            let wire =
                WireDelta::pack_in(&b.delta, &geom.shape, &mut server, geom.z_quantum, known);
            assert_eq!(wire.body.len(), b.bytes);
            assert!(
                b.bytes <= budget || b.delta.splits.len() <= 1,
                "{} > {budget}",
                b.bytes
            );
            let back = wire
                .unpack_in(
                    &geom.shape,
                    geom.z_quantum,
                    &mut client,
                    Known::mirror(&mirror),
                )
                .unwrap();
            mirror.apply(geom, &back, |_, _| {}).unwrap();
            assert_eq!(mirror.cut().digest(), cut.digest());
            assert!(!was_complete || b.complete, "complete, then not");
            was_complete = b.complete;
            incomplete += usize::from(!b.complete);
            if b.delta.is_empty() {
                assert!(b.complete);
                return (cut, incomplete);
            }
        }
        panic!("budgeted updates did not converge");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]

        #[test]
        fn unlimited_budget_is_the_full_pass(w in 5u32..90, h in 5u32..90, seed in any::<u64>(),
                                             tau in 0.5f32..4.0,
                                             poses in proptest::collection::vec(pose(), 1..8)) {
            let dir = tempfile::tempdir().unwrap();
            let s = store(dir.path(), w, h, seed);
            let engine = VertexEngine::new(&s);
            let p = LodParams { tau, ..LodParams::default() };
            let mut st = UpdateStats::default();
            let v0 = ViewState::new(&camera(w, h, poses[0]), &lens());
            let mut full = engine.initial_cut(&v0, &p, &mut st);
            let mut budgeted = full.clone();
            let mut models = BodyModels::new();
            for (i, t) in poses.iter().enumerate() {
                let view = ViewState::new(&camera(w, h, *t), &lens());
                let d = engine.update(&mut full, &view, &p, i as u64, &mut st);
                let b = budgeted_update(&engine, &mut budgeted, &view, &p, usize::MAX, &models,
                                        i as u64);
                prop_assert!(b.complete);
                let geom = engine.geometry();
                let known = Known { parents: &engine, cut: &full };
                prop_assert_eq!(b.bytes, d.pack_body_in(&geom.shape, &mut models, geom.z_quantum, known).len());
                prop_assert_eq!(b.delta, d);
            }
        }

        #[test]
        fn small_budgets_converge_to_the_full_pass(w in 20u32..90, h in 20u32..90,
                                                   seed in any::<u64>(), a in pose(), b in pose(),
                                                   budget in 1usize..300) {
            let dir = tempfile::tempdir().unwrap();
            let s = store(dir.path(), w, h, seed);
            let engine = VertexEngine::new(&s);
            let p = LodParams::default();
            let start = engine.initial_cut(
                &ViewState::new(&camera(w, h, a), &lens()), &p, &mut UpdateStats::default());
            let view = ViewState::new(&camera(w, h, b), &lens());
            let (cut, _) = drain(&engine, &s, start.clone(), &view, &p, budget);
            prop_assert_eq!(cut.digest(), settle(&engine, start, &view, &p).digest());
        }

        #[test]
        fn splits_taken_outrank_splits_deferred(w in 20u32..90, h in 20u32..90,
                                                seed in any::<u64>(), a in pose(), b in pose(),
                                                budget in 1usize..200) {
            let dir = tempfile::tempdir().unwrap();
            let s = store(dir.path(), w, h, seed);
            let engine = VertexEngine::new(&s);
            let shape = &engine.geometry().shape;
            let p = LodParams::default();
            let before = engine.initial_cut(
                &ViewState::new(&camera(w, h, a), &lens()), &p, &mut UpdateStats::default());
            let view = ViewState::new(&camera(w, h, b), &lens());
            let prio = |n: NodeId| {
                candidate(&engine, &view, &p, n).map(|c| c.priority)
            };
            let mut cut = before;
            for seq in 1..4 {
                let before = cut.clone();
                let r = budgeted_update(&engine, &mut cut, &view, &p, budget, &BodyModels::new(), seq);
                // Nodes in the heap from the start: those active before the call. Each taken one
                // was popped while every deferred one waited in the heap.
                let taken = r.delta.splits.iter()
                    .filter(|s| before.is_active(shape, s.node))
                    .filter_map(|s| prio(s.node))
                    .fold(f32::INFINITY, f32::min);
                let deferred = cut.active_nodes(shape).into_iter()
                    .filter(|&n| before.is_active(shape, n))
                    .filter_map(prio)
                    .fold(f32::NEG_INFINITY, f32::max);
                prop_assert!(taken >= deferred, "took {} but deferred {}", taken, deferred);
                let over_tau = cut.active_nodes(shape).into_iter().any(|n| prio(n).is_some());
                prop_assert_eq!(r.complete, !over_tau);
            }
        }
    }

    #[test]
    fn a_tiny_budget_still_progresses_one_split_at_a_time() {
        let (w, h) = (65, 65);
        let dir = tempfile::tempdir().unwrap();
        let s = store(dir.path(), w, h, 9);
        let engine = VertexEngine::new(&s);
        let p = LodParams::default();
        let view = ViewState::new(&camera(w, h, (0.5, 0.2, 0.05, 0.25, 0.3)), &lens());
        let root = Cut::root(&engine.geometry().shape);
        let target = settle(&engine, root.clone(), &view, &p);
        let mut cut = root.clone();
        let first = budgeted_update(&engine, &mut cut, &view, &p, 0, &BodyModels::new(), 1);
        assert_eq!(first.delta.splits.len(), 1);
        assert_eq!(first.delta.splits[0].node, NodeId::ROOT);
        assert!(!first.complete);
        let (cut, incomplete) = drain(&engine, &s, root, &view, &p, 0);
        assert_eq!(cut.digest(), target.digest());
        // One split per call: as many incomplete calls as splits, but the last.
        assert_eq!(incomplete + 1, target.interior_count());
    }

    #[test]
    fn budgeted_deltas_fill_most_of_their_budget() {
        let (w, h) = (300, 260);
        let dir = tempfile::tempdir().unwrap();
        let s = store(dir.path(), w, h, 6);
        let engine = VertexEngine::new(&s);
        let p = LodParams::default();
        let poses = [(0.3, 0.2, 0.1, 0.15, 0.2), (0.7, 0.6, 0.0, 0.6, 0.1)];
        for (t, budget) in poses.into_iter().zip([100, 2000]) {
            let view = ViewState::new(&camera(w, h, t), &lens());
            let mut cut = Cut::root(&engine.geometry().shape);
            let mut models = BodyModels::new();
            for seq in 0..4 {
                let b = budgeted_update(&engine, &mut cut, &view, &p, budget, &models, seq);
                let body = b.delta.pack_body_in(
                    &engine.geometry().shape,
                    &mut models,
                    engine.geometry().z_quantum,
                    Known {
                        parents: &engine,
                        cut: &cut,
                    },
                );
                assert_eq!(body.len(), b.bytes);
                assert!(!b.complete);
                assert!(
                    b.bytes <= budget && b.bytes * 4 >= budget * 3,
                    "{} B of {budget}",
                    b.bytes
                );
            }
        }
    }
}
