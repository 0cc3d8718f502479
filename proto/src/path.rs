//! The standard and stress camera paths (DESIGN.md section 7): deterministic flythroughs
//! computed from the terrain's extent, shared by the benchmarks, the load generator and viewers.
//!
//! **Standard:** a closed loop at 10 Hz for 60 s (600 poses) around the terrain's centre, of radius
//! `min(0.3 * shorter side, 1910 m)` with a gentle three-lobed wobble, so a circuit is about
//! 12 km at about 200 m/s on large terrains; 100-300 m above the ground (smoothed so the camera
//! does not jolt), looking along the direction of travel and 10-20 degrees down.
//!
//! **Stress:** faster and lower: the same loop flown in 30 s (300 poses), 40-80 m above the ground,
//! 25-35 degrees down.
//!
//! **Random** (for load tests, [`random_path`]): a standard-like loop whose centre, radius,
//! direction and starting point come from a seed, so that many sessions fly distinct paths.

use crate::view::Camera;
use glam::Vec3;
use std::f32::consts::TAU;

/// Which path to fly.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathKind {
    /// The standard path.
    Standard,
    /// The faster, lower stress path.
    Stress,
}

impl std::str::FromStr for PathKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "standard" => Ok(PathKind::Standard),
            "stress" => Ok(PathKind::Stress),
            _ => Err(format!("unknown path {s:?}: use standard or stress")),
        }
    }
}

/// Poses per second of every path.
pub const PATH_HZ: f32 = 10.0;

/// The poses of `kind` over a terrain of `extent_x` by `extent_y` metres (origin at the south-west
/// corner), with `ground(x, y)` the terrain height in metres.
pub fn camera_path(
    kind: PathKind,
    extent_x: f32,
    extent_y: f32,
    ground: impl Fn(f32, f32) -> f32,
) -> Vec<Camera> {
    let radius = (0.3 * extent_x.min(extent_y)).min(1910.0);
    let centre = Vec3::new(extent_x / 2.0, extent_y / 2.0, 0.0);
    loop_path(kind, centre, radius, 1.0, 0.0, ground)
}

/// A standard-paced loop for load tests: centre, radius (0.15-0.3 of the shorter side, at most
/// 1910 m), direction and starting phase drawn from `seed` (splitmix64), so that sessions with
/// different seeds fly different paths over the same terrain.
pub fn random_path(
    seed: u64,
    extent_x: f32,
    extent_y: f32,
    ground: impl Fn(f32, f32) -> f32,
) -> Vec<Camera> {
    let mut state = seed;
    let mut next = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    };
    let short = extent_x.min(extent_y);
    let radius = ((0.15 + 0.15 * next()) * short).min(1910.0);
    // Keep the loop (with its 15 % wobble) inside the terrain.
    let margin = (radius * 1.15).min(short / 2.0);
    let cx = margin + (extent_x - 2.0 * margin).max(0.0) * next();
    let cy = margin + (extent_y - 2.0 * margin).max(0.0) * next();
    let direction = if next() < 0.5 { 1.0 } else { -1.0 };
    let phase = next();
    loop_path(
        PathKind::Standard,
        Vec3::new(cx, cy, 0.0),
        radius,
        direction,
        phase,
        ground,
    )
}

/// The loop of `kind`'s pace and heights around `centre`, counter-clockwise for `direction` 1
/// (clockwise for -1), starting `phase` of a turn in.
fn loop_path(
    kind: PathKind,
    centre: Vec3,
    radius: f32,
    direction: f32,
    phase: f32,
    ground: impl Fn(f32, f32) -> f32,
) -> Vec<Camera> {
    let (seconds, agl_lo, agl_hi, pitch_lo, pitch_hi) = match kind {
        PathKind::Standard => (60.0, 100.0, 300.0, 10.0f32, 20.0f32),
        PathKind::Stress => (30.0, 40.0, 80.0, 25.0, 35.0),
    };
    let n = (seconds * PATH_HZ) as usize;
    let at = |t: f32| {
        let th = direction * TAU * (t + phase);
        let r = radius * (1.0 + 0.15 * (3.0 * th).sin());
        centre + Vec3::new(r * th.cos(), r * th.sin(), 0.0)
    };
    // Ground under and just ahead of each pose, then smoothed over +-2 s around the loop.
    let look = 1.0 / n as f32;
    let raw: Vec<f32> = (0..n)
        .map(|i| {
            let t = i as f32 / n as f32;
            (0..3)
                .map(|k| {
                    let p = at(t + k as f32 * look);
                    ground(p.x, p.y)
                })
                .fold(f32::MIN, f32::max)
        })
        .collect();
    let win = (2.0 * PATH_HZ) as isize;
    (0..n)
        .map(|i| {
            let t = i as f32 / n as f32;
            let smooth = (-win..=win)
                .map(|d| raw[(i as isize + d).rem_euclid(n as isize) as usize])
                .sum::<f32>()
                / (2 * win + 1) as f32;
            let wave = 0.5 + 0.5 * (2.0 * TAU * t).sin();
            let agl = agl_lo + (agl_hi - agl_lo) * wave;
            let pos = at(t);
            let z = (smooth + agl).max(raw[i] + agl_lo);
            let ahead = at(t + look) - pos;
            let pitch = pitch_lo + (pitch_hi - pitch_lo) * (0.5 + 0.5 * (3.0 * TAU * t).cos());
            Camera {
                eye: Vec3::new(pos.x, pos.y, z),
                yaw: ahead.y.atan2(ahead.x),
                pitch: -pitch.to_radians(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standard_path_is_a_closed_loop_above_ground() {
        let ground = |x: f32, y: f32| (x * 0.001).sin() * 300.0 + (y * 0.002).cos() * 200.0 + 500.0;
        let p = camera_path(PathKind::Standard, 40_000.0, 30_000.0, ground);
        assert_eq!(p.len(), 600);
        for c in &p {
            let agl = c.eye.z - ground(c.eye.x, c.eye.y);
            assert!((99.0..=700.0).contains(&agl), "{agl}");
            assert!(c.is_valid());
            let down = -c.pitch.to_degrees();
            assert!((10.0..=20.0).contains(&down));
        }
        let step = (p[1].eye - p[0].eye).truncate().length();
        let close = (p[599].eye - p[0].eye).truncate().length();
        assert!(close < 2.0 * step, "loop does not close: {close} vs {step}");
        assert_eq!(
            p,
            camera_path(PathKind::Standard, 40_000.0, 30_000.0, ground)
        );
    }

    #[test]
    fn random_paths_differ_by_seed_and_stay_over_the_terrain() {
        let ground = |x: f32, y: f32| (x * 0.001).sin() * 300.0 + (y * 0.002).cos() * 200.0 + 500.0;
        let (ex, ey) = (40_000.0, 30_000.0);
        let a = random_path(1, ex, ey, ground);
        let b = random_path(2, ex, ey, ground);
        assert_eq!(a.len(), 600);
        assert_ne!(a[0].eye, b[0].eye);
        assert_eq!(a, random_path(1, ex, ey, ground), "deterministic");
        for c in a.iter().chain(&b) {
            assert!(c.is_valid());
            assert!(
                (0.0..=ex).contains(&c.eye.x) && (0.0..=ey).contains(&c.eye.y),
                "{c:?}"
            );
            assert!(c.eye.z - ground(c.eye.x, c.eye.y) >= 99.0);
        }
    }
}
