//! A quick picture for checking detections by eye: the scan seen from the scanner
//! (orthographic along −z), coloured by shape index (blue = cup 0, green = saddle 0.5,
//! red = cap 1) and shaded by the normal, with each detected point drawn as a white-ringed
//! dot (`facesynth landmarks SCAN --png OUT.png`). Headless: no GPU, the `image` crate only.

use crate::feature_points::Landmarks;
use crate::mesh::{FrontView, Mesh};
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
    let view = FrontView::at_scale(lo, hi, PIXELS_PER_MM, 4000);
    let (w, h) = (view.width_px, view.height_px);
    let mut img = image::RgbImage::from_pixel(w, h, image::Rgb([30, 30, 30]));
    view.rasterise(mesh, |x, y, v, b| {
        let si = b[0] * shape_index[v[0]] + b[1] * shape_index[v[1]] + b[2] * shape_index[v[2]];
        let nz = (b[0] * mesh.normals[v[0]].z
            + b[1] * mesh.normals[v[1]].z
            + b[2] * mesh.normals[v[2]].z)
            .clamp(0.0, 1.0);
        let shade = 0.35 + 0.65 * nz;
        img.put_pixel(
            x,
            y,
            image::Rgb(colour(si).map(|c| (c * shade * 255.0) as u8)),
        );
    });
    if let Some(lm) = landmarks {
        for (_, x) in lm.iter() {
            let (cx, cy) = view.to_px(x);
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
    crate::io::write_png(path, &img)
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
