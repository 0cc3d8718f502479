//! The cell records of [`super::FanMesh`] in a sparse paged grid ([`crate::paged`]): the cells
//! around one block share a page or a few, so an update touches a few cache lines where a hash
//! table would touch one per cell. Changed cells are marked one bit each in their page.

use crate::paged::Paged;

/// A sparse grid of 16-bit cell records, 0 meaning empty, with dirty marks.
#[derive(Clone, Debug)]
pub(super) struct CellGrid {
    /// The non-empty records (a record is present exactly when it is not 0); a page's marks are
    /// the cells changed since the last [`CellGrid::take_dirty`].
    cells: Paged<u16>,
    /// Pages with a marked cell, each once.
    dirty_pages: Vec<u32>,
}

impl CellGrid {
    /// An empty grid of `cols` x `rows` cells.
    pub(super) fn new(cols: u32, rows: u32) -> CellGrid {
        CellGrid {
            cells: Paged::new(cols, rows),
            dirty_pages: Vec::new(),
        }
    }

    /// The record of cell `(c, r)`.
    #[inline]
    pub(super) fn get(&self, c: u32, r: u32) -> u16 {
        self.cells.get(c, r).copied().unwrap_or(0)
    }

    /// Sets cell `(c, r)` to `record`, marking it dirty if `track`; returns the old record, or
    /// `None` if it was already `record`.
    #[inline]
    pub(super) fn set(&mut self, c: u32, r: u32, record: u16, track: bool) -> Option<u16> {
        let (p, i) = if record == 0 {
            self.cells.slot(c, r)?
        } else {
            self.cells.slot_or_make(c, r)
        };
        let pg = self.cells.page_mut(p);
        let bit = 1u64 << i;
        // An absent record is 0 in its page too (pages are made zeroed, and a record that
        // empties is written 0), so the record is read without a branch on its presence bit.
        let old = pg.records[i as usize];
        if old == record {
            return None;
        }
        pg.records[i as usize] = record;
        pg.present ^= bit * u64::from((old == 0) != (record == 0));
        if track {
            if pg.marks == 0 {
                self.dirty_pages.push(p);
            }
            pg.marks |= bit;
        } else if record == 0 {
            self.cells.release_if_empty(p);
        }
        Some(old)
    }

    /// Appends the dirty cells to `out` and clears their marks; gives back pages left empty.
    pub(super) fn take_dirty(&mut self, out: &mut Vec<(u32, u32)>) {
        for p in std::mem::take(&mut self.dirty_pages) {
            let pg = self.cells.page_mut(p);
            let mut bits = std::mem::take(&mut pg.marks);
            while bits != 0 {
                let i = bits.trailing_zeros();
                bits &= bits - 1;
                out.push(pg.position(i));
            }
            self.cells.release_if_empty(p);
        }
    }

    /// Calls `f(c, r, record)` for every non-empty cell, in no set order.
    pub(super) fn for_each(&self, mut f: impl FnMut(u32, u32, u16)) {
        self.cells.for_each(|c, r, &rec| f(c, r, rec));
    }
}
