//! The editor's worker thread: slow jobs run here, results return over a channel, and the
//! worker asks egui for a repaint so the UI thread picks them up on its next frame. The jobs
//! themselves ([`run_job`]) are plain functions, tested without a window.

use super::jobs::{
    DenoiseState, DetectionState, FemState, FitState, Job, JobResult, RegistrationState, SPIKE_MM,
    ScanState,
};
use crate::denoise::DenoiseParams;
use crate::feature_points::FeaturePoint;
use crate::feature_points::Landmarks;
use crate::fem::expressions::ExpressionSet;
use crate::fem::muscles::MuscleSet;
use crate::fem::{FaceModel, FemParams};
use crate::generic_face::GenericFace;
use crate::registration::RegistrationParams;
use crate::{Mesh, io};
use eframe::egui;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Instant;

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
                let mut state = WorkerState::default();
                for job in job_rx {
                    if result_tx.send(state.run(job)).is_err() {
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

/// What the worker keeps between jobs: the FEM model with its cached factorization.
#[derive(Default)]
pub struct WorkerState {
    fem: Option<CachedFem>,
}

/// The FEM model of one surface, with the geometry the editor shares: a re-solve (materials,
/// muscles) hands back the same `Arc`s, so what the viewport built for that geometry stays.
struct CachedFem {
    surface_id: u64,
    model: FaceModel,
    muscles: MuscleSet,
    surface: Arc<Mesh>,
    volume: Arc<crate::fem::HexMesh>,
}

impl WorkerState {
    /// Runs one job to completion (on the worker thread, or directly in tests).
    pub fn run(&mut self, job: Job) -> JobResult {
        match job {
            Job::Fem {
                surface,
                surface_id,
                feature_vertices,
                params,
                muscles,
            } => JobResult::Fem(
                self.fem(&surface, surface_id, feature_vertices, params, *muscles)
                    .map(Box::new),
            ),
            Job::FitExpression {
                scan,
                neutral,
                presets,
            } => JobResult::Fitted(self.fit(&scan, neutral.as_deref(), &presets).map(Box::new)),
            other => run_job(other),
        }
    }

    fn fit(
        &self,
        path: &std::path::Path,
        neutral: Option<&Mesh>,
        presets: &ExpressionSet,
    ) -> Result<FitState, String> {
        let start = Instant::now();
        let Some(CachedFem { model, .. }) = &self.fem else {
            return Err("build the FEM model first".into());
        };
        let e = |e: crate::Error| e.in_file(path).to_string();
        // The scan's own points start the rigid alignment when they can be found.
        let (scan, points) = crate::pipeline::prepare_expression_scan(path, None).map_err(e)?;
        let params = crate::fem::fit::FitParams::default();
        let fit = crate::fem::fit::fit_expression(
            model,
            neutral,
            &scan,
            points.as_ref().map(|p| &p.landmarks),
            presets,
            &params,
        )
        .map_err(e)?;
        let name = path
            .file_stem()
            .map_or_else(|| "fitted".into(), |s| s.to_string_lossy().into_owned());
        let (_, residual_mm) = fit.residual_map(model, &params).map_err(e)?;
        let names = model.actuator_names();
        Ok(FitState {
            name,
            contributions_mm: fit.ranked_contributions(&names),
            activations: names
                .into_iter()
                .zip(&fit.activations)
                .filter(|(_, a)| **a > 0.0)
                .map(|(name, a)| (name, *a))
                .collect(),
            rms_before_mm: fit.rms_before_mm,
            rms_after_mm: fit.rms_after_mm,
            closest_preset: fit.closest_preset,
            vertices_used: fit.vertices_used,
            moving_rms_before_mm: fit.moving_rms_before_mm,
            moving_rms_after_mm: fit.moving_rms_after_mm,
            residual_mm,
            millis: start.elapsed().as_secs_f64() * 1e3,
        })
    }

    fn fem(
        &mut self,
        surface: &Mesh,
        surface_id: u64,
        feature_vertices: [u32; FeaturePoint::COUNT],
        params: FemParams,
        muscles: MuscleSet,
    ) -> Result<FemState, String> {
        let start = Instant::now();
        let e = |e: crate::Error| e.to_string();
        // Reuse the model when only materials or muscles changed; a new surface or new layer
        // thicknesses need a new volume, a new fixed border a new system.
        let reusable = self.fem.as_ref().is_some_and(|c| {
            c.surface_id == surface_id
                && c.model.params.layers.skin_thickness_mm == params.layers.skin_thickness_mm
                && c.model.params.layers.fat_thickness_mm == params.layers.fat_thickness_mm
                && c.model.params.fixed_border_rings == params.fixed_border_rings
        });
        let what;
        let mut note = String::new();
        if reusable {
            let CachedFem {
                model,
                muscles: old_muscles,
                ..
            } = self.fem.as_mut().expect("checked");
            let materials_changed =
                model.params.skin != params.skin || model.params.fat != params.fat;
            if materials_changed {
                model.set_materials(params.skin, params.fat).map_err(e)?;
                model.factor().map_err(e)?;
                what = "materials changed: refactored, basis re-solved";
            } else {
                what = "muscles re-solved with the cached factor";
            }
            if materials_changed || *old_muscles != muscles || !model.has_basis() {
                model.set_muscles(&muscles).map_err(e)?;
                model.compute_basis().map_err(e)?;
                *old_muscles = muscles.clone();
            }
        } else {
            // Drop the old model first so a failed build does not leave a stale one behind.
            self.fem = None;
            // As in the batch: folds the registration left are smoothed away, and the layers
            // thinned as a last resort (both reported in `last_update`).
            let (mut model, r) =
                crate::pipeline::repaired_fem_model(surface, feature_vertices, &params)
                    .map_err(e)?;
            if r.unfolded_vertices > 0
                || r.layer_thickness_factor < 1.0
                || r.local_surface_repairs > 0
            {
                note = format!(
                    "; {} folded vertices smoothed, layers × {}, {} local surface repairs",
                    r.unfolded_vertices, r.layer_thickness_factor, r.local_surface_repairs
                );
            }
            model.factor().map_err(e)?;
            model.set_muscles(&muscles).map_err(e)?;
            model.compute_basis().map_err(e)?;
            self.fem = Some(CachedFem {
                surface_id,
                surface: Arc::new(model.surface.clone()),
                volume: Arc::new(model.volume.clone()),
                model,
                muscles: muscles.clone(),
            });
            what = "built, factored, basis solved";
        }
        let cached = self.fem.as_ref().expect("set above");
        let model = &cached.model;
        let basis = (0..model.actuator_count())
            .map(|i| model.basis_displacement(i).unwrap_or_default())
            .collect();
        Ok(FemState {
            volume: cached.volume.clone(),
            surface: cached.surface.clone(),
            muscles: model.muscles().to_vec(),
            basis: Arc::new(basis),
            fixed: model.fixed_nodes().to_vec(),
            params: model.params,
            muscle_set: muscles,
            dofs: model.dofs(),
            quality: model.quality,
            timings: model.timings,
            last_update: format!("{what}{note}"),
            millis: start.elapsed().as_secs_f64() * 1e3,
            surface_id,
        })
    }
}

/// Runs one stateless job (everything but the FEM model).
pub fn run_job(job: Job) -> JobResult {
    match job {
        Job::Fem { .. } => JobResult::Fem(Err("the FEM job needs the worker's state".into())),
        Job::FitExpression { .. } => {
            JobResult::Fitted(Err("the fit needs the worker's FEM model".into()))
        }
        Job::DetectLandmarks { mesh } => JobResult::Detected(detect(&mesh).map(Box::new)),
        Job::Load(path) => JobResult::Loaded(load_scan(path).map(Box::new)),
        Job::Review {
            dir,
            landmarks_dir,
            progress,
        } => {
            use std::sync::atomic::Ordering::Relaxed;
            let queue =
                crate::pipeline::ReviewQueue::build(&dir, landmarks_dir.as_deref(), &|k, n| {
                    progress.total.store(n, Relaxed);
                    progress.done.store(k, Relaxed);
                });
            JobResult::Reviewed(queue.map(Box::new).map_err(|e| e.to_string()))
        }
        Job::Denoise { mesh, params } => JobResult::Denoised(denoise(&mesh, params).map(Box::new)),
        Job::Register {
            generic,
            scan,
            landmarks,
            borders_detected,
        } => JobResult::Registered(
            register(&generic, &scan, *landmarks, borders_detected).map(Box::new),
        ),
    }
}

fn load_scan(path: PathBuf) -> Result<ScanState, String> {
    let start = Instant::now();
    let (mesh, units) = io::read_mesh_and_units(&path).map_err(|e| e.to_string())?;
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
        units,
        load_millis: start.elapsed().as_secs_f64() * 1e3,
    })
}

fn detect(mesh: &Mesh) -> Result<DetectionState, String> {
    let start = Instant::now();
    let params = crate::landmarks::LandmarkParams::default();
    let e = |e: crate::Error| e.to_string();
    mesh.validate()?;
    let (report, desc) = crate::landmarks::detect_with_descriptors(mesh, &params).map_err(e)?;
    Ok(DetectionState {
        report,
        shape_index: desc.shape_index,
        millis: start.elapsed().as_secs_f64() * 1e3,
    })
}

fn denoise(mesh: &Mesh, params: DenoiseParams) -> Result<DenoiseState, String> {
    let start = Instant::now();
    let mut out = mesh.clone();
    let report = crate::denoise::denoise(&mut out, &params).map_err(|e| e.to_string())?;
    // Moved by more than a spike's height, or removed (NaN): the peaks the filter took away.
    let spikes = report
        .displacement_mm
        .iter()
        .enumerate()
        .filter(|(_, d)| **d > SPIKE_MM || d.is_nan())
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
    borders_detected: bool,
) -> Result<RegistrationState, String> {
    let params = RegistrationParams::default();
    let points = crate::pipeline::registration_points(&landmarks, borders_detected);
    let result = crate::registration::register_points(generic, scan, &points, &params)
        .map_err(|e| e.to_string())?;
    // Per-vertex distance for the heat map; filled (unmatched) vertices have no measured value.
    let mut distance_mm = result.vertex_distance_mm.clone();
    for &v in &result.unmatched_vertices {
        distance_mm[v as usize] = f64::NAN;
    }
    Ok(RegistrationState {
        result: Arc::new(result),
        distance_mm,
        landmarks,
    })
}
