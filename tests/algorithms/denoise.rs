//! Denoising: behaviour on analytic meshes, and scores against the synthetic benchmark's
//! clean twins.

use crate::common;

use common::grid;

use facesynth::Mesh;
use facesynth::denoise::{BoundaryRule, DenoiseMethod, DenoiseParams, MoveRule, denoise, eval};
use glam::DVec3;
use std::path::PathBuf;

/// Deterministic pseudo-random numbers (xorshift), uniform in [0, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (Box–Muller).
    fn normal(&mut self) -> f64 {
        let u = self.next().max(1e-300);
        let v = self.next();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

fn all_variants() -> Vec<(&'static str, DenoiseParams)> {
    vec![
        ("default", DenoiseParams::default()),
        ("paper", DenoiseParams::paper()),
        (
            "laplacian",
            DenoiseParams::baseline(DenoiseMethod::Laplacian, 5),
        ),
        ("taubin", DenoiseParams::baseline(DenoiseMethod::Taubin, 5)),
    ]
}

/// The default filter with every repair kept (no repair removed as over `repair_max_mm`).
fn repairing() -> DenoiseParams {
    DenoiseParams {
        repair_max_mm: f64::INFINITY,
        ..DenoiseParams::default()
    }
}

#[test]
fn plane_spike_is_removed_and_the_rest_is_untouched() {
    let nx = 12;
    let spike = 5 * nx + 6;
    // The default's filter, with every repair kept, and the paper's.
    for (name, params) in [
        ("default filter", repairing()),
        ("paper", DenoiseParams::paper()),
    ] {
        let mut m = grid(nx, 10, |_, _| 0.0);
        let input = {
            m.positions_mm[spike as usize].z = 25.0;
            m.positions_mm.clone()
        };
        let r = denoise(&mut m, &params).unwrap();
        assert!(
            m.positions_mm[spike as usize].z.abs() < 1e-12,
            "{name}: spike left at {}",
            m.positions_mm[spike as usize].z
        );
        for (v, (p, q)) in m.positions_mm.iter().zip(&input).enumerate() {
            if v != spike as usize {
                assert_eq!(p, q, "{name}: vertex {v} moved");
            }
        }
        assert_eq!(r.vertices_moved, 1, "{name}");
        assert_eq!(r.iterations_run, 1, "{name}");
        assert!((r.max_displacement_mm - 25.0).abs() < 1e-12);
        assert!((r.mean_displacement_mm - 25.0 / m.vertex_count() as f64).abs() < 1e-12);
        assert_eq!(r.displacement_mm.len(), m.vertex_count());
        // The default's quadric fit of an exact plane is exact to rounding.
        assert!((r.displacement_mm[spike as usize] - 25.0).abs() < 1e-12);
    }
    // The default removes a repair over 3 mm instead: a one-vertex hole, nothing moved.
    let mut m = grid(nx, 10, |_, _| 0.0);
    m.positions_mm[spike as usize].z = 25.0;
    let r = denoise(&mut m, &DenoiseParams::default()).unwrap();
    assert_eq!(r.removed, vec![spike]);
    assert_eq!(m.vertex_count() as u32, nx * 10 - 1);
    assert!(m.positions_mm.iter().all(|p| p.z == 0.0));
    assert_eq!((r.vertices_moved, r.max_displacement_mm), (0, 0.0));
}

/// A spherical cap (R = 60 mm) sampled on a 1 mm grid like a scan, with σ = 0.3 mm noise
/// along the normal and a few spikes; returns (mesh, centre, R).
fn noisy_cap(spikes: bool) -> (Mesh, DVec3, f64) {
    let r = 60.0;
    let n = 41;
    let centre = DVec3::new(20.0, 20.0, 0.0);
    let mut m = grid(n, n, |x, y| {
        (r * r - (x - centre.x).powi(2) - (y - centre.y).powi(2)).sqrt()
    });
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for p in &mut m.positions_mm {
        let dir = (*p - centre).normalize();
        *p += dir * 0.3 * rng.normal();
    }
    if spikes {
        for k in 0..12 {
            let v = (97 * k + 45) % (n * n) as usize;
            m.positions_mm[v].z += if k % 2 == 0 { 15.0 } else { -9.0 };
        }
    }
    (m, centre, r)
}

fn sphere_rmse(m: &Mesh, centre: DVec3, r: f64) -> f64 {
    let sse: f64 = m
        .positions_mm
        .iter()
        .map(|p| (p.distance(centre) - r).powi(2))
        .sum();
    (sse / m.vertex_count() as f64).sqrt()
}

#[test]
fn noisy_sphere_gets_closer_to_the_true_sphere() {
    for spikes in [true, false] {
        let (mesh, centre, r) = noisy_cap(spikes);
        let before = sphere_rmse(&mesh, centre, r);
        for (name, params) in all_variants() {
            // Without spikes the default's 1 mm floor leaves σ = 0.3 mm noise alone by design.
            if !spikes && name == "default" {
                continue;
            }
            let mut m = mesh.clone();
            denoise(&mut m, &params).unwrap();
            let after = sphere_rmse(&m, centre, r);
            assert!(
                after < 0.8 * before,
                "{name} spikes={spikes}: RMSE {before:.3} → {after:.3}"
            );
        }
    }
}

#[test]
fn default_leaves_plain_noise_alone_and_removes_spikes() {
    let (mesh, centre, r) = noisy_cap(false);
    let mut m = mesh.clone();
    let report = denoise(&mut m, &DenoiseParams::default()).unwrap();
    assert_eq!(report.vertices_moved, 0);
    let (mesh, ..) = noisy_cap(true);
    let mut m = mesh.clone();
    denoise(&mut m, &DenoiseParams::default()).unwrap();
    let worst = m
        .positions_mm
        .iter()
        .map(|p| (p.distance(centre) - r).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1.5, "worst {worst}");
}

#[test]
fn boundary_spike_is_removed_or_filtered_along_the_rim_or_held() {
    // Spike on the bottom rim (vertex 4 of a 10 × 6 grid), on a tilted plane.
    // Tilted across the rim only: along the bottom rim z is constant.
    let tilt = |_x: f64, y: f64| 0.3 * y;
    let mut m = grid(10, 6, tilt);
    m.positions_mm[4].z += 12.0;
    let input = m.positions_mm.clone();
    // Default: a rim spike has no support to be moved back by, so it is removed, and
    // nothing else is touched.
    let mut removed = m.clone();
    let r = denoise(&mut removed, &DenoiseParams::default()).unwrap();
    assert_eq!(r.removed, vec![4]);
    assert_eq!((r.vertices_removed, r.vertices_moved), (1, 0));
    assert_eq!(removed.vertex_count(), input.len() - 1);
    assert_eq!(r.kept.len(), removed.vertex_count());
    for (p, &v) in removed.positions_mm.iter().zip(&r.kept) {
        assert_ne!(v, 4);
        assert_eq!(*p, input[v as usize], "vertex {v} moved");
    }
    // The two quads at the spike lost a corner and stay as triangles.
    assert_eq!(removed.face_count(), m.face_count());
    assert_eq!(removed.face_counts().triangles, 2);
    assert!(r.displacement_mm[4].is_nan());
    // Without removal: along the rim the 3-point median of a straight rim is exact, the
    // spike is gone and the vertex did not move sideways or into the surface.
    let mut along = m.clone();
    let moving = DenoiseParams {
        remove_unrepairable: false,
        ..DenoiseParams::default()
    };
    let r = denoise(&mut along, &moving).unwrap();
    assert!((along.positions_mm[4] - DVec3::new(4.0, 0.0, tilt(4.0, 0.0))).length() < 1e-12);
    assert_eq!((r.vertices_moved, r.vertices_removed), (1, 0));
    // A straight rim of a clean grid is a fixed point: the corners do not move either.
    for (v, (p, q)) in along.positions_mm.iter().zip(&input).enumerate() {
        if v != 4 {
            assert_eq!(p, q, "vertex {v} moved");
        }
    }
    let mut held = m.clone();
    let params = DenoiseParams {
        boundary: BoundaryRule::Hold,
        ..moving
    };
    let r = denoise(&mut held, &params).unwrap();
    assert_eq!(held.positions_mm[4], input[4], "held rim vertex moved");
    assert_eq!(r.vertices_moved, 0);
}

#[test]
fn rim_spike_cluster_is_removed_and_a_clean_curved_grid_keeps_every_vertex() {
    // A dome (curved like a cheek at the grid scale) with a 3-vertex spike cluster on its
    // top rim; the cluster is its own support, so no fit can move it back.
    let dome = |x: f64, y: f64| -((x - 10.0).powi(2) + (y - 7.0).powi(2)) / 40.0;
    let clean = grid(21, 15, dome);
    let mut m = clean.clone();
    let top = 14 * 21;
    let cluster = [top + 9, top + 10, top + 10 - 21];
    for (v, dz) in cluster.iter().zip([9.0, 11.0, 7.0]) {
        m.positions_mm[*v as usize].z += dz;
    }
    let r = denoise(&mut m, &DenoiseParams::default()).unwrap();
    // The two rim members are removed; the interior one is either removed or put back.
    assert!(
        r.removed.contains(&cluster[0]) && r.removed.contains(&cluster[1]),
        "{:?}",
        r.removed
    );
    assert!(r.removed.len() <= 3, "{:?}", r.removed);
    for (p, &v) in m.positions_mm.iter().zip(&r.kept) {
        assert!(
            (p.z - dome(p.x, p.y)).abs() < 0.5,
            "vertex {v} off by {}",
            p.z - dome(p.x, p.y)
        );
    }
    // The clean dome: nothing moves, nothing goes.
    let mut c = clean.clone();
    let r = denoise(&mut c, &DenoiseParams::default()).unwrap();
    assert_eq!((r.vertices_moved, r.vertices_removed), (0, 0));
    assert_eq!(c, clean);
}

/// A real one-vertex pit 4 mm deep in a dome (a lid or lip line seen by the scanner, as on
/// synthetic seed 79): the filter cannot tell it from a spike and lifts it; the default then
/// removes it rather than keep a 4 mm guess, and keeps no vertex more than 3 mm from where
/// it was measured.
#[test]
fn a_lifted_real_pit_is_removed_not_kept_as_a_guess() {
    let dome = |x: f64, y: f64| -((x - 10.0).powi(2) + (y - 10.0).powi(2)) / 40.0;
    let pit = 10 * 21 + 9;
    let mut clean = grid(21, 21, dome);
    clean.positions_mm[pit].z -= 4.0;
    let mut lifted = clean.clone();
    let r = denoise(&mut lifted, &repairing()).unwrap();
    assert!(r.removed.is_empty(), "{:?}", r.removed);
    let guess_mm = lifted.positions_mm[pit].z - clean.positions_mm[pit].z;
    assert!(guess_mm > 3.0, "lifted {guess_mm} mm");
    let mut m = clean.clone();
    let r = denoise(&mut m, &DenoiseParams::default()).unwrap();
    assert_eq!(r.removed, vec![pit as u32]);
    assert!(r.max_displacement_mm <= 3.0, "{r:?}");
    for (p, &v) in m.positions_mm.iter().zip(&r.kept) {
        assert!(
            p.distance(clean.positions_mm[v as usize]) < 0.5,
            "vertex {v}"
        );
    }
}

#[test]
fn a_step_edge_is_not_taken_for_a_spike() {
    // A 6 mm step (a lid or lip edge at the grid scale) with one vertex of the low side
    // pushed into a notch: the quadric of the whole ring predicts the notch vertex several
    // mm higher, but it lies on the plane of the low side, so it stays where it is.
    let step = |x: f64, _y: f64| if x < 8.0 { 0.0 } else { 6.0 };
    let mut m = grid(16, 16, step);
    // The high side's first column is its edge; the low vertex in the middle of it.
    let notch = (8 * 16 + 8) as usize;
    m.positions_mm[notch].z = 0.0;
    let input = m.clone();
    let r = denoise(&mut m, &DenoiseParams::default()).unwrap();
    // Where the step meets the grid's border, a rim vertex is judged by its 4-ring, which a
    // quadric cannot fit across the step: those two may go (a cost of stop 32's rim rule,
    // counted in its measurements), nothing else.
    let ends = [8u32, 15 * 16 + 8];
    assert!(
        r.removed.iter().all(|v| ends.contains(v)),
        "{:?}",
        r.removed
    );
    let at = |v: usize| r.kept.iter().position(|&k| k as usize == v).unwrap();
    assert_eq!(m.positions_mm[at(notch)], input.positions_mm[notch]);
}

#[test]
fn a_spike_in_a_slot_is_removed_though_it_shares_a_plane_with_one_wall() {
    // A 3-row slot 4 mm deep (a closed lid's fissure at the grid scale) with its middle
    // vertex pushed 4.5 mm further down: a plane through it meets 8 of its 24 ring points
    // (the row beside it and the wall beyond), all on one side, so the step-edge test
    // alone would keep it; the plane's support must reach round it (150°).
    let slot = |_x: f64, y: f64| if (7.0..=9.0).contains(&y) { 0.0 } else { 4.0 };
    let mut m = grid(16, 16, slot);
    let spike = (8 * 16 + 8) as usize;
    m.positions_mm[spike].z = -4.5;
    let r = denoise(&mut m, &DenoiseParams::default()).unwrap();
    assert!(r.removed.contains(&(spike as u32)), "{:?}", r.removed);
    // Nothing inside the grid goes with it (rim vertices where the slot's walls meet the
    // border are judged by their 4-ring, which a quadric cannot fit across a step).
    let inside = |v: u32| (1..15).contains(&(v % 16)) && (1..15).contains(&(v / 16));
    assert_eq!(
        r.removed.iter().filter(|&&v| inside(v)).collect::<Vec<_>>(),
        vec![&(spike as u32)]
    );
    // The same vertex at the slot's floor is a sample of it: nothing inside goes.
    let mut m = grid(16, 16, slot);
    let r = denoise(&mut m, &DenoiseParams::default()).unwrap();
    assert!(!r.removed.iter().any(|&v| inside(v)), "{:?}", r.removed);
}

#[test]
fn a_piece_cut_off_by_depth_jumps_is_a_spike_cluster() {
    let mut m = grid(12, 12, |_, _| 0.0);
    // Two neighbouring vertices raised together by 20 mm: every edge out of them jumps.
    for v in [5 * 12 + 5, 5 * 12 + 6] {
        m.positions_mm[v].z = 20.0;
    }
    let topology = facesynth::mesh::Topology::new(&m);
    let flagged = facesynth::denoise::removal::jump_pieces(&m.positions_mm, &topology);
    let ids: Vec<usize> = (0..flagged.len()).filter(|&v| flagged[v]).collect();
    assert_eq!(ids, vec![5 * 12 + 5, 5 * 12 + 6]);
    // The same jump along a whole row splits the grid in two large pieces: nothing.
    let mut cliff = grid(12, 12, |_, y| if y < 6.0 { 0.0 } else { 20.0 });
    cliff.positions_mm[0].z = 0.0;
    let topology = facesynth::mesh::Topology::new(&cliff);
    assert!(
        !facesynth::denoise::removal::jump_pieces(&cliff.positions_mm, &topology)
            .iter()
            .any(|&f| f)
    );
}

#[test]
fn w_one_moves_only_the_largest_change_per_iteration() {
    let nx = 16;
    let mut m = grid(nx, 16, |_, _| 0.0);
    let spikes = [(3 * nx + 3, 30.0), (8 * nx + 10, 20.0), (12 * nx + 5, 10.0)];
    for (v, dz) in spikes {
        m.positions_mm[v as usize].z = dz;
    }
    let params = DenoiseParams {
        w: 1.0,
        iterations: 1,
        ..DenoiseParams::paper()
    };
    let mut one = m.clone();
    let r = denoise(&mut one, &params).unwrap();
    assert_eq!(r.vertices_moved, 1);
    assert_eq!(one.positions_mm[(3 * nx + 3) as usize].z, 0.0);
    assert_eq!(one.positions_mm[(8 * nx + 10) as usize].z, 20.0);
    let params = DenoiseParams {
        iterations: 3,
        ..params
    };
    let r = denoise(&mut m, &params).unwrap();
    assert_eq!((r.iterations_run, r.vertices_moved), (3, 3));
    assert!(m.positions_mm.iter().all(|p| p.z == 0.0));
}

/// The literal rule moves only the changes within `w` of the single largest one, so spikes
/// whose heights differ by more than 1/w = 1.25× take one iteration each; the per-region rule
/// removes them all at once. (Spikes of similar height fall in one iteration under both
/// rules: 20 spikes of 10–29 mm take the paper rule only 5 iterations.)
#[test]
fn paper_rule_needs_an_iteration_per_spike_per_region_does_not() {
    let nx = 30;
    let mut m = grid(nx, 30, |_, _| 0.0);
    // 8 isolated spikes, 5 mm × 1.3^k: 5.0 … 31.4 mm (the scanner's 5–40 mm range).
    let spikes: Vec<(usize, f64)> = (0..8u32)
        .map(|k| {
            let v = (k / 4 * 12 + 6) * nx + (k % 4) * 6 + 5;
            (v as usize, 5.0 * 1.3f64.powi(k as i32))
        })
        .collect();
    for &(v, dz) in &spikes {
        m.positions_mm[v].z = dz;
    }
    // Five iterations: the five largest are gone, the three smallest are left untouched.
    let mut paper = m.clone();
    let params = DenoiseParams {
        iterations: 5,
        ..DenoiseParams::paper()
    };
    let r = denoise(&mut paper, &params).unwrap();
    assert_eq!((r.iterations_run, r.vertices_moved), (5, 5));
    for (k, &(v, dz)) in spikes.iter().enumerate() {
        let expect = if k < 3 { dz } else { 0.0 };
        assert!(
            (paper.positions_mm[v].z - expect).abs() < 1e-12,
            "spike {k}"
        );
    }
    // Fifteen: one iteration per spike, then an iteration finds nothing to move.
    let mut paper = m.clone();
    let r = denoise(&mut paper, &DenoiseParams::paper()).unwrap();
    assert_eq!((r.iterations_run, r.vertices_moved), (8, 8));
    assert!(paper.positions_mm.iter().all(|p| p.z.abs() < 1e-12));
    let mut region = m.clone();
    let r = denoise(&mut region, &repairing()).unwrap();
    assert!(region.positions_mm.iter().all(|p| p.z.abs() < 1e-12));
    assert_eq!((r.iterations_run, r.vertices_moved), (1, 8));
}

#[test]
fn zero_iterations_is_identity() {
    let (mesh, ..) = noisy_cap(true);
    for (name, params) in all_variants() {
        let mut m = mesh.clone();
        let r = denoise(
            &mut m,
            &DenoiseParams {
                iterations: 0,
                ..params
            },
        )
        .unwrap();
        assert_eq!(m.positions_mm, mesh.positions_mm, "{name}");
        assert_eq!((r.iterations_run, r.vertices_moved), (0, 0), "{name}");
        assert_eq!(r.max_displacement_mm, 0.0);
    }
}

#[test]
fn bad_parameters_are_rejected() {
    let mut m = grid(3, 3, |_, _| 0.0);
    for params in [
        DenoiseParams {
            w: 0.0,
            ..Default::default()
        },
        DenoiseParams {
            w: 1.5,
            ..Default::default()
        },
        DenoiseParams {
            min_displacement_mm: -1.0,
            ..Default::default()
        },
        DenoiseParams {
            repair_max_mm: 0.0,
            ..Default::default()
        },
        DenoiseParams {
            repair_max_mm: f64::NAN,
            ..Default::default()
        },
        DenoiseParams {
            mu: -0.1,
            ..DenoiseParams::baseline(DenoiseMethod::Taubin, 3)
        },
    ] {
        assert!(denoise(&mut m, &params).is_err(), "{params:?}");
    }
    let _ = MoveRule::Global;
}

/// Noisy and clean benchmark folders: `FACESYNTH_DENOISE_NOISY` / `_CLEAN`, or a generated set.
fn bench_dirs(subjects: usize, seed: u64) -> (PathBuf, PathBuf) {
    match (
        std::env::var_os("FACESYNTH_DENOISE_NOISY"),
        std::env::var_os("FACESYNTH_DENOISE_CLEAN"),
    ) {
        (Some(n), Some(c)) => (n.into(), c.into()),
        _ => (
            common::synth_dataset(subjects, seed, false),
            common::synth_dataset(subjects, seed, true),
        ),
    }
}

/// The full benchmark (≥ 20 scans): `cargo test --release --no-default-features --test
/// denoise -- --ignored --nocapture benchmark`. Prints Markdown tables.
#[test]
#[ignore]
fn benchmark_against_clean_twins() {
    let (noisy, clean) = bench_dirs(5, 1);
    let pairs = eval::load_pairs(&noisy, &clean, usize::MAX).unwrap();
    let verts: usize = pairs.iter().map(|p| p.noisy.vertex_count()).sum();
    println!(
        "{} scans, mean {} vertices",
        pairs.len(),
        verts / pairs.len().max(1)
    );
    let b = eval::benchmark(&pairs, 60).unwrap();
    println!("{}", eval::markdown_table(&b.table));
    let sweeps: Vec<_> = b
        .laplacian_sweep
        .iter()
        .chain(&b.taubin_sweep)
        .filter(|s| s.k <= 10 || s.k % 5 == 0)
        .cloned()
        .collect();
    println!("{}", eval::markdown_table(&sweeps));
}

/// Regression on a small generated set (2 subjects × 5 scans, seed 11; generated by
/// synth_gavab.py on first use): the default removes the spikes, leaves the rest alone and
/// beats both baselines. Measured values are in the comments; bounds leave a margin.
#[test]
fn default_beats_the_baselines_on_generated_scans() {
    let (noisy, clean) = bench_dirs(2, 11);
    let pairs = eval::load_pairs(&noisy, &clean, usize::MAX).unwrap();
    assert_eq!(pairs.len(), 10);
    let input = eval::input_score(&pairs);
    let ours = eval::score_method(&pairs, "default", &DenoiseParams::default()).unwrap();
    let lap = eval::score_method(
        &pairs,
        "laplacian",
        &DenoiseParams::baseline(DenoiseMethod::Laplacian, 4),
    )
    .unwrap();
    let taubin = eval::score_method(
        &pairs,
        "taubin",
        &DenoiseParams::baseline(DenoiseMethod::Taubin, 37),
    )
    .unwrap();
    println!(
        "{}",
        eval::markdown_table(&[input.clone(), ours.clone(), lap.clone(), taubin.clone()])
    );
    assert!(input.rmse_mm > 0.8, "input {input:?}");
    // Injected spikes leave the surface: over 90 % of the input's vertices > 2 mm off their
    // twins are > 2 mm off the clean surface too (z spikes on steep sides are closer to it;
    // 98.8 % on seed 2024's 100 scans). The default leaves none > 2 mm off it.
    let (input_far, ours_far) = (
        input.over_2mm_surface.unwrap(),
        ours.over_2mm_surface.unwrap(),
    );
    assert!(input_far <= input.over_2mm && input_far * 10 > input.over_2mm * 9);
    assert!(
        ours_far == 0 && ours.max_surface_mm.unwrap() <= ours.max_mm,
        "{ours:?}"
    );
    assert!(ours.rmse_mm < 0.2, "{ours:?}"); // measured 0.151 mm
    assert!(ours.rmse_mm < 0.5 * lap.rmse_mm.min(taubin.rmse_mm));
    // The goal, every spike gone: max error ≤ 2 mm (measured 0.63 mm, none of the
    // input's 449 left; 1.54 mm while repairs over 3 mm were kept, until stop 32; 1 left at 6.3 mm before the cluster and repair checks of
    // `removal`, 33 and 36 mm before unrepairable vertices were removed).
    assert!(
        ours.over_2mm == 0 && ours.max_mm <= 2.0,
        "{} of {} left, max {} mm",
        ours.over_2mm,
        input.over_2mm,
        ours.max_mm
    );
    // What removal costs: measured 449 spike and 326 other vertices of ~153,000, and 166 of
    // the clean twins' (179 and 104 with fragments of ≤ 4 vertices and rims judged by their
    // 3-ring, until stop 32; 65 and 44 before stop 31's fragments). Every spike the filter
    // moves back is a repair over 3 mm, so nearly all spike vertices go (all 449; 220 while
    // those repairs were kept).
    let vertices: usize = pairs.iter().map(|p| p.noisy.vertex_count()).sum();
    assert!(ours.removed_spikes * 100 >= input.over_2mm * 95, "{ours:?}");
    assert!(ours.removed_non_spike * 300 < vertices, "{ours:?}");
    assert!(ours.clean_removed * 600 < vertices, "{ours:?}");
    assert!(ours.shrinkage_mm.abs() < 0.02, "{ours:?}");
    // Noise-free twins are (almost) left alone.
    assert!(ours.clean_rmse_mm < 0.1, "{ours:?}");
    assert!(ours.rmse_non_spike_mm < 0.2, "{ours:?}");
}

/// A scan in other axes (facing −x, forehead +z, as some tools export) is denoised as the same
/// scan in the scanner frame: the filter works along the line of sight, found from the normals
/// (the same vertices moved and removed, the same positions turned back).
#[test]
fn a_scan_in_other_axes_is_denoised_along_its_line_of_sight() {
    let base = facesynth::io::read_mesh(&common::gavab("cara1_sonrisa.wrl")).unwrap();
    // (x, y, z) ↦ (−z, −x, y): +z (the line of sight) to −x, +y to +z.
    let turn = |p: DVec3| DVec3::new(-p.z, -p.x, p.y);
    let mut turned = base.clone();
    for p in &mut turned.positions_mm {
        *p = turn(*p);
    }
    turned.update_normals();
    let mut level = base.clone();
    let a = denoise(&mut level, &DenoiseParams::default()).unwrap();
    let b = denoise(&mut turned, &DenoiseParams::default()).unwrap();
    assert!(a.vertices_removed > 0);
    assert_eq!(
        (a.vertices_moved, a.vertices_removed, &a.kept),
        (b.vertices_moved, b.vertices_removed, &b.kept)
    );
    for (p, q) in level.positions_mm.iter().zip(&turned.positions_mm) {
        assert!((turn(*p) - *q).length() < 1e-9, "{p} vs {q}");
    }
}
