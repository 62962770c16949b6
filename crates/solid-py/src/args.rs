//! Argument checks shared by the bindings: integers that are never bools and never overflow
//! into an `OverflowError`, numbers that are not bools, and allocations that fail with
//! `MemoryError` instead of aborting the interpreter.

use pyo3::exceptions::{PyMemoryError, PyOverflowError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyByteArray, PyBytes, PyMemoryView};

use crate::errors::ConfigError;

/// An integer argument `name` in `lo..=hi`. A bool or anything that is not an integer is a
/// `TypeError`; an integer out of the range (negative, say, or beyond 64 bits) is a
/// `ConfigError` naming the argument and what is valid, never an `OverflowError`.
pub fn int_arg<T: TryFrom<i128>>(
    v: &Bound<'_, PyAny>,
    name: &str,
    lo: i128,
    hi: i128,
) -> PyResult<T> {
    if v.is_instance_of::<PyBool>() {
        return Err(PyTypeError::new_err(format!(
            "{name} must be an integer, not a bool"
        )));
    }
    let expected = || {
        let range = if hi >= i128::from(u32::MAX) {
            format!(">= {lo}")
        } else {
            format!("in {lo}..={hi}")
        };
        ConfigError::new_err(format!(
            "invalid {name} = {}: expected an integer {range}",
            v.str().map(|s| s.to_string()).unwrap_or_default()
        ))
    };
    let i: i128 = match v.extract() {
        Ok(i) => i,
        Err(e) if e.is_instance_of::<PyOverflowError>(v.py()) => return Err(expected()),
        Err(_) => {
            return Err(PyTypeError::new_err(format!(
                "{name} must be an integer, got {}",
                type_name(v)
            )))
        }
    };
    if i < lo || i > hi {
        return Err(expected());
    }
    T::try_from(i).map_err(|_| expected())
}

/// [`int_arg`] for an optional argument (`None` or absent: `None`).
pub fn opt_int_arg<T: TryFrom<i128>>(
    v: Option<&Bound<'_, PyAny>>,
    name: &str,
    lo: i128,
    hi: i128,
) -> PyResult<Option<T>> {
    match v {
        Some(v) if !v.is_none() => int_arg(v, name, lo, hi).map(Some),
        _ => Ok(None),
    }
}

/// The name of `v`'s type, for messages.
pub fn type_name(v: &Bound<'_, PyAny>) -> String {
    v.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_default()
}

/// A timestamp argument: NaN for none.
pub fn timestamp(t: Option<f64>) -> f64 {
    t.unwrap_or(f64::NAN)
}

/// An empty vector with room for `n` elements; `MemoryError` (naming `what`) when that much
/// cannot be allocated, instead of aborting the interpreter.
pub fn try_vec<T>(n: usize, what: &str) -> PyResult<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| {
        PyMemoryError::new_err(format!(
            "out of memory: could not allocate {} bytes for {what}",
            n.saturating_mul(std::mem::size_of::<T>())
        ))
    })?;
    Ok(v)
}

/// A copy of `v` in a vector allocated with [`try_vec`].
pub fn try_copy<T: Clone>(v: &[T], what: &str) -> PyResult<Vec<T>> {
    let mut out = try_vec(v.len(), what)?;
    out.extend_from_slice(v);
    Ok(out)
}

/// A real-valued parameter: a number (an int or a float), not a bool.
pub fn float_param(v: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    if v.is_instance_of::<PyBool>() {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a number, not a bool"
        )));
    }
    v.extract::<f64>()
        .map_err(|_| PyTypeError::new_err(format!("{name} must be a number, got {}", type_name(v))))
}

/// `v` as a `bytes` object: `bytes` itself, or a copy of a `bytearray` or a `memoryview`
/// (made by Python, so that running out of memory is a `MemoryError`). Anything else is a
/// `TypeError` naming `name`.
pub fn bytes_arg<'py>(v: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyBytes>> {
    if let Ok(b) = v.cast::<PyBytes>() {
        return Ok(b.clone());
    }
    if v.is_instance_of::<PyByteArray>() || v.is_instance_of::<PyMemoryView>() {
        return Ok(v.py().get_type::<PyBytes>().call1((v,))?.cast_into()?);
    }
    Err(PyTypeError::new_err(format!(
        "{name} must be bytes, bytearray or memoryview, got {}",
        type_name(v)
    )))
}

/// Named extractors for `#[pyo3(from_py_with = ...)]`: each checks one integer argument with
/// [`int_arg`] (the optional ones take `None` as "not given").
macro_rules! int_args {
    ($($(#[$doc:meta])* $f:ident: $t:ty = $name:literal in $lo:expr, $hi:expr;)*) => {$(
        $(#[$doc])*
        pub fn $f(v: &Bound<'_, PyAny>) -> PyResult<$t> {
            int_arg(v, $name, $lo as i128, $hi as i128)
        }
    )*};
}

macro_rules! opt_int_args {
    ($($(#[$doc:meta])* $f:ident: $t:ty = $name:literal in $lo:expr, $hi:expr;)*) => {$(
        $(#[$doc])*
        pub fn $f(v: &Bound<'_, PyAny>) -> PyResult<Option<$t>> {
            opt_int_arg(Some(v), $name, $lo as i128, $hi as i128)
        }
    )*};
}

int_args! {
    /// `Descriptor(n_points=...)`.
    n_points: usize = "n_points" in 0, usize::MAX;
    /// `Descriptor(n_in_range=...)`.
    n_in_range: usize = "n_in_range" in 0, usize::MAX;
    /// `Descriptor(n_kept=...)`.
    n_kept: usize = "n_kept" in 0, usize::MAX;
    /// Number of neighbours of a search.
    k: usize = "k" in 0, usize::MAX;
    /// Most recent entries a search skips.
    exclude_recent: usize = "exclude_recent" in 0, usize::MAX;
    /// A session number.
    session: u32 = "session" in 0, u32::MAX;
    /// A seed.
    seed: u64 = "seed" in 0, u64::MAX;
    /// A frame index.
    frame: u64 = "frame" in 0, u64::MAX;
    /// The first frame index of a sequence.
    first_frame: u64 = "first_frame" in 0, u64::MAX;
    /// A rank (recall@n).
    n: usize = "n" in 0, usize::MAX;
    /// Blocks of a world (the simulator checks the range).
    blocks: usize = "blocks" in 0, usize::MAX;
    /// Offset bits of the cloud wire form (the core checks the range).
    bits: u8 = "bits" in 0, u8::MAX;
}

opt_int_args! {
    /// Worker threads (None or 0: one per core, `solid_lidar::pool::ONE_PER_CORE`).
    threads: usize = "threads" in 0, usize::MAX;
    /// Points per frame of the rosette sensor.
    points: usize = "points" in 0, usize::MAX;
    /// Number of candidates (None: the detector's top_k).
    opt_k: usize = "k" in 0, usize::MAX;
}
