//! The layered FEM face built on a registered surface, with the local repairs that keep its
//! hexahedra from inverting (folds unfolded, thin layers retried, patches smoothed).

use crate::generic_face::GenericFace;
use crate::{Error, Mesh, Result};

/// Smooths away the folds a registration can leave in the surface (a quad turned over where
/// the projection jumps across a crease or a hole's rim): the vertices of every quad whose
/// corner normals disagree with the quad's smoothed normal by more than 90° (or whose corner
/// turns the wrong way) move to the mean of their neighbours, a few rounds, until none is
/// left. Returns the surface and how many vertices moved. Folded quads extrude into inverted
/// hexahedra, so the FEM needs this; elsewhere the surface is untouched.
pub fn unfold_surface(surface: &Mesh) -> (Mesh, usize) {
    const ROUNDS: usize = 30;
    let mut mesh = surface.clone();
    let topology = crate::mesh::Topology::new(&mesh);
    let mut moved = vec![false; mesh.vertex_count()];
    for _ in 0..ROUNDS {
        mesh.update_normals();
        let mut bad = Vec::new();
        for poly in mesh.faces.iter() {
            let n = poly.len();
            let avg: glam::DVec3 = poly.iter().map(|&v| mesh.normals[v as usize]).sum();
            let folded = (0..n).any(|k| {
                let p = |i: usize| mesh.positions_mm[poly[(k + i) % n] as usize];
                let corner = (p(1) - p(0)).cross(p(n - 1) - p(0));
                corner.dot(avg) <= 0.0
            });
            if folded {
                bad.extend(poly.iter().map(|&v| v as usize));
            }
        }
        if bad.is_empty() {
            break;
        }
        bad.sort_unstable();
        bad.dedup();
        let old = mesh.positions_mm.clone();
        for &v in &bad {
            let ring = topology.neighbours(v);
            if !ring.is_empty() {
                let sum: glam::DVec3 = ring.iter().map(|&u| old[u as usize]).sum();
                mesh.positions_mm[v] = sum / ring.len() as f64;
                moved[v] = true;
            }
        }
    }
    mesh.update_normals();
    (mesh, moved.iter().filter(|&&m| m).count())
}

/// What [`repaired_fem_model`] changed to get valid layers under a registered face (nothing on
/// the generic face: 0, 1, 0).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FemRepairs {
    /// Vertices [`unfold_surface`] moved.
    pub unfolded_vertices: usize,
    /// Layer thickness factor [`fem_model`] used (1 = as asked).
    pub layer_thickness_factor: f64,
    /// Local surface repairs [`fem_model`] made.
    pub local_surface_repairs: usize,
}

/// The FEM model of a registered face the way every command builds it: folds unfolded
/// ([`unfold_surface`]), then [`fem_model`]'s thinner layers or local repairs. The model's
/// `surface` is the repaired one.
pub fn repaired_fem_model(
    surface: &Mesh,
    feature_vertices: [u32; crate::FeaturePoint::COUNT],
    params: &crate::fem::FemParams,
) -> Result<(crate::fem::FaceModel, FemRepairs)> {
    let (mesh, unfolded_vertices) = unfold_surface(surface);
    let face = GenericFace {
        mesh,
        feature_vertices,
    };
    let (model, layer_thickness_factor, local_surface_repairs) = fem_model(&face, params)?;
    Ok((
        model,
        FemRepairs {
            unfolded_vertices,
            layer_thickness_factor,
            local_surface_repairs,
        },
    ))
}

/// Thickness factors tried, in order, when the layers invert under a registered face (a crease
/// or fold of the scan that even local thinning cannot follow).
const THICKNESS_FALLBACK: [f64; 3] = [1.0, 0.6, 0.35];

/// Local surface repairs [`fem_model`] tries when every thickness still inverts an element.
pub const SURFACE_REPAIRS: usize = 16;

/// The FEM model of a registered face. When the layers invert, they are made thinner (the
/// factors of `THICKNESS_FALLBACK`); when even the thinnest layers invert, the registered surface is
/// smoothed locally around the offending element (its corners' 2-ring, [`smooth_patch`]) and
/// everything is tried again, up to [`SURFACE_REPAIRS`] times. Why: the elements that still
/// invert sit on a surface quad that the registration has all but collapsed (a projection
/// across a hole's rim or a scan border, seen on about one gallery scan in eight: see
/// docs/measurements.md), which no thickness fixes.
/// Returns the model (its `surface` is the repaired one), the factor used (1 = the requested
/// thicknesses) and the number of surface repairs.
pub fn fem_model(
    face: &GenericFace,
    params: &crate::fem::FemParams,
) -> Result<(crate::fem::FaceModel, f64, usize)> {
    let mut surface = face.mesh.clone();
    let mut repairs = 0;
    loop {
        let face = GenericFace {
            mesh: surface.clone(),
            feature_vertices: face.feature_vertices,
        };
        let mut inverted = None;
        for factor in THICKNESS_FALLBACK {
            let mut p = *params;
            p.layers.skin_thickness_mm *= factor;
            p.layers.fat_thickness_mm *= factor;
            match crate::fem::FaceModel::from_generic(&face, &p) {
                Ok(model) => return Ok((model, factor, repairs)),
                Err(e @ Error::Fem(crate::FemError::InvertedElement { .. })) => inverted = Some(e),
                Err(e) => return Err(e),
            }
        }
        let Some(Error::Fem(crate::FemError::InvertedElement { element, .. })) = inverted else {
            unreachable!("at least one thickness was tried");
        };
        if repairs == SURFACE_REPAIRS {
            return Err(inverted.unwrap());
        }
        // The element's surface corners: its nodes modulo the surface vertex count (the
        // extrusion numbers nodes layer by layer, the element order does not depend on the
        // smoothing or thickness).
        let hex = crate::fem::layers::extrude(&surface, &params.layers)?;
        let n = surface.vertex_count();
        let Some(nodes) = hex.elements.get(element) else {
            return Err(inverted.unwrap());
        };
        let corners: Vec<usize> = nodes.iter().map(|&v| v as usize % n).collect();
        surface = smooth_patch(&surface, &corners, 2, 5);
        repairs += 1;
    }
}

/// Umbrella (Laplacian, λ = ½) smoothing of the vertices within `rings` edge hops of `seeds`,
/// `iterations` times; all other vertices stay put. Normals are recomputed.
pub fn smooth_patch(surface: &Mesh, seeds: &[usize], rings: usize, iterations: usize) -> Mesh {
    let topology = crate::mesh::Topology::new(surface);
    let n = surface.vertex_count();
    let inside = topology.within_rings(seeds, rings);
    let patch: Vec<usize> = (0..n).filter(|&v| inside[v]).collect();
    let mut mesh = surface.clone();
    for _ in 0..iterations {
        let old = mesh.positions_mm.clone();
        for &v in &patch {
            let ring = topology.neighbours(v);
            if !ring.is_empty() {
                let mean: glam::DVec3 =
                    ring.iter().map(|&u| old[u as usize]).sum::<glam::DVec3>() / ring.len() as f64;
                mesh.positions_mm[v] = 0.5 * (old[v] + mean);
            }
        }
    }
    mesh.update_normals();
    mesh
}
