//! The project's own generic face (paper section 2, Figure 3b), built by code.
//! TODO(#2): build the real face.

use crate::feature_points::{FeaturePoint, Landmarks};
use crate::{Mesh, Result};
use std::path::Path;

/// A generic face: a quad-dominant surface (mm, looking towards +z, y up, nose tip near the
/// origin) and the vertex id of each of the 13 feature points.
#[derive(Debug, Clone)]
pub struct GenericFace {
    pub mesh: Mesh,
    /// Vertex id of each feature point, in [`FeaturePoint::ALL`] order.
    pub feature_vertices: [u32; FeaturePoint::COUNT],
}

impl GenericFace {
    /// The feature points' positions.
    pub fn landmarks(&self) -> Landmarks {
        Landmarks(
            self.feature_vertices
                .map(|v| self.mesh.positions_mm[v as usize]),
        )
    }

    pub fn feature_vertex(&self, p: FeaturePoint) -> u32 {
        self.feature_vertices[p.index()]
    }
}

/// Builds the default generic face.
pub fn build() -> GenericFace {
    todo!("generic face")
}

/// Loads a user's generic model: an OBJ plus a sidecar naming the 13 feature-point vertex ids.
pub fn load(_obj: &Path, _sidecar: &Path) -> Result<GenericFace> {
    todo!("custom generic face")
}
