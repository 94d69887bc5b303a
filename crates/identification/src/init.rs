//! Closed-form initialisation of the quantities a nominal model does not know: where the
//! instrument's world frame is (the base pose), which point of the hand the instrument sees
//! (the measured TCPs) and where unknown fixed points are.
//!
//! Levenberg–Marquardt converges from a nominal model that is a few mm and a few degrees off; a
//! laser tracker or motion-capture frame metres away and rotated arbitrarily, or a marker 80 mm
//! from the nominal TCP, is far outside that basin. [`initialise`] alternates two linear
//! problems, each solved exactly:
//!
//! 1. **Rigid registration** (Kabsch / Umeyama without scale, SVD of the 3 × 3 cross-covariance,
//!    reflection excluded): the rotation and translation that best map the model's predicted
//!    points onto the observed ones (tracker points, known calibration positions). It is
//!    composed with the base pose: `H_0^W ← T · H_0^W`, which moves every prediction rigidly.
//!    It is a change of world frame, not a tilt of the robot, so the gravity vector (given in
//!    the world frame) turns with it: the gravity torques of the compliances stay the same.
//! 2. **Tool point and fixed points** by linear least squares given the registration: with
//!    `T_k = (R_k, o_k)` the tool frame of row k in the world, a tracker row gives
//!    `R_k t = y_k − o_k`, a probe row at a known position `R_k t = P + offset − o_k`, and a probe
//!    row at an unknown fixed point j `R_k t − p_j = −o_k` — one linear system in the TCP
//!    coordinates `t` and the free points `p_j` (the pivot calibration of a ball in a socket).
//!    With the TCPs known, a free point is the mean of its predicted positions.
//!
//! 3. **Contact planes** the fit identifies: the least-squares plane through their rows'
//!    predicted contacts (`planes::plane_of_rows`).
//!
//! The steps repeat until the RMS residual stops falling (at most
//! [`InitOptions::max_rounds`]); the fit then starts from the result. The registration needs
//! at least three non-collinear observed points; it is skipped when every probe row is at an
//! unknown fixed point (the points absorb the base pose).

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use vatcal_core::{BaseParam, Measurement, ParamId, Target};
use vatcal_kinematics::Model;

use crate::IdentifyError;

/// What [`initialise`] may change.
#[derive(Debug, Clone, PartialEq)]
pub struct InitOptions {
    /// register the base pose rigidly onto the observed points (step 1)
    pub register_base: bool,
    /// solve the coordinates of these TCPs (step 2)
    pub tcps: Vec<u32>,
    /// solve the coordinates of these calibration positions (unknown fixed points, step 2)
    pub free_positions: Vec<u32>,
    /// re-estimate these contact planes through the predicted contacts (step 3)
    pub free_planes: Vec<u32>,
    /// at most this many rounds of steps 1 and 2 (default 30)
    pub max_rounds: usize,
}

impl Default for InitOptions {
    fn default() -> Self {
        Self {
            register_base: true,
            tcps: Vec::new(),
            free_positions: Vec::new(),
            free_planes: Vec::new(),
            max_rounds: 30,
        }
    }
}

impl InitOptions {
    /// What the parameter set frees: the base pose is registered when any base parameter is
    /// identified, the TCPs and positions whose coordinates are identified are solved.
    pub fn for_params(params: &vatcal_core::ParamSet) -> Self {
        let mut o =
            Self { register_base: params.iter().any(|p| matches!(p, ParamId::Base(_))), ..Self::default() };
        for p in params.iter() {
            match *p {
                ParamId::Tcp { id, .. } if !o.tcps.contains(&id) => o.tcps.push(id),
                ParamId::Position { id, .. } if !o.free_positions.contains(&id) => o.free_positions.push(id),
                ParamId::Plane { id, .. } if !o.free_planes.contains(&id) => o.free_planes.push(id),
                _ => {}
            }
        }
        o
    }
}

/// The model [`initialise`] produced and what it did.
#[derive(Debug, Clone)]
pub struct Initialisation {
    /// the initialised model (the start of the fit)
    pub model: Model,
    /// RMS of the residual norms before \[mm\]
    pub rms_before_mm: f64,
    /// RMS of the residual norms after \[mm\]
    pub rms_after_mm: f64,
    /// rounds of registration + linear solve that were run
    pub rounds: usize,
    /// whether the base pose was registered
    pub registered: bool,
}

/// Runs the initialisation described in the module docs on `start`.
///
/// # Errors
/// [`IdentifyError::Measurement`] for a row the model cannot evaluate (unknown TCP or position);
/// [`IdentifyError::NoMeasurements`]; [`IdentifyError::Model`] for a TCP or position to solve that
/// the model lacks.
///
/// # Examples
/// A tracker frame rotated and two metres away, found from the nominal model:
/// ```
/// use nalgebra::{Rotation3, Vector3};
/// use vatcal_core::{CellFile, Measurement};
/// use vatcal_identification::{InitOptions, initialise};
/// use vatcal_kinematics::Model;
///
/// let nominal = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))?)?;
/// let r = Rotation3::from_euler_angles(0.7, -1.1, 2.5);
/// let shift = Vector3::new(2000.0, -300.0, 450.0);
/// let ms: Vec<Measurement> = vatcal_sim::truth::probe_start_poses(&nominal, 30, 3)
///     .iter()
///     .map(|m| {
///         let p = nominal.tcp_position(&m.q, m.tcp).expect("fk");
///         Measurement::tracker(m.tcp, m.q, r * p + shift)
///     })
///     .collect();
/// let init = initialise(&nominal, &ms, &InitOptions::default())?;
/// assert!(init.rms_before_mm > 1000.0 && init.rms_after_mm < 1e-6, "{}", init.rms_after_mm);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn initialise(
    start: &Model,
    measurements: &[Measurement],
    options: &InitOptions,
) -> Result<Initialisation, IdentifyError> {
    if measurements.is_empty() {
        return Err(IdentifyError::NoMeasurements);
    }
    for id in &options.tcps {
        start.param(ParamId::Tcp { id: *id, axis: vatcal_core::Axis::X })?;
    }
    for id in &options.free_positions {
        start.param(ParamId::Position { id: *id, axis: vatcal_core::Axis::X })?;
    }
    let mut model = start.clone();
    let rms_before_mm = rms(&model, measurements)?;
    let anchored = measurements.iter().any(|m| match m.target {
        Target::Tracker { .. } => true,
        Target::Probe { position } => !options.free_positions.contains(&position),
        // orientation rows fix no point; plane rows only a height
        Target::Orientation { .. } | Target::Plane { .. } => false,
    });
    let register = options.register_base && anchored;
    let mut last = rms_before_mm;
    let mut rounds = 0;
    for _ in 0..options.max_rounds.max(1) {
        rounds += 1;
        let before = model.clone();
        if register {
            register_base(&mut model, measurements, &options.free_positions)?;
        }
        solve_points(&mut model, measurements, options)?;
        fit_free_planes(&mut model, measurements, &options.free_planes)?;
        let now = rms(&model, measurements)?;
        if now > last {
            // a round that makes things worse (degenerate data) is undone
            model = before;
            break;
        }
        let converged = last - now <= 1e-9 * last.max(1e-9);
        last = now;
        if converged {
            break;
        }
    }
    Ok(Initialisation {
        rms_after_mm: rms(&model, measurements)?,
        model,
        rms_before_mm,
        rounds,
        registered: register,
    })
}

/// RMS of the residual norms of the position and plane rows [mm] (orientation rows left out).
fn rms(model: &Model, measurements: &[Measurement]) -> Result<f64, IdentifyError> {
    let mut sum = 0.0;
    let mut count = 0usize;
    for (index, m) in measurements.iter().enumerate() {
        if m.target.is_orientation() {
            continue;
        }
        count += 1;
        let e = model.residual(m).map_err(|source| IdentifyError::Measurement { index, source })?
            + m.target_offset_mm();
        sum += e.norm_squared();
    }
    Ok((sum / count.max(1) as f64).sqrt())
}

/// The observed point of a row whose target is known (tracker, probe at a known position).
fn observed(model: &Model, m: &Measurement, free: &[u32]) -> Option<Vector3<f64>> {
    match m.target {
        Target::Tracker { xyz_mm } => Some(xyz_mm),
        Target::Probe { position } if !free.contains(&position) => {
            model.position(position).map(|p| p + m.target_offset_mm())
        }
        Target::Probe { .. } | Target::Orientation { .. } | Target::Plane { .. } => None,
    }
}

/// Step 3: each free plane through its rows' predicted contacts (its contact radius kept).
fn fit_free_planes(
    model: &mut Model,
    measurements: &[Measurement],
    free: &[u32],
) -> Result<(), IdentifyError> {
    for id in free {
        let radius = model
            .plane(*id)
            .map_or(vatcal_core::cell::PlaneEntry::DEFAULT_CONTACT_RADIUS_MM, |p| p.contact_radius_mm);
        if let Some(plane) = crate::planes::plane_of_rows(model, measurements, *id, radius)? {
            model.insert_plane(*id, plane);
        }
    }
    Ok(())
}

/// Step 1: the rigid transform (Kabsch) from predicted to observed points, composed into the
/// base pose. Skipped when fewer than three rows have a known target or they are collinear.
fn register_base(model: &mut Model, measurements: &[Measurement], free: &[u32]) -> Result<(), IdentifyError> {
    let mut pairs = Vec::new();
    for (index, m) in measurements.iter().enumerate() {
        if let Some(y) = observed(model, m, free) {
            let x = model
                .tcp_position_ctx(&m.q, &m.context, m.tcp)
                .map_err(|source| IdentifyError::Measurement { index, source })?;
            pairs.push((x, y));
        }
    }
    let Some((r, t)) = kabsch(&pairs) else { return Ok(()) };
    let b = model.base_frame();
    // a change of world frame, not a tilt of the robot: gravity turns with it
    model.set_gravity(r * model.gravity())?;
    let new_r = r * b.r;
    let new_p = r * b.p + t;
    let (alpha, beta, gamma) = xyz_euler(&new_r);
    let values = [new_p.x, new_p.y, new_p.z, alpha, beta, gamma];
    for (p, v) in BaseParam::ALL.iter().zip(values) {
        model.set_param(ParamId::Base(*p), v)?;
    }
    Ok(())
}

/// The proper rotation `R` and translation `t` minimising `Σ |R x + t − y|²`; `None` when the
/// points do not fix a rotation (fewer than 3, or collinear).
pub(crate) fn kabsch(pairs: &[(Vector3<f64>, Vector3<f64>)]) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    if pairs.len() < 3 {
        return None;
    }
    let n = pairs.len() as f64;
    let cx = pairs.iter().map(|p| p.0).sum::<Vector3<f64>>() / n;
    let cy = pairs.iter().map(|p| p.1).sum::<Vector3<f64>>() / n;
    let h: Matrix3<f64> = pairs.iter().map(|(x, y)| (x - cx) * (y - cy).transpose()).sum();
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut s = svd.singular_values;
    s.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    // collinear (or coincident) points leave the rotation about their line free
    if s[1].is_nan() || s[1] <= 1e-9 * s[0].max(f64::MIN_POSITIVE) {
        return None;
    }
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    Some((r, cy - r * cx))
}

/// `(alpha, beta, gamma)` with `R = Rx(alpha) Ry(beta) Rz(gamma)` (the base-pose convention).
pub(crate) fn xyz_euler(r: &Matrix3<f64>) -> (f64, f64, f64) {
    let beta = r[(0, 2)].clamp(-1.0, 1.0).asin();
    if r[(0, 2)].abs() < 1.0 - 1e-12 {
        (f64::atan2(-r[(1, 2)], r[(2, 2)]), beta, f64::atan2(-r[(0, 1)], r[(0, 0)]))
    } else {
        // gimbal lock: gamma folded into alpha
        (f64::atan2(r[(2, 1)], r[(1, 1)]), beta, 0.0)
    }
}

/// One row block of step 2: the right-hand side and the 3 × 3 blocks `(first column, block)`.
type LinearRow = ([f64; 3], Vec<(usize, Matrix3<f64>)>);

/// Step 2: TCP coordinates and free fixed points by one linear least-squares problem (minimum
/// norm where the data do not fix them; rows of TCPs that are not solved use their current
/// coordinates).
fn solve_points(
    model: &mut Model,
    measurements: &[Measurement],
    options: &InitOptions,
) -> Result<(), IdentifyError> {
    let tcps = &options.tcps;
    let free = &options.free_positions;
    let cols = 3 * (tcps.len() + free.len());
    if cols == 0 {
        return Ok(());
    }
    let mut rows: Vec<LinearRow> = Vec::new();
    for (index, m) in measurements.iter().enumerate() {
        let tool = model.chain_full(&m.q, &m.context, true, None).tool;
        let tcp_col = tcps.iter().position(|t| *t == m.tcp).map(|k| 3 * k);
        let current_tcp = model.tcp(m.tcp).ok_or_else(|| IdentifyError::Measurement {
            index,
            source: vatcal_kinematics::ModelError::UnknownTcp(m.tcp, model.tcp_ids()),
        })?;
        // observed − (part not solved for)
        let mut blocks = Vec::new();
        let mut rhs = -tool.p;
        match tcp_col {
            Some(c) => blocks.push((c, tool.r)),
            None => rhs -= tool.r * current_tcp,
        }
        match m.target {
            Target::Probe { position } if free.contains(&position) => {
                let k = free.iter().position(|p| *p == position).unwrap_or(0);
                blocks.push((3 * (tcps.len() + k), -Matrix3::identity()));
                rhs -= m.target_offset_mm();
            }
            _ => match observed(model, m, free) {
                Some(y) => rhs += y,
                None => continue,
            },
        }
        if !blocks.is_empty() {
            rows.push(([rhs.x, rhs.y, rhs.z], blocks));
        }
    }
    if rows.is_empty() {
        return Ok(());
    }
    let mut a = DMatrix::<f64>::zeros(3 * rows.len(), cols);
    let mut b = DVector::<f64>::zeros(3 * rows.len());
    for (k, (rhs, blocks)) in rows.iter().enumerate() {
        for (c, m) in blocks {
            a.view_mut((3 * k, *c), (3, 3)).copy_from(m);
        }
        b.rows_mut(3 * k, 3).copy_from_slice(rhs);
    }
    let svd = a.svd(true, true);
    let tol = 1e-10 * svd.singular_values.max();
    let x = svd.solve(&b, tol).map_err(|e| IdentifyError::Numerical(format!("initialisation: {e}")))?;
    let axes = vatcal_core::Axis::ALL;
    for (k, id) in tcps.iter().enumerate() {
        for axis in axes {
            model.set_param(ParamId::Tcp { id: *id, axis }, x[3 * k + axis.index()])?;
        }
    }
    for (k, id) in free.iter().enumerate() {
        for axis in axes {
            model.set_param(ParamId::Position { id: *id, axis }, x[3 * (tcps.len() + k) + axis.index()])?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Kabsch recovers any rotation and translation exactly from noiseless points, and the
        /// Euler angles of the base convention round-trip.
        #[test]
        fn kabsch_and_euler_recover_any_rigid_motion(
            ax in -3.1f64..3.1, ay in -1.5f64..1.5, az in -3.1f64..3.1,
            tx in -3000.0f64..3000.0, ty in -3000.0f64..3000.0, tz in -3000.0f64..3000.0,
        ) {
            let r = Rotation3::from_euler_angles(ax, ay, az).into_inner();
            let t = Vector3::new(tx, ty, tz);
            let xs = [Vector3::new(100.0, 0.0, 0.0), Vector3::new(0.0, 250.0, 10.0),
                      Vector3::new(-30.0, 40.0, 400.0), Vector3::new(500.0, -200.0, 60.0)];
            let pairs: Vec<_> = xs.iter().map(|x| (*x, r * x + t)).collect();
            let (rr, tt) = kabsch(&pairs).expect("rotation");
            prop_assert!((rr - r).norm() < 1e-9);
            prop_assert!((tt - t).norm() < 1e-6);
            let (a, b, g) = xyz_euler(&r);
            let back = vatcal_core::frame::rot_x(a) * vatcal_core::frame::rot_y(b) * vatcal_core::frame::rot_z(g);
            prop_assert!((back - r).norm() < 1e-9);
        }
    }

    #[test]
    fn collinear_points_fix_no_rotation() {
        let pairs: Vec<_> =
            (0..5).map(|k| (Vector3::new(k as f64, 0.0, 0.0), Vector3::new(0.0, k as f64, 0.0))).collect();
        assert!(kabsch(&pairs).is_none());
    }
}
