//! The editor window (eframe + the wgpu viewport). Panels emit [`Command`]s; the app applies
//! them once per frame to the [`Document`]; slow work (loading, denoising, registration) runs
//! on the worker thread and comes back over a channel; the UI thread never blocks.

pub mod autosave;
pub mod document;
pub mod jobs;
mod measure;
mod panels;
pub mod session;
pub mod undo;
mod viewport_ui;
pub mod worker;

use crate::feature_points::FeaturePoint;
use crate::generic_face;
use crate::render::{OrbitCamera, ViewportRenderer};
use crate::view_options::{Overlay, ViewArgs};
use anyhow::{Result, anyhow};
use document::{Command, Document};
use eframe::egui;
use glam::DVec3;
use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use worker::Worker;

/// Opens the editor window and runs it until it is closed (or, with `--screenshot`, until the
/// screenshot is written). An error in screenshot mode (file unreadable, no GPU) is returned.
pub fn run(args: ViewArgs) -> Result<()> {
    let scripted = args.scripted();
    let session = match &args.session {
        Some(path) => session::load(path)?,
        None => Vec::new(),
    };
    if scripted {
        // eframe may create the storage folder again while shutting down (empty): sweep the
        // empty ones earlier scripted runs left behind.
        if let Ok(entries) = std::fs::read_dir(std::env::temp_dir()) {
            for e in entries.flatten() {
                if e.file_name()
                    .to_string_lossy()
                    .starts_with("facesynth-scripted-")
                {
                    let _ = std::fs::remove_dir(e.path());
                }
            }
        }
    }
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("facesynth")
            .with_inner_size([args.width as f32, args.height as f32]),
        renderer: eframe::Renderer::Wgpu,
        // A scripted run must neither read nor overwrite the user's saved settings (panel
        // states included), so it gets a storage folder of its own that starts empty.
        persist_window: !scripted,
        persistence_path: scripted.then(|| {
            std::env::temp_dir().join(format!("facesynth-scripted-{}", std::process::id()))
        }),
        ..Default::default()
    };
    let options_dir = options.persistence_path.clone();
    let outcome: Arc<Mutex<Option<String>>> = Arc::default();
    let outcome_app = outcome.clone();
    let result = eframe::run_native(
        "facesynth",
        options,
        Box::new(move |cc| {
            let render_state = cc
                .wgpu_render_state
                .as_ref()
                .ok_or("the wgpu renderer is not available")?;
            ViewportRenderer::install(render_state);
            Ok(Box::new(EditorApp::new(cc, args, session, outcome_app)))
        }),
    )
    .map_err(|e| anyhow!("could not open the editor window: {e}"));
    if let Some(dir) = &options_dir {
        let _ = std::fs::remove_dir_all(dir);
    }
    result?;
    let failure = outcome.lock().map(|mut o| o.take()).unwrap_or(None);
    match failure {
        Some(message) => Err(anyhow!(message)),
        None => Ok(()),
    }
}

/// View options (what is drawn, how); persisted between sessions.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct ViewOptions {
    pub wireframe: bool,
    pub flat_shading: bool,
    pub show_landmarks: bool,
    pub show_labels: bool,
    #[serde(skip)]
    pub overlay: Overlay,
    /// Draw the original scan instead of the denoised one (before/after toggle).
    #[serde(skip)]
    pub show_original: bool,
    /// Draw the scan under the registered generic face.
    pub show_scan: bool,
    /// Opacity of the scan when the registered face is drawn over it.
    pub scan_opacity: f32,
    /// Mark the vertices the denoising filter moved by more than 2 mm.
    pub show_spikes: bool,
    /// How the FEM model is drawn.
    pub layers: LayerView,
}

/// What of the layered FEM face is drawn.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct LayerView {
    /// Show the FEM face (deformed by the current activations) when one is built.
    pub show_fem: bool,
    pub skin: bool,
    /// The skin/fat interface (middle node layer).
    pub fat: bool,
    /// The cranium (bottom node layer, fixed).
    pub cranium: bool,
    /// Edges of the hexahedra (polygon edges of each layer and the edges through it).
    pub hex_edges: bool,
    /// Clip everything at `x > cut_x_mm` (scan/face frame) to see through the thickness.
    pub cutaway: bool,
    pub cut_x_mm: f32,
    /// Muscles as arrows from insertion towards origin, length ∝ force × activation.
    pub muscles: bool,
}

impl Default for LayerView {
    fn default() -> Self {
        LayerView {
            show_fem: true,
            skin: true,
            fat: false,
            cranium: false,
            hex_edges: false,
            cutaway: false,
            cut_x_mm: -8.0,
            muscles: false,
        }
    }
}

impl LayerView {
    fn from_args(shown: crate::view_options::LayersShown, muscles: bool) -> Self {
        use crate::view_options::LayersShown::*;
        let all = shown != Skin;
        LayerView {
            fat: all,
            cranium: all,
            hex_edges: all,
            cutaway: shown == Cutaway,
            muscles,
            ..LayerView::default()
        }
    }
}

impl Default for ViewOptions {
    fn default() -> Self {
        ViewOptions {
            wireframe: false,
            flat_shading: false,
            show_landmarks: true,
            show_labels: true,
            overlay: Overlay::Plain,
            show_original: false,
            show_scan: true,
            scan_opacity: 0.45,
            show_spikes: true,
            layers: LayerView::default(),
        }
    }
}

/// Settings kept in eframe's storage.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
#[serde(default)]
struct Settings {
    recent_files: Vec<PathBuf>,
    view: ViewOptions,
}

const SETTINGS_KEY: &str = "facesynth-settings";

struct ScreenshotPlan {
    path: PathBuf,
    frames_drawn: u32,
    requested: bool,
    receiver: Option<std::sync::mpsc::Receiver<Arc<egui::ColorImage>>>,
}

pub struct EditorApp {
    worker: Worker,
    doc: Document,
    camera: OrbitCamera,
    /// Bounding box the camera was last framed on (re-framed when a new scan arrives).
    framed_on: Option<(DVec3, DVec3)>,
    view: ViewOptions,
    settings: Settings,
    /// Commands from the panels, applied once per frame.
    commands: Vec<Command>,
    /// Scripted steps (command line, `--session`), each run when the previous one is done.
    script: VecDeque<session::Step>,
    /// Close the window once the script has run (`--screenshot`, `--session`).
    exit_when_done: bool,
    /// A scripted run: the user's saved settings are neither read nor written.
    scripted: bool,
    /// The feature point being dragged in the viewport (one undo step per drag).
    landmark_drag: Option<FeaturePoint>,
    /// The feature point the next click on the surface places.
    picking: Option<FeaturePoint>,
    /// The erase brush is on: clicks and primary drags on the scan erase vertices.
    erasing: bool,
    erase_radius_mm: f64,
    /// The current brush stroke has sent its undo checkpoint.
    erase_stroke_started: bool,
    denoise_params: crate::denoise::DenoiseParams,
    /// Materials being dragged (sent to the worker on release).
    fem_draft: Option<crate::fem::FemParams>,
    /// Muscle definitions being edited (sent on release).
    muscle_draft: Option<crate::fem::muscles::MuscleSet>,
    /// Activation sliders move both sides of a pair together.
    mirror_muscles: bool,
    /// Name for "store as preset".
    preset_name: String,
    /// Weights of the blend sliders.
    blend: std::collections::BTreeMap<String, f64>,
    /// Which side-panel sections start open: the last scripted step's, so a screenshot shows
    /// the figures of what it computed; all of them for an interactive start.
    panels_open: panels::PanelsOpen,
    /// Side-panel sections a session step opened (all others closed), applied next frame.
    panels_force: Option<Vec<String>>,
    scene: Option<viewport_ui::SceneCache>,
    /// Time of the last scene rebuild (basis sum + GPU mesh arrays), ms.
    scene_build_ms: f64,
    screenshot: Option<ScreenshotPlan>,
    measure: Option<measure::SliderMeasurement>,
    outcome: Arc<Mutex<Option<String>>>,
    /// Where the autosave goes; `None` in scripted runs (they neither offer nor write one).
    autosave_path: Option<PathBuf>,
    /// `ctx.input(|i| i.time)` of the last autosave (or of the start).
    last_autosave_s: f64,
    /// An earlier session's autosave, offered until the user answers.
    autosave_offer: Option<autosave::AutosaveState>,
    /// The window's close was held back because of unsaved changes: the prompt is shown.
    close_prompt: bool,
    /// The user answered the prompt: let the next close request through.
    allow_close: bool,
}

impl EditorApp {
    fn new(
        cc: &eframe::CreationContext<'_>,
        args: ViewArgs,
        session: Vec<session::Step>,
        outcome: Arc<Mutex<Option<String>>>,
    ) -> Self {
        let scripted = args.scripted();
        let settings: Settings = match (scripted, cc.storage) {
            (false, Some(storage)) => eframe::get_value(storage, SETTINGS_KEY).unwrap_or_default(),
            _ => Settings::default(),
        };
        let mut view = settings.view;
        if args.layers.is_some() || args.muscles {
            view.layers = LayerView::from_args(
                args.layers
                    .unwrap_or(crate::view_options::LayersShown::Skin),
                args.muscles,
            );
        }
        let fem = args.fem || args.expression.is_some() || args.fit.is_some();
        view.overlay = args.show.unwrap_or(if args.fit.is_some() {
            Overlay::FitResidual
        } else if fem {
            Overlay::Plain
        } else if args.register {
            Overlay::Registration
        } else if args.detect {
            Overlay::ShapeIndex
        } else if args.denoise {
            Overlay::Denoise
        } else {
            Overlay::Plain
        });
        let (args_yaw, args_pitch) = (args.yaw, args.pitch);
        let mut app = EditorApp {
            worker: Worker::spawn(cc.egui_ctx.clone()),
            doc: Document::new(generic_face::build()),
            camera: OrbitCamera::default(),
            framed_on: None,
            view,
            settings,
            commands: Vec::new(),
            script: script_from_args(&args)
                .into_iter()
                .chain(session)
                .chain(args.screenshot.clone().map(session::Step::Screenshot))
                .collect(),
            exit_when_done: args.screenshot.is_some() || args.session.is_some(),
            scripted,
            landmark_drag: None,
            picking: None,
            erasing: false,
            erase_radius_mm: document::ERASE_RADIUS_MM,
            erase_stroke_started: false,
            denoise_params: Default::default(),
            fem_draft: None,
            muscle_draft: None,
            mirror_muscles: true,
            preset_name: "my_expression".into(),
            blend: Default::default(),
            panels_open: panels::PanelsOpen::for_args(&args),
            panels_force: None,
            measure: args.measure_slider.map(measure::SliderMeasurement::new),
            scene: None,
            scene_build_ms: 0.0,
            screenshot: None,
            outcome,
            autosave_path: None,
            last_autosave_s: 0.0,
            autosave_offer: None,
            close_prompt: false,
            allow_close: false,
        };
        app.doc.landmarks_dir = args.landmarks_dir.clone();
        if !app.scripted {
            app.autosave_path = autosave::default_path();
            match app.autosave_path.as_deref().and_then(autosave::find) {
                Some(Ok(state)) => app.autosave_offer = Some(state),
                Some(Err(e)) => app.doc.error = Some(format!("autosave not offered: {e}")),
                None => {}
            }
        }
        if args.file.is_none() {
            let (lo, hi) = app.doc.generic.mesh.bbox_mm().unwrap_or_default();
            app.camera = OrbitCamera::framing(lo, hi);
            app.framed_on = Some((lo, hi));
        }
        app.camera.yaw_rad = args_yaw.to_radians();
        app.camera.pitch_rad = args_pitch.to_radians();
        app
    }

    /// Applies queued commands and worker results (once per frame, before drawing).
    fn update_document(&mut self) {
        while let Some(result) = self.worker.try_recv() {
            for job in self.doc.receive(result) {
                self.worker.send(job);
            }
        }
        if let Some(scan) = &self.doc.scan
            && self.framed_on != Some(scan.bbox_mm)
        {
            let (yaw, pitch) = (self.camera.yaw_rad, self.camera.pitch_rad);
            self.camera = OrbitCamera::framing(scan.bbox_mm.0, scan.bbox_mm.1);
            (self.camera.yaw_rad, self.camera.pitch_rad) = (yaw, pitch);
            self.framed_on = Some(scan.bbox_mm);
        }
        // A scripted step waits until the previous one (and its screenshot) has finished; a
        // failure stops the script.
        if !self.doc.busy()
            && self.commands.is_empty()
            && self.screenshot.is_none()
            && self.doc.error.is_none()
            && let Some(next) = self.script.pop_front()
        {
            match next.action(&self.doc) {
                Ok(session::Action::Commands(c)) => self.commands.extend(c),
                Ok(session::Action::View(change)) => self.change_view(change),
                Ok(session::Action::Screenshot(path)) => {
                    self.screenshot = Some(ScreenshotPlan {
                        path,
                        frames_drawn: 0,
                        requested: false,
                        receiver: None,
                    })
                }
                Err(e) => self.doc.error = Some(format!("session step {next:?}: {e}")),
            }
        }
        for command in std::mem::take(&mut self.commands) {
            if let Command::Open(Some(path)) = &command {
                self.remember(path.clone());
            }
            for job in self.doc.apply(command) {
                self.worker.send(job);
            }
        }
    }

    fn change_view(&mut self, change: session::ViewChange) {
        use session::ViewChange as V;
        match change {
            V::Show(o) => self.view.overlay = o,
            V::Layers(l) => {
                self.view.layers = LayerView::from_args(l, self.view.layers.muscles);
            }
            V::Muscles(b) => self.view.layers.muscles = b,
            V::ShowScan(b) => self.view.show_scan = b,
            V::ShowOriginal(b) => self.view.show_original = b,
            V::Panels(open) => self.panels_force = Some(open),
            V::Camera { yaw_deg, pitch_deg } => {
                self.camera.yaw_rad = yaw_deg.to_radians();
                self.camera.pitch_rad = pitch_deg.to_radians();
            }
        }
        self.doc.version += 1;
    }

    fn remember(&mut self, path: PathBuf) {
        let recent = &mut self.settings.recent_files;
        recent.retain(|p| *p != path);
        recent.insert(0, path);
        recent.truncate(10);
    }

    fn shortcuts(&mut self, ctx: &egui::Context) {
        let (undo, redo) = ctx.input_mut(|i| {
            let redo = i.consume_key(
                egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
                egui::Key::Z,
            );
            let undo = i.consume_key(egui::Modifiers::COMMAND, egui::Key::Z);
            (undo, redo)
        });
        if redo {
            self.commands.push(Command::Redo);
        } else if undo {
            self.commands.push(Command::Undo);
        }
        panels::review_ui::review_keys(self, ctx);
        if ctx.input(|i| i.key_pressed(egui::Key::Escape)) {
            self.picking = None;
            self.erasing = false;
        }
    }

    /// Scripted runs: takes the screenshot a step asked for, and closes the window when the
    /// script is done (or has failed).
    fn handle_screenshot(&mut self, ctx: &egui::Context) {
        if !self.exit_when_done {
            return;
        }
        if let Some(plan) = &self.screenshot
            && let Some(rx) = &plan.receiver
        {
            if let Ok(image) = rx.try_recv() {
                if let Err(e) = save_png(&plan.path, &image) {
                    self.set_outcome(e.to_string());
                    ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    return;
                }
                self.screenshot = None;
            }
            ctx.request_repaint();
            return;
        }
        if let Some(error) = &self.doc.error {
            let message = error.clone();
            self.set_outcome(message);
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        if self.doc.busy() || !self.commands.is_empty() {
            ctx.request_repaint();
            return;
        }
        let Some(plan) = &mut self.screenshot else {
            if self.script.is_empty() {
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            } else {
                ctx.request_repaint();
            }
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

    /// Writes the autosave every [`autosave::AUTOSAVE_INTERVAL_S`] while there are unsaved
    /// changes; removes it once everything is saved. Not before an earlier session's autosave
    /// has been answered (it would be overwritten).
    fn autosave_step(&mut self, ctx: &egui::Context) {
        let Some(path) = &self.autosave_path else {
            return;
        };
        if self.autosave_offer.is_some() {
            return;
        }
        let now = ctx.input(|i| i.time);
        if self.doc.is_dirty() {
            if now - self.last_autosave_s >= autosave::AUTOSAVE_INTERVAL_S {
                self.last_autosave_s = now;
                if let Err(e) = autosave::AutosaveState::of(&self.doc).write(path) {
                    self.doc.error = Some(format!("autosave failed: {e}"));
                }
            }
            // Come back for the next autosave even when nothing else repaints.
            ctx.request_repaint_after(std::time::Duration::from_secs_f64(
                autosave::AUTOSAVE_INTERVAL_S,
            ));
        } else if path.exists() {
            autosave::remove(path);
        }
    }

    /// Holds back a close with unsaved changes and asks what to do with them.
    fn close_guard(&mut self, ctx: &egui::Context) {
        if self.scripted {
            return; // closes when done
        }
        if ctx.input(|i| i.viewport().close_requested()) && !self.allow_close && self.doc.is_dirty()
        {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.close_prompt = true;
        }
        if self.close_prompt {
            self.close_prompt_ui(ctx);
        }
        if let Some(state) = self.autosave_offer.clone() {
            self.autosave_offer_ui(ctx, &state);
        }
    }

    fn close_prompt_ui(&mut self, ctx: &egui::Context) {
        let unsaved = self.doc.unsaved();
        let modal = egui::Modal::new(egui::Id::unique("unsaved-changes")).show(ctx, |ui| {
            ui.heading("Unsaved changes");
            if unsaved.is_empty() {
                ui.label("Everything is saved now.");
            } else {
                let names: Vec<&str> = unsaved.iter().map(|p| p.name()).collect();
                ui.label(format!("Not saved: {}.", names.join(", ")));
            }
            ui.horizontal(|ui| {
                if unsaved.contains(&document::Part::Landmarks)
                    && ui.button("Save landmarks…").clicked()
                    && let Some(path) = panels::landmarks_ui::save_dialog(self).save_file()
                {
                    self.commands.push(Command::SaveLandmarks(path));
                }
                if (unsaved.contains(&document::Part::Presets)
                    || unsaved.contains(&document::Part::Activations))
                    && ui.button("Save preset…").clicked()
                    && let Some(path) = rfd::FileDialog::new()
                        .add_filter("RON", &["ron"])
                        .set_file_name("expressions.ron")
                        .save_file()
                {
                    if unsaved.contains(&document::Part::Activations)
                        && !self.doc.edits.activations.is_empty()
                    {
                        // The sliders are kept as a preset in the saved file.
                        self.commands.push(Command::StorePreset {
                            name: self.preset_name.clone(),
                            description: "saved on close".into(),
                        });
                    }
                    self.commands.push(Command::SavePresets(path));
                }
                if unsaved.contains(&document::Part::Scan)
                    && ui.button("Save scan…").clicked()
                    && let Some(path) = panels::denoise_ui::save_scan_dialog(self)
                {
                    self.commands.push(Command::SaveScan(path));
                }
            });
            ui.separator();
            ui.horizontal(|ui| {
                let close = if unsaved.is_empty() {
                    "Close"
                } else {
                    "Discard and close"
                };
                if ui.button(close).clicked() {
                    self.doc.mark_all_saved();
                    if let Some(p) = &self.autosave_path {
                        autosave::remove(p);
                    }
                    self.allow_close = true;
                    ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                }
                if ui.button("Cancel").clicked() {
                    self.close_prompt = false;
                }
            });
        });
        if modal.should_close() {
            self.close_prompt = false;
        }
    }

    fn autosave_offer_ui(&mut self, ctx: &egui::Context, state: &autosave::AutosaveState) {
        egui::Modal::new(egui::Id::unique("restore-autosave")).show(ctx, |ui| {
            ui.heading("Restore autosave?");
            ui.label("The last session ended with unsaved changes.");
            let age_s = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs())
                .saturating_sub(state.saved_unix_s);
            ui.label(format!(
                "Saved {} min ago; scan: {}.",
                age_s / 60,
                state
                    .scan
                    .as_ref()
                    .map_or("none (generic face)".into(), |p| p.display().to_string())
            ));
            ui.horizontal(|ui| {
                if ui.button("Restore").clicked() {
                    for job in state.restore(&mut self.doc) {
                        self.worker.send(job);
                    }
                    if let Some(p) = &state.scan {
                        self.remember(p.clone());
                    }
                    self.autosave_offer = None;
                }
                if ui.button("Discard").clicked() {
                    if let Some(p) = &self.autosave_path {
                        autosave::remove(p);
                    }
                    self.autosave_offer = None;
                }
            });
        });
    }

    fn set_outcome(&self, message: String) {
        if let Ok(mut o) = self.outcome.lock() {
            *o = Some(message);
        }
    }
}

/// The command-line steps of `facesynth view`, in pipeline order.
fn script_from_args(args: &ViewArgs) -> Vec<session::Step> {
    use session::Step;
    let mut script = Vec::new();
    if let Some(dir) = &args.review {
        script.push(Step::Review(dir.clone()));
    }
    if let Some(file) = &args.file {
        script.push(Step::Open(file.clone()));
    }
    if args.denoise {
        script.push(Step::Denoise);
    }
    // A correction file beside the scan gives its points when it opens (see
    // `Document::load_correction_if_any`): no detection then.
    let corrected = args.file.as_deref().is_some_and(|f| {
        crate::pipeline::correction_for(f, None, args.landmarks_dir.as_deref()).is_some()
    });
    if let Some(l) = &args.landmarks {
        script.push(Step::LoadLandmarks(l.clone()));
    } else if args.file.is_some() && (args.detect || args.register) && !corrected {
        // Registration needs the points: detect them when none are given.
        script.push(Step::DetectLandmarks);
    }
    if args.register {
        script.push(Step::Register);
    }
    if args.fem || args.expression.is_some() || args.fit.is_some() || args.measure_slider.is_some()
    {
        script.push(Step::BuildFem);
    }
    if let Some(name) = &args.expression {
        script.push(Step::ApplyPreset(name.clone()));
    }
    if let Some(scan) = &args.fit {
        script.push(Step::FitExpression(scan.clone()));
    }
    script
}

fn save_png(path: &std::path::Path, image: &egui::ColorImage) -> Result<()> {
    let [w, h] = image.size;
    let bytes: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    let buffer = image::RgbaImage::from_raw(w as u32, h as u32, bytes)
        .ok_or_else(|| anyhow!("{}: screenshot has the wrong size", path.display()))?;
    crate::io::write_png(path, &buffer)?;
    Ok(())
}

/// Marker colour of a feature point: subject's left green, right red, midline yellow.
pub fn feature_colour(p: FeaturePoint) -> [f32; 4] {
    match p.side() {
        s if s > 0.0 => [0.15, 0.85, 0.3, 1.0],
        s if s < 0.0 => [0.95, 0.25, 0.2, 1.0],
        _ => [1.0, 0.85, 0.1, 1.0],
    }
}

impl eframe::App for EditorApp {
    /// The side panel's colour: the panel itself paints no background (see `ui`).
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        visuals.panel_fill.to_normalized_gamma_f32()
    }

    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.shortcuts(&ctx);
        self.update_document();
        // The panel's background is the window's clear colour (see `clear_color`), not a
        // filled rectangle: on a software renderer egui's blended full-height fill cost ~8 ms
        // a frame at 1280×800, a clear next to nothing.
        let panel_frame = egui::Frame::side_top_panel(ui.style()).fill(egui::Color32::TRANSPARENT);
        egui::Panel::left("side")
            .resizable(true)
            .default_size(330.0)
            .frame(panel_frame)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| panels::side_panel_ui(self, ui));
            });
        egui::CentralPanel::no_frame().show(ui, |ui| viewport_ui::viewport_ui(self, ui));
        if self.measure.is_some() {
            measure::step(self, &ctx, frame.info().cpu_usage);
        } else {
            self.handle_screenshot(&ctx);
        }
        self.close_guard(&ctx);
        self.autosave_step(&ctx);
    }

    /// Last chance to keep unsaved work: an exit that did not go through the prompt (a
    /// session logout, a signal) writes the autosave; a clean exit removes it.
    fn on_exit(&mut self) {
        let Some(path) = &self.autosave_path else {
            return;
        };
        if self.doc.is_dirty() && self.autosave_offer.is_none() {
            let _ = autosave::AutosaveState::of(&self.doc).write(path);
        } else if self.autosave_offer.is_none() {
            autosave::remove(path);
        }
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        if !self.scripted {
            self.settings.view = self.view;
            eframe::set_value(storage, SETTINGS_KEY, &self.settings);
        }
    }
}
