//! Measurements: what the cell recorded, in internal units.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::units::{JointVector, MAX_JOINTS};

/// Joint-motion directions of the canonical 7-joint Meca500-on-guide cell from the six arm
/// directions (J1..J6 = cell joints 2..7): index `i - 1` holds joint i, the guide (joint 1)
/// gets 0.
pub fn dirs_from_meca500_arm(arm: [i8; 6]) -> [i8; MAX_JOINTS] {
    let mut d = [0; MAX_JOINTS];
    d[1..7].copy_from_slice(&arm);
    d
}

/// Optional per-sample data that some effects need.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct MeasurementContext {
    /// sign (+1/-1, 0 = unknown) of the last motion of each joint before the record
    /// (`dir{i}` columns, revolute joints only); index `i - 1` is joint i, unused entries 0
    pub dir: Option<[i8; MAX_JOINTS]>,
    /// seconds since the campaign start
    pub time_s: Option<f64>,
    /// temperature \[°C\]
    pub temperature_c: Option<f64>,
}

impl MeasurementContext {
    /// Motion direction of joint `joint` (1-based): +1, -1, or 0 when unknown / not recorded.
    #[inline]
    pub fn dir_of(&self, joint: u8) -> i8 {
        match (self.dir, (joint as usize).checked_sub(1)) {
            (Some(d), Some(k)) if k < MAX_JOINTS => d[k],
            _ => 0,
        }
    }
}

/// What a measurement observed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Target {
    /// The TCP sat on the probe origin at calibration position `position` (residual
    /// `calibration_position - FK`).
    Probe {
        /// calibration position id
        position: u32,
    },
    /// The TCP was measured at `xyz_mm` in the world frame (residual `measured - FK`).
    Tracker {
        /// measured world position \[mm\]
        xyz_mm: Vector3<f64>,
    },
    /// The orientation of the tool-changer frame (the marker body of a pose row) was measured
    /// as `rotation` in the world frame (residual: the rotation vector
    /// `log(R_measured · R_modelᵀ)` \[rad\], world axes). A pose row is read as two
    /// measurements: a [`Target::Tracker`] one for its position and this one.
    Orientation {
        /// measured world orientation of the tool frame (unit quaternion)
        rotation: UnitQuaternion<f64>,
    },
    /// The TCP touched contact plane `plane` (a plane row `plane,tcp,q…`): the residual is
    /// `offset − n·FK` \[mm\], the TCP's height above the plane with the sign reversed. With
    /// `normal` the tool axis (z of the tool-changer frame) was also held normal to the plane
    /// (a flat face pressed on it): two more rows, `−r·u'·(n × z)` and `−r·v'·(n × z)`, the
    /// height error at the rim of the contact face of radius `r` (the plane's
    /// `contact_radius_mm`) along the plane's basis directions \[mm\]. Without `normal` those
    /// two rows are zero and carry no information (see [`Target::residual_rows`]).
    Plane {
        /// contact plane id
        plane: u32,
        /// the tool axis was held normal to the plane too
        normal: bool,
    },
}

impl Target {
    /// Whether the residuals are rotation-vector errors \[rad\] rather than positions \[mm\].
    pub fn is_orientation(&self) -> bool {
        matches!(self, Target::Orientation { .. })
    }

    /// Whether this is a plane contact ([`Target::Plane`]).
    pub fn is_plane(&self) -> bool {
        matches!(self, Target::Plane { .. })
    }

    /// How many of the measurement's three residual rows carry information: 1 for a plane
    /// contact without the tool axis held normal (its other two rows are zero, with zero
    /// Jacobian rows), 3 otherwise. Degrees of freedom and RMS values count these rows.
    pub fn residual_rows(&self) -> usize {
        match self {
            Target::Plane { normal: false, .. } => 1,
            _ => 3,
        }
    }
}

/// The residual rows that carry information over a set of measurements (the sum of
/// [`Target::residual_rows`]: 3 per point, pose half or plane contact with the tool axis held
/// normal, 1 per plane contact without): the equations a fit's degrees of freedom count.
pub fn informative_rows(measurements: &[Measurement]) -> usize {
    measurements.iter().map(|m| m.target.residual_rows()).sum()
}

/// Rotation-vector error `log(measured · modelᵀ)` \[rad\] (world axes) between two rotation
/// matrices: the small rotation that takes the model's orientation to the measured one.
/// Computed as `atan2(‖v‖, c) · v/‖v‖` from the skew part `v` and `c = (tr − 1)/2`, accurate
/// to rounding for small errors (where an `acos` of the trace is not).
pub fn rotation_error(measured: &Matrix3<f64>, model: &Matrix3<f64>) -> Vector3<f64> {
    let e = measured * model.transpose();
    let v = 0.5 * Vector3::new(e[(2, 1)] - e[(1, 2)], e[(0, 2)] - e[(2, 0)], e[(1, 0)] - e[(0, 1)]);
    let s = v.norm();
    let c = 0.5 * (e.trace() - 1.0);
    let angle = s.atan2(c);
    if s < 1e-300 {
        return v;
    }
    v * (angle / s)
}

/// One measurement: joints, which TCP, what was observed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// TCP id
    pub tcp: u32,
    /// joints (internal units)
    pub q: JointVector,
    /// what was observed
    pub target: Target,
    /// optional per-sample data
    pub context: MeasurementContext,
    /// probe measurements: the final centring offset read by the gauges, in world axes
    /// (ball centre − probe origin, at most the centring tolerance, ~5 µm) \[mm\]. The observed
    /// target is then `calibration position + offset` instead of the position itself. `None`
    /// (or a tracker measurement) = no offset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe_offset_mm: Option<Vector3<f64>>,
}

impl Measurement {
    /// A probe measurement without context data.
    pub fn probe(position: u32, tcp: u32, q: JointVector) -> Self {
        Self {
            tcp,
            q,
            target: Target::Probe { position },
            context: MeasurementContext::default(),
            probe_offset_mm: None,
        }
    }

    /// A tracker measurement without context data.
    pub fn tracker(tcp: u32, q: JointVector, xyz_mm: Vector3<f64>) -> Self {
        Self {
            tcp,
            q,
            target: Target::Tracker { xyz_mm },
            context: MeasurementContext::default(),
            probe_offset_mm: None,
        }
    }

    /// An orientation measurement without context data: the world orientation `rotation` of
    /// the tool frame of TCP `tcp`'s tool at joints `q` (the rotation half of a pose row).
    pub fn orientation(tcp: u32, q: JointVector, rotation: UnitQuaternion<f64>) -> Self {
        Self {
            tcp,
            q,
            target: Target::Orientation { rotation },
            context: MeasurementContext::default(),
            probe_offset_mm: None,
        }
    }

    /// A plane contact without context data: TCP `tcp` touched plane `plane` at joints `q`,
    /// with the tool axis held normal to the plane when `normal`.
    pub fn plane(plane: u32, tcp: u32, q: JointVector, normal: bool) -> Self {
        Self {
            tcp,
            q,
            target: Target::Plane { plane, normal },
            context: MeasurementContext::default(),
            probe_offset_mm: None,
        }
    }

    /// The same probe measurement with the final centring offset `offset_mm` (world axes)
    /// recorded: the observed target becomes `calibration position + offset_mm`.
    pub fn with_probe_offset(mut self, offset_mm: Vector3<f64>) -> Self {
        self.probe_offset_mm = Some(offset_mm);
        self
    }

    /// What to add to the model's residual ([`Target`]: `position − FK` / `measured − FK`) to
    /// get the residual against the observed target: the recorded centring offset of a probe
    /// measurement, zero otherwise \[mm\].
    pub fn target_offset_mm(&self) -> Vector3<f64> {
        match (self.target, self.probe_offset_mm) {
            (Target::Probe { .. }, Some(o)) => o,
            _ => Vector3::zeros(),
        }
    }

    /// Calibration position id for probe measurements.
    pub fn position(&self) -> Option<u32> {
        match self.target {
            Target::Probe { position } => Some(position),
            Target::Tracker { .. } | Target::Orientation { .. } | Target::Plane { .. } => None,
        }
    }

    /// Contact plane id of a plane contact.
    pub fn plane_id(&self) -> Option<u32> {
        match self.target {
            Target::Plane { plane, .. } => Some(plane),
            _ => None,
        }
    }
}

/// A known distance between two fixed points (calibration positions / sockets): a measurement
/// of its own, the residual `distance_mm − |p_a − p_b|` with standard deviation `sigma_mm`. It
/// fixes the scale when the positions of the points are identified with the rest.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PointDistance {
    /// first calibration position (fixed point) id
    pub a: u32,
    /// second calibration position id
    pub b: u32,
    /// the known distance between their centres \[mm\]
    pub distance_mm: f64,
    /// its standard deviation \[mm\]
    pub sigma_mm: f64,
}

impl PointDistance {
    /// Default standard deviation of a known distance \[mm\]: a machined fixture, ~10 µm.
    pub const DEFAULT_SIGMA_MM: f64 = 0.01;

    /// Parses `a,b,distance_mm` or `a,b,distance_mm,sigma_mm` (the CLI's `--point-distance`).
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::PointDistance;
    ///
    /// let d = PointDistance::parse("0,1,50")?;
    /// assert_eq!((d.a, d.b, d.distance_mm, d.sigma_mm), (0, 1, 50.0, 0.01));
    /// assert!(PointDistance::parse("0,0,50").is_err());
    /// assert!(PointDistance::parse("0,1,-3").is_err());
    /// # Ok::<(), String>(())
    /// ```
    ///
    /// # Errors
    /// A message naming the field that is wrong (not a number, a negative distance or σ, the
    /// same id twice, a wrong field count).
    pub fn parse(spec: &str) -> Result<Self, String> {
        let fields: Vec<&str> = spec.split(',').map(str::trim).collect();
        if !(3..=4).contains(&fields.len()) {
            return Err(format!("`{spec}`: expected `a,b,distance_mm` or `a,b,distance_mm,sigma_mm`"));
        }
        let id = |k: usize, name: &str| {
            fields[k]
                .parse::<u32>()
                .map_err(|_| format!("`{spec}`: {name} `{}` is not a point id", fields[k]))
        };
        let num = |k: usize, name: &str| match fields[k].parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
            _ => Err(format!("`{spec}`: {name} `{}` must be a positive number", fields[k])),
        };
        let (a, b) = (id(0, "a")?, id(1, "b")?);
        if a == b {
            return Err(format!("`{spec}`: the two points must differ"));
        }
        let distance_mm = num(2, "distance_mm")?;
        let sigma_mm = if fields.len() == 4 { num(3, "sigma_mm")? } else { Self::DEFAULT_SIGMA_MM };
        Ok(Self { a, b, distance_mm, sigma_mm })
    }
}

/// A known distance between two parallel contact planes (e.g. a table and the top face of a
/// gauge block standing on it): three residual rows of their own, `distance_mm − (offset_b −
/// offset_a)` and the parallelism `L·(n_b − n_a)·u_a`, `L·(n_b − n_a)·v_a` at the lever
/// [`PlaneDistance::PARALLEL_LEVER_MM`], each with standard deviation `sigma_mm`. Plane rows
/// alone do not fix the chain's scale (every length and plane offset scaled together fits the
/// same contacts); a known distance does.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlaneDistance {
    /// first plane id
    pub a: u32,
    /// second plane id (its offset is the larger: `offset_b = offset_a + distance_mm`)
    pub b: u32,
    /// the known distance between the planes along their common normal \[mm\]
    pub distance_mm: f64,
    /// its standard deviation \[mm\] (also of the parallelism at the lever)
    pub sigma_mm: f64,
}

impl PlaneDistance {
    /// The lever \[mm\] at which the two normals' difference is expressed as a length: a
    /// tilt of 0.1 mrad between the planes is 10 µm over 100 mm.
    pub const PARALLEL_LEVER_MM: f64 = 100.0;

    /// Parses `a,b,distance_mm` or `a,b,distance_mm,sigma_mm` (the CLI's `--plane-distance`;
    /// default σ [`PointDistance::DEFAULT_SIGMA_MM`]).
    ///
    /// # Examples
    /// ```
    /// use vatcal_core::PlaneDistance;
    ///
    /// let d = PlaneDistance::parse("1,2,50,0.002")?;
    /// assert_eq!((d.a, d.b, d.distance_mm, d.sigma_mm), (1, 2, 50.0, 0.002));
    /// assert!(PlaneDistance::parse("1,1,50").is_err());
    /// # Ok::<(), String>(())
    /// ```
    ///
    /// # Errors
    /// As [`PointDistance::parse`], naming the plane ids.
    pub fn parse(spec: &str) -> Result<Self, String> {
        let d = PointDistance::parse(spec).map_err(|e| e.replace("point id", "plane id"))?;
        Ok(Self { a: d.a, b: d.b, distance_mm: d.distance_mm, sigma_mm: d.sigma_mm })
    }
}
