//! VTK XML unstructured-grid files (`.vtu`) of tetrahedral meshes with point and cell
//! data, as ParaView opens them.
//!
//! Written as ASCII (`format="ascii"`, numbers in shortest round-trip form, so a file
//! read back gives the same bits) to a temporary file renamed into place. The reader
//! takes what the writer produces and any other single-piece ASCII `.vtu` of
//! tetrahedra (VTK cell type 10); data arrays of any numeric type with one or three
//! components. Binary, appended or compressed data are refused with a message.
//!
//! [`read_fem_input`] reads the arrays the finite-element solver takes: point data
//! [`CONSTRAINED`] (0/1) and [`DISPLACEMENT`] (mm), cell data [`YOUNG_MODULUS`] (kPa) and
//! [`POISSON_RATIO`].

use crate::error::TetraError;
use crate::tetmesh::TetMesh;
use glam::DVec3;
use quick_xml::XmlVersion;
use quick_xml::events::{BytesStart, Event};
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// VTK's cell type number of a linear tetrahedron.
const VTK_TETRA: u8 = 10;
/// Point data: 1 where the displacement is prescribed, 0 where it is solved for.
pub const CONSTRAINED: &str = "constrained";
/// Point data: displacement (mm), 3 components.
pub const DISPLACEMENT: &str = "displacement";
/// Cell data: Young's modulus (kPa).
pub const YOUNG_MODULUS: &str = "young_modulus";
/// Cell data: Poisson's ratio.
pub const POISSON_RATIO: &str = "poisson_ratio";

/// The values of a data array: one per point or cell.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldValues {
    Scalars(Vec<f64>),
    Vectors(Vec<DVec3>),
}

/// A named data array.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    pub name: String,
    pub values: FieldValues,
}

impl Field {
    /// A scalar array.
    pub fn scalars(name: &str, values: Vec<f64>) -> Field {
        Field {
            name: name.to_string(),
            values: FieldValues::Scalars(values),
        }
    }

    /// A 3-vector array.
    pub fn vectors(name: &str, values: Vec<DVec3>) -> Field {
        Field {
            name: name.to_string(),
            values: FieldValues::Vectors(values),
        }
    }

    /// Number of entries (points or cells).
    pub fn len(&self) -> usize {
        match &self.values {
            FieldValues::Scalars(v) => v.len(),
            FieldValues::Vectors(v) => v.len(),
        }
    }

    /// Whether the array has no entries.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn components(&self) -> usize {
        match self.values {
            FieldValues::Scalars(_) => 1,
            FieldValues::Vectors(_) => 3,
        }
    }

    fn flat(&self) -> impl Iterator<Item = f64> + '_ {
        let (scalars, vectors) = match &self.values {
            FieldValues::Scalars(v) => (v.as_slice(), &[][..]),
            FieldValues::Vectors(v) => (&[][..], v.as_slice()),
        };
        scalars
            .iter()
            .copied()
            .chain(vectors.iter().flat_map(|v| v.to_array()))
    }
}

/// A mesh with its data arrays, as read from a `.vtu` file.
#[derive(Debug, Clone, PartialEq)]
pub struct VtuData {
    pub mesh: TetMesh,
    pub point_data: Vec<Field>,
    pub cell_data: Vec<Field>,
}

impl VtuData {
    /// The point data array called `name`.
    pub fn point_field(&self, name: &str) -> Option<&Field> {
        self.point_data.iter().find(|f| f.name == name)
    }

    /// The cell data array called `name`.
    pub fn cell_field(&self, name: &str) -> Option<&Field> {
        self.cell_data.iter().find(|f| f.name == name)
    }
}

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

/// Where in the file a data array sits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Section {
    None,
    PointData,
    CellData,
    Points,
    Cells,
}

/// A data array as parsed.
struct RawArray {
    name: String,
    components: usize,
    values: Vec<f64>,
    /// 1-based line of its start tag.
    line: usize,
}

/// Reads a `.vtu` file of tetrahedra with its data arrays. Errors name the file, the
/// line and what was expected. Tetrahedra keep the orientation they have in the file
/// (see [`TetMesh::validate`]).
pub fn read_vtu(path: &Path) -> Result<VtuData, TetraError> {
    let bytes = std::fs::read(path).map_err(|source| TetraError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let error = |line: Option<usize>, message: String| TetraError::Vtu {
        path: path.to_path_buf(),
        line,
        message,
    };
    let text =
        std::str::from_utf8(&bytes).map_err(|e| error(None, format!("not UTF-8 text: {e}")))?;
    parse_vtu(text).map_err(|(line, message)| error(line, message))
}

/// 1-based line number of byte `offset` in `text`.
fn line_at(text: &str, offset: u64) -> usize {
    let end = (offset as usize).min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

fn attribute(e: &BytesStart, key: &str) -> Result<Option<String>, String> {
    match e.try_get_attribute(key) {
        Ok(Some(a)) => a
            .normalized_value(XmlVersion::Implicit1_0)
            .map(|v| Some(v.into_owned()))
            .map_err(|err| format!("attribute {key}: {err}")),
        Ok(None) => Ok(None),
        Err(err) => Err(format!("attribute {key}: {err}")),
    }
}

fn count_attribute(e: &BytesStart, key: &str) -> Result<usize, String> {
    let value = attribute(e, key)?.ok_or_else(|| format!("<Piece> lacks {key}"))?;
    value
        .trim()
        .parse()
        .map_err(|_| format!("<Piece> {key}=\"{value}\" is not a count"))
}

type ParseResult<T> = Result<T, (Option<usize>, String)>;

/// The state of a parse: the section and the data array being read.
struct Parser {
    section: Section,
    counts: Option<(usize, usize)>,
    arrays: Vec<(Section, RawArray)>,
    open: Option<RawArray>,
    /// Depth of elements nested in the open data array (e.g. ParaView's
    /// `<InformationKey>`), whose text is not data.
    nested: usize,
    saw_root: bool,
}

impl Parser {
    /// A start tag (`empty` for `<tag/>`) on `line`.
    fn start(&mut self, e: &BytesStart, empty: bool, line: usize) -> Result<(), String> {
        if self.open.is_some() {
            self.nested += usize::from(!empty);
            return Ok(());
        }
        let sections = [
            ("PointData", Section::PointData),
            ("CellData", Section::CellData),
            ("Points", Section::Points),
            ("Cells", Section::Cells),
        ];
        let name = e.name();
        let tag = name.as_ref();
        if let Some(&(_, section)) = sections.iter().find(|(t, _)| *t == tag) {
            if !empty {
                self.section = section;
            }
            return Ok(());
        }
        match tag {
            "VTKFile" => {
                self.saw_root = true;
                let kind = attribute(e, "type")?;
                if kind.as_deref() != Some("UnstructuredGrid") {
                    return Err(format!(
                        "VTKFile type is {kind:?}, expected \"UnstructuredGrid\""
                    ));
                }
                if let Some(c) = attribute(e, "compressor")? {
                    return Err(format!(
                        "compressed data ({c}) is not supported: save the file as ASCII"
                    ));
                }
            }
            "Piece" => {
                if self.counts.is_some() {
                    return Err("more than one <Piece>: only one is supported".into());
                }
                self.counts = Some((
                    count_attribute(e, "NumberOfPoints")?,
                    count_attribute(e, "NumberOfCells")?,
                ));
            }
            "AppendedData" => {
                return Err("appended data is not supported: save the file as ASCII".into());
            }
            "DataArray" => {
                let name = attribute(e, "Name")?.unwrap_or_default();
                let format = attribute(e, "format")?;
                if format.as_deref().unwrap_or("ascii") != "ascii" {
                    return Err(format!(
                        "DataArray \"{name}\" has format {format:?}: only \"ascii\" is supported, save the file as ASCII"
                    ));
                }
                let components = match attribute(e, "NumberOfComponents")? {
                    None => 1,
                    Some(c) => c.trim().parse().map_err(|_| {
                        format!("DataArray \"{name}\": NumberOfComponents=\"{c}\" is not a count")
                    })?,
                };
                let array = RawArray {
                    name,
                    components,
                    values: Vec::new(),
                    line,
                };
                if empty {
                    self.arrays.push((self.section, array));
                } else {
                    self.open = Some(array);
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// Numbers of the open data array; `first_line` is the line the text starts on.
    fn text(&mut self, content: &str, first_line: usize) -> Result<(), (usize, String)> {
        let Some(array) = self.open.as_mut().filter(|_| self.nested == 0) else {
            return Ok(());
        };
        for (offset, line) in content.lines().enumerate() {
            for token in line.split_ascii_whitespace() {
                let value: f64 = token.parse().map_err(|_| {
                    (
                        first_line + offset,
                        format!("DataArray \"{}\": \"{token}\" is not a number", array.name),
                    )
                })?;
                array.values.push(value);
            }
        }
        Ok(())
    }

    fn end(&mut self, tag: &str) {
        if self.nested > 0 {
            self.nested -= 1;
            return;
        }
        match tag {
            "DataArray" => {
                if let Some(array) = self.open.take() {
                    self.arrays.push((self.section, array));
                }
            }
            "PointData" | "CellData" | "Points" | "Cells" => self.section = Section::None,
            _ => {}
        }
    }
}

fn parse_vtu(text: &str) -> ParseResult<VtuData> {
    let mut reader = quick_xml::Reader::from_str(text);
    reader.config_mut().trim_text(true);
    let mut parser = Parser {
        section: Section::None,
        counts: None,
        arrays: Vec::new(),
        open: None,
        nested: 0,
        saw_root: false,
    };
    loop {
        let before = reader.buffer_position() as usize;
        let event = reader.read_event().map_err(|e| {
            (
                Some(line_at(text, reader.error_position())),
                format!("malformed XML: {e}"),
            )
        })?;
        let after = (reader.buffer_position() as usize).min(text.len());
        // A tag starts at the last '<' before the reader's position; text at the first
        // non-blank character after the previous event.
        let tag_line = || line_at(text, text[..after].rfind('<').unwrap_or(before) as u64);
        let text_line = || {
            let start = before.min(text.len());
            let blank = text[start..].len() - text[start..].trim_start().len();
            line_at(text, (start + blank) as u64)
        };
        let result = match event {
            Event::Start(e) => parser
                .start(&e, false, tag_line())
                .map_err(|m| (tag_line(), m)),
            Event::Empty(e) => parser
                .start(&e, true, tag_line())
                .map_err(|m| (tag_line(), m)),
            Event::Text(t) => parser.text(&t.xml10_content(), text_line()),
            Event::End(e) => {
                parser.end(e.name().as_ref());
                Ok(())
            }
            Event::GeneralRef(_) if parser.open.is_some() => Err((
                tag_line(),
                "an entity reference inside numeric data".to_string(),
            )),
            Event::Eof => break,
            _ => Ok(()),
        };
        result.map_err(|(line, message)| (Some(line), message))?;
    }
    if !parser.saw_root {
        return Err((None, "no <VTKFile> element: not a VTK XML file".into()));
    }
    let (points, cells) = parser
        .counts
        .ok_or((None, "no <Piece> element".to_string()))?;
    assemble(points, cells, parser.arrays)
}

/// Builds the mesh and data from the parsed arrays, checking sizes and cell types.
fn assemble(
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

/// The input of a finite-element solve, from a `.vtu` file.
#[derive(Debug, Clone, PartialEq)]
pub struct FemInput {
    pub mesh: TetMesh,
    /// Per vertex: whether its displacement is prescribed.
    pub constrained: Vec<bool>,
    /// Per vertex (mm): prescribed where constrained, a start value elsewhere; zero when
    /// the file has no [`DISPLACEMENT`] array.
    pub displacement: Vec<DVec3>,
    /// Per tetrahedron (kPa), if the file has [`YOUNG_MODULUS`].
    pub young_modulus_kpa: Option<Vec<f64>>,
    /// Per tetrahedron, if the file has [`POISSON_RATIO`].
    pub poisson_ratio: Option<Vec<f64>>,
}

/// Reads a `.vtu` for a solve: point data [`CONSTRAINED`] (required, 0 or 1) and
/// [`DISPLACEMENT`] (optional, 3 components), cell data [`YOUNG_MODULUS`] (optional,
/// positive kPa) and [`POISSON_RATIO`] (optional, in (−1, 0.5)). Errors name the array
/// and the entry.
pub fn read_fem_input(path: &Path) -> Result<FemInput, TetraError> {
    let data = read_vtu(path)?;
    let error = |message: String| TetraError::Vtu {
        path: path.to_path_buf(),
        line: None,
        message,
    };
    let scalars = |field: Option<&Field>,
                   name: &str,
                   location: &str|
     -> Result<Option<Vec<f64>>, TetraError> {
        match field.map(|f| &f.values) {
            None => Ok(None),
            Some(FieldValues::Scalars(v)) => Ok(Some(v.clone())),
            Some(FieldValues::Vectors(_)) => Err(error(format!(
                "{location} data \"{name}\" must have 1 component, not 3"
            ))),
        }
    };
    let check = |values: &[f64], name: &str, what: &str, ok: &dyn Fn(f64) -> bool| match values
        .iter()
        .position(|&x| !ok(x))
    {
        Some(k) => Err(error(format!(
            "\"{name}\" entry {k} is {}: expected {what}",
            values[k]
        ))),
        None => Ok(()),
    };
    let constrained = scalars(data.point_field(CONSTRAINED), CONSTRAINED, "point")?
        .ok_or_else(|| error(format!("no point data \"{CONSTRAINED}\" (0/1 per point)")))?;
    check(&constrained, CONSTRAINED, "0 or 1", &|x| {
        x == 0.0 || x == 1.0
    })?;
    let displacement = match data.point_field(DISPLACEMENT).map(|f| &f.values) {
        None => vec![DVec3::ZERO; data.mesh.vertex_count()],
        Some(FieldValues::Vectors(v)) => v.clone(),
        Some(FieldValues::Scalars(_)) => {
            return Err(error(format!(
                "point data \"{DISPLACEMENT}\" must have 3 components"
            )));
        }
    };
    if let Some(k) = displacement.iter().position(|d| !d.is_finite()) {
        return Err(error(format!("\"{DISPLACEMENT}\" entry {k} is not finite")));
    }
    let young_modulus_kpa = scalars(data.cell_field(YOUNG_MODULUS), YOUNG_MODULUS, "cell")?;
    if let Some(e) = &young_modulus_kpa {
        check(e, YOUNG_MODULUS, "a positive modulus in kPa", &|x| {
            x.is_finite() && x > 0.0
        })?;
    }
    let poisson_ratio = scalars(data.cell_field(POISSON_RATIO), POISSON_RATIO, "cell")?;
    if let Some(nu) = &poisson_ratio {
        check(nu, POISSON_RATIO, "a ratio in (-1, 0.5)", &|x| {
            x > -1.0 && x < 0.5
        })?;
    }
    Ok(FemInput {
        constrained: constrained.iter().map(|&x| x == 1.0).collect(),
        displacement,
        young_modulus_kpa,
        poisson_ratio,
        mesh: data.mesh,
    })
}
