use super::*;

/// Bytes `a` gave back to the kernel so far.
fn unmapped(a: &Blocks) -> usize {
    a.unmapped.load(std::sync::atomic::Ordering::SeqCst)
}

/// Whether the page at `p` is mapped (`mincore` fails with ENOMEM where
/// not). Only for blocks the test holds: a range given back may be mapped
/// again at once by another test's thread.
fn is_mapped(p: *mut u8) -> bool {
    let page = (p as usize) / PAGE * PAGE;
    let mut vec = [0u8; 1];
    unsafe { libc::mincore(page as *mut libc::c_void, PAGE, vec.as_mut_ptr()) == 0 }
}

/// A block whose mapping is `mb` MB.
fn of_mb(mb: usize) -> Layout {
    big((mb << 20) - PAGE)
}

fn big(size: usize) -> Layout {
    Layout::from_size_align(size, 8).expect("a valid layout")
}

/// Fill `len` bytes at `p` with `byte`.
fn fill(p: *mut u8, len: usize, byte: u8) {
    unsafe { ptr::write_bytes(p, byte, len) };
}

/// Whether `len` bytes at `p` all equal `byte`.
fn all(p: *const u8, len: usize, byte: u8) -> bool {
    unsafe { std::slice::from_raw_parts(p, len) }
        .iter()
        .all(|&b| b == byte)
}

#[test]
fn small_blocks_go_to_the_system_allocator_and_are_not_kept() {
    let a = Blocks::new();
    let layout = big(BIG - 1);
    let p = unsafe { a.alloc(layout) };
    assert!(!p.is_null());
    fill(p, layout.size(), 7);
    unsafe { a.dealloc(p, layout) };
    assert_eq!(a.kept_bytes(), 0);
    // Over-aligned large blocks too.
    let over = Layout::from_size_align(BIG, 2 * PAGE).expect("a valid layout");
    let q = unsafe { a.alloc(over) };
    assert!(!q.is_null() && (q as usize).is_multiple_of(2 * PAGE));
    unsafe { a.dealloc(q, over) };
    assert_eq!(a.kept_bytes(), 0);
}

#[test]
fn a_freed_block_is_kept_and_handed_to_the_next_request_of_its_class() {
    let a = Blocks::new();
    let first = big(BIG + 1);
    let p = unsafe { a.alloc(first) };
    assert!(!p.is_null() && (p as usize).is_multiple_of(PAGE));
    fill(p, first.size(), 1);
    unsafe { a.dealloc(p, first) };
    let len = class(first.size()).expect("no overflow");
    assert_eq!(len, BIG + CLASS); // the header page and the block, in huge pages
    assert_eq!(a.kept_bytes(), len);
    // Another size in the same class gets the same block ...
    let second = big(BIG + CLASS - PAGE - 8);
    let q = unsafe { a.alloc(second) };
    assert_eq!(q, p);
    assert_eq!(a.kept_bytes(), 0);
    // ... and a size in the next class a fresh one.
    let third = big(BIG + CLASS + 8);
    let r = unsafe { a.alloc(third) };
    assert!(!r.is_null() && r != p);
    unsafe {
        a.dealloc(q, second);
        a.dealloc(r, third);
    }
    assert_eq!(
        a.kept_bytes(),
        len + class(third.size()).expect("no overflow")
    );
}

#[test]
fn a_kept_block_up_to_a_quarter_larger_serves_a_request() {
    let a = Blocks::new();
    assert_eq!(class(of_mb(10).size()), Some(10 << 20));
    let ten = unsafe { a.alloc(of_mb(10)) };
    let six = unsafe { a.alloc(of_mb(6)) };
    unsafe {
        a.dealloc(ten, of_mb(10));
        a.dealloc(six, of_mb(6));
    }
    // 8 MB: the 10 MB mapping (a quarter larger), not the 6 MB one.
    let p = unsafe { a.alloc(of_mb(8)) };
    assert_eq!(p, ten);
    assert_eq!(a.kept_bytes(), 6 << 20);
    // Again: the 6 MB one is too small, a fresh mapping.
    let q = unsafe { a.alloc(of_mb(8)) };
    assert!(q != six && q != ten);
    // The 10 MB mapping goes back whole (its header, not the request, says so).
    unsafe { a.dealloc(p, of_mb(8)) };
    assert_eq!(a.kept_bytes(), (6 + 10) << 20);
    // 6 MB: the 6 MB mapping, not the 10 MB one (two thirds larger).
    let r = unsafe { a.alloc(of_mb(6)) };
    assert_eq!(r, six);
    unsafe {
        a.dealloc(q, of_mb(8));
        a.dealloc(r, of_mb(6));
    }
    assert_eq!(a.kept_bytes(), (6 + 10 + 8) << 20);
    // Mappings start on a huge page, the block one page in.
    assert_eq!((p as usize - PAGE) % CLASS, 0);
}

#[test]
fn taking_a_kept_block_leaves_the_others_as_they_were() {
    let a = Blocks::new();
    let [six, eight, ten] = [6, 8, 10].map(|mb| unsafe { a.alloc(of_mb(mb)) });
    unsafe {
        a.dealloc(six, of_mb(6));
        a.dealloc(eight, of_mb(8));
        a.dealloc(ten, of_mb(10));
    }
    // The middle one first, then the others: each exactly once.
    assert_eq!(unsafe { a.alloc(of_mb(8)) }, eight);
    assert_eq!(unsafe { a.alloc(of_mb(10)) }, ten);
    assert_eq!(unsafe { a.alloc(of_mb(6)) }, six);
    assert_eq!(a.kept_bytes(), 0);
    let fresh = unsafe { a.alloc(of_mb(6)) };
    assert!(![six, eight, ten].contains(&fresh));
    unsafe {
        for (p, mb) in [(six, 6), (eight, 8), (ten, 10), (fresh, 6)] {
            a.dealloc(p, of_mb(mb));
        }
    }
}

#[test]
fn a_kept_block_asked_for_zeroed_reads_zero() {
    let a = Blocks::new();
    let layout = big(BIG);
    let p = unsafe { a.alloc(layout) };
    fill(p, layout.size(), 0xAB);
    unsafe { a.dealloc(p, layout) };
    let q = unsafe { a.alloc_zeroed(layout) };
    assert_eq!(q, p);
    assert!(all(q, layout.size(), 0));
    // A fresh mapping reads zero as well.
    let fresh = big(3 * BIG);
    let r = unsafe { a.alloc_zeroed(fresh) };
    assert!(all(r, fresh.size(), 0));
    unsafe {
        a.dealloc(q, layout);
        a.dealloc(r, fresh);
    }
}

#[test]
fn kept_blocks_stay_within_their_limits_the_oldest_given_back_first() {
    let a = Blocks::new();
    let layout = big(BIG);
    let len = class(BIG).expect("no overflow");
    // More blocks than may be kept (untouched: mapped, never resident).
    let ptrs: Vec<*mut u8> = (0..KEEP_BLOCKS + 3)
        .map(|_| unsafe { a.alloc(layout) })
        .collect();
    for &p in &ptrs {
        unsafe { a.dealloc(p, layout) };
        assert!(a.kept_bytes() <= KEEP_BYTES);
    }
    assert_eq!(a.kept_bytes(), KEEP_BLOCKS * len);
    // The last freed comes back first; the three oldest were given back.
    let q = unsafe { a.alloc(layout) };
    assert_eq!(q, ptrs[ptrs.len() - 1]);
    unsafe { a.dealloc(q, layout) };
    // Blocks whose total passes KEEP_BYTES: the oldest leave.
    let large = big(KEEP_BYTES / 2);
    let x = unsafe { a.alloc(large) };
    let y = unsafe { a.alloc(large) };
    unsafe {
        a.dealloc(x, large);
        a.dealloc(y, large);
    }
    assert!(a.kept_bytes() <= KEEP_BYTES);
    let z = unsafe { a.alloc(large) };
    assert_eq!(z, y);
    unsafe { a.dealloc(z, large) };
    // A block larger than KEEP_BYTES is never kept.
    let before = a.kept_bytes();
    let huge = big(KEEP_BYTES + 1);
    let h = unsafe { a.alloc(huge) };
    assert!(!h.is_null());
    unsafe { a.dealloc(h, huge) };
    assert_eq!(a.kept_bytes(), before);
}

#[test]
fn realloc_keeps_the_contents_across_classes_and_allocators() {
    let a = Blocks::new();
    let small = big(1024);
    let p = unsafe { a.alloc(small) };
    fill(p, small.size(), 3);
    // Small to large: the contents move to a mapped block.
    let first = BIG + 100;
    let p = unsafe { a.realloc(p, small, first) };
    assert!(all(p, small.size(), 3));
    fill(p, first, 4);
    // Within the class: the same block.
    let second = BIG + CLASS - PAGE;
    assert_eq!(class(first), class(second));
    let q = unsafe { a.realloc(p, big(first), second) };
    assert_eq!(q, p);
    assert!(all(q, first, 4));
    // To the next class: a new block with the contents, the old one kept.
    let third = BIG + 2 * CLASS;
    let r = unsafe { a.realloc(q, big(second), third) };
    assert!(r != q && all(r, first, 4));
    assert_eq!(a.kept_bytes(), class(second).expect("no overflow"));
    // Large to small: the leading bytes, in the system allocator's block.
    let s = unsafe { a.realloc(r, big(third), 512) };
    assert!(all(s, 512, 4));
    unsafe { a.dealloc(s, big(512)) };
}

#[test]
fn blocks_used_from_several_threads_never_overlap() {
    let a = std::sync::Arc::new(Blocks::new());
    let threads: Vec<_> = (0..4u8)
        .map(|t| {
            let a = a.clone();
            std::thread::spawn(move || {
                for round in 0..20usize {
                    let layout = big(BIG + (round % 3) * CLASS);
                    let p = unsafe { a.alloc(layout) };
                    assert!(!p.is_null());
                    let byte = t.wrapping_mul(31).wrapping_add(round as u8);
                    fill(p, layout.size(), byte);
                    std::thread::yield_now();
                    assert!(all(p, layout.size(), byte));
                    unsafe { a.dealloc(p, layout) };
                }
            })
        })
        .collect();
    for t in threads {
        t.join().expect("no thread panicked");
    }
    assert!(a.kept_bytes() <= KEEP_BYTES);
}

#[test]
fn release_gives_every_kept_mapping_back() {
    let a = Blocks::new();
    let layout = big(BIG);
    let p = unsafe { a.alloc(layout) };
    let q = unsafe { a.alloc(layout) };
    unsafe {
        a.dealloc(p, layout);
        a.dealloc(q, layout);
    }
    let len = class(BIG).expect("no overflow");
    assert_eq!(a.kept_bytes(), 2 * len);
    assert_eq!(a.release(), 2 * len);
    assert_eq!(a.kept_bytes(), 0);
    assert_eq!(a.release(), 0);
    // The next request maps afresh.
    let r = unsafe { a.alloc(layout) };
    assert!(!r.is_null());
    unsafe { a.dealloc(r, layout) };
    assert_eq!(a.kept_bytes(), len);
}

#[test]
fn kept_mappings_stay_mapped_and_the_others_are_given_back() {
    let a = Blocks::new();
    let layout = of_mb(6);
    let ptrs: Vec<*mut u8> = (0..KEEP_BLOCKS + 2)
        .map(|_| unsafe { a.alloc(layout) })
        .collect();
    for &p in &ptrs {
        unsafe { a.dealloc(p, layout) };
    }
    // The two oldest went back to the kernel; the others are kept, mapped.
    assert_eq!(unmapped(&a), 2 * (6 << 20));
    assert!(ptrs[2..].iter().all(|&p| is_mapped(p)));
    assert_eq!(a.release(), KEEP_BLOCKS * (6 << 20));
    assert_eq!(unmapped(&a), (KEEP_BLOCKS + 2) * (6 << 20));
    // A block larger than KEEP_BYTES goes back at once.
    let huge = of_mb((KEEP_BYTES >> 20) + 2);
    let h = unsafe { a.alloc(huge) };
    assert!(is_mapped(h));
    unsafe { a.dealloc(h, huge) };
    assert_eq!(
        unmapped(&a),
        (KEEP_BLOCKS + 2) * (6 << 20) + KEEP_BYTES + (2 << 20)
    );
    assert_eq!(a.kept_bytes(), 0);
}

#[test]
fn blocks_of_exactly_keep_bytes_in_all_are_kept() {
    let a = Blocks::new();
    let half = of_mb(KEEP_BYTES >> 21);
    let x = unsafe { a.alloc(half) };
    let y = unsafe { a.alloc(half) };
    unsafe {
        a.dealloc(x, half);
        a.dealloc(y, half);
    }
    assert_eq!(a.kept_bytes(), KEEP_BYTES);
    assert_eq!(unmapped(&a), 0);
    let whole = of_mb(KEEP_BYTES >> 20);
    let z = unsafe { a.alloc(whole) };
    unsafe { a.dealloc(z, whole) };
    // Kept, the two halves giving way to it.
    assert_eq!(a.kept_bytes(), KEEP_BYTES);
    assert_eq!(unmapped(&a), KEEP_BYTES);
    // So a half maps afresh (the whole one is too large to serve it) and
    // the whole one stays kept (the kernel may hand a freed address straight
    // back, so the kept bytes say it, not the address).
    let h = unsafe { a.alloc(half) };
    assert_eq!(a.kept_bytes(), KEEP_BYTES);
    unsafe { a.dealloc(h, half) };
    a.release();
}

#[test]
fn a_kept_mapping_more_than_a_quarter_larger_is_not_used() {
    let a = Blocks::new();
    let ten = unsafe { a.alloc(of_mb(10)) };
    unsafe { a.dealloc(ten, of_mb(10)) };
    let p = unsafe { a.alloc(of_mb(6)) };
    assert!(p != ten);
    assert_eq!(a.kept_bytes(), 10 << 20);
    unsafe { a.dealloc(p, of_mb(6)) };
    a.release();
}

#[test]
fn a_failed_mapping_gives_the_kept_ones_back_and_tries_once_more() {
    use std::sync::atomic::Ordering::SeqCst;
    let a = Blocks::new();
    // Nothing kept: the failure is the caller's.
    a.failing_maps.store(1, SeqCst);
    assert!(unsafe { a.alloc(of_mb(6)) }.is_null());
    // Something kept, but nothing that fits: given back, and the second try maps.
    let ten = unsafe { a.alloc(of_mb(10)) };
    unsafe { a.dealloc(ten, of_mb(10)) };
    a.failing_maps.store(1, SeqCst);
    let p = unsafe { a.alloc(of_mb(6)) };
    assert!(!p.is_null() && is_mapped(p));
    assert_eq!(unmapped(&a), 10 << 20);
    assert_eq!(a.kept_bytes(), 0);
    // Both tries failing: null, and what was kept is gone.
    unsafe { a.dealloc(p, of_mb(6)) };
    a.failing_maps.store(2, SeqCst);
    assert!(unsafe { a.alloc(of_mb(8)) }.is_null());
    assert_eq!(a.kept_bytes(), 0);
    assert_eq!(unmapped(&a), 16 << 20);
}
