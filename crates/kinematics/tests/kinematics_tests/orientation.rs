//! Orientation measurements (`Target::Orientation`, issue 31 item 1): the rotation-vector
//! residual and its finite-difference Jacobian rows against the frame axes of the chain (the
//! column of a joint-angle offset is that joint's world axis, of a link twist the previous
//! frame's x axis, of a length zero) and against an independent central difference of the
//! residual with a larger step.

use nalgebra::{UnitQuaternion, Vector3};
use vatcal_core::effects::EffectSpec;
use vatcal_core::params::{EffectParam, ToolFrameDof};
use vatcal_core::{CellFile, JointVector, Measurement, ParamId, rotation_error};
use vatcal_kinematics::Model;

fn ur5e() -> Model {
    let cell =
        CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml")).expect("fixture");
    Model::from_cell(&cell).expect("model")
}

fn q_test() -> JointVector {
    JointVector::from_slice(&[0.3, -1.1, 1.4, -0.7, 1.2, 0.4]).expect("joints")
}

/// The model's own orientation measured: residual 0; a rotation `w` applied on the world side:
/// residual `w`.
#[test]
fn residual_is_the_world_rotation_vector() {
    let model = ur5e();
    let q = q_test();
    let r = model.tool_rotation_ctx(&q, &Default::default()).expect("rotation");
    let exact = UnitQuaternion::from_matrix(&r);
    let m = Measurement::orientation(1, q, exact);
    assert!(model.residual(&m).expect("residual").norm() < 1e-12);
    let w = Vector3::new(2e-3, -1e-3, 4e-4);
    let moved = UnitQuaternion::from_scaled_axis(w) * exact;
    let m = Measurement::orientation(1, q, moved);
    assert!((model.residual(&m).expect("residual") - w).norm() < 1e-12);
    assert!((model.predict(&m).expect("predict") + w).norm() < 1e-12);
    // the log is accurate for tiny rotations (no acos of the trace)
    let tiny = Vector3::new(1e-9, 0.0, -2e-9);
    let e =
        rotation_error(&(UnitQuaternion::from_scaled_axis(tiny).to_rotation_matrix().into_inner() * r), &r);
    assert!((e - tiny).norm() < 1e-15, "{e}");
}

/// Jacobian rows of an orientation measurement: joint offsets give the joint axis, twists the
/// previous x axis, lengths and TCP coordinates zero; every column (tool-frame effect included,
/// not switched on) matches a central difference of the residual with a 10× larger step.
#[test]
fn jacobian_rows_match_frame_axes_and_differences() {
    let model = ur5e();
    let q = q_test();
    let r = model.tool_rotation_ctx(&q, &Default::default()).expect("rotation");
    let m = Measurement::orientation(1, q, UnitQuaternion::from_matrix(&r));
    let tool = |d| ParamId::Effect(EffectParam::ToolFrame(d));
    let mut params: Vec<ParamId> = Vec::new();
    for i in 1..=6 {
        params.extend([ParamId::ThetaOffset(i), ParamId::Alpha(i), ParamId::D(i), ParamId::A(i)]);
    }
    params.extend([
        ParamId::Tcp { id: 1, axis: vatcal_core::Axis::X },
        tool(ToolFrameDof::Rx),
        tool(ToolFrameDof::Ry),
    ]);
    let mut out = vec![0.0; 3 * params.len()];
    let residual = model.measurement_jacobian_into(&m, &params, &mut out).expect("jacobian");
    assert!(residual.norm() < 1e-12);
    let col = |j: usize| Vector3::new(out[3 * j], out[3 * j + 1], out[3 * j + 2]);
    let chain = model.chain(&q);
    for i in 1..=6usize {
        let k = 4 * (i - 1);
        assert!((col(k) - chain.frames[i].z_axis()).norm() < 1e-8, "theta {i}: {}", col(k));
        assert!((col(k + 1) - chain.frames[i - 1].x_axis()).norm() < 1e-8, "alpha {i}: {}", col(k + 1));
        assert!(col(k + 2).norm() < 1e-12 && col(k + 3).norm() < 1e-12, "lengths {i}");
    }
    assert_eq!(col(24), Vector3::zeros());
    // independent difference with a 10x step, the tool frame switched on for its parameters
    let mut on = model.clone();
    on.enable_effect(EffectSpec::ToolFrame).expect("tool frame");
    for (j, id) in params.iter().enumerate() {
        let h = 1e-2 * id.typical_scale();
        let at = |v: f64| {
            let mut x = on.clone();
            x.set_param(*id, v).expect("set");
            x.predict(&m).expect("predict")
        };
        let v = on.param(*id).expect("param");
        let fd = (at(v + h) - at(v - h)) / (2.0 * h);
        assert!((fd - col(j)).norm() < 1e-6 * (1.0 + fd.norm()), "{}: {fd} vs {}", id.name(), col(j));
    }
    // the tool-frame rotations turn the tool frame about its own x and y axes
    let tool_frame = chain.tool;
    assert!((col(25) - tool_frame.x_axis()).norm() < 1e-8, "tool rx {}", col(25));
    assert!((col(26) - tool_frame.y_axis()).norm() < 1e-8, "tool ry {}", col(26));
}
