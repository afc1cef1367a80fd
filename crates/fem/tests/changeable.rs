//! Changeable constraints: a hierarchy built once with only the permanent constraints
//! (the bottom face of a box, the chest wall), then a sequence of implant-like constraint
//! sets applied with `Multigrid::set_constraints` (symmetric elimination, masked
//! transfers) must give the answers of systems built from scratch with all the
//! constraints permanent.
//!
//! Body: the jittered box `[0, 100] x [0, 60] x [0, 60]` mm, 3 kPa, ν = 0.45, gravity;
//! coarse levels are non-nested boxes.

mod common;

use common::*;
use fem::multigrid::{Multigrid, MultigridOptions};
use fem::{
    Constraints, DirectSolver, FemError, FemModel, Formulation, Material, ReducedSystem,
    STANDARD_GRAVITY_M_S2, box_mesh,
};
use glam::DVec3;
use std::time::Instant;
use tetra::TetMesh;

const SIZE: DVec3 = DVec3::new(100.0, 60.0, 60.0);

fn wall(mesh: &TetMesh) -> Constraints {
    let mut c = Constraints::new();
    for (v, x) in mesh.positions.iter().enumerate() {
        if x.z <= 1e-9 {
            c.fix(v as u32);
        }
    }
    c
}

/// An implant-like template: the top-face vertices within `radius` of `(cx, cy)` pushed
/// down by a smooth bump of `depth` mm, and (if `hold_below`) the vertices of the plane
/// `z = 30` inside the same radius held fixed (a "behind the fill-in" set).
fn template(mesh: &TetMesh, cx: f64, cy: f64, radius: f64, depth: f64, hold: bool) -> Constraints {
    let mut c = Constraints::new();
    for (v, x) in mesh.positions.iter().enumerate() {
        let r = ((x.x - cx).powi(2) + (x.y - cy).powi(2)).sqrt();
        if r > radius {
            continue;
        }
        if x.z >= 60.0 - 1e-9 {
            let s = (std::f64::consts::PI * r / (2.0 * radius)).cos().powi(2);
            c.prescribe(v as u32, DVec3::new(0.2 * depth * s, 0.0, -depth * s));
        } else if hold && (x.z - 30.0).abs() < 3.0 {
            c.fix(v as u32);
        }
    }
    c
}

fn union(a: &Constraints, b: &Constraints) -> Constraints {
    let mut c = a.clone();
    c.prescribed.extend_from_slice(&b.prescribed);
    c
}

fn meshes(cells: &[[usize; 3]]) -> Vec<TetMesh> {
    cells
        .iter()
        .enumerate()
        .map(|(l, &n)| {
            if l == 0 {
                jittered_box(DVec3::ZERO, SIZE, n, 0.15)
            } else {
                box_mesh(DVec3::ZERO, SIZE, n)
            }
        })
        .collect()
}

fn levels(meshes: &[TetMesh], finest: &Constraints) -> Vec<(FemModel, Constraints)> {
    let material = Material::new(3.0, 0.45);
    meshes
        .iter()
        .enumerate()
        .map(|(l, m)| {
            let c = if l == 0 { finest.clone() } else { wall(m) };
            (FemModel::homogeneous(m, material).unwrap(), c)
        })
        .collect()
}

/// The reference: a reduced system built from scratch with all the constraints, assembled
/// at `u` (all vertices); returns the reduced system and its direct solution.
fn reference(
    model: &FemModel,
    all: &Constraints,
    u: &[DVec3],
    f_ext: &[DVec3],
    formulation: Formulation,
) -> (ReducedSystem, Vec<DVec3>) {
    let mut sys = ReducedSystem::new(model, all).unwrap();
    sys.assemble(model, u, f_ext, formulation, fem::Tangent::Warped)
        .unwrap();
    let x = DirectSolver::new(&sys.matrix)
        .unwrap()
        .solve(&sys.matrix, &sys.rhs)
        .unwrap();
    (sys, x)
}

/// Several constraint sets in a row on one hierarchy, linear and corotated: the
/// eliminated system's free rows equal the reference's, its direct solution and its
/// PCG solution (V(2,1) preconditioner, tolerance 1e-12) equal the reference's direct
/// solution to 1e-10 relative, the coarse spaces are those of a hierarchy built from
/// scratch, and the reused hierarchy's V-cycles are bitwise those of a hierarchy built
/// from scratch with the same permanent constraints and the same changeable ones.
#[test]
fn changed_constraints_match_fresh_systems() {
    let cells: &[[usize; 3]] = &[[20, 12, 12], [11, 7, 7], [5, 3, 3]];
    let meshes = meshes(cells);
    let permanent = wall(&meshes[0]);
    let mut mg =
        Multigrid::with_permanent_constraints(levels(&meshes, &permanent), Default::default())
            .unwrap();
    let model = mg.model().clone();
    let gravity = model
        .gravity_forces(DVec3::new(0.0, 0.0, -STANDARD_GRAVITY_M_S2))
        .unwrap();
    let sets = [
        template(&meshes[0], 50.0, 30.0, 20.0, 8.0, false),
        template(&meshes[0], 35.0, 25.0, 25.0, 10.0, true),
        template(&meshes[0], 70.0, 35.0, 15.0, 6.0, true),
        template(&meshes[0], 50.0, 30.0, 30.0, 12.0, false),
        template(&meshes[0], 50.0, 30.0, 20.0, 8.0, false),
    ];
    for (k, changeable) in sets.iter().enumerate() {
        let t0 = Instant::now();
        mg.set_constraints(changeable).unwrap();
        let set_ms = t0.elapsed().as_secs_f64() * 1e3;
        let all = union(&permanent, changeable);
        // coarse spaces equal those of a hierarchy built from scratch
        let fresh = Multigrid::new(levels(&meshes, &all), Default::default()).unwrap();
        assert_eq!(mg.active_unknowns_per_level(), fresh.unknowns_per_level());
        println!(
            "set {k}: set_constraints {set_ms:.3} ms, active unknowns {:?} of {:?}",
            mg.active_unknowns_per_level(),
            mg.unknowns_per_level()
        );
        let reduced_of = mg.system().reduced_of.clone();
        let sys_index = |v: u32| reduced_of[v as usize] as usize;
        let u0 = mg
            .system()
            .expand(&vec![DVec3::ZERO; mg.system().unknowns()]);
        let mut x_lin = Vec::new();
        for formulation in [Formulation::Linear, Formulation::Corotated] {
            let u = if formulation == Formulation::Linear {
                u0.clone()
            } else {
                // a large deformation: three times the linear answer
                let (rs, _) = reference(&model, &all, &u0, &gravity, Formulation::Linear);
                let mut u = u0.clone();
                for (&v, d) in rs.free.iter().zip(&x_lin) {
                    u[v as usize] = *d * 3.0;
                }
                u
            };
            mg.assemble(&u, &gravity, formulation).unwrap();
            let (rs, x_ref) = reference(&model, &all, &u, &gravity, formulation);
            // the free rows of the eliminated system are the reference's
            let a = &mg.system().matrix;
            let mut max_block_diff: f64 = 0.0;
            let mut max_block: f64 = 0.0;
            for (i, &v) in rs.free.iter().enumerate() {
                let ii = sys_index(v);
                assert_eq!(mg.system().rhs[ii], rs.rhs[i]);
                for s in rs.matrix.row_ptr[i]..rs.matrix.row_ptr[i + 1] {
                    let jj = sys_index(rs.free[rs.matrix.cols[s] as usize]);
                    let t = a.slot(ii, jj).unwrap();
                    for q in 0..9 {
                        max_block_diff =
                            max_block_diff.max((a.values[t][q] - rs.matrix.values[s][q]).abs());
                        max_block = max_block.max(rs.matrix.values[s][q].abs());
                    }
                }
            }
            assert!(max_block_diff <= 1e-14 * max_block, "{max_block_diff}");
            let b = mg.system().rhs.clone();
            let x_direct = DirectSolver::new(a).unwrap().solve(a, &b).unwrap();
            let mut x = vec![DVec3::ZERO; b.len()];
            let res = mg.pcg(&b, &mut x, 1e-12, 200);
            let gather =
                |y: &[DVec3]| -> Vec<DVec3> { rs.free.iter().map(|&v| y[sys_index(v)]).collect() };
            let e_direct = rel_diff(&gather(&x_direct), &x_ref);
            let e_pcg = rel_diff(&gather(&x), &x_ref);
            let held_max = mg
                .system()
                .eliminated()
                .iter()
                .zip(&x)
                .filter(|(e, _)| **e)
                .map(|(_, d)| d.length())
                .fold(0.0, f64::max);
            println!(
                "  {formulation:?}: PCG {} iterations, direct vs reference {e_direct:.1e}, \
                 PCG vs reference {e_pcg:.1e}, held correction {held_max:e}",
                res.iterations
            );
            assert!(res.converged);
            assert!(e_direct <= 1e-10, "{e_direct}");
            assert!(e_pcg <= 1e-10, "{e_pcg}");
            assert_eq!(held_max, 0.0);
            if formulation == Formulation::Linear {
                x_lin = x_ref.clone();
            }

            // history independence: a hierarchy built now with the same permanent and
            // changeable constraints cycles bitwise alike
            let mut again = Multigrid::with_permanent_constraints(
                levels(&meshes, &permanent),
                Default::default(),
            )
            .unwrap();
            again.set_constraints(changeable).unwrap();
            again.assemble(&u, &gravity, formulation).unwrap();
            let mut y1 = vec![DVec3::ZERO; b.len()];
            let mut y2 = vec![DVec3::ZERO; b.len()];
            for _ in 0..2 {
                mg.vcycle(&mut y1, &b);
                again.vcycle(&mut y2, &b);
            }
            assert_eq!(y1, y2);
        }
    }
}

/// The bare V(2,1) cycle on the eliminated system converges like the cycle of a
/// hierarchy built from scratch with all the constraints (same coarse spaces and
/// operators; only the colour order of the smoother differs), with the plain and with
/// the smoothed finest prolongation.
#[test]
fn changed_constraints_cycle_like_fresh_hierarchy() {
    let cells: &[[usize; 3]] = &[[20, 12, 12], [7, 4, 4]];
    let meshes = meshes(cells);
    let permanent = wall(&meshes[0]);
    for options in [
        MultigridOptions::default(),
        MultigridOptions {
            prolongation_smoothing: 0.5,
            ..MultigridOptions::default()
        },
    ] {
        let mut mg =
            Multigrid::with_permanent_constraints(levels(&meshes, &permanent), options).unwrap();
        for changeable in [
            template(&meshes[0], 50.0, 30.0, 20.0, 8.0, true),
            template(&meshes[0], 40.0, 30.0, 25.0, 8.0, false),
        ] {
            mg.set_constraints(&changeable).unwrap();
            let all = union(&permanent, &changeable);
            let mut fresh = Multigrid::new(levels(&meshes, &all), options).unwrap();
            let mut errors = Vec::new();
            for m in [&mut mg, &mut fresh] {
                let u0 = m.system().expand(&vec![DVec3::ZERO; m.system().unknowns()]);
                m.assemble(&u0, &[], Formulation::Linear).unwrap();
                let b = m.system().rhs.clone();
                let a = &m.system().matrix;
                let x_direct = DirectSolver::new(a).unwrap().solve(a, &b).unwrap();
                let mut x = vec![DVec3::ZERO; b.len()];
                for _ in 0..5 {
                    m.vcycle(&mut x, &b);
                }
                errors.push(rel_diff(&x, &x_direct));
            }
            println!(
                "error after five cycles: reused {:.2e}, fresh {:.2e}",
                errors[0], errors[1]
            );
            assert!(errors[0] <= 2.0 * errors[1] && errors[1] <= 2.0 * errors[0]);
        }
    }
}

/// Interactive use: `cycle` after `set_constraints` imposes the new prescribed values
/// and converges to the reference; errors are reported, not panics.
#[test]
fn interactive_cycles_after_set_constraints() {
    let cells: &[[usize; 3]] = &[[20, 12, 12], [7, 4, 4]];
    let meshes = meshes(cells);
    let mut mg = Multigrid::with_permanent_constraints(
        levels(&meshes, &Constraints::new()),
        Default::default(),
    )
    .unwrap();
    let n = mg.model().vertex_count();
    let mut u = vec![DVec3::ZERO; n];
    // nothing held: singular
    assert!(matches!(
        mg.set_constraints(&Constraints::new()),
        Err(FemError::NoConstraints)
    ));
    assert!(matches!(
        mg.cycle(&mut u, &[], Formulation::Linear),
        Err(FemError::NoConstraints)
    ));
    let mut bad = Constraints::new();
    bad.fix(n as u32);
    assert!(matches!(
        mg.set_constraints(&bad),
        Err(FemError::ConstraintOutOfRange { .. })
    ));
    let mut not_finite = Constraints::new();
    not_finite.prescribe(5, DVec3::new(0.0, f64::NAN, 0.0));
    assert!(matches!(
        mg.set_constraints(&not_finite),
        Err(FemError::NonFiniteInput { vertex: 5, .. })
    ));
    let c = union(
        &wall(&meshes[0]),
        &template(&meshes[0], 50.0, 30.0, 20.0, 8.0, false),
    );
    mg.set_constraints(&c).unwrap();
    for _ in 0..30 {
        mg.cycle(&mut u, &[], Formulation::Linear).unwrap();
    }
    let model = mg.model().clone();
    let u0 = mg
        .system()
        .expand(&vec![DVec3::ZERO; mg.system().unknowns()]);
    let (rs, x_ref) = reference(&model, &c, &u0, &[], Formulation::Linear);
    let u_ref = rs.expand(&x_ref);
    println!("30 cycles vs reference: {:.2e}", rel_diff(&u, &u_ref));
    assert!(rel_diff(&u, &u_ref) < 1e-8);
    // changing a prescribed value of a held vertex, and refusing a free one
    let (v, _) = c.prescribed[c.prescribed.len() - 1];
    mg.set_prescribed(v, DVec3::new(0.0, 0.0, -1.0)).unwrap();
    let free = rs.free[0];
    assert!(mg.set_prescribed(free, DVec3::ZERO).is_err());
    mg.cycle(&mut u, &[], Formulation::Linear).unwrap();
    assert_eq!(u[v as usize], DVec3::new(0.0, 0.0, -1.0));
}

/// A hierarchy kept across a change of tangent (the session's stages: warped stiffness
/// for the implant, full tangent for the gravity correction) and of constraints must
/// assemble and cycle exactly like one built for them: after `set_tangent` and
/// `set_constraints`, the assembled finest system and three V-cycles from zero are
/// bitwise those of a hierarchy built with the full tangent and the same changeable
/// constraints (same patterns, colourings and arithmetic). And back: the warped stage
/// again equals a hierarchy that never left it.
#[test]
fn a_kept_hierarchy_changes_tangent_like_a_fresh_one() {
    let cells: &[[usize; 3]] = &[[20, 12, 12], [7, 4, 4]];
    let meshes = meshes(cells);
    let hierarchy = |tangent| {
        let options = MultigridOptions {
            tangent,
            ..Default::default()
        };
        Multigrid::with_permanent_constraints(levels(&meshes, &wall(&meshes[0])), options).unwrap()
    };
    let implant = union(
        &wall(&meshes[0]),
        &template(&meshes[0], 50.0, 30.0, 20.0, 8.0, true),
    );
    let released = wall(&meshes[0]);
    let mut kept = hierarchy(fem::Tangent::Warped);
    kept.set_constraints(&implant).unwrap();
    let n = kept.model().vertex_count();
    let mut u = vec![DVec3::ZERO; n];
    for _ in 0..4 {
        kept.cycle(&mut u, &[], Formulation::Corotated).unwrap();
    }
    let cycles = |mg: &mut Multigrid| {
        mg.assemble(&u, &[], Formulation::Corotated).unwrap();
        let b = mg.system().rhs.clone();
        let mut x = vec![DVec3::ZERO; b.len()];
        for _ in 0..3 {
            mg.vcycle(&mut x, &b);
        }
        (mg.system().matrix.clone(), x)
    };
    for (tangent, constraints) in [
        (fem::Tangent::Full, &released),
        (fem::Tangent::Warped, &implant),
    ] {
        kept.set_tangent(tangent);
        kept.set_constraints(constraints).unwrap();
        assert_eq!(kept.tangent(), tangent);
        let mut fresh = hierarchy(tangent);
        fresh.set_constraints(constraints).unwrap();
        let (a_kept, x_kept) = cycles(&mut kept);
        let (a_fresh, x_fresh) = cycles(&mut fresh);
        assert!(a_kept == a_fresh, "{tangent:?}: assembled systems differ");
        assert!(x_kept == x_fresh, "{tangent:?}: V-cycles differ");
    }
}

/// The reaction norm `Σ |f_v|²` over the held vertices, gathered from the held vertices'
/// incident elements only, equals the one summed from the forces at every vertex
/// (`nodal_forces`), for permanent (the wall) and changeable (the template) constraints
/// in a deformed corotated state: to 1e-12 relative (only the order of the sums differs).
#[test]
fn reaction_norm_matches_the_nodal_forces() {
    let cells: &[[usize; 3]] = &[[20, 12, 12], [7, 4, 4]];
    let meshes = meshes(cells);
    let mut mg = Multigrid::with_permanent_constraints(
        levels(&meshes, &wall(&meshes[0])),
        Default::default(),
    )
    .unwrap();
    let implant = union(
        &wall(&meshes[0]),
        &template(&meshes[0], 50.0, 30.0, 20.0, 8.0, true),
    );
    mg.set_constraints(&implant).unwrap();
    let mut u = vec![DVec3::ZERO; mg.model().vertex_count()];
    for _ in 0..3 {
        mg.cycle(&mut u, &[], Formulation::Corotated).unwrap();
    }
    mg.assemble(&u, &[], Formulation::Corotated).unwrap();
    let sys = mg.system();
    let f = sys.nodal_forces(mg.model());
    let summed: f64 = f
        .iter()
        .enumerate()
        .filter(|&(v, _)| sys.is_held(v as u32) || sys.reduced_of[v] == fem::NOT_FREE)
        .map(|(_, x)| x.length_squared())
        .sum();
    let gathered = sys.reaction_norm_squared();
    println!("reaction norm² {gathered:e} (summed {summed:e})");
    assert!(summed > 0.0);
    assert!((gathered - summed).abs() <= 1e-12 * summed);
}
