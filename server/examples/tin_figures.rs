//! Figures for the `tin` tile mesh (paper 003): what shared borders cost, and how
//! many triangles and how much time a tile takes, on crops of real DEMs.
//!
//! `cargo run --release -p relief-server --example tin_figures -- FIGURE DEM.png...`
//!
//! Each PNG is read with its JSON sidecar (`offset`, `scale`, `spacing_m_xy`), voids filled
//! by the repository's reader. Figures:
//! - `paper`: paper 003's 41 x 41 example redone on real ground (its heights are not
//!   published): 41 x 41 crops, triangles at tolerance 0, the tolerance that gives about 475
//!   plain triangles, and the same crop with every sample of its four sides fixed;
//! - `sectors`: the paper's setting, one level of 65 x 65 tiles at stride 1: triangles of the
//!   plain `tin`, with the inner sides' points fixed at the finest tolerance for every LOD
//!   (the paper's rule), and with every inner border sample fixed;
//! - `pyramid`: Relief's pyramid (`T = 64`) over the largest `64 * 2^k + 1` crop, tolerances
//!   doubling per level up from the finest: triangles per level, plain and with
//!   [`borders::tile_borders`] (lines held to their home level's tolerance, or to the
//!   finest), and the shared tiles' largest lattice error over their tolerance;
//! - `timing`: triangles and milliseconds per 65 x 65 tile and per 257 x 257 crop.

#[path = "common/dems.rs"]
#[allow(dead_code, reason = "the tin examples use only the PNG loader")]
mod dems;

use relief_proto::tile::{TileId, TileShape};
use relief_server::lod::tile::mesh::borders::{self, edge_points};
use relief_server::lod::tile::mesh::tin::{lattice_error, tin, tin_span, whole};
use relief_server::lod::tile::mesh::{HeightGrid, TriMesh};
use std::time::Instant;

/// A DEM's heights, row-major metres.
struct Heights {
    /// The DEM's name (its file stem).
    name: String,
    /// Samples per row.
    w: usize,
    /// Rows.
    h: usize,
    /// Heights.
    z: Vec<f32>,
}

impl Heights {
    /// The `w x h` crop at `(c0, r0)`.
    fn crop(&self, c0: usize, r0: usize, w: usize, h: usize) -> Vec<f32> {
        (r0..r0 + h)
            .flat_map(|r| self.z[r * self.w + c0..r * self.w + c0 + w].iter().copied())
            .collect()
    }
}

/// Loads a PNG with its sidecar.
fn load(path: &str) -> anyhow::Result<Heights> {
    let d = dems::load_png(std::path::Path::new(path))?;
    let name = std::path::Path::new(path)
        .file_stem()
        .map_or_else(|| path.to_string(), |s| s.to_string_lossy().into_owned());
    Ok(Heights {
        name,
        w: d.width as usize,
        h: d.height as usize,
        z: d.heights,
    })
}

/// Fixed points and locked sides for a `n x n` sector with the given sides shared (north,
/// east, south, west): every border sample when `all`, else 1D greedy points at `tol`.
fn sector_borders(z: &[f32], n: usize, shared: [bool; 4], tol: f32, all: bool) -> Vec<[u32; 2]> {
    let last = n as u32 - 1;
    let side = |k: usize| -> Vec<[u32; 2]> {
        (0..n as u32)
            .map(|i| match k {
                0 => [i, 0],
                1 => [last, i],
                2 => [i, last],
                _ => [0, i],
            })
            .collect()
    };
    let mut fixed = Vec::new();
    for k in (0..4).filter(|&k| shared[k]) {
        let pts = side(k);
        if all {
            fixed.extend(pts);
            continue;
        }
        let pos: Vec<u32> = (0..n as u32).collect();
        let zs: Vec<f32> = pts
            .iter()
            .map(|p| z[p[1] as usize * n + p[0] as usize])
            .collect();
        fixed.extend(edge_points(&pos, &zs, tol, &[]).into_iter().map(|i| pts[i]));
    }
    fixed
}

/// Paper 003's example, redone: 41 x 41 crops at the tolerance giving about 475 triangles.
fn paper(d: &Heights) {
    let n = 41;
    for (c0, r0) in [(d.w / 3, d.h / 3), (d.w / 2, d.h / 4)] {
        let z = d.crop(c0, r0, n, n);
        let g = HeightGrid::new(n, n, &z).expect("41 x 41");
        let tris = |tol: f32| tin(&g, tol, &[]).triangles.len();
        let (mut lo, mut hi) = (0.0f32, 1000.0f32);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if tris(mid) > 475 { lo = mid } else { hi = mid }
        }
        let tol = hi;
        let zero = tris(0.0);
        let all = sector_borders(&z, n, [true; 4], tol, true);
        let all = tin_span(&g, &whole(&g), tol, &all, [true; 4]);
        println!(
            "| {} ({c0},{r0}) | {zero} | {tol:.2} | {} | {} |",
            d.name,
            tris(tol),
            all.triangles.len(),
        );
    }
}

/// Sum of triangles over a one-level cut of the crop into `n x n` sectors at stride 1: plain
/// (each side's 1D points at the tolerance: neighbours at one tolerance already agree), with
/// the inner sides' points fixed at the finest tolerance (`tols[0]`, the paper's rule: every
/// LOD of a sector keeps the same border points), and with every inner border sample fixed.
fn sectors(d: &Heights, tols: &[f32]) {
    let n = 65;
    let (tx, ty) = ((d.w - 1) / (n - 1), (d.h - 1) / (n - 1));
    for &tol in tols {
        let mut sum = [0usize; 3];
        for (x, y) in (0..tx).flat_map(|x| (0..ty).map(move |y| (x, y))) {
            let z = d.crop(x * (n - 1), y * (n - 1), n, n);
            let g = HeightGrid::new(n, n, &z).expect("65 x 65");
            let shared = [y > 0, x + 1 < tx, y + 1 < ty, x > 0];
            sum[0] += tin(&g, tol, &[]).triangles.len();
            for (k, all) in [(1, false), (2, true)] {
                let f = sector_borders(&z, n, shared, tols[0], all);
                sum[k] += tin_span(&g, &whole(&g), tol, &f, shared).triangles.len();
            }
        }
        let pct = |v: usize| 100.0 * (v as f64 / sum[0] as f64 - 1.0);
        println!(
            "| {} {}x{} tiles | {tol} | {} | {} ({:+.0}%) | {} ({:+.0}%) |",
            d.name,
            tx,
            ty,
            sum[0],
            sum[1],
            pct(sum[1]),
            sum[2],
            pct(sum[2])
        );
    }
}

/// The largest crop from the corner whose sides are `64 * 2^k` cells.
fn pyramid_crop(d: &Heights) -> (usize, usize) {
    let fit = |s: usize| {
        let mut c = 64;
        while 2 * c < s {
            c *= 2;
        }
        c + 1
    };
    (fit(d.w), fit(d.h))
}

/// Triangles per level of Relief's pyramid, plain and with shared borders (lines at their home
/// level's tolerance, and at the finest), and the shared tiles' largest lattice error over
/// their tolerance.
fn pyramid(d: &Heights, bases: &[f32]) -> anyhow::Result<()> {
    let (w, h) = pyramid_crop(d);
    let z = d.crop(0, 0, w, h);
    let grid = HeightGrid::new(w, h, &z).expect("crop");
    let shape = TileShape::new(w as u32, h as u32, 64)?;
    let depth = shape.depth();
    for &base in bases {
        let tol = |k: u8| base * f32::from(1u16 << (depth - k));
        let finest = |_: u8| base;
        for level in 0..=depth {
            let (nx, ny) = shape.level_dims(level);
            let mut sum = [0usize; 3];
            let mut ratio = [0.0f32; 2];
            for (x, y) in (0..nx).flat_map(|x| (0..ny).map(move |y| (x, y))) {
                let t = TileId { level, x, y };
                let m: [TriMesh; 3] = [
                    borders::tile_tin(&shape, t, &grid, tol(level), None),
                    borders::tile_tin(&shape, t, &grid, tol(level), Some(&tol)),
                    borders::tile_tin(&shape, t, &grid, tol(level), Some(&finest)),
                ];
                for (s, m) in sum.iter_mut().zip(&m) {
                    *s += m.triangles.len();
                }
                for (r, m) in ratio.iter_mut().zip(&m[1..]) {
                    *r = r.max(lattice_error(m, &grid, &shape.span(t)) / tol(level));
                }
            }
            let pct = |v: usize| 100.0 * (v as f64 / sum[0] as f64 - 1.0);
            println!(
                "| {} {w}x{h} | {base} | {level} ({nx}x{ny}) | {} | {} | {} ({:+.0}%) | {:.2} | {} ({:+.0}%) | {:.2} |",
                d.name,
                tol(level),
                sum[0],
                sum[1],
                pct(sum[1]),
                ratio[0],
                sum[2],
                pct(sum[2]),
                ratio[1],
            );
        }
    }
    Ok(())
}

/// Milliseconds and triangles per 65 x 65 tile and per 257 x 257 crop.
fn timing(d: &Heights, tols: &[f32]) {
    for n in [65usize, 257] {
        let crops: Vec<(usize, usize)> = (0..(d.w - 1) / (n - 1))
            .flat_map(|x| (0..(d.h - 1) / (n - 1)).map(move |y| (x * (n - 1), y * (n - 1))))
            .collect();
        for &tol in tols {
            let (mut tris, mut secs, mut worst) = (0usize, 0.0f64, 0.0f64);
            for &(c0, r0) in &crops {
                let z = d.crop(c0, r0, n, n);
                let g = HeightGrid::new(n, n, &z).expect("crop");
                let t0 = Instant::now();
                let m = tin(&g, tol, &[]);
                let s = t0.elapsed().as_secs_f64();
                secs += s;
                worst = worst.max(s);
                tris += m.triangles.len();
            }
            let k = crops.len() as f64;
            println!(
                "| {} | {n}x{n} x{} | {tol} | {:.0} | {:.3} | {:.3} |",
                d.name,
                crops.len(),
                tris as f64 / k,
                1e3 * secs / k,
                1e3 * worst
            );
        }
    }
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [figure, dems @ ..] = args.as_slice() else {
        anyhow::bail!("usage: tin_figures paper|sectors|pyramid|timing DEM.png...");
    };
    let tols = [1.0f32, 2.0, 5.0, 10.0, 20.0];
    for path in dems {
        let d = load(path)?;
        match figure.as_str() {
            "paper" => paper(&d),
            "sectors" => sectors(&d, &tols),
            "pyramid" => pyramid(&d, &[1.0, 2.0, 5.0])?,
            "timing" => timing(&d, &tols),
            other => anyhow::bail!("unknown figure {other}"),
        }
    }
    Ok(())
}
