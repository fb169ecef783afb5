//! Scores the denoisers against ground truth: noisy synthetic scans and their `--clean` twins
//! from `../shared/bench/synth_gavab.py` (same seed, so every noisy vertex is a clean vertex
//! on the same scanner grid).
//!
//! Definitions (all in mm, pooled over every matched vertex of every scan):
//! * **error** of a vertex: the 3D distance between its denoised position and its clean twin
//!   (sideways drift counts, not only z);
//! * **RMSE** and **max**: over all vertices; `rmse_non_spike` leaves out the injected spike
//!   vertices (it shows what happens to the σ = 0.15 mm scanner noise);
//! * **surface distance** of a vertex: the distance from its denoised position to the clean
//!   twin's surface (the nearest point of its polygons). At most the error; smaller where a
//!   vertex is off along the surface, as a z spike on a steep side mostly is (the scanner's
//!   line of sight grazes it). `max_surface` and `over_2mm_surface` are the max and the
//!   2 mm count of it, over all vertices as above;
//! * **shrinkage**: minus the mean signed displacement (output − input) along the clean
//!   twin's outward vertex normal, over the non-spike vertices: > 0 means the surface moved
//!   inwards on average;
//! * **clean RMSE**: the filter run on the clean twin itself, RMSE of its changes (damage
//!   done to noise-free data: ideally 0).
//!
//! The default filter removes the vertices it cannot repair ([`super::removal`]): the errors
//! above are over the vertices it keeps, and the removed ones are counted apart — injected
//! spikes (`removed_spikes`), other vertices of the noisy scans (`removed_non_spike`, real
//! data lost) and vertices of the clean twins (`clean_removed`).

use super::{DenoiseMethod, DenoiseParams, DenoiseReport, FilterNeighbours, STILL_MM, denoise};
use crate::ground_truth::{ScanTruth, TruthGrid};
use crate::mesh::SurfaceIndex;
use crate::mesh::{Mesh, Topology};
use crate::{Error, Result, io};
use glam::DVec3;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Instant;

/// A noisy scan, its clean twin and the vertex correspondence.
#[derive(Debug, Clone)]
pub struct ScanPair {
    /// File stem, e.g. `subj000_frontal1`.
    pub name: String,
    pub noisy: Mesh,
    pub clean: Mesh,
    /// Clean vertex id of every noisy vertex.
    pub to_clean: Vec<u32>,
    /// Noisy vertices that carry an injected spike.
    pub is_spike: Vec<bool>,
    /// The clean twin's surface for point-to-surface distances, built on first use.
    clean_surface: OnceLock<SurfaceIndex>,
}

impl ScanPair {
    pub fn new(
        name: String,
        noisy: Mesh,
        clean: Mesh,
        to_clean: Vec<u32>,
        is_spike: Vec<bool>,
    ) -> Self {
        ScanPair {
            name,
            noisy,
            clean,
            to_clean,
            is_spike,
            clean_surface: OnceLock::new(),
        }
    }

    /// Distance from `p` to the clean twin's surface, mm, given that clean vertex `c` is
    /// `bound_mm` away (so the search stops there).
    fn surface_distance(&self, p: DVec3, bound_mm: f64) -> f64 {
        let index = self
            .clean_surface
            .get_or_init(|| SurfaceIndex::new(&self.clean, 4.0));
        index.distance(p, bound_mm)
    }
}

/// Error statistics of one method (see the module docs for the definitions).
#[derive(Debug, Clone, Default, Serialize)]
pub struct MethodScore {
    pub label: String,
    pub method: Option<DenoiseMethod>,
    /// Iterations `k` asked for.
    pub k: usize,
    pub rmse_mm: f64,
    pub max_mm: f64,
    /// Vertices whose error exceeds 2 mm after denoising (all scans).
    pub over_2mm: usize,
    /// Largest distance of a vertex to the clean twin's surface, mm (`None` in the k sweeps,
    /// which do not measure it).
    pub max_surface_mm: Option<f64>,
    /// Vertices more than 2 mm from the clean twin's surface (all scans).
    pub over_2mm_surface: Option<usize>,
    pub rmse_non_spike_mm: f64,
    pub shrinkage_mm: f64,
    pub clean_rmse_mm: f64,
    /// Injected spike vertices removed (all scans).
    pub removed_spikes: usize,
    /// Other vertices of the noisy scans removed (all scans).
    pub removed_non_spike: usize,
    /// Vertices removed from the clean twins (all scans).
    pub clean_removed: usize,
    pub mean_iterations_run: f64,
    pub mean_vertices_moved: f64,
    /// Mean wall time of one [`denoise`] call (topology included), ms.
    pub mean_millis: f64,
    pub scans: usize,
}

/// Sums behind a [`MethodScore`].
#[derive(Debug, Clone, Copy, Default)]
struct Acc {
    n: usize,
    sse: f64,
    max: f64,
    over_2mm: usize,
    /// Measure surface distances (the sweeps, which only pick k by RMSE, do not).
    surface: bool,
    max_surface: f64,
    over_2mm_surface: usize,
    n_smooth: usize,
    sse_smooth: f64,
    along_normal: f64,
    clean_n: usize,
    clean_sse: f64,
    removed_spikes: usize,
    removed_non_spike: usize,
    clean_removed: usize,
    iterations: usize,
    moved: usize,
    millis: f64,
    scans: usize,
}

impl Acc {
    fn with_surface() -> Self {
        Acc {
            surface: true,
            ..Acc::default()
        }
    }

    /// `out[j]` is the output position of input vertex `kept[j]`.
    fn add_noisy(&mut self, pair: &ScanPair, out: &[DVec3], kept: &[u32]) {
        let spikes_in = pair.is_spike.iter().filter(|&&s| s).count();
        let spikes_kept = kept.iter().filter(|&&i| pair.is_spike[i as usize]).count();
        self.removed_spikes += spikes_in - spikes_kept;
        self.removed_non_spike += (pair.is_spike.len() - kept.len()) - (spikes_in - spikes_kept);
        // The surface distance is at most the error, so only vertices more than 2 mm off
        // their twin, or further off than the largest surface distance so far, are measured,
        // worst first.
        let mut candidates = Vec::new();
        for (p, &i) in out.iter().zip(kept) {
            let i = i as usize;
            let c = pair.to_clean[i] as usize;
            let e = p.distance(pair.clean.positions_mm[c]);
            self.n += 1;
            self.sse += e * e;
            self.max = self.max.max(e);
            self.over_2mm += usize::from(e > 2.0);
            if self.surface && e > self.max_surface.min(2.0) {
                candidates.push((e, *p));
            }
            if !pair.is_spike[i] {
                self.n_smooth += 1;
                self.sse_smooth += e * e;
                self.along_normal += (*p - pair.noisy.positions_mm[i]).dot(pair.clean.normals[c]);
            }
        }
        candidates.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (e, p) in candidates {
            if e <= 2.0 && e <= self.max_surface {
                break;
            }
            let d = pair.surface_distance(p, e);
            self.over_2mm_surface += usize::from(d > 2.0);
            self.max_surface = self.max_surface.max(d);
        }
    }

    /// `out[j]` is the output position of clean vertex `kept[j]`.
    fn add_clean(&mut self, pair: &ScanPair, out: &[DVec3], kept: &[u32]) {
        self.clean_removed += pair.clean.vertex_count() - kept.len();
        for (p, &i) in out.iter().zip(kept) {
            self.clean_n += 1;
            self.clean_sse += p.distance_squared(pair.clean.positions_mm[i as usize]);
        }
    }

    fn add_report(&mut self, report: &DenoiseReport, millis: f64) {
        self.iterations += report.iterations_run;
        self.moved += report.vertices_moved;
        self.millis += millis;
        self.scans += 1;
    }

    fn score(&self, label: &str, method: Option<DenoiseMethod>, k: usize) -> MethodScore {
        let div = |a: f64, b: usize| if b == 0 { 0.0 } else { a / b as f64 };
        MethodScore {
            label: label.to_string(),
            method,
            k,
            rmse_mm: div(self.sse, self.n).sqrt(),
            max_mm: self.max,
            over_2mm: self.over_2mm,
            max_surface_mm: self.surface.then_some(self.max_surface),
            over_2mm_surface: self.surface.then_some(self.over_2mm_surface),
            rmse_non_spike_mm: div(self.sse_smooth, self.n_smooth).sqrt(),
            shrinkage_mm: -div(self.along_normal, self.n_smooth),
            clean_rmse_mm: div(self.clean_sse, self.clean_n).sqrt(),
            removed_spikes: self.removed_spikes,
            removed_non_spike: self.removed_non_spike,
            clean_removed: self.clean_removed,
            mean_iterations_run: div(self.iterations as f64, self.scans),
            mean_vertices_moved: div(self.moved as f64, self.scans),
            mean_millis: div(self.millis, self.scans),
            scans: self.scans,
        }
    }
}

/// Finds the mesh file of a scan: `stem.wrl`, else `stem.obj`, else `stem.ply`.
fn mesh_file(dir: &Path, stem: &str) -> Option<PathBuf> {
    ["wrl", "obj", "ply"]
        .iter()
        .map(|e| dir.join(format!("{stem}.{e}")))
        .find(|p| p.is_file())
}

/// Loads up to `max_scans` noisy/clean pairs (sorted by name) from two synth_gavab folders.
pub fn load_pairs(noisy_dir: &Path, clean_dir: &Path, max_scans: usize) -> Result<Vec<ScanPair>> {
    let mut stems: Vec<String> = std::fs::read_dir(noisy_dir)
        .map_err(|e| Error::io(noisy_dir, e))?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let stem = name.strip_suffix(".json")?;
            (stem != "manifest").then(|| stem.to_string())
        })
        .collect();
    stems.sort();
    stems.truncate(max_scans);
    stems
        .iter()
        .map(|stem| load_pair(noisy_dir, clean_dir, stem))
        .collect()
}

/// Loads one pair by file stem and matches its vertices on the scanner grid.
pub fn load_pair(noisy_dir: &Path, clean_dir: &Path, stem: &str) -> Result<ScanPair> {
    let missing = |dir: &Path| Error::invalid(&dir.join(stem), "no .wrl/.obj/.ply mesh for scan");
    let noisy_path = mesh_file(noisy_dir, stem).ok_or_else(|| missing(noisy_dir))?;
    let clean_path = mesh_file(clean_dir, stem).ok_or_else(|| missing(clean_dir))?;
    let noisy_truth = ScanTruth::load(&noisy_dir.join(format!("{stem}.json")))?;
    let clean_truth = ScanTruth::load(&clean_dir.join(format!("{stem}.json")))?;
    let noisy = io::read_mesh(&noisy_path)?;
    let clean = io::read_mesh(&clean_path)?;
    let (g, h) = (&noisy_truth.grid, &clean_truth.grid);
    if g.ncols != h.ncols
        || g.nrows != h.nrows
        || (g.spacing_mm - h.spacing_mm).abs() > 1e-9
        || (g.x_first_col_mm - h.x_first_col_mm).abs() > 1e-9
        || (g.y_first_row_mm - h.y_first_row_mm).abs() > 1e-9
    {
        return Err(Error::invalid(
            &clean_path,
            "grid differs from the noisy scan's: not a clean twin (same seed?)",
        ));
    }
    let mut cell_to_clean = vec![u32::MAX; g.ncols * g.nrows];
    for (v, p) in clean.positions_mm.iter().enumerate() {
        let cell = grid_cell(g, *p)
            .ok_or_else(|| Error::invalid(&clean_path, format!("vertex {v} is not on the grid")))?;
        cell_to_clean[cell] = v as u32;
    }
    let mut to_clean = Vec::with_capacity(noisy.vertex_count());
    for (v, p) in noisy.positions_mm.iter().enumerate() {
        let c = grid_cell(g, *p)
            .map(|cell| cell_to_clean[cell])
            .filter(|&c| c != u32::MAX)
            .ok_or_else(|| {
                Error::invalid(
                    &noisy_path,
                    format!("vertex {v} has no clean twin on the grid"),
                )
            })?;
        to_clean.push(c);
    }
    let mut is_spike = vec![false; noisy.vertex_count()];
    if let Some(noise) = &noisy_truth.noise {
        for &v in &noise.spikes.vertex_index {
            if let Some(s) = is_spike.get_mut(v) {
                *s = true;
            }
        }
    }
    Ok(ScanPair::new(
        stem.to_string(),
        noisy,
        clean,
        to_clean,
        is_spike,
    ))
}

/// Grid cell (row-major) of a printed vertex position, if it lies on the grid (the files
/// print `%.2f`, so a sample is within 0.005 mm of its lattice point).
fn grid_cell(g: &TruthGrid, p: DVec3) -> Option<usize> {
    let fi = (p.x - g.x_first_col_mm) / g.spacing_mm;
    let fj = (g.y_first_row_mm - p.y) / g.spacing_mm;
    let (i, j) = (fi.round(), fj.round());
    let tol = 0.01 / g.spacing_mm;
    if (fi - i).abs() > tol || (fj - j).abs() > tol || i < 0.0 || j < 0.0 {
        return None;
    }
    let (i, j) = (i as usize, j as usize);
    (i < g.ncols && j < g.nrows).then_some(j * g.ncols + i)
}

/// The noisy input's scores (nothing run).
pub fn input_score(pairs: &[ScanPair]) -> MethodScore {
    let mut acc = Acc::with_surface();
    for pair in pairs {
        let all: Vec<u32> = (0..pair.noisy.vertex_count() as u32).collect();
        acc.add_noisy(pair, &pair.noisy.positions_mm, &all);
        acc.scans += 1;
    }
    acc.score("noisy input", None, 0)
}

/// Runs [`denoise`] with `params` on every noisy scan and on its clean twin, timing the noisy
/// run (one thread).
pub fn score_method(
    pairs: &[ScanPair],
    label: &str,
    params: &DenoiseParams,
) -> Result<MethodScore> {
    let mut acc = Acc::with_surface();
    for pair in pairs {
        let mut mesh = pair.noisy.clone();
        let start = Instant::now();
        let report = denoise(&mut mesh, params)?;
        let millis = start.elapsed().as_secs_f64() * 1e3;
        acc.add_noisy(pair, &mesh.positions_mm, &report.kept);
        acc.add_report(&report, millis);
        let mut clean = pair.clean.clone();
        let clean_report = denoise(&mut clean, params)?;
        acc.add_clean(pair, &clean.positions_mm, &clean_report.kept);
    }
    Ok(acc.score(label, Some(params.method), params.iterations))
}

/// Scores `params` for every k in 1..=`k_max` with one run per scan (a score after each
/// iteration). Timing and moved counts are not recorded. A run that stops early (nothing
/// moves) keeps its last positions for the larger k.
pub fn sweep_iterations(
    pairs: &[ScanPair],
    label: &str,
    params: &DenoiseParams,
    k_max: usize,
) -> Result<Vec<MethodScore>> {
    params.validate()?;
    let params = DenoiseParams {
        iterations: k_max,
        ..*params
    };
    let mut accs = vec![Acc::default(); k_max];
    for pair in pairs {
        for clean_run in [false, true] {
            let mesh = if clean_run { &pair.clean } else { &pair.noisy };
            let topology = Topology::new(mesh);
            let nb = FilterNeighbours::new(mesh, &topology, params.boundary);
            let mut positions = mesh.positions_mm.clone();
            // The sweep scores the moving filter alone (the baselines remove nothing).
            let all: Vec<u32> = (0..mesh.vertex_count() as u32).collect();
            let mut last = 0;
            let mut record = |k: usize, pos: &[DVec3]| {
                for acc in &mut accs[last..k] {
                    if clean_run {
                        acc.add_clean(pair, pos, &all);
                    } else {
                        acc.add_noisy(pair, pos, &all);
                        acc.scans += 1;
                    }
                }
                last = k;
            };
            super::run(&mut positions, &nb, &topology, &params, &mut record);
            record(k_max, &positions);
        }
    }
    Ok(accs
        .iter()
        .enumerate()
        .map(|(i, acc)| acc.score(label, Some(params.method), i + 1))
        .collect())
}

/// One vertex left more than a tolerance off its clean twin after denoising (diagnostics).
#[derive(Debug, Clone, Serialize)]
pub struct VertexError {
    pub scan: String,
    pub vertex: usize,
    pub error_mm: f64,
    /// Distance to the clean twin's surface, mm (see the module docs).
    pub surface_mm: f64,
    /// Signed z error (output − clean), mm.
    pub dz_mm: f64,
    /// Whether an injected spike sits on this vertex.
    pub spike: bool,
    pub boundary: bool,
    /// Whether the filter moved the vertex at all.
    pub moved: bool,
}

/// Every vertex whose error after [`denoise`] with `params` exceeds `tolerance_mm`, worst
/// first: where the filter still fails (untouched spikes, rims, damage on sharp features).
pub fn vertices_over(
    pairs: &[ScanPair],
    params: &DenoiseParams,
    tolerance_mm: f64,
) -> Result<Vec<VertexError>> {
    let mut out = Vec::new();
    for pair in pairs {
        let mut mesh = pair.noisy.clone();
        let topology = Topology::new(&mesh);
        let report = denoise(&mut mesh, params)?;
        for (p, &i) in mesh.positions_mm.iter().zip(&report.kept) {
            let i = i as usize;
            let c = pair.clean.positions_mm[pair.to_clean[i] as usize];
            let e = p.distance(c);
            if e > tolerance_mm {
                out.push(VertexError {
                    scan: pair.name.clone(),
                    vertex: i,
                    error_mm: e,
                    surface_mm: pair.surface_distance(*p, e),
                    dz_mm: p.z - c.z,
                    spike: pair.is_spike[i],
                    boundary: topology.is_boundary[i],
                    moved: report.displacement_mm[i] > STILL_MM,
                });
            }
        }
    }
    out.sort_by(|a, b| b.error_mm.total_cmp(&a.error_mm));
    Ok(out)
}

/// The k with the lowest RMSE of a sweep.
pub fn best_k(sweep: &[MethodScore]) -> Option<&MethodScore> {
    sweep.iter().min_by(|a, b| a.rmse_mm.total_cmp(&b.rmse_mm))
}

/// A Markdown table of scores.
pub fn markdown_table(scores: &[MethodScore]) -> String {
    let mut s = String::from(
        "| method | k | RMSE mm | max mm | >2 mm | to surface: max mm / >2 mm | RMSE non-spike mm | shrinkage mm | clean RMSE mm | removed: spikes / other / of clean twins | iters run | moved | ms/scan |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for m in scores {
        s += &format!(
            "| {} | {} | {:.3} | {:.2} | {} | {} | {:.3} | {:+.4} | {:.4} | {} / {} / {} | {:.1} | {:.0} | {:.2} |\n",
            m.label,
            m.k,
            m.rmse_mm,
            m.max_mm,
            m.over_2mm,
            match (m.max_surface_mm, m.over_2mm_surface) {
                (Some(max), Some(n)) => format!("{max:.2} / {n}"),
                _ => "–".into(),
            },
            m.rmse_non_spike_mm,
            m.shrinkage_mm,
            m.clean_rmse_mm,
            m.removed_spikes,
            m.removed_non_spike,
            m.clean_removed,
            m.mean_iterations_run,
            m.mean_vertices_moved,
            m.mean_millis
        );
    }
    s
}

/// The whole benchmark: the noisy input, the literal paper method, the per-region rule with
/// the paper's estimator, the default, and the two baselines at their best k of 1..=`k_max`, plus the sweeps.
#[derive(Debug, Clone, Serialize)]
pub struct Benchmark {
    pub scans: usize,
    pub table: Vec<MethodScore>,
    pub laplacian_sweep: Vec<MethodScore>,
    pub taubin_sweep: Vec<MethodScore>,
}

/// Runs [`Benchmark`] on loaded pairs.
pub fn benchmark(pairs: &[ScanPair], k_max: usize) -> Result<Benchmark> {
    let mut table = vec![input_score(pairs)];
    table.push(score_method(
        pairs,
        "median-laplacian, paper (global)",
        &DenoiseParams::paper(),
    )?);
    table.push(score_method(
        pairs,
        "median-laplacian estimator, per-region, 1 mm floor (previous default)",
        &DenoiseParams {
            estimator: super::Estimator::MedianLaplacian,
            min_displacement_mm: 1.0,
            ..DenoiseParams::default()
        },
    )?);
    table.push(score_method(
        pairs,
        "robust-quadric estimator, per-region (default)",
        &DenoiseParams::default(),
    )?);
    let mut sweeps = Vec::new();
    for method in [DenoiseMethod::Laplacian, DenoiseMethod::Taubin] {
        let params = DenoiseParams::baseline(method, k_max);
        let sweep = sweep_iterations(pairs, method.name(), &params, k_max)?;
        let k = best_k(&sweep).map_or(1, |b| b.k);
        let label = format!("{} (best k)", method.name());
        table.push(score_method(
            pairs,
            &label,
            &DenoiseParams::baseline(method, k),
        )?);
        sweeps.push(sweep);
    }
    let taubin_sweep = sweeps.pop().unwrap_or_default();
    let laplacian_sweep = sweeps.pop().unwrap_or_default();
    Ok(Benchmark {
        scans: pairs.len(),
        table,
        laplacian_sweep,
        taubin_sweep,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vertex slid along a plane is off its twin but on the surface; one lifted off it is
    /// as far from the surface as from its twin.
    #[test]
    fn surface_distance_tells_sliding_along_the_surface_from_leaving_it() {
        let clean = crate::test_support::grid(11, 11, |_, _| 0.0);
        let mut noisy = clean.clone();
        let (slid, lifted) = (3 * 11 + 3, 7 * 11 + 7);
        noisy.positions_mm[slid].x += 3.0;
        noisy.positions_mm[lifted].z += 2.5;
        let n = noisy.vertex_count();
        let pair = ScanPair::new(
            "plane".into(),
            noisy,
            clean,
            (0..n as u32).collect(),
            vec![false; n],
        );
        let s = input_score(std::slice::from_ref(&pair));
        assert_eq!(s.over_2mm, 2);
        assert!((s.max_mm - 3.0).abs() < 1e-12, "{s:?}");
        assert_eq!(s.over_2mm_surface, Some(1));
        assert!((s.max_surface_mm.unwrap() - 2.5).abs() < 1e-9, "{s:?}");
        // The sweeps leave it unmeasured rather than 0.
        let sweep = sweep_iterations(
            std::slice::from_ref(&pair),
            "laplacian",
            &DenoiseParams::baseline(DenoiseMethod::Laplacian, 2),
            2,
        )
        .unwrap();
        assert!(sweep.iter().all(|m| m.max_surface_mm.is_none()));
    }
}
