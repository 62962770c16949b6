//! The worker threads of the `parallel` feature: rayon pools of this process, started on first
//! use and kept for its life.
//!
//! Not rayon's global pool: no thread survives `fork` (Python's multiprocessing on Linux), so a
//! child that handed work to the global pool its parent had started waited forever (a brute-force
//! search over 100,000 rows in a `multiprocessing` worker never returned). A forked child forgets
//! the pools of its parent (a `pthread_atfork` handler, and each pool records the process that
//! started it) and starts its own. The pools are found without a lock: a child forked while
//! another thread of its parent held one would wait on it forever (it happened with a mutex
//! around the pools: docs/performance.md#thread-pools). Work that is already running on a worker
//! of some rayon pool (a batch's query, or a caller's own pool) stays in that pool, and no work
//! ever goes to rayon's global pool: without a pool of its own, work runs on the calling thread.
//!
//! Two pools for the crate's own work: one for batches and index builds, one for the helpers of
//! single searches, so that a search never waits behind a batch that another thread runs
//! (docs/performance.md#thread-pools). The Python bindings keep their `describe_batch` workers
//! here too ([`pool_of`]).

use core::ptr;
use core::sync::atomic::{AtomicPtr, Ordering};

use alloc::boxed::Box;
use alloc::format;
use alloc::string::{String, ToString};

/// One pool, in a list that only grows.
struct Entry {
    /// The process that started it.
    pid: u32,
    name: &'static str,
    threads: usize,
    pool: rayon::ThreadPool,
    next: *const Entry,
}

/// The newest pool of this process (the others follow it); null in a child until it starts one.
/// Entries are never freed: a pool is kept for the life of the process, and in a forked child
/// those of the parent are forgotten (their threads do not exist there; dropping one would
/// signal them).
static POOLS: AtomicPtr<Entry> = AtomicPtr::new(ptr::null_mut());

/// The pool `name` of `threads` threads of process `pid` in the list from `head`.
fn find(
    mut head: *const Entry,
    pid: u32,
    name: &str,
    threads: usize,
) -> Option<&'static rayon::ThreadPool> {
    while !head.is_null() {
        // SAFETY: every entry of the list was leaked from a `Box` and is never freed or changed
        // after it was published (release ordering of the publishing exchange, acquire of the
        // loads that led here).
        #[allow(unsafe_code)]
        let e: &'static Entry = unsafe { &*head };
        if e.pid == pid && e.name == name && e.threads == threads {
            return Some(&e.pool);
        }
        head = e.next;
    }
    None
}

/// This process's pool `name` of `threads` threads (0: `RAYON_NUM_THREADS`, or one per core),
/// started on first use; its threads are named `name-i`. Shared by every caller that asks for
/// the same name and size, and kept for the life of the process (a forked child starts its own).
///
/// # Errors
/// What stopped the pool's threads from starting (tried again on the next call).
#[doc(hidden)]
pub fn pool_of(name: &'static str, threads: usize) -> Result<&'static rayon::ThreadPool, String> {
    // Besides the fork handler, the process id: glibc runs only the fork handlers registered
    // before a fork began, and lets other threads run its `prepare` handlers meanwhile (those
    // of other libraries), so a pool published then, with the handler registered too late,
    // reached the child (a child's first pool hung in 3 of 3 runs of a review's probe).
    let pid = std::process::id();
    let mut head = POOLS.load(Ordering::Acquire);
    if let Some(p) = find(head, pid, name, threads) {
        return Ok(p);
    }
    forget_pools_in_children()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(move |i| format!("{name}-{i}"))
        .build()
        .map_err(|e| e.to_string())?;
    // Owned by this thread alone until the exchange below publishes it.
    let entry = Box::into_raw(Box::new(Entry {
        pid,
        name,
        threads,
        pool,
        next: head,
    }));
    loop {
        match POOLS.compare_exchange_weak(head, entry, Ordering::AcqRel, Ordering::Acquire) {
            Ok(_) => {
                // SAFETY: published, the entry is never freed or changed again (see `POOLS`).
                #[allow(unsafe_code)]
                let published: &'static Entry = unsafe { &*entry };
                return Ok(&published.pool);
            }
            Err(now) => {
                // Another thread added a pool meanwhile: this one, or another.
                if let Some(p) = find(now, pid, name, threads) {
                    // SAFETY: `entry` came from `Box::into_raw` and was never published. Its
                    // pool is dropped: its threads are told to end.
                    #[allow(unsafe_code)]
                    drop(unsafe { Box::from_raw(entry) });
                    return Ok(p);
                }
                // SAFETY: as above, not published: this thread alone has it.
                #[allow(unsafe_code)]
                unsafe {
                    (*entry).next = now;
                }
                head = now;
            }
        }
    }
}

/// Makes sure that a forked child forgets this process's pools, before any is published.
fn forget_pools_in_children() -> Result<(), String> {
    // (Emscripten's libc has no `pthread_atfork`; nor does it fork.)
    #[cfg(all(unix, not(target_os = "emscripten")))]
    {
        use core::sync::atomic::AtomicBool;
        static REGISTERED: AtomicBool = AtomicBool::new(false);
        extern "C" fn forget() {
            // Async-signal-safe: one atomic store. The entries leak in the child.
            POOLS.store(ptr::null_mut(), Ordering::Relaxed);
        }
        if !REGISTERED.load(Ordering::Acquire) {
            // Two threads may both register it before either has marked it: the handler then
            // runs twice, storing null twice.
            // SAFETY: `forget` only stores to an atomic, which a child of a multithreaded
            // process may do before `exec`.
            #[allow(unsafe_code)]
            let err = unsafe { libc::pthread_atfork(None, None, Some(forget)) };
            if err != 0 {
                return Err(format!(
                    "cannot register the fork handler of the thread pools (error {err})"
                ));
            }
            REGISTERED.store(true, Ordering::Release);
        }
    }
    Ok(())
}

/// Where work started from this thread runs: on the current pool on a rayon worker, else on a
/// pool of this process.
#[derive(Clone, Copy)]
pub(crate) enum Threads {
    Current,
    Pool(&'static rayon::ThreadPool),
}

impl Threads {
    /// How many threads run the work.
    pub(crate) fn count(self) -> usize {
        match self {
            Threads::Current => rayon::current_num_threads(),
            Threads::Pool(p) => p.current_num_threads(),
        }
    }

    /// Runs `op` (which may use rayon's parallel iterators) on these threads, this thread
    /// waiting; inline on a rayon worker.
    pub(crate) fn install<R: Send>(self, op: impl FnOnce() -> R + Send) -> R {
        match self {
            Threads::Current => op(),
            Threads::Pool(p) => p.install(op),
        }
    }

    /// `rayon::join` on these threads.
    pub(crate) fn join<A, B, RA, RB>(self, a: A, b: B) -> (RA, RB)
    where
        A: FnOnce() -> RA + Send,
        B: FnOnce() -> RB + Send,
        RA: Send,
        RB: Send,
    {
        self.install(|| rayon::join(a, b))
    }

    /// `rayon::in_place_scope` whose spawned jobs go to these threads while `op` runs on this
    /// one.
    pub(crate) fn in_place_scope<'scope, R>(
        self,
        op: impl FnOnce(&rayon::Scope<'scope>) -> R,
    ) -> R {
        match self {
            Threads::Current => rayon::in_place_scope(op),
            Threads::Pool(p) => p.in_place_scope(op),
        }
    }
}

/// The current pool on a rayon worker, else this process's pool `name`, when it has more than
/// one thread (`None`: run on this thread alone).
fn parallel(name: &'static str) -> Option<Threads> {
    let threads = if rayon::current_thread_index().is_some() {
        Threads::Current
    } else {
        Threads::Pool(pool_of(name, 0).ok()?)
    };
    (threads.count() > 1).then_some(threads)
}

/// Where batches, index builds and bulk adds started from this thread share their work; `None`:
/// run it on this thread.
pub(crate) fn work() -> Option<Threads> {
    parallel("solid")
}

/// Where the helpers of a single search's scan started from this thread run (another pool than
/// [`work`]'s: see the module); `None`: scan on this thread.
pub(crate) fn scan_helpers() -> Option<Threads> {
    parallel("solid-helper")
}

// The thread counts below serve the bindings (the feature `unstable-internals`) and the tests.

/// What a count of threads means in every API (Rust, the Python keywords, the C setters, the CLI
/// flags): 0 asks for one thread per core, any other number for that many.
#[cfg(any(test, feature = "unstable-internals"))]
pub const ONE_PER_CORE: usize = 0;

/// The threads a count asks for on this machine: its cores for [`ONE_PER_CORE`], else the count.
#[cfg(any(test, feature = "unstable-internals"))]
pub fn threads_asked(threads: usize) -> usize {
    threads_on(threads, cores())
}

/// This machine's cores (1 when unknown).
#[cfg(any(test, feature = "unstable-internals"))]
fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// [`threads_asked`] on a machine of `cores` cores.
#[cfg(any(test, feature = "unstable-internals"))]
fn threads_on(threads: usize, cores: usize) -> usize {
    if threads == ONE_PER_CORE {
        cores
    } else {
        threads
    }
}

/// The threads of the pool for a batch of `jobs` jobs when a caller asks for `threads`
/// ([`ONE_PER_CORE`] or a count), or `None` when one thread does (a single job or a single
/// thread): at most one per core, since more only adds switching. The pool has the threads asked
/// for even when there are fewer jobs (the jobs then take fewer of them): one pool per size
/// asked, not one per batch length. Ask [`pool_of`] for it.
#[cfg(feature = "unstable-internals")]
pub fn batch_threads(threads: usize, jobs: usize) -> Option<usize> {
    batch_threads_of(threads, jobs, cores())
}

/// [`batch_threads`] on a machine of `cores` cores.
#[cfg(any(test, feature = "unstable-internals"))]
fn batch_threads_of(threads: usize, jobs: usize, cores: usize) -> Option<usize> {
    let threads = threads_on(threads, cores).min(cores);
    (threads.min(jobs) > 1).then_some(threads)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_batch_gets_the_threads_asked_for_at_most_one_per_core() {
        assert_eq!(batch_threads_of(ONE_PER_CORE, 100, 8), Some(8));
        assert_eq!(batch_threads_of(3, 100, 8), Some(3));
        assert_eq!(batch_threads_of(64, 100, 8), Some(8));
        // Fewer jobs than threads: the pool of the size asked (one per size, not per batch).
        assert_eq!(batch_threads_of(ONE_PER_CORE, 2, 8), Some(8));
    }

    #[test]
    fn one_job_or_one_thread_runs_on_the_caller() {
        assert_eq!(batch_threads_of(ONE_PER_CORE, 1, 8), None);
        assert_eq!(batch_threads_of(ONE_PER_CORE, 0, 8), None);
        assert_eq!(batch_threads_of(1, 100, 8), None);
        assert_eq!(batch_threads_of(ONE_PER_CORE, 100, 1), None);
    }

    #[test]
    fn zero_threads_ask_for_one_per_core() {
        assert_eq!(ONE_PER_CORE, 0);
        assert_eq!(threads_on(0, 6), 6);
        assert_eq!(threads_on(1, 6), 1);
        assert_eq!(threads_on(9, 6), 9);
        assert!(threads_asked(0) >= 1);
        assert_eq!(threads_asked(0), cores());
    }
}
