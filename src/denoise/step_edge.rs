//! The step-edge test (item 6 of the module docs of `denoise`): a vertex that shares a plane
//! with a good part of its ring is one side of a crease, a closed lid or a lip edge, not a
//! spike, and the filter leaves it where it is; removal's peeling asks the same question.

use super::*;

/// Points of a vertex's 3-ring within this distance (mm, along z) of a plane through the
/// vertex count as its support in [`on_real_surface`].
pub(super) const SURFACE_SUPPORT_TOLERANCE_MM: f64 = 1.0;
/// [`on_real_surface`]: the fewest supporting ring points, and the smallest share of the ring.
/// A spike cluster has at most 5 other members; measured on 100 synthetic scans (3-rings of 24
/// points on the quad grid), interior spikes had at most 9 supporting points (95 % at most 6,
/// about a fifth of the ring), the clean crease and lid vertices the filter moved wrongly 5–13
/// (median 10, half the ring).
pub(super) const SURFACE_SUPPORT_MIN_POINTS: usize = 8;
pub(super) const SURFACE_SUPPORT_MIN_SHARE: f64 = 1.0 / 3.0;

/// Step-edge test: whether vertex `v`, where it lies in `input`, shares a plane with at least
/// [`SURFACE_SUPPORT_MIN_POINTS`] and [`SURFACE_SUPPORT_MIN_SHARE`] of its ring (within
/// [`SURFACE_SUPPORT_TOLERANCE_MM`]). Such a vertex is a sample of a real surface that the
/// quadric of the whole ring cannot follow (one side of a lid crease, a lip or mouth edge),
/// not a spike: a spike is off every plane through it but those through its own cluster.
/// With `min_span_deg`, the supporting points must also span that angle around the vertex
/// (the filter asks no span; peeling does, see `removal::PEEL_SUPPORT_MIN_SPAN_DEG`).
/// Tries every plane through the vertex and two ring points (24 points: 276 planes).
pub(super) fn on_real_surface(
    input: &[DVec3],
    v: usize,
    ring: &[u32],
    min_span_deg: Option<f64>,
) -> bool {
    let p = input[v];
    let need = SURFACE_SUPPORT_MIN_POINTS
        .max((SURFACE_SUPPORT_MIN_SHARE * ring.len() as f64).ceil() as usize);
    if ring.len() < need {
        return false;
    }
    let q: Vec<DVec3> = ring.iter().map(|&u| input[u as usize] - p).collect();
    for a in 0..q.len() {
        for b in a + 1..q.len() {
            // The plane z = c1 x + c2 y through the vertex, a and b; nearly collinear: none.
            let det = q[a].x * q[b].y - q[a].y * q[b].x;
            if det.abs() < 0.5 {
                continue;
            }
            let c1 = (q[a].z * q[b].y - q[a].y * q[b].z) / det;
            let c2 = (q[a].x * q[b].z - q[a].z * q[b].x) / det;
            let support = || {
                q.iter().filter(move |r| {
                    (r.z - c1 * r.x - c2 * r.y).abs() < SURFACE_SUPPORT_TOLERANCE_MM
                })
            };
            if support().count() >= need
                && min_span_deg.is_none_or(|min| span_deg(support()) >= min)
            {
                return true;
            }
        }
    }
    false
}

/// The angle (degrees) that `points` (relative to a vertex) span as seen from it: 360 less
/// the widest gap between their directions.
pub(super) fn span_deg<'a>(points: impl Iterator<Item = &'a DVec3>) -> f64 {
    let mut angles: Vec<f64> = points.map(|r| r.y.atan2(r.x).to_degrees()).collect();
    angles.sort_by(f64::total_cmp);
    let (Some(&first), Some(&last)) = (angles.first(), angles.last()) else {
        return 0.0;
    };
    let gap = angles
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(first + 360.0 - last, f64::max);
    360.0 - gap
}

/// An interior vertex that would move (`disp ≥ floor`) but lies on a real surface
/// ([`on_real_surface`]) does not: its floor becomes infinite.
pub(super) fn veto_real_surface(
    floor: f64,
    disp: f64,
    input: &[DVec3],
    v: usize,
    ring: &[u32],
    topology: &Topology,
) -> f64 {
    if disp >= floor && !topology.is_boundary[v] && on_real_surface(input, v, ring, None) {
        f64::INFINITY
    } else {
        floor
    }
}
