//! Collision-free joint-space paths between two configurations.
//!
//! 1. The straight joint-space segment is tried first: it is accepted when every configuration
//!    at the [`Resolution`] (default: ≤ 1° per arm joint and ≤ 1 mm of guide between checks, both
//!    ends included) is collision-free.
//! 2. Otherwise a seeded **RRT-Connect** grows two trees in joint space (within the joint limits
//!    shrunk by the planning margins) from the start and the goal; each extension is a straight
//!    segment checked at the same resolution. Distances are measured in time
//!    (`sqrt(Σ (Δq_j / v_j)²)` with the effective joint speeds), so the guide and the wrist are
//!    weighed by how long they take to move.
//! 3. The path found is **shortcut**: random pairs of points along it are joined by a straight
//!    segment whenever that segment is free and faster, which removes the RRT's detours; a
//!    final greedy pass jumps from each kept waypoint to the farthest one a free segment
//!    reaches.
//! 4. Every segment of the final path is verified again at the resolution before the path is
//!    returned; a path that fails (cannot happen unless the checker is non-deterministic) is an
//!    error, never returned.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use vatcal_core::JointVector;

use crate::collision::{CollisionChecker, Contact, ProbeState};
use crate::motion::{JointBounds, MotionTimer, Resolution, interpolate};

/// How a path was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PathMethod {
    /// the straight joint-space segment was free
    Straight,
    /// RRT-Connect + shortcutting
    RrtConnect,
}

/// A verified collision-free path.
#[derive(Debug, Clone, PartialEq)]
pub struct JointPath {
    /// waypoints from start to goal (both included); consecutive waypoints are joined by
    /// straight joint-space segments
    pub waypoints: Vec<JointVector>,
    /// how it was found
    pub method: PathMethod,
}

/// Why no path was found.
#[derive(Debug, Clone, PartialEq)]
pub enum PathFailure {
    /// the start configuration is in collision
    StartInCollision(Contact),
    /// the goal configuration is in collision
    GoalInCollision(Contact),
    /// start or goal outside the planning bounds
    OutOfBounds(&'static str),
    /// RRT-Connect used its whole budget
    Exhausted {
        /// iterations used
        iterations: usize,
    },
}

impl std::fmt::Display for PathFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PathFailure::StartInCollision(c) => write!(f, "start configuration in collision ({c})"),
            PathFailure::GoalInCollision(c) => write!(f, "goal configuration in collision ({c})"),
            PathFailure::OutOfBounds(which) => write!(f, "{which} configuration outside the joint limits"),
            PathFailure::Exhausted { iterations } => {
                write!(f, "RRT-Connect found no path in {iterations} iterations")
            }
        }
    }
}

/// Options of the path planner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathOptions {
    /// collision-check resolution along segments
    pub resolution: Resolution,
    /// RRT-Connect iteration budget (one sample per iteration)
    pub max_iterations: usize,
    /// largest RRT extension, in seconds of motion at the effective speeds
    pub step_s: f64,
    /// shortcutting attempts
    pub shortcut_attempts: usize,
}

impl Default for PathOptions {
    fn default() -> Self {
        Self { resolution: Resolution::default(), max_iterations: 4000, step_s: 0.25, shortcut_attempts: 150 }
    }
}

/// Checks the straight segment `a → b` at `resolution`; returns the first contact found.
pub fn segment_contact(
    checker: &CollisionChecker<'_>,
    a: &JointVector,
    b: &JointVector,
    probe: ProbeState,
    resolution: &Resolution,
) -> Option<Contact> {
    let n = resolution.intervals_for(a, b, checker.model().joint_kinds());
    (0..=n).find_map(|i| checker.check(&interpolate(a, b, i as f64 / n as f64), probe))
}

/// True when the straight segment `a → b` is collision-free at `resolution`.
pub fn segment_is_free(
    checker: &CollisionChecker<'_>,
    a: &JointVector,
    b: &JointVector,
    probe: ProbeState,
    resolution: &Resolution,
) -> bool {
    segment_contact(checker, a, b, probe, resolution).is_none()
}

/// A path planner: the collision checker, the joint bounds RRT samples in, the motion-time
/// model used as metric, and the options.
#[derive(Debug, Clone, Copy)]
pub struct PathPlanner<'c, 'm> {
    /// collision checker
    pub checker: &'c CollisionChecker<'m>,
    /// joint bounds of the RRT samples
    pub bounds: &'c JointBounds,
    /// motion-time model (metric of the RRT)
    pub timer: &'c MotionTimer,
    /// options
    pub opts: &'c PathOptions,
}

impl PathPlanner<'_, '_> {
    /// Plans a collision-free path from `start` to `goal` with the probe in state `probe`
    /// (see the module docs); `seed` seeds the RRT.
    pub fn plan(
        &self,
        start: &JointVector,
        goal: &JointVector,
        probe: ProbeState,
        seed: u64,
    ) -> Result<JointPath, PathFailure> {
        let (checker, bounds, opts) = (self.checker, self.bounds, self.opts);
        if let Some(c) = checker.check(start, probe) {
            return Err(PathFailure::StartInCollision(c));
        }
        if let Some(c) = checker.check(goal, probe) {
            return Err(PathFailure::GoalInCollision(c));
        }
        if segment_is_free(checker, start, goal, probe, &opts.resolution) {
            return Ok(JointPath { waypoints: vec![*start, *goal], method: PathMethod::Straight });
        }
        let slack = 1e-9;
        if !bounds.contains_with_slack(start, slack, slack) {
            return Err(PathFailure::OutOfBounds("start"));
        }
        if !bounds.contains_with_slack(goal, slack, slack) {
            return Err(PathFailure::OutOfBounds("goal"));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let planner = Rrt { checker, bounds, timer: self.timer, probe, opts };
        let raw = planner.connect(start, goal, &mut rng)?;
        let verified = |p: &[JointVector]| {
            p.windows(2).all(|w| segment_is_free(checker, &w[0], &w[1], probe, &opts.resolution))
        };
        let mut waypoints = planner.shortcut(raw.clone(), &mut rng);
        waypoints.dedup_by(|a, b| a == b);
        let waypoints = planner.skip_ahead(waypoints);
        if verified(&waypoints) {
            return Ok(JointPath { waypoints, method: PathMethod::RrtConnect });
        }
        // a shortcut endpoint fell between two checked samples of a tree edge: keep the raw path
        if verified(&raw) {
            return Ok(JointPath { waypoints: raw, method: PathMethod::RrtConnect });
        }
        Err(PathFailure::Exhausted { iterations: opts.max_iterations })
    }
}

#[derive(Debug, Clone, Copy)]
struct Node {
    q: JointVector,
    parent: usize,
}

struct Rrt<'c, 'm> {
    checker: &'c CollisionChecker<'m>,
    bounds: &'c JointBounds,
    timer: &'c MotionTimer,
    probe: ProbeState,
    opts: &'c PathOptions,
}

enum Extend {
    Reached(usize),
    Advanced(usize),
    Trapped,
}

impl Rrt<'_, '_> {
    fn distance(&self, a: &JointVector, b: &JointVector) -> f64 {
        let n = self.timer.joints.min(a.len()).min(b.len());
        (0..n).map(|k| ((b[k] - a[k]) / self.timer.speed[k]).powi(2)).sum::<f64>().sqrt()
    }

    fn sample(&self, rng: &mut ChaCha8Rng) -> JointVector {
        let mut q = JointVector::zeros(self.bounds.len);
        for (k, (lo, hi)) in self.bounds.as_slice().iter().enumerate() {
            q[k] = if hi > lo { rng.random_range(*lo..*hi) } else { *lo };
        }
        q
    }

    fn nearest(&self, tree: &[Node], q: &JointVector) -> usize {
        let mut best = (0, f64::INFINITY);
        for (i, n) in tree.iter().enumerate() {
            let d = self.distance(&n.q, q);
            if d < best.1 {
                best = (i, d);
            }
        }
        best.0
    }

    fn extend(&self, tree: &mut Vec<Node>, target: &JointVector) -> Extend {
        let near = self.nearest(tree, target);
        let from = tree[near].q;
        let d = self.distance(&from, target);
        let (to, reached) = if d <= self.opts.step_s {
            (*target, true)
        } else {
            (interpolate(&from, target, self.opts.step_s / d), false)
        };
        if !segment_is_free(self.checker, &from, &to, self.probe, &self.opts.resolution) {
            return Extend::Trapped;
        }
        tree.push(Node { q: to, parent: near });
        let idx = tree.len() - 1;
        if reached { Extend::Reached(idx) } else { Extend::Advanced(idx) }
    }

    fn connect_to(&self, tree: &mut Vec<Node>, target: &JointVector) -> Option<usize> {
        loop {
            match self.extend(tree, target) {
                Extend::Reached(i) => return Some(i),
                Extend::Advanced(_) => {}
                Extend::Trapped => return None,
            }
        }
    }

    fn branch(tree: &[Node], mut i: usize) -> Vec<JointVector> {
        let mut out = vec![tree[i].q];
        while i != 0 {
            i = tree[i].parent;
            out.push(tree[i].q);
        }
        out
    }

    fn connect(
        &self,
        start: &JointVector,
        goal: &JointVector,
        rng: &mut ChaCha8Rng,
    ) -> Result<Vec<JointVector>, PathFailure> {
        let mut a = vec![Node { q: *start, parent: 0 }];
        let mut b = vec![Node { q: *goal, parent: 0 }];
        let mut a_is_start = true;
        for _ in 0..self.opts.max_iterations {
            let sample = self.sample(rng);
            let new = match self.extend(&mut a, &sample) {
                Extend::Reached(i) | Extend::Advanced(i) => Some(i),
                Extend::Trapped => None,
            };
            if let Some(i) = new {
                let q_new = a[i].q;
                if let Some(j) = self.connect_to(&mut b, &q_new) {
                    let mut from_a = Self::branch(&a, i);
                    from_a.reverse();
                    let from_b = Self::branch(&b, j);
                    from_a.extend(from_b.into_iter().skip(1));
                    if !a_is_start {
                        from_a.reverse();
                    }
                    return Ok(from_a);
                }
            }
            std::mem::swap(&mut a, &mut b);
            a_is_start = !a_is_start;
        }
        Err(PathFailure::Exhausted { iterations: self.opts.max_iterations })
    }

    /// Greedy pass: from each kept waypoint jump to the farthest later waypoint that a free
    /// straight segment reaches.
    fn skip_ahead(&self, path: Vec<JointVector>) -> Vec<JointVector> {
        if path.len() < 3 {
            return path;
        }
        let mut out = vec![path[0]];
        let mut i = 0;
        while i + 1 < path.len() {
            let mut next = i + 1;
            for j in (i + 2..path.len()).rev() {
                if segment_is_free(self.checker, &path[i], &path[j], self.probe, &self.opts.resolution) {
                    next = j;
                    break;
                }
            }
            out.push(path[next]);
            i = next;
        }
        out
    }

    /// Random shortcutting: join two random points of the path (on its segments) when the
    /// straight segment between them is free.
    fn shortcut(&self, mut path: Vec<JointVector>, rng: &mut ChaCha8Rng) -> Vec<JointVector> {
        for _ in 0..self.opts.shortcut_attempts {
            if path.len() < 3 {
                break;
            }
            let n = path.len() - 1;
            let i = rng.random_range(0..n);
            let j = rng.random_range(0..n);
            let (i, j) = if i < j { (i, j) } else { (j, i) };
            if i == j {
                continue;
            }
            let ti: f64 = rng.random_range(0.0..1.0);
            let tj: f64 = rng.random_range(0.0..1.0);
            let qa = interpolate(&path[i], &path[i + 1], ti);
            let qb = interpolate(&path[j], &path[j + 1], tj);
            let old = self.timer.path_time_s(&[&[qa], &path[i + 1..=j], &[qb]].concat());
            if self.timer.move_time_s(&qa, &qb) >= old {
                continue;
            }
            if segment_is_free(self.checker, &qa, &qb, self.probe, &self.opts.resolution) {
                let mut next = path[..=i].to_vec();
                next.push(qa);
                next.push(qb);
                next.extend_from_slice(&path[j + 1..]);
                path = next;
            }
        }
        path
    }
}
