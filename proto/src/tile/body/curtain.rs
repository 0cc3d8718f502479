//! Curtain blobs (`rqt+patches`): an `rqt` tile's crack curtains, side by side, as
//! the server finds them (`server/src/lod/tile/mesh/curtain.rs` explains them) and as a client
//! rebuilds their triangles ([`decode_tile_curtains`]). They travel in the patch slot of an
//! `rqt` tile's body; `docs/protocol.md` section 15 specifies the bits.
//!
//! Per side with a neighbour (in [`crate::tile::EDGES`] order), per own border segment `a-c`
//! (the tile's vertices on that side, in order): one order-`k` code, `0` for no curtain, else
//! `n + 1` with `n` interior bottom points; their positions as codes of `x - previous - 1`
//! (the first from `a`; every `x` strictly between `a` and `c`); then for the `n + 2` bottom
//! points (`a`, the interior ones, `c`) the depth `floor(top(x)) - z >= 0` below the segment's
//! line `top`. The blob starts with the 4-bit order `k`.

use super::{IrregularMesh, TileBodyError, finished};
use crate::bits::{BitReader, BitWriter, best_order};
use crate::tile::{EDGES, Edge, TileId, TileShape, TileSpan};

/// A border polyline along a side: positions along the line (samples, increasing) and heights
/// (z quanta).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Polyline {
    /// Positions, increasing.
    pub pos: Vec<u32>,
    /// Heights, one per position.
    pub z: Vec<i32>,
}

impl Polyline {
    /// The height at `x`, when `x` lies within the polyline's range.
    pub fn at(&self, x: u32) -> Option<f64> {
        let (first, last) = (*self.pos.first()?, *self.pos.last()?);
        if x < first || x > last {
            return None;
        }
        let k = self.pos.partition_point(|&p| p <= x);
        if k == self.pos.len() {
            return Some(f64::from(self.z[k - 1]));
        }
        let (p0, p1) = (f64::from(self.pos[k - 1]), f64::from(self.pos[k]));
        let (z0, z1) = (f64::from(self.z[k - 1]), f64::from(self.z[k]));
        Some(z0 + (z1 - z0) * (f64::from(x) - p0) / (p1 - p0))
    }
}

/// A curtain vertex: one of the tile's own border vertices (by its index along the side's
/// polyline) or a bottom point (position along the line, height).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurtainVertex {
    /// `own.pos[i]`.
    Own(usize),
    /// A point below the border.
    Bottom(u32, i32),
}

/// One side's curtains: for each own segment, its bottom points (ends included), or `None`.
pub type SideCurtain = Vec<Option<Vec<(u32, i32)>>>;

/// The triangles of own segment `s`'s curtain over `bottom`: the fan from the segment's start
/// through the bottom points to its end, without the triangles that repeat a point (a bottom
/// point on the segment's start or end). Triangles of zero area with three distinct points
/// stay: a bottom point on the segment itself is a neighbour's border vertex there (a
/// T-junction), and the flat triangle through it shares that vertex exactly, which closes the
/// pixel-wide holes a rasterizer leaves along a T-junction.
pub fn fan(own: &Polyline, s: usize, bottom: &[(u32, i32)]) -> Vec<[CurtainVertex; 3]> {
    let v: Vec<CurtainVertex> = bottom
        .iter()
        .map(|&(x, z)| CurtainVertex::Bottom(x, z))
        .chain([CurtainVertex::Own(s + 1)])
        .collect();
    let xy = |v: CurtainVertex| match v {
        CurtainVertex::Own(i) => (own.pos[i], own.z[i]),
        CurtainVertex::Bottom(x, z) => (x, z),
    };
    let pa = xy(CurtainVertex::Own(s));
    v.windows(2)
        .filter(|w| {
            let (p, q) = (xy(w[0]), xy(w[1]));
            p != pa && q != pa && p != q
        })
        .map(|w| [CurtainVertex::Own(s), w[0], w[1]])
        .collect()
}

/// The depth code of bottom point `(x, z)` below `own`'s line at `x`.
fn depth(own: &Polyline, x: u32, z: i32) -> u64 {
    let top = own.at(x).unwrap_or(f64::from(z)).floor() as i64;
    (top - i64::from(z)).max(0) as u64
}

/// A corner of a curtain triangle as a client draws it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CurtainPoint {
    /// The tile's own vertex with this index.
    Vertex(u32),
    /// A point below the tile's border: grid column and row, height in z quanta.
    Below {
        /// Grid column and row.
        at: (u32, u32),
        /// Height, z quanta.
        z: i32,
    },
}

/// The border of tile `t` along side `e` for a mesh with vertices at `at` (offsets from the
/// span's first sample) and heights `z`: the polyline by absolute position along the line
/// (columns for north and south, rows for east and west), and each point's vertex index. A
/// position held by several vertices keeps the lowest-numbered one.
pub fn side_of(span: &TileSpan, e: Edge, at: &[[u32; 2]], z: &[i32]) -> (Polyline, Vec<u32>) {
    let (w, h) = (span.cols.1 - span.cols.0, span.rows.1 - span.rows.0);
    let mut pts: Vec<(u32, u32)> = at
        .iter()
        .enumerate()
        .filter_map(|(v, p)| {
            let on = match e {
                Edge::North => (p[1] == 0).then_some(span.cols.0 + p[0]),
                Edge::South => (p[1] == h).then_some(span.cols.0 + p[0]),
                Edge::West => (p[0] == 0).then_some(span.rows.0 + p[1]),
                Edge::East => (p[0] == w).then_some(span.rows.0 + p[1]),
            };
            on.map(|x| (x, v as u32))
        })
        .collect();
    pts.sort_unstable();
    pts.dedup_by_key(|p| p.0);
    let own = Polyline {
        pos: pts.iter().map(|p| p.0).collect(),
        z: pts.iter().map(|p| z[p.1 as usize]).collect(),
    };
    (own, pts.into_iter().map(|p| p.1).collect())
}

/// The grid position of the point `x` along side `e` of `span`.
fn on_side(span: &TileSpan, e: Edge, x: u32) -> (u32, u32) {
    match e {
        Edge::North => (x, span.rows.0),
        Edge::South => (x, span.rows.1),
        Edge::West => (span.cols.0, x),
        Edge::East => (span.cols.1, x),
    }
}

/// The sides of `t` that carry curtains, in blob order: those with a neighbour, in
/// [`EDGES`] order.
pub fn curtain_sides(shape: &TileShape, t: TileId) -> impl Iterator<Item = Edge> + '_ {
    EDGES
        .into_iter()
        .filter(move |&e| shape.neighbour(t, e).is_some())
}

/// Unpacks the curtain blob of `rqt` tile `t` whose decoded mesh is `mesh` with heights `z`,
/// into triangles ([`fan`] for every segment with a curtain).
pub fn decode_tile_curtains(
    shape: &TileShape,
    t: TileId,
    mesh: &IrregularMesh,
    z: &[i32],
    bytes: &[u8],
) -> Result<Vec<[CurtainPoint; 3]>, TileBodyError> {
    if z.len() != mesh.at.len() {
        return Err(TileBodyError::Heights(z.len(), mesh.at.len()));
    }
    let span = shape.span(t);
    let sides: Vec<(Edge, Polyline, Vec<u32>)> = curtain_sides(shape, t)
        .map(|e| {
            let (own, ids) = side_of(&span, e, &mesh.at, z);
            (e, own, ids)
        })
        .collect();
    let owns: Vec<Polyline> = sides.iter().map(|s| s.1.clone()).collect();
    let curtains = decode_curtains(&owns, bytes)?;
    let mut out = Vec::new();
    for ((e, own, ids), segs) in sides.iter().zip(&curtains) {
        for (s, bottom) in segs.iter().enumerate() {
            let Some(bottom) = bottom else { continue };
            out.extend(fan(own, s, bottom).into_iter().map(|tri| {
                tri.map(|v| match v {
                    CurtainVertex::Own(i) => CurtainPoint::Vertex(ids[i]),
                    CurtainVertex::Bottom(x, z) => CurtainPoint::Below {
                        at: on_side(&span, *e, x),
                        z,
                    },
                })
            }));
        }
    }
    Ok(out)
}

/// Packs the curtains of a tile's sides (each with its own polyline).
pub fn encode_curtains(sides: &[(Polyline, SideCurtain)]) -> Vec<u8> {
    let mut codes = Vec::new();
    for (own, segs) in sides {
        for (s, seg) in segs.iter().enumerate() {
            let Some(bottom) = seg else {
                codes.push(0);
                continue;
            };
            let n = bottom.len().saturating_sub(2);
            codes.push(n as u64 + 1);
            let mut prev = own.pos[s];
            for &(x, _) in &bottom[1..bottom.len() - 1] {
                codes.push(u64::from(x - prev - 1));
                prev = x;
            }
            codes.extend(bottom.iter().map(|&(x, z)| depth(own, x, z)));
        }
    }
    let k = best_order(codes.iter().copied(), 15);
    let mut w = BitWriter::new();
    w.put(k, 4);
    for c in codes {
        w.put_eg(c, k);
    }
    w.finish()
}

/// Unpacks curtains for sides whose own polylines are `owns`.
pub fn decode_curtains(owns: &[Polyline], bytes: &[u8]) -> Result<Vec<SideCurtain>, TileBodyError> {
    const T: TileBodyError = TileBodyError::Truncated;
    let mut r = BitReader::new(bytes);
    let k = r.get(4).ok_or(T)?;
    let mut out = Vec::with_capacity(owns.len());
    for own in owns {
        let mut side = Vec::new();
        for s in 0..own.pos.len().saturating_sub(1) {
            let code = r.get_eg(k).ok_or(T)?;
            if code == 0 {
                side.push(None);
                continue;
            }
            let (a, c) = (own.pos[s], own.pos[s + 1]);
            let n = code - 1;
            if n >= u64::from(c - a) {
                return Err(TileBodyError::Outside);
            }
            let mut xs = vec![a];
            for _ in 0..n {
                let d = r.get_eg(k).ok_or(T)?;
                let x = u64::from(*xs.last().unwrap_or(&a)) + d + 1;
                if x >= u64::from(c) {
                    return Err(TileBodyError::Outside);
                }
                xs.push(x as u32);
            }
            xs.push(c);
            let mut bottom = Vec::with_capacity(xs.len());
            for x in xs {
                let d = r.get_eg(k).ok_or(T)?;
                let top = own.at(x).ok_or(TileBodyError::Outside)?.floor() as i64;
                let z = i64::try_from(d)
                    .ok()
                    .and_then(|d| top.checked_sub(d))
                    .and_then(|z| i32::try_from(z).ok())
                    .ok_or(TileBodyError::Range)?;
                bottom.push((x, z));
            }
            side.push(Some(bottom));
        }
        out.push(side);
    }
    finished(&r)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The curtain blob example of `docs/protocol.md` section 15.2.
    #[test]
    fn the_curtain_example_of_the_protocol_doc_is_what_the_code_sends() {
        let own = Polyline {
            pos: vec![32, 40, 48],
            z: vec![100, 104, 100],
        };
        let segs: SideCurtain = vec![Some(vec![(32, 100), (36, 97), (40, 101)]), None];
        let blob = encode_curtains(&[(own.clone(), segs.clone())]);
        let hex: Vec<String> = blob.iter().map(|b| format!("{b:02X}")).collect();
        let hex = hex.join(" ");
        println!("{hex}");
        assert_eq!(
            decode_curtains(std::slice::from_ref(&own), &blob),
            Ok(vec![segs.clone()])
        );
        let tris = fan(&own, 0, segs[0].as_ref().unwrap());
        assert_eq!(
            tris,
            vec![
                [
                    CurtainVertex::Own(0),
                    CurtainVertex::Bottom(36, 97),
                    CurtainVertex::Bottom(40, 101)
                ],
                [
                    CurtainVertex::Own(0),
                    CurtainVertex::Bottom(40, 101),
                    CurtainVertex::Own(1)
                ],
            ]
        );
        let doc = include_str!("../../../../docs/protocol.md");
        let start = doc.find("**Curtain blob**").expect("the section");
        assert!(
            doc[start..].contains(&format!("`{hex}`")),
            "the doc lacks {hex}"
        );
    }

    proptest! {
        #[test]
        fn curtains_round_trip_and_junk_never_panics(
            seed in any::<u64>(), bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let mut x = seed | 1;
            let mut next = move || { x ^= x << 13; x ^= x >> 7; x ^= x << 17; x };
            let own = Polyline { pos: vec![0, 5, 6, 20], z: vec![3, -4, 7, 0] };
            let segs: SideCurtain = (0..3).map(|s| {
                (next() % 3 != 0).then(|| {
                    let (a, c) = (own.pos[s], own.pos[s + 1]);
                    let mut xs = vec![a];
                    for p in a + 1..c {
                        if next() % 2 == 0 { xs.push(p); }
                    }
                    xs.push(c);
                    xs.into_iter().map(|p| (p, own.at(p).unwrap().floor() as i32 - (next() % 9) as i32)).collect()
                })
            }).collect();
            let sides = vec![(own.clone(), segs.clone()), (own.clone(), vec![None, None, None])];
            let blob = encode_curtains(&sides);
            let back = decode_curtains(&[own.clone(), own.clone()], &blob).unwrap();
            prop_assert_eq!(&back[0], &segs);
            prop_assert!(back[1].iter().all(Option::is_none));
            let _ = decode_curtains(std::slice::from_ref(&own), &bytes);
        }
    }
}
