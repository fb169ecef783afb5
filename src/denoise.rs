//! Mesh denoising (paper section 2.1.1): an iterated median + Laplacian filter that moves only
//! the vertices with the largest change, plus the plain Laplacian and Taubin λ|μ baselines of
//! the paper's Table 1.
//!
//! # The filter, one iteration ([`DenoiseMethod::MedianLaplacian`])
//!
//! 1. **Median filter.** Every vertex gets the *component-wise* median of its own position and
//!    its filter neighbours' positions (x, y and z medians taken separately; an even count
//!    takes the mean of the two middle values).
//! 2. **Laplacian filter** of the median-filtered mesh: every vertex gets the average of its
//!    filter neighbours' median-filtered positions (the uniform "umbrella", centre excluded).
//! 3. The **displacement** `d_i` is the distance from the position before the iteration to
//!    that candidate.
//! 4. **Threshold** `t = w · max d` (see [`MoveRule`] for over which vertices the maximum runs).
//! 5. Only vertices with `d_i ≥ t` (and `d_i ≥` [`DenoiseParams::min_displacement_mm`]) take
//!    their candidate position; all others keep theirs exactly.
//! 6. Repeat until no vertex moves or [`DenoiseParams::iterations`] iterations have run.
//!
//! **Why the component-wise median.** Scanner noise and spikes are along the viewing axis (z),
//! and a scan is a height field sampled on a regular x–y grid. The component-wise median of a
//! grid vertex and its 1-ring leaves x and y where they are (the neighbours are symmetric about
//! the vertex) and replaces z by the median height, which is exactly the robust estimate a
//! spike needs. The vector median (the neighbour minimising the sum of distances) instead
//! snaps a vertex *onto* one of its neighbours, which moves it a whole grid step sideways and
//! makes degenerate faces. The component-wise median also costs three selections of ≤ ~10
//! numbers. It is not rotation invariant, which does not matter for scans in their own frame.
//!
//! **Boundaries** ([`BoundaryRule`]). Scans have a border, hair lines and holes, and spikes sit
//! on rim vertices as often as anywhere else, so rim vertices cannot simply be held. By default
//! a boundary vertex is filtered only along the boundary: its filter neighbours are the (two)
//! vertices it shares a boundary edge with, and the median-Laplacian filter gives it the
//! component-wise **median of those three points only, without the Laplacian step**. The rim
//! of a grid scan is a staircase; a 3-point median is a fixed point on a staircase (each
//! coordinate is monotone through a corner), whereas a 3-point average cuts every corner by
//! 0.7 grid steps and so would shrink every hole and border, and a 1-ring average would pull
//! the vertex across the rim into the surface. A rim spike is still replaced by a neighbour's
//! height. A boundary vertex with fewer than two boundary-edge neighbours (a corner of a
//! non-manifold fan) is held. Interior vertices use their whole 1-ring, rim vertices included.
//! The baselines use the same neighbours with their usual average (curve smoothing on rims).
//!
//! # What differs from the literal paper method, and why
//!
//! See [`MoveRule`]: the paper takes one global maximum, so each iteration moves only the
//! vertices within `w` of the single largest displacement in the whole scan. On a synthetic
//! scan with ~50 spike events of 5–40 mm, 15 iterations leave most spikes in place (numbers in
//! the crate's benchmark, [`eval`]). The default [`MoveRule::PerRegion`] applies the paper's
//! `w · max` rule independently to each connected region of vertices whose displacement is
//! at least [`DenoiseParams::min_displacement_mm`], so every spike is worked on in parallel
//! and the iteration stops by itself once the largest remaining candidate move is below the
//! floor. The literal rule is [`MoveRule::Global`] ([`DenoiseParams::paper`]).

pub mod eval;

use crate::mesh::{Mesh, Topology};
use crate::{Error, Result};
use glam::DVec3;
use serde::Serialize;

/// Which filter [`denoise`] runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum DenoiseMethod {
    /// The paper's filter: median, then Laplacian, move only the largest changes.
    #[default]
    MedianLaplacian,
    /// Baseline: uniform Laplacian smoothing `p ← p + λ(avg(N) − p)` on every vertex.
    Laplacian,
    /// Baseline: Taubin λ|μ smoothing; one iteration is a λ step then a μ step.
    Taubin,
}

impl DenoiseMethod {
    /// The name used on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            DenoiseMethod::MedianLaplacian => "median-laplacian",
            DenoiseMethod::Laplacian => "laplacian",
            DenoiseMethod::Taubin => "taubin",
        }
    }
}

/// Over which vertices the threshold `w · max d` of [`DenoiseMethod::MedianLaplacian`] takes
/// its maximum.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum MoveRule {
    /// The paper, literally: one maximum over the whole mesh.
    Global,
    /// The maximum of each connected region (1-ring connectivity) of vertices whose
    /// displacement is at least [`DenoiseParams::min_displacement_mm`]: every spike is its own
    /// region, so all spikes are reduced in parallel instead of the largest one first.
    #[default]
    PerRegion,
}

/// How boundary vertices (scan border, hole and hair rims) are filtered. Applies to all
/// methods.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum BoundaryRule {
    /// Filter a boundary vertex along the boundary only: its neighbours are the vertices it
    /// shares a boundary edge with (held if it has fewer than two).
    #[default]
    AlongBoundary,
    /// Never move boundary vertices (they still act as neighbours of interior vertices).
    Hold,
}

/// Parameters of [`denoise`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DenoiseParams {
    /// Filter to run. Default [`DenoiseMethod::MedianLaplacian`].
    pub method: DenoiseMethod,
    /// Maximum number of iterations `k` (count, ≥ 0; 0 returns the mesh unchanged). For Taubin
    /// one iteration is a λ step plus a μ step. Default 15 (paper).
    pub iterations: usize,
    /// Change fraction `w` of the median-Laplacian filter (0 < w ≤ 1): a vertex moves only if
    /// its displacement is at least `w` times the largest one (per [`MoveRule`]). Default 0.8
    /// (paper). Ignored by the baselines.
    pub w: f64,
    /// Over which vertices the maximum of the threshold is taken. Default
    /// [`MoveRule::PerRegion`]; [`MoveRule::Global`] is the literal paper.
    pub rule: MoveRule,
    /// Smallest displacement that moves a vertex in the median-Laplacian filter, mm (≥ 0).
    /// It stops the iteration once only scanner-noise-sized changes are left, and keeps the
    /// filter off smooth skin. Default 1.0 mm: well above the ~0.15 mm scanner noise and the
    /// ≤ ~0.5 mm curvature terms of a 1.5 mm-grid face, well below the ≥ 5 mm spikes.
    /// [`DenoiseParams::paper`] uses 0.
    pub min_displacement_mm: f64,
    /// Laplacian / Taubin smoothing factor λ (0 < λ ≤ 1). Default 0.5.
    pub lambda: f64,
    /// Taubin inflation factor μ (μ < −λ). Default −0.53 (pass-band k_PB = 1/λ + 1/μ ≈ 0.11,
    /// Taubin 1995's recommended range 0.01–0.1 nearly).
    pub mu: f64,
    /// Boundary handling. Default [`BoundaryRule::AlongBoundary`].
    pub boundary: BoundaryRule,
}

impl Default for DenoiseParams {
    fn default() -> Self {
        DenoiseParams {
            method: DenoiseMethod::MedianLaplacian,
            iterations: 15,
            w: 0.8,
            rule: MoveRule::PerRegion,
            min_displacement_mm: 1.0,
            lambda: 0.5,
            mu: -0.53,
            boundary: BoundaryRule::AlongBoundary,
        }
    }
}

impl DenoiseParams {
    /// The literal paper method: global threshold, no displacement floor, w = 0.8, k = 15.
    pub fn paper() -> Self {
        DenoiseParams {
            rule: MoveRule::Global,
            min_displacement_mm: 0.0,
            ..Self::default()
        }
    }

    /// A baseline with its default factors and `iterations` iterations.
    pub fn baseline(method: DenoiseMethod, iterations: usize) -> Self {
        DenoiseParams {
            method,
            iterations,
            ..Self::default()
        }
    }

    /// Checks the ranges documented on the fields.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::algorithm("denoise", m));
        if !(self.w > 0.0 && self.w <= 1.0) {
            return bad(format!("w must be in (0, 1], got {}", self.w));
        }
        if !(self.min_displacement_mm >= 0.0 && self.min_displacement_mm.is_finite()) {
            return bad(format!(
                "min_displacement_mm must be ≥ 0, got {}",
                self.min_displacement_mm
            ));
        }
        if !(self.lambda > 0.0 && self.lambda <= 1.0) {
            return bad(format!("lambda must be in (0, 1], got {}", self.lambda));
        }
        if self.method == DenoiseMethod::Taubin && !(self.mu < -self.lambda) {
            return bad(format!(
                "mu must be < -lambda ({}), got {}",
                -self.lambda, self.mu
            ));
        }
        Ok(())
    }
}

/// What [`denoise`] did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DenoiseReport {
    pub method: DenoiseMethod,
    /// Iterations that moved at least one vertex (the baselines: all `k`).
    pub iterations_run: usize,
    /// Distinct vertices moved at least once.
    pub vertices_moved: usize,
    /// Largest distance between a vertex's final and input position, mm.
    pub max_displacement_mm: f64,
    /// Mean distance between final and input positions over all vertices, mm.
    pub mean_displacement_mm: f64,
    /// Per-vertex distance between final and input position, mm (for heat maps).
    #[serde(skip)]
    pub displacement_mm: Vec<f64>,
}

/// Denoises `mesh` in place (positions and normals) and reports what moved.
pub fn denoise(mesh: &mut Mesh, params: &DenoiseParams) -> Result<DenoiseReport> {
    mesh.validate().map_err(Error::InvalidMesh)?;
    let topology = Topology::new(mesh);
    let report = denoise_with_topology(mesh, &topology, params)?;
    mesh.update_normals();
    Ok(report)
}

/// [`denoise`] for callers that already have the mesh's [`Topology`]. Updates positions only
/// (call [`Mesh::update_normals`] afterwards).
pub fn denoise_with_topology(
    mesh: &mut Mesh,
    topology: &Topology,
    params: &DenoiseParams,
) -> Result<DenoiseReport> {
    params.validate()?;
    if topology.vertex_count() != mesh.vertex_count() {
        return Err(Error::InvalidMesh(format!(
            "topology has {} vertices, mesh has {}",
            topology.vertex_count(),
            mesh.vertex_count()
        )));
    }
    let nb = FilterNeighbours::new(mesh, topology, params.boundary);
    Ok(run(
        &mut mesh.positions_mm,
        &nb,
        topology,
        params,
        |_, _| {},
    ))
}

/// The neighbours each vertex is filtered with (CSR): the 1-ring for interior vertices, the
/// boundary-edge neighbours (or none: held) for boundary vertices.
#[derive(Debug, Clone)]
pub struct FilterNeighbours {
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
    /// `true` for a boundary vertex filtered along the rim (its neighbours are rim vertices).
    along_rim: Vec<bool>,
}

impl FilterNeighbours {
    pub fn new(mesh: &Mesh, topology: &Topology, boundary: BoundaryRule) -> Self {
        let n = topology.vertex_count();
        let mut offsets = Vec::with_capacity(n + 1);
        let mut neighbours = Vec::with_capacity(n * 5);
        let mut along_rim = vec![false; n];
        offsets.push(0);
        for v in 0..n {
            let ring = topology.neighbours(v);
            if !topology.is_boundary[v] {
                neighbours.extend_from_slice(ring);
            } else if boundary == BoundaryRule::AlongBoundary {
                let start = neighbours.len();
                for &u in ring {
                    if topology.is_boundary[u as usize]
                        && edge_face_count(mesh, topology, v, u as usize) == 1
                    {
                        neighbours.push(u);
                    }
                }
                if neighbours.len() - start < 2 {
                    neighbours.truncate(start);
                } else {
                    along_rim[v] = true;
                }
            }
            offsets.push(neighbours.len() as u32);
        }
        FilterNeighbours {
            offsets,
            neighbours,
            along_rim,
        }
    }

    /// The filter neighbours of `v` (empty: `v` is held).
    pub fn of(&self, v: usize) -> &[u32] {
        &self.neighbours[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// Whether `v` is a boundary vertex filtered along the rim.
    pub fn is_along_rim(&self, v: usize) -> bool {
        self.along_rim[v]
    }

    pub fn vertex_count(&self) -> usize {
        self.offsets.len() - 1
    }
}

/// Number of faces that have `a`–`b` as an edge.
fn edge_face_count(mesh: &Mesh, topology: &Topology, a: usize, b: usize) -> usize {
    topology
        .vertex_faces(a)
        .iter()
        .filter(|&&f| {
            let poly = mesh.faces.get(f as usize);
            (0..poly.len()).any(|k| {
                let (p, q) = (poly[k] as usize, poly[(k + 1) % poly.len()] as usize);
                (p == a && q == b) || (p == b && q == a)
            })
        })
        .count()
}

/// Displacements at or below this count as "did not move", mm.
const STILL_MM: f64 = 1e-9;

/// Runs the filter on `positions`; `observe(iteration, positions)` is called after every
/// iteration (1-based), so a sweep over k costs one run (used by [`eval`]).
pub fn run(
    positions: &mut [DVec3],
    nb: &FilterNeighbours,
    topology: &Topology,
    params: &DenoiseParams,
    mut observe: impl FnMut(usize, &[DVec3]),
) -> DenoiseReport {
    let n = positions.len();
    assert_eq!(
        nb.vertex_count(),
        n,
        "filter neighbours do not fit the mesh"
    );
    let input = positions.to_vec();
    let mut moved = vec![false; n];
    let mut iterations_run = 0;
    match params.method {
        DenoiseMethod::MedianLaplacian => {
            let mut work = MedianLaplacianWork::new(n);
            for it in 1..=params.iterations {
                if work.iterate(positions, nb, topology, params, &mut moved) == 0 {
                    break;
                }
                iterations_run += 1;
                observe(it, positions);
            }
        }
        DenoiseMethod::Laplacian | DenoiseMethod::Taubin => {
            let mut scratch = vec![DVec3::ZERO; n];
            for it in 1..=params.iterations {
                laplacian_step(positions, &mut scratch, nb, params.lambda);
                if params.method == DenoiseMethod::Taubin {
                    laplacian_step(positions, &mut scratch, nb, params.mu);
                }
                iterations_run += 1;
                observe(it, positions);
            }
            for (m, (p, q)) in moved.iter_mut().zip(positions.iter().zip(&input)) {
                *m = p.distance(*q) > STILL_MM;
            }
        }
    }
    let displacement_mm: Vec<f64> = positions
        .iter()
        .zip(&input)
        .map(|(p, q)| p.distance(*q))
        .collect();
    let max = displacement_mm.iter().copied().fold(0.0, f64::max);
    let mean = if n == 0 {
        0.0
    } else {
        displacement_mm.iter().sum::<f64>() / n as f64
    };
    DenoiseReport {
        method: params.method,
        iterations_run,
        vertices_moved: moved.iter().filter(|&&m| m).count(),
        max_displacement_mm: max,
        mean_displacement_mm: mean,
        displacement_mm,
    }
}

/// One uniform Laplacian step `p ← p + factor · (avg(N) − p)` (Jacobi: all from the old
/// positions). Held vertices (no filter neighbours) stay.
fn laplacian_step(
    positions: &mut [DVec3],
    scratch: &mut [DVec3],
    nb: &FilterNeighbours,
    factor: f64,
) {
    scratch.copy_from_slice(positions);
    for (v, p) in positions.iter_mut().enumerate() {
        let ring = nb.of(v);
        if ring.is_empty() {
            continue;
        }
        let sum: DVec3 = ring.iter().map(|&u| scratch[u as usize]).sum();
        let avg = sum / ring.len() as f64;
        *p += factor * (avg - scratch[v]);
    }
}

/// Buffers of the median-Laplacian filter, allocated once per run.
struct MedianLaplacianWork {
    median: Vec<DVec3>,
    candidate: Vec<DVec3>,
    disp: Vec<f64>,
    label: Vec<u32>,
    region_max: Vec<f64>,
    stack: Vec<u32>,
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
}

impl MedianLaplacianWork {
    fn new(n: usize) -> Self {
        MedianLaplacianWork {
            median: vec![DVec3::ZERO; n],
            candidate: vec![DVec3::ZERO; n],
            disp: vec![0.0; n],
            label: vec![u32::MAX; n],
            region_max: Vec::new(),
            stack: Vec::new(),
            xs: Vec::with_capacity(16),
            ys: Vec::with_capacity(16),
            zs: Vec::with_capacity(16),
        }
    }

    /// One iteration; returns how many vertices moved.
    fn iterate(
        &mut self,
        positions: &mut [DVec3],
        nb: &FilterNeighbours,
        topology: &Topology,
        params: &DenoiseParams,
        moved: &mut [bool],
    ) -> usize {
        // 1. Component-wise median of the vertex and its filter neighbours.
        for (v, m) in self.median.iter_mut().enumerate() {
            let ring = nb.of(v);
            if ring.is_empty() {
                *m = positions[v];
                continue;
            }
            self.xs.clear();
            self.ys.clear();
            self.zs.clear();
            for p in std::iter::once(v).chain(ring.iter().map(|&u| u as usize)) {
                let p = positions[p];
                self.xs.push(p.x);
                self.ys.push(p.y);
                self.zs.push(p.z);
            }
            *m = DVec3::new(
                median(&mut self.xs),
                median(&mut self.ys),
                median(&mut self.zs),
            );
        }
        // 2. Laplacian (umbrella average) of the median-filtered mesh; 3. displacement.
        for v in 0..positions.len() {
            let ring = nb.of(v);
            let c = if ring.is_empty() {
                positions[v]
            } else if nb.is_along_rim(v) {
                self.median[v]
            } else {
                ring.iter().map(|&u| self.median[u as usize]).sum::<DVec3>() / ring.len() as f64
            };
            self.candidate[v] = c;
            self.disp[v] = c.distance(positions[v]);
        }
        // 4. Threshold; 5. move.
        let floor = params.min_displacement_mm.max(STILL_MM);
        let mut count = 0;
        match params.rule {
            MoveRule::Global => {
                let max = self.disp.iter().copied().fold(0.0, f64::max);
                let t = (params.w * max).max(floor);
                for v in 0..positions.len() {
                    if self.disp[v] >= t {
                        positions[v] = self.candidate[v];
                        moved[v] = true;
                        count += 1;
                    }
                }
            }
            MoveRule::PerRegion => {
                self.label_regions(topology, floor);
                for v in 0..positions.len() {
                    let l = self.label[v];
                    if l != u32::MAX && self.disp[v] >= params.w * self.region_max[l as usize] {
                        positions[v] = self.candidate[v];
                        moved[v] = true;
                        count += 1;
                    }
                }
            }
        }
        count
    }

    /// Labels the connected regions of vertices with `disp ≥ floor` and records each region's
    /// largest displacement.
    fn label_regions(&mut self, topology: &Topology, floor: f64) {
        self.label.fill(u32::MAX);
        self.region_max.clear();
        for seed in 0..self.disp.len() {
            if self.disp[seed] < floor || self.label[seed] != u32::MAX {
                continue;
            }
            let id = self.region_max.len() as u32;
            let mut max = 0.0f64;
            self.label[seed] = id;
            self.stack.clear();
            self.stack.push(seed as u32);
            while let Some(v) = self.stack.pop() {
                let v = v as usize;
                max = max.max(self.disp[v]);
                for &u in topology.neighbours(v) {
                    let u = u as usize;
                    if self.label[u] == u32::MAX && self.disp[u] >= floor {
                        self.label[u] = id;
                        self.stack.push(u as u32);
                    }
                }
            }
            self.region_max.push(max);
        }
    }
}

/// Median of a small non-empty list (mean of the two middle values for an even count).
fn median(values: &mut [f64]) -> f64 {
    let n = values.len();
    let mid = n / 2;
    let (lo, m, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    let m = *m;
    if n % 2 == 1 {
        m
    } else {
        let below = lo.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (below + m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `nx × ny` vertex grid of quads, spacing 1 mm, z = f(x, y).
    pub(crate) fn grid(nx: u32, ny: u32, f: impl Fn(f64, f64) -> f64) -> Mesh {
        let mut p = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let (x, y) = (i as f64, j as f64);
                p.push(DVec3::new(x, y, f(x, y)));
            }
        }
        let mut faces = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let v = j * nx + i;
                faces.push([v, v + 1, v + 1 + nx, v + nx]);
            }
        }
        Mesh::from_faces(p, faces)
    }

    #[test]
    fn median_odd_and_even() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&mut [7.0]), 7.0);
    }

    #[test]
    fn boundary_vertices_filter_along_the_rim() {
        let m = grid(4, 3, |_, _| 0.0);
        let t = Topology::new(&m);
        let nb = FilterNeighbours::new(&m, &t, BoundaryRule::AlongBoundary);
        // Vertex 1 (bottom edge): rim neighbours 0 and 2, not the interior vertex 5.
        assert_eq!(nb.of(1), &[0, 2]);
        // Interior vertex 5: its whole 1-ring.
        assert_eq!(nb.of(5), &[1, 4, 6, 9]);
        // Corner 0: its two rim neighbours.
        assert_eq!(nb.of(0), &[1, 4]);
        let held = FilterNeighbours::new(&m, &t, BoundaryRule::Hold);
        assert!(held.of(1).is_empty());
        assert_eq!(held.of(5), &[1, 4, 6, 9]);
    }
}
