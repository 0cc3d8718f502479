//! Building the vertex quadtree from a DEM (paper 000, sections 3.1-3.2): integer heights, the
//! Haar pyramid, subtree z-bounds and saturated static errors.
//!
//! One bottom-up pass per level over the children of each node:
//! - the node's height is the integer Haar low-pass of its children's ([`relief_proto::haar`]);
//! - its z-bounds are the min and max of its children's;
//! - its deviation is how far any sample of the subtree lies from its height,
//!   `max(zmax - z, z - zmin)`; its static error is that deviation saturated with each child's
//!   error *plus the child's offset* `|z_child - z|`, so that errors never decrease going up the
//!   tree (DESIGN.md section 3, as paper 002 does through its dependencies) and, more strongly,
//!   the box `z +- error` of a node holds its children's boxes. The error bounds the subtree's
//!   heights, which is what lets one byte give both the error and the z extent of a node's box;
//!   nested boxes make the screen error monotone, so threshold cuts are consistent;
//! - nodes on the grid's border also count their *border offset*: a border node's vertex sits half
//!   a block inside the west or north edge, and a clipped block's nominal centre up to half a
//!   block beyond the east or south edge (see `relief_proto::tree`). Counting that horizontal
//!   distance as error makes the mesh's outline refine like any other detail, so it never visibly
//!   recedes from or reaches past the grid's edge.
//!
//! The build streams. Rows of leaf heights go in a band at a time ([`TreeBuilder::push_rows`]);
//! a level's rows, as soon as they pair up, make the next row of the level above and leave as
//! node records in the store's layout ([`RecordSink`]), bottom level first. Each level holds at
//! most a band's rows and one more, so memory is linear in the grid's width, whatever its
//! height; the pairs of a band are built on every core, and the records are the same whatever
//! the number of threads or the band's size.

use super::StoreError;
use super::layout::{self, Z_LIMIT, quantise};
use relief_proto::haar::{self, Presence, error_code, error_value};
use relief_proto::terrain::TerrainGeometry;
use relief_proto::tree::NodeId;

/// Where the node records go: each level's records in the store's order ([`layout`]), a run of
/// whole quads at a time, the runs of one level in order; levels interleave, the root last.
pub trait RecordSink {
    /// The next records of `level` (for level 0, the root's one record).
    fn records(&mut self, level: u8, records: &[u32]) -> Result<(), StoreError>;
}

/// The rows of one level not yet paired, from row `first` on.
#[derive(Default)]
struct Rows {
    /// The first row held (even, until the level's last row has gone).
    first: u32,
    /// Heights, z quanta.
    z: Vec<i32>,
    /// The subtrees' lowest samples (empty at the leaf level, where they are `z`).
    zmin: Vec<i32>,
    /// The subtrees' highest samples (empty at the leaf level).
    zmax: Vec<i32>,
    /// Static-error codes (empty at the leaf level, where they are 0).
    err: Vec<u8>,
}

/// The tree of one grid, built from its rows as they come.
pub struct TreeBuilder<'g> {
    geom: &'g TerrainGeometry,
    /// One over the z quantum.
    inv: f32,
    /// Each level's unpaired rows, by level.
    levels: Vec<Rows>,
}

impl<'g> TreeBuilder<'g> {
    /// A builder of `geom`'s tree, no row in yet.
    pub fn new(geom: &'g TerrainGeometry) -> TreeBuilder<'g> {
        let depth = geom.shape.depth() as usize;
        TreeBuilder {
            geom,
            inv: 1.0 / geom.z_quantum,
            levels: (0..=depth).map(|_| Rows::default()).collect(),
        }
    }

    /// The leaf rows taken so far.
    pub fn rows_in(&self) -> u32 {
        let leaves = &self.levels[self.geom.shape.depth() as usize];
        leaves.first + (leaves.z.len() / self.geom.shape.width() as usize) as u32
    }

    /// Takes the next whole rows of heights in metres (voids filled) and sends `sink` every
    /// record they complete.
    pub fn push_rows(
        &mut self,
        heights: &[f32],
        sink: &mut impl RecordSink,
    ) -> Result<(), StoreError> {
        use rayon::prelude::*;
        let shape = &self.geom.shape;
        let w = shape.width() as usize;
        let rows = heights.len() / w;
        if !heights.len().is_multiple_of(w)
            || self.rows_in() as usize + rows > shape.height() as usize
        {
            return Err(StoreError::Input(format!(
                "{} heights are not whole rows of {w} within the grid's {} rows",
                heights.len(),
                shape.height()
            )));
        }
        let inv = self.inv;
        let leaves = &mut self.levels[shape.depth() as usize];
        let at = leaves.z.len();
        leaves.z.resize(at + heights.len(), 0);
        leaves.z[at..]
            .par_iter_mut()
            .zip(heights.par_iter())
            .with_min_len(1 << 14)
            .for_each(|(dst, &h)| *dst = quantise(h, inv));
        self.climb(sink)
    }

    /// Checks that every row came in (and so every record went out).
    pub fn finish(self) -> Result<(), StoreError> {
        let h = self.geom.shape.height();
        if self.rows_in() != h || self.levels.iter().any(|l| !l.z.is_empty()) {
            return Err(StoreError::Input(format!(
                "the tree took {} of the grid's {h} rows",
                self.rows_in()
            )));
        }
        Ok(())
    }

    /// Pairs the rows of every level, from the leaves up, as far as they go.
    fn climb(&mut self, sink: &mut impl RecordSink) -> Result<(), StoreError> {
        use rayon::prelude::*;
        let geom = self.geom;
        let shape = &geom.shape;
        for level in (0..=shape.depth()).rev() {
            let (w, h) = shape.level_dims(level);
            let wu = w as usize;
            let rows = &self.levels[level as usize];
            let held = rows.z.len() / wu;
            if held == 0 {
                break;
            }
            let leaf = level == shape.depth();
            let code = |i: usize| if leaf { 0 } else { rows.err[i] };
            let rec = |i: usize| -> Result<u32, StoreError> {
                let z = rows.z[i];
                if z.abs() > Z_LIMIT {
                    return Err(StoreError::Corrupt(format!(
                        "a height of {z} z quanta does not fit the store's 24-bit heights; \
                         build with a larger --z-quantum"
                    )));
                }
                Ok(layout::record(z, code(i)))
            };
            if level == 0 {
                sink.records(0, &[rec(0)?])?;
                self.levels[0] = Rows::default();
                self.levels[0].first = 1;
                break;
            }
            // Whole pairs, and the last row alone once it is in.
            let all_in = rows.first as usize + held == h as usize;
            let pairs = if all_in { held.div_ceil(2) } else { held / 2 };
            if pairs == 0 {
                break;
            }
            let (pw, _) = shape.level_dims(level - 1);
            let pwu = pw as usize;
            // This level's records, a run of quads per pair of rows.
            let mut run = vec![0u32; pairs * 4 * pwu];
            run.par_chunks_mut(4 * pwu)
                .enumerate()
                .try_for_each(|(p, quads)| {
                    for dy in 0..2 {
                        let y = 2 * p + dy;
                        if y >= held {
                            continue;
                        }
                        for x in 0..wu {
                            quads[4 * (x >> 1) + (x & 1) + 2 * dy] = rec(y * wu + x)?;
                        }
                    }
                    Ok::<(), StoreError>(())
                })?;
            sink.records(level, &run)?;
            drop(run);
            // The level above's rows, one per pair.
            let py0 = rows.first / 2;
            let mut up = Rows {
                first: 0,
                z: vec![0; pairs * pwu],
                zmin: vec![0; pairs * pwu],
                zmax: vec![0; pairs * pwu],
                err: vec![0; pairs * pwu],
            };
            up.z.par_chunks_mut(pwu)
                .zip(up.zmin.par_chunks_mut(pwu))
                .zip(up.zmax.par_chunks_mut(pwu))
                .zip(up.err.par_chunks_mut(pwu))
                .enumerate()
                .for_each(|(p, (((z, zmin), zmax), err))| {
                    let from = 2 * p * wu;
                    let below = Below {
                        z: &rows.z[from..],
                        zmin: rows.zmin.get(from..).unwrap_or(&[]),
                        zmax: rows.zmax.get(from..).unwrap_or(&[]),
                        err: rows.err.get(from..).unwrap_or(&[]),
                    };
                    build_row(
                        geom,
                        level - 1,
                        py0 + p as u32,
                        &below,
                        [z, zmin, zmax],
                        err,
                    );
                });
            // The paired rows leave; an odd one waits for its partner.
            let used_rows = (2 * pairs).min(held);
            let used = used_rows * wu;
            let rows = &mut self.levels[level as usize];
            rows.z.drain(..used);
            for v in [&mut rows.zmin, &mut rows.zmax] {
                v.drain(..used.min(v.len()));
            }
            rows.err.drain(..used.min(rows.err.len()));
            rows.first += used_rows as u32;
            let above = &mut self.levels[level as usize - 1];
            above.z.extend_from_slice(&up.z);
            above.zmin.extend_from_slice(&up.zmin);
            above.zmax.extend_from_slice(&up.zmax);
            above.err.extend_from_slice(&up.err);
        }
        Ok(())
    }
}

/// The two rows of the level below that a row of nodes is built from (or the last row alone,
/// when it has no partner), from the first one's first node.
struct Below<'a> {
    z: &'a [i32],
    zmin: &'a [i32],
    zmax: &'a [i32],
    err: &'a [u8],
}

/// Row `y` of level `level`: its nodes' heights, bounds and error codes, from `below`, which
/// starts at the first node of row `2 y` of the level below.
fn build_row(
    geom: &TerrainGeometry,
    level: u8,
    y: u32,
    below: &Below<'_>,
    [zs, zmins, zmaxs]: [&mut [i32]; 3],
    errs: &mut [u8],
) {
    let shape = &geom.shape;
    let quantum = geom.z_quantum;
    let (w, h) = shape.level_dims(level);
    let (cw, ch) = shape.level_dims(level + 1);
    let child_is_leaf = level + 1 == shape.depth();
    let south = 2 * y + 1 < ch;
    for x in 0..w {
        let east = 2 * x + 1 < cw;
        let p = Presence { east, south };
        let c0 = (2 * x) as usize;
        let c2 = c0 + cw as usize;
        let idx = [c0, c0 + east as usize, if south { c2 } else { c0 }, {
            if south {
                c2 + east as usize
            } else {
                c0 + east as usize
            }
        }];
        let quad = idx.map(|i| below.z[i]);
        let (z, _) = haar::forward(quad, p);
        let (lo, hi, nested) = if child_is_leaf {
            let lo = *quad.iter().min().unwrap_or(&z);
            let hi = *quad.iter().max().unwrap_or(&z);
            (lo, hi, 0.0f32)
        } else {
            let lo = idx.iter().map(|&i| below.zmin[i]).min().unwrap_or(z);
            let hi = idx.iter().map(|&i| below.zmax[i]).max().unwrap_or(z);
            let nested = idx
                .iter()
                .map(|&i| {
                    error_value(below.err[i]) + (below.z[i] - z).unsigned_abs() as f32 * quantum
                })
                .fold(0.0f32, f32::max);
            (lo, hi, nested)
        };
        let me = x as usize;
        let deviation = (hi as i64 - z as i64).max(z as i64 - lo as i64) as f32 * quantum;
        zs[me] = z;
        zmins[me] = lo;
        zmaxs[me] = hi;
        let on_border = x == 0 || y == 0 || x + 1 == w || y + 1 == h;
        let border = if on_border {
            border_offset(geom, NodeId { level, x, y })
        } else {
            0.0
        };
        errs[me] = error_code(deviation.max(border).max(nested));
    }
}

/// How far, in metres, `node`'s vertex lies off the grid edges its block touches: beyond the
/// east or south edge (a clipped block's nominal centre), or inside the west or north edge (half
/// a block in). Either moves the mesh's outline away from the grid's edge by that much.
fn border_offset(geom: &TerrainGeometry, node: NodeId) -> f32 {
    let shape = &geom.shape;
    let (c0, r0, c1, r1) = shape.block(node);
    let (c, r) = shape.grid_pos(node);
    let (dx, dy) = (geom.frame.dx, geom.frame.dy);
    let mut off: f32 = 0.0;
    if c0 == 0 {
        off = off.max(c * dx);
    }
    if r0 == 0 {
        off = off.max(r * dy);
    }
    if c1 == shape.width() - 1 {
        off = off.max((c - c1 as f32).abs() * dx);
    }
    if r1 == shape.height() - 1 {
        off = off.max((r - r1 as f32).abs() * dy);
    }
    off
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::store::layout::{QuadLayout, rec_code, rec_z};

    /// Collects each level's records in order.
    struct Levels(Vec<Vec<u32>>);

    impl RecordSink for Levels {
        fn records(&mut self, level: u8, records: &[u32]) -> Result<(), StoreError> {
            self.0[level as usize].extend_from_slice(records);
            Ok(())
        }
    }

    /// The node records of `heights`' tree in the store's layout, the rows pushed `band` at a
    /// time.
    pub(crate) fn records(geom: &TerrainGeometry, heights: &[f32], band: usize) -> Vec<u32> {
        let shape = &geom.shape;
        let mut sink = Levels(vec![Vec::new(); shape.depth() as usize + 1]);
        let mut b = TreeBuilder::new(geom);
        for rows in heights.chunks(band * shape.width() as usize) {
            b.push_rows(rows, &mut sink).unwrap();
        }
        b.finish().unwrap();
        let lay = QuadLayout::new(shape);
        let out: Vec<u32> = sink.0.concat();
        assert_eq!(out.len() as u64, lay.len());
        for (l, recs) in sink.0.iter().enumerate() {
            assert_eq!(
                lay.level_start(l as u8),
                sink.0[..l].iter().map(|v| v.len() as u64).sum::<u64>()
            );
            assert!(!recs.is_empty());
        }
        out
    }

    fn ramp(w: u32, h: u32) -> Vec<f32> {
        (0..w * h)
            .map(|i| ((i % w) as f32 * 3.0 + (i / w) as f32 * 7.0).sin() * 40.0 + 100.0)
            .collect()
    }

    #[test]
    fn errors_are_monotone_and_bound_the_subtree() {
        for (w, h) in [(17, 9), (32, 32), (5, 40)] {
            let geom = TerrainGeometry::new(w, h, 1.0, 1.0, 0.25).unwrap();
            let shape = &geom.shape;
            let recs = records(&geom, &ramp(w, h), 4);
            let lay = QuadLayout::new(shape);
            let z = |n: NodeId| rec_z(recs[lay.slot(n)]);
            let e = |n: NodeId| rec_code(recs[lay.slot(n)]);
            for i in 0..shape.level_offset(shape.depth()) {
                let node = shape.node(i).unwrap();
                let err = error_value(e(node));
                let (c0, r0, c1, r1) = shape.block(node);
                for r in r0..=r1 {
                    for c in c0..=c1 {
                        let leaf = z(shape.leaf(c, r));
                        assert!(((leaf - z(node)) as f32 * 0.25).abs() <= err, "{node:?}");
                    }
                }
                for (_, c) in shape.children(node) {
                    if c.level < shape.depth() {
                        assert!(e(c) <= e(node));
                        // The child's box lies inside the parent's.
                        let dz = (z(c) - z(node)) as f32 * 0.25;
                        assert!(
                            dz.abs() + error_value(e(c)) <= err,
                            "{c:?} escapes {node:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn details_rebuild_children_exactly() {
        let geom = TerrainGeometry::new(13, 6, 1.0, 1.0, 0.1).unwrap();
        let shape = &geom.shape;
        let recs = records(&geom, &ramp(13, 6), 1);
        let lay = QuadLayout::new(shape);
        let z = |n: NodeId| rec_z(recs[lay.slot(n)]);
        for i in 0..shape.level_offset(shape.depth()) {
            let node = shape.node(i).unwrap();
            let mut quad = [0i32; 4];
            let mut present = [false; 4];
            for (k, c) in shape.children(node) {
                quad[k] = z(c);
                present[k] = true;
            }
            let p = Presence {
                east: present[1],
                south: present[2],
            };
            let (parent, d) = haar::forward(quad, p);
            assert_eq!(parent, z(node));
            let back = haar::inverse(parent, d);
            for (k, c) in shape.children(node) {
                assert_eq!(back[k], z(c), "{c:?}");
            }
        }
    }

    #[test]
    fn the_records_do_not_depend_on_the_band_or_the_threads() {
        for (w, h) in [(2, 2), (33, 17), (9, 64)] {
            let geom = TerrainGeometry::new(w, h, 2.0, 3.0, 0.5).unwrap();
            let heights = ramp(w, h);
            let one = records(&geom, &heights, 1);
            for band in [2, 3, 7, h as usize] {
                assert_eq!(
                    records(&geom, &heights, band),
                    one,
                    "{w} x {h}, band {band}"
                );
            }
            let single = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .unwrap();
            assert_eq!(single.install(|| records(&geom, &heights, 5)), one);
        }
    }

    #[test]
    fn rows_past_the_grid_and_missing_rows_are_errors() {
        let geom = TerrainGeometry::new(4, 3, 1.0, 1.0, 1.0).unwrap();
        let mut sink = Levels(vec![Vec::new(); geom.shape.depth() as usize + 1]);
        let mut b = TreeBuilder::new(&geom);
        assert!(b.push_rows(&[0.0; 5], &mut sink).is_err());
        b.push_rows(&[0.0; 8], &mut sink).unwrap();
        assert!(b.push_rows(&[0.0; 8], &mut sink).is_err());
        assert!(
            b.finish()
                .unwrap_err()
                .to_string()
                .contains("2 of the grid's 3 rows")
        );
    }
}
