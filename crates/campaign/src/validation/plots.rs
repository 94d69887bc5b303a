//! SVG plots of a validation (via `vatcal-report`): the error histogram of the random poses
//! (paper Fig. 8) and the errors along the printing path (paper Fig. 10).

use vatcal_report::{HistogramOptions, PlotError, PlotSpec, Series, histogram_svg, line_plot_svg};

use super::{ModelValidation, PathValidation, PrintingSlice};

/// Histogram of the random-pose error magnitudes, one panel per model (nominal and calibrated
/// errors differ by orders of magnitude, so each panel has its own bins), `bins` bins.
///
/// # Errors
/// No model, or a plotting failure.
pub fn random_error_histogram_svg(results: &[ModelValidation], bins: usize) -> Result<String, PlotError> {
    let values: Vec<Vec<f64>> = results.iter().map(|r| r.random.magnitudes()).collect();
    let labels: Vec<String> =
        results.iter().map(|r| format!("{} model, mean {:.3} mm", r.label, r.random.stats.mean)).collect();
    let series: Vec<Series<'_>> = labels.iter().zip(&values).map(|(l, v)| Series::new(l, v)).collect();
    let mut spec = PlotSpec::new(
        "Position error at random poses (laser tracker)",
        "position error [mm]",
        "share of poses [%]",
    );
    spec.height = 300 * results.len().max(1) as u32;
    histogram_svg(&spec, &series, &HistogramOptions { bins, ..HistogramOptions::default() })
}

/// Error magnitude at the end of the printed part (tank bottom) against the slice number, one
/// line per path run, with `title`.
///
/// # Errors
/// No run, slice counts that differ from `slices`, or a plotting failure.
pub fn path_error_svg(
    title: &str,
    slices: &[PrintingSlice],
    runs: &[&PathValidation],
) -> Result<String, PlotError> {
    let x: Vec<f64> = slices.iter().map(|s| (s.index + 1) as f64).collect();
    let values: Vec<Vec<f64>> = runs.iter().map(|r| r.tip_magnitudes()).collect();
    let labels: Vec<String> = runs
        .iter()
        .map(|r| format!("commanded by the {} model, mean {:.3} mm", r.label, r.tip_stats.mean))
        .collect();
    let series: Vec<Series<'_>> = labels.iter().zip(&values).map(|(l, v)| Series::new(l, v)).collect();
    let spec = PlotSpec::new(title, "slice", "position error at the tank bottom [mm]");
    line_plot_svg(&spec, &x, &series)
}
