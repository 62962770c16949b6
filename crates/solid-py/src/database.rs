//! Bindings of the database (`solid_lidar::db::Database` and the wire form of one place):
//! `Database`, `Match`, `encode_place`, `decode_place`. Argument checks, locking, GIL release and
//! error mapping only; the search, and when to build its index, live in the core.

use std::path::PathBuf;
use std::sync::{Arc, PoisonError, RwLock, RwLockReadGuard, RwLockWriteGuard};

use numpy::ndarray::{Array2, Array3, ArrayView3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use solid_lidar::db::{self, Database, DbError, IndexPolicy, Method, SearchOptions};
use solid_lidar::{Descriptor, Stats};

use crate::args;
use crate::arrays::{borrow_2d, contiguous_query, parse_pose, parse_poses, Columns};
use crate::config::PyConfig;
use crate::describe::PyDescriptor;
use crate::errors::{core_err, ConfigError, DatabaseError};
use crate::SolidError;

fn parse_method(method: &str) -> PyResult<Method> {
    Method::parse(method).map_err(|_| {
        ConfigError::new_err(format!(
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
            return Err(ConfigError::new_err(
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

/// Query R-SOLiDs of a batch: an (M, n_range) float array, or a sequence of Descriptors made
/// with the database's config.
fn batch_queries(q: &Bound<'_, PyAny>, nr: usize, fingerprint: u64) -> PyResult<Vec<f32>> {
    if q.cast::<numpy::PyUntypedArray>().is_ok() {
        let b = borrow_2d(q, "queries", Columns::Exactly(nr))?;
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
        check_fingerprint(d.inner.fingerprint, fingerprint)?;
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

pub(crate) fn check_fingerprint(got: u64, expected: u64) -> PyResult<()> {
    if got != expected {
        return Err(core_err(DbError::ConfigMismatch { expected, got }));
    }
    Ok(())
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

/// Shared read access (searches run in parallel). Callers take it with the GIL released, so a
/// thread waiting for a writer never blocks Python. No code panics while holding a lock; should
/// one ever be poisoned, the data is still consistent (every update is applied whole or not at
/// all), so the guard is recovered rather than turned into a panic.
pub(crate) fn read<T>(l: &RwLock<T>) -> RwLockReadGuard<'_, T> {
    l.read().unwrap_or_else(PoisonError::into_inner)
}

/// Exclusive access (adds, merges); see [`read`].
pub(crate) fn write<T>(l: &RwLock<T>) -> RwLockWriteGuard<'_, T> {
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
///
/// A `LoopDetector.from_database` shares the places with the database instead of copying them
/// (the database's value is shared, then copied by whichever changes it first: an add, a merge
/// or a metadata change after that makes the database its own copy).
#[pyclass(name = "Database", module = "solid", frozen)]
pub struct PyDatabase {
    inner: RwLock<Arc<Database>>,
}

impl PyDatabase {
    pub(crate) fn wrap(inner: Database) -> Self {
        PyDatabase::share(Arc::new(inner))
    }

    /// A database object over places shared with others (copied when this one changes).
    pub(crate) fn share(inner: Arc<Database>) -> Self {
        PyDatabase {
            inner: RwLock::new(inner),
        }
    }

    /// `f` of the database under the write lock, made this object's own first when shared.
    /// Call with the GIL released.
    fn modify<R>(&self, f: impl FnOnce(&mut Database) -> R) -> R {
        f(Arc::make_mut(&mut write(&self.inner)))
    }

    /// The places to share with a detector, their index built first in place (a detector
    /// searches on every step), so that the detector does not copy them to build it. Call with
    /// the GIL released.
    pub(crate) fn shared_indexed(&self) -> Result<Arc<Database>, DbError> {
        let mut db = write(&self.inner);
        if db.index_pending() > 0 {
            Arc::make_mut(&mut db).build_index()?;
        }
        Ok(Arc::clone(&db))
    }

    /// The read lock for `queries` searches with `opts`, after building the index alone first
    /// when the core says these searches do ([`Database::search_builds_index`]). Call with the
    /// GIL released.
    fn read_for(&self, opts: &SearchOptions, queries: usize) -> RwLockReadGuard<'_, Arc<Database>> {
        let db = read(&self.inner);
        if !db.search_builds_index(opts, queries) {
            return db;
        }
        drop(db);
        // Asks again under the write lock: another search may have built it meanwhile.
        self.modify(|db| db.build_index_for_search(opts, queries));
        read(&self.inner)
    }

    /// `f` of the database under the read lock, taken with the GIL released.
    fn with<R: Send>(&self, py: Python<'_>, f: impl FnOnce(&Database) -> R + Send) -> R {
        py.detach(|| f(&read(&self.inner)))
    }

    /// The database's places as they are now (shared, not copied).
    pub(crate) fn snapshot(&self, py: Python<'_>) -> Arc<Database> {
        py.detach(|| Arc::clone(&read(&self.inner)))
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
    fn new(cfg: PyRef<'_, PyConfig>) -> PyResult<Self> {
        let inner = Database::new(cfg.inner).map_err(core_err)?;
        Ok(PyDatabase::wrap(inner))
    }

    /// Adds a descriptor (with its compact cloud for verification, if given); returns its id.
    #[pyo3(signature = (descriptor, session=0, timestamp=None, pose=None, cloud=None))]
    fn add(
        &self,
        py: Python<'_>,
        descriptor: PyRef<'_, PyDescriptor>,
        #[pyo3(from_py_with = args::session)] session: u32,
        timestamp: Option<f64>,
        pose: Option<&Bound<'_, PyAny>>,
        cloud: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u32> {
        let pose = parse_pose(pose)?;
        let d = &descriptor.inner;
        let cloud = cloud.map(|c| args::bytes_arg(c, "cloud")).transpose()?;
        let cloud = cloud.as_ref().map(|c| c.as_bytes());
        py.detach(|| {
            self.modify(|db| db.add_with_cloud(d, session, args::timestamp(timestamp), pose, cloud))
        })
        .map_err(core_err)
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
        let r = borrow_2d(r, "r", Columns::Exactly(cfg.n_range))?;
        let a = borrow_2d(a, "a", Columns::Exactly(cfg.n_azimuth))?;
        let n = r.rows();
        let poses = parse_poses(poses, n)?;
        let times = match &timestamps {
            Some(t) => Some(t.as_slice().map_err(|_| {
                PyValueError::new_err("timestamps must be a contiguous float64 array of shape (N,)")
            })?),
            None => None,
        };
        let (r, a) = (r.slice(), a.slice());
        let policy = match index {
            None => IndexPolicy::BySearches,
            Some(true) => IndexPolicy::Now,
            Some(false) => IndexPolicy::OnRequest,
        };
        py.detach(|| {
            let (r, a) = (r.to_f32(), a.to_f32());
            self.modify(|db| db.add_batch_with(&r, &a, session, times, poses.as_deref(), policy))
        })
        .map_err(core_err)
    }

    /// Entries the search sketch and the kd-tree do not cover yet (left by `add_batch`; the
    /// searches scan them by brute force).
    fn index_pending(&self, py: Python<'_>) -> usize {
        self.with(py, Database::index_pending)
    }

    /// Extends the search sketch and the kd-tree over every entry (after `add_batch`, before the
    /// searches build them); a loaded map's index is the kd-tree alone unless `sketch` says.
    #[pyo3(signature = (sketch=None))]
    fn build_index(&self, py: Python<'_>, sketch: Option<bool>) -> PyResult<()> {
        py.detach(|| {
            self.modify(|db| {
                if let Some(on) = sketch {
                    db.set_sketch(on);
                }
                db.build_index()
            })
        })
        .map_err(core_err)
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
            .map_err(core_err)?;
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
            .map_err(core_err)?;
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
        let ids = Array2::from_shape_vec(shape, ids).map_err(core_err)?;
        let dists = Array2::from_shape_vec(shape, found.distances).map_err(core_err)?;
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
        let d = self.with(py, |db| db.distances(&r)).map_err(core_err)?;
        Ok(d.into_pyarray(py))
    }

    /// Appends every entry of `other` (same config required). With `new_sessions`, the sessions
    /// of `other` are renumbered to follow this database's (maps of separate runs stay apart);
    /// with `anchor` (`T_map_other`, 3x4 or 4x4), the poses of `other` are carried into this map's
    /// world; with an array of shape (len(other), 3, 4) or (len(other), 4, 4), each place's pose
    /// by its own transform (a session whose odometry broke: one anchor per stretch), a place
    /// whose transform is all NaN keeping no pose. float32 arrays are read as float64.
    #[pyo3(signature = (other, new_sessions=false, anchor=None))]
    fn merge(
        &self,
        py: Python<'_>,
        other: &PyDatabase,
        new_sessions: bool,
        anchor: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let per_place = match anchor {
            Some(a)
                if !a.is_none()
                    && a.getattr("ndim").and_then(|d| d.extract::<usize>()).ok() == Some(3) =>
            {
                Some(per_place_anchors(a)?)
            }
            _ => None,
        };
        let anchor = match per_place {
            Some(_) => None,
            None => parse_pose(anchor).map_err(|e| {
                SolidError::new_err(format!(
                    "anchor: {} (or, one per place, an array of shape (len(other), 3, 4) or \
                     (len(other), 4, 4))",
                    e.value(py)
                ))
            })?,
        };
        let apply = |dst: &mut Database, src: &Database| {
            let how = match (&per_place, &anchor) {
                (Some(each), _) => Some(db::MergeAnchor::PerPlace(each)),
                (None, Some(t)) => Some(db::MergeAnchor::All(t)),
                (None, None) => None,
            };
            dst.merge_anchored(src, new_sessions, how).map(|_| ())
        };
        if std::ptr::eq(self, other) {
            let copy = self.snapshot(py);
            return py
                .detach(|| self.modify(|db| apply(db, &copy)))
                .map_err(core_err);
        }
        // Both locks in one global order (by address), so that a.merge(b) and b.merge(a) running
        // at the same time cannot deadlock.
        py.detach(|| {
            if (self as *const Self) < (other as *const Self) {
                let mut dst = write(&self.inner);
                let src = read(&other.inner);
                apply(Arc::make_mut(&mut dst), &src)
            } else {
                let src = read(&other.inner);
                let mut dst = write(&self.inner);
                apply(Arc::make_mut(&mut dst), &src)
            }
        })
        .map_err(core_err)
    }

    /// Saves atomically (temporary file in the same directory, then rename), in format
    /// `version` (4; 3 or 2 for older readers); with `replace=False` only where nothing exists
    /// yet (of concurrent saves to one path, exactly one succeeds). Never over a FIFO, a device
    /// or a directory.
    #[pyo3(signature = (path, version=4, *, replace=true))]
    fn save(&self, py: Python<'_>, path: PathBuf, version: u32, replace: bool) -> PyResult<()> {
        py.detach(|| {
            let db = read(&self.inner);
            if replace {
                db.save_version(&path, version)
            } else {
                db.save_new(&path, version)
            }
        })
        .map_err(core_err)
    }

    /// What the database file at `path` holds, from its header and small sections alone (format
    /// 3 on; older files are read whole): a dict of version, config, fingerprint, places,
    /// places_with_cloud, cloud_bytes, sessions (a list of dicts: session, places, with_pose,
    /// first_time, last_time, NaN when none) and metadata.
    #[staticmethod]
    fn summary<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        use pyo3::types::PyDict;
        let s = py.detach(|| Database::summary(&path)).map_err(core_err)?;
        let d = PyDict::new(py);
        d.set_item("version", s.version)?;
        d.set_item("config", PyConfig::new_unchecked(s.config))?;
        d.set_item("fingerprint", s.fingerprint)?;
        d.set_item("places", s.places)?;
        d.set_item("places_with_cloud", s.places_with_cloud)?;
        d.set_item("cloud_bytes", s.cloud_bytes)?;
        let sessions = pyo3::types::PyList::empty(py);
        for x in &s.sessions {
            let e = PyDict::new(py);
            e.set_item("session", x.session)?;
            e.set_item("places", x.places)?;
            e.set_item("with_pose", x.with_pose)?;
            e.set_item("first_time", x.first_time)?;
            e.set_item("last_time", x.last_time)?;
            sessions.append(e)?;
        }
        d.set_item("sessions", sessions)?;
        d.set_item("metadata", s.metadata)?;
        Ok(d)
    }

    /// Free-form text saved with the database (format 3 on), such as how its scans were clipped
    /// ("": none).
    #[getter]
    fn metadata(&self, py: Python<'_>) -> String {
        self.with(py, |db| db.metadata().to_owned())
    }

    #[setter]
    fn set_metadata(&self, py: Python<'_>, text: &str) -> PyResult<()> {
        py.detach(|| self.modify(|db| db.set_metadata(text)))
            .map_err(core_err)
    }

    /// Loads a database saved by `save`.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py.detach(|| Database::load(&path)).map_err(core_err)?;
        Ok(PyDatabase::wrap(inner))
    }

    /// The database in the file format `version` (4; 3 or 2 for older readers), as bytes (version
    /// 4 encoded straight into the bytes object).
    #[pyo3(signature = (version=4))]
    fn to_bytes<'py>(&self, py: Python<'py>, version: u32) -> PyResult<Bound<'py, PyBytes>> {
        if version != 4 {
            let b = self
                .with(py, |db| db.to_bytes_version(version))
                .map_err(core_err)?;
            return Ok(PyBytes::new(py, &b));
        }
        loop {
            let len = self.with(py, Database::encoded_len);
            let mut encoded = None;
            let bytes = PyBytes::new_with(py, len, |buf| {
                // An add between measuring and encoding changes the length: measure again.
                encoded = py.detach(|| {
                    let db = read(&self.inner);
                    (db.encoded_len() == buf.len()).then(|| db.encode_into(buf))
                });
                Ok(())
            })?;
            match encoded {
                Some(Ok(_)) => return Ok(bytes),
                // A stored cloud that is corrupt or cannot be read from the map's file.
                Some(Err(e)) => return Err(core_err(e)),
                None => {}
            }
        }
    }

    /// A database from bytes made by `to_bytes` (`bytes`, `bytearray`, `memoryview`, ...).
    #[staticmethod]
    fn from_bytes(py: Python<'_>, data: &Bound<'_, PyAny>) -> PyResult<Self> {
        let data = args::bytes_arg(data, "data")?;
        let data = data.as_bytes();
        let inner = py.detach(|| Database::from_bytes(data)).map_err(core_err)?;
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
        let a = Array2::from_shape_vec(shape, v?).map_err(core_err)?;
        Ok(a.into_pyarray(py))
    }

    /// All A-SOLiDs as stored, shape (N, n_azimuth), float32 (a copy): 8 bits per value with
    /// one step per entry, within half a step (0.2 % of the entry's largest value) of the
    /// values added.
    #[getter]
    fn a<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let (shape, v) = self.with(py, |db| ((db.len(), db.config().n_azimuth), db.a_all()));
        let a = Array2::from_shape_vec(shape, v).map_err(core_err)?;
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
    /// it with `solid.decode_cloud`), or None. A map loaded from a file reads it from the file
    /// now, its checksum checked: a corrupt cloud raises DatabaseError naming the place.
    fn cloud<'py>(
        &self,
        py: Python<'py>,
        id: &Bound<'_, PyAny>,
    ) -> PyResult<Option<Bound<'py, PyBytes>>> {
        let n = self.with(py, Database::len);
        if n == 0 {
            args::int_arg::<i128>(id, "id", 0, i128::MAX)?; // a bool or a non-integer: TypeError
            return Err(ConfigError::new_err(format!(
                "place {} does not exist: the database is empty",
                id.str()?
            )));
        }
        let id: u32 = args::int_arg(id, "id", 0, n as i128 - 1)?;
        let c = self
            .with(py, |db| db.try_cloud(id).map(|c| c.map(|b| b.into_owned())))
            .map_err(core_err)?;
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
        let a = Array3::from_shape_vec((n, 3, 4), flat?).map_err(core_err)?;
        Ok(a.into_pyarray(py))
    }
}

/// A per-place anchor array (N, 3, 4) or (N, 4, 4), float64 or float32: each row's transform,
/// None where it is all NaN (that place keeps no pose).
fn per_place_anchors(a: &Bound<'_, PyAny>) -> PyResult<Vec<Option<[f64; 12]>>> {
    let msg = "anchor: one transform per place must be a float64 or float32 array of shape \
               (len(other), 3, 4) or (len(other), 4, 4)";
    // float64 is read where it lies; float32 alone is copied, as float64 (the transforms are
    // applied in float64 either way).
    if let Ok(a) = a.extract::<numpy::PyReadonlyArray3<'_, f64>>() {
        anchor_rows(a.as_array(), msg)
    } else if let Ok(a) = a.extract::<numpy::PyReadonlyArray3<'_, f32>>() {
        anchor_rows(a.as_array().mapv(f64::from).view(), msg)
    } else {
        let dtype = a
            .getattr("dtype")
            .map(|d| d.to_string())
            .unwrap_or_else(|_| "?".into());
        Err(PyTypeError::new_err(format!("{msg}; got dtype {dtype}")))
    }
}

/// [`per_place_anchors`] of a float64 view.
fn anchor_rows(arr: ArrayView3<'_, f64>, msg: &str) -> PyResult<Vec<Option<[f64; 12]>>> {
    let (n, rows, cols) = arr.dim();
    if !matches!((rows, cols), (3, 4) | (4, 4)) {
        return Err(PyValueError::new_err(format!(
            "{msg}; got shape ({n}, {rows}, {cols})"
        )));
    }
    let mut out = Vec::with_capacity(n);
    for (i, t) in arr.outer_iter().enumerate() {
        if t.iter().all(|v| v.is_nan()) {
            out.push(None);
            continue;
        }
        if rows == 4 && t.row(3).iter().ne([0.0, 0.0, 0.0, 1.0].iter()) {
            return Err(PyValueError::new_err(format!(
                "anchor[{i}]: a 4x4 transform must end with the row [0, 0, 0, 1]"
            )));
        }
        let mut p = [0.0; 12];
        for (k, v) in t.iter().take(12).enumerate() {
            p[k] = *v;
        }
        out.push(Some(p));
    }
    Ok(out)
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
    let bytes = db::encode_place(&d.r, &d.a, d.fingerprint, quantized).map_err(core_err)?;
    Ok(PyBytes::new(py, &bytes))
}

/// Decodes a place made with `cfg` (checked by fingerprint: a place from another config is an
/// error, since its vectors cannot be compared). Point counts are not transmitted (they read 0).
/// `data` is `bytes`, `bytearray`, `memoryview` or any other buffer of bytes.
#[pyfunction]
fn decode_place(data: &Bound<'_, PyAny>, cfg: PyRef<'_, PyConfig>) -> PyResult<PyDescriptor> {
    let p = db::decode_place(args::bytes_arg(data, "data")?.as_bytes()).map_err(core_err)?;
    check_fingerprint(p.fingerprint, cfg.inner.fingerprint())?;
    if p.r.len() != cfg.inner.n_range || p.a.len() != cfg.inner.n_azimuth {
        return Err(DatabaseError::new_err(
            "place vector lengths do not match the config",
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

/// Registers the database's classes and functions on the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDatabase>()?;
    m.add_class::<PyMatch>()?;
    m.add_function(wrap_pyfunction!(encode_place, m)?)?;
    m.add_function(wrap_pyfunction!(decode_place, m)?)?;
    Ok(())
}
