//! The barycentric prolongation between non-nested levels.

mod common;

use common::*;
use fem::{Constraints, FemModel, Material, Prolongation, ReducedSystem, box_mesh};
use glam::{DMat3, DVec3};

fn affine(x: DVec3) -> DVec3 {
    DMat3::from_cols(
        DVec3::new(0.3, -0.1, 0.2),
        DVec3::new(0.05, 0.4, -0.3),
        DVec3::new(-0.2, 0.1, 0.25),
    ) * x
        + DVec3::new(1.0, -2.0, 0.5)
}

/// Nested levels: fine vertices on coarse vertices get them exactly; affine fields are
/// reproduced to 1e-12 relative everywhere.
#[test]
fn prolongation_on_nested_box_levels() {
    let coarse = box_mesh(DVec3::ZERO, DVec3::splat(40.0), [2, 2, 2]);
    let fine = box_mesh(DVec3::ZERO, DVec3::splat(40.0), [4, 4, 4]);
    let p = Prolongation::new(&coarse, &fine).unwrap();
    let uc: Vec<DVec3> = coarse.positions.iter().map(|&x| affine(x)).collect();
    let mut uf = vec![DVec3::ZERO; fine.positions.len()];
    p.prolong(&uc, &mut uf);
    let exact: Vec<DVec3> = fine.positions.iter().map(|&x| affine(x)).collect();
    let err = max_diff(&uf, &exact) / max_norm(&exact);
    println!("nested: affine field error {err:e}");
    assert!(err < 1e-12);
    assert!(p.distance_mm.iter().all(|&d| d == 0.0));
    for (row, x) in p.rows.iter().zip(&fine.positions) {
        let sum: f64 = row.iter().map(|r| r.1).sum();
        assert!((sum - 1.0).abs() < 1e-12);
        if let Some(c) = coarse.positions.iter().position(|y| y == x) {
            let w: f64 = row.iter().filter(|r| r.0 as usize == c).map(|r| r.1).sum();
            assert!((w - 1.0).abs() < 1e-12);
        }
    }
}

/// Non-nested levels, the fine mesh jittered and reaching 3 mm beyond the coarse one:
/// outside vertices are extrapolated from the nearest coarse element, which still
/// reproduces affine fields (1e-12 relative). Restriction is the transpose:
/// `<P c, f> = <c, Pᵀ f>` to 1e-12 relative.
#[test]
fn prolongation_on_non_nested_levels_and_restriction_is_the_transpose() {
    let coarse = box_mesh(DVec3::ZERO, DVec3::new(40.0, 30.0, 30.0), [3, 2, 2]);
    let fine = jittered_box(
        DVec3::splat(-3.0),
        DVec3::new(43.0, 33.0, 33.0),
        [7, 5, 5],
        0.15,
    );
    let p = Prolongation::new(&coarse, &fine).unwrap();
    assert!(p.distance_mm.iter().any(|&d| d > 0.0));
    let uc: Vec<DVec3> = coarse.positions.iter().map(|&x| affine(x)).collect();
    let mut uf = vec![DVec3::ZERO; fine.positions.len()];
    p.prolong(&uc, &mut uf);
    let exact: Vec<DVec3> = fine.positions.iter().map(|&x| affine(x)).collect();
    let err = max_diff(&uf, &exact) / max_norm(&exact);
    println!("non-nested with extrapolation: affine field error {err:e}");
    assert!(err < 1e-12);

    let f: Vec<DVec3> = (0..fine.positions.len())
        .map(|k| DVec3::new((k % 7) as f64 - 3.0, (k % 5) as f64, -((k % 3) as f64)))
        .collect();
    let mut rf = vec![DVec3::ZERO; coarse.positions.len()];
    p.restrict(&f, &mut rf);
    let lhs: f64 = uf.iter().zip(&f).map(|(a, b)| a.dot(*b)).sum();
    let rhs: f64 = uc.iter().zip(&rf).map(|(a, b)| a.dot(*b)).sum();
    assert!((lhs - rhs).abs() < 1e-12 * lhs.abs().max(1.0));

    // the reduced operator drops constrained rows and columns
    let mut cc = Constraints::new();
    let mut cf = Constraints::new();
    for (v, x) in coarse.positions.iter().enumerate() {
        if x.x == 0.0 {
            cc.fix(v as u32);
        }
    }
    for (v, x) in fine.positions.iter().enumerate() {
        if x.x == -3.0 {
            cf.fix(v as u32);
        }
    }
    let mc = FemModel::homogeneous(&coarse, Material::default()).unwrap();
    let mf = FemModel::homogeneous(&fine, Material::default()).unwrap();
    let sc = ReducedSystem::new(&mc, &cc).unwrap();
    let sf = ReducedSystem::new(&mf, &cf).unwrap();
    let (row_ptr, cols, _) = p.reduced(&sf.reduced_of, &sc.reduced_of);
    assert_eq!(row_ptr.len(), sf.unknowns() + 1);
    assert!(cols.iter().all(|&c| (c as usize) < sc.unknowns()));
}
