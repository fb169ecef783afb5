//! The lid fissure as a trench in the depth relief, shared by the refinements of steps 3
//! (inner eye corners) and 4 (outer eye corners); step 6 (mouth corners) follows the lips'
//! fissure through the same relief.

use super::detector::Detector;
use super::frame::{Frame, UvBox};
use glam::DVec2;

/// Scale of the surroundings an inner eye corner's lid fissure is a trench in (σ of the
/// Gaussian weights, mm).
pub const FISSURE_SMOOTHING_MM: f64 = 2.0;

impl Detector<'_> {
    /// Vertices relative to `near` in the face frame, x lateral (away from the midline on
    /// `side`), y up, mm.
    pub(super) fn lateral_from<'a>(
        &'a self,
        frame: &'a Frame,
        near: usize,
        side: f64,
    ) -> impl Fn(usize) -> DVec2 + 'a {
        let origin = frame.uv(self.p(near));
        move |v| {
            let q = frame.uv(self.p(v)) - origin;
            DVec2::new(q.x * side, q.y)
        }
    }

    /// Relief around `near`: every vertex in the box (mm from `near`, [`Self::lateral_from`]:
    /// lateral from, lateral to, down, up) with its position relative to `near` and its depth
    /// relative to the Gaussian-weighted mean depth of its surroundings (σ =
    /// [`FISSURE_SMOOTHING_MM`], so a face's own curvature and fall-off cancel), mm; `None`
    /// beside a hole, whose surroundings are one-sided.
    pub(super) fn relief_around(
        &self,
        frame: &Frame,
        near: usize,
        side: f64,
        (lat_from, lat_to, down, up): (f64, f64, f64, f64),
    ) -> Vec<Relief> {
        let search = UvBox {
            u: (lat_from, lat_to),
            v: (-down, up),
        };
        let reach = 3.0 * FISSURE_SMOOTHING_MM;
        let surroundings = search.grown(reach);
        let rel = self.lateral_from(frame, near, side);
        let local: Vec<(usize, DVec2)> = (0..self.mesh.vertex_count())
            .map(|v| (v, rel(v)))
            .filter(|&(_, q)| surroundings.contains(q))
            .collect();
        let two_s2 = 2.0 * FISSURE_SMOOTHING_MM * FISSURE_SMOOTHING_MM;
        let mut out = Vec::new();
        for &(v, q) in &local {
            if !search.contains(q) {
                continue;
            }
            let p = self.p(v);
            let (mut wz, mut w) = (0.0, 0.0);
            for &(u, _) in &local {
                let q = self.p(u);
                let d2 = (q - p).truncate().length_squared();
                if d2 < reach * reach {
                    let k = (-d2 / two_s2).exp();
                    wz += k * q.z;
                    w += k;
                }
            }
            let relief_mm = (!self.topology.touches_boundary(v)).then(|| p.z - wz / w);
            out.push(Relief {
                vertex: v,
                at: q,
                relief_mm,
            });
        }
        out
    }

    /// A lid fissure near `near`: a narrow trench, each vertex's relief
    /// ([`Self::relief_around`]) below −`min_depth_mm`. Of the regions of such vertices in the
    /// box (as [`Self::relief_around`]) the one with the deepest vertex; `None` when there is
    /// none of at least 3 vertices. Vertices beside a hole are not trench vertices.
    pub(super) fn fissure_trench(
        &self,
        frame: &Frame,
        near: usize,
        side: f64,
        search: (f64, f64, f64, f64),
        min_depth_mm: f64,
    ) -> Option<Trench> {
        let mut mask = vec![false; self.mesh.vertex_count()];
        let mut relief = vec![0.0; self.mesh.vertex_count()];
        for r in self.relief_around(frame, near, side, search) {
            if let Some(d) = r.relief_mm {
                relief[r.vertex] = d;
                mask[r.vertex] = d < -min_depth_mm;
            }
        }
        let deepest = |r: &[u32]| r.iter().map(|&v| relief[v as usize]).fold(0.0, f64::min);
        self.regions(&mask)
            .into_iter()
            .map(|r| (deepest(&r), r))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .filter(|(_, r)| r.len() >= 3)
            .map(|(_, r)| Trench {
                relief_mm: r.iter().map(|&v| relief[v as usize]).collect(),
                vertices: r,
            })
    }
}

/// One vertex of [`Detector::relief_around`].
pub(super) struct Relief {
    pub(super) vertex: usize,
    /// Relative to the reference vertex, mm (lateral, up).
    pub(super) at: DVec2,
    /// Depth below (negative) or above the mean of its surroundings, mm; `None` beside a hole.
    pub(super) relief_mm: Option<f64>,
}

/// A lid fissure's trench ([`Detector::fissure_trench`]).
pub(super) struct Trench {
    pub(super) vertices: Vec<u32>,
    /// Per vertex (as `vertices`), its depth below the Gaussian mean of its surroundings, mm
    /// (negative).
    pub(super) relief_mm: Vec<f64>,
}

impl Trench {
    /// The most negative relief of the trench, mm.
    pub(super) fn deepest_mm(&self) -> f64 {
        self.relief_mm.iter().copied().fold(0.0, f64::min)
    }
}
