//! # vatcal-gravity-torque
//!
//! Static gravity torques `tau_i` [N·m] on the revolute joints of a serial chain of N joints
//! (on the canonical cell: `tau_2..tau_7` on the six Meca500 joints), computed by Craig's
//! static outward/inward recursion (background.md §2.2):
//!
//! * outward: `R_i^W = R_{i-1}^W R_i^{i-1}`, gravity in frame i `g_i = (R_i^W)^T g^W`;
//! * inward (i = N..1, `f_{N+1} = n_{N+1} = 0`):
//!   `f_i = R f_{i+1} - m_i g_i`,
//!   `n_i = R n_{i+1} + p × (R f_{i+1}) + c_i × (-m_i g_i)`,
//!   with `R`, `p` the rotation and translation (metres) of `H_{i+1}^i`;
//! * `tau_i = -n_i · z` — the moment **exerted by gravity** about `+z_i` (the actuator holds
//!   `-tau_i`). A positive compliance makes the joint yield the way gravity pushes:
//!   `theta_i = q_i + theta_offset_i + c_i tau_i`. Prismatic joints get `tau_i = 0` (their
//!   axial force is not used).
//!
//! The tool (tool changer + end-effector) is lumped into the last link N.
//!
//! The function takes the N link transforms `H_i^{i-1}` (translations in mm) and the base
//! rotation, so the caller decides which geometry the torques are evaluated on. vatcal's
//! convention (see `docs/conventions.md`): the evaluated model's own MDH rows including beta,
//! its base orientation, all `c_i = 0`, no iteration.

use nalgebra::{Matrix3, Vector3};
use vatcal_core::cell::Inertials;
use vatcal_core::{Frame, JointKind, MAX_JOINTS};

/// Mass and centre of mass of one body.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Body {
    /// mass [kg]
    pub mass_kg: f64,
    /// centre of mass in the body's MDH frame [mm]
    pub com_mm: Vector3<f64>,
}

/// Masses of the links of a chain of N joints, the tool lumped into the last link N.
#[derive(Debug, Clone, PartialEq)]
pub struct MassModel {
    /// `links[i - 1]` is the body of MDH frame i (i = 1..=n); link n includes the tool.
    /// Entries from `n` on are zero.
    pub links: [Body; MAX_JOINTS],
    /// number of links N (= joints of the chain)
    pub n: usize,
}

impl MassModel {
    /// Builds the mass model from the cell file's `[inertials]` (missing links have zero mass).
    /// The chain has `inertials.tool.frame` links (the tool sits on the last frame; cell
    /// validation checks this).
    pub fn from_inertials(inertials: &Inertials) -> Self {
        let n = (inertials.tool.frame as usize).clamp(1, MAX_JOINTS);
        let mut links = [Body::default(); MAX_JOINTS];
        for l in &inertials.links {
            if (1..=n).contains(&(l.frame as usize)) {
                links[l.frame as usize - 1] = Body { mass_kg: l.mass_kg, com_mm: Vector3::from(l.com_mm) };
            }
        }
        let tool = Body { mass_kg: inertials.tool.mass_kg, com_mm: Vector3::from(inertials.tool.com_mm) };
        links[n - 1] = combine(links[n - 1], tool);
        Self { links, n }
    }

    /// The bodies of frames 1..=n.
    pub fn bodies(&self) -> &[Body] {
        &self.links[..self.n]
    }

    /// The bodies of frames 1..=n, mutable.
    pub fn bodies_mut(&mut self) -> &mut [Body] {
        &mut self.links[..self.n]
    }

    /// The body of MDH frame `frame` (1..=n); zero for other frames.
    pub fn body(&self, frame: usize) -> Body {
        if (1..=self.n).contains(&frame) { self.links[frame - 1] } else { Body::default() }
    }

    /// Total moving mass [kg].
    pub fn total_mass_kg(&self) -> f64 {
        self.bodies().iter().map(|b| b.mass_kg).sum()
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

/// [`gravity_torques`] for a chain of exactly `N` joints with fixed-size arrays (no length
/// checks in the loops; the FK hot path uses it for the common 6- and 7-joint chains).
/// `tau[i - 1]` is the torque of joint i, 0 for prismatic joints.
#[inline]
pub fn gravity_torques_n<const N: usize>(
    links: &[Frame; N],
    kinds: &[JointKind; N],
    base_rotation: &Matrix3<f64>,
    masses: &MassModel,
    gravity_world: &Vector3<f64>,
) -> [f64; N] {
    let mut tau = [0.0; N];
    let Some(first) = kinds.iter().position(|k| k.is_revolute()) else { return tau };
    // outward: g[i - 1] = gravity in frame i
    let mut g = [Vector3::zeros(); N];
    let mut prev = base_rotation.tr_mul(gravity_world);
    for (gi, link) in g.iter_mut().zip(links) {
        *gi = link.r.tr_mul(&prev);
        prev = *gi;
    }
    // inward
    let mut f = Vector3::zeros();
    let mut n = Vector3::zeros();
    for i in (first + 1..=N).rev() {
        let body = masses.links[i - 1];
        let weight = -body.mass_kg * g[i - 1];
        let (rf, rn) = if i < N {
            let next = &links[i];
            let rf = next.r * f;
            (rf, next.r * n + (next.p * 1e-3).cross(&rf))
        } else {
            (Vector3::zeros(), Vector3::zeros())
        };
        f = rf + weight;
        n = rn + (body.com_mm * 1e-3).cross(&weight);
        if kinds[i - 1].is_revolute() {
            tau[i - 1] = -n.z;
        }
    }
    tau
}

/// Gravity torques `tau[i - 1]` [N·m] about `+z_i` for every revolute joint i = 1..=N, exerted
/// by gravity on everything distal to joint i; 0 for prismatic joints and beyond N.
///
/// * `links[i-1]` = `H_i^{i-1}` for rows i = 1..=N (translation in mm), evaluated on the
///   geometry the torques should describe (vatcal: own geometry, no compliance); N =
///   `links.len()` (at most [`MAX_JOINTS`]; extra links are ignored);
/// * `kinds[i-1]` = kind of joint i (a missing kind counts as revolute);
/// * `base_rotation` = `R_0^W`;
/// * `masses` = bodies of frames 1..=N (`masses.n` should equal N; links beyond it are
///   massless);
/// * `gravity_world` = gravity vector in the world frame [m/s²].
///
/// Cost: ~0.1 µs for 7 joints (no allocation).
///
/// # Examples
/// A 2 kg body 100 mm out on a horizontal link (frame 3's z axis is world +y) feels
/// `m g L = 1.962 N·m` about joint 3; the vertical joint 2, the prismatic joint 1 and the distal
/// joints feel nothing:
/// ```
/// use nalgebra::{Matrix3, Vector3};
/// use vatcal_core::{Frame, JointKind, MAX_JOINTS};
/// use vatcal_gravity_torque::{Body, MassModel, gravity_torques};
///
/// let rx_m90 = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
/// let mut links = [Frame::identity(); 4];
/// links[2] = Frame { r: rx_m90, p: Vector3::zeros() };
/// links[3] = Frame { r: rx_m90.transpose(), p: Vector3::zeros() };
/// let kinds = [JointKind::Prismatic, JointKind::Revolute, JointKind::Revolute, JointKind::Revolute];
/// let mut masses = MassModel { links: [Body::default(); MAX_JOINTS], n: 4 };
/// masses.links[2] = Body { mass_kg: 2.0, com_mm: Vector3::new(100.0, 0.0, 0.0) }; // frame 3
/// let tau = gravity_torques(&links, &kinds, &Matrix3::identity(), &masses, &Vector3::new(0.0, 0.0, -9.81));
/// assert!((tau[2] - 2.0 * 9.81 * 0.1).abs() < 1e-12);
/// assert!(tau.iter().enumerate().all(|(k, t)| k == 2 || t.abs() < 1e-12));
/// ```
pub fn gravity_torques(
    links: &[Frame],
    kinds: &[JointKind],
    base_rotation: &Matrix3<f64>,
    masses: &MassModel,
    gravity_world: &Vector3<f64>,
) -> [f64; MAX_JOINTS] {
    let n_links = links.len().min(MAX_JOINTS);
    let mut tau = [0.0; MAX_JOINTS];
    // the common chains on fixed-size arrays
    if let (Ok(l), Some(Ok(k))) =
        (<&[Frame; 7]>::try_from(links), kinds.get(..7).map(<&[JointKind; 7]>::try_from))
    {
        tau[..7].copy_from_slice(&gravity_torques_n(l, k, base_rotation, masses, gravity_world));
        return tau;
    }
    if let (Ok(l), Some(Ok(k))) =
        (<&[Frame; 6]>::try_from(links), kinds.get(..6).map(<&[JointKind; 6]>::try_from))
    {
        tau[..6].copy_from_slice(&gravity_torques_n(l, k, base_rotation, masses, gravity_world));
        return tau;
    }
    // the recursion only needs to go down to the first revolute joint
    let Some(first) = (0..n_links).find(|k| kinds.get(*k).is_none_or(|k| k.is_revolute())) else {
        return tau;
    };
    // outward: gravity expressed in frames 0..N, g_i = (R_i^{i-1})^T g_{i-1}
    let mut g_frame = [Vector3::zeros(); MAX_JOINTS + 1];
    g_frame[0] = base_rotation.tr_mul(gravity_world);
    for (i, link) in links[..n_links].iter().enumerate() {
        g_frame[i + 1] = link.r.tr_mul(&g_frame[i]);
    }
    // inward
    let mut f = Vector3::zeros(); // force of link i on link i+1, in frame i+1 [N]
    let mut n = Vector3::zeros(); // moment [N m]
    for i in (first + 1..=n_links).rev() {
        let body = masses.links[i - 1];
        let weight = -body.mass_kg * g_frame[i]; // -m g in frame i, i.e. the "inertial" force
        let (rf, rn) = if i < n_links {
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
        if kinds.get(i - 1).is_none_or(|k| k.is_revolute()) {
            tau[i - 1] = -n.z;
        }
    }
    tau
}

#[cfg(test)]
mod tests {
    use super::*;

    use JointKind::{Prismatic, Revolute};

    const CELL: [JointKind; 7] = [Prismatic, Revolute, Revolute, Revolute, Revolute, Revolute, Revolute];

    fn single_body(mass_kg: f64, com_mm: [f64; 3], frame: usize, n: usize) -> MassModel {
        let mut links = [Body::default(); MAX_JOINTS];
        links[frame - 1] = Body { mass_kg, com_mm: Vector3::from(com_mm) };
        MassModel { links, n }
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
        let masses = single_body(2.0, [100.0, 0.0, 0.0], 3, 7);
        let tau =
            gravity_torques(&links, &CELL, &Matrix3::identity(), &masses, &Vector3::new(0.0, 0.0, -9.81));
        assert!((tau[2] - 2.0 * 9.81 * 0.1).abs() < 1e-12, "{tau:?}");
        // joint 2 (axis = world z, vertical) feels nothing from gravity
        assert!(tau[1].abs() < 1e-12);
        // distal joints carry nothing; the prismatic joint 1 has no torque
        assert!(tau[3..].iter().all(|t| t.abs() < 1e-12));
        assert_eq!(tau[0], 0.0);
    }

    #[test]
    fn any_chain_revolute_torques_only() {
        // a 3-joint chain R P R: frame 1 rotated so that z_1 is horizontal (world +y), a body on
        // frame 3 at x = 50 mm. Joint 1 carries the whole weight, the prismatic joint 2 none.
        let rx_m90 = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
        let links = [
            Frame { r: rx_m90, p: Vector3::zeros() },
            Frame::identity(),
            Frame { r: Matrix3::identity(), p: Vector3::new(0.0, 0.0, 0.0) },
        ];
        let masses = single_body(1.5, [50.0, 0.0, 0.0], 3, 3);
        let g = Vector3::new(0.0, 0.0, -9.81);
        let tau =
            gravity_torques(&links, &[Revolute, Prismatic, Revolute], &Matrix3::identity(), &masses, &g);
        // moment of the weight about +z_1 (= world +y) at x = 0.05 m: +m g x
        assert!((tau[0] - 1.5 * 9.81 * 0.05).abs() < 1e-12, "{tau:?}");
        assert_eq!(tau[1], 0.0);
        // z_3 is the same line as z_1 (identity rows 2 and 3): the same moment
        assert!((tau[2] - tau[0]).abs() < 1e-12, "{tau:?}");
        assert!(tau[3..].iter().all(|t| *t == 0.0));
        // all prismatic: no torque at all
        let tau = gravity_torques(&links, &[Prismatic; 3], &Matrix3::identity(), &masses, &g);
        assert!(tau.iter().all(|t| *t == 0.0));
    }

    #[test]
    fn tool_is_lumped_into_the_last_link() {
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
        assert_eq!(m.n, 7);
        assert_eq!(m.links[6].mass_kg, 2.0);
        assert!((m.links[6].com_mm.z - 50.0).abs() < 1e-12);
        assert_eq!(m.total_mass_kg(), 2.0);
        assert_eq!(m.body(7).mass_kg, 2.0);
        assert_eq!(m.body(8).mass_kg, 0.0);
    }
}
