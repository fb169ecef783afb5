use super::Polygons;
use glam::DVec3;

/// Area-weighted normal of a polygon (Newell's method: exact for planar polygons, the
/// least-squares plane normal for warped quads). Its length is the polygon's area.
pub fn face_normal(positions: &[DVec3], polygon: &[u32]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for (k, &a) in polygon.iter().enumerate() {
        let p = positions[a as usize];
        let q = positions[polygon[(k + 1) % polygon.len()] as usize];
        n += p.cross(q);
    }
    n * 0.5
}

/// Per-vertex unit normals: the sum of the vector areas of the faces around each vertex.
/// Vertices without faces (or with cancelling faces) get a zero normal.
pub fn vertex_normals(positions: &[DVec3], faces: &Polygons) -> Vec<DVec3> {
    let mut normals = vec![DVec3::ZERO; positions.len()];
    for poly in faces.iter() {
        if poly.iter().any(|&v| v as usize >= positions.len()) {
            continue; // invalid face: validation reports it, normals must not panic
        }
        let n = face_normal(positions, poly);
        for &v in poly {
            normals[v as usize] += n;
        }
    }
    for n in &mut normals {
        *n = n.normalize_or_zero();
    }
    normals
}
