//! Mesh checks beyond single triangles: repeated triangles, edges bordering more than two
//! triangles, and triangles that overlap (their interiors intersect). Any of these silently
//! double the mass and stiffness where it happens, so [`Mesh`](crate::mesh::Mesh) refuses them.
//!
//! - Edges: the `3n` edges are sorted by their vertex pair. An edge may border at most two
//!   triangles; with every triangle counter-clockwise (checked before), two triangles on one
//!   edge must run along it in opposite directions, else both lie on the same side of it and
//!   overlap. Same vertices in both triangles: a repeated triangle.
//! - Interiors: triangles are binned into a uniform grid of about one cell per triangle (by
//!   their bounding boxes); each pair in a cell is tested for a proper crossing of two of their
//!   edges that share no vertex, or a vertex of one strictly inside the other. "Properly" and
//!   "strictly" use a tolerance of `1e-12 L^2` on the orientation determinants (`L` the size of
//!   the mesh), so triangles that merely touch (a vertex on an edge) pass. Expected cost
//!   `O(n log n)`.

use crate::par::prelude::*;

use crate::math::{Real, Vec2};

/// What [`check`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Problem {
    /// `triangles[second]` has the vertices of `triangles[first]`.
    Repeated { first: usize, second: usize },
    /// The edge `(a, b)` borders these three (of possibly more) triangles.
    EdgeOfThree {
        edge: [u32; 2],
        triangles: [usize; 3],
    },
    /// The interiors of the two triangles intersect.
    Overlap { first: usize, second: usize },
}

/// The first problem of the (counter-clockwise, non-degenerate) triangles, if any.
pub(crate) fn check(vertices: &[Vec2], triangles: &[[u32; 3]]) -> Option<Problem> {
    edges(triangles).or_else(|| interiors(vertices, triangles))
}

fn edges(triangles: &[[u32; 3]]) -> Option<Problem> {
    // (low vertex, high vertex, triangle, forward = runs low -> high)
    let mut e: Vec<(u32, u32, u32, bool)> = Vec::with_capacity(3 * triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            e.push((a.min(b), a.max(b), t as u32, a < b));
        }
    }
    e.par_sort_unstable();
    let mut found: Option<Problem> = None;
    let mut keep = |p: Problem| {
        // The problem with the smallest triangle numbers, so the message does not depend on
        // the sort's tie-breaking.
        let key = |p: &Problem| match *p {
            Problem::Repeated { second, .. } => (second, 0),
            Problem::EdgeOfThree { triangles, .. } => (triangles[2], 1),
            Problem::Overlap { second, .. } => (second, 2),
        };
        if found.as_ref().is_none_or(|f| key(&p) < key(f)) {
            found = Some(p);
        }
    };
    let sorted = |t: u32| {
        let mut v = triangles[t as usize];
        v.sort_unstable();
        v
    };
    for group in e.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        if group.len() < 2 {
            continue;
        }
        // A repeated triangle first (its interior edges also border three triangles).
        let repeat = group.iter().enumerate().find_map(|(k, x)| {
            group[k + 1..]
                .iter()
                .find(|y| sorted(x.2) == sorted(y.2))
                .map(|y| (x.2.min(y.2) as usize, x.2.max(y.2) as usize))
        });
        if let Some((first, second)) = repeat {
            keep(Problem::Repeated { first, second });
        } else if let [x, y, z, ..] = group {
            keep(Problem::EdgeOfThree {
                edge: [x.0, x.1],
                triangles: [x.2 as usize, y.2 as usize, z.2 as usize],
            });
        } else if group[0].3 == group[1].3 {
            keep(Problem::Overlap {
                first: group[0].2 as usize,
                second: group[1].2 as usize,
            });
        }
    }
    found
}

/// `(b - a) x (c - a)`: positive when `a, b, c` turn counter-clockwise.
#[inline]
fn orient(a: Vec2, b: Vec2, c: Vec2) -> Real {
    (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)
}

fn overlaps(p: [Vec2; 3], ip: [u32; 3], q: [Vec2; 3], iq: [u32; 3], eps: Real) -> bool {
    // A vertex of one strictly inside the other (shared vertices excluded).
    let inside = |x: Vec2, t: [Vec2; 3]| {
        orient(t[0], t[1], x) > eps && orient(t[1], t[2], x) > eps && orient(t[2], t[0], x) > eps
    };
    for k in 0..3 {
        if !ip.contains(&iq[k]) && inside(q[k], p) {
            return true;
        }
        if !iq.contains(&ip[k]) && inside(p[k], q) {
            return true;
        }
    }
    // Two edges sharing no vertex that cross properly.
    for i in 0..3 {
        let (a0, a1) = (ip[i], ip[(i + 1) % 3]);
        for j in 0..3 {
            let (b0, b1) = (iq[j], iq[(j + 1) % 3]);
            if a0 == b0 || a0 == b1 || a1 == b0 || a1 == b1 {
                continue;
            }
            let (pa, pb) = (p[i], p[(i + 1) % 3]);
            let (qa, qb) = (q[j], q[(j + 1) % 3]);
            let (d1, d2) = (orient(pa, pb, qa), orient(pa, pb, qb));
            let (d3, d4) = (orient(qa, qb, pa), orient(qa, qb, pb));
            let opposite = |u: Real, v: Real| (u > eps && v < -eps) || (u < -eps && v > eps);
            if opposite(d1, d2) && opposite(d3, d4) {
                return true;
            }
        }
    }
    false
}

fn interiors(vertices: &[Vec2], triangles: &[[u32; 3]]) -> Option<Problem> {
    let n = triangles.len();
    let (mut lo, mut hi) = (vertices[0], vertices[0]);
    for v in vertices {
        lo = lo.inf(v);
        hi = hi.sup(v);
    }
    let extent = (hi - lo).max().max(Real::MIN_POSITIVE);
    let eps = 1e-12 * extent * extent;
    // About one cell per triangle; a triangle spanning many cells (strongly graded meshes)
    // only costs more entries, capped by coarsening the grid.
    let mut cells_per_side = ((n as Real).sqrt().ceil() as usize).clamp(1, 1 << 15);
    let entries = loop {
        let h = extent / cells_per_side as Real;
        let cell = |x: Real, o: Real| (((x - o) / h) as usize).min(cells_per_side - 1);
        let mut entries: Vec<(u64, u32)> = Vec::with_capacity(2 * n);
        let mut too_many = false;
        for (t, tri) in triangles.iter().enumerate() {
            let p = tri.map(|i| vertices[i as usize]);
            let (a, b) = (p[0].inf(&p[1]).inf(&p[2]), p[0].sup(&p[1]).sup(&p[2]));
            let (x0, x1) = (cell(a.x, lo.x), cell(b.x, lo.x));
            let (y0, y1) = (cell(a.y, lo.y), cell(b.y, lo.y));
            for cx in x0..=x1 {
                for cy in y0..=y1 {
                    entries.push(((cx as u64) << 32 | cy as u64, t as u32));
                }
            }
            if entries.len() > 16 * n + 64 {
                too_many = true;
                break;
            }
        }
        if !too_many || cells_per_side == 1 {
            break entries;
        }
        cells_per_side = cells_per_side.div_ceil(4);
    };
    let mut entries = entries;
    entries.par_sort_unstable();
    let groups: Vec<&[(u64, u32)]> = entries.chunk_by(|a, b| a.0 == b.0).collect();
    groups
        .par_iter()
        .filter_map(|g| {
            let mut best: Option<(usize, usize)> = None;
            for (k, &(_, s)) in g.iter().enumerate() {
                for &(_, t) in &g[k + 1..] {
                    let (s, t) = (s.min(t) as usize, s.max(t) as usize);
                    if best.is_some_and(|b| (t, s) >= (b.1, b.0)) {
                        continue;
                    }
                    let (ip, iq) = (triangles[s], triangles[t]);
                    let p = ip.map(|i| vertices[i as usize]);
                    let q = iq.map(|i| vertices[i as usize]);
                    if overlaps(p, ip, q, iq, eps) {
                        best = Some((s, t));
                    }
                }
            }
            best
        })
        // The pair with the smallest second triangle (then first): the same answer whatever
        // the thread count.
        .min_by_key(|&(s, t)| (t, s))
        .map(|(first, second)| Problem::Overlap { first, second })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(nx: usize, ny: usize) -> (Vec<Vec2>, Vec<[u32; 3]>) {
        let mut v = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                v.push(Vec2::new(i as Real, j as Real));
            }
        }
        let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
        let mut t = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (v, t)
    }

    #[test]
    fn a_conforming_mesh_passes_and_each_defect_is_named() {
        let (v, t) = grid(30, 20);
        assert_eq!(check(&v, &t), None);

        let mut rep = t.clone();
        rep.push([t[7][1], t[7][2], t[7][0]]);
        assert_eq!(
            check(&v, &rep),
            Some(Problem::Repeated {
                first: 7,
                second: t.len()
            })
        );

        // A third triangle on the edge (0, 32) of triangles 0 and 1, on the far side.
        let mut v3 = v.clone();
        v3.push(Vec2::new(-0.5, 0.5));
        let mut three = t.clone();
        three.push([0, 32, v3.len() as u32 - 1]);
        let p = check(&v3, &three).unwrap();
        assert!(
            matches!(p, Problem::EdgeOfThree { edge: [0, 32], .. }),
            "{p:?}"
        );

        // A triangle folded over its neighbour across their shared edge.
        let mut v4 = v.clone();
        v4.push(Vec2::new(0.7, 0.2));
        let mut fold = t.clone();
        fold[1] = [0, v4.len() as u32 - 1, 32];
        // Now triangles 0 and 1 run along (0, 32) in the same direction.
        assert!(matches!(check(&v4, &fold), Some(Problem::Overlap { .. })));

        // A second, shifted copy of a patch: shares no vertex with the first.
        let n = v.len() as u32;
        let mut v5 = v.clone();
        v5.extend(v.iter().map(|p| p + Vec2::new(10.3, 5.2)));
        let mut shifted = t.clone();
        shifted.extend(t.iter().map(|tri| tri.map(|i| i + n)));
        assert!(matches!(
            check(&v5, &shifted),
            Some(Problem::Overlap { .. })
        ));
        // Placed beside it instead (touching along x = 30), it passes.
        let mut v6 = v.clone();
        v6.extend(v.iter().map(|p| p + Vec2::new(30.0, 0.0)));
        assert_eq!(check(&v6, &shifted), None);
    }

    #[test]
    fn a_vertex_on_a_neighbours_edge_is_touching_not_overlap() {
        // Two triangles side by side, a third whose apex lies on the first's top edge.
        let v = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(0.0, 2.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(2.0, 2.0),
        ];
        let t = vec![[0, 1, 2], [1, 4, 3]];
        assert_eq!(check(&v, &t), None);
    }
}
