//! SVG plots of the residual against an added effect's driving variable, before and after the
//! effect was added (built with `vatcal-report`).

use std::path::{Path, PathBuf};

use vatcal_report::{PlotError, PlotSpec, Series, save_svg, scatter_svg};

use crate::workflow::{AddedEffect, Discovery};

/// The plot of one added effect: the residual against its driving variable, before and after
/// (see [`crate::workflow::DriverPlot`] for what the y axis shows).
pub fn effect_plot_svg(step: usize, added: &AddedEffect) -> Result<String, PlotError> {
    let spec = PlotSpec::new(
        format!("step {step}: {}", added.label),
        added.plot.x_label.clone(),
        added.plot.y_label.clone(),
    );
    scatter_svg(
        &spec,
        &added.plot.x,
        &[Series::new("before", &added.plot.before), Series::new("after", &added.plot.after)],
    )
}

/// File name of the plot of step `step` (1-based), e.g. `step1-joint-cyclic-j4.svg`.
pub fn effect_plot_file_name(step: usize, added: &AddedEffect) -> String {
    match added.joint {
        Some(j) => format!("step{step}-{}-j{j}.svg", added.effect),
        None => format!("step{step}-{}.svg", added.effect),
    }
}

/// Writes one plot per added effect into `dir` (created if missing); returns the files.
pub fn write_effect_plots(discovery: &Discovery, dir: &Path) -> Result<Vec<PathBuf>, PlotError> {
    std::fs::create_dir_all(dir).map_err(|source| PlotError::File { path: dir.to_path_buf(), source })?;
    let mut files = Vec::new();
    for (k, added) in discovery.added_effects.iter().enumerate() {
        let svg = effect_plot_svg(k + 1, added)?;
        let path = dir.join(effect_plot_file_name(k + 1, added));
        save_svg(&path, &svg)?;
        files.push(path);
    }
    Ok(files)
}
