//! Point-cloud registration: the metric 6-DoF pose of a loop (feature `alloc`).
//!
//! [`register`] estimates `T_query_candidate` (SPEC §3: `p_query ≈ T · p_candidate`) between two
//! [`PreparedCloud`]s by generalized ICP (GICP, Segal et al. 2009) or point-to-plane ICP, coarse
//! to fine over voxel levels, with a robust kernel, and reports what a loop-closure gate needs:
//! the overlap of each cloud with the other, the inlier RMSE, the iteration count, whether it
//! converged, and how well the pose is constrained (the smallest eigenvalues of the rotation and
//! translation blocks of the final information matrix, and of the translation's marginal).
//! [`register_hypotheses`] runs it from several initial yaws (the local minima of the A-SOLiD
//! shift cost, [`crate::heading_minima`], plus 0°) and [`Gate`] accepts or rejects the outcome.
//!
//! Preprocessing (downsampling, kd-tree, covariances) is separate from the registration loop,
//! as in koide3/small_gicp: a place is prepared once ([`PreparedCloud::new`]) and registered
//! against as many candidates as needed; the loop itself allocates nothing. The fine points of
//! a prepared cloud travel between robots in a compact quantised form ([`wire`]).
//!
//! ```
//! use solid_lidar::reg::{register, PreparedCloud, RegConfig, IDENTITY};
//! use solid_lidar::Points;
//!
//! // A corner of three walls, seen from two poses 0.3 m and 4° apart.
//! let mut xyz = Vec::new();
//! for i in 0..40 {
//!     for j in 0..40 {
//!         let (u, v) = (i as f64 * 0.25, j as f64 * 0.25);
//!         xyz.extend([u + 2.0, v - 5.0, 0.0, 2.0, u - 5.0, v, u + 2.0, 5.0, v]);
//!     }
//! }
//! let (c, s) = (4f64.to_radians().cos(), 4f64.to_radians().sin());
//! let moved: Vec<f64> = xyz
//!     .chunks(3)
//!     .flat_map(|p| [c * p[0] - s * p[1] + 0.3, s * p[0] + c * p[1], p[2]])
//!     .collect();
//! let cfg = RegConfig::default();
//! let query = PreparedCloud::new(Points::new(&moved, 3).unwrap(), &cfg).unwrap();
//! let candidate = PreparedCloud::new(Points::new(&xyz, 3).unwrap(), &cfg).unwrap();
//! let r = register(&query, &candidate, &IDENTITY, &cfg).unwrap();
//! assert!(r.converged);
//! assert!((r.pose[0][3] - 0.3).abs() < 0.01 && (r.yaw_degrees() - 4.0).abs() < 0.1);
//! ```
//!
//! # Choices
//! Each was measured against its alternatives on hku1-avia and the simulator; the figures, and
//! the commands that produce them, are in docs/performance.md#registration.
//!
//! - **GICP, not point-to-plane** ([`Factor`]): more accurate, and point-to-plane's cheaper
//!   iteration does not pay for the extra iterations it needs.
//! - **Geman–McClure kernel** ([`Kernel`]), scale half the correspondence distance: smaller
//!   errors than without a kernel (a truncated quadratic).
//! - **Damped Gauss–Newton** with the step scale halved whenever the robust cost (with fresh
//!   correspondences) rises: plain Gauss–Newton cycles between two correspondence sets; a
//!   strict line search stopped on bumps of the cost.
//! - **Coarse to fine**: 1 m voxels / 3 m correspondences, then 0.5 m / 1 m. With the same model
//!   (no kernel, no range cut, fine level only) and the same start, the pose agrees with
//!   small-gicp's (`tests/test_register.py`).
//! - **The coarse level's result replaces the start** ([`Schedule::CoarseFine`]): from the
//!   detector's starts the fine level alone finds half as many poses; the guards that keep a
//!   start of lower fine-level cost ([`Schedule::KeepStart`], [`Schedule::Both`]) changed no
//!   accepted registration on hku1 or the simulator.
//! - **Yaw hypotheses** ([`register_hypotheses`]): each runs the coarse level only and is
//!   ranked by the fine level's robust cost at its end; the fine level then continues from the
//!   best. On the narrow Avia the A-SOLiD cost has a single minimum, near 0°: the fixed ±25°
//!   give the other hypotheses. Each hypothesis gets two thirds of the coarse level's
//!   iterations and the best one goes on for the rest: four hypotheses from the identity on
//!   the simulated 360° drive's registered pairs cost 0.86× as much, with the same loops on
//!   hku1 and the simulator's drift and breakdown worlds and as wide a basin (half the
//!   iterations: 0.75×, but one of hku1's 36 identity starts fewer converged).
//! - **Local planes in closed form**: each point's normal is the smallest eigenvalue's vector
//!   of its neighbourhood's covariance, from the characteristic cubic and cross products
//!   (nalgebra's iterative decomposition agrees to rounding, tested); with the k-nearest search
//!   seeded from the point's neighbours in the tree's order, a 360° cloud prepares in 0.8× the
//!   time.
//! - **Giving up** ([`register_hypotheses_for`]): a verifying detector's hypotheses skip the
//!   fine level when the best one is clearly no match for the gate's `min_fitness` (on a
//!   simulated 360° drive, 78 of 80 candidates that took the hypotheses ended at low overlap).
//! - **Convergence**: updates below 0.1° and 1 mm (small-gicp's), 10× looser on the coarse
//!   level, at most 20 iterations per level: the same budget as small-gicp.
//!
//! # Allocation
//! [`register`], [`register_hypotheses`] ([`register_hypotheses_for`]), [`hypothesis_yaws`],
//! [`Gate::check`] and the
//! [`KdTree3`] queries allocate nothing. [`PreparedCloud`] owns its storage (points, tree,
//! covariances, normals: about 105 bytes a point) and allocates while it is built, once per
//! place; the [`wire`] form allocates its output.

mod cloud;
mod gate;
mod information;
pub mod kdtree;
mod solve;
pub mod wire;

use crate::params::{field, Field, Kind, ParamType, Params, Value, FINITE};

pub use crate::error::RegError;
pub use cloud::{Level, PreparedCloud, MAX_LEVEL_POINTS, MIN_NEIGHBORS, PLANE_EPSILON};
pub use gate::{Gate, Rejection};
pub use information::{Information, LOOP_SIGMA_M, LOOP_SIGMA_ROT_DEG};
pub use kdtree::{KdTree3, Nearest};
pub(crate) use solve::weakest_direction;
pub use solve::{
    agreement, hypothesis_yaws, pose_distance, register, register_hypotheses,
    register_hypotheses_for, Hypotheses, Hypothesis, HORIZONTAL, MAX_HYPOTHESES,
    ROTATION_TOLERANCE,
};
// The verifying detector's registration: crate-private, except with the feature
// `unstable-internals` (outside semver, for the Python module's private
// `_register_verifying`, the convergence-basin benchmark's).
#[cfg(not(feature = "unstable-internals"))]
pub(crate) use solve::{register_hypotheses_verifying, register_verifying, Floors};
#[cfg(feature = "unstable-internals")]
#[doc(hidden)]
pub use solve::{register_hypotheses_verifying, register_verifying, Floors};
pub use wire::{check_cloud, cloud_points, decode_cloud, encode_cloud};

use crate::Error;

/// A rigid transform as a row-major 4×4 matrix (`[R | t; 0 0 0 1]`).
pub type Pose = [[f64; 4]; 4];

/// The identity transform.
pub const IDENTITY: Pose = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// The rotation by `degrees` about +z (counter-clockwise seen from above), as a pose.
pub fn yaw_pose(degrees: f64) -> Pose {
    let (s, c) = libm::sincos(degrees.to_radians());
    [
        [c, -s, 0.0, 0.0],
        [s, c, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// `a·b` of two rigid transforms.
pub(crate) fn mul(a: &Pose, b: &Pose) -> Pose {
    let mut out = IDENTITY;
    for i in 0..3 {
        for j in 0..4 {
            out[i][j] =
                (0..3).map(|k| a[i][k] * b[k][j]).sum::<f64>() + if j == 3 { a[i][3] } else { 0.0 };
        }
    }
    out
}

/// A row-major 3×4 pose as a 4×4 one.
pub(crate) fn rows_to_pose(p: &[f64; 12]) -> Pose {
    let mut out = IDENTITY;
    for (i, row) in out.iter_mut().take(3).enumerate() {
        row.copy_from_slice(&p[4 * i..4 * i + 4]);
    }
    out
}

/// A 4×4 pose as a row-major 3×4 one.
pub(crate) fn pose_to_rows(p: &Pose) -> [f64; 12] {
    core::array::from_fn(|k| p[k / 4][k % 4])
}

/// The inverse of a rigid transform.
pub(crate) fn invert(p: &Pose) -> Pose {
    let mut out = IDENTITY;
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = p[j][i];
        }
        out[i][3] = -(0..3).map(|k| p[k][i] * p[k][3]).sum::<f64>();
    }
    out
}

/// The residual each correspondence contributes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Factor {
    /// Generalized ICP: the Mahalanobis distance under the sum of both points' plane-shaped
    /// covariances (plane-to-plane).
    Gicp,
    /// Point-to-plane ICP: the distance along the query point's normal.
    PointToPlane,
}

/// What the coarse level's result is allowed to replace: the order of the levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Schedule {
    /// The coarse level, then the fine level from where it stopped.
    CoarseFine,
    /// The coarse level, then the fine level from whichever of the start and the coarse result
    /// has the lower fine-level robust cost: a start that already fits is not dragged away by
    /// the coarse level's wider correspondences.
    KeepStart,
    /// The fine level from the start and from the coarse result; the one ending at the lower
    /// fine-level robust cost is kept (twice the fine level's work).
    Both,
}

/// The robust kernel `ρ(s)` on a correspondence's squared Mahalanobis residual `s = eᵀWe`.
///
/// Its scale `c` is `kernel_scale × max correspondence distance` of the level, in metres along
/// a normal, converted to the units of `s` (GICP weighs a normal offset `d` as
/// `d² / (2 PLANE_EPSILON)`, point-to-plane as `d²`). A source point without a correspondence
/// costs the kernel's ceiling `c²`, so the cost is a function of the pose alone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kernel {
    /// A truncated quadratic: `ρ(s) = min(s, c²)`.
    None,
    /// Geman–McClure: `ρ(s) = c²s / (c² + s)`, weight `(c² / (c² + s))²`.
    GemanMcClure,
}

/// Registration parameters. [`RegConfig::validate`] checks them; every function that takes one
/// validates it, so an invalid value is an error naming the parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegConfig {
    /// Voxel edge (metres) of the fine level; 0 keeps every point in range.
    pub voxel_size: f64,
    /// Voxel edge (metres) of the coarse level, voxelised from the fine points; 0 disables the
    /// coarse level. Must exceed `voxel_size` otherwise.
    pub coarse_voxel_size: f64,
    /// Points with a norm `<= min_range` (metres, sensor frame) are dropped.
    pub min_range: f64,
    /// Points with a norm `>= max_range` are dropped (and with them non-finite and huge ones).
    pub max_range: f64,
    /// Neighbours (the point included) of each local covariance, `MIN_NEIGHBORS..=64`.
    pub neighbors: usize,
    /// Largest correspondence distance (metres) at the fine level.
    pub max_correspondence: f64,
    /// Largest correspondence distance (metres) at the coarse level.
    pub coarse_max_correspondence: f64,
    /// Largest number of Gauss–Newton iterations per level.
    pub max_iterations: usize,
    /// A level has converged when an update rotates by less than this (degrees) ...
    pub rotation_eps_deg: f64,
    /// ... and translates by less than this (metres).
    pub translation_eps: f64,
    /// The residual.
    pub factor: Factor,
    /// The robust kernel.
    pub kernel: Kernel,
    /// How the coarse level's result and the start are used by the fine level.
    pub schedule: Schedule,
    /// Kernel scale as a fraction of the level's maximum correspondence distance, in `(0, 10]`.
    pub kernel_scale: f64,
    /// Distance (metres) within which a point counts as overlapping the other cloud, for the
    /// overlaps and the RMSE of the result.
    pub inlier_distance: f64,
}

impl Default for RegConfig {
    /// The measured defaults (see the module documentation): GICP with a Geman–McClure kernel,
    /// 1 m then 0.5 m voxels, 3 m then 1 m correspondences, 10 neighbours, 20 iterations per
    /// level, 0.1° / 1 mm, points between 1 m and 200 m, inliers within 0.5 m.
    fn default() -> Self {
        RegConfig {
            voxel_size: 0.5,
            coarse_voxel_size: 1.0,
            min_range: 1.0,
            max_range: 200.0,
            neighbors: 10,
            max_correspondence: 1.0,
            coarse_max_correspondence: 3.0,
            max_iterations: 20,
            rotation_eps_deg: 0.1,
            translation_eps: 1e-3,
            factor: Factor::Gicp,
            kernel: Kernel::GemanMcClure,
            schedule: Schedule::CoarseFine,
            kernel_scale: 0.5,
            inlier_distance: 0.5,
        }
    }
}

impl RegConfig {
    /// Checks every parameter: each against its range in [`RegConfig::FIELDS`], then the rules
    /// between them.
    ///
    /// # Errors
    /// [`RegError::Core`] with [`Error::InvalidParameter`] naming the first invalid parameter.
    pub fn validate(&self) -> Result<(), RegError> {
        self.check_fields()?;
        // The range and the fine voxel size obey the descriptor's rules (SPEC §1), checked by
        // the same code, since the same voxel downsampling applies them.
        cloud::voxel_config(self.min_range, self.max_range, self.voxel_size).validate()?;
        let voxel_ok =
            |v: f64| v.is_finite() && v > 0.0 && self.max_range / v < crate::MAX_VOXELS_PER_AXIS;
        if self.coarse_voxel_size != 0.0
            && (!voxel_ok(self.coarse_voxel_size) || self.coarse_voxel_size <= self.voxel_size)
        {
            return Err(Error::invalid(
                "coarse_voxel_size",
                self.coarse_voxel_size,
                "0 (no coarse level), or a finite value above voxel_size and >= max_range / 2^19",
            )
            .into());
        }
        Ok(())
    }
}

/// [`Factor`]'s values and their names, as users write them.
const FACTORS: [Factor; 2] = [Factor::Gicp, Factor::PointToPlane];
const FACTOR_NAMES: [&str; 2] = ["gicp", "point-to-plane"];
/// [`Kernel`]'s values and their names.
const KERNELS: [Kernel; 2] = [Kernel::GemanMcClure, Kernel::None];
const KERNEL_NAMES: [&str; 2] = ["geman-mcclure", "none"];
/// [`Schedule`]'s values and their names.
const SCHEDULES: [Schedule; 3] = [Schedule::CoarseFine, Schedule::KeepStart, Schedule::Both];
const SCHEDULE_NAMES: [&str; 3] = ["coarse-fine", "keep-start", "both"];

/// The name of `v`, one of `values`.
fn name_of<T: PartialEq>(values: &[T], names: &[&'static str], v: T) -> &'static str {
    values.iter().position(|x| *x == v).map_or("", |i| names[i])
}

/// The value called by the name `v` (the first one for another name, which the field's
/// [`Kind::Choice`] has already refused).
fn by_name<T: Copy>(values: &[T], names: &[&str], v: Value<'_>) -> T {
    let n = if let Value::Name(n) = v { n } else { "" };
    values[names.iter().position(|x| *x == n).unwrap_or(0)]
}

impl ParamType for Factor {
    fn to_value(self) -> Value<'static> {
        Value::Name(name_of(&FACTORS, &FACTOR_NAMES, self))
    }
    fn from_value(v: Value<'_>) -> Self {
        by_name(&FACTORS, &FACTOR_NAMES, v)
    }
}

impl ParamType for Kernel {
    fn to_value(self) -> Value<'static> {
        Value::Name(name_of(&KERNELS, &KERNEL_NAMES, self))
    }
    fn from_value(v: Value<'_>) -> Self {
        by_name(&KERNELS, &KERNEL_NAMES, v)
    }
}

impl ParamType for Schedule {
    fn to_value(self) -> Value<'static> {
        Value::Name(name_of(&SCHEDULES, &SCHEDULE_NAMES, self))
    }
    fn from_value(v: Value<'_>) -> Self {
        by_name(&SCHEDULES, &SCHEDULE_NAMES, v)
    }
}

/// A finite length > 0, metres.
const LENGTH: Kind = Kind::open_closed(0.0, FINITE);

impl Params for RegConfig {
    const NAME: &'static str = "RegistrationConfig";
    const FIELDS: &'static [Field<RegConfig>] = &[
        field!(
            RegConfig,
            "voxel_size",
            voxel_size,
            Kind::closed(0.0, FINITE),
            "a finite value >= 0 metres (0 disables downsampling)",
            "Voxel edge of the fine level, metres (0 keeps every point in range).", rule = "when > 0, `max_range / voxel_size` < 2^19"),
        field!(
            RegConfig,
            "coarse_voxel_size",
            coarse_voxel_size,
            Kind::closed(0.0, FINITE),
            "0 (no coarse level), or a finite value above voxel_size and >= max_range / 2^19",
            "Voxel edge of the coarse level, metres (0: no coarse level).", rule = "when > 0, above `voxel_size` and `max_range / coarse_voxel_size` < 2^19"),
        field!(
            RegConfig,
            "min_range",
            min_range,
            Kind::closed(0.0, FINITE),
            "a finite value >= 0 metres",
            "Points at or within this distance (metres, sensor frame) are dropped."
        ),
        field!(
            RegConfig,
            "max_range",
            max_range,
            Kind::closed(-FINITE, FINITE),
            "a finite value above min_range",
            "Points at or beyond this distance are dropped.", rule = "above `min_range`"),
        field!(
            RegConfig,
            "neighbors",
            neighbors,
            Kind::Int {
                min: MIN_NEIGHBORS as u64,
                max: 64
            },
            "an integer in 5..=64",
            "Neighbours (the point included) of each local covariance."
        ),
        field!(
            RegConfig,
            "max_correspondence",
            max_correspondence,
            LENGTH,
            "a finite value > 0 metres",
            "Largest correspondence distance at the fine level, metres."
        ),
        field!(
            RegConfig,
            "coarse_max_correspondence",
            coarse_max_correspondence,
            LENGTH,
            "a finite value > 0 metres",
            "Largest correspondence distance at the coarse level, metres."
        ),
        field!(
            RegConfig,
            "max_iterations",
            max_iterations,
            Kind::Int { min: 1, max: 1000 },
            "an integer in 1..=1000",
            "Largest number of Gauss-Newton iterations per level."
        ),
        field!(
            RegConfig,
            "rotation_eps_deg",
            rotation_eps_deg,
            LENGTH,
            "a finite value > 0 degrees",
            "A level has converged when an update rotates by less than this, degrees (and translates by less than translation_eps)."
        ),
        field!(
            RegConfig,
            "translation_eps",
            translation_eps,
            LENGTH,
            "a finite value > 0 metres",
            "A level has converged when an update translates by less than this, metres (and rotates by less than rotation_eps_deg)."
        ),
        field!(
            RegConfig,
            "factor",
            factor,
            Kind::Choice(&FACTOR_NAMES),
            "\"gicp\" or \"point-to-plane\"",
            "The residual: plane-to-plane GICP or point-to-plane ICP."
        ),
        field!(
            RegConfig,
            "kernel",
            kernel,
            Kind::Choice(&KERNEL_NAMES),
            "\"geman-mcclure\" or \"none\"",
            "The robust kernel."
        ),
        field!(
            RegConfig,
            "schedule",
            schedule,
            Kind::Choice(&SCHEDULE_NAMES),
            "\"coarse-fine\", \"keep-start\" or \"both\"",
            "Which pose the fine level starts from: the coarse level's result (coarse-fine), the lower fine-level cost of the start and that result (keep-start), or both, keeping the lower final cost (both)."
        ),
        field!(
            RegConfig,
            "kernel_scale",
            kernel_scale,
            Kind::open_closed(0.0, 10.0),
            "a value in (0, 10]",
            "Kernel scale as a fraction of the level's maximum correspondence distance."
        ),
        field!(
            RegConfig,
            "inlier_distance",
            inlier_distance,
            LENGTH,
            "a finite value > 0 metres",
            "Distance (metres) within which a point overlaps the other cloud (overlaps, RMSE)."
        ),
    ];

    fn defaults() -> RegConfig {
        RegConfig::default()
    }
}

/// How well the pose is constrained: the smallest eigenvalue of the rotation block, of the
/// translation block and of the translation's marginal of the final information matrix (the
/// Gauss–Newton Hessian `JᵀWJ` at the fine level, about the query's origin), each divided by
/// the number of correspondences.
///
/// A long corridor or a single wall leaves a direction unconstrained: its eigenvalue drops
/// towards 0 while the overlap can still look perfect.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Degeneracy {
    /// Smallest eigenvalue of the 3×3 rotation block, per correspondence (m² × weight).
    pub rotation: f64,
    /// Smallest eigenvalue of the 3×3 translation block, per correspondence (weight).
    pub translation: f64,
    /// Smallest eigenvalue of the translation's marginal information (the Schur complement of
    /// the rotation block: the rotation left free), per correspondence (weight). At most
    /// `translation`: a pose whose translation can trade against a rotation (a wall turned
    /// onto another) has a low one even when every direction of the block is well seen.
    pub marginal_translation: f64,
}

/// The outcome of one registration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    /// `T_query_candidate`, row-major 4×4: `p_query ≈ pose · p_candidate` (SPEC §3).
    pub pose: Pose,
    /// `min(overlap_query, overlap_candidate)`: symmetric in the two clouds.
    pub fitness: f64,
    /// Fraction of the query's fine points within `inlier_distance` of a transformed candidate
    /// point.
    pub overlap_query: f64,
    /// Fraction of the candidate's fine points that, transformed by `pose`, lie within
    /// `inlier_distance` of a query point.
    pub overlap_candidate: f64,
    /// [`Registration::fitness`] over structure points only (not on a horizontal surface, see
    /// [`HORIZONTAL`]): the ground of two unrelated places overlaps, their walls do not.
    pub structure_fitness: f64,
    /// Root mean square distance (metres) of the candidate's inliers to their nearest query
    /// point (0 when there are none).
    pub rmse: f64,
    /// Number of candidate inliers behind `rmse`.
    pub inliers: usize,
    /// Gauss–Newton iterations, summed over the levels.
    pub iterations: usize,
    /// Whether the fine level met the convergence criteria within `max_iterations`, with at
    /// least 6 correspondences and a well-posed final system.
    pub converged: bool,
    /// How well the pose is constrained.
    pub degeneracy: Degeneracy,
    /// The Gauss–Newton Hessian `JᵀWJ` at the fine level at the final pose (robust weights
    /// applied), row-major, in the solver's coordinates: `δ = (ω, v)`, rotation first, a
    /// perturbation `T ← Exp(δ)·T` in the query's frame. Unscaled (GICP's Mahalanobis units);
    /// zeros when the fine level had no final linearisation. [`Registration::information`] turns
    /// it into a pose graph's information matrix.
    pub hessian: Information,
}

impl Registration {
    /// The yaw of `pose` in degrees, `(−180, 180]`: the heading of SPEC §3.
    pub fn yaw_degrees(&self) -> f64 {
        crate::angle::yaw_degrees(self.pose[0][0], self.pose[1][0])
    }

    /// The translation of `pose` (metres).
    pub fn translation(&self) -> [f64; 3] {
        [self.pose[0][3], self.pose[1][3], self.pose[2][3]]
    }

    /// A result for clouds that could not be registered (empty, a handful of points):
    /// `pose = init`, nothing overlaps, not converged.
    pub fn failed(init: &Pose) -> Registration {
        Registration {
            pose: *init,
            fitness: 0.0,
            overlap_query: 0.0,
            overlap_candidate: 0.0,
            structure_fitness: 0.0,
            rmse: 0.0,
            inliers: 0,
            iterations: 0,
            converged: false,
            degeneracy: Degeneracy::default(),
            hessian: [[0.0; 6]; 6],
        }
    }
}

impl Default for Registration {
    fn default() -> Self {
        Registration::failed(&IDENTITY)
    }
}
