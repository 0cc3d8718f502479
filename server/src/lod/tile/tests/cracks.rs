//! Crack closure over a whole pyramid, as a client draws it: for every pair of tiles a
//! restricted selection can put side by side (the same level, or one level apart with the finer
//! tile on its parent's side), for every mesh kind and every crack mode that claims closure,
//! every point between the two tiles' borders is covered by a patch, curtain or skirt of one of
//! them (`docs/protocol.md` sections 15.2 and 15.3), and with patches every T-junction (a vertex
//! of one border exactly on a segment of the other) has a flat triangle through it.
//!
//! The tiles are decoded by a client's [`TileMirror`] from the built pyramid's blobs (as a
//! session sends them) and drawn by [`tile_triangles`]; the check works in the vertical plane of
//! each shared side, at every whole and half sample along it, at five heights in each gap.

use crate::dem::synthetic::generate;
use crate::lod::tile::mesh::curtain::across;
use crate::store::tiles::{TilePyramid, build_pyramid};
use relief_proto::msg::{CrackMode, TileStreamParams, WireDelta};
use relief_proto::tile::body::MeshKind;
use relief_proto::tile::cache::set_digest;
use relief_proto::tile::delta::{AddedTile, TileBlobs, TileDelta};
use relief_proto::tile::geometry::tile_triangles;
use relief_proto::tile::mirror::TileMirror;
use relief_proto::tile::{EDGES, Edge, TileSetInfo, TileShape};
use relief_proto::tree::WorldFrame;

/// A point in the vertical plane of a side: position along the line (samples), height (quanta).
type P2 = (f64, f64);

/// One side of one tile as drawn: where it lies, its border and its crack triangles there.
struct Side {
    /// Whether the tile is an `rqt` tile (two of them may leave T-junctions, see [`Openings`]).
    rqt: bool,
    /// The row (north, south) or column (west, east) the side lies on.
    line: u32,
    /// Its first and last position along the line.
    range: (u32, u32),
    /// The tile's border along the side, by position.
    border: Vec<P2>,
    /// Patch, curtain and skirt triangles lying in the side's plane.
    cover: Vec<[P2; 3]>,
}

/// What [`openings`] found.
#[derive(Debug, Default)]
struct Openings {
    /// Pairs of tiles that can meet.
    pairs: usize,
    /// Pairs with an open point.
    open_pairs: usize,
    /// Positions along shared sides where some height between the borders is uncovered.
    points: usize,
    /// The widest gap at an open point, metres.
    max_gap_m: f64,
    /// The first open point, in words.
    first: Option<String>,
    /// T-junctions with no flat triangle through them, on pairs with a `grid` or `tin` tile.
    tees: usize,
    /// The same between two `rqt` tiles: a curtain keeps its flat triangle through a
    /// neighbour's vertex only where no other neighbour dips below it there (reported only).
    rqt_tees: usize,
}

/// The border's height at `x` (inside its range).
fn border_at(b: &[P2], x: f64) -> f64 {
    let k = b.partition_point(|p| p.0 <= x).clamp(1, b.len() - 1);
    let ((x0, z0), (x1, z1)) = (b[k - 1], b[k]);
    if x1 == x0 {
        return z0;
    }
    z0 + (z1 - z0) * (x - x0) / (x1 - x0)
}

/// Whether `p` lies in triangle `t` (edges included, with a little slack for float heights);
/// flat triangles cover nothing.
fn inside(t: &[P2; 3], p: P2) -> bool {
    let cross = |a: P2, b: P2, c: P2| (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
    let area = cross(t[0], t[1], t[2]);
    if area.abs() < 1e-9 {
        return false;
    }
    let eps = 1e-6 * area.abs();
    let d = [
        cross(t[0], t[1], p),
        cross(t[1], t[2], p),
        cross(t[2], t[0], p),
    ];
    d.iter().all(|&v| v * area.signum() >= -eps)
}

/// The T-junctions inside `lo..hi` where a vertex of `fine`'s border lies exactly on a segment
/// of `coarse`'s and no patch or curtain triangle of either has a corner there and reaches
/// both sides of it (the flat triangle that closes the pixel-wide holes a rasterizer leaves).
fn open_tees(coarse: &Side, fine: &Side, lo: u32, hi: u32) -> usize {
    let cover: Vec<&[P2; 3]> = coarse.cover.iter().chain(&fine.cover).collect();
    let on_segment = |b: &&P2| {
        let k = coarse.border.partition_point(|p| p.0 < b.0);
        if k == 0 || k == coarse.border.len() || coarse.border[k].0 == b.0 {
            return false;
        }
        let (a, c) = (coarse.border[k - 1], coarse.border[k]);
        // Whole positions and heights: exact.
        b.1 * (c.0 - a.0) == a.1 * (c.0 - b.0) + c.1 * (b.0 - a.0)
    };
    let closed = |b: &&P2| {
        cover.iter().any(|t| {
            t.iter().any(|p| p.0 == b.0 && (p.1 - b.1).abs() < 1e-6)
                && t.iter().any(|p| p.0 < b.0)
                && t.iter().any(|p| p.0 > b.0)
        })
    };
    fine.border
        .iter()
        .filter(|b| b.0 > f64::from(lo) && b.0 < f64::from(hi))
        .filter(on_segment)
        .filter(|b| !closed(b))
        .count()
}

/// The tiles of `pyramid` as a client of a `crack` session holds them, drawn, side by side.
fn sides(
    shape: &TileShape,
    pyramid: &TilePyramid,
    kind: MeshKind,
    crack: CrackMode,
    quantum: f32,
) -> Vec<[Side; 4]> {
    let n = shape.tile_count();
    let data = pyramid.data();
    // One delta that adds every tile with its body, as a session sends it.
    let added = (0..n)
        .map(|i| {
            let r = pyramid.records[i as usize];
            let (mesh, patches) = data[r.offset as usize..].split_at(r.mesh_len as usize);
            AddedTile {
                tile: i,
                body: Some(TileBlobs {
                    mesh: mesh.to_vec(),
                    patches: match crack {
                        CrackMode::Patches => patches[..r.patch_len as usize].to_vec(),
                        _ => Vec::new(),
                    },
                }),
            }
        })
        .collect();
    let delta = TileDelta {
        removed: Vec::new(),
        added,
    };
    let params = TileStreamParams {
        cache_tiles: u32::MAX,
        crack,
    };
    let mut mirror = TileMirror::new(shape.clone(), params);
    let wire = WireDelta {
        seq: 1,
        digest: set_digest(0..n),
        body: delta.encode(),
    };
    mirror.apply(&wire).expect("a client takes every tile");
    let mut level_errors = vec![0f32; shape.depth() as usize + 1];
    for i in 0..n {
        let level = shape.tile(i).unwrap().level as usize;
        level_errors[level] = level_errors[level].max(pyramid.records[i as usize].error);
    }
    let info = TileSetInfo {
        tile_size: shape.tile_size(),
        depth: shape.depth(),
        mesh: kind.name().into(),
        level_errors,
    };
    let frame = WorldFrame {
        dx: 1.0,
        dy: 1.0,
        rows: shape.height(),
    };
    (0..n)
        .map(|i| {
            let data = mirror.tile(i).expect("held");
            let skirt =
                (crack == CrackMode::Skirts).then(|| info.skirt_height(data.tile.level) / quantum);
            // Heights in quanta: the client's positions with a quantum of 1.
            let tris = tile_triangles(&frame, 1.0, data, skirt);
            let grid = |v: u32| {
                let p = tris.positions[v as usize];
                let (c, r) = frame.to_grid(p[0], p[1]);
                (c.round() as u32, r.round() as u32, f64::from(p[2]))
            };
            let span = data.span;
            EDGES.map(|e| {
                let (line, range) = match e {
                    Edge::North => (span.rows.0, span.cols),
                    Edge::South => (span.rows.1, span.cols),
                    Edge::West => (span.cols.0, span.rows),
                    Edge::East => (span.cols.1, span.rows),
                };
                // The position along the side of a point, if it lies on the side's line.
                let on = |(c, r, z): (u32, u32, f64)| match e {
                    Edge::North | Edge::South => (r == line).then_some((f64::from(c), z)),
                    Edge::West | Edge::East => (c == line).then_some((f64::from(r), z)),
                };
                Side {
                    rqt: data.irregular.as_ref().map(|m| m.kind) == Some(MeshKind::Rqt),
                    line,
                    range,
                    border: data
                        .edge_vertices(e)
                        .into_iter()
                        .map(|v| on(grid(v)).expect("on its side"))
                        .collect(),
                    cover: tris
                        .patches
                        .iter()
                        .chain(&tris.skirts)
                        .filter_map(|t| {
                            let [a, b, c] = t.map(|v| on(grid(v)));
                            Some([a?, b?, c?])
                        })
                        .collect(),
                }
            })
        })
        .collect()
}

/// The open points and T-junctions between every pair of tiles of `pyramid` that can meet,
/// drawn as a client of a `crack` session draws them.
fn openings(
    shape: &TileShape,
    pyramid: &TilePyramid,
    kind: MeshKind,
    crack: CrackMode,
    quantum: f32,
) -> Openings {
    let sides = sides(shape, pyramid, kind, crack, quantum);
    let slot = |e: Edge| EDGES.iter().position(|&x| x == e).unwrap_or(0);
    let mut out = Openings::default();
    for i in 0..shape.tile_count() {
        let t = shape.tile(i).unwrap();
        for e in EDGES {
            for (u, back) in across(shape, t, e) {
                let j = shape.index(u);
                // Each pair once (a pair is across from both of its tiles).
                if j < i {
                    continue;
                }
                out.pairs += 1;
                let (a, b) = (&sides[i as usize][slot(e)], &sides[j as usize][slot(back)]);
                assert_eq!(a.line, b.line, "{t:?} {u:?}");
                let (lo, hi) = (a.range.0.max(b.range.0), a.range.1.min(b.range.1));
                assert!(lo < hi, "{t:?} {u:?} do not share a side");
                let mut open = 0;
                for x2 in 2 * lo..=2 * hi {
                    let x = f64::from(x2) / 2.0;
                    let (za, zb) = (border_at(&a.border, x), border_at(&b.border, x));
                    let (bottom, gap) = (za.min(zb), (za - zb).abs());
                    if gap < 1e-6 {
                        continue;
                    }
                    let shut = [0.02, 0.25, 0.5, 0.75, 0.98].iter().all(|f| {
                        let p = (x, bottom + gap * f);
                        a.cover.iter().chain(&b.cover).any(|t| inside(t, p))
                    });
                    if !shut {
                        open += 1;
                        let m = gap * f64::from(quantum);
                        out.max_gap_m = out.max_gap_m.max(m);
                        out.first.get_or_insert_with(|| {
                            format!(
                                "{t:?} {e:?} (at {za} quanta) and {u:?} {back:?} (at {zb}): \
                                 {m:.2} m open at {x} along line {}",
                                a.line
                            )
                        });
                    }
                }
                out.points += open;
                out.open_pairs += usize::from(open > 0);
                if crack == CrackMode::Patches {
                    let tees = open_tees(a, b, lo, hi) + open_tees(b, a, lo, hi);
                    if a.rqt && b.rqt {
                        out.rqt_tees += tees;
                    } else {
                        out.tees += tees;
                    }
                }
            }
        }
    }
    out
}

/// A crop of `synthetic:161` of `w x h` samples (mountains and valleys, heights in metres).
fn terrain(w: u32, h: u32) -> Vec<f32> {
    let full = generate(161, 1, false);
    (0..h)
        .flat_map(|r| (0..w).map(move |c| (r, c)))
        .map(|(r, c)| full[(r * 161 + c) as usize])
        .collect()
}

/// The tiles of an `rqt` store that fall back to `grid` (those the grid's east or south border
/// clips) carried an all-zero patch blob, and nothing closed the gaps where their border stood
/// above an `rqt` neighbour's, or a grid neighbour's one level apart (on 151 x 141 samples in
/// 16-cell tiles: 94 of 421 pairs open at 2,260 points, up to 69.1 m). Every pair of tiles
/// that can meet, in every mesh kind and crack mode that claims closure, must leave no point
/// open; with patches, no T-junction but between two `rqt` tiles may lack its flat triangle.
#[test]
fn every_pair_of_tiles_that_can_meet_leaves_no_crack_open() {
    let quantum = 0.1f32;
    let mut report = Vec::new();
    let mut failures = Vec::new();
    // Both clip tiles on the east and south borders at several levels, differently.
    for (w, h, tile) in [(151u32, 141u32, 16u32), (97, 161, 8)] {
        let heights = terrain(w, h);
        let (lo, hi) = heights
            .iter()
            .fold((f32::MAX, f32::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        assert!(hi - lo > 20.0, "not a test of relief: {} m", hi - lo);
        let shape = TileShape::new(w, h, tile).unwrap();
        for kind in [MeshKind::Grid, MeshKind::Rqt, MeshKind::Tin] {
            let pyramid = build_pyramid(&shape, &heights, quantum, kind, |_| {});
            for crack in [CrackMode::Patches, CrackMode::Skirts, CrackMode::None] {
                let o = openings(&shape, &pyramid, kind, crack, quantum);
                let name = format!("{w}x{h}/{tile} {}+{crack:?}", kind.name());
                report.push(format!(
                    "{name}: {} of {} pairs open, {} points, up to {:.2} m; open T-junctions \
                     {} (rqt-rqt {})",
                    o.open_pairs, o.pairs, o.points, o.max_gap_m, o.tees, o.rqt_tees
                ));
                // Without patches or skirts only `tin`'s shared borders claim closure; the
                // others must show cracks, or the check could not see them.
                let claims = crack != CrackMode::None || kind == MeshKind::Tin;
                if claims && (o.points > 0 || o.tees > 0) {
                    failures.push(format!("{name}: {:?}, {} T-junctions", o.first, o.tees));
                } else if !claims && o.points == 0 {
                    failures.push(format!("{name}: no crack seen"));
                }
            }
        }
    }
    eprintln!("{}", report.join("\n"));
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
