//! The `tin` mesh on raw files, for comparisons with other TIN builders
//! (`server/tools/pydelatin_compare.py` drives it against pydelatin).
//!
//! - `tin_cli crop DEM.png COL ROW W H OUT`: a crop of a DEM (read with its JSON sidecar, voids
//!   filled) as little-endian `f32`, row-major;
//! - `tin_cli tin RAW W H TOL`: Relief's `tin` of a raw grid within `TOL` metres;
//! - `tin_cli check RAW W H MESH`: the brute-force error of a mesh from elsewhere, given as text
//!   (`nv nt`, then `nv` lines `col row`, then `nt` lines `a b c`), its winding made
//!   counter-clockwise first.
//!
//! `tin` and `check` print one JSON object: triangles, vertices, max error (metres, by
//! [`TriMesh::max_error`]), whether the triangles cover the grid once, and for `tin` the best
//! of five runs in milliseconds.

#[path = "common/dems.rs"]
#[allow(dead_code, reason = "the tin examples use only the PNG loader")]
mod dems;

use relief_server::lod::tile::mesh::tin::tin;
use relief_server::lod::tile::mesh::{HeightGrid, TriMesh, area2};
use std::time::Instant;

/// Reads `w * h` little-endian `f32`.
fn read_raw(path: &str, w: usize, h: usize) -> anyhow::Result<Vec<f32>> {
    let bytes = std::fs::read(path)?;
    anyhow::ensure!(bytes.len() == 4 * w * h, "{path}: not {w} x {h} f32");
    Ok(bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect())
}

/// Writes a crop of a PNG DEM.
fn crop(path: &str, c0: usize, r0: usize, w: usize, h: usize, out: &str) -> anyhow::Result<()> {
    let d = dems::load_png(std::path::Path::new(path))?;
    let dw = d.width as usize;
    anyhow::ensure!(
        c0 + w <= dw && r0 + h <= d.height as usize,
        "crop outside the DEM"
    );
    let mut bytes = Vec::with_capacity(4 * w * h);
    for r in r0..r0 + h {
        for &z in &d.heights[r * dw + c0..r * dw + c0 + w] {
            bytes.extend_from_slice(&z.to_le_bytes());
        }
    }
    std::fs::write(out, bytes)?;
    Ok(())
}

/// Reads a text mesh, winding made counter-clockwise seen from above.
fn read_mesh(path: &str) -> anyhow::Result<TriMesh> {
    let text = std::fs::read_to_string(path)?;
    let mut nums = text.split_ascii_whitespace().map(str::parse::<u32>);
    let mut next = || -> anyhow::Result<u32> {
        Ok(nums
            .next()
            .ok_or_else(|| anyhow::anyhow!("{path}: short"))??)
    };
    let (nv, nt) = (next()?, next()?);
    let mut m = TriMesh::default();
    for _ in 0..nv {
        m.vertices.push([next()?, next()?]);
    }
    for _ in 0..nt {
        let mut t = [next()?, next()?, next()?];
        anyhow::ensure!(
            t.iter().all(|&i| i < nv),
            "{path}: vertex index out of range"
        );
        if area2(
            m.vertices[t[0] as usize],
            m.vertices[t[1] as usize],
            m.vertices[t[2] as usize],
        ) < 0
        {
            t.swap(1, 2);
        }
        m.triangles.push(t);
    }
    Ok(m)
}

/// The JSON line for a mesh.
fn report(m: &TriMesh, g: &HeightGrid<'_>, ms: Option<f64>) -> String {
    serde_json::json!({
        "triangles": m.triangles.len(),
        "vertices": m.vertices.len(),
        "max_error": m.max_error(g),
        "covers": m.covers(g.width, g.height),
        "ms": ms,
    })
    .to_string()
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let n = |s: &str| s.parse::<usize>();
    match a.as_slice() {
        ["crop", dem, c, r, w, h, out] => crop(dem, n(c)?, n(r)?, n(w)?, n(h)?, out),
        ["tin", raw, w, h, tol] => {
            let (w, h) = (n(w)?, n(h)?);
            let z = read_raw(raw, w, h)?;
            let g = HeightGrid::new(w, h, &z).ok_or_else(|| anyhow::anyhow!("bad grid"))?;
            let tol: f32 = tol.parse()?;
            let mut best = f64::MAX;
            let mut m = TriMesh::default();
            for _ in 0..5 {
                let t0 = Instant::now();
                m = tin(&g, tol, &[]);
                best = best.min(t0.elapsed().as_secs_f64() * 1e3);
            }
            println!("{}", report(&m, &g, Some(best)));
            Ok(())
        }
        ["check", raw, w, h, mesh] => {
            let (w, h) = (n(w)?, n(h)?);
            let z = read_raw(raw, w, h)?;
            let g = HeightGrid::new(w, h, &z).ok_or_else(|| anyhow::anyhow!("bad grid"))?;
            println!("{}", report(&read_mesh(mesh)?, &g, None));
            Ok(())
        }
        _ => anyhow::bail!(
            "usage: tin_cli crop DEM COL ROW W H OUT | tin RAW W H TOL | check RAW W H MESH"
        ),
    }
}
