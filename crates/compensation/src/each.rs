//! Independent poses: every row solved on its own (`vatcal compensate --each`).
//!
//! A list of unrelated poses (a measurement plan, the spots of a fixture, poses picked by
//! hand) is not a path: consecutive rows may need any joint change and any IK branch. Each row
//! here gets all the IK solutions of its pose under the calibrated model and keeps one:
//!
//! 1. on the branch the row names ([`Compensator::compensate_each`]'s `branches`), else on
//!    [`EachOptions::branch`], else on any branch;
//! 2. inside the joint limits;
//! 3. by [`Preference`]: the solution nearest a given joint configuration
//!    ([`Preference::Near`]), or the one farthest from the joint limits
//!    ([`Preference::Clearance`], the default — what the first row of a path takes).

use std::f64::consts::TAU;

use vatcal_core::JointVector;

use crate::path::{Compensated, Compensator, PathResult, RowOutcome, SkippedRow};
use crate::solve::{Branch, SolveOptions, Solved, newton};
use crate::{CompensationError, ToolTarget};

/// Which of a pose's IK solutions (on the wanted branch, inside the limits) a row keeps.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum Preference {
    /// The solution whose smallest distance of a solved joint to its limits is largest
    /// (revolute joints in rad, prismatic in mm; continuous joints have no limit).
    #[default]
    Clearance,
    /// The solution nearest this joint configuration (internal units, one value per joint of
    /// the chain; the given joints' values are not used): smallest Euclidean distance over the
    /// solved joints in degrees (revolute) and mm (prismatic). A revolute joint's solution is
    /// first moved by whole turns towards the configuration when its limits allow it.
    Near(JointVector),
}

/// Options of [`Compensator::compensate_each`].
#[derive(Debug, Clone, PartialEq)]
pub struct EachOptions {
    /// solver tolerances
    pub solve: SolveOptions,
    /// report unreachable rows (out of reach, joint limits, no solution on the wanted branch)
    /// as skips instead of failing
    pub skip_unreachable: bool,
    /// the branch of every row that names none (`None`: any branch)
    pub branch: Option<Branch>,
    /// which solution a row keeps
    pub prefer: Preference,
}

impl Default for EachOptions {
    /// Default solver, no skipping, any branch, the solution farthest from the limits.
    fn default() -> Self {
        Self {
            solve: SolveOptions::default(),
            skip_unreachable: false,
            branch: None,
            prefer: Preference::Clearance,
        }
    }
}

impl Compensator<'_> {
    /// Compensates independent poses: each row on its own, with no continuity between rows (no
    /// joint-jump limit, no branch kept from row to row). Row `k` is solved on the branch
    /// `branches[k]` when that is `Some` (`branches` may be shorter than `targets`, or empty),
    /// else on [`EachOptions::branch`], else on any branch; among the solutions on that branch
    /// inside the joint limits it keeps the one [`EachOptions::prefer`] asks for.
    ///
    /// [`PathResult::branch`] is the branch shared by every solved row, `None` when they
    /// differ.
    ///
    /// # Examples
    /// Two unrelated poses, the second on another branch than the first (a path would refuse
    /// it as a branch change):
    /// ```
    /// use vatcal_compensation::{Compensator, EachOptions, PoseRequest, RowOutcome};
    /// use vatcal_core::{CellFile, JointVector, MeasurementContext};
    /// use vatcal_kinematics::Model;
    ///
    /// let nominal = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
    /// let compensator = Compensator::new(&nominal, &nominal)?;
    /// let poses = [
    ///     JointVector::from_mm_deg(100.0, [10.0, 10.0, -20.0, 10.0, 40.0, 10.0]),
    ///     JointVector::from_mm_deg(20.0, [-40.0, -10.0, 20.0, -60.0, -50.0, 90.0]),
    /// ];
    /// let targets = poses
    ///     .iter()
    ///     .map(|q| {
    ///         let tool = nominal.chain(q).tool;
    ///         PoseRequest::from_tool_frame(&nominal, 1, *q, &tool, MeasurementContext::default())?
    ///             .tool_target(&nominal, 0)
    ///     })
    ///     .collect::<Result<Vec<_>, _>>()?;
    /// let result = compensator.compensate_each(&targets, &[], &EachOptions::default())?;
    /// for (row, outcome) in result.rows.iter().enumerate() {
    ///     let RowOutcome::Solved(c) = outcome else { panic!("row {row} skipped") };
    ///     assert!(c.position_residual_mm < 1e-6);
    /// }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`CompensationError::Option`] for a `Near` configuration of the wrong length or with a
    /// non-finite value; without [`EachOptions::skip_unreachable`], the first failing row's
    /// [`CompensationError::Unreachable`], [`CompensationError::BranchUnreachable`] or
    /// [`CompensationError::JointLimit`].
    pub fn compensate_each(
        &self,
        targets: &[ToolTarget],
        branches: &[Option<Branch>],
        opts: &EachOptions,
    ) -> Result<PathResult, CompensationError> {
        if let Preference::Near(q) = &opts.prefer {
            let n = self.calibrated().joint_count();
            if q.len() != n || q.as_slice().iter().any(|v| !v.is_finite()) {
                return Err(CompensationError::Option {
                    option: "near",
                    reason: format!("needs {n} finite joint values, got {:?}", q.as_slice()),
                });
            }
        }
        let mut rows = Vec::with_capacity(targets.len());
        for (row, target) in targets.iter().enumerate() {
            let branch = branches.get(row).copied().flatten().or(opts.branch);
            match self.solve_one(row, target, branch, opts) {
                Ok(c) => rows.push(RowOutcome::Solved(c)),
                Err(error) if opts.skip_unreachable && error.row().is_some() => {
                    rows.push(RowOutcome::Skipped(SkippedRow { row, error }));
                }
                Err(e) => return Err(e),
            }
        }
        let mut solved = rows.iter().filter_map(|r| match r {
            RowOutcome::Solved(c) => Some(c.branch),
            RowOutcome::Skipped(_) => None,
        });
        let first = solved.next();
        let branch = first.filter(|b| solved.all(|o| o == *b));
        Ok(PathResult { rows, branch })
    }

    fn solve_one(
        &self,
        row: usize,
        target: &ToolTarget,
        branch: Option<Branch>,
        opts: &EachOptions,
    ) -> Result<Compensated, CompensationError> {
        let solutions = self.all_solutions(target, &opts.solve);
        if solutions.is_empty() {
            return Err(CompensationError::Unreachable {
                row,
                reason: "no IK branch converges under the calibrated model".into(),
            });
        }
        let on_branch: Vec<Solved> = solutions
            .iter()
            .filter(|(b, _)| branch.is_none_or(|want| *b == want))
            .map(|(_, s)| match &opts.prefer {
                Preference::Near(near) => self.towards(target, *s, near, &opts.solve),
                Preference::Clearance => *s,
            })
            .collect();
        let Some(first) = on_branch.first() else {
            let mut available: Vec<Branch> = solutions.iter().map(|(b, _)| *b).collect();
            available.sort_by_key(|b| b.0);
            available.dedup();
            return Err(CompensationError::BranchUnreachable {
                row,
                branch: branch.unwrap_or(Branch(0)),
                available: available.iter().map(|b| b.column()).collect::<Vec<_>>().join(", "),
            });
        };
        let inside = on_branch.iter().filter(|s| self.calibrated().limit_violation(&s.q).is_none());
        let best = match &opts.prefer {
            Preference::Clearance => {
                inside.max_by(|a, b| self.clearance(&a.q).total_cmp(&self.clearance(&b.q)))
            }
            Preference::Near(near) => {
                inside.min_by(|a, b| self.distance(&a.q, near).total_cmp(&self.distance(&b.q, near)))
            }
        };
        match best {
            Some(s) => Ok(self.accept(*s, target)),
            None => {
                // every solution leaves the limits: name the first one's violation
                self.limits_ok(row, &first.q)?;
                Ok(self.accept(*first, target))
            }
        }
    }

    /// `s` with its revolute solved joints moved by whole turns towards `near` where the limits
    /// allow it, re-solved when that moved a joint (joint effects depend on the joint value
    /// itself, not only modulo 2π); `s` itself when the re-solve fails.
    fn towards(&self, target: &ToolTarget, s: Solved, near: &JointVector, opts: &SolveOptions) -> Solved {
        let model = self.calibrated();
        let mut q = s.q;
        let mut moved = false;
        for (slot, &k) in self.split().free().iter().enumerate() {
            if !self.split().free_revolute(slot) {
                continue;
            }
            let turned = q[k] + TAU * ((near[k] - q[k]) / TAU).round();
            if turned != q[k] && model.joint_limit(k + 1).is_none_or(|(lo, hi)| (lo..=hi).contains(&turned)) {
                q[k] = turned;
                moved = true;
            }
        }
        if moved { newton(model, self.split(), target, &q, opts).unwrap_or(s) } else { s }
    }

    /// Euclidean distance of the solved joints of `q` from `near`, in degrees (revolute) and
    /// mm (prismatic).
    fn distance(&self, q: &JointVector, near: &JointVector) -> f64 {
        self.split()
            .free()
            .iter()
            .enumerate()
            .map(|(slot, &k)| {
                let d = q[k] - near[k];
                if self.split().free_revolute(slot) { d.to_degrees() } else { d }
            })
            .map(|d| d * d)
            .sum::<f64>()
            .sqrt()
    }
}
