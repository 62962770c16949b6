//! A prepared cloud: voxel levels, a kd-tree and local covariances per level, built once per
//! place and reused for every registration it takes part in.

use alloc::vec;
use alloc::vec::Vec;

use super::kdtree::{KdTree3, Nearest};
use super::{RegConfig, RegError};
use crate::describe::stages::voxel_downsample;
use crate::owned::{reserve, try_filled};
use crate::{describe_scratch_len, Config, Coord, Points};

/// Eigenvalue that replaces the smallest one of a local covariance (the other two become 1):
/// every neighbourhood is modelled as a plane with this much thickness, in squared units of the
/// plane's extent (Segal et al.'s plane-to-plane GICP).
pub const PLANE_EPSILON: f64 = 1e-3;

/// Fewest neighbours (the point included) from which a covariance is estimated; points with
/// fewer get the identity (no structure, hence little weight) and a zero normal.
pub const MIN_NEIGHBORS: usize = 5;

/// One voxel level of a prepared cloud.
#[derive(Debug, Clone, Default)]
pub struct Level {
    /// Voxel edge (metres) of this level; 0 for an undownsampled level.
    pub voxel_size: f64,
    /// Points (voxel centroids), x, y, z.
    pub points: Vec<[f64; 3]>,
    perm: Vec<u32>,
    axes: Vec<u8>,
    /// Regularised covariance of each point, `xx, xy, xz, yy, yz, zz`.
    pub covs: Vec<[f64; 6]>,
    /// Unit normal of each point's local plane (zero when it has none).
    pub normals: Vec<[f64; 3]>,
}

impl Level {
    /// The kd-tree over this level's points.
    pub fn tree(&self) -> KdTree3<'_> {
        KdTree3::from_parts(&self.points, &self.perm, &self.axes, true)
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// `true` when the level holds no point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    fn new(points: Vec<[f64; 3]>, voxel_size: f64, neighbors: usize) -> Result<Level, RegError> {
        let mut level = Level::ordered(points, voxel_size)?;
        level.estimate(neighbors)?;
        Ok(level)
    }

    /// The level's points in kd-tree order with their tree, without covariances and normals
    /// ([`Level::estimate`]).
    fn ordered(points: Vec<[f64; 3]>, voxel_size: f64) -> Result<Level, RegError> {
        let n = points.len();
        let (mut perm, mut axes) = (
            try_filled(n, 0u32, "kd-tree")?,
            try_filled(n, 0u8, "kd-tree")?,
        );
        // `n` fits in u32 (the caller checked) and the buffers have length n: cannot fail.
        let _ = KdTree3::build(&points, &mut perm, &mut axes);
        // Store the points in tree order (the permutation becomes the identity): a query then
        // reads each leaf's points from one contiguous run of memory.
        let mut ordered = try_filled(n, [0.0; 3], "cloud points")?;
        for (o, &i) in ordered.iter_mut().zip(&perm) {
            *o = points[i as usize];
        }
        let points = ordered;
        for (i, p) in perm.iter_mut().enumerate() {
            *p = i as u32;
        }
        Ok(Level {
            voxel_size,
            points,
            perm,
            axes,
            covs: Vec::new(),
            normals: Vec::new(),
        })
    }

    /// Each point's covariance and normal from its `neighbors` nearest points.
    fn estimate(&mut self, neighbors: usize) -> Result<(), RegError> {
        let n = self.points.len();
        let mut covs = try_filled(n, [0.0; 6], "covariances")?;
        let mut normals = try_filled(n, [0.0; 3], "normals")?;
        let mut nb = vec![Nearest::default(); neighbors];
        let tree = self.tree();
        for (i, p) in self.points.iter().enumerate() {
            // The points are in the tree's order (`ordered`): the ones beside point i there
            // share its leaf, and bound the walk from its start.
            let first = i.saturating_sub(neighbors / 2);
            let k = tree
                .knn_near(*p, neighbors, &mut nb, first..first + neighbors)
                .unwrap_or(0);
            let (cov, normal) = local_plane(&self.points, &nb[..k]);
            covs[i] = cov;
            normals[i] = normal;
        }
        (self.covs, self.normals) = (covs, normals);
        Ok(())
    }
}

/// The regularised covariance and normal of a neighbourhood: `I − (1 − ε) n nᵀ` with `n` the
/// unit eigenvector of the neighbourhood's smallest covariance eigenvalue and `ε` =
/// [`PLANE_EPSILON`] (the eigenvalues become `ε, 1, 1`).
fn local_plane(points: &[[f64; 3]], nb: &[Nearest]) -> ([f64; 6], [f64; 3]) {
    const NONE: ([f64; 6], [f64; 3]) = ([1.0, 0.0, 0.0, 1.0, 0.0, 1.0], [0.0; 3]);
    if nb.len() < MIN_NEIGHBORS {
        return NONE;
    }
    let k = nb.len() as f64;
    let mut mean = [0.0; 3];
    for n in nb {
        let p = &points[n.id as usize];
        for d in 0..3 {
            mean[d] += p[d];
        }
    }
    let mean = mean.map(|m| m / k);
    let mut c = [0.0; 6];
    for n in nb {
        let p = &points[n.id as usize];
        let d = [p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]];
        c[0] += d[0] * d[0];
        c[1] += d[0] * d[1];
        c[2] += d[0] * d[2];
        c[3] += d[1] * d[1];
        c[4] += d[1] * d[2];
        c[5] += d[2] * d[2];
    }
    let Some(n0) = smallest_eigenvector(&c.map(|v| v / k)) else {
        return NONE;
    };
    let s = 1.0 - PLANE_EPSILON;
    let reg = [
        1.0 - s * n0[0] * n0[0],
        -s * n0[0] * n0[1],
        -s * n0[0] * n0[2],
        1.0 - s * n0[1] * n0[1],
        -s * n0[1] * n0[2],
        1.0 - s * n0[2] * n0[2],
    ];
    (reg, n0)
}

/// `a × b`.
#[inline(always)]
fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The rows of the symmetric `c − λI` (`c`: `xx, xy, xz, yy, yz, zz`).
#[inline(always)]
fn shifted_rows(c: &[f64; 6], lambda: f64) -> [[f64; 3]; 3] {
    [
        [c[0] - lambda, c[1], c[2]],
        [c[1], c[3] - lambda, c[4]],
        [c[2], c[4], c[5] - lambda],
    ]
}

/// The unit null vector of a rank-2 symmetric `m` (rows): the longest cross product of two of its
/// rows; None when every cross product vanishes.
fn null_vector(m: &[[f64; 3]; 3]) -> Option<[f64; 3]> {
    let candidates = [
        cross(&m[0], &m[1]),
        cross(&m[0], &m[2]),
        cross(&m[1], &m[2]),
    ];
    let (mut best, mut len2) = (candidates[0], dot(&candidates[0], &candidates[0]));
    for c in &candidates[1..] {
        let l = dot(c, c);
        if l > len2 {
            (best, len2) = (*c, l);
        }
    }
    (len2 > 0.0 && len2.is_finite()).then(|| best.map(|v| v / libm::sqrt(len2)))
}

/// The unit eigenvector of the smallest eigenvalue of the symmetric 3×3 `c` (`xx, xy, xz, yy,
/// yz, zz`), in closed form: the eigenvalues from the trigonometric solution of the
/// characteristic cubic, the vector from cross products of the rows of `c − λI` (an iterative
/// decomposition cost most of a 360° cloud's covariances). When the two smaller eigenvalues
/// nearly coincide their vectors are ill-defined one by one: the largest eigenvalue's vector,
/// well separated then, is found first and the smallest's is the null vector of `c − λ_min I`
/// within its orthogonal complement. A multiple of the identity (every direction an
/// eigenvector) gives `x`. None for a non-finite `c`.
pub(crate) fn smallest_eigenvector(c: &[f64; 6]) -> Option<[f64; 3]> {
    let scale = c.iter().fold(0.0f64, |m, v| m.max(libm::fabs(*v)));
    if !scale.is_finite() {
        return None;
    }
    if scale == 0.0 {
        return Some([1.0, 0.0, 0.0]);
    }
    // Scaled to entries of at most 1, shifted to a trace of 0.
    let a = c.map(|v| v / scale);
    let q = (a[0] + a[3] + a[5]) / 3.0;
    let b = [a[0] - q, a[1], a[2], a[3] - q, a[4], a[5] - q];
    let p2 =
        b[0] * b[0] + b[3] * b[3] + b[5] * b[5] + 2.0 * (b[1] * b[1] + b[2] * b[2] + b[4] * b[4]);
    // Equal eigenvalues to rounding: any direction.
    if p2 <= 1e-30 {
        return Some([1.0, 0.0, 0.0]);
    }
    let p = libm::sqrt(p2 / 6.0);
    let bn = b.map(|v| v / p);
    let det = bn[0] * (bn[3] * bn[5] - bn[4] * bn[4]) - bn[1] * (bn[1] * bn[5] - bn[4] * bn[2])
        + bn[2] * (bn[1] * bn[4] - bn[3] * bn[2]);
    let half = (det / 2.0).clamp(-1.0, 1.0);
    let phi = libm::acos(half) / 3.0;
    // The roots of the normalised cubic: 2cos(φ) ≥ 2cos(φ + 4π/3) ≥ 2cos(φ + 2π/3).
    let beta_max = 2.0 * libm::cos(phi);
    let beta_min = 2.0 * libm::cos(phi + 2.0 * core::f64::consts::FRAC_PI_3);
    let lambda_min = q + p * beta_min;
    if half < 0.0 {
        // The smallest eigenvalue is the one farthest from the others: directly.
        if let Some(v) = null_vector(&shifted_rows(&a, lambda_min)) {
            return Some(v);
        }
    }
    let vmax = null_vector(&shifted_rows(&a, q + p * beta_max))?;
    // An orthonormal basis (u, w) of the complement of vmax.
    let u = if libm::fabs(vmax[0]) > libm::fabs(vmax[1]) {
        let l = libm::sqrt(vmax[0] * vmax[0] + vmax[2] * vmax[2]);
        [-vmax[2] / l, 0.0, vmax[0] / l]
    } else {
        let l = libm::sqrt(vmax[1] * vmax[1] + vmax[2] * vmax[2]);
        [0.0, vmax[2] / l, -vmax[1] / l]
    };
    let w = cross(&vmax, &u);
    // c − λ_min I within (u, w): a symmetric 2×2 [[m00, m01], [m01, m11]] of rank ≤ 1.
    let m = shifted_rows(&a, lambda_min);
    let mv = |v: &[f64; 3]| [dot(&m[0], v), dot(&m[1], v), dot(&m[2], v)];
    let (mu, mw) = (mv(&u), mv(&w));
    let (m00, m01, m11) = (dot(&u, &mu), dot(&u, &mw), dot(&w, &mw));
    // The null vector (s, t) of the row of larger norm: (m01, −m00) or (m11, −m01).
    let (s, t) = if m00 * m00 + m01 * m01 >= m11 * m11 + m01 * m01 {
        (m01, -m00)
    } else {
        (m11, -m01)
    };
    let l = libm::sqrt(s * s + t * t);
    if l == 0.0 {
        // The two smaller eigenvalues coincide: any direction of the complement.
        return Some(u);
    }
    let (s, t) = (s / l, t / l);
    Some([
        s * u[0] + t * w[0],
        s * u[1] + t * w[1],
        s * u[2] + t * w[2],
    ])
}

/// A cloud prepared for registration: its voxel levels (fine first), each with a kd-tree and
/// local covariances. Build one per place with [`PreparedCloud::new`] (from raw points) or
/// [`PreparedCloud::from_downsampled`] (from the fine points alone, for example a decoded
/// [`super::wire`] cloud), then pass it to [`super::register`] as many times as needed.
///
/// Allocates (its own storage); registration over prepared clouds allocates nothing.
#[derive(Debug, Clone, Default)]
pub struct PreparedCloud {
    /// The fine level (the config's `voxel_size`): what registration finishes on, what the
    /// fitness is measured on, and what [`super::wire::encode_cloud`] sends.
    pub fine: Level,
    /// The coarse level (`coarse_voxel_size`, voxelised from the fine points), when enabled.
    pub coarse: Option<Level>,
    prep: [u64; 5],
    /// Of a deferred cloud ([`PreparedCloud::deferred`]) not yet completed: whether it has a coarse level; the fine level then holds its points alone (no tree, no
    /// covariances) and no coarse level is built yet.
    pending: Option<bool>,
}

/// Bits of the preparation parameters, to check that two clouds were prepared alike.
fn prep_key(cfg: &RegConfig) -> [u64; 5] {
    [
        cfg.voxel_size.to_bits(),
        cfg.coarse_voxel_size.to_bits(),
        cfg.min_range.to_bits(),
        cfg.max_range.to_bits(),
        cfg.neighbors as u64,
    ]
}

/// A descriptor config that only carries a range filter and a voxel size, to reuse the crate's
/// voxel downsampling (SPEC §2 steps 1–3) for registration.
pub(super) fn voxel_config(min_range: f64, max_range: f64, voxel_size: f64) -> Config {
    Config {
        n_range: 1,
        n_azimuth: 1,
        n_elevation: 1,
        fov_up: 1.0,
        fov_down: 0.0,
        min_range,
        max_range,
        voxel_size,
    }
}

/// Points of `points` that are finite and within `(min_range, max_range)`, downsampled on an
/// origin-anchored voxel grid of `voxel_size` (0: not downsampled).
fn filtered<T: Coord>(
    points: Points<'_, T>,
    min_range: f64,
    max_range: f64,
    voxel_size: f64,
) -> Result<Vec<[f64; 3]>, RegError> {
    let cfg = voxel_config(min_range, max_range, voxel_size);
    let kept = |m: usize| -> Result<Vec<[f64; 3]>, RegError> {
        let mut v = Vec::new();
        reserve(&mut v, m, "cloud points")?;
        Ok(v)
    };
    if voxel_size > 0.0 {
        let n = points.len();
        let mut scratch = try_filled(describe_scratch_len(n, &cfg), 0u64, "voxel scratch")?;
        let mut out = try_filled(n.saturating_mul(3), 0.0f64, "voxel centroids")?;
        // The config was validated by RegConfig::validate and the buffers are sized for it.
        let m = voxel_downsample(points, &cfg, &mut scratch, &mut out).map_or(0, |(_, m)| m);
        let mut v = kept(m)?;
        v.extend(out[..3 * m].chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        Ok(v)
    } else {
        let (min2, max2) = (min_range * min_range, max_range * max_range);
        let within = |p: &[f64; 3]| {
            let d2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
            d2 > min2 && d2 < max2
        };
        let xyz = |p: &[T]| [p[0].to_f64(), p[1].to_f64(), p[2].to_f64()];
        let rows = || points.as_slice().chunks_exact(points.stride()).map(xyz);
        let mut v = kept(rows().filter(within).count())?;
        v.extend(rows().filter(within));
        Ok(v)
    }
}

/// Most points the fine level of a [`PreparedCloud`] keeps. A cloud with more after voxel
/// downsampling (a dense scan, or far more points than any sensor gives) keeps an evenly spread
/// subset of this many (every k-th point in the voxel grid's order): the work of preparing and
/// registering one cloud is bounded (docs/performance.md#work-budgets).
pub const MAX_LEVEL_POINTS: usize = 200_000;

/// `fine` thinned to at most [`MAX_LEVEL_POINTS`]: every `ceil(n / MAX)`-th point.
fn within_budget(fine: Vec<[f64; 3]>) -> Vec<[f64; 3]> {
    let n = fine.len();
    if n <= MAX_LEVEL_POINTS {
        return fine;
    }
    let step = n.div_ceil(MAX_LEVEL_POINTS);
    fine.into_iter().step_by(step).collect()
}

impl PreparedCloud {
    /// Prepares raw points (sensor frame): drops non-finite points and points outside
    /// `(min_range, max_range)`, voxel-downsamples to the fine level (thinned to
    /// [`MAX_LEVEL_POINTS`] beyond it), voxelises the fine points again for the coarse level,
    /// and builds each level's kd-tree and covariances.
    ///
    /// # Errors
    /// [`RegError::Core`] when `cfg` is invalid, or with [`crate::Error::OutOfMemory`] when the
    /// cloud does not fit in memory.
    pub fn new<T: Coord>(
        points: Points<'_, T>,
        cfg: &RegConfig,
    ) -> Result<PreparedCloud, RegError> {
        let mut c = Self::deferred(points, cfg)?;
        c.complete()?;
        Ok(c)
    }

    /// Prepares a cloud from its fine points alone (already filtered and downsampled, for
    /// example decoded from the wire form): the fine level keeps them as they are (non-finite
    /// points and points outside the range are still dropped) and the coarse level is voxelised
    /// from them, exactly as [`PreparedCloud::new`] does.
    ///
    /// # Errors
    /// As [`PreparedCloud::new`].
    pub fn from_downsampled(fine: &[[f64; 3]], cfg: &RegConfig) -> Result<PreparedCloud, RegError> {
        cfg.validate()?;
        // Centroids of in-range points can sit a hair inside min_range: no lower bound here,
        // so that a decoded cloud keeps every point the sender had.
        let pts = Points::new(fine.as_flattened(), 3)?;
        let mut c = Self::defer(filtered(pts, 0.0, cfg.max_range, 0.0)?, cfg)?;
        c.complete()?;
        Ok(c)
    }

    /// [`PreparedCloud::new`] that defers the work only registration needs: only the fine
    /// level's points are made (filtered and voxelised, in the voxel grid's order: what a
    /// place stores, [`super::wire::encode_cloud`]); the kd-trees, covariances and the coarse
    /// level wait for [`PreparedCloud::complete`], which makes it exactly what `new` makes. A
    /// detector step prepares its scan so: most steps register nothing, and a 360° sensor's
    /// trees and covariances cost most of a step that does not.
    ///
    /// # Errors
    /// As [`PreparedCloud::new`].
    pub fn deferred<T: Coord>(
        points: Points<'_, T>,
        cfg: &RegConfig,
    ) -> Result<PreparedCloud, RegError> {
        cfg.validate()?;
        Self::defer(
            filtered(points, cfg.min_range, cfg.max_range, cfg.voxel_size)?,
            cfg,
        )
    }

    /// The deferred cloud of the fine points `fine` (the budget applied here): the points alone,
    /// in the voxel grid's order; their kd-tree, covariances and the coarse level wait for
    /// [`PreparedCloud::complete`].
    fn defer(fine: Vec<[f64; 3]>, cfg: &RegConfig) -> Result<PreparedCloud, RegError> {
        Ok(PreparedCloud {
            fine: Level {
                voxel_size: cfg.voxel_size,
                points: within_budget(fine),
                ..Level::default()
            },
            coarse: None,
            prep: prep_key(cfg),
            pending: Some(cfg.coarse_voxel_size > 0.0),
        })
    }

    /// Builds what [`PreparedCloud::deferred`] left for registration (nothing for a complete
    /// cloud): the coarse level's points, voxelised from the fine points, each level's kd-tree
    /// (its points reordered along it) and covariances.
    ///
    /// # Errors
    /// [`RegError::Core`] with [`crate::Error::OutOfMemory`] when it does not fit in memory.
    pub fn complete(&mut self) -> Result<(), RegError> {
        let Some(with_coarse) = self.pending else {
            return Ok(());
        };
        let neighbors = self.prep[4] as usize;
        let (voxel, max_range) = (f64::from_bits(self.prep[1]), f64::from_bits(self.prep[3]));
        // On error the cloud is left as it was (still deferred).
        let coarse = if with_coarse {
            // No lower range bound, as in `from_downsampled`.
            let pts = Points::new(self.fine.points.as_flattened(), 3)?;
            Some(Level::new(
                filtered(pts, 0.0, max_range, voxel)?,
                voxel,
                neighbors,
            )?)
        } else {
            None
        };
        let mut fine = Level::ordered(self.fine.points.clone(), self.fine.voxel_size)?;
        fine.estimate(neighbors)?;
        (self.fine, self.coarse, self.pending) = (fine, coarse, None);
        Ok(())
    }

    /// Whether the cloud is ready for registration (not deferred, or completed).
    pub fn is_complete(&self) -> bool {
        self.pending.is_none()
    }

    /// Whether this cloud was prepared with the preparation parameters of `cfg` (voxel sizes,
    /// range, neighbours) and is complete ([`PreparedCloud::complete`]).
    pub fn prepared_with(&self, cfg: &RegConfig) -> bool {
        self.prep == prep_key(cfg) && self.is_complete()
    }

    /// Bytes of heap memory this cloud holds (points, trees, covariances, normals).
    pub fn heap_bytes(&self) -> usize {
        let level = |l: &Level| l.len() * (24 + 4 + 1 + 48 + 24);
        level(&self.fine) + self.coarse.as_ref().map_or(0, level)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reg::{register, IDENTITY};

    use nalgebra::{Matrix3, SymmetricEigen, Vector3};

    /// nalgebra's smallest eigenpair of `c` and its other eigenvalues, ascending.
    fn reference(c: &[f64; 6]) -> ([f64; 3], Vector3<f64>) {
        let m = Matrix3::new(c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5]);
        let e = SymmetricEigen::new(m);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| e.eigenvalues[a].total_cmp(&e.eigenvalues[b]));
        (
            order.map(|i| e.eigenvalues[i]),
            e.eigenvectors.column(order[0]).into_owned(),
        )
    }

    /// Checks `smallest_eigenvector(c)` against nalgebra's decomposition: a unit vector, an
    /// eigenvector of the smallest eigenvalue (residual and Rayleigh quotient within rounding of
    /// the matrix's scale), and nalgebra's own vector (up to sign) whenever the smallest
    /// eigenvalue is apart from the next.
    fn check(c: &[f64; 6], what: &str) {
        let v = smallest_eigenvector(c).unwrap();
        let (lambda, n) = reference(c);
        let scale = c
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()))
            .max(f64::MIN_POSITIVE);
        let m = Matrix3::new(c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5]);
        let v = Vector3::from(v);
        assert!((v.norm() - 1.0).abs() < 1e-12, "{what}: |v| = {}", v.norm());
        let residual = (m * v - v * lambda[0]).norm() / scale;
        assert!(residual < 1e-7, "{what}: residual {residual:e}");
        let rayleigh = (v.dot(&(m * v)) - lambda[0]).abs() / scale;
        assert!(
            rayleigh < 1e-12,
            "{what}: Rayleigh quotient off by {rayleigh:e}"
        );
        if (lambda[1] - lambda[0]) / scale > 1e-4 {
            let along = v.dot(&n).abs();
            assert!(along > 1.0 - 1e-9, "{what}: |v·n| = {along}");
        }
    }

    /// The covariance (`xx, xy, xz, yy, yz, zz`) of `points`.
    fn covariance(points: &[[f64; 3]]) -> [f64; 6] {
        let k = points.len() as f64;
        let mean: [f64; 3] = core::array::from_fn(|d| points.iter().map(|p| p[d]).sum::<f64>() / k);
        let mut c = [0.0; 6];
        for p in points {
            let d = [p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]];
            let prods = [
                d[0] * d[0],
                d[0] * d[1],
                d[0] * d[2],
                d[1] * d[1],
                d[1] * d[2],
                d[2] * d[2],
            ];
            for (ci, x) in c.iter_mut().zip(prods) {
                *ci += x / k;
            }
        }
        c
    }

    #[test]
    fn the_closed_form_normal_is_nalgebras_smallest_eigenvector() {
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        // Random symmetric matrices (indefinite too), and covariances of random neighbourhoods:
        // blobs, thin planes, lines, tilted, at scales from micrometres to kilometres.
        for t in 0..3000 {
            let c: [f64; 6] = core::array::from_fn(|_| next());
            check(&c, &format!("random {t}"));
            let (sx, sy, sz) = (next() + 0.5, (next() + 0.5) * 0.5, 10f64.powi(-(t % 7)));
            let scale = 10f64.powi(t % 9 - 4);
            let (yaw, tilt) = (next() * 6.0, next() * 3.0);
            let (cy, sn, ct, st) = (yaw.cos(), yaw.sin(), tilt.cos(), tilt.sin());
            let pts: Vec<[f64; 3]> = (0..10)
                .map(|_| {
                    let (a, b, z) = (next() * sx, next() * sy, next() * sz);
                    // Turned about z, then about x.
                    let (x, y) = (cy * a - sn * b, sn * a + cy * b);
                    [
                        scale * (x + 3.0),
                        scale * (ct * y - st * z),
                        scale * (st * y + ct * z),
                    ]
                })
                .collect();
            check(&covariance(&pts), &format!("neighbourhood {t}"));
        }
    }

    #[test]
    fn the_closed_form_normal_of_degenerate_neighbourhoods() {
        // Every direction an eigenvector (zero, identity): x, as nalgebra gives for zero.
        assert_eq!(smallest_eigenvector(&[0.0; 6]), Some([1.0, 0.0, 0.0]));
        assert_eq!(
            smallest_eigenvector(&[2.0, 0.0, 0.0, 2.0, 0.0, 2.0]),
            Some([1.0, 0.0, 0.0])
        );
        assert_eq!(
            smallest_eigenvector(&[f64::NAN, 0.0, 0.0, 1.0, 0.0, 1.0]),
            None
        );
        assert_eq!(
            smallest_eigenvector(&[f64::INFINITY, 0.0, 0.0, 1.0, 0.0, 1.0]),
            None
        );
        // Diagonal, with repeated eigenvalues in each order.
        for d in [
            [1.0, 2.0, 3.0],
            [3.0, 2.0, 1.0],
            [2.0, 1.0, 3.0],
            [1.0, 1.0, 3.0],
            [3.0, 1.0, 1.0],
            [1.0, 3.0, 3.0],
            [0.0, 0.0, 1.0],
            [1e-12, 1.0, 1.0],
        ] {
            check(
                &[d[0], 0.0, 0.0, d[1], 0.0, d[2]],
                &format!("diagonal {d:?}"),
            );
        }
        // A line of points (two zero eigenvalues), a plane (one), a plane with a point off it,
        // collinear points along each axis and a diagonal, and a horizontal plane.
        let line: Vec<[f64; 3]> = (0..10)
            .map(|i| [f64::from(i), 2.0 * f64::from(i), -0.5 * f64::from(i)])
            .collect();
        check(&covariance(&line), "line");
        for axis in 0..3 {
            let pts: Vec<[f64; 3]> = (0..7)
                .map(|i| core::array::from_fn(|d| if d == axis { f64::from(i) } else { 1.0 }))
                .collect();
            check(&covariance(&pts), &format!("line along {axis}"));
        }
        let plane: Vec<[f64; 3]> = (0..10)
            .map(|i| {
                let (u, w) = (f64::from(i % 3), f64::from(i / 3));
                [u, w, 0.2 * u - 0.7 * w + 1.0]
            })
            .collect();
        check(&covariance(&plane), "plane");
        let v = Vector3::from(smallest_eigenvector(&covariance(&plane)).unwrap());
        assert!(
            v.cross(&Vector3::new(0.2, -0.7, -1.0)).norm() < 1e-9,
            "the plane's normal"
        );
        let mut off = plane.clone();
        off[4][2] += 1e-6;
        check(&covariance(&off), "plane with a point off it");
        let ground: Vec<[f64; 3]> = (0..9)
            .map(|i| [f64::from(i % 3), f64::from(i / 3), 0.0])
            .collect();
        let n = smallest_eigenvector(&covariance(&ground)).unwrap();
        assert!(
            (n[2].abs() - 1.0).abs() < 1e-12,
            "the ground's normal is z: {n:?}"
        );
    }

    #[test]
    fn local_planes_match_nalgebras_decomposition() {
        // The regularised covariance against the construction from nalgebra's eigenvectors.
        let mut pts = Vec::new();
        for i in 0..12 {
            let f = f64::from(i);
            pts.push([f * 0.3, (f * 1.7).sin(), 0.05 * (f * 0.9).cos() + 0.01 * f]);
        }
        let nb: Vec<Nearest> = (0..pts.len() as u32)
            .map(|id| Nearest { id, d2: 0.0 })
            .collect();
        let (cov, normal) = local_plane(&pts, &nb);
        let (_, n0) = reference(&covariance(&pts));
        let expected = Matrix3::identity() - n0 * n0.transpose() * (1.0 - PLANE_EPSILON);
        let got = Matrix3::new(
            cov[0], cov[1], cov[2], cov[1], cov[3], cov[4], cov[2], cov[4], cov[5],
        );
        assert!((got - expected).abs().max() < 1e-12);
        assert!(Vector3::from(normal).dot(&n0).abs() > 1.0 - 1e-12);
        // Too few neighbours: the identity, no normal.
        assert_eq!(
            local_plane(&pts, &nb[..4]),
            ([1.0, 0.0, 0.0, 1.0, 0.0, 1.0], [0.0; 3])
        );
    }

    #[test]
    fn a_deferred_cloud_registers_only_once_completed() {
        // A 20 m × 12 m room 3 m high, a point every 0.1 m of its walls, floor and ceiling.
        let mut xyz = Vec::new();
        for i in 0..=200 {
            for j in 0..=30 {
                let (x, z) = (-10.0 + 0.1 * f64::from(i), 0.1 * f64::from(j));
                xyz.extend([x, -6.0, z, x, 6.0, z]);
            }
            for j in 0..=120 {
                let (x, y) = (-10.0 + 0.1 * f64::from(i), -6.0 + 0.1 * f64::from(j));
                xyz.extend([x, y, 0.0, x, y, 3.0]);
            }
        }
        let cfg = RegConfig::default();
        let points = Points::new(&xyz, 3).unwrap();
        let full = PreparedCloud::new(points, &cfg).unwrap();
        let mut d = PreparedCloud::deferred(points, &cfg).unwrap();
        // The fine points (what a detector stores) are there at once, in the voxel grid's order
        // (a complete cloud holds them in its tree's): the same points, the same stored form.
        let sorted = |l: &Level| {
            let mut p = l.points.clone();
            p.sort_by(|a, b| a.partial_cmp(b).unwrap());
            p
        };
        assert_eq!(sorted(&d.fine), sorted(&full.fine));
        let stored = |l: &Level| crate::reg::encode_cloud(&l.points, 0.5, 8).unwrap();
        assert_eq!(stored(&d.fine), stored(&full.fine));
        assert!(d.fine.covs.is_empty() && d.coarse.is_none());
        assert!(!d.is_complete() && !d.prepared_with(&cfg));
        assert!(matches!(
            register(&d, &full, &IDENTITY, &cfg),
            Err(RegError::NotPreparedWith)
        ));
        d.complete().unwrap();
        assert!(d.is_complete() && d.prepared_with(&cfg));
        let same = |a: &Level, b: &Level| {
            a.points == b.points && a.covs == b.covs && a.normals == b.normals
        };
        assert!(same(&d.fine, &full.fine));
        assert!(same(
            d.coarse.as_ref().unwrap(),
            full.coarse.as_ref().unwrap()
        ));
        // Completing again changes nothing; registration then works.
        d.complete().unwrap();
        assert!(same(&d.fine, &full.fine));
        assert!(register(&d, &full, &IDENTITY, &cfg).is_ok());
    }
}
