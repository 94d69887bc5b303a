//! What a campaign does: an ordered list of [`CampaignStep`]s.
//!
//! Plans come from the tour file of `vatcal plan` ([`CampaignPlan::read_tour`]), from a list of
//! measurement poses in tour order ([`CampaignPlan::from_poses`], e.g. the rows of a candidate
//! or selection CSV read with `vatcal_io::read_candidates`), or are written by hand.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use vatcal_core::{JointKind, JointVector, Measurement, Target};
use vatcal_kinematics::Model;

use crate::checksum::fnv1a64;

/// One step of a measurement campaign (internal units: mm for prismatic, rad for revolute
/// joints; the canonical cell: q1 mm, q2..q7 rad).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "step", rename_all = "snake_case")]
pub enum CampaignStep {
    /// The operator places the probe plate at calibration position `position` (the arm must
    /// be clear of the probe).
    PlaceProbe {
        /// calibration position id
        position: u32,
    },
    /// Zero the probe with the master ball: the operator seats it, the gauges are preset, the
    /// operator removes it (the arm must be clear of the probe).
    ZeroProbe {
        /// calibration position the plate is at
        position: u32,
    },
    /// Move through joint-space waypoints (each reached in turn: guide and arm together). The
    /// last waypoint of the move before a [`CampaignStep::Measure`] is the approach pose: the
    /// nominal TCP on the probe origin.
    Move {
        /// waypoints
        path: Vec<JointVector>,
    },
    /// Auto-centre ball `tcp` on the probe (plate at `position`) and record the joints.
    Measure {
        /// calibration position the plate is at
        position: u32,
        /// TCP (ball) id
        tcp: u32,
    },
    /// Measure the world position of target `tcp` with the tracker and record it with the
    /// joints.
    Track {
        /// TCP / SMR id
        tcp: u32,
    },
}

/// Why a plan is rejected before anything moves.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CampaignPlanError {
    /// The plan has no steps.
    #[error("the plan has no steps")]
    Empty,
    /// A waypoint has another number of joints than the model.
    #[error("step {step}: waypoint {waypoint}: {got} joint values for a model of {expected} joints")]
    JointCount {
        /// step index (0-based)
        step: usize,
        /// waypoint index (0-based)
        waypoint: usize,
        /// the model's joint count
        expected: usize,
        /// values in the waypoint
        got: usize,
    },
    /// A waypoint is outside the joint limits or not finite.
    #[error("step {step}: waypoint {waypoint}: joint q{joint} = {value} is outside its limits")]
    Limits {
        /// step index (0-based)
        step: usize,
        /// waypoint index (0-based)
        waypoint: usize,
        /// cell joint 1..=N
        joint: usize,
        /// value (mm for prismatic, rad for revolute joints)
        value: f64,
    },
    /// A move has no waypoints.
    #[error("step {step}: a move needs at least one waypoint")]
    EmptyMove {
        /// step index
        step: usize,
    },
    /// An id does not exist in the model.
    #[error("step {step}: unknown {what} id {id}")]
    UnknownId {
        /// step index
        step: usize,
        /// "tcp" or "position"
        what: &'static str,
        /// the id
        id: u32,
    },
    /// A measurement at a position where the plate is not.
    #[error(
        "step {step}: measures at position {position} but the plate is at {placed:?} (add a place_probe step)"
    )]
    PlateNotThere {
        /// step index
        step: usize,
        /// position of the measure step
        position: u32,
        /// where the plate is at that point of the plan
        placed: Option<u32>,
    },
}

/// A bad row of a tour file.
#[derive(Debug, thiserror::Error)]
pub enum TourFileError {
    /// The file cannot be read or is not CSV.
    #[error("{path}: {reason}")]
    File {
        /// tour file
        path: PathBuf,
        /// what is wrong
        reason: String,
    },
    /// A field is missing or invalid.
    #[error("{path}:{line}: column `{column}`: {reason}")]
    Row {
        /// tour file
        path: PathBuf,
        /// 1-based line
        line: u64,
        /// column name
        column: String,
        /// what is wrong
        reason: String,
    },
}

/// Options of [`CampaignPlan::from_poses`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CampaignPlanOptions {
    /// a pose where the arm is clear of the probe; visited before every plate re-placement
    pub clear_pose: Option<JointVector>,
    /// zero the probe with the master ball after every placement
    pub zero_probe: bool,
}

/// An ordered list of steps.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct CampaignPlan {
    /// the steps, executed in order
    pub steps: Vec<CampaignStep>,
}

impl CampaignPlan {
    /// A plan from measurement poses in tour order. Probe poses (`Target::Probe`): a plate
    /// placement whenever the position changes (preceded by a move to `clear_pose` if given,
    /// followed by zeroing if asked), then a straight joint move to the pose and a
    /// measurement. Tracker poses: a move and a tracker measurement. Plane-contact poses: the
    /// move only (no instrument of the cell reads a contact; the robot's guarded touch and its
    /// joint readings are the measurement).
    pub fn from_poses(poses: &[Measurement], options: &CampaignPlanOptions) -> Self {
        let mut steps = Vec::new();
        let mut placed = None;
        for m in poses {
            if let Target::Probe { position } = m.target
                && placed != Some(position)
            {
                if let Some(clear) = options.clear_pose {
                    steps.push(CampaignStep::Move { path: vec![clear] });
                }
                steps.push(CampaignStep::PlaceProbe { position });
                if options.zero_probe {
                    steps.push(CampaignStep::ZeroProbe { position });
                }
                placed = Some(position);
            }
            steps.push(CampaignStep::Move { path: vec![m.q] });
            match m.target {
                Target::Probe { position } => steps.push(CampaignStep::Measure { position, tcp: m.tcp }),
                Target::Tracker { .. } | Target::Orientation { .. } => {
                    steps.push(CampaignStep::Track { tcp: m.tcp })
                }
                // no instrument reads a contact: the robot's own guarded touch records it
                Target::Plane { .. } => {}
            }
        }
        Self { steps }
    }

    /// Reads the tour file written by `vatcal plan` for the canonical Meca500-on-guide cell
    /// (`step,kind,position,tcp,q1..q7[,time_s]`, q1 in mm, q2..q7 in degrees, columns by
    /// name); [`CampaignPlan::read_tour_for`] reads any chain's. Consecutive `move` rows become
    /// one [`CampaignStep::Move`] through their waypoints; a `measure` row adds its joints as
    /// the last waypoint (the straight move from the approach pose down to the measurement
    /// pose) and then a [`CampaignStep::Measure`]; a `track` row likewise ends the move with
    /// its joints and adds a [`CampaignStep::Track`] (a `track` row right after another
    /// measurement at the same joints adds no move: another SMR at the same pose); a
    /// `replace_probe` row becomes a [`CampaignStep::PlaceProbe`], a `zero_probe` row a
    /// [`CampaignStep::ZeroProbe`]. [`CampaignPlan::tour_csv_for`] writes any plan in this
    /// format. Validate the result with [`CampaignPlan::validate`].
    ///
    /// # Errors
    /// [`TourFileError`] naming the file (and the line and column of a bad field).
    pub fn read_tour(path: impl AsRef<Path>) -> Result<Self, TourFileError> {
        Self::read_tour_for(path, &vatcal_io::MECA500_ON_GUIDE_KINDS)
    }

    /// [`CampaignPlan::read_tour`] for a chain with joints `kinds` (`model.joint_kinds()`):
    /// the columns `q1..qN`, mm for prismatic and degrees for revolute joints. A file with
    /// another number of q-columns (a `q{N+1}` column, or one of `q1..qN` missing) is an error
    /// naming the expected columns.
    ///
    /// # Errors
    /// [`TourFileError`] naming the file (and the line and column of a bad field).
    pub fn read_tour_for(path: impl AsRef<Path>, kinds: &[JointKind]) -> Result<Self, TourFileError> {
        let path = path.as_ref();
        let n = kinds.len();
        let file_err = |reason: String| TourFileError::File { path: path.into(), reason };
        let mut rdr = csv::ReaderBuilder::new()
            .comment(Some(b'#'))
            .trim(csv::Trim::All)
            .from_path(path)
            .map_err(|e| file_err(e.to_string()))?;
        let headers = rdr.headers().map_err(|e| file_err(e.to_string()))?.clone();
        let column = |name: &str| headers.iter().position(|h| h == name);
        let mut required: Vec<String> = ["kind", "position", "tcp"].map(String::from).to_vec();
        required.extend((1..=n).map(|j| format!("q{j}")));
        let expected = format!("q1..q{n} for the model's {n} joints");
        let mut index = vec![0usize; required.len()];
        for (k, name) in required.iter().enumerate() {
            index[k] = column(name).ok_or_else(|| {
                file_err(format!("missing column `{name}` (the joint columns are {expected})"))
            })?;
        }
        if column(&format!("q{}", n + 1)).is_some() {
            return Err(file_err(format!(
                "has a column `q{}`: the joint columns are {expected} (a tour of another robot?)",
                n + 1
            )));
        }
        let mut steps = Vec::new();
        let mut pending: Vec<JointVector> = Vec::new();
        // the last waypoint read: a `track` row at these joints with no move before it is
        // one more tracker measurement at the same pose (several SMRs per pose)
        let mut last_q: Option<JointVector> = None;
        for rec in rdr.records() {
            let rec = rec.map_err(|e| file_err(e.to_string()))?;
            let line = rec.position().map_or(0, |p| p.line());
            let row_err = |k: usize, reason: String| TourFileError::Row {
                path: path.into(),
                line,
                column: required[k].clone(),
                reason,
            };
            let field = |k: usize| rec.get(index[k]).unwrap_or("");
            let id = |k: usize| {
                field(k).parse::<u32>().map_err(|_| row_err(k, format!("`{}` is not an id", field(k))))
            };
            let mut values = vec![0.0; n];
            for (j, v) in values.iter_mut().enumerate() {
                let text = field(3 + j);
                *v = text
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| row_err(3 + j, format!("`{text}` is not a finite number")))?;
            }
            let q = JointVector::from_file_units(&values, kinds)
                .map_err(|e| file_err(format!("line {line}: {e}")))?;
            match field(0) {
                "move" => {
                    pending.push(q);
                    last_q = Some(q);
                }
                "measure" => {
                    pending.push(q);
                    last_q = Some(q);
                    steps.push(CampaignStep::Move { path: std::mem::take(&mut pending) });
                    steps.push(CampaignStep::Measure { position: id(1)?, tcp: id(2)? });
                }
                "track" => {
                    let tcp = id(2)?;
                    if !(pending.is_empty() && last_q == Some(q)) {
                        pending.push(q);
                        last_q = Some(q);
                        steps.push(CampaignStep::Move { path: std::mem::take(&mut pending) });
                    }
                    steps.push(CampaignStep::Track { tcp });
                }
                kind @ ("replace_probe" | "zero_probe") => {
                    if !pending.is_empty() {
                        steps.push(CampaignStep::Move { path: std::mem::take(&mut pending) });
                    }
                    let position = id(1)?;
                    steps.push(if kind == "zero_probe" {
                        CampaignStep::ZeroProbe { position }
                    } else {
                        CampaignStep::PlaceProbe { position }
                    });
                }
                other => {
                    return Err(row_err(
                        0,
                        format!("unknown kind `{other}` (move, measure, track, replace_probe or zero_probe)"),
                    ));
                }
            }
        }
        if !pending.is_empty() {
            steps.push(CampaignStep::Move { path: pending });
        }
        Ok(Self { steps })
    }

    /// The plan as tour CSV text of a chain with joints `kinds`
    /// (`step,kind,position,tcp,q1..qN`, mm for prismatic and degrees for revolute joints,
    /// shortest round-trip decimals), which [`CampaignPlan::read_tour_for`] reads back into
    /// the same steps (up to the degree conversion's last bit; consecutive moves become one
    /// move through their waypoints). A move's last waypoint is written on the row of the
    /// measurement that follows it (`measure`, `track`); further `track` rows at the same pose
    /// repeat its joints; `replace_probe` and `zero_probe` rows carry the current joints (the
    /// first waypoint of the plan before any move), which the reader ignores.
    pub fn tour_csv_for(&self, kinds: &[JointKind]) -> String {
        use std::fmt::Write as _;
        let mut text = String::from("step,kind,position,tcp");
        for j in 1..=kinds.len() {
            let _ = write!(text, ",q{j}");
        }
        text.push('\n');
        let first = self.steps.iter().find_map(|s| match s {
            CampaignStep::Move { path } => path.first().copied(),
            _ => None,
        });
        let mut current = first;
        let mut held: Option<JointVector> = None;
        let mut row = 0usize;
        let mut push =
            |text: &mut String, kind: &str, position: String, tcp: String, q: Option<JointVector>| {
                let _ = write!(text, "{row},{kind},{position},{tcp}");
                let values = q.map_or_else(|| vec![0.0; kinds.len()], |q| q.to_file_units(kinds));
                for v in values {
                    let _ = write!(text, ",{v}");
                }
                text.push('\n');
                row += 1;
            };
        let mut placed: Option<u32> = None;
        let at = |p: Option<u32>| p.map_or(String::new(), |p| p.to_string());
        for step in &self.steps {
            let measuring = matches!(step, CampaignStep::Measure { .. } | CampaignStep::Track { .. });
            if !measuring && let Some(q) = held.take() {
                push(&mut text, "move", at(placed), String::new(), Some(q));
            }
            match step {
                CampaignStep::Move { path } => {
                    let Some((last, before)) = path.split_last() else { continue };
                    for q in before {
                        push(&mut text, "move", at(placed), String::new(), Some(*q));
                    }
                    held = Some(*last);
                    current = Some(*last);
                }
                CampaignStep::Measure { position, tcp } => {
                    let q = held.take().or(current);
                    push(&mut text, "measure", position.to_string(), tcp.to_string(), q);
                }
                CampaignStep::Track { tcp } => {
                    let q = held.take().or(current);
                    push(&mut text, "track", String::new(), tcp.to_string(), q);
                }
                CampaignStep::PlaceProbe { position } => {
                    placed = Some(*position);
                    push(&mut text, "replace_probe", position.to_string(), String::new(), current);
                }
                CampaignStep::ZeroProbe { position } => {
                    push(&mut text, "zero_probe", position.to_string(), String::new(), current);
                }
            }
        }
        if let Some(q) = held {
            push(&mut text, "move", at(placed), String::new(), Some(q));
        }
        text
    }

    /// Writes [`CampaignPlan::tour_csv_for`] to `path`.
    ///
    /// # Errors
    /// [`TourFileError::File`] when the file cannot be written.
    pub fn write_tour_for(&self, path: impl AsRef<Path>, kinds: &[JointKind]) -> Result<(), TourFileError> {
        let path = path.as_ref();
        std::fs::write(path, self.tour_csv_for(kinds))
            .map_err(|e| TourFileError::File { path: path.into(), reason: e.to_string() })
    }

    /// Number of steps that record a measurement.
    pub fn measurement_count(&self) -> usize {
        self.steps
            .iter()
            .filter(|s| matches!(s, CampaignStep::Measure { .. } | CampaignStep::Track { .. }))
            .count()
    }

    /// A fingerprint of the plan (FNV-1a 64 of its JSON form): a journal only resumes the plan
    /// it was started with.
    pub fn fingerprint(&self) -> u64 {
        fnv1a64(serde_json::to_string(self).unwrap_or_default().as_bytes())
    }

    /// Checks the plan against the model: waypoints inside the joint limits, known ids, every
    /// measurement at the position where the plate is.
    pub fn validate(&self, model: &Model) -> Result<(), CampaignPlanError> {
        self.validate_from(model, None)
    }

    /// [`CampaignPlan::validate`] with the plate already at `plate_at_start` when the plan
    /// starts (left there by the campaign before).
    pub fn validate_from(&self, model: &Model, plate_at_start: Option<u32>) -> Result<(), CampaignPlanError> {
        if self.steps.is_empty() {
            return Err(CampaignPlanError::Empty);
        }
        let (tcps, positions) = (model.tcp_ids(), model.position_ids());
        let known = |step: usize, what: &'static str, id: u32, ids: &[u32]| {
            if ids.contains(&id) { Ok(()) } else { Err(CampaignPlanError::UnknownId { step, what, id }) }
        };
        let mut placed = plate_at_start;
        for (step, s) in self.steps.iter().enumerate() {
            match s {
                CampaignStep::PlaceProbe { position } => {
                    known(step, "position", *position, &positions)?;
                    placed = Some(*position);
                }
                CampaignStep::ZeroProbe { position } | CampaignStep::Measure { position, .. }
                    if placed != Some(*position) =>
                {
                    return Err(CampaignPlanError::PlateNotThere { step, position: *position, placed });
                }
                CampaignStep::ZeroProbe { .. } => {}
                CampaignStep::Measure { tcp, .. } | CampaignStep::Track { tcp } => {
                    known(step, "tcp", *tcp, &tcps)?
                }
                CampaignStep::Move { path } => {
                    if path.is_empty() {
                        return Err(CampaignPlanError::EmptyMove { step });
                    }
                    for (waypoint, q) in path.iter().enumerate() {
                        if q.len() != model.joint_count() {
                            return Err(CampaignPlanError::JointCount {
                                step,
                                waypoint,
                                expected: model.joint_count(),
                                got: q.len(),
                            });
                        }
                        let bad =
                            model.limit_violation(q).map(|(joint, value, ..)| (joint, value)).or_else(|| {
                                q.as_slice().iter().position(|v| !v.is_finite()).map(|k| (k + 1, q[k]))
                            });
                        if let Some((joint, value)) = bad {
                            return Err(CampaignPlanError::Limits { step, waypoint, joint, value });
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tour_rows_become_steps() {
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("tour.csv");
        std::fs::write(
            &path,
            "step,kind,position,tcp,q1,q2,q3,q4,q5,q6,q7,time_s\n\
             0,replace_probe,1,2,100,0,0,0,0,0,0,60.000\n\
             1,move,1,2,110,10,0,0,0,30,0,61.0\n\
             2,move,1,2,120,20,0,0,0,30,0,62.0\n\
             3,measure,1,2,120,20,5,0,0,30,0,82.0\n\
             4,replace_probe,2,1,120,20,5,0,0,30,0,142.0\n\
             5,measure,2,1,120,20,5,0,0,35,0,162.0\n",
        )
        .expect("write");
        let plan = CampaignPlan::read_tour(&path).expect("tour");
        let q = |g: f64, a: [f64; 6]| JointVector::from_mm_deg(g, a);
        assert_eq!(
            plan.steps,
            vec![
                CampaignStep::PlaceProbe { position: 1 },
                CampaignStep::Move {
                    path: vec![
                        q(110.0, [10.0, 0.0, 0.0, 0.0, 30.0, 0.0]),
                        q(120.0, [20.0, 0.0, 0.0, 0.0, 30.0, 0.0]),
                        q(120.0, [20.0, 5.0, 0.0, 0.0, 30.0, 0.0]),
                    ]
                },
                CampaignStep::Measure { position: 1, tcp: 2 },
                CampaignStep::PlaceProbe { position: 2 },
                CampaignStep::Move { path: vec![q(120.0, [20.0, 5.0, 0.0, 0.0, 35.0, 0.0])] },
                CampaignStep::Measure { position: 2, tcp: 1 },
            ]
        );
        assert_eq!(plan.measurement_count(), 2);
    }

    #[test]
    fn written_tours_read_back_into_the_same_steps() {
        let q = |g: f64, a: [f64; 6]| JointVector::from_mm_deg(g, a);
        let (a, b, c) = (
            q(110.0, [10.0, 0.0, 0.0, 0.0, 30.0, 0.0]),
            q(120.5, [20.25, -3.0, 1.0, 0.0, 30.0, 7.0]),
            q(130.0, [21.0, -2.0, 1.5, 0.5, 31.0, 7.5]),
        );
        let plan = CampaignPlan {
            steps: vec![
                CampaignStep::PlaceProbe { position: 1 },
                CampaignStep::ZeroProbe { position: 1 },
                CampaignStep::Move { path: vec![a, b] },
                CampaignStep::Measure { position: 1, tcp: 2 },
                CampaignStep::Move { path: vec![c] },
                CampaignStep::Track { tcp: 1 },
                CampaignStep::Track { tcp: 2 },
                CampaignStep::Track { tcp: 3 },
                CampaignStep::Move { path: vec![a] },
                CampaignStep::Track { tcp: 1 },
                CampaignStep::Move { path: vec![b] },
            ],
        };
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("tour.csv");
        plan.write_tour_for(&path, &vatcal_io::MECA500_ON_GUIDE_KINDS).expect("write");
        let back = CampaignPlan::read_tour(&path).expect("read");
        assert_eq!(back.steps.len(), plan.steps.len(), "{:#?}", back.steps);
        for (got, want) in back.steps.iter().zip(&plan.steps) {
            match (got, want) {
                (CampaignStep::Move { path: g }, CampaignStep::Move { path: w }) => {
                    assert_eq!(g.len(), w.len());
                    for (x, y) in g.iter().zip(w) {
                        let d: f64 = x.as_slice().iter().zip(y.as_slice()).map(|(u, v)| (u - v).abs()).sum();
                        assert!(d < 1e-12, "{x:?} vs {y:?}");
                    }
                }
                _ => assert_eq!(got, want),
            }
        }
        assert_eq!(back.measurement_count(), 5);
    }

    #[test]
    fn a_plan_may_start_where_the_plate_already_is() {
        let cell = vatcal_core::CellFile::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../fixtures/meca500-zaber.toml"
        ))
        .expect("cell");
        let model = Model::from_cell(&cell).expect("model");
        let q = JointVector::from_mm_deg(100.0, [10.0, 20.0, -20.0, 5.0, 30.0, 0.0]);
        let plan = CampaignPlan {
            steps: vec![CampaignStep::Move { path: vec![q] }, CampaignStep::Measure { position: 1, tcp: 2 }],
        };
        assert!(matches!(plan.validate(&model), Err(CampaignPlanError::PlateNotThere { step: 1, .. })));
        plan.validate_from(&model, Some(1)).expect("the plate is at position 1 already");
        assert!(matches!(
            plan.validate_from(&model, Some(2)),
            Err(CampaignPlanError::PlateNotThere { placed: Some(2), .. })
        ));
    }

    #[test]
    fn bad_tour_rows_name_line_and_column() {
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("tour.csv");
        std::fs::write(&path, "kind,position,tcp,q1,q2,q3,q4,q5,q6,q7\nmove,1,1,0,0,0,abc,0,0,0\n")
            .expect("write");
        let e = CampaignPlan::read_tour(&path).expect_err("bad").to_string();
        assert!(e.contains(":2: column `q4`") && e.contains("abc"), "{e}");
        std::fs::write(&path, "kind,position,tcp,q1,q2,q3,q4,q5,q6,q7\njump,1,1,0,0,0,0,0,0,0\n")
            .expect("write");
        let e = CampaignPlan::read_tour(&path).expect_err("bad").to_string();
        assert!(e.contains("unknown kind `jump`"), "{e}");
        std::fs::write(&path, "kind,position,q1\n").expect("write");
        let e = CampaignPlan::read_tour(&path).expect_err("bad").to_string();
        assert!(e.contains("missing column `tcp`"), "{e}");
    }
}
