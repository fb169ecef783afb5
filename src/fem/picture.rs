//! Front-view pictures of synthesized expressions: the deformed skin, Lambert-shaded, coloured
//! by displacement magnitude (blue 0 → red at `max_mm`), written as PNG. For looking at what
//! a preset does without the editor (`facesynth synthesize --png`).

use crate::Mesh;
use crate::mesh::FrontView;
use glam::DVec3;

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
/// by `magnitude_mm[v] / max_mm`, Lambert-shaded.
pub fn render_front(
    mesh: &Mesh,
    magnitude_mm: &[f64],
    max_mm: f64,
    width_px: u32,
) -> image::RgbImage {
    let (lo, hi) = mesh.bbox_mm().unwrap_or((DVec3::ZERO, DVec3::ONE));
    let view = FrontView::fit_width(lo, hi, width_px, 4.0);
    let mut img =
        image::RgbImage::from_pixel(view.width_px, view.height_px, image::Rgb([255, 255, 255]));
    let light = DVec3::new(-0.3, 0.4, 1.0).normalize();
    let shade = |i: usize| 0.35 + 0.65 * mesh.normals[i].dot(light).max(0.0);
    let colour = |i: usize| ramp(magnitude_mm[i] / max_mm.max(1e-9)) * shade(i);
    view.rasterise(mesh, |x, y, v, b| {
        let c = colour(v[0]) * b[0] + colour(v[1]) * b[1] + colour(v[2]) * b[2];
        let rgb = [c.x, c.y, c.z].map(|k| (k.clamp(0.0, 1.0) * 255.0) as u8);
        img.put_pixel(x, y, image::Rgb(rgb));
    });
    img
}
