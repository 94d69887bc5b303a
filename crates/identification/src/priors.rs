//! Realistic prior widths per parameter kind: what a MAP fit of a robot's parameters is
//! regularised with (issue 29).
//!
//! A prior is a Gaussian centred on the starting (nominal) value with a standard deviation per
//! **kind** of parameter — the size of the error such a parameter has on real robots, not the
//! resolution of the fit. At scale ×1 ([`PriorWidths::realistic`]):
//!
//! | kind (`--prior` name) | parameters | width at ×1 | where it comes from |
//! |---|---|---|---|
//! | `theta_offset` | joint-zero offset of a revolute joint | 10 mrad (0.57°) | MUKCa authors' calibrated Panda URDFs: 3–14 mrad; encoder-index / mastering errors of service robots reach tens of mrad |
//! | `prismatic_offset` | zero of a prismatic joint (`d_i`) | 1 mm | homing-switch repeatability and mounting of linear axes |
//! | `length` | MDH `a`, `d` of revolute rows | 1 mm | machining + assembly of links; URDF values rounded to the mm; MUKCa Panda calibrations: 0.1–3 mm |
//! | `alpha` | MDH twist `alpha` | 3 mrad (0.17°) | bearing-seat parallelism of cast/machined links; MUKCa Panda calibrations: 1–4 mrad |
//! | `beta` | Hayati tilt `beta` | 3 mrad | as `alpha` (the same machining tolerance about the other axis) |
//! | `compliance` | `c_i` | 2 mrad deflection at the joint's largest gravity torque in the data (at least 10 % of the chain's largest) | harmonic-drive stiffness 10⁴–10⁵ N·m/rad under the gravity torques of light arms: 0.1–5 mrad |
//! | `effect` | parameters of catalog effects | 10 × the parameter's typical size | `ParamId::typical_scale` |
//! | `base`, `tcp`, `position` | instrument frame, markers, fixed points | free (∞) | unknown by construction |
//!
//! A prior scale `k` multiplies every width ([`PriorSpec::scale`]); cross-validation chooses it
//! on a wide grid (0.1 … 30: 0.1 mm / 0.3 mrad … 30 mm / 0.3 rad). Per-kind overrides
//! ([`PriorSpec::with_override`], `--prior theta_offset=50mrad`) replace the width at ×1.

use std::fmt;
use std::str::FromStr;

use vatcal_core::{Measurement, ParamId, ParamSet};
use vatcal_kinematics::Model;

/// A kind of parameter that shares one prior width.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PriorKind {
    /// `theta_offset_i` of a revolute joint \[rad\]
    ThetaOffset,
    /// `d_i` of a prismatic joint (its zero) \[mm\]
    PrismaticOffset,
    /// MDH lengths `a_i`, `d_i` of revolute rows \[mm\]
    Length,
    /// MDH twist `alpha_i` \[rad\]
    Alpha,
    /// Hayati tilt `beta_i` \[rad\]
    Beta,
    /// joint compliance `c_i`, given as the deflection \[rad\] at the joint's largest gravity
    /// torque over the data's postures
    Compliance,
    /// catalog effect parameters, in multiples of their typical size
    Effect,
    /// base pose (the instrument or world frame) and contact planes (offsets in mm, tilts
    /// at the width / 1000 mm in rad)
    Base,
    /// TCP / marker coordinates \[mm\]
    Tcp,
    /// fixed-point coordinates \[mm\]
    Position,
}

impl PriorKind {
    /// Every kind, in the order of the report.
    pub const ALL: [PriorKind; 10] = [
        PriorKind::ThetaOffset,
        PriorKind::PrismaticOffset,
        PriorKind::Length,
        PriorKind::Alpha,
        PriorKind::Beta,
        PriorKind::Compliance,
        PriorKind::Effect,
        PriorKind::Base,
        PriorKind::Tcp,
        PriorKind::Position,
    ];

    /// The kind of `p` on `model` (a `d_i` is a prismatic joint's zero when joint i is
    /// prismatic, a length otherwise).
    pub fn of(p: ParamId, model: &Model) -> Self {
        match p {
            ParamId::ThetaOffset(_) => PriorKind::ThetaOffset,
            ParamId::D(i) if !model.is_revolute(i as usize) => PriorKind::PrismaticOffset,
            ParamId::A(_) | ParamId::D(_) => PriorKind::Length,
            ParamId::Alpha(_) => PriorKind::Alpha,
            ParamId::Beta(_) => PriorKind::Beta,
            ParamId::Compliance(_) => PriorKind::Compliance,
            ParamId::Effect(_) => PriorKind::Effect,
            // a contact plane is a fixture of the world frame, like the base pose
            ParamId::Base(_) | ParamId::Plane { .. } => PriorKind::Base,
            ParamId::Tcp { .. } => PriorKind::Tcp,
            ParamId::Position { .. } => PriorKind::Position,
        }
    }

    /// The name used by `--prior NAME=VALUE` and in the reports.
    pub fn name(self) -> &'static str {
        match self {
            PriorKind::ThetaOffset => "theta_offset",
            PriorKind::PrismaticOffset => "prismatic_offset",
            PriorKind::Length => "length",
            PriorKind::Alpha => "alpha",
            PriorKind::Beta => "beta",
            PriorKind::Compliance => "compliance",
            PriorKind::Effect => "effect",
            PriorKind::Base => "base",
            PriorKind::Tcp => "tcp",
            PriorKind::Position => "position",
        }
    }

    /// What a width of this kind is measured in: `length`, `angle` or `factor`.
    fn dimension(self) -> Dimension {
        match self {
            PriorKind::PrismaticOffset | PriorKind::Length | PriorKind::Tcp | PriorKind::Position => {
                Dimension::Length
            }
            PriorKind::ThetaOffset | PriorKind::Alpha | PriorKind::Beta | PriorKind::Compliance => {
                Dimension::Angle
            }
            PriorKind::Effect => Dimension::Factor,
            PriorKind::Base => Dimension::Mixed,
        }
    }
}

impl fmt::Display for PriorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for PriorKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        let alias = match s {
            "a" | "d" | "lengths" => Some(PriorKind::Length),
            "c" | "compliances" => Some(PriorKind::Compliance),
            "joint_offset" | "joint_zero" | "theta" => Some(PriorKind::ThetaOffset),
            _ => None,
        };
        alias.or_else(|| PriorKind::ALL.into_iter().find(|k| k.name() == s)).ok_or_else(|| {
            format!(
                "unknown prior kind `{s}` (expected one of {})",
                PriorKind::ALL.map(|k| k.name()).join(", ")
            )
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Dimension {
    Length,
    Angle,
    Factor,
    Mixed,
}

/// The width of every kind at scale ×1, internal units (mm, rad; compliance as a deflection
/// \[rad\]; effects as a factor of the typical size). `f64::INFINITY`: free.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PriorWidths {
    /// revolute joint-zero offsets \[rad\]
    pub theta_offset_rad: f64,
    /// prismatic joint zeros \[mm\]
    pub prismatic_offset_mm: f64,
    /// MDH lengths \[mm\]
    pub length_mm: f64,
    /// MDH twists \[rad\]
    pub alpha_rad: f64,
    /// Hayati tilts \[rad\]
    pub beta_rad: f64,
    /// deflection of a joint at its largest gravity torque over the data \[rad\]
    pub compliance_deflection_rad: f64,
    /// catalog effect parameters, in multiples of `ParamId::typical_scale`
    pub effect_factor: f64,
    /// base pose: translations \[mm\] (the rotations get this width / 1000 mm \[rad\])
    pub base_mm: f64,
    /// TCP / marker coordinates \[mm\]
    pub tcp_mm: f64,
    /// fixed-point coordinates \[mm\]
    pub position_mm: f64,
}

impl Default for PriorWidths {
    fn default() -> Self {
        Self::realistic()
    }
}

impl PriorWidths {
    /// The realistic widths of the module table.
    pub fn realistic() -> Self {
        Self {
            theta_offset_rad: 0.010,
            prismatic_offset_mm: 1.0,
            length_mm: 1.0,
            alpha_rad: 0.003,
            beta_rad: 0.003,
            compliance_deflection_rad: 0.002,
            effect_factor: 10.0,
            base_mm: f64::INFINITY,
            tcp_mm: f64::INFINITY,
            position_mm: f64::INFINITY,
        }
    }

    /// The width of `kind` at ×1 (internal units; see the fields).
    pub fn get(&self, kind: PriorKind) -> f64 {
        match kind {
            PriorKind::ThetaOffset => self.theta_offset_rad,
            PriorKind::PrismaticOffset => self.prismatic_offset_mm,
            PriorKind::Length => self.length_mm,
            PriorKind::Alpha => self.alpha_rad,
            PriorKind::Beta => self.beta_rad,
            PriorKind::Compliance => self.compliance_deflection_rad,
            PriorKind::Effect => self.effect_factor,
            PriorKind::Base => self.base_mm,
            PriorKind::Tcp => self.tcp_mm,
            PriorKind::Position => self.position_mm,
        }
    }

    /// Sets the width of `kind` at ×1.
    pub fn set(&mut self, kind: PriorKind, value: f64) {
        let slot = match kind {
            PriorKind::ThetaOffset => &mut self.theta_offset_rad,
            PriorKind::PrismaticOffset => &mut self.prismatic_offset_mm,
            PriorKind::Length => &mut self.length_mm,
            PriorKind::Alpha => &mut self.alpha_rad,
            PriorKind::Beta => &mut self.beta_rad,
            PriorKind::Compliance => &mut self.compliance_deflection_rad,
            PriorKind::Effect => &mut self.effect_factor,
            PriorKind::Base => &mut self.base_mm,
            PriorKind::Tcp => &mut self.tcp_mm,
            PriorKind::Position => &mut self.position_mm,
        };
        *slot = value;
    }
}

/// One `--prior KIND=VALUE` override: the kind and its width at ×1 (internal units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PriorOverride {
    /// the kind
    pub kind: PriorKind,
    /// its width at ×1 \[mm, rad, factor\]; `f64::INFINITY`: free
    pub width: f64,
}

impl FromStr for PriorOverride {
    type Err = String;

    /// Parses `theta_offset=50mrad`, `length=0.5mm`, `alpha=0.1deg`, `compliance=1mrad`,
    /// `effect=3` (a factor), `tcp=free` (or `inf`). Lengths take `mm`, `um`, `m`; angles
    /// `rad`, `mrad`, `urad`, `deg`, `arcmin`, `arcsec`. A number without a unit is refused
    /// (except for `effect`).
    fn from_str(s: &str) -> Result<Self, String> {
        let (name, value) = s
            .split_once('=')
            .ok_or_else(|| format!("`{s}`: expected KIND=VALUE with a unit, e.g. theta_offset=50mrad"))?;
        let kind: PriorKind = name.parse()?;
        let v = value.trim();
        if matches!(v, "inf" | "free" | "none") {
            return Ok(PriorOverride { kind, width: f64::INFINITY });
        }
        let split = v.find(|c: char| c.is_ascii_alphabetic() && c != 'e' && c != 'E').unwrap_or(v.len());
        // `1e-3mrad`: the exponent's `e` is part of the number; a unit never starts with e
        let (number, unit) = v.split_at(split);
        let x: f64 =
            number.trim().parse().map_err(|_| format!("`{s}`: `{}` is not a number", number.trim()))?;
        if !(x.is_finite() && x > 0.0) {
            return Err(format!("`{s}`: a prior width must be > 0 (or `free`)"));
        }
        let unit = unit.trim();
        let factor = match (kind.dimension(), unit) {
            (Dimension::Factor, "") => 1.0,
            (Dimension::Length | Dimension::Mixed, "mm") => 1.0,
            (Dimension::Length | Dimension::Mixed, "um") => 1e-3,
            (Dimension::Length | Dimension::Mixed, "m") => 1e3,
            (Dimension::Angle, "rad") => 1.0,
            (Dimension::Angle, "mrad") => 1e-3,
            (Dimension::Angle, "urad") => 1e-6,
            (Dimension::Angle, "deg") => std::f64::consts::PI / 180.0,
            (Dimension::Angle, "arcmin") => std::f64::consts::PI / 180.0 / 60.0,
            (Dimension::Angle, "arcsec") => std::f64::consts::PI / 180.0 / 3600.0,
            (d, u) => {
                let expected = match d {
                    Dimension::Length | Dimension::Mixed => "mm, um or m",
                    Dimension::Angle => "rad, mrad, urad, deg, arcmin or arcsec",
                    Dimension::Factor => "no unit (a factor of the typical size)",
                };
                return Err(if u.is_empty() {
                    format!("`{s}`: the width needs a unit ({expected})")
                } else {
                    format!("`{s}`: unit `{u}` does not fit `{kind}` (expected {expected})")
                });
            }
        };
        Ok(PriorOverride { kind, width: x * factor })
    }
}

/// The smallest reference torque of a joint's compliance prior, as a fraction of the chain's
/// largest gravity torque over the data.
pub const COMPLIANCE_TORQUE_FLOOR: f64 = 0.1;

/// The priors of a fit: the widths at ×1 and the scale that multiplies them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PriorSpec {
    /// widths at ×1
    pub widths: PriorWidths,
    /// multiplies every width
    pub scale: f64,
}

impl Default for PriorSpec {
    fn default() -> Self {
        Self { widths: PriorWidths::realistic(), scale: 1.0 }
    }
}

impl PriorSpec {
    /// `widths` at `scale`.
    pub fn new(widths: PriorWidths, scale: f64) -> Self {
        Self { widths, scale }
    }

    /// The same with one kind's width at ×1 replaced.
    pub fn with_override(mut self, o: PriorOverride) -> Self {
        self.widths.set(o.kind, o.width);
        self
    }

    /// The prior standard deviation of every parameter of `params` (internal units, same
    /// order; `f64::INFINITY` = free). Compliances: the deflection width over the joint's
    /// reference torque, its largest gravity torque at the rows' postures but at least
    /// [`COMPLIANCE_TORQUE_FLOOR`] of the chain's largest (a wrist joint loaded by 0.1 N·m is
    /// not allowed the shoulder's deflection; a chain no row loads keeps 10 × the typical size).
    pub fn sigmas(&self, model: &Model, measurements: &[Measurement], params: &ParamSet) -> Vec<f64> {
        let torques = largest_gravity_torques(model, measurements, params);
        params
            .iter()
            .map(|p| {
                let kind = PriorKind::of(*p, model);
                let w = self.widths.get(kind);
                if !w.is_finite() {
                    return f64::INFINITY;
                }
                let base = match (kind, p) {
                    (PriorKind::Compliance, ParamId::Compliance(i)) => {
                        let chain = torques.iter().fold(0.0f64, |m, t| m.max(*t));
                        let t = torques[*i as usize - 1].max(COMPLIANCE_TORQUE_FLOOR * chain);
                        if t > 0.0 { w / t } else { 10.0 * p.typical_scale() }
                    }
                    (PriorKind::Effect, _) => w * p.typical_scale(),
                    (PriorKind::Base, ParamId::Base(b)) => match b {
                        vatcal_core::BaseParam::X | vatcal_core::BaseParam::Y | vatcal_core::BaseParam::Z => {
                            w
                        }
                        _ => w / 1000.0,
                    },
                    (PriorKind::Base, ParamId::Plane { dof, .. }) => match dof {
                        vatcal_core::PlaneDof::Offset => w,
                        _ => w / 1000.0,
                    },
                    _ => w,
                };
                self.scale * base
            })
            .collect()
    }
}

/// The largest |gravity torque| \[N·m\] of every joint over the rows' postures (zeros when no
/// compliance is asked for: the loop is then skipped).
fn largest_gravity_torques(model: &Model, measurements: &[Measurement], params: &ParamSet) -> Vec<f64> {
    let n = model.joint_count();
    let mut largest = vec![0.0f64; n];
    if !params.iter().any(|p| matches!(p, ParamId::Compliance(_))) {
        return largest;
    }
    for m in measurements {
        if m.q.len() != n {
            continue;
        }
        let t = model.gravity_torques(&m.q);
        for (l, v) in largest.iter_mut().zip(t.iter()) {
            *l = l.max(v.abs());
        }
    }
    largest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_parse_with_units() {
        let o: PriorOverride = "theta_offset=50mrad".parse().expect("valid override");
        assert_eq!(o.kind, PriorKind::ThetaOffset);
        assert!((o.width - 0.05).abs() < 1e-15);
        let o: PriorOverride = "length=0.5mm".parse().expect("valid override");
        assert!((o.width - 0.5).abs() < 1e-15);
        let o: PriorOverride = "alpha=0.1deg".parse().expect("valid override");
        assert!((o.width - 0.1f64.to_radians()).abs() < 1e-15);
        let o: PriorOverride = "a=2um".parse().expect("valid override");
        assert_eq!(o.kind, PriorKind::Length);
        assert!((o.width - 0.002).abs() < 1e-15);
        let o: PriorOverride = "tcp=free".parse().expect("valid override");
        assert!(o.width.is_infinite());
        let o: PriorOverride = "theta_offset=1e-2rad".parse().expect("valid override");
        assert!((o.width - 0.01).abs() < 1e-15);
        let o: PriorOverride = "effect=3".parse().expect("valid override");
        assert_eq!(o.width, 3.0);
    }

    #[test]
    fn bad_overrides_are_refused_with_the_reason() {
        for (s, needle) in [
            ("theta_offset=50", "needs a unit"),
            ("theta_offset=50mm", "does not fit"),
            ("length=1deg", "does not fit"),
            ("twist=1deg", "unknown prior kind"),
            ("length", "expected KIND=VALUE"),
            ("length=-1mm", "must be > 0"),
            ("length=xmm", "not a number"),
        ] {
            let e = s.parse::<PriorOverride>().expect_err("invalid override");
            assert!(e.contains(needle), "{s}: {e}");
        }
    }
}
