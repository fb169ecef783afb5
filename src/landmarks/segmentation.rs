//! Step 1: facial segmentation.

use super::detector::Detector;
use crate::{Error, Result};
use glam::DVec2;

/// Paper step 1: vertices with `|∂/∂z|` below this face away from the scanner.
pub const FACE_MIN_DZ: f64 = 0.5;
/// Our step 1: a front-facing region of at least this many vertices that the largest one
/// surrounds (face vertices left, right, above and below its centroid, within
/// [`ENCLOSED_ISLAND_BAND_MM`] of its row / column) is part of the face.
pub const ENCLOSED_ISLAND_MIN_VERTICES: usize = 20;
pub const ENCLOSED_ISLAND_BAND_MM: f64 = 3.0;
/// Our step 1 after face localisation ([`super::localise`]): only vertices inside an ellipse
/// about the located nose tip (in the face frame) can be face, so a torso, collar or shoulder
/// cannot be the largest region. Semi-axes 80 mm across (beyond the cheek borders, ~65 mm;
/// short of the ears) and 105 mm up and down about a centre 5 mm above the tip (chin −71 mm
/// and hairline up to ~+100 mm, Table 2 plus margins).
pub const FACE_REGION_SEMI_X_MM: f64 = 80.0;
pub const FACE_REGION_SEMI_Y_MM: f64 = 105.0;
pub const FACE_REGION_CENTRE_Y_MM: f64 = 5.0;

impl Detector<'_> {
    /// Step 1: the largest connected region facing the scanner.
    pub(super) fn segment_face(&self) -> Result<Vec<bool>> {
        let near_prior = |v: usize| {
            self.prior_nose.is_none_or(|tip| {
                let d = self.p(v) - tip;
                (d.x / FACE_REGION_SEMI_X_MM).powi(2)
                    + ((d.y - FACE_REGION_CENTRE_Y_MM) / FACE_REGION_SEMI_Y_MM).powi(2)
                    <= 1.0
            })
        };
        let mask: Vec<bool> = (0..self.mesh.vertex_count())
            .map(|v| self.desc.dz(v) >= FACE_MIN_DZ && self.desc.normal[v].z > 0.0 && near_prior(v))
            .collect();
        // The regions once: the largest is the face, some others may join it below.
        let regions = self.regions(&mask);
        let (biggest, face) = regions
            .iter()
            .enumerate()
            .max_by_key(|(_, r)| r.len())
            .ok_or_else(|| {
                Error::algorithm(
                    "landmarks: facial segmentation",
                    "no vertex faces the scanner (+z); is the scan in its scanner frame?",
                )
            })?;
        if face.len() < 200 {
            return Err(Error::algorithm(
                "landmarks: facial segmentation",
                format!(
                    "the largest front-facing region has only {} vertices",
                    face.len()
                ),
            ));
        }
        let mut out = vec![false; mask.len()];
        for &v in face {
            out[v as usize] = true;
        }
        // Front-facing islands the face surrounds belong to it: a hole on the nose bridge
        // and the steep sides of the nose can cut the whole nose off the largest region
        // (seen on the benchmark: the tip was then sought on the hole's rim, 39 mm off).
        // Hair islands above the forehead and pieces of the ears are not surrounded.
        let pts: Vec<DVec2> = face
            .iter()
            .map(|&v| self.p(v as usize).truncate())
            .collect();
        for (k, region) in regions.iter().enumerate() {
            if k == biggest || region.len() < ENCLOSED_ISLAND_MIN_VERTICES {
                continue;
            }
            let c = region
                .iter()
                .map(|&v| self.p(v as usize).truncate())
                .sum::<DVec2>()
                / region.len() as f64;
            let band = ENCLOSED_ISLAND_BAND_MM;
            let side = |f: &dyn Fn(DVec2) -> bool| pts.iter().any(|&q| f(q - c));
            let enclosed = side(&|d| d.x < 0.0 && d.y.abs() < band)
                && side(&|d| d.x > 0.0 && d.y.abs() < band)
                && side(&|d| d.y < 0.0 && d.x.abs() < band)
                && side(&|d| d.y > 0.0 && d.x.abs() < band);
            if enclosed {
                for &v in region {
                    out[v as usize] = true;
                }
            }
        }
        Ok(out)
    }
}
