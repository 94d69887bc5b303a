//! Helpers shared by the identification tests: the UR5e fixture and its truths.

use nalgebra::Vector3;
use vatcal_core::{Axis, CellFile, ParamId};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{ErrorBudget, perturbed_truth};

/// The UR5e fixture's cell.
pub fn ur5e_cell() -> CellFile {
    CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml")).expect("fixture")
}

/// The UR5e fixture's nominal model.
pub fn ur5e() -> Model {
    Model::from_cell(&ur5e_cell()).expect("model")
}

/// Places `model`'s TCP 1 at `tcp`.
pub fn set_tcp1(model: &mut Model, tcp: Vector3<f64>) {
    for (axis, v) in Axis::ALL.iter().zip(tcp.iter()) {
        model.set_param(ParamId::Tcp { id: 1, axis: *axis }, *v).expect("tcp");
    }
}

/// The measured point's offset from TCP 1 in [`geometry_truth`].
pub const MARKER_MM: [f64; 3] = [30.0, -50.0, 56.6]; // |.| = 80 mm

/// The truth: perturbed geometry only (the compliance is an explicit addition, tested by the
/// CV's candidates), the measured point 80 mm ([`MARKER_MM`]) from the truth's TCP 1.
pub fn geometry_truth(nominal: &Model, seed: u64) -> Model {
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut t = perturbed_truth(nominal, seed, &budget);
    let tcp = t.tcp(1).expect("tcp 1") + Vector3::from(MARKER_MM);
    set_tcp1(&mut t, tcp);
    t
}
