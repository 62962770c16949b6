//! The information matrix of a registered pose, as a pose graph reads it.
//!
//! The solver's Hessian ([`Registration::hessian`]) is in its own coordinates: rotation first, a
//! perturbation applied on the left in the query's frame, in GICP's Mahalanobis units. A pose
//! graph's factor between `T_world_query` and `T_world_candidate` measuring `T_query_candidate`
//! (g2o's `EDGE_SE3:QUAT`, GTSAM's `BetweenFactor<Pose3>`) has the error `ξ` with
//! `measured⁻¹ · inv(T_world_query) · T_world_candidate = Exp(ξ)`: a perturbation on the right,
//! in the candidate's frame. [`Registration::information`] carries the Hessian over (through the
//! adjoint of the pose) and scales it so that its translation block has the mean eigenvalue
//! `1 / LOOP_SIGMA_M²`: the Hessian gives the shape (which directions the scene constrains, and
//! the rotation against the translation), the calibration the size, so that the errors of true
//! loops weighed by it follow the χ² law with 6 degrees of freedom (docs/slam.md#calibration).

use nalgebra::{Matrix3, Matrix6, Vector3};

use super::Registration;

/// A 6×6 information matrix, row-major.
pub type Information = [[f64; 6]; 6];

/// The typical standard deviation (metres) of a loop's translation per axis, which sets the size
/// of [`Registration::information`]. The correspondences of one registration are far from
/// independent (neighbouring points share surfaces and the voxel grid), so the Hessian's own
/// size, which grows with the number of points, is far too confident; its size normalised to
/// this sigma was calibrated against the true errors of loops on the shared Avia walk and the
/// simulator, where it beat a fixed factor on the Hessian (docs/slam.md#calibration).
pub const LOOP_SIGMA_M: f64 = 0.01;

impl Registration {
    /// The information matrix of [`Registration::pose`] for a pose graph, row-major, translation
    /// first (x, y, z, then rotation about x, y, z, radians: the order of g2o's `EDGE_SE3:QUAT`;
    /// GTSAM's `Pose3` puts rotation first), for the error on the right of the measurement (see
    /// the module documentation): [`Registration::hessian`] carried over by the pose's adjoint
    /// and scaled so that its translation block's mean eigenvalue is `1 / LOOP_SIGMA_M²`
    /// ([`LOOP_SIGMA_M`]). Zeros when the registration has no Hessian.
    pub fn information(&self) -> Information {
        let h = Matrix6::from_fn(|i, j| self.hessian[i][j]);
        let p = &self.pose;
        let r = Matrix3::from_fn(|i, j| p[i][j]);
        let t = Vector3::new(p[0][3], p[1][3], p[2][3]);
        // Exp(δ)·T = T·Exp(Ad(T⁻¹)δ), so δ = Ad(T)·ξ with Ad(T) = [[R, 0], [[t]×R, R]] for (ω, v).
        let mut ad = Matrix6::zeros();
        ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
        ad.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(t.cross_matrix() * r));
        let tr = h[(3, 3)] + h[(4, 4)] + h[(5, 5)];
        if !(tr > 0.0 && tr.is_finite()) {
            return [[0.0; 6]; 6];
        }
        let info = ad.transpose() * h * ad * (3.0 / (tr * LOOP_SIGMA_M * LOOP_SIGMA_M));
        // (ω, v) → (v, ω).
        let k = |i: usize| (i + 3) % 6;
        core::array::from_fn(|i| core::array::from_fn(|j| info[(k(i), k(j))]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reg::IDENTITY;

    #[test]
    fn identity_pose_only_reorders_and_scales() {
        let mut r = Registration::failed(&IDENTITY);
        for i in 0..6 {
            r.hessian[i][i] = (i + 1) as f64;
        }
        r.hessian[0][4] = 0.5;
        r.hessian[4][0] = 0.5;
        let info = r.information();
        // The translation block's trace is 4 + 5 + 6 = 15: scaled to 3 / σ².
        let s = 3.0 / (15.0 * LOOP_SIGMA_M * LOOP_SIGMA_M);
        for (i, row) in info.iter().enumerate() {
            let want = ((i + 3) % 6 + 1) as f64 * s;
            assert!((row[i] - want).abs() < 1e-9 * want);
        }
        // Rotation x (solver row 0) and translation y (solver row 4) → g2o rows 3 and 1.
        assert!((info[3][1] - 0.5 * s).abs() < 1e-9 * s);
        assert!((info[1][3] - 0.5 * s).abs() < 1e-9 * s);
        assert_eq!(Registration::failed(&IDENTITY).information(), [[0.0; 6]; 6]);
    }

    #[test]
    fn a_translated_pose_couples_rotation_and_translation() {
        // Pure translation information about the query's origin, with the candidate 10 m along
        // x: a rotation about z at the candidate moves nothing in the query frame's translation
        // block, so the information on it seen from the candidate is that of a 10 m lever arm.
        let mut r = Registration::failed(&IDENTITY);
        r.pose[0][3] = 10.0;
        for i in 3..6 {
            r.hessian[i][i] = 1.0;
        }
        let info = r.information();
        // ξ = ω_z e_z at the candidate ⇒ δ_v = [t]× ω = (0, 10 ω, 0): information 100.
        let s = 1.0 / (LOOP_SIGMA_M * LOOP_SIGMA_M);
        assert!((info[5][5] - 100.0 * s).abs() < 1e-9 * s);
        assert!((info[0][0] - s).abs() < 1e-9 * s);
    }
}
