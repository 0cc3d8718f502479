//! Why a shot shows no terrain, in words: a camera under the ground, one that looks away from
//! the terrain, or one too far outside it. `relief-client shot` prints these as warnings, so that
//! a plain sky image never comes without a reason.

use crate::flight::extent;
use crate::http::{self, HttpError};
use glam::Vec3;
use relief_proto::msg::TerrainInfo;
use relief_proto::view::{Aabb, Camera, Lens, ViewState};

/// Below this fraction of pixels differing from the background, a shot "shows no terrain".
const EMPTY_FRACTION: f64 = 0.001;

/// The fraction of `img`'s pixels that differ from `background` (8-bit RGB) by more than 2 in
/// some channel: what the terrain covers.
pub fn coverage(img: &image::RgbaImage, background: [u8; 3]) -> f64 {
    let n = img.pixels().len().max(1);
    let drawn = img
        .pixels()
        .filter(|p| (0..3).any(|c| p.0[c].abs_diff(background[c]) > 2))
        .count();
    drawn as f64 / n as f64
}

/// The ground height under `(x, y)` from the server's `POST /v1/heights`, or `None` outside the
/// terrain.
pub async fn ground_at(
    stream_url: &str,
    info: &TerrainInfo,
    x: f32,
    y: f32,
) -> Result<Option<f32>, HttpError> {
    let (w, h) = extent(info);
    if !(0.0..=w).contains(&x) || !(0.0..=h).contains(&y) {
        return Ok(None);
    }
    let url = format!("{}/v1/heights", http::base_of(stream_url)?);
    let v = http::post_json(&url, &serde_json::json!({ "points": [[x, y]] })).await?;
    Ok(v["heights"][0].as_f64().map(|z| z as f32))
}

/// Whether `b`'s centre or a corner is in view, or a ray through some point of a 33 x 19 grid over
/// the image meets `b` in front of the eye (the frustum-and-box test of culling is conservative: a box behind and below a camera
/// that looks up passes it).
fn sees(camera: &Camera, lens: &Lens, b: &Aabb) -> bool {
    let [forward, right, up] = ViewState::new(camera, lens).basis();
    let (tx, ty) = lens.half_tangents();
    let e = camera.eye;
    let hits = |d: Vec3| {
        let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
        for k in 0..3 {
            let (o, d, lo, hi) = (e[k], d[k], b.min[k], b.max[k]);
            if d.abs() < 1e-12 {
                if o < lo || o > hi {
                    return false;
                }
            } else {
                let (a, c) = ((lo - o) / d, (hi - o) / d);
                t0 = t0.max(a.min(c));
                t1 = t1.min(a.max(c));
            }
        }
        t0 <= t1
    };
    // A point of the box in view (its centre or a corner): a small, far box slips between rays.
    let in_view = |p: Vec3| {
        let r = p - e;
        let z = r.dot(forward);
        z > 0.0 && r.dot(right).abs() <= z * tx && r.dot(up).abs() <= z * ty
    };
    let points = (0..8).map(|k| {
        Vec3::select(
            glam::BVec3::new(k & 1 != 0, k & 2 != 0, k & 4 != 0),
            b.max,
            b.min,
        )
    });
    if std::iter::once((b.min + b.max) / 2.0)
        .chain(points)
        .any(in_view)
    {
        return true;
    }
    (0..=32).any(|i| {
        (0..=18).any(|j| {
            let u = i as f32 / 16.0 - 1.0;
            let v = j as f32 / 9.0 - 1.0;
            hits(forward + right * (u * tx) + up * (v * ty))
        })
    })
}

/// Warnings for a shot from `camera` that covered `coverage` of the image, given the ground
/// height under the camera (`None` outside the terrain). Empty when nothing looks wrong.
pub fn warnings(
    info: &TerrainInfo,
    camera: &Camera,
    lens: &Lens,
    ground: Option<f32>,
    coverage: f64,
) -> Vec<String> {
    let e = camera.eye;
    let at = format!("({:.0}, {:.0})", e.x, e.y);
    let empty = coverage < EMPTY_FRACTION;
    let shows = if empty {
        "the image shows no terrain"
    } else {
        "the image shows the terrain from below"
    };
    let mut out = Vec::new();
    if let Some(g) = ground
        && e.z < g
    {
        out.push(format!(
            "the camera is {:.0} m below the ground at {at} (ground {g:.0} m, camera {:.0} m): {shows}; raise z above {g:.0}",
            g - e.z,
            e.z
        ));
        return out;
    }
    if !empty {
        return out;
    }
    let (w, h) = extent(info);
    let [lo, hi] = info.height_range;
    let terrain = Aabb {
        min: Vec3::new(0.0, 0.0, lo),
        max: Vec3::new(w, h, hi),
    };
    let spans =
        format!("the terrain spans x 0..{w:.0} m, y 0..{h:.0} m, heights {lo:.0}..{hi:.0} m");
    let outside = {
        let dx = (-e.x).max(e.x - w).max(0.0);
        let dy = (-e.y).max(e.y - h).max(0.0);
        (dx * dx + dy * dy).sqrt()
    };
    let cam = format!("the camera at {at}, {:.0} m high,", e.z);
    let off = format!("is {:.1} km outside the terrain", outside / 1000.0);
    out.push(match (sees(camera, lens, &terrain), outside > 0.0) {
        (false, true) => format!(
            "{cam} {off} and looks away from it: the image shows no terrain ({spans}; yaw is degrees counter-clockwise from east, negative pitch looks down)"
        ),
        (false, false) => format!(
            "{cam} looks away from the terrain: the image shows no terrain ({spans}; yaw is degrees counter-clockwise from east, negative pitch looks down)"
        ),
        (true, true) => format!(
            "{cam} {off}: the image shows no terrain (too far or too small to cover a pixel; {spans})"
        ),
        (true, false) => {
            format!("{cam} sees no terrain: the image is the background alone ({spans})")
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info() -> TerrainInfo {
        TerrainInfo {
            width: 1001,
            height: 1001,
            spacing_x: 10.0,
            spacing_y: 10.0,
            height_range: [100.0, 900.0],
            id: 1,
            z_quantum: 0.1,
            root_z: 0,
        }
    }

    fn cam(x: f32, y: f32, z: f32, yaw: f32, pitch: f32) -> Camera {
        Camera {
            eye: Vec3::new(x, y, z),
            yaw: yaw.to_radians(),
            pitch: pitch.to_radians(),
        }
    }

    #[test]
    fn under_the_ground_says_how_deep() {
        let w = warnings(
            &info(),
            &cam(500.0, 600.0, 280.0, 0.0, -20.0),
            &Lens::STANDARD,
            Some(400.0),
            0.0,
        );
        assert_eq!(w.len(), 1);
        assert!(
            w[0].starts_with("the camera is 120 m below the ground at (500, 600)"),
            "{w:?}"
        );
    }

    #[test]
    fn looking_away_and_far_outside_are_told_apart() {
        let away = warnings(
            &info(),
            &cam(-2000.0, 5000.0, 1000.0, 180.0, -10.0),
            &Lens::STANDARD,
            None,
            0.0,
        );
        assert!(away[0].contains("2.0 km outside") && away[0].contains("looks away"));
        let up = warnings(
            &info(),
            &cam(5000.0, 5000.0, 1000.0, 0.0, 80.0),
            &Lens::STANDARD,
            Some(500.0),
            0.0,
        );
        assert!(up[0].contains("looks away"), "{up:?}");
        let far = warnings(
            &info(),
            &cam(-900_000.0, 5000.0, 1000.0, 0.0, 0.0),
            &Lens::STANDARD,
            None,
            0.0,
        );
        assert!(far[0].contains("too far"), "{far:?}");
    }

    #[test]
    fn a_shot_with_terrain_in_it_gives_no_warning() {
        let w = warnings(
            &info(),
            &cam(-2000.0, 5000.0, 3000.0, 0.0, -20.0),
            &Lens::STANDARD,
            None,
            0.4,
        );
        assert!(w.is_empty());
    }

    #[test]
    fn coverage_counts_pixels_unlike_the_background() {
        let mut img = image::RgbaImage::from_pixel(10, 10, image::Rgba([10, 20, 30, 255]));
        img.put_pixel(0, 0, image::Rgba([10, 20, 31, 255]));
        assert_eq!(coverage(&img, [10, 20, 30]), 0.0);
        img.put_pixel(1, 0, image::Rgba([90, 20, 30, 255]));
        assert_eq!(coverage(&img, [10, 20, 30]), 0.01);
    }
}
