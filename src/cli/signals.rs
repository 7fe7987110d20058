//! SIGINT, SIGTERM and SIGHUP: remove the unfinished outputs, then exit;
//! SIGPIPE: end quietly when the reader of standard output has gone.
//!
//! Outputs are written to registered temporary files and renamed into place
//! ([`npf_data_loaders::atomic`]); a process killed mid-write would leave
//! them (up to a 35 MB table, or a 1 GB sample CSV) in the output folder.
//! The signals are blocked in every thread and taken by one thread with
//! `sigwait`, so the clean-up runs as ordinary code, not in a signal handler.

/// Start the signal thread. Call first in `main`, before any other thread
/// starts (threads inherit the blocked mask). Exit status: 128 + signal.
pub fn install() {
    #[cfg(unix)]
    // SAFETY: plain libc calls on a sigset_t we own; the mask is set before
    // any other thread exists, and sigwait only reads the set.
    unsafe {
        // A reader that stops early (`npf sample ... | head`) ends npf
        // quietly, as it does any Unix filter; ignored (Rust's default),
        // the next print would panic on the closed pipe.
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        for s in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            libc::sigaddset(&mut set, s);
        }
        if libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) != 0 {
            return;
        }
        let spawned = std::thread::Builder::new()
            .name("npf-signals".into())
            .spawn(move || {
                let mut sig: libc::c_int = 0;
                while libc::sigwait(&set, &mut sig) != 0 {}
                let n = npf_data_loaders::atomic::remove_live_temps();
                eprintln!("npf: stopped by signal {sig}; removed {n} unfinished output file(s)");
                std::process::exit(128 + sig);
            });
        if spawned.is_err() {
            // No thread to take them: let the signals act as usual again.
            libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
        }
    }
}
