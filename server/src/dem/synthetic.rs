//! `synthetic:SIZE[:SEED]`: a deterministic fractal terrain of SIZE x SIZE samples, 10 m apart,
//! with mountain ranges, carved valleys and flat plains, for tests and benchmarks at any size up
//! to 16385.
//!
//! Value noise on an integer-hashed lattice, summed over octaves (fBm). A ridged sum shapes the
//! mountains, a low-frequency mask decides where mountains rise and where plains lie, and a
//! second low-frequency field carves valley floors along its zero crossings. Only integer hashing
//! and f32 arithmetic in a fixed order are used, so a seed gives bit-identical heights on every
//! machine.

use super::{Dem, DemError, LoadOptions, RawGrid, VoidMask, check_size};

/// Ground spacing of synthetic terrains, metres.
pub const SPACING_M: f64 = 10.0;
/// Largest size accepted.
pub const MAX_SIZE: u32 = 16385;
/// Wavelength of the largest mountain features, in samples.
const BASE_WAVELENGTH: f32 = 1024.0;

/// Parses `SIZE[:SEED]` and generates the terrain.
pub fn load(spec: &str, rest: &str, opts: &LoadOptions) -> Result<Dem, DemError> {
    let bad = |detail: String| DemError::BadSpec {
        spec: spec.into(),
        detail,
    };
    let mut parts = rest.split(':');
    let size: u32 = parts
        .next()
        .unwrap_or("")
        .parse()
        .map_err(|_| bad("SIZE must be a whole number, as in synthetic:1025".into()))?;
    let seed: u32 = match parts.next() {
        None => 1,
        Some(s) => s
            .parse()
            .map_err(|_| bad("SEED must be a whole number, as in synthetic:1025:7".into()))?,
    };
    if parts.next().is_some() {
        return Err(bad("expected synthetic:SIZE or synthetic:SIZE:SEED".into()));
    }
    if size > MAX_SIZE {
        return Err(bad(format!(
            "SIZE {size} is over the maximum of {MAX_SIZE}"
        )));
    }
    check_size(spec, size, size, opts)?;
    let heights = generate(size, seed, opts.progress);
    let raw = RawGrid {
        width: size,
        height: size,
        voids: VoidMask::new(heights.len()),
        heights,
        spacing: Some((SPACING_M, SPACING_M)),
        crs: None,
        nan_is_void: false,
    };
    super::finish(spec, raw, opts)
}

/// The heights of `synthetic:SIZE:SEED`, row-major, metres.
pub fn generate(size: u32, seed: u32, progress: bool) -> Vec<f32> {
    let n = size as usize;
    let mut out = vec![0.0f32; n * n];
    let bar = crate::bench::progress_bar(progress && n * n > 1 << 22, n as u64, "synthetic");
    for (r, row) in out.chunks_mut(n).enumerate() {
        for (c, h) in row.iter_mut().enumerate() {
            *h = height(c as f32, r as f32, seed);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    out
}

fn height(x: f32, y: f32, seed: u32) -> f32 {
    let u = x / BASE_WAVELENGTH;
    let v = y / BASE_WAVELENGTH;
    // Where mountains rise (1) and plains lie (0).
    let mask = smoothstep(0.38, 0.62, noise(u * 0.35, v * 0.35, seed ^ 0xA5A5));
    // Valley floors along the mid-level line of a slow field.
    let valley = ((noise(u * 0.7 + 3.1, v * 0.7 - 1.7, seed ^ 0x5151) - 0.5).abs() * 2.0).min(1.0);
    let carve = 0.35 + 0.65 * smoothstep(0.0, 0.22, valley);
    let hills = fbm(u * 2.0, v * 2.0, seed ^ 0x77, 5);
    let mountains = ridged(u, v, seed, 9);
    150.0
        + 220.0 * hills
        + mask * 2600.0 * mountains * mountains * carve
        + (1.0 - mask) * 25.0 * fbm(u * 16.0, v * 16.0, seed ^ 0x33, 3)
}

fn smoothstep(a: f32, b: f32, t: f32) -> f32 {
    let t = ((t - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn fbm(u: f32, v: f32, seed: u32, octaves: u32) -> f32 {
    let (mut sum, mut amp, mut norm, mut f) = (0.0, 1.0, 0.0, 1.0);
    for o in 0..octaves {
        sum += amp * noise(u * f, v * f, seed.wrapping_add(o * 7919));
        norm += amp;
        amp *= 0.5;
        f *= 2.0;
    }
    sum / norm
}

/// Ridged multifractal: sharp crests where the noise crosses its mid-level, finer octaves
/// weighted by the coarser ones so that detail gathers on the ridges.
fn ridged(u: f32, v: f32, seed: u32, octaves: u32) -> f32 {
    let (mut sum, mut amp, mut norm, mut f, mut weight) = (0.0, 1.0, 0.0, 1.0, 1.0f32);
    for o in 0..octaves {
        let n = 1.0 - (2.0 * noise(u * f, v * f, seed.wrapping_add(o * 104_729)) - 1.0).abs();
        let s = n * n * weight;
        weight = (s * 1.6).clamp(0.0, 1.0);
        sum += amp * s;
        norm += amp;
        amp *= 0.5;
        f *= 2.0;
    }
    sum / norm
}

/// Value noise in [0, 1): quintic interpolation of hashed lattice values.
fn noise(u: f32, v: f32, seed: u32) -> f32 {
    let (fx, fy) = (u.floor(), v.floor());
    let (ix, iy) = (fx as i32, fy as i32);
    let (tx, ty) = (fade(u - fx), fade(v - fy));
    let a = lattice(ix, iy, seed);
    let b = lattice(ix + 1, iy, seed);
    let c = lattice(ix, iy + 1, seed);
    let d = lattice(ix + 1, iy + 1, seed);
    let top = a + (b - a) * tx;
    let bottom = c + (d - c) * tx;
    top + (bottom - top) * ty
}

fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lattice(x: i32, y: i32, seed: u32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x27D4_EB2D)
        ^ (y as u32).wrapping_mul(0x1656_67B1)
        ^ seed.wrapping_mul(0x9E37_79B9);
    h ^= h >> 15;
    h = h.wrapping_mul(0x85EB_CA6B);
    h ^= h >> 13;
    h = h.wrapping_mul(0xC2B2_AE35);
    h ^= h >> 16;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

#[cfg(test)]
mod timing {
    #[test]
    #[ignore = "timing only"]
    fn speed_4097() {
        let t = std::time::Instant::now();
        let h = super::generate(4097, 1, false);
        let s = t.elapsed().as_secs_f64();
        let (lo, hi) = h
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        eprintln!(
            "synthetic:4097 {s:.2} s, {:.1} Msamples/s, {lo}..{hi}",
            4097.0 * 4097.0 / s / 1e6
        );
    }
}
