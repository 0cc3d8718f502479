//! The tile stream drawn by the wgpu client against the real server, offscreen (lavapipe in
//! CI): the crack test in images along the standard path, looking ahead, down and
//! grazing, on a magenta background. With crack patches, and with skirts, no background shows
//! through the terrain; with nothing against cracks it does (so the test can fail). It also
//! prints what paper 001's rule alone (dropped patches, no raised ones) would leave.
//!
//! The same for the adaptive meshes `rqt` (crack curtains, or skirts) and `tin` (shared
//! borders, or skirts).
//!
//! The server serves the embedded crop built with 16-cell tiles (five levels, so level seams
//! and patches are everywhere), and frames are drawn one pose interval after their pose, as
//! `shot` and `render-bench` draw them: tiles that arrived by a split are mid-morph.

use relief_client::render::frame::rgb8;
use relief_client::render::offscreen::{FORMAT, Offscreen, enclosed_background};
use relief_client::render::{FrameParams, Gpu, TileRenderer, TileScene};
use relief_client::session::{Session, SessionConfig};
use relief_proto::msg::{CrackMode, StreamKind, TileStreamParams};
use relief_proto::tile::body::MeshKind;
use relief_proto::view::Lens;
use relief_tests::{TestServer, path};
use std::time::Instant;

/// Tile size of the test's store: small, for many levels on the small crop.
const TILE: u32 = 16;

/// Poses a second along the path (the morph's clock: frames are drawn one interval late).
const HZ: f32 = 10.0;

/// Magenta: no terrain colour comes near it.
const BG: [u8; 3] = [255, 0, 255];

fn lens() -> Lens {
    Lens {
        width: 480,
        height: 270,
        fov_y_deg: 60.0,
        near: 1.0,
    }
}

/// What one flight saw.
#[derive(Debug, Default)]
struct Holes {
    /// Frames checked.
    frames: usize,
    /// Enclosed background pixels over all frames.
    pixels: usize,
    /// (pose, pitch in degrees, pixels) of the frames with holes, and where the first is saved.
    at: Vec<(usize, f32, usize)>,
    /// Patch triangles drawn in the checked frames (to show the patches are exercised).
    patch_triangles: usize,
    /// Tiles drawn mid-morph, summed over the checked frames.
    morphing: usize,
    /// Pixels that differ between one view drawn on arrival of morphing tiles and settled.
    morph_moved: usize,
    /// Tile levels active in the checked frames.
    levels: std::collections::BTreeSet<u8>,
}

/// Flies 160 poses of the standard path with a tile session in `crack` mode at `tau` and counts
/// the enclosed background pixels every fourth pose, looking ahead, down (-80 degrees) and
/// grazing (-3 degrees). Returns the counts drawn with every patch, and with the dropped ones
/// alone.
async fn fly(gpu: &Gpu, url: &str, crack: CrackMode, tau: f32) -> (Holes, Holes) {
    let config = SessionConfig {
        lens: lens(),
        tau,
        stream: StreamKind::Tiles(TileStreamParams {
            cache_tiles: 256,
            crack,
        }),
        ..SessionConfig::new(url)
    };
    let mut session = Session::connect(config).await.unwrap();
    let mut scene = TileScene::new(&session);
    let mut renderer = TileRenderer::new(gpu, FORMAT, &mut scene);
    let target = Offscreen::new(gpu, lens().width, lens().height);
    let (mut all, mut dropped) = (Holes::default(), Holes::default());
    for (k, cam) in path(0, 160).iter().enumerate() {
        let seq = session.send_pose(*cam).await.unwrap();
        session.wait_for_pose(seq).await.unwrap();
        let now = k as f32 / HZ;
        scene.sync(&session, now);
        renderer.upload(gpu, &mut scene);
        if k % 4 != 3 {
            continue;
        }
        // Drawn one pose interval later, as `shot` and `render-bench` draw (the tiles of this
        // pose's splits at alpha 0.4), or at once (alpha 0: on their parent's mesh).
        let drawn_at = now + if k % 8 == 7 { 1.0 / HZ } else { 0.0 };
        let morphing = scene
            .active
            .iter()
            .filter(|&&i| scene.arrival(i) > drawn_at - 0.25)
            .count();
        if morphing > 0 && all.morph_moved == 0 {
            // The morph shows: the same view drawn on arrival and once settled differs.
            let mut at = |t: f32| {
                let p = FrameParams {
                    background: rgb8(BG),
                    ..FrameParams::offscreen(&session, *cam, lens(), t)
                };
                renderer.render(gpu, &target.view, &p);
                target.read(gpu).unwrap()
            };
            let (a, b) = (at(now), at(now + 1.0));
            all.morph_moved = a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count();
        }
        let shape = session.tiles().unwrap().mirror().shape().clone();
        let levels: Vec<u8> = scene
            .active
            .iter()
            .map(|&i| shape.tile(i).unwrap().level)
            .collect();
        let views = relief_tests::crack_views(*cam);
        for c in views {
            for (dropped_only, holes) in [(false, &mut all), (true, &mut dropped)] {
                let p = FrameParams {
                    background: rgb8(BG),
                    dropped_only,
                    ..FrameParams::offscreen(&session, c, lens(), drawn_at)
                };
                renderer.render(gpu, &target.view, &p);
                let img = target.read(gpu).unwrap();
                let n = enclosed_background(&img, BG);
                if n > 0 {
                    if holes.at.is_empty() {
                        let name = format!("relief-tile-crack-{crack:?}-{tau}-{dropped_only}.png");
                        img.save(std::env::temp_dir().join(name)).unwrap();
                    }
                    holes.at.push((k, c.pitch.to_degrees().round(), n));
                }
                if c == views[1] && !dropped_only && crack != CrackMode::None {
                    let total = img.pixels().filter(|p| [p[0], p[1], p[2]] == BG).count();
                    assert_eq!(total, 0, "pose {k}: looking down, the tiles fill the frame");
                }
                holes.pixels += n;
                holes.frames += 1;
                holes.morphing += morphing;
                holes.levels.extend(levels.iter().copied());
                holes.patch_triangles += scene
                    .meshes
                    .values()
                    .map(|m| {
                        let [_, d, r, _] = m.counts;
                        (d + if dropped_only { 0 } else { r }) as usize
                    })
                    .sum::<usize>();
            }
        }
    }
    let c = session.counters();
    assert_eq!(c.desyncs, 0, "tile digests all matched");
    assert!(c.tiles_sent > 0, "{c:?}");
    session.close().await;
    (all, dropped)
}

/// A server of the embedded crop built with 16-cell tiles meshed as `mesh`, and its folder.
async fn serve(mesh: MeshKind) -> (tempfile::TempDir, TestServer) {
    relief_tests::serve_tiles_of(TILE, mesh).await
}

/// The adaptive meshes along the same path at tau 1 and 8: `rqt` tiles with their
/// crack curtains (the session asks for patches) or with skirts, and `tin` tiles with their
/// shared borders alone (the session asks for patches; `tin` tiles carry none) or with skirts
/// show no crack; `rqt` tiles with nothing do (so the test can see the cracks that adaptive
/// tiles open).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn adaptive_tiles_show_no_cracks_with_curtains_skirts_or_shared_borders() {
    let gpu = Gpu::headless().unwrap_or_else(|e| panic!("{e}"));
    let (_dir, rqt) = serve(MeshKind::Rqt).await;
    let (_dir2, tin) = serve(MeshKind::Tin).await;
    let mut rqt_none = 0;
    for tau in [1.0, 8.0] {
        let (curtains, _) = fly(&gpu, &rqt.url(), CrackMode::Patches, tau).await;
        let (rqt_skirts, _) = fly(&gpu, &rqt.url(), CrackMode::Skirts, tau).await;
        let (none, _) = fly(&gpu, &rqt.url(), CrackMode::None, tau).await;
        let (shared, _) = fly(&gpu, &tin.url(), CrackMode::Patches, tau).await;
        let (tin_skirts, _) = fly(&gpu, &tin.url(), CrackMode::Skirts, tau).await;
        eprintln!(
            "tau {tau}: enclosed background pixels over {} frames: rqt+patches {} ({} curtain \
             triangles drawn, levels {:?}), rqt+skirts {}, rqt+none {} (in {} frames), \
             tin+shared-borders {}, tin+skirts {}; levels {:?}",
            rqt_skirts.frames,
            curtains.pixels,
            curtains.patch_triangles,
            curtains.levels,
            rqt_skirts.pixels,
            none.pixels,
            none.at.len(),
            shared.pixels,
            tin_skirts.pixels,
            shared.levels,
        );
        assert!(
            shared.frames >= 120 && shared.levels.len() >= 3,
            "{shared:?}"
        );
        assert!(
            curtains.frames >= 120 && curtains.levels.len() >= 3,
            "{curtains:?}"
        );
        assert!(
            curtains.patch_triangles > 0,
            "no curtain was drawn: not a test of them"
        );
        assert_eq!(curtains.pixels, 0, "rqt+patches: {:?}", curtains.at);
        assert_eq!(rqt_skirts.pixels, 0, "rqt+skirts: {:?}", rqt_skirts.at);
        assert_eq!(shared.pixels, 0, "tin+shared-borders: {:?}", shared.at);
        assert_eq!(tin_skirts.pixels, 0, "tin+skirts: {:?}", tin_skirts.at);
        rqt_none += none.pixels;
    }
    assert!(
        rqt_none > 0,
        "rqt tiles with nothing show no crack: the test cannot see them"
    );
    rqt.stop().await;
    tin.stop().await;
}

/// The standard path at tau 1 and at tau 8, on the crop's 16-cell tile pyramid.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tiles_show_no_cracks_with_patches_or_skirts_and_cracks_without() {
    let t0 = Instant::now();
    let (_dir, server) = serve(MeshKind::Grid).await;
    let built = t0.elapsed();
    let gpu = Gpu::headless().unwrap_or_else(|e| panic!("{e}"));
    let url = server.url();
    let (mut none_total, mut morphing, mut moved) = (0, 0, 0);
    for tau in [1.0, 8.0] {
        let (patches, dropped_only) = fly(&gpu, &url, CrackMode::Patches, tau).await;
        let (skirts, _) = fly(&gpu, &url, CrackMode::Skirts, tau).await;
        let (none, _) = fly(&gpu, &url, CrackMode::None, tau).await;
        eprintln!(
            "tau {tau}: enclosed background pixels over {} frames: patches {} ({} patch \
             triangles drawn, {} tiles mid-morph summed over frames, {} pixels moved by a morph, \
             levels {:?}), skirts {}, none {} (in {} \
             frames), dropped patches only {} (in {} frames: {:?})",
            patches.frames,
            patches.pixels,
            patches.patch_triangles,
            patches.morphing,
            patches.morph_moved,
            patches.levels,
            skirts.pixels,
            none.pixels,
            none.at.len(),
            dropped_only.pixels,
            dropped_only.at.len(),
            dropped_only.at,
        );
        assert!(patches.frames >= 120, "{} frames checked", patches.frames);
        assert!(
            patches.patch_triangles > 0,
            "no patch was drawn: not a test of them"
        );
        assert!(
            patches.levels.len() >= 3,
            "level seams of at least three levels: {:?}",
            patches.levels
        );
        assert_eq!(
            patches.pixels, 0,
            "tau {tau}: cracks with patches: {:?}",
            patches.at
        );
        assert_eq!(
            skirts.pixels, 0,
            "tau {tau}: cracks with skirts: {:?}",
            skirts.at
        );
        none_total += none.pixels;
        morphing += patches.morphing;
        moved += patches.morph_moved;
    }
    assert!(
        morphing > 0,
        "no tile was drawn mid-morph: not a test of the morph"
    );
    assert!(moved > 0, "the morph moves nothing on screen");
    assert!(
        none_total > 0,
        "without patches or skirts no crack shows: the test cannot see cracks"
    );
    eprintln!(
        "store built in {:.1} s; test {:.1} s",
        built.as_secs_f64(),
        t0.elapsed().as_secs_f64()
    );
    server.stop().await;
}
