//! The 3D hole fill (`mesh::patch_hole`) on a band wrapping 250° round a sphere, the
//! shape of the crescent a standing scan leaves under a hanging breast: rims of 276 and
//! 554 vertices (a crescent at 1.7 and 0.8 mm spacing); the triangulation's time is cubic
//! in the rim.

use criterion::{Criterion, criterion_group, criterion_main};
use mesh::{DVec3, Topology, TriMesh, patch_hole};
use std::hint::black_box;

/// A sphere of `radius_mm` with the band (latitude within 4°, longitude 0-250°) cut
/// out, and the band's boundary loop.
fn banded_sphere(radius_mm: f64, subdivisions: u32) -> (TriMesh, Topology, Vec<u32>) {
    let mut sphere = mesh::shapes::icosphere(radius_mm, subdivisions);
    let in_band: Vec<usize> = (0..sphere.triangle_count())
        .filter(|&t| {
            let c = sphere.triangle_positions(t).iter().sum::<DVec3>() / 3.0;
            let latitude = (c.z / c.length()).asin().to_degrees();
            let longitude = c.y.atan2(c.x).to_degrees().rem_euclid(360.0);
            latitude.abs() < 4.0 && longitude < 250.0
        })
        .collect();
    sphere.remove_triangles(&in_band);
    let topology = Topology::new(&sphere);
    let hole = topology
        .boundary_loops(&sphere)
        .into_iter()
        .max_by_key(Vec::len)
        .expect("the band's loop");
    (sphere, topology, hole)
}

fn bench_hole_patch(c: &mut Criterion) {
    let mut group = c.benchmark_group("hole_patch");
    group.sample_size(10);
    for (radius_mm, subdivisions) in [(100.0, 5), (120.0, 6)] {
        let (sphere, topology, hole) = banded_sphere(radius_mm, subdivisions);
        group.bench_function(format!("band with a {}-vertex rim", hole.len()), |b| {
            b.iter(|| patch_hole(black_box(&sphere), &topology, &hole).expect("patched"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_hole_patch);
criterion_main!(benches);
