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
//! by angle `a` moves a point at distance `D` by at most `D * a`. So the group is filed in the
//! band of its distance, and each band keeps an odometer that advances by the eye's travel plus
//! the band's distance times the rotation; a group is due when its band's odometer passes its key.
//!
//! Due groups are processed shallowest first, as in the full pass. Splitting a child examines the
//! child's own new group at once (refinement goes as deep as the pose needs); a merge files the
//! grandparent's group as due at the next update (coarsening moves one level per update).
//!
//! Each band's queue is a timing wheel of buckets of node indices. State per session: the cut's
//! interior set, whose value per node is its packed due key and band, and the wheels' entries;
//! all proportional to the number of interior nodes (about a third of the active ones).

use super::{LodParams, UpdateStats, VertexEngine};
use glam::Vec3;
use relief_proto::cut::Cut;
use relief_proto::delta::Delta;
use relief_proto::tree::NodeId;
use relief_proto::view::{BoxView, ViewState};
use rustc_hash::FxHashMap;

/// Distance bands: band `b` holds groups whose boxes lie within `2^b` metres of the eye.
const BANDS: usize = 48;
/// Buckets per band's wheel; a bucket spans `2^b / BUCKETS_PER_DISTANCE` metres of odometer.
const WHEEL: u64 = 256;
const BUCKETS_PER_DISTANCE: f64 = 64.0;
/// Safety factor on every slack, against rounding in the bounds.
const SLACK_SAFETY: f64 = 0.98;
/// A rotation moves any vector by at most this factor times the largest move of the basis vectors.
const ROTATION_FACTOR: f64 = 1.25;

/// An interior node's schedule, packed in 32 bits: the due key (f32, rounded down to a multiple
/// of 64 units in the last place) with the band in the low 6 bits.
fn pack(key: f64, band: usize) -> u32 {
    let k = key.max(0.0) as f32;
    let mut bits = k.to_bits();
    if k as f64 > key.max(0.0) {
        bits = bits.saturating_sub(1);
    }
    (bits & !63) | band as u32
}

fn unpack(v: u32) -> (f64, usize) {
    (f32::from_bits(v & !63) as f64, (v & 63) as usize)
}

/// One band's timing wheel: node indices bucketed by due odometer reading.
#[derive(Default)]
struct Wheel {
    /// The occupied ones of `WHEEL` buckets, by slot; slot `i` holds keys in
    /// `[(cursor - cursor % WHEEL + i) * width, ...)`. Sparse, because most slots of most bands
    /// are empty and a dense array of them was most of a small session's memory.
    buckets: FxHashMap<u32, Vec<u32>>,
    /// Keys beyond the wheel's horizon, filed again each time the wheel turns.
    overflow: Vec<u32>,
    /// The bucket (absolute index) drained last.
    cursor: u64,
}

/// A session's cut plus the schedule of its next checks.
pub struct VertexSession {
    /// The cut; each interior node carries its packed schedule.
    cut: Cut<u32>,
    /// One wheel per distance band.
    wheels: Vec<Wheel>,
    /// Per band: the odometer, metres of camera-relative motion since the session began.
    odometers: Vec<f64>,
    /// The previous update's eye and view basis, to measure the camera's motion.
    previous: Option<(Vec3, [Vec3; 3])>,
    /// Splits stop once the cut holds this many interior nodes: a guard on server memory
    /// against a client asking for more detail than the server will hold (see
    /// [`VertexSession::set_max_interior`]).
    max_interior: usize,
}

fn width(band: usize) -> f64 {
    (band as f64).exp2() / BUCKETS_PER_DISTANCE
}

impl VertexSession {
    /// A session whose initial cut is computed for `view` (all groups due at the first update).
    pub fn new(engine: &VertexEngine<'_>, view: &ViewState, p: &LodParams) -> VertexSession {
        let cut = engine.initial_cut(view, p, &mut UpdateStats::default());
        VertexSession::from_cut(engine, &cut)
    }

    /// A session continuing from `cut` (all groups due at the first update).
    pub fn from_cut(engine: &VertexEngine<'_>, cut: &Cut) -> VertexSession {
        let mut s = VertexSession {
            cut: cut.with_values(),
            wheels: (0..BANDS).map(|_| Wheel::default()).collect(),
            odometers: vec![0.0; BANDS],
            previous: None,
            max_interior: usize::MAX,
        };
        let interior: Vec<u64> = s.cut.interior_indices().collect();
        for i in interior {
            if let Some(n) = engine.geometry().shape.node(i) {
                s.file(engine, n, 0.0, 0);
            }
        }
        s
    }

    /// The current cut.
    pub fn cut(&self) -> Cut {
        self.cut.with_values()
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
        let queued: usize = self
            .wheels
            .iter()
            .map(|w| {
                (w.buckets.values().map(Vec::capacity).sum::<usize>() + w.overflow.capacity()) * 4
                    + w.buckets.capacity() * (std::mem::size_of::<(u32, Vec<u32>)>() + 1)
            })
            .sum();
        self.cut.memory_bytes() + queued + std::mem::size_of::<Self>()
    }

    /// Files `node`'s group with `slack` metres of motion before it is due, in `band`.
    fn file(&mut self, engine: &VertexEngine<'_>, node: NodeId, slack: f64, band: usize) {
        let packed = pack(self.odometers[band] + slack, band);
        self.cut.set_value(&engine.geometry().shape, node, packed);
        let idx = engine.geometry().shape.index(node) as u32;
        self.enqueue(idx, packed);
    }

    /// Puts `idx` in the bucket of its packed key.
    fn enqueue(&mut self, idx: u32, packed: u32) {
        let (key, band) = unpack(packed);
        let wheel = &mut self.wheels[band];
        let at = ((key / width(band)) as u64).max(wheel.cursor);
        if at - wheel.cursor < WHEEL {
            wheel
                .buckets
                .entry((at % WHEEL) as u32)
                .or_default()
                .push(idx);
        } else {
            wheel.overflow.push(idx);
        }
    }

    /// Advances the odometers by the camera's motion since the last update.
    fn advance(&mut self, view: &ViewState) {
        let eye = view.eye();
        let basis = view.basis();
        if let Some((pe, pb)) = self.previous {
            let travel = (eye - pe).length() as f64;
            let turn = basis
                .iter()
                .zip(pb.iter())
                .map(|(a, b)| 2.0 * ((*a - *b).length() as f64 / 2.0).min(1.0).asin())
                .fold(0.0, f64::max)
                * ROTATION_FACTOR;
            for (b, o) in self.odometers.iter_mut().enumerate() {
                *o += travel + (b as f64).exp2() * turn;
            }
        }
        self.previous = Some((eye, basis));
    }

    /// Drains every band's due buckets: returns the due interior nodes' indices.
    fn due(&mut self) -> Vec<u32> {
        let mut due = Vec::new();
        let mut later = Vec::new();
        for band in 0..BANDS {
            let now = self.odometers[band];
            let wheel = &mut self.wheels[band];
            let target = (now / width(band)) as u64;
            let first = wheel.cursor;
            if wheel.buckets.is_empty() && wheel.overflow.is_empty() {
                // Nothing filed: the wheel turns to the odometer with nothing to drain.
                wheel.cursor = target.max(first);
                continue;
            }
            let last = target.min(first + WHEEL - 1);
            for at in first..=last {
                if let Some(bucket) = wheel.buckets.remove(&((at % WHEEL) as u32)) {
                    later.extend(bucket.into_iter().map(|i| (i, band)));
                }
            }
            if target / WHEEL != first / WHEEL || target >= first + WHEEL {
                later.extend(wheel.overflow.drain(..).map(|i| (i, band)));
            }
            wheel.cursor = target.max(first);
            for (idx, b) in later.drain(..) {
                // Stale entries (merged nodes, re-filed groups in another band) are dropped.
                let Some(packed) = self.cut.value_at(idx) else {
                    continue;
                };
                let (key, kb) = unpack(packed);
                if kb != b {
                    continue;
                }
                if key <= now {
                    due.push(idx);
                } else {
                    self.enqueue(idx, packed);
                }
            }
        }
        // Shallowest first (dense indices grow with depth), as the paper's top-down pass.
        due.sort_unstable();
        due.dedup();
        due
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
        self.advance(view);
        let mut delta = Delta {
            seq,
            ..Delta::default()
        };
        if !self.cut.is_interior(shape, NodeId::ROOT) {
            stats.visited += 1;
            if engine.screen_error(view, NodeId::ROOT) > p.tau {
                let _ = self.cut.split(shape, NodeId::ROOT);
                delta.splits.push(engine.split_payload(NodeId::ROOT));
                self.process(engine, view, p, NodeId::ROOT, &mut delta, stats);
                delta.canonicalize();
            }
            delta.digest = self.cut.digest();
            return delta;
        }
        for idx in self.due() {
            let Some(node) = shape.node(idx as u64) else {
                continue;
            };
            self.process(engine, view, p, node, &mut delta, stats);
        }
        delta.canonicalize();
        delta.digest = self.cut.digest();
        delta
    }

    /// Examines the group of interior node `node` (the caller knows it is interior).
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
        // Each child with whether it is interior: looked up once, used twice.
        let mut kids = [(NodeId::ROOT, false); 4];
        let mut n = 0;
        for (_, c) in shape.children(node) {
            kids[n] = (c, self.cut.is_interior(shape, c));
            n += 1;
        }
        let kids = &kids[..n];
        let all_active = kids.iter().all(|&(_, interior)| !interior);
        let (bv, err) = engine.box_view(view, node);
        let mut slack = f64::INFINITY;
        if all_active {
            stats.visited += 1;
            let e = view.error_of(&bv, err);
            if e < p.tau * p.merge_ratio {
                self.cut.merge_interior(shape, node);
                delta.merges.push(node);
                if let Some(parent) = node.parent() {
                    self.file(engine, parent, 0.0, 0);
                }
                return;
            }
            slack = merge_slack(view, &bv, err, p.tau * p.merge_ratio);
        }
        for &(c, interior) in kids {
            if interior || shape.is_leaf(c) {
                continue;
            }
            stats.visited += 1;
            let (cv, cerr) = engine.box_view(view, c);
            if view.error_of(&cv, cerr) > p.tau && !self.at_limit() {
                self.cut.split_active(shape, c, 0);
                delta.splits.push(engine.split_payload(c));
                // Refine as deep as this pose needs, as the full pass does.
                self.process(engine, view, p, c, delta, stats);
            } else {
                slack = slack.min(split_slack(view, &cv, cerr, p.tau));
            }
        }
        let slack = (slack * SLACK_SAFETY).max(0.0);
        let reach = bv.d_max as f64 + slack;
        let band = (reach.max(1.0).log2().ceil() as usize).min(BANDS - 1);
        self.file(engine, node, slack, band);
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
