//! The demo on the default, paper-like truth at the paper's sizes, on the CLI's default seed 1:
//! the nominal model is off by about the paper's 1.27 mm and the 34-parameter calibration
//! leaves the paper's few tenths of a millimetre — the physics it does not model — within ±25 %
//! of the paper's 0.271 mm (random poses) and 0.220 mm (printing path). docs/virtual-cell.md
//! has the eight-seed table (`examples/paper_like_table.rs`): the random-pose goal holds on most
//! seeds, the printing path scatters more. The run is the one shared with `compensation.rs` and
//! `discovery.rs` (`common::default_demo`; discovery comes after the validation of the 34
//! parameters and does not change it).

use vatcal_demo::TruthSpec;

use crate::common;

#[test]
fn the_34_parameters_leave_the_papers_error_on_the_paper_like_cell() {
    let demo = common::default_demo();
    assert_eq!(demo.opts.truth, TruthSpec::PaperLike, "paper-like is the default truth");
    let out = &demo.out;
    let nominal = out.validation("nominal").expect("nominal");
    let calibrated = out.validation("calibrated").expect("calibrated");
    let (nr, cr) = (nominal.random.stats.mean, calibrated.random.stats.mean);
    let cp = calibrated.path.as_ref().expect("path").tip_stats.mean;
    eprintln!("paper-like seed {}: random {nr:.3} -> {cr:.3} mm, path calibrated {cp:.3} mm", common::SEED);
    // issue 11's goal: within ±25 % of the paper's 1.272, 0.271 and 0.220 mm
    assert!((0.954..1.59).contains(&nr), "nominal random-pose mean {nr} mm");
    assert!((0.203..0.339).contains(&cr), "calibrated random-pose mean {cr} mm");
    assert!((0.165..0.275).contains(&cp), "calibrated path mean {cp} mm");
    assert!(out.report.campaign.measurements >= 30, "auto-centering must still work");
    let summary = &demo.summary_md;
    assert!(summary.contains("paper_like_truth") && summary.contains("do not model"), "{summary}");
    assert!(summary.contains("of exactly ±"), "the summary must say the errors have fixed sizes");
}
