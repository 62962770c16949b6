//! A prepared cloud: voxel levels, a kd-tree and local covariances per level, built once per
//! place and reused for every registration it takes part in.

use alloc::vec;
use alloc::vec::Vec;

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

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
        KdTree3::from_parts(&self.points, &self.perm, &self.axes)
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
            let k = tree.knn(*p, neighbors, &mut nb).unwrap_or(0);
            let (cov, normal) = local_plane(&self.points, &nb[..k]);
            covs[i] = cov;
            normals[i] = normal;
        }
        (self.covs, self.normals) = (covs, normals);
        Ok(())
    }
}

/// The regularised covariance and normal of a neighbourhood.
fn local_plane(points: &[[f64; 3]], nb: &[Nearest]) -> ([f64; 6], [f64; 3]) {
    if nb.len() < MIN_NEIGHBORS {
        return ([1.0, 0.0, 0.0, 1.0, 0.0, 1.0], [0.0; 3]);
    }
    let k = nb.len() as f64;
    let mut mean = Vector3::zeros();
    for n in nb {
        mean += Vector3::from(points[n.id as usize]);
    }
    mean /= k;
    let mut c = Matrix3::zeros();
    for n in nb {
        let d = Vector3::from(points[n.id as usize]) - mean;
        c += d * d.transpose();
    }
    c /= k;
    let eig = SymmetricEigen::new(c);
    // Sort the eigenpairs: the smallest eigenvalue's vector is the normal.
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let u = eig.eigenvectors;
    let n0 = u.column(order[0]).into_owned();
    let (n1, n2) = (u.column(order[1]), u.column(order[2]));
    let reg = n0 * n0.transpose() * PLANE_EPSILON + n1 * n1.transpose() + n2 * n2.transpose();
    if !reg.iter().all(|v| v.is_finite()) {
        return ([1.0, 0.0, 0.0, 1.0, 0.0, 1.0], [0.0; 3]);
    }
    (
        [
            reg[(0, 0)],
            reg[(0, 1)],
            reg[(0, 2)],
            reg[(1, 1)],
            reg[(1, 2)],
            reg[(2, 2)],
        ],
        [n0[0], n0[1], n0[2]],
    )
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
