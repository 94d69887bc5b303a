//! [`ImportedChain`] → cell file (format `serial-robot-cell`, version 2).

use nalgebra::Vector3;
use vatcal_core::cell::{
    CellFile, FORMAT_NAME_V2, FORMAT_VERSION_V2, Gravity, Inertials, JointRow, Obstacles, PointEntry,
    RobotInfo, ToolInertial, Units,
};

use crate::ImportedChain;

/// Gravity written into an imported cell [m/s², in the base link's frame]: the base link's z
/// axis is taken to point up.
pub const DEFAULT_GRAVITY_M_PER_S2: [f64; 3] = [0.0, 0.0, -9.81];

impl ImportedChain {
    /// Where TCP 1 is at `q = 0`, in the base link's frame \[mm\].
    pub fn tcp_at_zero_mm(&self) -> [f64; 3] {
        let p: Vector3<f64> = crate::convert::chain_tip(self, &vec![0.0; self.joints.len()]);
        [p.x, p.y, p.z]
    }

    /// The cell file (format `serial-robot-cell`, version 2) of this chain, ready to save:
    ///
    /// * `[[joints]]`: the rows, with the URDF joint names, limits (none for continuous joints)
    ///   and zero compliance; `[robot] name` = the URDF robot name;
    /// * `[base_in_world]`: the base pose; the world is the base link's frame, and `[gravity]`
    ///   is [`DEFAULT_GRAVITY_M_PER_S2`] (the base link's z axis up; edit it otherwise);
    /// * `[[tcps]]`: TCP 1 = the origin of the tip link in frame N;
    /// * `[[calibration_positions]]`: one placeholder (id 1) where TCP 1 is at `q = 0` — the file
    ///   format needs one; replace it with the probe's positions;
    /// * `[[inertials.links]]` as imported, `[inertials.tool]` 0 kg at the origin of frame N (the
    ///   tool is not in the URDF chain);
    /// * `[obstacles.robot_links] link_radii_mm`: the collision radii, when the URDF has
    ///   `<collision>` primitives ([`ImportedChain::link_radii_mm`]);
    /// * `[urdf_import]`: where the chain came from (`source`, `base_link`, `tip_link`), the
    ///   joints traversed up the tree (`reversed_joints`, when any) and the import notes.
    ///
    /// # Examples
    /// ```
    /// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.urdf");
    /// let chain = vatcal_urdf::import_file(path, "base_link", "tool0")?;
    /// let cell = chain.to_cell("ur5e.urdf");
    /// assert!(cell.is_v2() && cell.joint_count() == 6);
    /// // the cell file is valid as written, and loads back unchanged
    /// let text = cell.to_toml_string()?;
    /// assert_eq!(vatcal_core::CellFile::from_toml_str(&text, "ur5e-imported.toml")?, cell);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn to_cell(&self, source: &str) -> CellFile {
        let n = self.joints.len();
        let joints = self
            .joints
            .iter()
            .enumerate()
            .map(|(k, j)| JointRow {
                index: (k + 1) as u8,
                name: j.name.clone(),
                kind: j.kind.name().to_string(),
                alpha_deg: j.alpha_deg,
                a_mm: j.a_mm,
                beta_deg: j.beta_deg,
                theta_deg: j.theta_deg,
                d_mm: j.d_mm,
                q_min: j.q_min,
                q_max: j.q_max,
                compliance_rad_per_n_m: 0.0,
            })
            .collect();
        let [x, y, z] = self.tcp_at_zero_mm();
        let mut provenance = toml::Table::new();
        provenance.insert("source".into(), source.into());
        provenance.insert("base_link".into(), self.base_link.clone().into());
        provenance.insert("tip_link".into(), self.tip_link.clone().into());
        let reversed: Vec<toml::Value> =
            self.joints.iter().filter(|j| j.reversed).map(|j| j.name.clone().into()).collect();
        if !reversed.is_empty() {
            provenance.insert("reversed_joints".into(), toml::Value::Array(reversed));
        }
        if !self.notes.is_empty() {
            provenance.insert(
                "notes".into(),
                toml::Value::Array(self.notes.iter().map(|s| s.clone().into()).collect()),
            );
        }
        let mut extra = toml::Table::new();
        extra.insert("urdf_import".into(), toml::Value::Table(provenance));
        CellFile {
            format: FORMAT_NAME_V2.to_string(),
            version: FORMAT_VERSION_V2,
            units: Units::default(),
            robot: Some(RobotInfo { name: Some(self.robot_name.clone()), extra: toml::Table::new() }),
            joints,
            base_in_world: self.base_in_world.clone(),
            tcps: vec![PointEntry {
                id: 1,
                x_mm: self.tcp_mm[0],
                y_mm: self.tcp_mm[1],
                z_mm: self.tcp_mm[2],
            }],
            calibration_positions: vec![PointEntry { id: 1, x_mm: x, y_mm: y, z_mm: z }],
            planes: Vec::new(),
            gravity: Gravity { vector_m_per_s2: DEFAULT_GRAVITY_M_PER_S2 },
            inertials: Inertials {
                links: self.inertials.clone(),
                tool: ToolInertial { frame: n as u8, mass_kg: 0.0, com_mm: [0.0; 3] },
            },
            obstacles: self.link_radii_mm.as_ref().map(|radii| {
                let mut links = toml::Table::new();
                links.insert(
                    "link_radii_mm".into(),
                    toml::Value::Array(radii.iter().map(|r| (*r).into()).collect()),
                );
                let mut extra = toml::Table::new();
                extra.insert("robot_links".into(), toml::Value::Table(links));
                Obstacles { extra, ..Obstacles::default() }
            }),
            motion: None,
            effects: Vec::new(),
            training_range: None,
            extra,
        }
    }
}
