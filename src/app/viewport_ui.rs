//! The central 3D viewport: camera interaction and the paint callback.

use super::{Scene, ViewOptions, feature_colour};
use crate::render::{DrawStyle, MarkerInstance, OrbitCamera, SceneItem, ViewportCallback};
use eframe::{egui, egui_wgpu};

/// Background of the viewport (linear RGB): a dark blue-grey that skin tones read well on.
const BACKGROUND: [f32; 4] = [0.045, 0.05, 0.065, 1.0];

pub fn viewport_ui(
    ui: &mut egui::Ui,
    camera: &mut OrbitCamera,
    scene: Option<&Scene>,
    scene_version: u64,
    style: DrawStyle,
    view: &ViewOptions,
) {
    let rect = ui.available_rect_before_wrap();
    let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
    let delta = response.drag_delta();
    if response.dragged_by(egui::PointerButton::Primary) {
        camera.orbit(delta.x as f64, delta.y as f64);
    } else if response.dragged_by(egui::PointerButton::Secondary)
        || response.dragged_by(egui::PointerButton::Middle)
    {
        camera.pan(delta.x as f64, delta.y as f64, rect.height() as f64);
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            camera.zoom((scroll as f64 * 0.002).exp());
        }
    }
    if response.double_clicked()
        && let Some(scene) = scene
    {
        *camera = OrbitCamera::framing(scene.bbox_mm.0, scene.bbox_mm.1);
    }

    let aspect = (rect.width() / rect.height().max(1.0)) as f64;
    let mut items = Vec::new();
    let mut markers = Vec::new();
    if let Some(scene) = scene {
        items.push(SceneItem {
            id: 1,
            version: scene_version,
            data: scene.gpu.clone(),
            style,
        });
        if view.show_landmarks
            && let Some(landmarks) = &scene.landmarks
        {
            for (p, x) in landmarks.iter() {
                markers.push(MarkerInstance {
                    centre: x.as_vec3().to_array(),
                    colour: feature_colour(p),
                });
            }
        }
    }
    let callback = ViewportCallback {
        view_proj: camera.view_proj(aspect),
        eye_mm: camera.eye_mm().as_vec3(),
        size_points: [rect.width(), rect.height()],
        background: BACKGROUND,
        items,
        markers,
        marker_radius_px: 5.0,
    };
    ui.painter()
        .add(egui_wgpu::Callback::new_paint_callback(rect, callback));

    if let Some(scene) = scene
        && view.show_landmarks
        && view.show_labels
        && let Some(landmarks) = &scene.landmarks
    {
        let painter = ui.painter_at(rect);
        for (p, x) in landmarks.iter() {
            if let Some([px, py]) =
                camera.project_to_pixels(x, rect.width() as f64, rect.height() as f64)
            {
                let pos = rect.min + egui::vec2(px as f32 + 8.0, py as f32 - 8.0);
                painter.text(
                    pos,
                    egui::Align2::LEFT_BOTTOM,
                    p.name(),
                    egui::FontId::proportional(11.0),
                    egui::Color32::from_rgb(235, 235, 220),
                );
            }
        }
    }
}
