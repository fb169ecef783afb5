//! The editor window (eframe + the wgpu viewport). Panels send commands, a worker thread does
//! the slow work (loading, and later denoising, registration, FEM), results come back over a
//! channel and are applied once per frame; the UI thread never blocks.

mod viewport_ui;
mod worker;

use crate::Mesh;
use crate::cli::ViewArgs;
use crate::feature_points::{FeaturePoint, Landmarks};
use crate::mesh::FaceCounts;
use crate::render::{DrawStyle, MeshData, OrbitCamera, ViewportRenderer};
use anyhow::{Result, anyhow};
use eframe::egui;
use glam::DVec3;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use worker::{Job, JobResult, Worker};

/// Opens the editor window and runs it until it is closed (or, with `--screenshot`, until the
/// screenshot is written). An error in screenshot mode (file unreadable, no GPU) is returned.
pub fn run(args: ViewArgs) -> Result<()> {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("facesynth")
            .with_inner_size([args.width as f32, args.height as f32]),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let outcome: Arc<Mutex<Option<String>>> = Arc::default();
    let outcome_app = outcome.clone();
    eframe::run_native(
        "facesynth",
        options,
        Box::new(move |cc| {
            let render_state = cc
                .wgpu_render_state
                .as_ref()
                .ok_or("the wgpu renderer is not available")?;
            ViewportRenderer::install(render_state);
            Ok(Box::new(EditorApp::new(cc, args, outcome_app)))
        }),
    )
    .map_err(|e| anyhow!("could not open the editor window: {e}"))?;
    let failure = outcome.lock().map(|mut o| o.take()).unwrap_or(None);
    match failure {
        Some(message) => Err(anyhow!(message)),
        None => Ok(()),
    }
}

/// What the viewport shows: one loaded mesh with its figures.
pub struct Scene {
    /// Display name (file name, or "generic face").
    pub name: String,
    pub path: Option<PathBuf>,
    pub mesh: Arc<Mesh>,
    pub gpu: Arc<MeshData>,
    pub counts: FaceCounts,
    pub bbox_mm: (DVec3, DVec3),
    pub landmarks: Option<Landmarks>,
    pub load_millis: f64,
}

/// View options (what is drawn, how).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewOptions {
    pub wireframe: bool,
    pub flat_shading: bool,
    pub show_landmarks: bool,
    pub show_labels: bool,
}

impl Default for ViewOptions {
    fn default() -> Self {
        ViewOptions {
            wireframe: false,
            flat_shading: false,
            show_landmarks: true,
            show_labels: true,
        }
    }
}

struct ScreenshotPlan {
    path: PathBuf,
    frames_drawn: u32,
    requested: bool,
    receiver: Option<std::sync::mpsc::Receiver<Arc<egui::ColorImage>>>,
}

pub struct EditorApp {
    worker: Worker,
    scene: Option<Scene>,
    scene_version: u64,
    loading: Option<String>,
    error: Option<String>,
    camera: OrbitCamera,
    view: ViewOptions,
    screenshot: Option<ScreenshotPlan>,
    outcome: Arc<Mutex<Option<String>>>,
}

impl EditorApp {
    fn new(
        cc: &eframe::CreationContext<'_>,
        args: ViewArgs,
        outcome: Arc<Mutex<Option<String>>>,
    ) -> Self {
        let worker = Worker::spawn(cc.egui_ctx.clone());
        let mut app = EditorApp {
            worker,
            scene: None,
            scene_version: 0,
            loading: None,
            error: None,
            camera: OrbitCamera::default(),
            view: ViewOptions::default(),
            screenshot: args.screenshot.map(|path| ScreenshotPlan {
                path,
                frames_drawn: 0,
                requested: false,
                receiver: None,
            }),
            outcome,
        };
        app.open(args.file);
        app
    }

    /// Loads a scan (or the generic face when `path` is `None`) on the worker.
    fn open(&mut self, path: Option<PathBuf>) {
        self.loading = Some(
            path.as_ref()
                .map_or("generic face".into(), |p| p.display().to_string()),
        );
        self.worker.send(Job::Load(path));
    }

    fn poll_worker(&mut self) {
        while let Some(result) = self.worker.try_recv() {
            match result {
                JobResult::Loaded(Ok(scene)) => {
                    self.camera = OrbitCamera::framing(scene.bbox_mm.0, scene.bbox_mm.1);
                    self.scene_version += 1;
                    self.scene = Some(*scene);
                    self.loading = None;
                    self.error = None;
                }
                JobResult::Loaded(Err(message)) => {
                    self.loading = None;
                    self.error = Some(message);
                }
            }
        }
    }

    fn side_panel_ui(&mut self, ui: &mut egui::Ui) {
        ui.heading("facesynth");
        ui.horizontal(|ui| {
            if ui.button("Open scan…").clicked()
                && let Some(path) = rfd::FileDialog::new()
                    .add_filter("meshes", &["wrl", "vrml", "obj", "ply", "xyz", "txt"])
                    .pick_file()
            {
                self.open(Some(path));
            }
            if ui.button("Generic face").clicked() {
                self.open(None);
            }
        });
        if let Some(what) = &self.loading {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label(format!("loading {what}…"));
            });
        }
        if let Some(error) = &self.error {
            ui.colored_label(egui::Color32::from_rgb(220, 80, 60), error);
        }
        ui.separator();
        if let Some(scene) = &self.scene {
            figures_ui(ui, scene);
        }
        ui.separator();
        ui.label(egui::RichText::new("View").strong());
        ui.checkbox(&mut self.view.wireframe, "Wireframe");
        ui.checkbox(&mut self.view.flat_shading, "Flat shading");
        ui.checkbox(&mut self.view.show_landmarks, "Feature points");
        ui.add_enabled(
            self.view.show_landmarks,
            egui::Checkbox::new(&mut self.view.show_labels, "Labels"),
        );
        ui.horizontal(|ui| {
            if ui.button("Front").clicked() {
                self.camera.yaw_rad = 0.0;
                self.camera.pitch_rad = 0.0;
            }
            if ui.button("Left side").clicked() {
                self.camera.yaw_rad = std::f64::consts::FRAC_PI_2;
                self.camera.pitch_rad = 0.0;
            }
            if ui.button("Right side").clicked() {
                self.camera.yaw_rad = -std::f64::consts::FRAC_PI_2;
                self.camera.pitch_rad = 0.0;
            }
            if ui.button("Reset").clicked()
                && let Some(scene) = &self.scene
            {
                self.camera = OrbitCamera::framing(scene.bbox_mm.0, scene.bbox_mm.1);
            }
        });
        ui.small("Drag: orbit · right/middle drag: pan · scroll: zoom · double-click: reset");
    }

    fn handle_screenshot(&mut self, ctx: &egui::Context) {
        let Some(plan) = &mut self.screenshot else {
            return;
        };
        if let Some(rx) = &plan.receiver
            && let Ok(image) = rx.try_recv()
        {
            let result = save_png(&plan.path, &image);
            if let Err(e) = result {
                self.set_outcome(e.to_string());
            }
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        if self.loading.is_some() {
            ctx.request_repaint();
            return;
        }
        if let Some(error) = &self.error {
            let message = error.clone();
            self.set_outcome(message);
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        let Some(plan) = &mut self.screenshot else {
            return;
        };
        plan.frames_drawn += 1;
        // A couple of frames first, so layout and GPU uploads have settled.
        if plan.frames_drawn >= 3 && !plan.requested {
            let (tx, rx) = std::sync::mpsc::channel();
            let repaint = ctx.clone();
            ctx.request_screenshot(move |image| {
                let _ = tx.send(image);
                repaint.request_repaint();
            });
            plan.requested = true;
            plan.receiver = Some(rx);
        }
        ctx.request_repaint();
    }

    fn set_outcome(&self, message: String) {
        if let Ok(mut o) = self.outcome.lock() {
            *o = Some(message);
        }
    }
}

fn figures_ui(ui: &mut egui::Ui, scene: &Scene) {
    ui.label(egui::RichText::new(&scene.name).strong());
    egui::Grid::new("figures").num_columns(2).show(ui, |ui| {
        let row = |ui: &mut egui::Ui, k: &str, v: String| {
            ui.label(k);
            ui.label(v);
            ui.end_row();
        };
        row(ui, "vertices", scene.mesh.vertex_count().to_string());
        row(ui, "faces", scene.counts.faces.to_string());
        row(ui, "quads", scene.counts.quads.to_string());
        row(ui, "triangles", scene.counts.triangles.to_string());
        let (lo, hi) = scene.bbox_mm;
        let size = hi - lo;
        row(
            ui,
            "size (mm)",
            format!("{:.1} × {:.1} × {:.1}", size.x, size.y, size.z),
        );
        row(
            ui,
            "bbox min (mm)",
            format!("{:.1}, {:.1}, {:.1}", lo.x, lo.y, lo.z),
        );
        row(
            ui,
            "bbox max (mm)",
            format!("{:.1}, {:.1}, {:.1}", hi.x, hi.y, hi.z),
        );
        row(ui, "loaded in", format!("{:.0} ms", scene.load_millis));
    });
}

fn save_png(path: &std::path::Path, image: &egui::ColorImage) -> Result<()> {
    let [w, h] = image.size;
    let bytes: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    let buffer = image::RgbaImage::from_raw(w as u32, h as u32, bytes)
        .ok_or_else(|| anyhow!("{}: screenshot has the wrong size", path.display()))?;
    let mut png = Vec::new();
    buffer
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| anyhow!("{}: cannot encode PNG: {e}", path.display()))?;
    crate::io::write_atomic(path, |w| w.write_all(&png))?;
    Ok(())
}

/// Marker colour of a feature point: subject's left green, right red, midline yellow.
pub fn feature_colour(p: FeaturePoint) -> [f32; 4] {
    let name = p.name();
    if name.ends_with("_left") {
        [0.15, 0.85, 0.3, 1.0]
    } else if name.ends_with("_right") {
        [0.95, 0.25, 0.2, 1.0]
    } else {
        [1.0, 0.85, 0.1, 1.0]
    }
}

impl eframe::App for EditorApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.poll_worker();
        egui::Panel::left("side")
            .resizable(true)
            .default_size(280.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.side_panel_ui(ui));
            });
        egui::CentralPanel::no_frame().show(ui, |ui| {
            let style = DrawStyle {
                flat: self.view.flat_shading,
                wireframe: self.view.wireframe,
                ..DrawStyle::default()
            };
            viewport_ui::viewport_ui(
                ui,
                &mut self.camera,
                self.scene.as_ref(),
                self.scene_version,
                style,
                &self.view,
            );
        });
        let ctx = ui.ctx().clone();
        self.handle_screenshot(&ctx);
    }
}
