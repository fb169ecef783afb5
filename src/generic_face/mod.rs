//! The project's own generic face (paper section 2, Figure 3b), built procedurally by our code.
//!
//! The paper registers a generic face model (the face area of a head model: 2,777 vertices,
//! 2,676 quads) to every scan and extrudes it into two layers of hexahedra for the FEM. Ours is
//! generated from an analytic surface (`shape.rs`: an elliptic head section per height plus
//! smooth feature bumps) sampled by a structured, feature-aligned grid (`grid.rs`):
//!
//! * all quads (3,420 quads, no triangles, 3,577 vertices), from the forehead to one row
//!   (1.4 mm) under the chin point and round the cheeks to where a frontal scan still sees the face (132 mm wide,
//!   68° round the head section at mid height, narrower along the jaw);
//! * frame: millimetres, looking towards +z, y up, x to the subject's left, **nose tip at the
//!   origin**;
//! * the mouth is a slit between the mouth corners (upper and lower lip are separate
//!   boundaries, a 1.6 mm gap at the centre) and the eyes are almond-shaped holes whose ends are
//!   the eye corners;
//! * the 13 feature points are vertices, placed at the paper's Table 2 average distances
//!   ([`targets`](crate::generic_face::targets));
//! * left/right mirror symmetric to rounding.
//!
//! Users can bring their own model instead: an OBJ plus a sidecar naming the 13 feature-point
//! vertex ids ([`load`](crate::generic_face::load),
//! [`write_sidecar`](crate::generic_face::GenericFace::write_sidecar)).

mod grid;
mod interp;
mod shape;

use crate::feature_points::{FeaturePoint, Landmarks};
use crate::mesh::face_normal;
use crate::{Error, Mesh, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// The paper's Table 2 average inter-anchor distances (mm) that place our feature points, plus
/// the few placements the table does not give.
pub mod targets {
    /// Nose tip → inner eye corner, horizontal.
    pub const NOSE_TO_INNER_EYE_X: f64 = 17.5;
    /// Inner → outer eye corner, horizontal.
    pub const INNER_TO_OUTER_EYE_X: f64 = 30.6;
    /// Nose tip → mouth (corners' height), vertical.
    pub const NOSE_TO_MOUTH_Y: f64 = 34.4;
    /// Nose tip → chin, vertical.
    pub const NOSE_TO_CHIN_Y: f64 = 70.6;
    /// Nose tip → nose bridge (the inner eye corners' height), vertical.
    pub const NOSE_TO_BRIDGE_Y: f64 = 32.2;
    /// Not in Table 2: half the mouth width (mouth corner x), from adult anthropometry.
    pub const MOUTH_HALF_WIDTH_X: f64 = 25.0;
    /// Not in Table 2: height of the forehead point (upper forehead, below the hairline).
    pub const FOREHEAD_Y: f64 = 72.0;
}

/// A generic face: a quad-dominant surface (mm, looking towards +z, y up, nose tip at the
/// origin for the built-in face) and the vertex id of each of the 13 feature points.
#[derive(Debug, Clone)]
pub struct GenericFace {
    pub mesh: Mesh,
    /// Vertex id of each feature point, in [`FeaturePoint::ALL`] order.
    pub feature_vertices: [u32; FeaturePoint::COUNT],
}

impl GenericFace {
    /// The feature points' positions.
    pub fn landmarks(&self) -> Landmarks {
        Landmarks(
            self.feature_vertices
                .map(|v| self.mesh.positions_mm[v as usize]),
        )
    }

    pub fn feature_vertex(&self, p: FeaturePoint) -> u32 {
        self.feature_vertices[p.index()]
    }

    /// The sidecar's content: feature-point name → vertex id.
    pub fn sidecar_map(&self) -> BTreeMap<String, u32> {
        FeaturePoint::ALL
            .into_iter()
            .map(|p| (p.name().to_string(), self.feature_vertex(p)))
            .collect()
    }

    /// Writes the sidecar naming the feature-point vertex ids, as JSON or RON by extension
    /// (`.json`, `.ron`), for [`load`].
    pub fn write_sidecar(&self, path: &Path) -> Result<()> {
        let map = self.sidecar_map();
        let text = match SidecarFormat::from_path(path)? {
            SidecarFormat::Json => serde_json::to_string_pretty(&map)
                .map_err(|e| Error::invalid(path, e.to_string()))?,
            SidecarFormat::Ron => {
                ron::ser::to_string_pretty(&map, ron::ser::PrettyConfig::default())
                    .map_err(|e| Error::invalid(path, e.to_string()))?
            }
        };
        crate::io::write_text_atomic(path, &(text + "\n"))
    }

    /// Writes the mesh (OBJ or PLY by extension) and the sidecar.
    pub fn save(&self, mesh_path: &Path, sidecar_path: &Path) -> Result<()> {
        crate::io::write_mesh(mesh_path, &self.mesh)?;
        self.write_sidecar(sidecar_path)
    }

    /// Quality of the mesh's quads (see [`QuadQuality`]).
    pub fn quad_quality(&self) -> QuadQuality {
        quad_quality(&self.mesh)
    }
}

/// Builds the project's generic face (deterministic; a few milliseconds).
pub fn build() -> GenericFace {
    grid::build()
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SidecarFormat {
    Json,
    Ron,
}

impl SidecarFormat {
    fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        match ext.as_str() {
            "json" => Ok(SidecarFormat::Json),
            "ron" => Ok(SidecarFormat::Ron),
            _ => Err(Error::invalid(
                path,
                "unknown feature-point sidecar format (expected .json or .ron)",
            )),
        }
    }
}

/// Loads a user's generic model: a mesh (OBJ, or any format [`crate::io::read_mesh`] reads)
/// plus a JSON or RON sidecar (by extension) mapping each of the 13 feature-point names to a
/// 0-based vertex id (for OBJ: the order of the `v` lines), e.g.
/// `{"nose_tip": 1234, "inner_eye_left": 877, ...}`; RON also takes `(nose_tip: 1234, ...)`.
///
/// Errors name the file: unreadable mesh or sidecar, a missing or unknown name, an id out of
/// range, two feature points on one vertex.
pub fn load(obj: &Path, sidecar: &Path) -> Result<GenericFace> {
    let mesh = read_mesh_keeping_ids(obj)?;
    let feature_vertices = read_sidecar(sidecar, mesh.vertex_count())?;
    Ok(GenericFace {
        mesh,
        feature_vertices,
    })
}

/// Reads a mesh whose vertex ids are the file's own: for OBJ, the 0-based order of the `v`
/// lines (the general OBJ reader renumbers vertices in order of first use, which would break
/// the sidecar's ids), other formats through [`crate::io::read_mesh`].
fn read_mesh_keeping_ids(path: &Path) -> Result<Mesh> {
    if crate::io::MeshFormat::from_path(path)? != crate::io::MeshFormat::Obj {
        return crate::io::read_mesh(path);
    }
    let limits = crate::io::default_limits();
    let bytes = crate::io::read_file(path, &limits)?;
    let text = String::from_utf8_lossy(&bytes);
    let mut positions = Vec::new();
    let mut faces = crate::mesh::Polygons::new();
    let mut poly = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut xyz = [0.0f64; 3];
                for c in &mut xyz {
                    *c = words
                        .next()
                        .and_then(|w| w.parse().ok())
                        .ok_or_else(|| Error::syntax(path, k + 1, "bad vertex line"))?;
                }
                if positions.len() >= limits.max_vertices {
                    return Err(Error::invalid(
                        path,
                        "more vertices than the reader's limit",
                    ));
                }
                positions.push(glam::DVec3::from_array(xyz));
            }
            Some("f") => {
                poly.clear();
                for w in words {
                    let first = w.split('/').next().unwrap_or("");
                    let i: i64 = first
                        .parse()
                        .map_err(|_| Error::syntax(path, k + 1, format!("bad face index {w:?}")))?;
                    // 1-based; negative counts back from the latest vertex.
                    let id = if i < 0 {
                        positions.len() as i64 + i
                    } else {
                        i - 1
                    };
                    if id < 0 || id >= positions.len() as i64 {
                        return Err(Error::syntax(
                            path,
                            k + 1,
                            format!("face index {i} refers to no vertex defined so far"),
                        ));
                    }
                    poly.push(id as u32);
                }
                faces.push(&poly);
            }
            _ => {}
        }
    }
    let mesh = Mesh::new(positions, faces);
    mesh.validate().map_err(|m| Error::invalid(path, m))?;
    Ok(mesh)
}

/// Reads a feature-point sidecar and checks its ids against a mesh of `vertex_count` vertices.
pub fn read_sidecar(path: &Path, vertex_count: usize) -> Result<[u32; FeaturePoint::COUNT]> {
    let format = SidecarFormat::from_path(path)?;
    let bytes = crate::io::read_file(path, &crate::io::default_limits())?;
    let text = std::str::from_utf8(&bytes)
        .map_err(|_| Error::invalid(path, "feature-point sidecar is not UTF-8 text"))?;
    let map: BTreeMap<String, i64> = match format {
        SidecarFormat::Json => serde_json::from_str(text).map_err(|e| e.to_string()),
        // Through `ron::Value` so both map (`{"nose_tip": 12}`) and struct (`(nose_tip: 12)`)
        // syntax read.
        SidecarFormat::Ron => ron::from_str::<ron::Value>(text)
            .map_err(|e| e.to_string())
            .and_then(|v| v.into_rust().map_err(|e| e.to_string())),
    }
    .map_err(|e| {
        Error::invalid(
            path,
            format!("not a feature-point sidecar (name → vertex id map): {e}"),
        )
    })?;
    feature_ids_from_map(&map, vertex_count).map_err(|m| Error::invalid(path, m))
}

fn feature_ids_from_map(
    map: &BTreeMap<String, i64>,
    vertex_count: usize,
) -> std::result::Result<[u32; FeaturePoint::COUNT], String> {
    let mut ids = [None::<u32>; FeaturePoint::COUNT];
    for (name, &id) in map {
        let p = FeaturePoint::from_name(name).ok_or_else(|| {
            format!(
                "unknown feature point {name:?} (expected: {})",
                FeaturePoint::ALL.map(|p| p.name()).join(", ")
            )
        })?;
        if id < 0 || id as u64 >= vertex_count as u64 {
            return Err(format!(
                "feature point {name} refers to vertex {id}, but the mesh has {vertex_count} \
                 vertices (ids are 0-based)"
            ));
        }
        ids[p.index()] = Some(id as u32);
    }
    let mut out = [0u32; FeaturePoint::COUNT];
    for p in FeaturePoint::ALL {
        out[p.index()] =
            ids[p.index()].ok_or_else(|| format!("feature point {} is missing", p.name()))?;
    }
    for (a, b) in FeaturePoint::ALL
        .iter()
        .enumerate()
        .flat_map(|(k, a)| FeaturePoint::ALL[k + 1..].iter().map(move |b| (*a, *b)))
    {
        if out[a.index()] == out[b.index()] {
            return Err(format!(
                "feature points {a} and {b} both use vertex {}",
                out[a.index()]
            ));
        }
    }
    Ok(out)
}

/// Shape quality of a mesh's quads (triangles and larger polygons are not counted).
///
/// * **Scaled Jacobian** of a corner: `((e₁ × e₂) · n) / (|e₁| |e₂|)` with `e₁`, `e₂` the two
///   edges leaving the corner (counter-clockwise order) and `n` the quad's unit normal: the sine
///   of the corner angle, 1 for a right angle, ≤ 0 for a reflex or folded corner. A quad's
///   value is its worst corner.
/// * **Edge ratio**: longest over shortest edge of a quad.
/// * **Warp**: angle between the normals of the two triangles that split the quad along either
///   diagonal (the larger), 0° for a planar quad.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct QuadQuality {
    pub quads: usize,
    pub min_scaled_jacobian: f64,
    pub mean_scaled_jacobian: f64,
    pub max_edge_ratio: f64,
    pub mean_edge_ratio: f64,
    pub min_edge_mm: f64,
    pub max_edge_mm: f64,
    pub max_warp_deg: f64,
}

/// Measures [`QuadQuality`] over all quads of `mesh`.
pub fn quad_quality(mesh: &Mesh) -> QuadQuality {
    let mut q = QuadQuality {
        quads: 0,
        min_scaled_jacobian: f64::INFINITY,
        mean_scaled_jacobian: 0.0,
        max_edge_ratio: 0.0,
        mean_edge_ratio: 0.0,
        min_edge_mm: f64::INFINITY,
        max_edge_mm: 0.0,
        max_warp_deg: 0.0,
    };
    let p = &mesh.positions_mm;
    for poly in mesh.faces.iter().filter(|f| f.len() == 4) {
        let c = [0, 1, 2, 3].map(|k| p[poly[k] as usize]);
        let n = face_normal(p, poly).normalize_or_zero();
        let mut sj = f64::INFINITY;
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for k in 0..4 {
            let e1 = c[(k + 1) % 4] - c[k];
            let e2 = c[(k + 3) % 4] - c[k];
            let (l1, l2) = (e1.length(), e2.length());
            let j = if l1 > 0.0 && l2 > 0.0 {
                e1.cross(e2).dot(n) / (l1 * l2)
            } else {
                -1.0
            };
            sj = sj.min(j);
            lo = lo.min(l1);
            hi = hi.max(l1);
        }
        let warp = |a: usize| {
            let (p0, p1, p2, p3) = (c[a], c[(a + 1) % 4], c[(a + 2) % 4], c[(a + 3) % 4]);
            let n1 = (p1 - p0).cross(p2 - p0).normalize_or_zero();
            let n2 = (p2 - p0).cross(p3 - p0).normalize_or_zero();
            n1.dot(n2).clamp(-1.0, 1.0).acos().to_degrees()
        };
        let ratio = if lo > 0.0 { hi / lo } else { f64::INFINITY };
        q.quads += 1;
        q.min_scaled_jacobian = q.min_scaled_jacobian.min(sj);
        q.mean_scaled_jacobian += sj;
        q.max_edge_ratio = q.max_edge_ratio.max(ratio);
        q.mean_edge_ratio += ratio;
        q.min_edge_mm = q.min_edge_mm.min(lo);
        q.max_edge_mm = q.max_edge_mm.max(hi);
        q.max_warp_deg = q.max_warp_deg.max(warp(0).max(warp(1)));
    }
    if q.quads > 0 {
        q.mean_scaled_jacobian /= q.quads as f64;
        q.mean_edge_ratio /= q.quads as f64;
    } else {
        q.min_scaled_jacobian = 0.0;
        q.min_edge_mm = 0.0;
    }
    q
}

/// The mesh's boundary loops (outer border, eye holes, mouth), each a closed vertex cycle
/// following the boundary edges. Assumes a manifold boundary (each boundary vertex on exactly
/// two boundary edges); vertices where that fails end a loop early.
pub fn boundary_loops(mesh: &Mesh) -> Vec<Vec<u32>> {
    // Directed boundary edges: an edge used by one face, in that face's orientation.
    let mut count: std::collections::HashMap<(u32, u32), (u32, (u32, u32))> =
        std::collections::HashMap::new();
    for poly in mesh.faces.iter() {
        for (k, &a) in poly.iter().enumerate() {
            let b = poly[(k + 1) % poly.len()];
            let e = count.entry((a.min(b), a.max(b))).or_insert((0, (a, b)));
            e.0 += 1;
        }
    }
    let mut next: std::collections::HashMap<u32, u32> = count
        .values()
        .filter(|(n, _)| *n == 1)
        .map(|&(_, (a, b))| (a, b))
        .collect();
    let mut starts: Vec<u32> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut loops = Vec::new();
    for s in starts {
        let Some(mut v) = next.remove(&s) else {
            continue;
        };
        let mut lp = vec![s];
        while v != s {
            lp.push(v);
            match next.remove(&v) {
                Some(w) => v = w,
                None => break,
            }
        }
        loops.push(lp);
    }
    loops
}

#[cfg(test)]
mod tests;
