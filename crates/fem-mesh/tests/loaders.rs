//! Model loaders (OBJ, STL, PLY): valid files load with the right counts, group selection works,
//! malformed files are one-line errors naming the file and the line or element, and property
//! tests feed arbitrary and mutated bytes (truncations, junk, huge counts) expecting an error or a
//! result, never a panic or an unbounded allocation.

use std::path::Path;

use fem_mesh::load::{LoadOptions, load_model, parse_obj, parse_ply, parse_stl};
use proptest::prelude::*;

const OBJ: &str = "# two groups\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 5 5 5\nv 6 5 5\nv 5 6 5\n\
                   g body\nf 1/1 2/2 3/3 4/4\ng helper\nf -3 -2 -1\n";

fn stl_ascii() -> String {
    "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n\
     endfacet\nfacet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\n\
     endfacet\nendsolid t\n"
        .to_string()
}

fn stl_binary(triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend((triangles.len() as u32).to_le_bytes());
    for t in triangles {
        b.extend([0u8; 12]);
        for v in t {
            for c in v {
                b.extend(c.to_le_bytes());
            }
        }
        b.extend([0u8; 2]);
    }
    b
}

const PLY_ASCII: &str = "ply\nformat ascii 1.0\ncomment x\nelement vertex 4\nproperty float x\n\
                         property float y\nproperty float z\nproperty uchar red\nelement face 1\n\
                         property list uchar int vertex_indices\nend_header\n0 0 0 1\n1 0 0 2\n\
                         1 1 0 3\n0 1 0 4\n4 0 1 2 3\n";

fn ply_binary(big: bool) -> Vec<u8> {
    let fmt = if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut b = format!(
        "ply\nformat {fmt} 1.0\nelement vertex 3\nproperty double x\nproperty double y\n\
         property double z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n"
    )
    .into_bytes();
    for v in [[0.0f64, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 1.0]] {
        for c in v {
            b.extend(if big {
                c.to_be_bytes()
            } else {
                c.to_le_bytes()
            });
        }
    }
    b.push(3);
    for i in [0u32, 1, 2] {
        b.extend(if big {
            i.to_be_bytes()
        } else {
            i.to_le_bytes()
        });
    }
    b
}

fn p(name: &str) -> &Path {
    Path::new(name)
}

#[test]
fn obj_loads_all_faces_or_selected_groups() {
    let all = parse_obj(OBJ.as_bytes(), p("a.obj"), &LoadOptions::default()).unwrap();
    assert_eq!((all.vertices.len(), all.triangles.len()), (7, 3));
    assert_eq!(all.triangles[2], [4, 5, 6]);
    let body = LoadOptions {
        groups: vec!["body".into()],
    };
    let s = parse_obj(OBJ.as_bytes(), p("a.obj"), &body).unwrap();
    assert_eq!((s.vertices.len(), s.triangles.len()), (4, 2));
    assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    let missing = LoadOptions {
        groups: vec!["legs".into()],
    };
    let e = parse_obj(OBJ.as_bytes(), p("a.obj"), &missing)
        .unwrap_err()
        .to_string();
    assert!(e.contains("legs") && e.contains("body, helper"), "{e}");
}

#[test]
fn obj_errors_name_file_and_line() {
    let cases = [
        ("", "a.obj: contents: no vertices"),
        (
            "v 0 0 0\nv 1 nan 0\n",
            "a.obj: line 2: vertex y \"nan\" is not finite",
        ),
        ("v 0 0\n", "a.obj: line 1: vertex z coordinate is missing"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
            "a.obj: line 4: face index 9 is out of range",
        ),
        (
            "v 0 0 0\nv 1 0 0\nf 1 2\n",
            "a.obj: line 3: face has 2 vertices",
        ),
        ("v 0 0 0\nf 1 x 2\n", "a.obj: line 2: face index \"x\""),
        ("v 0 0 0\nf 0 1 1\n", "a.obj: line 2: face index 0"),
    ];
    for (text, needle) in cases {
        let e = parse_obj(text.as_bytes(), p("a.obj"), &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(needle), "{text:?} -> {e}");
    }
}

#[test]
fn stl_ascii_and_binary_load_and_weld() {
    let a = parse_stl(stl_ascii().as_bytes(), p("a.stl")).unwrap();
    assert_eq!((a.vertices.len(), a.triangles.len()), (4, 2));
    let tris = [
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
    ];
    let b = parse_stl(&stl_binary(&tris), p("b.stl")).unwrap();
    assert_eq!(a, b);
}

#[test]
fn stl_errors() {
    let e = parse_stl(b"", p("e.stl")).unwrap_err().to_string();
    assert!(e.starts_with("e.stl: header: not an STL file"), "{e}");
    let text = stl_ascii().replace("vertex 1 1 0", "vertex 1 inf 0");
    let e = parse_stl(text.as_bytes(), p("e.stl"))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("e.stl: line 12: vertex y"), "{e}");
    let mut bin = stl_binary(&[[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]]);
    bin[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = parse_stl(&bin, p("e.stl")).unwrap_err().to_string();
    assert!(e.contains("declares 4294967295 triangles"), "{e}");
    let nan = stl_binary(&[[[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]]);
    let e = parse_stl(&nan, p("e.stl")).unwrap_err().to_string();
    assert!(e.starts_with("e.stl: triangle 0: corner 0"), "{e}");
    let e = parse_stl(&stl_binary(&[]), p("e.stl"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("0 triangles"), "{e}");
}

#[test]
fn ply_ascii_and_binary_load() {
    let a = parse_ply(PLY_ASCII.as_bytes(), p("a.ply")).unwrap();
    assert_eq!((a.vertices.len(), a.triangles.len()), (4, 2));
    assert_eq!(a.vertices[2], [1.0, 1.0, 0.0]);
    for big in [false, true] {
        let b = parse_ply(&ply_binary(big), p("b.ply")).unwrap();
        assert_eq!(
            b.vertices,
            vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 1.0]]
        );
        assert_eq!(b.triangles, vec![[0, 1, 2]]);
    }
}

/// A UTF-8 byte-order mark before a text model (OBJ, ASCII STL, a PLY header) is skipped
/// (before: the OBJ's first vertex was silently dropped, the STL and PLY refused).
#[test]
fn a_byte_order_mark_before_a_text_model_is_skipped() {
    use fem_mesh::load::parse_model;
    let bom = |text: &str| [b"\xEF\xBB\xBF".as_slice(), text.as_bytes()].concat();
    let options = LoadOptions::default();
    for (name, text) in [
        ("a.obj", OBJ),
        ("a.stl", &stl_ascii()),
        ("a.ply", PLY_ASCII),
    ] {
        let plain = parse_model(text.as_bytes(), p(name), &options).unwrap();
        let marked = parse_model(&bom(text), p(name), &options).unwrap();
        assert_eq!(marked, plain, "{name}");
    }
}

#[test]
fn ply_errors() {
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (b"".to_vec(), "no `end_header`"),
        (b"plx\n".to_vec(), "line 1: not a PLY file"),
        (
            PLY_ASCII.replace("1 1 0 3", "1 nan 0 3").into_bytes(),
            "line 14 (vertex 2): coordinate y is not finite",
        ),
        (
            PLY_ASCII.replace("4 0 1 2 3", "4 0 1 2 9").into_bytes(),
            "face triangle 1: vertex index 9",
        ),
        (
            PLY_ASCII.replace("4 0 1 2 3", "4 0 1").into_bytes(),
            "line 16 (face 0): list vertex_indices",
        ),
        (
            PLY_ASCII
                .replace("element vertex 4", "element vertex 4000000000")
                .into_bytes(),
            "(vertex 4): line has 5 values",
        ),
        (
            PLY_ASCII.replace("float x", "quad x").into_bytes(),
            "unknown property type",
        ),
        (
            ply_binary(false)[..ply_binary(false).len() - 3].to_vec(),
            "face 0: list vertex_indices claims 3 entries, more than the file holds",
        ),
    ];
    for (bytes, needle) in cases {
        let e = parse_ply(&bytes, p("e.ply")).unwrap_err().to_string();
        assert!(
            e.starts_with("e.ply: ") && e.contains(needle),
            "{needle} -> {e}"
        );
    }
    // A huge face list count in a binary file is an error, not an allocation.
    let mut b = ply_binary(false);
    let at = b.len() - 13;
    b[at] = 255;
    let e = parse_ply(&b, p("e.ply")).unwrap_err().to_string();
    assert!(e.contains("face 0"), "{e}");
}

#[test]
fn load_model_dispatches_on_extension_and_reports_io_errors() {
    let e = load_model(p("/nonexistent/x.obj"), &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("/nonexistent/x.obj: "), "{e}");
    let e = load_model(p("model.dae"), &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown model format"), "{e}");
}

fn mutate(mut bytes: Vec<u8>, cut: usize, flips: &[(usize, u8)], insert: &[u8]) -> Vec<u8> {
    if !bytes.is_empty() {
        for &(at, b) in flips {
            let n = bytes.len();
            bytes[at % n] = b;
        }
    }
    let at = cut.min(bytes.len());
    bytes.splice(at..at, insert.iter().copied());
    bytes.truncate(cut.max(1));
    bytes
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn loaders_never_panic_on_junk(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let _ = parse_obj(&bytes, p("j.obj"), &LoadOptions::default());
        let _ = parse_stl(&bytes, p("j.stl"));
        let _ = parse_ply(&bytes, p("j.ply"));
        let mut prefixed = b"ply\nformat binary_little_endian 1.0\nelement vertex 99999999\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
        prefixed.extend(&bytes);
        let _ = parse_ply(&prefixed, p("j.ply"));
        let mut solid = b"solid ".to_vec();
        solid.extend(&bytes);
        let _ = parse_stl(&solid, p("j.stl"));
    }

    #[test]
    fn loaders_never_panic_on_mutated_files(
        cut in 0usize..700,
        flips in proptest::collection::vec((0usize..700, any::<u8>()), 0..5),
        insert in proptest::collection::vec(any::<u8>(), 0..12),
    ) {
        let _ = parse_obj(&mutate(OBJ.as_bytes().to_vec(), cut, &flips, &insert), p("m.obj"), &LoadOptions { groups: vec!["body".into()] });
        let _ = parse_stl(&mutate(stl_ascii().into_bytes(), cut, &flips, &insert), p("m.stl"));
        let tris = [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]; 3];
        let _ = parse_stl(&mutate(stl_binary(&tris), cut, &flips, &insert), p("m.stl"));
        let _ = parse_ply(&mutate(PLY_ASCII.as_bytes().to_vec(), cut, &flips, &insert), p("m.ply"));
        let _ = parse_ply(&mutate(ply_binary(false), cut, &flips, &insert), p("m.ply"));
        let _ = parse_ply(&mutate(ply_binary(true), cut, &flips, &insert), p("m.ply"));
    }

    #[test]
    fn loaders_never_panic_on_huge_counts(count in any::<u32>(), which in 0usize..4) {
        let count = count.to_string();
        let ply = match which {
            0 => PLY_ASCII.replace("element vertex 4", &format!("element vertex {count}")),
            1 => PLY_ASCII.replace("element face 1", &format!("element face {count}")),
            2 => PLY_ASCII.replace("4 0 1 2 3", &format!("{count} 0 1 2 3")),
            _ => String::from_utf8_lossy(&ply_binary(false))
                .replace("element vertex 3", &format!("element vertex {count}")),
        };
        let _ = parse_ply(ply.as_bytes(), p("h.ply"));
        let mut stl = stl_binary(&[[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]; 2]);
        stl[80..84].copy_from_slice(&count.parse::<u32>().unwrap().to_le_bytes());
        let _ = parse_stl(&stl, p("h.stl"));
    }
}
