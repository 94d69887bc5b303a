//! `vatcal plan`: plan a measurement campaign (candidates, Detmax, tour, paths).
//!
//! `--kind calibration` (the default) writes `candidates.csv`, `selected.csv`, `tour.csv` and
//! `summary.json` into `--out` and prints the summary. Works on any serial chain of the cell
//! file (joint columns `q1..qN`). See `docs/planning.md`.
//!
//! `--kind discovery` and `--kind validation` write the plan folders of `vatcal calibrate`'s
//! discovery and validation stages with the pipeline's own planning functions
//! (`vatcal_pipeline::discovery_stage::plan_discovery`, `vatcal_pipeline::plans`), which
//! `vatcal campaign --plan DIR` runs by hand. See `docs/campaign.md`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use vatcal_campaign::CampaignConfig;
use vatcal_core::{CellFile, JointVector, ParamSet};
use vatcal_kinematics::Model;
use vatcal_pipeline::plans::{discovery_tour_of, validation_plan, write_validation_plan};
use vatcal_pipeline::{DiscoveryStageOptions, PlanFolder, RunOptions, RunSizes};
use vatcal_planning::candidates::CandidateOptions;
use vatcal_planning::geometry::CellGeometry;
use vatcal_planning::output::write_plan;
use vatcal_planning::plan::{PlanOptions, plan_campaign};

/// What a plan is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// the probe campaign the identification uses
    Calibration,
    /// the extra probe campaign of the discovery: Detmax for the calibration's parameters and
    /// the candidate effects' directions, with two-sided repeats
    Discovery,
    /// the laser-tracker validation: random poses and the printing path
    Validation,
}

/// Arguments of `vatcal plan`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Cell model (TOML); a calibrated model plans with its calibrated kinematics. For
    /// `--kind validation` the nominal cell the robot controller believes.
    #[arg(long, value_name = "CELL.toml")]
    pub model: PathBuf,
    /// What to plan: the calibration campaign, the discovery campaign or the tracker
    /// validation (as `vatcal calibrate`'s stages plan them).
    #[arg(long, value_enum, default_value = "calibration")]
    pub kind: Kind,
    /// Random tool orientations per TCP × calibration position (calibration, discovery).
    #[arg(long, default_value_t = 500)]
    pub orientations: usize,
    /// Guide positions over the stroke (of the first prismatic joint; ignored without one;
    /// calibration, discovery).
    #[arg(long, default_value_t = 10)]
    pub guide_steps: usize,
    /// Number of measurements to select (default: 40 for a calibration plan, 360 for a
    /// discovery plan, as `vatcal calibrate`).
    #[arg(long)]
    pub count: Option<usize>,
    /// Discovery plans: planned poses measured a second time, approached from the opposite
    /// side on every revolute joint.
    #[arg(long, default_value_t = 12)]
    pub two_sided_repeats: usize,
    /// Validation plans: random poses measured by the tracker.
    #[arg(long, default_value_t = 573)]
    pub random_poses: usize,
    /// Validation plans: slices of the printing path (0: random poses only).
    #[arg(long, default_value_t = 300)]
    pub slices: usize,
    /// Validation plans: a model commanding its own run of the printing path besides the
    /// nominal one, `LABEL=CELL.toml` (e.g. `calibrated=run/calibrated.toml`; repeat for more).
    #[arg(long, value_name = "LABEL=CELL.toml")]
    pub path_model: Vec<String>,
    /// Master seed of every random stage.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Restarts of the tour heuristic (calibration plans).
    #[arg(long, default_value_t = 16)]
    pub restarts: usize,
    /// Restarts of Detmax (calibration plans).
    #[arg(long, default_value_t = 8)]
    pub detmax_restarts: usize,
    /// Half-angle of the cone around world +z holding the ball-to-flange direction \[deg\]
    /// (calibration plans).
    #[arg(long, default_value_t = 60.0)]
    pub cone_deg: f64,
    /// Margin kept from the arm joint limits at measurement poses \[deg\] (calibration plans).
    #[arg(long, default_value_t = 5.0)]
    pub joint_margin_deg: f64,
    /// Safety distance added around every robot body in collision checks \[mm\] (calibration
    /// plans).
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
    let model = super::model_of(&cell, &args.model)?;
    let geometry = CellGeometry::from_cell(&cell).with_context(|| format!("{}", args.model.display()))?;
    let params = match args.params.trim() {
        // resolved on the candidates by plan_campaign (paper34 on the canonical cell)
        "default" if model.is_meca500_on_guide() => vatcal_core::canonical::default_param_set(),
        "default" => ParamSet(Vec::new()),
        spec => ParamSet::parse(spec).map_err(|e| anyhow::anyhow!("--params: {e}"))?,
    };
    let start = args.start.as_deref().map(|s| parse_start(s, &model)).transpose()?;
    match args.kind {
        Kind::Calibration => {}
        Kind::Discovery => return plan_discovery(&args, cell, &model, &geometry, params, start),
        Kind::Validation => return plan_validation(&args, cell, &model, &geometry, start),
    }
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
        count: args.count.unwrap_or(40),
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

/// The pipeline's run options of a by-hand plan (seed, cell, sizes).
fn run_options(args: &Args, cell: CellFile, count: usize) -> RunOptions {
    RunOptions {
        seed: args.seed,
        nominal: cell,
        sizes: RunSizes {
            orientations: args.orientations,
            guide_steps: args.guide_steps,
            count,
            random_poses: args.random_poses,
            slices: args.slices,
        },
        campaign: CampaignConfig::default(),
    }
}

/// `--kind discovery`: `vatcal calibrate`'s discovery plan (`plan_discovery`) into `--out`.
fn plan_discovery(
    args: &Args,
    cell: CellFile,
    model: &Model,
    geometry: &CellGeometry,
    params: ParamSet,
    start: Option<JointVector>,
) -> anyhow::Result<()> {
    if params.is_empty() {
        anyhow::bail!(
            "--kind discovery on {}: give the calibration's parameter set with --params (the default set of a \
             chain other than the canonical cell is only known after planning its calibration)",
            model.describe_chain()
        );
    }
    let count = args.count.unwrap_or(360);
    let opts = run_options(args, cell, count);
    let stage = DiscoveryStageOptions {
        count,
        plan_effects: vatcal_pipeline::discovery_stage::plan_effects_for(model),
        two_sided_repeats: args.two_sided_repeats,
        ..DiscoveryStageOptions::new(args.seed)
    };
    let folder = PlanFolder::new(&args.out);
    let t0 = Instant::now();
    let summary = vatcal_pipeline::discovery_stage::plan_discovery(
        &opts, &stage, model, &params, geometry, start, &folder,
    )?;
    let (tour, repeats) =
        discovery_tour_of(&folder, model, stage.two_sided_repeats, stage.repeat_overshoot_rad)?;
    println!("{}", summary.text());
    println!(
        "discovery plan: {} measurements selected for {} parameters and {} candidate effects, {} two-sided repeats \
         added when it runs ({} measurements in {} campaign steps)",
        summary.selected,
        params.len(),
        stage.plan_effects.len(),
        repeats,
        tour.measurement_count(),
        tour.steps.len()
    );
    println!(
        "planned in {:.2} s; wrote candidates.csv, selected.csv, tour.csv, summary.json (kind discovery) to {}",
        t0.elapsed().as_secs_f64(),
        args.out.display()
    );
    Ok(())
}

/// `--kind validation`: `vatcal calibrate`'s validation plan into `--out`.
fn plan_validation(
    args: &Args,
    cell: CellFile,
    model: &Model,
    geometry: &CellGeometry,
    start: Option<JointVector>,
) -> anyhow::Result<()> {
    let mut others: Vec<(String, Model)> = Vec::new();
    for spec in &args.path_model {
        let Some((label, file)) = spec.split_once('=') else {
            anyhow::bail!("--path-model `{spec}`: expected LABEL=CELL.toml");
        };
        let label = label.trim();
        if label.is_empty() || label == vatcal_pipeline::NOMINAL || others.iter().any(|(l, _)| l == label) {
            anyhow::bail!(
                "--path-model `{spec}`: the label must be non-empty, not `{}` (the --model's run) and not repeated",
                vatcal_pipeline::NOMINAL
            );
        }
        let other = CellFile::load(file.trim())?;
        let m = Model::from_cell(&other).with_context(|| format!("{file}: cannot build the model"))?;
        if m.joint_kinds() != model.joint_kinds() {
            anyhow::bail!(
                "--path-model {file}: {} is not the chain of {}",
                m.describe_chain(),
                args.model.display()
            );
        }
        others.push((label.to_string(), m));
    }
    let opts = run_options(args, cell, args.count.unwrap_or(40));
    if opts.sizes.random_poses == 0 {
        anyhow::bail!("--random-poses must be at least 1");
    }
    let mut commanding: Vec<(&str, &Model)> = vec![(vatcal_pipeline::NOMINAL, model)];
    commanding.extend(others.iter().map(|(l, m)| (l.as_str(), m)));
    let t0 = Instant::now();
    let (plan, _) = validation_plan(&opts, model, geometry, &commanding, start)?;
    let summary = write_validation_plan(&plan, model, args.seed, &PlanFolder::new(&args.out))?;
    println!(
        "validation plan: {} random poses, {} printing-path slices × {} run(s) ({}), SMRs {:?}: {} tracker \
         measurements in {} campaign steps ({} RRT legs)",
        summary.random_poses,
        summary.slices,
        summary.path_runs.len(),
        summary.path_runs.join(", "),
        summary.slice_targets,
        summary.tracker_measurements,
        summary.steps,
        summary.rrt_legs
    );
    println!(
        "planned in {:.2} s; wrote tour.csv, summary.json (kind validation) to {}",
        t0.elapsed().as_secs_f64(),
        args.out.display()
    );
    Ok(())
}
