//! Active tile sets as resume snapshots: the vertex stream's [`Snapshot`] encoding applied to
//! the tile pyramid. Walk the pyramid depth first from the root tile, children in
//! [`crate::tree::NodeId::child`] order, descending only into split tiles; every visited tile
//! above the finest level gives one bit, 1 if it is split, 0 if it is active. Bits fill bytes
//! from the least significant bit up; the digest is [`super::cache::set_digest`] of the set.

use super::cache::set_digest;
use super::{EDGES, Edge, TileId, TileShape};
use crate::snapshot::{Snapshot, SnapshotError};
use rustc_hash::FxHashSet;

/// The split tiles of an active set: every strict ancestor of an active tile.
pub fn split_set(shape: &TileShape, active: &[u32]) -> FxHashSet<u32> {
    let mut split = FxHashSet::default();
    for &i in active {
        let Some(mut t) = shape.tile(i) else { continue };
        while let Some(p) = t.parent() {
            if !split.insert(shape.index(p)) {
                break;
            }
            t = p;
        }
    }
    split
}

/// The snapshot of the active set `active` (dense indices).
pub fn snapshot_of(shape: &TileShape, active: &[u32]) -> Snapshot {
    let split = split_set(shape, active);
    let mut bits = Vec::new();
    let mut n = 0usize;
    let mut stack = vec![TileId::ROOT];
    while let Some(t) = stack.pop() {
        if shape.is_leaf(t) {
            continue;
        }
        if n.is_multiple_of(8) {
            bits.push(0);
        }
        if split.contains(&shape.index(t)) {
            bits[n / 8] |= 1 << (n % 8);
            let children: Vec<TileId> = shape.children(t).collect();
            stack.extend(children.into_iter().rev());
        }
        n += 1;
    }
    Snapshot {
        digest: set_digest(active.iter().copied()),
        bits,
    }
}

/// The active set a snapshot describes, ascending; refuses more than `max_tiles` active tiles,
/// malformed bits and digest mismatches.
pub fn active_of(
    shape: &TileShape,
    snap: &Snapshot,
    max_tiles: usize,
) -> Result<Vec<u32>, SnapshotError> {
    let total = snap.bits.len() * 8;
    let mut at = 0usize;
    let mut active = Vec::new();
    let mut stack = vec![TileId::ROOT];
    while let Some(t) = stack.pop() {
        let split = if shape.is_leaf(t) {
            false
        } else {
            if at >= total {
                return Err(SnapshotError::Truncated(total));
            }
            let bit = snap.bits[at / 8] >> (at % 8) & 1;
            at += 1;
            bit == 1
        };
        if split {
            let children: Vec<TileId> = shape.children(t).collect();
            stack.extend(children.into_iter().rev());
        } else {
            active.push(shape.index(t));
            if active.len() > max_tiles {
                return Err(SnapshotError::TooLarge(max_tiles));
            }
        }
    }
    let rest = total - at;
    if rest >= 8 || (!at.is_multiple_of(8) && snap.bits[at / 8] >> (at % 8) != 0) {
        return Err(SnapshotError::Trailing(rest));
    }
    let ours = set_digest(active.iter().copied());
    if ours != snap.digest {
        return Err(SnapshotError::Digest {
            ours,
            theirs: snap.digest,
        });
    }
    active.sort_unstable();
    Ok(active)
}

/// Pairs of edge-adjacent active tiles whose levels differ by more than one: 0 for a
/// restricted set (paper 001, section 1). `active` must cover the terrain once.
pub fn restriction_violations(shape: &TileShape, active: &[u32]) -> usize {
    let split = split_set(shape, active);
    let mut bad = 0;
    for &i in &split {
        let Some(t) = shape.tile(i) else { continue };
        // A split tile's same-level neighbours must exist in the tree: their parents split.
        for e in EDGES {
            if let Some(n) = shape.neighbour(t, e)
                && let Some(p) = n.parent()
                && !split.contains(&shape.index(p))
            {
                bad += 1;
            }
        }
    }
    bad
}

/// The edges of `t` along which `t` touches a tile of the active set that is exactly one level
/// coarser (for statistics and tests).
pub fn coarser_edges(shape: &TileShape, t: TileId, active: &FxHashSet<u32>) -> Vec<Edge> {
    EDGES
        .into_iter()
        .filter(|&e| {
            shape
                .neighbour(t, e)
                .and_then(|n| n.parent())
                .is_some_and(|p| active.contains(&shape.index(p)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snapshots_round_trip_and_catch_restriction() {
        let s = TileShape::new(300, 200, 16).unwrap();
        // Split the root, its first child and that one's north-east child.
        let root = TileId::ROOT;
        let c0 = root.child(0);
        let mut split = vec![root, c0, c0.child(1)];
        split.retain(|t| s.contains(*t));
        let split_idx: FxHashSet<u32> = split.iter().map(|t| s.index(*t)).collect();
        let mut active = Vec::new();
        for &t in &split {
            for c in s.children(t) {
                if !split_idx.contains(&s.index(c)) {
                    active.push(s.index(c));
                }
            }
        }
        active.sort_unstable();
        let snap = snapshot_of(&s, &active);
        assert_eq!(active_of(&s, &snap, 1000).unwrap(), active);
        assert!(matches!(
            active_of(&s, &snap, 2),
            Err(SnapshotError::TooLarge(2))
        ));
        let mut bad = snap.clone();
        bad.digest ^= 1;
        assert!(matches!(
            active_of(&s, &bad, 1000),
            Err(SnapshotError::Digest { .. })
        ));
        // c0.child(1) is split while its east neighbour (level 1) is not: two levels apart.
        assert!(restriction_violations(&s, &active) > 0);
    }
}
