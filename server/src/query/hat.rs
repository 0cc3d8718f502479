//! Height of terrain (HOT) and height above terrain (HAT) for many entities, as CIGI's HAT/HOT
//! requests ask them: for an entity at `(x, y, z)`, the surface height under it, its height
//! above that, and the surface normal there (for vehicles that settle on the ground). The
//! surface is the bilinear one every query uses ([`super::surface`]).

use super::{QueryError, Terrain};
use glam::DVec3;

/// The ground under an entity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HatHot {
    /// Height of terrain under the entity, metres.
    pub hot: f64,
    /// Height of the entity above it, metres (negative when below the ground).
    pub hat: f64,
    /// The surface's unit upward normal under the entity.
    pub normal: DVec3,
}

impl Terrain {
    /// HAT and HOT of an entity at world `p`.
    pub fn hat_hot(&self, p: DVec3) -> Result<HatHot, QueryError> {
        if !p.z.is_finite() {
            return Err(QueryError::NotFinite);
        }
        let s = self.surface(p.x, p.y)?;
        Ok(HatHot {
            hot: s.height,
            hat: p.z - s.height,
            normal: s.normal,
        })
    }

    /// HAT and HOT of every entity in `entities`, one answer each, into `out` (cleared first).
    pub fn hat_hot_many(&self, entities: &[DVec3], out: &mut Vec<Result<HatHot, QueryError>>) {
        out.clear();
        out.extend(entities.iter().map(|&p| self.hat_hot(p)));
    }
}
