//! Which hidden truth a virtual cell gets (`--truth ideal|paper-like|FILE`) and building it.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use vatcal_core::CellFile;
use vatcal_kinematics::Model;

use crate::cell::VirtualCell;
use crate::config::{CellPhysics, SimConfig};

use super::{ErrorBudget, PaperLikePhysics, paper_like_truth, perturbed_truth, scaled_compliance};

/// Which hidden truth a virtual cell gets (`--truth ideal|paper-like|FILE`).
#[derive(Debug, Clone, PartialEq)]
pub enum TruthSpec {
    /// [`perturbed_truth`] with [`ErrorBudget::realistic`]: only errors of the paper's 34
    /// parameters; ideal tracker, no temperature channel (the behaviour before the paper-like
    /// truth existed)
    Ideal,
    /// [`paper_like_truth`] with [`PaperLikePhysics::paper`], plus the temperature channel and
    /// the tracker's registration and SMR-nest errors
    PaperLike,
    /// a cell file of the truth (a cell TOML with effects enabled), with the paper-like
    /// temperature channel (its thermal drift, if any, sees it) and tracker errors
    File(PathBuf),
}

impl FromStr for TruthSpec {
    type Err = TruthError;

    /// `ideal`, `paper-like`, or a path to a cell file (must not be empty).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "ideal" => Ok(Self::Ideal),
            "paper-like" | "paper_like" => Ok(Self::PaperLike),
            "" => Err(TruthError::Spec("expected `ideal`, `paper-like` or a cell file, got nothing".into())),
            path => Ok(Self::File(PathBuf::from(path))),
        }
    }
}

impl fmt::Display for TruthSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Ideal => f.write_str("ideal"),
            Self::PaperLike => f.write_str("paper-like"),
            Self::File(p) => write!(f, "{}", p.display()),
        }
    }
}

/// Why a truth could not be built.
#[derive(Debug, thiserror::Error)]
pub enum TruthError {
    /// The `--truth` value is malformed.
    #[error("--truth: {0}")]
    Spec(String),
    /// The truth's cell file could not be read or is invalid.
    #[error("truth file {path}: {message}")]
    File {
        /// the file
        path: PathBuf,
        /// what went wrong
        message: String,
    },
}

/// A built truth: the hidden model and the physics of the devices around it.
#[derive(Debug, Clone)]
pub struct BuiltTruth {
    /// the hidden true model (oracle)
    pub model: Model,
    /// temperature channel and tracker systematics for [`SimConfig::physics`]
    pub physics: CellPhysics,
    /// one line saying what the truth contains (for reports)
    pub description: String,
}

impl TruthSpec {
    /// Builds the hidden truth for `nominal` and `seed` (deterministic).
    ///
    /// # Errors
    /// A truth file that cannot be read or is not a valid cell model.
    pub fn build(&self, nominal: &Model, seed: u64) -> Result<BuiltTruth, TruthError> {
        let paper = PaperLikePhysics::paper();
        let paper_physics = CellPhysics { thermal: Some(paper.temperature), ..paper.tracker };
        Ok(match self {
            Self::Ideal => BuiltTruth {
                // any other chain: compliances scaled to its gravity torques (compliance_scale)
                model: if nominal.is_meca500_on_guide() {
                    perturbed_truth(nominal, seed, &ErrorBudget::realistic())
                } else {
                    perturbed_truth(nominal, seed, &scaled_compliance(nominal, &ErrorBudget::realistic()))
                },
                physics: CellPhysics::none(),
                description: "ideal: random errors of the paper's 34 parameters only (no effect \
                              outside the model, ideal tracker)"
                    .into(),
            },
            Self::PaperLike => BuiltTruth {
                model: paper_like_truth(nominal, seed, &paper),
                physics: paper_physics,
                description: "paper-like: random errors of the 34 parameters plus gear harmonics, \
                              backlash, guide pitch/yaw/roll and straightness, carriage tilt, wrong \
                              masses, CMM errors, tool-changer offset, thermal growth and tracker \
                              registration/SMR errors (docs/virtual-cell.md)"
                    .into(),
            },
            Self::File(path) => {
                let err = |message: String| TruthError::File { path: path.clone(), message };
                let cell = CellFile::load(path).map_err(|e| err(e.to_string()))?;
                let model = Model::from_cell(&cell).map_err(|e| err(e.to_string()))?;
                if model.tcp_ids() != nominal.tcp_ids() || model.position_ids() != nominal.position_ids() {
                    return Err(err(format!(
                        "its TCPs {:?} / calibration positions {:?} differ from the nominal cell's {:?} / {:?}",
                        model.tcp_ids(),
                        model.position_ids(),
                        nominal.tcp_ids(),
                        nominal.position_ids()
                    )));
                }
                BuiltTruth {
                    model,
                    physics: paper_physics,
                    description: format!(
                        "file {}: the cell file's model, paper-like temperature channel and tracker errors",
                        path.display()
                    ),
                }
            }
        })
    }

    /// A virtual cell on this truth: [`TruthSpec::build`], the default [`SimConfig`] with the
    /// nominal cell's motion limits and the truth's [`CellPhysics`]. `ideal` gives exactly
    /// [`VirtualCell::paper`].
    ///
    /// # Errors
    /// As [`TruthSpec::build`].
    pub fn virtual_cell(&self, nominal: Model, seed: u64) -> Result<VirtualCell, TruthError> {
        let built = self.build(&nominal, seed)?;
        let config = SimConfig {
            timing: SimConfig::paper_for(&nominal).timing,
            physics: built.physics,
            ..SimConfig::default()
        };
        Ok(VirtualCell::new(nominal, built.model, config, seed))
    }
}
