//! Cameras, the view frustum, the screen-space error of a node and the geomorph factor
//! (paper 000, sections 3.3 and 3.6).
//!
//! Server and client evaluate these with the same code on the same inputs (a node's quantised
//! static error and its bounding box, both derivable from what a split carries), so the client's
//! geomorph factor reaches 0 exactly when the server merges.
//!
//! **Screen error.** The paper projects the static error `e` at the distance `d` to the nearest
//! point of the node's box and scales it by the orientation factor `sqrt(1 - (e_p . e_z)^2)`, the
//! sine of the angle between the view ray and the vertical. For a planar projection with focal
//! length `K` pixels, a vertical offset `e` at a point with view depth `Z` and horizontal distance
//! `r` from the eye moves at most `K e r / Z^2` pixels, which is the paper's formula with the
//! sine written as `r / d` and the distance taken along the view axis. We bound it over the box:
//! `K e min(r_max / Z_min, c) / Z_min`, where `c = 1 / cos` of the frustum's widest off-axis
//! angle bounds `r / Z` for points in view. The bound is monotone (a parent's box holds its
//! children's and its error is saturated), which keeps threshold cuts consistent. Boxes outside
//! the frustum have screen error 0.

use crate::float::Extremum;
use glam::Vec3;
use wide::f32x4;

/// A camera pose in world metres and radians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position, world metres.
    pub eye: Vec3,
    /// Heading, counter-clockwise from east (0 looks east, pi/2 north).
    pub yaw: f32,
    /// Elevation of the view direction; negative looks down.
    pub pitch: f32,
}

impl Camera {
    /// Unit view direction.
    pub fn forward(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        Vec3::new(cy * cp, sy * cp, sp)
    }

    /// Whether every component is finite and the pitch is within (-90, 90) degrees.
    pub fn is_valid(&self) -> bool {
        self.eye.is_finite()
            && self.yaw.is_finite()
            && self.pitch.is_finite()
            && self.pitch.abs() < std::f32::consts::FRAC_PI_2
    }
}

/// Viewport and lens: what a client tells the server once per session.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lens {
    /// Viewport width, pixels.
    pub width: u32,
    /// Viewport height, pixels.
    pub height: u32,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f32,
    /// Near plane distance, metres.
    pub near: f32,
}

impl Lens {
    /// The project's standard view (DESIGN.md section 7): 1920x1080, 60 degrees, near 1 m.
    pub const STANDARD: Lens = Lens {
        width: 1920,
        height: 1080,
        fov_y_deg: 60.0,
        near: 1.0,
    };

    /// Focal length in pixels: pixels per metre at 1 m of view depth.
    pub fn focal_px(&self) -> f32 {
        self.height as f32 / (2.0 * (self.fov_y_deg.to_radians() / 2.0).tan())
    }

    /// Half-extents of the image plane at depth 1: (tan of half horizontal fov, of half vertical).
    pub fn half_tangents(&self) -> (f32, f32) {
        let ty = (self.fov_y_deg.to_radians() / 2.0).tan();
        (ty * self.width as f32 / self.height as f32, ty)
    }
}

/// The boxes of a 2 x 2 quad of nodes (a node's children): box `k` spans column `k & 1`'s x
/// range, row `k >> 1`'s y range and its own z range, each as `[min, max]` in world metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadBoxes {
    /// The west and east columns' x ranges.
    pub x: [[f32; 2]; 2],
    /// The north and south rows' y ranges.
    pub y: [[f32; 2]; 2],
    /// Each box's z range.
    pub z: [[f32; 2]; 4],
}

impl QuadBoxes {
    /// Box `k`.
    pub fn aabb(&self, k: usize) -> Aabb {
        let ([x0, x1], [y0, y1], [z0, z1]) = (self.x[k & 1], self.y[k >> 1], self.z[k]);
        Aabb {
            min: Vec3::new(x0, y0, z0),
            max: Vec3::new(x1, y1, z1),
        }
    }
}

/// An axis-aligned box in world metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl std::ops::Sub<Vec3> for &Aabb {
    type Output = (Vec3, Vec3);

    /// The box's corners relative to a point.
    fn sub(self, p: Vec3) -> (Vec3, Vec3) {
        (self.min - p, self.max - p)
    }
}

/// A camera and lens prepared for many screen-error evaluations.
#[derive(Clone, Debug)]
pub struct ViewState {
    /// The eye, world metres.
    eye: Vec3,
    /// Unit view direction.
    forward: Vec3,
    /// Focal length, pixels.
    focal: f32,
    /// Near plane distance, metres: depths are clamped to it.
    near: f32,
    /// Bound on `r / Z` for points in view (1 / cos of the widest off-axis angle).
    off_axis: f32,
    /// Inward normals of the four side planes through the eye, then the near plane's.
    planes: [Vec3; 5],
    /// Per plane, which box corner lies furthest along its normal: bit `a` set when the normal's
    /// component `a` is >= 0 (the maximum is taken on that axis).
    corners: [u8; 5],
}

impl ViewState {
    /// Prepares `camera` seen through `lens`.
    pub fn new(camera: &Camera, lens: &Lens) -> ViewState {
        let forward = camera.forward();
        let right = forward.cross(Vec3::Z).normalize_or(Vec3::X);
        let up = right.cross(forward);
        let (tx, ty) = lens.half_tangents();
        // Each side plane holds the eye and one frustum edge; `f * t + a` is its inward normal,
        // perpendicular to the edge direction `f - t * a` (a = right or up, unit and orthogonal).
        let planes = [
            (right + forward * tx).normalize(),
            (forward * tx - right).normalize(),
            (up + forward * ty).normalize(),
            (forward * ty - up).normalize(),
            forward,
        ];
        let corners = planes.map(|n| n.cmpge(Vec3::ZERO).bitmask() as u8);
        ViewState {
            eye: camera.eye,
            forward,
            focal: lens.focal_px(),
            near: lens.near,
            off_axis: (1.0 + tx * tx + ty * ty).sqrt(),
            planes,
            corners,
        }
    }

    /// The eye position.
    pub fn eye(&self) -> Vec3 {
        self.eye
    }

    /// Whether any part of `b` may lie inside the frustum (conservative).
    pub fn intersects(&self, b: &Aabb) -> bool {
        self.margin(b - self.eye) >= 0.0
    }

    /// [`BoxView::margin`] of a box given relative to the eye.
    #[inline]
    fn margin(&self, (rel_min, rel_max): (Vec3, Vec3)) -> f32 {
        let mut margin = f32::INFINITY;
        for (i, n) in self.planes.iter().enumerate() {
            // The box corner furthest along the plane normal (which corner is fixed per view).
            let c = self.corners[i];
            let p = Vec3::new(
                if c & 1 != 0 { rel_max.x } else { rel_min.x },
                if c & 2 != 0 { rel_max.y } else { rel_min.y },
                if c & 4 != 0 { rel_max.z } else { rel_min.z },
            );
            let offset = if i == 4 { self.near } else { 0.0 };
            margin = margin.lesser(n.dot(p) - offset);
        }
        margin
    }

    /// Where box `b` lies relative to this view: what the screen error and its bounds need.
    #[inline]
    pub fn box_view(&self, b: &Aabb) -> BoxView {
        let (rel_min, rel_max) = b - self.eye;
        let margin = self.margin((rel_min, rel_max));
        // Nearest depth along the view axis over the box.
        let near_corner = Vec3::select(self.forward.cmpge(Vec3::ZERO), rel_min, rel_max);
        let far = rel_min.abs().max(rel_max.abs());
        BoxView {
            margin,
            depth: self.forward.dot(near_corner),
            r_max: (far.x * far.x + far.y * far.y).sqrt(),
            d_max: far.length(),
        }
    }

    /// [`ViewState::box_view`] of the four boxes of a 2 x 2 quad (a node's children), lane by
    /// lane with the same operations in the same order, so bit for bit the same results: each
    /// term is one four-lane vector (lane `k` is the box in column `k & 1` and row `k >> 1`) and
    /// each step one packed instruction ([`wide`]; plain arrays where the target has no vector
    /// unit). A plane's normal times the box corner it picks is three multiplications and two
    /// additions for all four boxes.
    #[inline]
    pub fn quad_views(&self, q: &QuadBoxes) -> QuadViews {
        self.quad_lanes(q).to_arrays()
    }

    /// [`ViewState::quad_views`] and each box's [`ViewState::error_of`] for static errors `errs`,
    /// the errors also four lanes at once (bit for bit the scalar ones).
    #[inline]
    pub fn quad_errors(&self, q: &QuadBoxes, errs: [f32; 4]) -> (QuadViews, [f32; 4]) {
        let l = self.quad_lanes(q);
        let err = f32x4::from(errs);
        // `error_of`: 0 when err <= 0 or the box is culled, else
        // `focal err min(r_max / depth, off_axis) / depth` with the depth at least `near`.
        let depth = f32x4::splat(self.near).fast_max(l.depth);
        let ratio = f32x4::splat(self.off_axis).fast_min(l.r_max / depth);
        let e = f32x4::splat(self.focal) * err * ratio / depth;
        let zero = err.simd_le(f32x4::ZERO) | l.margin.simd_lt(f32x4::ZERO);
        (l.to_arrays(), zero.bitselect(f32x4::ZERO, e).to_array())
    }

    /// The four lanes of [`ViewState::quad_views`]. `a.fast_min(b)` is `a < b ? a : b` (the
    /// packed `minps`), so the scalar `x.lesser(y)` (`y < x ? y : x`) is `y.fast_min(x)` and
    /// `x.greater(y)` is `y.fast_max(x)`, NaN and signed zeros included.
    #[inline]
    fn quad_lanes(&self, q: &QuadBoxes) -> QuadLanes {
        let e = self.eye;
        let lanes = |a: [f32; 4], o: f32| f32x4::from(a) - f32x4::splat(o);
        // Per lane, the box's low and high coordinates relative to the eye.
        let x = [0, 1].map(|h| lanes([q.x[0][h], q.x[1][h], q.x[0][h], q.x[1][h]], e.x));
        let y = [0, 1].map(|h| lanes([q.y[0][h], q.y[0][h], q.y[1][h], q.y[1][h]], e.y));
        let z = [0, 1].map(|h| lanes([q.z[0][h], q.z[1][h], q.z[2][h], q.z[3][h]], e.z));
        // `a x + b y + c z` lane by lane, as `Vec3::dot` computes it.
        let dot = |n: Vec3, px: f32x4, py: f32x4, pz: f32x4| -> f32x4 {
            f32x4::splat(n.x) * px + f32x4::splat(n.y) * py + f32x4::splat(n.z) * pz
        };
        let mut margin = f32x4::splat(f32::INFINITY);
        for (k, n) in self.planes.iter().enumerate() {
            let c = self.corners[k] as usize;
            let d = dot(*n, x[c & 1], y[c >> 1 & 1], z[c >> 2 & 1]);
            let offset = if k == 4 { self.near } else { 0.0 };
            margin = (d - f32x4::splat(offset)).fast_min(margin);
        }
        // The nearest corner along the view axis: the minimum where forward is >= 0.
        let f = self.forward;
        let near = |fa: f32| usize::from(fa < 0.0);
        let depth = dot(f, x[near(f.x)], y[near(f.y)], z[near(f.z)]);
        let far = |[lo, hi]: [f32x4; 2]| hi.abs().fast_max(lo.abs());
        let (fx, fy, fz) = (far(x), far(y), far(z));
        let h = fx * fx + fy * fy;
        let d2 = h + fz * fz;
        QuadLanes {
            margin,
            depth,
            r_max: h.sqrt(),
            d_max: d2.sqrt(),
        }
    }

    /// Screen error from a box's view terms: see the module docs.
    #[inline]
    pub fn error_of(&self, bv: &BoxView, err: f32) -> f32 {
        if err <= 0.0 || bv.margin < 0.0 {
            return 0.0;
        }
        let depth = bv.depth.greater(self.near);
        self.focal * err * (bv.r_max / depth).lesser(self.off_axis) / depth
    }

    /// Screen-space error in pixels of a node with static error `err` metres and box `b`.
    pub fn screen_error(&self, b: &Aabb, err: f32) -> f32 {
        if err <= 0.0 {
            return 0.0;
        }
        self.error_of(&self.box_view(b), err)
    }

    /// Focal length, pixels.
    pub fn focal(&self) -> f32 {
        self.focal
    }

    /// Near plane distance, metres.
    pub fn near(&self) -> f32 {
        self.near
    }

    /// Bound on `r / Z` for points in view.
    pub fn off_axis(&self) -> f32 {
        self.off_axis
    }

    /// Inward unit normals of the four side planes through the eye, then the near plane's (whose
    /// offset from the eye is [`ViewState::near`]; the side planes pass through the eye).
    pub fn planes(&self) -> [Vec3; 5] {
        self.planes
    }

    /// The view basis: forward, right, up (unit vectors).
    pub fn basis(&self) -> [Vec3; 3] {
        let right = self.forward.cross(Vec3::Z).normalize_or(Vec3::X);
        [self.forward, right, right.cross(self.forward)]
    }
}

/// [`BoxView`]'s terms for the four boxes of a quad, one vector each.
struct QuadLanes {
    margin: f32x4,
    depth: f32x4,
    r_max: f32x4,
    d_max: f32x4,
}

impl QuadLanes {
    fn to_arrays(&self) -> QuadViews {
        QuadViews {
            margin: self.margin.to_array(),
            depth: self.depth.to_array(),
            r_max: self.r_max.to_array(),
            d_max: self.d_max.to_array(),
        }
    }
}

/// [`BoxView`]'s terms for the four boxes of a quad (a node's children), term by term: lane `k`
/// of each is box `k`'s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadViews {
    /// [`BoxView::margin`] by lane.
    pub margin: [f32; 4],
    /// [`BoxView::depth`] by lane.
    pub depth: [f32; 4],
    /// [`BoxView::r_max`] by lane.
    pub r_max: [f32; 4],
    /// [`BoxView::d_max`] by lane.
    pub d_max: [f32; 4],
}

impl QuadViews {
    /// Box `k`'s terms.
    pub fn lane(&self, k: usize) -> BoxView {
        BoxView {
            margin: self.margin[k],
            depth: self.depth[k],
            r_max: self.r_max[k],
            d_max: self.d_max[k],
        }
    }
}

impl From<[BoxView; 4]> for QuadViews {
    fn from(v: [BoxView; 4]) -> QuadViews {
        QuadViews {
            margin: v.map(|b| b.margin),
            depth: v.map(|b| b.depth),
            r_max: v.map(|b| b.r_max),
            d_max: v.map(|b| b.d_max),
        }
    }
}

/// A box seen from a view: the terms of its screen error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxView {
    /// Distance by which the box clears the frustum test: >= 0 when it may be in view (then the
    /// box can move this far relative to the camera and still pass), < 0 when culled (then minus
    /// the distance it must move to pass).
    pub margin: f32,
    /// Nearest depth of the box along the view axis (may be negative), metres.
    pub depth: f32,
    /// Furthest horizontal distance from the eye to the box, metres.
    pub r_max: f32,
    /// Furthest distance from the eye to the box, metres.
    pub d_max: f32,
}

/// Geomorph factor of the children of a node whose screen error is `e_scr` (paper 000,
/// section 3.6): 1 puts them at their own positions, 0 on their parent's. It falls from 1 to 0 as
/// the parent's error falls from `lambda * tau` to `tau`, so a merge at `tau` never pops.
pub fn morph_alpha(e_scr: f32, tau: f32, lambda: f32) -> f32 {
    ((e_scr - tau) / ((lambda - 1.0) * tau)).clamp(0.0, 1.0)
}

/// Parses `x,y,z,yaw,pitch`: metres east and north of the terrain's south-west sample, metres
/// of height, degrees counter-clockwise from east, degrees of elevation (negative looks down).
pub fn parse_camera(s: &str) -> Result<Camera, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|p| p.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("camera {s:?} is not five numbers x,y,z,yaw,pitch"))?;
    let [x, y, z, yaw, pitch] = v[..] else {
        return Err(format!("camera {s:?} is not five numbers x,y,z,yaw,pitch"));
    };
    let cam = Camera {
        eye: Vec3::new(x, y, z),
        yaw: yaw.to_radians(),
        pitch: pitch.to_radians(),
    };
    if cam.is_valid() {
        Ok(cam)
    } else {
        Err(format!(
            "camera {s:?}: numbers must be finite and the pitch within (-90, 90) degrees"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(pitch_deg: f32) -> ViewState {
        let c = Camera {
            eye: Vec3::new(0.0, 0.0, 100.0),
            yaw: 0.0,
            pitch: pitch_deg.to_radians(),
        };
        ViewState::new(&c, &Lens::STANDARD)
    }

    fn cube(x: f32, y: f32, z: f32, h: f32) -> Aabb {
        Aabb {
            min: Vec3::new(x - h, y - h, z - h),
            max: Vec3::new(x + h, y + h, z + h),
        }
    }

    #[test]
    fn culls_what_is_behind_or_beside() {
        let v = cam(0.0);
        assert!(v.intersects(&cube(500.0, 0.0, 100.0, 1.0)));
        assert!(!v.intersects(&cube(-500.0, 0.0, 100.0, 1.0)));
        assert!(!v.intersects(&cube(10.0, 500.0, 100.0, 1.0)));
        assert_eq!(v.screen_error(&cube(-500.0, 0.0, 100.0, 1.0), 5.0), 0.0);
    }

    #[test]
    fn error_falls_with_distance_and_vanishes_straight_down() {
        let v = cam(0.0);
        let near = v.screen_error(&cube(100.0, 0.0, 100.0, 1.0), 1.0);
        let far = v.screen_error(&cube(1000.0, 0.0, 100.0, 1.0), 1.0);
        assert!(near > 5.0 * far, "{near} vs {far}");
        let down = cam(-89.0);
        let below = down.screen_error(&cube(0.0, 0.0, 0.0, 0.01), 1.0);
        let aside = down.screen_error(&cube(50.0, 0.0, 0.0, 0.01), 1.0);
        assert!(below < 0.01 * aside, "{below} vs {aside}");
    }

    #[test]
    fn morph_alpha_spans_tau_to_lambda_tau() {
        assert_eq!(morph_alpha(1.0, 1.0, 2.0), 0.0);
        assert_eq!(morph_alpha(0.5, 1.0, 2.0), 0.0);
        assert_eq!(morph_alpha(1.5, 1.0, 2.0), 0.5);
        assert_eq!(morph_alpha(3.0, 1.0, 2.0), 1.0);
    }

    #[test]
    fn a_quad_at_once_is_bit_for_bit_one_box_at_a_time() {
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        };
        for _ in 0..2000 {
            let c = Camera {
                eye: Vec3::new(rnd() * 100.0, rnd() * 100.0, 50.0 + rnd() * 40.0),
                yaw: rnd() * 3.2,
                pitch: rnd() * 1.5,
            };
            let v = ViewState::new(&c, &Lens::STANDARD);
            let mut range = |scale: f32| {
                let (a, b) = (rnd() * scale, rnd() * scale);
                [a.min(b), a.max(b)]
            };
            let q = QuadBoxes {
                x: [range(300.0), range(300.0)],
                y: [range(300.0), range(300.0)],
                z: [range(80.0), range(80.0), range(80.0), range(80.0)],
            };
            // Static errors of every sign, zero included.
            let errs = [rnd() * 3.0, rnd() * 3.0, rnd().abs(), 0.0];
            let (views, screen) = v.quad_errors(&q, errs);
            assert_eq!(views, v.quad_views(&q));
            for k in 0..4 {
                let got = views.lane(k);
                let one = v.box_view(&q.aabb(k));
                assert_eq!(one.margin.to_bits(), got.margin.to_bits());
                assert_eq!(one.depth.to_bits(), got.depth.to_bits());
                assert_eq!(one.r_max.to_bits(), got.r_max.to_bits());
                assert_eq!(one.d_max.to_bits(), got.d_max.to_bits());
                assert_eq!(v.error_of(&one, errs[k]).to_bits(), screen[k].to_bits());
            }
        }
    }

    #[test]
    fn invalid_cameras_are_flagged() {
        let mut c = Camera {
            eye: Vec3::new(0.0, 0.0, f32::NAN),
            yaw: 0.0,
            pitch: 0.0,
        };
        assert!(!c.is_valid());
        c.eye.z = 1.0;
        assert!(c.is_valid());
        c.pitch = 2.0;
        assert!(!c.is_valid());
    }
}
