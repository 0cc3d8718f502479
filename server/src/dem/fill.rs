//! Void filling by pull-push interpolation over a pyramid, then harmonic smoothing.
//!
//! Each coarser level averages the valid samples under it (voids weigh nothing). Going back down,
//! a void takes the bilinear interpolation of the level above, which is defined everywhere once
//! any sample is valid. A few Jacobi sweeps of the Laplace equation over the voids alone then
//! smooth the fill so that it meets the surrounding surface without a step: no walls, no spikes,
//! and every filled value lies within the range of the valid samples around it.

use super::VoidMask;

/// Jacobi sweeps over the voids after the pyramid fill.
const SMOOTHING_SWEEPS: usize = 24;

/// Fills the voids of a `w` x `h` grid in place.
pub fn fill_voids(w: u32, h: u32, heights: &mut [f32], voids: &VoidMask, progress: bool) {
    if voids.count() == 0 {
        return;
    }
    let bar = crate::bench::progress_bar(progress && heights.len() > 1 << 22, 2, "voids");
    let (w, h) = (w as usize, h as usize);
    // Level 0 estimate: valid samples with weight 1.
    let mut levels: Vec<(usize, usize, Vec<f32>, Vec<f32>)> = Vec::new();
    let (sum, weight): (Vec<f32>, Vec<f32>) = heights
        .iter()
        .enumerate()
        .map(|(i, &v)| if voids.get(i) { (0.0, 0.0) } else { (v, 1.0) })
        .unzip();
    levels.push((w, h, sum, weight));
    while {
        let (lw, lh, _, _) = levels[levels.len() - 1];
        lw > 1 || lh > 1
    } {
        let (lw, lh, s, wt) = &levels[levels.len() - 1];
        let (cw, ch) = (lw.div_ceil(2), lh.div_ceil(2));
        let mut cs = vec![0.0f32; cw * ch];
        let mut cwt = vec![0.0f32; cw * ch];
        for y in 0..*lh {
            for x in 0..*lw {
                let (i, c) = (y * lw + x, (y / 2) * cw + x / 2);
                cs[c] += s[i];
                cwt[c] += wt[i];
            }
        }
        levels.push((cw, ch, cs, cwt));
    }
    bar.inc(1);
    // Pull down: each level's estimate is its own average where it has data, else the bilinear
    // interpolation of the coarser estimate.
    let top = levels.len() - 1;
    let (_, _, ts, tw) = &levels[top];
    let mut est = vec![ts[0] / tw[0].max(f32::MIN_POSITIVE)];
    let (mut ew, mut eh) = (1usize, 1usize);
    for k in (0..top).rev() {
        let (lw, lh, s, wt) = &levels[k];
        let mut next = vec![0.0f32; lw * lh];
        for y in 0..*lh {
            for x in 0..*lw {
                let i = y * lw + x;
                next[i] = if wt[i] > 0.0 {
                    s[i] / wt[i]
                } else {
                    bilinear(
                        &est,
                        ew,
                        eh,
                        (x as f32 + 0.5) / 2.0 - 0.5,
                        (y as f32 + 0.5) / 2.0 - 0.5,
                    )
                };
            }
        }
        est = next;
        (ew, eh) = (*lw, *lh);
    }
    for (i, v) in heights.iter_mut().enumerate() {
        if voids.get(i) {
            *v = est[i];
        }
    }
    smooth(w, h, heights, voids);
    bar.finish_and_clear();
}

fn bilinear(g: &[f32], w: usize, h: usize, x: f32, y: f32) -> f32 {
    let x = x.clamp(0.0, (w - 1) as f32);
    let y = y.clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let top = g[y0 * w + x0] * (1.0 - fx) + g[y0 * w + x1] * fx;
    let bottom = g[y1 * w + x0] * (1.0 - fx) + g[y1 * w + x1] * fx;
    top * (1.0 - fy) + bottom * fy
}

/// Jacobi sweeps of the Laplace equation over the void samples, valid samples held fixed.
fn smooth(w: usize, h: usize, heights: &mut [f32], voids: &VoidMask) {
    let holes: Vec<usize> = (0..heights.len()).filter(|&i| voids.get(i)).collect();
    let mut next = vec![0.0f32; holes.len()];
    for _ in 0..SMOOTHING_SWEEPS {
        for (k, &i) in holes.iter().enumerate() {
            let (x, y) = (i % w, i / w);
            let mut sum = 0.0;
            let mut n = 0.0;
            for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                    sum += heights[ny as usize * w + nx as usize];
                    n += 1.0;
                }
            }
            next[k] = sum / n;
        }
        for (k, &i) in holes.iter().enumerate() {
            heights[i] = next[k];
        }
    }
}
