//! The central 3D viewport: which meshes and overlays are drawn, camera interaction, picking,
//! labels and the colour legend. GPU meshes are rebuilt only when the document or the
//! colouring changes, not per frame.

use super::{EditorApp, LayerView, feature_colour};
use crate::Mesh;
use crate::feature_points::FeaturePoint;
use crate::mesh::pick::ray_hit;
use crate::mesh::simplify;
use crate::render::colormap::ColourScale;
use crate::render::{
    DrawStyle, MarkerInstance, MeshData, OrbitCamera, SceneItem, ViewportCallback,
};
use crate::view_options::Overlay;
use eframe::{egui, egui_wgpu};
use glam::DVec3;
use std::sync::Arc;

/// Background of the viewport (linear RGB): a dark blue-grey that skin tones read well on.
const BACKGROUND: [f32; 4] = [0.045, 0.05, 0.065, 1.0];
const SPIKE_COLOUR: [f32; 4] = [0.95, 0.2, 0.9, 1.0];
/// The scan under the FEM face is drawn clustered to cells of this many median edges: a
/// quarter of the triangles (a 1 mm GavabDB grid is ~2 px on screen at the default zoom, so
/// the full mesh adds triangles, not detail), which took ~3 ms off a software-rendered frame.
/// Picking and every computation use the full scan.
const UNDERLAY_CELL_EDGES: f64 = 2.0;
/// Scan polygons whose corners all lie within this distance of the FEM face (and are not
/// within two polygons of one that is farther) are left out of the underlay: the opaque face,
/// drawn in front, hides them anyway (the software renderer
/// still pays for every tiny hidden triangle). The scan beyond the face — hair, ears, neck,
/// whatever the registration did not cover — stays.
const UNDERLAY_HIDDEN_MM: f64 = 1.5;

/// The scan drawn under the FEM face (see [`underlay_mesh`]), for the face it was cut for.
#[derive(Clone)]
struct Underlay {
    scan: Arc<Mesh>,
    face: Arc<Mesh>,
    data: Arc<MeshData>,
}

/// The part of `scan` the FEM `face` does not hide, clustered for display (see
/// [`UNDERLAY_HIDDEN_MM`], [`UNDERLAY_CELL_EDGES`]).
fn underlay_mesh(scan: &Mesh, face: &Mesh) -> Mesh {
    let index = crate::mesh::SurfaceIndex::new(face, 4.0);
    let covered: Vec<bool> = scan
        .positions_mm
        .iter()
        .map(|&p| index.closest(p, UNDERLAY_HIDDEN_MM).is_some())
        .collect();
    // Two rings more than the uncovered polygons: a scan vertex just beyond the face's edge is
    // within the distance too, and dropping it would open a gap along the outline.
    let mut shown: Vec<bool> = covered.iter().map(|c| !c).collect();
    for _ in 0..2 {
        let mut grown = shown.clone();
        for poly in scan.faces.iter() {
            if poly.iter().any(|&v| shown[v as usize]) {
                poly.iter().for_each(|&v| grown[v as usize] = true);
            }
        }
        shown = grown;
    }
    let visible = scan
        .faces
        .iter()
        .filter(|poly| poly.iter().any(|&v| shown[v as usize]));
    // `cluster` reads positions and faces only: no normals to compute here.
    let cut = Mesh {
        positions_mm: scan.positions_mm.clone(),
        normals: Vec::new(),
        faces: crate::mesh::Polygons::from_polygons(visible),
    };
    simplify::cluster(&cut, UNDERLAY_CELL_EDGES * simplify::median_edge_mm(scan))
}

/// Meshes of the current scene, built for the GPU once per (document version, view), not per
/// frame.
pub struct SceneCache {
    key: SceneKey,
    /// (id, data, role) — the role decides the draw style each frame; the renderer re-uploads
    /// a mesh when its data is a new `Arc`.
    meshes: Vec<(u64, Arc<MeshData>, Role)>,
    /// The scan under the FEM face, its GPU data and version, kept across rebuilds: a slider
    /// drag rebuilds the face every frame but never changes the scan (re-uploading its 26k
    /// triangles each frame cost the software renderer several ms).
    underlay: Option<Underlay>,
    legend: Option<ColourScale>,
    /// The mesh clicks are picked on (the surface shown), for placing landmarks.
    pick_surface: Option<Arc<Mesh>>,
}

#[derive(Clone, Copy, PartialEq)]
struct SceneKey {
    version: u64,
    overlay: Overlay,
    show_original: bool,
    layers: LayerView,
}

#[derive(Clone, Copy, PartialEq)]
enum Role {
    /// The main surface (scan, generic face alone, or the FEM skin).
    Main,
    /// The scan drawn under the registered or FEM face.
    Underlay,
    /// The registered generic face.
    Registered,
    /// An inner FEM layer surface, drawn in its own colour.
    Layer([f32; 3]),
    /// Line-only items (hex edges through the thickness, muscle arrows).
    Lines,
}

fn denoise_scale(displacement_mm: &[f64]) -> ColourScale {
    ColourScale::magnitude(displacement_mm, 0.1, "denoise move (mm)")
}

/// Fixed 0 – [`crate::fem::fit::RESIDUAL_MAX_MM`], as `fit-expression --residual-png`.
fn fit_residual_scale() -> ColourScale {
    ColourScale {
        ramp: crate::render::colormap::Ramp::Sequential,
        min: 0.0,
        max: crate::fem::fit::RESIDUAL_MAX_MM,
        title: "distance to the expression scan (mm)".into(),
    }
}

fn registration_scale(distance_mm: &[f64]) -> ColourScale {
    // Fixed 0–3 mm: figures are comparable between scans; grey = unmatched (filled).
    ColourScale {
        ramp: crate::render::colormap::Ramp::Sequential,
        min: 0.0,
        max: 3.0,
        title: if distance_mm.iter().any(|d| d.is_nan()) {
            "distance to scan (mm; grey: filled)".into()
        } else {
            "distance to scan (mm)".into()
        },
    }
}

const FAT_COLOUR: [f32; 3] = [0.95, 0.8, 0.35];
const CRANIUM_COLOUR: [f32; 3] = [0.85, 0.85, 0.8];

fn scene_key(app: &EditorApp) -> SceneKey {
    SceneKey {
        version: app.doc.version,
        overlay: app.view.overlay,
        show_original: app.view.show_original,
        layers: app.view.layers,
    }
}

fn build_scene(app: &EditorApp) -> SceneCache {
    let previous = app.scene.as_ref();
    let doc = &app.doc;
    let view = &app.view;
    let mut meshes = Vec::new();
    // The last cut is kept through scenes that do not draw the FEM face (another overlay, the
    // face hidden), so switching back does not cut it again; it is only used if the scan and
    // the face are still the same `Arc`s.
    let mut underlay = previous.and_then(|p| p.underlay.clone());
    let mut legend = None;
    let pick_surface;
    let shown_scan = match (&doc.scan, &doc.working) {
        (Some(scan), _) if view.show_original => Some(scan.mesh.clone()),
        (_, Some(w)) => Some(w.mesh.clone()),
        _ => None,
    };
    let fem = doc.fem.as_ref().filter(|_| {
        view.layers.show_fem
            && matches!(
                view.overlay,
                Overlay::Plain | Overlay::Displacement | Overlay::FitResidual
            )
    });
    let registered = doc
        .registration
        .as_ref()
        .filter(|_| view.overlay == Overlay::Registration);
    if let Some(fem) = fem {
        let n = fem.surface.vertex_count();
        let u = fem.displacement(&doc.edits.activations);
        let layer_mesh = |k: usize| {
            let positions = (0..n)
                .map(|v| fem.volume.nodes_mm[k * n + v] + u[k * n + v])
                .collect();
            Mesh::new(positions, fem.surface.faces.clone())
        };
        let skin = Arc::new(layer_mesh(0));
        if view.layers.skin {
            let colours = match view.overlay {
                Overlay::Displacement => {
                    let magnitude: Vec<f64> = u[..n].iter().map(|d| d.length()).collect();
                    let scale = ColourScale::magnitude(&magnitude, 0.5, "displacement (mm)");
                    let c = scale.colours(&magnitude);
                    legend = Some(scale);
                    Some(c)
                }
                Overlay::FitResidual => doc.fit.as_ref().and_then(|f| {
                    let distance = f.residual_magnitude(n)?;
                    let scale = fit_residual_scale();
                    let c = scale.colours(&distance);
                    legend = Some(scale);
                    Some(c)
                }),
                _ => None,
            };
            meshes.push((
                10,
                Arc::new(MeshData::from_mesh(&skin, colours.as_deref())),
                Role::Main,
            ));
        }
        if view.layers.fat {
            let m = layer_mesh(1);
            meshes.push((
                11,
                Arc::new(MeshData::from_mesh(&m, None)),
                Role::Layer(FAT_COLOUR),
            ));
        }
        if view.layers.cranium {
            let m = layer_mesh(2);
            meshes.push((
                12,
                Arc::new(MeshData::from_mesh(&m, None)),
                Role::Layer(CRANIUM_COLOUR),
            ));
        }
        let mut segments = Vec::new();
        if view.layers.hex_edges {
            // Edges through the thickness; the in-layer edges come with each layer's wireframe.
            // With a cut-away only those next to the cut, which outline the hexahedra there.
            let colour = [0.2, 0.25, 0.35, 0.8];
            let cut = view.layers.cutaway.then(|| cut_plane_x(app, fem) as f64);
            for v in 0..n {
                if let Some(c) = cut
                    && (fem.volume.nodes_mm[v].x - c).abs() > 3.0
                {
                    continue;
                }
                for k in 0..2 {
                    let a = fem.volume.nodes_mm[k * n + v] + u[k * n + v];
                    let b = fem.volume.nodes_mm[(k + 1) * n + v] + u[(k + 1) * n + v];
                    segments.push((a.as_vec3().to_array(), b.as_vec3().to_array(), colour));
                }
            }
        }
        if view.layers.muscles {
            segments.extend(muscle_arrows(fem, &doc.edits.activations, &u));
        }
        if !segments.is_empty() {
            meshes.push((13, Arc::new(MeshData::lines(&segments)), Role::Lines));
        }
        if let Some(scan) = &shown_scan {
            let cached = previous
                .and_then(|p| p.underlay.as_ref())
                .filter(|u| Arc::ptr_eq(&u.scan, scan) && Arc::ptr_eq(&u.face, &fem.surface));
            let data = match cached {
                Some(u) => u.data.clone(),
                None => Arc::new(MeshData::from_mesh(
                    &underlay_mesh(scan, &fem.surface),
                    None,
                )),
            };
            meshes.push((1, data.clone(), Role::Underlay));
            underlay = Some(Underlay {
                scan: scan.clone(),
                face: fem.surface.clone(),
                data,
            });
        }
        pick_surface = Some(shown_scan.clone().unwrap_or(skin));
    } else if let Some(shown) = shown_scan {
        let mut colours = None;
        if view.overlay == Overlay::Denoise
            && let Some(d) = &doc.denoised
        {
            // Per input vertex on the original (removed vertices grey), per kept vertex on
            // the denoised scan.
            let scale = denoise_scale(&d.report.displacement_mm);
            colours = match (&doc.working, view.show_original) {
                (Some(w), false) => {
                    let per_vertex: Vec<f64> = w
                        .input_ids
                        .iter()
                        .map(|&v| d.report.displacement_mm[v as usize])
                        .collect();
                    Some(scale.colours(&per_vertex))
                }
                _ => Some(scale.colours(&d.report.displacement_mm)),
            };
            legend = Some(scale);
        }
        // The shape index belongs to the mesh the detector ran on (the working scan).
        if view.overlay == Overlay::ShapeIndex
            && !view.show_original
            && let Some(d) = &doc.detection
            && doc.detection_current()
            && d.shape_index.len() == shown.vertex_count()
        {
            let scale = ColourScale {
                ramp: crate::render::colormap::Ramp::Diverging,
                min: 0.0,
                max: 1.0,
                title: "shape index (cup 0 … cap 1)".into(),
            };
            colours = Some(scale.colours(&d.shape_index));
            legend = Some(scale);
        }
        let role = if registered.is_some() {
            Role::Underlay
        } else {
            Role::Main
        };
        meshes.push((
            1,
            Arc::new(MeshData::from_mesh(&shown, colours.as_deref())),
            role,
        ));
        pick_surface = Some(shown);
        if let Some(r) = registered {
            let scale = registration_scale(&r.distance_mm);
            let colours = scale.colours(&r.distance_mm);
            meshes.push((
                2,
                Arc::new(MeshData::from_mesh(&r.result.mesh, Some(&colours))),
                Role::Registered,
            ));
            legend = Some(scale);
        }
    } else {
        meshes.push((
            3,
            Arc::new(MeshData::from_mesh(&doc.generic.mesh, None)),
            Role::Main,
        ));
        pick_surface = Some(Arc::new(doc.generic.mesh.clone()));
    }
    SceneCache {
        key: scene_key(app),
        meshes,
        underlay,
        legend,
        pick_surface,
    }
}

/// The cut-away plane's x (mm), relative to the nose tip so the same cut works in the generic
/// and the scan frames.
fn cut_plane_x(app: &EditorApp, fem: &crate::app::jobs::FemState) -> f32 {
    let nose = app
        .doc
        .generic
        .feature_vertex(crate::feature_points::FeaturePoint::NoseTip);
    fem.surface.positions_mm[nose as usize].x as f32 + app.view.layers.cut_x_mm
}

/// Arrows from each muscle's insertion towards its origin; length ∝ force × activation (a
/// short stub for inactive muscles so every muscle can be found).
fn muscle_arrows(
    fem: &crate::app::jobs::FemState,
    activations: &std::collections::BTreeMap<String, f64>,
    u: &[glam::DVec3],
) -> Vec<([f32; 3], [f32; 3], [f32; 4])> {
    let a = fem.activation_vector(activations);
    let max_force = fem
        .muscles
        .iter()
        .map(|m| m.force_n)
        .fold(f64::EPSILON, f64::max);
    let mut out = Vec::new();
    for (m, &ai) in fem.muscles.iter().zip(&a) {
        // The arrow starts on the (deformed) skin at the insertion's nearest pulled node.
        let start = m
            .nodes
            .iter()
            .zip(&m.weights)
            .max_by(|x, y| x.1.total_cmp(y.1))
            .map_or(m.insertion_mm, |(&node, _)| {
                fem.volume.nodes_mm[node as usize] + u[node as usize]
            });
        let dir = (m.origin_mm - m.insertion_mm).normalize_or_zero();
        let strength = (m.force_n / max_force) * ai.abs();
        let length = 4.0 + 14.0 * strength.min(2.0);
        let end = start + dir * length;
        let colour = if ai.abs() > 1e-6 {
            [1.0, 0.55, 0.1, 1.0]
        } else {
            [0.45, 0.6, 0.9, 0.9]
        };
        let side = dir.cross(glam::DVec3::Z).normalize_or(glam::DVec3::X);
        let head = 2.5;
        let f = |p: glam::DVec3| p.as_vec3().to_array();
        out.push((f(start), f(end), colour));
        out.push((f(end), f(end - dir * head + side * head * 0.6), colour));
        out.push((f(end), f(end - dir * head - side * head * 0.6), colour));
    }
    out
}

pub fn viewport_ui(app: &mut EditorApp, ui: &mut egui::Ui) {
    let key = scene_key(app);
    if app.scene.as_ref().is_none_or(|s| s.key != key) {
        let start = std::time::Instant::now();
        app.scene = Some(build_scene(app));
        app.scene_build_ms = start.elapsed().as_secs_f64() * 1e3;
    }
    let rect = ui.available_rect_before_wrap();
    let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
    interact(app, ui, &response, rect);

    let Some(scene) = &app.scene else { return };
    let view = &app.view;
    let base = DrawStyle {
        flat: view.flat_shading,
        wireframe: view.wireframe,
        ..DrawStyle::default()
    };
    let items = scene
        .meshes
        .iter()
        .filter(|(_, _, role)| *role != Role::Underlay || view.show_scan)
        .map(|(id, data, role)| SceneItem {
            id: *id,
            data: data.clone(),
            style: match role {
                Role::Underlay => DrawStyle {
                    colour: Some([0.55, 0.62, 0.8]),
                    opacity: view.scan_opacity,
                    wireframe: false,
                    depth_push: 0.0015,
                    ..base
                },
                Role::Layer(c) => DrawStyle {
                    colour: Some(*c),
                    wireframe: base.wireframe || view.layers.hex_edges,
                    ..base
                },
                Role::Lines => DrawStyle {
                    surface: false,
                    wireframe: true,
                    wire_colour: None,
                    ..base
                },
                Role::Main | Role::Registered => DrawStyle {
                    wireframe: base.wireframe || (app.doc.fem.is_some() && view.layers.hex_edges),
                    ..base
                },
            },
        })
        .collect();

    let mut markers = Vec::new();
    if view.show_landmarks
        && let Some(landmarks) = &app.doc.edits.landmarks
    {
        for (p, x) in landmarks.iter() {
            markers.push(MarkerInstance {
                centre: x.as_vec3().to_array(),
                colour: feature_colour(p),
            });
        }
    }
    if view.overlay == Overlay::Denoise
        && view.show_spikes
        && let (Some(d), Some(scan)) = (&app.doc.denoised, &app.doc.scan)
    {
        // Where the spikes were (the original positions), so they can be seen and checked.
        for &v in &d.spikes {
            markers.push(MarkerInstance {
                centre: scan.mesh.positions_mm[v as usize].as_vec3().to_array(),
                colour: SPIKE_COLOUR,
            });
        }
    }
    let aspect = (rect.width() / rect.height().max(1.0)) as f64;
    let clip_plane = app
        .doc
        .fem
        .as_ref()
        .filter(|_| view.layers.cutaway)
        .map(|fem| (glam::Vec3::X, cut_plane_x(app, fem)));
    let callback = ViewportCallback {
        view_proj: app.camera.view_proj(aspect),
        eye_mm: app.camera.eye_mm().as_vec3(),
        size_points: [rect.width(), rect.height()],
        background: BACKGROUND,
        items,
        markers,
        marker_radius_px: 5.0,
        clip_plane,
    };
    ui.painter()
        .add(egui_wgpu::Callback::new_paint_callback(rect, callback));

    let painter = ui.painter_at(rect);
    if view.show_landmarks
        && view.show_labels
        && let Some(landmarks) = &app.doc.edits.landmarks
    {
        for (p, x) in landmarks.iter() {
            if clip_plane.is_some_and(|(n, d)| n.dot(x.as_vec3()) > d) {
                continue;
            }
            if let Some([px, py]) =
                app.camera
                    .project_to_pixels(x, rect.width() as f64, rect.height() as f64)
            {
                let pos = rect.min + egui::vec2(px as f32 + 8.0, py as f32 - 8.0);
                painter.text(
                    pos,
                    egui::Align2::LEFT_BOTTOM,
                    p.name(),
                    egui::FontId::proportional(11.0),
                    egui::Color32::from_rgb(235, 235, 220),
                );
            }
        }
    }
    if let Some(scale) = &scene.legend {
        legend_ui(&painter, rect, scale);
    }
    if app.erasing {
        brush_outline(app, &painter, &response);
    }
}

/// The erase brush: a click or a primary drag erases the working scan's vertices within the
/// brush radius of the surface under the pointer, one undo step per stroke. Returns whether
/// the primary button is busy erasing (so it does not orbit too).
fn erase_brush(app: &mut EditorApp, response: &egui::Response, rect: egui::Rect) -> bool {
    use super::document::Command;
    let primary = egui::PointerButton::Primary;
    let starts = response.drag_started_by(primary) || response.clicked();
    if starts {
        app.erase_stroke_started = false;
    }
    let active = starts || response.dragged_by(primary);
    if active
        && let Some(pos) = response.interact_pointer_pos()
        && let Some(hit) = surface_hit(app, pos - rect.min, rect)
    {
        // The checkpoint comes with the stroke's first hit: a click beside the scan is no step.
        if !app.erase_stroke_started {
            app.commands.push(Command::Checkpoint);
            app.erase_stroke_started = true;
        }
        app.commands.push(Command::Erase {
            centre_mm: hit,
            radius_mm: app.erase_radius_mm,
        });
    }
    active
}

/// The erase brush's outline around the surface point under the pointer.
fn brush_outline(app: &EditorApp, painter: &egui::Painter, response: &egui::Response) {
    let rect = response.rect;
    let Some(pos) = response.hover_pos() else {
        return;
    };
    let Some(hit) = surface_hit(app, pos - rect.min, rect) else {
        return;
    };
    let (right, _) = app.camera.right_up();
    let (w, h) = (rect.width() as f64, rect.height() as f64);
    let (Some(c), Some(e)) = (
        app.camera.project_to_pixels(hit, w, h),
        app.camera
            .project_to_pixels(hit + right * app.erase_radius_mm, w, h),
    ) else {
        return;
    };
    let radius_px = ((e[0] - c[0]).powi(2) + (e[1] - c[1]).powi(2)).sqrt() as f32;
    painter.circle_stroke(
        rect.min + egui::vec2(c[0] as f32, c[1] as f32),
        radius_px.max(2.0),
        egui::Stroke::new(1.5, egui::Color32::from_rgb(255, 120, 60)),
    );
}

fn interact(app: &mut EditorApp, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) {
    // Shift + drag orbits with the brush on.
    let shift = ui.input(|i| i.modifiers.shift);
    let erasing = app.erasing && !shift && erase_brush(app, response, rect);
    // Dragging a landmark marker moves the point over the surface; anywhere else a primary
    // drag orbits (in erase mode it erases).
    if !app.erasing
        && response.drag_started_by(egui::PointerButton::Primary)
        && let Some(press) = ui.input(|i| i.pointer.press_origin())
    {
        app.landmark_drag = landmark_under(app, press - rect.min, rect);
        if app.landmark_drag.is_some() {
            app.commands.push(super::document::Command::Checkpoint);
        }
    }
    if let Some(point) = app.landmark_drag {
        if response.dragged_by(egui::PointerButton::Primary)
            && let Some(pos) = response.interact_pointer_pos()
            && let Some(hit) = surface_hit(app, pos - rect.min, rect)
        {
            app.commands
                .push(super::document::Command::DragLandmark(point, hit));
        }
        if response.drag_stopped() {
            app.landmark_drag = None;
        }
        return;
    }
    let camera = &mut app.camera;
    let delta = response.drag_delta();
    if response.dragged_by(egui::PointerButton::Primary) && !erasing {
        camera.orbit(delta.x as f64, delta.y as f64);
    } else if response.dragged_by(egui::PointerButton::Secondary)
        || response.dragged_by(egui::PointerButton::Middle)
    {
        camera.pan(delta.x as f64, delta.y as f64, rect.height() as f64);
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            camera.zoom((scroll as f64 * 0.002).exp());
        }
    }
    if response.double_clicked()
        && let Some((lo, hi)) = app.framed_on
    {
        *camera = OrbitCamera::framing(lo, hi);
    }
    // Placing a landmark: a click (not a drag) on the surface shown.
    if response.clicked()
        && !app.erasing
        && let Some(point) = app.picking
        && let Some(pos) = response.interact_pointer_pos()
        && let Some(hit) = surface_hit(app, pos - rect.min, rect)
    {
        app.commands
            .push(super::document::Command::MoveLandmark(point, hit));
        app.picking = None;
    }
}

/// Where the ray through a viewport pixel meets the pickable surface, mm.
fn surface_hit(app: &EditorApp, local: egui::Vec2, rect: egui::Rect) -> Option<DVec3> {
    let surface = app.scene.as_ref().and_then(|s| s.pick_surface.clone())?;
    let (origin, dir) = app.camera.ray_through_pixel(
        local.x as f64,
        local.y as f64,
        rect.width() as f64,
        rect.height() as f64,
    );
    ray_hit(&surface, origin, dir).map(|hit| hit.point_mm)
}

/// The feature point whose marker is within grabbing distance of a viewport pixel.
fn landmark_under(app: &EditorApp, local: egui::Vec2, rect: egui::Rect) -> Option<FeaturePoint> {
    const GRAB_PX: f64 = 9.0;
    if !app.view.show_landmarks {
        return None;
    }
    let landmarks = app.doc.edits.landmarks.as_ref()?;
    landmarks
        .iter()
        .filter_map(|(p, x)| {
            let [px, py] =
                app.camera
                    .project_to_pixels(x, rect.width() as f64, rect.height() as f64)?;
            let d = ((px - local.x as f64).powi(2) + (py - local.y as f64).powi(2)).sqrt();
            (d <= GRAB_PX).then_some((p, d))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(p, _)| p)
}

/// A vertical colour bar with ticks at the viewport's right edge.
fn legend_ui(painter: &egui::Painter, rect: egui::Rect, scale: &ColourScale) {
    let bar = egui::Rect::from_min_size(
        egui::pos2(rect.max.x - 70.0, rect.min.y + 40.0),
        egui::vec2(16.0, 200.0),
    );
    let steps = 40;
    for i in 0..steps {
        let t0 = i as f32 / steps as f32;
        let t1 = (i + 1) as f32 / steps as f32;
        let v = scale.min + (scale.max - scale.min) * (1.0 - (t0 + t1) as f64 * 0.5);
        let [r, g, b, _] = scale.colour(v);
        let c = egui::Rgba::from_rgb(r, g, b);
        painter.rect_filled(
            egui::Rect::from_min_max(
                egui::pos2(bar.min.x, bar.min.y + t0 * bar.height()),
                egui::pos2(bar.max.x, bar.min.y + t1 * bar.height()),
            ),
            0.0,
            c,
        );
    }
    let text = egui::Color32::from_rgb(230, 230, 230);
    for (v, label) in scale.ticks(5) {
        let t = if scale.max > scale.min {
            ((scale.max - v) / (scale.max - scale.min)) as f32
        } else {
            0.0
        };
        painter.text(
            egui::pos2(bar.max.x + 4.0, bar.min.y + t * bar.height()),
            egui::Align2::LEFT_CENTER,
            label,
            egui::FontId::monospace(11.0),
            text,
        );
    }
    painter.text(
        egui::pos2(bar.max.x + 10.0, bar.min.y - 8.0),
        egui::Align2::RIGHT_BOTTOM,
        &scale.title,
        egui::FontId::proportional(12.0),
        text,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat `n × n`-quad grid of 1 mm spacing at height `z`, centred on the origin.
    fn plane(n: u32, z: f64) -> Mesh {
        let id = |i: u32, j: u32| i + (n + 1) * j;
        let h = n as f64 / 2.0;
        let positions = (0..=n)
            .flat_map(|j| (0..=n).map(move |i| DVec3::new(i as f64 - h, j as f64 - h, z)))
            .collect();
        let faces = (0..n).flat_map(|j| {
            (0..n).map(move |i| [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)])
        });
        Mesh::from_faces(positions, faces.collect::<Vec<_>>())
    }

    #[test]
    fn the_underlay_keeps_the_scan_around_the_face_and_drops_what_the_face_hides() {
        let scan = plane(60, 0.0);
        // The face covers the middle 30 × 30 mm, 0.5 mm in front of the scan.
        let face = plane(30, 0.5);
        let under = underlay_mesh(&scan, &face);
        let centres: Vec<DVec3> = under
            .triangles()
            .iter()
            .map(|t| {
                t.iter()
                    .map(|&v| under.positions_mm[v as usize])
                    .sum::<DVec3>()
                    / 3.0
            })
            .collect();
        assert!(!centres.is_empty());
        // Nothing deep under the face survives; the ring outside it does, at a quarter of
        // the scan's density.
        assert!(centres.iter().all(|c| c.x.abs().max(c.y.abs()) > 13.0));
        let ring = scan.triangles().len() as f64 * (1.0 - 0.25);
        let kept = centres.len() as f64;
        assert!(
            (0.15 * ring..0.4 * ring).contains(&kept),
            "{kept} of {ring}"
        );
        // A face far in front hides nothing.
        let far = underlay_mesh(&scan, &plane(30, 5.0));
        assert!(far.triangles().len() as f64 > 0.2 * scan.triangles().len() as f64);
    }
}
