//! Synthetic plane contacts: postures at which the truth's TCP touches one of its contact
//! planes (the tool axis held normal to it when asked), as a robot pressing a gripper or a
//! build plate on a table records them.

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use vatcal_core::{JointVector, Measurement, ParamId};
use vatcal_kinematics::Model;

use super::gauss;
use super::synthetic::random_joints;

/// Newton iterations per contact before the draw is given up.
const MAX_ITERATIONS: usize = 60;

/// `count` plane contacts of the truth: TCP `tcp` on plane `plane` of `truth` (and, with
/// `normal`, the tool axis normal to it), each found from random joints (10 % inside the
/// limits) by damped Gauss–Newton on the joints of the contact block; draws that do not
/// converge or leave the joint limits are retried (at most `50 × count` draws). The contact
/// noise: the TCP sits at a height drawn from `N(0, sigma_mm)` above the plane and, with
/// `normal`, the rim rows of the contact face are off by `N(0, sigma_mm)` each (a tilt of
/// `σ / r`). The recorded joints are the truth's, so the noise is in the contact, as on a
/// real robot. No collision check. Deterministic for a seed.
///
/// # Examples
/// ```
/// use nalgebra::Vector3;
/// use vatcal_core::CellFile;
/// use vatcal_kinematics::{ContactPlane, Model};
/// use vatcal_sim::truth::synthetic_plane_contacts;
///
/// let mut truth = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))?)?;
/// truth.insert_plane(1, ContactPlane::new(Vector3::z(), 50.0, 40.0));
/// let rows = synthetic_plane_contacts(&truth, 1, 1, true, 5, 0.0, 3);
/// assert_eq!(rows.len(), 5);
/// for m in &rows {
///     assert!(truth.residual(m)?.norm() < 1e-6);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn synthetic_plane_contacts(
    truth: &Model,
    plane: u32,
    tcp: u32,
    normal: bool,
    count: usize,
    sigma_mm: f64,
    seed: u64,
) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let joints: Vec<ParamId> = (1..=truth.joint_count() as u8)
        .map(|j| if truth.is_revolute(j as usize) { ParamId::ThetaOffset(j) } else { ParamId::D(j) })
        .collect();
    let rows = if normal { 3 } else { 1 };
    let mut out = Vec::with_capacity(count);
    for _ in 0..50 * count.max(1) {
        if out.len() == count {
            break;
        }
        let start = random_joints(truth, &mut rng, 0.1);
        let target: Vec<f64> = (0..rows).map(|_| gauss(&mut rng, sigma_mm)).collect();
        if let Some(q) = touch(truth, &joints, start, plane, tcp, normal, &target) {
            out.push(Measurement::plane(plane, tcp, q, normal));
        }
    }
    out
}

/// Inserts the two parallel contact planes of the plane-row examples into `truth`: plane 1,
/// a table at offset −50 mm, and plane 2, a block's top at offset 0, both with the normal
/// (0.001, −0.002, 1) (tilted by about 2.2 mrad) and a 40 mm contact face.
pub fn insert_table_and_block(truth: &mut Model) {
    let normal = nalgebra::Vector3::new(0.001, -0.002, 1.0);
    truth.insert_plane(1, vatcal_kinematics::ContactPlane::new(normal, -50.0, 40.0));
    truth.insert_plane(2, vatcal_kinematics::ContactPlane::new(normal, 0.0, 40.0));
}

/// The contacts of the plane-row examples on the planes of [`insert_table_and_block`]:
/// `count` touches of the table by TCP 1 (one row each) and `count` presses on the block with
/// the tool axis held normal (three rows each), `sigma_mm` contact noise; deterministic.
pub fn table_and_block_contacts(truth: &Model, count: usize, sigma_mm: f64) -> Vec<Measurement> {
    let mut rows = synthetic_plane_contacts(truth, 1, 1, false, count, sigma_mm, 1);
    rows.extend(synthetic_plane_contacts(truth, 2, 1, true, count, sigma_mm, 2));
    rows
}

/// Gauss–Newton (Levenberg-damped, minimum-norm) on the joints until the contact block
/// predicts `target`; `None` without convergence or outside the limits.
fn touch(
    truth: &Model,
    joints: &[ParamId],
    mut q: JointVector,
    plane: u32,
    tcp: u32,
    normal: bool,
    target: &[f64],
) -> Option<JointVector> {
    let rows = target.len();
    let n = joints.len();
    let mut block = vec![0.0; 3 * n];
    for _ in 0..MAX_ITERATIONS {
        let m = Measurement::plane(plane, tcp, q, normal);
        // the joint columns are those of the joint offsets
        let predicted = -truth.measurement_jacobian_into(&m, joints, &mut block).ok()?;
        let e = DVector::from_fn(rows, |r, _| target[r] - predicted[r]);
        if e.norm() < 1e-9 {
            let inside =
                truth.joint_limits().iter().enumerate().all(|(k, (lo, hi))| (*lo..=*hi).contains(&q[k]));
            return inside.then_some(q);
        }
        let j = DMatrix::from_fn(rows, n, |r, c| block[3 * c + r]);
        let jjt = &j * j.transpose() + DMatrix::identity(rows, rows) * 1e-9;
        let step = j.transpose() * jjt.lu().solve(&e)?;
        // at most 0.2 rad (or 20 mm) per iteration
        let scale = (0.2 / step.amax()).min(1.0);
        for k in 0..n {
            q[k] += scale * step[k];
        }
    }
    None
}

/// The plane fixture of the plane-contact examples (docs/real-data.md, the tests): a table
/// (plane 1, normal tilted by (2, −3) mrad) at height `table_mm`, the top of a 50 mm gauge block
/// standing on it (plane 2, parallel, `table_mm + 50`), a wall facing −x at `x = wall_mm`
/// (plane 3) and one facing +y at `y = −wall_mm` (plane 4), each tilted by a few mrad; contact
/// radius 40 mm. Added to `model` (replacing planes with these ids).
pub fn add_table_block_walls(model: &mut Model, table_mm: f64, wall_mm: f64) {
    use nalgebra::Vector3;
    use vatcal_kinematics::ContactPlane;
    let up = Vector3::new(0.002, -0.003, 1.0);
    model.insert_plane(1, ContactPlane::new(up, table_mm, 40.0));
    model.insert_plane(2, ContactPlane::new(up, table_mm + 50.0, 40.0));
    model.insert_plane(3, ContactPlane::new(Vector3::new(-1.0, 0.004, 0.002), -wall_mm, 40.0));
    model.insert_plane(4, ContactPlane::new(Vector3::new(0.003, 1.0, -0.001), -wall_mm, 40.0));
}
