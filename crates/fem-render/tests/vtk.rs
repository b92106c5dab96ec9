//! Tests of the VTK writer and reader: bit-exact round trips, the XML structure ParaView
//! expects, `.pvd` collections, validation errors, corrupted files, atomic writes.

use std::path::{Path, PathBuf};

use fem_render::RenderError;
use fem_render::vtk::{
    DataArray, PvdWriter, VtkFrame, VtuData, parse_vtu, pvd_string, read_pvd, read_vtu, vtu_string,
    write_vtu,
};

/// A fresh, empty directory for one test.
fn fresh_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("vtk-tests")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An `nx` x `ny` grid of points on [0, 1]^2, two triangles per square.
fn grid(nx: usize, ny: usize) -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
    let mut positions = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            positions.push([i as f64 / (nx - 1) as f64, j as f64 / (ny - 1) as f64]);
        }
    }
    let mut triangles = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = j * nx + i;
            triangles.push([a, a + 1, a + nx + 1]);
            triangles.push([a, a + nx + 1, a + nx]);
        }
    }
    (positions, triangles)
}

/// Values that are easy to get wrong when printing and parsing.
const AWKWARD: [f64; 16] = [
    1e-300,
    -0.0,
    0.1 + 0.2,
    1e300,
    0.0,
    5e-324,
    f64::MAX,
    f64::MIN_POSITIVE,
    1.0 / 3.0,
    -2.0 / 3.0,
    1e16,
    9999999999999998.0, // the largest f64 below 1e16
    1e-5,
    9.9999999999e-6,
    -123456.789e-7,
    std::f64::consts::PI * 1e-20,
];

fn awkward(i: usize) -> f64 {
    AWKWARD[i % AWKWARD.len()]
}

fn input_message(result: fem_render::Result<impl std::fmt::Debug>) -> String {
    match result {
        Err(RenderError::Input(m)) => m,
        other => panic!("expected an Input error, got {other:?}"),
    }
}

fn parse_error(result: fem_render::Result<impl std::fmt::Debug>) -> (PathBuf, String) {
    match result {
        Err(RenderError::Parse { path, message }) => (path, message),
        other => panic!("expected a Parse error, got {other:?}"),
    }
}

fn assert_bits_eq(what: &str, got: &[f64], want: &[f64]) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(
            g.to_bits(),
            w.to_bits(),
            "{what}[{i}]: got {g:e}, want {w:e}"
        );
    }
}

struct Fields {
    displacement: Vec<[f64; 2]>,
    velocity: Vec<[f64; 2]>,
    von_mises: Vec<f64>,
    det_f: Vec<f64>,
}

fn fields(np: usize, nc: usize) -> Fields {
    Fields {
        displacement: (0..np).map(|i| [awkward(i), awkward(i + 3)]).collect(),
        velocity: (0..np)
            .map(|i| [-awkward(i + 7), 0.5 * i as f64 + 0.1])
            .collect(),
        von_mises: (0..nc).map(|i| -awkward(i + 1)).collect(),
        det_f: (0..nc).map(|i| 1.0 + awkward(i) * 1e-3).collect(),
    }
}

fn frame<'a>(
    positions: &'a [[f64; 2]],
    triangles: &'a [[usize; 3]],
    f: &'a Fields,
) -> VtkFrame<'a> {
    VtkFrame {
        positions,
        triangles,
        point_data: vec![
            ("displacement", DataArray::Vectors(&f.displacement)),
            ("velocity", DataArray::Vectors(&f.velocity)),
        ],
        cell_data: vec![
            ("von_mises", DataArray::Scalars(&f.von_mises)),
            ("det_F", DataArray::Scalars(&f.det_f)),
        ],
        field_data: vec![],
    }
}

fn flatten3(v: &[[f64; 2]]) -> Vec<f64> {
    v.iter().flat_map(|p| [p[0], p[1], 0.0]).collect()
}

#[test]
fn round_trip_is_bit_exact() {
    let dir = fresh_dir("round_trip");
    let (mut positions, triangles) = grid(5, 4);
    // Awkward coordinates too.
    positions[1] = [0.1 + 0.2, -0.0];
    positions[2] = [1e-300, 1e300];
    let f = fields(positions.len(), triangles.len());
    let path = dir.join("mesh.vtu");
    write_vtu(&path, &frame(&positions, &triangles, &f)).unwrap();
    let data = read_vtu(&path).unwrap();

    assert_eq!(data.points.len(), positions.len());
    for (i, (p, q)) in data.points.iter().zip(&positions).enumerate() {
        assert_eq!(p[0].to_bits(), q[0].to_bits(), "point {i} x");
        assert_eq!(p[1].to_bits(), q[1].to_bits(), "point {i} y");
        assert_eq!(p[2].to_bits(), 0.0f64.to_bits(), "point {i} z");
    }
    let cells: Vec<Vec<usize>> = triangles.iter().map(|t| t.to_vec()).collect();
    assert_eq!(data.cells, cells);
    assert_eq!(data.cell_types, vec![5u8; triangles.len()]);

    let names: Vec<&str> = data.point_data.iter().map(|(n, _, _)| n.as_str()).collect();
    assert_eq!(names, ["displacement", "velocity"]);
    let names: Vec<&str> = data.cell_data.iter().map(|(n, _, _)| n.as_str()).collect();
    assert_eq!(names, ["von_mises", "det_F"]);

    let (c, v) = data.point_array("displacement").unwrap();
    assert_eq!(c, 3);
    assert_bits_eq("displacement", v, &flatten3(&f.displacement));
    let (c, v) = data.point_array("velocity").unwrap();
    assert_eq!(c, 3);
    assert_bits_eq("velocity", v, &flatten3(&f.velocity));
    let (c, v) = data.cell_array("von_mises").unwrap();
    assert_eq!(c, 1);
    assert_bits_eq("von_mises", v, &f.von_mises);
    let (c, v) = data.cell_array("det_F").unwrap();
    assert_eq!(c, 1);
    assert_bits_eq("det_F", v, &f.det_f);

    // Every awkward value actually went through the file.
    let all: Vec<u64> = v
        .iter()
        .chain(data.point_array("displacement").unwrap().1)
        .map(|x| x.to_bits())
        .collect();
    for a in AWKWARD {
        assert!(all.contains(&a.to_bits()), "{a:e} not exercised");
    }

    // The string form and the file agree.
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(
        text,
        vtu_string(&frame(&positions, &triangles, &f)).unwrap()
    );
    assert_eq!(parse_vtu(&text).unwrap(), data);
}

#[test]
fn empty_frame_round_trips() {
    let text = vtu_string(&VtkFrame::new(&[], &[])).unwrap();
    let data = parse_vtu(&text).unwrap();
    assert_eq!(
        data,
        VtuData {
            points: vec![],
            cells: vec![],
            cell_types: vec![],
            point_data: vec![],
            cell_data: vec![],
            field_data: vec![],
        }
    );
}

/// The single child element of `node` called `name`.
fn el<'a, 'i>(node: roxmltree::Node<'a, 'i>, name: &str) -> roxmltree::Node<'a, 'i> {
    let found: Vec<_> = node
        .children()
        .filter(|c| c.is_element() && c.tag_name().name() == name)
        .collect();
    assert_eq!(found.len(), 1, "exactly one <{name}>");
    found[0]
}

/// The `<DataArray>` children of `node`.
fn arrays<'a, 'i>(node: roxmltree::Node<'a, 'i>) -> Vec<roxmltree::Node<'a, 'i>> {
    node.children()
        .filter(|c| c.is_element() && c.tag_name().name() == "DataArray")
        .collect()
}

#[test]
fn written_file_matches_vtk_xml_structure() {
    let (positions, triangles) = grid(5, 4);
    let f = fields(positions.len(), triangles.len());
    let mut fr = frame(&positions, &triangles, &f);
    // The active scalar is the first scalar even when a vector comes first.
    let cell_vectors: Vec<[f64; 2]> = (0..triangles.len())
        .map(|i| [i as f64, -(i as f64)])
        .collect();
    fr.cell_data
        .insert(0, ("principal", DataArray::Vectors(&cell_vectors)));
    let text = vtu_string(&fr).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();

    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "VTKFile");
    assert_eq!(root.attribute("type"), Some("UnstructuredGrid"));
    assert!(root.attribute("version").is_some());
    assert_eq!(root.attribute("byte_order"), Some("LittleEndian"));

    let grid_el = el(root, "UnstructuredGrid");
    let piece = el(grid_el, "Piece");
    assert_eq!(
        piece.attribute("NumberOfPoints"),
        Some(positions.len().to_string().as_str())
    );
    assert_eq!(
        piece.attribute("NumberOfCells"),
        Some(triangles.len().to_string().as_str())
    );

    let tokens = |n: roxmltree::Node<'_, '_>| -> Vec<String> {
        n.text()
            .unwrap_or("")
            .split_whitespace()
            .map(str::to_owned)
            .collect()
    };

    let points = el(piece, "Points");
    let pa = arrays(points);
    assert_eq!(pa.len(), 1);
    assert_eq!(pa[0].attribute("NumberOfComponents"), Some("3"));
    assert_eq!(pa[0].attribute("type"), Some("Float64"));
    assert_eq!(pa[0].attribute("format"), Some("ascii"));
    assert_eq!(tokens(pa[0]).len(), 3 * positions.len());

    let cells = el(piece, "Cells");
    let by_name = |name: &str| {
        arrays(cells)
            .into_iter()
            .find(|a| a.attribute("Name") == Some(name))
            .unwrap_or_else(|| panic!("no {name} array"))
    };
    let conn = by_name("connectivity");
    assert_eq!(conn.attribute("type"), Some("Int64"));
    let conn_values: Vec<usize> = tokens(conn).iter().map(|t| t.parse().unwrap()).collect();
    let want: Vec<usize> = triangles.iter().flatten().copied().collect();
    assert_eq!(conn_values, want);
    let offsets = by_name("offsets");
    assert_eq!(offsets.attribute("type"), Some("Int64"));
    let offsets: Vec<usize> = tokens(offsets).iter().map(|t| t.parse().unwrap()).collect();
    let want: Vec<usize> = (1..=triangles.len()).map(|i| 3 * i).collect();
    assert_eq!(offsets, want);
    let types = by_name("types");
    assert_eq!(types.attribute("type"), Some("UInt8"));
    assert_eq!(tokens(types), vec!["5".to_owned(); triangles.len()]);

    let point_data = el(piece, "PointData");
    assert_eq!(point_data.attribute("Vectors"), Some("displacement"));
    assert_eq!(point_data.attribute("Scalars"), None);
    for a in arrays(point_data) {
        assert_eq!(a.attribute("NumberOfComponents"), Some("3"));
        assert_eq!(a.attribute("type"), Some("Float64"));
        let t = tokens(a);
        assert_eq!(t.len(), 3 * positions.len());
        // z components are zero.
        assert!(t.iter().skip(2).step_by(3).all(|z| z == "0"));
    }
    let cell_data = el(piece, "CellData");
    assert_eq!(cell_data.attribute("Scalars"), Some("von_mises"));
    assert_eq!(cell_data.attribute("Vectors"), Some("principal"));
    let names: Vec<_> = arrays(cell_data)
        .iter()
        .map(|a| a.attribute("Name").unwrap())
        .collect();
    assert_eq!(names, ["principal", "von_mises", "det_F"]);
    for a in arrays(cell_data) {
        let comps: usize = a.attribute("NumberOfComponents").unwrap().parse().unwrap();
        assert_eq!(tokens(a).len(), comps * triangles.len());
        assert_eq!(
            comps,
            if a.attribute("Name") == Some("principal") {
                3
            } else {
                1
            }
        );
    }
}

#[test]
fn pvd_writer_writes_frames_and_collection() {
    let dir = fresh_dir("pvd").join("nested/out");
    let (positions, triangles) = grid(3, 3);
    let f = fields(positions.len(), triangles.len());
    let mut writer = PvdWriter::new(&dir, "run").unwrap();
    assert!(dir.is_dir(), "new creates the directory");
    assert!(writer.is_empty());
    let times = [0.0, 0.1, 0.2];
    let mut written = Vec::new();
    for (k, &t) in times.iter().enumerate() {
        // Move the mesh a little per frame so frames differ.
        let moved: Vec<[f64; 2]> = positions.iter().map(|p| [p[0] + t, p[1]]).collect();
        let path = writer.add(t, &frame(&moved, &triangles, &f)).unwrap();
        assert_eq!(path, dir.join(format!("run_{k:06}.vtu")));
        assert!(path.is_file());
        written.push(path);
        assert_eq!(writer.len(), k + 1);
    }
    let pvd = writer.finish().unwrap();
    assert_eq!(pvd, dir.join("run.pvd"));

    let entries = read_pvd(&pvd).unwrap();
    assert_eq!(entries.len(), 3);
    for (k, ((t, path), want_t)) in entries.iter().zip(times).enumerate() {
        assert_eq!(t.to_bits(), want_t.to_bits(), "time of frame {k}");
        assert_eq!(path, &written[k]);
        let data = read_vtu(path).unwrap();
        assert_eq!(
            data.points[4][0].to_bits(),
            (positions[4][0] + want_t).to_bits()
        );
        assert_eq!(data.cells.len(), triangles.len());
    }

    // File names in the .pvd are relative to its directory.
    let text = std::fs::read_to_string(&pvd).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let root = doc.root_element();
    assert_eq!(root.attribute("type"), Some("Collection"));
    assert_eq!(root.attribute("version"), Some("0.1"));
    let files: Vec<_> = doc
        .descendants()
        .filter(|n| n.has_tag_name("DataSet"))
        .map(|n| {
            assert_eq!(n.attribute("group"), Some(""));
            assert_eq!(n.attribute("part"), Some("0"));
            n.attribute("file").unwrap().to_owned()
        })
        .collect();
    assert_eq!(
        files,
        ["run_000000.vtu", "run_000001.vtu", "run_000002.vtu"]
    );
}

#[test]
fn pvd_can_be_rewritten_during_a_run() {
    let dir = fresh_dir("pvd_rewrite");
    let (positions, triangles) = grid(2, 2);
    let fr = VtkFrame::new(&positions, &triangles);
    let mut writer = PvdWriter::new(&dir, "series").unwrap();
    writer.add(0.0, &fr).unwrap();
    let pvd = writer.write_pvd().unwrap();
    assert_eq!(read_pvd(&pvd).unwrap().len(), 1);
    writer.add(0.5, &fr).unwrap();
    writer.add(0.5, &fr).unwrap(); // equal times are allowed
    assert_eq!(writer.write_pvd().unwrap(), pvd);
    assert_eq!(read_pvd(&pvd).unwrap().len(), 3);
    writer.add(1.0, &fr).unwrap();
    let pvd2 = writer.finish().unwrap();
    assert_eq!(pvd2, pvd);
    let times: Vec<f64> = read_pvd(&pvd)
        .unwrap()
        .into_iter()
        .map(|(t, _)| t)
        .collect();
    assert_eq!(times, [0.0, 0.5, 0.5, 1.0]);
}

#[test]
fn rejects_triangle_index_out_of_range() {
    let (positions, mut triangles) = grid(3, 3);
    triangles[5][1] = 9;
    let m = input_message(vtu_string(&VtkFrame::new(&positions, &triangles)));
    assert!(
        m.contains("triangle 5") && m.contains('9') && m.contains("9 points"),
        "{m}"
    );
}

#[test]
fn rejects_array_length_mismatch() {
    let (positions, triangles) = grid(3, 3); // 9 points, 8 triangles
    let short = vec![[0.0, 0.0]; 8];
    let mut fr = VtkFrame::new(&positions, &triangles);
    fr.point_data.push(("velocity", DataArray::Vectors(&short)));
    let m = input_message(vtu_string(&fr));
    assert!(
        m.contains("\"velocity\"") && m.contains('8') && m.contains("9 points"),
        "{m}"
    );

    let long = vec![0.0; 9];
    let mut fr = VtkFrame::new(&positions, &triangles);
    fr.cell_data.push(("von_mises", DataArray::Scalars(&long)));
    let m = input_message(vtu_string(&fr));
    assert!(
        m.contains("\"von_mises\"") && m.contains('9') && m.contains("8 cells"),
        "{m}"
    );
}

#[test]
fn rejects_empty_and_duplicate_names() {
    let (positions, triangles) = grid(3, 3);
    let s = vec![1.0; triangles.len()];
    let mut fr = VtkFrame::new(&positions, &triangles);
    fr.cell_data.push(("a", DataArray::Scalars(&s)));
    fr.cell_data.push(("", DataArray::Scalars(&s)));
    let m = input_message(vtu_string(&fr));
    assert!(
        m.contains("empty name") && m.contains("cell data array 1"),
        "{m}"
    );

    let mut fr = VtkFrame::new(&positions, &triangles);
    fr.cell_data.push(("det_F", DataArray::Scalars(&s)));
    fr.cell_data.push(("det_F", DataArray::Scalars(&s)));
    let m = input_message(vtu_string(&fr));
    assert!(
        m.contains("\"det_F\"") && m.contains("more than once"),
        "{m}"
    );

    // The same name in point data and cell data is fine (VTK keeps them apart).
    let p = vec![1.0; positions.len()];
    let mut fr = VtkFrame::new(&positions, &triangles);
    fr.point_data.push(("det_F", DataArray::Scalars(&p)));
    fr.cell_data.push(("det_F", DataArray::Scalars(&s)));
    vtu_string(&fr).unwrap();
}

#[test]
fn rejects_names_that_break_xml() {
    let (positions, triangles) = grid(3, 3);
    let p = vec![1.0; positions.len()];
    for name in ["a\"b", "a'b", "a<b", "a>b", "a&b", "a\nb"] {
        let mut fr = VtkFrame::new(&positions, &triangles);
        fr.point_data.push((name, DataArray::Scalars(&p)));
        let m = input_message(vtu_string(&fr));
        assert!(m.contains(&format!("{name:?}")), "{name:?}: {m}");
    }
    // Spaces and non-ASCII letters are fine.
    let mut fr = VtkFrame::new(&positions, &triangles);
    fr.point_data.push(("σ von Mises", DataArray::Scalars(&p)));
    let data = parse_vtu(&vtu_string(&fr).unwrap()).unwrap();
    assert_eq!(data.point_data[0].0, "σ von Mises");
}

#[test]
fn rejects_non_finite_values() {
    let (mut positions, triangles) = grid(3, 3);
    let mut s = vec![1.0; triangles.len()];
    s[3] = f64::NAN;
    let mut fr = VtkFrame::new(&positions, &triangles);
    fr.cell_data.push(("von_mises", DataArray::Scalars(&s)));
    let m = input_message(vtu_string(&fr));
    assert!(
        m.contains("\"von_mises\"") && m.contains("entry 3") && m.contains("NaN"),
        "{m}"
    );

    let mut v = vec![[0.0, 0.0]; positions.len()];
    v[2][1] = f64::INFINITY;
    let mut fr = VtkFrame::new(&positions, &triangles);
    fr.point_data.push(("velocity", DataArray::Vectors(&v)));
    let m = input_message(vtu_string(&fr));
    assert!(
        m.contains("\"velocity\"") && m.contains("entry 2") && m.contains("inf"),
        "{m}"
    );

    positions[4][0] = f64::NEG_INFINITY;
    let m = input_message(vtu_string(&VtkFrame::new(&positions, &triangles)));
    assert!(m.contains("position 4") && m.contains("-inf"), "{m}");
}

#[test]
fn pvd_writer_rejects_non_finite_and_decreasing_times() {
    let dir = fresh_dir("pvd_times");
    let (positions, triangles) = grid(2, 2);
    let fr = VtkFrame::new(&positions, &triangles);
    let mut writer = PvdWriter::new(&dir, "t").unwrap();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let m = input_message(writer.add(bad, &fr));
        assert!(m.contains("not finite"), "{m}");
    }
    assert!(writer.is_empty());
    writer.add(1.0, &fr).unwrap();
    let m = input_message(writer.add(0.5, &fr));
    assert!(
        m.contains("0.5") && m.contains('1') && m.contains("before"),
        "{m}"
    );
    assert_eq!(writer.len(), 1, "a rejected frame is not recorded");

    // A frame that fails validation is not recorded and no file is written for it.
    let short = [1.0];
    let mut bad = VtkFrame::new(&positions, &triangles);
    bad.cell_data.push(("s", DataArray::Scalars(&short)));
    let m = input_message(writer.add(2.0, &bad));
    assert!(m.contains("frame 1") && m.contains("\"s\""), "{m}");
    assert_eq!(writer.len(), 1);
    assert!(!dir.join("t_000001.vtu").exists());
    assert_eq!(writer.add(2.0, &fr).unwrap(), dir.join("t_000001.vtu"));

    // pvd_string checks too.
    let m = input_message(pvd_string(&[(f64::NAN, "a.vtu")]));
    assert!(m.contains("not finite"), "{m}");
}

#[test]
fn pvd_writer_rejects_bad_stems() {
    let dir = fresh_dir("pvd_stems");
    for stem in ["", ".", "..", "a/b", "a\\b", "a\"b", "a<b", "a&b"] {
        let m = input_message(PvdWriter::new(&dir, stem));
        assert!(m.contains(&format!("{stem:?}")), "{stem:?}: {m}");
    }
    PvdWriter::new(&dir, "run-1.v2 final").unwrap();
}

#[test]
fn corrupted_vtu_gives_parse_error_naming_the_file() {
    let dir = fresh_dir("corrupted");
    let (positions, triangles) = grid(3, 3);
    let f = fields(positions.len(), triangles.len());
    let text = vtu_string(&frame(&positions, &triangles, &f)).unwrap();

    // Truncated.
    let path = dir.join("truncated.vtu");
    std::fs::write(&path, &text[..text.len() / 2]).unwrap();
    let (p, m) = parse_error(read_vtu(&path));
    assert_eq!(p, path);
    assert!(m.contains("XML"), "{m}");
    let err = read_vtu(&path).unwrap_err().to_string();
    assert!(err.contains("truncated.vtu"), "{err}");

    // A non-numeric token in a data array.
    let path = dir.join("token.vtu");
    let start = text.find("Name=\"velocity\"").unwrap();
    let first_line = start + text[start..].find('\n').unwrap() + 1;
    let mut bad = text.clone();
    bad.insert_str(first_line, "1.5x ");
    std::fs::write(&path, &bad).unwrap();
    let (p, m) = parse_error(read_vtu(&path));
    assert_eq!(p, path);
    assert!(m.contains("\"velocity\"") && m.contains("\"1.5x\""), "{m}");
    assert!(
        read_vtu(&path)
            .unwrap_err()
            .to_string()
            .contains("token.vtu")
    );

    // A non-numeric token in the connectivity.
    let start = text.find("Name=\"connectivity\"").unwrap();
    let first_line = start + text[start..].find('\n').unwrap() + 1;
    let mut bad = text.clone();
    bad.replace_range(first_line..first_line + 1, "z");
    let m = parse_vtu(&bad).unwrap_err();
    assert!(m.contains("connectivity") && m.contains("\"z\""), "{m}");

    // One value too many.
    let mut bad = text.clone();
    bad.insert_str(first_line_of(&text, "Name=\"det_F\""), "1 ");
    let m = parse_vtu(&bad).unwrap_err();
    assert!(
        m.contains("\"det_F\"") && m.contains("expected 8") && m.contains("found 9"),
        "{m}"
    );

    // Not UTF-8.
    let path = dir.join("binary.vtu");
    std::fs::write(&path, [0xff, 0xfe, 0x00]).unwrap();
    let (p, _) = parse_error(read_vtu(&path));
    assert_eq!(p, path);

    // Missing file.
    let path = dir.join("missing.vtu");
    match read_vtu(&path) {
        Err(RenderError::Io { path: p, .. }) => assert_eq!(p, path),
        other => panic!("expected an Io error, got {other:?}"),
    }
}

fn first_line_of(text: &str, marker: &str) -> usize {
    let start = text.find(marker).unwrap();
    start + text[start..].find('\n').unwrap() + 1
}

#[test]
fn parse_vtu_reports_missing_elements_and_attributes() {
    let (positions, triangles) = grid(3, 3);
    let text = vtu_string(&VtkFrame::new(&positions, &triangles)).unwrap();
    let cases = [
        (
            text.replace("type=\"UnstructuredGrid\"", "type=\"PolyData\""),
            "PolyData",
        ),
        (text.replace("NumberOfPoints=\"9\"", ""), "NumberOfPoints"),
        (
            text.replace("NumberOfCells=\"8\"", "NumberOfCells=\"x\""),
            "NumberOfCells",
        ),
        (
            text.replace("NumberOfPoints=\"9\"", "NumberOfPoints=\"10\""),
            "expected 30",
        ),
        (
            text.replace("<Points>", "<Pts>")
                .replace("</Points>", "</Pts>"),
            "<Points>",
        ),
        (text.replace("Name=\"offsets\"", "Name=\"offs\""), "offsets"),
        (
            text.replace("format=\"ascii\"", "format=\"binary\""),
            "binary",
        ),
        (text.replace("\n5 ", "\n300 "), "\"300\""),
        (text.replace(" 8\n", " 80\n"), "80"),
        ("<VTKFile/>".to_owned(), "type"),
        ("<Other/>".to_owned(), "<Other>"),
        ("not xml".to_owned(), "invalid XML"),
    ];
    for (xml, needle) in cases {
        let m = parse_vtu(&xml).unwrap_err();
        assert!(m.contains(needle), "want {needle:?} in {m:?}");
    }
}

#[test]
fn reads_a_simple_vtu_from_another_writer() {
    // Float32 points, Int32 connectivity, a quad among the cells, no NumberOfComponents on a
    // scalar, no format attribute on one array, a comment, no XML declaration.
    let xml = r#"<VTKFile type="UnstructuredGrid" version="0.1">
  <UnstructuredGrid>
    <Piece NumberOfPoints="5" NumberOfCells="2">
      <!-- made by hand -->
      <Points>
        <DataArray type="Float32" NumberOfComponents="3" format="ascii">
          0 0 0  1 0 0  1 1 0  0 1 0  2 0.5 0
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int32" Name="types" format="ascii">9 5</DataArray>
        <DataArray type="Int32" Name="connectivity">0 1 2 3 1 4 2</DataArray>
        <DataArray type="Int32" Name="offsets" format="ascii">4 7</DataArray>
      </Cells>
      <CellData>
        <DataArray type="Float32" Name="p" format="ascii">1.5 -2E+3</DataArray>
      </CellData>
    </Piece>
  </UnstructuredGrid>
</VTKFile>"#;
    let data = parse_vtu(xml).unwrap();
    assert_eq!(data.points.len(), 5);
    assert_eq!(data.points[4], [2.0, 0.5, 0.0]);
    assert_eq!(data.cells, vec![vec![0, 1, 2, 3], vec![1, 4, 2]]);
    assert_eq!(data.cell_types, vec![9, 5]);
    assert!(data.point_data.is_empty());
    assert_eq!(
        data.cell_data,
        vec![("p".to_owned(), 1, vec![1.5, -2000.0])]
    );
}

#[test]
fn read_pvd_errors_and_absolute_paths() {
    let dir = fresh_dir("pvd_read");
    let abs = dir.join("elsewhere.vtu");
    let good = pvd_string(&[(0.25, "a/b.vtu"), (0.5, abs.to_str().unwrap())]).unwrap();
    let path = dir.join("good.pvd");
    std::fs::write(&path, &good).unwrap();
    let entries = read_pvd(&path).unwrap();
    assert_eq!(entries, vec![(0.25, dir.join("a/b.vtu")), (0.5, abs)]);

    for (text, needle) in [
        (
            good.replace("timestep=\"0.25\"", "timestep=\"soon\""),
            "\"soon\"",
        ),
        (good.replace("timestep=\"0.25\"", ""), "timestep"),
        (good.replace("file=\"a/b.vtu\"", ""), "file"),
        (
            good.replace("Collection\"", "UnstructuredGrid\""),
            "Collection",
        ),
        (good[..good.len() - 20].to_owned(), "XML"),
    ] {
        std::fs::write(&path, &text).unwrap();
        let (p, m) = parse_error(read_pvd(&path));
        assert_eq!(p, path);
        assert!(m.contains(needle), "want {needle:?} in {m:?}");
    }
}

#[test]
fn no_temporary_files_left_behind() {
    let dir = fresh_dir("no_tmp");
    let (positions, triangles) = grid(4, 4);
    let f = fields(positions.len(), triangles.len());
    write_vtu(&dir.join("single.vtu"), &frame(&positions, &triangles, &f)).unwrap();
    // Overwriting an existing file works and leaves nothing behind either.
    write_vtu(&dir.join("single.vtu"), &frame(&positions, &triangles, &f)).unwrap();
    let mut writer = PvdWriter::new(&dir, "run").unwrap();
    for k in 0..3 {
        writer
            .add(k as f64, &frame(&positions, &triangles, &f))
            .unwrap();
    }
    writer.write_pvd().unwrap();
    writer.finish().unwrap();
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "run.pvd",
            "run_000000.vtu",
            "run_000001.vtu",
            "run_000002.vtu",
            "single.vtu"
        ]
    );
}

#[test]
fn large_frame_round_trips() {
    let (positions, triangles) = grid(72, 72); // 10 082 triangles
    assert!(triangles.len() >= 10_000);
    let f = fields(positions.len(), triangles.len());
    let fr = frame(&positions, &triangles, &f);
    let dir = fresh_dir("large");
    let path = dir.join("large.vtu");
    write_vtu(&path, &fr).unwrap();
    let data = read_vtu(&path).unwrap();
    assert_eq!(data.cells.len(), triangles.len());
    assert_bits_eq("det_F", data.cell_array("det_F").unwrap().1, &f.det_f);
}

/// Region tags as `UInt32` cell data and their names as `FieldData` string arrays, in the form
/// VTK itself writes (each string's bytes, then 0), read back exactly; the active scalar stays
/// the first `Float64` scalar.
#[test]
fn tags_and_field_strings_round_trip_in_vtk_form() {
    let (positions, triangles) = grid(4, 3);
    let f = fields(positions.len(), triangles.len());
    let tags: Vec<u32> = (0..triangles.len() as u32).map(|t| t % 3).collect();
    let names = ["soft-tissue".to_owned(), "bone".to_owned(), String::new()];
    let mut fr = frame(&positions, &triangles, &f);
    fr.cell_data.push(("region", DataArray::Tags(&tags)));
    fr.field_data.push(("region_names", &names));
    let text = vtu_string(&fr).unwrap();

    let doc = roxmltree::Document::parse(&text).unwrap();
    let grid_el = el(doc.root_element(), "UnstructuredGrid");
    let field = el(grid_el, "FieldData");
    let array = el(field, "Array");
    assert_eq!(array.attribute("type"), Some("String"));
    assert_eq!(array.attribute("Name"), Some("region_names"));
    assert_eq!(array.attribute("NumberOfTuples"), Some("3"));
    assert_eq!(array.attribute("format"), Some("ascii"));
    let codes: Vec<u8> = array
        .text()
        .unwrap()
        .split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect();
    assert_eq!(codes, b"soft-tissue\0bone\0\0");
    let cell_data = el(el(grid_el, "Piece"), "CellData");
    assert_eq!(cell_data.attribute("Scalars"), Some("von_mises"));
    let region = arrays(cell_data)
        .into_iter()
        .find(|a| a.attribute("Name") == Some("region"))
        .unwrap();
    assert_eq!(region.attribute("type"), Some("UInt32"));
    assert_eq!(region.attribute("NumberOfComponents"), Some("1"));

    let data = parse_vtu(&text).unwrap();
    let want: Vec<f64> = tags.iter().map(|&t| t as f64).collect();
    assert_eq!(data.cell_array("region"), Some((1, want.as_slice())));
    assert_eq!(data.field_strings("region_names"), Some(names.as_slice()));
    assert_eq!(data.field_strings("missing"), None);
}

/// The tags and field strings add their own elements and change nothing else: a frame
/// without them is written exactly as before they existed.
#[test]
fn frame_without_tags_or_field_strings_is_unchanged_by_them() {
    let (positions, triangles) = grid(3, 2);
    let f = fields(positions.len(), triangles.len());
    let plain = vtu_string(&frame(&positions, &triangles, &f)).unwrap();
    assert!(!plain.contains("FieldData") && !plain.contains("UInt32"));
    let tags = vec![7u32; triangles.len()];
    let names = ["a".to_owned()];
    let mut fr = frame(&positions, &triangles, &f);
    fr.cell_data.push(("region", DataArray::Tags(&tags)));
    fr.field_data.push(("region_names", &names));
    let with = vtu_string(&fr).unwrap();
    // Remove the FieldData block and the region array: what is left is the plain text.
    let cut = |text: &str, start: &str, end: &str| -> String {
        let a = text.find(start).unwrap();
        let b = a + text[a..].find(end).unwrap() + end.len();
        format!("{}{}", &text[..a], &text[b..])
    };
    let stripped = cut(&with, "    <FieldData>\n", "    </FieldData>\n");
    let stripped = cut(
        &stripped,
        "        <DataArray type=\"UInt32\" Name=\"region\"",
        "        </DataArray>\n",
    );
    assert_eq!(stripped, plain);
}

#[test]
fn rejects_bad_field_strings() {
    let (positions, triangles) = grid(2, 2);
    let bad = ["ok".to_owned(), "nul\0inside".to_owned()];
    let mut fr = VtkFrame::new(&positions, &triangles);
    fr.field_data.push(("names", &bad));
    let m = input_message(vtu_string(&fr));
    assert!(
        m.contains("\"names\"") && m.contains("entry 1") && m.contains("NUL"),
        "{m}"
    );

    let good = ["a".to_owned()];
    let mut fr = VtkFrame::new(&positions, &triangles);
    fr.field_data.push(("names", &good));
    fr.field_data.push(("names", &good));
    let m = input_message(vtu_string(&fr));
    assert!(m.contains("more than once"), "{m}");

    // A string array whose count disagrees with its strings is a parse error.
    let text = vtu_string(&VtkFrame {
        field_data: vec![("names", &good)],
        ..VtkFrame::new(&positions, &triangles)
    })
    .unwrap()
    .replace("NumberOfTuples=\"1\"", "NumberOfTuples=\"2\"");
    let e = parse_vtu(&text).unwrap_err();
    assert!(
        e.contains("NumberOfTuples=2") && e.contains("1 strings"),
        "{e}"
    );
}
