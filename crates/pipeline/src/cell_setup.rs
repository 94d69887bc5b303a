//! `report.json`'s `setup` of a run on real devices (`vatcal calibrate`): the nominal cell
//! file, the devices file, the sizes.

use serde::Serialize;
use vatcal_identification::Identification;

use crate::discovery_stage::parameter_set_name;
use crate::report::{ReportSetup, ValidationSummary};
use crate::{RunOptions, RunSizes};

/// `report.json`'s `setup` of a run on real devices (`vatcal calibrate`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CellRunSetup {
    /// the nominal cell file (copied to `nominal.toml`)
    pub nominal_cell: String,
    /// the devices file
    pub devices: String,
    /// the run's sizes
    pub sizes: RunSizes,
    /// identified parameter set
    pub parameters: String,
    /// estimation method
    pub method: String,
}

impl CellRunSetup {
    /// The setup of a run of `opts` with the devices file `devices` that identified `fit`.
    pub fn of(opts: &RunOptions, nominal_cell: &str, devices: &str, fit: &Identification) -> Self {
        Self {
            nominal_cell: nominal_cell.into(),
            devices: devices.into(),
            sizes: opts.sizes.clone(),
            parameters: format!("{} ({} parameters)", parameter_set_name(&fit.params), fit.params.len()),
            method: fit.method.to_string(),
        }
    }
}

/// `report.json`'s `format` of a run on real devices.
pub const CELL_REPORT_FORMAT: &str = "vatcal-calibrate-report";

impl ReportSetup for CellRunSetup {
    fn format(&self) -> &str {
        CELL_REPORT_FORMAT
    }

    fn title(&self, seed: u64) -> String {
        format!("# vatcal calibrate — calibration of {} (seed {seed})", self.nominal_cell)
    }

    fn intro(&self) -> String {
        format!(
            "Everything below was measured on the devices of `{}` (`stages.json`: the stages and their attempts; \
             the journals hold every measurement).",
            self.devices
        )
    }

    fn setup_markdown(&self, v: &ValidationSummary) -> String {
        use std::fmt::Write as _;
        let mut m = String::new();
        let _ = writeln!(
            m,
            "* nominal cell (what the robot controller believes): {} → `nominal.toml`",
            self.nominal_cell
        );
        let _ = writeln!(m, "* devices: `{}`", self.devices);
        let s = &self.sizes;
        let _ = writeln!(
            m,
            "* sizes: {} orientations × {} guide steps per TCP × position, {} measurements, {} random validation poses, \
             {} printing slices",
            s.orientations, s.guide_steps, s.count, v.random_poses, v.printing_path.slices
        );
        m
    }

    fn parameters(&self) -> String {
        self.parameters.clone()
    }

    fn method(&self) -> String {
        self.method.clone()
    }
}
