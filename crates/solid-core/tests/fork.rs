//! A process forked while another thread of its parent uses the thread pools: the child must
//! start pools of its own without waiting on anything the parent's threads held.

#![cfg(all(unix, feature = "parallel"))]

mod common;

use std::hint::black_box;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use common::reap;
use solid_lidar::search::auto_tree_row_cost;

#[test]
fn a_child_forked_while_another_thread_finds_the_pools_does_not_hang() {
    // `auto_tree_row_cost` over 65,536 rows asks how many threads a scan runs on: it finds the
    // helpers' pool, as every search of that size does. With a mutex around the pools, a child
    // forked while the other thread held it waited forever (6 of 200 children).
    let stop = Arc::new(AtomicBool::new(false));
    let busy = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                black_box(auto_tree_row_cost(black_box(1 << 16), 1));
            }
        })
    };
    let (mut hung, mut failed) = (0, 0);
    for _ in 0..200 {
        // SAFETY: the child only finds (or starts) its pools and leaves with `_exit`.
        let pid = unsafe { libc::fork() };
        assert!(pid >= 0, "fork failed");
        if pid == 0 {
            let cost = auto_tree_row_cost(1 << 16, 1);
            // SAFETY: ends the child at once, without running the parent's exit handlers.
            unsafe { libc::_exit(if cost > 0 { 0 } else { 3 }) };
        }
        match reap(pid, Duration::from_secs(2)) {
            None => hung += 1,
            Some(0) => {}
            Some(_) => failed += 1,
        }
    }
    stop.store(true, Ordering::Relaxed);
    busy.join().unwrap();
    assert_eq!((hung, failed), (0, 0), "of 200 children: hung, failed");
}
