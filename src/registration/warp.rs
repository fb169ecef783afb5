//! Step 2, planar deformation: the piecewise-linear warp over a Delaunay triangulation of
//! the feature points and a ring of anchors.

use super::delaunay::{cross2, delaunay};
use super::*;

/// A continuous piecewise-linear map of the plane: a triangulation of control points, each
/// with a source and a target position; a point inside a source triangle goes to the same
/// barycentric point of the target triangle, and a point outside the triangulation is not
/// moved (the outer control points are fixed anchors, so the map stays continuous there).
#[derive(Debug, Clone)]
pub struct PlanarWarp {
    src: Vec<DVec2>,
    dst: Vec<DVec2>,
    triangles: Vec<[usize; 3]>,
    /// The map outside the triangulation, `p ↦ m p + t` (identity unless anchors follow an
    /// affine map, see [`PlanarWarp::with_affine_anchor_ring`]).
    outside: (glam::DMat2, DVec2),
}

impl PlanarWarp {
    /// Feature points `src[i] → dst[i]` plus `anchor_count` fixed anchors on an ellipse with
    /// semi-axes `anchor_scale` × the features' largest offset from their centroid along each
    /// axis (`anchor_scale` > √2 puts every source feature inside the ring).
    pub fn with_anchor_ring(
        src: &[DVec2],
        dst: &[DVec2],
        anchor_scale: f64,
        anchor_count: usize,
    ) -> Result<Self> {
        if src.len() != dst.len() || src.len() < 3 {
            return Err(Error::algorithm("warp", "need ≥ 3 feature points"));
        }
        if anchor_scale <= std::f64::consts::SQRT_2 || anchor_count < 3 {
            return Err(Error::algorithm(
                "warp",
                "anchor_scale must exceed √2 and anchor_count ≥ 3",
            ));
        }
        let c = src.iter().copied().sum::<DVec2>() / src.len() as f64;
        let ext = src
            .iter()
            .fold(DVec2::ZERO, |m, p| m.max((*p - c).abs()))
            .max(DVec2::splat(1.0));
        let mut s = src.to_vec();
        let mut d = dst.to_vec();
        for k in 0..anchor_count {
            // The phase breaks the ring's mirror symmetry (no four cocircular anchors).
            let a = 0.1 + std::f64::consts::TAU * k as f64 / anchor_count as f64;
            let p = c + DVec2::new(a.cos(), a.sin()) * ext * anchor_scale;
            s.push(p);
            d.push(p);
        }
        Self::new(s, d)
    }

    /// As [`PlanarWarp::with_anchor_ring`], but the anchors (and everything outside the
    /// ring) follow the least-squares affine map of the feature points instead of staying
    /// put: beyond the feature points the generic face is stretched or narrowed like the
    /// face between them, instead of being pulled back towards its unwarped shape. Continuous
    /// (the piecewise-linear map equals the affine map along the ring's edges).
    /// `follow` ∈ [0, 1] blends the affine map with the identity (0: fixed anchors, the same
    /// map as [`PlanarWarp::with_anchor_ring`]).
    pub fn with_affine_anchor_ring(
        src: &[DVec2],
        dst: &[DVec2],
        anchor_scale: f64,
        anchor_count: usize,
        follow: f64,
    ) -> Result<Self> {
        if !(0.0..=1.0).contains(&follow) {
            return Err(Error::algorithm("warp", "affine follow must be in [0, 1]"));
        }
        let fixed = Self::with_anchor_ring(src, dst, anchor_scale, anchor_count)?;
        let (m, t) = affine_fit(src, dst)
            .ok_or_else(|| Error::algorithm("warp", "feature points are collinear"))?;
        let m = glam::DMat2::IDENTITY * (1.0 - follow) + m * follow;
        let t = t * follow;
        let mut d = fixed.dst;
        for (dp, sp) in d.iter_mut().zip(&fixed.src).skip(src.len()) {
            *dp = m * *sp + t;
        }
        Ok(PlanarWarp {
            src: fixed.src,
            dst: d,
            triangles: fixed.triangles,
            outside: (m, t),
        })
    }

    /// A warp over the Delaunay triangulation of `src` (control points `src[i] → dst[i]`).
    pub fn new(src: Vec<DVec2>, dst: Vec<DVec2>) -> Result<Self> {
        if src.len() != dst.len() {
            return Err(Error::algorithm("warp", "source and target counts differ"));
        }
        let triangles = delaunay(&src);
        if triangles.is_empty() {
            return Err(Error::algorithm("warp", "control points are collinear"));
        }
        Ok(PlanarWarp {
            src,
            dst,
            triangles,
            outside: (glam::DMat2::IDENTITY, DVec2::ZERO),
        })
    }

    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    pub fn sources(&self) -> &[DVec2] {
        &self.src
    }

    /// Number of triangles whose target orientation is opposite to (or degenerate compared
    /// with) their source orientation: the map folds over there.
    pub fn folded_triangles(&self) -> usize {
        self.triangles
            .iter()
            .filter(|t| {
                let a = cross2(
                    self.src[t[1]] - self.src[t[0]],
                    self.src[t[2]] - self.src[t[0]],
                );
                let b = cross2(
                    self.dst[t[1]] - self.dst[t[0]],
                    self.dst[t[2]] - self.dst[t[0]],
                );
                a * b <= 0.0
            })
            .count()
    }

    /// Maps a point.
    pub fn apply(&self, p: DVec2) -> DVec2 {
        let mut best: Option<(f64, usize, [f64; 3])> = None;
        for (i, t) in self.triangles.iter().enumerate() {
            if let Some(b) = barycentric2(p, self.src[t[0]], self.src[t[1]], self.src[t[2]]) {
                let m = b[0].min(b[1]).min(b[2]);
                if m >= -1e-9 {
                    if m >= 0.0 {
                        best = Some((m, i, b));
                        break;
                    }
                    if best.is_none_or(|(bm, _, _)| m > bm) {
                        best = Some((m, i, b));
                    }
                }
            }
        }
        match best {
            Some((_, i, b)) => {
                let t = self.triangles[i];
                self.dst[t[0]] * b[0] + self.dst[t[1]] * b[1] + self.dst[t[2]] * b[2]
            }
            None => self.outside.0 * p + self.outside.1,
        }
    }
}

/// Least-squares affine map `dst ≈ m src + t`; `None` if the sources are collinear.
fn affine_fit(src: &[DVec2], dst: &[DVec2]) -> Option<(glam::DMat2, DVec2)> {
    let n = src.len() as f64;
    let cs = src.iter().copied().sum::<DVec2>() / n;
    let cd = dst.iter().copied().sum::<DVec2>() / n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    let (mut bx, mut by) = (DVec2::ZERO, DVec2::ZERO);
    for (s, d) in src.iter().zip(dst) {
        let (a, b) = (*s - cs, *d - cd);
        sxx += a.x * a.x;
        sxy += a.x * a.y;
        syy += a.y * a.y;
        bx += a.x * b;
        by += a.y * b;
    }
    let det = sxx * syy - sxy * sxy;
    if !(det.abs() > 1e-12 * (sxx * syy).max(1e-300)) {
        return None;
    }
    // Rows of m solve [sxx sxy; sxy syy] [m_r0 m_r1]ᵀ = [bx_r by_r]ᵀ.
    let col0 = (bx * syy - by * sxy) / det;
    let col1 = (by * sxx - bx * sxy) / det;
    let m = glam::DMat2::from_cols(col0, col1);
    Some((m, cd - m * cs))
}

pub(super) fn barycentric2(p: DVec2, a: DVec2, b: DVec2, c: DVec2) -> Option<[f64; 3]> {
    let d = cross2(b - a, c - a);
    if d.abs() < 1e-300 {
        return None;
    }
    let l1 = cross2(p - a, c - a) / d;
    let l2 = cross2(b - a, p - a) / d;
    Some([1.0 - l1 - l2, l1, l2])
}
