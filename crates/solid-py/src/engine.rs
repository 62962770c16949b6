//! Bindings of the place-recognition engine: `Database`, `Match`, `LoopDetector`, `Loop` and the
//! wire form of one place. Argument checks, GIL release and error mapping only; the algorithms
//! live in `solid_lidar::db` and `solid_lidar::search`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::sync::{PoisonError, RwLock, RwLockReadGuard, RwLockWriteGuard};

use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBytes, PyDict, PyType};
use solid_lidar::db::{
    self, Database, DbError, DetectorConfig, LoopDetector, Method, SearchOptions,
};
use solid_lidar::{Config, Descriptor, Stats};

use crate::config::{detector_overrides, PyDetectorConfig};
use crate::{args, PyConfig, PyDescriptor};

/// `solid.DatabaseError`: created at registration as a subclass of `solid.SolidError` when the
/// module already defines it, else of `ValueError`.
static DATABASE_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

pub(crate) fn database_error(py: Python<'_>, msg: String) -> PyErr {
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
        DbError::Io { file, source } => crate::io_err(&source, Some(file)),
        DbError::OutOfMemory => pyo3::exceptions::PyMemoryError::new_err(
            "out of memory: the database operation could not allocate (nothing was changed)",
        ),
        other => database_error(py, other.to_string()),
    }
}

fn parse_method(method: &str) -> PyResult<Method> {
    Method::parse(method).map_err(|_| {
        crate::ConfigError::new_err(format!(
            "invalid method {method:?}: expected \"brute\", \"kdtree\", \"sketch\" or \"auto\""
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
            return Err(crate::ConfigError::new_err(
                "invalid max_distance = nan: expected a distance (or None for no bound)",
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
    if let Some(r) = contiguous_query(q) {
        return Ok(r);
    }
    q.extract::<Vec<f32>>().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "expected a solid.Descriptor or a 1-D sequence of floats (an R-SOLiD)",
        )
    })
}

/// A contiguous 1-D float32/float64 array read directly, as [`crate::PointSlice::to_f32`] reads
/// points; `None` for anything else (read as a sequence then). Extracting the array as a
/// sequence made a numpy scalar of each value (about 3 of the 31 µs of a brute-force search of
/// 10,000 entries).
fn contiguous_query(q: &Bound<'_, PyAny>) -> Option<Vec<f32>> {
    use crate::PointSlice;
    if let Ok(a) = q.cast::<PyArray1<f32>>() {
        let a = a.try_readonly().ok()?;
        let v = a.as_slice().ok()?;
        return Some(PointSlice::F32(v, v.len()).to_f32().into_owned());
    }
    let a = q.cast::<PyArray1<f64>>().ok()?.try_readonly().ok()?;
    let v = a.as_slice().ok()?;
    Some(PointSlice::F64(v, v.len()).to_f32().into_owned())
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
    let bad = |m: String| crate::SolidError::new_err(m);
    let flat: Vec<f64> = match p.extract::<Vec<Vec<f64>>>() {
        Ok(rows) if rows.len() == 3 && rows.iter().all(|r| r.len() == 4) => {
            rows.into_iter().flatten().collect()
        }
        Ok(rows) if rows.len() == 4 && rows.iter().all(|r| r.len() == 4) => {
            if rows[3] != [0.0, 0.0, 0.0, 1.0] {
                return Err(bad(format!(
                    "a 4x4 pose must end with the row [0, 0, 0, 1], got {:?}",
                    rows[3]
                )));
            }
            rows.into_iter().take(3).flatten().collect()
        }
        Ok(_) => return Err(bad(msg.to_string())),
        Err(_) => p.extract::<Vec<f64>>().map_err(|_| bad(msg.to_string()))?,
    };
    let arr: [f64; 12] = flat
        .try_into()
        .map_err(|v: Vec<f64>| bad(format!("{msg}; got {} values", v.len())))?;
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
    /// The score the loop was accepted with (the R-SOLiD distance; with verification
    /// 1 − fitness).
    #[pyo3(get)]
    pub score: f64,
    /// Overlap of the verifying registration (None when not verified).
    #[pyo3(get)]
    pub fitness: Option<f64>,
    /// Inlier RMSE of the verifying registration, metres (None when not verified).
    #[pyo3(get)]
    pub rmse: Option<f64>,
    pose_: Option<solid_lidar::reg::Pose>,
}

#[pymethods]
impl PyLoop {
    /// T_query_candidate, (4, 4) float64, of a verified loop (p_query ≈ pose @ p_candidate);
    /// None when the loop was not verified. Its yaw is `heading`.
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.pose_.map(|p| pose_array(py, &p))
    }

    /// Whether the loop was verified by registration.
    #[getter]
    fn verified(&self) -> bool {
        self.pose_.is_some()
    }

    fn __repr__(&self) -> String {
        format!(
            "Loop(query={}, candidate={}, distance={:.6}, heading={:.3}, score={:.6}, verified={})",
            self.query,
            self.candidate,
            self.distance,
            self.heading,
            self.score,
            if self.pose_.is_some() {
                "True"
            } else {
                "False"
            }
        )
    }
}

/// A (4, 4) float64 array of a pose.
pub(crate) fn pose_array<'py>(
    py: Python<'py>,
    p: &solid_lidar::reg::Pose,
) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = p.iter().flatten().copied().collect();
    Array2::from_shape_vec((4, 4), flat)
        .expect("4 x 4")
        .into_pyarray(py)
}

impl From<db::Loop> for PyLoop {
    fn from(l: db::Loop) -> Self {
        PyLoop {
            query: l.query,
            candidate: l.candidate,
            distance: l.distance,
            heading: l.heading_deg,
            score: l.score,
            fitness: l.fitness,
            rmse: l.rmse,
            pose_: l.pose,
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
    /// What ranks the candidates (the value a PR curve sweeps): the R-SOLiD distance, or with
    /// verification 1 − fitness for a candidate that passed the gate and 1.5 + distance / 2
    /// otherwise.
    #[pyo3(get)]
    pub score: f64,
    verification: Option<db::Verification>,
}

#[pymethods]
impl PyCandidate {
    /// Whether this candidate was registered.
    #[getter]
    fn verified(&self) -> bool {
        self.verification.is_some()
    }
    /// Whether its registration passed the gate (False when not registered).
    #[getter]
    fn accepted(&self) -> bool {
        self.verification.is_some_and(|v| v.accepted)
    }
    /// Why the gate rejected it (None when accepted or not registered).
    #[getter]
    fn rejection(&self) -> Option<String> {
        self.verification
            .and_then(|v| v.rejection)
            .map(|r| r.to_string())
    }
    /// T_query_candidate (4, 4) of its registration (None when not registered).
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.verification
            .map(|v| pose_array(py, &v.registration.pose))
    }
    /// Overlap of its registration (None when not registered).
    #[getter]
    fn fitness(&self) -> Option<f64> {
        self.verification.map(|v| v.registration.fitness)
    }
    /// Overlap of its registration's points off horizontal surfaces (None when not registered).
    #[getter]
    fn structure_fitness(&self) -> Option<f64> {
        self.verification.map(|v| v.registration.structure_fitness)
    }
    /// Inlier RMSE of its registration, metres (None when not registered).
    #[getter]
    fn rmse(&self) -> Option<f64> {
        self.verification.map(|v| v.registration.rmse)
    }
    /// Smallest eigenvalue of the translation block of its registration's information matrix.
    #[getter]
    fn degeneracy_translation(&self) -> Option<f64> {
        self.verification
            .map(|v| v.registration.degeneracy.translation)
    }
    /// Initial yaws that reached the best pose, of those tried (None when not registered).
    #[getter]
    fn agreement(&self) -> Option<(usize, usize)> {
        self.verification.map(|v| (v.agreement, v.hypotheses))
    }

    fn __repr__(&self) -> String {
        format!(
            "Candidate(id={}, distance={:.6}, heading={:.3}, score={:.6}, verified={}, accepted={})",
            self.id,
            self.distance,
            self.heading,
            self.score,
            if self.verified() { "True" } else { "False" },
            if self.accepted() { "True" } else { "False" }
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
            verification: c.verification,
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
/// and runs alone, and so does the search that builds an index left to the searches
/// ([`PyDatabase::read_for`]); every wait happens with the GIL released. A process forked while
/// another thread adds, merges or builds the index finds its copy locked (as with any lock held
/// across `fork`): fork while no thread does, or use `multiprocessing`'s `forkserver` or `spawn`
/// start method.
#[pyclass(name = "Database", module = "solid", frozen)]
pub struct PyDatabase {
    inner: RwLock<Database>,
    /// Whether the searches build the index when it is due (`add_batch(..., index=None)`).
    auto_index: AtomicBool,
}

impl PyDatabase {
    fn wrap(inner: Database) -> Self {
        PyDatabase {
            inner: RwLock::new(inner),
            auto_index: AtomicBool::new(false),
        }
    }

    /// The read lock for `queries` searches with `opts`, after building the index first when a
    /// bulk add left it to the searches and these make it due ([`Database::index_due`]). Call
    /// with the GIL released.
    fn read_for(&self, opts: &SearchOptions, queries: usize) -> RwLockReadGuard<'_, Database> {
        let db = read(&self.inner);
        if !self.auto_index.load(Relaxed) || !db.index_due(opts, queries) {
            return db;
        }
        drop(db);
        {
            let mut db = write(&self.inner);
            // Another search may have built it while this one waited, or an add_batch may have
            // left it to build_index.
            if self.auto_index.load(Relaxed)
                && db.index_due(opts, queries)
                && db.build_index().is_err()
            {
                // No memory for the index: the searches stay exact by brute force, and stop
                // trying.
                self.auto_index.store(false, Relaxed);
            }
        }
        read(&self.inner)
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

/// An array shape that does not match its data (cannot happen: the shapes come from the data).
fn shape_err(e: numpy::ndarray::ShapeError) -> PyErr {
    crate::SolidError::new_err(e.to_string())
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
        #[pyo3(from_py_with = args::session)] session: u32,
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
    /// poses; returns the first id (the others follow). Everything is checked first. The search
    /// sketch and the kd-tree: with `index=None` (the default) built by the first search that
    /// finds them due (`Database::index_due`), with `True` now, with `False` left for
    /// `build_index`, the next `add`, an indexed `add_batch` or a merge; the last call decides
    /// for every entry still waiting. Searches stay exact throughout.
    #[pyo3(signature = (r, a, session=0, timestamps=None, poses=None, index=None))]
    #[allow(clippy::too_many_arguments)]
    fn add_batch(
        &self,
        py: Python<'_>,
        r: &Bound<'_, PyAny>,
        a: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = args::session)] session: u32,
        timestamps: Option<numpy::PyReadonlyArray1<'_, f64>>,
        poses: Option<&Bound<'_, PyAny>>,
        index: Option<bool>,
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
            let mut db = write(&self.inner);
            let first = db.add_batch(
                &r,
                &a,
                session,
                times,
                poses.as_deref(),
                index == Some(true),
            )?;
            self.auto_index.store(index.is_none(), Relaxed);
            Ok(first)
        })
        .map_err(|e| db_err(py, e))
    }

    /// Entries the search sketch and the kd-tree do not cover yet (left by `add_batch`; the
    /// searches scan them by brute force).
    fn index_pending(&self, py: Python<'_>) -> usize {
        self.with(py, Database::index_pending)
    }

    /// Extends the search sketch and the kd-tree over every entry (after `add_batch`, before the
    /// searches build them).
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
        #[pyo3(from_py_with = args::k)] k: usize,
        #[pyo3(from_py_with = args::exclude_recent)] exclude_recent: usize,
        method: &str,
        not_newer_than: Option<f64>,
        max_distance: Option<f64>,
    ) -> PyResult<Vec<PyMatch>> {
        let opts = search_options(k, exclude_recent, method, not_newer_than, max_distance)?;
        let r = query_r(descriptor, self.fingerprint(py))?;
        let found = py
            .detach(|| self.read_for(&opts, 1).search_with(&r, &opts))
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
        #[pyo3(from_py_with = args::k)] k: usize,
        #[pyo3(from_py_with = args::exclude_recent)] exclude_recent: usize,
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
            .detach(|| self.read_for(&opts, m).search_batch(&q, &opts))
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

    /// The database in the file format, as bytes (encoded straight into the bytes object).
    fn to_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        loop {
            let len = self.with(py, Database::encoded_len);
            let mut whole = false;
            let bytes = PyBytes::new_with(py, len, |buf| {
                // An add between measuring and encoding changes the length: measure again.
                whole = py.detach(|| {
                    let db = read(&self.inner);
                    db.encoded_len() == buf.len() && db.encode_into(buf).is_ok()
                });
                Ok(())
            })?;
            if whole {
                return Ok(bytes);
            }
        }
    }

    /// A database from bytes made by `to_bytes` (`bytes`, `bytearray`, `memoryview`, ...).
    #[staticmethod]
    fn from_bytes(py: Python<'_>, data: &Bound<'_, PyAny>) -> PyResult<Self> {
        let data = args::bytes_arg(data, "data")?;
        let data = data.as_bytes();
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
            let v = args::try_copy(db.r_all(), "Database.r");
            ((db.len(), db.config().n_range), v)
        });
        let a = Array2::from_shape_vec(shape, v?).map_err(shape_err)?;
        Ok(a.into_pyarray(py))
    }

    /// All A-SOLiDs as stored, shape (N, n_azimuth), float32 (a copy): 8 bits per value with
    /// one step per entry, within half a step (0.2 % of the entry's largest value) of the
    /// values added.
    #[getter]
    fn a<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let (shape, v) = self.with(py, |db| ((db.len(), db.config().n_azimuth), db.a_all()));
        let a = Array2::from_shape_vec(shape, v).map_err(shape_err)?;
        Ok(a.into_pyarray(py))
    }

    /// Entry ids, 0..N, int64.
    #[getter]
    fn ids<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let n = self.with(py, Database::len);
        let mut ids = args::try_vec(n, "Database.ids")?;
        ids.extend(0..n as i64);
        Ok(ids.into_pyarray(py))
    }

    /// Bytes of the compact clouds stored for verification (0: none).
    #[getter]
    fn cloud_bytes(&self, py: Python<'_>) -> usize {
        self.with(py, Database::cloud_bytes)
    }

    /// Number of places that have a stored cloud.
    #[getter]
    fn clouds_stored(&self, py: Python<'_>) -> usize {
        self.with(py, Database::clouds_stored)
    }

    /// The compact cloud stored with place `id` (the wire form of `solid.encode_cloud`; decode
    /// it with `solid.decode_cloud`), or None.
    fn cloud<'py>(
        &self,
        py: Python<'py>,
        id: &Bound<'_, PyAny>,
    ) -> PyResult<Option<Bound<'py, PyBytes>>> {
        let n = self.with(py, Database::len);
        if n == 0 {
            args::int_arg::<i128>(id, "id", 0, i128::MAX)?; // a bool or a non-integer: TypeError
            return Err(crate::ConfigError::new_err(format!(
                "place {} does not exist: the database is empty",
                id.str()?
            )));
        }
        let id: u32 = args::int_arg(id, "id", 0, n as i128 - 1)?;
        let c = self.with(py, |db| db.cloud(id).map(<[u8]>::to_vec));
        Ok(c.map(|b| PyBytes::new(py, &b)))
    }

    /// Sessions, uint32.
    #[getter]
    fn sessions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<u32>>> {
        let v = self.with(py, |db| args::try_copy(db.sessions(), "Database.sessions"));
        Ok(v?.into_pyarray(py))
    }

    /// Timestamps, float64 (NaN where none was given).
    #[getter]
    fn timestamps<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let v = self.with(py, |db| {
            args::try_copy(db.timestamps(), "Database.timestamps")
        });
        Ok(v?.into_pyarray(py))
    }

    /// Poses, shape (N, 3, 4), float64 (all NaN where none was given).
    #[getter]
    fn poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let (n, flat) = self.with(py, |db| {
            let flat = args::try_vec(db.len().saturating_mul(12), "Database.poses").map(|mut v| {
                v.extend(db.poses().iter().flat_map(|p| p.unwrap_or([f64::NAN; 12])));
                v
            });
            (db.len(), flat)
        });
        let a = Array3::from_shape_vec((n, 3, 4), flat?).map_err(shape_err)?;
        Ok(a.into_pyarray(py))
    }
}

/// An online loop-closure detector.
///
/// Safe to share between threads: `add` (search then insert) runs alone, as one step, so no scan
/// is lost or searched against a half-added entry; `query` and the getters run in parallel. A
/// process forked while another thread runs a step finds its copy locked, as `Database`'s.
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

    /// A Descriptor argument as itself, or points described (and their cloud prepared, when the
    /// detector verifies) with the GIL released.
    fn input(&self, py: Python<'_>, x: &Bound<'_, PyAny>) -> PyResult<Input> {
        if x.cast::<PyDescriptor>().is_ok() {
            return Ok(Input::Descriptor(self.descriptor(py, x)?));
        }
        let borrowed = crate::borrow_points(x, "points")?;
        let slice = borrowed.slice();
        let cfg = self.cfg;
        let scan = py
            .detach(|| prepare_slice(&read(&self.inner), &slice, &cfg))
            .map_err(|e| db_err(py, e))?;
        Ok(Input::Scan(Box::new(scan)))
    }
}

/// Per-scan timestamps (NaN: none) and poses of a batch (empty: none at all).
type TimesAndPoses = (Vec<f64>, Vec<Option<[f64; 12]>>);

/// What a detector method was given.
enum Input {
    Descriptor(Descriptor),
    Scan(Box<db::Scan>),
}

/// Describes points (the thread's reusable describer) and prepares their cloud for `det`.
fn prepare_slice(
    det: &LoopDetector,
    s: &crate::PointSlice<'_>,
    cfg: &Config,
) -> Result<db::Scan, DbError> {
    let descriptor = crate::describe_slice(s, cfg)?;
    let cloud = match *s {
        crate::PointSlice::F32(v, stride) => {
            det.prepare_cloud(solid_lidar::Points::new(v, stride)?)?
        }
        crate::PointSlice::F64(v, stride) => {
            det.prepare_cloud(solid_lidar::Points::new(v, stride)?)?
        }
    };
    Ok(db::Scan { descriptor, cloud })
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

#[pymethods]
impl PyLoopDetector {
    #[new]
    #[pyo3(signature = (cfg, exclude_recent=None, threshold=None, top_k=None, rerank=None, *, exclude_meters=None, exclude_seconds=None, verify=None, detector=None))]
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
        verify: Option<&Bound<'_, PyAny>>,
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
            verify,
        )?;
        let dc = detector_config(&cfg, detector.as_deref(), Some(&kw))?;
        let inner = LoopDetector::new(cfg.inner, dc).map_err(|e| db_err(py, e))?;
        Ok(PyLoopDetector::wrap(inner))
    }

    /// A detector over a copy of an existing database (a prior map): its places are candidates
    /// from the first scan on and are never excluded as recent.
    #[staticmethod]
    #[pyo3(signature = (database, exclude_recent=None, threshold=None, top_k=None, rerank=None, *, exclude_meters=None, exclude_seconds=None, verify=None, detector=None))]
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
        verify: Option<&Bound<'_, PyAny>>,
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
            verify,
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

    /// As `add`, returning everything the step decided (a `Detection`). Points are described
    /// and, when the detector verifies (the default), their cloud is prepared, stored with the
    /// place and registered with the best candidates'; a Descriptor can only be used with
    /// verification off.
    #[pyo3(signature = (points_or_descriptor, timestamp=None, pose=None))]
    fn detect(
        &self,
        py: Python<'_>,
        points_or_descriptor: &Bound<'_, PyAny>,
        timestamp: Option<f64>,
        pose: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyDetection> {
        let input = self.input(py, points_or_descriptor)?;
        let pose = parse_pose(pose)?;
        let t = self::timestamp(timestamp);
        let found = py
            .detach(|| {
                let mut det = write(&self.inner);
                match input {
                    Input::Descriptor(d) => det.detect(&d, t, pose),
                    Input::Scan(scan) => det.detect_scan(*scan, t, pose),
                }
            })
            .map_err(|e| db_err(py, e))?;
        Ok(PyDetection::from(found))
    }

    /// `detect` for many scans in order, in one call: point arrays (described and prepared in
    /// parallel, `threads` workers, every core by default) or Descriptors (verification off).
    /// The GIL is released once. Every input is checked before the first is added: on error
    /// nothing is added.
    #[pyo3(signature = (scans, timestamps=None, poses=None, threads=None, progress=None))]
    fn detect_many(
        &self,
        py: Python<'_>,
        scans: &Bound<'_, PyAny>,
        timestamps: Option<&Bound<'_, PyAny>>,
        poses: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = args::threads)] threads: Option<usize>,
        progress: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Vec<PyDetection>> {
        let items: Vec<Bound<'_, PyAny>> = scans
            .try_iter()
            .map_err(|_| {
                PyTypeError::new_err("scans must be a sequence of point arrays or Descriptors")
            })?
            .collect::<PyResult<_>>()?;
        let (ts, ps) = self.times_and_poses(timestamps, poses)?;
        if items.iter().all(|x| x.cast::<PyDescriptor>().is_ok()) {
            let ds = items
                .iter()
                .map(|x| self.descriptor(py, x))
                .collect::<PyResult<Vec<_>>>()?;
            let found = py
                .detach(|| write(&self.inner).detect_many(&ds, &ts, &ps))
                .map_err(|e| db_err(py, e))?;
            return Ok(found.into_iter().map(PyDetection::from).collect());
        }
        let borrowed = items
            .iter()
            .enumerate()
            .map(|(i, p)| crate::borrow_points(p, &format!("scans[{i}]")))
            .collect::<PyResult<Vec<_>>>()?;
        let slices: Vec<crate::PointSlice<'_>> =
            borrowed.iter().map(crate::Borrowed::slice).collect();
        let cfg = self.cfg;
        let pool = crate::batch_pool(threads, slices.len())?;
        let progress = progress
            .filter(|p| !p.is_none())
            .map(|p| p.clone().unbind());
        let mut stopped: Option<PyErr> = None;
        let found = py
            .detach(|| -> Result<Vec<db::Detection>, DbError> {
                let scans = {
                    let det = read(&self.inner);
                    let prep = |s: &crate::PointSlice<'_>| prepare_slice(&det, s, &cfg);
                    match crate::map_interruptible(&slices, pool, prep) {
                        Ok(v) => v.into_iter().collect::<Result<Vec<_>, _>>()?,
                        Err(e) => {
                            stopped = Some(e);
                            return Ok(Vec::new());
                        }
                    }
                };
                // Between steps, the GIL is taken back briefly: Ctrl-C and progress.
                let mut each = |i: usize| {
                    let r = Python::attach(|py| -> PyResult<()> {
                        py.check_signals()?;
                        match &progress {
                            Some(f) if i > 0 => f.call1(py, (1,)).map(drop),
                            _ => Ok(()),
                        }
                    });
                    r.map_err(|e| stopped = Some(e)).is_ok()
                };
                let found = write(&self.inner).detect_scans_each(scans, &ts, &ps, &mut each)?;
                if stopped.is_none() && !found.is_empty() {
                    if let Some(f) = &progress {
                        Python::attach(|py| f.call1(py, (1,)).map(drop))
                            .unwrap_or_else(|e| stopped = Some(e));
                    }
                }
                Ok(found)
            })
            .map_err(|e| db_err(py, e))?;
        if let Some(e) = stopped {
            return Err(e);
        }
        Ok(found.into_iter().map(PyDetection::from).collect())
    }

    /// The candidates the scan would get if it were added now, without adding it.
    #[pyo3(signature = (points_or_descriptor, k=None, timestamp=None, pose=None))]
    fn candidates(
        &self,
        py: Python<'_>,
        points_or_descriptor: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = args::opt_k)] k: Option<usize>,
        timestamp: Option<f64>,
        pose: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Vec<PyCandidate>> {
        let d = self.descriptor(py, points_or_descriptor)?;
        let pose = parse_pose(pose)?;
        let k = match k {
            Some(k) => k,
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
    /// With verification on (the default), points are described, prepared and the best
    /// candidates registered, as a step would; a Descriptor needs verification off.
    fn query(
        &self,
        py: Python<'_>,
        points_or_descriptor: &Bound<'_, PyAny>,
    ) -> PyResult<Option<PyLoop>> {
        let verifies = self.with(py, |det| det.config().verify.enabled);
        let found =
            match self.input(py, points_or_descriptor)? {
                Input::Scan(scan) if verifies => py.detach(|| write(&self.inner).query_scan(&scan)),
                Input::Scan(scan) => self.with(py, |det| det.query(&scan.descriptor)),
                Input::Descriptor(_) if verifies => return Err(crate::ConfigError::new_err(
                    "query() with a Descriptor needs verification off (verify=False): a verifying \
                     detector registers the scan, so give its points",
                )),
                Input::Descriptor(d) => self.with(py, |det| det.query(&d)),
            }
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
    fn times_and_poses(
        &self,
        timestamps: Option<&Bound<'_, PyAny>>,
        poses: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<TimesAndPoses> {
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
        Ok((ts, ps))
    }
}

/// The positional/keyword detector arguments as a dict of overrides (None: not given).
#[allow(clippy::too_many_arguments)]
fn overrides_dict<'py>(
    py: Python<'py>,
    exclude_recent: Option<&Bound<'py, PyAny>>,
    threshold: Option<&Bound<'py, PyAny>>,
    top_k: Option<&Bound<'py, PyAny>>,
    rerank: Option<&Bound<'py, PyAny>>,
    exclude_meters: Option<&Bound<'py, PyAny>>,
    exclude_seconds: Option<&Bound<'py, PyAny>>,
    verify: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let kw = PyDict::new(py);
    for (k, v) in [
        ("exclude_frames", exclude_recent),
        ("threshold", threshold),
        ("top_k", top_k),
        ("rerank", rerank),
        ("exclude_meters", exclude_meters),
        ("exclude_seconds", exclude_seconds),
        ("verify", verify),
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
/// `data` is `bytes`, `bytearray`, `memoryview` or any other buffer of bytes.
#[pyfunction]
fn decode_place(
    py: Python<'_>,
    data: &Bound<'_, PyAny>,
    cfg: PyRef<'_, PyConfig>,
) -> PyResult<PyDescriptor> {
    let p =
        db::decode_place(args::bytes_arg(data, "data")?.as_bytes()).map_err(|e| db_err(py, e))?;
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
    m.add("VERIFIED_THRESHOLD", db::VERIFIED_THRESHOLD)?;
    m.add_function(wrap_pyfunction!(encode_place, m)?)?;
    m.add_function(wrap_pyfunction!(decode_place, m)?)?;
    Ok(())
}
