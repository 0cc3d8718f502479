//! Where a client draws each active node: the geomorph of paper 000, section 3.6, applied down
//! the whole chain of ancestors, with an age cap for splits that arrive late.
//!
//! **The paper's rule.** The four children of a node `p` slide linearly towards `p` as `p`'s
//! screen error falls from `lambda * tau` to `tau` ([`crate::view::morph_alpha`]). The server
//! merges only below `tau * merge_ratio`, so merging children have reached their parent.
//!
//! **Chains.** A child may itself have children in flight. For a merge never to pop, a node
//! must slide towards where its parent is *drawn*, not where its parent would stand at rest:
//! with `D(root) = P(root)` and `D(n) = D(p) + alpha(p) * (P(n) - D(p))`, a node whose parent
//! reaches alpha 0 stands exactly on the parent's drawn position, which is where the parent
//! will be drawn once the merge lands. [`drawn_position`] evaluates this walking up from the
//! node and stops at the first ancestor with alpha 1 (usually one or two levels up).
//!
//! **Late splits.** The server refines as deep as a pose needs in one update (see
//! `docs/vertex-stream.md`), so a node can split when its error is already past `lambda * tau`;
//! with the error-driven alpha alone its children would jump into place. So the alpha of a node
//! is also capped by its age since the client applied its split, rising linearly over
//! [`MorphRule::duration`]: children are born on their parent and grow out of it. The paper
//! drives alpha by error alone; this cap only ever lowers it, and only for a short time.
//!
//! The renderer's compute shader (`client/src/render/terrain.wgsl`) evaluates the same formula
//! per frame on the GPU; this module is its reference, used by tests and benchmarks.

use crate::haar::error_value;
use crate::mirror::Mirror;
use crate::terrain::TerrainGeometry;
use crate::tree::NodeId;
use crate::view::{ViewState, morph_alpha};
use glam::Vec3;

/// The parameters of the geomorph.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MorphRule {
    /// The split threshold, pixels: alpha reaches 0 here.
    pub tau: f32,
    /// Children start to slide at `lambda * tau` (> 1).
    pub lambda: f32,
    /// Seconds over which a fresh split's children grow out of their parent (0: no cap).
    pub duration: f32,
}

impl MorphRule {
    /// The default rule at `tau`: lambda 1.5, a quarter-second growth.
    pub fn new(tau: f32) -> MorphRule {
        MorphRule {
            tau,
            lambda: 1.5,
            duration: 0.25,
        }
    }

    /// Alpha of the children of a node whose screen error is `e_scr` and whose split is `age`
    /// seconds old.
    pub fn alpha(&self, e_scr: f32, age: f32) -> f32 {
        let by_error = morph_alpha(e_scr, self.tau, self.lambda);
        if self.duration > 0.0 {
            by_error.min((age / self.duration).clamp(0.0, 1.0))
        } else {
            by_error
        }
    }
}

/// The drawn position of `node` (held by `mirror`) seen from `view`. `age` gives the seconds
/// since a node's split was applied (`f32::INFINITY` when it does not matter).
pub fn drawn_position(
    geom: &TerrainGeometry,
    mirror: &Mirror,
    view: &ViewState,
    rule: &MorphRule,
    node: NodeId,
    age: impl Fn(NodeId) -> f32,
) -> Vec3 {
    let pos = |n: NodeId| mirror.node(geom, n).map(|d| geom.world_pos(n, d.z));
    let mut out = Vec3::ZERO;
    let mut weight = 1.0f32;
    let mut cur = node;
    loop {
        let own = pos(cur).unwrap_or(Vec3::ZERO);
        let Some(parent) = cur.parent() else {
            return out + own * weight;
        };
        let Some(pd) = mirror.node(geom, parent) else {
            return out + own * weight;
        };
        let e = error_value(pd.err_code);
        let b = geom.node_box(parent, pd.z, pd.err_code);
        let a = rule.alpha(view.screen_error(&b, e), age(parent));
        out += own * (weight * a);
        weight *= 1.0 - a;
        if weight <= 0.0 {
            return out;
        }
        cur = parent;
    }
}
