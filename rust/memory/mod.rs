//! Memory: the large arrays of a fit allocated fallibly, and the binding's
//! allocator ([`blocks`]). The estimate of what a fit needs, so that a run
//! too large for the machine is refused before it starts, is
//! [`crate::fit::estimate`], beside what it sizes.
//!
//! Rust aborts the process when an ordinary allocation fails, and faer's
//! constructors panic; neither may happen inside Python. Every array whose
//! size grows with the problem (the Gauss-Newton matrix, the per-point Gram
//! matrices and their pieces, the residuals, the cone step's dense block,
//! the time records' Jacobian blocks) is made here instead, and a failure
//! is [`Error::OutOfMemory`] with the size and the purpose of the array.
//! What is left to infallible allocation is small (vectors over the free
//! parameters, per-line scratch). Clarabel allocates its own arrays; the
//! cone step first checks that its estimate can be had ([`probe`]).

#[cfg(target_os = "linux")]
pub mod blocks;

pub use crate::error::human;
use crate::error::{Error, Result};
use faer::Mat;
use rayon::prelude::*;
use std::cell::Cell;
use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicI64, Ordering};

thread_local! {
    /// Set while this thread allocates through a fallible helper, or inside
    /// a call that was probed first (Clarabel's set-up).
    static GUARDED: Cell<bool> = const { Cell::new(false) };
}

/// Whether the allocation this thread is making goes through a fallible
/// helper or a probed call: for a test's allocator that checks that every
/// large array of a fit is made so.
#[doc(hidden)]
pub fn guarded_allocation() -> bool {
    GUARDED.with(Cell::get)
}

/// Run `f` with this thread's allocations marked as guarded.
pub(crate) fn guarded<T>(f: impl FnOnce() -> T) -> T {
    let before = GUARDED.with(|g| g.replace(true));
    let out = f();
    GUARDED.with(|g| g.set(before));
    out
}

/// Test hook: how many fallible allocations may still succeed before one
/// fails (negative: none is made to fail).
static FAIL_AFTER: AtomicI64 = AtomicI64::new(-1);

/// Make the fallible allocation after the next `count` fail (once), or
/// none with `None`: for tests of the out-of-memory path. The count is
/// shared by all threads.
#[doc(hidden)]
pub fn fail_allocation_after(count: Option<usize>) {
    let v = count.map_or(-1, |c| i64::try_from(c).unwrap_or(i64::MAX));
    FAIL_AFTER.store(v, Ordering::SeqCst);
}

/// Whether the test hook is armed and has not fired yet.
#[doc(hidden)]
pub fn allocation_failure_pending() -> bool {
    FAIL_AFTER.load(Ordering::SeqCst) >= 0
}

/// Whether the test hook fails this allocation.
fn injected() -> bool {
    if FAIL_AFTER.load(Ordering::Relaxed) < 0 {
        return false;
    }
    let before = FAIL_AFTER.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |c| match c {
        c if c > 0 => Some(c - 1),
        0 => Some(-1),
        _ => None,
    });
    before == Ok(0)
}

/// [`Error::OutOfMemory`] for an allocation of `bytes` for `what` that
/// failed elsewhere (a library's own fallible constructor).
pub fn out_of_memory_for(bytes: usize, what: &'static str) -> Error {
    Error::OutOfMemory { bytes, what }
}

use out_of_memory_for as out_of_memory;

/// Arrays of at least this many bytes are advised into transparent huge
/// pages ([`advise_huge_pages`]).
pub const HUGE_PAGES_FROM: usize = 4 << 20;

/// Ask the kernel to back `bytes` bytes at `ptr`, an allocation just made,
/// with transparent huge pages (Linux `madvise(MADV_HUGEPAGE)`; a no-op
/// elsewhere and for arrays below [`HUGE_PAGES_FROM`]). A fit's large
/// arrays are fresh memory whenever the allocator maps them anew (the
/// binding's allocator when it keeps no freed block of about their size,
/// `blocks`; the system allocator above its threshold), and fresh memory
/// costs a page fault and the kernel's zeroing at its first write: one per
/// 4 kB page, one per 2 MB huge page. Kernels whose huge pages are "madvise" only (Debian's
/// default) use them for these arrays and nowhere else; the contents and
/// the memory used do not change. Measured on the n16 rung's
/// Levenberg-Marquardt steps (`benches/bench_pages.py`, medians of 5):
/// 3.4 thousand page faults per step without, 0.4 thousand with; 71.5
/// against 66.3 ms per step, the same theta to the last bit.
pub fn advise_huge_pages(ptr: *const u8, bytes: usize) {
    #[cfg(target_os = "linux")]
    if let Some((start, len)) = whole_pages(ptr as usize, bytes) {
        // SAFETY: [start, start + len) lies inside the allocation of `bytes`
        // bytes at `ptr` that the caller owns; MADV_HUGEPAGE changes only
        // how the kernel backs those pages, never their contents or whether
        // they are valid. A refusal (a kernel without transparent huge
        // pages) leaves them as they were.
        unsafe {
            libc::madvise(start as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (ptr, bytes);
}

/// The whole 4 kB pages inside `bytes` bytes at address `at`, as (start,
/// length), for an array of at least [`HUGE_PAGES_FROM`] bytes.
fn whole_pages(at: usize, bytes: usize) -> Option<(usize, usize)> {
    const PAGE: usize = 4096;
    if bytes < HUGE_PAGES_FROM {
        return None;
    }
    let start = at.checked_next_multiple_of(PAGE)?;
    let end = at.checked_add(bytes)? / PAGE * PAGE;
    (end > start).then(|| (start, end - start))
}

/// `len` copies of `value`, or [`Error::OutOfMemory`] naming `what`.
pub fn try_vec<T: Clone>(len: usize, value: T, what: &'static str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    try_grow(&mut v, len, what)?;
    v.resize(len, value);
    Ok(v)
}

/// Make room for `additional` more elements in `v` (exactly), or
/// [`Error::OutOfMemory`] naming `what`.
pub fn try_grow<T>(v: &mut Vec<T>, additional: usize, what: &'static str) -> Result<()> {
    let bytes = v
        .len()
        .saturating_add(additional)
        .saturating_mul(std::mem::size_of::<T>());
    if bytes == 0 {
        return Ok(());
    }
    if injected() {
        return Err(out_of_memory(bytes, what));
    }
    guarded(|| v.try_reserve_exact(additional)).map_err(|_| out_of_memory(bytes, what))?;
    advise_huge_pages(v.as_ptr().cast(), v.capacity() * std::mem::size_of::<T>());
    Ok(())
}

/// A `rows x cols` matrix with entries `f(i, j)`, or
/// [`Error::OutOfMemory`] naming `what`.
pub fn try_mat(
    rows: usize,
    cols: usize,
    f: impl FnMut(usize, usize) -> f64,
    what: &'static str,
) -> Result<Mat<f64>> {
    let bytes = rows.saturating_mul(cols).saturating_mul(8);
    if bytes > 0 && injected() {
        return Err(out_of_memory(bytes, what));
    }
    let mut m: Mat<f64> = Mat::new();
    guarded(|| m.try_reserve(rows, cols)).map_err(|_| out_of_memory(bytes, what))?;
    advise_huge_pages(m.as_ptr().cast(), bytes);
    // Within the capacity just reserved: no further allocation.
    m.resize_with(rows, cols, f);
    Ok(m)
}

/// A `rows x cols` column-major array with entries `f(i, j)`, its columns
/// written in parallel and nothing written before, or
/// [`Error::OutOfMemory`] naming `what`: for the dense matrices of every
/// step (`J^T J`, the Levenberg-Marquardt factor: 336 MB each at n = 32
/// 4 x 4), which a serial pass of zeros and then of values kept one core
/// waiting. On the pool when `spread`, else in order on this thread (for
/// matrices too small to be worth the pool:
/// [`crate::base::spread::worth_spreading`]).
pub fn try_par_columns(
    rows: usize,
    cols: usize,
    f: impl Fn(usize, usize) -> f64 + Sync,
    spread: bool,
    what: &'static str,
) -> Result<Vec<f64>> {
    let fill = |j: usize, col: &mut [MaybeUninit<f64>]| {
        for (i, slot) in col.iter_mut().enumerate() {
            slot.write(f(i, j));
        }
    };
    // SAFETY: `fill` writes every slot of the column it is given.
    unsafe { try_par_columns_by(rows, cols, fill, spread, what) }
}

/// As [`try_par_columns`], every column `j` written whole by
/// `fill(j, column)`.
///
/// # Safety
///
/// `fill` must write every one of the `rows` slots of the column it is
/// given: the result is read as initialised.
pub unsafe fn try_par_columns_by(
    rows: usize,
    cols: usize,
    fill: impl Fn(usize, &mut [MaybeUninit<f64>]) + Sync,
    spread: bool,
    what: &'static str,
) -> Result<Vec<f64>> {
    let len = rows.saturating_mul(cols);
    let mut v = Vec::new();
    try_grow(&mut v, len, what)?;
    if rows > 0 {
        let room = &mut v.spare_capacity_mut()[..len];
        if spread {
            room.par_chunks_mut(rows)
                .enumerate()
                .for_each(|(j, col)| fill(j, col));
        } else {
            room.chunks_mut(rows)
                .enumerate()
                .for_each(|(j, col)| fill(j, col));
        }
    }
    // SAFETY: `try_grow` made room for `len` values and `fill` wrote every
    // slot of each of the `cols` chunks of `rows` slots (the caller's
    // promise).
    unsafe { v.set_len(len) };
    Ok(v)
}

/// A `rows x cols` matrix of zeros, or [`Error::OutOfMemory`] naming `what`.
pub fn try_zeros(rows: usize, cols: usize, what: &'static str) -> Result<Mat<f64>> {
    try_mat(rows, cols, |_, _| 0.0, what)
}

/// Check that `bytes` can be allocated now, and give them back: before a
/// library call that allocates about that much and would abort the
/// process if it could not (Clarabel). Not a guarantee (another thread may
/// take the memory meanwhile), but it turns the common case, a limit the
/// run is far beyond, into [`Error::OutOfMemory`].
pub fn probe(bytes: usize, what: &'static str) -> Result<()> {
    let mut v: Vec<u8> = Vec::new();
    try_grow(&mut v, bytes, what)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_whole_pages_of_large_arrays_are_advised() {
        let big = HUGE_PAGES_FROM;
        assert_eq!(whole_pages(4096, big - 1), None);
        assert_eq!(whole_pages(4096, big), Some((4096, big)));
        // An unaligned start and end: the pages wholly inside.
        assert_eq!(whole_pages(4096 + 16, big), Some((8192, big - 4096)));
        assert_eq!(whole_pages(usize::MAX - 10, big), None);
        // A large array's advice leaves its contents as they were.
        let v = try_vec(big / 8 + 3, 1.5f64, "v").unwrap();
        assert!(v.iter().all(|&x| x == 1.5));
    }

    #[test]
    fn an_impossible_allocation_is_an_error_naming_its_size() {
        // More than any address space: the allocator refuses at once.
        let len = usize::MAX / 16;
        let e = try_vec(len, 0.0f64, "a test array").unwrap_err();
        match &e {
            Error::OutOfMemory { bytes, what } => {
                assert_eq!(*bytes, len * 8);
                assert_eq!(*what, "a test array");
            }
            other => panic!("expected OutOfMemory, got {other:?}"),
        }
        assert!(e.to_string().contains("GB for a test array"), "{e}");
        let e = try_zeros(1 << 31, 1 << 31, "a test matrix").unwrap_err();
        // 2^62 entries of 8 bytes: the size saturates.
        assert!(matches!(e, Error::OutOfMemory { bytes, .. } if bytes == usize::MAX));
        assert!(probe(usize::MAX / 2, "a probe").is_err());
        let e = try_par_columns(1 << 31, 1 << 31, |_, _| 0.0, true, "a test array").unwrap_err();
        assert!(matches!(e, Error::OutOfMemory { bytes, .. } if bytes == usize::MAX));
    }

    /// Every entry where a column-major array keeps it, also when the
    /// columns are many (rayon splits them among the threads) and when
    /// there are none, on the pool and in order.
    #[test]
    fn par_columns_hold_every_entry_in_column_major_order() {
        for spread in [true, false] {
            for (rows, cols) in [(3, 4), (1, 1000), (257, 65)] {
                let f = |i: usize, j: usize| (1000 * i + j) as f64;
                let v = try_par_columns(rows, cols, f, spread, "v").unwrap();
                let want: Vec<f64> = (0..rows * cols).map(|k| f(k % rows, k / rows)).collect();
                assert_eq!(v, want);
            }
            assert!(try_par_columns(0, 5, |_, _| 1.0, spread, "v")
                .unwrap()
                .is_empty());
            assert!(try_par_columns(5, 0, |_, _| 1.0, spread, "v")
                .unwrap()
                .is_empty());
        }
    }

    #[test]
    fn possible_allocations_hold_what_was_asked() {
        let v = try_vec(1000, 2.5f64, "v").unwrap();
        assert_eq!(v.len(), 1000);
        assert!(v.iter().all(|&x| x == 2.5));
        let m = try_mat(3, 4, |i, j| (10 * i + j) as f64, "m").unwrap();
        assert_eq!((m.nrows(), m.ncols()), (3, 4));
        assert_eq!(m[(2, 3)], 23.0);
        assert!(probe(1 << 20, "a probe").is_ok());
        assert_eq!(human(2_950_000_000), "2.95 GB");
        assert_eq!(human(340_000_000), "340 MB");
    }
}
