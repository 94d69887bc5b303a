//! The linear algebra of effect screening (background.md §8.2): the column space of the
//! current model's Jacobian, the part of a candidate's columns it cannot explain (novelty), and
//! the score (Lagrange-multiplier) test.
//!
//! Notation: `J` is the N × p Jacobian of the fitted model at its optimum, `Z` the N × k
//! Jacobian columns of a candidate effect at the same point (derivatives at a zero value of the
//! effect), `r̂` the residual, `P⊥ = I − J J⁺`.

use faer::{Mat, MatRef};

use crate::DiscoveryError;
use crate::distributions::chi2_ln_sf;

/// Relative tolerance on the singular values of the unit-normalised current Jacobian below
/// which a direction counts as not identified (analytic derivatives: ≈ 1e-8 … 1e-10).
pub const RANK_TOLERANCE: f64 = 1e-9;

/// An orthonormal basis of the column space of a Jacobian (columns normalised to unit norm
/// before the SVD, so the rank decision does not depend on units).
#[derive(Debug, Clone)]
pub struct ColumnSpace {
    basis: Mat<f64>,
}

/// Left singular vectors and singular values (descending) of `a`.
fn svd_parts(a: MatRef<'_, f64>) -> Result<(Mat<f64>, Vec<f64>), DiscoveryError> {
    let svd = a.thin_svd().map_err(|e| DiscoveryError::Numerical(format!("SVD failed: {e:?}")))?;
    let s: Vec<f64> = svd.S().column_vector().iter().copied().collect();
    Ok((svd.U().to_owned(), s))
}

/// Copy of `a` with every column scaled to unit Euclidean norm (zero columns stay zero), and
/// the original norms.
pub fn unit_columns(a: MatRef<'_, f64>) -> (Mat<f64>, Vec<f64>) {
    let mut out = a.to_owned();
    let mut norms = Vec::with_capacity(a.ncols());
    for c in 0..a.ncols() {
        let n = a.col(c).iter().map(|v| v * v).sum::<f64>().sqrt();
        norms.push(n);
        if n > 0.0 {
            for v in out.col_mut(c).iter_mut() {
                *v /= n;
            }
        }
    }
    (out, norms)
}

/// First `r` columns of `u` as an owned matrix.
fn leading_columns(u: &Mat<f64>, r: usize) -> Mat<f64> {
    Mat::from_fn(u.nrows(), r, |i, j| u[(i, j)])
}

impl ColumnSpace {
    /// The column space of `j` with the default rank tolerance.
    pub fn of(j: MatRef<'_, f64>) -> Result<Self, DiscoveryError> {
        Self::with_tolerance(j, RANK_TOLERANCE)
    }

    /// The column space of `j`; directions whose normalised singular value is below
    /// `relative_tolerance · σ₁` are left out.
    pub fn with_tolerance(j: MatRef<'_, f64>, relative_tolerance: f64) -> Result<Self, DiscoveryError> {
        if j.ncols() == 0 {
            return Ok(Self { basis: Mat::zeros(j.nrows(), 0) });
        }
        let (jn, _) = unit_columns(j);
        let (u, s) = svd_parts(jn.as_ref())?;
        let s1 = s.first().copied().unwrap_or(0.0);
        let r = s.iter().filter(|v| **v > relative_tolerance * s1 && **v > 0.0).count();
        Ok(Self { basis: leading_columns(&u, r) })
    }

    /// Numerical rank (number of identified directions).
    pub fn rank(&self) -> usize {
        self.basis.ncols()
    }

    /// Number of rows (scalar residuals).
    pub fn rows(&self) -> usize {
        self.basis.nrows()
    }

    /// `P⊥ z`: the part of every column of `z` that the column space cannot explain.
    pub fn project_out(&self, z: MatRef<'_, f64>) -> Mat<f64> {
        let q = self.basis.as_ref();
        let coeffs = q.transpose() * z;
        z - q * coeffs
    }

    /// `P⊥ r` for a single vector.
    pub fn project_out_vec(&self, r: &[f64]) -> Vec<f64> {
        let m = Mat::from_fn(r.len(), 1, |i, _| r[i]);
        let p = self.project_out(m.as_ref());
        (0..r.len()).map(|i| p[(i, 0)]).collect()
    }
}

/// What a candidate effect adds to the current model's column space.
#[derive(Debug, Clone)]
pub struct EffectDirections {
    /// overall novelty `‖P⊥Ẑ‖_F / ‖Ẑ‖_F` of the unit-normalised columns Ẑ (0 = absorbed by
    /// the current parameters, 1 = orthogonal to all of them)
    pub novelty: f64,
    /// novelty `‖P⊥z‖/‖z‖` of every column (0 for a zero column)
    pub column_novelty: Vec<f64>,
    /// singular values of `P⊥Ẑ`, descending: the novelty of each independent direction
    pub direction_novelty: Vec<f64>,
    /// number of directions whose novelty is above the floor: the effective number of new
    /// parameters (degrees of freedom of the tests)
    pub dof: usize,
    /// orthonormal basis (N × dof) of the novel directions
    basis: Mat<f64>,
}

impl EffectDirections {
    /// Splits `z` (N × k) into what `space` explains and what it cannot. Directions of `P⊥Ẑ`
    /// with novelty (singular value of the unit-normalised projection) at or below
    /// `novelty_floor` are treated as absorbed.
    pub fn new(space: &ColumnSpace, z: MatRef<'_, f64>, novelty_floor: f64) -> Result<Self, DiscoveryError> {
        let (zn, norms) = unit_columns(z);
        let pz = space.project_out(zn.as_ref());
        let column_novelty: Vec<f64> = (0..pz.ncols())
            .map(|c| if norms[c] > 0.0 { pz.col(c).iter().map(|v| v * v).sum::<f64>().sqrt() } else { 0.0 })
            .collect();
        let live = norms.iter().filter(|n| **n > 0.0).count();
        let novelty = if live == 0 {
            0.0
        } else {
            (column_novelty.iter().map(|v| v * v).sum::<f64>() / live as f64).sqrt()
        };
        let (basis, direction_novelty) = if pz.ncols() == 0 {
            (Mat::zeros(z.nrows(), 0), Vec::new())
        } else {
            let (u, s) = svd_parts(pz.as_ref())?;
            let keep = s.iter().filter(|v| **v > novelty_floor).count();
            (leading_columns(&u, keep), s)
        };
        Ok(Self { novelty, column_novelty, dof: basis.ncols(), direction_novelty, basis })
    }

    /// Squared norm of the projection of `r` onto the novel directions: the reduction of the
    /// residual sum of squares a linearised refit with the effect would achieve.
    pub fn explained_sum_of_squares(&self, r: &[f64]) -> f64 {
        assert_eq!(r.len(), self.basis.nrows(), "explained_sum_of_squares: length mismatch");
        let rm = Mat::from_fn(r.len(), 1, |i, _| r[i]);
        let c = self.basis.transpose() * rm.as_ref();
        (0..c.nrows()).map(|i| c[(i, 0)] * c[(i, 0)]).sum()
    }
}

/// Result of a score (Lagrange-multiplier) test.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ScoreTest {
    /// `LM = r̂ᵀ Z (Zᵀ P⊥ Z)⁻¹ Zᵀ r̂ / σ̂²`
    pub statistic: f64,
    /// degrees of freedom (novel directions of the effect)
    pub dof: usize,
    /// `ln P(χ²_dof > LM)` (NaN when dof = 0)
    pub ln_p_value: f64,
}

impl ScoreTest {
    /// The p-value (may underflow to 0 for strong effects; rank by `ln_p_value`).
    pub fn p_value(&self) -> f64 {
        self.ln_p_value.exp()
    }
}

/// The score test of adding the effect described by `directions`, from the residual `r̂` of the
/// current fit and the noise variance estimate `sigma2` (σ̂² = RSS₀ / (N − p₀), or a known σ²).
/// `r̂` is projected onto `P⊥` first, so an incompletely converged fit does not inflate LM.
pub fn score_test(
    space: &ColumnSpace,
    directions: &EffectDirections,
    residual: &[f64],
    sigma2: f64,
) -> ScoreTest {
    let pr = space.project_out_vec(residual);
    let statistic =
        if sigma2 > 0.0 { directions.explained_sum_of_squares(&pr) / sigma2 } else { f64::INFINITY };
    let dof = directions.dof;
    let ln_p_value = if dof == 0 { f64::NAN } else { chi2_ln_sf(statistic, dof) };
    ScoreTest { statistic, dof, ln_p_value }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};

    fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
        // Box–Muller
        let u1: f64 = rng.random_range(f64::EPSILON..1.0);
        let u2: f64 = rng.random();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }

    fn random_matrix(rng: &mut ChaCha8Rng, n: usize, k: usize) -> Mat<f64> {
        Mat::from_fn(n, k, |_, _| gaussian(rng))
    }

    /// Least-squares residual of `y` on the columns of `a` (test-only reference).
    fn ls_residual(a: MatRef<'_, f64>, y: &[f64]) -> Vec<f64> {
        let space = ColumnSpace::of(a).expect("svd");
        space.project_out_vec(y)
    }

    fn sum_sq(v: &[f64]) -> f64 {
        v.iter().map(|x| x * x).sum()
    }

    #[test]
    fn column_space_rank_and_projection() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let a = random_matrix(&mut rng, 50, 4);
        // fifth column = combination of the first two (exactly redundant), scaled oddly
        let j = Mat::from_fn(50, 5, |i, c| {
            if c < 4 { a[(i, c)] * 1e3f64.powi(c as i32) } else { 2.0 * a[(i, 0)] - a[(i, 1)] }
        });
        let s = ColumnSpace::of(j.as_ref()).expect("svd");
        assert_eq!(s.rank(), 4);
        let (jn, _) = unit_columns(j.as_ref());
        let p = s.project_out(jn.as_ref());
        let max = p
            .col_iter()
            .flat_map(|c| c.iter().copied().collect::<Vec<_>>())
            .fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(max < 1e-12, "projection of the column space itself must vanish: {max}");
    }

    #[test]
    fn novelty_is_zero_inside_one_outside_and_between_otherwise() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let j = random_matrix(&mut rng, 80, 6);
        let s = ColumnSpace::of(j.as_ref()).expect("svd");
        let inside = Mat::from_fn(80, 1, |i, _| j[(i, 0)] + 0.5 * j[(i, 3)]);
        let d = EffectDirections::new(&s, inside.as_ref(), 1e-6).expect("svd");
        assert!(d.novelty < 1e-10 && d.dof == 0, "{}", d.novelty);
        // orthogonal column: build from P⊥ of a random vector
        let z = s.project_out(random_matrix(&mut rng, 80, 1).as_ref());
        let d = EffectDirections::new(&s, z.as_ref(), 1e-6).expect("svd");
        assert!((d.novelty - 1.0).abs() < 1e-10 && d.dof == 1);
        // mixture: cos 60° → novelty sin 60°
        let u_in = {
            let n = j.col(0).iter().map(|v| v * v).sum::<f64>().sqrt();
            Mat::from_fn(80, 1, |i, _| j[(i, 0)] / n)
        };
        let u_out = {
            let n = z.col(0).iter().map(|v| v * v).sum::<f64>().sqrt();
            Mat::from_fn(80, 1, |i, _| z[(i, 0)] / n)
        };
        let mix = Mat::from_fn(80, 1, |i, _| 0.5 * u_in[(i, 0)] + 0.75f64.sqrt() * u_out[(i, 0)]);
        let d = EffectDirections::new(&s, mix.as_ref(), 1e-6).expect("svd");
        assert!((d.novelty - 0.75f64.sqrt()).abs() < 1e-10, "{}", d.novelty);
    }

    #[test]
    fn lm_equals_linear_rss_drop_over_sigma2() {
        // in a linear model the score statistic is exactly (RSS0 − RSS1) / σ̂²
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (n, p, k) = (120, 8, 2);
        let j = random_matrix(&mut rng, n, p);
        let z = random_matrix(&mut rng, n, k);
        let y: Vec<f64> =
            (0..n).map(|i| 0.3 * z[(i, 0)] - 0.1 * z[(i, 1)] + j[(i, 2)] + gaussian(&mut rng)).collect();
        let r0 = ls_residual(j.as_ref(), &y);
        let jz = Mat::from_fn(n, p + k, |i, c| if c < p { j[(i, c)] } else { z[(i, c - p)] });
        let r1 = ls_residual(jz.as_ref(), &y);
        let sigma2 = sum_sq(&r0) / (n - p) as f64;
        let s = ColumnSpace::of(j.as_ref()).expect("svd");
        let d = EffectDirections::new(&s, z.as_ref(), 1e-6).expect("svd");
        let t = score_test(&s, &d, &r0, sigma2);
        assert_eq!(t.dof, 2);
        let expected = (sum_sq(&r0) - sum_sq(&r1)) / sigma2;
        assert!((t.statistic - expected).abs() < 1e-8 * expected.max(1.0), "{} vs {expected}", t.statistic);
    }

    #[test]
    fn score_test_false_alarm_rate_matches_its_size_under_the_null() {
        // no effect: LM ~ χ²(k); at 5 % the rejection rate over 400 draws is 5 % ± 3 σ
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let (n, p, k, trials) = (90, 6, 3, 400);
        let mut rejections = 0;
        for _ in 0..trials {
            let j = random_matrix(&mut rng, n, p);
            let z = random_matrix(&mut rng, n, k);
            let y: Vec<f64> =
                (0..n).map(|i| j[(i, 0)] - 2.0 * j[(i, 4)] + 0.01 * gaussian(&mut rng)).collect();
            let r0 = ls_residual(j.as_ref(), &y);
            let s = ColumnSpace::of(j.as_ref()).expect("svd");
            let d = EffectDirections::new(&s, z.as_ref(), 1e-6).expect("svd");
            let t = score_test(&s, &d, &r0, sum_sq(&r0) / (n - p) as f64);
            if t.p_value() < 0.05 {
                rejections += 1;
            }
        }
        let rate = f64::from(rejections) / f64::from(trials);
        let sd = (0.05f64 * 0.95 / f64::from(trials)).sqrt();
        assert!((rate - 0.05).abs() < 3.0 * sd, "false-alarm rate {rate}");
    }

    #[test]
    fn score_test_detects_an_effect_above_its_detection_limit() {
        // a_min ≈ 2.8 σ / ‖P⊥z‖ at 5 %/80 %: an amplitude of 3 a_min is found essentially always
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (n, p) = (150, 10);
        let mut found = 0;
        for _ in 0..50 {
            let j = random_matrix(&mut rng, n, p);
            let z = random_matrix(&mut rng, n, 1);
            let s = ColumnSpace::of(j.as_ref()).expect("svd");
            let pz = s.project_out(z.as_ref());
            let a_min = 2.8 / pz.col(0).iter().map(|v| v * v).sum::<f64>().sqrt();
            let y: Vec<f64> = (0..n).map(|i| 3.0 * a_min * z[(i, 0)] + gaussian(&mut rng)).collect();
            let r0 = ls_residual(j.as_ref(), &y);
            let d = EffectDirections::new(&s, z.as_ref(), 1e-6).expect("svd");
            let t = score_test(&s, &d, &r0, sum_sq(&r0) / (n - p) as f64);
            if t.p_value() < 0.05 {
                found += 1;
            }
        }
        assert!(found >= 48, "found {found} of 50");
    }
}
