//! `relief-server bench query`: the query library ([`crate::query`]) on one core, in process.
//!
//! Rays start at the standard path's cameras (DESIGN.md section 7), each turned a random
//! amount within the standard view's half-width off the camera's heading: half of them graze
//! the terrain, 1-5 degrees down, half are steep, 20-80 degrees down. Each ray is cast by the
//! max-mip traversal and by the brute-force march in the same run, each timed on its own; every
//! pair of answers must be identical (the report counts the mismatches, and the command fails
//! if there is any). Throughput (rays/s, heights/s, HAT/HOT/s, lines of sight/s) is timed over
//! whole batches, without per-query clocks.
//!
//! Built with `--features peer-parry`, the same rays are also cast by parry3d's `HeightField`
//! (the query benchmark's peer), built over the same heights; the feature is off by default, so
//! that the server does not ship parry3d.

use super::stats::{median, quantile};
use crate::dem::Dem;
use crate::query::{HatHot, Interp, QueryError, Ray, Terrain};
use glam::DVec3;
use relief_proto::path::{PathKind, camera_path};
use serde::Serialize;
use std::hint::black_box;
use std::time::Instant;

/// What to run.
#[derive(Clone, Debug)]
pub struct QueryBenchOptions {
    /// Rays to cast (half grazing, half steep).
    pub rays: usize,
    /// Height queries to time.
    pub heights: usize,
    /// Seed of the random rays and points.
    pub seed: u64,
    /// Consecutive rays cast from one camera (1: each ray from a random pose), as a sensor
    /// sweeping from one place would: the caches then hold what the camera's rays share.
    pub rays_per_camera: usize,
}

impl Default for QueryBenchOptions {
    fn default() -> Self {
        QueryBenchOptions {
            rays: 20_000,
            heights: 2_000_000,
            seed: 16,
            rays_per_camera: 1,
        }
    }
}

/// The benchmark's figures.
#[derive(Clone, Debug, Serialize)]
pub struct QueryBenchReport {
    /// The DEM queried.
    pub dem: String,
    /// Grid width, samples.
    pub width: u32,
    /// Grid height, samples.
    pub height: u32,
    /// Time to build the max-mip and min-mip pyramids (and flip the heights), milliseconds.
    pub pyramid_build_ms: f64,
    /// Bytes of the two pyramids.
    pub pyramid_bytes: usize,
    /// Bytes of the heights the queries read.
    pub heights_bytes: usize,
    /// Rays cast by each method.
    pub rays: usize,
    /// Consecutive rays from one camera.
    pub rays_per_camera: usize,
    /// Of those, rays that hit the ground.
    pub hits: usize,
    /// Rays whose max-mip and brute-force answers differ (must be 0).
    pub mismatches: usize,
    /// Max-mip cast time per ray, median, microseconds.
    pub cast_us_median: f64,
    /// Max-mip cast time per ray, 99th percentile, microseconds.
    pub cast_us_p99: f64,
    /// Brute-force march time per ray, median, microseconds.
    pub march_us_median: f64,
    /// Brute-force march time per ray, 99th percentile, microseconds.
    pub march_us_p99: f64,
    /// Median march time over median cast time.
    pub speedup_median: f64,
    /// Median over rays of each ray's march time over its cast time.
    pub speedup_per_ray_median: f64,
    /// Grazing rays (1-5 degrees down): median cast time, microseconds.
    pub grazing_cast_us_median: f64,
    /// Grazing rays: median march time, microseconds.
    pub grazing_march_us_median: f64,
    /// Steep rays (20-80 degrees down): median cast time, microseconds.
    pub steep_cast_us_median: f64,
    /// Steep rays: median march time, microseconds.
    pub steep_march_us_median: f64,
    /// Grazing rays' hit distance, median, metres.
    pub grazing_distance_m_median: f64,
    /// Max-mip rays per second, one core, over the whole batch.
    pub rays_per_s: f64,
    /// Brute-force rays per second, one core, over the whole batch.
    pub march_rays_per_s: f64,
    /// Bilinear heights per second, one core, at random points.
    pub heights_per_s: f64,
    /// Bicubic heights per second, one core, at random points.
    pub bicubic_heights_per_s: f64,
    /// HAT/HOT (height, height above, normal) per second, one core.
    pub hat_hot_per_s: f64,
    /// Lines of sight per second (1 m clearance), one core, from the rays' cameras to random
    /// points 2 m above the ground 0.1-3 km away.
    pub los_per_s: f64,
    /// Of those lines of sight, the fraction blocked.
    pub los_blocked_fraction: f64,
    /// The peer, with `--features peer-parry` (none without).
    #[serde(flatten)]
    pub peer: Option<PeerReport>,
}

/// parry3d's `HeightField` ray cast on the same grid and rays, timed in the same run.
#[derive(Clone, Debug, Serialize)]
pub struct PeerReport {
    /// parry3d's cast time per ray, median, microseconds.
    pub parry_us_median: f64,
    /// parry3d's cast time per ray, 99th percentile, microseconds.
    pub parry_us_p99: f64,
    /// parry3d's median over the max-mip cast's median.
    pub parry_over_cast_median: f64,
    /// parry3d's rays per second, one core, over the whole batch.
    pub parry_rays_per_s: f64,
    /// Rays where one hits and the other does not. parry3d meets two triangles per cell
    /// (a fixed diagonal), not the bilinear patch, so grazing rays may differ.
    pub parry_hit_disagreements: usize,
    /// Median over rays both hit of the difference in hit distance, metres.
    pub parry_distance_diff_m_median: f64,
}

/// parry3d's height field over a DEM, in parry's frame (y up, centred on the origin).
#[cfg(feature = "peer-parry")]
struct Peer {
    /// The height field: rows along parry's z (our north), columns along x.
    field: parry3d_f64::shape::HeightField,
    /// Half the terrain's extent east and north, to centre our coordinates.
    half: (f64, f64),
}

#[cfg(feature = "peer-parry")]
impl Peer {
    fn new(dem: &Dem) -> Peer {
        use parry3d_f64::math::Vector;
        let (w, h) = (dem.width as usize, dem.height as usize);
        // parry's arrays are column-major; its row i is our i-th row from the south.
        let mut data = vec![0.0; w * h];
        for r in 0..h {
            for c in 0..w {
                data[(h - 1 - r) + c * h] = f64::from(dem.heights[r * w + c]);
            }
        }
        let ex = (w - 1) as f64 * dem.spacing_x;
        let ey = (h - 1) as f64 * dem.spacing_y;
        let heights = parry3d_f64::utils::Array2::new(h, w, data);
        Peer {
            field: parry3d_f64::shape::HeightField::new(heights, Vector::new(ex, 1.0, ey)),
            half: (ex / 2.0, ey / 2.0),
        }
    }

    /// The hit distance of `r`, metres.
    fn cast(&self, r: &Ray) -> Option<f64> {
        use parry3d_f64::math::Vector;
        use parry3d_f64::query::RayCast;
        let u = r.dir.normalize();
        let o = Vector::new(
            r.origin.x - self.half.0,
            r.origin.z,
            r.origin.y - self.half.1,
        );
        let ray = parry3d_f64::query::Ray::new(o, Vector::new(u.x, u.z, u.y));
        self.field.cast_local_ray(&ray, r.max_dist, true)
    }
}

/// The peer's figures on `rays`, against the max-mip cast's median `cast_median` and hits.
#[cfg(feature = "peer-parry")]
fn peer(
    dem: &Dem,
    rays: &[(Ray, bool)],
    hits: &[Option<f64>],
    cast_median: f64,
) -> Option<PeerReport> {
    let peer = Peer::new(dem);
    let (mut us, mut diff, mut disagree) = (Vec::new(), Vec::new(), 0);
    for ((ray, _), ours) in rays.iter().zip(hits) {
        let t = Instant::now();
        let theirs = black_box(peer.cast(black_box(ray)));
        us.push(t.elapsed().as_secs_f64() * 1e6);
        match (ours, theirs) {
            (Some(a), Some(b)) => diff.push((a - b).abs()),
            (None, None) => {}
            _ => disagree += 1,
        }
    }
    let t = Instant::now();
    for (ray, _) in rays {
        black_box(peer.cast(black_box(ray)));
    }
    let per_s = rays.len() as f64 / t.elapsed().as_secs_f64();
    let m = median(&us);
    Some(PeerReport {
        parry_us_median: m,
        parry_us_p99: quantile(&us, 0.99),
        parry_over_cast_median: m / cast_median.max(1e-9),
        parry_rays_per_s: per_s,
        parry_hit_disagreements: disagree,
        parry_distance_diff_m_median: median(&diff),
    })
}

/// Without `--features peer-parry`: no peer.
#[cfg(not(feature = "peer-parry"))]
fn peer(_: &Dem, _: &[(Ray, bool)], _: &[Option<f64>], _: f64) -> Option<PeerReport> {
    None
}

/// splitmix64, as a uniform in `[0, 1)`.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

/// Runs the benchmark on `dem`'s heights.
pub fn run(dem: &Dem, opts: &QueryBenchOptions) -> anyhow::Result<QueryBenchReport> {
    let t0 = Instant::now();
    let terrain = Terrain::new(
        dem.width,
        dem.height,
        dem.spacing_x,
        dem.spacing_y,
        &dem.heights,
    )?;
    let pyramid_build_ms = t0.elapsed().as_secs_f64() * 1e3;
    let (ex, ey) = terrain.extent();
    let ground = |x: f32, y: f32| {
        let x = f64::from(x).clamp(0.0, ex);
        let y = f64::from(y).clamp(0.0, ey);
        terrain.height(x, y).unwrap_or(0.0) as f32
    };
    let cams = camera_path(PathKind::Standard, ex as f32, ey as f32, ground);
    let mut rng = Rng(opts.seed);
    let half_fov = (30f64.to_radians().tan() * 16.0 / 9.0).atan();
    let max_dist = (ex * ex + ey * ey).sqrt();
    let per_camera = opts.rays_per_camera.max(1);
    let mut cam = &cams[0];
    let rays: Vec<(Ray, bool)> = (0..opts.rays.max(2))
        .map(|k| {
            if k % per_camera == 0 {
                cam = &cams[(rng.next() * cams.len() as f64) as usize % cams.len()];
            }
            let grazing = k % 2 == 0;
            let pitch = if grazing {
                -rng.range(1.0, 5.0)
            } else {
                -rng.range(20.0, 80.0)
            }
            .to_radians();
            let yaw = f64::from(cam.yaw) + rng.range(-half_fov, half_fov);
            let dir = DVec3::new(
                yaw.cos() * pitch.cos(),
                yaw.sin() * pitch.cos(),
                pitch.sin(),
            );
            let e = cam.eye;
            let origin = DVec3::new(f64::from(e.x), f64::from(e.y), f64::from(e.z));
            (
                Ray {
                    origin,
                    dir,
                    max_dist,
                },
                grazing,
            )
        })
        .collect();

    // Each ray by both methods, each timed on its own.
    let (mut cast_us, mut march_us, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
    let (mut graze, mut steep) = ((Vec::new(), Vec::new()), (Vec::new(), Vec::new()));
    let (mut hits, mut mismatches, mut graze_dist) = (0, 0, Vec::new());
    let mut distances = Vec::with_capacity(rays.len());
    for (ray, grazing) in &rays {
        let a0 = Instant::now();
        let a = black_box(terrain.cast(black_box(ray)))?;
        let ta = a0.elapsed().as_secs_f64() * 1e6;
        let b0 = Instant::now();
        let b = black_box(terrain.march(black_box(ray)))?;
        let tb = b0.elapsed().as_secs_f64() * 1e6;
        if a != b {
            mismatches += 1;
        }
        distances.push(a.map(|h| h.distance));
        if let Some(h) = a {
            hits += 1;
            if *grazing {
                graze_dist.push(h.distance);
            }
        }
        cast_us.push(ta);
        march_us.push(tb);
        ratio.push(tb / ta.max(1e-3));
        let side = if *grazing { &mut graze } else { &mut steep };
        side.0.push(ta);
        side.1.push(tb);
    }

    // Throughput over whole batches.
    let batch = |f: &dyn Fn(&Ray) -> Result<Option<crate::query::Hit>, QueryError>| {
        let t = Instant::now();
        let mut n = 0usize;
        for (ray, _) in &rays {
            n += usize::from(black_box(f(black_box(ray))).is_ok_and(|h| h.is_some()));
        }
        black_box(n);
        rays.len() as f64 / t.elapsed().as_secs_f64()
    };
    let rays_per_s = batch(&|r| terrain.cast(r));
    let march_rays_per_s = batch(&|r| terrain.march(r));

    let points: Vec<[f64; 2]> = (0..opts.heights.max(1))
        .map(|_| [rng.next() * ex, rng.next() * ey])
        .collect();
    let mut out = Vec::with_capacity(points.len());
    let per_s = |interp: Interp, out: &mut Vec<Result<f64, QueryError>>| {
        let t = Instant::now();
        terrain.heights(black_box(&points), interp, out);
        black_box(&out);
        points.len() as f64 / t.elapsed().as_secs_f64()
    };
    let heights_per_s = per_s(Interp::Bilinear, &mut out);
    let bicubic_heights_per_s = per_s(Interp::Bicubic, &mut out);
    let entities: Vec<DVec3> = points
        .iter()
        .map(|&[x, y]| DVec3::new(x, y, 500.0))
        .collect();
    let mut hh: Vec<Result<HatHot, QueryError>> = Vec::with_capacity(entities.len());
    let t = Instant::now();
    terrain.hat_hot_many(black_box(&entities), &mut hh);
    black_box(&hh);
    let hat_hot_per_s = entities.len() as f64 / t.elapsed().as_secs_f64();

    // Lines of sight from the cameras to points on the ground within 3 km.
    let pairs: Vec<(DVec3, DVec3)> = rays
        .iter()
        .map(|(r, _)| {
            let (d, a) = (
                rng.range(100.0, 3000.0),
                rng.range(0.0, std::f64::consts::TAU),
            );
            let x = (r.origin.x + d * a.cos()).clamp(0.0, ex);
            let y = (r.origin.y + d * a.sin()).clamp(0.0, ey);
            let z = terrain.height(x, y).unwrap_or(0.0) + 2.0;
            (r.origin, DVec3::new(x, y, z))
        })
        .collect();
    let t = Instant::now();
    let mut blocked = 0usize;
    for &(a, b) in &pairs {
        let s = black_box(terrain.line_of_sight(black_box(a), black_box(b), 1.0))?;
        blocked += usize::from(!s.is_visible());
    }
    let los_per_s = pairs.len() as f64 / t.elapsed().as_secs_f64();

    let cast_median = median(&cast_us);
    let march_median = median(&march_us);
    let peer = peer(dem, &rays, &distances, cast_median);
    Ok(QueryBenchReport {
        dem: dem.source.clone(),
        width: dem.width,
        height: dem.height,
        pyramid_build_ms,
        pyramid_bytes: terrain.pyramid().bytes(),
        heights_bytes: terrain.bytes() - terrain.pyramid().bytes(),
        rays: rays.len(),
        rays_per_camera: per_camera,
        hits,
        mismatches,
        cast_us_median: cast_median,
        cast_us_p99: quantile(&cast_us, 0.99),
        march_us_median: march_median,
        march_us_p99: quantile(&march_us, 0.99),
        speedup_median: march_median / cast_median.max(1e-9),
        speedup_per_ray_median: median(&ratio),
        grazing_cast_us_median: median(&graze.0),
        grazing_march_us_median: median(&graze.1),
        steep_cast_us_median: median(&steep.0),
        steep_march_us_median: median(&steep.1),
        grazing_distance_m_median: median(&graze_dist),
        rays_per_s,
        march_rays_per_s,
        heights_per_s,
        bicubic_heights_per_s,
        hat_hot_per_s,
        los_per_s,
        los_blocked_fraction: blocked as f64 / pairs.len() as f64,
        peer,
    })
}
