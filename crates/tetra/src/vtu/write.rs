//! The writer: a mesh and its data arrays as ASCII `.vtu` text, written atomically.

use super::{Field, VTK_TETRA};
use crate::error::TetraError;
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
) -> Result<(), TetraError> {
    for (location, fields, expected) in [
        ("point", point_data, mesh.vertex_count()),
        ("cell", cell_data, mesh.tet_count()),
    ] {
        for field in fields {
            if field.len() != expected {
                return Err(TetraError::DataSize {
                    location,
                    name: field.name.clone(),
                    found: field.len(),
                    expected,
                });
            }
            if let Some(index) = field.flat().position(|x| !x.is_finite()) {
                return Err(TetraError::NonFiniteValue {
                    name: field.name.clone(),
                    entry: index / field.components(),
                });
            }
        }
    }
    mesh.validate_indices()?;
    let text = vtu_text(mesh, point_data, cell_data);
    mesh::io::write_atomically(path, |w| w.write_all(text.as_bytes())).map_err(|e| match e {
        mesh::MeshError::Io { path, source } => TetraError::Io { path, source },
        other => TetraError::Vtu {
            path: path.to_path_buf(),
            line: None,
            message: other.to_string(),
        },
    })
}

/// A number in shortest round-trip form, in exponent notation when plain digits would be
/// long.
fn number(out: &mut String, x: f64) {
    let plain = x == 0.0 || (1e-4..1e15).contains(&x.abs());
    let _ = if plain {
        write!(out, "{x}")
    } else {
        write!(out, "{x:e}")
    };
}

fn escape_attribute(name: &str) -> String {
    name.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

fn data_array(
    out: &mut String,
    vtk_type: &str,
    name: Option<&str>,
    components: usize,
    values: impl Iterator<Item = String>,
    per_line: usize,
) {
    let name = name
        .map(|n| format!(" Name=\"{}\"", escape_attribute(n)))
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "        <DataArray type=\"{vtk_type}\"{name} NumberOfComponents=\"{components}\" format=\"ascii\">"
    );
    for (k, value) in values.enumerate() {
        out.push_str(if k % per_line == 0 { "          " } else { " " });
        out.push_str(&value);
        if k % per_line == per_line - 1 {
            out.push('\n');
        }
    }
    if !out.ends_with('\n') {
        out.push('\n');
    }
    out.push_str("        </DataArray>\n");
}

fn float_strings(values: impl Iterator<Item = f64>) -> impl Iterator<Item = String> {
    values.map(|x| {
        let mut s = String::new();
        number(&mut s, x);
        s
    })
}

fn vtu_text(mesh: &TetMesh, point_data: &[Field], cell_data: &[Field]) -> String {
    let mut out = String::new();
    out.push_str("<?xml version=\"1.0\"?>\n");
    out.push_str(
        "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n",
    );
    out.push_str("  <UnstructuredGrid>\n");
    let _ = writeln!(
        out,
        "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
        mesh.vertex_count(),
        mesh.tet_count()
    );
    for (tag, fields) in [("PointData", point_data), ("CellData", cell_data)] {
        let _ = writeln!(out, "      <{tag}>");
        for field in fields {
            let components = field.components();
            data_array(
                &mut out,
                "Float64",
                Some(&field.name),
                components,
                float_strings(field.flat()),
                if components == 3 { 3 } else { 6 },
            );
        }
        let _ = writeln!(out, "      </{tag}>");
    }
    out.push_str("      <Points>\n");
    data_array(
        &mut out,
        "Float64",
        None,
        3,
        float_strings(mesh.positions.iter().flat_map(|p| p.to_array())),
        3,
    );
    out.push_str("      </Points>\n      <Cells>\n");
    data_array(
        &mut out,
        "Int64",
        Some("connectivity"),
        1,
        mesh.tets.iter().flatten().map(|v| v.to_string()),
        4,
    );
    data_array(
        &mut out,
        "Int64",
        Some("offsets"),
        1,
        (1..=mesh.tet_count()).map(|k| (4 * k).to_string()),
        12,
    );
    data_array(
        &mut out,
        "UInt8",
        Some("types"),
        1,
        std::iter::repeat_n(VTK_TETRA.to_string(), mesh.tet_count()),
        24,
    );
    out.push_str("      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n");
    out
}
