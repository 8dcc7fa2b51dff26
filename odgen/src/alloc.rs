//! The allocator of the `odgen` binary: mimalloc, called the way each allocation needs.
//!
//! Reading a file builds a model of many small parts (a `String` per entry name, the entries of
//! CompactSubObj arrays, diagnostics): about 45,000 allocations per pass over the 61-file
//! corpus. glibc's malloc and free took about 190 instructions per pair there, a fifth of the
//! time; mimalloc takes a fraction of that (callgrind: 83.2 -> 70.5 M instructions per corpus
//! pass). Only the binary is affected: programs that use the `eds` library keep their own
//! allocator.
//!
//! The `mimalloc` crate's allocator sends every request through mimalloc's aligned entry points,
//! which test the alignment and look for a block that happens to be aligned before they take
//! the ordinary path. Every block mimalloc hands out is aligned to a machine word, so requests
//! that ask no more than that (strings, and vectors of bytes, integers and pointers: most of
//! them) go straight to `mi_malloc`, `mi_zalloc` and `mi_realloc` here; only the others take the
//! aligned entry points. Corpus pass: 50.9 -> 50.2 M instructions, 1.3 % less time.

use std::alloc::{GlobalAlloc, Layout};
use std::ffi::c_void;

use libmimalloc_sys as mi;

/// The alignment every mimalloc block has (`MI_INTPTR_SIZE`: its size classes are whole
/// machine words, and its pages start at least that aligned).
const WORD: usize = std::mem::size_of::<usize>();

/// mimalloc as the global allocator.
pub(crate) struct Mimalloc;

// (Declared here rather than through the crate's `extended` feature, which would add a
// dependency for one function; the symbol is in the library either way.)
unsafe extern "C" {
    fn mi_option_set(option: i32, value: std::ffi::c_long);
    #[cfg(test)]
    fn mi_option_get(option: i32) -> std::ffi::c_long;
}

/// `mi_option_purge_delay` in mimalloc v3's `mi_option_t` (what `libmimalloc-sys` builds).
const MI_OPTION_PURGE_DELAY: i32 = 15;

/// The address space each arena reserves when the process has no address-space limit, in KiB:
/// 64 MiB, not mimalloc's 1 GiB.
///
/// An arena's bookkeeping (a bitmap per size class, over the arena's 64 KiB slices) is written
/// when the arena is made, and grows with the arena: for 1 GiB it is about 40 pages, each a
/// page fault in a process that runs for a few milliseconds (`odgen --version`: 195 -> 157
/// faults; `odgen check` on the 61 corpus files: 830 -> 790). A process that needs more gets
/// more arenas, which mimalloc makes larger as their number grows.
const DEFAULT_ARENA_RESERVE_KIB: std::ffi::c_long = 64 * 1024;

/// Tunes the allocator for a short-lived process, before its first allocation.
///
/// By default mimalloc gives freed pages back to the kernel (`madvise`) 10 ms after they empty;
/// a thread that then allocates again takes a fresh page fault for each. `odgen check` frees a
/// file's model and allocates the next file's at once, all within a few milliseconds, so
/// purging only cost system time (18 `madvise` calls and the faults after them on the corpus);
/// with it off, the pages stay and are reused. A process's peak memory is unchanged (memory
/// is given back at exit).
///
/// Arenas are sized by [`DEFAULT_ARENA_RESERVE_KIB`], or to fit the address-space limit
/// ([`arena_reserve_kib`]). The first arena is made at the first allocation, which the Rust
/// runtime makes before `main`: on Linux this runs from the executable's `.init_array`
/// ([`TUNE_BEFORE_MAIN`]), before that; elsewhere `main` calls it first thing
/// ([`tune_in_main`]), and only the later arenas follow it.
fn tune() {
    // SAFETY: mi_option_set only stores the value of a known option (it may be called at any
    // time, before mimalloc's own initialisation too: options it finds set are not read from
    // the environment; mimalloc reads them when it next considers purging or reserving).
    unsafe { mi_option_set(MI_OPTION_PURGE_DELAY, -1) }
    let reserve = address_space_limit().map_or(DEFAULT_ARENA_RESERVE_KIB, arena_reserve_kib);
    // SAFETY: as above; mimalloc reads this option each time it reserves an arena.
    unsafe { mi_option_set(MI_OPTION_ARENA_RESERVE, reserve) }
}

/// [`tune`], run by the dynamic loader before `main` (and so before the Rust runtime's first
/// allocation), from the executable's `.init_array` (ELF; the loader passes `argc`, `argv` and
/// `envp`, which a function of no arguments ignores under the C calling convention).
#[cfg(target_os = "linux")]
#[used]
#[unsafe(link_section = ".init_array")]
static TUNE_BEFORE_MAIN: extern "C" fn() = {
    extern "C" fn tune_before_main() {
        tune();
    }
    tune_before_main
};

/// Called first thing in `main`: [`tune`] where it did not run before `main`.
pub(crate) fn tune_in_main() {
    if !cfg!(target_os = "linux") {
        tune();
    }
}

/// `mi_option_arena_reserve` in mimalloc v3's `mi_option_t`: the address space an arena
/// reserves, in KiB (1 GiB by default).
const MI_OPTION_ARENA_RESERVE: i32 = 23;

/// The arena size for a process whose address space is limited to `limit` bytes
/// (`ulimit -v`): an eighth of it, at least mimalloc's least arena (32 MiB) and at most its
/// default (1 GiB).
///
/// By default every arena reserves 1 GiB. Under a limit of, say, 100 MB each reservation
/// fails, and mimalloc falls back to smaller ones (128 MiB, then less) on every thread that
/// needs memory, until one fits; when two threads did so at once, each holding address space
/// for its attempt, a large allocation could find no room left and abort the process: `odgen
/// dump` of a 4 MB file under "10 x the input + 64 MB" aborted in 3 to 5 runs out of 150
/// (`tests/memory.rs`). Arenas sized to the limit are reserved at the first attempt.
fn arena_reserve_kib(limit: u64) -> std::ffi::c_long {
    let kib = (limit / 8 / 1024).clamp(32 * 1024, 1024 * 1024);
    std::ffi::c_long::try_from(kib).unwrap_or(32 * 1024)
}

/// The process's address-space limit (`RLIMIT_AS`) in bytes, when it has one.
#[cfg(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64", target_arch = "riscv64")))]
fn address_space_limit() -> Option<u64> {
    /// `RLIMIT_AS` on these architectures (the generic Linux numbering).
    const RLIMIT_AS: i32 = 9;
    unsafe extern "C" {
        fn getrlimit(resource: i32, rlim: *mut [u64; 2]) -> i32;
    }
    let mut rlim = [0u64; 2];
    // SAFETY: getrlimit writes the two 64-bit fields of `struct rlimit` (current and maximum
    // limit; `rlim_t` is 64 bits on these 64-bit targets) into `rlim`, which has room for them.
    let ok = unsafe { getrlimit(RLIMIT_AS, &mut rlim) } == 0;
    // (RLIM_INFINITY is all ones.)
    (ok && rlim[0] != u64::MAX).then_some(rlim[0])
}

/// Elsewhere no limit is looked for: mimalloc keeps its default arenas.
#[cfg(not(all(target_os = "linux", any(target_arch = "x86_64", target_arch = "aarch64", target_arch = "riscv64"))))]
fn address_space_limit() -> Option<u64> {
    None
}

// SAFETY: each method forwards to the mimalloc function with the same contract as the
// `GlobalAlloc` method (a block of at least `size` bytes, or null on failure; `mi_free` and
// `mi_realloc*` accept any block from these functions). Blocks from `mi_malloc`, `mi_zalloc` and
// `mi_realloc` are aligned to `WORD`, so those are only used when the layout asks no more;
// larger alignments go to the `_aligned` functions, which honour any power of two.
unsafe impl GlobalAlloc for Mimalloc {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: see the impl.
        unsafe {
            if layout.align() <= WORD {
                mi::mi_malloc(layout.size()) as *mut u8
            } else {
                mi::mi_malloc_aligned(layout.size(), layout.align()) as *mut u8
            }
        }
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: see the impl.
        unsafe {
            if layout.align() <= WORD {
                mi::mi_zalloc(layout.size()) as *mut u8
            } else {
                mi::mi_zalloc_aligned(layout.size(), layout.align()) as *mut u8
            }
        }
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, _layout: Layout) {
        // SAFETY: `ptr` came from one of the functions above (the caller's contract).
        unsafe { mi::mi_free(ptr as *mut c_void) }
    }

    #[inline]
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: see the impl; `ptr` came from one of the functions above with `layout`.
        unsafe {
            if layout.align() <= WORD {
                mi::mi_realloc(ptr as *mut c_void, new_size) as *mut u8
            } else {
                mi::mi_realloc_aligned(ptr as *mut c_void, new_size, layout.align()) as *mut u8
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Arenas are an eighth of the limit, between mimalloc's least (32 MiB) and its default.
    #[test]
    fn arenas_fit_the_address_space_limit() {
        assert_eq!(arena_reserve_kib(100 << 20), 32 * 1024);
        assert_eq!(arena_reserve_kib(1 << 30), 128 * 1024);
        assert_eq!(arena_reserve_kib(64 << 30), 1024 * 1024);
        assert_eq!(arena_reserve_kib(u64::MAX - 1), 1024 * 1024);
        assert_eq!(arena_reserve_kib(0), 32 * 1024);
    }

    /// The options are set before `main`: this test binary's `main` (the test harness) never
    /// calls `tune_in_main`, so on Linux only the `.init_array` entry can have set them.
    #[test]
    #[cfg(target_os = "linux")]
    fn the_allocator_is_tuned_before_main() {
        let want = address_space_limit().map_or(DEFAULT_ARENA_RESERVE_KIB, arena_reserve_kib);
        // SAFETY: mi_option_get only reads the value of a known option.
        let (reserve, purge) =
            unsafe { (mi_option_get(MI_OPTION_ARENA_RESERVE), mi_option_get(MI_OPTION_PURGE_DELAY)) };
        assert_eq!((reserve, purge), (want, -1));
    }

    /// Every size and alignment gets a block that is aligned, writable over its whole size, and
    /// keeps its bytes when it grows and shrinks.
    #[test]
    fn blocks_are_aligned_and_keep_their_bytes() {
        let a = Mimalloc;
        for align in [1usize, 2, 4, 8, 16, 32, 64, 4096] {
            for size in [1usize, 3, 7, 8, 9, 15, 16, 17, 24, 40, 100, 1000, 70_000] {
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
