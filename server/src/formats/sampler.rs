//! Heights of the store at points of a global tile scheme: what every standard format is
//! resampled through.
//!
//! A point's height is the bilinear interpolation of the four store samples around its sample
//! position (the store's heights, rounded to its z quantum; voids hold their filled heights).
//! Where an output point stands for more ground than one sample (low zoom levels), up to 4 x 4
//! bilinear taps spread over its footprint are averaged, so that coarse tiles do not alias.
//! Points outside the store's samples have no height ([`None`]); each format says what it
//! writes there.
//!
//! Sample positions come from [`GeoTransform::sample`]. For a projected store that is a PROJ.4
//! inverse per point, so a tile's positions are computed exactly on a lattice every
//! [`LATTICE`] points and interpolated bilinearly between (the projections are smooth: the
//! interpolation moves a point by well under a thousandth of a sample).

use crate::geo::tiling::{Scheme, TileXyz};
use crate::geo::{GeoError, GeoTransform};
use crate::store::Store;

/// Points between exactly projected positions, for a projected store.
pub const LATTICE: usize = 8;
/// Most taps per axis when an output point covers many samples.
const MAX_TAPS: usize = 4;

/// Where the points of a tile lie within it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Points {
    /// `n` points a side from edge to edge, the first and last on the tile's edges (mesh
    /// vertices, as quantized-mesh wants them).
    Edges,
    /// `n` points a side at the centres of `n` equal cells (pixels, as PNG tiles want them).
    Centres,
}

/// Reads the store's heights at longitudes and latitudes.
pub struct Resampler<'a> {
    store: &'a Store,
    geo: &'a GeoTransform,
    width: u32,
    height: u32,
    quantum: f32,
}

impl<'a> Resampler<'a> {
    /// A resampler of `store`, placed on the Earth by `geo`.
    pub fn new(store: &'a Store, geo: &'a GeoTransform) -> Resampler<'a> {
        let g = store.geometry();
        Resampler {
            store,
            geo,
            width: g.shape.width(),
            height: g.shape.height(),
            quantum: g.z_quantum,
        }
    }

    /// The bilinear height at fractional sample position (`col`, `row`), or `None` outside
    /// the samples.
    pub fn bilinear(&self, col: f64, row: f64) -> Option<f32> {
        let (w, h) = ((self.width - 1) as f64, (self.height - 1) as f64);
        // Positions that went through a projection and back land a hair off the edge samples.
        const SLACK: f64 = 1e-6;
        if !(-SLACK..=w + SLACK).contains(&col) || !(-SLACK..=h + SLACK).contains(&row) {
            return None;
        }
        let (col, row) = (col.clamp(0.0, w), row.clamp(0.0, h));
        let (c0, r0) = (col.floor().min(w - 1.0), row.floor().min(h - 1.0));
        let (fx, fy) = ((col - c0) as f32, (row - r0) as f32);
        let (c, r) = (c0 as u32, r0 as u32);
        let z = |dc: u32, dr: u32| self.store.sample_z(c + dc, r + dr) as f32 * self.quantum;
        let top = z(0, 0) + (z(1, 0) - z(0, 0)) * fx;
        let bottom = z(0, 1) + (z(1, 1) - z(0, 1)) * fx;
        Some(top + (bottom - top) * fy)
    }

    /// The height at longitude `lon`, latitude `lat` (degrees), or `None` outside the store.
    pub fn at(&self, lon: f64, lat: f64) -> Result<Option<f32>, GeoError> {
        let [c, r] = self.geo.sample(lon, lat)?;
        Ok(self.bilinear(c, r))
    }

    /// Heights at `n` x `n` points of tile `t` of `scheme`, row by row from the north edge.
    pub fn tile(
        &self,
        scheme: Scheme,
        t: TileXyz,
        n: usize,
        points: Points,
    ) -> Result<Vec<Option<f32>>, GeoError> {
        let n = n.max(2);
        let frac = |i: usize| match points {
            Points::Edges => i as f64 / (n - 1) as f64,
            Points::Centres => (i as f64 + 0.5) / n as f64,
        };
        let exact = |i: usize, j: usize| -> Result<[f64; 2], GeoError> {
            let [lon, lat] = scheme.point(t, frac(i), frac(j));
            self.geo.sample(lon, lat)
        };
        let pos = self.positions(n, &exact)?;
        // The footprint of one output point, in samples along each axis, from the tile's
        // corners: beyond one sample, average taps across it.
        let span = |a: [f64; 2], b: [f64; 2]| [(b[0] - a[0]).abs(), (b[1] - a[1]).abs()];
        let across = span(pos[0], pos[n - 1]);
        let down = span(pos[0], pos[(n - 1) * n]);
        let step = [
            (across[0].max(down[0])) / (n - 1) as f64,
            (across[1].max(down[1])) / (n - 1) as f64,
        ];
        let taps = |s: f64| (s.round() as usize).clamp(1, MAX_TAPS);
        let (kx, ky) = (taps(step[0]), taps(step[1]));
        Ok(pos
            .iter()
            .map(|&[c, r]| {
                self.bilinear(c, r)?;
                let (mut sum, mut count) = (0.0f32, 0u32);
                for b in 0..ky {
                    let dr = ((b as f64 + 0.5) / ky as f64 - 0.5) * step[1];
                    for a in 0..kx {
                        let dc = ((a as f64 + 0.5) / kx as f64 - 0.5) * step[0];
                        if let Some(z) = self.bilinear(c + dc, r + dr) {
                            sum += z;
                            count += 1;
                        }
                    }
                }
                // The centre is inside, so some tap near it is too; fall back to it anyway.
                if count == 0 {
                    self.bilinear(c, r)
                } else {
                    Some(sum / count as f32)
                }
            })
            .collect())
    }

    /// Sample positions of the `n` x `n` points, exactly for a WGS 84 store, else exactly on a
    /// lattice and interpolated between.
    fn positions(
        &self,
        n: usize,
        exact: &dyn Fn(usize, usize) -> Result<[f64; 2], GeoError>,
    ) -> Result<Vec<[f64; 2]>, GeoError> {
        let mut out = vec![[0.0; 2]; n * n];
        if self.geo.georef().epsg == crate::geo::georef::EPSG_WGS84 {
            for j in 0..n {
                for i in 0..n {
                    out[j * n + i] = exact(i, j)?;
                }
            }
            return Ok(out);
        }
        let knots: Vec<usize> = (0..n)
            .step_by(LATTICE)
            .chain((!(n - 1).is_multiple_of(LATTICE)).then_some(n - 1))
            .collect();
        let m = knots.len();
        let mut lattice = Vec::with_capacity(m * m);
        for &j in &knots {
            for &i in &knots {
                lattice.push(exact(i, j)?);
            }
        }
        // For each index, the lattice cell it falls in and its fraction across.
        let cell = |i: usize| {
            let k = knots.partition_point(|&v| v <= i).clamp(1, m - 1) - 1;
            let f = (i - knots[k]) as f64 / (knots[k + 1] - knots[k]) as f64;
            (k, f)
        };
        for j in 0..n {
            let (kj, fj) = cell(j);
            for i in 0..n {
                let (ki, fi) = cell(i);
                let p = |a: usize, b: usize| lattice[(kj + b) * m + ki + a];
                let mut v = [0.0; 2];
                for (d, slot) in v.iter_mut().enumerate() {
                    let top = p(0, 0)[d] + (p(1, 0)[d] - p(0, 0)[d]) * fi;
                    let bottom = p(0, 1)[d] + (p(1, 1)[d] - p(0, 1)[d]) * fi;
                    *slot = top + (bottom - top) * fj;
                }
                out[j * n + i] = v;
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::{LoadOptions, load};
    use crate::geo::Georef;
    use crate::preprocess::{BuildOptions, build_store};

    /// A 65 x 65 synthetic store placed by `georef`.
    fn store(dir: &std::path::Path, georef: Georef) -> Store {
        let mut dem = load("synthetic:65", &LoadOptions::default()).unwrap();
        dem.georef = Some(georef);
        let path = dir.join("s.relief");
        build_store(&dem, &path, &BuildOptions::default()).unwrap();
        Store::open(&path).unwrap()
    }

    fn fuji_like() -> Georef {
        Georef {
            epsg: 4326,
            first: [138.0, 36.0],
            step: [1.0 / 1200.0, 1.0 / 1200.0],
        }
    }

    #[test]
    fn heights_at_samples_are_the_store_s_and_between_them_bilinear() {
        let dir = tempfile::tempdir().unwrap();
        let s = store(dir.path(), fuji_like());
        let geo = GeoTransform::new(&fuji_like()).unwrap();
        let r = Resampler::new(&s, &geo);
        let q = s.geometry().z_quantum;
        for (c, row) in [(0u32, 0u32), (64, 64), (17, 40)] {
            let [lon, lat] = geo.lonlat(c as f64, row as f64).unwrap();
            let z = r.at(lon, lat).unwrap().unwrap();
            assert!(
                (z - s.sample_z(c, row) as f32 * q).abs() < 1e-3,
                "{c},{row}"
            );
        }
        let mid = r.bilinear(10.5, 20.5).unwrap();
        let mean = [(10, 20), (11, 20), (10, 21), (11, 21)]
            .iter()
            .map(|&(c, row)| s.sample_z(c, row) as f32 * q)
            .sum::<f32>()
            / 4.0;
        assert!((mid - mean).abs() < 1e-3);
        assert_eq!(r.bilinear(-0.01, 3.0), None);
        assert_eq!(r.at(137.9, 35.99).unwrap(), None);
    }

    #[test]
    fn projected_tiles_on_a_lattice_agree_with_exact_positions() {
        let dir = tempfile::tempdir().unwrap();
        // UTM 54N, 10 m samples near Mt Fuji.
        let g = Georef {
            epsg: 32654,
            first: [290_000.0, 3_920_000.0],
            step: [10.0, 10.0],
        };
        let s = store(dir.path(), g.clone());
        let geo = GeoTransform::new(&g).unwrap();
        let r = Resampler::new(&s, &geo);
        let bounds = geo.bounds(65, 65).unwrap();
        for (scheme, z, n, points) in [
            (Scheme::Geographic, 15, 65, Points::Edges),
            (Scheme::Mercator, 14, 256, Points::Centres),
        ] {
            let range = scheme.range(&bounds, z).unwrap();
            let t = TileXyz {
                z,
                x: range.start_x,
                y: range.start_y,
            };
            let got = r.tile(scheme, t, n, points).unwrap();
            let frac = |i: usize| match points {
                Points::Edges => i as f64 / (n - 1) as f64,
                Points::Centres => (i as f64 + 0.5) / n as f64,
            };
            let mut inside = 0;
            for j in 0..n {
                for i in 0..n {
                    let [lon, lat] = scheme.point(t, frac(i), frac(j));
                    let [c, row] = geo.sample(lon, lat).unwrap();
                    let want = r.bilinear(c, row);
                    let g = got[j * n + i];
                    assert_eq!(g.is_some(), want.is_some(), "{scheme:?} {i},{j}");
                    if let (Some(a), Some(b)) = (g, want) {
                        // The footprint is under a sample here, so one tap: the same point
                        // up to the lattice's interpolation.
                        assert!((a - b).abs() < 0.05, "{scheme:?} {i},{j}: {a} {b}");
                        inside += 1;
                    }
                }
            }
            assert!(inside > 0, "{scheme:?}: the tile misses the store");
        }
    }

    #[test]
    fn coarse_tiles_average_their_footprint_and_stay_in_range() {
        let dir = tempfile::tempdir().unwrap();
        let s = store(dir.path(), fuji_like());
        let geo = GeoTransform::new(&fuji_like()).unwrap();
        let r = Resampler::new(&s, &geo);
        let (lo, hi) = (s.meta().height_min as f32, s.meta().height_max as f32);
        let b = geo.bounds(65, 65).unwrap();
        let range = Scheme::Geographic.range(&b, 6).unwrap();
        let t = TileXyz {
            z: 6,
            x: range.start_x,
            y: range.start_y,
        };
        let z = r.tile(Scheme::Geographic, t, 65, Points::Edges).unwrap();
        let inside: Vec<f32> = z.iter().flatten().copied().collect();
        assert!(!inside.is_empty() && inside.len() < z.len());
        assert!(inside.iter().all(|&h| h >= lo - 0.01 && h <= hi + 0.01));
    }
}
