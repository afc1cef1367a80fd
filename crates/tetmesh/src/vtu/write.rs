//! The writer: a mesh and its data arrays as a `.vtu` file with the arrays appended as
//! raw binary, zlib-compressed in VTK's blocks (what ParaView writes), written atomically.
//! Float64 values are stored exactly; a 327,000-element level takes a fraction of the
//! ASCII text's 40 MB.

use super::{Field, VTK_TETRA};
use crate::error::TetMeshError;
use crate::tetmesh::TetMesh;
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// Writes `mesh` with `point_data` (one entry per vertex) and `cell_data` (one per
/// tetrahedron) to `path`, atomically. Array sizes must match the mesh and values be
/// finite.
pub fn write_vtu(
    path: &Path,
    mesh: &TetMesh,
    point_data: &[Field],
    cell_data: &[Field],
) -> Result<(), TetMeshError> {
    for (location, fields, expected) in [
        ("point", point_data, mesh.vertex_count()),
        ("cell", cell_data, mesh.tet_count()),
    ] {
        for field in fields {
            if field.len() != expected {
                return Err(TetMeshError::DataSize {
                    location,
                    name: field.name.clone(),
                    found: field.len(),
                    expected,
                });
            }
            if let Some(index) = field.flat().position(|x| !x.is_finite()) {
                return Err(TetMeshError::NonFiniteValue {
                    name: field.name.clone(),
                    entry: index / field.components(),
                });
            }
        }
    }
    mesh.validate_indices()?;
    let bytes = vtu_bytes(mesh, point_data, cell_data);
    mesh::io::write_atomically(path, |w| w.write_all(&bytes)).map_err(|e| match e {
        mesh::MeshError::Io { path, source } => TetMeshError::Io { path, source },
        other => TetMeshError::Vtu {
            path: path.to_path_buf(),
            line: None,
            message: other.to_string(),
        },
    })
}

/// Bytes of one uncompressed block of VTK's zlib compressor.
const BLOCK_BYTES: usize = 1 << 15;

fn escape_attribute(name: &str) -> String {
    name.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// `data` as one appended block: the UInt64 header `[blocks, block size, last block
/// size, compressed size of each block]` (a last size of 0: a full block) and the
/// blocks, each a zlib stream.
fn compressed_block(data: &[u8]) -> Vec<u8> {
    let blocks: Vec<Vec<u8>> = data
        .chunks(BLOCK_BYTES)
        .map(|chunk| {
            let mut encoder =
                flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            // writing into a Vec cannot fail
            let _ = encoder.write_all(chunk);
            encoder.finish().unwrap_or_default()
        })
        .collect();
    let mut out = Vec::new();
    let words = [
        blocks.len() as u64,
        BLOCK_BYTES as u64,
        (data.len() % BLOCK_BYTES) as u64,
    ];
    for word in words
        .into_iter()
        .chain(blocks.iter().map(|b| b.len() as u64))
    {
        out.extend_from_slice(&word.to_le_bytes());
    }
    for block in &blocks {
        out.extend_from_slice(block);
    }
    out
}

/// The XML and the appended data being built: each array's element refers to its block
/// by offset.
#[derive(Default)]
struct Appended {
    xml: String,
    data: Vec<u8>,
}

impl Appended {
    fn array(&mut self, vtk_type: &str, name: Option<&str>, components: usize, bytes: &[u8]) {
        let name = name
            .map(|n| format!(" Name=\"{}\"", escape_attribute(n)))
            .unwrap_or_default();
        let _ = writeln!(
            self.xml,
            "        <DataArray type=\"{vtk_type}\"{name} NumberOfComponents=\"{components}\" format=\"appended\" offset=\"{}\"/>",
            self.data.len()
        );
        self.data.extend(compressed_block(bytes));
    }
}

fn f64_bytes(values: impl Iterator<Item = f64>) -> Vec<u8> {
    values.flat_map(f64::to_le_bytes).collect()
}

fn vtu_bytes(mesh: &TetMesh, point_data: &[Field], cell_data: &[Field]) -> Vec<u8> {
    let mut out = Appended::default();
    out.xml.push_str("<?xml version=\"1.0\"?>\n");
    out.xml.push_str(
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\">\n",
    );
    out.xml.push_str("  <UnstructuredGrid>\n");
    let _ = writeln!(
        out.xml,
        "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
        mesh.vertex_count(),
        mesh.tet_count()
    );
    for (tag, fields) in [("PointData", point_data), ("CellData", cell_data)] {
        let _ = writeln!(out.xml, "      <{tag}>");
        for field in fields {
            out.array(
                "Float64",
                Some(&field.name),
                field.components(),
                &f64_bytes(field.flat()),
            );
        }
        let _ = writeln!(out.xml, "      </{tag}>");
    }
    out.xml.push_str("      <Points>\n");
    let points = f64_bytes(mesh.positions.iter().flat_map(|p| p.to_array()));
    out.array("Float64", None, 3, &points);
    out.xml.push_str("      </Points>\n      <Cells>\n");
    let connectivity: Vec<u8> = (mesh.tets.iter().flatten())
        .flat_map(|&v| i64::from(v).to_le_bytes())
        .collect();
    out.array("Int64", Some("connectivity"), 1, &connectivity);
    let offsets: Vec<u8> = (1..=mesh.tet_count() as i64)
        .flat_map(|k| (4 * k).to_le_bytes())
        .collect();
    out.array("Int64", Some("offsets"), 1, &offsets);
    out.array(
        "UInt8",
        Some("types"),
        1,
        &vec![VTK_TETRA; mesh.tet_count()],
    );
    out.xml
        .push_str("      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n");
    out.xml.push_str("  <AppendedData encoding=\"raw\">\n   _");
    let mut bytes = out.xml.into_bytes();
    bytes.extend(out.data);
    bytes.extend_from_slice(b"\n  </AppendedData>\n</VTKFile>\n");
    bytes
}
