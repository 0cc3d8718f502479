//! The tile pyramid of a store (DESIGN.md section 4; paper 001): for every tile its mesh blob,
//! its crack-patch blob, its honest geometric error and its height bounds.
//!
//! - **Mesh**: `grid` (every lattice vertex), `rqt` or `tin` ([`crate::lod::tile::mesh::pyramid`]
//!   chooses the vertices, [`relief_proto::tile::body`] packs them). `tin` tiles carry no
//!   crack patches (they share their border points).
//! - **Geometric error**: the largest vertical distance, metres, between the tile's mesh and
//!   every full-resolution sample it covers (the original heights, before quantisation), then
//!   saturated up the pyramid (a tile's error is at least each child's), so that a selection by
//!   threshold is consistent and a tile's error bounds its whole subtree's.
//! - **Bounds**: the lowest and highest sample the tile covers, quanta (rounded outward), for
//!   the box its screen error is measured to.
//! - **Patches**: paper 001, section 2.2, steps 1-4 for dropped cracks plus the raised ones
//!   ([`relief_proto::tile::body`] explains why), found from the samples and packed; for `rqt`
//!   tiles, crack curtains down to every neighbour a selection may put across each side
//!   ([`crate::lod::tile::mesh::curtain`]), taken from every tile's mesh and packed in the
//!   patch slot ([`relief_proto::tile::body::curtain`]; store format 4). The `grid` tiles of an
//!   `rqt` store (those the grid's border clips) carry paper 001's patches, with a flat dropped
//!   patch also where the finer sample lies exactly on the segment, and the `rqt` sides they
//!   can meet keep every lattice vertex ([`crate::lod::tile::mesh::pyramid`]; store format 5:
//!   format 4 gave those tiles an empty patch set, which left their cracks open).
//!
//! Voids need nothing here: they were filled smoothly before the build, as for the vertex tree.

use super::layout::quantise;
use crate::lod::tile::mesh::HeightGrid;
use crate::lod::tile::mesh::curtain::{
    Polyline, SideCurtain, across, fan, side_curtain, side_polyline,
};
use crate::lod::tile::mesh::pyramid::{
    PyramidMesh, Quantised, Tolerances, irregular_error, mesh_tile,
};
use bytemuck::{Pod, Zeroable};
use relief_proto::tile::body::curtain::encode_curtains;
use relief_proto::tile::body::{
    MeshKind, Patches, encode_patches, find_patches, skirt_triangle_count,
};
use relief_proto::tile::{EDGES, Edge};
use relief_proto::tile::{TileId, TileShape, TileSpan};

/// One tile's entry in the store's `tiles` section (32 bytes, little-endian).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TileRecord {
    /// Offset of the tile's mesh blob in the `tile_data` section; its patch blob follows.
    pub offset: u64,
    /// Mesh blob length, bytes.
    pub mesh_len: u32,
    /// Patch blob length, bytes.
    pub patch_len: u32,
    /// Geometric error, metres, saturated over the tile's descendants.
    pub error: f32,
    /// Lowest covered sample, quanta (rounded down).
    pub zmin: i32,
    /// Highest covered sample, quanta (rounded up).
    pub zmax: i32,
    /// Crack-patch triangles the patch blob holds.
    pub patch_tris: u32,
}

/// The built pyramid: one record per tile by dense index, and the blobs.
pub struct TilePyramid {
    /// Records by dense index.
    pub records: Vec<TileRecord>,
    /// Mesh and patch blobs in the order of the `tile_data` section (each tile's mesh blob,
    /// then its patch blob), where they go back to back.
    pub blobs: Vec<Vec<u8>>,
}

impl TilePyramid {
    /// The `tile_data` section's bytes, the blobs back to back (a copy: for tests).
    pub fn data(&self) -> Vec<u8> {
        self.blobs.concat()
    }
}

/// A tile's own error (metres, before saturation), patch blob and patch triangles.
type Part = (f32, Vec<u8>, u32);

/// What the pyramid keeps of a tile once its mesh is made.
struct Made {
    /// The mesh blob.
    blob: Vec<u8>,
    /// The polylines of its four sides, in [`EDGES`] order (`rqt` pyramids only).
    sides: Option<[Polyline; 4]>,
    /// Its part, or for an `rqt` tile, whose curtains wait for its neighbours' sides, its
    /// error.
    part: Result<Part, f32>,
}

/// The polyline of tile `t`'s side `e` from its mesh `m`.
fn side_of(shape: &TileShape, t: TileId, m: &PyramidMesh, e: Edge) -> Polyline {
    let span = shape.span(t);
    side_polyline(&span, e, m.z.len(), |v| {
        let p = match &m.irregular {
            None => {
                let (c, r) = span.vertex_pos(v as u32);
                [c, r]
            }
            Some(irr) => [span.cols.0 + irr.at[v][0], span.rows.0 + irr.at[v][1]],
        };
        (p, m.z[v])
    })
}

/// Builds the pyramid over `heights` (row-major metres, voids filled) quantised by `quantum`,
/// with meshes of `kind` ([`pyramid`]). `progress` receives the fraction done.
pub fn build_pyramid(
    shape: &TileShape,
    heights: &[f32],
    quantum: f32,
    kind: MeshKind,
    mut progress: impl FnMut(f64),
) -> TilePyramid {
    let (w, h) = (shape.width(), shape.height());
    use rayon::prelude::*;
    let inv = 1.0 / quantum;
    // The heights in metres again, as a grid, only for `tin`: the other kinds quantise each
    // sample as they read it ([`Quantised::at`]; the same `f32`).
    let zf: Vec<f32> = match kind {
        MeshKind::Tin => heights
            .par_iter()
            .map(|&h| quantise(h, inv) as f32 * quantum)
            .collect(),
        MeshKind::Grid | MeshKind::Rqt => Vec::new(),
    };
    let Some(orig) = HeightGrid::new(w as usize, h as usize, heights) else {
        unreachable!("a tile shape has at least 2 x 2 samples, one height each");
    };
    let quantised = Quantised::new(
        heights,
        w,
        quantum,
        HeightGrid::new(w as usize, h as usize, &zf),
    );
    let n = shape.tile_count() as usize;
    let tile = |i: usize| shape.tile(i as u32).unwrap_or(TileId::ROOT);
    // Every tile's grid error and bounds first: the grid's own errors, and the adaptive kinds'
    // tolerances. Each step below is one tile at a time, independent of the others, on every
    // core; the results come back in tile order, so the store is the same bytes whatever the
    // number of threads.
    let steps = if kind == MeshKind::Rqt { 3.0 } else { 2.0 };
    let errors_bounds: Vec<(f32, (i32, i32))> = par_map(
        n,
        |i| {
            let span = shape.span(tile(i));
            let z = span.map_vertices(|c, r| quantised.at(c, r) as f32 * quantum);
            let (err, lo, hi) = grid_error_bounds(&span, &z, &orig);
            (err, ((lo * inv).floor() as i32, (hi * inv).ceil() as i32))
        },
        |f| progress(f / steps),
    );
    let grid_err: Vec<f32> = errors_bounds.iter().map(|e| e.0).collect();
    let tol = Tolerances::from_grid_errors(shape, &grid_err);
    // A grid tile's error, patch blob and patch triangles, from its lattice heights `z`: also
    // in an `rqt` store (one the grid's border clips), paper 001's patches, which close its
    // cracks against `rqt` tiles too, since their sides that can meet it keep every lattice
    // vertex ([`crate::lod::tile::mesh::pyramid`]).
    let grid_part = |i: usize, z: &[i32]| -> Part {
        let t = tile(i);
        let sample = |c: u32, r: u32| quantised.at(c, r);
        let patches = if kind == MeshKind::Rqt {
            grid_patches_in_rqt(shape, t, z, sample)
        } else {
            find_patches(shape, t, z, sample)
        };
        let pblob = encode_patches(shape, t, z, &patches);
        (grid_err[i], pblob, patches.triangle_count() as u32)
    };
    // Every tile's mesh, and with it all that depends on the tile alone: its blob, its error
    // and, but for an `rqt` tile's curtains, its patches. The mesh itself then goes: an `rqt`
    // tile keeps only its four sides' polylines, which its neighbours' curtains need, so the
    // pyramid never holds every tile's mesh at once.
    let made: Vec<Made> = par_map(
        n,
        |i| {
            let t = tile(i);
            let m = mesh_tile(kind, shape, t, &quantised, &tol);
            let sides = (kind == MeshKind::Rqt).then(|| EDGES.map(|e| side_of(shape, t, &m, e)));
            let part = match &m.irregular {
                None => Ok(grid_part(i, &m.z)),
                Some(irr) => {
                    let err = irregular_error(shape, t, irr, &m.z, quantum, &orig);
                    if kind == MeshKind::Rqt {
                        Err(err)
                    } else {
                        Ok((err, Vec::new(), 0))
                    }
                }
            };
            Made {
                blob: m.blob,
                sides,
                part,
            }
        },
        |f| progress((1.0 + f) / steps),
    );
    let side = |t: TileId, e: Edge| -> &Polyline {
        let sides = made[shape.index(t) as usize].sides.as_ref();
        &sides.expect("an rqt pyramid keeps every tile's sides")[e as usize]
    };
    // Each tile's own error, patch blob and patch triangles: the `rqt` tiles' curtains now,
    // on every side with a neighbour.
    let mut curtains: Vec<Option<Part>> = if kind != MeshKind::Rqt {
        Vec::new()
    } else {
        par_map(
            n,
            |i| {
                let err = match &made[i].part {
                    Ok(_) => return None,
                    Err(err) => *err,
                };
                let t = tile(i);
                let sides: Vec<(Polyline, SideCurtain)> = EDGES
                    .into_iter()
                    .filter(|&e| shape.neighbour(t, e).is_some())
                    .map(|e| {
                        let own = side(t, e);
                        let others: Vec<Polyline> = across(shape, t, e)
                            .into_iter()
                            .map(|(n, b)| side(n, b).clone())
                            .collect();
                        let c = side_curtain(own, &others);
                        (own.clone(), c)
                    })
                    .collect();
                let curtain_tris: usize = sides
                    .iter()
                    .flat_map(|(own, segs)| {
                        segs.iter()
                            .enumerate()
                            .filter_map(move |(s, b)| b.as_ref().map(|b| fan(own, s, b).len()))
                    })
                    .sum();
                Some((err, encode_curtains(&sides), curtain_tris as u32))
            },
            |f| progress((steps - 1.0 + f) / steps),
        )
    };
    // The records, finest level first, so that children's errors are known when parents
    // saturate; the blobs moved, not copied, into that order.
    let mut made = made;
    let mut records = vec![TileRecord::default(); n];
    let mut blobs = Vec::with_capacity(2 * n);
    let mut offset = 0u64;
    for level in (0..=shape.depth()).rev() {
        let (nx, ny) = shape.level_dims(level);
        for y in 0..ny {
            for x in 0..nx {
                let t = TileId { level, x, y };
                let i = shape.index(t) as usize;
                let (own_err, pblob, patch_tris) =
                    match std::mem::replace(&mut made[i].part, Err(0.0)) {
                        Ok(part) => part,
                        Err(_) => curtains[i].take().unwrap_or_default(),
                    };
                let mut err = own_err;
                for c in shape.children(t) {
                    err = err.max(records[shape.index(c) as usize].error);
                }
                let mesh = std::mem::take(&mut made[i].blob);
                records[i] = TileRecord {
                    offset,
                    mesh_len: mesh.len() as u32,
                    patch_len: pblob.len() as u32,
                    error: err,
                    zmin: errors_bounds[i].1.0,
                    zmax: errors_bounds[i].1.1,
                    patch_tris,
                };
                offset += (mesh.len() + pblob.len()) as u64;
                blobs.push(mesh);
                blobs.push(pblob);
            }
        }
    }
    progress(1.0);
    TilePyramid { records, blobs }
}

/// The grid mesh over `span` (vertex heights `z`) against the samples `orig` it covers: the
/// largest vertical distance, and the lowest and highest sample. The same numbers as
/// [`relief_proto::tile::body::grid_height`] at every sample, computed a row at a time: each
/// sample falls in the cell `grid_height` puts it in (the stride divides exactly in `f32`), with
/// the same `u` and `v`, and each height is the same `f32` expression (the greatest distance
/// and the extremes do not depend on the order they are taken in), so the store's bytes do not
/// change. The terms of a cell's two triangles that do not depend on `u` are made once a row;
/// a cell eight or more samples wide is done eight samples at a time.
fn grid_error_bounds(span: &TileSpan, z: &[f32], orig: &HeightGrid<'_>) -> (f32, f32, f32) {
    use wide::f32x8;
    let (nx, ny) = (span.nx(), span.ny());
    let w = nx as usize;
    let col0 = span.cols.0;
    // Each cell's first and last column, as offsets from the span's first: a sample on a cell's
    // far side belongs to the next cell, except on the last.
    let cells: Vec<(usize, usize)> = (0..nx - 1)
        .map(|i| {
            let (c0, c1) = (span.col(i), span.col(i + 1));
            let c_last = if i == nx - 2 { c1 } else { c1 - 1 };
            ((c0 - col0) as usize, (c_last - col0) as usize)
        })
        .collect();
    // `u` at each column of a cell, by the cell's width (all cells but the last share one).
    let u_of = |i: u32| -> Vec<f32> {
        let (c0, c1) = (span.col(i), span.col(i + 1));
        let (c0f, c1f) = (c0 as f32, c1 as f32);
        let (first, last) = cells[i as usize];
        (0..=last - first)
            .map(|d| (((c0 + d as u32) as f32 - c0f) / (c1f - c0f)).clamp(0.0, 1.0))
            .collect()
    };
    let u_first = u_of(0);
    let u_last = u_of(nx - 2);
    let (mut err, mut lo, mut hi) = (0f32, f32::MAX, f32::MIN);
    let (mut err8, mut lo8, mut hi8) =
        (f32x8::ZERO, f32x8::splat(f32::MAX), f32x8::splat(f32::MIN));
    for j in 0..ny - 1 {
        let (r0, r1) = (span.row(j), span.row(j + 1));
        let r_last = if j == ny - 2 { r1 } else { r1 - 1 };
        let (r0f, r1f) = (r0 as f32, r1 as f32);
        for r in r0..=r_last {
            let v = ((r as f32 - r0f) / (r1f - r0f)).clamp(0.0, 1.0);
            let start = r as usize * orig.width + col0 as usize;
            let row = &orig.z[start..];
            for (i, &(first, last)) in cells.iter().enumerate() {
                let at = j as usize * w + i;
                let [z00, z10, z01, z11] = [z[at], z[at + 1], z[at + w], z[at + w + 1]];
                // `cell_height`'s two triangles: under the diagonal (`u <= v`)
                // `(z00 + v * (z01 - z00)) + u * (z11 - z01)`, above it
                // `(z00 + u * (z10 - z00)) + v * (z11 - z10)`.
                let (a, b) = (z00 + v * (z01 - z00), z11 - z01);
                let (d, e) = (z10 - z00, v * (z11 - z10));
                let us: &[f32] = if i + 1 == cells.len() {
                    &u_last
                } else {
                    &u_first
                };
                let hs = &row[first..=last];
                let mut k = 0;
                if hs.len() >= 8 {
                    let (va, vb, vz, vd, ve, vv) = (
                        f32x8::splat(a),
                        f32x8::splat(b),
                        f32x8::splat(z00),
                        f32x8::splat(d),
                        f32x8::splat(e),
                        f32x8::splat(v),
                    );
                    while k + 8 <= hs.len() {
                        let h = f32x8::new(hs[k..k + 8].try_into().unwrap_or([0.0; 8]));
                        let u = f32x8::new(us[k..k + 8].try_into().unwrap_or([0.0; 8]));
                        let g = u.simd_le(vv).select(va + u * vb, vz + u * vd + ve);
                        lo8 = lo8.fast_min(h);
                        hi8 = hi8.fast_max(h);
                        err8 = err8.fast_max((g - h).abs());
                        k += 8;
                    }
                }
                for (&h, &u) in hs[k..].iter().zip(&us[k..]) {
                    let g = if u <= v { a + u * b } else { z00 + u * d + e };
                    lo = lo.min(h);
                    hi = hi.max(h);
                    err = err.max((g - h).abs());
                }
            }
        }
    }
    for ((e, l), h) in err8
        .to_array()
        .into_iter()
        .zip(lo8.to_array())
        .zip(hi8.to_array())
    {
        err = err.max(e);
        lo = lo.min(l);
        hi = hi.max(h);
    }
    (err, lo, hi)
}

/// `f(0) .. f(n - 1)` in order, computed on every core (rayon's pool), in rounds between which
/// `progress` receives the fraction done.
fn par_map<T: Send>(
    n: usize,
    f: impl Fn(usize) -> T + Sync + Send,
    mut progress: impl FnMut(f64),
) -> Vec<T> {
    use rayon::prelude::*;
    const ROUNDS: usize = 32;
    let step = n.div_ceil(ROUNDS).max(1);
    let mut out = Vec::with_capacity(n);
    let mut start = 0;
    while start < n {
        let end = (start + step).min(n);
        out.par_extend((start..end).into_par_iter().map(&f));
        start = end;
        progress(start as f64 / n as f64);
    }
    out
}

/// The patches of grid tile `t` (vertex heights `z`, finer samples `sample`) in an `rqt` store:
/// paper 001's ([`find_patches`]), and also a flat dropped patch where the finer sample `B` lies
/// exactly on its segment `A-C`. In a `grid` store the finer tile's raised patch closes that
/// T-junction; a finer `rqt` tile has `B` on its side too but its curtain cannot reach `C`, so
/// the coarse tile carries the flat triangle, as a coarse `rqt` tile's curtain does.
fn grid_patches_in_rqt(
    shape: &TileShape,
    t: TileId,
    z: &[i32],
    sample: impl Fn(u32, u32) -> i32,
) -> Patches {
    // With every finer sample one quantum lower, every `B` on or below its segment (and a few
    // less than a quantum above) gets a dropped patch; keep those on or below, at their height.
    let mut p = find_patches(shape, t, z, |c, r| sample(c, r).saturating_sub(1));
    let span = shape.span(t);
    p.dropped.retain_mut(|d| {
        d.z = sample(d.at.0, d.at.1);
        let (a, c) = (span.vertex_pos(d.a), span.vertex_pos(d.c));
        // Positions along the edge: columns along a row, rows along a column.
        let (pa, pb, pc) = if a.1 == c.1 {
            (a.0, d.at.0, c.0)
        } else {
            (a.1, d.at.1, c.1)
        };
        let (pa, pb, pc) = (i64::from(pa), i64::from(pb), i64::from(pc));
        let line = i64::from(z[d.a as usize]) * (pc - pb) + i64::from(z[d.c as usize]) * (pb - pa);
        i64::from(d.z) * (pc - pa) <= line
    });
    p
}

/// Patch and skirt triangles of a set of tiles, for comparisons (paper 001, table 1).
pub fn crack_triangles(shape: &TileShape, records: &[TileRecord], tiles: &[u32]) -> (u64, u64) {
    tiles.iter().fold((0, 0), |(p, s), &i| {
        let t = shape.tile(i).unwrap_or(TileId::ROOT);
        (
            p + u64::from(records[i as usize].patch_tris),
            s + skirt_triangle_count(&shape.span(t)) as u64,
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use relief_proto::tile::body::decode_mesh;
    use relief_proto::tile::geometry::Surface;
    use relief_proto::tile::mirror::TileData;

    #[test]
    fn grid_errors_by_cell_are_grid_height_at_every_sample() {
        // A grid whose border clips tiles at every level, so that last cells are narrower.
        let (w, h) = (151u32, 141u32);
        let heights: Vec<f32> = (0..w * h)
            .map(|i| {
                let (c, r) = ((i % w) as f32, (i / w) as f32);
                (c * 0.37).sin() * 41.0 + (r * 0.23).cos() * 17.0 + (c * r * 0.013).sin() * 5.0
            })
            .collect();
        let orig = HeightGrid::new(w as usize, h as usize, &heights).unwrap();
        let shape = TileShape::new(w, h, 16).unwrap();
        for i in 0..shape.tile_count() {
            let span = shape.span(shape.tile(i).unwrap());
            let z: Vec<f32> = (0..span.vertex_count() as u32)
                .map(|v| {
                    let (c, r) = span.vertex_pos(v);
                    (orig.at(c, r) * 4.0).round() / 4.0
                })
                .collect();
            let (mut err, mut lo, mut hi) = (0f32, f32::MAX, f32::MIN);
            for r in span.rows.0..=span.rows.1 {
                for c in span.cols.0..=span.cols.1 {
                    let s = orig.at(c, r);
                    lo = lo.min(s);
                    hi = hi.max(s);
                    let g = relief_proto::tile::body::grid_height(&span, &z, c as f32, r as f32);
                    err = err.max((g - s).abs());
                }
            }
            let by_cell = grid_error_bounds(&span, &z, &orig);
            assert_eq!(
                (by_cell.0.to_bits(), by_cell.1, by_cell.2),
                (err.to_bits(), lo, hi),
                "tile {i}"
            );
        }
    }

    /// For every mesh kind: each tile's blob decodes, and its recorded error bounds the
    /// distance from the decoded mesh (as a client draws it) to every sample it covers.
    #[test]
    fn decoded_meshes_stay_within_their_recorded_errors() {
        let (w, h) = (257u32, 257u32);
        let heights: Vec<f32> = (0..w * h)
            .map(|i| {
                let (c, r) = ((i % w) as f32, (i / w) as f32);
                (c * 0.31).sin() * 35.0 + (r * 0.17).cos() * 22.0 + ((c * r) * 0.011).sin() * 7.0
            })
            .collect();
        let shape = TileShape::new(w, h, 64).unwrap();
        for kind in [MeshKind::Grid, MeshKind::Rqt, MeshKind::Tin] {
            let q = 0.1;
            let p = build_pyramid(&shape, &heights, q, kind, |_| {});
            let data = p.data();
            for i in 0..shape.tile_count() {
                let t = shape.tile(i).unwrap();
                let r = p.records[i as usize];
                let blob = &data[r.offset as usize..][..r.mesh_len as usize];
                let span = shape.span(t);
                let m = decode_mesh(&span, blob).unwrap();
                let data = TileData {
                    tile: t,
                    span,
                    z: m.z,
                    irregular: m.irregular,
                    patches: Default::default(),
                };
                let surface = Surface::new(&data);
                let mut worst = 0f32;
                for rr in span.rows.0..=span.rows.1 {
                    for c in span.cols.0..=span.cols.1 {
                        let at = data.height_at(c as f32, rr as f32).expect("covered");
                        // The bucketed surface finds the same height.
                        let fast = surface.height_at(c as f32, rr as f32).expect("covered");
                        assert!((fast - at).abs() < 1e-3, "{kind:?} {t:?} {c} {rr}");
                        let z = at * q;
                        worst = worst.max((z - heights[(rr * w + c) as usize]).abs());
                    }
                }
                assert!(
                    worst <= r.error + 1e-3,
                    "{kind:?} {t:?}: {worst} > {}",
                    r.error
                );
            }
        }
    }

    /// `rqt+patches`: every `rqt` tile's curtain blob decodes as a client decodes it
    /// (against the decoded mesh alone) to as many triangles as the store counted, over the
    /// tile's own border vertices and points on its sides; tiles with a neighbour have some.
    #[test]
    fn rqt_curtain_blobs_decode_to_the_counted_triangles() {
        use relief_proto::tile::body::curtain::{CurtainPoint, decode_tile_curtains};
        let (w, h) = (129u32, 129u32);
        let heights: Vec<f32> = (0..w * h)
            .map(|i| {
                let (c, r) = ((i % w) as f32, (i / w) as f32);
                (c * 0.31).sin() * 35.0 + (r * 0.17).cos() * 22.0 + ((c * r) * 0.011).sin() * 7.0
            })
            .collect();
        let shape = TileShape::new(w, h, 16).unwrap();
        let p = build_pyramid(&shape, &heights, 0.1, MeshKind::Rqt, |_| {});
        let mut total = 0;
        for i in 0..shape.tile_count() {
            let t = shape.tile(i).unwrap();
            let r = p.records[i as usize];
            let data = &p.data()[r.offset as usize..];
            let (mesh, blob) = data.split_at(r.mesh_len as usize);
            let span = shape.span(t);
            let m = decode_mesh(&span, mesh).unwrap();
            let irr = m.irregular.as_ref().unwrap();
            let tris =
                decode_tile_curtains(&shape, t, irr, &m.z, &blob[..r.patch_len as usize]).unwrap();
            assert_eq!(tris.len(), r.patch_tris as usize, "{t:?}");
            let on_side = |(c, r): (u32, u32)| {
                c == span.cols.0 || c == span.cols.1 || r == span.rows.0 || r == span.rows.1
            };
            for p in tris.iter().flatten() {
                match *p {
                    CurtainPoint::Vertex(v) => {
                        let a = irr.at[v as usize];
                        assert!(on_side((span.cols.0 + a[0], span.rows.0 + a[1])));
                    }
                    CurtainPoint::Below { at, .. } => assert!(on_side(at), "{t:?} {at:?}"),
                }
            }
            total += tris.len();
        }
        assert!(total > 0);
    }

    #[test]
    fn errors_bound_every_sample_and_saturate() {
        let (w, h) = (70u32, 45u32);
        let heights: Vec<f32> = (0..w * h)
            .map(|i| ((i % w) as f32 * 0.7).sin() * 40.0 + ((i / w) as f32 * 0.3).cos() * 25.0)
            .collect();
        let shape = TileShape::new(w, h, 8).unwrap();
        let p = build_pyramid(&shape, &heights, 0.1, MeshKind::Grid, |_| {});
        for i in 0..shape.tile_count() {
            let t = shape.tile(i).unwrap();
            let r = p.records[i as usize];
            for c in shape.children(t) {
                assert!(r.error >= p.records[shape.index(c) as usize].error);
            }
            if t.level == shape.depth() {
                // Full resolution: only quantisation remains.
                assert!(r.error <= 0.051, "{r:?}");
            }
            assert!(r.zmin <= r.zmax);
        }
        assert!(p.records[0].error > 1.0);
        let all: Vec<u32> = (0..shape.tile_count()).collect();
        let (patch, skirt) = crack_triangles(&shape, &p.records, &all);
        assert!(patch > 0 && patch < skirt);
    }
}
