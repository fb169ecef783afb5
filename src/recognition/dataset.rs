//! A recognition dataset folder.
//!
//! **Layout** (GavabDB and `synth_gavab.py` alike): `DIR/<subject>_<scan>.<ext>` with
//! `<ext>` one of wrl, vrml, obj, ply, xyz, txt (point clouds, see `io::xyz`); the subject is everything before the last `_`
//! (`cara1_frontal1.wrl`, `subj007_risa.wrl`). Other files are ignored.
//!

use crate::{Result, io};
use std::path::{Path, PathBuf};

/// One scan file of a dataset.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct ScanFile {
    pub subject: String,
    /// `frontal1`, `risa`, …
    pub scan: String,
    pub path: PathBuf,
}

/// A mesh file by its extension (the formats [`io::MeshFormat`] reads).
pub(crate) fn is_mesh(path: &Path) -> bool {
    io::MeshFormat::from_path(path).is_ok()
}

/// The scans of a dataset folder, sorted by subject then scan.
pub fn list_scans(dir: &Path) -> Result<Vec<ScanFile>> {
    let mut out = Vec::new();
    for path in io::read_dir_sorted(dir)? {
        if !path.is_file() || !is_mesh(&path) {
            continue;
        }
        let Some(stem) = path.file_stem().and_then(|s| s.to_str()) else {
            continue;
        };
        if let Some((subject, scan)) = stem.rsplit_once('_')
            && !subject.is_empty()
            && !scan.is_empty()
        {
            out.push(ScanFile {
                subject: subject.to_string(),
                scan: scan.to_string(),
                path: path.clone(),
            });
        }
    }
    out.sort();
    Ok(out)
}
