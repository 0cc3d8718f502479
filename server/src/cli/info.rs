//! `relief-server info`: what a store holds, as one JSON object, and with `--fractal` paper
//! 002's region tree over the store's own heights (`docs/fractal.md`).

use crate::lod::tile::mesh::HeightGrid;
use crate::lod::tile::mesh::fractal::{
    FractalParams, LeafStop, fractal_leaves_with_progress, leaf_level,
};
use crate::store::Store;
use serde::Serialize;
use std::path::Path;
use std::time::{Duration, Instant};

/// The store's description: what `relief-server info` prints without `--fractal`.
pub(super) fn store_info(path: &Path, s: &Store) -> serde_json::Value {
    let g = s.geometry();
    serde_json::json!({
        "file": path.display().to_string(),
        "bytes": s.file_len(),
        "width": g.shape.width(),
        "height": g.shape.height(),
        "depth": g.shape.depth(),
        "nodes": g.shape.node_count(),
        "spacing_m": [g.frame.dx, g.frame.dy],
        "z_quantum_m": g.z_quantum,
        "tiles": {
            "tile_size": s.tile_info().tile_size,
            "depth": s.tile_info().depth,
            "mesh": s.tile_info().mesh,
            "level_errors_m": s.tile_info().level_errors,
        },
        "tile_count": s.tile_shape().tile_count(),
        "meta": s.meta(),
    })
}

/// A threshold on the command line: a number from 2 to 3 (clap's value parser).
pub(super) fn dimension_arg(s: &str) -> Result<f32, String> {
    let d: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number"))?;
    check_dimension(d)
}

/// `d` if it is a dimension a threshold can be: finite, from 2 to 3.
fn check_dimension(d: f32) -> Result<f32, String> {
    if !d.is_finite() {
        return Err(format!("{d} is not a finite number"));
    }
    if !(2.0..=3.0).contains(&d) {
        return Err(format!(
            "{d} is outside [2, 3]: a surface's box-counting dimension lies between 2 (a plane) \
             and 3 (see docs/fractal.md)"
        ));
    }
    Ok(d)
}

/// The region tree's parameters for `--flat` and `--rough`, checked: both finite and in
/// [2, 3], and `flat` not above `rough` (equal thresholds are a step: flat regions stop, all
/// others go down to the finest tiles).
pub(super) fn fractal_params(flat: f32, rough: f32) -> anyhow::Result<FractalParams> {
    for (name, d) in [("--flat", flat), ("--rough", rough)] {
        check_dimension(d).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    }
    if flat > rough {
        anyhow::bail!(
            "--flat {flat} is above --rough {rough}: regions at or below flat stop subdividing \
             and regions at or above rough go down to the finest tiles, so flat must not exceed \
             rough"
        );
    }
    Ok(FractalParams {
        flat,
        rough,
        ..FractalParams::default()
    })
}

/// The region tree over a store: its parameters, a summary, and every leaf.
#[derive(Clone, Debug, Serialize)]
pub(crate) struct FractalReport {
    /// Dimension at or below which a region is a leaf whatever its size.
    pub flat: f64,
    /// Dimension at or above which a region subdivides down to the finest tiles.
    pub rough: f64,
    /// Box sizes per estimate (1, 2, 4, ... cells).
    pub scales: u32,
    /// The regions are the tile pyramid's tiles: its tile size in cells...
    pub tile_size: u32,
    /// ...and its finest level.
    pub depth: u8,
    /// How many leaves.
    pub leaf_count: usize,
    /// Leaves at each pyramid level, level 0 (the root) first.
    pub per_level: Vec<usize>,
    /// Leaves by why they stopped (see [`LeafStop`]).
    pub by_stop: ByStop,
    /// The leaves' dimensions: least, median and greatest (`null` when no leaf has one).
    pub dimension: Option<Spread>,
    /// The leaves' dimensions in bins 0.01 wide, from the least's bin to the greatest's.
    pub histogram: Vec<Bin>,
    /// The leaves, depth first, children in `TileId::child` order.
    pub leaves: Vec<LeafReport>,
}

/// Leaves counted by why they stopped.
#[derive(Clone, Debug, Default, Serialize)]
pub(crate) struct ByStop {
    /// At or below `flat`.
    pub flat: usize,
    /// Between the thresholds, no larger than the dimension allows.
    pub sized: usize,
    /// Finest-level tiles whose dimension asks for the finest tiles.
    pub finest: usize,
    /// Under 16 cells across: no dimension.
    pub no_dimension: usize,
}

/// Least, median and greatest.
#[derive(Clone, Copy, Debug, Serialize)]
pub(crate) struct Spread {
    /// Least.
    pub min: f64,
    /// Median (the lower one of an even count).
    pub median: f64,
    /// Greatest.
    pub max: f64,
}

/// One histogram bin: dimensions in `[from, to)`.
#[derive(Clone, Copy, Debug, Serialize)]
pub(crate) struct Bin {
    /// Lower bound, included.
    pub from: f64,
    /// Upper bound, excluded.
    pub to: f64,
    /// Leaves whose dimension (as printed, to 4 decimals) falls in the bin.
    pub leaves: usize,
}

/// One leaf of the region tree.
#[derive(Clone, Debug, Serialize)]
pub(crate) struct LeafReport {
    /// Pyramid level of its tile (0 = the root).
    pub level: u8,
    /// Tile column within the level.
    pub x: u32,
    /// Tile row within the level (0 north).
    pub y: u32,
    /// First and last sample column it covers.
    pub cols: [u32; 2],
    /// First and last sample row it covers.
    pub rows: [u32; 2],
    /// Its box-counting dimension, to 4 decimals; `null` under 16 cells across.
    pub dimension: Option<f64>,
    /// The coarsest level its dimension allows as a leaf (`null` without a dimension).
    pub leaf_level: Option<u8>,
    /// Why it stopped: `flat`, `sized`, `finest` or `no_dimension`.
    pub stop: &'static str,
}

/// The region tree over the store's heights (each sample as stored, [`Store::heights`]) and its
/// tile pyramid's tiles. With `progress`, a bar on stderr once it has run for a second.
pub(crate) fn fractal_report(
    s: &Store,
    params: &FractalParams,
    progress: bool,
) -> anyhow::Result<FractalReport> {
    let start = Instant::now();
    let shape = s.tile_shape();
    let heights = s.heights();
    let grid = HeightGrid::new(shape.width() as usize, shape.height() as usize, &heights)
        .ok_or_else(|| anyhow::anyhow!("the store's grid is under 2 x 2 samples"))?;
    let frame = s.geometry().frame;
    let spacing = [f64::from(frame.dx), f64::from(frame.dy)];
    // No bar until the computation has taken a second: small stores print none at all.
    let mut bar: Option<indicatif::ProgressBar> = None;
    let leaves = fractal_leaves_with_progress(&grid, spacing, shape, params, |f| {
        if bar.is_none() && progress && start.elapsed() > Duration::from_secs(1) {
            bar = Some(crate::bench::progress_bar(true, 1000, "fractal"));
        }
        if let Some(b) = &bar {
            b.set_position((f * 1000.0) as u64);
        }
    });
    if let Some(b) = bar {
        b.finish_and_clear();
    }

    let depth = shape.depth();
    let round4 = |d: f32| (f64::from(d) * 1e4).round() / 1e4;
    let mut per_level = vec![0usize; depth as usize + 1];
    let mut by_stop = ByStop::default();
    let mut out = Vec::with_capacity(leaves.len());
    for l in &leaves {
        per_level[l.tile.level as usize] += 1;
        let stop = LeafStop::of(params, l, depth);
        *match stop {
            LeafStop::Flat => &mut by_stop.flat,
            LeafStop::Sized => &mut by_stop.sized,
            LeafStop::Finest => &mut by_stop.finest,
            LeafStop::NoDimension => &mut by_stop.no_dimension,
        } += 1;
        let span = shape.span(l.tile);
        out.push(LeafReport {
            level: l.tile.level,
            x: l.tile.x,
            y: l.tile.y,
            cols: [span.cols.0, span.cols.1],
            rows: [span.rows.0, span.rows.1],
            dimension: l.dimension.map(round4),
            leaf_level: l.dimension.map(|d| leaf_level(params, d, depth)),
            stop: stop.name(),
        });
    }
    let mut ds: Vec<f64> = out.iter().filter_map(|l| l.dimension).collect();
    ds.sort_by(f64::total_cmp);
    let dimension = (!ds.is_empty()).then(|| Spread {
        min: ds[0],
        median: ds[(ds.len() - 1) / 2],
        max: ds[ds.len() - 1],
    });
    Ok(FractalReport {
        flat: decimal(params.flat),
        rough: decimal(params.rough),
        scales: params.scales,
        tile_size: shape.tile_size(),
        depth,
        leaf_count: out.len(),
        per_level,
        by_stop,
        dimension,
        histogram: histogram(&ds),
        leaves: out,
    })
}

/// `x` as the shortest decimal that reads back as it (2.01, not 2.009999990463257).
fn decimal(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// `ds` (sorted) in bins 0.01 wide, empty bins between included.
fn histogram(ds: &[f64]) -> Vec<Bin> {
    // The bin of a dimension printed to 4 decimals; the nudge keeps 2.0100 out of 2.00's bin.
    let bin = |d: f64| (d * 100.0 + 1e-6).floor() as i64;
    let (Some(&lo), Some(&hi)) = (ds.first(), ds.last()) else {
        return Vec::new();
    };
    let (lo, hi) = (bin(lo), bin(hi));
    let mut bins: Vec<Bin> = (lo..=hi)
        .map(|k| Bin {
            from: k as f64 / 100.0,
            to: (k + 1) as f64 / 100.0,
            leaves: 0,
        })
        .collect();
    for &d in ds {
        bins[(bin(d) - lo) as usize].leaves += 1;
    }
    bins
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::preprocess::{self, BuildOptions};
    use crate::store::{StoreInput, StoreMeta, write_store};

    /// Cells covered by each leaf, counted per cell: every one must be 1.
    fn coverage(s: &Store, r: &FractalReport) -> Vec<u32> {
        let w = s.tile_shape().width() as usize - 1;
        let h = s.tile_shape().height() as usize - 1;
        let mut seen = vec![0u32; w * h];
        for l in &r.leaves {
            for row in l.rows[0]..l.rows[1] {
                for col in l.cols[0]..l.cols[1] {
                    seen[row as usize * w + col as usize] += 1;
                }
            }
        }
        seen
    }

    fn embedded_store(dir: &Path, tile_size: u32) -> Store {
        let d = crate::dem::embedded_default().unwrap();
        let path = dir.join(format!("fuji-{tile_size}.relief"));
        let opts = BuildOptions {
            tile_size,
            ..BuildOptions::default()
        };
        preprocess::build_store(&d, &path, &opts).unwrap();
        Store::open(&path).unwrap()
    }

    /// What holds of every report: the leaves tile the grid once, are their tiles, agree with
    /// their stop and the summary; dimensions lie in [2, 3].
    fn check(s: &Store, p: &FractalParams, r: &FractalReport) {
        assert!(coverage(s, r).iter().all(|&n| n == 1), "{r:?}");
        assert_eq!(r.leaf_count, r.leaves.len());
        assert_eq!(r.per_level.len(), s.tile_shape().depth() as usize + 1);
        assert_eq!(r.per_level.iter().sum::<usize>(), r.leaf_count);
        let b = &r.by_stop;
        assert_eq!(b.flat + b.sized + b.finest + b.no_dimension, r.leaf_count);
        let binned: usize = r.histogram.iter().map(|b| b.leaves).sum();
        assert_eq!(binned + b.no_dimension, r.leaf_count);
        for l in &r.leaves {
            let span = s.tile_shape().span(relief_proto::tile::TileId {
                level: l.level,
                x: l.x,
                y: l.y,
            });
            assert_eq!(
                (l.cols, l.rows),
                ([span.cols.0, span.cols.1], [span.rows.0, span.rows.1])
            );
            if let (Some(d), Some(ll)) = (l.dimension, l.leaf_level) {
                // Between 2 and 3, but a smooth 16-cell region (3 box sizes) can measure a
                // hair under 2: 1.9985 in this crop.
                assert!((1.99..=3.0).contains(&d), "{l:?}");
                // No leaf is coarser than its dimension allows.
                assert!(l.level >= ll, "{l:?}");
            }
            let d = l.dimension.unwrap_or(f64::NAN);
            match l.stop {
                "flat" => assert!(d <= f64::from(p.flat) + 1e-4, "{l:?}"),
                "finest" => assert!(l.level == r.depth && d > f64::from(p.flat), "{l:?}"),
                "sized" => assert!(d > f64::from(p.flat) - 1e-4, "{l:?}"),
                "no_dimension" => assert!(l.dimension.is_none(), "{l:?}"),
                other => panic!("unknown stop {other}"),
            }
        }
        if let Some(spread) = r.dimension {
            assert!(spread.min <= spread.median && spread.median <= spread.max);
        }
    }

    #[test]
    fn the_embedded_terrain_s_leaves_tile_the_grid_once() {
        let dir = tempfile::tempdir().unwrap();
        let s = embedded_store(dir.path(), 64);
        // Defaults: the crop (Mt Fuji's cone at 90 m) measures 2.0065 at the root, so flat.
        let p = FractalParams::default();
        let r = fractal_report(&s, &p, false).unwrap();
        check(&s, &p, &r);
        assert_eq!((r.leaf_count, r.leaves[0].stop), (1, "flat"), "{r:?}");
        // Thresholds inside the crop's range give a tree with every kind of stop.
        let p = fractal_params(2.004, 2.006).unwrap();
        let r = fractal_report(&s, &p, false).unwrap();
        check(&s, &p, &r);
        assert!(r.leaf_count > 4, "{r:?}");
        let b = &r.by_stop;
        assert!(b.flat > 0 && b.sized > 0 && b.finest > 0, "{b:?}");
        // The store's heights are the DEM's (whole metres, a 1 m quantum): the same tree as
        // over the DEM itself.
        let d = crate::dem::embedded_default().unwrap();
        let g = HeightGrid::new(d.width as usize, d.height as usize, &d.heights).unwrap();
        let spacing = [d.spacing_x, d.spacing_y];
        let direct =
            crate::lod::tile::mesh::fractal::fractal_leaves(&g, spacing, s.tile_shape(), &p);
        let got: Vec<_> = r.leaves.iter().map(|l| (l.level, l.x, l.y)).collect();
        let want: Vec<_> = direct
            .iter()
            .map(|l| (l.tile.level, l.tile.x, l.tile.y))
            .collect();
        assert_eq!(got, want);
        // Equal thresholds at 3: everything is flat, the root alone. At 2, nothing is: every
        // leaf is a finest tile.
        let p = fractal_params(3.0, 3.0).unwrap();
        let r = fractal_report(&s, &p, false).unwrap();
        check(&s, &p, &r);
        assert_eq!((r.leaf_count, r.leaves[0].stop), (1, "flat"));
        let p = fractal_params(2.0, 2.0).unwrap();
        let r = fractal_report(&s, &p, false).unwrap();
        check(&s, &p, &r);
        assert!(r.leaves.iter().all(|l| l.level == r.depth), "{r:?}");
        assert_eq!(r.by_stop.finest, r.leaf_count);
        // 8-cell tiles: the finest are too small for a dimension. Every other leaf measured
        // at most 2, a flat 16-cell patch.
        let s = embedded_store(dir.path(), 8);
        let r = fractal_report(&s, &p, false).unwrap();
        check(&s, &p, &r);
        let b = &r.by_stop;
        assert!(
            b.no_dimension > 0 && b.flat + b.no_dimension == r.leaf_count,
            "{b:?}"
        );
        for l in &r.leaves {
            assert_eq!(l.level == r.depth, l.stop == "no_dimension", "{l:?}");
        }
    }

    #[test]
    fn a_tilted_plane_is_one_flat_leaf() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (300u32, 170u32);
        let heights: Vec<f32> = (0..w * h)
            .map(|i| 800.0 + 3.0 * (i % w) as f32 - 1.7 * (i / w) as f32)
            .collect();
        let voids = crate::dem::VoidMask::new(heights.len());
        let path = dir.path().join("plane.relief");
        let input = StoreInput {
            width: w,
            height: h,
            spacing_x: 30.0,
            spacing_y: 30.0,
            z_quantum: 0.1,
            heights: &heights,
            voids: &voids,
            tile_size: 32,
            meta: StoreMeta::default(),
        };
        write_store(&path, &input, |_| {}).unwrap();
        let s = Store::open(&path).unwrap();
        assert!(s.tile_shape().depth() >= 2);
        let r = fractal_report(&s, &FractalParams::default(), false).unwrap();
        assert_eq!(r.leaf_count, 1, "{r:?}");
        let l = &r.leaves[0];
        assert_eq!((l.level, l.stop, l.leaf_level), (0, "flat", Some(0)));
        assert_eq!((l.cols, l.rows), ([0, w - 1], [0, h - 1]));
        assert!((l.dimension.unwrap() - 2.0).abs() < 0.01, "{l:?}");
        assert_eq!(r.per_level[0], 1);
        assert_eq!(r.per_level.len(), r.depth as usize + 1);
    }

    #[test]
    fn bad_thresholds_are_refused_with_a_reason() {
        for bad in ["NaN", "nan", "inf", "-inf", "abc", "", "1.9", "3.5", "-2"] {
            assert!(dimension_arg(bad).is_err(), "{bad}");
        }
        assert_eq!(dimension_arg(" 2.3 "), Ok(2.3));
        let e = fractal_params(2.05, 2.04).unwrap_err().to_string();
        assert!(e.contains("--flat 2.05 is above --rough 2.04"), "{e}");
        assert!(fractal_params(f32::NAN, 2.04).is_err());
        assert!(fractal_params(2.01, f32::INFINITY).is_err());
        assert_eq!(
            fractal_params(2.01, 2.04).unwrap(),
            FractalParams::default()
        );
        assert!(fractal_params(2.02, 2.02).is_ok());
    }

    #[test]
    fn the_histogram_bins_by_hundredths() {
        let h = histogram(&[2.0031, 2.0099, 2.01, 2.0349]);
        let got: Vec<_> = h.iter().map(|b| (b.from, b.leaves)).collect();
        assert_eq!(decimal(2.01), 2.01);
        assert_eq!(got, [(2.0, 2), (2.01, 1), (2.02, 0), (2.03, 1)]);
        assert!(histogram(&[]).is_empty());
    }
}
