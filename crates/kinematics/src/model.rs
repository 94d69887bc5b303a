//! The parameterised cell model.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use vatcal_core::cell::{CellFile, EffectEntry};
use vatcal_core::effects::{ChainInfo, EffectKind, EffectSpec, ErrorEffect};
use vatcal_core::params::{BaseParam, EffectParam, ParamUnit};
use vatcal_core::{JointKind, JointVector, MAX_JOINTS, ParamId, ParamSet, deg_to_rad, rad_to_deg};
use vatcal_gravity_torque::{GravityModel, MassModel};

use vatcal_core::Frame;
use vatcal_core::frame::{rot_x, rot_y, rot_z};

/// One MDH row in internal units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MdhRow {
    /// alpha_{i-1} \[rad\]
    pub alpha: f64,
    /// a_{i-1} \[mm\]
    pub a: f64,
    /// beta_{i-1} \[rad\]
    pub beta: f64,
    /// theta offset of joint i \[rad\]
    pub theta_offset: f64,
    /// d offset of joint i \[mm\]
    pub d: f64,
}

/// Errors of the model layer.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The TCP id is not in the model.
    #[error("unknown TCP id {0} (the model has TCPs {1:?})")]
    UnknownTcp(u32, Vec<u32>),
    /// The calibration position id is not in the model.
    #[error("unknown calibration position id {0} (the model has positions {1:?})")]
    UnknownPosition(u32, Vec<u32>),
    /// a plane row names a plane the model lacks
    #[error("unknown contact plane id {0} (the model has planes {1:?})")]
    UnknownPlane(u32, Vec<u32>),
    /// The parameter does not exist in this model (e.g. an effect that is not switched on).
    #[error("parameter `{0}` is not part of this model (switch its effect on first)")]
    ParamNotInModel(String),
    /// An effect specification is invalid.
    #[error("invalid effect {0}: {1}")]
    InvalidEffect(String, String),
    /// A value is not finite.
    #[error("parameter `{0}`: value must be finite, got {1}")]
    NonFinite(String, f64),
    /// Wrong number of values.
    #[error("expected {expected} parameter values, got {got}")]
    Length {
        /// expected count
        expected: usize,
        /// given count
        got: usize,
    },
    /// A joint vector does not have one value per joint of the chain.
    #[error("the chain has {expected} joints, the joint vector has {got} values")]
    JointCount {
        /// joints of the chain
        expected: usize,
        /// values given
        got: usize,
    },
    /// The cell's chain cannot be modelled (e.g. an unknown joint kind in an unvalidated file).
    #[error("invalid chain: {0}")]
    InvalidChain(String),
    /// The operation needs the canonical Meca500-on-guide chain (7 joints: a prismatic guide,
    /// then six revolute joints).
    #[error(
        "{0} needs the 7-joint Meca500-on-guide chain (prismatic guide + 6 revolute joints); this chain is {1}"
    )]
    NotMeca500OnGuide(String, String),
}

/// The cell model of a serial chain of N = 1..=[`MAX_JOINTS`] joints: MDH rows, joint kinds,
/// compliances, base pose, TCPs, calibration positions, masses and switched-on effects.
/// Internal units (mm, rad). Cheap to clone.
#[derive(Debug, Clone)]
pub struct Model {
    /// number of joints N
    pub(crate) n: usize,
    /// kinds of joints 1..=N at index i-1 (entries from N on unused)
    pub(crate) kinds: [JointKind; MAX_JOINTS],
    pub(crate) rows: [MdhRow; MAX_JOINTS],
    /// c_i for joint i at index i-1 (0 for prismatic joints)
    pub(crate) compliance: [f64; MAX_JOINTS],
    /// x, y, z \[mm\], alpha, beta, gamma \[rad\]
    pub(crate) base: [f64; 6],
    pub(crate) tcps: Vec<(u32, Vector3<f64>)>,
    pub(crate) positions: Vec<(u32, Vector3<f64>)>,
    /// contact planes of plane rows
    pub(crate) planes: Vec<(u32, crate::contact_plane::ContactPlane)>,
    /// joint limits (None = continuous revolute joint)
    pub(crate) limits: [Option<(f64, f64)>; MAX_JOINTS],
    /// limits with continuous joints as (-pi, pi), for [`Model::joint_limits`]
    pub(crate) ranges: [(f64, f64); MAX_JOINTS],
    /// 0-based index of the joint the guide effects act on (the first prismatic joint)
    pub(crate) guide: Option<usize>,
    pub(crate) masses: MassModel,
    pub(crate) gravity: Vector3<f64>,
    pub(crate) effects: Vec<EffectSpec>,
    pub(crate) effect_values: BTreeMap<ParamId, f64>,
    pub(crate) thermal_reference_c: f64,
    // caches (kept in sync by `refresh_caches`)
    pub(crate) row_fixed: [Frame; MAX_JOINTS],
    pub(crate) row_trig: [(f64, f64); MAX_JOINTS],
    /// `(sin, cos)` of `theta_offset_i` (the constant angle of a prismatic row)
    pub(crate) theta_trig: [(f64, f64); MAX_JOINTS],
    pub(crate) base_frame: Frame,
    /// the per-model constants of the gravity-torque recursion (masses, gravity in frame 0)
    pub(crate) gravity_model: GravityModel,
    pub(crate) any_compliance: bool,
    /// a switched-on effect needs the carriage moment
    pub(crate) effects_need_moment: bool,
    /// a switched-on effect needs the links' gravity bending moments
    pub(crate) effects_need_link_moments: bool,
    /// some switched-on effect needs the gravity torques
    pub(crate) effects_need_torques: bool,
    /// the registered implementation of each switched-on effect, `effect_impls[k]` for
    /// `effects[k]` (looked up once, not per sample)
    pub(crate) effect_impls: Vec<&'static dyn ErrorEffect>,
    /// the values of each switched-on effect's parameters, `effect_value_tables[k]` for
    /// `effects[k]` in the order of its [`EffectSpec::params`] (a copy of `effect_values` the
    /// FK reads without a map lookup per hook; kept in sync by `refresh_caches`)
    pub(crate) effect_value_tables: Vec<Vec<(EffectParam, f64)>>,
    template: CellFile,
}

/// `Rx(a) Ry(b)` and the fixed part of an MDH row `Rx(alpha) Tx(a) Ry(beta)`.
pub(crate) fn row_fixed_frame(row: &MdhRow) -> Frame {
    Frame { r: rot_x(row.alpha) * rot_y(row.beta), p: Vector3::new(row.a, 0.0, 0.0) }
}

/// `H_0^W = T(x,y,z) Rx(alpha) Ry(beta) Rz(gamma)`.
pub(crate) fn base_frame(b: &[f64; 6]) -> Frame {
    Frame { r: rot_x(b[3]) * rot_y(b[4]) * rot_z(b[5]), p: Vector3::new(b[0], b[1], b[2]) }
}

/// File-unit key of an effect parameter in `[[effects]].values`.
pub fn effect_value_key(id: ParamId) -> String {
    match id.unit() {
        ParamUnit::Rad => format!("{}_deg", id.name()),
        ParamUnit::Mm => format!("{}_mm", id.name()),
        _ => id.name(),
    }
}

fn to_file_units(id: ParamId, v: f64) -> f64 {
    if id.unit() == ParamUnit::Rad { rad_to_deg(v) } else { v }
}
fn from_file_units(id: ParamId, v: f64) -> f64 {
    if id.unit() == ParamUnit::Rad { deg_to_rad(v) } else { v }
}

impl Model {
    /// Builds the model from a validated cell file (degrees → radians).
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::CellFile;
    /// use vatcal_kinematics::{JointVector, Model};
    ///
    /// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
    /// // at the guide's zero with every arm joint at 0 the TCPs are where the canonical cell puts them
    /// let p = model.tcp_position(&JointVector::from_mm_deg(0.0, [0.0; 6]), 1)?;
    /// assert!((p - nalgebra::Vector3::new(64.78, -257.113, 49.485)).norm() < 1e-9);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`ModelError::InvalidEffect`] for an `[[effects]]` entry that does not describe a catalog
    /// effect (unknown name, missing joint / order, an unknown value key), and the errors of
    /// [`Model::enable_effect`] and [`Model::set_param`] for its values.
    pub fn from_cell(cell: &CellFile) -> Result<Self, ModelError> {
        let n = cell.joints.len().clamp(1, MAX_JOINTS);
        let mut rows = [MdhRow { alpha: 0.0, a: 0.0, beta: 0.0, theta_offset: 0.0, d: 0.0 }; MAX_JOINTS];
        let mut compliance = [0.0; MAX_JOINTS];
        let mut limits = [None; MAX_JOINTS];
        let mut kinds = [JointKind::Revolute; MAX_JOINTS];
        for j in &cell.joints {
            let k = (j.index as usize).saturating_sub(1).min(n - 1);
            rows[k] = MdhRow {
                alpha: deg_to_rad(j.alpha_deg),
                a: j.a_mm,
                beta: deg_to_rad(j.beta_deg),
                theta_offset: deg_to_rad(j.theta_deg),
                d: j.d_mm,
            };
            let kind = j.joint_kind().ok_or_else(|| {
                ModelError::InvalidChain(format!(
                    "joints[index={}].kind: unknown joint kind `{}`",
                    j.index, j.kind
                ))
            })?;
            kinds[k] = kind;
            limits[k] = j.limits().map(|(lo, hi)| (kind.from_file_unit(lo), kind.from_file_unit(hi)));
            if kind.is_revolute() {
                compliance[k] = j.compliance_rad_per_n_m;
            }
        }
        let mut ranges = [(-std::f64::consts::PI, std::f64::consts::PI); MAX_JOINTS];
        for (r, l) in ranges.iter_mut().zip(&limits) {
            if let Some(l) = l {
                *r = *l;
            }
        }
        let guide = kinds[..n].iter().position(|k| *k == JointKind::Prismatic);
        let b = &cell.base_in_world;
        let base = [
            b.x_mm,
            b.y_mm,
            b.z_mm,
            deg_to_rad(b.alpha_deg),
            deg_to_rad(b.beta_deg),
            deg_to_rad(b.gamma_deg),
        ];
        let point = |p: &vatcal_core::cell::PointEntry| (p.id, Vector3::new(p.x_mm, p.y_mm, p.z_mm));
        let masses = MassModel::from_inertials(&cell.inertials);
        let gravity = Vector3::from(cell.gravity.vector_m_per_s2);
        let mut model = Self {
            n,
            kinds,
            rows,
            compliance,
            base,
            tcps: cell.tcps.iter().map(point).collect(),
            positions: cell.calibration_positions.iter().map(point).collect(),
            planes: cell
                .planes
                .iter()
                .map(|e| (e.id, crate::contact_plane::ContactPlane::from_entry(e)))
                .collect(),
            limits,
            ranges,
            guide,
            gravity_model: GravityModel::new(&masses, &Frame::identity().r, &gravity),
            masses,
            gravity,
            effects: Vec::new(),
            effect_values: BTreeMap::new(),
            effect_value_tables: Vec::new(),
            thermal_reference_c: 20.0,
            row_fixed: [Frame::identity(); MAX_JOINTS],
            row_trig: [(0.0, 1.0); MAX_JOINTS],
            theta_trig: [(0.0, 1.0); MAX_JOINTS],
            base_frame: Frame::identity(),
            any_compliance: false,
            effects_need_moment: false,
            effects_need_link_moments: false,
            effects_need_torques: false,
            effect_impls: Vec::new(),
            template: cell.clone(),
        };
        for (k, e) in cell.effects.iter().enumerate() {
            let spec = spec_from_entry(e)
                .map_err(|m| ModelError::InvalidEffect(format!("effects[{k}] ({})", e.effect), m))?;
            model.enable_effect(spec)?;
            if let Some(t) = e.reference_temperature_c {
                model.thermal_reference_c = t;
            }
            for (key, v) in &e.values {
                let id = spec
                    .params()
                    .into_iter()
                    .find(|p| effect_value_key(*p) == *key || p.name() == *key)
                    .ok_or_else(|| {
                        ModelError::InvalidEffect(
                            format!("effects[{k}] ({})", e.effect),
                            format!(
                                "unknown value key `{key}` (expected one of {:?})",
                                spec.params().into_iter().map(effect_value_key).collect::<Vec<_>>()
                            ),
                        )
                    })?;
                let x = v.as_float().or_else(|| v.as_integer().map(|i| i as f64)).unwrap_or(f64::NAN);
                let x = if effect_value_key(id) == *key { from_file_units(id, x) } else { x };
                model.set_param(id, x)?;
            }
        }
        model.refresh_caches();
        Ok(model)
    }

    /// Writes the model back into the cell-file format (radians → degrees). Inertials,
    /// obstacles, motion limits and unknown tables are those of the file the model came from.
    ///
    /// # Examples
    /// A changed parameter is written in file units, and the file builds the same model:
    /// ```
    /// use vatcal_core::{CellFile, ParamId};
    /// use vatcal_kinematics::Model;
    ///
    /// let mut model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))?)?;
    /// model.set_param(ParamId::Beta(3), 0.01f64.to_radians())?;
    /// let cell = model.to_cell();
    /// assert!((cell.joints[2].beta_deg - 0.01).abs() < 1e-12);
    /// let back = Model::from_cell(&cell)?;
    /// assert_eq!(back.param(ParamId::Beta(3))?, model.param(ParamId::Beta(3))?);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn to_cell(&self) -> CellFile {
        let mut cell = self.template.clone();
        for j in cell.joints.iter_mut() {
            let k = (j.index as usize).saturating_sub(1).min(self.n - 1);
            let r = &self.rows[k];
            j.alpha_deg = rad_to_deg(r.alpha);
            j.a_mm = r.a;
            j.beta_deg = rad_to_deg(r.beta);
            j.theta_deg = rad_to_deg(r.theta_offset);
            j.d_mm = r.d;
            if self.kinds[k].is_revolute() {
                j.compliance_rad_per_n_m = self.compliance[k];
            }
        }
        let b = &mut cell.base_in_world;
        b.x_mm = self.base[0];
        b.y_mm = self.base[1];
        b.z_mm = self.base[2];
        b.alpha_deg = rad_to_deg(self.base[3]);
        b.beta_deg = rad_to_deg(self.base[4]);
        b.gamma_deg = rad_to_deg(self.base[5]);
        for t in cell.tcps.iter_mut() {
            if let Some(v) = self.tcp(t.id) {
                (t.x_mm, t.y_mm, t.z_mm) = (v.x, v.y, v.z);
            }
        }
        for p in cell.calibration_positions.iter_mut() {
            if let Some(v) = self.position(p.id) {
                (p.x_mm, p.y_mm, p.z_mm) = (v.x, v.y, v.z);
            }
        }
        cell.planes = self.planes.iter().map(|(id, p)| p.to_entry(*id)).collect();
        if Vector3::from(cell.gravity.vector_m_per_s2) != self.gravity {
            cell.gravity.vector_m_per_s2 = self.gravity.into();
        }
        cell.effects = self.effects.iter().map(|s| self.entry_of(s)).collect();
        cell
    }

    fn entry_of(&self, spec: &EffectSpec) -> EffectEntry {
        let mut e = EffectEntry { effect: spec.kind().name().to_string(), ..EffectEntry::default() };
        if let Some(effect) = spec.effect() {
            effect.write_entry(spec, &mut e, self.thermal_reference_c);
        }
        if !spec.kind().is_builtin() {
            for id in spec.params() {
                let v = self.effect_values.get(&id).copied().unwrap_or(0.0);
                e.values.insert(effect_value_key(id), toml::Value::Float(to_file_units(id, v)));
            }
        }
        e
    }

    /// Number of joints N of the chain.
    #[inline]
    pub fn joint_count(&self) -> usize {
        self.n
    }

    /// Kinds of joints 1..=N.
    #[inline]
    pub fn joint_kinds(&self) -> &[JointKind] {
        &self.kinds[..self.n]
    }

    /// Kind of joint `i` (1..=N).
    ///
    /// # Panics
    /// If `i` is not in 1..=N.
    #[track_caller]
    pub fn joint_kind(&self, i: usize) -> JointKind {
        self.joint_kinds()[i - 1]
    }

    /// True when joint `i` (1-based) exists and is revolute.
    #[inline]
    pub fn is_revolute(&self, i: usize) -> bool {
        (1..=self.n).contains(&i) && self.kinds[i - 1].is_revolute()
    }

    /// The joint the guide effects act on (1-based): the first prismatic joint, if any.
    pub fn guide_joint(&self) -> Option<usize> {
        self.guide.map(|g| g + 1)
    }

    /// True for the canonical chain of cell file version 1: 7 joints, a prismatic guide
    /// followed by the six revolute Meca500 joints ([`vatcal_core::canonical::is_canonical_chain`],
    /// the one dispatch predicate of canonical-cell behaviour).
    pub fn is_meca500_on_guide(&self) -> bool {
        vatcal_core::canonical::is_canonical_chain(self.joint_kinds())
    }

    /// `Ok` on the canonical Meca500-on-guide chain; otherwise the error
    /// [`ModelError::NotMeca500OnGuide`] naming `what` needs it.
    pub fn require_meca500_on_guide(&self, what: &str) -> Result<(), ModelError> {
        if self.is_meca500_on_guide() {
            Ok(())
        } else {
            Err(ModelError::NotMeca500OnGuide(what.to_string(), self.describe_chain()))
        }
    }

    /// A short description of the chain, e.g. `6 joints (RRRRRR)` (R revolute, P prismatic).
    pub fn describe_chain(&self) -> String {
        let letters: String =
            self.joint_kinds().iter().map(|k| if k.is_revolute() { 'R' } else { 'P' }).collect();
        format!("{} joints ({letters})", self.n)
    }

    /// `Ok` when `q` has one value per joint.
    pub fn check_joint_count(&self, q: &JointVector) -> Result<(), ModelError> {
        if q.len() == self.n {
            Ok(())
        } else {
            Err(ModelError::JointCount { expected: self.n, got: q.len() })
        }
    }

    /// MDH row `i` (1..=N).
    ///
    /// # Panics
    /// If `i` is not in 1..=N.
    #[track_caller]
    pub fn row(&self, i: usize) -> &MdhRow {
        &self.rows[..self.n][i - 1]
    }

    /// Base pose `[x, y, z] mm, [alpha, beta, gamma] rad`.
    pub fn base_params(&self) -> [f64; 6] {
        self.base
    }

    /// The base frame `H_0^W`.
    pub fn base_frame(&self) -> Frame {
        self.base_frame
    }

    /// Compliance `c_i` of joint `i` (1..=N; 0 for prismatic joints) \[rad/(N·m)\].
    ///
    /// # Panics
    /// If `i` is not in 1..=N.
    #[track_caller]
    pub fn compliance(&self, i: usize) -> f64 {
        self.compliance[..self.n][i - 1]
    }

    /// Joint ranges in internal units (mm for prismatic, rad for revolute joints), index =
    /// joint - 1, one per joint. A continuous joint (no limits) reports one turn
    /// `(-pi, pi)`; see [`Model::joint_limit`] for the limits as given.
    pub fn joint_limits(&self) -> &[(f64, f64)] {
        &self.ranges[..self.n]
    }

    /// Limits of joint `i` (1..=N) in internal units, `None` for a continuous joint (or an
    /// index outside the chain).
    pub fn joint_limit(&self, i: usize) -> Option<(f64, f64)> {
        if (1..=self.n).contains(&i) { self.limits[i - 1] } else { None }
    }

    /// Returns the first joint outside its limits as `(joint, value, min, max)`; continuous
    /// joints are never outside. A joint vector of the wrong length reports the first
    /// missing joint (value NaN).
    pub fn limit_violation(&self, q: &JointVector) -> Option<(usize, f64, f64, f64)> {
        (0..self.n).find_map(|k| {
            let v = q.as_slice().get(k).copied().unwrap_or(f64::NAN);
            match self.limits[k] {
                Some((lo, hi)) => (!(lo..=hi).contains(&v)).then_some((k + 1, v, lo, hi)),
                None => (!v.is_finite()).then_some((k + 1, v, f64::NEG_INFINITY, f64::INFINITY)),
            }
        })
    }

    /// TCP ids in file order.
    pub fn tcp_ids(&self) -> Vec<u32> {
        self.tcps.iter().map(|t| t.0).collect()
    }

    /// Calibration position ids in file order.
    pub fn position_ids(&self) -> Vec<u32> {
        self.positions.iter().map(|t| t.0).collect()
    }

    /// TCP `id` in the tool-changer frame \[mm\].
    pub fn tcp(&self, id: u32) -> Option<Vector3<f64>> {
        self.tcps.iter().find(|t| t.0 == id).map(|t| t.1)
    }

    /// Calibration position `id` in the world \[mm\].
    pub fn position(&self, id: u32) -> Option<Vector3<f64>> {
        self.positions.iter().find(|t| t.0 == id).map(|t| t.1)
    }

    pub(crate) fn tcp_or_err(&self, id: u32) -> Result<Vector3<f64>, ModelError> {
        self.tcp(id).ok_or_else(|| ModelError::UnknownTcp(id, self.tcp_ids()))
    }

    pub(crate) fn position_or_err(&self, id: u32) -> Result<Vector3<f64>, ModelError> {
        self.position(id).ok_or_else(|| ModelError::UnknownPosition(id, self.position_ids()))
    }

    /// Gravity vector in the world \[m/s²\].
    pub fn gravity(&self) -> Vector3<f64> {
        self.gravity
    }

    /// Sets the gravity vector in the world frame [m/s²] (e.g. after the world frame was
    /// re-registered onto an instrument's frame: gravity turns with it, so that its direction
    /// relative to the robot's base stays the same).
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] for a non-finite component.
    pub fn set_gravity(&mut self, g_m_per_s2: Vector3<f64>) -> Result<(), ModelError> {
        if let Some(v) = g_m_per_s2.iter().find(|v| !v.is_finite()) {
            return Err(ModelError::NonFinite("gravity".into(), *v));
        }
        self.gravity = g_m_per_s2;
        self.refresh_caches();
        Ok(())
    }

    /// The mass model used for gravity torques.
    pub fn masses(&self) -> &MassModel {
        &self.masses
    }

    /// Replaces the mass model used for gravity torques and the carriage moment (e.g. a
    /// simulated truth whose masses differ from the nominal estimates).
    pub fn set_masses(&mut self, masses: MassModel) {
        self.masses = masses;
        self.refresh_caches();
    }

    /// Sets the reference temperature \[°C\] of a temperature-driven thermal drift.
    pub fn set_thermal_reference_c(&mut self, t_c: f64) {
        self.thermal_reference_c = t_c;
    }

    /// Effects switched on in this model, in the order they were added.
    pub fn effects(&self) -> &[EffectSpec] {
        &self.effects
    }

    /// Reference temperature \[°C\] of a temperature-driven thermal drift.
    pub fn thermal_reference_c(&self) -> f64 {
        self.thermal_reference_c
    }

    /// Switches an effect on (its parameters start at zero, i.e. the model's predictions do not
    /// change). Built-in effects only record that they belong to the model. Adding an effect
    /// twice is a no-op, and so is adding a lower order of a polynomial effect whose higher
    /// order is on (e.g. `guide-straightness` orders up to 4 when orders up to 8 are on).
    ///
    /// # Errors
    /// [`ModelError::InvalidEffect`] when the instance does not exist on this model (e.g. a joint
    /// index out of range or an effect that needs a joint the chain lacks).
    pub fn enable_effect(&mut self, spec: EffectSpec) -> Result<(), ModelError> {
        let invalid = |m: String| ModelError::InvalidEffect(spec.label(), m);
        let effect = spec.effect().ok_or_else(|| invalid("no such effect is registered".to_string()))?;
        let (tcps, positions) = (self.tcp_ids(), self.position_ids());
        effect.check(&spec, &self.chain_info(&tcps, &positions)).map_err(invalid)?;
        if self.effects.contains(&spec) {
            return Ok(());
        }
        // polynomial effects: a higher order replaces a lower one of the same kind; a lower
        // order than the one on is already part of it (its parameters are a subset)
        if effect.single_instance()
            && let Some(k) = self.effects.iter().position(|e| e.kind() == spec.kind())
        {
            let on = self.effects[k].params();
            if spec.params().iter().all(|p| on.contains(p)) {
                return Ok(());
            }
            self.effects[k] = spec;
        } else {
            self.effects.push(spec);
        }
        if !effect.is_builtin() {
            for id in spec.params() {
                self.effect_values.entry(id).or_insert(0.0);
            }
        }
        // every effect in `effects` passed this function, so it is registered
        self.effect_impls = self.effects.iter().filter_map(|e| e.effect()).collect();
        self.effects_need_moment = self.effect_impls.iter().any(|e| e.needs_carriage_moment());
        self.effects_need_link_moments = self.effect_impls.iter().any(|e| e.needs_link_moments());
        self.effects_need_torques = self.effect_impls.iter().any(|e| e.needs_torques());
        self.refresh_caches();
        Ok(())
    }

    /// What the effect catalog may ask about this chain (`tcps`, `positions`: the model's
    /// TCP and calibration-position ids).
    pub fn chain_info<'a>(&'a self, tcps: &'a [u32], positions: &'a [u32]) -> ChainInfo<'a> {
        ChainInfo {
            kinds: self.joint_kinds(),
            guide: self.guide_joint().map(|g| g as u8),
            tcps,
            positions,
            canonical: self.is_meca500_on_guide(),
            ranges: self.joint_limits(),
        }
    }

    /// True when `id` exists in this model (built-in, or belonging to a switched-on effect).
    pub fn has_param(&self, id: ParamId) -> bool {
        match id {
            ParamId::Alpha(i)
            | ParamId::A(i)
            | ParamId::Beta(i)
            | ParamId::ThetaOffset(i)
            | ParamId::D(i) => (1..=self.n).contains(&(i as usize)),
            ParamId::Compliance(i) => self.is_revolute(i as usize),
            ParamId::Base(_) => true,
            ParamId::Tcp { id, .. } => self.tcp(id).is_some(),
            ParamId::Position { id, .. } => self.position(id).is_some(),
            ParamId::Plane { id, .. } => self.plane(id).is_some(),
            ParamId::Effect(_) => self.effect_values.contains_key(&id),
        }
    }

    /// Value of one parameter (internal units).
    pub fn param(&self, id: ParamId) -> Result<f64, ModelError> {
        let missing = || ModelError::ParamNotInModel(id.name());
        let row = |i: u8| -> Result<&MdhRow, ModelError> {
            self.rows[..self.n].get((i as usize).wrapping_sub(1)).ok_or_else(missing)
        };
        Ok(match id {
            ParamId::Alpha(i) => row(i)?.alpha,
            ParamId::A(i) => row(i)?.a,
            ParamId::Beta(i) => row(i)?.beta,
            ParamId::ThetaOffset(i) => row(i)?.theta_offset,
            ParamId::D(i) => row(i)?.d,
            ParamId::Compliance(i) if self.is_revolute(i as usize) => self.compliance[i as usize - 1],
            ParamId::Compliance(_) => return Err(missing()),
            ParamId::Base(b) => self.base[base_index(b)],
            ParamId::Tcp { id: t, axis } => self.tcp(t).ok_or_else(missing)?[axis.index()],
            ParamId::Position { id: p, axis } => self.position(p).ok_or_else(missing)?[axis.index()],
            ParamId::Plane { id: p, dof } => self.plane(p).ok_or_else(missing)?.dof(dof),
            ParamId::Effect(_) => *self.effect_values.get(&id).ok_or_else(missing)?,
        })
    }

    /// Sets one parameter (internal units).
    ///
    /// # Errors
    /// [`ModelError::ParamNotInModel`] for a parameter the model lacks (an effect that is not
    /// switched on, an unknown TCP or position id); [`ModelError::NonFinite`] for a value that is not
    /// finite.
    pub fn set_param(&mut self, id: ParamId, value: f64) -> Result<(), ModelError> {
        self.assign_param(id, value)?;
        self.refresh_caches();
        Ok(())
    }

    /// Stores one parameter value without refreshing the caches (callers refresh).
    fn assign_param(&mut self, id: ParamId, value: f64) -> Result<(), ModelError> {
        if !value.is_finite() {
            return Err(ModelError::NonFinite(id.name(), value));
        }
        if !self.has_param(id) {
            return Err(ModelError::ParamNotInModel(id.name()));
        }
        match id {
            ParamId::Alpha(i) => self.rows[i as usize - 1].alpha = value,
            ParamId::A(i) => self.rows[i as usize - 1].a = value,
            ParamId::Beta(i) => self.rows[i as usize - 1].beta = value,
            ParamId::ThetaOffset(i) => self.rows[i as usize - 1].theta_offset = value,
            ParamId::D(i) => self.rows[i as usize - 1].d = value,
            ParamId::Compliance(i) => self.compliance[i as usize - 1] = value,
            ParamId::Base(b) => self.base[base_index(b)] = value,
            ParamId::Tcp { id: t, axis } => {
                if let Some(e) = self.tcps.iter_mut().find(|e| e.0 == t) {
                    e.1[axis.index()] = value;
                }
            }
            ParamId::Position { id: p, axis } => {
                if let Some(e) = self.positions.iter_mut().find(|e| e.0 == p) {
                    e.1[axis.index()] = value;
                }
            }
            ParamId::Plane { id: p, dof } => {
                if let Some(e) = self.plane_mut(p) {
                    e.set_dof(dof, value);
                }
            }
            ParamId::Effect(_) => {
                self.effect_values.insert(id, value);
            }
        }
        Ok(())
    }

    /// Values of a parameter set, in order.
    pub fn params(&self, set: &ParamSet) -> Result<Vec<f64>, ModelError> {
        set.iter().map(|p| self.param(*p)).collect()
    }

    /// Sets the values of a parameter set, in order.
    pub fn set_params(&mut self, set: &ParamSet, values: &[f64]) -> Result<(), ModelError> {
        if set.len() != values.len() {
            return Err(ModelError::Length { expected: set.len(), got: values.len() });
        }
        // one cache refresh for the whole set (identification calls this in its inner loop)
        let result = set.iter().zip(values).try_for_each(|(p, v)| self.assign_param(*p, *v));
        self.refresh_caches();
        result
    }

    /// Every parameter this model has: the built-ins and those of switched-on effects.
    pub fn all_params(&self) -> ParamSet {
        let mut s = ParamSet::all_builtin_chain(self.joint_kinds(), &self.tcp_ids(), &self.position_ids());
        for id in self.plane_ids() {
            s.0.extend(vatcal_core::PlaneDof::ALL.iter().map(|dof| ParamId::Plane { id, dof: *dof }));
        }
        s.0.extend(self.effect_values.keys().copied());
        s
    }

    pub(crate) fn refresh_caches(&mut self) {
        self.effect_value_tables = self
            .effects
            .iter()
            .map(|spec| {
                spec.params()
                    .into_iter()
                    .filter_map(|id| match id {
                        ParamId::Effect(p) => Some((p, self.effect_values.get(&id).copied().unwrap_or(0.0))),
                        _ => None,
                    })
                    .collect()
            })
            .collect();
        for (k, row) in self.rows[..self.n].iter().enumerate() {
            self.row_fixed[k] = row_fixed_frame(row);
            self.row_trig[k] = row.alpha.sin_cos();
            self.theta_trig[k] = row.theta_offset.sin_cos();
        }
        self.base_frame = base_frame(&self.base);
        self.gravity_model = GravityModel::new(&self.masses, &self.base_frame.r, &self.gravity);
        self.any_compliance =
            self.compliance[..self.n].iter().zip(&self.kinds).any(|(c, k)| k.is_revolute() && *c != 0.0);
    }

    /// Normalised guide coordinate `u = (q_g - mid) / half_stroke` in [-1, 1] over the stroke
    /// of the guide joint g ([`Model::guide_joint`]); 0 when the chain has no guide.
    pub fn guide_u(&self, q_guide_mm: f64) -> f64 {
        let Some((lo, hi)) = self.guide.and_then(|g| self.limits[g]) else { return 0.0 };
        let half = 0.5 * (hi - lo);
        if half > 0.0 { (q_guide_mm - 0.5 * (hi + lo)) / half } else { 0.0 }
    }

    /// Value of the guide joint in `q` \[mm\] (0 when the chain has no guide).
    #[inline]
    pub(crate) fn guide_q(&self, q: &JointVector) -> f64 {
        self.guide.and_then(|g| q.as_slice().get(g).copied()).unwrap_or(0.0)
    }
}

pub(crate) fn base_index(b: BaseParam) -> usize {
    match b {
        BaseParam::X => 0,
        BaseParam::Y => 1,
        BaseParam::Z => 2,
        BaseParam::Alpha => 3,
        BaseParam::Beta => 4,
        BaseParam::Gamma => 5,
    }
}

fn spec_from_entry(e: &EffectEntry) -> Result<EffectSpec, String> {
    let effect = EffectKind::from_name(&e.effect)
        .and_then(EffectKind::effect)
        .ok_or_else(|| format!("unknown effect `{}`", e.effect))?;
    effect.read_entry(e)
}
