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
use super::{ChildViews, LodParams, UpdateStats, VertexEngine};
use relief_proto::cut::Cut;
use relief_proto::delta::Delta;
use relief_proto::float::Extremum;
use relief_proto::tree::NodeId;
use relief_proto::view::ViewState;
use rustc_hash::FxHashSet;
use wide::f32x4;

/// Safety factor on every slack, against rounding in the bounds.
const SLACK_SAFETY: f64 = 0.98;
/// Taken off a slack, times the sum of the magnitudes it is computed from (depth, reach and
/// the error's reach `a c`): the slacks are computed in single precision, whose roundings
/// (a few units of `2^-24` of those magnitudes, the discriminant written without cancellation)
/// this covers several times over; the relative part is [`SLACK_SAFETY`]'s.
const SLACK_GUARD: f32 = 2e-6;
/// A lane's share of the rotation's lever (see [`Bounds`]) is raised by this much, relative:
/// the square root and divisions it comes from round by a few units of `2^-24`.
const SHARE_GUARD: f32 = 1e-5;
/// A group's lever is raised by this much, relative: its few single-precision operations
/// (divisions and square roots from the lanes' slacks and distances) round by a few units of
/// `2^-24` each.
const LEVER_ROUND: f64 = 1e-5;
/// Added to a lever's square, times the square of the distance it is computed from: the
/// single-precision difference `d^2 - z^2` is within a few units of `2^-24 d^2`.
const LEVER_GUARD: f32 = 1e-6;
/// How many due groups ahead of the one examined its cut's page and records are prefetched.
const AHEAD: usize = 4;

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
            self.schedule.drain_bands(&mut due);
            if let Some(start) = self.resumed.take() {
                // The first update: every group of the cut continued from is due, read from
                // the copy (the cut itself changes as they are examined).
                for node in start.interior_nodes() {
                    if self.cut.is_interior(shape, node) && self.cut.tag(node) == 0 {
                        self.process(engine, view, p, node, &mut delta, stats);
                    }
                }
            }
            // The groups' state is scattered (and, on a loaded server, out of the caches): a
            // group's page of the cut and its children's records are prefetched AHEAD groups
            // before its examination, so that their loads overlap.
            for (i, &e) in due.iter().enumerate() {
                if let Some(&ahead) = due.get(i + AHEAD) {
                    let n = self.schedule.entry_parts(ahead).0;
                    self.cut.prefetch_tag(n);
                    engine.prefetch_children(n);
                }
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
            // Nibble `k` of the grandchildren's bits is child `k`'s children: bit `k` of
            // `busy` says any of them is interior (no branch per child).
            let grand = self.cut.interior_grandchildren(node);
            let any = (grand | grand >> 1 | grand >> 2 | grand >> 3) & 0x1111;
            let busy = (any | any >> 3 | any >> 6 | any >> 9) as u8 & 15;
            mergeable &= !busy;
        }
        let checked = active | mergeable;
        let tau_m = p.tau * p.merge_ratio;
        // The slacks' `focal / tau` factors, one division per group instead of one per lane
        // (they are bounds, with a safety factor: the rounding does not matter).
        let focal = view.focal() as f64;
        let (k_split, k_merge) = (focal / p.tau as f64, focal / tau_m as f64);
        let mut bounds = Bounds::default();
        if checked != 0 {
            let children = engine.children_views(view, node);
            let over = lane_bits(children.screen, |e| e > p.tau);
            let under = lane_bits(children.screen, |e| e < tau_m);
            stats.visited += u64::from((active | mergeable).count_ones());
            // A child of which a child merged in this update may not merge before the next
            // one: its merge check waits for it. Only a child whose error is under the merge
            // threshold is looked up; the others keep their merge check and its slack, which
            // bounds when they can merge whether or not they are blocked.
            let mut merging = mergeable & under;
            if merging != 0 && !self.blocked.is_empty() {
                for k in 0..4 {
                    if merging >> k & 1 != 0 && self.blocked.contains(&node_index(node.child(k))) {
                        merging &= !(1 << k);
                        bounds.due_now();
                    }
                }
            }
            // Most groups change nothing: each lane keeps its check. A lane that splits or
            // merges takes the other check instead, from the same evaluation, in child order
            // (a split may meet the cap on interior nodes that an earlier merge lifted).
            let mut split_checks = active & !over;
            let mut merge_checks = mergeable & !under;
            let mut changing = (active & over) | merging;
            while changing != 0 {
                let k = changing.trailing_zeros() as usize;
                changing &= changing - 1;
                let c = node.child(k);
                if active >> k & 1 != 0 {
                    if self.at_limit() {
                        split_checks |= 1 << k;
                        continue;
                    }
                    self.cut.split_active(shape, c);
                    delta.splits.push(engine.split_payload(c));
                    // Its merge check joins this group, and its error is over tau.
                    merge_checks |= 1 << k;
                    // Refine as deep as this pose needs, as the full pass does.
                    self.process(engine, view, p, c, delta, stats);
                } else {
                    self.cut.merge_interior(shape, c);
                    delta.merges.push(c);
                    // Its split check joins this group, and its error is under tau. This node
                    // may now merge, in its parent's group: at the next update. The parent's
                    // entry stays live, since its other checks may be due in this one.
                    split_checks |= 1 << k;
                    self.blocked.insert(node_index(node));
                    if let Some(parent) = node.parent() {
                        self.schedule.file_next(parent, self.cut.tag(parent));
                    }
                }
            }
            bounds.checks(
                view,
                &children,
                (split_checks, merge_checks),
                (k_split, k_merge),
            );
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
///
/// *Rotation's share.* A depth check's slack `s` is how far the depth and the horizontal reach
/// may both move against the check, but the eye's travel moves both (by at most `T`) while the
/// rotation moves only the depth (by at most `R`, the bound above): the reach is the horizontal
/// distance from the eye. Over the plane of (reach moved `x`, depth moved `y`) the check holds
/// in a region that holds `(s, s)`, and the motion reaches at most `(T, T + R)`. For a merge
/// the region of the first branch, `(z + y)^2 <= b (r - x)`, is convex, and so is its
/// intersection with the second's, `y <= b c - z`; it holds `(0, s_z)`, `s_z` the slack with the
/// reach held, so it holds the chord to `(s, s)`, and the check holds while
/// `T + (s / s_z) R <= s`. For a split the first branch's region, `y <= z - sqrt(a (r + x))`,
/// lies above its boundary's tangent at `x = s` (the boundary is convex), whose slope is
/// `-sqrt(a / (r + s)) / 2`, and the check holds while `T + R / (1 + sqrt(a / (r + s)) / 2)
/// <= s` and `T + R <= z - near`; where the second branch (the depth alone) bounds, the share
/// is 1. Each lane's lever (its off-axis distance and its distance along the axis) is
/// multiplied by its share: a depth slack is spent by rotation at the share's rate.
///
/// *Levers per lane.* The group is filed with the smallest slack `s` of its lanes and the
/// largest of the levers each lane needs at that slack: a lane with slack `s_i >= s` and
/// lever `L_i` holds while `T + L_i K < s_i`, which `T + L K < s` implies once
/// `L >= L_i s / s_i` (then `L_i K < (s - T) s_i / s <= s_i - T`). So a lane far from its
/// decision lends little to the lever, however far it lies. A margin lane's lever at the
/// group's slack is `d s / m` (its box at most `d` from the eye, its margin slack `m`); a depth
/// lane's is the larger root of `L^2 - (off s / s_i) L - along s^2 / (2 s_i)` (`off` and
/// `along` its shared distances off and along the axis): until the group is due `K < s / L`,
/// so the depth's quadratic term `along K^2 / 2` is at most `along K s / (2 L)`, and this `L`
/// keeps `T + off K + along K^2 / 2 < s_i` (exact where `s_i = s`).
#[derive(Clone, Copy, Debug)]
struct Bounds {
    /// The smallest margin slack (metres).
    margin: f64,
    /// The smallest depth and reach slack (metres).
    depth: f64,
    /// The lever for the group's slack (`min(margin, depth)`), metres.
    lever: f64,
    /// The furthest distance from the eye of a checked box (the band of a group due now).
    reach: f64,
}

impl Default for Bounds {
    fn default() -> Bounds {
        Bounds {
            margin: f64::INFINITY,
            depth: f64::INFINITY,
            lever: 0.0,
            reach: 0.0,
        }
    }
}

impl Bounds {
    /// Makes the group due at the next drain.
    fn due_now(&mut self) {
        self.margin = 0.0;
    }

    /// The slack to file the group with and the lever arm of its band: the group is due once
    /// `T + lever K` reaches `slack`, which comes no later than any lane's bound can be
    /// reached. None when nothing can change.
    fn filing(&self) -> Option<(f64, f64)> {
        let slack = self.margin.lesser(self.depth).greater(0.0);
        if !slack.is_finite() {
            return None;
        }
        if slack == 0.0 {
            return Some((0.0, self.reach));
        }
        Some((slack, self.lever))
    }
}

/// Bit `k` set where `test` holds for lane `k`.
#[inline]
fn lane_bits(v: [f32; 4], test: impl Fn(f32) -> bool) -> u8 {
    (0..4).fold(0, |m, k| m | u8::from(test(v[k])) << k)
}

/// Each lane's mask, all ones where bit `k` of the index is set.
const LANE_MASKS: [[f32; 4]; 16] = {
    let mut t = [[0.0; 4]; 16];
    let mut m = 0;
    while m < 16 {
        let mut k = 0;
        while k < 4 {
            if m >> k & 1 != 0 {
                t[m][k] = f32::from_bits(u32::MAX);
            }
            k += 1;
        }
        m += 1;
    }
    t
};

/// The mask of the lanes whose bits are set in `bits` (the low four).
#[inline]
fn lane_mask(bits: u8) -> f32x4 {
    f32x4::from(LANE_MASKS[bits as usize & 15])
}

impl Bounds {
    /// Adds a group's checks, all four lanes at once: a split check on the lanes of `checks.0`
    /// and a merge check on those of `checks.1` (bit `k`: child `k`); `k` holds `focal / tau`
    /// and `focal / tau_m`.
    ///
    /// A split check of a node with error `err` and screen error at most `tau` holds while
    /// its box moves less than the slack (nothing while its error is 0, the frustum margin
    /// while it is culled); a merge check, screen error at least `tau_m`, while it moves less
    /// than either slack (leaving the frustum drops the error to 0). The branches of the screen
    /// error (`e <= K err (r + d) / (z - d)^2` and `e <= K err c / (z - d)` for a split,
    /// `e >= K err (r - d) / (z + d)^2` and `e >= K err c / (z + d)` for a merge) are both
    /// computed on every lane and the checks' own kept by masks: each operation is one packed
    /// single-precision instruction over the four lanes ([`wide`]), in the precision of the
    /// views they start from. A slack is then smaller than the scalar formulas' in double
    /// precision (the reference, kept in the tests) by [`SLACK_GUARD`] times its magnitudes,
    /// and a lever's square larger by [`LEVER_GUARD`] times the distance's, so that a group
    /// is due no later than the reference would make it (tested over random boxes).
    #[inline]
    fn checks(&mut self, view: &ViewState, c: &ChildViews, checks: (u8, u8), k: (f64, f64)) {
        let (margin, z, r, d) = (
            f32x4::from(c.views.margin),
            f32x4::from(c.views.depth),
            f32x4::from(c.views.r_max),
            f32x4::from(c.views.d_max),
        );
        let err = f32x4::from(c.errs);
        let splat = f32x4::splat;
        let (zero, half, one, two, four) =
            (f32x4::ZERO, splat(0.5), f32x4::ONE, splat(2.0), splat(4.0));
        let near = splat(view.near());
        let off = splat(view.off_axis());
        let guard = splat(SLACK_GUARD);

        // Split: the smaller root of (z - d)^2 = a (r + d) where z > near and the root is
        // real, else 0; and z - max(a c, near). Skipped for a group without split checks. The
        // discriminant `(2 z + a)^2 - 4 (z^2 - a r)` is `a (a + 4 (z + r))`, a sum of
        // positive terms where the root is used, so it does not cancel in single precision.
        let (split, split_share) = if checks.0 == 0 {
            (zero, one)
        } else {
            let a = splat(k.0 as f32) * err;
            let cs = z * z - a * r;
            let b = two * z + a;
            let disc = zero.fast_max(a * (a + four * (z + r)));
            let root = (z - near).fast_min(two * cs / (b + disc.sqrt()));
            let real = z.simd_gt(near) & cs.simd_ge(zero);
            let s_a = real.bitselect(root, zero);
            let s_c = z - near.fast_max(a * off);
            let raw = zero.fast_max(s_c.fast_max(s_a));
            let slack = zero.fast_max(raw - guard * (z.abs() + r + a * off));
            // Rotation's share where the first branch bounds (see [`Bounds`], *rotation's share*):
            // its boundary's tangent at the slack before the guard (the guarded slack is
            // smaller, which the tangent's condition allows), and the near plane's.
            let tangent = one / (one + half * (a / (r + raw)).sqrt());
            let share = tangent.fast_max(raw / (z - near));
            let first = real & s_a.simd_gt(s_c);
            (slack, first.bitselect(share, one))
        };

        // Merge, with the depth at least `near`: the larger root of (z + d)^2 = b (r - d)
        // where it is positive, else 0; and b c - z. Skipped for a group without merge checks.
        // The discriminant is `b (b + 4 (z + r))`, as for a split.
        let (merge, merge_share) = if checks.1 == 0 {
            (zero, one)
        } else {
            let zm = near.fast_max(z);
            let b = splat(k.1 as f32) * err;
            let cm = zm * zm - b * r;
            let bb = two * zm + b;
            let disc = b * (b + four * (zm + r));
            let root = splat(-2.0) * cm / (bb + disc.sqrt());
            let s_a = cm.simd_le(zero).bitselect(root, zero);
            let s_c = b * off - zm;
            let raw = zero.fast_max(s_c.fast_min(s_a));
            let slack = zero.fast_max(raw - guard * (zm + r + b * off));
            // Rotation's share (see [`Bounds`], *rotation's share*): the slack before the guard
            // over the depth's own slack (the reach held), each branch's lowered by the guard.
            let br = (b * r).sqrt();
            let depth_only = (br - zm - guard * (zm + br)).fast_min(s_c - guard * (zm + b * off));
            let share = depth_only.simd_gt(raw).bitselect(raw / depth_only, one);
            (slack, share)
        };

        // Which lanes bound what.
        let splits = lane_mask(checks.0) & err.simd_gt(zero);
        let merges = lane_mask(checks.1);
        let culled = margin.simd_lt(zero);
        let inf = splat(f32::INFINITY);
        let margin_on = (splits & culled) | merges;
        let depth_on = (splits & !culled) | merges;
        let margin_slack = merges.bitselect(zero.fast_max(margin), -margin);
        let depth_slack = merges.bitselect(merge, split);
        // Every point of a box is at most `d_max` from the eye and at least `depth` along the
        // axis (when that is not negative), so at most this far off it. A lever must not come
        // out short: the square is raised by more than its rounding.
        // Rotation moves a depth lane's depth but not its reach: its lever counts at its share
        // (raised by more than the share's rounding, and at most 1).
        let share =
            one.fast_min(merges.bitselect(merge_share, split_share) * splat(1.0 + SHARE_GUARD));
        let off_sq = (z
            .simd_gt(zero)
            .bitselect(zero.fast_max(d * d - z * z), d * d)
            + splat(LEVER_GUARD) * d * d)
            * (share * share);

        let min = |on: f32x4, v: f32x4, acc: f64| -> f64 {
            let v = on.bitselect(v, inf).to_array();
            acc.lesser(v[0].lesser(v[1]).lesser(v[2].lesser(v[3])) as f64)
        };
        let max = |on: f32x4, v: f32x4, acc: f64| -> f64 {
            let v = on.bitselect(v, zero).to_array();
            acc.greater(v[0].greater(v[1]).greater(v[2].greater(v[3])) as f64)
        };
        self.margin = min(margin_on, margin_slack, self.margin);
        self.depth = min(depth_on, depth_slack, self.depth);
        let along = d * share;
        // Each lane's levers at the group's slack (see [`Bounds`], *levers per lane*), in single
        // precision: the margin's `d slack / m`, and the depth's larger root. A lane without a
        // check of a kind has that kind's slack infinite, so its term is 0.
        let slack = self.margin.lesser(self.depth).greater(0.0);
        if slack > 0.0 && slack.is_finite() {
            let g = splat(slack as f32);
            let m = margin_on.bitselect(margin_slack, inf);
            let s = depth_on.bitselect(depth_slack, inf);
            let ratio = g / s;
            let p = off_sq.sqrt() * ratio;
            let q = half * along * g * ratio;
            let depth_lever = half * (p + (p * p + four * q).sqrt());
            let lever = (d * g / m).fast_max(depth_lever);
            // Rounded up by more than the single precision's roundings.
            self.lever = max(margin_on | depth_on, lever, 0.0) * (1.0 + LEVER_ROUND);
        } else {
            // Only a group due now needs its reach (for its band).
            self.reach = max(margin_on, d, max(depth_on, along, self.reach));
        }
    }
}

#[cfg(test)]
mod tests {
    //! The four-lane checks against the scalar formulas they replaced (commit 399ccb8), in double
    //! precision, kept here as the reference.
    use super::*;
    use crate::lod::vertex::tests::{camera, lens, pose};
    use proptest::prelude::*;
    use relief_proto::view::BoxView;

    /// The reference's lanes, in double precision: each check's kind, slack and lever terms.
    #[derive(Clone, Debug, Default)]
    struct Reference {
        /// Margin checks: (slack, distance).
        margins: Vec<(f64, f64)>,
        /// Depth checks: (slack, off-axis distance, distance along the axis), both distances
        /// times the lane's share.
        depths: Vec<(f64, f64, f64)>,
        due: bool,
    }

    impl Reference {
        /// A check that holds while the frustum margin of box `bv` moves less than `slack`.
        fn margin(&mut self, slack: f64, bv: &BoxView) {
            self.margins.push((slack, bv.d_max as f64));
        }

        /// A check that holds while the depth and reach of box `bv` move less than `slack`,
        /// rotation spending it at `share` of its lever's rate.
        fn depth(&mut self, slack: f64, bv: &BoxView, share: f64) {
            let d = bv.d_max as f64;
            // Every point of the box is at most `d_max` from the eye and at least `depth` along the
            // axis (when that is not negative), so at most this far off it.
            let z = bv.depth as f64;
            let off_sq = if z > 0.0 {
                (d * d - z * z).greater(0.0)
            } else {
                d * d
            };
            self.depths.push((slack, off_sq.sqrt() * share, d * share));
        }

        fn smallest_margin(&self) -> f64 {
            let m = self
                .margins
                .iter()
                .fold(f64::INFINITY, |a, &(s, _)| a.lesser(s));
            if self.due { 0.0 } else { m }
        }

        fn smallest_depth(&self) -> f64 {
            self.depths
                .iter()
                .fold(f64::INFINITY, |a, &(s, ..)| a.lesser(s))
        }

        /// The largest shared distance along the axis of the depth checks.
        fn along(&self) -> f64 {
            self.depths
                .iter()
                .fold(0.0, |a, &(.., along)| a.greater(along))
        }

        /// The group's slack and lever (see [`Bounds`], *levers per lane*; the slack of a
        /// group due now is 0, whatever its lever).
        fn filing(&self) -> Option<(f64, f64)> {
            let slack = self
                .smallest_margin()
                .lesser(self.smallest_depth())
                .greater(0.0);
            if !slack.is_finite() {
                return None;
            }
            if slack == 0.0 {
                return Some((0.0, 0.0));
            }
            let margin = self.margins.iter().map(|&(m, d)| d * slack / m);
            // The larger root of `L^2 - (off slack / s) L - along slack^2 / (2 s)`.
            let depth = self.depths.iter().map(|&(s, off, along)| {
                let ratio = slack / s;
                let (p, q) = (off * ratio, along * slack * ratio / 2.0);
                (p + (p * p + 4.0 * q).sqrt()) / 2.0
            });
            Some((slack, margin.chain(depth).fold(0.0, f64::greater)))
        }
    }

    /// Bounds how far a box may move relative to the camera while a node with error `err` and screen
    /// error at most `tau` stays at most `tau`; `k` is `focal / tau`.
    fn split_slack(
        view: &ViewState,
        bv: &BoxView,
        err: f32,
        k: f64,
        shared: bool,
        bounds: &mut Reference,
    ) {
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
        let real = z > near && c >= 0.0;
        let s_a = if real {
            let b = 2.0 * z + a;
            let disc = (b * b - 4.0 * c).greater(0.0);
            (2.0 * c / (b + disc.sqrt())).lesser(z - near)
        } else {
            0.0
        };
        // Branch e <= K err c / (z - d). Leaving the frustum only lowers the error.
        let s_c = z - (a * view.off_axis() as f64).greater(near);
        let slack = s_a.greater(s_c).greater(0.0);
        // Rotation's share: where the first branch bounds, its boundary's tangent at the slack
        // and the near plane's.
        let share = if shared && real && s_a > s_c {
            (1.0 / (1.0 + (a / (r + slack)).sqrt() / 2.0)).greater(slack / (z - near))
        } else {
            1.0
        };
        bounds.depth(slack, bv, share);
    }

    /// Bounds how far a box may move relative to the camera while a node with error `err` and screen
    /// error at least `tau_m` stays at least `tau_m`; `k` is `focal / tau_m`.
    fn merge_slack(
        view: &ViewState,
        bv: &BoxView,
        err: f32,
        k: f64,
        shared: bool,
        bounds: &mut Reference,
    ) {
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
        let slack = s_a.lesser(s_c).greater(0.0);
        // Rotation's share: the slack over the depth's own (the reach held).
        let depth_only = ((b * r).sqrt() - z).lesser(s_c);
        let share = if shared && depth_only > slack {
            slack / depth_only
        } else {
            1.0
        };
        bounds.depth(slack, bv, share);
    }

    /// A lane's screen error over its threshold, `a min(r / z, c) / z` (`a` is `k err`), with the
    /// depth at least `near`.
    fn error_ratio(view: &ViewState, a: f64, z: f64, r: f64) -> f64 {
        let z = z.greater(view.near() as f64);
        a * (r / z).lesser(view.off_axis() as f64) / z
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]

        /// Rotation's share (see [`Bounds`]): a lane whose eye travelled `T` (moving its depth
        /// and its reach by up to `T` each) and whose view turned so that its depth moved by
        /// up to `R` more keeps its decision wherever `T + share R <= slack`, at the worst
        /// corner of that motion and at random points inside it. A share of 1 would allow
        /// `R <= slack - T` only.
        #[test]
        fn rotation_spends_a_depth_slack_at_its_share(
            (z, r, e) in (0.5f64..5000.0, 0.0f64..2.0, -3.0f64..0.0),
            (t, u, v) in (0.0f64..=1.0, 0.0f64..=1.0, 0.0f64..=1.0),
            merge in any::<bool>(),
        ) {
            let view = ViewState::new(&camera(100, 100, (0.5, 0.5, 0.3, 0.2, 0.1)), &lens());
            let r = r * z;
            let bv = BoxView { margin: 1.0, depth: z as f32, r_max: r as f32, d_max: (z + r) as f32 };
            let (z, r) = (bv.depth as f64, bv.r_max as f64);
            // The error at `10^e` (split) or `10^-e` (merge) of the threshold.
            let ratio = if merge { 10f64.powf(-e) } else { 10f64.powf(e) };
            let (k, err) = (1.0, (ratio / error_ratio(&view, 1.0, z, r)) as f32);
            let a = err as f64;
            let mut b = Reference::default();
            let mut whole = Reference::default();
            if merge {
                merge_slack(&view, &bv, err, k, true, &mut b);
                merge_slack(&view, &bv, err, k, false, &mut whole);
            } else {
                split_slack(&view, &bv, err, k, true, &mut b);
                split_slack(&view, &bv, err, k, false, &mut whole);
            }
            let slack = b.smallest_depth();
            prop_assume!(slack > 0.0 && slack.is_finite());
            let share = b.along() / whole.along();
            prop_assert!(share > 0.0 && share <= 1.0, "{share}");
            // Travel `T`, then the most rotation the share allows, then a point inside.
            let travel = t * slack;
            let turn = (slack - travel) / share;
            for (dr, dz) in [(travel, travel + turn), (u * travel, v * (travel + turn))] {
                if merge {
                    let ratio = error_ratio(&view, a, z.greater(view.near() as f64) + dz, r - dr);
                    prop_assert!(ratio >= 1.0 - 1e-9, "merge {ratio} at {dr} {dz}: {slack} {share}");
                } else {
                    let ratio = error_ratio(&view, a, z - dz, r + dr);
                    prop_assert!(ratio <= 1.0 + 1e-9, "split {ratio} at {dr} {dz}: {slack} {share}");
                }
            }
        }

        /// The four-lane checks, in single precision, against the scalar ones in double
        /// precision (the reference), over random boxes (culled, behind the eye, nearer than
        /// `near`, zero errors) at three scales and every mix of checks: never a larger slack
        /// nor a shorter lever (the group is due no later, at any motion), and no smaller than
        /// the guards need.
        #[test]
        fn four_lane_checks_are_the_scalar_ones_or_sooner(
            t in pose(),
            lanes in proptest::array::uniform4((-1.0f32..1.0, -1.0f32..1.0, 0.0f32..1.0,
                                                 0.0f32..1.0, 0.0f32..1.0)),
            scale in proptest::sample::select(vec![1.0f32, 30.0, 3000.0]),
            (splits, merges) in (0u8..16, 0u8..16),
            k in (1000.0f64..3000.0, 1200.0f64..3200.0),
            due in any::<bool>(),
        ) {
            let view = ViewState::new(&camera(100, 100, t), &lens());
            let views: [BoxView; 4] = lanes.map(|(m, z, r, d, _)| {
                let d = d * scale * 2.0;
                BoxView { margin: m * scale, depth: z * d, r_max: r * d, d_max: d }
            });
            // About one error in six is 0 (a flat node's), the others spread over five orders of
            // magnitude (small ones make `a c` fall under `near`).
            let errs = lanes.map(|(.., e)| {
                if e < 0.15 { 0.0 } else { scale * 0.05 * 10f32.powf(-5.0 * e) }
            });
            let merges = merges & !splits;
            let children = ChildViews { views: views.into(), errs, screen: [0.0; 4] };
            // The reference, and the reference without rotation's shares (every lever whole).
            let mut four = Bounds::default();
            let (mut scalar, mut whole) = (Reference::default(), Reference::default());
            if due {
                four.due_now();
                scalar.due = true;
                whole.due = true;
            }
            four.checks(&view, &children, (splits, merges), k);
            // The magnitudes a lane's slack is computed from, the largest of the checked lanes.
            let mut magnitude = 0.0f64;
            for i in 0..4 {
                let (z, r) = (views[i].depth.abs() as f64, views[i].r_max as f64);
                let reach = errs[i] as f64 * k.0.max(k.1) * view.off_axis() as f64;
                if splits >> i & 1 != 0 {
                    split_slack(&view, &views[i], errs[i], k.0, true, &mut scalar);
                    split_slack(&view, &views[i], errs[i], k.0, false, &mut whole);
                } else if merges >> i & 1 != 0 {
                    merge_slack(&view, &views[i], errs[i], k.1, true, &mut scalar);
                    merge_slack(&view, &views[i], errs[i], k.1, false, &mut whole);
                } else {
                    continue;
                }
                magnitude = magnitude.max(z + r + reach + view.near() as f64);
            }
            // What the frustum margin bounds, and how far, is exact.
            prop_assert_eq!(four.margin, scalar.smallest_margin());
            // The depth slack: no larger, and smaller by little more than the guard.
            let slack = SLACK_GUARD as f64 * magnitude;
            let depth = scalar.smallest_depth();
            prop_assert!(four.depth <= depth, "{:?} {:?}", four, scalar);
            prop_assert!(four.depth >= depth - 2.0 * slack - 1e-9, "{:?} {:?} {}", four, scalar, slack);
            // Due no later at any motion: `T + lever K >= slack` meets both axes no further out.
            match (four.filing(), scalar.filing()) {
                (Some((s4, l4)), Some((s, l))) => {
                    prop_assert!(s4 <= s, "{s4} {s}");
                    // (Where the margin binds, both sides are the same ratio, up to rounding.)
                    prop_assert!(s4 * l <= s * l4 * (1.0 + 1e-12), "{s4} {l4} {s} {l}");
                    // And no longer than whole levers need, beyond the guards: a lane's ratio of
                    // the group's slack to its own grows by at most its slack's guard, relative.
                    if s4 > 0.0 {
                        let (_, lw) = whole.filing().unwrap_or((0.0, 0.0));
                        let guarded = 1.001 + 4.0 * slack / s4;
                        prop_assert!(
                            l4 <= lw * guarded + LEVER_GUARD.sqrt() as f64 * whole.along() * 2.0 + 1e-6,
                            "{s4} {l4} {s} {lw}"
                        );
                    }
                }
                // Filed where the reference needs no filing: due sooner, never later.
                (Some(_), None) | (None, None) => {}
                (None, Some(f)) => prop_assert!(false, "not filed, the reference files {f:?}"),
            }
        }
    }
}
