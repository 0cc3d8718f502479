//! Figures of the `rqt` tile mesh (paper 002) on the shared real DEMs: triangles and
//! time per 65 x 65 tile and per 257 x 257 crop at a few tolerances, and the comparison with
//! pymartini (`server/tools/pymartini_compare.py`) at the same measured maximum error.
//!
//! ```text
//! cargo run --release -p relief-server --example rqt_figure -- table [DIR]
//! python server/tools/pymartini_compare.py DIR
//! cargo run --release -p relief-server --example rqt_figure -- compare DIR
//! ```
//!
//! `table` meshes every non-overlapping crop of each DEM, checks the error bound by brute
//! force ([`TriMesh::max_error`]) and prints means per crop; with `DIR` it also writes the
//! crops there (`{dem}_{n}.f32`: u32 n, u32 count, then per crop u32 col, u32 row and the
//! n*n heights, little-endian). The Python script meshes them with pymartini at each
//! tolerance (`{dem}_{n}.martini`: per crop and tolerance u32 vertices, u32 triangles, the
//! vertices as u16 (col, row) pairs, the triangles as u32 triples). `compare` measures
//! pymartini's meshes with the same brute force and meshes `rqt` at the same errors.

#[path = "common/dems.rs"]
mod dems;

use relief_server::lod::tile::mesh::rqt::RqtErrors;
use relief_server::lod::tile::mesh::{HeightGrid, TriMesh};
use std::io::{Read, Write};
use std::path::Path;
use std::time::Instant;

/// Tolerances, metres (the DEMs hold whole metres).
const TOLS: [f32; 5] = [1.0, 2.0, 5.0, 10.0, 20.0];
/// Crop sizes: a 65 x 65 tile and a 257 x 257 crop.
const SIZES: [u32; 2] = [65, 257];

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        ["table"] => table(None),
        ["table", dir] => table(Some(Path::new(dir))),
        ["compare", dir] => compare(Path::new(dir)),
        _ => anyhow::bail!("usage: rqt_figure table [DIR] | compare DIR"),
    }
}

fn table(dir: Option<&Path>) -> anyhow::Result<()> {
    println!(
        "| DEM | crop | crops | error table ms | tolerance m | triangles | of grid | max error m | mesh us |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for name in dems::NAMES {
        let dem = dems::load(name)?;
        for n in SIZES {
            let crops = dems::crops(&dem, n);
            if crops.is_empty() {
                continue;
            }
            if let Some(dir) = dir {
                write_crops(&dir.join(format!("{name}_{n}.f32")), n, &crops)?;
            }
            let grids: Vec<HeightGrid<'_>> = crops
                .iter()
                .map(|c| HeightGrid::new(n as usize, n as usize, &c.2).expect("square crop"))
                .collect();
            let t0 = Instant::now();
            let tables: Vec<RqtErrors> = grids
                .iter()
                .map(|g| RqtErrors::new(g).expect("2^k+1 crop"))
                .collect();
            let build_ms = t0.elapsed().as_secs_f64() * 1e3 / crops.len() as f64;
            for tol in TOLS {
                let t0 = Instant::now();
                let meshes: Vec<TriMesh> = tables.iter().map(|e| e.mesh(tol)).collect();
                let mesh_us = t0.elapsed().as_secs_f64() * 1e6 / crops.len() as f64;
                let mut worst = 0.0f32;
                for (m, g) in meshes.iter().zip(&grids) {
                    anyhow::ensure!(m.covers(n as usize, n as usize), "{name}: not a cover");
                    worst = worst.max(m.max_error(g));
                }
                anyhow::ensure!(worst <= tol, "{name} {n}: error {worst} above {tol}");
                let tris = meshes.iter().map(|m| m.triangles.len()).sum::<usize>() as f64
                    / crops.len() as f64;
                let full = 2.0 * f64::from(n - 1).powi(2);
                println!(
                    "| {name} | {n} | {} | {build_ms:.2} | {tol} | {tris:.0} | {:.1}% | {worst} | {mesh_us:.0} |",
                    crops.len(),
                    100.0 * tris / full
                );
            }
        }
    }
    Ok(())
}

fn write_crops(path: &Path, n: u32, crops: &[(u32, u32, Vec<f32>)]) -> anyhow::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    f.write_all(&n.to_le_bytes())?;
    f.write_all(&(crops.len() as u32).to_le_bytes())?;
    for (c, r, z) in crops {
        f.write_all(&c.to_le_bytes())?;
        f.write_all(&r.to_le_bytes())?;
        for v in z {
            f.write_all(&v.to_le_bytes())?;
        }
    }
    Ok(f.flush()?)
}

/// Reads `count` little-endian u32s.
fn u32s(r: &mut impl Read, count: usize) -> anyhow::Result<Vec<u32>> {
    let mut b = vec![0u8; count * 4];
    r.read_exact(&mut b)?;
    Ok(b.chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// Reads a crop file: n and the crops' heights.
fn read_crops(path: &Path) -> anyhow::Result<(u32, Vec<Vec<f32>>)> {
    let mut f = std::io::BufReader::new(std::fs::File::open(path)?);
    let [n, count] = u32s(&mut f, 2)?[..] else {
        unreachable!()
    };
    let mut crops = Vec::new();
    for _ in 0..count {
        u32s(&mut f, 2)?;
        crops.push(
            u32s(&mut f, (n * n) as usize)?
                .into_iter()
                .map(f32::from_bits)
                .collect(),
        );
    }
    Ok((n, crops))
}

/// Reads one pymartini mesh.
fn read_mesh(r: &mut impl Read) -> anyhow::Result<TriMesh> {
    let [nv, nt] = u32s(r, 2)?[..] else {
        unreachable!()
    };
    let mut b = vec![0u8; nv as usize * 4];
    r.read_exact(&mut b)?;
    let vertices = b
        .chunks_exact(4)
        .map(|c| {
            [
                u16::from_le_bytes([c[0], c[1]]),
                u16::from_le_bytes([c[2], c[3]]),
            ]
            .map(u32::from)
        })
        .collect();
    let t = u32s(r, nt as usize * 3)?;
    let triangles = t.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    Ok(TriMesh {
        vertices,
        triangles,
    })
}

fn compare(dir: &Path) -> anyhow::Result<()> {
    println!(
        "| DEM | crop | crops | pymartini max_error E | pymartini triangles | its measured max error | crops above E | rqt triangles at E | rqt at pymartini's measured error |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for name in dems::NAMES {
        for n in SIZES {
            let base = dir.join(format!("{name}_{n}"));
            if !base.with_extension("martini").exists() {
                continue;
            }
            let (_, crops) = read_crops(&base.with_extension("f32"))?;
            let mut f =
                std::io::BufReader::new(std::fs::File::open(base.with_extension("martini"))?);
            let mut rows = vec![(0usize, 0.0f32, 0usize, 0usize, 0usize); TOLS.len()];
            for z in &crops {
                let g = HeightGrid::new(n as usize, n as usize, z).expect("square crop");
                let e = RqtErrors::new(&g).expect("2^k+1 crop");
                for (k, tol) in TOLS.into_iter().enumerate() {
                    let m = read_mesh(&mut f)?;
                    let measured = m.max_error(&g);
                    let row = &mut rows[k];
                    row.0 += m.triangles.len();
                    row.1 = row.1.max(measured);
                    row.2 += usize::from(measured > tol);
                    row.3 += e.triangle_count(tol);
                    row.4 += e.triangle_count(measured);
                }
            }
            let c = crops.len() as f64;
            for (tol, r) in TOLS.into_iter().zip(rows) {
                println!(
                    "| {name} | {n} | {} | {tol} | {:.0} | {} | {} | {:.0} | {:.0} |",
                    crops.len(),
                    r.0 as f64 / c,
                    r.1,
                    r.2,
                    r.3 as f64 / c,
                    r.4 as f64 / c
                );
            }
        }
    }
    Ok(())
}
