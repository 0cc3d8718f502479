//! Stitching `rqt` tiles that share edges: a border vertex has one triangle in
//! each tile, so each tile alone gives it a threshold from its own side. Raising both to the
//! larger and re-saturating, until nothing changes, makes tiles of one level meet vertex for
//! vertex at any tolerance they share; raising only adds vertices, so each tile stays
//! restricted and within tolerance.

use super::{Pos, RqtErrors};
use relief_proto::tile::Edge;
use std::collections::BinaryHeap;

impl RqtErrors {
    /// Raises the thresholds of `raises` (`[col, row]`, value) to at least their values and
    /// re-saturates; returns whether any threshold changed. Raising keeps the mesh
    /// restricted and within tolerance; it only adds vertices.
    pub fn raise(&mut self, raises: impl IntoIterator<Item = (Pos, f32)>) -> bool {
        let mut heap = BinaryHeap::new();
        for (p, t) in raises {
            let i = self.index(p);
            if t > self.thr[i] {
                self.thr[i] = t;
                heap.push((t.to_bits(), i as u32));
            }
        }
        let changed = !heap.is_empty();
        self.saturate(heap);
        changed
    }

    /// The positions along `edge` of the grid, west to east or north to south.
    pub fn edge(&self, edge: Edge) -> Vec<Pos> {
        let s = self.side;
        (0..=s)
            .map(|i| match edge {
                Edge::North => [i, 0],
                Edge::South => [i, s],
                Edge::West => [0, i],
                Edge::East => [s, i],
            })
            .collect()
    }
}

/// Makes a row-major block of tiles (`cols` per row, all of one side, each sharing its east
/// edge with the next tile's west edge and its south edge with the west edge of the tile
/// `cols` further on) agree along every shared edge: each shared vertex gets the larger of
/// its two thresholds, and each tile re-saturates, until nothing changes. Returns the number
/// of passes.
pub fn stitch(tiles: &mut [RqtErrors], cols: usize) -> usize {
    let mut passes = 0;
    loop {
        passes += 1;
        let mut changed = false;
        for i in 0..tiles.len() {
            let east = (cols > 0 && (i + 1) % cols != 0 && i + 1 < tiles.len()).then_some(i + 1);
            let south = (i + cols < tiles.len()).then_some(i + cols);
            for (j, mine, theirs) in [
                (east, Edge::East, Edge::West),
                (south, Edge::South, Edge::North),
            ] {
                let Some(j) = j else { continue };
                let (a, b) = (&tiles[i], &tiles[j]);
                let pairs: Vec<(Pos, Pos, f32)> = a
                    .edge(mine)
                    .into_iter()
                    .zip(b.edge(theirs))
                    .map(|(p, q)| (p, q, a.threshold(p).max(b.threshold(q))))
                    .collect();
                changed |= tiles[i].raise(pairs.iter().map(|&(p, _, t)| (p, t)));
                changed |= tiles[j].raise(pairs.iter().map(|&(_, q, t)| (q, t)));
            }
        }
        if !changed {
            return passes;
        }
    }
}
