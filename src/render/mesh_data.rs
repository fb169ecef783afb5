//! CPU-side vertex and index arrays for the GPU, built from a [`Mesh`].

use crate::Mesh;
use bytemuck::{Pod, Zeroable};

/// One vertex as the mesh shader reads it (f32: the viewport needs no more than 0.1 µm).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct GpuVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub colour: [f32; 4],
}

/// Arrays ready for upload: triangles (polygons fanned) for shading, polygon edges (not the
/// fan diagonals, so quads look like quads) for the wireframe.
#[derive(Debug, Clone, Default)]
pub struct MeshData {
    pub vertices: Vec<GpuVertex>,
    pub triangles: Vec<u32>,
    pub edges: Vec<u32>,
}

impl MeshData {
    /// `colours`: per-vertex linear RGBA; `None` gives a neutral skin-like grey.
    pub fn from_mesh(mesh: &Mesh, colours: Option<&[[f32; 4]]>) -> Self {
        let default = [0.78, 0.72, 0.68, 1.0];
        let vertices = mesh
            .positions_mm
            .iter()
            .enumerate()
            .map(|(i, p)| GpuVertex {
                position: p.as_vec3().to_array(),
                normal: mesh
                    .normals
                    .get(i)
                    .map_or([0.0; 3], |n| n.as_vec3().to_array()),
                colour: colours.and_then(|c| c.get(i).copied()).unwrap_or(default),
            })
            .collect();
        let triangles = mesh.triangles().into_iter().flatten().collect();
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(mesh.faces.indices.len());
        for poly in mesh.faces.iter() {
            for (k, &a) in poly.iter().enumerate() {
                let b = poly[(k + 1) % poly.len()];
                edges.push((a.min(b), a.max(b)));
            }
        }
        edges.sort_unstable();
        edges.dedup();
        MeshData {
            vertices,
            triangles,
            edges: edges.into_iter().flat_map(|(a, b)| [a, b]).collect(),
        }
    }
}

impl MeshData {
    /// Line segments only (no surface), each with its own colour: muscle arrows, hex edges.
    pub fn lines(segments: &[([f32; 3], [f32; 3], [f32; 4])]) -> Self {
        let mut vertices = Vec::with_capacity(segments.len() * 2);
        for &(a, b, colour) in segments {
            for position in [a, b] {
                vertices.push(GpuVertex {
                    position,
                    normal: [0.0; 3],
                    colour,
                });
            }
        }
        MeshData {
            edges: (0..vertices.len() as u32).collect(),
            vertices,
            triangles: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn quad_gives_two_triangles_and_four_edges() {
        let mesh = Mesh::from_faces(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            [[0u32, 1, 2, 3]],
        );
        let data = MeshData::from_mesh(&mesh, None);
        assert_eq!(data.triangles.len(), 6);
        assert_eq!(data.edges.len(), 8);
        assert!(data.vertices.iter().all(|v| v.normal == [0.0, 0.0, 1.0]));
    }
}
