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
use super::bits::TileBits;
use relief_proto::tile::{EDGES, TileId};
use relief_proto::view::ViewState;

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
/// root alone when none is), and, when asked for, each evaluated tile's screen error.
#[derive(Clone, Debug, Default)]
pub struct Selection {
    /// The split tiles.
    pub split: TileBits,
    /// Screen error, pixels, of every evaluated tile (budgeted sessions only), by dense index.
    pub sse: Vec<(u32, f32)>,
    /// Counters.
    pub stats: SelectStats,
}

impl Selection {
    /// The screen error evaluated for tile `i` (0 if it was not).
    pub fn sse_of(&self, i: u32) -> f32 {
        self.sse
            .binary_search_by_key(&i, |e| e.0)
            .map_or(0.0, |k| self.sse[k].1)
    }
}

impl TileEngine<'_> {
    /// The restricted selection for `view` at threshold `tau`, with hysteresis against the
    /// previous selection's split set `prev`; `keep_sse` keeps each evaluated screen error.
    pub fn select(
        &self,
        view: &ViewState,
        tau: f32,
        merge_ratio: f32,
        prev: &TileBits,
        keep_sse: bool,
    ) -> Selection {
        let shape = self.shape();
        let mut sel = Selection {
            split: TileBits::new(shape.tile_count()),
            ..Selection::default()
        };
        let mut stack = vec![TileId::ROOT];
        let focal_over_tau = view.focal() / tau;
        while let Some(t) = stack.pop() {
            let i = shape.index(t);
            let split = !shape.is_leaf(t) && {
                let e = self.screen_error(view, i);
                sel.stats.visited += 1;
                if keep_sse {
                    sel.sse.push((i, e));
                }
                e > tau || (prev.contains(i) && e > tau * merge_ratio)
            };
            if split {
                sel.split.insert(i);
                stack.extend(shape.children(t));
            } else if let Some(p) = t.parent() {
                // The paper's ratio: the distance below which the parent is refined, over the
                // tile's size.
                let d = self.record(shape.index(p)).error * focal_over_tau;
                sel.stats.ratio_tiles += 1;
                if d > 3.0 * self.tile_size_m(i) {
                    sel.stats.ratio_gt_3 += 1;
                }
            }
        }
        sel.sse.sort_unstable_by_key(|e| e.0);
        sel.stats.forced = self.restrict(&mut sel.split);
        sel
    }

    /// Adds the splits that make `split` restricted; returns how many.
    pub fn restrict(&self, split: &mut TileBits) -> u64 {
        let shape = self.shape();
        let mut by_level: Vec<Vec<TileId>> = vec![Vec::new(); shape.depth() as usize + 1];
        for i in split.iter() {
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

    /// The active tiles of split set `split`: the root alone when none is split.
    pub fn active_of(&self, split: &TileBits) -> TileBits {
        let shape = self.shape();
        let mut out = TileBits::new(shape.tile_count());
        if split.is_empty() {
            out.insert(0);
            return out;
        }
        for i in split.iter() {
            if let Some(t) = shape.tile(i) {
                for c in shape.children(t) {
                    let ci = shape.index(c);
                    if !split.contains(ci) {
                        out.insert(ci);
                    }
                }
            }
        }
        out
    }
}
