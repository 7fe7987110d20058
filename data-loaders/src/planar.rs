//! Shared pieces of the channel-planar float64 formats.

use std::io::{self, Write};
use std::path::Path;

use byteorder::{ByteOrder, LittleEndian};

use crate::error::LoadError;

/// [`LoadError::NonFinite`] for the first NaN or infinite value of `raw`,
/// laid out as channel planes of `cells` values each.
pub(crate) fn check_finite(raw: &[f64], cells: usize, path: &Path) -> Result<(), LoadError> {
    use rayon::prelude::*;
    // Whole blocks are checked with a branch-free fold (vectorised), and
    // only a block that fails is searched for its first bad value: the
    // same answer as a search value by value, at a fraction of the work.
    const BLOCK: usize = 4096;
    let first = raw
        .par_chunks(BLOCK)
        .position_first(|b| !b.iter().fold(true, |ok, v| ok & v.is_finite()))
        .and_then(|k| {
            let at = raw[k * BLOCK..].iter().position(|v| !v.is_finite());
            at.map(|j| k * BLOCK + j)
        });
    match first {
        None => Ok(()),
        Some(i) => Err(LoadError::NonFinite {
            path: path.to_path_buf(),
            channel: i / cells,
            cell: i % cells,
        }),
    }
}

/// Writes `values` as little-endian f64, in chunks (no full-size copy).
pub(crate) fn write_f64s(w: &mut dyn Write, values: &[f64]) -> io::Result<()> {
    const CHUNK: usize = 8192;
    let mut buf = vec![0u8; 8 * CHUNK.min(values.len())];
    for chunk in values.chunks(CHUNK) {
        let b = &mut buf[..8 * chunk.len()];
        LittleEndian::write_f64_into(chunk, b);
        w.write_all(b)?;
    }
    Ok(())
}

/// Reads a file of exactly `expected` bytes: the size is checked before the
/// contents are read, and a file that grew meanwhile is reported too long.
#[allow(dead_code)] // for format modules without a name of their own
pub(crate) fn read_exact_size(path: &Path, expected: u64) -> Result<Vec<u8>, LoadError> {
    read_exact_size_as(path, expected, "a file of this format")
}

/// [`read_exact_size`] for a format named `what` ("a MERL table"): a path
/// that is not a regular file is refused without being opened for long
/// ([`crate::sniff::open_regular`]), and a file of the wrong size that is
/// recognisably something else is [`LoadError::WrongFormat`] naming it.
pub(crate) fn read_exact_size_as(
    path: &Path,
    expected: u64,
    what: &'static str,
) -> Result<Vec<u8>, LoadError> {
    use std::io::Read;
    let io = |e| LoadError::io(path, e);
    let file = open_sized(path, expected, what)?;
    let mut bytes = Vec::with_capacity(expected as usize + 1);
    file.take(expected + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 != expected {
        return Err(LoadError::WrongSize {
            path: path.to_path_buf(),
            expected,
            actual: bytes.len() as u64,
        });
    }
    Ok(bytes)
}

/// [`read_exact_size_as`] for a file of a `header` and little-endian f64
/// values: the values are read straight into their own buffer (no copy of
/// the whole file as bytes first, no second 35 MB allocation for a MERL
/// table), in pieces on rayon's current pool where the platform reads at
/// an offset (the copy out of the page cache and the buffer's page faults
/// were one core's 0.05-0.08 s for a MERL table). The same checks and errors.
pub(crate) fn read_header_f64s(
    path: &Path,
    expected: u64,
    header: &mut [u8],
    what: &'static str,
) -> Result<Vec<f64>, LoadError> {
    let file = open_sized(path, expected, what)?;
    let count = (expected as usize).saturating_sub(header.len()) / 8;
    let mut values = vec![0.0f64; count];
    // SAFETY: every bit pattern is a valid f64, and u8 needs no alignment.
    let body =
        unsafe { std::slice::from_raw_parts_mut(values.as_mut_ptr().cast::<u8>(), count * 8) };
    let io = |e| LoadError::io(path, e);
    let mut got = read_parts(&file, 0, header, body).map_err(io)?;
    // One byte more tells a file that grew meanwhile.
    if got == expected {
        got += read_parts(&file, expected, &mut [0u8; 1], &mut []).map_err(io)?;
    }
    if got != expected {
        return Err(LoadError::WrongSize {
            path: path.to_path_buf(),
            expected,
            actual: got,
        });
    }
    // The file is little-endian (a no-op on little-endian machines).
    for v in &mut values {
        *v = f64::from_bits(u64::from_le(v.to_bits()));
    }
    Ok(values)
}

/// Bytes the parallel read gives one task: a MERL table is 17 of them.
#[cfg(unix)]
const READ_PIECE: usize = 2 << 20;

/// Reads `head` then `body` from `file` at byte `start` on: each until it
/// is full or the file ends, `body` in pieces at their offsets on rayon's
/// current pool. The bytes read up to the first short piece; the first
/// error in file order.
#[cfg(unix)]
fn read_parts(
    file: &std::fs::File,
    start: u64,
    head: &mut [u8],
    body: &mut [u8],
) -> io::Result<u64> {
    use rayon::prelude::*;
    use std::os::unix::fs::FileExt;
    let fill_at = |buf: &mut [u8], mut offset: u64| -> io::Result<usize> {
        let mut at = 0;
        while at < buf.len() {
            match file.read_at(&mut buf[at..], offset) {
                Ok(0) => break,
                Ok(n) => (at, offset) = (at + n, offset + n as u64),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(at)
    };
    let n_head = fill_at(head, start)?;
    let mut got = n_head as u64;
    if n_head == head.len() {
        let base = start + head.len() as u64;
        let pieces: Vec<(usize, io::Result<usize>)> = body
            .par_chunks_mut(READ_PIECE)
            .enumerate()
            .map(|(k, piece)| (piece.len(), fill_at(piece, base + (k * READ_PIECE) as u64)))
            .collect();
        for (len, n) in pieces {
            let n = n?;
            got += n as u64;
            if n < len {
                break;
            }
        }
    }
    Ok(got)
}

/// [`read_parts`] where files are not read at offsets: one sequential read.
#[cfg(not(unix))]
fn read_parts(
    file: &std::fs::File,
    start: u64,
    head: &mut [u8],
    body: &mut [u8],
) -> io::Result<u64> {
    use std::io::Seek;
    let mut f = file;
    f.seek(io::SeekFrom::Start(start))?;
    let mut got = 0u64;
    for buf in [head, body] {
        let n = fill(&mut f, buf)?;
        got += n as u64;
        if n < buf.len() {
            break;
        }
    }
    Ok(got)
}

/// Reads into `buf` until it is full or the file ends: the bytes read.
#[cfg(not(unix))]
fn fill(file: &mut impl std::io::Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut at = 0;
    while at < buf.len() {
        match file.read(&mut buf[at..]) {
            Ok(0) => break,
            Ok(n) => at += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(at)
}

/// The file at `path`, opened after [`crate::sniff::open_regular`]'s checks,
/// if it is `expected` bytes long; else the error [`read_exact_size_as`]
/// describes.
fn open_sized(path: &Path, expected: u64, what: &'static str) -> Result<std::fs::File, LoadError> {
    let (file, actual) = crate::sniff::open_regular(path, what)?;
    if actual != expected {
        let found = crate::sniff::describe(path);
        let generic = ["an empty file", "a text file", "a binary file"];
        if generic.iter().any(|g| found.starts_with(g)) {
            return Err(LoadError::WrongSize {
                path: path.to_path_buf(),
                expected,
                actual,
            });
        }
        return Err(LoadError::WrongFormat {
            path: path.to_path_buf(),
            expected: what,
            found,
        });
    }
    Ok(file)
}

#[cfg(test)]
mod finite_tests {
    use super::*;

    #[test]
    fn the_first_non_finite_value_is_named() {
        let cells = 10_000;
        let path = Path::new("t");
        let at = |raw: &[f64]| match check_finite(raw, cells, path) {
            Ok(()) => None,
            Err(LoadError::NonFinite { channel, cell, .. }) => Some(channel * cells + cell),
            Err(e) => panic!("{e:?}"),
        };
        let mut raw = vec![1.0; 3 * cells];
        assert_eq!(at(&raw), None);
        // Several bad values, in one block and in later blocks: the first wins.
        for (i, v) in [
            (25_000, f64::NAN),
            (12_290, f64::INFINITY),
            (12_289, f64::NEG_INFINITY),
        ] {
            raw[i] = v;
        }
        raw[29_999] = f64::NAN;
        assert_eq!(at(&raw), Some(12_289));
        raw[0] = f64::NAN;
        assert_eq!(at(&raw), Some(0));
        let mut raw = vec![0.5; 3 * cells];
        raw[3 * cells - 1] = f64::INFINITY; // in the short last block
        assert_eq!(at(&raw), Some(3 * cells - 1));
    }
}

#[cfg(test)]
mod read_tests {
    use super::*;

    /// The pieces read at their offsets are the file, for any thread
    /// count; a buffer longer than the file is filled up to its end and
    /// the count says where it ended (a file that shrank), and the byte
    /// past the end reads as none (a file that did not grow).
    #[test]
    fn pieces_read_the_file_and_count_what_they_got() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f");
        let len = 3 * READ_PIECE_FOR_TESTS + 12_345;
        let bytes: Vec<u8> = (0..len).map(|i| (i * 7 + i / 251) as u8).collect();
        std::fs::write(&path, &bytes).unwrap();
        let file = std::fs::File::open(&path).unwrap();
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let (mut head, mut body) = (vec![0u8; 12], vec![0u8; len - 12]);
                let got = read_parts(&file, 0, &mut head, &mut body).unwrap();
                assert_eq!(got, len as u64);
                assert_eq!(head[..], bytes[..12]);
                assert!(body[..] == bytes[12..], "{threads} threads");
                // Asked for more than there is: the file's bytes, then zeros.
                let mut long = vec![0u8; len + READ_PIECE_FOR_TESTS];
                let got = read_parts(&file, 0, &mut [], &mut long).unwrap();
                assert_eq!(got, len as u64);
                assert!(long[..len] == bytes[..] && long[len..].iter().all(|&b| b == 0));
                // A short header stops the read there.
                let mut head = vec![0u8; 20];
                let got = read_parts(&file, len as u64 - 5, &mut head, &mut body).unwrap();
                assert_eq!(got, 5);
                let past = |at: u64| read_parts(&file, at, &mut [0u8; 1], &mut []).unwrap();
                assert_eq!((past(len as u64), past(len as u64 - 1)), (0, 1));
            });
        }
    }

    #[cfg(unix)]
    const READ_PIECE_FOR_TESTS: usize = READ_PIECE;
    #[cfg(not(unix))]
    const READ_PIECE_FOR_TESTS: usize = 1 << 20;
}
