//! PLY reader: `ascii`, `binary_little_endian` and `binary_big_endian` formats. Reads the
//! `x`, `y`, `z` properties of the `vertex` element and the index list (`vertex_indices` or
//! `vertex_index`) of the `face` element; other elements and properties are skipped. Header
//! counts are never trusted for allocation: reservations are capped by the bytes left.

use std::path::Path;

use super::{parse_finite, push_fan, require_vertices, show, tokens};
use crate::error::{MeshError, Result};
use crate::types::Surface3;

/// Longest header accepted, in bytes (a header is a few hundred bytes in practice).
const MAX_HEADER_BYTES: usize = 1 << 16;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &[u8]) -> Option<Self> {
        Some(match name {
            b"char" | b"int8" => Self::I8,
            b"uchar" | b"uint8" => Self::U8,
            b"short" | b"int16" => Self::I16,
            b"ushort" | b"uint16" => Self::U16,
            b"int" | b"int32" => Self::I32,
            b"uint" | b"uint32" => Self::U32,
            b"float" | b"float32" => Self::F32,
            b"double" | b"float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }
}

#[derive(Debug, Clone)]
enum Property {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<(String, Property)>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

/// Parses PLY `bytes` (`path` is only used in error messages).
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<Surface3> {
    let (format, elements, body_start, header_lines) = parse_header(bytes, path)?;
    let body = &bytes[body_start..];
    let mut reader: Box<dyn ValueReader> = match format {
        Format::Ascii => Box::new(AsciiReader::new(body, header_lines)),
        Format::Little | Format::Big => Box::new(BinaryReader {
            bytes: body,
            pos: 0,
            big: format == Format::Big,
        }),
    };

    let mut surface = Surface3::default();
    let mut polygon: Vec<usize> = Vec::new();
    let mut raw: Vec<f64> = Vec::new();
    for element in &elements {
        let is_vertex = element.name == "vertex";
        let is_face = element.name == "face";
        let xyz = if is_vertex {
            let find = |n: &str| {
                element
                    .properties
                    .iter()
                    .position(|(name, p)| name == n && matches!(p, Property::Scalar(_)))
            };
            match (find("x"), find("y"), find("z")) {
                (Some(x), Some(y), Some(z)) => Some([x, y, z]),
                _ => {
                    return Err(MeshError::parse(
                        path,
                        "header",
                        "element vertex lacks scalar properties x, y and z",
                    ));
                }
            }
        } else {
            None
        };
        let face_list = if is_face {
            element
                .properties
                .iter()
                .position(|(n, p)| {
                    matches!(p, Property::List { .. })
                        && (n == "vertex_indices" || n == "vertex_index")
                })
                .or_else(|| {
                    element
                        .properties
                        .iter()
                        .position(|(_, p)| matches!(p, Property::List { .. }))
                })
        } else {
            None
        };
        let min_size = element
            .properties
            .iter()
            .map(|(_, p)| match p {
                Property::Scalar(s) => s.size(),
                Property::List { count, .. } => count.size(),
            })
            .sum::<usize>()
            .max(1);
        let cap = element.count.min(reader.remaining() / min_size);
        if is_vertex {
            surface.vertices.reserve(cap);
        }
        if is_face {
            surface.triangles.reserve(cap);
        }
        // An element without properties has nothing to read (and a huge count must not spin).
        let items = if element.properties.is_empty() {
            0
        } else {
            element.count
        };
        for item in 0..items {
            reader
                .begin_item()
                .map_err(|m| reader.error(path, &element.name, item, m))?;
            let mut point = [0.0; 3];
            for (pi, (pname, prop)) in element.properties.iter().enumerate() {
                match prop {
                    Property::Scalar(s) => {
                        let v = reader.read(*s).map_err(|m| {
                            reader.error(
                                path,
                                &element.name,
                                item,
                                format!("property {pname}: {m}"),
                            )
                        })?;
                        if let Some(xyz) = xyz
                            && let Some(k) = xyz.iter().position(|&i| i == pi)
                        {
                            if !v.is_finite() {
                                return Err(reader.error(
                                    path,
                                    &element.name,
                                    item,
                                    format!("coordinate {pname} is not finite ({v})"),
                                ));
                            }
                            point[k] = v;
                        }
                    }
                    Property::List { count, item: ty } => {
                        let n = reader.read(*count).map_err(|m| {
                            reader.error(path, &element.name, item, format!("list {pname}: {m}"))
                        })?;
                        if !(n >= 0.0 && n.fract() == 0.0) {
                            return Err(reader.error(
                                path,
                                &element.name,
                                item,
                                format!("list {pname} has invalid length {n}"),
                            ));
                        }
                        let n = n as usize;
                        if !reader.can_hold(n, *ty) {
                            return Err(reader.error(
                                path,
                                &element.name,
                                item,
                                format!(
                                    "list {pname} claims {n} entries, more than the file holds"
                                ),
                            ));
                        }
                        raw.clear();
                        for _ in 0..n {
                            raw.push(reader.read(*ty).map_err(|m| {
                                reader.error(
                                    path,
                                    &element.name,
                                    item,
                                    format!("list {pname}: {m}"),
                                )
                            })?);
                        }
                        if face_list == Some(pi) {
                            if n < 3 {
                                return Err(reader.error(
                                    path,
                                    &element.name,
                                    item,
                                    format!("face has {n} vertices, at least 3 are needed"),
                                ));
                            }
                            polygon.clear();
                            for &v in &raw {
                                if !(v >= 0.0 && v.fract() == 0.0 && v < u32::MAX as f64) {
                                    return Err(reader.error(
                                        path,
                                        &element.name,
                                        item,
                                        format!("vertex index {v} is invalid"),
                                    ));
                                }
                                polygon.push(v as usize);
                            }
                            push_fan(&polygon, &mut surface.triangles);
                        }
                    }
                }
            }
            reader
                .end_item()
                .map_err(|m| reader.error(path, &element.name, item, m))?;
            if xyz.is_some() {
                surface.vertices.push(point);
            }
        }
    }
    let n = surface.vertices.len();
    for (t, tri) in surface.triangles.iter().enumerate() {
        if let Some(&bad) = tri.iter().find(|&&i| i >= n) {
            return Err(MeshError::parse(
                path,
                format!("face triangle {t}"),
                format!("vertex index {bad} is out of range ({n} vertices)"),
            ));
        }
    }
    require_vertices(&surface, path)?;
    Ok(surface)
}

type Header = (Format, Vec<Element>, usize, usize);

fn parse_header(bytes: &[u8], path: &Path) -> Result<Header> {
    let mut pos = 0;
    let mut line_no = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if pos >= bytes.len() || pos > MAX_HEADER_BYTES {
            return Err(MeshError::parse(path, "header", "no `end_header` line"));
        }
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |e| pos + e);
        let line = &bytes[pos..end];
        pos = (end + 1).min(bytes.len());
        line_no += 1;
        let err = |m: String| MeshError::parse(path, format!("line {line_no}"), m);
        let toks: Vec<&[u8]> = tokens(line).collect();
        if line_no == 1 {
            if toks.first() != Some(&&b"ply"[..]) {
                return Err(err("not a PLY file (first line is not `ply`)".into()));
            }
            continue;
        }
        match toks.first().copied() {
            Some(b"format") => {
                format = Some(match toks.get(1).copied() {
                    Some(b"ascii") => Format::Ascii,
                    Some(b"binary_little_endian") => Format::Little,
                    Some(b"binary_big_endian") => Format::Big,
                    other => {
                        return Err(err(format!(
                            "unknown format {:?}",
                            other.map(show).unwrap_or_default()
                        )));
                    }
                });
            }
            Some(b"element") => {
                let (Some(name), Some(count)) = (toks.get(1), toks.get(2)) else {
                    return Err(err("`element` needs a name and a count".into()));
                };
                let count: usize = std::str::from_utf8(count)
                    .ok()
                    .and_then(|c| c.parse().ok())
                    .ok_or_else(|| {
                        err(format!("element count {:?} is not a number", show(count)))
                    })?;
                elements.push(Element {
                    name: String::from_utf8_lossy(name).into_owned(),
                    count,
                    properties: Vec::new(),
                });
            }
            Some(b"property") => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| err("`property` before any `element`".into()))?;
                let scalar = |t: Option<&&[u8]>| {
                    t.and_then(|t| Scalar::parse(t)).ok_or_else(|| {
                        err(format!(
                            "unknown property type {:?}",
                            t.map(|t| show(t)).unwrap_or_default()
                        ))
                    })
                };
                let (prop, name) = if toks.get(1) == Some(&&b"list"[..]) {
                    let count = scalar(toks.get(2))?;
                    let item = scalar(toks.get(3))?;
                    if matches!(count, Scalar::F32 | Scalar::F64) {
                        return Err(err("list count type must be an integer type".into()));
                    }
                    (Property::List { count, item }, toks.get(4))
                } else {
                    (Property::Scalar(scalar(toks.get(1))?), toks.get(2))
                };
                let name = name.ok_or_else(|| err("property has no name".into()))?;
                element
                    .properties
                    .push((String::from_utf8_lossy(name).into_owned(), prop));
            }
            Some(b"end_header") => break,
            Some(b"comment") | Some(b"obj_info") | None => {}
            Some(other) => return Err(err(format!("unknown header keyword {:?}", show(other)))),
        }
    }
    let format = format.ok_or_else(|| MeshError::parse(path, "header", "no `format` line"))?;
    Ok((format, elements, pos, line_no))
}

/// Reads the values of one element item after another.
trait ValueReader {
    fn begin_item(&mut self) -> std::result::Result<(), String>;
    fn read(&mut self, ty: Scalar) -> std::result::Result<f64, String>;
    fn end_item(&mut self) -> std::result::Result<(), String>;
    fn remaining(&self) -> usize;
    /// Whether `n` further values of type `ty` can still be in the file.
    fn can_hold(&self, n: usize, ty: Scalar) -> bool;
    fn error(&self, path: &Path, element: &str, item: usize, message: String) -> MeshError;
}

struct BinaryReader<'a> {
    bytes: &'a [u8],
    pos: usize,
    big: bool,
}

impl ValueReader for BinaryReader<'_> {
    fn begin_item(&mut self) -> std::result::Result<(), String> {
        Ok(())
    }

    fn read(&mut self, ty: Scalar) -> std::result::Result<f64, String> {
        let n = ty.size();
        let Some(chunk) = self.bytes.get(self.pos..self.pos + n) else {
            return Err("file is truncated".into());
        };
        self.pos += n;
        let mut buf = [0u8; 8];
        buf[..n].copy_from_slice(chunk);
        if self.big {
            buf[..n].reverse();
        }
        Ok(match ty {
            Scalar::I8 => f64::from(buf[0] as i8),
            Scalar::U8 => f64::from(buf[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes([buf[0], buf[1]])),
            Scalar::U16 => f64::from(u16::from_le_bytes([buf[0], buf[1]])),
            Scalar::I32 => f64::from(i32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]])),
            Scalar::U32 => f64::from(u32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]])),
            Scalar::F32 => f64::from(f32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]])),
            Scalar::F64 => f64::from_le_bytes(buf),
        })
    }

    fn end_item(&mut self) -> std::result::Result<(), String> {
        Ok(())
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn can_hold(&self, n: usize, ty: Scalar) -> bool {
        n.saturating_mul(ty.size()) <= self.remaining()
    }

    fn error(&self, path: &Path, element: &str, item: usize, message: String) -> MeshError {
        MeshError::parse(path, format!("{element} {item}"), message)
    }
}

/// Numbered lines of the body of an ASCII file.
type Lines<'a> = std::iter::Enumerate<std::slice::Split<'a, u8, fn(&u8) -> bool>>;

struct AsciiReader<'a> {
    lines: Lines<'a>,
    tokens: Vec<&'a [u8]>,
    next: usize,
    line_no: usize,
    first_line: usize,
    remaining: usize,
}

impl<'a> AsciiReader<'a> {
    fn new(body: &'a [u8], header_lines: usize) -> Self {
        let newline: fn(&u8) -> bool = |&b| b == b'\n';
        Self {
            lines: body.split(newline).enumerate(),
            tokens: Vec::new(),
            next: 0,
            line_no: header_lines,
            first_line: header_lines,
            remaining: body.len(),
        }
    }
}

impl ValueReader for AsciiReader<'_> {
    fn begin_item(&mut self) -> std::result::Result<(), String> {
        // One item per non-empty line.
        for (i, line) in self.lines.by_ref() {
            self.remaining = self.remaining.saturating_sub(line.len() + 1);
            self.tokens.clear();
            self.tokens.extend(tokens(line));
            if !self.tokens.is_empty() {
                self.line_no = self.first_line + i + 1;
                self.next = 0;
                return Ok(());
            }
        }
        Err("file is truncated (fewer lines than the header declares)".into())
    }

    fn read(&mut self, ty: Scalar) -> std::result::Result<f64, String> {
        let tok = self
            .tokens
            .get(self.next)
            .ok_or_else(|| "line has too few values".to_string())?;
        self.next += 1;
        let v = if matches!(ty, Scalar::F32 | Scalar::F64) {
            // Non-finite values are reported by the caller, which knows the property.
            let text = std::str::from_utf8(tok).map_err(|_| "value is not text".to_string())?;
            text.parse::<f64>()
                .map_err(|_| format!("value {:?} is not a number", show(tok)))?
        } else {
            parse_finite(tok, "integer value")?
        };
        if !matches!(ty, Scalar::F32 | Scalar::F64) && v.fract() != 0.0 {
            return Err(format!("value {:?} is not an integer", show(tok)));
        }
        Ok(v)
    }

    fn end_item(&mut self) -> std::result::Result<(), String> {
        if self.next == self.tokens.len() {
            Ok(())
        } else {
            Err(format!(
                "line has {} values, the header declares {}",
                self.tokens.len(),
                self.next
            ))
        }
    }

    fn remaining(&self) -> usize {
        // Each further value needs at least two bytes ("0 ").
        self.remaining / 2 + (self.tokens.len() - self.next.min(self.tokens.len()))
    }

    fn can_hold(&self, n: usize, _ty: Scalar) -> bool {
        // A list lives on its item's line.
        n <= self.tokens.len() - self.next.min(self.tokens.len())
    }

    fn error(&self, path: &Path, element: &str, item: usize, message: String) -> MeshError {
        MeshError::parse(
            path,
            format!("line {} ({element} {item})", self.line_no),
            message,
        )
    }
}
