//! TEMPORARY STUB: being replaced by the real PLY reader/writer.
use crate::{MeshError, TriMesh};
use std::path::Path;
#[derive(Debug, Clone, Copy)]
pub enum PlyEncoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}
pub fn read_ply(path: &Path) -> Result<TriMesh, MeshError> {
    Err(MeshError::UnsupportedFormat { path: path.into() })
}
pub fn write_ply(path: &Path, _m: &TriMesh, _e: PlyEncoding) -> Result<(), MeshError> {
    Err(MeshError::UnsupportedFormat { path: path.into() })
}
