//! End to end with the real web clients: the server's standard formats read by
//! CesiumJS and MapLibre GL JS in headless Chromium (Debian's `chromium`, driven by
//! playwright-core), and by an independent quantized-mesh decoder (@loaders.gl/terrain), all
//! against the real `relief-server` process on 127.0.0.1 serving the store of the committed
//! Mt Fuji crop. The node scripts are in `web/tests/`; each prints one line of JSON, and the
//! assertions are here, against Relief's own heights and meshes computed through the library
//! on the same store.
//!
//! - CesiumJS: `sampleTerrainMostDetailed` at 200 points against the store's heights, within
//!   the geometric error of the deepest level (and against the very mesh Relief sent, within
//!   its quantization); a screenshot against a committed golden image; the page's request log
//!   stays on loopback.
//! - MapLibre: `queryTerrainElevation` at 200 points, terrain-RGB and Terrarium, against the
//!   heights Relief encoded in the DEM tiles MapLibre read, within the encoding's step; a
//!   screenshot that is not blank.
//! - @loaders.gl/terrain decodes tiles at several levels into the vertices, triangles, edges
//!   and extensions Relief meant to send.
//! - Bad tile addresses get 400 or 404, never a 5xx, and the server keeps serving.
//!
//! They need Node.js 20+, Chromium and `web/node_modules`; without them they fail and say how
//! to install them (the README's test command does). `RELIEF_BLESS=1` rewrites the golden image
//! and the screenshots in `docs/img/`.

use relief_server::formats::cesium::{CesiumLayer, GeoMesh, tile_mesh};
use relief_server::formats::sampler::{Points, Resampler};
use relief_server::geo::GeoTransform;
use relief_server::geo::tiling::{Scheme, TileXyz, cesium_level_error};
use relief_server::store::Store;
use relief_tests::shots::{assert_golden, bless, not_blank};
use relief_tests::{ChildServer, free_addr, node_json, repo, test_store};
use serde_json::Value;
use std::collections::{HashMap, HashSet};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

const BIN: &str = env!("CARGO_BIN_EXE_relief-test-server");

/// One browser at a time: each is a few processes rendering WebGL in software.
static BROWSER: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

fn node_modules() -> PathBuf {
    repo().join("web/node_modules")
}

fn chromium() -> PathBuf {
    std::env::var_os("RELIEF_CHROMIUM").map_or_else(|| "/usr/bin/chromium".into(), PathBuf::from)
}

/// Fails, saying what to install, unless Node.js 20+, the npm packages and (with `browser`)
/// Chromium are there.
fn prerequisites(browser: bool) {
    let mut missing = Vec::new();
    match Command::new("node").arg("--version").output() {
        Ok(o) if o.status.success() => {
            let v = String::from_utf8_lossy(&o.stdout).trim().to_string();
            let major: u32 = v
                .trim_start_matches('v')
                .split('.')
                .next()
                .and_then(|m| m.parse().ok())
                .unwrap_or(0);
            if major < 20 {
                missing.push(format!(
                    "Node.js 20 or newer (found {v}; playwright-core refuses older ones, and \
                     Debian 12's own nodejs is 18: install Node.js 20 from nodejs.org or \
                     NodeSource)"
                ));
            }
        }
        _ => missing.push("Node.js (`node` is not on the PATH)".to_string()),
    }
    if browser && !chromium().is_file() {
        missing.push(format!(
            "Chromium at {} (Debian's `chromium` package)",
            chromium().display()
        ));
    }
    for pkg in [
        "playwright-core",
        "cesium",
        "maplibre-gl",
        "@loaders.gl/core",
        "@loaders.gl/terrain",
    ] {
        if !node_modules().join(pkg).join("package.json").is_file() {
            missing.push(format!(
                "the npm package {pkg} in {}",
                node_modules().display()
            ));
        }
    }
    assert!(
        missing.is_empty(),
        "the browser tests need {}.\nInstall them with the README's test command, which runs \
         (as root) `apt-get install -y chromium` (and `apt-get install -y nodejs npm` where \
         `node` is missing) and `npm ci --prefix web` before `cargo test`.",
        missing.join("; ")
    );
}

/// The real server on a free loopback port, serving the test store (the committed crop), with
/// the pages' libraries from `web/node_modules`.
async fn server() -> ChildServer {
    let lib = node_modules().display().to_string();
    ChildServer::start_env(Path::new(BIN), free_addr(), &["--web-lib", &lib], &[]).await
}

/// The store the server serves, and its placement on the Earth.
fn store() -> (Store, GeoTransform) {
    let store = Store::open(test_store()).expect("the test store");
    let georef = store
        .meta()
        .georef
        .clone()
        .expect("the committed crop is georeferenced");
    let geo = GeoTransform::new(&georef).expect("a usable georeference");
    (store, geo)
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_f64().unwrap_or(f64::NAN))
        .collect()
}

fn points(v: &Value) -> Vec<[f64; 2]> {
    v.as_array()
        .expect("points")
        .iter()
        .map(|p| {
            let p = f64s(p);
            [p[0], p[1]]
        })
        .collect()
}

/// Maximum and 99th percentile of `d`'s magnitudes.
fn max_p99(d: &[f64]) -> (f64, f64) {
    let mut a: Vec<f64> = d.iter().map(|x| x.abs()).collect();
    a.sort_by(f64::total_cmp);
    let p99 = a[((a.len() as f64 * 0.99).ceil() as usize).clamp(1, a.len()) - 1];
    (a[a.len() - 1], p99)
}

/// Asserts that every request in the page's log went to loopback (data: and blob: are local);
/// returns how many there were.
fn all_local(requests: &Value) -> usize {
    let urls: Vec<&str> = requests
        .as_array()
        .expect("a request log")
        .iter()
        .filter_map(Value::as_str)
        .collect();
    let foreign: Vec<&&str> = urls
        .iter()
        .filter(|u| {
            !(u.starts_with("http://127.0.0.1:")
                || u.starts_with("http://localhost:")
                || u.starts_with("data:")
                || u.starts_with("blob:"))
        })
        .collect();
    assert!(foreign.is_empty(), "requests left localhost: {foreign:?}");
    urls.len()
}

// ---------------------------------------------------------------------------------------------
// Images

/// Where a test's screenshots go (kept after the run, to look at on failure).
fn shot(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("browser");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

// ---------------------------------------------------------------------------------------------
// Relief's own answers

/// The Cesium tile of level `z` holding a point.
fn cesium_tile(z: u8, lon: f64, lat: f64) -> TileXyz {
    let (nx, ny) = Scheme::Geographic.dims(z);
    TileXyz {
        z,
        x: (((lon + 180.0) / 360.0 * f64::from(nx)).floor() as u32).min(nx - 1),
        y: (((lat + 90.0) / 180.0 * f64::from(ny)).floor() as u32).min(ny - 1),
    }
}

/// The height of a mesh at a point: linear over the triangle holding it.
fn mesh_height(m: &GeoMesh, lon: f64, lat: f64) -> Option<f64> {
    // Coordinates within the tile, for well-conditioned barycentrics.
    let b = &m.bounds;
    let local = |p: [f64; 3]| {
        [
            (p[0] - b.west) / (b.east - b.west),
            (p[1] - b.south) / (b.north - b.south),
        ]
    };
    let q = local([lon, lat, 0.0]);
    for t in &m.triangles {
        let [a, bb, c] = t.map(|i| m.vertices[i as usize]);
        let (pa, pb, pc) = (local(a), local(bb), local(c));
        let det = (pb[1] - pc[1]) * (pa[0] - pc[0]) + (pc[0] - pb[0]) * (pa[1] - pc[1]);
        if det.abs() < 1e-15 {
            continue;
        }
        let wa = ((pb[1] - pc[1]) * (q[0] - pc[0]) + (pc[0] - pb[0]) * (q[1] - pc[1])) / det;
        let wb = ((pc[1] - pa[1]) * (q[0] - pc[0]) + (pa[0] - pc[0]) * (q[1] - pc[1])) / det;
        let wc = 1.0 - wa - wb;
        if wa >= -1e-9 && wb >= -1e-9 && wc >= -1e-9 {
            return Some(wa * a[2] + wb * bb[2] + wc * c[2]);
        }
    }
    None
}

/// How far CesiumJS's height at a point may be from a tile mesh's, from the quantization:
/// heights go in 32767 steps of the tile's range and u and v in 32767 steps of the tile, so a
/// vertex moves by up to half a step of each; the surface at the point then moves by up to half
/// a height step plus the steepest slope there (the largest |dh/du| + |dh/dv| of the triangles
/// within two u/v steps of it, u and v as fractions of the tile) times half a u/v step; and
/// 1 mm for float rounding.
fn mesh_tolerance(m: &GeoMesh, lon: f64, lat: f64) -> f64 {
    let b = &m.bounds;
    let local = |v: [f64; 3]| {
        [
            (v[0] - b.west) / (b.east - b.west),
            (v[1] - b.south) / (b.north - b.south),
            v[2],
        ]
    };
    let [px, py, _] = local([lon, lat, 0.0]);
    let near = 2.0 / 32767.0;
    let (lo, hi) = m
        .vertices
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, c), v| (a.min(v[2]), c.max(v[2])));
    let mut slope = 0.0f64;
    for t in &m.triangles {
        let [p, q, r] = t.map(|i| local(m.vertices[i as usize]));
        let (x0, x1) = (p[0].min(q[0]).min(r[0]), p[0].max(q[0]).max(r[0]));
        let (y0, y1) = (p[1].min(q[1]).min(r[1]), p[1].max(q[1]).max(r[1]));
        if px < x0 - near || px > x1 + near || py < y0 - near || py > y1 + near {
            continue;
        }
        let (ux, uy, uz) = (q[0] - p[0], q[1] - p[1], q[2] - p[2]);
        let (vx, vy, vz) = (r[0] - p[0], r[1] - p[1], r[2] - p[2]);
        let det = ux * vy - uy * vx;
        if det.abs() < 1e-15 {
            continue;
        }
        let gx = (uz * vy - vz * uy) / det;
        let gy = (vz * ux - uz * vx) / det;
        slope = slope.max(gx.abs() + gy.abs());
    }
    (hi - lo) / 32767.0 / 2.0 + slope * 0.5 / 32767.0 + 1e-3
}

/// Web Mercator world coordinates in [0, 1) of a point, as MapLibre counts them.
fn world(lon: f64, lat: f64) -> [f64; 2] {
    let s = lat.to_radians().sin();
    [
        (lon + 180.0) / 360.0,
        0.5 - ((1.0 + s) / (1.0 - s)).ln() / (4.0 * std::f64::consts::PI),
    ]
}

/// The heights Relief put in its Web Mercator DEM tiles of one level, before encoding: the
/// pixels of `size`-pixel tiles, each its centre's height (0 outside the store), read as one
/// image across tile borders.
struct DemLevel<'a> {
    r: &'a Resampler<'a>,
    z: u8,
    size: u32,
    tiles: HashMap<(u32, u32), Vec<f32>>,
}

impl DemLevel<'_> {
    fn pixel(&mut self, gx: i64, gy: i64) -> f64 {
        let n = i64::from(self.size) << self.z;
        let (gx, gy) = (gx.clamp(0, n - 1), gy.clamp(0, n - 1));
        let s = i64::from(self.size);
        let key = ((gx / s) as u32, (gy / s) as u32);
        let (r, z, size) = (self.r, self.z, self.size);
        let tile = self.tiles.entry(key).or_insert_with(|| {
            let t = TileXyz {
                z,
                x: key.0,
                y: key.1,
            };
            r.tile(Scheme::Mercator, t, size as usize, Points::Centres)
                .into_iter()
                .map(|h| h.unwrap_or(0.0))
                .collect()
        });
        f64::from(tile[((gy % s) * s + gx % s) as usize])
    }

    /// Bilinear between pixel centres at a point, as MapLibre samples a DEM tile. With
    /// `clamp_to`, pixels past that tile's edge are its edge pixels (what MapLibre reads
    /// before the neighbouring tile's border has been filled in).
    fn at(&mut self, lon: f64, lat: f64, clamp_to: Option<(u32, u32)>) -> f64 {
        let [wx, wy] = world(lon, lat);
        let scale = f64::from(self.size) * f64::from(1u32 << self.z);
        let (px, py) = (wx * scale - 0.5, wy * scale - 0.5);
        let (x0, y0) = (px.floor(), py.floor());
        let (fx, fy) = (px - x0, py - y0);
        let s = i64::from(self.size);
        let clamp = |g: i64, t: u32| match clamp_to {
            Some(_) => g.clamp(i64::from(t) * s, i64::from(t) * s + s - 1),
            None => g,
        };
        let (tx, ty) = clamp_to.unwrap_or((0, 0));
        let mut h =
            |dx: i64, dy: i64| self.pixel(clamp(x0 as i64 + dx, tx), clamp(y0 as i64 + dy, ty));
        let top = h(0, 0) * (1.0 - fx) + h(1, 0) * fx;
        let bottom = h(0, 1) * (1.0 - fx) + h(1, 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

// ---------------------------------------------------------------------------------------------
// HTTP by hand: status and headers of any answer

struct Answer {
    status: u16,
    headers: HashMap<String, String>,
    body: Vec<u8>,
}

async fn get(addr: SocketAddr, path: &str, extra: &[(&str, &str)]) -> Answer {
    let mut tcp = tokio::net::TcpStream::connect(addr).await.expect("connect");
    let mut req = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for (k, v) in extra {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    req.push_str("\r\n");
    tcp.write_all(req.as_bytes()).await.expect("send");
    let mut raw = Vec::new();
    tokio::time::timeout(Duration::from_secs(30), tcp.read_to_end(&mut raw))
        .await
        .unwrap_or_else(|_| panic!("GET {path}: no answer in 30 s"))
        .expect("read");
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| panic!("GET {path}: no HTTP head in {raw:?}"));
    let head = String::from_utf8_lossy(&raw[..split]).into_owned();
    let mut lines = head.lines();
    let status = lines
        .next()
        .and_then(|l| l.split(' ').nth(1))
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("GET {path}: bad status line in {head}"));
    let headers: HashMap<String, String> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    let mut body = raw[split + 4..].to_vec();
    if headers
        .get("transfer-encoding")
        .is_some_and(|t| t == "chunked")
    {
        let mut out = Vec::new();
        let mut rest = &body[..];
        while let Some(eol) = rest.windows(2).position(|w| w == b"\r\n") {
            let n = usize::from_str_radix(String::from_utf8_lossy(&rest[..eol]).trim(), 16)
                .unwrap_or(0);
            if n == 0 {
                break;
            }
            out.extend_from_slice(&rest[eol + 2..eol + 2 + n]);
            rest = &rest[eol + 2 + n + 2..];
        }
        body = out;
    }
    Answer {
        status,
        headers,
        body,
    }
}

// ---------------------------------------------------------------------------------------------
// The tests

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cesium_samples_the_terrain_and_draws_the_golden_view_from_loopback_only() {
    prerequisites(true);
    let _one = BROWSER.lock().await;
    let server = server().await;
    let url = format!("http://{}", server.addr);
    let actual = shot("cesium-actual.png");
    let out = node_json(
        "cesium.mjs",
        &url,
        &["--screenshot", &actual.display().to_string()],
    )
    .await;
    println!(
        "cesium: page ready in {} ms ({} frames after the flight)",
        out["loaded_ms"], out["ready"]["frames"]
    );

    // Nothing left loopback, and the page did load terrain tiles and CesiumJS from here.
    let n = all_local(&out["requests"]);
    let reqs: Vec<&str> = out["requests"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .collect();
    let tiles = reqs.iter().filter(|u| u.contains(".terrain")).count();
    assert!(tiles > 0 && reqs.iter().any(|u| u.contains("/lib/cesium/")));
    println!("cesium: {n} requests, all to 127.0.0.1 ({tiles} terrain tiles)");

    // Heights: against the store's (bilinear between samples), within the geometric error of
    // the deepest level, which is all Cesium's refinement promises of a tile; and against the
    // mesh of the tile Cesium read, as Relief made it, within that mesh's quantization.
    let (store, geo) = store();
    let r = Resampler::new(&store, &geo);
    let shape = &store.geometry().shape;
    let layer = CesiumLayer::new(&geo, shape.width(), shape.height()).unwrap();
    let error = cesium_level_error(layer.max_level);
    let pts = points(&out["points"]);
    let heights = f64s(&out["heights"]);
    assert_eq!(pts.len(), 200);
    let mut meshes: HashMap<TileXyz, GeoMesh> = HashMap::new();
    let (mut vs_store, mut vs_mesh, mut mesh_tol) = (Vec::new(), Vec::new(), 0.0f64);
    for (&[lon, lat], &h) in pts.iter().zip(&heights) {
        assert!(h.is_finite(), "Cesium has no height at {lon}, {lat}");
        let want = r.at(lon, lat).expect("inside the store");
        vs_store.push(h - f64::from(want));
        let t = cesium_tile(layer.max_level, lon, lat);
        let m = meshes
            .entry(t)
            .or_insert_with(|| tile_mesh(&r, store.tile_mesh(), t));
        let tol = mesh_tolerance(m, lon, lat);
        mesh_tol = mesh_tol.max(tol);
        let from_mesh = mesh_height(m, lon, lat).expect("a triangle under the point");
        vs_mesh.push(h - from_mesh);
        assert!(
            (h - from_mesh).abs() <= tol,
            "at {lon}, {lat}: Cesium {h}, Relief's mesh of tile {t:?} {from_mesh} (tolerance {tol})"
        );
    }
    let (max, p99) = max_p99(&vs_store);
    let (mmax, mp99) = max_p99(&vs_mesh);
    println!(
        "cesium: sampleTerrainMostDetailed at 200 points, level {}: vs the store's heights \
         max {max:.3} m, p99 {p99:.3} m (tolerance: the level's geometric error {error:.2} m); \
         vs Relief's mesh max {mmax:.4} m, p99 {mp99:.4} m (tolerance at most {mesh_tol:.4} m)",
        layer.max_level
    );
    assert!(
        max <= error,
        "Cesium's heights are {max} m from the store's, over the geometric error {error} m"
    );

    let img = image::open(&actual).expect("the screenshot").to_rgba8();
    let (unlike, sd) = not_blank(&img, "the Cesium screenshot");
    println!(
        "cesium: screenshot {}x{}, {:.0} % unlike its commonest colour, brightness sd {sd:.1}",
        img.width(),
        img.height(),
        unlike * 100.0,
    );
    // The golden view. Its tolerance (`relief_tests::shots`) is below the smallest real changes
    // measured against this golden image: the camera turned 0.5 degrees (mean 1.42, 0.21 % of
    // pixels off by more than 32), heights 5 % too high (1.64, 0.35 %), the camera 2 % farther
    // (2.19, 1.6 %), the sun half an hour later (8.8, 0 %), no vertex normals (40.7, 77 %).
    let golden = repo().join("web/tests/golden/cesium.png");
    assert_golden(&img, &actual, &golden, "the Cesium view");
    if bless() {
        img.save(repo().join("docs/img/cesium.png")).unwrap();
    }
    drop(server);
}

/// One MapLibre run: the page with `encoding`, its heights against Relief's in each view.
async fn maplibre(url: &str, encoding: &str, step: f64, screenshot: &Path) {
    let out = node_json(
        "maplibre.mjs",
        url,
        &[
            "--encoding",
            encoding,
            "--screenshot",
            &screenshot.display().to_string(),
        ],
    )
    .await;
    let n = all_local(&out["requests"]);
    println!(
        "maplibre {encoding}: page ready in {} ms, {n} requests, all to 127.0.0.1; TileJSON {}",
        out["loaded_ms"], out["source"]
    );
    let want_encoding = if encoding == "terrarium" {
        "terrarium"
    } else {
        "mapbox"
    };
    assert_eq!(out["source"]["encoding"], want_encoding);
    let size = out["source"]["tileSize"].as_u64().unwrap_or(256) as u32;
    let maxzoom = out["source"]["maxzoom"].as_u64().expect("maxzoom");

    let (store, geo) = store();
    let r = Resampler::new(&store, &geo);
    let mut levels: HashMap<u8, DemLevel> = HashMap::new();
    let views = out["views"].as_array().expect("views");
    let mut deepest = 0;
    for view in views {
        let pts = points(&view["points"]);
        let samples = view["samples"].as_array().expect("samples");
        assert_eq!(pts.len(), 200);
        let (mut vs_encoded, mut vs_store) = (Vec::new(), Vec::new());
        let (mut edge, mut clamped) = (0, 0);
        let mut zooms: HashMap<u64, usize> = HashMap::new();
        for (&[lon, lat], s) in pts.iter().zip(samples) {
            let h = s["elevation"]
                .as_f64()
                .unwrap_or_else(|| panic!("no elevation at {lon}, {lat}: {s}"));
            let dem = &s["dem"];
            let z = dem["z"].as_u64().unwrap_or_else(|| {
                panic!("no DEM tile read at {lon}, {lat} (MapLibre's internals moved?): {s}")
            });
            let (x, y) = (
                dem["x"].as_u64().unwrap() as u32,
                dem["y"].as_u64().unwrap() as u32,
            );
            *zooms.entry(z).or_default() += 1;
            deepest = deepest.max(z);
            let level = levels.entry(z as u8).or_insert_with(|| DemLevel {
                r: &r,
                z: z as u8,
                size,
                tiles: HashMap::new(),
            });
            // Within half a pixel of the DEM tile's edge MapLibre reads its border pixels:
            // the neighbouring tile's, once that has loaded, else copies of the edge's. Either
            // is Relief's encoded heights; the closer one counts, and the count is reported.
            let continuous = level.at(lon, lat, None);
            let mut want = continuous;
            let [wx, wy] = world(lon, lat);
            let scale = f64::from(size) * f64::from(1u32 << z);
            let (fx, fy) = (
                wx * scale - f64::from(x * size),
                wy * scale - f64::from(y * size),
            );
            let band = |f: f64| f < 0.5 || f > f64::from(size) - 0.5;
            if band(fx) || band(fy) {
                edge += 1;
                let alt = level.at(lon, lat, Some((x, y)));
                if (h - alt).abs() < (h - continuous).abs() {
                    want = alt;
                    clamped += 1;
                }
            }
            vs_encoded.push(h - want);
            assert!(
                (h - want).abs() <= step,
                "{encoding} at {lon}, {lat} (DEM tile {z}/{x}/{y}): MapLibre {h}, Relief's \
                 encoded heights {want}: off by more than the encoding's step {step}"
            );
            let direct = r.at(lon, lat).expect("inside the store");
            vs_store.push(h - f64::from(direct));
        }
        let (max, p99) = max_p99(&vs_encoded);
        let (smax, sp99) = max_p99(&vs_store);
        let mut zooms: Vec<_> = zooms.into_iter().collect();
        zooms.sort();
        println!(
            "maplibre {encoding}, {} view (zoom {:.2}): queryTerrainElevation at 200 points, \
             DEM tiles read at zooms {zooms:?} (zoom, points): vs the heights Relief encoded \
             there max {max:.5} m, p99 {p99:.5} m (step {step:.5} m; {} half a step); {edge} \
             points in a tile's border band, {clamped} of them read the clamped border; vs the \
             store's own heights (adds Relief's resampling onto Web Mercator pixels) max \
             {smax:.3} m, p99 {sp99:.3} m",
            view["name"].as_str().unwrap_or("?"),
            view["zoom"].as_f64().unwrap_or(f64::NAN),
            if max <= step / 2.0 + 1e-6 {
                "within"
            } else {
                "NOT within"
            }
        );
    }
    assert_eq!(
        deepest, maxzoom,
        "no view read MapLibre's deepest DEM tiles (zoom {maxzoom})"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn maplibre_reads_relief_heights_in_both_encodings() {
    prerequisites(true);
    let _one = BROWSER.lock().await;
    let server = server().await;
    let url = format!("http://{}", server.addr);
    let rgb = shot("maplibre-terrain-rgb.png");
    maplibre(&url, "terrain-rgb", 0.1, &rgb).await;
    let terrarium = shot("maplibre-terrarium.png");
    maplibre(&url, "terrarium", 1.0 / 256.0, &terrarium).await;
    for (path, what) in [(&rgb, "terrain-RGB"), (&terrarium, "Terrarium")] {
        let img = image::open(path).expect("the screenshot").to_rgba8();
        let (unlike, sd) = not_blank(&img, &format!("the MapLibre {what} screenshot"));
        println!(
            "maplibre {what}: screenshot {}x{}, {:.0} % unlike its commonest colour, \
             brightness sd {sd:.1} ({})",
            img.width(),
            img.height(),
            unlike * 100.0,
            path.display()
        );
    }
    if bless() {
        std::fs::copy(&rgb, repo().join("docs/img/maplibre.png")).unwrap();
    }
    // The server is still there and well.
    assert_eq!(get(server.addr, "/healthz", &[]).await.status, 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn loaders_gl_decodes_the_meshes_relief_meant_to_send() {
    prerequisites(false);
    let server = server().await;
    let url = format!("http://{}", server.addr);
    let out = node_json("quantized_mesh.mjs", &url, &[]).await;
    let (store, geo) = store();
    let r = Resampler::new(&store, &geo);
    let shape = &store.geometry().shape;
    let layer = CesiumLayer::new(&geo, shape.width(), shape.height()).unwrap();
    assert_eq!(out["max_level"], layer.max_level);
    let tiles = out["tiles"].as_array().expect("tiles");
    assert!(tiles.len() >= 5, "too few tiles decoded: {}", tiles.len());
    for d in tiles {
        let t = TileXyz {
            z: d["z"].as_u64().unwrap() as u8,
            x: d["x"].as_u64().unwrap() as u32,
            y: d["y"].as_u64().unwrap() as u32,
        };
        let name = format!("{}/{}/{}", t.z, t.x, t.y);
        let m = tile_mesh(&r, store.tile_mesh(), t);
        // The transport: gzip, Cesium's media type, CORS.
        assert_eq!(d["content_encoding"], "gzip", "{name}");
        assert!(
            d["content_type"]
                .as_str()
                .unwrap()
                .starts_with("application/vnd.quantized-mesh"),
            "{name}: {}",
            d["content_type"]
        );
        assert_eq!(d["cors"], "*", "{name}");
        // Counts.
        let nv = d["vertex_count"].as_u64().unwrap() as usize;
        let nt = d["triangle_count"].as_u64().unwrap() as usize;
        assert_eq!(
            (nv, nt),
            (m.vertices.len(), m.triangles.len()),
            "{name}: vertices and triangles"
        );
        // The header's heights are the mesh's range.
        let (lo, hi) = m
            .vertices
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v[2]), b.max(v[2])));
        let (hlo, hhi) = (
            d["header"]["minHeight"].as_f64().unwrap(),
            d["header"]["maxHeight"].as_f64().unwrap(),
        );
        assert!(
            (hlo - lo).abs() < 1e-3 && (hhi - hi).abs() < 1e-3,
            "{name}: header heights {hlo}..{hhi}, mesh {lo}..{hi}"
        );
        // Vertices: each decoded (u, v) is one of Relief's vertices quantized, and its height
        // and position are that vertex's within half a quantization step.
        let b = &m.bounds;
        let quant = |v: &[f64; 3]| {
            (
                ((v[0] - b.west) / (b.east - b.west) * 32767.0).round() as i64,
                ((v[1] - b.south) / (b.north - b.south) * 32767.0).round() as i64,
            )
        };
        let index: HashMap<(i64, i64), usize> = m
            .vertices
            .iter()
            .enumerate()
            .map(|(i, v)| (quant(v), i))
            .collect();
        assert_eq!(index.len(), m.vertices.len(), "{name}: vertices collide");
        let (u, v) = (f64s(&d["u"]), f64s(&d["v"]));
        let (lon, lat, h) = (f64s(&d["lon"]), f64s(&d["lat"]), f64s(&d["height"]));
        let h_step = (hi - lo) / 32767.0;
        let deg_step = (b.east - b.west) / 32767.0;
        // loaders.gl stores positions as float32: near 140 degrees that is 7.6e-6 degrees.
        let f32_deg = 140f64 * f64::from(f32::EPSILON);
        let (mut worst_h, mut worst_pos) = (0.0f64, 0.0f64);
        let mut to_relief = Vec::with_capacity(nv);
        for i in 0..nv {
            let key = (u[i] as i64, v[i] as i64);
            let k = *index
                .get(&key)
                .unwrap_or_else(|| panic!("{name}: decoded vertex {i} at {key:?} is not Relief's"));
            to_relief.push(k);
            let want = m.vertices[k];
            let dh = (h[i] - want[2]).abs();
            let dp = (lon[i] - want[0]).abs().max((lat[i] - want[1]).abs());
            worst_h = worst_h.max(dh / h_step.max(1e-9));
            worst_pos = worst_pos.max(dp);
            assert!(
                dh <= h_step / 2.0 + 1e-3,
                "{name}: vertex {i} height {} vs {} (step {h_step})",
                h[i],
                want[2]
            );
            assert!(
                dp <= deg_step / 2.0 + f32_deg,
                "{name}: vertex {i} at {}, {} vs {}, {}",
                lon[i],
                lat[i],
                want[0],
                want[1]
            );
        }
        // Triangles: the same ones, in the same winding.
        let canon = |t: [usize; 3]| {
            let i = (0..3).min_by_key(|&i| t[i]).unwrap();
            [t[i], t[(i + 1) % 3], t[(i + 2) % 3]]
        };
        let sent: HashSet<[usize; 3]> = d["triangles"]
            .as_array()
            .unwrap()
            .chunks(3)
            .map(|c| canon([0, 1, 2].map(|j| to_relief[c[j].as_u64().unwrap() as usize])))
            .collect();
        let meant: HashSet<[usize; 3]> = m
            .triangles
            .iter()
            .map(|t| canon(t.map(|i| i as usize)))
            .collect();
        assert_eq!(sent.len(), nt, "{name}: repeated triangles");
        assert!(sent == meant, "{name}: the triangles are not Relief's");
        // Edges: each list holds exactly the vertices on its side.
        for (side, on) in [
            (
                "west",
                Box::new(|q: (i64, i64)| q.0 == 0) as Box<dyn Fn((i64, i64)) -> bool>,
            ),
            ("east", Box::new(|q: (i64, i64)| q.0 == 32767)),
            ("south", Box::new(|q: (i64, i64)| q.1 == 0)),
            ("north", Box::new(|q: (i64, i64)| q.1 == 32767)),
        ] {
            let listed: HashSet<usize> = d["edges"][side]
                .as_array()
                .unwrap()
                .iter()
                .map(|i| to_relief[i.as_u64().unwrap() as usize])
                .collect();
            let want: HashSet<usize> = (0..m.vertices.len())
                .filter(|&k| on(quant(&m.vertices[k])))
                .collect();
            assert!(listed == want, "{name}: the {side} edge list");
        }
        // Extensions: what the Accept header asked for.
        let asked = d["accept"].as_str().unwrap().contains("extensions=");
        if asked {
            assert_eq!(d["normals_bytes"], 2 * nv as u64, "{name}: oct normals");
            let meta: Value = serde_json::from_str(&layer.metadata(t)).unwrap();
            assert_eq!(d["extensions"]["metadata"], meta, "{name}: metadata");
        } else {
            assert_eq!(d["normals_bytes"], 0, "{name}: unasked normals");
            assert!(d["extensions"].as_object().unwrap().is_empty(), "{name}");
        }
        println!(
            "loaders.gl {name}{}: {nv} vertices, {nt} triangles as meant; {} bytes (gunzipped); \
             heights within {worst_h:.3} of a step ({h_step:.4} m), positions within \
             {worst_pos:.2e} degrees (u/v step {deg_step:.2e}, float32 {f32_deg:.1e})",
            if asked { " +normals+metadata" } else { "" },
            d["bytes"]
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_tile_addresses_get_400_or_404_and_the_server_serves_on() {
    let mut server = server().await;
    let addr = server.addr;
    let bad = [
        "/cesium/abc/0/0.terrain",
        "/cesium/0/x/0.terrain",
        "/cesium/0/0/y.terrain",
        "/cesium/-1/0/0.terrain",
        "/cesium/99/0/0.terrain",
        "/cesium/25/0/0.terrain",
        "/cesium/99999999999999999999/0/0.terrain",
        "/cesium/0/2/0.terrain",
        "/cesium/0/0/1.terrain",
        "/cesium/12/4294967295/0.terrain",
        "/cesium/12/4294967296/4294967296.terrain",
        "/cesium/12/0/0.terrain",
        "/cesium/0/0/0",
        "/cesium/0/0/0.png",
        "/cesium/0/0/0.terrain.gz",
        "/cesium/0/0/0/0.terrain",
        "/cesium/layer.json/x",
        "/tiles/terrain-rgb/abc/0/0.png",
        "/tiles/terrain-rgb/99/0/0.png",
        "/tiles/terrain-rgb/25/0/0.png",
        "/tiles/terrain-rgb/1/5/0.png",
        "/tiles/terrain-rgb/1/0/5.png",
        "/tiles/terrain-rgb/0/0/0.jpg",
        "/tiles/terrain-rgb/0/0/0@3x.png",
        "/tiles/terrain-rgb/0/0/%00.png",
        "/tiles/terrain-rgb/5/0/0.png",
        "/tiles/terrain-rgb/18/0/0.png",
        "/tiles/terrarium/-3/0/0.png",
        "/tiles/bogus/0/0/0.png",
        "/tiles/bogus.json",
        "/tiles/terrain-rgb",
        "/tiles/terrain-rgb.json?tile_size=300",
        "/tiles/terrain-rgb.json?tile_size=abc",
        "/tiles/terrain-rgb.json?tile_size=99999999999999999999",
        "/lib/cesium/../../../../../etc/passwd",
        "/lib/cesium/%2e%2e/%2e%2e/package.json",
        "/lib/maplibre-gl/nope.mjs",
        "/maplibre/nope.js",
    ];
    let mut seen: HashMap<u16, usize> = HashMap::new();
    for path in bad {
        let a = get(addr, path, &[]).await;
        *seen.entry(a.status).or_default() += 1;
        assert!(
            a.status == 400 || a.status == 404,
            "GET {path} answered {}: {}",
            a.status,
            String::from_utf8_lossy(&a.body)
        );
    }
    // Odd Accept headers on a good tile change nothing but the extensions.
    let good = "/cesium/0/1/0.terrain";
    for accept in [
        "application/vnd.quantized-mesh;extensions=",
        "application/vnd.quantized-mesh;extensions=-----",
        "application/vnd.quantized-mesh;extensions=watermask-octvertexnormals;q=abc",
        "*/*;;;;,,,;",
    ] {
        let a = get(addr, good, &[("Accept", accept)]).await;
        assert_eq!(a.status, 200, "Accept {accept:?}");
    }
    // And the server serves on.
    assert!(
        server.child.try_wait().unwrap().is_none(),
        "the server exited"
    );
    assert_eq!(get(addr, "/healthz", &[]).await.status, 200);
    assert_eq!(get(addr, "/cesium/layer.json", &[]).await.status, 200);
    assert_eq!(get(addr, good, &[]).await.status, 200);
    assert_eq!(
        get(addr, "/tiles/terrain-rgb/0/0/0.png", &[]).await.status,
        200
    );
    let mut seen: Vec<_> = seen.into_iter().collect();
    seen.sort();
    println!(
        "bad input: {} addresses answered {seen:?} (status, count); the server serves on",
        bad.len()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_pages_are_served_with_their_libraries_or_say_how_to_install_them() {
    // With the libraries: the pages, their scripts, and the libraries from web/node_modules.
    let installed = node_modules()
        .join("cesium/Build/Cesium/Cesium.js")
        .is_file()
        && node_modules()
            .join("maplibre-gl/dist/maplibre-gl.mjs")
            .is_file();
    if installed {
        let server = server().await;
        for (path, kind) in [
            ("/cesium/", "text/html"),
            ("/cesium/main.js", "text/javascript"),
            ("/maplibre/", "text/html"),
            ("/maplibre/main.js", "text/javascript"),
            ("/lib/cesium/Cesium.js", "javascript"),
            ("/lib/cesium/Widgets/widgets.css", "text/css"),
            ("/lib/maplibre-gl/maplibre-gl.mjs", "javascript"),
            ("/lib/maplibre-gl/maplibre-gl.css", "text/css"),
        ] {
            let a = get(server.addr, path, &[]).await;
            assert_eq!(a.status, 200, "{path}");
            let ct = a.headers.get("content-type").cloned().unwrap_or_default();
            assert!(ct.contains(kind), "{path}: content-type {ct}");
        }
        let a = get(server.addr, "/cesium", &[]).await;
        assert!(a.status == 308 || a.status == 301, "{}", a.status);
        assert_eq!(a.headers["location"], "/cesium/");
    }
    // Without them: the pages say what to run, and nothing else breaks.
    let empty = tempfile::tempdir().unwrap();
    let dir = empty.path().display().to_string();
    let server = ChildServer::start_env(
        Path::new(BIN),
        free_addr(),
        &[],
        &[("RELIEF_WEB_LIB", &dir)],
    )
    .await;
    for page in ["/cesium/", "/maplibre/"] {
        let a = get(server.addr, page, &[]).await;
        let body = String::from_utf8_lossy(&a.body);
        assert_eq!(a.status, 503, "{page}");
        assert!(
            body.contains("npm ci --prefix web") && body.contains(&dir),
            "{page}: {body}"
        );
    }
    assert_eq!(
        get(server.addr, "/lib/cesium/Cesium.js", &[]).await.status,
        404
    );
    assert_eq!(
        get(server.addr, "/cesium/layer.json", &[]).await.status,
        200
    );
}
