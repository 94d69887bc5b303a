//! Validation of a cell file: every field checked in file order, each error naming the field.

use std::collections::BTreeSet;

use super::tables::{JointRow, MotionLimits, Units};
use super::{CellError, CellFile, FORMAT_NAME, FORMAT_NAME_V2, FORMAT_VERSION, FORMAT_VERSION_V2};
use crate::effects::EffectKind;
use crate::units::{JointKind, MAX_JOINTS};

/// The errors of one validation run: each names the origin (file path or `<string>`) and the
/// field; the line is added by the caller that has the text.
struct Check<'a> {
    origin: &'a str,
}

impl Check<'_> {
    /// An invalid value of `field`.
    fn bad(&self, field: String, reason: String) -> CellError {
        CellError::Invalid { origin: self.origin.to_string(), line: None, field, reason }
    }

    /// `v` must be a finite number.
    fn finite(&self, field: String, v: f64) -> Result<(), CellError> {
        if v.is_finite() { Ok(()) } else { Err(self.bad(field, format!("must be a finite number, got {v}"))) }
    }
}

impl CellFile {
    /// Checks every field. Errors name the field.
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::CellFile;
    ///
    /// let mut cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-table.toml"))?;
    /// cell.joints[0].q_max = Some(-500.0); // below q_min
    /// let e = cell.validate("edited.toml").expect_err("empty joint range");
    /// assert!(e.to_string().starts_with("edited.toml"), "{e}");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`CellError::Invalid`] naming `origin` and the first field that is wrong (a wrong format
    /// or version, joint rows that are not 1..N, limits, TCP and position ids, inertials,
    /// effects that do not fit the chain, ...).
    pub fn validate(&self, origin: &str) -> Result<(), CellError> {
        let c = Check { origin };
        let v2 = self.check_format(&c)?;
        self.check_units(&c)?;
        let n_expected = self.check_joint_rows(&c, v2)?;
        for j in &self.joints {
            check_joint(&c, j, v2)?;
        }
        self.check_base(&c)?;
        self.check_points(&c)?;
        self.check_planes(&c)?;
        for (k, v) in self.gravity.vector_m_per_s2.iter().enumerate() {
            c.finite(format!("gravity.vector_m_per_s2[{k}]"), *v)?;
        }
        self.check_links(&c, v2)?;
        self.check_tool(&c, n_expected)?;
        if let Some(m) = &self.motion {
            check_motion(&c, m)?;
        }
        self.check_effects(&c)?;
        if let Some(range) = &self.training_range {
            range.check(self.joints.len()).map_err(|(field, reason)| c.bad(field, reason))?;
        }
        Ok(())
    }

    /// `format` and `version` (one of the two known pairs) and `[robot]` (version 2 only).
    /// Returns true for version 2.
    fn check_format(&self, c: &Check<'_>) -> Result<bool, CellError> {
        let v2 = match self.format.as_str() {
            FORMAT_NAME => false,
            FORMAT_NAME_V2 => true,
            other => {
                return Err(c.bad(
                    "format".into(),
                    format!(
                        "expected \"{FORMAT_NAME}\" (version 1) or \"{FORMAT_NAME_V2}\" (version 2), got \"{other}\""
                    ),
                ));
            }
        };
        let want_version = if v2 { FORMAT_VERSION_V2 } else { FORMAT_VERSION };
        if self.version != want_version {
            return Err(c.bad(
                "version".into(),
                format!(
                    "unsupported version {} for format \"{}\" (this vatcal reads \"{FORMAT_NAME}\" version {FORMAT_VERSION} and \"{FORMAT_NAME_V2}\" version {FORMAT_VERSION_V2})",
                    self.version, self.format
                ),
            ));
        }
        if !v2 && self.robot.is_some() {
            return Err(c.bad("robot".into(), "the [robot] table needs format version 2".into()));
        }
        Ok(v2)
    }

    /// `[units]`: exactly the canonical units.
    fn check_units(&self, c: &Check<'_>) -> Result<(), CellError> {
        let u = Units::default();
        for (name, got, want) in [
            ("units.length", &self.units.length, &u.length),
            ("units.angle", &self.units.angle, &u.angle),
            ("units.mass", &self.units.mass, &u.mass),
            ("units.compliance", &self.units.compliance, &u.compliance),
            ("units.gravity", &self.units.gravity, &u.gravity),
        ] {
            if got != want {
                return Err(c.bad(name.into(), format!("expected \"{want}\", got \"{got}\"")));
            }
        }
        Ok(())
    }

    /// The joint rows' indices: 1..=N, each once (N = 7 in version 1, 1..=[`MAX_JOINTS`] in
    /// version 2). Returns the expected N.
    fn check_joint_rows(&self, c: &Check<'_>, v2: bool) -> Result<usize, CellError> {
        let n = self.joints.len();
        if v2 && !(1..=MAX_JOINTS).contains(&n) {
            return Err(c.bad(
                "joints".into(),
                format!("a serial chain has 1..={MAX_JOINTS} [[joints]] rows, got {n}"),
            ));
        }
        let n_expected = if v2 { n } else { 7 };
        let mut seen = BTreeSet::new();
        for (k, j) in self.joints.iter().enumerate() {
            if !(1..=n_expected).contains(&(j.index as usize)) {
                let why = if v2 {
                    format!("must be 1..={n} (rows are numbered contiguously from 1), got {}", j.index)
                } else {
                    format!("must be 1..=7, got {}", j.index)
                };
                return Err(c.bad(format!("joints[{k}].index"), why));
            }
            if !seen.insert(j.index) {
                return Err(c.bad(format!("joints[{k}].index"), format!("duplicate joint row {}", j.index)));
            }
        }
        for i in 1..=n_expected as u8 {
            if !seen.contains(&i) {
                return Err(c.bad("joints".into(), format!("missing [[joints]] row with index = {i}")));
            }
        }
        Ok(n_expected)
    }

    /// `[base_in_world]`: finite, and away from the XYZ-angle singularity.
    fn check_base(&self, c: &Check<'_>) -> Result<(), CellError> {
        let b = &self.base_in_world;
        for (name, v) in [
            ("x_mm", b.x_mm),
            ("y_mm", b.y_mm),
            ("z_mm", b.z_mm),
            ("alpha_deg", b.alpha_deg),
            ("beta_deg", b.beta_deg),
            ("gamma_deg", b.gamma_deg),
        ] {
            c.finite(format!("base_in_world.{name}"), v)?;
        }
        if (b.beta_deg.abs() - 90.0).abs() < 1.0 {
            return Err(c.bad(
                "base_in_world.beta_deg".into(),
                format!(
                    "{} is within 1 deg of the XYZ-angle singularity at +-90 deg; re-express the base pose",
                    b.beta_deg
                ),
            ));
        }
        Ok(())
    }

    /// `[[tcps]]` and `[[calibration_positions]]`: at least one each, unique ids, finite.
    fn check_points(&self, c: &Check<'_>) -> Result<(), CellError> {
        for (table, list) in [("tcps", &self.tcps), ("calibration_positions", &self.calibration_positions)] {
            if list.is_empty() {
                return Err(c.bad(table.into(), "at least one entry is required".into()));
            }
            let mut ids = BTreeSet::new();
            for (k, p) in list.iter().enumerate() {
                if !ids.insert(p.id) {
                    return Err(c.bad(format!("{table}[{k}].id"), format!("duplicate id {}", p.id)));
                }
                for (name, v) in [("x_mm", p.x_mm), ("y_mm", p.y_mm), ("z_mm", p.z_mm)] {
                    c.finite(format!("{table}[id={}].{name}", p.id), v)?;
                }
            }
        }
        Ok(())
    }

    /// `[[planes]]`: unique ids, a finite non-zero normal, a finite offset, a positive
    /// contact radius.
    fn check_planes(&self, c: &Check<'_>) -> Result<(), CellError> {
        let mut ids = BTreeSet::new();
        for (k, p) in self.planes.iter().enumerate() {
            if !ids.insert(p.id) {
                return Err(c.bad(format!("planes[{k}].id"), format!("duplicate id {}", p.id)));
            }
            for v in p.normal {
                c.finite(format!("planes[id={}].normal", p.id), v)?;
            }
            if p.normal.iter().map(|v| v * v).sum::<f64>().sqrt() < 1e-9 {
                return Err(c.bad(format!("planes[id={}].normal", p.id), "must not be zero".into()));
            }
            c.finite(format!("planes[id={}].offset_mm", p.id), p.offset_mm)?;
            if let Some(r) = p.contact_radius_mm
                && !(r.is_finite() && r > 0.0)
            {
                return Err(
                    c.bad(format!("planes[id={}].contact_radius_mm", p.id), format!("must be > 0, got {r}"))
                );
            }
        }
        Ok(())
    }

    /// `[[inertials.links]]`: on moving frames of the chain, each once, finite non-negative
    /// masses.
    fn check_links(&self, c: &Check<'_>, v2: bool) -> Result<(), CellError> {
        let n = self.joints.len();
        let mut frames = BTreeSet::new();
        for (k, l) in self.inertials.links.iter().enumerate() {
            if v2 && !(1..=n).contains(&(l.frame as usize)) {
                return Err(c.bad(
                    format!("inertials.links[{k}].frame"),
                    format!("must be a moving frame 1..={n} of this chain, got {}", l.frame),
                ));
            }
            if !v2 && !(2..=7).contains(&l.frame) {
                return Err(c.bad(
                    format!("inertials.links[{k}].frame"),
                    format!("must be 2..=7 (moving Meca500 links), got {}", l.frame),
                ));
            }
            if !frames.insert(l.frame) {
                return Err(
                    c.bad(format!("inertials.links[{k}].frame"), format!("duplicate frame {}", l.frame))
                );
            }
            c.finite(format!("inertials.links[frame={}].mass_kg", l.frame), l.mass_kg)?;
            if l.mass_kg < 0.0 {
                return Err(c.bad(
                    format!("inertials.links[frame={}].mass_kg", l.frame),
                    format!("negative mass {}", l.mass_kg),
                ));
            }
            for (k, v) in l.com_mm.iter().enumerate() {
                c.finite(format!("inertials.links[frame={}].com_mm[{k}]", l.frame), *v)?;
            }
        }
        Ok(())
    }

    /// `[inertials.tool]`: on the last frame, finite non-negative mass.
    fn check_tool(&self, c: &Check<'_>, n_expected: usize) -> Result<(), CellError> {
        let t = &self.inertials.tool;
        if t.frame as usize != n_expected {
            return Err(c.bad(
                "inertials.tool.frame".into(),
                format!("the tool is attached to the last frame {n_expected}, got {}", t.frame),
            ));
        }
        c.finite("inertials.tool.mass_kg".into(), t.mass_kg)?;
        if t.mass_kg < 0.0 {
            return Err(c.bad("inertials.tool.mass_kg".into(), format!("negative mass {}", t.mass_kg)));
        }
        for (k, v) in t.com_mm.iter().enumerate() {
            c.finite(format!("inertials.tool.com_mm[{k}]"), *v)?;
        }
        Ok(())
    }

    /// `[[effects]]`: known catalog names, finite values.
    fn check_effects(&self, c: &Check<'_>) -> Result<(), CellError> {
        for (k, e) in self.effects.iter().enumerate() {
            if EffectKind::from_name(&e.effect).is_none() {
                let names: Vec<&str> = EffectKind::ALL.iter().map(|k| k.name()).collect();
                return Err(c.bad(
                    format!("effects[{k}].effect"),
                    format!("unknown effect \"{}\" (known: {})", e.effect, names.join(", ")),
                ));
            }
            for (key, v) in &e.values {
                match v.as_float().or_else(|| v.as_integer().map(|i| i as f64)) {
                    Some(x) if x.is_finite() => {}
                    _ => {
                        return Err(
                            c.bad(format!("effects[{k}].values.{key}"), "must be a finite number".into())
                        );
                    }
                }
            }
        }
        Ok(())
    }
}

/// One `[[joints]]` row: a known kind (version 1: the guide then six revolute joints, with
/// names), finite values, limits in order (optional only on a version-2 revolute joint) and no
/// compliance on a prismatic joint.
fn check_joint(c: &Check<'_>, j: &JointRow, v2: bool) -> Result<(), CellError> {
    let f = |name: &str| format!("joints[index={}].{name}", j.index);
    let Some(kind) = j.joint_kind() else {
        return Err(c.bad(
            f("kind"),
            format!("unknown joint kind \"{}\" (expected \"prismatic\" or \"revolute\")", j.kind),
        ));
    };
    if !v2 {
        check_v1_joint(c, j, kind)?;
    }
    for (name, v) in [
        ("alpha_deg", j.alpha_deg),
        ("a_mm", j.a_mm),
        ("beta_deg", j.beta_deg),
        ("theta_deg", j.theta_deg),
        ("d_mm", j.d_mm),
        ("q_min", j.q_min.unwrap_or(0.0)),
        ("q_max", j.q_max.unwrap_or(0.0)),
        ("compliance_rad_per_n_m", j.compliance_rad_per_n_m),
    ] {
        c.finite(f(name), v)?;
    }
    check_limits(c, j, kind, v2)?;
    if v2 && kind == JointKind::Prismatic && j.compliance_rad_per_n_m != 0.0 {
        return Err(c.bad(
            f("compliance_rad_per_n_m"),
            format!(
                "joint compliance applies to revolute joints only; prismatic joint {} has {}",
                j.index, j.compliance_rad_per_n_m
            ),
        ));
    }
    Ok(())
}

/// A version-1 row: joint 1 prismatic (the guide), 2..7 revolute, each named.
fn check_v1_joint(c: &Check<'_>, j: &JointRow, kind: JointKind) -> Result<(), CellError> {
    let f = |name: &str| format!("joints[index={}].{name}", j.index);
    let expected = if j.index == 1 { JointKind::Prismatic } else { JointKind::Revolute };
    if kind != expected {
        return Err(c.bad(
            f("kind"),
            format!(
                "joint {} must be {expected} in this cell (joint 1 is the linear guide, 2..7 the Meca500), got \"{}\"; use format \"{FORMAT_NAME_V2}\" version 2 for other chains",
                j.index, j.kind
            ),
        ));
    }
    if j.name.is_empty() {
        return Err(c.bad(f("name"), "missing joint name (required in version 1)".into()));
    }
    Ok(())
}

/// A row's limits: in order, and both present (or, on a version-2 revolute joint, both absent:
/// a continuous joint).
fn check_limits(c: &Check<'_>, j: &JointRow, kind: JointKind, v2: bool) -> Result<(), CellError> {
    let f = |name: &str| format!("joints[index={}].{name}", j.index);
    let limits_optional = v2 && kind == JointKind::Revolute;
    match (j.q_min, j.q_max) {
        (Some(lo), Some(hi)) if lo > hi => {
            Err(c.bad(f("q_min"), format!("q_min ({lo}) > q_max ({hi}): limits inverted")))
        }
        (Some(_), Some(_)) => Ok(()),
        (None, None) if limits_optional => Ok(()),
        (lo, _) => {
            let missing = if lo.is_none() { "q_min" } else { "q_max" };
            let why = if limits_optional {
                "give both q_min and q_max, or neither for a continuous joint".to_string()
            } else if v2 {
                "a prismatic joint needs q_min and q_max (mm)".to_string()
            } else {
                "required in version 1".to_string()
            };
            Err(c.bad(f(missing), format!("missing joint limit: {why}")))
        }
    }
}

/// `[motion]`: positive speeds and times, a speed fraction in (0, 1].
fn check_motion(c: &Check<'_>, m: &MotionLimits) -> Result<(), CellError> {
    for (k, v) in m.joint_speed_deg_per_s.iter().enumerate() {
        if !(v.is_finite() && *v > 0.0) {
            return Err(c.bad(format!("motion.joint_speed_deg_per_s[{k}]"), format!("must be > 0, got {v}")));
        }
    }
    for (name, v) in [
        ("guide_speed_mm_per_s", m.guide_speed_mm_per_s),
        ("measurement_s", m.measurement_s + 1.0),
        ("probe_replacement_s", m.probe_replacement_s + 1.0),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(c.bad(format!("motion.{name}"), "must be a positive finite number".into()));
        }
    }
    if !(m.speed_fraction > 0.0 && m.speed_fraction <= 1.0) {
        return Err(
            c.bad("motion.speed_fraction".into(), format!("must be in (0, 1], got {}", m.speed_fraction))
        );
    }
    Ok(())
}
