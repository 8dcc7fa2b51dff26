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
//!
//! Requests aligned to 16 bytes (the model's entries hold an `i128`, so vectors of them ask
//! for 16) of at least 16 bytes take the plain entry points too, and the block is checked: in
//! mimalloc v3 every block of 16 bytes or more is 16-aligned (its size classes from 16 up are
//! multiples of 16 and its pages start so aligned), but its aligned entry points take that for
//! granted only up to 1 KiB or for powers of two, and serve the other requests from a block
//! one alignment larger, of another size class: more pages in use, each a page fault when
//! fresh. A block that is not aligned (never seen) is given back and the aligned entry point
//! asked instead.

use std::alloc::{GlobalAlloc, Layout};
use std::ffi::c_void;

use libmimalloc_sys as mi;

use crate::arena;

/// The alignment every mimalloc block has (`MI_INTPTR_SIZE`: its size classes are whole
/// machine words, and its pages start at least that aligned).
const WORD: usize = std::mem::size_of::<usize>();

/// mimalloc as the global allocator.
pub(crate) struct Mimalloc;

// (Declared here rather than through the crate's `extended` feature, which would add a
// dependency for one function; the symbol is in the library either way.)
unsafe extern "C" {
    fn mi_option_set(option: i32, value: std::ffi::c_long);
}

/// `mi_option_purge_delay` in mimalloc v3's `mi_option_t` (what `libmimalloc-sys` builds).
const MI_OPTION_PURGE_DELAY: i32 = 15;

/// Tunes the allocator for a short-lived process: before `main` on Linux ([`TUNE_BEFORE_MAIN`]),
/// and first thing in `main`.
///
/// By default mimalloc gives freed pages back to the kernel (`madvise`) 10 ms after they empty;
/// a thread that then allocates again takes a fresh page fault for each. `odgen check` frees a
/// file's model and allocates the next file's at once, all within a few milliseconds, so
/// purging only cost system time (18 `madvise` calls and the faults after them on the corpus);
/// with it off, the pages stay and are reused. A process's peak memory is unchanged (memory
/// is given back at exit).
///
/// Arenas are mimalloc's least, 32 MiB, rather than its default 1 GiB. Setting up an arena
/// writes its bitmaps, in proportion to its size: for 1 GiB, 40 fresh pages before the first
/// allocation (a fifth of `odgen --version`'s faults, and 5% of `odgen check`'s on the corpus).
/// A process that needs more reserves more arenas, mimalloc doubling their size every eight.
/// Small arenas also fit an address-space limit (`ulimit -v`): 1 GiB reservations failed there
/// and were retried smaller on every thread that needed memory, and when two threads did so at
/// once a large allocation could find no room left and abort the process (`odgen dump` of a
/// 4 MB file under "10 x the input + 64 MB" aborted in 3 to 5 runs out of 150,
/// `tests/memory.rs`).
pub(crate) fn tune() {
    // SAFETY: mi_option_set only stores the value of a known option (it may be called at any
    // time; mimalloc reads the option when it next considers purging).
    unsafe { mi_option_set(MI_OPTION_PURGE_DELAY, -1) }
    // SAFETY: as above; mimalloc reads this option each time it reserves an arena (the first
    // time at the first allocation, after this).
    unsafe { mi_option_set(MI_OPTION_ARENA_RESERVE, ARENA_RESERVE_KIB) }
}

/// [`tune`], run by the C runtime before `main` (an ELF constructor): the Rust runtime
/// allocates before `main` runs (the main thread's name and stack guard), and mimalloc reserves
/// its first arena at the first allocation, with the options it has then. (`main` calls `tune`
/// too, for targets without `.init_array`; setting the options again changes nothing.)
#[cfg(target_os = "linux")]
#[used]
#[unsafe(link_section = ".init_array")]
static TUNE_BEFORE_MAIN: extern "C" fn() = {
    extern "C" fn before_main() {
        tune()
    }
    before_main
};

/// `mi_option_arena_reserve` in mimalloc v3's `mi_option_t`: the address space an arena
/// reserves, in KiB (1 GiB by default).
const MI_OPTION_ARENA_RESERVE: i32 = 23;

/// The arena size: mimalloc's least (`MI_ARENA_MIN_SIZE`, 32 MiB on 64-bit targets).
const ARENA_RESERVE_KIB: std::ffi::c_long = 32 * 1024;

// SAFETY: each method forwards to the mimalloc function with the same contract as the
// `GlobalAlloc` method (a block of at least `size` bytes, or null on failure; `mi_free` and
// `mi_realloc*` accept any block from these functions). Blocks from `mi_malloc`, `mi_zalloc` and
// `mi_realloc` are aligned to `WORD`, so those are only used when the layout asks no more;
// larger alignments go to the `_aligned` functions, which honour any power of two.
unsafe impl GlobalAlloc for Mimalloc {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if let Some(p) = from_arena(layout) {
            return p;
        }
        // SAFETY: see the impl.
        unsafe {
            match Path::of(layout.size(), layout.align()) {
                Path::Plain => mi::mi_malloc(layout.size()) as *mut u8,
                Path::Checked => or_aligned(mi::mi_malloc(layout.size()), layout.align(), || {
                    mi::mi_malloc_aligned(layout.size(), layout.align())
                }),
                Path::Aligned => mi::mi_malloc_aligned(layout.size(), layout.align()) as *mut u8,
            }
        }
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if let Some(p) = from_arena(layout) {
            // SAFETY: a block of at least `layout.size()` bytes (a reused one is not zero).
            unsafe { p.write_bytes(0, layout.size()) };
            return p;
        }
        // SAFETY: see the impl.
        unsafe {
            match Path::of(layout.size(), layout.align()) {
                Path::Plain => mi::mi_zalloc(layout.size()) as *mut u8,
                Path::Checked => or_aligned(mi::mi_zalloc(layout.size()), layout.align(), || {
                    mi::mi_zalloc_aligned(layout.size(), layout.align())
                }),
                Path::Aligned => mi::mi_zalloc_aligned(layout.size(), layout.align()) as *mut u8,
            }
        }
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if arena::contains(ptr) {
            // SAFETY: an arena block made for `layout` (the caller's contract).
            return unsafe { arena::free(ptr, layout.size()) };
        }
        // SAFETY: `ptr` came from one of the functions above (the caller's contract).
        unsafe { mi::mi_free(ptr as *mut c_void) }
    }

    #[inline]
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if arena::contains(ptr) {
            // A size of the same class keeps its block; otherwise a new block (the arena's or
            // mimalloc's), the bytes copied, and the old block given back once that succeeded.
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
        // SAFETY: see the impl; `ptr` came from one of the functions above with `layout`.
        // `mi_realloc_aligned` of a block that is not aligned moves it to one that is (the
        // bytes kept as `mi_realloc` keeps them).
        unsafe {
            match Path::of(new_size, layout.align()) {
                Path::Plain => mi::mi_realloc(ptr as *mut c_void, new_size) as *mut u8,
                Path::Checked => {
                    let p = mi::mi_realloc(ptr as *mut c_void, new_size) as *mut u8;
                    if aligned(p, layout.align()) {
                        p
                    } else {
                        mi::mi_realloc_aligned(p as *mut c_void, new_size, layout.align()) as *mut u8
                    }
                }
                Path::Aligned => mi::mi_realloc_aligned(ptr as *mut c_void, new_size, layout.align()) as *mut u8,
            }
        }
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

/// mimalloc's `MI_MAX_ALIGN_SIZE` on 64-bit targets: blocks of at least this size are aligned
/// to it.
const MAX_ALIGN: usize = 16;

/// Which of mimalloc's entry points serves a request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Path {
    /// The plain one: every block is aligned to [`WORD`].
    Plain,
    /// The plain one, the block checked for alignment (see the module's documentation).
    Checked,
    /// The aligned one.
    Aligned,
}

impl Path {
    fn of(size: usize, align: usize) -> Path {
        if align <= WORD {
            Path::Plain
        } else if align <= MAX_ALIGN && size >= MAX_ALIGN {
            Path::Checked
        } else {
            Path::Aligned
        }
    }
}

/// `p` (a new block, or null) when it is null or aligned to `align`; otherwise `p` is freed and
/// `aligned_alloc`'s block given instead.
///
/// # Safety
/// `p` is null or a block from mimalloc that nothing else refers to.
#[inline]
unsafe fn or_aligned(p: *mut c_void, align: usize, aligned_alloc: impl FnOnce() -> *mut c_void) -> *mut u8 {
    let p = p as *mut u8;
    if aligned(p, align) {
        return p;
    }
    // SAFETY: `p` is a block from mimalloc that nothing refers to (the caller's contract).
    unsafe { mi::mi_free(p as *mut c_void) };
    aligned_alloc() as *mut u8
}

/// Whether `p` is null (a failure, passed on as such) or aligned to `align`.
#[inline]
fn aligned(p: *mut u8, align: usize) -> bool {
    (p as usize) & (align - 1) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// mimalloc reserves arenas of 32 MiB and never purges: on Linux from before `main` (this
    /// test does not call `tune` first there), elsewhere once `tune` has run.
    #[test]
    fn tune_sets_the_options() {
        unsafe extern "C" {
            fn mi_option_get(option: i32) -> std::ffi::c_long;
        }
        if !cfg!(target_os = "linux") {
            tune();
        }
        // SAFETY: mi_option_get reads the value of a known option.
        let (reserve, purge) =
            unsafe { (mi_option_get(MI_OPTION_ARENA_RESERVE), mi_option_get(MI_OPTION_PURGE_DELAY)) };
        assert_eq!((reserve, purge), (32 * 1024, -1));
    }

    /// The property the checked path counts on: mimalloc's plain blocks of 16 bytes or more
    /// are 16-aligned, for every size class up to large objects (were it to change, the checked
    /// path would still be correct, through its fallback, but slower: this says so).
    #[test]
    fn plain_blocks_of_sixteen_bytes_or_more_are_sixteen_aligned() {
        let mut blocks = Vec::new();
        for size in (16..=4096).chain((4096..=600_000).step_by(1000)) {
            for _ in 0..3 {
                // SAFETY: a non-zero size; freed once below.
                let p = unsafe { mi::mi_malloc(size) } as *mut u8;
                assert!(!p.is_null());
                assert!(aligned(p, 16), "size {size}: {p:p}");
                blocks.push(p);
            }
        }
        for p in blocks {
            // SAFETY: each came from mi_malloc and is freed once.
            unsafe { mi::mi_free(p as *mut c_void) }
        }
        assert_eq!(Path::of(3840, 16), Path::Checked);
        assert_eq!(Path::of(8, 16), Path::Aligned);
        assert_eq!(Path::of(64, 32), Path::Aligned);
        assert_eq!(Path::of(5, 8), Path::Plain);
    }

    /// Every size and alignment gets a block that is aligned, writable over its whole size, and
    /// keeps its bytes when it grows and shrinks.
    #[test]
    fn blocks_are_aligned_and_keep_their_bytes() {
        let a = Mimalloc;
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
