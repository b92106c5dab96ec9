//! STL reader, ASCII and binary. Binary files are recognised by their exact size
//! (84 + 50 * count bytes); anything else starting with `solid` is read as ASCII. Identical
//! corner positions are merged so the result is an indexed surface.

use std::collections::HashMap;
use std::path::Path;

use super::{parse_finite, show, tokens};
use crate::error::{MeshError, Result};
use crate::types::Surface3;

/// Parses STL `bytes` (`path` is only used in error messages).
pub fn parse_stl(bytes: &[u8], path: &Path) -> Result<Surface3> {
    if bytes.len() >= 84 {
        let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        if 84 + 50 * count == bytes.len() as u64 {
            return parse_binary(bytes, count as usize, path);
        }
    }
    // An ASCII file may start with a UTF-8 byte-order mark.
    let text = crate::io::strip_bom(bytes);
    if text.trim_ascii_start().starts_with(b"solid") {
        return parse_ascii(text, path);
    }
    if bytes.len() >= 84 {
        let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        return Err(MeshError::parse(
            path,
            "header",
            format!(
                "binary STL declares {count} triangles ({} bytes) but the file has {} bytes",
                84 + 50 * count,
                bytes.len()
            ),
        ));
    }
    Err(MeshError::parse(
        path,
        "header",
        format!(
            "not an STL file ({} bytes, no `solid` keyword and too short for binary STL)",
            bytes.len()
        ),
    ))
}

/// Merges bit-identical corner positions into shared vertices.
#[derive(Default)]
struct Welder {
    map: HashMap<[u64; 3], usize>,
    surface: Surface3,
}

impl Welder {
    fn vertex(&mut self, p: [f64; 3]) -> usize {
        // `+ 0.0` folds -0.0 into 0.0 so both weld together.
        let key = p.map(|c| (c + 0.0).to_bits());
        *self.map.entry(key).or_insert_with(|| {
            self.surface.vertices.push(p);
            self.surface.vertices.len() - 1
        })
    }
}

fn parse_binary(bytes: &[u8], count: usize, path: &Path) -> Result<Surface3> {
    let mut welder = Welder::default();
    welder.surface.triangles.reserve(count);
    for t in 0..count {
        let rec = &bytes[84 + 50 * t..84 + 50 * (t + 1)];
        let mut corners = [0usize; 3];
        for (k, corner) in corners.iter_mut().enumerate() {
            let mut p = [0.0f64; 3];
            for (c, value) in p.iter_mut().enumerate() {
                let o = 12 + 12 * k + 4 * c;
                let v = f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]);
                if !v.is_finite() {
                    return Err(MeshError::parse(
                        path,
                        format!("triangle {t}"),
                        format!("corner {k} has a non-finite coordinate {v}"),
                    ));
                }
                *value = f64::from(v);
            }
            *corner = welder.vertex(p);
        }
        welder.surface.triangles.push(corners);
    }
    if count == 0 {
        return Err(MeshError::parse(
            path,
            "header",
            "binary STL with 0 triangles (empty model)",
        ));
    }
    Ok(welder.surface)
}

fn parse_ascii(bytes: &[u8], path: &Path) -> Result<Surface3> {
    let mut welder = Welder::default();
    let mut corners: Vec<usize> = Vec::with_capacity(3);
    let mut in_loop = false;
    for (index, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = index + 1;
        let err = |message: String| MeshError::parse(path, format!("line {line_no}"), message);
        let mut toks = tokens(line);
        let Some(keyword) = toks.next() else { continue };
        match keyword {
            b"outer" => {
                if in_loop {
                    return Err(err("`outer loop` inside an open loop".into()));
                }
                in_loop = true;
                corners.clear();
            }
            b"vertex" => {
                if !in_loop {
                    return Err(err("`vertex` outside `outer loop`".into()));
                }
                let mut p = [0.0; 3];
                for (k, name) in ["vertex x", "vertex y", "vertex z"].iter().enumerate() {
                    let tok = toks
                        .next()
                        .ok_or_else(|| err(format!("{name} coordinate is missing")))?;
                    p[k] = parse_finite(tok, name).map_err(err)?;
                }
                if corners.len() == 3 {
                    return Err(err("facet has more than 3 vertices".into()));
                }
                corners.push(welder.vertex(p));
            }
            b"endloop" => {
                if !in_loop || corners.len() != 3 {
                    return Err(err(format!(
                        "facet loop has {} vertices, exactly 3 are needed",
                        corners.len()
                    )));
                }
                in_loop = false;
                welder
                    .surface
                    .triangles
                    .push([corners[0], corners[1], corners[2]]);
            }
            b"solid" | b"facet" | b"endfacet" | b"endsolid" => {}
            other => {
                return Err(err(format!("unexpected keyword {:?}", show(other))));
            }
        }
    }
    if in_loop {
        return Err(MeshError::parse(
            path,
            "end of file",
            "unterminated `outer loop`",
        ));
    }
    if welder.surface.triangles.is_empty() {
        return Err(MeshError::parse(
            path,
            "contents",
            "no facets (empty model)",
        ));
    }
    Ok(welder.surface)
}
