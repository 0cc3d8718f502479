//! The LOD side of one session, without I/O: its cut or tile set, its engine state and the
//! delta bodies it produces (DESIGN.md section 6, "Updates" and "Budget"). The session flow
//! around it (window, budget tokens, resume, closes) is the same for both streams.
//!
//! A tile session runs [`TileSession`] (budgeted or not, the same code).
//!
//! Without a bandwidth budget a session runs the event-driven [`VertexSession`], which yields
//! the deltas of the paper's full top-down pass (paper 000, section 3.4). With a budget it
//! keeps a plain [`Cut`] and runs [`budget::budgeted_update`]: merges, then the splits that
//! remove the most screen error per byte, until the delta's byte allowance is spent. A budgeted
//! delta that leaves splits for later is marked incomplete, and the session sends the rest as
//! the budget refills, without a new pose.

use crate::lod::tile::TileEngine;
use crate::lod::tile::session::TileSession;
use crate::lod::vertex::budget;
use crate::lod::vertex::session::VertexSession;
use crate::lod::vertex::{LodParams, UpdateStats, VertexEngine};
use crate::store::Store;
use relief_proto::cut::Cut;
use relief_proto::delta::{BodyModels, Known};
use relief_proto::view::{Camera, Lens, ViewState};

/// A vertex update that evaluates at most this many nodes is cheap: under a millisecond, and
/// running it on the async worker saves the two thread switches of a trip to a blocking thread.
/// A session on the embedded crop evaluates about 800 nodes an update in 0.1 ms; in a load sweep
/// on one core the trips cost a quarter of the throughput (1,000 sessions: 6,880 deltas a second
/// through the blocking pool, 9,367 inline; a limit of 2,048 gave 9,309). The count is the work
/// itself: a wall-clock time would grow on a loaded server and send sessions back to the
/// blocking pool just when the switches hurt most.
const CHEAP_EVALUATIONS: u64 = 8192;
/// Consecutive cheap updates after which a vertex session's next update runs on the async
/// worker. A camera jump can make one update dear; it then costs the worker that one update, and
/// the session goes back to the blocking pool until it has again been cheap this many times.
const CHEAP_STREAK: u32 = 8;
/// A vertex update that evaluated more than this many nodes (tens of milliseconds), or a
/// budgeted session whose cut holds more interior nodes (each update passes over the whole cut),
/// makes the session's next update expensive: it runs on the background pool, at a lower
/// priority, so that a few sessions with huge viewports cannot hold up everyone else's.
const HEAVY_EVALUATIONS: u64 = 1 << 18;

/// How a session's cut is kept.
enum Lod {
    /// Unbudgeted: the event-driven session.
    Coherent(Box<VertexSession>),
    /// Budgeted: the cut alone, updated by the budgeted full pass.
    Budgeted(Cut),
    /// The tile stream.
    Tiles(TileSession),
}

/// One session's LOD state.
pub struct Stream {
    /// The cut and its engine state.
    lod: Lod,
    /// Tau and hysteresis.
    params: LodParams,
    /// The client's viewport.
    lens: Lens,
    /// Sequence number of the last delta produced.
    seq: u64,
    /// The connection's delta-body models (docs/protocol.md section 5.2), for a vertex stream.
    models: Option<Box<BodyModels>>,
    /// Consecutive event-driven vertex updates that evaluated at most [`CHEAP_EVALUATIONS`]
    /// nodes, which [`Stream::is_cheap`] reads.
    cheap_streak: u32,
    /// Nodes the last event-driven vertex update evaluated, which [`Stream::is_heavy`] reads.
    last_evaluations: u64,
}

/// One produced delta.
pub struct Produced {
    /// Sequence number of the delta in the session.
    pub seq: u64,
    /// Digest of the cut or tile set after it.
    pub digest: u64,
    /// Whether the cut now meets tau for the camera (always true without a budget).
    pub complete: bool,
    /// The packed body.
    pub body: Vec<u8>,
    /// What changed: splits and merges of the vertex stream, tiles added and removed.
    pub changes: usize,
}

impl Stream {
    /// A stream continuing from `cut`; `budgeted` picks the budgeted engine. The coherent
    /// engine stops splitting at `max_interior` interior nodes; the budgeted one grows by at
    /// most one delta's allowance per update. Either way [`Stream::over_limit`] tells the
    /// session to end.
    pub fn new(
        engine: &VertexEngine<'_>,
        cut: &Cut,
        params: LodParams,
        lens: Lens,
        budgeted: bool,
        max_interior: usize,
    ) -> Stream {
        let lod = if budgeted {
            Lod::Budgeted(cut.clone())
        } else {
            let mut s = VertexSession::from_cut(engine, cut);
            s.set_max_interior(max_interior);
            Lod::Coherent(Box::new(s))
        };
        Stream {
            lod,
            params,
            lens,
            seq: 0,
            models: Some(Box::default()),
            cheap_streak: 0,
            last_evaluations: 0,
        }
    }

    /// A tile stream continuing from `session`.
    pub fn tiles(session: TileSession, lens: Lens) -> Stream {
        Stream {
            lod: Lod::Tiles(session),
            params: LodParams::default(),
            lens,
            seq: 0,
            models: None,
            cheap_streak: 0,
            last_evaluations: 0,
        }
    }

    /// An empty stream that holds a session's place while its state is on a worker thread.
    pub fn placeholder() -> Stream {
        Stream {
            lod: Lod::Budgeted(Cut::default()),
            params: LodParams::default(),
            lens: Lens::STANDARD,
            seq: 0,
            models: None,
            cheap_streak: 0,
            last_evaluations: 0,
        }
    }

    /// The next delta for `camera`, packed; `max_body_bytes` bounds a budgeted delta's body.
    pub fn update(&mut self, store: &Store, camera: &Camera, max_body_bytes: usize) -> Produced {
        self.seq += 1;
        let seq = self.seq;
        let view = ViewState::new(camera, &self.lens);
        let (delta, complete, after) = match &mut self.lod {
            Lod::Tiles(s) => {
                let u = s.update(&TileEngine::new(store), &view, max_body_bytes);
                return Produced {
                    seq,
                    digest: u.digest,
                    complete: u.complete,
                    changes: u.delta.added.len() + u.delta.removed.len(),
                    body: u.delta.encode(),
                };
            }
            Lod::Coherent(s) => {
                let engine = VertexEngine::new(store);
                let mut stats = UpdateStats::default();
                let d = s.update(&engine, &view, &self.params, seq, &mut stats);
                self.last_evaluations = stats.visited;
                self.cheap_streak = if stats.visited <= CHEAP_EVALUATIONS {
                    self.cheap_streak.saturating_add(1)
                } else {
                    0
                };
                (d, true, s.cut_ref())
            }
            Lod::Budgeted(cut) => {
                let engine = VertexEngine::new(store);
                let b = budget::budgeted_update(
                    &engine,
                    cut,
                    &view,
                    &self.params,
                    max_body_bytes,
                    self.models.get_or_insert_with(Box::default),
                    seq,
                );
                (b.delta, b.complete, &*cut)
            }
        };
        let g = store.geometry();
        Produced {
            seq,
            digest: delta.digest,
            complete,
            changes: delta.merges.len() + delta.splits.len(),
            body: delta.pack_body_in(
                &g.shape,
                self.models.get_or_insert_with(Box::default),
                g.z_quantum,
                Known {
                    parents: &VertexEngine::new(store),
                    cut: after,
                },
            ),
        }
    }

    /// Whether the next update is cheap enough to run on the async worker rather than on a
    /// blocking thread: a tile selection always (tens of microseconds, bounded by the pyramid),
    /// an event-driven vertex update once the session's last [`CHEAP_STREAK`] updates each
    /// evaluated at most [`CHEAP_EVALUATIONS`] nodes. A budgeted update is a full pass over the
    /// cut and always goes to a blocking thread.
    pub fn is_cheap(&self) -> bool {
        matches!(self.lod, Lod::Tiles(_)) || self.cheap_streak >= CHEAP_STREAK
    }

    /// Whether the next update is expensive enough to run on the background pool (see
    /// [`HEAVY_EVALUATIONS`]): never for a tile session.
    pub fn is_heavy(&self) -> bool {
        match &self.lod {
            Lod::Coherent(_) => self.last_evaluations > HEAVY_EVALUATIONS,
            Lod::Budgeted(c) => c.interior_count() as u64 > HEAVY_EVALUATIONS,
            Lod::Tiles(_) => false,
        }
    }

    /// The current cut's digest.
    pub fn digest(&self) -> u64 {
        match &self.lod {
            Lod::Coherent(s) => s.digest(),
            Lod::Budgeted(c) => c.digest(),
            Lod::Tiles(s) => s.digest(),
        }
    }

    /// Whether the cut holds at least `max_interior` interior nodes.
    pub fn over_limit(&self, max_interior: usize) -> bool {
        match &self.lod {
            Lod::Coherent(s) => s.at_limit(),
            Lod::Budgeted(c) => c.interior_count() >= max_interior,
            // A tile selection is bounded by the pyramid, which the store bounds.
            Lod::Tiles(_) => false,
        }
    }

    /// Active nodes in the cut.
    pub fn active_count(&self) -> u64 {
        match &self.lod {
            Lod::Coherent(s) => s.active_count(),
            Lod::Budgeted(c) => c.active_count(),
            Lod::Tiles(s) => s.active_count(),
        }
    }

    /// Bytes of memory the state holds.
    pub fn memory_bytes(&self) -> usize {
        let models = self.models.as_ref().map_or(0, |_| size_of::<BodyModels>());
        models
            + match &self.lod {
                Lod::Coherent(s) => s.memory_bytes(),
                Lod::Budgeted(c) => c.memory_bytes(),
                Lod::Tiles(s) => s.memory_bytes(),
            }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lod::vertex::tests::{camera, lens, store};

    #[test]
    fn a_vertex_session_runs_inline_only_after_a_streak_of_cheap_updates() {
        let dir = tempfile::tempdir().unwrap();
        let store = store(dir.path(), 1025, 1025, 7);
        let engine = VertexEngine::new(&store);
        let root = Cut::root(&store.geometry().shape);
        let mut s = Stream::new(&engine, &root, LodParams::default(), lens(), false, 1 << 20);
        // From the root to a low camera's cut: thousands of evaluations.
        let low = camera(1025, 1025, (0.5, 0.5, 0.0, 0.1, 0.2));
        s.update(&store, &low, usize::MAX);
        assert!(!s.is_cheap());
        // At rest an update evaluates nothing: cheap, but inline only after a streak.
        for k in 1..=CHEAP_STREAK {
            assert!(!s.is_cheap(), "inline after {k} cheap updates");
            s.update(&store, &low, usize::MAX);
        }
        assert!(s.is_cheap());
        // A jump far across makes one dear update, and the streak starts again.
        let far = camera(1025, 1025, (0.05, 0.95, 0.0, 0.6, 0.2));
        s.update(&store, &far, usize::MAX);
        assert!(!s.is_cheap());
        // A budgeted session never runs inline, however small its updates.
        let mut b = Stream::new(&engine, &root, LodParams::default(), lens(), true, 1 << 20);
        for _ in 0..=CHEAP_STREAK {
            b.update(&store, &low, 1 << 20);
        }
        assert!(!b.is_cheap());
    }
}
