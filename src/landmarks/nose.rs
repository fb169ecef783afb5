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

/// The paper's bound on the in-plane slope `∇xy` (the fitted normal's component across the
/// view) of the nose tip's region, dimensionless: the surface there faces the viewer within
/// 14.5°.
pub const NOSE_TIP_MAX_SLOPE: f64 = 0.25;

/// The tip's region keeps to this distance from the highest point, mm: about half the height
/// of the nose's lobule, so that a flat dorsum or a cheek reached through a flat lobule side
/// does not join it.
pub const NOSE_TIP_REACH_MM: f64 = 6.0;

impl Detector<'_> {
    /// Step 2: the most protruding face vertex, refined to the centroid of the flat region
    /// around the local height maximum; returns the tip and the region vertex nearest it.
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
        // The paper's tip: the centroid of the region around the highest point whose in-plane
        // slope is small. On a nose the lobule curves gently up into the dorsum and sharply
        // down into the columella, so this centroid sits above the highest point.
        let t = self.p(top);
        let mut mask = vec![false; self.mesh.vertex_count()];
        for &v in &near {
            let n = self.desc.normal[v];
            mask[v] = n.z > 0.0
                && n.truncate().length() < NOSE_TIP_MAX_SLOPE
                && (self.p(v) - t).length() < NOSE_TIP_REACH_MM;
        }
        mask[top] = true;
        let region = self.region_of(top, &mask);
        Ok((self.centroid(&region), self.centroid_vertex(&region)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::landmarks::detector::TestSurface;
    use crate::test_support::grid;

    /// A nose on a flat face (z = 0, facing +z): a dome 20 mm high, round across (radius of
    /// curvature 10 mm) and lopsided along the face: 30 mm radius above its apex (the lobule
    /// running into the dorsum), 8 mm below it (into the columella). Its `∇xy < 0.25` region
    /// is two half-ellipses, 7.5 mm up and 2 mm down, 2.5 mm across; their centroid lies
    /// 4/(3π) · (7.5 − 2) = 2.3 mm above the apex. The highest point (the tip before) is the
    /// apex itself.
    #[test]
    fn the_nose_tip_is_the_centroid_of_the_flat_region_around_the_apex() {
        let apex = DVec2::new(40.0, 50.0);
        let surface = TestSurface::new(grid(81, 101, |x, y| {
            let (dx, dy) = (x - apex.x, y - apex.y);
            let r = if dy > 0.0 { 30.0 } else { 8.0 };
            (20.0 - dx * dx / 20.0 - dy * dy / (2.0 * r)).max(0.0)
        }));
        let face = vec![true; surface.mesh.vertex_count()];
        let (tip, _) = surface.detector().nose_tip(&face).unwrap();
        let expected = 4.0 / (3.0 * std::f64::consts::PI) * (7.5 - 2.0);
        assert!(
            (tip.x - apex.x).abs() < 0.3 && (tip.y - apex.y - expected).abs() < 0.6,
            "tip at ({:.2}, {:.2}) from the apex, expected (0, {expected:.2})",
            tip.x - apex.x,
            tip.y - apex.y
        );
    }
}
