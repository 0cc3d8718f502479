//! One session's cut with event-driven updates: only the nodes whose decision can have changed
//! since they were last examined are examined again.
//!
//! The paper's top-down pass (paper 000, section 3.4; [`VertexEngine::update`]) touches every
//! interior and active node on every update. This session produces exactly the same deltas, but
//! it groups the checks by interior node: the group of an interior node `P` is the split check of
//! each of its active children and, when all of them are active, `P`'s own merge check. After a
//! group is examined, the engine computes a *slack*: how far the camera-relative position of `P`'s
//! box may move before any of those decisions can flip. The bounds are the screen-error formula's
//! own terms ([`BoxView`]) taken at their worst over that displacement: the nearest depth shrinks
//! or grows by at most the displacement, the horizontal reach likewise, and the frustum test's
//! margin likewise. Camera translation moves a box by at most the eye's travel; camera rotation
//! by angle `a` moves a point at distance `D` by at most `2 D sin(a / 2)`. So the group is filed
//! in the band of its distance, and each band keeps an odometer that advances by the eye's travel
//! plus the band's distance times that chord; a group is due when its band's odometer passes its
//! key.
//!
//! Due groups are examined as they come out of the schedule, in no order of depth. The full pass
//! examines parents first, so a node whose child merged in this update may not merge before the
//! next one: such nodes are *blocked* for the rest of the update (their split checks still run)
//! and filed for the next update (coarsening moves one level per update). Splitting a child
//! examines the child's own new group at once (refinement goes as deep as the pose needs).
//!
//! The schedule ([`super::schedule`]) keeps one entry per interior node whose group checks
//! anything, in flat per-band buckets; an interior node whose children are all interior checks
//! nothing and is filed nowhere until a child merges. State per session: the cut's interior
//! bitset with a 4-bit generation per interior node, and the schedule's entries (4 bytes each).
//! Due groups are examined band by band as they come out of the wheels (no sort).

use super::schedule::{Schedule, node_index};
use super::{LodParams, UpdateStats, VertexEngine};
use relief_proto::cut::Cut;
use relief_proto::delta::Delta;
use relief_proto::tree::NodeId;
use relief_proto::view::{BoxView, ViewState};
use rustc_hash::FxHashSet;

/// Safety factor on every slack, against rounding in the bounds.
const SLACK_SAFETY: f64 = 0.98;

/// A session's cut plus the schedule of its next checks.
pub struct VertexSession {
    /// The cut; each interior node's tag is its schedule generation.
    cut: Cut,
    /// When each group is due.
    schedule: Schedule,
    /// Due entries of the band being processed, reused across updates.
    due: Vec<u32>,
    /// Interior nodes a child of which merged in the update under way (packed): they may not
    /// merge before the next update.
    blocked: FxHashSet<u32>,
    /// Splits stop once the cut holds this many interior nodes: a guard on server memory
    /// against a client asking for more detail than the server will hold (see
    /// [`VertexSession::set_max_interior`]).
    max_interior: usize,
    /// The cut a session continues from, until its first update examines every group of it.
    /// Scheduling each of its groups instead would cost a 4-byte entry per interior node:
    /// 32 times the snapshot a resuming client sends, where this copy costs under one byte.
    resumed: Option<Cut>,
}

impl VertexSession {
    /// A session whose initial cut is computed for `view` (all groups due at the first update).
    pub fn new(engine: &VertexEngine<'_>, view: &ViewState, p: &LodParams) -> VertexSession {
        let cut = engine.initial_cut(view, p, &mut UpdateStats::default());
        VertexSession::from_cut(engine, &cut)
    }

    /// A session continuing from `cut` (all groups due at the first update).
    pub fn from_cut(engine: &VertexEngine<'_>, cut: &Cut) -> VertexSession {
        let shape = &engine.geometry().shape;
        VertexSession {
            cut: cut.tagged(shape),
            schedule: Schedule::new(shape.depth()),
            due: Vec::new(),
            blocked: FxHashSet::default(),
            max_interior: usize::MAX,
            resumed: (cut.interior_count() > 0).then(|| cut.clone()),
        }
    }

    /// The current cut.
    pub fn cut(&self) -> Cut {
        self.cut.clone()
    }

    /// The current cut's digest.
    pub fn digest(&self) -> u64 {
        self.cut.digest()
    }

    /// Caps the cut at `max` interior nodes: past it the session splits nothing more, so its
    /// deltas stop matching the full pass; [`VertexSession::at_limit`] tells the caller.
    pub fn set_max_interior(&mut self, max: usize) {
        self.max_interior = max;
    }

    /// Whether the cut has reached its cap of interior nodes.
    pub fn at_limit(&self) -> bool {
        self.cut.interior_count() >= self.max_interior
    }

    /// Number of active nodes.
    pub fn active_count(&self) -> u64 {
        self.cut.active_count()
    }

    /// Bytes of memory the session's state holds.
    pub fn memory_bytes(&self) -> usize {
        self.cut.memory_bytes()
            + self.resumed.as_ref().map_or(0, Cut::memory_bytes)
            + self.schedule.memory_bytes()
            + self.due.capacity() * 4
            + self.blocked.capacity() * 5
            + std::mem::size_of::<Self>()
    }

    /// A new generation for interior node `node`: its older entries are stale from now on.
    fn next_generation(&mut self, node: NodeId) -> u8 {
        self.cut.bump_tag(node)
    }

    /// One update for `view`: the same delta as the paper's full top-down pass.
    pub fn update(
        &mut self,
        engine: &VertexEngine<'_>,
        view: &ViewState,
        p: &LodParams,
        seq: u64,
        stats: &mut UpdateStats,
    ) -> Delta {
        let shape = &engine.geometry().shape;
        self.schedule.advance(view);
        let mut delta = Delta {
            seq,
            ..Delta::default()
        };
        if !self.cut.is_interior(shape, NodeId::ROOT) {
            stats.visited += 1;
            if engine.screen_error(view, NodeId::ROOT) > p.tau {
                self.cut.split_active(shape, NodeId::ROOT);
                delta.splits.push(engine.split_payload(NodeId::ROOT));
                self.process(engine, view, p, NodeId::ROOT, &mut delta, stats);
            }
        } else {
            // Band by band, in no order of depth: a parent examined after its child merged in
            // this update is blocked from merging (and examined again at the next update), so
            // coarsening still moves one level per update, as in the paper's top-down pass.
            self.blocked.clear();
            let mut due = std::mem::take(&mut self.due);
            let mut peak = 0;
            for band in 0..=self.schedule.bands() {
                if band == 0 {
                    if let Some(start) = self.resumed.take() {
                        // The first update: every group of the cut continued from is due,
                        // read from the copy (the cut itself changes as they are examined).
                        for node in start.interior_nodes() {
                            if self.cut.is_interior(shape, node) && self.cut.tag(node) == 0 {
                                self.process(engine, view, p, node, &mut delta, stats);
                            }
                        }
                    }
                    self.schedule.drain_next(&mut due);
                } else {
                    self.schedule.drain_band(band - 1, &mut due);
                }
                peak = peak.max(due.len());
                for e in due.drain(..) {
                    let (node, generation) = self.schedule.entry_parts(e);
                    let tag = self.cut.interior_tag(node);
                    if tag.is_some_and(|t| self.schedule.generation(t) == generation) {
                        self.process(engine, view, p, node, &mut delta, stats);
                    }
                }
            }
            trim(&mut due, peak);
            self.due = due;
        }
        delta.canonicalize();
        delta.digest = self.cut.digest();
        delta
    }

    /// Examines the group of interior node `node` and files it again.
    fn process(
        &mut self,
        engine: &VertexEngine<'_>,
        view: &ViewState,
        p: &LodParams,
        node: NodeId,
        delta: &mut Delta,
        stats: &mut UpdateStats,
    ) {
        let shape = &engine.geometry().shape;
        let exists = engine.existing_children(node);
        let active = exists & !self.cut.interior_children(node);
        let mut slack = f64::INFINITY;
        let mut reach = 0.0f32;
        if active == exists && self.blocked.contains(&node_index(node)) {
            // A child merged in this update: the merge check waits for the next one.
            slack = 0.0;
        } else if active == exists {
            stats.visited += 1;
            let (bv, err) = engine.box_view(view, node);
            let e = view.error_of(&bv, err);
            if e < p.tau * p.merge_ratio {
                self.cut.merge_interior(shape, node);
                delta.merges.push(node);
                if let Some(parent) = node.parent() {
                    // Its group gained this node's split check and maybe its own merge check:
                    // examined at the next update. Its entry stays live, since its other
                    // checks may be due in this one.
                    self.blocked.insert(node_index(parent));
                    self.schedule.file_next(parent, self.cut.tag(parent));
                }
                return;
            }
            slack = merge_slack(view, &bv, err, p.tau * p.merge_ratio);
            reach = bv.d_max;
        }
        if node.level + 1 < shape.depth() && active != 0 {
            let views = engine.children_views(view, node, active);
            for (k, (cv, cerr)) in views.iter().enumerate() {
                if active >> k & 1 == 0 {
                    continue;
                }
                stats.visited += 1;
                let c = node.child(k);
                if view.error_of(cv, *cerr) > p.tau && !self.at_limit() {
                    self.cut.split_active(shape, c);
                    delta.splits.push(engine.split_payload(c));
                    // Refine as deep as this pose needs, as the full pass does.
                    self.process(engine, view, p, c, delta, stats);
                } else {
                    slack = slack.min(split_slack(view, cv, *cerr, p.tau));
                    reach = reach.max(cv.d_max);
                }
            }
        }
        let g = self.next_generation(node);
        if slack.is_finite() {
            let slack = (slack * SLACK_SAFETY).max(0.0);
            self.schedule.file(node, g, slack, reach as f64);
        }
    }
}

/// Lets a reused buffer that now holds `len` items give back what a burst (the first update's
/// full set of groups, say) made it grow to.
fn trim<T>(v: &mut Vec<T>, len: usize) {
    if v.capacity() > 4096 && v.capacity() > 8 * len {
        v.shrink_to(2 * len);
    }
}

/// How far a box may move relative to the camera while a node with error `err` and screen error
/// at most `tau` stays at most `tau`.
fn split_slack(view: &ViewState, bv: &BoxView, err: f32, tau: f32) -> f64 {
    if err <= 0.0 {
        return f64::INFINITY;
    }
    if bv.margin < 0.0 {
        // Culled: nothing can change until the box reaches the frustum.
        return -bv.margin as f64;
    }
    let near = view.near() as f64;
    let z = bv.depth as f64;
    let r = bv.r_max as f64;
    let a = view.focal() as f64 * err as f64 / tau as f64;
    // Branch e <= K err (r + d) / (z - d)^2: the smaller root of (z - d)^2 = a (r + d).
    let c = z * z - a * r;
    let s_a = if z > near && c >= 0.0 {
        let b = 2.0 * z + a;
        let disc = (b * b - 4.0 * c).max(0.0);
        (2.0 * c / (b + disc.sqrt())).min(z - near)
    } else {
        0.0
    };
    // Branch e <= K err c / (z - d).
    let s_c = z - (a * view.off_axis() as f64).max(near);
    s_a.max(s_c).max(0.0)
}

/// How far a box may move relative to the camera while a node with error `err` and screen error
/// at least `tau_m` stays at least `tau_m`.
fn merge_slack(view: &ViewState, bv: &BoxView, err: f32, tau_m: f32) -> f64 {
    let near = view.near() as f64;
    let z = (bv.depth as f64).max(near);
    let r = bv.r_max as f64;
    let b = view.focal() as f64 * err as f64 / tau_m as f64;
    // Branch e >= K err (r - d) / (z + d)^2: the larger root of (z + d)^2 = b (r - d).
    let c = z * z - b * r;
    let s_a = if c <= 0.0 {
        let bb = 2.0 * z + b;
        -2.0 * c / (bb + (bb * bb - 4.0 * c).sqrt())
    } else {
        0.0
    };
    // Branch e >= K err c / (z + d).
    let s_c = b * view.off_axis() as f64 - z;
    (bv.margin as f64).min(s_a).min(s_c).max(0.0)
}
