//! Plane contacts (`Target::Plane`, issue 31 item 3): the residual block (height above the
//! plane; with the tool axis held normal, the rim heights of the tilted contact face), and its
//! Jacobian against central differences of the residual over robot, TCP and plane parameters,
//! with the tool-frame effect switched off (differenced at zero) and on.

use nalgebra::Vector3;
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::{EffectParam, ToolFrameDof};
use vatcal_core::{Axis, CellFile, JointVector, Measurement, ParamId, PlaneDof};
use vatcal_kinematics::{ContactPlane, Model};

fn ur5e_with_table() -> Model {
    let cell =
        CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml")).expect("fixture");
    let mut model = Model::from_cell(&cell).expect("model");
    model.insert_plane(3, ContactPlane::new(Vector3::new(0.02, -0.01, 1.0), -20.0, 40.0));
    model
}

fn q_test() -> JointVector {
    JointVector::from_slice(&[0.3, -1.1, 1.4, -0.7, 1.2, 0.4]).expect("joints")
}

/// Row 1 is minus the TCP's height above the plane; rows 2–3 are zero without the normal and
/// `−r·(u, v)·(n × z)` with it (zero when the tool axis is along the normal, either sign).
#[test]
fn residual_is_the_height_and_the_rim_tilt() {
    let mut model = ur5e_with_table();
    let q = q_test();
    let p = model.tcp_position(&q, 1).expect("fk");
    let plane = *model.plane(3).expect("plane");
    let e = model.residual(&Measurement::plane(3, 1, q, false)).expect("residual");
    assert!((e.x + plane.height_mm(&p)).abs() < 1e-9 && e.y == 0.0 && e.z == 0.0, "{e}");
    // a plane through the tool axis direction: the normal rows vanish
    let z = model.tool_rotation_ctx(&q, &Default::default()).expect("rotation").column(2).into_owned();
    model.insert_plane(4, ContactPlane::new(-z, -z.dot(&p), 40.0));
    let e = model.residual(&Measurement::plane(4, 1, q, true)).expect("residual");
    assert!(e.norm() < 1e-9, "{e}");
    // tilted by 1 mrad about u: the rim error is r × 1 mrad = 0.04 mm
    model.set_param(ParamId::Plane { id: 4, dof: PlaneDof::TiltU }, 1e-3).expect("tilt");
    let e = model.residual(&Measurement::plane(4, 1, q, true)).expect("residual");
    assert!((e.yz().norm() - 0.04).abs() < 1e-6, "{e}");
    assert!(model.residual(&Measurement::plane(9, 1, q, false)).is_err(), "unknown plane");
}

/// Every Jacobian column matches a central difference of the prediction (10× the internal
/// step for the tool-axis rows), with and without the normal, for robot, TCP, base, plane and
/// tool-frame parameters.
#[test]
fn jacobian_matches_central_differences() {
    let tool = |d| ParamId::Effect(EffectParam::ToolFrame(d));
    let mut params: Vec<ParamId> = Vec::new();
    for i in 1..=6 {
        params.extend([ParamId::ThetaOffset(i), ParamId::Alpha(i), ParamId::D(i), ParamId::A(i)]);
    }
    params.extend([ParamId::Tcp { id: 1, axis: Axis::Z }, ParamId::Base(vatcal_core::BaseParam::Beta)]);
    params.extend(PlaneDof::ALL.map(|dof| ParamId::Plane { id: 3, dof }));
    params.extend([tool(ToolFrameDof::Rx), tool(ToolFrameDof::Tx)]);
    let off = ur5e_with_table();
    let mut on = off.clone();
    on.enable_effect(EffectSpec::ToolFrame).expect("tool frame");
    let mut on_tilted = on.clone();
    on_tilted.set_param(tool(ToolFrameDof::Ry), 2e-3).expect("tilt");
    for model in [&off, &on, &on_tilted] {
        for normal in [false, true] {
            let m = Measurement::plane(3, 1, q_test(), normal);
            let mut out = vec![0.0; 3 * params.len()];
            let residual = model.measurement_jacobian_into(&m, &params, &mut out).expect("jacobian");
            assert!((residual - model.residual(&m).expect("residual")).norm() < 1e-12);
            for (j, id) in params.iter().enumerate() {
                let h = 1e-2 * id.typical_scale();
                let mut work = if model.has_param(*id) { model.clone() } else { on.clone() };
                let v = work.param(*id).expect("value");
                work.set_param(*id, v + h).expect("set");
                let plus = work.predict(&m).expect("predict");
                work.set_param(*id, v - h).expect("set");
                let minus = work.predict(&m).expect("predict");
                let fd = (plus - minus) / (2.0 * h);
                let col = Vector3::new(out[3 * j], out[3 * j + 1], out[3 * j + 2]);
                assert!((col - fd).norm() < 1e-5 * (1.0 + fd.norm()), "{id} normal={normal}: {col} vs {fd}");
                if !normal {
                    assert_eq!((col.y, col.z), (0.0, 0.0), "{id}: rows 2-3 without the normal");
                }
            }
        }
    }
}
