//! Errors of the file formats: every one names the file and the problem.
//!
//! Each variant carries the `path` it is about, and its `Display` starts with
//! that path, so a message printed on its own is enough to act on.
use std::path::{Path, PathBuf};

/// Why a file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The operating system refused a read, write, create or rename.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The file is not exactly as long as the format requires.
    #[error(
        "{path}: wrong file size, {} ({actual} bytes, expected {expected})",
        size_problem(*.expected, *.actual)
    )]
    WrongSize {
        /// The file.
        path: PathBuf,
        /// The size the format requires (bytes).
        expected: u64,
        /// The file's size (bytes).
        actual: u64,
    },
    /// The header dimensions are not those of a MERL table.
    #[error(
        "{path}: not a MERL table, header dimensions are {} {} {} (expected 90 90 180)",
        .dims[0], .dims[1], .dims[2]
    )]
    BadHeader {
        /// The file.
        path: PathBuf,
        /// The header's three dimensions.
        dims: [i32; 3],
    },
    /// The first NaN or infinite value found (channel 0 = red, 1 = green, 2 = blue).
    #[error(
        "{path}: value is NaN or infinite ({} channel, cell {cell})",
        channel_name(*.channel)
    )]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// The channel (0 red, 1 green, 2 blue).
        channel: usize,
        /// The cell index within the channel.
        cell: usize,
    },
    /// The output file exists and overwriting was not asked for.
    #[error("{path}: already exists (refusing to overwrite)")]
    Exists {
        /// The file.
        path: PathBuf,
    },
    /// Anything else wrong with the contents.
    #[error("{path}: {problem}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// The path is not a regular file (a directory, FIFO, device, socket or
    /// dangling symbolic link): `kind` says which, `expected` what was wanted.
    #[error("{path}: is {kind}, not {expected}")]
    NotRegular {
        /// The path.
        path: PathBuf,
        /// What the path is.
        kind: String,
        /// What was wanted.
        expected: &'static str,
    },
    /// The file is larger than the format allows (checked before reading).
    #[error("{path}: {size} bytes, more than the {max} bytes this format allows")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size (bytes).
        size: u64,
        /// The format's maximum (bytes).
        max: u64,
    },
    /// The file is another known kind of file than the one expected.
    #[error("{path}: not {expected}: it looks like {found}")]
    WrongFormat {
        /// The file.
        path: PathBuf,
        /// What was wanted.
        expected: &'static str,
        /// What the file looks like.
        found: String,
    },
}

fn size_problem(expected: u64, actual: u64) -> &'static str {
    match actual {
        0 => "the file is empty",
        a if a < expected => "the file is truncated",
        _ => "the file is too long",
    }
}

fn channel_name(channel: usize) -> String {
    match channel {
        0 => "red".to_string(),
        1 => "green".to_string(),
        2 => "blue".to_string(),
        c => format!("#{c}"),
    }
}

impl LoadError {
    /// An [`LoadError::Io`] about `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        LoadError::Io {
            path: path.into(),
            source,
        }
    }

    /// An [`LoadError::Invalid`] about `path`.
    pub fn invalid(path: impl Into<PathBuf>, problem: impl Into<String>) -> Self {
        LoadError::Invalid {
            path: path.into(),
            problem: problem.into(),
        }
    }

    /// The file this error is about.
    pub fn path(&self) -> &Path {
        match self {
            LoadError::Io { path, .. }
            | LoadError::WrongSize { path, .. }
            | LoadError::BadHeader { path, .. }
            | LoadError::NonFinite { path, .. }
            | LoadError::Exists { path }
            | LoadError::Invalid { path, .. }
            | LoadError::NotRegular { path, .. }
            | LoadError::TooLarge { path, .. }
            | LoadError::WrongFormat { path, .. } => path,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_file_and_the_problem() {
        let p = PathBuf::from("dir/x.binary");
        let cases = [
            (
                LoadError::WrongSize {
                    path: p.clone(),
                    expected: 10,
                    actual: 0,
                },
                "empty",
            ),
            (
                LoadError::WrongSize {
                    path: p.clone(),
                    expected: 10,
                    actual: 9,
                },
                "truncated",
            ),
            (
                LoadError::WrongSize {
                    path: p.clone(),
                    expected: 10,
                    actual: 11,
                },
                "too long",
            ),
            (
                LoadError::BadHeader {
                    path: p.clone(),
                    dims: [1, 2, 3],
                },
                "1 2 3",
            ),
            (
                LoadError::NonFinite {
                    path: p.clone(),
                    channel: 1,
                    cell: 7,
                },
                "green channel, cell 7",
            ),
            (LoadError::Exists { path: p.clone() }, "already exists"),
            (LoadError::invalid(&p, "odd"), "odd"),
            (
                LoadError::io(&p, std::io::Error::other("disk on fire")),
                "disk on fire",
            ),
        ];
        for (e, want) in cases {
            let s = e.to_string();
            assert!(s.starts_with("dir/x.binary: "), "{s}");
            assert!(s.contains(want), "{s}");
            assert_eq!(e.path(), p.as_path());
        }
    }
}
