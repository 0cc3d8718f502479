//! Relief's quantized-mesh encoder and decoder on files, for comparisons with other encoders
//! (`server/tools/qm_peer.py` drives it against the Python `quantized-mesh-encoder`).
//!
//! - `qm_encode MESH.json OUT.terrain`: encodes a mesh given as
//!   `{"bounds":[w,s,e,n],"vertices":[[lon,lat,h],...],"triangles":[[a,b,c],...]}` (degrees,
//!   metres, counter-clockwise) into a tile without extensions, not gzipped;
//! - `qm_encode --decode TILE.terrain W S E N`: decodes any quantized-mesh tile with Relief's
//!   decoder and prints one JSON object: the header, the vertices as `[lon, lat, h]` for those
//!   bounds, the triangles and the four edge lists.

use anyhow::Context;
use relief_server::formats::quantized_mesh::{QmExtensions, QmMesh, decode, encode};
use serde::Deserialize;

#[derive(Deserialize)]
struct MeshJson {
    bounds: [f64; 4],
    vertices: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
}

fn encode_file(mesh: &str, out: &str) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(mesh).with_context(|| format!("{mesh}: cannot read"))?;
    let m: MeshJson = serde_json::from_str(&text).with_context(|| format!("{mesh}: not a mesh"))?;
    let [west, south, east, north] = m.bounds;
    let mesh = QmMesh {
        west,
        south,
        east,
        north,
        vertices: m.vertices,
        triangles: m.triangles,
    };
    let bytes = encode(&mesh, &QmExtensions::default())?;
    std::fs::write(out, bytes).with_context(|| format!("{out}: cannot write"))?;
    Ok(())
}

fn decode_file(tile: &str, bounds: &[String]) -> anyhow::Result<()> {
    let bytes = std::fs::read(tile).with_context(|| format!("{tile}: cannot read"))?;
    let b: Vec<f64> = bounds
        .iter()
        .map(|s| s.parse::<f64>())
        .collect::<Result<_, _>>()
        .context("bounds W S E N must be numbers")?;
    let [w, s, e, n] = b[..] else {
        anyhow::bail!("give four bounds: W S E N");
    };
    let t = decode(&bytes).with_context(|| format!("{tile}: not a quantized-mesh tile"))?;
    let h = &t.header;
    let out = serde_json::json!({
        "header": {
            "center": h.center,
            "min_height": h.min_height,
            "max_height": h.max_height,
            "sphere_center": h.sphere_center,
            "sphere_radius": h.sphere_radius,
            // NaN (no point) is not JSON: null.
            "horizon_occlusion_point": h.horizon_occlusion_point.map(|c| c.is_finite().then_some(c)),
        },
        "wide_indices": t.wide_indices,
        "vertices": t.positions(w, s, e, n),
        "triangles": t.triangles,
        "west": t.west,
        "south": t.south,
        "east": t.east,
        "north": t.north,
    });
    println!("{out}");
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.as_slice() {
        [flag, tile, bounds @ ..] if flag == "--decode" => decode_file(tile, bounds),
        [mesh, out] => encode_file(mesh, out),
        _ => anyhow::bail!(
            "usage: qm_encode MESH.json OUT.terrain | qm_encode --decode TILE.terrain W S E N"
        ),
    }
}
