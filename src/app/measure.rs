//! `facesynth view --measure-slider N`: the editor's responsiveness, measured in the real
//! window. Drives the zygomatic sliders for N frames (each frame: 30-term basis sum, new GPU
//! mesh, render) and records the interval between frames (on a software renderer mostly the
//! rasterizer's time) and eframe's CPU time of the UI thread, then changes the skin modulus and
//! times the worker's refactor + basis re-solve. Prints one JSON object and closes.

use super::EditorApp;
use super::document::Command;
use eframe::egui;
use std::time::Instant;

pub struct SliderMeasurement {
    frames: u32,
    last_frame: Option<Instant>,
    frame_ms: Vec<f64>,
    /// Scene rebuild per frame (30-term basis sum, normals, GPU arrays), ms.
    ui_ms: Vec<f64>,
    /// eframe's CPU time of the previous frame (ui + tessellation + render submission, vsync wait excluded), ms.
    cpu_ms: Vec<f64>,
    material_sent: Option<Instant>,
    material_ms: Option<f64>,
    reported: bool,
}

impl SliderMeasurement {
    pub fn new(frames: u32) -> Self {
        SliderMeasurement {
            frames: frames.max(1),
            last_frame: None,
            frame_ms: Vec::new(),
            ui_ms: Vec::new(),
            cpu_ms: Vec::new(),
            material_sent: None,
            material_ms: None,
            reported: false,
        }
    }
}

fn stats(values: &[f64]) -> serde_json::Value {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let at = |q: f64| {
        v.get(((v.len() as f64 - 1.0) * q).round() as usize)
            .copied()
    };
    serde_json::json!({
        "median": at(0.5), "p95": at(0.95), "max": v.last(),
        "mean": v.iter().sum::<f64>() / v.len().max(1) as f64,
    })
}

/// One frame of the measurement (called at the end of `App::ui`).
pub fn step(app: &mut EditorApp, ctx: &egui::Context, cpu_usage_s: Option<f32>) {
    ctx.request_repaint();
    let idle = !app.doc.busy() && app.script.is_empty() && app.commands.is_empty();
    if let Some(error) = app.doc.error.clone() {
        app.set_outcome(error);
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        return;
    }
    let Some(m) = app.measure.as_mut() else {
        return;
    };
    if !idle || app.doc.fem.is_none() {
        return;
    }
    let now = Instant::now();
    if (m.frame_ms.len() as u32) < m.frames {
        if let Some(last) = m.last_frame {
            m.frame_ms.push((now - last).as_secs_f64() * 1e3);
            m.ui_ms.push(app.scene_build_ms);
            if let Some(cpu) = cpu_usage_s {
                m.cpu_ms.push(cpu as f64 * 1e3);
            }
        }
        m.last_frame = Some(now);
        // The slider "drag": both zygomatic muscles follow a smooth ramp.
        let t = m.frame_ms.len() as f64 * 0.15;
        let a = 0.8 + 0.6 * t.sin();
        let mut activations = app.doc.edits.activations.clone();
        activations.insert("zygomatic_major_left".into(), a);
        activations.insert("zygomatic_major_right".into(), a);
        app.commands.push(Command::SetActivations(activations));
        return;
    }
    match (m.material_sent, m.material_ms) {
        (None, _) => {
            let mut params = app.doc.edits.fem;
            params.skin.young_modulus_pa *= 0.5;
            app.commands.push(Command::SetFemParams(params));
            m.material_sent = Some(now);
        }
        (Some(sent), None) => {
            m.material_ms = Some((now - sent).as_secs_f64() * 1e3);
        }
        (Some(_), Some(_)) if m.reported => {}
        (Some(_), Some(material_ms)) => {
            m.reported = true;
            let fem = app.doc.fem.as_ref().expect("checked");
            let report = serde_json::json!({
                "surface_vertices": fem.surface.vertex_count(),
                "dofs": fem.dofs,
                "registered": fem.surface_id != 0,
                "frames": m.frame_ms.len(),
                "frame_interval_ms": stats(&m.frame_ms),
                "scene_rebuild_ms": stats(&m.ui_ms),
                "frame_cpu_ms": stats(&m.cpu_ms),
                "material_change_ms": material_ms,
                "material_change_worker_ms": fem.millis,
            });
            println!(
                "{}",
                serde_json::to_string_pretty(&report).unwrap_or_default()
            );
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }
}
