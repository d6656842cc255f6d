//! Whether a loop's work is worth the thread pool, and the loops that run
//! on it or in order on the calling thread by that answer.
//!
//! A parallel loop started from a thread outside rayon's pool (every fit
//! the binding runs: the calling thread is Python's) hands its work to the
//! pool and sleeps until it is done: a wake-up and a sleep on each side,
//! tens of microseconds, however little the work. A local model's fit
//! (one point, SISO, n = 10, 200 lines: one task) crossed that way six
//! times a Levenberg-Marquardt step (the frozen forms, the lines, the
//! Gram unfolding, `J^T J`, the step's copy and its predicted decrease),
//! twice more for every trial point. Loops of little work run here, in
//! order; the results are the same to the last bit either way, since every
//! loop that goes through these helpers keeps its items' order (sums in
//! task order, results collected in place).

use rayon::prelude::*;

/// Work (in flops at the pace of the Gram kernels, about 100 us of it)
/// from which a loop of more than one item goes to the pool: below it the
/// hand-over costs more than the second core saves. Loops of scalar work
/// (eigenvalues, Hessenberg reductions) count their time at that pace.
/// Measured on two cores: 5e5 and 2e6 gave the gantry and n = 10 2x2 the
/// same times (medians of nine runs each).
pub const SPREAD_FLOPS: f64 = 2e6;

thread_local! {
    /// Whether every loop this thread starts runs in order here ([`in_order_here`]).
    static HERE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

#[cfg(test)]
thread_local! {
    /// A test's answer for every loop this thread starts ([`forced`]).
    static FORCED: std::cell::Cell<Option<bool>> = const { std::cell::Cell::new(None) };
}

/// Whether `items` pieces of `flops` work in all are worth the pool: never
/// on a thread told to run its loops here ([`in_order_here`]).
pub fn worth_spreading(items: usize, flops: f64) -> bool {
    #[cfg(test)]
    if let Some(spread) = FORCED.with(std::cell::Cell::get) {
        return spread && items > 1;
    }
    items > 1 && flops >= SPREAD_FLOPS && !kept_here()
}

/// From now on, every loop this thread starts runs in order on it (`here`)
/// or by its work ([`worth_spreading`]); returns the setting before. For a
/// fit that runs beside others on threads of their own (a thread pool of
/// the caller's, each thread one fit): handed to the pool too, their loops
/// would wait for each other's there, more threads than cores. The results
/// are the same to the last bit either way.
pub fn in_order_here(here: bool) -> bool {
    HERE.with(|c| c.replace(here))
}

/// Whether this thread runs its loops in order whatever their work
/// ([`in_order_here`]): the dense kernels ask too.
pub fn kept_here() -> bool {
    HERE.with(std::cell::Cell::get)
}

/// `f` with every loop this thread starts on the pool (`spread`) or in
/// order here, whatever its work: for tests that both ways give the same
/// bits.
#[cfg(test)]
pub(crate) fn forced<T>(spread: bool, f: impl FnOnce() -> T) -> T {
    let before = FORCED.with(|c| c.replace(Some(spread)));
    let out = f();
    FORCED.with(|c| c.set(before));
    out
}

/// `op` on every item, each thread with its own `init()` state: on the pool
/// when `spread`, else in order on this thread with one state. Stops at the
/// first error (on the pool: at one of them).
pub fn try_for_each_init<T, W, E, I, F>(
    items: Vec<T>,
    spread: bool,
    init: I,
    op: F,
) -> Result<(), E>
where
    T: Send,
    E: Send,
    I: Fn() -> W + Sync + Send,
    F: Fn(&mut W, T) -> Result<(), E> + Sync + Send,
{
    if spread {
        items.into_par_iter().try_for_each_init(init, op)
    } else {
        let mut state = init();
        items.into_iter().try_for_each(|item| op(&mut state, item))
    }
}

/// `op` of every item, in the items' order: on the pool when `spread`,
/// else in order on this thread.
pub fn map<I, T, R, F>(items: I, spread: bool, op: F) -> Vec<R>
where
    I: IntoParallelIterator<Item = T> + IntoIterator<Item = T>,
    T: Send,
    R: Send,
    F: Fn(T) -> R + Sync + Send,
{
    if spread {
        items.into_par_iter().map(op).collect()
    } else {
        items.into_iter().map(op).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pool_only_for_more_than_one_item_of_enough_work() {
        assert!(worth_spreading(2, SPREAD_FLOPS));
        assert!(!worth_spreading(1, 1e12));
        assert!(!worth_spreading(8, SPREAD_FLOPS * 0.99));
    }

    #[test]
    fn a_thread_told_to_keep_its_loops_runs_none_on_the_pool() {
        let before = in_order_here(true);
        assert!(!worth_spreading(8, SPREAD_FLOPS * 1e3));
        assert!(in_order_here(before));
        assert!(worth_spreading(8, SPREAD_FLOPS * 1e3));
        // another thread's setting is its own
        std::thread::scope(|s| {
            s.spawn(|| {
                in_order_here(true);
            });
        });
        assert!(worth_spreading(8, SPREAD_FLOPS * 1e3));
    }

    #[test]
    fn both_ways_give_the_items_in_order() {
        for spread in [false, true] {
            let out = map(0..100u64, spread, |k: u64| k * k);
            assert_eq!(out, (0..100).map(|k| k * k).collect::<Vec<_>>());
            let seen = std::sync::Mutex::new(Vec::new());
            let run = try_for_each_init(
                (0..50).collect(),
                spread,
                || 0usize,
                |count, k: usize| {
                    *count += 1;
                    seen.lock().map_err(|_| "poisoned")?.push(k);
                    if k == 60 {
                        return Err("never");
                    }
                    Ok(())
                },
            );
            assert_eq!(run, Ok(()));
            let mut seen = seen.into_inner().unwrap_or_default();
            if spread {
                seen.sort_unstable();
            }
            assert_eq!(seen, (0..50).collect::<Vec<_>>());
        }
    }

    #[test]
    fn an_error_stops_the_loop_in_order() {
        let visited = std::sync::atomic::AtomicUsize::new(0);
        let run = try_for_each_init(
            (0..10).collect(),
            false,
            || (),
            |_, k: usize| {
                visited.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if k == 3 {
                    Err(k)
                } else {
                    Ok(())
                }
            },
        );
        assert_eq!(run, Err(3));
        assert_eq!(visited.into_inner(), 4);
    }
}
