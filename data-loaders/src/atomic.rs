//! Atomic writes: the target either keeps its old content or gets the whole
//! new content, never a partial file.
//!
//! The data goes into a temporary file in the target's directory (so the final
//! rename stays on one file system), is flushed and synced, and is then renamed
//! into place. Without `overwrite` the rename is a no-clobber one
//! ([`tempfile::NamedTempFile::persist_noclobber`]), so a file that appears
//! between the check and the rename is not replaced either. On every error the
//! temporary file is removed.

use std::io::{self, BufWriter, Write};
use std::path::Path;

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
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(name);
    prefix.push(".");

    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir).map_err(io_err)?;

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
