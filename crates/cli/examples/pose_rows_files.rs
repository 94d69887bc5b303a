//! Writes the simulated pose files of docs/real-data.md's pose-row section: a UR5e truth
//! (geometry perturbed, seed 23; the tool tilted by (3, -2) mrad) seen by a motion-capture
//! system as ROS writes it (metres, radians, quaternions `qw,qx,qy,qz`): `train.csv` (10 µm,
//! 1 mrad of noise) and the noise-free held-out `held.csv`, in the folder given (default
//! `/tmp/vatcal-poses`).
//!
//! `cargo run -p vatcal-cli --example pose_rows_files -- /tmp/vatcal-poses`

use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::{EffectParam, ToolFrameDof};
use vatcal_core::{CellFile, ParamId};
use vatcal_kinematics::Model;
use vatcal_sim::truth::{ErrorBudget, perturbed_truth, synthetic_tracker_measurements};

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    // Box-Muller
    let u1: f64 = rng.random_range(1e-12..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// The UR5e truth: geometry perturbed (no compliance), the tool tilted by (3, -2) mrad.
fn truth() -> anyhow::Result<Model> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml");
    let nominal = Model::from_cell(&CellFile::load(path)?)?;
    let budget = ErrorBudget { compliance_range: (0.0, 0.0), ..ErrorBudget::realistic() };
    let mut t = perturbed_truth(&nominal, 23, &budget);
    t.enable_effect(EffectSpec::ToolFrame)?;
    t.set_param(ParamId::Effect(EffectParam::ToolFrame(ToolFrameDof::Rx)), 3e-3)?;
    t.set_param(ParamId::Effect(EffectParam::ToolFrame(ToolFrameDof::Ry)), -2e-3)?;
    Ok(t)
}

/// A pose CSV of TCP 1 (metres, radians, `qw,qx,qy,qz`) with noise `sigma_mm` / `sigma_rad`.
fn write_poses(path: &Path, truth: &Model, n: usize, noise: (f64, f64), seed: u64) -> anyhow::Result<usize> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed + 1000);
    let mut text = String::from("tcp,q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy,qz\n");
    let mut rows = 0;
    for m in synthetic_tracker_measurements(truth, n, 0.0, seed).into_iter().filter(|m| m.tcp == 1) {
        let mut g = |s: f64| Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * s;
        let p = (truth.tcp_position(&m.q, 1)? + g(noise.0)) / 1000.0;
        let r = truth.tool_rotation_ctx(&m.q, &m.context)?;
        let q = (UnitQuaternion::from_scaled_axis(g(noise.1)) * UnitQuaternion::from_matrix(&r)).into_inner();
        let joints: Vec<String> = m.q.as_slice().iter().map(f64::to_string).collect();
        text += &format!("1,{},{},{},{},{},{},{},{}\n", joints.join(","), p.x, p.y, p.z, q.w, q.i, q.j, q.k);
        rows += 1;
    }
    std::fs::write(path, text)?;
    Ok(rows)
}

fn main() -> anyhow::Result<()> {
    let dir = std::env::args().nth(1).unwrap_or_else(|| "/tmp/vatcal-poses".to_string());
    let dir = Path::new(&dir);
    std::fs::create_dir_all(dir)?;
    let truth = truth()?;
    let train = write_poses(&dir.join("train.csv"), &truth, 300, (0.01, 1e-3), 5)?;
    let held = write_poses(&dir.join("held.csv"), &truth, 300, (0.0, 0.0), 6)?;
    println!("{}: train.csv ({train} pose rows), held.csv ({held})", dir.display());
    Ok(())
}
