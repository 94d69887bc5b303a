#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Static gravity torques `tau_i` \[N·m\] on the revolute joints of a serial chain of N joints
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
    /// mass \[kg\]
    pub mass_kg: f64,
    /// centre of mass in the body's MDH frame \[mm\]
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

    /// Total moving mass \[kg\].
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

/// The per-model constants of the torque recursion, computed once by [`GravityModel::new`]:
/// gravity in frame 0, the first moments `m_i c_i` of the bodies and the masses distal to each
/// frame. [`GravityModel::torques_n`] then costs one rotation of a first-moment vector and one
/// of the gravity vector per joint (no allocation).
///
/// The recursion is the static one of the crate documentation written with the first moment
/// `s_i = Σ_{j ≥ i} m_j (c_j − o_i)` (frame i, kg·mm) of everything distal to joint i:
/// `s_i = m_i c_i + R s_{i+1} + M_{i+1} p` with `R`, `p` of `H_{i+1}^i` and `M_{i+1}` the mass
/// distal to frame i+1. The moment of the weights about `o_i` is `s_i × g_i` (the force
/// recursion's `-n_i`), so `tau_i = (s_i × g_i) · z = s_x g_y − s_y g_x` (×10⁻³ for mm → m).
///
/// # Examples
/// The same numbers as [`gravity_torques`], with the constants computed once:
/// ```
/// use nalgebra::{Matrix3, Vector3};
/// use vatcal_core::{Frame, JointKind, MAX_JOINTS};
/// use vatcal_gravity_torque::{Body, GravityModel, MassModel, gravity_torques};
///
/// let rx_m90 = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
/// let mut links = [Frame::identity(); 4];
/// links[2] = Frame { r: rx_m90, p: Vector3::new(0.0, 0.0, 50.0) };
/// let kinds = [JointKind::Prismatic, JointKind::Revolute, JointKind::Revolute, JointKind::Revolute];
/// let mut masses = MassModel { links: [Body::default(); MAX_JOINTS], n: 4 };
/// masses.links[2] = Body { mass_kg: 2.0, com_mm: Vector3::new(100.0, 0.0, 0.0) };
/// masses.links[3] = Body { mass_kg: 0.5, com_mm: Vector3::new(0.0, 30.0, 0.0) };
/// let g = Vector3::new(0.0, 0.0, -9.81);
/// let model = GravityModel::new(&masses, &Matrix3::identity(), &g);
/// let tau = model.torques_n(&links, &kinds);
/// let reference = gravity_torques(&links, &kinds, &Matrix3::identity(), &masses, &g);
/// assert!(tau.iter().zip(&reference).all(|(a, b)| (a - b).abs() < 1e-12));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GravityModel {
    /// gravity in frame 0, `R_0^Wᵀ g^W` \[m/s²\]
    pub gravity_frame0: Vector3<f64>,
    /// `first_moment_kg_mm[i - 1] = m_i c_i` of the body of frame i [kg·mm]; zero from `n` on
    pub first_moment_kg_mm: [Vector3<f64>; MAX_JOINTS],
    /// `mass_kg[i - 1]` = mass of the body of frame i \[kg\]; zero from `n` on
    pub mass_kg: [f64; MAX_JOINTS],
}

impl GravityModel {
    /// The constants of `masses` (frames 1..=`masses.n`; later links are massless) under
    /// `gravity_world` \[m/s²\] for a chain whose frame 0 has the world orientation
    /// `base_rotation` (`R_0^W`).
    pub fn new(masses: &MassModel, base_rotation: &Matrix3<f64>, gravity_world: &Vector3<f64>) -> Self {
        let mut first_moment_kg_mm = [Vector3::zeros(); MAX_JOINTS];
        let mut mass_kg = [0.0; MAX_JOINTS];
        for (k, body) in masses.bodies().iter().enumerate() {
            first_moment_kg_mm[k] = body.com_mm * body.mass_kg;
            mass_kg[k] = body.mass_kg;
        }
        Self { gravity_frame0: base_rotation.tr_mul(gravity_world), first_moment_kg_mm, mass_kg }
    }

    /// Gravity torques `tau[i - 1]` \[N·m\] about `+z_i` of the chain of exactly `N` joints with
    /// link transforms `links[i - 1] = H_i^{i-1}` (mm) and joint kinds `kinds`; 0 for
    /// prismatic joints. Bodies of frames beyond N are ignored. The same quantity as
    /// [`gravity_torques_n`] (equal to round-off).
    #[inline]
    pub fn torques_n<const N: usize>(&self, links: &[Frame; N], kinds: &[JointKind; N]) -> [f64; N] {
        let mut tau = [0.0; N];
        recursion(
            links,
            |k| kinds[k].is_revolute(),
            self.gravity_frame0,
            |k| self.first_moment_kg_mm[k],
            |k| self.mass_kg[k],
            &mut tau,
        );
        tau
    }

    /// [`GravityModel::torques_n`] for a chain of `links.len()` joints (at most
    /// [`MAX_JOINTS`]; extra links are ignored); a missing kind counts as revolute.
    pub fn torques(&self, links: &[Frame], kinds: &[JointKind]) -> [f64; MAX_JOINTS] {
        let n = links.len().min(MAX_JOINTS);
        let mut tau = [0.0; MAX_JOINTS];
        recursion(
            &links[..n],
            |k| kinds.get(k).is_none_or(|k| k.is_revolute()),
            self.gravity_frame0,
            |k| self.first_moment_kg_mm[k],
            |k| self.mass_kg[k],
            &mut tau[..n],
        );
        tau
    }

    /// The full gravity moment \[N·m\] exerted on everything distal to joint i about the
    /// origin of frame i, in frame i's axes, `moments[i - 1]` for row i = 1..=N (any joint
    /// kind; zero beyond N). Its z component is the torque of a revolute joint
    /// ([`GravityModel::torques`]); the x and y components are the **bending moment** the
    /// joint's bearing carries (what tilts the link about the axes perpendicular to its joint
    /// axis). `links` as for [`GravityModel::torques`].
    ///
    /// # Examples
    /// A 2 kg body 100 mm out along x of a vertical joint's frame and 50 mm along its axis:
    /// gravity (−z) gives no torque about the axis and a bending moment about y of
    /// `m g x = 1.962 N·m`.
    /// ```
    /// use nalgebra::{Matrix3, Vector3};
    /// use vatcal_core::{Frame, MAX_JOINTS};
    /// use vatcal_gravity_torque::{Body, GravityModel, MassModel};
    ///
    /// let mut masses = MassModel { links: [Body::default(); MAX_JOINTS], n: 1 };
    /// masses.links[0] = Body { mass_kg: 2.0, com_mm: Vector3::new(100.0, 0.0, 50.0) };
    /// let model = GravityModel::new(&masses, &Matrix3::identity(), &Vector3::new(0.0, 0.0, -9.81));
    /// let m = model.moments(&[Frame::identity()]);
    /// assert!(m[0].z.abs() < 1e-12 && m[0].x.abs() < 1e-12);
    /// assert!((m[0].y - 2.0 * 9.81 * 0.1).abs() < 1e-12);
    /// ```
    pub fn moments(&self, links: &[Frame]) -> [Vector3<f64>; MAX_JOINTS] {
        let mut out = [Vector3::zeros(); MAX_JOINTS];
        walk(
            links,
            0,
            self.gravity_frame0,
            |k| self.first_moment_kg_mm[k],
            |k| self.mass_kg[k],
            |k, s, g| out[k] = s.cross(g) * 1e-3,
        );
        out
    }
}

/// The first-moment recursion (see [`GravityModel`]) on `links.len() == tau.len()` joints:
/// `revolute(k)`, `first_moment(k)` [kg·mm] and `mass(k)` \[kg\] describe row / body k + 1,
/// `g0` is gravity in frame 0.
#[inline(always)]
fn recursion(
    links: &[Frame],
    revolute: impl Fn(usize) -> bool,
    g0: Vector3<f64>,
    first_moment: impl Fn(usize) -> Vector3<f64>,
    mass: impl Fn(usize) -> f64,
    tau: &mut [f64],
) {
    let n = links.len().min(tau.len());
    // the recursion only needs to go down to the first revolute joint
    let Some(first) = (0..n).find(|k| revolute(*k)) else { return };
    walk(&links[..n], first, g0, first_moment, mass, |k, s, gk| {
        if revolute(k) {
            tau[k] = (s.x * gk.y - s.y * gk.x) * 1e-3;
        }
    });
}

/// The outward/inward walk of the recursion over `links`, from the last row down to row
/// `first + 1`: calls `visit(k, s, g)` for row k + 1 with `s` the first moment of bodies
/// k+1..=n about the origin of frame k+1 and `g` gravity, both in frame k+1.
#[inline(always)]
fn walk(
    links: &[Frame],
    first: usize,
    g0: Vector3<f64>,
    first_moment: impl Fn(usize) -> Vector3<f64>,
    mass: impl Fn(usize) -> f64,
    mut visit: impl FnMut(usize, &Vector3<f64>, &Vector3<f64>),
) {
    let n = links.len().min(MAX_JOINTS);
    if n == 0 {
        return;
    }
    // outward: g[k] = gravity in frame k + 1
    let mut g = [Vector3::zeros(); MAX_JOINTS];
    let mut prev = g0;
    for (gk, link) in g.iter_mut().zip(&links[..n]) {
        *gk = link.r.tr_mul(&prev);
        prev = *gk;
    }
    // inward: s = first moment of bodies k+1..=n about the origin of frame k+1, in frame k+1
    // [kg·mm]; distal = their mass [kg]
    let mut s = first_moment(n - 1);
    let mut distal = mass(n - 1);
    for k in (first..n).rev() {
        if k + 1 < n {
            let next = &links[k + 1]; // H_{k+2}^{k+1}
            s = next.r * s + next.p * distal + first_moment(k);
            distal += mass(k);
        }
        visit(k, &s, &g[k]);
    }
}

/// [`gravity_torques`] for a chain of exactly `N` joints with fixed-size arrays (no length
/// checks in the loops; the FK hot path uses it for the common 6- and 7-joint chains).
/// `tau[i - 1]` is the torque of joint i, 0 for prismatic joints.
///
/// A caller that evaluates many joint vectors of one model can keep a [`GravityModel`] and
/// call [`GravityModel::torques_n`] (the same numbers, the per-model constants computed once).
#[inline]
pub fn gravity_torques_n<const N: usize>(
    links: &[Frame; N],
    kinds: &[JointKind; N],
    base_rotation: &Matrix3<f64>,
    masses: &MassModel,
    gravity_world: &Vector3<f64>,
) -> [f64; N] {
    let mut tau = [0.0; N];
    recursion(
        links,
        |k| kinds[k].is_revolute(),
        base_rotation.tr_mul(gravity_world),
        |k| masses.links[k].com_mm * masses.links[k].mass_kg,
        |k| masses.links[k].mass_kg,
        &mut tau,
    );
    tau
}

/// Gravity torques `tau[i - 1]` \[N·m\] about `+z_i` for every revolute joint i = 1..=N, exerted
/// by gravity on everything distal to joint i; 0 for prismatic joints and beyond N.
///
/// * `links[i-1]` = `H_i^{i-1}` for rows i = 1..=N (translation in mm), evaluated on the
///   geometry the torques should describe (vatcal: own geometry, no compliance); N =
///   `links.len()` (at most [`MAX_JOINTS`]; extra links are ignored);
/// * `kinds[i-1]` = kind of joint i (a missing kind counts as revolute);
/// * `base_rotation` = `R_0^W`;
/// * `masses` = bodies of frames 1..=N (`masses.n` should equal N; links beyond it are
///   massless);
/// * `gravity_world` = gravity vector in the world frame \[m/s²\].
///
/// Cost: well under 0.1 µs for 7 joints (no allocation); [`GravityModel`] keeps the
/// per-model constants for repeated calls.
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
    recursion(
        &links[..n_links],
        |k| kinds.get(k).is_none_or(|k| k.is_revolute()),
        base_rotation.tr_mul(gravity_world),
        |k| masses.links[k].com_mm * masses.links[k].mass_kg,
        |k| masses.links[k].mass_kg,
        &mut tau[..n_links],
    );
    tau
}

/// The force/moment form of the recursion (the crate documentation's equations, as the crate
/// computed them before [`GravityModel`]), kept as the reference the tests compare against.
#[cfg(test)]
fn reference_torques(
    links: &[Frame],
    kinds: &[JointKind],
    base_rotation: &Matrix3<f64>,
    masses: &MassModel,
    gravity_world: &Vector3<f64>,
) -> [f64; MAX_JOINTS] {
    let n_links = links.len().min(MAX_JOINTS);
    let mut tau = [0.0; MAX_JOINTS];
    let Some(first) = (0..n_links).find(|k| kinds.get(*k).is_none_or(|k| k.is_revolute())) else {
        return tau;
    };
    let mut g_frame = [Vector3::zeros(); MAX_JOINTS + 1];
    g_frame[0] = base_rotation.tr_mul(gravity_world);
    for (i, link) in links[..n_links].iter().enumerate() {
        g_frame[i + 1] = link.r.tr_mul(&g_frame[i]);
    }
    let mut f = Vector3::zeros();
    let mut n = Vector3::zeros();
    for i in (first + 1..=n_links).rev() {
        let body = masses.links[i - 1];
        let weight = -body.mass_kg * g_frame[i];
        let (rf, rn) = if i < n_links {
            let next = &links[i];
            let rf = next.r * f;
            (rf, next.r * n + (next.p * 1e-3).cross(&rf))
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
    use proptest::prelude::*;

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

    fn chain_strategy() -> impl Strategy<Value = (Vec<Frame>, Vec<JointKind>, MassModel, Vector3<f64>)> {
        (1..=MAX_JOINTS).prop_flat_map(|n| {
            (
                proptest::collection::vec(
                    (proptest::array::uniform3(-3.2..3.2f64), proptest::array::uniform3(-300.0..300.0f64)),
                    n,
                ),
                proptest::collection::vec(proptest::bool::weighted(0.8), n),
                proptest::collection::vec((0.0..5.0f64, proptest::array::uniform3(-150.0..150.0f64)), n),
                proptest::array::uniform3(-10.0..10.0f64),
            )
                .prop_map(move |(frames, revolute, bodies, g)| {
                    let links = frames
                        .iter()
                        .map(|(e, p)| Frame {
                            r: *nalgebra::Rotation3::from_euler_angles(e[0], e[1], e[2]).matrix(),
                            p: Vector3::from(*p),
                        })
                        .collect();
                    let kinds = revolute.iter().map(|r| if *r { Revolute } else { Prismatic }).collect();
                    let mut masses = MassModel { links: [Body::default(); MAX_JOINTS], n };
                    for (k, (m, c)) in bodies.iter().enumerate() {
                        masses.links[k] = Body { mass_kg: *m, com_mm: Vector3::from(*c) };
                    }
                    (links, kinds, masses, Vector3::from(g))
                })
        })
    }

    proptest! {
        /// The first-moment recursion (plain, fixed-size and precomputed forms) equals the
        /// force/moment recursion on random chains of 1..=12 joints of either kind.
        #[test]
        fn first_moment_recursion_equals_the_force_recursion(
            (links, kinds, masses, g) in chain_strategy(),
            base in proptest::array::uniform3(-3.2..3.2f64),
        ) {
            let base = *nalgebra::Rotation3::from_euler_angles(base[0], base[1], base[2]).matrix();
            let reference = reference_torques(&links, &kinds, &base, &masses, &g);
            let scale = 1e-3 * masses.total_mass_kg() * g.norm() * 1000.0 * links.len() as f64 + 1e-9;
            let plain = gravity_torques(&links, &kinds, &base, &masses, &g);
            let model = GravityModel::new(&masses, &base, &g);
            let pre = model.torques(&links, &kinds);
            for k in 0..MAX_JOINTS {
                prop_assert!((plain[k] - reference[k]).abs() <= 1e-12 * scale, "joint {}: {} vs {}", k + 1, plain[k], reference[k]);
                prop_assert_eq!(pre[k].to_bits(), plain[k].to_bits());
            }
            if let (Ok(l), Ok(kd)) = (<&[Frame; 7]>::try_from(&links[..]), <&[JointKind; 7]>::try_from(&kinds[..])) {
                let n7 = model.torques_n(l, kd);
                prop_assert!(n7.iter().zip(&plain).all(|(a, b)| a.to_bits() == b.to_bits()));
            }
        }
    }

    proptest! {
        /// The full moment of every joint equals the sum over the distal bodies of
        /// `(c - o_i) × m g` computed directly in the world and turned into frame i; its z
        /// component is the torque of a revolute joint.
        #[test]
        fn moments_are_the_distal_weights_moments_about_each_frame(
            (links, kinds, masses, g) in chain_strategy(),
            base in proptest::array::uniform3(-3.2..3.2f64),
        ) {
            let base = *nalgebra::Rotation3::from_euler_angles(base[0], base[1], base[2]).matrix();
            let model = GravityModel::new(&masses, &base, &g);
            let moments = model.moments(&links);
            let tau = model.torques(&links, &kinds);
            // world poses of frames 1..=n
            let mut w = Frame { r: base, p: Vector3::zeros() };
            let mut world = Vec::new();
            for l in &links {
                w = w.compose(l);
                world.push(w);
            }
            let scale = masses.total_mass_kg() * g.norm() * 1.0 * links.len() as f64 + 1e-9;
            for (i, frame) in world.iter().enumerate() {
                let mut m = Vector3::zeros();
                for (k, body) in world.iter().enumerate().skip(i) {
                    let b = masses.links[k];
                    let arm_m = (body.transform_point(&b.com_mm) - frame.p) * 1e-3;
                    m += arm_m.cross(&(g * b.mass_kg));
                }
                let local = frame.r.tr_mul(&m);
                prop_assert!((moments[i] - local).norm() <= 1e-9 * scale, "row {}: {} vs {}", i + 1, moments[i], local);
                if kinds[i].is_revolute() {
                    prop_assert!((moments[i].z - tau[i]).abs() <= 1e-9 * scale);
                }
            }
            prop_assert!(moments[links.len()..].iter().all(|m| m.norm() == 0.0));
        }
    }

    #[test]
    fn bodies_beyond_the_chain_are_ignored() {
        // a mass model of 5 links evaluated on a 3-link chain: links 4 and 5 do not count
        let rx_m90 = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
        let links = [Frame { r: rx_m90, p: Vector3::zeros() }, Frame::identity(), Frame::identity()];
        let mut masses = single_body(1.0, [40.0, 0.0, 0.0], 3, 5);
        masses.links[4] = Body { mass_kg: 7.0, com_mm: Vector3::new(500.0, 0.0, 0.0) };
        let g = Vector3::new(0.0, 0.0, -9.81);
        let kinds = [Revolute; 3];
        let plain = gravity_torques(&links, &kinds, &Matrix3::identity(), &masses, &g);
        let model = GravityModel::new(&masses, &Matrix3::identity(), &g);
        let pre = model.torques_n(&links, &kinds);
        assert!((plain[0] - 9.81 * 0.04).abs() < 1e-12, "{plain:?}");
        assert_eq!(&plain[..3], &pre[..]);
        let reference = reference_torques(&links, &kinds, &Matrix3::identity(), &masses, &g);
        assert!(plain.iter().zip(&reference).all(|(a, b)| (a - b).abs() < 1e-14), "{reference:?}");
    }
}
