#![doc = include_str!("../README.md")]
//!
//! ## Overview
//!
//! Reads a URDF file (with [`urdf_rs`]) and converts the serial chain from a base link `B` to a
//! tip link `T` — any two links of the tree: up from `B` to their lowest common ancestor, then
//! down to `T` — into the representation every other vatcal crate uses: one MDH + Hayati-β row
//! per actuated joint,
//!
//! ```text
//! H_i^{i-1} = Rx(alpha_{i-1}) Tx(a_{i-1}) Ry(beta_{i-1}) Rz(theta_i) Tz(d_i)
//! ```
//!
//! a base pose `H_0^W = T(x, y, z) Rx(alpha) Ry(beta) Rz(gamma)` (the "world" is the frame of
//! `B`), one TCP (the origin of `T`, expressed in the last MDH frame), joint limits and the
//! masses and centres of mass of the moving links. The result is the neutral
//! [`ImportedChain`], in file units (mm, degrees, kg).
//!
//! ## The conversion is exact
//!
//! It is not a fit: for every joint vector `q` (URDF joint positions, converted to mm and
//! degrees), the MDH chain puts the TCP exactly where the URDF puts the origin of `T` (the tests
//! check 1e-9 mm on random joint vectors). The construction:
//!
//! * every actuated joint (revolute, continuous, prismatic) is a line in space at `q = 0`: its
//!   URDF joint origin and its (normalised) axis. MDH frame `i` has `z_i` along that axis (same
//!   sense, so `q_i` keeps the URDF's sign) and its origin on it; fixed joints only contribute
//!   their constant transform;
//! * a joint the chain traverses up the tree (from its child link to its parent link,
//!   [`ImportedJoint::reversed`]) moves the rest of the chain by the inverse of its motion: the
//!   segment is `R(a, -q) · T_o⁻¹` instead of `T_o · R(a, q)`. Since `R(a, -q) = R(-a, q)`
//!   (and a translation by `-a q` is one by `q` along `-a`), `z_i` points against the URDF
//!   axis and `q_i` is still the URDF joint position: no sign convention is needed in the cell;
//! * for consecutive axes that are not (nearly) parallel, frame `i` is the classic MDH one:
//!   origin at the foot of the common normal, `x_i` along it (`beta = 0`);
//! * for (nearly) parallel axes (within [`PARALLEL_AXES_TOLERANCE_DEG`]), the common normal is
//!   ill-defined, so the Hayati form is used: frame `i` keeps the origin the previous row gave it
//!   (`d_i = 0`), `x_i` points to where axis `i+1` crosses the plane through that origin normal to
//!   `z_i`, and `beta_i` takes up the residual tilt;
//! * frame 0 coincides with frame 1 at `q = 0` (row 1 is then all zero apart from an
//!   `alpha_0 = 90°` used only to keep the base angles away from gimbal lock), and the base pose
//!   absorbs `B` → frame 0;
//! * the last frame `N` has its origin where the perpendicular from `T`'s origin meets axis `N`,
//!   and its `x` axis along `T`'s `x` axis when `T`'s `z` axis lies along axis `N` (so frame `N`
//!   is `T`'s own frame for the usual flange / `tool0` links and the TCP is `(0, 0, 0)`).
//!
//! Values within a few units in the last place of a multiple of 1e-6 mm or degrees are snapped
//! onto it, so that `-90.00000000000001` reads `-90`; this moves a TCP by far less than 1e-9 mm. After the conversion, the forward kinematics of the
//! rows is checked against the URDF's at a few joint vectors, and a mismatch above 1e-6 mm is
//! reported as an error (it would be a bug, never silent garbage).
//!
//! ## What is rejected
//!
//! `B == T`, or two links in separate trees ([`UrdfImportError::NoPath`], naming both links),
//! planar / floating / spherical joints on the path
//! ([`UrdfImportError::UnsupportedJoint`]), `<mimic>` joints on the path
//! ([`UrdfImportError::MimicJoint`]), a zero axis, revolute/prismatic joints without a usable
//! `<limit>` ([`UrdfImportError::InvalidJoint`]), and chains with no or more than
//! [`MAX_IMPORTED_JOINTS`] actuated joints. Continuous joints become revolute joints without
//! limits. Errors name the file, the line of the joint (when it can be found) and the joint.
//!
//! ## Masses
//!
//! Links are seen from `B` (the tree re-rooted at the base link): the subtree of `B` when the
//! chain only goes down, every link of the tree when it goes up (a humanoid standing on its sole
//! carries the whole body). A link belongs to the MDH frame of the last actuated path joint on
//! its way from `B`: the link joint `i` leads to, the links hanging from it on fixed joints (on
//! the path or beside it) and, after the last joint, everything fixed to `T`. Their masses are added and their centres of
//! mass combined in frame `i`. Links that do not move (above the first joint) are not listed;
//! links moved by a joint that is not on the path (a gripper finger, a second arm) are left out
//! and mentioned in [`ImportedChain::notes`].
//!
//! ## Collision radii
//!
//! The planner models the links of a chain as capsules along the MDH offsets, one radius per
//! link (`[obstacles.robot_links] link_radii_mm`, docs/formats.md). A link's `<collision>`
//! primitives give it: the radius of a cylinder, capsule or sphere, half the diagonal across
//! the two smallest sides of a box; the largest over the URDF links that move with MDH frame
//! `i` (frame 0: the links fixed to `B`) is link `i`'s radius ([`ImportedChain::link_radii_mm`]).
//! Meshes give none (noted); a link without a primitive, when others have one, gets
//! [`DEFAULT_LINK_RADIUS_MM`] (noted).
//!
//! ```
//! let urdf = r#"<robot name="two">
//!   <link name="base"/> <link name="l1"/> <link name="l2"/>
//!   <joint name="j1" type="continuous">
//!     <parent link="base"/> <child link="l1"/> <origin xyz="0 0 0.1"/> <axis xyz="0 0 1"/>
//!   </joint>
//!   <joint name="j2" type="prismatic">
//!     <parent link="l1"/> <child link="l2"/> <origin xyz="0.2 0 0"/> <axis xyz="1 0 0"/>
//!     <limit lower="0" upper="0.3" effort="1" velocity="1"/>
//!   </joint>
//! </robot>"#;
//! let chain = vatcal_urdf::import_str(urdf, "two.urdf", "base", "l2")?;
//! assert_eq!(chain.joints.len(), 2);
//! assert_eq!(chain.joints[0].q_min, None); // continuous
//! assert_eq!(chain.joints[1].q_max, Some(300.0)); // mm
//! # Ok::<(), vatcal_urdf::UrdfImportError>(())
//! ```

mod cell;
mod convert;
mod tree;

use std::path::{Path, PathBuf};

pub use cell::DEFAULT_GRAVITY_M_PER_S2;
pub use vatcal_core::JointKind;
pub use vatcal_core::cell::{BaseInWorld, LinkInertial};

/// Most actuated joints an imported chain may have (the cell model's limit).
pub const MAX_IMPORTED_JOINTS: usize = vatcal_core::MAX_JOINTS;

/// Capsule radius (mm) of an imported link without a `<collision>` primitive when other links
/// have one (the default `chain_link_radius_mm` of `vatcal-planning`).
pub const DEFAULT_LINK_RADIUS_MM: f64 = 30.0;

/// Consecutive joint axes closer than this to parallel (or anti-parallel) use the Hayati
/// construction (`beta`) instead of the common normal \[deg\].
pub const PARALLEL_AXES_TOLERANCE_DEG: f64 = 1.0;

/// One MDH + Hayati-β row, i.e. one actuated URDF joint, in file units.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedJoint {
    /// URDF joint name
    pub name: String,
    /// the link the joint leads to along the chain: the URDF child link, or the URDF parent
    /// link when the chain goes up the tree through this joint (`reversed`)
    pub child_link: String,
    /// true when the chain traverses the joint from its URDF child link to its parent link (up
    /// the tree, e.g. a leg joint of a chain that starts at the sole). The joint then moves the
    /// rest of the chain by the inverse motion, `R(axis, -q)`, which is `R(-axis, q)`: the MDH
    /// `z` axis points against the URDF axis and the joint value is still the URDF joint
    /// position (same sign, same limits).
    pub reversed: bool,
    /// revolute (URDF `revolute` or `continuous`) or prismatic
    pub kind: JointKind,
    /// true for a URDF `continuous` joint (a revolute joint without limits)
    pub continuous: bool,
    /// alpha_{i-1} \[deg\]
    pub alpha_deg: f64,
    /// a_{i-1} \[mm\]
    pub a_mm: f64,
    /// Hayati beta_{i-1} \[deg\] (non-zero only after a (nearly) parallel axis)
    pub beta_deg: f64,
    /// theta offset of joint i \[deg\]
    pub theta_deg: f64,
    /// d offset of joint i \[mm\]
    pub d_mm: f64,
    /// lower limit (deg for revolute, mm for prismatic); `None` = unlimited
    pub q_min: Option<f64>,
    /// upper limit (deg for revolute, mm for prismatic); `None` = unlimited
    pub q_max: Option<f64>,
}

/// The serial chain from a base link to a tip link of a URDF, as MDH + Hayati-β rows, in file
/// units (mm, degrees, kg). See the crate docs for the construction.
///
/// Forward kinematics: `p_B = H_0^B · H_1^0(q_1) · … · H_N^{N-1}(q_N) · tcp_mm`, with
/// `H_0^B` from [`ImportedChain::base_in_world`] and the joint values equal to the URDF joint
/// positions (degrees for revolute joints, mm for prismatic ones).
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedChain {
    /// `<robot name>`
    pub robot_name: String,
    /// the base link `B` (its frame is the "world" of the chain)
    pub base_link: String,
    /// the tip link `T`
    pub tip_link: String,
    /// one row per actuated joint, base to tip (rows 1..N)
    pub joints: Vec<ImportedJoint>,
    /// pose of MDH frame 0 in the frame of `B`
    pub base_in_world: BaseInWorld,
    /// origin of `T` in MDH frame N \[mm\] (the TCP with id 1)
    pub tcp_mm: [f64; 3],
    /// masses and centres of mass of the moving links, in the MDH frame (1..=N) that moves them
    /// (one entry per frame that carries mass, frames ascending)
    pub inertials: Vec<LinkInertial>,
    /// capsule radius of each MDH link 0..N (mm) for the planner's collision model, from the
    /// `<collision>` cylinders, capsules, spheres and boxes (see the crate docs); `None` when the
    /// chain has none (meshes only, or no `<collision>` at all)
    pub link_radii_mm: Option<Vec<f64>>,
    /// things the user should know (masses left out, links lumped together)
    pub notes: Vec<String>,
}

/// Errors of the URDF import. Every variant names the file; joint errors also the joint and,
/// when it can be found, its line.
#[derive(Debug, thiserror::Error)]
pub enum UrdfImportError {
    /// The file could not be read.
    #[error("cannot read URDF file {path}: {cause}")]
    Io {
        /// file path
        path: PathBuf,
        /// cause (kept out of the error chain: the message states it)
        cause: std::io::Error,
    },
    /// Not well-formed XML, or not a URDF `<robot>`.
    #[error("{origin}: not a readable URDF: {message}")]
    Parse {
        /// file path or `<string>`
        origin: String,
        /// the parser's message
        message: String,
    },
    /// The link tree is broken (a link defined twice, a joint naming a missing link, a link with
    /// two parent joints, a loop).
    #[error("{origin}: {reason}")]
    InvalidTree {
        /// file path or `<string>`
        origin: String,
        /// what is wrong
        reason: String,
    },
    /// `--base-link` or `--tip-link` names a link that is not in the file.
    #[error("{origin}: the {role} link `{link}` is not in the URDF (its links: {known})")]
    UnknownLink {
        /// file path or `<string>`
        origin: String,
        /// `"base"` or `"tip"`
        role: &'static str,
        /// the name given
        link: String,
        /// the links of the file
        known: String,
    },
    /// The base and tip links are the same link, or in two separate trees of the file.
    #[error("{origin}: no serial chain from base link `{base}` to tip link `{tip}`: {reason}")]
    NoPath {
        /// file path or `<string>`
        origin: String,
        /// base link
        base: String,
        /// tip link
        tip: String,
        /// why, in terms of the tree
        reason: String,
    },
    /// A planar, floating or spherical joint lies on the path.
    #[error(
        "{location}: joint `{joint}` is a {joint_type} joint; only revolute, continuous, prismatic \
         and fixed joints can be expressed as MDH rows"
    )]
    UnsupportedJoint {
        /// `file:line` (or the file alone)
        location: String,
        /// joint name
        joint: String,
        /// URDF type
        joint_type: String,
    },
    /// A joint on the path mimics another joint.
    #[error(
        "{location}: joint `{joint}` mimics joint `{mimicked}`; a coupled (<mimic>) joint cannot be \
         an independent MDH row"
    )]
    MimicJoint {
        /// `file:line` (or the file alone)
        location: String,
        /// joint name
        joint: String,
        /// the joint it follows
        mimicked: String,
    },
    /// A joint on the path has an unusable value (zero axis, missing or empty limits, NaN...).
    #[error("{location}: joint `{joint}`: {reason}")]
    InvalidJoint {
        /// `file:line` (or the file alone)
        location: String,
        /// joint name
        joint: String,
        /// what is wrong
        reason: String,
    },
    /// A moving link has an unusable inertial (negative or non-finite mass, NaN COM).
    #[error("{location}: link `{link}`: {reason}")]
    InvalidLink {
        /// `file:line` (or the file alone)
        location: String,
        /// link name
        link: String,
        /// what is wrong
        reason: String,
    },
    /// The path has no actuated joint, or more than [`MAX_IMPORTED_JOINTS`].
    #[error(
        "{origin}: the chain from `{base}` to `{tip}` has {count} actuated joints; vatcal needs \
         1..={MAX_IMPORTED_JOINTS}"
    )]
    JointCount {
        /// file path or `<string>`
        origin: String,
        /// base link
        base: String,
        /// tip link
        tip: String,
        /// number of revolute / continuous / prismatic joints found
        count: usize,
    },
    /// The converted rows do not reproduce the URDF's forward kinematics (a bug, reported
    /// instead of writing a wrong model).
    #[error(
        "{origin}: internal error: the MDH rows place the tip {deviation_mm:e} mm away from the \
         URDF's forward kinematics; please report this file"
    )]
    SelfCheck {
        /// file path or `<string>`
        origin: String,
        /// largest deviation found \[mm\]
        deviation_mm: f64,
    },
}

/// Reads `path` and imports the chain from `base_link` to `tip_link` (up the tree to their
/// lowest common ancestor where needed, then down).
///
/// # Examples
/// ```
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.urdf");
/// let chain = vatcal_urdf::import_file(path, "base_link", "tool0")?;
/// let names: Vec<&str> = chain.joints.iter().map(|j| j.name.as_str()).collect();
/// assert_eq!(names[..2], ["shoulder_pan_joint", "shoulder_lift_joint"]);
/// assert_eq!(chain.joints.len(), 6);
/// // a link that is not in the file is an error naming it
/// let e = vatcal_urdf::import_file(path, "base_link", "gripper").expect_err("no such link");
/// assert!(e.to_string().contains("gripper"), "{e}");
/// # Ok::<(), vatcal_urdf::UrdfImportError>(())
/// ```
///
/// # Errors
/// [`UrdfImportError::Io`] when the file cannot be read, and every error of [`import_str`].
pub fn import_file(
    path: impl AsRef<Path>,
    base_link: &str,
    tip_link: &str,
) -> Result<ImportedChain, UrdfImportError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path)
        .map_err(|cause| UrdfImportError::Io { path: path.to_path_buf(), cause })?;
    import_str(&text, &path.display().to_string(), base_link, tip_link)
}

/// Imports the chain from `base_link` to `tip_link` of the URDF `text` (any two links of the
/// tree: up from `base_link` to their lowest common ancestor, then down); `origin` names the
/// source (a file path) in error messages.
///
/// # Errors
/// See [`UrdfImportError`]: unreadable XML, unknown links, no path, unsupported or mimic joints
/// on the path, unusable joint values or inertials, a joint count outside 1..=12.
pub fn import_str(
    text: &str,
    origin: &str,
    base_link: &str,
    tip_link: &str,
) -> Result<ImportedChain, UrdfImportError> {
    let robot = urdf_rs::read_from_string(text)
        .map_err(|e| UrdfImportError::Parse { origin: origin.to_string(), message: e.to_string() })?;
    let tree = tree::Tree::new(&robot, origin)?;
    let path = tree.path(base_link, tip_link, origin)?;
    convert::convert(&tree, &path, base_link, tip_link, text, origin)
}

/// Forward kinematics straight from a URDF's joint origins and axes (no MDH rows involved): the
/// position of the tip link's origin in the base link's frame (a joint traversed up the tree
/// contributes the inverse of its transform). Use it to check a model built from
/// an [`ImportedChain`] (`vatcal import-urdf` does, and so do the tests).
///
/// ```
/// # let urdf = r#"<robot name="one"><link name="b"/><link name="t"/>
/// #   <joint name="j" type="continuous"><parent link="b"/><child link="t"/>
/// #   <origin xyz="0.1 0 0"/><axis xyz="0 0 1"/></joint></robot>"#;
/// let fk = vatcal_urdf::UrdfFk::new(urdf, "one.urdf", "b", "t")?;
/// let p = fk.tip_position_mm(&[90.0]).expect("one joint value");
/// assert!((p[0] - 100.0).abs() < 1e-12 && p[1].abs() < 1e-12);
/// # Ok::<(), vatcal_urdf::UrdfImportError>(())
/// ```
#[derive(Debug, Clone)]
pub struct UrdfFk {
    steps: Vec<convert::Step>,
    kinds: Vec<JointKind>,
}

impl UrdfFk {
    /// Parses `text` and validates the path from `base_link` to `tip_link` like
    /// [`import_str`] does.
    ///
    /// # Errors
    /// The same as [`import_str`] (apart from the self-check and the inertials).
    pub fn new(text: &str, origin: &str, base_link: &str, tip_link: &str) -> Result<Self, UrdfImportError> {
        let robot = urdf_rs::read_from_string(text)
            .map_err(|e| UrdfImportError::Parse { origin: origin.to_string(), message: e.to_string() })?;
        let tree = tree::Tree::new(&robot, origin)?;
        let path = tree.path(base_link, tip_link, origin)?;
        let (steps, rows) = convert::path_steps(&tree, &path, base_link, tip_link, text, origin)?;
        Ok(Self { steps, kinds: rows.iter().map(|r| r.kind).collect() })
    }

    /// Number of actuated joints (the length [`UrdfFk::tip_position_mm`] expects).
    pub fn joint_count(&self) -> usize {
        self.kinds.len()
    }

    /// Tip origin in the base link's frame \[mm\] for joint values in file units (degrees for
    /// revolute joints, mm for prismatic ones, in chain order); `None` when `q_file` does not
    /// have [`UrdfFk::joint_count`] values.
    pub fn tip_position_mm(&self, q_file: &[f64]) -> Option<[f64; 3]> {
        if q_file.len() != self.kinds.len() {
            return None;
        }
        let q: Vec<f64> = q_file
            .iter()
            .zip(&self.kinds)
            .map(|(v, k)| match k {
                JointKind::Revolute => v.to_radians(),
                JointKind::Prismatic => *v,
            })
            .collect();
        let p = convert::urdf_tip(&self.steps, &q);
        Some([p.x, p.y, p.z])
    }
}
