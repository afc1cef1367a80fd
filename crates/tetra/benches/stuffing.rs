//! Meshing a breast-model-sized closed surface (an ellipsoid of 250 × 200 × 100 mm as
//! 39,600 triangles): the surface checks, one 60,000-element level (target < 1 s) and
//! a three-level hierarchy (target < 2 s).

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use std::hint::black_box;
use tetra::{ClosedSurface, build_hierarchy, level_with_elements, stuff};

fn bench_stuffing(c: &mut Criterion) {
    let input = common::ellipsoid(DVec3::new(125.0, 100.0, 50.0), 200, 100);
    let surface = ClosedSurface::new(&input).expect("a closed surface");
    let level = level_with_elements(&surface, 60_000).expect("a 60k level");
    let spacing = level.spacing_mm;
    eprintln!(
        "{} triangles; spacing {spacing:.3} mm gives {} tetrahedra, {} vertices",
        input.triangle_count(),
        level.mesh.tet_count(),
        level.mesh.vertex_count()
    );
    let mut group = c.benchmark_group("stuffing");
    group.sample_size(20);
    group.bench_function("closed surface checks and index, 40k triangles", |b| {
        b.iter(|| ClosedSurface::new(black_box(&input)).expect("a closed surface"))
    });
    group.bench_function("one level, 60k tetrahedra", |b| {
        b.iter(|| stuff(black_box(&surface), spacing).expect("a mesh"))
    });
    group.bench_function("surface checks and one level, 60k tetrahedra", |b| {
        b.iter(|| {
            let surface = ClosedSurface::new(black_box(&input)).expect("a closed surface");
            stuff(&surface, spacing).expect("a mesh")
        })
    });
    group.bench_function("hierarchy of 3 levels from 60k tetrahedra", |b| {
        b.iter(|| build_hierarchy(black_box(&surface), spacing, 3).expect("a hierarchy"))
    });
    group.finish();
}

criterion_group!(benches, bench_stuffing);
criterion_main!(benches);
