//! Mesh readers and writers, one format per file. Formats are chosen by file extension.
//!
//! Every reader returns a validated [`Mesh`] in millimetres or an [`Error`] whose one-line
//! message names the file and the problem; no input makes a reader panic. Every writer writes
//! to a temporary file beside the target and renames it into place, so an interrupted write
//! never leaves a half-written file under the real name.

pub mod obj;
pub mod ply;
pub mod vrml;
pub mod xyz;

use crate::mesh::Polygons;
use crate::{Error, Mesh, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The mesh formats facesynth knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// VRML 1.0 or 2.0 (`.wrl`, `.vrml`): GavabDB / Minolta VIVID scans. Read only.
    Vrml,
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// Stanford PLY (`.ply`), ascii or binary little-endian.
    Ply,
    /// Point cloud, one `x y z` per line (`.xyz`, `.txt`); triangulated on reading. Read only.
    Xyz,
}

impl MeshFormat {
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        match ext.as_str() {
            "wrl" | "vrml" => Ok(MeshFormat::Vrml),
            "obj" => Ok(MeshFormat::Obj),
            "ply" => Ok(MeshFormat::Ply),
            "xyz" | "txt" => Ok(MeshFormat::Xyz),
            _ => Err(Error::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }
}

/// Limits on what a reader accepts, so a corrupt header cannot make us allocate without bound.
#[derive(Debug, Clone, Copy)]
pub struct ReadLimits {
    /// Largest file accepted, bytes. Default 1 GiB (the largest GavabDB scan is < 1 MB).
    pub max_file_bytes: u64,
    /// Largest vertex count accepted. Default 20 million.
    pub max_vertices: usize,
}

impl Default for ReadLimits {
    fn default() -> Self {
        ReadLimits {
            max_file_bytes: 1 << 30,
            max_vertices: 20_000_000,
        }
    }
}

/// Reads a mesh in any known format (by extension) with default limits.
pub fn read_mesh(path: &Path) -> Result<Mesh> {
    read_mesh_with(path, &ReadLimits::default())
}

/// Reads a mesh in any known format (by extension).
pub fn read_mesh_with(path: &Path, limits: &ReadLimits) -> Result<Mesh> {
    let format = MeshFormat::from_path(path)?;
    let bytes = read_file(path, limits)?;
    let mesh = match format {
        MeshFormat::Vrml => vrml::parse(&bytes, path, limits)?,
        MeshFormat::Obj => obj::parse(&bytes, path, limits)?,
        MeshFormat::Ply => ply::parse(&bytes, path, limits)?,
        MeshFormat::Xyz => xyz::parse(&bytes, path, limits)?,
    };
    mesh.validate().map_err(|m| Error::invalid(path, m))?;
    Ok(mesh)
}

/// Writes a mesh; the format follows the extension (OBJ or PLY).
pub fn write_mesh(path: &Path, mesh: &Mesh) -> Result<()> {
    match MeshFormat::from_path(path)? {
        MeshFormat::Obj => write_atomic(path, |w| obj::write(w, mesh)),
        MeshFormat::Ply => write_atomic(path, |w| ply::write_binary(w, mesh, None)),
        MeshFormat::Vrml | MeshFormat::Xyz => Err(Error::invalid(
            path,
            "facesynth writes meshes as .obj or .ply only",
        )),
    }
}

/// Reads a whole file after checking it is a regular file within the size limit.
pub fn read_file(path: &Path, limits: &ReadLimits) -> Result<Vec<u8>> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::invalid(path, "is a directory, not a file"));
    }
    if meta.len() > limits.max_file_bytes {
        return Err(Error::invalid(
            path,
            format!(
                "file is {} bytes, more than the limit of {} bytes",
                meta.len(),
                limits.max_file_bytes
            ),
        ));
    }
    std::fs::read(path).map_err(|e| Error::io(path, e))
}

/// Writes through `body` into `path.tmp-<pid>` beside `path`, then renames it over `path`.
/// On any error the temporary file is removed and `path` is left as it was.
pub fn write_atomic(
    path: &Path,
    body: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let tmp = temp_path_for(path);
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(file);
        body(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

/// Writes a string atomically (JSON reports, RON presets, landmark files).
pub fn write_text_atomic(path: &Path, text: &str) -> Result<()> {
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}

/// Appends a face read from a file after merging consecutive repeated corners (cyclically);
/// a face left with fewer than 3 corners, or with a corner repeated elsewhere, is dropped since
/// it has no area. `reverse` turns a clockwise face counter-clockwise. Returns whether it was
/// kept. Shared by the readers so they treat degenerate faces alike.
pub(crate) fn push_clean_face(faces: &mut Polygons, face: &mut Vec<u32>, reverse: bool) -> bool {
    face.dedup();
    while face.len() > 1 && face.first() == face.last() {
        face.pop();
    }
    if face.len() < 3 {
        return false;
    }
    for (k, a) in face.iter().enumerate() {
        if face.get(k + 1..).is_some_and(|rest| rest.contains(a)) {
            return false;
        }
    }
    if reverse {
        face.reverse();
    }
    faces.push(face);
    true
}

fn temp_path_for(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}
