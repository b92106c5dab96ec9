//! The structured rectangle: every diagonal pattern tiles the rectangle with counter-clockwise
//! triangles, the node numbering is the documented one, and bad parameters are refused with
//! the value named.

use fem_core::mesh::MeshError;
use fem_core::structured::{Diagonal, RectangleParams, rectangle};

#[test]
fn every_diagonal_pattern_tiles_the_rectangle_counter_clockwise() {
    for (diagonal, per_cell) in [
        (Diagonal::Right, 2),
        (Diagonal::Left, 2),
        (Diagonal::Alternating, 2),
        (Diagonal::Crossed, 4),
    ] {
        let params = RectangleParams {
            origin: [-1.0, 0.5],
            diagonal,
            ..RectangleParams::new(5.0, 1.0, 10, 3)
        };
        // Mesh::new has already refused clockwise, degenerate and overlapping triangles.
        let mesh = rectangle(&params).unwrap();
        assert_eq!(mesh.n_triangles(), 10 * 3 * per_cell, "{diagonal:?}");
        let area = mesh.area();
        assert!((area - 5.0).abs() < 1e-12, "{diagonal:?}: area {area}");
        for j in 0..=3 {
            for i in 0..=10 {
                let p = mesh.vertices()[params.node(i, j)];
                assert_eq!(p.x, -1.0 + 5.0 * i as f64 / 10.0);
                assert_eq!(p.y, 0.5 + j as f64 / 3.0);
            }
        }
    }
    // The two plain patterns differ only in their diagonals.
    let one = |diagonal| {
        rectangle(&RectangleParams {
            diagonal,
            ..RectangleParams::new(1.0, 1.0, 1, 1)
        })
        .unwrap()
        .triangles()
        .to_vec()
    };
    assert_eq!(one(Diagonal::Right), vec![[0, 1, 3], [0, 3, 2]]);
    assert_eq!(one(Diagonal::Left), vec![[0, 1, 2], [1, 3, 2]]);
}

#[test]
fn bad_parameters_are_refused_with_the_value() {
    let err = |p: RectangleParams| match rectangle(&p) {
        Err(MeshError::Rectangle(m)) => m,
        other => panic!("expected a rectangle error, got {other:?}"),
    };
    assert!(err(RectangleParams::new(1.0, 1.0, 0, 1)).contains("got 0 x 1"));
    assert!(err(RectangleParams::new(-1.0, 1.0, 1, 1)).contains("got -1 x 1"));
    assert!(err(RectangleParams::new(1.0, f64::NAN, 1, 1)).contains("NaN"));
    let far = RectangleParams {
        origin: [f64::INFINITY, 0.0],
        ..RectangleParams::new(1.0, 1.0, 1, 1)
    };
    assert!(err(far).contains("origin"));
    assert!(err(RectangleParams::new(1.0, 1.0, 100_000, 100_000)).contains("50000000"));
}
