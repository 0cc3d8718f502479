//! The viewer's fly camera: keys held move it, mouse drags turn it; speeds scale with the
//! terrain; an optional follow-ground mode keeps a constant height above the ground.

use glam::Vec3;
use relief_proto::view::Camera;

/// Which movement keys are held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Held {
    /// Forward (W, Up).
    pub forward: bool,
    /// Back (S, Down).
    pub back: bool,
    /// Left (A, Left).
    pub left: bool,
    /// Right (D, Right).
    pub right: bool,
    /// Up (E, PageUp).
    pub up: bool,
    /// Down (Q, PageDown).
    pub down: bool,
    /// Five times faster (Shift).
    pub fast: bool,
    /// Five times slower (Ctrl).
    pub slow: bool,
}

/// A camera flown by hand.
#[derive(Clone, Copy, Debug)]
pub struct FlyCamera {
    /// The pose.
    pub camera: Camera,
    /// Base speed, metres per second.
    pub speed: f32,
    /// Height above the ground kept in follow-ground mode; `None` when off.
    pub follow: Option<f32>,
}

/// Radians of turn per pixel of mouse drag.
const TURN_PER_PIXEL: f32 = 0.003;
/// The steepest pitch allowed, radians (just short of straight up or down).
const MAX_PITCH: f32 = 1.55;
/// The least height above ground in follow mode, metres.
const MIN_CLEARANCE: f32 = 5.0;

impl FlyCamera {
    /// A camera over a terrain of `extent` metres with heights up to `z_max`: south of the
    /// centre, above the highest point, looking north and down.
    pub fn over(extent: (f32, f32), z_max: f32) -> FlyCamera {
        let size = extent.0.max(extent.1).max(1.0);
        FlyCamera {
            camera: Camera {
                eye: Vec3::new(extent.0 / 2.0, -0.1 * extent.1, z_max + 0.25 * size),
                yaw: std::f32::consts::FRAC_PI_2,
                pitch: -0.45,
            },
            speed: (size / 60.0).clamp(20.0, 2000.0),
            follow: None,
        }
    }

    /// Moves for `dt` seconds with `held` keys; `ground` is the height under the eye, if known.
    pub fn step(&mut self, dt: f32, held: Held, ground: Option<f32>) {
        let mut speed = self.speed;
        if held.fast {
            speed *= 5.0;
        }
        if held.slow {
            speed /= 5.0;
        }
        let (sy, cy) = self.camera.yaw.sin_cos();
        let ahead = Vec3::new(cy, sy, 0.0);
        let right = Vec3::new(sy, -cy, 0.0);
        let axis = |a: bool, b: bool| f32::from(u8::from(a)) - f32::from(u8::from(b));
        let mut v = ahead * axis(held.forward, held.back) + right * axis(held.right, held.left);
        if v.length_squared() > 0.0 {
            v = v.normalize();
        }
        let climb = axis(held.up, held.down);
        self.camera.eye += v * speed * dt;
        match (self.follow.as_mut(), ground) {
            (Some(clearance), Some(g)) => {
                *clearance = (*clearance + climb * speed * dt).max(MIN_CLEARANCE);
                self.camera.eye.z = g + *clearance;
            }
            _ => self.camera.eye.z += climb * speed * dt,
        }
    }

    /// Turns by a mouse drag of `dx`, `dy` pixels (right and down are positive).
    pub fn turn(&mut self, dx: f32, dy: f32) {
        self.camera.yaw -= dx * TURN_PER_PIXEL;
        self.camera.yaw = self.camera.yaw.rem_euclid(std::f32::consts::TAU);
        self.camera.pitch = (self.camera.pitch - dy * TURN_PER_PIXEL).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Turns follow-ground mode on (keeping the present height above `ground`) or off.
    pub fn toggle_follow(&mut self, ground: Option<f32>) {
        self.follow = match (self.follow, ground) {
            (None, Some(g)) => Some((self.camera.eye.z - g).max(MIN_CLEARANCE)),
            _ => None,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_turns_and_follows_the_ground() {
        let mut c = FlyCamera::over((10_000.0, 8_000.0), 500.0);
        assert!(c.camera.is_valid());
        let start = c.camera.eye;
        let held = Held {
            forward: true,
            ..Held::default()
        };
        c.step(1.0, held, None);
        // Looking north: forward is +y, at the base speed.
        assert!((c.camera.eye.y - start.y - c.speed).abs() < 1e-2);
        assert!((c.camera.eye.x - start.x).abs() < 1e-2);
        let fast = Held { fast: true, ..held };
        let y = c.camera.eye.y;
        c.step(1.0, fast, None);
        assert!((c.camera.eye.y - y - 5.0 * c.speed).abs() < 1e-1);
        c.turn(0.0, 10_000.0);
        assert!(c.camera.pitch >= -MAX_PITCH && c.camera.is_valid());
        c.camera.eye.z = 300.0;
        c.toggle_follow(Some(100.0));
        assert_eq!(c.follow, Some(200.0));
        c.step(0.1, Held::default(), Some(150.0));
        assert_eq!(c.camera.eye.z, 350.0, "keeps 200 m above the new ground");
        c.toggle_follow(Some(150.0));
        assert_eq!(c.follow, None);
    }
}
