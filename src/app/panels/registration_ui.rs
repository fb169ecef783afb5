//! Registration panel (paper 2.1.3): run, quality figures, landmark residuals, heat map.

use super::super::EditorApp;
use super::super::document::Command;
use super::figures_grid;
use crate::view_options::Overlay;
use eframe::egui;

pub fn registration_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.horizontal(|ui| {
        let can_run =
            app.doc.scan.is_some() && app.doc.edits.landmarks.is_some() && !app.doc.busy();
        if ui
            .add_enabled(can_run, egui::Button::new("Register"))
            .on_disabled_hover_text("needs a scan and its 13 feature points")
            .clicked()
        {
            app.commands.push(Command::Register);
            app.view.overlay = Overlay::Registration;
        }
        if ui
            .add_enabled(app.doc.registration.is_some(), egui::Button::new("Export…"))
            .clicked()
            && let Some(path) = rfd::FileDialog::new()
                .add_filter("mesh", &["obj", "ply"])
                .set_file_name("registered.obj")
                .save_file()
        {
            app.commands.push(Command::ExportRegistered(path));
        }
    });
    let Some(reg) = &app.doc.registration else {
        return;
    };
    if app.doc.registration_stale() {
        ui.colored_label(
            egui::Color32::from_rgb(250, 210, 80),
            "landmarks or scan changed since: register again",
        );
    }
    let r = &reg.result;
    let s = r.surface_distance_mm;
    figures_grid(
        ui,
        "registration-figures",
        &[
            ("rigid RMS", format!("{:.2} mm", r.rigid_rms_mm)),
            ("scale", format!("{:.3}", r.scan_from_generic.scale)),
            (
                "distance mean / p95 / max",
                format!("{:.2} / {:.2} / {:.2} mm", s.mean, s.p95, s.max),
            ),
            (
                "unmatched (filled)",
                format!(
                    "{} of {}",
                    r.unmatched_vertices.len(),
                    r.mesh.vertex_count()
                ),
            ),
            ("time", format!("{:.0} ms", r.millis)),
        ],
    );
    egui::CollapsingHeader::new("landmark residuals (mm)")
        .default_open(false)
        .show(ui, |ui| {
            egui::Grid::new("residuals").striped(true).show(ui, |ui| {
                for (p, d) in &r.landmark_residual_mm {
                    ui.label(p.name());
                    ui.monospace(format!("{d:.3}"));
                    ui.end_row();
                }
            });
        });
}
