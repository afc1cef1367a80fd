//! Files written by VTK itself read as written.

use glam::DVec3;
use std::path::Path;
use tetra::vtu::{Field, read_vtu};

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
