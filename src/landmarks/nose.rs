//! Step 2: the nose tip.

use super::detector::Detector;
use super::frame::DepthGrid;
use crate::{Error, Result};
use glam::{DVec2, DVec3};

/// After face localisation, step 2 looks for the tip within this distance (across the view) of
/// where the generic face's tip landed, mm. The rigid fit of an average face places its tip
/// within ~20 mm of a real one (faces differ in size and nose shape); a chin, collar or
/// shoulder that protrudes like a nose lies 60 mm or more away.
pub const NOSE_PRIOR_REACH_MM: f64 = 30.0;

impl Detector<'_> {
    /// Step 2: the most protruding face vertex, refined to the local height maximum.
    pub(super) fn nose_tip(&self, face: &[bool]) -> Result<(DVec3, usize)> {
        const CELL: f64 = 3.0;
        let pts: Vec<usize> = (0..face.len()).filter(|&v| face[v]).collect();
        let (mut lo, mut hi) = (DVec2::splat(f64::MAX), DVec2::splat(f64::MIN));
        for &v in &pts {
            lo = lo.min(self.p(v).truncate());
            hi = hi.max(self.p(v).truncate());
        }
        let nx = ((hi.x - lo.x) / CELL) as usize + 1;
        let ny = ((hi.y - lo.y) / CELL) as usize + 1;
        let grid = DepthGrid::new(lo, CELL, nx, ny, pts.iter().map(|&v| self.p(v)));
        const DIRS: usize = 16;
        let r = self.params.nose_probe_radius_mm;
        let circle: Vec<DVec2> = (0..DIRS)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / DIRS as f64;
                DVec2::new(a.cos(), a.sin()) * r
            })
            .collect();
        let mut best: Option<(f64, usize)> = None;
        for &v in &pts {
            if self.desc.shape_index[v] < 0.5
                || self
                    .prior_nose
                    .is_some_and(|tip| (self.p(v) - tip).truncate().length() > NOSE_PRIOR_REACH_MM)
            {
                continue;
            }
            let p = self.p(v);
            let (mut s, mut c) = (0.0, 0);
            for d in &circle {
                if let Some(h) = grid.at(p.truncate() + *d) {
                    s += h;
                    c += 1;
                }
            }
            if c * 8 < DIRS * 5 {
                continue;
            }
            let score = p.z - s / c as f64;
            if best.is_none_or(|(b, _)| score > b) {
                best = Some((score, v));
            }
        }
        let (score, coarse) = best.ok_or_else(|| {
            Error::algorithm(
                "landmarks: nose tip",
                "no convex face vertex with enough face around it",
            )
        })?;
        if score < 8.0 {
            return Err(Error::algorithm(
                "landmarks: nose tip",
                format!(
                    "nothing protrudes like a nose (best {score:.1} mm above its surroundings)"
                ),
            ));
        }
        let c = self.p(coarse);
        let near: Vec<usize> = pts
            .iter()
            .copied()
            .filter(|&v| (self.p(v) - c).truncate().length() <= 10.0)
            .collect();
        let top = near
            .iter()
            .copied()
            .max_by(|&a, &b| self.p(a).z.total_cmp(&self.p(b).z))
            .unwrap_or(coarse);
        let zmax = self.p(top).z;
        let cap: Vec<DVec3> = near
            .iter()
            .map(|&v| self.p(v))
            .filter(|p| p.z >= zmax - 0.3 && (*p - self.p(top)).length() < 4.0)
            .collect();
        let tip = cap.iter().sum::<DVec3>() / cap.len() as f64;
        Ok((tip, top))
    }
}
