//! Mesh files: small snapshot tests of the mesh JSON, Gmsh and VTK text,
//! round trips, the reader's validation errors, atomic writes, and property tests feeding the
//! mesh JSON reader arbitrary and mutated bytes (an error, never a panic).

use std::path::Path;

use fem_mesh::Mesh2;
use fem_mesh::io::{
    mesh_to_gmsh, mesh_to_json, mesh_to_vtk, parse_mesh_json, read_mesh_json, write_mesh_json,
};
use proptest::prelude::*;

/// Two unit cells side by side, each split along its `/` diagonal.
fn two_cells() -> Mesh2 {
    Mesh2 {
        vertices: vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [2.0, 0.0],
            [0.0, 1.0],
            [1.0, 1.0],
            [2.0, 1.0],
        ],
        triangles: vec![[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]],
    }
}

#[test]
fn snapshot_rectangle_mesh_json() {
    let expected = r#"{
  "vertices": [
    [0.0,0.0],
    [1.0,0.0],
    [2.0,0.0],
    [0.0,1.0],
    [1.0,1.0],
    [2.0,1.0]
  ],
  "triangles": [
    [0,1,4],
    [0,4,3],
    [1,2,5],
    [1,5,4]
  ]
}
"#;
    assert_eq!(mesh_to_json(&two_cells()), expected);
}

#[test]
fn snapshot_gmsh_and_vtk() {
    let mesh = Mesh2 {
        vertices: vec![[0.0, 0.0], [1.5, 0.0], [0.0, 0.25]],
        triangles: vec![[0, 1, 2]],
    };
    let gmsh = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0.0 0.0 0\n2 1.5 0.0 0\n\
                3 0.0 0.25 0\n$EndNodes\n$Elements\n1\n1 2 2 1 1 1 2 3\n$EndElements\n";
    assert_eq!(mesh_to_gmsh(&mesh), gmsh);
    let vtk = "# vtk DataFile Version 3.0\nfem2d mesh\nASCII\nDATASET UNSTRUCTURED_GRID\n\
               POINTS 3 double\n0.0 0.0 0\n1.5 0.0 0\n0.0 0.25 0\nCELLS 1 4\n3 0 1 2\n\
               CELL_TYPES 1\n5\n";
    assert_eq!(mesh_to_vtk(&mesh), vtk);
}

#[test]
fn json_round_trip_is_exact_and_atomic() {
    let dir = std::env::temp_dir().join(format!("fem-mesh-files-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("mesh.json");
    // Coordinates with no short decimal form, which the writer must round-trip exactly.
    let mut mesh = two_cells();
    for p in &mut mesh.vertices {
        *p = [0.1 + p[0] / 3.0, -0.3 + 0.7 * p[1]];
    }
    write_mesh_json(&path, &mesh).unwrap();
    assert_eq!(read_mesh_json(&path).unwrap(), mesh);
    // No temporary file left behind.
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "{names:?}");
    // Writing into a missing directory fails cleanly.
    assert!(write_mesh_json(&dir.join("missing").join("m.json"), &mesh).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn reader_errors_name_the_entry() {
    let p = Path::new("m.json");
    let cases: [(&str, &str); 7] = [
        (
            r#"{"vertices": [[0,0],[1,0],[0,1]], "triangles": [[0,1,3]]}"#,
            "triangle 0",
        ),
        (
            r#"{"vertices": [[0,0],[1,0],[0,1]], "triangles": [[0,2,1]]}"#,
            "clockwise",
        ),
        (
            r#"{"vertices": [[0,0],[1,0],[0,1]], "triangles": [[0,1,1]]}"#,
            "repeated",
        ),
        (
            r#"{"vertices": [[0,0],[1,0],[0,1]], "triangles": []}"#,
            "no triangle",
        ),
        (
            r#"{"vertices": [[0,0],[1,0],[0,1e999]], "triangles": [[0,1,2]]}"#,
            "m.json: line 1",
        ),
        (r#"{"vertices": [[0,0],[1,0]]}"#, "triangles"),
        ("", "line 1"),
    ];
    for (text, needle) in cases {
        let e = parse_mesh_json(text.as_bytes(), p).unwrap_err().to_string();
        assert!(
            e.starts_with("m.json: ") && e.contains(needle),
            "{text} -> {e}"
        );
        assert!(!e.contains('\n'), "one line: {e}");
    }
    // Extra keys are ignored.
    let ok = r#"{"vertices": [[0,0],[1,0],[0,1]], "triangles": [[0,1,2]], "units": "m"}"#;
    assert_eq!(
        parse_mesh_json(ok.as_bytes(), p).unwrap().triangles.len(),
        1
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn json_reader_never_panics_on_junk(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = parse_mesh_json(&bytes, Path::new("junk.json"));
    }

    #[test]
    fn json_reader_never_panics_on_mutations(
        cut in 0usize..400,
        flips in proptest::collection::vec((0usize..400, any::<u8>()), 0..4),
    ) {
        let mut bytes = mesh_to_json(&two_cells()).into_bytes();
        for (at, b) in flips {
            let n = bytes.len();
            bytes[at % n] = b;
        }
        bytes.truncate(cut.min(bytes.len()));
        let _ = parse_mesh_json(&bytes, Path::new("mutated.json"));
    }
}
