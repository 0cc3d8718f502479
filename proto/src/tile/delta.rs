//! A tile delta's body: the tiles removed from the active set and the tiles added, each added
//! tile with its body or marked as coming from the client's cache ([`super::cache`]).
//!
//! **Layout** (bytes; `varint` is unsigned LEB128, at most 5 bytes here):
//! - `varint` count of removed tiles, then each removed tile's dense index as the `varint`
//!   difference from the previous one (the first from 0), ascending;
//! - `varint` count of added tiles, then for each, ascending by index: the `varint` index
//!   difference, a `varint` mesh blob length (0: the tile comes from the cache, nothing follows),
//!   else a `varint` patch blob length and the two blobs ([`super::body`]).

/// An added tile's blobs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TileBlobs {
    /// The mesh blob.
    pub mesh: Vec<u8>,
    /// The patch blob (empty for sessions that draw skirts or nothing).
    pub patches: Vec<u8>,
}

/// A tile added to the active set.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AddedTile {
    /// Dense index of the tile.
    pub tile: u32,
    /// Its blobs; `None` when the client holds it in its cache.
    pub body: Option<TileBlobs>,
}

/// The change of a session's active tile set.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TileDelta {
    /// Dense indices of the tiles removed, ascending.
    pub removed: Vec<u32>,
    /// The tiles added, ascending by index.
    pub added: Vec<AddedTile>,
}

/// A tile delta body that does not decode.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum TileDeltaError {
    /// The bytes end early.
    #[error("tile delta is truncated")]
    Truncated,
    /// A varint longer than 5 bytes or over 32 bits.
    #[error("tile delta holds a malformed number")]
    Varint,
    /// A tile index outside the pyramid, or not ascending.
    #[error("tile delta names tile {0}, which is not in the pyramid or out of order")]
    Tile(u64),
    /// Bytes remain after the body.
    #[error("tile delta has {0} bytes after its end")]
    Trailing(usize),
}

/// The most tiles [`TileDelta::decode`] reserves room for in a list before decoding them. A
/// count that passes the length check can still claim one tile per byte left, and reserving for
/// all of them made a 2 MiB body of garbage reserve 117 MB before it was refused.
pub const RESERVE_MAX: usize = 1 << 12;

/// Appends `v` as an unsigned LEB128 varint.
pub fn put_varint(out: &mut Vec<u8>, mut v: u32) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Reads an unsigned LEB128 varint of at most 32 bits.
pub fn get_varint(b: &[u8], at: &mut usize) -> Result<u32, TileDeltaError> {
    let mut v = 0u64;
    for i in 0..5 {
        let byte = *b.get(*at).ok_or(TileDeltaError::Truncated)?;
        *at += 1;
        v |= u64::from(byte & 0x7F) << (7 * i);
        if byte & 0x80 == 0 {
            return u32::try_from(v).map_err(|_| TileDeltaError::Varint);
        }
    }
    Err(TileDeltaError::Varint)
}

impl TileDelta {
    /// Whether the delta changes nothing.
    pub fn is_empty(&self) -> bool {
        self.removed.is_empty() && self.added.is_empty()
    }

    /// Packs the body. Indices must be ascending (as [`TileDelta`] keeps them).
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::new();
        put_varint(&mut out, self.removed.len() as u32);
        let mut prev = 0;
        for &t in &self.removed {
            put_varint(&mut out, t - prev);
            prev = t;
        }
        put_varint(&mut out, self.added.len() as u32);
        prev = 0;
        for a in &self.added {
            put_varint(&mut out, a.tile - prev);
            prev = a.tile;
            match &a.body {
                None => put_varint(&mut out, 0),
                Some(b) => {
                    put_varint(&mut out, b.mesh.len() as u32);
                    put_varint(&mut out, b.patches.len() as u32);
                    out.extend_from_slice(&b.mesh);
                    out.extend_from_slice(&b.patches);
                }
            }
        }
        out
    }

    /// Unpacks a body for a pyramid of `tile_count` tiles. Reserves room for at most
    /// [`RESERVE_MAX`] tiles per list up front: beyond that, lists grow as their tiles decode.
    pub fn decode(b: &[u8], tile_count: u32) -> Result<TileDelta, TileDeltaError> {
        let mut at = 0usize;
        let count = |b: &[u8], at: &mut usize| -> Result<usize, TileDeltaError> {
            let n = get_varint(b, at)? as usize;
            if n > tile_count as usize || n > b.len() - *at {
                return Err(TileDeltaError::Truncated);
            }
            Ok(n)
        };
        let n_removed = count(b, &mut at)?;
        let mut removed = Vec::with_capacity(n_removed.min(RESERVE_MAX));
        let mut next = 0u64;
        for i in 0..n_removed {
            let t = next + u64::from(get_varint(b, &mut at)?);
            if t >= tile_count as u64 || (i > 0 && t == next) {
                return Err(TileDeltaError::Tile(t));
            }
            removed.push(t as u32);
            next = t;
        }
        let n_added = count(b, &mut at)?;
        let mut added = Vec::with_capacity(n_added.min(RESERVE_MAX));
        next = 0;
        for i in 0..n_added {
            let t = next + u64::from(get_varint(b, &mut at)?);
            if t >= tile_count as u64 || (i > 0 && t == next) {
                return Err(TileDeltaError::Tile(t));
            }
            next = t;
            let mesh_len = get_varint(b, &mut at)? as usize;
            let body = if mesh_len == 0 {
                None
            } else {
                let patch_len = get_varint(b, &mut at)? as usize;
                let end = at
                    .checked_add(mesh_len)
                    .and_then(|e| e.checked_add(patch_len))
                    .filter(|&e| e <= b.len())
                    .ok_or(TileDeltaError::Truncated)?;
                let mesh = b[at..at + mesh_len].to_vec();
                let patches = b[at + mesh_len..end].to_vec();
                at = end;
                Some(TileBlobs { mesh, patches })
            };
            added.push(AddedTile {
                tile: t as u32,
                body,
            });
        }
        if at != b.len() {
            return Err(TileDeltaError::Trailing(b.len() - at));
        }
        Ok(TileDelta { removed, added })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn deltas_round_trip(removed in proptest::collection::btree_set(0u32..5000, 0..40),
                             added in proptest::collection::btree_map(0u32..5000,
                                 proptest::option::of((proptest::collection::vec(any::<u8>(), 1..40),
                                                       proptest::collection::vec(any::<u8>(), 0..10))), 0..40)) {
            let d = TileDelta {
                removed: removed.into_iter().collect(),
                added: added.into_iter().map(|(tile, b)| AddedTile {
                    tile, body: b.map(|(mesh, patches)| TileBlobs { mesh, patches }),
                }).collect(),
            };
            prop_assert_eq!(TileDelta::decode(&d.encode(), 5000).unwrap(), d);
        }

        #[test]
        fn random_bytes_never_panic_or_overallocate(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            if let Ok(d) = TileDelta::decode(&bytes, 5000) {
                prop_assert!(d.removed.len() + d.added.len() <= bytes.len());
            }
        }
    }

    /// Hostile input: a count that the bytes left could hold, in a body of garbage, reserved room
    /// for every claimed tile (a 2 MiB body, 117 MB) before the second tile failed to decode.
    #[test]
    fn lying_counts_reserve_little() {
        let mut body = vec![0];
        put_varint(&mut body, (2 << 20) - 8);
        body.resize(2 << 20, 0);
        // Tile 0 from the cache, then tile 0 again: not ascending.
        assert_eq!(
            TileDelta::decode(&body, u32::MAX),
            Err(TileDeltaError::Tile(0))
        );
    }

    #[test]
    fn lying_counts_and_lengths_are_refused() {
        assert_eq!(
            TileDelta::decode(&[0xFF, 0xFF, 0xFF, 0x0F], 10),
            Err(TileDeltaError::Truncated)
        );
        assert_eq!(
            TileDelta::decode(&[0, 1, 3, 100, 0], 10),
            Err(TileDeltaError::Truncated)
        );
        assert_eq!(
            TileDelta::decode(&[1, 20, 0], 10),
            Err(TileDeltaError::Tile(20))
        );
        assert_eq!(
            TileDelta::decode(&[0, 0, 9], 10),
            Err(TileDeltaError::Trailing(1))
        );
        assert_eq!(TileDelta::decode(&[0, 0], 10), Ok(TileDelta::default()));
    }
}
