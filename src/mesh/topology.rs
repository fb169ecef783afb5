use super::Mesh;

/// Vertex adjacency of a mesh, for neighbourhood filters, region growing and boundaries.
///
/// Neighbours are edge neighbours (the 1-ring), taken from polygon edges, so a quad's diagonal
/// is not an edge.
#[derive(Debug, Clone)]
pub struct Topology {
    neighbour_offsets: Vec<u32>,
    neighbours: Vec<u32>,
    vertex_face_offsets: Vec<u32>,
    vertex_faces: Vec<u32>,
    /// `true` for a vertex on an edge used by only one face (scan borders and hole rims) or
    /// on a non-manifold edge; isolated vertices count as boundary too.
    pub is_boundary: Vec<bool>,
}

impl Topology {
    pub fn new(mesh: &Mesh) -> Self {
        let n = mesh.vertex_count();
        // Directed edges (a, b) with a < b, plus how many faces use each.
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(mesh.faces.indices.len());
        for poly in mesh.faces.iter() {
            for (k, &a) in poly.iter().enumerate() {
                let b = poly[(k + 1) % poly.len()];
                if a != b && (a as usize) < n && (b as usize) < n {
                    edges.push((a.min(b), a.max(b)));
                }
            }
        }
        edges.sort_unstable();
        let mut is_boundary = vec![false; n];
        let mut unique: Vec<(u32, u32)> = Vec::with_capacity(edges.len() / 2 + 1);
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && edges[j] == edges[i] {
                j += 1;
            }
            if j - i != 2 {
                is_boundary[edges[i].0 as usize] = true;
                is_boundary[edges[i].1 as usize] = true;
            }
            unique.push(edges[i]);
            i = j;
        }
        let mut degree = vec![0u32; n];
        for &(a, b) in &unique {
            degree[a as usize] += 1;
            degree[b as usize] += 1;
        }
        let neighbour_offsets = prefix_sum(&degree);
        let mut fill = neighbour_offsets.clone();
        let mut neighbours = vec![0u32; unique.len() * 2];
        for &(a, b) in &unique {
            neighbours[fill[a as usize] as usize] = b;
            fill[a as usize] += 1;
            neighbours[fill[b as usize] as usize] = a;
            fill[b as usize] += 1;
        }
        for (v, d) in degree.iter().enumerate() {
            if *d == 0 {
                is_boundary[v] = true;
            }
        }

        let mut face_degree = vec![0u32; n];
        for &v in &mesh.faces.indices {
            if (v as usize) < n {
                face_degree[v as usize] += 1;
            }
        }
        let vertex_face_offsets = prefix_sum(&face_degree);
        let mut fill = vertex_face_offsets.clone();
        let mut vertex_faces = vec![0u32; *vertex_face_offsets.last().unwrap_or(&0) as usize];
        for (f, poly) in mesh.faces.iter().enumerate() {
            for &v in poly {
                if (v as usize) < n {
                    vertex_faces[fill[v as usize] as usize] = f as u32;
                    fill[v as usize] += 1;
                }
            }
        }
        Topology {
            neighbour_offsets,
            neighbours,
            vertex_face_offsets,
            vertex_faces,
            is_boundary,
        }
    }

    pub fn vertex_count(&self) -> usize {
        self.is_boundary.len()
    }

    /// Edge neighbours (1-ring) of vertex `v`, sorted ascending.
    pub fn neighbours(&self, v: usize) -> &[u32] {
        &self.neighbours[self.neighbour_offsets[v] as usize..self.neighbour_offsets[v + 1] as usize]
    }

    /// `v` is on the boundary or one of its neighbours is (its ring is one-sided).
    pub fn touches_boundary(&self, v: usize) -> bool {
        self.is_boundary[v]
            || self
                .neighbours(v)
                .iter()
                .any(|&u| self.is_boundary[u as usize])
    }

    /// Faces that use vertex `v`.
    pub fn vertex_faces(&self, v: usize) -> &[u32] {
        &self.vertex_faces
            [self.vertex_face_offsets[v] as usize..self.vertex_face_offsets[v + 1] as usize]
    }

    /// Flags (one per vertex) of `seeds` and every vertex within `rings` edge hops of one of
    /// them; seeds out of range are ignored.
    pub fn within_rings(&self, seeds: &[usize], rings: usize) -> Vec<bool> {
        let n = self.vertex_count();
        let mut inside = vec![false; n];
        let mut front: Vec<usize> = seeds.iter().copied().filter(|&v| v < n).collect();
        for &v in &front {
            inside[v] = true;
        }
        for _ in 0..rings {
            if front.is_empty() {
                break;
            }
            let mut next = Vec::new();
            for &v in &front {
                for &u in self.neighbours(v) {
                    if !std::mem::replace(&mut inside[u as usize], true) {
                        next.push(u as usize);
                    }
                }
            }
            front = next;
        }
        inside
    }

    /// Vertices within `rings` edge hops of `v` (excluding `v`), breadth first. `scratch`
    /// must hold `vertex_count()` falses and is returned that way (saves an allocation per call).
    pub fn k_ring(&self, v: usize, rings: usize, scratch: &mut [bool], out: &mut Vec<u32>) {
        out.clear();
        scratch[v] = true;
        let mut start = 0;
        out.extend(self.neighbours(v).iter().copied());
        for &u in out.iter() {
            scratch[u as usize] = true;
        }
        for _ in 1..rings {
            let end = out.len();
            for i in start..end {
                let u = out[i] as usize;
                for &w in self.neighbours(u) {
                    if !scratch[w as usize] {
                        scratch[w as usize] = true;
                        out.push(w);
                    }
                }
            }
            start = end;
        }
        scratch[v] = false;
        for &u in out.iter() {
            scratch[u as usize] = false;
        }
    }
}

fn prefix_sum(counts: &[u32]) -> Vec<u32> {
    let mut offsets = Vec::with_capacity(counts.len() + 1);
    let mut acc = 0u32;
    offsets.push(0);
    for c in counts {
        acc += c;
        offsets.push(acc);
    }
    offsets
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// 3×3 vertex grid of 4 quads: the centre vertex is interior, the rest are boundary.
    fn grid() -> Mesh {
        let mut p = Vec::new();
        for j in 0..3 {
            for i in 0..3 {
                p.push(DVec3::new(i as f64, j as f64, 0.0));
            }
        }
        let q = |i: u32, j: u32| {
            [
                j * 3 + i,
                j * 3 + i + 1,
                (j + 1) * 3 + i + 1,
                (j + 1) * 3 + i,
            ]
        };
        Mesh::from_faces(p, [q(0, 0), q(1, 0), q(0, 1), q(1, 1)])
    }

    #[test]
    fn centre_is_interior_with_four_edge_neighbours() {
        let t = Topology::new(&grid());
        assert!(!t.is_boundary[4]);
        assert_eq!(t.neighbours(4), &[1, 3, 5, 7]);
        assert_eq!(t.vertex_faces(4).len(), 4);
        assert_eq!((0..9).filter(|&v| t.is_boundary[v]).count(), 8);
    }

    #[test]
    fn two_ring_of_corner_covers_grid() {
        let t = Topology::new(&grid());
        let mut scratch = vec![false; 9];
        let mut out = Vec::new();
        t.k_ring(0, 2, &mut scratch, &mut out);
        out.sort();
        assert_eq!(out, vec![1, 2, 3, 4, 6]);
        assert!(scratch.iter().all(|s| !s));
    }
}
