//! The tile side of a session's state, fed tile deltas built with the proto's encoders: counts
//! of sent and cached tiles, triangles, desyncs, and the cache cut to the active set on resume.

use super::*;
use relief_proto::tile::TileShape;
use relief_proto::tile::body::{encode_mesh, encode_patches, find_patches};
use relief_proto::tile::cache::set_digest;
use relief_proto::tile::delta::{AddedTile, TileBlobs, TileDelta};

/// A 33 x 33 terrain with 8-cell tiles: depth 2, 1 + 4 + 16 tiles.
const W: u32 = 33;

fn dem(c: u32, r: u32) -> i32 {
    ((c * 7 + r * 13) % 23) as i32 * 3 - ((c * r) % 5) as i32
}

fn geom() -> TerrainGeometry {
    TerrainGeometry::new(W, W, 10.0, 10.0, 0.5).unwrap()
}

fn shape() -> TileShape {
    TileShape::new(W, W, 8).unwrap()
}

fn state(crack: CrackMode, cache_tiles: u32) -> TileState {
    let params = TileStreamParams { cache_tiles, crack };
    TileState {
        info: TileSetInfo {
            tile_size: 8,
            depth: 2,
            mesh: "grid".into(),
            level_errors: vec![4.0, 2.0, 0.0],
        },
        params,
        mirror: TileMirror::new(shape(), params),
        drawn: FxHashMap::default(),
        triangles: 0,
    }
}

/// The body of one delta: `removed`, then `added` (with a body unless in `cached`).
fn delta(
    crack: CrackMode,
    removed: &[u32],
    added: &[u32],
    cached: &[u32],
    active_after: &[u32],
) -> WireDelta {
    let shape = shape();
    let added = added
        .iter()
        .map(|&i| {
            let t = shape.tile(i).unwrap();
            let span = shape.span(t);
            let z: Vec<i32> = (0..span.vertex_count() as u32)
                .map(|v| {
                    let (c, r) = span.vertex_pos(v);
                    dem(c, r)
                })
                .collect();
            let body = (!cached.contains(&i)).then(|| TileBlobs {
                mesh: encode_mesh(&span, &z),
                patches: if crack == CrackMode::Patches {
                    let p = find_patches(&shape, t, &z, dem);
                    encode_patches(&shape, t, &z, &p)
                } else {
                    Vec::new()
                },
            });
            AddedTile { tile: i, body }
        })
        .collect();
    WireDelta {
        seq: 1,
        digest: set_digest(active_after.iter().copied()),
        body: TileDelta {
            removed: removed.to_vec(),
            added,
        }
        .encode(),
    }
}

#[test]
fn tiles_are_counted_sent_or_cached_with_their_triangles() {
    let mut s = state(CrackMode::Skirts, u32::MAX);
    // The root, then its four children (8 x 8 cells each), then the root again from the cache.
    let a = s
        .apply(&delta(CrackMode::Skirts, &[], &[0], &[], &[0]))
        .unwrap();
    assert_eq!((a.changes, a.tiles_sent, a.tiles_cached), (1, 1, 0));
    // 8 x 8 cells: 128 mesh triangles, 4 x 8 x 2 skirt triangles.
    assert_eq!(s.triangles, 128 + 64);
    let kids = [1, 2, 3, 4];
    let a = s
        .apply(&delta(CrackMode::Skirts, &[0], &kids, &[], &kids))
        .unwrap();
    assert_eq!((a.changes, a.tiles_sent, a.tiles_cached), (5, 4, 0));
    assert_eq!(s.triangles, 4 * (128 + 64));
    assert_eq!(s.active_count(), 4);
    let a = s
        .apply(&delta(CrackMode::Skirts, &kids, &[0], &[0], &[0]))
        .unwrap();
    assert_eq!((a.tiles_sent, a.tiles_cached), (0, 1));
    assert_eq!(s.triangles, 128 + 64);
    assert_eq!(s.skirt_depth(1), Some(20.0), "the level above's error");
    assert_eq!(
        s.skirt_depth(2),
        Some(10.0),
        "full resolution hangs skirts too"
    );
    assert_eq!(s.skirt_depth(0), Some(20.0));
    let g = geom();
    assert!(s.height_at(&g, 15.0, 15.0).is_some());
    assert!(s.height_at(&g, -15.0, 15.0).is_none());
    // A wrong digest is a desync.
    let mut bad = delta(CrackMode::Skirts, &[0], &kids, &[], &kids);
    bad.digest ^= 1;
    assert!(s.apply(&bad).is_err());
}

#[test]
fn patches_count_as_triangles_and_resume_keeps_the_active_tiles_only() {
    let mut s = state(CrackMode::Patches, u32::MAX);
    s.apply(&delta(CrackMode::Patches, &[], &[0], &[], &[0]))
        .unwrap();
    let kids = [1, 2, 3, 4];
    s.apply(&delta(CrackMode::Patches, &[0], &kids, &[], &kids))
        .unwrap();
    // Split the first child: its four children and three coarse neighbours.
    let fine = [5, 6, 9, 10];
    let after = [2, 3, 4, 5, 6, 9, 10];
    s.apply(&delta(CrackMode::Patches, &[1], &fine, &[], &after))
        .unwrap();
    let patches: usize = after
        .iter()
        .map(|i| s.mirror.tile(*i).unwrap().patches.triangle_count())
        .sum();
    assert!(patches > 0, "the test terrain has cracks to patch");
    assert_eq!(s.triangles, 7 * 128 + patches);
    assert_eq!(s.mirror.held_count(), 9);
    let digest = s.mirror.digest();
    let before = s.mirror.clone();
    let mut st = StreamState::Tiles(s);
    st.resumed();
    let StreamState::Tiles(s) = st else {
        unreachable!()
    };
    let kept = s.mirror();
    assert_eq!(kept.digest(), digest);
    assert_eq!(
        kept.held_count(),
        7,
        "the cached root and child are dropped"
    );
    for i in after {
        assert_eq!(kept.tile(i), before.tile(i));
    }
    assert!(kept.tile(0).is_none() && kept.tile(1).is_none());
}

#[test]
fn a_light_mirror_checks_every_delta_and_keeps_no_tile() {
    let params = TileStreamParams {
        cache_tiles: u32::MAX,
        crack: CrackMode::Patches,
    };
    let mut s = state(CrackMode::Patches, u32::MAX);
    s.mirror = TileMirror::light(shape(), params);
    s.apply(&delta(CrackMode::Patches, &[], &[0], &[], &[0]))
        .unwrap();
    let kids = [1, 2, 3, 4];
    let a = s
        .apply(&delta(CrackMode::Patches, &[0], &kids, &[], &kids))
        .unwrap();
    assert_eq!((a.tiles_sent, s.active_count()), (4, 4));
    assert!(kids.iter().all(|i| s.mirror.tile(*i).is_none()));
    assert_eq!(s.mirror.held_count(), 5);
    let mut bad = delta(CrackMode::Patches, &kids, &[0], &[0], &[0]);
    bad.digest ^= 1;
    assert!(
        s.apply(&bad).is_err(),
        "a light mirror still checks digests"
    );
}
