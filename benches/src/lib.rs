//! Shared helpers for the vatcal benchmarks: the canonical cell and its seeded, model-based
//! candidate poses (used by the `detmax` and `select` benches and by the
//! `candidates_csv` example that writes the candidate file timed in `docs/performance.md`).

use vatcal_core::{CellFile, Measurement};
use vatcal_kinematics::Model;

/// Path of the canonical cell fixture (`fixtures/meca500-zaber.toml`).
pub const CANONICAL_CELL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml");

/// The canonical cell's nominal model.
///
/// # Panics
/// If the fixture is missing or invalid (benchmarks only).
pub fn canonical() -> Model {
    let cell = CellFile::load(CANONICAL_CELL).expect("canonical cell fixture");
    Model::from_cell(&cell).expect("model")
}

/// `count` model-based candidate poses of `model` (`vatcal_sim::truth::probe_start_poses`:
/// random joints inside the limits, then numerical position IK that puts a random TCP exactly
/// on a calibration position, cycling over the positions), seeded.
///
/// # Panics
/// If fewer than `count` poses could be generated (benchmarks only).
pub fn candidate_poses(model: &Model, count: usize, seed: u64) -> Vec<Measurement> {
    let poses = vatcal_sim::truth::probe_start_poses(model, count, seed);
    assert_eq!(poses.len(), count, "pose generation");
    poses
}

/// CPU time of the process so far \[ns\] (Linux: on-CPU time of every live thread from
/// `/proc/self/task/*/schedstat`; 0 elsewhere).
pub fn cpu_ns() -> u64 {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else { return 0 };
    tasks
        .flatten()
        .filter_map(|t| std::fs::read_to_string(t.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next().and_then(|x| x.parse::<u64>().ok()))
        .sum()
}
