//! The descriptors' neighbourhood in millimetres: the shape index and the normal maps the steps
//! read come from a quadric fitted over the rings of each vertex ([`crate::curvature`]), and a
//! ring is one sample wide, so the rings are set from the face's sampling: the same surface
//! sampled twice as densely gets twice the rings ([`LandmarkParams::curvature_for`]).
//! Departure from the paper: it fits a fixed neighbourhood on its one scanner's grid.

use super::LandmarkParams;
use crate::curvature::CurvatureParams;
use crate::mesh::Mesh;

/// The sampling that sets the descriptors' rings is measured on the edges within this distance
/// of the located nose tip, mm: the nose, eyes, cheeks and mouth, short of the chin and the
/// forehead (70–80 mm away), so that a torso or a hair cap sampled otherwise does not count.
pub const SPACING_RADIUS_MM: f64 = 60.0;

/// The median length of the edges of `mesh` with both ends within [`SPACING_RADIUS_MM`] of
/// `around`, mm; of all edges where `around` is `None` or no edge lies there (0 without edges).
pub fn face_spacing_mm(mesh: &Mesh, around: Option<glam::DVec3>) -> f64 {
    let near = |v: u32| {
        around.is_none_or(|c| mesh.positions_mm[v as usize].distance(c) <= SPACING_RADIUS_MM)
    };
    match crate::mesh::simplify::median_edge_mm_where(mesh, near) {
        0.0 if around.is_some() => crate::mesh::simplify::median_edge_mm(mesh),
        spacing_mm => spacing_mm,
    }
}

/// The descriptors' quadric fit takes at least this many rings ([`LandmarkParams::curvature_for`]):
/// fewer give too few neighbours to fit a quadric to noisy samples.
pub const MIN_DESCRIPTOR_RINGS: usize = 2;
/// ... and at most this many: the cost grows with the square of the rings, so scans sampled
/// finer than reach / 16 (0.6 mm at the default reach) get a shorter reach.
pub const MAX_DESCRIPTOR_RINGS: usize = 16;

/// The sampling the descriptors were fitted on, for the report (`descriptors` in the JSON).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DescriptorSampling {
    /// The median edge length [`LandmarkParams::curvature_for`] measured, mm.
    pub spacing_mm: f64,
    /// The rings of the quadric fit.
    pub rings: usize,
}

impl LandmarkParams {
    /// The descriptor settings for `mesh`: [`Self::curvature`] with its rings set from
    /// [`Self::descriptor_reach_mm`] and the median length of the edges within
    /// [`SPACING_RADIUS_MM`] of `around` (the located nose tip; the whole mesh where `None` or
    /// where no edge lies there), within [`MIN_DESCRIPTOR_RINGS`]..=[`MAX_DESCRIPTOR_RINGS`].
    /// The same surface sampled twice as densely gets twice the rings (measured on the 34
    /// real scans split 1 → 4 and clustered at 3 mm: docs/measurements.md, "descriptor reach
    /// in millimetres").
    pub fn curvature_for(&self, mesh: &Mesh, around: Option<glam::DVec3>) -> CurvatureParams {
        self.curvature_with(self.descriptor_sampling(mesh, around))
    }

    /// [`Self::curvature`] with the rings of `sampling`.
    pub fn curvature_with(&self, sampling: DescriptorSampling) -> CurvatureParams {
        CurvatureParams {
            rings: sampling.rings,
            ..self.curvature
        }
    }

    /// The spacing and the rings [`Self::curvature_for`] takes.
    pub fn descriptor_sampling(
        &self,
        mesh: &Mesh,
        around: Option<glam::DVec3>,
    ) -> DescriptorSampling {
        let spacing_mm = face_spacing_mm(mesh, around);
        let rings = match self.descriptor_reach_mm {
            Some(reach_mm) if spacing_mm > 0.0 => (reach_mm / spacing_mm)
                .round()
                .clamp(MIN_DESCRIPTOR_RINGS as f64, MAX_DESCRIPTOR_RINGS as f64)
                as usize,
            _ => self.curvature.rings,
        };
        DescriptorSampling { spacing_mm, rings }
    }
}
