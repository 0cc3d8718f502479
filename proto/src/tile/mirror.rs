//! The client's side of a tile session: the active tiles and the cached ones, decoded, rebuilt
//! from tile deltas alone and checked by digest. A thin client needs nothing else: each held
//! tile's [`TileData`] gives its triangles ([`super::geometry`]), patches included.

use super::body::curtain::decode_tile_curtains;
use super::body::{
    DecodedMesh, IrregularMesh, MeshKind, Patches, TileBodyError, decode_mesh, decode_patches,
};
use super::cache::{TileCache, TileSetError};
use super::delta::{TileDelta, TileDeltaError};
use super::{TileId, TileShape, TileSpan};
use crate::msg::{CrackMode, TileStreamParams, WireDelta};
use crate::snapshot::Snapshot;
use rustc_hash::FxHashMap;

/// A tile the client holds.
#[derive(Clone, Debug, PartialEq)]
pub struct TileData {
    /// Which tile.
    pub tile: TileId,
    /// The samples it covers.
    pub span: TileSpan,
    /// Vertex heights, z quanta: row-major over the span for a grid mesh, else one per vertex
    /// of `irregular`.
    pub z: Vec<i32>,
    /// The vertices and triangles of an irregular (`rqt` or `tin`) mesh; `None` for a grid.
    pub irregular: Option<IrregularMesh>,
    /// Its crack patches (empty unless the session draws patches).
    pub patches: Patches,
}

/// A delta the mirror could not apply: the session is out of step and must resume.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum TileMirrorError {
    /// The body does not decode.
    #[error(transparent)]
    Delta(#[from] TileDeltaError),
    /// A tile body does not decode.
    #[error("tile {0}: {1}")]
    Body(u32, TileBodyError),
    /// The change does not apply to the held set.
    #[error(transparent)]
    Set(#[from] TileSetError),
    /// The active set after the delta is not the server's.
    #[error("tile set digest mismatch: ours {ours:#018x}, the server's {theirs:#018x}")]
    Digest {
        /// Ours.
        ours: u64,
        /// The delta's.
        theirs: u64,
    },
}

/// What one delta changed.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TileChanges {
    /// Tiles no longer drawn.
    pub removed: Vec<u32>,
    /// Tiles drawn from now on.
    pub added: Vec<u32>,
    /// Tiles dropped from the cache.
    pub evicted: Vec<u32>,
    /// Added tiles that came with a body (the rest came from the cache).
    pub sent: usize,
}

/// The client's tiles.
#[derive(Clone, Debug)]
pub struct TileMirror {
    /// The pyramid.
    shape: TileShape,
    /// What the bodies carry.
    crack: CrackMode,
    /// Active and cached tiles, as the server models them.
    cache: TileCache,
    /// Every held tile's data, by dense index (none in a light mirror).
    tiles: FxHashMap<u32, TileData>,
    /// Decode and keep the tiles (a light mirror keeps only the bookkeeping).
    keep: bool,
}

impl TileMirror {
    /// An empty mirror for a session opened with `params`.
    pub fn new(shape: TileShape, params: TileStreamParams) -> TileMirror {
        TileMirror {
            shape,
            crack: params.crack,
            cache: TileCache::new(params.cache_tiles),
            tiles: FxHashMap::default(),
            keep: true,
        }
    }

    /// A mirror that checks every delta's layout, the cache bookkeeping and every digest, but
    /// neither decodes nor keeps tile bodies: what a load generator needs to drive thousands of
    /// sessions from one core (viewers and tests decode every body).
    pub fn light(shape: TileShape, params: TileStreamParams) -> TileMirror {
        TileMirror {
            keep: false,
            ..TileMirror::new(shape, params)
        }
    }

    /// Drops the cached tiles and keeps the active ones, as both ends do on a resume (the
    /// server then knows of no cached tile).
    pub fn keep_active_only(&mut self) {
        let active = self.cache.active();
        let mut cache = TileCache::new(self.cache.limit());
        // The active set of a consistent mirror applies to an empty cache.
        let _ = cache.apply(&[], &active, |_| true);
        self.cache = cache;
        self.tiles.retain(|i, _| active.binary_search(i).is_ok());
    }

    /// The pyramid.
    pub fn shape(&self) -> &TileShape {
        &self.shape
    }

    /// Applies one delta and checks its digest. On error the mirror may be partly changed and
    /// must be rebuilt (resume).
    pub fn apply(&mut self, wire: &WireDelta) -> Result<TileChanges, TileMirrorError> {
        let d = TileDelta::decode(&wire.body, self.shape.tile_count())?;
        let mut decoded = Vec::with_capacity(d.added.len());
        for a in &d.added {
            let Some(b) = a.body.as_ref().filter(|_| self.keep) else {
                decoded.push(None);
                continue;
            };
            let tile = self
                .shape
                .tile(a.tile)
                .ok_or(TileMirrorError::Delta(TileDeltaError::Tile(a.tile as u64)))?;
            let span = self.shape.span(tile);
            let body_err = |e| TileMirrorError::Body(a.tile, e);
            let DecodedMesh { z, irregular } = decode_mesh(&span, &b.mesh).map_err(body_err)?;
            let patches = match &irregular {
                // An rqt tile's patch blob holds its crack curtains.
                Some(m) if m.kind == MeshKind::Rqt && self.crack == CrackMode::Patches => Patches {
                    curtains: decode_tile_curtains(&self.shape, tile, m, &z, &b.patches)
                        .map_err(body_err)?,
                    ..Patches::default()
                },
                // Other irregular meshes carry no patch blob (tin's shared borders need none),
                // nor does any tile in a session without patches.
                Some(m) if !b.patches.is_empty() => {
                    return Err(body_err(TileBodyError::PatchesUnexpected(m.kind as u32)));
                }
                None if self.crack == CrackMode::Patches => {
                    decode_patches(&self.shape, tile, &z, &b.patches).map_err(body_err)?
                }
                _ => Patches::default(),
            };
            decoded.push(Some(TileData {
                tile,
                span,
                z,
                irregular,
                patches,
            }));
        }
        let added: Vec<u32> = d.added.iter().map(|a| a.tile).collect();
        let evicted = self
            .cache
            .apply(&d.removed, &added, |i| d.added[i].body.is_some())?;
        let sent = d.added.iter().filter(|a| a.body.is_some()).count();
        for (i, data) in decoded.into_iter().enumerate() {
            if let Some(data) = data {
                self.tiles.insert(added[i], data);
            }
        }
        for t in &evicted {
            self.tiles.remove(t);
        }
        if self.cache.digest() != wire.digest {
            return Err(TileMirrorError::Digest {
                ours: self.cache.digest(),
                theirs: wire.digest,
            });
        }
        Ok(TileChanges {
            removed: d.removed,
            added,
            evicted,
            sent,
        })
    }

    /// A held tile's data.
    pub fn tile(&self, index: u32) -> Option<&TileData> {
        self.tiles.get(&index)
    }

    /// The active tiles' dense indices, ascending.
    pub fn active(&self) -> Vec<u32> {
        self.cache.active()
    }

    /// Digest of the active set.
    pub fn digest(&self) -> u64 {
        self.cache.digest()
    }

    /// Tiles held, active and cached.
    pub fn held_count(&self) -> usize {
        self.cache.held_count()
    }

    /// The resume snapshot of the active set.
    pub fn snapshot(&self) -> Snapshot {
        super::snapshot::snapshot_of(&self.shape, &self.active())
    }
}
