//! Gallery augmentation (paper section 3): 18 synthetic expressions per neutral gallery scan,
//! in parallel, resumable, failures listed.

use crate::generic_face::GenericFace;
use crate::pipeline::{
    CavityParams, LandmarkFile, LandmarkSource, TransferWeights, correction_for, gallery_scans,
    mouth_cavity, prepare_scan, repaired_fem_model,
};
use crate::{Error, Result, io};
use std::path::Path;

/// Settings of [`augment`].
#[derive(Debug, Clone)]
pub struct AugmentParams {
    /// A gallery scan is a mesh file whose stem ends with this (default `_frontal1`, the
    /// GavabDB neutral scan).
    pub gallery_suffix: String,
    /// `all` or a comma-separated list of preset names (default `all`: the 18 presets).
    pub expressions: String,
    /// The presets to choose from (default: the 18 built-ins; `augment --presets FILE` adds or
    /// replaces some, e.g. expressions learned with `fit-expression`).
    pub presets: crate::fem::expressions::ExpressionSet,
    /// Materials and layers of the FEM face (default: the paper's).
    pub fem: crate::fem::FemParams,
    /// The muscles (default: the built-in `assets/muscles.ron`; `augment --muscles FILE`).
    pub muscles: crate::fem::muscles::MuscleSet,
    /// Reach of the expression transfer onto the scan, mm (default 8: about three of the
    /// generic face's quads; see [`transfer_expression`]).
    pub transfer_radius_mm: f64,
    /// Each preset is also written at these multiples of its activations (default `[1]`:
    /// the presets as they are). A multiple other than 1 is written as `<name>_x<m>.ply`.
    pub intensities: Vec<f64>,
    /// Open-mouth laughs: for each angle (degrees), [`Self::laugh_base`] with the FEM jaw
    /// opened by that angle (`jaw_open`, on top of the preset's own), carried onto the scan,
    /// with the mouth's inside pushed back ([`mouth_cavity`]); written as `laugh_jaw<deg>.ply`.
    /// Default empty (the 18 presets only).
    pub jaw_open_deg: Vec<f64>,
    /// The FEM preset the laughs start from (default `broad_smile`).
    pub laugh_base: String,
    /// The open mouth's inside as the scanner sees it ([`mouth_cavity`]).
    pub cavity: CavityParams,
    /// Also write the FEM face's own surfaces (`face/*.obj`, for looking at). Default true.
    pub write_face_meshes: bool,
    /// Where the correction files `<scan stem>.landmarks.json` are ([`correction_for`]);
    /// default `None`: beside each gallery scan. A scan with one is augmented from its points.
    pub landmarks_dir: Option<std::path::PathBuf>,
    /// Only this share of the gallery (`--shard K/N`); default `None`: all of it.
    pub shard: Option<Shard>,
}

/// One of `count` shares of a gallery: the scans whose index in the sorted gallery is
/// ≡ `index` (mod `count`). Shards run anywhere (a cluster's job array) and write the same
/// folders one run would.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;
    /// `K/N` with 0 ≤ K < N.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let (k, n) = s
            .split_once('/')
            .ok_or_else(|| format!("shard `{s}`: expected K/N, e.g. 0/16"))?;
        let parse = |t: &str| {
            t.trim()
                .parse::<usize>()
                .map_err(|_| format!("shard `{s}`: `{t}` is not a whole number"))
        };
        let (index, count) = (parse(k)?, parse(n)?);
        if count == 0 || index >= count {
            return Err(format!("shard `{s}`: need 0 ≤ K < N"));
        }
        Ok(Shard { index, count })
    }
}

impl Shard {
    /// The failure list's file name: `failures.K-of-N.json`.
    pub fn failures_file(self) -> String {
        format!("failures.{}-of-{}.json", self.index, self.count)
    }
}

impl Default for AugmentParams {
    fn default() -> Self {
        AugmentParams {
            gallery_suffix: "_frontal1".into(),
            expressions: "all".into(),
            presets: crate::fem::expressions::ExpressionSet::builtin(),
            fem: crate::fem::FemParams::default(),
            muscles: crate::fem::muscles::MuscleSet::builtin(),
            transfer_radius_mm: 8.0,
            intensities: vec![1.0],
            jaw_open_deg: Vec::new(),
            laugh_base: "broad_smile".into(),
            cavity: CavityParams::default(),
            write_face_meshes: true,
            landmarks_dir: None,
            shard: None,
        }
    }
}

/// What [`augment`] did with one gallery scan.
#[derive(Debug, Clone, serde::Serialize)]
pub struct AugmentedScan {
    pub scan: std::path::PathBuf,
    /// `OUT/<stem>/`: one PLY per expression (the scan carrying it, scan frame, mm) and
    /// `face/` with the FEM face's own surfaces (`neutral.obj` + one OBJ per expression).
    pub dir: std::path::PathBuf,
    /// Finished by an earlier run with the same settings (its `done.json` records the same
    /// [`augment_recipe`]): skipped.
    pub resumed: bool,
    /// Finished by an earlier run with other settings: its samples were removed and made again.
    pub redone: bool,
    pub expressions: usize,
    pub landmark_warnings: usize,
    /// Where the feature points came from: detected, or a correction file (`corrected`, or
    /// `given` for a file of unknown origin).
    pub landmarks_source: LandmarkSource,
    /// The points placed by hand (from the correction file).
    pub corrected_points: Vec<String>,
    /// The axes the face was found in and how the head is turned, as `landmarks --json` gives
    /// them (`LandmarkReport::orientation_json`); `None` where the points came from a file.
    pub orientation: Option<serde_json::Value>,
    pub matched_fraction: f64,
    pub millis: f64,
}

/// A gallery scan that a step failed on, and why (the batch goes on).
#[derive(Debug, Clone, serde::Serialize)]
pub struct AugmentFailure {
    pub scan: std::path::PathBuf,
    /// The step that failed (`landmarks` for "no nose tip found", `fem` for a singular
    /// system, `input` for a bad file …).
    pub stage: crate::error::Stage,
    pub reason: String,
    /// The detected feature points were suspect ([`crate::landmarks::LandmarkReport::suspect`]):
    /// the scan was not augmented from them.
    pub suspect: bool,
}

/// The marker a finished subject's folder gets last: a folder without it is unfinished and is
/// redone (its files may be from a killed run).
pub const DONE_MARKER: &str = "done.json";

/// Everything that decides what a subject's samples look like: the chosen presets (names
/// *and* activations: a `--presets` file may change a preset under the same name), their
/// intensities, the open-mouth laughs, the cavity, the FEM and the transfer settings. It is
/// recorded in [`DONE_MARKER`]; a resumed [`augment`] skips a subject only if its recorded
/// recipe is this one, and otherwise redoes it (samples made with other settings would be
/// mixed into one gallery without anyone noticing).
///
/// Errors (the settings' only check, so [`augment`] refuses them before any scan): an unknown
/// preset name, a negative or non-finite laugh angle.
pub fn augment_recipe(params: &AugmentParams) -> Result<serde_json::Value> {
    if let Some(bad) = params
        .jaw_open_deg
        .iter()
        .find(|d| !(d.is_finite() && **d >= 0.0))
    {
        return Err(Error::algorithm(
            "augment",
            format!(
                "jaw opening {bad}° (must be ≥ 0: a negative angle closes the jaw into the face)"
            ),
        ));
    }
    let chosen = params.presets.select(&params.expressions)?;
    let laugh = if params.jaw_open_deg.is_empty() {
        serde_json::Value::Null
    } else {
        let base = params.presets.select(&params.laugh_base)?;
        serde_json::json!({
            "base": base.first().map(|e| (&e.name, &e.activations)),
            "jaw_open_deg": params.jaw_open_deg,
        })
    };
    Ok(serde_json::json!({
        "presets": chosen.iter().map(|e| (&e.name, &e.activations)).collect::<Vec<_>>(),
        "intensities": params.intensities,
        "laughs": laugh,
        "cavity": params.cavity,
        "fem": params.fem,
        "muscles": params.muscles,
        "transfer_radius_mm": params.transfer_radius_mm,
    }))
}

/// Whether `dir` holds a finished augmentation made with `recipe` (its [`DONE_MARKER`] records
/// the same recipe) from the same correction file (`correction`: its content, `null` for
/// none); with the marker's content where it could be read (a resumed scan takes what its run
/// recorded from it).
fn finished_with(
    dir: &Path,
    recipe: &serde_json::Value,
    correction: &serde_json::Value,
) -> (Finished, Option<serde_json::Value>) {
    let Ok(text) = std::fs::read_to_string(dir.join(DONE_MARKER)) else {
        return (Finished::No, None);
    };
    let Ok(done) = serde_json::from_str::<serde_json::Value>(&text) else {
        return (Finished::OtherSettings, None);
    };
    let finished = if done.get("recipe") != Some(recipe) {
        Finished::OtherSettings
    } else if done
        .get("landmark_file")
        .unwrap_or(&serde_json::Value::Null)
        == correction
    {
        Finished::Same
    } else {
        Finished::OtherLandmarks
    };
    (finished, Some(done))
}

#[derive(Debug, PartialEq)]
enum Finished {
    No,
    Same,
    /// Finished with other settings (or by a version that did not record them).
    OtherSettings,
    /// Finished from other feature points: the correction file was added, changed or removed.
    OtherLandmarks,
}

/// The correction file a gallery scan is augmented from ([`correction_for`]) and its content
/// as recorded in [`DONE_MARKER`] (`null` without one).
fn correction_of(
    scan: &Path,
    params: &AugmentParams,
) -> Result<(Option<std::path::PathBuf>, serde_json::Value)> {
    match correction_for(scan, None, params.landmarks_dir.as_deref()) {
        Some(path) => {
            let file = LandmarkFile::read(&path)?;
            Ok((Some(path), file.to_json()))
        }
        None => Ok((None, serde_json::Value::Null)),
    }
}

/// Empties a subject folder before it is (re)done: the marker first, so a run killed while
/// clearing leaves an unfinished folder, then the sample meshes directly in it (the folder is
/// `augment`'s own output; `face/` is overwritten as it is written). Without this, the samples
/// of presets the new run does not make would stay and be read as gallery samples.
fn clear_samples(dir: &Path) -> Result<()> {
    let marker = dir.join(DONE_MARKER);
    if marker.is_file() {
        std::fs::remove_file(&marker).map_err(|e| Error::io(&marker, e))?;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    for p in entries.flatten().map(|e| e.path()) {
        if p.is_file() && io::MeshFormat::from_path(&p).is_ok() {
            std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
        }
    }
    Ok(())
}

/// Removes the temporary files [`io::write_atomic`] leaves when a process is killed mid-write
/// (`.<name>.tmp-<pid>`). Best effort: a file that cannot be removed is left.
fn remove_stale_temp_files(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        if name.starts_with('.') && name.contains(".tmp-") {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// One gallery scan: denoise → landmarks → register → FEM → expressions, written into
/// `out_dir` atomically, `done.json` last; the scan's correction file is already read
/// ([`correction_of`]).
fn augment_scan(
    scan: &Path,
    (correction, correction_json): (Option<std::path::PathBuf>, serde_json::Value),
    out_dir: &Path,
    generic: &GenericFace,
    params: &AugmentParams,
) -> Result<AugmentedScan> {
    let start = std::time::Instant::now();
    let presets = &params.presets;
    // Checked before the FEM work, so a bad name or angle fails at once, not after every
    // expression.
    let recipe = augment_recipe(params)?;
    let chosen = presets.select(&params.expressions)?;
    let laugh = if params.jaw_open_deg.is_empty() {
        None
    } else {
        Some(presets.select(&params.laugh_base)?)
    };
    let prepared = prepare_scan(scan, correction.as_deref(), generic)?;
    let in_file = |e: Error| e.in_file(scan);
    // Suspect points would carry a wrong registration into 18 wrong expressions.
    if let Some(report) = prepared
        .detection
        .as_ref()
        .filter(|r| !r.suspect.is_empty())
    {
        return Err(in_file(Error::SuspectLandmarks {
            reasons: report.suspect.clone(),
        }));
    }
    let (mut model, repairs) = repaired_fem_model(
        &prepared.registration.mesh,
        generic.feature_vertices,
        &params.fem,
    )
    .map_err(in_file)?;
    model.factor().map_err(in_file)?;
    model.set_muscles(&params.muscles).map_err(in_file)?;
    model.compute_basis().map_err(in_file)?;
    // The gallery samples (the scan with each expression) go in `out_dir`, the FEM face's own
    // surfaces in `out_dir/face/` (for looking at; recognition reads only the top folder).
    let face_dir = out_dir.join("face");
    std::fs::create_dir_all(out_dir).map_err(|e| Error::io(out_dir, e))?;
    // A killed run may have left temporary files; nothing reads them, but they would pile up.
    remove_stale_temp_files(out_dir);
    if params.write_face_meshes {
        std::fs::create_dir_all(&face_dir).map_err(|e| Error::io(&face_dir, e))?;
        remove_stale_temp_files(&face_dir);
        // The surface the FEM was built on (locally repaired where the layers inverted).
        io::write_mesh(&face_dir.join("neutral.obj"), &model.surface)?;
    }
    let names: Vec<String> = model.actuator_names();
    let open = names.iter().position(|n| n == "jaw_open");
    let mut figures = serde_json::Map::new();
    let mut u = Vec::new();
    let mut written = 0;
    let transfer = TransferWeights::new(
        &prepared.denoised,
        &model.surface,
        params.transfer_radius_mm,
    );
    let intensity_tag = |m: f64| {
        if m == 1.0 {
            String::new()
        } else {
            format!("_x{m}")
        }
    };
    for e in &chosen {
        let base = e.activations_for(&names)?;
        for &m in &params.intensities {
            let a: Vec<f64> = base.iter().map(|x| x * m).collect();
            model.combine_surface(&a, &mut u)?;
            let name = format!("{}{}", e.name, intensity_tag(m));
            if params.write_face_meshes {
                let mesh = model.surface.displaced(&u);
                io::write_mesh(&face_dir.join(format!("{name}.obj")), &mesh)?;
            }
            let mut on_scan = transfer.apply(&prepared.denoised, &u);
            if let Some(deg) = open.map(|k| a[k]).filter(|&d| d > 0.0) {
                mouth_cavity(&mut on_scan, &model, &u, deg, &params.cavity).map_err(in_file)?;
            }
            io::write_mesh(&out_dir.join(format!("{name}.ply")), &on_scan)?;
            written += 1;
            let max = u.iter().map(|d| d.length()).fold(0.0, f64::max);
            figures.insert(name, serde_json::json!({ "max_displacement_mm": max }));
        }
    }
    if let Some(laugh) = laugh {
        let mut a = laugh
            .first()
            .ok_or_else(|| Error::algorithm("augment", "no laugh base preset"))?
            .activations_for(&names)?;
        let open = open.ok_or_else(|| Error::algorithm("augment", "the muscle set has no jaw"))?;
        let base_deg = a[open];
        for &deg in &params.jaw_open_deg {
            a[open] = base_deg + deg;
            model.combine_surface(&a, &mut u)?;
            let mut on_scan = transfer.apply(&prepared.denoised, &u);
            mouth_cavity(&mut on_scan, &model, &u, a[open], &params.cavity).map_err(in_file)?;
            io::write_mesh(&out_dir.join(format!("laugh_jaw{deg}.ply")), &on_scan)?;
            written += 1;
        }
    }
    let result = AugmentedScan {
        scan: scan.to_path_buf(),
        dir: out_dir.to_path_buf(),
        resumed: false,
        redone: false,
        expressions: written,
        landmark_warnings: prepared.detection.as_ref().map_or(0, |d| d.warnings.len()),
        landmarks_source: prepared.landmark_source(),
        corrected_points: prepared
            .given
            .as_ref()
            .map(|(_, f)| f.corrected.iter().map(|p| p.name().to_string()).collect())
            .unwrap_or_default(),
        orientation: prepared
            .detection
            .as_ref()
            .and_then(|d| d.orientation_json()),
        matched_fraction: prepared.registration.matched_fraction(),
        millis: start.elapsed().as_secs_f64() * 1e3,
    };
    let mut done = serde_json::to_value(&result).unwrap_or_default();
    done["layer_thickness_factor"] = serde_json::json!(repairs.layer_thickness_factor);
    done["unfolded_vertices"] = serde_json::json!(repairs.unfolded_vertices);
    done["surface_repairs"] = serde_json::json!(repairs.local_surface_repairs);
    done["expressions_mm"] = serde_json::Value::Object(figures);
    // What made the samples (presets, laughs' angles …), so a resumed run with other settings
    // can be told apart.
    done["recipe"] = recipe;
    done["landmarks"] = serde_json::to_value(prepared.landmarks).unwrap_or_default();
    // The correction file the points came from (path and content), so a changed one redoes
    // the subject.
    done["landmarks_file"] = serde_json::json!(correction);
    done["landmark_file"] = correction_json;
    io::write_text_atomic(
        &out_dir.join(DONE_MARKER),
        &(serde_json::to_string_pretty(&done).unwrap_or_default() + "\n"),
    )?;
    Ok(result)
}

/// Augments every gallery scan of `gallery` into `out/<stem>/`, in parallel. Resumable: a
/// subject whose folder has [`DONE_MARKER`] is skipped. A failed scan goes to the failure
/// list; the batch goes on. `progress` is called once before the first scan (0, total, line)
/// and after each scan (done count, total, line).
pub fn augment(
    gallery: &Path,
    out: &Path,
    params: &AugmentParams,
    progress: &(dyn Fn(usize, usize, &str) + Sync),
) -> Result<(Vec<AugmentedScan>, Vec<AugmentFailure>)> {
    use rayon::prelude::*;
    let all = gallery_scans(gallery, &params.gallery_suffix)?;
    if all.is_empty() {
        return Err(Error::InvalidData {
            path: gallery.to_path_buf(),
            message: format!(
                "no gallery scans (mesh files whose name ends with `{}`)",
                params.gallery_suffix
            ),
        });
    }
    // This shard's share of the sorted gallery (all of it without a shard).
    let scans: Vec<_> = match params.shard {
        Some(sh) => all
            .into_iter()
            .enumerate()
            .filter(|(i, _)| i % sh.count == sh.index)
            .map(|(_, p)| p)
            .collect(),
        None => all,
    };
    // Checked once up front: a bad preset name or angle fails the batch, not every scan.
    let recipe = augment_recipe(params)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let generic = crate::generic_face::build();
    let total = scans.len();
    progress(0, total, &format!("{total} gallery scans"));
    let counter = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<std::result::Result<AugmentedScan, AugmentFailure>> = scans
        .par_iter()
        .map(|scan| {
            let stem = scan
                .file_stem()
                .map_or_else(|| "scan".into(), |s| s.to_string_lossy().into_owned());
            let dir = out.join(&stem);
            let failure = |e: Error| AugmentFailure {
                scan: scan.clone(),
                stage: e.stage(),
                reason: e.to_string(),
                suspect: e.is_suspect(),
            };
            let r = correction_of(scan, params).map_err(failure).and_then(|correction| {
                let json = &correction.1;
                let (finished, done) = finished_with(&dir, &recipe, json);
                if finished == Finished::Same {
                    // A resumed scan is not detected again: the orientation its run recorded
                    // (none where its points came from a file).
                    let orientation = (done.as_ref())
                        .and_then(|d| d.get("orientation"))
                        .filter(|o| !o.is_null())
                        .cloned();
                    return Ok(AugmentedScan {
                        scan: scan.clone(),
                        dir,
                        resumed: true,
                        redone: false,
                        expressions: 0,
                        landmark_warnings: 0,
                        landmarks_source: serde_json::from_value(json["source"].clone())
                            .unwrap_or(LandmarkSource::Detected),
                        corrected_points: serde_json::from_value(json["corrected"].clone())
                            .unwrap_or_default(),
                        orientation,
                        matched_fraction: f64::NAN,
                        millis: 0.0,
                    });
                }
                let redone = matches!(finished, Finished::OtherSettings | Finished::OtherLandmarks);
                clear_samples(&dir)
                    .and_then(|()| augment_scan(scan, correction, &dir, &generic, params))
                    .map(|a| AugmentedScan { redone, ..a })
                    .map_err(failure)
            });
            let k = counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            let line = match &r {
                Ok(a) if a.resumed => format!("{stem}: already done"),
                Ok(a) if a.redone => format!(
                    "{stem}: redone (the earlier run used other settings or feature points): {} expressions in {:.0} ms",
                    a.expressions, a.millis
                ),
                Ok(a) => format!(
                    "{stem}: {} expressions in {:.0} ms",
                    a.expressions, a.millis
                ),
                Err(f) => format!("{stem}: FAILED: {}", f.reason),
            };
            progress(k, total, &line);
            r
        })
        .collect();
    let mut done = Vec::new();
    let mut failed = Vec::new();
    for r in results {
        match r {
            Ok(a) => done.push(a),
            Err(f) => failed.push(f),
        }
    }
    let failures = serde_json::to_string_pretty(&failed).unwrap_or_default() + "\n";
    let name = params
        .shard
        .map_or_else(|| FAILURES_FILE.to_string(), Shard::failures_file);
    io::write_text_atomic(&out.join(name), &failures)?;
    Ok((done, failed))
}

/// The failure list of an unsharded run; a shard writes [`Shard::failures_file`].
pub const FAILURES_FILE: &str = "failures.json";

/// The failures recorded in an augmented folder: `failures.json` and every shard's
/// `failures.K-of-N.json`, merged (sorted by scan). A scan listed by a shard file and done by
/// a later run (it has [`DONE_MARKER`]) is no longer a failure and is left out.
pub fn read_augment_failures(out: &Path) -> Result<Vec<serde_json::Value>> {
    let entries = std::fs::read_dir(out).map_err(|e| Error::io(out, e))?;
    let mut files: Vec<_> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name().is_some_and(|n| {
                let n = n.to_string_lossy();
                n == FAILURES_FILE
                    || (n.starts_with("failures.") && n.contains("-of-") && n.ends_with(".json"))
            })
        })
        .collect();
    files.sort();
    let mut all = Vec::new();
    for f in files {
        let text = io::read_text_file(&f)?;
        let list: Vec<serde_json::Value> =
            serde_json::from_str(&text).map_err(|e| Error::invalid(&f, e.to_string()))?;
        all.extend(list);
    }
    all.retain(|f| {
        let stem = f["scan"]
            .as_str()
            .and_then(|s| Path::new(s).file_stem())
            .map(|s| s.to_string_lossy().into_owned());
        !stem.is_some_and(|s| out.join(s).join(DONE_MARKER).is_file())
    });
    all.sort_by(|a, b| a["scan"].as_str().cmp(&b["scan"].as_str()));
    all.dedup_by(|a, b| a["scan"] == b["scan"]);
    Ok(all)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A recorded recipe is read back as the same recipe, also for activations whose shortest
    /// decimal form a best-effort float parser reads one ulp off (fitted presets have such
    /// values; without exact parsing every resume would redo every subject).
    #[test]
    fn a_recorded_recipe_reads_back_as_the_same_recipe() {
        let mut params = AugmentParams::default();
        for (i, e) in params.presets.expressions.iter_mut().enumerate() {
            e.activations.insert(
                "zygomatic_major".into(),
                2.6739865357037638 + i as f64 * 0.1,
            );
        }
        let recipe = augment_recipe(&params).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let done = serde_json::json!({ "recipe": recipe });
        std::fs::write(
            dir.path().join(DONE_MARKER),
            serde_json::to_string_pretty(&done).unwrap(),
        )
        .unwrap();
        let none = serde_json::Value::Null;
        assert_eq!(finished_with(dir.path(), &recipe, &none).0, Finished::Same);
        // A correction file added since: other feature points.
        let correction = serde_json::json!({"source": "corrected"});
        assert_eq!(
            finished_with(dir.path(), &recipe, &correction).0,
            Finished::OtherLandmarks
        );
        // Another activation, or no recipe at all: other settings.
        params.presets.expressions[0]
            .activations
            .insert("zygomatic_major".into(), 2.673986535703764);
        let other = augment_recipe(&params).unwrap();
        assert_eq!(
            finished_with(dir.path(), &other, &none).0,
            Finished::OtherSettings
        );
        std::fs::write(dir.path().join(DONE_MARKER), "{}").unwrap();
        assert_eq!(
            finished_with(dir.path(), &recipe, &none).0,
            Finished::OtherSettings
        );
        std::fs::remove_file(dir.path().join(DONE_MARKER)).unwrap();
        assert_eq!(finished_with(dir.path(), &recipe, &none).0, Finished::No);
    }
}
