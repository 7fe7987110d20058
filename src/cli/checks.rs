//! Checks a command makes before any work: outputs that would overwrite
//! an input or an existing file, thread counts.

use super::error::{CliError, CliResult};
use std::path::Path;

/// Refuse early (before any work) to overwrite an output, and fail early on
/// an output that could not be written: a directory, a special file (a
/// device or FIFO would be replaced by the final rename), a dangling
/// symbolic link, or a folder that does not exist or is not writable.
pub fn check_output(path: &Path, force: bool) -> CliResult {
    let refuse = |why: String| Err(CliError::Message(format!("{}: {why}", path.display())));
    if path.symlink_metadata().is_ok() {
        match std::fs::metadata(path) {
            Err(_) => {
                return refuse(
                    "is a dangling symbolic link (remove it or choose another output)".into(),
                )
            }
            Ok(m) if m.is_dir() => return refuse("is a directory, not an output file".into()),
            Ok(m) if !m.is_file() => {
                return refuse(format!(
                    "is {}, not a regular file: refusing to replace it",
                    npf_data_loaders::sniff::describe(path)
                ))
            }
            Ok(_) if !force => return refuse("already exists (pass --force to overwrite)".into()),
            Ok(_) => {}
        }
    }
    if path.file_name().is_none() {
        return refuse("is not a file name".into());
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(CliError::Message(format!(
            "{}: the output folder {} does not exist",
            path.display(),
            parent.display()
        )));
    }
    // Outputs are written through a temporary file in the same folder:
    // find out now, not after a long fit, whether that is possible.
    tempfile::NamedTempFile::new_in(parent).map_err(|e| {
        CliError::Message(format!(
            "{}: cannot write in {}: {e}",
            path.display(),
            parent.display()
        ))
    })?;
    Ok(())
}

/// Where `path` is or would be: the canonical path of the file, or of its
/// folder joined with its name when it does not exist yet.
fn canonical_target(path: &Path) -> Option<std::path::PathBuf> {
    if let Ok(p) = std::fs::canonicalize(path) {
        return Some(p);
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    Some(std::fs::canonicalize(parent).ok()?.join(path.file_name()?))
}

/// Whether two paths name the same file: the same canonical path, or (for
/// hard links) the same device and inode.
fn same_file(a: &Path, b: &Path) -> bool {
    if let (Some(x), Some(y)) = (canonical_target(a), canonical_target(b)) {
        if x == y {
            return true;
        }
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return x.dev() == y.dev() && x.ino() == y.ino();
        }
    }
    false
}

/// [`check_output`] for every output of a command, and refuse before any
/// work an output that is the same file as an input or as another output
/// (by canonical path or inode), so an input is never overwritten and no
/// command writes one file twice.
pub fn check_outputs(outputs: &[&Path], inputs: &[&Path], force: bool) -> CliResult {
    for (k, out) in outputs.iter().enumerate() {
        if let Some(input) = inputs.iter().find(|i| same_file(out, i)) {
            return Err(CliError::Message(format!(
                "{}: is the input {}: refusing to overwrite an input (choose another output)",
                out.display(),
                input.display()
            )));
        }
        if let Some(other) = outputs[..k].iter().find(|o| same_file(out, o)) {
            return Err(CliError::Message(format!(
                "{}: is also the output {}: give each output its own file",
                out.display(),
                other.display()
            )));
        }
        check_output(out, force)?;
    }
    Ok(())
}

/// Refuse a thread count above [`crate::fit::max_threads`] (0 means all cores).
pub fn check_threads(flag: &str, n: usize) -> CliResult {
    let max = crate::fit::max_threads();
    if n > max {
        return Err(CliError::Message(format!(
            "{flag} {n}: at most {max} (4 per core on this machine; 0 uses every core)"
        )));
    }
    Ok(())
}
