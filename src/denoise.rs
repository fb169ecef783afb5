//! Mesh denoising (paper section 2.1.1): an iterated median + Laplacian filter that moves only
//! the vertices with the largest change, plus the plain Laplacian and Taubin λ|μ baselines of
//! the paper's Table 1.
//!
//! # The filter, one iteration ([`DenoiseMethod::MedianLaplacian`])
//!
//! Steps 1–2 below are the paper's estimate ([`Estimator::MedianLaplacian`]); the default
//! replaces them by a robust local fit ([`Estimator::RobustQuadric`], see the next section).
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
//! Measured on 100 synthetic scans (20 subjects × 5, `synth_gavab.py --seed 2024`, ~0.31 % of
//! the vertices spiked by 5–40 mm, σ = 0.15 mm noise; `facesynth eval-denoise NOISY CLEAN`):
//! the literal method (global threshold, no floor) leaves RMSE 0.40 mm, max 40.7 mm and 13,675
//! vertices more than 2 mm off (the input: 1.20 mm, 40.1 mm, 4,988); it damages the noise-free
//! twins by 0.36 mm RMSE. Three things go wrong, and the default changes each:
//!
//! 1. **One global maximum** ([`MoveRule`]): each iteration only moves the changes within `w`
//!    of the single largest one, so 5–40 mm spikes need ~10 iterations between them, and the
//!    largest changes on a clean face (steep sides, rims) keep the threshold high. The default
//!    [`MoveRule::PerRegion`] applies `w · max` to each connected region of eligible vertices.
//! 2. **The median → Laplacian estimate** is biased wherever the surface is steep or curved at
//!    the grid scale (a 1.47 mm grid over a face whose sides turn 80° away): the umbrella
//!    average of a height field moves a vertex by ~h²/4 · ∇²z, several mm at the silhouette,
//!    and a 1-ring median is captured by spike clusters (2–6 neighbouring spiked vertices).
//!    The default [`Estimator::RobustQuadric`] predicts the vertex from a quadric fitted to
//!    its 2-ring (3-ring when the 2-ring stays rough), L1-reweighted when a residual exceeds
//!    2 mm, or a consensus fit (the quadric most ring points agree with, from random 9-point
//!    subsets) when that has more inliers, and trimmed at `max(3 σ̂, 1 mm)`. It moves along
//!    z only (the scanner's viewing axis: spikes and noise are along z, and x, y are the
//!    scanner grid), so no vertex drifts sideways.
//! 3. **Rims**: the component-wise median of a staircase rim snaps protruding rim vertices a
//!    grid step sideways and several mm in z, and a one-sided fit of a rim vertex guesses
//!    (the rim phase of earlier versions moved real lip and silhouette vertices by 8–12 mm
//!    and left rim spikes whose neighbours were spiked too). By default rim vertices are not
//!    moved at all: those that are off are removed (item 7). With
//!    [`DenoiseParams::remove_unrepairable`] off, rim vertices are filtered after the
//!    interior has settled (a phase of up to k iterations of its own), from the interior
//!    vertices of their 3-ring, with an 8 mm floor ([`DenoiseParams::rim_floor_mm`]), and
//!    only towards their neighbours' median height.
//! 4. **Eligibility**: a change must be at least 4 mm
//!    ([`DenoiseParams::min_displacement_mm`]: above the 2–3.5 mm by which a quadric
//!    mispredicts canthus folds, lip corners and steep sides, below the ≥ 5 mm of a long
//!    spike), 6 σ̂ of the ring, and 3× the ring's own roughness (90th percentile of its fit
//!    residuals below half the change), so creases and lip edges are left alone. A vertex
//!    already moved keeps being refined while its change is ≥ 1 mm
//!    ([`DenoiseParams::refine_displacement_mm`]).
//! 5. **Spike clusters**: a vertex whose change clears the floor but not the roughness test,
//!    next to other such vertices, is refitted from its 3-ring without all of them: several
//!    spiked neighbours otherwise pull the fit and make the ring look rough. When the filter
//!    stops, every vertex it moved is refitted once more from the ring points it did not
//!    move (`polish`).
//! 6. **Step edges** (`on_real_surface`): an interior vertex that, as scanned, shares a plane
//!    with at least 8 and a third of its 3-ring points (within 1 mm) is one side of a crease,
//!    a closed lid or a lip edge, and is never moved: the ring's quadric cannot follow such
//!    an edge and mispredicts it by 4–10 mm, which the eligibility tests above did not
//!    always catch (48 real vertices moved > 2 mm on the 100 scans before this test, 2 after).
//!    The spikes it keeps (2 of the 11 vertices left > 2 mm off before `removal`'s tests 3
//!    and 4, 1 of the 2 after; more on stop 29's fresh sets, see [`removal`]) lie on steep
//!    sides or beside real steps, where
//!    some plane through the spike meets 8 ring points; asking for 2–4 of those supporters
//!    within 2.2 mm (the 1-ring) as well left 12 instead of 11 (one real vertex more moved).
//! 7. **Removal** ([`removal`], [`DenoiseParams::remove_unrepairable`]): what the filter
//!    cannot repair — rim spikes, spike clusters that are their own support — and, since
//!    stop 32, every repair over [`DenoiseParams::repair_max_mm`] (3 mm) is taken out of
//!    the mesh (a quad that loses a corner stays as a triangle); downstream steps see a
//!    small hole, which registration and range images fill. [`DenoiseReport::kept`] maps
//!    output vertices to input ones.
//!
//! Since stop 32 the defaults keep no vertex further than 3 mm from where it was measured
//! (on seed 79 that removes the last vertex > 2 mm off, a real pit the filter lifted; every
//! repaired spike is removed: 1,941 → 4,987 spike vertices on seed 2024), judge rim vertices
//! by a wider fit and remove fragments of ≤ 8 vertices, also those the removals leave: over
//! 1,050 synthetic scans (seeds 2024, 1, 77–85) 7 vertices stay > 2 mm off (max 5.4 mm),
//! 45 at stop 31; on seed 85, made after these rules, 2 → 0 (max 0.71 mm). Stop 34 removes
//! spiked corners of the rim (`removal`'s test 6): 5 → 3 over those 1,050 scans (all three on
//! seed 78, max 5.31 mm), 5 → 4 on the hold-out seeds 86–88 and 3 → 2 on seeds 89–90, made
//! afterwards; seed 91, made at stop 35: 4 (max 7.43 mm; 3 of them > 2 mm from the clean
//! surface, one rim cluster); with stop 35's lower cluster threshold at rims, 1 (4.97 mm,
//! 1.49 mm from the surface). See [`removal`].
//! Result with the defaults of stop 31 (same 100 scans, 1,581,547 vertices): RMSE 0.150 mm over the
//! kept vertices (Laplacian at its best k = 4: 0.717, Taubin at its best k = 37: 0.762),
//! shrinkage 0.0000 mm, damage to the clean twins 0.000 mm RMSE; **1 vertex still more
//! than 2 mm off, max 4.98 mm** (since stop 29; 2 at stop 28, 11 before `removal`'s cluster
//! and repair checks): a rim spike (see [`removal`]). Removed: 1,941 spike vertices (of
//! ~4,900 injected; the rest were moved back) and 1,876 other vertices (0.12 %; 743 before
//! stop 31 removed isolated fragments of ≤ 4 vertices, the rest mostly rims next to spikes
//! and on the eye, nostril and lip gaps); from the clean twins 969 vertices (0.06 %; 629).
//! **The goal of max ≤ 2 mm is not met on fresh data**: new 100-scan sets
//! (`--subjects 20`) leave 5, 4, 1, 0 and 4 vertices > 2 mm off on seeds 77, 78, 79, 80, 81
//! (max 6.3, 5.9, 3.9, 1.5, 9.6 mm; 7, 4, 1, 3, 8 at stop 29, 12, 12, 4, 6 at stop 28), and
//! seed 82 (made after stop 31's changes) 6 (max 6.8 mm; 7 with stop 29's rules), RMSE
//! 0.150–0.151 mm against Laplacian 0.72–0.73 and Taubin 0.77, shrinkage 0.0000 mm; seeds
//! 77–79 were looked at while making stop 29's rules, seeds 80 and 81 at stop 31's (the
//! fragment size, 4, was chosen over 3 on seed 81: 8 → 8 with 3). Second set,
//! `--subjects 10 --seed 1` (50 scans; held out until stop 28): RMSE 0.171 → 0.150 mm,
//! > 2 mm 111 → 0, max 32.6 → 1.03 mm, 592 vertices removed from the clean twins (353
//! before stop 31). Measured as distance to the clean twin's *surface* instead of to the twin
//! vertex (`eval::MethodScore::max_surface_mm`): vertices > 2 mm off it, seeds 2024 / 1 /
//! 77 / 78 / 79 / 80 / 81 / 82: 0 / 0 / 2 / 4 / 0 / 0 / 3 / 4 (max 1.6 / 0.6 / 5.1 / 3.3 /
//! 0.8 / 0.7 / 4.0 / 5.1 mm): a rim tip or a lifted pit is a sample moved along the surface,
//! the clusters on steep sides are not. The literal paper method leaves 13,675 vertices
//! > 2 mm off their twins on seed 2024 but only 457 off the surface (it slides vertices
//! sideways); the input has 4,988 and 4,929. What is left is in [`removal`]'s docs; the
//! editor's erase brush takes it out by hand. The previous
//! default (no removal, no step-edge test): RMSE 0.180 mm, 255
//! vertices > 2 mm, max 36.1 mm. Speed: 38 ms per synthetic scan; whole `facesynth denoise`
//! process (read, filter, write), CPU time, paired medians against the build before removal
//! and the step-edge test: cara1_frontal1 55 ms (ratio 0.97), cara1_sonrisa 126 ms (1.14).
//! Stop 29's removal tests (putting back, re-peeling) cost cara1_sonrisa 83 → 89–96 ms of
//! denoising (`bench-landmarks`, one core, medians of 20, four alternating runs each;
//! denoise + feature points 102 → 108–117 ms, goal 150).
//! The removal's fits are only made at rims, where the filter's own last fit was ≥ 1 mm off,
//! and around moved vertices.
//! Stop 25: the quadric's normal equations and Cholesky on fixed-size arrays instead of
//! nalgebra's generic matrices (45 % of the time was there; results identical): denoise
//! alone in `bench-landmarks`, min / median, cara1_frontal1 35.0 / 36.2 ms, cara1_sonrisa
//! 98.0 / 101.3 ms (was 109 / 115). Stop 33: the consensus fit's 48 subsets depend on the
//! ring size alone, so they are drawn once per size and fitted as index lists (a mask over
//! the ring cost a mispredicted branch per point), and a trial stops counting inliers once it
//! cannot beat the best; identical output, cara1_sonrisa denoising 131 → 111 ms (median).
//!
//! The literal method is [`DenoiseParams::paper`] (`--paper`): global rule, no floor, the
//! paper's median → Laplacian estimate.

pub mod eval;
pub mod removal;

use crate::mesh::{Mesh, Topology};
use crate::{Error, Result};
use glam::DVec3;
use serde::Serialize;

/// Which filter [`denoise`] runs.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize, clap::ValueEnum,
)]
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
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize, clap::ValueEnum,
)]
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
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum BoundaryRule {
    /// Filter a boundary vertex along the boundary only: its neighbours are the vertices it
    /// shares a boundary edge with (held if it has fewer than two).
    #[default]
    AlongBoundary,
    /// Never move boundary vertices (they still act as neighbours of interior vertices).
    Hold,
}

/// How [`DenoiseMethod::MedianLaplacian`] estimates where a vertex should be (steps 1–2 of
/// the iteration); the thresholding and moving (steps 3–6) are the same for both.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum Estimator {
    /// The paper: component-wise median of the 1-ring, then the umbrella Laplacian of the
    /// median-filtered mesh; the vertex moves in 3D.
    MedianLaplacian,
    /// Robust local surface fit (the default): a quadric `z = f(x, y)` fitted by least squares
    /// to the vertex's 2-ring (the vertex itself left out), refitted once without the ring
    /// points whose residual exceeds `max(3 σ̂, 1 mm)` (σ̂ = 1.4826 · median |residual|).
    /// The candidate is the fit's height at the vertex, so the vertex moves along the
    /// scanner's viewing axis z only; x and y (the scanner grid) are kept exactly.
    /// A vertex is eligible only if its change is at least
    /// [`DenoiseParams::outlier_sigmas`] × σ̂ of its ring (and the floor).
    #[default]
    RobustQuadric,
}

/// Parameters of [`denoise`] (missing fields read as their defaults).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
#[serde(default)]
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
    /// filter off smooth skin and off sharp features a local fit mispredicts by a few mm.
    /// Default 4.0 mm: 27 σ of the ~0.15 mm scanner noise, above the 2–3.5 mm by which the
    /// quadric mispredicts canthus folds, lip corners and steep sides, below the ≥ 5 mm of a
    /// long spike. [`DenoiseParams::paper`] uses 0.
    pub min_displacement_mm: f64,
    /// [`Estimator::RobustQuadric`] only: a vertex the filter has already moved (a spike being
    /// taken down) keeps moving while its change is at least this, mm (≥ 0), so the first,
    /// cluster-contaminated estimate of a spike is refined as its neighbours come down.
    /// Default 1.0 mm.
    pub refine_displacement_mm: f64,
    /// Laplacian / Taubin smoothing factor λ (0 < λ ≤ 1). Default 0.5.
    pub lambda: f64,
    /// Taubin inflation factor μ (μ < −λ). Default −0.53 (pass-band k_PB = 1/λ + 1/μ ≈ 0.11,
    /// Taubin 1995's recommended range 0.01–0.1 nearly).
    pub mu: f64,
    /// Boundary handling. Default [`BoundaryRule::AlongBoundary`].
    pub boundary: BoundaryRule,
    /// Local estimate of the median-Laplacian filter. Default [`Estimator::RobustQuadric`];
    /// [`DenoiseParams::paper`] uses [`Estimator::MedianLaplacian`].
    pub estimator: Estimator,
    /// [`Estimator::RobustQuadric`] only: a vertex is eligible to move only if its change is
    /// at least this many robust standard deviations σ̂ of its ring's fit residuals (≥ 0).
    /// It keeps the filter off places where the surface is rough at the grid scale (cone
    /// tips of the eye and mouth fills, lip and nostril edges). Default 6.
    pub outlier_sigmas: f64,
    /// [`Estimator::RobustQuadric`] only: eligibility floor of boundary vertices, mm (≥ 0).
    /// A rim vertex's fit is a one-sided extrapolation, and at the face's silhouette the
    /// surface turns away faster than a quadric predicts: on the clean synthetic twins rim
    /// extrapolations are off by up to ~8 mm, the scanner's own depth-jump limit (faces
    /// spanning more than ~8 mm of depth are not built). Default 8 mm: rim vertices further
    /// off than a real rim can be are spikes.
    pub rim_floor_mm: f64,
    /// [`Estimator::RobustQuadric`] only: remove the vertices the filter cannot repair
    /// (spikes whose support is spiked too, mostly on rims) instead of leaving them; rim
    /// vertices are then never moved, only removed (see [`removal`]). Default `true`;
    /// [`DenoiseParams::paper`] uses `false`.
    pub remove_unrepairable: bool,
    /// [`removal`]: a vertex whose height is off its robust 3-ring fit by more than this,
    /// mm (> 0), is removed. Default 3 mm: 20 σ of the scanner noise, below the ≥ 5 mm of a
    /// spike. Measured on 100 synthetic scans: 2 mm removes three times as many real
    /// vertices (rims of the eye, nostril and lip gaps) for 2 fewer vertices left > 2 mm off;
    /// 4 mm leaves 2 more rim spikes.
    pub removal_residual_mm: f64,
    /// [`removal`] test 5: a vertex the filter moved further than this, mm (> 0), is removed
    /// rather than kept where the filter put it. Default 3 mm: a spike (≥ 5 mm) moved back
    /// held nothing of the surface, and a real one-vertex pit the filter lifted (lid and lip
    /// lines) is a guess of that size; either way the hole is filled downstream as the
    /// repair was. `f64::INFINITY` keeps every repair (a closed mesh, the stop-29 behaviour
    /// less its removals beside repairs). Measured at stop 32, see [`removal`].
    pub repair_max_mm: f64,
}

impl Default for DenoiseParams {
    fn default() -> Self {
        DenoiseParams {
            method: DenoiseMethod::MedianLaplacian,
            iterations: 15,
            w: 0.8,
            rule: MoveRule::PerRegion,
            min_displacement_mm: 4.0,
            refine_displacement_mm: 1.0,
            lambda: 0.5,
            mu: -0.53,
            boundary: BoundaryRule::AlongBoundary,
            estimator: Estimator::RobustQuadric,
            outlier_sigmas: 6.0,
            rim_floor_mm: 8.0,
            remove_unrepairable: true,
            removal_residual_mm: 3.0,
            repair_max_mm: 3.0,
        }
    }
}

impl DenoiseParams {
    /// The literal paper method: global threshold, no displacement floor, w = 0.8, k = 15.
    pub fn paper() -> Self {
        DenoiseParams {
            rule: MoveRule::Global,
            min_displacement_mm: 0.0,
            estimator: Estimator::MedianLaplacian,
            remove_unrepairable: false,
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
        if !(self.refine_displacement_mm >= 0.0 && self.refine_displacement_mm.is_finite()) {
            return bad(format!(
                "refine_displacement_mm must be ≥ 0, got {}",
                self.refine_displacement_mm
            ));
        }
        if !(self.outlier_sigmas >= 0.0 && self.outlier_sigmas.is_finite()) {
            return bad(format!(
                "outlier_sigmas must be ≥ 0, got {}",
                self.outlier_sigmas
            ));
        }
        if !(self.rim_floor_mm >= 0.0 && self.rim_floor_mm.is_finite()) {
            return bad(format!(
                "rim_floor_mm must be ≥ 0, got {}",
                self.rim_floor_mm
            ));
        }
        if !(self.removal_residual_mm > 0.0 && self.removal_residual_mm.is_finite()) {
            return bad(format!(
                "removal_residual_mm must be > 0, got {}",
                self.removal_residual_mm
            ));
        }
        if !(self.repair_max_mm > 0.0) {
            return bad(format!(
                "repair_max_mm must be > 0, got {}",
                self.repair_max_mm
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
    /// Distinct vertices moved at least once (of those kept).
    pub vertices_moved: usize,
    /// Vertices removed as unrepairable ([`removal`]; 0 unless
    /// [`DenoiseParams::remove_unrepairable`]), with the vertices left without a face.
    pub vertices_removed: usize,
    /// Largest distance between a kept vertex's final and input position, mm.
    pub max_displacement_mm: f64,
    /// Mean distance between final and input positions over the kept vertices, mm.
    pub mean_displacement_mm: f64,
    /// Per input vertex: distance between final and input position, mm (for heat maps); NaN
    /// for a removed vertex.
    #[serde(skip)]
    pub displacement_mm: Vec<f64>,
    /// Input ids of the removed vertices, ascending.
    #[serde(skip)]
    pub removed: Vec<u32>,
    /// Input id of every output vertex (output → input; the identity when nothing was
    /// removed).
    #[serde(skip)]
    pub kept: Vec<u32>,
}

impl DenoiseReport {
    /// The report of a filter run: `positions` (one per input vertex) are where it left the
    /// vertices; figures are over the kept ones.
    fn new(method: DenoiseMethod, filtered: &Filtered, positions: &[DVec3]) -> Self {
        let Filtered {
            input,
            iterations_run,
            moved,
            removed: gone,
        } = filtered;
        let n = input.len() as u32;
        let removed: Vec<u32> = (0..n).filter(|&v| gone[v as usize]).collect();
        let kept: Vec<u32> = (0..n).filter(|&v| !gone[v as usize]).collect();
        let displacement_mm: Vec<f64> = positions
            .iter()
            .zip(input)
            .zip(gone)
            .map(|((p, q), &g)| if g { f64::NAN } else { p.distance(*q) })
            .collect();
        let on_kept = || kept.iter().map(|&v| displacement_mm[v as usize]);
        let mean_displacement_mm = if kept.is_empty() {
            0.0
        } else {
            on_kept().sum::<f64>() / kept.len() as f64
        };
        DenoiseReport {
            method,
            iterations_run: *iterations_run,
            vertices_moved: kept.iter().filter(|&&v| moved[v as usize]).count(),
            vertices_removed: removed.len(),
            max_displacement_mm: on_kept().fold(0.0, f64::max),
            mean_displacement_mm,
            displacement_mm,
            removed,
            kept,
        }
    }
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
    let mut filtered = filter(&mut mesh.positions_mm, &nb, topology, params, |_, _| {});
    if !filtered.removed.iter().any(|&r| r) {
        return Ok(DenoiseReport::new(
            params.method,
            &filtered,
            &mesh.positions_mm,
        ));
    }
    removal::add_orphans(&mesh.faces, &mut filtered.removed);
    let report = DenoiseReport::new(params.method, &filtered, &mesh.positions_mm);
    let keep: Vec<bool> = filtered.removed.iter().map(|r| !r).collect();
    mesh.retain_vertices(&keep);
    Ok(report)
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
pub(crate) const STILL_MM: f64 = 1e-9;

/// Runs the filter on `positions`; `observe(iteration, positions)` is called after every
/// iteration (1-based), so a sweep over k costs one run (used by [`eval`]). Vertices to be
/// removed are only reported (`removed`, NaN displacement), not taken out: [`denoise`] does
/// that with the mesh.
pub fn run(
    positions: &mut [DVec3],
    nb: &FilterNeighbours,
    topology: &Topology,
    params: &DenoiseParams,
    observe: impl FnMut(usize, &[DVec3]),
) -> DenoiseReport {
    let filtered = filter(positions, nb, topology, params, observe);
    DenoiseReport::new(params.method, &filtered, positions)
}

/// What the filter did, before [`DenoiseReport::new`] sums it up (one entry per input vertex).
struct Filtered {
    input: Vec<DVec3>,
    iterations_run: usize,
    moved: Vec<bool>,
    /// Vertices to take out of the mesh (none unless removal is on).
    removed: Vec<bool>,
}

fn filter(
    positions: &mut [DVec3],
    nb: &FilterNeighbours,
    topology: &Topology,
    params: &DenoiseParams,
    mut observe: impl FnMut(usize, &[DVec3]),
) -> Filtered {
    let n = positions.len();
    assert_eq!(
        nb.vertex_count(),
        n,
        "filter neighbours do not fit the mesh"
    );
    let input = positions.to_vec();
    let mut moved = vec![false; n];
    let mut removed = vec![false; n];
    let mut iterations_run = 0;
    match params.method {
        DenoiseMethod::MedianLaplacian => {
            let mut work = MedianLaplacianWork::new(n, topology, params.estimator);
            // Iterations of the current phase; the quadric estimator does the rims once the
            // interior has settled or used its k, and the rim phase gets k of its own (else a
            // slowly converging interior would leave every rim spike untouched).
            let (mut it, mut phase_it) = (0, 0);
            loop {
                let count = if phase_it < params.iterations {
                    work.iterate(positions, &input, nb, topology, params, &mut moved)
                } else {
                    0
                };
                if count == 0 {
                    // With removal on, rim vertices are removed, never moved (see [`removal`]).
                    if work.rim_phase
                        || params.remove_unrepairable
                        || !work.start_rim_phase(topology)
                    {
                        break;
                    }
                    phase_it = 0;
                    continue;
                }
                phase_it += 1;
                it += 1;
                iterations_run += 1;
                observe(it, positions);
            }
            // k = 0 leaves the mesh as it is (the documented identity).
            if let Some(rings3) = work.rings3.as_ref().filter(|_| params.iterations > 0) {
                polish(positions, topology, rings3, &moved, &mut work.fit);
                if params.remove_unrepairable {
                    removed = removal::unrepairable(
                        positions, &input, topology, rings3, params, &work.disp, &moved,
                    );
                }
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
    Filtered {
        input,
        iterations_run,
        moved,
        removed,
    }
}

/// The quadric estimator's last pass: every interior vertex the filter moved is refitted
/// from the vertices of its 3-ring that it did not move. A spike cluster's members were
/// first estimated from rings that held the cluster's other spikes; once all are down, the
/// unmoved ring is clean support.
fn polish(
    positions: &mut [DVec3],
    topology: &Topology,
    rings3: &Rings,
    moved: &[bool],
    fit: &mut QuadricFit,
) {
    for v in 0..positions.len() {
        if !moved[v] || topology.is_boundary[v] {
            continue;
        }
        let p = positions[v];
        if let Some((z, _, _)) = fit.predict(positions, p, rings3.of(v), |u| !moved[u]) {
            positions[v].z = z;
        }
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
    /// Per-vertex eligibility floor, mm (the robust estimator's `k σ̂`, else the global floor).
    floor: Vec<f64>,
    label: Vec<u32>,
    region_max: Vec<f64>,
    stack: Vec<u32>,
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
    /// [`Estimator::RobustQuadric`]: the 2-rings (CSR), and which vertices need a new fit.
    rings: Option<Rings>,
    /// The 3-rings, for vertices whose 2-ring fit stays rough (spike clusters).
    rings3: Option<Rings>,
    dirty: Vec<bool>,
    /// [`Estimator::RobustQuadric`]: `false` while the interior is filtered (rim vertices
    /// wait), `true` once it has settled and the rim vertices are filtered.
    rim_phase: bool,
    fit: QuadricFit,
}

/// The 2-ring of every vertex (the vertex itself excluded), CSR.
struct Rings {
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl Rings {
    fn new(topology: &Topology, k: usize) -> Self {
        let n = topology.vertex_count();
        let mut offsets = Vec::with_capacity(n + 1);
        let mut items = Vec::with_capacity(n * 12);
        let mut scratch = vec![false; n];
        let mut ring = Vec::new();
        offsets.push(0);
        for v in 0..n {
            topology.k_ring(v, k, &mut scratch, &mut ring);
            items.extend_from_slice(&ring);
            offsets.push(items.len() as u32);
        }
        Rings { offsets, items }
    }

    fn of(&self, v: usize) -> &[u32] {
        &self.items[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }
}

impl MedianLaplacianWork {
    fn new(n: usize, topology: &Topology, estimator: Estimator) -> Self {
        MedianLaplacianWork {
            median: vec![DVec3::ZERO; n],
            candidate: vec![DVec3::ZERO; n],
            disp: vec![0.0; n],
            floor: vec![0.0; n],
            label: vec![u32::MAX; n],
            region_max: Vec::new(),
            stack: Vec::new(),
            xs: Vec::with_capacity(16),
            ys: Vec::with_capacity(16),
            zs: Vec::with_capacity(16),
            rings: (estimator == Estimator::RobustQuadric).then(|| Rings::new(topology, 2)),
            rings3: (estimator == Estimator::RobustQuadric).then(|| Rings::new(topology, 3)),
            dirty: vec![true; n],
            rim_phase: false,
            fit: QuadricFit::default(),
        }
    }

    /// Steps 1–3 of [`Estimator::MedianLaplacian`]: candidates and displacements.
    fn estimate_median_laplacian(
        &mut self,
        positions: &[DVec3],
        nb: &FilterNeighbours,
        floor: f64,
    ) {
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
            self.floor[v] = floor;
        }
    }

    /// Steps 1–3 of [`Estimator::RobustQuadric`] for the vertices marked dirty.
    fn estimate_quadric(
        &mut self,
        positions: &[DVec3],
        input: &[DVec3],
        topology: &Topology,
        params: &DenoiseParams,
        floor: f64,
        moved: &[bool],
    ) {
        let rings = self
            .rings
            .as_ref()
            .expect("rings are built for the quadric estimator");
        let rings3 = self
            .rings3
            .as_ref()
            .expect("rings are built for the quadric estimator");
        for v in 0..positions.len() {
            if !self.dirty[v] {
                continue;
            }
            self.dirty[v] = false;
            let p = positions[v];
            let held = topology.is_boundary[v]
                && (params.boundary == BoundaryRule::Hold || !self.rim_phase);
            let estimate = if held {
                None
            } else {
                if topology.is_boundary[v] {
                    // A rim vertex is fitted from the interior of its 3-ring only: other rim
                    // vertices (single-face tips, rim spikes) are the least reliable support.
                    let interior = |u: usize| !topology.is_boundary[u];
                    self.fit
                        .predict(positions, p, rings3.of(v), interior)
                        .or_else(|| self.fit.predict(positions, p, rings3.of(v), |_| true))
                } else {
                    let all = |_: usize| true;
                    match self.fit.predict(positions, p, rings.of(v), all) {
                        // A rough 2-ring: a spike cluster may hold too large a share of it.
                        Some((_, sigma, _)) if sigma > TRIM_MIN_MM => self
                            .fit
                            .predict(positions, p, rings3.of(v), all)
                            .filter(|e| e.1 < sigma),
                        e => e,
                    }
                    .or_else(|| self.fit.predict(positions, p, rings.of(v), all))
                }
            };
            // A rim vertex moves only towards its neighbours' median height and not much
            // past it: a one-sided fit next to other defects can point the wrong way.
            let estimate = estimate.filter(|&(z, _, _)| {
                if !topology.is_boundary[v] {
                    return true;
                }
                self.zs.clear();
                self.zs.extend(
                    topology
                        .neighbours(v)
                        .iter()
                        .map(|&u| positions[u as usize].z),
                );
                if self.zs.is_empty() {
                    return false;
                }
                let towards = median(&mut self.zs) - p.z;
                let step = z - p.z;
                step * towards > 0.0 && step.abs() <= towards.abs() + params.rim_floor_mm
            });
            match estimate {
                Some((z, sigma, rough)) => {
                    self.candidate[v] = DVec3::new(p.x, p.y, z);
                    self.disp[v] = (z - p.z).abs();
                    self.floor[v] = if moved[v] {
                        params.refine_displacement_mm.max(STILL_MM)
                    } else {
                        let f =
                            eligibility_floor(params, floor, sigma, rough, topology.is_boundary[v]);
                        veto_real_surface(f, self.disp[v], input, v, rings3.of(v), topology)
                    };
                }
                None => {
                    self.candidate[v] = p;
                    self.disp[v] = 0.0;
                    self.floor[v] = f64::INFINITY;
                }
            }
        }
        self.estimate_clusters(positions, input, topology, params, floor, moved);
    }

    /// Spike clusters: a vertex whose change clears the displacement floor but not its ring's
    /// roughness test, next to other such vertices, is refitted from its 3-ring without all
    /// of them. Several spiked neighbours (up to a third of a rim vertex's ring) otherwise
    /// pull its fit towards them and make its ring look rough, so the whole cluster stays.
    fn estimate_clusters(
        &mut self,
        positions: &[DVec3],
        input: &[DVec3],
        topology: &Topology,
        params: &DenoiseParams,
        floor: f64,
        moved: &[bool],
    ) {
        let rings3 = self
            .rings3
            .as_ref()
            .expect("rings are built for the quadric estimator");
        let n = positions.len();
        let suspect: Vec<bool> = (0..n).map(|v| self.disp[v] >= floor).collect();
        for v in 0..n {
            let blocked = suspect[v] && self.disp[v] < self.floor[v] && !moved[v];
            if !blocked
                || (topology.is_boundary[v] && !self.rim_phase)
                || !topology.neighbours(v).iter().any(|&u| suspect[u as usize])
            {
                continue;
            }
            let p = positions[v];
            let use_point = |u: usize| !suspect[u] && !topology.is_boundary[u];
            let Some((z, sigma, rough)) = self.fit.predict(positions, p, rings3.of(v), use_point)
            else {
                continue;
            };
            // Only a change the same way as the first estimate's: the cluster is one event.
            if (z - p.z) * (self.candidate[v].z - p.z) <= 0.0 {
                continue;
            }
            self.candidate[v] = DVec3::new(p.x, p.y, z);
            self.disp[v] = (z - p.z).abs();
            let f = eligibility_floor(params, floor, sigma, rough, topology.is_boundary[v]);
            self.floor[v] = veto_real_surface(f, self.disp[v], input, v, rings3.of(v), topology);
        }
    }

    /// One iteration; returns how many vertices moved.
    fn iterate(
        &mut self,
        positions: &mut [DVec3],
        input: &[DVec3],
        nb: &FilterNeighbours,
        topology: &Topology,
        params: &DenoiseParams,
        moved: &mut [bool],
    ) -> usize {
        let floor = params.min_displacement_mm.max(STILL_MM);
        match params.estimator {
            Estimator::MedianLaplacian => self.estimate_median_laplacian(positions, nb, floor),
            Estimator::RobustQuadric => {
                self.estimate_quadric(positions, input, topology, params, floor, moved)
            }
        }
        // 4. Threshold; 5. move.
        let mut count = 0;
        match params.rule {
            MoveRule::Global => {
                let max = self
                    .disp
                    .iter()
                    .zip(&self.floor)
                    .filter(|(d, f)| d >= f)
                    .map(|(d, _)| *d)
                    .fold(0.0, f64::max);
                let t = params.w * max;
                for v in 0..positions.len() {
                    if self.disp[v] >= t && self.disp[v] >= self.floor[v] {
                        positions[v] = self.candidate[v];
                        moved[v] = true;
                        count += 1;
                        self.mark_dirty(v);
                    }
                }
            }
            MoveRule::PerRegion => {
                self.label_regions(topology);
                for v in 0..positions.len() {
                    let l = self.label[v];
                    if l != u32::MAX && self.disp[v] >= params.w * self.region_max[l as usize] {
                        positions[v] = self.candidate[v];
                        moved[v] = true;
                        count += 1;
                        self.mark_dirty(v);
                    }
                }
            }
        }
        count
    }

    /// Switches the quadric estimator to the rim phase; `false` if there is none (the paper's
    /// estimator, or no rim).
    fn start_rim_phase(&mut self, topology: &Topology) -> bool {
        if self.rings.is_none() || !topology.is_boundary.iter().any(|&b| b) {
            return false;
        }
        self.rim_phase = true;
        for (d, &b) in self.dirty.iter_mut().zip(&topology.is_boundary) {
            *d |= b;
        }
        true
    }

    /// After `v` moved: every vertex whose estimate uses `v` needs a new one.
    fn mark_dirty(&mut self, v: usize) {
        if let Some(rings) = &self.rings3 {
            self.dirty[v] = true;
            for &u in rings.of(v) {
                self.dirty[u as usize] = true;
            }
        }
    }

    /// Labels the connected regions of eligible vertices (`disp ≥ floor`) and records each
    /// region's largest displacement.
    fn label_regions(&mut self, topology: &Topology) {
        self.label.fill(u32::MAX);
        self.region_max.clear();
        for seed in 0..self.disp.len() {
            if self.disp[seed] < self.floor[seed] || self.label[seed] != u32::MAX {
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
                    if self.label[u] == u32::MAX && self.disp[u] >= self.floor[u] {
                        self.label[u] = id;
                        self.stack.push(u as u32);
                    }
                }
            }
            self.region_max.push(max);
        }
    }
}

/// Least-squares quadric (or plane) fit of a height field over a vertex's ring, with one
/// trimming pass ([`Estimator::RobustQuadric`]).
#[derive(Default)]
struct QuadricFit {
    /// Ring points relative to the vertex: (x, y, z).
    pts: Vec<DVec3>,
    keep: Vec<bool>,
    /// Least-squares weights (1 = plain least squares; the L1 reweighting changes them).
    weight: Vec<f64>,
    res: Vec<f64>,
    /// The consensus fit's subsets for a ring of `n` points, at index `n`: the pseudo-random
    /// sequence depends on `n` alone, so each is drawn once per fit object.
    subsets: Vec<Vec<[u32; QUADRIC_MIN_POINTS]>>,
}

/// Fewest ring points for a quadric fit (6 unknowns) and for a plane fit (3 unknowns).
const QUADRIC_MIN_POINTS: usize = 9;
const PLANE_MIN_POINTS: usize = 4;
/// L1 (least absolute deviations) reweighting rounds used when a plain fit leaves a rough
/// ring (σ̂ above [`TRIM_MIN_MM`]): a spike cluster inside the ring pulls a least-squares
/// fit towards it, the L1 fit is not pulled by a minority of outliers in z.
const L1_ROUNDS: usize = 10;
/// A vertex is eligible only if its change is at least this many times the ring's own
/// roughness (90th percentile of the ring residuals below half the change): a spike stands
/// out of a smooth ring, a vertex on a crease or lip edge the quadric cannot follow has
/// ring neighbours almost as far off as itself.
const RING_ROUGHNESS_RATIO: f64 = 3.0;
/// A first fit with a ring residual above this (mm) is redone by L1 reweighting.
const L1_TRIGGER_MM: f64 = 2.0;
/// Random subsets tried by the consensus fit, and the residual (mm) within which a ring point
/// agrees with a candidate quadric (scanner noise σ ≈ 0.15 mm, plus what a quadric cannot
/// follow over a 3-ring).
const CONSENSUS_TRIALS: usize = 48;
const CONSENSUS_TOLERANCE_MM: f64 = 1.5;
/// Ring points with a residual above `max(TRIM_SIGMAS σ̂, TRIM_MIN_MM)` are left out of the
/// refit.
const TRIM_SIGMAS: f64 = 3.0;
const TRIM_MIN_MM: f64 = 1.0;

impl QuadricFit {
    /// Takes the ring points `use_point` admits, relative to `p`, all kept, unit weights.
    fn load(
        &mut self,
        positions: &[DVec3],
        p: DVec3,
        ring: &[u32],
        use_point: impl Fn(usize) -> bool,
    ) {
        self.pts.clear();
        self.pts.extend(
            ring.iter()
                .filter(|&&u| use_point(u as usize))
                .map(|&u| positions[u as usize] - p),
        );
        self.keep.clear();
        self.keep.resize(self.pts.len(), true);
        self.weight.clear();
        self.weight.resize(self.pts.len(), 1.0);
    }

    /// The height [`QuadricFit::predict`] would give at `p`, computed the cheap way when the
    /// ring is smooth: one least-squares fit that leaves every ring point within
    /// [`TRIM_MIN_MM`] is what `predict` keeps (no L1, no consensus, nothing trimmed), so the
    /// height is the same. `None` when the ring is not that smooth (call `predict`).
    fn predict_smooth(
        &mut self,
        positions: &[DVec3],
        p: DVec3,
        ring: &[u32],
        use_point: impl Fn(usize) -> bool,
    ) -> Option<f64> {
        self.load(positions, p, ring, use_point);
        let (z, c) = self.solve()?;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for q in &self.pts {
            if (q.z - eval_quadric(&c, q.x, q.y)).abs() > TRIM_MIN_MM {
                return None;
            }
            (lo, hi) = (lo.min(q.z), hi.max(q.z));
        }
        let span = hi - lo;
        (z >= lo - span - 1.0 && z <= hi + span + 1.0).then_some(p.z + z)
    }

    /// The fitted height at `p`: [`Self::predict_smooth`] where the ring is smooth, else
    /// [`Self::predict`]'s.
    fn height(
        &mut self,
        positions: &[DVec3],
        p: DVec3,
        ring: &[u32],
        use_point: impl Fn(usize) -> bool + Copy,
    ) -> Option<f64> {
        self.predict_smooth(positions, p, ring, use_point)
            .or_else(|| {
                self.predict(positions, p, ring, use_point)
                    .map(|(z, _, _)| z)
            })
    }

    /// The fitted height at `p`, the robust residual scale σ̂ of the kept ring points and the
    /// ring's roughness on the scale of the change (see [`RING_ROUGHNESS_RATIO`]), or `None`
    /// when the ring cannot support a fit.
    fn predict(
        &mut self,
        positions: &[DVec3],
        p: DVec3,
        ring: &[u32],
        use_point: impl Fn(usize) -> bool,
    ) -> Option<(f64, f64, f64)> {
        self.load(positions, p, ring, use_point);
        let mut z = self.solve()?;
        let rough = self
            .pts
            .iter()
            .any(|q| (q.z - eval_quadric(&z.1, q.x, q.y)).abs() > L1_TRIGGER_MM);
        if rough {
            for _ in 0..L1_ROUNDS {
                for (i, q) in self.pts.iter().enumerate() {
                    let r = (q.z - eval_quadric(&z.1, q.x, q.y)).abs();
                    self.weight[i] = 1.0 / r.max(0.05);
                }
                z = self.solve()?;
            }
            self.weight.fill(1.0);
            // A spike cluster can hold a third of a rim vertex's ring, more than L1 resists:
            // a consensus fit (random 9-point subsets, the quadric most points agree with)
            // is not pulled by any minority.
            if let Some(c) = self.consensus()
                && self.inliers(&c.1, 0) > self.inliers(&z.1, 0)
            {
                z = c;
            }
        }
        let sigma = self.trim(z.1);
        if self.keep.iter().any(|k| !k) {
            z = self.solve()?;
        }
        let sigma = self.sigma_of(z.1).min(sigma);
        // A wild extrapolation (thin strips, one-sided rims): not trusted.
        let (lo, hi) = self
            .pts
            .iter()
            .zip(&self.keep)
            .filter(|(_, k)| **k)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (q, _)| {
                (lo.min(q.z), hi.max(q.z))
            });
        let span = hi - lo;
        if !(z.0 >= lo - span - 1.0 && z.0 <= hi + span + 1.0) {
            return None;
        }
        // How rough the ring is on the scale of this change: the 90th percentile of the ring
        // residuals below half the change (a cluster's other spikes are above it).
        let d = z.0.abs();
        self.res.clear();
        for q in &self.pts {
            let r = (q.z - eval_quadric(&z.1, q.x, q.y)).abs();
            if r < 0.5 * d {
                self.res.push(r);
            }
        }
        let rough = if self.res.is_empty() {
            0.0
        } else {
            let k = (0.9 * (self.res.len() - 1) as f64).round() as usize;
            *self.res.select_nth_unstable_by(k, f64::total_cmp).1
        };
        Some((p.z + z.0, sigma, rough))
    }

    /// Ring points within [`CONSENSUS_TOLERANCE_MM`] of the quadric `coef`, counted until the
    /// count can no longer exceed `beat` (0: the whole count).
    fn inliers(&self, coef: &[f64; 6], beat: usize) -> usize {
        let n = self.pts.len();
        let mut count = 0;
        for (seen, q) in self.pts.iter().enumerate() {
            if count + (n - seen) <= beat {
                break;
            }
            if (q.z - eval_quadric(coef, q.x, q.y)).abs() < CONSENSUS_TOLERANCE_MM {
                count += 1;
            }
        }
        count
    }

    /// Consensus fit: of [`CONSENSUS_TRIALS`] least-squares quadrics through random
    /// [`QUADRIC_MIN_POINTS`]-point subsets (a fixed pseudo-random sequence, so runs repeat),
    /// the one with the most inliers, refitted to its inliers. Leaves `keep` all set.
    fn consensus(&mut self) -> Option<(f64, [f64; 6])> {
        let n = self.pts.len();
        if n < 2 * QUADRIC_MIN_POINTS {
            return None;
        }
        if self.subsets.len() <= n {
            self.subsets.resize(n + 1, Vec::new());
        }
        if self.subsets[n].is_empty() {
            self.subsets[n] = consensus_subsets(n);
        }
        let mut best: Option<(usize, [f64; 6])> = None;
        for subset in &self.subsets[n] {
            let Some(c) = fit_terms::<6>(subset.iter().map(|&i| (self.pts[i as usize], 1.0)))
            else {
                continue;
            };
            // Only a count above the best so far matters.
            let count = self.inliers(&c, best.map_or(0, |(b, _)| b));
            if best.is_none_or(|(b, _)| count > b) {
                best = Some((count, c));
            }
        }
        let (_, c) = best?;
        for (q, k) in self.pts.iter().zip(self.keep.iter_mut()) {
            *k = (q.z - eval_quadric(&c, q.x, q.y)).abs() < CONSENSUS_TOLERANCE_MM;
        }
        let refit = self.solve();
        self.keep.fill(true);
        refit
    }

    /// Robust σ̂ (1.4826 · median |residual|) of the kept points under `coef`.
    fn sigma_of(&mut self, coef: [f64; 6]) -> f64 {
        self.res.clear();
        for (q, k) in self.pts.iter().zip(&self.keep) {
            if *k {
                self.res.push((q.z - eval_quadric(&coef, q.x, q.y)).abs());
            }
        }
        if self.res.is_empty() {
            return 0.0;
        }
        1.4826 * median(&mut self.res)
    }

    /// Drops the points whose residual is above the trimming limit; returns σ̂ before.
    fn trim(&mut self, coef: [f64; 6]) -> f64 {
        let sigma = self.sigma_of(coef);
        let limit = (TRIM_SIGMAS * sigma).max(TRIM_MIN_MM);
        for (q, k) in self.pts.iter().zip(self.keep.iter_mut()) {
            if (q.z - eval_quadric(&coef, q.x, q.y)).abs() > limit {
                *k = false;
            }
        }
        sigma
    }

    /// Least squares over the kept points: a quadric if there are enough and it is well
    /// conditioned, else a plane. Returns (height at the origin, coefficients).
    fn solve(&self) -> Option<(f64, [f64; 6])> {
        let count = self.keep.iter().filter(|k| **k).count();
        if count >= QUADRIC_MIN_POINTS
            && let Some(c) = self.solve_terms::<6>()
        {
            return Some((c[0], c));
        }
        if count >= PLANE_MIN_POINTS
            && let Some(c) = self.solve_terms::<3>()
        {
            return Some((c[0], [c[0], c[1], c[2], 0.0, 0.0, 0.0]));
        }
        None
    }

    /// [`fit_terms`] over the kept points with their weights.
    fn solve_terms<const K: usize>(&self) -> Option<[f64; K]> {
        fit_terms::<K>(
            self.pts
                .iter()
                .zip(&self.keep)
                .zip(&self.weight)
                .filter(|((_, k), _)| **k)
                .map(|((q, _), w)| (*q, *w)),
        )
    }
}

/// [`CONSENSUS_TRIALS`] distinct-index subsets of [`QUADRIC_MIN_POINTS`] ring points out of
/// `n`, each in ring order (a fixed xorshift sequence seeded by `n`, so runs repeat).
fn consensus_subsets(n: usize) -> Vec<[u32; QUADRIC_MIN_POINTS]> {
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15 ^ n as u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    (0..CONSENSUS_TRIALS)
        .map(|_| {
            let mut subset = [0u32; QUADRIC_MIN_POINTS];
            let mut chosen = 0;
            while chosen < QUADRIC_MIN_POINTS {
                let i = (next() % n as u64) as u32;
                if !subset[..chosen].contains(&i) {
                    subset[chosen] = i;
                    chosen += 1;
                }
            }
            // Ring order, as a mask over the ring would visit them, so the sums are the
            // same; an index list spares a mispredicted branch per ring point.
            subset.sort_unstable();
            subset
        })
        .collect()
}

/// Weighted least squares for the first `K` terms of `[1, x, y, x², xy, y²]` through points
/// (x, y, z) with weights, in coordinates scaled by the points' RMS radius; `None` if
/// (nearly) singular.
fn fit_terms<const K: usize>(
    points: impl Iterator<Item = (DVec3, f64)> + Clone,
) -> Option<[f64; K]> {
    let (mut r2, mut n) = (0.0, 0.0);
    for (q, _) in points.clone() {
        r2 += q.x * q.x + q.y * q.y;
        n += 1.0;
    }
    let scale = (r2 / n).sqrt();
    if !(scale > 1e-9) {
        return None;
    }
    // Upper triangle of AᵀWA and AᵀWz, then an in-place Cholesky: this runs ~10⁵ times
    // per scan (L1 rounds, consensus trials), so it avoids generic matrix temporaries.
    let mut ata = [[0.0f64; K]; K];
    let mut atb = [0.0f64; K];
    for (q, w) in points {
        let (x, y) = (q.x / scale, q.y / scale);
        let all = quadric_terms(x, y);
        for i in 0..K {
            let wi = w * all[i];
            for j in i..K {
                ata[i][j] += wi * all[j];
            }
            atb[i] += wi * q.z;
        }
    }
    // Cholesky A = LLᵀ, L stored in the lower triangle (row i, column j ≤ i).
    let mut l = [[0.0f64; K]; K];
    for j in 0..K {
        let mut d = ata[j][j];
        for m in 0..j {
            d -= l[j][m] * l[j][m];
        }
        if !(d > 0.0) {
            return None;
        }
        let d = d.sqrt();
        l[j][j] = d;
        for i in j + 1..K {
            let mut s = ata[j][i];
            for m in 0..j {
                s -= l[i][m] * l[j][m];
            }
            l[i][j] = s / d;
        }
    }
    let (dmin, dmax) = (0..K).fold((f64::INFINITY, 0.0f64), |(lo, hi), i| {
        (lo.min(l[i][i]), hi.max(l[i][i]))
    });
    // Diagonal of the factor ~ singular values' square roots: reject condition > ~1e8.
    if !(dmin > 1e-4 * dmax) {
        return None;
    }
    // Forward (L u = b) then back (Lᵀ c = u) substitution.
    let mut c = atb;
    for i in 0..K {
        for m in 0..i {
            c[i] -= l[i][m] * c[m];
        }
        c[i] /= l[i][i];
    }
    for i in (0..K).rev() {
        for m in i + 1..K {
            c[i] -= l[m][i] * c[m];
        }
        c[i] /= l[i][i];
    }
    let unscale = [
        1.0,
        1.0 / scale,
        1.0 / scale,
        1.0 / (scale * scale),
        1.0 / (scale * scale),
        1.0 / (scale * scale),
    ];
    Some(std::array::from_fn(|i| c[i] * unscale[i]))
}

/// Points of a vertex's 3-ring within this distance (mm, along z) of a plane through the
/// vertex count as its support in [`on_real_surface`].
const SURFACE_SUPPORT_TOLERANCE_MM: f64 = 1.0;
/// [`on_real_surface`]: the fewest supporting ring points, and the smallest share of the ring.
/// A spike cluster has at most 5 other members; measured on 100 synthetic scans (3-rings of 24
/// points on the quad grid), interior spikes had at most 9 supporting points (95 % at most 6,
/// about a fifth of the ring), the clean crease and lid vertices the filter moved wrongly 5–13
/// (median 10, half the ring).
const SURFACE_SUPPORT_MIN_POINTS: usize = 8;
const SURFACE_SUPPORT_MIN_SHARE: f64 = 1.0 / 3.0;

/// Step-edge test: whether vertex `v`, where it lies in `input`, shares a plane with at least
/// [`SURFACE_SUPPORT_MIN_POINTS`] and [`SURFACE_SUPPORT_MIN_SHARE`] of its ring (within
/// [`SURFACE_SUPPORT_TOLERANCE_MM`]). Such a vertex is a sample of a real surface that the
/// quadric of the whole ring cannot follow (one side of a lid crease, a lip or mouth edge),
/// not a spike: a spike is off every plane through it but those through its own cluster.
/// With `min_span_deg`, the supporting points must also span that angle around the vertex
/// (the filter asks no span; peeling does, see `removal::PEEL_SUPPORT_MIN_SPAN_DEG`).
/// Tries every plane through the vertex and two ring points (24 points: 276 planes).
fn on_real_surface(input: &[DVec3], v: usize, ring: &[u32], min_span_deg: Option<f64>) -> bool {
    let p = input[v];
    let need = SURFACE_SUPPORT_MIN_POINTS
        .max((SURFACE_SUPPORT_MIN_SHARE * ring.len() as f64).ceil() as usize);
    if ring.len() < need {
        return false;
    }
    let q: Vec<DVec3> = ring.iter().map(|&u| input[u as usize] - p).collect();
    for a in 0..q.len() {
        for b in a + 1..q.len() {
            // The plane z = c1 x + c2 y through the vertex, a and b; nearly collinear: none.
            let det = q[a].x * q[b].y - q[a].y * q[b].x;
            if det.abs() < 0.5 {
                continue;
            }
            let c1 = (q[a].z * q[b].y - q[a].y * q[b].z) / det;
            let c2 = (q[a].x * q[b].z - q[a].z * q[b].x) / det;
            let support = || {
                q.iter().filter(move |r| {
                    (r.z - c1 * r.x - c2 * r.y).abs() < SURFACE_SUPPORT_TOLERANCE_MM
                })
            };
            if support().count() >= need
                && min_span_deg.is_none_or(|min| span_deg(support()) >= min)
            {
                return true;
            }
        }
    }
    false
}

/// The angle (degrees) that `points` (relative to a vertex) span as seen from it: 360 less
/// the widest gap between their directions.
fn span_deg<'a>(points: impl Iterator<Item = &'a DVec3>) -> f64 {
    let mut angles: Vec<f64> = points.map(|r| r.y.atan2(r.x).to_degrees()).collect();
    angles.sort_by(f64::total_cmp);
    let (Some(&first), Some(&last)) = (angles.first(), angles.last()) else {
        return 0.0;
    };
    let gap = angles
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(first + 360.0 - last, f64::max);
    360.0 - gap
}

/// An interior vertex that would move (`disp ≥ floor`) but lies on a real surface
/// ([`on_real_surface`]) does not: its floor becomes infinite.
fn veto_real_surface(
    floor: f64,
    disp: f64,
    input: &[DVec3],
    v: usize,
    ring: &[u32],
    topology: &Topology,
) -> f64 {
    if disp >= floor && !topology.is_boundary[v] && on_real_surface(input, v, ring, None) {
        f64::INFINITY
    } else {
        floor
    }
}

/// The smallest change that moves a vertex not yet moved: the displacement floor, `k σ̂` of
/// its ring, [`RING_ROUGHNESS_RATIO`] × the ring's roughness, and the rim floor on a rim.
fn eligibility_floor(
    params: &DenoiseParams,
    floor: f64,
    sigma: f64,
    rough: f64,
    boundary: bool,
) -> f64 {
    let rim = if boundary { params.rim_floor_mm } else { 0.0 };
    floor
        .max(params.outlier_sigmas * sigma)
        .max(RING_ROUGHNESS_RATIO * rough)
        .max(rim)
}

/// The quadric's terms `[1, x, y, x², xy, y²]` at (x, y): one row of the fit's design matrix.
fn quadric_terms(x: f64, y: f64) -> [f64; 6] {
    [1.0, x, y, x * x, x * y, y * y]
}

fn eval_quadric(c: &[f64; 6], x: f64, y: f64) -> f64 {
    c[0] + c[1] * x + c[2] * y + c[3] * x * x + c[4] * x * y + c[5] * y * y
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

    /// The hand-written normal equations and Cholesky of `solve_terms` give nalgebra's
    /// least-squares solution, recover an exact quadric, and refuse a collinear ring.
    #[test]
    fn quadric_solve_matches_a_reference_least_squares() {
        let truth = [0.7, -0.3, 0.2, 0.05, -0.02, 0.08];
        let mut fit = QuadricFit::default();
        let mut rnd = crate::test_support::uniform(12345);
        for _ in 0..18 {
            let (x, y) = (6.0 * rnd(), 6.0 * rnd());
            fit.pts
                .push(DVec3::new(x, y, eval_quadric(&truth, x, y) + 0.3 * rnd()));
            fit.weight.push(0.5 + rnd());
        }
        fit.keep = vec![true; fit.pts.len()];
        fit.keep[3] = false;
        // Reference: weighted least squares over the kept points with nalgebra's SVD.
        let kept: Vec<usize> = (0..fit.pts.len()).filter(|&i| fit.keep[i]).collect();
        let a = nalgebra::DMatrix::from_fn(kept.len(), 6, |r, c| {
            let q = fit.pts[kept[r]];
            let w = fit.weight[kept[r]].sqrt();
            w * quadric_terms(q.x, q.y)[c]
        });
        let b = nalgebra::DVector::from_fn(kept.len(), |r, _| {
            fit.weight[kept[r]].sqrt() * fit.pts[kept[r]].z
        });
        let reference = a.svd(true, true).solve(&b, 1e-12).expect("full rank");
        let c = fit.solve_terms::<6>().expect("well conditioned");
        for i in 0..6 {
            assert!(
                (c[i] - reference[i]).abs() < 1e-9,
                "{i}: {} vs {}",
                c[i],
                reference[i]
            );
        }
        // Noise-free points: the quadric itself.
        for (q, w) in fit.pts.iter_mut().zip(&mut fit.weight) {
            q.z = eval_quadric(&truth, q.x, q.y);
            *w = 1.0;
        }
        let c = fit.solve_terms::<6>().expect("well conditioned");
        for i in 0..6 {
            assert!((c[i] - truth[i]).abs() < 1e-9);
        }
        // Points on one line cannot fix a quadric (nor a plane).
        for (i, q) in fit.pts.iter_mut().enumerate() {
            *q = DVec3::new(i as f64, 2.0 * i as f64, 1.0);
        }
        assert!(fit.solve_terms::<6>().is_none());
        assert!(fit.solve_terms::<3>().is_none());
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
