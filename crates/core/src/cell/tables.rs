//! The tables of the cell file other than the file itself: units, joint rows, base, points,
//! gravity, inertials, obstacles, effects and motion limits (serde types, file units).

use serde::{Deserialize, Serialize};

use crate::units::JointKind;

/// `[units]`: must be exactly the canonical units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Units {
    /// `"mm"`
    pub length: String,
    /// `"deg"`
    pub angle: String,
    /// `"kg"`
    pub mass: String,
    /// `"rad/(N*m)"`
    pub compliance: String,
    /// `"m/s^2"`
    pub gravity: String,
}

impl Default for Units {
    fn default() -> Self {
        Self {
            length: "mm".into(),
            angle: "deg".into(),
            mass: "kg".into(),
            compliance: "rad/(N*m)".into(),
            gravity: "m/s^2".into(),
        }
    }
}

/// `[robot]` (version 2, optional): informational.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RobotInfo {
    /// robot name, e.g. `"UR5e"`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// other keys, kept verbatim
    #[serde(flatten)]
    pub extra: toml::Table,
}

/// One `[[joints]]` row: MDH row `index` (transform from frame index-1 to frame index).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointRow {
    /// row / joint index 1..=N
    pub index: u8,
    /// joint name (e.g. `guide`, `J1`; required in version 1, optional in version 2)
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub name: String,
    /// `"prismatic"` or `"revolute"` (version 1: row 1 prismatic, rows 2..7 revolute)
    pub kind: String,
    /// alpha_{i-1} \[deg\]
    pub alpha_deg: f64,
    /// a_{i-1} \[mm\]
    pub a_mm: f64,
    /// Hayati beta_{i-1} \[deg\] (optional, default 0)
    #[serde(default)]
    pub beta_deg: f64,
    /// theta offset of joint i \[deg\]
    pub theta_deg: f64,
    /// d offset of joint i \[mm\]
    pub d_mm: f64,
    /// lower joint limit (mm for prismatic, deg for revolute joints); required except on
    /// revolute rows of version 2, where absent limits mean a continuous joint
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q_min: Option<f64>,
    /// upper joint limit (see `q_min`)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q_max: Option<f64>,
    /// joint compliance c_i \[rad/(N·m)\] (optional, default 0; must be 0 on prismatic rows of
    /// version 2, unused on the guide of version 1)
    #[serde(default)]
    pub compliance_rad_per_n_m: f64,
}

impl JointRow {
    /// The joint kind, `None` for an unknown `kind` string (rejected by validation).
    pub fn joint_kind(&self) -> Option<JointKind> {
        JointKind::from_name(&self.kind)
    }

    /// `(q_min, q_max)` in file units when both are given (`None` = continuous joint).
    pub fn limits(&self) -> Option<(f64, f64)> {
        self.q_min.zip(self.q_max)
    }
}

/// `[base_in_world]`: `H_0^W = T(x,y,z) Rx(alpha) Ry(beta) Rz(gamma)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BaseInWorld {
    /// x \[mm\]
    pub x_mm: f64,
    /// y \[mm\]
    pub y_mm: f64,
    /// z \[mm\]
    pub z_mm: f64,
    /// alpha \[deg\]
    pub alpha_deg: f64,
    /// beta \[deg\]
    pub beta_deg: f64,
    /// gamma \[deg\]
    pub gamma_deg: f64,
}

/// A `[[tcps]]` or `[[calibration_positions]]` entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointEntry {
    /// id
    pub id: u32,
    /// x \[mm\]
    pub x_mm: f64,
    /// y \[mm\]
    pub y_mm: f64,
    /// z \[mm\]
    pub z_mm: f64,
}

/// A `[[planes]]` entry (optional): a contact plane `normal·x = offset_mm` in the world,
/// known to the cell (its plane rows are then fitted with the plane held fixed). Planes that
/// plane rows name and the cell file lacks are identified with the rest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaneEntry {
    /// plane id (the `plane` column of plane rows)
    pub id: u32,
    /// normal direction in the world (any non-zero length; normalised on load)
    pub normal: [f64; 3],
    /// signed distance of the plane from the world origin along the unit normal \[mm\]
    pub offset_mm: f64,
    /// radius of the flat contact face pressed on the plane when the tool axis is held
    /// normal to it \[mm\]: the lever at which a tilt becomes a height error (optional;
    /// default [`PlaneEntry::DEFAULT_CONTACT_RADIUS_MM`])
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_radius_mm: Option<f64>,
}

impl PlaneEntry {
    /// Default contact-face radius \[mm\].
    pub const DEFAULT_CONTACT_RADIUS_MM: f64 = 50.0;
}

/// `[gravity]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Gravity {
    /// gravity vector in the world frame \[m/s²\]
    pub vector_m_per_s2: [f64; 3],
}

/// `[[inertials.links]]`: mass and COM of link `frame` in its own MDH frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinkInertial {
    /// MDH frame: 2..=7 in version 1 (the Meca500 links), 1..=N in version 2
    pub frame: u8,
    /// informational URDF link name
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub urdf_link: Option<String>,
    /// mass \[kg\]
    pub mass_kg: f64,
    /// centre of mass in frame `frame` \[mm\]
    pub com_mm: [f64; 3],
}

/// `[inertials.tool]`: the tool (tool changer + end-effector), rigidly attached to the last
/// frame N (7 on the canonical cell).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ToolInertial {
    /// must be N, the last frame
    pub frame: u8,
    /// mass \[kg\]
    pub mass_kg: f64,
    /// COM in frame N \[mm\]
    pub com_mm: [f64; 3],
}

/// `[inertials]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Inertials {
    /// moving links (a link without an entry has no mass)
    pub links: Vec<LinkInertial>,
    /// tool
    pub tool: ToolInertial,
}

/// A vertical cylinder on the world z axis (or, for `trical`, below the active position).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CylinderObstacle {
    /// radius \[mm\]
    pub radius_mm: f64,
    /// bottom \[mm\]
    pub z_min_mm: f64,
    /// top \[mm\]
    pub z_max_mm: f64,
}

/// An axis-aligned box in frame-0 coordinates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoxObstacle {
    /// x min \[mm\]
    pub x_min_mm: f64,
    /// x max \[mm\]
    pub x_max_mm: f64,
    /// y min \[mm\]
    pub y_min_mm: f64,
    /// y max \[mm\]
    pub y_max_mm: f64,
    /// z min \[mm\]
    pub z_min_mm: f64,
    /// z max \[mm\]
    pub z_max_mm: f64,
}

/// A horizontal plane (world z).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaneObstacle {
    /// height \[mm\]
    pub z_mm: f64,
}

/// `[obstacles]`: the simple collision model used to screen candidate poses.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Obstacles {
    /// resin tank + kinematic plate
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tank: Option<CylinderObstacle>,
    /// TriCal body below the active calibration position
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trical: Option<CylinderObstacle>,
    /// guide body + carriage (frame 0)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guide: Option<BoxObstacle>,
    /// base plate
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor: Option<PlaneObstacle>,
    /// other obstacle tables, kept verbatim
    #[serde(flatten)]
    pub extra: toml::Table,
}

/// `[[effects]]`: an effect of the catalog switched on in this model, with its values.
///
/// `values` maps parameter names to values in file units: keys of angular parameters end in
/// `_deg`, of length parameters in `_mm`; other parameters use their bare name
/// (e.g. `cyclic4_h1_sin_deg = 0.012`, `tool_tx_mm = 0.03`, `guide_scale = 2e-5`).
/// Built-in effects (`joint-compliance`, `tcp-offset`, `position-offset`, `hayati-beta`) keep
/// their values in the ordinary fields and only mark that the effect belongs to the model.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct EffectEntry {
    /// catalog name, e.g. `joint-cyclic`
    pub effect: String,
    /// cell joint (1..=7) for per-joint effects
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<u8>,
    /// harmonic for `joint-cyclic`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub harmonic: Option<u8>,
    /// highest polynomial order for `guide-angular` / `guide-straightness`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub order: Option<u8>,
    /// `time` or `temperature` for `thermal-drift`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub driver: Option<String>,
    /// reference temperature \[°C\] for a temperature-driven `thermal-drift` (default 20)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_temperature_c: Option<f64>,
    /// TCP id for `tcp-offset`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tcp: Option<u32>,
    /// calibration position id for `position-offset`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<u32>,
    /// MDH row for `hayati-beta`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub row: Option<u8>,
    /// which motion of the link frame for `link-out-of-plane`: `axial`, `tilt-x` or `tilt-y`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub component: Option<String>,
    /// the joint whose angle drives the error, for `joint-coupling`
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub driving_joint: Option<u8>,
    /// parameter values in file units
    #[serde(default, skip_serializing_if = "toml::Table::is_empty")]
    pub values: toml::Table,
}

/// `[motion]` (optional): speed limits used to estimate motion time when planning a tour.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotionLimits {
    /// maximum speed of the Meca500 joints J1..J6 \[deg/s\]
    pub joint_speed_deg_per_s: [f64; 6],
    /// maximum speed of the linear guide \[mm/s\]
    pub guide_speed_mm_per_s: f64,
    /// fraction of the maximum speed used for planned moves (0..1]
    #[serde(default = "default_speed_fraction")]
    pub speed_fraction: f64,
    /// time to settle + auto-centre at each measurement \[s\]
    #[serde(default = "default_measure_s")]
    pub measurement_s: f64,
    /// time for the operator to re-place the probe plate \[s\]
    #[serde(default = "default_replacement_s")]
    pub probe_replacement_s: f64,
}

fn default_speed_fraction() -> f64 {
    0.25
}
fn default_measure_s() -> f64 {
    20.0
}
fn default_replacement_s() -> f64 {
    60.0
}

impl Default for MotionLimits {
    /// Meca500 R3 maximum joint speeds (150, 150, 180, 300, 300, 500 deg/s) and a conservative
    /// 50 mm/s for the guide.
    fn default() -> Self {
        Self {
            joint_speed_deg_per_s: [150.0, 150.0, 180.0, 300.0, 300.0, 500.0],
            guide_speed_mm_per_s: 50.0,
            speed_fraction: default_speed_fraction(),
            measurement_s: default_measure_s(),
            probe_replacement_s: default_replacement_s(),
        }
    }
}
