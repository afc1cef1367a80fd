//! Scan to closed surface (issue 3: under 2 s for a 150,000-vertex scan on the 2-core
//! machine): the phantom scan (145,245 vertices), already in memory with its topology,
//! spatial index and frame, through `plan::model::build_model` (cut curves, cutting,
//! fill-ins, breast and quadrant volumes, closed surface with its watertightness and
//! self-intersection checks). Writing the files is not included.

use criterion::{Criterion, criterion_group, criterion_main};
use phantom::PhantomParams;
use plan::model::{ModelOptions, build_model};
use plan::{MarkedScan, Scan, Silent};
use std::hint::black_box;
use std::path::Path;

fn bench_model(c: &mut Criterion) {
    let phantom = phantom::generate(&PhantomParams::default());
    let marked = MarkedScan::new(
        Scan::from_mesh(phantom.scan, Path::new("phantom.ply")).expect("a valid scan"),
        phantom.landmarks,
        Path::new("phantom.json"),
        &Silent,
    )
    .expect("landmarks on the scan");
    let options = ModelOptions::default();
    let mut group = c.benchmark_group("model");
    group.sample_size(10);
    group.bench_function(
        format!(
            "scan to closed surface ({} vertices)",
            marked.scan.mesh.vertex_count()
        ),
        |b| {
            b.iter(|| {
                build_model(black_box(&marked), &options, &Silent).expect("the phantom's model")
            })
        },
    );
    group.finish();
}

criterion_group!(benches, bench_model);
criterion_main!(benches);
