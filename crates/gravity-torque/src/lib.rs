//! # vatcal-gravity-torque
//!
//! Static gravity torques `tau_2..tau_7` [N·m] on the six Meca500 joints of the cell, computed
//! by Craig's static outward/inward recursion (background.md §2.2):
//!
//! * outward: `R_i^W = R_{i-1}^W R_i^{i-1}`, gravity in frame i `g_i = (R_i^W)^T g^W`;
//! * inward (i = 7..2, `f_8 = n_8 = 0`):
//!   `f_i = R f_{i+1} - m_i g_i`,
//!   `n_i = R n_{i+1} + p × (R f_{i+1}) + c_i × (-m_i g_i)`,
//!   with `R`, `p` the rotation and translation (metres) of `H_{i+1}^i`;
//! * `tau_i = -n_i · z` — the moment **exerted by gravity** about `+z_i` (the actuator holds
//!   `-tau_i`). A positive compliance makes the joint yield the way gravity pushes:
//!   `theta_i = q_i + theta_offset_i + c_i tau_i`.
//!
//! The tool (tool changer + end-effector) is lumped into link 7.
//!
//! The function takes the seven link transforms `H_i^{i-1}` (translations in mm) and the base
//! rotation, so the caller decides which geometry the torques are evaluated on. vatcal's
//! convention (see `docs/conventions.md`): the evaluated model's own MDH rows including beta,
//! its base orientation, all `c_i = 0`, no iteration.

use nalgebra::{Matrix3, Vector3};
use vatcal_core::Frame;
use vatcal_core::cell::Inertials;

/// Mass and centre of mass of one body.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Body {
    /// mass [kg]
    pub mass_kg: f64,
    /// centre of mass in the body's MDH frame [mm]
    pub com_mm: Vector3<f64>,
}

/// Masses of the moving links 2..7, the tool lumped into link 7.
#[derive(Debug, Clone, PartialEq)]
pub struct MassModel {
    /// `links[k]` is the body of MDH frame `k + 2` (k = 0..6); link 7 includes the tool.
    pub links: [Body; 6],
}

impl MassModel {
    /// Builds the mass model from the cell file's `[inertials]` (missing links have zero mass).
    pub fn from_inertials(inertials: &Inertials) -> Self {
        let mut links = [Body::default(); 6];
        for l in &inertials.links {
            if (2..=7).contains(&l.frame) {
                links[(l.frame - 2) as usize] = Body { mass_kg: l.mass_kg, com_mm: Vector3::from(l.com_mm) };
            }
        }
        let tool = Body { mass_kg: inertials.tool.mass_kg, com_mm: Vector3::from(inertials.tool.com_mm) };
        links[5] = combine(links[5], tool);
        Self { links }
    }

    /// Total moving mass [kg].
    pub fn total_mass_kg(&self) -> f64 {
        self.links.iter().map(|b| b.mass_kg).sum()
    }
}

/// Combines two bodies expressed in the same frame.
pub fn combine(a: Body, b: Body) -> Body {
    let m = a.mass_kg + b.mass_kg;
    if m <= 0.0 {
        return Body { mass_kg: 0.0, com_mm: Vector3::zeros() };
    }
    Body { mass_kg: m, com_mm: (a.com_mm * a.mass_kg + b.com_mm * b.mass_kg) / m }
}

/// Gravity torques `[tau_2, ..., tau_7]` [N·m] about `+z_i`, exerted by gravity on everything
/// distal to joint i.
///
/// * `links[i-1]` = `H_i^{i-1}` for rows i = 1..7 (translation in mm), evaluated on the geometry
///   the torques should describe (vatcal: own geometry, no compliance);
/// * `base_rotation` = `R_0^W`;
/// * `gravity_world` = gravity vector in the world frame [m/s²].
///
/// Cost: ~0.1 µs (no allocation).
///
/// # Examples
/// A 2 kg body 100 mm out on a horizontal link (frame 3's z axis is world +y) feels
/// `m g L = 1.962 N·m` about joint 3; the vertical joint 2 and the distal joints feel nothing:
/// ```
/// use nalgebra::{Matrix3, Vector3};
/// use vatcal_core::Frame;
/// use vatcal_gravity_torque::{Body, MassModel, gravity_torques};
///
/// let rx_m90 = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
/// let mut links = [Frame::identity(); 7];
/// links[2] = Frame { r: rx_m90, p: Vector3::zeros() };
/// links[3] = Frame { r: rx_m90.transpose(), p: Vector3::zeros() };
/// let mut masses = MassModel { links: [Body::default(); 6] };
/// masses.links[1] = Body { mass_kg: 2.0, com_mm: Vector3::new(100.0, 0.0, 0.0) }; // frame 3
/// let tau = gravity_torques(&links, &Matrix3::identity(), &masses, &Vector3::new(0.0, 0.0, -9.81));
/// assert!((tau[1] - 2.0 * 9.81 * 0.1).abs() < 1e-12);
/// assert!(tau[0].abs() < 1e-12 && tau[2..].iter().all(|t| t.abs() < 1e-12));
/// ```
pub fn gravity_torques(
    links: &[Frame; 7],
    base_rotation: &Matrix3<f64>,
    masses: &MassModel,
    gravity_world: &Vector3<f64>,
) -> [f64; 6] {
    // outward: gravity expressed in frames 0..7, g_i = (R_i^{i-1})^T g_{i-1}
    let mut g_frame = [Vector3::zeros(); 8];
    g_frame[0] = base_rotation.tr_mul(gravity_world);
    for (i, link) in links.iter().enumerate() {
        g_frame[i + 1] = link.r.tr_mul(&g_frame[i]);
    }
    // inward
    let mut f = Vector3::zeros(); // force of link i on link i+1, in frame i+1 [N]
    let mut n = Vector3::zeros(); // moment [N m]
    let mut tau = [0.0; 6];
    for i in (2..=7usize).rev() {
        let body = masses.links[i - 2];
        let weight = -body.mass_kg * g_frame[i]; // -m g in frame i, i.e. the "inertial" force
        let (rf, rn) = if i < 7 {
            let next = &links[i]; // H_{i+1}^i
            let r = next.r;
            let p_m = next.p * 1e-3;
            let rf = r * f;
            (rf, r * n + p_m.cross(&rf))
        } else {
            (Vector3::zeros(), Vector3::zeros())
        };
        f = rf + weight;
        n = rn + (body.com_mm * 1e-3).cross(&weight);
        tau[i - 2] = -n.z;
    }
    tau
}

#[cfg(test)]
mod tests {
    use super::*;

    fn single_body(mass_kg: f64, com_mm: [f64; 3], frame: usize) -> MassModel {
        let mut links = [Body::default(); 6];
        links[frame - 2] = Body { mass_kg, com_mm: Vector3::from(com_mm) };
        MassModel { links }
    }

    #[test]
    fn horizontal_link_gets_plus_m_g_l_over_two_about_plus_y() {
        // background.md §2.2 sign test: every frame = world except frame 3, whose z axis is world
        // +y (Rx(-90)); a 2 kg body with COM at x = 100 mm in frame 3 is a horizontal link along
        // +x; gravity (0,0,-9.81) pulls it down: tau_3 = +m g L/2 about +z_3 = +y_world.
        let rx_m90 = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
        let mut links = [Frame::identity(); 7];
        links[2] = Frame { r: rx_m90, p: Vector3::zeros() };
        links[3] = Frame { r: rx_m90.transpose(), p: Vector3::zeros() };
        let masses = single_body(2.0, [100.0, 0.0, 0.0], 3);
        let tau = gravity_torques(&links, &Matrix3::identity(), &masses, &Vector3::new(0.0, 0.0, -9.81));
        assert!((tau[1] - 2.0 * 9.81 * 0.1).abs() < 1e-12, "{tau:?}");
        // joint 2 (axis = world z, vertical) feels nothing from gravity
        assert!(tau[0].abs() < 1e-12);
        // distal joints carry nothing
        assert!(tau[2..].iter().all(|t| t.abs() < 1e-12));
    }

    #[test]
    fn tool_is_lumped_into_link_seven() {
        let inertials = Inertials {
            links: vec![vatcal_core::cell::LinkInertial {
                frame: 7,
                urdf_link: None,
                mass_kg: 1.0,
                com_mm: [0.0, 0.0, 0.0],
            }],
            tool: vatcal_core::cell::ToolInertial { frame: 7, mass_kg: 1.0, com_mm: [0.0, 0.0, 100.0] },
        };
        let m = MassModel::from_inertials(&inertials);
        assert_eq!(m.links[5].mass_kg, 2.0);
        assert!((m.links[5].com_mm.z - 50.0).abs() < 1e-12);
        assert_eq!(m.total_mass_kg(), 2.0);
    }
}
