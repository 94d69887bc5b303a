//! Deterministic, history-free noise.
//!
//! Every random draw of the virtual cell comes from a ChaCha8 stream seeded by a key that is a
//! hash of the cell seed and of *what happened*: the command (its target bits and the state it
//! started from) and, for readings, how many readings were taken since that command. Nothing
//! depends on how many draws happened before, so a campaign that is killed and resumed —
//! replaying the same commands from the same recorded state — sees exactly the same noise as an
//! uninterrupted run.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// splitmix64 finaliser: a bijective 64-bit mix.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Key of an event: `tag` (a short constant naming the kind of event) and `parts` folded into
/// `base` (the seed, or a previous key).
pub(crate) fn key(base: u64, tag: &str, parts: &[u64]) -> u64 {
    let mut h = mix(base);
    for b in tag.bytes() {
        h = mix(h ^ u64::from(b));
    }
    for p in parts {
        h = mix(h ^ *p);
    }
    h
}

/// Bits of a slice of floats (exact: equal floats give equal keys).
pub(crate) fn bits(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

/// The stream of one event.
pub(crate) fn rng(key: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(key)
}

/// Gaussian with standard deviation `sigma` (0 → 0).
pub(crate) fn gauss(rng: &mut ChaCha8Rng, sigma: f64) -> f64 {
    if sigma > 0.0 {
        let z: f64 = StandardNormal.sample(rng);
        sigma * z
    } else {
        0.0
    }
}

/// Isotropic Gaussian vector, `sigma` per axis.
pub(crate) fn gauss3(rng: &mut ChaCha8Rng, sigma: f64) -> Vector3<f64> {
    Vector3::new(gauss(rng, sigma), gauss(rng, sigma), gauss(rng, sigma))
}

/// Uniform in `[-half_width, half_width]`.
pub(crate) fn uniform(rng: &mut ChaCha8Rng, half_width: f64) -> f64 {
    if half_width > 0.0 { rng.random_range(-half_width..=half_width) } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_depend_on_every_part_and_are_reproducible() {
        let a = key(7, "arm", &bits(&[1.0, 2.0]));
        assert_eq!(a, key(7, "arm", &bits(&[1.0, 2.0])));
        assert_ne!(a, key(8, "arm", &bits(&[1.0, 2.0])));
        assert_ne!(a, key(7, "arn", &bits(&[1.0, 2.0])));
        assert_ne!(a, key(7, "arm", &bits(&[2.0, 1.0])));
        assert_ne!(a, key(7, "arm", &bits(&[1.0, 2.0 + 1e-15])));
        let mut r1 = rng(a);
        let mut r2 = rng(a);
        assert_eq!(gauss3(&mut r1, 1.0), gauss3(&mut r2, 1.0));
    }

    #[test]
    fn gaussian_scale() {
        let mut r = rng(1);
        let n = 20_000;
        let v: Vec<f64> = (0..n).map(|_| gauss(&mut r, 0.5)).collect();
        let mean = v.iter().sum::<f64>() / n as f64;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        assert!(mean.abs() < 0.02 && (sd - 0.5).abs() < 0.02, "{mean} {sd}");
        assert!((0..1000).all(|_| uniform(&mut r, 0.3).abs() <= 0.3));
    }
}
