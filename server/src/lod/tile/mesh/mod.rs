//! Tile meshes over a grid of samples: what every mesh kind shares.
//!
//! A mesh kind takes the heights of a tile's samples and a vertical tolerance, and returns a
//! [`TriMesh`] whose vertices are a subset of the samples and whose triangles cover the tile's
//! grid exactly once. Its *error* is the largest vertical distance between the mesh (each
//! triangle interpolated linearly) and any sample ([`TriMesh::max_error`]).
//!
//! Conventions: a sample is addressed by `[col, row]`; columns grow east, rows grow south (as in
//! the store). Triangles are counter-clockwise seen from above in world axes (x east, y north),
//! which is clockwise in `(col, row)` image axes.
//!
//! Mesh kinds and their helpers:
//! - [`rqt`]: paper 002's restricted-quadtree mesh, from saturated vertex errors;
//! - [`fractal`]: paper 002's box-counting fractal dimension and its region tree;
//! - [`tin`]: paper 003's greedy-insertion Delaunay TIN to a tolerance, over `delaunay`
//!   and `queue`;
//! - [`borders`]: paper 003's shared border points, so that `tin` tiles of the same and
//!   adjacent levels meet vertex for vertex;
//! - [`pyramid`]: one tile of the store's pyramid meshed by kind, at its level's tolerance.

pub mod borders;
pub mod curtain;
mod delaunay;
pub mod fractal;
pub mod pyramid;
mod queue;
pub mod rqt;
pub mod tin;

/// Heights on a regular grid, row-major, metres.
#[derive(Clone, Copy, Debug)]
pub struct HeightGrid<'a> {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width * height` heights, row by row from the north.
    pub z: &'a [f32],
}

impl<'a> HeightGrid<'a> {
    /// A grid over `z`; `None` when the sizes do not match or a side is under 2 samples.
    pub fn new(width: usize, height: usize, z: &'a [f32]) -> Option<HeightGrid<'a>> {
        (width >= 2 && height >= 2 && z.len() == width * height).then_some(HeightGrid {
            width,
            height,
            z,
        })
    }

    /// The height at `[col, row]`.
    #[inline]
    pub fn at(&self, col: u32, row: u32) -> f32 {
        self.z[row as usize * self.width + col as usize]
    }
}

/// A triangle mesh over grid samples.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertices: sample positions `[col, row]`.
    pub vertices: Vec<[u32; 2]>,
    /// Triangles: three vertex indices each, counter-clockwise seen from above.
    pub triangles: Vec<[u32; 3]>,
}

pub use relief_proto::tile::body::rqt::area2;

impl TriMesh {
    /// Whether every triangle is counter-clockwise and non-degenerate, and the triangles'
    /// areas add up to the grid's: with no overlaps (a watertight planar mesh over the grid's
    /// rectangle has exactly that area), the grid is covered once.
    pub fn covers(&self, width: usize, height: usize) -> bool {
        let mut area = 0i64;
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.vertices[i as usize]);
            let a2 = area2(a, b, c);
            if a2 <= 0 {
                return false;
            }
            area += a2;
        }
        area == 2 * (width as i64 - 1) * (height as i64 - 1)
    }

    /// The largest vertical distance, metres, between the mesh and every sample of `grid`
    /// inside its triangles (brute force: each triangle's bounding box of samples is tested
    /// point by point, barycentric interpolation in `f64` of the vertices' height differences
    /// to the sample, so that a sample on the plane has no rounding error). Samples on
    /// shared edges are tested by every triangle that holds them.
    pub fn max_error(&self, grid: &HeightGrid<'_>) -> f32 {
        let z: Vec<f32> = self.vertices.iter().map(|p| grid.at(p[0], p[1])).collect();
        self.error_against(&z, grid, [0, 0])
    }

    /// The largest vertical distance, metres, between the mesh with vertex heights `vertex_z`
    /// and the samples of `grid` it covers, its vertex `[c, r]` standing on the grid's sample
    /// `origin + [c, r]` (as [`TriMesh::max_error`], whose vertices take the grid's heights).
    /// This measures a mesh of quantised heights against the original samples.
    pub fn error_against(&self, vertex_z: &[f32], grid: &HeightGrid<'_>, origin: [u32; 2]) -> f32 {
        let mut worst = 0.0f64;
        for t in &self.triangles {
            let v = t.map(|i| {
                let p = self.vertices[i as usize];
                [p[0] + origin[0], p[1] + origin[1]]
            });
            let z = t.map(|i| f64::from(vertex_z[i as usize]));
            let d = area2(v[0], v[1], v[2]) as f64;
            if d == 0.0 {
                continue;
            }
            let c0 = v.iter().map(|p| p[0]).min().unwrap_or(0);
            let c1 = v.iter().map(|p| p[0]).max().unwrap_or(0);
            let r0 = v.iter().map(|p| p[1]).min().unwrap_or(0);
            let r1 = v.iter().map(|p| p[1]).max().unwrap_or(0);
            for r in r0..=r1 {
                for c in c0..=c1 {
                    let p = [c, r];
                    let a0 = area2(v[1], v[2], p) as f64;
                    let a1 = area2(v[2], v[0], p) as f64;
                    let a2 = area2(v[0], v[1], p) as f64;
                    if a0 < 0.0 || a1 < 0.0 || a2 < 0.0 {
                        continue;
                    }
                    // The mesh minus the sample, sum a_k (z_k - z) / d with integer areas a_k:
                    // exactly zero for a sample on a plane through integer heights.
                    let zs = f64::from(grid.at(c, r));
                    let m = (a0 * (z[0] - zs) + a1 * (z[1] - zs) + a2 * (z[2] - zs)) / d;
                    worst = worst.max(m.abs());
                }
            }
        }
        worst as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The two triangles of a `w x h` grid's corners (NW-SE diagonal).
    fn corners(w: u32, h: u32) -> TriMesh {
        TriMesh {
            vertices: vec![[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]],
            triangles: vec![[0, 2, 3], [0, 3, 1]],
        }
    }

    #[test]
    fn a_plane_has_no_error_and_a_bump_has_its_height() {
        let (w, h) = (9usize, 5usize);
        let plane: Vec<f32> = (0..w * h)
            .map(|i| 2.0 * (i % w) as f32 - 0.5 * (i / w) as f32 + 10.0)
            .collect();
        let g = HeightGrid::new(w, h, &plane).unwrap();
        let m = corners(w as u32, h as u32);
        assert!(m.covers(w, h));
        assert!(m.max_error(&g) < 1e-4);
        let mut bump = plane.clone();
        bump[2 * w + 4] += 7.5;
        let g = HeightGrid::new(w, h, &bump).unwrap();
        assert!((m.max_error(&g) - 7.5).abs() < 1e-4);
    }

    #[test]
    fn wrong_winding_or_missing_area_is_caught() {
        let mut m = corners(5, 5);
        m.triangles[0].swap(1, 2);
        assert!(!m.covers(5, 5));
        let mut m = corners(5, 5);
        m.triangles.pop();
        assert!(!m.covers(5, 5));
    }
}
