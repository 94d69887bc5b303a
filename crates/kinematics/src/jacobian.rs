//! Analytic parameter Jacobians of TCP positions and of measurement predictions.
//!
//! Every parameter enters the chain as an elementary motion of a known frame: a rotation about
//! a world axis `w` through a point `o` (column `w × (p - o)`) or a translation along `v`
//! (column `v`), scaled by the derivative of the joint angle / polynomial with respect to the
//! parameter. Gravity torques are held fixed (paper Section 4.4): the column of `c_i` is
//! `(∂p/∂theta_i) tau_i`.
//!
//! Columns of effect parameters whose effect is *not* switched on are the derivatives at a zero
//! value of that effect — exactly what a score test for adding the effect needs.

use nalgebra::{Matrix3xX, Vector3};
use vatcal_core::effects::{ErrorEffect, Hook, hook_of};
use vatcal_core::params::{Axis, BaseParam, EffectParam};
use vatcal_core::{JointVector, Measurement, MeasurementContext, ParamId, Target};

use crate::chain::{Chain, InsertAxes};
use crate::model::{Model, ModelError};

fn unit(axis: Axis) -> Vector3<f64> {
    let mut v = Vector3::zeros();
    v[axis.index()] = 1.0;
    v
}

impl Model {
    fn zero_insert(frame: &vatcal_core::Frame) -> InsertAxes {
        InsertAxes {
            tx: frame.x_axis(),
            ty: frame.y_axis(),
            tz: frame.z_axis(),
            rot: [frame.x_axis(), frame.y_axis(), frame.z_axis()],
            o: frame.p,
        }
    }

    /// One Jacobian column ∂p/∂param of the world point `p` (given in the tool frame as `t`).
    fn column(
        &self,
        chain: &Chain,
        q: &JointVector,
        ctx: &MeasurementContext,
        tcp: u32,
        p: &Vector3<f64>,
        id: ParamId,
    ) -> Result<Vector3<f64>, ModelError> {
        let rot = |w: Vector3<f64>, o: Vector3<f64>| w.cross(&(p - o));
        let thermal = |i: u8| if self.is_revolute(i as usize) { chain.thermal_factor } else { 1.0 };
        let dtheta = |j: u8| {
            let a = &chain.axes[j as usize - 1];
            rot(a.z, a.o)
        };
        let row_ok = |i: u8| (1..=self.n).contains(&(i as usize));
        // every arm checks that the parameter exists in the model (as `has_param` would), so
        // that a column costs no lookup for the common parameters; `tcp` itself is checked by
        // the caller
        Ok(match id {
            ParamId::Alpha(i) if row_ok(i) => {
                let a = &chain.axes[i as usize - 1];
                rot(a.x_prev, a.o_prev)
            }
            ParamId::A(i) if row_ok(i) => chain.axes[i as usize - 1].x_prev * thermal(i),
            ParamId::Beta(i) if row_ok(i) => {
                let a = &chain.axes[i as usize - 1];
                rot(a.y_beta, a.o_beta)
            }
            ParamId::ThetaOffset(i) if row_ok(i) => dtheta(i),
            ParamId::D(i) if row_ok(i) => chain.axes[i as usize - 1].z * thermal(i),
            ParamId::Compliance(j) if self.is_revolute(j as usize) => {
                let tau = if chain.torques_evaluated {
                    chain.torques[j as usize - 1]
                } else {
                    self.gravity_torques(q)[j as usize - 1]
                };
                dtheta(j) * tau
            }
            ParamId::Base(b) => {
                let o = chain.frames[0].p;
                let (sa, ca) = self.base[3].sin_cos();
                match b {
                    BaseParam::X => Vector3::x(),
                    BaseParam::Y => Vector3::y(),
                    BaseParam::Z => Vector3::z(),
                    BaseParam::Alpha => rot(Vector3::x(), o),
                    BaseParam::Beta => rot(Vector3::new(0.0, ca, sa), o),
                    BaseParam::Gamma => rot(chain.frames[0].z_axis(), o),
                }
            }
            ParamId::Tcp { id: t, axis } if t == tcp => chain.tool.r * unit(axis),
            ParamId::Tcp { id: t, .. } if self.tcp(t).is_some() => Vector3::zeros(),
            ParamId::Position { id: pos, .. } if self.position(pos).is_some() => Vector3::zeros(),
            ParamId::Plane { id: pl, .. } if self.plane(pl).is_some() => Vector3::zeros(),
            ParamId::Effect(e) => self.effect_column(chain, q, ctx, p, e)?,
            _ => return Err(ModelError::ParamNotInModel(id.name())),
        })
    }

    /// Column of an effect parameter: the parameter's coefficient on its [`Hook`] (from the
    /// effect's module) times the hook's column.
    fn effect_column(
        &self,
        chain: &Chain,
        q: &JointVector,
        ctx: &MeasurementContext,
        p: &Vector3<f64>,
        e: EffectParam,
    ) -> Result<Vector3<f64>, ModelError> {
        let missing = || ModelError::ParamNotInModel(ParamId::Effect(e).name());
        let effect = e.kind().effect().ok_or_else(missing)?;
        if !self.effect_values.contains_key(&ParamId::Effect(e)) {
            // an effect that is not switched on: its column exists where the effect could be
            let owner = effect.owner(&e).ok_or_else(missing)?;
            effect.check(&owner, &self.chain_info(&[], &[])).map_err(|_| missing())?;
        }
        // the gravity loads the chain was evaluated with (held fixed, as for the compliances;
        // `jacobian_into` evaluates the ones the requested columns need, once per sample)
        let inputs = self.effect_inputs(q, ctx, chain.carriage_moment, chain.link_moments, &chain.torques);
        let (hook, coefficient) = hook_of(e, &inputs).ok_or_else(missing)?;
        Ok(self.hook_column(chain, p, hook).ok_or_else(missing)? * coefficient)
    }

    /// ∂p/∂h of the world point `p` for a unit change of hook `h` at the chain's state; `None`
    /// when the chain lacks what the hook acts on (a revolute/prismatic joint, a guide).
    fn hook_column(&self, chain: &Chain, p: &Vector3<f64>, hook: Hook) -> Option<Vector3<f64>> {
        let rot = |w: Vector3<f64>, o: Vector3<f64>| w.cross(&(p - o));
        // the guide corrections act after the guide joint's frame g (1-based)
        let guide = || {
            let g = self.guide? + 1;
            Some(chain.guide.unwrap_or_else(|| Self::zero_insert(&chain.frames[g])))
        };
        let tool = || chain.tool_axes.unwrap_or_else(|| Self::zero_insert(&chain.frames[self.n]));
        Some(match hook {
            Hook::Joint(j) => {
                let a = chain.axes[..self.n].get((j as usize).wrapping_sub(1))?;
                if self.is_revolute(j as usize) { rot(a.z, a.o) } else { a.z }
            }
            Hook::GuideShift(Axis::X) => guide()?.tx,
            Hook::GuideShift(Axis::Y) => guide()?.ty,
            Hook::GuideShift(Axis::Z) => return None,
            Hook::GuideRotation(axis) => {
                let ax = guide()?;
                rot(ax.rot[axis.index()], ax.o)
            }
            Hook::ToolShift(Axis::X) => tool().tx,
            Hook::ToolShift(Axis::Y) => tool().ty,
            Hook::ToolRotation(axis @ (Axis::X | Axis::Y)) => {
                let ax = tool();
                rot(ax.rot[axis.index()], ax.o)
            }
            Hook::ToolShift(Axis::Z) | Hook::ToolRotation(Axis::Z) => return None,
            Hook::LinkRotation { joint, axis: axis @ (Axis::X | Axis::Y) } => {
                let k = (joint as usize).checked_sub(1).filter(|k| *k < self.n)?;
                let ax = chain.link_axes[k].unwrap_or_else(|| Self::zero_insert(&chain.frames[k + 1]));
                rot(ax.rot[axis.index()], ax.o)
            }
            Hook::LinkRotation { .. } => return None,
            Hook::LinkShift { joint, axis } => {
                let k = (joint as usize).checked_sub(1).filter(|k| *k < self.n)?;
                let ax = chain.link_axes[k].unwrap_or_else(|| Self::zero_insert(&chain.frames[k + 1]));
                [ax.tx, ax.ty, ax.tz][axis.index()]
            }
            Hook::LengthScale => {
                let mut col = Vector3::zeros();
                for k in (0..self.n).filter(|k| self.kinds[*k].is_revolute()) {
                    let a = &chain.axes[k];
                    col += a.x_prev * self.rows[k].a + a.z * self.rows[k].d;
                }
                col
            }
        })
    }

    /// Analytic Jacobian of the world position of TCP `tcp` with respect to `params`, written
    /// column-major into `out` (`out[3*j..3*j+3]` = column j; length `3 * params.len()`).
    /// Returns the TCP position. Units: mm per (param unit).
    ///
    /// # Panics
    /// If `out.len() != 3 * params.len()` (a programming error).
    #[track_caller]
    pub fn jacobian_into(
        &self,
        q: &JointVector,
        ctx: &MeasurementContext,
        tcp: u32,
        params: &[ParamId],
        out: &mut [f64],
    ) -> Result<Vector3<f64>, ModelError> {
        assert_eq!(out.len(), 3 * params.len(), "jacobian_into: out has the wrong length");
        let t = self.tcp_or_err(tcp)?;
        self.check_joint_count(q)?;
        // the gravity loads the columns need, once per sample (the chain evaluates the ones its
        // switched-on effects need itself)
        let needs = |f: fn(&dyn ErrorEffect) -> bool| {
            params.iter().any(|p| matches!(p, ParamId::Effect(e) if e.kind().effect().is_some_and(f)))
        };
        let needs_tau =
            params.iter().any(|p| matches!(p, ParamId::Compliance(_))) || needs(|e| e.needs_torques());
        let moment = (needs(|e| e.needs_carriage_moment()) && !self.effects_need_moment)
            .then(|| self.carriage_moment(q));
        let link_moments = (needs(|e| e.needs_link_moments()) && !self.effects_need_link_moments)
            .then(|| self.link_bending_moments(q));
        let chain = self.chain_inner(q, ctx, needs_tau, None, moment, link_moments);
        let p = chain.tool_point(&t);
        for (j, id) in params.iter().enumerate() {
            let c = self.column(&chain, q, ctx, tcp, &p, *id)?;
            out[3 * j..3 * j + 3].copy_from_slice(c.as_slice());
        }
        Ok(p)
    }

    /// Analytic Jacobian (3 × n) of TCP `tcp`'s world position at `q` (no per-sample context).
    ///
    /// # Examples
    /// The column of `d_4` against a central difference of the forward kinematics:
    /// ```
    /// use vatcal_core::{CellFile, ParamId};
    /// use vatcal_kinematics::{JointVector, Model};
    ///
    /// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?)?;
    /// let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    /// let params = [ParamId::D(4), ParamId::ThetaOffset(3)];
    /// let j = model.jacobian(&q, 1, &params)?;
    /// let h = 1e-6;
    /// let (mut plus, mut minus) = (model.clone(), model.clone());
    /// plus.set_param(ParamId::D(4), model.param(ParamId::D(4))? + h)?;
    /// minus.set_param(ParamId::D(4), model.param(ParamId::D(4))? - h)?;
    /// let fd = (plus.tcp_position(&q, 1)? - minus.tcp_position(&q, 1)?) / (2.0 * h);
    /// assert!((fd - j.column(0)).norm() < 1e-6);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`ModelError::UnknownTcp`]; [`ModelError::ParamNotInModel`] for a parameter the model lacks.
    pub fn jacobian(
        &self,
        q: &JointVector,
        tcp: u32,
        params: &[ParamId],
    ) -> Result<Matrix3xX<f64>, ModelError> {
        let mut out = vec![0.0; 3 * params.len()];
        self.jacobian_into(q, &MeasurementContext::default(), tcp, params, &mut out)?;
        Ok(Matrix3xX::from_column_slice(&out))
    }

    /// What the model predicts a measurement should read: `FK - calibration_position` for a
    /// probe measurement (ideally 0), `FK` for a tracker measurement \[mm\], the rotation
    /// vector `log(R_model · R_measuredᵀ)` for an orientation measurement (ideally 0) \[rad\].
    pub fn predict(&self, m: &Measurement) -> Result<Vector3<f64>, ModelError> {
        if let Target::Orientation { rotation } = &m.target {
            return self.orientation_predict(m, rotation);
        }
        if let Some((plane, normal)) = crate::plane::plane_of(m) {
            return self.plane_predict(m, plane, normal);
        }
        let p = self.tcp_position_ctx(&m.q, &m.context, m.tcp)?;
        Ok(match m.target {
            Target::Probe { position } => p - self.position_or_err(position)?,
            // orientation measurements returned above
            Target::Tracker { .. } | Target::Orientation { .. } | Target::Plane { .. } => p,
        })
    }

    /// Residual of a measurement: `calibration_position - FK` (probe) or `measured_xyz - FK`
    /// (tracker) \[mm\]; `log(R_measured · R_modelᵀ)` (orientation) \[rad\].
    pub fn residual(&self, m: &Measurement) -> Result<Vector3<f64>, ModelError> {
        if let Target::Orientation { rotation } = &m.target {
            return Ok(-self.orientation_predict(m, rotation)?);
        }
        if let Some((plane, normal)) = crate::plane::plane_of(m) {
            return Ok(-self.plane_predict(m, plane, normal)?);
        }
        let p = self.tcp_position_ctx(&m.q, &m.context, m.tcp)?;
        Ok(match m.target {
            Target::Probe { position } => self.position_or_err(position)? - p,
            Target::Tracker { xyz_mm } => xyz_mm - p,
            // returned above
            Target::Orientation { .. } | Target::Plane { .. } => Vector3::zeros(),
        })
    }

    /// Jacobian of [`Model::predict`] (= minus the Jacobian of [`Model::residual`]) with respect
    /// to `params`, column-major into `out`; returns the residual. Calibration-position
    /// parameters contribute `-e_axis` to probe measurements at that position. Orientation
    /// measurements get finite-difference rows (see [`Model::tool_rotation_ctx`] and the
    /// `orientation` module).
    ///
    /// # Panics
    /// If `out.len() != 3 * params.len()`.
    #[track_caller]
    pub fn measurement_jacobian_into(
        &self,
        m: &Measurement,
        params: &[ParamId],
        out: &mut [f64],
    ) -> Result<Vector3<f64>, ModelError> {
        if let Target::Orientation { rotation } = &m.target {
            assert_eq!(out.len(), 3 * params.len(), "measurement_jacobian_into: out has the wrong length");
            return self.orientation_jacobian_into(m, rotation, params, out);
        }
        if let Some((plane, normal)) = crate::plane::plane_of(m) {
            assert_eq!(out.len(), 3 * params.len(), "measurement_jacobian_into: out has the wrong length");
            return self.plane_jacobian_into(m, plane, normal, params, out);
        }
        let p = self.jacobian_into(&m.q, &m.context, m.tcp, params, out)?;
        match m.target {
            Target::Probe { position } => {
                let target = self.position_or_err(position)?;
                for (j, id) in params.iter().enumerate() {
                    if let ParamId::Position { id: pid, axis } = id
                        && *pid == position
                    {
                        out[3 * j + axis.index()] -= 1.0;
                    }
                }
                Ok(target - p)
            }
            Target::Tracker { xyz_mm } => Ok(xyz_mm - p),
            // returned above
            Target::Orientation { .. } | Target::Plane { .. } => Ok(Vector3::zeros()),
        }
    }
}
