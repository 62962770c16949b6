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
//! the rotation against the translation), the calibration the size. A rotational covariance of
//! `LOOP_SIGMA_ROT_DEG²` per axis is then added, because far points pin the rotation in the
//! Hessian more tightly than any registration gets it. So calibrated, the errors of true loops
//! weighed by it follow the χ² law with 6 degrees of freedom (docs/slam.md#calibration).

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
pub const LOOP_SIGMA_M: f64 = 0.009;

/// The floor (degrees, per axis, about the query's origin) on a loop's rotational standard
/// deviation: added as a covariance, calibrated on the true errors of the shared Avia walk and
/// the simulator, whose 100 m scans gave the Hessian 6× too small a rotational sigma; not the
/// simulator's own best fit (0.06°), as GNC-TLS lost a seed's true loops from 0.055° up
/// (docs/slam.md#calibration).
pub const LOOP_SIGMA_ROT_DEG: f64 = 0.05;

impl Registration {
    /// The information matrix of [`Registration::pose`] for a pose graph, row-major, translation
    /// first (x, y, z, then rotation about x, y, z, radians: the order of g2o's `EDGE_SE3:QUAT`;
    /// GTSAM's `Pose3` puts rotation first), for the error on the right of the measurement (see
    /// the module documentation): [`Registration::hessian`] carried over by the pose's adjoint
    /// and scaled so that its translation block's mean eigenvalue is `1 / LOOP_SIGMA_M²`
    /// ([`LOOP_SIGMA_M`]), with the covariance `LOOP_SIGMA_ROT_DEG²` ([`LOOP_SIGMA_ROT_DEG`])
    /// added on each axis of the rotation about the query's origin before the adjoint. Zeros when
    /// the registration has no Hessian.
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
        let h = h * (3.0 / (tr * LOOP_SIGMA_M * LOOP_SIGMA_M));
        // (H⁻¹ + diag(σ_r² I, 0))⁻¹ by Woodbury: defined where H is singular (a corridor).
        let sigma_r = LOOP_SIGMA_ROT_DEG.to_radians();
        let floor = Matrix3::identity() / (sigma_r * sigma_r);
        let Some(inner) = (floor + h.fixed_view::<3, 3>(0, 0)).try_inverse() else {
            return [[0.0; 6]; 6];
        };
        let hr = h.fixed_view::<6, 3>(0, 0);
        let h = h - hr * inner * hr.transpose();
        let info = ad.transpose() * h * ad;
        // (ω, v) → (v, ω).
        let k = |i: usize| (i + 3) % 6;
        core::array::from_fn(|i| core::array::from_fn(|j| info[(k(i), k(j))]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reg::IDENTITY;

    /// The covariance (g2o's order) of `info`.
    fn covariance(info: &Information) -> Matrix6<f64> {
        Matrix6::from_fn(|i, j| info[i][j]).try_inverse().unwrap()
    }

    #[test]
    fn identity_pose_only_reorders_scales_and_floors_the_rotation() {
        let mut r = Registration::failed(&IDENTITY);
        for i in 0..6 {
            r.hessian[i][i] = (i + 1) as f64;
        }
        r.hessian[0][4] = 0.5;
        r.hessian[4][0] = 0.5;
        let info = r.information();
        // The translation block's trace is 4 + 5 + 6 = 15: scaled to 3 / σ², the rotational
        // covariance σ_r² added, (ω, v) → (v, ω).
        let s = 3.0 / (15.0 * LOOP_SIGMA_M * LOOP_SIGMA_M);
        let mut want = (Matrix6::from_fn(|i, j| r.hessian[i][j]) * s)
            .try_inverse()
            .unwrap();
        for i in 0..3 {
            want[(i, i)] += LOOP_SIGMA_ROT_DEG.to_radians().powi(2);
        }
        let got = covariance(&info);
        let k = |i: usize| (i + 3) % 6;
        for i in 0..6 {
            for j in 0..6 {
                let scale = (want[(k(i), k(i))] * want[(k(j), k(j))]).sqrt();
                assert!(
                    (got[(i, j)] - want[(k(i), k(j))]).abs() < 1e-9 * scale,
                    "{i} {j}"
                );
            }
        }
        assert_eq!(Registration::failed(&IDENTITY).information(), [[0.0; 6]; 6]);
    }

    #[test]
    fn far_points_do_not_pin_the_rotation_below_the_floor() {
        // Points 100 m out: the Hessian's rotation block 10⁴× its translation block's, a
        // rotational sigma of 10⁻⁴ rad (0.006°) from the Hessian alone.
        let mut r = Registration::failed(&IDENTITY);
        for i in 0..6 {
            r.hessian[i][i] = if i < 3 { 1e4 } else { 1.0 };
        }
        let cov = covariance(&r.information());
        let floor = LOOP_SIGMA_ROT_DEG.to_radians();
        for i in 3..6 {
            let sigma = cov[(i, i)].sqrt();
            assert!(
                sigma >= floor && sigma < 1.01 * floor,
                "{sigma} against {floor}"
            );
        }
        // The translation keeps its sigma.
        assert!((cov[(0, 0)].sqrt() - LOOP_SIGMA_M).abs() < 1e-9);
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
