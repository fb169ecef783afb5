//! Materials panel: E and ν per layer, layer thicknesses; each change re-solves on the worker
//! (numeric refactor only, or a new volume for thicknesses); the last solution stays shown.

use super::super::EditorApp;
use super::super::document::Command;
use super::figures_grid;
use eframe::egui;

pub fn materials_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    let Some(fem) = &app.doc.fem else {
        ui.horizontal(|ui| {
            let on = if app.doc.registration.is_some() {
                "Build FEM on the registered face"
            } else {
                "Build FEM on the generic face"
            };
            if ui
                .add_enabled(!app.doc.busy(), egui::Button::new(on))
                .clicked()
            {
                app.commands.push(Command::BuildFem);
            }
        });
        return;
    };
    let mut params = app.fem_draft.unwrap_or(app.doc.edits.fem);
    let mut changed = false;
    let mut started = false;
    let mut slider = |ui: &mut egui::Ui, value: &mut f64, range, text: &str, log: bool| {
        let r = ui.add(egui::Slider::new(value, range).logarithmic(log).text(text));
        // Re-solve when the drag ends (or on a typed value), not on every frame of the drag.
        let (s, f) = super::edit_phase(&r);
        started |= s;
        changed |= f;
    };
    ui.label("skin");
    slider(
        ui,
        &mut params.skin.young_modulus_pa,
        100.0..=100_000.0,
        "E (Pa)",
        true,
    );
    slider(ui, &mut params.skin.poisson_ratio, 0.0..=0.49, "ν", false);
    ui.label("fatty tissue");
    slider(
        ui,
        &mut params.fat.young_modulus_pa,
        10.0..=10_000.0,
        "E (Pa)",
        true,
    );
    slider(ui, &mut params.fat.poisson_ratio, 0.0..=0.49, "ν", false);
    ui.label("layers");
    slider(
        ui,
        &mut params.layers.skin_thickness_mm,
        0.5..=8.0,
        "skin (mm)",
        false,
    );
    slider(
        ui,
        &mut params.layers.fat_thickness_mm,
        1.0..=25.0,
        "fat (mm)",
        false,
    );
    ui.label("boundary")
        .on_hover_text("vertex rings of the outer border held in all three layers (1 = the paper's border nodes, 0 = only the cranium layer)");
    let r =
        ui.add(egui::Slider::new(&mut params.fixed_border_rings, 0..=6).text("fixed border rings"));
    let (s, f) = super::edit_phase(&r);
    started |= s;
    changed |= f;
    if started {
        app.commands.push(Command::Checkpoint);
    }
    // While a slider is dragged the value is a draft; it is sent (and solved) on release.
    app.fem_draft = (params != app.doc.edits.fem).then_some(params);
    if changed {
        app.commands.push(Command::SetFemParams(params));
        app.fem_draft = None;
    }
    if ui.button("Paper defaults").clicked() {
        app.commands.push(Command::Checkpoint);
        app.commands
            .push(Command::SetFemParams(crate::fem::FemParams::default()));
    }
    let solving = app.doc.pending.contains(&"solving");
    if solving {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.label("solving… (the last solution stays on screen)");
        });
    }
    figures_grid(
        ui,
        "fem-figures",
        &[
            ("free DOF", fem.dofs.to_string()),
            ("hexahedra", fem.volume.elements.len().to_string()),
            (
                "scaled Jacobian min / mean",
                format!(
                    "{:.2} / {:.2}",
                    fem.quality.min_scaled_jacobian, fem.quality.mean_scaled_jacobian
                ),
            ),
            ("last update", fem.last_update.clone()),
            ("worker time", format!("{:.0} ms", fem.millis)),
            (
                "factor / basis",
                format!(
                    "{:.0} / {:.0} ms",
                    fem.timings.factor_millis, fem.timings.basis_millis
                ),
            ),
        ],
    );
}
