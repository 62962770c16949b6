//! Registration: [`SolidCloud`] (a cloud prepared once: downsampled, kd-tree, covariances) and
//! [`solid_register`], the metric pose `T_query_candidate` between two prepared clouds.

use solid_lidar::reg::{register, PreparedCloud, RegConfig, IDENTITY};

use crate::config::SolidRegConfig;
use crate::SolidStatus;
use crate::{flat_pose, guard, new_handle, nonnull, out, points, pose_3x4, release, with_points};

/// A point cloud prepared for registration (about 105 bytes a point kept).
///
/// Threads: read-only once made: may be shared, and used in several registrations at once.
pub struct SolidCloud {
    cloud: PreparedCloud,
}

/// The outcome of [`solid_register`].
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct SolidRegistration {
    /// `T_query_candidate`, row-major 4x4: `p_query = pose * p_candidate`.
    pub pose: [f64; 16],
    /// The smaller of the two overlaps, in [0, 1].
    pub fitness: f64,
    /// Fraction of the query's points within `inlier_distance` of a moved candidate point.
    pub overlap_query: f64,
    /// Fraction of the moved candidate's points within `inlier_distance` of a query point.
    pub overlap_candidate: f64,
    /// `fitness` over points not on horizontal surfaces.
    pub structure_fitness: f64,
    /// Root mean square distance (metres) of the candidate's inliers to the query.
    pub rmse: f64,
    /// Number of candidate inliers behind `rmse`.
    pub inliers: usize,
    /// Gauss-Newton iterations, over both levels.
    pub iterations: usize,
    /// Whether the fine level converged with a well-posed system.
    pub converged: bool,
    /// Smallest eigenvalue of the rotation block of the information matrix, per correspondence.
    pub rotation_information: f64,
    /// Smallest eigenvalue of the translation block, per correspondence (a corridor or a single
    /// wall makes it small).
    pub translation_information: f64,
}

/// The configuration of a handle, or the defaults for NULL.
unsafe fn reg_config(cfg: *const SolidRegConfig) -> RegConfig {
    cfg.as_ref().map_or_else(RegConfig::default, |c| c.cfg)
}

/// Prepares a cloud (sensor frame; see [`crate::SolidPoints`]) with `config` (NULL: the
/// defaults) in `*out`; release it with [`solid_cloud_free`].
#[no_mangle]
pub unsafe extern "C" fn solid_cloud_new(
    points_in: *const crate::SolidPoints,
    config: *const SolidRegConfig,
    out_cloud: *mut *mut SolidCloud,
) -> SolidStatus {
    new_handle("solid_cloud_new", out_cloud, "out_cloud", || {
        let cfg = reg_config(config);
        let pts = points(points_in)?;
        let cloud = with_points!(pts, |p| PreparedCloud::new(p, &cfg))?;
        Ok(SolidCloud { cloud })
    })
}

/// Releases a prepared cloud (NULL: nothing).
#[no_mangle]
pub unsafe extern "C" fn solid_cloud_free(cloud: *mut SolidCloud) {
    release(cloud);
}

/// Registers `candidate` to `query` from the initial guess `init` (NULL: identity; else a
/// row-major 4x4 rigid transform), with `config` (NULL: the defaults; it must be the
/// configuration both clouds were prepared with), and writes the outcome to `*result`.
#[no_mangle]
pub unsafe extern "C" fn solid_register(
    query: *const SolidCloud,
    candidate: *const SolidCloud,
    init: *const f64,
    config: *const SolidRegConfig,
    result: *mut SolidRegistration,
) -> SolidStatus {
    guard("solid_register", || {
        let q = &nonnull(query, "query")?.cloud;
        let c = &nonnull(candidate, "candidate")?.cloud;
        let res = out(result, "result")?;
        let start = match init.as_ref() {
            None => IDENTITY,
            Some(_) => {
                let m = pose_3x4(&*init.cast::<[f64; 16]>(), "init")?;
                [
                    [m[0], m[1], m[2], m[3]],
                    [m[4], m[5], m[6], m[7]],
                    [m[8], m[9], m[10], m[11]],
                    [0.0, 0.0, 0.0, 1.0],
                ]
            }
        };
        let r = register(q, c, &start, &reg_config(config))?;
        *res = SolidRegistration {
            pose: flat_pose(&r.pose),
            fitness: r.fitness,
            overlap_query: r.overlap_query,
            overlap_candidate: r.overlap_candidate,
            structure_fitness: r.structure_fitness,
            rmse: r.rmse,
            inliers: r.inliers,
            iterations: r.iterations,
            converged: r.converged,
            rotation_information: r.degeneracy.rotation,
            translation_information: r.degeneracy.translation,
        };
        Ok(())
    })
}
