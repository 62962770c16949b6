//! The worker threads of the `parallel` feature: rayon pools of this process, started on first
//! use.
//!
//! Not rayon's global pool: no thread survives `fork` (Python's multiprocessing on Linux), so a
//! child that handed work to the global pool its parent had started waited forever (a brute-force
//! search over 100,000 rows in a `multiprocessing` worker never returned). These pools are keyed
//! by process id: a child starts its own. Work that is already running on a worker of some rayon
//! pool (a batch's query, or a caller's own pool) stays in that pool.
//!
//! Two pools: one for batches and index builds, one for the helpers of single searches, so that
//! a search never waits behind a batch that another thread runs (sharing one pool, a brute-force
//! search over 1M rows took up to 546 ms while a batch ran, against 4–8 ms otherwise).

use std::sync::{Arc, Mutex, PoisonError};

/// A pool and the process that started it.
type Slot = Mutex<Option<(u32, Arc<rayon::ThreadPool>)>>;

/// Batches and index builds.
static WORK: Slot = Mutex::new(None);
/// The threads that join single searches' scans.
static HELPERS: Slot = Mutex::new(None);

/// This process's pool of `slot` (its threads: `RAYON_NUM_THREADS`, or one per core); `None`
/// when no thread could be started.
fn pool_in(slot: &Slot, name: &'static str) -> Option<Arc<rayon::ThreadPool>> {
    let pid = std::process::id();
    let mut slot = slot.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some((id, p)) = slot.as_ref() {
        if *id == pid {
            return Some(Arc::clone(p));
        }
    }
    // A pool of the parent process has no threads here: forget it (dropping it would signal
    // threads that do not exist).
    if let Some((_, stale)) = slot.take() {
        core::mem::forget(stale);
    }
    let p = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .thread_name(move |i| format!("{name}-{i}"))
            .build()
            .ok()?,
    );
    *slot = Some((pid, Arc::clone(&p)));
    Some(p)
}

fn pool() -> Option<Arc<rayon::ThreadPool>> {
    pool_in(&WORK, "solid")
}

fn helpers() -> Option<Arc<rayon::ThreadPool>> {
    pool_in(&HELPERS, "solid-helper")
}

/// How many threads work started from this thread runs on: the current pool's on a rayon
/// worker, else this process's pool's (1 without one: run serially then).
pub(crate) fn threads() -> usize {
    if rayon::current_thread_index().is_some() {
        return rayon::current_num_threads();
    }
    pool().map_or(1, |p| p.current_num_threads())
}

/// How many threads a scan started from this thread through [`in_place_scope`] should run on
/// (this one and one fewer helpers): the current pool's size on a rayon worker, else the
/// helpers' pool's (1 without it: scan alone then).
pub(crate) fn scan_threads() -> usize {
    if rayon::current_thread_index().is_some() {
        return rayon::current_num_threads();
    }
    helpers().map_or(1, |p| p.current_num_threads())
}

/// Runs `op` (which may use rayon's parallel iterators) on the pool's threads, this thread
/// waiting; inline on a rayon worker. Call it when [`threads`] is more than 1.
pub(crate) fn install<R: Send>(op: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_none() {
        if let Some(p) = pool() {
            return p.install(op);
        }
    }
    op()
}

/// `rayon::join` on the pool's threads (see [`install`]).
pub(crate) fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA + Send,
    B: FnOnce() -> RB + Send,
    RA: Send,
    RB: Send,
{
    install(|| rayon::join(a, b))
}

/// `rayon::in_place_scope` whose spawned jobs go to the helpers' pool while `op` runs on this
/// thread; on a rayon worker, to the current pool.
pub(crate) fn in_place_scope<'scope, R>(op: impl FnOnce(&rayon::Scope<'scope>) -> R) -> R {
    if rayon::current_thread_index().is_none() {
        if let Some(p) = helpers() {
            return p.in_place_scope(op);
        }
    }
    rayon::in_place_scope(op)
}
