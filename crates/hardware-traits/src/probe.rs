//! A 3D probe built from three gauges: TriCal (background §7).
//!
//! Three plunger gauges with flat tips, axes nominally orthogonal and meeting at the probe
//! origin, touch a 1-inch ball. With `u_i` the unit direction of gauge `i` (from the origin
//! toward the gauge body) and `c` the ball centre relative to the origin, gauge `i` reads
//! `g_i = u_i · c` once zeroed with the master ball (§7.2–7.3): `g = A c` with the rows of `A`
//! the `u_iᵀ`. [`TriCal`] inverts this through the **nominal** axes, `c ≈ Â⁻¹ g`. The nominal
//! axes need not be exact: auto-centering drives `g` to zero, and `g = 0 ⇔ c = 0` for any
//! non-singular `A` (§7.4); the axes only set how fast the loop converges.
//!
//! The probe frame has the nominal gauge axes as its x, y, z axes. The plate sits on the tank
//! in one of three placements rotated 120° from each other about the world z axis; the world
//! orientation of the probe frame at each calibration position is part of the configuration
//! ([`ProbePlacement`]).

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, ErrorKind, Result};
use crate::gauge::Gauge;

/// Orientation of the probe frame in the world for one calibration position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbePlacement {
    /// calibration position id
    pub position: u32,
    /// rotation world ← probe (columns: probe axes in world coordinates)
    pub world_from_probe: Matrix3<f64>,
}

impl ProbePlacement {
    /// The trihedral TriCal seen from above: the three gauge axes point downward and outward,
    /// each 54.7° from the vertical (their sum points straight down, −z world), gauge 1 leans
    /// toward the azimuth `azimuth_rad` (measured about world z from world x), gauges 2 and 3
    /// follow at −120° and +120° so that the frame is right-handed.
    pub fn trihedral(position: u32, azimuth_rad: f64) -> Self {
        let horizontal = (2.0f64 / 3.0).sqrt();
        let down = -(1.0f64 / 3.0).sqrt();
        let axis = |angle: f64| Vector3::new(horizontal * angle.cos(), horizontal * angle.sin(), down);
        let third = 2.0 * std::f64::consts::FRAC_PI_3;
        let r =
            Matrix3::from_columns(&[axis(azimuth_rad), axis(azimuth_rad - third), axis(azimuth_rad + third)]);
        Self { position, world_from_probe: r }
    }

    /// One trihedral placement per calibration position, gauge 1 leaning radially outward
    /// from the world z axis (the tank axis the plate is rotated about): azimuth =
    /// `atan2(y, x)` of the position.
    pub fn radial_placements(positions: &[(u32, Vector3<f64>)]) -> Vec<Self> {
        positions.iter().map(|(id, p)| Self::trihedral(*id, p.y.atan2(p.x))).collect()
    }

    /// Maps a probe-frame vector into the world.
    pub fn to_world(&self, v_probe: &Vector3<f64>) -> Vector3<f64> {
        self.world_from_probe * v_probe
    }
}

/// One reading of a 3D probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeReading {
    /// the three gauge readings \[mm\]
    pub gauges_mm: [f64; 3],
    /// ball-centre offset from the probe origin in the probe frame, computed through the
    /// nominal gauge axes (`Â⁻¹ g`) \[mm\]
    pub offset_mm: Vector3<f64>,
}

impl ProbeReading {
    /// Composite error: the length of the offset \[mm\] (the paper stops auto-centering when it
    /// is below 0.005 mm).
    pub fn composite_mm(&self) -> f64 {
        self.offset_mm.norm()
    }
}

/// A probe that reports a ball-centre offset in its own frame.
///
/// # Implementation
/// Readings beyond the measuring range are [`ErrorKind::OutOfRange`] errors. Calls use the
/// gauges' I/O timeouts.
pub trait Probe3d: Send {
    /// Reads all gauges and converts them to an offset.
    fn read(&mut self) -> Result<ProbeReading>;

    /// Zeroes the probe with the master ball seated: every gauge is preset so that a centred
    /// calibration ball reads zero (TriCal: 6.350 mm, background §7.3).
    fn preset_master(&mut self) -> Result<()>;

    /// Orientation of the probe frame at calibration position `position`, if configured.
    fn placement(&self, position: u32) -> Option<ProbePlacement>;

    /// Measuring range: each gauge reading must stay within ±range \[mm\].
    fn range_mm(&self) -> f64;
}

impl<T: Probe3d + ?Sized> Probe3d for &mut T {
    fn read(&mut self) -> Result<ProbeReading> {
        (**self).read()
    }
    fn preset_master(&mut self) -> Result<()> {
        (**self).preset_master()
    }
    fn placement(&self, position: u32) -> Option<ProbePlacement> {
        (**self).placement(position)
    }
    fn range_mm(&self) -> f64 {
        (**self).range_mm()
    }
}

impl<T: Probe3d + ?Sized> Probe3d for Box<T> {
    fn read(&mut self) -> Result<ProbeReading> {
        (**self).read()
    }
    fn preset_master(&mut self) -> Result<()> {
        (**self).preset_master()
    }
    fn placement(&self, position: u32) -> Option<ProbePlacement> {
        (**self).placement(position)
    }
    fn range_mm(&self) -> f64 {
        (**self).range_mm()
    }
}

/// Master ball 1.5 in minus calibration ball 1 in, as radii: the preset that makes a centred
/// 1-inch ball read zero \[mm\].
pub const TRICAL_MASTER_PRESET_MM: f64 = 6.35;

/// Configuration of a [`TriCal`].
#[derive(Debug, Clone, PartialEq)]
pub struct TriCalConfig {
    /// nominal gauge directions `u_i` in the probe frame (unit vectors; nominally the probe
    /// frame's x, y, z axes)
    pub gauge_axes: [Vector3<f64>; 3],
    /// probe orientation at each calibration position
    pub placements: Vec<ProbePlacement>,
    /// each reading must stay within ±range \[mm\] (TriCal: 6 mm)
    pub range_mm: f64,
    /// preset applied with the master ball seated \[mm\]
    pub master_preset_mm: f64,
}

impl TriCalConfig {
    /// Orthogonal nominal axes, ±6 mm range, 6.350 mm master preset, the given placements.
    pub fn new(placements: Vec<ProbePlacement>) -> Self {
        Self {
            gauge_axes: [Vector3::x(), Vector3::y(), Vector3::z()],
            placements,
            range_mm: 6.0,
            master_preset_mm: TRICAL_MASTER_PRESET_MM,
        }
    }
}

/// Three [`Gauge`]s as a [`Probe3d`] (TriCal).
#[derive(Debug)]
pub struct TriCal<G: Gauge> {
    gauges: [G; 3],
    config: TriCalConfig,
    /// `Â⁻¹`
    axes_inverse: Matrix3<f64>,
}

impl<G: Gauge> TriCal<G> {
    /// Builds the probe. Fails with [`ErrorKind::Other`] if the nominal axes are (nearly)
    /// coplanar or the range is not positive.
    pub fn new(gauges: [G; 3], config: TriCalConfig) -> Result<Self> {
        let a = Matrix3::from_rows(&config.gauge_axes.map(|u| u.normalize().transpose()));
        if !config.range_mm.is_finite() || config.range_mm <= 0.0 {
            return Err(Error::new(
                ErrorKind::Other,
                "trical",
                format!("range must be > 0 mm, got {}", config.range_mm),
            ));
        }
        let axes_inverse =
            (a.determinant().abs() > 1e-3).then(|| a.try_inverse()).flatten().ok_or_else(|| {
                Error::new(ErrorKind::Other, "trical", "the nominal gauge axes are (nearly) coplanar")
            })?;
        Ok(Self { gauges, config, axes_inverse })
    }

    /// The configuration.
    pub fn config(&self) -> &TriCalConfig {
        &self.config
    }

    /// The gauges, e.g. to hand them back.
    pub fn into_gauges(self) -> [G; 3] {
        self.gauges
    }

    /// Offset `Â⁻¹ g` of three readings \[mm\].
    pub fn offset_of(&self, gauges_mm: &[f64; 3]) -> Vector3<f64> {
        self.axes_inverse * Vector3::from(*gauges_mm)
    }
}

impl<G: Gauge> Probe3d for TriCal<G> {
    fn read(&mut self) -> Result<ProbeReading> {
        let mut g = [0.0; 3];
        for (i, gauge) in self.gauges.iter_mut().enumerate() {
            let v = gauge.read_mm().map_err(|e| e.context(format!("TriCal gauge {}", i + 1)))?;
            if !v.is_finite() || v.abs() > self.config.range_mm {
                return Err(Error::new(
                    ErrorKind::OutOfRange,
                    "trical",
                    format!("gauge {} reads {v} mm, outside ±{} mm", i + 1, self.config.range_mm),
                ));
            }
            g[i] = v;
        }
        Ok(ProbeReading { gauges_mm: g, offset_mm: self.offset_of(&g) })
    }

    fn preset_master(&mut self) -> Result<()> {
        for (i, gauge) in self.gauges.iter_mut().enumerate() {
            gauge
                .preset_mm(self.config.master_preset_mm)
                .map_err(|e| e.context(format!("TriCal gauge {}", i + 1)))?;
        }
        Ok(())
    }

    fn placement(&self, position: u32) -> Option<ProbePlacement> {
        self.config.placements.iter().find(|p| p.position == position).copied()
    }

    fn range_mm(&self) -> f64 {
        self.config.range_mm
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    /// A gauge that reads `u · c` for a settable ball centre.
    #[derive(Debug)]
    struct IdealGauge {
        u: Vector3<f64>,
        c: Vector3<f64>,
        offset: f64,
    }

    impl Gauge for IdealGauge {
        fn read_mm(&mut self) -> Result<f64> {
            Ok(self.u.dot(&self.c) + self.offset)
        }
        fn preset_mm(&mut self, value_mm: f64) -> Result<()> {
            self.offset = value_mm - self.u.dot(&self.c);
            Ok(())
        }
    }

    fn probe(true_axes: [Vector3<f64>; 3], c: Vector3<f64>) -> TriCal<IdealGauge> {
        let gauges = true_axes.map(|u| IdealGauge { u: u.normalize(), c, offset: 0.0 });
        TriCal::new(gauges, TriCalConfig::new(vec![ProbePlacement::trihedral(1, 0.0)])).expect("probe")
    }

    #[test]
    fn trihedral_placement_is_a_right_handed_rotation_pointing_down() {
        for az in [0.0, 1.0, -2.5] {
            let p = ProbePlacement::trihedral(1, az);
            let r = p.world_from_probe;
            assert_relative_eq!(r.transpose() * r, Matrix3::identity(), epsilon = 1e-12);
            assert_relative_eq!(r.determinant(), 1.0, epsilon = 1e-12);
            let sum = r.column(0) + r.column(1) + r.column(2);
            assert_relative_eq!(sum, Vector3::new(0.0, 0.0, -(3.0f64).sqrt()), epsilon = 1e-12);
            let g1 = r.column(0);
            assert_relative_eq!(g1.y.atan2(g1.x), az, epsilon = 1e-12);
        }
        let ps = ProbePlacement::radial_placements(&[
            (1, Vector3::new(-87.0, 0.0, 47.0)),
            (2, Vector3::new(44.0, -75.6, 47.0)),
        ]);
        assert_eq!(ps.len(), 2);
        // 120° apart about z
        let rel = ps[1].world_from_probe * ps[0].world_from_probe.transpose();
        assert_relative_eq!(rel[(2, 2)], 1.0, epsilon = 1e-9);
        assert_relative_eq!(rel[(1, 0)].atan2(rel[(0, 0)]).to_degrees().abs(), 120.0, epsilon = 0.5);
    }

    proptest! {
        /// With exact nominal axes the probe returns the ball offset itself.
        #[test]
        fn exact_axes_recover_the_offset(x in -3.0..3.0f64, y in -3.0..3.0f64, z in -3.0..3.0f64) {
            let c = Vector3::new(x, y, z);
            let mut p = probe([Vector3::x(), Vector3::y(), Vector3::z()], c);
            let r = p.read().expect("read");
            prop_assert!((r.offset_mm - c).norm() < 1e-12);
        }

        /// With slightly wrong true axes the reading is zero only at the origin, and the
        /// offset error is a small fraction of the offset (what makes auto-centering contract).
        #[test]
        fn skewed_axes_give_a_small_relative_error(x in -3.0..3.0f64, y in -3.0..3.0f64, z in -3.0..3.0f64) {
            let c = Vector3::new(x, y, z);
            let skew = [Vector3::new(1.0, 0.004, -0.003), Vector3::new(0.005, 1.0, 0.002), Vector3::new(-0.002, 0.006, 1.0)];
            let mut p = probe(skew, c);
            let r = p.read().expect("read");
            prop_assert!((r.offset_mm - c).norm() <= 0.02 * c.norm() + 1e-12);
        }
    }

    #[test]
    fn readings_outside_the_range_are_errors() {
        let mut p = probe([Vector3::x(), Vector3::y(), Vector3::z()], Vector3::new(0.0, 6.5, 0.0));
        let e = p.read().expect_err("out of range");
        assert_eq!(e.kind(), ErrorKind::OutOfRange);
        assert!(e.to_string().contains("gauge 2"), "{e}");
    }

    #[test]
    fn master_preset_and_coplanar_axes() {
        let mut p = probe([Vector3::x(), Vector3::y(), Vector3::z()], Vector3::zeros());
        p.preset_master().expect("preset");
        // the master ball reads the preset, beyond the ±6 mm working range of a calibration ball
        assert_eq!(p.read().expect_err("master ball").kind(), ErrorKind::OutOfRange);
        let mut gauges = p.into_gauges();
        assert_relative_eq!(gauges[0].read_mm().expect("gauge"), TRICAL_MASTER_PRESET_MM);
        let mut cfg = TriCalConfig::new(vec![]);
        cfg.gauge_axes = [Vector3::x(), Vector3::y(), Vector3::new(1.0, 1.0, 0.0)];
        let gauges = [0, 1, 2].map(|_| IdealGauge { u: Vector3::x(), c: Vector3::zeros(), offset: 0.0 });
        assert!(TriCal::new(gauges, cfg).is_err());
    }
}
