#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Generic SVG plots for calibration reports, built on `plotters` with the SVG backend only (no
//! system fonts: text is written as SVG `<text>` elements and rendered by the viewer).
//!
//! | function | what it draws | typical use |
//! |---|---|---|
//! | [`histogram_svg`] | histogram of one or more value series on shared bins | position errors before/after calibration (the paper's Fig. 8) |
//! | [`line_plot_svg`] | one or more series against a common x variable | error along a printing path, convergence history |
//! | [`scatter_svg`] | points of one or more series against an x variable | residual vs a joint angle, a torque, time |
//!
//! Every function returns the SVG document as a `String`; [`save_svg`] writes it to a file.
//! [`html::HtmlReport`] assembles text, tables and these SVGs into one self-contained HTML file.
//! Inputs are checked: empty or non-finite data is an error ([`PlotError`]), never a panic.
//! Units belong in the labels (e.g. `"position error [mm]"`).

use std::path::{Path, PathBuf};

pub mod html;

use plotters::coord::Shift;
use plotters::prelude::*;

/// Errors of the plotting layer.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// No series, or a series without values.
    #[error("nothing to plot: {0}")]
    Empty(String),
    /// A value is NaN or infinite.
    #[error("series `{series}`: value {index} is not finite ({value})")]
    NonFinite {
        /// label of the series
        series: String,
        /// 0-based index of the value
        index: usize,
        /// the offending value
        value: f64,
    },
    /// The x values and a series have different lengths.
    #[error("series `{series}` has {got} values but there are {expected} x values")]
    Length {
        /// label of the series
        series: String,
        /// number of x values
        expected: usize,
        /// number of series values
        got: usize,
    },
    /// Invalid plot options (size, bin count).
    #[error("invalid plot option: {0}")]
    Option(String),
    /// plotters reported a drawing failure.
    #[error("drawing failed: {0}")]
    Draw(String),
    /// The SVG file could not be written.
    #[error("{path}: {source}")]
    File {
        /// file
        path: PathBuf,
        /// cause
        source: std::io::Error,
    },
}

/// One named series of values.
#[derive(Debug, Clone, Copy)]
pub struct Series<'a> {
    /// legend label
    pub label: &'a str,
    /// the values
    pub values: &'a [f64],
}

impl<'a> Series<'a> {
    /// A labelled series.
    pub fn new(label: &'a str, values: &'a [f64]) -> Self {
        Self { label, values }
    }
}

/// Title, axis labels and size of a plot.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotSpec {
    /// caption above the chart
    pub title: String,
    /// x-axis label, with its unit
    pub x_label: String,
    /// y-axis label, with its unit
    pub y_label: String,
    /// width in pixels
    pub width: u32,
    /// height in pixels
    pub height: u32,
}

impl PlotSpec {
    /// A 900 × 520 px plot.
    pub fn new(title: impl Into<String>, x_label: impl Into<String>, y_label: impl Into<String>) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            width: 900,
            height: 520,
        }
    }

    fn check(&self) -> Result<(), PlotError> {
        if !(200..=10_000).contains(&self.width) || !(150..=10_000).contains(&self.height) {
            return Err(PlotError::Option(format!(
                "plot size {}x{} px must be within 200..=10000 x 150..=10000",
                self.width, self.height
            )));
        }
        Ok(())
    }
}

/// What the bar height of a histogram means.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HistogramScale {
    /// number of values in the bin
    Count,
    /// percentage of the series' values in the bin (series of different sizes stay comparable)
    #[default]
    Percent,
}

/// How several histogram series are arranged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HistogramLayout {
    /// one panel per series, each with its own bins, stacked vertically
    #[default]
    Panels,
    /// all series in one chart on shared bins, semi-transparent bars
    Overlay,
}

/// Options of [`histogram_svg`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HistogramOptions {
    /// number of bins (shared by all series), ≥ 1
    pub bins: usize,
    /// bar height: count or percentage
    pub scale: HistogramScale,
    /// start the bins at 0 when every value is ≥ 0 (natural for error magnitudes)
    pub from_zero: bool,
    /// panels or overlay
    pub layout: HistogramLayout,
}

impl Default for HistogramOptions {
    fn default() -> Self {
        Self { bins: 40, scale: HistogramScale::Percent, from_zero: true, layout: HistogramLayout::Panels }
    }
}

/// Colour of series `k` (a fixed, distinguishable cycle: blue, red, green, orange, purple, ...).
pub fn series_color(k: usize) -> RGBColor {
    const COLORS: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];
    COLORS[k % COLORS.len()]
}

fn check_series(series: &[Series<'_>]) -> Result<(), PlotError> {
    if series.is_empty() {
        return Err(PlotError::Empty("no series given".into()));
    }
    for s in series {
        if s.values.is_empty() {
            return Err(PlotError::Empty(format!("series `{}` has no values", s.label)));
        }
        check_finite(s.label, s.values)?;
    }
    Ok(())
}

fn check_finite(label: &str, values: &[f64]) -> Result<(), PlotError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(PlotError::NonFinite { series: label.to_string(), index, value: values[index] }),
        None => Ok(()),
    }
}

fn check_xy(x: &[f64], series: &[Series<'_>]) -> Result<(), PlotError> {
    check_series(series)?;
    if x.is_empty() {
        return Err(PlotError::Empty("no x values".into()));
    }
    check_finite("x", x)?;
    for s in series {
        if s.values.len() != x.len() {
            return Err(PlotError::Length {
                series: s.label.to_string(),
                expected: x.len(),
                got: s.values.len(),
            });
        }
    }
    Ok(())
}

fn draw_err<E: std::fmt::Debug>(e: E) -> PlotError {
    PlotError::Draw(format!("{e:?}"))
}

/// `(lo, hi)` of all values, widened so that the range is never empty, plus a margin fraction.
fn padded_range(values: impl Iterator<Item = f64>, margin: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() || !hi.is_finite() {
        return (0.0, 1.0);
    }
    let span = hi - lo;
    let pad = if span > 0.0 { span * margin } else { lo.abs().max(1.0) * 0.05 };
    (lo - pad, hi + pad)
}

/// Bin counts of `values` over `bins` equal bins spanning `[lo, hi]` (the last bin is closed).
pub fn bin_counts(values: &[f64], lo: f64, hi: f64, bins: usize) -> Vec<usize> {
    let mut counts = vec![0usize; bins];
    if bins == 0 || hi <= lo {
        if let Some(c) = counts.first_mut() {
            *c = values.len();
        }
        return counts;
    }
    let width = (hi - lo) / bins as f64;
    for v in values {
        let k = ((v - lo) / width).floor();
        let k = if k < 0.0 { 0 } else { (k as usize).min(bins - 1) };
        counts[k] += 1;
    }
    counts
}

fn render(
    spec: &PlotSpec,
    draw: impl FnOnce(&DrawingArea<SVGBackend<'_>, Shift>) -> Result<(), PlotError>,
) -> Result<String, PlotError> {
    spec.check()?;
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (spec.width, spec.height)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        draw(&root)?;
        root.present().map_err(draw_err)?;
    }
    Ok(buf)
}

/// Histogram of one or more series (e.g. "nominal" and "calibrated" position errors, like the
/// paper's Fig. 8). Returns the SVG document.
///
/// With [`HistogramLayout::Overlay`] all series share one set of bins, bars drawn
/// semi-transparent on top of each other. With [`HistogramLayout::Panels`] (the default) each
/// series gets its own panel and bins, stacked vertically — readable even when the errors
/// differ by orders of magnitude, as before and after a calibration do. The bins span the range
/// of the data (from 0 if `options.from_zero` and no value is negative).
///
/// # Examples
/// ```
/// use vatcal_report::{HistogramOptions, PlotError, PlotSpec, Series, histogram_svg};
///
/// let nominal = [0.8, 1.1, 0.9, 1.3, 1.0];
/// let calibrated = [0.012, 0.018, 0.015, 0.011, 0.020];
/// let spec = PlotSpec::new("Position error", "error [mm]", "share of poses [%]");
/// let series = [Series::new("nominal", &nominal), Series::new("calibrated", &calibrated)];
/// let svg = histogram_svg(&spec, &series, &HistogramOptions::default())?;
/// assert!(svg.contains("<svg") && svg.contains("calibrated"));
/// // a NaN is refused, naming the series and the value's index
/// let bad = [0.1, f64::NAN];
/// let e = histogram_svg(&spec, &[Series::new("tracker", &bad)], &HistogramOptions::default());
/// assert!(matches!(e, Err(PlotError::NonFinite { index: 1, .. })));
/// # Ok::<(), PlotError>(())
/// ```
///
/// # Errors
/// Empty or non-finite data, `bins == 0`, an unusable plot size, or a drawing failure.
pub fn histogram_svg(
    spec: &PlotSpec,
    series: &[Series<'_>],
    options: &HistogramOptions,
) -> Result<String, PlotError> {
    check_series(series)?;
    if options.bins == 0 || options.bins > 10_000 {
        return Err(PlotError::Option(format!("bins must be 1..=10000, got {}", options.bins)));
    }
    render(spec, |root| match options.layout {
        HistogramLayout::Overlay => draw_histogram(root, &spec.title, spec, series, 0, options),
        HistogramLayout::Panels => {
            let panels = root.split_evenly((series.len(), 1));
            for (k, (area, s)) in panels.iter().zip(series).enumerate() {
                let caption = if series.len() == 1 {
                    spec.title.clone()
                } else {
                    format!("{}: {}", spec.title, s.label)
                };
                draw_histogram(area, &caption, spec, std::slice::from_ref(s), k, options)?;
            }
            Ok(())
        }
    })
}

/// One histogram chart of `series` on shared bins; colours start at `first_color`.
fn draw_histogram(
    area: &DrawingArea<SVGBackend<'_>, Shift>,
    caption: &str,
    spec: &PlotSpec,
    series: &[Series<'_>],
    first_color: usize,
    options: &HistogramOptions,
) -> Result<(), PlotError> {
    let all = || series.iter().flat_map(|s| s.values.iter().copied());
    let (mut lo, mut hi) = padded_range(all(), 0.0);
    if options.from_zero && lo >= 0.0 {
        lo = 0.0;
    }
    if hi <= lo {
        hi = lo + 1.0;
    }
    let width = (hi - lo) / options.bins as f64;
    let heights: Vec<Vec<f64>> = series
        .iter()
        .map(|s| {
            let n = s.values.len() as f64;
            bin_counts(s.values, lo, hi, options.bins)
                .into_iter()
                .map(|c| match options.scale {
                    HistogramScale::Count => c as f64,
                    HistogramScale::Percent => 100.0 * c as f64 / n,
                })
                .collect()
        })
        .collect();
    let top = heights.iter().flatten().copied().fold(0.0, f64::max).max(1e-12) * 1.08;
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(lo..hi, 0.0..top)
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc(spec.x_label.as_str())
        .y_desc(spec.y_label.as_str())
        .draw()
        .map_err(draw_err)?;
    for (k, (s, h)) in series.iter().zip(&heights).enumerate() {
        let color = series_color(first_color + k);
        let bars = h.iter().enumerate().filter(|(_, v)| **v > 0.0).map(move |(b, v)| {
            let x0 = lo + b as f64 * width;
            Rectangle::new([(x0, 0.0), (x0 + width, *v)], color.mix(0.45).filled())
        });
        chart
            .draw_series(bars)
            .map_err(draw_err)?
            .label(legend_label(s))
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 16, y + 5)], color.mix(0.45).filled()));
    }
    draw_legend(&mut chart)
}

fn legend_label(s: &Series<'_>) -> String {
    format!("{} (n = {})", s.label, s.values.len())
}

fn draw_legend<'a, 'b: 'a>(chart: &mut XyChart<'a, 'b>) -> Result<(), PlotError> {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(draw_err)
}

/// Line plot of one or more series against a common x variable (e.g. position error along a
/// printing path, with one series per model). Returns the SVG document.
///
/// # Examples
/// ```
/// use vatcal_report::{PlotSpec, Series, line_plot_svg};
///
/// let slice = [0.0, 1.0, 2.0, 3.0];
/// let error_mm = [0.020, 0.015, 0.017, 0.012];
/// let svg = line_plot_svg(&PlotSpec::new("Error along the path", "slice", "error [mm]"), &slice, &[
///     Series::new("calibrated", &error_mm),
/// ])?;
/// assert!(svg.contains("Error along the path"));
/// // every series needs one value per x value
/// assert!(line_plot_svg(&PlotSpec::new("t", "x", "y"), &slice, &[Series::new("short", &error_mm[..2])]).is_err());
/// # Ok::<(), vatcal_report::PlotError>(())
/// ```
///
/// # Errors
/// Empty or non-finite data, series whose length differs from `x`, an unusable plot size.
pub fn line_plot_svg(spec: &PlotSpec, x: &[f64], series: &[Series<'_>]) -> Result<String, PlotError> {
    check_xy(x, series)?;
    xy_chart(spec, x, series, |chart, k, s| {
        let color = series_color(k);
        let pts: Vec<(f64, f64)> = x.iter().copied().zip(s.values.iter().copied()).collect();
        chart
            .draw_series(LineSeries::new(pts, color.stroke_width(2)))
            .map_err(draw_err)?
            .label(s.label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
        Ok(())
    })
}

/// Scatter plot of one or more series against a driving variable (e.g. a residual coordinate
/// against a joint angle or a gravity torque). Returns the SVG document.
///
/// # Errors
/// Empty or non-finite data, series whose length differs from `x`, an unusable plot size.
pub fn scatter_svg(spec: &PlotSpec, x: &[f64], series: &[Series<'_>]) -> Result<String, PlotError> {
    check_xy(x, series)?;
    xy_chart(spec, x, series, |chart, k, s| {
        let color = series_color(k);
        let pts = x.iter().copied().zip(s.values.iter().copied());
        chart
            .draw_series(pts.map(move |p| Circle::new(p, 3, color.mix(0.8).filled())))
            .map_err(draw_err)?
            .label(s.label)
            .legend(move |(x, y)| Circle::new((x + 8, y), 4, color.filled()));
        Ok(())
    })
}

type XyChart<'a, 'b> = ChartContext<
    'a,
    SVGBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

fn xy_chart(
    spec: &PlotSpec,
    x: &[f64],
    series: &[Series<'_>],
    mut draw_one: impl for<'a, 'b> FnMut(&mut XyChart<'a, 'b>, usize, &Series<'_>) -> Result<(), PlotError>,
) -> Result<String, PlotError> {
    let (x0, x1) = padded_range(x.iter().copied(), 0.02);
    let (y0, y1) = padded_range(series.iter().flat_map(|s| s.values.iter().copied()), 0.08);
    render(spec, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(&spec.title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc(spec.x_label.as_str())
            .y_desc(spec.y_label.as_str())
            .draw()
            .map_err(draw_err)?;
        for (k, s) in series.iter().enumerate() {
            draw_one(&mut chart, k, s)?;
        }
        draw_legend(&mut chart)
    })
}

/// Writes an SVG document to `path`.
///
/// # Examples
/// ```
/// let e = vatcal_report::save_svg("/no-such-directory/plot.svg", "<svg/>").expect_err("no directory");
/// assert!(e.to_string().starts_with("/no-such-directory/plot.svg"));
/// ```
///
/// # Errors
/// The file cannot be written (the error names the path).
pub fn save_svg(path: impl AsRef<Path>, svg: &str) -> Result<(), PlotError> {
    let path = path.as_ref();
    std::fs::write(path, svg).map_err(|source| PlotError::File { path: path.to_path_buf(), source })
}
