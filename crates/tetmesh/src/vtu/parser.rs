//! The XML parse: elements and attributes read into raw data arrays, whose binary and
//! appended values are then decoded.

use super::VtuData;
use super::binary::{Layout, Scalar, base64_decode, exact_block, read_block};
use super::read::assemble;
use quick_xml::XmlVersion;
use quick_xml::events::{BytesStart, Event};
use std::borrow::Cow;

/// Where in the file a data array sits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Section {
    None,
    PointData,
    CellData,
    Points,
    Cells,
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
pub(super) struct RawArray {
    pub(super) name: String,
    pub(super) components: usize,
    pub(super) values: Vec<f64>,
    /// 1-based line of its start tag.
    pub(super) line: usize,
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

pub(super) type ParseResult<T> = Result<T, (Option<usize>, String)>;

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

pub(super) fn parse_vtu(text: &str, appended: Option<&[u8]>) -> ParseResult<VtuData> {
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
