//! The working memory of a run over many files, on transparent huge pages.
//!
//! A run of `odgen check` is a few milliseconds, and every page of memory it touches is a fresh
//! one: a page fault, about 2.2 us on our VMs, and more work for the kernel at exit (about 2.9
//! us a page end to end, measured by touching extra pages). With mimalloc alone (the binary's
//! allocator then) the corpus check touched about 740 pages of heap on two threads, a third of
//! the run's time. Most of that memory is in use, not wasted: packing the same blocks tightly
//! (below, on ordinary pages) saved only 30 of them.
//!
//! What is cheaper is fewer, larger pages. The arena is 6 MiB, aligned to 2 MiB and advised
//! for transparent huge pages (`MADV_HUGEPAGE`): the kernel fills each 2 MiB of it with one
//! fault, zeroing a huge page (150 to 250 us), instead of 512. Blocks are packed into it from
//! the start, so a run touches only as many huge pages as it needs; mimalloc's own huge-page
//! mode spread a run's memory over seven to fourteen 2 MiB ranges of its arena (small, medium
//! and large pages each elsewhere), each zeroed whole. The corpus check (61 files, 1.3 MB) uses
//! 2.5 to 3.8 MB of it, two huge pages; the third is for larger runs, and is only filled when
//! one reaches it.
//!
//! What fills the arena is mostly what a file's reading keeps until its next file: its text and
//! the lists pass 1 and pass 3 make, together about seven times the file's size, sized before
//! the file is read, on each thread for the largest file it reads (the threads of `odgen check`
//! take the files largest first, and their readers size these buffers by their first file:
//! `eds::Reader::with_room`). Room never written costs nothing on ordinary pages; here it is
//! arena. Sized for a 256 KiB file, as a reader does for files in any order, and with the
//! reports rendered into 64 KiB blocks, the corpus filled the 4 MiB the arena then had, and
//! 0.3 to 1.8 MB went to the other allocator's fresh pages, about 180 page faults.
//!
//! The arena serves requests up to [`MAX_BLOCK`] bytes aligned to at most 16, in 56 size
//! classes (16-byte steps up to 128 bytes, then four a doubling: at most a quarter wasted).
//! Each thread carves blocks from 64 KiB chunks it takes in turn from the arena, and keeps the
//! blocks freed on it in one list per class (a freed block holds the next one's address), from
//! which that thread reuses them first: a block may be freed on another thread than the one
//! that made it, and is then that thread's to reuse. Nothing is returned to the system before
//! the process ends, and blocks of one class are never cut for another: the arena's size bounds
//! what this keeps. What it cannot serve (larger or more aligned requests, or any once it is
//! full) the caller takes from the system's allocator (`crate::alloc`); a block is the arena's
//! if its address is in it.
//!
//! It is opened by `odgen check` when the files it is given add up to [`WORTH_OPENING`] bytes
//! or more (a smaller run touches fewer pages than a huge page's zeroing costs), and only where
//! the process gets transparent huge pages (Linux, the system's setting `always` or `madvise`,
//! not turned off for the process): on ordinary pages it would save few faults.

use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// The arena's size: three huge pages.
pub(crate) const SIZE: usize = 6 << 20;

/// A transparent huge page on x86_64 and aarch64 (4 KiB base pages).
const HUGE: usize = 2 << 20;

/// The largest request the arena serves (a reader's list of entries for a 300 KB file).
pub(crate) const MAX_BLOCK: usize = 512 << 10;

/// The alignment every arena block has (class sizes are multiples of 16, chunks are aligned).
pub(crate) const ALIGN: usize = 16;

/// What a thread takes from the arena at a time to carve blocks from.
const CHUNK: usize = 64 << 10;

/// The number of size classes ([`class`]).
const CLASSES: usize = 56;

/// The input size from which the arena is opened ([`open_for`]).
const WORTH_OPENING: u64 = 128 << 10;

/// The arena's first byte; [`CLOSED`] until it is opened (then never changed).
static BASE: AtomicUsize = AtomicUsize::new(CLOSED);

/// A `BASE` that no pointer is within `SIZE` of: the top `SIZE` bytes of the address space,
/// which user memory never reaches, so that [`contains`] needs no other test while the arena is
/// closed.
const CLOSED: usize = 0usize.wrapping_sub(SIZE);

/// The start of the arena's next free chunk.
static NEXT: AtomicUsize = AtomicUsize::new(0);

/// Whether the second huge page was asked for ([`warm`]).
static WARMED: AtomicBool = AtomicBool::new(false);

/// A thread's part: the chunk it carves from, and the blocks freed on it by class.
struct Local {
    /// The next free byte of the current chunk.
    bump: usize,
    /// One past the current chunk.
    limit: usize,
    /// Each class's list of freed blocks (0: empty).
    free: [usize; CLASSES],
}

thread_local! {
    // (Const-initialised and without `Drop`: reached without a check or a registration, and
    // never gone, even while the thread's other thread-locals are dropped.)
    static LOCAL: UnsafeCell<Local> = const { UnsafeCell::new(Local { bump: 0, limit: 0, free: [0; CLASSES] }) };
}

/// The size class of a request of `size` bytes (1 to [`MAX_BLOCK`]): its index and the size of
/// its blocks. 16 to 128 bytes in steps of 16, then four classes between powers of two.
#[inline]
pub(crate) fn class(size: usize) -> (usize, usize) {
    debug_assert!(size <= MAX_BLOCK);
    if size <= 128 {
        let i = size.max(1).div_ceil(16);
        (i - 1, i * 16)
    } else {
        // log: the power of two below `size` (7 for 129..=256); the classes between 2^log and
        // 2^(log+1) are 2^log + k * 2^(log-2), k = 1..=4.
        let log = (usize::BITS - 1 - (size - 1).leading_zeros()) as usize;
        let step = 1usize << (log - 2);
        let block = (size + step - 1) & !(step - 1);
        (8 + (log - 7) * 4 + (block >> (log - 2)) - 5, block)
    }
}

/// Whether `p` is a block of the arena.
#[inline]
pub(crate) fn contains(p: *mut u8) -> bool {
    (p as usize).wrapping_sub(BASE.load(Ordering::Relaxed)) < SIZE
}

/// Opens the arena for a run whose files add up to `bytes`, if they are [`WORTH_OPENING`]:
/// whether it is open. The one rule for both of `odgen check`'s ways (one thread or several).
///
/// The thread that opens it has the kernel fill its first huge page at once, before any other
/// thread allocates from it, and is the one that fills the second ([`warm`]): see there why
/// the thread matters.
pub(crate) fn open_for(bytes: u64) -> bool {
    if bytes < WORTH_OPENING {
        return false;
    }
    let opened = open();
    if opened && !OPENED_HERE.replace(true) {
        let base = BASE.load(Ordering::Acquire);
        populate(base, HUGE);
    }
    opened
}

thread_local! {
    /// Whether this thread opened the arena (it fills its huge pages).
    static OPENED_HERE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Opens the arena (once; later calls change nothing): whether it is open. It is not when it
/// could not be mapped, or when this process gets no transparent huge pages ([`huge_pages`]):
/// on ordinary pages the arena saves few faults, and filling its second half would cost a
/// worker 512 of them.
fn open() -> bool {
    open_with(true)
}

/// [`open`]; `require_huge_pages` false opens it on any machine (the tests, which hold the
/// arena to its contract whatever pages it has).
fn open_with(require_huge_pages: bool) -> bool {
    // (Once: a mapping is made and published by one thread only. Not called by the allocator,
    // so `Once`, which never allocates anyway, may block.)
    static OPENING: std::sync::Once = std::sync::Once::new();
    OPENING.call_once(|| {
        #[cfg(target_os = "linux")]
        if !require_huge_pages || huge_pages() {
            publish_new();
        }
        #[cfg(not(target_os = "linux"))]
        let _ = require_huge_pages;
    });
    BASE.load(Ordering::Acquire) != CLOSED
}

/// Maps the arena, aligned to a huge page and advised for them, and opens it.
#[cfg(target_os = "linux")]
fn publish_new() {
    let len = SIZE + HUGE;
    // SAFETY: a new private anonymous mapping; nothing else refers to it. (It is never
    // unmapped: the arena lasts as long as the process.)
    let p = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            len,
            libc::PROT_READ | libc::PROT_WRITE,
            libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_NORESERVE,
            -1,
            0,
        )
    };
    if p == libc::MAP_FAILED {
        return;
    }
    let start = (p as usize + HUGE - 1) & !(HUGE - 1);
    // SAFETY: advice on part of the mapping just made.
    unsafe { libc::madvise(start as *mut libc::c_void, SIZE, libc::MADV_HUGEPAGE) };
    NEXT.store(start, Ordering::Relaxed);
    // (Release: a thread that sees the arena open sees `NEXT` set.)
    BASE.store(start, Ordering::Release);
}

/// Whether memory this process advises for transparent huge pages gets them: the system's
/// setting is `always` or `madvise` (not `never`, and the file exists: the kernel has them),
/// and the process has not turned them off (`PR_SET_THP_DISABLE`, which a parent process's
/// setting passes on to its children).
#[cfg(target_os = "linux")]
fn huge_pages() -> bool {
    // SAFETY: PR_GET_THP_DISABLE takes no pointer; it returns 1 when disabled, -1 on error.
    if unsafe { libc::prctl(libc::PR_GET_THP_DISABLE, 0, 0, 0, 0) } == 1 {
        return false;
    }
    let mut setting = [0u8; 64];
    let read = std::fs::File::open("/sys/kernel/mm/transparent_hugepage/enabled")
        .and_then(|mut f| std::io::Read::read(&mut f, &mut setting));
    thp_setting_allows(read.map(|n| &setting[..n]).ok())
}

/// Whether the text of `/sys/kernel/mm/transparent_hugepage/enabled` (`None`: not there) lets
/// an advised mapping have huge pages: the choice in brackets is `always` or `madvise`.
fn thp_setting_allows(setting: Option<&[u8]>) -> bool {
    let Some(text) = setting else { return false };
    let chosen = text.split(|&b| b == b'[').nth(1).and_then(|rest| rest.split(|&b| b == b']').next());
    matches!(chosen, Some(b"always" | b"madvise"))
}

/// Has the kernel fill the arena's second huge page now, if the calling thread opened the arena
/// (nothing on any other: see below), for several threads reading, which fill the first page
/// and then reach the second. `odgen check` has its main thread call this as it starts its
/// first file, after the other threads have the files (and the first page) to start on.
///
/// The kernel takes a huge page first from the free memory it keeps for the CPU asking, where
/// the huge pages of the run before, freed as it ended, went (its threads' memory is freed by
/// the thread that ends last, on its CPU). Filled by the other thread, on the other CPU, the
/// second page was one the host of our VMs had taken back in 12 runs out of 300, and backing
/// it anew took 6 ms (0.2 ms otherwise); filled by the opening thread, in none of 300 (at most
/// 0.8 ms). On the corpus, dist binaries, 1,000 alternating runs: mean 5.03 -> 4.91 ms, the
/// median unchanged. Not the third page, which most runs never reach (filling it too cost 0.2
/// to 0.5 ms of CPU). Once per run; nothing when the
/// arena is closed or the kernel cannot (`MADV_POPULATE_WRITE` is Linux 5.14 and later: the
/// page is then filled when first touched).
pub(crate) fn warm() {
    let base = BASE.load(Ordering::Acquire);
    if base == CLOSED || !OPENED_HERE.get() || WARMED.swap(true, Ordering::Relaxed) {
        return;
    }
    populate(base + HUGE, HUGE);
}

/// Has the kernel fill `len` bytes of the arena from `at` now (nothing where it cannot:
/// `MADV_POPULATE_WRITE` is Linux 5.14 and later, and the pages are then filled when first
/// touched).
fn populate(at: usize, len: usize) {
    #[cfg(target_os = "linux")]
    // SAFETY: advice on the arena's own mapping; filling pages changes no byte (fresh pages are
    // zero, and a page in use is left as it is).
    unsafe {
        libc::madvise(at as *mut libc::c_void, len, libc::MADV_POPULATE_WRITE);
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (at, len);
}

/// A block of at least `size` bytes (1 to [`MAX_BLOCK`]), aligned to [`ALIGN`], or null when
/// the arena is closed or full.
///
/// # Safety
/// `size` is 1 to [`MAX_BLOCK`].
#[inline]
pub(crate) unsafe fn alloc(size: usize) -> *mut u8 {
    let base = BASE.load(Ordering::Acquire);
    if base == CLOSED {
        return std::ptr::null_mut();
    }
    let (i, block) = class(size);
    // (`try_with` cannot fail for this thread-local, which has no destructor; a failure would
    // only send the request to the system's allocator.)
    LOCAL
        .try_with(|l| {
            // SAFETY: this thread's own state; nothing here allocates or frees, so it is not
            // reached again while borrowed.
            let l = unsafe { &mut *l.get() };
            let head = l.free[i];
            if head != 0 {
                // SAFETY: a block freed on this thread, whose first word holds the next one.
                l.free[i] = unsafe { *(head as *const usize) };
                return head as *mut u8;
            }
            if l.limit - l.bump >= block {
                let p = l.bump;
                l.bump += block;
                return p as *mut u8;
            }
            if block >= CHUNK {
                // A block of a chunk or more is a chunk of its own; the current one stays.
                return take(base, block).map_or(std::ptr::null_mut(), |c| c as *mut u8);
            }
            match take(base, CHUNK) {
                Some(c) => {
                    l.bump = c + block;
                    l.limit = c + CHUNK;
                    c as *mut u8
                }
                None => std::ptr::null_mut(),
            }
        })
        .unwrap_or(std::ptr::null_mut())
}

/// The next `len` bytes of the arena, if it has them.
#[inline]
fn take(base: usize, len: usize) -> Option<usize> {
    let end = base + SIZE;
    let mut at = NEXT.load(Ordering::Relaxed);
    loop {
        if end - at < len {
            return None;
        }
        match NEXT.compare_exchange_weak(at, at + len, Ordering::Relaxed, Ordering::Relaxed) {
            Ok(_) => return Some(at),
            Err(now) => at = now,
        }
    }
}

/// Gives back a block of the arena, to be reused by this thread.
///
/// # Safety
/// `p` is a block of the arena ([`contains`]) that nothing refers to any more, made for
/// `size` bytes or for a size of the same class.
#[inline]
pub(crate) unsafe fn free(p: *mut u8, size: usize) {
    let (i, _) = class(size);
    // (Were the thread-local gone, the block would stay unused until the process ends.)
    let _ = LOCAL.try_with(|l| {
        // SAFETY: this thread's own state (see `alloc`); the block is unused and at least 16
        // bytes long and 16-aligned, so it holds the list's next address.
        let l = unsafe { &mut *l.get() };
        unsafe { *(p as *mut usize) = l.free[i] };
        l.free[i] = p as usize;
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The classes cover 1 to MAX_BLOCK in order, each block at least the request, at most a
    /// quarter (or 15 bytes) more, a multiple of 16; 56 of them.
    #[test]
    fn size_classes_are_ordered_tight_and_aligned() {
        let mut last = (0usize, 16usize);
        for size in 1..=MAX_BLOCK {
            let (i, block) = class(size);
            assert!(block >= size, "{size}");
            assert_eq!(block % ALIGN, 0, "{size}");
            assert!(block - size < 16 || (block - size) * 4 <= size, "{size}: {block}");
            assert!(i < CLASSES);
            assert!(i == last.0 || i == last.0 + 1, "{size}: class {i} after {}", last.0);
            if i == last.0 {
                assert_eq!(block, last.1, "{size}");
            }
            last = (i, block);
        }
        assert_eq!(last, (CLASSES - 1, MAX_BLOCK));
    }

    /// While the arena is closed no address a process can have is taken for one of its blocks
    /// (the null pointer, and the top of the user address space included).
    #[test]
    fn a_closed_arena_contains_nothing() {
        let within = |p: usize| p.wrapping_sub(CLOSED) < SIZE;
        for p in [0, 1, 16, 4096, 0x5555_5555_0000, 0x7fff_ffff_f000, (1 << 56) - 1, usize::MAX / 2] {
            assert!(!within(p), "{p:#x}");
        }
        assert!(within(CLOSED) && within(usize::MAX), "the closed range is the top of the address space");
    }

    /// The arena is opened only where the system's setting gives advised memory huge pages.
    #[test]
    fn the_system_setting_decides_whether_huge_pages_come() {
        assert!(thp_setting_allows(Some(b"always [madvise] never\n")));
        assert!(thp_setting_allows(Some(b"[always] madvise never\n")));
        assert!(!thp_setting_allows(Some(b"always madvise [never]\n")));
        assert!(!thp_setting_allows(Some(b"")));
        assert!(!thp_setting_allows(Some(b"[")));
        assert!(!thp_setting_allows(None));
    }

    /// With the arena open, small blocks come from it, are aligned and writable, are reused
    /// once freed, and the system allocator's blocks are told apart from them.
    #[test]
    fn blocks_come_from_the_open_arena_and_are_reused() {
        assert!(open_with(false));
        assert!(open_with(false), "opening again changes nothing");
        let base = BASE.load(Ordering::Relaxed);
        assert_eq!(base % HUGE, 0);
        // SAFETY: sizes within 1..=MAX_BLOCK; each block used within its size and freed once.
        unsafe {
            let a = alloc(40);
            let b = alloc(40);
            assert!(contains(a) && contains(b) && a != b);
            assert_eq!(a as usize % ALIGN, 0);
            a.write_bytes(0xAB, 40);
            b.write_bytes(0xCD, 48);
            free(a, 40);
            // (The same class, another size in it: the block just freed.)
            assert_eq!(alloc(33), a);
            let big = alloc(MAX_BLOCK);
            assert!(contains(big));
            big.write_bytes(1, MAX_BLOCK);
            free(big, MAX_BLOCK);
            free(a, 33);
            free(b, 40);
        }
        // (Larger than the arena serves: the system's, through the global allocator.)
        let large = vec![0u8; MAX_BLOCK + 1];
        assert!(!contains(large.as_ptr() as *mut u8));
        assert!(!contains(std::ptr::null_mut()));
        assert!(!contains(usize::MAX as *mut u8));
    }

    /// Too few bytes do not open the arena; only the thread that opened it fills its pages
    /// (`warm` on any other does nothing), and only once.
    #[test]
    fn only_the_thread_that_opened_the_arena_fills_its_pages() {
        assert!(!open_for(WORTH_OPENING - 1));
        assert!(open_with(false));
        std::thread::spawn(warm).join().expect("warm");
        assert!(!WARMED.load(Ordering::Relaxed), "a thread that did not open the arena fills nothing");
        OPENED_HERE.set(true);
        warm();
        assert!(WARMED.load(Ordering::Relaxed));
        warm();
    }

    /// Many threads allocating, growing, shrinking and freeing blocks of every size through
    /// the global allocator with the arena open (until it is full, and past), some blocks
    /// freed on another thread than the one that made them: every block keeps its bytes.
    #[test]
    fn threads_keep_their_bytes_through_the_global_allocator() {
        assert!(open_with(false));
        let (tx, rx) = std::sync::mpsc::channel::<Vec<u8>>();
        let check = |v: &Vec<u8>| {
            let seed = v.len() as u8;
            assert!(v.iter().enumerate().all(|(i, &b)| b == seed.wrapping_add(i as u8)), "a block lost its bytes");
        };
        let fill = |len: usize| -> Vec<u8> {
            let seed = len as u8;
            (0..len).map(|i| seed.wrapping_add(i as u8)).collect()
        };
        std::thread::scope(|s| {
            for t in 0..4u64 {
                let tx = tx.clone();
                s.spawn(move || {
                    let mut x = 0x9E37_79B9_7F4A_7C15u64 ^ t;
                    let mut next = move || {
                        x ^= x << 13;
                        x ^= x >> 7;
                        x ^= x << 17;
                        x
                    };
                    let mut kept: Vec<Vec<u8>> = Vec::new();
                    for round in 0..3000 {
                        let r = next();
                        // Mostly small, some up to the largest arena block and beyond.
                        let len = match r % 10 {
                            0 => (r >> 8) as usize % (MAX_BLOCK + 4096) + 1,
                            1..=3 => (r >> 8) as usize % 4096 + 1,
                            _ => (r >> 8) as usize % 200 + 1,
                        };
                        let mut v = fill(len);
                        if r % 7 == 0 {
                            // Grown by pushes (realloc through the classes), then cut back.
                            let more = (r >> 20) as usize % 3000;
                            v.clear();
                            v.extend((0..len + more).map(|i| ((len + more) as u8).wrapping_add(i as u8)));
                            v.truncate(len);
                            v.shrink_to_fit();
                            v.iter_mut().enumerate().for_each(|(i, b)| *b = (len as u8).wrapping_add(i as u8));
                        }
                        check(&v);
                        match r % 3 {
                            0 => tx.send(v).expect("receiver"),
                            1 => kept.push(v),
                            _ => drop(v),
                        }
                        if round % 50 == 0 {
                            kept.iter().for_each(check);
                            kept.retain(|_| next() % 2 == 0);
                        }
                    }
                    kept.iter().for_each(check);
                });
            }
            drop(tx);
            s.spawn(move || {
                for v in rx {
                    check(&v);
                }
            });
        });
    }

    /// A full arena serves nothing more: the caller goes to the system's allocator.
    #[test]
    fn a_full_arena_gives_null() {
        assert!(open_with(false));
        let base = BASE.load(Ordering::Relaxed);
        assert_eq!(take(base, SIZE + 1), None);
    }
}
