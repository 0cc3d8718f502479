//! The measured pixel error of a mesh for a camera (DESIGN.md section 7).
//!
//! For every full-resolution sample inside the view frustum, project the DEM point
//! `(x, y, z_dem)` and the mesh point `(x, y, z_mesh(x, y))` and take the distance in pixels
//! between the two. Occlusion is ignored, which is conservative. `z_mesh` comes from rasterising
//! the mesh's triangles over the sample grid in the xy plane.
//!
//! Large grids may be measured on a *stratified sample*: the samples of one residue class of a
//! `stride x stride` lattice, the class changing from frame to frame, so that every sample is
//! measured over a run and each frame's sample is spread evenly over the grid.
//!
//! Samples that were voids in the source are skipped (there is no truth to compare with).
//! Samples the mesh does not cover (a sliver along the grid border, where border vertices sit
//! inside the border; see `store::build`) are counted separately.

use glam::Vec3;
use relief_proto::terrain::TerrainGeometry;
use relief_proto::view::{Camera, Lens, ViewState};

/// The pixel errors of one frame.
#[derive(Clone, Debug, Default)]
pub struct FrameErrors {
    /// Error in pixels of each covered, non-void sample inside the frustum.
    pub errors: Vec<f32>,
    /// Non-void samples inside the frustum that no triangle covers.
    pub uncovered: u64,
}

/// Which samples to measure: those with `col % stride == offset.0 && row % stride == offset.1`.
#[derive(Clone, Copy, Debug)]
pub struct Lattice {
    /// Spacing of the measured samples, in samples (1 = every sample).
    pub stride: u32,
    /// Residue class of the measured columns and rows.
    pub offset: (u32, u32),
}

impl Lattice {
    /// The smallest stride that still measures at least `min_samples` samples of a w x h grid.
    pub fn for_grid(w: u32, h: u32, min_samples: u64, frame: usize) -> Lattice {
        let total = w as u64 * h as u64;
        let stride = ((total as f64 / min_samples as f64).sqrt().floor() as u32).max(1);
        // Walk the residue classes in a fixed, well-spread order.
        let k = (frame as u64 * 7919) % (stride as u64 * stride as u64);
        Lattice {
            stride,
            offset: ((k % stride as u64) as u32, (k / stride as u64) as u32),
        }
    }

    /// How many lattice samples fall in an axis of `n` samples, starting at `off`.
    pub fn count(&self, n: u32, off: u32) -> u32 {
        if off >= n {
            0
        } else {
            (n - off).div_ceil(self.stride)
        }
    }
}

/// Measures the pixel error of the mesh `tris` (world-space triangles) against the DEM `heights`
/// (row-major metres) for `camera` through `lens`.
pub fn frame_errors(
    geom: &TerrainGeometry,
    heights: &[f32],
    is_void: impl Fn(u32, u32) -> bool,
    tris: &[[Vec3; 3]],
    camera: &Camera,
    lens: &Lens,
    lat: Lattice,
) -> FrameErrors {
    let w = geom.shape.width();
    let lw = lat.count(w, lat.offset.0);
    let lh = lat.count(geom.shape.height(), lat.offset.1);
    let mut zbuf = vec![f32::NAN; lw as usize * lh as usize];
    for t in tris {
        raster(geom, t, lat, lw, lh, &mut zbuf);
    }
    let proj = Projector::new(camera, lens);
    let mut out = FrameErrors::default();
    for j in 0..lh {
        let row = lat.offset.1 + j * lat.stride;
        for i in 0..lw {
            let col = lat.offset.0 + i * lat.stride;
            if is_void(col, row) {
                continue;
            }
            let (x, y) = geom.frame.to_world(col as f32, row as f32);
            let truth = Vec3::new(x, y, heights[(row * w + col) as usize]);
            let Some(a) = proj.project(truth) else {
                continue;
            };
            let zm = zbuf[(j * lw + i) as usize];
            if zm.is_nan() {
                out.uncovered += 1;
                continue;
            }
            let b = proj.project_clamped(Vec3::new(x, y, zm));
            out.errors.push((a - b).length());
        }
    }
    out
}

/// Writes the triangle's height at each lattice sample it covers.
fn raster(geom: &TerrainGeometry, t: &[Vec3; 3], lat: Lattice, lw: u32, lh: u32, zbuf: &mut [f32]) {
    let g = t.map(|p| {
        let (c, r) = geom.frame.to_grid(p.x, p.y);
        (c, r)
    });
    let area = (g[1].0 - g[0].0) * (g[2].1 - g[0].1) - (g[2].0 - g[0].0) * (g[1].1 - g[0].1);
    if area.abs() < 1e-12 {
        return;
    }
    let (cmin, cmax) = (
        g[0].0.min(g[1].0).min(g[2].0),
        g[0].0.max(g[1].0).max(g[2].0),
    );
    let (rmin, rmax) = (
        g[0].1.min(g[1].1).min(g[2].1),
        g[0].1.max(g[1].1).max(g[2].1),
    );
    let s = lat.stride as f32;
    let i0 = ((cmin - lat.offset.0 as f32) / s).ceil().max(0.0) as u32;
    let i1 = (((cmax - lat.offset.0 as f32) / s).floor() as i64).min(lw as i64 - 1);
    let j0 = ((rmin - lat.offset.1 as f32) / s).ceil().max(0.0) as u32;
    let j1 = (((rmax - lat.offset.1 as f32) / s).floor() as i64).min(lh as i64 - 1);
    let eps = -1e-4 * area.abs();
    for j in j0 as i64..=j1 {
        let r = lat.offset.1 as f32 + j as f32 * s;
        for i in i0 as i64..=i1 {
            let c = lat.offset.0 as f32 + i as f32 * s;
            let edge = |a: (f32, f32), b: (f32, f32)| {
                ((b.0 - a.0) * (r - a.1) - (c - a.0) * (b.1 - a.1)) * area.signum()
            };
            let w0 = edge(g[1], g[2]);
            let w1 = edge(g[2], g[0]);
            let w2 = edge(g[0], g[1]);
            if w0 >= eps && w1 >= eps && w2 >= eps {
                let z = (w0 * t[0].z + w1 * t[1].z + w2 * t[2].z) / area.abs();
                zbuf[(j as u32 * lw + i as u32) as usize] = z;
            }
        }
    }
}

/// Pinhole projection to pixel offsets from the image centre.
pub struct Projector {
    /// The eye.
    eye: Vec3,
    /// View basis: right.
    right: Vec3,
    /// View basis: up.
    up: Vec3,
    /// View basis: forward.
    forward: Vec3,
    /// Focal length, pixels.
    focal: f32,
    /// Near plane, metres.
    near: f32,
    /// Half-tangent of the horizontal field of view.
    tx: f32,
    /// Half-tangent of the vertical field of view.
    ty: f32,
}

impl Projector {
    /// The projection of `c` through `lens`.
    pub fn new(c: &Camera, lens: &Lens) -> Projector {
        let [forward, right, up] = ViewState::new(c, lens).basis();
        let (tx, ty) = lens.half_tangents();
        Projector {
            eye: c.eye,
            right,
            up,
            forward,
            focal: lens.focal_px(),
            near: lens.near,
            tx,
            ty,
        }
    }

    /// Pixel position of `p`, or `None` outside the frustum.
    pub fn project(&self, p: Vec3) -> Option<glam::Vec2> {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        if z < self.near {
            return None;
        }
        let (x, y) = (d.dot(self.right) / z, d.dot(self.up) / z);
        (x.abs() <= self.tx && y.abs() <= self.ty).then(|| glam::Vec2::new(x, y) * self.focal)
    }

    /// Pixel position of `p` with its depth clamped to the near plane.
    pub fn project_clamped(&self, p: Vec3) -> glam::Vec2 {
        let d = p - self.eye;
        let z = d.dot(self.forward).max(self.near);
        glam::Vec2::new(d.dot(self.right), d.dot(self.up)) * (self.focal / z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_mesh_over_flat_terrain_has_no_error_and_offset_one_has_some() {
        let geom = TerrainGeometry::new(11, 11, 10.0, 10.0, 0.25).unwrap();
        let heights = vec![5.0; 121];
        let quad = |z: f32| {
            let a = Vec3::new(0.0, 0.0, z);
            let b = Vec3::new(100.0, 0.0, z);
            let c = Vec3::new(100.0, 100.0, z);
            let d = Vec3::new(0.0, 100.0, z);
            vec![[a, b, c], [a, c, d]]
        };
        let cam = Camera {
            eye: Vec3::new(50.0, -50.0, 60.0),
            yaw: std::f32::consts::FRAC_PI_2,
            pitch: -0.6,
        };
        let lat = Lattice::for_grid(11, 11, 1000, 0);
        assert_eq!(lat.stride, 1);
        let e = frame_errors(
            &geom,
            &heights,
            |_, _| false,
            &quad(5.0),
            &cam,
            &Lens::STANDARD,
            lat,
        );
        assert!(!e.errors.is_empty());
        assert!(e.errors.iter().all(|&v| v < 1e-3));
        assert_eq!(e.uncovered, 0);
        let e = frame_errors(
            &geom,
            &heights,
            |_, _| false,
            &quad(6.0),
            &cam,
            &Lens::STANDARD,
            lat,
        );
        assert!(e.errors.iter().all(|&v| v > 0.5));
        let e = frame_errors(
            &geom,
            &heights,
            |_, _| false,
            &quad(5.0)[..1],
            &cam,
            &Lens::STANDARD,
            lat,
        );
        assert!(e.uncovered > 0);
    }

    #[test]
    fn lattice_keeps_enough_samples() {
        let l = Lattice::for_grid(4097, 4097, 1_000_000, 3);
        assert_eq!(l.stride, 4);
        assert!(l.count(4097, l.offset.0) as u64 * l.count(4097, l.offset.1) as u64 >= 1_000_000);
    }
}
