//! VTU writing and reading: exact round trip, the solver's arrays, and errors naming
//! the file, the line and the problem; binary, appended and zlib-compressed files built
//! byte by byte from the format specification (every encoding, byte order and header
//! type), files written by VTK itself, and damaged binary data.

use glam::DVec3;
use std::path::{Path, PathBuf};
use tetra::vtu::{Field, FieldValues, read_fem_input, read_vtu, write_vtu};
use tetra::{ClosedSurface, TetMesh, TetMeshError, stuff};

fn small_mesh() -> TetMesh {
    let surface = ClosedSurface::new(&mesh::shapes::icosphere(10.0, 2)).unwrap();
    stuff(&surface, 4.0).unwrap()
}

fn write_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn write_then_read_gives_the_same_bits() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.vtu");
    let mesh = small_mesh();
    let n = mesh.vertex_count();
    let point_data = vec![
        Field::scalars("constrained", (0..n).map(|i| (i % 2) as f64).collect()),
        Field::vectors(
            "displacement",
            mesh.positions
                .iter()
                .map(|p| *p * 1e-7 + DVec3::new(1e20, -0.1, 1.0 / 3.0))
                .collect(),
        ),
    ];
    let cell_data = vec![
        Field::scalars("young_modulus", vec![3.25; mesh.tet_count()]),
        Field::scalars(
            "poisson_ratio \"quoted\" & <odd>",
            vec![0.49; mesh.tet_count()],
        ),
    ];
    write_vtu(&path, &mesh, &point_data, &cell_data).unwrap();
    let read = read_vtu(&path).unwrap();
    assert_eq!(read.mesh, mesh);
    assert_eq!(read.point_data, point_data);
    assert_eq!(read.cell_data, cell_data);
    // Nothing but the file itself is left in the folder.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);

    let fem = read_fem_input(&path).unwrap();
    assert_eq!(fem.mesh, mesh);
    assert_eq!(fem.constrained.iter().filter(|&&c| c).count(), n / 2);
    let FieldValues::Vectors(displacement) = &point_data[1].values else {
        unreachable!()
    };
    assert_eq!(&fem.displacement, displacement);
    assert_eq!(fem.young_modulus_kpa, Some(vec![3.25; mesh.tet_count()]));
    assert_eq!(fem.poisson_ratio, None, "the name differs");
}

#[test]
fn arrays_of_the_wrong_size_or_with_nan_are_not_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.vtu");
    let mesh = small_mesh();
    let short = vec![Field::scalars("x", vec![0.0; 3])];
    assert!(matches!(
        write_vtu(&path, &mesh, &short, &[]),
        Err(TetMeshError::DataSize { found: 3, .. })
    ));
    let nan = vec![Field::scalars("x", vec![f64::NAN; mesh.tet_count()])];
    assert!(write_vtu(&path, &mesh, &[], &nan).is_err());
    assert!(!path.exists());
}

const HEADER: &str = r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
  <UnstructuredGrid>
    <Piece NumberOfPoints="4" NumberOfCells="1">
      <PointData>
"#;
const POINTS_AND_CELLS: &str = r#"      </PointData>
      <Points>
        <DataArray type="Float32" NumberOfComponents="3" format="ascii">0 0 0 1 0 0 0 1 0 0 0 1</DataArray>
      </Points>
      <Cells>
        <DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3</DataArray>
        <DataArray type="Int32" Name="offsets" format="ascii">4</DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">TYPE</DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"#;

fn one_tet_file(point_data: &str, cell_type: &str) -> String {
    format!(
        "{HEADER}{point_data}{}",
        POINTS_AND_CELLS.replace("TYPE", cell_type)
    )
}

fn error_text(result: Result<impl std::fmt::Debug, TetMeshError>) -> String {
    result.expect_err("expected an error").to_string()
}

#[test]
fn foreign_files_and_their_problems_are_reported_with_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    // ParaView may put information keys inside an array; their text is not data.
    let constrained = r#"        <DataArray type="Int32" Name="constrained" format="ascii">1 1 1 0<InformationKey name="R" location="vtkDataArray"><Value index="0">7</Value></InformationKey></DataArray>
"#;
    let good = write_file(dir.path(), "good.vtu", &one_tet_file(constrained, "10"));
    let fem = read_fem_input(&good).unwrap();
    assert_eq!(fem.constrained, vec![true, true, true, false]);
    assert_eq!(fem.displacement, vec![DVec3::ZERO; 4]);

    let hexahedron = write_file(dir.path(), "hex.vtu", &one_tet_file(constrained, "12"));
    let text = error_text(read_vtu(&hexahedron));
    assert!(
        text.contains("hex.vtu, line 14") && text.contains("cell 0 has VTK type 12"),
        "{text}"
    );

    let half = constrained.replace("1 1 1 0", "1 0.5 1 0");
    let bad_flag = write_file(dir.path(), "flag.vtu", &one_tet_file(&half, "10"));
    let text = error_text(read_fem_input(&bad_flag));
    assert!(text.contains("\"constrained\" entry 1 is 0.5"), "{text}");

    let missing = write_file(dir.path(), "missing.vtu", &one_tet_file("", "10"));
    let text = error_text(read_fem_input(&missing));
    assert!(text.contains("no point data \"constrained\""), "{text}");

    // Three bytes of base64 data cannot even hold the UInt32 block header.
    let binary = constrained.replace("format=\"ascii\">1 1 1 0", "format=\"binary\">AAAA");
    let binary = write_file(dir.path(), "binary.vtu", &one_tet_file(&binary, "10"));
    let text = error_text(read_vtu(&binary));
    assert!(
        text.contains("line 6")
            && text.contains("DataArray \"constrained\"")
            && text.contains("truncated"),
        "{text}"
    );

    let garbage = constrained.replace("1 1 1 0", "1 1 x 0");
    let garbage = write_file(dir.path(), "garbage.vtu", &one_tet_file(&garbage, "10"));
    let text = error_text(read_vtu(&garbage));
    assert!(text.contains("\"x\" is not a number"), "{text}");

    let short = constrained.replace("1 1 1 0", "1 1 1");
    let short = write_file(dir.path(), "short.vtu", &one_tet_file(&short, "10"));
    let text = error_text(read_vtu(&short));
    assert!(text.contains("has 3 values, expected 4"), "{text}");

    let broken = write_file(
        dir.path(),
        "broken.vtu",
        "<VTKFile type=\"UnstructuredGrid\"><Piece",
    );
    assert!(error_text(read_vtu(&broken)).contains("broken.vtu"));
    let absent = dir.path().join("absent.vtu");
    assert!(matches!(read_vtu(&absent), Err(TetMeshError::Io { .. })));
}

// Binary, appended and compressed files, built byte by byte from the VTK file format
// specification ("VTK File Formats", XML section: binary data blocks, appended data,
// compression header), independently of the reader.

/// A data array to write: values, VTK type and components.
struct Array {
    name: &'static str,
    vtk_type: &'static str,
    components: usize,
    values: Vec<f64>,
}

/// The arrays of a file: field data (not part of the mesh), point and cell data, the
/// points, and the three cell arrays.
struct Content {
    field: Vec<Array>,
    point: Vec<Array>,
    cell: Vec<Array>,
    points: Array,
    cells: [Array; 3],
}

/// Where the array data goes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum DataMode {
    /// `format="binary"`, base64 inside the element.
    Inline,
    /// `<AppendedData encoding="raw">`.
    AppendedRaw,
    /// `<AppendedData encoding="base64">`.
    AppendedBase64,
}

/// How each array's bytes are packed into a block.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Compression {
    None,
    /// zlib streams of stored (uncompressed) deflate blocks, written by hand below.
    ZlibStored {
        block: usize,
    },
    /// zlib streams from flate2's encoder.
    ZlibDeflate {
        block: usize,
    },
}

#[derive(Debug, Clone, Copy)]
struct Encoding {
    data: DataMode,
    compression: Compression,
    header64: bool,
    big_endian: bool,
    /// Base64 of the header and the data as two padded streams (VTK does so when
    /// compressing) rather than one.
    split_base64: bool,
    /// A full last compression block recorded with its size (as meshio writes it) rather
    /// than 0 (as VTK writes it).
    full_last_block_size: bool,
}

const PLAIN: Encoding = Encoding {
    data: DataMode::Inline,
    compression: Compression::None,
    header64: false,
    big_endian: false,
    split_base64: false,
    full_last_block_size: false,
};

/// Changes an array's block before it is encoded: `(array name, header, data)`.
type TamperFn = dyn Fn(&str, &mut Vec<u8>, &mut Vec<u8>);
type Tamper<'a> = &'a TamperFn;

fn no_tamper(_: &str, _: &mut Vec<u8>, _: &mut Vec<u8>) {}

/// Base64 (RFC 4648, standard alphabet, `=` padding).
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [0, 1, 2].map(|k| chunk.get(k).copied().unwrap_or(0) as u32);
        let n = (b[0] << 16) | (b[1] << 8) | b[2];
        for k in 0..4 {
            out.push(if k <= chunk.len() {
                ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char
            } else {
                '='
            });
        }
    }
    out
}

/// Adler-32 checksum (RFC 1950).
fn adler32(bytes: &[u8]) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    for &x in bytes {
        a = (a + x as u32) % 65521;
        b = (b + a) % 65521;
    }
    (b << 16) | a
}

/// A zlib stream (RFC 1950) of stored deflate blocks (RFC 1951, BTYPE 00).
fn zlib_stored(bytes: &[u8]) -> Vec<u8> {
    // CMF 0x78 (deflate, 32 KiB window), FLG 0x01: 0x7801 is a multiple of 31.
    let mut out = vec![0x78, 0x01];
    let chunks: Vec<&[u8]> = if bytes.is_empty() {
        vec![&[]]
    } else {
        bytes.chunks(65535).collect()
    };
    for (k, chunk) in chunks.iter().enumerate() {
        out.push(u8::from(k + 1 == chunks.len())); // BFINAL, BTYPE 00
        let len = chunk.len() as u16;
        out.extend(len.to_le_bytes());
        out.extend((!len).to_le_bytes());
        out.extend_from_slice(chunk);
    }
    out.extend(adler32(bytes).to_be_bytes());
    out
}

fn zlib_deflate(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write as _;
    let mut encoder = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

/// The values of `array` packed as its VTK type in the byte order.
fn pack(array: &Array, big_endian: bool) -> Vec<u8> {
    macro_rules! put {
        ($t:ty) => {
            array
                .values
                .iter()
                .flat_map(|&x| {
                    let v = x as $t;
                    assert_eq!(
                        v as f64, x,
                        "{} value {x} fits {}",
                        array.name, array.vtk_type
                    );
                    if big_endian {
                        v.to_be_bytes().to_vec()
                    } else {
                        v.to_le_bytes().to_vec()
                    }
                })
                .collect()
        };
    }
    match array.vtk_type {
        "Int8" => put!(i8),
        "UInt8" => put!(u8),
        "Int16" => put!(i16),
        "UInt16" => put!(u16),
        "Int32" => put!(i32),
        "UInt32" => put!(u32),
        "Int64" => put!(i64),
        "UInt64" => put!(u64),
        "Float32" => put!(f32),
        "Float64" => put!(f64),
        other => panic!("type {other}"),
    }
}

/// A header word (UInt32 or UInt64) in the byte order.
fn word(x: usize, e: &Encoding) -> Vec<u8> {
    match (e.header64, e.big_endian) {
        (true, false) => (x as u64).to_le_bytes().to_vec(),
        (true, true) => (x as u64).to_be_bytes().to_vec(),
        (false, false) => u32::try_from(x).unwrap().to_le_bytes().to_vec(),
        (false, true) => u32::try_from(x).unwrap().to_be_bytes().to_vec(),
    }
}

/// A zlib compressor of one block.
type Compressor = fn(&[u8]) -> Vec<u8>;

/// One binary block `(header, data)`: uncompressed, the header is the byte count;
/// compressed, `[blocks, block size, last block size, compressed sizes...]` and the
/// concatenated zlib streams of the blocks.
fn block(bytes: &[u8], e: &Encoding) -> (Vec<u8>, Vec<u8>) {
    let (size, compress): (usize, Compressor) = match e.compression {
        Compression::None => return (word(bytes.len(), e), bytes.to_vec()),
        Compression::ZlibStored { block } => (block, zlib_stored),
        Compression::ZlibDeflate { block } => (block, zlib_deflate),
    };
    let streams: Vec<Vec<u8>> = bytes.chunks(size).map(compress).collect();
    let last = match bytes.len() % size {
        0 if e.full_last_block_size && !bytes.is_empty() => size,
        partial => partial,
    };
    let mut header = [word(streams.len(), e), word(size, e), word(last, e)].concat();
    for s in &streams {
        header.extend(word(s.len(), e));
    }
    (header, streams.concat())
}

/// A `.vtu` file of `content` in encoding `e`, with `tamper` applied to each block.
fn vtu_bytes(content: &Content, e: &Encoding, tamper: Tamper) -> Vec<u8> {
    use std::fmt::Write as _;
    let order = if e.big_endian {
        "BigEndian"
    } else {
        "LittleEndian"
    };
    let header = if e.header64 { "UInt64" } else { "UInt32" };
    let compressor = if e.compression == Compression::None {
        ""
    } else {
        " compressor=\"vtkZLibDataCompressor\""
    };
    let mut xml = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"{order}\" header_type=\"{header}\"{compressor}>\n  <UnstructuredGrid>\n"
    );
    let mut appended: Vec<u8> = Vec::new();
    let mut put = |xml: &mut String, a: &Array| {
        let (mut head, mut data) = block(&pack(a, e.big_endian), e);
        tamper(a.name, &mut head, &mut data);
        let text = if e.split_base64 {
            base64(&head) + &base64(&data)
        } else {
            base64(&[head.clone(), data.clone()].concat())
        };
        let start = format!(
            "        <DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\"",
            a.vtk_type, a.name, a.components
        );
        let offset = appended.len();
        match e.data {
            DataMode::Inline => {
                let _ = writeln!(
                    xml,
                    "{start} format=\"binary\">\n          {text}\n        </DataArray>"
                );
            }
            DataMode::AppendedRaw | DataMode::AppendedBase64 => {
                let _ = writeln!(xml, "{start} format=\"appended\" offset=\"{offset}\"/>");
                if e.data == DataMode::AppendedRaw {
                    appended.extend(head);
                    appended.extend(data);
                } else {
                    appended.extend(text.as_bytes());
                }
            }
        }
    };
    xml.push_str("    <FieldData>\n");
    for a in &content.field {
        put(&mut xml, a);
    }
    let points = content.points.values.len() / 3;
    let cells = content.cells[1].values.len();
    let _ = writeln!(
        xml,
        "    </FieldData>\n    <Piece NumberOfPoints=\"{points}\" NumberOfCells=\"{cells}\">"
    );
    for (tag, arrays) in [
        ("PointData", &content.point[..]),
        ("CellData", &content.cell[..]),
        ("Points", std::slice::from_ref(&content.points)),
        ("Cells", &content.cells[..]),
    ] {
        let _ = writeln!(xml, "      <{tag}>");
        for a in arrays {
            put(&mut xml, a);
        }
        let _ = writeln!(xml, "      </{tag}>");
    }
    xml.push_str("    </Piece>\n  </UnstructuredGrid>\n");
    let mut file = xml.into_bytes();
    if e.data != DataMode::Inline {
        let encoding = if e.data == DataMode::AppendedRaw {
            "raw"
        } else {
            "base64"
        };
        file.extend(format!("  <AppendedData encoding=\"{encoding}\">\n   _").bytes());
        file.extend(appended);
        file.extend(b"\n  </AppendedData>\n");
    }
    file.extend(b"</VTKFile>\n");
    file
}

const SCALAR_TYPES: [&str; 10] = [
    "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64", "Float32", "Float64",
];

/// A stuffed sphere with one point data array of every numeric type, vectors in Float32
/// and Float64, and cell data; each value exactly representable in its type.
fn rich_content() -> (Content, TetMesh, Vec<Field>, Vec<Field>) {
    let mesh = small_mesh();
    let n = mesh.vertex_count();
    let scalar = |ty: &'static str, name: &'static str| {
        let values = (0..n)
            .map(|i| {
                let k = (i * 37 % 200) as f64;
                match ty {
                    t if t.starts_with("UInt") => k,
                    t if t.starts_with("Int") => k - 100.0,
                    _ => k * 0.375 - 7.0,
                }
            })
            .collect();
        Array {
            name,
            vtk_type: ty,
            components: 1,
            values,
        }
    };
    let mut point: Vec<Array> = SCALAR_TYPES.iter().map(|&t| scalar(t, t)).collect();
    let displacement: Vec<DVec3> = mesh
        .positions
        .iter()
        .map(|p| DVec3::new(p.x.sin() * 1e-3, p.y / 3.0, -p.z * 1e20))
        .collect();
    point.push(Array {
        name: "displacement",
        vtk_type: "Float64",
        components: 3,
        values: displacement.iter().flat_map(|d| d.to_array()).collect(),
    });
    point.push(Array {
        name: "direction",
        vtk_type: "Float32",
        components: 3,
        values: (0..3 * n).map(|k| (k % 7) as f64 * 0.25).collect(),
    });
    let cells = mesh.tet_count();
    let cell = vec![
        Array {
            name: "young_modulus",
            vtk_type: "Float64",
            components: 1,
            values: (0..cells).map(|c| 3.0 + c as f64 / 7.0).collect(),
        },
        Array {
            name: "region",
            vtk_type: "Int32",
            components: 1,
            values: (0..cells).map(|c| (c % 5) as f64 - 2.0).collect(),
        },
    ];
    let fields = |arrays: &[Array]| -> Vec<Field> {
        arrays
            .iter()
            .map(|a| match a.components {
                1 => Field::scalars(a.name, a.values.clone()),
                _ => Field::vectors(
                    a.name,
                    a.values.chunks_exact(3).map(DVec3::from_slice).collect(),
                ),
            })
            .collect()
    };
    let (point_fields, cell_fields) = (fields(&point), fields(&cell));
    let content = Content {
        // ParaView's time stamp: not part of the mesh, but it shares the appended data.
        field: vec![Array {
            name: "TimeValue",
            vtk_type: "Float64",
            components: 1,
            values: vec![0.5],
        }],
        point,
        cell,
        points: Array {
            name: "Points",
            vtk_type: "Float64",
            components: 3,
            values: mesh.positions.iter().flat_map(|p| p.to_array()).collect(),
        },
        cells: [
            Array {
                name: "connectivity",
                vtk_type: "Int64",
                components: 1,
                values: mesh.tets.iter().flatten().map(|&v| v as f64).collect(),
            },
            Array {
                name: "offsets",
                vtk_type: "UInt32",
                components: 1,
                values: (1..=cells).map(|c| (4 * c) as f64).collect(),
            },
            Array {
                name: "types",
                vtk_type: "UInt8",
                components: 1,
                values: vec![10.0; cells],
            },
        ],
    };
    (content, mesh, point_fields, cell_fields)
}

/// The encodings tested, each with a label.
fn encodings() -> Vec<(&'static str, Encoding)> {
    let zlib = Compression::ZlibDeflate { block: 512 };
    vec![
        ("inline binary", PLAIN),
        (
            "inline binary, header and data as two base64 streams",
            Encoding {
                split_base64: true,
                ..PLAIN
            },
        ),
        (
            "inline binary, big-endian",
            Encoding {
                big_endian: true,
                ..PLAIN
            },
        ),
        (
            "inline binary, UInt64 header",
            Encoding {
                header64: true,
                ..PLAIN
            },
        ),
        (
            "inline binary, zlib (deflate), two base64 streams as VTK writes",
            Encoding {
                compression: zlib,
                split_base64: true,
                ..PLAIN
            },
        ),
        (
            "inline binary, zlib (stored blocks), one base64 stream, UInt64 header, big-endian",
            Encoding {
                compression: Compression::ZlibStored { block: 100 },
                header64: true,
                big_endian: true,
                ..PLAIN
            },
        ),
        (
            // Blocks of 4 bytes: every array of 4- or 8-byte values ends on a full block.
            "inline binary, zlib, full last blocks recorded as meshio does",
            Encoding {
                compression: Compression::ZlibStored { block: 4 },
                full_last_block_size: true,
                split_base64: true,
                ..PLAIN
            },
        ),
        (
            "inline binary, zlib, full last blocks recorded as 0 as VTK does",
            Encoding {
                compression: Compression::ZlibDeflate { block: 4 },
                split_base64: true,
                ..PLAIN
            },
        ),
        (
            "appended raw",
            Encoding {
                data: DataMode::AppendedRaw,
                ..PLAIN
            },
        ),
        (
            "appended raw, zlib, big-endian, UInt64 header",
            Encoding {
                data: DataMode::AppendedRaw,
                compression: zlib,
                big_endian: true,
                header64: true,
                ..PLAIN
            },
        ),
        (
            "appended base64",
            Encoding {
                data: DataMode::AppendedBase64,
                ..PLAIN
            },
        ),
        (
            "appended base64, zlib, two streams per array",
            Encoding {
                data: DataMode::AppendedBase64,
                compression: Compression::ZlibStored { block: 64 },
                split_base64: true,
                ..PLAIN
            },
        ),
        (
            "appended base64, big-endian, UInt64 header",
            Encoding {
                data: DataMode::AppendedBase64,
                big_endian: true,
                header64: true,
                ..PLAIN
            },
        ),
    ]
}

/// The writer appends every array as raw binary in VTK's zlib blocks (ParaView's own
/// format; meshio 5.3 reads the simulation's fe_result.vtu back) and the reader gives
/// back exactly what was written: Float64 values bit for bit.
#[test]
fn written_files_hold_compressed_appended_arrays_that_read_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mesh, point_data, cell_data) = rich_content();
    let path = dir.path().join("written.vtu");
    write_vtu(&path, &mesh, &point_data, &cell_data).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let xml_end = find(&bytes, b"<AppendedData encoding=\"raw\">");
    let xml = String::from_utf8_lossy(&bytes[..xml_end]);
    assert!(
        xml.contains("compressor=\"vtkZLibDataCompressor\""),
        "{xml}"
    );
    assert!(xml.contains("header_type=\"UInt64\""), "{xml}");
    assert!(!xml.contains("format=\"ascii\""), "{xml}");
    let arrays = point_data.len() + cell_data.len() + 4;
    assert_eq!(xml.matches("format=\"appended\"").count(), arrays, "{xml}");
    let read = read_vtu(&path).unwrap();
    assert_eq!(read.mesh, mesh);
    assert_eq!(read.point_data, point_data);
    assert_eq!(read.cell_data, cell_data);
}

#[test]
fn every_binary_encoding_reads_as_the_written_file() {
    let dir = tempfile::tempdir().unwrap();
    let (content, mesh, point_data, cell_data) = rich_content();
    let written = dir.path().join("written.vtu");
    write_vtu(&written, &mesh, &point_data, &cell_data).unwrap();
    let twin = read_vtu(&written).unwrap();
    assert_eq!(twin.mesh, mesh);
    assert_eq!(twin.point_data, point_data);
    for (k, (label, encoding)) in encodings().into_iter().enumerate() {
        let path = dir.path().join(format!("binary{k}.vtu"));
        std::fs::write(&path, vtu_bytes(&content, &encoding, &no_tamper)).unwrap();
        let read = read_vtu(&path).unwrap_or_else(|e| panic!("{label}: {e}"));
        assert_eq!(read, twin, "{label}");
    }
}

/// The error message of reading `bytes` as a file.
fn read_error(dir: &Path, bytes: &[u8]) -> String {
    let path = dir.join("bad.vtu");
    std::fs::write(&path, bytes).unwrap();
    error_text(read_vtu(&path))
}

/// Asserts that `text` names the file and contains every one of `parts` (`a|b`: either
/// `a` or `b`).
fn assert_mentions(text: &str, parts: &[&str]) {
    assert!(text.contains("bad.vtu"), "{text}");
    for part in parts {
        assert!(
            part.split('|').any(|p| text.contains(p)),
            "expected {part:?} in: {text}"
        );
    }
}

/// Position of `needle` in `haystack`, which must hold it.
fn find(haystack: &[u8], needle: &[u8]) -> usize {
    haystack
        .windows(needle.len())
        .position(|w| w == needle)
        .expect("present")
}

fn set_word(header: &mut [u8], k: usize, value: u32) {
    header[4 * k..4 * k + 4].copy_from_slice(&value.to_le_bytes());
}

#[test]
fn corrupt_blocks_are_reported_with_the_array_and_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let (content, ..) = rich_content();
    let only = |name: &'static str, f: fn(&mut Vec<u8>, &mut Vec<u8>)| {
        move |array: &str, header: &mut Vec<u8>, data: &mut Vec<u8>| {
            if array == name {
                f(header, data);
            }
        }
    };
    let zlib = Encoding {
        compression: Compression::ZlibDeflate { block: 256 },
        split_base64: true,
        ..PLAIN
    };
    let cases: Vec<(Encoding, Box<TamperFn>, &[&str])> = vec![
        (
            PLAIN,
            Box::new(only("displacement", |h, _| {
                let n = u32::from_le_bytes(h[..4].try_into().unwrap());
                set_word(h, 0, n + 8);
            })),
            // In raw appended data the array reads on into the next one: its value count
            // is wrong then (the other encodings see the end of its data).
            &["\"displacement\"", "truncated|has 526 values, expected 525"],
        ),
        (
            PLAIN,
            Box::new(only("Int16", |h, d| {
                d.pop();
                set_word(h, 0, d.len() as u32);
            })),
            &["DataArray \"Int16\"", "not a whole number of Int16 values"],
        ),
        (
            PLAIN,
            Box::new(only("Float32", |h, _| {
                let n = u32::from_le_bytes(h[..4].try_into().unwrap());
                set_word(h, 0, n - 4);
            })),
            &["\"Float32\"", "4 bytes follow|has 174 values, expected 175"],
        ),
        (
            zlib,
            Box::new(only("young_modulus", |h, _| set_word(h, 0, 1_000_000))),
            &["DataArray \"young_modulus\"", "1000000 blocks", "truncated"],
        ),
        (
            zlib,
            Box::new(only("young_modulus", |h, _| {
                // a larger block size than the blocks hold
                set_word(h, 1, 300);
            })),
            &[
                "DataArray \"young_modulus\"",
                "decompresses to",
                "announces 300",
            ],
        ),
        (
            zlib,
            Box::new(only("Points", |_, d| {
                // inside the first deflate stream, past its 2-byte zlib header
                for b in &mut d[2..40] {
                    *b ^= 0x5a;
                }
            })),
            &["DataArray \"Points\"", "compressed block 1 of"],
        ),
        (
            zlib,
            Box::new(only("connectivity", |_, d| {
                let n = d.len();
                d[n - 1] ^= 1; // the Adler-32 checksum of the last stream
            })),
            &["DataArray \"connectivity\"", "corrupt"],
        ),
        (
            zlib,
            // Raw appended data runs on into the blank before </AppendedData>: the
            // stream is corrupt rather than short there.
            Box::new(only("types", |_, d| d.truncate(d.len() - 3))),
            &[
                "DataArray \"types\"",
                "truncated|corrupt",
                "compressed block 3 of 3",
            ],
        ),
        (
            zlib,
            Box::new(only("region", |h, _| set_word(h, 2, 999))),
            &[
                "DataArray \"region\"",
                "last block size 999 exceeds block size 256",
            ],
        ),
    ];
    for (encoding, tamper, parts) in &cases {
        for data in [
            DataMode::Inline,
            DataMode::AppendedRaw,
            DataMode::AppendedBase64,
        ] {
            let e = Encoding { data, ..*encoding };
            let text = read_error(dir.path(), &vtu_bytes(&content, &e, tamper.as_ref()));
            assert_mentions(&text, parts);
            assert!(text.contains(", line "), "{text}");
        }
    }
}

#[test]
fn damaged_base64_and_missing_appended_data_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let (content, ..) = rich_content();
    let inline = String::from_utf8(vtu_bytes(&content, &PLAIN, &no_tamper)).unwrap();
    // The base64 text of the displacement is the line after its start tag.
    let start = inline.find("Name=\"displacement\"").unwrap();
    let line_start = start + inline[start..].find('\n').unwrap() + 1;
    let line_end = line_start + inline[line_start..].find('\n').unwrap();
    let damage = |f: &dyn Fn(&str) -> String| {
        format!(
            "{}{}{}",
            &inline[..line_start],
            f(&inline[line_start..line_end]),
            &inline[line_end..]
        )
    };
    let cut = damage(&|t| t[..t.len() - 4].to_string());
    assert_mentions(
        &read_error(dir.path(), cut.as_bytes()),
        &["DataArray \"displacement\"", "truncated"],
    );
    let odd = damage(&|t| t[..t.len() - 1].to_string());
    assert_mentions(
        &read_error(dir.path(), odd.as_bytes()),
        &["DataArray \"displacement\"", "not a multiple of 4"],
    );
    let star = damage(&|t| format!("{}*{}", &t[..20], &t[21..]));
    assert_mentions(
        &read_error(dir.path(), star.as_bytes()),
        &["DataArray \"displacement\"", "invalid base64"],
    );

    // Appended files cut short: within the last array, or before its offset.
    let raw = Encoding {
        data: DataMode::AppendedRaw,
        ..PLAIN
    };
    let file = vtu_bytes(&content, &raw, &no_tamper);
    let closing = b"\n  </AppendedData>\n</VTKFile>\n".len();
    let types = content.cells[2].values.len();
    assert_mentions(
        &read_error(dir.path(), &file[..file.len() - closing - types / 2]),
        &["DataArray \"types\"", "truncated"],
    );
    assert_mentions(
        &read_error(dir.path(), &file[..file.len() - closing - types - 4]),
        &[
            "DataArray \"types\"",
            "truncated",
            "cannot hold header word 1",
        ],
    );
    let types_tag = find(&file, b"Name=\"types\"");
    let offset_at = types_tag + find(&file[types_tag..], b"offset=\"") + 8;
    let mut far = file[..offset_at].to_vec();
    far.extend(b"99999999");
    far.extend(&file[offset_at + find(&file[offset_at..], b"\"")..]);
    assert_mentions(
        &read_error(dir.path(), &far),
        &["DataArray \"types\"", "offset 99999999 lies beyond"],
    );
    // Every cut inside the appended data is an error, never a panic or a wrong mesh.
    let data_start = find(&file, b"   _") + 4;
    let step = ((file.len() - data_start) / 300) | 1;
    for end in (data_start..file.len() - closing).step_by(step) {
        let path = dir.path().join("cut.vtu");
        std::fs::write(&path, &file[..end]).unwrap();
        assert!(read_vtu(&path).is_err(), "cut at {end} of {}", file.len());
    }

    // The reader takes files that are not text as a whole.
    assert!(std::str::from_utf8(&file).is_err());
    let no_marker = {
        let mut f = file.clone();
        let at = f.windows(4).position(|w| w == b"   _").unwrap() + 3;
        f[at] = b'x';
        f
    };
    assert_mentions(
        &read_error(dir.path(), &no_marker),
        &["must begin with '_'"],
    );
    let header_end = file
        .windows(13)
        .position(|w| w == b"<AppendedData")
        .unwrap();
    let mut no_data = file[..header_end].to_vec();
    no_data.extend(b"</VTKFile>\n");
    assert_mentions(
        &read_error(dir.path(), &no_data),
        &["DataArray \"Int8\"", "no <AppendedData>"],
    );
}

#[test]
fn unsupported_attributes_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let (content, ..) = rich_content();
    let inline = String::from_utf8(vtu_bytes(&content, &PLAIN, &no_tamper)).unwrap();
    let cases: [(&str, &str, &[&str]); 6] = [
        (
            "header_type=\"UInt32\"",
            "header_type=\"UInt16\"",
            &["header_type=\"UInt16\"", "\"UInt64\""],
        ),
        (
            "byte_order=\"LittleEndian\"",
            "byte_order=\"Middle\"",
            &["byte_order=\"Middle\""],
        ),
        (
            "header_type=\"UInt32\"",
            "header_type=\"UInt32\" compressor=\"vtkLZ4DataCompressor\"",
            &["vtkLZ4DataCompressor", "not supported"],
        ),
        (
            "type=\"Float64\" Name=\"displacement\"",
            "type=\"String\" Name=\"displacement\"",
            &["DataArray \"displacement\"", "type \"String\""],
        ),
        (
            "Name=\"displacement\" NumberOfComponents=\"3\" format=\"binary\"",
            "Name=\"displacement\" NumberOfComponents=\"3\" format=\"hex\"",
            &["DataArray \"displacement\"", "format \"hex\""],
        ),
        (
            "Name=\"displacement\" NumberOfComponents=\"3\" format=\"binary\"",
            "Name=\"displacement\" NumberOfComponents=\"3\" format=\"appended\"",
            &["DataArray \"displacement\"", "no offset"],
        ),
    ];
    for (from, to, parts) in cases {
        assert!(inline.contains(from), "{from}");
        let text = read_error(dir.path(), inline.replacen(from, to, 1).as_bytes());
        assert_mentions(&text, parts);
    }
}

#[test]
fn flipped_bytes_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let (content, ..) = rich_content();
    let path = dir.path().join("flipped.vtu");
    for e in [
        Encoding {
            data: DataMode::AppendedRaw,
            compression: Compression::ZlibDeflate { block: 128 },
            ..PLAIN
        },
        Encoding {
            data: DataMode::AppendedRaw,
            header64: true,
            ..PLAIN
        },
    ] {
        let file = vtu_bytes(&content, &e, &no_tamper);
        let start = file.windows(4).position(|w| w == b"   _").unwrap();
        // About 300 positions per file (writing a file takes milliseconds here).
        let step = ((file.len() - start) / 300) | 1;
        for at in (start..file.len()).step_by(step) {
            let mut f = file.clone();
            f[at] ^= 0xa5;
            std::fs::write(&path, &f).unwrap();
            // Either an error or a mesh; what matters is no panic and no huge allocation.
            let _ = read_vtu(&path);
        }
    }
}

/// `vtkXMLUnstructuredGridWriter` of VTK 9.7.2 (Python wheel), inline binary data
/// compressed with zlib: header and data are separate base64 streams.
const VTK_INLINE_ZLIB: &str = r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian" header_type="UInt32" compressor="vtkZLibDataCompressor">
  <UnstructuredGrid>
    <Piece NumberOfPoints="5" NumberOfCells="2">
      <PointData>
        <DataArray type="Float32" Name="f32" format="binary" RangeMin="-2.25" RangeMax="3">
          AQAAAACAAAAUAAAAGgAAAA==eF5jYGCwZ2A4AMQCBxgYHBzyhZqtAB9IA80=
        </DataArray>
        <DataArray type="Float64" Name="displacement" NumberOfComponents="3" format="binary" RangeMin="0.3333333333333333" RangeMax="0.9545214042184236">
          AQAAAACAAAB4AAAAMQAAAA==eF5jYEABDaFgcNV+1kwQ2AmlT+5HFT8JpW/CxU2MQeAylH6Mpv4mlH4JFwcAiuAyXw==
          <InformationKey name="L2_NORM_RANGE" location="vtkDataArray" length="2">
            <Value index="0">
              0.33333333333
            </Value>
            <Value index="1">
              0.95452140422
            </Value>
          </InformationKey>
        </DataArray>
      </PointData>
      <CellData>
        <DataArray type="Int32" Name="i32" format="binary" RangeMin="-7" RangeMax="123456">
          AQAAAACAAAAIAAAAEAAAAA==eF77+f//f4dHjAwAHWYFGg==
        </DataArray>
      </CellData>
      <Points>
        <DataArray type="Float64" Name="Points" NumberOfComponents="3" format="binary" RangeMin="0" RangeMax="1.7320508075688772">
          AQAAAACAAAB4AAAAFAAAAA==eF5jYMAHPtjjlSZaHpMGAPByBxs=
          <InformationKey name="L2_NORM_RANGE" location="vtkDataArray" length="2">
            <Value index="0">
              0
            </Value>
            <Value index="1">
              1.7320508076
            </Value>
          </InformationKey>
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="binary" RangeMin="0" RangeMax="4">
          AQAAAACAAABAAAAAFgAAAA==eF5jYIAARijNBKWZCYizQGkAAfAAEQ==
        </DataArray>
        <DataArray type="Int64" Name="offsets" format="binary" RangeMin="4" RangeMax="8">
          AQAAAACAAAAQAAAADgAAAA==eF5jYYAADigNAACQAA0=
        </DataArray>
        <DataArray type="UInt8" Name="types" format="binary" RangeMin="10" RangeMax="10">
          AQAAAACAAAACAAAACgAAAA==eF7j4gIAACAAFQ==
        </DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"#;
/// The same grid as [`VTK_INLINE_ZLIB`], written by VTK 9.7.2 as appended raw data,
/// big-endian, zlib-compressed: the XML up to the `_` marker, then the data in hex.
const VTK_APPENDED_RAW_XML: &str = r#"<VTKFile type="UnstructuredGrid" version="0.1" byte_order="BigEndian" header_type="UInt32" compressor="vtkZLibDataCompressor">
  <UnstructuredGrid>
    <Piece NumberOfPoints="5"                    NumberOfCells="2"                   >
      <PointData>
        <DataArray type="Float32" Name="f32" format="appended" RangeMin="-2.25"                RangeMax="3"                    offset="0"                   >
        </DataArray>
        <DataArray type="Float64" Name="displacement" NumberOfComponents="3" format="appended" RangeMin="0.33333333333"        RangeMax="0.95452140422"        offset="44"                  >
          <InformationKey name="L2_NORM_RANGE" location="vtkDataArray" length="2">
            <Value index="0">
              0.33333333333
            </Value>
            <Value index="1">
              0.95452140422
            </Value>
          </InformationKey>
        </DataArray>
      </PointData>
      <CellData>
        <DataArray type="Int32" Name="i32" format="appended" RangeMin="-7"                   RangeMax="123456"               offset="113"                 >
        </DataArray>
      </CellData>
      <Points>
        <DataArray type="Float64" Name="Points" NumberOfComponents="3" format="appended" RangeMin="0"                    RangeMax="1.7320508076"         offset="145"                 >
          <InformationKey name="L2_NORM_RANGE" location="vtkDataArray" length="2">
            <Value index="0">
              0
            </Value>
            <Value index="1">
              1.7320508076
            </Value>
          </InformationKey>
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="appended" RangeMin=""                     RangeMax=""                     offset="181"                 />
        <DataArray type="Int64" Name="offsets" format="appended" RangeMin=""                     RangeMax=""                     offset="218"                 />
        <DataArray type="UInt8" Name="types" format="appended" RangeMin=""                     RangeMax=""                     offset="250"                 >
        </DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
  <AppendedData encoding="raw">
   _"#;
const VTK_APPENDED_RAW_HEX: &str = "\
    0000000100008000000000140000001c785eb3676060b03fc0c070408081c1c18181c1aa59281f0024a403cd00000001\
    000080000000007800000035785e6360808006286d7f35140cec77ce048159fb4f4268b83894bfff269af865631030d9\
    ff1842c3c5a1eaf6bf44550f00a4aa325f00000001000080000000000800000010785efbffffff4f06c6470e001bd705\
    1a00000001000080000000007800000014785e6360c00eec3fe09020511e170d0016f7071b0000000100008000000000\
    4000000015785e636040018c509a094a3313106701000180001100000001000080000000001000000010785e63600003\
    1608c5c00100003c000d0000000100008000000000020000000a785ee3e20200002000150a2020\
";

fn vtk_reference(dir: &Path, name: &str, bytes: &[u8]) -> tetra::vtu::VtuData {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    read_vtu(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn files_written_by_vtk_read_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let hex = VTK_APPENDED_RAW_HEX.as_bytes();
    let raw_data: Vec<u8> = (0..hex.len() / 2)
        .map(|k| {
            u8::from_str_radix(std::str::from_utf8(&hex[2 * k..2 * k + 2]).unwrap(), 16).unwrap()
        })
        .collect();
    let mut raw = VTK_APPENDED_RAW_XML.as_bytes().to_vec();
    raw.extend(raw_data);
    raw.extend(b"</AppendedData>\n</VTKFile>\n");
    let inline = vtk_reference(dir.path(), "inline.vtu", VTK_INLINE_ZLIB.as_bytes());
    let appended = vtk_reference(dir.path(), "appended.vtu", &raw);
    assert_eq!(inline, appended);
    // What the Python script gave VTK.
    let positions = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
    ];
    assert_eq!(
        inline.mesh.positions,
        positions.map(DVec3::from_array).to_vec()
    );
    assert_eq!(inline.mesh.tets, vec![[0, 1, 2, 3], [1, 2, 3, 4]]);
    let f32_values = [0.5f32, 1.5, -2.25, 3.0, 1e-3].map(f64::from).to_vec();
    assert_eq!(inline.point_data[0], Field::scalars("f32", f32_values));
    let displacement = (0..5)
        .map(|i| DVec3::new(0.1 * i as f64, -0.2 * i as f64, 1.0 / 3.0))
        .collect();
    assert_eq!(
        inline.point_data[1],
        Field::vectors("displacement", displacement)
    );
    assert_eq!(
        inline.cell_data,
        vec![Field::scalars("i32", vec![-7.0, 123456.0])]
    );
}
