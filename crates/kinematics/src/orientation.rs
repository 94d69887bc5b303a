//! Orientation measurements ([`Target::Orientation`]): the model's tool-frame rotation, the
//! rotation-vector residual and its parameter Jacobian.
//!
//! The measured rotation is compared with the tool-changer frame of the chain
//! ([`Chain::tool`](crate::Chain::tool): the flange frame N times the `tool-frame` effect when it
//! is on). The residual is `log(R_measured · R_modelᵀ)` \[rad\] in world axes; the prediction is
//! its negative `log(R_model · R_measuredᵀ)` (ideally 0, like a probe prediction).
//!
//! The Jacobian rows are **central finite differences** over the parameters (step
//! `1e-3 ×` [`ParamId::typical_scale`]): the analytic position Jacobian has no angular part. TCP
//! and position coordinates do not rotate the tool frame (zero columns); an effect parameter
//! whose effect is not switched on is differenced on a copy of the model with the effect on (the
//! derivative at zero, as the analytic columns give). Gravity loads are re-evaluated at each
//! step, unlike the analytic columns (a second-order difference).

use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use vatcal_core::{JointVector, Measurement, MeasurementContext, ParamId, rotation_error};

use crate::model::{Model, ModelError};

/// Relative finite-difference step (times the parameter's typical scale).
const FD_STEP: f64 = 1e-3;

impl Model {
    /// World rotation of the tool-changer frame at `q` with per-sample context `ctx`: what an
    /// orientation measurement observes.
    ///
    /// # Errors
    /// [`ModelError`] when `q` has the wrong number of joints.
    pub fn tool_rotation_ctx(
        &self,
        q: &JointVector,
        ctx: &MeasurementContext,
    ) -> Result<Matrix3<f64>, ModelError> {
        self.check_joint_count(q)?;
        Ok(self.chain_full(q, ctx, false, None).tool.r)
    }

    /// Predicted orientation error `log(R_model · R_measuredᵀ)` \[rad\] of a measurement of the
    /// tool-frame rotation `rotation` (module docs).
    pub(crate) fn orientation_predict(
        &self,
        m: &Measurement,
        rotation: &UnitQuaternion<f64>,
    ) -> Result<Vector3<f64>, ModelError> {
        let r = self.tool_rotation_ctx(&m.q, &m.context)?;
        Ok(rotation_error(&r, &rotation.to_rotation_matrix().into_inner()))
    }

    /// Finite-difference Jacobian of [`Model::orientation_predict`] with respect to `params`,
    /// column-major into `out` (module docs); returns the residual (minus the prediction).
    pub(crate) fn orientation_jacobian_into(
        &self,
        m: &Measurement,
        rotation: &UnitQuaternion<f64>,
        params: &[ParamId],
        out: &mut [f64],
    ) -> Result<Vector3<f64>, ModelError> {
        let base = self.orientation_predict(m, rotation)?;
        let mut work = self.clone();
        for (j, id) in params.iter().enumerate() {
            let col = match id {
                ParamId::Tcp { .. } | ParamId::Position { .. } | ParamId::Plane { .. } => Vector3::zeros(),
                _ => work.orientation_column(m, rotation, *id)?,
            };
            out[3 * j..3 * j + 3].copy_from_slice(col.as_slice());
        }
        Ok(-base)
    }

    /// A copy of the model with the effect that owns `id` switched on (at zero), for the
    /// finite-difference columns of a parameter the model lacks.
    ///
    /// # Errors
    /// [`ModelError::ParamNotInModel`] when no catalog effect owns `id` on this model.
    pub(crate) fn with_effect_of(&self, id: ParamId) -> Result<Model, ModelError> {
        let mut on = self.clone();
        if let ParamId::Effect(e) = id
            && let Some(spec) = e.kind().effect().and_then(|eff| eff.owner(&e))
        {
            on.enable_effect(spec)?;
        }
        if !on.has_param(id) {
            return Err(ModelError::ParamNotInModel(id.name()));
        }
        Ok(on)
    }

    /// One central-difference column; the model is restored afterwards.
    fn orientation_column(
        &mut self,
        m: &Measurement,
        rotation: &UnitQuaternion<f64>,
        id: ParamId,
    ) -> Result<Vector3<f64>, ModelError> {
        self.central_difference(id, &|model| model.orientation_predict(m, rotation))
    }

    /// Central difference of `f` with respect to parameter `id` (step `FD_STEP ×` its typical
    /// scale); the model is restored afterwards. A parameter of an effect that is not switched
    /// on is differenced on a copy with the effect on (the derivative at zero, as the analytic
    /// columns give).
    pub(crate) fn central_difference(
        &mut self,
        id: ParamId,
        f: &dyn Fn(&Model) -> Result<Vector3<f64>, ModelError>,
    ) -> Result<Vector3<f64>, ModelError> {
        if !self.has_param(id) {
            return self.with_effect_of(id)?.central_difference(id, f);
        }
        let v = self.param(id)?;
        let h = FD_STEP * id.typical_scale();
        self.set_param(id, v + h)?;
        let plus = f(self);
        self.set_param(id, v - h)?;
        let minus = f(self);
        self.set_param(id, v)?;
        Ok((plus? - minus?) / (2.0 * h))
    }
}
