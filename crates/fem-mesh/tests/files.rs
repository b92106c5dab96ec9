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
        ..Mesh2::default()
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
        ..Mesh2::default()
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

/// [`two_cells`] with its left cell in region 0 ("soft-tissue") and its right cell in region 1
/// ("bone").
fn two_regions() -> Mesh2 {
    Mesh2 {
        regions: vec![0, 0, 1, 1],
        region_names: vec!["soft-tissue".into(), "bone".into()],
        ..two_cells()
    }
}

#[test]
fn region_tags_round_trip_through_json_and_untagged_json_is_unchanged() {
    let mesh = two_regions();
    let text = mesh_to_json(&mesh);
    assert!(text.contains("\"regions\": [0,0,1,1]"), "{text}");
    assert!(
        text.contains("\"region_names\": [\"soft-tissue\",\"bone\"]"),
        "{text}"
    );
    let back = parse_mesh_json(text.as_bytes(), Path::new("regions.json")).unwrap();
    assert_eq!(back, mesh);
    assert_eq!(back.region_of(2), 1);
    assert_eq!(back.region_index("bone"), Some(1));
    assert_eq!(back.region_count(), 2);
    // Each cell is 1 m^2.
    assert!((back.region_area(0) - 1.0).abs() < 1e-15);
    assert!((back.region_area(1) - 1.0).abs() < 1e-15);
    assert_eq!(back.region_components(1), 1);
    // No tags: no extra keys, and every triangle is region 0.
    let plain = mesh_to_json(&two_cells());
    assert!(!plain.contains("regions"), "{plain}");
    let plain = parse_mesh_json(plain.as_bytes(), Path::new("plain.json")).unwrap();
    assert_eq!(plain.region_of(3), 0);
    assert!((plain.region_area(0) - 2.0).abs() < 1e-15);
}

#[test]
fn region_tags_reach_gmsh_physical_tags_and_vtk_cell_data() {
    let mesh = two_regions();
    let gmsh = mesh_to_gmsh(&mesh);
    assert!(
        gmsh.contains("$PhysicalNames\n2\n2 1 \"soft-tissue\"\n2 2 \"bone\"\n$EndPhysicalNames\n"),
        "{gmsh}"
    );
    // Element lines: number, type 2, two tags (physical, elementary), nodes.
    assert!(gmsh.contains("\n2 2 2 1 1 1 5 4\n"), "{gmsh}");
    assert!(gmsh.contains("\n3 2 2 2 2 2 3 6\n"), "{gmsh}");
    let vtk = mesh_to_vtk(&mesh);
    assert!(
        vtk.ends_with("CELL_DATA 4\nSCALARS region int 1\nLOOKUP_TABLE default\n0\n0\n1\n1\n"),
        "{vtk}"
    );
    // Untagged exports carry neither.
    assert!(!mesh_to_gmsh(&two_cells()).contains("PhysicalNames"));
    assert!(!mesh_to_vtk(&two_cells()).contains("CELL_DATA"));
}

#[test]
fn bad_region_tags_are_one_line_errors_naming_the_key_and_value() {
    let base = mesh_to_json(&two_cells());
    let with = |extra: &str| base.replacen("\n  ]\n}", &format!("\n  ],\n  {extra}\n}}"), 1);
    let cases = [
        (
            with("\"regions\": [0, 1]"),
            "regions: 2 region tags for 4 triangles",
        ),
        (
            with("\"regions\": [0, 0, 0, 3], \"region_names\": [\"a\", \"b\"]"),
            "regions[3]: tag 3 has no name (2 region_names)",
        ),
        // serde names the line and the value of a negative tag.
        (
            with("\"regions\": [0, 0, -1, 0]"),
            "integer `-1`, expected u32",
        ),
    ];
    for (text, expected) in cases {
        let err = parse_mesh_json(text.as_bytes(), Path::new("m.json"))
            .unwrap_err()
            .to_string();
        assert!(err.contains(expected), "{err} should contain {expected}");
        assert_eq!(err.lines().count(), 1, "{err}");
    }
    // Tags without names are fine (any non-negative tag).
    let text = with("\"regions\": [0, 4, 4, 0]");
    let mesh = parse_mesh_json(text.as_bytes(), Path::new("m.json")).unwrap();
    assert_eq!(mesh.region_count(), 5);
}

/// `region_names` `["b", "b"]` was accepted, and a scene's `mesh_regions = ["b"]` then took
/// both tags; an empty name or one with a line break (which would split a one-line message or
/// a Gmsh name) was accepted too. Each is an error naming the file, the key and the name.
#[test]
fn repeated_empty_or_unprintable_region_names_are_errors_naming_the_file_and_the_name() {
    let base = mesh_to_json(&two_cells());
    let with = |names: &str| {
        base.replacen(
            "\n  ]\n}",
            &format!("\n  ],\n  \"regions\": [0, 0, 1, 1], \"region_names\": {names}\n}}"),
            1,
        )
    };
    let cases = [
        (
            r#"["b", "b"]"#,
            r#"m.json: region_names[1]: "b" is given twice (also region_names[0]); each region needs its own name"#,
        ),
        (
            r#"["", "b"]"#,
            r#"m.json: region_names[0]: "" must be non-empty, without commas, double quotes or control characters (line breaks, tabs)"#,
        ),
        (
            r#"["a", "x\ny"]"#,
            r#"m.json: region_names[1]: "x\ny" must be non-empty, without commas"#,
        ),
        (
            r#"["a,b", "c"]"#,
            r#"m.json: region_names[0]: "a,b" must be"#,
        ),
        (
            r#"["a", "q\"q"]"#,
            r#"m.json: region_names[1]: "q\"q" must be"#,
        ),
    ];
    for (names, expected) in cases {
        let err = parse_mesh_json(with(names).as_bytes(), Path::new("m.json"))
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with(expected),
            "{err} should start with {expected}"
        );
        assert_eq!(err.lines().count(), 1, "{err}");
    }
    parse_mesh_json(
        with(r#"["soft tissue", "bone (tibia)"]"#).as_bytes(),
        Path::new("m.json"),
    )
    .unwrap();
    // Unnamed tags are bounded: a tag of four billion would make a reader name four billion
    // regions.
    let huge = base.replacen(
        "\n  ]\n}",
        "\n  ],\n  \"regions\": [0, 0, 0, 4000000000]\n}",
        1,
    );
    let err = parse_mesh_json(huge.as_bytes(), Path::new("m.json"))
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with(
            "m.json: regions[3]: tag 4000000000: without region_names tags must be below 65536"
        ),
        "{err}"
    );
}

/// A UTF-8 byte-order mark, which some editors write first, is skipped (before: "invalid
/// JSON" at line 1 column 1).
#[test]
fn a_byte_order_mark_before_mesh_json_is_skipped() {
    let text = mesh_to_json(&two_regions());
    let mut bytes = b"\xEF\xBB\xBF".to_vec();
    bytes.extend_from_slice(text.as_bytes());
    assert_eq!(
        parse_mesh_json(&bytes, Path::new("bom.json")).unwrap(),
        two_regions()
    );
}
