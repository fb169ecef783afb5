//! The layered FEM face on the generic face: well-posed reduced system, cached solves,
//! mirror-symmetric muscles, plausible expressions, clear errors for ill-posed setups.

use facesynth::fem::expressions::ExpressionSet;
use facesynth::fem::muscles::MuscleSet;
use facesynth::fem::{FaceModel, FemParams, Material, flatten};
use facesynth::{Error, FeaturePoint, FemError};
use glam::DVec3;

fn model() -> FaceModel {
    model_with(&FemParams::default())
}

/// The generic face's model with these parameters, factored, with the built-in muscle basis.
fn model_with(params: &FemParams) -> FaceModel {
    let face = facesynth::generic_face::build();
    let mut model = FaceModel::from_generic(&face, params).unwrap();
    model.factor().unwrap();
    model.set_muscles(&MuscleSet::builtin()).unwrap();
    model.compute_basis().unwrap();
    model
}

/// For each surface vertex, the vertex nearest its mirror image (x → −x).
fn mirror_map(positions: &[DVec3]) -> Vec<usize> {
    positions
        .iter()
        .map(|p| {
            let m = DVec3::new(-p.x, p.y, p.z);
            (0..positions.len())
                .min_by(|&a, &b| {
                    (positions[a] - m)
                        .length_squared()
                        .total_cmp(&(positions[b] - m).length_squared())
                })
                .unwrap()
        })
        .collect()
}

#[test]
fn reduced_system_is_spd_and_solves_to_tight_residual() {
    let mut model = model();
    let q = model.quality;
    println!(
        "dofs {} elements {} nnz {} quality {q:?} timings {:?}",
        model.dofs(),
        model.elements(),
        model.system().nonzeros(),
        model.timings
    );
    assert_eq!(q.inverted_elements, 0);
    let system = model.system().clone();
    let n = system.dofs();
    // Symmetric by construction (upper triangle); positive definite: xᵀKx > 0 for test vectors
    // and the Cholesky factorization succeeded.
    for seed in 1..4u64 {
        let x: Vec<f64> = (0..n)
            .map(|i| (((i as u64 + 1) * 2654435761 * seed) % 1000) as f64 / 500.0 - 1.0)
            .collect();
        let mut kx = vec![0.0; n];
        system.multiply(&x, &mut kx);
        let energy: f64 = x.iter().zip(&kx).map(|(a, b)| a * b).sum();
        assert!(energy > 0.0);
    }
    // K u = f for a muscle's force field.
    let forces = model.muscles()[0].nodal_forces(model.volume.nodes_mm.len());
    let u = model.solve(&forces).unwrap();
    let f = system.restrict(&flatten(&forces));
    let ur = system.restrict(&flatten(&u));
    let mut ku = vec![0.0; n];
    system.multiply(&ur, &mut ku);
    let res = ku
        .iter()
        .zip(&f)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    let norm = f.iter().map(|v| v * v).sum::<f64>().sqrt();
    println!("relative residual {:.3e}", res / norm);
    assert!(res <= 1e-10 * norm);
    // The basis is the same solve.
    let b = model.basis_displacement(0).unwrap();
    let diff = b
        .iter()
        .zip(&u)
        .map(|(a, c)| (*a - *c).length())
        .fold(0.0, f64::max);
    assert!(diff < 1e-12);
}

#[test]
fn left_and_right_muscles_give_mirror_symmetric_displacements() {
    let model = model();
    let n = model.surface.vertex_count();
    let mirror = mirror_map(&model.surface.positions_mm);
    let names: Vec<String> = model.actuator_names();
    for i in (0..model.muscles().len()).step_by(2) {
        assert!(names[i].ends_with("_left") && names[i + 1].ends_with("_right"));
        let left = model.basis_displacement(i).unwrap();
        let right = model.basis_displacement(i + 1).unwrap();
        let max = left[..n].iter().map(|u| u.length()).fold(0.0, f64::max);
        let mut worst: f64 = 0.0;
        for v in 0..n {
            let m = mirror[v];
            let l = left[v];
            let mirrored = DVec3::new(-l.x, l.y, l.z);
            worst = worst.max((right[m] - mirrored).length());
        }
        println!(
            "{}: max {max:.3} mm, mirror mismatch {worst:.2e} mm",
            names[i]
        );
        assert!(max > 0.1, "{} barely moves the face", names[i]);
        assert!(worst <= 1e-6 * max.max(1.0), "{}: {worst}", names[i]);
    }
}

#[test]
fn reactions_balance_the_loads_and_internal_forces_match_the_assembled_matrix() {
    let model = model();
    let names = model.actuator_names();
    let n_nodes = model.volume.nodes_mm.len();

    // Element-by-element K u equals the assembled reduced matrix on every free DOF (two
    // independent paths: the element loop and the scatter map + CSC product).
    let field: Vec<DVec3> = (0..n_nodes)
        .map(|v| {
            let t = v as f64;
            DVec3::new((0.37 * t).sin(), (0.11 * t).cos(), (0.05 * t).sin() * 0.5)
        })
        .collect();
    let mut full = flatten(&field);
    let sys = model.system();
    let reduced = sys.restrict(&full);
    sys.extend(&reduced, &mut full); // fixed DOFs zeroed
    let free_field: Vec<DVec3> = full
        .chunks(3)
        .map(|c| DVec3::new(c[0], c[1], c[2]))
        .collect();
    let ku = flatten(&model.internal_forces(&free_field).unwrap());
    let mut y = vec![0.0; reduced.len()];
    sys.multiply(&reduced, &mut y);
    let scale = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let worst = sys
        .restrict(&ku)
        .iter()
        .zip(&y)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(worst <= 1e-12 * scale, "{worst} vs {scale}");

    // A muscle expression: the free nodes are balanced, the reactions take the loads.
    let happy = ExpressionSet::builtin()
        .get("happiness")
        .unwrap()
        .activations_for(&names)
        .unwrap();
    let u = model.combine_volume(&happy).unwrap();
    let f = model.forces(&happy);
    let eq = model.equilibrium(&u, &f).unwrap();
    let applied = eq.applied_sum_n.length();
    let max_f = f.iter().map(|v| v.length()).fold(0.0, f64::max);
    println!(
        "happiness: Σf {:?} N, Σreactions {:?} N, free residual {:.2e} N",
        eq.applied_sum_n, eq.reaction_sum_n, eq.free_residual_n
    );
    assert!(applied > 0.0);
    assert!((eq.reaction_sum_n + eq.applied_sum_n).length() <= 1e-9 * max_f * n_nodes as f64);
    assert!(eq.free_residual_n <= 1e-9 * max_f);
    let fixed = model.fixed_nodes();
    assert!(
        eq.reaction_n
            .iter()
            .zip(fixed)
            .all(|(r, &fx)| fx || *r == DVec3::ZERO)
    );

    // The jaw alone: no loads, reactions that hold it open and sum to zero.
    let mut jaw = vec![0.0; names.len()];
    jaw[names.iter().position(|a| a == "jaw_open").unwrap()] = 10.0;
    let u = model.combine_volume(&jaw).unwrap();
    let f = model.forces(&jaw);
    let eq = model.equilibrium(&u, &f).unwrap();
    let total: f64 = eq.reaction_n.iter().map(|r| r.length()).sum();
    assert!(eq.applied_sum_n == DVec3::ZERO && total > 0.0);
    assert!(
        eq.reaction_sum_n.length() <= 1e-9 * total,
        "{:?}",
        eq.reaction_sum_n
    );
    assert!(eq.free_residual_n <= 1e-9 * total);
}

#[test]
fn the_jaw_drops_the_chin_opens_the_mouth_and_is_an_equilibrium() {
    let model = model();
    let names = model.actuator_names();
    let n = model.surface.vertex_count();
    let open = names
        .iter()
        .position(|a| a == "jaw_open")
        .expect("jaw actuator");
    assert_eq!(
        &names[open..],
        ["jaw_open", "jaw_left", "jaw_right", "jaw_forward"]
    );
    let jaw = model.jaw().unwrap();
    let u = model.basis_displacement(open).unwrap();
    let fixed = model.fixed_nodes();

    // The bone under the chin follows the rigid rotation exactly (1 degree per unit).
    let chin = model.feature_vertices[FeaturePoint::Chin.index()] as usize;
    let bone = 2 * n + chin;
    assert!(fixed[bone] && jaw.weights[chin] > 0.999);
    let rigid = jaw.axis.cross(model.volume.nodes_mm[bone] - jaw.hinge_mm) * 1f64.to_radians();
    assert!(
        (u[bone] - rigid).length() < 1e-12,
        "{:?} vs {rigid:?}",
        u[bone]
    );

    // Free nodes are in equilibrium: (K u) vanishes on every free DOF, while the fixed nodes
    // carry the reactions that hold the jaw open.
    let r = model.internal_forces(&u).unwrap();
    let reaction = (0..u.len())
        .filter(|&v| fixed[v])
        .map(|v| r[v].length())
        .fold(0.0, f64::max);
    let residual = (0..u.len())
        .filter(|&v| !fixed[v])
        .map(|v| r[v].length())
        .fold(0.0, f64::max);
    println!("jaw_open: reaction {reaction:.3e} N, free residual {residual:.3e} N");
    assert!(reaction > 0.0 && residual <= 1e-9 * reaction);

    // 10 degrees: the chin skin goes down and back, the lips part, the upper face stays.
    let at = |v: usize| u[v] * 10.0;
    let d_chin = at(chin);
    println!("chin skin at 10 degrees: {d_chin:?}");
    assert!(d_chin.y < -8.0 && d_chin.z < -3.0, "{d_chin:?}");
    let p = &model.surface.positions_mm;
    let mouth = (p[model.feature_vertices[FeaturePoint::MouthCornerLeft.index()] as usize]
        + p[model.feature_vertices[FeaturePoint::MouthCornerRight.index()] as usize])
        * 0.5;
    let lip = |above: bool| {
        (0..n)
            .filter(|&v| (p[v].x - mouth.x).abs() < 3.0 && (p[v].y > mouth.y) == above)
            .min_by(|&a, &b| (p[a] - mouth).length().total_cmp(&(p[b] - mouth).length()))
            .unwrap()
    };
    let (upper, lower) = (lip(true), lip(false));
    // The slit's rim is classified by topology: the lower lip on the jaw, the upper lip not.
    assert!(jaw.weights[lower] > 0.99 && jaw.weights[upper] < 0.01);
    let opening = (p[upper] + at(upper)).y - (p[lower] + at(lower)).y - (p[upper].y - p[lower].y);
    println!("the lips part by {opening:.1} mm");
    assert!(opening > 5.0, "{opening}");
    for point in [FeaturePoint::Forehead, FeaturePoint::InnerEyeLeft] {
        let v = model.feature_vertices[point.index()] as usize;
        assert!(
            at(v).length() < 0.2 * d_chin.length(),
            "{point:?} {:?}",
            at(v)
        );
    }

    // Opening is mirror-symmetric; the two sideways shifts mirror each other.
    let mirror = mirror_map(p);
    let left = model.basis_displacement(open + 1).unwrap();
    let right = model.basis_displacement(open + 2).unwrap();
    let flip = |d: DVec3| DVec3::new(-d.x, d.y, d.z);
    for v in 0..n {
        let m = mirror[v];
        assert!((u[m] - flip(u[v])).length() < 1e-6, "open at {v}");
        assert!(
            (right[m] - flip(left[v])).length() < 1e-6,
            "sideways at {v}"
        );
    }
    assert!(
        left[chin].x > 0.5,
        "jaw_left moves the chin to the subject's left"
    );
    let forward = model.basis_displacement(open + 3).unwrap();
    for v in 0..n {
        assert!(
            (forward[mirror[v]] - flip(forward[v])).length() < 1e-6,
            "forward at {v}"
        );
    }
    assert!(
        forward[chin].dot(jaw.forward) > 0.5,
        "jaw_forward moves the chin forward"
    );
    assert!(forward[upper].length() < 0.5 * forward[lower].length());

    // Freeing every node under the jaw would leave it nothing to move: refused, state kept.
    let jaw_weights = jaw.weights.clone();
    let mut freed = fixed.to_vec();
    for (node, f) in freed.iter_mut().enumerate() {
        if jaw_weights[node % n] > 0.0 {
            *f = false;
        }
    }
    let mut model = model;
    assert!(model.set_fixed_nodes(freed).is_err());
    assert!(model.has_basis() && model.jaw().unwrap().weights == jaw_weights);
}

#[test]
fn expressions_move_the_face_plausibly() {
    let model = model();
    let names: Vec<String> = model.actuator_names();
    let set = ExpressionSet::builtin();
    let corner = model.feature_vertices[FeaturePoint::MouthCornerLeft.index()] as usize;
    let mut u = Vec::new();
    for e in &set.expressions {
        let a = e.activations_for(&names).unwrap();
        model.combine_surface(&a, &mut u).unwrap();
        let max = u.iter().map(|d| d.length()).fold(0.0, f64::max);
        println!(
            "{}: max {max:.2} mm, left mouth corner {:?}",
            e.name, u[corner]
        );
        assert!(max > 1.0, "{} hardly moves", e.name);
        assert!(max < 15.0, "{} moves {max} mm", e.name);
        if e.name == "happiness" {
            let d = u[corner];
            assert!(
                d.y > 0.0 && d.x > 0.0,
                "smile moves the left corner up and out: {d:?}"
            );
            assert!((3.0..=8.0).contains(&d.length()), "corner moves {d:?}");
        }
    }
}

#[test]
fn modulus_change_refactors_and_scales_the_answer() {
    let mut model = model();
    let before = model.basis_displacement(0).unwrap();
    let p = model.params;
    let stiffer = |m: Material| Material {
        young_modulus_pa: 2.0 * m.young_modulus_pa,
        ..m
    };
    model
        .set_materials(stiffer(p.skin), stiffer(p.fat))
        .unwrap();
    assert!(!model.is_factored() && !model.has_basis());
    model.factor().unwrap();
    model.compute_basis().unwrap();
    let after = model.basis_displacement(0).unwrap();
    // Linear elasticity: doubling every modulus halves the displacement.
    for (a, b) in before.iter().zip(&after) {
        assert!((*a * 0.5 - *b).length() < 1e-9);
    }
    // Re-solving one muscle with a doubled force doubles its field only.
    let mut m = model.muscles()[3].clone();
    m.forces_n.iter_mut().for_each(|f| *f *= 2.0);
    let old3 = model.basis_displacement(3).unwrap();
    let old4 = model.basis_displacement(4).unwrap();
    model.set_muscle(3, m).unwrap();
    let new3 = model.basis_displacement(3).unwrap();
    for (a, b) in old3.iter().zip(&new3) {
        assert!((*a * 2.0 - *b).length() < 1e-9);
    }
    assert_eq!(old4, model.basis_displacement(4).unwrap());
}

#[test]
fn ill_posed_systems_are_clear_errors() {
    let face = facesynth::generic_face::build();
    let params = FemParams::default();
    // Zero modulus.
    let mut bad = params;
    bad.fat.young_modulus_pa = 0.0;
    assert!(matches!(
        FaceModel::from_generic(&face, &bad),
        Err(Error::Fem(FemError::InvalidMaterial { .. }))
    ));
    // No fixed nodes.
    let mut model = FaceModel::from_generic(&face, &params).unwrap();
    let none = vec![false; model.volume.nodes_mm.len()];
    assert!(matches!(
        model.set_fixed_nodes(none),
        Err(Error::Fem(FemError::NoFixedNodes))
    ));
    // Inverted elements: a layer thicker than the face is curved (offsets cross).
    let mut thick = params;
    thick.layers.fat_thickness_mm = 200.0;
    match FaceModel::from_generic(&face, &thick) {
        Err(Error::Fem(FemError::InvertedElement { .. })) => {}
        other => panic!("expected an inverted element, got {:?}", other.map(|_| ())),
    }
    // An inverted element handed to the assembly directly.
    let mut block = facesynth::fem::HexMesh::block(DVec3::splat(10.0), 2, 1, 1);
    block.elements[1].swap(0, 4);
    block.elements[1].swap(1, 5);
    block.elements[1].swap(2, 6);
    block.elements[1].swap(3, 7);
    let fixed: Vec<bool> = block.nodes_mm.iter().map(|p| p.x == 0.0).collect();
    assert!(matches!(
        facesynth::fem::assembly::ReducedSystem::new(&block, &fixed, &[0.45]),
        Err(Error::Fem(FemError::InvertedElement { element: 1, .. }))
    ));
    // One fixed node leaves rotations free: rejected before factoring.
    let mut one = vec![false; model.volume.nodes_mm.len()];
    one[0] = true;
    assert!(matches!(
        model.set_fixed_nodes(one),
        Err(Error::Fem(FemError::FloatingPart { .. }))
    ));
    // The model keeps its previous, valid state.
    model.factor().unwrap();
}

#[test]
fn the_model_can_live_on_a_worker_thread() {
    fn send_sync<T: Send + Sync + Clone>() {}
    send_sync::<FaceModel>();
}

#[test]
fn the_fixed_border_is_editable_and_holds_what_it_says() {
    let face = facesynth::generic_face::build();
    let n = face.mesh.vertex_count();
    let held = |fixed: &[bool]| fixed[..n].iter().filter(|&&f| f).count();
    let count = |rings| held(&facesynth::fem::fixed_nodes(&face.mesh, rings));
    // 0: only the cranium layer; 1: the paper's border loop; more rings hold strictly more.
    assert_eq!(count(0), 0);
    assert_eq!(
        count(1),
        held(&facesynth::fem::default_fixed_nodes(&face.mesh))
    );
    assert!(0 < count(1) && count(1) < count(2) && count(2) < count(3));
    let cranium = facesynth::fem::fixed_nodes(&face.mesh, 0);
    assert!(cranium[2 * n..].iter().all(|&f| f));

    // Under the outer cheek load the border loop stays put when held and moves when free.
    let bulge = |rings| {
        let model = model_with(&FemParams {
            fixed_border_rings: rings,
            ..FemParams::default()
        });
        let k = model
            .actuator_names()
            .iter()
            .position(|a| a == "buccal_bulge_left")
            .unwrap();
        let u = model.basis_displacement(k).unwrap();
        let border = facesynth::fem::default_fixed_nodes(&model.surface);
        (0..n)
            .filter(|&v| border[v])
            .map(|v| u[v].length())
            .fold(0.0, f64::max)
    };
    assert_eq!(bulge(1), 0.0);
    let free = bulge(0);
    println!("buccal_bulge_left, border free: the border loop moves up to {free:.3} mm");
    assert!(free > 0.05, "{free}");
}
