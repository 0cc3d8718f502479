//! Store round trip and corrupt-input tests.

use super::*;

fn input<'a>(heights: &'a [f32], voids: &'a [bool], w: u32, h: u32) -> StoreInput<'a> {
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
    let voids: Vec<bool> = (0..w * h).map(|i| i % 50 == 0).collect();
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

    // The tile sections (issue 10): a flipped byte in the last tile blob, and a tile record
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
    // Issue 13: a version-3 store (rqt tiles without crack curtains) is refused the same way.
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
    let voids = vec![false; (w * h) as usize];
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
