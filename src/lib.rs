//! facesynth — 3D facial expression synthesis with a layered FEM face, and its use in 3D face
//! recognition (after "3D-Facial Expression Synthesis and its Application to Face Recognition
//! Systems"). Units everywhere: millimetres, pascals, newtons.
//!
//! Module map (one paper step per file):

/// Headless command implementations behind `facesynth <command>` (main.rs only parses).
pub mod augment;
pub mod cli;
/// Surface descriptors (paper 2.1.2, Figure 7): principal curvatures, shape index, normal maps.
pub mod curvature;
/// Mesh denoising (paper 2.1.1): median + Laplacian filter moving only the largest changes; baselines.
pub mod denoise;
/// Typed errors of the library (one-line messages that name the file and the problem).
pub mod error;
/// The 13 named feature points shared by the generic face, detection and registration.
pub mod feature_points;
/// Layered hexahedral FEM face (paper section 2): element, layers, assembly, cached Cholesky,
/// muscles, expressions.
pub mod fem;
/// The project's own generic face, built by code (paper section 2, Figure 3b).
pub mod generic_face;
/// Ground truth of the synthetic GavabDB-like benchmark (../shared/bench/synth_gavab.py).
pub mod ground_truth;
/// Mesh readers and writers: VRML 1.0/2.0, OBJ, PLY, xyz point clouds.
pub mod io;
/// Automatic feature points (paper 2.1.2): the nine steps, Table 2 checks, evaluation.
pub mod landmarks;
/// The polygon mesh (positions in mm, faces as they come), topology and normals.
pub mod mesh;
/// The per-scan pipeline shared by the commands and the editor: denoise → landmarks → register.
pub mod pipeline;
/// 3D face recognition (paper sections 3–4): range images, Fisherfaces, CMC, GavabDB protocol.
pub mod recognition;
/// Registration of the generic face to a scan: Horn alignment, planar warp, cylindrical Z.
pub mod registration;
pub mod view_options;

/// The editor window: eframe app, panels, worker thread.
#[cfg(feature = "gui")]
pub mod app;
/// wgpu pipelines and the egui_wgpu callback bridge (no egui panels here).
#[cfg(feature = "gui")]
pub mod render;

pub use error::{Error, FemError, Result};
pub use feature_points::{FeaturePoint, Landmarks};
pub use mesh::Mesh;

/// Helpers shared by the unit tests.
#[cfg(test)]
pub(crate) mod test_support {
    use crate::Mesh;
    use glam::DVec3;

    /// `nx × ny` vertex grid of quads, spacing 1 mm, z = f(x, y).
    pub fn grid(nx: u32, ny: u32, f: impl Fn(f64, f64) -> f64) -> Mesh {
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

    /// A seeded uniform generator on [-0.5, 0.5) (64-bit LCG): repeatable test data without
    /// a random-number crate.
    pub fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }
}
