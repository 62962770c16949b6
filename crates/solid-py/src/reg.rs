//! Bindings of registration (`solid_lidar::reg`): `RegistrationConfig`, `PreparedCloud`,
//! `register`, `Registration`, `Hypothesis`, `AcceptanceGate`, `hypothesis_yaws` and the cloud
//! wire form. Argument checks, GIL release and error mapping only.

use std::sync::Arc;

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use solid_lidar::reg::{
    self, decode_cloud, encode_cloud, hypothesis_yaws as core_yaws, Factor, Gate, Hypothesis,
    Kernel, Pose, PreparedCloud, RegConfig, RegError, Registration, IDENTITY,
};
use solid_lidar::Points;

use crate::{args, borrow_points, core_err, ConfigError, PointSlice, PyDescriptor, SolidError};

fn reg_err(e: RegError) -> PyErr {
    match e {
        RegError::Core(c) => core_err(c),
        // Corrupt or foreign bytes, as for a database or a place.
        RegError::Format { .. } => {
            Python::attach(|py| crate::engine::database_error(py, e.to_string()))
        }
        other => SolidError::new_err(other.to_string()),
    }
}

const FACTORS: [(&str, Factor); 2] = [
    ("gicp", Factor::Gicp),
    ("point-to-plane", Factor::PointToPlane),
];
const KERNELS: [(&str, Kernel); 2] = [
    ("geman-mcclure", Kernel::GemanMcClure),
    ("none", Kernel::None),
];

fn factor_name(f: Factor) -> &'static str {
    FACTORS
        .iter()
        .find(|(_, v)| *v == f)
        .map_or("gicp", |(n, _)| n)
}

fn kernel_name(k: Kernel) -> &'static str {
    KERNELS
        .iter()
        .find(|(_, v)| *v == k)
        .map_or("none", |(n, _)| n)
}

/// `solid.RegistrationConfig`: the parameters of registration (immutable, validated).
/// A registration config as a dict (what `RegistrationConfig(**d)` takes back).
pub(crate) fn reg_config_dict<'py>(py: Python<'py>, c: &RegConfig) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);

    d.set_item("voxel_size", c.voxel_size)?;
    d.set_item("coarse_voxel_size", c.coarse_voxel_size)?;
    d.set_item("min_range", c.min_range)?;
    d.set_item("max_range", c.max_range)?;
    d.set_item("neighbors", c.neighbors)?;
    d.set_item("max_correspondence", c.max_correspondence)?;
    d.set_item("coarse_max_correspondence", c.coarse_max_correspondence)?;
    d.set_item("max_iterations", c.max_iterations)?;
    d.set_item("rotation_eps_deg", c.rotation_eps_deg)?;
    d.set_item("translation_eps", c.translation_eps)?;
    d.set_item("factor", factor_name(c.factor))?;
    d.set_item("kernel", kernel_name(c.kernel))?;
    d.set_item("kernel_scale", c.kernel_scale)?;
    d.set_item("inlier_distance", c.inlier_distance)?;
    Ok(d)
}

/// A registration config from a `RegistrationConfig` or a dict of overrides of `base`.
pub(crate) fn reg_config_from(obj: &Bound<'_, PyAny>, base: RegConfig) -> PyResult<RegConfig> {
    if let Ok(c) = obj.cast::<PyRegConfig>() {
        return Ok(c.get().inner);
    }
    let d = obj.cast::<PyDict>().map_err(|_| {
        PyTypeError::new_err(
            "registration must be a solid.RegistrationConfig or a dict of its parameters",
        )
    })?;
    apply(base, Some(d))
}

/// A gate as a dict (what `AcceptanceGate(**d)` takes back).
pub(crate) fn gate_dict<'py>(py: Python<'py>, g: &Gate) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("require_converged", g.require_converged)?;
    d.set_item("min_fitness", g.min_fitness)?;
    d.set_item("min_structure_fitness", g.min_structure_fitness)?;
    d.set_item("max_rmse", g.max_rmse)?;
    d.set_item("min_translation_information", g.min_translation_information)?;
    d.set_item("min_rotation_information", g.min_rotation_information)?;
    d.set_item("min_agreement", g.min_agreement)?;
    d.set_item("max_translation", g.max_translation)?;
    d.set_item("agree_translation", g.agree_translation)?;
    d.set_item("agree_rotation_deg", g.agree_rotation_deg)?;
    Ok(d)
}

/// A gate from an `AcceptanceGate` or a dict of its parameters (missing ones: the defaults).
pub(crate) fn gate_from(obj: &Bound<'_, PyAny>) -> PyResult<Gate> {
    if let Ok(g) = obj.cast::<PyGate>() {
        return Ok(g.get().inner);
    }
    let d = obj.cast::<PyDict>().map_err(|_| {
        PyTypeError::new_err("gate must be a solid.AcceptanceGate or a dict of its thresholds")
    })?;
    let g = obj.py().get_type::<PyGate>().call((), Some(d))?;
    Ok(g.cast::<PyGate>()?.get().inner)
}

#[pyclass(name = "RegistrationConfig", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyRegConfig {
    pub(crate) inner: RegConfig,
}

const REG_FIELDS: [&str; 14] = [
    "voxel_size",
    "coarse_voxel_size",
    "min_range",
    "max_range",
    "neighbors",
    "max_correspondence",
    "coarse_max_correspondence",
    "max_iterations",
    "rotation_eps_deg",
    "translation_eps",
    "factor",
    "kernel",
    "kernel_scale",
    "inlier_distance",
];

fn apply(mut c: RegConfig, kw: Option<&Bound<'_, PyDict>>) -> PyResult<RegConfig> {
    if let Some(kw) = kw {
        for (k, v) in kw.iter() {
            let key: String = k.extract()?;
            let float = || args::float_param(&v, &key);
            let int = || args::int_arg(&v, &key, 0, usize::MAX as i128);
            let name = || -> PyResult<String> {
                v.extract::<String>()
                    .map_err(|_| PyTypeError::new_err(format!("{key} must be a string")))
            };
            match key.as_str() {
                "voxel_size" => c.voxel_size = float()?,
                "coarse_voxel_size" => c.coarse_voxel_size = float()?,
                "min_range" => c.min_range = float()?,
                "max_range" => c.max_range = float()?,
                "neighbors" => c.neighbors = int()?,
                "max_correspondence" => c.max_correspondence = float()?,
                "coarse_max_correspondence" => c.coarse_max_correspondence = float()?,
                "max_iterations" => c.max_iterations = int()?,
                "rotation_eps_deg" => c.rotation_eps_deg = float()?,
                "translation_eps" => c.translation_eps = float()?,
                "kernel_scale" => c.kernel_scale = float()?,
                "inlier_distance" => c.inlier_distance = float()?,
                "factor" => {
                    let n = name()?;
                    c.factor = FACTORS
                        .iter()
                        .find(|(f, _)| *f == n)
                        .map(|(_, f)| *f)
                        .ok_or_else(|| {
                            ConfigError::new_err(format!(
                                "invalid factor = {n:?}: expected \"gicp\" or \"point-to-plane\""
                            ))
                        })?;
                }
                "kernel" => {
                    let n = name()?;
                    c.kernel = KERNELS
                        .iter()
                        .find(|(k, _)| *k == n)
                        .map(|(_, k)| *k)
                        .ok_or_else(|| {
                            ConfigError::new_err(format!(
                                "invalid kernel = {n:?}: expected \"geman-mcclure\" or \"none\""
                            ))
                        })?;
                }
                other => {
                    return Err(PyTypeError::new_err(format!(
                        "unknown RegistrationConfig parameter {other:?}; valid: {}",
                        REG_FIELDS.join(", ")
                    )))
                }
            }
        }
    }
    c.validate().map_err(reg_err)?;
    Ok(c)
}

#[pymethods]
impl PyRegConfig {
    /// Defaults (measured; see the Rust documentation of `solid_lidar::reg`) with keyword
    /// overrides.
    #[new]
    #[pyo3(signature = (**overrides))]
    fn new(overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyRegConfig {
            inner: apply(RegConfig::default(), overrides)?,
        })
    }

    /// A copy with some parameters changed.
    #[pyo3(signature = (**overrides))]
    fn replace(&self, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyRegConfig {
            inner: apply(self.inner, overrides)?,
        })
    }

    /// The parameters as a dict (what `RegistrationConfig(**d)` takes back).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        reg_config_dict(py, &self.inner)
    }

    #[getter]
    fn voxel_size(&self) -> f64 {
        let c = &self.inner;
        c.voxel_size
    }
    #[getter]
    fn coarse_voxel_size(&self) -> f64 {
        let c = &self.inner;
        c.coarse_voxel_size
    }
    #[getter]
    fn min_range(&self) -> f64 {
        let c = &self.inner;
        c.min_range
    }
    #[getter]
    fn max_range(&self) -> f64 {
        let c = &self.inner;
        c.max_range
    }
    #[getter]
    fn neighbors(&self) -> usize {
        let c = &self.inner;
        c.neighbors
    }
    #[getter]
    fn max_correspondence(&self) -> f64 {
        let c = &self.inner;
        c.max_correspondence
    }
    #[getter]
    fn coarse_max_correspondence(&self) -> f64 {
        let c = &self.inner;
        c.coarse_max_correspondence
    }
    #[getter]
    fn max_iterations(&self) -> usize {
        let c = &self.inner;
        c.max_iterations
    }
    #[getter]
    fn rotation_eps_deg(&self) -> f64 {
        let c = &self.inner;
        c.rotation_eps_deg
    }
    #[getter]
    fn translation_eps(&self) -> f64 {
        let c = &self.inner;
        c.translation_eps
    }
    #[getter]
    fn factor(&self) -> &'static str {
        let c = &self.inner;
        factor_name(c.factor)
    }
    #[getter]
    fn kernel(&self) -> &'static str {
        let c = &self.inner;
        kernel_name(c.kernel)
    }
    #[getter]
    fn kernel_scale(&self) -> f64 {
        let c = &self.inner;
        c.kernel_scale
    }
    #[getter]
    fn inlier_distance(&self) -> f64 {
        let c = &self.inner;
        c.inlier_distance
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let d = self.to_dict(py)?;
        let parts: Vec<String> = REG_FIELDS
            .iter()
            .map(|k| -> PyResult<String> {
                let v = d
                    .get_item(k)?
                    .map(|v| v.repr().map(|r| r.to_string()))
                    .transpose()?;
                Ok(format!("{k}={}", v.unwrap_or_default()))
            })
            .collect::<PyResult<_>>()?;
        Ok(format!("RegistrationConfig({})", parts.join(", ")))
    }
}

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
    let a = Array2::from_shape_vec((pts.len(), 3), flat)
        .map_err(|e| SolidError::new_err(e.to_string()))?;
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
        let inner = py.detach(|| prepare_slice(&slice, &cfg)).map_err(reg_err)?;
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
            .map_err(reg_err)?;
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
        let bytes = encode_cloud(&self.inner.fine.points, grid, bits).map_err(reg_err)?;
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

fn pose_array<'py>(py: Python<'py>, p: &Pose) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((4, 4), |(i, j)| p[i][j]).into_pyarray(py)
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
    inner: Registration,
    hypotheses: Vec<Hypothesis>,
    best: Option<usize>,
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
    Raw(crate::Borrowed<'py>),
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
                inner: reg::register(&qp, &cp, &init, &cfg)?,
                hypotheses: Vec::new(),
                best: None,
            }),
            Some(y) => {
                let mut hyps = vec![Hypothesis::default(); y.len()];
                let h = reg::register_hypotheses(&qp, &cp, &y, &init, &cfg, &mut hyps)?;
                Ok(PyRegistration {
                    inner: h.registration,
                    hypotheses: hyps,
                    best: Some(h.best),
                })
            }
        }
    });
    out.map_err(reg_err)
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
    crate::comparable(query, candidate)?;
    let mut out = vec![0.0; n.min(solid_lidar::MAX_MINIMA + 1)];
    let k = core_yaws(&query.inner.a, &candidate.inner.a, &mut out).map_err(core_err)?;
    out.truncate(k);
    Ok(out)
}

/// The acceptance gate, exposed as `solid.AcceptanceGate` (immutable).
#[pyclass(name = "AcceptanceGate", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyGate {
    pub(crate) inner: Gate,
}

#[pymethods]
impl PyGate {
    /// The measured default thresholds, with keyword overrides.
    #[new]
    #[pyo3(signature = (*, require_converged=None, min_fitness=None, min_structure_fitness=None, max_rmse=None, min_translation_information=None, min_rotation_information=None, min_agreement=None, max_translation=None, agree_translation=None, agree_rotation_deg=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        require_converged: Option<bool>,
        min_fitness: Option<&Bound<'_, PyAny>>,
        min_structure_fitness: Option<&Bound<'_, PyAny>>,
        max_rmse: Option<&Bound<'_, PyAny>>,
        min_translation_information: Option<&Bound<'_, PyAny>>,
        min_rotation_information: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = args::min_agreement)] min_agreement: Option<usize>,
        max_translation: Option<&Bound<'_, PyAny>>,
        agree_translation: Option<&Bound<'_, PyAny>>,
        agree_rotation_deg: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let mut g = Gate::default();
        let number = |name: &str, v: Option<&Bound<'_, PyAny>>| -> PyResult<Option<f64>> {
            v.filter(|v| !v.is_none())
                .map(|v| args::float_param(v, name))
                .transpose()
        };
        let max_translation = number("max_translation", max_translation)?;
        let set = |name: &str, v: Option<&Bound<'_, PyAny>>, slot: &mut f64| -> PyResult<()> {
            if let Some(v) = number(name, v)? {
                if !v.is_finite() {
                    return Err(ConfigError::new_err(format!(
                        "invalid {name} = {v}: expected a finite number"
                    )));
                }
                *slot = v;
            }
            Ok(())
        };
        set("min_fitness", min_fitness, &mut g.min_fitness)?;
        set(
            "min_structure_fitness",
            min_structure_fitness,
            &mut g.min_structure_fitness,
        )?;
        set("max_rmse", max_rmse, &mut g.max_rmse)?;
        set(
            "min_translation_information",
            min_translation_information,
            &mut g.min_translation_information,
        )?;
        set(
            "min_rotation_information",
            min_rotation_information,
            &mut g.min_rotation_information,
        )?;
        set(
            "agree_translation",
            agree_translation,
            &mut g.agree_translation,
        )?;
        if let Some(v) = max_translation {
            if v.is_nan() {
                return Err(ConfigError::new_err(format!(
                    "invalid max_translation = {v}: expected a number (inf: no limit)"
                )));
            }
            g.max_translation = v;
        }
        set(
            "agree_rotation_deg",
            agree_rotation_deg,
            &mut g.agree_rotation_deg,
        )?;
        if let Some(v) = require_converged {
            g.require_converged = v;
        }
        if let Some(v) = min_agreement {
            g.min_agreement = v;
        }
        Ok(PyGate { inner: g })
    }

    /// The thresholds as a dict (what `AcceptanceGate(**d)` takes back).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        gate_dict(py, &self.inner)
    }

    /// None when `registration` passes, else why it is rejected.
    fn check(&self, registration: &PyRegistration) -> Option<String> {
        self.inner
            .check(
                &registration.inner,
                &registration.hypotheses,
                registration.best.unwrap_or(0),
            )
            .err()
            .map(|r| r.to_string())
    }

    /// Whether `registration` passes every threshold.
    fn accepts(&self, registration: &PyRegistration) -> bool {
        self.check(registration).is_none()
    }

    /// How many hypotheses reached the best one's pose (0 without hypotheses).
    fn agreement(&self, registration: &PyRegistration) -> usize {
        registration
            .best
            .map_or(0, |b| self.inner.agreement(&registration.hypotheses, b))
    }

    #[getter]
    fn require_converged(&self) -> bool {
        self.inner.require_converged
    }
    #[getter]
    fn min_fitness(&self) -> f64 {
        self.inner.min_fitness
    }
    #[getter]
    fn min_structure_fitness(&self) -> f64 {
        self.inner.min_structure_fitness
    }
    #[getter]
    fn max_rmse(&self) -> f64 {
        self.inner.max_rmse
    }
    #[getter]
    fn min_translation_information(&self) -> f64 {
        self.inner.min_translation_information
    }
    #[getter]
    fn min_rotation_information(&self) -> f64 {
        self.inner.min_rotation_information
    }
    #[getter]
    fn min_agreement(&self) -> usize {
        self.inner.min_agreement
    }
    #[getter]
    fn max_translation(&self) -> f64 {
        self.inner.max_translation
    }
    #[getter]
    fn agree_translation(&self) -> f64 {
        self.inner.agree_translation
    }
    #[getter]
    fn agree_rotation_deg(&self) -> f64 {
        self.inner.agree_rotation_deg
    }
    fn __repr__(&self) -> String {
        let g = &self.inner;
        format!(
            "AcceptanceGate(require_converged={}, min_fitness={:?}, min_structure_fitness={:?}, max_rmse={:?}, min_translation_information={:?}, min_rotation_information={:?}, min_agreement={}, max_translation={:?}, agree_translation={:?}, agree_rotation_deg={:?})",
            if g.require_converged { "True" } else { "False" },
            g.min_fitness,
            g.min_structure_fitness,
            g.max_rmse,
            g.min_translation_information,
            g.min_rotation_information,
            g.min_agreement,
            g.max_translation,
            g.agree_translation,
            g.agree_rotation_deg
        )
    }
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
        .map_err(reg_err)?;
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
    let pts = py.detach(|| decode_cloud(data)).map_err(reg_err)?;
    points_array(py, &pts)
}

/// Adds the registration classes and functions to the module.
pub fn register_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRegConfig>()?;
    m.add_class::<PyPrepared>()?;
    m.add_class::<PyHypothesis>()?;
    m.add_class::<PyRegistration>()?;
    m.add_class::<PyGate>()?;
    m.add_function(wrap_pyfunction!(register, m)?)?;
    m.add_function(wrap_pyfunction!(hypothesis_yaws, m)?)?;
    m.add_function(wrap_pyfunction!(encode_cloud_py, m)?)?;
    m.add_function(wrap_pyfunction!(decode_cloud_py, m)?)?;
    Ok(())
}
