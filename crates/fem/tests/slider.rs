//! Sliders ([`fem::Slider`]) against the analytic solution of a block compressed between
//! two frictionless plates, and their energy in the model's potential energy.

use fem::{
    Constraints, FemModel, Formulation, Material, Slider, SolveOptions, Tangent, box_mesh,
    solve_static,
};
use glam::DVec3;

const SIZE_MM: DVec3 = DVec3::new(30.0, 20.0, 40.0);

fn material() -> Material {
    Material {
        young_kpa: 10.0,
        poisson_ratio: 0.3,
        density_kg_m3: 1000.0,
    }
}

/// A block on a frictionless plate (sliders at `z = 0`) pressed down by `squeeze_mm` by
/// a second one (sliders on the top face, target `-squeeze_mm` along `z`). One bottom
/// corner is fixed, and a vertex halfway up the edge above the corner beside it along
/// `x` slides on the plane `y = 0` (they remove the rigid slides and the turn about `z`
/// the plates leave; the answer is what they already obey, so they add no force).
/// Uniaxial compression: strain `-ε` along `z` with `ε = squeeze / height` and, free to
/// slide, `ν ε` across; linear tetrahedra represent it exactly (the patch test), so
/// only the penalty's gap `force / k` separates the result from it.
#[test]
fn a_block_between_frictionless_plates_expands_sideways() {
    let n = [3, 2, 4];
    let mesh = box_mesh(DVec3::ZERO, SIZE_MM, n);
    let mut model = FemModel::homogeneous(&mesh, material()).unwrap();
    let squeeze_mm = 0.02 * SIZE_MM.z;
    let strain = squeeze_mm / SIZE_MM.z;
    let nu = material().poisson_ratio;
    let exact = |p: DVec3| DVec3::new(nu * strain * p.x, nu * strain * p.y, -strain * p.z);
    let stiffness_mn_per_mm = 1e7;
    let corner = 0u32;
    let mut sliders = vec![Slider {
        vertex: fem::box_vertex_index(n, n[0], 0, n[2] / 2),
        displacement: DVec3::ZERO,
        normal: DVec3::Y,
        stiffness_mn_per_mm: 1e7,
    }];
    for (v, p) in mesh.positions.iter().enumerate() {
        let v = v as u32;
        let on_plate = p.z == 0.0 || p.z == SIZE_MM.z;
        if on_plate && v != corner {
            sliders.push(Slider {
                vertex: v,
                displacement: DVec3::new(0.0, 0.0, -strain * p.z),
                normal: DVec3::Z * 2.0,
                stiffness_mn_per_mm,
            });
        }
    }
    model.set_sliders(&sliders).unwrap();
    assert!((model.sliders()[0].normal.length() - 1.0).abs() < 1e-15);
    let mut c = Constraints::new();
    c.fix(corner);
    for formulation in [Formulation::Linear, Formulation::Corotated] {
        let options = SolveOptions {
            formulation,
            tangent: Tangent::Full,
            ..SolveOptions::default()
        };
        let solution = solve_static(&model, &c, &[], &options).unwrap();
        assert!(
            solution.converged,
            "{formulation:?}: {}",
            solution.relative_residual
        );
        let worst = (mesh.positions.iter())
            .zip(&solution.displacement)
            .map(|(p, u)| (*u - exact(*p)).length())
            .fold(0.0, f64::max);
        // the plates' force on a vertex is below E ε A = 10 kPa * 0.02 * 600 mm² =
        // 120 mN, its gap below 1.2e-5 mm; the sideways slide is 0.18 mm at x = 30 mm
        println!("{formulation:?}: largest error {worst:.2e} mm");
        assert!(worst < 2e-5, "{formulation:?}: {worst}");
    }
}

/// The model's potential energy and internal forces include the sliders': at zero
/// displacement, where the elements store nothing, a slider whose plane lies `s` away
/// adds `½ k s²` and the force `k s n`.
#[test]
fn potential_energy_and_forces_include_the_sliders() {
    let mesh = box_mesh(DVec3::ZERO, SIZE_MM, [1, 1, 1]);
    let mut model = FemModel::homogeneous(&mesh, material()).unwrap();
    let u = vec![DVec3::ZERO; mesh.positions.len()];
    let elastic_only = model.potential_energy(&u, &[], Formulation::Linear);
    let normal = DVec3::new(1.0, 2.0, 2.0) / 3.0;
    let slider = Slider {
        vertex: 3,
        displacement: -normal * 0.5,
        normal,
        stiffness_mn_per_mm: 4.0,
    };
    model.set_sliders(&[slider]).unwrap();
    let energy = model.potential_energy(&u, &[], Formulation::Linear);
    assert!((energy - elastic_only - 0.5 * 4.0 * 0.25).abs() < 1e-12);
    let forces = model.internal_forces(&u, Formulation::Linear).unwrap();
    assert!((forces[3] - normal * 2.0).length() < 1e-12);
    for bad in [
        Slider {
            vertex: 99,
            ..slider
        },
        Slider {
            normal: DVec3::ZERO,
            ..slider
        },
        Slider {
            stiffness_mn_per_mm: 0.0,
            ..slider
        },
        Slider {
            displacement: DVec3::NAN,
            ..slider
        },
    ] {
        assert!(model.set_sliders(&[bad]).is_err(), "{bad:?}");
    }
    assert!(model.set_sliders(&[slider, slider]).is_err());
    assert_eq!(model.sliders(), &[slider]);
}
