//! Greedy graph colourings: of the triangles ([`Colouring`]: no two triangles of one colour
//! share a vertex, so the constraints of one colour can be projected in parallel without
//! conflicts) and of the vertices ([`VertexColouring`]: no two vertices of one colour share a
//! triangle, so the vertices of one colour can be moved in parallel, each seeing the others'
//! positions unchanged; or, for the averaged nodal pressure triangle, no two share a node's
//! patch, [`VertexColouring::greedy_patches`], so each also sees the others' nodal volumes
//! unchanged).
//!
//! Items are coloured in index order, each with the smallest colour not used by an
//! already-coloured neighbour (deterministic; structured meshes need about 7 to 10 triangle
//! colours and 4 to 7 vertex colours).

use fem_core::mesh::Mesh;
use fem_core::nodal_pressure::NodalPressure;

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

/// A colouring of the free vertices as a permutation grouped by colour.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VertexColouring {
    /// Free vertices sorted by (colour, index).
    pub order: Vec<u32>,
    /// `order[offsets[c]..offsets[c + 1]]` are the vertices of colour `c`.
    pub offsets: Vec<usize>,
}

impl VertexColouring {
    /// Colour the vertices of `mesh` for which `free` is true; two vertices of one triangle
    /// never share a colour.
    pub fn greedy(mesh: &Mesh, free: &[bool]) -> Self {
        let adj = mesh.adjacency();
        let tris = mesh.triangles();
        Self::greedy_by(mesh.n_vertices(), free, |v| {
            adj.of(v).iter().flat_map(move |&(t, _)| tris[t as usize])
        })
    }

    /// Colour the vertices of `mesh` for which `free` is true so that no two of one colour lie
    /// in the patch of one node of `np` (the vertices of the triangles at the node): then no
    /// two share a triangle either, and moving one never changes a nodal volume another one's
    /// local energy reads (the nodes whose patch holds it). Vertices at distance two apart
    /// differ, so it takes more colours than [`VertexColouring::greedy`] (about 12 to 20 on
    /// structured meshes).
    pub fn greedy_patches(mesh: &Mesh, np: &NodalPressure, free: &[bool]) -> Self {
        let stencil = np.stencil(mesh);
        Self::greedy_by(stencil.len(), free, |v| stencil[v].iter().copied())
    }

    /// Colour the `nv` vertices for which `free` is true, in index order, each with the
    /// smallest colour of no vertex among its `neighbours(v)` (a symmetric relation; `v`
    /// itself may be listed).
    pub(crate) fn greedy_by<I: Iterator<Item = u32>>(
        nv: usize,
        free: &[bool],
        neighbours: impl Fn(usize) -> I,
    ) -> Self {
        let mut colour = vec![u32::MAX; nv];
        // stamp[c] == v marks colour c as taken for vertex v.
        let mut stamp: Vec<usize> = Vec::new();
        let mut n_colours = 0usize;
        for v in (0..nv).filter(|&v| free[v]) {
            for u in neighbours(v) {
                let c = colour[u as usize];
                if c != u32::MAX {
                    stamp[c as usize] = v;
                }
            }
            let c = (0..n_colours).find(|&c| stamp[c] != v).unwrap_or_else(|| {
                stamp.push(usize::MAX);
                n_colours += 1;
                n_colours - 1
            });
            colour[v] = c as u32;
        }
        Self::from_colours(&colour, n_colours)
    }

    /// The permutation of the coloured vertices (`u32::MAX`: not coloured).
    fn from_colours(colour: &[u32], n_colours: usize) -> Self {
        let mut offsets = vec![0usize; n_colours + 1];
        for &c in colour.iter().filter(|&&c| c != u32::MAX) {
            offsets[c as usize + 1] += 1;
        }
        for c in 0..n_colours {
            offsets[c + 1] += offsets[c];
        }
        let mut next = offsets.clone();
        let mut order = vec![0u32; offsets[n_colours]];
        for (v, &c) in colour.iter().enumerate() {
            if c != u32::MAX {
                order[next[c as usize]] = v as u32;
                next[c as usize] += 1;
            }
        }
        VertexColouring { order, offsets }
    }

    /// Number of colours.
    pub fn n_colours(&self) -> usize {
        self.offsets.len() - 1
    }

    /// The vertices of colour `k`, increasing.
    pub fn class(&self, k: usize) -> &[u32] {
        &self.order[self.offsets[k]..self.offsets[k + 1]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{RectangleParams, rectangle};

    #[test]
    fn no_two_triangles_of_a_colour_share_a_vertex() {
        let mesh = rectangle(&RectangleParams::new(5.0, 1.0, 17, 5)).unwrap();
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

    #[test]
    fn no_two_vertices_of_a_colour_share_a_triangle_and_fixed_ones_are_left_out() {
        let mesh = rectangle(&RectangleParams::new(5.0, 1.0, 17, 5)).unwrap();
        let free: Vec<bool> = (0..mesh.n_vertices()).map(|v| v % 5 != 0).collect();
        let c = VertexColouring::greedy(&mesh, &free);
        assert!(c.n_colours() <= 8, "{} colours", c.n_colours());
        let mut colour = vec![usize::MAX; mesh.n_vertices()];
        for k in 0..c.n_colours() {
            for &v in &c.order[c.offsets[k]..c.offsets[k + 1]] {
                colour[v as usize] = k;
            }
        }
        for (v, &f) in free.iter().enumerate() {
            assert_eq!(f, colour[v] != usize::MAX, "vertex {v}");
        }
        for t in mesh.triangles() {
            for a in 0..3 {
                for b in a + 1..3 {
                    let (ca, cb) = (colour[t[a] as usize], colour[t[b] as usize]);
                    assert!(ca == usize::MAX || ca != cb, "triangle {t:?}");
                }
            }
        }
    }

    #[test]
    fn no_two_vertices_of_a_patch_colour_share_a_node_patch() {
        let mesh = rectangle(&RectangleParams::new(5.0, 1.0, 17, 5)).unwrap();
        // Two regions: the vertices on the interface have one node per side.
        let tags: Vec<u32> = (0..mesh.n_triangles())
            .map(|t| u32::from(t % 7 < 3))
            .collect();
        let np = NodalPressure::new(&mesh, &tags);
        let free: Vec<bool> = (0..mesh.n_vertices()).map(|v| v % 5 != 0).collect();
        let c = VertexColouring::greedy_patches(&mesh, &np, &free);
        let plain = VertexColouring::greedy(&mesh, &free);
        assert!(c.n_colours() > plain.n_colours() && c.n_colours() <= 24);
        let mut colour = vec![usize::MAX; mesh.n_vertices()];
        for k in 0..c.n_colours() {
            for &v in c.class(k) {
                colour[v as usize] = k;
            }
        }
        for (v, &f) in free.iter().enumerate() {
            assert_eq!(f, colour[v] != usize::MAX, "vertex {v}");
        }
        let mut patch = Vec::new();
        for n in 0..np.n_nodes() {
            np.patch(&mesh, n, &mut patch);
            let mut seen: Vec<usize> = (patch.iter())
                .map(|&v| colour[v as usize])
                .filter(|&k| k != usize::MAX)
                .collect();
            let len = seen.len();
            seen.sort_unstable();
            seen.dedup();
            assert_eq!(seen.len(), len, "node {n}: a colour twice in its patch");
        }
    }
}
