//! Step 3, the planar warp's triangulation: Delaunay (Bowyer–Watson) of the feature points and
//! the anchor ring in the warp plane.

use glam::DVec2;

/// Delaunay triangulation (Bowyer–Watson), counter-clockwise triangles over input indices.
/// Near-cocircular points are resolved consistently (a relative tolerance on the in-circle
/// test), so symmetric configurations triangulate without overlaps.
pub fn delaunay(points: &[DVec2]) -> Vec<[usize; 3]> {
    let n = points.len();
    if n < 3 {
        return Vec::new();
    }
    let (lo, hi) = points
        .iter()
        .fold((points[0], points[0]), |(l, h), p| (l.min(*p), h.max(*p)));
    let span = (hi - lo).max_element().max(1e-9);
    let mid = (lo + hi) * 0.5;
    let mut pts = points.to_vec();
    pts.push(mid + DVec2::new(-40.0 * span, -30.0 * span));
    pts.push(mid + DVec2::new(40.0 * span, -30.0 * span));
    pts.push(mid + DVec2::new(0.0, 50.0 * span));
    let mut tris: Vec<[usize; 3]> = vec![[n, n + 1, n + 2]];
    let scale2 = span * span;
    for i in 0..n {
        let p = pts[i];
        let mut bad = Vec::new();
        for (k, t) in tris.iter().enumerate() {
            if in_circumcircle(pts[t[0]], pts[t[1]], pts[t[2]], p, scale2) {
                bad.push(k);
            }
        }
        let mut edges: Vec<(usize, usize)> = Vec::new();
        for &k in &bad {
            let t = tris[k];
            for e in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                if let Some(j) = edges.iter().position(|&(a, b)| a == e.1 && b == e.0) {
                    edges.swap_remove(j);
                } else {
                    edges.push(e);
                }
            }
        }
        for &k in bad.iter().rev() {
            tris.swap_remove(k);
        }
        for (a, b) in edges {
            if cross2(pts[b] - pts[a], p - pts[a]) > 0.0 {
                tris.push([a, b, i]);
            }
        }
    }
    tris.retain(|t| t.iter().all(|&v| v < n));
    tris
}

fn in_circumcircle(a: DVec2, b: DVec2, c: DVec2, p: DVec2, scale2: f64) -> bool {
    let (ax, ay) = (a.x - p.x, a.y - p.y);
    let (bx, by) = (b.x - p.x, b.y - p.y);
    let (cx, cy) = (c.x - p.x, c.y - p.y);
    let det = (ax * ax + ay * ay) * (bx * cy - cx * by) - (bx * bx + by * by) * (ax * cy - cx * ay)
        + (cx * cx + cy * cy) * (ax * by - bx * ay);
    let orient = cross2(b - a, c - a);
    // Triangles are kept counter-clockwise, so det > 0 means inside; the tolerance is relative
    // to the size of the configuration (det scales with length⁴).
    det * orient.signum() > 1e-10 * scale2 * scale2
}

/// The z component of the 2-D cross product (twice the signed area of the triangle 0, a, b).
pub(super) fn cross2(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}
