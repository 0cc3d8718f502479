//! Windowed GeoTIFF reading: [`TiffWindows`] decodes only the internal tiles or strips (the
//! TIFF's "chunks") that a window of the grid touches, so that a Cloud-Optimized GeoTIFF (a
//! tiled GeoTIFF with its directories first, as `gdal_translate -of COG` writes) is read
//! piecemeal, from a file or by HTTP range requests ([`super::http_range`]).
//!
//! - Chunks are decoded by the `tiff` crate (`Decoder::read_chunk`): deflate, LZW and zstd,
//!   horizontal (2) and floating-point (3) predictors. Striped files are read the same way: a
//!   strip is a chunk as wide as the image.
//! - The whole-grid read ([`super::geotiff::read`]) is one window over everything: its peak
//!   memory is the output grid plus one decoded chunk, not the grid plus the decoded image.
//! - A chunk that a window uses only partly is kept, with the others of its chunk row, so that
//!   windows that walk down the grid in bands decode each chunk once. Chunks a window covers
//!   whole are not kept.
//! - Each chunk's bytes (its TileOffsets / TileByteCounts entry) are checked against the
//!   source's size before decoding, and the decoder reads through a fence that ends there: a
//!   truncated file, or a byte count that lies, is an error naming the chunk, never a read of
//!   another chunk's bytes. A chunk with no bytes (GDAL's sparse files) is all no-data.
//! - The source is a [`Source`]: it counts the bytes it reads ([`IoStats`]) and may be told
//!   which bytes come next ([`Source::will_read`]), so that a remote source fetches a chunk in
//!   one request.

use super::geotiff::{GeoTags, corrupt, kind};
use super::{DemError, IoStats, LoadOptions, check_size};
use crate::geo::Georef;
use std::io::{self, Read, Seek, SeekFrom};
use std::ops::Range;
use tiff::ColorType;
use tiff::decoder::{ChunkType, Decoder, DecodingResult, Limits};
use tiff::tags::Tag;

/// A byte source for [`TiffWindows`]: a file, bytes in memory, or a remote file.
pub trait Source: Read + Seek {
    /// Bytes read from the source so far, and its size.
    fn io(&self) -> IoStats;

    /// A hint that the bytes `range` are read next (one chunk's), so that a remote source can
    /// fetch them in one request rather than block by block.
    fn will_read(&mut self, range: Range<u64>) -> Result<(), DemError> {
        let _ = range;
        Ok(())
    }
}

/// A reader that counts the bytes read through it, for [`IoStats`] of local files.
pub struct Counting<R> {
    /// The file or bytes.
    inner: R,
    /// Bytes read so far.
    read: u64,
    /// The source's size, reported beside what was read.
    size: u64,
}

impl<R> Counting<R> {
    /// Wraps `inner`, a source of `size` bytes.
    pub fn new(inner: R, size: u64) -> Counting<R> {
        Counting {
            inner,
            read: 0,
            size,
        }
    }
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.read += n as u64;
        Ok(n)
    }
}

impl<R: Seek> Seek for Counting<R> {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.inner.seek(pos)
    }
}

impl<R: Read + Seek> Source for Counting<R> {
    fn io(&self) -> IoStats {
        IoStats {
            bytes_read: self.read,
            source_bytes: self.size,
        }
    }
}

/// The decoder's reader: passes reads through, but none past `end` while a chunk is decoded,
/// so that a decompressor that reads ahead, or a byte count that lies, cannot reach beyond the
/// chunk.
struct Fenced<R> {
    /// The source.
    inner: R,
    /// The position in the source, to know how far the fence is.
    pos: u64,
    /// Where reads stop, while a chunk is decoded.
    end: Option<u64>,
}

impl<R: Read> Read for Fenced<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let room = match self.end {
            Some(end) => usize::try_from(end.saturating_sub(self.pos)).unwrap_or(usize::MAX),
            None => usize::MAX,
        };
        let len = buf.len().min(room);
        let n = self.inner.read(&mut buf[..len])?;
        self.pos += n as u64;
        Ok(n)
    }
}

impl<R: Seek> Seek for Fenced<R> {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.pos = self.inner.seek(pos)?;
        Ok(self.pos)
    }
}

/// Sample types by (SampleFormat, BitsPerSample): their names for messages, and whether Relief
/// reads them (as the decoder widens them to `f32`).
const SAMPLE_TYPES: [(u16, u8, &str, bool); 11] = [
    (1, 8, "uint8", false),
    (1, 16, "uint16", true),
    (1, 32, "uint32", false),
    (1, 64, "uint64", false),
    (2, 8, "int8", false),
    (2, 16, "int16", true),
    (2, 32, "int32", true),
    (2, 64, "int64", false),
    (3, 16, "float16", false),
    (3, 32, "float32", true),
    (3, 64, "float64", true),
];

/// A single-band GeoTIFF read window by window; see the module docs.
pub struct TiffWindows<R: Source> {
    /// The input's name, for messages.
    name: String,
    /// The decoder, over the fenced source.
    dec: Decoder<Fenced<R>>,
    /// Image size in samples.
    size: (u32, u32),
    /// Chunk size in samples (a strip is as wide as the image).
    chunk: (u32, u32),
    /// Chunks per row of chunks.
    across: u32,
    /// "tile" or "strip", for messages.
    what: &'static str,
    /// Each chunk's first byte in the source.
    offsets: Vec<u64>,
    /// Each chunk's byte count.
    counts: Vec<u64>,
    /// The GDAL_NODATA value, if the file declares one.
    nodata: Option<f64>,
    /// The tags that place the grid.
    geo: GeoTags,
    /// The chunk row whose partly used chunks `cache` holds.
    cache_row: Option<u32>,
    /// Decoded chunks of `cache_row` that a window used only partly: (chunk column, samples).
    cache: Vec<(u32, Vec<f32>)>,
    /// Chunks decoded so far, for tests and benchmarks.
    decoded: u64,
}

impl<R: Source> TiffWindows<R> {
    /// Opens the GeoTIFF in `reader` (`name` is used in messages): reads its directory and
    /// tags, and checks its size against `opts` and its sample type, but decodes nothing.
    pub fn open(name: &str, reader: R, opts: &LoadOptions) -> Result<TiffWindows<R>, DemError> {
        let corrupt = |e| corrupt(name, e);
        let fenced = Fenced {
            inner: reader,
            pos: 0,
            end: None,
        };
        let mut dec = Decoder::new(fenced).map_err(corrupt)?;
        let (w, h) = dec.dimensions().map_err(corrupt)?;
        check_size(name, w, h, opts)?;
        let bits = match dec.colortype().map_err(corrupt)? {
            ColorType::Gray(bits) => bits,
            other => {
                return Err(DemError::Unsupported {
                    path: name.into(),
                    detail: format!(
                        "{other:?} pixels; only single-band (grayscale) grids are read"
                    ),
                });
            }
        };
        let format = dec
            .find_tag_unsigned_vec::<u16>(Tag::SampleFormat)
            .map_err(corrupt)?
            .and_then(|v| v.first().copied())
            .unwrap_or(1);
        match SAMPLE_TYPES.iter().find(|t| (t.0, t.1) == (format, bits)) {
            Some(&(_, _, _, true)) => {}
            found => {
                let what = found.map_or_else(
                    || format!("{bits}-bit (format {format})"),
                    |t| t.2.to_string(),
                );
                return Err(unsupported_type(name, &what));
            }
        }
        // The size was checked against max_samples, so the decoder may hold that many 8-byte
        // samples (one chunk, at most the whole image), decoded or still compressed; tag
        // values keep the crate's 1 MiB limit.
        let mut limits = Limits::default();
        let bytes = usize::try_from(opts.max_samples.saturating_mul(8)).unwrap_or(usize::MAX);
        limits.decoding_buffer_size = bytes.max(limits.decoding_buffer_size);
        limits.intermediate_buffer_size = bytes.max(limits.intermediate_buffer_size);
        dec = dec.with_limits(limits);
        let nodata: Option<f64> = dec
            .get_tag_ascii_string(Tag::GdalNodata)
            .ok()
            .and_then(|s| s.trim().trim_end_matches('\0').trim().parse().ok());
        let geo = GeoTags::read(&mut dec);
        let (what, offsets, counts) = match dec.get_chunk_type() {
            ChunkType::Tile => ("tile", Tag::TileOffsets, Tag::TileByteCounts),
            ChunkType::Strip => ("strip", Tag::StripOffsets, Tag::StripByteCounts),
        };
        let offsets = dec.get_tag_u64_vec(offsets).map_err(corrupt)?;
        let counts = dec.get_tag_u64_vec(counts).map_err(corrupt)?;
        let chunk = dec.chunk_dimensions();
        let (across, down) = match chunk {
            (0, _) | (_, 0) => (0, 0),
            (cw, ch) => (w.div_ceil(cw), h.div_ceil(ch)),
        };
        let needed = across as usize * down as usize;
        if needed == 0 || offsets.len() < needed || counts.len() < needed {
            return Err(DemError::Corrupt {
                path: name.into(),
                kind: "GeoTIFF",
                detail: format!(
                    "{} {what} offsets and {} byte counts for {needed} {what}s of {} x {}",
                    offsets.len(),
                    counts.len(),
                    chunk.0,
                    chunk.1
                ),
            });
        }
        Ok(TiffWindows {
            name: name.into(),
            dec,
            size: (w, h),
            chunk,
            across,
            what,
            offsets,
            counts,
            nodata,
            geo,
            cache_row: None,
            cache: Vec::new(),
            decoded: 0,
        })
    }

    /// Samples per row.
    pub fn width(&self) -> u32 {
        self.size.0
    }

    /// Rows.
    pub fn height(&self) -> u32 {
        self.size.1
    }

    /// The size of the file's tiles (or strips: the image's width by the rows per strip).
    pub fn chunk_size(&self) -> (u32, u32) {
        self.chunk
    }

    /// The GDAL_NODATA value, if the file declares one (NaN where it declares `nan`).
    pub fn nodata(&self) -> Option<f64> {
        self.nodata
    }

    /// Ground spacing (x, y) in metres from the geo tags, or why there is none.
    pub fn spacing(&self) -> Result<(f64, f64), String> {
        self.geo.spacing(self.size.0, self.size.1)
    }

    /// `EPSG:n`, if the geo keys name a CRS.
    pub fn crs(&self) -> Option<String> {
        self.geo.crs()
    }

    /// Where the samples lie, if the tags place the grid north-up in an EPSG CRS.
    pub fn georef(&self) -> Option<Georef> {
        self.geo.georef()
    }

    /// What reading has cost so far: bytes read from the source against its size.
    pub fn io(&mut self) -> IoStats {
        self.dec.inner().inner.io()
    }

    /// Chunks decoded so far (a chunk kept for a later window counts once).
    pub fn chunks_decoded(&self) -> u64 {
        self.decoded
    }

    /// Reads the `w` x `h` samples whose top-left sample is column `x0`, row `y0`, row-major
    /// into `out` (exactly `w * h` long), decoding only the chunks the window touches. The
    /// samples are the file's values widened to `f32`; no-data values are left as they are
    /// ([`TiffWindows::nodata`]).
    pub fn read_window(
        &mut self,
        x0: u32,
        y0: u32,
        w: u32,
        h: u32,
        out: &mut [f32],
    ) -> Result<(), DemError> {
        let inside = x0.checked_add(w).is_some_and(|x1| x1 <= self.size.0)
            && y0.checked_add(h).is_some_and(|y1| y1 <= self.size.1);
        if !inside || out.len() != w as usize * h as usize {
            return Err(DemError::BadOptions {
                input: self.name.clone(),
                detail: format!(
                    "a window of {w} x {h} at ({x0}, {y0}) into {} samples: it must lie in the \
                     {} x {} grid and fill its buffer",
                    out.len(),
                    self.size.0,
                    self.size.1
                ),
            });
        }
        if w == 0 || h == 0 {
            return Ok(());
        }
        let (cw, ch) = self.chunk;
        let window = (x0, y0, x0 + w, y0 + h);
        for row in y0 / ch..=(y0 + h - 1) / ch {
            for col in x0 / cw..=(x0 + w - 1) / cw {
                let (cx0, cy0) = (col * cw, row * ch);
                let (cx1, cy1) = ((cx0 + cw).min(self.size.0), (cy0 + ch).min(self.size.1));
                let whole = x0 <= cx0 && cx1 <= window.2 && y0 <= cy0 && cy1 <= window.3;
                let chunk_rect = (cx0, cy0, cx1, cy1);
                if self.cached(row, col).is_none() {
                    let data = self.decode(col, row)?;
                    if whole {
                        place(&data, chunk_rect, window, out);
                        continue;
                    }
                    if self.cache_row != Some(row) {
                        self.cache.clear();
                        self.cache_row = Some(row);
                    }
                    self.cache.push((col, data));
                }
                if let Some(i) = self.cached(row, col) {
                    place(&self.cache[i].1, chunk_rect, window, out);
                }
            }
        }
        Ok(())
    }

    /// Where chunk (`col`, `row`) is in the cache, if it is.
    fn cached(&self, row: u32, col: u32) -> Option<usize> {
        if self.cache_row != Some(row) {
            return None;
        }
        self.cache.iter().position(|(c, _)| *c == col)
    }

    /// Decodes chunk (`col`, `row`) into `f32` samples, row-major at its data size.
    fn decode(&mut self, col: u32, row: u32) -> Result<Vec<f32>, DemError> {
        let index = row * self.across + col;
        let (dw, dh) = (
            self.chunk.0.min(self.size.0 - col * self.chunk.0),
            self.chunk.1.min(self.size.1 - row * self.chunk.1),
        );
        let n = dw as usize * dh as usize;
        let (offset, count) = (self.offsets[index as usize], self.counts[index as usize]);
        let (name, what) = (self.name.clone(), self.what);
        let err = |detail: String| DemError::Corrupt {
            path: name.clone(),
            kind: "GeoTIFF",
            detail: format!("{what} {index} (column {col}, row {row}): {detail}"),
        };
        if count == 0 {
            // GDAL writes no bytes for a chunk that is all no-data (SPARSE_OK files).
            return match self.nodata {
                Some(nd) => Ok(vec![nd as f32; n]),
                None => Err(err(
                    "it has no bytes (a sparse file) and the file declares no GDAL_NODATA value \
                     to fill it with"
                        .into(),
                )),
            };
        }
        let size = self.dec.inner().inner.io().source_bytes;
        let end = offset.checked_add(count).filter(|&e| e <= size);
        let Some(end) = end else {
            let cap = if what == "tile" { "Tile" } else { "Strip" };
            return Err(err(format!(
                "its {count} bytes at offset {offset} run past the end of the file ({size} \
                 bytes): the file is truncated, or its {cap}ByteCounts or {cap}Offsets are wrong"
            )));
        };
        self.dec.inner().inner.will_read(offset..end)?;
        self.dec.inner().end = Some(end);
        let decoded = self.dec.read_chunk(index);
        self.dec.inner().end = None;
        let decoded = decoded.map_err(|e| match e {
            tiff::TiffError::IoError(io) if io.kind() == io::ErrorKind::UnexpectedEof => {
                err(format!(
                    "its data ({count} bytes by the file's byte counts) ends before the \
                     {what} does: the byte count is wrong or the data corrupt"
                ))
            }
            e => match corrupt(&name, e) {
                DemError::Corrupt { detail, .. } => err(detail),
                other => other,
            },
        })?;
        self.decoded += 1;
        let samples: Vec<f32> = match decoded {
            DecodingResult::I16(v) => v.into_iter().map(f32::from).collect(),
            DecodingResult::U16(v) => v.into_iter().map(f32::from).collect(),
            DecodingResult::I32(v) => v.into_iter().map(|x| x as f32).collect(),
            DecodingResult::F32(v) => v,
            DecodingResult::F64(v) => v.into_iter().map(|x| x as f32).collect(),
            other => return Err(unsupported_type(&name, kind(&other))),
        };
        if samples.len() != n {
            return Err(err(format!(
                "{} samples decoded for {dw} x {dh}",
                samples.len()
            )));
        }
        Ok(samples)
    }
}

/// Copies the part of a chunk's `data` (covering `chunk`: x0, y0, x1, y1) that lies in
/// `window` into `out`, the window's samples.
fn place(data: &[f32], chunk: (u32, u32, u32, u32), window: (u32, u32, u32, u32), out: &mut [f32]) {
    let (x0, x1) = (chunk.0.max(window.0), chunk.2.min(window.2));
    let (y0, y1) = (chunk.1.max(window.1), chunk.3.min(window.3));
    let (cw, ww) = ((chunk.2 - chunk.0) as usize, (window.2 - window.0) as usize);
    let len = (x1 - x0) as usize;
    for y in y0..y1 {
        let src = (y - chunk.1) as usize * cw + (x0 - chunk.0) as usize;
        let dst = (y - window.1) as usize * ww + (x0 - window.0) as usize;
        out[dst..dst + len].copy_from_slice(&data[src..src + len]);
    }
}

/// The error for samples of a type Relief does not read.
fn unsupported_type(name: &str, what: &str) -> DemError {
    DemError::Unsupported {
        path: name.into(),
        detail: format!("{what} samples; Relief reads int16, uint16, int32, float32 and float64"),
    }
}

#[cfg(test)]
#[path = "tests/windows.rs"]
pub(crate) mod tests;
