//! Bindings of the readers' compiled parts: LZF decoding for PCD `binary_compressed` data.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use solid_lidar::lzf;

use crate::errors::{core_err, SolidError};

/// Decodes the LZF stream `data[start:stop]` into the caller's uint8 array `out` (C-contiguous,
/// writable) with the GIL released, and returns the number of bytes written. The stream may not
/// expand beyond `len(out)`.
#[pyfunction]
#[pyo3(signature = (data, out, start=0, stop=None))]
fn _lzf_decompress_into(
    py: Python<'_>,
    data: &[u8],
    out: &Bound<'_, PyArray1<u8>>,
    start: usize,
    stop: Option<usize>,
) -> PyResult<usize> {
    let stop = stop.unwrap_or(data.len());
    let src = data.get(start..stop).ok_or_else(|| {
        SolidError::new_err(format!(
            "data[{start}:{stop}] is out of range for {} B",
            data.len()
        ))
    })?;
    let mut rw = out
        .try_readwrite()
        .map_err(|e| SolidError::new_err(format!("out: {e}")))?;
    let dst = rw
        .as_slice_mut()
        .map_err(|_| SolidError::new_err("out must be a C-contiguous uint8 array"))?;
    py.detach(|| lzf::decompress_into(src, dst))
        .map_err(core_err)
}

/// The most bytes an LZF stream of `n` bytes can decode to.
#[pyfunction]
fn _lzf_max_decompressed_len(n: usize) -> usize {
    lzf::max_decompressed_len(n)
}

/// Registers the readers' functions on the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    add_functions! { m, _lzf_decompress_into, _lzf_max_decompressed_len }
    Ok(())
}
