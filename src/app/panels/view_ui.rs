//! View panel: colouring, shading, overlays, camera presets.

use super::super::EditorApp;
use crate::render::OrbitCamera;
use crate::view_options::Overlay;
use eframe::egui;

pub fn view_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    let v = &mut app.view;
    ui.horizontal_wrapped(|ui| {
        ui.label("colour by");
        ui.selectable_value(&mut v.overlay, Overlay::Plain, "plain");
        ui.selectable_value(&mut v.overlay, Overlay::Denoise, "denoise");
        ui.selectable_value(&mut v.overlay, Overlay::Registration, "registration");
        ui.selectable_value(&mut v.overlay, Overlay::Displacement, "displacement");
        ui.selectable_value(&mut v.overlay, Overlay::FitResidual, "fit residual");
        ui.selectable_value(&mut v.overlay, Overlay::ShapeIndex, "shape index");
    });
    if app.doc.fem.is_some() {
        let l = &mut v.layers;
        ui.horizontal(|ui| {
            ui.checkbox(&mut l.show_fem, "FEM face");
            ui.checkbox(&mut l.skin, "skin");
            ui.checkbox(&mut l.fat, "fat");
            ui.checkbox(&mut l.cranium, "cranium");
        });
        ui.horizontal(|ui| {
            ui.checkbox(&mut l.hex_edges, "hexahedra");
            ui.checkbox(&mut l.muscles, "muscles");
            ui.checkbox(&mut l.cutaway, "cut-away");
        });
        if l.cutaway {
            ui.add(egui::Slider::new(&mut l.cut_x_mm, -70.0..=70.0).text("cut x from nose (mm)"));
        }
        if app.doc.scan.is_some() {
            ui.checkbox(&mut v.show_scan, "Scan under the FEM face");
        }
    }
    if v.overlay == Overlay::Registration {
        ui.checkbox(&mut v.show_scan, "Scan under the registered face");
        ui.add_enabled(
            v.show_scan,
            egui::Slider::new(&mut v.scan_opacity, 0.05..=1.0).text("scan opacity"),
        );
    }
    ui.checkbox(&mut v.wireframe, "Wireframe");
    ui.checkbox(&mut v.flat_shading, "Flat shading");
    ui.checkbox(&mut v.show_landmarks, "Feature points");
    ui.add_enabled(
        v.show_landmarks,
        egui::Checkbox::new(&mut v.show_labels, "Labels"),
    );
    ui.horizontal(|ui| {
        let cam = &mut app.camera;
        if ui.button("Front").clicked() {
            cam.yaw_rad = 0.0;
            cam.pitch_rad = 0.0;
        }
        if ui.button("Left side").clicked() {
            cam.yaw_rad = std::f64::consts::FRAC_PI_2;
            cam.pitch_rad = 0.0;
        }
        if ui.button("Right side").clicked() {
            cam.yaw_rad = -std::f64::consts::FRAC_PI_2;
            cam.pitch_rad = 0.0;
        }
        if ui.button("Reset").clicked()
            && let Some((lo, hi)) = app.framed_on
        {
            *cam = OrbitCamera::framing(lo, hi);
        }
    });
    ui.small("Drag: orbit · right/middle drag: pan · scroll: zoom · double-click: reset");
}
