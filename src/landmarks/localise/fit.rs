//! The generic face's fit to a candidate: iterated closest points, point-to-point (Horn) then
//! point-to-plane with an isotropic scale; closest scan vertices through a grid; the
//! face-likeness score.

use super::*;

/// One stage of the fit: at most `iterations`, pairs farther apart than `trim_mm` dropped,
/// and the distance minimised.
#[derive(Debug, Clone, Copy)]
pub(super) struct IcpStage {
    pub(super) iterations: usize,
    pub(super) trim_mm: f64,
    /// Point-to-plane (along the template's normals, one Gauss–Newton step per iteration)
    /// rather than point-to-point (Horn's closed form). Point-to-point is the robust start: its
    /// pairs hold the template back where the face differs from the average. Point-to-plane
    /// then lets it slide along the surface into place (on the generic face itself,
    /// point-to-point alone stopped 3.5 mm short after 18 iterations).
    pub(super) plane: bool,
}

impl IcpStage {
    /// A point-to-point stage.
    pub(super) const fn points(iterations: usize, trim_mm: f64) -> Self {
        IcpStage {
            iterations,
            trim_mm,
            plane: false,
        }
    }

    /// A point-to-plane stage.
    pub(super) const fn plane(iterations: usize, trim_mm: f64) -> Self {
        IcpStage {
            iterations,
            trim_mm,
            plane: true,
        }
    }
}

/// The template's pose in the scan: `p ↦ scale · rot · p + shift` (rot: scan from face; shift:
/// where the template's origin, its nose tip, lies).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Pose {
    pub(super) rot: DMat3,
    pub(super) scale: f64,
    pub(super) shift: DVec3,
}

impl Pose {
    pub(super) fn apply(&self, g: DVec3) -> DVec3 {
        self.scale * (self.rot * g) + self.shift
    }
}

/// Faces differ in size from the generic one by about ±10 % (outer eye corners 82–96 mm on
/// the benchmark, 96 on the generic face): the fit scales the template within these bounds, so
/// that a small or large face is not fitted by sliding or turning an average-sized template.
pub(super) const SCALE_RANGE: (f64, f64) = (0.8, 1.25);

/// ICP of `template` (face frame) onto the scan from `pose`, stage by stage; rotation,
/// translation and an isotropic scale (within [`SCALE_RANGE`]). `None` when fewer than 30
/// points pair up.
pub(super) fn icp(
    index: &impl Closest,
    template: &[(DVec3, DVec3)],
    mut pose: Pose,
    schedule: &[IcpStage],
) -> Option<Pose> {
    let mut pairs: Vec<(DVec3, DVec3, DVec3)> = Vec::new();
    for stage in schedule {
        for _ in 0..stage.iterations {
            pairs.clear();
            for &(g, n) in template {
                if let Some((_, c)) = index.closest(pose.apply(g), stage.trim_mm) {
                    pairs.push((g, n, c));
                }
            }
            if pairs.len() < 30 {
                return None;
            }
            let mut new = if stage.plane {
                point_to_plane_step(&pairs, pose)?
            } else {
                let from: Vec<DVec3> = pairs.iter().map(|p| p.0).collect();
                let to: Vec<DVec3> = pairs.iter().map(|p| p.2).collect();
                let fit = horn_absolute_orientation(&from, &to, true).ok()?;
                Pose {
                    rot: fit.rotation_matrix(),
                    scale: fit.scale,
                    shift: fit.translation_mm,
                }
            };
            new.scale = new.scale.clamp(SCALE_RANGE.0, SCALE_RANGE.1);
            let moved = (new.shift - pose.shift).length();
            // Trace of the rotation between the two: 3 for none.
            let trace = (new.rot.transpose() * pose.rot).to_cols_array()[..]
                .iter()
                .step_by(4)
                .sum::<f64>();
            let rescaled = (new.scale - pose.scale).abs();
            pose = new;
            // Converged: under 0.01 mm, ~0.003° and 1e-5 in scale in this iteration.
            if moved < 0.01 && trace > 3.0 - 2e-9 && rescaled < 1e-5 {
                break;
            }
        }
    }
    Some(pose)
}

/// One Gauss–Newton step on the point-to-plane distances of `pairs` (template point, its
/// normal, scan point), for a small motion about the current nose tip:
/// p' = p + ω × (p − shift) + σ (p − shift) + t.
pub(super) fn point_to_plane_step(pairs: &[(DVec3, DVec3, DVec3)], pose: Pose) -> Option<Pose> {
    use nalgebra::{SMatrix, SVector};
    /// Largest turn, shift and relative scale change of one step: the linearisation holds for
    /// small motions.
    const MAX_STEP_RAD: f64 = 0.15;
    const MAX_SHIFT_MM: f64 = 10.0;
    const MAX_SCALE_STEP: f64 = 0.05;
    let mut ata = SMatrix::<f64, 7, 7>::zeros();
    let mut atb = SVector::<f64, 7>::zeros();
    for &(g, n, c) in pairs {
        let p = pose.apply(g);
        let m = pose.rot * n;
        let r = p - pose.shift;
        let a = r.cross(m);
        let row = SVector::<f64, 7>::from([a.x, a.y, a.z, m.x, m.y, m.z, r.dot(m)]);
        ata += row * row.transpose();
        atb -= row * (p - c).dot(m);
    }
    // A little damping: a flat patch leaves the sliding directions unconstrained.
    let damping = 1e-6 * ata.trace() + 1e-9;
    for k in 0..7 {
        ata[(k, k)] += damping;
    }
    let x = ata.lu().solve(&atb)?;
    let mut omega = DVec3::new(x[0], x[1], x[2]);
    let mut t = DVec3::new(x[3], x[4], x[5]);
    let sigma = x[6].clamp(-MAX_SCALE_STEP, MAX_SCALE_STEP);
    if !(omega.is_finite() && t.is_finite() && sigma.is_finite()) {
        return None;
    }
    if omega.length() > MAX_STEP_RAD {
        omega *= MAX_STEP_RAD / omega.length();
    }
    if t.length() > MAX_SHIFT_MM {
        t *= MAX_SHIFT_MM / t.length();
    }
    let angle = omega.length();
    let turn = if angle > 0.0 {
        DMat3::from_axis_angle(omega / angle, angle)
    } else {
        DMat3::IDENTITY
    };
    Some(Pose {
        rot: turn * pose.rot,
        scale: pose.scale * (1.0 + sigma),
        shift: pose.shift + t,
    })
}

/// The closest scan point within a distance: (distance, point).
pub(super) trait Closest {
    fn closest(&self, p: DVec3, max_mm: f64) -> Option<(f64, DVec3)>;
}

impl Closest for SurfaceIndex {
    fn closest(&self, p: DVec3, max_mm: f64) -> Option<(f64, DVec3)> {
        SurfaceIndex::closest(self, p, max_mm)
    }
}

/// Cell of [`VertexGrid`], mm: about two scanner samples.
pub(super) const VERTEX_GRID_CELL_MM: f64 = 3.0;

/// Nearest scan *vertex* through a uniform grid: the candidates' coarse fits pair with vertices
/// (a sample spacing of 1.5–3 mm moves a pair by under 1.5 mm, which a coarse fit does not
/// notice) at a tenth of the cost of the exact point-on-triangle search; the winner is refitted
/// and scored on the surface.
pub(super) struct VertexGrid<'a> {
    pub(super) points: &'a [DVec3],
    pub(super) lo: DVec3,
    pub(super) cell: f64,
    pub(super) dims: [usize; 3],
    /// Vertex ids sorted by cell; `start[c]..start[c + 1]` are cell `c`'s.
    pub(super) start: Vec<u32>,
    pub(super) ids: Vec<u32>,
}

impl<'a> VertexGrid<'a> {
    pub(super) fn new(points: &'a [DVec3], cell_mm: f64) -> Self {
        let (lo, hi) = bounds(points).unwrap_or((DVec3::ZERO, DVec3::ZERO));
        // Cells grow until there are at most ~8 per point (a far-off stray point would
        // otherwise ask for a huge grid).
        let mut cell = cell_mm;
        let count = |c: f64| [0, 1, 2].map(|k| ((hi[k] - lo[k]) / c) as usize + 1);
        while count(cell).iter().product::<usize>() > 8 * points.len().max(512) {
            cell *= 2.0;
        }
        let dims = count(cell);
        let mut grid = VertexGrid {
            points,
            lo,
            cell,
            dims,
            start: vec![0; dims[0] * dims[1] * dims[2] + 1],
            ids: vec![0; points.len()],
        };
        let cells: Vec<usize> = points.iter().map(|&p| grid.cell_of(p)).collect();
        for &c in &cells {
            grid.start[c + 1] += 1;
        }
        for c in 1..grid.start.len() {
            grid.start[c] += grid.start[c - 1];
        }
        let mut fill = grid.start.clone();
        for (v, &c) in cells.iter().enumerate() {
            grid.ids[fill[c] as usize] = v as u32;
            fill[c] += 1;
        }
        grid
    }

    pub(super) fn index(&self, p: DVec3) -> [i64; 3] {
        [0, 1, 2].map(|k| ((p[k] - self.lo[k]) / self.cell).floor() as i64)
    }

    pub(super) fn cell_of(&self, p: DVec3) -> usize {
        let i = self.index(p);
        let c = [0, 1, 2].map(|k| i[k].clamp(0, self.dims[k] as i64 - 1) as usize);
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }
}

impl Closest for VertexGrid<'_> {
    fn closest(&self, p: DVec3, max_mm: f64) -> Option<(f64, DVec3)> {
        let reach = (max_mm / self.cell).ceil() as i64;
        let centre = self.index(p);
        let mut best: Option<(f64, DVec3)> = None;
        // Shells of cells outwards; stop once the next shell is farther than the best.
        for r in 0..=reach {
            if best.is_some_and(|(d, _)| d <= (r - 1).max(0) as f64 * self.cell) {
                break;
            }
            let lo = [0, 1, 2].map(|k| (centre[k] - r).max(0));
            let hi = [0, 1, 2].map(|k| (centre[k] + r).min(self.dims[k] as i64 - 1));
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let shell = [x, y, z]
                            .iter()
                            .zip(centre)
                            .any(|(&a, c)| (a - c).abs() == r);
                        if !shell {
                            continue;
                        }
                        let c =
                            (z as usize * self.dims[1] + y as usize) * self.dims[0] + x as usize;
                        for &v in &self.ids[self.start[c] as usize..self.start[c + 1] as usize] {
                            let q = self.points[v as usize];
                            let d = q.distance(p);
                            if d <= max_mm && best.is_none_or(|(b, _)| d < b) {
                                best = Some((d, q));
                            }
                        }
                    }
                }
            }
        }
        best
    }
}

/// Face-likeness (the fraction of `template` within `inlier_mm` of the scan) and the RMS
/// distance of those points, mm.
pub(super) fn score(
    index: &impl Closest,
    template: &[(DVec3, DVec3)],
    pose: Pose,
    inlier_mm: f64,
) -> (f64, f64) {
    let (mut inliers, mut sum2) = (0usize, 0.0);
    for &(g, _) in template {
        if let Some((d, _)) = index.closest(pose.apply(g), inlier_mm) {
            inliers += 1;
            sum2 += d * d;
        }
    }
    let rms = if inliers > 0 {
        (sum2 / inliers as f64).sqrt()
    } else {
        f64::NAN
    };
    (inliers as f64 / template.len().max(1) as f64, rms)
}
