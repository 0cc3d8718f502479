//! Curtain ("rqt patches") triangles against skirt triangles over a whole `rqt` pyramid (issue
//! 13): `cargo run --release -p relief-server --example curtain_ratio --
//! synthetic:1025 [TILE]`. The tiles are built as the store builds them and decoded from their
//! blobs; each tile's curtain is taken against every tile a restricted selection may put across
//! each of its sides.

use relief_proto::tile::EDGES;
use relief_proto::tile::body::{MeshKind, decode_mesh};
use relief_proto::tile::mirror::TileData;
use relief_proto::tile::{TileId, TileShape};
use relief_server::lod::tile::mesh::curtain::{Polyline, across, curtain, side_polyline};
use relief_server::store::tiles::build_pyramid;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let spec = args.next().unwrap_or_else(|| "synthetic:1025".into());
    let tile: u32 = args.next().map_or(Ok(64), |s| s.parse())?;
    let dem = relief_server::dem::load(&spec, &Default::default())?;
    let q = relief_server::preprocess::default_quantum(&dem) as f32;
    let shape = TileShape::new(dem.width, dem.height, tile)?;
    for kind in [MeshKind::Rqt, MeshKind::Grid] {
        let p = build_pyramid(&shape, &dem.heights, q, kind, |_| {});
        let data = p.data();
        let tiles: Vec<TileData> = (0..shape.tile_count())
            .map(|i| {
                let t = shape.tile(i).unwrap_or(TileId::ROOT);
                let r = p.records[i as usize];
                let blob = &data[r.offset as usize..][..r.mesh_len as usize];
                let span = shape.span(t);
                let m = decode_mesh(&span, blob).expect("a built blob decodes");
                TileData {
                    tile: t,
                    span,
                    z: m.z,
                    irregular: m.irregular,
                    patches: Default::default(),
                }
            })
            .collect();
        let side = |t: TileId, e| -> Polyline {
            let d = &tiles[shape.index(t) as usize];
            side_polyline(&d.span, e, d.z.len(), |v| {
                let (c, r) = d.vertex_pos(v as u32);
                ([c, r], d.z[v])
            })
        };
        let (mut curtains, mut skirts, mut patches) = (0usize, 0usize, 0u64);
        for d in &tiles {
            skirts += d.skirt_triangle_count();
            patches += u64::from(p.records[shape.index(d.tile) as usize].patch_tris);
            for e in EDGES {
                let others: Vec<Polyline> = across(&shape, d.tile, e)
                    .into_iter()
                    .map(|(n, b)| side(n, b))
                    .collect();
                if !others.is_empty() {
                    curtains += curtain(&side(d.tile, e), &others).len();
                }
            }
        }
        println!(
            "{spec} tile {tile} {}: curtain triangles {curtains}, skirt triangles {skirts}, \
             ratio {:.3}; grid patches (paper 001) {patches}",
            kind.name(),
            curtains as f64 / skirts as f64
        );
    }
    Ok(())
}
