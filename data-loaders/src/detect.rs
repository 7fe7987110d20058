//! Which measured format a file is: the one place MERL and UTIA tables are
//! told apart (by extension and by exact size; the formats have no magic
//! number a UTIA file could be checked against).
//!
//! Rules, in order: a forced [`Format`] is used as given (the reader then
//! checks the size); `.binary` means MERL and `.bin` means UTIA, and a file
//! whose size is the *other* format's is refused as ambiguous (pass the
//! format explicitly); any other extension is decided by size alone; a file
//! of neither size is refused with what it looks like (its size against both
//! formats'). A `.bsdf` file (RGL's tensor format, no `--format`) is read
//! as its BRDF tabulated on a MERL table's nodes, or on a UTIA table's if
//! it is anisotropic ([`crate::rgl_brdf`]).

use std::path::Path;

use crate::error::LoadError;
use crate::merl::MerlTable;
use crate::samples::MeasuredSamples;
use crate::utia::UtiaTable;

/// A measured table format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// MERL `.binary` (isotropic, 90 x 90 x 180).
    Merl,
    /// UTIA `.bin` (anisotropic, 6 x 48 x 6 x 48).
    Utia,
}

impl Format {
    /// The format's name as the `--format` flag spells it.
    pub fn name(self) -> &'static str {
        match self {
            Format::Merl => "merl",
            Format::Utia => "utia",
        }
    }

    /// Exact file size of the format.
    pub fn file_bytes(self) -> u64 {
        match self {
            Format::Merl => MerlTable::FILE_BYTES,
            Format::Utia => UtiaTable::FILE_BYTES,
        }
    }

    /// The format a file of this name and size is (see the module notes).
    pub fn detect(path: &Path, bytes: u64) -> Result<Format, LoadError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let by_size = [Format::Merl, Format::Utia]
            .into_iter()
            .find(|f| f.file_bytes() == bytes);
        let by_ext = match ext.as_deref() {
            Some("binary") => Some(Format::Merl),
            Some("bin") => Some(Format::Utia),
            _ => None,
        };
        match (by_ext, by_size) {
            (Some(e), Some(s)) if e != s => Err(LoadError::invalid(
                path,
                format!(
                    "ambiguous format: the extension says {} but the size ({bytes} bytes) is a {} table's; pass --format {} or --format {}",
                    e.name().to_uppercase(),
                    s.name().to_uppercase(),
                    e.name(),
                    s.name()
                ),
            )),
            (Some(e), _) => Ok(e),
            (None, Some(s)) => Ok(s),
            (None, None) => Err(LoadError::invalid(
                path,
                format!(
                    "not a measured table: {bytes} bytes, a MERL .binary has {} and a UTIA .bin {}",
                    MerlTable::FILE_BYTES,
                    UtiaTable::FILE_BYTES
                ),
            )),
        }
    }
}

/// A measured table of either format.
#[derive(Clone, Debug)]
pub enum Table {
    /// An isotropic MERL table.
    Merl(MerlTable),
    /// An anisotropic UTIA table.
    Utia(UtiaTable),
}

impl Table {
    /// Reads `path` as `hint` if given, else as the format
    /// [`Format::detect`] finds; every error names the file.
    pub fn read(path: &Path, hint: Option<Format>) -> Result<Table, LoadError> {
        // An RGL `.bsdf` file: its BRDF tabulated as a MERL table, or as a
        // UTIA table if it is anisotropic.
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        if hint.is_none() && ext.eq_ignore_ascii_case("bsdf") {
            let brdf = crate::rgl_brdf::RglBrdf::read(path)?;
            return Ok(if brdf.is_isotropic() {
                Table::Merl(brdf.to_merl()?)
            } else {
                Table::Utia(brdf.to_utia())
            });
        }
        let format = match hint {
            Some(f) => f,
            None => {
                // Says what a directory, FIFO or device is, without opening
                // it for a blocking read.
                let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
                let expected = if ext.eq_ignore_ascii_case("binary") {
                    "a MERL table"
                } else if ext.eq_ignore_ascii_case("bin") {
                    "a UTIA table"
                } else {
                    "a measured table"
                };
                let (_, size) = crate::sniff::open_regular(path, expected)?;
                Format::detect(path, size)?
            }
        };
        Ok(match format {
            Format::Merl => Table::Merl(MerlTable::read(path)?),
            Format::Utia => Table::Utia(UtiaTable::read(path)?),
        })
    }

    /// Which format the table is.
    pub fn format(&self) -> Format {
        match self {
            Table::Merl(_) => Format::Merl,
            Table::Utia(_) => Format::Utia,
        }
    }

    /// The table's valid cells as samples (see each format's `samples`).
    pub fn samples(&self, source: &str) -> MeasuredSamples {
        match self {
            Table::Merl(t) => t.samples(source),
            Table::Utia(t) => t.samples(source),
        }
    }

    /// `f` of each consecutive piece of `chunk` samples of [`Table::samples`]
    /// (the last may be shorter), in piece order, computed in parallel. The
    /// samples are made piece by piece, never all held
    /// ([`MerlTable::map_sample_chunks`], [`UtiaTable::map_sample_chunks`]).
    ///
    /// # Panics
    /// If `chunk` is 0.
    pub fn map_sample_chunks<R: Send>(
        &self,
        chunk: usize,
        f: impl Fn(&[crate::MeasuredSample]) -> R + Sync,
    ) -> Vec<R> {
        match self {
            Table::Merl(t) => t.map_sample_chunks(chunk, f),
            Table::Utia(t) => t.map_sample_chunks(chunk, f),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extension_and_size_decide_and_conflicts_are_named() {
        let m = MerlTable::FILE_BYTES;
        let u = UtiaTable::FILE_BYTES;
        let p = |s: &str| Path::new(s).to_path_buf();
        assert_eq!(Format::detect(&p("a.binary"), m).unwrap(), Format::Merl);
        assert_eq!(Format::detect(&p("a.bin"), u).unwrap(), Format::Utia);
        assert_eq!(Format::detect(&p("a.dat"), u).unwrap(), Format::Utia);
        assert_eq!(Format::detect(&p("a"), m).unwrap(), Format::Merl);
        // A truncated file keeps its extension's format (the reader names the size).
        assert_eq!(Format::detect(&p("a.bin"), 10).unwrap(), Format::Utia);
        let e = Format::detect(&p("x.bin"), m).unwrap_err().to_string();
        assert!(
            e.contains("x.bin") && e.contains("ambiguous") && e.contains("--format"),
            "{e}"
        );
        let e = Format::detect(&p("x.txt"), 17).unwrap_err().to_string();
        assert!(
            e.contains("x.txt") && e.contains("17 bytes") && e.contains("UTIA"),
            "{e}"
        );
    }
}
