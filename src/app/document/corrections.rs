//! The document's feature points as a landmark file ([`crate::pipeline::LandmarkFile`]): where
//! they came from, which points the user moved, and the correction file beside the scan.

use super::*;
use crate::pipeline::{LandmarkFile, LandmarkSource};

impl Document {
    /// The current points as a landmark file: `detected` (or the loaded file's source) while no
    /// point was moved, `corrected` with the moved points listed once one was.
    pub fn landmark_file(&self) -> Option<LandmarkFile> {
        let landmarks = self.edits.landmarks?;
        let (baseline, source, mut corrected) = match &self.landmark_origin {
            Some(o) => (o.landmarks, o.source, o.corrected.clone()),
            // Placed by hand from the generic face's points.
            None => (
                self.generic.landmarks(),
                LandmarkSource::Corrected,
                Vec::new(),
            ),
        };
        corrected.extend(
            FeaturePoint::ALL
                .into_iter()
                .filter(|&p| landmarks.get(p) != baseline.get(p)),
        );
        corrected.sort();
        corrected.dedup();
        let source = if corrected.is_empty() {
            source
        } else {
            LandmarkSource::Corrected
        };
        Some(LandmarkFile {
            landmarks,
            source,
            scan: self
                .scan
                .as_ref()
                .and_then(|s| s.path.file_name())
                .map(|n| n.to_string_lossy().into_owned()),
            corrected,
        })
    }

    /// The scan's correction file (`<stem>.landmarks.json` beside it, or in
    /// [`Document::landmarks_dir`]); `None` without a scan.
    pub fn correction_path(&self) -> Option<PathBuf> {
        let scan = self.scan.as_ref()?;
        Some(crate::pipeline::correction_path(
            &scan.path,
            self.landmarks_dir.as_deref(),
        ))
    }

    /// Reads a landmark file as the scan's points (undoable).
    pub(super) fn load_landmark_file(&mut self, path: &std::path::Path) -> Vec<Job> {
        match LandmarkFile::read(path) {
            Ok(file) => {
                self.status = Some(format!(
                    "loaded {} ({})",
                    path.display(),
                    file.source.name()
                ));
                self.saved.landmarks = Some(file.landmarks);
                let landmarks = file.landmarks;
                self.landmark_origin = Some(file);
                self.apply(Command::SetLandmarks(Box::new(landmarks)))
            }
            Err(e) => self.fail(e.to_string()),
        }
    }

    /// Writes the points as a landmark file (atomically).
    pub(super) fn save_landmark_file(&mut self, path: &std::path::Path) {
        let Some(file) = self.landmark_file() else {
            self.error = Some("no landmarks to save".into());
            return;
        };
        match file.write(path) {
            Ok(()) => {
                self.saved.landmarks = Some(file.landmarks);
                self.status = Some(format!("saved {} ({})", path.display(), file.source.name()));
            }
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    /// After a scan has loaded: its correction file, if there is one, gives its points; else
    /// the points the review queue detected for it, if it was opened from there.
    pub(super) fn points_on_open(&mut self) -> Vec<Job> {
        let pending = self.pending_points.take();
        if self.edits.landmarks.is_some() {
            return Vec::new();
        }
        let jobs = match self.correction_path().filter(|p| p.is_file()) {
            Some(path) => self.load_landmark_file(&path),
            None => {
                if let Some(file) = pending {
                    self.edits.landmarks = Some(file.landmarks);
                    self.saved.landmarks = Some(file.landmarks);
                    self.landmark_origin = Some(file);
                    self.version += 1;
                }
                Vec::new()
            }
        };
        // The scan's own points, as it opened: nothing to undo, nothing unsaved.
        self.history.clear();
        jobs
    }

    /// Whether the registration should leave the cheek and forehead points out (the detector's
    /// region borders, not the generic face's points; see
    /// [`crate::pipeline::registration_points`]).
    pub(super) fn borders_detected(&self) -> bool {
        self.landmark_origin.is_some() && self.landmark_file().is_some_and(|f| f.borders_detected())
    }
}
