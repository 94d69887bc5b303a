//! First estimates of contact planes from plane rows: the plane through the model's predicted
//! contact points (least squares, the smallest singular direction of their scatter), its
//! normal turned towards the robot: the mean of the arm's frame origins over the contacts lies
//! on the positive side (the arm is on the free side of a surface it touches; the base alone
//! may lie on the plane, e.g. a table at the base's height).
//!
//! Used twice: for the planes the data name and the cell file lacks ([`estimate_planes`]: they
//! are added to the model before the fit, like markers and unknown fixed points), and by
//! [`initialise`](crate::initialise) for the planes a fit identifies, after the base and TCPs.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Vector3};
use vatcal_core::Measurement;
use vatcal_core::cell::PlaneEntry;
use vatcal_kinematics::{ContactPlane, Model};

use crate::IdentifyError;

/// The least-squares plane through `points`: its unit normal (either sign) and the centroid;
/// `None` for fewer than three points or points on a line.
pub fn plane_through(points: &[Vector3<f64>]) -> Option<(Vector3<f64>, Vector3<f64>)> {
    if points.len() < 3 {
        return None;
    }
    let c = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let scatter: Matrix3<f64> = points.iter().map(|p| (p - c) * (p - c).transpose()).sum();
    let eig = scatter.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|a, b| eig.eigenvalues[*a].total_cmp(&eig.eigenvalues[*b]));
    let (small, middle) = (eig.eigenvalues[order[0]], eig.eigenvalues[order[1]]);
    // collinear points leave the plane's rotation about their line free
    let spread = middle > 1e-9 * eig.eigenvalues[order[2]].max(f64::MIN_POSITIVE);
    if !spread || !small.is_finite() {
        return None;
    }
    Some((eig.eigenvectors.column(order[0]).normalize(), c))
}

/// The plane through the predicted contact points of `plane`'s rows at `model`, with the
/// normal turned towards the arm (module docs); `None` when the rows do not fix a plane (fewer
/// than three, or on a line).
///
/// # Errors
/// [`IdentifyError::Measurement`] for a row the model cannot evaluate.
pub fn plane_of_rows(
    model: &Model,
    measurements: &[Measurement],
    plane: u32,
    contact_radius_mm: f64,
) -> Result<Option<ContactPlane>, IdentifyError> {
    let (mut points, mut arm, mut frames) = (Vec::new(), Vector3::zeros(), 0usize);
    for (index, m) in measurements.iter().enumerate() {
        if m.plane_id() == Some(plane) {
            points.push(
                model
                    .tcp_position_ctx(&m.q, &m.context, m.tcp)
                    .map_err(|source| IdentifyError::Measurement { index, source })?,
            );
            let chain = model.chain_full(&m.q, &m.context, false, None);
            for f in &chain.frames()[1..] {
                arm += f.p;
                frames += 1;
            }
        }
    }
    let Some((mut n, c)) = plane_through(&points) else { return Ok(None) };
    if n.dot(&(arm / frames.max(1) as f64 - c)) < 0.0 {
        n = -n;
    }
    Ok(Some(ContactPlane::new(n, n.dot(&c), contact_radius_mm)))
}

/// The cell-file entries of the planes that plane rows name and `model` lacks, each first
/// estimated by [`plane_of_rows`] at `model` (the nominal model: good to its accuracy, ~1 mm,
/// which is all the fit needs to start).
///
/// # Errors
/// [`IdentifyError::Measurement`] for a row the model cannot evaluate;
/// [`IdentifyError::UndeterminedPlane`] naming a plane whose rows do not fix it (fewer than
/// three contacts, or all on a line).
pub fn estimate_planes(
    model: &Model,
    measurements: &[Measurement],
) -> Result<Vec<PlaneEntry>, IdentifyError> {
    let mut rows: BTreeMap<u32, usize> = BTreeMap::new();
    for m in measurements {
        if let Some(id) = m.plane_id()
            && model.plane(id).is_none()
        {
            *rows.entry(id).or_default() += 1;
        }
    }
    let mut out = Vec::new();
    for (id, count) in rows {
        let plane = plane_of_rows(model, measurements, id, PlaneEntry::DEFAULT_CONTACT_RADIUS_MM)?
            .ok_or(IdentifyError::UndeterminedPlane { id, rows: count })?;
        out.push(plane.to_entry(id));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_through_recovers_a_tilted_plane_and_refuses_a_line() {
        let n = Vector3::new(0.1, -0.2, 1.0).normalize();
        let (u, v) = (n.cross(&Vector3::x()).normalize(), n);
        let w = v.cross(&u);
        let points: Vec<_> = (0..12)
            .map(|k| 40.0 * n + (k as f64 * 7.0 - 30.0) * u + ((k * k) as f64 % 11.0 - 5.0) * 9.0 * w)
            .collect();
        let (m, c) = plane_through(&points).expect("plane");
        assert!(m.cross(&n).norm() < 1e-12, "{m} vs {n}");
        assert!((m.dot(&c).abs() - 40.0).abs() < 1e-9);
        let line: Vec<_> = (0..5).map(|k| k as f64 * u).collect();
        assert!(plane_through(&line).is_none());
    }
}
