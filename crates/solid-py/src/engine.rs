//! Bindings of the place-recognition engine: `Database`, `Match`, `LoopDetector`, `Loop` and the
//! wire form of one place. Argument checks, GIL release and error mapping only; the algorithms
//! live in `solid_lidar::db` and `solid_lidar::search`.

use std::path::PathBuf;
use std::sync::{PoisonError, RwLock, RwLockReadGuard, RwLockWriteGuard};

use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::PyTypeError;
use pyo3::exceptions::{
    PyFileNotFoundError, PyIsADirectoryError, PyOSError, PyPermissionError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBytes, PyDict, PyType};
use solid_lidar::db::{
    self, Database, DbError, DetectorConfig, LoopDetector, Method, SearchOptions,
};
use solid_lidar::{Config, Descriptor, Stats};

use crate::{PyConfig, PyDescriptor};

/// `solid.DatabaseError`: created at registration as a subclass of `solid.SolidError` when the
/// module already defines it, else of `ValueError`.
static DATABASE_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

fn database_error(py: Python<'_>, msg: String) -> PyErr {
    match DATABASE_ERROR.get(py) {
        Some(t) => PyErr::from_type(t.bind(py).clone(), msg),
        None => PyValueError::new_err(msg),
    }
}

/// Maps a database error to a Python exception: I/O errors to the matching `OSError` subclass
/// (with `filename` set), everything else to `solid.DatabaseError` (a `ValueError`).
fn db_err(py: Python<'_>, e: DbError) -> PyErr {
    match e {
        DbError::Core(c) => crate::core_err(c),
        DbError::Io { file, source } => {
            let args = (source.raw_os_error().unwrap_or(0), source.to_string(), file);
            match source.kind() {
                std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(args),
                std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(args),
                std::io::ErrorKind::IsADirectory => PyIsADirectoryError::new_err(args),
                _ => PyOSError::new_err(args),
            }
        }
        DbError::OutOfMemory => pyo3::exceptions::PyMemoryError::new_err(
            "out of memory: the database operation could not allocate (nothing was changed)",
        ),
        other => database_error(py, other.to_string()),
    }
}

fn parse_method(method: &str) -> PyResult<Method> {
    Method::parse(method).map_err(|_| {
        PyValueError::new_err(format!(
            "method must be \"brute\", \"kdtree\", \"sketch\" or \"auto\", got {method:?}"
        ))
    })
}

/// The search options of the Python keyword arguments.
fn search_options(
    k: usize,
    exclude_recent: usize,
    method: &str,
    not_newer_than: Option<f64>,
    max_distance: Option<f64>,
) -> PyResult<SearchOptions> {
    let max_distance = match max_distance {
        Some(d) if d.is_nan() => {
            return Err(PyValueError::new_err(
                "max_distance must be a distance (or None for no bound), got nan",
            ))
        }
        Some(d) => d as f32,
        None => f32::INFINITY,
    };
    Ok(SearchOptions {
        k,
        exclude_recent,
        not_newer_than,
        max_distance,
        method: parse_method(method)?,
    })
}

/// Per-entry poses of a batch: `None`, or a float64 array of shape (N, 3, 4), (N, 4, 4) (last
/// row 0, 0, 0, 1) or (N, 12), row-major `[R|t]`.
fn parse_poses(poses: Option<&Bound<'_, PyAny>>, n: usize) -> PyResult<Option<Vec<[f64; 12]>>> {
    let Some(p) = poses.filter(|p| !p.is_none()) else {
        return Ok(None);
    };
    let msg = "poses must be None or a float64 array of shape (N, 3, 4), (N, 4, 4) or (N, 12)";
    let arr = p
        .extract::<numpy::PyReadonlyArrayDyn<'_, f64>>()
        .map_err(|_| PyTypeError::new_err(msg))?;
    let view = arr.as_array();
    let shape = view.shape().to_vec();
    let rows_per = match shape[..] {
        [m, 3, 4] | [m, 4, 4] | [m, 12] if m == n => shape[1..].iter().product::<usize>(),
        _ => {
            return Err(PyValueError::new_err(format!(
                "{msg}, with N = {n} rows; got shape {shape:?}"
            )))
        }
    };
    let flat: Vec<f64> = view.iter().copied().collect();
    let mut out = Vec::with_capacity(n);
    for (i, p) in flat.chunks_exact(rows_per).enumerate() {
        if rows_per == 16 && p[12..] != [0.0, 0.0, 0.0, 1.0] {
            return Err(PyValueError::new_err(format!(
                "poses[{i}]: a 4x4 pose must end with the row [0, 0, 0, 1]"
            )));
        }
        let mut pose = [0.0; 12];
        pose.copy_from_slice(&p[..12]);
        out.push(pose);
    }
    Ok(Some(out))
}

/// Query R-SOLiDs of a batch: an (M, n_range) float array, or a sequence of Descriptors made
/// with the database's config.
fn batch_queries(q: &Bound<'_, PyAny>, nr: usize, fingerprint: u64) -> PyResult<Vec<f32>> {
    if q.cast::<numpy::PyUntypedArray>().is_ok() {
        let b = crate::borrow_2d(q, "queries", crate::Columns::Exactly(nr))?;
        return Ok(b.slice().to_f32().into_owned());
    }
    let items = q.try_iter().map_err(|_| {
        PyTypeError::new_err(
            "queries must be an (M, n_range) float array or a sequence of solid.Descriptor",
        )
    })?;
    let mut out = Vec::new();
    for item in items {
        out.extend(query_r(&item?, fingerprint)?);
    }
    Ok(out)
}

/// A descriptor argument, or a 1-D sequence of floats taken as an R-SOLiD.
fn query_r(q: &Bound<'_, PyAny>, fingerprint: u64) -> PyResult<Vec<f32>> {
    if let Ok(d) = q.cast::<PyDescriptor>() {
        let d = d.borrow();
        check_fingerprint(q.py(), d.inner.fingerprint, fingerprint)?;
        return Ok(d.inner.r.clone());
    }
    q.extract::<Vec<f32>>().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "expected a solid.Descriptor or a 1-D sequence of floats (an R-SOLiD)",
        )
    })
}

fn check_fingerprint(py: Python<'_>, got: u64, expected: u64) -> PyResult<()> {
    if got != expected {
        return Err(db_err(py, DbError::ConfigMismatch { expected, got }));
    }
    Ok(())
}

/// A pose argument: `None`, 12 floats, or a 3×4 nested sequence / array (row-major `[R|t]`).
fn parse_pose(pose: Option<&Bound<'_, PyAny>>) -> PyResult<Option<[f64; 12]>> {
    let Some(p) = pose else { return Ok(None) };
    if p.is_none() {
        return Ok(None);
    }
    let msg =
        "pose must be None, 12 floats, or a 3x4 or 4x4 array (row-major [R|t], T_world_sensor)";
    let flat: Vec<f64> = match p.extract::<Vec<Vec<f64>>>() {
        Ok(rows) if rows.len() == 3 && rows.iter().all(|r| r.len() == 4) => {
            rows.into_iter().flatten().collect()
        }
        Ok(rows) if rows.len() == 4 && rows.iter().all(|r| r.len() == 4) => {
            if rows[3] != [0.0, 0.0, 0.0, 1.0] {
                return Err(PyValueError::new_err(format!(
                    "a 4x4 pose must end with the row [0, 0, 0, 1], got {:?}",
                    rows[3]
                )));
            }
            rows.into_iter().take(3).flatten().collect()
        }
        Ok(_) => return Err(PyValueError::new_err(msg)),
        Err(_) => p
            .extract::<Vec<f64>>()
            .map_err(|_| PyValueError::new_err(msg))?,
    };
    let arr: [f64; 12] = flat
        .try_into()
        .map_err(|v: Vec<f64>| PyValueError::new_err(format!("{msg}; got {} values", v.len())))?;
    Ok(Some(arr))
}

fn timestamp(t: Option<f64>) -> f64 {
    t.unwrap_or(f64::NAN)
}

/// One search result.
#[pyclass(name = "Match", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyMatch {
    /// The entry's id.
    #[pyo3(get)]
    pub id: u32,
    /// Cosine distance of the R-SOLiDs, in [0, 1].
    #[pyo3(get)]
    pub distance: f64,
}

#[pymethods]
impl PyMatch {
    fn __repr__(&self) -> String {
        format!("Match(id={}, distance={:.6})", self.id, self.distance)
    }
}

/// A detected loop closure.
#[pyclass(name = "Loop", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyLoop {
    /// Id of the query scan.
    #[pyo3(get)]
    pub query: u32,
    /// Id of the matched database entry.
    #[pyo3(get)]
    pub candidate: u32,
    /// Cosine distance of the R-SOLiDs.
    #[pyo3(get)]
    pub distance: f64,
    /// Heading of the query relative to the candidate, degrees in (-180, 180].
    #[pyo3(get)]
    pub heading: f64,
    /// The score the threshold accepted (today the R-SOLiD distance).
    #[pyo3(get)]
    pub score: f64,
}

#[pymethods]
impl PyLoop {
    fn __repr__(&self) -> String {
        format!(
            "Loop(query={}, candidate={}, distance={:.6}, heading={:.3}, score={:.6})",
            self.query, self.candidate, self.distance, self.heading, self.score
        )
    }
}

impl From<db::Loop> for PyLoop {
    fn from(l: db::Loop) -> Self {
        PyLoop {
            query: l.query,
            candidate: l.candidate,
            distance: l.distance,
            heading: l.heading_deg,
            score: l.score,
        }
    }
}

/// One candidate of a detector step, in the detector's order.
#[pyclass(name = "Candidate", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyCandidate {
    /// Id of the database entry.
    #[pyo3(get)]
    pub id: u32,
    /// Cosine distance of the R-SOLiDs.
    #[pyo3(get)]
    pub distance: f64,
    /// Heading of the query relative to this candidate, degrees in (-180, 180].
    #[pyo3(get)]
    pub heading: f64,
    /// What the threshold is compared with (the value a PR curve sweeps).
    #[pyo3(get)]
    pub score: f64,
}

#[pymethods]
impl PyCandidate {
    fn __repr__(&self) -> String {
        format!(
            "Candidate(id={}, distance={:.6}, heading={:.3}, score={:.6})",
            self.id, self.distance, self.heading, self.score
        )
    }
}

impl From<&db::Candidate> for PyCandidate {
    fn from(c: &db::Candidate) -> Self {
        PyCandidate {
            id: c.id,
            distance: c.distance,
            heading: c.heading_deg,
            score: c.score,
        }
    }
}

/// Everything one detector step decided.
#[pyclass(name = "Detection", module = "solid", frozen)]
pub struct PyDetection {
    /// Id of the query (the entry the step added).
    #[pyo3(get)]
    pub query: u32,
    /// The candidates came from the entries 0..eligible (0: nothing to search yet).
    #[pyo3(get)]
    pub eligible: u32,
    candidates: Vec<PyCandidate>,
    accepted: Option<PyLoop>,
}

#[pymethods]
impl PyDetection {
    /// Up to top_k candidates, best first.
    #[getter]
    fn candidates(&self) -> Vec<PyCandidate> {
        self.candidates.clone()
    }

    /// The loop, when the best candidate's score passes the threshold.
    #[getter]
    fn r#loop(&self) -> Option<PyLoop> {
        self.accepted.clone()
    }

    fn __repr__(&self) -> String {
        format!(
            "Detection(query={}, eligible={}, candidates={}, loop={})",
            self.query,
            self.eligible,
            self.candidates.len(),
            self.accepted
                .as_ref()
                .map_or_else(|| String::from("None"), PyLoop::__repr__)
        )
    }
}

impl From<db::Detection> for PyDetection {
    fn from(d: db::Detection) -> Self {
        PyDetection {
            query: d.query,
            eligible: d.eligible,
            candidates: d.candidates.iter().map(PyCandidate::from).collect(),
            accepted: d.accepted.map(PyLoop::from),
        }
    }
}

/// The loop detector's parameters (the defaults come from the core).
#[pyclass(name = "DetectorConfig", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyDetectorConfig {
    /// The validated core parameters.
    pub inner: DetectorConfig,
}

/// Names of the detector parameters, in order.
const DETECTOR_FIELDS: [&str; 6] = [
    "exclude_frames",
    "exclude_meters",
    "exclude_seconds",
    "threshold",
    "top_k",
    "rerank",
];

fn non_negative(name: &str, v: i64) -> PyResult<usize> {
    usize::try_from(v).map_err(|_| {
        crate::ConfigError::new_err(format!("invalid {name} = {v}: expected an integer >= 0"))
    })
}

/// Applies detector overrides given by name; `None` values are skipped. Validates the result.
fn detector_overrides(
    mut c: DetectorConfig,
    kw: Option<&Bound<'_, PyDict>>,
) -> PyResult<DetectorConfig> {
    if let Some(kw) = kw {
        for (k, v) in kw.iter() {
            if v.is_none() {
                continue;
            }
            let key: String = k.extract()?;
            let float = || -> PyResult<f64> {
                v.extract::<f64>()
                    .map_err(|_| PyTypeError::new_err(format!("{key} must be a number")))
            };
            let int = || -> PyResult<usize> {
                if v.is_instance_of::<pyo3::types::PyBool>() {
                    return Err(PyTypeError::new_err(format!(
                        "{key} must be an integer, not a bool"
                    )));
                }
                let i: i64 = v
                    .extract()
                    .map_err(|_| PyTypeError::new_err(format!("{key} must be an integer")))?;
                non_negative(&key, i)
            };
            match key.as_str() {
                "exclude_frames" | "exclude_recent" => c.exclude_frames = int()?,
                "exclude_meters" => c.exclude_meters = float()?,
                "exclude_seconds" => c.exclude_seconds = float()?,
                "threshold" => c.threshold = float()?,
                "top_k" => c.top_k = int()?,
                "rerank" => {
                    c.rerank = v
                        .extract::<bool>()
                        .map_err(|_| PyTypeError::new_err("rerank must be a bool"))?
                }
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
        Ok(d)
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
        format!(
            "DetectorConfig(exclude_frames={}, exclude_meters={:?}, exclude_seconds={:?}, threshold={:?}, top_k={}, rerank={})",
            c.exclude_frames, c.exclude_meters, c.exclude_seconds, c.threshold, c.top_k,
            if c.rerank { "True" } else { "False" }
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

/// Shared read access (searches run in parallel). Callers take it with the GIL released, so a
/// thread waiting for a writer never blocks Python. No code panics while holding a lock; should
/// one ever be poisoned, the data is still consistent (every update is applied whole or not at
/// all), so the guard is recovered rather than turned into a panic.
fn read<T>(l: &RwLock<T>) -> RwLockReadGuard<'_, T> {
    l.read().unwrap_or_else(PoisonError::into_inner)
}

/// Exclusive access (adds, merges); see [`read`].
fn write<T>(l: &RwLock<T>) -> RwLockWriteGuard<'_, T> {
    l.write().unwrap_or_else(PoisonError::into_inner)
}

/// A database of places: exact search at every size, merge, save and load.
///
/// Safe to share between threads: searches run in parallel, an add or a merge waits for them
/// and runs alone; every wait happens with the GIL released.
#[pyclass(name = "Database", module = "solid", frozen)]
pub struct PyDatabase {
    inner: RwLock<Database>,
}

impl PyDatabase {
    fn wrap(inner: Database) -> Self {
        PyDatabase {
            inner: RwLock::new(inner),
        }
    }

    /// `f` of the database under the read lock, taken with the GIL released.
    fn with<R: Send>(&self, py: Python<'_>, f: impl FnOnce(&Database) -> R + Send) -> R {
        py.detach(|| f(&read(&self.inner)))
    }

    /// A copy of the database (under the read lock, with the GIL released).
    pub(crate) fn snapshot(&self, py: Python<'_>) -> Database {
        self.with(py, Database::clone)
    }

    fn fingerprint(&self, py: Python<'_>) -> u64 {
        self.with(py, |db| db.config().fingerprint())
    }
}

fn to_matches(v: Vec<solid_lidar::search::Neighbor>) -> Vec<PyMatch> {
    v.into_iter()
        .map(|n| PyMatch {
            id: n.id,
            distance: f64::from(n.distance),
        })
        .collect()
}

#[pymethods]
impl PyDatabase {
    #[new]
    fn new(py: Python<'_>, cfg: PyRef<'_, PyConfig>) -> PyResult<Self> {
        let inner = Database::new(cfg.inner).map_err(|e| db_err(py, e))?;
        Ok(PyDatabase::wrap(inner))
    }

    /// Adds a descriptor; returns its id.
    #[pyo3(signature = (descriptor, session=0, timestamp=None, pose=None))]
    fn add(
        &self,
        py: Python<'_>,
        descriptor: PyRef<'_, PyDescriptor>,
        session: u32,
        timestamp: Option<f64>,
        pose: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u32> {
        let pose = parse_pose(pose)?;
        let d = &descriptor.inner;
        py.detach(|| write(&self.inner).add(d, session, self::timestamp(timestamp), pose))
            .map_err(|e| db_err(py, e))
    }

    /// Adds N entries at once: R-SOLiDs `r` (N, n_range) and A-SOLiDs `a` (N, n_azimuth)
    /// (float32 read in place, float64 converted), one session, optional timestamps (N,) and
    /// poses; returns the first id (the others follow). Everything is checked first; with
    /// `index=False` the kd-tree is left for `build_index` (searches stay exact).
    #[pyo3(signature = (r, a, session=0, timestamps=None, poses=None, index=true))]
    #[allow(clippy::too_many_arguments)]
    fn add_batch(
        &self,
        py: Python<'_>,
        r: &Bound<'_, PyAny>,
        a: &Bound<'_, PyAny>,
        session: u32,
        timestamps: Option<numpy::PyReadonlyArray1<'_, f64>>,
        poses: Option<&Bound<'_, PyAny>>,
        index: bool,
    ) -> PyResult<u32> {
        let cfg = self.with(py, |db| *db.config());
        let r = crate::borrow_2d(r, "r", crate::Columns::Exactly(cfg.n_range))?;
        let a = crate::borrow_2d(a, "a", crate::Columns::Exactly(cfg.n_azimuth))?;
        let n = r.rows();
        let poses = parse_poses(poses, n)?;
        let times = match &timestamps {
            Some(t) => Some(t.as_slice().map_err(|_| {
                PyValueError::new_err("timestamps must be a contiguous float64 array of shape (N,)")
            })?),
            None => None,
        };
        let (r, a) = (r.slice(), a.slice());
        py.detach(|| {
            let (r, a) = (r.to_f32(), a.to_f32());
            write(&self.inner).add_batch(&r, &a, session, times, poses.as_deref(), index)
        })
        .map_err(|e| db_err(py, e))
    }

    /// Extends the kd-tree over every entry (after `add_batch(..., index=False)`).
    fn build_index(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| write(&self.inner).build_index())
            .map_err(|e| db_err(py, e))
    }

    /// Bytes of memory the database holds.
    fn memory_bytes(&self, py: Python<'_>) -> usize {
        self.with(py, Database::memory_bytes)
    }

    /// The `k` nearest entries, nearest first (ties by lower id).
    #[pyo3(signature = (descriptor, k=1, exclude_recent=0, method="auto", not_newer_than=None, max_distance=None))]
    #[allow(clippy::too_many_arguments)]
    fn search(
        &self,
        py: Python<'_>,
        descriptor: &Bound<'_, PyAny>,
        k: usize,
        exclude_recent: usize,
        method: &str,
        not_newer_than: Option<f64>,
        max_distance: Option<f64>,
    ) -> PyResult<Vec<PyMatch>> {
        let opts = search_options(k, exclude_recent, method, not_newer_than, max_distance)?;
        let r = query_r(descriptor, self.fingerprint(py))?;
        let found = py
            .detach(|| read(&self.inner).search_with(&r, &opts))
            .map_err(|e| db_err(py, e))?;
        Ok(to_matches(found))
    }

    /// The `k` nearest entries to each query (an (M, n_range) array of R-SOLiDs or a sequence
    /// of Descriptors), in one call with the GIL released once and every core searching: ids
    /// (M, k) int64 (-1 in empty slots) and distances (M, k) float32 (inf in empty slots),
    /// nearest first; row i is `search(queries[i], ...)`.
    #[pyo3(signature = (queries, k=1, exclude_recent=0, method="auto", not_newer_than=None, max_distance=None))]
    #[allow(clippy::too_many_arguments)]
    #[allow(clippy::type_complexity)]
    fn search_batch<'py>(
        &self,
        py: Python<'py>,
        queries: &Bound<'_, PyAny>,
        k: usize,
        exclude_recent: usize,
        method: &str,
        not_newer_than: Option<f64>,
        max_distance: Option<f64>,
    ) -> PyResult<(Bound<'py, PyArray2<i64>>, Bound<'py, PyArray2<f32>>)> {
        let opts = search_options(k, exclude_recent, method, not_newer_than, max_distance)?;
        let (nr, fingerprint) =
            self.with(py, |db| (db.config().n_range, db.config().fingerprint()));
        let q = batch_queries(queries, nr, fingerprint)?;
        let m = q.len() / nr;
        let found = py
            .detach(|| read(&self.inner).search_batch(&q, &opts))
            .map_err(|e| db_err(py, e))?;
        let ids: Vec<i64> = found
            .ids
            .iter()
            .map(|&id| {
                if id == db::BatchResults::NONE {
                    -1
                } else {
                    i64::from(id)
                }
            })
            .collect();
        let shape = (m, found.k);
        let ids =
            Array2::from_shape_vec(shape, ids).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let dists = Array2::from_shape_vec(shape, found.distances)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok((ids.into_pyarray(py), dists.into_pyarray(py)))
    }

    /// The cosine distance from the query (a Descriptor or an R-SOLiD) to every entry, in id
    /// order, float32 (for plots and analysis; `search` finds the nearest).
    fn distances<'py>(
        &self,
        py: Python<'py>,
        descriptor: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let r = query_r(descriptor, self.fingerprint(py))?;
        let d = self
            .with(py, |db| db.distances(&r))
            .map_err(|e| db_err(py, e))?;
        Ok(d.into_pyarray(py))
    }

    /// Appends every entry of `other` (same config required). With `new_sessions`, the sessions
    /// of `other` are renumbered to follow this database's (maps of separate runs stay apart).
    #[pyo3(signature = (other, new_sessions=false))]
    fn merge(&self, py: Python<'_>, other: &PyDatabase, new_sessions: bool) -> PyResult<()> {
        let apply = |dst: &mut Database, src: &Database| {
            if new_sessions {
                dst.merge_as_new_sessions(src).map(|_| ())
            } else {
                dst.merge(src)
            }
        };
        if std::ptr::eq(self, other) {
            let copy = self.snapshot(py);
            return py
                .detach(|| apply(&mut write(&self.inner), &copy))
                .map_err(|e| db_err(py, e));
        }
        // Both locks in one global order (by address), so that a.merge(b) and b.merge(a) running
        // at the same time cannot deadlock.
        py.detach(|| {
            if (self as *const Self) < (other as *const Self) {
                let mut dst = write(&self.inner);
                let src = read(&other.inner);
                apply(&mut dst, &src)
            } else {
                let src = read(&other.inner);
                let mut dst = write(&self.inner);
                apply(&mut dst, &src)
            }
        })
        .map_err(|e| db_err(py, e))
    }

    /// Saves atomically (temporary file in the same directory, then rename).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| read(&self.inner).save(&path))
            .map_err(|e| db_err(py, e))
    }

    /// Loads a database saved by `save`.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py
            .detach(|| Database::load(&path))
            .map_err(|e| db_err(py, e))?;
        Ok(PyDatabase::wrap(inner))
    }

    /// The database in the file format, as bytes.
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let b = py.detach(|| read(&self.inner).to_bytes());
        PyBytes::new(py, &b)
    }

    /// A database from bytes made by `to_bytes`.
    #[staticmethod]
    fn from_bytes(py: Python<'_>, data: &[u8]) -> PyResult<Self> {
        let inner = py
            .detach(|| Database::from_bytes(data))
            .map_err(|e| db_err(py, e))?;
        Ok(PyDatabase::wrap(inner))
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.with(py, Database::len)
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let (n, cfg) = self.with(py, |db| (db.len(), *db.config()));
        format!(
            "Database(len={n}, n_range={}, n_azimuth={})",
            cfg.n_range, cfg.n_azimuth
        )
    }

    /// The configuration.
    #[getter]
    fn config(&self, py: Python<'_>) -> PyConfig {
        PyConfig::new_unchecked(self.with(py, |db| *db.config()))
    }

    /// All R-SOLiDs, shape (N, n_range), float32 (a copy).
    #[getter]
    fn r<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let (shape, v) = self.with(py, |db| {
            ((db.len(), db.config().n_range), db.r_all().to_vec())
        });
        let a =
            Array2::from_shape_vec(shape, v).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(a.into_pyarray(py))
    }

    /// All A-SOLiDs as stored, shape (N, n_azimuth), float32 (a copy): 8 bits per value with
    /// one step per entry, within half a step (0.2 % of the entry's largest value) of the
    /// values added.
    #[getter]
    fn a<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let (shape, v) = self.with(py, |db| ((db.len(), db.config().n_azimuth), db.a_all()));
        let a =
            Array2::from_shape_vec(shape, v).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(a.into_pyarray(py))
    }

    /// Entry ids, 0..N, int64.
    #[getter]
    fn ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        Array1::from_iter(0..self.with(py, Database::len) as i64).into_pyarray(py)
    }

    /// Sessions, uint32.
    #[getter]
    fn sessions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        self.with(py, |db| db.sessions().to_vec()).into_pyarray(py)
    }

    /// Timestamps, float64 (NaN where none was given).
    #[getter]
    fn timestamps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.with(py, |db| db.timestamps().to_vec())
            .into_pyarray(py)
    }

    /// Poses, shape (N, 3, 4), float64 (all NaN where none was given).
    #[getter]
    fn poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let (n, flat) = self.with(py, |db| {
            let flat: Vec<f64> = db
                .poses()
                .iter()
                .flat_map(|p| p.unwrap_or([f64::NAN; 12]))
                .collect();
            (db.len(), flat)
        });
        let a = Array3::from_shape_vec((n, 3, 4), flat)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(a.into_pyarray(py))
    }
}

/// An online loop-closure detector.
///
/// Safe to share between threads: `add` (search then insert) runs alone, as one step, so no scan
/// is lost or searched against a half-added entry; `query` and the getters run in parallel.
#[pyclass(name = "LoopDetector", module = "solid", frozen)]
pub struct PyLoopDetector {
    /// The descriptor configuration (fixed for the detector's life).
    cfg: Config,
    inner: RwLock<LoopDetector>,
}

impl PyLoopDetector {
    fn wrap(inner: LoopDetector) -> Self {
        PyLoopDetector {
            cfg: *inner.database().config(),
            inner: RwLock::new(inner),
        }
    }

    /// `f` of the detector under the read lock, taken with the GIL released.
    fn with<R: Send>(&self, py: Python<'_>, f: impl FnOnce(&LoopDetector) -> R + Send) -> R {
        py.detach(|| f(&read(&self.inner)))
    }

    fn descriptor(&self, py: Python<'_>, x: &Bound<'_, PyAny>) -> PyResult<Descriptor> {
        if let Ok(d) = x.cast::<PyDescriptor>() {
            let d = d.borrow();
            check_fingerprint(py, d.inner.fingerprint, self.cfg.fingerprint())?;
            return Ok(d.inner.clone());
        }
        crate::describe_points(py, x, &self.cfg)
    }
}

/// The detector parameters from a base (a DetectorConfig, else the config's preset defaults)
/// and keyword overrides.
fn detector_config(
    cfg: &PyConfig,
    detector: Option<&PyDetectorConfig>,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<DetectorConfig> {
    let base = detector.map_or_else(|| cfg.detector_defaults(), |d| d.inner);
    detector_overrides(base, overrides)
}

/// Descriptors and per-scan timestamps/poses of a batch, checked.
type Batch = (Vec<Descriptor>, Vec<f64>, Vec<Option<[f64; 12]>>);

#[pymethods]
impl PyLoopDetector {
    #[new]
    #[pyo3(signature = (cfg, exclude_recent=None, threshold=None, top_k=None, rerank=None, *, exclude_meters=None, exclude_seconds=None, detector=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        cfg: PyRef<'_, PyConfig>,
        exclude_recent: Option<&Bound<'_, PyAny>>,
        threshold: Option<&Bound<'_, PyAny>>,
        top_k: Option<&Bound<'_, PyAny>>,
        rerank: Option<&Bound<'_, PyAny>>,
        exclude_meters: Option<&Bound<'_, PyAny>>,
        exclude_seconds: Option<&Bound<'_, PyAny>>,
        detector: Option<PyRef<'_, PyDetectorConfig>>,
    ) -> PyResult<Self> {
        let kw = overrides_dict(
            py,
            exclude_recent,
            threshold,
            top_k,
            rerank,
            exclude_meters,
            exclude_seconds,
        )?;
        let dc = detector_config(&cfg, detector.as_deref(), Some(&kw))?;
        let inner = LoopDetector::new(cfg.inner, dc).map_err(|e| db_err(py, e))?;
        Ok(PyLoopDetector::wrap(inner))
    }

    /// A detector over a copy of an existing database (a prior map): its places are candidates
    /// from the first scan on and are never excluded as recent.
    #[staticmethod]
    #[pyo3(signature = (database, exclude_recent=None, threshold=None, top_k=None, rerank=None, *, exclude_meters=None, exclude_seconds=None, detector=None))]
    #[allow(clippy::too_many_arguments)]
    fn from_database(
        py: Python<'_>,
        database: &PyDatabase,
        exclude_recent: Option<&Bound<'_, PyAny>>,
        threshold: Option<&Bound<'_, PyAny>>,
        top_k: Option<&Bound<'_, PyAny>>,
        rerank: Option<&Bound<'_, PyAny>>,
        exclude_meters: Option<&Bound<'_, PyAny>>,
        exclude_seconds: Option<&Bound<'_, PyAny>>,
        detector: Option<PyRef<'_, PyDetectorConfig>>,
    ) -> PyResult<Self> {
        let kw = overrides_dict(
            py,
            exclude_recent,
            threshold,
            top_k,
            rerank,
            exclude_meters,
            exclude_seconds,
        )?;
        let db = database.snapshot(py);
        let cfg = PyConfig::new_unchecked(*db.config());
        let dc = detector_config(&cfg, detector.as_deref(), Some(&kw))?;
        let inner = LoopDetector::with_database(db, dc).map_err(|e| db_err(py, e))?;
        Ok(PyLoopDetector::wrap(inner))
    }

    /// Searches the scan (points or a Descriptor) against the eligible places, adds it, and
    /// returns the loop if its best candidate passes the threshold.
    #[pyo3(signature = (points_or_descriptor, timestamp=None, pose=None))]
    fn add(
        &self,
        py: Python<'_>,
        points_or_descriptor: &Bound<'_, PyAny>,
        timestamp: Option<f64>,
        pose: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Option<PyLoop>> {
        Ok(self
            .detect(py, points_or_descriptor, timestamp, pose)?
            .accepted)
    }

    /// As `add`, returning everything the step decided (a `Detection`).
    #[pyo3(signature = (points_or_descriptor, timestamp=None, pose=None))]
    fn detect(
        &self,
        py: Python<'_>,
        points_or_descriptor: &Bound<'_, PyAny>,
        timestamp: Option<f64>,
        pose: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyDetection> {
        let d = self.descriptor(py, points_or_descriptor)?;
        let pose = parse_pose(pose)?;
        let found = py
            .detach(|| write(&self.inner).detect(&d, self::timestamp(timestamp), pose))
            .map_err(|e| db_err(py, e))?;
        Ok(PyDetection::from(found))
    }

    /// `detect` for many descriptors in order, in one call (the GIL is released once). Every
    /// input is checked before the first is added: on error nothing is added.
    #[pyo3(signature = (descriptors, timestamps=None, poses=None))]
    fn detect_many(
        &self,
        py: Python<'_>,
        descriptors: &Bound<'_, PyAny>,
        timestamps: Option<&Bound<'_, PyAny>>,
        poses: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Vec<PyDetection>> {
        let (ds, ts, ps): Batch = self.batch(py, descriptors, timestamps, poses)?;
        let found = py
            .detach(|| write(&self.inner).detect_many(&ds, &ts, &ps))
            .map_err(|e| db_err(py, e))?;
        Ok(found.into_iter().map(PyDetection::from).collect())
    }

    /// The candidates the scan would get if it were added now, without adding it.
    #[pyo3(signature = (points_or_descriptor, k=None, timestamp=None, pose=None))]
    fn candidates(
        &self,
        py: Python<'_>,
        points_or_descriptor: &Bound<'_, PyAny>,
        k: Option<i64>,
        timestamp: Option<f64>,
        pose: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Vec<PyCandidate>> {
        let d = self.descriptor(py, points_or_descriptor)?;
        let pose = parse_pose(pose)?;
        let k = match k {
            Some(k) => non_negative("k", k)?,
            None => self.with(py, |det| det.config().top_k),
        };
        let found = self
            .with(py, |det| {
                det.candidates(&d, k, self::timestamp(timestamp), pose)
            })
            .map_err(|e| db_err(py, e))?;
        Ok(found.iter().map(PyCandidate::from).collect())
    }

    /// Searches the scan against every place without adding it (localisation in a prior map).
    fn query(
        &self,
        py: Python<'_>,
        points_or_descriptor: &Bound<'_, PyAny>,
    ) -> PyResult<Option<PyLoop>> {
        let d = self.descriptor(py, points_or_descriptor)?;
        let found = self
            .with(py, |det| det.query(&d))
            .map_err(|e| db_err(py, e))?;
        Ok(found.map(PyLoop::from))
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.with(py, |det| det.database().len())
    }

    /// A copy of the detector's database.
    #[getter]
    fn database(&self, py: Python<'_>) -> PyDatabase {
        PyDatabase::wrap(self.with(py, |det| det.database().clone()))
    }

    /// The parameters.
    #[getter]
    fn config(&self, py: Python<'_>) -> PyDetectorConfig {
        PyDetectorConfig {
            inner: self.with(py, |det| *det.config()),
        }
    }

    /// The session of the scans this detector adds.
    #[getter]
    fn session(&self, py: Python<'_>) -> u32 {
        self.with(py, LoopDetector::session)
    }

    /// Id of the first scan of the own session (the number of prior-map places).
    #[getter]
    fn session_start(&self, py: Python<'_>) -> usize {
        self.with(py, LoopDetector::session_start)
    }

    /// Frames of the own session excluded as too recent.
    #[getter]
    fn exclude_recent(&self, py: Python<'_>) -> usize {
        self.with(py, |det| det.config().exclude_frames)
    }

    /// Largest accepted score.
    #[getter]
    fn threshold(&self, py: Python<'_>) -> f64 {
        self.with(py, |det| det.config().threshold)
    }

    /// Candidates per step.
    #[getter]
    fn top_k(&self, py: Python<'_>) -> usize {
        self.with(py, |det| det.config().top_k)
    }

    /// Whether re-ranking is on.
    #[getter]
    fn rerank(&self, py: Python<'_>) -> bool {
        self.with(py, |det| det.config().rerank)
    }
}

impl PyLoopDetector {
    fn batch(
        &self,
        py: Python<'_>,
        descriptors: &Bound<'_, PyAny>,
        timestamps: Option<&Bound<'_, PyAny>>,
        poses: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Batch> {
        let mut ds = Vec::new();
        for item in descriptors.try_iter()? {
            let item = item?;
            let d = item.cast::<PyDescriptor>().map_err(|_| {
                pyo3::exceptions::PyTypeError::new_err(
                    "detect_many takes a sequence of solid.Descriptor (describe_batch makes them)",
                )
            })?;
            let d = d.borrow();
            check_fingerprint(py, d.inner.fingerprint, self.cfg.fingerprint())?;
            ds.push(d.inner.clone());
        }
        let ts: Vec<f64> = match timestamps {
            Some(t) if !t.is_none() => t
                .extract::<Vec<Option<f64>>>()
                .map_err(|_| {
                    PyTypeError::new_err("timestamps must be a sequence of floats (or None)")
                })?
                .into_iter()
                .map(self::timestamp)
                .collect(),
            _ => Vec::new(),
        };
        let ps: Vec<Option<[f64; 12]>> = match poses {
            Some(p) if !p.is_none() => {
                let mut out = Vec::new();
                for item in p.try_iter()? {
                    out.push(parse_pose(Some(&item?))?);
                }
                out
            }
            _ => Vec::new(),
        };
        Ok((ds, ts, ps))
    }
}

/// The positional/keyword detector arguments as a dict of overrides (None: not given).
fn overrides_dict<'py>(
    py: Python<'py>,
    exclude_recent: Option<&Bound<'py, PyAny>>,
    threshold: Option<&Bound<'py, PyAny>>,
    top_k: Option<&Bound<'py, PyAny>>,
    rerank: Option<&Bound<'py, PyAny>>,
    exclude_meters: Option<&Bound<'py, PyAny>>,
    exclude_seconds: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let kw = PyDict::new(py);
    for (k, v) in [
        ("exclude_frames", exclude_recent),
        ("threshold", threshold),
        ("top_k", top_k),
        ("rerank", rerank),
        ("exclude_meters", exclude_meters),
        ("exclude_seconds", exclude_seconds),
    ] {
        if let Some(v) = v {
            kw.set_item(k, v)?;
        }
    }
    Ok(kw)
}

/// Encodes one place for exchange between robots: float32 (416 + 4 B for the defaults) or
/// quantised (128 B for the defaults).
#[pyfunction]
#[pyo3(signature = (descriptor, quantized=false))]
fn encode_place<'py>(
    py: Python<'py>,
    descriptor: PyRef<'_, PyDescriptor>,
    quantized: bool,
) -> PyResult<Bound<'py, PyBytes>> {
    let d = &descriptor.inner;
    let bytes = db::encode_place(&d.r, &d.a, d.fingerprint, quantized).map_err(crate::core_err)?;
    Ok(PyBytes::new(py, &bytes))
}

/// Decodes a place made with `cfg` (checked by fingerprint: a place from another config is an
/// error, since its vectors cannot be compared). Point counts are not transmitted (they read 0).
#[pyfunction]
fn decode_place(py: Python<'_>, data: &[u8], cfg: PyRef<'_, PyConfig>) -> PyResult<PyDescriptor> {
    let p = db::decode_place(data).map_err(|e| db_err(py, e))?;
    check_fingerprint(py, p.fingerprint, cfg.inner.fingerprint())?;
    if p.r.len() != cfg.inner.n_range || p.a.len() != cfg.inner.n_azimuth {
        return Err(database_error(
            py,
            String::from("place vector lengths do not match the config"),
        ));
    }
    Ok(PyDescriptor::new(
        Descriptor {
            r: p.r,
            a: p.a,
            stats: Stats::default(),
            fingerprint: p.fingerprint,
        },
        cfg.inner,
    ))
}

/// Registers the engine's classes, functions and `DatabaseError` on the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let base = match m.getattr("SolidError") {
        Ok(b) => b.cast_into::<PyType>()?,
        Err(_) => py.get_type::<PyValueError>(),
    };
    let ty = DATABASE_ERROR.get_or_try_init(py, || {
        PyErr::new_type(
            py,
            c"solid.DatabaseError",
            Some(c"A database, place or loop-detector error: config mismatch, corrupt or foreign file."),
            Some(&base),
            None,
        )
    })?;
    m.add("DatabaseError", ty.bind(py))?;
    m.add_class::<PyDatabase>()?;
    m.add_class::<PyMatch>()?;
    m.add_class::<PyLoopDetector>()?;
    m.add_class::<PyLoop>()?;
    m.add_class::<PyCandidate>()?;
    m.add_class::<PyDetection>()?;
    m.add_class::<PyDetectorConfig>()?;
    m.add_function(wrap_pyfunction!(_detector_config_from_dict, m)?)?;
    m.add_function(wrap_pyfunction!(encode_place, m)?)?;
    m.add_function(wrap_pyfunction!(decode_place, m)?)?;
    Ok(())
}
