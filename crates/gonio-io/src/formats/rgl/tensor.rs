//! The tensor file that holds an RGL material: named, typed, n-dimensional arrays.
//!
//! Layout (Mitsuba 3's `TensorFile`, `src/core/tensor.cpp`, and its writer
//! `tensor_io.py`; all numbers little-endian):
//!
//! | bytes | what |
//! |---|---|
//! | 12 | `tensor_file\0` |
//! | 2 | version: major 1, minor 0 |
//! | 4 | `u32` number of fields |
//! | per field | `u16` name length, the name (UTF-8), `u16` number of dimensions, `u8` type, `u64` offset of the data from the file's start, a `u64` per dimension (the shape, slowest first) |
//! | … | each field's data at its offset, row-major, 8-byte aligned |
//!
//! Types (Mitsuba's `Struct::Type`): 1 `u8`, 2 `i8`, 3 `u16`, 4 `i16`, 5 `u32`,
//! 6 `i32`, 7 `u64`, 8 `i64`, 9 `f16`, 10 `f32`, 11 `f64`. An RGL material uses `u8`
//! (`description`, `jacobian`, `valid`) and `f32` (everything else).

use std::path::Path;

use super::super::{Format, FormatError};

/// The file's first 12 bytes.
pub const MAGIC: &[u8; 12] = b"tensor_file\0";

/// The most fields, dimensions and name bytes a file may declare: far beyond any RGL
/// material (about ten fields of at most five dimensions), and a bound on what a
/// corrupt header can make the reader allocate.
const MAX_FIELDS: u32 = 256;
const MAX_DIMS: u16 = 8;

/// The element type of a field (the types an RGL material uses).
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    /// `u8` (type 1).
    U8(Vec<u8>),
    /// `f32` (type 10).
    F32(Vec<f32>),
    /// Any other type (its code): skipped when read, as the plugin never reads it.
    Other(u8),
}

impl Values {
    fn code(&self) -> u8 {
        match self {
            Values::U8(_) => 1,
            Values::F32(_) => 10,
            Values::Other(c) => *c,
        }
    }

    fn len(&self) -> usize {
        match self {
            Values::U8(v) => v.len(),
            Values::F32(v) => v.len(),
            Values::Other(_) => 0,
        }
    }

    /// The type's name in messages.
    pub fn type_name(&self) -> &'static str {
        match self {
            Values::U8(_) => "u8",
            Values::F32(_) => "f32",
            Values::Other(_) => "another type",
        }
    }
}

/// One named array.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// The name (`theta_i`, `vndf`, …).
    pub name: String,
    /// The shape, slowest dimension first.
    pub shape: Vec<usize>,
    /// The values, row-major.
    pub values: Values,
}

impl Field {
    /// A field of `f32`s; `values.len()` must be the shape's product.
    pub fn f32(name: &str, shape: Vec<usize>, values: Vec<f32>) -> Field {
        debug_assert_eq!(shape.iter().product::<usize>(), values.len());
        Field {
            name: name.into(),
            shape,
            values: Values::F32(values),
        }
    }

    /// A one-dimensional field of bytes.
    pub fn bytes(name: &str, values: Vec<u8>) -> Field {
        Field {
            name: name.into(),
            shape: vec![values.len()],
            values: Values::U8(values),
        }
    }
}

/// Size in bytes of an element of Mitsuba's type `code`, or `None` for no type.
fn type_size(code: u8) -> Option<usize> {
    Some(match code {
        1 | 2 => 1,
        3 | 4 | 9 => 2,
        5 | 6 | 10 => 4,
        7 | 8 | 11 => 8,
        _ => return None,
    })
}

/// Writes `fields` as a tensor file, in order, each field's data 8-byte aligned
/// ([`Values::Other`] fields, whose data was not read, are left out).
pub fn write(fields: &[Field]) -> Vec<u8> {
    let fields: Vec<&Field> = fields
        .iter()
        .filter(|f| !matches!(f.values, Values::Other(_)))
        .collect();
    let mut header = Vec::new();
    header.extend_from_slice(MAGIC);
    header.extend_from_slice(&[1, 0]);
    header.extend_from_slice(&(fields.len() as u32).to_le_bytes());
    let header_len = header.len()
        + fields
            .iter()
            .map(|f| 2 + f.name.len() + 2 + 1 + 8 + 8 * f.shape.len())
            .sum::<usize>();
    let align = |x: usize| x.div_ceil(8) * 8;
    let mut offset = align(header_len);
    let mut offsets = Vec::with_capacity(fields.len());
    for f in &fields {
        offsets.push(offset);
        let size = f.values.len() * type_size(f.values.code()).unwrap_or(1);
        offset = align(offset + size);
    }
    for (f, off) in fields.iter().zip(&offsets) {
        header.extend_from_slice(&(f.name.len() as u16).to_le_bytes());
        header.extend_from_slice(f.name.as_bytes());
        header.extend_from_slice(&(f.shape.len() as u16).to_le_bytes());
        header.push(f.values.code());
        header.extend_from_slice(&(*off as u64).to_le_bytes());
        for d in &f.shape {
            header.extend_from_slice(&(*d as u64).to_le_bytes());
        }
    }
    let mut out = header;
    for (f, off) in fields.iter().zip(&offsets) {
        out.resize(*off, 0);
        match &f.values {
            Values::U8(v) => out.extend_from_slice(v),
            Values::F32(v) => v
                .iter()
                .for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
            Values::Other(_) => {}
        }
    }
    out
}

/// A cursor over the header that names the byte where it ran out.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    path: Option<&'a Path>,
}

impl Cursor<'_> {
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8], FormatError> {
        let end = self.at.checked_add(n).filter(|e| *e <= self.bytes.len());
        let Some(end) = end else {
            return Err(self.error(format!("truncated: the header's {what} runs past the end")));
        };
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u16(&mut self, what: &str) -> Result<u16, FormatError> {
        let b = self.take(2, what)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u64(&mut self, what: &str) -> Result<u64, FormatError> {
        let b = self.take(8, what)?;
        Ok(u64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
    }

    fn error(&self, message: String) -> FormatError {
        FormatError::at_byte(Format::Rgl, self.path, self.at as u64, message)
    }
}

/// True when `bytes` start like a tensor file.
pub fn is_tensor_file(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// Reads a tensor file. Every declared size is checked against the file's length
/// before anything is allocated for it; fields of other types than `u8` and `f32`
/// are kept as [`Values::Other`] without their data (the plugin reads none).
pub fn read(bytes: &[u8], path: Option<&Path>) -> Result<Vec<Field>, FormatError> {
    let mut c = Cursor { bytes, at: 0, path };
    if c.take(12, "magic")? != MAGIC {
        return Err(FormatError::at_byte(
            Format::Rgl,
            path,
            0,
            "not a tensor file: it does not start with `tensor_file\\0`",
        ));
    }
    let version = c.take(2, "version")?;
    if version != [1, 0] {
        let v = (version[0], version[1]);
        return Err(FormatError::at_byte(
            Format::Rgl,
            path,
            12,
            format!("tensor file version {}.{}: only 1.0 is read", v.0, v.1),
        ));
    }
    let n = u32::from_le_bytes(c.take(4, "field count")?.try_into().unwrap_or([0; 4]));
    if n > MAX_FIELDS {
        return Err(FormatError::at_byte(
            Format::Rgl,
            path,
            14,
            format!("{n} fields: more than the {MAX_FIELDS} a tensor file may have"),
        ));
    }
    let mut fields = Vec::with_capacity(n as usize);
    for _ in 0..n {
        let start = c.at as u64;
        let len = c.u16("name length")? as usize;
        let raw = c.take(len, "field name")?.to_vec();
        let name =
            String::from_utf8(raw).map_err(|_| c.error("a field name that is not UTF-8".into()))?;
        let ndim = c.u16("dimension count")?;
        if ndim == 0 || ndim > MAX_DIMS {
            return Err(c.error(format!(
                "field `{name}`: {ndim} dimensions (1 to {MAX_DIMS} are read)"
            )));
        }
        let code = c.take(1, "type")?[0];
        let offset = c.u64("data offset")?;
        let mut shape = Vec::with_capacity(ndim as usize);
        for _ in 0..ndim {
            shape.push(c.u64("shape")?);
        }
        let Some(size) = type_size(code) else {
            return Err(FormatError::at_byte(
                Format::Rgl,
                path,
                start,
                format!("field `{name}`: unknown type {code}"),
            ));
        };
        let count = shape.iter().try_fold(1u64, |a, d| a.checked_mul(*d));
        let end = count
            .and_then(|k| k.checked_mul(size as u64))
            .and_then(|b| b.checked_add(offset));
        let Some(count) = count.filter(|_| end.is_some_and(|e| e <= bytes.len() as u64)) else {
            return Err(FormatError::at_byte(
                Format::Rgl,
                path,
                start,
                format!(
                    "field `{name}`: shape {shape:?} at byte {offset} runs past the end of \
                     the file ({} bytes)",
                    bytes.len()
                ),
            ));
        };
        let data = &bytes[offset as usize..offset as usize + count as usize * size];
        let values = match code {
            1 => Values::U8(data.to_vec()),
            10 => Values::F32(
                data.chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect(),
            ),
            c => Values::Other(c),
        };
        fields.push(Field {
            name,
            shape: shape.into_iter().map(|d| d as usize).collect(),
            values,
        });
    }
    Ok(fields)
}
