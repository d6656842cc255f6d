//! The thread pool of a process forked from one that ran the core.
//!
//! The core's parallel loops run on rayon's global pool (and faer's and
//! gemm's, which use it). A child forked from a process whose pool had
//! started (`os.fork`, a `multiprocessing` pool with the fork start method,
//! the default on Linux before Python 3.14) inherits the pool's state but
//! none of its threads: the first loop it hands over waits for good. So
//! the binding runs each call of the core in a forked child on a pool of
//! the child's own, started at its first call (as many threads as the
//! global pool would have: `RAYON_NUM_THREADS` or the processor's). The
//! loops and their results are the same on either pool (no result depends
//! on the number of threads, [`crate::base::dense`]).

use crate::error::{Error, Result};
use rayon::{ThreadPool, ThreadPoolBuilder};
use std::sync::{Mutex, OnceLock};

/// The process that loaded the module.
static LOADED_IN: OnceLock<u32> = OnceLock::new();

/// The pool of a forked process, with that process's id: a process forked
/// from a forked one starts its own again.
static FORKED: Mutex<Option<(u32, &'static ThreadPool)>> = Mutex::new(None);

/// Note this process as the one whose global pool the core may use (at the
/// module's initialisation).
pub fn loaded_here() {
    LOADED_IN.get_or_init(std::process::id);
}

/// `work` on the global pool in the process that loaded the module, on the
/// process's own pool in a process forked from it.
pub fn in_this_process<T: Send>(work: impl FnOnce() -> Result<T> + Send) -> Result<T> {
    let id = std::process::id();
    match LOADED_IN.get() {
        Some(&loaded) if loaded != id => own_pool(id)?.install(work),
        _ => work(),
    }
}

/// The pool of forked process `id`, started at its first call.
fn own_pool(id: u32) -> Result<&'static ThreadPool> {
    // A lock held at the fork by another thread of the parent would be held
    // for good in the child; this one is only ever taken in forked
    // processes, at their calls into the core.
    let mut forked = FORKED
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some((of, pool)) = *forked {
        if of == id {
            return Ok(pool);
        }
    }
    let pool = ThreadPoolBuilder::new()
        .thread_name(|i| format!("lpvid-forked-{i}"))
        .build()
        .map_err(|e| {
            Error::Internal(format!(
                "this process was forked from one that had run lpvid's core, whose threads it \
                 does not have, and a thread pool of its own could not be started: {e}"
            ))
        })?;
    let pool: &'static ThreadPool = Box::leak(Box::new(pool));
    *forked = Some((id, pool));
    Ok(pool)
}
