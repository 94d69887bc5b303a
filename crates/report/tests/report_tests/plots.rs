//! Tests of the SVG plot functions.

use proptest::prelude::*;
use vatcal_report::{
    HistogramLayout, HistogramOptions, HistogramScale, PlotError, PlotSpec, Series, bin_counts,
    histogram_svg, line_plot_svg, save_svg, scatter_svg,
};

fn spec() -> PlotSpec {
    PlotSpec::new("Position error", "error [mm]", "share of poses [%]")
}

#[test]
fn histogram_of_two_series_has_both_legends_and_bars() {
    let before: Vec<f64> = (0..200).map(|k| 0.8 + 0.004 * k as f64).collect();
    let after: Vec<f64> = (0..150).map(|k| 0.01 + 0.0001 * k as f64).collect();
    let svg = histogram_svg(
        &spec(),
        &[Series::new("nominal", &before), Series::new("calibrated", &after)],
        &HistogramOptions::default(),
    )
    .expect("svg");
    assert!(svg.starts_with("<svg"), "{}", &svg[..40]);
    assert!(svg.contains("nominal (n = 200)"));
    assert!(svg.contains("calibrated (n = 150)"));
    // default layout: one panel per series, each with its own bins and caption
    assert!(svg.contains("Position error: nominal"), "panel caption");
    assert!(svg.contains("Position error: calibrated"), "panel caption");
    assert_eq!(svg.matches("error [mm]").count(), 2, "one x label per panel");
    // every non-empty bin is a rectangle; with its own bins (from 0) each series fills about
    // half of its 40 bins: 20 + 24 bars
    assert!(svg.matches("<rect").count() > 44);

    let overlay = histogram_svg(
        &spec(),
        &[Series::new("nominal", &before), Series::new("calibrated", &after)],
        &HistogramOptions { layout: HistogramLayout::Overlay, ..Default::default() },
    )
    .expect("overlay");
    assert!(overlay.contains("nominal (n = 200)") && overlay.contains("calibrated (n = 150)"));
    assert_eq!(overlay.matches("error [mm]").count(), 1);
    // shared bins: all "after" values fall into the first bin
    assert!(overlay.matches("<rect").count() < svg.matches("<rect").count());
}

#[test]
fn histogram_percentages_and_counts_differ_only_in_scale() {
    let v = [0.1, 0.2, 0.2, 0.3];
    let opts =
        HistogramOptions { bins: 3, scale: HistogramScale::Count, from_zero: false, ..Default::default() };
    let counts = histogram_svg(&spec(), &[Series::new("a", &v)], &opts).expect("counts");
    let pct = histogram_svg(
        &spec(),
        &[Series::new("a", &v)],
        &HistogramOptions { scale: HistogramScale::Percent, ..opts },
    )
    .expect("pct");
    assert_eq!(counts.matches("<rect").count(), pct.matches("<rect").count());
}

#[test]
fn line_and_scatter_plots_draw_every_series() {
    let x: Vec<f64> = (0..50).map(|k| k as f64).collect();
    let a: Vec<f64> = x.iter().map(|v| (v * 0.2).sin()).collect();
    let b: Vec<f64> = x.iter().map(|v| 0.5 * (v * 0.1).cos()).collect();
    let s = [Series::new("nominal", &a), Series::new("calibrated", &b)];
    let line = line_plot_svg(&spec(), &x, &s).expect("line");
    assert!(line.matches("<polyline").count() >= 2, "two line series");
    assert!(line.contains("nominal") && line.contains("calibrated"));
    let scatter = scatter_svg(&spec(), &x, &s).expect("scatter");
    assert!(scatter.matches("<circle").count() >= 100, "one circle per point");
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let x = [0.0, 1.0, 2.0];
    assert!(matches!(histogram_svg(&spec(), &[], &HistogramOptions::default()), Err(PlotError::Empty(_))));
    assert!(matches!(
        histogram_svg(&spec(), &[Series::new("e", &[])], &HistogramOptions::default()),
        Err(PlotError::Empty(_))
    ));
    let nan = [1.0, f64::NAN];
    assert!(matches!(
        histogram_svg(&spec(), &[Series::new("bad", &nan)], &HistogramOptions::default()),
        Err(PlotError::NonFinite { index: 1, .. })
    ));
    assert!(matches!(
        histogram_svg(&spec(), &[Series::new("a", &x)], &HistogramOptions { bins: 0, ..Default::default() }),
        Err(PlotError::Option(_))
    ));
    assert!(matches!(
        line_plot_svg(&spec(), &x, &[Series::new("short", &[1.0, 2.0])]),
        Err(PlotError::Length { expected: 3, got: 2, .. })
    ));
    let tiny = PlotSpec { width: 10, ..spec() };
    assert!(matches!(scatter_svg(&tiny, &x, &[Series::new("a", &x)]), Err(PlotError::Option(_))));
}

#[test]
fn constant_series_still_plot() {
    let v = [0.5; 10];
    histogram_svg(&spec(), &[Series::new("c", &v)], &HistogramOptions::default()).expect("hist");
    let x: Vec<f64> = (0..10).map(f64::from).collect();
    line_plot_svg(&spec(), &x, &[Series::new("c", &v)]).expect("line");
    scatter_svg(&spec(), &[1.0; 10], &[Series::new("c", &v)]).expect("scatter");
}

#[test]
fn save_writes_the_file_and_names_a_bad_path() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("h.svg");
    let svg =
        histogram_svg(&spec(), &[Series::new("a", &[1.0, 2.0])], &HistogramOptions::default()).expect("svg");
    save_svg(&path, &svg).expect("save");
    assert_eq!(std::fs::read_to_string(&path).expect("read"), svg);
    let bad = dir.path().join("missing-dir").join("h.svg");
    let err = save_svg(&bad, &svg).expect_err("must fail");
    assert!(err.to_string().contains("missing-dir"), "{err}");
}

proptest! {
    #[test]
    fn bins_count_every_value_once(values in proptest::collection::vec(-10.0f64..10.0, 1..200), bins in 1usize..60) {
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let counts = bin_counts(&values, lo, hi, bins);
        prop_assert_eq!(counts.len(), bins);
        prop_assert_eq!(counts.iter().sum::<usize>(), values.len());
    }
}
