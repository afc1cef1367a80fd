//! What the mesh file tests share: files written into a folder, binary STL records.

use std::path::{Path, PathBuf};

pub fn write_file(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// A binary STL facet record with the given corners.
pub fn stl_facet(corners: [[f32; 3]; 3]) -> Vec<u8> {
    let mut record = Vec::new();
    for c in [[0.0; 3]].iter().chain(&corners).flatten() {
        record.extend(c.to_le_bytes());
    }
    record.extend([0, 0]);
    record
}
