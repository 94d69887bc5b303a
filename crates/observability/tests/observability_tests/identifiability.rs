//! Identifiability on the canonical cell (background.md §5.2, §5.3) and on synthetic matrices.

use crate::common;

use common::{canonical_model, probe_poses};
use faer::Mat;
use vatcal_core::{BaseParam, ParamId, ParamSet};
use vatcal_observability::identifiability::{
    AnalysisOptions, analyze_jacobian, preference_order, rank_deficient_error,
};
use vatcal_observability::{
    ObservabilityError, all_identifiable, analyze, assemble_jacobian, check_identifiable,
};

fn redundancy(
    report: &vatcal_observability::IdentifiabilityReport,
    p: ParamId,
) -> &vatcal_observability::Redundancy {
    report.redundant.iter().find(|r| r.param == p).unwrap_or_else(|| panic!("{p} not reported redundant"))
}

fn is_base(p: ParamId) -> bool {
    matches!(p, ParamId::Base(_))
}

#[test]
fn jacobian_matches_central_differences_of_predict() {
    let model = canonical_model();
    let poses = probe_poses(&model, &[1, 2, 3], 4, 11);
    let params = preference_order(&model);
    let j = assemble_jacobian(&model, &poses, &params).expect("jacobian");
    assert_eq!((j.nrows(), j.ncols()), (12, params.len()));
    for (c, p) in params.iter().enumerate() {
        let h = 1e-6 * p.typical_scale().max(1e-3) / 1e-3;
        let mut plus = model.clone();
        plus.set_param(*p, model.param(*p).expect("param") + h).expect("set");
        let mut minus = model.clone();
        minus.set_param(*p, model.param(*p).expect("param") - h).expect("set");
        for (k, m) in poses.iter().enumerate() {
            let fd = (plus.predict(m).expect("predict") - minus.predict(m).expect("predict")) / (2.0 * h);
            for r in 0..3 {
                let a = j[(3 * k + r, c)];
                assert!((a - fd[r]).abs() <= 1e-5 * (1.0 + fd[r].abs()), "{p} row {r}: {a} vs {}", fd[r]);
            }
        }
    }
}

#[test]
fn three_positions_give_rank_34_and_the_paper_basis() {
    let model = canonical_model();
    let poses = probe_poses(&model, &[1, 2, 3], 60, 1);
    let order = preference_order(&model);
    let report = analyze(&model, &poses, &order).expect("analysis");
    eprintln!("{report}");
    assert_eq!(report.rank, 34, "full parameter set");
    assert_eq!(report.identifiable, ParamSet::paper34().0, "preference order keeps the paper's 34");
    assert_eq!(report.lost_directions.len(), order.len() - 34);

    // The paper's 34 alone are a valid basis.
    let paper = check_identifiable(&model, &poses, &ParamSet::paper34()).expect("paper34 identifiable");
    assert_eq!(paper.rank, 34);
    assert!(paper.redundant.is_empty() && paper.lost_directions.is_empty());
    assert!(paper.condition_number_of_rank() < 1e6, "cond {}", paper.condition_number_of_rank());

    // Redundant parameters of background §5.2 with sensible partners.
    let d3 = redundancy(&report, ParamId::D(3));
    assert_eq!(d3.confounded_with.len(), 1, "{}", d3.sentence());
    assert_eq!(d3.confounded_with[0].0, ParamId::D(4));
    assert!((d3.confounded_with[0].1 - 1.0).abs() < 1e-6, "{}", d3.sentence());
    for p in [ParamId::A(2), ParamId::D(2), ParamId::D(1), ParamId::A(1)] {
        let r = redundancy(&report, p);
        assert!(r.fit_residual < 1e-8, "{}", r.sentence());
        assert!(r.confounded_with.iter().all(|(q, _)| is_base(*q)), "{}", r.sentence());
    }
    // a_1 is a translation along x_1 = -y_W: base_y with weight -1.
    let a1 = redundancy(&report, ParamId::A(2));
    assert_eq!(a1.confounded_with[0].0, ParamId::Base(BaseParam::Y), "{}", a1.sentence());
    assert!((a1.confounded_with[0].1 + 1.0).abs() < 1e-6, "{}", a1.sentence());
    for p in [ParamId::Alpha(1), ParamId::ThetaOffset(1)] {
        let r = redundancy(&report, p);
        assert!(r.fit_residual < 1e-8, "{}", r.sentence());
        assert!(
            r.confounded_with.iter().any(|(q, _)| matches!(
                q,
                ParamId::Base(BaseParam::Alpha | BaseParam::Beta | BaseParam::Gamma)
            )),
            "{}",
            r.sentence()
        );
    }
    assert!(redundancy(&report, ParamId::D(3)).sentence().contains("d_3 is absorbed by d_4"));

    // all-identifiable = the paper's 34
    assert_eq!(all_identifiable(&model, &poses).expect("basis"), ParamSet::paper34());
}

#[test]
fn fewer_positions_lose_the_world_frame() {
    let model = canonical_model();
    let paper = ParamSet::paper34();
    for (positions, expected_rank) in [(&[1u32][..], 31usize), (&[2, 3][..], 33), (&[1, 3][..], 33)] {
        let poses = probe_poses(&model, positions, 45, 7);
        let report = analyze(&model, &poses, &paper).expect("analysis");
        eprintln!("positions {positions:?}:\n{report}");
        assert_eq!(report.rank, expected_rank, "positions {positions:?}");
        assert_eq!(report.lost_directions.len(), 34 - expected_rank);
        assert_eq!(report.redundant.len(), 34 - expected_rank);
        // the lost directions are rigid motions of the world frame: they involve base angles
        for d in &report.lost_directions {
            assert!(d.singular_value <= report.threshold());
            assert!(d.combination.iter().any(|(p, _)| is_base(*p)), "{}", d.sentence());
        }
        match check_identifiable(&model, &poses, &paper) {
            Err(ObservabilityError::RankDeficient { rank, needed, unidentifiable, message }) => {
                assert_eq!((rank, needed), (expected_rank, 34));
                assert_eq!(unidentifiable.len(), 34 - expected_rank);
                for p in &unidentifiable {
                    assert!(message.contains(&p.name()), "{message}");
                }
            }
            other => panic!("expected RankDeficient, got {other:?}"),
        }
        assert_eq!(all_identifiable(&model, &poses).expect("basis").len(), expected_rank);
    }
}

#[test]
fn zero_column_is_reported_as_without_effect() {
    // c_2 has no effect when its torque is zero: emulate with a synthetic zero column.
    let mut j = Mat::<f64>::zeros(9, 3);
    for r in 0..9 {
        j[(r, 0)] = (r as f64 + 1.0).sin();
        j[(r, 2)] = (r as f64 * 0.7).cos();
    }
    let params = ParamSet(vec![ParamId::D(4), ParamId::Compliance(2), ParamId::D(5)]);
    let report = analyze_jacobian(j.as_ref(), &params, &AnalysisOptions::default()).expect("analysis");
    assert_eq!(report.rank, 2);
    assert_eq!(report.identifiable, vec![ParamId::D(4), ParamId::D(5)]);
    assert!(report.redundant[0].sentence().contains("c_2 has no effect"));
}

#[test]
fn synthetic_dependency_is_named_with_natural_unit_weights() {
    // column 2 = 2·col0 − 1000·col1 (col1 is 1000× smaller, as a compliance vs a length might be)
    let (m, l) = (30, 4);
    let mut j = Mat::<f64>::zeros(m, l);
    for r in 0..m {
        let x = r as f64;
        j[(r, 0)] = (0.3 * x).sin() + 0.1;
        j[(r, 1)] = 1e-3 * (0.17 * x + 1.0).cos();
        j[(r, 3)] = (0.05 * x * x).sin();
        j[(r, 2)] = 2.0 * j[(r, 0)] - 1000.0 * j[(r, 1)];
    }
    let params = ParamSet(vec![ParamId::D(4), ParamId::Compliance(3), ParamId::A(3), ParamId::D(6)]);
    let report = analyze_jacobian(j.as_ref(), &params, &AnalysisOptions::default()).expect("analysis");
    assert_eq!(report.rank, 3);
    assert_eq!(report.identifiable, vec![ParamId::D(4), ParamId::Compliance(3), ParamId::D(6)]);
    let r = &report.redundant[0];
    assert_eq!(r.param, ParamId::A(3));
    let w = |p: ParamId| r.confounded_with.iter().find(|(q, _)| *q == p).map(|x| x.1).expect("partner");
    assert!((w(ParamId::D(4)) - 2.0).abs() < 1e-9);
    assert!((w(ParamId::Compliance(3)) + 1000.0).abs() < 1e-6);
    assert!(r.confounded_with.iter().all(|(p, _)| *p != ParamId::D(6)));
    assert_eq!(report.lost_directions.len(), 1);

    // Preference order decides which of the dependent columns is dropped.
    let reordered = ParamSet(vec![ParamId::A(3), ParamId::D(4), ParamId::Compliance(3), ParamId::D(6)]);
    let perm = [2, 0, 1, 3];
    let jr = Mat::from_fn(m, l, |row, c| j[(row, perm[c])]);
    let report2 = analyze_jacobian(jr.as_ref(), &reordered, &AnalysisOptions::default()).expect("analysis");
    assert_eq!(report2.rank, 3);
    assert_eq!(report2.identifiable[0], ParamId::A(3));
    assert_eq!(report2.redundant[0].param, ParamId::Compliance(3));
}

#[test]
fn rank_is_invariant_to_column_units() {
    let model = canonical_model();
    let poses = probe_poses(&model, &[1, 2, 3], 30, 5);
    let params = preference_order(&model);
    let j = assemble_jacobian(&model, &poses, &params).expect("jacobian");
    let base = analyze_jacobian(j.as_ref(), &params, &AnalysisOptions::default()).expect("analysis");
    let mut scaled = j.clone();
    for c in 0..scaled.ncols() {
        let f = 10f64.powi((c as i32 % 7) - 3);
        for x in scaled.col_mut(c).iter_mut() {
            *x *= f;
        }
    }
    let other = analyze_jacobian(scaled.as_ref(), &params, &AnalysisOptions::default()).expect("analysis");
    assert_eq!(base.rank, other.rank);
    assert_eq!(base.identifiable, other.identifiable);
}

#[test]
fn too_few_poses_are_refused_with_a_count() {
    let model = canonical_model();
    let poses = probe_poses(&model, &[1, 2, 3], 6, 3);
    let report = analyze(&model, &poses, &ParamSet::paper34()).expect("analysis");
    assert_eq!(report.rank, 18);
    assert_eq!(report.singular_values.len(), 34);
    assert_eq!(report.lost_directions.len(), 16);
    match rank_deficient_error(&report) {
        ObservabilityError::RankDeficient { message, .. } => {
            assert!(message.contains("at least 12 poses"), "{message}")
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(analyze(&model, &[], &ParamSet::paper34()), Err(ObservabilityError::NoMeasurements)));
}

#[test]
fn unknown_tcp_is_an_error_naming_the_measurement() {
    let model = canonical_model();
    let mut poses = probe_poses(&model, &[1, 2, 3], 3, 3);
    poses[2].tcp = 9;
    match analyze(&model, &poses, &ParamSet::paper34()) {
        Err(e @ ObservabilityError::Model { index: 2, .. }) => assert!(e.to_string().contains("TCP"), "{e}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn parameter_specs_resolve_or_fail_clearly() {
    use vatcal_observability::identifiability::param_set_from_spec;
    let model = canonical_model();
    let poses = probe_poses(&model, &[1, 2, 3], 40, 8);
    assert_eq!(param_set_from_spec("paper34", &model, &poses).expect("paper34"), ParamSet::paper34());
    assert_eq!(param_set_from_spec("all-identifiable", &model, &poses).expect("basis"), ParamSet::paper34());
    let e = param_set_from_spec("d_4,alpha_9", &model, &poses).expect_err("unknown name");
    assert!(e.to_string().contains("alpha_9"), "{e}");
    let e = param_set_from_spec("d_4,tool_tx", &model, &poses).expect_err("effect not switched on");
    assert!(e.to_string().contains("tool_tx"), "{e}");
}
