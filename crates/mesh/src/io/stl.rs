//! STL: ASCII and binary read, binary write.
//!
//! STL stores every triangle with its own three corners. The reader merges corners with
//! exactly equal coordinates (compared by bit pattern, with -0 taken as 0) so the mesh has
//! shared vertices and its topology works; facets whose corners merge into fewer than three
//! vertices have no area and are dropped. Stored normals are ignored (we recompute them).
//!
//! Reading is our own rather than `stl_io`'s, whose format detection trusts a leading
//! "solid" (which many binary exporters write into the header) and whose errors name no
//! line. Here a file is binary when its size is exactly 84 + 50·n bytes for the n
//! triangles its header announces, and ASCII when it is text starting with `solid`.
//! Writing uses `stl_io`.

use super::{ParseError, parse_number, read_file, write_atomically};
use crate::error::MeshError;
use crate::geometry::check_position;
use crate::trimesh::TriMesh;
use glam::DVec3;
use std::collections::HashMap;
use std::path::Path;

/// Size of the binary header and triangle count (bytes).
const BINARY_HEADER: usize = 84;
/// Size of one binary triangle record (bytes): normal, three corners, attribute.
const BINARY_TRIANGLE: usize = 50;

/// Reads an ASCII or binary STL file, merging equal corners into shared vertices.
pub fn read_stl(path: &Path) -> Result<TriMesh, MeshError> {
    let data = read_file(path)?;
    parse(&data).map_err(|e| e.in_file(path))
}

/// Writes a binary STL file atomically (coordinates as f32, facet normals computed).
/// Refuses a mesh that fails [`TriMesh::validate`].
pub fn write_stl(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    mesh.validate()?;
    let facets = (0..mesh.triangle_count()).map(|t| stl_io::Triangle {
        normal: stl_io::Normal::new(mesh.triangle_normal(t).as_vec3().to_array()),
        vertices: mesh
            .triangle_positions(t)
            .map(|p| stl_io::Vertex::new(p.as_vec3().to_array())),
    });
    write_atomically(path, |out| stl_io::write_stl(out, facets))
}

fn parse(data: &[u8]) -> Result<TriMesh, ParseError> {
    let mut mesh = Welder::default();
    if let Some(count) = binary_triangle_count(data) {
        read_binary(&data[BINARY_HEADER..], count, &mut mesh)?;
    } else if let Some(text) = std::str::from_utf8(data)
        .ok()
        .filter(|text| text.trim_start().starts_with("solid") && !text.contains('\0'))
    {
        read_ascii(text, &mut mesh)?;
    } else if let Some(count) = data.get(80..BINARY_HEADER).and_then(<[u8]>::first_chunk) {
        let count = u32::from_le_bytes(*count);
        return Err(ParseError::new(format!(
            "not an ASCII STL, and as binary STL its header announces {count} triangles \
             ({} bytes) but the file has {} bytes (truncated?)",
            BINARY_HEADER as u64 + BINARY_TRIANGLE as u64 * u64::from(count),
            data.len()
        )));
    } else {
        return Err(ParseError::new(format!(
            "not an STL file: {} bytes, neither ASCII ('solid …') nor a binary header",
            data.len()
        )));
    }
    Ok(TriMesh::new(mesh.positions, mesh.triangles))
}

/// The triangle count of a binary STL, if the file size matches it exactly.
fn binary_triangle_count(data: &[u8]) -> Option<usize> {
    let count = u32::from_le_bytes(*data.get(80..BINARY_HEADER)?.first_chunk()?) as usize;
    let size = count
        .checked_mul(BINARY_TRIANGLE)?
        .checked_add(BINARY_HEADER)?;
    (size == data.len()).then_some(count)
}

fn read_binary(records: &[u8], count: usize, mesh: &mut Welder) -> Result<(), ParseError> {
    mesh.reserve(count);
    for (facet, record) in records.chunks_exact(BINARY_TRIANGLE).enumerate() {
        let (floats, _) = record.as_chunks::<4>();
        let c = |i: usize| f64::from(f32::from_le_bytes(floats[i]));
        let corners = [3, 6, 9].map(|i| DVec3::new(c(i), c(i + 1), c(i + 2)));
        mesh.facet(corners, facet).map_err(ParseError::new)?;
    }
    Ok(())
}

/// Reads `solid … facet normal … outer loop, vertex ×3, endloop, endfacet … endsolid`,
/// line by line; several solids in one file are joined.
fn read_ascii(text: &str, mesh: &mut Welder) -> Result<(), ParseError> {
    let mut corners = [DVec3::ZERO; 3];
    let mut corner_count = 0;
    let mut facet = 0;
    let mut in_solid = false;
    let mut line = 0;
    for (index, content) in text.lines().enumerate() {
        line = index + 1;
        let error = |message: String| ParseError::at(line, message);
        let mut words = content.split_ascii_whitespace();
        match words.next() {
            None | Some("facet" | "outer" | "endfacet") => {}
            Some("solid") => in_solid = true,
            Some("endsolid") => in_solid = false,
            Some("vertex") => {
                let slot = corners
                    .get_mut(corner_count)
                    .ok_or_else(|| error(format!("facet {facet} has more than 3 vertices")))?;
                let mut xyz = [0.0; 3];
                let mut found = 0;
                for word in words {
                    let value = xyz
                        .get_mut(found)
                        .ok_or_else(|| error("a vertex needs exactly 3 coordinates".to_owned()))?;
                    *value = parse_number(word).map_err(error)?;
                    found += 1;
                }
                if found != 3 {
                    return Err(error("a vertex needs exactly 3 coordinates".to_owned()));
                }
                *slot = DVec3::from_array(xyz);
                corner_count += 1;
            }
            Some("endloop") => {
                if corner_count != 3 {
                    return Err(error(format!(
                        "facet {facet} has {corner_count} vertices (expected 3)"
                    )));
                }
                mesh.facet(corners, facet).map_err(error)?;
                facet += 1;
                corner_count = 0;
            }
            Some(other) => {
                return Err(error(format!(
                    "unexpected '{other}' (expected solid, facet, outer loop, vertex, endloop, \
                     endfacet or endsolid)"
                )));
            }
        }
    }
    if in_solid || corner_count != 0 {
        return Err(ParseError::at(
            line,
            format!("file ends after {facet} facets without 'endsolid' (truncated?)"),
        ));
    }
    Ok(())
}

/// Builds a mesh with shared vertices from facets with separate corners.
#[derive(Default)]
struct Welder {
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    /// Vertex index by coordinate bit patterns.
    index: HashMap<[u64; 3], u32>,
}

impl Welder {
    fn reserve(&mut self, facets: usize) {
        // A closed triangle mesh has about half as many vertices as triangles.
        self.positions.reserve(facets / 2);
        self.index.reserve(facets / 2);
        self.triangles.reserve(facets);
    }

    fn facet(&mut self, corners: [DVec3; 3], facet: usize) -> Result<(), String> {
        for &p in &corners {
            check_position(p).map_err(|what| format!("facet {facet}: {what}"))?;
        }
        let [a, b, c] = corners.map(|p| self.vertex(p));
        if a != b && b != c && a != c {
            self.triangles.push([a, b, c]);
        }
        Ok(())
    }

    fn vertex(&mut self, p: DVec3) -> u32 {
        // Adding 0 turns -0 into 0, so both merge.
        let key = p.to_array().map(|c| (c + 0.0).to_bits());
        *self.index.entry(key).or_insert_with(|| {
            self.positions.push(p + DVec3::ZERO);
            self.positions.len() as u32 - 1
        })
    }
}
