//! `synthetic:SIZE[:SEED]`: a deterministic fractal terrain of SIZE x SIZE samples (2..=32768,
//! default seed 1), 10 m apart, with mountain ranges, valleys and plains, for tests and benchmarks
//! at any size.
//!
//! The terrain sums gradient-noise fields (`dem/noise.rs`):
//! - a slow **mask** decides where mountains rise (1) and where plains lie (0). Its threshold is
//!   the 40th percentile of the mask over the grid, so every grid, whatever its size and seed, is
//!   about 40% plains and 60% mountains;
//! - a **ridged** multifractal (Musgrave's: octaves of `1 - |noise|`, squared, each weighted by
//!   the one before so that detail gathers on the crests) shapes the mountains;
//! - a slow **valley** field carves valley floors along its zero lines through the mountains;
//! - gentle **hills** everywhere, and faint texture on the plains.
//!
//! Each octave has its own lattice offset, so that lattice lines of different octaves do not
//! coincide (aligned lattices show as a grid pattern).
//!
//! Features scale with the grid: the largest mountains are a quarter of the grid across (at least
//! 32 and at most 1024 samples, 10 km), and heights scale with them, so slopes look alike at every
//! size: from 4097 samples up, mountains rise about 2,000 m above plains at 150..400 m, and smaller
//! grids are the same kind of landscape in miniature. Octaves finer than 4 samples are dropped, as
//! they would only alias into spikes.
//!
//! Determinism and speed: see `dem/noise.rs`. The fields are combined in loops over a row, one
//! step of the formula at a time, which the compiler vectorises; every sample sees the same
//! operations in the same order, so a seed gives bit-identical heights on every machine.

use super::noise::{Field, RowSampler};
use super::{Dem, DemError, LoadOptions, RawGrid, VoidMask, check_size};
use std::ops::Range;

/// Ground spacing of synthetic terrains, metres.
pub const SPACING_M: f64 = 10.0;
/// Largest size accepted: the vertex tree's largest grid ([`relief_proto::tree::MAX_DEPTH`]).
pub const MAX_SIZE: u32 = 1 << relief_proto::tree::MAX_DEPTH;
/// Wavelength of the largest mountains on big grids, samples.
const MAX_WAVELENGTH: f32 = 1024.0;
/// Wavelength of the largest mountains on tiny grids, samples.
const MIN_WAVELENGTH: f32 = 32.0;
/// Finest wavelength an octave may have, samples.
const FINEST_WAVELENGTH: f32 = 4.0;
/// Share of the grid below the mountain mask's threshold.
const PLAINS_SHARE: f32 = 0.4;
/// Half-width of the mask's transition from plains to mountains, in noise units.
const MASK_RAMP: f32 = 0.08;

/// Parses `SIZE[:SEED]` (the part of `spec` after `synthetic:`) and generates the terrain.
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
        spacing: Ok((SPACING_M, SPACING_M)),
        crs: None,
        georef: None,
        nan_is_void: false,
        io: Default::default(),
    };
    super::finish(spec, raw, opts)
}

/// Everything that defines `synthetic:SIZE:SEED`.
struct Terrain {
    /// Height scale, 1 at [`MAX_WAVELENGTH`]: heights shrink with the features on small grids,
    /// so that slopes stay those of real terrain.
    relief: f32,
    /// The fields: the mask, the valley field, then the octaves of `hills`, `ridges`, `plains`.
    fields: Vec<Field>,
    /// Octaves of the hills, rising frequency.
    hills: Range<usize>,
    /// Octaves of the ridged mountains, rising frequency.
    ridges: Range<usize>,
    /// Octaves of the plains' texture, rising frequency.
    plains: Range<usize>,
    /// Mask value where plains turn to mountains: the grid's [`PLAINS_SHARE`] quantile.
    mask_level: f32,
}

/// Index of the mask and valley fields in [`Terrain::fields`].
const MASK: usize = 0;
const VALLEY: usize = 1;

impl Terrain {
    fn new(size: u32, seed: u32) -> Terrain {
        let wavelength = (size as f32 / 4.0).clamp(MIN_WAVELENGTH, MAX_WAVELENGTH);
        let mut fields = Vec::new();
        // Up to `max` octaves from `base` cycles per wavelength, none finer than
        // FINEST_WAVELENGTH, each on its own seed and lattice offset.
        let mut octaves = |base: f32, max: u32, seed: u32| {
            let start = fields.len();
            for o in 0..max {
                let cycles = base * (1u32 << o) as f32;
                if o > 0 && wavelength / cycles < FINEST_WAVELENGTH {
                    break;
                }
                let k = fields.len() as f32;
                fields.push(Field {
                    scale: cycles / wavelength,
                    off_x: 0.29 + 7.31 * k,
                    off_y: 0.671 + 3.17 * k,
                    seed: seed.wrapping_add(o * 104_729),
                });
            }
            start..fields.len()
        };
        octaves(0.35, 1, seed ^ 0xA5A5);
        octaves(0.7, 1, seed ^ 0x5151);
        let hills = octaves(2.0, 5, seed ^ 0x77);
        let ridges = octaves(1.0, 9, seed);
        let plains = octaves(16.0, 3, seed ^ 0x33);
        // The mask's quantile over a 65 x 65 lattice of the grid.
        let step = (size.max(1) - 1) as f32 / 64.0;
        let mut mask: Vec<f32> = (0..65 * 65)
            .map(|i| {
                fields[MASK].at(
                    ((i % 65) as f32 * step).floor(),
                    ((i / 65) as f32 * step).floor(),
                )
            })
            .collect();
        mask.sort_by(f32::total_cmp);
        Terrain {
            relief: wavelength / MAX_WAVELENGTH,
            mask_level: mask[(PLAINS_SHARE * (mask.len() - 1) as f32) as usize],
            fields,
            hills,
            ridges,
            plains,
        }
    }
}

/// Scratch rows of [`combine_rows`], one value per sample of the row.
#[derive(Default)]
struct Scratch {
    /// Where mountains rise (1) and plains lie (0).
    mask: Vec<f32>,
    /// Valley carving factor, 0.3 on valley floors to 1 away from them.
    carve: Vec<f32>,
    /// Hills fBm, about [-0.7, 0.7].
    hills: Vec<f32>,
    /// Plains texture fBm, about [-0.7, 0.7].
    plains: Vec<f32>,
    /// Ridged multifractal in [0, 1].
    mountains: Vec<f32>,
    /// The ridged sum's running weight (finer octaves count where coarser ones are high).
    weight: Vec<f32>,
}

/// Heights in metres of the `out.len()` samples of a row from the fields' values `n`
/// (field-major: field `k` is `n[k * len..(k + 1) * len]`).
fn combine_rows(t: &Terrain, n: &[f32], out: &mut [f32], s: &mut Scratch) {
    let len = out.len();
    let f = |k: usize| &n[k * len..(k + 1) * len];
    for v in [&mut s.mask, &mut s.carve, &mut s.mountains, &mut s.weight] {
        v.resize(len, 0.0);
    }
    let (lo, hi) = (t.mask_level - MASK_RAMP, t.mask_level + MASK_RAMP);
    for (m, &v) in s.mask.iter_mut().zip(f(MASK)) {
        *m = smoothstep(lo, hi, v);
    }
    for (c, &v) in s.carve.iter_mut().zip(f(VALLEY)) {
        *c = 0.3 + 0.7 * smoothstep(0.0, 0.12, v.abs());
    }
    fbm(t.hills.clone().map(f), &mut s.hills, len);
    fbm(t.plains.clone().map(f), &mut s.plains, len);
    s.mountains.fill(0.0);
    s.weight.fill(1.0);
    let (mut amp, mut norm) = (1.0f32, 0.0f32);
    for k in t.ridges.clone() {
        for ((sum, w), &v) in s.mountains.iter_mut().zip(&mut s.weight).zip(f(k)) {
            let r = (1.0 - 1.4 * v.abs()).max(0.0);
            let ridge = r * r * *w;
            *w = (ridge * 1.6).clamp(0.0, 1.0);
            *sum += amp * ridge;
        }
        norm += amp;
        amp *= 0.5;
    }
    for m in &mut s.mountains {
        *m /= norm;
    }
    let parts = s.mask.iter().zip(&s.carve).zip(&s.hills).zip(&s.plains);
    for ((h, &m), (((&mask, &carve), &hills), &plains)) in
        out.iter_mut().zip(&s.mountains).zip(parts)
    {
        *h = 150.0
            + t.relief
                * (120.0 * (hills + 0.7)
                    + mask * 2600.0 * m * m * carve
                    + (1.0 - mask) * 8.0 * plains);
    }
}

/// Octaves summed with halving amplitudes and normalised, into `dst` (`len` samples).
fn fbm<'a>(octaves: impl Iterator<Item = &'a [f32]>, dst: &mut Vec<f32>, len: usize) {
    dst.clear();
    dst.resize(len, 0.0);
    let (mut amp, mut norm) = (1.0f32, 0.0f32);
    for o in octaves {
        for (d, &v) in dst.iter_mut().zip(o) {
            *d += amp * v;
        }
        norm += amp;
        amp *= 0.5;
    }
    for d in dst.iter_mut() {
        *d /= norm;
    }
}

fn smoothstep(a: f32, b: f32, t: f32) -> f32 {
    let t = ((t - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The heights of `synthetic:SIZE:SEED`, row-major, metres.
pub fn generate(size: u32, seed: u32, progress: bool) -> Vec<f32> {
    let n = size as usize;
    let mut out = vec![0.0f32; n * n];
    if n == 0 {
        return out;
    }
    use rayon::prelude::*;
    let bar = crate::bench::progress_bar(progress && n * n > 1 << 22, n as u64, "synthetic");
    let t = Terrain::new(size, seed);
    // Bands of rows on every core: a row depends on its index alone (the samplers only keep
    // what the last row computed), so the heights are the same whatever the number of threads.
    const BAND: usize = 64;
    out.par_chunks_mut(n * BAND)
        .enumerate()
        .for_each(|(band, lines)| {
            let mut samplers: Vec<RowSampler> =
                t.fields.iter().map(|&f| RowSampler::new(f, n)).collect();
            let mut rows = vec![0.0f32; t.fields.len() * n];
            let mut scratch = Scratch::default();
            for (i, line) in lines.chunks_mut(n).enumerate() {
                for (s, row) in samplers.iter_mut().zip(rows.chunks_mut(n)) {
                    s.row(band * BAND + i, row);
                }
                combine_rows(&t, &rows, line, &mut scratch);
            }
            bar.inc((lines.len() / n) as u64);
        });
    bar.finish_and_clear();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The height at one sample, straight from the definition: the oracle of [`generate`].
    fn reference(t: &Terrain, x: u32, y: u32) -> f32 {
        let n: Vec<f32> = t.fields.iter().map(|f| f.at(x as f32, y as f32)).collect();
        let mut h = [0.0];
        combine_rows(t, &n, &mut h, &mut Scratch::default());
        h[0]
    }

    #[test]
    fn row_generation_matches_the_per_sample_definition_bit_for_bit() {
        for (size, seed) in [(300u32, 9u32), (37, 1), (4097, 2)] {
            let g = generate(size, seed, false);
            let t = Terrain::new(size, seed);
            for y in (0..size).step_by(size as usize / 13) {
                for x in (0..size).step_by(size as usize / 300 + 1) {
                    let (a, b) = (g[(y * size + x) as usize], reference(&t, x, y));
                    assert_eq!(a.to_bits(), b.to_bits(), "{size}: ({x}, {y}): {a} vs {b}");
                }
            }
        }
    }

    #[test]
    fn same_seed_same_terrain_other_seed_other_terrain() {
        let opts = LoadOptions::default();
        let a = crate::dem::load("synthetic:257:3", &opts).unwrap();
        let b = crate::dem::load("synthetic:257:3", &opts).unwrap();
        let c = crate::dem::load("synthetic:257:4", &opts).unwrap();
        assert_eq!(a.heights, b.heights);
        assert_ne!(a.heights, c.heights);
        let d = crate::dem::load("synthetic:257", &opts).unwrap();
        assert_eq!(d.heights, generate(257, 1, false), "default seed is 1");
        assert_eq!((d.spacing_x, d.spacing_y, d.voids.count()), (10.0, 10.0, 0));
    }

    /// Locks the terrain's exact bits: a change of formula, or a platform that computes
    /// differently, shows here. Update the constant only for an intended change of terrain.
    #[test]
    fn golden_checksum() {
        let h = generate(129, 1, false);
        let mut crc = crc32fast::Hasher::new();
        h.iter()
            .for_each(|v| crc.update(&v.to_bits().to_le_bytes()));
        assert_eq!(crc.finalize(), 3_489_088_650, "synthetic:129:1 changed");
    }

    #[test]
    fn size_two_works() {
        let d = crate::dem::load("synthetic:2", &LoadOptions::default()).unwrap();
        assert_eq!((d.width, d.height, d.heights.len()), (2, 2, 4));
        assert!(d.heights.iter().all(|h| h.is_finite()));
    }

    #[test]
    fn size_1000_looks_like_terrain() {
        let d = crate::dem::load("synthetic:1000", &LoadOptions::default()).unwrap();
        let (lo, hi) = d.valid_range();
        // 10 km of terrain: features 2.5 km across, about 600 m of relief.
        assert!(
            lo >= 100.0 && hi <= 3500.0 && hi - lo > 400.0,
            "heights {lo}..{hi}"
        );
        let n = d.heights.len() as f64;
        let mean = d.heights.iter().map(|&h| h as f64).sum::<f64>() / n;
        let sd = (d
            .heights
            .iter()
            .map(|&h| (h as f64 - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        assert!(sd > 50.0, "standard deviation {sd} m");
        let (flat, steep) = slope_shares(&d);
        assert!(
            flat > 0.15 && steep > 0.03,
            "flat {flat:.3}, steep {steep:.3}"
        );
    }

    /// Shares of samples (on a 3-sample lattice) with slopes under 3% and over 50%.
    fn slope_shares(d: &Dem) -> (f64, f64) {
        let (mut flat, mut steep, mut total) = (0usize, 0usize, 0usize);
        for y in (1..d.height - 1).step_by(3) {
            for x in (1..d.width - 1).step_by(3) {
                let gx = (d.at(x + 1, y) - d.at(x - 1, y)) / 20.0;
                let gy = (d.at(x, y + 1) - d.at(x, y - 1)) / 20.0;
                let slope = gx.hypot(gy);
                flat += (slope < 0.03) as usize;
                steep += (slope > 0.5) as usize;
                total += 1;
            }
        }
        (flat as f64 / total as f64, steep as f64 / total as f64)
    }

    #[test]
    fn every_seed_and_size_mixes_plains_and_mountains() {
        for size in [257, 600] {
            for seed in 1..=5 {
                let d =
                    crate::dem::load(&format!("synthetic:{size}:{seed}"), &LoadOptions::default())
                        .unwrap();
                let (flat, steep) = slope_shares(&d);
                assert!(
                    flat > 0.1 && steep > 0.01,
                    "{size}:{seed}: flat {flat:.3}, steep {steep:.3}"
                );
            }
        }
    }

    #[test]
    fn bad_specs_are_refused() {
        let opts = LoadOptions::default();
        for spec in [
            "synthetic:",
            "synthetic:x",
            "synthetic:5:y",
            "synthetic:5:1:2",
            "synthetic:32769",
        ] {
            let e = crate::dem::load(spec, &opts).unwrap_err();
            assert!(matches!(e, DemError::BadSpec { .. }), "{spec}: {e}");
        }
        for spec in ["synthetic:0", "synthetic:1"] {
            let e = crate::dem::load(spec, &opts).unwrap_err();
            assert!(matches!(e, DemError::TooSmall { .. }), "{spec}: {e}");
        }
        let small = LoadOptions {
            max_samples: 1000,
            ..LoadOptions::default()
        };
        let e = crate::dem::load("synthetic:40", &small).unwrap_err();
        assert!(e.to_string().contains("--max-samples"), "{e}");
    }

    /// `cargo test --release -p relief-server --lib synthetic_speed -- --ignored --nocapture`
    #[test]
    #[ignore = "timing only"]
    fn synthetic_speed() {
        for size in [4097u32, 16385] {
            let t = std::time::Instant::now();
            let h = generate(size, 1, false);
            let s = t.elapsed().as_secs_f64();
            let (lo, hi) = h
                .iter()
                .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            let m = size as f64 * size as f64 / 1e6;
            eprintln!(
                "synthetic:{size}: {s:.2} s, {:.1} M samples/s, {lo}..{hi} m",
                m / s
            );
        }
    }
}
