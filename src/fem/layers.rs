//! The layered tissue volume (paper section 2, Figure 4): the face surface is offset along its
//! vertex unit normals, **inwards** (into the head), by two thicknesses, giving 3 node layers
//! and 2 layers of hexahedra: skin on top, fatty tissue below it, and the bottom node layer
//! standing for the cranium (fixed).
//!
//! Node numbering: layer `k` (0 = skin surface, 1 = skin/fat interface, 2 = cranium) of surface
//! vertex `v` is node `k·n + v`, so the first `n` nodes are the surface's own vertices.
//!
//! A quad `(a, b, c, d)` (counter-clockwise seen from outside) becomes the hexahedron
//! `[deep a b c d, shallow a b c d]`, which has a positive Jacobian. A **triangle** `(a, b, c)`
//! becomes a *collapsed hexahedron* `[deep a b c c, shallow a b c c]` — geometrically a wedge;
//! its Gauss-point Jacobians stay positive, only the collapsed edge has a zero corner Jacobian
//! (scaled Jacobian 0 there). This keeps one element type and one VTK cell type; a collapsed
//! hex is slightly stiffer than a true wedge. Larger polygons are rejected.

use super::hex8;
use super::{FAT, HexMesh, SKIN};
use crate::{FemError, Mesh, Result};
use glam::DVec3;

/// Layer thicknesses (the paper's two "factors" multiplying the vertex unit normal).
///
/// Facial soft tissue (skin + subcutaneous fat + muscle) is roughly 10–15 mm thick over most of
/// the face (thinner on the forehead and nose bridge, thicker in the cheeks), and the skin
/// proper (epidermis + dermis) 1.5–3 mm. The defaults give 12 mm in total.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LayerParams {
    /// Skin layer thickness, mm (default 3.0; dermis ~1.5–3 mm, a little thicker keeps the
    /// skin elements from being too flat: the face's quads are ~2.5 mm wide).
    pub skin_thickness_mm: f64,
    /// Fatty-tissue layer thickness, mm (default 9.0, so skin + fat = 12 mm, inside the
    /// 10–15 mm soft-tissue range).
    pub fat_thickness_mm: f64,
    /// Rounds of averaging each vertex's offset direction with its 1-ring neighbours' (default
    /// 20, i.e. directions smooth over roughly the layer thickness). With raw normals (0) a
    /// 12 mm offset folds under the nose, lips, chin and eye rims (198 inverted elements on the
    /// generic face; 2 rounds: 142; 8: 38; 20: none).
    pub normal_smoothing_rounds: usize,
    /// Rounds of umbrella (Laplacian, λ = ½) smoothing of the cranium node layer (default 0).
    /// Smoothing it untangles folds of the fat layer in creases (under the nose, the lip
    /// line) that smoother directions alone cannot; the cranium layer becomes smoother than
    /// the skin, as the skull is.
    pub layer_smoothing_rounds: usize,
    /// At most this fraction of the surface vertices may be thinned locally by
    /// [`extrude_valid`] (default 0.05); beyond that the thickness itself is the problem and
    /// the extrusion fails with [`FemError::InvertedElement`].
    pub max_thinned_fraction: f64,
}

impl Default for LayerParams {
    fn default() -> Self {
        LayerParams {
            skin_thickness_mm: 3.0,
            fat_thickness_mm: 9.0,
            normal_smoothing_rounds: 20,
            layer_smoothing_rounds: 0,
            max_thinned_fraction: 0.05,
        }
    }
}

/// Shape quality of the hexahedra.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ElementQuality {
    /// Smallest scaled Jacobian over all elements (1 = cube; 0 for collapsed wedges).
    pub min_scaled_jacobian: f64,
    /// Mean of the elements' scaled Jacobians.
    pub mean_scaled_jacobian: f64,
    /// Smallest Jacobian determinant at any Gauss point, mm³ (must be > 0).
    pub min_gauss_jacobian_det_mm3: f64,
    /// Elements with a non-positive Jacobian at a Gauss point.
    pub inverted_elements: usize,
}

/// The offset directions: unit vertex normals, optionally smoothed over the 1-ring.
fn offset_directions(surface: &Mesh, rounds: usize) -> Vec<DVec3> {
    let mut normals = surface.normals.clone();
    if rounds == 0 {
        return normals;
    }
    let topology = crate::mesh::Topology::new(surface);
    for _ in 0..rounds {
        normals = (0..normals.len())
            .map(|v| {
                let sum: DVec3 = normals[v]
                    + topology
                        .neighbours(v)
                        .iter()
                        .map(|&w| normals[w as usize])
                        .sum::<DVec3>();
                sum.normalize_or_zero()
            })
            .collect();
    }
    normals
}

/// The smallest scaled Jacobian an element may have (Verdict's acceptable range for hexahedra
/// starts at 0.2): below it a corner is so skewed that the trilinear element's strain is
/// unreliable, and at 0 it is inverted. [`extrude_valid`] thins the layers locally until every
/// element is above it.
pub const MIN_SCALED_JACOBIAN: f64 = 0.2;

/// The elements at or below [`MIN_SCALED_JACOBIAN`], or with a Gauss-point Jacobian ≤ 0:
/// (element, smallest Gauss-point Jacobian determinant mm³, scaled Jacobian).
pub fn poor_elements(mesh: &HexMesh) -> Vec<(usize, f64, f64)> {
    (0..mesh.elements.len())
        .map(|e| {
            let nodes = mesh.element_nodes(e);
            (
                e,
                hex8::min_gauss_jacobian_det(&nodes),
                hex8::scaled_jacobian(&nodes),
            )
        })
        .filter(|(_, det, sj)| !(*det > 0.0 && *sj > MIN_SCALED_JACOBIAN))
        .collect()
}

/// What [`extrude_valid`] had to do to avoid inverted elements.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct ExtrusionFix {
    /// Normal-smoothing rounds finally used.
    pub normal_smoothing_rounds: usize,
    /// Surface vertices whose layer thickness was reduced locally.
    pub thinned_vertices: usize,
    /// Smallest remaining thickness factor (1 = as requested).
    pub min_thickness_factor: f64,
}

/// Extrudes `surface` so that every element's scaled Jacobian is above
/// [`MIN_SCALED_JACOBIAN`], with [`LayerParams::normal_smoothing_rounds`]. The inner node
/// layers are evened out first ([`super::untangle`]); where elements still invert or skew
/// (creases of a registered scan, e.g. under the nostrils, where the offset directions converge
/// and the deep face of an element shrinks) the layer thickness is reduced **locally**: the
/// corners of each poor element get ×0.85 per pass, down to 0.2 of the requested thickness.
/// Errors with [`FemError::InvertedElement`] (or [`FemError::PoorElement`] when no element is
/// inverted) when that is not enough: the surface itself must change there (the caller's
/// repair, `fem::repair`). Smoother offset directions (more rounds) were the old
/// remedy; with the inner layers evened out they only made more elements poor on real
/// registrations and cost time (docs/measurements.md).
pub fn extrude_valid(surface: &Mesh, params: &LayerParams) -> Result<(HexMesh, ExtrusionFix)> {
    let n = surface.vertex_count();
    let topology = crate::mesh::Topology::new(surface);
    let mut scale = vec![1.0; n];
    loop {
        let mut mesh = extrude_scaled(surface, params, &scale)?;
        super::untangle::untangle(
            &mut mesh,
            &topology,
            &surface.normals,
            surface.face_count(),
            MIN_SCALED_JACOBIAN,
        );
        let poor = poor_elements(&mesh);
        if poor.is_empty() {
            let thinned = scale.iter().filter(|&&s| s < 1.0).count();
            return Ok((
                mesh,
                ExtrusionFix {
                    normal_smoothing_rounds: params.normal_smoothing_rounds,
                    thinned_vertices: thinned,
                    min_thickness_factor: scale.iter().copied().fold(1.0, f64::min),
                },
            ));
        }
        let mut changed = false;
        for &(e, _, _) in &poor {
            for &node in &mesh.elements[e] {
                let v = node as usize % n;
                if scale[v] > 0.2 {
                    scale[v] = (scale[v] * 0.85).max(0.2);
                    changed = true;
                }
            }
        }
        let thinned = scale.iter().filter(|&&s| s < 1.0).count();
        if changed && thinned as f64 <= params.max_thinned_fraction * n as f64 {
            continue;
        }
        // The worst element names the failure: inverted if any is.
        let &(element, det, sj) = poor
            .iter()
            .min_by(|a, b| a.1.min(a.2).total_cmp(&b.1.min(b.2)))
            .expect("not empty");
        return Err(if det > 0.0 {
            FemError::PoorElement {
                element,
                scaled_jacobian: sj,
                limit: MIN_SCALED_JACOBIAN,
            }
        } else {
            FemError::InvertedElement {
                element,
                min_jacobian_det: det,
            }
        }
        .into());
    }
}

/// Extrudes `surface` into the two-layer hexahedral volume with exactly the given smoothing.
/// Fails on a polygon with more than 4 corners, bad thicknesses, or a vertex without a normal.
/// Inversion is *checked* by [`element_quality`] (and rejected at assembly), not here.
pub fn extrude(surface: &Mesh, params: &LayerParams) -> Result<HexMesh> {
    extrude_scaled(surface, params, &vec![1.0; surface.vertex_count()])
}

/// [`extrude`] with a per-vertex factor on both layer thicknesses.
fn extrude_scaled(surface: &Mesh, params: &LayerParams, scale: &[f64]) -> Result<HexMesh> {
    let positive = |t: f64| t > 0.0 && t.is_finite();
    if !(positive(params.skin_thickness_mm) && positive(params.fat_thickness_mm)) {
        return Err(FemError::Definition(format!(
            "layer thicknesses must be finite and > 0 mm (skin {}, fat {})",
            params.skin_thickness_mm, params.fat_thickness_mm
        ))
        .into());
    }
    let n = surface.vertex_count();
    let directions = offset_directions(surface, params.normal_smoothing_rounds);
    if let Some(v) = directions.iter().position(|d| !(d.length() > 0.5)) {
        return Err(FemError::Definition(format!(
            "surface vertex {v} has no normal (isolated vertex?); remove unreferenced vertices"
        ))
        .into());
    }
    let mut nodes_mm = Vec::with_capacity(3 * n);
    nodes_mm.extend_from_slice(&surface.positions_mm);
    let depths = [
        params.skin_thickness_mm,
        params.skin_thickness_mm + params.fat_thickness_mm,
    ];
    let topology = (params.layer_smoothing_rounds > 0).then(|| crate::mesh::Topology::new(surface));
    for (k, depth) in depths.into_iter().enumerate() {
        let mut layer: Vec<DVec3> = (0..n)
            .map(|v| surface.positions_mm[v] - directions[v] * (depth * scale[v]))
            .collect();
        // Only the cranium layer is smoothed: the 3 mm skin layer folds nowhere, and smoothing
        // the interface layer pulls it through the skin under the nostrils.
        if let (Some(topology), 1) = (&topology, k) {
            for _ in 0..params.layer_smoothing_rounds {
                layer = (0..n)
                    .map(|v| {
                        let ring = topology.neighbours(v);
                        if ring.is_empty() {
                            return layer[v];
                        }
                        let mean = ring.iter().map(|&w| layer[w as usize]).sum::<DVec3>()
                            / ring.len() as f64;
                        (layer[v] + mean) * 0.5
                    })
                    .collect();
            }
        }
        nodes_mm.extend(layer);
    }
    let mut elements = Vec::with_capacity(2 * surface.face_count());
    let mut element_group = Vec::with_capacity(2 * surface.face_count());
    for layer in [SKIN, FAT] {
        let (shallow, deep) = (layer as u32 * n as u32, (layer as u32 + 1) * n as u32);
        for (f, poly) in surface.faces.iter().enumerate() {
            let quad: [u32; 4] = match poly.len() {
                4 => [poly[0], poly[1], poly[2], poly[3]],
                3 => [poly[0], poly[1], poly[2], poly[2]],
                corners => return Err(FemError::UnsupportedPolygon { face: f, corners }.into()),
            };
            elements.push([
                deep + quad[0],
                deep + quad[1],
                deep + quad[2],
                deep + quad[3],
                shallow + quad[0],
                shallow + quad[1],
                shallow + quad[2],
                shallow + quad[3],
            ]);
            element_group.push(layer);
        }
    }
    Ok(HexMesh {
        nodes_mm,
        elements,
        element_group,
        group_names: vec!["skin".into(), "fat".into()],
    })
}

/// Scaled and Gauss-point Jacobians of every element.
pub fn element_quality(mesh: &HexMesh) -> ElementQuality {
    let mut min_sj = f64::INFINITY;
    let mut sum_sj = 0.0;
    let mut min_det = f64::INFINITY;
    let mut inverted = 0;
    for e in 0..mesh.elements.len() {
        let nodes = mesh.element_nodes(e);
        let sj = hex8::scaled_jacobian(&nodes);
        let det = hex8::min_gauss_jacobian_det(&nodes);
        min_sj = min_sj.min(sj);
        sum_sj += sj;
        min_det = min_det.min(det);
        if !(det > 0.0) {
            inverted += 1;
        }
    }
    ElementQuality {
        min_scaled_jacobian: min_sj,
        mean_scaled_jacobian: sum_sj / mesh.elements.len().max(1) as f64,
        min_gauss_jacobian_det_mm3: min_det,
        inverted_elements: inverted,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generic_face_extrudes_without_inversion() {
        let face = crate::generic_face::build();
        let (mesh, fix) = extrude_valid(&face.mesh, &LayerParams::default()).unwrap();
        assert_eq!(
            fix.normal_smoothing_rounds,
            LayerParams::default().normal_smoothing_rounds
        );
        assert_eq!(fix.thinned_vertices, 0);
        assert_eq!(mesh.nodes_mm.len(), 3 * face.mesh.vertex_count());
        assert_eq!(mesh.elements.len(), 2 * face.mesh.face_count());
        let q = element_quality(&mesh);
        assert_eq!(q.inverted_elements, 0, "{q:?}");
        assert!(q.min_gauss_jacobian_det_mm3 > 0.0);
        assert!(q.min_scaled_jacobian > 0.0, "{q:?}");
        assert!(q.mean_scaled_jacobian > 0.9, "{q:?}");
        println!("generic face layers: {q:?}");
        // Raw normals fold the volume under the nose and lips: the check sees it.
        let raw = LayerParams {
            normal_smoothing_rounds: 0,
            ..LayerParams::default()
        };
        assert!(element_quality(&extrude(&face.mesh, &raw).unwrap()).inverted_elements > 0);
        // Cranium nodes lie 12 mm inside the skin along the offset direction.
        let n = face.mesh.vertex_count();
        let d = (mesh.nodes_mm[0] - mesh.nodes_mm[2 * n]).length();
        assert!((d - 12.0).abs() < 1e-9);
    }

    #[test]
    fn triangles_become_collapsed_hexes_with_positive_gauss_jacobians() {
        let positions = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(0.0, 10.0, 0.0),
        ];
        let surface = Mesh::from_faces(positions, [[0u32, 1, 2]]);
        let mesh = extrude(&surface, &LayerParams::default()).unwrap();
        assert_eq!(mesh.elements.len(), 2);
        let q = element_quality(&mesh);
        assert_eq!(q.inverted_elements, 0);
        assert!(q.min_scaled_jacobian.abs() < 1e-12);
        // Its volume equals the prism's: ½·10·10·thickness.
        let volume: f64 = hex8::gauss_points()
            .iter()
            .map(|&xi| hex8::jacobian(&mesh.element_nodes(0), xi).determinant())
            .sum();
        assert!((volume - 50.0 * 3.0).abs() < 1e-9, "{volume}");
    }

    #[test]
    fn pentagons_are_rejected() {
        let positions = (0..5)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 5.0;
                DVec3::new(a.cos(), a.sin(), 0.0) * 10.0
            })
            .collect();
        let surface = Mesh::from_faces(positions, [[0u32, 1, 2, 3, 4]]);
        assert!(extrude(&surface, &LayerParams::default()).is_err());
    }
}
