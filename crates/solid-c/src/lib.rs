//! The C ABI of `solid-lidar`: `libsolid.so`, `libsolid.a` and `include/solid.h` (generated from
//! these doc comments by cbindgen; `make c-header` rewrites it, `make c-test` checks it is current).
//!
//! Conventions of every function:
//! - It returns a [`SolidStatus`]; on anything but `SOLID_STATUS_OK` nothing was changed, the
//!   outputs were not written, and [`solid_last_error`] names the problem on this thread.
//! - No panic crosses the boundary: an internal panic is caught and reported as
//!   `SOLID_STATUS_PANIC`.
//! - Objects are opaque handles made by a `*_new` function and released by its `*_free`
//!   function (which accepts NULL). Each handle's documentation says whether several threads may
//!   use it at once.
//! - Buffers passed in are only read during the call and never kept; buffers passed out are
//!   owned by the caller.
//!
//! The files are split by handle: [`config`] (parameters by name), [`describe`] (describer,
//! distance, heading), [`database`], [`detector`] (the loop detector) and [`registration`].
// Every `extern "C"` function takes raw pointers from C and checks them before use (null,
// alignment, lengths); the safety contract is the header's documentation.
#![allow(clippy::missing_safety_doc)]
#![deny(missing_docs)]

use std::cell::RefCell;
use std::ffi::{c_char, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use solid_lidar::db::DbError;
use solid_lidar::reg::RegError;
use solid_lidar::{Error, Points};

pub mod config;
pub mod database;
pub mod describe;
pub mod detector;
pub mod registration;

/// What a call returned. Every value but `SOLID_STATUS_OK` comes with a message from
/// [`solid_last_error`].
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolidStatus {
    /// Success.
    Ok = 0,
    /// A NULL pointer where a value is needed, a misaligned or malformed point buffer, a string
    /// that is not UTF-8, an unknown parameter name, vectors of the wrong length.
    InvalidArgument = 1,
    /// A parameter or input value out of its valid range (the message names it), or an unknown
    /// preset.
    InvalidParameter = 2,
    /// An output buffer is shorter than needed (the message says how long it must be).
    BufferTooSmall = 3,
    /// A database, descriptor or cloud made with another configuration.
    ConfigMismatch = 4,
    /// A file or byte string that is not a valid SOLiD database (foreign, truncated, corrupted).
    Format = 5,
    /// A file could not be read or written, an output path is not a regular file, or the map a
    /// database was loaded from changed while it was open (the message names it).
    Io = 6,
    /// A database already holds 2^32 - 1 entries.
    Full = 7,
    /// Memory could not be allocated (nothing was changed).
    OutOfMemory = 8,
    /// An internal error (a bug: please report it with the message). A handle that was in use
    /// is unusable afterwards: every later call on it returns this status.
    Panic = 9,
}

/// The failure of one call: its status and message.
#[derive(Debug)]
pub(crate) struct Failure {
    status: SolidStatus,
    message: String,
}

impl Failure {
    pub(crate) fn new(status: SolidStatus, message: impl Into<String>) -> Failure {
        Failure {
            status,
            message: message.into(),
        }
    }

    pub(crate) fn arg(message: impl Into<String>) -> Failure {
        Failure::new(SolidStatus::InvalidArgument, message)
    }
}

impl From<Error> for Failure {
    fn from(e: Error) -> Failure {
        let status = match e {
            Error::InvalidParameter { .. } | Error::UnknownPreset => SolidStatus::InvalidParameter,
            Error::BufferTooSmall { .. } => SolidStatus::BufferTooSmall,
            Error::OutOfMemory { .. } => SolidStatus::OutOfMemory,
            _ => SolidStatus::InvalidArgument,
        };
        Failure::new(status, e.to_string())
    }
}

impl From<DbError> for Failure {
    fn from(e: DbError) -> Failure {
        let status = match &e {
            DbError::Core(c) => return Failure::from(*c),
            DbError::ConfigMismatch { .. } => SolidStatus::ConfigMismatch,
            DbError::Format { .. } => SolidStatus::Format,
            DbError::Io { .. } | DbError::Changed { .. } => SolidStatus::Io,
            DbError::Full => SolidStatus::Full,
            DbError::OutOfMemory => SolidStatus::OutOfMemory,
            DbError::AnchorCount { .. } | DbError::BadAnchor { .. } => {
                SolidStatus::InvalidParameter
            }
            _ => SolidStatus::InvalidArgument,
        };
        Failure::new(status, e.to_string())
    }
}

impl From<RegError> for Failure {
    fn from(e: RegError) -> Failure {
        match e {
            RegError::Core(c) => Failure::from(c),
            RegError::NotPreparedWith => Failure::new(SolidStatus::ConfigMismatch, e.to_string()),
            _ => Failure::new(SolidStatus::Format, e.to_string()),
        }
    }
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_last_error(message: String) {
    // An interior NUL would cut the C string short: show it instead.
    let c = CString::new(message.replace('\0', "\\0")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = c);
}

/// Runs the body of the entry point `what`: maps its failure to a status and the thread's last
/// error, and catches a panic so that it never unwinds into C.
pub(crate) fn guard(what: &str, f: impl FnOnce() -> Result<(), Failure>) -> SolidStatus {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(())) => SolidStatus::Ok,
        Ok(Err(e)) => {
            set_last_error(format!("{what}: {}", e.message));
            e.status
        }
        Err(payload) => {
            let detail = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            set_last_error(format!("{what}: internal error (a bug): {detail}"));
            SolidStatus::Panic
        }
    }
}

/// The message of the last call on this thread that did not return `SOLID_STATUS_OK`: it names
/// the function and the problem. Empty when no call has failed on this thread. The string is
/// owned by the library and valid until the next failing call on this thread.
#[no_mangle]
pub extern "C" fn solid_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// The library's version, e.g. `"0.1.0"` (a static string).
#[no_mangle]
pub extern "C" fn solid_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// A borrowed point cloud: `count` points, each starting `stride_bytes` after the previous one,
/// whose first three coordinates are x, y, z (metres, sensor frame: x forward, y left, z up) of
/// `coord_bytes` each: `sizeof(float)` (4) or `sizeof(double)` (8). Other fields of a point
/// (intensity, time, padding) are skipped, so an array of PCL `PointXYZI` (32 bytes) or a KITTI
/// x y z intensity array (16 bytes) is read in place, without a copy.
///
/// `data` must be aligned for its coordinate type, `stride_bytes` a multiple of `coord_bytes`
/// and at least `3 * coord_bytes`, and the buffer must hold `count * stride_bytes` bytes. It is
/// read during the call only. `data` may be NULL when `count` is 0.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct SolidPoints {
    /// The first point.
    pub data: *const c_void,
    /// Number of points.
    pub count: usize,
    /// Bytes from one point to the next.
    pub stride_bytes: usize,
    /// Bytes per coordinate: 4 (float) or 8 (double).
    pub coord_bytes: usize,
}

/// The points of a [`SolidPoints`], typed.
pub(crate) enum PointsRef<'a> {
    F32(Points<'a, f32>),
    F64(Points<'a, f64>),
}

/// Calls `$body` with `$p` bound to the typed points of a [`PointsRef`].
macro_rules! with_points {
    ($points:expr, |$p:ident| $body:expr) => {
        match $points {
            $crate::PointsRef::F32($p) => $body,
            $crate::PointsRef::F64($p) => $body,
        }
    };
}
pub(crate) use with_points;

/// Checks a [`SolidPoints`] and borrows its buffer in place.
///
/// # Safety
/// `pts` is NULL or points to a `SolidPoints` whose buffer holds `count * stride_bytes` bytes
/// that stay valid and unchanged for `'a`.
pub(crate) unsafe fn points<'a>(pts: *const SolidPoints) -> Result<PointsRef<'a>, Failure> {
    let p = *nonnull(pts, "points")?;
    unsafe fn typed<'a, T: solid_lidar::Coord>(p: &SolidPoints) -> Result<Points<'a, T>, Failure> {
        let size = std::mem::size_of::<T>();
        if p.stride_bytes < 3 * size || !p.stride_bytes.is_multiple_of(size) {
            return Err(Failure::arg(format!(
                "points.stride_bytes = {} must be a multiple of coord_bytes = {size} and at least {}",
                p.stride_bytes,
                3 * size
            )));
        }
        let stride = p.stride_bytes / size;
        let len = p.count.checked_mul(stride).filter(|n| {
            n.checked_mul(size)
                .is_some_and(|b| b <= isize::MAX as usize)
        });
        let Some(len) = len else {
            return Err(Failure::arg(format!(
                "points.count = {} is too large",
                p.count
            )));
        };
        let data: &[T] = if len == 0 {
            &[]
        } else if p.data.is_null() {
            return Err(Failure::arg("points.data is NULL"));
        } else if !p.data.cast::<T>().is_aligned() {
            return Err(Failure::arg(format!(
                "points.data is not aligned to {} bytes",
                std::mem::align_of::<T>()
            )));
        } else {
            // SAFETY: non-null, aligned, and the caller vouches for count * stride_bytes bytes.
            std::slice::from_raw_parts(p.data.cast::<T>(), len)
        };
        Ok(Points::new(data, stride)?)
    }
    match p.coord_bytes {
        4 => Ok(PointsRef::F32(typed(&p)?)),
        8 => Ok(PointsRef::F64(typed(&p)?)),
        n => Err(Failure::arg(format!(
            "points.coord_bytes = {n}: expected 4 (float) or 8 (double)"
        ))),
    }
}

/// `*p`, or an error naming `name` when `p` is NULL.
///
/// # Safety
/// `p` is NULL or valid for reads for `'a`.
pub(crate) unsafe fn nonnull<'a, T>(p: *const T, name: &str) -> Result<&'a T, Failure> {
    p.as_ref()
        .ok_or_else(|| Failure::arg(format!("{name} is NULL")))
}

/// `*p` for writing, or an error naming `name` when `p` is NULL.
///
/// # Safety
/// `p` is NULL or valid for writes for `'a`, and not aliased.
pub(crate) unsafe fn out<'a, T>(p: *mut T, name: &str) -> Result<&'a mut T, Failure> {
    p.as_mut()
        .ok_or_else(|| Failure::arg(format!("{name} is NULL")))
}

/// The `len` values at `p` (NULL allowed when `len` is 0).
///
/// # Safety
/// `p` is NULL or valid for `len` reads for `'a`.
pub(crate) unsafe fn slice<'a, T>(p: *const T, len: usize, name: &str) -> Result<&'a [T], Failure> {
    if len == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(Failure::arg(format!("{name} is NULL")));
    }
    Ok(std::slice::from_raw_parts(p, len))
}

/// The `len` values at `p` for writing (NULL allowed when `len` is 0).
///
/// # Safety
/// `p` is NULL or valid for `len` writes for `'a`, and not aliased.
pub(crate) unsafe fn slice_mut<'a, T>(
    p: *mut T,
    len: usize,
    name: &str,
) -> Result<&'a mut [T], Failure> {
    if len == 0 {
        return Ok(&mut []);
    }
    if p.is_null() {
        return Err(Failure::arg(format!("{name} is NULL")));
    }
    Ok(std::slice::from_raw_parts_mut(p, len))
}

/// A C string argument as UTF-8.
///
/// # Safety
/// `p` is NULL or a NUL-terminated string valid for `'a`.
pub(crate) unsafe fn string<'a>(p: *const c_char, name: &str) -> Result<&'a str, Failure> {
    if p.is_null() {
        return Err(Failure::arg(format!("{name} is NULL")));
    }
    CStr::from_ptr(p)
        .to_str()
        .map_err(|_| Failure::arg(format!("{name} is not UTF-8")))
}

/// Writes `value` to the output `p` named `name`.
///
/// # Safety
/// As [`out`].
pub(crate) unsafe fn put<T>(p: *mut T, name: &str, value: T) -> Result<(), Failure> {
    *out(p, name)? = value;
    Ok(())
}

/// The body of the entry point `what` that makes a handle: checks the output `handle` named
/// `name` (nothing is made for NULL), then writes to it a new handle holding what `make` returns
/// (see [`guard`]). Release it with [`release`].
///
/// # Safety
/// As [`out`].
pub(crate) unsafe fn new_handle<T>(
    what: &str,
    handle: *mut *mut T,
    name: &str,
    make: impl FnOnce() -> Result<T, Failure>,
) -> SolidStatus {
    guard(what, || {
        let o = out(handle, name)?;
        *o = Box::into_raw(Box::new(make()?));
        Ok(())
    })
}

/// Releases a handle made by [`new_handle`] (NULL: nothing).
///
/// # Safety
/// `p` is NULL or came from [`new_handle`] and is not used afterwards.
pub(crate) unsafe fn release<T>(p: *mut T) {
    if !p.is_null() {
        drop(Box::from_raw(p));
    }
}

/// A row-major 4×4 rigid transform from C as the core's row-major 3×4 `[R|t]`.
pub(crate) fn pose_3x4(m: &[f64; 16], name: &str) -> Result<[f64; 12], Failure> {
    if m[12..] != [0.0, 0.0, 0.0, 1.0] {
        return Err(Failure::new(
            SolidStatus::InvalidParameter,
            format!(
                "{name}: the last row of a row-major 4x4 pose must be 0 0 0 1, got {:?} \
                 (a column-major matrix, such as Eigen's default, must be transposed)",
                &m[12..]
            ),
        ));
    }
    let mut p = [0.0; 12];
    p.copy_from_slice(&m[..12]);
    Ok(p)
}

/// A row-major 4×4 array from the core's pose.
pub(crate) fn flat_pose(p: &solid_lidar::reg::Pose) -> [f64; 16] {
    let mut m = [0.0; 16];
    for (row, src) in m.chunks_exact_mut(4).zip(p) {
        row.copy_from_slice(src);
    }
    m
}

/// Locks a handle's lock for reading; a lock poisoned by a panic makes the handle unusable.
pub(crate) fn read<'a, T>(
    l: &'a std::sync::RwLock<T>,
) -> Result<std::sync::RwLockReadGuard<'a, T>, Failure> {
    l.read().map_err(|_| poisoned())
}

/// Locks a handle's lock for writing (see [`read`]).
pub(crate) fn write<'a, T>(
    l: &'a std::sync::RwLock<T>,
) -> Result<std::sync::RwLockWriteGuard<'a, T>, Failure> {
    l.write().map_err(|_| poisoned())
}

fn poisoned() -> Failure {
    Failure::new(
        SolidStatus::Panic,
        "this handle is unusable: an earlier call on it failed with an internal error",
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_a_status_and_a_message() {
        let s = guard("solid_example", || panic!("boom"));
        assert_eq!(s, SolidStatus::Panic);
        let msg = unsafe { CStr::from_ptr(solid_last_error()) };
        assert_eq!(
            msg.to_str().unwrap(),
            "solid_example: internal error (a bug): boom"
        );
    }
}
