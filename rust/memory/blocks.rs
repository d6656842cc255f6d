//! The binding's allocator: large blocks mapped whole and reused whole.
//!
//! A fit allocates its large arrays afresh at every step (the Gauss-Newton
//! matrix, the damped copy of Levenberg-Marquardt, the cone step's dense
//! block: 22.5 GB in 2252 blocks above 2 MB over one n16 `identify`), in
//! sizes that change as groups leave the cone program. The system
//! allocator serves blocks below its adaptive threshold (up to 32 MB) from
//! its heaps and keeps what they free: identical n16 runs peaked anywhere
//! from 371 to 744 MB of resident memory for about 250 MB of live arrays,
//! beyond the 529 MB the run was admitted on. [`Blocks`] maps every block
//! of [`BIG`] bytes or more on its own (a header page, then the block,
//! rounded up to whole huge pages of [`CLASS`] bytes and aligned to one),
//! keeps freed ones up to [`KEEP_BYTES`], hands a kept one that is large
//! enough but not by more than a quarter to the next request, and returns
//! the rest to the kernel at once: resident memory is the live blocks plus
//! at most `KEEP_BYTES`, whatever the order of the steps. Smaller blocks,
//! and blocks aligned beyond a page, go to the system allocator.

use std::alloc::{GlobalAlloc, Layout, System};
use std::ptr;
use std::sync::Mutex;

/// Blocks of at least this many bytes are mapped whole.
pub const BIG: usize = 4 << 20;

/// Mapped blocks are whole multiples of this (a huge page).
pub const CLASS: usize = 2 << 20;

/// Most bytes of freed blocks kept for reuse: room for the two largest of
/// an n = 32 4 x 4 step (`J^T J` and the Levenberg-Marquardt factor, 336
/// MB each). With 256 MB they were never kept and every step mapped and
/// faulted them in afresh: n = 32's `identify` took 67 s of system time
/// and 455 s, now 42 s and 437 s, its peak 1.51 -> 2.01 GB (the same
/// model; one run each, 2026-11-27).
pub const KEEP_BYTES: usize = 1 << 30;

/// Most freed blocks kept for reuse.
const KEEP_BLOCKS: usize = 16;

/// The page size mapped blocks are aligned to.
const PAGE: usize = 4096;

/// Freed blocks kept for reuse, oldest first: (address, mapped bytes).
struct Kept {
    blocks: [(usize, usize); KEEP_BLOCKS],
    n: usize,
    bytes: usize,
}

/// The binding's global allocator (see the module notes).
pub struct Blocks {
    kept: Mutex<Kept>,
    /// Test hook: how many of the next fresh mappings fail.
    #[cfg(test)]
    failing_maps: std::sync::atomic::AtomicUsize,
    /// Test record: bytes of mappings given back to the kernel.
    #[cfg(test)]
    unmapped: std::sync::atomic::AtomicUsize,
}

impl Default for Blocks {
    fn default() -> Self {
        Self::new()
    }
}

/// Whether a block of this layout is mapped whole (the same answer at its
/// allocation and at its release).
fn mapped(layout: Layout) -> bool {
    layout.size() >= BIG && layout.align() <= PAGE
}

/// The mapped size of a block of `size` bytes: its header page and the
/// block, in whole huge pages (None on overflow).
fn class(size: usize) -> Option<usize> {
    size.checked_add(PAGE)?.checked_next_multiple_of(CLASS)
}

/// Whether a kept mapping of `len` bytes serves a request of `need`:
/// large enough, and larger by at most a quarter.
fn fits(len: usize, need: usize) -> bool {
    len >= need && len - need <= need / 4
}

/// The mapping a block handed out at `p` starts at, and its length (from
/// its header).
///
/// # Safety
/// `p` is a block that [`Blocks`] mapped and handed out.
unsafe fn mapping(p: *mut u8) -> (*mut u8, usize) {
    let base = unsafe { p.sub(PAGE) };
    (base, unsafe { base.cast::<usize>().read() })
}

impl Blocks {
    /// An allocator with nothing kept.
    pub const fn new() -> Self {
        Blocks {
            kept: Mutex::new(Kept {
                blocks: [(0, 0); KEEP_BLOCKS],
                n: 0,
                bytes: 0,
            }),
            #[cfg(test)]
            failing_maps: std::sync::atomic::AtomicUsize::new(0),
            #[cfg(test)]
            unmapped: std::sync::atomic::AtomicUsize::new(0),
        }
    }

    /// Give these (address, length) mappings back to the kernel.
    fn unmap_all(&self, mappings: &[(usize, usize)]) {
        for &(a, l) in mappings {
            unmap(a as *mut u8, l);
            #[cfg(test)]
            self.unmapped
                .fetch_add(l, std::sync::atomic::Ordering::SeqCst);
        }
    }

    /// A fresh mapping of `len` bytes ([`map`]), or null.
    fn map(&self, len: usize) -> *mut u8 {
        #[cfg(test)]
        {
            use std::sync::atomic::Ordering::SeqCst;
            let fail = self
                .failing_maps
                .fetch_update(SeqCst, SeqCst, |n| n.checked_sub(1));
            if fail.is_ok() {
                return ptr::null_mut();
            }
        }
        map(len)
    }

    /// Bytes of freed blocks kept now.
    pub fn kept_bytes(&self) -> usize {
        self.kept.lock().unwrap_or_else(|e| e.into_inner()).bytes
    }

    /// Give every kept mapping back to the kernel; the bytes given back.
    pub fn release(&self) -> usize {
        let (out, n) = {
            let mut k = self.kept.lock().unwrap_or_else(|e| e.into_inner());
            let out = k.blocks;
            let n = std::mem::replace(&mut k.n, 0);
            k.bytes = 0;
            (out, n)
        };
        self.unmap_all(&out[..n]);
        out[..n].iter().map(|&(_, l)| l).sum()
    }

    /// The kept mapping that [`fits`] `need` most closely (the last freed
    /// of equals), taken out of the kept ones.
    fn take(&self, need: usize) -> Option<*mut u8> {
        let mut k = self.kept.lock().unwrap_or_else(|e| e.into_inner());
        let n = k.n;
        let at = (0..n)
            .rev()
            .filter(|&i| fits(k.blocks[i].1, need))
            .min_by_key(|&i| k.blocks[i].1)?;
        let (addr, len) = k.blocks[at];
        k.blocks.copy_within(at + 1..n, at);
        k.n -= 1;
        k.bytes -= len;
        Some(addr as *mut u8)
    }

    /// Keep the freed mapping at `addr` of `len` bytes, unmapping the
    /// oldest kept ones (or this one) beyond the limits.
    fn give(&self, addr: *mut u8, len: usize) {
        let mut out = [(0usize, 0usize); KEEP_BLOCKS];
        let mut n_out = 0;
        {
            let mut k = self.kept.lock().unwrap_or_else(|e| e.into_inner());
            if len > KEEP_BYTES {
                out[0] = (addr as usize, len);
                n_out = 1;
            } else {
                while k.n > 0 && (k.n == KEEP_BLOCKS || k.bytes + len > KEEP_BYTES) {
                    out[n_out] = k.blocks[0];
                    n_out += 1;
                    k.bytes -= k.blocks[0].1;
                    let n = k.n;
                    k.blocks.copy_within(1..n, 0);
                    k.n -= 1;
                }
                let n = k.n;
                k.blocks[n] = (addr as usize, len);
                k.n += 1;
                k.bytes += len;
            }
        }
        // The system calls outside the lock.
        self.unmap_all(&out[..n_out]);
    }

    /// A block for `layout` (a mapping's block), zeroed when asked.
    fn get(&self, layout: Layout, zeroed: bool) -> *mut u8 {
        let Some(need) = class(layout.size()) else {
            return ptr::null_mut();
        };
        let (base, fresh) = match self.take(need) {
            Some(base) => (base, false),
            // Short of memory: what is kept goes back first.
            None => match self.map(need) {
                p if p.is_null() && self.release() > 0 => (self.map(need), true),
                p => (p, true),
            },
        };
        if base.is_null() {
            return base;
        }
        // SAFETY: the mapping holds its header page and at least
        // `layout.size()` bytes after it.
        unsafe {
            let p = base.add(PAGE);
            if zeroed && !fresh {
                ptr::write_bytes(p, 0, layout.size()); // fresh pages read as zero
            }
            p
        }
    }
}

/// A fresh anonymous mapping of `len` bytes aligned to a huge page, its
/// length written in its header, or null.
fn map(len: usize) -> *mut u8 {
    let Some(wide) = len.checked_add(CLASS) else {
        return ptr::null_mut();
    };
    // SAFETY: an anonymous private mapping at an address the kernel picks;
    // no existing memory is touched.
    let p = unsafe {
        libc::mmap(
            ptr::null_mut(),
            wide,
            libc::PROT_READ | libc::PROT_WRITE,
            libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
            -1,
            0,
        )
    };
    if p == libc::MAP_FAILED {
        return ptr::null_mut();
    }
    // Keep the aligned `len` bytes inside the wider mapping.
    let start = p as usize;
    let lead = start.next_multiple_of(CLASS) - start;
    let base = p.cast::<u8>().wrapping_add(lead);
    if lead > 0 {
        unmap(p.cast(), lead);
    }
    unmap(base.wrapping_add(len), CLASS - lead);
    super::advise_huge_pages(base, len);
    // SAFETY: `base` starts `len` bytes of the mapping, the first page its header.
    unsafe { base.cast::<usize>().write(len) };
    base
}

/// How much free memory at the top of a system allocator's heap it keeps
/// rather than give back (see [`system_heaps`]).
pub const TRIM_BYTES: usize = 16 << 20;

/// Tune the system allocator for the blocks it still serves (glibc's
/// `M_MMAP_THRESHOLD` and `M_TRIM_THRESHOLD`; elsewhere nothing to do).
///
/// glibc maps blocks above an adaptive threshold on their own and gives
/// back the free top of its heaps beyond another; it raises both when a
/// mapped block is freed (the second to twice the first, up to 64 MB).
/// With the large blocks served here instead it never raises them from
/// their 128 kB starts, and the heap was given back and faulted in again
/// at every Gauss-Newton evaluation (its Gram pieces and sums: 3.6 million
/// page faults per n16 `identify` against 0.34 million with glibc alone).
/// Blocks below [`BIG`] now come from the heaps, which keep up to
/// [`TRIM_BYTES`] free at their top: what glibc settles at by itself.
pub fn system_heaps() {
    #[cfg(target_env = "gnu")]
    // SAFETY: mallopt changes tuning parameters of glibc's allocator;
    // blocks already handed out are not affected.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, BIG as libc::c_int);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_BYTES as libc::c_int);
    }
}

/// Give back a mapping made by [`map`].
fn unmap(p: *mut u8, len: usize) {
    // SAFETY: `p` and `len` are those of a mapping from `map` that no one
    // uses any more (freed, and not kept).
    unsafe {
        libc::munmap(p.cast(), len);
    }
}

// SAFETY: every block handed out is either the system allocator's (small
// or over-aligned layouts, released to it by the same test on the layout)
// or the page-aligned rest of a mapping after its header page, at least
// the layout's size, that no other block overlaps, owned by the caller
// until released here.
unsafe impl GlobalAlloc for Blocks {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if mapped(layout) {
            self.get(layout, false)
        } else {
            unsafe { System.alloc(layout) }
        }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if mapped(layout) {
            self.get(layout, true)
        } else {
            unsafe { System.alloc_zeroed(layout) }
        }
    }

    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        if mapped(layout) {
            let (base, len) = unsafe { mapping(p) };
            self.give(base, len);
        } else {
            unsafe { System.dealloc(p, layout) }
        }
    }

    unsafe fn realloc(&self, p: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let Ok(new) = Layout::from_size_align(new_size, layout.align()) else {
            return ptr::null_mut();
        };
        if !mapped(layout) && !mapped(new) {
            return unsafe { System.realloc(p, layout, new_size) };
        }
        if mapped(layout) && mapped(new) {
            let (_, len) = unsafe { mapping(p) };
            if class(new_size).is_some_and(|need| need <= len) {
                return p; // the mapping already holds the new size
            }
        }
        let q = unsafe { self.alloc(new) };
        if !q.is_null() {
            // SAFETY: both blocks hold at least the bytes copied, and a
            // fresh block never overlaps a live one.
            unsafe {
                ptr::copy_nonoverlapping(p, q, layout.size().min(new_size));
                self.dealloc(p, layout);
            }
        }
        q
    }
}

#[cfg(test)]
#[path = "blocks_tests.rs"]
mod tests;
