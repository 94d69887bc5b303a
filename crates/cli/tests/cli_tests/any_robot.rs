//! End-to-end tests of the commands on the two version-2 fixtures (a UR5e-class 6R arm and the
//! Meca500 alone on a table): `fk`, `torque`, `observability`, `select`, `identify`,
//! `validate`, `discover`, through the real binary, on small files generated here from a
//! perturbed "true" model of each fixture (`vatcal_sim::truth::perturbed_truth`; probe poses
//! solved by the planning crate's multi-start numerical IK on the true model, tracker rows at
//! random joint vectors, seeded noise).

use std::process::Command;

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::EffectParam;
use vatcal_core::{CellFile, JointVector, Measurement, ParamId};
use vatcal_kinematics::Model;
use vatcal_planning::ik::ChainTool;
use vatcal_planning::numeric_ik::{IkTarget, JointSpec, MultiStartOptions, NumericIk};
use vatcal_sim::truth::{ErrorBudget, perturbed_truth, random_joints};

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

/// The planning crate's multi-start numerical IK with every joint of `model` free (random
/// starts only, from stream `seed`, so that different seeds give different solutions).
fn ik_for(model: &Model, seed: u64) -> NumericIk<ChainTool<'_>> {
    let n = model.joint_count();
    let revolute: Vec<bool> = model.joint_kinds().iter().map(|k| k.is_revolute()).collect();
    let specs: Vec<JointSpec> = (1..=n)
        .map(|i| match (model.joint_limit(i), revolute[i - 1]) {
            (Some((lo, hi)), true) => JointSpec::revolute(lo, hi),
            (Some((lo, hi)), false) => JointSpec::prismatic(lo, hi),
            (None, _) => JointSpec::continuous(),
        })
        .collect();
    let tool = ChainTool { model, fixed: JointVector::zeros(n), free: (1..=n).collect(), revolute };
    let opts = MultiStartOptions { grid_levels: 0, random_starts: 24, seed, ..MultiStartOptions::default() };
    NumericIk::new(tool, &specs, opts).expect("ik options")
}

/// True when every joint of `q` is at least 1e-4 (rad or mm) inside its limits: an IK solution
/// on a bound would leave the limits with the joint noise added to the data.
fn clear_of_limits(model: &Model, q: &JointVector) -> bool {
    (1..=model.joint_count()).all(|i| match model.joint_limit(i) {
        Some((lo, hi)) => q[i - 1] > lo + 1e-4 && q[i - 1] < hi - 1e-4,
        None => true,
    })
}

/// Up to `count` distinct joint vectors (inside the limits) that put TCP `tcp` of the IK's model
/// exactly on the world point `point` (the orientation is free, so every start gives another).
fn poses_at(ik: &NumericIk<ChainTool<'_>>, tcp: u32, point: Vector3<f64>, count: usize) -> Vec<JointVector> {
    let model = ik.kinematics().model;
    let tcp_in_tool = model.tcp(tcp).expect("tcp");
    let out = ik.solve(&IkTarget::Point { tcp_in_tool, point });
    out.joints()
        .map(|q| ik.kinematics().joints(q))
        .filter(|q| clear_of_limits(model, q))
        .inspect(|q| {
            let miss = (model.tcp_position(q, tcp).expect("fk") - point).norm();
            assert!(miss < 1e-6, "IK solution misses the target by {miss} mm");
        })
        .take(count)
        .collect()
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

/// Probe measurements of `truth` at every calibration position with every TCP (`per_pair`
/// IK solutions each, joint noise 2e-6 rad), tracker rows at random joint vectors (noise 5 µm
/// per axis), written as the files of the nominal model's joint kinds.
fn generate(nominal: &Model, truth: &Model, seed: u64, per_pair: usize, tracker: usize) -> Data {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let kinds = nominal.joint_kinds().to_vec();
    let ik = ik_for(truth, seed);
    let mut probe = Vec::new();
    for pos in nominal.position_ids() {
        let target = truth.position(pos).expect("position");
        for tcp in nominal.tcp_ids() {
            let poses = poses_at(&ik, tcp, target, per_pair);
            assert_eq!(poses.len(), per_pair, "too few IK solutions for TCP {tcp} at position {pos}");
            for mut q in poses {
                for k in 0..q.len() {
                    q[k] += 2e-6 * gauss(&mut rng);
                }
                probe.push(Measurement::probe(pos, tcp, q));
            }
        }
    }
    let mut tracker_rows = Vec::new();
    while tracker_rows.len() < tracker {
        let q = random_joints(nominal, &mut rng, 0.05);
        let tcp = nominal.tcp_ids()[tracker_rows.len() % nominal.tcp_ids().len()];
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
    Data {
        dir,
        nominal: nominal.clone(),
        truth: truth.clone(),
        probe: probe_path,
        tracker: tracker_path,
        joints: joints_path,
        tracker_rows,
    }
}

fn load(path: &str) -> Model {
    Model::from_cell(&CellFile::load(path).expect("cell")).expect("model")
}

fn parse_rows(text: &str) -> (String, Vec<Vec<f64>>) {
    let mut lines = text.lines();
    let header = lines.next().expect("header").to_string();
    (header, lines.map(|l| l.split(',').map(|v| v.parse().expect("number")).collect()).collect())
}

/// The numbers in "mean error" rows of `vatcal validate`: (baseline mean, model mean) [mm].
fn validate_means(text: &str) -> (f64, f64) {
    let mean = |prefix: &str| -> f64 {
        let line = text
            .lines()
            .find(|l| l.starts_with(prefix))
            .unwrap_or_else(|| panic!("no `{prefix}` row in\n{text}"));
        line.split_whitespace().nth(3).expect("mean column").parse().expect("number")
    };
    (mean("baseline ("), mean("model ("))
}

fn check_fixture(name: &str, seed: u64) {
    let model_path = fixture(name);
    let nominal = load(&model_path);
    let truth = perturbed_truth(&nominal, seed, &ErrorBudget::realistic());
    let d = generate(&nominal, &truth, seed, 12, 40);
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

    // observability: rank and named redundancies; the vertical first joint's compliance is
    // named as having no effect (its gravity torque is zero)
    let text = run(&["observability", "--model", &model_path, "--measurements", &d.probe]);
    assert!(text.contains("rank ") && text.contains(" parameters"), "{name}: {text}");
    assert!(
        text.contains("redundant (") && text.contains(" is absorbed by "),
        "{name}: no named redundancies in\n{text}"
    );
    assert!(text.contains("c_1 has no effect on these measurements"), "{name}: c_1 not named in\n{text}");

    // select: 45 of the 108 candidate probe poses, D-optimal for the default parameter set
    let selected = d.dir.path().join("selected.csv").display().to_string();
    let text = run(&[
        "select",
        "--model",
        &model_path,
        "--candidates",
        &d.probe,
        "--count",
        "45",
        "--restarts",
        "2",
        "--no-ablation",
        "--out",
        &selected,
    ]);
    let chosen = vatcal_io::read_probe_measurements(&selected, &d.nominal).expect("selected rows");
    assert_eq!(chosen.len(), 45, "{name}: {text}");
    assert!(text.contains("O1"), "{name}: no indices in\n{text}");

    // identify with the default parameter set (on these chains: the robot-agnostic set chosen
    // by cross-validation) on the selection
    let out_path = d.dir.path().join("calibrated.toml").display().to_string();
    let text = run(&["identify", "--model", &model_path, "--measurements", &selected, "--out", &out_path]);
    assert!(text.contains("identifying") && text.contains("converged"), "{name}: {text}");
    assert!(!text.contains("\nc_1 "), "{name}: the vertical joint's compliance was fitted:\n{text}");
    assert!(text.contains("<- chosen"), "{name}: the chosen set is not printed:\n{text}");
    // asking for the vertical joint's compliance explicitly is a clear error naming it (not a
    // stalled fit)
    let bad = d.dir.path().join("bad.toml").display().to_string();
    let out = vatcal()
        .args(["identify", "--model", &model_path, "--measurements", &selected, "--out", &bad])
        .args(["--params", "d_2,c_1,c_2"])
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("c_1 has no effect on these measurements"),
        "{name}: {err}"
    );
    let calibrated = load(&out_path);
    assert!(std::fs::read_to_string(&out_path).expect("read").contains("serial-robot-cell"));
    // predicted positions against the truth at held-out poses at the calibration positions
    // (other IK solutions than the data's, noise-free)
    let held_out = ik_for(&d.truth, seed + 100);
    let (mut worst_nominal, mut worst_calibrated, mut count) = (0.0f64, 0.0f64, 0);
    for pos in d.nominal.position_ids() {
        let target = d.truth.position(pos).expect("position");
        for tcp in d.nominal.tcp_ids() {
            for q in poses_at(&held_out, tcp, target, 4) {
                let t = d.truth.tcp_position(&q, tcp).expect("truth");
                worst_nominal = worst_nominal.max((d.nominal.tcp_position(&q, tcp).expect("n") - t).norm());
                worst_calibrated =
                    worst_calibrated.max((calibrated.tcp_position(&q, tcp).expect("c") - t).norm());
                count += 1;
            }
        }
    }
    eprintln!(
        "{name}: {count} held-out poses: worst error nominal {worst_nominal:.4} mm, calibrated {worst_calibrated:.5} mm"
    );
    assert!(count >= 27, "{name}: only {count} held-out poses");
    assert!(worst_nominal > 0.3, "{name}: the perturbation is too small to test ({worst_nominal} mm)");
    // joint noise 2e-6 rad on ~0.5-1 m levers: a few µm per probe row
    assert!(
        worst_calibrated < 0.01,
        "{name}: calibrated error {worst_calibrated} mm (nominal {worst_nominal} mm)"
    );

    // validate the calibrated model against the nominal one on the tracker rows (random joint
    // vectors over the whole workspace, 5 µm noise per axis)
    let text = run(&["validate", "--model", &out_path, "--baseline", &model_path, "--tracker", &d.tracker]);
    let (baseline_mm, model_mm) = validate_means(&text);
    eprintln!(
        "{name}: validate on {} tracker rows: mean {baseline_mm} -> {model_mm} mm",
        d.tracker_rows.len()
    );
    assert!(baseline_mm > 0.3 && model_mm < 0.05, "{name}: {text}");
}

/// `discover` on tracker data of a UR5e whose shoulder (joint 2) has a hidden second-harmonic
/// transmission error: it must add exactly that effect, starting from the nominal model and
/// the default parameter set.
#[test]
fn discover_finds_a_hidden_joint_cyclic_error_on_the_ur5e() {
    let model_path = fixture("ur5e.toml");
    let nominal = load(&model_path);
    let mut truth = perturbed_truth(&nominal, 21, &ErrorBudget::realistic());
    let hidden = EffectSpec::JointCyclic { joint: 2, harmonic: 2 };
    truth.enable_effect(hidden).expect("effect");
    // 1.0 arcmin amplitude (~0.25 mm at the tool)
    truth.set_param(ParamId::Effect(EffectParam::CyclicCos { joint: 2, harmonic: 2 }), 2.4e-4).expect("cos");
    truth.set_param(ParamId::Effect(EffectParam::CyclicSin { joint: 2, harmonic: 2 }), -1.6e-4).expect("sin");
    let d = generate(&nominal, &truth, 21, 2, 150);
    let report = d.dir.path().join("discover.json").display().to_string();
    let out = d.dir.path().join("discovered.toml").display().to_string();
    let text = run(&[
        "discover",
        "--model",
        &model_path,
        "--measurements",
        &d.tracker,
        "--report",
        &report,
        "--out",
        &out,
    ]);
    eprintln!("{text}");
    assert!(
        text.contains("result: 1 effect(s) added (joint-cyclic (joint 2, harmonic 2))"),
        "the hidden effect was not found:\n{text}"
    );
    assert!(std::path::Path::new(&report).exists());
    // the discovered model predicts the truth at new random poses to the noise level
    let found = load(&out);
    let mut rng = ChaCha8Rng::seed_from_u64(121);
    let (mut worst_nominal, mut worst_found, mut sum_found) = (0.0f64, 0.0f64, 0.0);
    for _ in 0..50 {
        let q = random_joints(&nominal, &mut rng, 0.05);
        let t = truth.tcp_position(&q, 1).expect("truth");
        worst_nominal = worst_nominal.max((nominal.tcp_position(&q, 1).expect("n") - t).norm());
        let e = (found.tcp_position(&q, 1).expect("f") - t).norm();
        worst_found = worst_found.max(e);
        sum_found += e / 50.0;
    }
    eprintln!(
        "discover: error at 50 new poses: nominal worst {worst_nominal:.4} mm, discovered mean {sum_found:.5} worst {worst_found:.5} mm"
    );
    // tracker noise 5 µm per axis (8.7 µm as a norm), 150 rows for 33 parameters
    assert!(
        sum_found < 0.015 && worst_found < 0.05,
        "discovered model error mean {sum_found} worst {worst_found} mm (nominal {worst_nominal} mm)"
    );
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
