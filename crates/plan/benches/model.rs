//! Scan to model (issue 3: scan to closed surface under 2 s for a 150,000-vertex scan on
//! the 2-core machine): the phantom scan (145,245 vertices), already in memory with its
//! topology, spatial index and frame, through `plan::model::build_model` (cut curves,
//! cutting, fill-ins, breast and quadrant volumes, closed surface with its watertightness
//! and self-intersection checks, and the 3-level tetrahedral hierarchy), and the same for
//! a large hanging cup scanned with occlusion. Writing the files is not included. Then
//! (issue 4: a 60,000-element level under 1 s, the hierarchy under 2 s) the hierarchy
//! alone from the model's closed surface, including the surface's checks and index.

use criterion::{Criterion, criterion_group, criterion_main};
use phantom::{Cup, PhantomParams};
use plan::model::{ModelOptions, build_model};
use plan::{MarkedScan, Scan, Silent};
use std::hint::black_box;
use std::path::Path;

/// The phantom of `params` with its landmarks, as `mammaplan model` loads it.
fn marked_phantom(params: &PhantomParams) -> MarkedScan {
    let phantom = phantom::generate(params);
    MarkedScan::new(
        Scan::from_mesh(phantom.scan, Path::new("phantom.ply")).expect("a valid scan"),
        phantom.landmarks,
        Path::new("phantom.json"),
        None,
        &Silent,
    )
    .expect("landmarks on the scan")
}

fn bench_model(c: &mut Criterion) {
    let marked = marked_phantom(&PhantomParams::default());
    // A large, hanging cup scanned with occlusion: the crescent holes under both breasts
    // (some 470 mm round, 400 vertices) go through the 3D fill.
    let occluded = marked_phantom(&PhantomParams {
        cup: Cup::Large,
        ptosis: 0.7,
        occlusion: true,
        ..PhantomParams::default()
    });
    let options = ModelOptions::default();
    let mut group = c.benchmark_group("model");
    group.sample_size(10);
    for (what, marked) in [("scan", &marked), ("occluded large cup scan", &occluded)] {
        group.bench_function(
            format!(
                "{what} to model ({} vertices)",
                marked.scan.mesh.vertex_count()
            ),
            |b| {
                b.iter(|| {
                    build_model(black_box(marked), &options, &Silent).expect("the phantom's model")
                })
            },
        );
    }
    let model = build_model(&marked, &options, &Silent).expect("the phantom's model");
    let closed = &model.closed_surface.mesh;
    group.bench_function(
        format!(
            "closed surface ({} triangles) to 3 levels from {} tetrahedra",
            closed.triangle_count(),
            options.elements
        ),
        |b| {
            b.iter(|| {
                let surface = tetra::ClosedSurface::new(black_box(closed)).expect("closed");
                tetra::build_hierarchy_with_elements(&surface, options.elements, 3)
                    .expect("the hierarchy")
            })
        },
    );
    group.finish();
}

criterion_group!(benches, bench_model);
criterion_main!(benches);
