//! Mesh file I/O round trips: every format and PLY encoding, and the shared torso scans.

use mesh::io::{
    PlyEncoding, VertexScalar, read_mesh, read_obj, read_ply, read_ply_with_scalars, read_stl,
    write_mesh, write_obj, write_ply, write_ply_with_scalars, write_stl,
};
use mesh::{DVec2, DVec3, MaterialLayer, MeshError, TriMesh, UvLayer, shapes};
use std::path::Path;

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
