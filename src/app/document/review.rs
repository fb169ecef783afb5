//! The review queue in the editor (`facesynth review DIR`): the folder's scans worst first;
//! *Next* / *Previous* open the next scan with its points, and moving on from a scan whose
//! points were corrected writes its correction file.

use super::*;
use crate::pipeline::{LandmarkSource, ReviewQueue};

/// The queue and where the user is in it.
#[derive(Debug, Clone)]
pub struct Review {
    pub queue: ReviewQueue,
    /// The entry open in the editor.
    pub current: Option<usize>,
}

impl Document {
    /// Starts building the queue of `dir` on the worker.
    pub(super) fn start_review(&mut self, dir: PathBuf) -> Vec<Job> {
        let progress = Arc::new(ReviewProgress::default());
        self.review_progress = Some(progress.clone());
        self.pending.push("reviewing");
        vec![Job::Review {
            dir,
            landmarks_dir: self.landmarks_dir.clone(),
            progress,
        }]
    }

    /// The queue has been built: open its first (worst) scan.
    pub(super) fn review_ready(&mut self, queue: ReviewQueue) -> Vec<Job> {
        self.review_progress = None;
        self.status = Some(format!(
            "review: {} scans ({} from the cache), {} reviewed",
            queue.entries.len(),
            queue.cached,
            queue.reviewed()
        ));
        self.review = Some(Review {
            queue,
            current: None,
        });
        self.review_go(0)
    }

    /// Leaves the open entry (writing its correction if points were moved and not saved, and
    /// marking it reviewed), then opens entry `to` with its points.
    pub(super) fn review_go(&mut self, to: usize) -> Vec<Job> {
        let Some(count) = self.review.as_ref().map(|r| r.queue.entries.len()) else {
            return self.fail("no review queue (File → Review folder…)");
        };
        if let Some(current) = self.review.as_ref().and_then(|r| r.current) {
            let corrected = self
                .landmark_file()
                .is_some_and(|f| f.source == LandmarkSource::Corrected);
            if corrected && self.unsaved().contains(&Part::Landmarks) {
                self.apply(Command::SaveCorrection);
                if self.error.is_some() {
                    return Vec::new();
                }
            }
            if let Some(review) = &mut self.review
                && let Err(e) = review.queue.mark_reviewed(current)
            {
                self.error = Some(e.to_string());
                return Vec::new();
            }
        }
        if to >= count {
            // Past the last scan: the last one is reviewed, the editor stays on it.
            self.status = Some(format!(
                "end of the review queue: {}",
                self.review_counter().unwrap_or_default()
            ));
            return Vec::new();
        }
        let review = self.review.as_mut().expect("checked above");
        review.current = Some(to);
        let entry = &review.queue.entries[to];
        self.pending_points = entry.detected_file();
        let scan = entry.scan.clone();
        self.apply(Command::Open(Some(scan)))
    }

    /// "12 of 61 reviewed".
    pub fn review_counter(&self) -> Option<String> {
        let r = self.review.as_ref()?;
        Some(format!(
            "{} of {} reviewed",
            r.queue.reviewed(),
            r.queue.entries.len()
        ))
    }
}
