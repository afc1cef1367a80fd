//! Mesh file reading errors: every error case names the file's problem and its line, and
//! damaged files never panic.

mod common;

use common::*;
use mesh::io::{
    PlyEncoding, read_mesh, read_obj, read_ply, read_stl, write_obj, write_ply, write_stl,
};
use mesh::{DVec2, MaterialLayer, MeshError, TriMesh, UvLayer, shapes};

/// Asserts a parse error on `line` whose message contains every one of `words`.
#[track_caller]
fn assert_parse_error(result: Result<TriMesh, MeshError>, line: Option<usize>, words: &[&str]) {
    assert!(result.is_err(), "expected an error, got {result:?}");
    let error = result.unwrap_err();
    let text = error.to_string();
    let MeshError::Parse {
        line: found_line, ..
    } = &error
    else {
        panic!("expected a parse error, got {error:?}");
    };
    assert_eq!(*found_line, line, "wrong line in '{text}'");
    if let Some(line) = line {
        assert!(text.contains(&format!("line {line}")), "'{text}'");
    }
    for word in words {
        assert!(text.contains(word), "'{text}' does not contain '{word}'");
    }
}

const TRIANGLE_HEADER: &str = "ply
format ascii 1.0
element vertex 3
property float x
property float y
property float z
element face 1
property list uchar int vertex_indices
end_header
";

/// Reads `text` as a PLY file.
fn read_ply_text(text: &str) -> Result<TriMesh, MeshError> {
    let dir = tempfile::tempdir().unwrap();
    read_ply(&write_file(dir.path(), "test.ply", text))
}

fn read_obj_text(text: &str) -> Result<TriMesh, MeshError> {
    let dir = tempfile::tempdir().unwrap();
    read_obj(&write_file(dir.path(), "test.obj", text))
}

fn read_stl_bytes(bytes: &[u8]) -> Result<TriMesh, MeshError> {
    let dir = tempfile::tempdir().unwrap();
    read_stl(&write_file(dir.path(), "test.stl", bytes))
}

#[test]
fn truncated_binary_ply_names_the_element_and_count() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("grid.ply");
    let mesh = shapes::grid(10, 10, 1.0); // 121 vertices, 200 faces
    write_ply(&path, &mesh, PlyEncoding::BinaryLittleEndian).unwrap();
    let data = std::fs::read(&path).unwrap();

    // Each face is 13 bytes (uchar count, 3 ints): cutting 20 leaves 198 whole faces.
    std::fs::write(&path, &data[..data.len() - 20]).unwrap();
    assert_parse_error(
        read_ply(&path),
        None,
        &["file ends after 198 of 200 faces (truncated?)"],
    );

    // Each vertex is 24 bytes (3 doubles).
    let header = data.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    std::fs::write(&path, &data[..header + 24 * 50 + 7]).unwrap();
    assert_parse_error(
        read_ply(&path),
        None,
        &["file ends after 50 of 121 vertices (truncated?)"],
    );
}

#[test]
fn truncated_ascii_ply_names_the_element_and_line() {
    let text = TRIANGLE_HEADER.replace("vertex 3", "vertex 4") + "0 0 0\n1 0 0\n";
    assert_parse_error(
        read_ply_text(&text),
        Some(11),
        &["file ends after 2 of 4 vertices", "truncated"],
    );
    let text = format!("{TRIANGLE_HEADER}0 0 0\n1 0 0\n0 1 0\n");
    assert_parse_error(
        read_ply_text(&text),
        Some(12),
        &["file ends after 0 of 1 faces"],
    );
    let text = format!("{TRIANGLE_HEADER}0 0 0\n1 0 0\n0 1 0\n3 0 1\n");
    assert_parse_error(
        read_ply_text(&text),
        Some(13),
        &["face 0", "fewer values than the header declares"],
    );
}

#[test]
fn bad_ply_values_are_reported_with_their_line() {
    let cases: [(&str, usize, &[&str]); 7] = [
        (
            "0 0 0\n1 abc 0\n0 1 0\n3 0 1 2\n",
            11,
            &["vertex 1", "'abc' is not a number"],
        ),
        (
            "0 0 0\n1 0 0 4\n0 1 0\n3 0 1 2\n",
            11,
            &["vertex 1", "more values"],
        ),
        (
            "0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n",
            11,
            &["vertex 1", "non-finite"],
        ),
        (
            "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
            13,
            &["face 0 refers to vertex 7 but the file has only 3 vertices"],
        ),
        (
            "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
            13,
            &["face 0", "invalid vertex index -1"],
        ),
        (
            "0 0 0\n1 0 0\n0 1 0\n2 0 1\n",
            13,
            &["face 0 has 2 vertices", "at least 3"],
        ),
        (
            "0 0 0\n1 0 0\n0 1 0\n1.5 0 1\n",
            13,
            &["face 0", "invalid length 1.5"],
        ),
    ];
    for (body, line, words) in cases {
        assert_parse_error(
            read_ply_text(&format!("{TRIANGLE_HEADER}{body}")),
            Some(line),
            words,
        );
    }
}

#[test]
fn bad_ply_headers_are_reported() {
    let body = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let cases: [(String, Option<usize>, &[&str]); 8] = [
        (String::new(), Some(1), &["not a PLY file"]),
        (
            TRIANGLE_HEADER.replace("ply\n", "plx\n"),
            Some(1),
            &["not a PLY file"],
        ),
        (
            TRIANGLE_HEADER.replace("float y", "float16 y"),
            Some(5),
            &["unknown property type 'float16'"],
        ),
        (
            TRIANGLE_HEADER.replace("ascii", "binary_middle_endian"),
            Some(2),
            &["unknown format 'binary_middle_endian'"],
        ),
        (
            TRIANGLE_HEADER.replace("format ascii 1.0\n", ""),
            None,
            &["no 'format' line"],
        ),
        (
            TRIANGLE_HEADER.replace("vertex 3", "vertex three"),
            Some(3),
            &["'three' is not a count"],
        ),
        (
            TRIANGLE_HEADER.replace("property float y", "property float"),
            Some(5),
            &["expected 'property <type> <name>'"],
        ),
        (
            TRIANGLE_HEADER.replace("property float z", "property float w"),
            None,
            &["no scalar property 'z'"],
        ),
    ];
    for (header, line, words) in cases {
        assert_parse_error(read_ply_text(&(header + body)), line, words);
    }
    assert_parse_error(
        read_ply_text(&TRIANGLE_HEADER.replace("end_header\n", "")),
        None,
        &["the header ends after 8 lines without 'end_header' (truncated?)"],
    );
}

#[test]
fn bad_obj_lines_are_reported_with_their_line() {
    let vertices = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n";
    let cases: [(&str, usize, &[&str]); 10] = [
        (
            "f 1 2 12\n",
            5,
            &["face refers to vertex 12 but only 3 vertices are defined"],
        ),
        (
            "f 1 2 -4\n",
            5,
            &["face refers to vertex -4 but only 3 vertices are defined"],
        ),
        (
            "f 1/1 2/2 3/1\n",
            5,
            &["texture coordinate 2 but only 1 texture coordinates are defined"],
        ),
        ("f 1//1 2//1 3//1\n", 5, &["normal 1 but only 0 normals"]),
        ("f 0 1 2\n", 5, &["index 0 is invalid"]),
        ("f 1 2\n", 5, &["face has 2 vertices", "at least 3"]),
        ("f 1/1 2 3/1\n", 5, &["some corners", "texture coordinates"]),
        ("f 1 2 x\n", 5, &["'x' is not a vertex index"]),
        ("\n\nv 1 2 abc\n", 7, &["'abc' is not a number"]),
        ("v 1 2\n", 5, &["a vertex needs", "found 2 values"]),
    ];
    for (tail, line, words) in cases {
        assert_parse_error(
            read_obj_text(&format!("{vertices}{tail}")),
            Some(line),
            words,
        );
    }
    assert_parse_error(
        read_obj_text("v 1 2 nan\n"),
        Some(1),
        &["vertex 1: non-finite coordinate"],
    );
    // a finite coordinate far beyond any body (its squared distances overflow)
    assert_parse_error(
        read_obj_text("v 1 2 3e300\n"),
        Some(1),
        &[
            "vertex 1: a coordinate of 3.000e300 mm",
            "more than a kilometre",
        ],
    );
    assert_parse_error(
        read_obj_text("usemtl\n"),
        Some(1),
        &["usemtl needs a material name"],
    );
    assert_parse_error(
        read_obj_text("v 1 2 3 \\\n 4 5\n f 1 2 3\n"),
        Some(1),
        &["found 5 values"],
    );
}

#[test]
fn garbage_and_empty_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let garbage: Vec<u8> = (0..1000u32).map(|i| (i * 7919 % 251) as u8).collect();
    for name in ["garbage.ply", "garbage.obj", "garbage.stl"] {
        let path = write_file(dir.path(), name, &garbage);
        assert!(read_mesh(&path).is_err(), "{name}");
    }
    for name in ["empty.ply", "empty.obj", "empty.stl"] {
        let path = write_file(dir.path(), name, "");
        let error = read_mesh(&path).unwrap_err().to_string();
        assert!(error.contains(name), "{error}");
    }
    let path = write_file(dir.path(), "empty.obj", "# nothing\n");
    assert!(
        read_mesh(&path)
            .unwrap_err()
            .to_string()
            .contains("no triangles")
    );
    assert!(matches!(
        read_mesh(&dir.path().join("missing.ply")),
        Err(MeshError::Io { .. })
    ));
}

#[test]
fn bad_stl_files_are_reported() {
    let mut binary = vec![0u8; 80];
    binary.extend(2u32.to_le_bytes());
    binary.extend(stl_facet([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]));
    binary.extend(stl_facet([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]));
    assert!(read_stl_bytes(&binary).is_ok());
    assert_parse_error(
        read_stl_bytes(&binary[..binary.len() - 10]),
        None,
        &[
            "announces 2 triangles (184 bytes)",
            "174 bytes",
            "truncated",
        ],
    );
    binary[96..100].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_parse_error(read_stl_bytes(&binary), None, &["facet 0", "non-finite"]);

    assert_parse_error(read_stl_bytes(b"hello"), None, &["not an STL file"]);
    let facet = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n";
    assert_parse_error(
        read_stl_bytes(format!("solid x\n{facet}vertex 0 1 0\nendloop\n").as_bytes()),
        Some(7),
        &["file ends after 1 facets without 'endsolid' (truncated?)"],
    );
    assert_parse_error(
        read_stl_bytes(format!("solid x\n{facet}endloop\nendfacet\nendsolid\n").as_bytes()),
        Some(6),
        &["facet 0 has 2 vertices (expected 3)"],
    );
    assert_parse_error(
        read_stl_bytes(format!("solid x\n{facet}vertex 0 1\n").as_bytes()),
        Some(6),
        &["exactly 3 coordinates"],
    );
    assert_parse_error(
        read_stl_bytes(b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 zero\n"),
        Some(4),
        &["'zero' is not a number"],
    );
}

/// Every prefix and many single-byte corruptions of small valid files: readers return
/// an error or a mesh, never panic.
#[test]
fn readers_never_panic_on_damaged_files() {
    let dir = tempfile::tempdir().unwrap();
    let small = {
        let mut small = shapes::cube(3.0);
        small.vertex_colors = Some(vec![[1, 2, 3]; 8]);
        small.uv = Some(UvLayer {
            coords: vec![DVec2::new(0.5, 0.25); 8],
            triangles: small.triangles.clone(),
        });
        small
    };
    let mut files = Vec::new();
    for encoding in [
        PlyEncoding::Ascii,
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
    ] {
        let path = dir.path().join(format!("{encoding:?}.ply"));
        write_ply(&path, &small, encoding).unwrap();
        files.push(path);
    }
    let mut obj = small.clone();
    obj.uv = Some(UvLayer {
        coords: (0..36).map(|i| DVec2::new(i as f64, 0.5)).collect(),
        triangles: (0..12).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
    });
    obj.materials = Some(MaterialLayer {
        libraries: vec!["a.mtl".into()],
        names: vec!["a".into(), "b".into()],
        triangle_material: (0..12).map(|t| Some(t % 2)).collect(),
    });
    let obj_path = dir.path().join("cube.obj");
    write_obj(&obj_path, &obj).unwrap();
    let stl_path = dir.path().join("cube.stl");
    write_stl(&stl_path, &small).unwrap();
    files.extend([obj_path, stl_path]);

    for path in files {
        let data = std::fs::read(&path).unwrap();
        let damaged = dir.path().join(format!(
            "damaged.{}",
            path.extension().unwrap().to_str().unwrap()
        ));
        let mut variants: Vec<Vec<u8>> = (0..data.len()).map(|n| data[..n].to_vec()).collect();
        for i in (0..data.len()).step_by(7) {
            for byte in [0u8, b'9', b'-', b' ', b'\n', 0xff, b'/'] {
                let mut corrupt = data.clone();
                corrupt[i] = byte;
                variants.push(corrupt);
            }
        }
        for variant in variants {
            std::fs::write(&damaged, &variant).unwrap();
            let _ = read_mesh(&damaged);
        }
    }
}
