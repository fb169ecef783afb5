//! Face regions on the model's skin surface, placed in the face frame of its own 13 feature
//! points ([`FaceFrame`]: x between the outer eye corners, y from chin to forehead; face units
//! of half the outer-eye distance across, ≈ 48 mm, and the inner-eye-to-mouth height down,
//! ≈ 67 mm), so they land on the same anatomy on any face.
//!
//! * **Stable parts**, which expressions barely move, for the rigid alignment of an expression
//!   scan: the upper forehead (more than 0.75 face heights above the nose tip, above the brows'
//!   reach) and the nose (within 0.3 face widths of the tip, and the bridge: within 0.2 face
//!   widths of the inner-eye midpoint, the nasal bone under thin skin). The cheeks are left
//!   out although they sit on bone: a smile raises them (AU6, `cheek_raiser`).
//! * **Expression regions**, for per-region comparisons (`compare-expression`):
//!   - *mouth*: the ellipse around the mouth-corner midpoint with semi-axes 0.75 face widths
//!     (the corners sit near ±0.5) and 0.3 face heights: lips, philtrum, chin top;
//!   - *eyes*: within 0.4 face widths of each eye's centre (midpoint of its two corners) and
//!     less than 0.1 face heights above the eye line: lids and corners;
//!   - *brows*: 0.1–0.45 face heights above the eye line, within 1 face width of the midline;
//!   - *cheeks*: 0.35–1.1 face widths from the midline, from 0.1 face heights below the mouth
//!     line up to 0.15 face heights below the eye line, outside the other regions and the nose.
//!
//! A vertex lies in at most one expression region; the stable parts may overlap the brows.

use super::anchor::FaceFrame;
use crate::feature_points::FeaturePoint;
use crate::{Mesh, Result};

/// The expression regions, in report order.
pub const EXPRESSION_REGIONS: [&str; 4] = ["mouth", "cheeks", "brows", "eyes"];

/// Vertex ids (of the skin surface) per region.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Regions {
    pub forehead: Vec<usize>,
    pub nose: Vec<usize>,
    pub mouth: Vec<usize>,
    pub cheeks: Vec<usize>,
    pub brows: Vec<usize>,
    pub eyes: Vec<usize>,
}

impl Regions {
    /// The regions of `surface`, whose feature points are vertices `feature_vertices`.
    pub fn of(surface: &Mesh, feature_vertices: &[u32; FeaturePoint::COUNT]) -> Result<Self> {
        let pos = |p: FeaturePoint| surface.positions_mm[feature_vertices[p.index()] as usize];
        let frame = FaceFrame::new(pos)?;
        let (w, h) = (frame.scale_xz_mm, frame.scale_y_mm);
        let tip = pos(FeaturePoint::NoseTip);
        let mid = |a: FeaturePoint, b: FeaturePoint| (pos(a) + pos(b)) * 0.5;
        let mouth = mid(
            FeaturePoint::MouthCornerLeft,
            FeaturePoint::MouthCornerRight,
        );
        let eye_left = mid(FeaturePoint::InnerEyeLeft, FeaturePoint::OuterEyeLeft);
        let eye_right = mid(FeaturePoint::InnerEyeRight, FeaturePoint::OuterEyeRight);
        let eye_line = ((eye_left + eye_right) * 0.5).dot(frame.y);
        let mouth_line = mouth.dot(frame.y);
        let bridge = mid(FeaturePoint::InnerEyeLeft, FeaturePoint::InnerEyeRight);
        let mut out = Regions::default();
        for (v, &p) in surface.positions_mm.iter().enumerate() {
            let from_tip = p - tip;
            // The nose: its tip and wings, and the bridge up to the inner eye corners (nasal
            // bone under thin skin).
            let nose = from_tip.length() < 0.3 * w
                || ((p - bridge).length() < 0.2 * w && from_tip.dot(frame.y) > 0.0);
            if from_tip.dot(frame.y) > 0.75 * h {
                out.forehead.push(v);
            } else if nose {
                out.nose.push(v);
            }
            let m = p - mouth;
            let (mx, my) = (m.dot(frame.x) / (0.75 * w), m.dot(frame.y) / (0.3 * h));
            let above_eyes = (p.dot(frame.y) - eye_line) / h;
            let across = from_tip.dot(frame.x).abs() / w;
            let near_eye = (p - eye_left).length().min((p - eye_right).length()) < 0.4 * w;
            if mx * mx + my * my < 1.0 {
                out.mouth.push(v);
            } else if near_eye && above_eyes < 0.1 {
                out.eyes.push(v);
            } else if (0.1..0.45).contains(&above_eyes) && across < 1.0 {
                out.brows.push(v);
            } else if !nose
                && (0.35..1.1).contains(&across)
                && p.dot(frame.y) > mouth_line - 0.1 * h
                && above_eyes < -0.15
            {
                out.cheeks.push(v);
            }
        }
        Ok(out)
    }

    /// The stable parts together (forehead, then nose).
    pub fn stable(&self) -> Vec<usize> {
        self.forehead.iter().chain(&self.nose).copied().collect()
    }

    /// An expression region by name ([`EXPRESSION_REGIONS`]).
    pub fn expression_region(&self, name: &str) -> Option<&[usize]> {
        match name {
            "mouth" => Some(&self.mouth),
            "cheeks" => Some(&self.cheeks),
            "brows" => Some(&self.brows),
            "eyes" => Some(&self.eyes),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On the generic face each region holds the feature points it is named after, and lies
    /// where anatomy puts it: the mouth below the nose, the brows above the eyes, the cheeks
    /// on both sides.
    #[test]
    fn regions_hold_their_feature_points_on_the_generic_face() {
        let face = crate::generic_face::build();
        let r = Regions::of(&face.mesh, &face.feature_vertices).unwrap();
        let vertex = |p: FeaturePoint| face.feature_vertices[p.index()] as usize;
        for p in [
            FeaturePoint::MouthCornerLeft,
            FeaturePoint::MouthCornerRight,
        ] {
            assert!(r.mouth.contains(&vertex(p)), "{p:?}");
        }
        for p in [
            FeaturePoint::InnerEyeLeft,
            FeaturePoint::InnerEyeRight,
            FeaturePoint::OuterEyeLeft,
            FeaturePoint::OuterEyeRight,
        ] {
            assert!(r.eyes.contains(&vertex(p)), "{p:?}");
        }
        assert!(r.nose.contains(&vertex(FeaturePoint::NoseTip)));
        let y = |vs: &[usize]| {
            vs.iter().map(|&v| face.mesh.positions_mm[v].y).sum::<f64>() / vs.len() as f64
        };
        assert!(y(&r.brows) > y(&r.eyes) && y(&r.eyes) > y(&r.mouth));
        assert!(y(&r.forehead) > y(&r.brows));
        let left = r
            .cheeks
            .iter()
            .filter(|&&v| face.mesh.positions_mm[v].x > 0.0)
            .count();
        let right = r.cheeks.len() - left;
        assert!(left > 20 && right > 20, "{left} {right}");
        // Disjoint expression regions.
        let mut all: Vec<usize> = EXPRESSION_REGIONS
            .iter()
            .flat_map(|n| r.expression_region(n).unwrap().to_vec())
            .collect();
        let n = all.len();
        all.sort_unstable();
        all.dedup();
        assert_eq!(all.len(), n);
    }
}
