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

/// A quad's scaled Jacobian as a surface element: the smallest over its corners of
/// `(e1 × e2) · n / (|e1| |e2|)`, the sine of the corner angle, with `n` the quad's normal (from
/// its diagonals). 1 for a square, ≤ 0 for a folded corner.
pub fn quad_scaled_jacobian(p: [glam::DVec3; 4]) -> f64 {
    let n = (p[2] - p[0]).cross(p[3] - p[1]).normalize_or_zero();
    (0..4)
        .map(|k| {
            let (a, b, d) = (p[k], p[(k + 1) % 4], p[(k + 3) % 4]);
            let len = (b - a).length() * (d - a).length();
            if len > 0.0 {
                (b - a).cross(d - a).dot(n) / len
            } else {
                0.0
            }
        })
        .fold(f64::INFINITY, f64::min)
}

/// The skin element a surface quad extrudes into, judged at the surface: the smallest over
/// the quad's corners of `(e1 × e2) · n / (|e1| |e2|)` with `n` the corner's **vertex** normal
/// (the direction the layers grow in there). This is the element's scaled Jacobian at that
/// corner for an edge straight down, so it sees a skewed corner and a crease (a quad tilted
/// against its vertex normal) alike. 1 for a flat square; triangles count as 1.
pub fn quad_corner_quality(mesh: &Mesh, f: usize) -> f64 {
    let poly = mesh.faces.get(f);
    if poly.len() != 4 {
        return 1.0;
    }
    (0..4)
        .map(|k| {
            let v = poly[k] as usize;
            let a = mesh.positions_mm[v];
            let b = mesh.positions_mm[poly[(k + 1) % 4] as usize];
            let d = mesh.positions_mm[poly[(k + 3) % 4] as usize];
            let len = (b - a).length() * (d - a).length();
            if len > 0.0 {
                (b - a).cross(d - a).dot(mesh.normals[v]) / len
            } else {
                0.0
            }
        })
        .fold(f64::INFINITY, f64::min)
}

/// Surface quads more skewed than this (the sine of their sharpest corner) are relaxed by
/// [`relax_skewed_quads`]: an element on a quad with a 20° corner cannot reach the layers'
/// [`crate::fem::layers::MIN_SCALED_JACOBIAN`] of 0.2 at any thickness, and the deep faces of
/// the layers come out more skewed than the surface where the offset directions converge
/// (measured on real registrations: elements on quads of 0.36–0.41 still below 0.2), so the
/// surface gets a wide margin (0.5: no corner sharper than 30°).
pub const MIN_QUAD_SCALED_JACOBIAN: f64 = 0.5;

/// Evens out the skewed quads a registration leaves where the scan is creased or sparse: each
/// corner of a quad below [`MIN_QUAD_SCALED_JACOBIAN`] ([`quad_corner_quality`]) moves
/// **within its tangent plane** down the gradient of `Σ max(0, 0.6 − q)²` over the quads
/// around it (central differences along the world axes, steps of ½, ¼ and ⅛ of its mean
/// edge), if that lowers the penalty without sharpening their sharpest corner. Dropping the normal component keeps the
/// surface's shape to first order; only the vertex spacing changes. Smoothing towards the
/// neighbours' mean would not do: a uniformly sheared band of quads is its own Laplacian mean.
/// Every move of a round is decided from the same positions and applied together (a quad two
/// moves made worse gets its corners put back), so a mirror-symmetric face stays symmetric.
/// Border vertices stay (the FEM fixes them). Returns the surface and how many vertices moved.
pub fn relax_skewed_quads(surface: &Mesh) -> (Mesh, usize) {
    const ROUNDS: usize = 20;
    const GRADIENT_TARGET: f64 = 0.6;
    let mut mesh = surface.clone();
    let topology = crate::mesh::Topology::new(&mesh);
    let worst_around = |mesh: &Mesh, v: usize| {
        topology
            .vertex_faces(v)
            .iter()
            .map(|&f| quad_corner_quality(mesh, f as usize))
            .fold(f64::INFINITY, f64::min)
    };
    let penalty = |mesh: &Mesh, v: usize| {
        topology
            .vertex_faces(v)
            .iter()
            .map(|&f| {
                (GRADIENT_TARGET - quad_corner_quality(mesh, f as usize))
                    .max(0.0)
                    .powi(2)
            })
            .sum::<f64>()
    };
    let mut moved = vec![false; mesh.vertex_count()];
    for _ in 0..ROUNDS {
        let quality: Vec<f64> = (0..mesh.faces.len())
            .map(|f| quad_corner_quality(&mesh, f))
            .collect();
        let mut bad: Vec<usize> = (0..mesh.faces.len())
            .filter(|&f| quality[f] < MIN_QUAD_SCALED_JACOBIAN)
            .flat_map(|f| mesh.faces.get(f).to_vec())
            .map(|v| v as usize)
            .filter(|&v| !topology.touches_boundary(v))
            .collect();
        if bad.is_empty() {
            break;
        }
        bad.sort_unstable();
        bad.dedup();
        let mut trial = mesh.clone();
        let mut moves = Vec::new();
        for v in bad {
            let p = mesh.positions_mm[v];
            let ring = topology.neighbours(v);
            if ring.is_empty() {
                continue;
            }
            let edge = ring
                .iter()
                .map(|&u| (mesh.positions_mm[u as usize] - p).length())
                .sum::<f64>()
                / ring.len() as f64;
            let g = crate::mesh::central_gradient(
                |q| {
                    trial.positions_mm[v] = q;
                    let value = penalty(&trial, v);
                    trial.positions_mm[v] = p;
                    value
                },
                p,
                1e-3 * edge,
            );
            let n = mesh.normals[v];
            let g = (g - n * n.dot(g)).normalize_or_zero();
            // A move is taken if the sharpest corner around the vertex does not get sharper
            // and the penalty falls (the sharpest corner may be one this vertex cannot widen
            // alone; its neighbours' moves will).
            let floor = worst_around(&mesh, v);
            let mut best = (penalty(&mesh, v), p);
            for step in [0.5, 0.25, 0.125] {
                let q = p - g * (step * edge);
                trial.positions_mm[v] = q;
                let value = penalty(&trial, v);
                if worst_around(&trial, v) >= floor && value < best.0 {
                    best = (value, q);
                }
            }
            trial.positions_mm[v] = p;
            if best.1 != p {
                moves.push((v, p, best.1));
            }
        }
        if moves.is_empty() {
            break;
        }
        for &(v, _, to) in &moves {
            mesh.positions_mm[v] = to;
        }
        let mut undo = vec![false; mesh.vertex_count()];
        for (f, &before) in quality.iter().enumerate() {
            let now = quad_corner_quality(&mesh, f);
            if now < before && now < MIN_QUAD_SCALED_JACOBIAN {
                for &v in mesh.faces.get(f) {
                    undo[v as usize] = true;
                }
            }
        }
        for &(v, from, _) in &moves {
            if undo[v] {
                mesh.positions_mm[v] = from;
            } else {
                moved[v] = true;
            }
        }
        mesh.update_normals();
    }
    (mesh, moved.iter().filter(|&&m| m).count())
}

/// What [`repaired_fem_model`] changed to get valid layers under a registered face (nothing on
/// the generic face: 0, 0, 1, 0).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FemRepairs {
    /// Vertices [`unfold_surface`] moved.
    pub unfolded_vertices: usize,
    /// Vertices [`relax_skewed_quads`] moved (within their tangent planes).
    pub relaxed_vertices: usize,
    /// Layer thickness factor [`fem_model`] used (1 = as asked).
    pub layer_thickness_factor: f64,
    /// Local surface repairs [`fem_model`] made.
    pub local_surface_repairs: usize,
}

/// The FEM model of a registered face the way every command builds it: folds unfolded
/// ([`unfold_surface`]), skewed quads evened out ([`relax_skewed_quads`]), then
/// [`fem_model`]'s thinner layers or local repairs. The model's
/// `surface` is the repaired one.
pub fn repaired_fem_model(
    surface: &Mesh,
    feature_vertices: [u32; crate::FeaturePoint::COUNT],
    params: &crate::fem::FemParams,
) -> Result<(crate::fem::FaceModel, FemRepairs)> {
    let (mesh, unfolded_vertices) = unfold_surface(surface);
    let (mesh, relaxed_vertices) = relax_skewed_quads(&mesh);
    let face = GenericFace {
        mesh,
        feature_vertices,
    };
    let (model, layer_thickness_factor, local_surface_repairs) = fem_model(&face, params)?;
    Ok((
        model,
        FemRepairs {
            unfolded_vertices,
            relaxed_vertices,
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
                Err(
                    e @ Error::Fem(
                        crate::FemError::InvertedElement { .. }
                        | crate::FemError::PoorElement { .. },
                    ),
                ) => inverted = Some(e),
                Err(e) => return Err(e),
            }
        }
        let element = match &inverted {
            Some(Error::Fem(
                crate::FemError::InvertedElement { element, .. }
                | crate::FemError::PoorElement { element, .. },
            )) => *element,
            _ => unreachable!("at least one thickness was tried"),
        };
        if repairs == SURFACE_REPAIRS {
            // Refused, naming where: the feature point nearest the element's surface quad.
            let e = inverted.unwrap();
            let quad = surface.faces.get(element % surface.face_count().max(1));
            let at = surface.positions_mm[quad[0] as usize];
            let (point, mm) = crate::FeaturePoint::ALL
                .iter()
                .map(|&p| {
                    let v = face.feature_vertices[p.index()] as usize;
                    (p, surface.positions_mm[v].distance(at))
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .expect("13 points");
            return Err(Error::algorithm(
                "fem",
                format!(
                    "the layers under the face {mm:.0} mm from the {} stay too distorted after {SURFACE_REPAIRS} local repairs ({e}); the registered surface is creased there: check the feature points or erase the spikes around it",
                    point.name()
                ),
            ));
        }
        // The surface corners of every element still poor at the requested thickness (its
        // nodes modulo the surface vertex count: the extrusion numbers nodes layer by layer),
        // all repaired at once; the element the error named if the plain extrusion shows none.
        let mut hex = crate::fem::layers::extrude(&surface, &params.layers)?;
        let n = surface.vertex_count();
        crate::fem::untangle::untangle(
            &mut hex,
            &crate::mesh::Topology::new(&surface),
            &surface.normals,
            surface.face_count(),
            crate::fem::layers::MIN_SCALED_JACOBIAN,
        );
        let mut poor: Vec<usize> = crate::fem::layers::poor_elements(&hex)
            .into_iter()
            .map(|(e, _, _)| e)
            .collect();
        if poor.is_empty() {
            poor.push(element);
        }
        let corners: Vec<usize> = poor
            .iter()
            .filter_map(|&e| hex.elements.get(e))
            .flat_map(|nodes| nodes.iter().map(|&v| v as usize % n))
            .collect();
        if corners.is_empty() {
            return Err(inverted.unwrap());
        }
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
