//! Landmark files: the one schema every command and the editor read and write, and the
//! corrections kept beside a scan.
//!
//! A file is a JSON object with the 13 points under `"landmarks"` (name → [x, y, z] mm, scan
//! frame), `"source"` (`detected`: written by `facesynth landmarks --json`; `corrected`: saved
//! by the editor after points were moved; `given`: anything else), `"scan"` (the file name of
//! the scan it belongs to) and `"corrected"` (the names of the points placed by hand).
//! `landmarks --json` adds its checks beside them, and `"units"`: the scan file's unit (`file`:
//! `mm`, `cm` or `m`; `mm_per_file_unit`; `guessed` from its size or given by `--units`), since
//! the points are in millimetres whatever the file's. A flat map name → [x, y, z] is read as
//! `given`.
//!
//! A correction file `<scan stem>.landmarks.json` beside a scan, or in the folder given by
//! `--landmarks-dir`, replaces detection in `register`, `fit-expression`, `augment`,
//! `evaluate` and `view` ([`correction_for`]).

use crate::{Error, FeaturePoint, Landmarks, Result, io};
use serde_json::json;
use std::path::{Path, PathBuf};

/// What a correction file is named after its scan: `<scan stem>` + this.
pub const CORRECTION_SUFFIX: &str = ".landmarks.json";

/// Where a file's points come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LandmarkSource {
    /// The detector's, unchanged (`facesynth landmarks --json`, or the editor without a move).
    Detected,
    /// The detector's (or a loaded file's) with points moved by hand in the editor.
    Corrected,
    /// A file of unknown origin (a flat map, another tool): every point is taken as meant.
    Given,
}

impl LandmarkSource {
    pub fn name(self) -> &'static str {
        match self {
            LandmarkSource::Detected => "detected",
            LandmarkSource::Corrected => "corrected",
            LandmarkSource::Given => "given",
        }
    }
}

/// A landmark file's content.
#[derive(Debug, Clone, PartialEq)]
pub struct LandmarkFile {
    pub landmarks: Landmarks,
    pub source: LandmarkSource,
    /// The file name of the scan the points belong to, if recorded.
    pub scan: Option<String>,
    /// The points placed by hand (for [`LandmarkSource::Corrected`]).
    pub corrected: Vec<FeaturePoint>,
}

impl LandmarkFile {
    /// Reads either shape (see the module docs); errors name the file.
    pub fn read(path: &Path) -> Result<Self> {
        Self::parse(&io::read_text_file(path)?, path)
    }

    /// Parses a landmark file's text (`path` only names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let value: serde_json::Value = serde_json::from_str(text)
            .map_err(|e| Error::syntax(path, e.line(), format!("not a landmark file: {e}")))?;
        let bad = |m: String| Error::invalid(path, format!("not a landmark file: {m}"));
        let (points, wrapped) = match value.get("landmarks") {
            Some(inner) if inner.is_object() => (inner.clone(), true),
            _ => (value.clone(), false),
        };
        let landmarks: Landmarks =
            serde_json::from_value(points).map_err(|e| bad(e.to_string()))?;
        let source = match value.get("source").filter(|_| wrapped) {
            Some(s) => serde_json::from_value(s.clone()).map_err(|_| {
                bad(format!(
                    "source {s} (expected detected, corrected or given)"
                ))
            })?,
            // `landmarks --json` from before the field: its checks are beside the points.
            None if wrapped && value.get("distances_mm").is_some() => LandmarkSource::Detected,
            None => LandmarkSource::Given,
        };
        let mut corrected = Vec::new();
        if let Some(list) = value.get("corrected").filter(|_| wrapped) {
            for name in list.as_array().into_iter().flatten() {
                let p = name
                    .as_str()
                    .and_then(FeaturePoint::from_name)
                    .ok_or_else(|| bad(format!("unknown corrected point {name}")))?;
                corrected.push(p);
            }
            corrected.sort();
            corrected.dedup();
        }
        let scan = value
            .get("scan")
            .filter(|_| wrapped)
            .and_then(|s| s.as_str())
            .map(str::to_string);
        Ok(LandmarkFile {
            landmarks,
            source,
            scan,
            corrected,
        })
    }

    /// The file's JSON: `source`, `scan`, `corrected`, `landmarks`.
    pub fn to_json(&self) -> serde_json::Value {
        json!({
            "source": self.source,
            "scan": self.scan,
            "corrected": self.corrected.iter().map(|p| p.name()).collect::<Vec<_>>(),
            "landmarks": self.landmarks,
        })
    }

    /// Writes the file atomically (a temporary file, then a rename).
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(&self.to_json()).unwrap_or_default() + "\n";
        io::write_text_atomic(path, &text)
    }

    /// Whether the cheek and forehead points are the detector's region borders, which the
    /// registration leaves out ([`super::registration_points`]); points of unknown origin, or
    /// borders placed by hand, are the generic face's points and are matched.
    pub fn borders_detected(&self) -> bool {
        match self.source {
            LandmarkSource::Detected => true,
            LandmarkSource::Corrected => !self
                .corrected
                .iter()
                .any(|p| FeaturePoint::BORDER.contains(p)),
            LandmarkSource::Given => false,
        }
    }
}

/// Where the correction file of `scan` is (or would be): `<stem>.landmarks.json` in `dir`, or
/// beside the scan without one.
pub fn correction_path(scan: &Path, dir: Option<&Path>) -> PathBuf {
    let stem = scan
        .file_stem()
        .map_or_else(|| "scan".into(), |s| s.to_string_lossy().into_owned());
    let folder = dir.map_or_else(
        || scan.parent().unwrap_or(Path::new("")).to_path_buf(),
        Path::to_path_buf,
    );
    folder.join(format!("{stem}{CORRECTION_SUFFIX}"))
}

/// The landmark file a command uses for `scan`: `explicit` (a `--landmarks` option) if given,
/// else the correction file ([`correction_path`]) if it exists; `None`: detect.
pub fn correction_for(scan: &Path, explicit: Option<&Path>, dir: Option<&Path>) -> Option<PathBuf> {
    explicit
        .map(Path::to_path_buf)
        .or_else(|| Some(correction_path(scan, dir)).filter(|p| p.is_file()))
}

/// Whether `path` is a correction file (so scan listings can skip it).
pub fn is_correction_file(path: &Path) -> bool {
    path.file_name()
        .is_some_and(|n| n.to_string_lossy().ends_with(CORRECTION_SUFFIX))
}
