//! Landmarks panel: the 13 feature points (subject's left/right), click-to-place on the
//! surface, load/save JSON, undo/redo.

use super::super::document::Command;
use super::super::{EditorApp, feature_colour};
use crate::feature_points::FeaturePoint;
use eframe::egui;

/// The save dialog for landmark files: in the scan's folder, named as its correction file.
pub fn save_dialog(app: &EditorApp) -> rfd::FileDialog {
    let dialog = rfd::FileDialog::new().add_filter("landmarks", &["json"]);
    match app.doc.correction_path() {
        Some(path) => {
            let dialog = match path.parent().filter(|p| !p.as_os_str().is_empty()) {
                Some(dir) => dialog.set_directory(dir),
                None => dialog,
            };
            dialog.set_file_name(
                path.file_name()
                    .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            )
        }
        None => dialog.set_file_name("landmarks.json"),
    }
}

pub fn landmarks_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.small("left/right = the subject's own (left is +x, the image's right in a front view)");
    ui.horizontal(|ui| {
        let can = app.doc.scan.is_some() && !app.doc.busy();
        if ui
            .add_enabled(can, egui::Button::new("Detect"))
            .on_hover_text("paper 2.1.2 on the working (denoised) scan")
            .clicked()
        {
            app.commands.push(Command::DetectLandmarks);
            app.view.overlay = crate::view_options::Overlay::ShapeIndex;
        }
        if ui.button("Load JSON…").clicked()
            && let Some(path) = rfd::FileDialog::new()
                .add_filter("landmarks", &["json"])
                .pick_file()
        {
            app.commands.push(Command::LoadLandmarks(path));
        }
        if ui
            .add_enabled(
                app.doc.edits.landmarks.is_some(),
                egui::Button::new("Save JSON…"),
            )
            .clicked()
            && let Some(path) = save_dialog(app).save_file()
        {
            app.commands.push(Command::SaveLandmarks(path));
        }
    });
    if let Some(path) = app.doc.correction_path() {
        let name = path
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        if ui
            .add_enabled(
                app.doc.edits.landmarks.is_some(),
                egui::Button::new(format!("Save as correction ({name})")),
            )
            .on_hover_text(format!(
                "{}: register, augment, evaluate and fit-expression use these points instead \
                 of detecting",
                path.display()
            ))
            .clicked()
        {
            app.commands.push(Command::SaveCorrection);
        }
    }
    if let Some(file) = app.doc.landmark_file() {
        let moved = file.corrected.len();
        ui.small(match file.source {
            crate::pipeline::LandmarkSource::Corrected => {
                format!("points: corrected ({moved} placed by hand)")
            }
            s => format!("points: {}", s.name()),
        });
    }
    ui.horizontal(|ui| {
        if ui
            .add_enabled(app.doc.history.can_undo(), egui::Button::new("Undo"))
            .on_hover_text("Ctrl+Z")
            .clicked()
        {
            app.commands.push(Command::Undo);
        }
        if ui
            .add_enabled(app.doc.history.can_redo(), egui::Button::new("Redo"))
            .on_hover_text("Ctrl+Shift+Z")
            .clicked()
        {
            app.commands.push(Command::Redo);
        }
    });
    if let Some(p) = app.picking {
        ui.colored_label(
            egui::Color32::from_rgb(250, 210, 80),
            format!("click the surface to place {} (Esc cancels)", p.name()),
        );
    }
    if let Some(d) = &app.doc.detection {
        let symmetry = d
            .report
            .symmetry_roll_deg
            .map_or("not found".to_string(), |r| format!("{r:.1}°"));
        ui.small(format!(
            "detected in {:.0} ms; face region {} vertices, roll {:.1}° (symmetry {symmetry})",
            d.millis, d.report.face_vertices, d.report.roll_deg
        ));
        if let Some(l) = &d.report.localisation {
            use crate::landmarks::localise::{facing_and_up, yaw_pitch_roll_deg};
            let (yaw, pitch, roll) = yaw_pitch_roll_deg(l.face_from_scan);
            let (facing, up) = facing_and_up(l.face_from_scan);
            ui.small(format!(
                "face found: likeness {:.2}, facing {facing}, up {up}; yaw {yaw:.0}°, pitch \
                 {pitch:.0}°, roll {roll:.0}°",
                l.face_likeness
            ));
        }
        // Reasons not to trust the points: the user corrects them here before going on.
        for s in &d.report.suspect {
            ui.colored_label(
                egui::Color32::from_rgb(255, 80, 80),
                format!("suspect: {s}"),
            );
        }
        for w in &d.report.warnings {
            ui.colored_label(egui::Color32::from_rgb(255, 150, 40), w);
        }
    }
    let landmarks = app.doc.edits.landmarks;
    egui::Grid::new("landmarks")
        .num_columns(3)
        .striped(true)
        .show(ui, |ui| {
            for p in FeaturePoint::ALL {
                let [r, g, b, _] = feature_colour(p);
                let colour = egui::Color32::from_rgb(
                    (r * 255.0) as u8,
                    (g * 255.0) as u8,
                    (b * 255.0) as u8,
                );
                let flags = app
                    .doc
                    .detection
                    .as_ref()
                    .map(|d| d.implausible(p))
                    .unwrap_or_default();
                if flags.is_empty() {
                    ui.colored_label(colour, p.name());
                } else {
                    // Outside its Table 2 range: flagged for a look.
                    ui.colored_label(
                        egui::Color32::from_rgb(255, 150, 40),
                        // "!" rather than ⚠, which the default fonts lack (drawn as a box).
                        format!("! {}", p.name()),
                    )
                    .on_hover_text(flags.join("\n"));
                }
                match &landmarks {
                    Some(l) => {
                        let x = l.get(p);
                        ui.monospace(format!("{:7.1} {:7.1} {:7.1}", x.x, x.y, x.z));
                    }
                    None => {
                        ui.label("—");
                    }
                }
                let placing = app.picking == Some(p);
                if ui
                    .selectable_label(placing, "place")
                    .on_hover_text("then click the surface")
                    .clicked()
                {
                    app.picking = if placing { None } else { Some(p) };
                }
                ui.end_row();
            }
        });
}
