//! Wavefront OBJ reader: `v` positions and `f` faces (any `v/vt/vn` form, negative indices,
//! polygons split into fans), with selection of faces by group (`g`) or object (`o`) name. Other
//! statements (`vt`, `vn`, `s`, `usemtl`, `mtllib`, ...) are skipped.

use std::path::Path;

use super::{LoadOptions, parse_finite, push_fan, require_vertices, show, tokens};
use crate::error::{MeshError, Result};
use crate::types::Surface3;

/// Parses OBJ `bytes` (`path` is only used in error messages).
///
/// With a group selection, only faces in a selected group or object are kept, and only the
/// vertices those faces use (renumbered in file order). Without faces, every vertex is kept.
pub fn parse_obj(bytes: &[u8], path: &Path, options: &LoadOptions) -> Result<Surface3> {
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut triangles: Vec<[usize; 3]> = Vec::new();
    let mut polygon: Vec<usize> = Vec::with_capacity(8);
    let mut seen_names: Vec<String> = Vec::new();
    let selecting = !options.groups.is_empty();
    let mut object_selected = false;
    let mut group_selected = false;

    for (index, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = index + 1;
        let err = |message: String| MeshError::parse(path, format!("line {line_no}"), message);
        let mut toks = tokens(line);
        let Some(keyword) = toks.next() else { continue };
        match keyword {
            b"v" => {
                let mut p = [0.0; 3];
                for (k, name) in ["vertex x", "vertex y", "vertex z"].iter().enumerate() {
                    let tok = toks
                        .next()
                        .ok_or_else(|| err(format!("{name} coordinate is missing")))?;
                    p[k] = parse_finite(tok, name).map_err(err)?;
                }
                positions.push(p);
            }
            b"f" => {
                polygon.clear();
                for tok in toks {
                    let first = tok.split(|&b| b == b'/').next().unwrap_or(tok);
                    let text = std::str::from_utf8(first).unwrap_or("");
                    let raw: i64 = text.parse().map_err(|_| {
                        err(format!("face index {:?} is not an integer", show(tok)))
                    })?;
                    let n = positions.len() as i64;
                    let resolved = if raw > 0 { raw - 1 } else { n + raw };
                    if raw == 0 || resolved < 0 || resolved >= n {
                        return Err(err(format!(
                            "face index {raw} is out of range ({n} vertices defined so far)"
                        )));
                    }
                    polygon.push(resolved as usize);
                }
                if polygon.len() < 3 {
                    return Err(err(format!(
                        "face has {} vertices, at least 3 are needed",
                        polygon.len()
                    )));
                }
                if !selecting || object_selected || group_selected {
                    push_fan(&polygon, &mut triangles);
                }
            }
            b"g" | b"o" => {
                let names: Vec<String> = toks
                    .map(|t| String::from_utf8_lossy(t).into_owned())
                    .collect();
                let selected = names.iter().any(|n| options.groups.contains(n));
                for n in &names {
                    if seen_names.len() < 10_000 && !seen_names.contains(n) {
                        seen_names.push(n.clone());
                    }
                }
                if keyword == b"g" {
                    group_selected = selected;
                } else {
                    object_selected = selected;
                    // A new object starts outside any group.
                    group_selected = false;
                }
            }
            _ => {}
        }
    }

    if positions.is_empty() {
        return Err(MeshError::parse(
            path,
            "contents",
            "no vertices (empty model)",
        ));
    }
    if selecting {
        if triangles.is_empty() {
            let mut listed: Vec<&str> = seen_names.iter().map(String::as_str).take(12).collect();
            if seen_names.len() > 12 {
                listed.push("...");
            }
            return Err(MeshError::parse(
                path,
                "groups",
                format!(
                    "no face belongs to the selected group(s) {:?}; groups and objects in the file: {}",
                    options.groups,
                    if listed.is_empty() {
                        "none".to_string()
                    } else {
                        listed.join(", ")
                    }
                ),
            ));
        }
        return Ok(compact(&positions, &triangles));
    }
    let surface = Surface3 {
        vertices: positions,
        triangles,
    };
    require_vertices(&surface, path)?;
    Ok(surface)
}

/// Keeps only the vertices used by `triangles`, renumbered in their original order.
fn compact(positions: &[[f64; 3]], triangles: &[[usize; 3]]) -> Surface3 {
    let mut new_index = vec![usize::MAX; positions.len()];
    for t in triangles {
        for &v in t {
            new_index[v] = 0;
        }
    }
    let mut vertices = Vec::new();
    for (i, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = vertices.len();
            vertices.push(positions[i]);
        }
    }
    let triangles = triangles
        .iter()
        .map(|t| [new_index[t[0]], new_index[t[1]], new_index[t[2]]])
        .collect();
    Surface3 {
        vertices,
        triangles,
    }
}
