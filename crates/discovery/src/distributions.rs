//! Tail probabilities of the χ² and F distributions, also as logarithms (the statistics of a
//! strong effect are far in the tail, where plain p-values underflow to 0 and can no longer be
//! ranked).
//!
//! Implemented with the regularised incomplete gamma and beta functions (series and Lentz
//! continued fractions, Numerical Recipes §6.2/§6.4) and a Lanczos `ln Γ`.

const EPS: f64 = 1e-15;
const TINY: f64 = 1e-300;
const MAX_ITER: usize = 10_000;

/// `ln Γ(x)` for `x > 0` (Lanczos, g = 7, relative error ≈ 1e-15).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // reflection: Γ(x) Γ(1 − x) = π / sin(πx)
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).abs().ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// `ln P(a, x)` by the series (good for `x < a + 1`).
fn ln_gamma_p_series(a: f64, x: f64) -> f64 {
    let mut ap = a;
    let mut sum = 1.0 / a;
    let mut del = sum;
    for _ in 0..MAX_ITER {
        ap += 1.0;
        del *= x / ap;
        sum += del;
        if del.abs() < sum.abs() * EPS {
            break;
        }
    }
    sum.ln() - x + a * x.ln() - ln_gamma(a)
}

/// `ln Q(a, x)` by the continued fraction (good for `x ≥ a + 1`).
fn ln_gamma_q_cf(a: f64, x: f64) -> f64 {
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..MAX_ITER {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < TINY {
            d = TINY;
        }
        c = b + an / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < EPS {
            break;
        }
    }
    h.ln() - x + a * x.ln() - ln_gamma(a)
}

/// `ln Q(a, x)`, the log of the regularised upper incomplete gamma function.
fn ln_gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        0.0
    } else if x < a + 1.0 {
        (-ln_gamma_p_series(a, x).exp()).ln_1p()
    } else {
        ln_gamma_q_cf(a, x)
    }
}

/// `ln P(χ²_k > x)`, the log survival function of the χ² distribution with `k` degrees of
/// freedom. Returns 0 (p = 1) for `x ≤ 0` and NaN for `k == 0` or a NaN statistic.
pub fn chi2_ln_sf(x: f64, k: usize) -> f64 {
    if k == 0 || x.is_nan() {
        return f64::NAN;
    }
    ln_gamma_q(0.5 * k as f64, 0.5 * x)
}

/// `P(χ²_k > x)`.
pub fn chi2_sf(x: f64, k: usize) -> f64 {
    chi2_ln_sf(x, k).exp()
}

/// `ln P(Z > z)` for a standard normal Z (via `P(Z > z) = ½ P(χ²₁ > z²)` for z ≥ 0).
pub fn normal_ln_sf(z: f64) -> f64 {
    if z.is_nan() {
        return f64::NAN;
    }
    let half_tail = (0.5f64).ln() + chi2_ln_sf(z * z, 1);
    if z >= 0.0 { half_tail } else { (-half_tail.exp()).ln_1p() }
}

/// The upper quantile `z` with `P(Z > z) = alpha` of a standard normal Z (bisection on
/// [`normal_ln_sf`], |error| < 1e-10; `alpha` is clamped to `[1e-300, 1 − 1e-16]`).
pub fn normal_upper_quantile(alpha: f64) -> f64 {
    let ln_alpha = alpha.clamp(1e-300, 1.0 - 1e-16).ln();
    let (mut lo, mut hi) = (-40.0_f64, 40.0_f64);
    while hi - lo > 1e-10 {
        let mid = 0.5 * (lo + hi);
        if normal_ln_sf(mid) > ln_alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Continued fraction of the incomplete beta function (Numerical Recipes `betacf`).
fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    let qab = a + b;
    let qap = a + 1.0;
    let qam = a - 1.0;
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..MAX_ITER {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        if d.abs() < TINY {
            d = TINY;
        }
        c = 1.0 + aa / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        if d.abs() < TINY {
            d = TINY;
        }
        c = 1.0 + aa / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < EPS {
            break;
        }
    }
    h
}

/// `ln I_x(a, b)`, the log of the regularised incomplete beta function.
fn ln_beta_inc(x: f64, a: f64, b: f64) -> f64 {
    if x <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if x >= 1.0 {
        return 0.0;
    }
    let ln_front = a * x.ln() + b * (-x).ln_1p() - (ln_gamma(a) + ln_gamma(b) - ln_gamma(a + b));
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front + beta_cf(a, b, x).ln() - a.ln()
    } else {
        // I_x(a, b) = 1 − I_{1−x}(b, a)
        let ln_other = b * (-x).ln_1p() + a * x.ln() - (ln_gamma(a) + ln_gamma(b) - ln_gamma(a + b))
            + beta_cf(b, a, 1.0 - x).ln()
            - b.ln();
        (-ln_other.exp()).ln_1p()
    }
}

/// `ln P(F_{d1,d2} > f)`, the log survival function of Fisher's F distribution.
/// Returns 0 for `f ≤ 0` and NaN for zero degrees of freedom or a NaN statistic.
pub fn f_ln_sf(f: f64, d1: usize, d2: usize) -> f64 {
    if d1 == 0 || d2 == 0 || f.is_nan() {
        return f64::NAN;
    }
    if f <= 0.0 {
        return 0.0;
    }
    let (d1, d2) = (d1 as f64, d2 as f64);
    ln_beta_inc(d2 / (d2 + d1 * f), 0.5 * d2, 0.5 * d1)
}

/// `P(F_{d1,d2} > f)`.
pub fn f_sf(f: f64, d1: usize, d2: usize) -> f64 {
    f_ln_sf(f, d1, d2).exp()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn ln_gamma_matches_factorials_and_half_integers() {
        let mut fact = 1.0f64;
        for n in 1..25u32 {
            // Γ(n) = (n-1)!
            assert_relative_eq!(ln_gamma(f64::from(n)), fact.ln(), epsilon = 1e-12, max_relative = 1e-13);
            fact *= f64::from(n);
        }
        assert_relative_eq!(ln_gamma(0.5), std::f64::consts::PI.sqrt().ln(), epsilon = 1e-13);
        assert_relative_eq!(ln_gamma(1.5), (0.5 * std::f64::consts::PI.sqrt()).ln(), epsilon = 1e-13);
    }

    #[test]
    fn chi2_matches_tables() {
        // classical 5 % and 1 % critical values
        assert_relative_eq!(chi2_sf(3.841_458_820_694_124, 1), 0.05, max_relative = 1e-9);
        assert_relative_eq!(chi2_sf(6.634_896_601_021_214, 1), 0.01, max_relative = 1e-9);
        assert_relative_eq!(chi2_sf(11.070_497_693_516_351, 5), 0.05, max_relative = 1e-9);
        assert_relative_eq!(chi2_sf(18.307_038_053_275_146, 10), 0.05, max_relative = 1e-9);
        assert_relative_eq!(chi2_sf(124.342_113_404_880_3, 100), 0.05, max_relative = 1e-8);
        assert_eq!(chi2_sf(0.0, 3), 1.0);
    }

    #[test]
    fn normal_tail_matches_tables() {
        assert_relative_eq!(normal_ln_sf(0.0).exp(), 0.5, max_relative = 1e-12);
        assert_relative_eq!(normal_ln_sf(1.644_853_626_951_472_2).exp(), 0.05, max_relative = 1e-9);
        assert_relative_eq!(normal_ln_sf(2.326_347_874_040_840_8).exp(), 0.01, max_relative = 1e-9);
        assert_relative_eq!(normal_ln_sf(-1.644_853_626_951_472_2).exp(), 0.95, max_relative = 1e-9);
        // far tail: ln P ≈ −z²/2 − ln(z √(2π))
        let z = 30.0f64;
        let approx = -0.5 * z * z - (z * (2.0 * std::f64::consts::PI).sqrt()).ln();
        assert!((normal_ln_sf(z) - approx).abs() < 2e-3);
    }

    #[test]
    fn chi2_with_two_dof_is_exponential_even_far_in_the_tail() {
        for x in [0.1, 1.0, 5.0, 40.0, 300.0, 2000.0, 20_000.0] {
            assert_relative_eq!(chi2_ln_sf(x, 2), -0.5 * x, max_relative = 1e-12);
        }
    }

    #[test]
    fn f_matches_tables_and_closed_forms() {
        assert_relative_eq!(f_sf(4.964_602_743_730_711, 1, 10), 0.05, max_relative = 1e-8);
        assert_relative_eq!(f_sf(3.087_295_893_017_37, 2, 100), 0.05, max_relative = 1e-7);
        // d2 = 2: P(F > f) = 1 − (d1 f / (2 + d1 f))^(d1/2)
        for (f, d1) in [(0.7, 5usize), (3.0, 9), (19.0, 1), (150.0, 30)] {
            let x = d1 as f64 * f / (2.0 + d1 as f64 * f);
            assert_relative_eq!(f_sf(f, d1, 2), 1.0 - x.powf(d1 as f64 / 2.0), max_relative = 1e-10);
        }
        // d1 = 2: P(F > f) = (1 + 2 f / d2)^(-d2/2), also deep in the tail
        for (f, d2) in [(0.5, 7usize), (3.0, 40), (50.0, 300), (4000.0, 500)] {
            let exact = -(d2 as f64 / 2.0) * (2.0 * f / d2 as f64).ln_1p();
            assert_relative_eq!(f_ln_sf(f, 2, d2), exact, max_relative = 1e-10);
        }
        assert_eq!(f_sf(0.0, 3, 9), 1.0);
    }

    #[test]
    fn f_approaches_chi2_over_k_for_large_denominator_dof() {
        let k = 4;
        for x in [1.0, 2.5, 6.0] {
            assert_relative_eq!(f_sf(x, k, 1_000_000), chi2_sf(k as f64 * x, k), max_relative = 1e-3);
        }
    }

    proptest::proptest! {
        #[test]
        fn survival_functions_are_probabilities_and_decrease(x in 0.0f64..200.0, dx in 0.01f64..20.0, k in 1usize..60, d2 in 1usize..500) {
            let a = chi2_sf(x, k);
            let b = chi2_sf(x + dx, k);
            proptest::prop_assert!((0.0..=1.0).contains(&a) && b <= a + 1e-15, "chi2 {a} {b}");
            let fa = f_sf(x / 10.0, k, d2);
            let fb = f_sf((x + dx) / 10.0, k, d2);
            proptest::prop_assert!((0.0..=1.0).contains(&fa) && fb <= fa + 1e-12, "F {fa} {fb}");
        }
    }
}
