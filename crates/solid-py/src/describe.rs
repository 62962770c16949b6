//! Bindings of the descriptor (`solid_lidar::describe` and `compare`): `Descriptor`, `describe`,
//! `describe_batch`, `distance`, `heading` and the presets.

use std::cell::RefCell;

use numpy::PyArray1;
use pyo3::exceptions::{PyMemoryError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use solid_lidar::pool;
use solid_lidar::{Config, Describer, Descriptor, Error, Points, Stats, PRESETS};

use crate::args;
use crate::arrays::{borrow_points, borrow_scans, Borrowed, PointSlice};
use crate::config::PyConfig;
use crate::errors::{core_err, SolidError};

/// One scan's SOLiD descriptor, exposed as `solid.Descriptor` (immutable).
#[pyclass(name = "Descriptor", module = "solid", frozen)]
pub struct PyDescriptor {
    /// The core descriptor (vectors, counts, config fingerprint).
    pub inner: Descriptor,
    /// The config that produced it.
    pub cfg: Config,
}

impl PyDescriptor {
    /// Wraps a core descriptor made with `cfg`.
    pub fn new(inner: Descriptor, cfg: Config) -> Self {
        PyDescriptor { inner, cfg }
    }
}

/// Checks that two descriptors can be compared: same config.
pub(crate) fn comparable(a: &PyDescriptor, b: &PyDescriptor) -> PyResult<()> {
    if a.cfg != b.cfg {
        return Err(SolidError::new_err(format!(
            "descriptors come from different configs ({:?} vs {:?}); describe both scans with the same SolidConfig",
            PyConfig::new_unchecked(a.cfg).repr(),
            PyConfig::new_unchecked(b.cfg).repr()
        )));
    }
    Ok(())
}

fn vector_from_py(name: &str, v: &Bound<'_, PyAny>, len: usize) -> PyResult<Vec<f32>> {
    let arr: Vec<f32> = v
        .extract()
        .map_err(|_| PyTypeError::new_err(format!("{name} must be a 1-D sequence of floats")))?;
    if arr.len() != len {
        return Err(SolidError::new_err(format!(
            "{name} has length {}, the config needs {len}",
            arr.len()
        )));
    }
    if let Some(bad) = arr.iter().find(|x| !x.is_finite() || **x < 0.0) {
        return Err(SolidError::new_err(format!(
            "{name} must be finite and non-negative, found {bad}"
        )));
    }
    Ok(arr)
}

#[pymethods]
impl PyDescriptor {
    /// Rebuilds a descriptor from stored vectors (for instance read back from disk).
    #[new]
    #[pyo3(signature = (r, a, config, n_points=0, n_in_range=0, n_kept=0))]
    fn py_new(
        r: &Bound<'_, PyAny>,
        a: &Bound<'_, PyAny>,
        config: &PyConfig,
        #[pyo3(from_py_with = args::n_points)] n_points: usize,
        #[pyo3(from_py_with = args::n_in_range)] n_in_range: usize,
        #[pyo3(from_py_with = args::n_kept)] n_kept: usize,
    ) -> PyResult<Self> {
        let cfg = config.inner;
        let inner = Descriptor {
            r: vector_from_py("r", r, cfg.n_range)?,
            a: vector_from_py("a", a, cfg.n_azimuth)?,
            stats: Stats {
                n_points,
                n_in_range,
                n_kept,
            },
            fingerprint: cfg.fingerprint(),
        };
        Ok(PyDescriptor { inner, cfg })
    }

    /// R-SOLiD (float32, length n_range).
    #[getter]
    fn r<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        PyArray1::from_slice(py, &self.inner.r)
    }
    /// A-SOLiD (float32, length n_azimuth).
    #[getter]
    fn a<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        PyArray1::from_slice(py, &self.inner.a)
    }
    #[getter]
    fn n_points(&self) -> usize {
        self.inner.stats.n_points
    }
    #[getter]
    fn n_in_range(&self) -> usize {
        self.inner.stats.n_in_range
    }
    #[getter]
    fn n_kept(&self) -> usize {
        self.inner.stats.n_kept
    }
    #[getter]
    fn config(&self) -> PyConfig {
        PyConfig::new_unchecked(self.cfg)
    }

    /// Cosine distance to `other` (docs/spec.md §3).
    fn distance(&self, other: &PyDescriptor) -> PyResult<f64> {
        distance(self, other)
    }

    /// Heading of this scan relative to `candidate`, degrees in (-180, 180] (docs/spec.md §3).
    #[pyo3(signature = (candidate, refine=true))]
    fn heading(&self, candidate: &PyDescriptor, refine: bool) -> PyResult<f64> {
        heading(self, candidate, refine)
    }

    fn __repr__(&self) -> String {
        format!(
            "Descriptor(n_range={}, n_azimuth={}, n_points={}, n_in_range={}, n_kept={})",
            self.inner.r.len(),
            self.inner.a.len(),
            self.inner.stats.n_points,
            self.inner.stats.n_in_range,
            self.inner.stats.n_kept
        )
    }

    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let d = slf.get();
        let cls = py.import("solid._solid")?.getattr("Descriptor")?;
        let args = (
            d.r(py),
            d.a(py),
            PyConfig::new_unchecked(d.cfg),
            d.inner.stats.n_points,
            d.inner.stats.n_in_range,
            d.inner.stats.n_kept,
        )
            .into_pyobject(py)?;
        Ok((cls, args))
    }
}

/// Scratch buffers above this size are freed after a call instead of kept for the next one.
const KEEP_SCRATCH_BYTES: usize = 64 << 20;

thread_local! {
    static DESCRIBER: RefCell<Option<Describer>> = const { RefCell::new(None) };
}

/// Describes `points` with a per-thread [`Describer`] so repeated calls reuse their scratch.
pub fn describe_slice(points: &PointSlice<'_>, cfg: &Config) -> Result<Descriptor, Error> {
    DESCRIBER.with(|cell| {
        let mut slot = cell.borrow_mut();
        if slot.as_ref().is_none_or(|d| d.config() != cfg) {
            *slot = Some(Describer::new(*cfg)?);
        }
        let describer = slot.as_mut().expect("set above");
        let out = match *points {
            PointSlice::F32(s, stride) => describer.describe(Points::new(s, stride)?),
            PointSlice::F64(s, stride) => describer.describe(Points::new(s, stride)?),
        };
        if describer.scratch_bytes() > KEEP_SCRATCH_BYTES {
            *slot = None;
        }
        out
    })
}

/// Checks `points`, then describes them with the GIL released.
pub fn describe_points(
    py: Python<'_>,
    points: &Bound<'_, PyAny>,
    cfg: &Config,
) -> PyResult<Descriptor> {
    let borrowed = borrow_points(points, "points")?;
    let slice = borrowed.slice();
    py.detach(|| describe_slice(&slice, cfg)).map_err(core_err)
}

/// Computes the SOLiD descriptor of one scan.
#[pyfunction]
fn describe(
    py: Python<'_>,
    points: &Bound<'_, PyAny>,
    config: &PyConfig,
) -> PyResult<PyDescriptor> {
    let d = describe_points(py, points, &config.inner)?;
    Ok(PyDescriptor::new(d, config.inner))
}

/// The persistent pool of [`describe_batch`] (and the detector's batch) for `jobs` jobs asked to
/// run on `threads` threads (None or 0: one per core), as the core sizes it
/// ([`solid_lidar::pool::batch_threads`]); `None`: run on this thread.
///
/// A pool is built on first use and kept: a batch starts no thread, and each worker keeps its
/// scratch buffers from one batch to the next (the thread-local [`Describer`] of
/// [`describe_slice`]). rayon rather than a pool of our own: its scoped parallel iterators run
/// closures that borrow the numpy arrays without `unsafe`, it balances uneven scans by work
/// stealing and hands a worker's panic back to the caller, all of it well tested. The core
/// crate keeps the pools: a process forked by Python's multiprocessing starts its own, and
/// finding one takes no lock that a fork could leave held.
pub(crate) fn batch_pool(
    threads: Option<usize>,
    jobs: usize,
) -> PyResult<Option<&'static rayon::ThreadPool>> {
    let Some(threads) = pool::batch_threads(threads.unwrap_or(pool::ONE_PER_CORE), jobs) else {
        return Ok(None);
    };
    pool::pool_of("solid-describe", threads)
        .map(Some)
        .map_err(|e| SolidError::new_err(format!("cannot start describe workers: {e}")))
}

/// `f` of every item, in order: on `pool`'s workers ([`batch_pool`]), else on this thread; a
/// chunk at a time, and between chunks the GIL is taken back briefly to check for signals, so
/// that Ctrl-C stops a long batch within a chunk's time (`Err`: the signal handler's exception).
/// Call it with the GIL released.
pub(crate) fn batch_map<T: Sync, R: Send>(
    pool: Option<&rayon::ThreadPool>,
    items: &[T],
    f: impl Fn(&T) -> R + Sync + Send,
) -> PyResult<Vec<R>> {
    use rayon::prelude::*;
    // A few items per worker: enough to balance uneven scans, short enough to answer a signal.
    let chunk = 4 * pool.map_or(1, rayon::ThreadPool::current_num_threads);
    let mut out = Vec::new();
    out.try_reserve_exact(items.len())
        .map_err(|_| PyMemoryError::new_err("no memory for the batch's results"))?;
    for part in items.chunks(chunk) {
        Python::attach(|py| py.check_signals())?;
        match pool {
            Some(p) => out.extend(p.install(|| part.par_iter().map(&f).collect::<Vec<_>>())),
            None => out.extend(part.iter().map(&f)),
        }
    }
    Ok(out)
}

/// Describes many scans in parallel (every core by default), GIL released for the batch but
/// for a signal check between chunks (Ctrl-C raises KeyboardInterrupt within a chunk's time).
#[pyfunction]
#[pyo3(signature = (scans, config, threads=None))]
fn describe_batch(
    py: Python<'_>,
    scans: &Bound<'_, PyAny>,
    config: &PyConfig,
    #[pyo3(from_py_with = args::threads)] threads: Option<usize>,
) -> PyResult<Vec<PyDescriptor>> {
    let items: Vec<Bound<'_, PyAny>> = if let Ok(list) = scans.cast::<PyList>() {
        list.iter().collect()
    } else {
        scans
            .try_iter()
            .map_err(|_| {
                PyTypeError::new_err("scans must be a list (or iterable) of numpy arrays")
            })?
            .collect::<PyResult<_>>()?
    };
    let borrowed = borrow_scans(&items)?;
    let slices: Vec<PointSlice<'_>> = borrowed.iter().map(Borrowed::slice).collect();
    let cfg = config.inner;
    let pool = batch_pool(threads, slices.len())?;
    py.detach(|| batch_map(pool, &slices, |s| describe_slice(s, &cfg)))?
        .into_iter()
        .map(|r| r.map(|d| PyDescriptor::new(d, cfg)).map_err(core_err))
        .collect()
}

/// Cosine distance between two descriptors' R-SOLiDs (docs/spec.md §3), in [0, 1].
#[pyfunction]
fn distance(a: &PyDescriptor, b: &PyDescriptor) -> PyResult<f64> {
    comparable(a, b)?;
    a.inner.distance(&b.inner).map_err(core_err)
}

/// Heading of `query` relative to `candidate` in degrees, (-180, 180] (docs/spec.md §3): the query scan
/// is the candidate rotated by this angle counter-clockwise about +z.
#[pyfunction]
#[pyo3(signature = (query, candidate, refine=true))]
fn heading(query: &PyDescriptor, candidate: &PyDescriptor, refine: bool) -> PyResult<f64> {
    comparable(query, candidate)?;
    Ok(query
        .inner
        .heading(&candidate.inner, refine)
        .map_err(core_err)?
        .degrees)
}

/// Every sensor preset (docs/spec.md §4) by name.
#[pyfunction]
fn presets<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for p in PRESETS.iter() {
        d.set_item(
            p.name,
            PyConfig {
                inner: p.config,
                base_preset: Some(p),
            },
        )?;
    }
    Ok(d)
}

/// The sensor each preset describes, by preset name.
#[pyfunction]
fn preset_sensors<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for p in PRESETS {
        d.set_item(p.name, p.sensor)?;
    }
    Ok(d)
}

/// Registers the descriptor's class and functions on the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDescriptor>()?;
    add_functions! { m, describe, describe_batch, distance, heading, presets, preset_sensors }
    Ok(())
}
