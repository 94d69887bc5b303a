//! Pose requests of `vatcal compensate`: `tcp`, the given joints' `q{i}`,
//! `x,y,z,alpha,beta,gamma` and the optional context and `branch` columns.

use std::path::Path;

use vatcal_core::{JointVector, MeasurementContext};
use vatcal_kinematics::Model;

use crate::error::IoError;
use crate::table::Table;

/// One row of a pose-request file of any chain (`vatcal compensate`): TCP `tcp` must reach the
/// world point `x,y,z` \[mm\] with the chain's last frame at Mecademic Euler angles
/// `alpha,beta,gamma` \[deg\] (intrinsic X-Y-Z), the given joints (e.g. the guide `q1`) at
/// their columns' values.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseRequestRow {
    /// 1-based line number in the file
    pub line: u64,
    /// TCP id
    pub tcp: u32,
    /// one value per joint of the model (internal units): the given joints' columns, 0 for
    /// the joints the pose determines
    pub given: JointVector,
    /// TCP point in the world \[mm\]
    pub xyz_mm: [f64; 3],
    /// orientation of the last frame, intrinsic X-Y-Z Euler angles \[deg\]
    pub abc_deg: [f64; 3],
    /// optional `time_s`, `temperature_c`, `dir{i}` of the model's revolute joints
    pub context: MeasurementContext,
    /// the optional `branch` column (trimmed; `None` when absent or empty): the IK branch the
    /// row asks for, as `vatcal compensate` writes it (`0..7` on the canonical cell, `+`/`-`
    /// on another chain) — the caller parses it
    pub branch: Option<String>,
}

/// Reads pose requests of any chain: the columns `tcp`, `q{i}` for each joint `i` of `given`
/// (1-based; the joints the request fixes, e.g. `[1]` for the canonical cell's guide, none for
/// a six-joint arm), `x,y,z,alpha,beta,gamma`, the optional context columns `time_s`,
/// `temperature_c`, `dir{i}` of the model's revolute joints, and the optional `branch` column
/// (kept as text). TCP ids are checked against the
/// model, the given joints against their limits; a `q` column of a joint that is not given is
/// an error (the pose determines that joint); context columns the model's effects need must be
/// present ([`IoError::ModelNeedsColumn`]).
///
/// # Examples
/// ```
/// use vatcal_core::CellFile;
/// use vatcal_io::read_pose_requests;
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// // the canonical cell: the request gives the guide `q1` (mm), the pose determines q2..q7
/// let rows = read_pose_requests(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/compensate-poses.csv"), &model, &[1])?;
/// assert!(!rows.is_empty() && rows.iter().all(|r| model.tcp(r.tcp).is_some()));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`read_joint_rows`](crate::read_joint_rows) (a given joint outside its limits is an
/// [`IoError::Row`] naming the column), with [`IoError::UnsupportedChain`] for a `q` column that is not one of the
/// given joints'.
pub fn read_pose_requests(
    path: impl AsRef<Path>,
    model: &Model,
    given: &[usize],
) -> Result<Vec<PoseRequestRow>, IoError> {
    let path = path.as_ref();
    let n = model.joint_count();
    let given_cols: Vec<String> = given.iter().map(|i| format!("q{i}")).collect();
    let mut required: Vec<&str> = vec!["tcp"];
    required.extend(given_cols.iter().map(String::as_str));
    required.extend(["x", "y", "z", "alpha", "beta", "gamma"]);
    let t = Table::read(path, model, &required)?;
    let stray: Vec<&str> = t
        .headers
        .iter()
        .filter(|h| h.strip_prefix('q').and_then(|k| k.parse::<usize>().ok()).is_some())
        .filter(|h| !given_cols.iter().any(|g| g == h))
        .collect();
    if !stray.is_empty() {
        return Err(IoError::UnsupportedChain {
            path: path.into(),
            reason: format!(
                "column(s) {} in the header: a pose request on this chain ({}) gives the joint columns {} \
                 and the pose determines the others",
                stray.join(","),
                model.describe_chain(),
                if given_cols.is_empty() { "none".to_string() } else { given_cols.join(",") }
            ),
        });
    }
    t.check_model_columns(model)?;
    let tcps = model.tcp_ids();
    let kinds = model.joint_kinds();
    t.convert(|line, rec| {
        let tcp = t.id(line, rec, "tcp", &tcps)?;
        let mut q = JointVector::zeros(n);
        for (i, col) in given.iter().zip(&given_cols) {
            let Some(kind) = kinds.get(i.wrapping_sub(1)) else {
                return Err(t.err(line, col, format!("the model has {n} joints")));
            };
            let v = t.float(line, rec, col)?;
            let internal = kind.from_file_unit(v);
            if let Some((lo, hi)) = model.joint_limit(*i)
                && !(lo..=hi).contains(&internal)
            {
                let unit = kind.file_unit();
                let (lo, hi) = (kind.to_file_unit(lo), kind.to_file_unit(hi));
                return Err(t.err(
                    line,
                    col,
                    format!("{v} {unit} is outside the joint limits [{lo}, {hi}] {unit}"),
                ));
            }
            q.set(*i, internal);
        }
        let f = |c: &str| t.float(line, rec, c);
        Ok(PoseRequestRow {
            line,
            tcp,
            given: q,
            xyz_mm: [f("x")?, f("y")?, f("z")?],
            abc_deg: [f("alpha")?, f("beta")?, f("gamma")?],
            context: t.context(line, rec)?,
            branch: t.field(rec, "branch").map(str::trim).filter(|b| !b.is_empty()).map(String::from),
        })
    })
}
