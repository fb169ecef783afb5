//! Muscles panel: 18 muscle sliders, the soft-tissue loads' 8 and the jaw's four (instant preview
//! through the basis), mirror left↔right, and each pair's definition (force, insertion, origin, radius),
//! which re-solves that basis on the worker with the cached factorization.

use super::super::EditorApp;
use super::super::document::Command;
use eframe::egui;

pub fn muscles_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    if app.doc.fem.is_none() {
        ui.label("build the FEM model first (Materials)");
        return;
    }
    ui.checkbox(&mut app.mirror_muscles, "Mirror left ↔ right");
    let mut activations = app.doc.edits.activations.clone();
    let mut started = false;
    let mut changed = false;
    let pairs: Vec<String> = app
        .doc
        .edits
        .muscles
        .pairs()
        .map(|d| d.name.clone())
        .collect();
    egui::Grid::new("activations")
        .num_columns(2)
        .show(ui, |ui| {
            for pair in &pairs {
                for side in ["left", "right"] {
                    let name = format!("{pair}_{side}");
                    let mut a = activations.get(&name).copied().unwrap_or(0.0);
                    ui.label(&name);
                    let r = ui.add(
                        egui::Slider::new(&mut a, 0.0..=2.0)
                            .clamping(egui::SliderClamping::Never)
                            .fixed_decimals(2),
                    );
                    started |= super::edit_phase(&r).0;
                    if r.changed() {
                        changed = true;
                        activations.insert(name.clone(), a);
                        if app.mirror_muscles {
                            let other = if side == "left" { "right" } else { "left" };
                            activations.insert(format!("{pair}_{other}"), a);
                        }
                    }
                    ui.end_row();
                }
            }
            // The jaw is bone, not a muscle: degrees and millimetres, never mirrored (jaw_left
            // and jaw_right are opposite shifts).
            let fem = app.doc.fem.as_ref().expect("checked above");
            // In `jaw::ACTUATORS` order: open (degrees), left, right, forward (mm).
            let ranges = [(20.0, "°"), (8.0, " mm"), (8.0, " mm"), (8.0, " mm")];
            let jaw: &[&str] = if fem.muscle_set.jaw.is_some() {
                &crate::fem::jaw::ACTUATORS
            } else {
                &[]
            };
            for (&name, (max, unit)) in jaw.iter().zip(ranges) {
                let range = 0.0..=max;
                let mut a = activations.get(name).copied().unwrap_or(0.0);
                ui.label(name);
                // No clamping: a fitted or blended value beyond the range must survive showing
                // the panel.
                let r = ui.add(
                    egui::Slider::new(&mut a, range)
                        .clamping(egui::SliderClamping::Never)
                        .fixed_decimals(1)
                        .suffix(unit),
                );
                started |= super::edit_phase(&r).0;
                if r.changed() {
                    changed = true;
                    activations.insert(name.to_string(), a);
                }
                ui.end_row();
            }
        });
    if started {
        app.commands.push(Command::Checkpoint);
    }
    if changed {
        activations.retain(|_, a| *a != 0.0);
        app.commands.push(Command::SetActivations(activations));
    }
    ui.horizontal(|ui| {
        if ui.button("Neutral").clicked() {
            app.commands.push(Command::Checkpoint);
            app.commands
                .push(Command::SetActivations(Default::default()));
        }
        ui.checkbox(&mut app.view.layers.muscles, "Show arrows");
    });

    egui::CollapsingHeader::new("definitions (per pair; the right side is the mirror)")
        .default_open(false)
        .show(ui, |ui| {
            let mut set = app
                .muscle_draft
                .clone()
                .unwrap_or_else(|| app.doc.edits.muscles.clone());
            let mut started = false;
            let mut commit = false;
            for def in set.pairs_mut() {
                ui.collapsing(&def.name, |ui| {
                    if !def.description.is_empty() {
                        ui.small(&def.description);
                    }
                    let mut track = |r: egui::Response| {
                        let (s, f) = super::edit_phase(&r);
                        started |= s;
                        commit |= f;
                    };
                    track(ui.add(egui::Slider::new(&mut def.force_n, 0.0..=1.0).text("force (N)")));
                    track(
                        ui.add(
                            egui::Slider::new(&mut def.radius, 0.05..=1.2)
                                .text("fall-off radius (face units)"),
                        ),
                    );
                    for (label, anchor) in [
                        ("insertion", &mut def.insertion),
                        ("origin", &mut def.origin),
                    ] {
                        ui.horizontal(|ui| {
                            ui.label(format!("{label} @ {}", anchor.point));
                            for (axis, v) in ["x", "y", "z"].iter().zip(anchor.offset.iter_mut()) {
                                track(
                                    ui.add(
                                        egui::DragValue::new(v)
                                            .speed(0.005)
                                            .prefix(format!("{axis} ")),
                                    ),
                                );
                            }
                        });
                    }
                });
            }
            if started {
                app.commands.push(Command::Checkpoint);
            }
            app.muscle_draft = (set != app.doc.edits.muscles).then(|| set.clone());
            if commit {
                app.commands.push(Command::SetMuscles(set));
                app.muscle_draft = None;
            }
        });
}
