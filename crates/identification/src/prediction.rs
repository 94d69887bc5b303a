//! What a fit predicts with its uncertainty: the covariance of a TCP's world position.

use nalgebra::{Matrix3, Vector3};
use vatcal_core::JointVector;

use crate::{Identification, IdentifyError};

impl Identification {
    /// Covariance \[mm²\] of the predicted world position of TCP `tcp` at joints `q`:
    /// `J_q Cov J_qᵀ` with `J_q` the 3 × L Jacobian of the calibrated model.
    pub fn predicted_position_covariance(
        &self,
        q: &JointVector,
        tcp: u32,
    ) -> Result<Matrix3<f64>, IdentifyError> {
        let j = self.model.jacobian(q, tcp, &self.params.0)?;
        Ok(&j * &self.covariance * j.transpose())
    }

    /// Standard deviation \[mm\] of each world coordinate of the predicted position of TCP `tcp`
    /// at `q` (square roots of the diagonal of [`Self::predicted_position_covariance`]).
    pub fn predicted_position_sigma(&self, q: &JointVector, tcp: u32) -> Result<Vector3<f64>, IdentifyError> {
        let c = self.predicted_position_covariance(q, tcp)?;
        Ok(Vector3::new(c[(0, 0)].max(0.0).sqrt(), c[(1, 1)].max(0.0).sqrt(), c[(2, 2)].max(0.0).sqrt()))
    }
}
