//! `vatcal compensate`: compensated joint targets, corrected controller poses and Meca500
//! programs from a calibrated cell model of any chain of six or more joints (issues 13 and 12;
//! see `docs/compensation.md`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use vatcal_compensation::{
    Branch, CompensationError, Compensator, EachOptions, PathOptions, PathResult, PoseRequest, Preference,
    SolveOptions,
};
use vatcal_core::training_range;
use vatcal_core::{CellFile, JointVector};
use vatcal_drivers_meca500::Command as MecaCommand;
use vatcal_drivers_meca500::codec::format_number;
use vatcal_kinematics::Model;

/// The canonical nominal cell, used when neither `--nominal` nor the calibrated file names one.
const BUILT_IN_NOMINAL: &str = vatcal_core::CANONICAL_CELL_TOML;

/// What `vatcal compensate` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Emit {
    /// CSV `line,tcp,q1..qN,branch,residual_mm,residual_deg` (joint targets, mm/deg)
    Joints,
    /// CSV of corrected poses in the input format: FK_nominal(IK_calibrated(request))
    Poses,
    /// Meca500 program of `MoveJoints(...)` lines, guide moves as `# guide` comments (a chain
    /// whose last six joints are a Meca500 arm only)
    Meca500,
    /// Meca500 program of `MovePose(...)` lines (robot base frame, WRF = TRF = identity)
    #[value(name = "meca500-poses")]
    Meca500Poses,
}

/// Arguments of `vatcal compensate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Calibrated cell model (TOML, e.g. written by `vatcal identify`).
    #[arg(long)]
    pub model: PathBuf,
    /// Requested poses: CSV `tcp,q1,x,y,z,alpha,beta,gamma` on the canonical cell (mm, deg;
    /// world frame; Mecademic intrinsic X-Y-Z Euler angles of the tool-changer frame); on a
    /// six-joint arm `tcp,x,y,z,alpha,beta,gamma`; on a longer chain `tcp`, the prismatic
    /// joints' `q{i}`, then the pose. Optional `time_s`, `temperature_c`, `dir{i}`.
    #[arg(long)]
    pub poses: PathBuf,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
    /// Nominal cell model of the robot controller (default: `[provenance] nominal_cell` of the
    /// calibrated file, else the built-in canonical cell).
    #[arg(long)]
    pub nominal: Option<PathBuf>,
    /// What to write.
    #[arg(long, value_enum, default_value = "joints")]
    pub emit: Emit,
    /// Report unreachable rows (out of reach, limits, branch change, joint jump) and go on,
    /// instead of failing.
    #[arg(long)]
    pub skip_unreachable: bool,
    /// Largest change of an arm joint between consecutive rows \[deg\].
    #[arg(long, default_value_t = 30.0)]
    pub max_joint_step_deg: f64,
    /// IK branch of the path (with --each: of every row whose `branch` field is empty): on the
    /// canonical cell 0..=7 (bit 0 shoulder, bit 1 elbow, bit 2 wrist); on another chain `+`
    /// or `-` (sign of det J of the solved joints); default: the first row's solution farthest
    /// from the joint limits (with --each: each row's).
    #[arg(long, value_parser = parse_branch, allow_hyphen_values = true)]
    pub branch: Option<Branch>,
    /// Independent poses: solve every row on its own (no joint-jump limit, no branch kept from
    /// row to row). Implied by a `branch` column with a value on some row.
    #[arg(long)]
    pub each: bool,
    /// A joint configuration `q1,...,qN` (mm for prismatic, deg for revolute joints): with
    /// --each every row takes its solution nearest it; on a path the first row does (and so
    /// fixes the path's branch). Default: the solution farthest from the joint limits.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1)]
    pub near: Option<Vec<f64>>,
}

fn parse_branch(s: &str) -> Result<Branch, String> {
    match s {
        "+" => Ok(Branch::DET_POSITIVE),
        "-" => Ok(Branch::DET_NEGATIVE),
        _ => match s.parse::<u8>() {
            Ok(b) if b <= 7 => Ok(Branch(b)),
            _ => Err(format!("`{s}`: expected 0..=7 (canonical cell) or + / - (sign of det J)")),
        },
    }
}

/// The `--near` configuration (file units, one value per joint) in internal units.
fn near_joints(values: &[f64], model: &Model) -> anyhow::Result<JointVector> {
    let kinds = model.joint_kinds();
    if values.len() != kinds.len() || values.iter().any(|v| !v.is_finite()) {
        anyhow::bail!(
            "--near: expected {} finite joint values q1..q{} (mm / deg) of {}, got {values:?}",
            kinds.len(),
            kinds.len(),
            model.describe_chain()
        );
    }
    JointVector::from_file_units(values, kinds).map_err(|e| anyhow::anyhow!("--near: {e}"))
}

/// The branch each row's `branch` column names (`None` for an empty field or no column),
/// checked against the chain: `0..7` on the canonical cell, `+` / `-` on another chain.
fn row_branches(
    rows: &[vatcal_io::PoseRequestRow],
    compensator: &Compensator<'_>,
    poses: &Path,
) -> anyhow::Result<Vec<Option<Branch>>> {
    rows.iter()
        .map(|r| {
            let Some(text) = &r.branch else { return Ok(None) };
            let b = parse_branch(text)
                .map_err(|e| anyhow::anyhow!("{}:{}: column `branch`: {e}", poses.display(), r.line))?;
            if b.is_determinant_class() == compensator.is_closed_form() {
                anyhow::bail!(
                    "{}:{}: column `branch`: `{text}`: {}",
                    poses.display(),
                    r.line,
                    if compensator.is_closed_form() {
                        "the canonical cell's branches are 0..=7"
                    } else {
                        "on this chain the branch is the sign of det J: + or -"
                    }
                );
            }
            Ok(Some(b))
        })
        .collect()
}

/// The nominal model and a description of where it came from; `None` for a chain other than
/// the canonical cell that names none (then only `--emit joints` works).
fn nominal_model(
    args: &Args,
    calibrated: &CellFile,
    model: &Model,
) -> anyhow::Result<Option<(Model, String)>> {
    let from_file = |p: &Path| -> anyhow::Result<(Model, String)> {
        let model = super::load_model(p)?;
        let text = std::fs::read(p).with_context(|| format!("{}: cannot read", p.display()))?;
        Ok((model, format!("{} (fnv1a64 {:016x})", p.display(), vatcal_campaign::fnv1a64(&text))))
    };
    if let Some(p) = &args.nominal {
        return from_file(p).map(Some);
    }
    let named =
        calibrated.extra.get("provenance").and_then(|t| t.get("nominal_cell")).and_then(|v| v.as_str());
    if let Some(name) = named {
        let p = args.model.parent().unwrap_or(Path::new(".")).join(name);
        return from_file(&p)
            .with_context(|| format!("{}: [provenance] nominal_cell", args.model.display()))
            .map(Some);
    }
    if !model.is_meca500_on_guide() {
        return Ok(None);
    }
    let cell = CellFile::from_toml_str(BUILT_IN_NOMINAL, "built-in canonical cell")?;
    let model = Model::from_cell(&cell).context("built-in canonical cell")?;
    Ok(Some((
        model,
        format!(
            "built-in canonical cell fixtures/meca500-zaber.toml (fnv1a64 {:016x})",
            vatcal_campaign::fnv1a64(BUILT_IN_NOMINAL.as_bytes())
        ),
    )))
}

/// Compensates every requested pose and writes the chosen output.
pub fn run(args: Args) -> anyhow::Result<()> {
    let cell = CellFile::load(&args.model)?;
    let calibrated = super::model_of(&cell, &args.model)?;
    let model_bytes =
        std::fs::read(&args.model).with_context(|| format!("{}: cannot read", args.model.display()))?;
    let (nominal, nominal_desc) = nominal_or_calibrated(&args, &cell, &calibrated)?;
    let compensator = Compensator::new(&calibrated, &nominal)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.model.display()))?;
    check_emit_and_branch(&args, &compensator, &nominal)?;
    let given_joints: Vec<usize> = compensator.split().given_joints().collect();
    let rows = vatcal_io::read_pose_requests(&args.poses, &calibrated, &given_joints)?;
    let requests: Vec<PoseRequest> = rows
        .iter()
        .map(|r| PoseRequest {
            tcp: r.tcp,
            given: r.given,
            xyz_mm: r.xyz_mm,
            abc_deg: r.abc_deg,
            context: r.context,
        })
        .collect();
    let lines = RowLines { poses: &args.poses, rows: &rows };
    let near = args.near.as_deref().map(|values| near_joints(values, &calibrated)).transpose()?;
    let row_branches = row_branches(&rows, &compensator, &args.poses)?;
    let each = args.each || row_branches.iter().any(Option::is_some);
    let job = Job {
        args: &args,
        calibrated: &calibrated,
        compensator: &compensator,
        requests: &requests,
        lines,
        near,
    };
    let result = if each { job.solve_each(&row_branches)? } else { job.solve_path()? };

    let mut out = header(&args, &model_bytes, &nominal_desc, requests.len());
    if each {
        each_header(&mut out, &args, &row_branches, &result);
    } else if let Some(b) = result.branch {
        let _ = writeln!(out, "# IK branch: {b}");
    }
    if let Some(range) = &cell.training_range {
        job.warn_extrapolation(range, &result, &mut out);
    }
    for s in result.skipped() {
        let msg = format!("skipped {}:{}: {}", args.poses.display(), lines.line(s.row), s.error);
        eprintln!("{msg}");
        let _ = writeln!(out, "# {msg}");
    }
    match args.emit {
        Emit::Joints => job.write_joints(&result, &mut out),
        Emit::Poses => job.write_poses(&result, &given_joints, &mut out)?,
        Emit::Meca500 | Emit::Meca500Poses => job.write_meca500(&result, &given_joints, &mut out)?,
    }
    std::fs::write(&args.out, out).with_context(|| format!("{}: cannot write", args.out.display()))?;
    let solved = result.solved().count();
    eprintln!(
        "compensated {solved} of {} poses -> {}{}",
        requests.len(),
        args.out.display(),
        if solved < requests.len() {
            format!(" ({} skipped)", requests.len() - solved)
        } else {
            String::new()
        }
    );
    Ok(())
}

/// The nominal model and its description; without one, the calibrated model itself for
/// `--emit joints` (which needs none), else an error.
fn nominal_or_calibrated(
    args: &Args,
    cell: &CellFile,
    calibrated: &Model,
) -> anyhow::Result<(Model, String)> {
    Ok(match nominal_model(args, cell, calibrated)? {
        Some(n) => n,
        None if args.emit == Emit::Joints => (
            calibrated.clone(),
            "none (the calibrated file names no [provenance] nominal_cell; --emit joints needs none)".into(),
        ),
        None => anyhow::bail!(
            "{}: --emit {:?} needs the nominal (controller) model of this chain ({}): pass --nominal or \
             name it in the calibrated file's [provenance] nominal_cell",
            args.model.display(),
            args.emit,
            calibrated.describe_chain()
        ),
    })
}

/// Refuses a Meca500 program of a chain that is not a Meca500 arm, and a `--branch` of the
/// wrong kind for the chain.
fn check_emit_and_branch(args: &Args, compensator: &Compensator<'_>, nominal: &Model) -> anyhow::Result<()> {
    if matches!(args.emit, Emit::Meca500 | Emit::Meca500Poses) && compensator.meca500_arm().is_none() {
        anyhow::bail!(
            "--emit meca500 / meca500-poses: the nominal chain ({}) is not a Meca500 arm (its last six joints \
             do not move like the Meca500 controller's kinematics); use --emit joints or poses",
            nominal.describe_chain()
        );
    }
    if let Some(b) = args.branch
        && b.is_determinant_class() == compensator.is_closed_form()
    {
        anyhow::bail!(
            "--branch {}: {}",
            b.column(),
            if compensator.is_closed_form() {
                "the canonical cell's branches are 0..=7"
            } else {
                "on this chain the branch is the sign of det J: + or -"
            }
        );
    }
    Ok(())
}

/// The file lines of the pose rows, to name a row in messages.
#[derive(Clone, Copy)]
struct RowLines<'a> {
    poses: &'a Path,
    rows: &'a [vatcal_io::PoseRequestRow],
}

impl RowLines<'_> {
    /// The file line of row `row` (0 when out of range).
    fn line(&self, row: usize) -> u64 {
        self.rows.get(row).map_or(0, |r| r.line)
    }

    /// The error with the file and, when it names a row, the row's line.
    fn name(&self, e: CompensationError) -> anyhow::Error {
        match e.row() {
            Some(row) => anyhow::anyhow!("{}:{}: {e}", self.poses.display(), self.line(row)),
            None => anyhow::anyhow!("{}: {e}", self.poses.display()),
        }
    }
}

/// One `vatcal compensate` run: the models, the requests and their lines.
struct Job<'a> {
    args: &'a Args,
    calibrated: &'a Model,
    compensator: &'a Compensator<'a>,
    requests: &'a [PoseRequest],
    lines: RowLines<'a>,
    /// the `--near` configuration (internal units)
    near: Option<JointVector>,
}

impl Job<'_> {
    /// Every row solved on its own (`--each`, or a `branch` column with a value).
    fn solve_each(&self, row_branches: &[Option<Branch>]) -> anyhow::Result<PathResult> {
        let targets = self
            .requests
            .iter()
            .enumerate()
            .map(|(row, r)| r.tool_target(self.calibrated, row))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| self.lines.name(e))?;
        let opts = EachOptions {
            solve: SolveOptions::default(),
            skip_unreachable: self.args.skip_unreachable,
            branch: self.args.branch,
            prefer: self.near.map_or(Preference::Clearance, Preference::Near),
        };
        self.compensator.compensate_each(&targets, row_branches, &opts).map_err(|e| self.lines.name(e))
    }

    /// The rows solved as one path (joint-jump limit, one branch); with `--near` the first
    /// row's solution nearest it starts the path on its branch.
    fn solve_path(&self) -> anyhow::Result<PathResult> {
        let mut opts = PathOptions {
            solve: SolveOptions::default(),
            skip_unreachable: self.args.skip_unreachable,
            max_joint_step_deg: self.args.max_joint_step_deg,
            start: None,
            branch: self.args.branch,
        };
        if let (Some(near), Some(first)) = (self.near, self.requests.first()) {
            // the first row's solution nearest the configuration starts the path on its branch
            let target = first.tool_target(self.calibrated, 0).map_err(|e| self.lines.name(e))?;
            let each_opts = EachOptions {
                solve: opts.solve,
                skip_unreachable: false,
                branch: self.args.branch,
                prefer: Preference::Near(near),
            };
            let start: PathResult = self
                .compensator
                .compensate_each(&[target], &[], &each_opts)
                .map_err(|e| self.lines.name(e))?;
            if let Some((_, c)) = start.solved().next() {
                opts.start = Some(c.q);
                opts.branch = Some(c.branch);
            }
        }
        self.compensator.compensate_requests(self.requests, &opts).map_err(|e| self.lines.name(e))
    }

    /// Issue 29: warns of targets outside the joint range the calibration was fitted on (the
    /// first few by line, then a count), and records the count in the output's header.
    fn warn_extrapolation(
        &self,
        range: &training_range::TrainingRange,
        result: &PathResult,
        out: &mut String,
    ) {
        let (args, kinds) = (self.args, self.calibrated.joint_kinds());
        let mut outside = 0;
        for (row, c) in result.solved() {
            let joints = range.excursions(kinds, &c.q);
            if joints.is_empty() {
                continue;
            }
            outside += 1;
            if outside <= training_range::MAX_WARNINGS {
                eprintln!(
                    "warning: {}:{}: the target leaves the training range of {}: {}",
                    args.poses.display(),
                    self.lines.line(row),
                    args.model.display(),
                    training_range::list(&joints)
                );
            }
        }
        if outside > 0 {
            let msg = format!(
                "extrapolation: {outside} of {} targets leave the joint range the calibration was fitted on \
                 ({} rows; tolerance max(1 % of the range, 0.5 deg / 0.5 mm)): the model extrapolates there",
                result.solved().count(),
                range.rows
            );
            if outside > training_range::MAX_WARNINGS {
                eprintln!("warning: ... and {} more", outside - training_range::MAX_WARNINGS);
            }
            eprintln!("{msg}");
            let _ = writeln!(out, "# {msg}");
        }
    }

    /// `--emit joints`: `line,tcp,q1..qN,branch,residual_mm,residual_deg`.
    fn write_joints(&self, result: &PathResult, out: &mut String) {
        let kinds = self.calibrated.joint_kinds();
        out.push_str("line,tcp,");
        out.push_str(&vatcal_io::joint_columns(kinds.len()).join(","));
        out.push_str(",branch,residual_mm,residual_deg\n");
        for (row, c) in result.solved() {
            let q = if self.compensator.is_closed_form() {
                c.q.to_mm_deg().to_vec()
            } else {
                c.q.to_file_units(kinds)
            };
            let _ = write!(out, "{},{}", self.lines.line(row), self.requests[row].tcp);
            for v in q {
                let _ = write!(out, ",{v}");
            }
            let _ = writeln!(
                out,
                ",{},{:e},{:e}",
                c.branch.column(),
                c.position_residual_mm,
                c.rotation_residual_rad.to_degrees()
            );
        }
    }

    /// `--emit poses`: the corrected poses in the input format, with the context columns the
    /// requests have.
    fn write_poses(
        &self,
        result: &PathResult,
        given_joints: &[usize],
        out: &mut String,
    ) -> anyhow::Result<()> {
        let requests = self.requests;
        let time = requests.iter().any(|r| r.context.time_s.is_some());
        let temp = requests.iter().any(|r| r.context.temperature_c.is_some());
        let dir = requests.iter().any(|r| r.context.dir.is_some());
        out.push_str("line,tcp");
        for j in given_joints {
            let _ = write!(out, ",q{j}");
        }
        out.push_str(",x,y,z,alpha,beta,gamma");
        if time {
            out.push_str(",time_s");
        }
        if temp {
            out.push_str(",temperature_c");
        }
        let dir_cols = vatcal_io::dir_columns(self.calibrated.joint_kinds());
        if dir {
            for (_, col) in &dir_cols {
                let _ = write!(out, ",{col}");
            }
        }
        out.push('\n');
        for (row, c) in result.solved() {
            let r = &requests[row];
            let p = self
                .compensator
                .corrected_pose(&c.q, r.tcp, r.context)
                .map_err(|e| self.lines.name(e))?
                .world;
            let _ = write!(out, "{},{}", self.lines.line(row), p.tcp);
            for j in given_joints {
                let _ = write!(out, ",{}", p.given.get(*j));
            }
            let _ = write!(
                out,
                ",{},{},{},{},{},{}",
                p.xyz_mm[0], p.xyz_mm[1], p.xyz_mm[2], p.abc_deg[0], p.abc_deg[1], p.abc_deg[2]
            );
            let opt = |v: Option<f64>| v.map(|x| x.to_string()).unwrap_or_default();
            if time {
                let _ = write!(out, ",{}", opt(r.context.time_s));
            }
            if temp {
                let _ = write!(out, ",{}", opt(r.context.temperature_c));
            }
            if dir {
                for (joint, _) in &dir_cols {
                    match r.context.dir {
                        Some(d) => {
                            let _ = write!(out, ",{}", d[joint - 1]);
                        }
                        None => out.push(','),
                    }
                }
            }
            out.push('\n');
        }
        Ok(())
    }

    /// `--emit meca500` / `meca500-poses`: a Meca500 program of `MoveJoints` / `MovePose`
    /// lines, the guide positions as `# guide` comments.
    fn write_meca500(
        &self,
        result: &PathResult,
        given_joints: &[usize],
        out: &mut String,
    ) -> anyhow::Result<()> {
        if given_joints.is_empty() {
            out.push_str("# Lines starting with '#' are not robot commands.\n");
        } else {
            out.push_str(
                "# Lines starting with '#' are not robot commands. Before each motion command, move the \
                 guide to the\n# position of the '# guide q1_mm=<mm>' line above it (the Meca500 does not \
                 drive the guide).\n",
            );
        }
        if self.args.emit == Emit::Meca500Poses {
            out.push_str(
                "# MovePose: flange pose in the robot base frame by the nominal controller kinematics; \
                 the controller\n# must pick the same posture (IK branch above) - MoveJoints \
                 (--emit meca500) avoids that question.\n",
            );
            let zero = [0.0; 6];
            let _ = writeln!(out, "{}", MecaCommand::SetWrf(zero).to_text());
            let _ = writeln!(out, "{}", MecaCommand::SetTrf(zero).to_text());
        }
        for (row, c) in result.solved() {
            let r = &self.requests[row];
            let corrected =
                self.compensator.corrected_pose(&c.q, r.tcp, r.context).map_err(|e| self.lines.name(e))?;
            for j in given_joints {
                let _ = writeln!(
                    out,
                    "# guide q{j}_mm={} (line {})",
                    format_number(c.q.get(*j)),
                    self.lines.line(row)
                );
            }
            let not_meca = || anyhow::anyhow!("the nominal chain is not a Meca500 arm");
            let cmd = match self.args.emit {
                Emit::Meca500 => {
                    MecaCommand::MoveJoints(corrected.controller_joints_deg.ok_or_else(not_meca)?)
                }
                _ => MecaCommand::MovePose(corrected.controller_pose.ok_or_else(not_meca)?),
            };
            let _ = writeln!(out, "{}", cmd.to_text());
        }
        Ok(())
    }
}

/// The output's first comment lines: the request file, the calibration and the nominal model.
fn header(args: &Args, model_bytes: &[u8], nominal_desc: &str, poses: usize) -> String {
    let mut header = String::new();
    let _ = writeln!(header, "# vatcal compensate: {poses} poses from {}", args.poses.display());
    let _ = writeln!(
        header,
        "# calibration: {} (fnv1a64 {:016x})",
        args.model.display(),
        vatcal_campaign::fnv1a64(model_bytes)
    );
    let _ = writeln!(header, "# nominal (controller) model: {nominal_desc}");
    header
}

/// The header lines of independent poses: how each row was solved and its branch.
fn each_header(out: &mut String, args: &Args, row_branches: &[Option<Branch>], result: &PathResult) {
    let how = if args.near.is_some() {
        "the solution nearest --near"
    } else {
        "the solution farthest from the joint limits"
    };
    let named = if row_branches.iter().any(Option::is_some) {
        " on the branch its `branch` column names"
    } else {
        ""
    };
    let _ = writeln!(out, "# independent poses (--each): every row solved on its own{named}, {how}");
    match result.branch {
        Some(b) => {
            let _ = writeln!(out, "# IK branch: {b} (every row)");
        }
        None => {
            let _ = writeln!(out, "# IK branch: per row (the `branch` column)");
        }
    }
}
