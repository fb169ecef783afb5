//! A quick picture for checking detections by eye: the scan seen from the scanner
//! (orthographic along −z), coloured by shape index (blue = cup 0, green = saddle 0.5,
//! red = cap 1) and shaded by the normal, with each detected point drawn as a white-ringed
//! dot (`facesynth landmarks SCAN --png OUT.png`). Headless: no GPU, the `image` crate only.

use crate::feature_points::Landmarks;
use crate::mesh::Mesh;
use crate::{Error, Result};
use std::path::Path;

/// Pixels per millimetre of the picture.
pub const PIXELS_PER_MM: f64 = 3.0;

/// Renders `mesh` coloured by `shape_index` with `landmarks` on top and writes a PNG.
pub fn write_png(
    path: &Path,
    mesh: &Mesh,
    shape_index: &[f64],
    landmarks: Option<&Landmarks>,
) -> Result<()> {
    let (lo, hi) = mesh
        .bbox_mm()
        .ok_or_else(|| Error::InvalidMesh("empty mesh".into()))?;
    if shape_index.len() != mesh.vertex_count() {
        return Err(Error::InvalidMesh(format!(
            "{} shape index values for {} vertices",
            shape_index.len(),
            mesh.vertex_count()
        )));
    }
    let s = PIXELS_PER_MM;
    let w = (((hi.x - lo.x) * s) as u32 + 1).min(4000);
    let h = (((hi.y - lo.y) * s) as u32 + 1).min(4000);
    let mut img = image::RgbImage::from_pixel(w, h, image::Rgb([30, 30, 30]));
    let mut depth = vec![f64::MIN; (w * h) as usize];
    let to_px = |x: f64, y: f64| ((x - lo.x) * s, (hi.y - y) * s);
    for t in mesh.triangles() {
        let p = t.map(|v| mesh.positions_mm[v as usize]);
        let q = p.map(|p| to_px(p.x, p.y));
        let area = (q[1].0 - q[0].0) * (q[2].1 - q[0].1) - (q[2].0 - q[0].0) * (q[1].1 - q[0].1);
        if area.abs() < 1e-12 {
            continue;
        }
        let x0 = q
            .iter()
            .map(|a| a.0)
            .fold(f64::MAX, f64::min)
            .floor()
            .max(0.0) as u32;
        let x1 = (q.iter().map(|a| a.0).fold(f64::MIN, f64::max).ceil() as u32).min(w - 1);
        let y0 = q
            .iter()
            .map(|a| a.1)
            .fold(f64::MAX, f64::min)
            .floor()
            .max(0.0) as u32;
        let y1 = (q.iter().map(|a| a.1).fold(f64::MIN, f64::max).ceil() as u32).min(h - 1);
        for py in y0..=y1 {
            for px in x0..=x1 {
                let (fx, fy) = (px as f64 + 0.5, py as f64 + 0.5);
                let b1 =
                    ((fx - q[0].0) * (q[2].1 - q[0].1) - (q[2].0 - q[0].0) * (fy - q[0].1)) / area;
                let b2 =
                    ((q[1].0 - q[0].0) * (fy - q[0].1) - (fx - q[0].0) * (q[1].1 - q[0].1)) / area;
                let b0 = 1.0 - b1 - b2;
                if b0 < -1e-9 || b1 < -1e-9 || b2 < -1e-9 {
                    continue;
                }
                let z = b0 * p[0].z + b1 * p[1].z + b2 * p[2].z;
                let k = (py * w + px) as usize;
                if z <= depth[k] {
                    continue;
                }
                depth[k] = z;
                let [a, b, c] = t.map(|v| v as usize);
                let si = b0 * shape_index[a] + b1 * shape_index[b] + b2 * shape_index[c];
                let nz = (b0 * mesh.normals[a].z + b1 * mesh.normals[b].z + b2 * mesh.normals[c].z)
                    .clamp(0.0, 1.0);
                let shade = 0.35 + 0.65 * nz;
                let col = colour(si).map(|c| (c * shade * 255.0) as u8);
                img.put_pixel(px, py, image::Rgb(col));
            }
        }
    }
    if let Some(lm) = landmarks {
        for (_, x) in lm.iter() {
            let (cx, cy) = to_px(x.x, x.y);
            for dy in -6i32..=6 {
                for dx in -6i32..=6 {
                    let r2 = dx * dx + dy * dy;
                    let (px, py) = (cx as i32 + dx, cy as i32 + dy);
                    if r2 > 36 || px < 0 || py < 0 || px >= w as i32 || py >= h as i32 {
                        continue;
                    }
                    let c = if r2 > 16 {
                        [255, 255, 255]
                    } else {
                        [255, 0, 255]
                    };
                    img.put_pixel(px as u32, py as u32, image::Rgb(c));
                }
            }
        }
    }
    // Through the atomic writer like every other output, so a killed run leaves no half PNG.
    crate::fem::picture::save_png(path, &img)
}

/// Blue (0) → green (0.5) → red (1).
fn colour(s: f64) -> [f64; 3] {
    let s = s.clamp(0.0, 1.0);
    if s < 0.5 {
        let t = s * 2.0;
        [0.1, 0.2 + 0.7 * t, 1.0 - 0.8 * t]
    } else {
        let t = (s - 0.5) * 2.0;
        [0.1 + 0.9 * t, 0.9 - 0.7 * t, 0.2 - 0.1 * t]
    }
}
