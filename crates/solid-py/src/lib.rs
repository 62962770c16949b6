//! Python bindings of `solid-lidar`: argument checks, GIL release and error mapping only; the
//! algorithm lives in the core crate. One file per core module, plus `errors` (the exceptions
//! and the mapping of core errors to them), `arrays` (numpy in and out) and `args` (scalar
//! arguments).

use pyo3::prelude::*;

pub use config::PyConfig;
// The parameter classes (config.rs) name these from the crate root.
pub(crate) use errors::{core_err, ConfigError, SolidError};

/// Adds the `#[pyfunction]`s named to the module `m` (in a `PyResult` function).
macro_rules! add_functions {
    ($m:expr, $($f:ident),+ $(,)?) => {
        $($m.add_function(pyo3::wrap_pyfunction!($f, $m)?)?;)+
    };
}

mod args;
mod arrays;
mod config;
mod database;
mod describe;
mod detector;
mod errors;
mod eval;
mod io;
mod reg;
mod sim;

#[pymodule(gil_used = false)]
fn _solid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("SolidError", py.get_type::<SolidError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("DatabaseError", py.get_type::<errors::DatabaseError>())?;
    config::register(m)?;
    describe::register(m)?;
    database::register(m)?;
    detector::register(m)?;
    eval::register(m)?;
    reg::register_module(m)?;
    sim::register(m)?;
    io::register(m)?;
    drop_private_names(m)
}

/// Leaves the private names (`_name`: helpers of the Python package, its tests and the
/// benchmarks, outside the API) out of the module's `__all__`, which pyo3 fills with every name
/// added; dunders (`__version__`) stay. The stub's `__all__` (stubs/00_module.pyi) lists the
/// same names (`tools/stubgen.py` rejects a private one; stubtest compares them).
fn drop_private_names(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let mut public = Vec::new();
    for name in m.index()?.iter() {
        let n: String = name.extract()?;
        if !n.starts_with('_') || (n.starts_with("__") && n.ends_with("__")) {
            public.push(n);
        }
    }
    m.setattr("__all__", public)
}
