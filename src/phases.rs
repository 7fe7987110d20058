//! An opt-in wall-clock breakdown of a fit's phases: with the environment
//! variable `NPF_TIMING` set (to anything but `0`), each [`mark`] prints to
//! stderr the time since the previous mark and since the first. For
//! measuring where the time outside the sweeps goes (issue 15); a no-op
//! costing one atomic load otherwise.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// 0: not read yet, 1: off, 2: on.
static STATE: AtomicU8 = AtomicU8::new(0);
/// (first mark, previous mark, process CPU seconds at the previous mark).
static MARKS: Mutex<Option<(Instant, Instant, f64)>> = Mutex::new(None);

/// User + system CPU seconds of the whole process so far (NaN where
/// unknown): on a shared machine, wall time alone says little.
fn cpu_seconds() -> f64 {
    #[cfg(unix)]
    {
        // SAFETY: getrusage only writes the struct it is given.
        let mut u: libc::rusage = unsafe { std::mem::zeroed() };
        if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } == 0 {
            let s = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
            return s(u.ru_utime) + s(u.ru_stime);
        }
    }
    f64::NAN
}

/// The process's peak resident memory so far (MB), where the system says.
fn peak_memory() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Whether `NPF_TIMING` asks for the breakdown.
pub fn enabled() -> bool {
    match STATE.load(Ordering::Relaxed) {
        0 => {
            let on = std::env::var_os("NPF_TIMING").is_some_and(|v| v != "0");
            STATE.store(if on { 2 } else { 1 }, Ordering::Relaxed);
            on
        }
        s => s == 2,
    }
}

/// The end of `phase`: prints its duration (since the previous mark) when
/// [`enabled`]. The first mark starts the clock.
pub fn mark(phase: &str) {
    if !enabled() {
        return;
    }
    let (now, cpu) = (Instant::now(), cpu_seconds());
    let mut marks = MARKS.lock().unwrap_or_else(|e| e.into_inner());
    let (first, last, last_cpu) = marks.get_or_insert((now, now, cpu));
    eprintln!(
        "npf timing: {phase:<28} {:8.3} s wall {:7.3} s cpu  (at {:7.3} s){}",
        (now - *last).as_secs_f64(),
        cpu - *last_cpu,
        (now - *first).as_secs_f64(),
        peak_memory().map_or(String::new(), |m| format!("  peak {m:.0} MB"))
    );
    (*last, *last_cpu) = (now, cpu);
}

/// Prints a duration measured elsewhere (e.g. a phase that ran
/// concurrently with others), without moving the clock.
pub fn note(phase: &str, seconds: f64) {
    if enabled() {
        eprintln!("npf timing: {phase:<28} {seconds:8.3} s wall (concurrent with the above)");
    }
}

/// Laps of a function's steps, printed as one line at the end when
/// [`enabled`] (a function that may run concurrently with others, such
/// as a sample-set build, cannot use [`mark`]).
pub struct Lap {
    what: String,
    last: Option<Instant>,
    laps: Vec<(&'static str, f64)>,
}

impl Lap {
    /// Start timing the steps of `what` over `n` items.
    pub fn new(what: &str, n: usize) -> Self {
        let on = enabled();
        Lap {
            what: if on {
                format!("{what} ({n})")
            } else {
                String::new()
            },
            last: on.then(Instant::now),
            laps: Vec::new(),
        }
    }

    /// The end of step `step`.
    pub fn done(&mut self, step: &'static str) {
        if let Some(last) = &mut self.last {
            let now = Instant::now();
            self.laps.push((step, (now - *last).as_secs_f64()));
            *last = now;
        }
    }
}

impl Drop for Lap {
    fn drop(&mut self) {
        if self.last.is_some() {
            let laps: Vec<String> = self
                .laps
                .iter()
                .map(|(s, t)| format!("{s} {:.0} ms", t * 1e3))
                .collect();
            eprintln!("npf timing: {}: {}", self.what, laps.join(", "));
        }
    }
}
