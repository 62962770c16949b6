//! A pool started while a fork runs another library's `prepare` handler: glibc lets other threads
//! run meanwhile and, in the child, runs only the fork handlers registered before the fork began,
//! so the handler that makes a child forget its parent's pools may come too late for the first
//! pool. The child must still start its own. (A process of its own: the race needs a process
//! that has not asked for any pool yet.)

// The pools are public only with `unstable-internals` (the workspace's tests build with it:
// the Python module asks for it).
#![cfg(all(unix, feature = "parallel", feature = "unstable-internals"))]

mod common;

use std::time::Duration;

use common::reap;
use solid_lidar::pool::pool_of;

/// Stands in for a library's `prepare` handler that takes a while.
extern "C" fn slow_prepare() {
    std::thread::sleep(Duration::from_millis(300));
}

#[test]
fn a_pool_started_during_a_fork_is_not_the_childs() {
    // SAFETY: registers a handler that only sleeps.
    assert_eq!(
        unsafe { libc::pthread_atfork(Some(slow_prepare), None, None) },
        0
    );
    // Another thread asks for the first pool of the process 100 ms into the fork's prepare phase.
    let other = std::thread::spawn(|| {
        std::thread::sleep(Duration::from_millis(100));
        pool_of("solid-helper", 2).unwrap().install(|| ());
    });
    // SAFETY: the child only finds (or starts) a pool, runs on it and leaves with `_exit`.
    let pid = unsafe { libc::fork() };
    assert!(pid >= 0, "fork failed");
    if pid == 0 {
        let seven = pool_of("solid-helper", 2).unwrap().install(|| 7);
        // SAFETY: ends the child at once, without running the parent's exit handlers.
        unsafe { libc::_exit(if seven == 7 { 0 } else { 3 }) };
    }
    other.join().unwrap();
    let exited = reap(pid, Duration::from_secs(5));
    assert_eq!(
        exited,
        Some(0),
        "the child (None: hung on its parent's pool, whose threads it does not have)"
    );
}
