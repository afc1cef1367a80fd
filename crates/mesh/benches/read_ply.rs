//! Reading a 150,000-vertex binary PLY (the size of a torso scan); target well under
//! 100 ms.

use criterion::{Criterion, criterion_group, criterion_main};
use mesh::io::{PlyEncoding, read_ply, write_ply};
use std::hint::black_box;

fn bench_read_ply(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("grid.ply");
    // 387 × 387 = 149,769 vertices, 297,992 triangles.
    let mesh = mesh::shapes::grid(386, 386, 0.7);
    write_ply(&path, &mesh, PlyEncoding::BinaryLittleEndian).expect("write the PLY");
    c.bench_function("read_ply binary 150k vertices", |b| {
        b.iter(|| read_ply(black_box(&path)).expect("read the PLY"))
    });
}

criterion_group!(benches, bench_read_ply);
criterion_main!(benches);
