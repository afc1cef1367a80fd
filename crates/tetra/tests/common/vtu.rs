//! What the VTU tests share: a small stuffed mesh, files written into a folder, error
//! text, and binary, appended and compressed files built byte by byte from the VTK file
//! format specification ("VTK File Formats", XML section: binary data blocks, appended
//! data, compression header), independently of the reader.

use glam::DVec3;
use std::path::{Path, PathBuf};
use tetra::vtu::Field;
use tetra::{ClosedSurface, TetMesh, TetMeshError, stuff};

pub fn small_mesh() -> TetMesh {
    let surface = ClosedSurface::new(&mesh::shapes::icosphere(10.0, 2)).unwrap();
    stuff(&surface, 4.0).unwrap()
}

pub fn write_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

pub fn error_text(result: Result<impl std::fmt::Debug, TetMeshError>) -> String {
    result.expect_err("expected an error").to_string()
}

/// A data array to write: values, VTK type and components.
pub struct Array {
    pub name: &'static str,
    pub vtk_type: &'static str,
    pub components: usize,
    pub values: Vec<f64>,
}

/// The arrays of a file: field data (not part of the mesh), point and cell data, the
/// points, and the three cell arrays.
pub struct Content {
    pub field: Vec<Array>,
    pub point: Vec<Array>,
    pub cell: Vec<Array>,
    pub points: Array,
    pub cells: [Array; 3],
}

/// Where the array data goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DataMode {
    /// `format="binary"`, base64 inside the element.
    Inline,
    /// `<AppendedData encoding="raw">`.
    AppendedRaw,
    /// `<AppendedData encoding="base64">`.
    AppendedBase64,
}

/// How each array's bytes are packed into a block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Compression {
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
pub struct Encoding {
    pub data: DataMode,
    pub compression: Compression,
    pub header64: bool,
    pub big_endian: bool,
    /// Base64 of the header and the data as two padded streams (VTK does so when
    /// compressing) rather than one.
    pub split_base64: bool,
    /// A full last compression block recorded with its size (as meshio writes it) rather
    /// than 0 (as VTK writes it).
    pub full_last_block_size: bool,
}

pub const PLAIN: Encoding = Encoding {
    data: DataMode::Inline,
    compression: Compression::None,
    header64: false,
    big_endian: false,
    split_base64: false,
    full_last_block_size: false,
};

/// Changes an array's block before it is encoded: `(array name, header, data)`.
pub type TamperFn = dyn Fn(&str, &mut Vec<u8>, &mut Vec<u8>);
pub type Tamper<'a> = &'a TamperFn;

pub fn no_tamper(_: &str, _: &mut Vec<u8>, _: &mut Vec<u8>) {}

/// Base64 (RFC 4648, standard alphabet, `=` padding).
pub fn base64(bytes: &[u8]) -> String {
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
pub fn adler32(bytes: &[u8]) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    for &x in bytes {
        a = (a + x as u32) % 65521;
        b = (b + a) % 65521;
    }
    (b << 16) | a
}

/// A zlib stream (RFC 1950) of stored deflate blocks (RFC 1951, BTYPE 00).
pub fn zlib_stored(bytes: &[u8]) -> Vec<u8> {
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

pub fn zlib_deflate(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write as _;
    let mut encoder = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

/// The values of `array` packed as its VTK type in the byte order.
pub fn pack(array: &Array, big_endian: bool) -> Vec<u8> {
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
pub fn word(x: usize, e: &Encoding) -> Vec<u8> {
    match (e.header64, e.big_endian) {
        (true, false) => (x as u64).to_le_bytes().to_vec(),
        (true, true) => (x as u64).to_be_bytes().to_vec(),
        (false, false) => u32::try_from(x).unwrap().to_le_bytes().to_vec(),
        (false, true) => u32::try_from(x).unwrap().to_be_bytes().to_vec(),
    }
}

/// A zlib compressor of one block.
pub type Compressor = fn(&[u8]) -> Vec<u8>;

/// One binary block `(header, data)`: uncompressed, the header is the byte count;
/// compressed, `[blocks, block size, last block size, compressed sizes...]` and the
/// concatenated zlib streams of the blocks.
pub fn block(bytes: &[u8], e: &Encoding) -> (Vec<u8>, Vec<u8>) {
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
pub fn vtu_bytes(content: &Content, e: &Encoding, tamper: Tamper) -> Vec<u8> {
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

pub const SCALAR_TYPES: [&str; 10] = [
    "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64", "Float32", "Float64",
];

/// A stuffed sphere with one point data array of every numeric type, vectors in Float32
/// and Float64, and cell data; each value exactly representable in its type.
pub fn rich_content() -> (Content, TetMesh, Vec<Field>, Vec<Field>) {
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
pub fn encodings() -> Vec<(&'static str, Encoding)> {
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
