//! Bindings of the place-recognition engine: `Database`, `Match`, `LoopDetector`, `Loop` and the
//! wire form of one place. Argument checks, GIL release and error mapping only; the algorithms
//! live in `solid_lidar::db` and `solid_lidar::search`.

use std::path::PathBuf;
use std::sync::{PoisonError, RwLock, RwLockReadGuard, RwLockWriteGuard};

use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::{
    PyFileNotFoundError, PyIsADirectoryError, PyOSError, PyPermissionError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBytes, PyType};
use solid_lidar::db::{self, Database, DbError, LoopDetector, Method, SearchOptions};
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
        other => database_error(py, other.to_string()),
    }
}

fn parse_method(method: &str) -> PyResult<Method> {
    Method::parse(method).map_err(|_| {
        PyValueError::new_err(format!(
            "method must be \"brute\", \"kdtree\" or \"auto\", got {method:?}"
        ))
    })
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
    let flat: Vec<f64> = match p.extract::<Vec<Vec<f64>>>() {
        Ok(rows) if rows.len() == 3 && rows.iter().all(|r| r.len() == 4) => {
            rows.into_iter().flatten().collect()
        }
        _ => p.extract::<Vec<f64>>().map_err(|_| {
            PyValueError::new_err("pose must be None, 12 floats or a 3x4 array (row-major [R|t])")
        })?,
    };
    let arr: [f64; 12] = flat.try_into().map_err(|v: Vec<f64>| {
        PyValueError::new_err(format!(
            "pose must have 12 values (a 3x4 [R|t]), got {}",
            v.len()
        ))
    })?;
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
}

#[pymethods]
impl PyLoop {
    fn __repr__(&self) -> String {
        format!(
            "Loop(query={}, candidate={}, distance={:.6}, heading={:.3})",
            self.query, self.candidate, self.distance, self.heading
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
        }
    }
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

    /// The `k` nearest entries, nearest first (ties by lower id).
    #[pyo3(signature = (descriptor, k=1, exclude_recent=0, method="auto", not_newer_than=None))]
    fn search(
        &self,
        py: Python<'_>,
        descriptor: &Bound<'_, PyAny>,
        k: usize,
        exclude_recent: usize,
        method: &str,
        not_newer_than: Option<f64>,
    ) -> PyResult<Vec<PyMatch>> {
        let method = parse_method(method)?;
        let r = query_r(descriptor, self.fingerprint(py))?;
        let opts = SearchOptions {
            k,
            exclude_recent,
            not_newer_than,
            method,
        };
        let found = py
            .detach(|| read(&self.inner).search_with(&r, &opts))
            .map_err(|e| db_err(py, e))?;
        Ok(to_matches(found))
    }

    /// Appends every entry of `other` (same config required).
    fn merge(&self, py: Python<'_>, other: &PyDatabase) -> PyResult<()> {
        if std::ptr::eq(self, other) {
            let copy = self.snapshot(py);
            return py
                .detach(|| write(&self.inner).merge(&copy))
                .map_err(|e| db_err(py, e));
        }
        // Both locks in one global order (by address), so that a.merge(b) and b.merge(a) running
        // at the same time cannot deadlock.
        py.detach(|| {
            if (self as *const Self) < (other as *const Self) {
                let mut dst = write(&self.inner);
                let src = read(&other.inner);
                dst.merge(&src)
            } else {
                let src = read(&other.inner);
                let mut dst = write(&self.inner);
                dst.merge(&src)
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

    /// All A-SOLiDs, shape (N, n_azimuth), float32 (a copy).
    #[getter]
    fn a<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let (shape, v) = self.with(py, |db| {
            ((db.len(), db.config().n_azimuth), db.a_all().to_vec())
        });
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

#[pymethods]
impl PyLoopDetector {
    #[new]
    #[pyo3(signature = (cfg, exclude_recent=50, threshold=0.1, top_k=10, rerank=true))]
    fn new(
        py: Python<'_>,
        cfg: PyRef<'_, PyConfig>,
        exclude_recent: usize,
        threshold: f64,
        top_k: usize,
        rerank: bool,
    ) -> PyResult<Self> {
        let mut inner = LoopDetector::new(cfg.inner, exclude_recent, threshold, top_k)
            .map_err(|e| db_err(py, e))?;
        inner.rerank = rerank;
        Ok(PyLoopDetector::wrap(inner))
    }

    /// A detector over a copy of an existing database (a prior map).
    #[staticmethod]
    #[pyo3(signature = (database, exclude_recent=50, threshold=0.1, top_k=10, rerank=true))]
    fn from_database(
        py: Python<'_>,
        database: &PyDatabase,
        exclude_recent: usize,
        threshold: f64,
        top_k: usize,
        rerank: bool,
    ) -> PyResult<Self> {
        if !threshold.is_finite() || top_k == 0 {
            return Err(PyValueError::new_err(
                "threshold must be finite and top_k at least 1",
            ));
        }
        let mut inner =
            LoopDetector::with_database(database.snapshot(py), exclude_recent, threshold, top_k);
        inner.rerank = rerank;
        Ok(PyLoopDetector::wrap(inner))
    }

    /// Searches the scan (points or a Descriptor) against the past scans, then adds it.
    #[pyo3(signature = (points_or_descriptor, timestamp=None))]
    fn add(
        &self,
        py: Python<'_>,
        points_or_descriptor: &Bound<'_, PyAny>,
        timestamp: Option<f64>,
    ) -> PyResult<Option<PyLoop>> {
        let d = self.descriptor(py, points_or_descriptor)?;
        let found = py
            .detach(|| write(&self.inner).add(&d, self::timestamp(timestamp)))
            .map_err(|e| db_err(py, e))?;
        Ok(found.map(PyLoop::from))
    }

    /// Searches the scan against every entry without adding it.
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

    /// Entries skipped as too recent.
    #[getter]
    fn exclude_recent(&self, py: Python<'_>) -> usize {
        self.with(py, |det| det.exclude_recent)
    }

    /// Largest accepted distance.
    #[getter]
    fn threshold(&self, py: Python<'_>) -> f64 {
        self.with(py, |det| det.threshold)
    }

    /// Candidates re-ranked by A-SOLiD alignment.
    #[getter]
    fn top_k(&self, py: Python<'_>) -> usize {
        self.with(py, |det| det.top_k)
    }

    /// Whether re-ranking is on.
    #[getter]
    fn rerank(&self, py: Python<'_>) -> bool {
        self.with(py, |det| det.rerank)
    }
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
    m.add_function(wrap_pyfunction!(encode_place, m)?)?;
    m.add_function(wrap_pyfunction!(decode_place, m)?)?;
    Ok(())
}
