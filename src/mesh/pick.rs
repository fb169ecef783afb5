//! Ray picking on a mesh: the editor's "click the surface to place a landmark". Brute force
//! over the fanned triangles (a 27k-triangle scan takes well under a millisecond per click,
//! so no acceleration structure is worth its memory).

use super::Mesh;
use glam::DVec3;

/// Where a ray first meets a mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// The hit point on the surface, mm.
    pub point_mm: DVec3,
    /// Distance along the (unit) ray from its origin, mm.
    pub distance_mm: f64,
    /// Polygon that was hit.
    pub face: usize,
    /// Vertex of that polygon nearest to the hit point (for snapping to vertices).
    pub nearest_vertex: u32,
}

/// First intersection of the ray `origin + t·dir` (t > 0) with the mesh, both sides of each
/// face counted (scans are open surfaces). `dir` need not be unit length.
pub fn ray_hit(mesh: &Mesh, origin: DVec3, dir: DVec3) -> Option<RayHit> {
    let dir = dir.try_normalize()?;
    let p = &mesh.positions_mm;
    let mut best: Option<RayHit> = None;
    for (f, poly) in mesh.faces.iter().enumerate() {
        for k in 1..poly.len().saturating_sub(1) {
            let (a, b, c) = (
                p[poly[0] as usize],
                p[poly[k] as usize],
                p[poly[k + 1] as usize],
            );
            let Some(t) = super::ray_triangle(origin, dir, a, b, c)
                .map(|(t, _)| t)
                .filter(|&t| t > 1e-9)
            else {
                continue;
            };
            if best.is_some_and(|h| h.distance_mm <= t) {
                continue;
            }
            let point = origin + dir * t;
            let nearest_vertex = *poly
                .iter()
                .min_by(|&&i, &&j| {
                    let di = p[i as usize].distance_squared(point);
                    let dj = p[j as usize].distance_squared(point);
                    di.total_cmp(&dj)
                })
                .expect("a polygon has vertices");
            best = Some(RayHit {
                point_mm: point,
                distance_mm: t,
                face: f,
                nearest_vertex,
            });
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two parallel unit-spaced grids of quads at z = 0 and z = -5.
    fn two_sheets() -> Mesh {
        let mut positions = Vec::new();
        let mut faces = Vec::new();
        for (sheet, z) in [0.0, -5.0].into_iter().enumerate() {
            let base = (sheet * 16) as u32;
            for j in 0..4 {
                for i in 0..4 {
                    positions.push(DVec3::new(i as f64 * 10.0, j as f64 * 10.0, z));
                }
            }
            for j in 0..3u32 {
                for i in 0..3u32 {
                    let v = base + j * 4 + i;
                    faces.push([v, v + 1, v + 5, v + 4]);
                }
            }
        }
        Mesh::from_faces(positions, faces)
    }

    #[test]
    fn ray_from_the_front_hits_the_front_sheet_at_the_right_point() {
        let mesh = two_sheets();
        let hit = ray_hit(&mesh, DVec3::new(12.0, 17.0, 100.0), -DVec3::Z).unwrap();
        assert!((hit.point_mm - DVec3::new(12.0, 17.0, 0.0)).length() < 1e-9);
        assert!((hit.distance_mm - 100.0).abs() < 1e-9);
        assert_eq!(hit.nearest_vertex, 2 * 4 + 1); // (10, 20, 0) is the closest corner
        // From behind, the back sheet comes first.
        let back = ray_hit(&mesh, DVec3::new(12.0, 17.0, -100.0), DVec3::Z).unwrap();
        assert!((back.point_mm.z + 5.0).abs() < 1e-9);
    }

    #[test]
    fn ray_that_misses_or_points_away_gives_none() {
        let mesh = two_sheets();
        assert!(ray_hit(&mesh, DVec3::new(50.0, 5.0, 10.0), -DVec3::Z).is_none());
        assert!(ray_hit(&mesh, DVec3::new(5.0, 5.0, 10.0), DVec3::Z).is_none());
        assert!(ray_hit(&mesh, DVec3::new(5.0, 5.0, 10.0), DVec3::ZERO).is_none());
    }
}
