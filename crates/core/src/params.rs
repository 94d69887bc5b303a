//! Stable, human-readable parameter identifiers and named parameter sets.
//!
//! Naming follows the paper's subscripts. MDH row `i` (1..=N, N <= [`MAX_JOINTS`]; the
//! transform from frame i-1 to frame i) carries `alpha_{i-1}`, `a_{i-1}`, `beta_{i-1}`, `theta_offset_i` and `d_i`:
//!
//! | identifier | name | unit inside vatcal |
//! |---|---|---|
//! | `ParamId::Alpha(i)` | `alpha_{i-1}` | rad |
//! | `ParamId::A(i)` | `a_{i-1}` | mm |
//! | `ParamId::Beta(i)` | `beta_{i-1}` | rad |
//! | `ParamId::ThetaOffset(i)` | `theta_offset_i` | rad |
//! | `ParamId::D(i)` | `d_i` (row 1: the guide offset `d_OFS,1`) | mm |
//! | `ParamId::Compliance(i)` | `c_i` of a revolute joint i (2..7 on the canonical cell) | rad/(N·m) |
//! | `ParamId::Base(..)` | `base_x`, `base_y`, `base_z` (mm), `base_alpha`, `base_beta`, `base_gamma` (rad) | |
//! | `ParamId::Tcp{id, axis}` | `tcp{id}_{x,y,z}` | mm |
//! | `ParamId::Position{id, axis}` | `position{id}_{x,y,z}` | mm |
//! | `ParamId::Plane{id, dof}` | `plane{id}_tilt_u`, `plane{id}_tilt_v` (rad), `plane{id}_offset` (mm) | |
//! | `ParamId::Effect(..)` | see [`EffectParam`] | see there |
//!
//! Names round-trip: `ParamId::from_name(&p.name()) == Some(p)`.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::effects::catalog;
use crate::units::{JointKind, MAX_JOINTS};
pub use crate::vocabulary::{Axis, BaseParam, EffectParam, ParamId, ParamUnit, PlaneDof, ToolFrameDof};

impl ParamId {
    /// The stable name (e.g. `alpha_1`, `theta_offset_2`, `c_4`, `base_gamma`, `tcp2_z`).
    pub fn name(&self) -> String {
        match *self {
            ParamId::Alpha(i) => format!("alpha_{}", i - 1),
            ParamId::A(i) => format!("a_{}", i - 1),
            ParamId::Beta(i) => format!("beta_{}", i - 1),
            ParamId::ThetaOffset(i) => format!("theta_offset_{i}"),
            ParamId::D(i) => format!("d_{i}"),
            ParamId::Compliance(i) => format!("c_{i}"),
            ParamId::Base(b) => format!("base_{}", b.suffix()),
            ParamId::Tcp { id, axis } => format!("tcp{id}_{}", axis.letter()),
            ParamId::Position { id, axis } => format!("position{id}_{}", axis.letter()),
            ParamId::Plane { id, dof } => format!("plane{id}_{}", dof.suffix()),
            ParamId::Effect(e) => match e.kind().effect() {
                Some(effect) => effect.param_name(&e),
                None => format!("{e:?}"),
            },
        }
    }

    /// Parses a name produced by [`ParamId::name`]. Returns `None` for unknown names.
    pub fn from_name(name: &str) -> Option<ParamId> {
        let row = |s: &str, shift: u8| -> Option<u8> {
            let v: u8 = s.parse().ok()?;
            let r = v.checked_add(shift)?;
            (1..=MAX_JOINTS as u8).contains(&r).then_some(r)
        };
        if let Some(s) = name.strip_prefix("alpha_") {
            return row(s, 1).map(ParamId::Alpha);
        }
        if let Some(s) = name.strip_prefix("beta_") {
            return row(s, 1).map(ParamId::Beta);
        }
        if let Some(s) = name.strip_prefix("theta_offset_") {
            return row(s, 0).map(ParamId::ThetaOffset);
        }
        if let Some(s) = name.strip_prefix("a_") {
            return row(s, 1).map(ParamId::A);
        }
        if let Some(s) = name.strip_prefix("d_") {
            return row(s, 0).map(ParamId::D);
        }
        if let Some(s) = name.strip_prefix("c_") {
            return row(s, 0).map(ParamId::Compliance);
        }
        if let Some(s) = name.strip_prefix("base_") {
            return BaseParam::ALL.iter().find(|b| b.suffix() == s).map(|b| ParamId::Base(*b));
        }
        if let Some(s) = name.strip_prefix("tcp") {
            let (id, ax) = s.split_once('_')?;
            return Some(ParamId::Tcp { id: id.parse().ok()?, axis: Axis::from_letter(ax)? });
        }
        if let Some(s) = name.strip_prefix("position") {
            let (id, ax) = s.split_once('_')?;
            return Some(ParamId::Position { id: id.parse().ok()?, axis: Axis::from_letter(ax)? });
        }
        if let Some(s) = name.strip_prefix("plane") {
            let (id, dof) = s.split_once('_')?;
            let dof = PlaneDof::ALL.into_iter().find(|d| d.suffix() == dof)?;
            return Some(ParamId::Plane { id: id.parse().ok()?, dof });
        }
        catalog().iter().find_map(|e| e.parse_param(name)).map(ParamId::Effect)
    }

    /// The physical unit of the parameter inside vatcal.
    pub fn unit(&self) -> ParamUnit {
        match self {
            ParamId::Alpha(_) | ParamId::Beta(_) | ParamId::ThetaOffset(_) => ParamUnit::Rad,
            ParamId::A(_) | ParamId::D(_) => ParamUnit::Mm,
            ParamId::Compliance(_) => ParamUnit::RadPerNm,
            ParamId::Base(b) => match b {
                BaseParam::X | BaseParam::Y | BaseParam::Z => ParamUnit::Mm,
                _ => ParamUnit::Rad,
            },
            ParamId::Tcp { .. } | ParamId::Position { .. } => ParamUnit::Mm,
            ParamId::Plane { dof: PlaneDof::Offset, .. } => ParamUnit::Mm,
            ParamId::Plane { .. } => ParamUnit::Rad,
            ParamId::Effect(e) => e.kind().effect().map_or(ParamUnit::Ratio, |effect| effect.param_unit(e)),
        }
    }

    /// A typical a-priori standard deviation of the parameter's *error*, in internal units.
    /// Used for column scaling and as a default prior (background.md §6.3).
    pub fn typical_scale(&self) -> f64 {
        match self.unit() {
            ParamUnit::Mm => match self {
                ParamId::Base(_) | ParamId::Plane { .. } => 1.0,
                _ => 0.1,
            },
            ParamUnit::Rad => match self {
                ParamId::Base(_) | ParamId::Plane { .. } => 1e-2,
                _ => 1e-3,
            },
            ParamUnit::RadPerNm => 1e-4,
            ParamUnit::RadPerNm2 => 1e-5,
            ParamUnit::Ratio => 1e-4,
            ParamUnit::PerSecond => 1e-8,
            ParamUnit::PerKelvin => 2.3e-5,
        }
    }
}

impl fmt::Display for ParamId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

/// An ordered list of parameters (the columns of a Jacobian, the unknowns of a fit).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ParamSet(pub Vec<ParamId>);

/// Error when a parameter-set specification cannot be parsed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ParamSetError {
    /// a name in a comma-separated list is not a known parameter
    #[error(
        "unknown parameter name `{0}` (examples of valid names: alpha_1, a_2, d_4, theta_offset_2, beta_3, c_2, base_x, tcp1_x, position2_z, cyclic4_h1_sin)"
    )]
    UnknownName(String),
    /// a parameter appears twice
    #[error("parameter `{0}` is listed twice")]
    Duplicate(String),
    /// empty list
    #[error("the parameter list is empty")]
    Empty,
}

impl ParamSet {
    /// The paper's 34 identifiable parameters, in the order of Eq. (7):
    /// alpha_1..6, a_2..6, d_4..7, theta_offset_2..7, beta_3, c_2..7, base pose.
    pub fn paper34() -> Self {
        let mut v = Vec::with_capacity(34);
        v.extend((2..=7).map(ParamId::Alpha)); // alpha_1..alpha_6
        v.extend((3..=7).map(ParamId::A)); // a_2..a_6
        v.extend((4..=7).map(ParamId::D)); // d_4..d_7
        v.extend((2..=7).map(ParamId::ThetaOffset));
        v.push(ParamId::Beta(4)); // beta_3
        v.extend((2..=7).map(ParamId::Compliance));
        v.extend(BaseParam::ALL.iter().map(|b| ParamId::Base(*b)));
        Self(v)
    }

    /// The paper's 28 geometric parameters (paper34 without the compliances).
    pub fn geometric() -> Self {
        Self(Self::paper34().0.into_iter().filter(|p| !matches!(p, ParamId::Compliance(_))).collect())
    }

    /// Every built-in parameter of the canonical Meca500-on-guide cell: the 5 MDH values of
    /// all 7 rows, c_2..c_7, the base pose, and the coordinates of the given TCPs and
    /// calibration positions. [`ParamSet::all_builtin_chain`] does the same for any chain.
    pub fn all_builtin(tcp_ids: &[u32], position_ids: &[u32]) -> Self {
        use JointKind::{Prismatic, Revolute};
        Self::all_builtin_chain(
            &[Prismatic, Revolute, Revolute, Revolute, Revolute, Revolute, Revolute],
            tcp_ids,
            position_ids,
        )
    }

    /// Every built-in parameter of a chain with joints `kinds` (1..=N): the 5 MDH values of
    /// every row, `c_i` of every revolute joint, the base pose, and the coordinates of the
    /// given TCPs and calibration positions.
    pub fn all_builtin_chain(kinds: &[JointKind], tcp_ids: &[u32], position_ids: &[u32]) -> Self {
        let mut v = Vec::new();
        for i in 1..=kinds.len().min(MAX_JOINTS) as u8 {
            v.extend([
                ParamId::Alpha(i),
                ParamId::A(i),
                ParamId::Beta(i),
                ParamId::ThetaOffset(i),
                ParamId::D(i),
            ]);
        }
        v.extend(
            kinds
                .iter()
                .take(MAX_JOINTS)
                .enumerate()
                .filter(|(_, k)| k.is_revolute())
                .map(|(k, _)| ParamId::Compliance(k as u8 + 1)),
        );
        v.extend(BaseParam::ALL.iter().map(|b| ParamId::Base(*b)));
        for id in tcp_ids {
            v.extend(Axis::ALL.iter().map(|a| ParamId::Tcp { id: *id, axis: *a }));
        }
        for id in position_ids {
            v.extend(Axis::ALL.iter().map(|a| ParamId::Position { id: *id, axis: *a }));
        }
        Self(v)
    }

    /// Parses `paper34`, `geometric`, or a comma-separated list of parameter names.
    /// (`all-identifiable` needs data and is resolved by the observability crate.)
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::{ParamId, ParamSet};
    ///
    /// assert_eq!(ParamSet::parse("paper34")?.len(), 34);
    /// let set = ParamSet::parse("a_2, theta_offset_3, base_x")?;
    /// assert_eq!(set.0[1], ParamId::ThetaOffset(3));
    /// assert!(ParamSet::parse("a_2, a_2").is_err());
    /// # Ok::<(), vatcal_core::params::ParamSetError>(())
    /// ```
    ///
    /// # Errors
    /// [`ParamSetError::UnknownName`], [`ParamSetError::Duplicate`], [`ParamSetError::Empty`].
    pub fn parse(spec: &str) -> Result<Self, ParamSetError> {
        match spec.trim() {
            "paper34" => return Ok(Self::paper34()),
            "geometric" => return Ok(Self::geometric()),
            _ => {}
        }
        let mut v: Vec<ParamId> = Vec::new();
        for raw in spec.split(',') {
            let name = raw.trim();
            if name.is_empty() {
                continue;
            }
            let id = ParamId::from_name(name).ok_or_else(|| ParamSetError::UnknownName(name.to_string()))?;
            if v.contains(&id) {
                return Err(ParamSetError::Duplicate(name.to_string()));
            }
            v.push(id);
        }
        if v.is_empty() {
            return Err(ParamSetError::Empty);
        }
        Ok(Self(v))
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Iterator over the ids.
    pub fn iter(&self) -> std::slice::Iter<'_, ParamId> {
        self.0.iter()
    }

    /// Position of `id` in the set.
    pub fn index_of(&self, id: ParamId) -> Option<usize> {
        self.0.iter().position(|p| *p == id)
    }

    /// Names of all parameters, in order.
    pub fn names(&self) -> Vec<String> {
        self.0.iter().map(|p| p.name()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper34_has_34_unique_params_with_paper_names() {
        let s = ParamSet::paper34();
        assert_eq!(s.len(), 34);
        let names = s.names();
        for n in [
            "alpha_1",
            "alpha_6",
            "a_2",
            "a_6",
            "d_4",
            "d_7",
            "theta_offset_2",
            "beta_3",
            "c_2",
            "c_7",
            "base_gamma",
        ] {
            assert!(names.contains(&n.to_string()), "{n} missing");
        }
        let mut sorted = s.0.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), 34);
        assert_eq!(ParamSet::geometric().len(), 28);
    }

    #[test]
    fn all_builtin_follows_the_joint_kinds() {
        use JointKind::{Prismatic as P, Revolute as R};
        let s = ParamSet::all_builtin_chain(&[R, R, P, R], &[1], &[]);
        assert_eq!(s.len(), 4 * 5 + 3 + 6 + 3);
        assert!(s.index_of(ParamId::Compliance(1)).is_some());
        assert!(s.index_of(ParamId::Compliance(3)).is_none(), "no compliance on a prismatic joint");
        assert_eq!(ParamSet::all_builtin(&[1], &[2]).len(), 7 * 5 + 6 + 6 + 3 + 3);
    }

    #[test]
    fn names_round_trip() {
        let mut all = ParamSet::all_builtin(&[1, 2, 3], &[1, 2, 3]).0;
        for j in 2..=7 {
            all.push(ParamId::Effect(EffectParam::CyclicSin { joint: j, harmonic: 2 }));
            all.push(ParamId::Effect(EffectParam::CyclicCos { joint: j, harmonic: 1 }));
            all.push(ParamId::Effect(EffectParam::JointScale { joint: j }));
            all.push(ParamId::Effect(EffectParam::Backlash { joint: j }));
        }
        for a in Axis::ALL {
            all.push(ParamId::Effect(EffectParam::GuideAngular { axis: a, order: 2 }));
        }
        all.push(ParamId::Effect(EffectParam::GuideStraightness { axis: Axis::Y, order: 2 }));
        all.push(ParamId::Effect(EffectParam::GuideScale));
        all.push(ParamId::Effect(EffectParam::CarriageTilt { axis: Axis::X }));
        all.push(ParamId::Effect(EffectParam::CarriageTilt { axis: Axis::Y }));
        all.extend(ToolFrameDof::ALL.iter().map(|d| ParamId::Effect(EffectParam::ToolFrame(*d))));
        all.push(ParamId::Effect(EffectParam::ThermalPerSecond));
        all.push(ParamId::Effect(EffectParam::ThermalPerKelvin));
        for p in all {
            assert_eq!(ParamId::from_name(&p.name()), Some(p), "{}", p.name());
        }
    }

    #[test]
    fn parse_lists_and_errors() {
        assert_eq!(ParamSet::parse("paper34").map(|s| s.len()), Ok(34));
        assert_eq!(ParamSet::parse("alpha_1, d_4").map(|s| s.len()), Ok(2));
        assert!(matches!(ParamSet::parse("alpha_12"), Err(ParamSetError::UnknownName(_))));
        assert_eq!(ParamSet::parse("alpha_11").map(|s| s.0), Ok(vec![ParamId::Alpha(12)]));
        assert!(matches!(ParamSet::parse("d_4,d_4"), Err(ParamSetError::Duplicate(_))));
        assert!(matches!(ParamSet::parse(" , "), Err(ParamSetError::Empty)));
        assert_eq!(ParamId::from_name("c_1"), Some(ParamId::Compliance(1)));
        assert_eq!(ParamId::from_name("c_13"), None);
        assert_eq!(ParamId::from_name("c_0"), None);
    }
}
