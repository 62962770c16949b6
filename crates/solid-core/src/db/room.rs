//! Room for new entries: reserving the database's columns and writing new rows in place.
//!
//! A bulk add writes much fresh memory; on Linux the kernel zeroes each page on first touch,
//! which took a large part of the time when `Vec::extend_from_slice` / `Vec::resize` touched every
//! page from one thread (docs/performance.md#database). Two things cut it:
//! - Columns of 4 MiB and more ask for transparent huge pages (`madvise(MADV_HUGEPAGE)`, as
//!   numpy does for its large arrays): one fault per 2 MiB instead of per 4 KiB, and fewer TLB
//!   misses when a search scans every row. Linux with `std` only; a no-op elsewhere.
//! - New rows are written straight into the spare capacity by the threads that compute them
//!   ([`spare`], [`zeroed`], [`copied`], then [`commit`]), so the pages are first touched in
//!   parallel and only once.

use alloc::collections::TryReserveError;
use alloc::vec::Vec;
use core::mem::MaybeUninit;

/// Reserves room for `extra` more values in `v`; when the buffer moved or grew to at least
/// 4 MiB, asks the kernel to back it with huge pages.
pub(super) fn reserve<T>(v: &mut Vec<T>, extra: usize) -> Result<(), TryReserveError> {
    let before = v.capacity();
    v.try_reserve(extra)?;
    if v.capacity() != before {
        advise_huge(v);
    }
    Ok(())
}

/// Buffers from this size on ask for transparent huge pages (numpy's threshold as well).
#[cfg(all(feature = "std", target_os = "linux"))]
const HUGE_FROM: usize = 4 << 20;

#[cfg(all(feature = "std", target_os = "linux"))]
#[allow(unsafe_code)]
fn advise_huge<T>(v: &Vec<T>) {
    const PAGE: usize = 4096;
    let bytes = v.capacity() * core::mem::size_of::<T>();
    if bytes < HUGE_FROM {
        return;
    }
    // The whole pages inside the allocation (madvise wants an aligned start).
    let start = v.as_ptr() as usize;
    let (from, to) = (start.next_multiple_of(PAGE), (start + bytes) & !(PAGE - 1));
    if to > from {
        // SAFETY: the range lies inside `v`'s allocation; MADV_HUGEPAGE is advice only (it
        // changes no content and cannot fail in a way that matters: an error leaves the
        // default pages).
        unsafe {
            libc::madvise(from as *mut libc::c_void, to - from, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(all(feature = "std", target_os = "linux")))]
fn advise_huge<T>(_: &Vec<T>) {}

/// The first `len` slots of `v`'s spare capacity (reserved before).
///
/// # Panics
/// When fewer than `len` slots are reserved (a bug of the caller).
pub(super) fn spare<T>(v: &mut Vec<T>, len: usize) -> &mut [MaybeUninit<T>] {
    &mut v.spare_capacity_mut()[..len]
}

/// Zeroes `slots` and returns them as values.
#[allow(unsafe_code)]
pub(super) fn zeroed<T: bytemuck::Zeroable>(slots: &mut [MaybeUninit<T>]) -> &mut [T] {
    for s in slots.iter_mut() {
        s.write(T::zeroed());
    }
    // SAFETY: every slot was just written; `MaybeUninit<T>` has the layout of `T`.
    unsafe { &mut *(core::ptr::from_mut::<[MaybeUninit<T>]>(slots) as *mut [T]) }
}

/// Copies `from` into `slots` (of the same length) and returns them as values.
///
/// # Panics
/// When the lengths differ (a bug of the caller).
#[allow(unsafe_code)]
pub(super) fn copied<'a, T: Copy>(slots: &'a mut [MaybeUninit<T>], from: &[T]) -> &'a mut [T] {
    assert_eq!(slots.len(), from.len(), "copied: lengths differ");
    for (s, &x) in slots.iter_mut().zip(from) {
        s.write(x);
    }
    // SAFETY: every slot was just written; `MaybeUninit<T>` has the layout of `T`.
    unsafe { &mut *(core::ptr::from_mut::<[MaybeUninit<T>]>(slots) as *mut [T]) }
}

/// Makes the first `len` spare slots of `v` part of it, once they were all written through
/// [`zeroed`] or [`copied`].
///
/// # Safety
/// The caller wrote every one of the `len` slots of [`spare`]`(v, len)`.
#[allow(unsafe_code)]
pub(super) unsafe fn commit<T>(v: &mut Vec<T>, len: usize) {
    debug_assert!(len <= v.capacity() - v.len());
    // SAFETY: the slots are within the capacity and initialised (the caller's contract).
    unsafe { v.set_len(v.len() + len) }
}
