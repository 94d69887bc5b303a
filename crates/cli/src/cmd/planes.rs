//! Contact planes of plane rows (`plane,tcp,q…`) for the commands that fit models: the planes
//! the rows name and the cell file lacks are added to the model (first estimated through the
//! nominal model's contacts) and identified; the planes the cell file has are held fixed.

use std::path::Path;

use anyhow::Context;
use vatcal_core::{CellFile, Measurement, PlaneDistance, PointDistance};
use vatcal_kinematics::Model;

/// Adds the planes the rows name and `cell` lacks (estimated by
/// [`vatcal_identification::estimate_planes`] at `model`), prints one line about them, and
/// returns the model rebuilt from the cell with their ids (the free planes). `model` is
/// returned as it was when no plane is missing.
///
/// # Errors
/// A plane whose rows do not fix it (fewer than three contacts, or on a line), naming it.
pub fn model_with_unknown_planes(
    cell: &mut CellFile,
    model: Model,
    model_path: &Path,
    rows: &[Measurement],
) -> anyhow::Result<(Model, Vec<u32>)> {
    let added = vatcal_identification::estimate_planes(&model, rows).context("plane rows")?;
    if added.is_empty() {
        return Ok((model, Vec::new()));
    }
    let ids: Vec<u32> = added.iter().map(|p| p.id).collect();
    println!(
        "planes: {} not in the cell file ({}): identified with the rest (first estimated through the nominal contacts)",
        ids.len(),
        ids.iter().map(u32::to_string).collect::<Vec<_>>().join(", ")
    );
    cell.planes.extend(added);
    let model = super::model_of(cell, model_path)?;
    Ok((model, ids))
}

/// Parses the `--plane-distance A,B,MM[,SIGMA_MM]` values.
///
/// # Errors
/// A value [`PlaneDistance::parse`] refuses, naming the flag.
pub fn plane_distances(specs: &[String]) -> anyhow::Result<Vec<PlaneDistance>> {
    specs
        .iter()
        .map(|s| PlaneDistance::parse(s).map_err(anyhow::Error::msg).context("--plane-distance"))
        .collect()
}

/// Parses the `--point-distance A,B,MM[,SIGMA_MM]` values.
///
/// # Errors
/// A value [`PointDistance::parse`] refuses, naming the flag.
pub fn point_distances(specs: &[String]) -> anyhow::Result<Vec<PointDistance>> {
    specs
        .iter()
        .map(|s| PointDistance::parse(s).map_err(anyhow::Error::msg).context("--point-distance"))
        .collect()
}
