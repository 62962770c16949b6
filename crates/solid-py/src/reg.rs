//! Bindings of registration (`solid_lidar::reg`): `RegistrationConfig`, `PreparedCloud`,
//! `register`, `Registration`, `Hypothesis`, `AcceptanceGate`, `hypothesis_yaws` and the cloud
//! wire form. Argument checks, GIL release and error mapping only.

use std::sync::Arc;

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use solid_lidar::reg::{
    self, decode_cloud, encode_cloud, hypothesis_yaws as core_yaws, Gate, Hypothesis, Pose,
    PreparedCloud, RegConfig, RegError, Registration, IDENTITY,
};
use solid_lidar::Points;

use crate::args;
use crate::arrays::{borrow_points, matrix6, pose_array, Borrowed, PointSlice};
use crate::config::{PyGate, PyRegConfig};
use crate::describe::{comparable, PyDescriptor};
use crate::errors::{core_err, SolidError};

/// A cloud prepared for registration, exposed as `solid.PreparedCloud` (immutable).
#[pyclass(name = "PreparedCloud", module = "solid", frozen)]
pub struct PyPrepared {
    inner: Arc<PreparedCloud>,
    cfg: RegConfig,
}

fn prepare_slice(s: &PointSlice<'_>, cfg: &RegConfig) -> Result<PreparedCloud, RegError> {
    match *s {
        PointSlice::F32(d, stride) => PreparedCloud::new(Points::new(d, stride)?, cfg),
        PointSlice::F64(d, stride) => PreparedCloud::new(Points::new(d, stride)?, cfg),
    }
}

fn points_array<'py>(py: Python<'py>, pts: &[[f64; 3]]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let flat = args::try_copy(pts.as_flattened(), "cloud points")?;
    let a = Array2::from_shape_vec((pts.len(), 3), flat).map_err(core_err)?;
    Ok(a.into_pyarray(py))
}

fn config_or_default(config: Option<&PyRegConfig>) -> RegConfig {
    config.map_or_else(RegConfig::default, |c| c.inner)
}

#[pymethods]
impl PyPrepared {
    /// Prepares raw points (an (N, >=3) float32/float64 array, sensor frame).
    #[new]
    #[pyo3(signature = (points, config=None))]
    fn new(
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        config: Option<&PyRegConfig>,
    ) -> PyResult<Self> {
        let cfg = config_or_default(config);
        let borrowed = borrow_points(points, "points")?;
        let slice = borrowed.slice();
        let inner = py
            .detach(|| prepare_slice(&slice, &cfg))
            .map_err(core_err)?;
        Ok(PyPrepared {
            inner: Arc::new(inner),
            cfg,
        })
    }

    /// Decodes a cloud from `encode()` and prepares it with `config` (which must have the
    /// sender's preparation parameters for the two to register).
    #[staticmethod]
    #[pyo3(signature = (data, config=None))]
    fn decode(
        py: Python<'_>,
        data: &Bound<'_, PyAny>,
        config: Option<&PyRegConfig>,
    ) -> PyResult<Self> {
        let cfg = config_or_default(config);
        let data = args::bytes_arg(data, "data")?;
        let data = data.as_bytes();
        let inner = py
            .detach(|| {
                decode_cloud(data).and_then(|pts| PreparedCloud::from_downsampled(&pts, &cfg))
            })
            .map_err(core_err)?;
        Ok(PyPrepared {
            inner: Arc::new(inner),
            cfg,
        })
    }

    /// The compact wire form of the fine points (see `solid.encode_cloud`): the grid is the
    /// config's voxel size (0.5 m when it is 0).
    #[pyo3(signature = (bits=8))]
    fn encode<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = args::bits)] bits: u8,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let grid = if self.cfg.voxel_size > 0.0 {
            self.cfg.voxel_size
        } else {
            0.5
        };
        let bytes = encode_cloud(&self.inner.fine.points, grid, bits).map_err(core_err)?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// The fine points, (N, 3) float64.
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        points_array(py, &self.inner.fine.points)
    }

    /// The coarse points, (M, 3) float64 (empty without a coarse level).
    #[getter]
    fn coarse_points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        points_array(py, self.inner.coarse.as_ref().map_or(&[], |c| &c.points))
    }

    #[getter]
    fn config(&self) -> PyRegConfig {
        PyRegConfig { inner: self.cfg }
    }

    fn __len__(&self) -> usize {
        self.inner.fine.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "PreparedCloud(fine={}, coarse={})",
            self.inner.fine.len(),
            self.inner.coarse.as_ref().map_or(0, |c| c.len())
        )
    }
}

/// One initial yaw of a multi-hypothesis registration, exposed as `solid.Hypothesis`.
#[pyclass(name = "Hypothesis", module = "solid", frozen)]
#[derive(Clone)]
pub struct PyHypothesis {
    inner: Hypothesis,
}

#[pymethods]
impl PyHypothesis {
    /// The initial yaw, degrees.
    #[getter]
    fn yaw(&self) -> f64 {
        self.inner.yaw_deg
    }
    /// The pose after the coarse level, (4, 4) float64.
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        pose_array(py, &self.inner.pose)
    }
    /// Normalised robust cost at the fine level, in [0, 1] (lower is better).
    #[getter]
    fn cost(&self) -> f64 {
        self.inner.cost
    }
    #[getter]
    fn converged(&self) -> bool {
        self.inner.converged
    }
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.iterations
    }
    fn __repr__(&self) -> String {
        format!(
            "Hypothesis(yaw={:.2}, cost={:.4}, converged={})",
            self.inner.yaw_deg,
            self.inner.cost,
            if self.inner.converged {
                "True"
            } else {
                "False"
            }
        )
    }
}

/// The outcome of `solid.register`, exposed as `solid.Registration` (immutable).
#[pyclass(name = "Registration", module = "solid", frozen)]
pub struct PyRegistration {
    pub(crate) inner: Registration,
    pub(crate) hypotheses: Vec<Hypothesis>,
    pub(crate) best: Option<usize>,
}

#[pymethods]
impl PyRegistration {
    /// T_query_candidate, (4, 4) float64: p_query ≈ pose @ p_candidate (SPEC §3).
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        pose_array(py, &self.inner.pose)
    }
    /// min(overlap_query, overlap_candidate).
    #[getter]
    fn fitness(&self) -> f64 {
        self.inner.fitness
    }
    #[getter]
    fn overlap_query(&self) -> f64 {
        self.inner.overlap_query
    }
    #[getter]
    fn overlap_candidate(&self) -> f64 {
        self.inner.overlap_candidate
    }
    /// min of the two overlaps over structure points (not on horizontal surfaces).
    #[getter]
    fn structure_fitness(&self) -> f64 {
        self.inner.structure_fitness
    }
    /// RMS distance of the candidate's inliers (metres).
    #[getter]
    fn rmse(&self) -> f64 {
        self.inner.rmse
    }
    #[getter]
    fn inliers(&self) -> usize {
        self.inner.inliers
    }
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.iterations
    }
    #[getter]
    fn converged(&self) -> bool {
        self.inner.converged
    }
    /// Smallest eigenvalue of the rotation block of the information matrix, per correspondence.
    #[getter]
    fn degeneracy_rotation(&self) -> f64 {
        self.inner.degeneracy.rotation
    }
    /// Smallest eigenvalue of the translation block, per correspondence.
    #[getter]
    fn degeneracy_translation(&self) -> f64 {
        self.inner.degeneracy.translation
    }
    /// Smallest eigenvalue of the translation's information with the rotation marginalised, per
    /// correspondence.
    #[getter]
    fn degeneracy_marginal_translation(&self) -> f64 {
        self.inner.degeneracy.marginal_translation
    }
    /// The Gauss-Newton Hessian at the fine level, (6, 6): rotation first, perturbation on the
    /// left in the query's frame, unscaled.
    #[getter]
    fn hessian<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        matrix6(py, &self.inner.hessian)
    }
    /// The information matrix of `pose` for a pose graph, (6, 6), translation first.
    #[getter]
    fn information<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        matrix6(py, &self.inner.information())
    }
    /// Yaw of the pose, degrees in (-180, 180]: the heading of SPEC §3.
    #[getter]
    fn yaw(&self) -> f64 {
        self.inner.yaw_degrees()
    }
    /// Every hypothesis (empty unless `yaws` were given).
    #[getter]
    fn hypotheses(&self) -> Vec<PyHypothesis> {
        self.hypotheses
            .iter()
            .map(|h| PyHypothesis { inner: *h })
            .collect()
    }
    /// Index of the best hypothesis (None without hypotheses).
    #[getter]
    fn best_hypothesis(&self) -> Option<usize> {
        self.best
    }
    fn __repr__(&self) -> String {
        let t = self.inner.translation();
        format!(
            "Registration(t=[{:.3}, {:.3}, {:.3}], yaw={:.2}, fitness={:.3}, rmse={:.3}, converged={}, iterations={})",
            t[0],
            t[1],
            t[2],
            self.inner.yaw_degrees(),
            self.inner.fitness,
            self.inner.rmse,
            if self.inner.converged { "True" } else { "False" },
            self.inner.iterations
        )
    }
}

/// A cloud argument: a `PreparedCloud` (its config must match) or raw points to prepare.
enum CloudArg<'py> {
    Prepared(Arc<PreparedCloud>),
    Raw(Borrowed<'py>),
}

fn cloud_arg<'py>(v: &Bound<'py, PyAny>, what: &str, cfg: &RegConfig) -> PyResult<CloudArg<'py>> {
    if let Ok(p) = v.cast::<PyPrepared>() {
        let p = p.get();
        if !p.inner.prepared_with(cfg) {
            return Err(SolidError::new_err(format!(
                "{what} was prepared with another RegistrationConfig (voxel sizes, range or neighbors differ); prepare it with the config passed to register"
            )));
        }
        return Ok(CloudArg::Prepared(p.inner.clone()));
    }
    Ok(CloudArg::Raw(borrow_points(v, what)?))
}

/// What the GIL-free part needs of a cloud argument.
enum Source<'a> {
    Prepared(Arc<PreparedCloud>),
    Raw(PointSlice<'a>),
}

fn source<'a>(arg: &'a CloudArg<'_>) -> Source<'a> {
    match arg {
        CloudArg::Prepared(p) => Source::Prepared(p.clone()),
        CloudArg::Raw(b) => Source::Raw(b.slice()),
    }
}

fn resolve(s: Source<'_>, cfg: &RegConfig) -> Result<Arc<PreparedCloud>, RegError> {
    match s {
        Source::Prepared(p) => Ok(p),
        Source::Raw(slice) => Ok(Arc::new(prepare_slice(&slice, cfg)?)),
    }
}

fn parse_init(init: Option<&Bound<'_, PyAny>>) -> PyResult<Pose> {
    let Some(v) = init else { return Ok(IDENTITY) };
    if v.is_none() {
        return Ok(IDENTITY);
    }
    let rows: Vec<Vec<f64>> = v
        .extract()
        .map_err(|_| PyTypeError::new_err("init must be a (4, 4) array of floats or None"))?;
    if rows.len() != 4 || rows.iter().any(|r| r.len() != 4) {
        return Err(SolidError::new_err("init must have shape (4, 4)"));
    }
    let mut p = IDENTITY;
    for (i, r) in rows.iter().enumerate() {
        p[i].copy_from_slice(r);
    }
    Ok(p)
}

/// Registers `candidate` to `query`: the pose T_query_candidate with p_query ≈ T @ p_candidate.
#[pyfunction]
#[pyo3(signature = (query, candidate, init=None, *, yaws=None, config=None))]
fn register(
    py: Python<'_>,
    query: &Bound<'_, PyAny>,
    candidate: &Bound<'_, PyAny>,
    init: Option<&Bound<'_, PyAny>>,
    yaws: Option<Vec<f64>>,
    config: Option<&PyRegConfig>,
) -> PyResult<PyRegistration> {
    register_with(py, query, candidate, init, yaws, config, None)
}

/// `register` as a verifying detector runs it for a loop candidate (`gate`: its acceptance gate;
/// None: `AcceptanceGate()`): the fine level (with `yaws`, every level) also stops at a cost
/// stall below the gate's `min_fitness` / `min_structure_fitness`, and with `yaws` a candidate
/// clearly below `min_fitness` gives up before the fine level. For the convergence-basin benchmark
/// (`benches/reg_basin.py`); not part of the public API.
#[pyfunction]
#[pyo3(name = "_register_verifying", signature = (query, candidate, init=None, *, yaws=None, config=None, gate=None))]
fn register_verifying(
    py: Python<'_>,
    query: &Bound<'_, PyAny>,
    candidate: &Bound<'_, PyAny>,
    init: Option<&Bound<'_, PyAny>>,
    yaws: Option<Vec<f64>>,
    config: Option<&PyRegConfig>,
    gate: Option<&PyGate>,
) -> PyResult<PyRegistration> {
    let gate = gate.map_or_else(Gate::default, |g| g.inner);
    let floors = reg::Floors::of(&gate);
    register_with(py, query, candidate, init, yaws, config, Some(floors))
}

/// `register`, or with a gate's `floors` the verifying detector's registration
/// (`reg::register_verifying`, `reg::register_hypotheses_verifying` giving up below the floors'
/// `min_fitness`: `Floors::give_up`, as the detector).
fn register_with(
    py: Python<'_>,
    query: &Bound<'_, PyAny>,
    candidate: &Bound<'_, PyAny>,
    init: Option<&Bound<'_, PyAny>>,
    yaws: Option<Vec<f64>>,
    config: Option<&PyRegConfig>,
    floors: Option<reg::Floors>,
) -> PyResult<PyRegistration> {
    let cfg = config_or_default(config);
    let init = parse_init(init)?;
    let q = cloud_arg(query, "query", &cfg)?;
    let c = cloud_arg(candidate, "candidate", &cfg)?;
    if let Some(y) = &yaws {
        if y.is_empty() {
            return Err(SolidError::new_err(
                "yaws must hold at least one angle (degrees) or be None",
            ));
        }
    }
    let (q_src, c_src) = (source(&q), source(&c));
    let out = py.detach(|| -> Result<PyRegistration, RegError> {
        let qp = resolve(q_src, &cfg)?;
        let cp = resolve(c_src, &cfg)?;
        match yaws {
            None => Ok(PyRegistration {
                inner: match floors {
                    None => reg::register(&qp, &cp, &init, &cfg)?,
                    Some(f) => reg::register_verifying(&qp, &cp, &init, &cfg, f)?,
                },
                hypotheses: Vec::new(),
                best: None,
            }),
            Some(y) => {
                let mut hyps = vec![Hypothesis::default(); y.len()];
                let h = match floors {
                    Some(f) => reg::register_hypotheses_verifying(
                        &qp,
                        &cp,
                        &y,
                        &init,
                        &cfg,
                        &mut hyps,
                        f.give_up(),
                        f,
                    )?,
                    None => reg::register_hypotheses(&qp, &cp, &y, &init, &cfg, &mut hyps)?,
                };
                Ok(PyRegistration {
                    inner: h.registration,
                    hypotheses: hyps,
                    best: Some(h.best),
                })
            }
        }
    });
    out.map_err(core_err)
}

/// Initial yaws (degrees) worth trying for a pair of places: 0° then the local minima of the
/// A-SOLiD shift cost, at most `n` in all.
#[pyfunction]
#[pyo3(signature = (query, candidate, n=4))]
fn hypothesis_yaws(
    query: &PyDescriptor,
    candidate: &PyDescriptor,
    #[pyo3(from_py_with = args::n)] n: usize,
) -> PyResult<Vec<f64>> {
    comparable(query, candidate)?;
    let mut out = vec![0.0; n.min(solid_lidar::MAX_MINIMA + 1)];
    let k = core_yaws(&query.inner.a, &candidate.inner.a, &mut out).map_err(core_err)?;
    out.truncate(k);
    Ok(out)
}

/// Encodes (N, 3) points compactly (quantised on a grid of edge `grid` metres, `bits` bits per
/// axis within a cell, CRC-checked).
#[pyfunction]
#[pyo3(name = "encode_cloud", signature = (points, grid=0.5, bits=8))]
fn encode_cloud_py<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    grid: f64,
    #[pyo3(from_py_with = args::bits)] bits: u8,
) -> PyResult<Bound<'py, PyBytes>> {
    let borrowed = borrow_points(points, "points")?;
    let slice = borrowed.slice();
    let n = match slice {
        PointSlice::F32(d, s) => d.len() / s,
        PointSlice::F64(d, s) => d.len() / s,
    };
    let mut pts: Vec<[f64; 3]> = args::try_vec(n, "points")?;
    match slice {
        PointSlice::F32(d, s) => pts.extend(
            d.chunks_exact(s)
                .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]),
        ),
        PointSlice::F64(d, s) => pts.extend(d.chunks_exact(s).map(|p| [p[0], p[1], p[2]])),
    }
    let bytes = py
        .detach(|| encode_cloud(&pts, grid, bits))
        .map_err(core_err)?;
    Ok(PyBytes::new(py, &bytes))
}

/// Decodes points encoded by `encode_cloud`, (N, 3) float64.
#[pyfunction]
#[pyo3(name = "decode_cloud")]
fn decode_cloud_py<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let data = args::bytes_arg(data, "data")?;
    let data = data.as_bytes();
    let pts = py.detach(|| decode_cloud(data)).map_err(core_err)?;
    points_array(py, &pts)
}

/// Adds the registration classes and functions to the module.
pub fn register_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyPrepared>()?;
    m.add_class::<PyHypothesis>()?;
    m.add_class::<PyRegistration>()?;
    add_functions! { m, register, register_verifying, hypothesis_yaws, encode_cloud_py, decode_cloud_py }
    Ok(())
}
