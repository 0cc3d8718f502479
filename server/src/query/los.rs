//! Line of sight between two points with a clearance: the sight line from `a` to `b` is
//! blocked where it first comes within `clearance` metres above the surface, i.e. where the
//! segment lowered by the clearance first meets the ground. That is a ray cast
//! ([`super::ray`]) from `a` towards `b`, as far as `b`, over the same max-mip pyramid, so the
//! blocking point is exact against the same surface.
//!
//! An endpoint on or under the ground (plus clearance) blocks the line at that endpoint:
//! entities asking for sight should give points above their footprint (an eye, a sensor).
//! Parts of the segment outside the terrain's extent are never blocked there.

use super::ray::{GridRay, Ray};
use super::{QueryError, Terrain};
use glam::DVec3;

/// What a line of sight found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sight {
    /// The whole segment stays more than the clearance above the ground.
    Visible,
    /// The segment comes within the clearance of the ground.
    Blocked {
        /// The first blocking point on the segment, world metres.
        point: DVec3,
        /// Its distance from `a`, metres.
        distance: f64,
    },
}

impl Sight {
    /// Whether the line is clear.
    pub fn is_visible(&self) -> bool {
        matches!(self, Sight::Visible)
    }
}

impl Terrain {
    /// Line of sight from `a` to `b` with `clearance` metres (finite, not negative).
    pub fn line_of_sight(&self, a: DVec3, b: DVec3, clearance: f64) -> Result<Sight, QueryError> {
        if !(a.is_finite() && b.is_finite() && clearance.is_finite()) {
            return Err(QueryError::NotFinite);
        }
        if clearance < 0.0 {
            return Err(QueryError::Negative(clearance));
        }
        self.check_reach(a, "the line's start")?;
        self.check_reach(b, "the line's end")?;
        let dir = b - a;
        if dir == DVec3::ZERO {
            // A point: blocked where it is within the clearance of the ground under it.
            return Ok(match self.height(a.x, a.y) {
                Ok(h) if a.z - clearance <= h => Sight::Blocked {
                    point: a,
                    distance: 0.0,
                },
                _ => Sight::Visible,
            });
        }
        let ray = Ray {
            origin: a,
            dir,
            max_dist: dir.length(),
        };
        let r = GridRay::new(self, &ray, clearance)?;
        Ok(match self.cast_grid(&r) {
            None => Sight::Visible,
            Some(h) => {
                let hit = self.hit(&r, h);
                Sight::Blocked {
                    point: hit.point,
                    distance: hit.distance,
                }
            }
        })
    }
}
