//! Kernels of the static solve on a structured box of about 15,000 and 60,000
//! tetrahedra, Poisson ratio 0.45, bottom face fixed and top face pushed sideways:
//! corotated assembly (warped and full tangent) and one sparse Cholesky
//! refactorisation and solve (symbolic factorisation reused).

use criterion::{Criterion, criterion_group, criterion_main};
use fem::{
    Constraints, DirectSolver, FemModel, Formulation, Material, ReducedSystem, Tangent, box_mesh,
};
use glam::DVec3;
use std::hint::black_box;

fn setup(n: [usize; 3]) -> (FemModel, ReducedSystem, Vec<DVec3>) {
    let size = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64) * 5.0;
    let mesh = box_mesh(DVec3::ZERO, size, n);
    let model = FemModel::homogeneous(&mesh, Material::default()).unwrap();
    let mut c = Constraints::new();
    for (v, x) in mesh.positions.iter().enumerate() {
        if x.z == 0.0 {
            c.fix(v as u32);
        } else if x.z == size.z {
            c.prescribe(v as u32, DVec3::new(0.3 * size.z, 0.0, -0.1 * size.z));
        }
    }
    let system = ReducedSystem::new(&model, &c).unwrap();
    // a sheared state: the linear interpolation of the top displacement
    let u: Vec<DVec3> = mesh
        .positions
        .iter()
        .map(|x| DVec3::new(0.3 * x.z, 0.0, -0.1 * x.z))
        .collect();
    (model, system, u)
}

fn kernels(c: &mut Criterion) {
    for n in [[14, 14, 13], [22, 22, 21]] {
        let (model, mut system, u) = setup(n);
        let ne = model.element_count();
        c.bench_function(&format!("assemble_warped_{ne}"), |b| {
            b.iter(|| {
                system
                    .assemble(
                        &model,
                        black_box(&u),
                        &[],
                        Formulation::Corotated,
                        Tangent::Warped,
                    )
                    .unwrap()
            })
        });
        c.bench_function(&format!("assemble_full_{ne}"), |b| {
            b.iter(|| {
                system
                    .assemble(
                        &model,
                        black_box(&u),
                        &[],
                        Formulation::Corotated,
                        Tangent::Full,
                    )
                    .unwrap()
            })
        });
        let mut direct = DirectSolver::new(&system.matrix).unwrap();
        let rhs = system.rhs.clone();
        c.bench_function(&format!("cholesky_refactor_solve_{ne}"), |b| {
            b.iter(|| direct.solve(&system.matrix, black_box(&rhs)).unwrap())
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = kernels
}
criterion_main!(benches);
