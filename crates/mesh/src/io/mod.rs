//! Reading and writing surface meshes by file extension (`.ply`, `.obj`, `.stl`), and
//! atomic file writes shared by every output of the tool.

mod obj;
mod ply;
mod stl;

pub use obj::{read_obj, write_obj};
pub use ply::{PlyEncoding, read_ply, write_ply};
pub use stl::{read_stl, write_stl};

use crate::error::MeshError;
use crate::trimesh::TriMesh;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Reads a mesh, choosing the format by extension, and validates it
/// ([`TriMesh::validate`]): a file that parses but has NaN coordinates or out-of-range
/// indices is an error naming the file and the element.
pub fn read_mesh(path: &Path) -> Result<TriMesh, MeshError> {
    let mesh = match extension(path).as_deref() {
        Some("ply") => read_ply(path)?,
        Some("obj") => read_obj(path)?,
        Some("stl") => read_stl(path)?,
        _ => {
            return Err(MeshError::UnsupportedFormat {
                path: path.to_path_buf(),
            });
        }
    };
    mesh.validate().map_err(|e| e.in_file(path))?;
    Ok(mesh)
}

/// Writes a mesh, choosing the format by extension (PLY as binary little endian),
/// atomically: the file appears complete or not at all.
pub fn write_mesh(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    match extension(path).as_deref() {
        Some("ply") => write_ply(path, mesh, PlyEncoding::BinaryLittleEndian),
        Some("obj") => write_obj(path, mesh),
        Some("stl") => write_stl(path, mesh),
        _ => Err(MeshError::UnsupportedFormat {
            path: path.to_path_buf(),
        }),
    }
}

fn extension(path: &Path) -> Option<String> {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
}

/// Writes a file through `write` into a temporary sibling and renames it into place, so
/// a crash or an error never leaves a half-written file under `path`.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), MeshError> {
    let io_error = |source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    };
    let temporary = temporary_sibling(path);
    let result = (|| {
        let file = std::fs::File::create(&temporary)?;
        let mut writer = std::io::BufWriter::new(file);
        write(&mut writer)?;
        writer.flush()?;
        writer.get_ref().sync_all()?;
        std::fs::rename(&temporary, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result.map_err(io_error)
}

fn temporary_sibling(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.partial", std::process::id()))
}
