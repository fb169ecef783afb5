//! Review queue panel: the folder's scans worst first, with their state and why; *Next* /
//! *Previous* (keys N / P, Page Down / Page Up) open the next scan with its points.

use super::super::EditorApp;
use super::super::document::Command;
use crate::pipeline::ReviewState;
use eframe::egui;

/// Colour of a state: failed red, suspect orange, detected grey, corrected green.
fn state_colour(s: ReviewState) -> egui::Color32 {
    match s {
        ReviewState::Failed => egui::Color32::from_rgb(230, 90, 70),
        ReviewState::Suspect => egui::Color32::from_rgb(240, 160, 60),
        ReviewState::Detected => egui::Color32::from_gray(170),
        ReviewState::Corrected => egui::Color32::from_rgb(110, 200, 110),
    }
}

pub fn review_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    if let Some(progress) = &app.doc.review_progress {
        let (done, total) = progress.get();
        let fraction = if total == 0 {
            0.0
        } else {
            done as f32 / total as f32
        };
        ui.add(
            egui::ProgressBar::new(fraction)
                .text(format!("detecting feature points: {done} of {total} scans")),
        );
        // The worker does not repaint per scan; keep the bar moving.
        ui.ctx()
            .request_repaint_after(std::time::Duration::from_millis(200));
    }
    let Some(review) = &app.doc.review else {
        return;
    };
    let busy = app.doc.busy();
    ui.horizontal(|ui| {
        if ui
            .add_enabled(!busy, egui::Button::new("< Previous"))
            .on_hover_text("P or Page Up")
            .clicked()
        {
            app.commands.push(Command::ReviewPrevious);
        }
        if ui
            .add_enabled(!busy, egui::Button::new("Next >"))
            .on_hover_text("N or Page Down; moved points are saved as the scan's correction")
            .clicked()
        {
            app.commands.push(Command::ReviewNext);
        }
        if let Some(counter) = app.doc.review_counter() {
            ui.label(counter);
        }
    });
    let current = review.current;
    let mut go = None;
    egui::ScrollArea::vertical()
        .id_salt("review-rows")
        .max_height(220.0)
        .show(ui, |ui| {
            egui::Grid::new("review-grid")
                .num_columns(3)
                .striped(true)
                .show(ui, |ui| {
                    for (i, e) in review.queue.entries.iter().enumerate() {
                        let name = e
                            .scan
                            .file_name()
                            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
                        let mark = if e.reviewed { "* " } else { "" };
                        if ui
                            .selectable_label(current == Some(i), format!("{mark}{name}"))
                            .on_hover_text(if e.reviewed {
                                "reviewed"
                            } else {
                                "not reviewed yet"
                            })
                            .clicked()
                            && !busy
                        {
                            go = Some(i);
                        }
                        ui.colored_label(state_colour(e.state), e.state.name());
                        let short: String = e.reason.chars().take(48).collect();
                        ui.label(short).on_hover_text(&e.reason);
                        ui.end_row();
                    }
                });
        });
    if let Some(i) = go {
        app.commands.push(Command::ReviewGo(i));
    }
}

/// N / P and Page Down / Page Up move through the queue (not while a text field has the keys).
pub fn review_keys(app: &mut EditorApp, ctx: &egui::Context) {
    if app.doc.review.is_none() || app.doc.busy() || ctx.egui_wants_keyboard_input() {
        return;
    }
    let (next, previous) = ctx.input(|i| {
        (
            i.key_pressed(egui::Key::N) || i.key_pressed(egui::Key::PageDown),
            i.key_pressed(egui::Key::P) || i.key_pressed(egui::Key::PageUp),
        )
    });
    if next {
        app.commands.push(Command::ReviewNext);
    } else if previous {
        app.commands.push(Command::ReviewPrevious);
    }
}
