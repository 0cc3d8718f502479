//! A picture of the terrain from a camera, ray-cast with no triangles: one ray per pixel
//! through the client renderer's pinhole, its first hit on the exact surface shaded as the
//! renderer shades a fragment (`GET /v1/raycast.png`). A thumbnail, and a reference
//! that owes nothing to the LOD mesh or the GPU, for the renderer's shots to be compared with.
//!
//! **Rays.** The camera basis is [`relief_proto::view::ViewState`]'s and the client's
//! (`look_to` in `client/src/render/frame.rs`): `right = forward x z`, `up = right x forward`.
//! Pixel `(px, py)` (row 0 at the top) is sampled at its centre, as a rasteriser does, at
//! normalised device coordinates `x = 2 (px + 0.5) / W - 1`, `y = 1 - 2 (py + 0.5) / H`; its
//! ray leaves the eye along `forward + x tx right + y ty up`, with `ty = tan(fov_y / 2)` and
//! `tx = ty W / H` (the projection of `frame.rs` inverted). A ray starts where it crosses the
//! near plane, as the renderer clips what is nearer, and meets nothing past the terrain's
//! extent: those pixels show the sky. The renderer draws no walls under the terrain's edges,
//! so neither does the picture: a ray that enters the extent from the side under the surface
//! (a hit of [`Terrain::cast`] below the surface) shows the sky too. The renderer would show
//! the surface's underside where such a ray comes up through it again; the picture leaves that
//! out.
//!
//! **Shading** is a port of `client/src/render/shade.wgsl` and of the uniform block in
//! `frame.rs`, in `f32` as the GPU computes it: the hypsometric ramp of the hit's height
//! ([`RAMP`]), lambert from [`SUN`] with 0.30 ambient and 0.95 diffuse, haze towards [`HAZE`]
//! by `0.45 (1 - exp(-distance / fog))` with the fog distance of `render::fog_distance` (the
//! terrain's larger side, [`fog_distance`]), then the shader's sRGB encoding `c^(1/2.2)`, and
//! the client's default sky ([`SKY_RGB8`]) where a ray hits nothing. The constants are
//! duplicated, not shared: the WGSL holds them as literals, and the end-to-end test
//! (`tests/tests/e2e/raycast_shot.rs`) checks that the shader's text still holds these values.
//! The height is the exact surface's (the renderer interpolates the LOD mesh's vertices). The
//! normal is smooth, as the renderer's is, but of the full grid: each sample's normal by
//! central differences, blended bilinearly over the hit's cell (the renderer blends the normals
//! it sums at the drawn mesh's vertices). The bilinear patch's own normal would show every
//! cell as a facet up close, and differs from the shot twice as much.

use super::{Hit, QueryError, Ray, Terrain};
use glam::{DVec3, Vec3};
use relief_proto::view::{Camera, Lens};

/// The hypsometric colour ramp of `shade.wgsl`: per stop, the height in metres above sea
/// level and the linear RGB colour there.
pub const RAMP: [[f32; 4]; 9] = [
    [0.0, 0.13, 0.27, 0.10],
    [300.0, 0.24, 0.38, 0.14],
    [800.0, 0.42, 0.45, 0.22],
    [1400.0, 0.50, 0.42, 0.26],
    [2000.0, 0.42, 0.32, 0.21],
    [2600.0, 0.40, 0.36, 0.33],
    [3100.0, 0.55, 0.54, 0.53],
    [3400.0, 0.82, 0.82, 0.84],
    [3700.0, 0.95, 0.95, 0.97],
];

/// Direction towards the sun (not unit; normalised when used), as in `frame.rs`.
pub const SUN: [f32; 3] = [-0.55, 0.45, 0.70];

/// The haze colour, linear RGB, as in `frame.rs`.
pub const HAZE: [f32; 3] = [0.62, 0.70, 0.80];

/// The sky where a ray hits nothing: the renderer's default clear colour, 8-bit sRGB
/// (`SKY_RGB8` in `frame.rs`).
pub const SKY_RGB8: [u8; 3] = [158, 179, 204];

/// Most pixels (rays) in one picture.
pub const MAX_PIXELS: u64 = 1 << 20;

/// Why a picture cannot be made.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum ViewError {
    /// The image is empty or has more than [`MAX_PIXELS`] pixels.
    #[error("image size {0}x{1} is empty or over {MAX_PIXELS} pixels")]
    Size(u32, u32),
    /// The vertical field of view is outside 1 to 170 degrees.
    #[error("vertical field of view {0} is outside 1..=170 degrees")]
    Fov(f32),
    /// The near plane is not a positive finite distance.
    #[error("near plane {0} is not a positive number of metres")]
    Near(f32),
    /// The camera is not finite or looks straight up or down.
    #[error("the camera is not finite or looks straight up or down")]
    Camera,
    /// A ray could not be cast (not expected of a valid camera).
    #[error(transparent)]
    Query(#[from] QueryError),
}

/// The haze's fog distance for `terrain`, metres: its larger side counted in samples times
/// their spacing, as the client's `render::fog_distance` computes it.
pub fn fog_distance(terrain: &Terrain) -> f32 {
    let (w, h) = terrain.size();
    let (dx, dy) = terrain.spacing();
    (w as f32 * dx as f32).max(h as f32 * dy as f32)
}

/// The rays of a camera seen through a lens: its basis and image-plane half-extents.
#[derive(Clone, Copy, Debug)]
pub struct Pinhole {
    /// The eye, world metres.
    eye: DVec3,
    /// Unit view direction.
    forward: DVec3,
    /// Unit right of the image.
    right: DVec3,
    /// Unit up of the image.
    up: DVec3,
    /// Half-extents of the image plane at depth 1: horizontal, vertical.
    half: (f64, f64),
    /// Image width and height, pixels.
    size: (u32, u32),
    /// Near plane distance along the view axis, metres.
    near: f64,
}

impl Pinhole {
    /// The rays of `camera` through `lens` (its width and height are the image's).
    pub fn new(camera: &Camera, lens: &Lens) -> Result<Pinhole, ViewError> {
        let (w, h) = (lens.width, lens.height);
        if w == 0 || h == 0 || u64::from(w) * u64::from(h) > MAX_PIXELS {
            return Err(ViewError::Size(w, h));
        }
        if !(lens.fov_y_deg.is_finite() && (1.0..=170.0).contains(&lens.fov_y_deg)) {
            return Err(ViewError::Fov(lens.fov_y_deg));
        }
        if !(lens.near.is_finite() && lens.near > 0.0) {
            return Err(ViewError::Near(lens.near));
        }
        if !camera.is_valid() {
            return Err(ViewError::Camera);
        }
        // The basis in f32 as the renderer builds it, then widened.
        let forward = camera.forward();
        let right = forward.cross(Vec3::Z).normalize_or(Vec3::X);
        let up = right.cross(forward);
        let ty = (f64::from(lens.fov_y_deg).to_radians() / 2.0).tan();
        Ok(Pinhole {
            eye: camera.eye.as_dvec3(),
            forward: forward.as_dvec3(),
            right: right.as_dvec3(),
            up: up.as_dvec3(),
            half: (ty * f64::from(w) / f64::from(h), ty),
            size: (w, h),
            near: f64::from(lens.near),
        })
    }

    /// The eye, world metres.
    pub fn eye(&self) -> DVec3 {
        self.eye
    }

    /// The ray through the centre of pixel `(px, py)` (row 0 at the top): from the near
    /// plane, along a direction whose component along the view axis is 1.
    pub fn ray(&self, px: u32, py: u32) -> Ray {
        let (w, h) = self.size;
        let x = 2.0 * (f64::from(px) + 0.5) / f64::from(w) - 1.0;
        let y = 1.0 - 2.0 * (f64::from(py) + 0.5) / f64::from(h);
        let dir = self.forward + self.right * (x * self.half.0) + self.up * (y * self.half.1);
        Ray {
            origin: self.eye + dir * self.near,
            dir,
            max_dist: f64::INFINITY,
        }
    }
}

/// The ramp's colour at height `h` metres (`ramp` in `shade.wgsl`).
fn ramp(h: f32) -> Vec3 {
    let rgb = |s: &[f32; 4]| Vec3::new(s[1], s[2], s[3]);
    if h <= RAMP[0][0] {
        return rgb(&RAMP[0]);
    }
    for pair in RAMP.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        if h < b[0] {
            return rgb(a).lerp(rgb(b), (h - a[0]) / (b[0] - a[0]));
        }
    }
    rgb(&RAMP[RAMP.len() - 1])
}

/// The 8-bit RGBA colour of a fragment at height `height` metres with unit upward `normal`,
/// `distance` metres from the eye (`fs` in `shade.wgsl`, sRGB encoded, as an 8-bit unorm
/// target stores it).
pub fn shade(height: f64, normal: DVec3, distance: f64, fog_distance: f32) -> [u8; 4] {
    let sun = Vec3::from(SUN).normalize();
    let lambert = normal.as_vec3().dot(sun).max(0.0);
    let c = ramp(height as f32) * (0.30 + 0.95 * lambert);
    let fog = 1.0 - (-(distance as f32) / fog_distance.max(1.0)).exp();
    let c = c.lerp(Vec3::from(HAZE), 0.45 * fog);
    let unorm = |v: f32| (v.powf(1.0 / 2.2).clamp(0.0, 1.0) * 255.0).round() as u8;
    [unorm(c.x), unorm(c.y), unorm(c.z), 255]
}

/// How far below the surface a hit must lie to be on a wall, metres: far more than the
/// rounding of a hit on the surface, far less than any wall worth drawing.
const WALL_DEPTH: f64 = 1e-3;

/// Whether `hit` is where a ray enters the terrain's extent from the side under the surface (or
/// starts under it), rather than on the surface: the renderer draws no walls there.
fn on_a_wall(terrain: &Terrain, hit: &Hit) -> bool {
    let p = hit.point;
    terrain.height(p.x, p.y).is_ok_and(|h| p.z < h - WALL_DEPTH)
}

/// The smooth normal at world `(x, y)`: the samples' normals (by central differences, one-sided
/// on the border) blended bilinearly over the cell, as the renderer blends its vertices'
/// normals, so that the cells do not show as facets.
fn smooth_normal(terrain: &Terrain, x: f64, y: f64) -> DVec3 {
    let (w, h) = terrain.size();
    let (dx, dy) = terrain.spacing();
    let (cx, cy) = (f64::from(w - 1), f64::from(h - 1));
    let (u, v) = ((x / dx).clamp(0.0, cx), (y / dy).clamp(0.0, cy));
    let (i, j) = (u.floor().min(cx - 1.0), v.floor().min(cy - 1.0));
    let (a, b) = (u - i, v - j);
    let z = |i: f64, j: f64| terrain.height(i * dx, j * dy).unwrap_or(0.0);
    let at = |i: f64, j: f64| {
        let (w0, e0) = ((i - 1.0).max(0.0), (i + 1.0).min(cx));
        let (s0, n0) = ((j - 1.0).max(0.0), (j + 1.0).min(cy));
        let gx = (z(e0, j) - z(w0, j)) / ((e0 - w0) * dx);
        let gy = (z(i, n0) - z(i, s0)) / ((n0 - s0) * dy);
        DVec3::new(-gx, -gy, 1.0).normalize()
    };
    let n = at(i, j) * ((1.0 - a) * (1.0 - b))
        + at(i + 1.0, j) * (a * (1.0 - b))
        + at(i, j + 1.0) * ((1.0 - a) * b)
        + at(i + 1.0, j + 1.0) * (a * b);
    n.normalize()
}

/// The picture of `terrain` from `camera` through `lens`, `lens.width` x `lens.height` RGBA
/// pixels, rows top first, cast on `threads` threads (at least 1).
pub fn render(
    terrain: &Terrain,
    camera: &Camera,
    lens: &Lens,
    threads: usize,
) -> Result<image::RgbaImage, ViewError> {
    let pin = Pinhole::new(camera, lens)?;
    let fog = fog_distance(terrain);
    let (w, h) = (lens.width, lens.height);
    let mut buf = vec![0u8; w as usize * h as usize * 4];
    let row_bytes = w as usize * 4;
    let threads = threads.clamp(1, h as usize);
    // Rows dealt out in turn, so that each thread gets as much sky as ground.
    let mut shares: Vec<Vec<(u32, &mut [u8])>> = (0..threads).map(|_| Vec::new()).collect();
    for (y, row) in buf.chunks_exact_mut(row_bytes).enumerate() {
        shares[y % threads].push((y as u32, row));
    }
    let cast_rows = |rows: Vec<(u32, &mut [u8])>| -> Result<(), QueryError> {
        for (py, row) in rows {
            for (px, out) in row.chunks_exact_mut(4).enumerate() {
                let ray = pin.ray(px as u32, py);
                let rgba = match terrain.cast(&ray)? {
                    Some(hit) if !on_a_wall(terrain, &hit) => shade(
                        hit.point.z,
                        smooth_normal(terrain, hit.point.x, hit.point.y),
                        hit.point.distance(pin.eye),
                        fog,
                    ),
                    _ => [SKY_RGB8[0], SKY_RGB8[1], SKY_RGB8[2], 255],
                };
                out.copy_from_slice(&rgba);
            }
        }
        Ok(())
    };
    std::thread::scope(|s| {
        let mut shares = shares.into_iter();
        let first = shares.next().unwrap_or_default();
        let others: Vec<_> = shares.map(|rows| s.spawn(|| cast_rows(rows))).collect();
        let mut result = cast_rows(first);
        for t in others {
            let r = t.join().unwrap_or_else(|p| std::panic::resume_unwind(p));
            result = result.and(r);
        }
        result
    })?;
    Ok(image::RgbaImage::from_raw(w, h, buf).expect("the buffer holds w x h pixels"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::FRAC_PI_4;

    /// A flat terrain at height `z0`, `n` x `n` samples 10 m apart.
    fn flat(n: u32, z0: f32) -> Terrain {
        Terrain::new(n, n, 10.0, 10.0, &vec![z0; (n * n) as usize]).unwrap()
    }

    fn lens(width: u32, height: u32) -> Lens {
        Lens {
            width,
            height,
            fov_y_deg: 60.0,
            near: 1.0,
        }
    }

    const SKY: [u8; 4] = [SKY_RGB8[0], SKY_RGB8[1], SKY_RGB8[2], 255];

    #[test]
    fn level_camera_sees_sky_above_the_horizon_and_ground_below() {
        // 10 km of flat ground at 100 m, seen level from its south-west quarter at 200 m,
        // looking north-east: the horizon (the far edge, about 0.8 degrees down) lies just
        // under the middle row.
        let t = flat(1001, 100.0);
        let cam = Camera {
            eye: glam::Vec3::new(2000.0, 2000.0, 200.0),
            yaw: FRAC_PI_4,
            pitch: 0.0,
        };
        let img = render(&t, &cam, &lens(64, 36), 2).unwrap();
        for x in 0..64 {
            assert_eq!(img.get_pixel(x, 0).0, SKY, "top row at {x}");
            assert_eq!(img.get_pixel(x, 17).0, SKY, "above the horizon at {x}");
            assert_ne!(img.get_pixel(x, 19).0, SKY, "below the horizon at {x}");
            assert_ne!(img.get_pixel(x, 35).0, SKY, "bottom row at {x}");
        }
        // Flat ground: every ground pixel of a row has the same height and normal, so the
        // nearer rows (less haze) are darker than the far ones, and a row is uniform up to the
        // haze's change with distance across it.
        let near = img.get_pixel(32, 35).0;
        let far = img.get_pixel(32, 19).0;
        assert!(near[0] < far[0] && near[2] < far[2], "{near:?} {far:?}");
    }

    #[test]
    fn no_walls_are_drawn_under_the_edges() {
        // From west of a 100 m plateau, 50 m up, looking east: the rays below the plateau's
        // edge enter the extent under the surface, the others pass over it; all show the sky.
        let t = flat(101, 100.0);
        let cam = Camera {
            eye: glam::Vec3::new(-200.0, 500.0, 50.0),
            yaw: 0.0,
            pitch: 0.0,
        };
        let img = render(&t, &cam, &lens(32, 18), 1).unwrap();
        assert!(img.pixels().all(|p| p.0 == SKY));
        assert!(
            t.cast(&Pinhole::new(&cam, &lens(32, 18)).unwrap().ray(16, 17))
                .unwrap()
                .is_some()
        );
    }

    #[test]
    fn smooth_normals_of_a_plane_are_its_normal() {
        // z = 0.3 x - 0.2 y: central and one-sided differences are exact, inside and on the
        // border.
        let (w, h, dx, dy) = (9u32, 7u32, 10.0, 20.0);
        let z: Vec<f32> = (0..h)
            .flat_map(|r| (0..w).map(move |c| (c, h - 1 - r)))
            .map(|(c, j)| (0.3 * dx * f64::from(c) - 0.2 * dy * f64::from(j)) as f32)
            .collect();
        let t = Terrain::new(w, h, dx, dy, &z).unwrap();
        let want = DVec3::new(-0.3, 0.2, 1.0).normalize();
        for (x, y) in [
            (0.0, 0.0),
            (80.0, 120.0),
            (33.3, 57.1),
            (80.0, 5.0),
            (1.0, 120.0),
        ] {
            let n = smooth_normal(&t, x, y);
            assert!(n.distance(want) < 1e-6, "({x}, {y}): {n}");
        }
    }

    #[test]
    fn a_pixel_ray_hits_where_the_projection_puts_it() {
        let t = flat(201, 0.0);
        let cam = Camera {
            eye: glam::Vec3::new(1000.0, 500.0, 300.0),
            yaw: 1.0,
            pitch: -1.0,
        };
        let l = lens(320, 180);
        let pin = Pinhole::new(&cam, &l).unwrap();
        let view = relief_proto::view::ViewState::new(&cam, &l);
        let f = cam.forward().as_dvec3();
        let right = cam.forward().cross(glam::Vec3::Z).normalize().as_dvec3();
        let up = right.cross(f);
        for (px, py) in [(0, 0), (319, 179), (160, 90), (17, 150), (300, 101)] {
            let hit = t
                .cast(&pin.ray(px, py))
                .unwrap()
                .expect("looking down at the ground");
            assert!(hit.point.z.abs() < 1e-9);
            // Project the hit back as the renderer does: view depth, then the focal length.
            let rel = hit.point - pin.eye();
            let depth = rel.dot(f);
            let focal = f64::from(view.focal());
            let sx = 160.0 + focal * rel.dot(right) / depth;
            let sy = 90.0 - focal * rel.dot(up) / depth;
            assert!(
                (sx - (f64::from(px) + 0.5)).abs() < 1e-3
                    && (sy - (f64::from(py) + 0.5)).abs() < 1e-3,
                "pixel ({px}, {py}) projects back to ({sx}, {sy})"
            );
            assert!(depth >= 1.0, "the ray starts at the near plane");
        }
    }

    #[test]
    fn shading_follows_the_ramp_sun_and_haze() {
        let up = DVec3::Z;
        // Lowland green lit from above, no haze: 0.13 x (0.30 + 0.95 x 0.70 / |sun|).
        let sun = Vec3::from(SUN).normalize();
        let lit = 0.30 + 0.95 * sun.z;
        let want = |v: f32| ((v * lit).powf(1.0 / 2.2) * 255.0).round() as u8;
        assert_eq!(
            shade(0.0, up, 0.0, 1e4),
            [want(0.13), want(0.27), want(0.10), 255]
        );
        // Below sea level keeps the lowland green; above the top stop stays snow.
        assert_eq!(shade(-50.0, up, 0.0, 1e4), shade(0.0, up, 0.0, 1e4));
        assert_eq!(shade(9000.0, up, 0.0, 1e4), shade(3700.0, up, 0.0, 1e4));
        // Far away, the colour tends to the haze mixed at 45%.
        let far = shade(0.0, up, 1e9, 1e4);
        let haze = |g: f32, h: f32| (g * lit * 0.55 + 0.45 * h).powf(1.0 / 2.2) * 255.0;
        for (k, g) in [0.13, 0.27, 0.10].into_iter().enumerate() {
            let want = haze(g, HAZE[k]);
            assert!(
                (f32::from(far[k]) - want).abs() <= 0.51,
                "{far:?} channel {k}: {want}"
            );
        }
        // A face turned from the sun gets the ambient term only.
        let away = -sun.as_dvec3();
        let dark = shade(0.0, DVec3::new(away.x, away.y, 0.0).normalize(), 0.0, 1e4);
        assert!(dark[1] < shade(0.0, up, 0.0, 1e4)[1]);
    }

    #[test]
    fn bad_sizes_lenses_and_cameras_are_refused() {
        let t = flat(3, 0.0);
        let cam = Camera {
            eye: glam::Vec3::new(0.0, 0.0, 10.0),
            yaw: 0.0,
            pitch: -0.1,
        };
        assert_eq!(
            render(&t, &cam, &lens(0, 10), 1).unwrap_err(),
            ViewError::Size(0, 10)
        );
        assert_eq!(
            render(&t, &cam, &lens(2048, 1024), 1).unwrap_err(),
            ViewError::Size(2048, 1024)
        );
        let wide = Lens {
            fov_y_deg: 179.0,
            ..lens(8, 8)
        };
        assert_eq!(
            render(&t, &cam, &wide, 1).unwrap_err(),
            ViewError::Fov(179.0)
        );
        let up = Camera {
            pitch: std::f32::consts::FRAC_PI_2,
            ..cam
        };
        assert_eq!(
            render(&t, &up, &lens(8, 8), 1).unwrap_err(),
            ViewError::Camera
        );
    }

    #[test]
    fn threads_do_not_change_the_picture() {
        let z: Vec<f32> = (0..40 * 40)
            .map(|k| ((k * 37) % 23) as f32 * 20.0)
            .collect();
        let t = Terrain::new(40, 40, 25.0, 25.0, &z).unwrap();
        let cam = Camera {
            eye: glam::Vec3::new(-200.0, -300.0, 900.0),
            yaw: 0.8,
            pitch: -0.35,
        };
        let one = render(&t, &cam, &lens(96, 54), 1).unwrap();
        let three = render(&t, &cam, &lens(96, 54), 3).unwrap();
        assert!(one == three);
        assert!(one.pixels().any(|p| p.0 == SKY) && one.pixels().any(|p| p.0 != SKY));
    }
}
