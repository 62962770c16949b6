//! The registration loop: Gauss–Newton on SE(3), coarse to fine, over prepared clouds.

use nalgebra::{Matrix3, Matrix6, SymmetricEigen, UnitQuaternion, Vector3, Vector6};

use super::cloud::{Level, PreparedCloud};
use super::{Degeneracy, Factor, Gate, Kernel, Pose, RegConfig, RegError, Registration, Schedule};
use crate::Error;

/// Fewest correspondences for a Gauss–Newton step (six unknowns).
const MIN_CORRESPONDENCES: usize = 6;

/// Largest `max |RᵀR − I|` of an initial rotation.
pub const ROTATION_TOLERANCE: f64 = 1e-3;

/// A rigid transform being estimated: `p ↦ rot · p + t`.
#[derive(Debug, Clone, Copy)]
struct Rigid {
    rot: UnitQuaternion<f64>,
    t: Vector3<f64>,
}

impl Rigid {
    /// Reads a row-major pose whose rotation block is a rotation within [`ROTATION_TOLERANCE`]
    /// (poses written with six digits are not orthonormal to 1e-6); it is orthonormalised.
    fn from_pose(p: &Pose) -> Result<Rigid, RegError> {
        let bad = |value: f64| -> RegError {
            Error::InvalidParameter {
                name: "init",
                value,
                expected: "a finite rigid transform [R | t; 0 0 0 1] with R a rotation",
            }
            .into()
        };
        if let Some(v) = p.iter().flatten().find(|v| !v.is_finite()) {
            return Err(bad(*v));
        }
        if p[3] != [0.0, 0.0, 0.0, 1.0] {
            return Err(bad(p[3][3]));
        }
        let r = Matrix3::from_fn(|i, j| p[i][j]);
        let off = (r.transpose() * r - Matrix3::identity()).abs().max();
        if off > ROTATION_TOLERANCE || r.determinant() < 0.0 {
            return Err(bad(off));
        }
        let rot = UnitQuaternion::from_matrix(&r);
        Ok(Rigid {
            rot,
            t: Vector3::new(p[0][3], p[1][3], p[2][3]),
        })
    }

    fn to_pose(self) -> Pose {
        let r = self.rot.to_rotation_matrix();
        let m = r.matrix();
        [
            [m[(0, 0)], m[(0, 1)], m[(0, 2)], self.t[0]],
            [m[(1, 0)], m[(1, 1)], m[(1, 2)], self.t[1]],
            [m[(2, 0)], m[(2, 1)], m[(2, 2)], self.t[2]],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    fn inverse(self) -> Rigid {
        let rot = self.rot.inverse();
        Rigid {
            rot,
            t: -(rot * self.t),
        }
    }
}

#[inline(always)]
fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v[2], v[1], v[2], 0.0, -v[0], -v[1], v[0], 0.0)
}

#[inline(always)]
fn sym(c: &[f64; 6]) -> Matrix3<f64> {
    Matrix3::new(c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5])
}

/// The normal equations of one linearisation and the cost there.
struct Linear {
    h: Matrix6<f64>,
    g: Vector6<f64>,
    /// Correspondences found.
    n: usize,
    /// The robust cost `Σᵢ ρ(sᵢ)` over every source point, unmatched points at the kernel's
    /// ceiling: a function of the pose alone (correspondences are re-found), which the line
    /// search requires to decrease.
    cost: f64,
    /// The source's overlap with the target within the inlier distance (`inlier_d2` of
    /// [`linearize`]): the same figures as [`overlap`] at this pose, found by the same queries.
    overlap: Overlap,
}

/// The robust kernel on the squared Mahalanobis residual `s = eᵀWe`, with its scale `c²` in
/// the units of `s`.
#[derive(Clone, Copy)]
struct Robust {
    c2: f64,
    kernel: Kernel,
}

impl Robust {
    /// The kernel of `cfg` at a level with maximum correspondence distance `max_corr`: its
    /// scale, `kernel_scale × max_corr` metres along a normal, in units of `s` (GICP weighs a
    /// normal offset `d` as `d² / (2 PLANE_EPSILON)`, point-to-plane as `d²`).
    fn new(cfg: &RegConfig, max_corr: f64) -> Robust {
        let c = cfg.kernel_scale * max_corr;
        let per_m2 = match cfg.factor {
            Factor::Gicp => 1.0 / (2.0 * super::PLANE_EPSILON),
            Factor::PointToPlane => 1.0,
        };
        Robust {
            c2: c * c * per_m2,
            kernel: cfg.kernel,
        }
    }

    /// `(ρ(s), ρ'(s))`. Geman–McClure: `ρ = c²s / (c² + s)`, `ρ' = (c² / (c² + s))²`, bounded
    /// by `c²`. Without a kernel: `ρ = min(s, c²)` (a truncated quadratic).
    #[inline(always)]
    fn eval(&self, s: f64) -> (f64, f64) {
        match self.kernel {
            Kernel::GemanMcClure => {
                let k = self.c2 / (self.c2 + s);
                (k * s, k * k)
            }
            Kernel::None => {
                if s < self.c2 {
                    (s, 1.0)
                } else {
                    (self.c2, 0.0)
                }
            }
        }
    }

    /// The cost of a source point without a correspondence.
    fn ceiling(&self) -> f64 {
        self.c2
    }
}

/// Linearises the cost at `x`: every source point transformed by `x` is matched to its nearest
/// target point within `max_d2`. Allocates nothing.
fn linearize(
    target: &Level,
    source: &Level,
    x: &Rigid,
    max_d2: f64,
    robust: &Robust,
    factor: Factor,
    inlier_d2: f64,
) -> Linear {
    let tree = target.tree();
    let r = *x.rot.to_rotation_matrix().matrix();
    let mut h = Matrix6::zeros();
    let mut g = Vector6::zeros();
    let mut n = 0;
    let mut cost = 0.0;
    let mut hits = Hits::default();
    for (i, p) in source.points.iter().enumerate() {
        let y = r * Vector3::from(*p) + x.t;
        let structure = hits.point(source, i);
        let Some(nb) = tree.nearest([y[0], y[1], y[2]], max_d2) else {
            cost += robust.ceiling();
            continue;
        };
        // The nearest within max_d2 is the nearest within any smaller distance too.
        if nb.d2 < inlier_d2 {
            hits.hit(nb.d2, structure);
        }
        let j = nb.id as usize;
        let e = Vector3::from(target.points[j]) - y;
        let w_mat = match factor {
            Factor::Gicp => {
                let m = sym(&target.covs[j]) + r * sym(&source.covs[i]) * r.transpose();
                match m.try_inverse() {
                    Some(w) => w,
                    None => {
                        cost += robust.ceiling();
                        continue;
                    }
                }
            }
            Factor::PointToPlane => {
                let nv = Vector3::from(target.normals[j]);
                nv * nv.transpose()
            }
        };
        let we = w_mat * e;
        let (rho, w) = robust.eval(e.dot(&we));
        cost += rho;
        if w == 0.0 {
            continue;
        }
        let wm = w_mat * w;
        let we = we * w;
        let a = skew(&y);
        let wa = wm * a;
        // J = [[y]×, −I]: JᵀWJ = [[AᵀWA, −AᵀW], [−WA, W]] with Aᵀ = −A; JᵀWe = [AᵀWe; −We].
        let rr = -(a * wa);
        let rt = a * wm;
        h.fixed_view_mut::<3, 3>(0, 0).add_assign(&rr);
        h.fixed_view_mut::<3, 3>(0, 3).add_assign(&rt);
        h.fixed_view_mut::<3, 3>(3, 0).add_assign(&rt.transpose());
        h.fixed_view_mut::<3, 3>(3, 3).add_assign(&wm);
        g.fixed_rows_mut::<3>(0).add_assign(&(-(a * we)));
        g.fixed_rows_mut::<3>(3).add_assign(&(-we));
        n += 1;
    }
    Linear {
        h,
        g,
        n,
        cost,
        overlap: hits.overlap(source.len()),
    }
}

use core::ops::AddAssign;

/// The coarse level stops at updates this many times larger than the convergence thresholds:
/// it only has to bring the pose within the fine level's reach.
const COARSE_EPS_FACTOR: f64 = 10.0;

/// Smallest step scale: the scale halves each time a step raises the cost, down to this.
const MIN_STEP_SCALE: f64 = 0.125;

/// Factor by which the step scale grows back after a step that lowered the cost.
const STEP_RECOVERY: f64 = 1.5;

/// A verifying detector's level stops (without converging) after this many iterations in a row
/// that did not lower its lowest robust cost while the candidate's overlap is below the gate's
/// floors ([`Floors`]): the damping has shrunk the steps and the cost no longer falls. On hku1's
/// failing candidates the fine level ran its 20 iterations so, its cost rising from the first
/// step while millimetre steps crept on (docs/performance.md, r19-p95). A registration at or
/// above the floors runs on (stopped at every stall, a corridor's true match lost the last
/// centimetres of its creep along the weak axis), and so do [`register`] and
/// [`register_hypotheses`]: a start metres off crosses such stalls on its way; so does the
/// coarse level of [`register_verifying`] (from a single start).
const STALL_ITERATIONS: usize = 3;

/// The gate's overlap floors (`min_fitness`, `min_structure_fitness`) for a verifying
/// detector's registration: a level stalled ([`STALL_ITERATIONS`]) stops only while the
/// candidate's overlap at its pose is below one of them (the gate would reject it there; the
/// fitness is the smaller of the two clouds' overlaps). A registration at or above both runs on
/// exactly as without.
///
/// Crate-private, like [`register_verifying`] and [`register_hypotheses_verifying`], except
/// with the feature `unstable-internals` (not part of the public API, outside semver), for
/// the convergence-basin benchmark (`benches/reg_basin.py`, through the Python module's private
/// `_register_verifying`).
#[doc(hidden)]
#[non_exhaustive]
#[derive(Clone, Copy, Debug)]
pub struct Floors {
    /// The gate's `min_fitness`.
    pub fitness: f64,
    /// The gate's `min_structure_fitness`.
    pub structure: f64,
}

/// Whether a stalled level stops at pose `x` (its last linearisation given): see [`Floors`].
type Stall<'a> = Option<&'a dyn Fn(&Rigid, &Linear) -> bool>;

impl Floors {
    /// No floors (0): a stalled level never stops (a chain link, whose floors depend on the pose).
    pub const NONE: Floors = Floors {
        fitness: 0.0,
        structure: 0.0,
    };

    /// The floors of `gate` (`min_fitness`, `min_structure_fitness`).
    pub fn of(gate: &Gate) -> Floors {
        Floors {
            fitness: gate.min_fitness,
            structure: gate.min_structure_fitness,
        }
    }

    /// The `min_fitness` below which [`register_hypotheses_verifying`] gives up before the fine
    /// level, for these floors: the fitness floor within `[0, 1]` (0 for [`Floors::NONE`]: it
    /// never gives up).
    pub fn give_up(self) -> f64 {
        self.fitness.clamp(0.0, 1.0)
    }

    /// Whether an overlap is below a floor.
    fn below(self, o: &Overlap) -> bool {
        o.all < self.fitness || o.structure < self.structure
    }

    /// The fine level's test: its linearisation has measured the overlap (when its
    /// correspondences reach the inlier distance; otherwise measured here).
    fn fine<'a>(
        self,
        query: &'a PreparedCloud,
        candidate: &'a PreparedCloud,
        cfg: &'a RegConfig,
    ) -> impl Fn(&Rigid, &Linear) -> bool + 'a {
        let measured = self.coarse(query, candidate, cfg);
        move |x, lin| {
            if fine_inlier_d2(cfg) > 0.0 {
                self.below(&lin.overlap)
            } else {
                measured(x, lin)
            }
        }
    }

    /// The coarse level's test: the candidate's overlap measured on the fine clouds at `x`.
    fn coarse<'a>(
        self,
        query: &'a PreparedCloud,
        candidate: &'a PreparedCloud,
        cfg: &'a RegConfig,
    ) -> impl Fn(&Rigid, &Linear) -> bool + 'a {
        move |x, _| {
            self.below(&overlap(
                &query.fine,
                &candidate.fine,
                x,
                cfg.inlier_distance,
            ))
        }
    }
}

/// What one level's optimisation reports.
struct LevelOutcome {
    iterations: usize,
    converged: bool,
    /// The linearisation at the final pose.
    last: Option<Linear>,
}

/// Damped Gauss–Newton at one level, from `x` (updated in place).
///
/// Every Gauss–Newton step is taken, scaled by a factor that starts at 1 and halves (down to
/// [`MIN_STEP_SCALE`]) each time a step raised the robust cost (correspondences found anew).
/// Plain Gauss–Newton can cycle forever between two sets of correspondences a few millimetres
/// apart; the shrinking scale damps such a cycle until its steps fall below the convergence
/// thresholds. A stricter line search (reject any step that raises the cost) was measured
/// first: on hku1 it stopped on bumps of the cost while the Gauss–Newton direction still
/// pointed a metre away, towards the right pose. A level converges when a (scaled) update is
/// below both `rotation_eps_deg` and `translation_eps`. With `stall` (a verifying detector's), a
/// level that has not lowered its lowest cost for [`STALL_ITERATIONS`] iterations in a row stops
/// there, not converged, when `stall` says so at its pose (below the gate's [`Floors`]: a wrong
/// match creeping on at the smallest scales). Every linearisation counts as an iteration.
#[allow(clippy::too_many_arguments)]
fn align_level(
    target: &Level,
    source: &Level,
    x: &mut Rigid,
    max_corr: f64,
    cfg: &RegConfig,
    eps_scale: f64,
    inlier_d2: f64,
    stall: Stall<'_>,
) -> LevelOutcome {
    let robust = Robust::new(cfg, max_corr);
    let max_d2 = max_corr * max_corr;
    let rot_eps = cfg.rotation_eps_deg.to_radians() * eps_scale;
    let trans_eps = cfg.translation_eps * eps_scale;
    let mut lin = linearize(target, source, x, max_d2, &robust, cfg.factor, inlier_d2);
    let mut out = LevelOutcome {
        iterations: 1,
        converged: false,
        last: None,
    };
    let mut scale = 1.0;
    // The lowest cost so far, and the iterations since it last fell.
    let (mut lowest, mut stalled) = (lin.cost, 0);
    while out.iterations < cfg.max_iterations {
        if lin.n < MIN_CORRESPONDENCES {
            return out;
        }
        let Some(chol) = lin.h.cholesky() else {
            return out;
        };
        let delta = -chol.solve(&lin.g) * scale;
        if !delta.iter().all(|v| v.is_finite()) {
            return out;
        }
        let w = delta.fixed_rows::<3>(0).into_owned();
        let v = delta.fixed_rows::<3>(3).into_owned();
        let dr = UnitQuaternion::from_scaled_axis(w);
        x.rot = dr * x.rot;
        x.t = dr * x.t + v;
        let next = linearize(target, source, x, max_d2, &robust, cfg.factor, inlier_d2);
        out.iterations += 1;
        scale = if next.cost >= lin.cost {
            (scale * 0.5).max(MIN_STEP_SCALE)
        } else {
            (scale * STEP_RECOVERY).min(1.0)
        };
        if next.cost < lowest {
            (lowest, stalled) = (next.cost, 0);
        } else {
            stalled += 1;
        }
        lin = next;
        if w.norm() < rot_eps && v.norm() < trans_eps {
            out.converged = true;
            break;
        }
        if stalled >= STALL_ITERATIONS && stall.is_some_and(|failing| failing(x, &lin)) {
            break;
        }
    }
    if lin.n >= MIN_CORRESPONDENCES {
        out.last = Some(lin);
    } else {
        out.converged = false;
    }
    out
}

/// How much of one cloud overlaps the other.
#[derive(Clone, Copy)]
struct Overlap {
    /// Fraction of the points with a match.
    all: f64,
    /// Fraction of the structure points (see [`HORIZONTAL`]) with a match.
    structure: f64,
    /// Points with a match, and the sum of their squared distances.
    inliers: usize,
    sum: f64,
}

/// A point whose normal (in its own sensor frame) has `|n_z|` above this lies on a horizontal
/// surface (the ground, mostly; 25° of tilt) and is not counted as structure; nor is a point
/// without a normal.
pub const HORIZONTAL: f64 = 0.9;

/// Counts of an overlap being measured, point by point.
#[derive(Default)]
struct Hits {
    n: usize,
    sum: f64,
    n_struct: usize,
    hit_struct: usize,
}

impl Hits {
    /// Counts point `i` of `from` (when it has normals); whether it is a structure point.
    #[inline(always)]
    fn point(&mut self, from: &Level, i: usize) -> bool {
        let structure = from
            .normals
            .get(i)
            .is_some_and(|nv| libm::fabs(nv[2]) <= HORIZONTAL && nv != &[0.0; 3]);
        self.n_struct += usize::from(structure);
        structure
    }

    /// A point with a match at squared distance `d2`.
    #[inline(always)]
    fn hit(&mut self, d2: f64, structure: bool) {
        self.n += 1;
        self.sum += d2;
        self.hit_struct += usize::from(structure);
    }

    fn overlap(&self, len: usize) -> Overlap {
        let frac = |a: usize, b: usize| if b > 0 { a as f64 / b as f64 } else { 0.0 };
        Overlap {
            all: frac(self.n, len),
            structure: frac(self.hit_struct, self.n_struct),
            inliers: self.n,
            sum: self.sum,
        }
    }
}

/// How many of `from`'s points `x` maps within `d` of a point of `to`.
fn overlap(to: &Level, from: &Level, x: &Rigid, d: f64) -> Overlap {
    let tree = to.tree();
    let r = *x.rot.to_rotation_matrix().matrix();
    let mut hits = Hits::default();
    for (i, p) in from.points.iter().enumerate() {
        let structure = hits.point(from, i);
        let y = r * Vector3::from(*p) + x.t;
        if let Some(nb) = tree.nearest([y[0], y[1], y[2]], d * d) {
            hits.hit(nb.d2, structure);
        }
    }
    hits.overlap(from.len())
}

fn min_eigenvalue(m: Matrix3<f64>) -> f64 {
    weakest_direction(m).0
}

/// The smallest eigenvalue of a symmetric 3×3 information block and its unit eigenvector: how
/// little the block constrains, and along which direction.
pub(crate) fn weakest_direction(m: Matrix3<f64>) -> (f64, Vector3<f64>) {
    let e = SymmetricEigen::new(m);
    let i = e.eigenvalues.imin();
    (e.eigenvalues[i], e.eigenvectors.column(i).into_owned())
}

/// The smallest eigenvalue of the translation's information once the rotation is marginalised
/// (the Schur complement `H_tt − H_tr H_rr⁻¹ H_rt` of the rotation block): the inverse of the
/// largest translation variance the Hessian allows when the rotation is free too. 0 when the
/// rotation block is singular (the rotation is not constrained at all).
pub(super) fn marginal_translation(h: &Matrix6<f64>) -> f64 {
    let hrr = h.fixed_view::<3, 3>(0, 0).into_owned();
    let hrt = h.fixed_view::<3, 3>(0, 3).into_owned();
    let htt = h.fixed_view::<3, 3>(3, 3).into_owned();
    match hrr.cholesky() {
        Some(c) => min_eigenvalue(htt - hrt.transpose() * c.solve(&hrt)).max(0.0),
        None => 0.0,
    }
}

/// Registers `candidate` to `query`: estimates `T_query_candidate` (`p_query ≈ T · p_candidate`,
/// SPEC §3) from the initial guess `init`, first on the coarse levels (when the config has them),
/// then on the fine levels, and measures the result on the fine levels.
///
/// Allocates nothing. Clouds too small to register (fewer than 6 correspondences) give a
/// [`Registration::failed`]-like result that is not converged; the call never panics.
///
/// # Errors
/// [`RegError::Core`] when `cfg` is invalid or `init` is not a finite rigid transform (name
/// `init`); [`RegError::NotPreparedWith`] when a cloud was prepared with other preparation
/// parameters than `cfg`.
pub fn register(
    query: &PreparedCloud,
    candidate: &PreparedCloud,
    init: &Pose,
    cfg: &RegConfig,
) -> Result<Registration, RegError> {
    register_checked(query, candidate, init, cfg, None)
}

/// [`register`] as a verifying detector runs it: the fine level also stops once its cost has
/// stalled ([`STALL_ITERATIONS`]) below the gate's `floors`; the gate judges the result. The
/// coarse level runs as [`register`]'s: stopped at its stalls, the coarse level of a start 1–3 m
/// and up to 30° off stopped true matches on plateaus it was still crossing towards the truth
/// (`make bench-basin`, docs/performance.md "Convergence basin"). Outside semver: see [`Floors`].
#[doc(hidden)]
pub fn register_verifying(
    query: &PreparedCloud,
    candidate: &PreparedCloud,
    init: &Pose,
    cfg: &RegConfig,
    floors: Floors,
) -> Result<Registration, RegError> {
    register_checked(query, candidate, init, cfg, Some(floors))
}

/// [`register`]'s checks of the configuration, the clouds' preparation and the start, then
/// [`register_from`] with the stall `floors`, if any.
fn register_checked(
    query: &PreparedCloud,
    candidate: &PreparedCloud,
    init: &Pose,
    cfg: &RegConfig,
    floors: Option<Floors>,
) -> Result<Registration, RegError> {
    cfg.validate()?;
    if !query.prepared_with(cfg) || !candidate.prepared_with(cfg) {
        return Err(RegError::NotPreparedWith);
    }
    let mut x = Rigid::from_pose(init)?;
    Ok(register_from(query, candidate, &mut x, cfg, floors))
}

fn register_from(
    query: &PreparedCloud,
    candidate: &PreparedCloud,
    x: &mut Rigid,
    cfg: &RegConfig,
    floors: Option<Floors>,
) -> Registration {
    let (Some(qc), Some(cc)) = (&query.coarse, &candidate.coarse) else {
        return fine_from(query, candidate, x, None, cfg, 0, floors);
    };
    let start = *x;
    // No stall at this coarse level, `floors` or not (see [`register_verifying`]).
    let o = align_level(
        qc,
        cc,
        x,
        cfg.coarse_max_correspondence,
        cfg,
        COARSE_EPS_FACTOR,
        0.0,
        None,
    );
    let alt = match cfg.schedule {
        Schedule::CoarseFine => None,
        Schedule::KeepStart => {
            if fine_cost(query, candidate, &start, cfg) <= fine_cost(query, candidate, x, cfg) {
                *x = start;
            }
            None
        }
        Schedule::Both => Some(start),
    };
    fine_from(query, candidate, x, alt, cfg, o.iterations, floors)
}

/// The fine level's robust cost at `x` (correspondences found there).
fn fine_cost(query: &PreparedCloud, candidate: &PreparedCloud, x: &Rigid, cfg: &RegConfig) -> f64 {
    let robust = Robust::new(cfg, cfg.max_correspondence);
    let d2 = cfg.max_correspondence * cfg.max_correspondence;
    linearize(
        &query.fine,
        &candidate.fine,
        x,
        d2,
        &robust,
        cfg.factor,
        0.0,
    )
    .cost
}

/// The squared inlier distance at which the fine level measures the candidate's overlap while
/// it linearises (see [`measure`]); 0 (none) when the correspondences do not reach it.
fn fine_inlier_d2(cfg: &RegConfig) -> f64 {
    if cfg.inlier_distance <= cfg.max_correspondence {
        cfg.inlier_distance * cfg.inlier_distance
    } else {
        0.0
    }
}

/// The fine level's final robust cost, infinite without a final linearisation.
fn final_cost(o: &LevelOutcome) -> f64 {
    o.last.as_ref().map_or(f64::INFINITY, |l| l.cost)
}

/// The fine level from `x` (and from `alt` too when given, keeping the one that ends at the
/// lower robust cost), then the measures of the result; `iterations` were spent before.
fn fine_from(
    query: &PreparedCloud,
    candidate: &PreparedCloud,
    x: &mut Rigid,
    alt: Option<Rigid>,
    cfg: &RegConfig,
    mut iterations: usize,
    floors: Option<Floors>,
) -> Registration {
    let failing = floors.map(|f| f.fine(query, candidate, cfg));
    let stall = failing
        .as_ref()
        .map(|f| f as &dyn Fn(&Rigid, &Linear) -> bool);
    let mut o = align_level(
        &query.fine,
        &candidate.fine,
        x,
        cfg.max_correspondence,
        cfg,
        1.0,
        fine_inlier_d2(cfg),
        stall,
    );
    iterations += o.iterations;
    if let Some(mut y) = alt {
        let p = align_level(
            &query.fine,
            &candidate.fine,
            &mut y,
            cfg.max_correspondence,
            cfg,
            1.0,
            fine_inlier_d2(cfg),
            stall,
        );
        iterations += p.iterations;
        if final_cost(&p) < final_cost(&o) {
            *x = y;
            o = p;
        }
    }
    measure(query, candidate, x, &o, cfg, iterations)
}

/// The measures of a registration ended at `x` (overlaps, RMSE, the fine level's final
/// linearisation `o`: convergence, degeneracy, Hessian) after `iterations` in all.
fn measure(
    query: &PreparedCloud,
    candidate: &PreparedCloud,
    x: &Rigid,
    o: &LevelOutcome,
    cfg: &RegConfig,
    iterations: usize,
) -> Registration {
    // The fine level's last linearisation (at `x`) has measured the candidate's overlap when
    // its correspondences reach the inlier distance.
    let oc = match &o.last {
        Some(lin) if fine_inlier_d2(cfg) > 0.0 => lin.overlap,
        _ => overlap(&query.fine, &candidate.fine, x, cfg.inlier_distance),
    };
    let oq = overlap(
        &candidate.fine,
        &query.fine,
        &x.inverse(),
        cfg.inlier_distance,
    );
    let degeneracy = o.last.as_ref().map_or(Degeneracy::default(), |lin| {
        let n = lin.n as f64;
        Degeneracy {
            rotation: min_eigenvalue(lin.h.fixed_view::<3, 3>(0, 0).into_owned()) / n,
            translation: min_eigenvalue(lin.h.fixed_view::<3, 3>(3, 3).into_owned()) / n,
            marginal_translation: marginal_translation(&lin.h) / n,
        }
    });
    Registration {
        pose: x.to_pose(),
        fitness: oq.all.min(oc.all),
        overlap_query: oq.all,
        overlap_candidate: oc.all,
        structure_fitness: oq.structure.min(oc.structure),
        rmse: if oc.inliers > 0 {
            libm::sqrt(oc.sum / oc.inliers as f64)
        } else {
            0.0
        },
        inliers: oc.inliers,
        iterations,
        converged: o.converged && o.last.is_some(),
        degeneracy,
        hessian: o.last.as_ref().map_or([[0.0; 6]; 6], |lin| {
            core::array::from_fn(|i| core::array::from_fn(|j| lin.h[(i, j)]))
        }),
    }
}

/// Most initial yaws one [`register_hypotheses`] call takes: each costs a coarse registration,
/// so a call's work is bounded (a sweep in 5° steps fits; docs/performance.md#work-budgets).
pub const MAX_HYPOTHESES: usize = 72;

/// One initial yaw of [`register_hypotheses`] and where the coarse level took it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hypothesis {
    /// The initial yaw (degrees) this hypothesis started from.
    pub yaw_deg: f64,
    /// The pose the fine level would go on from: after the coarse level (the fine level when
    /// the config has no coarse level), or the start when the config's [`Schedule`] keeps a
    /// start that fits the fine level better.
    pub pose: Pose,
    /// The robust cost there, normalised to `[0, 1]`: 0 when every candidate point sits on
    /// its match, 1 when none has one.
    pub cost: f64,
    /// Whether that level converged.
    pub converged: bool,
    /// Iterations that level took.
    pub iterations: usize,
}

impl Default for Hypothesis {
    fn default() -> Self {
        Hypothesis {
            yaw_deg: 0.0,
            pose: super::IDENTITY,
            cost: 1.0,
            converged: false,
            iterations: 0,
        }
    }
}

/// The outcome of [`register_hypotheses`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hypotheses {
    /// Number of hypotheses (their coarse outcomes are in `out[..count]`).
    pub count: usize,
    /// Index of the best one: the lowest coarse cost, ties by lower index.
    pub best: usize,
    /// The full registration (coarse then fine) from the best hypothesis's initial pose.
    pub registration: Registration,
}

/// Registers `candidate` to `query` from several initial yaws and keeps the best.
///
/// Each hypothesis `k` starts from `yaw_pose(yaws_deg[k]) · init` and runs the coarse level
/// only (the cheap one; the fine level when the config has no coarse level); its outcome goes
/// to `out[k]` (with [`Schedule::KeepStart`] or [`Schedule::Both`], its start instead when
/// that has the lower fine-level cost). The fine level then goes on from the hypothesis with
/// the lowest normalised cost. Hypotheses that end at the same pose from
/// different yaws are evidence of a real match (see [`agreement`]); a wrong candidate scatters
/// them. A verifying detector passes [`hypothesis_yaws`] of the two A-SOLiDs.
///
/// Allocates nothing.
///
/// # Errors
/// As [`register`]; [`Error::Empty`] (what `yaws_deg`) for no yaw,
/// [`Error::InvalidParameter`] (name `yaws_deg`) for a non-finite one or more than
/// [`MAX_HYPOTHESES`], and
/// [`Error::BufferTooSmall`] (buffer `out`) when `out` is shorter than `yaws_deg`.
pub fn register_hypotheses(
    query: &PreparedCloud,
    candidate: &PreparedCloud,
    yaws_deg: &[f64],
    init: &Pose,
    cfg: &RegConfig,
    out: &mut [Hypothesis],
) -> Result<Hypotheses, RegError> {
    register_hypotheses_for(query, candidate, yaws_deg, init, cfg, out, 0.0)
}

/// [`register_hypotheses`] for a gate that asks for a fitness of at least `min_fitness`: a
/// candidate that is clearly no match gives up before the fine level. When the best
/// hypothesis's normalised cost exceeds `1 − min_fitness` (its fine-level robust cost as high
/// as if fewer than `min_fitness` of the candidate's points had a match) and its fitness
/// measured there is below `min_fitness`, the registration is that measurement (the best
/// hypothesis's pose, not converged, no fine-level Hessian): the gate rejects it for its
/// overlap, and the fine level (about 40 % of the work of a wrong candidate on a 360° sensor) is
/// not run. Otherwise, and with `min_fitness` 0, exactly [`register_hypotheses`].
///
/// Allocates nothing.
///
/// # Errors
/// As [`register_hypotheses`]; [`Error::InvalidParameter`] (name `min_fitness`) outside `[0, 1]`.
pub fn register_hypotheses_for(
    query: &PreparedCloud,
    candidate: &PreparedCloud,
    yaws_deg: &[f64],
    init: &Pose,
    cfg: &RegConfig,
    out: &mut [Hypothesis],
    min_fitness: f64,
) -> Result<Hypotheses, RegError> {
    hypotheses(
        query,
        candidate,
        yaws_deg,
        init,
        cfg,
        out,
        min_fitness,
        None,
    )
}

/// [`register_hypotheses_for`] as a verifying detector runs it: each level also stops once its
/// cost has stalled ([`STALL_ITERATIONS`]) below the gate's `floors`; the gate judges the result.
/// The detector gives up below the floors' fitness (`min_fitness`: [`Floors::give_up`]). Outside
/// semver: see [`Floors`].
#[doc(hidden)]
#[allow(clippy::too_many_arguments)]
pub fn register_hypotheses_verifying(
    query: &PreparedCloud,
    candidate: &PreparedCloud,
    yaws_deg: &[f64],
    init: &Pose,
    cfg: &RegConfig,
    out: &mut [Hypothesis],
    min_fitness: f64,
    floors: Floors,
) -> Result<Hypotheses, RegError> {
    hypotheses(
        query,
        candidate,
        yaws_deg,
        init,
        cfg,
        out,
        min_fitness,
        Some(floors),
    )
}

#[allow(clippy::too_many_arguments)]
fn hypotheses(
    query: &PreparedCloud,
    candidate: &PreparedCloud,
    yaws_deg: &[f64],
    init: &Pose,
    cfg: &RegConfig,
    out: &mut [Hypothesis],
    min_fitness: f64,
    floors: Option<Floors>,
) -> Result<Hypotheses, RegError> {
    cfg.validate()?;
    if !(0.0..=1.0).contains(&min_fitness) {
        return Err(Error::InvalidParameter {
            name: "min_fitness",
            value: min_fitness,
            expected: "a fitness in [0, 1]",
        }
        .into());
    }
    if !query.prepared_with(cfg) || !candidate.prepared_with(cfg) {
        return Err(RegError::NotPreparedWith);
    }
    let base = Rigid::from_pose(init)?;
    if yaws_deg.is_empty() {
        return Err(Error::Empty { what: "yaws_deg" }.into());
    }
    if yaws_deg.len() > MAX_HYPOTHESES {
        return Err(Error::InvalidParameter {
            name: "yaws_deg",
            value: yaws_deg.len() as f64,
            expected: "at most MAX_HYPOTHESES (72) initial yaws",
        }
        .into());
    }
    if let Some(&y) = yaws_deg.iter().find(|y| !y.is_finite()) {
        return Err(Error::InvalidParameter {
            name: "yaws_deg",
            value: y,
            expected: "finite angles in degrees",
        }
        .into());
    }
    if out.len() < yaws_deg.len() {
        return Err(Error::BufferTooSmall {
            buffer: "out",
            needed: yaws_deg.len(),
            got: out.len(),
        }
        .into());
    }
    let start = |yaw: f64| {
        let dr = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw.to_radians());
        Rigid {
            rot: dr * base.rot,
            t: dr * base.t,
        }
    };
    let (qc, cc, max_corr) = match (&query.coarse, &candidate.coarse) {
        (Some(qc), Some(cc)) => (qc, cc, cfg.coarse_max_correspondence),
        _ => (&query.fine, &candidate.fine, cfg.max_correspondence),
    };
    let has_coarse = query.coarse.is_some() && candidate.coarse.is_some();
    let fine_ceiling =
        Robust::new(cfg, cfg.max_correspondence).ceiling() * candidate.fine.len() as f64;
    // The fine level's cost at a pose, normalised to [0, 1].
    let normalised = |x: &Rigid| {
        if fine_ceiling > 0.0 {
            (fine_cost(query, candidate, x, cfg) / fine_ceiling).clamp(0.0, 1.0)
        } else {
            1.0
        }
    };
    let mut best = 0;
    // The pose of the best hypothesis the schedule did not choose (its start or coarse result).
    let mut best_other = base;
    let eps = if has_coarse { COARSE_EPS_FACTOR } else { 1.0 };
    // Several hypotheses each get two thirds of the level's iterations, and the best one's
    // level then goes on for the rest (below): one that has not converged by then and is not
    // the best is clearly behind. (Half of them lost a basin pair on hku1.) Only with the
    // default schedule (the others may keep a hypothesis's start).
    let several = yaws_deg.len() > 1 && cfg.schedule == Schedule::CoarseFine;
    let share = RegConfig {
        max_iterations: if several {
            (2 * cfg.max_iterations).div_ceil(3)
        } else {
            cfg.max_iterations
        },
        ..*cfg
    };
    let failing = floors.map(|f| f.coarse(query, candidate, cfg));
    let stall = failing
        .as_ref()
        .map(|f| f as &dyn Fn(&Rigid, &Linear) -> bool);
    for (k, &yaw) in yaws_deg.iter().enumerate() {
        let s = start(yaw);
        let mut x = s;
        let o = align_level(qc, cc, &mut x, max_corr, &share, eps, 0.0, stall);
        let mut cost = if o.last.is_some() {
            normalised(&x)
        } else {
            1.0
        };
        let mut other = s;
        if has_coarse && cfg.schedule != Schedule::CoarseFine {
            let at_start = normalised(&s);
            if at_start <= cost {
                (cost, other, x) = (at_start, x, s);
            }
        }
        out[k] = Hypothesis {
            yaw_deg: yaw,
            pose: x.to_pose(),
            cost,
            converged: o.converged,
            iterations: o.iterations,
        };
        if k == 0 || out[k].cost < out[best].cost {
            best = k;
            best_other = other;
        }
    }
    // The best hypothesis's level goes on for the iterations it was not given, unless it
    // converged.
    let h = out[best];
    let rest = cfg.max_iterations.saturating_sub(h.iterations);
    if several && !h.converged && rest > 0 {
        if let Ok(mut x) = Rigid::from_pose(&h.pose) {
            let more = RegConfig {
                max_iterations: rest,
                ..*cfg
            };
            let o = align_level(qc, cc, &mut x, max_corr, &more, eps, 0.0, stall);
            out[best] = Hypothesis {
                pose: x.to_pose(),
                cost: if o.last.is_some() {
                    normalised(&x)
                } else {
                    1.0
                },
                converged: o.converged,
                iterations: h.iterations + o.iterations,
                ..h
            };
            // Still the lowest cost (ties by lower index), should going on have raised it.
            for k in 0..yaws_deg.len() {
                if out[k].cost < out[best].cost || (out[k].cost == out[best].cost && k < best) {
                    best = k;
                }
            }
        }
    }
    // The fine level goes on from the best hypothesis's pose (and from its other pose too when
    // the schedule runs both).
    let mut x = Rigid::from_pose(&out[best].pose).unwrap_or(base);
    if min_fitness > 0.0 && out[best].cost > 1.0 - min_fitness {
        let none = LevelOutcome {
            iterations: 0,
            converged: false,
            last: None,
        };
        let r = measure(query, candidate, &x, &none, cfg, out[best].iterations);
        if r.fitness < min_fitness {
            return Ok(Hypotheses {
                count: yaws_deg.len(),
                best,
                registration: r,
            });
        }
    }
    let alt = (has_coarse && cfg.schedule == Schedule::Both).then_some(best_other);
    Ok(Hypotheses {
        count: yaws_deg.len(),
        best,
        registration: fine_from(
            query,
            candidate,
            &mut x,
            alt,
            cfg,
            out[best].iterations,
            floors,
        ),
    })
}

/// Number of `hypotheses` (the best included) whose pose is within `tol_m` metres and
/// `tol_deg` degrees of `hypotheses[best]`'s; 0 when `best` is out of range.
pub fn agreement(hypotheses: &[Hypothesis], best: usize, tol_m: f64, tol_deg: f64) -> usize {
    let Some(b) = hypotheses.get(best) else {
        return 0;
    };
    hypotheses
        .iter()
        .filter(|h| {
            pose_distance(&h.pose, &b.pose).is_some_and(|(m, deg)| m <= tol_m && deg <= tol_deg)
        })
        .count()
}

/// Translation (metres) and rotation angle (degrees) of `inv(a) · b`; `None` for non-finite
/// input.
pub fn pose_distance(a: &Pose, b: &Pose) -> Option<(f64, f64)> {
    let ra = Matrix3::from_fn(|i, j| a[i][j]);
    let rb = Matrix3::from_fn(|i, j| b[i][j]);
    let d = ra.transpose() * rb;
    let ta = Vector3::new(a[0][3], a[1][3], a[2][3]);
    let tb = Vector3::new(b[0][3], b[1][3], b[2][3]);
    let m = (tb - ta).norm();
    let c = ((d.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    let deg = libm::acos(c).to_degrees();
    (m.is_finite() && deg.is_finite()).then_some((m, deg))
}

/// The initial yaws to try for a pair of places (degrees): 0° first, then the local minima of
/// the A-SOLiD shift cost ([`crate::heading_minima`]) lowest cost first, skipping any within one
/// azimuth bin of a yaw already chosen. Up to `out.len()` (at most [`crate::MAX_MINIMA`] + 1)
/// yaws are written; their number is returned. Allocates nothing.
///
/// # Errors
/// [`Error::LengthMismatch`] when the A-SOLiDs differ in length, [`Error::Empty`] when they
/// are empty.
pub fn hypothesis_yaws(
    a_query: &[f32],
    a_candidate: &[f32],
    out: &mut [f64],
) -> Result<usize, Error> {
    let mut minima = [crate::Heading {
        shift: 0,
        degrees: 0.0,
    }; crate::MAX_MINIMA];
    let room = out.len().min(crate::MAX_MINIMA + 1);
    let k = crate::heading_minima(
        a_query,
        a_candidate,
        &mut minima[..room.saturating_sub(1).max(1)],
    )?;
    if room == 0 {
        return Ok(0);
    }
    let bin = 360.0 / a_query.len() as f64;
    out[0] = 0.0;
    let mut m = 1;
    for h in &minima[..k] {
        if m >= room {
            break;
        }
        let near = out[..m].iter().any(|&y| {
            let d = libm::fabs(h.degrees - y) % 360.0;
            d.min(360.0 - d) < bin
        });
        if !near {
            out[m] = h.degrees;
            m += 1;
        }
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reg::{yaw_pose, IDENTITY};
    use crate::Points;

    /// The clouds `moved · xyz` (the query) and `xyz` (the candidate), prepared.
    fn prepared_pair(xyz: &[f64], moved: &Pose, cfg: &RegConfig) -> (PreparedCloud, PreparedCloud) {
        let query: Vec<f64> = xyz
            .chunks(3)
            .flat_map(|p| {
                (0..3).map(move |r| (0..3).map(|k| moved[r][k] * p[k]).sum::<f64>() + moved[r][3])
            })
            .collect();
        let q = PreparedCloud::new(Points::new(&query, 3).unwrap(), cfg).unwrap();
        let c = PreparedCloud::new(Points::new(xyz, 3).unwrap(), cfg).unwrap();
        (q, c)
    }

    #[test]
    fn hypotheses_share_the_coarse_iterations_and_the_best_goes_on() {
        // An L-shaped building's walls and the ground, seen again 1.5 m and 30° away: from the
        // yaws 0° (wrong), 30° (right) and 150°, the right one is the best, and its pose the
        // truth.
        let mut xyz = Vec::new();
        for i in 0..=120 {
            for j in 0..=20 {
                let (u, z) = (0.1 * f64::from(i), 0.15 * f64::from(j));
                xyz.extend([u - 4.0, 3.0, z, 8.0, u - 6.0, z, u * 0.5 - 6.0, -4.0, z]);
                xyz.extend([-6.0, u * 0.6 - 4.0, z]);
            }
            for j in 0..=80 {
                xyz.extend([0.12 * f64::from(i) - 6.0, 0.1 * f64::from(j) - 5.0, 0.0]);
            }
        }
        let mut moved = yaw_pose(30.0);
        (moved[0][3], moved[1][3]) = (1.5, -0.5);
        let cfg = RegConfig::default();
        let (q, c) = prepared_pair(&xyz, &moved, &cfg);
        let mut out = [Hypothesis::default(); 3];
        let h =
            register_hypotheses(&q, &c, &[0.0, 30.0, 150.0], &IDENTITY, &cfg, &mut out).unwrap();
        let share = (2 * cfg.max_iterations).div_ceil(3);
        for (k, o) in out.iter().enumerate() {
            let cap = if k == h.best {
                cfg.max_iterations
            } else {
                share
            };
            assert!(
                o.iterations <= cap,
                "hypothesis {k}: {} iterations",
                o.iterations
            );
            assert!(out[h.best].cost <= o.cost);
        }
        assert_eq!(h.best, 1);
        let (m, deg) = pose_distance(&h.registration.pose, &moved).unwrap();
        assert!(m < 0.05 && deg < 0.5, "{m} m, {deg}° off");
        // One hypothesis keeps the whole budget: a registration from its start (to rounding).
        let mut one = [Hypothesis::default(); 1];
        let h1 = register_hypotheses(&q, &c, &[30.0], &IDENTITY, &cfg, &mut one).unwrap();
        let r = register(&q, &c, &yaw_pose(30.0), &cfg).unwrap();
        let (m, deg) = pose_distance(&h1.registration.pose, &r.pose).unwrap();
        assert!(m < 1e-6 && deg < 1e-4, "{m} m, {deg}° from register's");
    }

    #[test]
    fn the_fine_level_measures_the_same_overlap_as_a_pass_of_its_own() {
        // A room with a pillar, and the same room seen 0.4 m and 3° away.
        let mut xyz = Vec::new();
        for i in 0..=160 {
            for j in 0..=24 {
                let (u, z) = (-8.0 + 0.1 * f64::from(i), 0.1 * f64::from(j));
                xyz.extend([u, -5.0, z, u, 5.0, z, 8.0, 0.0625 * f64::from(i) - 5.0, z]);
                xyz.extend([1.0 + 0.2 * libm::cos(u), 0.2 * libm::sin(u), z]);
            }
            for j in 0..=100 {
                xyz.extend([-8.0 + 0.1 * f64::from(i), -5.0 + 0.1 * f64::from(j), 0.0]);
            }
        }
        let mut moved = yaw_pose(3.0);
        moved[0][3] = 0.4;
        let cfg = RegConfig::default();
        let (q, c) = prepared_pair(&xyz, &moved, &cfg);
        let mut measured = 0;
        for start in [IDENTITY, yaw_pose(10.0), moved] {
            let mut x = Rigid::from_pose(&start).unwrap();
            let o = align_level(
                &q.fine,
                &c.fine,
                &mut x,
                1.0,
                &cfg,
                1.0,
                fine_inlier_d2(&cfg),
                None,
            );
            let Some(lin) = &o.last else { continue };
            let own = overlap(&q.fine, &c.fine, &x, cfg.inlier_distance);
            let by_level = lin.overlap;
            assert_eq!(
                (
                    by_level.all,
                    by_level.structure,
                    by_level.inliers,
                    by_level.sum
                ),
                (own.all, own.structure, own.inliers, own.sum)
            );
            assert!(own.inliers > 0);
            measured += 1;
        }
        assert_eq!(measured, 3);
    }

    /// A room with a pillar (`(dx, dy)` off the room's axis near x = 1 m).
    fn room(dx: f64, dy: f64) -> Vec<f64> {
        let mut xyz = Vec::new();
        for i in 0..=160 {
            for j in 0..=24 {
                let (u, z) = (-8.0 + 0.1 * f64::from(i), 0.1 * f64::from(j));
                xyz.extend([u, -5.0, z, u, 5.0, z, 8.0, 0.0625 * f64::from(i) - 5.0, z]);
                xyz.extend([1.0 + dx + 0.2 * libm::cos(u), dy + 0.2 * libm::sin(u), z]);
            }
            for j in 0..=100 {
                xyz.extend([-8.0 + 0.1 * f64::from(i), -5.0 + 0.1 * f64::from(j), 0.0]);
            }
        }
        xyz
    }

    /// An L-shaped building's walls and the ground (another place than [`room`]).
    fn building() -> Vec<f64> {
        let mut xyz = Vec::new();
        for i in 0..=120 {
            for j in 0..=20 {
                let (u, z) = (0.1 * f64::from(i), 0.15 * f64::from(j));
                xyz.extend([u - 4.0, 3.0, z, 8.0, u - 6.0, z, u * 0.5 - 6.0, -4.0, z]);
                xyz.extend([-6.0, u * 0.6 - 4.0, z]);
            }
            for j in 0..=80 {
                xyz.extend([0.12 * f64::from(i) - 6.0, 0.1 * f64::from(j) - 5.0, 0.0]);
            }
        }
        xyz
    }

    /// The stall tests' wrong match: the building against the room, with 200 iterations a level
    /// and the default gate's floors (the configuration, the floors, the two prepared clouds).
    fn wrong_match() -> (RegConfig, Floors, PreparedCloud, PreparedCloud) {
        let cfg = RegConfig {
            max_iterations: 200,
            ..RegConfig::default()
        };
        let floors = Floors::of(&super::super::Gate::default());
        let q = PreparedCloud::new(Points::new(&building(), 3).unwrap(), &cfg).unwrap();
        let c = PreparedCloud::new(Points::new(&room(0.0, 0.0), 3).unwrap(), &cfg).unwrap();
        (cfg, floors, q, c)
    }

    #[test]
    fn a_verifying_level_stops_at_a_stall_only_below_the_gates_floors() {
        // A wrong match (the building against the room, turned 45°), given 200 iterations a
        // level: without the stall (`register`'s) each level creeps on, 57 coarse iterations
        // and 191 fine before converging; with the gate's floors, a verifying detector's stops,
        // not converged, once its lowest cost has not fallen for STALL_ITERATIONS iterations
        // while its overlap is below them; with floors of 0 it runs exactly as without.
        let (cfg, floors, q, c) = wrong_match();
        let none = Floors::NONE;
        for coarse in [true, false] {
            let (target, source, corr, eps, inlier) = if coarse {
                let (Some(qc), Some(cc)) = (&q.coarse, &c.coarse) else {
                    panic!("no coarse level")
                };
                (
                    qc,
                    cc,
                    cfg.coarse_max_correspondence,
                    COARSE_EPS_FACTOR,
                    0.0,
                )
            } else {
                (
                    &q.fine,
                    &c.fine,
                    cfg.max_correspondence,
                    1.0,
                    fine_inlier_d2(&cfg),
                )
            };
            let run = |f: Option<Floors>| {
                let mut x = Rigid::from_pose(&yaw_pose(45.0)).unwrap();
                let failing = |x: &Rigid, lin: &Linear| {
                    f.is_some_and(|f| {
                        if coarse {
                            f.coarse(&q, &c, &cfg)(x, lin)
                        } else {
                            f.fine(&q, &c, &cfg)(x, lin)
                        }
                    })
                };
                let o = align_level(
                    target,
                    source,
                    &mut x,
                    corr,
                    &cfg,
                    eps,
                    inlier,
                    Some(&failing),
                );
                (o.iterations, o.converged, x.to_pose())
            };
            let (creeps, stops, runs_on) = (run(None), run(Some(floors)), run(Some(none)));
            assert!(creeps.0 > 40, "coarse {coarse}: {} iterations", creeps.0);
            assert!(
                !stops.1 && stops.0 < 20,
                "coarse {coarse}: {} iterations, converged {}",
                stops.0,
                stops.1
            );
            assert_eq!(runs_on, creeps, "coarse {coarse}");
        }
        // The room seen 0.3 m and 3° away: at or above the floors all along its stalls, the
        // verifying registration is exactly `register`'s, at the truth.
        let mut moved = yaw_pose(3.0);
        moved[0][3] = 0.3;
        let (q, c) = prepared_pair(&room(0.3, 0.0), &moved, &cfg);
        let plain = register(&q, &c, &IDENTITY, &cfg).unwrap();
        let verifying = register_verifying(&q, &c, &IDENTITY, &cfg, floors).unwrap();
        assert!(plain.converged);
        assert_eq!(
            (plain.pose, plain.iterations, plain.fitness),
            (verifying.pose, verifying.iterations, verifying.fitness)
        );
        let (m, deg) = pose_distance(&plain.pose, &moved).unwrap();
        assert!(m < 0.02 && deg < 0.2, "{m} m, {deg}° off");
    }

    #[test]
    fn a_verifying_registration_from_a_start_does_not_stop_its_coarse_level_at_a_stall() {
        // The wrong match above from the same start, given 200 iterations a level: a single
        // start's verifying registration runs its coarse level as `register` does, through its
        // stalls below the floors (57 iterations of creep), and here ends exactly as
        // `register` (the fine level converges from there). From the hypotheses (the same single
        // yaw) the coarse level stops at its first stall below the floors.
        let (cfg, floors, q, c) = wrong_match();
        let (Some(qc), Some(cc)) = (&q.coarse, &c.coarse) else {
            panic!("no coarse level")
        };
        let start = yaw_pose(45.0);
        let mut x = Rigid::from_pose(&start).unwrap();
        let coarse = align_level(
            qc,
            cc,
            &mut x,
            cfg.coarse_max_correspondence,
            &cfg,
            COARSE_EPS_FACTOR,
            0.0,
            None,
        );
        assert!(coarse.iterations > 40, "{} iterations", coarse.iterations);
        let plain = register(&q, &c, &start, &cfg).unwrap();
        let verifying = register_verifying(&q, &c, &start, &cfg, floors).unwrap();
        assert!(verifying.iterations > coarse.iterations);
        assert_eq!(
            (plain.pose, plain.iterations, plain.fitness),
            (verifying.pose, verifying.iterations, verifying.fitness)
        );
        let mut out = [Hypothesis::default(); 1];
        let h = register_hypotheses_verifying(&q, &c, &[0.0], &start, &cfg, &mut out, 0.0, floors)
            .unwrap();
        assert!(out[0].iterations < 20, "{} iterations", out[0].iterations);
        assert!(h.registration.iterations < coarse.iterations);
    }
}
