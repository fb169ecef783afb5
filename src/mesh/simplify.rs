//! Vertex-clustering simplification, for display: every vertex falls into a cube of side
//! `cell_mm`, each occupied cube becomes one vertex (the mean of its members), and triangles
//! that keep three distinct corners survive. Cheap (one pass, no quadrics) and bounded: no
//! vertex moves farther than the cube's diagonal. It may close gaps narrower than a cell (a
//! parted mouth), which is why only the viewport uses it, never an algorithm.

use super::{Mesh, Polygons};
use glam::DVec3;
use std::collections::HashMap;

/// The median edge length of `mesh`, mm (0 for a mesh without edges).
pub fn median_edge_mm(mesh: &Mesh) -> f64 {
    median_edge_mm_where(mesh, |_| true)
}

/// The median length of the edges of `mesh` whose two vertices are both `kept`, mm (0 where
/// there are none).
pub fn median_edge_mm_where(mesh: &Mesh, kept: impl Fn(u32) -> bool) -> f64 {
    let mut lengths: Vec<f64> = mesh
        .faces
        .iter()
        .flat_map(|poly| (0..poly.len()).map(move |k| (poly[k], poly[(k + 1) % poly.len()])))
        .filter(|&(a, b)| kept(a) && kept(b))
        .map(|(a, b)| (mesh.positions_mm[a as usize] - mesh.positions_mm[b as usize]).length())
        .collect();
    if lengths.is_empty() {
        return 0.0;
    }
    let mid = lengths.len() / 2;
    *lengths.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// `mesh` clustered into cubes of side `cell_mm` (see the module docs); a triangle mesh.
/// A non-positive or non-finite `cell_mm` returns the mesh triangulated, unchanged otherwise.
pub fn cluster(mesh: &Mesh, cell_mm: f64) -> Mesh {
    let triangles = mesh.triangles();
    if !(cell_mm > 0.0 && cell_mm.is_finite()) {
        return Mesh::new(
            mesh.positions_mm.clone(),
            Polygons::from_polygons(triangles),
        );
    }
    let mut cell_of = HashMap::new();
    let mut sums: Vec<(DVec3, u32)> = Vec::new();
    let remap: Vec<u32> = mesh
        .positions_mm
        .iter()
        .map(|p| {
            let key = (*p / cell_mm).floor().as_i64vec3().to_array();
            let id = *cell_of.entry(key).or_insert_with(|| {
                sums.push((DVec3::ZERO, 0));
                sums.len() as u32 - 1
            });
            let s = &mut sums[id as usize];
            s.0 += *p;
            s.1 += 1;
            id
        })
        .collect();
    let positions = sums.iter().map(|(sum, n)| *sum / *n as f64).collect();
    let kept = triangles
        .iter()
        .map(|t| t.map(|v| remap[v as usize]))
        .filter(|[a, b, c]| a != b && b != c && a != c);
    let mut faces = Polygons::from_polygons(kept);
    faces.remove_duplicates();
    Mesh::new(positions, faces)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `n × n`-quad height field z = f(x, y) on a 1 mm grid.
    fn grid(n: u32, f: impl Fn(f64, f64) -> f64) -> Mesh {
        let id = |i: u32, j: u32| i + (n + 1) * j;
        let mut positions = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f64, j as f64);
                positions.push(DVec3::new(x, y, f(x, y)));
            }
        }
        let mut faces = Vec::new();
        for j in 0..n {
            for i in 0..n {
                faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        Mesh::from_faces(positions, faces)
    }

    #[test]
    fn a_grid_at_twice_its_spacing_keeps_a_quarter_of_the_triangles_on_the_surface() {
        let f = |x: f64, y: f64| 5.0 * (x / 10.0).sin() * (y / 13.0).cos();
        let mesh = grid(60, f);
        assert!((median_edge_mm(&mesh) - 1.0).abs() < 0.05);
        let coarse = cluster(&mesh, 2.0);
        let before = mesh.triangles().len() as f64;
        let after = coarse.triangles().len() as f64;
        assert!(
            (0.2..0.33).contains(&(after / before)),
            "{after} / {before}"
        );
        // Every cluster vertex stays near the surface (a cell's mean of a smooth patch).
        for p in &coarse.positions_mm {
            assert!((p.z - f(p.x, p.y)).abs() < 0.3, "{p}");
        }
        // Orientation survives: normals still face +z like the grid's.
        let up = coarse.normals.iter().filter(|n| n.z > 0.5).count();
        assert!(up as f64 > 0.95 * coarse.vertex_count() as f64);
    }

    #[test]
    fn a_cell_smaller_than_the_spacing_changes_nothing_but_the_triangulation() {
        let mesh = grid(8, |_, _| 0.0);
        let same = cluster(&mesh, 0.25);
        assert_eq!(same.vertex_count(), mesh.vertex_count());
        assert_eq!(same.triangles().len(), mesh.triangles().len());
        let none = cluster(&mesh, f64::NAN);
        assert_eq!(none.triangles(), mesh.triangles());
    }
}
