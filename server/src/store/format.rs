//! The store file: one versioned, checksummed file holding the vertex quadtree and the tile
//! pyramid.
//!
//! Layout, all little-endian:
//! - a 256-byte header: magic `RELIEFST`, format version, grid size, spacing, z quantum, then
//!   the offset and length of each section, the CRC-32 of the sections, and last the CRC-32 of
//!   the header itself;
//! - the sections, each aligned to 8 bytes so that they can be read in place from the map:
//!   `nodes` (one u32 record per node, height and error code, children adjacent: see
//!   [`super::layout`]), `voids` (one bit per sample, row-major, 1 = no data in the source),
//!   `meta` (JSON), `tiles`
//!   (one 32-byte [`super::tiles::TileRecord`] per tile by dense index) and `tile_data` (the
//!   tiles' mesh and patch blobs).
//!
//! Opening checks the magic, the version, the header CRC, that every section lies inside the file
//! and has the length the grid implies, and the sections' CRC. Any failure is a [`StoreError`]
//! naming the problem: a store is never half-read.

use super::StoreError;
use std::io::Write;

/// File magic: the first eight bytes of every store.
pub const MAGIC: &[u8; 8] = b"RELIEFST";
/// The format version this build writes and reads. 3: quad-adjacent node records. 4: a grid
/// tile's raised patches also close T-junctions (a fine vertex exactly on the
/// coarse edge), and an `rqt` pyramid's patch blobs hold its crack curtains (version 3 left them
/// empty), so a version-3 store is refused with a call to rebuild it. 5: the `grid` tiles of
/// an `rqt` pyramid (those the grid's border clips) carry their patches, and the `rqt` sides
/// they can meet keep every lattice vertex (version 4 left those cracks open).
pub const VERSION: u32 = 5;
/// Header size in bytes.
pub const HEADER_LEN: usize = 256;
/// Section order in the file.
pub const SECTIONS: [&str; 5] = ["nodes", "voids", "meta", "tiles", "tile_data"];
/// Index of the node records in [`SECTIONS`].
pub const NODES: usize = 0;
/// Index of the void bits.
pub const VOIDS: usize = 1;
/// Index of the metadata.
pub const META: usize = 2;
/// Index of the tile records.
pub const TILES: usize = 3;
/// Index of the tile blobs.
pub const TILE_DATA: usize = 4;
/// Number of sections.
pub const SECTION_COUNT: usize = SECTIONS.len();
/// Where the body CRC sits in the header, after the section table.
const BODY_CRC_AT: usize = 48 + 16 * SECTION_COUNT;

/// The fixed fields of the header.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Grid width in samples.
    pub width: u32,
    /// Grid height in samples.
    pub height: u32,
    /// Ground metres between columns.
    pub spacing_x: f64,
    /// Ground metres between rows.
    pub spacing_y: f64,
    /// Metres per integer height unit.
    pub z_quantum: f64,
    /// Cells per side of the tile pyramid's tiles.
    pub tile_size: u32,
    /// (offset, length) in bytes of each section, in [`SECTIONS`] order.
    pub sections: [(u64, u64); SECTION_COUNT],
    /// CRC-32 of all section bytes, in file order.
    pub body_crc: u32,
}

impl Header {
    /// Serialises the header, CRC last.
    pub fn to_bytes(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        b[0..8].copy_from_slice(MAGIC);
        b[8..12].copy_from_slice(&VERSION.to_le_bytes());
        b[12..16].copy_from_slice(&self.width.to_le_bytes());
        b[16..20].copy_from_slice(&self.height.to_le_bytes());
        b[24..32].copy_from_slice(&self.spacing_x.to_le_bytes());
        b[32..40].copy_from_slice(&self.spacing_y.to_le_bytes());
        b[40..48].copy_from_slice(&self.z_quantum.to_le_bytes());
        for (i, (off, len)) in self.sections.iter().enumerate() {
            let at = 48 + 16 * i;
            b[at..at + 8].copy_from_slice(&off.to_le_bytes());
            b[at + 8..at + 16].copy_from_slice(&len.to_le_bytes());
        }
        b[BODY_CRC_AT..BODY_CRC_AT + 4].copy_from_slice(&self.body_crc.to_le_bytes());
        b[BODY_CRC_AT + 4..BODY_CRC_AT + 8].copy_from_slice(&self.tile_size.to_le_bytes());
        let crc = crc32fast::hash(&b[..HEADER_LEN - 4]);
        b[HEADER_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
        b
    }

    /// Parses and checks a header; `file_len` is the whole file's size.
    pub fn parse(b: &[u8], file_len: u64) -> Result<Header, StoreError> {
        if b.len() < HEADER_LEN {
            if b.len() >= 8 && &b[..8] != MAGIC {
                return Err(StoreError::NotAStore);
            }
            return Err(StoreError::Truncated {
                expected: HEADER_LEN as u64,
                actual: b.len() as u64,
            });
        }
        if &b[..8] != MAGIC {
            return Err(StoreError::NotAStore);
        }
        let u32_at = |at: usize| u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        let u64_at = |at: usize| {
            let mut a = [0u8; 8];
            a.copy_from_slice(&b[at..at + 8]);
            u64::from_le_bytes(a)
        };
        let version = u32_at(8);
        if version != VERSION {
            return Err(StoreError::Version {
                found: version,
                supported: VERSION,
            });
        }
        if crc32fast::hash(&b[..HEADER_LEN - 4]) != u32_at(HEADER_LEN - 4) {
            return Err(StoreError::Corrupt("header checksum mismatch".into()));
        }
        let mut sections = [(0u64, 0u64); SECTION_COUNT];
        for (i, s) in sections.iter_mut().enumerate() {
            *s = (u64_at(48 + 16 * i), u64_at(56 + 16 * i));
            let end =
                s.0.checked_add(s.1)
                    .ok_or(StoreError::Corrupt("section bounds overflow".into()))?;
            if end > file_len {
                return Err(StoreError::Truncated {
                    expected: end,
                    actual: file_len,
                });
            }
            if s.0 % 8 != 0 || s.0 < HEADER_LEN as u64 {
                return Err(StoreError::Corrupt(format!(
                    "section {} is misplaced",
                    SECTIONS[i]
                )));
            }
        }
        Ok(Header {
            width: u32_at(12),
            height: u32_at(16),
            spacing_x: f64::from_bits(u64_at(24)),
            spacing_y: f64::from_bits(u64_at(32)),
            z_quantum: f64::from_bits(u64_at(40)),
            tile_size: u32_at(BODY_CRC_AT + 4),
            sections,
            body_crc: u32_at(BODY_CRC_AT),
        })
    }
}

/// Writes a store's sections one after another to `out`, each as soon as it is made: a header
/// placeholder first, the real header (section offsets and the body's checksum) last.
pub struct SectionWriter<W> {
    out: W,
    header: Header,
    /// The next section's index.
    next: usize,
    /// Bytes written so far.
    pos: u64,
    crc: crc32fast::Hasher,
}

impl<W: Write + std::io::Seek> SectionWriter<W> {
    /// Starts a store of `header`'s fields (its sections and checksum are filled in here).
    pub fn new(mut out: W, header: Header) -> std::io::Result<SectionWriter<W>> {
        out.write_all(&[0u8; HEADER_LEN])?;
        Ok(SectionWriter {
            out,
            header,
            next: 0,
            pos: HEADER_LEN as u64,
            crc: crc32fast::Hasher::new(),
        })
    }

    /// Appends the next section, padded to 8 bytes.
    pub fn section(&mut self, s: &[u8]) -> std::io::Result<()> {
        self.section_parts(std::iter::once(s))
    }

    /// Appends the next section made of `parts` back to back, padded to 8 bytes.
    pub fn section_parts<'p>(
        &mut self,
        parts: impl Iterator<Item = &'p [u8]> + Clone,
    ) -> std::io::Result<()> {
        let len: u64 = parts.clone().map(|p| p.len() as u64).sum();
        self.claim(len)?;
        for p in parts {
            self.out.write_all(p)?;
            self.crc.update(p);
        }
        self.close(len)
    }

    /// Where the next section starts.
    pub fn position(&self) -> u64 {
        self.pos
    }

    /// Takes the next section as `len` bytes already written in place at [`Self::position`]
    /// (by positioned writes to the same file) with checksum `crc`, and moves past it.
    pub fn section_written(&mut self, len: u64, crc: &crc32fast::Hasher) -> std::io::Result<()> {
        self.claim(len)?;
        self.crc.combine(crc);
        self.out.seek(std::io::SeekFrom::Start(self.pos + len))?;
        self.close(len)
    }

    /// Records the next section as `len` bytes from here.
    fn claim(&mut self, len: u64) -> std::io::Result<()> {
        let Some(slot) = self.header.sections.get_mut(self.next) else {
            return Err(std::io::Error::other(format!(
                "a store has {SECTION_COUNT} sections, not more"
            )));
        };
        *slot = (self.pos, len);
        Ok(())
    }

    /// Moves past the `len` bytes of the section just written and pads it to 8 bytes.
    fn close(&mut self, len: u64) -> std::io::Result<()> {
        self.pos += len;
        let pad = (8 - self.pos % 8) % 8;
        self.out.write_all(&[0u8; 8][..pad as usize])?;
        self.pos += pad;
        self.next += 1;
        Ok(())
    }

    /// The writer, e.g. to flush and sync what is written so far.
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.out
    }

    /// Writes the real header once every section is written; returns the writer and the
    /// store's size.
    pub fn finish(mut self) -> std::io::Result<(W, u64)> {
        use std::io::SeekFrom;
        if self.next != SECTION_COUNT {
            return Err(std::io::Error::other(format!(
                "{} of a store's {SECTION_COUNT} sections written",
                self.next
            )));
        }
        self.header.body_crc = self.crc.finalize();
        self.out.seek(SeekFrom::Start(0))?;
        self.out.write_all(&self.header.to_bytes())?;
        Ok((self.out, self.pos))
    }
}

/// Writes a header placeholder, the sections, then the real header, to `out`.
pub fn write_sections<W: Write + std::io::Seek>(
    out: &mut W,
    header: Header,
    sections: [&[u8]; SECTION_COUNT],
) -> std::io::Result<u64> {
    let mut w = SectionWriter::new(out, header)?;
    for s in sections {
        w.section(s)?;
    }
    Ok(w.finish()?.1)
}
