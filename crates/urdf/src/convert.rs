//! URDF path → MDH + Hayati-β rows, base pose, TCP and inertials (the construction described in
//! the crate docs). Everything inside is in mm and radians.

use std::collections::{BTreeMap, HashMap};
use std::f64::consts::FRAC_PI_2;

use nalgebra::{Rotation3, Unit, Vector3};
use urdf_rs::{JointType, Pose};
use vatcal_core::cell::{BaseInWorld, LinkInertial};
use vatcal_core::frame::{Frame, rot_x, rot_y, rot_z};

use crate::tree::{PathJoint, Tree, element_line};
use crate::{
    ImportedChain, ImportedJoint, JointKind, MAX_IMPORTED_JOINTS, PARALLEL_AXES_TOLERANCE_DEG,
    UrdfImportError,
};

/// URDF lengths are metres; vatcal's are millimetres.
const M_TO_MM: f64 = 1000.0;

/// Largest FK deviation the self-check accepts \[mm\] (the construction is exact; anything near
/// this is a bug).
const SELF_CHECK_MM: f64 = 1e-6;

/// A joint axis at q = 0, in the frame of the base link \[mm\].
#[derive(Debug, Clone, Copy)]
struct Line {
    point: Vector3<f64>,
    dir: Vector3<f64>,
}

/// One joint of the path: its constant origin and, for actuated joints, how it moves. Down the
/// tree the step is `origin · motion(q)`; up the tree (`reversed`) its inverse
/// `motion(-q) · origin⁻¹`.
#[derive(Debug, Clone)]
pub(crate) struct Step {
    origin: Frame,
    /// kind and unit axis in the joint frame (the URDF axis, normalised)
    motion: Option<(JointKind, Vector3<f64>)>,
    /// traversed from the joint's child link to its parent link
    reversed: bool,
}

/// What the rows need from an actuated joint of the path besides the geometry.
#[derive(Debug, Clone)]
pub(crate) struct Actuated {
    name: String,
    /// the link the joint leads to along the chain (the URDF child, or the parent when reversed)
    child: String,
    pub kind: JointKind,
    /// traversed from child to parent
    reversed: bool,
    continuous: bool,
    q_min: Option<f64>,
    q_max: Option<f64>,
    /// index into `robot.joints`
    joint: usize,
}

/// URDF `<origin>` as a frame (`R = Rz(yaw) Ry(pitch) Rx(roll)`), translation in mm.
fn pose_frame(p: &Pose) -> Frame {
    Frame {
        r: rot_z(p.rpy[2]) * rot_y(p.rpy[1]) * rot_x(p.rpy[0]),
        p: Vector3::new(p.xyz[0], p.xyz[1], p.xyz[2]) * M_TO_MM,
    }
}

/// The transform of one MDH + Hayati-β row: `Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)`.
fn mdh_frame(alpha: f64, a: f64, beta: f64, theta: f64, d: f64) -> Frame {
    let rxy = rot_x(alpha) * rot_y(beta);
    Frame { r: rxy * rot_z(theta), p: Vector3::new(a, 0.0, 0.0) + rxy * Vector3::new(0.0, 0.0, d) }
}

/// MDH + β values of a transform whose `x` line meets the new `z` axis (rad, mm).
fn decompose(t: &Frame) -> [f64; 5] {
    let z = t.z_axis();
    let beta = z.x.atan2(z.y.hypot(z.z));
    let alpha = (-z.y).atan2(z.z);
    let m = (rot_x(alpha) * rot_y(beta)).transpose() * t.r;
    let theta = m[(1, 0)].atan2(m[(0, 0)]);
    // p = a e_x + d z'  (cos^2 beta > 0: |beta| < 90° in every row this crate builds)
    let d = (t.p.y * z.y + t.p.z * z.z) / (z.y * z.y + z.z * z.z);
    let a = t.p.x - d * z.x;
    [alpha, a, beta, theta, d]
}

/// `R = Rx(alpha) Ry(beta) Rz(gamma)` → (alpha, beta, gamma) \[rad\]; `|beta|` must be well below
/// 90° for full precision (the caller makes sure).
fn xyz_euler(r: &nalgebra::Matrix3<f64>) -> [f64; 3] {
    let beta = r[(0, 2)].atan2(r[(1, 2)].hypot(r[(2, 2)]));
    let alpha = (-r[(1, 2)]).atan2(r[(2, 2)]);
    let gamma = (-r[(0, 1)]).atan2(r[(0, 0)]);
    [alpha, beta, gamma]
}

/// Snaps a value that is within a few units in the last place (8 ε · max(100, |x|)) of a
/// multiple of 1e-6 onto it, so that `-90.00000000000001` reads `-90`, `392.2000000000001` reads
/// `392.2` and `-0` reads `0`; any other value is returned unchanged. The change is below
/// 2e-13 · max(100, |x|), i.e. far below the 1e-9 mm the FK tests demand even with a common
/// normal 10 m away.
fn clean(x: f64) -> f64 {
    let g = (x * 1e6).round() / 1e6;
    let r = if (x - g).abs() <= 8.0 * f64::EPSILON * x.abs().max(100.0) { g } else { x };
    if r == 0.0 { 0.0 } else { r }
}

/// The unit vector of the first candidate with a usable component normal to `z`.
fn perp_unit(z: &Vector3<f64>, candidates: &[Vector3<f64>]) -> Vector3<f64> {
    for c in candidates {
        let v = c - z * z.dot(c);
        let n = v.norm();
        if n > 1e-6 {
            return v / n;
        }
    }
    // unreachable for a unit z (x and y of the base frame cannot both be parallel to it)
    let v = z.cross(&Vector3::x()) + z.cross(&Vector3::y());
    v / v.norm()
}

/// The point of `line` closest to `p`.
fn project(p: &Vector3<f64>, line: &Line) -> Vector3<f64> {
    line.point + line.dir * line.dir.dot(&(p - line.point))
}

/// A frame from its origin, x axis and z axis (unit, orthogonal).
fn frame_from(o: Vector3<f64>, x: Vector3<f64>, z: Vector3<f64>) -> Frame {
    let y = z.cross(&x);
    Frame { r: nalgebra::Matrix3::from_columns(&[x, y, z]), p: o }
}

/// Origin and x axis of frame i from axes i and i+1, and the point where the x line meets axis
/// i+1 (the preferred origin of frame i+1).
fn pair_frame(
    ai: &Line,
    aj: &Line,
    preferred: &Vector3<f64>,
    x_hints: &[Vector3<f64>],
    tol_sin: f64,
) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let (z, u) = (ai.dir, aj.dir);
    let n = z.cross(&u);
    let s = n.norm();
    if s > tol_sin {
        // classic MDH: common normal
        let nh = n / s;
        let w = ai.point - aj.point;
        let (b, d, e) = (z.dot(&u), z.dot(&w), u.dot(&w));
        let den = 1.0 - b * b;
        let fi = ai.point + z * ((b * e - d) / den);
        let fj = aj.point + u * ((e - b * d) / den);
        let v = fj - fi;
        // skew axes: x from axis i towards axis i+1 (a >= 0); intersecting axes: the sense
        // closest to the hint (the previous x axis, or the base's x), for small theta offsets
        let reference = if v.norm() > 1e-9 { v } else { x_hints.first().copied().unwrap_or(nh) };
        let x = if reference.dot(&nh) < 0.0 { -nh } else { nh };
        (fi, x, fj)
    } else {
        // Hayati: keep the preferred origin, aim x at axis j's crossing of the x-y plane
        let o = project(preferred, ai);
        let t = -(aj.point - o).dot(&z) / u.dot(&z);
        let p = aj.point + u * t;
        let mut v = p - o;
        v -= z * z.dot(&v);
        let x = if v.norm() > 1e-9 { v / v.norm() } else { perp_unit(&z, x_hints) };
        (o, x, p)
    }
}

/// Forward kinematics of the URDF path (tip origin in the base-link frame), `q` internal units.
pub(crate) fn urdf_tip(steps: &[Step], q: &[f64]) -> Vector3<f64> {
    let mut x = Frame::identity();
    let mut k = 0;
    for s in steps {
        let mut f = s.origin;
        if let Some((kind, axis)) = s.motion {
            let m = match kind {
                JointKind::Revolute => Frame {
                    r: *Rotation3::from_axis_angle(&Unit::new_unchecked(axis), q[k]).matrix(),
                    p: Vector3::zeros(),
                },
                JointKind::Prismatic => Frame { r: nalgebra::Matrix3::identity(), p: axis * q[k] },
            };
            f = f.compose(&m);
            k += 1;
        }
        x = x.compose(&if s.reversed { f.inverse() } else { f });
    }
    x.p
}

/// Forward kinematics of the imported rows (file units in `chain`, `q` internal units).
pub(crate) fn chain_tip(chain: &ImportedChain, q: &[f64]) -> Vector3<f64> {
    let b = &chain.base_in_world;
    let mut x = Frame {
        r: rot_x(b.alpha_deg.to_radians()) * rot_y(b.beta_deg.to_radians()) * rot_z(b.gamma_deg.to_radians()),
        p: Vector3::new(b.x_mm, b.y_mm, b.z_mm),
    };
    for (j, qi) in chain.joints.iter().zip(q) {
        let (dt, dd) = match j.kind {
            JointKind::Revolute => (*qi, 0.0),
            JointKind::Prismatic => (0.0, *qi),
        };
        x = x.compose(&mdh_frame(
            j.alpha_deg.to_radians(),
            j.a_mm,
            j.beta_deg.to_radians(),
            j.theta_deg.to_radians() + dt,
            j.d_mm + dd,
        ));
    }
    x.transform_point(&Vector3::from(chain.tcp_mm))
}

/// The steps of the path (constant origins and motions) and its actuated joints, validated:
/// unsupported / mimic joints, unusable axes, origins and limits, and joint counts are errors.
pub(crate) fn path_steps(
    tree: &Tree<'_>,
    path: &[PathJoint],
    base: &str,
    tip: &str,
    text: &str,
    origin: &str,
) -> Result<(Vec<Step>, Vec<Actuated>), UrdfImportError> {
    let robot = tree.robot;
    let locate = |tag: &str, name: &str| match element_line(text, tag, name) {
        Some(line) => format!("{origin}:{line}"),
        None => origin.to_string(),
    };
    let invalid = |name: &str, reason: String| UrdfImportError::InvalidJoint {
        location: locate("joint", name),
        joint: name.to_string(),
        reason,
    };

    // 1. the joints of the path
    let mut steps = Vec::with_capacity(path.len());
    let mut rows = Vec::new();
    for &PathJoint { joint: ji, reversed } in path {
        let j = &robot.joints[ji];
        let (kind, continuous) = match j.joint_type {
            JointType::Revolute => (Some(JointKind::Revolute), false),
            JointType::Continuous => (Some(JointKind::Revolute), true),
            JointType::Prismatic => (Some(JointKind::Prismatic), false),
            JointType::Fixed => (None, false),
            JointType::Floating | JointType::Planar | JointType::Spherical => {
                return Err(UrdfImportError::UnsupportedJoint {
                    location: locate("joint", &j.name),
                    joint: j.name.clone(),
                    joint_type: format!("{:?}", j.joint_type).to_lowercase(),
                });
            }
        };
        if let (Some(_), Some(m)) = (kind, &j.mimic) {
            return Err(UrdfImportError::MimicJoint {
                location: locate("joint", &j.name),
                joint: j.name.clone(),
                mimicked: m.joint.clone(),
            });
        }
        if j.origin.xyz.iter().chain(j.origin.rpy.iter()).any(|v| !v.is_finite()) {
            return Err(invalid(&j.name, "<origin> has a non-finite value".into()));
        }
        let motion = match kind {
            None => None,
            Some(kind) => {
                let a = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
                let n = a.norm();
                if !(n.is_finite() && n > 1e-12) {
                    return Err(invalid(
                        &j.name,
                        format!("<axis xyz> {:?} is not a usable direction", j.axis.xyz.0),
                    ));
                }
                let (lo, hi) = (j.limit.lower, j.limit.upper);
                if lo.is_nan() || hi.is_nan() {
                    return Err(invalid(&j.name, "<limit> has a NaN bound".into()));
                }
                // URDF >= 1.2: omitted bounds mean unlimited
                let unbounded = lo == f64::NEG_INFINITY && hi == f64::INFINITY;
                let (q_min, q_max) = if continuous || (unbounded && kind == JointKind::Revolute) {
                    (None, None)
                } else if !(lo.is_finite() && hi.is_finite()) {
                    return Err(invalid(
                        &j.name,
                        format!("<limit> lower = {lo}, upper = {hi}: both bounds must be finite"),
                    ));
                } else if lo >= hi {
                    return Err(invalid(
                        &j.name,
                        format!(
                            "<limit> lower = {lo}, upper = {hi} is an empty range (missing <limit>? \
                             make a locked joint `fixed`)"
                        ),
                    ));
                } else if kind == JointKind::Revolute {
                    (Some(lo.to_degrees()), Some(hi.to_degrees()))
                } else {
                    (Some(lo * M_TO_MM), Some(hi * M_TO_MM))
                };
                rows.push(Actuated {
                    name: j.name.clone(),
                    child: if reversed { j.parent.link.clone() } else { j.child.link.clone() },
                    kind,
                    reversed,
                    continuous,
                    q_min,
                    q_max,
                    joint: ji,
                });
                Some((kind, a / n))
            }
        };
        steps.push(Step { origin: pose_frame(&j.origin), motion, reversed });
    }
    if rows.is_empty() || rows.len() > MAX_IMPORTED_JOINTS {
        return Err(UrdfImportError::JointCount {
            origin: origin.to_string(),
            base: base.to_string(),
            tip: tip.to_string(),
            count: rows.len(),
        });
    }
    Ok((steps, rows))
}

/// The conversion (see the crate docs). `path` = the joints from `base` to `tip`.
pub(crate) fn convert(
    tree: &Tree<'_>,
    path: &[PathJoint],
    base: &str,
    tip: &str,
    text: &str,
    origin: &str,
) -> Result<ImportedChain, UrdfImportError> {
    // 1. the steps from the base link to the tip link and the actuated joints among them
    let (steps, rows) = path_steps(tree, path, base, tip, text, origin)?;
    let n = rows.len();
    // 2. joint axes and tip pose at q = 0, in the base-link frame
    let (axes, tip_pose) = axes_at_zero(&steps, n);
    // 3. MDH frames 1..N at q = 0
    let frames = mdh_frames(&axes, &tip_pose);
    // 4. frame 0 = frame 1 at q = 0 (tilted by alpha_0 = 90° when z_1 lies near the base's x
    //    axis, so that the base angles stay far from gimbal lock)
    let alpha0 = if frames[0].z_axis().x.abs() > 0.7 { FRAC_PI_2 } else { 0.0 };
    let f0 = frames[0].compose(&Frame { r: rot_x(-alpha0), p: Vector3::zeros() });
    // 5. rows
    let joints = imported_joints(&rows, &f0, &frames);
    let tcp = frames[n - 1].inverse().transform_point(&tip_pose.p);
    // 6. inertials
    let frame_of_joint: HashMap<usize, usize> =
        rows.iter().enumerate().map(|(i, r)| (r.joint, i + 1)).collect();
    let carried = carried_links(tree, base, path, &frame_of_joint, origin)?;
    let (inertials, mut notes) = inertials(tree, &carried, &frames, text, origin)?;
    let link_radii_mm = link_radii(tree, &carried, n, text, origin, &mut notes)?;
    if let Some(note) = reversed_joints_note(&rows) {
        notes.insert(0, note);
    }
    let chain = ImportedChain {
        robot_name: tree.robot.name.clone(),
        base_link: base.to_string(),
        tip_link: tip.to_string(),
        joints,
        base_in_world: base_in_world(&f0),
        tcp_mm: [clean(tcp.x), clean(tcp.y), clean(tcp.z)],
        inertials,
        link_radii_mm,
        notes,
    };
    // 7. self-check against the URDF's own forward kinematics
    self_check(&steps, &chain, origin)?;
    Ok(chain)
}

/// The `n` joint axes and the tip pose at q = 0, in the base-link frame. A joint traversed up
/// the tree moves the rest of the chain by motion(-q) about its axis, i.e. by +q about the
/// opposite direction: z_i points against the URDF axis and q_i keeps the URDF's sign.
fn axes_at_zero(steps: &[Step], n: usize) -> (Vec<Line>, Frame) {
    let mut x = Frame::identity();
    let mut axes = Vec::with_capacity(n);
    for s in steps {
        if !s.reversed {
            x = x.compose(&s.origin);
        }
        if let Some((_, a)) = s.motion {
            let dir = x.r * a;
            axes.push(Line { point: x.p, dir: if s.reversed { -dir } else { dir } });
        }
        if s.reversed {
            x = x.compose(&s.origin.inverse());
        }
    }
    (axes, x)
}

/// The MDH frames 1..N at q = 0: each on its axis, its x axis along the common normal to the
/// next axis (the last one's origin the tip point's projection on its axis).
fn mdh_frames(axes: &[Line], tip_pose: &Frame) -> Vec<Frame> {
    let n = axes.len();
    let tol_sin = PARALLEL_AXES_TOLERANCE_DEG.to_radians().sin();
    let mut frames: Vec<Frame> = Vec::with_capacity(n);
    let mut preferred = axes[0].point;
    for i in 0..n {
        let z = axes[i].dir;
        let mut hints: Vec<Vector3<f64>> = frames.last().map(|f| f.x_axis()).into_iter().collect();
        if i + 1 < n {
            hints.extend([Vector3::x(), Vector3::y()]);
            let (o, xi, next) = pair_frame(&axes[i], &axes[i + 1], &preferred, &hints, tol_sin);
            frames.push(frame_from(o, xi, z));
            preferred = next;
        } else {
            let o = project(&tip_pose.p, &axes[i]);
            if tip_pose.z_axis().dot(&z).abs() > 1.0 - 1e-9 {
                hints.insert(0, tip_pose.x_axis());
            }
            hints.extend([Vector3::x(), Vector3::y()]);
            frames.push(frame_from(o, perp_unit(&z, &hints), z));
        }
    }
    frames
}

/// The MDH rows of the actuated joints: frame i relative to frame i - 1 (`f0` before the
/// first), rounded ([`clean`]).
fn imported_joints(rows: &[Actuated], f0: &Frame, frames: &[Frame]) -> Vec<ImportedJoint> {
    let mut joints = Vec::with_capacity(rows.len());
    for (i, r) in rows.iter().enumerate() {
        let prev = if i == 0 { f0 } else { &frames[i - 1] };
        let [alpha, a, beta, theta, d] = decompose(&prev.inverse().compose(&frames[i]));
        joints.push(ImportedJoint {
            name: r.name.clone(),
            child_link: r.child.clone(),
            reversed: r.reversed,
            kind: r.kind,
            continuous: r.continuous,
            alpha_deg: clean(alpha.to_degrees()),
            a_mm: clean(a),
            beta_deg: clean(beta.to_degrees()),
            theta_deg: clean(theta.to_degrees()),
            d_mm: clean(d),
            q_min: r.q_min.map(clean),
            q_max: r.q_max.map(clean),
        });
    }
    joints
}

/// Frame 0 in the base link's frame as the cell file's `[base_in_world]`.
fn base_in_world(f0: &Frame) -> BaseInWorld {
    let [ba, bb, bg] = xyz_euler(&f0.r);
    BaseInWorld {
        x_mm: clean(f0.p.x),
        y_mm: clean(f0.p.y),
        z_mm: clean(f0.p.z),
        alpha_deg: clean(ba.to_degrees()),
        beta_deg: clean(bb.to_degrees()),
        gamma_deg: clean(bg.to_degrees()),
    }
}

/// The note naming the joints the chain traverses up the tree (None when there are none).
fn reversed_joints_note(rows: &[Actuated]) -> Option<String> {
    let reversed: Vec<&str> = rows.iter().filter(|r| r.reversed).map(|r| r.name.as_str()).collect();
    (!reversed.is_empty()).then(|| {
        format!(
            "the chain goes up the tree through joint(s) {} (child to parent): their z axes point \
             against the URDF axes, so joint values stay the URDF joint positions",
            reversed.join(", ")
        )
    })
}

/// Compares the chain's tip with the URDF's own forward kinematics at q = 0 and three spread
/// postures: [`UrdfImportError::SelfCheck`] beyond [`SELF_CHECK_MM`].
fn self_check(steps: &[Step], chain: &ImportedChain, origin: &str) -> Result<(), UrdfImportError> {
    let mut worst: f64 = 0.0;
    for sample in 0..4 {
        let q: Vec<f64> = chain
            .joints
            .iter()
            .enumerate()
            .map(|(k, j)| {
                let s = if sample == 0 { 0.0 } else { (1.7 * (k + 1) as f64 * sample as f64).sin() };
                match j.kind {
                    JointKind::Revolute => 2.5 * s,
                    JointKind::Prismatic => 150.0 * s,
                }
            })
            .collect();
        worst = worst.max((urdf_tip(steps, &q) - chain_tip(chain, &q)).norm());
    }
    if worst.is_nan() || worst > SELF_CHECK_MM {
        return Err(UrdfImportError::SelfCheck { origin: origin.to_string(), deviation_mm: worst });
    }
    Ok(())
}

/// How a link moves relative to the base link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Carrier {
    /// with MDH frame `i` (0: fixed to the base link)
    Frame(usize),
    /// with a joint that is not on the chain (index into `robot.joints`)
    OffChain(usize),
}

/// A link of the tree seen from the base link: its pose at q = 0 (base-link frame, mm) and what
/// moves it.
#[derive(Debug, Clone)]
struct CarriedLink<'a> {
    name: &'a str,
    pose: Frame,
    carrier: Carrier,
}

/// The links the chain carries, seen from `base` (the tree re-rooted at the base link): the
/// subtree of `base` when the chain only goes down, every link connected to `base` when it goes
/// up (a humanoid standing on its sole carries the whole body). A link moves with the MDH frame
/// of the last actuated chain joint on its path from `base` when its path leaves the chain on
/// fixed joints only, and with an off-chain joint otherwise.
fn carried_links<'a>(
    tree: &Tree<'a>,
    base: &'a str,
    chain: &[PathJoint],
    frame_of_joint: &HashMap<usize, usize>,
    origin: &str,
) -> Result<Vec<CarriedLink<'a>>, UrdfImportError> {
    let robot = tree.robot;
    let names: Vec<&'a str> = if chain.iter().any(|p| p.reversed) {
        robot.links.iter().map(|l| l.name.as_str()).collect()
    } else {
        tree.subtree(base)
    };
    let mut out = Vec::with_capacity(names.len());
    for name in names {
        let Some(path) = tree.path_between(base, name, origin)? else { continue };
        let mut pose = Frame::identity();
        for p in &path {
            let o = pose_frame(&robot.joints[p.joint].origin);
            pose = pose.compose(&if p.reversed { o.inverse() } else { o });
        }
        let shared = path.iter().zip(chain).take_while(|(a, b)| a == b).count();
        let actuated = |p: &&PathJoint| robot.joints[p.joint].joint_type != JointType::Fixed;
        let carrier = match path[shared..].iter().rev().find(actuated) {
            Some(p) => Carrier::OffChain(p.joint),
            None => match path[..shared].iter().rev().find(actuated) {
                None => Carrier::Frame(0),
                Some(p) => match frame_of_joint.get(&p.joint) {
                    Some(&f) => Carrier::Frame(f),
                    None => Carrier::OffChain(p.joint), // unreachable: shared joints are the chain's
                },
            },
        };
        out.push(CarriedLink { name, pose, carrier });
    }
    Ok(out)
}

/// Radius (mm) of the capsule that covers a URDF collision primitive: a cylinder's or capsule's
/// radius, a sphere's radius, a box's half diagonal across its two smallest sides (the link
/// runs along the longest); `None` for a mesh.
fn primitive_radius_mm(g: &urdf_rs::Geometry) -> Option<f64> {
    match g {
        urdf_rs::Geometry::Cylinder { radius, .. }
        | urdf_rs::Geometry::Capsule { radius, .. }
        | urdf_rs::Geometry::Sphere { radius } => Some(radius * M_TO_MM),
        urdf_rs::Geometry::Box { size } => {
            let mut s = [size[0].abs(), size[1].abs(), size[2].abs()];
            s.sort_by(f64::total_cmp);
            Some(0.5 * s[0].hypot(s[1]) * M_TO_MM)
        }
        urdf_rs::Geometry::Mesh { .. } => None,
    }
}

/// Capsule radius per MDH link 0..N from the `<collision>` primitives (see the crate docs): the
/// largest primitive radius among the links that move with frame `i` (frame 0: the links fixed
/// to the base); `None` when no link on the chain has a primitive. A link with primitives only
/// on some frames gets [`DEFAULT_LINK_RADIUS_MM`](crate::DEFAULT_LINK_RADIUS_MM) on the others,
/// named in the notes.
fn link_radii(
    tree: &Tree<'_>,
    carried: &[CarriedLink<'_>],
    n: usize,
    text: &str,
    origin: &str,
    notes: &mut Vec<String>,
) -> Result<Option<Vec<f64>>, UrdfImportError> {
    let robot = tree.robot;
    let mut radii: Vec<Option<f64>> = vec![None; n + 1];
    let mut meshes = 0usize;
    for link in carried {
        let l = link.name;
        let Some(&li) = tree.link_index.get(l) else { continue };
        let Carrier::Frame(frame) = link.carrier else {
            continue; // moved by a joint off the chain (named in the mass notes)
        };
        for c in &robot.links[li].collision {
            let Some(r) = primitive_radius_mm(&c.geometry) else {
                meshes += 1;
                continue;
            };
            if !(r.is_finite() && r > 0.0) {
                return Err(UrdfImportError::InvalidLink {
                    location: match element_line(text, "link", l) {
                        Some(line) => format!("{origin}:{line}"),
                        None => origin.to_string(),
                    },
                    link: l.to_string(),
                    reason: format!("<collision> primitive with radius / size {r} mm: must be > 0"),
                });
            }
            let e = &mut radii[frame];
            *e = Some(e.map_or(r, |v: f64| v.max(r)));
        }
    }
    if meshes > 0 {
        notes.push(format!(
            "{meshes} <collision> mesh(es) give no link radius (only cylinders, capsules, spheres and boxes do)"
        ));
    }
    if radii.iter().all(Option::is_none) {
        return Ok(None);
    }
    let missing: Vec<String> =
        radii.iter().enumerate().filter(|(_, r)| r.is_none()).map(|(k, _)| k.to_string()).collect();
    if !missing.is_empty() {
        notes.push(format!(
            "links {} have no <collision> primitive: capsule radius {} mm (the planner's default)",
            missing.join(", "),
            crate::DEFAULT_LINK_RADIUS_MM
        ));
    }
    Ok(Some(radii.into_iter().map(|r| clean(r.unwrap_or(crate::DEFAULT_LINK_RADIUS_MM))).collect()))
}

/// Masses and COMs per MDH frame (see the crate docs), and notes on what was left out.
fn inertials(
    tree: &Tree<'_>,
    carried: &[CarriedLink<'_>],
    frames: &[Frame],
    text: &str,
    origin: &str,
) -> Result<(Vec<LinkInertial>, Vec<String>), UrdfImportError> {
    let robot = tree.robot;
    let mut notes = Vec::new();
    // frame → (mass, mass-weighted COM in the base-link frame, link names)
    let mut acc: BTreeMap<usize, (f64, Vector3<f64>, Vec<String>)> = BTreeMap::new();
    for carried_link in carried {
        let l = carried_link.name;
        let Some(&li) = tree.link_index.get(l) else { continue };
        let link = &robot.links[li];
        let m = link.inertial.mass.value;
        let c = &link.inertial.origin.xyz;
        let bad = |reason: String| UrdfImportError::InvalidLink {
            location: match element_line(text, "link", l) {
                Some(line) => format!("{origin}:{line}"),
                None => origin.to_string(),
            },
            link: l.to_string(),
            reason,
        };
        if !(m.is_finite() && m >= 0.0) {
            return Err(bad(format!("<mass value> {m} must be a finite number >= 0")));
        }
        if m == 0.0 {
            continue;
        }
        if c.iter().any(|v| !v.is_finite()) {
            return Err(bad("<inertial><origin xyz> has a non-finite value".into()));
        }
        let frame = match carried_link.carrier {
            Carrier::Frame(0) => continue, // fixed to the base
            Carrier::Frame(f) => f,
            Carrier::OffChain(j) => {
                notes.push(format!(
                    "link `{l}` ({m} kg) moves with joint `{}`, which is not on the chain: its mass is left out",
                    robot.joints[j].name
                ));
                continue;
            }
        };
        let pose = &carried_link.pose;
        let com_b = pose.transform_point(&(Vector3::new(c[0], c[1], c[2]) * M_TO_MM));
        let e = acc.entry(frame).or_insert((0.0, Vector3::zeros(), Vec::new()));
        e.0 += m;
        e.1 += com_b * m;
        e.2.push(l.to_string());
    }
    let mut out = Vec::new();
    for (frame, (m, mc, names)) in acc {
        let com = frames[frame - 1].inverse().transform_point(&(mc / m));
        if names.len() > 1 {
            notes.push(format!("frame {frame} carries the lumped masses of links {}", names.join(", ")));
        }
        out.push(LinkInertial {
            frame: frame as u8,
            urdf_link: Some(names.join("+")),
            mass_kg: m,
            com_mm: [clean(com.x), clean(com.y), clean(com.z)],
        });
    }
    Ok((out, notes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decompose_inverts_mdh_frame() {
        for &(al, a, be, th, d) in
            &[(0.3, 12.0, 0.0, -1.2, 40.0), (-1.5, 0.0, 0.01, 2.9, -3.0), (3.1, 100.0, -0.2, 0.0, 0.0)]
        {
            let [al2, a2, be2, th2, d2] = decompose(&mdh_frame(al, a, be, th, d));
            for (x, y) in [(al, al2), (a, a2), (be, be2), (th, th2), (d, d2)] {
                assert!((x - y).abs() < 1e-12, "{x} vs {y}");
            }
        }
    }

    #[test]
    fn euler_round_trip() {
        let r = rot_x(0.4) * rot_y(-0.7) * rot_z(2.0);
        let [a, b, g] = xyz_euler(&r);
        assert!((a - 0.4).abs() < 1e-14 && (b + 0.7).abs() < 1e-14 && (g - 2.0).abs() < 1e-14);
    }

    #[test]
    fn clean_snaps_float_noise_only() {
        assert_eq!(clean(-90.00000000000001), -90.0);
        assert_eq!(clean(-1e-17), 0.0);
        assert!(clean(-0.0).is_sign_positive());
        assert_eq!(clean(0.0997 * 1000.0), 99.7);
        assert_eq!(clean(392.2000000000001), 392.2);
        assert_eq!(clean(1.25e-9), 1.25e-9);
        assert_eq!(clean(12.345678901234), 12.345678901234);
    }
}
