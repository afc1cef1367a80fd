//! PLY (Stanford polygon file): ASCII and binary (little and big endian), read and write.
//!
//! The parser is our own rather than `ply-rs-bw`, for two reasons. Speed: that crate parses
//! every element into a hash map of properties, which is far too slow for the target of
//! reading a 150,000-vertex binary scan well under 100 ms; here the whole file is read into
//! memory, binary elements whose properties are all scalars are decoded at fixed offsets
//! after one length check, and nothing is allocated per vertex or face. Errors name the
//! header line, the ASCII body line, or the element and record ("file ends after 1234 of
//! 5000 vertices (truncated?)", "face 17 refers to vertex 9000 but the file has only 5000
//! vertices").
//!
//! Read: positions `x`/`y`/`z` of any scalar type; faces from the `vertex_indices` (or
//! `vertex_index`) list of any count and index type, polygons fan-triangulated; per-vertex
//! colour `red`/`green`/`blue` (integer types taken as 0–255, float types as 0–1); per-vertex
//! texture coordinates `s`/`t`, `u`/`v` or `texture_u`/`texture_v`; on request
//! ([`read_ply_with_scalars`]) named scalar vertex properties (e.g. a deviation map's
//! `distance_mm`). Every other property and element (including list properties, e.g.
//! per-face `texcoord`) is skipped.

use super::{ParseError, fan, parse_number, read_file, write_atomically};
use crate::error::MeshError;
use crate::geometry::check_position;
use crate::trimesh::{TriMesh, UvLayer};
use glam::{DVec2, DVec3};
use std::fmt::Display;
use std::io::Write;
use std::path::Path;

/// How the body of a PLY file is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyEncoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// Reads a PLY file (any encoding). Texture coordinates come back as a [`UvLayer`] whose
/// triangles equal the mesh triangles. Coordinates are checked to be finite; the rest of
/// [`TriMesh::validate`] is left to the caller (`read_mesh` runs it).
pub fn read_ply(path: &Path) -> Result<TriMesh, MeshError> {
    read_ply_with_scalars(path, &[]).map(|(mesh, _)| mesh)
}

/// Reads a PLY file as [`read_ply`] does, and the scalar vertex properties `names` (as
/// f64, one value per vertex, in the order of `names`). A missing property is an error
/// naming it.
pub fn read_ply_with_scalars(
    path: &Path,
    names: &[&str],
) -> Result<(TriMesh, Vec<Vec<f64>>), MeshError> {
    let data = read_file(path)?;
    parse(&data, names).map_err(|e| e.in_file(path))
}

/// A named scalar per vertex, written as an extra `double` vertex property (e.g. a
/// distance map for ParaView or MeshLab).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexScalar<'a> {
    /// The property name: letters, digits and `_`, not one of the standard properties.
    pub name: &'a str,
    /// One value per vertex.
    pub values: &'a [f64],
}

/// Vertex property names [`write_ply`] uses itself.
const STANDARD_VERTEX_PROPERTIES: [&str; 8] = ["x", "y", "z", "red", "green", "blue", "s", "t"];

/// Writes a PLY file atomically: positions as `double` (scans are stored without losing
/// precision), colours as `uchar` `red`/`green`/`blue` if present, texture coordinates as
/// `double` `s`/`t` if every vertex has a single one (a layer with seams cannot be stored
/// per vertex and is dropped; use OBJ to keep it), faces as `list uchar int
/// vertex_indices`. Materials are not stored. Refuses a mesh that fails
/// [`TriMesh::validate`].
pub fn write_ply(path: &Path, mesh: &TriMesh, encoding: PlyEncoding) -> Result<(), MeshError> {
    write_ply_with_scalars(path, mesh, encoding, &[])
}

/// Writes a PLY file as [`write_ply`] does, with extra scalar vertex properties after the
/// standard ones (`property double <name>`). Refuses a name that is empty, not made of
/// letters, digits and `_`, standard or repeated, and a scalar without one value per
/// vertex.
pub fn write_ply_with_scalars(
    path: &Path,
    mesh: &TriMesh,
    encoding: PlyEncoding,
    scalars: &[VertexScalar<'_>],
) -> Result<(), MeshError> {
    mesh.validate()?;
    check_scalars(mesh, scalars)?;
    let uv = per_vertex_uv(mesh);
    write_atomically(path, |out| {
        write_header(out, mesh, encoding, uv.is_some(), scalars)?;
        let mut record = RecordWriter {
            out,
            encoding,
            first: true,
        };
        for (vertex, p) in mesh.positions.iter().enumerate() {
            for c in p.to_array() {
                record.value(c)?;
            }
            if let Some(colors) = &mesh.vertex_colors {
                for channel in colors[vertex] {
                    record.value(channel)?;
                }
            }
            if let Some(uv) = &uv {
                record.value(uv[vertex].x)?;
                record.value(uv[vertex].y)?;
            }
            for scalar in scalars {
                record.value(scalar.values[vertex])?;
            }
            record.end()?;
        }
        for triangle in &mesh.triangles {
            record.value(3u8)?;
            for &index in triangle {
                let index = i32::try_from(index)
                    .map_err(|_| std::io::Error::other("vertex index too large for PLY int"))?;
                record.value(index)?;
            }
            record.end()?;
        }
        Ok(())
    })
}

// ---------------------------------------------------------------------------------------
// Header

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    /// The type of a header type name, including the sized aliases (`uint8`, `float32`…).
    fn from_name(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Size in a binary body (bytes).
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decodes a value from the start of `bytes`; `None` if `bytes` is too short.
    #[inline]
    fn decode(self, bytes: &[u8], big_endian: bool) -> Option<f64> {
        macro_rules! decode {
            ($t:ty) => {{
                let raw = *bytes.first_chunk::<{ size_of::<$t>() }>()?;
                let value = if big_endian {
                    <$t>::from_be_bytes(raw)
                } else {
                    <$t>::from_le_bytes(raw)
                };
                f64::from(value)
            }};
        }
        Some(match self {
            Scalar::I8 => decode!(i8),
            Scalar::U8 => decode!(u8),
            Scalar::I16 => decode!(i16),
            Scalar::U16 => decode!(u16),
            Scalar::I32 => decode!(i32),
            Scalar::U32 => decode!(u32),
            Scalar::F32 => decode!(f32),
            Scalar::F64 => decode!(f64),
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

impl Element {
    /// The property types if all are scalars (records of fixed size).
    fn scalar_types(&self) -> Option<Vec<Scalar>> {
        self.properties
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(ty) => Some(ty),
                Kind::List { .. } => None,
            })
            .collect()
    }

    fn scalar(&self, name: &str) -> Option<(usize, Scalar)> {
        self.properties
            .iter()
            .enumerate()
            .find_map(|(index, p)| match p.kind {
                Kind::Scalar(ty) if p.name == name => Some((index, ty)),
                _ => None,
            })
    }

    /// "1234 of 5000 vertices" style wording for truncation errors.
    fn truncated(&self, complete: usize) -> String {
        let records = match self.name.as_str() {
            "vertex" => "vertices".to_owned(),
            "face" => "faces".to_owned(),
            other => format!("'{other}' elements"),
        };
        format!(
            "file ends after {complete} of {} {records} (truncated?)",
            self.count
        )
    }
}

#[derive(Debug)]
struct Header {
    encoding: PlyEncoding,
    elements: Vec<Element>,
    /// Byte offset of the body.
    body_start: usize,
    /// Number of header lines (the body starts on the next line).
    lines: usize,
}

fn parse_header(data: &[u8]) -> Result<Header, ParseError> {
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = 0;
    let mut line = 0;
    loop {
        let Some(length) = data[pos..].iter().position(|&b| b == b'\n') else {
            return Err(ParseError::new(if line == 0 {
                "not a PLY file (no header)".to_owned()
            } else {
                format!("the header ends after {line} lines without 'end_header' (truncated?)")
            }));
        };
        let raw = &data[pos..pos + length];
        pos += length + 1;
        line += 1;
        let text = std::str::from_utf8(raw)
            .map_err(|_| ParseError::at(line, "the header contains bytes that are not text"))?
            .trim();
        if line == 1 {
            if text != "ply" {
                return Err(ParseError::at(
                    1,
                    "not a PLY file (the first line is not 'ply')",
                ));
            }
            continue;
        }
        let mut words = text.split_ascii_whitespace();
        let error = |message: String| ParseError::at(line, message);
        match words.next() {
            None | Some("comment" | "obj_info") => {}
            Some("format") => {
                encoding = Some(match words.next() {
                    Some("ascii") => PlyEncoding::Ascii,
                    Some("binary_little_endian") => PlyEncoding::BinaryLittleEndian,
                    Some("binary_big_endian") => PlyEncoding::BinaryBigEndian,
                    other => {
                        return Err(error(format!(
                            "unknown format '{}' (expected ascii, binary_little_endian or \
                             binary_big_endian)",
                            other.unwrap_or_default()
                        )));
                    }
                });
            }
            Some("element") => {
                let (Some(name), Some(count)) = (words.next(), words.next()) else {
                    return Err(error("expected 'element <name> <count>'".to_owned()));
                };
                let count = count
                    .parse()
                    .map_err(|_| error(format!("element count '{count}' is not a count")))?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(error(format!("element '{name}' is declared twice")));
                }
                elements.push(Element {
                    name: name.to_owned(),
                    count,
                    properties: Vec::new(),
                });
            }
            Some("property") => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| error("property before any element".to_owned()))?;
                let words: Vec<&str> = words.collect();
                let scalar = |name: &str| {
                    Scalar::from_name(name)
                        .ok_or_else(|| error(format!("unknown property type '{name}'")))
                };
                let (kind, name) = match words.as_slice() {
                    ["list", count, item, name] => (
                        Kind::List {
                            count: scalar(count)?,
                            item: scalar(item)?,
                        },
                        name,
                    ),
                    [ty, name] if *ty != "list" => (Kind::Scalar(scalar(ty)?), name),
                    _ => {
                        return Err(error(
                            "expected 'property <type> <name>' or 'property list <count type> \
                             <item type> <name>'"
                                .to_owned(),
                        ));
                    }
                };
                element.properties.push(Property {
                    name: (*name).to_owned(),
                    kind,
                });
            }
            Some("end_header") => break,
            Some(other) => return Err(error(format!("unknown header keyword '{other}'"))),
        }
    }
    let encoding = encoding.ok_or_else(|| ParseError::new("the header has no 'format' line"))?;
    Ok(Header {
        encoding,
        elements,
        body_start: pos,
        lines: line,
    })
}

// ---------------------------------------------------------------------------------------
// Body

/// What the reader keeps of an element.
enum Role {
    Vertices(VertexLayout),
    /// Faces, with the index of their vertex index list property.
    Faces(usize),
    Skip,
}

/// Where the vertex attributes we keep sit among the vertex properties.
struct VertexLayout {
    xyz: [usize; 3],
    /// `red`/`green`/`blue` and whether they are floats (0–1) rather than integers (0–255).
    color: Option<([usize; 3], bool)>,
    uv: Option<[usize; 2]>,
    /// The scalar properties asked for by name, in the order asked.
    scalars: Vec<usize>,
}

impl VertexLayout {
    fn new(element: &Element, scalar_names: &[&str]) -> Result<VertexLayout, ParseError> {
        let mut xyz = [0; 3];
        for (slot, name) in xyz.iter_mut().zip(["x", "y", "z"]) {
            *slot = element
                .scalar(name)
                .map(|(index, _)| index)
                .ok_or_else(|| {
                    ParseError::new(format!(
                        "the vertex element has no scalar property '{name}'"
                    ))
                })?;
        }
        let color = match ["red", "green", "blue"].map(|name| element.scalar(name)) {
            [Some((r, ty)), Some((g, _)), Some((b, _))] => Some(([r, g, b], ty.is_float())),
            _ => None,
        };
        let uv = [("s", "t"), ("u", "v"), ("texture_u", "texture_v")]
            .into_iter()
            .find_map(|(u, v)| Some([element.scalar(u)?.0, element.scalar(v)?.0]));
        let scalars = scalar_names
            .iter()
            .map(|&name| {
                element.scalar(name).map(|(index, _)| index).ok_or_else(|| {
                    ParseError::new(format!(
                        "the vertex element has no scalar property '{name}'"
                    ))
                })
            })
            .collect::<Result<_, _>>()?;
        Ok(VertexLayout {
            xyz,
            color,
            uv,
            scalars,
        })
    }

    /// Indices of the properties we read.
    fn properties(&self) -> impl Iterator<Item = usize> + '_ {
        let color = self.color.iter().flat_map(|(channels, _)| *channels);
        self.xyz
            .into_iter()
            .chain(color)
            .chain(self.uv.into_iter().flatten())
            .chain(self.scalars.iter().copied())
    }
}

fn roles(header: &Header, scalar_names: &[&str]) -> Result<Vec<Role>, ParseError> {
    header
        .elements
        .iter()
        .map(|element| match element.name.as_str() {
            "vertex" => VertexLayout::new(element, scalar_names).map(Role::Vertices),
            "face" => element
                .properties
                .iter()
                .position(|p| {
                    matches!(p.kind, Kind::List { .. })
                        && matches!(p.name.as_str(), "vertex_indices" | "vertex_index")
                })
                .map(Role::Faces)
                .ok_or_else(|| {
                    ParseError::new("the face element has no 'vertex_indices' list property")
                }),
            _ => Ok(Role::Skip),
        })
        .collect()
}

/// The mesh being read, with reusable scratch buffers.
struct Builder {
    /// Vertex count announced by the header (faces may precede vertices).
    vertex_count: usize,
    positions: Vec<DVec3>,
    colors: Vec<[u8; 3]>,
    uvs: Vec<DVec2>,
    /// The requested scalar properties, one list per name.
    scalars: Vec<Vec<f64>>,
    triangles: Vec<[u32; 3]>,
    corners: Vec<u32>,
}

impl Builder {
    fn new(header: &Header, file_size: usize, scalar_count: usize) -> Builder {
        let count = |name: &str| {
            let element = header.elements.iter().find(|e| e.name == name);
            element.map_or(0, |e| e.count)
        };
        let vertex_count = count("vertex");
        // Never trust a header count for allocation beyond what the file can hold.
        Builder {
            vertex_count,
            positions: Vec::with_capacity(vertex_count.min(file_size)),
            colors: Vec::new(),
            uvs: Vec::new(),
            scalars: vec![Vec::new(); scalar_count],
            triangles: Vec::with_capacity(count("face").min(file_size)),
            corners: Vec::new(),
        }
    }

    fn vertex(
        &mut self,
        layout: &VertexLayout,
        values: &[f64],
        vertex: usize,
    ) -> Result<(), String> {
        let position = DVec3::from_array(layout.xyz.map(|p| values[p]));
        check_position(position).map_err(|what| format!("vertex {vertex}: {what}"))?;
        self.positions.push(position);
        if let Some((channels, float)) = layout.color {
            self.colors.push(channels.map(|p| {
                let value = if float { values[p] * 255.0 } else { values[p] };
                value.round().clamp(0.0, 255.0) as u8
            }));
        }
        if let Some([u, v]) = layout.uv {
            self.uvs.push(DVec2::new(values[u], values[v]));
        }
        for (list, &p) in self.scalars.iter_mut().zip(&layout.scalars) {
            list.push(values[p]);
        }
        Ok(())
    }

    fn face(&mut self, indices: &[f64], face: usize) -> Result<(), String> {
        if indices.len() < 3 {
            return Err(format!(
                "face {face} has {} vertices (a face needs at least 3)",
                indices.len()
            ));
        }
        self.corners.clear();
        for &value in indices {
            let index = whole(value)
                .ok_or_else(|| format!("face {face} has an invalid vertex index {value}"))?;
            if index >= self.vertex_count {
                return Err(format!(
                    "face {face} refers to vertex {index} but the file has only {} vertices",
                    self.vertex_count
                ));
            }
            self.corners.push(index as u32);
        }
        for corners in fan(self.corners.len()) {
            self.triangles.push(corners.map(|k| self.corners[k]));
        }
        Ok(())
    }

    /// The mesh and the requested scalars.
    fn finish(self) -> (TriMesh, Vec<Vec<f64>>) {
        let uv = (!self.uvs.is_empty()).then(|| UvLayer {
            coords: self.uvs,
            triangles: self.triangles.clone(),
        });
        let mesh = TriMesh {
            positions: self.positions,
            triangles: self.triangles,
            vertex_colors: (!self.colors.is_empty()).then_some(self.colors),
            uv,
            materials: None,
        };
        (mesh, self.scalars)
    }
}

fn parse(data: &[u8], scalar_names: &[&str]) -> Result<(TriMesh, Vec<Vec<f64>>), ParseError> {
    let header = parse_header(data)?;
    let roles = roles(&header, scalar_names)?;
    if !roles.iter().any(|r| matches!(r, Role::Vertices(_))) {
        return Err(ParseError::new("the file has no vertex element"));
    }
    let mut mesh = Builder::new(&header, data.len(), scalar_names.len());
    let body = &data[header.body_start..];
    let elements = header.elements.iter().zip(&roles);
    match header.encoding {
        PlyEncoding::Ascii => {
            let text = std::str::from_utf8(body).map_err(|e| {
                let line = header.lines
                    + 1
                    + body[..e.valid_up_to()]
                        .iter()
                        .filter(|&&b| b == b'\n')
                        .count();
                ParseError::at(line, "the ASCII body contains bytes that are not text")
            })?;
            let mut body = AsciiBody {
                lines: text.lines(),
                values: "".split_ascii_whitespace(),
                line: header.lines,
            };
            for (element, role) in elements {
                read_records(&mut body, element, role, &mut mesh)?;
            }
        }
        PlyEncoding::BinaryLittleEndian | PlyEncoding::BinaryBigEndian => {
            let mut body = BinaryBody {
                data: body,
                pos: 0,
                big_endian: header.encoding == PlyEncoding::BinaryBigEndian,
            };
            for (element, role) in elements {
                match element.scalar_types() {
                    Some(types) => body.read_fixed(element, &types, role, &mut mesh)?,
                    None => read_records(&mut body, element, role, &mut mesh)?,
                }
            }
        }
    }
    Ok(mesh.finish())
}

/// Why a record could not be read.
enum Fault {
    /// The data ended.
    End,
    /// A value is malformed or misplaced.
    Invalid(String),
}

/// Sequential access to the records of an ASCII or binary body.
trait Body {
    /// Moves to the next record; `false` at the end of the data.
    fn next_record(&mut self) -> bool;
    /// The next value of the current record, stored as `ty`.
    fn value(&mut self, ty: Scalar) -> Result<f64, Fault>;
    /// Checks that the current record has no values left.
    fn end_record(&mut self) -> Result<(), Fault>;
    /// The current line of a text body.
    fn line(&self) -> Option<usize>;
}

/// An ASCII body: one record per line.
struct AsciiBody<'a> {
    lines: std::str::Lines<'a>,
    values: std::str::SplitAsciiWhitespace<'a>,
    line: usize,
}

impl Body for AsciiBody<'_> {
    fn next_record(&mut self) -> bool {
        for text in self.lines.by_ref() {
            self.line += 1;
            if !text.trim_ascii().is_empty() {
                self.values = text.split_ascii_whitespace();
                return true;
            }
        }
        false
    }

    fn value(&mut self, _: Scalar) -> Result<f64, Fault> {
        let word = self.values.next().ok_or_else(|| {
            Fault::Invalid("the line has fewer values than the header declares".to_owned())
        })?;
        parse_number(word).map_err(Fault::Invalid)
    }

    fn end_record(&mut self) -> Result<(), Fault> {
        match self.values.next() {
            None => Ok(()),
            Some(_) => Err(Fault::Invalid(
                "the line has more values than the header declares".to_owned(),
            )),
        }
    }

    fn line(&self) -> Option<usize> {
        Some(self.line)
    }
}

/// A binary body in either byte order.
struct BinaryBody<'a> {
    data: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl Body for BinaryBody<'_> {
    fn next_record(&mut self) -> bool {
        self.pos < self.data.len()
    }

    #[inline]
    fn value(&mut self, ty: Scalar) -> Result<f64, Fault> {
        let value = ty
            .decode(&self.data[self.pos..], self.big_endian)
            .ok_or(Fault::End)?;
        self.pos += ty.size();
        Ok(value)
    }

    fn end_record(&mut self) -> Result<(), Fault> {
        Ok(())
    }

    fn line(&self) -> Option<usize> {
        None
    }
}

impl BinaryBody<'_> {
    /// Reads an element whose properties are all scalars (`types`): records of fixed
    /// size, checked against the data once and decoded at fixed offsets.
    fn read_fixed(
        &mut self,
        element: &Element,
        types: &[Scalar],
        role: &Role,
        mesh: &mut Builder,
    ) -> Result<(), ParseError> {
        let offsets: Vec<usize> = types
            .iter()
            .scan(0, |offset, ty| {
                let start = *offset;
                *offset += ty.size();
                Some(start)
            })
            .collect();
        let stride: usize = types.iter().map(|ty| ty.size()).sum();
        if stride == 0 {
            return Ok(());
        }
        let available = (self.data.len() - self.pos) / stride;
        if available < element.count {
            return Err(ParseError::new(element.truncated(available)));
        }
        let block = &self.data[self.pos..self.pos + stride * element.count];
        self.pos += block.len();
        match role {
            Role::Vertices(layout) => {
                let fields: Vec<(usize, usize, Scalar)> = layout
                    .properties()
                    .map(|p| (p, offsets[p], types[p]))
                    .collect();
                let mut values = vec![0.0; types.len()];
                for (vertex, record) in block.chunks_exact(stride).enumerate() {
                    for &(p, offset, ty) in &fields {
                        values[p] = ty
                            .decode(&record[offset..], self.big_endian)
                            .expect("a record holds all its fields");
                    }
                    mesh.vertex(layout, &values, vertex)
                        .map_err(ParseError::new)?;
                }
                Ok(())
            }
            Role::Faces(_) | Role::Skip => Ok(()),
        }
    }
}

/// Reads an element record by record (any encoding, list properties allowed).
fn read_records(
    body: &mut impl Body,
    element: &Element,
    role: &Role,
    mesh: &mut Builder,
) -> Result<(), ParseError> {
    let mut values = vec![0.0; element.properties.len()];
    let mut list = Vec::new();
    let kept_list = match role {
        Role::Faces(index) => Some(*index),
        Role::Vertices(_) | Role::Skip => None,
    };
    for record in 0..element.count {
        let result = if body.next_record() {
            read_record(body, element, kept_list, &mut values, &mut list)
        } else {
            Err(Fault::End)
        };
        let line = body.line();
        let error = |message| ParseError { line, message };
        match result {
            Ok(()) => {}
            Err(Fault::End) => return Err(error(element.truncated(record))),
            Err(Fault::Invalid(message)) => {
                return Err(error(format!("{} {record}: {message}", element.name)));
            }
        }
        match role {
            Role::Vertices(layout) => mesh.vertex(layout, &values, record),
            Role::Faces(_) => mesh.face(&list, record),
            Role::Skip => Ok(()),
        }
        .map_err(error)?;
    }
    Ok(())
}

/// Reads one record: scalars into `values` (by property index), the items of list
/// property `kept_list` into `list`; other lists are read and dropped.
fn read_record(
    body: &mut impl Body,
    element: &Element,
    kept_list: Option<usize>,
    values: &mut [f64],
    list: &mut Vec<f64>,
) -> Result<(), Fault> {
    for (index, property) in element.properties.iter().enumerate() {
        match property.kind {
            Kind::Scalar(ty) => values[index] = body.value(ty)?,
            Kind::List { count, item } => {
                let length = body.value(count)?;
                let length = whole(length).ok_or_else(|| {
                    Fault::Invalid(format!(
                        "list '{}' has an invalid length {length}",
                        property.name
                    ))
                })?;
                let keep = kept_list == Some(index);
                if keep {
                    list.clear();
                }
                for _ in 0..length {
                    let value = body.value(item)?;
                    if keep {
                        list.push(value);
                    }
                }
            }
        }
    }
    body.end_record()
}

/// `value` as a count or index, if it is a non-negative whole number.
#[inline]
fn whole(value: f64) -> Option<usize> {
    // The cast saturates (and maps NaN to 0), so only whole numbers in range survive.
    let whole = value as usize;
    (whole as f64 == value).then_some(whole)
}

// ---------------------------------------------------------------------------------------
// Writing

/// The texture coordinate of every vertex, if each vertex has exactly one (vertices no
/// triangle uses get (0, 0)); `None` without a UV layer or when it has seams.
fn per_vertex_uv(mesh: &TriMesh) -> Option<Vec<DVec2>> {
    let uv = mesh.uv.as_ref()?;
    let mut per_vertex: Vec<Option<DVec2>> = vec![None; mesh.positions.len()];
    for (triangle, uv_triangle) in mesh.triangles.iter().zip(&uv.triangles) {
        for (&vertex, &coord) in triangle.iter().zip(uv_triangle) {
            let coord = uv.coords[coord as usize];
            match &mut per_vertex[vertex as usize] {
                slot @ None => *slot = Some(coord),
                Some(existing) if *existing == coord => {}
                Some(_) => return None,
            }
        }
    }
    Some(
        per_vertex
            .into_iter()
            .map(Option::unwrap_or_default)
            .collect(),
    )
}

/// Checks the names and sizes of extra vertex scalars (see [`write_ply_with_scalars`]).
fn check_scalars(mesh: &TriMesh, scalars: &[VertexScalar<'_>]) -> Result<(), MeshError> {
    for (k, scalar) in scalars.iter().enumerate() {
        let name = scalar.name;
        let error = |message| MeshError::VertexProperty {
            name: name.to_string(),
            message,
        };
        if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(error("a name must be letters, digits and '_'"));
        }
        if STANDARD_VERTEX_PROPERTIES.contains(&name) {
            return Err(error("the name is taken by a standard property"));
        }
        if scalars[..k].iter().any(|other| other.name == name) {
            return Err(error("the name is given twice"));
        }
        if scalar.values.len() != mesh.vertex_count() {
            return Err(MeshError::AttributeSize {
                layer: "vertex scalar",
                found: scalar.values.len(),
                expected: mesh.vertex_count(),
            });
        }
    }
    Ok(())
}

fn write_header(
    out: &mut impl Write,
    mesh: &TriMesh,
    encoding: PlyEncoding,
    uv: bool,
    scalars: &[VertexScalar<'_>],
) -> std::io::Result<()> {
    let format = match encoding {
        PlyEncoding::Ascii => "ascii",
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
        PlyEncoding::BinaryBigEndian => "binary_big_endian",
    };
    writeln!(
        out,
        "ply\nformat {format} 1.0\ncomment written by mammaplan"
    )?;
    writeln!(out, "element vertex {}", mesh.positions.len())?;
    writeln!(
        out,
        "property double x\nproperty double y\nproperty double z"
    )?;
    if mesh.vertex_colors.is_some() {
        writeln!(
            out,
            "property uchar red\nproperty uchar green\nproperty uchar blue"
        )?;
    }
    if uv {
        writeln!(out, "property double s\nproperty double t")?;
    }
    for scalar in scalars {
        writeln!(out, "property double {}", scalar.name)?;
    }
    writeln!(out, "element face {}", mesh.triangles.len())?;
    writeln!(out, "property list uchar int vertex_indices\nend_header")
}

/// A value of a body record, in either text or binary form.
trait Value: Display + Copy {
    type Bytes: AsRef<[u8]>;
    fn le_bytes(self) -> Self::Bytes;
    fn be_bytes(self) -> Self::Bytes;
}

macro_rules! impl_value {
    ($($t:ty),*) => {$(
        impl Value for $t {
            type Bytes = [u8; size_of::<$t>()];
            fn le_bytes(self) -> Self::Bytes {
                self.to_le_bytes()
            }
            fn be_bytes(self) -> Self::Bytes {
                self.to_be_bytes()
            }
        }
    )*};
}

impl_value!(u8, i32, f64);

/// Writes body records value by value.
struct RecordWriter<'w, W> {
    out: &'w mut W,
    encoding: PlyEncoding,
    /// No value of the current ASCII record written yet.
    first: bool,
}

impl<W: Write> RecordWriter<'_, W> {
    /// Writes one value; ASCII `f64` uses the shortest text that reads back exactly.
    fn value(&mut self, value: impl Value) -> std::io::Result<()> {
        match self.encoding {
            PlyEncoding::Ascii => {
                let separator = if self.first { "" } else { " " };
                self.first = false;
                write!(self.out, "{separator}{value}")
            }
            PlyEncoding::BinaryLittleEndian => self.out.write_all(value.le_bytes().as_ref()),
            PlyEncoding::BinaryBigEndian => self.out.write_all(value.be_bytes().as_ref()),
        }
    }

    fn end(&mut self) -> std::io::Result<()> {
        if self.encoding == PlyEncoding::Ascii {
            self.first = true;
            self.out.write_all(b"\n")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
