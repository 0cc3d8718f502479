//! A [`Scene`] that follows a [`Session`]: each call applies the splits and merges the session
//! applied since the last one, or rebuilds when the session started again from the root.

use crate::session::Session;
use relief_proto::mesh::scene::Scene;

/// A scene and the session generation it reflects.
pub struct Follower {
    /// The records.
    pub scene: Scene,
    /// The session's generation the records belong to.
    generation: u64,
}

impl Follower {
    /// The scene of what `session` holds now. The session must record its changes
    /// (`SessionConfig::record_changes`).
    pub fn new(session: &mut Session) -> Follower {
        let _ = session.take_changes();
        let generation = session.generation();
        let (geom, mirror, mesh) = session.parts_mut();
        Follower {
            scene: Scene::build(geom, mirror, mesh),
            generation,
        }
    }

    /// Applies what `session` changed since the last call, stamping new splits with `now`;
    /// returns the number of splits and merges applied (or of held nodes, after a rebuild).
    pub fn sync(&mut self, session: &mut Session, now: f32) -> usize {
        let changes = session.take_changes();
        if session.generation() != self.generation {
            *self = Follower::new(session);
            return self.scene.held_count();
        }
        let (geom, mirror, mesh) = session.parts_mut();
        self.scene.apply(geom, mirror, mesh, &changes, now);
        changes.len()
    }
}
