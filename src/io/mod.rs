//! Mesh readers and writers, one format per file. Formats are chosen by file extension.
//!
//! Every reader returns a validated [`Mesh`] in millimetres or an [`Error`] whose one-line
//! message names the file and the problem; no input makes a reader panic. Every writer writes
//! to a temporary file beside the target and renames it into place, so an interrupted write
//! never leaves a half-written file under the real name.
//!
//! What the readers accept rather than refuse (the sensible outcome for scan data):
//! - a face repeating a vertex is cleaned (consecutive repeats merged) or, with no area left,
//!   dropped; a face with the same vertices as an earlier one (either orientation) is dropped;
//! - collinear (zero-area) faces and non-manifold edges (three or more faces on one edge) are
//!   kept as they are: they carry no area, so area-weighted normals and curvature ignore them;
//! - a mesh of one face is a mesh; the pipeline steps then say what they cannot do with it.
//!
//! What they refuse, each with the file and the problem: truncated data, counts that do not
//! match the data, indices out of range, non-finite or beyond-±[`ReadLimits`] coordinates,
//! no vertices or faces, text in another encoding, binary garbage, directories, unreadable
//! files, and anything over the file-size or vertex-count limits.

pub mod obj;
pub mod ply;
pub mod units;
pub mod vrml;
pub mod xyz;

pub use units::{Units, UnitsRead};

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
    /// Stanford PLY (`.ply`): reads ascii and binary (either byte order), writes binary
    /// little-endian.
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

/// Limits on what a reader accepts, so a corrupt header cannot make us allocate without bound
/// and a mistaken path to a huge file fails at once. The CLI sets them with `--max-file-mb`
/// and `--max-vertices` (see [`set_default_limits`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadLimits {
    /// Largest file accepted, bytes. Default 1 GiB (the largest GavabDB scan is < 1 MB; a
    /// 1M-vertex binary PLY of quads is ~29 MB, a 1.4M-vertex VRML scan ~85 MB).
    pub max_file_bytes: u64,
    /// Largest vertex (or point) count accepted. Default 20 million (peak memory through the
    /// landmark pipeline is ~400 bytes per vertex, measured on 1M-vertex meshes: ~8 GB at the
    /// limit).
    pub max_vertices: usize,
    /// Largest |coordinate| accepted, mm. Default 1e6 (1 km): a face scan spans < 1 m, so a
    /// larger value is a corrupt number or a file in other units, and would wreck every
    /// distance-based step downstream.
    pub max_abs_coordinate_mm: f64,
    /// The unit of the file's coordinates, scaled to mm on reading. Default [`Units::Auto`]:
    /// a mesh the size of a head in metres is scaled, and [`notify`] says so.
    pub units: Units,
}

impl ReadLimits {
    /// The documented defaults (see the fields).
    pub const DEFAULT: ReadLimits = ReadLimits {
        max_file_bytes: 1 << 30,
        max_vertices: 20_000_000,
        max_abs_coordinate_mm: 1e6,
        units: Units::Auto,
    };
}

impl Default for ReadLimits {
    fn default() -> Self {
        ReadLimits::DEFAULT
    }
}

/// The limits [`read_mesh`] uses; the CLI sets them once at start from its flags.
static DEFAULT_LIMITS: std::sync::RwLock<ReadLimits> = std::sync::RwLock::new(ReadLimits::DEFAULT);

/// Sets the limits every [`read_mesh`] call uses from now on (process-wide, so the CLI's
/// flags reach every command and pipeline step without threading them through).
pub fn set_default_limits(limits: ReadLimits) {
    *DEFAULT_LIMITS.write().unwrap_or_else(|e| e.into_inner()) = limits;
}

/// The limits [`read_mesh`] uses now.
pub fn default_limits() -> ReadLimits {
    *DEFAULT_LIMITS.read().unwrap_or_else(|e| e.into_inner())
}

/// Where [`notify`] sends its notes: nowhere by default; the CLI prints them on stderr.
static NOTICE_HOOK: std::sync::RwLock<Option<fn(&str)>> = std::sync::RwLock::new(None);

/// Sets where the readers' notes go (e.g. "scaled from metres"): things the user must know
/// that are not errors.
pub fn set_notice_hook(hook: fn(&str)) {
    *NOTICE_HOOK.write().unwrap_or_else(|e| e.into_inner()) = Some(hook);
}

/// Passes a one-line note to the hook set by [`set_notice_hook`].
pub fn notify(note: &str) {
    if let Some(hook) = *NOTICE_HOOK.read().unwrap_or_else(|e| e.into_inner()) {
        hook(note);
    }
}

/// Reads a mesh in any known format (by extension) with the [`default_limits`].
pub fn read_mesh(path: &Path) -> Result<Mesh> {
    read_mesh_with(path, &default_limits())
}

/// Reads a mesh in any known format (by extension).
pub fn read_mesh_with(path: &Path, limits: &ReadLimits) -> Result<Mesh> {
    read_mesh_and_units_with(path, limits).map(|(mesh, _)| mesh)
}

/// [`read_mesh`], with the unit the file was read in (for reports: the mesh is in millimetres
/// whatever the file's unit).
pub fn read_mesh_and_units(path: &Path) -> Result<(Mesh, UnitsRead)> {
    read_mesh_and_units_with(path, &default_limits())
}

fn read_mesh_and_units_with(path: &Path, limits: &ReadLimits) -> Result<(Mesh, UnitsRead)> {
    let format = MeshFormat::from_path(path)?;
    let bytes = read_file(path, limits)?;
    parse_mesh_and_units(&bytes, format, path, limits)
}

/// Parses a file's bytes in `format` and validates the mesh: what [`read_mesh_with`] does after
/// reading (the fuzz targets enter here). `path` only names the file in errors.
pub fn parse_mesh(
    bytes: &[u8],
    format: MeshFormat,
    path: &Path,
    limits: &ReadLimits,
) -> Result<Mesh> {
    parse_mesh_and_units(bytes, format, path, limits).map(|(mesh, _)| mesh)
}

/// [`parse_mesh`], with the unit the file was read in.
fn parse_mesh_and_units(
    bytes: &[u8],
    format: MeshFormat,
    path: &Path,
    limits: &ReadLimits,
) -> Result<(Mesh, UnitsRead)> {
    if looks_like_utf16(bytes) {
        return Err(Error::invalid(
            path,
            "the file is UTF-16 text; facesynth reads ASCII/UTF-8 (convert it, e.g. \
             `iconv -f UTF-16 -t UTF-8`)",
        ));
    }
    let mesh = match format {
        MeshFormat::Vrml => vrml::parse(bytes, path, limits)?,
        MeshFormat::Obj => obj::parse(bytes, path, limits)?,
        MeshFormat::Ply => ply::parse(bytes, path, limits)?,
        MeshFormat::Xyz => xyz::parse(bytes, path, limits)?,
    };
    let mut mesh = mesh;
    if mesh.faces.remove_duplicates() > 0 {
        mesh.update_normals();
    }
    mesh.validate().map_err(|m| Error::invalid(path, m))?;
    let (units_read, note) = units::to_millimetres(&mut mesh, limits.units, path);
    if let Some(note) = note {
        notify(&note);
    }
    let bound = limits.max_abs_coordinate_mm;
    if let Some((i, p)) = mesh
        .positions_mm
        .iter()
        .enumerate()
        .find(|(_, p)| p.abs().max_element() > bound)
    {
        return Err(Error::invalid(
            path,
            format!(
                "vertex {i} is at ({}, {}, {}) mm, beyond the limit of ±{bound:e} mm (a corrupt \
                 number, or the file is not in mm)",
                p.x, p.y, p.z
            ),
        ));
    }
    Ok((mesh, units_read))
}

/// A UTF-16 byte-order mark, or ASCII text with a zero byte after every character (Windows
/// tools save "Unicode" text so): every reader would otherwise report a puzzling syntax error.
fn looks_like_utf16(bytes: &[u8]) -> bool {
    if bytes.starts_with(&[0xff, 0xfe]) || bytes.starts_with(&[0xfe, 0xff]) {
        return true;
    }
    let head = &bytes[..bytes.len().min(64)];
    head.len() >= 8
        && head
            .chunks_exact(2)
            .all(|c| (c[0] == 0) != (c[1] == 0) && (c[0] | c[1]).is_ascii())
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
                "file is {} bytes, more than the limit of {} bytes (raise it with --max-file-mb)",
                meta.len(),
                limits.max_file_bytes
            ),
        ));
    }
    std::fs::read(path).map_err(|e| Error::io(path, e))
}

/// Largest text file (landmarks, presets, muscles, ground truth) accepted, bytes: 64 MiB, far
/// above any real one, so a mistaken path to a scan or a device fails fast.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// Reads a small UTF-8 text file (JSON, RON) through [`read_file`]'s checks.
/// The entries of the folder `dir`, sorted by path.
pub(crate) fn read_dir_sorted(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    out.sort();
    Ok(out)
}

pub fn read_text_file(path: &Path) -> Result<String> {
    let limits = ReadLimits {
        max_file_bytes: MAX_TEXT_BYTES.min(default_limits().max_file_bytes),
        ..default_limits()
    };
    let bytes = read_file(path, &limits)?;
    String::from_utf8(bytes).map_err(|e| {
        Error::invalid(
            path,
            format!(
                "not UTF-8 text (bad byte at offset {}); save it as UTF-8",
                e.utf8_error().valid_up_to()
            ),
        )
    })
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

/// Writes a picture as PNG atomically (headless pictures, plots, editor screenshots).
pub fn write_png<P>(path: &Path, img: &image::ImageBuffer<P, Vec<P::Subpixel>>) -> Result<()>
where
    P: image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
{
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::invalid(path, e.to_string()))?;
    write_atomic(path, |w| w.write_all(&bytes))
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

/// `.<name>.tmp-<pid>-<n>` beside `path`: hidden, never a mesh extension (so no reader or
/// batch takes it for an output), unique per process and per write (two threads writing the
/// same file do not share one).
pub fn temp_path_for(path: &Path) -> PathBuf {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    path.with_file_name(format!(".{name}.tmp-{}-{n}", std::process::id()))
}
