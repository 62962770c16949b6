//! Bindings of the loop detector (`solid_lidar::db::LoopDetector`): `LoopDetector`, `Detection`,
//! `Candidate`, `Loop`. Argument checks, locking, GIL release and error mapping only.

use std::sync::RwLock;

use numpy::PyArray2;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use solid_lidar::db::{self, DbError, DetectorConfig, LoopDetector};
use solid_lidar::detector;
use solid_lidar::reg::{Pose, Rejection, IDENTITY};
use solid_lidar::{Config, Descriptor};

use crate::args;
use crate::arrays::{
    borrow_points, borrow_scans, matrix6, parse_pose, pose_array, Borrowed, PointSlice,
};
use crate::config::{detector_overrides, PyConfig, PyDetectorConfig};
use crate::database::{check_fingerprint, read, write, PyDatabase};
use crate::describe::{batch_map, batch_pool, describe_points, describe_slice, PyDescriptor};
use crate::errors::{core_err, SolidError};

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
    /// |t| / (1 + |t|), the loop's length mapped into [0, 1)).
    #[pyo3(get)]
    pub score: f64,
    /// Overlap of the verifying registration (None when not verified).
    #[pyo3(get)]
    pub fitness: Option<f64>,
    /// Inlier RMSE of the verifying registration, metres (None when not verified).
    #[pyo3(get)]
    pub rmse: Option<f64>,
    pose_: Option<solid_lidar::reg::Pose>,
    information_: Option<solid_lidar::reg::Information>,
}

#[pymethods]
impl PyLoop {
    /// T_query_candidate, (4, 4) float64, of a verified loop (p_query ≈ pose @ p_candidate);
    /// None when the loop was not verified. Its yaw is `heading`.
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.pose_.map(|p| pose_array(py, &p))
    }

    /// The 6×6 information matrix of `pose` for a pose graph (translation first, g2o's order;
    /// the error on the right of the measurement), or None when the loop was not verified.
    #[getter]
    fn information<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.information_.map(|m| matrix6(py, &m))
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
            information_: l.information,
        }
    }
}

/// Where a detector's session lies in its prior map (docs/spec.md §8, placement): None until
/// mutually consistent loops into the map have placed it.
#[pyclass(name = "MapAnchor", module = "solid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyMapAnchor {
    /// Mutually consistent loops into the map that support the placement (distinct queries).
    #[pyo3(get)]
    pub loops: usize,
    /// Metres of the session's path they span.
    #[pyo3(get)]
    pub metres: f64,
    /// Id of the first supporting query.
    #[pyo3(get)]
    pub first_query: u32,
    /// Id of the latest supporting query.
    #[pyo3(get)]
    pub last_query: u32,
    /// Id of the first query of the stretch of the session's odometry (between breaks) that the
    /// anchor places.
    #[pyo3(get)]
    pub from_query: u32,
    /// Id of the last query of that stretch when a break of the odometry ended it; None: the
    /// stretch goes on (`transform` is the map -> odom of now).
    #[pyo3(get)]
    pub to_query: Option<u32>,
    inner: db::MapAnchor,
}

#[pymethods]
impl PyMapAnchor {
    /// T_map_world, (4, 4) float64: maps the session's pose frame ("odom") into the map's frame.
    #[getter]
    fn transform<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        pose_array(py, &self.inner.transform)
    }

    /// The spread of the supporting loops' placements about `transform`, (6, 6) float64
    /// ((rotation in radians, translation in metres) order), or None with fewer than two.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.inner.covariance.map(|m| matrix6(py, &m))
    }

    fn __repr__(&self) -> String {
        let t = &self.inner.transform;
        format!(
            "MapAnchor(loops={}, metres={:.1}, first_query={}, last_query={}, from_query={}, to_query={}, translation=[{:.3}, {:.3}, {:.3}])",
            self.loops,
            self.metres,
            self.first_query,
            self.last_query,
            self.from_query,
            self.to_query.map_or("None".into(), |q| q.to_string()),
            t[0][3],
            t[1][3],
            t[2][3]
        )
    }
}

impl From<db::MapAnchor> for PyMapAnchor {
    fn from(a: db::MapAnchor) -> Self {
        PyMapAnchor {
            loops: a.loops,
            metres: a.metres,
            first_query: a.first_query,
            last_query: a.last_query,
            from_query: a.from_query,
            to_query: a.to_query,
            inner: a,
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
    /// verification |t| / (1 + |t|) for a candidate that passed the gate and 1.5 + distance / 2
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
    /// Why the gate rejected it (None when accepted or not registered); a candidate whose stored
    /// cloud is corrupt or unreadable says so, naming the place.
    #[getter]
    fn rejection(&self) -> Option<String> {
        self.verification
            .and_then(|v| v.rejection)
            .map(|r| match r {
                Rejection::CorruptCloud => format!("place {}: {r}", self.id),
                _ => r.to_string(),
            })
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
    released: Vec<PyLoop>,
    /// "placed" or "revised" when this step placed the session in its map or revised the
    /// placement; None otherwise.
    #[pyo3(get)]
    pub placement: Option<&'static str>,
    /// Ids of the candidates this step's budget deferred (verify_step_points): not registered
    /// yet (unverified among candidates); the next steps register them, and a loop of theirs
    /// comes in the released list of the step that does. Empty when the step found its loop.
    #[pyo3(get)]
    pub deferred: Vec<u32>,
    pose: Option<[f64; 12]>,
    pose_source: Option<db::PoseSource>,
}

#[pymethods]
impl PyDetection {
    /// Loops of earlier queries reported late, in query order: loops into the map held until
    /// this step's placement (or revision) found them consistent with it, loops the
    /// neighbours' vouching waited for, loops the previous steps did not support that a later
    /// step's loop agrees with, and the loops of candidates a step's budget deferred to this
    /// one (verify_step_points).
    #[getter]
    fn released(&self) -> Vec<PyLoop> {
        self.released.clone()
    }

    /// T_world_sensor (4, 4) the step's checks used for the query: the caller's, or without
    /// one the detector's own odometry (None: neither).
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.pose.map(|p| {
            let mut t = [[0.0, 0.0, 0.0, 1.0]; 4];
            for (i, row) in t.iter_mut().take(3).enumerate() {
                row.copy_from_slice(&p[4 * i..4 * i + 4]);
            }
            pose_array(py, &t)
        })
    }

    /// Where `pose` came from: "given" (the caller's), "chained" (the scan registered with the
    /// previous keyframe, chained), "started" (the own odometry starts a frame here: the first
    /// scan, or the first after a link that failed); None without a pose.
    #[getter]
    fn pose_source(&self) -> Option<&'static str> {
        self.pose_source.map(|s| match s {
            db::PoseSource::Given => "given",
            db::PoseSource::Chained => "chained",
            db::PoseSource::Started => "started",
        })
    }

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
            released: d.released.into_iter().map(PyLoop::from).collect(),
            deferred: d.deferred,
            placement: d.placement.map(|p| match p {
                db::PlacementChange::Placed => "placed",
                db::PlacementChange::Revised => "revised",
            }),
            pose: d.pose,
            pose_source: d.pose_source,
        }
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
            cfg: *inner.map().config(),
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
            check_fingerprint(d.inner.fingerprint, self.cfg.fingerprint())?;
            return Ok(d.inner.clone());
        }
        describe_points(py, x, &self.cfg)
    }

    /// A Descriptor argument as itself, or points described (and their cloud prepared, when the
    /// detector verifies) with the GIL released.
    fn input(&self, py: Python<'_>, x: &Bound<'_, PyAny>) -> PyResult<Input> {
        if x.cast::<PyDescriptor>().is_ok() {
            return Ok(Input::Descriptor(self.descriptor(py, x)?));
        }
        let borrowed = borrow_points(x, "points")?;
        let slice = borrowed.slice();
        let cfg = self.cfg;
        let scan = py
            .detach(|| prepare_slice(&read(&self.inner), &slice, &cfg))
            .map_err(core_err)?;
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
    s: &PointSlice<'_>,
    cfg: &Config,
) -> Result<db::Scan, DbError> {
    let descriptor = describe_slice(s, cfg)?;
    let cloud = match *s {
        PointSlice::F32(v, stride) => det.prepare_cloud(solid_lidar::Points::new(v, stride)?)?,
        PointSlice::F64(v, stride) => det.prepare_cloud(solid_lidar::Points::new(v, stride)?)?,
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
        let inner = LoopDetector::new(cfg.inner, dc).map_err(core_err)?;
        Ok(PyLoopDetector::wrap(inner))
    }

    /// A detector over an existing database (a prior map), sharing its places instead of
    /// copying them: they are candidates from the first scan on and are never excluded as
    /// recent. The detector keeps its own scans apart from `database`, which stays as it was (an
    /// add to it afterwards does not reach the detector, and makes it its own copy first).
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
        let map = py.detach(|| database.shared_indexed()).map_err(core_err)?;
        let cfg = PyConfig::new_unchecked(*map.config());
        let dc = detector_config(&cfg, detector.as_deref(), Some(&kw))?;
        let inner = LoopDetector::with_map(map, dc).map_err(core_err)?;
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
        let t = args::timestamp(timestamp);
        let found = py
            .detach(|| {
                let mut det = write(&self.inner);
                match input {
                    Input::Descriptor(d) => det.detect(&d, t, pose),
                    Input::Scan(scan) => det.detect_scan(*scan, t, pose),
                }
            })
            .map_err(core_err)?;
        Ok(PyDetection::from(found))
    }

    /// `detect` for many scans in order, in one call: point arrays (described and prepared in
    /// parallel, `threads` workers, every core by default) or Descriptors (verification off).
    /// The GIL is released but for a moment between steps (Ctrl-C and `progress`). Every input
    /// is checked before the first is added: on error nothing is added.
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
                .map_err(core_err)?;
            return Ok(found.into_iter().map(PyDetection::from).collect());
        }
        let borrowed = borrow_scans(&items)?;
        let slices: Vec<PointSlice<'_>> = borrowed.iter().map(Borrowed::slice).collect();
        let cfg = self.cfg;
        let pool = batch_pool(threads, slices.len())?;
        let progress = progress
            .filter(|p| !p.is_none())
            .map(|p| p.clone().unbind());
        let mut stopped: Option<PyErr> = None;
        let found = py
            .detach(|| -> Result<Vec<db::Detection>, DbError> {
                let scans: Vec<db::Scan> = {
                    let det = read(&self.inner);
                    let prep = |s: &PointSlice<'_>| prepare_slice(&det, s, &cfg);
                    match batch_map(pool, &slices, prep) {
                        Ok(v) => v.into_iter().collect::<Result<_, _>>()?,
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
            .map_err(core_err)?;
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
                det.candidates(&d, k, args::timestamp(timestamp), pose)
            })
            .map_err(core_err)?;
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
            .map_err(core_err)?;
        Ok(found.map(PyLoop::from))
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.with(py, LoopDetector::len)
    }

    /// Every place (the prior map's, then the detector's scans) as a Database of its own: the
    /// prior map itself, shared, while the detector has added no scan; after that a copy of the
    /// descriptors made by this call (a loaded map's clouds stay in its file). Later steps do not
    /// reach it. `map` is the prior map alone, never copied.
    #[getter]
    fn database(&self, py: Python<'_>) -> PyResult<PyDatabase> {
        let db = self
            .with(py, LoopDetector::shared_database)
            .map_err(core_err)?;
        Ok(PyDatabase::share(db))
    }

    /// The prior map the detector was made over (`from_database`'s database as it was then;
    /// empty for a new detector), shared with the detector rather than copied.
    #[getter]
    fn map(&self, py: Python<'_>) -> PyDatabase {
        PyDatabase::share(self.with(py, |det| det.map().clone()))
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

    /// Where the session lies in the prior map, once loops into the map have placed it
    /// (docs/spec.md §8, placement: `placement_loops` mutually consistent loops over `placement_m`
    /// metres of its path); None before, and for a detector without a map or poses.
    #[getter]
    fn map_anchor(&self, py: Python<'_>) -> Option<PyMapAnchor> {
        self.with(py, LoopDetector::map_anchor)
            .map(PyMapAnchor::from)
    }

    /// The session's anchors in the map, one per stretch of its odometry between breaks that
    /// loops into the map placed, in order (`MapAnchor.from_query`); the last is `map_anchor`.
    /// Empty before the session is placed.
    #[getter]
    fn map_anchors(&self, py: Python<'_>) -> Vec<PyMapAnchor> {
        self.with(py, LoopDetector::map_anchors)
            .into_iter()
            .map(PyMapAnchor::from)
            .collect()
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
                .map(args::timestamp)
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

/// A (3, 3) rotation (or the rotation block of a (3, 4) or (4, 4) pose) as a [`Pose`] with no
/// translation; `name` names it in the error.
fn rotation_arg(r: &numpy::PyReadonlyArray2<'_, f64>, name: &str) -> PyResult<Pose> {
    let a = r.as_array();
    let (rows, cols) = a.dim();
    if rows < 3 || cols < 3 || rows > 4 || cols > 4 {
        return Err(SolidError::new_err(format!(
            "{name} must be a (3, 3) rotation or a (3, 4) / (4, 4) pose, got shape ({rows}, {cols})"
        )));
    }
    let mut p = IDENTITY;
    for (i, row) in p.iter_mut().take(3).enumerate() {
        for (j, v) in row.iter_mut().take(3).enumerate() {
            *v = a[[i, j]];
        }
    }
    if p.iter().flatten().any(|v| !v.is_finite()) {
        return Err(SolidError::new_err(format!(
            "{name} holds a NaN or infinity"
        )));
    }
    Ok(p)
}

/// `ω × arm`: the displacement of the query (in its frame) that a rotation drift at a constant
/// rate along the path `positions` ((N, 3) in the world, the place's first, the query's last)
/// predicts, `ω` the rotation vector of `r_expected · r_poseᵀ` and the arm the place's position
/// less the path's centroid, turned into the query's frame by `r_query`: the odometry check's
/// allowance for a rotation drift (docs/spec.md §8; `solid.commands.measured_drift` uses it).
#[pyfunction]
#[pyo3(name = "_drift_swing")]
fn drift_swing(
    r_expected: numpy::PyReadonlyArray2<'_, f64>,
    r_pose: numpy::PyReadonlyArray2<'_, f64>,
    positions: numpy::PyReadonlyArray2<'_, f64>,
    r_query: numpy::PyReadonlyArray2<'_, f64>,
) -> PyResult<[f64; 3]> {
    let expected = rotation_arg(&r_expected, "r_expected")?;
    let pose = rotation_arg(&r_pose, "r_pose")?;
    let q = rotation_arg(&r_query, "r_query")?;
    let p = positions.as_array();
    if p.ncols() != 3 {
        return Err(SolidError::new_err(format!(
            "positions must have shape (N, 3), got (N, {})",
            p.ncols()
        )));
    }
    if p.iter().any(|v| !v.is_finite()) {
        return Err(SolidError::new_err("positions hold a NaN or infinity"));
    }
    let query: [f64; 12] = core::array::from_fn(|k| q[k / 4][k % 4]);
    let path = p.rows().into_iter().map(|r| [r[0], r[1], r[2]]);
    let arm = detector::path_arm(path, &query);
    Ok(detector::rotation_displacement(&expected, &pose, &arm))
}

/// Registers the detector's classes on the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLoopDetector>()?;
    m.add_class::<PyLoop>()?;
    m.add_class::<PyMapAnchor>()?;
    m.add_class::<PyCandidate>()?;
    m.add_class::<PyDetection>()?;
    m.add("VERIFIED_THRESHOLD", db::VERIFIED_THRESHOLD)?;
    add_functions! { m, drift_swing }
    Ok(())
}
