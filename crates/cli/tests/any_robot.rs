//! End-to-end tests of the commands on the two version-2 fixtures (a UR5e-class 6R arm and the
//! Meca500 alone on a table): `fk`, `torque`, `observability`, `identify`, `validate`,
//! `discover`, through the real binary, on small files generated here from a perturbed "true"
//! model of each fixture (probe poses solved by a numerical IK on the true model, tracker rows
//! at random joint vectors, seeded noise).

use std::process::Command;

use nalgebra::{DMatrix, DVector, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::{CellFile, JointVector, Measurement, ParamId};
use vatcal_kinematics::Model;

fn vatcal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vatcal"))
}

fn fixture(name: &str) -> String {
    format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn run(args: &[&str]) -> String {
    let out = vatcal().args(args).output().expect("run");
    assert!(out.status.success(), "vatcal {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).expect("utf8")
}

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    // Box-Muller
    let u1: f64 = rng.random_range(1e-12..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// The fixture's model with every MDH value of rows 2..N, the base and the compliances
/// perturbed (the "real robot").
fn perturbed_truth(nominal: &Model, rng: &mut ChaCha8Rng) -> Model {
    let mut truth = nominal.clone();
    for id in nominal.all_params().0 {
        let sigma = match id {
            ParamId::Alpha(i) | ParamId::ThetaOffset(i) if i >= 2 => 2e-3,
            ParamId::A(i) | ParamId::D(i) if i >= 2 => 0.3,
            ParamId::Compliance(_) => 2e-4,
            ParamId::Base(_) => {
                if id.unit() == vatcal_core::params::ParamUnit::Mm {
                    0.5
                } else {
                    2e-3
                }
            }
            _ => 0.0,
        };
        if sigma > 0.0 {
            let v = truth.param(id).expect("param")
                + sigma * gauss(rng)
                + if matches!(id, ParamId::Compliance(_)) { 5e-4 } else { 0.0 };
            truth.set_param(id, v).expect("set");
        }
    }
    truth
}

/// Random joint vector inside the limits (continuous joints: one turn).
fn random_q(model: &Model, rng: &mut ChaCha8Rng) -> JointVector {
    let mut q = JointVector::zeros(model.joint_count());
    for (k, (lo, hi)) in model.joint_limits().iter().enumerate() {
        let pad = 0.05 * (hi - lo);
        q[k] = rng.random_range(lo + pad..hi - pad);
    }
    q
}

/// Joints that put TCP `tcp` of `model` on `target` (damped least squares on a
/// finite-difference Jacobian), from random starts; `None` if no start converges within limits.
fn solve_ik(model: &Model, tcp: u32, target: &Vector3<f64>, rng: &mut ChaCha8Rng) -> Option<JointVector> {
    let n = model.joint_count();
    for _ in 0..40 {
        let mut q = random_q(model, rng);
        for _ in 0..100 {
            let p = model.tcp_position(&q, tcp).ok()?;
            let e = target - p;
            if e.norm() < 1e-10 {
                if model.limit_violation(&q).is_none() {
                    return Some(q);
                }
                break; // converged outside the joint limits: try the next start
            }
            let mut j = DMatrix::zeros(3, n);
            for k in 0..n {
                let mut qp = q;
                qp[k] += 1e-7;
                let d = (model.tcp_position(&qp, tcp).ok()? - p) / 1e-7;
                j.set_column(k, &d);
            }
            let jjt = &j * j.transpose() + DMatrix::identity(3, 3) * 1e-6;
            let step = j.transpose() * jjt.try_inverse()? * DVector::from_column_slice(e.as_slice());
            let scale = (0.3 / step.amax()).min(1.0);
            for k in 0..n {
                q[k] += scale * step[k];
            }
        }
    }
    None
}

struct Data {
    dir: tempfile::TempDir,
    nominal: Model,
    truth: Model,
    probe: String,
    tracker: String,
    joints: String,
    tracker_rows: Vec<Measurement>,
}

/// Probe measurements at every calibration position with every TCP (`per_pair` random
/// orientations each, joint noise 2e-6 rad), tracker rows at random joint vectors (noise 5 µm).
fn generate(name: &str, seed: u64, per_pair: usize, tracker: usize) -> Data {
    let cell = CellFile::load(fixture(name)).expect("fixture");
    let nominal = Model::from_cell(&cell).expect("model");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = perturbed_truth(&nominal, &mut rng);
    let kinds = nominal.joint_kinds().to_vec();
    let mut probe = Vec::new();
    for pos in nominal.position_ids() {
        let target = truth.position(pos).expect("position");
        for tcp in nominal.tcp_ids() {
            let mut found = 0;
            while found < per_pair {
                let Some(mut q) = solve_ik(&truth, tcp, &target, &mut rng) else { break };
                for k in 0..q.len() {
                    q[k] += 2e-6 * gauss(&mut rng);
                }
                probe.push(Measurement::probe(pos, tcp, q));
                found += 1;
            }
            assert!(found == per_pair, "{name}: no IK solution for TCP {tcp} at position {pos}");
        }
    }
    let mut tracker_rows = Vec::new();
    while tracker_rows.len() < tracker {
        let q = random_q(&nominal, &mut rng);
        let tcp = nominal.tcp_ids()[tracker_rows.len() % 3];
        let p = truth.tcp_position(&q, tcp).expect("fk");
        let noise = Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * 0.005;
        tracker_rows.push(Measurement::tracker(tcp, q, p + noise));
    }
    let dir = tempfile::tempdir().expect("tmp");
    let path = |f: &str| dir.path().join(f).display().to_string();
    let (probe_path, tracker_path, joints_path) =
        (path("probe.csv"), path("tracker.csv"), path("joints.csv"));
    vatcal_io::write_measurements_for(&probe_path, &probe, &kinds).expect("write probe");
    vatcal_io::write_measurements_for(&tracker_path, &tracker_rows, &kinds).expect("write tracker");
    let rows: Vec<(u32, JointVector)> = tracker_rows.iter().map(|m| (m.tcp, m.q)).collect();
    vatcal_io::write_joint_rows_for(&joints_path, &rows, &kinds).expect("write joints");
    Data { dir, nominal, truth, probe: probe_path, tracker: tracker_path, joints: joints_path, tracker_rows }
}

fn parse_rows(text: &str) -> (String, Vec<Vec<f64>>) {
    let mut lines = text.lines();
    let header = lines.next().expect("header").to_string();
    (header, lines.map(|l| l.split(',').map(|v| v.parse().expect("number")).collect()).collect())
}

fn check_fixture(name: &str, seed: u64) {
    let model_path = fixture(name);
    let d = generate(name, seed, 6, 30);
    let n = d.nominal.joint_count();

    // fk: the library's nominal FK, one row per input row
    let (header, rows) = parse_rows(&run(&["fk", "--model", &model_path, "--input", &d.joints]));
    assert_eq!(header, "x,y,z");
    assert_eq!(rows.len(), d.tracker_rows.len());
    for (row, m) in rows.iter().zip(&d.tracker_rows) {
        let p = d.nominal.tcp_position(&m.q, m.tcp).expect("fk");
        assert!((Vector3::new(row[0], row[1], row[2]) - p).norm() < 1e-9, "{name}: fk {row:?} vs {p}");
    }

    // torque: one column per revolute joint (all of them here)
    let (header, rows) = parse_rows(&run(&["torque", "--model", &model_path, "--input", &d.joints]));
    let want: Vec<String> = (1..=n).map(|i| format!("tau{i}")).collect();
    assert_eq!(header, want.join(","));
    let tau = d.nominal.gravity_torques(&d.tracker_rows[0].q);
    for i in 0..n {
        assert!((rows[0][i] - tau[i]).abs() < 1e-9);
    }

    // observability: rank and named redundancies
    let text = run(&["observability", "--model", &model_path, "--measurements", &d.probe]);
    assert!(text.contains("rank ") && text.contains(" parameters"), "{name}: {text}");
    assert!(
        text.contains("redundant (") && text.contains(" is absorbed by "),
        "{name}: no named redundancies in\n{text}"
    );

    // identify with the default parameter set (all-identifiable on these chains)
    let out_path = d.dir.path().join("calibrated.toml").display().to_string();
    let text = run(&["identify", "--model", &model_path, "--measurements", &d.probe, "--out", &out_path]);
    assert!(text.contains("all-identifiable") || text.contains("identifying"), "{text}");
    let calibrated = Model::from_cell(&CellFile::load(&out_path).expect("calibrated cell")).expect("model");
    assert!(std::fs::read_to_string(&out_path).expect("read").contains("serial-robot-cell"));
    // predictions at the calibration positions recovered to within the noise: compare with the
    // truth at fresh poses near the probe (solved on the truth, as the data)
    let mut rng = ChaCha8Rng::seed_from_u64(seed + 100);
    let (mut worst_nominal, mut worst_calibrated) = (0.0f64, 0.0f64);
    for pos in d.nominal.position_ids() {
        let target = d.truth.position(pos).expect("position");
        for tcp in d.nominal.tcp_ids() {
            let q = solve_ik(&d.truth, tcp, &target, &mut rng).expect("ik");
            let t = d.truth.tcp_position(&q, tcp).expect("truth");
            worst_nominal = worst_nominal.max((d.nominal.tcp_position(&q, tcp).expect("n") - t).norm());
            worst_calibrated =
                worst_calibrated.max((calibrated.tcp_position(&q, tcp).expect("c") - t).norm());
        }
    }
    assert!(worst_nominal > 0.3, "{name}: the perturbation is too small to test ({worst_nominal} mm)");
    assert!(
        worst_calibrated < 0.02,
        "{name}: calibrated error {worst_calibrated} mm (nominal {worst_nominal} mm)"
    );

    // validate the calibrated model against the nominal one on the tracker rows
    let text = run(&["validate", "--model", &out_path, "--baseline", &model_path, "--tracker", &d.tracker]);
    assert!(text.contains("mm"), "{text}");

    // discover: starts from the nominal model, fits the default set, reports
    let report = d.dir.path().join("discover.json").display().to_string();
    let text = run(&["discover", "--model", &model_path, "--measurements", &d.probe, "--report", &report]);
    assert!(!text.is_empty());
    assert!(std::path::Path::new(&report).exists());
}

#[test]
fn ur5e_commands_end_to_end() {
    check_fixture("ur5e.toml", 11);
}

#[test]
fn meca500_on_a_table_commands_end_to_end() {
    check_fixture("meca500-table.toml", 12);
}

#[test]
fn seven_joint_files_on_a_six_joint_model_are_a_clear_error() {
    let out = vatcal()
        .args(["fk", "--model", &fixture("ur5e.toml"), "--input", &fixture("joints-example.csv")])
        .output()
        .expect("run");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("joints-example.csv") && err.contains("expected the joint columns q1..q6"), "{err}");
}
