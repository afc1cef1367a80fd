//! Implant setup (placement, footprint check, displacement template) on the phantom's
//! 60,000-element model, one interactive cycle, and carrying the displacement to the
//! scan (the live view's per-frame update).
//! `cargo bench -p simulation --bench template`

use anatomy::breast::Side;
use criterion::{Criterion, criterion_group, criterion_main};
use implant::Catalog;
use phantom::PhantomParams;
use plan::model::{ModelOptions, build_model};
use plan::{MarkedScan, Scan, Silent};
use simulation::{PatientInput, Placement, Simulation, SimulationOptions};
use std::path::Path;

fn bench(c: &mut Criterion) {
    let phantom = phantom::generate(&PhantomParams::default());
    let marked = MarkedScan::new(
        Scan::from_mesh(phantom.scan.clone(), Path::new("phantom.ply")).unwrap(),
        phantom.landmarks.clone(),
        Path::new("phantom.json"),
        None,
        &Silent,
    )
    .unwrap();
    let model = build_model(&marked, &ModelOptions::default(), &Silent).unwrap();
    let input = PatientInput {
        scan: &marked.scan.mesh,
        landmarks: &marked.landmarks,
        frame: &marked.frame,
        breasts: &model.breasts,
        closed_surface: &model.closed_surface,
        tets: &model.tets,
    };
    let mut sim = Simulation::new(input, SimulationOptions::default()).unwrap();
    let shape = *Catalog::builtin().get("R-MOD-120").unwrap().shape();
    let elements = model.tets.levels[0].mesh.tet_count();
    let mut up = 0.0;
    c.bench_function(&format!("implant_setup_{elements}_elements"), |b| {
        b.iter(|| {
            up = if up == 0.0 { 1.0 } else { 0.0 };
            sim.set_implant(Side::Left, shape, Placement::moved(0.0, up, 0.0))
                .unwrap()
                .template
                .implant_vertices
                .len()
        })
    });
    sim.set_implant(Side::Right, shape, Placement::default())
        .unwrap();
    sim.run(true).unwrap();
    c.bench_function(&format!("cycle_{elements}_elements"), |b| {
        b.iter(|| sim.cycle().unwrap().residual_mn)
    });
    let vertices = marked.scan.mesh.vertex_count();
    c.bench_function(&format!("scan_displacements_{vertices}_vertices"), |b| {
        b.iter(|| sim.scan_displacements().len())
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench
}
criterion_main!(benches);
