//! Greedy graph colouring of the triangles: no two triangles of one colour share a vertex, so
//! the constraints of one colour can be projected in parallel without conflicts.
//!
//! Triangles are coloured in index order, each with the smallest colour not used by an
//! already-coloured triangle sharing a vertex with it (deterministic; structured meshes need
//! about 7 to 10 colours).

use fem_core::mesh::Mesh;

/// A colouring as a permutation of the triangles grouped by colour.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Colouring {
    /// Colour of each triangle.
    pub colour: Vec<u32>,
    /// Triangles sorted by (colour, index).
    pub order: Vec<u32>,
    /// `order[offsets[c]..offsets[c + 1]]` are the triangles of colour `c`.
    pub offsets: Vec<usize>,
}

impl Colouring {
    /// Colour the triangles of `mesh`.
    pub fn greedy(mesh: &Mesh) -> Self {
        let nt = mesh.n_triangles();
        let adj = mesh.adjacency();
        let mut colour = vec![u32::MAX; nt];
        // stamp[c] == t marks colour c as taken for triangle t.
        let mut stamp: Vec<usize> = Vec::new();
        let mut n_colours = 0usize;
        for (t, tri) in mesh.triangles().iter().enumerate() {
            for &v in tri {
                for &(e, _) in adj.of(v as usize) {
                    let c = colour[e as usize];
                    if c != u32::MAX {
                        stamp[c as usize] = t;
                    }
                }
            }
            let c = (0..n_colours).find(|&c| stamp[c] != t).unwrap_or_else(|| {
                stamp.push(usize::MAX);
                n_colours += 1;
                n_colours - 1
            });
            colour[t] = c as u32;
        }
        let mut offsets = vec![0usize; n_colours + 1];
        for &c in &colour {
            offsets[c as usize + 1] += 1;
        }
        for c in 0..n_colours {
            offsets[c + 1] += offsets[c];
        }
        let mut next = offsets.clone();
        let mut order = vec![0u32; nt];
        for (t, &c) in colour.iter().enumerate() {
            order[next[c as usize]] = t as u32;
            next[c as usize] += 1;
        }
        Colouring {
            colour,
            order,
            offsets,
        }
    }

    /// Number of colours.
    pub fn n_colours(&self) -> usize {
        self.offsets.len() - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::rectangle_mesh;
    use fem_core::math::Vec2;

    #[test]
    fn no_two_triangles_of_a_colour_share_a_vertex() {
        let mesh = rectangle_mesh(Vec2::zeros(), 5.0, 1.0, 17, 5).unwrap();
        let c = Colouring::greedy(&mesh);
        assert!(c.n_colours() <= 12, "{} colours", c.n_colours());
        for k in 0..c.n_colours() {
            let mut seen = vec![false; mesh.n_vertices()];
            for &t in &c.order[c.offsets[k]..c.offsets[k + 1]] {
                assert_eq!(c.colour[t as usize], k as u32);
                for &v in &mesh.triangles()[t as usize] {
                    assert!(!seen[v as usize], "colour {k} reuses vertex {v}");
                    seen[v as usize] = true;
                }
            }
        }
        let mut all = c.order.clone();
        all.sort_unstable();
        assert!(all.iter().enumerate().all(|(i, &t)| i as u32 == t));
    }
}
