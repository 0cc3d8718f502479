use super::*;
use crate::tile::TileShape;
use proptest::prelude::*;

/// A random DEM of `w` x `h` samples in quanta.
fn dem(w: u32, h: u32, seed: u64, amp: i32) -> Vec<i32> {
    let mut x = seed | 1;
    (0..w * h)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x % (2 * amp as u64 + 1)) as i32 - amp
        })
        .collect()
}

fn tile_z(shape: &TileShape, t: TileId, d: &[i32]) -> Vec<i32> {
    let sp = shape.span(t);
    (0..sp.vertex_count() as u32)
        .map(|v| {
            let (c, r) = sp.vertex_pos(v);
            d[(r * shape.width() + c) as usize]
        })
        .collect()
}

/// The triangle of a patch as grid positions with heights.
type Tri = [(u32, u32, i32); 3];

fn patch_tris(shape: &TileShape, t: TileId, d: &[i32]) -> Vec<Tri> {
    let sp = shape.span(t);
    let z = tile_z(shape, t, d);
    let p = find_patches(shape, t, &z, |c, r| d[(r * shape.width() + c) as usize]);
    let at = |v: u32| {
        let (c, r) = sp.vertex_pos(v);
        (c, r, z[v as usize])
    };
    let mut out: Vec<Tri> = p
        .dropped
        .iter()
        .map(|q| [at(q.a), (q.at.0, q.at.1, q.z), at(q.c)])
        .collect();
    out.extend(p.raised.iter().map(|r| [at(r[0]), at(r[1]), at(r[2])]));
    out
}

/// The `rqt` mesh of `d` over tile `t`'s lattice where vertex `p` is active when `active(p)`:
/// its blob, and the mesh the recursion gives directly.
fn rqt_case(
    shape: &TileShape,
    t: TileId,
    d: &[i32],
    active: impl Fn([u32; 2]) -> bool,
) -> Option<(Vec<u8>, IrregularMesh, Vec<i32>)> {
    let sp = shape.span(t);
    let s = sp.stride;
    let z_at =
        |p: [u32; 2]| d[((sp.rows.0 + p[1] * s) * shape.width() + sp.cols.0 + p[0] * s) as usize];
    let blob = rqt::encode_rqt(&sp, &active, z_at)?;
    let side = rqt::rqt_side(&sp)?;
    let (v, triangles) = rqt::rqt_triangles(side, |m, _, _| active(m));
    let z = v.iter().map(|&p| z_at(p)).collect();
    let at = v.iter().map(|p| p.map(|x| x * s)).collect();
    Some((
        blob,
        IrregularMesh {
            kind: MeshKind::Rqt,
            at,
            triangles,
        },
        z,
    ))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// `rqt` blobs decode to the recursion's own mesh and heights, whichever vertices are active
    /// (restricted or not), and cover the tile: the triangles' areas add up to the tile's.
    #[test]
    fn rqt_meshes_round_trip(t in 2u32..6, seed in any::<u64>(), amp in 0i32..100_000, p_active in 0u64..100) {
        let size = (1u32 << t) * 2 + 1;
        let shape = TileShape::new(size, size, 1 << t).unwrap();
        let d = dem(size, size, seed, amp);
        for i in 0..shape.tile_count() {
            let tile = shape.tile(i).unwrap();
            let sp = shape.span(tile);
            let hash = |p: [u32; 2]| (u64::from(p[0]) * 7919 + u64::from(p[1]) * 104_729 + seed) % 100;
            let case = rqt_case(&shape, tile, &d, |p| hash(p) < p_active);
            prop_assert!(case.is_some(), "square tiles take rqt");
            let (blob, mesh, z) = case.unwrap();
            let got = decode_mesh(&sp, &blob).unwrap();
            prop_assert_eq!(&got.z, &z);
            let irr = got.irregular.unwrap();
            let area: i64 = irr.triangles.iter().map(|t| {
                let [a, b, c] = t.map(|v| irr.at[v as usize]);
                rqt::area2(a, b, c)
            }).sum();
            let ccw = irr.triangles.iter().all(|t| {
                let [a, b, c] = t.map(|v| irr.at[v as usize]);
                rqt::area2(a, b, c) > 0
            });
            prop_assert!(ccw);
            prop_assert_eq!(area, 2 * i64::from(sp.cols.1 - sp.cols.0) * i64::from(sp.rows.1 - sp.rows.0));
            prop_assert_eq!(irr, mesh);
        }
    }

    /// `tin`'s blobs decode to the same mesh, renumbered in [`irregular::canonical`] order.
    #[test]
    fn irregular_meshes_round_trip(n in 3usize..200, seed in any::<u64>(), amp in 0i32..100_000) {
        let sp = TileSpan { cols: (64, 128), rows: (0, 40), stride: 1 };
        let d = dem(65, 41, seed, amp);
        // A fan from the tile's centre over points on its border: any triangles will do here.
        let mut at: Vec<[u32; 2]> = vec![[32, 20]];
        let mut k = seed;
        for _ in 0..n {
            k = k.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            at.push([((k >> 33) % 65) as u32, ((k >> 17) % 41) as u32]);
        }
        let triangles: Vec<[u32; 3]> = (1..at.len() as u32 - 1).map(|v| [0, v, v + 1]).collect();
        let z: Vec<i32> = at.iter().map(|p| d[(p[1] * 65 + p[0]) as usize]).collect();
        let mesh = IrregularMesh { kind: MeshKind::Tin, at, triangles };
        let blob = encode_irregular(&mesh, &z);
        let (want, want_z) = irregular::canonical(&mesh, &z);
        let got = decode_mesh(&sp, &blob).unwrap();
        prop_assert_eq!(got.z, want_z);
        prop_assert_eq!(got.irregular.unwrap(), want);
    }

    #[test]
    fn meshes_and_patches_round_trip(w in 3u32..80, h in 3u32..80, t in 1u32..4, seed in any::<u64>(), amp in 0i32..100_000) {
        let shape = TileShape::new(w, h, 1 << t).unwrap();
        let d = dem(w, h, seed, amp);
        for i in 0..shape.tile_count() {
            let tile = shape.tile(i).unwrap();
            let sp = shape.span(tile);
            let z = tile_z(&shape, tile, &d);
            let mesh = encode_mesh(&sp, &z);
            prop_assert_eq!(decode_mesh(&sp, &mesh).unwrap(), DecodedMesh { z: z.clone(), irregular: None });
            let p = find_patches(&shape, tile, &z, |c, r| d[(r * w + c) as usize]);
            let blob = encode_patches(&shape, tile, &z, &p);
            prop_assert_eq!(decode_patches(&shape, tile, &z, &blob).unwrap(), p);
        }
    }

    #[test]
    fn random_bodies_never_panic_or_overallocate(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        let shape = TileShape::new(200, 150, 64).unwrap();
        for i in 0..shape.tile_count() {
            let t = shape.tile(i).unwrap();
            let sp = shape.span(t);
            if let Ok(m) = decode_mesh(&sp, &bytes) {
                match &m.irregular {
                    None => prop_assert_eq!(m.z.len(), sp.vertex_count()),
                    Some(irr) => {
                        prop_assert_eq!(m.z.len(), irr.at.len());
                        let (w, h) = (sp.cols.1 - sp.cols.0, sp.rows.1 - sp.rows.0);
                        prop_assert!(irr.at.iter().all(|p| p[0] <= w && p[1] <= h));
                        prop_assert!(irr.triangles.iter().flatten().all(|&v| (v as usize) < m.z.len()));
                    }
                }
                let _ = decode_patches(&shape, t, &m.z, &bytes);
            }
            let _ = decode_patches(&shape, t, &vec![0; sp.vertex_count()], &bytes);
        }
    }

    /// Curtain blobs decoded against a real `rqt` mesh: junk gives an error or
    /// triangles over the tile's vertices and points on its sides, never a panic.
    #[test]
    fn random_curtain_blobs_never_panic(seed in any::<u64>(), p_active in 0u64..100,
        bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let size = 33;
        let shape = TileShape::new(size, size, 8).unwrap();
        let d = dem(size, size, seed, 1000);
        for i in 0..shape.tile_count() {
            let tile = shape.tile(i).unwrap();
            let sp = shape.span(tile);
            let hash = |p: [u32; 2]| (u64::from(p[0]) * 7919 + u64::from(p[1]) * 104_729 + seed) % 100;
            let (_, mesh, z) = rqt_case(&shape, tile, &d, |p| hash(p) < p_active).unwrap();
            prop_assert!(curtain::decode_tile_curtains(&shape, tile, &mesh, &z[1..], &bytes).is_err());
            if let Ok(tris) = curtain::decode_tile_curtains(&shape, tile, &mesh, &z, &bytes) {
                for p in tris.iter().flatten() {
                    match *p {
                        curtain::CurtainPoint::Vertex(v) => prop_assert!((v as usize) < z.len()),
                        curtain::CurtainPoint::Below { at: (c, r), .. } => prop_assert!(
                            (c == sp.cols.0 || c == sp.cols.1) && (sp.rows.0..=sp.rows.1).contains(&r)
                                || (r == sp.rows.0 || r == sp.rows.1) && (sp.cols.0..=sp.cols.1).contains(&c)
                        ),
                    }
                }
            }
        }
    }

    /// Paper 001's rule, checked against the geometry: wherever a tile meets a neighbour's child
    /// (one level finer), every finer vertex has exactly one patch, the triangle from the coarse
    /// segment to it: the coarse tile's below the segment, the fine tile's on or above it.
    #[test]
    fn every_finer_vertex_on_a_coarse_edge_has_exactly_one_patch(
        w in 3u32..70, h in 3u32..70, seed in any::<u64>(), amp in 0i32..50) {
        let shape = TileShape::new(w, h, 4).unwrap();
        let d = dem(w, h, seed, amp);
        let z_at = |c: u32, r: u32| d[(r * w + c) as usize] as i64;
        let mut checked = 0;
        for i in 0..shape.tile_count() {
            let t = shape.tile(i).unwrap();
            let mine = patch_tris(&shape, t, &d);
            for e in crate::tile::EDGES {
                let Some(n) = shape.neighbour(t, e) else { continue };
                let sp = shape.span(t);
                let edge: Vec<(u32, u32)> = sp.edge_vertices(e).iter().map(|&v| sp.vertex_pos(v)).collect();
                // The finer tiles across this edge: the neighbour's children that touch it.
                let fine: Vec<TileId> = shape.children(n).collect();
                let theirs: Vec<Tri> = fine.iter().flat_map(|&f| patch_tris(&shape, f, &d)).collect();
                for seg in edge.windows(2) {
                    let (a, c) = (seg[0], seg[1]);
                    let mid = if a.0 == c.0 { (a.0, a.1 + sp.stride / 2) } else { (a.0 + sp.stride / 2, a.1) };
                    if (mid.0, mid.1) >= (c.0, c.1) || fine.is_empty() { continue; }
                    let (pa, pb, pc) = if a.0 == c.0 { (a.1, mid.1, c.1) } else { (a.0, mid.0, c.0) };
                    let line = (z_at(a.0, a.1) * (pc - pb) as i64 + z_at(c.0, c.1) * (pb - pa) as i64) as f64 / (pc - pa) as f64;
                    let zb = z_at(mid.0, mid.1) as f64;
                    let has = |tris: &[Tri]| tris.iter().filter(|q| {
                        q.iter().any(|p| (p.0, p.1) == mid) && q.iter().any(|p| (p.0, p.1) == a) && q.iter().any(|p| (p.0, p.1) == c)
                    }).count();
                    let (dropped, raised) = (has(&mine), has(&theirs));
                    checked += 1;
                    // On the line (a T-junction) the fine tile closes it too.
                    if zb < line {
                        prop_assert_eq!((dropped, raised), (1, 0));
                    } else {
                        prop_assert_eq!((dropped, raised), (0, 1));
                    }
                }
            }
        }
        // Seams exist wherever a tile above the finest level has a neighbour.
        let seams = (0..shape.tile_count()).filter_map(|i| shape.tile(i)).any(|t| {
            t.level < shape.depth()
                && crate::tile::EDGES.iter().any(|&e| shape.neighbour(t, e).is_some())
        });
        prop_assert!(checked > 0 || !seams);
    }
}

#[test]
fn grid_heights_interpolate_the_two_triangles() {
    let shape = TileShape::new(5, 4, 4).unwrap();
    let t = TileId::ROOT;
    let sp = shape.span(t);
    let z: Vec<f32> = (0..sp.vertex_count() as u32)
        .map(|v| {
            let (c, r) = sp.vertex_pos(v);
            (3 * c + 5 * r) as f32
        })
        .collect();
    // A plane is reproduced exactly, also in the narrower last row.
    for &(c, r) in &[(0.5, 0.25), (3.9, 2.5), (1.0, 3.0), (2.2, 2.9)] {
        assert!((grid_height(&sp, &z, c, r) - (3.0 * c + 5.0 * r)).abs() < 1e-4);
    }
    assert_eq!(grid_triangles(&sp).len(), 2 * 4 * 3);
    assert_eq!(skirt_triangle_count(&sp), 4 * (4 + 3));
}

/// Patches decode only against the tile's own grid heights: an irregular mesh's heights (or
/// another tile's) are refused, not indexed out of range (a CI run found the panic).
#[test]
fn patches_refuse_heights_that_are_not_the_tiles_grid() {
    let shape = TileShape::new(200, 150, 64).unwrap();
    let t = shape.tile(1).unwrap();
    let want = shape.span(t).vertex_count();
    let blob = [0u8, 0xff, 0xff, 0xff];
    for got in [0, 8, want - 1, want + 1] {
        assert_eq!(
            decode_patches(&shape, t, &vec![0; got], &blob),
            Err(TileBodyError::Heights(got, want))
        );
    }
}
