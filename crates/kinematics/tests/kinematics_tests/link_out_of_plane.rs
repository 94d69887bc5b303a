//! `link-out-of-plane` and the link-shift hook: the moved TCP against an explicit translation
//! and rotation of the distal chain, the analytic Jacobian columns against central differences
//! on both fixtures (with `link-bending` on the same links, so shift and tilt compose), and the
//! cell file's round trip.

use nalgebra::{Rotation3, Unit};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::cell::CellFile;
use vatcal_core::effects::link_bending;
use vatcal_core::effects::link_out_of_plane::{self, Component, TERMS};
use vatcal_core::params::Axis;
use vatcal_core::{JointVector, ParamId};
use vatcal_kinematics::Model;

use crate::link_bending::assert_columns_match_central_differences;

fn fixture(name: &str) -> Model {
    let cell =
        CellFile::load(format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"))).expect("fixture");
    Model::from_cell(&cell).expect("model")
}

fn random_q(model: &Model, rng: &mut ChaCha8Rng) -> JointVector {
    let mut q = JointVector::zeros(model.joint_count());
    for (k, (lo, hi)) in model.joint_limits().iter().enumerate() {
        let (lo, hi) = if lo.is_finite() && hi.is_finite() { (*lo, *hi) } else { (-3.0, 3.0) };
        q[k] = rng.random_range(lo..hi);
    }
    q
}

/// The links that follow a revolute joint (where the effect exists).
fn links(model: &Model) -> Vec<u8> {
    (2..=model.joint_count())
        .filter(|j| model.is_revolute(*j) && model.is_revolute(j - 1))
        .map(|j| j as u8)
        .collect()
}

fn map(coefficients: &[f64; TERMS], q: &JointVector, j: u8) -> f64 {
    let phi = link_out_of_plane::terms(q[j as usize - 2], q[j as usize - 1]);
    phi.iter().zip(coefficients).map(|(p, c)| p * c).sum()
}

#[test]
fn the_link_frame_moves_along_its_axis_then_tilts_about_the_moved_origin() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    for name in ["meca500-zaber.toml", "ur5e.toml"] {
        let nominal = fixture(name);
        for j in links(&nominal) {
            let mut model = nominal.clone();
            let mut coefficients = [[0.0; TERMS]; 3];
            for (c, comp) in Component::ALL.into_iter().enumerate() {
                model.enable_effect(link_out_of_plane::spec(j, comp)).expect("on");
                let scale = if comp == Component::Axial { 0.05 } else { 2e-4 };
                for (k, v) in coefficients[c].iter_mut().enumerate() {
                    *v = rng.random_range(-scale..scale);
                    let id = ParamId::Effect(link_out_of_plane::param(j, comp, k as u8));
                    model.set_param(id, *v).expect("set");
                }
            }
            for _ in 0..5 {
                let q = random_q(&nominal, &mut rng);
                let tcp = nominal.tcp_ids()[0];
                let [sz, ex, ey] = [0, 1, 2].map(|c| map(&coefficients[c], &q, j));
                let f = nominal.chain(&q).frames()[j as usize];
                let p = nominal.tcp_position(&q, tcp).expect("fk");
                let o = f.p + f.z_axis() * sz;
                let rx = Rotation3::from_axis_angle(&Unit::new_normalize(f.x_axis()), ex);
                let ry = Rotation3::from_axis_angle(&Unit::new_normalize(rx * f.y_axis()), ey);
                let expected = o + (ry * rx) * (p - f.p);
                let got = model.tcp_position(&q, tcp).expect("fk");
                assert!(
                    (got - expected).norm() < 1e-9,
                    "{name} link {j}: {got:?} vs {expected:?} (moved {:.4} mm)",
                    (p - expected).norm()
                );
            }
        }
    }
}

#[test]
fn link_out_of_plane_columns_match_central_differences_on_any_chain() {
    let mut rng = ChaCha8Rng::seed_from_u64(32);
    for name in ["meca500-zaber.toml", "ur5e.toml"] {
        let nominal = fixture(name);
        let mut model = nominal.clone();
        let mut params = Vec::new();
        for j in links(&nominal) {
            model.enable_effect(link_bending::spec(j)).expect("bending on");
            let bend = ParamId::Effect(link_bending::param(j, Axis::X));
            model.set_param(bend, rng.random_range(-2e-4..2e-4)).expect("bend");
            params.push(bend);
            for comp in Component::ALL {
                model.enable_effect(link_out_of_plane::spec(j, comp)).expect("on");
                let scale = if comp == Component::Axial { 0.05 } else { 2e-4 };
                for k in 0..TERMS as u8 {
                    let id = ParamId::Effect(link_out_of_plane::param(j, comp, k));
                    model.set_param(id, rng.random_range(-scale..scale)).expect("set");
                    params.push(id);
                }
            }
        }
        params.push(ParamId::Alpha(3));
        for _ in 0..4 {
            let q = random_q(&nominal, &mut rng);
            assert_columns_match_central_differences(&model, &params, &q, name);
        }
    }
}

#[test]
fn link_out_of_plane_round_trips_through_the_cell_file() {
    let nominal = fixture("meca500-zaber.toml");
    let mut model = nominal.clone();
    model.enable_effect(link_out_of_plane::spec(4, Component::Axial)).expect("on");
    model.enable_effect(link_out_of_plane::spec(4, Component::TiltY)).expect("on");
    let a = ParamId::Effect(link_out_of_plane::param(4, Component::Axial, 6));
    let r = ParamId::Effect(link_out_of_plane::param(4, Component::TiltY, 2));
    model.set_param(a, 0.021).expect("axial");
    model.set_param(r, 0.01f64.to_radians()).expect("tilt");
    let text = model.to_cell().to_toml_string().expect("write");
    assert!(
        text.contains("effect = \"link-out-of-plane\"") && text.contains("component = \"axial\""),
        "{text}"
    );
    assert!(text.contains("oop4_axial_sin3cos4_mm = 0.021"), "{text}");
    assert!(text.contains("oop4_ry_cos4_deg = 0.01"), "{text}");
    let back = Model::from_cell(&CellFile::from_toml_str(&text, "back").expect("reload")).expect("model");
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    for _ in 0..5 {
        let q = random_q(&nominal, &mut rng);
        let (p, b) = (model.tcp_position(&q, 1).expect("fk"), back.tcp_position(&q, 1).expect("fk"));
        assert!((p - b).norm() < 1e-9, "{p:?} vs {b:?}");
    }
    // a component the effect does not know is an error naming the field
    let bad = text.replace("component = \"axial\"", "component = \"sideways\"");
    let err = match CellFile::from_toml_str(&bad, "bad.toml") {
        Err(e) => e.to_string(),
        Ok(cell) => Model::from_cell(&cell).map(|_| String::new()).unwrap_or_else(|e| e.to_string()),
    };
    assert!(err.contains("sideways"), "{err}");
}
