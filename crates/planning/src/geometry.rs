//! The collision geometry of the cell: fixed obstacles from the cell file's `[obstacles]`
//! tables, plus the robot's links and the calibration end-effector.
//!
//! The fixed obstacles (`tank`, `trical`, `guide`, `floor`) are the core tables of the cell
//! format. The robot and end-effector shapes are two optional tables of this crate, read from
//! `[obstacles.robot_links]` and `[obstacles.end_effector]` (kept verbatim by `vatcal-core` as
//! extra obstacle tables); every field is optional and defaults to the values below, which are
//! estimates from the Meca500 R3 outline drawing (a 4.5 kg arm with ~55–70 mm wide links) and the
//! paper's calibration end-effector.
//!
//! | body | attached to | shape | default |
//! |---|---|---|---|
//! | base | frame B (carriage) | cylinder on `z_B` from the mounting face | radius 45, height 100 mm |
//! | shoulder | frame 2 (J1) | capsule on the J2 axis, centred on it | radius 35, half-length 40 mm |
//! | upper arm | frame 3 (J2) | capsule J2 axis → J3 axis | radius 28 mm |
//! | elbow | frame 4 (J3) | capsule J3 axis → elbow corner (`a_4` along `x_4`) | radius 28 mm |
//! | forearm | frame 5 (J4) | capsule elbow corner → wrist centre | radius 24 mm |
//! | wrist | frame 6 (J5) | capsule on the J5 axis, centred on the wrist centre | radius 22, half-length 25 mm |
//! | flange | frame 7 (J6) | capsule wrist centre → flange face | radius 20 mm |
//! | tool changer | tool frame | cylinder on `z_7` from the flange face | radius 25, length 25 mm |
//! | plate | tool frame | box, centre `(0, 18, 70)`, half extents `(45, 6, 45)` | see `plate_*` |
//! | balls | tool frame | spheres at the TCPs | radius 12.7 mm (1 inch balls) |
//!
//! The plate default is a slab in the plane of the three balls (`y_7 ≈ 30 mm`), between the
//! tool changer and the balls, leaving the lower half of each ball free for the probe.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use vatcal_core::CellFile;
use vatcal_core::cell::{BoxObstacle, CylinderObstacle, PlaneObstacle};

use crate::error::PlanError;

/// Link shapes of the Meca500 (`[obstacles.robot_links]`), lengths in mm; on any other chain
/// `chain_link_radius_mm` and `link_radii_mm`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotLinkGeometry {
    /// base cylinder radius
    pub base_radius_mm: f64,
    /// base cylinder height above the mounting face (along the J1 axis)
    pub base_height_mm: f64,
    /// shoulder capsule radius (J1 body, around the J2 axis)
    pub shoulder_radius_mm: f64,
    /// shoulder capsule half-length along the J2 axis
    pub shoulder_half_length_mm: f64,
    /// upper-arm capsule radius
    pub upper_arm_radius_mm: f64,
    /// elbow capsule radius
    pub elbow_radius_mm: f64,
    /// forearm capsule radius
    pub forearm_radius_mm: f64,
    /// wrist capsule radius (around the J5 axis)
    pub wrist_radius_mm: f64,
    /// wrist capsule half-length along the J5 axis
    pub wrist_half_length_mm: f64,
    /// flange capsule radius (wrist centre to flange face)
    pub flange_radius_mm: f64,
    /// any chain other than the canonical cell: radius of the capsules along the MDH `a` and
    /// `d` offsets of every row (see `crate::collision`)
    pub chain_link_radius_mm: f64,
    /// any chain other than the canonical cell: the capsule radius of each link, links 0 (the
    /// base) to N (the flange), N + 1 values; `None`: `chain_link_radius_mm` for every link
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link_radii_mm: Option<Vec<f64>>,
}

impl RobotLinkGeometry {
    /// Capsule radius of link `link` (0 = base, N = flange) of a chain other than the canonical
    /// cell: `link_radii_mm[link]`, else `chain_link_radius_mm`.
    pub fn chain_radius_mm(&self, link: usize) -> f64 {
        self.link_radii_mm.as_ref().and_then(|r| r.get(link)).copied().unwrap_or(self.chain_link_radius_mm)
    }

    /// Checks that `link_radii_mm`, when given, has one value per link of an `n_joints`-joint
    /// chain (N + 1 values, links 0..N).
    pub fn check_link_count(&self, n_joints: usize) -> Result<(), PlanError> {
        match &self.link_radii_mm {
            Some(r) if r.len() != n_joints + 1 => Err(PlanError::Geometry {
                field: "obstacles.robot_links.link_radii_mm".into(),
                reason: format!(
                    "needs one radius per link 0..{n_joints} ({} values) for this {n_joints}-joint chain, got {}",
                    n_joints + 1,
                    r.len()
                ),
            }),
            _ => Ok(()),
        }
    }
}

impl Default for RobotLinkGeometry {
    fn default() -> Self {
        Self {
            base_radius_mm: 45.0,
            base_height_mm: 100.0,
            shoulder_radius_mm: 35.0,
            shoulder_half_length_mm: 40.0,
            upper_arm_radius_mm: 28.0,
            elbow_radius_mm: 28.0,
            forearm_radius_mm: 24.0,
            wrist_radius_mm: 22.0,
            wrist_half_length_mm: 25.0,
            flange_radius_mm: 20.0,
            chain_link_radius_mm: 30.0,
            link_radii_mm: None,
        }
    }
}

/// The tool changer and calibration end-effector (`[obstacles.end_effector]`), in the
/// tool-changer frame, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EndEffectorGeometry {
    /// tool-changer cylinder radius
    pub tool_changer_radius_mm: f64,
    /// tool-changer cylinder length along `z_7`
    pub tool_changer_length_mm: f64,
    /// plate box centre
    pub plate_center_mm: [f64; 3],
    /// plate box half extents
    pub plate_half_extents_mm: [f64; 3],
    /// radius of the calibration balls (1 inch = 25.4 mm diameter)
    pub ball_radius_mm: f64,
}

impl Default for EndEffectorGeometry {
    fn default() -> Self {
        Self {
            tool_changer_radius_mm: 25.0,
            tool_changer_length_mm: 25.0,
            plate_center_mm: [0.0, 18.0, 70.0],
            plate_half_extents_mm: [45.0, 6.0, 45.0],
            ball_radius_mm: 12.7,
        }
    }
}

/// Everything the collision checker needs besides the kinematic model.
#[derive(Debug, Clone, PartialEq)]
pub struct CellGeometry {
    /// resin tank + kinematic plate: vertical cylinder on the world z axis
    pub tank: Option<CylinderObstacle>,
    /// TriCal body: vertical cylinder below the active calibration position
    pub trical: Option<CylinderObstacle>,
    /// guide body + carriage: box in frame-0 coordinates
    pub guide: Option<BoxObstacle>,
    /// base plate (world z)
    pub floor: Option<PlaneObstacle>,
    /// robot link shapes
    pub robot: RobotLinkGeometry,
    /// tool changer, plate and balls
    pub end_effector: EndEffectorGeometry,
}

impl Default for CellGeometry {
    /// No fixed obstacles, default robot and end-effector shapes.
    fn default() -> Self {
        Self {
            tank: None,
            trical: None,
            guide: None,
            floor: None,
            robot: RobotLinkGeometry::default(),
            end_effector: EndEffectorGeometry::default(),
        }
    }
}

impl CellGeometry {
    /// Reads the geometry from a cell file: `[obstacles]` and the optional
    /// `[obstacles.robot_links]` / `[obstacles.end_effector]` tables.
    pub fn from_cell(cell: &CellFile) -> Result<Self, PlanError> {
        let mut g = Self::default();
        let Some(obs) = &cell.obstacles else {
            return Ok(g);
        };
        g.tank = obs.tank.clone();
        g.trical = obs.trical.clone();
        g.guide = obs.guide.clone();
        g.floor = obs.floor.clone();
        if let Some(v) = obs.extra.get("robot_links") {
            g.robot = v.clone().try_into().map_err(|e: toml::de::Error| PlanError::Geometry {
                field: "obstacles.robot_links".into(),
                reason: e.message().to_string(),
            })?;
        }
        if let Some(v) = obs.extra.get("end_effector") {
            g.end_effector = v.clone().try_into().map_err(|e: toml::de::Error| PlanError::Geometry {
                field: "obstacles.end_effector".into(),
                reason: e.message().to_string(),
            })?;
        }
        g.validate()?;
        g.robot.check_link_count(cell.joints.len())?;
        Ok(g)
    }

    /// Checks that every length is finite and every radius / extent positive.
    pub fn validate(&self) -> Result<(), PlanError> {
        let r = &self.robot;
        let e = &self.end_effector;
        let positive: [(&str, f64); 16] = [
            ("robot_links.chain_link_radius_mm", r.chain_link_radius_mm),
            ("robot_links.base_radius_mm", r.base_radius_mm),
            ("robot_links.base_height_mm", r.base_height_mm),
            ("robot_links.shoulder_radius_mm", r.shoulder_radius_mm),
            ("robot_links.shoulder_half_length_mm", r.shoulder_half_length_mm),
            ("robot_links.upper_arm_radius_mm", r.upper_arm_radius_mm),
            ("robot_links.elbow_radius_mm", r.elbow_radius_mm),
            ("robot_links.forearm_radius_mm", r.forearm_radius_mm),
            ("robot_links.wrist_radius_mm", r.wrist_radius_mm),
            ("robot_links.wrist_half_length_mm", r.wrist_half_length_mm),
            ("robot_links.flange_radius_mm", r.flange_radius_mm),
            ("end_effector.tool_changer_radius_mm", e.tool_changer_radius_mm),
            ("end_effector.tool_changer_length_mm", e.tool_changer_length_mm),
            ("end_effector.plate_half_extents_mm[0]", e.plate_half_extents_mm[0]),
            ("end_effector.plate_half_extents_mm[1]", e.plate_half_extents_mm[1]),
            ("end_effector.plate_half_extents_mm[2]", e.plate_half_extents_mm[2]),
        ];
        for (name, v) in positive.into_iter().chain([("end_effector.ball_radius_mm", e.ball_radius_mm)]) {
            if !(v.is_finite() && v > 0.0) {
                return Err(PlanError::Geometry {
                    field: format!("obstacles.{name}"),
                    reason: format!("must be a positive finite length, got {v}"),
                });
            }
        }
        for (k, v) in r.link_radii_mm.iter().flatten().enumerate() {
            if !(v.is_finite() && *v > 0.0) {
                return Err(PlanError::Geometry {
                    field: format!("obstacles.robot_links.link_radii_mm[{k}]"),
                    reason: format!("must be a positive finite length, got {v}"),
                });
            }
        }
        for (k, v) in e.plate_center_mm.iter().enumerate() {
            if !v.is_finite() {
                return Err(PlanError::Geometry {
                    field: format!("obstacles.end_effector.plate_center_mm[{k}]"),
                    reason: format!("must be finite, got {v}"),
                });
            }
        }
        for (name, c) in [("tank", &self.tank), ("trical", &self.trical)] {
            if let Some(c) = c
                && !(c.radius_mm > 0.0 && c.z_max_mm > c.z_min_mm)
            {
                return Err(PlanError::Geometry {
                    field: format!("obstacles.{name}"),
                    reason: format!("needs radius_mm > 0 and z_max_mm > z_min_mm, got {c:?}"),
                });
            }
        }
        if let Some(b) = &self.guide
            && !(b.x_max_mm > b.x_min_mm && b.y_max_mm > b.y_min_mm && b.z_max_mm > b.z_min_mm)
        {
            return Err(PlanError::Geometry {
                field: "obstacles.guide".into(),
                reason: format!("every max must exceed its min, got {b:?}"),
            });
        }
        Ok(())
    }

    /// Plate centre in the tool frame (mm).
    pub(crate) fn plate_center(&self) -> Vector3<f64> {
        Vector3::from(self.end_effector.plate_center_mm)
    }
}
