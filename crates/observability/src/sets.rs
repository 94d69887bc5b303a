//! Robot-agnostic parameter sets and the data beyond joint rows that a fit can use.
//!
//! The named sets of the paper (`paper34`, `geometric`) list the canonical cell's parameters
//! ([`vatcal_core::canonical`]). Any chain — measured by any instrument — uses the nested,
//! generic sets of [`GenericSet`]:
//!
//! | set | preference order before the rank analysis |
//! |---|---|
//! | `registration` | free fixed-point coordinates, coordinates of every measured TCP, base pose |
//! | `joint-offsets` | + `theta_offset_i` of revolute and `d_i` of prismatic joints |
//! | `kinematic` | + `alpha`, `a`, `theta_offset`, `d` of every row, then `beta` of every row |
//! | `kinematic+compliance` | + the compliance `c_i` of every revolute joint |
//!
//! Each list is reduced to its identifiable basis on the data at hand
//! ([`crate::identifiability::analyze_jacobian`], preference order: earlier parameters are
//! kept). So the registration of tracker data is the base pose plus the TCP, while for probe
//! data at **unknown** fixed points ([`DataDesign::free_positions`]) the base pose is absorbed
//! by the points and drops out; without a known distance between two points
//! ([`DataDesign::distances`]) a `kinematic` fit also loses the overall scale (one length).
//! Plane rows at **unknown** planes ([`DataDesign::free_planes`]) are the same: the plane's
//! tilts and offset come first, the base pose drops out, and without a known distance between
//! two parallel planes ([`DataDesign::plane_distances`]) the scale is lost.

use faer::Mat;
use nalgebra::Vector3;
use vatcal_core::params::{Axis, EffectParam, ToolFrameDof};
use vatcal_core::{BaseParam, Measurement, ParamId, ParamSet, PlaneDistance, PlaneDof, PointDistance};
use vatcal_kinematics::Model;

use crate::ObservabilityError;
use crate::identifiability::{
    AnalysisOptions, IdentifiabilityReport, all_identifiable, analyze_jacobian, assemble_jacobian,
};

/// The robot-agnostic parameter sets, smallest first; each contains the previous one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum GenericSet {
    /// where the robot is (base pose) and which point the instrument sees (TCP coordinates,
    /// unknown fixed points; with orientation rows the tool body's tilt, `tool_rx`, `tool_ry`,
    /// when the model has the `tool-frame` effect on)
    Registration,
    /// registration + the zero offset of every joint
    JointOffsets,
    /// the full identifiable geometric basis (MDH + Hayati β of every row, TCPs, base)
    Kinematic,
    /// kinematic + the compliance of every revolute joint
    KinematicCompliance,
}

impl GenericSet {
    /// All four, smallest first (the candidates of the cross-validated default).
    pub const ALL: [GenericSet; 4] = [
        GenericSet::Registration,
        GenericSet::JointOffsets,
        GenericSet::Kinematic,
        GenericSet::KinematicCompliance,
    ];

    /// The `--params` name: `registration`, `joint-offsets`, `kinematic`, `kinematic+compliance`.
    pub fn name(self) -> &'static str {
        match self {
            GenericSet::Registration => "registration",
            GenericSet::JointOffsets => "joint-offsets",
            GenericSet::Kinematic => "kinematic",
            GenericSet::KinematicCompliance => "kinematic+compliance",
        }
    }

    /// Parses a name of [`GenericSet::name`] (surrounding blanks ignored).
    pub fn parse(spec: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == spec.trim())
    }
}

impl std::fmt::Display for GenericSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What a fit knows beyond the joint rows: which fixed points (calibration positions) are at
/// unknown places — their coordinates are then parameters — and known distances between them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DataDesign {
    /// ids of the calibration positions whose coordinates are unknown (identified)
    pub free_positions: Vec<u32>,
    /// known distances between fixed points (one residual row each)
    pub distances: Vec<PointDistance>,
    /// ids of the contact planes whose normal and offset are unknown (identified)
    pub free_planes: Vec<u32>,
    /// known distances between parallel contact planes (three residual rows each:
    /// [`plane_distance_rows`])
    pub plane_distances: Vec<PlaneDistance>,
}

impl DataDesign {
    /// Checks that every distance names two positions of the model.
    ///
    /// # Errors
    /// [`ObservabilityError::InvalidInput`] naming the distance and the unknown id.
    pub fn check(&self, model: &Model) -> Result<(), ObservabilityError> {
        let known = model.position_ids();
        for d in &self.distances {
            for id in [d.a, d.b] {
                if !known.contains(&id) {
                    return Err(ObservabilityError::InvalidInput(format!(
                        "point distance {},{},{}: point {id} is not a calibration position of the model or the data (known: {known:?})",
                        d.a, d.b, d.distance_mm
                    )));
                }
            }
        }
        for id in &self.free_positions {
            if !known.contains(id) {
                return Err(ObservabilityError::InvalidInput(format!(
                    "unknown position {id} is not a calibration position of the model (known: {known:?})"
                )));
            }
        }
        let planes = model.plane_ids();
        for (what, id) in self.free_planes.iter().map(|id| ("unknown plane", *id)).chain(
            self.plane_distances
                .iter()
                .flat_map(|d| [("plane distance: plane", d.a), ("plane distance: plane", d.b)]),
        ) {
            if !planes.contains(&id) {
                return Err(ObservabilityError::InvalidInput(format!(
                    "{what} {id} is not a contact plane of the model or the data (known: {planes:?})"
                )));
            }
        }
        Ok(())
    }

    /// Rows the known distances add after the measurement rows: one per point distance,
    /// three per plane distance.
    pub fn constraint_rows(&self) -> usize {
        self.distances.len() + 3 * self.plane_distances.len()
    }

    /// The constraint rows' Jacobian at `model` over `params`, unweighted (point distances,
    /// then plane distances): `constraint_rows()` × `params.len()`, 0 rows when there is no
    /// known distance. [`assemble_design_jacobian`] appends it after the measurement rows;
    /// [`detmax_with_prior`](crate::detmax::detmax_with_prior) takes it as the prior rows of a
    /// selection that knows those distances.
    ///
    /// # Errors
    /// As [`DataDesign::for_each_constraint_row`].
    pub fn constraint_jacobian(
        &self,
        model: &Model,
        params: &ParamSet,
    ) -> Result<Mat<f64>, ObservabilityError> {
        let mut rows = Mat::<f64>::zeros(self.constraint_rows(), params.len());
        self.for_each_constraint_row(model, &params.0, |k, _, row| {
            for (c, v) in row.iter().enumerate() {
                rows[(k, c)] = *v;
            }
        })?;
        Ok(rows)
    }

    /// Every constraint row's residual and Jacobian row over `params` (point distances, then
    /// plane distances), handed to `each(row index, residual, jacobian row)` in order.
    ///
    /// # Errors
    /// As [`distance_row`] and [`plane_distance_rows`].
    pub fn for_each_constraint_row(
        &self,
        model: &Model,
        params: &[ParamId],
        mut each: impl FnMut(usize, f64, &[f64]),
    ) -> Result<(), ObservabilityError> {
        let l = params.len();
        let mut row = vec![0.0; 3 * l];
        for (k, d) in self.distances.iter().enumerate() {
            let e = distance_row(model, d, params, &mut row[..l])?;
            each(k, e, &row[..l]);
        }
        for (k, d) in self.plane_distances.iter().enumerate() {
            let e = plane_distance_rows(model, d, params, &mut row)?;
            for (r, e) in e.iter().enumerate() {
                each(self.distances.len() + 3 * k + r, *e, &row[r * l..(r + 1) * l]);
            }
        }
        Ok(())
    }
}

/// The three residuals of a known distance between parallel planes at `model`
/// ([`PlaneDistance`]: `distance_mm − (offset_b − offset_a)` and the parallelism
/// `−L·(n_b − n_a)·u_a`, `−L·(n_b − n_a)·v_a`) and their Jacobian rows over `params`, row-major
/// into `rows` (`3 × params.len()`; the sign convention of the measurement rows:
/// `d(model − observed)/dρ`).
///
/// # Errors
/// [`ObservabilityError::InvalidInput`] when a plane is not in the model.
pub fn plane_distance_rows(
    model: &Model,
    d: &PlaneDistance,
    params: &[ParamId],
    rows: &mut [f64],
) -> Result<[f64; 3], ObservabilityError> {
    let plane = |id: u32| {
        model.plane(id).copied().ok_or_else(|| {
            ObservabilityError::InvalidInput(format!(
                "plane distance {},{}: plane {id} is not a contact plane of the model",
                d.a, d.b
            ))
        })
    };
    let (pa, pb) = (plane(d.a)?, plane(d.b)?);
    let (u, v) = pa.basis();
    let lever = PlaneDistance::PARALLEL_LEVER_MM;
    let dn = pb.normal() - pa.normal();
    let l = params.len();
    for (c, p) in params.iter().enumerate() {
        let (off, dnormal) = match *p {
            ParamId::Plane { id, dof } if id == d.b => {
                (if dof == PlaneDof::Offset { 1.0 } else { 0.0 }, pb.normal_derivative(dof))
            }
            ParamId::Plane { id, dof } if id == d.a => {
                (if dof == PlaneDof::Offset { -1.0 } else { 0.0 }, -pa.normal_derivative(dof))
            }
            _ => (0.0, Vector3::zeros()),
        };
        rows[c] = off;
        rows[l + c] = lever * dnormal.dot(&u);
        rows[2 * l + c] = lever * dnormal.dot(&v);
    }
    Ok([d.distance_mm - (pb.offset_mm - pa.offset_mm), -lever * dn.dot(&u), -lever * dn.dot(&v)])
}

/// The residual `distance_mm − |p_a − p_b|` of a known distance at `model`, and its Jacobian
/// row `d|p_a − p_b| / dρ` over `params` into `row` (the sign convention of the measurement
/// rows: `d(model − observed)/dρ`). Only the coordinates of `a` and `b` have non-zero entries.
///
/// # Errors
/// [`ObservabilityError::InvalidInput`] when a point is not in the model or the two coincide.
pub fn distance_row(
    model: &Model,
    d: &PointDistance,
    params: &[ParamId],
    row: &mut [f64],
) -> Result<f64, ObservabilityError> {
    let point = |id: u32| {
        model.position(id).ok_or_else(|| {
            ObservabilityError::InvalidInput(format!(
                "point distance {},{}: point {id} is not a calibration position of the model",
                d.a, d.b
            ))
        })
    };
    let diff = point(d.a)? - point(d.b)?;
    let len = diff.norm();
    if !(len > 0.0 && len.is_finite()) {
        return Err(ObservabilityError::InvalidInput(format!(
            "point distance {},{}: the two points coincide in the model; give them distinct starting places",
            d.a, d.b
        )));
    }
    let u = diff / len;
    for (c, p) in params.iter().enumerate() {
        row[c] = match *p {
            ParamId::Position { id, axis } if id == d.a => u[axis.index()],
            ParamId::Position { id, axis } if id == d.b => -u[axis.index()],
            _ => 0.0,
        };
    }
    Ok(d.distance_mm - len)
}

/// [`assemble_jacobian`] with one more row per known distance (unweighted; row order:
/// measurements, then distances).
///
/// # Errors
/// As [`assemble_jacobian`] and [`distance_row`].
pub fn assemble_design_jacobian(
    model: &Model,
    measurements: &[Measurement],
    design: &DataDesign,
    params: &ParamSet,
) -> Result<Mat<f64>, ObservabilityError> {
    let j = assemble_jacobian(model, measurements, params)?;
    if design.constraint_rows() == 0 {
        return Ok(j);
    }
    let (m, l) = (j.nrows(), params.len());
    let mut out = Mat::<f64>::zeros(m + design.constraint_rows(), l);
    out.as_mut().get_mut(..m, ..).copy_from(j.as_ref());
    out.as_mut().get_mut(m.., ..).copy_from(design.constraint_jacobian(model, params)?.as_ref());
    Ok(out)
}

/// [`crate::analyze`] of the measurements together with the known distances.
///
/// # Errors
/// As [`crate::analyze`] and [`distance_row`].
pub fn analyze_design(
    model: &Model,
    measurements: &[Measurement],
    design: &DataDesign,
    params: &ParamSet,
) -> Result<IdentifiabilityReport, ObservabilityError> {
    if measurements.is_empty() {
        return Err(ObservabilityError::NoMeasurements);
    }
    analyze_design_with(model, measurements, design, params, &AnalysisOptions::default())
}

/// [`analyze_design`] with explicit options. The report counts the measurements and the
/// informative rows ([`vatcal_core::informative_rows`] plus [`DataDesign::constraint_rows`]).
///
/// # Errors
/// As [`analyze_design`].
pub fn analyze_design_with(
    model: &Model,
    measurements: &[Measurement],
    design: &DataDesign,
    params: &ParamSet,
    options: &AnalysisOptions,
) -> Result<IdentifiabilityReport, ObservabilityError> {
    if measurements.is_empty() {
        return Err(ObservabilityError::NoMeasurements);
    }
    let j = assemble_design_jacobian(model, measurements, design, params)?;
    let mut report = analyze_jacobian(j.as_ref(), params, options)?;
    report.measurement_count = measurements.len();
    report.equation_count = vatcal_core::informative_rows(measurements) + design.constraint_rows();
    Ok(report)
}

/// The ids of the TCPs the measurements use, ascending.
pub fn measured_tcps(measurements: &[Measurement]) -> Vec<u32> {
    let mut ids: Vec<u32> = measurements.iter().map(|m| m.tcp).collect();
    ids.sort_unstable();
    ids.dedup();
    ids
}

/// True when some row observes a known place — a tracker row, or a probe row at a calibration
/// position that is not free. Without such a row the world frame is a gauge: moving the base
/// pose (or anything before joint 1: MDH row 1) and every free point by the same rigid motion
/// leaves the cost unchanged, so neither the base pose nor row 1 can be identified.
pub fn anchored(measurements: &[Measurement], design: &DataDesign) -> bool {
    measurements.iter().any(|m| match m.target {
        vatcal_core::Target::Tracker { .. } => true,
        vatcal_core::Target::Probe { position } => !design.free_positions.contains(&position),
        // fixes the world frame's rotation only, not its origin
        vatcal_core::Target::Orientation { .. } => false,
        // a known plane fixes the height along its normal (the rank test drops the rest)
        vatcal_core::Target::Plane { plane, .. } => !design.free_planes.contains(&plane),
    })
}

/// The preference order of `set` (see the module docs) before the rank analysis. Data without
/// an anchor ([`anchored`]) leave out the base pose and MDH row 1 (a gauge of the world frame:
/// the rank test at a model that does not fit yet cannot see it, because the cost, not the
/// residual vector, is invariant).
pub fn generic_order(
    model: &Model,
    measurements: &[Measurement],
    set: GenericSet,
    design: &DataDesign,
) -> ParamSet {
    let anchor = anchored(measurements, design);
    let first_row = if anchor { 1 } else { 2 };
    let xyz = |f: &dyn Fn(Axis) -> ParamId| Axis::ALL.map(f);
    let mut v: Vec<ParamId> = Vec::new();
    for id in &design.free_positions {
        v.extend(xyz(&|axis| ParamId::Position { id: *id, axis }));
    }
    for id in &design.free_planes {
        v.extend(PlaneDof::ALL.map(|dof| ParamId::Plane { id: *id, dof }));
    }
    for id in measured_tcps(measurements) {
        v.extend(xyz(&|axis| ParamId::Tcp { id, axis }));
    }
    // orientation rows (pose rows) see the tool body's rotation: its tilt is registration
    if measurements.iter().any(|m| m.target.is_orientation()) {
        v.extend(
            [ToolFrameDof::Rx, ToolFrameDof::Ry]
                .map(|d| ParamId::Effect(EffectParam::ToolFrame(d)))
                .into_iter()
                .filter(|p| model.has_param(*p)),
        );
    }
    if anchor {
        v.extend(base_order(model, measurements, design).map(ParamId::Base));
    }
    let n = model.joint_count() as u8;
    if set >= GenericSet::JointOffsets {
        v.extend(
            (first_row..=n)
                .map(|i| if model.is_revolute(i as usize) { ParamId::ThetaOffset(i) } else { ParamId::D(i) }),
        );
    }
    if set >= GenericSet::Kinematic {
        for i in first_row..=n {
            for p in [ParamId::Alpha(i), ParamId::A(i), ParamId::ThetaOffset(i), ParamId::D(i)] {
                if !v.contains(&p) {
                    v.push(p);
                }
            }
        }
        v.extend((first_row..=n).map(ParamId::Beta));
    }
    if set >= GenericSet::KinematicCompliance {
        v.extend((1..=n).map(ParamId::Compliance).filter(|p| model.has_param(*p)));
    }
    ParamSet(v)
}

/// The identifiable basis of `set` on these data ([`generic_order`] reduced by
/// [`analyze_design`]).
///
/// # Errors
/// As [`analyze_design`]; [`ObservabilityError::InvalidInput`] for a `kinematic` set on data
/// that fix no length — every probe row at an unknown fixed point (every plane row on an
/// unknown plane), no tracker row and no known distance: scaling every length of the chain and the points together changes nothing but the
/// size of the residuals, and the fit would shrink the robot.
pub fn generic_set(
    model: &Model,
    measurements: &[Measurement],
    set: GenericSet,
    design: &DataDesign,
) -> Result<ParamSet, ObservabilityError> {
    if set >= GenericSet::Kinematic && !anchored(measurements, design) && design.constraint_rows() == 0 {
        return Err(ObservabilityError::InvalidInput(format!(
            "`{set}` cannot be identified from these data: every row is at an unknown fixed point or plane, so nothing fixes the scale of the chain; give a known distance between two points (--point-distance A,B,MM) or two parallel planes (--plane-distance A,B,MM), or use registration / joint-offsets"
        )));
    }
    let order = generic_order(model, measurements, set, design);
    Ok(analyze_design(model, measurements, design, &order)?.identifiable_set())
}

/// The base pose's parameters in the order the rank analysis should prefer them: x, y, z, α,
/// β, γ — unless only rows on known contact planes anchor the world (no tracker row, no probe
/// row at a known place). Heights then see the base only along the planes' normals: the
/// translations come in decreasing `Σ |n·axis|` over those rows (a horizontal table: z first,
/// which it fixes, rather than x standing in for it through a slight tilt) and the rotations in
/// increasing order (the turn about the normal, which no height sees, last).
fn base_order(model: &Model, measurements: &[Measurement], design: &DataDesign) -> [BaseParam; 6] {
    let mut weight = [0.0f64; 3];
    for m in measurements {
        match m.target {
            vatcal_core::Target::Plane { plane, .. } if !design.free_planes.contains(&plane) => {
                if let Some(p) = model.plane(plane) {
                    let n = p.normal();
                    for (w, c) in weight.iter_mut().zip(n.iter()) {
                        *w += c.abs();
                    }
                }
            }
            vatcal_core::Target::Plane { .. } | vatcal_core::Target::Orientation { .. } => {}
            vatcal_core::Target::Tracker { .. } => return BaseParam::ALL,
            vatcal_core::Target::Probe { position } if !design.free_positions.contains(&position) => {
                return BaseParam::ALL;
            }
            vatcal_core::Target::Probe { .. } => {}
        }
    }
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|a, b| weight[*b].total_cmp(&weight[*a]));
    let translations = [BaseParam::X, BaseParam::Y, BaseParam::Z];
    let rotations = [BaseParam::Alpha, BaseParam::Beta, BaseParam::Gamma];
    [
        translations[axes[0]],
        translations[axes[1]],
        translations[axes[2]],
        rotations[axes[2]],
        rotations[axes[1]],
        rotations[axes[0]],
    ]
}

/// Resolves a `--params` specification for these data:
///
/// * a [`GenericSet`] name → [`generic_set`];
/// * `paper34`, `geometric` → the paper's lists, **only on the canonical cell**
///   ([`vatcal_core::canonical::CANONICAL_ONLY_SETS`]); refused on any other chain;
/// * `all-identifiable` → [`all_identifiable`] (plus, first, the free fixed-point coordinates
///   and the free contact planes' tilts and offsets);
/// * `default` → the canonical default ([`vatcal_core::canonical::default_param_set`]) on the
///   canonical cell; on another chain `all-identifiable` (the CLI's `identify` picks among the
///   generic sets by cross-validation instead, `vatcal_identification::cross_validate_sets`);
/// * a comma-separated list of names (each must be a parameter of the model).
///
/// # Errors
/// [`ObservabilityError::InvalidInput`] naming the specification and what is wrong; the errors
/// of [`analyze_design`].
pub fn resolve_spec(
    spec: &str,
    model: &Model,
    measurements: &[Measurement],
    design: &DataDesign,
) -> Result<ParamSet, ObservabilityError> {
    let trimmed = spec.trim();
    let canonical = model.is_meca500_on_guide();
    if let Some(set) = GenericSet::parse(trimmed) {
        return generic_set(model, measurements, set, design);
    }
    if vatcal_core::canonical::is_canonical_only_set(trimmed) && !canonical {
        return Err(ObservabilityError::InvalidInput(format!(
            "parameter set `{trimmed}` names the parameters of the canonical Meca500-on-guide cell (the paper's list); this chain is {}: use registration, joint-offsets, kinematic, kinematic+compliance, all-identifiable, default or a list of names",
            model.describe_chain()
        )));
    }
    if trimmed == "default" && canonical {
        return Ok(vatcal_core::canonical::default_param_set());
    }
    if trimmed == "all-identifiable" || trimmed == "default" {
        if design.free_positions.is_empty()
            && design.distances.is_empty()
            && design.free_planes.is_empty()
            && design.plane_distances.is_empty()
        {
            return all_identifiable(model, measurements);
        }
        // the free points' coordinates and the free planes' tilts and offsets first
        let mut order = generic_order(model, measurements, GenericSet::Registration, design);
        order.0.retain(|p| matches!(p, ParamId::Position { .. } | ParamId::Plane { .. }));
        for p in crate::identifiability::preference_order(model).0 {
            if !order.0.contains(&p) {
                order.0.push(p);
            }
        }
        return Ok(analyze_design(model, measurements, design, &order)?.identifiable_set());
    }
    let set = ParamSet::parse(spec)
        .map_err(|e| ObservabilityError::InvalidInput(format!("parameter set `{spec}`: {e}")))?;
    if let Some(p) = set.iter().find(|p| !model.has_param(**p)) {
        return Err(ObservabilityError::InvalidInput(format!(
            "parameter set `{spec}`: `{p}` is not part of this model (switch its effect on in the cell file first)"
        )));
    }
    Ok(set)
}

/// Resolves a `--params` specification: `paper34`, `geometric` (canonical cell only), a
/// comma-separated list of names, `all-identifiable` (the [`all_identifiable`] basis for these
/// measurements), `default` ([`default_params`](crate::identifiability::default_params)) or a
/// robot-agnostic set (`registration`, `joint-offsets`, `kinematic`, `kinematic+compliance`):
/// [`resolve_spec`] without unknown fixed points or distances.
pub fn param_set_from_spec(
    spec: &str,
    model: &Model,
    measurements: &[Measurement],
) -> Result<ParamSet, ObservabilityError> {
    resolve_spec(spec, model, measurements, &DataDesign::default())
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::CellFile;

    fn ur5e() -> Model {
        let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))
            .expect("fixture");
        Model::from_cell(&cell).expect("model")
    }

    /// Contacts on one known, slightly tilted table: the base's height is kept (not its x
    /// standing in for it through the tilt), its in-plane position and turn about the normal
    /// are not identifiable.
    #[test]
    fn a_known_table_keeps_the_base_height_not_its_in_plane_position() {
        let mut model = ur5e();
        model.insert_plane(
            1,
            vatcal_kinematics::ContactPlane::new(nalgebra::Vector3::new(0.001, 0.0, 1.0), -50.0, 40.0),
        );
        let rows = vatcal_sim::truth::synthetic_plane_contacts(&model, 1, 1, false, 60, 0.0, 3);
        let set = generic_set(&model, &rows, GenericSet::Kinematic, &DataDesign::default()).expect("set");
        let has = |b| set.0.contains(&ParamId::Base(b));
        assert!(has(BaseParam::Z), "{:?}", set.names());
        assert!(!has(BaseParam::X) && !has(BaseParam::Y) && !has(BaseParam::Gamma), "{:?}", set.names());
    }

    #[test]
    fn sets_are_nested_and_parse() {
        let model = ur5e();
        let tcp = model.tcp_ids()[0];
        let q = vatcal_core::JointVector::from_slice(&[0.1, -1.0, 1.2, -0.5, 0.7, 0.3]).expect("q");
        let ms = vec![Measurement::tracker(tcp, q, nalgebra::Vector3::zeros())];
        let design = DataDesign::default();
        let mut last = 0;
        for s in GenericSet::ALL {
            assert_eq!(GenericSet::parse(s.name()), Some(s));
            let order = generic_order(&model, &ms, s, &design);
            assert!(order.len() > last, "{s}");
            let mut dedup = order.0.clone();
            dedup.sort();
            dedup.dedup();
            assert_eq!(dedup.len(), order.len(), "{s}: no duplicates");
            last = order.len();
        }
        assert_eq!(generic_order(&model, &ms, GenericSet::Registration, &design).len(), 9);
        let e = resolve_spec("paper34", &model, &ms, &design).expect_err("refused").to_string();
        assert!(e.contains("canonical") && e.contains("6 joints"), "{e}");
    }

    #[test]
    fn distance_row_matches_finite_differences() {
        let mut model = ur5e();
        let ids = model.position_ids();
        assert!(ids.len() >= 2, "the fixture has calibration positions");
        let (a, b) = (ids[0], ids[1]);
        let d = PointDistance { a, b, distance_mm: 50.0, sigma_mm: 0.01 };
        let params: Vec<ParamId> = [a, b]
            .iter()
            .flat_map(|id| Axis::ALL.map(|axis| ParamId::Position { id: *id, axis }))
            .chain([ParamId::Base(BaseParam::X)])
            .collect();
        let mut row = vec![0.0; params.len()];
        let r0 = distance_row(&model, &d, &params, &mut row).expect("row");
        for (c, p) in params.iter().enumerate() {
            let v = model.param(*p).expect("value");
            let h = 1e-4;
            model.set_param(*p, v + h).expect("set");
            let mut scratch = vec![0.0; params.len()];
            let rp = distance_row(&model, &d, &params, &mut scratch).expect("row");
            model.set_param(*p, v).expect("reset");
            // residual = d − |p_a − p_b|, row = +d|p_a − p_b|/dρ
            let fd = -(rp - r0) / h;
            assert!((fd - row[c]).abs() < 1e-6, "{p}: {fd} vs {}", row[c]);
        }
    }
}
