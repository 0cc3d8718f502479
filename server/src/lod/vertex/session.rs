//! One session's cut with event-driven updates: only the nodes whose decision can have changed
//! since they were last examined are examined again.
//!
//! The paper's top-down pass (paper 000, section 3.4; [`VertexEngine::update`]) touches every
//! interior and active node on every update. This session produces exactly the same deltas, but
//! it groups the checks by interior node: the group of an interior node `P` is the checks of its
//! children, the split check of each active child and the merge check of each interior child
//! whose own children are all active. The four children's boxes are one quad of records, so a
//! group is one evaluation of four lanes ([`VertexEngine::children_views`]), and a node one level
//! above the leaves, whose only check is its merge check, has no group of its own: its parent's
//! covers it and three siblings at once. The root's merge check belongs to no group and runs at
//! every update where the root's children are all active. After a group is examined, the engine
//! computes a *slack*: how far the camera-relative position of the children's boxes may move
//! before any of those decisions can flip. The bounds are the screen-error formula's
//! own terms ([`BoxView`]) taken at their worst over that displacement: the nearest depth shrinks
//! or grows by at most the displacement, the horizontal reach likewise, and the frustum test's
//! margin likewise. Camera translation moves them by at most the eye's travel `T`. Camera rotation
//! by angle `a` moves a point at distance `D` by at most the chord `D 2 sin(a / 2)`, which bounds
//! the margin's move; but the depth of a point near the view axis moves much less (see
//! `Bounds`), so a group whose slack is a depth slack has a shorter *lever* than its distance.
//! The group is filed in the band of its lever, and each band keeps an odometer that advances by
//! the eye's travel plus the band's lever times the chords; a group is due when its band's
//! odometer passes its key.
//!
//! Due groups are examined as they come out of the schedule, in no order of depth. The full pass
//! examines parents first, so a node whose child merged in this update may not merge before the
//! next one: such nodes are *blocked* for the rest of the update (the other checks of their
//! parent's group still run) and their parent's group is filed for the next update (coarsening
//! moves one level per update). Splitting a child examines the child's own new group at once
//! (refinement goes as deep as the pose needs).
//!
//! The schedule ([`super::schedule`]) keeps one entry per interior node whose group checks
//! anything, in flat per-band buckets; an interior node whose children are leaves, or interior
//! with interior children of their own, checks nothing and is filed nowhere. State per session:
//! the cut's interior bitset with a 4-bit generation per interior node, and the schedule's
//! entries (4 bytes each).
//! Due groups are drained from every band before any is examined, then examined as they came out
//! of the wheels (no sort).

use super::schedule::{Schedule, node_index};
use super::{LodParams, UpdateStats, VertexEngine};
use relief_proto::cut::Cut;
use relief_proto::delta::Delta;
use relief_proto::float::Extremum;
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
    /// The last delta's numbers of merges and splits: the next delta's lists start with room
    /// for as many (a list grown from empty is reallocated at every doubling).
    last_sizes: (usize, usize),
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
            last_sizes: (0, 0),
            blocked: FxHashSet::default(),
            max_interior: usize::MAX,
            resumed: (cut.interior_count() > 0).then(|| cut.clone()),
        }
    }

    /// The current cut.
    pub fn cut(&self) -> Cut {
        self.cut.clone()
    }

    /// The current cut, borrowed (a delta's body is packed against it: [`relief_proto::delta::Known`]).
    pub fn cut_ref(&self) -> &Cut {
        &self.cut
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
            merges: Vec::with_capacity(self.last_sizes.0),
            splits: Vec::with_capacity(self.last_sizes.1),
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
            // The root's merge check belongs to no group: it runs at every update where its
            // children are all active, first, as in the full pass (then no child can split: a
            // child's screen error is at most its parent's).
            if self.cut.interior_children(NodeId::ROOT) == 0 {
                stats.visited += 1;
                if engine.screen_error(view, NodeId::ROOT) < p.tau * p.merge_ratio {
                    self.cut.merge_interior(shape, NodeId::ROOT);
                    delta.merges.push(NodeId::ROOT);
                }
            }
            // Everything due is drained before anything is examined, so that a group filed
            // again during this update (its slack computed for this very pose) waits for the
            // next pose instead of coming out of a band drained after it. Due groups are then
            // examined in no order of depth: a parent examined after its child merged in this
            // update is blocked from merging (and examined again at the next update), so
            // coarsening still moves one level per update, as in the paper's top-down pass.
            self.blocked.clear();
            let mut due = std::mem::take(&mut self.due);
            self.schedule.drain_next(&mut due);
            for band in 0..self.schedule.bands() {
                self.schedule.drain_band(band, &mut due);
            }
            if let Some(start) = self.resumed.take() {
                // The first update: every group of the cut continued from is due, read from
                // the copy (the cut itself changes as they are examined).
                for node in start.interior_nodes() {
                    if self.cut.is_interior(shape, node) && self.cut.tag(node) == 0 {
                        self.process(engine, view, p, node, &mut delta, stats);
                    }
                }
            }
            for &e in &due {
                let (node, generation) = self.schedule.entry_parts(e);
                let tag = self.cut.interior_tag(node);
                if tag.is_some_and(|t| self.schedule.generation(t) == generation) {
                    self.process(engine, view, p, node, &mut delta, stats);
                }
            }
            let peak = due.len();
            due.clear();
            trim(&mut due, peak);
            self.due = due;
        }
        delta.canonicalize();
        delta.digest = self.cut.digest();
        self.last_sizes = (delta.merges.len(), delta.splits.len());
        delta
    }

    /// Examines the group of interior node `node` and files it again: the checks of its
    /// children, all four evaluated together from one quad of records. An active child (not a
    /// leaf) has its split check; an interior child whose children are all active has its merge
    /// check; an interior child with an interior child has none.
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
        if node.level + 1 >= shape.depth() {
            // Leaf children: nothing to check, nothing to file.
            return;
        }
        let exists = engine.existing_children(node);
        let interior = self.cut.interior_children(node);
        let active = exists & !interior;
        // An interior child can merge when none of its children is interior (one read for all
        // four: their grandchildren bits). Under a node two levels above the leaves the
        // grandchildren are leaves, never interior, so there is nothing to read.
        let mut mergeable = interior;
        if interior != 0 && node.level + 2 < shape.depth() {
            let grand = self.cut.interior_grandchildren(node);
            for k in 0..4 {
                if grand >> (4 * k) & 15 != 0 {
                    mergeable &= !(1 << k);
                }
            }
        }
        let checked = active | mergeable;
        let tau_m = p.tau * p.merge_ratio;
        // The slacks' `focal / tau` factors, one division per group instead of one per lane
        // (they are bounds, with a safety factor: the rounding does not matter).
        let focal = view.focal() as f64;
        let (k_split, k_merge) = (focal / p.tau as f64, focal / tau_m as f64);
        let mut bounds = Bounds::default();
        if checked != 0 {
            let (views, errs) = engine.children_views(view, node);
            for (k, (cv, cerr)) in views.iter().zip(&errs).enumerate() {
                let c = node.child(k);
                if active >> k & 1 != 0 {
                    stats.visited += 1;
                    if view.error_of(cv, *cerr) > p.tau && !self.at_limit() {
                        self.cut.split_active(shape, c);
                        delta.splits.push(engine.split_payload(c));
                        // Its merge check joins this group, and its error is over tau.
                        merge_slack(view, cv, *cerr, k_merge, &mut bounds);
                        // Refine as deep as this pose needs, as the full pass does.
                        self.process(engine, view, p, c, delta, stats);
                    } else {
                        split_slack(view, cv, *cerr, k_split, &mut bounds);
                    }
                } else if mergeable >> k & 1 != 0 {
                    if !self.blocked.is_empty() && self.blocked.contains(&node_index(c)) {
                        // A child of it merged in this update: its merge check waits for the
                        // next one.
                        bounds.due_now();
                        continue;
                    }
                    stats.visited += 1;
                    if view.error_of(cv, *cerr) < tau_m {
                        self.cut.merge_interior(shape, c);
                        delta.merges.push(c);
                        // Its split check joins this group, and its error is under tau. This
                        // node may now merge, in its parent's group: at the next update. The
                        // parent's entry stays live, since its other checks may be due in
                        // this one.
                        split_slack(view, cv, *cerr, k_split, &mut bounds);
                        self.blocked.insert(node_index(node));
                        if let Some(parent) = node.parent() {
                            self.schedule.file_next(parent, self.cut.tag(parent));
                        }
                    } else {
                        merge_slack(view, cv, *cerr, k_merge, &mut bounds);
                    }
                }
            }
        }
        let g = self.next_generation(node);
        if let Some((slack, lever)) = bounds.filing() {
            self.schedule.file(node, g, slack * SLACK_SAFETY, lever);
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

/// What a group's checks allow, in the two kinds of bound that camera motion is measured against
/// (see the module docs): how far the frustum test's margin may move, and how far the depth and
/// horizontal reach may.
///
/// A point's offset from the eye `v` is fixed at filing; `k` poses later its depth is
/// `v . f_k - (e_k - e_0) . f_k`, so the depth moves by at most the eye's travel `T` plus
/// `|v . (f_k - f_0)|`. With `c = |f_k - f_0|`, at most the running sum of the per-pose chords
/// `K`, that is at most `|v_perp| c + |v . f_0| c^2 / 2`, where `v_perp` is `v` off the view
/// axis: rotation moves the depth of what lies near the axis far less than the point itself.
/// A plane's distance (the margin) has no such axis, and moves by up to `|v| K + T`.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    /// Margin slack (metres) and the furthest distance from the eye of a box it bounds.
    margin: (f64, f64),
    /// Depth and reach slack (metres).
    depth: f64,
    /// The square of the furthest distance off the view axis of a box whose depth `depth`
    /// bounds (one square root per group at filing, not one per check: the root of the largest
    /// square is the largest root, bit for bit), and the furthest distance along it.
    off_axis_sq: f64,
    along: f64,
}

impl Default for Bounds {
    fn default() -> Bounds {
        Bounds {
            margin: (f64::INFINITY, 0.0),
            depth: f64::INFINITY,
            off_axis_sq: 0.0,
            along: 0.0,
        }
    }
}

impl Bounds {
    /// Makes the group due at the next drain.
    fn due_now(&mut self) {
        self.margin.0 = 0.0;
    }

    /// A check that holds while the frustum margin of box `bv` moves less than `slack`.
    fn margin(&mut self, slack: f64, bv: &BoxView) {
        self.margin = (
            self.margin.0.lesser(slack),
            self.margin.1.greater(bv.d_max as f64),
        );
    }

    /// A check that holds while the depth and reach of box `bv` move less than `slack`.
    fn depth(&mut self, slack: f64, bv: &BoxView) {
        let d = bv.d_max as f64;
        // Every point of the box is at most `d_max` from the eye and at least `depth` along the
        // axis (when that is not negative), so at most this far off it.
        let z = bv.depth as f64;
        let off_sq = if z > 0.0 {
            (d * d - z * z).greater(0.0)
        } else {
            d * d
        };
        self.depth = self.depth.lesser(slack);
        self.off_axis_sq = self.off_axis_sq.greater(off_sq);
        self.along = self.along.greater(d);
    }

    /// The slack to file the group with and the lever arm of its band: the group is due once
    /// `T + lever K` reaches `slack`, which comes no later than either bound can be reached.
    /// None when nothing can change.
    ///
    /// Until then `K < slack / lever`, so the depth's quadratic term is at most
    /// `along K / 2 * slack / lever`; the lever solves `lever = (off_axis + along (slack / lever)
    /// / 2) slack / depth`, the smallest that keeps the depth bound (and exact at `depth` =
    /// `slack`). For the margin, `lever >= margin's distance * slack / margin slack` keeps it.
    fn filing(&self) -> Option<(f64, f64)> {
        let (m, m_reach) = self.margin;
        let s = self.depth;
        let slack = m.lesser(s).greater(0.0);
        if !slack.is_finite() {
            return None;
        }
        if slack == 0.0 {
            return Some((0.0, m_reach.greater(self.along)));
        }
        let mut lever: f64 = 0.0;
        if m.is_finite() {
            lever = lever.greater(m_reach * slack / m);
        }
        if s.is_finite() {
            // lever^2 - (off_axis slack / s) lever - along slack^2 / (2 s) = 0, larger root.
            let ratio = slack / s;
            let (p, q) = (
                self.off_axis_sq.sqrt() * ratio,
                self.along * slack * ratio / 2.0,
            );
            lever = lever.greater((p + (p * p + 4.0 * q).sqrt()) / 2.0);
        }
        Some((slack, lever))
    }
}

/// Bounds how far a box may move relative to the camera while a node with error `err` and screen
/// error at most `tau` stays at most `tau`; `k` is `focal / tau`.
fn split_slack(view: &ViewState, bv: &BoxView, err: f32, k: f64, bounds: &mut Bounds) {
    if err <= 0.0 {
        return;
    }
    if bv.margin < 0.0 {
        // Culled: nothing can change until the box reaches the frustum.
        bounds.margin(-bv.margin as f64, bv);
        return;
    }
    let near = view.near() as f64;
    let z = bv.depth as f64;
    let r = bv.r_max as f64;
    let a = k * err as f64;
    // Branch e <= K err (r + d) / (z - d)^2: the smaller root of (z - d)^2 = a (r + d).
    let c = z * z - a * r;
    let s_a = if z > near && c >= 0.0 {
        let b = 2.0 * z + a;
        let disc = (b * b - 4.0 * c).greater(0.0);
        (2.0 * c / (b + disc.sqrt())).lesser(z - near)
    } else {
        0.0
    };
    // Branch e <= K err c / (z - d). Leaving the frustum only lowers the error.
    let s_c = z - (a * view.off_axis() as f64).greater(near);
    bounds.depth(s_a.greater(s_c).greater(0.0), bv);
}

/// Bounds how far a box may move relative to the camera while a node with error `err` and screen
/// error at least `tau_m` stays at least `tau_m`; `k` is `focal / tau_m`.
fn merge_slack(view: &ViewState, bv: &BoxView, err: f32, k: f64, bounds: &mut Bounds) {
    let near = view.near() as f64;
    let z = (bv.depth as f64).greater(near);
    let r = bv.r_max as f64;
    let b = k * err as f64;
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
    // Leaving the frustum drops the error to 0.
    bounds.margin((bv.margin as f64).greater(0.0), bv);
    bounds.depth(s_a.lesser(s_c).greater(0.0), bv);
}
