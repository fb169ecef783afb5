//! Denoise panel (paper 2.1.1): method, k, w; run; before/after; moved vertices and spikes.

use super::super::EditorApp;
use super::super::document::{Command, SPIKE_MM};
use super::figures_grid;
use crate::cli::Overlay;
use crate::denoise::DenoiseMethod;
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
}
