//! Elements with a rest shape of their own (`FemModel::set_rest_shape`): an inflated
//! element pushes until its vertices reach its shape, against analytic answers.

use fem::{Constraints, FemModel, Formulation, Material, SolveOptions, StaticSolver, box_mesh};
use glam::{DMat3, DVec3};

/// A box whose every element is given its rest shape stretched by `s` about the origin
/// (a uniform eigenstrain) and whose `x = 0` face is held at that stretch's displacement
/// reaches the stretch everywhere: `u = (s - 1) X` is stress-free and satisfies every
/// constraint, so it is the unique equilibrium. Linear and corotated, to 1e-9 mm; also
/// for a stretch with a turn (corotated only: the linear strain is not turn-invariant).
#[test]
fn a_box_of_inflated_elements_reaches_their_shape() {
    let mesh = box_mesh(DVec3::ZERO, DVec3::new(40.0, 20.0, 10.0), [4, 2, 2]);
    let turn = DMat3::from_rotation_z(0.3);
    for (map, formulations) in [
        (
            DMat3::from_diagonal(DVec3::new(1.4, 1.1, 0.9)),
            &[Formulation::Linear, Formulation::Corotated][..],
        ),
        (
            turn * DMat3::from_diagonal(DVec3::new(1.3, 1.0, 1.2)),
            &[Formulation::Corotated][..],
        ),
    ] {
        let mut model = FemModel::homogeneous(&mesh, Material::new(10.0, 0.45)).unwrap();
        for (e, t) in mesh.tets.iter().enumerate() {
            model
                .set_rest_shape(e, t.map(|v| map * mesh.positions[v as usize]))
                .unwrap();
        }
        let exact: Vec<DVec3> = mesh.positions.iter().map(|&x| map * x - x).collect();
        let mut constraints = Constraints::new();
        for (v, x) in mesh.positions.iter().enumerate() {
            if x.x == 0.0 {
                constraints.prescribe(v as u32, exact[v]);
            }
        }
        for &formulation in formulations {
            let options = SolveOptions {
                formulation,
                max_iterations: 60,
                relative_tolerance: 1e-12,
                ..SolveOptions::default()
            };
            let f = vec![DVec3::ZERO; mesh.positions.len()];
            let solution = StaticSolver::new(&model, &constraints)
                .unwrap()
                .solve(&model, &f, None, &options)
                .unwrap();
            let worst = solution
                .displacement
                .iter()
                .zip(&exact)
                .map(|(u, e)| (*u - *e).length())
                .fold(0.0, f64::max);
            assert!(worst < 1e-9, "{formulation:?}: {worst:e} mm");
            // stress-free there: no energy
            let energy = model.potential_energy(&exact, &f, formulation);
            assert!(energy.abs() < 1e-9, "{formulation:?}: {energy:e}");
        }
    }
}

/// The rest shape's volume is the element's: its weight follows it, and a reset gives
/// the mesh's back.
#[test]
fn an_element_weighs_as_its_rest_shape() {
    let mesh = box_mesh(DVec3::ZERO, DVec3::splat(10.0), [1, 1, 1]);
    let mut model = FemModel::homogeneous(&mesh, Material::default()).unwrap();
    let g = DVec3::new(0.0, -9.81, 0.0);
    let weight =
        |model: &FemModel| -> f64 { model.gravity_forces(g).unwrap().iter().map(|f| f.y).sum() };
    let before = weight(&model);
    let t = mesh.tets[0];
    let doubled = t.map(|v| mesh.positions[v as usize] * DVec3::new(2.0, 1.0, 1.0));
    model.set_rest_shape(0, doubled).unwrap();
    let one_volume = model.elements()[0].volume_mm3;
    let others: f64 = model.elements()[1..].iter().map(|e| e.volume_mm3).sum();
    let scale = (one_volume + others) / (one_volume / 2.0 + others);
    assert!((weight(&model) / before - scale).abs() < 1e-12);
    model.reset_rest_shape(0).unwrap();
    assert!((weight(&model) / before - 1.0).abs() < 1e-12);
    // an inverted shape is refused, the model unchanged
    let flipped = [doubled[1], doubled[0], doubled[2], doubled[3]];
    assert!(model.set_rest_shape(0, flipped).is_err());
    assert!((weight(&model) / before - 1.0).abs() < 1e-12);
}
