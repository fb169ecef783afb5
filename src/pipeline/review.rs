//! The review queue of a gallery folder (`facesynth review DIR`): every scan's detected
//! feature points, worst first, so a person corrects the bad ones before anything is built
//! from them.
//!
//! Order: scans whose detection failed, then suspect ones ([`LandmarkReport::suspect`]), then
//! the rest by how many anatomical checks their points fail ([`landmarks::implausibility`]:
//! failed Table 2 and level checks, guessed or unstable points) and then by face-likeness, low
//! first; scans with a correction file come last (already reviewed by a person).
//!
//! Detection (denoise → feature points, as `augment` does) runs once per scan and is cached in
//! `.facesynth-review.json` in the corrections folder, keyed by the scan's size and
//! modification time, so the queue opens at once the second time. The cache also records which
//! scans were reviewed.

use super::{LandmarkFile, LandmarkSource, correction_for, detect_scan, gallery_scans};
use crate::landmarks::{self, LandmarkReport};
use crate::{Error, Result, io};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The cache's file name, in the corrections folder.
pub const REVIEW_CACHE: &str = ".facesynth-review.json";

/// Where a scan stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReviewState {
    /// Detection found no face (or the file is unreadable): place the points by hand.
    Failed,
    /// Detected, but the points are suspect.
    Suspect,
    /// Detected.
    Detected,
    /// A correction file gives the points.
    Corrected,
}

impl ReviewState {
    pub fn name(self) -> &'static str {
        match self {
            ReviewState::Failed => "failed",
            ReviewState::Suspect => "suspect",
            ReviewState::Detected => "detected",
            ReviewState::Corrected => "corrected",
        }
    }
}

/// One scan of the queue.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReviewEntry {
    pub scan: PathBuf,
    pub state: ReviewState,
    /// Why it is where it is (one line).
    pub reason: String,
    /// Anatomical problems of the detected points ([`landmarks::implausibility`]).
    pub problems: usize,
    /// Face localisation's face-likeness of the detection (0–1), where localised.
    pub face_likeness: Option<f64>,
    /// The detected points (`None` when detection failed).
    pub detected: Option<serde_json::Value>,
    /// A person moved on from it in the queue (or corrected it).
    pub reviewed: bool,
}

impl ReviewEntry {
    /// The detected points as a landmark file (source `detected`).
    pub fn detected_file(&self) -> Option<LandmarkFile> {
        let v = self.detected.as_ref()?;
        LandmarkFile::parse(&v.to_string(), &self.scan).ok()
    }

    /// Sort key: worst first.
    fn order(&self) -> (ReviewState, std::cmp::Reverse<usize>, u64) {
        let likeness = self.face_likeness.unwrap_or(1.0).clamp(0.0, 1.0);
        (
            self.state,
            std::cmp::Reverse(self.problems),
            (likeness * 1e6) as u64,
        )
    }
}

/// The queue of a folder.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReviewQueue {
    pub dir: PathBuf,
    /// Where the correction files are (`None`: beside the scans).
    pub landmarks_dir: Option<PathBuf>,
    pub entries: Vec<ReviewEntry>,
    /// Scans whose detection came from the cache.
    pub cached: usize,
}

/// What the cache keeps per scan file name.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct CacheEntry {
    size: u64,
    modified_ns: u128,
    entry: ReviewEntry,
}

/// A file's size and modification time (ns since the epoch), which key the cache.
fn stamp(path: &Path) -> Option<(u64, u128)> {
    let m = std::fs::metadata(path).ok()?;
    let t = m
        .modified()
        .ok()?
        .duration_since(std::time::UNIX_EPOCH)
        .ok()?;
    Some((m.len(), t.as_nanos()))
}

/// Denoises and detects as `augment` does; the queue's row for it.
fn detect_entry(scan: &Path) -> ReviewEntry {
    let found = io::read_mesh(scan).and_then(detect_scan);
    match found {
        Ok(report) => entry_of(scan, &report),
        Err(e) => ReviewEntry {
            scan: scan.to_path_buf(),
            state: ReviewState::Failed,
            reason: e.to_string(),
            problems: 0,
            face_likeness: None,
            detected: None,
            reviewed: false,
        },
    }
}

fn entry_of(scan: &Path, report: &LandmarkReport) -> ReviewEntry {
    let problems = landmarks::implausibility(report);
    let (state, reason) = if !report.suspect.is_empty() {
        (ReviewState::Suspect, report.suspect.join("; "))
    } else if problems > 0 {
        let mut lines: Vec<String> = report
            .failed_checks()
            .iter()
            .map(|c| format!("{c} out of Table 2 range"))
            .collect();
        lines.extend(report.warnings.iter().cloned());
        lines.truncate(3);
        (ReviewState::Detected, lines.join("; "))
    } else {
        (ReviewState::Detected, "every check passes".to_string())
    };
    let file = LandmarkFile {
        landmarks: report.landmarks,
        source: LandmarkSource::Detected,
        scan: scan.file_name().map(|n| n.to_string_lossy().into_owned()),
        corrected: Vec::new(),
    };
    ReviewEntry {
        scan: scan.to_path_buf(),
        state,
        reason,
        problems,
        face_likeness: report.localisation.as_ref().map(|l| l.face_likeness),
        detected: Some(file.to_json()),
        reviewed: false,
    }
}

impl ReviewQueue {
    /// Builds the queue of `dir` (detecting where the cache has nothing for a scan as it is
    /// now); `progress(done, total)` after each scan.
    pub fn build(
        dir: &Path,
        landmarks_dir: Option<&Path>,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<ReviewQueue> {
        use rayon::prelude::*;
        // Every mesh file of the folder (a gallery scan with any suffix).
        let scans = gallery_scans(dir, "")?;
        if scans.is_empty() {
            return Err(Error::invalid(dir, "no scans (mesh files) to review"));
        }
        let cache = read_cache(&cache_path(dir, landmarks_dir));
        let total = scans.len();
        let counter = std::sync::atomic::AtomicUsize::new(0);
        progress(0, total);
        let rows: Vec<(ReviewEntry, bool)> = scans
            .par_iter()
            .map(|scan| {
                let name = file_name(scan);
                let hit = stamp(scan).and_then(|(size, modified_ns)| {
                    cache
                        .get(&name)
                        .filter(|c| c.size == size && c.modified_ns == modified_ns)
                        .map(|c| ReviewEntry {
                            scan: scan.clone(),
                            ..c.entry.clone()
                        })
                });
                let row = match hit {
                    Some(e) => (e, true),
                    None => (detect_entry(scan), false),
                };
                let k = counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(k, total);
                row
            })
            .collect();
        let mut queue = ReviewQueue {
            dir: dir.to_path_buf(),
            landmarks_dir: landmarks_dir.map(Path::to_path_buf),
            cached: rows.iter().filter(|(_, hit)| *hit).count(),
            entries: rows.into_iter().map(|(e, _)| e).collect(),
        };
        for i in 0..queue.entries.len() {
            queue.refresh(i);
        }
        queue
            .entries
            .sort_by(|a, b| a.order().cmp(&b.order()).then(a.scan.cmp(&b.scan)));
        queue.save_cache()?;
        Ok(queue)
    }

    /// The correction file of entry `i`, where there is one.
    pub fn correction(&self, i: usize) -> Option<PathBuf> {
        correction_for(&self.entries[i].scan, None, self.landmarks_dir.as_deref())
    }

    /// Re-reads entry `i`'s correction file: with one, the entry is `corrected` (and
    /// reviewed); without, it is what detection made it.
    pub fn refresh(&mut self, i: usize) {
        let correction = self.correction(i).map(|p| LandmarkFile::read(&p));
        let e = &mut self.entries[i];
        match correction {
            Some(Ok(file)) => {
                e.state = ReviewState::Corrected;
                e.reviewed = true;
                e.reason = match file.corrected.len() {
                    0 => format!("points from a {} file", file.source.name()),
                    n => format!(
                        "{n} placed by hand: {}",
                        file.corrected
                            .iter()
                            .map(|p| p.name())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                };
            }
            Some(Err(err)) => {
                e.state = ReviewState::Failed;
                e.reason = format!("correction file unreadable: {err}");
            }
            None if e.state == ReviewState::Corrected => {
                // The file was removed: back to the detection.
                let detected = e.detected.clone();
                let reviewed = e.reviewed;
                *e = match detected {
                    Some(_) => detect_entry(&e.scan),
                    None => e.clone(),
                };
                e.reviewed = reviewed;
            }
            None => {}
        }
    }

    /// Marks entry `i` reviewed (and keeps that in the cache).
    pub fn mark_reviewed(&mut self, i: usize) -> Result<()> {
        self.refresh(i);
        self.entries[i].reviewed = true;
        self.save_cache()
    }

    /// How many entries were reviewed.
    pub fn reviewed(&self) -> usize {
        self.entries.iter().filter(|e| e.reviewed).count()
    }

    fn save_cache(&self) -> Result<()> {
        let mut map = BTreeMap::new();
        for e in &self.entries {
            if let Some((size, modified_ns)) = stamp(&e.scan) {
                map.insert(
                    file_name(&e.scan),
                    CacheEntry {
                        size,
                        modified_ns,
                        entry: e.clone(),
                    },
                );
            }
        }
        let path = cache_path(&self.dir, self.landmarks_dir.as_deref());
        let text = serde_json::to_string(&map).unwrap_or_default() + "\n";
        io::write_text_atomic(&path, &text)
    }
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

fn cache_path(dir: &Path, landmarks_dir: Option<&Path>) -> PathBuf {
    landmarks_dir.unwrap_or(dir).join(REVIEW_CACHE)
}

/// The cache, or an empty one (a missing or stale cache only costs time).
fn read_cache(path: &Path) -> BTreeMap<String, CacheEntry> {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or_default()
}
