//! Reading and writing surface meshes by file extension (`.ply`, `.obj`, `.stl`), and
//! atomic file writes shared by every output of the tool.

mod obj;
mod ply;
mod stl;
mod texture;

pub use obj::{read_obj, write_obj};
pub use ply::{
    PlyEncoding, VertexScalar, read_ply, read_ply_with_scalars, write_ply, write_ply_with_scalars,
};
pub use stl::{read_stl, write_stl};
pub use texture::{diffuse_maps, texture_image_path};

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

/// Reads the whole file into memory (every reader parses from a byte slice).
/// The largest mesh file read (GiB): a 150,000-vertex textured scan takes some 100 MB.
const MAX_FILE_GIB: u64 = 1;

/// The file's bytes, at most [`MAX_FILE_GIB`] of them (a device such as `/dev/zero`
/// would otherwise be read until memory runs out).
fn read_file(path: &Path) -> Result<Vec<u8>, MeshError> {
    read_at_most(path, MAX_FILE_GIB << 30).map_err(|error| match error {
        MeshError::TooLarge { path, .. } => MeshError::TooLarge {
            path,
            limit_gib: MAX_FILE_GIB,
        },
        other => other,
    })
}

/// The file's bytes if there are at most `limit` of them, else [`MeshError::TooLarge`]
/// (its `limit_gib` left for the caller to fill in).
fn read_at_most(path: &Path, limit: u64) -> Result<Vec<u8>, MeshError> {
    use std::io::Read;
    let io = |source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    };
    let too_large = || MeshError::TooLarge {
        path: path.to_path_buf(),
        limit_gib: 0,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    // A regular file's size is known without reading it; a device or pipe is read up to
    // the limit.
    let metadata = file.metadata().map_err(io)?;
    if metadata.is_file() && metadata.len() > limit {
        return Err(too_large());
    }
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(too_large());
    }
    Ok(bytes)
}

/// A format error found by a reader, before the file path is attached.
#[derive(Debug)]
struct ParseError {
    /// 1-based line number for text formats.
    line: Option<usize>,
    message: String,
}

impl ParseError {
    /// An error not tied to a line (binary data, whole-file checks).
    fn new(message: impl Into<String>) -> ParseError {
        ParseError {
            line: None,
            message: message.into(),
        }
    }

    /// An error on 1-based line `line`.
    fn at(line: usize, message: impl Into<String>) -> ParseError {
        ParseError {
            line: Some(line),
            message: message.into(),
        }
    }

    fn in_file(self, path: &Path) -> MeshError {
        MeshError::Parse {
            path: path.to_path_buf(),
            line: self.line,
            message: self.message,
        }
    }
}

/// Parses a decimal number of a text format, naming the offending word on failure.
fn parse_number(word: &str) -> Result<f64, String> {
    word.parse()
        .map_err(|_| format!("'{word}' is not a number"))
}

/// Corner triples of the fan triangulation of a polygon with `corners` corners:
/// `[0, 1, 2], [0, 2, 3], …` (none for fewer than three).
fn fan(corners: usize) -> impl Iterator<Item = [usize; 3]> {
    (2..corners).map(|k| [0, k - 1, k])
}

/// A temporary name beside `path`, unique per process and per call: two threads (or
/// two calls under way) writing the same path never share one.
fn temporary_sibling(path: &Path) -> PathBuf {
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}-{call}.partial", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Threads writing one path at once each write whole files through names of their
    /// own: the path ends up holding one writer's complete content, never a mixture.
    #[test]
    fn threads_writing_one_path_do_not_share_a_temporary_file() {
        let directory = tempfile::tempdir().unwrap();
        let path = directory.path().join("shared.txt");
        let contents: Vec<String> = (0..8).map(|k| format!("{k}").repeat(100_000)).collect();
        std::thread::scope(|scope| {
            for content in &contents {
                let path = &path;
                scope.spawn(move || {
                    for _ in 0..5 {
                        write_atomically(path, |out| out.write_all(content.as_bytes())).unwrap();
                    }
                });
            }
        });
        let written = std::fs::read_to_string(&path).unwrap();
        assert!(
            contents.contains(&written),
            "a mixture of {} bytes",
            written.len()
        );
        let leftovers = std::fs::read_dir(directory.path()).unwrap().count();
        assert_eq!(leftovers, 1, "temporary files left behind");
    }

    /// A file one byte over the limit is refused, one at the limit read whole.
    #[test]
    fn a_file_over_the_limit_is_refused() {
        let directory = tempfile::tempdir().unwrap();
        let path = directory.path().join("scan.ply");
        std::fs::write(&path, [7u8; 100]).unwrap();
        assert_eq!(read_at_most(&path, 100).unwrap().len(), 100);
        assert!(matches!(
            read_at_most(&path, 99),
            Err(MeshError::TooLarge { .. })
        ));
    }
}
