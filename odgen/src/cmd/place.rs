//! Where a new worker thread first runs: on another CPU than the thread that starts it.
//!
//! A thread that `par_each` starts is left by the kernel to pick a CPU. On some machines the
//! scheduler puts it on the CPU of the thread that started it, which is busy with the files
//! (a guest kernel that packs work onto few virtual CPUs does, as the 2-CPU virtual machines
//! this project is measured on run: `sched_vcpu_pack`), and moves it to an idle CPU only when
//! it next balances the load: measured there, a new thread first ran 0.4 to 5.7 ms after it was
//! started, when `odgen check` takes 4 to 8 ms in all, so that a second thread mostly came too
//! late to share the files. Allowed on every CPU but the starting thread's, it ran within
//! 0.15 ms in 30 runs out of 30.
//!
//! So each worker is first allowed only the CPUs the process may use other than the one the
//! starting thread is on ([`Steer::others`]), and once it runs it is allowed all of them again
//! ([`Steer::release`]): the first choice is steered, nothing after it is pinned. The setting
//! and the release are ordered by an atomic state, so that a worker that starts before it is
//! steered is not left pinned ([`Steered`]).
//!
//! Elsewhere than Linux, and when the process may use one CPU only, this does nothing.

use std::sync::atomic::{AtomicU8, Ordering};

/// The CPUs a worker is first allowed, and those it is allowed once it runs.
pub(crate) struct Steer {
    #[cfg(target_os = "linux")]
    sets: Option<(libc::cpu_set_t, libc::cpu_set_t)>,
}

impl Steer {
    /// The CPUs the process may use other than the one the calling thread is on (none when it
    /// may use no other, or when they cannot be known).
    pub(crate) fn others() -> Steer {
        #[cfg(target_os = "linux")]
        {
            Steer { sets: linux::others() }
        }
        #[cfg(not(target_os = "linux"))]
        {
            Steer {}
        }
    }

    /// Steers the thread that `state` belongs to, just started as `thread`, to the other CPUs
    /// (called by the starting thread, once).
    pub(crate) fn steer<T>(&self, thread: &std::thread::JoinHandle<T>, state: &Steered) {
        #[cfg(target_os = "linux")]
        if let Some((others, all)) = &self.sets {
            use std::os::unix::thread::JoinHandleExt as _;
            // (std's `RawPthread` is a `u64` on every Linux; the C library's `pthread_t` is an
            // integer in glibc and a pointer in musl: the same bits either way.)
            let id = thread.as_pthread_t() as usize as libc::pthread_t;
            linux::set(id, others);
            if !state.steered() {
                // It ran before it was steered: it let nothing go, so it is let go here.
                linux::set(id, all);
            }
        }
        #[cfg(not(target_os = "linux"))]
        let _ = (thread, state);
    }

    /// Lets the calling worker run on every CPU again, if it was steered (called by the worker,
    /// first thing).
    pub(crate) fn release(&self, state: &Steered) {
        #[cfg(target_os = "linux")]
        if let Some((_, all)) = &self.sets
            && state.started()
        {
            // SAFETY: pthread_self is always valid for the calling thread.
            linux::set(unsafe { libc::pthread_self() }, all);
        }
        #[cfg(not(target_os = "linux"))]
        let _ = state;
    }
}

/// Whether a worker was steered, started, or both, in which order: the one of the two that
/// comes second lets the worker go (sets all the CPUs back).
#[derive(Default)]
pub(crate) struct Steered(AtomicU8);

const NEW: u8 = 0;
const STEERED: u8 = 1;
const STARTED: u8 = 2;

impl Steered {
    /// The starting thread has steered the worker: whether the worker had not started yet
    /// (then the worker lets itself go when it starts; otherwise the caller must).
    pub(crate) fn steered(&self) -> bool {
        self.0.compare_exchange(NEW, STEERED, Ordering::AcqRel, Ordering::Acquire).is_ok()
    }

    /// The worker has started: whether it was steered before (then it must let itself go).
    pub(crate) fn started(&self) -> bool {
        self.0.swap(STARTED, Ordering::AcqRel) == STEERED
    }
}

/// How many CPUs the calling thread may run on (`None` where the kernel does not say, or
/// elsewhere than Linux): one system call.
pub(crate) fn allowed_cpus() -> Option<usize> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: CPU_COUNT reads a whole cpu_set_t.
        linux::allowed().map(|set| unsafe { libc::CPU_COUNT(&set) } as usize)
    }
    #[cfg(not(target_os = "linux"))]
    None
}

#[cfg(target_os = "linux")]
mod linux {
    /// The CPUs the calling thread may run on, or `None` when the kernel does not say.
    pub(super) fn allowed() -> Option<libc::cpu_set_t> {
        // SAFETY: cpu_set_t is plain bits, valid when zeroed; sched_getaffinity writes at most
        // the size given.
        unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            (libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) == 0).then_some(set)
        }
    }

    /// (The CPUs the process may use but the calling thread's, all it may use), or `None` when
    /// that leaves none or the kernel does not say.
    pub(super) fn others() -> Option<(libc::cpu_set_t, libc::cpu_set_t)> {
        let all = allowed()?;
        // SAFETY: sched_getcpu takes nothing; the CPU_ macros read and write whole cpu_set_ts.
        unsafe {
            let here = libc::sched_getcpu();
            let mut others = all;
            if here >= 0 && (here as usize) < libc::CPU_SETSIZE as usize {
                libc::CPU_CLR(here as usize, &mut others);
            }
            (libc::CPU_COUNT(&others) > 0 && libc::CPU_COUNT(&others) < libc::CPU_COUNT(&all)).then_some((others, all))
        }
    }

    /// Sets the CPUs `thread` may run on (a failure, such as a set that another program changed
    /// meanwhile, leaves the thread as it was: it only runs where the kernel puts it).
    pub(super) fn set(thread: libc::pthread_t, cpus: &libc::cpu_set_t) {
        // SAFETY: `thread` is a thread of this process that has not been joined (its handle is
        // held by the caller, or it is the calling thread), and `cpus` is a whole cpu_set_t.
        unsafe {
            libc::pthread_setaffinity_np(thread, std::mem::size_of::<libc::cpu_set_t>(), cpus);
        }
    }

    /// The CPUs the calling thread may run on.
    #[cfg(test)]
    pub(super) fn current() -> Vec<usize> {
        let set = allowed().expect("the kernel says which CPUs");
        // SAFETY: CPU_ISSET reads a whole cpu_set_t.
        (0..libc::CPU_SETSIZE as usize).filter(|&c| unsafe { libc::CPU_ISSET(c, &set) }).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every order of "steered" and "started" lets the worker go exactly once.
    #[test]
    fn whichever_comes_second_lets_the_worker_go() {
        // Steered first: the worker lets itself go.
        let s = Steered::default();
        assert!(s.steered());
        assert!(s.started());
        // Started first: the starting thread lets it go.
        let s = Steered::default();
        assert!(!s.started());
        assert!(!s.steered());
    }

    /// A worker that was steered and started runs where the process may run, whichever of the
    /// two came first, and never on the starting thread's CPU before it was let go.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_steered_worker_ends_up_free() {
        use std::sync::{Arc, Barrier};
        let before = linux::current();
        for early in [false, true] {
            let shared = Arc::new((Steer::others(), Steered::default(), Barrier::new(2)));
            let theirs = Arc::clone(&shared);
            let h = std::thread::spawn(move || {
                let (steer, state, gate) = &*theirs;
                if !early {
                    // Started after it was steered.
                    gate.wait();
                }
                steer.release(state);
                if early {
                    gate.wait();
                }
                gate.wait();
                linux::current()
            });
            let (steer, state, gate) = &*shared;
            if early {
                // Started (and released itself) before it was steered.
                gate.wait();
            }
            steer.steer(&h, state);
            if !early {
                gate.wait();
            }
            gate.wait();
            assert_eq!(h.join().unwrap(), before, "early start: {early}");
        }
        assert_eq!(linux::current(), before, "the starting thread is left as it was");
    }

    /// With more than one CPU, a steered worker starts on another CPU than the starting
    /// thread's (the set it is first given leaves that CPU out).
    #[cfg(target_os = "linux")]
    #[test]
    fn others_leaves_out_the_calling_threads_cpu() {
        let all = linux::current();
        match linux::others() {
            None => assert!(all.len() <= 1, "{all:?}"),
            Some((others, full)) => {
                let others: Vec<usize> =
                    (0..libc::CPU_SETSIZE as usize).filter(|&c| unsafe { libc::CPU_ISSET(c, &others) }).collect();
                let full: Vec<usize> =
                    (0..libc::CPU_SETSIZE as usize).filter(|&c| unsafe { libc::CPU_ISSET(c, &full) }).collect();
                assert_eq!(full, all);
                assert_eq!(others.len() + 1, all.len(), "{others:?} of {all:?}");
                assert!(others.iter().all(|c| all.contains(c)));
            }
        }
    }
}
