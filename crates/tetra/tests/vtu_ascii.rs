//! VTU writing and reading: exact round trip, the solver's arrays, and errors naming
//! the file, the line and the problem.

mod common;

use common::vtu::*;
use glam::DVec3;
use tetra::TetMeshError;
use tetra::vtu::{Field, FieldValues, read_fem_input, read_vtu, write_vtu};

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
