//! The one error type of the crate.

use core::fmt;

/// Everything that can go wrong in `solid-lidar`.
///
/// Every variant names what was wrong, so that a message can tell the user what to fix.
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Error {
    /// A configuration parameter is out of its valid range ([spec §1](crate::spec#1-parameters)). Nothing is ever clamped.
    InvalidParameter {
        /// The parameter's name, as in the configuration (`n_range`, `fov_up`, ...).
        name: &'static str,
        /// The rejected value (converted to `f64`).
        value: f64,
        /// What a valid value looks like.
        expected: &'static str,
    },
    /// A caller-owned buffer is shorter than the operation needs.
    BufferTooSmall {
        /// Which buffer (`scratch`, `r_out`, `a_out`, ...).
        buffer: &'static str,
        /// Length that is needed, in elements.
        needed: usize,
        /// Length that was passed, in elements.
        got: usize,
    },
    /// The point slice and its stride do not describe whole points.
    BadPointLayout {
        /// Length of the flat slice, in elements.
        len: usize,
        /// Elements per point (must be at least 3 and divide `len`).
        stride: usize,
    },
    /// Two vectors that must have the same length do not.
    LengthMismatch {
        /// What was compared (`r_solid`, `a_solid`, ...).
        what: &'static str,
        /// Length of the first vector.
        left: usize,
        /// Length of the second vector.
        right: usize,
    },
    /// A vector that must not be empty is.
    Empty {
        /// Which vector.
        what: &'static str,
    },
    /// A preset name that is not one of [`crate::PRESETS`].
    UnknownPreset,
    /// Memory for a buffer could not be allocated (only the `alloc` conveniences allocate;
    /// nothing was changed).
    OutOfMemory {
        /// What the memory was for (`describe scratch`, ...).
        what: &'static str,
        /// Bytes that were asked for.
        bytes: usize,
    },
}

impl Error {
    /// [`Error::InvalidParameter`]: parameter `name` has `value`, which is not `expected`.
    pub const fn invalid(name: &'static str, value: f64, expected: &'static str) -> Error {
        Error::InvalidParameter {
            name,
            value,
            expected,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::InvalidParameter {
                name,
                value,
                expected,
            } => write!(f, "invalid {name} = {value}: expected {expected}"),
            Error::BufferTooSmall {
                buffer,
                needed,
                got,
            } => write!(
                f,
                "buffer `{buffer}` too small: needs {needed} elements, got {got}"
            ),
            Error::BadPointLayout { len, stride } => write!(
                f,
                "points slice of length {len} is not a whole number of points with stride {stride} (stride must be >= 3)"
            ),
            Error::LengthMismatch { what, left, right } => {
                write!(f, "{what} lengths differ: {left} vs {right}")
            }
            Error::Empty { what } => write!(f, "{what} is empty"),
            Error::OutOfMemory { what, bytes } => write!(
                f,
                "out of memory: could not allocate {bytes} bytes for the {what}"
            ),
            Error::UnknownPreset => write!(
                f,
                "unknown preset: expected one of hdl64, hdl32, vlp16, os1-64, avia, aeva"
            ),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for Error {}
