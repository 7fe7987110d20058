//! A low-latency partner for the decimated levels' short loops.
//!
//! A coarse level's Gauss-Seidel steps are small (a G control point has
//! ~2,600 entries at 1/32, ~5 us of work): a rayon task per half costs
//! more in dispatch and wake-up than it saves (BENCHMARKS.md as of 4d8d1ee, c27). A
//! [`Duo`] instead keeps one partner spinning on a job slot while the level
//! runs: [`Duo::halves`] hands it half of a job, does the other half and
//! spins until the partner is done (well under a microsecond each way).
//!
//! The partner is the thread that built the full sample set
//! (`coarse::fit`'s first join arm): once the build is done it calls
//! [`Duo::serve`] and works for the level until [`Duo::lead`] ends. While
//! idle it also runs the level's pending rayon work (`rayon::yield_now`), so
//! the level's `par_iter` passes keep both cores without waking a third
//! thread. With one thread (or before the build ends) nobody serves and
//! [`Duo::halves`] runs both halves itself, in the same order with the same
//! arithmetic: results never depend on whether the partner helped.

use std::any::Any;
use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};
use std::thread::ThreadId;

/// The level's loops have started ([`Duo::lead`]).
const LEADING: u32 = 1;
/// The partner is in [`Duo::serve`]'s loop.
const SERVING: u32 = 2;
/// The level's loops have ended: the partner leaves.
const FINISHED: u32 = 4;

/// Idle spins between two looks for pending rayon work.
const SPINS_PER_STEAL: u32 = 32;
/// Idle spins between two yields of the time slice (so the spinning
/// partner never starves another thread of the machine).
const SPINS_PER_YIELD: u32 = 512;

/// A gap this long in the partner's idle loop means it was off the core.
const PREEMPTED: std::time::Duration = std::time::Duration::from_millis(2);
/// The partner leaves after this many such gaps.
const PREEMPTIONS: usize = 8;

/// The half job the partner runs: a closure on the caller's stack, its
/// lifetime erased (see [`Duo::halves`] for why it stays valid).
type Task = *mut (dyn FnMut() + Send + 'static);

/// A partner thread's job slot and state; see the module notes.
pub struct Duo {
    state: AtomicU32,
    owner: OnceLock<ThreadId>,
    /// Jobs posted; the slot holds job `posted`.
    posted: AtomicU64,
    /// The last job claimed (by the partner to run it, or back by the
    /// owner when the partner had not started it).
    claimed: AtomicU64,
    /// Jobs the partner finished.
    done: AtomicU64,
    slot: UnsafeCell<Option<Task>>,
    /// A panic of the partner's half, for the caller to resume.
    panic: Mutex<Option<Box<dyn Any + Send>>>,
    panicked: AtomicBool,
    /// Halves the partner ran, and halves taken back (for `NPF_TIMING`).
    ran: AtomicU64,
    taken_back: AtomicU64,
    /// Whether the partner left early ([`PREEMPTIONS`]).
    retired: AtomicBool,
}

// SAFETY: `slot` is written only by the owner before it publishes the job
// (`posted`, Release) and read only by the partner after it sees that job
// (Acquire); the owner does not touch it again until the partner signals
// `done` (Release/Acquire). The task it points to is `Send`.
unsafe impl Sync for Duo {}

impl Default for Duo {
    fn default() -> Self {
        Self::new()
    }
}

impl Duo {
    /// A duo nobody leads or serves yet.
    pub fn new() -> Self {
        Duo {
            state: AtomicU32::new(0),
            owner: OnceLock::new(),
            posted: AtomicU64::new(0),
            claimed: AtomicU64::new(0),
            done: AtomicU64::new(0),
            slot: UnsafeCell::new(None),
            panic: Mutex::new(None),
            panicked: AtomicBool::new(false),
            ran: AtomicU64::new(0),
            taken_back: AtomicU64::new(0),
            retired: AtomicBool::new(false),
        }
    }

    /// Run `f` (the level's loops) on this thread as the duo's owner: its
    /// [`Duo::halves`] may hand halves to a partner in [`Duo::serve`]. The
    /// partner is released when `f` returns or unwinds. One lead per duo:
    /// a second one runs `f` without a partner.
    pub fn lead<R>(&self, f: impl FnOnce() -> R) -> R {
        struct Release<'a>(&'a Duo);
        impl Drop for Release<'_> {
            fn drop(&mut self) {
                self.0.state.fetch_or(FINISHED, Ordering::AcqRel);
            }
        }
        if self.owner.set(std::thread::current().id()).is_err() {
            return f();
        }
        self.state.fetch_or(LEADING, Ordering::AcqRel);
        let _release = Release(self);
        f()
    }

    /// Serve the owner's halves until its [`Duo::lead`] ends; returns at
    /// once if the lead has not started (it may then run on this very
    /// thread later, and must not wait for a partner that is its caller)
    /// or has ended.
    pub fn serve(&self) {
        let s = self.state.load(Ordering::Acquire);
        if s & LEADING == 0 || s & FINISHED != 0 {
            return;
        }
        if self.owner.get() == Some(&std::thread::current().id()) {
            return;
        }
        self.state.fetch_or(SERVING, Ordering::AcqRel);
        let (mut seen, mut idle) = (self.posted.load(Ordering::Acquire), 0u32);
        let (mut last, mut preempted) = (std::time::Instant::now(), 0usize);
        loop {
            let p = self.posted.load(Ordering::Acquire);
            if p != seen {
                seen = p;
                let claim =
                    self.claimed
                        .compare_exchange(p - 1, p, Ordering::AcqRel, Ordering::Acquire);
                if claim.is_err() {
                    // The owner took it back.
                    continue;
                }
                // SAFETY: job `p` is published (Acquire above) and claimed
                // by this thread; the owner waits for `done == p` before
                // its frame (where the task lives) moves on.
                let task = unsafe { (*self.slot.get()).take() };
                if let Some(task) = task {
                    // SAFETY: as above; no one else calls this task.
                    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| unsafe {
                        (*task)()
                    }));
                    if let Err(e) = run {
                        *self.panic.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
                        self.panicked.store(true, Ordering::Release);
                    }
                }
                self.ran.fetch_add(1, Ordering::Relaxed);
                self.done.store(p, Ordering::Release);
                idle = 0;
                last = std::time::Instant::now();
                continue;
            }
            if self.state.load(Ordering::Acquire) & FINISHED != 0 {
                return;
            }
            idle = idle.wrapping_add(1);
            if idle % SPINS_PER_STEAL == 0 {
                // Off the core for a time slice: the machine has more
                // runnable threads than cores, and a spinning partner
                // would take the owner's time. Leave it to rayon's join
                // (whose idle threads sleep).
                let now = std::time::Instant::now();
                if now - last > PREEMPTED {
                    preempted += 1;
                    if preempted > PREEMPTIONS {
                        self.state.fetch_and(!SERVING, Ordering::AcqRel);
                        self.retired.store(true, Ordering::Relaxed);
                        // A job posted but not claimed is taken back by
                        // the owner, so nothing waits for this thread.
                        return;
                    }
                }
                last = now;
            }
            if idle % SPINS_PER_YIELD == 0 {
                std::thread::yield_now();
            } else if idle % SPINS_PER_STEAL == 0 {
                // The level's par_iter pieces (only the owner makes work
                // in this pool while it leads).
                if let Some(rayon::Yield::Executed) = rayon::yield_now() {
                    idle = 0;
                    // Time in that work is not time off the core (a long
                    // piece, such as auto's renders, would read as one).
                    last = std::time::Instant::now();
                }
            } else {
                std::hint::spin_loop();
            }
        }
    }

    /// Halves handed off (run by the partner, taken back by the owner),
    /// and whether the partner left early (the machine was busy).
    pub fn handed_off(&self) -> (u64, u64, bool) {
        (
            self.ran.load(Ordering::Relaxed),
            self.taken_back.load(Ordering::Relaxed),
            self.retired.load(Ordering::Relaxed),
        )
    }

    /// Whether a lead has started (it may have ended since).
    pub fn is_led(&self) -> bool {
        self.state.load(Ordering::Acquire) & LEADING != 0
    }

    /// `f` led on this thread with a partner on another one (scoped):
    /// the partner waits for the lead and serves it, `f` starts once it
    /// serves (or has left, on a busy machine). For tests and benches;
    /// `coarse::fit` never waits for its partner.
    pub fn with_partner<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        std::thread::scope(|scope| {
            scope.spawn(|| {
                while !self.is_led() {
                    std::thread::yield_now();
                }
                self.serve();
            });
            self.lead(|| {
                while !(self.active() || self.retired.load(Ordering::Relaxed)) {
                    std::thread::yield_now();
                }
                f()
            })
        })
    }

    /// Whether a partner serves the calling thread's halves now.
    pub fn active(&self) -> bool {
        let s = self.state.load(Ordering::Acquire);
        s & SERVING != 0
            && s & FINISHED == 0
            && self.owner.get() == Some(&std::thread::current().id())
    }

    /// `[f(0), f(1)]`: the first half on this thread, the second on the
    /// partner when one serves and `hand_off` is true, else both here in
    /// that order. Which thread runs a half never changes its result.
    pub fn halves<R: Send>(&self, hand_off: bool, f: impl Fn(usize) -> R + Sync) -> [R; 2] {
        if !(hand_off && self.active()) {
            let a = f(0);
            return [a, f(1)];
        }
        let mut second: Option<R> = None;
        let first;
        {
            let mut task = || second = Some(f(1));
            let task: &mut (dyn FnMut() + Send + '_) = &mut task;
            // SAFETY: only the lifetime is erased; this block does not end
            // before the task is taken back or the partner has finished it
            // (`Wait`, also when the first half unwinds), so the borrow
            // outlives every use.
            let task: Task = unsafe { std::mem::transmute(task as *mut (dyn FnMut() + Send + '_)) };
            let job = self.posted.load(Ordering::Relaxed) + 1;
            // SAFETY: the partner reads the slot only after claiming job
            // `job`, which `posted` announces below; the previous job is
            // over (run back here or awaited), so nobody reads it now.
            unsafe { *self.slot.get() = Some(task) };
            self.posted.store(job, Ordering::Release);
            /// Takes the job back if the partner has not claimed it, else
            /// waits until the partner has finished it.
            struct Wait<'a>(&'a Duo, u64);
            impl Wait<'_> {
                fn settle(&self) -> bool {
                    let back = self.0.claimed.compare_exchange(
                        self.1 - 1,
                        self.1,
                        Ordering::AcqRel,
                        Ordering::Acquire,
                    );
                    if back.is_ok() {
                        // SAFETY: the partner never claimed this job, so it
                        // never reads the slot for it.
                        unsafe { *self.0.slot.get() = None };
                        return true;
                    }
                    let mut spins = 0u32;
                    while self.0.done.load(Ordering::Acquire) != self.1 {
                        // A preempted partner: give it the core.
                        spins = spins.wrapping_add(1);
                        if spins % SPINS_PER_STEAL == 0 {
                            std::thread::yield_now();
                        } else {
                            std::hint::spin_loop();
                        }
                    }
                    false
                }
            }
            impl Drop for Wait<'_> {
                fn drop(&mut self) {
                    if std::thread::panicking() {
                        self.settle();
                    }
                }
            }
            let wait = Wait(self, job);
            first = f(0);
            let taken_back = wait.settle();
            std::mem::forget(wait);
            if taken_back {
                self.taken_back.fetch_add(1, Ordering::Relaxed);
                let s = f(1);
                return [first, s];
            }
        }
        if self.panicked.swap(false, Ordering::AcqRel) {
            let e = self.panic.lock().unwrap_or_else(|p| p.into_inner()).take();
            std::panic::resume_unwind(e.unwrap_or_else(|| Box::new("duo partner panicked")));
        }
        match second {
            Some(s) => [first, s],
            // Unreachable: the partner ran the task (no panic).
            None => [first, f(1)],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A partner's halves equal the caller's own, job after job.
    #[test]
    fn halves_with_and_without_a_partner_agree() {
        let data: Vec<f64> = (0..10_000)
            .map(|i| ((i * 7919) % 1000) as f64 * 1e-3)
            .collect();
        let sum = |duo: &Duo, n: usize| {
            let mid = n / 2;
            let [a, b] = duo.halves(true, |k| {
                let r = if k == 0 { 0..mid } else { mid..n };
                data[r].iter().sum::<f64>()
            });
            a + b
        };
        let alone = Duo::new();
        let want: Vec<f64> = (1..300).map(|n| sum(&alone, n * 30)).collect();
        let duo = Duo::new();
        let got = duo.with_partner(|| (1..300).map(|n| sum(&duo, n * 30)).collect::<Vec<_>>());
        assert_eq!(want, got);
    }

    /// A serve before any lead, or after it ended, returns at once; a lead
    /// that is never served runs both halves itself.
    #[test]
    fn no_wait_without_the_other_side() {
        let duo = Duo::new();
        duo.serve();
        let r = duo.lead(|| duo.halves(true, |h| h * 10));
        assert_eq!(r, [0, 10]);
        duo.serve();
        assert!(!duo.active());
    }

    /// A lead that unwinds releases its partner.
    #[test]
    fn an_unwinding_lead_releases_the_partner() {
        let duo = Duo::new();
        // The scope returns only once the partner has left.
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            duo.with_partner(|| panic!("level failed"))
        }));
        assert!(r.is_err());
        assert!(duo.is_led() && !duo.active());
    }
}
