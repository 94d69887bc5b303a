//! The validation's CSVs and the SVG plots of a run folder, written from the stages'
//! outputs (the tracker records, each model's errors, the identification).

use std::fmt::Write as _;

use vatcal_campaign::validation::plots::{path_error_svg, random_error_histogram_svg};
use vatcal_campaign::validation::{ModelValidation, PathValidation, PrintingSlice, ValidationRecords};
use vatcal_identification::Identification;
use vatcal_report::{PlotSpec, Series, line_plot_svg};

use crate::files::Files;
use crate::folders::{
    IDENTIFICATION_CONVERGENCE_SVG, PATH_ERRORS_CALIBRATED_SVG, PATH_ERRORS_SVG, PRINTING_PATH_ERRORS_CSV,
    RANDOM_ERRORS_HISTOGRAM_SVG, VALIDATION_RANDOM_CSV, VALIDATION_RANDOM_ERRORS_CSV, validation_path_csv,
};
use crate::{CALIBRATED, PipelineError};

impl Files {
    /// The tracker measurements (random poses, each path run) and the error tables.
    pub fn validation_csvs(
        &mut self,
        records: &ValidationRecords,
        slices: &[PrintingSlice],
        results: &[ModelValidation],
    ) -> Result<(), PipelineError> {
        self.measurements(VALIDATION_RANDOM_CSV, &records.random)?;
        for p in &records.paths {
            self.measurements(&validation_path_csv(&p.label), &records.path_measurements(&p.label))?;
        }
        self.text(VALIDATION_RANDOM_ERRORS_CSV, &random_errors_csv(records, results))?;
        if slices.is_empty() {
            // a chain without the printing path
            return Ok(());
        }
        self.text(PRINTING_PATH_ERRORS_CSV, &path_errors_csv(slices, results))
    }

    /// The SVG plots: histogram (Fig. 8), path errors (Fig. 10, all models and the calibrated
    /// one alone), identification convergence.
    pub fn plots(
        &mut self,
        fit: &Identification,
        slices: &[PrintingSlice],
        results: &[ModelValidation],
    ) -> Result<(), PipelineError> {
        self.svg(RANDOM_ERRORS_HISTOGRAM_SVG, &random_error_histogram_svg(results, 40)?)?;
        let paths: Vec<&PathValidation> = results.iter().filter_map(|r| r.path.as_ref()).collect();
        if slices.is_empty() || paths.is_empty() {
            // a chain without the printing path
            return self.svg(IDENTIFICATION_CONVERGENCE_SVG, &convergence_svg(fit)?);
        }
        let title = "Position error at the tank bottom along the printing path";
        self.svg(PATH_ERRORS_SVG, &path_error_svg(title, slices, &paths)?)?;
        let calibrated: Vec<&PathValidation> =
            paths.iter().copied().filter(|p| p.label == CALIBRATED).collect();
        if !calibrated.is_empty() {
            let title = "Position error along the printing path, calibrated model";
            self.svg(PATH_ERRORS_CALIBRATED_SVG, &path_error_svg(title, slices, &calibrated)?)?;
        }
        self.svg(IDENTIFICATION_CONVERGENCE_SVG, &convergence_svg(fit)?)
    }
}

fn convergence_svg(fit: &Identification) -> Result<String, vatcal_report::PlotError> {
    let x: Vec<f64> = fit.iterations.iter().map(|l| l.iteration as f64).collect();
    let y: Vec<f64> = fit.iterations.iter().map(|l| l.mean_mm.max(1e-12).log10()).collect();
    let spec = PlotSpec::new(
        "Identification (Levenberg-Marquardt): mean residual per iteration",
        "iteration",
        "log10(mean residual / 1 mm)",
    );
    line_plot_svg(&spec, &x, &[Series::new("mean residual of the probe measurements", &y)])
}

/// `pose,tcp,<label>_dx_mm,<label>_dy_mm,<label>_dz_mm,<label>_error_mm,...`
fn random_errors_csv(records: &ValidationRecords, results: &[ModelValidation]) -> String {
    let mut out = String::from("pose,tcp");
    for r in results {
        let l = &r.label;
        let _ = write!(out, ",{l}_dx_mm,{l}_dy_mm,{l}_dz_mm,{l}_error_mm");
    }
    out.push('\n');
    for (k, m) in records.random.iter().enumerate() {
        let _ = write!(out, "{k},{}", m.tcp);
        for r in results {
            if let Some(e) = r.random.errors_mm.get(k) {
                let _ = write!(out, ",{},{},{},{}", e.x, e.y, e.z, e.norm());
            }
        }
        out.push('\n');
    }
    out
}

/// `slice,part_height_mm,target_x_mm,target_y_mm,target_z_mm`, then per model
/// `<label>_dx_mm,<label>_dy_mm,<label>_dz_mm,<label>_error_mm,<label>_plate_error_mm,
/// <label>_orientation_error_deg`.
fn path_errors_csv(slices: &[PrintingSlice], results: &[ModelValidation]) -> String {
    let paths: Vec<&PathValidation> = results.iter().filter_map(|r| r.path.as_ref()).collect();
    let mut out = String::from("slice,part_height_mm,target_x_mm,target_y_mm,target_z_mm");
    for p in &paths {
        let l = &p.label;
        let _ = write!(
            out,
            ",{l}_dx_mm,{l}_dy_mm,{l}_dz_mm,{l}_error_mm,{l}_plate_error_mm,{l}_orientation_error_deg"
        );
    }
    out.push('\n');
    for (k, s) in slices.iter().enumerate() {
        let t = s.tip_world_mm;
        let _ = write!(out, "{},{},{},{},{}", s.index, s.part_height_mm, t.x, t.y, t.z);
        for p in &paths {
            let e = p.tip_errors_mm[k];
            let _ = write!(
                out,
                ",{},{},{},{},{},{}",
                e.x,
                e.y,
                e.z,
                e.norm(),
                p.plate_errors_mm[k].norm(),
                p.orientation_errors_rad[k].to_degrees()
            );
        }
        out.push('\n');
    }
    out
}
