//! The model-IK front door ([`ModelIk`]): a closed form wherever the chain qualifies, the
//! multi-start numerical IK otherwise.

use nalgebra::{Matrix3, Vector3};
use vatcal_core::{Frame, JointVector};
use vatcal_kinematics::Model;

use super::common::{RefineOptions, wrap_angle};
use super::refine::ChainTool;
use super::tool_pose::ToolPoseIk;
use crate::error::PlanError;
use crate::numeric_ik::{IkTarget, JointSpec, MultiStartOptions, NumericIk, solve_local};
use crate::parallel_arm::ParallelArm;

/// Per joint of `model` (1..=N): true when revolute.
fn revolute_joints(model: &Model) -> Vec<bool> {
    model.joint_kinds().iter().map(|k| k.is_revolute()).collect()
}

/// The numerical IK's view of joint `i` (1-based) of `model`: kind and limits (none for a
/// continuous joint).
fn joint_spec(model: &Model, i: usize, revolute: bool) -> JointSpec {
    match (model.joint_limit(i), revolute) {
        (Some((lo, hi)), true) => JointSpec::revolute(lo, hi),
        (Some((lo, hi)), false) => JointSpec::prismatic(lo, hi),
        (None, true) => JointSpec::continuous(),
        // a prismatic joint always has limits in a valid cell; NumericIk::new reports it otherwise
        (None, false) => JointSpec { revolute: false, limits: None },
    }
}

/// Which inverse kinematics a [`ModelIk`] uses.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum IkMethod {
    /// Closed form on the nominal geometry (6R arm with a spherical wrist, up to 8 branches),
    /// refined on the full model ([`ToolPoseIk`]).
    ClosedForm,
    /// Closed form on the nominal geometry of a 6R arm with three parallel middle axes and a
    /// UR-type wrist ([`ParallelArm`], up to 8 branches), refined on the full model
    /// ([`ToolPoseIk`]).
    ParallelClosedForm,
    /// Multi-start numerical IK ([`crate::numeric_ik::NumericIk`]); `reason` says why the
    /// closed form does not apply (`None` when the numerical IK was asked for).
    Numerical {
        /// why the chain does not qualify for the closed form
        reason: Option<String>,
    },
}

impl std::fmt::Display for IkMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::ClosedForm => {
                write!(
                    f,
                    "closed form (6R arm with a spherical wrist, up to 8 branches), refined on the model"
                )
            }
            Self::ParallelClosedForm => {
                write!(
                    f,
                    "closed form (6R arm with three parallel middle axes and a UR-type wrist, up to 8 branches), refined on the model"
                )
            }
            Self::Numerical { reason: Some(r) } => write!(f, "multi-start numerical (no closed form: {r})"),
            Self::Numerical { reason: None } => write!(f, "multi-start numerical"),
        }
    }
}

/// Inverse kinematics of the tool-changer frame of any [`Model`]: the closed form + refinement
/// ([`ToolPoseIk`]) when the chain is a 6R arm with a spherical wrist
/// ([`ArmGeometry::from_model`](crate::ik::ArmGeometry::from_model)) or — with
/// [`ModelIk::closed_form_first`] — with three parallel middle axes and a UR-type wrist
/// ([`ParallelArm::from_model`]), alone or behind one prismatic guide, the multi-start numerical IK ([`crate::numeric_ik::NumericIk`] on a [`ChainTool`])
/// otherwise ([`ModelIk::method`] says which, and why not a closed form). The first prismatic joint, if any, is the guide: it is
/// held at the given guide positions and the other joints are solved for; a chain without one
/// ignores the guide positions.
#[derive(Debug)]
pub struct ModelIk<'a> {
    pub(super) model: &'a Model,
    solver: Solver<'a>,
}

#[derive(Debug)]
enum Solver<'a> {
    /// the closed form, and every joint's spec (to normalise the solutions into the limits)
    ClosedForm(Box<ToolPoseIk<'a>>, Vec<JointSpec>),
    /// the closed form of an arm with three parallel middle axes, and every joint's spec
    Parallel(Box<ToolPoseIk<'a, ParallelArm>>, Vec<JointSpec>),
    Numeric {
        guide: Option<usize>,
        free: Vec<usize>,
        specs: Vec<JointSpec>,
        opts: MultiStartOptions,
        reason: Option<String>,
    },
}

impl<'a> ModelIk<'a> {
    /// The spherical-wrist closed form when the model allows it, the numerical IK otherwise
    /// (the IK of every user of this type outside the candidate generator: compensation,
    /// validation, the campaign; see [`ModelIk::closed_form_first`] for the closed form of arms
    /// with three parallel middle axes too).
    ///
    /// # Examples
    /// The Meca500 alone on a table has a spherical wrist; the UR5e has not:
    /// ```
    /// use vatcal_core::CellFile;
    /// use vatcal_kinematics::Model;
    /// use vatcal_planning::ik::{IkMethod, ModelIk, RefineOptions};
    /// use vatcal_planning::numeric_ik::MultiStartOptions;
    ///
    /// let fixture = |name: &str| -> Result<Model, Box<dyn std::error::Error>> {
    ///     let path = format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    ///     Ok(Model::from_cell(&CellFile::load(path)?)?)
    /// };
    /// let table = fixture("meca500-table.toml")?;
    /// let ik = ModelIk::new(&table, RefineOptions::default(), MultiStartOptions::default())?;
    /// assert_eq!(ik.method(), IkMethod::ClosedForm);
    /// let ur5e = fixture("ur5e.toml")?;
    /// let ik = ModelIk::new(&ur5e, RefineOptions::default(), MultiStartOptions::default())?;
    /// assert!(ik.method().to_string().contains("spherical wrist"));
    /// // it has three parallel middle axes and a UR-type wrist
    /// let ik = ModelIk::closed_form_first(&ur5e, RefineOptions::default(), MultiStartOptions::default())?;
    /// assert_eq!(ik.method(), IkMethod::ParallelClosedForm);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// Invalid numerical-IK options or joint limits ([`PlanError::Option`]).
    pub fn new(
        model: &'a Model,
        refine: RefineOptions,
        numeric: MultiStartOptions,
    ) -> Result<Self, PlanError> {
        match ToolPoseIk::new(model, refine) {
            Ok(ik) => Ok(Self { model, solver: Solver::ClosedForm(Box::new(ik), all_joint_specs(model)) }),
            Err(PlanError::UnsupportedArm(reason)) => Self::numerical_because(model, numeric, reason),
            Err(e) => Err(e),
        }
    }

    /// A closed form when the model allows it — a spherical wrist
    /// ([`ArmGeometry`](crate::ik::ArmGeometry)) first, then three parallel middle axes with a UR-type wrist ([`ParallelArm`]) — the numerical IK
    /// otherwise, naming why neither closed form applies. The candidate generator's default
    /// ([`crate::candidates::IkChoice::ClosedFormFirst`]).
    ///
    /// The solutions of a pose are the same set as [`ModelIk::new`]'s up to rounding where the
    /// numerical IK finds every branch, in closed-form branch order instead of the order the
    /// starts found them; callers that pick among equally good solutions by their order get
    /// other picks.
    ///
    /// # Errors
    /// Invalid numerical-IK options or joint limits ([`PlanError::Option`]).
    pub fn closed_form_first(
        model: &'a Model,
        refine: RefineOptions,
        numeric: MultiStartOptions,
    ) -> Result<Self, PlanError> {
        let spherical = match ToolPoseIk::new(model, refine) {
            Ok(ik) => {
                return Ok(Self { model, solver: Solver::ClosedForm(Box::new(ik), all_joint_specs(model)) });
            }
            Err(PlanError::UnsupportedArm(reason)) => reason,
            Err(e) => return Err(e),
        };
        let parallel = match ToolPoseIk::<ParallelArm>::with_closed_form(model, refine) {
            Ok(ik) => {
                return Ok(Self { model, solver: Solver::Parallel(Box::new(ik), all_joint_specs(model)) });
            }
            Err(PlanError::UnsupportedArm(reason)) => reason,
            Err(e) => return Err(e),
        };
        let reason = if spherical == parallel { spherical } else { format!("{spherical}; {parallel}") };
        Self::numerical_because(model, numeric, reason)
    }

    /// The numerical IK, `reason` saying why no closed form applies.
    fn numerical_because(
        model: &'a Model,
        numeric: MultiStartOptions,
        reason: String,
    ) -> Result<Self, PlanError> {
        let mut me = Self::numerical(model, numeric)?;
        if let Solver::Numeric { reason: r, .. } = &mut me.solver {
            *r = Some(reason);
        }
        Ok(me)
    }

    /// Always the numerical IK (also for a Meca500-like arm, e.g. to cross-check the closed form).
    ///
    /// # Errors
    /// Invalid options or joint limits ([`PlanError::Option`]).
    pub fn numerical(model: &'a Model, numeric: MultiStartOptions) -> Result<Self, PlanError> {
        let revolute = revolute_joints(model);
        let guide = revolute.iter().position(|r| !r).map(|k| k + 1);
        let free: Vec<usize> = (1..=revolute.len()).filter(|i| Some(*i) != guide).collect();
        let specs: Vec<JointSpec> = free.iter().map(|i| joint_spec(model, *i, revolute[i - 1])).collect();
        let me = Self { model, solver: Solver::Numeric { guide, free, specs, opts: numeric, reason: None } };
        // validate the options and limits once
        me.numeric_at(0.0).transpose()?;
        Ok(me)
    }

    /// True when a closed form is in use.
    pub fn is_closed_form(&self) -> bool {
        matches!(self.solver, Solver::ClosedForm(..) | Solver::Parallel(..))
    }

    /// The IK in use (and why not the closed form).
    pub fn method(&self) -> IkMethod {
        match &self.solver {
            Solver::ClosedForm(..) => IkMethod::ClosedForm,
            Solver::Parallel(..) => IkMethod::ParallelClosedForm,
            Solver::Numeric { reason, .. } => IkMethod::Numerical { reason: reason.clone() },
        }
    }

    /// The joint held at the guide positions (1-based), if the chain has one.
    pub fn guide_joint(&self) -> Option<usize> {
        match &self.solver {
            Solver::ClosedForm(ik, _) => ik.guide_joint(),
            Solver::Parallel(ik, _) => ik.guide_joint(),
            Solver::Numeric { guide, .. } => *guide,
        }
    }

    /// The model.
    pub fn model(&self) -> &'a Model {
        self.model
    }

    /// The numerical solver with the guide at `guide_mm` (`None` for the closed form).
    fn numeric_at(&self, guide_mm: f64) -> Option<Result<NumericIk<ChainTool<'a>>, PlanError>> {
        let Solver::Numeric { guide, free, specs, opts, .. } = &self.solver else {
            return None;
        };
        let mut fixed = JointVector::zeros(self.model.joint_count());
        if let Some(g) = guide {
            fixed.set(*g, guide_mm);
        }
        let revolute = specs.iter().map(|s| s.revolute).collect();
        let tool = ChainTool { model: self.model, fixed, free: free.clone(), revolute };
        Some(NumericIk::new(tool, specs, *opts))
    }

    /// Every solution with the guide at `guide_mm` (ignored without a guide), duplicates
    /// merged; revolute joints wrapped to (-pi, pi] where the limits allow, else moved by whole
    /// turns into the limits. The numerical IK returns solutions inside the limits only, the
    /// closed form every branch (also outside the limits, as [`ToolPoseIk`]).
    pub fn solve_at_guide(&self, guide_mm: f64, target: &Frame) -> Vec<JointVector> {
        match self.numeric_at(guide_mm) {
            None => match &self.solver {
                Solver::ClosedForm(ik, specs) => normalised(ik.solve_at_guide(guide_mm, target), specs),
                Solver::Parallel(ik, specs) => normalised(ik.solve_at_guide(guide_mm, target), specs),
                Solver::Numeric { .. } => Vec::new(),
            },
            Some(Err(_)) => Vec::new(),
            Some(Ok(ik)) => {
                let out = ik.solve(&IkTarget::Pose(*target));
                out.joints().map(|q| ik.kinematics().joints(q)).collect()
            }
        }
    }

    /// Like [`ModelIk::solve_at_guide`], warm-started when the numerical IK is in use: the
    /// joint vectors `warm` (solutions of a neighbouring target, e.g. the previous guide step
    /// or a nearby tool orientation; their guide value is ignored) are tried first, and the
    /// search stops as soon as `enough` distinct solutions are found (0: every start is tried;
    /// see [`NumericIk::solve_warm`]). A closed form ignores `warm` and `enough` (it is exact
    /// and complete). Deterministic for given arguments.
    pub fn solve_at_guide_warm(
        &self,
        guide_mm: f64,
        target: &Frame,
        warm: &[JointVector],
        enough: usize,
    ) -> Vec<JointVector> {
        let (Solver::Numeric { free, .. }, Some(Ok(ik))) = (&self.solver, self.numeric_at(guide_mm)) else {
            return self.solve_at_guide(guide_mm, target);
        };
        let starts: Vec<Vec<f64>> = warm.iter().map(|q| free.iter().map(|i| q.get(*i)).collect()).collect();
        let starts: Vec<&[f64]> = starts.iter().map(Vec::as_slice).collect();
        let out = ik.solve_warm(&IkTarget::Pose(*target), &starts, enough);
        out.joints().map(|q| ik.kinematics().joints(q)).collect()
    }

    /// Every solution over several guide positions (one pass when the chain has no guide).
    pub fn solve(&self, guide_positions_mm: &[f64], target: &Frame) -> Vec<JointVector> {
        if self.guide_joint().is_none() {
            return self.solve_at_guide(0.0, target);
        }
        guide_positions_mm.iter().flat_map(|g| self.solve_at_guide(*g, target)).collect()
    }

    /// One local solve ([`solve_local`]) from `q` so that the tool-changer frame reaches
    /// `target`, with the guide joint (the first prismatic joint, if any) held at its value in
    /// `q` and the other joints kept inside their limits; each revolute value of the result is
    /// then moved by whole turns to the representative nearest its value in `q` (a short move
    /// from `q`, e.g. to a retreat pose). Works on any chain, closed form or not.
    ///
    /// # Errors
    /// [`PlanError::IkNotConverged`] when the local solve misses the tolerances of `refine`.
    pub fn refine_from(
        &self,
        q: &JointVector,
        target: &Frame,
        refine: &RefineOptions,
    ) -> Result<JointVector, PlanError> {
        let revolute = revolute_joints(self.model);
        let guide = revolute.iter().position(|r| !r).map(|k| k + 1);
        let free: Vec<usize> = (1..=revolute.len()).filter(|i| Some(*i) != guide).collect();
        let specs: Vec<JointSpec> =
            free.iter().map(|i| joint_spec(self.model, *i, revolute[i - 1])).collect();
        let tool = ChainTool {
            model: self.model,
            fixed: *q,
            free: free.clone(),
            revolute: free.iter().map(|i| revolute[i - 1]).collect(),
        };
        let start: Vec<f64> = free.iter().map(|i| q.get(*i)).collect();
        let r = solve_local(&tool, &specs, &start, &IkTarget::Pose(*target), refine)?;
        let mut out = tool.joints(&r.q);
        for i in free.into_iter().filter(|i| revolute[i - 1]) {
            let q0 = q.get(i);
            out.set(i, q0 + wrap_angle(out.get(i) - q0));
        }
        Ok(out)
    }
}

/// Every joint's spec of `model` (the closed forms normalise their solutions into the limits
/// with them).
fn all_joint_specs(model: &Model) -> Vec<JointSpec> {
    let revolute = revolute_joints(model);
    (1..=revolute.len()).map(|i| joint_spec(model, i, revolute[i - 1])).collect()
}

/// `solutions` with every value normalised into its joint's limits ([`JointSpec::normalise`]).
fn normalised(mut solutions: Vec<JointVector>, specs: &[JointSpec]) -> Vec<JointVector> {
    for q in &mut solutions {
        for (v, spec) in q.as_mut_slice().iter_mut().zip(specs) {
            *v = spec.normalise(*v);
        }
    }
    solutions
}

/// World tool-changer-frame pose that puts TCP offset `tcp_in_tool` at `point_world` with tool
/// orientation `rotation` (world).
pub fn tool_pose_for_tcp(
    rotation: &Matrix3<f64>,
    tcp_in_tool: &Vector3<f64>,
    point_world: &Vector3<f64>,
) -> Frame {
    Frame { r: *rotation, p: point_world - rotation * tcp_in_tool }
}
