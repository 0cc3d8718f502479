//! `bench formats`: the standard formats' tiles over a whole terrain, as the server makes them
//! on request: quantized-mesh bytes (raw and gzipped, mean and p99) and triangles per mesh kind,
//! terrain-RGB and Terrarium PNG bytes, and the time to make each tile (resampling, meshing and
//! encoding; single-threaded, medians and p99 of the same run).
//!
//! Every available tile of every level is made, up to `max_per_level` per level (then an even
//! sample of the level's range, the same for every kind, so that the kinds are compared on the
//! same tiles).

use super::stats::{mean, median, quantile};
use crate::formats::cesium::{
    CesiumLayer, TILE_POINTS, mesh_heights, tile_heights, tile_mesh, tolerance,
};
use crate::formats::quantized_mesh::{QmExtensions, QmMesh, encode};
use crate::formats::raster::{RasterLayer, tile_png};
use crate::formats::sampler::Resampler;
use crate::formats::terrain_rgb::Encoding;
use crate::geo::GeoTransform;
use crate::geo::tiling::{Scheme, TileRange, TileXyz};
use crate::lod::tile::mesh::HeightGrid;
use crate::store::Store;
use relief_proto::tile::body::MeshKind;
use serde::Serialize;
use std::time::Instant;

/// Options of [`run`].
#[derive(Clone, Debug)]
pub struct FormatsBenchOptions {
    /// Most tiles made per level and kind.
    pub max_per_level: usize,
    /// PNG tile size, pixels.
    pub tile_size: u32,
    /// Show a progress bar.
    pub progress: bool,
}

impl Default for FormatsBenchOptions {
    fn default() -> Self {
        FormatsBenchOptions {
            max_per_level: 64,
            tile_size: 256,
            progress: false,
        }
    }
}

/// Figures of one kind of tile.
#[derive(Clone, Debug, Serialize)]
pub struct TileFigures {
    /// `quantized-mesh/grid`, `png/terrain-rgb`, ...
    pub kind: String,
    /// Tiles made.
    pub tiles: usize,
    /// Mean triangles per tile (meshes only).
    pub triangles_mean: f64,
    /// Mean bytes per tile as served before gzip.
    pub bytes_mean: f64,
    /// 99th percentile of the same.
    pub bytes_p99: f64,
    /// Mean gzipped bytes per tile (what a browser receives for meshes).
    pub gzip_mean: f64,
    /// 99th percentile of the same.
    pub gzip_p99: f64,
    /// Median time to make one tile, milliseconds.
    pub make_ms_median: f64,
    /// 99th percentile of the same.
    pub make_ms_p99: f64,
    /// Largest vertical error of a simplified mesh against its 65 x 65 resampled grid, as a
    /// fraction of its tolerance (meshes only; at most 1).
    pub worst_error_of_tolerance: f64,
}

/// The report of [`run`].
#[derive(Clone, Debug, Serialize)]
pub struct FormatsReport {
    /// The terrain's longitude/latitude box.
    pub bounds: [f64; 4],
    /// Cesium levels served, 0 to this.
    pub cesium_max_level: u8,
    /// Web Mercator levels served, 0 to this.
    pub raster_max_level: u8,
    /// One row per kind.
    pub kinds: Vec<TileFigures>,
}

/// Up to `max` tiles of range `r` at level `z`, spread evenly.
fn sample(r: &TileRange, z: u8, max: usize) -> Vec<TileXyz> {
    let all: Vec<TileXyz> = (r.start_y..=r.end_y)
        .flat_map(|y| (r.start_x..=r.end_x).map(move |x| TileXyz { z, x, y }))
        .collect();
    if all.len() <= max {
        return all;
    }
    (0..max).map(|i| all[i * all.len() / max]).collect()
}

fn figures(kind: String, bytes: &[f64], gzip: &[f64], ms: &[f64], tris: &[f64]) -> TileFigures {
    TileFigures {
        kind,
        tiles: bytes.len(),
        triangles_mean: mean(tris),
        bytes_mean: mean(bytes),
        bytes_p99: quantile(bytes, 0.99),
        gzip_mean: mean(gzip),
        gzip_p99: quantile(gzip, 0.99),
        make_ms_median: median(ms),
        make_ms_p99: quantile(ms, 0.99),
        worst_error_of_tolerance: 0.0,
    }
}

/// Makes the tiles of `store` and measures them.
pub fn run(store: &Store, opts: &FormatsBenchOptions) -> anyhow::Result<FormatsReport> {
    let g = store.meta().georef.as_ref().ok_or_else(|| {
        anyhow::anyhow!("the terrain has no georeference: build it with --origin LON,LAT")
    })?;
    let geo = GeoTransform::new(g)?;
    let shape = &store.geometry().shape;
    let (w, h) = (shape.width(), shape.height());
    let cesium = CesiumLayer::new(&geo, w, h)?;
    let raster = RasterLayer::new(&geo, w, h, opts.tile_size)?;
    let r = Resampler::new(store, &geo);
    let mesh_tiles: Vec<TileXyz> = cesium
        .ranges
        .iter()
        .enumerate()
        .flat_map(|(z, range)| sample(range, z as u8, opts.max_per_level))
        .collect();
    let png_tiles: Vec<TileXyz> = (0..=raster.max_level)
        .filter_map(|z| Some((z, Scheme::Mercator.range(&raster.bounds, z)?)))
        .flat_map(|(z, range)| sample(&range, z, opts.max_per_level))
        .collect();
    let kinds = [MeshKind::Grid, MeshKind::Rqt, MeshKind::Tin];
    let total = (mesh_tiles.len() * kinds.len() + png_tiles.len() * 2) as u64;
    let bar = super::progress_bar(opts.progress, total, "tiles");
    let mut rows = Vec::new();
    for kind in kinds {
        let (mut bytes, mut gz, mut ms, mut tris) = (vec![], vec![], vec![], vec![]);
        let mut worst = 0.0f64;
        for &t in &mesh_tiles {
            let t0 = Instant::now();
            let m = tile_mesh(&r, kind, t);
            let b = m.bounds;
            let body = encode(
                &QmMesh {
                    west: b.west,
                    south: b.south,
                    east: b.east,
                    north: b.north,
                    vertices: m.vertices.clone(),
                    triangles: m.triangles.clone(),
                },
                &QmExtensions {
                    normals: true,
                    metadata: Some(cesium.metadata(t)),
                },
            )?;
            ms.push(t0.elapsed().as_secs_f64() * 1e3);
            bytes.push(body.len() as f64);
            gz.push(crate::bench::flight::gzip_len(&body) as f64);
            tris.push(m.triangles.len() as f64);
            if kind != MeshKind::Grid {
                worst = worst.max(f64::from(mesh_error(&r, kind, t)) / f64::from(tolerance(t.z)));
            }
            bar.inc(1);
        }
        let mut f = figures(
            format!("quantized-mesh/{}", kind.name()),
            &bytes,
            &gz,
            &ms,
            &tris,
        );
        f.worst_error_of_tolerance = worst;
        rows.push(f);
    }
    for enc in [Encoding::TerrainRgb, Encoding::Terrarium] {
        let (mut bytes, mut ms) = (vec![], vec![]);
        for &t in &png_tiles {
            let t0 = Instant::now();
            let png = tile_png(&r, enc, t, opts.tile_size);
            ms.push(t0.elapsed().as_secs_f64() * 1e3);
            bytes.push(png.len() as f64);
            bar.inc(1);
        }
        // PNGs are served as they are: gzip would not shrink them.
        rows.push(figures(
            format!("png/{}/{}", enc.name(), opts.tile_size),
            &bytes,
            &bytes,
            &ms,
            &[],
        ));
    }
    bar.finish_and_clear();
    Ok(FormatsReport {
        bounds: cesium.bounds.to_array(),
        cesium_max_level: cesium.max_level,
        raster_max_level: raster.max_level,
        kinds: rows,
    })
}

/// The largest vertical distance between tile `t`'s `kind` mesh and its resampled grid.
fn mesh_error(r: &Resampler<'_>, kind: MeshKind, t: TileXyz) -> f32 {
    let z = tile_heights(r, t);
    let grid = HeightGrid::new(TILE_POINTS, TILE_POINTS, &z).expect("a 65 x 65 grid");
    mesh_heights(&grid, kind, t.z).max_error(&grid)
}
