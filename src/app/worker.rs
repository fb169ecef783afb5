//! The editor's worker thread: slow jobs run here, results return over a channel, and the
//! worker asks egui for a repaint so the UI thread picks them up on its next frame. The jobs
//! themselves ([`run_job`]) are plain functions, tested without a window.

use super::document::{DenoiseState, RegistrationState, SPIKE_MM, ScanState};
use crate::denoise::DenoiseParams;
use crate::feature_points::Landmarks;
use crate::generic_face::GenericFace;
use crate::registration::{RegistrationParams, SurfaceIndex};
use crate::{Mesh, io};
use eframe::egui;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Instant;

pub enum Job {
    Load(PathBuf),
    Denoise {
        mesh: Arc<Mesh>,
        params: DenoiseParams,
    },
    Register {
        generic: Arc<GenericFace>,
        scan: Arc<Mesh>,
        landmarks: Box<Landmarks>,
    },
}

pub enum JobResult {
    Loaded(Result<Box<ScanState>, String>),
    Denoised(Result<Box<DenoiseState>, String>),
    Registered(Result<Box<RegistrationState>, String>),
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
                    if result_tx.send(run_job(job)).is_err() {
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

/// Runs one job to completion (on the worker thread, or directly in tests).
pub fn run_job(job: Job) -> JobResult {
    match job {
        Job::Load(path) => JobResult::Loaded(load_scan(path).map(Box::new)),
        Job::Denoise { mesh, params } => JobResult::Denoised(denoise(&mesh, params).map(Box::new)),
        Job::Register {
            generic,
            scan,
            landmarks,
        } => JobResult::Registered(register(&generic, &scan, *landmarks).map(Box::new)),
    }
}

fn load_scan(path: PathBuf) -> Result<ScanState, String> {
    let start = Instant::now();
    let mesh = io::read_mesh(&path).map_err(|e| e.to_string())?;
    let bbox_mm = mesh
        .bbox_mm()
        .ok_or_else(|| format!("{}: the mesh is empty", path.display()))?;
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into(),
    );
    Ok(ScanState {
        name,
        counts: mesh.face_counts(),
        mesh: Arc::new(mesh),
        path,
        bbox_mm,
        load_millis: start.elapsed().as_secs_f64() * 1e3,
    })
}

fn denoise(mesh: &Mesh, params: DenoiseParams) -> Result<DenoiseState, String> {
    let start = Instant::now();
    let mut out = mesh.clone();
    let report = crate::denoise::denoise(&mut out, &params).map_err(|e| e.to_string())?;
    let spikes = report
        .displacement_mm
        .iter()
        .enumerate()
        .filter(|(_, d)| **d > SPIKE_MM)
        .map(|(i, _)| i as u32)
        .collect();
    Ok(DenoiseState {
        params,
        mesh: Arc::new(out),
        report,
        spikes,
        millis: start.elapsed().as_secs_f64() * 1e3,
    })
}

fn register(
    generic: &GenericFace,
    scan: &Mesh,
    landmarks: Landmarks,
) -> Result<RegistrationState, String> {
    let params = RegistrationParams::default();
    let result = crate::registration::register(generic, scan, &landmarks, &params)
        .map_err(|e| e.to_string())?;
    // Per-vertex distance for the heat map; filled (unmatched) vertices have no measured value.
    let index = SurfaceIndex::new(scan, params.grid_cell_mm);
    let mut distance_mm: Vec<f64> = result
        .mesh
        .positions_mm
        .iter()
        .map(|&p| index.distance(p, params.max_offset_mm))
        .collect();
    for &v in &result.unmatched_vertices {
        distance_mm[v as usize] = f64::NAN;
    }
    Ok(RegistrationState {
        result: Arc::new(result),
        distance_mm,
        landmarks,
    })
}
