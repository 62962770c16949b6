//! The parameter classes: `SolidConfig`, `DetectorConfig`, `RegistrationConfig` and
//! `AcceptanceGate`.

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use solid_lidar::db::DetectorConfig;
use solid_lidar::reg::{Factor, Gate, Kernel, RegConfig};
use solid_lidar::{Config, PRESETS};

use crate::args::{self, float_param, int_arg};
use crate::reg::PyRegistration;
use crate::{core_err, core_err as reg_err, ConfigError};

/// The descriptor configuration exposed as `solid.SolidConfig` (immutable).
#[pyclass(name = "SolidConfig", module = "solid", frozen, eq)]
#[derive(Clone)]
pub struct PyConfig {
    /// The validated core config.
    pub inner: Config,
    /// The preset it was made from (`SolidConfig.preset`), kept through `replace` and pickling:
    /// it chooses the loop detector's default threshold. Not part of equality or hashing.
    pub base_preset: Option<&'static str>,
}

impl PartialEq for PyConfig {
    fn eq(&self, other: &Self) -> bool {
        self.inner == other.inner
    }
}

const FIELDS: [&str; 8] = [
    "n_range",
    "n_azimuth",
    "n_elevation",
    "fov_up",
    "fov_down",
    "min_range",
    "max_range",
    "voxel_size",
];

/// A bin count of the config (`n_range`, ...): an integer; its range is the core's to check.
fn count_param(v: &Bound<'_, PyAny>, name: &str) -> PyResult<usize> {
    int_arg(v, name, 0, u32::MAX.into())
}

/// Applies keyword overrides (by field name) to `cfg`, then validates it.
fn apply_overrides(mut cfg: Config, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Config> {
    if let Some(kw) = overrides {
        for (k, v) in kw.iter() {
            let key: String = k.extract()?;
            let float = |v: &Bound<'_, PyAny>| float_param(v, &key);
            let int = |v: &Bound<'_, PyAny>| count_param(v, &key);
            match key.as_str() {
                "n_range" => cfg.n_range = int(&v)?,
                "n_azimuth" => cfg.n_azimuth = int(&v)?,
                "n_elevation" => cfg.n_elevation = int(&v)?,
                "fov_up" => cfg.fov_up = float(&v)?,
                "fov_down" => cfg.fov_down = float(&v)?,
                "min_range" => cfg.min_range = float(&v)?,
                "max_range" => cfg.max_range = float(&v)?,
                "voxel_size" => cfg.voxel_size = float(&v)?,
                other => {
                    return Err(PyTypeError::new_err(format!(
                        "unknown SolidConfig parameter {other:?}; valid: {}",
                        FIELDS.join(", ")
                    )))
                }
            }
        }
    }
    cfg.validate().map_err(core_err)?;
    Ok(cfg)
}

impl PyConfig {
    /// Wraps a config that was validated already (a database's, say).
    pub fn new_unchecked(inner: Config) -> Self {
        PyConfig {
            inner,
            base_preset: None,
        }
    }

    /// The detector defaults for this config: its base preset's loop threshold, else the
    /// general default.
    pub fn detector_defaults(&self) -> solid_lidar::db::DetectorConfig {
        self.base_preset
            .and_then(|p| solid_lidar::db::DetectorConfig::for_preset(p).ok())
            .unwrap_or_default()
    }
}

#[pymethods]
impl PyConfig {
    #[new]
    #[pyo3(signature = (*, fov_up, fov_down, n_elevation, n_range=None, n_azimuth=None, min_range=None, max_range=None, voxel_size=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        fov_up: &Bound<'_, PyAny>,
        fov_down: &Bound<'_, PyAny>,
        n_elevation: &Bound<'_, PyAny>,
        n_range: Option<&Bound<'_, PyAny>>,
        n_azimuth: Option<&Bound<'_, PyAny>>,
        min_range: Option<&Bound<'_, PyAny>>,
        max_range: Option<&Bound<'_, PyAny>>,
        voxel_size: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let (fov_up, fov_down) = (
            float_param(fov_up, "fov_up")?,
            float_param(fov_down, "fov_down")?,
        );
        // The docs/spec.md §1 defaults come from the core (Config::with_defaults), not from here.
        let d = Config::with_defaults(fov_up, fov_down, 1);
        let count = |v: Option<&Bound<'_, PyAny>>, name, default| match v {
            Some(v) if !v.is_none() => count_param(v, name),
            _ => Ok(default),
        };
        let float = |v: Option<&Bound<'_, PyAny>>, name, default| match v {
            Some(v) if !v.is_none() => float_param(v, name),
            _ => Ok(default),
        };
        let cfg = Config {
            n_range: count(n_range, "n_range", d.n_range)?,
            n_azimuth: count(n_azimuth, "n_azimuth", d.n_azimuth)?,
            n_elevation: count_param(n_elevation, "n_elevation")?,
            fov_up,
            fov_down,
            min_range: float(min_range, "min_range", d.min_range)?,
            max_range: float(max_range, "max_range", d.max_range)?,
            voxel_size: float(voxel_size, "voxel_size", d.voxel_size)?,
        };
        cfg.validate().map_err(core_err)?;
        Ok(PyConfig::new_unchecked(cfg))
    }

    /// A sensor preset (docs/spec.md §4), with optional keyword overrides.
    #[staticmethod]
    #[pyo3(signature = (name, **overrides))]
    fn preset(name: &str, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let base = Config::preset(name).map_err(|_| {
            ConfigError::new_err(format!(
                "unknown preset {name:?}; available: {}",
                PRESETS
                    .iter()
                    .map(|p| p.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })?;
        let preset = PRESETS.iter().find(|p| p.name == name).map(|p| p.name);
        Ok(PyConfig {
            inner: apply_overrides(base, overrides)?,
            base_preset: preset,
        })
    }

    /// A copy with some parameters changed (it keeps its base preset).
    #[pyo3(signature = (**overrides))]
    fn replace(&self, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyConfig {
            inner: apply_overrides(self.inner, overrides)?,
            base_preset: self.base_preset,
        })
    }

    /// The preset this config was made from (`SolidConfig.preset(name, ...)`), or None. It
    /// chooses the loop detector's default threshold; it is not part of equality.
    #[getter]
    fn base_preset(&self) -> Option<&'static str> {
        self.base_preset
    }

    /// The parameters as a dict (what `SolidConfig(**d)` takes back).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = &self.inner;
        let d = PyDict::new(py);
        d.set_item("n_range", c.n_range)?;
        d.set_item("n_azimuth", c.n_azimuth)?;
        d.set_item("n_elevation", c.n_elevation)?;
        d.set_item("fov_up", c.fov_up)?;
        d.set_item("fov_down", c.fov_down)?;
        d.set_item("min_range", c.min_range)?;
        d.set_item("max_range", c.max_range)?;
        d.set_item("voxel_size", c.voxel_size)?;
        Ok(d)
    }

    #[getter]
    fn n_range(&self) -> usize {
        self.inner.n_range
    }
    #[getter]
    fn n_azimuth(&self) -> usize {
        self.inner.n_azimuth
    }
    #[getter]
    fn n_elevation(&self) -> usize {
        self.inner.n_elevation
    }
    #[getter]
    fn fov_up(&self) -> f64 {
        self.inner.fov_up
    }
    #[getter]
    fn fov_down(&self) -> f64 {
        self.inner.fov_down
    }
    #[getter]
    fn min_range(&self) -> f64 {
        self.inner.min_range
    }
    #[getter]
    fn max_range(&self) -> f64 {
        self.inner.max_range
    }
    #[getter]
    fn voxel_size(&self) -> f64 {
        self.inner.voxel_size
    }
    /// A 64-bit fingerprint of every parameter; equal configs have equal fingerprints.
    #[getter]
    fn fingerprint(&self) -> u64 {
        self.inner.fingerprint()
    }

    fn __hash__(&self) -> u64 {
        self.inner.fingerprint()
    }

    pub(crate) fn __repr__(&self) -> String {
        let c = &self.inner;
        format!(
            "SolidConfig(n_range={}, n_azimuth={}, n_elevation={}, fov_up={:?}, fov_down={:?}, min_range={:?}, max_range={:?}, voxel_size={:?})",
            c.n_range, c.n_azimuth, c.n_elevation, c.fov_up, c.fov_down, c.min_range, c.max_range, c.voxel_size
        )
    }

    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let py = slf.py();
        let ctor = py.import("solid._solid")?.getattr("_config_from_dict")?;
        let d = slf.get().to_dict(py)?;
        if let Some(p) = slf.get().base_preset {
            d.set_item("base_preset", p)?;
        }
        Ok((ctor, (d,)))
    }
}

#[pyfunction]
fn _config_from_dict(d: &Bound<'_, PyDict>) -> PyResult<PyConfig> {
    let base = Config::with_defaults(1.0, 0.0, 1);
    for need in ["fov_up", "fov_down", "n_elevation"] {
        if !d.contains(need)? {
            return Err(ConfigError::new_err(format!("config is missing {need}")));
        }
    }
    let d = d.copy()?;
    let preset = match d.get_item("base_preset")? {
        Some(v) => {
            d.del_item("base_preset")?;
            let name: String = v.extract()?;
            PRESETS.iter().find(|p| p.name == name).map(|p| p.name)
        }
        None => None,
    };
    Ok(PyConfig {
        inner: apply_overrides(base, Some(&d))?,
        base_preset: preset,
    })
}

/// The loop detector's parameters (the defaults come from the core).
#[pyclass(name = "DetectorConfig", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyDetectorConfig {
    /// The validated core parameters.
    pub inner: DetectorConfig,
}

/// Names of the detector parameters, in order.
const DETECTOR_FIELDS: [&str; 15] = [
    "exclude_frames",
    "exclude_meters",
    "exclude_seconds",
    "threshold",
    "top_k",
    "rerank",
    "verify",
    "verify_candidates",
    "verify_hypotheses",
    "verify_fan_deg",
    "cloud_bits",
    "cache_bytes",
    "verify_threads",
    "registration",
    "gate",
];

/// Applies detector overrides given by name; `None` values are skipped. Validates the result.
pub(crate) fn detector_overrides(
    mut c: DetectorConfig,
    kw: Option<&Bound<'_, PyDict>>,
) -> PyResult<DetectorConfig> {
    if let Some(kw) = kw {
        for (k, v) in kw.iter() {
            if v.is_none() {
                continue;
            }
            let key: String = k.extract()?;
            let float = || args::float_param(&v, &key);
            let int = || args::int_arg(&v, &key, 0, usize::MAX as i128);
            match key.as_str() {
                "exclude_frames" | "exclude_recent" => c.exclude_frames = int()?,
                "exclude_meters" => c.exclude_meters = float()?,
                "exclude_seconds" => c.exclude_seconds = float()?,
                "threshold" => c.threshold = float()?,
                "top_k" => c.top_k = int()?,
                "rerank" | "verify" => {
                    let b = v
                        .cast::<pyo3::types::PyBool>()
                        .map_err(|_| PyTypeError::new_err(format!("{key} must be a bool")))?
                        .is_true();
                    if key == "rerank" {
                        c.rerank = b;
                    } else {
                        c.verify.enabled = b;
                    }
                }
                "verify_candidates" => c.verify.candidates = int()?,
                "verify_hypotheses" => c.verify.hypotheses = int()?,
                "verify_fan_deg" => c.verify.fan_deg = float()?,
                "cloud_bits" => {
                    c.verify.cloud_bits = u8::try_from(int()?).map_err(|_| {
                        crate::ConfigError::new_err(
                            "invalid cloud_bits: expected an integer in 1..=16",
                        )
                    })?
                }
                "cache_bytes" => c.verify.cache_bytes = int()?,
                "verify_threads" => c.verify.threads = int()?,
                "registration" => {
                    c.verify.registration = reg_config_from(&v, c.verify.registration)?
                }
                "gate" => c.verify.gate = gate_from(&v)?,
                other => {
                    return Err(PyTypeError::new_err(format!(
                        "unknown DetectorConfig parameter {other:?}; valid: {}",
                        DETECTOR_FIELDS.join(", ")
                    )))
                }
            }
        }
    }
    c.validate().map_err(crate::core_err)?;
    Ok(c)
}

#[pymethods]
impl PyDetectorConfig {
    /// Parameters by keyword; those not given take the core's defaults (the threshold: the
    /// largest preset threshold; prefer `DetectorConfig.preset(name)`).
    #[new]
    #[pyo3(signature = (**params))]
    fn new(params: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyDetectorConfig {
            inner: detector_overrides(DetectorConfig::default(), params)?,
        })
    }

    /// The defaults for a sensor preset (its measured loop threshold), with overrides.
    #[staticmethod]
    #[pyo3(signature = (name, **params))]
    fn preset(name: &str, params: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let base = DetectorConfig::for_preset(name).map_err(|_| {
            crate::ConfigError::new_err(format!(
                "unknown preset {name:?}; available: {}",
                solid_lidar::PRESETS
                    .iter()
                    .map(|p| p.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })?;
        Ok(PyDetectorConfig {
            inner: detector_overrides(base, params)?,
        })
    }

    /// A copy with some parameters changed.
    #[pyo3(signature = (**params))]
    fn replace(&self, params: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyDetectorConfig {
            inner: detector_overrides(self.inner, params)?,
        })
    }

    /// The parameters as a dict (what `DetectorConfig(**d)` takes back).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = &self.inner;
        let d = PyDict::new(py);
        d.set_item("exclude_frames", c.exclude_frames)?;
        d.set_item("exclude_meters", c.exclude_meters + 0.0)?;
        d.set_item("exclude_seconds", c.exclude_seconds + 0.0)?;
        d.set_item("threshold", c.threshold + 0.0)?;
        d.set_item("top_k", c.top_k)?;
        d.set_item("rerank", c.rerank)?;
        let v = &c.verify;
        d.set_item("verify", v.enabled)?;
        d.set_item("verify_candidates", v.candidates)?;
        d.set_item("verify_hypotheses", v.hypotheses)?;
        d.set_item("verify_fan_deg", v.fan_deg + 0.0)?;
        d.set_item("cloud_bits", v.cloud_bits)?;
        d.set_item("cache_bytes", v.cache_bytes)?;
        d.set_item("verify_threads", v.threads)?;
        d.set_item("registration", reg_config_dict(py, &v.registration)?)?;
        d.set_item("gate", gate_dict(py, &v.gate)?)?;
        Ok(d)
    }

    /// Whether the best candidates are verified by registration.
    #[getter]
    fn verify(&self) -> bool {
        self.inner.verify.enabled
    }
    /// Candidates registered per step.
    #[getter]
    fn verify_candidates(&self) -> usize {
        self.inner.verify.candidates
    }
    /// Initial yaws per registration, at most.
    #[getter]
    fn verify_hypotheses(&self) -> usize {
        self.inner.verify.hypotheses
    }
    /// The fixed ± yaw fan added to the hypotheses, degrees.
    #[getter]
    fn verify_fan_deg(&self) -> f64 {
        self.inner.verify.fan_deg
    }
    /// Bits per axis of the stored clouds.
    #[getter]
    fn cloud_bits(&self) -> u8 {
        self.inner.verify.cloud_bits
    }
    /// Memory for prepared clouds kept between steps, bytes.
    #[getter]
    fn cache_bytes(&self) -> usize {
        self.inner.verify.cache_bytes
    }
    /// Threads registering a step's candidates (0: one per core).
    #[getter]
    fn verify_threads(&self) -> usize {
        self.inner.verify.threads
    }
    /// The registration parameters.
    #[getter]
    fn registration(&self) -> PyRegConfig {
        PyRegConfig {
            inner: self.inner.verify.registration,
        }
    }
    /// The acceptance gate (its max_translation is the largest loop, metres).
    #[getter]
    fn gate(&self) -> PyGate {
        PyGate {
            inner: self.inner.verify.gate,
        }
    }

    /// Frames of the own session excluded (docs/spec.md §5 `exclude`).
    #[getter]
    fn exclude_frames(&self) -> usize {
        self.inner.exclude_frames
    }
    /// Metres of the own path excluded (0: off).
    #[getter]
    fn exclude_meters(&self) -> f64 {
        self.inner.exclude_meters
    }
    /// Seconds of the own session excluded (0: off).
    #[getter]
    fn exclude_seconds(&self) -> f64 {
        self.inner.exclude_seconds
    }
    /// Largest accepted score (cosine distance).
    #[getter]
    fn threshold(&self) -> f64 {
        self.inner.threshold
    }
    /// Candidates per step.
    #[getter]
    fn top_k(&self) -> usize {
        self.inner.top_k
    }
    /// Whether candidates are re-ranked by A-SOLiD alignment.
    #[getter]
    fn rerank(&self) -> bool {
        self.inner.rerank
    }

    fn __repr__(&self) -> String {
        let c = &self.inner;
        let b = |x: bool| if x { "True" } else { "False" };
        format!(
            "DetectorConfig(exclude_frames={}, exclude_meters={:?}, exclude_seconds={:?}, threshold={:?}, top_k={}, rerank={}, verify={}, verify_candidates={})",
            c.exclude_frames, c.exclude_meters, c.exclude_seconds, c.threshold, c.top_k,
            b(c.rerank), b(c.verify.enabled), c.verify.candidates
        )
    }

    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let py = slf.py();
        let ctor = py
            .import("solid._solid")?
            .getattr("_detector_config_from_dict")?;
        Ok((ctor, (slf.get().to_dict(py)?,)))
    }
}

#[pyfunction]
fn _detector_config_from_dict(params: &Bound<'_, PyDict>) -> PyResult<PyDetectorConfig> {
    PyDetectorConfig::new(Some(params))
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

/// Adds the parameter classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyConfig>()?;
    m.add_class::<PyDetectorConfig>()?;
    m.add_class::<PyRegConfig>()?;
    m.add_class::<PyGate>()?;
    m.add_function(wrap_pyfunction!(_config_from_dict, m)?)?;
    m.add_function(wrap_pyfunction!(_detector_config_from_dict, m)?)?;
    Ok(())
}
