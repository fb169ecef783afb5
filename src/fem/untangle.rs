//! Evening out the layers' inner nodes (a "smart" Laplacian): the offset directions of the
//! extrusion converge in creases and diverge on ridges, so an element's deep face can come out
//! skewed while its surface quad is fine. Only the inner node layers move (the skin surface is
//! the scan); a node moves only if that raises the smallest scaled Jacobian of the elements
//! around it. Two moves are tried: straight below the node above it along the surface's own
//! normal (where the smoothed offset direction runs oblique to a crease, the element's
//! vertical edges lie almost in its faces), towards the mean of its neighbours in the same
//! layer (½, ¼ of the way), and down the gradient of `Σ max(0, 0.35 − SJ)²` over the elements
//! around it (central differences along the world axes; steps of ½, ¼, ⅛ of its mean edge),
//! which also mends a sheared band that is its own Laplacian mean.
//!
//! Each pass decides every move from the same positions and then applies them all (Jacobi,
//! not Gauss–Seidel), so the result does not depend on the node order and a mirror-symmetric
//! face stays mirror-symmetric; an element two moved nodes made worse together gets its nodes
//! put back.

use super::HexMesh;
use super::hex8;
use crate::mesh::Topology;
use glam::DVec3;

/// Passes over the nodes of poor elements.
const PASSES: usize = 12;

/// The gradient step pushes the elements around a node above this scaled Jacobian (a margin
/// over the target, so the step does not stop just at it).
const GRADIENT_TARGET: f64 = 0.35;

/// Moves the inner nodes (node layers 1 and 2: under the skin and the cranium) of every element
/// whose scaled Jacobian is at or below `target` (see the module docs). `topology` is the
/// surface's, `normals` its unit vertex normals; `faces` the surface face count (element `f`
/// is the skin element of face `f`, element `faces + f` the fat one). Returns how many nodes
/// moved.
pub fn untangle(
    mesh: &mut HexMesh,
    topology: &Topology,
    normals: &[DVec3],
    faces: usize,
    target: f64,
) -> usize {
    let n = topology.vertex_count();
    let sj = |mesh: &HexMesh, e: usize| hex8::scaled_jacobian(&mesh.element_nodes(e));
    // Elements around node (layer k, vertex v).
    let around = |k: usize, v: usize| -> Vec<usize> {
        let fs = topology.vertex_faces(v).iter().map(|&f| f as usize);
        match k {
            1 => fs.flat_map(|f| [f, faces + f]).collect(),
            _ => fs.map(|f| faces + f).collect(),
        }
    };
    let worst = |mesh: &HexMesh, elements: &[usize]| {
        elements
            .iter()
            .map(|&e| sj(mesh, e))
            .fold(f64::INFINITY, f64::min)
    };
    let mut moved = vec![false; 3 * n];
    for _ in 0..PASSES {
        let quality: Vec<f64> = (0..mesh.elements.len()).map(|e| sj(mesh, e)).collect();
        let mut nodes: Vec<usize> = (0..mesh.elements.len())
            .filter(|&e| quality[e] <= target)
            .flat_map(|e| mesh.elements[e])
            .map(|node| node as usize)
            .filter(|&node| node >= n)
            .collect();
        if nodes.is_empty() {
            break;
        }
        nodes.sort_unstable();
        nodes.dedup();
        // Each node's best move, judged with every other node where it is now.
        let mut moves = Vec::new();
        let mut trial = mesh.clone();
        for &node in &nodes {
            let (k, v) = (node / n, node % n);
            let ring = topology.neighbours(v);
            if ring.is_empty() {
                continue;
            }
            let old = mesh.nodes_mm[node];
            let above = mesh.nodes_mm[(k - 1) * n + v];
            let mean = ring
                .iter()
                .map(|&w| mesh.nodes_mm[k * n + w as usize])
                .sum::<DVec3>()
                / ring.len() as f64;
            let elements = around(k, v);
            let mut best = (worst(mesh, &elements), old);
            let straight = above - normals[v] * (above - old).length();
            let edge = ring
                .iter()
                .map(|&w| (mesh.nodes_mm[k * n + w as usize] - old).length())
                .sum::<f64>()
                / ring.len() as f64;
            let penalty = |trial: &mut HexMesh, at: DVec3| {
                trial.nodes_mm[node] = at;
                elements
                    .iter()
                    .map(|&e| (GRADIENT_TARGET - sj(trial, e)).max(0.0).powi(2))
                    .sum::<f64>()
            };
            let gradient =
                crate::mesh::central_gradient(|at| penalty(&mut trial, at), old, 1e-3 * edge)
                    .normalize_or_zero();
            let down = [0.5, 0.25, 0.125].map(|step| old - gradient * (step * edge));
            let towards = [0.5, 0.25].map(|step| old + step * (mean - old));
            for candidate in [straight, towards[0], towards[1], down[0], down[1], down[2]] {
                trial.nodes_mm[node] = candidate;
                let w = worst(&trial, &elements);
                if w > best.0 {
                    best = (w, candidate);
                }
            }
            trial.nodes_mm[node] = old;
            if best.1 != old {
                moves.push((node, old, best.1));
            }
        }
        if moves.is_empty() {
            break;
        }
        for &(node, _, to) in &moves {
            mesh.nodes_mm[node] = to;
        }
        // Moves that together made an element worse than it was (and poor) are undone.
        let mut undo = vec![false; 3 * n];
        for (e, &before) in quality.iter().enumerate() {
            let now = sj(mesh, e);
            if now < before && now <= target {
                for &node in &mesh.elements[e] {
                    undo[node as usize] = true;
                }
            }
        }
        for &(node, from, _) in &moves {
            if undo[node] {
                mesh.nodes_mm[node] = from;
            } else {
                moved[node] = true;
            }
        }
    }
    moved.iter().filter(|&&m| m).count()
}
