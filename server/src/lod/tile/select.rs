//! The restricted tile selection for one camera (paper 001, section 1; DESIGN.md section 4).
//!
//! **Plain rule.** From the root down, a tile is split while its screen error exceeds tau; a
//! tile split in the previous selection stays split until its error falls below
//! `tau * merge_ratio` (hysteresis, so that a camera at rest or jittering changes nothing).
//!
//! **Restriction.** Paper 001's theorem 1 shows that its distance rule keeps neighbours within
//! one level when the visible-distance/size ratio exceeds 3. Under a screen-space-error rule
//! that is not guaranteed (a rough far tile can need more detail than a flat near one), so the
//! selection enforces it: a split tile's same-level edge neighbours must exist, that is their
//! parents must be split. Split tiles are visited from the finest level up, and every missing
//! parent (and every split tile's own parent) is split too; each forced split can only force
//! splits one level up, so one pass suffices. The result is the coarsest restricted selection
//! that refines everything the plain rule refines.
//!
//! **The paper's ratio.** For an active tile `t` with parent `p`, the distance below which `p`
//! is refined plays the paper's `d_lod` (the upper end of `t`'s visible range): `error(p) *
//! focal / tau`. Its ratio to `t`'s size is what theorem 1 needs above 3. [`SelectStats`]
//! counts how often that already held, to compare with the forced splits.

use super::TileEngine;
use relief_proto::tile::{EDGES, TileId};
use relief_proto::view::ViewState;
use rustc_hash::{FxHashMap, FxHashSet};

/// Counters of one selection.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SelectStats {
    /// Tiles whose screen error was evaluated.
    pub visited: u64,
    /// Splits the restriction added to the plain rule's.
    pub forced: u64,
    /// Active tiles of the plain rule's selection (root excluded) with ratio > 3.
    pub ratio_gt_3: u64,
    /// Active tiles of the plain rule's selection (root excluded).
    pub ratio_tiles: u64,
}

/// A selection: the split tiles (the active ones are their children that are not split, or the
/// root alone when none is), and each evaluated tile's screen error.
#[derive(Clone, Debug, Default)]
pub struct Selection {
    /// Dense indices of the split tiles.
    pub split: FxHashSet<u32>,
    /// Screen error, pixels, of every evaluated tile.
    pub sse: FxHashMap<u32, f32>,
    /// Counters.
    pub stats: SelectStats,
}

impl TileEngine<'_> {
    /// The restricted selection for `view` at threshold `tau`, with hysteresis against the
    /// previous selection's split set `prev`.
    pub fn select(
        &self,
        view: &ViewState,
        tau: f32,
        merge_ratio: f32,
        prev: &FxHashSet<u32>,
    ) -> Selection {
        let shape = self.shape();
        let mut sel = Selection::default();
        let mut stack = vec![TileId::ROOT];
        let mut leaves = Vec::new();
        while let Some(t) = stack.pop() {
            let i = shape.index(t);
            if shape.is_leaf(t) {
                leaves.push(t);
                continue;
            }
            let e = self.screen_error(view, t, i);
            sel.stats.visited += 1;
            sel.sse.insert(i, e);
            let split = e > tau || (prev.contains(&i) && e > tau * merge_ratio);
            if split {
                sel.split.insert(i);
                stack.extend(shape.children(t));
            } else {
                leaves.push(t);
            }
        }
        for t in leaves {
            if let Some(p) = t.parent() {
                let d = self.record(shape.index(p)).error * view.focal() / tau;
                sel.stats.ratio_tiles += 1;
                if d > 3.0 * self.tile_size_m(t) {
                    sel.stats.ratio_gt_3 += 1;
                }
            }
        }
        sel.stats.forced = self.restrict(&mut sel.split);
        sel
    }

    /// Adds the splits that make `split` restricted; returns how many.
    pub fn restrict(&self, split: &mut FxHashSet<u32>) -> u64 {
        let shape = self.shape();
        let mut by_level: Vec<Vec<TileId>> = vec![Vec::new(); shape.depth() as usize + 1];
        for &i in split.iter() {
            if let Some(t) = shape.tile(i) {
                by_level[t.level as usize].push(t);
            }
        }
        let mut forced = 0;
        for level in (1..by_level.len()).rev() {
            let tiles = std::mem::take(&mut by_level[level]);
            for t in tiles {
                let needed = std::iter::once(t.parent())
                    .chain(
                        EDGES
                            .iter()
                            .map(|&e| shape.neighbour(t, e).and_then(|n| n.parent())),
                    )
                    .flatten();
                for p in needed {
                    if split.insert(shape.index(p)) {
                        forced += 1;
                        by_level[level - 1].push(p);
                    }
                }
            }
        }
        forced
    }

    /// The active tiles of split set `split`, ascending.
    pub fn active_of(&self, split: &FxHashSet<u32>) -> Vec<u32> {
        let shape = self.shape();
        if split.is_empty() {
            return vec![0];
        }
        let mut out = Vec::with_capacity(split.len() * 3);
        for &i in split {
            if let Some(t) = shape.tile(i) {
                out.extend(
                    shape
                        .children(t)
                        .map(|c| shape.index(c))
                        .filter(|c| !split.contains(c)),
                );
            }
        }
        out.sort_unstable();
        out
    }
}
