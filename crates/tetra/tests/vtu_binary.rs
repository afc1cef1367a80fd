//! Binary, appended and zlib-compressed VTU files built byte by byte from the format
//! specification (every encoding, byte order and header type) read as written, and
//! damaged binary data reported, never a panic.

mod common;

use common::vtu::*;
use std::path::Path;
use tetra::vtu::{read_vtu, write_vtu};

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
