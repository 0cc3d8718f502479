//! The cell records of [`super::FanMesh`], in a sparse paged grid: pages of 8 x 8 cells, found
//! through a dense table of regions of 8 x 8 pages. A cell's page is two array reads away and
//! the cells around one block share a page or a few, so an update touches a few cache lines
//! where a hash table would touch one per cell.

/// Cells per page side, as a shift.
const PAGE: u32 = 3;
/// Pages per region side, as a shift.
const REGION: u32 = 3;
/// "No region" or "no page".
const NONE: u32 = u32::MAX;

/// 8 x 8 cells.
#[derive(Clone, Debug)]
struct Page {
    /// The cells' records, row by row; 0 is an empty cell.
    records: [u16; 64],
    /// Cells changed since the last [`CellGrid::take_dirty`], one bit per cell.
    dirty: u64,
    /// Non-empty cells: a page that has none, and no dirty bit, is given back.
    used: u16,
    /// Page column, to find its cells when iterating.
    px: u16,
    /// Page row.
    py: u16,
}

/// A sparse grid of 16-bit cell records, 0 meaning empty, with dirty marks.
#[derive(Clone, Debug)]
pub(super) struct CellGrid {
    /// Regions per row.
    regions_across: u32,
    /// Index into `regions` of each region, row by row, or [`NONE`].
    top: Vec<u32>,
    /// Index into `pages` of each page of a region, or [`NONE`]. Regions are never given back
    /// (256 bytes each, at most one per 64 x 64 cells).
    regions: Vec<[u32; 64]>,
    /// The pages, used or free.
    pages: Vec<Page>,
    /// Pages given back, reused first.
    free: Vec<u32>,
    /// Pages with a dirty bit, each once.
    dirty_pages: Vec<u32>,
}

impl CellGrid {
    /// An empty grid of `cols` x `rows` cells.
    pub(super) fn new(cols: u32, rows: u32) -> CellGrid {
        let side = PAGE + REGION;
        let (across, down) = (cols.div_ceil(1 << side), rows.div_ceil(1 << side));
        CellGrid {
            regions_across: across,
            top: vec![NONE; (across * down) as usize],
            regions: Vec::new(),
            pages: Vec::new(),
            free: Vec::new(),
            dirty_pages: Vec::new(),
        }
    }

    /// Where cell `(c, r)` lives: its region's slot in `top`, its page's slot in the region and
    /// its own slot in the page.
    fn locate(&self, c: u32, r: u32) -> (usize, usize, usize) {
        let side = PAGE + REGION;
        let region = ((r >> side) * self.regions_across + (c >> side)) as usize;
        let mask = (1 << REGION) - 1;
        let page = ((((r >> PAGE) & mask) << REGION) | ((c >> PAGE) & mask)) as usize;
        let cell = (((r & 7) << PAGE) | (c & 7)) as usize;
        (region, page, cell)
    }

    /// The record of cell `(c, r)`.
    pub(super) fn get(&self, c: u32, r: u32) -> u16 {
        let (region, page, cell) = self.locate(c, r);
        match self.top[region] {
            NONE => 0,
            g => match self.regions[g as usize][page] {
                NONE => 0,
                p => self.pages[p as usize].records[cell],
            },
        }
    }

    /// Sets cell `(c, r)` to `record`, marking it dirty if `track`; returns the old record, or
    /// `None` if it was already `record`.
    pub(super) fn set(&mut self, c: u32, r: u32, record: u16, track: bool) -> Option<u16> {
        let (region, page, cell) = self.locate(c, r);
        let mut g = self.top[region];
        if g == NONE {
            if record == 0 {
                return None;
            }
            g = self.regions.len() as u32;
            self.regions.push([NONE; 64]);
            self.top[region] = g;
        }
        let mut p = self.regions[g as usize][page];
        if p == NONE {
            if record == 0 {
                return None;
            }
            p = self.new_page(c >> PAGE, r >> PAGE);
            self.regions[g as usize][page] = p;
        }
        let pg = &mut self.pages[p as usize];
        let old = pg.records[cell];
        if old == record {
            return None;
        }
        pg.records[cell] = record;
        pg.used = pg.used + u16::from(record != 0) - u16::from(old != 0);
        if track {
            if pg.dirty == 0 {
                self.dirty_pages.push(p);
            }
            pg.dirty |= 1 << cell;
        } else if pg.used == 0 && pg.dirty == 0 {
            self.regions[g as usize][page] = NONE;
            self.free.push(p);
        }
        Some(old)
    }

    fn new_page(&mut self, px: u32, py: u32) -> u32 {
        let page = Page {
            records: [0; 64],
            dirty: 0,
            used: 0,
            px: px as u16,
            py: py as u16,
        };
        match self.free.pop() {
            Some(p) => {
                self.pages[p as usize] = page;
                p
            }
            None => {
                self.pages.push(page);
                self.pages.len() as u32 - 1
            }
        }
    }

    /// Appends the dirty cells to `out` and clears their marks; gives back pages left empty.
    pub(super) fn take_dirty(&mut self, out: &mut Vec<(u32, u32)>) {
        for p in std::mem::take(&mut self.dirty_pages) {
            let pg = &mut self.pages[p as usize];
            let (x0, y0) = (u32::from(pg.px) << PAGE, u32::from(pg.py) << PAGE);
            let mut bits = std::mem::take(&mut pg.dirty);
            while bits != 0 {
                let i = bits.trailing_zeros();
                bits &= bits - 1;
                out.push((x0 + (i & 7), y0 + (i >> PAGE)));
            }
            if pg.used == 0 {
                let (region, page, _) = self.locate(x0, y0);
                let g = self.top[region] as usize;
                self.regions[g][page] = NONE;
                self.free.push(p);
            }
        }
    }

    /// Calls `f(c, r, record)` for every non-empty cell, in no set order.
    pub(super) fn for_each(&self, mut f: impl FnMut(u32, u32, u16)) {
        for pg in self.pages.iter().filter(|pg| pg.used > 0) {
            let (x0, y0) = (u32::from(pg.px) << PAGE, u32::from(pg.py) << PAGE);
            for (i, &rec) in pg.records.iter().enumerate() {
                if rec != 0 {
                    f(x0 + (i as u32 & 7), y0 + (i as u32 >> PAGE), rec);
                }
            }
        }
    }
}
