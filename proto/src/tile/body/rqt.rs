//! The `rqt` mesh (paper 002, figure 6) and its blob: the restricted quadtree's shape as one bit
//! per visited midpoint, each new vertex's height as a residual from its hypotenuse's midpoint.
//!
//! **Recursion** ([`rqt_triangles`]). Over a square lattice of `side` cells (a power of two) the
//! two root triangles share the north-west to south-east diagonal; a triangle with apex `c` and
//! hypotenuse `a-b` splits at the hypotenuse's midpoint `m`, when `m` is active, into `(m, c, b)`
//! and `(m, a, c)`, depth first from a stack. The server decides which midpoints are active
//! (from its saturated errors); the client replays the same recursion from the bits, so both
//! get the same vertices in the same order and the same triangles.
//!
//! **Blob** (after the 2-bit mesh kind 1): the lowest height as 32 bits (two's complement), a
//! 4-bit order `k`, the four corners' heights above the lowest (north-west, north-east,
//! south-west, south-east) as order-`k` codes, then, in the recursion's order, at the first
//! visit of each midpoint one bit (1 = active) and for an active one the signed order-`k` code
//! of its height minus `floor((z_a + z_b) / 2)`. The lattice is the tile's (its span must be
//! square with `2^k + 1` vertices a side), so vertex `[i, j]` stands on sample offset
//! `[i * stride, j * stride]`.

use super::{IrregularMesh, MeshKind, TileBodyError, finished, mesh_header};
use crate::bits::{BitReader, best_order, zigzag};
use crate::tile::TileSpan;

/// A lattice position `[col, row]`.
pub type Pos = [u32; 2];

/// Twice the signed area of triangle `a b c` in world axes (x = col, y = -row): positive when
/// counter-clockwise seen from above.
#[inline]
pub fn area2(a: Pos, b: Pos, c: Pos) -> i64 {
    let (ax, ay) = (i64::from(a[0]), -i64::from(a[1]));
    let (bx, by) = (i64::from(b[0]), -i64::from(b[1]));
    let (cx, cy) = (i64::from(c[0]), -i64::from(c[1]));
    (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
}

/// Figure 6's recursion over a lattice of `side` cells: `active(m, a, b)` says whether
/// midpoint `m` of hypotenuse `a-b` is active (asked at every visit; a midpoint is visited once
/// or twice, and must get the same answer). Returns the vertices in the order the triangles
/// first use them and the triangles, counter-clockwise seen from above.
pub fn rqt_triangles(
    side: u32,
    mut active: impl FnMut(Pos, Pos, Pos) -> bool,
) -> (Vec<Pos>, Vec<[u32; 3]>) {
    let n = side as usize + 1;
    let mut slot = vec![u32::MAX; n * n];
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    // (apex, hypotenuse end, hypotenuse end)
    let mut stack = vec![
        ([0, side], [0, 0], [side, side]),
        ([side, 0], [side, side], [0, 0]),
    ];
    while let Some((c, a, b)) = stack.pop() {
        let sum = [a[0] + b[0], a[1] + b[1]];
        if sum[0] % 2 == 0 && sum[1] % 2 == 0 {
            let m = sum.map(|v| v / 2);
            if active(m, a, b) {
                stack.push((m, c, b));
                stack.push((m, a, c));
                continue;
            }
        }
        let t = if area2(c, a, b) > 0 {
            [c, a, b]
        } else {
            [c, b, a]
        };
        triangles.push(t.map(|p| {
            let i = p[1] as usize * n + p[0] as usize;
            if slot[i] == u32::MAX {
                slot[i] = vertices.len() as u32;
                vertices.push(p);
            }
            slot[i]
        }));
    }
    (vertices, triangles)
}

/// The lattice side of an `rqt` tile over `span`, when the span allows one.
pub fn rqt_side(span: &TileSpan) -> Option<u32> {
    let (nx, ny) = (span.nx(), span.ny());
    let full = (nx - 1) * span.stride == span.cols.1 - span.cols.0
        && (ny - 1) * span.stride == span.rows.1 - span.rows.0;
    (nx == ny && (nx - 1).is_power_of_two() && full).then_some(nx - 1)
}

/// Packs the `rqt` mesh over `span`'s lattice whose active midpoints `is_active` names, with
/// lattice heights `z_at` (z quanta). `None` when the span is not a square `2^k + 1` lattice.
pub fn encode_rqt(
    span: &TileSpan,
    is_active: impl Fn(Pos) -> bool,
    z_at: impl Fn(Pos) -> i32,
) -> Option<Vec<u8>> {
    let side = rqt_side(span)?;
    let n = side as usize + 1;
    let corners = [[0, 0], [side, 0], [0, side], [side, side]].map(&z_at);
    let zmin = corners.iter().copied().min().unwrap_or(0);
    let mut seen = vec![false; n * n];
    // (activity bit, residual for an active one)
    let mut events: Vec<(bool, i64)> = Vec::new();
    rqt_triangles(side, |m, a, b| {
        let on = is_active(m);
        let i = m[1] as usize * n + m[0] as usize;
        if !seen[i] {
            seen[i] = true;
            let pred = (i64::from(z_at(a)) + i64::from(z_at(b))).div_euclid(2);
            events.push((on, i64::from(z_at(m)) - pred));
        }
        on
    });
    let corner_codes = corners.map(|z| (i64::from(z) - i64::from(zmin)) as u64);
    let k = best_order(
        corner_codes
            .iter()
            .copied()
            .chain(events.iter().filter(|e| e.0).map(|e| zigzag(e.1))),
        15,
    );
    let mut w = mesh_header(MeshKind::Rqt, zmin);
    w.put(k, 4);
    for c in corner_codes {
        w.put_eg(c, k);
    }
    for (on, res) in events {
        w.put(u32::from(on), 1);
        if on {
            w.put_eg_signed(res, k);
        }
    }
    Some(w.finish())
}

/// Unpacks an `rqt` blob over `span` from `r` (just past the kind): the mesh (vertex offsets in
/// samples) and its vertex heights.
pub(super) fn decode_rqt(
    span: &TileSpan,
    mut r: BitReader<'_>,
) -> Result<(IrregularMesh, Vec<i32>), TileBodyError> {
    const T: TileBodyError = TileBodyError::Truncated;
    let side = rqt_side(span).ok_or(TileBodyError::MeshKind(MeshKind::Rqt as u32))?;
    let n = side as usize + 1;
    let zmin = i64::from(r.get(32).ok_or(T)? as i32);
    let k = r.get(4).ok_or(T)?;
    let mut z = vec![0i64; n * n];
    let at = |p: Pos| p[1] as usize * n + p[0] as usize;
    for c in [[0, 0], [side, 0], [0, side], [side, side]] {
        let v = r.get_eg(k).ok_or(T)?;
        z[at(c)] = i64::try_from(v)
            .ok()
            .and_then(|v| zmin.checked_add(v))
            .filter(|v| i32::try_from(*v).is_ok())
            .ok_or(TileBodyError::Range)?;
    }
    // 0: not yet visited, 1: inactive, 2: active.
    let mut state = vec![0u8; n * n];
    let mut err = None;
    let (vertices, triangles) = rqt_triangles(side, |m, a, b| {
        let i = at(m);
        if state[i] == 0 {
            let mut step = || -> Result<bool, TileBodyError> {
                let on = r.get(1).ok_or(T)? == 1;
                if on {
                    let res = r.get_eg_signed(k).ok_or(T)?;
                    let v = (z[at(a)] + z[at(b)])
                        .div_euclid(2)
                        .checked_add(res)
                        .filter(|v| i32::try_from(*v).is_ok())
                        .ok_or(TileBodyError::Range)?;
                    z[i] = v;
                }
                Ok(on)
            };
            match step() {
                Ok(on) => state[i] = 1 + u8::from(on),
                Err(e) => {
                    // Stop the recursion: every later midpoint reads as inactive.
                    err.get_or_insert(e);
                    state[i] = 1;
                }
            }
        }
        state[i] == 2
    });
    if let Some(e) = err {
        return Err(e);
    }
    finished(&r)?;
    let s = span.stride;
    let heights = vertices.iter().map(|&p| z[at(p)] as i32).collect();
    Ok((
        IrregularMesh {
            kind: MeshKind::Rqt,
            at: vertices.iter().map(|p| p.map(|v| v * s)).collect(),
            triangles,
        },
        heights,
    ))
}
