//! TEMPORARY STUB: being replaced by the real OBJ reader/writer.
use crate::{MeshError, TriMesh};
use std::path::Path;
pub fn read_obj(path: &Path) -> Result<TriMesh, MeshError> {
    Err(MeshError::UnsupportedFormat { path: path.into() })
}
pub fn write_obj(path: &Path, _m: &TriMesh) -> Result<(), MeshError> {
    Err(MeshError::UnsupportedFormat { path: path.into() })
}
