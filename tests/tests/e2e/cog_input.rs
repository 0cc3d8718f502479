//! Cloud-Optimized GeoTIFF input, against the real tools: Debian's GDAL (`gdal_translate -of
//! COG`) makes COGs of the committed Fuji crop, and Debian's nginx serves them on 127.0.0.1.
//! - COGs in int16 (deflate, predictor 2), float32 (zstd, predictor 3) and uint16 (LZW), in
//!   128 x 128 tiles (6 tiles, the last column 1 sample wide), load to exactly the original's
//!   heights and place, and `relief-server build` makes a store byte-identical to the
//!   original's (the same terrain id);
//! - a folder of them is one mosaic;
//! - one served by nginx loads by URL to the same heights (and `build URL` to the same store),
//!   and a window of one tile of a 2048 x 2048 COG fetches a small part of the file;
//! - a truncated COG, and COGs whose TileByteCounts lie (too large, too small), are refused with
//!   a message naming the file and the tile, not a panic; so is a URL that is not there.
//!
//! `tests/setup.sh` installs gdal-bin and nginx; without them this test fails and says so.

use relief_server::dem::cog::TiffWindows;
use relief_server::dem::http_range::RangeReader;
use relief_server::dem::{Dem, LoadOptions, load_all};
use relief_tests::{Reaped, free_addr};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_relief-test-server");

/// `gdal_translate` options of an int16 COG in 128 x 128 tiles, deflate with the horizontal
/// predictor: the served and the corrupted files.
const DEFLATE_128: &[&str] = &[
    "-co",
    "BLOCKSIZE=128",
    "-co",
    "COMPRESS=DEFLATE",
    "-co",
    "PREDICTOR=STANDARD",
];

/// The path of a Debian tool, or a failure that says how to install it.
fn tool(name: &str, package: &str) -> PathBuf {
    ["/usr/bin", "/usr/sbin", "/usr/local/bin"]
        .iter()
        .map(|d| Path::new(d).join(name))
        .find(|p| p.exists())
        .unwrap_or_else(|| {
            panic!("{name} is missing: run `bash tests/setup.sh` (it installs {package})")
        })
}

/// The committed crop, copied into `dir` (GDAL writes nothing beside its inputs then).
fn fuji(dir: &Path) -> PathBuf {
    let src = relief_tests::repo().join("server/data/fuji_crop.tif");
    let p = dir.join("fuji_crop.tif");
    std::fs::copy(src, &p).expect("copy the crop");
    p
}

/// `gdal_translate -q -of COG ARGS SRC DST`, checked.
fn cog(src: &Path, dst: &Path, args: &[&str]) {
    std::fs::create_dir_all(dst.parent().unwrap()).unwrap();
    let out = Command::new(tool("gdal_translate", "gdal-bin"))
        .args(["-q", "-of", "COG"])
        .args(args)
        .arg(src)
        .arg(dst)
        .env("GDAL_PAM_ENABLED", "NO")
        .output()
        .expect("run gdal_translate");
    assert!(
        out.status.success(),
        "gdal_translate {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `gdalinfo` of `path`, to check what GDAL wrote.
fn gdalinfo(path: &Path) -> String {
    let out = Command::new(tool("gdalinfo", "gdal-bin"))
        .arg(path)
        .env("GDAL_PAM_ENABLED", "NO")
        .output()
        .expect("run gdalinfo");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// `relief-server build INPUT -o OUT --quiet`.
fn build(input: &str, out: &Path) -> Output {
    Command::new(BIN)
        .args(["build", input, "-o"])
        .arg(out)
        .arg("--quiet")
        .output()
        .expect("run build")
}

/// Builds `input` into `out` and returns the store's bytes.
fn store(input: &str, out: &Path) -> Vec<u8> {
    let o = build(input, out);
    assert!(
        o.status.success(),
        "build {input}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::read(out).expect("the store")
}

/// Loads `input` through the library.
fn dem(input: &str) -> Dem {
    load_all(&[input], &LoadOptions::default()).unwrap_or_else(|e| panic!("{input}: {e}"))
}

/// Asserts that `d` is `want`'s terrain: the same heights, voids and place.
fn same_terrain(what: &str, d: &Dem, want: &Dem) {
    assert_eq!((d.width, d.height), (want.width, want.height), "{what}");
    assert!(d.heights == want.heights, "{what}: heights differ");
    assert_eq!(d.voids.count(), want.voids.count(), "{what}");
    assert_eq!((d.spacing_x, d.spacing_y), (want.spacing_x, want.spacing_y));
    assert_eq!(d.georef, want.georef, "{what}");
}

/// The COGs of the crop: (folder, gdal_translate options, what gdalinfo must show).
const KINDS: [(&str, &[&str], &[&str]); 3] = [
    (
        "i16-deflate-p2",
        &["-co", "COMPRESS=DEFLATE", "-co", "PREDICTOR=STANDARD"],
        &["Type=Int16", "COMPRESSION=DEFLATE", "PREDICTOR=2"],
    ),
    (
        "f32-zstd-p3",
        &[
            "-ot",
            "Float32",
            "-co",
            "COMPRESS=ZSTD",
            "-co",
            "PREDICTOR=FLOATING_POINT",
        ],
        &["Type=Float32", "COMPRESSION=ZSTD", "PREDICTOR=3"],
    ),
    (
        "u16-lzw",
        &["-ot", "UInt16", "-a_nodata", "0", "-co", "COMPRESS=LZW"],
        &["Type=UInt16", "COMPRESSION=LZW"],
    ),
];

#[test]
fn cogs_from_gdal_load_and_build_the_same_terrain_as_the_original() {
    let dir = tempfile::tempdir().unwrap();
    let src = fuji(dir.path());
    let src_s = src.to_str().unwrap();
    let original = dem(src_s);
    let reference = store(src_s, &dir.path().join("original.relief"));
    for (kind, args, shows) in KINDS {
        // Same file name, so that the store records the same source.
        let path = dir.path().join(kind).join("fuji_crop.tif");
        let mut all = vec!["-co", "BLOCKSIZE=128"];
        all.extend_from_slice(args);
        cog(&src, &path, &all);
        let info = gdalinfo(&path);
        for s in shows.iter().chain(&["Block=128x128", "LAYOUT=COG"]) {
            assert!(info.contains(s), "{kind}: gdalinfo shows no {s}:\n{info}");
        }
        let p = path.to_str().unwrap();
        let d = dem(p);
        same_terrain(kind, &d, &original);
        let size = std::fs::metadata(&path).unwrap().len();
        assert_eq!(d.io.source_bytes, size, "{kind}");
        assert!(d.io.bytes_read > 0, "{kind}: {:?}", d.io);
        let built = store(p, &dir.path().join(format!("{kind}.relief")));
        assert!(
            built == reference,
            "{kind}: the store differs from the original's"
        );
    }
    // A folder of COGs is their mosaic: two halves of the crop, split by GDAL.
    let halves = dir.path().join("halves");
    cog(
        &src,
        &halves.join("a_west.tif"),
        &["-srcwin", "0", "0", "130", "193", "-co", "BLOCKSIZE=128"],
    );
    cog(
        &src,
        &halves.join("b_east.tif"),
        &["-srcwin", "130", "0", "127", "193", "-co", "BLOCKSIZE=128"],
    );
    let d = dem(halves.to_str().unwrap());
    assert!(d.source.contains("a_west.tif + ") && d.source.contains("b_east.tif"));
    same_terrain("folder mosaic", &d, &original);
}

/// nginx serving `root` on a free 127.0.0.1 port, in the foreground, killed on drop.
struct Nginx {
    /// The process.
    _child: Reaped,
    /// Where it listens.
    addr: std::net::SocketAddr,
}

impl Nginx {
    /// Starts nginx with a minimal configuration in `dir` (its logs, pid and temporary files
    /// there too) and waits until it accepts connections.
    fn start(dir: &Path, root: &Path) -> Nginx {
        let bin = tool("nginx", "nginx");
        let addr = free_addr();
        let d = dir.display();
        // One process: no workers that drop privileges and could not read a private tempdir.
        let conf = format!(
            "daemon off;\nmaster_process off;\npid {d}/nginx.pid;\nerror_log {d}/error.log;\n\
             events {{}}\nhttp {{\n  access_log {d}/access.log;\n  \
             client_body_temp_path {d}/body;\n  proxy_temp_path {d}/proxy;\n  \
             fastcgi_temp_path {d}/fastcgi;\n  uwsgi_temp_path {d}/uwsgi;\n  \
             scgi_temp_path {d}/scgi;\n  server {{\n    listen {addr};\n    root {};\n  }}\n}}\n",
            root.display()
        );
        let conf_path = dir.join("nginx.conf");
        std::fs::write(&conf_path, conf).unwrap();
        let mut child = Reaped(
            Command::new(bin)
                .arg("-p")
                .arg(dir)
                .arg("-e")
                .arg(dir.join("error.log"))
                .arg("-c")
                .arg(&conf_path)
                .stderr(std::process::Stdio::null())
                .spawn()
                .expect("start nginx"),
        );
        let deadline = Instant::now() + Duration::from_secs(20);
        while std::net::TcpStream::connect(addr).is_err() {
            if let Ok(Some(status)) = child.try_wait() {
                let log = std::fs::read_to_string(dir.join("error.log")).unwrap_or_default();
                panic!("nginx exited ({status}): {log}");
            }
            assert!(Instant::now() < deadline, "nginx never listened on {addr}");
            std::thread::sleep(Duration::from_millis(20));
        }
        Nginx {
            _child: child,
            addr,
        }
    }
}

#[test]
fn cogs_served_by_nginx_load_by_url_and_a_window_fetches_one_tile() {
    let dir = tempfile::tempdir().unwrap();
    let src = fuji(dir.path());
    let www = dir.path().join("www");
    let small = www.join("fuji_crop.tif");
    cog(&src, &small, DEFLATE_128);
    // 2048 x 2048 in 64 tiles of 256 x 256, for a window read.
    let big = www.join("fuji_big.tif");
    cog(
        &src,
        &big,
        &[
            "-outsize",
            "2048",
            "2048",
            "-r",
            "bilinear",
            "-co",
            "BLOCKSIZE=256",
            "-co",
            "COMPRESS=DEFLATE",
            "-co",
            "PREDICTOR=STANDARD",
        ],
    );
    let nginx = Nginx::start(dir.path(), &www);
    let url = |name: &str| format!("http://{}/{name}", nginx.addr);

    // The whole crop by URL: the local file's terrain, and the same store.
    let remote = dem(&url("fuji_crop.tif"));
    same_terrain("by URL", &remote, &dem(small.to_str().unwrap()));
    let size = std::fs::metadata(&small).unwrap().len();
    assert_eq!(remote.io.source_bytes, size);
    assert!(remote.io.bytes_read >= size / 2, "{:?}", remote.io);
    let built = store(&url("fuji_crop.tif"), &dir.path().join("url.relief"));
    let local = store(small.to_str().unwrap(), &dir.path().join("local.relief"));
    assert!(
        built == local,
        "the store built by URL differs from the local file's"
    );

    // One tile of the big COG: the window equals the local file's, for a fraction of it.
    let big_url = url("fuji_big.tif");
    let opts = LoadOptions::default();
    let reader = RangeReader::open(&big_url).expect("open the URL");
    let requests_at_open = reader.requests();
    let mut remote = TiffWindows::open(&big_url, reader, &opts).unwrap();
    assert_eq!(remote.chunk_size(), (256, 256));
    let mut window = vec![0.0f32; 256 * 256];
    remote
        .read_window(768, 1024, 256, 256, &mut window)
        .unwrap();
    let io = remote.io();
    let file = std::fs::File::open(&big).unwrap();
    let len = file.metadata().unwrap().len();
    let file = relief_server::dem::cog::Counting::new(std::io::BufReader::new(file), len);
    let mut local = TiffWindows::open("big", file, &opts).unwrap();
    let mut want = vec![0.0f32; 256 * 256];
    local.read_window(768, 1024, 256, 256, &mut want).unwrap();
    assert!(
        window == want,
        "the window by URL differs from the local file's"
    );
    println!(
        "one 256 x 256 tile by HTTP: {} of {} bytes fetched ({:.1}%), {} requests at open",
        io.bytes_read,
        io.source_bytes,
        100.0 * io.bytes_read as f64 / io.source_bytes as f64,
        requests_at_open
    );
    assert_eq!(io.source_bytes, len);
    assert!(
        io.bytes_read * 5 < io.source_bytes,
        "a window of one tile fetched {io:?}"
    );

    // A URL that is not there: a clear failure naming it.
    let o = build(&url("nowhere.tif"), &dir.path().join("none.relief"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("nowhere.tif") && err.contains("404"), "{err}");

    // The server's store cache knows a URL by its object, not its signature: two signings of
    // the same object share a store, and the object replaced (nginx's ETag changes with the
    // file) builds a new one.
    let key = |u: &str| relief_server::serve::source::cache_key(&[u], &LoadOptions::default());
    let crop = url("fuji_crop.tif");
    let first = key(&format!("{crop}?X-Amz-Signature=aaaa"));
    assert_eq!(first, key(&format!("{crop}?X-Amz-Signature=bbbb")));
    std::fs::copy(&big, &small).unwrap();
    assert_ne!(first, key(&format!("{crop}?X-Amz-Signature=aaaa")));
}

/// Where the TileByteCounts entry of tile `k` is in a classic little-endian TIFF (as GDAL
/// writes a small COG), with the entry's value.
fn tile_byte_count(tiff: &[u8], k: usize) -> (usize, u32) {
    let u16_at = |i: usize| u16::from_le_bytes([tiff[i], tiff[i + 1]]);
    let u32_at = |i: usize| u32::from_le_bytes(tiff[i..i + 4].try_into().unwrap());
    assert_eq!(&tiff[..4], b"II*\0", "a little-endian classic TIFF");
    let ifd = u32_at(4) as usize;
    for e in 0..u16_at(ifd) as usize {
        let at = ifd + 2 + 12 * e;
        if u16_at(at) == 325 {
            assert_eq!(u16_at(at + 2), 4, "TileByteCounts as LONG");
            let count = u32_at(at + 4) as usize;
            let base = if count == 1 {
                at + 8
            } else {
                u32_at(at + 8) as usize
            };
            let entry = base + 4 * k;
            return (entry, u32_at(entry));
        }
    }
    panic!("no TileByteCounts tag");
}

#[test]
fn truncated_cogs_and_lying_tile_byte_counts_are_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let src = fuji(dir.path());
    let good = dir.path().join("good.tif");
    cog(&src, &good, DEFLATE_128);
    let bytes = std::fs::read(&good).unwrap();
    let (entry, count) = tile_byte_count(&bytes, 4);
    let half = bytes[..bytes.len() / 2].to_vec();
    let patched = |v: u32| {
        let mut b = bytes.clone();
        b[entry..entry + 4].copy_from_slice(&v.to_le_bytes());
        b
    };
    for (name, data, needle) in [
        ("truncated.tif", half, "past the end of the file"),
        (
            "count-large.tif",
            patched(bytes.len() as u32 * 4),
            "past the end",
        ),
        (
            "count-small.tif",
            patched(count / 3),
            "tile 4 (column 1, row 1)",
        ),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, data).unwrap();
        let o = build(p.to_str().unwrap(), &dir.path().join("x.relief"));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
        assert!(err.contains(name) && err.contains(needle), "{name}: {err}");
        assert!(err.contains("not a readable GeoTIFF"), "{name}: {err}");
    }
}
