//! The editor's worker thread: slow jobs run here, results return over a channel, and the
//! worker asks egui for a repaint so the UI thread picks them up on its next frame.

use super::Scene;
use crate::generic_face;
use crate::render::MeshData;
use eframe::egui;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Instant;

pub enum Job {
    /// Load a mesh file, or the generic face for `None`.
    Load(Option<PathBuf>),
}

pub enum JobResult {
    Loaded(Result<Box<Scene>, String>),
}

pub struct Worker {
    jobs: Sender<Job>,
    results: Receiver<JobResult>,
}

impl Worker {
    pub fn spawn(ctx: egui::Context) -> Self {
        let (jobs, job_rx) = channel::<Job>();
        let (result_tx, results) = channel();
        std::thread::Builder::new()
            .name("facesynth-worker".into())
            .spawn(move || {
                for job in job_rx {
                    let result = match job {
                        Job::Load(path) => JobResult::Loaded(load_scene(path).map(Box::new)),
                    };
                    if result_tx.send(result).is_err() {
                        break;
                    }
                    ctx.request_repaint();
                }
            })
            .expect("spawn the worker thread");
        Worker { jobs, results }
    }

    pub fn send(&self, job: Job) {
        // The worker only stops when the app drops its sender, so this cannot fail while the
        // app is alive.
        let _ = self.jobs.send(job);
    }

    pub fn try_recv(&self) -> Option<JobResult> {
        self.results.try_recv().ok()
    }
}

fn load_scene(path: Option<PathBuf>) -> Result<Scene, String> {
    let start = Instant::now();
    let (name, mesh, landmarks) = match &path {
        Some(p) => {
            let mesh = crate::io::read_mesh(p).map_err(|e| e.to_string())?;
            let name = p
                .file_name()
                .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into());
            (name, mesh, None)
        }
        None => {
            let face = generic_face::build();
            let landmarks = face.landmarks();
            ("generic face".to_string(), face.mesh, Some(landmarks))
        }
    };
    let bbox_mm = mesh
        .bbox_mm()
        .ok_or_else(|| "the mesh is empty".to_string())?;
    let gpu = Arc::new(MeshData::from_mesh(&mesh, None));
    Ok(Scene {
        name,
        path,
        counts: mesh.face_counts(),
        mesh: Arc::new(mesh),
        gpu,
        bbox_mm,
        landmarks,
        load_millis: start.elapsed().as_secs_f64() * 1e3,
    })
}
