//! `vatcal plan`: plan a measurement campaign (candidates, Detmax, tour, paths).
//!
//! Writes `candidates.csv`, `selected.csv`, `tour.csv` and `summary.json` into `--out` and
//! prints the summary. Works on any serial chain of the cell file (joint columns `q1..qN`).
//! See `docs/planning.md`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use vatcal_core::{CellFile, JointVector, ParamSet};
use vatcal_kinematics::Model;
use vatcal_planning::candidates::CandidateOptions;
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::output::write_plan;
use vatcal_planning::plan::{PlanOptions, plan_campaign};

/// Arguments of `vatcal plan`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Cell model (TOML); a calibrated model plans with its calibrated kinematics.
    #[arg(long, value_name = "CELL.toml")]
    pub model: PathBuf,
    /// Random tool orientations per TCP × calibration position.
    #[arg(long, default_value_t = 500)]
    pub orientations: usize,
    /// Guide positions over the stroke (of the first prismatic joint; ignored without one).
    #[arg(long, default_value_t = 10)]
    pub guide_steps: usize,
    /// Number of measurements to select.
    #[arg(long, default_value_t = 40)]
    pub count: usize,
    /// Master seed of every random stage.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Restarts of the tour heuristic.
    #[arg(long, default_value_t = 16)]
    pub restarts: usize,
    /// Restarts of Detmax.
    #[arg(long, default_value_t = 8)]
    pub detmax_restarts: usize,
    /// Half-angle of the cone around world +z holding the ball-to-flange direction \[deg\].
    #[arg(long, default_value_t = 60.0)]
    pub cone_deg: f64,
    /// Margin kept from the arm joint limits at measurement poses \[deg\].
    #[arg(long, default_value_t = 5.0)]
    pub joint_margin_deg: f64,
    /// Safety distance added around every robot body in collision checks \[mm\].
    #[arg(long, default_value_t = 2.0)]
    pub collision_margin_mm: f64,
    /// Parameters the selection must identify: `default` (`paper34` on the canonical
    /// Meca500-on-guide cell, the identifiable basis of all parameters for the candidates on any
    /// other chain), `paper34`, `geometric` or a comma list of names.
    #[arg(long, default_value = "default")]
    pub params: String,
    /// Robot joints at the start of the campaign, `q1,...,qN` in mm (prismatic) / deg (revolute)
    /// (default: start at the first measurement).
    #[arg(long, value_name = "Q1,..,QN")]
    pub start: Option<String>,
    /// Output directory.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Do not draw the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

fn parse_start(text: &str, model: &Model) -> anyhow::Result<JointVector> {
    let values: Vec<f64> = text
        .split(',')
        .enumerate()
        .map(|(k, s)| {
            s.trim()
                .parse::<f64>()
                .with_context(|| format!("--start: q{} = `{}` is not a number", k + 1, s.trim()))
        })
        .collect::<anyhow::Result<_>>()?;
    let n = model.joint_count();
    if values.len() != n {
        anyhow::bail!(
            "--start needs {n} values q1..q{n} (mm for prismatic, deg for revolute joints), got {}",
            values.len()
        );
    }
    let q = JointVector::from_file_units(&values, model.joint_kinds())
        .map_err(|e| anyhow::anyhow!("--start: {e}"))?;
    if let Some((j, v, lo, hi)) = model.limit_violation(&q) {
        let revolute = model.is_revolute(j);
        let unit = |x: f64| if revolute { format!("{} deg", x.to_degrees()) } else { format!("{x} mm") };
        anyhow::bail!("--start: q{j} = {} is outside its limits {}..{}", unit(v), unit(lo), unit(hi));
    }
    Ok(q)
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let cell = CellFile::load(&args.model)?;
    let model = Model::from_cell(&cell)
        .with_context(|| format!("{}: cannot build the model", args.model.display()))?;
    let geometry = CellGeometry::from_cell(&cell).with_context(|| format!("{}", args.model.display()))?;
    let params = match args.params.trim() {
        // resolved on the candidates by plan_campaign (paper34 on the canonical cell)
        "default" if model.is_meca500_on_guide() => vatcal_core::canonical::default_param_set(),
        "default" => ParamSet(Vec::new()),
        spec => ParamSet::parse(spec).map_err(|e| anyhow::anyhow!("--params: {e}"))?,
    };
    let start = args.start.as_deref().map(|s| parse_start(s, &model)).transpose()?;
    let opts = PlanOptions {
        candidates: CandidateOptions {
            orientations: args.orientations,
            guide_steps: args.guide_steps,
            cone_half_angle_deg: args.cone_deg,
            joint_margin_deg: args.joint_margin_deg,
            collision_margin_mm: args.collision_margin_mm,
            progress: !args.quiet,
            ..CandidateOptions::default()
        },
        count: args.count,
        params,
        detmax_restarts: args.detmax_restarts,
        tour_restarts: args.restarts,
        motion: cell.motion_limits(),
        start,
        seed: args.seed,
        ..PlanOptions::default()
    };
    let t0 = Instant::now();
    let plan = plan_campaign(&model, &geometry, &opts)?;
    let elapsed = t0.elapsed();
    let summary = write_plan(&plan, &args.out)?;
    println!("{}", summary.text());
    println!(
        "planned in {:.2} s; wrote candidates.csv, selected.csv, tour.csv, summary.json to {}",
        elapsed.as_secs_f64(),
        args.out.display()
    );
    Ok(())
}
