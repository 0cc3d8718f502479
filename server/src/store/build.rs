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
//! The pass touches each node once, a level at a time from the leaves up, each level's rows on
//! every core.

use relief_proto::haar::{self, Presence, error_code, error_value};
use relief_proto::terrain::TerrainGeometry;
use relief_proto::tree::{NodeId, TreeShape};

/// The tree's per-node arrays, indexed by dense node index ([`TreeShape::index`]).
#[derive(Debug, Default)]
pub struct TreeArrays {
    /// Height of every node, in z quanta.
    pub z: Vec<i32>,
    /// Static-error code of every inner node (leaves have error 0 and are not stored).
    pub err: Vec<u8>,
    /// Lowest sample height in each inner node's subtree, in z quanta.
    pub zmin: Vec<i32>,
    /// Highest sample height in each inner node's subtree, in z quanta.
    pub zmax: Vec<i32>,
}

/// Builds the arrays from row-major heights in metres (voids already filled).
///
/// `progress` is called with the fraction done after each level.
pub fn build_arrays(
    geom: &TerrainGeometry,
    heights: &[f32],
    mut progress: impl FnMut(f64),
) -> TreeArrays {
    let shape = &geom.shape;
    let quantum = geom.z_quantum;
    let n = shape.node_count() as usize;
    let inner = shape.level_offset(shape.depth()) as usize;
    let mut t = TreeArrays {
        z: vec![0; n],
        err: vec![0; inner],
        zmin: vec![0; inner],
        zmax: vec![0; inner],
    };
    let leaf0 = inner;
    // Round half away from zero, without a libm call per sample.
    let inv = 1.0 / quantum;
    {
        use rayon::prelude::*;
        t.z[leaf0..]
            .par_iter_mut()
            .zip(heights.par_iter())
            .with_min_len(1 << 16)
            .for_each(|(dst, &h)| {
                let v = h * inv;
                *dst = (v + 0.5f32.copysign(v)) as i32;
            });
    }
    let total = n as f64;
    let mut done = (n - inner) as f64;
    progress(done / total);
    for level in (0..shape.depth()).rev() {
        build_level(geom, level, &mut t);
        let (w, h) = shape.level_dims(level);
        done += w as f64 * h as f64;
        progress(done / total);
    }
    t
}

/// Level `level`'s nodes from their children's, one row of nodes per task on every core (rayon's
/// pool). A row reads only the level below and writes only its own nodes, so the arrays are the
/// same whatever the number of threads.
fn build_level(geom: &TerrainGeometry, level: u8, t: &mut TreeArrays) {
    use rayon::prelude::*;
    let shape = &geom.shape;
    let (w, h) = shape.level_dims(level);
    let base = shape.level_offset(level) as usize;
    let cbase = shape.level_offset(level + 1) as usize;
    let n = w as usize * h as usize;
    // The level is the slice before the next level's; the arrays of inner nodes end where the
    // leaves begin.
    let (z_up, z_below) = t.z.split_at_mut(cbase);
    let inner = cbase.min(t.err.len());
    let (zmin_up, zmin_below) = t.zmin.split_at_mut(inner);
    let (zmax_up, zmax_below) = t.zmax.split_at_mut(inner);
    let (err_up, err_below) = t.err.split_at_mut(inner);
    let below = Below {
        z: z_below,
        zmin: zmin_below,
        zmax: zmax_below,
        err: err_below,
    };
    let w = w as usize;
    z_up[base..base + n]
        .par_chunks_mut(w)
        .zip(zmin_up[base..base + n].par_chunks_mut(w))
        .zip(zmax_up[base..base + n].par_chunks_mut(w))
        .zip(err_up[base..base + n].par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (((z, zmin), zmax), err))| {
            build_row(geom, level, y as u32, &below, [z, zmin, zmax], err);
        });
}

/// The arrays of the level below the one being built, indexed from that level's first node.
struct Below<'a> {
    z: &'a [i32],
    zmin: &'a [i32],
    zmax: &'a [i32],
    err: &'a [u8],
}

/// Row `y` of level `level`: its nodes' heights, bounds and error codes.
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
        let c0 = (2 * y) as usize * cw as usize + (2 * x) as usize;
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

/// The three Haar details of `node`'s split, from its children's heights in `z`.
pub fn split_details(shape: &TreeShape, z: &[i32], node: NodeId) -> [i32; 3] {
    let mut quad = [0i32; 4];
    let mut present = [false; 4];
    for (k, c) in shape.children(node) {
        quad[k] = z[shape.index(c) as usize];
        present[k] = true;
    }
    let p = Presence {
        east: present[1],
        south: present[2],
    };
    haar::forward(quad, p).1
}

#[cfg(test)]
mod tests {
    use super::*;

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
            let heights = ramp(w, h);
            let t = build_arrays(&geom, &heights, |_| {});
            let inner = shape.level_offset(shape.depth());
            for i in 0..inner {
                let node = shape.node(i).unwrap();
                let e = error_value(t.err[i as usize]);
                let z = t.z[i as usize];
                let (c0, r0, c1, r1) = shape.block(node);
                for r in r0..=r1 {
                    for c in c0..=c1 {
                        let leaf = t.z[shape.index(shape.leaf(c, r)) as usize];
                        assert!(((leaf - z) as f32 * 0.25).abs() <= e, "{node:?}");
                    }
                }
                for (_, c) in shape.children(node) {
                    let ci = shape.index(c);
                    if ci < inner {
                        assert!(t.err[ci as usize] <= t.err[i as usize]);
                        // The child's box lies inside the parent's.
                        let ce = error_value(t.err[ci as usize]);
                        let dz = (t.z[ci as usize] - z) as f32 * 0.25;
                        assert!(dz.abs() + ce <= e, "{c:?} box escapes {node:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn details_rebuild_children_exactly() {
        let geom = TerrainGeometry::new(13, 6, 1.0, 1.0, 0.1).unwrap();
        let shape = &geom.shape;
        let t = build_arrays(&geom, &ramp(13, 6), |_| {});
        for i in 0..shape.level_offset(shape.depth()) {
            let node = shape.node(i).unwrap();
            let d = split_details(shape, &t.z, node);
            let quad = haar::inverse(t.z[i as usize], d);
            for (k, c) in shape.children(node) {
                assert_eq!(quad[k], t.z[shape.index(c) as usize]);
            }
        }
    }
}
