//! Collision checking of a joint vector against the cell (parry3d-f64).
//!
//! The robot bodies of [`crate::geometry`] are placed with the model's own chain (so a calibrated
//! model is checked with its calibrated frames), inflated by a safety margin, and tested against:
//!
//! * the fixed obstacles: guide box (frame 0), tank cylinder, floor half-space, and the TriCal
//!   cylinder below the calibration position(s) where the probe plate sits ([`ProbeState`]);
//! * each other (arm self-collision), for every pair of bodies whose links are not adjacent
//!   (link numbers differing by at least 2), except the two pairs that touch by construction at
//!   a joint (upper arm – forearm at the elbow corner, forearm – flange at the wrist centre).
//!   Bodies fixed to the same link never move relative to each other and are not tested.
//!
//! The ball whose centre is being placed on the probe origin touches the probe by design; a
//! [`ProbeState::Measuring`] state exempts exactly that ball from the TriCal test.
//!
//! # Any serial chain
//! On any chain other than the canonical cell the robot is a set of capsules built from the MDH
//! rows (radius of link k: `[obstacles.robot_links] link_radii_mm[k]`, one per link 0..N, else
//! `chain_link_radius_mm`, default 30 mm; see [`RobotLinkGeometry::chain_radius_mm`]): row i
//! (`Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)`) gives a capsule along its `a` offset (from the
//! origin of frame i-1 along x_{i-1}, moving with link i-1) and, on a revolute row, one along
//! its `d` offset (ending at the origin of frame i along z_i, moving with link i); offsets
//! under 1 mm give no capsule, and a prismatic row's `d` (its travel) none either (a guide
//! body is the cell's `[obstacles.guide]` box). The end-effector bodies are as on the canonical
//! cell, on link N. Bodies of links 0 and 1 sit on the mounting surface and are not tested
//! against the floor and the guide box. Self-collision is tested between bodies whose links
//! differ by at least 2, except pairs that touch at a joint they share: they touch in every one
//! of [`ALWAYS_TOUCHING_SAMPLES`] seeded random configurations (MoveIt's "always in collision"
//! rule) *and* an end of one body's axis stays, in all of them, at the same distance from an
//! end of the other's, close enough for the two to overlap there (the ends sit on the joint
//! axes between the bodies, like the elbow corner or the wrist centre of the canonical arm; a
//! body other than a capsule counts by its centre and bounding radius). A pair that merely
//! happens to touch in every sample (an oversized body) is still tested, so it shows up as
//! rejected poses instead of being silently skipped.
//! [`CollisionChecker::contacts`] lists every contact of a configuration with its depth and
//! [`CollisionChecker::self_collision_pairs`] the pairs tested (diagnostics: the example
//! `collision_breakdown` counts which pairs reject a cell's candidates).
//!
//! Each pair is first screened with bounding spheres / boxes; only overlapping candidates reach
//! parry's `intersection_test`. Shapes are built directly in world coordinates (capsules,
//! balls) or with a world pose converted from nalgebra through glamx (cylinders, boxes).

use nalgebra::{Matrix3, Vector3};
use parry3d_f64::math::{Pose, Vector};
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, Capsule, Cuboid, Cylinder, HalfSpace, Shape};
use vatcal_core::{Frame, JointVector};
use vatcal_kinematics::{Chain, Model};

use crate::error::PlanError;
use crate::geometry::CellGeometry;
#[cfg(doc)]
use crate::geometry::RobotLinkGeometry;
use vatcal_core::frame::{rot_x, rot_y};

/// Names of the robot and end-effector bodies, in body-index order (balls follow as
/// `ball{tcp}`).
pub const BODY_NAMES: [&str; 9] =
    ["base", "shoulder", "upper arm", "elbow", "forearm", "wrist", "flange", "tool changer", "plate"];

/// MDH link each named body moves with (B = 1: the carriage).
const BODY_LINKS: [u8; 9] = [1, 2, 3, 4, 5, 6, 7, 7, 7];

/// Random configurations in which a self-collision pair of a generic chain must touch to be
/// treated as touching by construction (and not tested).
pub const ALWAYS_TOUCHING_SAMPLES: usize = 24;

/// How much the distance between two body ends may change over the sampled configurations for
/// the ends to count as one joint the bodies share (mm; round-off only).
const SHARED_JOINT_TOLERANCE_MM: f64 = 1e-6;

/// A body of a generic chain's link capsules (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
enum ChainSegment {
    /// along the `a` offset of row `row` (moves with link `row - 1`)
    A { row: usize },
    /// along the `d` offset of revolute row `row` (moves with link `row`)
    D { row: usize },
}

/// Body layout of a generic chain.
#[derive(Debug, Clone)]
struct ChainLayout {
    segments: Vec<ChainSegment>,
    /// names of the segments, then the tool changer and the plate
    names: Vec<String>,
    /// link of every body (segments, tool changer, plate, then balls)
    links: Vec<usize>,
}

impl ChainLayout {
    fn new(model: &Model, tcps: usize) -> Self {
        let n = model.joint_count();
        let mut segments = Vec::new();
        let mut names = Vec::new();
        let mut links = Vec::new();
        for row in 1..=n {
            let r = model.row(row);
            if r.a.abs() >= 1.0 {
                segments.push(ChainSegment::A { row });
                names.push(format!("link {} (a_{})", row - 1, row - 1));
                links.push(row - 1);
            }
            if model.is_revolute(row) && r.d.abs() >= 1.0 {
                segments.push(ChainSegment::D { row });
                names.push(format!("link {row} (d_{row})"));
                links.push(row);
            }
        }
        names.push("tool changer".into());
        names.push("plate".into());
        links.extend([n, n]);
        links.extend(std::iter::repeat_n(n, tcps));
        Self { segments, names, links }
    }
}

/// Where the probe plate is while a joint vector is checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProbeState {
    /// No probe on the tank.
    Absent,
    /// Probe at calibration position `position`; every ball must stay clear of it.
    At {
        /// calibration position id
        position: u32,
    },
    /// Probe at `position` and ball `tcp` sits in it (measurement pose, final approach).
    Measuring {
        /// calibration position id
        position: u32,
        /// TCP id of the ball on the probe origin
        tcp: u32,
    },
    /// A probe at every calibration position at once (poses where the operator may re-place
    /// the plate while the robot waits).
    Everywhere,
}

/// The two bodies found in contact.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Contact {
    /// first body (robot / end-effector)
    pub body: String,
    /// second body (robot, end-effector or obstacle)
    pub other: String,
}

impl std::fmt::Display for Contact {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} hits {}", self.body, self.other)
    }
}

/// A concrete parry shape with its world pose and a bounding sphere.
#[derive(Debug, Clone)]
enum Placed {
    Capsule(Capsule),
    Ball(Ball, Pose),
    Cylinder(Cylinder, Pose),
    Cuboid(Cuboid, Pose),
}

impl Placed {
    fn parts(&self) -> (&dyn Shape, Pose) {
        match self {
            Placed::Capsule(c) => (c, Pose::IDENTITY),
            Placed::Ball(b, p) => (b, *p),
            Placed::Cylinder(c, p) => (c, *p),
            Placed::Cuboid(c, p) => (c, *p),
        }
    }
}

#[derive(Debug, Clone)]
struct Body {
    shape: Placed,
    center: Vector3<f64>,
    radius: f64,
    /// TCP id for balls
    tcp: Option<u32>,
}

/// An axis-aligned bounding box in the world.
#[derive(Debug, Clone, Copy)]
struct WorldAabb {
    min: Vector3<f64>,
    max: Vector3<f64>,
}

impl WorldAabb {
    fn separated_from_sphere(&self, c: &Vector3<f64>, r: f64) -> bool {
        let mut d2 = 0.0;
        for k in 0..3 {
            let v = if c[k] < self.min[k] {
                self.min[k] - c[k]
            } else if c[k] > self.max[k] {
                c[k] - self.max[k]
            } else {
                0.0
            };
            d2 += v * v;
        }
        d2 > r * r
    }
}

#[derive(Debug, Clone)]
struct Obstacle {
    name: String,
    shape: ObstacleShape,
    aabb: WorldAabb,
    /// calibration position id for TriCal placements
    probe_position: Option<u32>,
}

#[derive(Debug, Clone)]
enum ObstacleShape {
    Cylinder(Cylinder, Pose),
    Cuboid(Cuboid, Pose),
    Floor(HalfSpace, Pose),
}

impl ObstacleShape {
    fn parts(&self) -> (&dyn Shape, Pose) {
        match self {
            ObstacleShape::Cylinder(c, p) => (c, *p),
            ObstacleShape::Cuboid(c, p) => (c, *p),
            ObstacleShape::Floor(h, p) => (h, *p),
        }
    }
}

fn v(p: &Vector3<f64>) -> Vector {
    Vector::new(p.x, p.y, p.z)
}

fn pose(frame: &Frame) -> Pose {
    Pose::from(frame.to_isometry())
}

/// Rotation whose y axis is `axis_frame`'s z axis (parry cylinders are along y).
fn y_along_z(r: &Matrix3<f64>) -> Matrix3<f64> {
    r * rot_x(std::f64::consts::FRAC_PI_2)
}

/// Collision checker for one model and one cell geometry.
#[derive(Debug, Clone)]
pub struct CollisionChecker<'a> {
    model: &'a Model,
    geometry: CellGeometry,
    margin_mm: f64,
    obstacles: Vec<Obstacle>,
    self_pairs: Vec<(usize, usize)>,
    tcps: Vec<(u32, Vector3<f64>)>,
    /// body layout of a chain other than the canonical cell
    layout: Option<ChainLayout>,
}

impl<'a> CollisionChecker<'a> {
    /// Builds the checker. `margin_mm` inflates every robot and end-effector body (a safety
    /// distance to obstacles and between links).
    pub fn new(model: &'a Model, geometry: &CellGeometry, margin_mm: f64) -> Result<Self, PlanError> {
        if !(margin_mm.is_finite() && margin_mm >= 0.0) {
            return Err(PlanError::Option {
                option: "collision margin".into(),
                reason: format!("must be a finite length >= 0, got {margin_mm}"),
            });
        }
        geometry.validate()?;
        let tcps: Vec<(u32, Vector3<f64>)> =
            model.tcp_ids().into_iter().filter_map(|id| model.tcp(id).map(|t| (id, t))).collect();
        let obstacles = build_obstacles(model, geometry);
        if !model.is_meca500_on_guide() {
            geometry.robot.check_link_count(model.joint_count())?;
            return Ok(Self::for_any_chain(model, geometry, margin_mm, obstacles, tcps));
        }
        let n_bodies = BODY_NAMES.len() + tcps.len();
        let link = |i: usize| if i < BODY_LINKS.len() { BODY_LINKS[i] } else { 7 };
        let mut self_pairs = Vec::new();
        for i in 0..n_bodies {
            for j in i + 1..n_bodies {
                let (li, lj) = (link(i), link(j));
                let skip = li.abs_diff(lj) < 2 || (li, lj) == (3, 5) || (li, lj) == (5, 7);
                if !skip {
                    self_pairs.push((i, j));
                }
            }
        }
        Ok(Self { model, geometry: geometry.clone(), margin_mm, obstacles, self_pairs, tcps, layout: None })
    }

    /// The checker of a chain other than the canonical cell (see the module docs).
    fn for_any_chain(
        model: &'a Model,
        geometry: &CellGeometry,
        margin_mm: f64,
        obstacles: Vec<Obstacle>,
        tcps: Vec<(u32, Vector3<f64>)>,
    ) -> Self {
        use rand::{RngExt, SeedableRng};
        let layout = ChainLayout::new(model, tcps.len());
        let mut me = Self {
            model,
            geometry: geometry.clone(),
            margin_mm,
            obstacles,
            self_pairs: Vec::new(),
            tcps,
            layout: Some(layout.clone()),
        };
        let n_bodies = layout.links.len();
        let mut pairs: Vec<(usize, usize)> = Vec::new();
        for i in 0..n_bodies {
            for j in i + 1..n_bodies {
                if layout.links[i].abs_diff(layout.links[j]) >= 2 {
                    pairs.push((i, j));
                }
            }
        }
        // drop the pairs that touch at a joint they share: in every sampled configuration they
        // touch, and some end of one is at the same distance from some end of the other (a point
        // on the joint axes between them, which no joint moves relative to the other body)
        let mut always = vec![true; pairs.len()];
        // per pair: distances of every (end of i, end of j) at the first sample, and whether
        // each has stayed the same since
        let mut anchors: Vec<Vec<(f64, bool)>> = vec![Vec::new(); pairs.len()];
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(0x5eed);
        for sample in 0..ALWAYS_TOUCHING_SAMPLES {
            let mut q = JointVector::zeros(model.joint_count());
            for (k, (lo, hi)) in model.joint_limits().iter().enumerate() {
                q[k] = if hi > lo { rng.random_range(*lo..*hi) } else { *lo };
            }
            let bodies = me.bodies(&model.chain(&q));
            for ((a, fixed), &(i, j)) in always.iter_mut().zip(anchors.iter_mut()).zip(&pairs) {
                if !*a {
                    continue;
                }
                if !bodies_intersect(&bodies[i], &bodies[j]) {
                    *a = false;
                    continue;
                }
                let ((ei, ri), (ej, rj)) = (ends(&bodies[i]), ends(&bodies[j]));
                let d = ei.iter().flat_map(|p| ej.iter().map(move |r| (p - r).norm()));
                if sample == 0 {
                    // only ends close enough for the two bodies to overlap there
                    *fixed = d.map(|d| (d, d <= ri + rj)).collect();
                } else {
                    for ((d0, same), d) in fixed.iter_mut().zip(d) {
                        *same &= (d - *d0).abs() <= SHARED_JOINT_TOLERANCE_MM;
                    }
                }
            }
        }
        let shared = |(a, fixed): (&bool, &Vec<(f64, bool)>)| *a && fixed.iter().any(|(_, same)| *same);
        me.self_pairs = pairs
            .into_iter()
            .zip(always.iter().zip(&anchors))
            .filter(|(_, touch)| !shared(*touch))
            .map(|(p, _)| p)
            .collect();
        me
    }

    /// The pairs of bodies tested for self-collision, by name (see the module docs for the rule).
    pub fn self_collision_pairs(&self) -> Vec<(String, String)> {
        self.self_pairs.iter().map(|&(i, j)| (self.body_name(i), self.body_name(j))).collect()
    }

    /// The model whose chain places the bodies.
    pub fn model(&self) -> &'a Model {
        self.model
    }

    /// The safety margin (mm).
    pub fn margin_mm(&self) -> f64 {
        self.margin_mm
    }

    /// Name of body `i`.
    fn body_name(&self, i: usize) -> String {
        if let Some(layout) = &self.layout {
            return match layout.names.get(i) {
                Some(n) => n.clone(),
                None => format!("ball{}", self.tcps.get(i - layout.names.len()).map_or(0, |t| t.0)),
            };
        }
        match BODY_NAMES.get(i) {
            Some(n) => (*n).to_string(),
            None => format!("ball{}", self.tcps.get(i - BODY_NAMES.len()).map_or(0, |t| t.0)),
        }
    }

    /// Places every body for `chain`.
    fn bodies(&self, chain: &Chain) -> Vec<Body> {
        if let Some(layout) = &self.layout {
            return self.chain_bodies(layout, chain);
        }
        let m = self.margin_mm;
        let r = &self.geometry.robot;
        let f = &chain.frames;
        let row2 = self.model.row(2);
        let base = f[1]
            .compose(&Frame { r: rot_x(row2.alpha) * rot_y(row2.beta), p: Vector3::new(row2.a, 0.0, 0.0) });
        let mut out = Vec::with_capacity(BODY_NAMES.len() + self.tcps.len());
        let capsule = |a: Vector3<f64>, b: Vector3<f64>, radius: f64| Body {
            shape: Placed::Capsule(Capsule::new(v(&a), v(&b), radius + m)),
            center: 0.5 * (a + b),
            radius: 0.5 * (b - a).norm() + radius + m,
            tcp: None,
        };
        // base: cylinder on z_B from the mounting face
        out.push(placed_cylinder(&base, 0.0, r.base_height_mm, r.base_radius_mm, m));
        // shoulder: capsule on the J2 axis (z_3) through the shoulder
        let (o3, z3) = (f[3].p, f[3].z_axis());
        let sh = r.shoulder_half_length_mm;
        out.push(capsule(o3 - z3 * sh, o3 + z3 * sh, r.shoulder_radius_mm));
        // upper arm
        out.push(capsule(o3, f[4].p, r.upper_arm_radius_mm));
        // elbow: J3 axis to the elbow corner; forearm: corner to the wrist centre
        let corner = f[5].p - f[5].z_axis() * self.model.row(5).d;
        out.push(capsule(f[4].p, corner, r.elbow_radius_mm));
        out.push(capsule(corner, f[5].p, r.forearm_radius_mm));
        // wrist: capsule on the J5 axis through the wrist centre
        let (o6, z6) = (f[6].p, f[6].z_axis());
        let wh = r.wrist_half_length_mm;
        out.push(capsule(o6 - z6 * wh, o6 + z6 * wh, r.wrist_radius_mm));
        // flange: wrist centre to the flange face
        out.push(capsule(o6, f[7].p, r.flange_radius_mm));
        self.end_effector_bodies(&chain.tool, &mut out);
        out
    }

    /// The tool changer, the plate and the balls (tool frame), appended to `out`.
    fn end_effector_bodies(&self, tool: &Frame, out: &mut Vec<Body>) {
        let m = self.margin_mm;
        let e = &self.geometry.end_effector;
        out.push(placed_cylinder(tool, 0.0, e.tool_changer_length_mm, e.tool_changer_radius_mm, m));
        let half = Vector3::from(e.plate_half_extents_mm).add_scalar(m);
        let plate_center = tool.transform_point(&self.geometry.plate_center());
        out.push(Body {
            shape: Placed::Cuboid(Cuboid::new(v(&half)), pose(&Frame { r: tool.r, p: plate_center })),
            center: plate_center,
            radius: half.norm(),
            tcp: None,
        });
        for (id, t) in &self.tcps {
            let c = tool.transform_point(t);
            let rr = e.ball_radius_mm + m;
            out.push(Body {
                shape: Placed::Ball(Ball::new(rr), Pose::from_translation(v(&c))),
                center: c,
                radius: rr,
                tcp: Some(*id),
            });
        }
    }

    /// The bodies of a generic chain (see the module docs).
    fn chain_bodies(&self, layout: &ChainLayout, chain: &Chain) -> Vec<Body> {
        let f = &chain.frames;
        let mut out = Vec::with_capacity(layout.links.len());
        for (seg, link) in layout.segments.iter().zip(&layout.links) {
            let radius = self.geometry.robot.chain_radius_mm(*link) + self.margin_mm;
            let (a, b) = match *seg {
                ChainSegment::A { row } => {
                    let o = f[row - 1].p;
                    (o, o + f[row - 1].r.column(0) * self.model.row(row).a)
                }
                ChainSegment::D { row } => {
                    let o = f[row].p;
                    (o - f[row].z_axis() * self.model.row(row).d, o)
                }
            };
            out.push(Body {
                shape: Placed::Capsule(Capsule::new(v(&a), v(&b), radius)),
                center: 0.5 * (a + b),
                radius: 0.5 * (b - a).norm() + radius,
                tcp: None,
            });
        }
        self.end_effector_bodies(&chain.tool, &mut out);
        out
    }

    /// True when body `i` sits on the mounting surface (not tested against the floor and the
    /// guide box): the canonical base, or a body of link 0 or 1 of a generic chain.
    fn mounted(&self, i: usize) -> bool {
        match &self.layout {
            Some(layout) => layout.links.get(i).is_some_and(|l| *l <= 1),
            None => i == 0,
        }
    }

    /// The first contact at `q` with the probe in state `probe`, or `None` when collision-free.
    pub fn check(&self, q: &JointVector, probe: ProbeState) -> Option<Contact> {
        let chain = self.model.chain(q);
        self.check_chain(&chain, probe)
    }

    /// True when `q` is collision-free.
    pub fn is_free(&self, q: &JointVector, probe: ProbeState) -> bool {
        self.check(q, probe).is_none()
    }

    /// [`CollisionChecker::check`] for an already computed chain.
    pub fn check_chain(&self, chain: &Chain, probe: ProbeState) -> Option<Contact> {
        let mut first = None;
        self.scan(chain, probe, |i, other| {
            first = Some(Contact { body: self.body_name(i), other: other.name(self) });
            true
        });
        first
    }

    /// Every contact at `chain` with the probe in state `probe` (not only the first one), each
    /// with its penetration depth (mm, the margin included; 0 where parry gives none): a
    /// diagnostic of which pairs reject a pose, in the order [`CollisionChecker::check_chain`]
    /// tests them.
    pub fn contacts(&self, chain: &Chain, probe: ProbeState) -> Vec<(Contact, f64)> {
        let bodies = self.bodies(chain);
        let mut out = Vec::new();
        self.scan_bodies(&bodies, probe, |i, other| {
            let (sa, pa) = bodies[i].shape.parts();
            let (sb, pb) = match other {
                Other::Obstacle(k) => self.obstacles[k].shape.parts(),
                Other::Body(j) => bodies[j].shape.parts(),
            };
            // the obstacle first: parry 0.31 gives a cuboid's depth in the floor half-space wrong
            // the other way round (checked against the cuboid's lowest corner)
            let depth = query::contact(&pb, sb, &pa, sa, 0.0).ok().flatten().map_or(0.0, |c| -c.dist);
            out.push((Contact { body: self.body_name(i), other: other.name(self) }, depth));
            false
        });
        out
    }

    /// Calls `hit(body, other)` for every contact, in the checking order, until it returns true.
    fn scan(&self, chain: &Chain, probe: ProbeState, hit: impl FnMut(usize, Other) -> bool) {
        let bodies = self.bodies(chain);
        self.scan_bodies(&bodies, probe, hit);
    }

    fn scan_bodies(&self, bodies: &[Body], probe: ProbeState, mut hit: impl FnMut(usize, Other) -> bool) {
        for (k, obstacle) in self.obstacles.iter().enumerate() {
            if let Some(pos) = obstacle.probe_position {
                let present = match probe {
                    ProbeState::Absent => false,
                    ProbeState::Everywhere => true,
                    ProbeState::At { position } | ProbeState::Measuring { position, .. } => position == pos,
                };
                if !present {
                    continue;
                }
            }
            let (shape_o, pose_o) = obstacle.shape.parts();
            for (i, b) in bodies.iter().enumerate() {
                if self.mounted(i)
                    && (obstacle.name == "guide" || (self.layout.is_some() && obstacle.name == "floor"))
                {
                    // the base is bolted to the carriage (part of the guide box) / the table
                    continue;
                }
                if obstacle.probe_position.is_some()
                    && let ProbeState::Measuring { tcp, .. } = probe
                    && b.tcp == Some(tcp)
                {
                    continue;
                }
                if obstacle.aabb.separated_from_sphere(&b.center, b.radius) {
                    continue;
                }
                let (shape_b, pose_b) = b.shape.parts();
                if intersects(&pose_b, shape_b, &pose_o, shape_o) && hit(i, Other::Obstacle(k)) {
                    return;
                }
            }
        }
        for &(i, j) in &self.self_pairs {
            if bodies_intersect(&bodies[i], &bodies[j]) && hit(i, Other::Body(j)) {
                return;
            }
        }
    }
}

/// The second party of a contact: an obstacle or a body (indices).
#[derive(Debug, Clone, Copy)]
enum Other {
    Obstacle(usize),
    Body(usize),
}

impl Other {
    fn name(self, checker: &CollisionChecker<'_>) -> String {
        match self {
            Other::Obstacle(k) => checker.obstacles[k].name.clone(),
            Other::Body(j) => checker.body_name(j),
        }
    }
}

/// The ends of a body's axis for the shared-joint rule of a generic chain and the body's reach
/// around them: a capsule's two segment ends and its radius, the centre and bounding radius of
/// any other body.
fn ends(b: &Body) -> (Vec<Vector3<f64>>, f64) {
    match &b.shape {
        Placed::Capsule(c) => {
            let (a, e) = (c.segment.a, c.segment.b);
            (vec![Vector3::new(a.x, a.y, a.z), Vector3::new(e.x, e.y, e.z)], c.radius)
        }
        _ => (vec![b.center], b.radius),
    }
}

/// Bounding-sphere screen, then parry's intersection test.
fn bodies_intersect(a: &Body, b: &Body) -> bool {
    if (a.center - b.center).norm() > a.radius + b.radius {
        return false;
    }
    let (sa, pa) = a.shape.parts();
    let (sb, pb) = b.shape.parts();
    intersects(&pa, sa, &pb, sb)
}

/// A cylinder on `frame`'s z axis from `from` over `length`, inflated by `margin`.
fn placed_cylinder(frame: &Frame, from: f64, length: f64, radius: f64, margin: f64) -> Body {
    let center = frame.p + frame.z_axis() * (from + 0.5 * length);
    let half = 0.5 * length + margin;
    let rr = radius + margin;
    Body {
        shape: Placed::Cylinder(Cylinder::new(half, rr), pose(&Frame { r: y_along_z(&frame.r), p: center })),
        center,
        radius: half.hypot(rr),
        tcp: None,
    }
}

/// parry intersection test; an unsupported pair (cannot happen with the `alloc` feature and
/// these convex shapes) is treated as a collision, the safe side.
fn intersects(p1: &Pose, s1: &dyn Shape, p2: &Pose, s2: &dyn Shape) -> bool {
    query::intersection_test(p1, s1, p2, s2).map_or(true, |r| r.intersecting)
}

fn build_obstacles(model: &Model, g: &CellGeometry) -> Vec<Obstacle> {
    let mut out = Vec::new();
    let vertical =
        |name: String, x: f64, y: f64, c: &vatcal_core::cell::CylinderObstacle, probe: Option<u32>| {
            let half = 0.5 * (c.z_max_mm - c.z_min_mm);
            let center = Vector3::new(x, y, 0.5 * (c.z_max_mm + c.z_min_mm));
            Obstacle {
                name,
                shape: ObstacleShape::Cylinder(
                    Cylinder::new(half, c.radius_mm),
                    pose(&Frame { r: y_along_z(&Matrix3::identity()), p: center }),
                ),
                aabb: WorldAabb {
                    min: Vector3::new(x - c.radius_mm, y - c.radius_mm, c.z_min_mm),
                    max: Vector3::new(x + c.radius_mm, y + c.radius_mm, c.z_max_mm),
                },
                probe_position: probe,
            }
        };
    if let Some(t) = &g.tank {
        out.push(vertical("tank".into(), 0.0, 0.0, t, None));
    }
    if let Some(t) = &g.trical {
        for id in model.position_ids() {
            if let Some(p) = model.position(id) {
                out.push(vertical(format!("TriCal at position {id}"), p.x, p.y, t, Some(id)));
            }
        }
    }
    if let Some(b) = &g.guide {
        let base = model.base_frame();
        let lo = Vector3::new(b.x_min_mm, b.y_min_mm, b.z_min_mm);
        let hi = Vector3::new(b.x_max_mm, b.y_max_mm, b.z_max_mm);
        let half = 0.5 * (hi - lo);
        let center = base.transform_point(&(0.5 * (hi + lo)));
        let extent = base.r.abs() * half;
        out.push(Obstacle {
            name: "guide".into(),
            shape: ObstacleShape::Cuboid(Cuboid::new(v(&half)), pose(&Frame { r: base.r, p: center })),
            aabb: WorldAabb { min: center - extent, max: center + extent },
            probe_position: None,
        });
    }
    if let Some(f) = &g.floor {
        out.push(Obstacle {
            name: "floor".into(),
            shape: ObstacleShape::Floor(
                HalfSpace::new(Vector::new(0.0, 0.0, 1.0)),
                Pose::translation(0.0, 0.0, f.z_mm),
            ),
            aabb: WorldAabb {
                min: Vector3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
                max: Vector3::new(f64::INFINITY, f64::INFINITY, f.z_mm),
            },
            probe_position: None,
        });
    }
    out
}
