//! The reader: the file split into its XML and its appended data, and the parsed arrays
//! assembled into the mesh and its data arrays.

use super::parser::{ParseResult, RawArray, Section, parse_vtu};
use super::{Field, FieldValues, VTK_TETRA, VtuData};
use crate::error::TetMeshError;
use crate::tetmesh::TetMesh;
use glam::DVec3;
use std::borrow::Cow;
use std::path::Path;

/// Reads a `.vtu` file of tetrahedra with its data arrays. Errors name the file, the
/// line and what was expected. Tetrahedra keep the orientation they have in the file
/// (see [`TetMesh::validate`]).
pub fn read_vtu(path: &Path) -> Result<VtuData, TetMeshError> {
    let bytes = std::fs::read(path).map_err(|source| TetMeshError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let error = |line: Option<usize>, message: String| TetMeshError::Vtu {
        path: path.to_path_buf(),
        line,
        message,
    };
    let (xml, appended) = split_appended(&bytes).map_err(|(line, message)| error(line, message))?;
    let text =
        std::str::from_utf8(&xml).map_err(|e| error(None, format!("not UTF-8 text: {e}")))?;
    parse_vtu(text, appended).map_err(|(line, message)| error(line, message))
}

/// First position of `needle` (not empty) in `haystack`.
fn find_bytes(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    let mut from = 0;
    while let Some(k) = haystack[from..].iter().position(|&b| b == needle[0]) {
        let at = from + k;
        if haystack[at..].starts_with(needle) {
            return Some(at);
        }
        from = at + 1;
    }
    None
}

/// The XML part of a file and its appended data, if any.
type XmlAndAppended<'a> = (Cow<'a, [u8]>, Option<&'a [u8]>);

/// Splits a file with `<AppendedData>` into its XML part and the appended bytes (after
/// the `_` marker, up to the last `</AppendedData>` or the end of the file). Raw
/// appended data is not text, so the XML parser sees only the part before it, closed by
/// `</AppendedData></VTKFile>`; line numbers stay those of the file.
fn split_appended(bytes: &[u8]) -> ParseResult<XmlAndAppended<'_>> {
    const OPEN: &[u8] = b"<AppendedData";
    const CLOSE: &[u8] = b"</AppendedData>";
    let unsplit = Ok((Cow::Borrowed(bytes), None));
    let Some(tag) = find_bytes(bytes, OPEN) else {
        return unsplit;
    };
    let Some(end) = bytes[tag..]
        .iter()
        .position(|&b| b == b'>')
        .map(|k| tag + k)
    else {
        return unsplit; // the XML parser reports the broken tag
    };
    if bytes[end - 1] == b'/' {
        return unsplit; // <AppendedData/>: no data
    }
    let rest = &bytes[end + 1..];
    let marker = rest.iter().position(|b| !b.is_ascii_whitespace());
    let Some(marker) = marker.filter(|&k| rest[k] == b'_') else {
        let line = bytes[..end].iter().filter(|&&b| b == b'\n').count() + 1;
        return Err((
            Some(line),
            "<AppendedData> must begin with '_' before its data".into(),
        ));
    };
    let data = &rest[marker + 1..];
    let data_end = data
        .windows(CLOSE.len())
        .rposition(|w| w == CLOSE)
        .unwrap_or(data.len());
    let mut xml = bytes[..=end].to_vec();
    xml.extend_from_slice(b"</AppendedData></VTKFile>");
    Ok((Cow::Owned(xml), Some(&data[..data_end])))
}

/// Builds the mesh and data from the parsed arrays, checking sizes and cell types.
pub(super) fn assemble(
    point_count: usize,
    cell_count: usize,
    arrays: Vec<(Section, RawArray)>,
) -> ParseResult<VtuData> {
    let find = |section: Section, name: Option<&str>| {
        arrays
            .iter()
            .find(|(s, a)| *s == section && name.is_none_or(|n| a.name == n))
            .map(|(_, a)| a)
    };
    let require = |section: Section, name: Option<&str>, what: &str| {
        find(section, name).ok_or((None, format!("no {what} array")))
    };
    let expect_len = |array: &RawArray, expected: usize, what: &str| {
        if array.values.len() == expected {
            Ok(())
        } else {
            Err((
                Some(array.line),
                format!(
                    "{what} has {} values, expected {expected}",
                    array.values.len()
                ),
            ))
        }
    };
    let points = require(Section::Points, None, "<Points> DataArray")?;
    if points.components != 3 {
        return Err((Some(points.line), "<Points> must have 3 components".into()));
    }
    expect_len(points, 3 * point_count, "<Points>")?;
    let positions: Vec<DVec3> = points
        .values
        .chunks_exact(3)
        .map(DVec3::from_slice)
        .collect();
    let indices = |array: &RawArray, what: &str| -> ParseResult<Vec<u64>> {
        array
            .values
            .iter()
            .enumerate()
            .map(|(k, &x)| {
                if x >= 0.0 && x.fract() == 0.0 && x < u32::MAX as f64 {
                    Ok(x as u64)
                } else {
                    Err((
                        Some(array.line),
                        format!("{what} entry {k} is {x}, expected a non-negative integer"),
                    ))
                }
            })
            .collect()
    };
    let connectivity_array = require(Section::Cells, Some("connectivity"), "<Cells> connectivity")?;
    let offsets_array = require(Section::Cells, Some("offsets"), "<Cells> offsets")?;
    let types_array = require(Section::Cells, Some("types"), "<Cells> types")?;
    expect_len(offsets_array, cell_count, "<Cells> offsets")?;
    expect_len(types_array, cell_count, "<Cells> types")?;
    let connectivity = indices(connectivity_array, "connectivity")?;
    let offsets = indices(offsets_array, "offsets")?;
    let types = indices(types_array, "types")?;
    if let Some(cell) = types.iter().position(|&t| t != VTK_TETRA as u64) {
        return Err((
            Some(types_array.line),
            format!(
                "cell {cell} has VTK type {}: only tetrahedra (type {VTK_TETRA}) are supported",
                types[cell]
            ),
        ));
    }
    let mut tets = Vec::with_capacity(cell_count);
    let mut start = 0u64;
    for (cell, &end) in offsets.iter().enumerate() {
        if end != start + 4 || end as usize > connectivity.len() {
            return Err((
                Some(offsets_array.line),
                format!(
                    "cell {cell}: offsets {start}..{end} do not give 4 vertices within the connectivity"
                ),
            ));
        }
        let tet: [u64; 4] = connectivity[start as usize..end as usize]
            .try_into()
            .map_err(|_| {
                (
                    Some(offsets_array.line),
                    format!("cell {cell} is not a tetrahedron"),
                )
            })?;
        if let Some(&v) = tet.iter().find(|&&v| v as usize >= point_count) {
            return Err((
                Some(connectivity_array.line),
                format!("cell {cell} refers to point {v}, but there are {point_count} points"),
            ));
        }
        tets.push(tet.map(|v| v as u32));
        start = end;
    }
    let fields = |section: Section, expected: usize, what: &str| -> ParseResult<Vec<Field>> {
        arrays
            .iter()
            .filter(|(s, _)| *s == section)
            .map(|(_, array)| {
                expect_len(
                    array,
                    expected * array.components,
                    &format!("{what} \"{}\"", array.name),
                )?;
                let values = match array.components {
                    1 => FieldValues::Scalars(array.values.clone()),
                    3 => FieldValues::Vectors(
                        array
                            .values
                            .chunks_exact(3)
                            .map(DVec3::from_slice)
                            .collect(),
                    ),
                    n => {
                        return Err((
                            Some(array.line),
                            format!(
                                "{what} \"{}\" has {n} components: only 1 or 3 are supported",
                                array.name
                            ),
                        ));
                    }
                };
                Ok(Field {
                    name: array.name.clone(),
                    values,
                })
            })
            .collect()
    };
    Ok(VtuData {
        point_data: fields(Section::PointData, point_count, "point data")?,
        cell_data: fields(Section::CellData, cell_count, "cell data")?,
        mesh: TetMesh { positions, tets },
    })
}
