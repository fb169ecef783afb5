//! The face frame's roll (step 3): the face's bilateral symmetry line, and the inner-eye
//! line where there is none.

use super::detector::Detector;
use super::frame::DepthGrid;
use glam::{DVec2, DVec3};

impl Detector<'_> {
    /// The roll bilateral symmetry tells: the face's depth, averaged on a 2 mm grid around
    /// the nose tip, is mirrored about lines through the tip at rolls within ±25° and offsets
    /// within ±4 mm; the roll whose mirror matches best (least mean squared Δz over the cells
    /// both sides have, at least half of them, after removing the part linear in the distance
    /// from the line, which a turned head adds) wins. Searched coarse (3°, 2 mm) then fine (0.5°,
    /// 1 mm) around the best. `None` where too little of the face overlaps its mirror (a
    /// head turned ~90°). It reads the roll better than the detected inner corners do
    /// (docs/measurements.md).
    pub(super) fn symmetry_roll(&self, face: &[bool], tip: DVec3) -> Option<f64> {
        const CELL: f64 = 2.0;
        const HALF_W: f64 = 50.0;
        const DOWN: f64 = 60.0;
        const UP: f64 = 50.0;
        let grid = DepthGrid::new(
            DVec2::new(-HALF_W, -DOWN),
            CELL,
            (2.0 * HALF_W / CELL) as usize,
            ((DOWN + UP) / CELL) as usize,
            face.iter()
                .enumerate()
                .filter(|(_, f)| **f)
                .map(|(v, _)| self.p(v) - tip),
        );
        let filled: Vec<(DVec2, f64)> = grid.filled().collect();
        let score = |roll_deg: f64, offset_mm: f64, stride: usize| -> Option<f64> {
            let roll = roll_deg.to_radians();
            let u = DVec2::new(roll.cos(), roll.sin());
            // A turned head (yaw) adds a term linear in the distance from the mirror line to
            // every difference; it is fitted and removed, or a yaw of 10° read as a roll of 12°.
            let (mut dd, mut ds, mut ss, mut n) = (0.0, 0.0, 0.0, 0usize);
            for &(c, z) in filled.iter().step_by(stride) {
                let side = c.dot(u) - offset_mm;
                let m = c - 2.0 * side * u;
                if let Some(zm) = grid.at(m) {
                    let d = (z - zm).clamp(-10.0, 10.0);
                    dd += d * d;
                    ds += d * side;
                    ss += side * side;
                    n += 1;
                }
            }
            let yaw_part = if ss > 0.0 { ds * ds / ss } else { 0.0 };
            (n * 2 * stride >= filled.len()).then(|| ((dd - yaw_part) / n as f64).max(0.0))
        };
        let search = |rolls: &mut dyn Iterator<Item = f64>, offsets: &[f64], stride: usize| {
            let mut best: Option<(f64, f64, f64)> = None;
            for roll in rolls {
                for &o in offsets {
                    if let Some(s) = score(roll, o, stride)
                        && best.is_none_or(|(b, _, _)| s < b)
                    {
                        best = Some((s, roll, o));
                    }
                }
            }
            best
        };
        // Coarse on every other cell, then fine on all (the search is ~5 % of detection).
        let (_, roll, offset) = search(
            &mut (-8..=8).map(|k| k as f64 * 3.0),
            &[-4.0, -2.0, 0.0, 2.0, 4.0],
            2,
        )?;
        let fine: Vec<f64> = [-1.0, 0.0, 1.0].iter().map(|d| offset + d).collect();
        let (_, roll, _) = search(&mut (-3..=3).map(|k| roll + k as f64 * 0.5), &fine, 1)?;
        Some(roll.to_radians())
    }

    /// Angle of the line from the right to the left inner eye corner from +x, radians.
    pub(super) fn eye_line_roll(&self, right: usize, left: usize) -> f64 {
        let d = (self.p(left) - self.p(right)).truncate();
        d.y.atan2(d.x)
    }
}
