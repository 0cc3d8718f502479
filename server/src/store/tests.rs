//! Store round trip and corrupt-input tests.

use super::*;
use crate::dem::VoidMask;

/// A mask of `n` samples with sample `i` void where `void(i)`.
fn mask(n: usize, void: impl Fn(usize) -> bool) -> VoidMask {
    let mut m = VoidMask::new(n);
    (0..n).filter(|&i| void(i)).for_each(|i| m.set(i));
    m
}

fn input<'a>(heights: &'a [f32], voids: &'a VoidMask, w: u32, h: u32) -> StoreInput<'a> {
    StoreInput {
        width: w,
        height: h,
        spacing_x: 30.0,
        spacing_y: 25.0,
        z_quantum: 0.25,
        heights,
        voids,
        tile_size: 8,
        meta: StoreMeta {
            source: "test".into(),
            ..StoreMeta::default()
        },
    }
}

fn sample_store(dir: &Path) -> std::path::PathBuf {
    let (w, h) = (37u32, 21u32);
    let heights: Vec<f32> = (0..w * h).map(|i| (i % 13) as f32 * 2.5).collect();
    let voids = mask((w * h) as usize, |i| i % 50 == 0);
    let path = dir.join("t.relief");
    write_store(&path, &input(&heights, &voids, w, h), |_| {}).unwrap();
    path
}

#[test]
fn round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let path = sample_store(dir.path());
    let s = Store::open(&path).unwrap();
    let g = s.geometry();
    assert_eq!((g.shape.width(), g.shape.height()), (37, 21));
    assert_eq!(s.nodes().len() as u64, s.layout().len());
    assert!(s.is_void(0, 0));
    assert!(!s.is_void(1, 0));
    assert_eq!(s.sample_z(3, 0), 30); // 7.5 m / 0.25 m
    assert_eq!(s.meta().source, "test");
    // The nodes section holds the tree's records as the builder streams them, the band's size
    // whatever it is, on a grid whose border nodes lack children (their slots stay empty).
    let (w, h) = (37u32, 21u32);
    let heights: Vec<f32> = (0..w * h).map(|i| (i % 13) as f32 * 2.5).collect();
    assert_eq!(s.nodes(), build::tests::records(g, &heights, 3));
    let empty = s.nodes().iter().filter(|&&r| r == 0).count() as u64;
    assert!(s.layout().len() - g.shape.node_count() <= empty);
}

fn expect_err(path: &Path, bytes: &[u8]) -> StoreError {
    std::fs::write(path, bytes).unwrap();
    match Store::open(path) {
        Ok(_) => panic!("corrupt store accepted"),
        Err(e) => e,
    }
}

#[test]
fn corrupt_stores_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = sample_store(dir.path());
    let good = std::fs::read(&path).unwrap();
    let bad = dir.path().join("bad.relief");

    let e = expect_err(&bad, &good[..good.len() / 2]);
    assert!(matches!(e, StoreError::Truncated { .. }), "{e}");
    let e = expect_err(&bad, &good[..100]);
    assert!(matches!(e, StoreError::Truncated { .. }), "{e}");
    let e = expect_err(&bad, b"GIF89a not a store at all");
    assert!(matches!(e, StoreError::NotAStore), "{e}");
    let e = expect_err(&bad, b"");
    assert!(matches!(e, StoreError::Truncated { .. }), "{e}");

    let mut flipped = good.clone();
    let n = flipped.len();
    flipped[n / 2] ^= 0x10;
    let e = expect_err(&bad, &flipped);
    assert!(matches!(e, StoreError::Corrupt(_)), "{e}");

    // The tile sections: a flipped byte in the last tile blob, and a tile record
    // pointing past the blobs with its checksums recomputed, are both refused.
    let mut tile = good.clone();
    let header = format::Header::parse(&good[..format::HEADER_LEN], good.len() as u64).unwrap();
    let (data_off, data_len) = header.sections[format::TILE_DATA];
    tile[(data_off + data_len - 1) as usize] ^= 0x01;
    let e = expect_err(&bad, &tile);
    assert!(e.to_string().contains("checksum"), "{e}");
    let mut rec = good.clone();
    let (rec_off, _) = header.sections[format::TILES];
    rec[rec_off as usize + 8..rec_off as usize + 12].copy_from_slice(&u32::MAX.to_le_bytes());
    let mut h2 = header.clone();
    let mut crc = crc32fast::Hasher::new();
    for (off, len) in h2.sections {
        crc.update(&rec[off as usize..(off + len) as usize]);
    }
    h2.body_crc = crc.finalize();
    rec[..format::HEADER_LEN].copy_from_slice(&h2.to_bytes());
    let e = expect_err(&bad, &rec);
    assert!(e.to_string().contains("tile record 0"), "{e}");

    let mut hdr = good.clone();
    hdr[13] ^= 1; // width
    let e = expect_err(&bad, &hdr);
    assert!(matches!(e, StoreError::Corrupt(_)), "{e}");

    let mut ver = good.clone();
    ver[8] = 9;
    let e = expect_err(&bad, &ver);
    assert!(matches!(e, StoreError::Version { found: 9, .. }), "{e}");
    assert!(e.to_string().contains("rebuild"));
    // A version-3 store (rqt tiles without crack curtains) is refused the same way.
    let mut v3 = good.clone();
    v3[8..12].copy_from_slice(&3u32.to_le_bytes());
    let e = expect_err(&bad, &v3);
    assert!(matches!(e, StoreError::Version { found: 3, .. }), "{e}");
    assert!(e.to_string().contains("rebuild"), "{e}");

    let e = Store::open(&dir.path().join("missing.relief"))
        .err()
        .unwrap();
    assert!(matches!(e, StoreError::Io { .. }), "{e}");
}

#[test]
fn heights_give_back_the_grid_to_within_half_a_quantum() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (37u32, 21u32);
    // Heights off the 0.25 m quantum, negative ones included, and a ramp across rows.
    let heights: Vec<f32> = (0..w * h)
        .map(|i| (i % 13) as f32 * 2.37 - 9.1 + 0.61 * (i / w) as f32)
        .collect();
    let voids = VoidMask::new((w * h) as usize);
    let path = dir.path().join("h.relief");
    write_store(&path, &input(&heights, &voids, w, h), |_| {}).unwrap();
    let s = Store::open(&path).unwrap();
    let back = s.heights();
    assert_eq!(back.len(), heights.len());
    for (i, (&a, &b)) in heights.iter().zip(&back).enumerate() {
        assert!(
            (a - b).abs() <= 0.125 + 1e-4,
            "sample {i}: {a} stored as {b}"
        );
    }
    // Row-major from the north: sample (3, 2) is index 2 * w + 3.
    assert_eq!(back[(2 * w + 3) as usize], s.sample_z(3, 2) as f32 * 0.25);
}

/// `docs/protocol.md` section 15.8, written out from the document alone and checked against the
/// store and the tile engine: each tile's box and saturated error (voids counted at their
/// filled heights), `level_errors`, and the selection (the screen error, the plain rule with
/// its `0.9 tau` hysteresis, the restriction, the active set) over a walk of poses.
#[test]
fn the_tile_selection_rule_of_the_protocol_doc_is_what_the_server_does() {
    use crate::lod::tile::TileEngine;
    use crate::lod::tile::session::TileSession;
    use relief_proto::msg::{CrackMode, TileStreamParams};
    use relief_proto::tile::body::grid_height;
    use relief_proto::tile::{EDGES, TileId};
    use relief_proto::view::{Camera, Lens, ViewState};
    use std::collections::BTreeSet;

    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (97u32, 81u32);
    let (dx, dy, q) = (30.0f32, 25.0f32, 0.25f32);
    let heights: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            (x * 0.21).sin() * 40.0 + (y * 0.13).cos() * 55.0 + ((i * 7919) % 23) as f32 * 0.37
        })
        .collect();
    // Voids, already filled (as the build gets them): they count like any other sample.
    let voids = mask((w * h) as usize, |i| i % 7 == 0);
    let path = dir.path().join("sel.relief");
    write_store(&path, &input(&heights, &voids, w, h), |_| {}).unwrap();
    let st = Store::open(&path).unwrap();
    let plain = dir.path().join("sel-novoids.relief");
    let no_voids = VoidMask::new(voids.len());
    write_store(&plain, &input(&heights, &no_voids, w, h), |_| {}).unwrap();
    let st_plain = Store::open(&plain).unwrap();
    assert_eq!(st.tile_records(), st_plain.tile_records());
    assert_eq!(
        st.tile_info().level_errors,
        st_plain.tile_info().level_errors
    );

    let engine = TileEngine::new(&st);
    let shape = engine.shape();
    let n = shape.tile_count();
    let src = |c: u32, r: u32| heights[(r * w + c) as usize];
    let stored = |c: u32, r: u32| st.sample_z(c, r) as f32 * q;
    // Error and box of every tile; `level_errors` their maximum per level.
    let mut level_max = vec![0f32; shape.depth() as usize + 1];
    for level in (0..=shape.depth()).rev() {
        let (nx, ny) = shape.level_dims(level);
        for (x, y) in (0..ny).flat_map(|y| (0..nx).map(move |x| (x, y))) {
            let t = TileId { level, x, y };
            let i = shape.index(t);
            let sp = shape.span(t);
            let z: Vec<f32> = (0..sp.vertex_count() as u32)
                .map(|v| {
                    let (c, r) = sp.vertex_pos(v);
                    stored(c, r)
                })
                .collect();
            let (mut own, mut lo, mut hi) = (0f32, f32::MAX, f32::MIN);
            for r in sp.rows.0..=sp.rows.1 {
                for c in sp.cols.0..=sp.cols.1 {
                    own = own.max((grid_height(&sp, &z, c as f32, r as f32) - src(c, r)).abs());
                    lo = lo.min(src(c, r));
                    hi = hi.max(src(c, r));
                }
            }
            let e = shape
                .children(t)
                .map(|c| engine.record(shape.index(c)).error)
                .fold(own, f32::max);
            assert_eq!(engine.record(i).error, e, "e({t:?})");
            level_max[level as usize] = level_max[level as usize].max(e);
            let b = engine.tile_box(i);
            let want_min = [
                sp.cols.0 as f32 * dx,
                (h - 1 - sp.rows.1) as f32 * dy,
                (lo / q).floor() * q,
            ];
            let want_max = [
                sp.cols.1 as f32 * dx,
                (h - 1 - sp.rows.0) as f32 * dy,
                (hi / q).ceil() * q,
            ];
            assert_eq!(b.min.to_array(), want_min, "B({t:?})");
            assert_eq!(b.max.to_array(), want_max, "B({t:?})");
        }
    }
    assert_eq!(st.tile_info().level_errors, level_max);
    assert!(level_max.windows(2).all(|p| p[0] >= p[1]));

    let sse = |view: &ViewState, i: u32| -> f32 {
        let (e, b) = (engine.record(i).error, engine.tile_box(i));
        if e == 0.0 || !view.intersects(&b) {
            return 0.0;
        }
        let d = (view.eye().clamp(b.min, b.max) - view.eye()).length();
        e * view.focal() / d.max(view.near())
    };
    let lens = Lens {
        width: 640,
        height: 480,
        ..Lens::STANDARD
    };
    let tau = 2.0;
    let mut session = TileSession::new(
        n,
        TileStreamParams {
            cache_tiles: u32::MAX,
            crack: CrackMode::Skirts,
        },
        tau,
        0.9,
    );
    let mut prev: BTreeSet<u32> = BTreeSet::new();
    let (mut held, mut forced, mut bounded) = (0, 0, 0);
    for k in 0..60 {
        let s = k as f32 / 59.0;
        let camera = Camera {
            eye: glam::Vec3::new(
                (0.1 + 0.8 * s) * (w - 1) as f32 * dx,
                (0.2 + 0.3 * s) * (h - 1) as f32 * dy,
                150.0 + 900.0 * (s * 3.0).sin().abs(),
            ),
            yaw: 0.3 + 2.0 * s,
            pitch: -0.35,
        };
        let view = ViewState::new(&camera, &lens);
        // 1. The plain rule, depth first from the root.
        let mut split = BTreeSet::new();
        let mut stack = vec![TileId::ROOT];
        while let Some(t) = stack.pop() {
            let i = shape.index(t);
            if t.level == shape.depth() {
                continue;
            }
            let e = sse(&view, i);
            if e > tau || (prev.contains(&i) && e > 0.9 * tau) {
                held += usize::from(e <= tau);
                split.insert(i);
                stack.extend(shape.children(t));
            }
        }
        let plain = split.clone();
        // 2. The restriction, from the finest level up.
        for level in (1..=shape.depth()).rev() {
            let at: Vec<TileId> = split
                .iter()
                .filter_map(|&i| shape.tile(i))
                .filter(|t| t.level == level)
                .collect();
            for t in at {
                let across = EDGES
                    .iter()
                    .map(|&e| shape.neighbour(t, e).and_then(TileId::parent));
                for p in std::iter::once(t.parent()).chain(across).flatten() {
                    split.insert(shape.index(p));
                }
            }
        }
        forced += split.len() - plain.len();
        // 3. The active tiles.
        let active: Vec<u32> = if split.is_empty() {
            vec![0]
        } else {
            let mut a: Vec<u32> = split
                .iter()
                .flat_map(|&i| shape.children(shape.tile(i).unwrap()))
                .map(|c| shape.index(c))
                .filter(|c| !split.contains(c))
                .collect();
            a.sort_unstable();
            a
        };
        let u = session.update(&engine, &view, usize::MAX);
        assert!(u.complete);
        assert_eq!(
            session.split().iter().collect::<BTreeSet<u32>>(),
            split,
            "pose {k}"
        );
        assert_eq!(session.active(), active, "pose {k}");
        // What a client can check: a split tile under its bound was forced by the restriction.
        let info = st.tile_info();
        for &i in &split {
            let t = shape.tile(i).unwrap();
            let b = engine.tile_box(i);
            let eye = view.eye();
            let flat = |v: glam::Vec3| glam::Vec2::new(v.x, v.y);
            let d_xy = (flat(eye).clamp(flat(b.min), flat(b.max)) - flat(eye)).length();
            let ub = info.level_errors[t.level as usize] * view.focal() / d_xy.max(view.near());
            assert!(sse(&view, i) <= ub);
            let limit = if prev.contains(&i) { 0.9 * tau } else { tau };
            if ub <= limit {
                bounded += 1;
                let needed = split.iter().filter_map(|&j| shape.tile(j)).any(|c| {
                    c.parent() == Some(t)
                        || EDGES
                            .iter()
                            .any(|&e| shape.neighbour(c, e).and_then(TileId::parent) == Some(t))
                });
                assert!(needed, "{t:?} split under its bound, not forced");
            }
        }
        prev = split;
    }
    // The client's bound is loose: it decides nothing on this walk (`bounded` stays 0).
    println!("held by hysteresis {held}, forced {forced}, under the client's bound {bounded}");
    assert!(held > 0 && forced > 0, "the walk exercises neither rule");
}
