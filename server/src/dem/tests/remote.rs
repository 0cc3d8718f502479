//! Tests of [`RangeReader`](super::RangeReader) (declared in `http_range.rs`) against tiny HTTP
//! servers on 127.0.0.1, one a misbehaviour: one that answers ranges properly, one that
//! ignores them (200 and the whole file), one that 404s, one that sends a short body, one that
//! drops the connection mid-body (always, or once), one that answers another range, one that
//! never answers, and one whose file is replaced between requests.

use super::{RangeOptions, RangeReader};
use crate::dem::cog::tests::{check_window, tiled};
use crate::dem::cog::{Source, TiffWindows};
use crate::dem::{DemError, LoadOptions, load};
use std::io::{Read, Seek, SeekFrom, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// How a test server answers a range request.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    /// 206 with the range asked for.
    Ranges,
    /// 200 with the whole file.
    IgnoresRange,
    /// 404.
    NotFound,
    /// 206 with the right Content-Range but half the bytes (and a Content-Length that says so).
    Short,
    /// 206, then half the body and the connection closed.
    Drops,
    /// As `Drops` on the first connection, then as `Ranges`.
    DropsOnce,
    /// 206 with the range one byte later than asked.
    WrongRange,
    /// Reads the request and never answers.
    Silent,
    /// As `Ranges`, with an `ETag` that changes with every connection: a file replaced between
    /// any two requests.
    Replaced,
}

/// Serves `data` in `mode` on a free loopback port; returns the URL (with a query string that
/// messages must not show) and the count of connections.
fn serve(data: Vec<u8>, mode: Mode) -> (String, Arc<AtomicUsize>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!(
        "http://{}/dem/f.tif?sig=secret",
        listener.local_addr().unwrap()
    );
    let (data, seen) = (Arc::new(data), Arc::new(AtomicUsize::new(0)));
    let counter = seen.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(stream) = stream else { return };
            let n = counter.fetch_add(1, Ordering::SeqCst);
            let data = data.clone();
            std::thread::spawn(move || answer(stream, &data, mode, n));
        }
    });
    (url, seen)
}

/// Answers one request on `s`, the `n`th connection.
fn answer(mut s: TcpStream, data: &[u8], mode: Mode, n: usize) {
    let mut head = Vec::new();
    let mut buf = [0u8; 1024];
    while !head.windows(4).any(|w| w == b"\r\n\r\n") {
        match s.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(k) => head.extend_from_slice(&buf[..k]),
        }
    }
    let head = String::from_utf8_lossy(&head).to_ascii_lowercase();
    let range = head
        .lines()
        .find_map(|l| l.strip_prefix("range: bytes="))
        .and_then(|r| {
            let (a, b) = r.trim().split_once('-')?;
            Some((a.parse::<usize>().ok()?, b.parse::<usize>().ok()?))
        });
    let Some((a, b)) = range else { return };
    let len = data.len();
    let b = b.min(len - 1);
    let body = &data[a..=b];
    let etag = match mode {
        Mode::Replaced => format!("ETag: \"v{n}\"\r\n"),
        _ => String::new(),
    };
    let reply =
        |s: &mut TcpStream, status: &str, range: Option<String>, length: usize, body: &[u8]| {
            let range = range.map_or(String::new(), |r| format!("Content-Range: {r}\r\n"));
            let _ = write!(
                s,
                "HTTP/1.1 {status}\r\nContent-Length: {length}\r\n{range}{etag}Connection: \
                 close\r\n\r\n"
            );
            let _ = s.write_all(body);
            let _ = s.flush();
        };
    let range = Some(format!("bytes {a}-{b}/{len}"));
    match mode {
        Mode::Ranges | Mode::Replaced => {
            reply(&mut s, "206 Partial Content", range, body.len(), body)
        }
        Mode::DropsOnce if n > 0 => reply(&mut s, "206 Partial Content", range, body.len(), body),
        Mode::IgnoresRange => reply(&mut s, "200 OK", None, len, data),
        Mode::NotFound => reply(&mut s, "404 Not Found", None, 9, b"not found"),
        Mode::Short => {
            let half = &body[..body.len() / 2];
            reply(&mut s, "206 Partial Content", range, half.len(), half);
        }
        Mode::Drops | Mode::DropsOnce => {
            reply(
                &mut s,
                "206 Partial Content",
                range,
                body.len(),
                &body[..body.len() / 2],
            );
            let _ = s.shutdown(std::net::Shutdown::Both);
        }
        Mode::WrongRange => {
            let r = Some(format!("bytes {}-{b}/{len}", a + 1));
            reply(&mut s, "206 Partial Content", r, body.len() - 1, &body[1..]);
        }
        Mode::Silent => std::thread::sleep(Duration::from_secs(5)),
    }
}

/// 10 000 distinct-ish bytes.
fn bytes() -> Vec<u8> {
    (0..10_000u32).map(|i| (i * 31 % 251) as u8).collect()
}

/// Small blocks, so that a few kilobytes make several.
fn small() -> RangeOptions {
    RangeOptions {
        block_size: 1024,
        cache_blocks: 2,
        ..RangeOptions::default()
    }
}

#[test]
fn ranges_read_seek_cache_and_count() {
    let data = bytes();
    let (url, _) = serve(data.clone(), Mode::Ranges);
    let mut r = RangeReader::open_with(&url, small()).unwrap();
    assert_eq!((r.size(), r.requests()), (10_000, 1));
    assert_eq!(r.shown_url(), url.split('?').next().unwrap());
    // Reads across blocks, from anywhere.
    for (at, len) in [(0usize, 10usize), (1000, 100), (5000, 3000), (9990, 10)] {
        r.seek(SeekFrom::Start(at as u64)).unwrap();
        let mut got = vec![0u8; len];
        r.read_exact(&mut got).unwrap();
        assert_eq!(got, data[at..at + len], "{at}+{len}");
    }
    let mut tail = Vec::new();
    r.seek(SeekFrom::End(-5)).unwrap();
    r.read_to_end(&mut tail).unwrap();
    assert_eq!(tail, data[9995..]);
    // An announced chunk of five blocks is one request.
    let before = r.requests();
    r.will_read(2048..7000).unwrap();
    assert_eq!(r.requests(), before + 1);
    r.seek(SeekFrom::Start(2048)).unwrap();
    let mut got = vec![0u8; 7000 - 2048];
    r.read_exact(&mut got).unwrap();
    assert_eq!(
        (got.as_slice(), r.requests()),
        (&data[2048..7000], before + 1)
    );
    // Blocks 0, 1, 4 to 7, 9 (784 bytes, the file's end), then 2 to 6 again (evicted).
    let io = r.io();
    assert_eq!(
        (io.bytes_read, io.source_bytes),
        (6 * 1024 + 784 + 5 * 1024, 10_000)
    );
}

#[test]
fn a_window_over_http_fetches_about_one_tile() {
    let t = tiled(256, 256, 32, 32, true, "");
    let (url, _) = serve(t.bytes.clone(), Mode::Ranges);
    let opts = RangeOptions {
        block_size: 4096,
        ..RangeOptions::default()
    };
    let reader = RangeReader::open_with(&url, opts).unwrap();
    let mut w = TiffWindows::open(&url, reader, &LoadOptions::default()).unwrap();
    check_window(&mut w, 100, 70, 20, 20);
    let io = w.io();
    // The directory lies at the end: a block there, the first block, and one tile's block.
    assert!(io.bytes_read <= 4 * 4096, "{io:?}");
    assert!(io.bytes_read * 4 < io.source_bytes, "{io:?}");
    check_window(&mut w, 0, 0, 256, 256);
}

/// The error of opening `url` and reading a window of a served TIFF.
fn fails(mode: Mode) -> DemError {
    let t = tiled(64, 64, 16, 16, false, "");
    let (url, _) = serve(t.bytes, mode);
    let e = load(&url, &LoadOptions::default()).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("/dem/f.tif"), "{mode:?}: {msg}");
    assert!(!msg.contains("secret"), "{mode:?} shows the query: {msg}");
    e
}

#[test]
fn misbehaving_servers_get_clear_errors() {
    let e = fails(Mode::IgnoresRange);
    assert!(matches!(e, DemError::NoRanges { .. }), "{e}");
    assert!(
        e.to_string()
            .contains("does not support HTTP range requests (it answered 200 to a Range request)"),
        "{e}"
    );
    let e = fails(Mode::NotFound).to_string();
    assert!(e.contains("404") && e.contains("no such file"), "{e}");
    let e = fails(Mode::Short).to_string();
    assert!(e.contains("cut short"), "{e}");
    let e = fails(Mode::WrongRange).to_string();
    assert!(e.contains("bytes 1-") && e.contains("bytes 0-"), "{e}");
    // A file replaced after the first request: its bytes are never mixed with the new one's.
    let (url, _) = serve(bytes(), Mode::Replaced);
    let mut r = RangeReader::open_with(&url, small()).unwrap();
    r.seek(SeekFrom::Start(5000)).unwrap();
    let e = r.read(&mut [0u8; 10]).unwrap_err().to_string();
    assert!(
        e.contains("changed while it was read") && e.contains("\"v0\"") && e.contains("\"v1\""),
        "{e}"
    );
    assert!(!e.contains("secret"), "{e}");
    let (url, _) = serve(bytes(), Mode::Replaced);
    assert_eq!(RangeReader::open(&url).unwrap().version(), Some("\"v0\""));
    let (url, _) = serve(bytes(), Mode::Ranges);
    assert_eq!(RangeReader::open(&url).unwrap().version(), None);
}

#[test]
fn dropped_connections_are_tried_again() {
    let (url, seen) = serve(bytes(), Mode::Drops);
    let e = RangeReader::open_with(&url, small())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("dropped") && e.contains("tried 3 times"), "{e}");
    assert_eq!(seen.load(Ordering::SeqCst), 3);
    let (url, seen) = serve(bytes(), Mode::DropsOnce);
    let mut r = RangeReader::open_with(&url, small()).unwrap();
    let mut got = [0u8; 4];
    r.read_exact(&mut got).unwrap();
    assert_eq!(
        (got.as_slice(), seen.load(Ordering::SeqCst)),
        (&bytes()[..4], 2)
    );
}

#[test]
fn silent_servers_and_closed_ports_are_errors_not_hangs() {
    let (url, _) = serve(bytes(), Mode::Silent);
    let t = Instant::now();
    let opts = RangeOptions {
        timeout: Duration::from_millis(300),
        ..small()
    };
    let e = RangeReader::open_with(&url, opts.clone())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("f.tif") && e.to_lowercase().contains("timeout"),
        "{e}"
    );
    assert!(t.elapsed() < Duration::from_secs(4), "{:?}", t.elapsed());
    // Nothing listens on a port just freed.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap();
    let e = RangeReader::open_with(&format!("http://{port}/x.tif"), opts)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("x.tif") && e.contains("tried 3 times"), "{e}");
}

#[test]
fn a_url_that_is_not_a_tiff_says_so() {
    let (url, _) = serve(b"<html>no</html>".to_vec(), Mode::Ranges);
    let e = load(&url, &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, DemError::Unsupported { .. }), "{e}");
    assert!(e.to_string().contains("GeoTIFF"), "{e}");
}
