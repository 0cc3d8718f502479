//! What the stream benchmarks share: the store built for the DEM, the camera path flown over it
//! (DESIGN.md section 7), and the measured pixel error of the frames they draw.

use super::stats::{mean, median, quantile};
use crate::dem::Dem;
use crate::lod::measure::{Lattice, frame_errors};
use crate::preprocess::{self, BuildReport};
use crate::store::Store;
use glam::Vec3;
use relief_proto::path::{PathKind, camera_path};
use relief_proto::view::{Camera, Lens};
use serde::Serialize;

/// A store and the path flown over it.
pub struct Flight {
    /// The store, built in `_dir`.
    pub store: Store,
    /// One camera per pose, at [`relief_proto::path::PATH_HZ`].
    pub cams: Vec<Camera>,
    /// Measure pixel error on every k-th frame.
    pub px_every: usize,
    /// Minimum samples of each measured frame's lattice.
    pub px_min_samples: u64,
    /// How the store build went.
    pub built: BuildReport,
    /// Keeps the store's folder alive.
    _dir: tempfile::TempDir,
}

impl Flight {
    /// The same flight cut to its first `poses` poses (`None`: unchanged).
    pub fn first_poses(mut self, poses: Option<usize>) -> Flight {
        if let Some(n) = poses {
            self.cams.truncate(n.max(2));
        }
        self
    }

    /// Builds the store of `dem` (as `build` says) in a temporary folder and the
    /// camera path `path` over it. `px_every` `None` picks k so that at least 60 frames and
    /// about 20 M samples are measured.
    pub fn prepare(
        dem: &Dem,
        path: PathKind,
        build: preprocess::BuildOptions,
        px_every: Option<usize>,
        px_min_samples: u64,
        progress: bool,
    ) -> anyhow::Result<Flight> {
        let dir = tempfile::tempdir()?;
        let store_path = dir.path().join("bench.relief");
        let built = preprocess::build_store(
            dem,
            &store_path,
            &preprocess::BuildOptions { progress, ..build },
        )?;
        let store = Store::open(&store_path)?;
        let cams = Flight::paths_over(dem, &store, |extent, ground| {
            camera_path(path, extent.0, extent.1, ground)
        });
        let (w, h) = (
            store.geometry().shape.width(),
            store.geometry().shape.height(),
        );
        let frames = cams.len();
        let px_every = px_every.unwrap_or_else(|| {
            let lat = Lattice::for_grid(w, h, px_min_samples, 0);
            let per_frame = (w as u64 / lat.stride as u64) * (h as u64 / lat.stride as u64);
            let budget = (20_000_000 / per_frame.max(1)).max(60) as usize;
            (frames / budget.min(frames)).clamp(1, (frames / 60).max(1))
        });
        Ok(Flight {
            store,
            cams,
            px_every,
            px_min_samples,
            built,
            _dir: dir,
        })
    }

    /// What `make` builds from the terrain's extent in metres (the grid's, from the first sample
    /// to the last) and its ground height at a point (the DEM's nearest sample): a camera path.
    pub fn paths_over<T>(
        dem: &Dem,
        store: &Store,
        make: impl FnOnce((f32, f32), &dyn Fn(f32, f32) -> f32) -> T,
    ) -> T {
        let geom = store.geometry();
        let (w, h) = (geom.shape.width(), geom.shape.height());
        let ground = |x: f32, y: f32| {
            let (c, r) = geom.frame.to_grid(x, y);
            let c = (c.round().max(0.0) as u32).min(w - 1);
            let r = (r.round().max(0.0) as u32).min(h - 1);
            dem.heights[(r * w + c) as usize]
        };
        let extent = (
            (w - 1) as f32 * geom.frame.dx,
            (h - 1) as f32 * geom.frame.dy,
        );
        make(extent, &ground)
    }

    /// Grid width and height, samples.
    pub fn size(&self) -> (u32, u32) {
        let s = &self.store.geometry().shape;
        (s.width(), s.height())
    }
}

/// Pixel errors gathered over the measured frames.
#[derive(Default)]
pub struct PxAccum {
    /// Each measured frame's 99th percentile.
    p99: Vec<f64>,
    /// Each measured frame's in-view samples.
    samples: Vec<f64>,
    /// Largest error of any sample.
    max: f64,
    /// In-view samples no triangle covers.
    uncovered: u64,
    /// In-view samples measured.
    covered: u64,
}

/// The pixel-error fields of a benchmark report (DESIGN.md section 7); meanings in the README.
#[derive(Clone, Debug, Serialize)]
pub struct PxSummary {
    /// Worst measured frame's 99th-percentile pixel error.
    pub px_error_p99_max: f64,
    /// Median measured frame's 99th-percentile pixel error.
    pub px_error_p99_median: f64,
    /// Largest pixel error of any measured sample.
    pub px_error_max: f64,
    /// Frames whose pixel error was measured.
    pub px_error_frames: usize,
    /// In-view samples measured per measured frame (mean).
    pub px_error_samples_per_frame: f64,
    /// Grid samples in each measured frame's lattice (all samples when the stride is 1).
    pub px_error_lattice_samples: u64,
    /// Stride of that lattice, in samples.
    pub px_error_lattice_stride: u32,
    /// In-view samples outside the mesh's outline, as a fraction.
    pub px_error_uncovered_fraction: f64,
}

impl PxAccum {
    /// Measures frame `f` drawn as `tris` (world triangles) from `cam`.
    pub fn measure(
        &mut self,
        flight: &Flight,
        dem: &Dem,
        tris: &[[Vec3; 3]],
        f: usize,
        lens: &Lens,
    ) {
        let (w, h) = flight.size();
        let lat = Lattice::for_grid(w, h, flight.px_min_samples, f);
        let store = &flight.store;
        let fe = frame_errors(
            store.geometry(),
            &dem.heights,
            |c, r| store.is_void(c, r),
            tris,
            &flight.cams[f],
            lens,
            lat,
        );
        let errs: Vec<f64> = fe.errors.iter().map(|&v| v as f64).collect();
        self.p99.push(quantile(&errs, 0.99));
        if std::env::var("PXDEBUG").is_ok() {
            eprintln!(
                "frame {f} p99 {:.3} max {:.2} n {}",
                quantile(&errs, 0.99),
                errs.iter().copied().fold(0.0, f64::max),
                errs.len()
            );
        }
        self.max = self.max.max(errs.iter().copied().fold(0.0, f64::max));
        self.samples.push((errs.len() as u64 + fe.uncovered) as f64);
        self.uncovered += fe.uncovered;
        self.covered += errs.len() as u64;
    }

    /// The report's fields.
    pub fn summary(&self, flight: &Flight) -> PxSummary {
        let (w, h) = flight.size();
        let l = Lattice::for_grid(w, h, flight.px_min_samples, 0);
        PxSummary {
            px_error_p99_max: quantile(&self.p99, 1.0),
            px_error_p99_median: median(&self.p99),
            px_error_max: self.max,
            px_error_frames: self.p99.len(),
            px_error_samples_per_frame: mean(&self.samples),
            px_error_lattice_samples: l.count(w, 0) as u64 * l.count(h, 0) as u64,
            px_error_lattice_stride: l.stride,
            px_error_uncovered_fraction: self.uncovered as f64
                / (self.uncovered + self.covered).max(1) as f64,
        }
    }
}

/// The cost fields of a benchmark report; meanings in the README.
#[derive(Clone, Debug, Serialize)]
pub struct CostSummary {
    /// Server time per pose (update plus delta encoding), median, microseconds.
    pub update_us_median: f64,
    /// Same, 99th percentile.
    pub update_us_p99: f64,
    /// The same selection or cut computed from scratch for the same pose, median, microseconds.
    pub scratch_us_median: f64,
    /// Client time per delta (decode, apply, digest, mesh), median, microseconds.
    pub client_us_median: f64,
    /// Same, 99th percentile.
    pub client_us_p99: f64,
}

impl CostSummary {
    /// The summary of per-pose times, microseconds.
    pub fn of(update: &[f64], scratch: &[f64], client: &[f64]) -> CostSummary {
        CostSummary {
            update_us_median: median(update),
            update_us_p99: quantile(update, 0.99),
            scratch_us_median: median(scratch),
            client_us_median: median(client),
            client_us_p99: quantile(client, 0.99),
        }
    }
}

/// The bytes a stream sent over a flight, frame by frame: raw and as gzip would send each
/// message (deflate per message, as HTTP or WebSocket compression does).
#[derive(Clone, Debug, Default)]
pub struct WireBytes {
    /// Per frame: (raw bytes, gzipped bytes).
    frames: Vec<(u64, u64)>,
}

/// What [`WireBytes`] reports.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct WireSummary {
    /// All bytes over the path, the first frame's (the session start) included.
    pub bytes_total: u64,
    /// Same, each message gzipped.
    pub gzip_bytes_total: u64,
    /// Bytes per second over the path after the first frame: mean.
    pub bytes_per_s_mean: f64,
    /// Same, the 99th percentile of one-second bins.
    pub bytes_per_s_p99: f64,
    /// Gzipped bytes per second after the first frame: mean.
    pub gzip_bytes_per_s_mean: f64,
    /// Same, the 99th percentile of one-second bins.
    pub gzip_bytes_per_s_p99: f64,
}

impl WireBytes {
    /// Adds the next frame's message.
    pub fn push(&mut self, msg: &[u8]) {
        self.frames.push((msg.len() as u64, gzip_len(msg) as u64));
    }

    /// Adds the next frame's bytes, raw and gzipped, when they are not one message (tiles over
    /// HTTP, each gzipped on its own).
    pub fn push_sizes(&mut self, raw: u64, gzip: u64) {
        self.frames.push((raw, gzip));
    }

    /// The totals, and the rates in bins of `hz` frames (one second of the path).
    pub fn summary(&self, hz: usize) -> WireSummary {
        let total = |k: fn(&(u64, u64)) -> u64| self.frames.iter().map(k).sum::<u64>();
        let rest = self.frames.get(1..).unwrap_or(&[]);
        let seconds = (rest.len() as f64 / hz as f64).max(1.0 / hz as f64);
        let bins = |k: fn(&(u64, u64)) -> u64| -> Vec<f64> {
            rest.chunks(hz.max(1))
                .filter(|c| c.len() == hz.max(1))
                .map(|c| c.iter().map(k).sum::<u64>() as f64)
                .collect()
        };
        let raw = |f: &(u64, u64)| f.0;
        let gz = |f: &(u64, u64)| f.1;
        WireSummary {
            bytes_total: total(raw),
            gzip_bytes_total: total(gz),
            bytes_per_s_mean: rest.iter().map(raw).sum::<u64>() as f64 / seconds,
            bytes_per_s_p99: quantile(&bins(raw), 0.99),
            gzip_bytes_per_s_mean: rest.iter().map(gz).sum::<u64>() as f64 / seconds,
            gzip_bytes_per_s_p99: quantile(&bins(gz), 0.99),
        }
    }
}

/// The length of `b` gzipped at the default level.
pub fn gzip_len(b: &[u8]) -> usize {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    let _ = e.write_all(b);
    e.finish().map_or(0, |v| v.len())
}
