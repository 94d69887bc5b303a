//! A benchmark of `discover` on hidden-effect cases unlike the demo's truth (issue 21, item 5).
//!
//! Every case is drawn from one seeded stream ([`generate`]): a robot (the canonical
//! Meca500-on-guide cell or the UR5e fixture), a kind of data (probe rows, tracker rows, or
//! both), with or without replicated poses, with or without the instruments' noise given to
//! discovery, and 0–3 hidden effects. A hidden effect is either an instance of the catalog
//! (random direction in its parameter space) or physics the catalog does not have:
//!
//! * [`Shape::FractionalCyclic`]: `θ_j += a sin(k q_j + φ)` with k = 1.5 or 2.5 turns⁻¹ (the
//!   catalog has integer harmonics only);
//! * [`Shape::LinkBending`]: the upper arm bends out of the arm plane by an amount that depends
//!   on the shoulder and elbow angles: the TCP moves by `a sin(q_elbow) cos(q_shoulder)` along
//!   the shoulder axis (no catalog hook moves a point sideways out of the arm plane);
//! * [`Shape::GuideWaviness`]: the carriage path waves sideways with a period of 70–130 mm
//!   along the 300 mm stroke (the catalog's straightness is a Legendre polynomial of order ≤ 3);
//! * [`Shape::JointCoupling`]: `θ_j += a q_k` for a neighbouring joint k (a coupled drive whose
//!   ratio is off: the catalog's `joint-scale` scales a joint by its own angle);
//! * [`Shape::ThermalJointDrift`]: `θ_j += a (T − 20 °C)` (an encoder zero that drifts with the
//!   temperature: the catalog's `thermal-drift` scales lengths);
//! * [`Shape::StiffeningCompliance`]: `θ_j += a (τ_j / τ_ref)³` (the non-linear part of a joint
//!   spring: the catalog's compliance is linear in the torque).
//!
//! **Size.** Each effect's size is set as a multiple `m` of the instrument noise of its
//! prediction change: `m = RMS_i ‖(P⊥ d)_i‖ / (√3 σ)`, with `d` the displacement the effect
//! causes at the data's poses, `P⊥` the projection out of the starting parameters' Jacobian
//! columns (what the fit cannot absorb), and `√3 σ` the norm of one measurement's noise (σ per
//! axis of the data's main instrument: the probe when the data has probe rows, else the
//! tracker). This is the quantity discovery's size rule compares with `√3 σ`. `m` is drawn
//! log-uniform in [0.3, 10]; when the amplitude would exceed the effect's plausibility bound
//! (catalog) or a physical cap (extra physics) it is capped there and the case records the
//! smaller `m` it really has.
//!
//! **Scoring** ([`run_case`]): an effect counts as *named with its driver* when an added effect
//! is driven by the same variable (catalog `driver`), *named exactly* when the added instance
//! is the hidden one (same effect, joint, harmonic; any order of the guide polynomials). A null
//! case (no hidden effect; the truth still has the 34 parameters' errors) fails when anything is
//! added. The held-out error is the mean error on independent tracker validation rows; the
//! floor is the fit of the **true structure** — the starting parameters plus the hidden catalog
//! effects' parameters, with the extra physics known exactly (subtracted from the data) — on the
//! same data.
//!
//! **Generator versions** ([`GENERATOR_VERSION`], [`Generator`]). The stream of cases is part of
//! the benchmark: a result is only comparable with results of the same generator version.
//! * `v1` (`bd93486`): the mixture above with three kinds of extra physics;
//! * `v2` (`d310186`): three more extra physics (coupling, thermal zero drift, cubic stiffness);
//!   reachable as [`Generator::V2`];
//! * `v3` (issue 30, item 5; frozen before the method of issue 30 changes; [`generate`]): the
//!   cases that broke on independent data. Its own stream (the seed is mixed with a v3 tag).
//!   Every case has one [`Shape::Campaign`] entry (not an effect): **180 rows** to fit (v2: 120;
//!   at 120 rows the saturated σ̂ is never computed, so its collapse is not reached), and in half
//!   the cases, null cases included, **fixture errors**: the truth's TCP and
//!   calibration-position coordinates off the nominal by N(0, [`FIXTURE_SIGMA_MM`]) per
//!   coordinate (the CMM's uncertainty; drawn from their own stream, `campaign::add_cmm_errors`),
//!   so that the only misfit of a null case beyond the start and the noise is those ~1 µm. They
//!   are not an effect to discover: on a null case anything added is a false positive, and in
//!   any case a `position-offset`, `tcp-offset` or `tool-frame` that is not hidden is counted as
//!   a false addition ([`CaseResult::fixture_additions`]); the floor fits the nominal
//!   coordinates. Of the non-null cases half hide v2's mixtures, a quarter one member of the
//!   **gravity-load family** of look-alikes ([`LookAlike`]: the start **without the
//!   compliances** `c_i` — the truth keeps the drawn ones and the floor fits them — or
//!   `link-bending`, `joint-stiffness-nonlinear` (τ|τ|), `guide-carriage-tilt` of a size drawn in
//!   [`LOOK_ALIKE_SIZE_RANGE`]) and a quarter two members together. Robot, data kind, replicates
//!   and noise metadata are drawn as in v2 (50 % without metadata, a quarter of the cases with
//!   neither metadata nor replicates). Sizes are measured in the linear regime
//!   ([`linear_unabsorbed_rms`]), each missing compliance's given the others, and no drawn
//!   effect moves the TCP by more than [`V3_MAX_DISPLACEMENT_MM`]. Every case carries its
//!   [`Category`] tags.

use std::time::Instant;

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use serde::Serialize;
use vatcal_core::effects::{
    EffectKind, EffectSpec, ThermalDriver, bound_of, joint_stiffness_nonlinear, link_bending,
};
use vatcal_core::{CellFile, JointVector, Measurement, MeasurementContext, ParamId, ParamSet, Target};
use vatcal_discovery::catalog::driver_of_in;
use vatcal_discovery::fit::{fit, residuals};
use vatcal_discovery::linear::ColumnSpace;
use vatcal_discovery::location::Driver;
use vatcal_discovery::workflow::CandidateStatus;
use vatcal_discovery::{DiscoverOptions, Discovery, discover};
use vatcal_identification::{ErrorStats, IdentifyOptions, KindSigmas};
use vatcal_kinematics::Model;
use vatcal_observability::assemble_jacobian;
use vatcal_observability::identifiability::param_set_from_spec;
use vatcal_sim::truth::{ErrorBudget, compliance_scale, perturbed_truth, random_joints, reach};

use super::campaign::{add_cmm_errors, gaussian};

/// σ per axis of a probe row [mm] (robot, guide, gauges: the demo's probe budget).
pub const PROBE_SIGMA_MM: f64 = 0.002;
/// σ per axis of a tracker row [mm].
pub const TRACKER_SIGMA_MM: f64 = 0.005;
/// Sizes are drawn log-uniform in this range of multiples of the noise.
pub const SIZE_RANGE: (f64, f64) = (0.3, 10.0);
/// An effect of at least this multiple must be named (the target).
pub const MUST_NAME: f64 = 3.0;
/// Held-out error must be within this factor of the floor (the target).
pub const FLOOR_FACTOR: f64 = 1.3;
/// The version of the generator [`generate`] draws from (see the module's documentation and
/// `docs/discovery-benchmark.md`): results are comparable only within one version.
pub const GENERATOR_VERSION: &str = "v3";
/// σ per coordinate of the fixture (CMM) errors of the TCP and calibration-position coordinates
/// in the cases that have them [mm] (generator v3).
pub const FIXTURE_SIGMA_MM: f64 = 0.001;
/// Share of the cases with fixture errors (generator v3; null cases included).
pub const FIXTURE_SHARE: f64 = 0.5;
/// Sizes of the gravity-load look-alikes (other than the missing compliances, which have the
/// truth's own size) are drawn log-uniform in this range (generator v3).
pub const LOOK_ALIKE_SIZE_RANGE: (f64, f64) = (1.0, 10.0);

/// Which robot a case uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Robot {
    /// `fixtures/meca500-zaber.toml` (guide + Meca500, 7 joints)
    Canonical,
    /// `fixtures/ur5e.toml` (6R, no guide)
    Ur5e,
}

impl Robot {
    /// The fixture's nominal model.
    pub fn nominal(self) -> Model {
        let file = match self {
            Robot::Canonical => "meca500-zaber.toml",
            Robot::Ur5e => "ur5e.toml",
        };
        let path = format!("{}/../../fixtures/{file}", env!("CARGO_MANIFEST_DIR"));
        let cell = CellFile::load(&path).expect("fixture cell");
        Model::from_cell(&cell).expect("fixture model")
    }

    /// (shoulder, elbow) joints: the two parallel pitch axes of the arm.
    fn shoulder_elbow(self) -> (u8, u8) {
        match self {
            Robot::Canonical => (3, 4),
            Robot::Ur5e => (2, 3),
        }
    }
}

/// What kind of rows the data to fit holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum DataKind {
    /// probe rows only (the TriCal at the calibration positions)
    Probe,
    /// tracker rows only (random poses over the workspace)
    Tracker,
    /// probe rows and some tracker rows
    Mixed,
}

/// A hidden effect's shape (its size is separate).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Shape {
    /// a catalog instance; the unit values are a random direction in its parameter space
    Catalog(EffectSpec),
    /// `θ_j += a sin(k q_j + φ)`, k not an integer
    FractionalCyclic {
        /// revolute joint
        joint: u8,
        /// periods per joint turn
        k: f64,
        /// phase [rad]
        phase: f64,
    },
    /// the TCP moves by `a sin(q_elbow) cos(q_shoulder)` along the shoulder axis
    LinkBending {
        /// shoulder joint (its axis is the bending direction)
        shoulder: u8,
        /// elbow joint
        elbow: u8,
    },
    /// the TCP moves by `a sin(2π q1/P + φ)` across the guide's travel
    GuideWaviness {
        /// period P [mm]
        period_mm: f64,
        /// phase [rad]
        phase: f64,
    },
    /// `θ_driven += a q_by`
    JointCoupling {
        /// the joint whose angle is off
        driven: u8,
        /// the joint whose angle drives the error
        by: u8,
    },
    /// `θ_j += a (T − 20 °C)`
    ThermalJointDrift {
        /// revolute joint
        joint: u8,
    },
    /// `θ_j += a (τ_j / τ_ref)³`
    StiffeningCompliance {
        /// revolute joint
        joint: u8,
        /// the joint's largest |gravity torque| over random poses of the nominal model [N·m]
        tau_ref_nm: f64,
    },
    /// **Not an effect**: how the case's campaign departs from generator v2's (every case of
    /// generator v3 has one such entry; a case without one is a v2 case: 120 rows, exact
    /// fixtures). Nothing is to be discovered for it: a case whose only hidden entry is this one
    /// is a null case.
    Campaign {
        /// rows to fit (v2: 120); mixed data hold a third of them as tracker rows
        rows: usize,
        /// σ per coordinate of the **fixture errors** [mm] (0: none): the truth's TCP and
        /// calibration-position coordinates differ from the nominal ones by N(0, σ) per
        /// coordinate (CMM errors, within the CMM's stated uncertainty). The floor fits the
        /// nominal coordinates, as a user would; an effect added for them is a false addition.
        fixture_sigma_mm: f64,
    },
}

impl Shape {
    /// Human label.
    pub fn label(&self) -> String {
        match self {
            Shape::FractionalCyclic { joint, k, .. } => {
                format!("sinusoid {k} per turn on joint {joint} (extra)")
            }
            Shape::LinkBending { shoulder, elbow } => {
                format!("out-of-plane link bending (q{elbow}, q{shoulder}) (extra)")
            }
            Shape::GuideWaviness { period_mm, .. } => {
                format!("guide waviness, period {period_mm:.0} mm (extra)")
            }
            Shape::JointCoupling { driven, by } => format!("joint {driven} coupled to q{by} (extra)"),
            Shape::ThermalJointDrift { joint } => format!("thermal zero drift of joint {joint} (extra)"),
            Shape::StiffeningCompliance { joint, .. } => format!("cubic stiffness of joint {joint} (extra)"),
            Shape::Campaign { rows, fixture_sigma_mm } if *fixture_sigma_mm > 0.0 => {
                format!(
                    "{rows} rows, fixture (CMM) errors of {:.1} um (not an effect)",
                    fixture_sigma_mm * 1e3
                )
            }
            Shape::Campaign { rows, .. } => format!("{rows} rows (not an effect)"),
            Shape::Catalog(EffectSpec::JointCompliance { joint }) => {
                format!("joint-compliance (joint {joint}) missing from the start")
            }
            Shape::Catalog(s) => s.label(),
        }
    }

    /// Whether the catalog has this effect.
    pub fn in_catalog(&self) -> bool {
        matches!(self, Shape::Catalog(_))
    }

    /// Whether it is an effect to discover ([`Shape::Campaign`] is not).
    pub fn is_effect(&self) -> bool {
        !matches!(self, Shape::Campaign { .. })
    }

    /// The member of the gravity-load family of look-alikes this is, if it is one (generator
    /// v3): the missing compliances (whatever the joint), `link-bending`,
    /// `joint-stiffness-nonlinear`, `guide-carriage-tilt`.
    pub fn look_alike(&self) -> Option<LookAlike> {
        let Shape::Catalog(spec) = self else { return None };
        match spec {
            EffectSpec::JointCompliance { .. } => Some(LookAlike::MissingCompliance),
            EffectSpec::GuideCarriageTilt => Some(LookAlike::CarriageTilt),
            s if s.kind() == EffectKind::Extension(link_bending::ID) => Some(LookAlike::LinkBending),
            s if s.kind() == EffectKind::Extension(joint_stiffness_nonlinear::ID) => {
                Some(LookAlike::StiffnessNonlinear)
            }
            _ => None,
        }
    }

    /// The variables that drive it (an added effect driven by one of them names it).
    pub fn drivers(&self, model: &Model) -> Vec<Driver> {
        let guide = model.guide_joint().unwrap_or(1) as u8;
        let n = model.joint_count() as u8;
        match self {
            Shape::Catalog(s) => vec![driver_of_in(s, guide, n)],
            Shape::FractionalCyclic { joint, .. } => vec![Driver::Joint(*joint)],
            Shape::LinkBending { shoulder, elbow } => vec![
                Driver::Joint(*elbow),
                Driver::Joint(*shoulder),
                Driver::Torque(*elbow),
                Driver::Torque(*shoulder),
            ],
            Shape::GuideWaviness { .. } => vec![Driver::Joint(guide)],
            Shape::JointCoupling { driven, by } => vec![Driver::Joint(*driven), Driver::Joint(*by)],
            Shape::ThermalJointDrift { joint } => vec![Driver::Temperature, Driver::Joint(*joint)],
            Shape::StiffeningCompliance { joint, .. } => vec![Driver::Torque(*joint), Driver::Joint(*joint)],
            Shape::Campaign { .. } => Vec::new(),
        }
    }
}

/// The members of the gravity-load family: their prediction changes point nearly the same way
/// (cosine 0.92–0.99 on the demo's data, issue 30).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub enum LookAlike {
    /// the start without the joint compliances `c_i`; the truth has them
    MissingCompliance,
    /// `link-bending` of a loaded joint
    LinkBending,
    /// `joint-stiffness-nonlinear` (τ|τ|) of a loaded joint
    StiffnessNonlinear,
    /// `guide-carriage-tilt` (canonical cell)
    CarriageTilt,
}

/// The categories a case belongs to (generator v3; a case can be in several), reported
/// separately besides the totals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub enum Category {
    /// fixture errors, nothing else hidden
    FixtureNull,
    /// fixture errors and hidden effects
    FixtureNonNull,
    /// one member of the gravity-load family hidden, nothing else
    LookAlikeAlone,
    /// two members of the gravity-load family hidden, nothing else
    LookAlikeTogether,
    /// the start without the compliances (the truth has them)
    StartWithoutCompliance,
    /// no noise metadata and no replicates: the noise reference is the residual σ̂
    NoMetadataNoReplicates,
}

impl Category {
    /// Every category, in the order of the tables.
    pub const ALL: [Category; 6] = [
        Category::FixtureNull,
        Category::FixtureNonNull,
        Category::LookAlikeAlone,
        Category::LookAlikeTogether,
        Category::StartWithoutCompliance,
        Category::NoMetadataNoReplicates,
    ];

    /// Short tag (per-case output).
    pub fn tag(self) -> &'static str {
        match self {
            Category::FixtureNull => "fixture-null",
            Category::FixtureNonNull => "fixture",
            Category::LookAlikeAlone => "look-alike-alone",
            Category::LookAlikeTogether => "look-alike-together",
            Category::StartWithoutCompliance => "no-compliance-start",
            Category::NoMetadataNoReplicates => "no-meta-no-rep",
        }
    }

    /// Row label of the tables.
    pub fn label(self) -> &'static str {
        match self {
            Category::FixtureNull => "fixture errors, null",
            Category::FixtureNonNull => "fixture errors, with hidden effects",
            Category::LookAlikeAlone => "look-alike alone",
            Category::LookAlikeTogether => "look-alikes together",
            Category::StartWithoutCompliance => "start without compliance",
            Category::NoMetadataNoReplicates => "no noise metadata, no replicates",
        }
    }
}

/// A hidden effect of a case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HiddenEffect {
    /// its shape
    pub shape: Shape,
    /// catalog: the values of its parameters (internal units); extra physics: `[a]`
    pub values: Vec<f64>,
    /// size drawn, in multiples of the noise of its prediction change
    pub requested_multiple: f64,
    /// size it has (smaller when capped by the plausibility bound)
    pub multiple: f64,
}

/// One benchmark case (what to generate; [`CaseData::build`] generates it).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Case {
    /// index in the benchmark
    pub id: usize,
    /// seed of everything random in the case
    pub seed: u64,
    /// the robot
    pub robot: Robot,
    /// the kind of data to fit
    pub data: DataKind,
    /// a quarter of the poses measured twice
    pub replicates: bool,
    /// the instruments' noise is given to discovery
    pub noise_metadata: bool,
    /// the hidden effects (none, or only a [`Shape::Campaign`]: a null case)
    pub hidden: Vec<HiddenEffect>,
}

impl Case {
    /// The hidden entries that are effects to discover (all but [`Shape::Campaign`]).
    pub fn effects(&self) -> impl Iterator<Item = &HiddenEffect> {
        self.hidden.iter().filter(|h| h.shape.is_effect())
    }

    /// Nothing to discover: no hidden effect (fixture errors may be there).
    pub fn is_null(&self) -> bool {
        self.effects().next().is_none()
    }

    /// The [`Shape::Campaign`] entry's rows and fixture σ [mm]; v2's (120 rows, 0) without one.
    pub fn campaign(&self) -> (usize, f64) {
        self.hidden
            .iter()
            .find_map(|h| match h.shape {
                Shape::Campaign { rows, fixture_sigma_mm } => Some((rows, fixture_sigma_mm)),
                _ => None,
            })
            .unwrap_or((V2_ROWS, 0.0))
    }

    /// The truth's fixture coordinates differ from the nominal ones.
    pub fn has_fixture_errors(&self) -> bool {
        self.campaign().1 > 0.0
    }

    /// The start has no compliances (a hidden `joint-compliance`: the truth has them).
    pub fn starts_without_compliance(&self) -> bool {
        self.hidden.iter().any(|h| matches!(h.shape, Shape::Catalog(EffectSpec::JointCompliance { .. })))
    }

    /// The members of the gravity-load family hidden (each once), when every hidden effect is
    /// one; else empty.
    pub fn look_alikes(&self) -> Vec<LookAlike> {
        let mut members: Vec<LookAlike> = Vec::new();
        for h in self.effects() {
            let Some(m) = h.shape.look_alike() else { return Vec::new() };
            if !members.contains(&m) {
                members.push(m);
            }
        }
        members
    }

    /// The categories of the case (generator v3's report).
    pub fn categories(&self) -> Vec<Category> {
        let mut v = Vec::new();
        if self.has_fixture_errors() {
            v.push(if self.is_null() { Category::FixtureNull } else { Category::FixtureNonNull });
        }
        match self.look_alikes().len() {
            1 => v.push(Category::LookAlikeAlone),
            2 => v.push(Category::LookAlikeTogether),
            _ => {}
        }
        if self.starts_without_compliance() {
            v.push(Category::StartWithoutCompliance);
        }
        if !self.noise_metadata && !self.replicates {
            v.push(Category::NoMetadataNoReplicates);
        }
        v
    }

    /// The categories' tags, joined (per-case output); `-` when none.
    pub fn tags(&self) -> String {
        let t: Vec<&str> = self.categories().into_iter().map(Category::tag).collect();
        if t.is_empty() { "-".into() } else { t.join(",") }
    }
}

/// The truth of a case: a model (34 parameters' errors + hidden catalog effects) and the
/// extra physics on top.
#[derive(Debug, Clone)]
pub struct Truth {
    /// the model part
    pub model: Model,
    /// extra physics and their amplitudes
    pub extras: Vec<(Shape, f64)>,
    /// unit vector across the guide's travel (world), when the chain has a guide
    pub across_guide: Option<Vector3<f64>>,
}

impl Truth {
    /// The joint values the arm really has when it reports `q`.
    pub fn true_joints(&self, q: &JointVector, ctx: &MeasurementContext) -> JointVector {
        let mut t = *q;
        let mut torques = None;
        for (shape, a) in &self.extras {
            match shape {
                Shape::FractionalCyclic { joint, k, phase } => {
                    let j = *joint as usize - 1;
                    t[j] += a * (k * q[j] + phase).sin();
                }
                Shape::JointCoupling { driven, by } => t[*driven as usize - 1] += a * q[*by as usize - 1],
                Shape::ThermalJointDrift { joint } => {
                    t[*joint as usize - 1] += a * (ctx.temperature_c.unwrap_or(20.0) - 20.0);
                }
                Shape::StiffeningCompliance { joint, tau_ref_nm } => {
                    let tau =
                        torques.get_or_insert_with(|| self.model.gravity_torques(q))[*joint as usize - 1];
                    t[*joint as usize - 1] += a * (tau / tau_ref_nm).powi(3);
                }
                _ => {}
            }
        }
        t
    }

    /// The displacement of the TCP by the Cartesian extra physics at true joints `qt`.
    pub fn displacement(&self, qt: &JointVector) -> Vector3<f64> {
        let mut d = Vector3::zeros();
        for (shape, a) in &self.extras {
            match shape {
                Shape::LinkBending { shoulder, elbow } => {
                    let chain = self.model.chain(qt);
                    let axis = chain.frames()[*shoulder as usize].r.column(2).into_owned();
                    let s = (qt[*elbow as usize - 1]).sin() * (qt[*shoulder as usize - 1]).cos();
                    d += axis * (a * s);
                }
                Shape::GuideWaviness { period_mm, phase } => {
                    if let Some(n) = self.across_guide {
                        d += n * (a * (std::f64::consts::TAU * qt[0] / period_mm + phase).sin());
                    }
                }
                _ => {}
            }
        }
        d
    }

    /// World position of TCP `tcp` when the arm reports `q`.
    pub fn position(&self, q: &JointVector, ctx: &MeasurementContext, tcp: u32) -> Option<Vector3<f64>> {
        let qt = self.true_joints(q, ctx);
        let p = self.model.tcp_position_ctx(&qt, ctx, tcp).ok()?;
        Some(p + self.displacement(&qt))
    }

    /// The joints the arm reports when it puts TCP `tcp` on `target` (fixed point around the
    /// numerical IK of the model part), starting near `q0`; `None` when it does not get within
    /// 10 nm.
    pub fn reach(
        &self,
        q0: &JointVector,
        ctx: &MeasurementContext,
        tcp: u32,
        target: &Vector3<f64>,
    ) -> Option<JointVector> {
        let mut shifted = *target;
        let mut q = *q0;
        let mut best: Option<(f64, JointVector)> = None;
        for _ in 0..12 {
            let qt = reach(&self.model, &q, tcp, &shifted, 1e-11).ok()?;
            // the reported joints: q + δ(q) = qt
            q = qt;
            for _ in 0..6 {
                let t = self.true_joints(&q, ctx);
                for j in 0..q.len() {
                    q[j] = qt[j] - (t[j] - q[j]);
                }
            }
            let err = target - self.position(&q, ctx, tcp)?;
            if err.norm() < 1e-9 {
                return Some(q);
            }
            if best.is_none_or(|(e, _)| err.norm() < e) {
                best = Some((err.norm(), q));
            }
            shifted += err;
        }
        // several extra physics together can stall the fixed point at ~1 nm: far below the
        // 2 µm noise, accepted
        best.filter(|(e, _)| *e < 1e-5).map(|(_, q)| q)
    }

    /// `m` corrected for the extra physics (joints → true joints, target → minus the
    /// displacement): what the model part alone would have recorded.
    pub fn corrected(&self, m: &Measurement) -> Measurement {
        let qt = self.true_joints(&m.q, &m.context);
        let d = self.displacement(&qt);
        let mut c = Measurement { q: qt, ..*m };
        match m.target {
            Target::Probe { .. } => {
                c.probe_offset_mm = Some(m.probe_offset_mm.unwrap_or_else(Vector3::zeros) - d);
            }
            Target::Tracker { xyz_mm } => c.target = Target::Tracker { xyz_mm: xyz_mm - d },
            Target::Orientation { .. } | Target::Plane { .. } => {}
        }
        c
    }
}

/// The generated data of a case.
pub struct CaseData {
    /// the nominal model (discovery starts from it)
    pub nominal: Model,
    /// the truth
    pub truth: Truth,
    /// the starting parameter set (`default`: paper34 on the canonical cell, all identifiable
    /// parameters otherwise; without the compliances when the case hides them)
    pub params: ParamSet,
    /// the starting parameters of the true structure (`default`, compliances included)
    pub true_params: ParamSet,
    /// the data to fit
    pub measurements: Vec<Measurement>,
    /// independent tracker validation rows
    pub validation: Vec<Measurement>,
    /// σ per axis of the data's main instrument [mm]
    pub sigma_mm: f64,
}

/// Temperature of the cell [°C] at time `t` of a campaign of `total_s`: a warm-up and a swing.
fn temperature(t: f64, total_s: f64) -> f64 {
    super::campaign::temperature_at(t, total_s)
}

/// Per-sample context: random approach directions on every revolute joint, time, temperature.
fn context(model: &Model, rng: &mut ChaCha8Rng, t: f64, total_s: f64) -> MeasurementContext {
    let mut dir = [0i8; vatcal_core::MAX_JOINTS];
    for j in 1..=model.joint_count() {
        if model.is_revolute(j) {
            dir[j - 1] = if rng.random::<bool>() { 1 } else { -1 };
        }
    }
    MeasurementContext { dir: Some(dir), time_s: Some(t), temperature_c: Some(temperature(t, total_s)) }
}

/// Nominal poses (no noise) of the data: probe start poses reached on the nominal model, and
/// random tracker poses; each with its context. `replicated[i]` says whether row i repeats
/// the previous pose.
struct Poses {
    rows: Vec<Measurement>,
    replicated: Vec<bool>,
}

/// Rows to fit in a case of generator v2 (and of a hand-made case without a [`Shape::Campaign`]).
pub const V2_ROWS: usize = 120;
/// Rows to fit in a case of generator v3: the independent data of issue 30 had ~540 residuals;
/// at 120 rows with the benchmark's contexts the saturated σ̂ is never computed (fewer than a
/// quarter of the residuals stay free), so the path where it collapses is not reached.
pub const V3_ROWS: usize = 180;
const VALIDATION_ROWS: usize = 150;
const SECONDS_PER_ROW: f64 = 45.0;

fn poses(case: &Case, nominal: &Model, rng: &mut ChaCha8Rng) -> Poses {
    let (rows, _) = case.campaign();
    let (probe_n, tracker_n) = match case.data {
        DataKind::Probe => (rows, 0),
        DataKind::Tracker => (0, rows),
        // a third tracker rows (v2: 80 probe + 40 tracker)
        DataKind::Mixed => (rows - rows / 3, rows / 3),
    };
    let total = probe_n + tracker_n;
    let total_s = SECONDS_PER_ROW * total as f64;
    let unique = |n: usize| if case.replicates { n - n / 4 } else { n };
    let mut base: Vec<Measurement> = Vec::new();
    if probe_n > 0 {
        base.extend(vatcal_sim::truth::probe_start_poses(nominal, unique(probe_n), rng.random()));
    }
    let tcps = nominal.tcp_ids();
    for _ in 0..unique(tracker_n) {
        let q = random_joints(nominal, rng, 0.1);
        let tcp = tcps[rng.random_range(0..tcps.len())];
        base.push(Measurement::tracker(tcp, q, Vector3::zeros()));
    }
    // replicate every fourth pose of each kind right after itself
    let mut rows = Vec::new();
    let mut replicated = Vec::new();
    let mut probe_seen = 0;
    let mut tracker_seen = 0;
    for b in base {
        let is_probe = matches!(b.target, Target::Probe { .. });
        let k = if is_probe { &mut probe_seen } else { &mut tracker_seen };
        let repeat =
            case.replicates && *k % 3 == 0 && *k / 3 < (if is_probe { probe_n } else { tracker_n }) / 4;
        *k += 1;
        let t = SECONDS_PER_ROW * rows.len() as f64;
        let ctx = context(nominal, rng, t, total_s);
        rows.push(Measurement { context: ctx, ..b });
        replicated.push(false);
        if repeat {
            let t = SECONDS_PER_ROW * rows.len() as f64;
            // same pose, same approach directions, a little later
            let ctx2 =
                MeasurementContext { time_s: Some(t), temperature_c: Some(temperature(t, total_s)), ..ctx };
            rows.push(Measurement { context: ctx2, ..b });
            replicated.push(true);
        }
    }
    Poses { rows, replicated }
}

/// Displacement of the TCP at the data's poses caused by `shape` at unit values `unit` on the
/// nominal model (stacked x, y, z).
fn displacement_field(nominal: &Model, shape: &Shape, unit: &[f64], rows: &[Measurement]) -> Vec<f64> {
    let (model, truth) = match shape {
        Shape::Catalog(spec) => {
            let mut m = nominal.clone();
            m.enable_effect(*spec).expect("effect on the chain");
            for (id, v) in spec.params().into_iter().zip(unit) {
                let base = m.param(id).expect("param");
                m.set_param(id, base + v).expect("param");
            }
            (m, None)
        }
        extra => (
            nominal.clone(),
            Some(Truth {
                model: nominal.clone(),
                extras: vec![(*extra, unit[0])],
                across_guide: across_guide(nominal),
            }),
        ),
    };
    let mut out = Vec::with_capacity(3 * rows.len());
    for m in rows {
        let p0 = nominal.tcp_position_ctx(&m.q, &m.context, m.tcp).expect("fk");
        let p1 = match &truth {
            None => model.tcp_position_ctx(&m.q, &m.context, m.tcp).expect("fk"),
            Some(t) => t.position(&m.q, &m.context, m.tcp).expect("fk"),
        };
        out.extend((p1 - p0).iter());
    }
    out
}

/// [`unabsorbed_rms`] of `shape` at `unit` measured in the linear regime (generator v3): the
/// displacement field is evaluated at `unit` scaled down until no row moves by more than
/// 0.1 µm, and the size scaled back up. At the unit amplitude itself a large, mostly absorbed
/// displacement (a base joint's `link-bending` on the UR5e moves the TCP by ~1 mm) has an
/// unabsorbed part that is mostly second order, which the linear scaling to a size then
/// overstates many times.
///
/// Returns that size and the largest displacement of a row, both per `unit` (linear).
fn linear_unabsorbed_rms(
    nominal: &Model,
    shape: &Shape,
    unit: &[f64],
    rows: &[Measurement],
    space: &ColumnSpace,
) -> (f64, f64) {
    const PEAK_MM: f64 = 1e-4;
    let peak_of =
        |d: &[f64]| d.chunks(3).map(|r| r.iter().map(|x| x * x).sum::<f64>().sqrt()).fold(0.0, f64::max);
    let d = displacement_field(nominal, shape, unit, rows);
    let peak = peak_of(&d);
    if peak <= PEAK_MM {
        return (unabsorbed_rms(space, &d), peak);
    }
    let k = PEAK_MM / peak;
    let small: Vec<f64> = unit.iter().map(|u| u * k).collect();
    let d = displacement_field(nominal, shape, &small, rows);
    (unabsorbed_rms(space, &d) / k, peak_of(&d) / k)
}

/// Largest TCP displacement a drawn effect of generator v3 may cause at the data's poses [mm]
/// (its amplitude is capped at 90 % of it): a gravity-load look-alike of a large arm reaches
/// its plausibility bound (sized for the Meca500) only with a tilt of degrees.
pub const V3_MAX_DISPLACEMENT_MM: f64 = 0.5;

/// `RMS_i ‖(P⊥ d)_i‖` over the rows: the part of the displacement the parameters cannot absorb.
fn unabsorbed_rms(space: &ColumnSpace, d: &[f64]) -> f64 {
    let p = space.project_out_vec(d);
    let n = p.len() / 3;
    (p.iter().map(|x| x * x).sum::<f64>() / n.max(1) as f64).sqrt()
}

/// A unit vector across the guide's travel (world), on a chain with a guide.
fn across_guide(nominal: &Model) -> Option<Vector3<f64>> {
    let g = nominal.guide_joint()?;
    let mut q0 = JointVector::zeros(nominal.joint_count());
    let mut q1 = q0;
    let (lo, hi) = nominal.joint_limit(g)?;
    q0[g - 1] = lo;
    q1[g - 1] = hi;
    let along = nominal.chain(&q1).frames()[g].p - nominal.chain(&q0).frames()[g].p;
    // the world axis least aligned with the travel, made perpendicular to it
    let axes = [Vector3::x(), Vector3::y(), Vector3::z()];
    let e = axes.iter().min_by(|a, b| along.dot(a).abs().total_cmp(&along.dot(b).abs()))?;
    let across = along.cross(e);
    (across.norm() > 1e-9).then(|| across.normalize())
}

/// Largest amplitude of extra physics (internal units): 0.5° of joint angle, 0.5 mm of
/// bending, 0.2 mm of waviness.
fn extra_cap(shape: &Shape) -> f64 {
    match shape {
        Shape::FractionalCyclic { .. } => 0.5f64.to_radians(),
        Shape::LinkBending { .. } => 0.5,
        Shape::GuideWaviness { .. } => 0.2,
        // 0.5° over half a turn of the driving joint
        Shape::JointCoupling { .. } => 0.5f64.to_radians() / std::f64::consts::PI,
        // 0.5° over the campaign's ±2 K
        Shape::ThermalJointDrift { .. } => 0.25f64.to_radians(),
        Shape::StiffeningCompliance { .. } => 0.5f64.to_radians(),
        Shape::Catalog(_) | Shape::Campaign { .. } => f64::INFINITY,
    }
}

/// The revolute joints whose largest |gravity torque| (`bending = false`) or |bending moment|
/// (`bending = true`) over 32 random poses of the nominal model exceeds 0.1 N·m, with that
/// largest value. The poses come from their own fixed stream, so the list is a property of the
/// robot.
fn loaded_joints(model: &Model, bending: bool) -> Vec<(u8, f64)> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x10ad);
    let poses: Vec<JointVector> = (0..32).map(|_| random_joints(model, &mut rng, 0.1)).collect();
    (1..=model.joint_count())
        .filter(|j| model.is_revolute(*j))
        .map(|j| {
            let load = poses
                .iter()
                .map(|q| {
                    if bending {
                        let m = model.link_bending_moments(q)[j - 1];
                        m[0].hypot(m[1])
                    } else {
                        model.gravity_torques(q)[j - 1].abs()
                    }
                })
                .fold(0.0, f64::max);
            (j as u8, load)
        })
        .filter(|(_, load)| *load > 0.1)
        .collect()
}

/// Draws one member of the gravity-load family not in `taken` (generator v3) and returns its
/// hidden entries: the missing compliances are one entry per loaded joint (their size is the
/// truth's own, filled in by [`CaseData::build`]); the others one entry of a size drawn in
/// [`LOOK_ALIKE_SIZE_RANGE`]. `None` when every member is taken.
fn draw_look_alike(model: &Model, taken: &[LookAlike], rng: &mut ChaCha8Rng) -> Option<Vec<HiddenEffect>> {
    let mut members =
        vec![LookAlike::MissingCompliance, LookAlike::LinkBending, LookAlike::StiffnessNonlinear];
    if model.guide_joint().is_some() {
        members.push(LookAlike::CarriageTilt);
    }
    members.retain(|m| !taken.contains(m));
    if members.is_empty() {
        return None;
    }
    let member = members[rng.random_range(0..members.len())];
    let (lo, hi) = LOOK_ALIKE_SIZE_RANGE;
    let m = (lo.ln() + rng.random::<f64>() * (hi.ln() - lo.ln())).exp();
    let one = |spec: EffectSpec| HiddenEffect {
        shape: Shape::Catalog(spec),
        values: Vec::new(),
        requested_multiple: m,
        multiple: m,
    };
    let pick = |list: &[(u8, f64)], rng: &mut ChaCha8Rng| list[rng.random_range(0..list.len())].0;
    Some(match member {
        LookAlike::MissingCompliance => loaded_joints(model, false)
            .into_iter()
            .map(|(joint, _)| HiddenEffect {
                shape: Shape::Catalog(EffectSpec::JointCompliance { joint }),
                values: Vec::new(),
                requested_multiple: 0.0,
                multiple: 0.0,
            })
            .collect(),
        LookAlike::LinkBending => vec![one(link_bending::spec(pick(&loaded_joints(model, true), rng)))],
        LookAlike::StiffnessNonlinear => {
            vec![one(joint_stiffness_nonlinear::spec(pick(&loaded_joints(model, false), rng)))]
        }
        LookAlike::CarriageTilt => vec![one(EffectSpec::GuideCarriageTilt)],
    })
}

/// Draws a hidden effect's shape for `robot`.
fn draw_shape(robot: Robot, model: &Model, rng: &mut ChaCha8Rng) -> Shape {
    let revolute: Vec<u8> =
        (1..=model.joint_count()).filter(|j| model.is_revolute(*j)).map(|j| j as u8).collect();
    let joint = revolute[rng.random_range(0..revolute.len())];
    let has_guide = model.guide_joint().is_some();
    if rng.random::<f64>() < 0.4 {
        // physics the catalog does not have
        let kinds = [0, 1, 2, 3, 4, 5];
        let kinds: Vec<u8> = kinds.into_iter().filter(|k| has_guide || *k != 2).collect();
        return match kinds[rng.random_range(0..kinds.len())] {
            0 => Shape::FractionalCyclic {
                joint,
                k: if rng.random::<bool>() { 1.5 } else { 2.5 },
                phase: rng.random_range(0.0..std::f64::consts::TAU),
            },
            1 => {
                let (shoulder, elbow) = robot.shoulder_elbow();
                Shape::LinkBending { shoulder, elbow }
            }
            2 => Shape::GuideWaviness {
                period_mm: rng.random_range(70.0..130.0),
                phase: rng.random_range(0.0..std::f64::consts::TAU),
            },
            3 => {
                // a neighbouring revolute joint drives it
                let near: Vec<u8> =
                    [joint.wrapping_sub(1), joint + 1].into_iter().filter(|k| revolute.contains(k)).collect();
                let by = near[rng.random_range(0..near.len())];
                Shape::JointCoupling { driven: joint, by }
            }
            4 => Shape::ThermalJointDrift { joint },
            _ => {
                // on a joint that carries a gravity torque (not a vertical base joint)
                let poses: Vec<JointVector> = (0..32).map(|_| random_joints(model, rng, 0.1)).collect();
                let loaded: Vec<(u8, f64)> = revolute
                    .iter()
                    .map(|j| {
                        let k = *j as usize - 1;
                        (*j, poses.iter().map(|q| model.gravity_torques(q)[k].abs()).fold(0.0, f64::max))
                    })
                    .filter(|(_, tau)| *tau > 0.1)
                    .collect();
                let (joint, tau_ref_nm) = loaded[rng.random_range(0..loaded.len())];
                Shape::StiffeningCompliance { joint, tau_ref_nm }
            }
        };
    }
    let tcps = model.tcp_ids();
    let mut pool = vec![
        EffectSpec::JointCyclic { joint, harmonic: 1 + u8::from(rng.random::<bool>()) },
        EffectSpec::JointScale { joint },
        EffectSpec::JointBacklash { joint },
        EffectSpec::ToolFrame,
        EffectSpec::TcpOffset { tcp: tcps[rng.random_range(0..tcps.len())] },
        EffectSpec::ThermalDrift { driver: ThermalDriver::Temperature },
    ];
    if has_guide {
        pool.extend([
            EffectSpec::GuideAngular { order: 1 },
            EffectSpec::GuideStraightness { order: 2 },
            EffectSpec::GuideCarriageTilt,
        ]);
    }
    Shape::Catalog(pool[rng.random_range(0..pool.len())])
}

/// A version of the case generator (the module's documentation says what each draws).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Generator {
    /// the generator of issue 21's third round (`d310186`): mixtures of catalog effects and
    /// extra physics
    V2,
    /// issue 30, item 5: v2's mixtures, fixture errors, the gravity-load look-alikes and the
    /// start without compliance
    V3,
}

impl Generator {
    /// The version string (`v2`, `v3`).
    pub fn version(self) -> &'static str {
        match self {
            Generator::V2 => "v2",
            Generator::V3 => "v3",
        }
    }

    /// The generator of a version string; `None` for an unknown one.
    pub fn parse(s: &str) -> Option<Generator> {
        match s.trim() {
            "v2" => Some(Generator::V2),
            "v3" => Some(Generator::V3),
            _ => None,
        }
    }
}

/// The benchmark's cases from the current generator ([`GENERATOR_VERSION`]): `count` cases
/// from `seed`; every fifth case is a null case.
pub fn generate(count: usize, seed: u64) -> Vec<Case> {
    generate_with(Generator::V3, count, seed)
}

/// `count` cases from `seed` drawn by `generator`.
pub fn generate_with(generator: Generator, count: usize, seed: u64) -> Vec<Case> {
    match generator {
        Generator::V2 => generate_v2(count, seed),
        Generator::V3 => generate_v3(count, seed),
    }
}

/// Up to `n_hidden` hidden effects drawn by [`draw_shape`] (v2's mixtures): one instance per
/// effect kind (two draws of the same effect would be one effect), sizes in [`SIZE_RANGE`].
fn draw_mixture(robot: Robot, model: &Model, n_hidden: usize, rng: &mut ChaCha8Rng) -> Vec<HiddenEffect> {
    let mut hidden: Vec<HiddenEffect> = Vec::new();
    while hidden.len() < n_hidden {
        let shape = draw_shape(robot, model, rng);
        let same = |h: &HiddenEffect| match (&h.shape, &shape) {
            (Shape::Catalog(a), Shape::Catalog(b)) => a.kind() == b.kind(),
            (a, b) => std::mem::discriminant(a) == std::mem::discriminant(b),
        };
        if hidden.iter().any(same) {
            continue;
        }
        let (lo, hi) = SIZE_RANGE;
        let m = (lo.ln() + rng.random::<f64>() * (hi.ln() - lo.ln())).exp();
        // values are filled in by `CaseData::build` (they depend on the poses)
        hidden.push(HiddenEffect { shape, values: Vec::new(), requested_multiple: m, multiple: m });
    }
    hidden
}

/// Generator v3 (issue 30, item 5). Per case, from one ChaCha8 stream: the robot, data kind,
/// replicates and noise metadata as v2; fixture errors with probability [`FIXTURE_SHARE`];
/// then every fifth case is a null case, and of the others half hide v2's mixtures (1–3
/// effects), a quarter one member of the gravity-load family alone and a quarter two members
/// together.
fn generate_v3(count: usize, seed: u64) -> Vec<Case> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0003_0000_0000);
    let canonical = Robot::Canonical.nominal();
    let ur5e = Robot::Ur5e.nominal();
    (0..count)
        .map(|id| {
            let robot = if rng.random::<f64>() < 0.6 { Robot::Canonical } else { Robot::Ur5e };
            let model = if robot == Robot::Canonical { &canonical } else { &ur5e };
            let data = match rng.random_range(0..4) {
                0 | 1 => DataKind::Probe,
                2 => DataKind::Tracker,
                _ => DataKind::Mixed,
            };
            let replicates = rng.random::<bool>();
            let noise_metadata = rng.random::<bool>();
            let fixture = rng.random::<f64>() < FIXTURE_SHARE;
            let case_seed = rng.random::<u64>() >> 16;
            let mut hidden = Vec::new();
            if id % 5 != 4 {
                let kind = rng.random::<f64>();
                if kind < 0.5 {
                    let n = rng.random_range(1..=3usize);
                    hidden = draw_mixture(robot, model, n, &mut rng);
                } else {
                    let members = if kind < 0.75 { 1 } else { 2 };
                    let mut taken = Vec::new();
                    for _ in 0..members {
                        if let Some(h) = draw_look_alike(model, &taken, &mut rng) {
                            taken.extend(h.first().and_then(|h| h.shape.look_alike()));
                            hidden.extend(h);
                        }
                    }
                }
            }
            hidden.push(HiddenEffect {
                shape: Shape::Campaign {
                    rows: V3_ROWS,
                    fixture_sigma_mm: if fixture { FIXTURE_SIGMA_MM } else { 0.0 },
                },
                values: Vec::new(),
                requested_multiple: 0.0,
                multiple: 0.0,
            });
            Case { id, seed: case_seed, robot, data, replicates, noise_metadata, hidden }
        })
        .collect()
}

/// Generator v2: `count` cases from `seed`; every fifth case is a null case.
fn generate_v2(count: usize, seed: u64) -> Vec<Case> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|id| {
            let robot = if rng.random::<f64>() < 0.6 { Robot::Canonical } else { Robot::Ur5e };
            let data = match rng.random_range(0..4) {
                0 | 1 => DataKind::Probe,
                2 => DataKind::Tracker,
                _ => DataKind::Mixed,
            };
            let replicates = rng.random::<bool>();
            let noise_metadata = rng.random::<bool>();
            let n_hidden = if id % 5 == 4 { 0 } else { rng.random_range(1..=3usize) };
            let case_seed = rng.random::<u64>() >> 16;
            let hidden = draw_mixture(robot, &robot.nominal(), n_hidden, &mut rng);
            Case { id, seed: case_seed, robot, data, replicates, noise_metadata, hidden }
        })
        .collect()
}

impl CaseData {
    /// Generates the data of `case` and fills in the hidden effects' values (scaled to their
    /// requested multiples on these poses).
    pub fn build(case: &mut Case) -> Option<CaseData> {
        let nominal = case.robot.nominal();
        let mut rng = ChaCha8Rng::seed_from_u64(case.seed);
        let budget = ErrorBudget::realistic();
        let k = compliance_scale(&nominal);
        let budget = ErrorBudget {
            compliance_range: (budget.compliance_range.0 * k, budget.compliance_range.1 * k),
            ..budget
        };
        let poses = poses(case, &nominal, &mut rng);
        let true_params = param_set_from_spec("default", &nominal, &poses.rows).ok()?;
        let params = if case.starts_without_compliance() {
            ParamSet(true_params.0.iter().copied().filter(|p| !matches!(p, ParamId::Compliance(_))).collect())
        } else {
            true_params.clone()
        };
        let sigma_mm = if case.data == DataKind::Tracker { TRACKER_SIGMA_MM } else { PROBE_SIGMA_MM };
        let j = assemble_jacobian(&nominal, &poses.rows, &params).ok()?;
        let space = ColumnSpace::of(j.as_ref()).ok()?;
        let mut model = perturbed_truth(&nominal, case.seed, &budget);
        // the fixture errors: their own stream (seeded by the case), so the rest of the case is
        // the same with and without them
        let (_, fixture_sigma) = case.campaign();
        if fixture_sigma > 0.0 {
            add_cmm_errors(&mut model, case.seed, fixture_sigma);
        }
        let sizing = Sizing::new(case, &nominal, &poses, &params, &space, sigma_mm);
        let mut extras = Vec::new();
        for h in &mut case.hidden {
            // not drawn: the fixture errors and the missing compliances have the truth's size;
            // their multiple is recorded
            if let Some(values) = sizing.given(h, &model)? {
                h.values = values;
                h.requested_multiple = h.multiple;
                continue;
            }
            sizing.draw(h, &mut rng);
            match &h.shape {
                Shape::Catalog(spec) => {
                    model.enable_effect(*spec).ok()?;
                    for (id, v) in spec.params().into_iter().zip(&h.values) {
                        let base = model.param(id).ok()?;
                        model.set_param(id, base + v).ok()?;
                    }
                }
                s => extras.push((*s, h.values[0])),
            }
        }
        let truth = Truth { model, extras, across_guide: across_guide(&nominal) };
        let measurements = measure_poses(&truth, &poses, &mut rng)?;
        if measurements.is_empty() {
            return None;
        }
        let validation = validation_rows(&nominal, &truth, measurements.len(), &mut rng)?;
        Some(CaseData { nominal, truth, params, true_params, measurements, validation, sigma_mm })
    }
}

/// What sizing a case's hidden effects needs: the poses, the fitted parameters' column space
/// and the noise the multiples are of.
struct Sizing<'a> {
    seed: u64,
    nominal: &'a Model,
    poses: &'a Poses,
    params: &'a ParamSet,
    space: &'a ColumnSpace,
    sigma_mm: f64,
    /// a v3 case (it has a campaign entry) measures sizes in the linear regime
    v3: bool,
    missing_compliances: Vec<ParamId>,
}

impl<'a> Sizing<'a> {
    fn new(
        case: &Case,
        nominal: &'a Model,
        poses: &'a Poses,
        params: &'a ParamSet,
        space: &'a ColumnSpace,
        sigma_mm: f64,
    ) -> Self {
        let missing_compliances: Vec<ParamId> = case
            .hidden
            .iter()
            .filter_map(|h| match h.shape {
                Shape::Catalog(EffectSpec::JointCompliance { joint }) => Some(ParamId::Compliance(joint)),
                _ => None,
            })
            .collect();
        let v3 = case.hidden.iter().any(|h| !h.shape.is_effect());
        Self { seed: case.seed, nominal, poses, params, space, sigma_mm, v3, missing_compliances }
    }

    /// The values of a hidden entry that is not drawn (fixture errors, a missing compliance:
    /// the truth's size), its multiple recorded in `h`; `Some(None)` for a drawn one, `None`
    /// when the model rejects a pose.
    fn given(&self, h: &mut HiddenEffect, model: &Model) -> Option<Option<Vec<f64>>> {
        let (nominal, rows) = (self.nominal, &self.poses.rows);
        match h.shape {
            Shape::Campaign { fixture_sigma_mm, .. } => {
                let mut off = nominal.clone();
                add_cmm_errors(&mut off, self.seed, fixture_sigma_mm);
                let mut d = Vec::with_capacity(3 * rows.len());
                for m in rows {
                    d.extend((off.predict(m).ok()? - nominal.predict(m).ok()?).iter());
                }
                h.multiple = unabsorbed_rms(self.space, &d) / (3f64.sqrt() * self.sigma_mm);
                Some(Some(Vec::new()))
            }
            Shape::Catalog(EffectSpec::JointCompliance { joint }) => {
                let id = ParamId::Compliance(joint);
                let v = model.param(id).ok()? - nominal.param(id).ok()?;
                // its size given the other missing compliances (the compliances of
                // neighbouring joints overlap: what only this one does is what must be named)
                let mut with_others = self.params.clone();
                with_others.0.extend(self.missing_compliances.iter().filter(|p| **p != id));
                let j = assemble_jacobian(nominal, rows, &with_others).ok()?;
                let space_j = ColumnSpace::of(j.as_ref()).ok()?;
                let (size, _) = linear_unabsorbed_rms(nominal, &h.shape, &[v], rows, &space_j);
                h.multiple = size / (3f64.sqrt() * self.sigma_mm);
                Some(Some(vec![v]))
            }
            _ => Some(None),
        }
    }

    /// Draws a hidden entry's direction and scales it to its requested multiple, capped at
    /// the plausibility bound / physical cap (90 % of it; v3: also at a TCP displacement of
    /// 90 % of `V3_MAX_DISPLACEMENT_MM`); sets its values and actual multiple.
    fn draw(&self, h: &mut HiddenEffect, rng: &mut ChaCha8Rng) {
        let (nominal, rows) = (self.nominal, &self.poses.rows);
        let unit: Vec<f64> = match &h.shape {
            Shape::Catalog(spec) => {
                spec.params().iter().map(|id| gaussian(rng) * bound_of(id).map_or(1e-3, |b| b.0)).collect()
            }
            _ => vec![1e-3],
        };
        let (size, peak) = if self.v3 {
            linear_unabsorbed_rms(nominal, &h.shape, &unit, rows, self.space)
        } else {
            (unabsorbed_rms(self.space, &displacement_field(nominal, &h.shape, &unit, rows)), 0.0)
        };
        let mut scale = h.requested_multiple * 3f64.sqrt() * self.sigma_mm / size.max(1e-300);
        let displacement_cap =
            if self.v3 && peak > 0.0 { 0.9 * V3_MAX_DISPLACEMENT_MM / peak } else { f64::INFINITY };
        let cap = displacement_cap.min(match &h.shape {
            Shape::Catalog(spec) => spec
                .params()
                .iter()
                .zip(&unit)
                .filter_map(|(id, u)| bound_of(id).map(|b| 0.9 * b.0 / u.abs().max(1e-300)))
                .fold(f64::INFINITY, f64::min),
            s => 0.9 * extra_cap(s) / unit[0],
        });
        if scale > cap {
            scale = cap;
        }
        h.values = unit.iter().map(|u| u * scale).collect();
        h.multiple = size * scale / (3f64.sqrt() * self.sigma_mm);
    }
}

/// Measures the case's poses on the truth: probe rows driven onto their position + noise (a
/// replicate starts from the previous measurement's joints), tracker rows at their joints.
/// `None` when the truth rejects a pose.
fn measure_poses(truth: &Truth, poses: &Poses, rng: &mut ChaCha8Rng) -> Option<Vec<Measurement>> {
    let mut measurements = Vec::with_capacity(poses.rows.len());
    let mut last: Option<JointVector> = None;
    for (m, rep) in poses.rows.iter().zip(&poses.replicated) {
        let noise = |rng: &mut ChaCha8Rng, s: f64| Vector3::from_fn(|_, _| s * gaussian(rng));
        match m.target {
            Target::Probe { position } => {
                let target = truth.model.position(position)? + noise(rng, PROBE_SIGMA_MM);
                let start = if *rep { last.unwrap_or(m.q) } else { m.q };
                let Some(q) = truth.reach(&start, &m.context, m.tcp, &target) else { continue };
                last = Some(q);
                measurements.push(Measurement { q, ..*m });
            }
            Target::Tracker { .. } => {
                let p = truth.position(&m.q, &m.context, m.tcp)? + noise(rng, TRACKER_SIGMA_MM);
                measurements.push(Measurement { context: m.context, ..Measurement::tracker(m.tcp, m.q, p) });
            }
            Target::Orientation { .. } | Target::Plane { .. } => {}
        }
    }
    Some(measurements)
}

/// Validation: random tracker poses over the workspace, contexts inside the campaign's
/// (`rows` measurements long).
fn validation_rows(
    nominal: &Model,
    truth: &Truth,
    rows: usize,
    rng: &mut ChaCha8Rng,
) -> Option<Vec<Measurement>> {
    let tcps = nominal.tcp_ids();
    let total_s = SECONDS_PER_ROW * rows as f64;
    let mut validation = Vec::with_capacity(VALIDATION_ROWS);
    for _ in 0..VALIDATION_ROWS {
        let q = random_joints(nominal, rng, 0.1);
        let tcp = tcps[rng.random_range(0..tcps.len())];
        let t = rng.random_range(0.0..total_s);
        let ctx = context(nominal, rng, t, total_s);
        let p = truth.position(&q, &ctx, tcp)? + Vector3::from_fn(|_, _| TRACKER_SIGMA_MM * gaussian(rng));
        validation.push(Measurement { context: ctx, ..Measurement::tracker(tcp, q, p) });
    }
    Some(validation)
}

impl CaseData {
    /// Measures `poses` (probe start poses or tracker poses, e.g. a proposal) on the truth, with
    /// the instruments' noise and a context continuing the campaign's (seeded).
    pub fn measure_more(&self, poses: &[Measurement], seed: u64) -> Vec<Measurement> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let t0 = self.measurements.iter().filter_map(|m| m.context.time_s).fold(0.0, f64::max);
        let total_s = t0 + SECONDS_PER_ROW * (poses.len() + 1) as f64;
        let mut out = Vec::with_capacity(poses.len());
        for (k, m) in poses.iter().enumerate() {
            let t = t0 + SECONDS_PER_ROW * (k + 1) as f64;
            let ctx = context(&self.nominal, &mut rng, t, total_s);
            let noise = Vector3::from_fn(|_, _| gaussian(&mut rng));
            match m.target {
                Target::Probe { position } => {
                    let Some(p) = self.truth.model.position(position) else { continue };
                    if let Some(q) = self.truth.reach(&m.q, &ctx, m.tcp, &(p + noise * PROBE_SIGMA_MM)) {
                        out.push(Measurement { q, context: ctx, ..*m });
                    }
                }
                Target::Tracker { .. } => {
                    if let Some(p) = self.truth.position(&m.q, &ctx, m.tcp) {
                        let xyz = p + noise * TRACKER_SIGMA_MM;
                        out.push(Measurement { context: ctx, ..Measurement::tracker(m.tcp, m.q, xyz) });
                    }
                }
                Target::Orientation { .. } | Target::Plane { .. } => {}
            }
        }
        out
    }
}

/// How one hidden effect was handled.
#[derive(Debug, Clone, Serialize)]
pub struct HiddenOutcome {
    /// label
    pub label: String,
    /// in the catalog
    pub in_catalog: bool,
    /// size in multiples of the noise
    pub multiple: f64,
    /// an added effect has its driver
    pub named_driver: bool,
    /// the added effect is the hidden instance
    pub named_exactly: bool,
    /// what became of it (for misses)
    pub why: String,
}

/// The result of one case.
#[derive(Debug, Clone, Serialize)]
pub struct CaseResult {
    /// the case
    pub case: Case,
    /// its categories ([`Case::categories`])
    pub tags: Vec<Category>,
    /// rows to fit
    pub rows: usize,
    /// the hidden effects' outcomes ([`Shape::Campaign`] is not an effect: not here)
    pub hidden: Vec<HiddenOutcome>,
    /// labels of the effects discovery added
    pub added: Vec<String>,
    /// of them, the fixture-type effects (`position-offset`, `tcp-offset`, `tool-frame`) that
    /// are not a hidden instance: false additions
    pub fixture_additions: Vec<String>,
    /// detected, negligible
    pub negligible: Vec<String>,
    /// mean validation error of the starting fit [mm]
    pub start_mm: f64,
    /// mean validation error of the discovered model [mm]
    pub discovered_mm: f64,
    /// mean validation error of the true-structure fit [mm] (`None`: that fit failed)
    pub floor_mm: Option<f64>,
    /// mean validation error of the truth itself (the tracker's noise) [mm]
    pub truth_mm: f64,
    /// rounds run
    pub rounds: usize,
    /// wall time of the discovery run [s]
    pub seconds: f64,
    /// the run failed (error text)
    pub error: Option<String>,
}

impl CaseResult {
    /// The result of a case that did not run to the end (`error`): nothing added, nothing
    /// scored.
    fn failed(
        case: Case,
        rows: usize,
        floor_mm: Option<f64>,
        truth_mm: f64,
        seconds: f64,
        error: String,
    ) -> CaseResult {
        CaseResult {
            tags: case.categories(),
            case,
            rows,
            hidden: Vec::new(),
            fixture_additions: Vec::new(),
            added: Vec::new(),
            negligible: Vec::new(),
            start_mm: f64::NAN,
            discovered_mm: f64::NAN,
            floor_mm,
            truth_mm,
            rounds: 0,
            seconds,
            error: Some(error),
        }
    }

    /// discovered / floor.
    pub fn ratio(&self) -> Option<f64> {
        self.floor_mm.map(|f| self.discovered_mm / f.max(1e-12))
    }

    /// Whether something was added on a null case (fixture errors are not an effect).
    pub fn false_positive(&self) -> bool {
        self.case.is_null() && !self.added.is_empty()
    }
}

/// Discovery's options for a case: the defaults, plus the instruments' noise when the case
/// has noise metadata (what `vatcal discover` passes when the measurement file has a
/// `# vatcal-noise:` line). No noise flags: the replicates, when the data has them, are found
/// by discovery itself.
pub fn options_for(case: &Case, data: &CaseData) -> DiscoverOptions {
    let has_probe = data.measurements.iter().any(|m| matches!(m.target, Target::Probe { .. }));
    let has_tracker = data.measurements.iter().any(|m| matches!(m.target, Target::Tracker { .. }));
    DiscoverOptions {
        seed: case.seed,
        instrument_sigmas: case.noise_metadata.then_some(KindSigmas {
            probe_mm: has_probe.then_some(PROBE_SIGMA_MM),
            tracker_mm: has_tracker.then_some(TRACKER_SIGMA_MM),
        }),
        instrument_noise_origin: case
            .noise_metadata
            .then(|| "recorded with the measurements (`# vatcal-noise:`)".to_string()),
        ..DiscoverOptions::default()
    }
}

/// The true-structure fit: the starting parameters plus the hidden catalog effects'
/// parameters (weak prior of their typical scale toward 0, as the demo's), on the data with
/// the extra physics subtracted; its mean error on the equally corrected validation rows.
///
/// The starting parameters are the true structure's ([`CaseData::true_params`]: with the
/// compliances when the case's start lacks them, without prior, as the default start fits
/// them); the fixture coordinates are the nominal ones (a user's fit cannot know the CMM's
/// errors either).
pub fn floor(case: &Case, data: &CaseData) -> Result<f64, String> {
    let mut start = data.nominal.clone();
    let mut params = data.true_params.0.clone();
    let mut priors = vec![f64::INFINITY; params.len()];
    for h in &case.hidden {
        if let Shape::Catalog(spec) = h.shape {
            if matches!(spec, EffectSpec::JointCompliance { .. }) {
                // built-in: on in every model; its parameter is in `true_params`
                for id in spec.params() {
                    if !params.contains(&id) {
                        params.push(id);
                        priors.push(f64::INFINITY);
                    }
                }
                continue;
            }
            start.enable_effect(spec).map_err(|e| e.to_string())?;
            for id in spec.params() {
                if !params.contains(&id) {
                    params.push(id);
                    priors.push(id.typical_scale());
                }
            }
        }
    }
    let ms: Vec<Measurement> = data.measurements.iter().map(|m| data.truth.corrected(m)).collect();
    let val: Vec<Measurement> = data.validation.iter().map(|m| data.truth.corrected(m)).collect();
    let weights = KindSigmas { probe_mm: Some(PROBE_SIGMA_MM), tracker_mm: Some(TRACKER_SIGMA_MM) }.weights();
    let options = IdentifyOptions {
        priors: Some(priors),
        max_condition_number: f64::INFINITY,
        weights,
        ..IdentifyOptions::default()
    };
    let f = fit(&start, &ms, &ParamSet(params), &options).map_err(|e| e.to_string())?;
    let r = residuals(&f.model, &val).map_err(|e| e.to_string())?;
    Ok(ErrorStats::from_errors(&r).mean)
}

/// The last status discovery gave a candidate matching `shape` (for the "why" of a miss).
fn last_status(d: &Discovery, shape: &Shape) -> Option<String> {
    let Shape::Catalog(spec) = shape else { return None };
    for round in d.rounds.iter().rev() {
        if let Some(c) = round.candidates.iter().find(|c| c.label == spec.label()) {
            let s = match &c.status {
                CandidateStatus::MissingData(w) => format!("missing data: {w}"),
                CandidateStatus::AlreadyInModel => "already in the model".into(),
                CandidateStatus::NotDiscoverable => "not discoverable (absorbed)".into(),
                CandidateStatus::NotSignificant => format!(
                    "not significant in round {} (ln p {:.1} vs threshold {:.1})",
                    round.index,
                    c.score.map_or(f64::NAN, |s| s.ln_p_value),
                    round.ln_threshold
                ),
                CandidateStatus::NotRefitted => format!("screened but not refitted in round {}", round.index),
                CandidateStatus::Rejected(w) => format!("rejected in round {}: {w}", round.index),
                CandidateStatus::DetectedNegligible(w) => {
                    format!("detected, negligible in round {}: {w}", round.index)
                }
                CandidateStatus::PassedNotBest => format!("passed but not best in round {}", round.index),
                CandidateStatus::Added => "added".into(),
            };
            return Some(s);
        }
    }
    None
}

/// Whether an added instance is the hidden catalog instance (any order of the guide
/// polynomials).
fn same_instance(added: &EffectSpec, hidden: &EffectSpec) -> bool {
    match (added, hidden) {
        (EffectSpec::GuideAngular { .. }, EffectSpec::GuideAngular { .. }) => true,
        (EffectSpec::GuideStraightness { .. }, EffectSpec::GuideStraightness { .. }) => true,
        (a, b) => a == b,
    }
}

/// Whether an effect describes fixture coordinates: `position-offset`, `tcp-offset`,
/// `tool-frame` (what discovery adds for fixture errors).
fn is_fixture_type(spec: &EffectSpec) -> bool {
    matches!(spec, EffectSpec::PositionOffset { .. } | EffectSpec::TcpOffset { .. } | EffectSpec::ToolFrame)
}

/// Runs discovery on one case and scores it.
pub fn run_case(case: Case) -> CaseResult {
    run_case_with(case, &[])
}

/// [`run_case`] with the catalog effects named in `excluded` not proposed
/// (`DiscoverOptions::excluded_effects`).
pub fn run_case_with(case: Case, excluded: &[&str]) -> CaseResult {
    run_case_tuned(case, |o| o.excluded_effects = excluded.iter().map(|n| n.to_string()).collect())
}

/// [`run_case`] with the case's options ([`options_for`]) changed by `tune`.
pub fn run_case_tuned(mut case: Case, tune: impl Fn(&mut DiscoverOptions)) -> CaseResult {
    let Some(data) = CaseData::build(&mut case) else {
        return CaseResult::failed(case, 0, None, f64::NAN, 0.0, "the case could not be generated".into());
    };
    let truth_mm = {
        let e: Vec<Vector3<f64>> = data
            .validation
            .iter()
            .map(|m| match m.target {
                Target::Tracker { xyz_mm } => {
                    xyz_mm - data.truth.position(&m.q, &m.context, m.tcp).unwrap_or(xyz_mm)
                }
                Target::Probe { .. } | Target::Orientation { .. } | Target::Plane { .. } => Vector3::zeros(),
            })
            .collect();
        ErrorStats::from_errors(&e).mean
    };
    let floor_mm = floor(&case, &data).ok();
    let mut options = options_for(&case, &data);
    tune(&mut options);
    let t0 = Instant::now();
    let result = discover(&data.nominal, &data.measurements, &data.params, Some(&data.validation), &options);
    let seconds = t0.elapsed().as_secs_f64();
    let d = match result {
        Ok(d) => d,
        Err(e) => {
            return CaseResult::failed(
                case,
                data.measurements.len(),
                floor_mm,
                truth_mm,
                seconds,
                e.to_string(),
            );
        }
    };
    let guide = data.nominal.guide_joint().unwrap_or(1) as u8;
    let n = data.nominal.joint_count() as u8;
    let added_drivers: Vec<Driver> =
        d.added_effects.iter().map(|a| driver_of_in(&a.spec, guide, n)).collect();
    let hidden = case
        .effects()
        .map(|h| {
            let drivers = h.shape.drivers(&data.nominal);
            let named_driver = added_drivers.iter().any(|a| drivers.contains(a));
            let named_exactly = match &h.shape {
                Shape::Catalog(spec) => d.added_effects.iter().any(|a| same_instance(&a.spec, spec)),
                _ => false,
            };
            let why = if named_driver {
                String::new()
            } else {
                last_status(&d, &h.shape).unwrap_or_else(|| {
                    d.rounds.last().map_or(String::new(), |r| format!("last round: {}", r.decision))
                })
            };
            HiddenOutcome {
                label: h.shape.label(),
                in_catalog: h.shape.in_catalog(),
                multiple: h.multiple,
                named_driver,
                named_exactly,
                why,
            }
        })
        .collect();
    let hidden_specs: Vec<EffectSpec> =
        case.effects().filter_map(|h| if let Shape::Catalog(s) = h.shape { Some(s) } else { None }).collect();
    let fixture_additions = d
        .added_effects
        .iter()
        .filter(|a| is_fixture_type(&a.spec) && !hidden_specs.iter().any(|h| same_instance(&a.spec, h)))
        .map(|a| a.label.clone())
        .collect();
    CaseResult {
        tags: case.categories(),
        rows: data.measurements.len(),
        hidden,
        fixture_additions,
        added: d.added_effects.iter().map(|a| a.label.clone()).collect(),
        negligible: d
            .negligible_effects
            .iter()
            .map(|x| format!("{} ({:.1} um)", x.label, x.change_um))
            .collect(),
        start_mm: d.initial_gap.validation.as_ref().map_or(f64::NAN, |v| v.mean),
        discovered_mm: d.final_gap.validation.as_ref().map_or(f64::NAN, |v| v.mean),
        floor_mm,
        truth_mm,
        rounds: d.rounds.len(),
        seconds,
        error: None,
        case,
    }
}

/// Size bins of the detection table (multiples of the noise).
pub const SIZE_BINS: [(f64, f64); 4] = [(0.0, 1.0), (1.0, 3.0), (3.0, 10.0), (10.0, f64::INFINITY)];

/// Totals of a run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Totals {
    /// effects of at least [`MUST_NAME`] × noise
    pub must_name: usize,
    /// of them, named with their driver
    pub must_name_named: usize,
    /// null cases
    pub null_cases: usize,
    /// null cases where something was added
    pub null_additions: usize,
    /// cases with a floor
    pub with_floor: usize,
    /// of them, discovered ≤ [`FLOOR_FACTOR`] × floor
    pub within_floor: usize,
    /// catalog effects of at least [`MUST_NAME`] × noise
    pub must_name_catalog: usize,
    /// of them, named exactly (the hidden instance added)
    pub must_name_exact: usize,
    /// cases (that ran)
    pub cases: usize,
    /// cases with fixture errors
    pub fixture_cases: usize,
    /// of them, cases where a fixture-type effect that is not hidden was added
    pub fixture_additions: usize,
    /// discovered / floor of the cases with a floor, sorted
    pub ratios: Vec<f64>,
}

impl Totals {
    /// The `p` quantile (0..=1) of the ratios; `None` without any.
    pub fn ratio_quantile(&self, p: f64) -> Option<f64> {
        if self.ratios.is_empty() {
            return None;
        }
        Some(self.ratios[((self.ratios.len() - 1) as f64 * p.clamp(0.0, 1.0)).round() as usize])
    }
}

/// Totals of `results` restricted to `keep`.
pub fn totals(results: &[CaseResult], keep: impl Fn(&CaseResult) -> bool) -> Totals {
    let mut t = Totals::default();
    for r in results.iter().filter(|r| keep(r) && r.error.is_none()) {
        t.cases += 1;
        for h in r.hidden.iter().filter(|h| h.multiple >= MUST_NAME) {
            t.must_name += 1;
            t.must_name_named += usize::from(h.named_driver);
            if h.in_catalog {
                t.must_name_catalog += 1;
                t.must_name_exact += usize::from(h.named_exactly);
            }
        }
        if r.case.has_fixture_errors() {
            t.fixture_cases += 1;
            t.fixture_additions += usize::from(!r.fixture_additions.is_empty());
        }
        if r.case.is_null() {
            t.null_cases += 1;
            t.null_additions += usize::from(r.false_positive());
        }
        if let Some(x) = r.ratio() {
            t.with_floor += 1;
            t.within_floor += usize::from(x <= FLOOR_FACTOR);
            t.ratios.push(x);
        }
    }
    t.ratios.sort_by(f64::total_cmp);
    t
}

/// A subset of the results (a row of the targets table).
type Subset = Box<dyn Fn(&CaseResult) -> bool>;

fn pct(a: usize, b: usize) -> String {
    if b == 0 { "—".into() } else { format!("{a}/{b} = {:.0} %", 100.0 * a as f64 / b as f64) }
}

/// The results as the Markdown tables of `docs/discovery-benchmark.md`.
pub fn markdown(results: &[CaseResult]) -> String {
    let mut s = String::new();
    targets_table(&mut s, results);
    category_table(&mut s, results);
    size_table(&mut s, results);
    wrong_table(&mut s, results);
    s
}

/// The targets per subset of the cases.
fn targets_table(s: &mut String, results: &[CaseResult]) {
    use std::fmt::Write;
    let _ = writeln!(s, "### Targets\n");
    let _ = writeln!(
        s,
        "| subset | effects ≥ {MUST_NAME}× noise named with their driver (goal ≥ 95 %) | null cases with an addition (goal ≤ 1 %) | held-out ≤ {FLOOR_FACTOR}× floor (goal ≥ 90 %) |"
    );
    let _ = writeln!(s, "|---|---|---|---|");
    let subsets: Vec<(&str, Subset)> = vec![
        ("all cases", Box::new(|_| true)),
        ("without noise metadata", Box::new(|r| !r.case.noise_metadata)),
        ("with noise metadata", Box::new(|r| r.case.noise_metadata)),
        ("canonical cell", Box::new(|r| r.case.robot == Robot::Canonical)),
        ("UR5e", Box::new(|r| r.case.robot == Robot::Ur5e)),
        ("probe-only data", Box::new(|r| r.case.data == DataKind::Probe)),
        ("tracker-only data", Box::new(|r| r.case.data == DataKind::Tracker)),
        ("mixed data", Box::new(|r| r.case.data == DataKind::Mixed)),
        ("with replicates", Box::new(|r| r.case.replicates)),
        ("without replicates", Box::new(|r| !r.case.replicates)),
        (
            "catalog effects only",
            Box::new(|r| !r.case.is_null() && r.case.effects().all(|h| h.shape.in_catalog())),
        ),
        ("with extra physics", Box::new(|r| r.case.effects().any(|h| !h.shape.in_catalog()))),
    ];
    for (name, keep) in &subsets {
        let t = totals(results, keep);
        let _ = writeln!(
            s,
            "| {name} | {} | {} | {} |",
            pct(t.must_name_named, t.must_name),
            pct(t.null_additions, t.null_cases),
            pct(t.within_floor, t.with_floor)
        );
    }
}

/// The outcomes per category.
fn category_table(s: &mut String, results: &[CaseResult]) {
    use std::fmt::Write;
    let _ = writeln!(s, "\n### By category\n");
    let _ = writeln!(
        s,
        "| category | cases | effects ≥ {MUST_NAME}× named with their driver | catalog effects ≥ {MUST_NAME}× named exactly | null cases with an addition | fixture cases with a fixture-type addition not hidden | held-out ≤ {FLOOR_FACTOR}× floor | held-out / floor: median, max |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    let mut rows: Vec<(String, Totals)> = vec![("all cases".into(), totals(results, |_| true))];
    for c in Category::ALL {
        rows.push((format!("{} (`{}`)", c.label(), c.tag()), totals(results, |r| r.tags.contains(&c))));
    }
    rows.push(("none of these".into(), totals(results, |r| r.tags.is_empty())));
    for (name, t) in &rows {
        let spread = match (t.ratio_quantile(0.5), t.ratio_quantile(1.0)) {
            (Some(m), Some(x)) => format!("{m:.2}, {x:.2}"),
            _ => "—".into(),
        };
        let _ = writeln!(
            s,
            "| {name} | {} | {} | {} | {} | {} | {} | {spread} |",
            t.cases,
            pct(t.must_name_named, t.must_name),
            pct(t.must_name_exact, t.must_name_catalog),
            pct(t.null_additions, t.null_cases),
            pct(t.fixture_additions, t.fixture_cases),
            pct(t.within_floor, t.with_floor),
        );
    }
}

/// Detection by size, the held-out / floor ratios and the wall time.
fn size_table(s: &mut String, results: &[CaseResult]) {
    use std::fmt::Write;
    let ok: Vec<&CaseResult> = results.iter().filter(|r| r.error.is_none()).collect();
    let _ = writeln!(s, "\n### Detection by size (multiples of the noise of the prediction change)\n");
    let _ = writeln!(
        s,
        "| size | catalog: named with driver | catalog: named exactly | extra physics: named with driver |"
    );
    let _ = writeln!(s, "|---|---|---|---|");
    for (lo, hi) in SIZE_BINS {
        let in_bin = |h: &&HiddenOutcome| h.multiple >= lo && h.multiple < hi;
        let cat: Vec<&HiddenOutcome> =
            ok.iter().flat_map(|r| &r.hidden).filter(|h| h.in_catalog).filter(in_bin).collect();
        let ext: Vec<&HiddenOutcome> =
            ok.iter().flat_map(|r| &r.hidden).filter(|h| !h.in_catalog).filter(in_bin).collect();
        let range = if hi.is_finite() { format!("[{lo}, {hi})") } else { format!("≥ {lo}") };
        let _ = writeln!(
            s,
            "| {range} | {} | {} | {} |",
            pct(cat.iter().filter(|h| h.named_driver).count(), cat.len()),
            pct(cat.iter().filter(|h| h.named_exactly).count(), cat.len()),
            pct(ext.iter().filter(|h| h.named_driver).count(), ext.len()),
        );
    }
    let mut ratios: Vec<f64> = ok.iter().filter_map(|r| r.ratio()).collect();
    ratios.sort_by(f64::total_cmp);
    if !ratios.is_empty() {
        let q = |p: f64| ratios[((ratios.len() - 1) as f64 * p).round() as usize];
        let _ = writeln!(
            s,
            "\nHeld-out (validation) error / true-structure floor over {} cases: median {:.2}, 90th percentile {:.2}, max {:.2}.",
            ratios.len(),
            q(0.5),
            q(0.9),
            q(1.0)
        );
    }
    let secs: f64 = ok.iter().map(|r| r.seconds).sum();
    let _ = writeln!(
        s,
        "Discovery wall time summed over the cases: {secs:.0} s; failed runs: {}.",
        results.len() - ok.len()
    );
}

/// The cases it gets wrong, one row each.
fn wrong_table(s: &mut String, results: &[CaseResult]) {
    use std::fmt::Write;
    let _ = writeln!(s, "\n### Cases it gets wrong\n");
    let _ = writeln!(
        s,
        "| case | tags | robot, data, replicates, noise given | hidden (size ×noise) | added | validation mm: start / discovered / floor | what went wrong |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for r in results {
        let wrong = what_went_wrong(r);
        if wrong.is_empty() {
            continue;
        }
        let hidden: Vec<String> =
            r.case.hidden.iter().map(|h| format!("{} ({:.1})", h.shape.label(), h.multiple)).collect();
        let _ = writeln!(
            s,
            "| {} | {} | {:?}, {:?}, {}, {} | {} | {} | {:.4} / {:.4} / {} | {} |",
            r.case.id,
            r.case.tags(),
            r.case.robot,
            r.case.data,
            if r.case.replicates { "yes" } else { "no" },
            if r.case.noise_metadata { "yes" } else { "no" },
            if hidden.is_empty() { "none".into() } else { hidden.join("; ") },
            if r.added.is_empty() { "—".into() } else { r.added.join("; ") },
            r.start_mm,
            r.discovered_mm,
            r.floor_mm.map_or("—".into(), |f| format!("{f:.4}")),
            wrong.join("; ").replace('|', "/")
        );
    }
}

/// What went wrong in one case (empty when nothing did).
fn what_went_wrong(r: &CaseResult) -> Vec<String> {
    let mut wrong = Vec::new();
    if let Some(e) = &r.error {
        wrong.push(format!("run failed: {e}"));
    }
    for h in r.hidden.iter().filter(|h| h.multiple >= MUST_NAME && !h.named_driver) {
        wrong.push(format!(
            "missed {} ({:.1}×): {}",
            h.label,
            h.multiple,
            if h.why.is_empty() { "—" } else { &h.why }
        ));
    }
    for h in r
        .hidden
        .iter()
        .filter(|h| h.in_catalog && h.multiple >= MUST_NAME && h.named_driver && !h.named_exactly)
    {
        wrong.push(format!("{} ({:.1}×) named only through its driver (not exactly)", h.label, h.multiple));
    }
    if r.false_positive() {
        wrong.push("added on a null case".into());
    } else if !r.fixture_additions.is_empty() {
        wrong.push(format!("fixture-type addition not hidden: {}", r.fixture_additions.join(", ")));
    }
    if r.ratio().is_some_and(|x| x > FLOOR_FACTOR) {
        wrong.push(format!("held-out {:.2}× the floor", r.ratio().unwrap_or(f64::NAN)));
    }
    wrong
}

/// A canonical-cell probe case (no replicates, noise recorded) with one hidden catalog effect
/// of `multiple` × the noise, built with `seed` (the proposal's test and timing example).
pub fn probe_case_with(seed: u64, spec: EffectSpec, multiple: f64) -> CaseData {
    let mut c = Case {
        id: 0,
        seed,
        robot: Robot::Canonical,
        data: DataKind::Probe,
        replicates: false,
        noise_metadata: true,
        hidden: vec![HiddenEffect {
            shape: Shape::Catalog(spec),
            values: Vec::new(),
            requested_multiple: multiple,
            multiple,
        }],
    };
    CaseData::build(&mut c).expect("case")
}

/// Discovery on `ms` of a probe case from its nominal model and parameters, with the probe's
/// stated noise and `seed`.
pub fn discover_probe_case(d: &CaseData, ms: &[Measurement], seed: u64) -> Discovery {
    let options = DiscoverOptions {
        seed,
        instrument_sigmas: Some(KindSigmas { probe_mm: Some(PROBE_SIGMA_MM), tracker_mm: None }),
        ..DiscoverOptions::default()
    };
    discover(&d.nominal, ms, &d.params, Some(&d.validation), &options).expect("discover")
}
