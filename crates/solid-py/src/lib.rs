//! Python bindings of `solid-lidar`: argument checks, GIL release and error mapping only; the
//! algorithm lives in the core crate.

use std::cell::RefCell;

use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyMemoryError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use solid_lidar::{Config, Describer, Descriptor, Error, Points, Stats, PRESETS};

pub use config::PyConfig;

mod args;
mod config;
mod engine;
mod eval;
mod io;
mod reg;
mod sim;

create_exception!(
    solid,
    SolidError,
    PyValueError,
    "Base class of the errors raised by solid (a ValueError): ConfigError for invalid parameters and argument values, DatabaseError for corrupt or foreign files and places, SolidError itself for data of the wrong shape."
);
create_exception!(
    solid,
    ConfigError,
    SolidError,
    "An invalid configuration parameter, argument value or preset name."
);

/// Maps a core error to the matching Python exception.
pub fn core_err(e: Error) -> PyErr {
    match e {
        Error::InvalidParameter { .. } | Error::UnknownPreset => {
            ConfigError::new_err(e.to_string())
        }
        Error::OutOfMemory { .. } => PyMemoryError::new_err(e.to_string()),
        _ => SolidError::new_err(e.to_string()),
    }
}

/// Maps an I/O error to the matching `OSError` subclass, with `errno`, `strerror` and (when
/// known) `filename` set.
pub fn io_err(source: &std::io::Error, file: Option<String>) -> PyErr {
    use pyo3::exceptions::{
        PyFileExistsError, PyFileNotFoundError, PyIsADirectoryError, PyNotADirectoryError,
        PyOSError, PyPermissionError,
    };
    let args = (source.raw_os_error().unwrap_or(0), source.to_string(), file);
    match source.kind() {
        std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(args),
        std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(args),
        std::io::ErrorKind::IsADirectory => PyIsADirectoryError::new_err(args),
        std::io::ErrorKind::NotADirectory => PyNotADirectoryError::new_err(args),
        std::io::ErrorKind::AlreadyExists => PyFileExistsError::new_err(args),
        std::io::ErrorKind::OutOfMemory => PyMemoryError::new_err(source.to_string()),
        _ => PyOSError::new_err(args),
    }
}

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

/// A point array checked and borrowed for reading without the GIL.
pub enum PointSlice<'a> {
    /// float32 rows.
    F32(&'a [f32], usize),
    /// float64 rows.
    F64(&'a [f64], usize),
}

impl<'a> PointSlice<'a> {
    /// The values as `f32` (float32 read in place, float64 rounded into a copy).
    pub fn to_f32(&self) -> std::borrow::Cow<'a, [f32]> {
        match *self {
            PointSlice::F32(s, _) => std::borrow::Cow::Borrowed(s),
            PointSlice::F64(s, _) => s.iter().map(|&v| v as f32).collect(),
        }
    }
}

/// Keeps the numpy read-only borrow alive while its slice is used.
pub enum Borrowed<'py> {
    /// float32 array.
    F32(numpy::PyReadonlyArray2<'py, f32>),
    /// float64 array.
    F64(numpy::PyReadonlyArray2<'py, f64>),
}

impl Borrowed<'_> {
    /// Number of rows.
    pub fn rows(&self) -> usize {
        match self {
            Borrowed::F32(a) => a.shape()[0],
            Borrowed::F64(a) => a.shape()[0],
        }
    }

    /// The flat slice and its stride.
    pub fn slice(&self) -> PointSlice<'_> {
        match self {
            // Contiguity and alignment were checked in `borrow_2d`.
            Borrowed::F32(a) => {
                PointSlice::F32(a.as_slice().expect("checked C-contiguous"), a.shape()[1])
            }
            Borrowed::F64(a) => {
                PointSlice::F64(a.as_slice().expect("checked C-contiguous"), a.shape()[1])
            }
        }
    }
}

/// Checks a points argument (numpy, 2-D, ≥ 3 columns, float32/float64, C-contiguous, aligned)
/// and borrows it read-only. `what` names the argument in messages.
pub fn borrow_points<'py>(points: &Bound<'py, PyAny>, what: &str) -> PyResult<Borrowed<'py>> {
    borrow_2d(points, what, Columns::AtLeast(3))
}

/// The columns a 2-D array argument must have.
#[derive(Clone, Copy)]
pub enum Columns {
    /// At least this many (points: x, y, z first).
    AtLeast(usize),
    /// Exactly this many (descriptor rows).
    Exactly(usize),
}

/// Checks a 2-D float32/float64 array argument (columns, C-contiguity, alignment) and borrows
/// it read-only. `what` names the argument in messages.
pub fn borrow_2d<'py>(
    points: &Bound<'py, PyAny>,
    what: &str,
    columns: Columns,
) -> PyResult<Borrowed<'py>> {
    let want = match columns {
        Columns::AtLeast(3) => String::from("(N, >=3) with x, y, z first"),
        Columns::AtLeast(c) => format!("(N, >={c})"),
        Columns::Exactly(c) => format!("(N, {c})"),
    };
    let arr = points.cast::<PyUntypedArray>().map_err(|_| {
        let ty = points.get_type().name().map(|n| n.to_string()).unwrap_or_default();
        PyTypeError::new_err(format!(
            "{what} must be a numpy array of shape {want}, got {ty}; convert with np.asarray({what}, dtype=np.float32)"
        ))
    })?;
    let shape = arr.shape().to_vec();
    let fits = shape.len() == 2
        && match columns {
            Columns::AtLeast(c) => shape[1] >= c,
            Columns::Exactly(c) => shape[1] == c,
        };
    if !fits {
        return Err(SolidError::new_err(format!(
            "{what} must have shape {want}; got shape {}",
            fmt_shape(&shape)
        )));
    }
    let borrowed = if let Ok(a) = points.cast::<PyArray2<f32>>() {
        Borrowed::F32(
            a.try_readonly()
                .map_err(|e| SolidError::new_err(format!("{what}: {e}")))?,
        )
    } else if let Ok(a) = points.cast::<PyArray2<f64>>() {
        Borrowed::F64(
            a.try_readonly()
                .map_err(|e| SolidError::new_err(format!("{what}: {e}")))?,
        )
    } else {
        let dt = arr.dtype().str().map(|s| s.to_string()).unwrap_or_default();
        return Err(PyTypeError::new_err(format!(
            "{what} has dtype {dt}; solid reads native float32 or float64: convert with {what}.astype(np.float32)"
        )));
    };
    if !arr.is_c_contiguous() {
        return Err(SolidError::new_err(format!(
            "{what} is not C-contiguous (Fortran-ordered or a strided view); reading it in place would be wrong: pass np.ascontiguousarray({what})"
        )));
    }
    let (ptr, align) = match &borrowed {
        Borrowed::F32(a) => (a.as_array().as_ptr() as usize, std::mem::align_of::<f32>()),
        Borrowed::F64(a) => (a.as_array().as_ptr() as usize, std::mem::align_of::<f64>()),
    };
    if ptr % align != 0 {
        return Err(SolidError::new_err(format!(
            "{what} is not aligned for its dtype; pass np.array({what}) (an aligned copy)"
        )));
    }
    Ok(borrowed)
}

fn fmt_shape(shape: &[usize]) -> String {
    let parts: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    if parts.len() == 1 {
        format!("({},)", parts[0])
    } else {
        format!("({})", parts.join(", "))
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

/// The persistent pool of `threads` workers of [`describe_batch`] (and the detector's batch) in
/// this process.
///
/// A pool is built on first use and kept: a batch starts no thread, and each worker keeps its
/// scratch buffers from one batch to the next (the thread-local [`Describer`] of
/// [`describe_slice`]). rayon rather than a pool of our own: its scoped parallel iterators run
/// closures that borrow the numpy arrays without `unsafe`, it balances uneven scans by work
/// stealing and hands a worker's panic back to the caller, all of it well tested. The core
/// crate keeps the pools: a process forked by Python's multiprocessing starts its own, and
/// finding one takes no lock that a fork could leave held.
fn pool(threads: usize) -> PyResult<&'static rayon::ThreadPool> {
    solid_lidar::pool::pool_of("solid-describe", threads)
        .map_err(|e| SolidError::new_err(format!("cannot start describe workers: {e}")))
}

/// The workers of a batch of `scans` scans asked to run on `threads` threads (None: every
/// core): at most one per core (more only adds switching), and `None` when one thread does (a
/// single scan or a single thread). The pool has the threads asked for even when there are
/// fewer scans (the scans then take fewer of them): one pool per size asked, not one per batch
/// length. `threads = 0` is refused.
pub(crate) fn batch_pool(
    threads: Option<usize>,
    scans: usize,
) -> PyResult<Option<&'static rayon::ThreadPool>> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = match threads {
        Some(0) => {
            return Err(ConfigError::new_err(
                "invalid threads = 0: expected at least 1 (or None for every core)",
            ))
        }
        Some(t) => t.min(cores),
        None => cores,
    };
    if threads.min(scans) > 1 {
        pool(threads).map(Some)
    } else {
        Ok(None)
    }
}

/// `f` of every item, on `pool` (or this thread), a chunk at a time: between chunks the GIL is
/// taken back briefly to check for signals, so that Ctrl-C stops a long batch within a chunk's
/// time (`Err`: the signal handler's exception). Call it with the GIL released.
pub(crate) fn map_interruptible<T: Sync, R: Send>(
    items: &[T],
    pool: Option<&rayon::ThreadPool>,
    f: impl Fn(&T) -> R + Sync,
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
    let borrowed = items
        .iter()
        .enumerate()
        .map(|(i, p)| borrow_points(p, &format!("scans[{i}]")))
        .collect::<PyResult<Vec<_>>>()?;
    let slices: Vec<PointSlice<'_>> = borrowed.iter().map(Borrowed::slice).collect();
    let cfg = config.inner;
    let pool = batch_pool(threads, slices.len())?;
    let results = py.detach(|| map_interruptible(&slices, pool, |s| describe_slice(s, &cfg)))?;
    results
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
    for p in PRESETS {
        d.set_item(
            p.name,
            PyConfig {
                inner: p.config,
                base_preset: Some(p.name),
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

#[pymodule(gil_used = false)]
fn _solid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("SolidError", py.get_type::<SolidError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    config::register(m)?;
    m.add_class::<PyDescriptor>()?;
    m.add_function(wrap_pyfunction!(describe, m)?)?;
    m.add_function(wrap_pyfunction!(describe_batch, m)?)?;
    m.add_function(wrap_pyfunction!(distance, m)?)?;
    m.add_function(wrap_pyfunction!(heading, m)?)?;
    m.add_function(wrap_pyfunction!(presets, m)?)?;
    m.add_function(wrap_pyfunction!(preset_sensors, m)?)?;
    engine::register(m)?;
    eval::register(m)?;
    reg::register_module(m)?;
    sim::register(m)?;
    io::register(m)?;
    Ok(())
}
