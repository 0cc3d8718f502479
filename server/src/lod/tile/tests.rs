//! Property tests of the tile engine: every selection covers the terrain exactly once and is
//! restricted; deltas replayed by a client mirror rebuild the server's set (with and without a
//! budget, with a small cache); a camera at rest yields empty deltas. [`cracks`]: no pair of
//! tiles that can meet leaves a crack open, for every mesh kind and crack mode.

mod cracks;

use super::TileEngine;
use super::session::TileSession;
use crate::lod::vertex::tests::{Pose, camera, lens, pose, store};
use proptest::prelude::*;
use relief_proto::msg::{CrackMode, TileStreamParams, WireDelta};
use relief_proto::tile::mirror::TileMirror;
use relief_proto::tile::snapshot::restriction_violations;
use relief_proto::view::ViewState;

/// Whether `active` covers every cell of the grid exactly once.
fn covers_once(engine: &TileEngine<'_>, active: &[u32]) -> bool {
    let s = engine.shape();
    let (w, h) = (s.width() as usize - 1, s.height() as usize - 1);
    let mut hits = vec![0u8; w * h];
    for &i in active {
        let sp = s.span(s.tile(i).unwrap());
        for r in sp.rows.0..sp.rows.1 {
            for c in sp.cols.0..sp.cols.1 {
                hits[r as usize * w + c as usize] += 1;
            }
        }
    }
    hits.iter().all(|&n| n == 1)
}

fn params(cache: u32, crack: CrackMode) -> TileStreamParams {
    TileStreamParams {
        cache_tiles: cache,
        crack,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    #[test]
    fn selections_cover_once_are_restricted_and_mirrors_follow(
        w in 20u32..140, h in 20u32..140, seed in any::<u64>(),
        poses in proptest::collection::vec(pose(), 1..12),
        budget in proptest::option::of(200usize..4000), cache in prop_oneof![Just(u32::MAX), 1u32..40],
        tau in 0.5f32..4.0) {
        let dir = tempfile::tempdir().unwrap();
        let st = store(dir.path(), w, h, seed);
        let engine = TileEngine::new(&st);
        let p = params(cache, CrackMode::Patches);
        let mut session = TileSession::new(engine.shape().tile_count(), p, tau, 0.9);
        let mut mirror = TileMirror::new(engine.shape().clone(), p);
        let mut seq = 0;
        for &ps in &poses {
            let view = ViewState::new(&camera(w, h, ps), &lens());
            // A budgeted session takes several deltas to reach the target.
            for _ in 0..50 {
                let u = session.update(&engine, &view, budget.unwrap_or(usize::MAX));
                seq += 1;
                let wire = WireDelta { seq, digest: u.digest, body: u.delta.encode() };
                mirror.apply(&wire).unwrap();
                let active = mirror.active();
                prop_assert_eq!(&active, &session.active());
                prop_assert!(covers_once(&engine, &active));
                prop_assert_eq!(restriction_violations(engine.shape(), &active), 0);
                if u.complete { break; }
            }
            let sel = engine.select(&view, tau, 0.9, session.split(), false);
            let selected: Vec<u32> = engine.active_of(&sel.split).iter().collect();
            prop_assert!(selected == session.active() || budget.is_some());
        }
    }

    #[test]
    fn a_camera_at_rest_changes_nothing(w in 20u32..100, h in 20u32..100, seed in any::<u64>(), ps in pose()) {
        let dir = tempfile::tempdir().unwrap();
        let st = store(dir.path(), w, h, seed);
        let engine = TileEngine::new(&st);
        let mut session = TileSession::new(engine.shape().tile_count(), params(u32::MAX, CrackMode::Skirts), 1.0, 0.9);
        let view = ViewState::new(&camera(w, h, ps), &lens());
        let first = session.update(&engine, &view, usize::MAX);
        prop_assert!(!first.delta.is_empty());
        let again = session.update(&engine, &view, usize::MAX);
        prop_assert!(again.delta.is_empty());
        prop_assert_eq!(again.digest, first.digest);
    }
}

#[test]
fn an_unbudgeted_delta_over_the_largest_body_goes_out_in_parts() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (200, 160);
    let st = store(dir.path(), w, h, 11);
    let engine = TileEngine::new(&st);
    let p = params(u32::MAX, CrackMode::Patches);
    let view = ViewState::new(&camera(w, h, (0.5, 0.5, 0.0, 0.3, 0.9)), &lens());
    let mut whole = TileSession::new(engine.shape().tile_count(), p, 0.5, 0.9);
    let one = whole.update(&engine, &view, usize::MAX);
    assert!(one.complete);
    let one_len = one.delta.encode().len();
    let cap = one_len / 6;
    let mut parted = TileSession::new(engine.shape().tile_count(), p, 0.5, 0.9).with_max_body(cap);
    let mut mirror = TileMirror::new(engine.shape().clone(), p);
    let mut parts = 0;
    for seq in 1..100 {
        let u = parted.update(&engine, &view, usize::MAX);
        let body = u.delta.encode();
        // A part passes the cap by at most the one split it always makes.
        assert!(
            body.len() < cap * 2,
            "a part of {} bytes against {cap}",
            body.len()
        );
        let wire = WireDelta {
            seq,
            digest: u.digest,
            body,
        };
        mirror.apply(&wire).unwrap();
        assert_eq!(restriction_violations(engine.shape(), &mirror.active()), 0);
        parts += 1;
        if u.complete {
            break;
        }
    }
    assert!(
        parts >= 4,
        "{parts} parts for {one_len} bytes at {cap} a part"
    );
    assert_eq!(mirror.active(), whole.active());
}

#[test]
fn tiles_are_sent_once_and_then_come_from_the_cache() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (120, 90);
    let st = store(dir.path(), w, h, 7);
    let engine = TileEngine::new(&st);
    let mut session = TileSession::new(
        engine.shape().tile_count(),
        params(u32::MAX, CrackMode::Patches),
        1.0,
        0.9,
    );
    let near: Pose = (0.5, 0.5, 0.0, 0.3, 0.9);
    let far: Pose = (0.5, 0.5, 1.0, 0.3, 0.0);
    let mut sent = std::collections::HashSet::new();
    for k in 0..6 {
        let c = camera(w, h, if k % 2 == 0 { near } else { far });
        let u = session.update(&engine, &ViewState::new(&c, &lens()), usize::MAX);
        for a in &u.delta.added {
            if a.body.is_some() {
                assert!(sent.insert(a.tile), "tile {} sent twice", a.tile);
            }
        }
    }
    assert!(sent.len() > 4);
}

#[test]
fn the_restriction_forces_splits_only_where_needed() {
    let dir = tempfile::tempdir().unwrap();
    let st = store(dir.path(), 200, 200, 3);
    let engine = TileEngine::new(&st);
    let shape = engine.shape();
    // Split one finest-level path down the north-west corner by hand: a chain of levels.
    let mut split = super::bits::TileBits::new(shape.tile_count());
    let mut t = relief_proto::tile::TileId::ROOT;
    while t.level < shape.depth() {
        split.insert(shape.index(t));
        t = t.child(0);
    }
    let before = split.len();
    let forced = engine.restrict(&mut split);
    assert_eq!(split.len(), before + forced as usize);
    let active: Vec<u32> = engine.active_of(&split).iter().collect();
    assert_eq!(restriction_violations(shape, &active), 0);
    assert!(covers_once(&engine, &active));
}
