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
    Ok(())
}
