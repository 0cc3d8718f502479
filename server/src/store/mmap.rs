//! The one place that maps a file into memory.
#![allow(unsafe_code)] // Reason: memory-mapping a file is inherently unsafe in Rust's model.

use memmap2::Mmap;
use std::fs::File;

/// Maps `file` read-only.
pub fn map(file: &File) -> std::io::Result<Mmap> {
    // SAFETY: the map is read-only. Relief never writes a store in place: `build` writes a new
    // file and renames it over the old one. The server maps a private, unnamed copy that no
    // other process can open by name (see `private`), so nothing truncates or changes it under
    // us. Every byte is checksummed at open, before any read.
    unsafe { Mmap::map(file) }
}
