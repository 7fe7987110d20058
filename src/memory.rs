//! Handing freed memory back to the system between the phases of a fit.
//!
//! glibc keeps freed blocks below its (adaptive, up to 32 MB) mmap
//! threshold in the freeing thread's arena. A fit frees large buffers in
//! worker threads (the coarse level's set, the full set's build
//! temporaries, then the whole set), so without a trim the next phase's
//! allocations stack on that free memory and the process's peak resident
//! memory grows by it.

/// Return free heap pages to the system (glibc's `malloc_trim(0)`); a no-op
/// elsewhere. It touches no live allocation; it costs a few milliseconds.
pub fn release_free() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free heap pages; it touches no live allocation.
    unsafe {
        libc::malloc_trim(0);
    }
}
