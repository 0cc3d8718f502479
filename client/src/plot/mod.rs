//! PNG charts for the figures of `relief-client load --report DIR`: bandwidth over time, the
//! latency CDF, latency and server CPU against sessions.
//!
//! Drawn with [`plotters`] into an RGB buffer (its bitmap backend, no system fonts: the text face
//! is an ASCII subset of DejaVu Sans embedded from `client/fonts/`, with its licence beside it)
//! and saved with [`image`]. Either axis may be logarithmic; a series may carry point markers;
//! notes under the plot explain what a reader could trip over; the legend sits in the plot area's
//! emptiest corner. Points that cannot be drawn are skipped: non-finite ones, and on a log axis
//! those at or below 0.

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

/// One line of a chart.
#[derive(Clone, Debug, Default)]
pub struct Series {
    /// The label in the legend.
    pub label: String,
    /// The points, (x, y), joined in this order.
    pub points: Vec<(f64, f64)>,
    /// Whether each point also gets a marker (for sparse series, where the line alone hides
    /// where the measurements are).
    pub markers: bool,
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
    /// Whether the x axis is logarithmic (points with x <= 0 are skipped).
    pub log_x: bool,
    /// Whether the y axis is logarithmic (points with y <= 0 are skipped): for values that span
    /// decades, which a linear axis squashes onto its zero line. Data within one decade is drawn
    /// on a linear axis from 0 instead.
    pub log_y: bool,
    /// A fixed y range instead of the data's (e.g. 0..1 for a CDF).
    pub y_range: Option<(f64, f64)>,
    /// Lines of text under the plot: what the reader should know to read it.
    pub notes: Vec<String>,
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
    /// plotters failed to draw (a font or backend error).
    #[error("cannot draw the plot: {0}")]
    Draw(String),
}

/// Matplotlib's first six "tab10" colours.
const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// The text face: DejaVu Sans cut to ASCII and a few symbols (14 KB; see
/// `client/fonts/LICENSE.txt`).
const FONT: &[u8] = include_bytes!("../../fonts/ReliefPlotSans.ttf");

/// The family every text style names.
const FAMILY: &str = "sans-serif";

/// Registers [`FONT`] with plotters once per process.
fn font() -> Result<(), PlotError> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE
        .get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    ok.then_some(())
        .ok_or_else(|| PlotError::Draw("the embedded font does not load".into()))
}

/// Renders `chart` as a `width` x `height` RGB PNG at `path`.
///
/// 900 x 500 suits a report page. Fails with [`PlotError::NoData`] when no series has a
/// drawable point, and with [`PlotError::Write`] when the file cannot be written.
pub fn render_png(chart: &Chart, path: &Path, width: u32, height: u32) -> Result<(), PlotError> {
    let img = render(chart, width, height)?;
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|source| PlotError::Write {
            path: path.display().to_string(),
            source,
        })
}

/// Renders `chart` into an image.
pub fn render(chart: &Chart, width: u32, height: u32) -> Result<image::RgbImage, PlotError> {
    font()?;
    let ok = |&(x, y): &(f64, f64)| {
        x.is_finite() && y.is_finite() && (!chart.log_x || x > 0.0) && (!chart.log_y || y > 0.0)
    };
    let series: Vec<Vec<(f64, f64)>> = chart
        .series
        .iter()
        .map(|s| s.points.iter().copied().filter(ok).collect())
        .collect();
    if series.iter().all(Vec::is_empty) {
        return Err(PlotError::NoData);
    }
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in series.iter().flatten() {
        (x_lo, x_hi, y_lo, y_hi) = (x_lo.min(x), x_hi.max(x), y_lo.min(y), y_hi.max(y));
    }
    // Less than a decade reads better (and gets labelled ticks) on a linear axis.
    let log_y = chart.log_y && y_hi >= 10.0 * y_lo;
    if let Some((lo, hi)) = chart.y_range {
        (y_lo, y_hi) = (lo, hi);
    } else if !log_y {
        // Linear y axes start at 0 for positive data, so that bars of bandwidth or CPU read true.
        y_lo = y_lo.min(0.0);
        y_hi += (y_hi - y_lo) * 0.05;
    }
    let (mut x_lo, mut x_hi) = padded(x_lo, x_hi, chart.log_x);
    let (mut y_lo, mut y_hi) = padded(y_lo, y_hi, log_y);
    if chart.series.iter().any(|s| s.markers) {
        // Room for the markers at the ends (a fixed y range is kept).
        (x_lo, x_hi) = widened(x_lo, x_hi, chart.log_x);
        if chart.y_range.is_none() {
            (y_lo, y_hi) = widened(y_lo, y_hi, log_y);
        }
    }
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        let draw = |e: &dyn std::fmt::Display| PlotError::Draw(e.to_string());
        root.fill(&WHITE).map_err(|e| draw(&e))?;
        let note_h = if chart.notes.is_empty() {
            0
        } else {
            chart.notes.len() as u32 * 18 + 10
        };
        let (plot, notes) = root.split_vertically(height.saturating_sub(note_h));
        let corner = emptiest_corner(&series, (x_lo, x_hi, chart.log_x), (y_lo, y_hi, log_y));
        let xs = (x_lo, x_hi);
        let ys = (y_lo, y_hi);
        match (chart.log_x, log_y) {
            (false, false) => draw_on(&plot, chart, &series, xs.0..xs.1, ys.0..ys.1, corner),
            (true, false) => draw_on(
                &plot,
                chart,
                &series,
                (xs.0..xs.1).log_scale(),
                ys.0..ys.1,
                corner,
            ),
            (false, true) => draw_on(
                &plot,
                chart,
                &series,
                xs.0..xs.1,
                (ys.0..ys.1).log_scale(),
                corner,
            ),
            (true, true) => draw_on(
                &plot,
                chart,
                &series,
                (xs.0..xs.1).log_scale(),
                (ys.0..ys.1).log_scale(),
                corner,
            ),
        }
        .map_err(|e| PlotError::Draw(e.to_string()))?;
        for (i, line) in chart.notes.iter().enumerate() {
            notes
                .draw(&Text::new(
                    line.as_str(),
                    (14, 4 + i as i32 * 18),
                    (FAMILY, 14).into_font().color(&RGBColor(70, 70, 70)),
                ))
                .map_err(|e| draw(&e))?;
        }
        root.present().map_err(|e| draw(&e))?;
    }
    image::RgbImage::from_raw(width, height, buf)
        .ok_or_else(|| PlotError::Draw("the plot buffer has the wrong size".into()))
}

/// `lo..hi` widened when empty (by 10 %, or to 0..1 around 0; on a log axis by a factor of 2).
fn padded(lo: f64, hi: f64, log: bool) -> (f64, f64) {
    if hi - lo > 1e-9 * lo.abs().max(hi.abs()) {
        (lo, hi)
    } else if log {
        (lo / 2.0, hi * 2.0)
    } else if lo == 0.0 {
        (lo - 1.0, hi + 1.0)
    } else {
        (lo - lo.abs() * 0.1, hi + lo.abs() * 0.1)
    }
}

/// `lo..hi` widened by 4 % of its span at each end (of its log span on a log axis).
fn widened(lo: f64, hi: f64, log: bool) -> (f64, f64) {
    if log {
        let k = (hi / lo).powf(0.04);
        (lo / k, hi * k)
    } else {
        let d = (hi - lo) * 0.04;
        (if lo == 0.0 { lo } else { lo - d }, hi + d)
    }
}

/// The legend's corner: the quadrant of the plot area with the fewest points.
fn emptiest_corner(
    series: &[Vec<(f64, f64)>],
    (x_lo, x_hi, log_x): (f64, f64, bool),
    (y_lo, y_hi, log_y): (f64, f64, bool),
) -> SeriesLabelPosition {
    let frac = |v: f64, lo: f64, hi: f64, log: bool| {
        if log {
            (v.ln() - lo.ln()) / (hi.ln() - lo.ln())
        } else {
            (v - lo) / (hi - lo)
        }
    };
    let mut count = [0usize; 4]; // upper left, upper right, lower left, lower right
    for &(x, y) in series.iter().flatten() {
        let right = frac(x, x_lo, x_hi, log_x) > 0.5;
        let lower = frac(y, y_lo, y_hi, log_y) < 0.5;
        count[usize::from(lower) * 2 + usize::from(right)] += 1;
    }
    let order = [
        (1, SeriesLabelPosition::UpperRight),
        (0, SeriesLabelPosition::UpperLeft),
        (3, SeriesLabelPosition::LowerRight),
        (2, SeriesLabelPosition::LowerLeft),
    ];
    order
        .into_iter()
        .min_by_key(|(i, _)| count[*i])
        .map_or(SeriesLabelPosition::UpperRight, |(_, p)| p)
}

/// A tick label: compact (1500 -> 1.5k, 2000000 -> 2M), at most three significant digits.
pub fn compact(v: f64) -> String {
    let a = v.abs();
    let (scaled, suffix) = if a >= 1e9 {
        (v / 1e9, "G")
    } else if a >= 1e6 {
        (v / 1e6, "M")
    } else if a >= 1e3 {
        (v / 1e3, "k")
    } else {
        (v, "")
    };
    let s = if scaled == 0.0 {
        "0".to_string()
    } else {
        let digits = (2 - scaled.abs().log10().floor() as i32).clamp(0, 6) as usize;
        format!("{scaled:.digits$}")
    };
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    format!("{s}{suffix}")
}

/// Draws the axes, the series and the legend on `area` with the given axis ranges.
fn draw_on<X, Y>(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    chart: &Chart,
    series: &[Vec<(f64, f64)>],
    x: X,
    y: Y,
    corner: SeriesLabelPosition,
) -> Result<(), DrawingAreaErrorKind<<BitMapBackend<'static> as DrawingBackend>::ErrorType>>
where
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let mut c = ChartBuilder::on(area)
        .caption(&chart.title, (FAMILY, 22))
        .margin(14)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(x, y)?;
    c.configure_mesh()
        .x_desc(chart.x_label.as_str())
        .y_desc(chart.y_label.as_str())
        .x_label_formatter(&|v| compact(*v))
        .y_label_formatter(&|v| compact(*v))
        .label_style((FAMILY, 14))
        .axis_desc_style((FAMILY, 15))
        .light_line_style(RGBColor(238, 238, 238))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()?;
    for (k, (s, points)) in chart.series.iter().zip(series).enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        c.draw_series(LineSeries::new(
            points.iter().copied(),
            colour.stroke_width(2),
        ))?
        .label(s.label.as_str())
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], colour.stroke_width(2)));
        if s.markers {
            c.draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled())))?;
        }
    }
    c.configure_series_labels()
        .position(corner)
        .label_font((FAMILY, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(160, 160, 160))
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count(img: &image::RgbImage, c: RGBColor) -> usize {
        img.pixels().filter(|p| p.0 == [c.0, c.1, c.2]).count()
    }

    fn one(points: Vec<(f64, f64)>) -> Chart {
        Chart {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![Series {
                label: "a".into(),
                points,
                markers: false,
            }],
            ..Chart::default()
        }
    }

    #[test]
    fn two_series_draw_in_their_colours_with_text() {
        let mut c = one(vec![(0.0, 0.0), (10.0, 5.0)]);
        c.series.push(Series {
            label: "b".into(),
            points: vec![(0.0, 5.0), (10.0, 0.0)],
            markers: true,
        });
        c.notes = vec!["a note".into()];
        let img = render(&c, 400, 300).unwrap();
        assert!(count(&img, PALETTE[0]) > 100);
        assert!(count(&img, PALETTE[1]) > 100);
        // Text is drawn (anti-aliased dark pixels in the notes strip).
        let dark = (img.height() - 20..img.height())
            .flat_map(|y| (0..100).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0[0] < 150)
            .count();
        assert!(dark > 10, "{dark}");
    }

    #[test]
    fn log_axes_skip_undrawable_points() {
        let mut c = one(vec![
            (0.0, 1.0),
            (-1.0, 2.0),
            (1.0, 0.0),
            (10.0, 100.0),
            (100.0, 3.0),
        ]);
        c.log_x = true;
        c.log_y = true;
        assert!(render(&c, 400, 300).is_ok());
        let c = Chart {
            log_x: true,
            ..one(vec![(0.0, 1.0), (f64::NAN, 2.0)])
        };
        assert!(matches!(render(&c, 400, 300), Err(PlotError::NoData)));
    }

    #[test]
    fn degenerate_ranges_render() {
        assert!(render(&one(vec![(1.0, 1.0)]), 300, 200).is_ok());
        assert!(render(&one(vec![(0.0, 0.0), (0.0, 0.0)]), 300, 200).is_ok());
        let c = Chart {
            log_y: true,
            ..one(vec![(3.0, 2.5)])
        };
        assert!(render(&c, 300, 200).is_ok());
    }

    #[test]
    fn labels_are_compact() {
        assert_eq!(compact(1500.0), "1.5k");
        assert_eq!(compact(250.0), "250");
        assert_eq!(compact(15000.0), "15k");
        assert_eq!(compact(2_500_000.0), "2.5M");
        assert_eq!(compact(0.25), "0.25");
        assert_eq!(compact(0.0), "0");
        assert_eq!(compact(3.0e9), "3G");
    }
}
