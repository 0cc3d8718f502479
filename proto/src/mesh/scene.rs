//! The CPU side of the GPU buffers: node and triangle records in slot pools, kept in step with
//! the mirror and its fan mesh one split or merge at a time, with the pages that changed marked
//! for upload. No GPU API here: the wgpu client (`client/src/render/renderer.rs`) and the browser
//! page's WebAssembly (`web/wasm/`) both upload these records, and it is unit-tested without a
//! GPU.
//!
//! **Nodes.** Every node the mirror holds (active and interior) owns a slot in the node pool
//! while it is held. Its record, [`NODE_WORDS`] 32-bit words, carries what the geomorph needs
//! (paper 000, section 3.6; [`crate::mesh::morph`]): its position at rest, its parent's
//! slot, the box and static error its screen error is computed from, and when its split was
//! applied. A split allocates the children's slots; a merge frees them.
//!
//! **Triangles.** Every non-empty junction cell of the fan mesh owns a slot in the cell pool,
//! [`CELL_WORDS`] words: its two triangles as node slots ([`NONE`] for a missing triangle, which
//! the vertex shader drops). Cells are rewritten when the fan mesh reports them dirty.
//!
//! **Upload.** Pools only grow (doubling). Writes mark fixed-size pages dirty; the renderer
//! uploads runs of dirty pages, never the whole mesh per delta.

use crate::haar::error_value;
use crate::mesh::FanMesh;
use crate::mirror::{Change, Mirror};
use crate::terrain::TerrainGeometry;
use crate::tree::NodeId;
use rustc_hash::FxHashMap;

/// "No slot": the root's parent, a missing triangle, a free record.
pub const NONE: u32 = u32::MAX;
/// 32-bit words per node record: position, parent slot, box min, static error, box max, split
/// time (see `terrain.wgsl`).
pub const NODE_WORDS: usize = 12;
/// 32-bit words per cell record: two triangles of node slots.
pub const CELL_WORDS: usize = 6;
/// Records per upload page.
const PAGE_RECORDS: usize = 64;
/// The split time of a node split before anyone was watching: long enough ago that its
/// children have grown out fully.
const LONG_AGO: f32 = -1.0e30;

/// A pool of fixed-size records, handed out in blocks of a fixed number of consecutive
/// records, with a free list of blocks and dirty pages.
#[derive(Debug)]
pub struct Pool {
    /// 32-bit words per record.
    stride: usize,
    /// Records per block.
    unit: u32,
    /// The records, `capacity * stride` words: a shadow of the GPU buffer.
    words: Vec<u32>,
    /// Records ever handed out (slots below this are used or free).
    used: u32,
    /// First slots of released blocks, reused first.
    free: Vec<u32>,
    /// One flag per page: written since the last upload.
    dirty: Vec<bool>,
    /// The capacity changed since the last upload: the GPU buffer must be made anew.
    grown: bool,
}

impl Pool {
    /// An empty pool of records of `stride` words, handed out `unit` at a time.
    pub fn new(stride: usize, unit: u32) -> Pool {
        let mut p = Pool {
            stride,
            unit,
            words: Vec::new(),
            used: 0,
            free: Vec::new(),
            dirty: Vec::new(),
            grown: true,
        };
        p.reserve(PAGE_RECORDS);
        p
    }

    fn reserve(&mut self, records: usize) {
        let cap = self.capacity();
        if records <= cap {
            return;
        }
        let new_cap = records.next_power_of_two().max(PAGE_RECORDS);
        self.words.resize(new_cap * self.stride, NONE);
        self.dirty.resize(new_cap / PAGE_RECORDS, true);
        self.grown = true;
    }

    /// Records the buffer has room for.
    pub fn capacity(&self) -> usize {
        self.words.len() / self.stride
    }

    /// Records below the highest slot ever handed out: what a draw or a dispatch must cover.
    pub fn high_water(&self) -> usize {
        self.used as usize
    }

    /// The first slot of a free block of `unit` consecutive records.
    pub fn alloc(&mut self) -> u32 {
        if let Some(s) = self.free.pop() {
            return s;
        }
        let s = self.used;
        self.used += self.unit;
        self.reserve(self.used as usize);
        s
    }

    /// Gives back the block starting at `slot`; its records are cleared to [`NONE`].
    pub fn release(&mut self, slot: u32) {
        let at = slot as usize * self.stride;
        self.words[at..at + self.stride * self.unit as usize].fill(NONE);
        for s in slot..slot + self.unit {
            self.dirty[s as usize / PAGE_RECORDS] = true;
        }
        self.free.push(slot);
    }

    /// Writes the record at `slot`.
    pub fn write(&mut self, slot: u32, record: &[u32]) {
        let at = slot as usize * self.stride;
        if self.words[at..at + self.stride] != *record {
            self.words[at..at + self.stride].copy_from_slice(record);
            self.dirty[slot as usize / PAGE_RECORDS] = true;
        }
    }

    /// The record at `slot`.
    pub fn record(&self, slot: u32) -> &[u32] {
        let at = slot as usize * self.stride;
        &self.words[at..at + self.stride]
    }

    /// All records, for a full upload.
    pub fn words(&self) -> &[u32] {
        &self.words
    }

    /// Whether the capacity changed since the last [`Pool::take_dirty`].
    pub fn grown(&self) -> bool {
        self.grown
    }

    /// The dirty ranges of words, as `(first word, word count)`, adjacent pages merged; clears
    /// the dirty marks.
    pub fn take_dirty(&mut self) -> Vec<(usize, usize)> {
        let page = PAGE_RECORDS * self.stride;
        let mut runs: Vec<(usize, usize)> = Vec::new();
        for (i, d) in self.dirty.iter_mut().enumerate() {
            if !std::mem::take(d) {
                continue;
            }
            match runs.last_mut() {
                Some((start, len)) if *start + *len == i * page => *len += page,
                _ => runs.push((i * page, page)),
            }
        }
        self.grown = false;
        runs
    }
}

/// The node and triangle records of one mirror.
#[derive(Debug)]
pub struct Scene {
    /// Slot of the root, while it is held.
    root_slot: Option<u32>,
    /// First slot of each interior node's block of children (child `k` at `k`), by the node's
    /// dense index: children are always held together, so one entry stands for four.
    child_block: FxHashMap<u32, u32>,
    /// Nodes with a slot, kept so that counting needs no walk.
    held: usize,
    /// Node records.
    pub nodes: Pool,
    /// Slot of each non-empty junction cell.
    cell_slot: FxHashMap<(u32, u32), u32>,
    /// Cell records.
    pub cells: Pool,
    /// Nodes whose records [`Scene::apply`] rewrites, each with whether it split in that call:
    /// a buffer kept between calls.
    touched: FxHashMap<NodeId, bool>,
    /// The fan mesh's dirty cells: a buffer kept between calls.
    dirty: Vec<(u32, u32)>,
}

impl Scene {
    /// The records of everything `mirror` holds and every cell of `mesh`, which from now on
    /// marks the cells that change (and whose marks are cleared). Splits count as long done:
    /// nothing is still growing.
    pub fn build(geom: &TerrainGeometry, mirror: &Mirror, mesh: &mut FanMesh) -> Scene {
        let mut s = Scene {
            root_slot: None,
            child_block: FxHashMap::default(),
            held: 0,
            nodes: Pool::new(NODE_WORDS, 4),
            cell_slot: FxHashMap::default(),
            cells: Pool::new(CELL_WORDS, 1),
            touched: FxHashMap::default(),
            dirty: Vec::new(),
        };
        let mut held: Vec<u64> = mirror.held().map(|(i, _)| i).collect();
        // Parents before children (dense indices go level by level): a node's slot is given
        // when its parent is visited, its children's block when it is.
        held.sort_unstable();
        let shape = &geom.shape;
        let root = shape.index(NodeId::ROOT);
        if held.first() == Some(&root) {
            s.root_slot = Some(s.nodes.alloc());
            s.held = 1;
        }
        for &i in &held {
            if let Some(n) = shape.node(i) {
                s.place_children(geom, mirror, n);
            }
        }
        for &i in &held {
            if let Some(n) = geom.shape.node(i) {
                s.write_node(geom, mirror, n, LONG_AGO);
            }
        }
        mesh.track_dirty(true);
        mesh.take_dirty(&mut s.dirty);
        for cell in mesh.cells() {
            s.write_cell(geom, mesh, cell);
        }
        s
    }

    /// Brings the records up to date after the mirror applied `changes` (in order) and `mesh`
    /// followed; `now` is the split time given to new splits, seconds on the renderer's clock.
    pub fn apply(
        &mut self,
        geom: &TerrainGeometry,
        mirror: &Mirror,
        mesh: &mut FanMesh,
        changes: &[Change],
        now: f32,
    ) {
        let shape = &geom.shape;
        let mut touched = std::mem::take(&mut self.touched);
        for &c in changes {
            match c {
                Change::Merge(m) => {
                    if let Some(b) = self.child_block.remove(&(shape.index(m) as u32)) {
                        self.nodes.release(b);
                        self.held -= shape.children(m).count();
                    }
                    for (_, child) in shape.children(m) {
                        touched.remove(&child);
                    }
                    touched.entry(m).or_insert(false);
                }
                Change::Split(n) => {
                    self.place_children(geom, mirror, n);
                    for (_, child) in shape.children(n) {
                        touched.entry(child).or_insert(false);
                    }
                    touched.insert(n, true);
                }
            }
        }
        // Every slot is placed by now, so records can be written in any order.
        for (&n, &split_now) in &touched {
            let Some(slot) = self.slot_of(geom, n) else {
                continue;
            };
            let t = if split_now {
                now
            } else if self.nodes.record(slot)[11] == NONE {
                LONG_AGO
            } else {
                f32::from_bits(self.nodes.record(slot)[11])
            };
            self.write_node(geom, mirror, n, t);
        }
        touched.clear();
        self.touched = touched;
        let mut dirty = std::mem::take(&mut self.dirty);
        mesh.take_dirty(&mut dirty);
        for &cell in &dirty {
            self.write_cell(geom, mesh, cell);
        }
        self.dirty = dirty;
    }

    /// Gives `n`'s held children one block of four consecutive slots (child `k` at `k`), so
    /// that a split or merge writes one place of the node pool, unless they have slots.
    fn place_children(&mut self, geom: &TerrainGeometry, mirror: &Mirror, n: NodeId) {
        let shape = &geom.shape;
        let key = shape.index(n) as u32;
        if self.child_block.contains_key(&key) {
            return;
        }
        // The mirror holds a node's children all together, or none of them.
        let held = shape
            .children(n)
            .filter(|&(_, c)| mirror.node(geom, c).is_some())
            .count();
        if held > 0 {
            self.child_block.insert(key, self.nodes.alloc());
            self.held += held;
        }
    }

    /// Nodes with a slot (every node the mirror holds).
    pub fn held_count(&self) -> usize {
        self.held
    }

    fn write_node(&mut self, geom: &TerrainGeometry, mirror: &Mirror, n: NodeId, t_split: f32) {
        let (Some(slot), Some(d)) = (self.slot_of(geom, n), mirror.node(geom, n)) else {
            return;
        };
        let parent = n
            .parent()
            .and_then(|p| self.slot_of(geom, p))
            .unwrap_or(NONE);
        let p = geom.world_pos(n, d.z);
        let b = geom.node_box(n, d.z, d.err_code);
        let f = |v: f32| v.to_bits();
        let rec = [
            f(p.x),
            f(p.y),
            f(p.z),
            parent,
            f(b.min.x),
            f(b.min.y),
            f(b.min.z),
            f(error_value(d.err_code)),
            f(b.max.x),
            f(b.max.y),
            f(b.max.z),
            f(t_split),
        ];
        self.nodes.write(slot, &rec);
    }

    fn write_cell(&mut self, geom: &TerrainGeometry, mesh: &FanMesh, cell: (u32, u32)) {
        let tris = mesh.cell(cell);
        if tris.iter().all(Option::is_none) {
            if let Some(slot) = self.cell_slot.remove(&cell) {
                self.cells.release(slot);
            }
            return;
        }
        let slot = match self.cell_slot.get(&cell) {
            Some(&s) => s,
            None => {
                let s = self.cells.alloc();
                self.cell_slot.insert(cell, s);
                s
            }
        };
        let mut rec = [NONE; CELL_WORDS];
        for (k, t) in tris.iter().enumerate() {
            let Some(t) = t else { continue };
            let slots = t.0.map(|n| self.slot_of(geom, n));
            // Every vertex of a triangle of the mesh is held; if not, drop the triangle whole
            // rather than draw it with a missing corner.
            debug_assert!(
                slots.iter().all(Option::is_some),
                "cell {cell:?}: vertex not held"
            );
            if let [Some(a), Some(b), Some(c)] = slots {
                rec[k * 3..k * 3 + 3].copy_from_slice(&[a, b, c]);
            }
        }
        self.cells.write(slot, &rec);
    }

    /// The slot of a held node.
    pub fn slot_of(&self, geom: &TerrainGeometry, n: NodeId) -> Option<u32> {
        match n.parent() {
            None => self.root_slot,
            Some(p) => {
                let k = (n.x & 1) | (n.y & 1) << 1;
                let held = geom.shape.contains(n);
                let block = self.child_block.get(&(geom.shape.index(p) as u32));
                block.filter(|_| held).map(|&b| b + k)
            }
        }
    }
}

#[cfg(test)]
mod tests;
