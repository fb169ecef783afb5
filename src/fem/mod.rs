//! The layered hexahedral finite-element face (paper section 2).
//!
//! Pipeline: [`layers::extrude`] offsets the (registered) generic surface into 3 node layers /
//! 2 element layers; [`assembly::ReducedSystem`] assembles linear isotropic [`hex8`] stiffness
//! over the free DOFs into a fixed sparsity pattern; [`solver::CachedCholesky`] factors it once;
//! [`muscles`] turn 18 feature-point-relative muscle definitions into nodal forces; the muscle
//! basis `u_i = K⁻¹ f_i` is solved once, after which any expression
//! ([`expressions`]) is `u = Σ a_i u_i` — a slider change is an 18-term sum (22 with the jaw), not a solve.
//! [`jaw`] adds four actuators after the muscles (open, left, right, forward): prescribed motions of
//! the bone under the lower face, solved into basis vectors the same way (`K_ff u_f = −K_fp
//! u_p`), so an expression is an 18 + 4-term sum.
//!
//! **Units:** positions and displacements mm, forces N, Young's moduli Pa (converted to
//! N/mm² = MPa inside [`hex8`]), so stiffness is N/mm.
//!
//! [`FaceModel`] is the stateful object a GUI worker thread keeps: build it from a mesh + the
//! 13 feature-point vertex ids, then factor, compute the basis, change a modulus (numeric
//! refactor only), re-solve one muscle, and combine activations.

pub mod anchor;
pub mod assembly;
pub mod compare;
pub mod expressions;
pub mod fit;
pub mod hex8;
pub mod jaw;
pub mod layers;
pub mod muscles;
pub mod picture;
pub mod regions;
pub mod repair;
pub mod solver;
pub mod untangle;
pub mod vtk;

use crate::feature_points::FeaturePoint;
use crate::generic_face::GenericFace;
use crate::{FemError, Mesh, Result};
use assembly::ReducedSystem;
use glam::DVec3;
use layers::{ElementQuality, LayerParams};
use muscles::{Muscle, MuscleSet};
use solver::CachedCholesky;
use std::time::Instant;

/// Material group of the skin elements (top element layer).
pub const SKIN: u8 = 0;
/// Material group of the fatty-tissue elements (bottom element layer).
pub const FAT: u8 = 1;

/// A hexahedral mesh (hex8, VTK node order) with a material group per element.
#[derive(Debug, Clone, Default)]
pub struct HexMesh {
    /// Node positions, mm.
    pub nodes_mm: Vec<DVec3>,
    /// 8 node ids per element.
    pub elements: Vec<[u32; 8]>,
    /// Material group of each element (index into the model's materials).
    pub element_group: Vec<u8>,
    /// A name per material group (for messages and exports).
    pub group_names: Vec<String>,
}

impl HexMesh {
    /// The 8 node positions of element `e`.
    pub fn element_nodes(&self, e: usize) -> [DVec3; 8] {
        self.elements[e].map(|n| self.nodes_mm[n as usize])
    }

    /// A structured `nx × ny × nz`-element box `[0, size.x] × [0, size.y] × [0, size.z]` (one
    /// material group), for tests and benchmarks. Node `(i, j, k)` is `i + (nx+1)(j + (ny+1)k)`.
    pub fn block(size_mm: DVec3, nx: usize, ny: usize, nz: usize) -> HexMesh {
        let id = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
        let mut nodes_mm = Vec::new();
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    nodes_mm.push(DVec3::new(
                        size_mm.x * i as f64 / nx as f64,
                        size_mm.y * j as f64 / ny as f64,
                        size_mm.z * k as f64 / nz as f64,
                    ));
                }
            }
        }
        let mut elements = Vec::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    elements.push([
                        id(i, j, k),
                        id(i + 1, j, k),
                        id(i + 1, j + 1, k),
                        id(i, j + 1, k),
                        id(i, j, k + 1),
                        id(i + 1, j, k + 1),
                        id(i + 1, j + 1, k + 1),
                        id(i, j + 1, k + 1),
                    ]);
                }
            }
        }
        let count = elements.len();
        HexMesh {
            nodes_mm,
            elements,
            element_group: vec![0; count],
            group_names: vec!["block".into()],
        }
    }
}

/// Linear isotropic material of one layer.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Material {
    /// Young's modulus, Pa (> 0).
    pub young_modulus_pa: f64,
    /// Poisson ratio, in (−1, 0.5); 0.45 models quasi-incompressible tissue.
    pub poisson_ratio: f64,
}

impl Material {
    fn check(&self, layer: &str) -> Result<()> {
        if !(self.young_modulus_pa > 0.0
            && self.young_modulus_pa.is_finite()
            && self.poisson_ratio > -1.0
            && self.poisson_ratio < 0.5)
        {
            return Err(FemError::InvalidMaterial {
                layer: layer.into(),
                young_modulus_pa: self.young_modulus_pa,
                poisson_ratio: self.poisson_ratio,
            }
            .into());
        }
        Ok(())
    }
}

/// The forces of a solved field ([`FaceModel::equilibrium`]).
#[derive(Debug, Clone)]
pub struct Equilibrium {
    /// Support force on each node (N): `K u − f` at the fixed nodes, zero at the free ones.
    pub reaction_n: Vec<DVec3>,
    /// `Σ f` over all nodes (N), loads on fixed nodes included (the supports take those).
    pub applied_sum_n: DVec3,
    /// `Σ reactions` (N). Rigid translations are in the stiffness's null space, so this is
    /// `−applied_sum_n` up to round-off; a jaw motion without loads gives zero.
    pub reaction_sum_n: DVec3,
    /// Largest `|K u − f|` over the free nodes (N): what the solve left unbalanced.
    pub free_residual_n: f64,
}

/// Parameters of the face model. Defaults are the paper's (section 2, after its ref. 14).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FemParams {
    /// Layer thicknesses (default skin 3 mm + fat 9 mm).
    pub layers: LayerParams,
    /// Skin: E = 5.6 kPa, ν = 0.45.
    pub skin: Material,
    /// Fatty tissue: E = 0.12 kPa, ν = 0.45.
    pub fat: Material,
    /// How much of the face's outer border is held (all three layers): 1 = its boundary loop
    /// (the paper's border nodes, default), k = that loop and the k − 1 vertex rings inside it,
    /// 0 = none (only the cranium layer holds the face). Files without the field get 1.
    #[serde(default = "default_fixed_border_rings")]
    pub fixed_border_rings: usize,
}

fn default_fixed_border_rings() -> usize {
    1
}

impl Default for FemParams {
    fn default() -> Self {
        FemParams {
            layers: LayerParams::default(),
            skin: Material {
                young_modulus_pa: 5600.0,
                poisson_ratio: 0.45,
            },
            fat: Material {
                young_modulus_pa: 120.0,
                poisson_ratio: 0.45,
            },
            fixed_border_rings: default_fixed_border_rings(),
        }
    }
}

/// Wall-clock times of the last operations, milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Timings {
    /// Layer extrusion (normal smoothing, inversion checks) and element quality.
    pub extrusion_millis: f64,
    /// Pattern + scatter map + unit matrices (per-element stiffness).
    pub assembly_millis: f64,
    /// Symbolic analysis (once per pattern).
    pub analysis_millis: f64,
    /// Combining the unit matrices and the numeric factorization.
    pub factor_millis: f64,
    /// Solving the whole muscle basis.
    pub basis_millis: f64,
}

/// The face FEM model: the layered volume, its boundary conditions, the cached factorization
/// and the muscle basis.
#[derive(Debug, Clone)]
pub struct FaceModel {
    /// The skin surface (the first `surface.vertex_count()` nodes of `volume`).
    pub surface: Mesh,
    /// Vertex id of each feature point on `surface`, in [`FeaturePoint::ALL`] order.
    pub feature_vertices: [u32; FeaturePoint::COUNT],
    pub params: FemParams,
    /// The two-layer hexahedral volume.
    pub volume: HexMesh,
    /// Shape quality of `volume`'s elements.
    pub quality: ElementQuality,
    /// What the extrusion changed to keep every element valid.
    pub extrusion: layers::ExtrusionFix,
    fixed: Vec<bool>,
    system: ReducedSystem,
    solver: CachedCholesky,
    muscles: Vec<Muscle>,
    /// The jaw's actuators, after the muscles (none if the muscle set defines no jaw).
    jaw: Option<jaw::Jaw>,
    /// Per actuator (muscles, then the jaw's): full nodal displacement (3 per node, mm) at unit
    /// activation; empty if stale.
    basis: Vec<Vec<f64>>,
    pub timings: Timings,
}

impl FaceModel {
    /// Builds the layered volume of `surface`, fixes the cranium layer and the face's outer
    /// border, assembles and analyses the system (not yet factored; see [`factor`](Self::factor)).
    ///
    /// Errors on invalid materials or thicknesses, an inverted element, non-extrudable faces.
    pub fn new(
        surface: &Mesh,
        feature_vertices: [u32; FeaturePoint::COUNT],
        params: &FemParams,
    ) -> Result<Self> {
        params.skin.check("skin")?;
        params.fat.check("fat")?;
        if let Some(&v) = feature_vertices
            .iter()
            .find(|&&v| v as usize >= surface.vertex_count())
        {
            return Err(FemError::Definition(format!(
                "feature-point vertex {v} is not a vertex of the surface"
            ))
            .into());
        }
        let start = Instant::now();
        let (volume, extrusion) = layers::extrude_valid(surface, &params.layers)?;
        let quality = layers::element_quality(&volume);
        let extrusion_millis = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        let fixed = fixed_nodes(surface, params.fixed_border_rings);
        let system = ReducedSystem::new(
            &volume,
            &fixed,
            &[params.skin.poisson_ratio, params.fat.poisson_ratio],
        )?;
        let assembly_millis = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        let solver = CachedCholesky::analyze(system.dofs(), &system.col_ptr, &system.row_idx)?;
        let analysis_millis = start.elapsed().as_secs_f64() * 1e3;
        Ok(FaceModel {
            surface: surface.clone(),
            feature_vertices,
            params: FemParams {
                layers: LayerParams {
                    normal_smoothing_rounds: extrusion.normal_smoothing_rounds,
                    ..params.layers
                },
                ..*params
            },
            volume,
            quality,
            extrusion,
            fixed,
            system,
            solver,
            muscles: Vec::new(),
            jaw: None,
            basis: Vec::new(),
            timings: Timings {
                extrusion_millis,
                assembly_millis,
                analysis_millis,
                ..Timings::default()
            },
        })
    }

    /// [`FaceModel::new`] on a generic (or registered generic) face.
    pub fn from_generic(face: &GenericFace, params: &FemParams) -> Result<Self> {
        Self::new(&face.mesh, face.feature_vertices, params)
    }

    /// Free DOFs of the reduced system.
    pub fn dofs(&self) -> usize {
        self.system.dofs()
    }

    /// Hexahedra in the volume.
    pub fn elements(&self) -> usize {
        self.volume.elements.len()
    }

    /// The reduced system (pattern, values), e.g. for checks.
    pub fn system(&self) -> &ReducedSystem {
        &self.system
    }

    /// The cached factorization (its size and how its single solve is split).
    pub fn solver(&self) -> &CachedCholesky {
        &self.solver
    }

    /// Which volume nodes are held in place (or, under the lower face, moved by the jaw's
    /// prescribed motion: see [`jaw`]).
    pub fn fixed_nodes(&self) -> &[bool] {
        &self.fixed
    }

    /// Replaces the fixed-node set (one flag per volume node): rebuilds the pattern, re-analyses
    /// and drops the factor and basis. Errors if the new set leaves the system singular.
    pub fn set_fixed_nodes(&mut self, fixed: Vec<bool>) -> Result<()> {
        if fixed.len() != self.volume.nodes_mm.len() {
            return Err(FemError::Definition(format!(
                "{} fixed flags for {} nodes",
                fixed.len(),
                self.volume.nodes_mm.len()
            ))
            .into());
        }
        let start = Instant::now();
        let system = ReducedSystem::new(
            &self.volume,
            &fixed,
            &[
                self.params.skin.poisson_ratio,
                self.params.fat.poisson_ratio,
            ],
        )?;
        if self.jaw.as_ref().is_some_and(|jaw| !jaw.moves_some(&fixed)) {
            return Err(FemError::Definition(
                "no fixed node would be left under the jaw to move it (turn the jaw off with `jaw: None` in the muscle set)".into(),
            )
            .into());
        }
        self.timings.assembly_millis = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        self.solver = CachedCholesky::analyze(system.dofs(), &system.col_ptr, &system.row_idx)?;
        self.timings.analysis_millis = start.elapsed().as_secs_f64() * 1e3;
        self.system = system;
        self.fixed = fixed;
        self.basis.clear();
        Ok(())
    }

    /// Changes the layer materials. A Young's-modulus change only recombines the unit
    /// matrices; a Poisson-ratio change re-assembles that layer. Drops the factor and basis
    /// (call [`factor`](Self::factor) and [`compute_basis`](Self::compute_basis) again).
    pub fn set_materials(&mut self, skin: Material, fat: Material) -> Result<()> {
        skin.check("skin")?;
        fat.check("fat")?;
        self.system
            .set_poisson_ratio(&self.volume, SKIN as usize, skin.poisson_ratio)?;
        self.system
            .set_poisson_ratio(&self.volume, FAT as usize, fat.poisson_ratio)?;
        self.params.skin = skin;
        self.params.fat = fat;
        self.solver.invalidate();
        self.basis.clear();
        Ok(())
    }

    /// Combines the unit matrices with the current moduli and factors (numeric only).
    pub fn factor(&mut self) -> Result<()> {
        let start = Instant::now();
        self.system.combine(&[
            self.params.skin.young_modulus_pa,
            self.params.fat.young_modulus_pa,
        ]);
        self.solver.factor(
            &self.system.col_ptr,
            &self.system.row_idx,
            &self.system.values,
        )?;
        self.timings.factor_millis = start.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// Whether the current matrix is factored.
    pub fn is_factored(&self) -> bool {
        self.solver.is_factored()
    }

    fn ensure_factored(&mut self) -> Result<()> {
        if !self.solver.is_factored() {
            self.factor()?;
        }
        Ok(())
    }

    /// Solves `K u = f` for nodal forces `forces_n` (one per volume node, N; forces on fixed
    /// nodes are ignored) and returns the nodal displacements (mm; fixed nodes 0). Uses the
    /// cached factor (factoring first if needed).
    pub fn solve(&mut self, forces_n: &[DVec3]) -> Result<Vec<DVec3>> {
        self.ensure_factored()?;
        let full = flatten(forces_n);
        let mut rhs = self.system.restrict(&full);
        self.solver.solve_in_place(&mut rhs)?;
        let mut out = vec![0.0; full.len()];
        self.system.extend(&rhs, &mut out);
        Ok(unflatten(&out))
    }

    /// Resolves the muscle (and jaw) definitions against this face's feature points and drops
    /// the basis.
    pub fn set_muscles(&mut self, set: &MuscleSet) -> Result<()> {
        // Both resolve before either is stored, so a failure leaves the model as it was.
        let muscles = set.resolve(self)?;
        let jaw = set.jaw.as_ref().map(|def| def.resolve(self)).transpose()?;
        self.muscles = muscles;
        self.jaw = jaw;
        self.basis.clear();
        Ok(())
    }

    /// The resolved jaw, if the muscle set defines one.
    pub fn jaw(&self) -> Option<&jaw::Jaw> {
        self.jaw.as_ref()
    }

    /// Actuator names in basis / activation order: the muscles, then `jaw_open`, `jaw_left`,
    /// `jaw_right`, `jaw_forward` when there is a jaw.
    pub fn actuator_names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.muscles.iter().map(|m| m.name.clone()).collect();
        if self.jaw.is_some() {
            names.extend(jaw::ACTUATORS.iter().map(|s| s.to_string()));
        }
        names
    }

    /// Number of actuators (length of an activation vector).
    pub fn actuator_count(&self) -> usize {
        self.muscles.len()
            + if self.jaw.is_some() {
                jaw::ACTUATORS.len()
            } else {
                0
            }
    }

    /// The element stiffness of element `e` with its layer's material (N/mm).
    fn element_stiffness(&self, e: usize) -> Result<hex8::ElementStiffness> {
        let material = match self.volume.element_group[e] {
            SKIN => self.params.skin,
            _ => self.params.fat,
        };
        hex8::element_stiffness(
            &self.volume.element_nodes(e),
            material.young_modulus_pa,
            material.poisson_ratio,
        )
        .map_err(|_| FemError::Definition(format!("element {e} is invalid")).into())
    }

    /// `K_e u` of each field summed into nodal forces (N, one per node and field) over the
    /// given elements; each element matrix is computed once for all fields.
    fn element_forces(&self, elements: &[usize], fields: &[&[DVec3]]) -> Result<Vec<Vec<DVec3>>> {
        use rayon::prelude::*;
        let per_element: Vec<Vec<nalgebra::SVector<f64, 24>>> = elements
            .par_iter()
            .map(|&e| {
                let k = self.element_stiffness(e)?;
                let nodes = self.volume.elements[e];
                Ok(fields
                    .iter()
                    .map(|u| k * hex8::stack(&nodes.map(|n| u[n as usize])))
                    .collect())
            })
            .collect::<Result<_>>()?;
        let mut out = vec![vec![DVec3::ZERO; self.volume.nodes_mm.len()]; fields.len()];
        for (&e, per_field) in elements.iter().zip(per_element) {
            for (out, f) in out.iter_mut().zip(per_field) {
                for (a, &node) in self.volume.elements[e].iter().enumerate() {
                    out[node as usize] += DVec3::new(f[3 * a], f[3 * a + 1], f[3 * a + 2]);
                }
            }
        }
        Ok(out)
    }

    /// The internal nodal forces `K u` (N) of a displacement field over all nodes (mm),
    /// assembled element by element from the full, unconstrained stiffness.
    pub fn internal_forces(&self, displacement_mm: &[DVec3]) -> Result<Vec<DVec3>> {
        let n = self.volume.nodes_mm.len();
        if displacement_mm.len() != n {
            return Err(FemError::Definition(format!(
                "{} displacements for {n} nodes",
                displacement_mm.len()
            ))
            .into());
        }
        let all: Vec<usize> = (0..self.volume.elements.len()).collect();
        Ok(self
            .element_forces(&all, &[displacement_mm])?
            .pop()
            .unwrap_or_default())
    }

    /// Reactions and the balance of forces for a solved field `u` under loads `f` (both one
    /// per node). See [`Equilibrium`].
    pub fn equilibrium(&self, displacement_mm: &[DVec3], force_n: &[DVec3]) -> Result<Equilibrium> {
        let mut r = self.internal_forces(displacement_mm)?;
        let mut free_residual_n = 0.0f64;
        for ((r, &fixed), f) in r.iter_mut().zip(self.fixed_nodes()).zip(force_n) {
            let rest = *r - *f;
            if fixed {
                *r = rest;
            } else {
                free_residual_n = free_residual_n.max(rest.length());
                *r = DVec3::ZERO;
            }
        }
        Ok(Equilibrium {
            applied_sum_n: force_n.iter().sum(),
            reaction_sum_n: r.iter().sum(),
            reaction_n: r,
            free_residual_n,
        })
    }

    /// The reduced right-hand sides `−K_fp u_p` of several prescribed displacement fields
    /// `u_p` on fixed nodes, element by element: only elements that touch a moving node, each
    /// element matrix computed once for all fields.
    fn prescribed_rhs(&self, fields: &[Vec<DVec3>]) -> Result<Vec<Vec<f64>>> {
        let touched: Vec<usize> = (0..self.volume.elements.len())
            .filter(|&e| {
                self.volume.elements[e]
                    .iter()
                    .any(|&n| fields.iter().any(|u| u[n as usize] != DVec3::ZERO))
            })
            .collect();
        let fields: Vec<&[DVec3]> = fields.iter().map(Vec::as_slice).collect();
        Ok(self
            .element_forces(&touched, &fields)?
            .iter()
            .map(|ku| {
                let minus: Vec<f64> = flatten(ku).iter().map(|x| -x).collect();
                self.system.restrict(&minus)
            })
            .collect())
    }

    /// The resolved muscles (empty until [`set_muscles`](Self::set_muscles)).
    pub fn muscles(&self) -> &[Muscle] {
        &self.muscles
    }

    /// Index of the muscle called `name`.
    pub fn muscle_index(&self, name: &str) -> Option<usize> {
        self.muscles.iter().position(|m| m.name == name)
    }

    /// Solves the muscle basis: one displacement field per muscle at unit activation, all
    /// right-hand sides in one call to the cached factor.
    pub fn compute_basis(&mut self) -> Result<()> {
        self.ensure_factored()?;
        let start = Instant::now();
        let dim = self.system.dofs();
        let count = self.actuator_count();
        let mut rhs = vec![0.0; dim * count];
        for (i, muscle) in self.muscles.iter().enumerate() {
            let full = flatten(&muscle.nodal_forces(self.volume.nodes_mm.len()));
            rhs[i * dim..(i + 1) * dim].copy_from_slice(&self.system.restrict(&full));
        }
        let prescribed: Vec<Vec<DVec3>> = match &self.jaw {
            Some(jaw) => (0..jaw::ACTUATORS.len())
                .map(|k| jaw.prescribed(k, &self.volume, &self.fixed))
                .collect(),
            None => Vec::new(),
        };
        for (k, r) in self.prescribed_rhs(&prescribed)?.into_iter().enumerate() {
            let i = self.muscles.len() + k;
            rhs[i * dim..(i + 1) * dim].copy_from_slice(&r);
        }
        if count > 0 {
            self.solver.solve_many_in_place(&mut rhs, count)?;
        }
        let n3 = 3 * self.volume.nodes_mm.len();
        let muscles = self.muscles.len();
        self.basis = (0..count)
            .map(|i| {
                let mut full = vec![0.0; n3];
                self.system.extend(&rhs[i * dim..(i + 1) * dim], &mut full);
                // The jaw's fixed nodes move by their prescribed displacement.
                if let Some(u_p) = i.checked_sub(muscles).map(|k| &prescribed[k]) {
                    for (node, d) in u_p.iter().enumerate() {
                        if self.fixed[node] {
                            full[3 * node..3 * node + 3].copy_from_slice(&d.to_array());
                        }
                    }
                }
                full
            })
            .collect();
        self.timings.basis_millis = start.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// Whether the basis matches the current muscles, jaw, materials and fixed nodes.
    pub fn has_basis(&self) -> bool {
        self.basis.len() == self.actuator_count() && self.actuator_count() > 0
    }

    /// Replaces muscle `index` (e.g. a new force direction or magnitude) and re-solves only its
    /// basis vector with the cached factor.
    pub fn set_muscle(&mut self, index: usize, muscle: Muscle) -> Result<()> {
        if index >= self.muscles.len() {
            return Err(FemError::Definition(format!("no muscle {index}")).into());
        }
        self.muscles[index] = muscle;
        if !self.has_basis() {
            return self.compute_basis();
        }
        let forces = self.muscles[index].nodal_forces(self.volume.nodes_mm.len());
        let u = self.solve(&forces)?;
        self.basis[index] = flatten(&u);
        Ok(())
    }

    /// Per actuator (muscles, then the jaw's): the displacement (mm) of every volume node at
    /// unit activation.
    pub fn basis_displacement(&self, actuator: usize) -> Option<Vec<DVec3>> {
        self.basis.get(actuator).map(|b| unflatten(b))
    }

    fn check_activations(&self, activations: &[f64]) -> Result<()> {
        if !self.has_basis() {
            return Err(FemError::Definition(
                "no muscle basis: call set_muscles and compute_basis".into(),
            )
            .into());
        }
        if activations.len() != self.actuator_count() || activations.iter().any(|a| !a.is_finite())
        {
            return Err(FemError::Definition(format!(
                "need {} finite activations, got {}",
                self.actuator_count(),
                activations.len()
            ))
            .into());
        }
        Ok(())
    }

    /// `u = Σ a_i u_i` on the skin surface only (the slider update): writes one displacement
    /// (mm) per surface vertex into `out`.
    pub fn combine_surface(&self, activations: &[f64], out: &mut Vec<DVec3>) -> Result<()> {
        self.check_activations(activations)?;
        let n = self.surface.vertex_count();
        out.clear();
        out.resize(n, DVec3::ZERO);
        for (a, basis) in activations.iter().zip(&self.basis) {
            if *a == 0.0 {
                continue;
            }
            for v in 0..n {
                out[v] += DVec3::new(basis[3 * v], basis[3 * v + 1], basis[3 * v + 2]) * *a;
            }
        }
        Ok(())
    }

    /// `u = Σ a_i u_i` at every volume node (mm).
    pub fn combine_volume(&self, activations: &[f64]) -> Result<Vec<DVec3>> {
        self.check_activations(activations)?;
        let mut out = vec![DVec3::ZERO; self.volume.nodes_mm.len()];
        for (a, basis) in activations.iter().zip(&self.basis) {
            for (v, o) in out.iter_mut().enumerate() {
                *o += DVec3::new(basis[3 * v], basis[3 * v + 1], basis[3 * v + 2]) * *a;
            }
        }
        Ok(out)
    }

    /// The nodal forces (N) of an activation vector.
    pub fn forces(&self, activations: &[f64]) -> Vec<DVec3> {
        let mut out = vec![DVec3::ZERO; self.volume.nodes_mm.len()];
        for (muscle, &a) in self.muscles.iter().zip(activations) {
            for (&node, &f) in muscle.nodes.iter().zip(&muscle.forces_n) {
                out[node as usize] += f * a;
            }
        }
        out
    }

    /// The skin surface deformed by an activation vector (normals recomputed).
    pub fn deformed_surface(&self, activations: &[f64]) -> Result<Mesh> {
        let mut u = Vec::new();
        self.combine_surface(activations, &mut u)?;
        Ok(self.surface.displaced(&u))
    }
}

/// Default boundary conditions (paper): every cranium-layer node, plus all three layers under
/// the face's **outer** border (the longest boundary loop). Eye and mouth rims stay free.
pub fn default_fixed_nodes(surface: &Mesh) -> Vec<bool> {
    fixed_nodes(surface, 1)
}

/// Every cranium-layer node, plus all three layers under the outer border loop and the
/// `border_rings − 1` vertex rings inside it (none for 0; see [`FemParams::fixed_border_rings`]).
pub fn fixed_nodes(surface: &Mesh, border_rings: usize) -> Vec<bool> {
    let n = surface.vertex_count();
    let mut fixed = vec![false; 3 * n];
    fixed[2 * n..].iter_mut().for_each(|f| *f = true);
    let loops = crate::generic_face::boundary_loops(surface);
    let Some(outer) = loops.iter().max_by_key(|l| l.len()) else {
        return fixed;
    };
    if border_rings == 0 {
        return fixed;
    }
    let outer: Vec<usize> = outer.iter().map(|&v| v as usize).collect();
    let held = crate::mesh::Topology::new(surface).within_rings(&outer, border_rings - 1);
    for (v, _) in held.iter().enumerate().filter(|(_, h)| **h) {
        for layer in 0..3 {
            fixed[layer * n + v] = true;
        }
    }
    fixed
}

/// `[DVec3]` → `[x0, y0, z0, x1, …]`.
pub fn flatten(v: &[DVec3]) -> Vec<f64> {
    v.iter().flat_map(|p| p.to_array()).collect()
}

/// `[x0, y0, z0, x1, …]` → `[DVec3]`.
pub fn unflatten(v: &[f64]) -> Vec<DVec3> {
    v.chunks_exact(3)
        .map(|c| DVec3::new(c[0], c[1], c[2]))
        .collect()
}
