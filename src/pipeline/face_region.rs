//! How closely the registered generic face lies on the scan inside the face proper, per face
//! region (`fem::regions`), apart from where hair and the scan's edge leave filled vertices by
//! design (`register`'s `face_region_distance_mm`).

use super::PreparedScan;
use crate::Result;
use crate::feature_points::FeaturePoint;
use crate::registration::DistanceStats;
use serde_json::json;

impl PreparedScan {
    /// The registered face's distance to the scan (`registration.vertex_distance_mm`) per face
    /// region of the generic face (feature vertices `feature_vertices`). The forehead is cut
    /// at the scan's own forehead point (the detector's hairline, where smooth skin ends; the
    /// registered generic's forehead vertex is not moved onto it, a border point) and at the
    /// temples (between the outer eye corners, beyond which hair often covers the scan); the
    /// rest of it is reported apart as `above_hairline_or_temples`.
    pub fn face_region_report(
        &self,
        feature_vertices: &[u32; FeaturePoint::COUNT],
    ) -> Result<serde_json::Value> {
        let reg = &self.registration;
        let mesh = &reg.mesh;
        let regions = crate::fem::regions::Regions::of(mesh, feature_vertices)?;
        let lm = &self.landmarks;
        let hairline = lm.get(FeaturePoint::Forehead);
        let up = (hairline - lm.get(FeaturePoint::Chin)).normalize_or_zero();
        let (left, right) = (
            lm.get(FeaturePoint::OuterEyeLeft),
            lm.get(FeaturePoint::OuterEyeRight),
        );
        let across = (left - right).normalize_or_zero();
        let mid = (left + right) * 0.5;
        let half_width = (left - mid).length();
        let (forehead, hair): (Vec<usize>, Vec<usize>) = regions.forehead.iter().partition(|&&v| {
            let p = mesh.positions_mm[v];
            (p - hairline).dot(up) <= 0.0 && (p - mid).dot(across).abs() <= half_width
        });
        let stats = |vs: &[usize]| {
            let d: Vec<f64> = vs.iter().map(|&v| reg.vertex_distance_mm[v]).collect();
            let mut out = json!(DistanceStats::of(&d).rounded());
            out["vertices"] = json!(vs.len());
            out
        };
        let parts: [(&str, &[usize]); 6] = [
            ("forehead", &forehead),
            ("brows", &regions.brows),
            ("eyes", &regions.eyes),
            ("nose", &regions.nose),
            ("cheeks", &regions.cheeks),
            ("mouth", &regions.mouth),
        ];
        let mut face: Vec<usize> = parts
            .iter()
            .flat_map(|(_, vs)| vs.iter().copied())
            .collect();
        face.sort_unstable();
        face.dedup();
        let mut value = stats(&face);
        // Inside the face a miss is a real gap; above the hairline it is expected.
        value["unmatched_by_reason"] = json!(reg.unmatched_by_reason(Some(&face)));
        for (name, vs) in parts {
            value["by_region"][name] = stats(vs);
        }
        value["above_hairline_or_temples"] = stats(&hair);
        Ok(value)
    }
}
