//! The three kinds of plan folder and their campaigns, shared by `vatcal calibrate`'s stages
//! and the by-hand commands (`vatcal plan --kind …`, `vatcal campaign --plan DIR`):
//!
//! | kind | planned by | `tour.csv` | campaign journal | measurements |
//! |---|---|---|---|---|
//! | `calibration` | [`crate::plan_stage()`] (`vatcal plan`) | probe poses | `campaign.journal` | `measurements.csv` |
//! | `discovery` | [`crate::discovery_stage::plan_discovery`] | probe poses; the two-sided repeats are added when it is run ([`discovery_tour_of`]) | `discovery.journal` | `discovery_measurements.csv` |
//! | `validation` | [`validation_plan`] + [`write_validation_plan`] | tracker poses (`track` rows): random poses, then the printing path commanded by each model | `validation.journal` | `validation_measurements.csv` (tracker rows, tank frame) |
//!
//! The folder says its kind in `summary.json` (`"kind"`; a summary without it, or no summary,
//! is a calibration plan, as `vatcal plan` has always written them), with what its campaign
//! needs besides the tour (a discovery plan's repeats).
//!
//! This module only gathers them: each lives with its stage (`plan_stage`, `discovery_stage`,
//! `validation_stage`) and the folder types and file names with [`crate::folders`].

pub use crate::discovery_stage::{discovery_campaign_stage, discovery_tour_of};
pub use crate::folders::{PlanHeader, PlanKind, VALIDATION_MEASUREMENTS_CSV};
pub use crate::validation_stage::{
    ValidationPlanSummary, tracker_campaign_stage, validation_plan, write_validation_plan,
};
