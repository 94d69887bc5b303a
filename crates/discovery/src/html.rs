//! The discovery report as one self-contained HTML page (`vatcal discover --report` writes it
//! beside the JSON): the gap before and after, the effects added (with their plots inline),
//! the effects detected but negligible, those removed by the backward check, every round's
//! decision and the notes.

use vatcal_report::PlotError;
use vatcal_report::html::HtmlReport;

use crate::plots::effect_plot_svg;
use crate::workflow::{Discovery, Gap};

fn mm(v: f64) -> String {
    format!("{v:.4}")
}

fn gap_row(name: &str, g: &Gap) -> Vec<String> {
    vec![
        name.to_string(),
        mm(g.heldout.mean),
        mm(g.heldout.rms),
        g.validation.as_ref().map_or("-".into(), |v| mm(v.mean)),
        g.validation.as_ref().map_or("-".into(), |v| mm(v.rms)),
    ]
}

/// Builds the HTML report of a discovery run.
pub fn html_report(d: &Discovery) -> Result<HtmlReport, PlotError> {
    let mut r = HtmlReport::new("vatcal discover: missing-effect discovery");
    summary(&mut r, d);
    added_section(&mut r, d)?;
    negligible_and_removed(&mut r, d);
    rounds_and_notes(&mut r, d);
    Ok(r)
}

/// The headline, the gap table and the predicted uncertainty.
fn summary(r: &mut HtmlReport, d: &Discovery) {
    let names: Vec<String> = d.added_effects.iter().map(|a| format!("**{}**", a.label)).collect();
    r.paragraph(format!(
        "{} effect(s) added{}. Gap ({}): **{:.4} mm** before, **{:.4} mm** after. Screening used {} \
         measurements, confirmation {} others that the screening never saw; an effect is added only \
         when it lowers the held-out prediction error by more than its own uncertainty and changes \
         the predictions by more than the noise.",
        names.len(),
        if names.is_empty() { String::new() } else { format!(": {}", names.join(", ")) },
        d.final_gap.headline_name(),
        d.initial_gap_mm,
        d.final_gap_mm,
        d.split[0],
        d.split[1],
    ));
    r.heading("Gap");
    r.table(
        &["model", "held-out mean [mm]", "held-out RMS [mm]", "validation mean [mm]", "validation RMS [mm]"],
        &[gap_row("start", &d.initial_gap), gap_row("final", &d.final_gap)],
    );
    if let Some(u) = &d.uncertainty {
        r.paragraph(format!(
            "Predicted TCP uncertainty of the final model at the {} {} poses: mean |sigma| {:.4} mm from the \
             parameter covariance, {:.4} mm with systematic CMM errors of {:.4} mm per TCP / position coordinate.",
            u.count, u.poses, u.statistical_mean_mm, u.with_cmm_mean_mm, u.cmm_sigma_mm
        ));
    }
}

/// The effects added: a table and each one's plot.
fn added_section(r: &mut HtmlReport, d: &Discovery) -> Result<(), PlotError> {
    r.heading("Effects added");
    if d.added_effects.is_empty() {
        r.paragraph("None: no candidate shrank the held-out gap by more than its uncertainty.");
        return Ok(());
    }
    let rows: Vec<Vec<String>> = d
        .added_effects
        .iter()
        .map(|a| {
            let values: Vec<String> = a.values.iter().map(|(k, v)| format!("`{k}` = {v:.4e}")).collect();
            vec![
                a.round.to_string(),
                a.label.clone(),
                a.meaning.clone(),
                values.join(", "),
                format!("{} -> {}", mm(a.heldout.rms_before_mm), mm(a.heldout.rms_after_mm)),
                format!("{:.1}", a.heldout.z),
                format!("{} -> {}", mm(a.gap_before_mm), mm(a.gap_after_mm)),
            ]
        })
        .collect();
    r.table(
        &[
            "round",
            "effect",
            "meaning",
            "identified values",
            "confirmation held-out RMS [mm]",
            "z",
            "gap [mm]",
        ],
        &rows,
    );
    for (k, a) in d.added_effects.iter().enumerate() {
        let svg = effect_plot_svg(k + 1, a)?;
        r.svg(svg, format!("{}: residual against {}, before and after adding it", a.label, a.plot.x_label));
    }
    Ok(())
}

/// The effects detected but negligible, and those removed by the backward check.
fn negligible_and_removed(r: &mut HtmlReport, d: &Discovery) {
    if !d.negligible_effects.is_empty() {
        r.heading("Detected, negligible (not added)");
        let rows: Vec<Vec<String>> = d
            .negligible_effects
            .iter()
            .map(|n| {
                vec![
                    n.round.to_string(),
                    n.label.clone(),
                    format!("{:.1}", n.change_um),
                    format!("{:.1}", n.heldout.z),
                ]
            })
            .collect();
        r.table(&["round", "effect", "prediction change [um]", "z"], &rows);
    }
    if !d.removed_effects.is_empty() {
        r.heading("Removed by the backward check");
        let rows: Vec<Vec<String>> = d
            .removed_effects
            .iter()
            .map(|x| {
                vec![
                    x.label.clone(),
                    x.added_in_round.to_string(),
                    x.removed_in_round.to_string(),
                    format!("{:.2}", x.heldout.z),
                ]
            })
            .collect();
        r.table(&["effect", "added in round", "removed in round", "z of keeping it"], &rows);
    }
}

/// Every round's decision, and the notes.
fn rounds_and_notes(r: &mut HtmlReport, d: &Discovery) {
    r.heading("Rounds");
    let rows: Vec<Vec<String>> = d
        .rounds
        .iter()
        .map(|x| {
            vec![
                x.index.to_string(),
                x.fit.params.len().to_string(),
                mm(x.fit.fit_errors.rms),
                x.location.first().map_or(String::new(), |l| l.sentence()),
                x.decision.clone(),
            ]
        })
        .collect();
    r.table(&["round", "parameters", "RMS residual [mm]", "residual depends most on", "decision"], &rows);
    if !d.notes.is_empty() {
        r.heading("Notes");
        r.paragraph(d.notes.join("\n\n"));
    }
}
