//! The calibration pipeline on devices of your own: plan → campaign → identify → validate →
//! report.
//!
//! [`vatcal_pipeline::run`] takes anything that lends a cell's devices ([`DeviceSet`]) and a
//! description of the setup for the report ([`ReportSetup`]). Here the devices are the virtual
//! cell of `vatcal-sim` (a real cell lends the drivers connected by `vatcal-devices`), the
//! sizes are small so it runs in seconds, and the report folder goes to the temporary
//! directory (or the first argument).
//!
//! ```text
//! cargo run -p vatcal-pipeline --example run_pipeline -- /tmp/pipeline-example
//! ```

use serde::Serialize;
use vatcal_campaign::{CampaignConfig, CellDevices};
use vatcal_core::CellFile;
use vatcal_hardware_traits::{TriCal, VirtualClock};
use vatcal_identification::Identification;
use vatcal_kinematics::Model;
use vatcal_pipeline::report::ValidationSummary;
use vatcal_pipeline::{CALIBRATED, DeviceSet, NOMINAL, ReportSetup, RunOptions, RunSizes, StageLog};
use vatcal_sim::{SimArm, SimGauge, SimGuide, SimOperator, SimTracker, VirtualCell};

/// The simulated devices, lent to each campaign (measurement, then validation).
struct Devices {
    arm: SimArm,
    guide: SimGuide,
    probe: TriCal<SimGauge>,
    tracker: SimTracker,
    operator: SimOperator,
    clock: VirtualClock,
    thermometer: Option<vatcal_sim::SimThermometer>,
}

impl DeviceSet for Devices {
    fn devices(&mut self) -> CellDevices<'_> {
        CellDevices {
            arm: &mut self.arm,
            guide: Some(&mut self.guide),
            probe: &mut self.probe,
            tracker: Some(&mut self.tracker),
            operator: &mut self.operator,
            clock: &self.clock,
            thermometer: self.thermometer.as_mut().map(|t| t as &mut dyn vatcal_hardware_traits::Thermometer),
        }
    }
}

/// What `report.json`'s `setup` and `summary.md`'s header say about this run.
#[derive(Serialize)]
struct Setup {
    parameters: usize,
}

impl ReportSetup for Setup {
    fn format(&self) -> &str {
        "pipeline-example-report"
    }
    fn title(&self, seed: u64) -> String {
        format!("# Pipeline example (seed {seed})")
    }
    fn intro(&self) -> String {
        "A small calibration of the virtual cell through `vatcal_pipeline::run`.".into()
    }
    fn setup_markdown(&self, v: &ValidationSummary) -> String {
        format!("* {} random validation poses\n", v.random_poses)
    }
    fn parameters(&self) -> String {
        format!("paper34 ({} parameters)", self.parameters)
    }
    fn method(&self) -> String {
        "Levenberg–Marquardt".into()
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("vatcal-pipeline-example"));
    let nominal = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?;
    let cell = VirtualCell::paper(Model::from_cell(&nominal)?, 5);
    let mut devices = Devices {
        arm: cell.arm(),
        guide: cell.guide().expect("the canonical cell has a guide"),
        probe: cell.probe()?,
        tracker: cell.tracker(),
        operator: cell.operator(),
        clock: cell.clock(),
        thermometer: cell.thermometer(),
    };
    let options = RunOptions {
        seed: 5,
        nominal,
        sizes: RunSizes { orientations: 120, guide_steps: 3, count: 40, random_poses: 60, slices: 30 },
        campaign: CampaignConfig {
            show_progress: false,
            skip_failed_measurements: true,
            sync_journal_each_step: false,
            ..CampaignConfig::default()
        },
    };
    let setup = |fit: &Identification| Setup { parameters: fit.params.len() };
    let mut log = |line: &str| println!("{line}");
    let outcome = vatcal_pipeline::run(&options, &mut devices, setup, &out, &mut StageLog(&mut log))?;
    for label in [NOMINAL, CALIBRATED] {
        let v = outcome.validation(label).ok_or("validation missing")?;
        println!("{label:>10}: random poses {}", v.random.stats.one_line());
    }
    println!("files in {}: {:?}", out.display(), outcome.files);
    Ok(())
}
