//! The node records written into the store file as the tree streams them ([`RecordSink`]): each
//! level's records go to their own range of the `nodes` section, through a buffer of their own,
//! and each level's checksum is kept apart and joined in file order at the end, so that the
//! levels can arrive interleaved, as [`super::build::TreeBuilder`] sends them.

use super::StoreError;
use super::build::RecordSink;
use super::layout::QuadLayout;
use std::fs::File;
use std::os::unix::fs::FileExt;

/// Bytes a level gathers before they are written.
const FLUSH_BYTES: usize = 256 << 10;

/// The `nodes` section being written in place.
pub struct RecordFile<'f> {
    file: &'f File,
    /// The file's name, for errors.
    path: String,
    /// Each level's first offset in the file.
    start: Vec<u64>,
    /// Each level's next offset in the file.
    at: Vec<u64>,
    /// Each level's end offset.
    end: Vec<u64>,
    /// Each level's records not yet written.
    pending: Vec<Vec<u8>>,
    /// Each level's checksum so far.
    crc: Vec<crc32fast::Hasher>,
}

impl<'f> RecordFile<'f> {
    /// The section of `layout`'s records, starting at byte `offset` of `file` (named `path`).
    pub fn new(file: &'f File, path: &str, offset: u64, layout: &QuadLayout) -> RecordFile<'f> {
        let levels = layout.levels();
        let start = |l: usize| {
            let slot = if l < levels {
                layout.level_start(l as u8)
            } else {
                layout.len()
            };
            offset + 4 * slot
        };
        RecordFile {
            file,
            path: path.to_string(),
            start: (0..levels).map(start).collect(),
            at: (0..levels).map(start).collect(),
            end: (1..=levels).map(start).collect(),
            pending: vec![Vec::new(); levels],
            crc: vec![crc32fast::Hasher::new(); levels],
        }
    }

    fn flush(&mut self, level: usize) -> Result<(), StoreError> {
        let buf = &mut self.pending[level];
        self.file
            .write_all_at(buf, self.at[level])
            .map_err(|source| StoreError::Io {
                path: self.path.clone(),
                source,
            })?;
        self.at[level] += buf.len() as u64;
        buf.clear();
        Ok(())
    }

    /// Writes what is pending and returns the section's checksum, once every level is
    /// complete.
    pub fn finish(mut self) -> Result<crc32fast::Hasher, StoreError> {
        let mut crc = crc32fast::Hasher::new();
        for l in 0..self.at.len() {
            self.flush(l)?;
            if self.at[l] != self.end[l] {
                return Err(StoreError::Corrupt(format!(
                    "level {l} of the tree wrote {} of its {} bytes",
                    self.at[l] - self.start[l],
                    self.end[l] - self.start[l]
                )));
            }
            crc.combine(&self.crc[l]);
        }
        Ok(crc)
    }
}

impl RecordSink for RecordFile<'_> {
    fn records(&mut self, level: u8, records: &[u32]) -> Result<(), StoreError> {
        let l = level as usize;
        let bytes: &[u8] = bytemuck::cast_slice(records);
        let room = self.end[l] - self.at[l] - self.pending[l].len() as u64;
        if bytes.len() as u64 > room {
            return Err(StoreError::Corrupt(format!(
                "level {l} of the tree sent more records than it has slots"
            )));
        }
        self.crc[l].update(bytes);
        self.pending[l].extend_from_slice(bytes);
        if self.pending[l].len() >= FLUSH_BYTES {
            self.flush(l)?;
        }
        Ok(())
    }
}
