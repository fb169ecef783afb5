//! The polygon mesh every step works on.
//!
//! Positions are millimetres (f64). Faces are kept as they come — quads stay quads, because the
//! FEM later extrudes the generic face's quads into hexahedra — and stored flat (CSR style) so a
//! 14k-face scan is two allocations, not 14k.

mod normals;
/// Ray picking (the editor's click-on-surface).
pub mod pick;
/// Vertex-clustering simplification (the viewport's light copy of a dense scan).
pub mod simplify;
/// Closest points, ray–triangle, headless front-view pictures.
pub mod spatial;
mod topology;

pub use normals::{face_normal, vertex_normals};
pub use spatial::{FrontView, SurfaceIndex, closest_point_on_triangle, ray_triangle};
pub use topology::Topology;

use glam::DVec3;

/// A polygon mesh in millimetres with per-vertex unit normals.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions, mm.
    pub positions_mm: Vec<DVec3>,
    /// Per-vertex unit normals (area-weighted face normals); zero for isolated vertices.
    /// Kept in sync by [`Mesh::update_normals`]; constructors call it.
    pub normals: Vec<DVec3>,
    /// `faces.indices[faces.offsets[f]..faces.offsets[f + 1]]` are face `f`'s vertex ids, in
    /// counter-clockwise order seen from outside (for scans: seen from the scanner, +z).
    pub faces: Polygons,
}

/// Polygons stored flat: one index array plus offsets (`offsets.len() == faces + 1`).
#[derive(Debug, Clone, PartialEq)]
pub struct Polygons {
    pub offsets: Vec<u32>,
    pub indices: Vec<u32>,
}

impl Default for Polygons {
    fn default() -> Self {
        Polygons {
            offsets: vec![0],
            indices: Vec::new(),
        }
    }
}

impl Polygons {
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of faces.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Appends one polygon.
    pub fn push(&mut self, polygon: &[u32]) {
        self.indices.extend_from_slice(polygon);
        self.offsets.push(self.indices.len() as u32);
    }

    /// Drops every face whose vertex set equals an earlier face's (in either orientation);
    /// returns how many were dropped. A doubled face makes its edges look non-manifold and
    /// counts twice in area-weighted normals, and carries nothing the first copy does not.
    pub fn remove_duplicates(&mut self) -> usize {
        use std::collections::HashSet;
        let mut small: HashSet<[u32; 4]> = HashSet::with_capacity(self.len());
        let mut large: HashSet<Vec<u32>> = HashSet::new();
        let mut keep = Vec::with_capacity(self.len());
        for f in self.iter() {
            let fresh = if f.len() <= 4 {
                let mut key = [u32::MAX; 4];
                key[..f.len()].copy_from_slice(f);
                key.sort_unstable();
                small.insert(key)
            } else {
                let mut key = f.to_vec();
                key.sort_unstable();
                large.insert(key)
            };
            keep.push(fresh);
        }
        let dropped = keep.iter().filter(|k| !**k).count();
        if dropped > 0 {
            let mut out = Polygons::new();
            out.offsets.reserve(self.len() - dropped);
            out.indices.reserve(self.indices.len());
            for (f, k) in self.iter().zip(&keep) {
                if *k {
                    out.push(f);
                }
            }
            *self = out;
        }
        dropped
    }

    /// Vertex ids of face `f`.
    pub fn get(&self, f: usize) -> &[u32] {
        &self.indices[self.offsets[f] as usize..self.offsets[f + 1] as usize]
    }

    pub fn iter(&self) -> impl ExactSizeIterator<Item = &[u32]> + '_ {
        (0..self.len()).map(move |f| self.get(f))
    }

    /// Builds from a list of polygons.
    pub fn from_polygons<P: AsRef<[u32]>>(polygons: impl IntoIterator<Item = P>) -> Self {
        let mut out = Polygons::new();
        for p in polygons {
            out.push(p.as_ref());
        }
        out
    }
}

/// Counts of faces by arity.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct FaceCounts {
    pub faces: usize,
    pub triangles: usize,
    pub quads: usize,
    /// Polygons with more than four corners.
    pub other: usize,
}

impl Mesh {
    /// Builds a mesh and computes its normals. Does not validate: call [`Mesh::validate`].
    pub fn new(positions_mm: Vec<DVec3>, faces: Polygons) -> Self {
        let mut mesh = Mesh {
            positions_mm,
            normals: Vec::new(),
            faces,
        };
        mesh.update_normals();
        mesh
    }

    /// Convenience constructor from per-face vectors (tests, generated meshes).
    pub fn from_faces<P: AsRef<[u32]>>(
        positions_mm: Vec<DVec3>,
        faces: impl IntoIterator<Item = P>,
    ) -> Self {
        Self::new(positions_mm, Polygons::from_polygons(faces))
    }

    pub fn vertex_count(&self) -> usize {
        self.positions_mm.len()
    }

    pub fn face_count(&self) -> usize {
        self.faces.len()
    }

    /// The same polygons with every vertex moved by `displacement_mm` (one per vertex; missing
    /// entries count as zero), normals recomputed: a deformed copy for display and export.
    pub fn displaced(&self, displacement_mm: &[DVec3]) -> Mesh {
        let positions = self
            .positions_mm
            .iter()
            .enumerate()
            .map(|(i, p)| *p + displacement_mm.get(i).copied().unwrap_or(DVec3::ZERO))
            .collect();
        Mesh::new(positions, self.faces.clone())
    }

    /// Recomputes [`Mesh::normals`] from the current positions.
    pub fn update_normals(&mut self) {
        self.normals = vertex_normals(&self.positions_mm, &self.faces);
    }

    pub fn face_counts(&self) -> FaceCounts {
        let mut c = FaceCounts {
            faces: self.faces.len(),
            ..FaceCounts::default()
        };
        for f in self.faces.iter() {
            match f.len() {
                3 => c.triangles += 1,
                4 => c.quads += 1,
                _ => c.other += 1,
            }
        }
        c
    }

    /// Axis-aligned bounding box (min, max) in mm; `None` for an empty mesh.
    pub fn bbox_mm(&self) -> Option<(DVec3, DVec3)> {
        let first = *self.positions_mm.first()?;
        Some(
            self.positions_mm
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))),
        )
    }

    /// Checks what every algorithm relies on: at least one vertex and one face, finite
    /// coordinates, faces of ≥ 3 corners with indices in range and no repeated corner.
    /// Returns a message naming the first offending vertex or face.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if self.positions_mm.is_empty() {
            return Err("mesh has no vertices".into());
        }
        if self.faces.is_empty() {
            return Err("mesh has no faces".into());
        }
        if let Some((i, p)) = self
            .positions_mm
            .iter()
            .enumerate()
            .find(|(_, p)| !p.is_finite())
        {
            return Err(format!("vertex {i} has a non-finite coordinate {p:?}"));
        }
        let n = self.positions_mm.len();
        for (f, poly) in self.faces.iter().enumerate() {
            if poly.len() < 3 {
                return Err(format!("face {f} has {} corners (need ≥ 3)", poly.len()));
            }
            if let Some(&bad) = poly.iter().find(|&&v| v as usize >= n) {
                return Err(format!(
                    "face {f} refers to vertex {bad}, but there are only {n} vertices"
                ));
            }
            for (k, a) in poly.iter().enumerate() {
                if poly[k + 1..].contains(a) {
                    return Err(format!("face {f} uses vertex {a} twice"));
                }
            }
        }
        Ok(())
    }

    /// Drops vertices no face uses and renumbers faces; returns old→new ids (`u32::MAX` if
    /// dropped).
    pub fn remove_unreferenced_vertices(&mut self) -> Vec<u32> {
        let mut used = vec![false; self.positions_mm.len()];
        for &v in &self.faces.indices {
            used[v as usize] = true;
        }
        let kept = self.retain_vertices(&used);
        let mut remap = vec![u32::MAX; used.len()];
        for (new, &old) in kept.iter().enumerate() {
            remap[old as usize] = new as u32;
        }
        remap
    }

    /// Keeps the vertices with `keep[v]` (renumbered in order) and drops the others; a polygon
    /// loses its corners at dropped vertices and is dropped itself when fewer than 3 are left
    /// (a quad with one corner gone stays as a triangle, as scanners write it). Returns the
    /// input id of every kept vertex (new → old).
    pub fn retain_vertices(&mut self, keep: &[bool]) -> Vec<u32> {
        assert_eq!(keep.len(), self.positions_mm.len(), "one flag per vertex");
        let mut remap = vec![u32::MAX; keep.len()];
        let mut kept = Vec::with_capacity(keep.len());
        for (v, _) in keep.iter().enumerate().filter(|(_, k)| **k) {
            remap[v] = kept.len() as u32;
            kept.push(v as u32);
        }
        let mut faces = Polygons::new();
        let mut corners = Vec::with_capacity(4);
        for f in self.faces.iter() {
            corners.clear();
            corners.extend(
                f.iter()
                    .map(|&v| remap[v as usize])
                    .filter(|&v| v != u32::MAX),
            );
            if corners.len() >= 3 {
                faces.push(&corners);
            }
        }
        self.positions_mm = kept
            .iter()
            .map(|&v| self.positions_mm[v as usize])
            .collect();
        self.faces = faces;
        self.update_normals();
        kept
    }

    /// Splits every polygon into a triangle fan (for rendering and point-in-triangle queries).
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::with_capacity(self.faces.indices.len());
        for poly in self.faces.iter() {
            for k in 1..poly.len().saturating_sub(1) {
                out.push([poly[0], poly[k], poly[k + 1]]);
            }
        }
        out
    }
}

/// The gradient of `f` at `p` by central differences of step `h` along the world axes. Along
/// fixed axes a mirrored point gets the mirrored gradient, so a search driven by it keeps a
/// symmetric mesh symmetric (`fem::untangle`, `fem::repair::relax_skewed_quads`).
pub fn central_gradient(mut f: impl FnMut(DVec3) -> f64, p: DVec3, h: f64) -> DVec3 {
    let d = |f: &mut dyn FnMut(DVec3) -> f64, axis: DVec3| f(p + axis * h) - f(p - axis * h);
    DVec3::new(
        d(&mut f, DVec3::X),
        d(&mut f, DVec3::Y),
        d(&mut f, DVec3::Z),
    ) / (2.0 * h)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_square() -> Mesh {
        Mesh::from_faces(
            vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            [[0u32, 1, 2, 3]],
        )
    }

    #[test]
    fn quad_normal_points_along_ccw_side() {
        let m = unit_square();
        for n in &m.normals {
            assert!((*n - DVec3::Z).length() < 1e-12);
        }
        assert_eq!(m.face_counts().quads, 1);
    }

    #[test]
    fn validate_rejects_out_of_range_and_nan() {
        let mut m = unit_square();
        assert!(m.validate().is_ok());
        m.faces = Polygons::from_polygons([[0u32, 1, 7]]);
        assert!(m.validate().unwrap_err().contains("vertex 7"));
        let mut m = unit_square();
        m.positions_mm[2].y = f64::NAN;
        assert!(m.validate().unwrap_err().contains("vertex 2"));
    }

    #[test]
    fn unreferenced_vertices_are_dropped() {
        let mut m = unit_square();
        m.positions_mm.push(DVec3::splat(9.0));
        m.positions_mm.insert(0, DVec3::splat(-9.0));
        m.faces = Polygons::from_polygons([[1u32, 2, 3, 4]]);
        let remap = m.remove_unreferenced_vertices();
        assert_eq!(m.vertex_count(), 4);
        assert_eq!(remap[0], u32::MAX);
        assert_eq!(m.faces.get(0), &[0, 1, 2, 3]);
    }
}
