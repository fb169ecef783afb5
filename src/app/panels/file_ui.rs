//! File panel: open a scan or the generic face, recent files, export.

use super::super::EditorApp;
use super::super::document::Command;
use super::figures_grid;
use eframe::egui;

const MESH_EXTENSIONS: [&str; 6] = ["wrl", "vrml", "obj", "ply", "xyz", "txt"];

pub fn file_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.horizontal(|ui| {
        if ui.button("Open scan…").clicked()
            && let Some(path) = rfd::FileDialog::new()
                .add_filter("meshes", &MESH_EXTENSIONS)
                .pick_file()
        {
            app.commands.push(Command::Open(Some(path)));
        }
        if ui
            .button("Review folder…")
            .on_hover_text("every scan of a folder, worst feature points first")
            .clicked()
            && let Some(dir) = rfd::FileDialog::new().pick_folder()
        {
            app.commands.push(Command::Review(dir));
        }
        if ui.button("Generic face").clicked() {
            app.commands.push(Command::Open(None));
        }
        ui.menu_button("Recent", |ui| {
            if app.settings.recent_files.is_empty() {
                ui.label("(none)");
            }
            for path in app.settings.recent_files.clone() {
                if ui.button(path.display().to_string()).clicked() {
                    app.commands.push(Command::Open(Some(path)));
                    ui.close();
                }
            }
        });
    });
    if let Some(scan) = &app.doc.scan {
        ui.label(egui::RichText::new(&scan.name).strong());
        let (lo, hi) = scan.bbox_mm;
        let size = hi - lo;
        figures_grid(
            ui,
            "scan-figures",
            &[
                ("vertices", scan.mesh.vertex_count().to_string()),
                (
                    "faces",
                    format!(
                        "{} ({} quads, {} triangles)",
                        scan.counts.faces, scan.counts.quads, scan.counts.triangles
                    ),
                ),
                (
                    "size (mm)",
                    format!("{:.1} × {:.1} × {:.1}", size.x, size.y, size.z),
                ),
                ("file units", scan.units.describe()),
                ("loaded in", format!("{:.0} ms", scan.load_millis)),
            ],
        );
    } else {
        let mesh = &app.doc.generic.mesh;
        ui.label(egui::RichText::new("generic face").strong());
        let counts = mesh.face_counts();
        figures_grid(
            ui,
            "generic-figures",
            &[
                ("vertices", mesh.vertex_count().to_string()),
                ("quads", counts.quads.to_string()),
                ("triangles", counts.triangles.to_string()),
            ],
        );
    }
}
