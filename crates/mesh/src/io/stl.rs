//! TEMPORARY STUB: being replaced by the real STL reader/writer.
use crate::{MeshError, TriMesh};
use std::path::Path;
pub fn read_stl(path: &Path) -> Result<TriMesh, MeshError> {
    Err(MeshError::UnsupportedFormat { path: path.into() })
}
pub fn write_stl(path: &Path, _m: &TriMesh) -> Result<(), MeshError> {
    Err(MeshError::UnsupportedFormat { path: path.into() })
}
