//! Front-view pictures of synthesized expressions: the deformed skin, Lambert-shaded, coloured
//! by displacement magnitude (blue 0 → red at `max_mm`), written as PNG. For looking at what
//! a preset does without the editor (`facesynth synthesize --png`).

use crate::{Error, Mesh, Result};
use glam::DVec3;
use std::path::Path;

/// Colour ramp blue → cyan → green → yellow → red for `t` in [0, 1].
fn ramp(t: f64) -> DVec3 {
    let t = t.clamp(0.0, 1.0);
    let stops = [
        DVec3::new(0.15, 0.25, 0.85),
        DVec3::new(0.1, 0.75, 0.9),
        DVec3::new(0.2, 0.8, 0.3),
        DVec3::new(0.95, 0.85, 0.2),
        DVec3::new(0.9, 0.15, 0.1),
    ];
    let x = t * (stops.len() - 1) as f64;
    let i = (x.floor() as usize).min(stops.len() - 2);
    stops[i].lerp(stops[i + 1], x - i as f64)
}

/// Renders `mesh` seen from +z (orthographic, y up) at `width_px` wide, each vertex coloured
/// by `magnitude_mm[v] / max_mm`.
pub fn render_front(
    mesh: &Mesh,
    magnitude_mm: &[f64],
    max_mm: f64,
    width_px: u32,
) -> image::RgbImage {
    let (lo, hi) = mesh.bbox_mm().unwrap_or((DVec3::ZERO, DVec3::ONE));
    let margin = 4.0;
    let scale = (width_px as f64 - 2.0 * margin) / (hi.x - lo.x).max(1e-9);
    let height_px = ((hi.y - lo.y) * scale + 2.0 * margin).ceil() as u32;
    let (w, h) = (width_px as usize, height_px as usize);
    let mut depth = vec![f64::NEG_INFINITY; w * h];
    let mut img = image::RgbImage::from_pixel(width_px, height_px, image::Rgb([255, 255, 255]));
    let to_px = |p: DVec3| {
        (
            (p.x - lo.x) * scale + margin,
            (hi.y - p.y) * scale + margin,
            p.z,
        )
    };
    let light = DVec3::new(-0.3, 0.4, 1.0).normalize();
    for tri in mesh.triangles() {
        let v = tri.map(|i| i as usize);
        let p = v.map(|i| to_px(mesh.positions_mm[i]));
        let shade = v.map(|i| 0.35 + 0.65 * mesh.normals[i].dot(light).max(0.0));
        let colour = v.map(|i| ramp(magnitude_mm[i] / max_mm.max(1e-9)));
        let (x0, x1) = (
            p.iter().map(|q| q.0).fold(f64::INFINITY, f64::min),
            p.iter().map(|q| q.0).fold(f64::NEG_INFINITY, f64::max),
        );
        let (y0, y1) = (
            p.iter().map(|q| q.1).fold(f64::INFINITY, f64::min),
            p.iter().map(|q| q.1).fold(f64::NEG_INFINITY, f64::max),
        );
        let area = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
        if area.abs() < 1e-12 {
            continue;
        }
        for y in (y0.floor().max(0.0) as usize)..=(y1.ceil() as usize).min(h - 1) {
            for x in (x0.floor().max(0.0) as usize)..=(x1.ceil() as usize).min(w - 1) {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let b1 =
                    ((px - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (py - p[0].1)) / area;
                let b2 =
                    ((p[1].0 - p[0].0) * (py - p[0].1) - (px - p[0].0) * (p[1].1 - p[0].1)) / area;
                let b0 = 1.0 - b1 - b2;
                if b0 < 0.0 || b1 < 0.0 || b2 < 0.0 {
                    continue;
                }
                let z = b0 * p[0].2 + b1 * p[1].2 + b2 * p[2].2;
                if z <= depth[y * w + x] {
                    continue;
                }
                depth[y * w + x] = z;
                let c = (colour[0] * shade[0]) * b0
                    + (colour[1] * shade[1]) * b1
                    + (colour[2] * shade[2]) * b2;
                img.put_pixel(
                    x as u32,
                    y as u32,
                    image::Rgb([c.x, c.y, c.z].map(|k| (k.clamp(0.0, 1.0) * 255.0) as u8)),
                );
            }
        }
    }
    img
}

/// Writes a PNG atomically.
pub fn save_png(path: &Path, img: &image::RgbImage) -> Result<()> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::invalid(path, e.to_string()))?;
    crate::io::write_atomic(path, |w| w.write_all(&bytes))
}
