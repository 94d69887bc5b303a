//! Any serial chain (cell file version 2): FK, gravity torques and the analytic Jacobian against
//! an independent, deliberately naive implementation (4×4 matrices built from the file in
//! degrees, joint kinds read from the file, torques by the closed form
//! Σ z_i · ((c_j − o_i) × m_j g) over revolute joints), and the Jacobian against central
//! differences. Chains: a mixed revolute/prismatic chain written here (prismatic joint in the
//! middle, continuous joints, beta and compliance on several rows), and the fixtures of the
//! repository that use version 2.

use nalgebra::{Matrix4, Vector3, Vector4};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use vatcal_core::cell::CellFile;
use vatcal_core::effects::EffectSpec;
use vatcal_core::{JointKind, JointVector, MAX_JOINTS, MeasurementContext, ParamId};
use vatcal_kinematics::{Model, ModelError};

/// A 5-joint R-P-R-R-R chain with a tilted base, continuous joints 1 and 5, beta and
/// compliance on several rows, masses on frames 1..5 and a tool on frame 5.
const MIXED: &str = r#"
format = "serial-robot-cell"
version = 2

[units]
length = "mm"
angle = "deg"
mass = "kg"
compliance = "rad/(N*m)"
gravity = "m/s^2"

[robot]
name = "test chain"

[[joints]]
index = 1
kind = "revolute"
alpha_deg = 0.0
a_mm = 0.0
beta_deg = 0.4
theta_deg = 10.0
d_mm = 120.0
compliance_rad_per_n_m = 3e-3

[[joints]]
index = 2
name = "slide"
kind = "prismatic"
alpha_deg = -90.0
a_mm = 25.0
beta_deg = 0.0
theta_deg = -5.0
d_mm = 40.0
q_min = 0.0
q_max = 250.0

[[joints]]
index = 3
kind = "revolute"
alpha_deg = 90.0
a_mm = 10.0
beta_deg = -0.7
theta_deg = 0.0
d_mm = 0.0
q_min = -120.0
q_max = 120.0
compliance_rad_per_n_m = 2e-3

[[joints]]
index = 4
kind = "revolute"
alpha_deg = 3.0
a_mm = 200.0
beta_deg = 0.9
theta_deg = 90.0
d_mm = 15.0
q_min = -150.0
q_max = 150.0
compliance_rad_per_n_m = 4e-3

[[joints]]
index = 5
kind = "revolute"
alpha_deg = -90.0
a_mm = 30.0
beta_deg = 0.0
theta_deg = 0.0
d_mm = 80.0
compliance_rad_per_n_m = 1e-3

[base_in_world]
x_mm = 100.0
y_mm = -50.0
z_mm = 20.0
alpha_deg = 12.0
beta_deg = -8.0
gamma_deg = 30.0

[[tcps]]
id = 1
x_mm = 0.0
y_mm = 0.0
z_mm = 60.0

[[tcps]]
id = 4
x_mm = 20.0
y_mm = -15.0
z_mm = 45.0

[[calibration_positions]]
id = 1
x_mm = 300.0
y_mm = 0.0
z_mm = 0.0

[gravity]
vector_m_per_s2 = [0.2, -0.3, -9.79]

[[inertials.links]]
frame = 1
mass_kg = 3.0
com_mm = [5.0, 10.0, -40.0]

[[inertials.links]]
frame = 2
mass_kg = 2.0
com_mm = [0.0, 30.0, 10.0]

[[inertials.links]]
frame = 4
mass_kg = 1.5
com_mm = [100.0, 0.0, 5.0]

[[inertials.links]]
frame = 5
mass_kg = 0.5
com_mm = [0.0, 0.0, 20.0]

[inertials.tool]
frame = 5
mass_kg = 0.4
com_mm = [0.0, 5.0, 30.0]
"#;

fn mixed() -> CellFile {
    CellFile::from_toml_str(MIXED, "mixed").expect("valid v2 chain")
}

fn h(a: f64, axis: usize) -> Matrix4<f64> {
    let (s, c) = a.to_radians().sin_cos();
    match axis {
        0 => Matrix4::new(1., 0., 0., 0., 0., c, -s, 0., 0., s, c, 0., 0., 0., 0., 1.),
        1 => Matrix4::new(c, 0., s, 0., 0., 1., 0., 0., -s, 0., c, 0., 0., 0., 0., 1.),
        _ => Matrix4::new(c, -s, 0., 0., s, c, 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.),
    }
}
fn t(x: f64, y: f64, z: f64) -> Matrix4<f64> {
    Matrix4::new(1., 0., 0., x, 0., 1., 0., y, 0., 0., 1., z, 0., 0., 0., 1.)
}

/// World transforms of frames 0..N; q in file units (mm / deg), extra_deg added to revolute
/// joint angles.
fn naive_frames(c: &CellFile, q_file: &[f64], extra_deg: &[f64]) -> Vec<Matrix4<f64>> {
    let b = &c.base_in_world;
    let mut w = t(b.x_mm, b.y_mm, b.z_mm) * h(b.alpha_deg, 0) * h(b.beta_deg, 1) * h(b.gamma_deg, 2);
    let mut out = vec![w];
    for i in 1..=c.joints.len() {
        let j = c.joint(i as u8).expect("row");
        let (theta, d) = if j.kind == "prismatic" {
            (j.theta_deg, q_file[i - 1] + j.d_mm)
        } else {
            (q_file[i - 1] + j.theta_deg + extra_deg[i - 1], j.d_mm)
        };
        w = w * h(j.alpha_deg, 0) * t(j.a_mm, 0.0, 0.0) * h(j.beta_deg, 1) * h(theta, 2) * t(0.0, 0.0, d);
        out.push(w);
    }
    out
}

/// Closed-form gravity torques of every joint on the c = 0 geometry (0 for prismatic joints).
fn naive_torques(c: &CellFile, q_file: &[f64]) -> Vec<f64> {
    let n = c.joints.len();
    let f = naive_frames(c, q_file, &vec![0.0; n]);
    let g = Vector3::from(c.gravity.vector_m_per_s2);
    let pt = |m: &Matrix4<f64>, p: [f64; 3]| (m * Vector4::new(p[0], p[1], p[2], 1.0)).xyz() * 1e-3;
    let mut bodies: Vec<(usize, f64, Vector3<f64>)> = c
        .inertials
        .links
        .iter()
        .map(|l| (l.frame as usize, l.mass_kg, pt(&f[l.frame as usize], l.com_mm)))
        .collect();
    bodies.push((n, c.inertials.tool.mass_kg, pt(&f[n], c.inertials.tool.com_mm)));
    (1..=n)
        .map(|i| {
            if c.joint(i as u8).expect("row").kind == "prismatic" {
                return 0.0;
            }
            let o = f[i].column(3).xyz() * 1e-3;
            let z = f[i].column(2).xyz();
            bodies
                .iter()
                .filter(|(frame, ..)| *frame >= i)
                .map(|(_, m, com)| z.dot(&(com - o).cross(&(g * *m))))
                .sum()
        })
        .collect()
}

fn naive_tcp(c: &CellFile, q_file: &[f64], tcp: usize) -> Vector3<f64> {
    let n = c.joints.len();
    let tau = naive_torques(c, q_file);
    let extra: Vec<f64> = (1..=n)
        .map(|i| (c.joint(i as u8).expect("row").compliance_rad_per_n_m * tau[i - 1]).to_degrees())
        .collect();
    let f = naive_frames(c, q_file, &extra);
    let tp = &c.tcps[tcp];
    (f[n] * Vector4::new(tp.x_mm, tp.y_mm, tp.z_mm, 1.0)).xyz()
}

/// A joint vector in file units inside the model's ranges (continuous joints: ±360°).
fn file_joints(c: &CellFile, unit: &[f64]) -> Vec<f64> {
    (1..=c.joints.len())
        .map(|i| {
            let j = c.joint(i as u8).expect("row");
            let (lo, hi) = j.limits().unwrap_or((-360.0, 360.0));
            lo + (hi - lo) * unit[i - 1]
        })
        .collect()
}

fn check_cell(c: &CellFile, unit: &[f64]) -> Result<(), TestCaseError> {
    let m = Model::from_cell(c).expect("model");
    let n = c.joints.len();
    let q_file = file_joints(c, unit);
    let q = JointVector::from_file_units(&q_file, &c.joint_kinds()).expect("joints");
    let tau = m.gravity_torques(&q);
    let tau_ref = naive_torques(c, &q_file);
    for i in 0..n {
        prop_assert!((tau[i] - tau_ref[i]).abs() < 1e-9, "tau_{} {} vs {}", i + 1, tau[i], tau_ref[i]);
    }
    prop_assert!(tau[n..].iter().all(|v| *v == 0.0));
    for (k, tp) in c.tcps.iter().enumerate() {
        let p = m.tcp_position(&q, tp.id).expect("fk");
        let p_ref = naive_tcp(c, &q_file, k);
        prop_assert!((p - p_ref).norm() < 1e-9, "tcp {}: {} vs {}", tp.id, p, p_ref);
    }
    let chain = m.chain(&q);
    let extra: Vec<f64> = (1..=n)
        .map(|i| (c.joint(i as u8).expect("row").compliance_rad_per_n_m * tau_ref[i - 1]).to_degrees())
        .collect();
    let frames = naive_frames(c, &q_file, &extra);
    prop_assert_eq!(chain.frames().len(), n + 1);
    for (i, (got, want)) in chain.frames().iter().zip(&frames).enumerate() {
        let diff = (got.to_matrix4() - want).abs().max();
        prop_assert!(diff < 1e-9, "frame {} differs by {}", i, diff);
    }
    prop_assert!((chain.flange().to_matrix4() - frames[n]).abs().max() < 1e-9);
    Ok(())
}

fn fd_column(m: &Model, q: &JointVector, tcp: u32, id: ParamId, tau: &[f64; MAX_JOINTS]) -> Vector3<f64> {
    let hstep = match id.unit() {
        vatcal_core::params::ParamUnit::Mm => 1e-5,
        vatcal_core::params::ParamUnit::RadPerNm => 1e-6,
        _ => 1e-7,
    };
    let tp = m.tcp(tcp).expect("tcp");
    let ctx = MeasurementContext::default();
    let eval = |v: f64| {
        let mut mm = m.clone();
        mm.set_param(id, v).expect("set");
        let tpp = mm.tcp(tcp).unwrap_or(tp);
        mm.chain_full(q, &ctx, false, Some(tau)).tool_point(&tpp)
    };
    let v0 = m.param(id).expect("param");
    (eval(v0 + hstep) - eval(v0 - hstep)) / (2.0 * hstep)
}

fn check_jacobian(c: &CellFile, unit: &[f64], tcp_index: usize) -> Result<(), TestCaseError> {
    let m = Model::from_cell(c).expect("model");
    let q = JointVector::from_file_units(&file_joints(c, unit), &c.joint_kinds()).expect("joints");
    let tcp = c.tcps[tcp_index % c.tcps.len()].id;
    let params = m.all_params();
    let jac = m.jacobian(&q, tcp, &params.0).expect("jacobian");
    let tau = m.gravity_torques(&q);
    for (k, id) in params.iter().enumerate() {
        let fd = fd_column(&m, &q, tcp, *id, &tau);
        let an = jac.column(k).into_owned();
        let scale = 1.0 + an.norm();
        prop_assert!((fd - an).norm() < 2e-6 * scale, "{}: analytic {} vs fd {}", id, an, fd);
    }
    // a revolute joint's compliance is a parameter, a prismatic joint's is not
    for i in 1..=m.joint_count() {
        prop_assert_eq!(m.has_param(ParamId::Compliance(i as u8)), m.is_revolute(i));
    }
    Ok(())
}

fn unit_vector() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(0.0..1.0f64, MAX_JOINTS)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(100))]

    #[test]
    fn mixed_chain_fk_and_torques_match_independent_implementation(u in unit_vector()) {
        check_cell(&mixed(), &u)?;
    }

    #[test]
    fn mixed_chain_jacobian_matches_central_differences(u in unit_vector(), tcp in 0usize..2) {
        check_jacobian(&mixed(), &u, tcp)?;
    }
}

#[test]
fn mixed_chain_model_shape() {
    let m = Model::from_cell(&mixed()).expect("model");
    assert_eq!(m.joint_count(), 5);
    use JointKind::{Prismatic as P, Revolute as R};
    assert_eq!(m.joint_kinds(), &[R, P, R, R, R]);
    assert_eq!(m.guide_joint(), Some(2));
    assert!(!m.is_meca500_on_guide());
    assert_eq!(m.describe_chain(), "5 joints (RPRRR)");
    // continuous joints: no limits, reported as one turn; never a limit violation
    assert_eq!(m.joint_limit(1), None);
    assert_eq!(m.joint_limit(2), Some((0.0, 250.0)));
    assert_eq!(m.joint_limits().len(), 5);
    assert_eq!(m.joint_limits()[0], (-std::f64::consts::PI, std::f64::consts::PI));
    let q = JointVector::from_file_units(&[1000.0, 100.0, 0.0, 0.0, -720.0], m.joint_kinds()).expect("q");
    assert_eq!(m.limit_violation(&q), None);
    let q = JointVector::from_file_units(&[0.0, 300.0, 0.0, 0.0, 0.0], m.joint_kinds()).expect("q");
    assert_eq!(m.limit_violation(&q).map(|v| v.0), Some(2));
    // 5 MDH values per row, c of the 4 revolute joints, base, 2 TCPs, 1 position
    assert_eq!(m.all_params().len(), 25 + 4 + 6 + 6 + 3);
    // wrong joint count: a clear error, not a panic
    let q7 = JointVector::default();
    assert!(matches!(m.tcp_position(&q7, 1), Err(ModelError::JointCount { expected: 5, got: 7 })));
    assert!(matches!(m.jacobian(&q7, 1, &[ParamId::D(1)]), Err(ModelError::JointCount { .. })));
    assert!(m.require_meca500_on_guide("planning").is_err());
}

#[test]
fn effects_follow_the_joint_kinds() {
    let mut m = Model::from_cell(&mixed()).expect("model");
    // joint effects on revolute joints only
    assert!(m.enable_effect(EffectSpec::JointScale { joint: 1 }).is_ok());
    assert!(m.enable_effect(EffectSpec::JointScale { joint: 2 }).is_err(), "joint 2 is prismatic");
    assert!(m.enable_effect(EffectSpec::JointCyclic { joint: 6, harmonic: 1 }).is_err(), "no joint 6");
    // guide effects act on the prismatic joint 2
    m.enable_effect(EffectSpec::GuideScale).expect("guide scale");
    m.set_param(ParamId::Effect(vatcal_core::params::EffectParam::GuideScale), 1e-3).expect("set");
    let q = JointVector::from_file_units(&[10.0, 200.0, 20.0, -30.0, 40.0], m.joint_kinds()).expect("q");
    // torques held at those of q (they are evaluated on the unscaled joint values)
    let tau = m.gravity_torques(&q);
    let ctx = MeasurementContext::default();
    let tcp = m.tcp(1).expect("tcp");
    let moved = m.chain_full(&q, &ctx, true, Some(&tau)).tool_point(&tcp);
    let mut longer = q;
    longer[1] *= 1.0 + 1e-3;
    let plain = Model::from_cell(&mixed()).expect("model");
    let want = plain.chain_full(&longer, &ctx, true, Some(&tau)).tool_point(&tcp);
    assert!((moved - want).norm() < 1e-9, "{moved} vs {want}");
    assert!((moved - plain.chain_full(&q, &ctx, true, Some(&tau)).tool_point(&tcp)).norm() > 1e-3);
    // a chain without a prismatic joint refuses guide effects with a clear message
    let mut all_revolute = mixed();
    all_revolute.joints[1].kind = "revolute".into();
    all_revolute.joints[1].q_min = Some(-90.0);
    all_revolute.joints[1].q_max = Some(90.0);
    let mut r = Model::from_cell(&all_revolute).expect("model");
    let e = r.enable_effect(EffectSpec::GuideAngular { order: 2 }).expect_err("no guide");
    assert!(e.to_string().contains("prismatic"), "{e}");
}

#[test]
fn v2_cell_round_trips_and_stays_v2() {
    let c = mixed();
    let back = CellFile::from_toml_str(&c.to_toml_string().expect("write"), "back").expect("reload");
    assert_eq!(back, c);
    let m = Model::from_cell(&c).expect("model");
    let text = m.to_cell().to_toml_string().expect("write");
    assert!(text.contains("format = \"serial-robot-cell\""), "{text}");
    assert!(text.contains("version = 2"));
    assert!(!text.contains("q_min = nan"));
    let back = CellFile::from_toml_str(&text, "back").expect("reload");
    assert_eq!(back.joints[0].limits(), None, "continuous joints stay continuous");
    let q = JointVector::from_file_units(&[10.0, 200.0, 20.0, -30.0, 40.0], &c.joint_kinds()).expect("q");
    let m2 = Model::from_cell(&back).expect("model");
    assert!((m.tcp_position(&q, 4).expect("a") - m2.tcp_position(&q, 4).expect("b")).norm() < 1e-12);
}

// ------------------------------------------------------------------------------------------
// The version-2 fixtures: a UR5e-class arm and the Meca500 alone on a table.
// ------------------------------------------------------------------------------------------

fn fixture(name: &str) -> CellFile {
    CellFile::load(format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))).expect("fixture")
}

/// The fixture with non-zero compliances and betas, so that the checks exercise them.
fn perturbed_fixture(name: &str) -> CellFile {
    let mut c = fixture(name);
    for (k, j) in c.joints.iter_mut().enumerate() {
        j.beta_deg = 0.3 * (k as f64 - 2.5);
        j.compliance_rad_per_n_m = 1e-3 * (1.0 + k as f64);
    }
    c.base_in_world.alpha_deg = 2.0;
    c.base_in_world.gamma_deg = 25.0;
    c
}

/// Standard DH `Rz(theta) Tz(d) Tx(a) Rx(alpha)`, degrees and mm.
fn std_dh(theta: f64, d: f64, a: f64, alpha: f64) -> Matrix4<f64> {
    h(theta, 2) * t(0.0, 0.0, d) * t(a, 0.0, 0.0) * h(alpha, 0)
}

/// UR5e flange pose from Universal Robots' published standard-DH table (q in degrees).
fn ur5e_flange(q_deg: &[f64]) -> Matrix4<f64> {
    let d = [162.5, 0.0, 0.0, 133.3, 99.7, 99.6];
    let a = [0.0, -425.0, -392.2, 0.0, 0.0, 0.0];
    let alpha = [90.0, 0.0, 0.0, 90.0, -90.0, 0.0];
    (0..6).fold(Matrix4::identity(), |m, i| m * std_dh(q_deg[i], d[i], a[i], alpha[i]))
}

/// UR5e standard-DH link frames 1..6 (index 0 = base).
fn ur5e_dh_frames(q_deg: &[f64]) -> Vec<Matrix4<f64>> {
    let d = [162.5, 0.0, 0.0, 133.3, 99.7, 99.6];
    let a = [0.0, -425.0, -392.2, 0.0, 0.0, 0.0];
    let alpha = [90.0, 0.0, 0.0, 90.0, -90.0, 0.0];
    let mut out = vec![Matrix4::identity()];
    for i in 0..6 {
        let last = out[i];
        out.push(last * std_dh(q_deg[i], d[i], a[i], alpha[i]));
    }
    out
}

/// Meca500 R3 flange pose from its standard-DH table (Mecademic's convention: J2 offset -90°,
/// J6 offset 180°; q in degrees).
fn meca500_flange(q_deg: &[f64]) -> Matrix4<f64> {
    let d = [135.0, 0.0, 0.0, 120.0, 0.0, 70.0];
    let a = [0.0, 135.0, 38.0, 0.0, 0.0, 0.0];
    let alpha = [-90.0, 0.0, -90.0, 90.0, -90.0, 0.0];
    let offset = [0.0, -90.0, 0.0, 0.0, 0.0, -180.0];
    (0..6).fold(Matrix4::identity(), |m, i| m * std_dh(q_deg[i] + offset[i], d[i], a[i], alpha[i]))
}

fn fixture_fk_matches(
    c: &CellFile,
    unit: &[f64],
    flange: fn(&[f64]) -> Matrix4<f64>,
) -> Result<(), TestCaseError> {
    let m = Model::from_cell(c).expect("model");
    let q_file = file_joints(c, unit);
    let q = JointVector::from_file_units(&q_file, &c.joint_kinds()).expect("joints");
    // the fixtures stand on the table with the base at the world origin
    let want = flange(&q_file);
    let got = m.chain(&q).flange().to_matrix4();
    let diff = (got - want).abs().max();
    prop_assert!(diff < 1e-9, "flange differs by {} mm", diff);
    for tp in &c.tcps {
        let p = m.tcp_position(&q, tp.id).expect("fk");
        let p_ref = (want * Vector4::new(tp.x_mm, tp.y_mm, tp.z_mm, 1.0)).xyz();
        prop_assert!((p - p_ref).norm() < 1e-9, "tcp {}: {} vs {}", tp.id, p, p_ref);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(100))]

    #[test]
    fn ur5e_fk_matches_the_published_standard_dh_table(u in unit_vector()) {
        fixture_fk_matches(&fixture("ur5e.toml"), &u, ur5e_flange)?;
    }

    #[test]
    fn meca500_table_fk_matches_the_standard_dh_table(u in unit_vector()) {
        fixture_fk_matches(&fixture("meca500-table.toml"), &u, meca500_flange)?;
    }

    #[test]
    fn fixtures_fk_and_torques_match_independent_implementation(u in unit_vector()) {
        for name in ["ur5e.toml", "meca500-table.toml"] {
            check_cell(&perturbed_fixture(name), &u)?;
        }
    }

    #[test]
    fn fixtures_jacobian_matches_central_differences(u in unit_vector(), tcp in 0usize..3) {
        for name in ["ur5e.toml", "meca500-table.toml"] {
            check_jacobian(&perturbed_fixture(name), &u, tcp)?;
        }
    }

    /// The UR5e torques from the published centres of mass in the standard-DH link frames
    /// (independent of the MDH conversion of the fixture).
    #[test]
    fn ur5e_torques_match_the_published_inertials(u in unit_vector()) {
        let c = fixture("ur5e.toml");
        let m = Model::from_cell(&c).expect("model");
        let q_file = file_joints(&c, &u);
        let q = JointVector::from_file_units(&q_file, &c.joint_kinds()).expect("joints");
        let mass = [3.761, 8.058, 2.846, 1.37, 1.3, 0.365];
        let com_m = [
            [0.0, -0.02561, 0.00193],
            [0.2125, 0.0, 0.11336],
            [0.15, 0.0, 0.0265],
            [0.0, -0.0018, 0.01634],
            [0.0, 0.0018, 0.01634],
            [0.0, 0.0, -0.001159],
        ];
        let dh = ur5e_dh_frames(&q_file);
        let g = Vector3::new(0.0, 0.0, -9.81);
        let mut bodies: Vec<(usize, f64, Vector3<f64>)> = (0..6)
            .map(|i| {
                let c = com_m[i];
                (i + 1, mass[i], (dh[i + 1] * Vector4::new(c[0] * 1e3, c[1] * 1e3, c[2] * 1e3, 1.0)).xyz() * 1e-3)
            })
            .collect();
        let tool = &c.inertials.tool;
        let tc = tool.com_mm;
        bodies.push((6, tool.mass_kg, (dh[6] * Vector4::new(tc[0], tc[1], tc[2], 1.0)).xyz() * 1e-3));
        let tau = m.gravity_torques(&q);
        for i in 1..=6 {
            // joint i turns about z of standard frame i-1, through its origin
            let z = dh[i - 1].column(2).xyz();
            let o = dh[i - 1].column(3).xyz() * 1e-3;
            let want: f64 = bodies
                .iter()
                .filter(|(f, ..)| *f >= i)
                .map(|(_, mk, com)| z.dot(&(com - o).cross(&(g * *mk))))
                .sum();
            prop_assert!((tau[i - 1] - want).abs() < 1e-9, "tau_{} {} vs {}", i, tau[i - 1], want);
        }
    }
}

#[test]
fn fixtures_describe_their_chains() {
    let ur = Model::from_cell(&fixture("ur5e.toml")).expect("model");
    assert_eq!(ur.describe_chain(), "6 joints (RRRRRR)");
    assert_eq!(ur.guide_joint(), None);
    assert_eq!(ur.tcp_ids(), vec![1, 2, 3]);
    assert_eq!(ur.position_ids(), vec![1, 2, 3]);
    assert!(
        (ur.masses().total_mass_kg() - (3.761 + 8.058 + 2.846 + 1.37 + 1.3 + 0.365 + 0.45)).abs() < 1e-12
    );
    let meca = Model::from_cell(&fixture("meca500-table.toml")).expect("model");
    assert_eq!(meca.joint_count(), 6);
    // zero pose: the Meca500's published zero position of the flange relative to its base,
    // 190 mm forward and 308 mm up (as for the canonical cell's arm)
    let q0 = JointVector::zeros(6);
    let flange = meca.chain(&q0).flange();
    assert!((flange.p - Vector3::new(190.0, 0.0, 308.0)).norm() < 1e-9, "{}", flange.p);
}
