//! "Where" the current model disagrees with the data: the residuals of a fit against every
//! variable that could drive a missing effect (each joint, the gravity torques, TCP,
//! calibration position, time, temperature, approach direction, measurement order).
//!
//! For each variable the residuals are regressed on a few functions of the variable (angles:
//! `sin q, cos q, sin 2q, cos 2q`; other continuous variables: a centred quadratic; categories:
//! one indicator per level), with an intercept. Variables tied to a revolute joint j (q_j, τ_j,
//! dir_j) regress the residual expressed as an angle error of joint j; the others regress the
//! x, y, z components. The fraction of the residual sum of squares this explains and its F-test
//! p-value say how strongly the residuals depend on that variable; binned residual norms show
//! how.

use nalgebra::Vector3;
use serde::Serialize;
use vatcal_core::{JointKind, MAX_JOINTS, Measurement, ParamId, Target, deg_to_rad};
use vatcal_kinematics::Model;

use crate::DiscoveryError;
use crate::distributions::f_ln_sf;
use crate::linear::ColumnSpace;

/// A variable the residuals can be plotted against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum Driver {
    /// joint 1..=N (mm for prismatic, degrees for revolute joints; canonical cell: q1 in mm,
    /// the others in degrees)
    Joint(u8),
    /// gravity torque of revolute joint j \[N·m\] (on the fitted model)
    Torque(u8),
    /// the TCP id
    Tcp,
    /// the calibration position id (probe measurements; tracker measurements count as 0)
    Position,
    /// `time_s`
    Time,
    /// `temperature_c`
    Temperature,
    /// sign of the last motion of revolute joint j
    Direction(u8),
    /// index of the measurement in the file (a proxy for time when no time stamps exist)
    Order,
}

/// How a driver's values are treated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum DriverKind {
    /// an angle in degrees: periodic basis
    Angle,
    /// a continuous quantity: quadratic basis
    Continuous,
    /// a label: one indicator per level
    Categorical,
}

use vatcal_core::MECA500_ON_GUIDE_KINDS as CANONICAL;

/// True when joint `j` (1-based) is prismatic in `kinds`.
fn prismatic(kinds: &[JointKind], j: u8) -> bool {
    kinds.get((j as usize).wrapping_sub(1)) == Some(&JointKind::Prismatic)
}

impl Driver {
    /// Axis label with unit on the canonical cell, e.g. `q4 [deg]`, `tau3 [N*m]`.
    pub fn label(&self) -> String {
        self.label_for(&CANONICAL)
    }

    /// Axis label with unit on a chain with joints `kinds`.
    pub fn label_for(&self, kinds: &[JointKind]) -> String {
        match self {
            Driver::Joint(1) if prismatic(kinds, 1) && kinds == CANONICAL => "q1 (guide) [mm]".to_string(),
            Driver::Joint(j) if prismatic(kinds, *j) => format!("q{j} [mm]"),
            Driver::Joint(j) => format!("q{j} [deg]"),
            Driver::Torque(j) => format!("tau{j} [N*m]"),
            Driver::Tcp => "TCP id".to_string(),
            Driver::Position => "calibration position id".to_string(),
            Driver::Time => "time [s]".to_string(),
            Driver::Temperature => "temperature [degC]".to_string(),
            Driver::Direction(j) => format!("dir{j} (sign of last motion)"),
            Driver::Order => "measurement order".to_string(),
        }
    }

    /// How the values are treated on the canonical cell.
    pub fn kind(&self) -> DriverKind {
        self.kind_for(&CANONICAL)
    }

    /// How the values are treated on a chain with joints `kinds`.
    pub fn kind_for(&self, kinds: &[JointKind]) -> DriverKind {
        match self {
            Driver::Joint(j) if !prismatic(kinds, *j) => DriverKind::Angle,
            Driver::Tcp | Driver::Position | Driver::Direction(_) => DriverKind::Categorical,
            _ => DriverKind::Continuous,
        }
    }

    /// The value of this variable for measurement `index` (None when the data lacks it), in
    /// the units of [`Driver::label_for`]. `pose` holds the joint kinds and the gravity torques
    /// of the measurements.
    pub fn value(&self, index: usize, m: &Measurement, pose: &PoseData) -> Option<f64> {
        let torques = pose.torques.get(index)?;
        match *self {
            Driver::Joint(j) if prismatic(pose.kinds(), j) => m.q.as_slice().get(j as usize - 1).copied(),
            Driver::Joint(j) => m.q.as_slice().get((j as usize).wrapping_sub(1)).map(|v| v.to_degrees()),
            Driver::Torque(j) => torques.get((j as usize).wrapping_sub(1)).copied(),
            Driver::Tcp => Some(f64::from(m.tcp)),
            Driver::Position => Some(match m.target {
                Target::Probe { position } => f64::from(position),
                Target::Tracker { .. } | Target::Orientation { .. } | Target::Plane { .. } => 0.0,
            }),
            Driver::Time => m.context.time_s,
            Driver::Temperature => m.context.temperature_c,
            Driver::Direction(j) => m.context.dir.map(|_| f64::from(m.context.dir_of(j))),
            Driver::Order => Some(index as f64),
        }
    }

    /// Every driver of the canonical cell, in a fixed order.
    pub fn all() -> Vec<Driver> {
        Self::all_for(&CANONICAL)
    }

    /// Every driver of a chain with joints `kinds`, in a fixed order: every joint, the torques
    /// and directions of the revolute joints, TCP, position, time, temperature, order.
    pub fn all_for(kinds: &[JointKind]) -> Vec<Driver> {
        let n = kinds.len().min(MAX_JOINTS) as u8;
        let revolute: Vec<u8> = (1..=n).filter(|j| !prismatic(kinds, *j)).collect();
        let mut v: Vec<Driver> = (1..=n).map(Driver::Joint).collect();
        v.extend(revolute.iter().map(|j| Driver::Torque(*j)));
        v.extend([Driver::Tcp, Driver::Position, Driver::Time, Driver::Temperature]);
        v.extend(revolute.iter().map(|j| Driver::Direction(*j)));
        v.push(Driver::Order);
        v
    }
}

/// Residuals of the measurements falling into one range (or level) of a driver.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Bin {
    /// lowest driver value in the bin
    pub lo: f64,
    /// highest driver value in the bin
    pub hi: f64,
    /// number of measurements
    pub count: usize,
    /// mean residual norm \[mm\]
    pub mean_mm: f64,
    /// RMS residual norm \[mm\]
    pub rms_mm: f64,
}

/// How strongly the residuals depend on one driver.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DriverSummary {
    /// the variable
    pub driver: Driver,
    /// its label with unit
    pub label: String,
    /// fraction of the residual sum of squares explained by functions of the variable
    pub explained_fraction: f64,
    /// fraction expected by chance alone (number of regressors / number of residuals)
    pub chance_fraction: f64,
    /// `ln p` of the regression F-test (very negative = the residuals clearly depend on it)
    pub ln_p_value: f64,
    /// residual norms in equal-count bins (continuous) or per level (categorical)
    pub bins: Vec<Bin>,
}

impl DriverSummary {
    /// One line for people, e.g. `q4 [deg]: explains 61.2 % of the residual (chance 2.2 %)`.
    pub fn sentence(&self) -> String {
        format!(
            "{}: explains {:.1} % of the residual sum of squares (chance {:.1} %, log10 p = {:.1})",
            self.label,
            100.0 * self.explained_fraction,
            100.0 * self.chance_fraction,
            self.ln_p_value / std::f64::consts::LN_10
        )
    }
}

const BINS: usize = 6;

/// Regressors (without intercept) for the values `v` of a driver of kind `kind`.
fn regressors(kind: DriverKind, v: &[f64]) -> Vec<Vec<f64>> {
    match kind {
        DriverKind::Angle => {
            let r: Vec<f64> = v.iter().map(|x| deg_to_rad(*x)).collect();
            vec![
                r.iter().map(|x| x.sin()).collect(),
                r.iter().map(|x| x.cos()).collect(),
                r.iter().map(|x| (2.0 * x).sin()).collect(),
                r.iter().map(|x| (2.0 * x).cos()).collect(),
            ]
        }
        DriverKind::Continuous => {
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
            if sd <= 0.0 {
                return Vec::new();
            }
            let t: Vec<f64> = v.iter().map(|x| (x - mean) / sd).collect();
            vec![t.clone(), t.iter().map(|x| x * x - 1.0).collect()]
        }
        DriverKind::Categorical => {
            let levels = levels(v);
            levels.iter().skip(1).map(|l| v.iter().map(|x| f64::from(u8::from(x == l))).collect()).collect()
        }
    }
}

fn levels(v: &[f64]) -> Vec<f64> {
    let mut l: Vec<f64> = v.to_vec();
    l.sort_by(f64::total_cmp);
    l.dedup();
    l
}

fn bin_of(members: &[(f64, f64)]) -> Bin {
    let count = members.len();
    let n = count.max(1) as f64;
    Bin {
        lo: members.iter().map(|m| m.0).fold(f64::INFINITY, f64::min),
        hi: members.iter().map(|m| m.0).fold(f64::NEG_INFINITY, f64::max),
        count,
        mean_mm: members.iter().map(|m| m.1).sum::<f64>() / n,
        rms_mm: (members.iter().map(|m| m.1 * m.1).sum::<f64>() / n).sqrt(),
    }
}

fn bins(kind: DriverKind, v: &[f64], norms: &[f64]) -> Vec<Bin> {
    let mut pairs: Vec<(f64, f64)> = v.iter().copied().zip(norms.iter().copied()).collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    match kind {
        DriverKind::Categorical => levels(v)
            .iter()
            .map(|l| bin_of(&pairs.iter().copied().filter(|p| p.0 == *l).collect::<Vec<_>>()))
            .collect(),
        _ => {
            let n = pairs.len();
            let b = BINS.min(n);
            (0..b).map(|k| bin_of(&pairs[k * n / b..(k + 1) * n / b])).collect()
        }
    }
}

/// Per-measurement quantities the drivers need besides the measurement itself.
#[derive(Debug, Clone, Default)]
pub struct PoseData {
    /// gravity torques \[N·m\], `[i - 1]` for joint i
    pub torques: Vec<[f64; MAX_JOINTS]>,
    /// `∂p/∂θ_j` of every joint, `[j - 1]` for revolute joint j (zero for prismatic joints)
    /// \[mm/rad\] (the direction an angle error of joint j moves the TCP), when known
    pub joint_directions: Option<Vec<[Vector3<f64>; MAX_JOINTS]>>,
    /// joint kinds of the chain (empty = the canonical Meca500-on-guide cell)
    pub joint_kinds: Vec<JointKind>,
}

impl PoseData {
    /// Torques and joint directions of every measurement under `model`.
    pub fn of(model: &Model, measurements: &[Measurement]) -> Result<Self, DiscoveryError> {
        let revolute: Vec<usize> = (1..=model.joint_count()).filter(|j| model.is_revolute(*j)).collect();
        let joints: Vec<ParamId> = revolute.iter().map(|j| ParamId::ThetaOffset(*j as u8)).collect();
        let mut buf = vec![0.0; 3 * joints.len()];
        let mut dirs = Vec::with_capacity(measurements.len());
        for (index, m) in measurements.iter().enumerate() {
            model
                .jacobian_into(&m.q, &m.context, m.tcp, &joints, &mut buf)
                .map_err(|e| DiscoveryError::Measurement { index, source: e })?;
            let mut d = [Vector3::zeros(); MAX_JOINTS];
            for (k, j) in revolute.iter().enumerate() {
                d[j - 1] = Vector3::new(buf[3 * k], buf[3 * k + 1], buf[3 * k + 2]);
            }
            dirs.push(d);
        }
        Ok(Self {
            torques: measurements.iter().map(|m| model.gravity_torques(&m.q)).collect(),
            joint_directions: Some(dirs),
            joint_kinds: model.joint_kinds().to_vec(),
        })
    }

    /// Torques only (no joint directions: every driver uses the world residual components), on
    /// the canonical cell.
    pub fn torques_only(torques: Vec<[f64; MAX_JOINTS]>) -> Self {
        Self { torques, joint_directions: None, joint_kinds: Vec::new() }
    }

    /// The joint kinds (the canonical cell's when none were recorded).
    pub fn kinds(&self) -> &[JointKind] {
        if self.joint_kinds.is_empty() { &CANONICAL } else { &self.joint_kinds }
    }
}

/// The revolute joint whose angle error a driver is about (q_j, tau_j, dir_j).
fn joint_of(driver: Driver, kinds: &[JointKind]) -> Option<usize> {
    match driver {
        Driver::Joint(j) | Driver::Torque(j) | Driver::Direction(j) if !prismatic(kinds, j) && j >= 1 => {
            Some(j as usize)
        }
        _ => None,
    }
}

/// Least-squares regression of `response` on `design`: (explained SS, unexplained SS, rank).
fn regress(design: faer::Mat<f64>, response: &[f64]) -> Result<(f64, f64, usize), DiscoveryError> {
    let space = ColumnSpace::of(design.as_ref())?;
    let total: f64 = response.iter().map(|x| x * x).sum();
    let left: f64 = space.project_out_vec(response).iter().map(|x| x * x).sum();
    Ok(((total - left).max(0.0), left, space.rank()))
}

/// Summarises how the residuals depend on `driver`; `None` if the data lacks the variable or it
/// does not vary.
///
/// For drivers tied to a revolute joint j (q_j, tau_j, dir_j) and known joint directions, the
/// residual is first expressed as an equivalent angle error of joint j (its component along
/// `∂p/∂θ_j`), which is then regressed on functions of the driver — weighted by the lever arm,
/// so this is the fraction of the residual an angle error of joint j following the driver
/// would remove. Otherwise the x, y, z residual components are each regressed on the
/// functions (with an intercept).
pub fn summarize_driver(
    driver: Driver,
    measurements: &[Measurement],
    residuals: &[Vector3<f64>],
    pose: &PoseData,
) -> Result<Option<DriverSummary>, DiscoveryError> {
    let values: Option<Vec<f64>> =
        measurements.iter().enumerate().map(|(i, m)| driver.value(i, m, pose)).collect();
    let Some(v) = values else { return Ok(None) };
    let kind = driver.kind_for(pose.kinds());
    let regs = regressors(kind, &v);
    let n = v.len();
    if regs.is_empty() || n <= regs.len() + 2 {
        return Ok(None);
    }
    let b = regs.len() + 1;
    let basis = |k: usize, j: usize| if j == 0 { 1.0 } else { regs[j - 1][k] };
    let rss: f64 = residuals.iter().map(|x| x.norm_squared()).sum();
    let (explained, left, q, rows) = match (joint_of(driver, pose.kinds()), pose.joint_directions.as_ref()) {
        (Some(j), Some(dirs)) => {
            let lever: Vec<f64> = dirs.iter().map(|d| d[j - 1].norm()).collect();
            let response: Vec<f64> = residuals
                .iter()
                .zip(dirs)
                .zip(&lever)
                .map(|((r, d), l)| if *l > 0.0 { r.dot(&d[j - 1]) / l } else { 0.0 })
                .collect();
            let design = faer::Mat::from_fn(n, b, |k, c| lever[k] * basis(k, c));
            let (e, l, q) = regress(design, &response)?;
            (e, l, q, n)
        }
        _ => {
            // block-diagonal design: the same regressors (with intercept) for x, y and z
            let design = faer::Mat::from_fn(3 * n, 3 * b, |row, col| {
                if col / b == row % 3 { basis(row / 3, col % b) } else { 0.0 }
            });
            let r: Vec<f64> = residuals.iter().flat_map(|x| [x.x, x.y, x.z]).collect();
            let (e, l, q) = regress(design, &r)?;
            (e, l, q, 3 * n)
        }
    };
    let dof2 = rows.saturating_sub(q);
    let ln_p_value = if q == 0 || dof2 == 0 || left <= 0.0 {
        0.0
    } else {
        f_ln_sf((explained / q as f64) / (left / dof2 as f64), q, dof2)
    };
    let norms: Vec<f64> = residuals.iter().map(|x| x.norm()).collect();
    Ok(Some(DriverSummary {
        driver,
        label: driver.label_for(pose.kinds()),
        explained_fraction: if rss > 0.0 { (explained / rss).clamp(0.0, 1.0) } else { 0.0 },
        chance_fraction: q as f64 / (3 * n) as f64,
        ln_p_value,
        bins: bins(kind, &v, &norms),
    }))
}

/// A gravity torque below this on every measurement is round-off (no load on the joint) \[N·m\].
const NO_LOAD_N_M: f64 = 1e-9;

/// Summaries of every available driver, most significant first (torques of joints that carry
/// no gravity load on any measurement are left out).
pub fn locate(
    model: &Model,
    measurements: &[Measurement],
    residuals: &[Vector3<f64>],
) -> Result<Vec<DriverSummary>, DiscoveryError> {
    let pose = PoseData::of(model, measurements)?;
    let mut out = Vec::new();
    for d in Driver::all_for(model.joint_kinds()) {
        // a joint that never carries a gravity load (a vertical first axis) has a torque of
        // round-off size: it drives nothing, although its values correlate with the pose
        if let Driver::Torque(j) = d
            && pose
                .torques
                .iter()
                .all(|t| t.get(usize::from(j).wrapping_sub(1)).is_none_or(|v| v.abs() < NO_LOAD_N_M))
        {
            continue;
        }
        if let Some(s) = summarize_driver(d, measurements, residuals, &pose)? {
            out.push(s);
        }
    }
    out.sort_by(|a, b| a.ln_p_value.total_cmp(&b.ln_p_value));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};
    use vatcal_core::JointVector;

    #[test]
    fn a_residual_that_oscillates_with_q4_is_located_on_q4() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut ms = Vec::new();
        let mut res = Vec::new();
        for i in 0..150 {
            let mut q = [0.0; 7];
            q[0] = rng.random_range(0.0..300.0);
            for v in q.iter_mut().skip(1) {
                *v = rng.random_range(-2.5..2.5);
            }
            let m = Measurement::probe(1 + (i % 3) as u32, 1 + (i % 3) as u32, JointVector::new(q));
            let noise = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ) * 0.002;
            res.push(Vector3::new(0.02 * q[3].sin(), -0.01 * q[3].sin(), 0.0) + noise);
            ms.push(m);
        }
        let pose = PoseData::torques_only(vec![[0.0; MAX_JOINTS]; ms.len()]);
        let all: Vec<DriverSummary> = Driver::all()
            .into_iter()
            .filter_map(|d| summarize_driver(d, &ms, &res, &pose).expect("ok"))
            .collect();
        let best = all.iter().min_by(|a, b| a.ln_p_value.total_cmp(&b.ln_p_value)).expect("some");
        assert_eq!(best.driver, Driver::Joint(4), "{}", best.sentence());
        assert!(best.explained_fraction > 0.8);
        // variables that are not in the data are left out
        assert!(!all.iter().any(|s| s.driver == Driver::Time || s.driver == Driver::Direction(3)));
        // pure noise on an unrelated joint is not significant
        let q2 = all.iter().find(|s| s.driver == Driver::Joint(2)).expect("q2");
        assert!(q2.ln_p_value > (1e-4f64).ln(), "{}", q2.sentence());
        assert_eq!(q2.bins.len(), BINS);
        assert_eq!(q2.bins.iter().map(|b| b.count).sum::<usize>(), 150);
    }

    #[test]
    fn the_torque_of_a_vertical_first_joint_is_no_driver() {
        let cell =
            vatcal_core::CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))
                .expect("fixture");
        let model = Model::from_cell(&cell).expect("model");
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (mut ms, mut res) = (Vec::new(), Vec::new());
        for _ in 0..60 {
            let q: Vec<f64> = (0..6).map(|_| rng.random_range(-2.5..2.5)).collect();
            let q = JointVector::from_slice(&q).expect("q");
            ms.push(Measurement::tracker(1, q, Vector3::zeros()));
            res.push(Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 0.0) * 0.002);
        }
        let all = locate(&model, &ms, &res).expect("locate");
        assert!(!all.iter().any(|s| s.driver == Driver::Torque(1)), "tau1 (round-off) offered as a driver");
        assert!(all.iter().any(|s| s.driver == Driver::Torque(2)));
    }
}
