//! The tile pyramid of a store (DESIGN.md section 4; paper 001): for every tile its mesh blob,
//! its crack-patch blob, its honest geometric error and its height bounds.
//!
//! - **Mesh**: `grid` (every tile vertex is a sample; [`relief_proto::tile::body`]). The mesh is
//!   one pluggable step ([`mesh_tile`]): the next mesh kinds replace it and keep the rest.
//! - **Geometric error**: the largest vertical distance, metres, between the tile's mesh and
//!   every full-resolution sample it covers (the original heights, before quantisation), then
//!   saturated up the pyramid (a tile's error is at least each child's), so that a selection by
//!   threshold is consistent and a tile's error bounds its whole subtree's.
//! - **Bounds**: the lowest and highest sample the tile covers, quanta (rounded outward), for
//!   the box its screen error is measured to.
//! - **Patches**: paper 001, section 2.2, steps 1-4 for dropped cracks plus the raised ones
//!   ([`relief_proto::tile::body`] explains why), found from the samples and packed.
//!
//! Voids need nothing here: they were filled smoothly before the build, as for the vertex tree.

use bytemuck::{Pod, Zeroable};
use relief_proto::tile::body::{
    encode_mesh, encode_patches, find_patches, grid_height, skirt_triangle_count,
};
use relief_proto::tile::{TileId, TileShape};

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
    /// Mesh and patch blobs, back to back.
    pub data: Vec<u8>,
}

/// Heights of the tile's vertices, quanta (the mesh step for `grid`).
fn mesh_tile(shape: &TileShape, t: TileId, zq: &[i32]) -> Vec<i32> {
    let span = shape.span(t);
    let w = shape.width();
    (0..span.vertex_count() as u32)
        .map(|v| {
            let (c, r) = span.vertex_pos(v);
            zq[(r * w + c) as usize]
        })
        .collect()
}

/// Builds the pyramid over `heights` (row-major metres, voids filled) quantised by `quantum`.
/// `progress` receives the fraction done.
pub fn build_pyramid(
    shape: &TileShape,
    heights: &[f32],
    quantum: f32,
    mut progress: impl FnMut(f64),
) -> TilePyramid {
    let w = shape.width();
    let inv = 1.0 / quantum;
    let zq: Vec<i32> = heights
        .iter()
        .map(|&h| {
            let v = h * inv;
            (v + 0.5f32.copysign(v)) as i32
        })
        .collect();
    let n = shape.tile_count() as usize;
    let mut records = vec![TileRecord::default(); n];
    let mut data = Vec::new();
    // Finest level first, so that children's errors are known when parents saturate.
    for level in (0..=shape.depth()).rev() {
        let (nx, ny) = shape.level_dims(level);
        for y in 0..ny {
            for x in 0..nx {
                let t = TileId { level, x, y };
                let span = shape.span(t);
                let z = mesh_tile(shape, t, &zq);
                let zf: Vec<f32> = z.iter().map(|&v| v as f32 * quantum).collect();
                let (mut err, mut lo, mut hi) = (0f32, f32::MAX, f32::MIN);
                for r in span.rows.0..=span.rows.1 {
                    for c in span.cols.0..=span.cols.1 {
                        let h = heights[(r * w + c) as usize];
                        lo = lo.min(h);
                        hi = hi.max(h);
                        err = err.max((grid_height(&span, &zf, c as f32, r as f32) - h).abs());
                    }
                }
                for c in shape.children(t) {
                    err = err.max(records[shape.index(c) as usize].error);
                }
                let patches = find_patches(shape, t, &z, |c, r| zq[(r * w + c) as usize]);
                let mesh = encode_mesh(&span, &z);
                let pblob = encode_patches(shape, t, &z, &patches);
                records[shape.index(t) as usize] = TileRecord {
                    offset: data.len() as u64,
                    mesh_len: mesh.len() as u32,
                    patch_len: pblob.len() as u32,
                    error: err,
                    zmin: (lo * inv).floor() as i32,
                    zmax: (hi * inv).ceil() as i32,
                    patch_tris: patches.triangle_count() as u32,
                };
                data.extend_from_slice(&mesh);
                data.extend_from_slice(&pblob);
            }
        }
        progress(1.0 - f64::from(level) / f64::from(shape.depth() + 1));
    }
    TilePyramid { records, data }
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

    #[test]
    fn errors_bound_every_sample_and_saturate() {
        let (w, h) = (70u32, 45u32);
        let heights: Vec<f32> = (0..w * h)
            .map(|i| ((i % w) as f32 * 0.7).sin() * 40.0 + ((i / w) as f32 * 0.3).cos() * 25.0)
            .collect();
        let shape = TileShape::new(w, h, 8).unwrap();
        let p = build_pyramid(&shape, &heights, 0.1, |_| {});
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
