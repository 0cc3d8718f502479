//! End to end over 127.0.0.1: the tile stream. Tile sessions resume after a dropped
//! connection, stay consistent under a budget, are never sent a tile twice with an unlimited
//! cache (and are re-sent evicted tiles with a small one), run beside vertex sessions on one
//! server; the tile pyramid over HTTP, with ETags, gzip and clear errors for bad requests.

use relief_client::session::{Session, SessionConfig};
use relief_proto::msg::{CrackMode, StreamKind, TileStreamParams};
use relief_proto::tile::body::decode_mesh;
use relief_proto::tile::delta::get_varint;
use relief_proto::tile::snapshot::restriction_violations;
use relief_proto::view::Camera;
use relief_server::serve::config::Limits;
use relief_tests::http::{get as http, header};
use relief_tests::{TestServer, fly, path};
use std::io::Read;

fn tiles_config(url: &str, cache: u32, budget: Option<u32>) -> SessionConfig {
    let mut c = SessionConfig::new(url);
    c.stream = StreamKind::Tiles(TileStreamParams {
        cache_tiles: cache,
        crack: CrackMode::Patches,
    });
    c.budget = budget;
    c
}

fn active(s: &Session) -> Vec<u32> {
    s.tiles().expect("a tile session").mirror().active()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dropped_tile_session_resumes_to_the_same_tiles() {
    let server = TestServer::start(Limits::default()).await;
    let cams = path(1, 80);
    let whole = fly(tiles_config(&server.url(), u32::MAX, None), &cams, None).await;
    let resumed = fly(tiles_config(&server.url(), u32::MAX, None), &cams, Some(40)).await;
    let c = resumed.counters();
    assert_eq!((c.reconnects, c.resumes, c.desyncs), (1, 1, 0), "{c:?}");
    assert_eq!(active(&whole), active(&resumed));
    assert!(active(&whole).len() > 1);
    assert!(
        server
            .state
            .metrics
            .render()
            .contains("relief_resumes_total 1")
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_budgeted_tile_session_stays_restricted_and_within_budget() {
    let server = TestServer::start(Limits::default()).await;
    let budget = 6_000u32;
    let mut s = Session::connect(tiles_config(&server.url(), u32::MAX, Some(budget)))
        .await
        .unwrap();
    let shape = s.tiles().unwrap().mirror().shape().clone();
    let t0 = std::time::Instant::now();
    let (mut incomplete, mut largest) = (0, 0);
    for cam in &path(0, 12) {
        let seq = s.send_pose(*cam).await.unwrap();
        for a in s.wait_for_pose(seq).await.unwrap() {
            incomplete += usize::from(!a.complete);
            largest = largest.max(a.bytes);
            // Every delta, complete or not, leaves a restricted set.
            assert_eq!(restriction_violations(&shape, &active(&s)), 0);
        }
    }
    let secs = t0.elapsed().as_secs_f64();
    let c = s.counters();
    assert_eq!(c.desyncs, 0);
    assert!(incomplete > 0, "no delta was held back by the budget");
    // A delta always makes one split of progress, so one split's bytes may overshoot the
    // one-second burst; beyond that the rate holds.
    let allowed = budget as f64 * (secs + 1.0) + largest as f64 + 64.0 * c.deltas as f64;
    assert!(
        (c.bytes_in as f64) <= allowed,
        "{} bytes in {secs:.2} s exceeds {allowed:.0}",
        c.bytes_in
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tiles_are_sent_once_with_an_unlimited_cache_and_again_after_eviction() {
    let server = TestServer::start(Limits::default()).await;
    let tiles = server
        .state
        .terrain()
        .unwrap()
        .store
        .tile_shape()
        .tile_count() as u64;
    // Back and forth between far and near poses, many times.
    let cams: Vec<Camera> = path(0, 300).into_iter().step_by(5).collect();
    let unlimited = fly(tiles_config(&server.url(), u32::MAX, None), &cams, None).await;
    let u = unlimited.counters();
    assert_eq!(u.desyncs, 0);
    assert!(
        u.tiles_sent <= tiles,
        "{} tiles sent, the pyramid has {tiles}",
        u.tiles_sent
    );
    assert!(u.tiles_from_cache > 0, "{u:?}");
    let small = fly(tiles_config(&server.url(), 4, None), &cams, None).await;
    let c = small.counters();
    assert_eq!(c.desyncs, 0);
    assert!(
        c.tiles_sent > u.tiles_sent,
        "evicted tiles were not sent again: {c:?} vs {u:?}"
    );
    assert_eq!(active(&small), active(&unlimited));
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn vertex_and_tile_sessions_share_one_server() {
    let server = TestServer::start(Limits::default()).await;
    let mut tasks = Vec::new();
    for i in 0..12 {
        let url = server.url();
        tasks.push(tokio::spawn(async move {
            let config = if i % 2 == 0 {
                SessionConfig::new(&url)
            } else {
                tiles_config(&url, 64, None)
            };
            let s = fly(config, &path(i, 30), None).await;
            let c = s.counters();
            (s.is_tiles(), c.desyncs, c.deltas)
        }));
    }
    let mut kinds = (0, 0);
    for t in tasks {
        let (tiles, desyncs, deltas) = t.await.unwrap();
        assert_eq!(desyncs, 0);
        assert!(deltas >= 30);
        if tiles {
            kinds.1 += 1;
        } else {
            kinds.0 += 1;
        }
    }
    assert_eq!(kinds, (6, 6));
    assert!(
        server
            .state
            .metrics
            .render()
            .contains("relief_sessions_total 12")
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_pyramid_over_http_with_etags_gzip_and_clear_errors() {
    let server = TestServer::start(Limits::default()).await;
    let terrain = server.state.terrain().unwrap();
    let shape = terrain.store.tile_shape().clone();

    let (status, _, body) = http(&server, "/v1/tiles.json", &[]).await;
    assert_eq!(status, 200);
    let j: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(j["tile_size"], 64);
    assert_eq!(j["depth"], shape.depth());
    assert_eq!(
        j["levels"].as_array().unwrap().len(),
        shape.depth() as usize + 1
    );

    // A tile of the finest level: its mesh decodes to the store's heights.
    let t = relief_proto::tile::TileId {
        level: shape.depth(),
        x: 1,
        y: 1,
    };
    let url = format!("/v1/tiles/{}/{}/{}", t.level, t.x, t.y);
    let (status, hs, body) = http(&server, &url, &[]).await;
    assert_eq!(status, 200);
    let etag = header(&hs, "etag").expect("an ETag").to_string();
    assert!(header(&hs, "cache-control").unwrap().contains("max-age"));
    let mut at = 0;
    let mesh_len = get_varint(&body, &mut at).unwrap() as usize;
    let patch_len = get_varint(&body, &mut at).unwrap() as usize;
    assert_eq!(at + mesh_len + patch_len, body.len());
    let z = decode_mesh(&shape.span(t), &body[at..at + mesh_len]).unwrap();
    let (mesh, _) = terrain.store.tile_blobs(shape.index(t));
    assert_eq!(z, decode_mesh(&shape.span(t), mesh).unwrap());

    // Revalidation: the same ETag is not sent again.
    let (status, _, body304) = http(&server, &url, &[&format!("If-None-Match: {etag}")]).await;
    assert_eq!((status, body304.len()), (304, 0));
    // Gzip for clients that accept it.
    let (status, hs, gz) = http(&server, &url, &["Accept-Encoding: gzip"]).await;
    assert_eq!(status, 200);
    assert_eq!(header(&hs, "content-encoding"), Some("gzip"));
    let mut plain = Vec::new();
    flate2::read::GzDecoder::new(&gz[..])
        .read_to_end(&mut plain)
        .unwrap();
    assert_eq!(plain, body);
    // Without patches the body is shorter and has a different ETag.
    let (_, hs2, nop) = http(&server, &format!("{url}?crack=none"), &[]).await;
    assert!(nop.len() <= body.len());
    assert_ne!(header(&hs2, "etag").unwrap(), etag);

    // Bad requests get a JSON error that names the problem.
    for (path, want, needle) in [
        ("/v1/tiles/a/0/0", 400, "level"),
        ("/v1/tiles/0/-1/0", 400, "column"),
        ("/v1/tiles/99/0/0", 404, "levels go from 0"),
        ("/v1/tiles/1/7/0", 404, "does not exist"),
        ("/v1/tiles/0/0/0?crack=glue", 400, "crack"),
    ] {
        let (status, _, body) = http(&server, path, &[]).await;
        let text = String::from_utf8_lossy(&body);
        assert_eq!(status, want, "{path}: {text}");
        assert!(text.contains(needle), "{path}: {text}");
    }
    // And the server goes on serving.
    let s = fly(
        tiles_config(&server.url(), u32::MAX, None),
        &path(2, 5),
        None,
    )
    .await;
    assert_eq!(s.counters().desyncs, 0);
    server.stop().await;
}

/// `rqt+patches`: an `rqt` terrain serves its tiles' crack curtains in the patch slot,
/// over HTTP (`?crack=patches`, none with `?crack=skirts`) and in tile sessions asking for
/// patches, and a client decodes and draws them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rqt_tiles_carry_their_curtains_over_http_and_in_sessions() {
    use relief_proto::tile::body::MeshKind;
    use relief_proto::tile::body::curtain::decode_tile_curtains;
    let (_dir, server) = relief_tests::serve_tiles_of(16, MeshKind::Rqt).await;
    let shape = server.state.terrain().unwrap().store.tile_shape().clone();
    let t = relief_proto::tile::TileId {
        level: 2,
        x: 1,
        y: 1,
    };
    let url = format!("/v1/tiles/{}/{}/{}", t.level, t.x, t.y);
    let split = |body: &[u8]| {
        let mut at = 0;
        let mesh_len = get_varint(body, &mut at).unwrap() as usize;
        let patch_len = get_varint(body, &mut at).unwrap() as usize;
        assert_eq!(at + mesh_len + patch_len, body.len());
        (
            body[at..at + mesh_len].to_vec(),
            body[at + mesh_len..].to_vec(),
        )
    };
    let (status, _, body) = http(&server, &format!("{url}?crack=patches"), &[]).await;
    assert_eq!(status, 200);
    let (mesh, curtains) = split(&body);
    let m = decode_mesh(&shape.span(t), &mesh).unwrap();
    let irr = m.irregular.as_ref().expect("an rqt mesh");
    let tris = decode_tile_curtains(&shape, t, irr, &m.z, &curtains).unwrap();
    assert!(!tris.is_empty(), "an inner tile has curtains");
    let (_, _, body) = http(&server, &format!("{url}?crack=skirts"), &[]).await;
    assert!(split(&body).1.is_empty());

    let s = fly(
        tiles_config(&server.url(), u32::MAX, None),
        &path(0, 20),
        None,
    )
    .await;
    assert_eq!(s.counters().desyncs, 0);
    let tiles = s.tiles().unwrap();
    let drawn: usize = tiles
        .mirror()
        .active()
        .iter()
        .map(|&i| tiles.mirror().tile(i).unwrap().patches.curtains.len())
        .sum();
    assert!(drawn > 0, "the session's tiles hold curtains");
    server.stop().await;
}
