//! RGL "tensor files" (`.bsdf`): the container of the RGL measured-BRDF
//! database, read by Mitsuba 3's `measured` plugin, pbrt-v4's
//! `MeasuredBxDF` and rgl-epfl/brdf-loader (see `../shared/docs/RGL_FORMAT.md`
//! section 1). A reader and a writer that mirror each other, as in libbsdf:
//! [`TensorFile::from_bytes`] accepts exactly what [`TensorFile::to_bytes`]
//! can produce, plus the other numeric dtypes (kept as raw bytes).
//!
//! Layout (little-endian): `"tensor_file\0"`, version u8 major = 1, u8
//! minor = 0, u32 field count, then per field `u16 name_len`, name, `u16
//! ndim`, `u8 dtype`, `u64 offset`, `ndim` x `u64` extents; each array's
//! data in C order at its absolute offset (the writer pads starts to 8
//! bytes).
//!
//! The reader never trusts a count or an offset: every field's extent
//! product is checked against the file's length (with overflow checks)
//! before anything is allocated, so a hostile file is an error, never a
//! panic or a runaway allocation.

use std::path::Path;

use byteorder::{ByteOrder, LittleEndian};

use crate::atomic::write_bytes_atomic;
use crate::error::LoadError;

const MAGIC: &[u8; 12] = b"tensor_file\0";
/// Largest tensor file the reader opens (the database's files are a few MB).
pub const MAX_FILE_BYTES: u64 = 1 << 32;
/// Largest rank of a field.
pub const MAX_RANK: usize = 16;

/// A field's element type, with its tensor-file dtype code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    /// 1: uint8.
    U8,
    /// 2: int8.
    I8,
    /// 3: uint16.
    U16,
    /// 4: int16.
    I16,
    /// 5: uint32.
    U32,
    /// 6: int32.
    I32,
    /// 7: uint64.
    U64,
    /// 8: int64.
    I64,
    /// 9: float16.
    F16,
    /// 10: float32.
    F32,
    /// 11: float64.
    F64,
}

impl Dtype {
    /// The dtype code in the file.
    pub fn code(self) -> u8 {
        self as u8 + 1
    }

    /// The dtype of a code; `None` for 0 and codes above 11 (rejected by
    /// every reader).
    pub fn from_code(code: u8) -> Option<Self> {
        use Dtype::*;
        [U8, I8, U16, I16, U32, I32, U64, I64, F16, F32, F64]
            .get((code as usize).wrapping_sub(1))
            .copied()
    }

    /// Bytes per element.
    pub fn size(self) -> usize {
        use Dtype::*;
        match self {
            U8 | I8 => 1,
            U16 | I16 | F16 => 2,
            U32 | I32 | F32 => 4,
            U64 | I64 | F64 => 8,
        }
    }
}

/// A field's values. The renderers read only float32 and uint8 fields;
/// other dtypes are kept as their little-endian bytes.
#[derive(Clone, Debug, PartialEq)]
pub enum Data {
    /// float32 values.
    F32(Vec<f32>),
    /// uint8 values (`description`, `jacobian`).
    U8(Vec<u8>),
    /// Any other dtype, as the file's bytes.
    Raw(Dtype, Vec<u8>),
}

impl Data {
    /// The element type.
    pub fn dtype(&self) -> Dtype {
        match self {
            Data::F32(_) => Dtype::F32,
            Data::U8(_) => Dtype::U8,
            Data::Raw(d, _) => *d,
        }
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        match self {
            Data::F32(v) => v.len(),
            Data::U8(v) => v.len(),
            Data::Raw(d, b) => b.len() / d.size(),
        }
    }

    /// True when there are no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One named array.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// Name (case-sensitive).
    pub name: String,
    /// Extents, outermost first.
    pub shape: Vec<usize>,
    /// Values in C order; `data.len()` is the product of `shape`.
    pub data: Data,
}

impl Field {
    /// A float32 field.
    pub fn f32(name: &str, shape: &[usize], data: Vec<f32>) -> Self {
        Field {
            name: name.to_string(),
            shape: shape.to_vec(),
            data: Data::F32(data),
        }
    }

    /// A uint8 field.
    pub fn u8(name: &str, shape: &[usize], data: Vec<u8>) -> Self {
        Field {
            name: name.to_string(),
            shape: shape.to_vec(),
            data: Data::U8(data),
        }
    }

    /// The float32 values, if that is the field's dtype.
    pub fn as_f32(&self) -> Option<&[f32]> {
        match &self.data {
            Data::F32(v) => Some(v),
            _ => None,
        }
    }

    /// The uint8 values, if that is the field's dtype.
    pub fn as_u8(&self) -> Option<&[u8]> {
        match &self.data {
            Data::U8(v) => Some(v),
            _ => None,
        }
    }
}

/// A tensor file: its fields in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TensorFile {
    /// The fields, in the order they are written.
    pub fields: Vec<Field>,
}

fn element_count(shape: &[usize]) -> Option<usize> {
    shape.iter().try_fold(1usize, |a, &n| a.checked_mul(n))
}

impl TensorFile {
    /// The field called `name`.
    pub fn get(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// Checks what the writer relies on: unique names that fit in a u16,
    /// ranks up to [`MAX_RANK`], element counts matching the shapes.
    /// `path` only names the file in the message.
    pub fn validate(&self, path: &Path) -> Result<(), LoadError> {
        let bad = |p: String| Err(LoadError::invalid(path, p));
        for (k, f) in self.fields.iter().enumerate() {
            if f.name.len() > u16::MAX as usize {
                return bad(format!("field {k}: name longer than 65535 bytes"));
            }
            if self.fields[..k].iter().any(|g| g.name == f.name) {
                return bad(format!("field {:?} appears twice", f.name));
            }
            if f.shape.len() > MAX_RANK {
                return bad(format!(
                    "field {:?}: rank {} > {MAX_RANK}",
                    f.name,
                    f.shape.len()
                ));
            }
            if let Data::Raw(d, b) = &f.data {
                if b.len() % d.size() != 0 {
                    return bad(format!("field {:?}: raw bytes not whole elements", f.name));
                }
            }
            if element_count(&f.shape) != Some(f.data.len()) {
                return bad(format!(
                    "field {:?}: shape {:?} but {} values",
                    f.name,
                    f.shape,
                    f.data.len()
                ));
            }
        }
        Ok(())
    }

    /// The file's bytes. Call [`TensorFile::validate`] first (the writer
    /// [`TensorFile::write`] does); on an invalid file the bytes are
    /// unspecified but this never panics.
    pub fn to_bytes(&self) -> Vec<u8> {
        let header: usize = 12
            + 2
            + 4
            + self
                .fields
                .iter()
                .map(|f| 2 + f.name.len() + 2 + 1 + 8 + 8 * f.shape.len())
                .sum::<usize>();
        let pad = |x: usize| (x + 7) & !7;
        let mut offsets = Vec::with_capacity(self.fields.len());
        let mut end = pad(header);
        for f in &self.fields {
            offsets.push(end);
            end = pad(end + f.data.len() * f.data.dtype().size());
        }
        let mut out = Vec::with_capacity(end);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&[1, 0]);
        out.extend_from_slice(&(self.fields.len() as u32).to_le_bytes());
        for (f, &off) in self.fields.iter().zip(&offsets) {
            out.extend_from_slice(&(f.name.len() as u16).to_le_bytes());
            out.extend_from_slice(f.name.as_bytes());
            out.extend_from_slice(&(f.shape.len() as u16).to_le_bytes());
            out.push(f.data.dtype().code());
            out.extend_from_slice(&(off as u64).to_le_bytes());
            for &n in &f.shape {
                out.extend_from_slice(&(n as u64).to_le_bytes());
            }
        }
        for (f, &off) in self.fields.iter().zip(&offsets) {
            out.resize(off, 0);
            match &f.data {
                Data::F32(v) => {
                    let start = out.len();
                    out.resize(start + 4 * v.len(), 0);
                    LittleEndian::write_f32_into(v, &mut out[start..]);
                }
                Data::U8(v) => out.extend_from_slice(v),
                Data::Raw(_, b) => out.extend_from_slice(b),
            }
        }
        out.resize(end, 0);
        out
    }

    /// Decodes a tensor file; `path` is only used in messages. Errors
    /// ([`LoadError::Invalid`]) for a wrong magic or version, a truncated
    /// header, an unknown dtype, a rank above [`MAX_RANK`], a duplicated
    /// name, a name that is not UTF-8, and any field whose data would reach
    /// past the end of the file.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, LoadError> {
        let bad = |p: String| LoadError::invalid(path, p);
        if bytes.len() < 18 || &bytes[..12] != MAGIC {
            return Err(bad("not a tensor file (no \"tensor_file\" magic)".into()));
        }
        if bytes[12] != 1 || bytes[13] != 0 {
            return Err(bad(format!(
                "tensor file version {}.{}, only 1.0 is supported",
                bytes[12], bytes[13]
            )));
        }
        let count = LittleEndian::read_u32(&bytes[14..18]) as usize;
        let mut pos = 18usize;
        let mut take = |n: usize, what: &str| -> Result<&[u8], LoadError> {
            let end = pos
                .checked_add(n)
                .filter(|&e| e <= bytes.len())
                .ok_or_else(|| bad(format!("truncated field table ({what})")))?;
            let s = &bytes[pos..end];
            pos = end;
            Ok(s)
        };
        // Each record takes at least 15 bytes: no count larger than the
        // file allows gets a vector.
        let mut fields = Vec::with_capacity(count.min(bytes.len() / 15));
        for k in 0..count {
            let name_len = LittleEndian::read_u16(take(2, "name length")?) as usize;
            let name = std::str::from_utf8(take(name_len, "name")?)
                .map_err(|_| bad(format!("field {k}: name is not UTF-8")))?
                .to_string();
            let ndim = LittleEndian::read_u16(take(2, "rank")?) as usize;
            let code = take(1, "dtype")?[0];
            let dtype = Dtype::from_code(code)
                .ok_or_else(|| bad(format!("field {name:?}: unknown dtype code {code}")))?;
            let offset = LittleEndian::read_u64(take(8, "offset")?);
            if ndim > MAX_RANK {
                return Err(bad(format!("field {name:?}: rank {ndim} > {MAX_RANK}")));
            }
            let mut shape = Vec::with_capacity(ndim);
            for _ in 0..ndim {
                let n = LittleEndian::read_u64(take(8, "extents")?);
                shape.push(usize::try_from(n).unwrap_or(usize::MAX));
            }
            let n_bytes = element_count(&shape).and_then(|n| n.checked_mul(dtype.size()));
            let range = n_bytes.and_then(|nb| {
                let start = usize::try_from(offset).ok()?;
                let end = start.checked_add(nb)?;
                (end <= bytes.len()).then_some(start..end)
            });
            let range = range.ok_or_else(|| {
                bad(format!(
                    "field {name:?}: data (shape {shape:?}, offset {offset}) reaches past the end \
                     of the file ({} bytes)",
                    bytes.len()
                ))
            })?;
            if fields.iter().any(|f: &Field| f.name == name) {
                return Err(bad(format!("field {name:?} appears twice")));
            }
            let raw = &bytes[range];
            let data = match dtype {
                Dtype::F32 => {
                    let mut v = vec![0f32; raw.len() / 4];
                    LittleEndian::read_f32_into(raw, &mut v);
                    Data::F32(v)
                }
                Dtype::U8 => Data::U8(raw.to_vec()),
                d => Data::Raw(d, raw.to_vec()),
            };
            fields.push(Field { name, shape, data });
        }
        Ok(TensorFile { fields })
    }

    /// Reads a tensor file. Only regular files up to [`MAX_FILE_BYTES`] are
    /// opened (not a FIFO or a device, which could block or never end).
    pub fn read(path: &Path) -> Result<Self, LoadError> {
        let meta = std::fs::metadata(path).map_err(|e| LoadError::io(path, e))?;
        if !meta.is_file() {
            return Err(LoadError::invalid(path, "not a regular file"));
        }
        if meta.len() > MAX_FILE_BYTES {
            return Err(LoadError::invalid(
                path,
                format!(
                    "{} bytes, more than the {MAX_FILE_BYTES} a tensor file may have",
                    meta.len()
                ),
            ));
        }
        let bytes = std::fs::read(path).map_err(|e| LoadError::io(path, e))?;
        Self::from_bytes(&bytes, path)
    }

    /// Validates and writes the file atomically
    /// ([`crate::atomic::write_bytes_atomic`]); returns its size in bytes.
    pub fn write(&self, path: &Path, overwrite: bool) -> Result<u64, LoadError> {
        self.validate(path)?;
        let bytes = self.to_bytes();
        write_bytes_atomic(path, overwrite, &bytes)?;
        Ok(bytes.len() as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> TensorFile {
        TensorFile {
            fields: vec![
                Field::u8("description", &[5], b"hello".to_vec()),
                Field::f32("theta_i", &[3], vec![0.0, 0.5, 1.0]),
                Field::f32(
                    "rgb",
                    &[1, 3, 3, 2, 2],
                    (0..36).map(|k| k as f32 * 0.25).collect(),
                ),
                Field::u8("jacobian", &[1], vec![1]),
                Field {
                    name: "raw".into(),
                    shape: vec![2],
                    data: Data::Raw(Dtype::U16, vec![1, 0, 2, 0]),
                },
            ],
        }
    }

    #[test]
    fn round_trip_is_exact_and_aligned() {
        let t = sample();
        let p = Path::new("t.bsdf");
        t.validate(p).unwrap();
        let bytes = t.to_bytes();
        assert_eq!(&bytes[..12], MAGIC);
        assert_eq!(bytes.len() % 8, 0);
        let back = TensorFile::from_bytes(&bytes, p).unwrap();
        assert_eq!(back, t);
        assert_eq!(back.to_bytes(), bytes);
        // Offsets are 8-aligned: read the first record's offset.
        let off = LittleEndian::read_u64(&bytes[18 + 2 + 11 + 2 + 1..]);
        assert_eq!(off % 8, 0);
    }

    #[test]
    fn every_truncation_is_an_error_naming_the_file() {
        let bytes = sample().to_bytes();
        let p = Path::new("dir/t.bsdf");
        // Trailing padding may go; everything up to the last field's data
        // must stay.
        let needed = bytes.len() - 4;
        for n in 0..needed {
            let e = TensorFile::from_bytes(&bytes[..n], p).unwrap_err();
            assert!(e.to_string().starts_with("dir/t.bsdf: "), "{e}");
        }
    }

    #[test]
    fn hostile_headers_are_errors() {
        let p = Path::new("x.bsdf");
        let mut b = sample().to_bytes();
        b[12] = 2;
        assert!(TensorFile::from_bytes(&b, p)
            .unwrap_err()
            .to_string()
            .contains("version"));
        // A huge field count with no records.
        let mut h = MAGIC.to_vec();
        h.extend_from_slice(&[1, 0]);
        h.extend_from_slice(&u32::MAX.to_le_bytes());
        assert!(TensorFile::from_bytes(&h, p).is_err());
        // Extents whose product overflows.
        let t = TensorFile {
            fields: vec![Field::f32("a", &[1], vec![1.0])],
        };
        let mut b = t.to_bytes();
        let ext = 18 + 2 + 1 + 2 + 1 + 8;
        b[ext..ext + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        let e = TensorFile::from_bytes(&b, p).unwrap_err().to_string();
        assert!(e.contains("past the end"), "{e}");
        // Unknown dtype.
        let mut b = t.to_bytes();
        b[18 + 2 + 1 + 2] = 12;
        assert!(TensorFile::from_bytes(&b, p)
            .unwrap_err()
            .to_string()
            .contains("dtype"));
        // A shape that does not match its data is refused by the writer.
        let bad = TensorFile {
            fields: vec![Field::f32("a", &[2], vec![1.0])],
        };
        assert!(bad.validate(p).is_err());
    }

    #[test]
    fn write_is_atomic_and_refuses_to_overwrite() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.bsdf");
        let n = sample().write(&p, false).unwrap();
        assert_eq!(std::fs::metadata(&p).unwrap().len(), n);
        assert!(matches!(
            sample().write(&p, false),
            Err(LoadError::Exists { .. })
        ));
        assert_eq!(TensorFile::read(&p).unwrap(), sample());
        assert!(TensorFile::read(dir.path()).is_err());
    }
}
