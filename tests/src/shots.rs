//! Screenshots in the browser tests: not blank, and against a committed golden image.
//!
//! `RELIEF_BLESS=1` rewrites the golden images from this run's screenshots.

use std::collections::HashMap;
use std::path::Path;

/// A channel difference that counts a pixel as different.
pub const FAR: u32 = 32;

/// How far apart two images are: the mean absolute difference over all RGB channels (0-255),
/// and the fraction of pixels with some channel off by more than [`FAR`].
pub fn difference(a: &image::RgbaImage, b: &image::RgbaImage) -> (f64, f64) {
    let (mean, far, _) = difference3(a, b);
    (mean, far)
}

/// [`difference`], and the fraction of pixels that differ at all.
pub fn difference3(a: &image::RgbaImage, b: &image::RgbaImage) -> (f64, f64, f64) {
    assert_eq!(a.dimensions(), b.dimensions(), "image sizes differ");
    let (mut sum, mut far, mut any) = (0u64, 0u64, 0u64);
    for (p, q) in a.pixels().zip(b.pixels()) {
        let mut worst = 0;
        for c in 0..3 {
            let d = (i32::from(p[c]) - i32::from(q[c])).unsigned_abs();
            sum += u64::from(d);
            worst = worst.max(d);
        }
        if worst > FAR {
            far += 1;
        }
        if worst > 0 {
            any += 1;
        }
    }
    let n = u64::from(a.width()) * u64::from(a.height());
    (
        sum as f64 / (3 * n) as f64,
        far as f64 / n as f64,
        any as f64 / n as f64,
    )
}

/// Asserts that an image is not blank: a fifth of it or more differs from its commonest colour
/// (the background), the brightness varies and it has hundreds of colours (a page that drew
/// nothing, or only its background or an error message, has a handful). Returns the fraction
/// unlike the commonest colour and the brightness's standard deviation.
pub fn not_blank(img: &image::RgbaImage, what: &str) -> (f64, f64) {
    let mut counts: HashMap<[u8; 3], u32> = HashMap::new();
    let mut lum = Vec::with_capacity(img.pixels().len());
    for p in img.pixels() {
        *counts.entry([p[0], p[1], p[2]]).or_default() += 1;
        lum.push(0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]));
    }
    let n = lum.len() as f64;
    let commonest = counts.values().max().copied().unwrap_or(0);
    let unlike = 1.0 - f64::from(commonest) / n;
    let mean = lum.iter().sum::<f64>() / n;
    let sd = (lum.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / n).sqrt();
    assert!(
        unlike > 0.2 && sd > 8.0 && counts.len() > 500,
        "{what} looks blank: {:.0} % of it unlike its commonest colour, brightness sd {sd:.1}, \
         {} colours",
        unlike * 100.0,
        counts.len()
    );
    (unlike, sd)
}

/// Whether this run rewrites the golden images (`RELIEF_BLESS=1`).
pub fn bless() -> bool {
    std::env::var_os("RELIEF_BLESS").is_some()
}

/// Largest mean absolute channel difference from a golden image, levels of 255.
pub const GOLDEN_MEAN: f64 = 0.5;
/// Largest fraction of pixels off by more than [`FAR`] from a golden image.
pub const GOLDEN_FAR: f64 = 0.001;

/// Asserts that `img` (the screenshot at `actual`) is the golden image at `golden` within
/// [`GOLDEN_MEAN`] and [`GOLDEN_FAR`] (written there first when blessing), and that this
/// tolerance can tell the golden image from its mirror image. SwiftShader renders the same
/// frame to the bit from run to run here, so the tolerance only leaves room for rounding that
/// differs on other CPUs or Chromium builds (a level or two on some channels). Returns the
/// mean difference, the fraction of pixels off by more than [`FAR`] and of those that differ
/// at all.
pub fn assert_golden(
    img: &image::RgbaImage,
    actual: &Path,
    golden: &Path,
    what: &str,
) -> (f64, f64, f64) {
    if bless() {
        std::fs::create_dir_all(golden.parent().expect("a folder")).expect("golden folder");
        img.save(golden).expect("the golden image");
    }
    let want = image::open(golden)
        .unwrap_or_else(|e| panic!("{}: {e} (RELIEF_BLESS=1 writes it)", golden.display()))
        .to_rgba8();
    let (mean, far, any) = difference3(img, &want);
    println!(
        "{what}: vs golden {}: mean |difference| {mean:.4} levels (at most {GOLDEN_MEAN}), \
         {:.4} % of pixels off by more than {FAR} (at most {:.1} %), {:.4} % of pixels differ \
         at all",
        golden.display(),
        far * 100.0,
        GOLDEN_FAR * 100.0,
        any * 100.0
    );
    assert!(
        mean <= GOLDEN_MEAN && far <= GOLDEN_FAR,
        "{what} is not the golden view: mean difference {mean:.3} (at most {GOLDEN_MEAN}), \
         {:.3} % pixels off (at most {:.1} %); this render is at {}",
        far * 100.0,
        GOLDEN_FAR * 100.0,
        actual.display()
    );
    let mirrored = image::imageops::flip_horizontal(&want);
    let (m_mean, m_far) = difference(&mirrored, &want);
    assert!(
        m_mean > GOLDEN_MEAN && m_far > GOLDEN_FAR,
        "the tolerance cannot tell {what} from its mirror image ({m_mean:.2}, {m_far:.3})"
    );
    (mean, far, any)
}
