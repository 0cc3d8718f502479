//! A sparse 2D grid of small records: pages of 8 x 8 records, found through a dense table of
//! regions of 8 x 8 pages. A record is two array reads away, with no hashing, and records close
//! in the grid share a page and often a cache line, where a hash table scatters them. The
//! client's fan mesh keeps its cells in one, and its mirror its nodes' heights (one per level).

/// Records per page side, as a shift.
const PAGE: u32 = 3;
/// Pages per region side, as a shift.
const REGION: u32 = 3;
/// "No region" or "no page".
const NONE: u32 = u32::MAX;

/// 8 x 8 records.
#[derive(Clone, Debug)]
pub(crate) struct Page<T> {
    /// The records, row by row.
    pub(crate) records: [T; 64],
    /// Which records are present, one bit each.
    pub(crate) present: u64,
    /// One bit per record for the owner's use (the fan mesh marks changed cells); a page with
    /// none present and none marked is given back.
    pub(crate) marks: u64,
    /// Page column, to find its records' positions when iterating.
    px: u16,
    /// Page row.
    py: u16,
}

impl<T> Page<T> {
    /// Grid position of record `i` of this page.
    pub(crate) fn position(&self, i: u32) -> (u32, u32) {
        let (x0, y0) = (u32::from(self.px) << PAGE, u32::from(self.py) << PAGE);
        (x0 + (i & 7), y0 + (i >> PAGE))
    }
}

/// A sparse grid of `T` records.
#[derive(Clone, Debug)]
pub(crate) struct Paged<T> {
    /// Regions per row.
    regions_across: u32,
    /// Index into `regions` of each region, row by row, or [`NONE`].
    top: Vec<u32>,
    /// Index into `pages` of each page of a region, or [`NONE`]. Regions are never given back
    /// (256 bytes each, at most one per 64 x 64 records).
    regions: Vec<[u32; 64]>,
    /// The pages, used or free.
    pages: Vec<Page<T>>,
    /// Pages given back, reused first.
    free: Vec<u32>,
}

/// Where a record lives: its page's index in [`Paged`] and its index in the page.
pub(crate) type Slot = (u32, u32);

impl<T: Copy + Default> Paged<T> {
    /// An empty grid of `cols` x `rows` records.
    pub(crate) fn new(cols: u32, rows: u32) -> Paged<T> {
        let side = PAGE + REGION;
        let (across, down) = (cols.div_ceil(1 << side), rows.div_ceil(1 << side));
        Paged {
            regions_across: across,
            top: vec![NONE; (across * down) as usize],
            regions: Vec::new(),
            pages: Vec::new(),
            free: Vec::new(),
        }
    }

    /// Where record `(c, r)` lives: its region's place in `top`, its page's place in the
    /// region, its own place in the page.
    fn locate(&self, c: u32, r: u32) -> (usize, usize, u32) {
        let side = PAGE + REGION;
        let region = ((r >> side) * self.regions_across + (c >> side)) as usize;
        let mask = (1 << REGION) - 1;
        let page = ((((r >> PAGE) & mask) << REGION) | ((c >> PAGE) & mask)) as usize;
        (region, page, ((r & 7) << PAGE) | (c & 7))
    }

    /// The slot of `(c, r)` if its page exists (the record may be absent).
    #[inline]
    pub(crate) fn slot(&self, c: u32, r: u32) -> Option<Slot> {
        let (region, page, i) = self.locate(c, r);
        let p = self.page_at(region, page);
        (p != NONE).then_some((p, i))
    }

    /// The index of the page at `page` of region `region`, or [`NONE`].
    #[inline]
    fn page_at(&self, region: usize, page: usize) -> u32 {
        match self.top[region] {
            NONE => NONE,
            g => self.regions[g as usize][page],
        }
    }

    /// The slot of `(c, r)`, making its page if needed. Inlined for the page that exists (the
    /// fan mesh calls it per cell), the page made out of line.
    #[inline]
    pub(crate) fn slot_or_make(&mut self, c: u32, r: u32) -> Slot {
        let (region, page, i) = self.locate(c, r);
        match self.page_at(region, page) {
            NONE => (self.make_page(c, r, region, page), i),
            p => (p, i),
        }
    }

    /// Makes the absent page of `(c, r)`, at `page` of region `region`, and the region if
    /// needed; returns its index.
    #[cold]
    #[inline(never)]
    fn make_page(&mut self, c: u32, r: u32, region: usize, page: usize) -> u32 {
        let mut g = self.top[region];
        if g == NONE {
            g = self.regions.len() as u32;
            self.regions.push([NONE; 64]);
            self.top[region] = g;
        }
        let new = Page {
            records: [T::default(); 64],
            present: 0,
            marks: 0,
            px: (c >> PAGE) as u16,
            py: (r >> PAGE) as u16,
        };
        let p = match self.free.pop() {
            Some(p) => {
                self.pages[p as usize] = new;
                p
            }
            None => {
                self.pages.push(new);
                self.pages.len() as u32 - 1
            }
        };
        self.regions[g as usize][page] = p;
        p
    }

    /// The record of `(c, r)`, if present.
    #[inline]
    pub(crate) fn get(&self, c: u32, r: u32) -> Option<&T> {
        let (p, i) = self.slot(c, r)?;
        let pg = &self.pages[p as usize];
        (pg.present >> i & 1 != 0).then(|| &pg.records[i as usize])
    }

    /// The record of `(c, r)`, if present, for changing in place.
    pub(crate) fn get_mut(&mut self, c: u32, r: u32) -> Option<&mut T> {
        let (p, i) = self.slot(c, r)?;
        let pg = &mut self.pages[p as usize];
        (pg.present >> i & 1 != 0).then(|| &mut pg.records[i as usize])
    }

    /// Sets the record of `(c, r)`.
    pub(crate) fn insert(&mut self, c: u32, r: u32, record: T) {
        let (p, i) = self.slot_or_make(c, r);
        let pg = &mut self.pages[p as usize];
        pg.records[i as usize] = record;
        pg.present |= 1 << i;
    }

    /// Removes the record of `(c, r)`; gives its page back if that leaves it empty and unmarked.
    pub(crate) fn remove(&mut self, c: u32, r: u32) {
        if let Some((p, i)) = self.slot(c, r) {
            self.pages[p as usize].present &= !(1 << i);
            self.release_if_empty(p);
        }
    }

    /// The page at index `p`, for changing in place (then call [`Paged::release_if_empty`]).
    pub(crate) fn page_mut(&mut self, p: u32) -> &mut Page<T> {
        &mut self.pages[p as usize]
    }

    /// Gives page `p` back if it holds no present or marked record.
    pub(crate) fn release_if_empty(&mut self, p: u32) {
        let pg = &self.pages[p as usize];
        if pg.present != 0 || pg.marks != 0 {
            return;
        }
        let (x, y) = pg.position(0);
        let (region, page, _) = self.locate(x, y);
        let g = self.top[region] as usize;
        self.regions[g][page] = NONE;
        self.free.push(p);
    }

    /// Calls `f(c, r, record)` for every present record, in no set order.
    pub(crate) fn for_each(&self, mut f: impl FnMut(u32, u32, &T)) {
        for pg in &self.pages {
            let mut bits = pg.present;
            while bits != 0 {
                let i = bits.trailing_zeros();
                bits &= bits - 1;
                let (c, r) = pg.position(i);
                f(c, r, &pg.records[i as usize]);
            }
        }
    }
}
