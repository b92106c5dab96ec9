//! VTK XML output for ParaView: one `.vtu` (UnstructuredGrid) file per frame and a `.pvd`
//! collection that indexes the frames by time, plus a small reader for the files written here
//! (and for simple ASCII `.vtu`/`.pvd` files in general).
//!
//! The mesh is 2D: points are written in 3D with z = 0, cells are linear triangles
//! (`VTK_TRIANGLE`, type 5). Point data and cell data are scalars or 2-vectors; vectors are written
//! with three components (z = 0) so ParaView can glyph and warp by them. The first scalar and
//! the first vector array of each section are marked active (`Scalars=`/`Vectors=`). Integer
//! tags (a region index per cell) are written as `UInt32` arrays; lists of names (what each
//! tag means) as string arrays in the data set's `FieldData`, which ParaView lists in its
//! Information panel and spreadsheet view.
//!
//! Everything is written in the ASCII format with the shortest representation that reads back
//! to the same `f64`, so values survive a write/read round trip bit for bit. Non-finite values
//! are rejected: VTK's ASCII reader cannot read them back.
//!
//! ```no_run
//! use fem_render::vtk::{DataArray, PvdWriter, VtkFrame};
//! # fn main() -> fem_render::Result<()> {
//! let positions = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
//! let triangles = [[0, 1, 2]];
//! let stress = [1.5];
//! let mut run = PvdWriter::new(std::path::Path::new("out"), "beam")?;
//! let frame = VtkFrame {
//!     positions: &positions,
//!     triangles: &triangles,
//!     point_data: vec![],
//!     cell_data: vec![("von_mises", DataArray::Scalars(&stress))],
//!     field_data: vec![],
//! };
//! run.add(0.0, &frame)?; // out/beam_000000.vtu
//! run.finish()?; // out/beam.pvd
//! # Ok(())
//! # }
//! ```

use std::path::{Path, PathBuf};

use crate::{RenderError, Result, write_atomic};

/// The VTK cell type of a linear triangle.
pub const VTK_TRIANGLE: u8 = 5;

/// One named array of point or cell data, one entry per point or per cell.
#[derive(Debug, Clone, Copy)]
pub enum DataArray<'a> {
    /// One value per point or cell (written with one component).
    Scalars(&'a [f64]),
    /// One 2-vector per point or cell (written with three components, z = 0).
    Vectors(&'a [[f64; 2]]),
    /// One non-negative integer per point or cell, e.g. a region index (written as `UInt32`
    /// with one component; read back as `f64` like every array).
    Tags(&'a [u32]),
    /// One 3-vector per point or cell (a 3D body's displacement).
    Vectors3(&'a [[f64; 3]]),
}

impl DataArray<'_> {
    /// Number of tuples (values for scalars, vectors for vectors).
    pub fn len(&self) -> usize {
        match self {
            DataArray::Scalars(v) => v.len(),
            DataArray::Vectors(v) => v.len(),
            DataArray::Tags(v) => v.len(),
            DataArray::Vectors3(v) => v.len(),
        }
    }

    /// Whether the array holds no tuples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of components written to the file: 1 for scalars, 3 for vectors.
    pub fn components(&self) -> usize {
        match self {
            DataArray::Scalars(_) | DataArray::Tags(_) => 1,
            DataArray::Vectors(_) | DataArray::Vectors3(_) => 3,
        }
    }
}

/// One frame of a 2D triangle mesh with the data to attach to it.
#[derive(Debug, Clone, Default)]
pub struct VtkFrame<'a> {
    /// Point positions (written with z = 0).
    pub positions: &'a [[f64; 2]],
    /// Triangles as indices into `positions`.
    pub triangles: &'a [[usize; 3]],
    /// Arrays with one entry per point, e.g. `("displacement", DataArray::Vectors(..))`.
    pub point_data: Vec<(&'a str, DataArray<'a>)>,
    /// Arrays with one entry per triangle, e.g. `("von_mises", DataArray::Scalars(..))`.
    pub cell_data: Vec<(&'a str, DataArray<'a>)>,
    /// Lists of strings attached to the whole data set (VTK `FieldData`), e.g.
    /// `("region_names", &names)` saying what each value of a `region` cell array means.
    /// A string may not contain NUL (it ends each string in the file).
    pub field_data: Vec<(&'a str, &'a [String])>,
}

impl<'a> VtkFrame<'a> {
    /// A frame with the given mesh and no data arrays.
    pub fn new(positions: &'a [[f64; 2]], triangles: &'a [[usize; 3]]) -> Self {
        VtkFrame {
            positions,
            triangles,
            point_data: Vec::new(),
            cell_data: Vec::new(),
            field_data: Vec::new(),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Writing
// ---------------------------------------------------------------------------------------------

/// Appends the shortest decimal representation of `v` that parses back to the same `f64`, by
/// the `ryu` crate (Rust's own `{}` made writing a frame about twice as slow). Only finite
/// values reach here: [`validate`] rejects the others.
fn push_f64(out: &mut String, v: f64) {
    let mut buf = ryu::Buffer::new();
    out.push_str(buf.format_finite(v));
}

/// Appends a non-negative integer in decimal (the `itoa` crate, for the same reason).
fn push_usize(out: &mut String, v: usize) {
    let mut buf = itoa::Buffer::new();
    out.push_str(buf.format(v));
}

/// The character of `name` that cannot appear in an XML attribute value as written, if any.
fn bad_attribute_char(name: &str) -> Option<char> {
    name.chars().find(|&c| is_bad_attribute_char(c))
}

fn is_bad_attribute_char(c: char) -> bool {
    matches!(c, '"' | '\'' | '<' | '>' | '&') || c.is_control()
}

fn check_name(kind: &str, index: usize, name: &str) -> Result<()> {
    if name.is_empty() {
        return Err(RenderError::Input(format!(
            "{kind} array {index} has an empty name"
        )));
    }
    if let Some(c) = bad_attribute_char(name) {
        return Err(RenderError::Input(format!(
            "{kind} array name {name:?} contains {c:?}, which is not allowed in an XML attribute"
        )));
    }
    Ok(())
}

fn check_arrays(kind: &str, what: &str, arrays: &[(&str, DataArray<'_>)], n: usize) -> Result<()> {
    for (i, (name, array)) in arrays.iter().enumerate() {
        check_name(kind, i, name)?;
        if arrays[..i].iter().any(|(other, _)| other == name) {
            return Err(RenderError::Input(format!(
                "{kind} array name {name:?} is used more than once"
            )));
        }
        if array.len() != n {
            return Err(RenderError::Input(format!(
                "{kind} array {name:?} has {} entries, but there are {n} {what}",
                array.len()
            )));
        }
        let bad = match array {
            DataArray::Scalars(v) => v
                .iter()
                .position(|x| !x.is_finite())
                .map(|j| (j, format!("{}", v[j]))),
            DataArray::Vectors(v) => v
                .iter()
                .position(|x| !(x[0].is_finite() && x[1].is_finite()))
                .map(|j| (j, format!("[{}, {}]", v[j][0], v[j][1]))),
            DataArray::Tags(_) => None,
            DataArray::Vectors3(v) => v
                .iter()
                .position(|x| !x.iter().all(|c| c.is_finite()))
                .map(|j| (j, format!("{:?}", v[j]))),
        };
        if let Some((j, value)) = bad {
            return Err(RenderError::Input(format!(
                "{kind} array {name:?} entry {j} is not finite: {value}"
            )));
        }
    }
    Ok(())
}

fn validate(frame: &VtkFrame<'_>) -> Result<()> {
    let np = frame.positions.len();
    if let Some(i) = frame
        .positions
        .iter()
        .position(|p| !(p[0].is_finite() && p[1].is_finite()))
    {
        let p = frame.positions[i];
        return Err(RenderError::Input(format!(
            "position {i} is not finite: [{}, {}]",
            p[0], p[1]
        )));
    }
    for (t, tri) in frame.triangles.iter().enumerate() {
        if let Some(&v) = tri.iter().find(|&&v| v >= np) {
            return Err(RenderError::Input(format!(
                "triangle {t} refers to point {v}, but there are {np} points"
            )));
        }
    }
    check_arrays("point data", "points", &frame.point_data, np)?;
    check_arrays(
        "cell data",
        "cells",
        &frame.cell_data,
        frame.triangles.len(),
    )?;
    for (i, (name, strings)) in frame.field_data.iter().enumerate() {
        check_name("field data", i, name)?;
        if frame.field_data[..i].iter().any(|(other, _)| other == name) {
            return Err(RenderError::Input(format!(
                "field data array name {name:?} is used more than once"
            )));
        }
        if let Some(j) = strings.iter().position(|s| s.contains('\0')) {
            return Err(RenderError::Input(format!(
                "field data array {name:?} entry {j} contains NUL, which ends a string in VTK"
            )));
        }
    }
    Ok(())
}

/// The data set's `FieldData` section: each list of strings as a VTK string array, in ASCII
/// as VTK writes it (each string's bytes as numbers, then 0), one string per line.
fn push_field_data(out: &mut String, arrays: &[(&str, &[String])]) {
    if arrays.is_empty() {
        return;
    }
    out.push_str("    <FieldData>\n");
    for (name, strings) in arrays {
        out.push_str("      <Array type=\"String\" Name=\"");
        out.push_str(name);
        out.push_str("\" NumberOfTuples=\"");
        push_usize(out, strings.len());
        out.push_str("\" format=\"ascii\">\n");
        for s in *strings {
            for b in s.bytes() {
                push_usize(out, b as usize);
                out.push(' ');
            }
            out.push_str("0\n");
        }
        out.push_str("      </Array>\n");
    }
    out.push_str("    </FieldData>\n");
}

fn push_section(out: &mut String, tag: &str, arrays: &[(&str, DataArray<'_>)]) {
    out.push_str("      <");
    out.push_str(tag);
    let scalars = arrays
        .iter()
        .find(|(_, a)| matches!(a, DataArray::Scalars(_)));
    let vectors = arrays
        .iter()
        .find(|(_, a)| matches!(a, DataArray::Vectors(_) | DataArray::Vectors3(_)));
    if let Some((name, _)) = scalars {
        out.push_str(" Scalars=\"");
        out.push_str(name);
        out.push('"');
    }
    if let Some((name, _)) = vectors {
        out.push_str(" Vectors=\"");
        out.push_str(name);
        out.push('"');
    }
    out.push_str(">\n");
    for (name, array) in arrays {
        out.push_str("        <DataArray type=\"");
        out.push_str(match array {
            DataArray::Tags(_) => "UInt32",
            DataArray::Scalars(_) | DataArray::Vectors(_) | DataArray::Vectors3(_) => "Float64",
        });
        out.push_str("\" Name=\"");
        out.push_str(name);
        out.push_str("\" NumberOfComponents=\"");
        push_usize(out, array.components());
        out.push_str("\" format=\"ascii\">\n");
        match array {
            DataArray::Scalars(values) => {
                for row in values.chunks(6) {
                    for (k, &v) in row.iter().enumerate() {
                        if k > 0 {
                            out.push(' ');
                        }
                        push_f64(out, v);
                    }
                    out.push('\n');
                }
            }
            DataArray::Vectors(values) => {
                for v in *values {
                    push_f64(out, v[0]);
                    out.push(' ');
                    push_f64(out, v[1]);
                    out.push_str(" 0\n");
                }
            }
            DataArray::Vectors3(values) => {
                for v in *values {
                    push_f64(out, v[0]);
                    out.push(' ');
                    push_f64(out, v[1]);
                    out.push(' ');
                    push_f64(out, v[2]);
                    out.push('\n');
                }
            }
            DataArray::Tags(values) => {
                for row in values.chunks(24) {
                    for (k, &v) in row.iter().enumerate() {
                        if k > 0 {
                            out.push(' ');
                        }
                        push_usize(out, v as usize);
                    }
                    out.push('\n');
                }
            }
        }
        out.push_str("        </DataArray>\n");
    }
    out.push_str("      </");
    out.push_str(tag);
    out.push_str(">\n");
}

/// The `.vtu` (VTK XML UnstructuredGrid, ASCII) text of one frame.
///
/// Fails with [`RenderError::Input`] if a triangle refers to a point that does not exist, a
/// data array's length differs from the number of points or cells, a name is empty, used twice
/// in the same section, or contains a character that would break an XML attribute (quotes,
/// `<`, `>`, `&`, control characters), a position or data value is not finite, or a field
/// data string contains NUL.
pub fn vtu_string(frame: &VtkFrame<'_>) -> Result<String> {
    validate(frame)?;
    let np = frame.positions.len();
    let nc = frame.triangles.len();
    let point_values: usize = frame.point_data.iter().map(|(_, a)| a.len() * 3).sum();
    let cell_values: usize = frame.cell_data.iter().map(|(_, a)| a.len() * 3).sum();
    let mut out =
        String::with_capacity(1024 + 24 * (3 * np + point_values + cell_values) + 40 * nc);

    out.push_str("<?xml version=\"1.0\"?>\n");
    out.push_str(
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\">\n",
    );
    out.push_str("  <UnstructuredGrid>\n");
    push_field_data(&mut out, &frame.field_data);
    out.push_str("    <Piece NumberOfPoints=\"");
    push_usize(&mut out, np);
    out.push_str("\" NumberOfCells=\"");
    push_usize(&mut out, nc);
    out.push_str("\">\n");

    push_section(&mut out, "PointData", &frame.point_data);
    push_section(&mut out, "CellData", &frame.cell_data);

    out.push_str("      <Points>\n");
    out.push_str(
        "        <DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" \
         format=\"ascii\">\n",
    );
    for p in frame.positions {
        push_f64(&mut out, p[0]);
        out.push(' ');
        push_f64(&mut out, p[1]);
        out.push_str(" 0\n");
    }
    out.push_str("        </DataArray>\n");
    out.push_str("      </Points>\n");

    push_cells(
        &mut out,
        frame.triangles.iter().map(|t| &t[..]),
        3,
        VTK_TRIANGLE,
    );
    Ok(out)
}

/// The `Cells` section (connectivity, offsets, types) of cells of `nodes` points each, all of
/// VTK type `cell_type`, and the closing tags of the piece and the file.
fn push_cells<'c>(
    out: &mut String,
    cells: impl ExactSizeIterator<Item = &'c [usize]> + Clone,
    nodes: usize,
    cell_type: u8,
) {
    let nc = cells.len();
    out.push_str("      <Cells>\n");
    out.push_str("        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for cell in cells {
        for (k, &v) in cell.iter().enumerate() {
            if k > 0 {
                out.push(' ');
            }
            push_usize(out, v);
        }
        out.push('\n');
    }
    out.push_str("        </DataArray>\n");
    out.push_str("        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    for c in 0..nc {
        push_usize(out, nodes * (c + 1));
        out.push(if c % 12 == 11 || c + 1 == nc {
            '\n'
        } else {
            ' '
        });
    }
    out.push_str("        </DataArray>\n");
    out.push_str("        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
    for c in 0..nc {
        push_usize(out, cell_type as usize);
        out.push(if c % 24 == 23 || c + 1 == nc {
            '\n'
        } else {
            ' '
        });
    }
    out.push_str("        </DataArray>\n");
    out.push_str("      </Cells>\n");
    out.push_str("    </Piece>\n");
    out.push_str("  </UnstructuredGrid>\n");
    out.push_str("</VTKFile>\n");
}

/// Writes one frame to `path` as a `.vtu` file (atomically: temporary file and rename).
///
/// Fails as [`vtu_string`] does, or with [`RenderError::Io`] naming the file.
pub fn write_vtu(path: &Path, frame: &VtkFrame<'_>) -> Result<()> {
    let text = vtu_string(frame)?;
    write_atomic(path, text.as_bytes())
}

/// The `.pvd` collection text for `(time, file)` pairs, in the given order; `file` is written
/// as is (normally a path relative to the `.pvd`'s directory, with `/` separators).
///
/// Fails with [`RenderError::Input`] if a time is not finite or a file name is empty or contains
/// a character that would break an XML attribute.
pub fn pvd_string(datasets: &[(f64, &str)]) -> Result<String> {
    let mut out = String::with_capacity(160 + 96 * datasets.len());
    out.push_str("<?xml version=\"1.0\"?>\n");
    out.push_str("<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n");
    out.push_str("  <Collection>\n");
    for (i, &(time, file)) in datasets.iter().enumerate() {
        if !time.is_finite() {
            return Err(RenderError::Input(format!(
                "data set {i} ({file:?}): time {time} is not finite"
            )));
        }
        if file.is_empty() {
            return Err(RenderError::Input(format!(
                "data set {i} has an empty file name"
            )));
        }
        if let Some(c) = bad_attribute_char(file) {
            return Err(RenderError::Input(format!(
                "data set {i}: file name {file:?} contains {c:?}, which is not allowed in an XML \
                 attribute"
            )));
        }
        out.push_str("    <DataSet timestep=\"");
        push_f64(&mut out, time);
        out.push_str("\" group=\"\" part=\"0\" file=\"");
        out.push_str(file);
        out.push_str("\"/>\n");
    }
    out.push_str("  </Collection>\n");
    out.push_str("</VTKFile>\n");
    Ok(out)
}

/// Writes a time series: `<dir>/<stem>_<NNNNNN>.vtu` for each frame, numbered from 0, and
/// `<dir>/<stem>.pvd` indexing them by time.
///
/// Every file is written atomically. The `.pvd` is written by [`finish`](Self::finish) (and, to
/// have a readable index while a long run is still going, by [`write_pvd`](Self::write_pvd) as
/// often as wanted); rewriting it replaces the previous one in one step. Files of an earlier run
/// with more frames are not deleted, but the new `.pvd` does not refer to them.
#[derive(Debug)]
pub struct PvdWriter {
    dir: PathBuf,
    stem: String,
    /// `(time, file name relative to dir)`.
    entries: Vec<(f64, String)>,
}

impl PvdWriter {
    /// Starts a time series in `dir` (created if missing) with file names starting with `stem`.
    ///
    /// `stem` must be a plain file name: not empty, not `.` or `..`, no path separators, no
    /// characters that would break an XML attribute.
    pub fn new(dir: &Path, stem: &str) -> Result<Self> {
        if stem.is_empty() || stem == "." || stem == ".." {
            return Err(RenderError::Input(format!(
                "stem {stem:?} is not a plain file name"
            )));
        }
        if let Some(c) = stem
            .chars()
            .find(|&c| matches!(c, '/' | '\\' | ':') || is_bad_attribute_char(c))
        {
            return Err(RenderError::Input(format!(
                "stem {stem:?} contains {c:?}; it must be a plain file name"
            )));
        }
        std::fs::create_dir_all(dir).map_err(|source| RenderError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        Ok(PvdWriter {
            dir: dir.to_path_buf(),
            stem: stem.to_owned(),
            entries: Vec::new(),
        })
    }

    /// Writes `frame` as the next `.vtu` file and records it at `time`; returns the file's path.
    ///
    /// `time` must be finite and not smaller than the previous frame's time. On error nothing is
    /// recorded (and the frame can be added again).
    pub fn add(&mut self, time: f64, frame: &VtkFrame<'_>) -> Result<PathBuf> {
        self.add_with(time, || vtu_string(frame))
    }

    /// [`PvdWriter::add`] for a frame of a tetrahedral mesh ([`solid_vtu_string`]).
    pub fn add_solid(&mut self, time: f64, frame: &SolidFrame<'_>) -> Result<PathBuf> {
        self.add_with(time, || solid_vtu_string(frame))
    }

    fn add_with(&mut self, time: f64, text: impl FnOnce() -> Result<String>) -> Result<PathBuf> {
        let index = self.entries.len();
        if !time.is_finite() {
            return Err(RenderError::Input(format!(
                "frame {index}: time {time} is not finite"
            )));
        }
        if let Some(&(last, _)) = self.entries.last().filter(|(last, _)| time < *last) {
            return Err(RenderError::Input(format!(
                "frame {index}: time {time} is before the previous frame's time {last}"
            )));
        }
        let name = format!("{}_{index:06}.vtu", self.stem);
        let path = self.dir.join(&name);
        let text = text().map_err(|e| match e {
            RenderError::Input(m) => {
                RenderError::Input(format!("frame {index} (time {time}): {m}"))
            }
            other => other,
        })?;
        write_atomic(&path, text.as_bytes())?;
        self.entries.push((time, name));
        Ok(path)
    }

    /// Number of frames added so far.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether no frame has been added yet.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The path of the `.pvd` file: `<dir>/<stem>.pvd`.
    pub fn pvd_path(&self) -> PathBuf {
        self.dir.join(format!("{}.pvd", self.stem))
    }

    /// Writes the `.pvd` for the frames added so far (atomically) and returns its path. May be
    /// called any number of times during a run.
    pub fn write_pvd(&self) -> Result<PathBuf> {
        let datasets: Vec<(f64, &str)> = self
            .entries
            .iter()
            .map(|(t, name)| (*t, name.as_str()))
            .collect();
        let text = pvd_string(&datasets)?;
        let path = self.pvd_path();
        write_atomic(&path, text.as_bytes())?;
        Ok(path)
    }

    /// Writes the `.pvd` (atomically) and returns its path.
    pub fn finish(self) -> Result<PathBuf> {
        self.write_pvd()
    }
}

// ---------------------------------------------------------------------------------------------
// Reading
// ---------------------------------------------------------------------------------------------

/// The content of a `.vtu` file, as read by [`read_vtu`] / [`parse_vtu`].
#[derive(Debug, Clone, PartialEq)]
pub struct VtuData {
    /// Point coordinates.
    pub points: Vec<[f64; 3]>,
    /// Connectivity of each cell (indices into `points`).
    pub cells: Vec<Vec<usize>>,
    /// VTK cell type of each cell (5 for triangles).
    pub cell_types: Vec<u8>,
    /// Point data arrays: `(name, number of components, values)`, values tuple by tuple.
    pub point_data: Vec<(String, usize, Vec<f64>)>,
    /// Cell data arrays: `(name, number of components, values)`, values tuple by tuple.
    pub cell_data: Vec<(String, usize, Vec<f64>)>,
    /// The data set's string arrays (`FieldData`): `(name, strings)`. Numeric field data
    /// arrays are not read.
    pub field_data: Vec<(String, Vec<String>)>,
}

impl VtuData {
    /// The point data array called `name`: `(components, values)`.
    pub fn point_array(&self, name: &str) -> Option<(usize, &[f64])> {
        find_array(&self.point_data, name)
    }

    /// The cell data array called `name`: `(components, values)`.
    pub fn cell_array(&self, name: &str) -> Option<(usize, &[f64])> {
        find_array(&self.cell_data, name)
    }

    /// The field data string array called `name`.
    pub fn field_strings(&self, name: &str) -> Option<&[String]> {
        self.field_data
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }
}

fn find_array<'a>(
    arrays: &'a [(String, usize, Vec<f64>)],
    name: &str,
) -> Option<(usize, &'a [f64])> {
    arrays
        .iter()
        .find(|(n, _, _)| n == name)
        .map(|(_, c, v)| (*c, v.as_slice()))
}

type Node<'a, 'i> = roxmltree::Node<'a, 'i>;

fn child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> std::result::Result<Node<'a, 'i>, String> {
    node.children()
        .find(|c| c.is_element() && c.tag_name().name() == name)
        .ok_or_else(|| format!("<{}>: missing <{name}> element", node.tag_name().name()))
}

fn attr<'a>(node: Node<'a, '_>, name: &str) -> std::result::Result<&'a str, String> {
    node.attribute(name)
        .ok_or_else(|| format!("<{}>: missing attribute {name}", node.tag_name().name()))
}

fn usize_attr(node: Node<'_, '_>, name: &str) -> std::result::Result<usize, String> {
    let text = attr(node, name)?;
    text.trim().parse().map_err(|_| {
        format!(
            "<{}>: attribute {name}={text:?} is not a non-negative integer",
            node.tag_name().name()
        )
    })
}

/// A human-readable label for a `<DataArray>`: its name, or `fallback`.
fn array_label(node: Node<'_, '_>, fallback: &str) -> String {
    match node.attribute("Name") {
        Some(name) => format!("DataArray {name:?}"),
        None => format!("DataArray of {fallback}"),
    }
}

fn check_ascii(node: Node<'_, '_>, label: &str) -> std::result::Result<(), String> {
    match node.attribute("format") {
        None | Some("ascii") => Ok(()),
        Some(other) => Err(format!(
            "{label}: format={other:?} is not supported (only ascii)"
        )),
    }
}

fn components(node: Node<'_, '_>, label: &str) -> std::result::Result<usize, String> {
    match node.attribute("NumberOfComponents") {
        None => Ok(1),
        Some(text) => match text.trim().parse::<usize>() {
            Ok(n) if n > 0 => Ok(n),
            _ => Err(format!(
                "{label}: NumberOfComponents={text:?} is not a positive integer"
            )),
        },
    }
}

/// The whitespace-separated tokens of an element's text.
fn tokens<'a>(node: Node<'a, '_>) -> impl Iterator<Item = &'a str> {
    node.children()
        .filter(|c| c.is_text())
        .filter_map(|c| c.text())
        .flat_map(str::split_ascii_whitespace)
}

/// Parses every token of `node` with `parse`, requiring exactly `expected` values if given.
fn parse_values<T>(
    node: Node<'_, '_>,
    label: &str,
    expected: Option<(usize, &str)>,
    parse: impl Fn(&str) -> Option<T>,
) -> std::result::Result<Vec<T>, String> {
    check_ascii(node, label)?;
    let mut values = Vec::with_capacity(expected.map_or(0, |(n, _)| n));
    for (i, token) in tokens(node).enumerate() {
        match parse(token) {
            Some(v) => values.push(v),
            None => {
                return Err(format!(
                    "{label}: value {i} is not a valid number: {token:?}"
                ));
            }
        }
    }
    if let Some((n, why)) = expected.filter(|&(n, _)| values.len() != n) {
        return Err(format!(
            "{label}: expected {n} values ({why}), found {}",
            values.len()
        ));
    }
    Ok(values)
}

fn parse_f64(token: &str) -> Option<f64> {
    token.parse().ok()
}

fn parse_index(token: &str) -> Option<usize> {
    token.parse().ok()
}

fn read_section(
    piece: Node<'_, '_>,
    tag: &str,
    n: usize,
    what: &str,
) -> std::result::Result<Vec<(String, usize, Vec<f64>)>, String> {
    let Some(section) = piece
        .children()
        .find(|c| c.is_element() && c.tag_name().name() == tag)
    else {
        return Ok(Vec::new());
    };
    let mut arrays = Vec::new();
    for node in section
        .children()
        .filter(|c| c.is_element() && c.tag_name().name() == "DataArray")
    {
        let name = node
            .attribute("Name")
            .ok_or_else(|| format!("<{tag}>: a <DataArray> has no Name attribute"))?;
        let label = format!("{tag} DataArray {name:?}");
        let comps = components(node, &label)?;
        let why = format!("{n} {what} x {comps} components");
        let values = parse_values(node, &label, Some((n * comps, &why)), parse_f64)?;
        arrays.push((name.to_owned(), comps, values));
    }
    Ok(arrays)
}

/// The string arrays of the data set's `<FieldData>` (none without one): each `<Array
/// type="String">` as VTK writes it in ASCII, byte values with 0 ending each string.
fn read_field_strings(
    grid: Node<'_, '_>,
) -> std::result::Result<Vec<(String, Vec<String>)>, String> {
    let Some(section) = grid
        .children()
        .find(|c| c.is_element() && c.tag_name().name() == "FieldData")
    else {
        return Ok(Vec::new());
    };
    let mut arrays = Vec::new();
    for node in section.children().filter(|c| {
        c.is_element() && c.tag_name().name() == "Array" && c.attribute("type") == Some("String")
    }) {
        let name = node
            .attribute("Name")
            .ok_or_else(|| "<FieldData>: an <Array> has no Name attribute".to_owned())?;
        let label = format!("FieldData Array {name:?}");
        let bytes = parse_values(node, &label, None, |t| t.parse::<u8>().ok())?;
        if bytes.last().is_some_and(|&b| b != 0) {
            return Err(format!("{label}: the last string does not end with 0"));
        }
        let strings: Vec<String> = bytes
            .split(|&b| b == 0)
            .take(bytes.iter().filter(|&&b| b == 0).count())
            .map(|s| String::from_utf8_lossy(s).into_owned())
            .collect();
        if let Some(n) = node.attribute("NumberOfTuples") {
            let n: usize = n
                .trim()
                .parse()
                .map_err(|_| format!("{label}: NumberOfTuples={n:?} is not an integer"))?;
            if n != strings.len() {
                return Err(format!(
                    "{label}: NumberOfTuples={n}, but it holds {} strings",
                    strings.len()
                ));
            }
        }
        arrays.push((name.to_owned(), strings));
    }
    Ok(arrays)
}

/// The document's `<VTKFile>` root, checked to be of `kind` (`UnstructuredGrid`, `Collection`).
fn vtk_root<'a, 'i>(
    doc: &'a roxmltree::Document<'i>,
    kind: &str,
) -> std::result::Result<Node<'a, 'i>, String> {
    let root = doc.root_element();
    if root.tag_name().name() != "VTKFile" {
        return Err(format!(
            "root element is <{}>, expected <VTKFile>",
            root.tag_name().name()
        ));
    }
    let found = attr(root, "type")?;
    if found != kind {
        return Err(format!("<VTKFile>: type={found:?}, expected \"{kind}\""));
    }
    Ok(root)
}

/// Parses the text of an ASCII `.vtu` file (VTK XML UnstructuredGrid with one Piece).
///
/// The error names what is wrong: a missing element or attribute, a wrong number of values, a
/// token that is not a number (with its value), an index out of range, a non-ASCII format.
pub fn parse_vtu(xml: &str) -> std::result::Result<VtuData, String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("invalid XML: {e}"))?;
    let root = vtk_root(&doc, "UnstructuredGrid")?;
    let grid = child(root, "UnstructuredGrid")?;
    let mut pieces = grid
        .children()
        .filter(|c| c.is_element() && c.tag_name().name() == "Piece");
    let piece = pieces
        .next()
        .ok_or_else(|| "<UnstructuredGrid>: missing <Piece> element".to_owned())?;
    if pieces.next().is_some() {
        return Err("<UnstructuredGrid>: more than one <Piece> (not supported)".to_owned());
    }
    let np = usize_attr(piece, "NumberOfPoints")?;
    let nc = usize_attr(piece, "NumberOfCells")?;

    // Points.
    let points_node = child(child(piece, "Points")?, "DataArray")?;
    let label = array_label(points_node, "Points");
    let comps = components(points_node, &label)?;
    if comps != 3 {
        return Err(format!("{label}: NumberOfComponents={comps}, expected 3"));
    }
    let why = format!("{np} points x 3 components");
    let coords = parse_values(points_node, &label, Some((3 * np, &why)), parse_f64)?;
    let points = coords.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();

    // Cells.
    let cells_node = child(piece, "Cells")?;
    let cell_array = |name: &str| {
        cells_node
            .children()
            .find(|c| {
                c.is_element()
                    && c.tag_name().name() == "DataArray"
                    && c.attribute("Name") == Some(name)
            })
            .ok_or_else(|| format!("<Cells>: missing <DataArray Name=\"{name}\">"))
    };
    let conn_node = cell_array("connectivity")?;
    let offsets_node = cell_array("offsets")?;
    let types_node = cell_array("types")?;
    let connectivity = parse_values(conn_node, "DataArray \"connectivity\"", None, parse_index)?;
    let why = format!("one per cell, {nc} cells");
    let offsets = parse_values(
        offsets_node,
        "DataArray \"offsets\"",
        Some((nc, &why)),
        parse_index,
    )?;
    let cell_types = parse_values(types_node, "DataArray \"types\"", Some((nc, &why)), |t| {
        t.parse::<u8>().ok()
    })?;
    if let Some(&v) = connectivity.iter().find(|&&v| v >= np) {
        return Err(format!(
            "DataArray \"connectivity\": point index {v} is out of range ({np} points)"
        ));
    }
    let mut cells = Vec::with_capacity(nc);
    let mut start = 0;
    for (c, &end) in offsets.iter().enumerate() {
        if end < start || end > connectivity.len() {
            return Err(format!(
                "DataArray \"offsets\": offset {c} is {end}, expected between {start} and {} \
                 (the connectivity length)",
                connectivity.len()
            ));
        }
        cells.push(connectivity[start..end].to_vec());
        start = end;
    }
    if start != connectivity.len() {
        return Err(format!(
            "DataArray \"connectivity\": {} values, but the last offset is {start}",
            connectivity.len()
        ));
    }

    let point_data = read_section(piece, "PointData", np, "points")?;
    let cell_data = read_section(piece, "CellData", nc, "cells")?;
    let field_data = read_field_strings(grid)?;
    Ok(VtuData {
        points,
        cells,
        cell_types,
        point_data,
        cell_data,
        field_data,
    })
}

fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|source| RenderError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    String::from_utf8(bytes).map_err(|e| RenderError::Parse {
        path: path.to_path_buf(),
        message: format!("not UTF-8 text: {e}"),
    })
}

/// Reads an ASCII `.vtu` file; see [`parse_vtu`]. Errors are [`RenderError::Io`] or
/// [`RenderError::Parse`], both naming the file.
pub fn read_vtu(path: &Path) -> Result<VtuData> {
    let text = read_text(path)?;
    parse_vtu(&text).map_err(|message| RenderError::Parse {
        path: path.to_path_buf(),
        message,
    })
}

/// Parses the text of a `.pvd` collection: `(timestep, file)` per `<DataSet>`, in file order.
fn parse_pvd(xml: &str) -> std::result::Result<Vec<(f64, String)>, String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("invalid XML: {e}"))?;
    let root = vtk_root(&doc, "Collection")?;
    let collection = child(root, "Collection")?;
    let mut out = Vec::new();
    for (i, ds) in collection
        .children()
        .filter(|c| c.is_element() && c.tag_name().name() == "DataSet")
        .enumerate()
    {
        let time_text = ds
            .attribute("timestep")
            .ok_or_else(|| format!("<DataSet> {i}: missing attribute timestep"))?;
        let time: f64 = time_text
            .trim()
            .parse()
            .map_err(|_| format!("<DataSet> {i}: timestep={time_text:?} is not a number"))?;
        let file = ds
            .attribute("file")
            .ok_or_else(|| format!("<DataSet> {i}: missing attribute file"))?;
        if file.is_empty() {
            return Err(format!("<DataSet> {i}: empty file attribute"));
        }
        out.push((time, file.to_owned()));
    }
    Ok(out)
}

/// Reads a `.pvd` collection: `(time, path of the data set)` per `<DataSet>`, in file order.
/// Relative file names are joined to the `.pvd`'s directory; absolute ones are kept.
pub fn read_pvd(path: &Path) -> Result<Vec<(f64, PathBuf)>> {
    let text = read_text(path)?;
    let entries = parse_pvd(&text).map_err(|message| RenderError::Parse {
        path: path.to_path_buf(),
        message,
    })?;
    let dir = path.parent().unwrap_or(Path::new(""));
    Ok(entries
        .into_iter()
        .map(|(t, file)| (t, dir.join(file)))
        .collect())
}

/// The VTK cell type of a linear tetrahedron.
pub const VTK_TETRA: u8 = 10;

/// One frame of a 3D tetrahedral mesh with the data to attach to it.
#[derive(Debug, Clone, Default)]
pub struct SolidFrame<'a> {
    /// Point positions.
    pub positions: &'a [[f64; 3]],
    /// Tetrahedra as indices into `positions`.
    pub tetrahedra: &'a [[usize; 4]],
    /// Arrays with one entry per point, e.g. `("displacement", DataArray::Vectors3(..))`.
    pub point_data: Vec<(&'a str, DataArray<'a>)>,
    /// Arrays with one entry per tetrahedron, e.g. `("von_mises", DataArray::Scalars(..))`.
    pub cell_data: Vec<(&'a str, DataArray<'a>)>,
}

/// The `.vtu` text of one frame of a tetrahedral mesh (cell type [`VTK_TETRA`]); fails as
/// [`vtu_string`] does.
pub fn solid_vtu_string(frame: &SolidFrame<'_>) -> Result<String> {
    let np = frame.positions.len();
    let nc = frame.tetrahedra.len();
    if let Some(i) = frame
        .positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(RenderError::Input(format!(
            "position {i} is not finite: {:?}",
            frame.positions[i]
        )));
    }
    for (t, tet) in frame.tetrahedra.iter().enumerate() {
        if let Some(&v) = tet.iter().find(|&&v| v >= np) {
            return Err(RenderError::Input(format!(
                "tetrahedron {t} refers to point {v}, but there are {np} points"
            )));
        }
    }
    check_arrays("point data", "points", &frame.point_data, np)?;
    check_arrays("cell data", "cells", &frame.cell_data, nc)?;
    let mut out = String::with_capacity(1024 + 80 * np + 60 * nc);
    out.push_str("<?xml version=\"1.0\"?>\n");
    out.push_str(
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\">\n",
    );
    out.push_str("  <UnstructuredGrid>\n");
    out.push_str("    <Piece NumberOfPoints=\"");
    push_usize(&mut out, np);
    out.push_str("\" NumberOfCells=\"");
    push_usize(&mut out, nc);
    out.push_str("\">\n");
    push_section(&mut out, "PointData", &frame.point_data);
    push_section(&mut out, "CellData", &frame.cell_data);
    out.push_str("      <Points>\n");
    out.push_str(
        "        <DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" \
         format=\"ascii\">\n",
    );
    for p in frame.positions {
        push_f64(&mut out, p[0]);
        out.push(' ');
        push_f64(&mut out, p[1]);
        out.push(' ');
        push_f64(&mut out, p[2]);
        out.push('\n');
    }
    out.push_str("        </DataArray>\n");
    out.push_str("      </Points>\n");
    push_cells(
        &mut out,
        frame.tetrahedra.iter().map(|t| &t[..]),
        4,
        VTK_TETRA,
    );
    Ok(out)
}
