//! SVG plots and a self-contained HTML page, as every vatcal report writes them.
//!
//! Makes two deterministic error series (a "nominal" model around 1 mm and a "calibrated" one
//! around 15 µm), draws their histogram and a line plot along a path, counts the bins the way
//! the histogram does, and puts everything into one HTML page in the temporary directory.
//!
//! ```text
//! cargo run -p vatcal-report --example plots_and_page
//! ```

use vatcal_report::html::HtmlReport;
use vatcal_report::{HistogramOptions, PlotSpec, Series, bin_counts, histogram_svg, line_plot_svg, save_svg};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // deterministic "errors" (no random numbers needed for a plot example)
    let n = 300;
    let nominal: Vec<f64> = (0..n).map(|k| 1.0 + 0.4 * (k as f64 * 0.37).sin()).collect();
    let calibrated: Vec<f64> = (0..n).map(|k| 0.015 + 0.006 * (k as f64 * 0.91).cos()).collect();
    let slices: Vec<f64> = (0..n).map(|k| k as f64).collect();

    let counts = bin_counts(&calibrated, 0.0, 0.03, 6);
    println!("calibrated errors in 6 bins of 5 µm: {counts:?}");
    if counts.iter().sum::<usize>() != n {
        return Err("every value lies inside 0..0.03 mm and must be counted once".into());
    }

    let series = [Series::new("nominal", &nominal), Series::new("calibrated", &calibrated)];
    let hist = histogram_svg(
        &PlotSpec::new("Position error at 300 poses", "error [mm]", "share of poses [%]"),
        &series,
        &HistogramOptions::default(),
    )?;
    let line =
        line_plot_svg(&PlotSpec::new("Error along the path", "slice", "error [mm]"), &slices, &series)?;

    let dir = std::env::temp_dir().join(format!("vatcal-report-example-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    save_svg(dir.join("histogram.svg"), &hist)?;
    let mut page = HtmlReport::new("vatcal report example");
    page.heading("Errors")
        .paragraph("Two series of position errors, **nominal** and **calibrated**.")
        .table(
            &["model", "mean [mm]"],
            &[
                vec!["nominal".into(), format!("{:.4}", nominal.iter().sum::<f64>() / n as f64)],
                vec!["calibrated".into(), format!("{:.4}", calibrated.iter().sum::<f64>() / n as f64)],
            ],
        )
        .svg(hist, "histogram of the errors")
        .svg(line, "error along the path");
    let html = dir.join("report.html");
    page.save(&html)?;
    println!("wrote {} ({} bytes) and histogram.svg", html.display(), std::fs::metadata(&html)?.len());
    Ok(())
}
