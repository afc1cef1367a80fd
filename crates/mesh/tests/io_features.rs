//! Mesh file reading: hand-written PLY, OBJ and STL files for every feature the readers
//! support.

mod common;

use common::*;
use mesh::io::{read_obj, read_ply, read_stl};
use mesh::{DVec2, DVec3, MaterialLayer};

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
