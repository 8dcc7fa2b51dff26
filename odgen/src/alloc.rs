//! The allocator of the `odgen` binary: the arena where it is open (`crate::arena`: `odgen
//! check` over enough files, on transparent huge pages), the system's allocator (glibc's
//! `malloc` on Linux) for everything else.
//!
//! Reading a file builds a model of many small parts (a `String` per entry name, the entries of
//! CompactSubObj arrays, diagnostics): about 45,000 allocations per pass over the 61-file
//! corpus. Until the arena took them, the binary called mimalloc for them: glibc's `malloc` and
//! `free` took about 190 instructions per pair there, mimalloc a fraction of that (callgrind:
//! 83.2 -> 70.5 M instructions per corpus pass). Once the arena served nearly all of a corpus
//! check (blocks up to 512 KiB; 27 KB of the run's allocations left to the other allocator),
//! what mimalloc still cost was its setting up, in every run: four `cpuid` instructions (each
//! an exit to the hypervisor on a virtual machine), a dozen system calls (reading two files of
//! `/proc` and `/sys`, three mappings and their names) and 37 fresh pages. Dropped for glibc's
//! allocator (dist binaries, alternating runs from Python, 1,000 of each or 400 where marked):
//! `odgen check` of a file that does not exist 1.28 -> 0.90 ms; of one 44 KB file (400) 1.70 ->
//! 1.28 ms; the corpus 4.37 -> 4.31 ms, with `-j1` (400) 7.31 -> 6.78 ms; `odgen dump` of the
//! 44 KB file (400) 3.71 -> 3.52 ms. The reader alone, in process and without the arena
//! (`bench-read --jobs 1`), is 6% slower (3.92 -> 4.17 ms a pass): a program that reads many
//! files in one process chooses its own allocator, and the `eds` library leaves it to it.

use std::alloc::{GlobalAlloc, Layout, System};

use crate::arena;

/// Tunes glibc's allocator for a short process, first thing in `main`: freed memory at the top
/// of its heap is not given back to the kernel (`M_TRIM_THRESHOLD`, 128 KiB by default: a
/// file's model freed, then the next one's allocated, shrank the heap and grew it again onto
/// fresh pages), and the heap grows 1 MiB at a time (`M_TOP_PAD`: fewer `brk` calls; room not
/// written costs no memory). `odgen check` of one 44 KB file, 400 alternating runs: 1.67 ->
/// 1.42 ms. Large blocks are still mapped on their own (`M_MMAP_THRESHOLD` is left alone), so
/// that a large buffer freed is given back at once and memory stays within its bounds on
/// hostile input (`tests/memory.rs`).
///
/// Under an address-space limit (`ulimit -v`) all threads share the one heap (`M_ARENA_MAX` 1):
/// glibc gives each new thread a heap of its own, reserving 64 MiB of address space for it (128
/// MiB for a moment, to align it), and under "10 x the input + 64 MB" (`tests/memory.rs`) that
/// reservation, when it succeeded, left too little for the large blocks: `odgen dump` (two
/// threads) of a 4 MB value aborted in about one run of 30 (none in 150 with one heap). Without
/// a limit each thread keeps its own heap: on one, threads that allocate at once wait for each
/// other (the reader on two threads without the arena, `bench-read --jobs 2`, took 3.9 ms a
/// corpus pass instead of 2.4). Nothing elsewhere than Linux with glibc.
pub(crate) fn tune() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets the allocator's parameters (it may be called at any time);
    // getrlimit writes the limit it is given room for.
    unsafe {
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
        libc::mallopt(libc::M_TOP_PAD, 1 << 20);
        let mut limit = libc::rlimit { rlim_cur: libc::RLIM_INFINITY, rlim_max: libc::RLIM_INFINITY };
        if libc::getrlimit(libc::RLIMIT_AS, &mut limit) == 0 && limit.rlim_cur != libc::RLIM_INFINITY {
            libc::mallopt(libc::M_ARENA_MAX, 1);
        }
    }
}

/// The arena when it serves the request, the system's allocator otherwise.
pub(crate) struct Allocator;

// SAFETY: a block is the arena's exactly when its address is in the arena (`arena::contains`),
// and is then given back to it; every other block came from `System` and goes back to it, with
// the layout it was made with (the caller's contract). `System` honours every alignment; the
// arena serves only requests aligned to at most `arena::ALIGN`.
unsafe impl GlobalAlloc for Allocator {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        match from_arena(layout) {
            Some(p) => p,
            // SAFETY: the caller's contract (a non-zero size).
            None => unsafe { System.alloc(layout) },
        }
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        match from_arena(layout) {
            Some(p) => {
                // SAFETY: a block of at least `layout.size()` bytes (a reused one is not zero).
                unsafe { p.write_bytes(0, layout.size()) };
                p
            }
            // SAFETY: the caller's contract (a non-zero size).
            None => unsafe { System.alloc_zeroed(layout) },
        }
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if arena::contains(ptr) {
            // SAFETY: an arena block made for `layout` (the caller's contract).
            return unsafe { arena::free(ptr, layout.size()) };
        }
        // SAFETY: `ptr` came from `System` with `layout` (the caller's contract).
        unsafe { System.dealloc(ptr, layout) }
    }

    #[inline]
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if arena::contains(ptr) {
            // A size of the same class keeps its block; otherwise a new block (the arena's or
            // the system's), the bytes copied, and the old block given back once that
            // succeeded.
            if new_size <= arena::MAX_BLOCK && arena::class(new_size).0 == arena::class(layout.size()).0 {
                return ptr;
            }
            // SAFETY: the caller's contract: `new_size` is non-zero and, rounded up to
            // `layout.align()`, does not overflow.
            let new = unsafe { self.alloc(Layout::from_size_align_unchecked(new_size, layout.align())) };
            if !new.is_null() {
                // SAFETY: both blocks hold at least the bytes copied and do not overlap; the
                // old block is the arena's, made for `layout`, and no longer used.
                unsafe {
                    std::ptr::copy_nonoverlapping(ptr, new, layout.size().min(new_size));
                    arena::free(ptr, layout.size());
                }
            }
            return new;
        }
        // SAFETY: `ptr` came from `System` with `layout` (the caller's contract). (A block of
        // the system's stays the system's when it grows: it is not moved into the arena.)
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// A block of the arena for `layout`, when it is open and serves that size and alignment.
#[inline]
fn from_arena(layout: Layout) -> Option<*mut u8> {
    if layout.size() > arena::MAX_BLOCK || layout.align() > arena::ALIGN {
        return None;
    }
    // SAFETY: the size is at most MAX_BLOCK and, a GlobalAlloc request, not zero.
    let p = unsafe { arena::alloc(layout.size()) };
    (!p.is_null()).then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every size and alignment gets a block that is aligned, writable over its whole size, and
    /// keeps its bytes when it grows and shrinks (from the system's allocator or the arena,
    /// whichever serves it when the test runs).
    #[test]
    fn blocks_are_aligned_and_keep_their_bytes() {
        let a = Allocator;
        for align in [1usize, 2, 4, 8, 16, 32, 64, 4096] {
            for size in [1usize, 3, 7, 8, 9, 15, 16, 17, 24, 40, 48, 96, 100, 1000, 1056, 3840, 9600, 70_000, 300_000] {
                let layout = Layout::from_size_align(size, align).expect("layout");
                // SAFETY: the layouts have non-zero sizes; each block is used within its size
                // and freed once, with the layout it was made with.
                unsafe {
                    let zeroed = a.alloc_zeroed(layout);
                    assert!(!zeroed.is_null());
                    assert_eq!(zeroed as usize % align, 0, "zeroed {size} {align}");
                    assert!(std::slice::from_raw_parts(zeroed, size).iter().all(|&b| b == 0));
                    a.dealloc(zeroed, layout);
                    let p = a.alloc(layout);
                    assert!(!p.is_null());
                    assert_eq!(p as usize % align, 0, "{size} {align}");
                    for i in 0..size {
                        p.add(i).write(i as u8);
                    }
                    let grown = a.realloc(p, layout, size * 3);
                    assert_eq!(grown as usize % align, 0, "grown {size} {align}");
                    assert!((0..size).all(|i| grown.add(i).read() == i as u8));
                    let big = Layout::from_size_align(size * 3, align).expect("layout");
                    let shrunk = a.realloc(grown, big, size.div_ceil(2));
                    assert_eq!(shrunk as usize % align, 0, "shrunk {size} {align}");
                    assert!((0..size.div_ceil(2)).all(|i| shrunk.add(i).read() == i as u8));
                    a.dealloc(shrunk, Layout::from_size_align(size.div_ceil(2), align).expect("layout"));
                }
            }
        }
    }
}
