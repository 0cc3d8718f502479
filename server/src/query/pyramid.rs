//! The max-mip and min-mip pyramids of paper 004 (section "Геометрическая модель", figure 4):
//! level n-1 holds the maximum (minimum) of 2 x 2 nodes of level n, up to one node holding the
//! whole map's.
//!
//! **Nodes cover cells, not samples.** The surface over a cell is the bilinear patch of its
//! four corner samples ([`super::surface`]), which never leaves their range, so what bounds a
//! ray over a cell is the max (min) of those four corners. A node at shift `s` covers the cells
//! `[x 2^s, (x+1) 2^s) x [y 2^s, (y+1) 2^s)` that exist, and holds the max (min) of every
//! corner sample of those cells: samples `x 2^s ..= min((x+1) 2^s, width-1)` in x, and the same
//! in y. Neighbouring nodes therefore share their border samples, exactly as neighbouring cells
//! share their edges; on grids that are not 2^n + 1 a side, the last node of a level covers
//! fewer cells and still every corner of them (nothing is padded, nothing is left out).
//!
//! Shift 0 (single cells) is not stored: its bound is the max of four corners, read from the
//! heights when needed. Shifts 1 and up are stored, so the pyramids hold about 2/3 of a
//! height per cell in all (max and min together). Each level is stored in tiles of 4 x 4
//! nodes, one 64-byte cache line of each array, so that the ray cast ([`super::ray`]),
//! stepping from a node to its neighbour east, west, north or south, mostly finds it in the
//! line it has just read (a level's last row and column of tiles are padded).
//!
//! Rows count from the south, as in [`super::Terrain`].

/// The max-mip and min-mip pyramids over a terrain's cells.
#[derive(Clone, Debug)]
pub struct Pyramid {
    /// Cells per row, to clip nodes at the east border.
    cells_x: u32,
    /// Cells per column, to clip nodes at the north border.
    cells_y: u32,
    /// Stored levels: `levels[k]` holds shift `k + 1`.
    levels: Vec<Level>,
}

/// One level of both pyramids, stored in tiles of 4 x 4 nodes (64 bytes of each array), so
/// that a ray stepping to a neighbouring node, north or east alike, mostly stays in the cache
/// line it has just read.
#[derive(Clone, Debug)]
struct Level {
    /// Nodes per row.
    w: u32,
    /// Nodes per column.
    h: u32,
    /// Tiles per row, to index the arrays.
    tiles: u32,
    /// The max over each node's samples: what a ray must stay above to skip the node.
    max: Vec<f32>,
    /// The min over each node's samples: a segment below it over a node is certainly under
    /// the ground there (the ray cast needs only the max; callers bound heights over areas).
    min: Vec<f32>,
}

impl Pyramid {
    /// Builds both pyramids over the `width` x `height` heights `z` (row-major from the south;
    /// at least 2 x 2 samples).
    pub fn build(z: &[f32], width: u32, height: u32) -> Pyramid {
        let (cx, cy) = (width - 1, height - 1);
        let mut levels: Vec<Level> = Vec::new();
        let top = top_shift(cx, cy);
        for s in 1..=top {
            let (w, h) = (cx.div_ceil(1 << s), cy.div_ceil(1 << s));
            let tiles = w.div_ceil(TILE);
            let n = (tiles * TILE) as usize * h.next_multiple_of(TILE) as usize;
            let (mut max, mut min) = (vec![f32::MIN; n], vec![f32::MAX; n]);
            match levels.last() {
                // Shift 1 from the samples: each node's cells' corners, up to 3 x 3 samples.
                None => {
                    for y in 0..h {
                        let (r0, r1) = (2 * y, (2 * y + 2).min(cy));
                        for x in 0..w {
                            let (c0, c1) = (2 * x, (2 * x + 2).min(cx));
                            let (mut hi, mut lo) = (f32::MIN, f32::MAX);
                            for r in r0..=r1 {
                                let row = &z[(r * width) as usize..][..width as usize];
                                for &v in &row[c0 as usize..=c1 as usize] {
                                    hi = hi.max(v);
                                    lo = lo.min(v);
                                }
                            }
                            let i = tiled(tiles, x, y);
                            (max[i], min[i]) = (hi, lo);
                        }
                    }
                }
                // Higher shifts from the level below: the nodes' children that exist.
                Some(below) => {
                    let bh = below.h;
                    for y in 0..h {
                        for x in 0..w {
                            let (mut hi, mut lo) = (f32::MIN, f32::MAX);
                            for ky in 2 * y..(2 * y + 2).min(bh) {
                                for kx in 2 * x..(2 * x + 2).min(below.w) {
                                    let k = tiled(below.tiles, kx, ky);
                                    hi = hi.max(below.max[k]);
                                    lo = lo.min(below.min[k]);
                                }
                            }
                            let i = tiled(tiles, x, y);
                            (max[i], min[i]) = (hi, lo);
                        }
                    }
                }
            }
            levels.push(Level {
                w,
                h,
                tiles,
                max,
                min,
            });
        }
        Pyramid {
            cells_x: cx,
            cells_y: cy,
            levels,
        }
    }

    /// The shift of the single root node, which covers every cell (0 for a single cell).
    pub fn top_shift(&self) -> u32 {
        self.levels.len() as u32
    }

    /// Nodes per row and per column at shift `s` (`s` up to [`Pyramid::top_shift`]).
    #[inline]
    pub fn dims(&self, s: u32) -> (u32, u32) {
        let up = |c: u32| ((u64::from(c) + (1u64 << s) - 1) >> s) as u32;
        (up(self.cells_x), up(self.cells_y))
    }

    /// The max of node `(x, y)` at shift `s >= 1`, metres.
    #[inline]
    pub fn max(&self, s: u32, x: u32, y: u32) -> f32 {
        let l = &self.levels[s as usize - 1];
        l.max[tiled(l.tiles, x, y)]
    }

    /// The min of node `(x, y)` at shift `s >= 1`, metres.
    #[inline]
    pub fn min(&self, s: u32, x: u32, y: u32) -> f32 {
        let l = &self.levels[s as usize - 1];
        l.min[tiled(l.tiles, x, y)]
    }

    /// Bytes held by both pyramids.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.max.len() * 8).sum()
    }
}

/// Nodes per side of a tile.
const TILE: u32 = 4;

/// Where node `(x, y)` lies in a level `tiles` tiles wide: its tile, row-major, then the node
/// in the tile, row-major.
#[inline]
fn tiled(tiles: u32, x: u32, y: u32) -> usize {
    let tile = (y / TILE) as usize * tiles as usize + (x / TILE) as usize;
    tile * (TILE * TILE) as usize + ((y % TILE) * TILE + x % TILE) as usize
}

/// The smallest shift at which a `cx` x `cy`-cell grid is one node.
fn top_shift(cx: u32, cy: u32) -> u32 {
    let n = cx.max(cy).max(1);
    n.next_power_of_two().trailing_zeros()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every node's max and min equal those of its cells' corner samples, on sizes that are
    /// not 2^n + 1.
    #[test]
    fn nodes_bound_their_cells_corners() {
        for (w, h) in [(2, 2), (3, 2), (5, 5), (6, 3), (9, 17), (12, 7)] {
            let z: Vec<f32> = (0..w * h)
                .map(|i| ((i * 7919) % 101) as f32 - 50.0)
                .collect();
            let p = Pyramid::build(&z, w, h);
            let (cx, cy) = (w - 1, h - 1);
            assert_eq!(p.dims(p.top_shift()), (1, 1));
            for s in 1..=p.top_shift() {
                let (nw, nh) = p.dims(s);
                for y in 0..nh {
                    for x in 0..nw {
                        let (c0, c1) = (x << s, ((x + 1) << s).min(cx));
                        let (r0, r1) = (y << s, ((y + 1) << s).min(cy));
                        let z = &z;
                        let samples =
                            (r0..=r1).flat_map(|r| (c0..=c1).map(move |c| z[(r * w + c) as usize]));
                        let hi = samples.clone().fold(f32::MIN, f32::max);
                        let lo = samples.fold(f32::MAX, f32::min);
                        assert_eq!((p.max(s, x, y), p.min(s, x, y)), (hi, lo), "{w}x{h} {s}");
                    }
                }
            }
        }
    }
}
