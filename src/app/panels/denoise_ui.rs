//! Denoise panel (paper 2.1.1): method, k, w; run; before/after; moved vertices and spikes.

use super::super::EditorApp;
use super::super::document::Command;
use super::super::jobs::SPIKE_MM;
use super::figures_grid;
use crate::denoise::DenoiseMethod;
use crate::view_options::Overlay;
use eframe::egui;

pub fn denoise_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    let p = &mut app.denoise_params;
    egui::ComboBox::from_label("method")
        .selected_text(p.method.name())
        .show_ui(ui, |ui| {
            for m in [
                DenoiseMethod::MedianLaplacian,
                DenoiseMethod::Laplacian,
                DenoiseMethod::Taubin,
            ] {
                ui.selectable_value(&mut p.method, m, m.name());
            }
        });
    ui.add(egui::Slider::new(&mut p.iterations, 0..=50).text("iterations k"));
    ui.add_enabled(
        p.method == DenoiseMethod::MedianLaplacian,
        egui::Slider::new(&mut p.w, 0.05..=1.0).text("change fraction w"),
    );
    ui.add_enabled(
        p.method == DenoiseMethod::MedianLaplacian && p.remove_unrepairable,
        egui::Slider::new(&mut p.repair_max_mm, 1.0..=50.0)
            .logarithmic(true)
            .suffix(" mm")
            .text("largest repair"),
    )
    .on_hover_text("a vertex the filter would move further than this is removed instead");
    ui.horizontal(|ui| {
        let can_run = app.doc.scan.is_some() && !app.doc.busy();
        if ui.add_enabled(can_run, egui::Button::new("Run")).clicked() {
            app.commands.push(Command::Denoise(app.denoise_params));
            app.view.overlay = Overlay::Denoise;
        }
        if ui
            .add_enabled(app.doc.denoised.is_some(), egui::Button::new("Discard"))
            .clicked()
        {
            app.commands.push(Command::ClearDenoise);
        }
        if ui.button("Defaults").clicked() {
            app.denoise_params = Default::default();
        }
    });
    if let Some(d) = &app.doc.denoised {
        figures_grid(
            ui,
            "denoise-figures",
            &[
                ("iterations run", d.report.iterations_run.to_string()),
                ("vertices moved", d.report.vertices_moved.to_string()),
                ("vertices removed", d.report.vertices_removed.to_string()),
                (
                    &format!("spikes (> {SPIKE_MM} mm, or removed)"),
                    d.spikes.len().to_string(),
                ),
                (
                    "max move",
                    format!("{:.2} mm", d.report.max_displacement_mm),
                ),
                (
                    "mean move",
                    format!("{:.3} mm", d.report.mean_displacement_mm),
                ),
                ("time", format!("{:.0} ms", d.millis)),
            ],
        );
        ui.checkbox(&mut app.view.show_original, "Show the original (before)");
        ui.checkbox(&mut app.view.show_spikes, "Mark removed spikes");
    }
    erase_ui(app, ui);
}

/// Erasing by hand what the filter left (a spike cluster, hair, an ear), and saving the
/// corrected scan for the batch commands.
fn erase_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.separator();
    let has_scan = app.doc.working.is_some();
    ui.horizontal(|ui| {
        ui.add_enabled_ui(has_scan, |ui| {
            ui.toggle_value(&mut app.erasing, "Erase brush")
                .on_hover_text("click or drag on the scan to erase; Shift + drag orbits; Esc ends");
        });
        ui.add(
            egui::Slider::new(&mut app.erase_radius_mm, 0.5..=30.0)
                .logarithmic(true)
                .suffix(" mm")
                .text("radius"),
        );
    });
    let erased = app.doc.edits.erased.len();
    let working = app
        .doc
        .working
        .as_ref()
        .map_or(0, |w| w.mesh.vertex_count());
    ui.label(format!(
        "{erased} vertices erased by hand; working scan {working} vertices"
    ));
    ui.horizontal(|ui| {
        if ui
            .add_enabled(erased > 0, egui::Button::new("Restore all"))
            .clicked()
        {
            app.commands.push(Command::RestoreErased);
        }
        if ui
            .add_enabled(has_scan, egui::Button::new("Save scan…"))
            .on_hover_text("the working scan: denoised, erased vertices gone (.obj/.ply)")
            .clicked()
            && let Some(path) = save_scan_dialog(app)
        {
            app.commands.push(Command::SaveScan(path));
        }
    });
    if !has_scan {
        app.erasing = false;
    }
}

/// Asks where to write the working scan (`<scan>_clean.ply` beside the scan by default).
pub fn save_scan_dialog(app: &EditorApp) -> Option<std::path::PathBuf> {
    let mut dialog = rfd::FileDialog::new().add_filter("mesh", &["ply", "obj"]);
    if let Some(scan) = &app.doc.scan {
        if let Some(dir) = scan.path.parent() {
            dialog = dialog.set_directory(dir);
        }
        let stem = scan
            .path
            .file_stem()
            .map_or("scan".into(), |s| s.to_string_lossy());
        dialog = dialog.set_file_name(format!("{stem}_clean.ply"));
    }
    dialog.save_file()
}
