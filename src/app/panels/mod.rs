//! The side panels, one file per step. Each reads the document and view state and pushes
//! [`Command`](super::document::Command)s; none of them computes anything itself.

pub(super) mod denoise_ui;
mod expressions_ui;
mod file_ui;
pub(super) mod landmarks_ui;
mod materials_ui;
mod muscles_ui;
mod registration_ui;
pub(super) mod review_ui;
mod view_ui;

use super::EditorApp;
use eframe::egui;

/// Initial open state of the side-panel sections.
#[derive(Debug, Clone, Copy)]
pub struct PanelsOpen {
    denoise: bool,
    landmarks: bool,
    registration: bool,
    fem: bool,
}

impl PanelsOpen {
    pub fn for_args(args: &crate::view_options::ViewArgs) -> Self {
        let fem = args.fem || args.expression.is_some() || args.fit.is_some();
        let registration = args.register && !fem;
        let landmarks = (args.detect || args.landmarks.is_some()) && !registration && !fem;
        let denoise = args.denoise && !landmarks && !registration && !fem;
        if denoise || landmarks || registration || fem {
            PanelsOpen {
                denoise,
                landmarks,
                registration,
                fem,
            }
        } else {
            PanelsOpen {
                denoise: true,
                landmarks: true,
                registration: true,
                fem: true,
            }
        }
    }
}

pub fn side_panel_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.heading("facesynth");
    file_ui::file_ui(app, ui);
    if !app.doc.pending.is_empty() {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.label(format!("{}…", app.doc.pending.join(", ")));
        });
    }
    if let Some(error) = &app.doc.error {
        ui.colored_label(egui::Color32::from_rgb(230, 90, 70), error);
    } else if let Some(status) = &app.doc.status {
        ui.small(status);
    }
    ui.separator();
    if app.doc.review.is_some() || app.doc.review_progress.is_some() {
        egui::CollapsingHeader::new("Review queue")
            .default_open(true)
            .show(ui, |ui| review_ui::review_ui(app, ui));
    }
    let open = app.panels_open;
    // A session step may set which sections are open (once; the user can toggle them again).
    let force = app.panels_force.take();
    let header = |title: &str, key: &str, default: bool| {
        let h = egui::CollapsingHeader::new(title).default_open(default);
        match &force {
            Some(keys) => h.open(Some(keys.iter().any(|k| k == key))),
            None => h,
        }
    };
    header("Denoise", "denoise", open.denoise).show(ui, |ui| denoise_ui::denoise_ui(app, ui));
    header("Landmarks", "landmarks", open.landmarks)
        .show(ui, |ui| landmarks_ui::landmarks_ui(app, ui));
    header("Registration", "registration", open.registration)
        .show(ui, |ui| registration_ui::registration_ui(app, ui));
    header("Materials (FEM)", "materials", open.fem)
        .show(ui, |ui| materials_ui::materials_ui(app, ui));
    header("Muscles", "muscles", false).show(ui, |ui| muscles_ui::muscles_ui(app, ui));
    header("Expressions", "expressions", open.fem)
        .show(ui, |ui| expressions_ui::expressions_ui(app, ui));
    header("View", "view", true).show(ui, |ui| view_ui::view_ui(app, ui));
}

/// The side-panel section names a session's `Panels` step takes.
pub const SECTIONS: [&str; 7] = [
    "denoise",
    "landmarks",
    "registration",
    "materials",
    "muscles",
    "expressions",
    "view",
];

/// How a value widget's edit progresses this frame: `(started, finished)`. A drag starts
/// (undo checkpoint) and finishes (send the value for solving) once each; a click or typed
/// value does both in the same frame. So one drag is one undo step and one re-solve.
pub fn edit_phase(r: &egui::Response) -> (bool, bool) {
    let instant = r.changed() && !r.dragged();
    (r.drag_started() || instant, r.drag_stopped() || instant)
}

/// A two-column grid of (label, value) rows.
pub fn figures_grid(ui: &mut egui::Ui, id: &str, rows: &[(&str, String)]) {
    egui::Grid::new(id).num_columns(2).show(ui, |ui| {
        for (k, v) in rows {
            ui.label(*k);
            ui.label(v);
            ui.end_row();
        }
    });
}
