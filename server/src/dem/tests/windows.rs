//! Tests of [`TiffWindows`](super::TiffWindows) (declared in `cog.rs`): windows over tiled and
//! striped TIFFs equal the samples they cover, each chunk is decoded once by windows that walk
//! down the grid, a window of one tile reads about one tile's bytes, and truncated files or
//! lying byte counts are errors naming the tile. Real Cloud-Optimized GeoTIFFs from GDAL
//! (deflate, LZW, zstd, predictors 2 and 3) are tested end to end in
//! `tests/tests/e2e/cog_input.rs`.

use super::{Counting, TiffWindows};
use crate::dem::{DemError, LoadOptions};
use std::io::{Cursor, Write};
use tiff::encoder::{TiffEncoder, colortype};

/// A tiled int16 TIFF written by hand (the `tiff` crate writes strips only).
pub(crate) struct Tiled {
    /// The file.
    pub bytes: Vec<u8>,
    /// Where each tile's TileByteCounts entry (a little-endian u32) is in `bytes`.
    pub count_at: Vec<usize>,
    /// Each tile's data offset.
    pub offsets: Vec<u32>,
}

/// The test surface: distinct, signed values.
pub(crate) fn surface(x: u32, y: u32) -> i16 {
    (x as i32 * 7 + y as i32 * 13 - 100) as i16
}

/// A `w` x `h` int16 TIFF of [`surface`] in `tw` x `th` tiles (edge tiles padded with 9999,
/// which no window may show), zlib-deflated or not, with an optional GDAL_NODATA.
pub(crate) fn tiled(w: u32, h: u32, tw: u32, th: u32, deflate: bool, nodata: &str) -> Tiled {
    let (across, down) = (w.div_ceil(tw), h.div_ceil(th));
    let mut bytes = b"II*\0\0\0\0\0".to_vec();
    let (mut offsets, mut counts) = (Vec::new(), Vec::new());
    for ty in 0..down {
        for tx in 0..across {
            let mut raw = Vec::new();
            for y in ty * th..(ty + 1) * th {
                for x in tx * tw..(tx + 1) * tw {
                    let v = if x < w && y < h { surface(x, y) } else { 9999 };
                    raw.extend_from_slice(&v.to_le_bytes());
                }
            }
            if deflate {
                let mut z = flate2::write::ZlibEncoder::new(Vec::new(), Default::default());
                z.write_all(&raw).unwrap();
                raw = z.finish().unwrap();
            }
            offsets.push(bytes.len() as u32);
            counts.push(raw.len() as u32);
            bytes.extend_from_slice(&raw);
        }
    }
    if bytes.len() % 2 == 1 {
        bytes.push(0);
    }
    let ifd = bytes.len();
    bytes[4..8].copy_from_slice(&(ifd as u32).to_le_bytes());
    let n = offsets.len() as u32;
    let mut nodata = nodata.as_bytes().to_vec();
    nodata.push(0);
    // (tag, type, count, inline value); arrays go after the directory.
    let short = |tag: u16, v: u16| (tag, 3u16, 1u32, u32::from(v));
    let long = |tag: u16, v: u32| (tag, 4u16, 1u32, v);
    let mut entries = vec![
        long(256, w),
        long(257, h),
        short(258, 16),
        short(259, if deflate { 8 } else { 1 }),
        short(262, 1),
        short(277, 1),
        long(322, tw),
        long(323, th),
        (324, 4, n, 0),
        (325, 4, n, 0),
        short(339, 2),
    ];
    if nodata.len() > 1 {
        entries.push((42113, 2, nodata.len() as u32, 0));
    }
    let dir_len = 2 + 12 * entries.len() + 4;
    let mut extra = ifd + dir_len;
    let mut tail = Vec::new();
    let mut count_at = Vec::new();
    bytes.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, kind, count, value) in entries {
        let out_of_line: Option<Vec<u8>> = match tag {
            324 => Some(offsets.iter().flat_map(|o| o.to_le_bytes()).collect()),
            325 => {
                count_at = (0..n as usize).map(|i| extra + 4 * i).collect();
                Some(counts.iter().flat_map(|c| c.to_le_bytes()).collect())
            }
            42113 => Some(nodata.clone()),
            _ => None,
        };
        bytes.extend_from_slice(&tag.to_le_bytes());
        bytes.extend_from_slice(&kind.to_le_bytes());
        bytes.extend_from_slice(&count.to_le_bytes());
        match out_of_line {
            Some(data) if data.len() > 4 => {
                bytes.extend_from_slice(&(extra as u32).to_le_bytes());
                extra += data.len() + data.len() % 2;
                tail.extend_from_slice(&data);
                if data.len() % 2 == 1 {
                    tail.push(0);
                }
            }
            Some(mut data) => {
                if tag == 325 {
                    count_at = vec![bytes.len()];
                }
                data.resize(4, 0);
                bytes.extend_from_slice(&data);
            }
            None => bytes.extend_from_slice(&value.to_le_bytes()),
        }
    }
    bytes.extend_from_slice(&0u32.to_le_bytes());
    bytes.extend_from_slice(&tail);
    Tiled {
        bytes,
        count_at,
        offsets,
    }
}

/// Windows over `bytes` in memory.
pub(crate) fn windows(bytes: &[u8]) -> Result<TiffWindows<Counting<Cursor<Vec<u8>>>>, DemError> {
    let len = bytes.len() as u64;
    TiffWindows::open(
        "test.tif",
        Counting::new(Cursor::new(bytes.to_vec()), len),
        &LoadOptions::default(),
    )
}

/// Reads the window and checks it against [`surface`].
pub(crate) fn check_window<R: super::Source>(
    t: &mut TiffWindows<R>,
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
) {
    let mut out = vec![f32::NAN; (w * h) as usize];
    t.read_window(x0, y0, w, h, &mut out).unwrap();
    for y in 0..h {
        for x in 0..w {
            let want = f32::from(surface(x0 + x, y0 + y));
            let got = out[(y * w + x) as usize];
            assert_eq!(got, want, "window ({x0}, {y0}) {w}x{h} at ({x}, {y})");
        }
    }
}

#[test]
fn windows_over_tiles_equal_the_samples_and_decode_each_tile_once() {
    for deflate in [false, true] {
        // 3 x 3 tiles of 16 x 16, the last column 8 wide and the last row 3 high.
        let t = tiled(40, 35, 16, 16, deflate, "");
        let mut w = windows(&t.bytes).unwrap();
        assert_eq!((w.width(), w.height(), w.chunk_size()), (40, 35, (16, 16)));
        check_window(&mut w, 0, 0, 40, 35);
        assert_eq!(w.chunks_decoded(), 9);
        for (x0, y0, ww, wh) in [(0, 0, 1, 1), (39, 34, 1, 1), (15, 15, 2, 2), (5, 30, 35, 5)] {
            check_window(&mut w, x0, y0, ww, wh);
        }
        // Bands down the grid: partly used tiles are kept for the next band.
        let mut w = windows(&t.bytes).unwrap();
        for (y0, h) in [(0, 10), (10, 10), (20, 15)] {
            check_window(&mut w, 0, y0, 40, h);
        }
        assert_eq!(w.chunks_decoded(), 9, "deflate {deflate}");
    }
}

#[test]
fn a_window_of_one_tile_reads_about_one_tile() {
    let t = tiled(128, 128, 16, 16, false, "");
    let mut w = windows(&t.bytes).unwrap();
    let header = w.io().bytes_read;
    check_window(&mut w, 48, 64, 16, 16);
    let io = w.io();
    assert_eq!(io.source_bytes, t.bytes.len() as u64);
    // The directory, then one 512-byte tile (BufReader-free: exact).
    assert_eq!(io.bytes_read - header, 512, "{io:?}");
    assert_eq!(w.chunks_decoded(), 1);
}

#[test]
fn windows_over_strips_equal_the_samples() {
    let (wd, ht) = (30u32, 23u32);
    let data: Vec<i16> = (0..ht)
        .flat_map(|y| (0..wd).map(move |x| surface(x, y)))
        .collect();
    let mut buf = Cursor::new(Vec::new());
    let mut enc = TiffEncoder::new(&mut buf).unwrap();
    let mut img = enc.new_image::<colortype::GrayI16>(wd, ht).unwrap();
    img.rows_per_strip(5).unwrap();
    img.write_data(&data).unwrap();
    let mut w = windows(&buf.into_inner()).unwrap();
    assert_eq!(w.chunk_size(), (30, 5));
    check_window(&mut w, 0, 0, wd, ht);
    check_window(&mut w, 3, 4, 20, 13);
    check_window(&mut w, 29, 22, 1, 1);
}

#[test]
fn windows_outside_the_grid_are_errors() {
    let t = tiled(40, 35, 16, 16, false, "");
    let mut w = windows(&t.bytes).unwrap();
    let mut out = vec![0.0; 4];
    for (x0, y0, ww, wh) in [
        (39, 0, 2, 2),
        (0, 34, 2, 2),
        (u32::MAX, 0, 2, 2),
        (0, 0, 1, 1),
    ] {
        let e = w.read_window(x0, y0, ww, wh, &mut out).unwrap_err();
        assert!(matches!(e, DemError::BadOptions { .. }), "{e}");
    }
}

#[test]
fn truncated_files_and_lying_byte_counts_name_the_tile() {
    let t = tiled(40, 35, 16, 16, true, "");
    // Cut in half: the directory (at the end) is gone.
    let e = windows(&t.bytes[..t.bytes.len() / 2]).err().unwrap();
    assert!(matches!(e, DemError::Corrupt { .. }), "{e}");
    // A count past the file's end.
    let patch = |tile: usize, count: u32| {
        let mut b = t.bytes.clone();
        let at = t.count_at[tile];
        b[at..at + 4].copy_from_slice(&count.to_le_bytes());
        b
    };
    let e = windows(&patch(4, 1 << 30))
        .unwrap()
        .read_window(0, 0, 40, 35, &mut vec![0.0; 40 * 35])
        .unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, DemError::Corrupt { .. }), "{msg}");
    assert!(
        msg.contains("tile 4 (column 1, row 1)") && msg.contains("past the end"),
        "{msg}"
    );
    // A count too small: the fence stops the inflater at the tile's end.
    let tile4 = (t.offsets[5] - t.offsets[4]) / 2;
    let e = windows(&patch(4, tile4))
        .unwrap()
        .read_window(0, 0, 40, 35, &mut vec![0.0; 40 * 35])
        .unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, DemError::Corrupt { .. }), "{msg}");
    assert!(msg.contains("tile 4 (column 1, row 1)"), "{msg}");
    // Windows that miss the broken tile still read.
    let mut w = windows(&patch(4, tile4)).unwrap();
    check_window(&mut w, 0, 0, 16, 16);
}

#[test]
fn tiles_without_bytes_are_no_data_where_the_file_declares_it() {
    let mut t = tiled(40, 35, 16, 16, false, "-32768");
    let at = t.count_at[2];
    t.bytes[at..at + 4].copy_from_slice(&0u32.to_le_bytes());
    let mut w = windows(&t.bytes).unwrap();
    assert_eq!(w.nodata(), Some(-32768.0));
    let mut out = vec![0.0; 8 * 16];
    w.read_window(32, 0, 8, 16, &mut out).unwrap();
    assert!(out.iter().all(|&v| v == -32768.0));
    let mut t = tiled(40, 35, 16, 16, false, "");
    let at = t.count_at[2];
    t.bytes[at..at + 4].copy_from_slice(&0u32.to_le_bytes());
    let e = windows(&t.bytes)
        .unwrap()
        .read_window(32, 0, 8, 16, &mut out)
        .unwrap_err();
    assert!(e.to_string().contains("GDAL_NODATA"), "{e}");
}
