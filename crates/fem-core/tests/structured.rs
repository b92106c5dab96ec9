//! The structured rectangle: every diagonal pattern tiles the rectangle with counter-clockwise
//! triangles, the node numbering is the documented one, and bad parameters are refused with
//! the value named.

use fem_core::mesh::MeshError;
use fem_core::structured::{Diagonal, NodeOrder, RectangleParams, rectangle};

#[test]
fn every_diagonal_pattern_tiles_the_rectangle_counter_clockwise() {
    for (diagonal, per_cell) in [
        (Diagonal::Right, 2),
        (Diagonal::Left, 2),
        (Diagonal::Alternating, 2),
        (Diagonal::Crossed, 4),
    ] {
        for order in [NodeOrder::XFastest, NodeOrder::YFastest] {
            let params = RectangleParams {
                origin: [-1.0, 0.5],
                diagonal,
                order,
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

#[test]
fn y_fastest_is_the_benchmark_scripts_layout() {
    // Node (i, j) is i (ny + 1) + j; cell (i, j) gives (a, b, c) and (a, c, d), cells column by
    // column.
    let (nx, ny) = (4, 2);
    let params = RectangleParams {
        order: NodeOrder::YFastest,
        ..RectangleParams::new(2.0, 1.0, nx, ny)
    };
    let mesh = rectangle(&params).unwrap();
    let id = |i: usize, j: usize| (i * (ny + 1) + j) as u32;
    let mut want = Vec::new();
    for i in 0..nx {
        for j in 0..ny {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            want.extend([[a, b, c], [a, c, d]]);
        }
    }
    assert_eq!(mesh.triangles(), &want[..]);
    assert_eq!(params.node(3, 1), 10);
    assert_eq!(mesh.vertices()[10], nalgebra::Vector2::new(1.5, 0.5));
    // The same triangles as the default numbering, renumbered.
    let x_fastest = rectangle(&RectangleParams::new(2.0, 1.0, nx, ny)).unwrap();
    let corners = |m: &fem_core::mesh::Mesh| {
        let mut t: Vec<Vec<[u64; 2]>> = m
            .triangles()
            .iter()
            .map(|t| {
                let mut c: Vec<[u64; 2]> = t
                    .iter()
                    .map(|&v| {
                        let p = m.vertices()[v as usize];
                        [p.x.to_bits(), p.y.to_bits()]
                    })
                    .collect();
                c.sort();
                c
            })
            .collect();
        t.sort();
        t
    };
    assert_eq!(corners(&mesh), corners(&x_fastest));
}
