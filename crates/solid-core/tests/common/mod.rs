//! Test helpers: locate `../shared` and read the shared scans (formats of shared/data/README.md).
#![allow(dead_code)]

use std::path::PathBuf;

#[cfg(feature = "std")]
pub mod db;
mod scan;
pub mod search;

// Each test binary uses some of them.
#[allow(unused_imports)]
pub use scan::{read_kitti, read_scan, read_xyz_f32};

/// The shared folder (`SOLID_SHARED`, else `<repo>/../shared`), or `None` when absent.
/// Under `CI=true` a missing folder is a failure, not a skip.
pub fn shared() -> Option<PathBuf> {
    let dir = match std::env::var_os("SOLID_SHARED") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared"),
    };
    if dir.join("data").is_dir() {
        return Some(dir);
    }
    assert!(
        std::env::var("CI").as_deref() != Ok("true"),
        "shared data folder {} is missing under CI",
        dir.display()
    );
    eprintln!("skipping: shared data folder {} not found", dir.display());
    None
}

/// `<shared>/data`, or `None` when absent (a failure under `CI=true`).
pub fn data_dir() -> Option<PathBuf> {
    shared().map(|s| s.join("data"))
}

/// A global allocator that counts allocations, for the no-allocation tests: install it with
/// `#[global_allocator] static GLOBAL: common::Counting = common::Counting;`.
pub struct Counting;

std::thread_local! {
    // Per thread: the test harness's own threads allocate while a test runs. Const-initialised
    // and without a destructor, so the allocator can use it without allocating.
    static ALLOCS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// Allocations (and reallocations) so far through [`Counting`] on the calling thread.
pub fn allocations() -> usize {
    ALLOCS.with(|c| c.get())
}

fn count() {
    // try_with: a thread being torn down may still free (never allocate through) its locals.
    let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
}

// SAFETY: forwards every call to the system allocator; only counts them.
unsafe impl std::alloc::GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        count();
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { std::alloc::System.realloc(ptr, layout, new_size) }
    }
}

/// xorshift64: a small deterministic generator for tests.
pub struct Xorshift(pub u64);

impl Xorshift {
    /// The next value in [0, 1).
    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Waits for the child `pid` (of a test that forks) up to `wait`; its exit code, or `None` when
/// it had to be killed.
#[cfg(unix)]
pub fn reap(pid: libc::pid_t, wait: std::time::Duration) -> Option<i32> {
    use std::time::{Duration, Instant};
    let deadline = Instant::now() + wait;
    let mut status = 0;
    loop {
        // SAFETY: waits for a child of this process, writing its status to a local.
        let got = unsafe { libc::waitpid(pid, &mut status, libc::WNOHANG) };
        if got == pid {
            return Some(if libc::WIFEXITED(status) {
                libc::WEXITSTATUS(status)
            } else {
                -1
            });
        }
        if Instant::now() > deadline {
            // SAFETY: ends and reaps a child of this process.
            unsafe {
                libc::kill(pid, libc::SIGKILL);
                libc::waitpid(pid, &mut status, 0);
            }
            return None;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}
