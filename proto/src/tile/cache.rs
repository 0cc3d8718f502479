//! The active tile set, its digest, and the client's tile cache, kept identically by both ends.
//!
//! A client caches the tiles it was sent, up to `limit` tiles in all (the active ones included),
//! as its hello says. Both ends apply every delta the same way: remove the delta's removed tiles
//! (they become cached, newest last), add its added tiles (from the delta's bodies or from the
//! cache), then evict the cached tiles that were deactivated longest ago while more than `limit`
//! tiles are held. Active tiles are never evicted. So the server knows exactly which tiles the
//! client holds and sends a tile's body only when the client does not: never twice, unless the
//! limit evicted it. The digest is the wrapping sum of [`node_hash`] of the active tiles' dense
//! indices, as for the vertex stream's cut.

use crate::cut::node_hash;
use rustc_hash::FxHashMap;
use std::collections::BTreeMap;

/// A delta that does not apply to the tile set.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum TileSetError {
    /// A removed tile is not active.
    #[error("tile {0} is removed but is not active")]
    NotActive(u32),
    /// An added tile is already active.
    #[error("tile {0} is added but is already active")]
    AlreadyActive(u32),
    /// An added tile came without a body and is not cached.
    #[error("tile {0} is added from the cache, but the cache does not hold it")]
    NotCached(u32),
}

/// Unlimited cache.
pub const UNLIMITED: u32 = u32::MAX;

/// The active tiles plus the cached ones.
#[derive(Clone, Debug, Default)]
pub struct TileCache {
    /// Most tiles held, active ones included ([`UNLIMITED`] for no limit).
    limit: u32,
    /// Every held tile: `None` when active, else the tick it was deactivated at.
    held: FxHashMap<u32, Option<u64>>,
    /// Cached (inactive) tiles by deactivation tick, oldest first.
    inactive: BTreeMap<u64, u32>,
    /// Deactivations so far: the next tick.
    tick: u64,
    /// Wrapping sum of [`node_hash`] over the active tiles.
    digest: u64,
    /// Active tiles.
    active: usize,
}

impl TileCache {
    /// An empty set with a cache of at most `limit` tiles.
    pub fn new(limit: u32) -> TileCache {
        TileCache {
            limit,
            ..TileCache::default()
        }
    }

    /// The most tiles held.
    pub fn limit(&self) -> u32 {
        self.limit
    }

    /// Whether `tile` is active or cached: a client that holds it needs no body.
    pub fn holds(&self, tile: u32) -> bool {
        self.held.contains_key(&tile)
    }

    /// Whether `tile` is active.
    pub fn is_active(&self, tile: u32) -> bool {
        matches!(self.held.get(&tile), Some(None))
    }

    /// Digest of the active set.
    pub fn digest(&self) -> u64 {
        self.digest
    }

    /// Active tiles.
    pub fn active_count(&self) -> usize {
        self.active
    }

    /// Tiles held, active or cached.
    pub fn held_count(&self) -> usize {
        self.held.len()
    }

    /// The active tiles' dense indices, ascending.
    pub fn active(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self
            .held
            .iter()
            .filter(|(_, s)| s.is_none())
            .map(|(&t, _)| t)
            .collect();
        v.sort_unstable();
        v
    }

    /// Bytes of memory the bookkeeping holds (approximately).
    pub fn memory_bytes(&self) -> usize {
        self.held.capacity() * 24 + self.inactive.len() * 40
    }

    /// Applies a delta: `removed` become cached, `added` become active (`has_body(i)` tells
    /// whether the delta carried added tile `i`'s body). Returns the tiles evicted.
    pub fn apply(
        &mut self,
        removed: &[u32],
        added: &[u32],
        has_body: impl Fn(usize) -> bool,
    ) -> Result<Vec<u32>, TileSetError> {
        for &t in removed {
            if !self.is_active(t) {
                return Err(TileSetError::NotActive(t));
            }
        }
        for (i, &t) in added.iter().enumerate() {
            match self.held.get(&t) {
                Some(None) => return Err(TileSetError::AlreadyActive(t)),
                None if !has_body(i) => return Err(TileSetError::NotCached(t)),
                _ => {}
            }
        }
        for &t in removed {
            self.held.insert(t, Some(self.tick));
            self.inactive.insert(self.tick, t);
            self.tick += 1;
            self.digest = self.digest.wrapping_sub(node_hash(t as u64));
            self.active -= 1;
        }
        for &t in added {
            if let Some(Some(tick)) = self.held.insert(t, None) {
                self.inactive.remove(&tick);
            }
            self.digest = self.digest.wrapping_add(node_hash(t as u64));
            self.active += 1;
        }
        let mut evicted = Vec::new();
        while self.held.len() > self.limit as usize {
            let Some((_, t)) = self.inactive.pop_first() else {
                break;
            };
            self.held.remove(&t);
            evicted.push(t);
        }
        Ok(evicted)
    }
}

/// The digest of an active set given by dense indices.
pub fn set_digest(active: impl IntoIterator<Item = u32>) -> u64 {
    active
        .into_iter()
        .fold(0u64, |d, t| d.wrapping_add(node_hash(t as u64)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evicts_the_longest_inactive_and_never_the_active() {
        let mut c = TileCache::new(3);
        c.apply(&[], &[0], |_| true).unwrap();
        c.apply(&[0], &[1, 2, 3, 4], |_| true).unwrap();
        // Five held, limit three: tile 0 (inactive) goes; active ones stay although over.
        assert!(!c.holds(0));
        assert_eq!(c.active_count(), 4);
        let ev = c.apply(&[1, 2], &[0], |_| true).unwrap();
        assert_eq!(ev, vec![1, 2]);
        assert_eq!((c.held_count(), c.active()), (3, vec![0, 3, 4]));
        assert_eq!(
            c.apply(&[7], &[], |_| true),
            Err(TileSetError::NotActive(7))
        );
        assert_eq!(
            c.apply(&[], &[3], |_| true),
            Err(TileSetError::AlreadyActive(3))
        );
        assert_eq!(
            c.apply(&[], &[9], |_| false),
            Err(TileSetError::NotCached(9))
        );
        assert_eq!(c.digest(), set_digest(c.active()));
    }

    #[test]
    fn an_unlimited_cache_keeps_everything_and_reactivates_without_bodies() {
        let mut c = TileCache::new(UNLIMITED);
        c.apply(&[], &[0], |_| true).unwrap();
        c.apply(&[0], &[1, 2, 3, 4], |_| true).unwrap();
        c.apply(&[1, 2, 3, 4], &[0], |_| false).unwrap();
        assert_eq!(c.active(), vec![0]);
        assert_eq!(c.held_count(), 5);
        assert_eq!(c.digest(), set_digest([0]));
    }
}
