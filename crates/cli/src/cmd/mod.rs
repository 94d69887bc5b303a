//! One module per subcommand.

pub mod calibrate;
pub mod campaign;
pub mod compensate;
pub mod demo;
pub mod discover;
pub mod evaluate_fixed_points;
pub mod fk;
pub mod identify;
pub mod import_urdf;
pub mod markers;
pub mod observability;
pub mod plan;
pub mod planes;
pub mod read_args;
pub mod select;
pub mod shared;
pub mod sim_cell;
pub mod size_args;
pub mod torque;
pub mod validate;

use std::path::Path;

use anyhow::Context;
use vatcal_core::CellFile;
use vatcal_kinematics::Model;

/// Loads and validates a cell file and builds the model.
pub fn load_model(path: &Path) -> anyhow::Result<Model> {
    model_of(&CellFile::load(path)?, path)
}

/// The model of `cell`, read from `path`; an error names the file.
pub fn model_of(cell: &CellFile, path: &Path) -> anyhow::Result<Model> {
    Model::from_cell(cell).with_context(|| format!("{}: cannot build the model", path.display()))
}
