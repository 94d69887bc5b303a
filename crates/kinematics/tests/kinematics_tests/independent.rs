//! Cross-checks of FK, gravity torques and the Jacobian against an independent, deliberately
//! naive implementation of the same conventions (4×4 homogeneous matrices built from the cell
//! file in degrees, torques by the closed form Σ z_i · ((c_j − o_i) × m_j g)).

use nalgebra::{Matrix4, Vector3, Vector4};
use proptest::prelude::*;
use vatcal_core::cell::CellFile;
use vatcal_core::{JointVector, MeasurementContext, ParamId};
use vatcal_kinematics::Model;

fn canonical() -> CellFile {
    CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))
        .expect("fixture")
}

/// A heavily perturbed cell: beta on several rows, nonzero compliances, tilted base, odd TCPs.
fn perturbed() -> CellFile {
    let mut c = canonical();
    let deltas = [0.3, -0.7, 0.45, 1.1, -0.25, 0.6, -0.9];
    for (k, j) in c.joints.iter_mut().enumerate() {
        j.beta_deg = deltas[k] * 0.8;
        j.alpha_deg += deltas[(k + 2) % 7] * 0.5;
        j.theta_deg += deltas[(k + 4) % 7];
        j.a_mm += deltas[(k + 1) % 7] * 2.0;
        j.d_mm += deltas[(k + 3) % 7] * 3.0;
        if j.index >= 2 {
            j.compliance_rad_per_n_m = 2e-3 * (1.0 + deltas[k].abs());
        }
    }
    c.base_in_world.alpha_deg = 3.0;
    c.base_in_world.beta_deg = -4.5;
    c.base_in_world.gamma_deg = -80.0;
    c.gravity.vector_m_per_s2 = [0.3, -0.2, -9.78];
    c.tcps[0].x_mm += 1.5;
    c
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

/// World transforms of frames 0..7 with joint angles theta_i = q_i + offset + extra_deg[i].
fn naive_frames(c: &CellFile, q_file: &[f64; 7], extra_deg: &[f64; 7]) -> Vec<Matrix4<f64>> {
    let b = &c.base_in_world;
    let mut w = t(b.x_mm, b.y_mm, b.z_mm) * h(b.alpha_deg, 0) * h(b.beta_deg, 1) * h(b.gamma_deg, 2);
    let mut out = vec![w];
    for i in 1..=7u8 {
        let j = c.joint(i).expect("row");
        let (theta, d) = if i == 1 {
            (j.theta_deg, q_file[0] + j.d_mm)
        } else {
            (q_file[i as usize - 1] + j.theta_deg + extra_deg[i as usize - 1], j.d_mm)
        };
        w = w * h(j.alpha_deg, 0) * t(j.a_mm, 0.0, 0.0) * h(j.beta_deg, 1) * h(theta, 2) * t(0.0, 0.0, d);
        out.push(w);
    }
    out
}

/// Closed-form gravity torques on the c = 0 geometry.
fn naive_torques(c: &CellFile, q_file: &[f64; 7]) -> [f64; 6] {
    let f = naive_frames(c, q_file, &[0.0; 7]);
    let g = Vector3::from(c.gravity.vector_m_per_s2);
    let pt = |m: &Matrix4<f64>, p: [f64; 3]| (m * Vector4::new(p[0], p[1], p[2], 1.0)).xyz() * 1e-3;
    let mut bodies: Vec<(usize, f64, Vector3<f64>)> = c
        .inertials
        .links
        .iter()
        .map(|l| (l.frame as usize, l.mass_kg, pt(&f[l.frame as usize], l.com_mm)))
        .collect();
    bodies.push((7, c.inertials.tool.mass_kg, pt(&f[7], c.inertials.tool.com_mm)));
    let mut tau = [0.0; 6];
    for i in 2..=7usize {
        let o = f[i].column(3).xyz() * 1e-3;
        let z = f[i].column(2).xyz();
        tau[i - 2] = bodies
            .iter()
            .filter(|(frame, ..)| *frame >= i)
            .map(|(_, m, com)| z.dot(&(com - o).cross(&(g * *m))))
            .sum();
    }
    tau
}

fn naive_tcp(c: &CellFile, q_file: &[f64; 7], tcp: usize) -> Vector3<f64> {
    let tau = naive_torques(c, q_file);
    let mut extra = [0.0; 7];
    for i in 2..=7usize {
        extra[i - 1] = (c.joint(i as u8).expect("row").compliance_rad_per_n_m * tau[i - 2]).to_degrees();
    }
    let f = naive_frames(c, q_file, &extra);
    let tp = &c.tcps[tcp];
    (f[7] * Vector4::new(tp.x_mm, tp.y_mm, tp.z_mm, 1.0)).xyz()
}

fn joints_strategy() -> impl Strategy<Value = [f64; 7]> {
    (0.0..300.0f64, prop::array::uniform6(-170.0..170.0f64)).prop_map(|(g, a)| {
        let mut q = [0.0; 7];
        q[0] = g;
        q[1..].copy_from_slice(&a);
        q
    })
}

fn check_cell(c: &CellFile, q_file: [f64; 7]) -> Result<(), TestCaseError> {
    let m = Model::from_cell(c).expect("model");
    let mut arm = [0.0; 6];
    arm.copy_from_slice(&q_file[1..]);
    let q = JointVector::from_mm_deg(q_file[0], arm);
    let tau = m.gravity_torques(&q);
    let tau_ref = naive_torques(c, &q_file);
    prop_assert!(tau[0] == 0.0, "the prismatic guide has no torque");
    for k in 0..6 {
        prop_assert!(
            (tau[k + 1] - tau_ref[k]).abs() < 1e-9,
            "tau_{} {} vs {}",
            k + 2,
            tau[k + 1],
            tau_ref[k]
        );
    }
    for (k, tp) in c.tcps.iter().enumerate() {
        let p = m.tcp_position(&q, tp.id).expect("fk");
        let p_ref = naive_tcp(c, &q_file, k);
        prop_assert!((p - p_ref).norm() < 1e-9, "tcp {}: {} vs {}", tp.id, p, p_ref);
    }
    // every frame, not only the TCP
    let chain = m.chain(&q);
    let mut extra = [0.0; 7];
    for i in 2..=7usize {
        extra[i - 1] = (c.joint(i as u8).expect("row").compliance_rad_per_n_m * tau_ref[i - 2]).to_degrees();
    }
    let frames = naive_frames(c, &q_file, &extra);
    for (i, (got, want)) in chain.frames.iter().zip(&frames).enumerate() {
        let diff = (got.to_matrix4() - want).abs().max();
        prop_assert!(diff < 1e-9, "frame {i} differs by {diff}");
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn fk_and_torques_match_independent_implementation_canonical(q in joints_strategy()) {
        check_cell(&canonical(), q)?;
    }

    #[test]
    fn fk_and_torques_match_independent_implementation_perturbed(q in joints_strategy()) {
        check_cell(&perturbed(), q)?;
    }
}

#[test]
fn meca500_zero_pose_is_where_the_datasheet_says() {
    // With the base at the identity, q = 0 puts the flange (frame 7) at the Meca500's published
    // zero position relative to its base: 190 mm forward, 308 mm up (135 + 135 + 38 ...).
    let mut c = canonical();
    c.base_in_world = vatcal_core::cell::BaseInWorld {
        x_mm: 0.0,
        y_mm: 0.0,
        z_mm: 0.0,
        alpha_deg: 0.0,
        beta_deg: 0.0,
        gamma_deg: 0.0,
    };
    let m = Model::from_cell(&c).expect("model");
    let chain = m.chain(&JointVector::default());
    // express the flange in frame 1 (the carriage); the arm base is rotated by alpha_1 = -90 deg
    // about x1, so the arm's "up" axis z2 = Rx(-90) z = +y1.
    let f1 = chain.frames[1];
    let rel = f1.inverse().compose(&chain.frames[7]);
    // up = 135 + 135 + 38 = 308 along z2 = +y1, forward 120 + 70 = 190 along x1.
    assert!((rel.p.x - 190.0).abs() < 1e-9, "{}", rel.p);
    assert!((rel.p.y - 308.0).abs() < 1e-9, "{}", rel.p);
    assert!(rel.p.z.abs() < 1e-9, "{}", rel.p);
}

#[test]
fn gravity_sign_matches_the_single_link_test() {
    // background §2.2: a horizontal link along +x, axis along world +y, COM at L/2 gets
    // tau = +m g L/2 about +y. Build it from the cell: only link 7 has mass, everything else 0.
    let mut c = canonical();
    for l in c.inertials.links.iter_mut() {
        l.mass_kg = 0.0;
    }
    c.inertials.tool.mass_kg = 0.0;
    c.inertials.links.retain(|l| l.frame != 3);
    c.inertials.links.push(vatcal_core::cell::LinkInertial {
        frame: 3,
        urdf_link: None,
        mass_kg: 2.0,
        com_mm: [100.0, 0.0, 0.0],
    });
    let m = Model::from_cell(&c).expect("model");
    // find a pose where z_3 is horizontal and x_3 horizontal: check against the closed form and
    // against energy: tau = -dV/dtheta with V = m g h
    let q = JointVector::from_mm_deg(100.0, [20.0, 30.0, -40.0, 10.0, 50.0, 0.0]);
    let tau = m.gravity_torques(&q);
    let energy = |qq: &JointVector| {
        let ch = m.chain(qq);
        let com = ch.frames[3].transform_point(&Vector3::new(100.0, 0.0, 0.0)) * 1e-3;
        -2.0 * m.gravity().dot(&com)
    };
    let hstep = 1e-6;
    let mut qp = q;
    let mut qm = q;
    qp[2] += hstep;
    qm[2] -= hstep;
    let dv = (energy(&qp) - energy(&qm)) / (2.0 * hstep);
    assert!((tau[2] + dv).abs() < 1e-6, "tau_3 {} vs -dV/dq {}", tau[2], -dv);
}

fn fd_column(
    m: &Model,
    q: &JointVector,
    ctx: &MeasurementContext,
    tcp: u32,
    id: ParamId,
    tau: &[f64; vatcal_core::MAX_JOINTS],
) -> Vector3<f64> {
    let hstep = match id.unit() {
        vatcal_core::params::ParamUnit::Mm => 1e-5,
        vatcal_core::params::ParamUnit::RadPerNm => 1e-6,
        _ => 1e-7,
    };
    let tp = m.tcp(tcp).expect("tcp");
    let eval = |v: f64| {
        let mut mm = m.clone();
        mm.set_param(id, v).expect("set");
        let tpp = mm.tcp(tcp).unwrap_or(tp);
        mm.chain_full(q, ctx, false, Some(tau)).tool_point(&tpp)
    };
    let v0 = m.param(id).expect("param");
    (eval(v0 + hstep) - eval(v0 - hstep)) / (2.0 * hstep)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(60))]

    #[test]
    fn jacobian_matches_central_differences(q in joints_strategy(), tcp in 1u32..=3) {
        let c = perturbed();
        let m = Model::from_cell(&c).expect("model");
        let mut arm = [0.0; 6];
        arm.copy_from_slice(&q[1..]);
        let qv = JointVector::from_mm_deg(q[0], arm);
        let params = m.all_params();
        let jac = m.jacobian(&qv, tcp, &params.0).expect("jacobian");
        let tau = m.gravity_torques(&qv);
        let ctx = MeasurementContext::default();
        for (k, id) in params.iter().enumerate() {
            let fd = fd_column(&m, &qv, &ctx, tcp, *id, &tau);
            let an = jac.column(k).into_owned();
            let scale = 1.0 + an.norm();
            prop_assert!((fd - an).norm() < 2e-6 * scale, "{}: analytic {} vs fd {}", id, an, fd);
        }
    }
}

#[test]
fn paper34_jacobian_has_the_documented_units_and_shape() {
    let m = Model::from_cell(&canonical()).expect("model");
    let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    let set = vatcal_core::ParamSet::paper34();
    let j = m.jacobian(&q, 2, &set.0).expect("jacobian");
    assert_eq!(j.shape(), (3, 34));
    // base_x/y/z columns are unit vectors (mm per mm)
    for (k, id) in set.iter().enumerate() {
        if let ParamId::Base(b) = id
            && matches!(b, vatcal_core::BaseParam::X | vatcal_core::BaseParam::Y | vatcal_core::BaseParam::Z)
        {
            assert!((j.column(k).norm() - 1.0).abs() < 1e-12);
        }
    }
}

#[test]
fn measurement_jacobian_handles_positions_and_residual_sign() {
    let m = Model::from_cell(&canonical()).expect("model");
    let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    let meas = vatcal_core::Measurement::probe(2, 1, q);
    let params = [
        ParamId::Position { id: 2, axis: vatcal_core::Axis::Y },
        ParamId::Position { id: 1, axis: vatcal_core::Axis::Y },
        ParamId::Base(vatcal_core::BaseParam::X),
    ];
    let mut out = [0.0; 9];
    let r = m.measurement_jacobian_into(&meas, &params, &mut out).expect("ok");
    assert_eq!(&out[0..3], &[0.0, -1.0, 0.0]);
    assert_eq!(&out[3..6], &[0.0, 0.0, 0.0]);
    assert_eq!(&out[6..9], &[1.0, 0.0, 0.0]);
    let p = m.tcp_position(&q, 1).expect("fk");
    assert!((r - (m.position(2).expect("pos") - p)).norm() < 1e-12);
    assert!((m.predict(&meas).expect("p") + r).norm() < 1e-12);
}

#[test]
fn cell_round_trip_through_the_model_preserves_predictions() {
    let c = perturbed();
    let m = Model::from_cell(&c).expect("model");
    let back = Model::from_cell(&m.to_cell()).expect("model");
    let q = JointVector::from_mm_deg(33.0, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    for tcp in [1, 2, 3] {
        let a = m.tcp_position(&q, tcp).expect("a");
        let b = back.tcp_position(&q, tcp).expect("b");
        assert!((a - b).norm() < 1e-10);
    }
}
