//! `link-bending` and the link-rotation hook it acts through: the links' bending moments
//! against a direct sum over the distal bodies, the deflected TCP against an explicit
//! rotation of the distal chain, the analytic Jacobian columns against central differences
//! (loads held fixed, as the Jacobian holds them), and the cell file's round trip.

use nalgebra::{Rotation3, Unit, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::cell::CellFile;
use vatcal_core::effects::link_bending;
use vatcal_core::params::Axis;
use vatcal_core::{JointVector, MeasurementContext, ParamId};
use vatcal_gravity_torque::MassModel;
use vatcal_kinematics::Model;

fn fixture(name: &str) -> (CellFile, Model) {
    let cell =
        CellFile::load(format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))).expect("fixture");
    let model = Model::from_cell(&cell).expect("model");
    (cell, model)
}

fn random_q(model: &Model, rng: &mut ChaCha8Rng) -> JointVector {
    let mut q = JointVector::zeros(model.joint_count());
    for (k, (lo, hi)) in model.joint_limits().iter().enumerate() {
        let (lo, hi) = if lo.is_finite() && hi.is_finite() { (*lo, *hi) } else { (-3.0, 3.0) };
        q[k] = rng.random_range(lo..hi);
    }
    q
}

/// Σ over the bodies of frames j..=N of `(c − o_j) × m g`, in frame j's axes (x, y).
fn direct_bending_moment(cell: &CellFile, model: &Model, q: &JointVector, j: usize) -> [f64; 2] {
    let chain = model.chain(q);
    let frames = chain.frames();
    let masses = MassModel::from_inertials(&cell.inertials);
    let g = Vector3::from(cell.gravity.vector_m_per_s2);
    let fj = frames[j];
    let mut m = Vector3::zeros();
    for (k, frame) in frames.iter().enumerate().skip(j) {
        let body = masses.body(k);
        let c = frame.transform_point(&body.com_mm);
        m += ((c - fj.p) * 1e-3).cross(&(g * body.mass_kg));
    }
    let local = fj.r.transpose() * m;
    [local.x, local.y]
}

fn revolute_joints(model: &Model) -> Vec<u8> {
    (1..=model.joint_count()).filter(|j| model.is_revolute(*j)).map(|j| j as u8).collect()
}

#[test]
fn bending_moments_are_the_distal_weight_about_each_joint() {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    for name in ["meca500-zaber.toml", "ur5e.toml"] {
        let (cell, model) = fixture(name);
        let mut largest: f64 = 0.0;
        for _ in 0..20 {
            let q = random_q(&model, &mut rng);
            let m = model.link_bending_moments(&q);
            for j in 1..=model.joint_count() {
                let d = direct_bending_moment(&cell, &model, &q, j);
                assert!(
                    (m[j - 1][0] - d[0]).abs() < 1e-9 && (m[j - 1][1] - d[1]).abs() < 1e-9,
                    "{name} joint {j}: {:?} vs {d:?}",
                    m[j - 1]
                );
                largest = largest.max(d[0].hypot(d[1]));
            }
        }
        assert!(largest > 0.1, "{name}: bending moments all near zero ({largest} N*m)");
    }
}

#[test]
fn link_bending_rotates_the_distal_chain_about_the_link_axes() {
    let mut rng = ChaCha8Rng::seed_from_u64(22);
    for name in ["meca500-zaber.toml", "ur5e.toml"] {
        let (cell, nominal) = fixture(name);
        for j in revolute_joints(&nominal) {
            let mut model = nominal.clone();
            model.enable_effect(link_bending::spec(j)).expect("on any revolute joint");
            let (kx, ky) = (rng.random_range(-3e-4..3e-4), rng.random_range(-3e-4..3e-4));
            model.set_param(ParamId::Effect(link_bending::param(j, Axis::X)), kx).expect("x");
            model.set_param(ParamId::Effect(link_bending::param(j, Axis::Y)), ky).expect("y");
            for _ in 0..5 {
                let q = random_q(&nominal, &mut rng);
                let tcp = nominal.tcp_ids()[0];
                let [mx, my] = direct_bending_moment(&cell, &nominal, &q, j as usize);
                let chain = nominal.chain(&q);
                let f = chain.frames()[j as usize];
                let p = nominal.tcp_position(&q, tcp).expect("fk");
                // Rx(ex) Ry(ey) in frame j's axes: about x_j, then about the rotated y
                let rx = Rotation3::from_axis_angle(&Unit::new_normalize(f.x_axis()), kx * mx);
                let ry_axis = rx * f.y_axis();
                let ry = Rotation3::from_axis_angle(&Unit::new_normalize(ry_axis), ky * my);
                let expected = f.p + (ry * rx) * (p - f.p);
                let got = model.tcp_position(&q, tcp).expect("fk");
                assert!(
                    (got - expected).norm() < 1e-9,
                    "{name} joint {j}: {got:?} vs {expected:?} (moved {:.4} mm)",
                    (p - expected).norm()
                );
            }
        }
    }
}

#[test]
fn link_bending_columns_match_central_differences_on_any_chain() {
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    for name in ["meca500-zaber.toml", "ur5e.toml"] {
        let (_, nominal) = fixture(name);
        let mut model = nominal.clone();
        let mut params = Vec::new();
        for j in revolute_joints(&nominal) {
            model.enable_effect(link_bending::spec(j)).expect("on");
            for axis in [Axis::X, Axis::Y] {
                let id = ParamId::Effect(link_bending::param(j, axis));
                model.set_param(id, rng.random_range(-2e-4..2e-4)).expect("set");
                params.push(id);
            }
        }
        // a compliance too, so that the torque path runs beside the bending
        model.set_param(ParamId::Compliance(3), 2e-4).expect("c_3");
        params.push(ParamId::Compliance(3));
        params.push(ParamId::Alpha(3));
        for _ in 0..6 {
            let q = random_q(&nominal, &mut rng);
            assert_columns_match_central_differences(&model, &params, &q, name);
        }
    }
}

/// The analytic Jacobian columns of `params` at `q` (first TCP) equal central differences of
/// the FK with the gravity loads held at their values at `q` (as the Jacobian holds them).
pub(crate) fn assert_columns_match_central_differences(
    model: &Model,
    params: &[ParamId],
    q: &JointVector,
    name: &str,
) {
    let ctx = MeasurementContext::default();
    let tcp = model.tcp_ids()[0];
    let mut out = vec![0.0; 3 * params.len()];
    model.jacobian_into(q, &ctx, tcp, params, &mut out).expect("jacobian");
    let loads = model.gravity_loads(q);
    let t = model.tcp(tcp).expect("tcp");
    for (c, id) in params.iter().enumerate() {
        let h = id.typical_scale() * 1e-3;
        let v0 = model.param(*id).expect("param");
        let at = |v: f64| {
            let mut m = model.clone();
            m.set_param(*id, v).expect("set");
            m.chain_with_loads(q, &ctx, &loads).tool_point(&t)
        };
        let fd = (at(v0 + h) - at(v0 - h)) / (2.0 * h);
        let analytic = Vector3::new(out[3 * c], out[3 * c + 1], out[3 * c + 2]);
        let s = id.typical_scale();
        assert!(
            (analytic - fd).norm() * s <= 1e-9 + 1e-6 * analytic.norm() * s,
            "{name}: {} analytic {analytic:?} vs fd {fd:?}",
            id.name()
        );
    }
}

#[test]
fn link_bending_round_trips_through_the_cell_file() {
    let (cell, nominal) = fixture("meca500-zaber.toml");
    let mut model = nominal.clone();
    model.enable_effect(link_bending::spec(3)).expect("on");
    let kx = ParamId::Effect(link_bending::param(3, Axis::X));
    let ky = ParamId::Effect(link_bending::param(3, Axis::Y));
    model.set_param(kx, 1.5e-4).expect("x");
    model.set_param(ky, -7e-5).expect("y");
    let text = model.to_cell().to_toml_string().expect("write");
    assert!(text.contains("effect = \"link-bending\""), "{text}");
    assert!(text.contains("bend3_x = ") && text.contains("joint = 3"), "{text}");
    let back = Model::from_cell(&CellFile::from_toml_str(&text, "back").expect("reload")).expect("model");
    assert_eq!(back.param(kx).expect("x"), 1.5e-4);
    assert_eq!(back.param(ky).expect("y"), -7e-5);
    let q = JointVector::from_mm_deg(120.0, [10.0, 30.0, -20.0, 40.0, 50.0, 60.0]);
    let d = model.tcp_position(&q, 1).expect("a") - back.tcp_position(&q, 1).expect("b");
    assert!(d.norm() < 1e-12, "{d:?}");
    assert!(
        (model.tcp_position(&q, 1).expect("a") - nominal.tcp_position(&q, 1).expect("c")).norm() > 1e-4,
        "the effect moves the TCP"
    );
    // the canonical fixture itself has no such entry and is unchanged by the new effect
    assert_eq!(Model::from_cell(&cell).expect("fixture").effects(), nominal.effects());
    assert!(
        !CellFile::load(format!("{}/../../fixtures/meca500-zaber.toml", env!("CARGO_MANIFEST_DIR")))
            .expect("fixture")
            .to_toml_string()
            .expect("write")
            .contains("link-bending")
    );
}
