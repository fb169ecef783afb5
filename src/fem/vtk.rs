//! Legacy ASCII VTK export of the FEM model (unstructured grid of hexahedra, cell type 12):
//! POINT_DATA vectors `displacement` (mm) and `force` (N), scalars `fixed` (0/1); CELL_DATA
//! scalars `young_modulus_pa` and `poisson_ratio`. ParaView opens it; it is also how a solve is
//! cross-checked against another FEM code: the `fixed` nodes' `displacement` is their boundary
//! condition (zero, or the jaw's prescribed motion under the lower face), `force` the load on
//! the nodes (the muscles'; the jaw adds none), and `reaction` (N) the support force at the fixed
//! nodes (`K u − f` there, zero elsewhere; [`FaceModel::equilibrium`]): the reactions another code
//! computes for the same boundary conditions should match them. Written atomically.

use super::FaceModel;
use crate::Result;
use glam::DVec3;
use std::io::Write;
use std::path::Path;

/// Writes `model` with nodal `displacement_mm`, `force_n` and `reaction_n` (one per volume
/// node) to `path`.
pub fn write(
    path: &Path,
    model: &FaceModel,
    displacement_mm: &[DVec3],
    force_n: &[DVec3],
    reaction_n: &[DVec3],
) -> Result<()> {
    crate::io::write_atomic(path, |w| {
        write_to(w, model, displacement_mm, force_n, reaction_n)
    })
}

/// The VTK text into any writer.
pub fn write_to(
    w: &mut dyn Write,
    model: &FaceModel,
    displacement_mm: &[DVec3],
    force_n: &[DVec3],
    reaction_n: &[DVec3],
) -> std::io::Result<()> {
    let mesh = &model.volume;
    let n = mesh.nodes_mm.len();
    let cells = mesh.elements.len();
    writeln!(w, "# vtk DataFile Version 3.0")?;
    writeln!(w, "facesynth layered FEM face (mm, N, Pa)")?;
    writeln!(w, "ASCII")?;
    writeln!(w, "DATASET UNSTRUCTURED_GRID")?;
    writeln!(w, "POINTS {n} double")?;
    for p in &mesh.nodes_mm {
        writeln!(w, "{} {} {}", p.x, p.y, p.z)?;
    }
    writeln!(w, "CELLS {cells} {}", cells * 9)?;
    for e in &mesh.elements {
        writeln!(
            w,
            "8 {} {} {} {} {} {} {} {}",
            e[0], e[1], e[2], e[3], e[4], e[5], e[6], e[7]
        )?;
    }
    writeln!(w, "CELL_TYPES {cells}")?;
    for _ in 0..cells {
        writeln!(w, "12")?;
    }
    writeln!(w, "POINT_DATA {n}")?;
    for (name, field) in [
        ("displacement", displacement_mm),
        ("force", force_n),
        ("reaction", reaction_n),
    ] {
        writeln!(w, "VECTORS {name} double")?;
        for v in field {
            writeln!(w, "{} {} {}", v.x, v.y, v.z)?;
        }
    }
    writeln!(w, "SCALARS fixed int 1")?;
    writeln!(w, "LOOKUP_TABLE default")?;
    for &f in model.fixed_nodes() {
        writeln!(w, "{}", f as u8)?;
    }
    writeln!(w, "CELL_DATA {cells}")?;
    let materials = [model.params.skin, model.params.fat];
    writeln!(w, "SCALARS young_modulus_pa double 1")?;
    writeln!(w, "LOOKUP_TABLE default")?;
    for &g in &mesh.element_group {
        writeln!(w, "{}", materials[g as usize].young_modulus_pa)?;
    }
    writeln!(w, "SCALARS poisson_ratio double 1")?;
    writeln!(w, "LOOKUP_TABLE default")?;
    for &g in &mesh.element_group {
        writeln!(w, "{}", materials[g as usize].poisson_ratio)?;
    }
    Ok(())
}
