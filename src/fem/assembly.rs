//! Global assembly of the reduced stiffness matrix into a precomputed sparsity pattern.
//!
//! The pattern (upper triangle, compressed sparse columns, over the **free** DOFs only) and a
//! scatter map from every element's 24×24 entries to their slots are built once per mesh and
//! fixed-node set. Stiffness is linear in Young's modulus, so for every material group we keep
//! the values assembled at E = 1 Pa ("unit" matrices); the reduced matrix for any moduli is then
//! `K = Σ_g E_g · K_g`, one pass over the nonzeros — a modulus change costs that pass plus a
//! numeric refactorization, never a new pattern.

use super::HexMesh;
use super::hex8::{self, ElementError};
use crate::{FemError, Result};

/// Marks a fixed DOF (or an element entry that is not assembled) in the maps below.
pub const NONE: u32 = u32::MAX;

/// The reduced stiffness system on a fixed pattern.
#[derive(Debug, Clone)]
pub struct ReducedSystem {
    /// `free_index[dof]`: position of DOF `3·node + axis` among the free DOFs, or [`NONE`].
    pub free_index: Vec<u32>,
    /// The free DOFs in increasing order.
    pub free_dofs: Vec<u32>,
    /// CSC column pointers of the upper triangle (`row ≤ col`), length `free + 1`.
    pub col_ptr: Vec<usize>,
    /// CSC row indices, sorted within each column.
    pub row_idx: Vec<usize>,
    /// `scatter[576·e + 24·p + q]`: slot of element `e`'s entry `(p, q)`, or [`NONE`].
    scatter: Vec<u32>,
    /// Per material group: the matrix values at E = 1 Pa (N/mm per Pa).
    unit_values: Vec<Vec<f64>>,
    /// Poisson ratio each unit matrix was computed with.
    unit_poisson: Vec<f64>,
    /// The current matrix values (N/mm).
    pub values: Vec<f64>,
}

impl ReducedSystem {
    /// Builds the pattern and scatter map for `mesh` with the nodes in `fixed` held in place,
    /// and assembles the unit matrix of every material group (`poisson_ratio[g]` per group).
    ///
    /// Errors: no fixed node, a part with no fixed node, an invalid Poisson ratio, an inverted
    /// element.
    pub fn new(mesh: &HexMesh, fixed: &[bool], poisson_ratio: &[f64]) -> Result<Self> {
        let n_nodes = mesh.nodes_mm.len();
        assert_eq!(fixed.len(), n_nodes, "one fixed flag per node");
        check_constraints(mesh, fixed)?;
        let mut free_index = vec![NONE; 3 * n_nodes];
        let mut free_dofs = Vec::new();
        for node in 0..n_nodes {
            if !fixed[node] {
                for axis in 0..3 {
                    free_index[3 * node + axis] = free_dofs.len() as u32;
                    free_dofs.push((3 * node + axis) as u32);
                }
            }
        }
        // Node adjacency through elements (each list sorted, self included).
        let mut adjacency: Vec<Vec<u32>> = vec![Vec::new(); n_nodes];
        for element in &mesh.elements {
            for &a in element {
                adjacency[a as usize].extend_from_slice(element);
            }
        }
        for list in &mut adjacency {
            list.sort_unstable();
            list.dedup();
        }
        let n_free = free_dofs.len();
        let mut col_ptr = Vec::with_capacity(n_free + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for &dof in &free_dofs {
            let j = free_index[dof as usize];
            let node = dof as usize / 3;
            for &a in &adjacency[node] {
                for axis in 0..3 {
                    let i = free_index[3 * a as usize + axis];
                    if i != NONE && i <= j {
                        row_idx.push(i as usize);
                    }
                }
            }
            col_ptr.push(row_idx.len());
        }
        let mut scatter = vec![NONE; 576 * mesh.elements.len()];
        for (e, element) in mesh.elements.iter().enumerate() {
            for p in 0..24 {
                let i = free_index[3 * element[p / 3] as usize + p % 3];
                if i == NONE {
                    continue;
                }
                for q in 0..24 {
                    let j = free_index[3 * element[q / 3] as usize + q % 3];
                    if j == NONE || i > j {
                        continue;
                    }
                    let column = &row_idx[col_ptr[j as usize]..col_ptr[j as usize + 1]];
                    let slot = column
                        .binary_search(&(i as usize))
                        .expect("pattern holds every element entry");
                    scatter[576 * e + 24 * p + q] = (col_ptr[j as usize] + slot) as u32;
                }
            }
        }
        let groups = poisson_ratio.len();
        let nnz = row_idx.len();
        let mut system = ReducedSystem {
            free_index,
            free_dofs,
            col_ptr,
            row_idx,
            scatter,
            unit_values: vec![vec![0.0; nnz]; groups],
            unit_poisson: vec![f64::NAN; groups],
            values: vec![0.0; nnz],
        };
        for g in 0..groups {
            system.set_poisson_ratio(mesh, g, poisson_ratio[g])?;
        }
        Ok(system)
    }

    /// Number of free DOFs (the reduced matrix's size).
    pub fn dofs(&self) -> usize {
        self.free_dofs.len()
    }

    /// Stored nonzeros of the upper triangle.
    pub fn nonzeros(&self) -> usize {
        self.row_idx.len()
    }

    /// Re-assembles group `g`'s unit matrix with a new Poisson ratio (element stiffness is not
    /// linear in ν). Costs one pass over that group's elements.
    pub fn set_poisson_ratio(
        &mut self,
        mesh: &HexMesh,
        g: usize,
        poisson_ratio: f64,
    ) -> Result<()> {
        if self.unit_poisson[g] == poisson_ratio {
            return Ok(());
        }
        use rayon::prelude::*;
        let values = &mut self.unit_values[g];
        values.iter_mut().for_each(|v| *v = 0.0);
        let group: Vec<usize> = (0..mesh.elements.len())
            .filter(|&e| mesh.element_group[e] as usize == g)
            .collect();
        // Element matrices in parallel, a chunk at a time (bounded memory); scatter serially
        // so the sums are deterministic for any thread count.
        for chunk in group.chunks(512) {
            let ks: Vec<hex8::ElementStiffness> = chunk
                .par_iter()
                .map(|&e| {
                    hex8::element_stiffness(&mesh.element_nodes(e), 1.0, poisson_ratio).map_err(
                        |err| match err {
                            ElementError::Inverted { min_det } => FemError::InvertedElement {
                                element: e,
                                min_jacobian_det: min_det,
                            },
                            ElementError::Material => FemError::InvalidMaterial {
                                layer: mesh.group_names.get(g).cloned().unwrap_or_default(),
                                young_modulus_pa: 1.0,
                                poisson_ratio,
                            },
                        },
                    )
                })
                .collect::<std::result::Result<_, FemError>>()?;
            for (&e, k) in chunk.iter().zip(&ks) {
                let map = &self.scatter[576 * e..576 * (e + 1)];
                for p in 0..24 {
                    for q in 0..24 {
                        let slot = map[24 * p + q];
                        if slot != NONE {
                            values[slot as usize] += k[(p, q)];
                        }
                    }
                }
            }
        }
        self.unit_poisson[g] = poisson_ratio;
        Ok(())
    }

    /// `values = Σ_g young_modulus_pa[g] · unit_g` (one pass over the nonzeros).
    pub fn combine(&mut self, young_modulus_pa: &[f64]) {
        assert_eq!(young_modulus_pa.len(), self.unit_values.len());
        self.values.iter_mut().for_each(|v| *v = 0.0);
        for (unit, &e) in self.unit_values.iter().zip(young_modulus_pa) {
            for (v, u) in self.values.iter_mut().zip(unit) {
                *v += e * u;
            }
        }
    }

    /// `y = K x` with the symmetric matrix stored as its upper triangle.
    pub fn multiply(&self, x: &[f64], y: &mut [f64]) {
        symmetric_upper_multiply(&self.col_ptr, &self.row_idx, &self.values, x, y);
    }

    /// Gathers the free entries of a full (3 per node) vector.
    pub fn restrict(&self, full: &[f64]) -> Vec<f64> {
        self.free_dofs.iter().map(|&d| full[d as usize]).collect()
    }

    /// Scatters a reduced vector to a full one (fixed DOFs zero).
    pub fn extend(&self, reduced: &[f64], full: &mut [f64]) {
        full.iter_mut().for_each(|v| *v = 0.0);
        for (k, &d) in self.free_dofs.iter().enumerate() {
            full[d as usize] = reduced[k];
        }
    }
}

/// Rejects constraint sets that leave the system singular: no fixed node at all, or a connected
/// part of the mesh (through elements) held by fewer than three non-collinear fixed nodes.
fn check_constraints(mesh: &HexMesh, fixed: &[bool]) -> Result<()> {
    if !fixed.iter().any(|&f| f) {
        return Err(FemError::NoFixedNodes.into());
    }
    let n = mesh.nodes_mm.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    for element in &mesh.elements {
        let r0 = find(&mut parent, element[0] as usize);
        for &b in &element[1..] {
            let rb = find(&mut parent, b as usize);
            if rb != r0 {
                parent[rb] = r0;
            }
        }
    }
    // A part is held when it has three non-collinear fixed nodes (fewer leave a rigid
    // rotation free and the matrix singular).
    let (mut lo, mut hi) = (
        glam::DVec3::splat(f64::INFINITY),
        glam::DVec3::splat(f64::NEG_INFINITY),
    );
    for p in &mesh.nodes_mm {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let eps = 1e-6 * (hi - lo).length().max(1e-300);
    let mut first: Vec<Option<glam::DVec3>> = vec![None; n];
    let mut second: Vec<Option<glam::DVec3>> = vec![None; n];
    let mut anchored = vec![false; n];
    for node in 0..n {
        if !fixed[node] {
            continue;
        }
        let r = find(&mut parent, node);
        let p = mesh.nodes_mm[node];
        match (first[r], second[r]) {
            (None, _) => first[r] = Some(p),
            (Some(p0), None) => {
                if (p - p0).length() > eps {
                    second[r] = Some(p);
                }
            }
            (Some(p0), Some(p1)) => {
                if (p - p0).cross(p1 - p0).length() > eps * (p1 - p0).length() {
                    anchored[r] = true;
                }
            }
        }
    }
    // A free node in no element is floating too (its rows would be empty).
    let floating = (0..n)
        .filter(|&node| !fixed[node] && !anchored[find(&mut parent, node)])
        .count();
    if floating > 0 {
        return Err(FemError::FloatingPart {
            free_nodes: floating,
        }
        .into());
    }
    Ok(())
}

/// `y = A x` for a symmetric matrix given by its upper triangle in CSC form.
pub fn symmetric_upper_multiply(
    col_ptr: &[usize],
    row_idx: &[usize],
    values: &[f64],
    x: &[f64],
    y: &mut [f64],
) {
    y.iter_mut().for_each(|v| *v = 0.0);
    for j in 0..col_ptr.len() - 1 {
        for k in col_ptr[j]..col_ptr[j + 1] {
            let i = row_idx[k];
            let v = values[k];
            y[i] += v * x[j];
            if i != j {
                y[j] += v * x[i];
            }
        }
    }
}
