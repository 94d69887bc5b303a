//! Identifiability analysis: numerical rank, identifiable basis, redundant parameters and the
//! parameter combinations a measurement set cannot see (background.md §5).
//!
//! # The Jacobian
//! [`assemble_jacobian`] stacks, for every measurement, the 3 × L block
//! `d(FK − target)/dρ` from [`Model::measurement_jacobian_into`] (analytic, gravity torques
//! held fixed). Columns are in natural units: mm/mm, mm/rad, mm per rad/(N·m). Row order:
//! measurement k occupies rows `3k..3k+3` (x, y, z).
//!
//! # Column scaling ([`ColumnScaling`])
//! * `None` — natural units. O1 in these units is what the paper reports (background.md §3).
//! * `UnitNorm` — every column divided by its Euclidean norm over *the given rows*. Rank,
//!   condition number and singular-value ratios then do not depend on the choice of units.
//!   This is what [`analyze`] uses. (To compare designs, compute the norms once over the whole
//!   candidate set and apply them with [`scale_columns`].)
//! * `APriori` — every column multiplied by [`ParamId::typical_scale`], the a-priori standard
//!   deviation of the parameter error: a singular value then reads "mm of TCP error per
//!   one-sigma parameter change".
//!
//! # Rank tolerance
//! The rank is the number of singular values of the unit-column-normalised Jacobian above
//! `tol · σ₁` with `tol = max(1e-8, max(rows, cols) · ε)` (ε = f64 machine epsilon). The
//! columns are analytic derivatives, exact to round-off (~1e-15 relative), so exactly
//! redundant combinations show up near 1e-15 while the weakest physically identifiable
//! direction of this cell (c₇, the flange compliance) sits several orders of magnitude above
//! 1e-8. The `max(rows, cols) · ε` term is the usual LAPACK/NumPy floor for very tall
//! matrices. Normalising the columns first makes the tolerance independent of units (a
//! compliance column in mm per rad/(N·m) is ~1e3 times longer than an angle column in mm/rad).
//! Finite-difference Jacobians would need ~1e-6 (background.md §5.1) — pass it through
//! [`AnalysisOptions`].
//!
//! # Columns without effect
//! Normalising makes every non-zero column count, however small it is physically. A column
//! that is zero up to round-off would then look like an independent direction: the compliance
//! of a vertical first joint (UR5e, Meca500 on a table) has a gravity torque of ~1e-15 N·m, so
//! its column is round-off noise, and after normalisation that noise is "identifiable" — a
//! least-squares fit then takes huge steps along it and stalls. So before the rank test every
//! column's *a-priori effect* `‖J_j‖ · typical_scale_j` (mm of stacked residual per one
//! a-priori standard deviation of the parameter, [`ParamId::typical_scale`]) is compared with
//! the largest one; a column below [`NEGLIGIBLE_RELATIVE_EFFECT`] of it is treated as zero
//! (see [`negligible_columns`]) and reported as a parameter without effect. Real weak
//! parameters stay far above this floor: the flange compliance c_7 of the canonical cell sits
//! at 7.5e-5 of the strongest on 40 probe poses.
//!
//! # Which parameters are kept
//! A column-pivoted Householder QR whose pivot rule is *preference order*: the columns are
//! visited in the order of the given [`ParamSet`], and column j becomes the next pivot when
//! the norm of its part orthogonal to the already chosen columns exceeds the rank threshold;
//! otherwise it is dropped as redundant. The identifiable basis therefore always prefers
//! earlier parameters (faer's `ColPivQr` pivots on the largest remaining norm, which ignores
//! the preference, so the rule is implemented here).
//!
//! The QR's test on one column's remaining norm misses a dependency whose weights are large:
//! a column `x` times away from a combination of the kept ones in a direction of singular
//! value σ keeps a remaining norm of about `σ·x`, so σ = 1e-12 with weights of ~1e4 passes a
//! threshold of 1e-8. The kept columns could then be more than the SVD rank, with a direction
//! no data see among them (the UR5e on two unknown parallel planes kept `alpha_0` beside both
//! planes' tilts: 33 columns, rank 32, smallest singular value 1.1e-12). So the basis is
//! checked with the SVD criterion of the rank ([`full_rank_basis`]): while the kept columns'
//! own smallest singular value is at most the threshold, the parameter with the largest entry
//! in that singular vector is dropped (the one the others explain with the smallest weights;
//! among entries within [`TIE_FRACTION`] of the largest, the least preferred); if that leaves
//! fewer than `rank` columns, dropped columns are taken back in preference order as long as
//! the basis stays of full rank. The basis then has `rank` parameters and is of full rank on
//! its own — except when the smallest singular value counted in the rank lies within a small
//! factor of the threshold: no `rank` of the columns may then be of full rank, and the basis is
//! one short (the UR5e planes with a known distance between them: rank 34, σ₃₄ = 1.1 × the
//! threshold, basis 33; a largest-norm pivoted QR's 34 columns fall below the threshold too).
//! Every dropped column is then written as the least-squares combination of the kept columns
//! (faer QR), which names the parameters that absorb it.

use std::fmt;

use faer::linalg::solvers::SolveLstsq;
use faer::{Mat, MatRef};
use vatcal_core::{JointKind, Measurement, ParamId, ParamSet};
use vatcal_kinematics::Model;

use crate::error::ObservabilityError;
// resolving a `--params` spec needs the generic sets, which build on this module
pub use crate::sets::param_set_from_spec;

/// Default relative rank tolerance for analytic Jacobians (see the module docs).
pub const DEFAULT_RELATIVE_TOLERANCE: f64 = 1e-8;

/// A column whose a-priori effect (`‖J_j‖ · typical_scale_j`) is at most this fraction of the
/// largest column's is zero to round-off: the parameter has no effect on the measurements
/// (module docs, "Columns without effect").
pub const NEGLIGIBLE_RELATIVE_EFFECT: f64 = 1e-8;

/// A partner is named in a [`Redundancy`] when its normalised weight is at least this fraction
/// of the largest normalised weight.
const SIGNIFICANT_FRACTION: f64 = 0.1;
/// At most this many partners / entries are named per redundancy or lost direction.
const MAX_NAMED: usize = 8;

/// How Jacobian columns are scaled before an analysis (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ColumnScaling {
    /// Natural units (mm per parameter unit); the paper's O1 convention.
    None,
    /// Divide every column by its Euclidean norm (zero columns stay zero).
    #[default]
    UnitNorm,
    /// Multiply every column by the parameter's a-priori standard deviation
    /// ([`ParamId::typical_scale`]).
    APriori,
}

impl fmt::Display for ColumnScaling {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ColumnScaling::None => "raw (natural units)",
            ColumnScaling::UnitNorm => "unit-norm",
            ColumnScaling::APriori => "a-priori σ",
        })
    }
}

/// The factors `s_j` such that the scaled Jacobian is `J · diag(s)`.
pub fn column_scale_factors(j: MatRef<'_, f64>, params: &[ParamId], scaling: ColumnScaling) -> Vec<f64> {
    match scaling {
        ColumnScaling::None => vec![1.0; j.ncols()],
        ColumnScaling::UnitNorm => (0..j.ncols())
            .map(|c| {
                let n = j.col(c).norm_l2();
                if n > 0.0 { 1.0 / n } else { 1.0 }
            })
            .collect(),
        ColumnScaling::APriori => params.iter().map(|p| p.typical_scale()).collect(),
    }
}

/// Multiplies column j of `j` by `factors[j]`.
///
/// # Panics
/// If `factors.len() != j.ncols()` (a programming error).
#[track_caller]
pub fn scale_columns(j: &mut Mat<f64>, factors: &[f64]) {
    assert_eq!(factors.len(), j.ncols(), "scale_columns: one factor per column");
    for (c, f) in factors.iter().enumerate() {
        for x in j.col_mut(c).iter_mut() {
            *x *= f;
        }
    }
}

/// Indices of the columns without effect: natural-unit column norm × the parameter's
/// a-priori standard deviation ([`ParamId::typical_scale`]) at most
/// [`NEGLIGIBLE_RELATIVE_EFFECT`] times the largest such product (zero columns included).
/// `column_norms[j]` is the Euclidean norm of the natural-unit column of `params[j]`.
///
/// # Examples
/// ```
/// use vatcal_core::ParamId;
/// use vatcal_observability::identifiability::negligible_columns;
///
/// // d_2 moves the TCP by ~10 mm per mm; c_1 (a vertical joint) by round-off only
/// let params = [ParamId::D(2), ParamId::Compliance(1)];
/// assert_eq!(negligible_columns(&[10.0, 1e-12], &params), vec![1]);
/// ```
pub fn negligible_columns(column_norms: &[f64], params: &[ParamId]) -> Vec<usize> {
    let effects: Vec<f64> =
        column_norms.iter().zip(params).map(|(n, p)| n.abs() * p.typical_scale()).collect();
    let largest = effects.iter().fold(0.0_f64, |a, e| a.max(*e));
    (0..effects.len()).filter(|&j| effects[j] <= NEGLIGIBLE_RELATIVE_EFFECT * largest).collect()
}

/// Applies `scaling` to `j` in place and returns the factors used (`J ← J · diag(factors)`).
pub fn apply_column_scaling(j: &mut Mat<f64>, params: &ParamSet, scaling: ColumnScaling) -> Vec<f64> {
    let f = column_scale_factors(j.as_ref(), &params.0, scaling);
    scale_columns(j, &f);
    f
}

/// Stacks the 3 × L Jacobian blocks `d(FK − target)/dρ` of all measurements (3 rows per
/// measurement, natural units). Errors name the measurement index (0-based).
pub fn assemble_jacobian(
    model: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
) -> Result<Mat<f64>, ObservabilityError> {
    let l = params.len();
    let mut j = Mat::<f64>::zeros(3 * measurements.len(), l);
    let mut block = vec![0.0; 3 * l];
    for (k, m) in measurements.iter().enumerate() {
        measurement_block(model, m, &params.0, &mut block).map_err(|e| reindex(e, k))?;
        for c in 0..l {
            for r in 0..3 {
                j[(3 * k + r, c)] = block[3 * c + r];
            }
        }
    }
    Ok(j)
}

/// One measurement's 3 × L block, column-major into `out`, checked for finiteness.
pub(crate) fn measurement_block(
    model: &Model,
    m: &Measurement,
    params: &[ParamId],
    out: &mut [f64],
) -> Result<(), ObservabilityError> {
    model
        .measurement_jacobian_into(m, params, out)
        .map_err(|source| ObservabilityError::Model { index: 0, source })?;
    if let Some(c) = out.iter().position(|x| !x.is_finite()) {
        return Err(ObservabilityError::NonFinite { index: 0, param: params[c / 3] });
    }
    Ok(())
}

/// Replaces the measurement index of an error raised for a single measurement.
pub(crate) fn reindex(e: ObservabilityError, index: usize) -> ObservabilityError {
    match e {
        ObservabilityError::Model { source, .. } => ObservabilityError::Model { index, source },
        ObservabilityError::NonFinite { param, .. } => ObservabilityError::NonFinite { index, param },
        other => other,
    }
}

/// A parameter whose column is (numerically) a combination of the identifiable ones.
#[derive(Debug, Clone, PartialEq)]
pub struct Redundancy {
    /// the redundant parameter
    pub param: ParamId,
    /// the identifiable parameters that absorb it, with weights in natural units:
    /// `∂/∂param ≈ Σ weight · ∂/∂partner`, so a change δ of `param` is indistinguishable from
    /// changes `weight · δ` of the partners. Largest normalised contribution first.
    pub confounded_with: Vec<(ParamId, f64)>,
    /// the same weights on the unit-normalised columns (unit-free, comparable between
    /// partners), in the order of `confounded_with`
    pub normalized_weights: Vec<f64>,
    /// norm of the part of the unit-normalised column that the partners do not explain
    /// (≈ 0 for an exact redundancy, 1 for a column that has no effect at all)
    pub fit_residual: f64,
}

impl Redundancy {
    /// A sentence such as "a_1 is absorbed by base_y (-1)".
    pub fn sentence(&self) -> String {
        if self.confounded_with.is_empty() {
            let why = match self.param {
                ParamId::Compliance(_) => {
                    ": no gravity torque about this joint's axis (a vertical axis, or a massless chain beyond it)"
                }
                _ => "",
            };
            return format!(
                "{} has no effect on these measurements (its Jacobian column is zero to round-off{why})",
                self.param
            );
        }
        let partners: Vec<String> =
            self.confounded_with.iter().map(|(p, w)| format!("{p} ({w:.4})")).collect();
        format!("{} is absorbed by {}", self.param, partners.join(", "))
    }
}

/// A parameter combination the measurements cannot see: a right singular vector of the
/// unit-normalised Jacobian whose singular value is below the rank threshold.
#[derive(Debug, Clone, PartialEq)]
pub struct LostDirection {
    /// its singular value (of the unit-normalised Jacobian; 0 if there are fewer rows than
    /// parameters)
    pub singular_value: f64,
    /// the largest entries of the singular vector, largest magnitude first, in unit-normalised
    /// coordinates (entry × 1/‖column‖ is the change in natural units). Sign chosen so the
    /// first entry is positive.
    pub combination: Vec<(ParamId, f64)>,
}

impl LostDirection {
    /// A sentence such as "σ = 2.1e-16: +0.707 a_1 − 0.707 base_y".
    pub fn sentence(&self) -> String {
        let terms: Vec<String> = self
            .combination
            .iter()
            .enumerate()
            .map(|(i, (p, w))| {
                let sign = if *w < 0.0 {
                    "-"
                } else if i == 0 {
                    ""
                } else {
                    "+"
                };
                format!("{sign}{:.3} {p}", w.abs())
            })
            .collect();
        format!("σ = {:.2e}: {}", self.singular_value, terms.join(" "))
    }
}

/// Result of [`analyze`].
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifiabilityReport {
    /// numerical rank of the unit-normalised Jacobian
    pub rank: usize,
    /// number of parameters analysed (columns)
    pub parameter_count: usize,
    /// all `parameter_count` singular values of the unit-normalised Jacobian, descending
    /// (zeros appended when there are fewer rows than columns)
    pub singular_values: Vec<f64>,
    /// relative rank tolerance used (threshold = tolerance · σ₁)
    pub tolerance: f64,
    /// the identifiable basis chosen in preference order (a subset of the input, input order):
    /// `rank` parameters whose own columns are of full rank by the same SVD threshold (fewer
    /// only when a singular value counted in the rank is within a small factor of the
    /// threshold; [`full_rank_basis`])
    pub identifiable: Vec<ParamId>,
    /// the parameters not in the basis and what absorbs them (input order)
    pub redundant: Vec<Redundancy>,
    /// the `parameter_count − rank` invisible combinations, smallest singular value last
    pub lost_directions: Vec<LostDirection>,
    /// the parameters analysed, in input (preference) order
    pub params: ParamSet,
    /// Euclidean norm of every natural-unit column (input order)
    pub column_norms: Vec<f64>,
    /// number of measurements (poses)
    pub measurement_count: usize,
    /// number of rows that carry information: [`vatcal_core::informative_rows`] of the
    /// measurements (3 per point, pose half or plane contact with the tool axis held normal, 1 per
    /// plane contact without) plus the rows of known distances; from a bare Jacobian
    /// ([`analyze_jacobian`]) its non-zero rows
    pub equation_count: usize,
}

impl IdentifiabilityReport {
    /// True when every parameter is identifiable.
    pub fn is_full_rank(&self) -> bool {
        self.rank == self.parameter_count
    }

    /// The identifiable basis as a parameter set.
    pub fn identifiable_set(&self) -> ParamSet {
        ParamSet(self.identifiable.clone())
    }

    /// Absolute threshold on the normalised singular values.
    pub fn threshold(&self) -> f64 {
        self.tolerance * self.singular_values.first().copied().unwrap_or(0.0)
    }

    /// Condition number σ₁/σ_rank of the unit-normalised Jacobian restricted to its rank
    /// (∞ if the rank is 0).
    pub fn condition_number_of_rank(&self) -> f64 {
        match self.rank {
            0 => f64::INFINITY,
            r => self.singular_values[0] / self.singular_values[r - 1],
        }
    }

    /// Parameters to name when the set is rank-deficient: the columns left out of the basis
    /// (input order). The basis is never larger than the rank ([`full_rank_basis`]), so a
    /// rank-deficient set always names at least `parameter_count − rank` of them.
    pub fn unidentifiable(&self) -> Vec<ParamId> {
        self.redundant.iter().map(|r| r.param).collect()
    }
}

impl fmt::Display for IdentifiabilityReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // the informative rows are named when they are not 3 per measurement (plane contacts
        // without the tool axis, known distances)
        let rows = if self.equation_count == 3 * self.measurement_count {
            String::new()
        } else {
            format!(", {} informative rows", self.equation_count)
        };
        writeln!(
            f,
            "rank {} of {} parameters ({} measurements{rows}, relative tolerance {:.1e}, threshold {:.2e})",
            self.rank,
            self.parameter_count,
            self.measurement_count,
            self.tolerance,
            self.threshold()
        )?;
        if let (Some(first), Some(last)) = (self.singular_values.first(), self.singular_values.last()) {
            writeln!(
                f,
                "singular values of the unit-normalised Jacobian: largest {first:.4e}, smallest kept {:.4e}, smallest {last:.4e}; condition number (kept) {:.4e}",
                self.singular_values.get(self.rank.max(1) - 1).copied().unwrap_or(0.0),
                self.condition_number_of_rank()
            )?;
        }
        let names: Vec<String> = self.identifiable.iter().map(|p| p.name()).collect();
        writeln!(f, "identifiable ({}): {}", self.identifiable.len(), names.join(", "))?;
        if self.redundant.is_empty() {
            writeln!(f, "redundant: none")?;
        } else {
            writeln!(f, "redundant ({}):", self.redundant.len())?;
            for r in &self.redundant {
                writeln!(f, "  {}", r.sentence())?;
            }
        }
        if !self.lost_directions.is_empty() {
            writeln!(f, "invisible parameter combinations ({}):", self.lost_directions.len())?;
            for d in &self.lost_directions {
                writeln!(f, "  {}", d.sentence())?;
            }
        }
        Ok(())
    }
}

/// Options of [`analyze_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnalysisOptions {
    /// relative rank tolerance on the unit-normalised singular values (floored at
    /// `max(rows, cols) · ε`)
    pub relative_tolerance: f64,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        Self { relative_tolerance: DEFAULT_RELATIVE_TOLERANCE }
    }
}

/// Identifiability of `params` from `measurements` with the default tolerance.
///
/// # Examples
/// The paper's 34 parameters plus `a_1` (row 2's `a`), which the base's y translation absorbs:
/// ```
/// use vatcal_core::{CellFile, ParamId, ParamSet};
/// use vatcal_kinematics::Model;
/// use vatcal_observability::analyze;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
/// let poses = vatcal_sim::truth::probe_start_poses(&model, 40, 1);
/// let mut params = ParamSet::paper34();
/// params.0.push(ParamId::A(2));
/// let report = analyze(&model, &poses, &params)?;
/// assert_eq!((report.rank, report.parameter_count), (34, 35));
/// assert_eq!(report.redundant.len(), 1);
/// assert_eq!(report.redundant[0].param, ParamId::A(2));
/// assert_eq!(report.redundant[0].confounded_with[0].0.name(), "base_y");
/// println!("{}", report.redundant[0].sentence()); // a_1 is absorbed by base_y (-1.0000)
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`ObservabilityError::NoMeasurements`], [`ObservabilityError::NoParameters`];
/// [`ObservabilityError::Model`] when the model lacks a measurement's TCP or calibration position
/// or one of `params` (e.g. an effect that is not switched on), naming the measurement;
/// [`ObservabilityError::NonFinite`] for a non-finite Jacobian entry;
/// [`ObservabilityError::Numerical`] when the SVD does not converge.
pub fn analyze(
    model: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
) -> Result<IdentifiabilityReport, ObservabilityError> {
    analyze_with(model, measurements, params, &AnalysisOptions::default())
}

/// [`analyze`] with explicit options.
pub fn analyze_with(
    model: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
    options: &AnalysisOptions,
) -> Result<IdentifiabilityReport, ObservabilityError> {
    if measurements.is_empty() {
        return Err(ObservabilityError::NoMeasurements);
    }
    let j = assemble_jacobian(model, measurements, params)?;
    let mut report = analyze_jacobian(j.as_ref(), params, options)?;
    report.equation_count = vatcal_core::informative_rows(measurements);
    Ok(report)
}

/// The analysis of [`analyze`] on a given natural-unit Jacobian (rows = measurements × 3,
/// columns = `params`). The report's `measurement_count` is `rows / 3` and its
/// `equation_count` the number of non-zero rows (callers that know the measurements set both).
pub fn analyze_jacobian(
    j: MatRef<'_, f64>,
    params: &ParamSet,
    options: &AnalysisOptions,
) -> Result<IdentifiabilityReport, ObservabilityError> {
    let l = params.len();
    if l == 0 {
        return Err(ObservabilityError::NoParameters);
    }
    if j.ncols() != l {
        return Err(ObservabilityError::InvalidInput(format!(
            "Jacobian has {} columns for {l} parameters",
            j.ncols()
        )));
    }
    if j.nrows() == 0 {
        return Err(ObservabilityError::NoMeasurements);
    }
    let column_norms: Vec<f64> = (0..l).map(|c| j.col(c).norm_l2()).collect();
    let mut jn = j.to_owned();
    scale_columns(&mut jn, &column_scale_factors(j, &params.0, ColumnScaling::UnitNorm));
    // columns without effect are zero (round-off must not pass for an independent direction)
    let negligible = negligible_columns(&column_norms, &params.0);
    for &c in &negligible {
        for x in jn.col_mut(c).iter_mut() {
            *x = 0.0;
        }
    }

    let (singular_values, v) = full_right_svd(jn.as_ref())?;
    let tolerance = options.relative_tolerance.max(j.nrows().max(l) as f64 * f64::EPSILON);
    let threshold = tolerance * singular_values[0];
    let rank = singular_values.iter().filter(|s| **s > threshold).count();

    let kept = full_rank_basis(jn.as_ref(), threshold, rank)?;
    let dropped: Vec<usize> = (0..l).filter(|c| !kept.contains(c)).collect();
    let redundant = explain_dropped(jn.as_ref(), &kept, &dropped, params, &column_norms, &negligible);
    let lost_directions = (rank..l).map(|i| lost_direction(singular_values[i], v.col(i), params)).collect();

    Ok(IdentifiabilityReport {
        rank,
        parameter_count: l,
        singular_values,
        tolerance,
        identifiable: kept.iter().map(|c| params.0[*c]).collect(),
        redundant,
        lost_directions,
        params: params.clone(),
        column_norms,
        measurement_count: j.nrows() / 3,
        equation_count: (0..j.nrows()).filter(|r| j.row(*r).iter().any(|x| *x != 0.0)).count(),
    })
}

/// All `ncols` singular values (descending, zero-padded) and the full `ncols × ncols` V.
fn full_right_svd(a: MatRef<'_, f64>) -> Result<(Vec<f64>, Mat<f64>), ObservabilityError> {
    let l = a.ncols();
    // With fewer rows than columns the thin V would miss null-space vectors: pad with zero rows.
    let padded;
    let a = if a.nrows() < l {
        padded = Mat::from_fn(l, l, |r, c| if r < a.nrows() { a[(r, c)] } else { 0.0 });
        padded.as_ref()
    } else {
        a
    };
    let svd = a.thin_svd().map_err(|e| ObservabilityError::Numerical(format!("SVD: {e:?}")))?;
    let s: Vec<f64> = svd.S().column_vector().iter().copied().collect();
    Ok((s, svd.V().to_owned()))
}

/// Column-pivoted Householder QR with the *preference* pivot rule (module docs): returns the
/// indices of the kept columns, in input order.
pub fn preference_ordered_basis(a: MatRef<'_, f64>, threshold: f64) -> Vec<usize> {
    let (m, l) = (a.nrows(), a.ncols());
    let mut w = a.to_owned();
    let mut kept = Vec::new();
    let mut v = vec![0.0; m];
    for c in 0..l {
        let k = kept.len();
        if k == m {
            break;
        }
        let norm = (k..m).map(|r| w[(r, c)] * w[(r, c)]).sum::<f64>().sqrt();
        if norm <= threshold {
            continue;
        }
        // Householder vector v (rows k..m) mapping w[k.., c] onto alpha·e_k.
        let x0 = w[(k, c)];
        let alpha = if x0 >= 0.0 { -norm } else { norm };
        for r in k..m {
            v[r] = w[(r, c)];
        }
        v[k] -= alpha;
        let vtv: f64 = (k..m).map(|r| v[r] * v[r]).sum();
        if vtv > 0.0 {
            let beta = 2.0 / vtv;
            for cc in c + 1..l {
                let dot: f64 = (k..m).map(|r| v[r] * w[(r, cc)]).sum();
                let f = beta * dot;
                for r in k..m {
                    w[(r, cc)] -= f * v[r];
                }
            }
        }
        kept.push(c);
    }
    kept
}

/// The identifiable basis of the (unit-normalised) columns of `a` (module docs, "Which
/// parameters are kept"): [`preference_ordered_basis`], then made consistent with the SVD rank.
///
/// 1. While the kept columns' own smallest singular value is at most `threshold` (the absolute
///    threshold of the report's rank), the kept column with the largest entry in that singular
///    vector is dropped — among entries within [`TIE_FRACTION`] of the largest, the one latest
///    in the input (preference) order. The others explain that column with the smallest
///    weights, so the basis left is the best conditioned.
/// 2. While fewer columns are kept than `rank`, the dropped columns are offered back in input
///    order and taken when the basis stays of full rank.
/// 3. If the basis is still short of `rank` — two nearly dependent columns, each above the
///    threshold, can take up a dimension the other columns would fill clearly (seen with fewer
///    rows than parameters) — steps 1 and 2 are repeated with the QR's and step 2's acceptance raised ten
///    times at a time (never above the threshold times 1e8), and the first basis of `rank`
///    columns is taken (else the largest one).
///
/// Returns the indices of the kept columns, in input order; their own smallest singular value
/// is above `threshold`, and their number is `rank` unless no subset of the columns reaches a
/// direction the SVD counts (possible for a singular value close to the threshold).
///
/// # Errors
/// [`ObservabilityError::Numerical`] when an SVD does not converge.
pub fn full_rank_basis(
    a: MatRef<'_, f64>,
    threshold: f64,
    rank: usize,
) -> Result<Vec<usize>, ObservabilityError> {
    let mut best: Vec<usize> = Vec::new();
    for step in 0..=8 {
        let kept = basis_with_acceptance(a, threshold, threshold * 10f64.powi(step), rank)?;
        if step == 0 || kept.len() > best.len() {
            best = kept;
        }
        if best.len() >= rank {
            break;
        }
    }
    Ok(best)
}

/// Steps 1 and 2 of [`full_rank_basis`]: the preference-ordered QR accepting remaining norms
/// above `accept`, pruned until of full rank by `threshold`, completed with the columns that
/// keep its smallest singular value above `accept`.
fn basis_with_acceptance(
    a: MatRef<'_, f64>,
    threshold: f64,
    accept: f64,
    rank: usize,
) -> Result<Vec<usize>, ObservabilityError> {
    let mut kept = preference_ordered_basis(a, accept);
    loop {
        let (smallest, direction) = weakest_direction(a, &kept)?;
        if smallest > threshold {
            break;
        }
        kept.remove(column_to_drop(&direction));
    }
    for c in 0..a.ncols() {
        if kept.len() >= rank {
            break;
        }
        if kept.contains(&c) {
            continue;
        }
        let mut trial = kept.clone();
        trial.insert(trial.partition_point(|k| *k < c), c);
        if weakest_direction(a, &trial)?.0 > accept {
            kept = trial;
        }
    }
    Ok(kept)
}

/// Entries of a lost direction within this fraction of its largest magnitude count as tied for
/// dropping ([`full_rank_basis`]): the latest of them in preference order goes. Two columns
/// that are the same up to a small part of a third give entries like 0.707 and 0.705.
pub const TIE_FRACTION: f64 = 0.9;

/// The smallest singular value of the columns `cols` of `a` and its right singular vector
/// (entries in the order of `cols`); ∞ and no entries for no columns.
fn weakest_direction(a: MatRef<'_, f64>, cols: &[usize]) -> Result<(f64, Vec<f64>), ObservabilityError> {
    if cols.is_empty() {
        return Ok((f64::INFINITY, Vec::new()));
    }
    let sub = Mat::from_fn(a.nrows(), cols.len(), |r, c| a[(r, cols[c])]);
    let (s, v) = full_right_svd(sub.as_ref())?;
    let k = cols.len() - 1;
    Ok((s[k], v.col(k).iter().copied().collect()))
}

/// Position of the entry of `x` to drop: the last one within [`TIE_FRACTION`] of the largest
/// magnitude.
fn column_to_drop(x: &[f64]) -> usize {
    let max = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    (0..x.len()).rev().find(|&i| x[i].abs() >= TIE_FRACTION * max).unwrap_or(x.len() - 1)
}

/// Least-squares combination of the kept columns for every dropped column.
fn explain_dropped(
    jn: MatRef<'_, f64>,
    kept: &[usize],
    dropped: &[usize],
    params: &ParamSet,
    column_norms: &[f64],
    negligible: &[usize],
) -> Vec<Redundancy> {
    if dropped.is_empty() {
        return Vec::new();
    }
    let m = jn.nrows();
    let mut solution = Mat::from_fn(m, dropped.len(), |r, c| jn[(r, dropped[c])]);
    if !kept.is_empty() {
        let basis = Mat::from_fn(m, kept.len(), |r, c| jn[(r, kept[c])]);
        basis.qr().solve_lstsq_in_place(solution.as_mut());
    }
    dropped
        .iter()
        .enumerate()
        .map(|(d, &col)| {
            let param = params.0[col];
            if column_norms[col] == 0.0 || negligible.contains(&col) || kept.is_empty() {
                return Redundancy {
                    param,
                    confounded_with: Vec::new(),
                    normalized_weights: Vec::new(),
                    fit_residual: 1.0,
                };
            }
            let x: Vec<f64> = (0..kept.len()).map(|i| solution[(i, d)]).collect();
            let fit_residual = (0..m)
                .map(|r| {
                    let fit: f64 = kept.iter().zip(&x).map(|(k, xi)| jn[(r, *k)] * xi).sum();
                    (fit - jn[(r, col)]).powi(2)
                })
                .sum::<f64>()
                .sqrt();
            let named = largest_entries(&x);
            Redundancy {
                param,
                confounded_with: named
                    .iter()
                    .map(|&i| (params.0[kept[i]], x[i] * column_norms[col] / column_norms[kept[i]]))
                    .collect(),
                normalized_weights: named.iter().map(|&i| x[i]).collect(),
                fit_residual,
            }
        })
        .collect()
}

/// Indices of the entries with |x| ≥ SIGNIFICANT_FRACTION · max |x|, largest first, at most
/// MAX_NAMED; ties broken by index.
fn largest_entries(x: &[f64]) -> Vec<usize> {
    let max = x.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    if max == 0.0 {
        return Vec::new();
    }
    let mut idx: Vec<usize> = (0..x.len()).filter(|&i| x[i].abs() >= SIGNIFICANT_FRACTION * max).collect();
    idx.sort_by(|&a, &b| x[b].abs().total_cmp(&x[a].abs()).then(a.cmp(&b)));
    idx.truncate(MAX_NAMED);
    idx
}

fn lost_direction(singular_value: f64, v: faer::ColRef<'_, f64>, params: &ParamSet) -> LostDirection {
    let x: Vec<f64> = v.iter().copied().collect();
    let named = largest_entries(&x);
    let sign = named.first().map_or(1.0, |&i| x[i].signum());
    LostDirection { singular_value, combination: named.iter().map(|&i| (params.0[i], sign * x[i])).collect() }
}

/// Like [`analyze`], but refuses a rank-deficient parameter set with
/// [`ObservabilityError::RankDeficient`] naming the parameters that cannot be identified.
pub fn check_identifiable(
    model: &Model,
    measurements: &[Measurement],
    params: &ParamSet,
) -> Result<IdentifiabilityReport, ObservabilityError> {
    let report = analyze(model, measurements, params)?;
    if report.is_full_rank() {
        return Ok(report);
    }
    Err(rank_deficient_error_for(&report, model.joint_kinds()))
}

/// [`rank_deficient_error`] ending with the advice for the chain at hand
/// ([`vatcal_core::canonical::rank_hint`]: the three calibration positions on the canonical
/// cell, generic advice on any other chain).
pub fn rank_deficient_error_for(report: &IdentifiabilityReport, kinds: &[JointKind]) -> ObservabilityError {
    rank_deficient_error_with(report, vatcal_core::canonical::rank_hint(kinds))
}

/// The [`ObservabilityError::RankDeficient`] describing a rank-deficient report, with
/// chain-neutral advice (see [`rank_deficient_error_for`]).
pub fn rank_deficient_error(report: &IdentifiabilityReport) -> ObservabilityError {
    rank_deficient_error_with(report, "Fix or drop these parameters, or add poses.")
}

fn rank_deficient_error_with(report: &IdentifiabilityReport, hint: &str) -> ObservabilityError {
    let unidentifiable = report.unidentifiable();
    let names: Vec<String> = unidentifiable.iter().map(|p| p.name()).collect();
    let mut message = format!(
        "the measurements identify only {} of {} parameters ({} poses); cannot identify: {}",
        report.rank,
        report.parameter_count,
        report.measurement_count,
        names.join(", ")
    );
    let l = report.parameter_count;
    if report.equation_count < l && report.equation_count == 3 * report.measurement_count {
        message.push_str(&format!(
            ". {l} parameters need at least {} poses (3 equations per pose)",
            l.div_ceil(3)
        ));
    } else if report.equation_count < l {
        message.push_str(&format!(
            ". {l} parameters need at least {l} equations; these {} measurements give {} (3 per pose, 1 per plane contact without the tool axis held normal)",
            report.measurement_count, report.equation_count
        ));
    }
    for r in &report.redundant {
        message.push_str(&format!("; {}", r.sentence()));
    }
    if !report.lost_directions.is_empty() {
        let dirs: Vec<String> = report.lost_directions.iter().map(|d| d.sentence()).collect();
        message.push_str(&format!(". Invisible combinations: {}", dirs.join(" | ")));
    }
    message.push_str(". ");
    message.push_str(hint);
    ObservabilityError::RankDeficient {
        rank: report.rank,
        needed: report.parameter_count,
        unidentifiable,
        message,
    }
}

/// The preference order used by [`all_identifiable`]. On the canonical Meca500-on-guide cell:
/// the paper's 34 parameters first (Eq. 7 order), then every other parameter of the model (MDH
/// rows 1..7, compliances, base, then the parameters of switched-on effects). On any other
/// chain: `alpha`, `a`, `theta_offset`, `d` of rows 1..N (the four classical MDH values), then
/// the Hayati `beta` of every row (so that beta enters the basis only where the classical
/// values cannot describe the chain, i.e. at parallel axes), the compliances of the revolute
/// joints, the base pose, then the parameters of switched-on effects. TCP and
/// calibration-position coordinates are left out: they are measured on a CMM and kept fixed,
/// and leaving them free would make the world frame and the tool frame trade places with them.
/// The contact planes of the cell file are left out for the same reason (they are held fixed;
/// planes at unknown places come first through [`crate::sets::resolve_spec`] and
/// [`crate::sets::DataDesign::free_planes`]).
pub fn preference_order(model: &Model) -> ParamSet {
    let mut v: Vec<ParamId> = if model.is_meca500_on_guide() {
        vatcal_core::canonical::default_param_set().0.into_iter().filter(|p| model.has_param(*p)).collect()
    } else {
        let rows = 1..=model.joint_count() as u8;
        let mut v: Vec<ParamId> = rows
            .clone()
            .flat_map(|i| [ParamId::Alpha(i), ParamId::A(i), ParamId::ThetaOffset(i), ParamId::D(i)])
            .collect();
        v.extend(rows.clone().map(ParamId::Beta));
        v.extend(rows.map(ParamId::Compliance).filter(|p| model.has_param(*p)));
        v
    };
    for p in model.all_params().0 {
        if !matches!(p, ParamId::Tcp { .. } | ParamId::Position { .. } | ParamId::Plane { .. })
            && !v.contains(&p)
        {
            v.push(p);
        }
    }
    ParamSet(v)
}

/// The identifiable basis of all the model's parameters ([`preference_order`]) for these
/// measurements — what `--params all-identifiable` means, and the default parameter set of any
/// chain other than the canonical cell. With poses at all three calibration positions of the
/// canonical cell this is exactly the paper's 34.
pub fn all_identifiable(model: &Model, measurements: &[Measurement]) -> Result<ParamSet, ObservabilityError> {
    Ok(analyze(model, measurements, &preference_order(model))?.identifiable_set())
}

/// The default parameter set of `model`: the paper's 34 on the canonical Meca500-on-guide
/// cell, the [`all_identifiable`] basis for these measurements on any other chain.
pub fn default_params(model: &Model, measurements: &[Measurement]) -> Result<ParamSet, ObservabilityError> {
    if model.is_meca500_on_guide() {
        Ok(vatcal_core::canonical::default_param_set())
    } else {
        all_identifiable(model, measurements)
    }
}

/// The columns of `j` (columns = `params`) that belong to `subset`, in `subset`'s order.
/// Parameters of `subset` that are not in `params` are an error.
pub fn select_columns(
    j: MatRef<'_, f64>,
    params: &ParamSet,
    subset: &ParamSet,
) -> Result<Mat<f64>, ObservabilityError> {
    let columns = subset
        .iter()
        .map(|p| {
            params.index_of(*p).ok_or_else(|| {
                ObservabilityError::InvalidInput(format!("parameter `{p}` is not a column of the Jacobian"))
            })
        })
        .collect::<Result<Vec<usize>, _>>()?;
    Ok(Mat::from_fn(j.nrows(), columns.len(), |r, c| j[(r, columns[c])]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A column at round-off level (the compliance of a vertical joint) must not count as an
    /// independent direction although its unit-normalised version is as long as any other.
    #[test]
    fn a_round_off_column_has_no_effect_and_is_named() {
        let params = ParamSet(vec![ParamId::D(2), ParamId::A(3), ParamId::Compliance(1)]);
        let j = Mat::from_fn(9, 3, |r, c| match c {
            0 => 1.0 + r as f64,
            1 => ((r * r) % 5) as f64 - 2.0,
            // 1e-15 N·m torque times a lever of ~500 mm, with a pattern of its own
            _ => 5e-13 * ((r * 7) % 3) as f64,
        });
        let report = analyze_jacobian(j.as_ref(), &params, &AnalysisOptions::default()).expect("analysis");
        assert_eq!(report.rank, 2);
        assert_eq!(report.identifiable, vec![ParamId::D(2), ParamId::A(3)]);
        assert_eq!(report.redundant.len(), 1);
        let r = &report.redundant[0];
        assert_eq!(r.param, ParamId::Compliance(1));
        assert!(r.confounded_with.is_empty() && r.fit_residual == 1.0);
        assert!(r.sentence().contains("has no effect"), "{}", r.sentence());
        // the same column at a physical size (c ~ 1e-4 rad/(N·m) moving the TCP by 0.1 mm) stays
        let j = Mat::from_fn(9, 3, |r, c| if c == 2 { 1e3 * ((r * 7) % 3) as f64 } else { j[(r, c)] });
        let report = analyze_jacobian(j.as_ref(), &params, &AnalysisOptions::default()).expect("analysis");
        assert_eq!(report.rank, 3);
        assert!(report.redundant.is_empty());
    }

    /// The floor is far below every real parameter of the canonical cell: the weakest of the
    /// paper's 34 (a flange compliance) still has an a-priori effect well above 1e-8 of the
    /// strongest on probe data.
    #[test]
    fn no_parameter_of_the_paper34_is_negligible_on_the_canonical_cell() {
        let cell = vatcal_core::CellFile::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../fixtures/meca500-zaber.toml"
        ))
        .expect("fixture");
        let model = Model::from_cell(&cell).expect("model");
        let poses = vatcal_sim::truth::probe_start_poses(&model, 40, 1);
        let params = ParamSet::paper34();
        let j = assemble_jacobian(&model, &poses, &params).expect("jacobian");
        let norms: Vec<f64> = (0..j.ncols()).map(|c| j.col(c).norm_l2()).collect();
        let effects: Vec<f64> = norms.iter().zip(&params.0).map(|(n, p)| n * p.typical_scale()).collect();
        let largest = effects.iter().fold(0.0_f64, |a, e| a.max(*e));
        let (weakest, ratio) = params
            .0
            .iter()
            .zip(&effects)
            .map(|(p, e)| (*p, e / largest))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("params");
        eprintln!("weakest a-priori effect: {weakest} at {ratio:.2e} of the strongest");
        assert!(ratio > 1e3 * NEGLIGIBLE_RELATIVE_EFFECT, "{weakest}: {ratio:e}");
        assert!(negligible_columns(&norms, &params.0).is_empty());
    }
}
