//! Mesh file I/O: round-trips for every format and PLY encoding, hand-written files for
//! every feature the readers support, every error case, and the shared torso scans.

use mesh::io::{
    PlyEncoding, VertexScalar, read_mesh, read_obj, read_ply, read_ply_with_scalars, read_stl,
    write_mesh, write_obj, write_ply, write_ply_with_scalars, write_stl,
};
use mesh::{DVec2, DVec3, MaterialLayer, MeshError, TriMesh, UvLayer, shapes};
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------
// Helpers

fn write_file(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

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

/// An icosphere with awkward coordinates (not representable in few digits), per-vertex
/// colours and per-vertex texture coordinates.
fn decorated_sphere() -> TriMesh {
    let mut mesh = shapes::icosphere(57.3, 2);
    mesh.map_positions(|p| p + DVec3::new(0.1, 1e-7, 1_234.567_891_234));
    let colors = (0..mesh.vertex_count())
        .map(|v| [(v % 256) as u8, (v * 7 % 256) as u8, (v * 13 % 256) as u8])
        .collect();
    let coords = mesh
        .positions
        .iter()
        .map(|p| DVec2::new(p.x / 1000.0, p.y / 7.0))
        .collect();
    mesh.vertex_colors = Some(colors);
    mesh.uv = Some(UvLayer {
        coords,
        triangles: mesh.triangles.clone(),
    });
    mesh
}

/// Encodes `value` as PLY scalar type `ty`.
fn encode(ty: &str, value: f64, big_endian: bool) -> Vec<u8> {
    macro_rules! encode {
        ($t:ty) => {{
            let value = value as $t;
            if big_endian {
                value.to_be_bytes().to_vec()
            } else {
                value.to_le_bytes().to_vec()
            }
        }};
    }
    match ty {
        "char" | "int8" => encode!(i8),
        "uchar" | "uint8" => encode!(u8),
        "short" | "int16" => encode!(i16),
        "ushort" | "uint16" => encode!(u16),
        "int" | "int32" => encode!(i32),
        "uint" | "uint32" => encode!(u32),
        "float" | "float32" => encode!(f32),
        "double" | "float64" => encode!(f64),
        _ => panic!("unknown type {ty}"),
    }
}

/// A binary STL facet record with the given corners.
fn stl_facet(corners: [[f32; 3]; 3]) -> Vec<u8> {
    let mut record = Vec::new();
    for c in [[0.0; 3]].iter().chain(&corners).flatten() {
        record.extend(c.to_le_bytes());
    }
    record.extend([0, 0]);
    record
}

// ---------------------------------------------------------------------------------------
// Round trips

#[test]
fn ply_round_trip_in_every_encoding_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = decorated_sphere();
    for encoding in [
        PlyEncoding::Ascii,
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
    ] {
        let path = dir.path().join(format!("{encoding:?}.ply"));
        write_ply(&path, &mesh, encoding).unwrap();
        assert_eq!(read_ply(&path).unwrap(), mesh, "{encoding:?}");
    }
}

#[test]
fn ply_extra_vertex_scalars_round_trip_and_bad_ones_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = decorated_sphere();
    let distance: Vec<f64> = (0..mesh.vertex_count()).map(|v| v as f64 * 0.25).collect();
    // NaN marks "no value" (e.g. outside a comparison's overlap) and must survive.
    let signed: Vec<f64> = (0..mesh.vertex_count())
        .map(|v| if v % 7 == 0 { f64::NAN } else { -(v as f64) })
        .collect();
    let scalars = [
        VertexScalar {
            name: "distance_mm",
            values: &distance,
        },
        VertexScalar {
            name: "signed_distance_mm",
            values: &signed,
        },
    ];
    for encoding in [
        PlyEncoding::Ascii,
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
    ] {
        let path = dir.path().join(format!("scalars_{encoding:?}.ply"));
        write_ply_with_scalars(&path, &mesh, encoding, &scalars).unwrap();
        // Readers that do not ask for them see the mesh unchanged.
        assert_eq!(read_ply(&path).unwrap(), mesh, "{encoding:?}");
        let (read, values) =
            read_ply_with_scalars(&path, &["signed_distance_mm", "distance_mm"]).unwrap();
        assert_eq!(read, mesh);
        assert_eq!(values[1], distance, "{encoding:?}");
        for (read, written) in values[0].iter().zip(&signed) {
            assert!(read == written || (read.is_nan() && written.is_nan()));
        }
        let error = read_ply_with_scalars(&path, &["curvature"]).unwrap_err();
        assert!(
            error.to_string().contains("no scalar property 'curvature'"),
            "{error}"
        );
    }

    let path = dir.path().join("refused.ply");
    let short = [1.0, 2.0];
    for (bad, expected) in [
        (
            VertexScalar {
                name: "red",
                values: &distance,
            },
            "standard property",
        ),
        (
            VertexScalar {
                name: "two words",
                values: &distance,
            },
            "letters, digits",
        ),
        (
            VertexScalar {
                name: "distance_mm",
                values: &short,
            },
            "expected",
        ),
    ] {
        let error = write_ply_with_scalars(&path, &mesh, PlyEncoding::Ascii, &[bad]).unwrap_err();
        assert!(error.to_string().contains(expected), "{error}");
    }
    let twice = [scalars[0], scalars[0]];
    let error = write_ply_with_scalars(&path, &mesh, PlyEncoding::Ascii, &twice).unwrap_err();
    assert!(error.to_string().contains("given twice"), "{error}");
    assert!(!path.exists());
}

#[test]
fn ply_keeps_uv_without_seams_and_drops_uv_with_seams() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("uv.ply");

    // Per-vertex UVs under a different index buffer (each coordinate stored 3 times):
    // still one UV per vertex, so it is written.
    let mut mesh = shapes::grid(3, 2, 1.0);
    let per_corner = |mesh: &TriMesh, f: &dyn Fn(usize, usize) -> DVec2| {
        let coords = (0..mesh.triangle_count())
            .flat_map(|t| (0..3).map(move |k| (t, k)))
            .map(|(t, k)| f(t, k))
            .collect();
        let triangles = (0..mesh.triangle_count() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        UvLayer { coords, triangles }
    };
    let by_vertex = |t: usize, k: usize| {
        let p = mesh.positions[mesh.triangles[t][k] as usize];
        DVec2::new(p.x / 3.0, p.y / 2.0)
    };
    mesh.uv = Some(per_corner(&mesh, &by_vertex));
    write_ply(&path, &mesh, PlyEncoding::BinaryLittleEndian).unwrap();
    let read = read_ply(&path).unwrap();
    let uv = read.uv.expect("per-vertex UVs are written");
    assert_eq!(uv.triangles, read.triangles);
    for (t, triangle) in read.triangles.iter().enumerate() {
        for (k, &vertex) in triangle.iter().enumerate() {
            assert_eq!(uv.coords[vertex as usize], by_vertex(t, k));
        }
    }

    // A seam: one corner differs from the others of its vertex.
    let seamed = |t: usize, k: usize| DVec2::new(t as f64, k as f64);
    mesh.uv = Some(per_corner(&mesh, &seamed));
    write_ply(&path, &mesh, PlyEncoding::Ascii).unwrap();
    let read = read_ply(&path).unwrap();
    assert_eq!(read.uv, None);
    assert_eq!(read.triangles, mesh.triangles);
}

/// A sphere with seams everywhere (a UV per corner), materials and colours.
fn textured_sphere() -> TriMesh {
    let mut mesh = decorated_sphere();
    let count = mesh.triangle_count();
    mesh.uv = Some(UvLayer {
        coords: (0..3 * count)
            .map(|i| DVec2::new(i as f64 / 3.0, 1.0 / (i + 1) as f64))
            .collect(),
        triangles: (0..count as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect(),
    });
    mesh.materials = Some(MaterialLayer {
        libraries: vec!["skin.mtl".into(), "marks.mtl".into()],
        names: vec!["skin".into(), "areola left".into()],
        triangle_material: (0..count)
            .map(|t| match t {
                0..5 => None,
                _ if t % 40 < 30 => Some(0),
                _ => Some(1),
            })
            .collect(),
    });
    mesh
}

#[test]
fn obj_round_trip_is_exact_with_seams_colours_and_materials() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.obj");
    let mesh = textured_sphere();
    write_obj(&path, &mesh).unwrap();
    // Tolerance: none. Numbers are printed in the shortest form that parses back exactly.
    assert_eq!(read_obj(&path).unwrap(), mesh);
}

#[test]
fn stl_round_trip_keeps_triangles_and_shared_vertices_in_f32() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.stl");
    let mesh = decorated_sphere();
    write_stl(&path, &mesh).unwrap();
    let read = read_stl(&path).unwrap();
    assert_eq!(read.vertex_count(), mesh.vertex_count());
    assert_eq!(read.triangle_count(), mesh.triangle_count());
    for t in 0..mesh.triangle_count() {
        let expected = mesh.triangle_positions(t).map(|p| p.as_vec3().as_dvec3());
        assert_eq!(read.triangle_positions(t), expected, "triangle {t}");
    }
    assert!(read.validate().is_ok());
    assert_eq!(read.vertex_colors, None);
}

#[test]
fn read_and_write_mesh_choose_the_format_by_extension() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = shapes::cube(10.0);
    for name in ["cube.ply", "cube.OBJ", "cube.stl"] {
        let path = dir.path().join(name);
        write_mesh(&path, &mesh).unwrap();
        let read = read_mesh(&path).unwrap();
        assert_eq!(read.triangle_count(), 12, "{name}");
        assert_eq!(read.vertex_count(), 8, "{name}");
    }
    let ply = read_mesh(&dir.path().join("cube.ply")).unwrap();
    assert_eq!(ply, mesh);
    let text = std::fs::read_to_string(dir.path().join("cube.OBJ")).unwrap();
    assert!(text.contains("\nf 1 3 2\n"), "{text}");

    let path = dir.path().join("cube.off");
    assert!(matches!(
        write_mesh(&path, &mesh),
        Err(MeshError::UnsupportedFormat { .. })
    ));
    // Nothing but the three outputs is left behind (no temporary files).
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 3);
}

#[test]
fn writers_refuse_invalid_meshes() {
    let dir = tempfile::tempdir().unwrap();
    let mut mesh = shapes::cube(1.0);
    mesh.triangles[3] = [0, 1, 99];
    let path = dir.path().join("bad.ply");
    assert!(matches!(
        write_ply(&path, &mesh, PlyEncoding::Ascii),
        Err(MeshError::IndexOutOfRange { index: 99, .. })
    ));
    assert!(write_obj(&dir.path().join("bad.obj"), &mesh).is_err());
    assert!(write_stl(&dir.path().join("bad.stl"), &mesh).is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

// ---------------------------------------------------------------------------------------
// PLY features

#[test]
fn ascii_ply_skips_unknown_properties_and_elements() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_file(
        dir.path(),
        "features.ply",
        "ply\r
format ascii 1.0\r
comment made by hand\r
obj_info scanner 3\r
element vertex 4
property float x
property float y
property double z
property float nx
property list uchar int neighbours
property uchar red
property uchar green
property uchar blue
property uchar alpha
property float s
property float t
element material 2
property list uchar float coefficients
property int id
element face 2
property uchar flags
property list uchar int vertex_indices
property list uchar float texcoord
end_header
0 0 0.5 1 2 1 2 255 0 0 255 0 0
1 0 0.25 1 0 0 255 0 255 1 0

1.5 1 0 1 3 0 1 2 0 0 255 255 1 1
0 1 -1e3 1 1 0 10 20 30 255 0 1
3 0.5 0.25 0.125 7
0 8
0 4 0 1 2 3 0
9 3 1 3 2 6 0 0 1 0 1 1
",
    );
    let mesh = read_ply(&path).unwrap();
    assert_eq!(
        mesh.positions,
        [
            DVec3::new(0.0, 0.0, 0.5),
            DVec3::new(1.0, 0.0, 0.25),
            DVec3::new(1.5, 1.0, 0.0),
            DVec3::new(0.0, 1.0, -1000.0),
        ]
    );
    assert_eq!(mesh.triangles, [[0, 1, 2], [0, 2, 3], [1, 3, 2]]);
    assert_eq!(
        mesh.vertex_colors,
        Some(vec![[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]])
    );
    let uv = mesh.uv.unwrap();
    assert_eq!(uv.triangles, mesh.triangles);
    assert_eq!(
        uv.coords,
        [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 1.0),
        ]
    );
}

#[test]
fn ascii_ply_reads_float_colours_vertex_index_and_texture_u_v() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_file(
        dir.path(),
        "float_colours.ply",
        "ply
format ascii 1.0
element vertex 3
property float32 texture_u
property float32 texture_v
property float32 x
property float32 y
property float32 z
property float32 red
property float32 green
property float32 blue
element face 1
property list uint8 uint32 vertex_index
end_header
0.25 0.5 0 0 0 1 0.5 0
0.75 0.5 1 0 0 0 0 0
0.5 1 0 1 0 1.5 -1 0.2
3 2 1 0
",
    );
    let mesh = read_ply(&path).unwrap();
    assert_eq!(mesh.triangles, [[2, 1, 0]]);
    assert_eq!(
        mesh.vertex_colors,
        Some(vec![[255, 128, 0], [0, 0, 0], [255, 0, 51]])
    );
    assert_eq!(mesh.uv.unwrap().coords[2], DVec2::new(0.5, 1.0));
}

#[test]
fn big_endian_ply_with_unknown_list_element() {
    let dir = tempfile::tempdir().unwrap();
    let mut data = b"ply
format binary_big_endian 1.0
element vertex 4
property double x
property double y
property double z
property short quality
element edge 2
property list uchar int vertices
property uint id
element face 2
property list ushort uint vertex_indices
end_header
"
    .to_vec();
    let positions = [
        [0.1, 0.2, 0.3],
        [10.0, 0.0, -1e-9],
        [10.0, 10.0, 1234.5678],
        [0.0, 10.0, f64::MIN_POSITIVE],
    ];
    for (v, p) in positions.iter().enumerate() {
        for &c in p {
            data.extend(encode("double", c, true));
        }
        data.extend(encode("short", -(v as f64), true));
    }
    for edge in [[0.0, 1.0, 2.0], [2.0, 3.0, 0.0]] {
        data.extend(encode("uchar", 3.0, true));
        for index in edge {
            data.extend(encode("int", index, true));
        }
        data.extend(encode("uint", 77.0, true));
    }
    for face in [&[0.0, 1.0, 2.0, 3.0][..], &[3.0, 2.0, 1.0]] {
        data.extend(encode("ushort", face.len() as f64, true));
        for &index in face {
            data.extend(encode("uint", index, true));
        }
    }
    let path = write_file(dir.path(), "big.ply", data);
    let mesh = read_ply(&path).unwrap();
    let expected: Vec<DVec3> = positions.iter().map(|&p| DVec3::from_array(p)).collect();
    assert_eq!(mesh.positions, expected);
    assert_eq!(mesh.triangles, [[0, 1, 2], [0, 2, 3], [3, 2, 1]]);
    assert_eq!(mesh.vertex_colors, None);
    assert_eq!(mesh.uv, None);
}

#[test]
fn binary_ply_reads_every_list_count_and_index_type() {
    let dir = tempfile::tempdir().unwrap();
    let types = [
        ("uchar", "int"),
        ("uchar", "uint"),
        ("ushort", "uint"),
        ("uint", "ushort"),
        ("char", "short"),
        ("int", "uchar"),
        ("uint8", "int32"),
        ("int16", "uint16"),
    ];
    for (count_type, index_type) in types {
        let mut data = format!(
            "ply
format binary_little_endian 1.0
element vertex 5
property uchar x
property char y
property ushort z
element face 2
property uchar flags
property list {count_type} {index_type} vertex_indices
property list {index_type} {count_type} extra
end_header
"
        )
        .into_bytes();
        for v in 0..5 {
            data.extend(encode("uchar", v as f64, false));
            data.extend(encode("char", -(v as f64), false));
            data.extend(encode("ushort", 1000.0 + v as f64, false));
        }
        for face in [&[0.0, 1.0, 2.0, 3.0, 4.0][..], &[4.0, 3.0, 2.0]] {
            data.extend(encode("uchar", 1.0, false));
            data.extend(encode(count_type, face.len() as f64, false));
            for &index in face {
                data.extend(encode(index_type, index, false));
            }
            data.extend(encode(index_type, 2.0, false));
            data.extend(encode(count_type, 9.0, false));
            data.extend(encode(count_type, 9.0, false));
        }
        let path = write_file(dir.path(), &format!("{count_type}_{index_type}.ply"), data);
        let mesh = read_ply(&path).unwrap();
        assert_eq!(mesh.positions[3], DVec3::new(3.0, -3.0, 1003.0));
        assert_eq!(
            mesh.triangles,
            [[0, 1, 2], [0, 2, 3], [0, 3, 4], [4, 3, 2]],
            "list {count_type} {index_type}"
        );
    }
}

// ---------------------------------------------------------------------------------------
// OBJ features

#[test]
fn obj_reads_every_face_form_negative_indices_seams_and_materials() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_file(
        dir.path(),
        "features.obj",
        "# every feature
mtllib skin.mtl extra.mtl
o body
g front
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0 0 1.0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vt 0.5 0.5 0
vn 0 0 1
vp 0.5
s off
f 1 2 3 # no texture coordinates
usemtl skin
f 1/1 2/2 3/3 4/4
f 1//1 3//1 4//1
usemtl extra
f 2/5/1 5/5/1 3/3/1
usemtl skin
f -5/-5 -4/-4 \\
  -3/-3
l 1 2
p 1
unknownstatement 1 2 3
",
    );
    let mesh = read_obj(&path).unwrap();
    assert_eq!(mesh.vertex_count(), 5);
    assert_eq!(
        mesh.triangles,
        [
            [0, 1, 2],
            [0, 1, 2],
            [0, 2, 3],
            [0, 2, 3],
            [1, 4, 2],
            [0, 1, 2]
        ]
    );
    let uv = mesh.uv.unwrap();
    // Faces without texture coordinates use an appended (0, 0).
    assert_eq!(uv.coords.len(), 6);
    assert_eq!(uv.coords[4], DVec2::new(0.5, 0.5));
    assert_eq!(uv.coords[5], DVec2::ZERO);
    assert_eq!(
        uv.triangles,
        [
            [5, 5, 5],
            [0, 1, 2],
            [0, 2, 3],
            [5, 5, 5],
            [4, 4, 2],
            [0, 1, 2]
        ]
    );
    assert_eq!(
        mesh.materials,
        Some(MaterialLayer {
            libraries: vec!["skin.mtl".into(), "extra.mtl".into()],
            names: vec!["skin".into(), "extra".into()],
            triangle_material: vec![None, Some(0), Some(0), Some(0), Some(1), Some(0)],
        })
    );
    assert_eq!(mesh.vertex_colors, None);
}

#[test]
fn obj_reads_vertex_colours_and_fills_missing_ones_with_white() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_file(
        dir.path(),
        "colours.obj",
        "v 0 0 0\nv 1 0 0 1 0.5 0\nv 0 1 0 0 0 2\nf 1 2 3\n",
    );
    let mesh = read_obj(&path).unwrap();
    assert_eq!(
        mesh.vertex_colors,
        Some(vec![[255, 255, 255], [255, 128, 0], [0, 0, 255]])
    );
    assert_eq!(mesh.uv, None);
    assert_eq!(mesh.materials, None);
}

// ---------------------------------------------------------------------------------------
// STL features

#[test]
fn ascii_stl_merges_equal_corners() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_file(
        dir.path(),
        "square.stl",
        "solid square
  facet normal 0 0 1
    outer loop
      vertex 0 0 0
      vertex 1 0 0
      vertex 1 1 0
    endloop
  endfacet
  facet normal 0 0 1
    outer loop
      vertex -0 0 0
      vertex 1 1 0
      vertex 0 1.0 0e0
    endloop
  endfacet
  facet normal 0 0 0
    outer loop
      vertex 1 1 0
      vertex 1 1 0
      vertex 0 0 0
    endloop
  endfacet
endsolid square
solid second
  facet normal 0 0 1
    outer loop
      vertex 1 0 0
      vertex 2 0 0
      vertex 1 1 0
    endloop
  endfacet
endsolid
",
    );
    let mesh = read_stl(&path).unwrap();
    assert_eq!(
        mesh.positions,
        [
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::Y,
            DVec3::new(2.0, 0.0, 0.0),
        ]
    );
    // The degenerate third facet is dropped.
    assert_eq!(mesh.triangles, [[0, 1, 2], [0, 2, 3], [1, 4, 2]]);
    assert!(mesh.positions[0].x.is_sign_positive());
}

#[test]
fn binary_stl_whose_header_starts_with_solid() {
    let dir = tempfile::tempdir().unwrap();
    let mut data = b"solid exported by a scanner".to_vec();
    data.resize(80, b' ');
    data.extend(2u32.to_le_bytes());
    data.extend(stl_facet([
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
    ]));
    data.extend(stl_facet([
        [0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.5],
    ]));
    let path = write_file(dir.path(), "binary.stl", data);
    let mesh = read_stl(&path).unwrap();
    assert_eq!(mesh.vertex_count(), 4);
    assert_eq!(mesh.triangles, [[0, 1, 2], [0, 2, 3]]);
    assert_eq!(mesh.positions[3], DVec3::new(0.0, 1.0, 0.5));
}

// ---------------------------------------------------------------------------------------
// Errors

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

// ---------------------------------------------------------------------------------------
// Shared scans

#[test]
fn shared_scan_ply_and_obj_agree() {
    let scans = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/scans"
    ));
    if !scans.is_dir() {
        eprintln!("skipped: {} is missing", scans.display());
        return;
    }
    let ply = read_mesh(&scans.join("v02_average.ply")).unwrap();
    let obj = read_mesh(&scans.join("v02_average.obj")).unwrap();
    assert_eq!(ply.vertex_count(), 91792);
    assert_eq!(obj.vertex_count(), 91792);
    assert_eq!(ply.triangle_count(), obj.triangle_count());
    assert_eq!(ply.triangles, obj.triangles);
    // The OBJ prints 3 decimals, the PLY stores f32: both within 1e-3 mm.
    for (v, (a, b)) in ply.positions.iter().zip(&obj.positions).enumerate() {
        assert!(a.distance(*b) < 1e-3, "vertex {v}: {a} vs {b}");
    }
    for name in ["pair1_pre.ply", "pair1_post.ply"] {
        let scan = read_mesh(&scans.join(name)).unwrap();
        assert!(scan.vertex_count() > 80_000, "{name}");
    }
}
