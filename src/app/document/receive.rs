//! The document taking the workers' results (the GUI sends commands; workers compute; results
//! come back here).

use super::*;

impl Document {
    /// Takes one worker result; returns follow-up jobs. A failure keeps the previous state
    /// (the last good solution stays on screen) and shows the error.
    pub fn receive(&mut self, result: JobResult) -> Vec<Job> {
        let what = match &result {
            JobResult::Loaded(_) => "loading",
            JobResult::Denoised(_) => "denoising",
            JobResult::Registered(_) => "registering",
            JobResult::Fem(_) => "solving",
            JobResult::Detected(_) => "detecting",
            JobResult::Reviewed(_) => "reviewing",
            JobResult::Fitted(_) => "fitting",
        };
        if let Some(i) = self.pending.iter().position(|p| *p == what) {
            self.pending.remove(i);
        }
        let mut jobs = Vec::new();
        match result {
            JobResult::Loaded(Ok(scan)) => {
                self.scan = Some(*scan);
                self.denoised = None;
                self.detection = None;
                self.registration = None;
                self.fem_dirty |= self.fem.as_ref().is_some_and(|f| f.surface_id != 0);
                // A new scan's feature points are unknown until detected, loaded or placed,
                // and none of its vertices is erased.
                self.edits.landmarks = None;
                self.saved.landmarks = None;
                self.landmark_origin = None;
                self.edits.erased.clear();
                self.saved.erased.clear();
                self.history.clear();
                if let Some(edits) = self.pending_restore.take() {
                    self.fem_dirty |=
                        edits.fem != self.edits.fem || edits.muscles != self.edits.muscles;
                    self.edits = edits;
                }
                self.rebuild_working();
                // Corrections beside the scan win over detection.
                jobs.extend(self.points_on_open());
                if let (Some(params), Some(scan)) = (self.pending_denoise.take(), &self.scan) {
                    let job = Job::Denoise {
                        mesh: scan.mesh.clone(),
                        params,
                    };
                    self.pending.push("denoising");
                    jobs.push(job);
                }
            }
            JobResult::Denoised(Ok(d)) => {
                self.denoised = Some(*d);
                self.rebuild_working();
            }
            JobResult::Registered(Ok(r)) => {
                self.registration = Some(*r);
                self.registered_on = self.register_sent_on;
                self.registration_count += 1;
                self.version += 1;
                // The FEM model follows the new face.
                self.fem_dirty |= self.fem_enabled;
            }
            JobResult::Fem(Ok(f)) => {
                self.fem = Some(*f);
                self.version += 1;
            }
            JobResult::Fitted(Ok(f)) => {
                self.history.checkpoint(&self.edits);
                self.edits.activations = f.activations.clone();
                self.edits.applied_preset = None;
                self.preset_name_hint = Some(f.name.clone());
                self.fit = Some(*f);
                self.version += 1;
            }
            JobResult::Detected(Ok(d)) => {
                self.history.checkpoint(&self.edits);
                self.edits.landmarks = Some(d.report.landmarks);
                self.landmark_origin = Some(crate::pipeline::LandmarkFile {
                    landmarks: d.report.landmarks,
                    source: crate::pipeline::LandmarkSource::Detected,
                    scan: None,
                    corrected: Vec::new(),
                });
                self.status = Some(match d.report.warnings.len() {
                    0 => format!("13 points found in {:.0} ms", d.millis),
                    n => format!("13 points found, {n} warnings"),
                });
                self.detection = Some(*d);
                self.detected_on = self.detect_sent_on;
                self.version += 1;
            }
            JobResult::Reviewed(Ok(queue)) => jobs.extend(self.review_ready(*queue)),
            JobResult::Loaded(Err(e))
            | JobResult::Reviewed(Err(e))
            | JobResult::Denoised(Err(e))
            | JobResult::Registered(Err(e))
            | JobResult::Fem(Err(e))
            | JobResult::Detected(Err(e))
            | JobResult::Fitted(Err(e)) => {
                let restoring = what == "loading" && self.pending_restore.take().is_some();
                if what == "loading" {
                    self.pending_denoise = None;
                    self.pending_points = None;
                }
                if what == "reviewing" {
                    self.review_progress = None;
                }
                self.error = Some(if restoring {
                    format!("autosave not restored: {e}")
                } else {
                    e
                });
            }
        }
        if self.fem_dirty {
            jobs.extend(self.fem_job());
        }
        jobs
    }
}
