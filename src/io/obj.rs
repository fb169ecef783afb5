//! Wavefront OBJ through tobj, without forced triangulation (quads stay quads).

use crate::io::ReadLimits;
use crate::mesh::Polygons;
use crate::{Error, Mesh, Result};
use glam::DVec3;
use std::io::Write;
use std::path::Path;

/// Parses OBJ text. All objects/groups are merged into one mesh; texture coordinates,
/// normals and materials are ignored (normals are recomputed from the faces).
pub fn parse(bytes: &[u8], path: &Path, limits: &ReadLimits) -> Result<Mesh> {
    let opts = tobj::LoadOptions {
        triangulate: false,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = std::io::BufReader::new(bytes);
    let (models, _) =
        tobj::load_obj_buf(&mut reader, &opts, |_| Err(tobj::LoadError::OpenFileFailed))
            .map_err(|e| Error::invalid(path, format!("not a readable OBJ file ({e})")))?;
    let mut positions = Vec::new();
    let mut faces = Polygons::new();
    for model in &models {
        let m = &model.mesh;
        let base = positions.len() as u32;
        if positions.len() + m.positions.len() / 3 > limits.max_vertices {
            return Err(Error::invalid(
                path,
                "more vertices than the reader's limit",
            ));
        }
        positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)),
        );
        let mut start = 0usize;
        let arities: Vec<u32> = if m.face_arities.is_empty() {
            vec![3; m.indices.len() / 3]
        } else {
            m.face_arities.clone()
        };
        for arity in arities {
            let end = start + arity as usize;
            let Some(poly) = m.indices.get(start..end) else {
                return Err(Error::invalid(
                    path,
                    "face list is shorter than its arities",
                ));
            };
            let poly: Vec<u32> = poly.iter().map(|&i| base + i).collect();
            faces.push(&poly);
            start = end;
        }
    }
    Ok(Mesh::new(positions, faces))
}

/// Writes OBJ text (`v` lines in mm with 6 decimals, 1-based `f` lines, polygons kept).
pub fn write(w: &mut dyn Write, mesh: &Mesh) -> std::io::Result<()> {
    writeln!(w, "# facesynth mesh, units: millimetres")?;
    for p in &mesh.positions_mm {
        writeln!(w, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z)?;
    }
    for poly in mesh.faces.iter() {
        w.write_all(b"f")?;
        for &v in poly {
            write!(w, " {}", v + 1)?;
        }
        w.write_all(b"\n")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_survive_a_round_trip() {
        let mesh = Mesh::from_faces(
            vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.5, 0.0, 0.0),
                DVec3::new(1.5, 2.0, 0.25),
                DVec3::new(0.0, 2.0, 0.0),
                DVec3::new(3.0, 1.0, -1.0),
            ],
            [vec![0u32, 1, 2, 3], vec![1, 4, 2]],
        );
        let mut text = Vec::new();
        write(&mut text, &mesh).unwrap();
        let back = parse(&text, Path::new("t.obj"), &ReadLimits::default()).unwrap();
        assert_eq!(back.faces, mesh.faces);
        for (a, b) in back.positions_mm.iter().zip(&mesh.positions_mm) {
            assert!((*a - *b).length() < 1e-6);
        }
    }
}
