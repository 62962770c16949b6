//! The exceptions of `solid` and the one mapping of the core crates' errors to them: each layer's
//! error (database, registration, simulator, LZF) maps its own cases and hands the core's
//! [`Error`] on to the same rule.

use pyo3::create_exception;
use pyo3::exceptions::{
    PyFileExistsError, PyFileNotFoundError, PyIsADirectoryError, PyMemoryError,
    PyNotADirectoryError, PyOSError, PyPermissionError, PyValueError,
};
use pyo3::PyErr;
use solid_lidar::db::DbError;
use solid_lidar::lzf::LzfError;
use solid_lidar::reg::RegError;
use solid_lidar::Error;
use solid_lidar_sim::SimError;

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
create_exception!(
    solid,
    DatabaseError,
    SolidError,
    "A database, place or loop-detector error: config mismatch, corrupt or foreign file."
);

/// An error of the core crates that becomes a Python exception.
pub trait ToPyErr {
    /// The exception that names this error.
    fn to_py_err(self) -> PyErr;
}

/// `e` as its Python exception (for `map_err`).
pub fn core_err(e: impl ToPyErr) -> PyErr {
    e.to_py_err()
}

/// Invalid parameters and preset names are `ConfigError`, exhausted memory `MemoryError`, the rest
/// (data of the wrong shape) `SolidError`.
impl ToPyErr for Error {
    fn to_py_err(self) -> PyErr {
        match self {
            Error::InvalidParameter { .. } | Error::UnknownPreset => {
                ConfigError::new_err(self.to_string())
            }
            Error::OutOfMemory { .. } => PyMemoryError::new_err(self.to_string()),
            _ => SolidError::new_err(self.to_string()),
        }
    }
}

/// I/O errors are the matching `OSError` (with `filename`), everything the database itself
/// refuses (a config mismatch, a corrupt or foreign file) `DatabaseError`, a merge's bad anchors
/// (argument values) `ConfigError`.
impl ToPyErr for DbError {
    fn to_py_err(self) -> PyErr {
        match self {
            DbError::Core(c) => c.to_py_err(),
            DbError::AnchorCount { .. } | DbError::BadAnchor { .. } => {
                ConfigError::new_err(self.to_string())
            }
            DbError::Io { file, source } => io_err(&source, Some(file)),
            DbError::OutOfMemory => PyMemoryError::new_err(
                "out of memory: the database operation could not allocate (nothing was changed)",
            ),
            other => DatabaseError::new_err(other.to_string()),
        }
    }
}

/// Corrupt or foreign cloud bytes are a `DatabaseError`, as for a database or a place.
impl ToPyErr for RegError {
    fn to_py_err(self) -> PyErr {
        match self {
            RegError::Core(c) => c.to_py_err(),
            RegError::Format { .. } => DatabaseError::new_err(self.to_string()),
            other => SolidError::new_err(other.to_string()),
        }
    }
}

/// Invalid parameters and unknown names are `ConfigError`.
impl ToPyErr for SimError {
    fn to_py_err(self) -> PyErr {
        match self {
            SimError::Io(io) => io_err(&io, None),
            SimError::OutOfMemory { .. } => PyMemoryError::new_err(self.to_string()),
            other => ConfigError::new_err(other.to_string()),
        }
    }
}

/// A stream that does not decode is data of the wrong shape.
impl ToPyErr for LzfError {
    fn to_py_err(self) -> PyErr {
        SolidError::new_err(self.to_string())
    }
}

/// An array shape that does not match its data (cannot happen: the shapes come from the data).
impl ToPyErr for numpy::ndarray::ShapeError {
    fn to_py_err(self) -> PyErr {
        SolidError::new_err(self.to_string())
    }
}

/// POSIX's "File exists" (the same number on Linux, the BSDs, macOS and Windows' C runtime).
const EEXIST: i32 = 17;

/// The `OSError` subclass of an I/O error, with `errno`, `strerror` and (when known) `filename`.
fn io_err(source: &std::io::Error, file: Option<String>) -> PyErr {
    // An error of solid's own (no errno) has the errno of its kind where it has one.
    let errno = match (source.raw_os_error(), source.kind()) {
        (Some(e), _) => e,
        (None, std::io::ErrorKind::AlreadyExists) => EEXIST,
        _ => 0,
    };
    let args = (errno, source.to_string(), file);
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
