//! What a path is, in words, and opening only regular files.
//!
//! Every loader opens its input through [`open_regular`] (no FIFO, device,
//! directory or socket: a FIFO would block and `/dev/zero` never ends) and
//! reads it through [`read_bounded`] (the size is known before anything is
//! allocated). When a file is not what a loader expected, [`describe`] says
//! what it looks like instead (a UTIA table, an npf model, a directory...),
//! so the message points at the mix-up rather than at a wrong size.

use std::fs::{File, Metadata};
use std::io::Read;
use std::path::Path;

use crate::error::LoadError;

/// Size of a MERL `.binary` table (kept here so sniffing needs no table type).
const MERL_BYTES: u64 = 12 + 3 * 1_458_000 * 8;
/// Size of a UTIA `.bin` table.
const UTIA_BYTES: u64 = 3 * 82_944 * 8;

/// What kind of file system object `meta` is, when it is not a regular file.
fn special_kind(meta: &Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("a FIFO (named pipe)");
        }
        if t.is_char_device() {
            return Some("a character device");
        }
        if t.is_block_device() {
            return Some("a block device");
        }
        if t.is_socket() {
            return Some("a socket");
        }
    }
    Some("not a regular file")
}

/// What the first bytes (`head`, a few kilobytes are enough) and the size of
/// a regular file say it is: [`describe`] without the file system.
pub fn describe_bytes(head: &[u8], size: u64) -> String {
    let text = std::str::from_utf8(head).ok();
    let trimmed = text.map(str::trim_start);
    if size == 0 {
        "an empty file".into()
    } else if head.starts_with(b"NPFB") {
        "an npf binary model (.npfb)".into()
    } else if head.starts_with(b"tensor_file\0") {
        "an RGL tensor file (.bsdf)".into()
    } else if head.starts_with(b"\x89PNG") {
        "a PNG image".into()
    } else if size == MERL_BYTES && head.len() >= 12 && head[..12] == merl_header() {
        "a MERL table (.binary)".into()
    } else if size == UTIA_BYTES {
        "a UTIA table (.bin)".into()
    } else if trimmed.is_some_and(|t| t.starts_with('{')) {
        if text.is_some_and(|t| t.contains("\"npf-model\"")) {
            "an npf model (JSON)".into()
        } else {
            "a JSON file".into()
        }
    } else if text.is_some() {
        format!("a text file of {size} bytes")
    } else {
        format!("a binary file of {size} bytes")
    }
}

fn merl_header() -> [u8; 12] {
    let mut h = [0u8; 12];
    for (i, d) in [90i32, 90, 180].iter().enumerate() {
        h[4 * i..4 * i + 4].copy_from_slice(&d.to_le_bytes());
    }
    h
}

/// Bytes read to recognise a file (JSON models name their format early).
const SNIFF_BYTES: usize = 4096;

/// What `path` is, in a few words: "a directory", "a FIFO (named pipe)",
/// "a UTIA table (.bin)", "an npf model (JSON)", "a dangling symbolic
/// link", "missing"... Never blocks (special files are not opened) and
/// reads at most a few kilobytes.
pub fn describe(path: &Path) -> String {
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(_) if path.symlink_metadata().is_ok() => return "a dangling symbolic link".into(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return "missing".into(),
        Err(e) => return format!("unreadable ({e})"),
    };
    if let Some(k) = special_kind(&meta) {
        return k.into();
    }
    let mut head = Vec::with_capacity(SNIFF_BYTES);
    match File::open(path) {
        Ok(f) => {
            if let Err(e) = f.take(SNIFF_BYTES as u64).read_to_end(&mut head) {
                return format!("unreadable ({e})");
            }
        }
        Err(e) => return format!("unreadable ({e})"),
    }
    // A JSON file cut inside a multi-byte character is still text.
    let mut cut = head.len();
    while cut > 0 && cut + 4 > head.len() && std::str::from_utf8(&head[..cut]).is_err() {
        cut -= 1;
    }
    let head = if std::str::from_utf8(&head[..cut]).is_ok() {
        &head[..cut]
    } else {
        &head[..]
    };
    describe_bytes(head, meta.len())
}

/// Opens `path` for reading if it is a regular file (after following
/// symbolic links); otherwise [`LoadError::NotRegular`] saying what it is.
/// `expected` names what the caller wanted ("a MERL table"). The file is
/// opened non-blocking and checked again, so a FIFO swapped in after the
/// first check cannot hang the reader. Returns the file and its size.
pub fn open_regular(path: &Path, expected: &'static str) -> Result<(File, u64), LoadError> {
    let not_regular = |kind: &str| LoadError::NotRegular {
        path: path.to_path_buf(),
        kind: kind.to_string(),
        expected,
    };
    let meta = std::fs::metadata(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound && path.symlink_metadata().is_ok() {
            not_regular("a dangling symbolic link")
        } else {
            LoadError::io(path, e)
        }
    })?;
    if let Some(k) = special_kind(&meta) {
        return Err(not_regular(k));
    }
    let mut opts = std::fs::OpenOptions::new();
    opts.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        opts.custom_flags(libc::O_NONBLOCK);
    }
    let file = opts.open(path).map_err(|e| LoadError::io(path, e))?;
    let meta = file.metadata().map_err(|e| LoadError::io(path, e))?;
    if let Some(k) = special_kind(&meta) {
        return Err(not_regular(k));
    }
    Ok((file, meta.len()))
}

/// Reads a regular file of at most `max` bytes ([`open_regular`]); a larger
/// one is [`LoadError::TooLarge`] before anything is read, and a file that
/// grows while being read is cut off at `max + 1` bytes and refused too.
pub fn read_bounded(path: &Path, max: u64, expected: &'static str) -> Result<Vec<u8>, LoadError> {
    let (file, size) = open_regular(path, expected)?;
    let too_large = |size| LoadError::TooLarge {
        path: path.to_path_buf(),
        size,
        max,
    };
    if size > max {
        return Err(too_large(size));
    }
    let mut bytes = Vec::with_capacity(size as usize);
    file.take(max + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| LoadError::io(path, e))?;
    if bytes.len() as u64 > max {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_what_a_path_is() {
        let dir = tempfile::tempdir().unwrap();
        let p = |n: &str| dir.path().join(n);
        assert_eq!(describe(dir.path()), "a directory");
        assert_eq!(describe(&p("nothing")), "missing");
        std::fs::write(p("empty"), b"").unwrap();
        assert_eq!(describe(&p("empty")), "an empty file");
        std::fs::write(p("m.json"), br#"{"format": "npf-model", "version": 1}"#).unwrap();
        assert_eq!(describe(&p("m.json")), "an npf model (JSON)");
        std::fs::write(p("o.json"), b"  {\"a\": 1}").unwrap();
        assert_eq!(describe(&p("o.json")), "a JSON file");
        std::fs::write(p("m.npfb"), b"NPFB\x01\x00").unwrap();
        assert!(describe(&p("m.npfb")).contains(".npfb"));
        std::fs::write(p("u.bin"), vec![0u8; UTIA_BYTES as usize]).unwrap();
        assert_eq!(describe(&p("u.bin")), "a UTIA table (.bin)");
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(p("gone"), p("link")).unwrap();
            assert_eq!(describe(&p("link")), "a dangling symbolic link");
            assert_eq!(describe(Path::new("/dev/null")), "a character device");
        }
    }

    #[test]
    fn refuses_special_files_and_oversized_ones() {
        let dir = tempfile::tempdir().unwrap();
        let e = open_regular(dir.path(), "a MERL table").unwrap_err();
        assert!(
            e.to_string().contains("is a directory, not a MERL table"),
            "{e}"
        );
        #[cfg(unix)]
        {
            let e = read_bounded(Path::new("/dev/zero"), 10, "a model").unwrap_err();
            assert!(e.to_string().contains("character device"), "{e}");
        }
        let f = dir.path().join("big");
        std::fs::write(&f, vec![1u8; 11]).unwrap();
        let e = read_bounded(&f, 10, "a model").unwrap_err();
        assert!(
            matches!(
                e,
                LoadError::TooLarge {
                    size: 11,
                    max: 10,
                    ..
                }
            ),
            "{e}"
        );
        assert_eq!(read_bounded(&f, 11, "a model").unwrap().len(), 11);
    }
}
