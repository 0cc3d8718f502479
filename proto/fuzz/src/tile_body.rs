//! Target `tile_body`: a [`Header`] (grid size; the parameter picks the tile size, 2 to 256)
//! and then a tile delta body, decoded as a tile client does: [`TileDelta::decode`] for the
//! pyramid, then each added tile's mesh blob ([`decode_mesh`]) and patch blob
//! ([`decode_patches`]; against the decoded heights, or flat ones when the mesh is refused, so
//! that patch blobs are explored on their own too; an `rqt` tile's patch blob as its crack
//! curtains, [`decode_tile_curtains`]).
//!
//! Whatever decodes is re-encoded and decoded again to the same value (`rqt` and `tin` meshes
//! too: their vertices must lie in the tile and their triangles name them). The delta's re-encoding
//! must be the shortest form of the input ([`crate::assert_canonical`]); a patch blob's must be
//! no longer than the input (orders are chosen to minimise it). A mesh re-encodes to heights
//! equal to the decoded ones (the encoder picks its own `zmin` and order, so the bytes may
//! differ), and re-encoding that gives the same bytes. Patches must name vertices of the tile.

use crate::Header;
use relief_proto::tile::body::curtain::{
    CurtainPoint, Polyline, curtain_sides, decode_curtains, decode_tile_curtains, encode_curtains,
    side_of,
};
use relief_proto::tile::body::irregular::canonical;
use relief_proto::tile::body::rqt::encode_rqt;
use relief_proto::tile::body::{
    DecodedMesh, IrregularMesh, MeshKind, decode_mesh, decode_patches, encode_irregular,
    encode_mesh, encode_patches, find_patches,
};
use relief_proto::tile::delta::{AddedTile, TileBlobs, TileDelta};
use relief_proto::tile::{TileId, TileShape, TileSpan};
use std::collections::HashMap;

/// Decodes and round-trips one input; true if the tile delta decoded.
pub fn check(data: &[u8]) -> bool {
    let Some((header, body)) = Header::split(data) else {
        return false;
    };
    let tile = 2 << (header.param % 8);
    let Ok(shape) = TileShape::new(header.width, header.height, tile) else {
        return false;
    };
    let Ok(delta) = TileDelta::decode(body, shape.tile_count()) else {
        return false;
    };
    let bytes = delta.encode();
    crate::assert_canonical(body, &bytes);
    assert_eq!(
        TileDelta::decode(&bytes, shape.tile_count()).as_ref(),
        Ok(&delta)
    );
    for added in &delta.added {
        let t = shape.tile(added.tile).expect("a decoded index is a tile");
        if let Some(blobs) = &added.body {
            tile_blobs(&shape, t, blobs);
        }
    }
    true
}

/// Decodes and round-trips the blobs of tile `t`.
fn tile_blobs(shape: &TileShape, t: TileId, blobs: &TileBlobs) {
    let span = shape.span(t);
    let n = span.vertex_count();
    let z = match decode_mesh(&span, &blobs.mesh) {
        Ok(DecodedMesh { z, irregular: None }) => {
            assert_eq!(z.len(), n);
            let mesh = encode_mesh(&span, &z);
            let again = decode_mesh(&span, &mesh).expect("an encoded mesh");
            assert_eq!(again.z, z);
            assert_eq!(encode_mesh(&span, &again.z), mesh);
            z
        }
        Ok(DecodedMesh {
            z,
            irregular: Some(m),
        }) => {
            irregular_round_trip(&span, &m, &z);
            if m.kind == MeshKind::Rqt {
                curtain_round_trip(shape, t, &m, &z, &blobs.patches);
            }
            return;
        }
        Err(_) => vec![0; n],
    };
    let Ok(patches) = decode_patches(shape, t, &z, &blobs.patches) else {
        return;
    };
    let n = n as u32;
    assert!(patches.dropped.iter().all(|d| d.a < n && d.c < n));
    assert!(patches.raised.iter().flatten().all(|&v| v < n));
    let blob = encode_patches(shape, t, &z, &patches);
    assert!(
        blob.len() <= blobs.patches.len(),
        "re-encoding grew {} bytes to {}",
        blobs.patches.len(),
        blob.len()
    );
    assert_eq!(decode_patches(shape, t, &z, &blob), Ok(patches));
}

/// Decodes an `rqt` tile's patch blob as its crack curtains: the triangles name the
/// tile's vertices and points on its sides; the curtains re-encode no longer than the input
/// and decode the same.
fn curtain_round_trip(shape: &TileShape, t: TileId, m: &IrregularMesh, z: &[i32], bytes: &[u8]) {
    let span = shape.span(t);
    let Ok(tris) = decode_tile_curtains(shape, t, m, z, bytes) else {
        return;
    };
    for p in tris.iter().flatten() {
        match *p {
            CurtainPoint::Vertex(v) => assert!((v as usize) < z.len()),
            CurtainPoint::Below { at: (c, r), .. } => assert!(
                (c == span.cols.0 || c == span.cols.1) && (span.rows.0..=span.rows.1).contains(&r)
                    || (r == span.rows.0 || r == span.rows.1)
                        && (span.cols.0..=span.cols.1).contains(&c)
            ),
        }
    }
    let owns: Vec<Polyline> = curtain_sides(shape, t)
        .map(|e| side_of(&span, e, &m.at, z).0)
        .collect();
    let sides = decode_curtains(&owns, bytes).expect("decoded once");
    let blob = encode_curtains(
        &owns
            .iter()
            .cloned()
            .zip(sides.iter().cloned())
            .collect::<Vec<_>>(),
    );
    assert!(
        blob.len() <= bytes.len(),
        "re-encoding grew {} bytes to {}",
        bytes.len(),
        blob.len()
    );
    assert_eq!(decode_curtains(&owns, &blob), Ok(sides));
}

/// Re-encodes a decoded `rqt` or `tin` mesh and checks it decodes to the same mesh (`tin` in its
/// canonical order). Vertices lie in the tile and triangles name them.
fn irregular_round_trip(span: &TileSpan, m: &IrregularMesh, z: &[i32]) {
    let (w, h) = (span.cols.1 - span.cols.0, span.rows.1 - span.rows.0);
    assert_eq!(m.at.len(), z.len());
    assert!(m.at.iter().all(|p| p[0] <= w && p[1] <= h));
    assert!(
        m.triangles
            .iter()
            .flatten()
            .all(|&v| (v as usize) < z.len())
    );
    let (blob, want) = match m.kind {
        MeshKind::Rqt => {
            let s = span.stride;
            let height: HashMap<[u32; 2], i32> =
                m.at.iter()
                    .map(|p| p.map(|v| v / s))
                    .zip(z.iter().copied())
                    .collect();
            let blob = encode_rqt(
                span,
                |p| height.contains_key(&p),
                |p| height.get(&p).copied().unwrap_or(0),
            )
            .expect("a decoded rqt span is square");
            (blob, (m.clone(), z.to_vec()))
        }
        _ => (encode_irregular(m, z), canonical(m, z)),
    };
    let again = decode_mesh(span, &blob).expect("an encoded mesh");
    assert_eq!(again.irregular.as_ref(), Some(&want.0));
    assert_eq!(again.z, want.1);
}

/// The blobs of tile `t` over a made-up terrain: a tilted plane with bumps, in z quanta.
fn made_up_blobs(shape: &TileShape, t: TileId) -> TileBlobs {
    let sample = |c: u32, r: u32| (3 * c + 2 * r) as i32 + ((c * 7 + r * 13) % 11) as i32 - 5;
    let span = shape.span(t);
    let z: Vec<i32> = (0..span.vertex_count() as u32)
        .map(|v| {
            let (c, r) = span.vertex_pos(v);
            sample(c, r)
        })
        .collect();
    let patches = find_patches(shape, t, &z, sample);
    TileBlobs {
        mesh: encode_mesh(&span, &z),
        patches: encode_patches(shape, t, &z, &patches),
    }
}

/// The blobs of `rqt` tile `t` over the same made-up terrain, every third lattice point active,
/// with a curtain one and two quanta deep under every border segment.
fn made_up_rqt_blobs(shape: &TileShape, t: TileId) -> TileBlobs {
    let sample = |c: u32, r: u32| (3 * c + 2 * r) as i32 + ((c * 7 + r * 13) % 11) as i32 - 5;
    let span = shape.span(t);
    let s = span.stride;
    let z_at = |p: [u32; 2]| sample(span.cols.0 + p[0] * s, span.rows.0 + p[1] * s);
    let mesh = encode_rqt(&span, |p| (p[0] + p[1]) % 3 == 0, z_at).expect("square tiles");
    let m = decode_mesh(&span, &mesh).expect("an encoded mesh");
    let irr = m.irregular.expect("an rqt mesh");
    let sides: Vec<_> = curtain_sides(shape, t)
        .map(|e| {
            let (own, _) = side_of(&span, e, &irr.at, &m.z);
            let segs = (0..own.pos.len() - 1)
                .map(|k| {
                    Some(vec![
                        (own.pos[k], own.z[k] - 1),
                        (own.pos[k + 1], own.z[k + 1] - 2),
                    ])
                })
                .collect();
            (own, segs)
        })
        .collect();
    TileBlobs {
        mesh,
        patches: encode_curtains(&sides),
    }
}

/// Tile deltas on small pyramids: the root tile sent, the root split into its children, and
/// a merge back from the cache.
pub fn seeds() -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for (w, h, param) in [(5, 3, 0), (40, 30, 1)] {
        let shape = TileShape::new(w, h, 2 << param).expect("a small pyramid");
        let header = Header {
            width: w,
            height: h,
            param,
        };
        let root = TileId::ROOT;
        let first = TileDelta {
            removed: vec![],
            added: vec![AddedTile {
                tile: 0,
                body: Some(made_up_blobs(&shape, root)),
            }],
        };
        let split = TileDelta {
            removed: vec![0],
            added: shape
                .children(root)
                .map(|c| AddedTile {
                    tile: shape.index(c),
                    body: Some(made_up_blobs(&shape, c)),
                })
                .collect(),
        };
        let back = TileDelta {
            removed: shape.children(root).map(|c| shape.index(c)).collect(),
            added: vec![AddedTile {
                tile: 0,
                body: None,
            }],
        };
        for (name, d) in [("root", first), ("split", split), ("merge", back)] {
            out.push((format!("{name}_{w}x{h}"), header.with(&d.encode())));
        }
    }
    // An `rqt` pyramid (square tiles) split once, with curtains.
    let (w, h, param) = (33, 33, 2);
    let shape = TileShape::new(w, h, 2 << param).expect("a small pyramid");
    let split = TileDelta {
        removed: vec![],
        added: shape
            .children(TileId::ROOT)
            .map(|c| AddedTile {
                tile: shape.index(c),
                body: Some(made_up_rqt_blobs(&shape, c)),
            })
            .collect(),
    };
    let header = Header {
        width: w,
        height: h,
        param,
    };
    out.push((format!("rqt_split_{w}x{h}"), header.with(&split.encode())));
    out
}
