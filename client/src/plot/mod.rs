//! A small PNG line-chart renderer for the figures of `relief-client load --report DIR`:
//! bandwidth over time, the latency CDF, latency and server CPU against sessions.
//!
//! No plotting or font library: the canvas is an [`image::RgbImage`], lines are 2-px Bresenham
//! polylines and text is an embedded 5x7 bitmap font drawn at 2x. Axes get "nice" ticks (1-2-5
//! steps, or decades with [`Chart::log_x`]) with compact labels (1500 -> "1.5k"); a legend box
//! sits in the plot area's emptiest corner. Points that cannot be drawn are skipped: non-finite
//! ones, and with a log x axis those with x <= 0.

mod canvas;

use canvas::{BLACK, Canvas, GLYPH_H, GRID, WHITE, text_width, widest};
use image::{ImageFormat, Rgb, RgbImage};
use std::path::Path;

/// One line of a chart.
#[derive(Clone, Debug, Default)]
pub struct Series {
    /// The label in the legend.
    pub label: String,
    /// The points, (x, y), joined in this order.
    pub points: Vec<(f64, f64)>,
}

/// A line chart.
#[derive(Clone, Debug, Default)]
pub struct Chart {
    /// The title above the plot.
    pub title: String,
    /// The x axis's label, below it.
    pub x_label: String,
    /// The y axis's label, to its left, reading upwards.
    pub y_label: String,
    /// The lines, coloured in order from a fixed palette of six.
    pub series: Vec<Series>,
    /// Whether the x axis is logarithmic (decade ticks; points with x <= 0 are skipped).
    pub log_x: bool,
}

/// Why a chart could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Encoding or writing the PNG failed.
    #[error("cannot write the plot {path}: {source}")]
    Write {
        /// The file.
        path: String,
        /// What the encoder or the OS said.
        source: image::ImageError,
    },
    /// No series has a point that can be drawn.
    #[error("the chart has no finite points to draw")]
    NoData,
}

const PALETTE: [[u8; 3]; 6] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
];

/// Renders `chart` as a `width` x `height` RGB PNG at `path`.
///
/// 640 x 400 suits a report page. Fails with [`PlotError::NoData`] when no series has a
/// drawable point, and with [`PlotError::Write`] when the file cannot be written.
pub fn render_png(chart: &Chart, path: &Path, width: u32, height: u32) -> Result<(), PlotError> {
    let ok = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite() && (!chart.log_x || x > 0.0);
    let series = chart.series.iter();
    let series: Vec<Vec<_>> = series
        .map(|s| s.points.iter().copied().filter(ok).collect())
        .collect();
    if series.iter().all(Vec::is_empty) {
        return Err(PlotError::NoData);
    }
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in series.iter().flatten() {
        (x_lo, x_hi, y_lo, y_hi) = (x_lo.min(x), x_hi.max(x), y_lo.min(y), y_hi.max(y));
    }
    let xa = if chart.log_x {
        Axis::log(x_lo, x_hi)
    } else {
        Axis::linear(x_lo, x_hi)
    };
    let ya = Axis::linear(y_lo, y_hi);

    // The plot area, (x0, y0) to (x1, y1) in pixels: room on the left for the rotated y label
    // and the widest y tick label, below for the x tick labels and the x label, above for the
    // title, on the right for half the last x tick label.
    let last_x_w = widest(xa.ticks.last().map(|t| t.1.as_str()).into_iter());
    let x0 = 8 + GLYPH_H + 10 + widest(ya.ticks.iter().map(|t| t.1.as_str())) + 10;
    let x1 = (i64::from(width) - (last_x_w / 2 + 8).max(20)).max(x0 + 1);
    let y0 = 10 + GLYPH_H + 12;
    let y1 = (i64::from(height) - (8 + GLYPH_H + 10 + GLYPH_H + 8)).max(y0 + 1);
    let px = |x: f64| x0 as f64 + xa.frac(x) * (x1 - x0) as f64;
    let py = |y: f64| y1 as f64 - ya.frac(y) * (y1 - y0) as f64;

    let mut c = Canvas(RgbImage::from_pixel(width, height, WHITE));
    for (x, _) in &xa.ticks {
        c.fill(px(*x).round() as i64, y0, 1, y1 - y0, GRID);
    }
    for (y, _) in &ya.ticks {
        c.fill(x0, py(*y).round() as i64, x1 - x0, 1, GRID);
    }
    let lines: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| s.iter().map(|&(x, y)| (px(x), py(y))).collect())
        .collect();
    for (i, line) in lines.iter().enumerate() {
        let colour = Rgb(PALETTE[i % PALETTE.len()]);
        if let [(x, y)] = line.as_slice() {
            c.fill(*x as i64 - 2, *y as i64 - 2, 5, 5, colour);
        }
        for s in line.windows(2) {
            c.line(s[0], s[1], colour);
        }
    }

    c.frame(x0, y0, x1 - x0, y1 - y0);
    for (x, label) in &xa.ticks {
        let x = px(*x).round() as i64;
        c.fill(x, y1, 1, 5, BLACK);
        c.text(x - text_width(label) / 2, y1 + 8, label, false);
    }
    for (y, label) in &ya.ticks {
        let y = py(*y).round() as i64;
        c.fill(x0 - 5, y, 5, 1, BLACK);
        c.text(x0 - 8 - text_width(label), y - GLYPH_H / 2, label, false);
    }
    let centred = |s: &str| (x0 + x1 - text_width(s)) / 2;
    c.text(
        centred(&chart.x_label),
        y1 + 18 + GLYPH_H,
        &chart.x_label,
        false,
    );
    c.text(centred(&chart.title), 10, &chart.title, false);
    let yl = &chart.y_label;
    c.text(8, (y0 + y1 + text_width(yl)) / 2, yl, true);

    // The legend, in the corner of the plot area that the lines cross least.
    let lw = 8 + 20 + 6 + widest(chart.series.iter().map(|s| s.label.as_str())) + 8;
    let lh = 6 + 20 * chart.series.len() as i64;
    let (left, right, top, bottom) = (x0 + 8, x1 - 8 - lw, y0 + 8, y1 - 8 - lh);
    let crossings = |&(lx, ly): &(i64, i64)| {
        let inside = |(x, y): (f64, f64)| {
            (lx..=lx + lw).contains(&(x as i64)) && (ly..=ly + lh).contains(&(y as i64))
        };
        let segments = lines
            .iter()
            .flat_map(|l| l.windows(2).map(|s| (s[0], s[1])));
        let samples = segments.flat_map(|(a, b)| (0..=8).map(move |k| lerp(a, b, k)));
        samples.filter(|&p| inside(p)).count()
    };
    let corners = [(right, top), (left, top), (right, bottom), (left, bottom)];
    let (lx, ly) = corners
        .iter()
        .copied()
        .min_by_key(crossings)
        .unwrap_or(corners[0]);
    c.fill(lx, ly, lw, lh, WHITE);
    c.frame(lx, ly, lw, lh);
    for (i, s) in chart.series.iter().enumerate() {
        let row = ly + 6 + 20 * i as i64;
        c.fill(
            lx + 8,
            row + GLYPH_H / 2 - 2,
            20,
            4,
            Rgb(PALETTE[i % PALETTE.len()]),
        );
        c.text(lx + 34, row, &s.label, false);
    }

    let write = |source| PlotError::Write {
        path: path.display().to_string(),
        source,
    };
    c.0.save_with_format(path, ImageFormat::Png).map_err(write)
}

/// An axis: its range in transformed units (log10 for a log axis) and its labelled ticks as
/// (data value, label).
struct Axis {
    lo: f64,
    hi: f64,
    log: bool,
    ticks: Vec<(f64, String)>,
}

impl Axis {
    /// Ticks at 1-2-5 steps covering `lo..=hi`, the range padded when it is empty.
    fn linear(lo: f64, hi: f64) -> Axis {
        let pad = match (hi - lo <= 1e-9 * lo.abs().max(hi.abs()), lo == 0.0) {
            (false, _) => 0.0,
            (true, true) => 1.0,
            (true, false) => lo.abs() * 0.1,
        };
        let (lo, hi) = (lo - pad, hi + pad);
        let raw = (hi - lo) / 5.0;
        let mag = 10f64.powf(raw.log10().floor());
        let steps = [(1.5, 1.0), (3.5, 2.0), (7.5, 5.0)];
        let step = mag
            * steps
                .iter()
                .find(|(f, _)| raw / mag < *f)
                .map_or(10.0, |m| m.1);
        let (k0, k1) = ((lo / step).floor(), (hi / step).ceil());
        if !(step.is_finite() && step > 0.0 && k1 - k0 <= 100.0) {
            let ticks = [lo, hi].map(|v| (v, format_tick(v, hi - lo))).into();
            return Axis {
                lo,
                hi,
                log: false,
                ticks,
            };
        }
        let ticks = (k0 as i64..=k1 as i64).map(|k| k as f64 * step);
        let ticks = ticks.map(|v| (v, format_tick(v, step))).collect();
        Axis {
            lo: k0 * step,
            hi: k1 * step,
            log: false,
            ticks,
        }
    }

    /// Decade ticks covering `lo..=hi` (both > 0), about ten of them at most.
    fn log(lo: f64, hi: f64) -> Axis {
        let (e0, e1) = (lo.log10().floor(), hi.log10().ceil());
        let e1 = e1.max(e0 + 1.0);
        let stride = ((e1 - e0) / 10.0).ceil().max(1.0) as usize;
        let ticks = (e0 as i32..=e1 as i32)
            .step_by(stride)
            .map(|e| 10f64.powi(e));
        let ticks = ticks.map(|v| (v, format_tick(v, v))).collect();
        Axis {
            lo: e0,
            hi: e1,
            log: true,
            ticks,
        }
    }

    /// Where data value `v` falls, 0 at `lo` and 1 at `hi`.
    fn frac(&self, v: f64) -> f64 {
        let t = if self.log { v.log10() } else { v };
        (t - self.lo) / (self.hi - self.lo)
    }
}

/// A tick label, compact: 1500 -> "1.5k", 2000000 -> "2M", 0.25 -> "0.25", 0.00002 -> "2e-5",
/// with the decimals that `step` (the spacing of the ticks) needs.
fn format_tick(v: f64, step: f64) -> String {
    fn trim(s: &str) -> &str {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.')
        } else {
            s
        }
    }
    let a = v.abs();
    if a == 0.0 || a < step.abs() * 1e-9 {
        return "0".into();
    }
    if !(1e-3..1e15).contains(&a) {
        let s = format!("{v:.2e}");
        let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
        return format!("{}e{exp}", trim(mantissa));
    }
    let suffixes = [(1e12, "T"), (1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, "")];
    let (div, suffix) = suffixes
        .into_iter()
        .find(|(d, _)| a >= *d)
        .unwrap_or((1.0, ""));
    let decimals = (-(step.abs() / div).log10().floor()).clamp(0.0, 6.0) as usize;
    format!("{}{suffix}", trim(&format!("{:.*}", decimals, v / div)))
}

/// The point `k` eighths of the way from `a` to `b`.
fn lerp(a: (f64, f64), b: (f64, f64), k: u8) -> (f64, f64) {
    let t = f64::from(k) / 8.0;
    (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Renders `chart` at 640 x 400 into a temporary directory and reads it back.
    fn render(chart: &Chart) -> Result<RgbImage, PlotError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("chart.png");
        render_png(chart, &path, 640, 400)?;
        Ok(image::open(&path).unwrap().to_rgb8())
    }

    fn count(img: &RgbImage, colour: [u8; 3]) -> usize {
        img.pixels().filter(|p| p.0 == colour).count()
    }

    fn one(points: Vec<(f64, f64)>) -> Chart {
        let series = vec![Series {
            label: "p99 (ms)".into(),
            points,
        }];
        Chart {
            title: "Latency: 100% / 2".into(),
            series,
            ..Chart::default()
        }
    }

    #[test]
    fn two_series_draw_in_their_colours() {
        let series = |label: &str, f: fn(f64) -> f64| {
            let points = (0..200)
                .map(|i| f64::from(i) * 0.1)
                .map(|x| (x, f(x)))
                .collect();
            Series {
                label: label.into(),
                points,
            }
        };
        let series = vec![
            series("sin", |x| 1500.0 * x.sin()),
            series("linear", |x| 100.0 * x),
        ];
        let (title, x_label, y_label) = ("Bandwidth".into(), "time (s)".into(), "MB/s".into());
        let img = render(&Chart {
            title,
            x_label,
            y_label,
            series,
            log_x: false,
        })
        .unwrap();
        assert_eq!(img.dimensions(), (640, 400));
        assert!(img.pixels().any(|p| p.0 != [255, 255, 255]));
        assert!(count(&img, PALETTE[0]) > 300, "{}", count(&img, PALETTE[0]));
        assert!(count(&img, PALETTE[1]) > 300, "{}", count(&img, PALETTE[1]));
    }

    #[test]
    fn log_x_skips_undrawable_points() {
        let mut points: Vec<_> = (0..40)
            .map(|i| (10f64.powf(f64::from(i) / 10.0), 1.0))
            .collect();
        points.extend([
            (0.0, 1.0),
            (-5.0, 2.0),
            (f64::NAN, 1.0),
            (3.0, f64::INFINITY),
        ]);
        let img = render(&Chart {
            log_x: true,
            ..one(points)
        })
        .unwrap();
        assert_eq!(img.dimensions(), (640, 400));
        assert!(count(&img, PALETTE[0]) > 300, "{}", count(&img, PALETTE[0]));
        let ticks = Axis::log(1.0, 10f64.powf(3.9)).ticks;
        assert_eq!(
            ticks.iter().map(|t| t.1.as_str()).collect::<Vec<_>>(),
            ["1", "10", "100", "1k", "10k"]
        );
    }

    #[test]
    fn degenerate_ranges_render_and_no_data_is_an_error() {
        for points in [
            vec![(1.0, 2.0)],
            vec![(0.0, 0.0); 2],
            vec![(1.0, 5.0), (2.0, 5.0)],
        ] {
            render(&one(points)).unwrap();
        }
        let nan = one(vec![(f64::NAN, 1.0), (f64::INFINITY, 2.0)]);
        let log = Chart {
            log_x: true,
            ..one(vec![(0.0, 1.0), (-1.0, 2.0)])
        };
        for chart in [nan, log, Chart::default()] {
            assert!(matches!(render(&chart), Err(PlotError::NoData)));
        }
        let err = render_png(
            &one(vec![(1.0, 1.0)]),
            Path::new("/nonexistent/dir/x.png"),
            64,
            64,
        );
        assert!(matches!(err, Err(PlotError::Write { .. })));
    }

    #[test]
    fn ticks_are_nice_and_labels_compact() {
        let labels = |a: Axis| a.ticks.into_iter().map(|t| t.1).collect::<Vec<_>>();
        assert_eq!(
            labels(Axis::linear(0.0, 9.7)),
            ["0", "2", "4", "6", "8", "10"]
        );
        let want = ["0.1", "0.15", "0.2", "0.25", "0.3", "0.35"];
        assert_eq!(labels(Axis::linear(0.1, 0.33)), want);
        let want = ["0", "500", "1k", "1.5k", "2k", "2.5k", "3k"];
        assert_eq!(labels(Axis::linear(0.0, 2600.0)), want);
        assert_eq!(
            labels(Axis::linear(5.0, 5.0)),
            ["4.4", "4.6", "4.8", "5", "5.2", "5.4", "5.6"]
        );
        let cases = [
            (1500.0, 500.0, "1.5k"),
            (2e6, 1e6, "2M"),
            (0.25, 0.05, "0.25"),
            (-1500.0, 500.0, "-1.5k"),
        ];
        for (v, step, want) in cases {
            assert_eq!(format_tick(v, step), want);
        }
        for (v, step, want) in [(2e-5, 1e-5, "2e-5"), (3e9, 1e9, "3G"), (1e-17, 0.1, "0")] {
            assert_eq!(format_tick(v, step), want);
        }
    }
}
