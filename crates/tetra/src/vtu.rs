//! VTK XML unstructured-grid files (`.vtu`) of tetrahedral meshes with point and cell
//! data, as ParaView opens them.
//!
//! Written as ASCII (`format="ascii"`, numbers in shortest round-trip form, so a file
//! read back gives the same bits) to a temporary file renamed into place. The reader
//! takes what the writer produces and any other single-piece `.vtu` of tetrahedra (VTK
//! cell type 10) as ParaView, VTK or meshio write them; data arrays of any numeric type
//! (Int8 to Int64, UInt8 to UInt64, Float32, Float64) with one or three components, in
//! any of VTK's encodings:
//!
//! - `format="ascii"`;
//! - `format="binary"`: base64 inside the element;
//! - `format="appended"` with an `offset` into `<AppendedData encoding="raw">` (bytes
//!   after the `_` marker) or `encoding="base64"` (characters after it);
//! - each binary block a header then the data: uncompressed, the header is the byte
//!   count; with `compressor="vtkZLibDataCompressor"`, it is `[blocks, block size, last
//!   block size, compressed size of each block]` followed by the zlib streams. Header
//!   words are UInt32 or UInt64 (`header_type`, default UInt32), headers and values in
//!   the file's `byte_order` (LittleEndian or BigEndian). Base64 header and data may be
//!   one stream or two (VTK writes two when compressing).
//!
//! Truncated or corrupt binary data give an error naming the array, its line and the
//! problem. Arrays outside the mesh's sections (e.g. `<FieldData>`) are not read.
//!
//! [`read_fem_input`] reads the arrays the finite-element solver takes: point data
//! [`CONSTRAINED`] (0/1) and [`DISPLACEMENT`] (mm), cell data [`YOUNG_MODULUS`] (kPa) and
//! [`POISSON_RATIO`].

use crate::error::TetraError;
use crate::tetmesh::TetMesh;
use glam::DVec3;
use quick_xml::XmlVersion;
use quick_xml::events::{BytesStart, Event};
use std::borrow::Cow;
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

/// The numeric type of a binary data array (its `type` attribute).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "Int8" => Scalar::Int8,
            "UInt8" => Scalar::UInt8,
            "Int16" => Scalar::Int16,
            "UInt16" => Scalar::UInt16,
            "Int32" => Scalar::Int32,
            "UInt32" => Scalar::UInt32,
            "Int64" => Scalar::Int64,
            "UInt64" => Scalar::UInt64,
            "Float32" => Scalar::Float32,
            "Float64" => Scalar::Float64,
            _ => return None,
        })
    }

    /// Bytes per value.
    fn size(self) -> usize {
        match self {
            Scalar::Int8 | Scalar::UInt8 => 1,
            Scalar::Int16 | Scalar::UInt16 => 2,
            Scalar::Int32 | Scalar::UInt32 | Scalar::Float32 => 4,
            Scalar::Int64 | Scalar::UInt64 | Scalar::Float64 => 8,
        }
    }

    /// The values packed in `bytes` (a whole number of them) in the given byte order.
    /// 64-bit integers beyond 2^53 are rounded.
    fn values(self, bytes: &[u8], big_endian: bool) -> Vec<f64> {
        macro_rules! convert {
            ($t:ty) => {
                bytes
                    .chunks_exact(std::mem::size_of::<$t>())
                    .map(|chunk| {
                        let mut a = [0u8; std::mem::size_of::<$t>()];
                        a.copy_from_slice(chunk);
                        (if big_endian {
                            <$t>::from_be_bytes(a)
                        } else {
                            <$t>::from_le_bytes(a)
                        }) as f64
                    })
                    .collect()
            };
        }
        match self {
            Scalar::Int8 => convert!(i8),
            Scalar::UInt8 => convert!(u8),
            Scalar::Int16 => convert!(i16),
            Scalar::UInt16 => convert!(u16),
            Scalar::Int32 => convert!(i32),
            Scalar::UInt32 => convert!(u32),
            Scalar::Int64 => convert!(i64),
            Scalar::UInt64 => convert!(u64),
            Scalar::Float32 => convert!(f32),
            Scalar::Float64 => convert!(f64),
        }
    }
}

/// How binary data is laid out, from the `VTKFile` attributes `header_type` (UInt32 or
/// UInt64 block headers), `byte_order` (of headers and values) and `compressor`.
#[derive(Debug, Clone, Copy)]
struct Layout {
    header_bytes: usize,
    big_endian: bool,
    zlib: bool,
}

/// The `encoding` of `<AppendedData>`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum AppendedEncoding {
    Raw,
    Base64,
}

/// Where a data array's values are.
enum Storage {
    /// `format="ascii"`: parsed into [`RawArray::values`] as read.
    Ascii,
    /// `format="binary"`: the base64 text inside the element.
    Binary(String),
    /// `format="appended"`: at this byte offset after the `_` of `<AppendedData>`.
    Appended(u64),
}

/// A data array as parsed.
struct RawArray {
    name: String,
    components: usize,
    values: Vec<f64>,
    /// 1-based line of its start tag.
    line: usize,
    /// The value type; `None` for ASCII arrays, whose type is not needed.
    scalar: Option<Scalar>,
    storage: Storage,
}

/// How errors name a data array.
fn array_label(section: Section, name: &str) -> String {
    match (name, section) {
        ("", Section::Points) => "<Points> DataArray".to_string(),
        ("", _) => "unnamed DataArray".to_string(),
        _ => format!("DataArray \"{name}\""),
    }
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

/// 1-based line number of byte `offset` in `text`.
fn line_at(text: &str, offset: u64) -> usize {
    let end = (offset as usize).min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// Line numbers of byte offsets, counted on from the previous offset (the parser asks
/// in increasing order), so a large file is scanned once.
struct LineCounter<'a> {
    text: &'a str,
    offset: usize,
    line: usize,
}

impl LineCounter<'_> {
    /// 1-based line number of byte `offset`.
    fn line(&mut self, offset: usize) -> usize {
        let offset = offset.min(self.text.len());
        if offset < self.offset {
            (self.offset, self.line) = (0, 1);
        }
        self.line += self.text.as_bytes()[self.offset..offset]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        self.offset = offset;
        self.line
    }
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
    /// Whether the open data array lies outside the mesh's sections (e.g. in
    /// `<FieldData>`) and is not read.
    ignored: bool,
    /// Depth of elements nested in the open data array (e.g. ParaView's
    /// `<InformationKey>`), whose text is not data.
    nested: usize,
    saw_root: bool,
    layout: Layout,
    appended: Option<AppendedEncoding>,
    /// Offsets of all appended arrays, read or not: each array's base64 text ends
    /// where the next one starts.
    appended_offsets: Vec<u64>,
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
                self.root(e)?;
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
                let encoding = attribute(e, "encoding")?;
                self.appended = Some(match encoding.as_deref().map(str::trim) {
                    Some("raw") => AppendedEncoding::Raw,
                    Some("base64") => AppendedEncoding::Base64,
                    other => {
                        return Err(format!(
                            "<AppendedData> encoding is {other:?}, expected \"raw\" or \"base64\""
                        ));
                    }
                });
            }
            "DataArray" => self.data_array(e, empty, line)?,
            _ => {}
        }
        Ok(())
    }

    /// The attributes of `<VTKFile>`: kind, header type, byte order, compressor.
    fn root(&mut self, e: &BytesStart) -> Result<(), String> {
        let kind = attribute(e, "type")?;
        if kind.as_deref() != Some("UnstructuredGrid") {
            return Err(format!(
                "VTKFile type is {kind:?}, expected \"UnstructuredGrid\""
            ));
        }
        self.layout.header_bytes = match attribute(e, "header_type")?.as_deref().map(str::trim) {
            None | Some("UInt32") => 4,
            Some("UInt64") => 8,
            Some(other) => {
                return Err(format!(
                    "VTKFile header_type=\"{other}\", expected \"UInt32\" or \"UInt64\""
                ));
            }
        };
        self.layout.big_endian = match attribute(e, "byte_order")?.as_deref().map(str::trim) {
            None | Some("LittleEndian") => false,
            Some("BigEndian") => true,
            Some(other) => {
                return Err(format!(
                    "VTKFile byte_order=\"{other}\", expected \"LittleEndian\" or \"BigEndian\""
                ));
            }
        };
        self.layout.zlib = match attribute(e, "compressor")?.as_deref().map(str::trim) {
            None | Some("") => false,
            Some("vtkZLibDataCompressor") => true,
            Some(other) => {
                return Err(format!(
                    "compressor \"{other}\" is not supported (only vtkZLibDataCompressor): save the file with zlib compression or none"
                ));
            }
        };
        Ok(())
    }

    /// A `<DataArray>` start tag.
    fn data_array(&mut self, e: &BytesStart, empty: bool, line: usize) -> Result<(), String> {
        let name = attribute(e, "Name")?.unwrap_or_default();
        let label = array_label(self.section, &name);
        let format = attribute(e, "format")?.unwrap_or_else(|| "ascii".into());
        let offset = attribute(e, "offset")?;
        let ignored = self.section == Section::None;
        let storage = match format.trim() {
            "ascii" => Storage::Ascii,
            "binary" => Storage::Binary(String::new()),
            "appended" => {
                let parsed = offset.as_deref().map(|o| o.trim().parse::<u64>());
                let offset = match parsed {
                    Some(Ok(o)) => o,
                    _ if ignored => 0,
                    None => return Err(format!("{label} is appended but has no offset")),
                    Some(Err(_)) => {
                        return Err(format!(
                            "{label}: offset=\"{}\" is not a byte offset",
                            offset.unwrap_or_default()
                        ));
                    }
                };
                self.appended_offsets.push(offset);
                Storage::Appended(offset)
            }
            _ if ignored => Storage::Ascii,
            other => {
                return Err(format!(
                    "{label} has format \"{other}\", expected \"ascii\", \"binary\" or \"appended\""
                ));
            }
        };
        let scalar = match (&storage, attribute(e, "type")?) {
            (Storage::Ascii, _) => None,
            _ if ignored => None,
            (_, None) => return Err(format!("{label} has no type")),
            (_, Some(t)) => Some(Scalar::parse(t.trim()).ok_or_else(|| {
                format!(
                    "{label} has type \"{t}\", expected a numeric type (Int8 to Int64, UInt8 to UInt64, Float32, Float64)"
                )
            })?),
        };
        let components = match attribute(e, "NumberOfComponents")? {
            None => 1,
            Some(_) if ignored => 1,
            Some(c) => c
                .trim()
                .parse()
                .map_err(|_| format!("{label}: NumberOfComponents=\"{c}\" is not a count"))?,
        };
        let array = RawArray {
            name,
            components,
            values: Vec::new(),
            line,
            scalar,
            storage,
        };
        if empty {
            if !ignored {
                self.arrays.push((self.section, array));
            }
        } else {
            self.open = Some(array);
            self.ignored = ignored;
        }
        Ok(())
    }

    /// Text of the open data array; `first_line` is the line the text starts on.
    fn text(&mut self, content: &str, first_line: usize) -> Result<(), (usize, String)> {
        let Some(array) = self
            .open
            .as_mut()
            .filter(|_| self.nested == 0 && !self.ignored)
        else {
            return Ok(());
        };
        match &mut array.storage {
            Storage::Binary(base64) => {
                base64.push_str(content);
                return Ok(());
            }
            // Appended arrays hold no data in the element.
            Storage::Appended(_) => return Ok(()),
            Storage::Ascii => {}
        }
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
                if let Some(array) = self.open.take()
                    && !std::mem::take(&mut self.ignored)
                {
                    self.arrays.push((self.section, array));
                }
            }
            "PointData" | "CellData" | "Points" | "Cells" => self.section = Section::None,
            _ => {}
        }
    }

    /// Decodes the binary and appended arrays the mesh needs (`appended`: the bytes
    /// after the `_` of `<AppendedData>`).
    fn decode(&mut self, appended: Option<&[u8]>) -> ParseResult<()> {
        let mut offsets = self.appended_offsets.clone();
        offsets.sort_unstable();
        offsets.dedup();
        for (section, array) in &mut self.arrays {
            let unused = *section == Section::Cells
                && !matches!(array.name.as_str(), "connectivity" | "offsets" | "types");
            let Some(scalar) = array.scalar.filter(|_| !unused) else {
                continue;
            };
            let label = array_label(*section, &array.name);
            let located = |message: String| (Some(array.line), format!("{label}: {message}"));
            let layout = self.layout;
            let bytes = match &array.storage {
                Storage::Ascii => continue,
                Storage::Binary(text) => {
                    let chars: Vec<u8> =
                        text.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
                    let decoded = base64_decode(&chars).map_err(&located)?;
                    Cow::Owned(
                        exact_block(&decoded, layout)
                            .map_err(&located)?
                            .into_owned(),
                    )
                }
                &Storage::Appended(offset) => {
                    let (Some(data), Some(encoding)) = (appended, self.appended) else {
                        return Err(located(
                            "format is \"appended\" but the file has no <AppendedData>".into(),
                        ));
                    };
                    let start = usize::try_from(offset)
                        .ok()
                        .filter(|&s| s <= data.len())
                        .ok_or_else(|| {
                            located(format!(
                                "offset {offset} lies beyond the {} bytes of appended data (truncated file?)",
                                data.len()
                            ))
                        })?;
                    match encoding {
                        AppendedEncoding::Raw => {
                            read_block(&data[start..], layout).map_err(&located)?.0
                        }
                        AppendedEncoding::Base64 => {
                            // This array's text runs to the next array's offset.
                            let end = offsets
                                .iter()
                                .find(|&&o| o > offset)
                                .map_or(data.len(), |&o| (o as usize).min(data.len()));
                            let chars: Vec<u8> = data[start..end]
                                .iter()
                                .copied()
                                .filter(|b| !b.is_ascii_whitespace())
                                .collect();
                            let decoded = base64_decode(&chars).map_err(&located)?;
                            Cow::Owned(
                                exact_block(&decoded, layout)
                                    .map_err(&located)?
                                    .into_owned(),
                            )
                        }
                    }
                }
            };
            if !bytes.len().is_multiple_of(scalar.size()) {
                return Err(located(format!(
                    "{} bytes of data are not a whole number of {scalar:?} values ({} bytes each)",
                    bytes.len(),
                    scalar.size()
                )));
            }
            array.values = scalar.values(&bytes, layout.big_endian);
        }
        Ok(())
    }
}

/// Decodes base64 text without whitespace. VTK encodes a block header and its data
/// either as one base64 stream or as two, each padded with `=`; both decode to the same
/// bytes here because every padded 4-character group ends a stream and the next starts
/// afresh.
fn base64_decode(chars: &[u8]) -> Result<Vec<u8>, String> {
    use base64::Engine as _;
    use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
    const ENGINE: GeneralPurpose = GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        GeneralPurposeConfig::new()
            .with_decode_allow_trailing_bits(true)
            .with_decode_padding_mode(DecodePaddingMode::RequireCanonical),
    );
    if !chars.len().is_multiple_of(4) {
        return Err(format!(
            "its base64 text has {} characters, not a multiple of 4 (truncated?)",
            chars.len()
        ));
    }
    let mut out = Vec::with_capacity(chars.len() / 4 * 3);
    let mut start = 0;
    for group in (0..chars.len()).step_by(4) {
        let end = group + 4;
        if chars[end - 1] == b'=' || end == chars.len() {
            ENGINE
                .decode_vec(&chars[start..end], &mut out)
                .map_err(|e| format!("invalid base64 in characters {start}..{end}: {e}"))?;
            start = end;
        }
    }
    Ok(out)
}

/// Like [`read_block`], and the block must fill `bytes` exactly.
fn exact_block(bytes: &[u8], layout: Layout) -> Result<Cow<'_, [u8]>, String> {
    let (data, used) = read_block(bytes, layout)?;
    if used != bytes.len() {
        return Err(format!(
            "{} bytes follow the {used} bytes its header announces",
            bytes.len() - used
        ));
    }
    Ok(data)
}

/// Reads one binary block from the start of `bytes`: a header and the data it
/// announces. Uncompressed: the header is the data's byte count. Compressed (zlib): the
/// header is `[blocks, block size, last block size, compressed size of each block]`
/// (a last block size of 0 means a full block), followed by the compressed blocks.
/// Header words are `layout.header_bytes` wide in the file's byte order. Returns the
/// (uncompressed) data and the number of bytes of `bytes` used.
fn read_block(bytes: &[u8], layout: Layout) -> Result<(Cow<'_, [u8]>, usize), String> {
    let h = layout.header_bytes;
    let kind = if h == 8 { "UInt64" } else { "UInt32" };
    let word = |k: usize| -> Result<u64, String> {
        let Some(b) = bytes.get(k * h..(k + 1) * h) else {
            return Err(format!(
                "truncated: {} bytes cannot hold header word {} ({kind})",
                bytes.len(),
                k + 1
            ));
        };
        let mut a = [0u8; 8];
        Ok(match (h, layout.big_endian) {
            (8, false) => {
                a.copy_from_slice(b);
                u64::from_le_bytes(a)
            }
            (8, true) => {
                a.copy_from_slice(b);
                u64::from_be_bytes(a)
            }
            (_, false) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64,
            (_, true) => u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as u64,
        })
    };
    if !layout.zlib {
        let n = word(0)?;
        let available = bytes.len() - h;
        return match usize::try_from(n).ok().filter(|&n| n <= available) {
            Some(n) => Ok((Cow::Borrowed(&bytes[h..h + n]), h + n)),
            None => Err(format!(
                "truncated: the header announces {n} bytes of data, {available} follow"
            )),
        };
    }
    let blocks = word(0)?;
    let block_size = word(1)?;
    let last_size = word(2)?;
    let header_len = usize::try_from(blocks)
        .ok()
        .and_then(|b| b.checked_add(3)?.checked_mul(h))
        .filter(|&len| len <= bytes.len())
        .ok_or_else(|| {
            format!(
                "truncated: the compression header announces {blocks} blocks, but {} bytes cannot hold their sizes",
                bytes.len()
            )
        })?;
    if last_size > block_size {
        return Err(format!(
            "corrupt compression header: last block size {last_size} exceeds block size {block_size}"
        ));
    }
    let blocks = blocks as usize;
    let mut data = Vec::new();
    let mut position = header_len;
    // One inflater for all blocks: setting one up costs more than a small block.
    let mut inflater = flate2::Decompress::new(true);
    for b in 0..blocks {
        let compressed = word(3 + b)?;
        let expected = if b + 1 == blocks && last_size != 0 {
            last_size
        } else {
            block_size
        };
        let available = bytes.len() - position;
        let compressed = usize::try_from(compressed)
            .ok()
            .filter(|&c| c <= available)
            .ok_or_else(|| {
                format!(
                    "truncated: compressed block {} of {blocks} needs {compressed} bytes, {available} follow",
                    b + 1
                )
            })?;
        inflate_block(
            &mut inflater,
            &bytes[position..position + compressed],
            expected,
            &mut data,
        )
        .map_err(|problem| format!("compressed block {} of {blocks} {problem}", b + 1))?;
        position += compressed;
    }
    Ok((Cow::Owned(data), position))
}

/// Appends the zlib stream `block` inflated to `out`, which must give exactly `expected`
/// bytes. Memory grows with the output actually produced, so a corrupt header claiming
/// a huge block allocates nothing. The error completes "compressed block k of n ...".
fn inflate_block(
    inflater: &mut flate2::Decompress,
    block: &[u8],
    expected: u64,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    const CHUNK: u64 = 1 << 20;
    inflater.reset(true);
    let start = out.len();
    let mut input = block;
    loop {
        let produced = (out.len() - start) as u64;
        if produced > expected {
            return Err(format!(
                "decompresses to more than the {expected} bytes its header announces"
            ));
        }
        // Room for one byte more than expected, to notice a block that is too long.
        out.reserve((expected - produced + 1).min(CHUNK) as usize);
        let (in_before, out_before) = (inflater.total_in(), out.len());
        let status = inflater
            .decompress_vec(input, out, flate2::FlushDecompress::Finish)
            .map_err(|e| format!("is corrupt: {e}"))?;
        input = &input[(inflater.total_in() - in_before) as usize..];
        let produced = (out.len() - start) as u64;
        if status == flate2::Status::StreamEnd {
            return if produced == expected {
                Ok(())
            } else {
                Err(format!(
                    "decompresses to {produced} bytes, the header announces {expected}"
                ))
            };
        }
        if inflater.total_in() == in_before && out.len() == out_before {
            return Err(format!(
                "ends after {produced} of {expected} bytes: the stream is truncated or corrupt"
            ));
        }
    }
}

fn parse_vtu(text: &str, appended: Option<&[u8]>) -> ParseResult<VtuData> {
    let mut reader = quick_xml::Reader::from_str(text);
    reader.config_mut().trim_text(true);
    let mut parser = Parser {
        section: Section::None,
        counts: None,
        arrays: Vec::new(),
        open: None,
        ignored: false,
        nested: 0,
        saw_root: false,
        layout: Layout {
            header_bytes: 4,
            big_endian: false,
            zlib: false,
        },
        appended: None,
        appended_offsets: Vec::new(),
    };
    let mut lines = LineCounter {
        text,
        offset: 0,
        line: 1,
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
        let line = match &event {
            Event::Start(_) | Event::Empty(_) | Event::GeneralRef(_) => {
                lines.line(text[..after].rfind('<').unwrap_or(before))
            }
            Event::Text(_) => {
                let start = before.min(text.len());
                let blank = text[start..].len() - text[start..].trim_start().len();
                lines.line(start + blank)
            }
            _ => 0,
        };
        let result = match event {
            Event::Start(e) => parser.start(&e, false, line).map_err(|m| (line, m)),
            Event::Empty(e) => parser.start(&e, true, line).map_err(|m| (line, m)),
            Event::Text(t) => parser.text(&t.xml10_content(), line),
            Event::End(e) => {
                parser.end(e.name().as_ref());
                Ok(())
            }
            Event::GeneralRef(_) if parser.open.is_some() => {
                Err((line, "an entity reference inside numeric data".to_string()))
            }
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
    parser.decode(appended)?;
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
