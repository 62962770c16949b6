//! The simulator's error type.

use std::fmt;

/// Errors of the simulator.
#[derive(Debug)]
#[non_exhaustive]
pub enum SimError {
    /// A parameter is out of its valid range.
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// What would have been valid.
        expected: &'static str,
    },
    /// An unknown sensor preset or trajectory name.
    UnknownName {
        /// What kind of name (e.g. "sensor preset").
        what: &'static str,
        /// The rejected name.
        name: String,
    },
    /// An I/O error while writing a sequence.
    Io(std::io::Error),
    /// Memory for a result could not be allocated.
    OutOfMemory {
        /// What the memory was for.
        what: &'static str,
        /// Bytes that were asked for.
        bytes: usize,
    },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::InvalidParameter {
                name,
                value,
                expected,
            } => write!(f, "invalid parameter {name} = {value}: expected {expected}"),
            SimError::UnknownName { what, name } => write!(f, "unknown {what} {name:?}"),
            SimError::Io(e) => write!(f, "I/O error: {e}"),
            SimError::OutOfMemory { what, bytes } => write!(
                f,
                "out of memory: could not allocate {bytes} bytes for the {what}"
            ),
        }
    }
}

impl std::error::Error for SimError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SimError::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<std::io::Error> for SimError {
    fn from(e: std::io::Error) -> Self {
        SimError::Io(e)
    }
}

/// An empty vector with room for `n` elements, or [`SimError::OutOfMemory`] naming `what`.
pub(crate) fn try_vec<T>(n: usize, what: &'static str) -> Result<Vec<T>, SimError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| SimError::OutOfMemory {
        what,
        bytes: n.saturating_mul(core::mem::size_of::<T>()),
    })?;
    Ok(v)
}

/// Checks `lo <= value <= hi` (and finiteness), naming the parameter on failure.
pub(crate) fn check(
    name: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), SimError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(SimError::InvalidParameter {
            name,
            value,
            expected,
        })
    }
}

/// Checks `lo <= value <= hi` (and finiteness), naming the parameter on failure.
pub(crate) fn check_in(
    name: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    expected: &'static str,
) -> Result<(), SimError> {
    check(name, value, (lo..=hi).contains(&value), expected)
}
