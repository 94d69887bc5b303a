//! Forward kinematics: every frame of the chain in the world.

use nalgebra::{Matrix3, Vector3};
use vatcal_core::effects::{EffectInputs, Hook};
use vatcal_core::params::{Axis, EffectParam};
use vatcal_core::{Frame, JointKind, JointVector, MAX_JOINTS, MeasurementContext};

use vatcal_core::frame::{rot_x as rx, rot_y as ry, rot_z as rz};

use crate::model::{Model, ModelError};

/// World-frame axes of one MDH row, needed by the Jacobian.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct RowAxes {
    /// x axis of frame i-1 (alpha rotation axis, a translation direction)
    pub x_prev: Vector3<f64>,
    /// origin of frame i-1
    pub o_prev: Vector3<f64>,
    /// y axis after Rx(alpha) Tx(a) (beta rotation axis)
    pub y_beta: Vector3<f64>,
    /// origin after Tx(a)
    pub o_beta: Vector3<f64>,
    /// z axis of frame i (theta rotation axis, d translation direction)
    pub z: Vector3<f64>,
    /// origin of frame i (before any inserted effect transform)
    pub o: Vector3<f64>,
}

/// Axes of an inserted `T(sx, sy, 0) Rx(ex) Ry(ey) Rz(ez)`-type transform.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct InsertAxes {
    pub tx: Vector3<f64>,
    pub ty: Vector3<f64>,
    pub tz: Vector3<f64>,
    pub rot: [Vector3<f64>; 3],
    pub o: Vector3<f64>,
}

/// The summed hooks of the switched-on effects at one sample.
#[derive(Debug, Clone, Copy, Default)]
struct EffectState {
    /// joint-space offsets, `joint[i - 1]` for joint i
    joint: [f64; MAX_JOINTS],
    /// a guide-carriage correction is switched on
    guide_active: bool,
    guide_shift: [f64; 2],
    guide_rot: [f64; 3],
    /// a tool-frame correction is switched on
    tool_active: bool,
    /// tx, ty, rx, ry
    tool: [f64; 4],
    /// relative length change of the revolute rows
    length: f64,
    /// rotation of link frame i about its x and y axes, `link_rot[i - 1]` \[rad\]
    link_rot: [[f64; 2]; MAX_JOINTS],
    /// translation of link frame i along its x, y and z axes, `link_shift[i - 1]` \[mm\]
    link_shift: [[f64; 3]; MAX_JOINTS],
}

/// All frames of the chain for one joint vector, in the world (tank) frame.
#[derive(Debug, Clone)]
pub struct Chain {
    /// World poses of MDH frames 0..=N (`frames[..=n]`; later entries are identity). The frame
    /// of the guide joint (frame 1 on the canonical cell, the carriage) includes the guide
    /// effects when they are switched on; frame N is the last-joint (flange) frame.
    pub frames: [Frame; MAX_JOINTS + 1],
    /// Number of joints N.
    pub n: usize,
    /// The tool-changer frame in which TCPs are given: frame N, times the `tool-frame` effect
    /// transform when that effect is on.
    pub tool: Frame,
    /// Gravity torques \[N·m\] used for the compliance, `torques[i - 1]` for joint i (0 for
    /// prismatic joints; all zeros when not evaluated).
    pub torques: [f64; MAX_JOINTS],
    /// Whether `torques` were evaluated.
    pub torques_evaluated: bool,
    /// Gravity moment \[N·m\] of the arm and its load about the carriage origin, components
    /// along the carriage x and y axes (evaluated when `guide-carriage-tilt` is on or when
    /// given; `None` otherwise).
    pub carriage_moment: Option<[f64; 2]>,
    /// Gravity bending moments \[N·m\] of the joints along their frames' x and y axes
    /// (evaluated when `link-bending` is on or when given; `None` otherwise).
    pub link_moments: Option<[[f64; 2]; MAX_JOINTS]>,
    /// Joint angles theta_1..theta_N \[rad\] that entered Eq. (1), `theta[i - 1]` for row i.
    pub theta: [f64; MAX_JOINTS],
    pub(crate) axes: [RowAxes; MAX_JOINTS],
    pub(crate) guide: Option<InsertAxes>,
    pub(crate) tool_axes: Option<InsertAxes>,
    /// axes of the link correction inserted after frame i (`[i - 1]`), when one is on
    pub(crate) link_axes: [Option<InsertAxes>; MAX_JOINTS],
    pub(crate) thermal_factor: f64,
}

impl Chain {
    /// World position of a point given in the tool-changer frame (e.g. a TCP) \[mm\].
    pub fn tool_point(&self, t: &Vector3<f64>) -> Vector3<f64> {
        self.tool.transform_point(t)
    }

    /// The flange frame N in the world.
    pub fn flange(&self) -> Frame {
        self.frames[self.n]
    }

    /// World poses of frames 0..=N.
    pub fn frames(&self) -> &[Frame] {
        &self.frames[..=self.n]
    }
}

/// Gravity loads evaluated on a model's undeflected geometry: what the compliance-type effects
/// (`joint-compliance`, `guide-carriage-tilt`) multiply. Holding them fixed gives the
/// derivatives the analytic Jacobian computes (second-order terms dropped).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GravityLoads {
    /// gravity torques \[N·m\], `torques[i - 1]` for joint i (0 for prismatic joints)
    pub torques: [f64; MAX_JOINTS],
    /// gravity moment about the carriage origin along the carriage x and y axes \[N·m\]
    pub carriage_moment: [f64; 2],
    /// gravity bending moment of each joint along its frame's x and y axes \[N·m\],
    /// `[i - 1]` for joint i
    pub link_moments: [[f64; 2]; MAX_JOINTS],
}

#[inline]
fn rz_tz(fixed: &Frame, theta: f64, d: f64) -> Frame {
    rz_tz_trig(fixed, theta.sin_cos(), d)
}

/// `fixed · Rz(theta) · Tz(d)` with `(sin theta, cos theta)` given.
#[inline(always)]
fn rz_tz_trig(fixed: &Frame, (s, c): (f64, f64), d: f64) -> Frame {
    let m = &fixed.r;
    let c0 = m.column(0) * c + m.column(1) * s;
    let c1 = m.column(1) * c - m.column(0) * s;
    let c2 = m.column(2).into_owned();
    let r = Matrix3::from_columns(&[c0, c1, c2]);
    Frame { r, p: fixed.p + c2 * d }
}

impl Model {
    /// Gravity torques \[N·m\] at `q`, `tau[i - 1]` for joint i (0 for prismatic joints and
    /// beyond N), on this model's own geometry (its MDH rows incl. beta, its base
    /// orientation), with all compliances zero and no iteration.
    ///
    /// # Panics
    /// If `q` does not have [`Model::joint_count`] values (a programming error).
    #[track_caller]
    pub fn gravity_torques(&self, q: &JointVector) -> [f64; MAX_JOINTS] {
        self.assert_len(q);
        let trig = self.undeflected_trig(q);
        self.gravity_torques_trig(q, &trig)
    }

    #[inline]
    #[track_caller]
    pub(crate) fn assert_len(&self, q: &JointVector) {
        assert!(q.len() == self.n, "joint vector of {} values for a chain of {} joints", q.len(), self.n);
    }

    /// `(sin, cos)` of the undeflected joint angles `q_i + theta_offset_i` (prismatic rows:
    /// constant `theta_offset_i`).
    #[inline]
    fn undeflected_trig(&self, q: &JointVector) -> [(f64, f64); MAX_JOINTS] {
        let mut trig = [(0.0, 1.0); MAX_JOINTS];
        let q = q.as_slice();
        for k in 0..self.n {
            let th = if self.kinds[k].is_revolute() { q[k] } else { 0.0 };
            trig[k] = (th + self.rows[k].theta_offset).sin_cos();
        }
        trig
    }

    /// `d_i` of row k (0-based) on the undeflected geometry.
    #[inline(always)]
    fn row_d(&self, k: usize, q: &[f64]) -> f64 {
        match self.kinds[k] {
            JointKind::Revolute => self.rows[k].d,
            JointKind::Prismatic => q[k] + self.rows[k].d,
        }
    }

    /// Gravity torques from the undeflected trigonometry, with the model's stored
    /// [`GravityModel`](vatcal_gravity_torque::GravityModel) (the same numbers as
    /// `vatcal_gravity_torque::gravity_torques`, bit for bit).
    #[inline]
    fn gravity_torques_trig(&self, q: &JointVector, trig: &[(f64, f64); MAX_JOINTS]) -> [f64; MAX_JOINTS] {
        let qs = q.as_slice();
        let mut tau = [0.0; MAX_JOINTS];
        match self.n {
            7 => tau[..7].copy_from_slice(&self.gravity_torques_n::<7>(qs, trig)),
            6 => tau[..6].copy_from_slice(&self.gravity_torques_n::<6>(qs, trig)),
            n => {
                let mut links = [Frame::identity(); MAX_JOINTS];
                for k in 0..n {
                    links[k] = rz_tz_trig(&self.row_fixed[k], trig[k], self.row_d(k, qs));
                }
                tau = self.gravity_model.torques(&links[..n], &self.kinds[..n]);
            }
        }
        tau
    }

    /// [`Model::gravity_torques_trig`] on fixed-size arrays for a chain of exactly `N` joints.
    #[inline(always)]
    fn gravity_torques_n<const N: usize>(&self, q: &[f64], trig: &[(f64, f64); MAX_JOINTS]) -> [f64; N] {
        let Ok(kinds) = <&[JointKind; N]>::try_from(&self.kinds[..N]) else {
            return [f64::NAN; N]; // unreachable: callers dispatch on self.n == N
        };
        let mut links = [Frame::identity(); N];
        for (k, link) in links.iter_mut().enumerate() {
            *link = rz_tz_trig(&self.row_fixed[k], trig[k], self.row_d(k, q));
        }
        self.gravity_model.torques_n(&links, kinds)
    }

    /// Gravity moment \[N·m\] of everything distal to the guide joint g ([`Model::guide_joint`];
    /// on the canonical cell: links 2..7 and the tool) about the origin of the carriage frame
    /// g, as components along the carriage x and y axes, on this model's own undeflected
    /// geometry (no effect, no compliance). With a vertical guide the moment about the guide
    /// axis (z) is zero, so only x and y are returned. Zero when the chain has no guide.
    ///
    /// # Panics
    /// If `q` does not have [`Model::joint_count`] values (a programming error).
    #[track_caller]
    #[allow(clippy::needless_range_loop)] // several parallel per-row arrays
    pub fn carriage_moment(&self, q: &JointVector) -> [f64; 2] {
        self.assert_len(q);
        let Some(g) = self.guide else { return [0.0; 2] };
        let trig = self.undeflected_trig(q);
        let qs = q.as_slice();
        let mut w = self.base_frame;
        let mut carriage = w;
        let mut moment = Vector3::zeros();
        for k in 0..self.n {
            w = w.compose(&rz_tz_trig(&self.row_fixed[k], trig[k], self.row_d(k, qs)));
            if k == g {
                carriage = w;
            } else if k > g {
                let body = self.masses.body(k + 1);
                let arm_m = (w.transform_point(&body.com_mm) - carriage.p) * 1e-3;
                moment += arm_m.cross(&(self.gravity * body.mass_kg));
            }
        }
        [moment.dot(&carriage.x_axis()), moment.dot(&carriage.y_axis())]
    }

    /// Gravity bending moment \[N·m\] each joint carries at `q`: the moment of gravity on
    /// everything distal to joint i about the origin of frame i, along frame i's x and y
    /// axes, `[i - 1]` for joint i (any joint kind; zeros beyond N), on this model's own
    /// undeflected geometry (no effect, no compliance), as the torques. What `link-bending`
    /// multiplies; the z component (not returned) is the torque of a revolute joint.
    ///
    /// # Panics
    /// If `q` does not have [`Model::joint_count`] values (a programming error).
    #[track_caller]
    pub fn link_bending_moments(&self, q: &JointVector) -> [[f64; 2]; MAX_JOINTS] {
        self.assert_len(q);
        let trig = self.undeflected_trig(q);
        let qs = q.as_slice();
        let mut links = [Frame::identity(); MAX_JOINTS];
        for k in 0..self.n {
            links[k] = rz_tz_trig(&self.row_fixed[k], trig[k], self.row_d(k, qs));
        }
        let m = self.gravity_model.moments(&links[..self.n]);
        let mut out = [[0.0; 2]; MAX_JOINTS];
        for (o, v) in out.iter_mut().zip(&m) {
            *o = [v.x, v.y];
        }
        out
    }

    /// Gravity torques, carriage moment and bending moments at `q` (see [`GravityLoads`]).
    pub fn gravity_loads(&self, q: &JointVector) -> GravityLoads {
        GravityLoads {
            torques: self.gravity_torques(q),
            carriage_moment: self.carriage_moment(q),
            link_moments: self.link_bending_moments(q),
        }
    }

    /// Lean FK of a point in the tool frame when no effect is switched on: no Jacobian axes,
    /// and the deflected angles reuse the trigonometry of the torque pass.
    #[inline]
    fn fast_tool_point(&self, q: &JointVector, t: &Vector3<f64>) -> Vector3<f64> {
        match self.n {
            7 => self.fast_tool_point_n::<7>(q.as_slice(), t),
            6 => self.fast_tool_point_n::<6>(q.as_slice(), t),
            _ => self.fast_tool_point_any(q, t),
        }
    }

    /// [`Model::fast_tool_point`] on fixed-size arrays for a chain of exactly `N` joints.
    ///
    /// The point is carried backwards through the rows (`v <- H_k v`, a 3×3 matrix times a
    /// vector per row) instead of composing N frames forwards; with compliance the links of
    /// the torque pass are reused, the deflection entering as `Rz(c_k tau_k)` before link k's
    /// rotation (`Rz` commutes with `Tz(d_k)`).
    #[allow(clippy::needless_range_loop)] // several parallel per-row arrays
    fn fast_tool_point_n<const N: usize>(&self, q: &[f64], t: &Vector3<f64>) -> Vector3<f64> {
        let (Ok(kinds), Ok(q)) = (<&[JointKind; N]>::try_from(&self.kinds[..N]), <&[f64; N]>::try_from(q))
        else {
            return Vector3::repeat(f64::NAN); // unreachable: callers dispatch on self.n == N == q.len()
        };
        let mut trig = [(0.0, 1.0); N];
        for k in 0..N {
            trig[k] = if kinds[k].is_revolute() {
                (q[k] + self.rows[k].theta_offset).sin_cos()
            } else {
                self.theta_trig[k]
            };
        }
        let d = |k: usize| if kinds[k].is_revolute() { self.rows[k].d } else { q[k] + self.rows[k].d };
        let mut v = *t;
        if self.any_compliance {
            let mut links = [Frame::identity(); N];
            for k in 0..N {
                links[k] = rz_tz_trig(&self.row_fixed[k], trig[k], d(k));
            }
            let tau = self.gravity_model.torques_n(&links, kinds);
            for k in (0..N).rev() {
                let delta = self.compliance[k] * tau[k];
                if kinds[k].is_revolute() && delta != 0.0 {
                    let (s, c) = small_angle_sin_cos(delta);
                    v = Vector3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z);
                }
                v = links[k].transform_point(&v);
            }
        } else {
            for k in (0..N).rev() {
                let (s, c) = trig[k];
                let local = Vector3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z + d(k));
                v = self.row_fixed[k].transform_point(&local);
            }
        }
        self.base_frame.transform_point(&v)
    }

    #[allow(clippy::needless_range_loop)] // several parallel per-row arrays
    fn fast_tool_point_any(&self, q: &JointVector, t: &Vector3<f64>) -> Vector3<f64> {
        let trig = self.undeflected_trig(q);
        let qs = q.as_slice();
        let mut w = self.base_frame;
        if self.any_compliance {
            let tau = self.gravity_torques_trig(q, &trig);
            for k in 0..self.n {
                let tr = if self.kinds[k].is_revolute() {
                    add_small_angle(trig[k], self.compliance[k] * tau[k])
                } else {
                    trig[k]
                };
                w = w.compose(&rz_tz_trig(&self.row_fixed[k], tr, self.row_d(k, qs)));
            }
        } else {
            for k in 0..self.n {
                w = w.compose(&rz_tz_trig(&self.row_fixed[k], trig[k], self.row_d(k, qs)));
            }
        }
        w.transform_point(t)
    }

    /// The inputs of the effects' hook coefficients at one sample.
    pub(crate) fn effect_inputs<'a>(
        &self,
        q: &'a JointVector,
        ctx: &'a MeasurementContext,
        carriage_moment: Option<[f64; 2]>,
        link_moments: Option<[[f64; 2]; MAX_JOINTS]>,
        torques: &[f64; MAX_JOINTS],
    ) -> EffectInputs<'a> {
        EffectInputs {
            q: q.as_slice(),
            ctx,
            guide: self.guide_joint().map(|g| g as u8),
            guide_u: self.guide_u(self.guide_q(q)),
            carriage_moment: carriage_moment.unwrap_or([0.0; 2]),
            thermal_reference_c: self.thermal_reference_c,
            link_moments: link_moments.unwrap_or([[0.0; 2]; MAX_JOINTS]),
            torques: *torques,
        }
    }

    /// Sums the hooks of every switched-on effect at one sample (the effect layer: called
    /// only when an effect is on). One dynamic call per effect, none per joint.
    fn effect_state(&self, x: &EffectInputs<'_>) -> EffectState {
        let mut st = EffectState::default();
        for ((spec, effect), table) in
            self.effects.iter().zip(&self.effect_impls).zip(&self.effect_value_tables)
        {
            let mut cursor = EffectValueCursor { table, next: 0 };
            effect.contributions(spec, x, &mut |param, hook, coefficient| {
                let v = cursor.value(param) * coefficient;
                match hook {
                    Hook::Joint(j) => {
                        if let Some(o) = st.joint.get_mut((j as usize).wrapping_sub(1)) {
                            *o += v;
                        }
                    }
                    Hook::GuideShift(a) => {
                        st.guide_active = true;
                        if a != Axis::Z {
                            st.guide_shift[a.index()] += v;
                        }
                    }
                    Hook::GuideRotation(a) => {
                        st.guide_active = true;
                        st.guide_rot[a.index()] += v;
                    }
                    Hook::ToolShift(a) => {
                        st.tool_active = true;
                        if a != Axis::Z {
                            st.tool[a.index()] += v;
                        }
                    }
                    Hook::ToolRotation(a) => {
                        st.tool_active = true;
                        if a != Axis::Z {
                            st.tool[2 + a.index()] += v;
                        }
                    }
                    Hook::LengthScale => st.length += v,
                    Hook::LinkShift { joint, axis } => {
                        if let Some(t) = st.link_shift.get_mut((joint as usize).wrapping_sub(1)) {
                            t[axis.index()] += v;
                        }
                    }
                    Hook::LinkRotation { joint, axis } => {
                        if let (Some(r), Axis::X | Axis::Y) =
                            (st.link_rot.get_mut((joint as usize).wrapping_sub(1)), axis)
                        {
                            r[axis.index()] += v;
                        }
                    }
                }
            });
        }
        st
    }

    /// Computes every frame at `q`. Torques are evaluated when a compliance is non-zero or
    /// `with_torques` is set; `fixed_torques` overrides them (used to check the Jacobian,
    /// which holds tau fixed).
    ///
    /// # Panics
    /// If `q` does not have [`Model::joint_count`] values (a programming error).
    #[track_caller]
    pub fn chain_full(
        &self,
        q: &JointVector,
        ctx: &MeasurementContext,
        with_torques: bool,
        fixed_torques: Option<&[f64; MAX_JOINTS]>,
    ) -> Chain {
        self.chain_inner(q, ctx, with_torques, fixed_torques, None, None)
    }

    /// Every frame at `q` with all gravity loads held at `loads` (torques for the compliances,
    /// carriage moment for `guide-carriage-tilt`): the function whose derivatives the analytic
    /// Jacobian gives.
    ///
    /// # Panics
    /// If `q` does not have [`Model::joint_count`] values (a programming error).
    #[track_caller]
    pub fn chain_with_loads(&self, q: &JointVector, ctx: &MeasurementContext, loads: &GravityLoads) -> Chain {
        self.chain_inner(
            q,
            ctx,
            true,
            Some(&loads.torques),
            Some(loads.carriage_moment),
            Some(loads.link_moments),
        )
    }

    #[track_caller]
    pub(crate) fn chain_inner(
        &self,
        q: &JointVector,
        ctx: &MeasurementContext,
        with_torques: bool,
        fixed_torques: Option<&[f64; MAX_JOINTS]>,
        fixed_moment: Option<[f64; 2]>,
        fixed_link_moments: Option<[[f64; 2]; MAX_JOINTS]>,
    ) -> Chain {
        self.assert_len(q);
        let (torques, torques_evaluated) = match fixed_torques {
            Some(t) => (*t, true),
            None if with_torques || self.any_compliance || self.effects_need_torques => {
                (self.gravity_torques(q), true)
            }
            None => ([0.0; MAX_JOINTS], false),
        };
        let carriage_moment = match fixed_moment {
            Some(m) => Some(m),
            None if self.effects_need_moment => Some(self.carriage_moment(q)),
            None => None,
        };
        let link_moments = match fixed_link_moments {
            Some(m) => Some(m),
            None if self.effects_need_link_moments => Some(self.link_bending_moments(q)),
            None => None,
        };
        let st = if self.effects.is_empty() {
            EffectState::default()
        } else {
            self.effect_state(&self.effect_inputs(q, ctx, carriage_moment, link_moments, &torques))
        };
        let thermal_factor = 1.0 + st.length;
        let mut frames = [Frame::identity(); MAX_JOINTS + 1];
        let mut axes = [RowAxes::default(); MAX_JOINTS];
        let mut theta = [0.0; MAX_JOINTS];
        let mut guide = None;
        let mut link_axes = [None; MAX_JOINTS];
        let mut w = self.base_frame;
        frames[0] = w;
        for k in 0..self.n {
            let row = &self.rows[k];
            let mut fixed = self.row_fixed[k];
            let (th, d) = if self.kinds[k] == JointKind::Prismatic {
                (row.theta_offset, q[k] + st.joint[k] + row.d)
            } else {
                let th = q[k] + row.theta_offset + self.compliance[k] * torques[k] + st.joint[k];
                let mut d = row.d;
                if thermal_factor != 1.0 {
                    fixed.p *= thermal_factor;
                    d *= thermal_factor;
                }
                (th, d)
            };
            theta[k] = th;
            let (sa, ca) = self.row_trig[k];
            let x_prev = w.x_axis();
            axes[k].x_prev = x_prev;
            axes[k].o_prev = w.p;
            axes[k].y_beta = w.r * Vector3::new(0.0, ca, sa);
            axes[k].o_beta = w.p + x_prev * fixed.p.x;
            w = w.compose(&rz_tz(&fixed, th, d));
            axes[k].z = w.z_axis();
            axes[k].o = w.p;
            if self.guide == Some(k) && st.guide_active {
                let ([sx, sy], e) = (st.guide_shift, st.guide_rot);
                let (ins, ax) = insert_transform(&w, [sx, sy, 0.0], e[0], e[1], Some(e[2]));
                guide = Some(ax);
                w = w.compose(&ins);
            }
            if st.link_rot[k] != [0.0; 2] || st.link_shift[k] != [0.0; 3] {
                let [ex, ey] = st.link_rot[k];
                let (ins, ax) = insert_transform(&w, st.link_shift[k], ex, ey, None);
                link_axes[k] = Some(ax);
                w = w.compose(&ins);
            }
            frames[k + 1] = w;
        }
        let mut tool = w;
        let mut tool_axes = None;
        if st.tool_active {
            let [tx, ty, rx_, ry_] = st.tool;
            let (ins, ax) = insert_transform(&w, [tx, ty, 0.0], rx_, ry_, None);
            tool_axes = Some(ax);
            tool = w.compose(&ins);
        }
        Chain {
            frames,
            n: self.n,
            tool,
            torques,
            torques_evaluated,
            carriage_moment,
            link_moments,
            theta,
            axes,
            guide,
            tool_axes,
            link_axes,
            thermal_factor,
        }
    }

    /// Every frame at `q` (no per-sample context).
    ///
    /// # Panics
    /// If `q` does not have [`Model::joint_count`] values (a programming error; the
    /// `Result`-returning functions such as [`Model::tcp_position`] check it).
    #[track_caller]
    pub fn chain(&self, q: &JointVector) -> Chain {
        self.chain_full(q, &MeasurementContext::default(), false, None)
    }

    /// World position \[mm\] of TCP `tcp` at `q` with per-sample context `ctx`.
    pub fn tcp_position_ctx(
        &self,
        q: &JointVector,
        ctx: &MeasurementContext,
        tcp: u32,
    ) -> Result<Vector3<f64>, ModelError> {
        let t = self.tcp_or_err(tcp)?;
        self.check_joint_count(q)?;
        if self.effects.is_empty() {
            return Ok(self.fast_tool_point(q, &t));
        }
        Ok(self.chain_full(q, ctx, false, None).tool_point(&t))
    }

    /// World position \[mm\] of TCP `tcp` at `q`.
    ///
    /// # Errors
    /// [`ModelError::UnknownTcp`] when the model has no TCP `tcp`.
    pub fn tcp_position(&self, q: &JointVector, tcp: u32) -> Result<Vector3<f64>, ModelError> {
        self.tcp_position_ctx(q, &MeasurementContext::default(), tcp)
    }
}

/// `(sin, cos)` of `theta + delta` from those of `theta`; exact to rounding for any delta
/// (a Taylor series for the small compliance deflections, `sin_cos` otherwise).
#[inline]
fn add_small_angle((s, c): (f64, f64), delta: f64) -> (f64, f64) {
    let (sd, cd) = small_angle_sin_cos(delta);
    (s * cd + c * sd, c * cd - s * sd)
}

/// `(sin, cos)` of an angle, by a Taylor series when it is small (compliance deflections)
/// and `sin_cos` otherwise; exact to rounding either way.
#[inline]
fn small_angle_sin_cos(delta: f64) -> (f64, f64) {
    if delta.abs() < 1e-2 {
        let d2 = delta * delta;
        (
            delta * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0))),
            1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0 * (1.0 - d2 / 56.0))),
        )
    } else {
        delta.sin_cos()
    }
}

/// `T(t) Rx(ex) Ry(ey) [Rz(ez)]` relative to `w`, and its world axes for the Jacobian.
fn insert_transform(w: &Frame, t: [f64; 3], ex: f64, ey: f64, ez: Option<f64>) -> (Frame, InsertAxes) {
    let rxm = rx(ex);
    let rxy = rxm * ry(ey);
    let r = match ez {
        Some(z) => rxy * rz(z),
        None => rxy,
    };
    let local = Frame { r, p: Vector3::from(t) };
    let o = w.p + w.r * local.p;
    let ax = InsertAxes {
        tx: w.x_axis(),
        ty: w.y_axis(),
        tz: w.z_axis(),
        rot: [w.x_axis(), w.r * rxm.column(1), w.r * rxy.column(2)],
        o,
    };
    (local, ax)
}

/// Reads one effect's parameter values from its table ([`Model`]'s `effect_value_tables`):
/// effects report their hooks in the order of their parameters, so the next entry is almost
/// always the one asked for (O(1)); otherwise a scan of the effect's few parameters. A parameter
/// the table lacks (a built-in effect's) reads 0, as the map did.
struct EffectValueCursor<'a> {
    table: &'a [(EffectParam, f64)],
    next: usize,
}

impl EffectValueCursor<'_> {
    #[inline]
    fn value(&mut self, param: EffectParam) -> f64 {
        if let Some((p, v)) = self.table.get(self.next)
            && *p == param
        {
            self.next += 1;
            return *v;
        }
        match self.table.iter().position(|(p, _)| *p == param) {
            Some(k) => {
                self.next = k + 1;
                self.table[k].1
            }
            None => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};
    use vatcal_core::{CellFile, ParamId, ParamSet};
    use vatcal_gravity_torque::gravity_torques;

    use super::*;

    fn fixture(name: &str) -> Model {
        let path = format!("{}/../../fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
        Model::from_cell(&CellFile::load(&path).expect("fixture loads")).expect("model")
    }

    /// The lean FK (backward point pass, links reused for the compliance) equals the full
    /// chain (frames composed forwards) to rounding, on every fixture, with and without
    /// compliance.
    #[test]
    fn fast_tool_point_equals_the_full_chain() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let mut worst: f64 = 0.0;
        for name in ["meca500-zaber.toml", "ur5e.toml", "meca500-table.toml"] {
            let nominal = fixture(name);
            let mut compliant = nominal.clone();
            for j in 1..=compliant.joint_count() {
                if compliant.is_revolute(j) {
                    compliant.set_param(ParamId::Compliance(j as u8), 3e-4).expect("c");
                }
            }
            for model in [&nominal, &compliant] {
                let t = model.tcp(model.tcp_ids()[0]).expect("a TCP");
                for _ in 0..200 {
                    let q: Vec<f64> = model
                        .joint_limits()
                        .iter()
                        .map(|(lo, hi)| lo + (hi - lo) * rng.random::<f64>())
                        .collect();
                    let q = JointVector::from_slice(&q).expect("q");
                    let fast = model.fast_tool_point(&q, &t);
                    let full = model.chain(&q).tool_point(&t);
                    worst = worst.max((fast - full).norm());
                }
            }
        }
        assert!(worst < 1e-12, "fast FK differs from the full chain by {worst:e} mm");
    }

    /// The lean FK with compliance as it was before the model kept a `GravityModel` (links
    /// built per row, torques from the mass model by `vatcal_gravity_torque::gravity_torques`,
    /// the point carried backwards): the reference the proptest below compares against.
    fn reference_tool_point(model: &Model, q: &JointVector, t: &Vector3<f64>) -> Vector3<f64> {
        let (n, qs) = (model.n, q.as_slice());
        let mut links = [Frame::identity(); MAX_JOINTS];
        for k in 0..n {
            let (th, d) = match model.kinds[k] {
                JointKind::Revolute => (qs[k] + model.rows[k].theta_offset, model.rows[k].d),
                JointKind::Prismatic => (model.rows[k].theta_offset, qs[k] + model.rows[k].d),
            };
            links[k] = rz_tz(&model.row_fixed[k], th, d);
        }
        let tau = gravity_torques(
            &links[..n],
            &model.kinds[..n],
            &model.base_frame.r,
            &model.masses,
            &model.gravity,
        );
        let mut v = *t;
        for k in (0..n).rev() {
            let delta = model.compliance[k] * tau[k];
            if model.kinds[k].is_revolute() && delta != 0.0 {
                let (s, c) = small_angle_sin_cos(delta);
                v = Vector3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z);
            }
            v = links[k].transform_point(&v);
        }
        model.base_frame.transform_point(&v)
    }

    /// Torques of `model` at `q` from its public state only (frames of the full chain, mass
    /// model, base rotation, gravity), by the free function of `vatcal-gravity-torque`.
    fn torques_from_public_state(model: &Model, q: &JointVector) -> [f64; MAX_JOINTS] {
        let frames =
            model.chain_full(q, &MeasurementContext::default(), false, Some(&[0.0; MAX_JOINTS])).frames;
        let n = model.joint_count();
        let links: Vec<Frame> = (0..n).map(|k| frames[k].inverse().compose(&frames[k + 1])).collect();
        gravity_torques(&links, model.joint_kinds(), &model.base_frame().r, model.masses(), &model.gravity())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The lean FK (stored `GravityModel`, links shared by the torque pass and the point
        /// pass) equals the FK before that change to rounding (1e-14 of the distance from the world
        /// origin, about 10 ulps), on random poses and random
        /// parameters (every built-in parameter perturbed, compliance on every revolute
        /// joint, masses scaled) of the canonical cell, the UR5e and the Meca500 on a table.
        #[test]
        fn lean_fk_equals_the_previous_fk(
            seed in any::<u64>(),
            mass_scale in 0.5..2.0f64,
            compliance in -2e-3..2e-3f64,
        ) {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            for name in ["meca500-zaber.toml", "ur5e.toml", "meca500-table.toml"] {
                let mut model = fixture(name);
                let params = ParamSet::all_builtin_chain(model.joint_kinds(), &model.tcp_ids(), &model.position_ids());
                for id in params.iter() {
                    let scale = match id.unit() {
                        vatcal_core::params::ParamUnit::Rad => 0.02,
                        vatcal_core::params::ParamUnit::Mm => 2.0,
                        _ => 0.0,
                    };
                    let v = model.param(*id).expect("param") + scale * (rng.random::<f64>() - 0.5);
                    model.set_param(*id, v).expect("set");
                }
                for j in 1..=model.joint_count() {
                    if model.is_revolute(j) {
                        let c = compliance * (0.5 + rng.random::<f64>());
                        model.set_param(ParamId::Compliance(j as u8), c).expect("c");
                    }
                }
                let mut masses = model.masses().clone();
                for b in masses.bodies_mut() {
                    b.mass_kg *= mass_scale;
                }
                model.set_masses(masses);
                for _ in 0..8 {
                    let q: Vec<f64> =
                        model.joint_limits().iter().map(|(lo, hi)| lo + (hi - lo) * rng.random::<f64>()).collect();
                    let q = JointVector::from_slice(&q).expect("q");
                    for t in model.tcp_ids() {
                        let tcp = model.tcp(t).expect("tcp");
                        let new = model.tcp_position(&q, t).expect("fk");
                        let old = reference_tool_point(&model, &q, &tcp);
                        // a few ulps of a point up to ~1 m from the origin (1 ulp of 865 mm is
                        // 1.1e-13 mm): the three paths round differently, not more
                        let tol = 1e-14 * (1.0 + old.norm());
                        prop_assert!((new - old).norm() <= tol, "{name}: lean FK {new} vs previous {old}");
                        let full = model.chain(&q).tool_point(&tcp);
                        prop_assert!((new - full).norm() <= tol, "{name}: lean FK {new} vs full chain {full}");
                    }
                }
            }
        }
    }

    /// The model's stored gravity constants follow every way its torques can change: base
    /// orientation (set_param, set_params), masses (set_masses), effects switched on, and a
    /// write/read round trip through the cell file.
    #[test]
    fn gravity_model_follows_every_mutation() {
        let q = JointVector::from_mm_deg(120.0, [15.0, -25.0, 35.0, -45.0, 55.0, -65.0]);
        let check = |m: &Model, what: &str| {
            let tau = m.gravity_torques(&q);
            let reference = torques_from_public_state(m, &q);
            let worst = tau.iter().zip(&reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-12, "{what}: torques {tau:?} vs {reference:?}");
            // and the FK with compliance uses them
            let t = m.tcp(1).expect("tcp 1");
            let fk = m.tcp_position(&q, 1).expect("fk");
            assert!((fk - reference_tool_point(m, &q, &t)).norm() < 1e-12, "{what}: FK");
        };
        let mut model = fixture("meca500-zaber.toml");
        for j in 2..=7u8 {
            model.set_param(ParamId::Compliance(j), 5e-4).expect("c");
        }
        check(&model, "loaded");
        let before = model.gravity_torques(&q);
        model.set_param(ParamId::Base(vatcal_core::params::BaseParam::Alpha), 0.3).expect("alpha");
        check(&model, "base alpha via set_param");
        assert!(model.gravity_torques(&q) != before, "tilting the base changes the torques");
        let set = ParamSet(vec![ParamId::Base(vatcal_core::params::BaseParam::Beta)]);
        model.set_params(&set, &[-0.2]).expect("beta");
        check(&model, "base beta via set_params");
        let before = model.gravity_torques(&q);
        let mut masses = model.masses().clone();
        masses.bodies_mut()[3].mass_kg *= 3.0;
        model.set_masses(masses);
        check(&model, "set_masses");
        assert!(model.gravity_torques(&q) != before, "heavier link 4 changes the torques");
        model.enable_effect(vatcal_core::EffectSpec::ToolFrame).expect("tool frame");
        check(&model, "effect switched on");
        let reloaded = Model::from_cell(&model.to_cell()).expect("round trip");
        check(&reloaded, "cell file round trip");
    }
}
