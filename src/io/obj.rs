//! Wavefront OBJ: `v` and `f` lines, polygons kept as they are (quads stay quads).
//!
//! A small line parser rather than tobj: tobj renumbers vertices in the order faces first use
//! them and drops unused ones (so vertex ids, and any per-vertex data or landmark ids tied to
//! them, would not survive a write/read round trip), and its index arithmetic can overflow on
//! hostile input. Here vertices keep their file order; `f` corners may be `v`, `v/vt`, `v//vn`
//! or `v/vt/vn` (only `v` is used; negative ids count back from the latest vertex); all
//! objects and groups are merged; `vt`, `vn`, materials, `l`/`p` elements and every other
//! statement are ignored (normals are recomputed from the faces).

use crate::io::{ReadLimits, push_clean_face};
use crate::mesh::Polygons;
use crate::{Error, Mesh, Result};
use glam::DVec3;
use std::io::Write;
use std::path::Path;

/// Parses OBJ text into one mesh.
pub fn parse(bytes: &[u8], path: &Path, limits: &ReadLimits) -> Result<Mesh> {
    if bytes.is_empty() {
        return Err(Error::invalid(path, "file is empty"));
    }
    let mut positions: Vec<DVec3> = Vec::new();
    let mut faces = Polygons::new();
    let mut face = Vec::new();
    for (k, raw) in bytes.split(|&c| c == b'\n').enumerate() {
        let line_no = k + 1;
        let err = |m: String| Error::syntax(path, line_no, m);
        let mut words = raw
            .split(|c| c.is_ascii_whitespace())
            .filter(|w| !w.is_empty());
        match words.next() {
            Some(b"v") => {
                let mut xyz = [0.0f64; 3];
                for (axis, slot) in xyz.iter_mut().enumerate() {
                    let w = words
                        .next()
                        .ok_or_else(|| err(format!("vertex has {axis} coordinates, need 3")))?;
                    let v = std::str::from_utf8(w)
                        .ok()
                        .and_then(|t| t.parse::<f64>().ok())
                        .ok_or_else(|| err(format!("'{}' is not a number", show(w))))?;
                    if !v.is_finite() {
                        return Err(err(format!(
                            "vertex {} has a non-finite coordinate '{}'",
                            positions.len() + 1,
                            show(w)
                        )));
                    }
                    *slot = v;
                }
                if positions.len() >= limits.max_vertices {
                    return Err(err(format!(
                        "more than {} vertices (the reader's limit; raise it with --max-vertices)",
                        limits.max_vertices
                    )));
                }
                positions.push(DVec3::from_array(xyz));
            }
            Some(b"f") => {
                face.clear();
                let n = positions.len() as i64;
                for w in words {
                    let v = w.split(|&c| c == b'/').next().unwrap_or(&[]);
                    let i = std::str::from_utf8(v)
                        .ok()
                        .and_then(|t| t.parse::<i64>().ok())
                        .ok_or_else(|| {
                            err(format!("'{}' is not a face corner (v/vt/vn)", show(w)))
                        })?;
                    // 1-based, or negative: relative to the vertices read so far.
                    let id = if i < 0 { n + i } else { i - 1 };
                    if !(0..n).contains(&id) {
                        return Err(err(format!(
                            "face refers to vertex {i}, but {n} vertices precede it"
                        )));
                    }
                    face.push(id as u32);
                }
                if face.len() < 3 {
                    return Err(err(format!(
                        "face has {} corners (need 3 or more)",
                        face.len()
                    )));
                }
                push_clean_face(&mut faces, &mut face, false);
            }
            _ => {}
        }
    }
    if positions.is_empty() {
        return Err(Error::invalid(
            path,
            "the file has no vertices (no 'v' lines)",
        ));
    }
    if faces.is_empty() {
        return Err(Error::invalid(
            path,
            "the file has no faces (no usable 'f' lines)",
        ));
    }
    Ok(Mesh::new(positions, faces))
}

/// A word for an error message: lossy text, cut to 40 characters.
fn show(w: &[u8]) -> String {
    String::from_utf8_lossy(w)
        .chars()
        .take(40)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect()
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
    fn vertex_order_and_unused_vertices_are_kept() {
        let text = b"# t\nv 0 0 0\nv 9 9 9\nv 1 0 0\nvt 0 0\nv 0 1 0\no a\ng b\n\
                     f 4/1 1/1/1 3//1\nf -1 -4 -2\nl 1 2\n";
        let m = parse(text, Path::new("t.obj"), &ReadLimits::default()).unwrap();
        assert_eq!(m.vertex_count(), 4);
        assert_eq!(m.positions_mm[1], DVec3::splat(9.0));
        assert_eq!(m.faces.get(0), &[3, 0, 2]);
        assert_eq!(m.faces.get(1), &[3, 0, 2]);
    }

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
