//! The one place that maps a file into memory.
#![allow(unsafe_code)] // Reason: memory-mapping a file is inherently unsafe in Rust's model.

use memmap2::Mmap;
use std::fs::File;

/// Maps `file` read-only.
pub fn map(file: &File) -> std::io::Result<Mmap> {
    // SAFETY: the map is read-only and private to this process. Relief never writes a store in
    // place: `build` writes a new file and renames it over the old one, so a mapped store is not
    // truncated under us by Relief itself. Every byte is checksummed at open, before any read.
    unsafe { Mmap::map(file) }
}
