//! One tile session's state: the split set of its last selection, the client's tile cache as
//! the client keeps it ([`relief_proto::tile::cache`]), and the delta from one selection to the
//! next (DESIGN.md section 6, "Updates" and "Budget").
//!
//! **Delta.** The tiles that leave the active set are removed; those that join are added, each
//! with its mesh and (for sessions that draw patches) its patch blob, or without a body when
//! the client's cache holds it: no tile is sent twice unless the client's cache limit evicted it.
//!
//! **Budget.** With a byte allowance, the delta first applies every merge (the split set becomes
//! its intersection with the target's, which is restricted when both are), then adds the
//! target's splits one at a time, most screen error removed per byte of new children first,
//! each only once its parent and its neighbours' parents are split, so that every delta leaves a
//! restricted selection that covers the terrain once. It stops at the allowance (but always
//! makes one split of progress) and says whether the target was reached.
//!
//! **Parts.** An unbudgeted delta whose bodies would pass [`MAX_DELTA_BODY`] is budgeted at that
//! size, so that it goes out in parts, each a restricted selection, and every message stays
//! under the protocol's 16 MiB limit (`docs/protocol.md` section 2.3). A first view of a fine
//! `tin` mesh at a small tau reaches 19 MB on synthetic:4097.

use super::TileEngine;
use super::bits::TileBits;
use super::select::{SelectStats, Selection};
use relief_proto::msg::{CrackMode, TileStreamParams};
use relief_proto::tile::cache::TileCache;
use relief_proto::tile::delta::{AddedTile, TileBlobs, TileDelta};
use relief_proto::tile::snapshot::restriction_violations;
use relief_proto::tile::{EDGES, TileId};
use relief_proto::view::ViewState;
use std::collections::BinaryHeap;

/// Largest body an update's delta carries where it can, bytes (see "Parts" above).
pub const MAX_DELTA_BODY: usize = 4 << 20;

/// One tile session.
#[derive(Clone, Debug)]
pub struct TileSession {
    /// Split tiles of the selection the client holds.
    split: TileBits,
    /// Active tiles the client holds (none before the first delta).
    active: TileBits,
    /// Active and cached tiles, as the client keeps them.
    cache: TileCache,
    /// What bodies carry.
    crack: CrackMode,
    /// Split threshold, pixels.
    tau: f32,
    /// Merge below `tau * merge_ratio`.
    merge_ratio: f32,
    /// Largest body a delta carries where it can ([`MAX_DELTA_BODY`]).
    max_body: usize,
}

/// One update's outcome.
#[derive(Clone, Debug, Default)]
pub struct TileUpdate {
    /// The delta.
    pub delta: TileDelta,
    /// Digest of the active set after it.
    pub digest: u64,
    /// Whether the selection now meets tau (false while a budget holds splits back).
    pub complete: bool,
    /// The selection's counters.
    pub stats: SelectStats,
}

/// Orders candidate splits by priority (screen error per byte), highest first.
#[derive(PartialEq)]
struct Candidate(f32, u32);

impl Eq for Candidate {}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Candidate {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&o.0).then(o.1.cmp(&self.1))
    }
}

impl TileSession {
    /// A new session over a pyramid of `tile_count` tiles: the client holds nothing, and the
    /// first delta adds the tiles.
    pub fn new(
        tile_count: u32,
        params: TileStreamParams,
        tau: f32,
        merge_ratio: f32,
    ) -> TileSession {
        TileSession {
            split: TileBits::new(tile_count),
            active: TileBits::new(tile_count),
            cache: TileCache::new(params.cache_tiles),
            crack: params.crack,
            tau,
            merge_ratio,
            max_body: MAX_DELTA_BODY,
        }
    }

    /// The same session with deltas in parts of at most `bytes` (tests; the server keeps
    /// [`MAX_DELTA_BODY`]).
    pub fn with_max_body(mut self, bytes: usize) -> TileSession {
        self.max_body = bytes;
        self
    }

    /// A session resumed from the client's active set (from its snapshot: it covers the
    /// terrain once). The client keeps only its active tiles across a resume. Refuses a set
    /// that is not restricted.
    pub fn resume(
        engine: &TileEngine<'_>,
        params: TileStreamParams,
        tau: f32,
        merge_ratio: f32,
        active: &[u32],
    ) -> Result<TileSession, String> {
        let shape = engine.shape();
        let bad = restriction_violations(shape, active);
        if bad > 0 {
            return Err(format!(
                "the snapshot's tiles are not restricted ({bad} neighbours differ by more than one level)"
            ));
        }
        let mut s = TileSession::new(shape.tile_count(), params, tau, merge_ratio);
        for i in relief_proto::tile::snapshot::split_set(shape, active) {
            s.split.insert(i);
        }
        for &i in active {
            s.active.insert(i);
        }
        s.cache
            .apply(&[], active, |_| true)
            .map_err(|e| e.to_string())?;
        Ok(s)
    }

    /// Digest of the active set the client holds.
    pub fn digest(&self) -> u64 {
        self.cache.digest()
    }

    /// Active tiles.
    pub fn active_count(&self) -> u64 {
        self.cache.active_count() as u64
    }

    /// The active tiles, ascending.
    pub fn active(&self) -> Vec<u32> {
        self.active.iter().collect()
    }

    /// The split set.
    pub fn split(&self) -> &TileBits {
        &self.split
    }

    /// Bytes of memory the state holds (approximately).
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.split.memory_bytes()
            + self.active.memory_bytes()
            + self.cache.memory_bytes()
    }

    /// Wire bytes of adding tile `i` now.
    fn cost(&self, engine: &TileEngine<'_>, i: u32) -> usize {
        if self.cache.holds(i) {
            return 3;
        }
        let r = engine.record(i);
        let patches = if self.crack == CrackMode::Patches {
            r.patch_len as usize
        } else {
            0
        };
        r.mesh_len as usize + patches + 8
    }

    /// The next delta for `view`, its body within `allowance` bytes where it can be
    /// (`usize::MAX`: unbudgeted).
    pub fn update(
        &mut self,
        engine: &TileEngine<'_>,
        view: &ViewState,
        allowance: usize,
    ) -> TileUpdate {
        let budgeted = allowance < self.max_body;
        let sel = engine.select(view, self.tau, self.merge_ratio, &self.split, budgeted);
        let (sel, active) = if budgeted {
            (sel, None)
        } else {
            // The unbudgeted target's active set serves both the size check and the delta.
            let active = engine.active_of(&sel.split);
            if self.added_cost(engine, &active) <= self.max_body {
                (sel, Some(active))
            } else {
                let sel = engine.select(view, self.tau, self.merge_ratio, &self.split, true);
                (sel, None)
            }
        };
        let stats = sel.stats;
        let (delta, complete) = match active {
            Some(active) => (self.advance_to(engine, sel.split, active), true),
            None => {
                let (split, complete) = self.budgeted(engine, &sel, allowance.min(self.max_body));
                (self.advance(engine, split), complete)
            }
        };
        TileUpdate {
            delta,
            digest: self.cache.digest(),
            complete,
            stats,
        }
    }

    /// Wire bytes of the tiles that moving to active set `active` adds.
    fn added_cost(&self, engine: &TileEngine<'_>, active: &TileBits) -> usize {
        active
            .minus(&self.active)
            .map(|t| self.cost(engine, t))
            .sum()
    }

    /// Moves the client to split set `split`: the delta, with bodies for what it lacks.
    pub fn advance(&mut self, engine: &TileEngine<'_>, split: TileBits) -> TileDelta {
        let new = engine.active_of(&split);
        self.advance_to(engine, split, new)
    }

    /// [`TileSession::advance`] with the split set's active set `new` already known.
    fn advance_to(&mut self, engine: &TileEngine<'_>, split: TileBits, new: TileBits) -> TileDelta {
        let removed: Vec<u32> = self.active.minus(&new).collect();
        let added_ids: Vec<u32> = new.minus(&self.active).collect();
        let added: Vec<AddedTile> = added_ids
            .iter()
            .map(|&t| AddedTile {
                tile: t,
                body: (!self.cache.holds(t)).then(|| {
                    let (mesh, patches) = engine.store().tile_blobs(t);
                    TileBlobs {
                        mesh: mesh.to_vec(),
                        patches: if self.crack == CrackMode::Patches {
                            patches.to_vec()
                        } else {
                            Vec::new()
                        },
                    }
                }),
            })
            .collect();
        // The delta is computed from this very state, so it always applies.
        let _ = self
            .cache
            .apply(&removed, &added_ids, |i| added[i].body.is_some());
        self.split = split;
        self.active = new;
        TileDelta { removed, added }
    }

    /// The budgeted split set: all merges, then the best splits within `allowance`.
    fn budgeted(
        &self,
        engine: &TileEngine<'_>,
        sel: &Selection,
        allowance: usize,
    ) -> (TileBits, bool) {
        let shape = engine.shape();
        let target = &sel.split;
        let mut p = self.split.and(target);
        let mut spent = self.added_cost(engine, &engine.active_of(&p));
        let eligible = |p: &TileBits, t: TileId| {
            let i = shape.index(t);
            target.contains(i)
                && !p.contains(i)
                && t.parent().is_none_or(|q| p.contains(shape.index(q)))
                && EDGES.iter().all(|&e| {
                    shape
                        .neighbour(t, e)
                        .and_then(|n| n.parent())
                        .is_none_or(|q| p.contains(shape.index(q)))
                })
        };
        let children_cost = |t: TileId| -> usize {
            shape
                .children(t)
                .map(|c| self.cost(engine, shape.index(c)))
                .sum()
        };
        let prio = |t: TileId| sel.sse_of(shape.index(t)) / children_cost(t).max(1) as f32;
        let mut heap = BinaryHeap::new();
        for i in target.minus(&p) {
            if let Some(t) = shape.tile(i)
                && eligible(&p, t)
            {
                heap.push(Candidate(prio(t), i));
            }
        }
        let mut progressed = false;
        while let Some(Candidate(_, i)) = heap.pop() {
            let Some(t) = shape.tile(i) else { continue };
            if p.contains(i) {
                continue;
            }
            // A split replaces the tile by its children.
            let c = children_cost(t);
            if progressed && spent + c > allowance {
                break;
            }
            p.insert(i);
            spent += c;
            progressed = true;
            let around = std::iter::once(t)
                .chain(EDGES.iter().filter_map(|&e| shape.neighbour(t, e)))
                .flat_map(|n| shape.children(n).collect::<Vec<_>>());
            for n in around {
                if eligible(&p, n) {
                    heap.push(Candidate(prio(n), shape.index(n)));
                }
            }
        }
        let complete = p == *target;
        (p, complete)
    }
}
