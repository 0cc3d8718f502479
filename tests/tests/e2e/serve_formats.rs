//! End to end over 127.0.0.1: the standard formats from the real server. Cesium's
//! `layer.json` and quantized-mesh tiles decode to the mesh Relief meant to send, with the
//! extensions the `Accept` header asks for; terrain-RGB and Terrarium PNG tiles decode to
//! Relief's heights within half an encoding step; TileJSON describes them; tiles carry ETags,
//! gzip where it helps, and CORS; bad addresses get 400 or 404 and the server goes on.

use relief_server::formats::cesium::{TILE_POINTS, tile_mesh};
use relief_server::formats::quantized_mesh::decode;
use relief_server::formats::sampler::{Points, Resampler};
use relief_server::formats::terrain_rgb::{Encoding, decode_png};
use relief_server::geo::tiling::{Scheme, TileXyz};
use relief_server::serve::config::Limits;
use relief_tests::TestServer;
use relief_tests::http::{get, header};
use std::io::Read;

fn gunzip(b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(b)
        .read_to_end(&mut out)
        .unwrap();
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cesium_layer_and_tiles_decode_to_the_meant_mesh() {
    let server = TestServer::start(Limits::default()).await;
    let t = server.state.terrain().unwrap();
    let f = t
        .formats
        .as_ref()
        .expect("the embedded crop is georeferenced");

    let (status, hs, body) = get(&server, "/cesium/layer.json", &[]).await;
    assert_eq!(status, 200);
    assert_eq!(header(&hs, "access-control-allow-origin"), Some("*"));
    let layer: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(layer["format"], "quantized-mesh-1.0");
    assert_eq!(layer["scheme"], "tms");
    let max = layer["maxzoom"].as_u64().unwrap() as u8;
    assert_eq!(max, f.cesium.max_level);
    assert_eq!(
        layer["available"].as_array().unwrap().len(),
        max as usize + 1
    );
    // 3" samples in 65-point tiles: level 12 is as fine as the store.
    assert_eq!(max, 12);

    // The finest level's first tile, and a coarse one.
    for z in [max, 9, 0] {
        let r = f.cesium.ranges[z as usize];
        let tile = TileXyz {
            z,
            x: r.start_x,
            y: r.start_y,
        };
        let url = format!("/cesium/{}/{}/{}.terrain", tile.z, tile.x, tile.y);
        let accept = "Accept: application/vnd.quantized-mesh;extensions=octvertexnormals-metadata,application/octet-stream;q=0.9,*/*;q=0.01";
        let (status, hs, gz) = get(&server, &url, &[accept, "Accept-Encoding: gzip"]).await;
        assert_eq!(status, 200, "{url}");
        assert_eq!(header(&hs, "content-encoding"), Some("gzip"));
        assert_eq!(
            header(&hs, "content-type"),
            Some("application/vnd.quantized-mesh;extensions=octvertexnormals-metadata")
        );
        let etag = header(&hs, "etag").unwrap().to_string();
        let tile_bytes = gunzip(&gz);
        let got = decode(&tile_bytes).unwrap();
        assert!(got.normals.is_some() && got.metadata.is_some(), "{url}");
        // The mesh Relief meant to send: same counts, positions within a quantization step.
        let r = Resampler::new(&t.store, &f.geo);
        let want = tile_mesh(&r, t.store.tile_mesh(), tile);
        assert_eq!(got.u.len(), want.vertices.len(), "{url}");
        assert_eq!(got.triangles.len(), want.triangles.len(), "{url}");
        let b = want.bounds;
        let pos = got.positions(b.west, b.south, b.east, b.north);
        let (lo, hi) = (
            f64::from(got.header.min_height),
            f64::from(got.header.max_height),
        );
        let dz = (hi - lo) / 32767.0;
        let (dx, dy) = ((b.east - b.west) / 32767.0, (b.north - b.south) / 32767.0);
        let mut sorted_got: Vec<[f64; 3]> = pos.clone();
        let mut sorted_want = want.vertices.clone();
        let key = |p: &[f64; 3]| ((p[1] * 1e6).round() as i64, (p[0] * 1e6).round() as i64);
        sorted_got.sort_by_key(key);
        sorted_want.sort_by_key(key);
        for (g, w) in sorted_got.iter().zip(&sorted_want) {
            assert!(
                (g[0] - w[0]).abs() <= dx && (g[1] - w[1]).abs() <= dy,
                "{url}"
            );
            assert!((g[2] - w[2]).abs() <= dz.max(1e-3), "{url}: {g:?} {w:?}");
        }
        if z == max {
            assert_eq!(
                got.u.len(),
                TILE_POINTS * TILE_POINTS,
                "grid keeps every point"
            );
        }
        // Revalidation, and the bare tile without extensions for a plain Accept.
        let (s304, _, _) = get(&server, &url, &[accept, &format!("If-None-Match: {etag}")]).await;
        assert_eq!(s304, 304);
        let (_, hs, plain) = get(&server, &url, &[]).await;
        assert_eq!(
            header(&hs, "content-type"),
            Some("application/vnd.quantized-mesh")
        );
        let bare = decode(&plain).unwrap();
        assert!(bare.normals.is_none() && bare.metadata.is_none());
        assert_ne!(header(&hs, "etag").unwrap(), etag);
    }
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn png_tiles_carry_relief_heights_within_half_a_step() {
    let server = TestServer::start(Limits::default()).await;
    let t = server.state.terrain().unwrap();
    let f = t.formats.as_ref().unwrap();
    for enc in [Encoding::TerrainRgb, Encoding::Terrarium] {
        for size in [256u32, 512] {
            let q = if size == 512 { "?tile_size=512" } else { "" };
            let (status, hs, body) =
                get(&server, &format!("/tiles/{}.json{q}", enc.name()), &[]).await;
            assert_eq!(status, 200);
            assert_eq!(header(&hs, "access-control-allow-origin"), Some("*"));
            let tj: serde_json::Value = serde_json::from_slice(&body).unwrap();
            assert_eq!(tj["tileSize"], size);
            assert_eq!(tj["encoding"], enc.maplibre_name());
            let url = tj["tiles"][0].as_str().unwrap();
            assert!(url.starts_with("http://127.0.0.1/tiles/"), "{url}");
            let max = tj["maxzoom"].as_u64().unwrap() as u8;
            let layer = &f.raster[usize::from(size == 512)];
            let r = Scheme::Mercator.range(&layer.bounds, max).unwrap();
            let tile = TileXyz {
                z: max,
                x: r.start_x,
                y: r.start_y,
            };
            let path = url
                .trim_start_matches("http://127.0.0.1")
                .split('?')
                .next()
                .unwrap()
                .replace("{z}", &tile.z.to_string())
                .replace("{x}", &tile.x.to_string())
                .replace("{y}", &tile.y.to_string());
            let (status, hs, png) = get(&server, &path, &["Accept-Encoding: gzip"]).await;
            assert_eq!(status, 200, "{path}");
            assert_eq!(header(&hs, "content-type"), Some("image/png"));
            assert_eq!(
                header(&hs, "content-encoding"),
                None,
                "PNGs are not gzipped again"
            );
            let (w, h, z) = decode_png(&png, enc).unwrap();
            assert_eq!((w, h), (size, size));
            let want = Resampler::new(&t.store, &f.geo).tile(
                Scheme::Mercator,
                tile,
                size as usize,
                Points::Centres,
            );
            let half = enc.step() / 2.0 + 1e-6;
            let mut inside = 0;
            for (g, w) in z.iter().zip(&want) {
                let w = w.unwrap_or(0.0);
                assert!(f64::from((g - w).abs()) <= half, "{path}: {g} vs {w}");
                inside += usize::from(w != 0.0);
            }
            assert!(inside > 0, "{path} holds no terrain");
        }
    }
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_format_addresses_get_400_or_404_and_the_server_goes_on() {
    let server = TestServer::start(Limits::default()).await;
    for (path, want) in [
        ("/cesium/a/0/0.terrain", 400),
        ("/cesium/0/0/x.terrain", 400),
        ("/cesium/0/0/0.png", 400),
        ("/cesium/99/0/0.terrain", 400),
        ("/cesium/0/2/0.terrain", 404),
        ("/cesium/12/0/0.terrain", 404),
        ("/cesium/13/0/0.terrain", 404),
        ("/tiles/geotiff.json", 404),
        ("/tiles/terrain-rgb.json?tile_size=300", 400),
        ("/tiles/terrain-rgb/0/0/0.jpg", 400),
        ("/tiles/terrain-rgb/4294967296/0/0.png", 400),
        ("/tiles/terrain-rgb/3/0/0.png", 404),
        ("/tiles/terrarium/30/0/0.png", 400),
        ("/tiles/elevation/0/0/0.png", 404),
    ] {
        let (status, _, body) = get(&server, path, &[]).await;
        let text = String::from_utf8_lossy(&body);
        assert_eq!(status, want, "{path}: {text}");
        assert!(text.contains("error"), "{path}: {text}");
    }
    let (status, _, _) = get(&server, "/cesium/0/1/0.terrain", &[]).await;
    assert_eq!(status, 200);
    server.stop().await;
}

/// The loop users close: Relief's PNG tiles saved as a `Z/X/Y.png` folder and built back by
/// Relief's terrain-tile reader (a mosaic) give Relief's heights at every pixel inside the
/// terrain, within half an encoding step: the writer and the reader place pixels alike.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn served_png_tiles_read_back_as_a_mosaic_give_relief_heights() {
    use relief_server::dem::{LoadOptions, load_all};
    use relief_server::geo::GeoTransform;
    let server = TestServer::start(Limits::default()).await;
    let t = server.state.terrain().unwrap();
    let f = t.formats.as_ref().unwrap();
    let layer = &f.raster[0];
    let z = layer.max_level;
    let range = Scheme::Mercator.range(&layer.bounds, z).unwrap();
    let r = Resampler::new(&t.store, &f.geo);
    for enc in [Encoding::TerrainRgb, Encoding::Terrarium] {
        let dir = tempfile::tempdir().unwrap();
        let mut files = Vec::new();
        for y in range.start_y..=range.end_y {
            for x in range.start_x..=range.end_x {
                let path = format!("/tiles/{}/{z}/{x}/{y}.png", enc.name());
                let (status, _, png) = get(&server, &path, &[]).await;
                assert_eq!(status, 200, "{path}");
                let file = dir.path().join(format!("{z}/{x}/{y}.png"));
                std::fs::create_dir_all(file.parent().unwrap()).unwrap();
                std::fs::write(&file, png).unwrap();
                files.push(file.to_string_lossy().to_string());
            }
        }
        let opts = LoadOptions {
            encoding: Some(enc),
            ..LoadOptions::default()
        };
        let dem = load_all(&files, &opts).unwrap();
        let g = dem.georef.clone().expect("tiles are placed by their z/x/y");
        assert_eq!(g.epsg, 3857);
        let back = GeoTransform::new(&g).unwrap();
        let (mut checked, mut worst) = (0usize, 0f64);
        for row in (0..dem.height).step_by(3) {
            for col in (0..dem.width).step_by(3) {
                let [lon, lat] = back.lonlat(col as f64, row as f64).unwrap();
                // Pixels outside the terrain hold 0 m; compare those inside.
                if let Some(want) = r.at(lon, lat) {
                    let got = dem.at(col, row);
                    worst = worst.max(f64::from((got - want).abs()));
                    checked += 1;
                }
            }
        }
        assert!(checked > 1000, "{checked} pixels inside the terrain");
        // Half a step, plus what the round trip through the projection moves a pixel centre
        // (a micrometre here, worth well under a millimetre of height).
        assert!(
            worst <= enc.step() / 2.0 + 1e-3,
            "{}: worst {worst} m over {checked} pixels",
            enc.name()
        );
        println!(
            "{}: {} tiles at zoom {z} read back; {checked} pixels, worst {worst:.4} m (half a step {:.4} m)",
            enc.name(),
            files.len(),
            enc.step() / 2.0
        );
    }
    server.stop().await;
}
