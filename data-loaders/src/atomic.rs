//! Atomic writes: the target either keeps its old content or gets the whole
//! new content, never a partial file.
//!
//! The data goes into a temporary file in the target's directory (so the final
//! rename stays on one file system), is flushed and synced, and is then renamed
//! into place. Without `overwrite` the rename is a no-clobber one
//! ([`tempfile::NamedTempFile::persist_noclobber`]), so a file that appears
//! between the check and the rename is not replaced either. On every error the
//! temporary file is removed.
//!
//! A process killed mid-write cannot run that clean-up, so every live
//! temporary file is also registered ([`remove_live_temps`] deletes them;
//! the `npf` program calls it from its SIGINT/SIGTERM handler), and its name
//! carries the writer's process id (`.NAME.npf-PID.XXXXXX.tmp`): a later
//! write of the same target removes the leftovers of writers that are no
//! longer running (on Linux, where `/proc` tells).

use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Temporary files being written now, in this process.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Deletes every temporary file an unfinished [`write_atomic`] of this
/// process holds, and returns how many it removed. For a signal handler
/// about to end the process (the writes themselves then fail or never
/// finish; their targets are untouched). Also [`register_temp`]'s paths.
pub fn remove_live_temps() -> usize {
    // A writer that panicked while holding the lock left a usable list.
    let live = match LIVE.lock() {
        Ok(g) => g,
        Err(p) => p.into_inner(),
    };
    live.iter()
        .filter(|p| std::fs::remove_file(p).is_ok())
        .count()
}

/// The temporary files [`remove_live_temps`] would delete now.
pub fn live_temps() -> Vec<PathBuf> {
    LIVE.lock().map(|l| l.clone()).unwrap_or_default()
}

/// Registers a temporary file made outside [`write_atomic`] for
/// [`remove_live_temps`]; it stays registered until the guard drops.
pub fn register_temp(path: &Path) -> TempGuard {
    if let Ok(mut live) = LIVE.lock() {
        live.push(path.to_path_buf());
    }
    TempGuard(path.to_path_buf())
}

/// Keeps a path in the live temporary-file list while it exists.
#[derive(Debug)]
pub struct TempGuard(PathBuf);

impl Drop for TempGuard {
    fn drop(&mut self) {
        if let Ok(mut live) = LIVE.lock() {
            if let Some(i) = live.iter().position(|p| *p == self.0) {
                live.swap_remove(i);
            }
        }
    }
}

/// Whether process `pid` still runs (unknown, so assumed running, off Linux).
fn running(pid: u32) -> bool {
    if !Path::new("/proc/self").exists() {
        return true;
    }
    Path::new("/proc").join(pid.to_string()).exists()
}

/// Removes `dir`'s temporary files for target `name` left by writers that
/// are no longer running (killed before they could clean up).
fn remove_stale(dir: &Path, name: &std::ffi::OsStr) {
    let Some(name) = name.to_str() else { return };
    let prefix = format!(".{name}.npf-");
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let file = e.file_name();
        let Some(f) = file.to_str() else { continue };
        let Some(rest) = f.strip_prefix(&prefix) else {
            continue;
        };
        if !f.ends_with(".tmp") {
            continue;
        }
        let pid = rest.split('.').next().and_then(|p| p.parse::<u32>().ok());
        if pid.is_some_and(|p| p != std::process::id() && !running(p)) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

use crate::error::LoadError;

/// Writes a file atomically through `write`.
///
/// If `overwrite` is false and `path` exists (even as a dangling symlink),
/// returns [`LoadError::Exists`] and leaves it untouched. Errors from `write`,
/// from creating the temporary file (for example an unwritable or missing
/// directory) and from the rename are returned as [`LoadError::Io`] naming
/// `path`; in all these cases no output and no temporary file remain.
///
/// On Unix the new file gets the usual permissions of a newly created file
/// (0666 minus the umask), not the 0600 of a temporary file.
pub fn write_atomic(
    path: &Path,
    overwrite: bool,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<(), LoadError> {
    let exists = || LoadError::Exists {
        path: path.to_path_buf(),
    };
    // Early check, only to fail before doing the work; the no-clobber rename
    // below is what makes it safe.
    if !overwrite && path.symlink_metadata().is_ok() {
        return Err(exists());
    }
    let io_err = |e| LoadError::io(path, e);

    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| io_err(io::Error::other("not a file name")))?;
    remove_stale(dir, name);
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(name);
    prefix.push(format!(".npf-{}.", std::process::id()));

    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir).map_err(io_err)?;
    let _live = register_temp(tmp.path());

    {
        let mut w = BufWriter::with_capacity(1 << 20, tmp.as_file_mut());
        write(&mut w).map_err(io_err)?;
        w.flush().map_err(io_err)?;
    }
    tmp.as_file().sync_all().map_err(io_err)?;

    if overwrite {
        tmp.persist(path).map_err(|e| io_err(e.error))?;
    } else {
        match tmp.persist_noclobber(path) {
            Ok(_) => {}
            Err(e) if e.error.kind() == io::ErrorKind::AlreadyExists => return Err(exists()),
            Err(e) => return Err(io_err(e.error)),
        }
    }
    // Make the rename itself durable; failure here does not undo the write.
    #[cfg(unix)]
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// [`write_atomic`] for bytes already in memory.
pub fn write_bytes_atomic(path: &Path, overwrite: bool, bytes: &[u8]) -> Result<(), LoadError> {
    write_atomic(path, overwrite, |w| w.write_all(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn creates_refuses_and_overwrites() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.bin");
        write_bytes_atomic(&p, false, b"first").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"first");

        let e = write_bytes_atomic(&p, false, b"second").unwrap_err();
        assert!(matches!(e, LoadError::Exists { .. }), "{e}");
        assert!(e.to_string().contains("out.bin"), "{e}");
        assert_eq!(std::fs::read(&p).unwrap(), b"first");

        write_bytes_atomic(&p, true, b"third").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"third");
        assert_eq!(entries(dir.path()), vec!["out.bin"]);
    }

    #[test]
    fn failing_writer_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.bin");
        let e = write_atomic(&p, false, |w| {
            w.write_all(&[0u8; 5000])?;
            Err(io::Error::other("generator failed"))
        })
        .unwrap_err();
        assert!(matches!(e, LoadError::Io { .. }), "{e}");
        assert!(e.to_string().contains("generator failed"), "{e}");
        assert!(entries(dir.path()).is_empty());

        // Nor does it damage an existing file when overwriting.
        std::fs::write(&p, b"old").unwrap();
        write_atomic(&p, true, |_| Err(io::Error::other("no"))).unwrap_err();
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(entries(dir.path()), vec!["out.bin"]);
    }

    #[test]
    fn missing_directory_is_an_io_error_naming_the_target() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("nope").join("out.bin");
        let e = write_bytes_atomic(&p, true, b"x").unwrap_err();
        assert!(matches!(e, LoadError::Io { .. }), "{e}");
        assert_eq!(e.path(), p.as_path());
        assert!(!p.exists());
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn live_temps_are_registered_and_removed() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.bin");
        let e = write_atomic(&p, false, |w| {
            w.write_all(b"partial")?;
            // What a signal handler does while the write is under way
            // (only for this test's file: other tests write concurrently).
            let mine: Vec<PathBuf> = live_temps()
                .into_iter()
                .filter(|t| t.parent() == Some(dir.path()))
                .collect();
            assert_eq!(mine.len(), 1);
            std::fs::remove_file(&mine[0])?;
            Err(io::Error::other("interrupted"))
        })
        .unwrap_err();
        assert!(e.to_string().contains("interrupted"), "{e}");
        assert!(entries(dir.path()).is_empty());
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn stale_temps_of_dead_writers_are_cleaned() {
        let dir = tempfile::tempdir().unwrap();
        // No process has pid u32::MAX - 1 on Linux (pid_max <= 2^22).
        let stale = dir
            .path()
            .join(format!(".out.bin.npf-{}.abc123.tmp", u32::MAX - 1));
        let other = dir.path().join(".other.bin.npf-4294967294.x.tmp");
        std::fs::write(&stale, b"left by a killed run").unwrap();
        std::fs::write(&other, b"not ours").unwrap();
        write_bytes_atomic(&dir.path().join("out.bin"), false, b"x").unwrap();
        assert_eq!(
            entries(dir.path()),
            vec![".other.bin.npf-4294967294.x.tmp", "out.bin"]
        );
    }

    #[cfg(unix)]
    #[test]
    fn new_files_are_not_private() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.bin");
        write_bytes_atomic(&p, false, b"x").unwrap();
        std::fs::write(dir.path().join("plain"), b"x").unwrap();
        let mode = |q: &Path| std::fs::metadata(q).unwrap().permissions().mode() & 0o777;
        // Same mode as any newly created file (0666 minus the umask), not the
        // temporary file's 0600.
        assert_eq!(mode(&p), mode(&dir.path().join("plain")));
    }
}
