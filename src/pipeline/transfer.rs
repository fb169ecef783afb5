//! Carrying the FEM face's expression onto the scan itself (the gallery samples are the
//! person's own scan, moved), and the open mouth's cavity.

use crate::{Error, Mesh, Result};

/// How deep the open mouth looks to the scanner ([`mouth_cavity`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CavityParams {
    /// Deepest point of the cavity, mm per degree of jaw opening (default 2.5: synth_gavab's
    /// laughs show a ~20–25 mm deep opening between the lips for ~5–9°). 0: none.
    pub depth_mm_per_deg: f64,
    /// How fast the cavity deepens inwards from the lips, mm of depth per mm of distance from
    /// the nearest lip (default 1.5: the inner lip and the teeth behind it).
    pub wall_slope: f64,
}

impl Default for CavityParams {
    fn default() -> Self {
        CavityParams {
            depth_mm_per_deg: 2.5,
            wall_slope: 1.5,
        }
    }
}

/// Pushes back the part of an expression-carrying scan that lies inside the FEM face's open
/// mouth. The neutral scan's lips are closed, so carrying an open jaw onto it stretches its
/// skin across the opening, where a real scan of an open mouth sees the inside of the mouth
/// (teeth, tongue, shadow) far behind the lips. Every scan vertex that falls, in the face plane,
/// inside the deformed mouth rim of `model` (the slit's boundary loop displaced by `u_mm`)
/// moves back along the face's forward axis by `min(depth, wall_slope × distance to the rim)`,
/// `depth = depth_mm_per_deg × jaw_deg`.
pub fn mouth_cavity(
    scan: &mut Mesh,
    model: &crate::fem::FaceModel,
    u_mm: &[glam::DVec3],
    jaw_deg: f64,
    params: &CavityParams,
) -> Result<()> {
    use glam::{DVec2, DVec3};
    let depth = params.depth_mm_per_deg * jaw_deg;
    if !(depth > 0.0) {
        return Ok(());
    }
    // The jaw resolved the lips' rim and the face's axes once for all expressions.
    let Some(jaw) = model.jaw().filter(|j| !j.mouth_rim.is_empty()) else {
        return Err(Error::algorithm(
            "augment",
            "the FEM face has no jaw or no mouth opening",
        ));
    };
    let surface = &model.surface;
    let rim = &jaw.mouth_rim;
    let plane = |p: DVec3| DVec2::new(p.dot(jaw.axis), p.dot(jaw.up));
    let polygon: Vec<DVec2> = rim
        .iter()
        .map(|&v| plane(surface.positions_mm[v as usize] + u_mm[v as usize]))
        .collect();
    let (lo, hi) = polygon.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    for q in &mut scan.positions_mm {
        let p = plane(*q);
        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
            continue;
        }
        // Even-odd rule, and the distance to the nearest rim edge.
        let mut inside = false;
        let mut nearest = f64::INFINITY;
        for k in 0..polygon.len() {
            let (a, b) = (polygon[k], polygon[(k + 1) % polygon.len()]);
            if (a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x) {
                inside = !inside;
            }
            let ab = b - a;
            let t = ((p - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
            nearest = nearest.min((a + ab * t).distance(p));
        }
        if inside {
            *q -= jaw.forward * depth.min(params.wall_slope * nearest);
        }
    }
    scan.update_normals();
    Ok(())
}

/// Carries the FEM face's expression onto the scan itself: every scan vertex moves by the
/// displacement of the registered face near it (inverse-square-distance weights over the face
/// vertices within `radius_mm`), faded out linearly between `radius_mm / 2` and `radius_mm`
/// from the face (hair, ears and neck stay put).
///
/// Why: recognition trains on range images, and a synthetic sample made from the generic
/// face differs from the person's real scans in everything the generic face lacks (eyeballs,
/// skin detail, the hairline, scan holes) — LDA then learns "generic vs scan" instead of
/// "expression". Moving the scan itself keeps all of that and changes only the expression.
pub fn transfer_expression(
    scan: &Mesh,
    face_rest: &Mesh,
    displacement_mm: &[glam::DVec3],
    radius_mm: f64,
) -> Mesh {
    TransferWeights::new(scan, face_rest, radius_mm).apply(scan, displacement_mm)
}

/// The weights of [`transfer_expression`] for one scan and rest face, computed once and
/// applied to any number of displacement fields (augment carries 18+ expressions onto the same
/// scan; the neighbour search is the costly part).
#[derive(Debug, Clone)]
pub struct TransferWeights {
    /// Per scan vertex: start of its entries in `face_vertex` / `weight`.
    offsets: Vec<usize>,
    face_vertex: Vec<u32>,
    /// Normalised weight × fade.
    weight: Vec<f64>,
}

impl TransferWeights {
    pub fn new(scan: &Mesh, face_rest: &Mesh, radius_mm: f64) -> TransferWeights {
        use glam::DVec3;
        let cell = radius_mm.max(0.5);
        let key = |p: DVec3| {
            (
                (p.x / cell).floor() as i64,
                (p.y / cell).floor() as i64,
                (p.z / cell).floor() as i64,
            )
        };
        let mut grid: std::collections::HashMap<(i64, i64, i64), Vec<u32>> = Default::default();
        for (i, &p) in face_rest.positions_mm.iter().enumerate() {
            grid.entry(key(p)).or_default().push(i as u32);
        }
        let mut offsets = Vec::with_capacity(scan.vertex_count() + 1);
        let mut face_vertex = Vec::new();
        let mut weight = Vec::new();
        offsets.push(0);
        for &p in &scan.positions_mm {
            let (cx, cy, cz) = key(p);
            let start = face_vertex.len();
            let (mut total, mut nearest) = (0.0, f64::INFINITY);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(ids) = grid.get(&(cx + dx, cy + dy, cz + dz)) else {
                            continue;
                        };
                        for &i in ids {
                            let d = face_rest.positions_mm[i as usize].distance(p);
                            if d < radius_mm {
                                let w = 1.0 / (d * d + 0.25);
                                face_vertex.push(i);
                                weight.push(w);
                                total += w;
                                nearest = nearest.min(d);
                            }
                        }
                    }
                }
            }
            if total > 0.0 {
                let fade = ((radius_mm - nearest) / (radius_mm * 0.5)).clamp(0.0, 1.0);
                for w in &mut weight[start..] {
                    *w *= fade / total;
                }
            }
            offsets.push(face_vertex.len());
        }
        TransferWeights {
            offsets,
            face_vertex,
            weight,
        }
    }

    /// The scan moved by `displacement_mm` (one per rest-face vertex); normals recomputed.
    /// `scan` must be the mesh the weights were made for.
    pub fn apply(&self, scan: &Mesh, displacement_mm: &[glam::DVec3]) -> Mesh {
        let positions = scan
            .positions_mm
            .iter()
            .enumerate()
            .map(|(v, &p)| {
                let range = self.offsets[v]..self.offsets[v + 1];
                p + self.face_vertex[range.clone()]
                    .iter()
                    .zip(&self.weight[range])
                    .map(|(&i, &w)| {
                        displacement_mm.get(i as usize).copied().unwrap_or_default() * w
                    })
                    .sum::<glam::DVec3>()
            })
            .collect();
        let mut out = Mesh::new(positions, scan.faces.clone());
        out.update_normals();
        out
    }
}
