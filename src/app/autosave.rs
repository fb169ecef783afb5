//! The editor's autosave: the document's editable state (scan path, landmarks, erased vertices,
//! materials, muscles, activations, presets) as RON, written atomically every [`AUTOSAVE_INTERVAL_S`]
//! while there are unsaved changes and at exit, and removed at a clean exit. So a file found
//! at start means the last session ended with unsaved work (a crash, a kill, a power cut, or
//! closing with "keep autosave"): the editor offers to restore it.
//!
//! No egui here, so the round trip and the restore are tested without a window.

use super::document::{Document, Edits};
use crate::{Error, Result, io};
use std::path::{Path, PathBuf};

/// Seconds between autosaves while the document has unsaved changes.
pub const AUTOSAVE_INTERVAL_S: f64 = 30.0;

/// Version of the file layout; a file of another version is not offered.
pub const FORMAT: u32 = 1;

/// What the autosave file holds.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AutosaveState {
    pub format: u32,
    /// When it was written, seconds since the Unix epoch (shown in the restore prompt).
    pub saved_unix_s: u64,
    /// The scan that was open (re-read on restore; `None`: the generic face alone).
    pub scan: Option<PathBuf>,
    /// The document's edits, exactly what undo/redo restores.
    pub edits: Edits,
    /// The denoising run on the scan, if any: restoring runs it again (it is deterministic),
    /// so the erased vertices and the landmarks come back on the same working scan.
    #[serde(default)]
    pub denoise: Option<crate::denoise::DenoiseParams>,
}

impl AutosaveState {
    /// The document's editable state now.
    pub fn of(doc: &Document) -> Self {
        AutosaveState {
            format: FORMAT,
            saved_unix_s: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs()),
            scan: doc.scan.as_ref().map(|s| s.path.clone()),
            edits: doc.edits.clone(),
            denoise: doc.denoised.as_ref().map(|d| d.params),
        }
    }

    /// Puts this state back into `doc` (see [`Document::restore_saved`]); the jobs to run.
    pub fn restore(&self, doc: &mut Document) -> Vec<super::jobs::Job> {
        doc.restore_saved(self.scan.as_deref(), self.edits.clone(), self.denoise)
    }

    pub fn to_ron(&self) -> String {
        ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::new()).unwrap_or_default() + "\n"
    }

    /// Parses an autosave file's text (`path` only names it in errors).
    pub fn from_ron(text: &str, path: &Path) -> Result<Self> {
        let state: AutosaveState = ron::from_str(text)
            .map_err(|e| Error::syntax(path, e.span.start.line, e.code.to_string()))?;
        if state.format != FORMAT {
            return Err(Error::invalid(
                path,
                format!(
                    "autosave format {} (this editor reads {FORMAT})",
                    state.format
                ),
            ));
        }
        Ok(state)
    }

    /// Writes atomically (a crash mid-write leaves the previous autosave intact).
    pub fn write(&self, path: &Path) -> Result<()> {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
        io::write_text_atomic(path, &self.to_ron())
    }

    pub fn read(path: &Path) -> Result<Self> {
        Self::from_ron(&io::read_text_file(path)?, path)
    }
}

/// Where the autosave lives: `$FACESYNTH_AUTOSAVE` if set, else
/// `$XDG_STATE_HOME/facesynth/autosave.ron`, else `~/.local/state/facesynth/autosave.ron`.
pub fn default_path() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("FACESYNTH_AUTOSAVE") {
        return Some(PathBuf::from(p));
    }
    let state = std::env::var_os("XDG_STATE_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/state")))?;
    Some(state.join("facesynth").join("autosave.ron"))
}

/// The autosave left by an earlier session, if there is a readable one. An unreadable file is
/// reported (so it is not silently lost) and not offered.
pub fn find(path: &Path) -> Option<Result<AutosaveState>> {
    path.is_file().then(|| AutosaveState::read(path))
}

/// Removes the autosave (a clean exit, or the user declined to restore it).
pub fn remove(path: &Path) {
    let _ = std::fs::remove_file(path);
}
