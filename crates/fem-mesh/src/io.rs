//! Mesh files: the mesh JSON contract (read and write) and exports for other tools (Gmsh `.msh`
//! 2.2 ASCII, legacy VTK ASCII). Every writer goes through [`write_atomic`]: a temporary file in
//! the target directory renamed into place, so a failed run never leaves a half-written file.
//!
//! **Mesh JSON:** `{"vertices": [[x, y], ...], "triangles": [[i, j, k], ...]}`, 0-based indices,
//! counter-clockwise triangles; extra keys are allowed and ignored on read. The reader rejects
//! non-finite coordinates, out-of-range or repeated indices and clockwise or degenerate triangles,
//! naming the offending entry.
//!
//! Two optional keys carry material regions: `"regions": [t0, t1, ...]`, one non-negative
//! integer tag per triangle, and `"region_names": ["soft-tissue", "femur", ...]`, the name of
//! each tag. Absent, the mesh is one region (tag 0). When present, `regions` has one entry per
//! triangle and every tag is below the number of names (when names are given; without names,
//! below [`MAX_UNNAMED_REGIONS`]); each name passes [`check_region_name`] and is given once. A
//! UTF-8 byte-order mark before the JSON is skipped. The Gmsh export
//! writes tag `k` as physical tag `k + 1` with a `$PhysicalNames` section; the VTK export writes
//! an integer `region` cell scalar.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

use crate::error::{MeshError, Result};
use crate::types::Mesh2;

/// Writes `bytes` to `path` atomically (temporary file in the same directory, then rename).
/// Only regular files are written: an existing directory, device, FIFO or symbolic link at
/// `path` is an error (a rename would replace it).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    Staged::write(path, bytes)?.commit()
}

/// A file written to a temporary name beside its destination, not yet renamed into place: a
/// command with several outputs stages them all and commits them only when every one was
/// written, so a failure leaves none of them.
#[derive(Debug)]
pub struct Staged {
    tmp: std::path::PathBuf,
    dest: std::path::PathBuf,
    done: bool,
}

impl Staged {
    /// Check that `path` is (or may become) a regular file, and write `bytes` beside it.
    pub fn write(path: &Path, bytes: &[u8]) -> Result<Staged> {
        static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        if let Ok(meta) = std::fs::symlink_metadata(path) {
            let ft = meta.file_type();
            if !ft.is_file() {
                let what = if ft.is_dir() {
                    "a directory"
                } else if ft.is_symlink() {
                    "a symbolic link"
                } else {
                    "a device, FIFO or socket"
                };
                return Err(MeshError::io(
                    path,
                    std::io::Error::other(format!("is {what}; fem2d writes regular files only")),
                ));
            }
        }
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        };
        let name = path
            .file_name()
            .ok_or_else(|| MeshError::io(path, std::io::Error::other("not a file path")))?;
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let tmp = dir.join(format!(
            ".{}.tmp{}-{n}",
            name.to_string_lossy(),
            std::process::id()
        ));
        STAGED
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(tmp.clone());
        let result = (|| {
            let mut file = std::fs::File::create(&tmp)?;
            file.write_all(bytes)?;
            file.sync_all()
        })();
        if let Err(e) = result {
            forget_staged(&tmp);
            return Err(MeshError::io(path, e));
        }
        Ok(Staged {
            tmp,
            dest: path.to_path_buf(),
            done: false,
        })
    }

    /// Rename into place.
    pub fn commit(mut self) -> Result<()> {
        // Held across the rename, so an interruption never removes a file already in place.
        let mut staged = STAGED.lock().unwrap_or_else(|p| p.into_inner());
        let result = std::fs::rename(&self.tmp, &self.dest);
        self.done = result.is_ok();
        if self.done {
            staged.retain(|t| t != &self.tmp);
        }
        result.map_err(|e| MeshError::io(&self.dest, e))
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.done {
            forget_staged(&self.tmp);
        }
    }
}

/// Temporary files of [`Staged`] writes not yet renamed into place, for [`interrupted`].
static STAGED: std::sync::Mutex<Vec<std::path::PathBuf>> = std::sync::Mutex::new(Vec::new());

fn forget_staged(tmp: &Path) {
    let mut staged = STAGED.lock().unwrap_or_else(|p| p.into_inner());
    let _ = std::fs::remove_file(tmp);
    staged.retain(|t| t != tmp);
}

/// Remove the temporary file of every [`Staged`] write not yet renamed into place, so that an
/// interrupted command leaves none behind. For a signal handler, which then exits: the list
/// stays locked, so no rename starts afterwards.
pub fn interrupted() {
    let staged = STAGED.lock().unwrap_or_else(|p| p.into_inner());
    // A thread may be creating one of them right now: look again a few times.
    for _ in 0..5 {
        for tmp in staged.iter() {
            let _ = std::fs::remove_file(tmp);
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    std::mem::forget(staged);
}

/// Mesh JSON text of `mesh` (one vertex or triangle per line).
pub fn mesh_to_json(mesh: &Mesh2) -> String {
    let mut s = String::with_capacity(40 * (mesh.vertices.len() + mesh.triangles.len()) + 64);
    s.push_str("{\n  \"vertices\": [");
    for (i, v) in mesh.vertices.iter().enumerate() {
        let sep = if i == 0 { "\n    " } else { ",\n    " };
        // serde_json prints the shortest representation that reads back exactly.
        let text = serde_json::to_string(v).unwrap_or_default();
        let _ = write!(s, "{sep}{text}");
    }
    s.push_str("\n  ],\n  \"triangles\": [");
    for (i, t) in mesh.triangles.iter().enumerate() {
        let sep = if i == 0 { "\n    " } else { ",\n    " };
        let _ = write!(s, "{sep}[{},{},{}]", t[0], t[1], t[2]);
    }
    s.push_str("\n  ]");
    if !mesh.regions.is_empty() {
        s.push_str(",\n  \"regions\": [");
        for (i, r) in mesh.regions.iter().enumerate() {
            let sep = if i == 0 { "" } else { "," };
            let _ = write!(s, "{sep}{r}");
        }
        s.push(']');
    }
    if !mesh.region_names.is_empty() {
        let names = serde_json::to_string(&mesh.region_names).unwrap_or_default();
        let _ = write!(s, ",\n  \"region_names\": {names}");
    }
    s.push_str("\n}\n");
    s
}

/// Writes `mesh` as mesh JSON to `path`.
pub fn write_mesh_json(path: &Path, mesh: &Mesh2) -> Result<()> {
    write_atomic(path, mesh_to_json(mesh).as_bytes())
}

/// `bytes` without a leading UTF-8 byte-order mark (which some editors write at the start of a
/// text file).
pub fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes)
}

/// Parses and validates mesh JSON `bytes` (`path` is only used in error messages).
pub fn parse_mesh_json(bytes: &[u8], path: &Path) -> Result<Mesh2> {
    // serde ignores unknown keys, as the contract requires.
    let mesh: Mesh2 = serde_json::from_slice(strip_bom(bytes)).map_err(|e| {
        MeshError::parse(
            path,
            format!("line {} column {}", e.line(), e.column()),
            e.to_string(),
        )
    })?;
    validate_mesh(&mesh)
        .map_err(|(location, message)| MeshError::parse(path, location, message))?;
    Ok(mesh)
}

/// Reads and validates a mesh JSON file.
pub fn read_mesh_json(path: &Path) -> Result<Mesh2> {
    let bytes = std::fs::read(path).map_err(|e| MeshError::io(path, e))?;
    parse_mesh_json(&bytes, path)
}

/// Checks the mesh contract; on failure returns `(location, message)`.
pub fn validate_mesh(mesh: &Mesh2) -> std::result::Result<(), (String, String)> {
    if mesh.triangles.is_empty() {
        return Err(("triangles".into(), "the mesh has no triangle".into()));
    }
    for (i, v) in mesh.vertices.iter().enumerate() {
        if !(v[0].is_finite() && v[1].is_finite()) {
            return Err((
                format!("vertex {i}"),
                format!("coordinate {v:?} is not finite"),
            ));
        }
    }
    let n = mesh.vertices.len();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if let Some(bad) = tri.iter().find(|&&i| i >= n) {
            return Err((
                format!("triangle {t}"),
                format!("vertex index {bad} is out of range ({n} vertices)"),
            ));
        }
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            return Err((
                format!("triangle {t}"),
                format!("repeated vertex index in {tri:?}"),
            ));
        }
        let area = mesh.signed_area(t);
        if area.is_nan() || area <= 0.0 {
            return Err((
                format!("triangle {t}"),
                format!("{tri:?} is clockwise or degenerate (signed area {area:e})"),
            ));
        }
    }
    validate_regions(mesh)
}

/// Most regions a mesh without `region_names` may tag: its tags must be below this. A program
/// that reads the mesh names each unnamed tag (`region-7`), so one tag of four billion would
/// make it name four billion regions; a named mesh's tags are bounded by its names.
pub const MAX_UNNAMED_REGIONS: u32 = 65_536;

/// The rule every region name follows (a mesh's `region_names`, and in scenes `material.name`
/// and each `[[regions]]` entry's `name`): not empty (nor only spaces), and without control
/// characters (line breaks, tabs), commas or double quotes, so that a name is one field of a
/// CSV header (`regions.csv`) and of a one-line message as it is. The error is the rule.
pub fn check_region_name(name: &str) -> std::result::Result<(), &'static str> {
    if name.trim().is_empty() || name.chars().any(|c| c.is_control() || c == ',' || c == '"') {
        Err(
            "must be non-empty, without commas, double quotes or control characters (line breaks, tabs)",
        )
    } else {
        Ok(())
    }
}

/// Checks the optional region keys: one tag per triangle, every tag below the number of names
/// (when names are given, else below [`MAX_UNNAMED_REGIONS`]), every name valid
/// ([`check_region_name`]) and given once; on failure returns `(location, message)`.
pub fn validate_regions(mesh: &Mesh2) -> std::result::Result<(), (String, String)> {
    for (k, name) in mesh.region_names.iter().enumerate() {
        if let Err(rule) = check_region_name(name) {
            return Err((format!("region_names[{k}]"), format!("{name:?} {rule}")));
        }
        if let Some(first) = mesh.region_names[..k].iter().position(|n| n == name) {
            return Err((
                format!("region_names[{k}]"),
                format!(
                    "{name:?} is given twice (also region_names[{first}]); each region needs its own name"
                ),
            ));
        }
    }
    let (m, tags, names) = (
        mesh.triangles.len(),
        mesh.regions.len(),
        mesh.region_names.len(),
    );
    if tags != 0 && tags != m {
        return Err((
            "regions".into(),
            format!("{tags} region tags for {m} triangles (one per triangle needed)"),
        ));
    }
    if names != 0
        && let Some((t, k)) = mesh
            .regions
            .iter()
            .enumerate()
            .find(|&(_, &k)| k as usize >= names)
    {
        return Err((
            format!("regions[{t}]"),
            format!("tag {k} has no name ({names} region_names)"),
        ));
    }
    if names == 0
        && let Some((t, k)) = mesh
            .regions
            .iter()
            .enumerate()
            .find(|&(_, &k)| k >= MAX_UNNAMED_REGIONS)
    {
        return Err((
            format!("regions[{t}]"),
            format!(
                "tag {k}: without region_names tags must be below {MAX_UNNAMED_REGIONS} (fem_mesh::io::MAX_UNNAMED_REGIONS)"
            ),
        ));
    }
    Ok(())
}

/// Gmsh `.msh` 2.2 ASCII text of `mesh` (z = 0, 3-node triangles). A triangle of region `k`
/// has physical and elementary tag `k + 1` (Gmsh tags start at 1; an untagged mesh is all 1);
/// named regions get a `$PhysicalNames` section (dimension 2).
pub fn mesh_to_gmsh(mesh: &Mesh2) -> String {
    let mut s = String::new();
    s.push_str("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n");
    if !mesh.region_names.is_empty() {
        let _ = writeln!(s, "$PhysicalNames\n{}", mesh.region_names.len());
        for (k, name) in mesh.region_names.iter().enumerate() {
            // Gmsh names are quoted strings: a quote inside a name would end it early.
            let _ = writeln!(s, "2 {} \"{}\"", k + 1, name.replace('"', "'"));
        }
        s.push_str("$EndPhysicalNames\n");
    }
    s.push_str("$Nodes\n");
    let _ = writeln!(s, "{}", mesh.vertices.len());
    for (i, v) in mesh.vertices.iter().enumerate() {
        let _ = writeln!(s, "{} {:?} {:?} 0", i + 1, v[0], v[1]);
    }
    s.push_str("$EndNodes\n$Elements\n");
    let _ = writeln!(s, "{}", mesh.triangles.len());
    for (i, t) in mesh.triangles.iter().enumerate() {
        let tag = u64::from(mesh.region_of(i)) + 1;
        let _ = writeln!(
            s,
            "{} 2 2 {tag} {tag} {} {} {}",
            i + 1,
            t[0] + 1,
            t[1] + 1,
            t[2] + 1
        );
    }
    s.push_str("$EndElements\n");
    s
}

/// Writes `mesh` as Gmsh `.msh` 2.2 ASCII.
pub fn write_gmsh(path: &Path, mesh: &Mesh2) -> Result<()> {
    write_atomic(path, mesh_to_gmsh(mesh).as_bytes())
}

/// Legacy VTK ASCII text of `mesh` (unstructured grid of triangles, z = 0); a tagged mesh also
/// gets `CELL_DATA` with an integer `region` scalar (the tag of each triangle).
pub fn mesh_to_vtk(mesh: &Mesh2) -> String {
    let mut s = String::new();
    s.push_str("# vtk DataFile Version 3.0\nfem2d mesh\nASCII\nDATASET UNSTRUCTURED_GRID\n");
    let _ = writeln!(s, "POINTS {} double", mesh.vertices.len());
    for v in &mesh.vertices {
        let _ = writeln!(s, "{:?} {:?} 0", v[0], v[1]);
    }
    let m = mesh.triangles.len();
    let _ = writeln!(s, "CELLS {m} {}", 4 * m);
    for t in &mesh.triangles {
        let _ = writeln!(s, "3 {} {} {}", t[0], t[1], t[2]);
    }
    let _ = writeln!(s, "CELL_TYPES {m}");
    for _ in 0..m {
        s.push_str("5\n");
    }
    if !mesh.regions.is_empty() {
        let _ = writeln!(
            s,
            "CELL_DATA {m}\nSCALARS region int 1\nLOOKUP_TABLE default"
        );
        for t in 0..m {
            let _ = writeln!(s, "{}", mesh.region_of(t));
        }
    }
    s
}

/// Writes `mesh` as legacy VTK ASCII.
pub fn write_vtk(path: &Path, mesh: &Mesh2) -> Result<()> {
    write_atomic(path, mesh_to_vtk(mesh).as_bytes())
}
