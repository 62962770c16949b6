//! The errors of the crate, one enum per layer, each wrapping the one below (through `From`):
//!
//! ```text
//! DbError    the database, the loop detector, files and the wire form    (feature `alloc`)
//!   ├─ Core(Error)                   From<Error>
//!   └─ RegError, as Core or Format   From<RegError>  (a verification's registration)
//! RegError   registration and the compact cloud                         (feature `alloc`)
//!   └─ Core(Error)                   From<Error>
//! Error      the descriptor, comparison, search, configuration: no allocation, `Copy`
//! LzfError   the LZF decoder (PCD files): a codec of its own, `Copy`
//! ```
//!
//! A function returns the enum of its layer; `?` lifts an error of a layer below. Every
//! variant's message names what was wrong, so that the bindings can pass it on unchanged.

use core::fmt;

#[cfg(feature = "alloc")]
use alloc::string::String;

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

    /// `Ok` when a buffer of `got` elements holds the `needed` ones, else
    /// [`Error::BufferTooSmall`] naming `buffer`.
    #[inline]
    pub(crate) const fn check_buffer(
        buffer: &'static str,
        needed: usize,
        got: usize,
    ) -> Result<(), Error> {
        if got < needed {
            return Err(Error::BufferTooSmall {
                buffer,
                needed,
                got,
            });
        }
        Ok(())
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

#[cfg(feature = "alloc")]
/// Everything that can go wrong in registration and in the cloud wire form.
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RegError {
    /// An error of the core: an invalid parameter (named), a buffer too small, a bad layout.
    Core(Error),
    /// The two clouds were prepared with other preparation parameters than the config passed
    /// to registration (voxel sizes, range or neighbours differ), or one was deferred and not
    /// completed ([`crate::reg::PreparedCloud::complete`]).
    NotPreparedWith,
    /// A wire-form cloud that cannot be decoded.
    Format {
        /// Why.
        reason: &'static str,
    },
}

/// `From<Error>` for an error layered on the core's: the core error as its `Core` variant.
macro_rules! layered_on_core {
    ($layer:ident) => {
        #[cfg(feature = "alloc")]
        impl From<Error> for $layer {
            fn from(e: Error) -> Self {
                $layer::Core(e)
            }
        }
    };
}

layered_on_core!(RegError);

#[cfg(feature = "alloc")]
impl fmt::Display for RegError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RegError::Core(e) => e.fmt(f),
            RegError::NotPreparedWith => write!(
                f,
                "the clouds were prepared with other voxel sizes, range or neighbours than the registration config (or one was deferred and not completed)"
            ),
            RegError::Format { reason } => write!(f, "not a valid SOLiD cloud: {reason}"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for RegError {}

#[cfg(feature = "alloc")]
/// Everything that can go wrong in the database, the loop detector and the wire form.
#[non_exhaustive]
#[derive(Debug)]
pub enum DbError {
    /// An error of the core (a bad vector length, a non-finite value, an invalid config, ...).
    Core(Error),
    /// A descriptor, database or place made with another configuration.
    ConfigMismatch {
        /// Fingerprint of this database's config.
        expected: u64,
        /// Fingerprint of what was offered.
        got: u64,
    },
    /// Bytes that are not a valid database or place: foreign, truncated, corrupted or newer.
    Format {
        /// The file, when the bytes came from one.
        file: Option<String>,
        /// What is wrong, in words.
        reason: String,
    },
    /// The file could not be read or written.
    #[cfg(feature = "std")]
    Io {
        /// The file.
        file: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The file a database was loaded from, which it still reads clouds from, changed since it
    /// was opened (truncated or written in place): what it holds now is not what was loaded.
    #[cfg(feature = "std")]
    Changed {
        /// The file.
        file: String,
        /// How it changed, in words.
        how: String,
    },
    /// A per-place anchor list of a merge (`Database::merge_anchored`) that does not hold one
    /// transform per place of the database merged.
    AnchorCount {
        /// Transforms given.
        given: usize,
        /// Places of the database merged (`other.len()`).
        places: usize,
    },
    /// A per-place anchor of a merge that is not a finite rigid transform.
    BadAnchor {
        /// The place (id in the database merged) whose transform it is.
        place: usize,
        /// What is wrong with it (an [`Error::InvalidParameter`] named `anchor`).
        error: Error,
    },
    /// More than `u32::MAX` entries (or sessions).
    Full,
    /// Memory for the operation could not be allocated (nothing was changed).
    OutOfMemory,
}

layered_on_core!(DbError);

#[cfg(feature = "alloc")]
impl fmt::Display for DbError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DbError::Core(e) => e.fmt(f),
            DbError::ConfigMismatch { expected, got } => write!(
                f,
                "config mismatch: the database uses config fingerprint {expected:#018x}, \
                 this one has {got:#018x} (descriptors from different configs are not comparable)"
            ),
            DbError::Format {
                file: Some(file),
                reason,
            } => write!(f, "cannot load {file}: {reason}"),
            DbError::Format { file: None, reason } => write!(f, "invalid data: {reason}"),
            #[cfg(feature = "std")]
            DbError::Io { file, source } => write!(f, "{file}: {source}"),
            #[cfg(feature = "std")]
            DbError::Changed { file, how } => write!(
                f,
                "the map {file} changed while it was open ({how}): its clouds can no longer be \
                 read as they were loaded; load it again"
            ),
            DbError::AnchorCount { given, places } => write!(
                f,
                "per-place anchors: {given} given, but the database merged has {places} places \
                 (one transform per place: None, in Python a row of NaN, for a place without one)"
            ),
            DbError::BadAnchor { place, error } => write!(f, "anchor of place {place}: {error}"),
            DbError::Full => write!(f, "database full: at most 2^32 - 1 entries"),
            DbError::OutOfMemory => write!(f, "out of memory"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for DbError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            DbError::Core(e) => Some(e),
            DbError::Io { source, .. } => Some(source),
            DbError::BadAnchor { error, .. } => Some(error),
            _ => None,
        }
    }
}

#[cfg(feature = "alloc")]
impl From<RegError> for DbError {
    /// An error of the core stays one; a cloud that cannot be decoded is invalid data.
    fn from(e: RegError) -> Self {
        match e {
            RegError::Core(c) => DbError::Core(c),
            other => DbError::Format {
                file: None,
                reason: alloc::format!("{other}"),
            },
        }
    }
}

/// Everything that can go wrong while decoding an LZF stream.
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LzfError {
    /// The stream decodes to more bytes than the output holds (at least `needed`).
    OutputTooSmall {
        /// Output bytes the stream needs at least (what was written plus the token that overflowed).
        needed: usize,
        /// Length of the output slice.
        capacity: usize,
    },
    /// A token runs past the end of the input.
    Truncated {
        /// Input offset of the token's control byte.
        offset: usize,
    },
    /// A back-reference points before the start of the output.
    BadReference {
        /// Input offset of the token's control byte.
        offset: usize,
        /// How far back the reference points, in bytes.
        distance: usize,
        /// Bytes written so far (the reference must not reach further back than this).
        written: usize,
    },
}

impl fmt::Display for LzfError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            LzfError::OutputTooSmall { needed, capacity } => write!(
                f,
                "LZF data expands beyond the declared {capacity} B (at least {needed} B)"
            ),
            LzfError::Truncated { offset } => write!(
                f,
                "LZF stream is truncated: the token at input byte {offset} runs past the end of the data"
            ),
            LzfError::BadReference {
                offset,
                distance,
                written,
            } => write!(
                f,
                "LZF back-reference before the start of the output (input byte {offset}: {distance} B back after {written} B)"
            ),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for LzfError {}
