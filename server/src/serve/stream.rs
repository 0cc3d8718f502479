//! The LOD side of one session, without I/O: its cut, its engine state and the deltas it
//! produces (DESIGN.md section 6, "Updates" and "Budget").
//!
//! Without a bandwidth budget a session runs the event-driven [`VertexSession`], which yields
//! the deltas of the paper's full top-down pass (paper 000, section 3.4). With a budget it
//! keeps a plain [`Cut`] and runs [`budget::budgeted_update`]: merges, then the splits that
//! remove the most screen error per byte, until the delta's byte allowance is spent. A budgeted
//! delta that leaves splits for later is marked incomplete, and the session sends the rest as
//! the budget refills, without a new pose.

use crate::lod::budget;
use crate::lod::session::VertexSession;
use crate::lod::vertex::{LodParams, UpdateStats, VertexEngine};
use relief_proto::cut::Cut;
use relief_proto::delta::Delta;
use relief_proto::view::{Camera, Lens, ViewState};

/// How a session's cut is kept.
enum Lod {
    /// Unbudgeted: the event-driven session.
    Coherent(VertexSession),
    /// Budgeted: the cut alone, updated by the budgeted full pass.
    Budgeted(Cut),
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
}

/// One produced delta.
pub struct Produced {
    /// The delta, canonical, with its digest.
    pub delta: Delta,
    /// Whether the cut now meets tau for the camera (always true without a budget).
    pub complete: bool,
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
            Lod::Coherent(s)
        };
        Stream {
            lod,
            params,
            lens,
            seq: 0,
        }
    }

    /// An empty stream that holds a session's place while its state is on a worker thread.
    pub fn placeholder() -> Stream {
        Stream {
            lod: Lod::Budgeted(Cut::default()),
            params: LodParams::default(),
            lens: Lens::STANDARD,
            seq: 0,
        }
    }

    /// The next delta for `camera`; `max_body_bytes` bounds a budgeted delta's body.
    pub fn update(
        &mut self,
        engine: &VertexEngine<'_>,
        camera: &Camera,
        max_body_bytes: usize,
    ) -> Produced {
        self.seq += 1;
        let view = ViewState::new(camera, &self.lens);
        match &mut self.lod {
            Lod::Coherent(s) => Produced {
                delta: s.update(
                    engine,
                    &view,
                    &self.params,
                    self.seq,
                    &mut UpdateStats::default(),
                ),
                complete: true,
            },
            Lod::Budgeted(cut) => {
                let b = budget::budgeted_update(
                    engine,
                    cut,
                    &view,
                    &self.params,
                    max_body_bytes,
                    self.seq,
                );
                Produced {
                    delta: b.delta,
                    complete: b.complete,
                }
            }
        }
    }

    /// The current cut's digest.
    pub fn digest(&self) -> u64 {
        match &self.lod {
            Lod::Coherent(s) => s.digest(),
            Lod::Budgeted(c) => c.digest(),
        }
    }

    /// Whether the cut holds at least `max_interior` interior nodes.
    pub fn over_limit(&self, max_interior: usize) -> bool {
        match &self.lod {
            Lod::Coherent(s) => s.at_limit(),
            Lod::Budgeted(c) => c.interior_count() >= max_interior,
        }
    }

    /// Active nodes in the cut.
    pub fn active_count(&self) -> u64 {
        match &self.lod {
            Lod::Coherent(s) => s.active_count(),
            Lod::Budgeted(c) => c.active_count(),
        }
    }

    /// Bytes of memory the state holds.
    pub fn memory_bytes(&self) -> usize {
        match &self.lod {
            Lod::Coherent(s) => s.memory_bytes(),
            Lod::Budgeted(c) => c.memory_bytes(),
        }
    }
}
