//! Expressions panel: the presets; apply, blend, store the current activations as a preset,
//! save/load RON, revert; export the current expression or all of them.

use super::super::EditorApp;
use super::super::document::Command;
use eframe::egui;

pub fn expressions_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    if app.doc.fem.is_none() {
        ui.label("build the FEM model first (Materials)");
        return;
    }
    let names: Vec<String> = app
        .doc
        .edits
        .presets
        .names()
        .into_iter()
        .map(String::from)
        .collect();
    ui.horizontal_wrapped(|ui| {
        for name in &names {
            let on = app.doc.edits.applied_preset.as_deref() == Some(name.as_str());
            let tip = app
                .doc
                .edits
                .presets
                .get(name)
                .map(|e| e.description.clone())
                .unwrap_or_default();
            if ui.selectable_label(on, name).on_hover_text(tip).clicked() {
                app.commands.push(Command::ApplyPreset(name.clone()));
            }
        }
    });
    ui.horizontal(|ui| {
        if ui
            .button("Revert")
            .on_hover_text("back to the preset last applied")
            .clicked()
        {
            app.commands.push(Command::RevertActivations);
        }
        ui.text_edit_singleline(&mut app.preset_name);
        if ui.button("Store as preset").clicked() {
            app.commands.push(Command::StorePreset {
                name: app.preset_name.clone(),
                description: "made in the editor".into(),
            });
        }
    });
    ui.horizontal(|ui| {
        if ui.button("Save presets…").clicked()
            && let Some(path) = rfd::FileDialog::new()
                .add_filter("RON", &["ron"])
                .set_file_name("expressions.ron")
                .save_file()
        {
            app.commands.push(Command::SavePresets(path));
        }
        if ui.button("Load presets…").clicked()
            && let Some(path) = rfd::FileDialog::new()
                .add_filter("RON", &["ron"])
                .pick_file()
        {
            app.commands.push(Command::LoadPresets(path));
        }
    });
    ui.horizontal(|ui| {
        if ui.button("Export current…").clicked()
            && let Some(path) = rfd::FileDialog::new()
                .add_filter("mesh", &["obj", "ply"])
                .set_file_name("expression.obj")
                .save_file()
        {
            app.commands.push(Command::ExportExpression(path));
        }
        if ui.button("Export all…").clicked()
            && let Some(dir) = rfd::FileDialog::new().pick_folder()
        {
            app.commands.push(Command::ExportAllExpressions(dir));
        }
    });
    ui.horizontal(|ui| {
        if ui
            .add_enabled(!app.doc.busy(), egui::Button::new("Learn from scan…"))
            .on_hover_text(
                "fit the muscle and jaw activations to an expression scan of the same person",
            )
            .clicked()
            && let Some(path) = rfd::FileDialog::new()
                .add_filter("meshes", &["wrl", "vrml", "obj", "ply", "xyz", "txt"])
                .pick_file()
        {
            app.commands.push(Command::FitExpression(path));
        }
    });
    if let Some(f) = &app.doc.fit {
        super::figures_grid(
            ui,
            "fit-figures",
            &[
                ("learned from", f.name.clone()),
                (
                    "RMS to the scan",
                    format!(
                        "{:.2} mm neutral → {:.2} mm fitted",
                        f.rms_before_mm, f.rms_after_mm
                    ),
                ),
                (
                    "moving part (mouth, cheeks, chin)",
                    format!(
                        "{:.2} mm → {:.2} mm",
                        f.moving_rms_before_mm, f.moving_rms_after_mm
                    ),
                ),
                (
                    "explained by",
                    f.contributions_mm
                        .iter()
                        .take(3)
                        .map(|(n, c)| format!("{n} {c:.2}"))
                        .collect::<Vec<_>>()
                        .join(", "),
                ),
                (
                    "closest preset",
                    f.closest_preset
                        .as_ref()
                        .map_or("—".into(), |(n, d)| format!("{n} ({d:.2} mm)")),
                ),
                ("vertices used", f.vertices_used.to_string()),
                ("time", format!("{:.0} ms", f.millis)),
            ],
        );
    }
    if let Some(name) = app.doc.preset_name_hint.take() {
        app.preset_name = name;
    }
    egui::CollapsingHeader::new("blend")
        .default_open(false)
        .show(ui, |ui| {
            let mut changed = false;
            let mut started = false;
            for name in &names {
                let w = app.blend.entry(name.clone()).or_insert(0.0);
                let r = ui.add(egui::Slider::new(w, 0.0..=1.0).text(name));
                started |= r.drag_started();
                changed |= r.changed();
            }
            if started {
                app.commands.push(Command::Checkpoint);
            }
            if changed {
                let weights = app
                    .blend
                    .iter()
                    .filter(|(_, w)| **w > 0.0)
                    .map(|(k, w)| (k.clone(), *w))
                    .collect();
                app.commands.push(Command::BlendPresets(weights));
            }
        });
}
