//! VTK XML unstructured-grid files (`.vtu`) of tetrahedral meshes with point and cell
//! data, as ParaView opens them.
//!
//! Written with every array appended as raw binary in VTK's zlib blocks (Float64 values
//! stored exactly, so a file read back gives the same bits) to a temporary file renamed
//! into place. The reader
//! takes what the writer produces and any other single-piece `.vtu` of tetrahedra (VTK
//! cell type 10) as ParaView, VTK or meshio write them; data arrays of any numeric type
//! (Int8 to Int64, UInt8 to UInt64, Float32, Float64) with one or three components, in
//! any of VTK's encodings:
//!
//! - `format="ascii"`;
//! - `format="binary"`: base64 inside the element;
//! - `format="appended"` with an `offset` into `<AppendedData encoding="raw">` (bytes
//!   after the `_` marker) or `encoding="base64"` (characters after it);
//! - each binary block a header then the data: uncompressed, the header is the byte
//!   count; with `compressor="vtkZLibDataCompressor"`, it is `[blocks, block size, last
//!   block size, compressed size of each block]` followed by the zlib streams. Header
//!   words are UInt32 or UInt64 (`header_type`, default UInt32), headers and values in
//!   the file's `byte_order` (LittleEndian or BigEndian). Base64 header and data may be
//!   one stream or two (VTK writes two when compressing).
//!
//! Truncated or corrupt binary data give an error naming the array, its line and the
//! problem. Arrays outside the mesh's sections (e.g. `<FieldData>`) are not read.
//!
//! [`read_fem_input`] reads the arrays the finite-element solver takes: point data
//! [`CONSTRAINED`] (0/1) and [`DISPLACEMENT`] (mm), cell data [`YOUNG_MODULUS`] (kPa) and
//! [`POISSON_RATIO`].
//!
//! # Files
//! - `write.rs`: the writer ([`write_vtu`]).
//! - `read.rs`: the reader ([`read_vtu`]): appended data split off, arrays assembled.
//! - `parser.rs`: the XML parse into raw data arrays.
//! - `binary.rs`: binary arrays: value types, block headers, base64, zlib.
//! - `fem_input.rs`: the finite-element input ([`read_fem_input`]).

mod binary;
mod fem_input;
mod parser;
mod read;
mod write;

pub use fem_input::{FemInput, read_fem_input};
pub use read::read_vtu;
pub use write::write_vtu;

use crate::tetmesh::TetMesh;
use glam::DVec3;

/// VTK's cell type number of a linear tetrahedron.
const VTK_TETRA: u8 = 10;
/// Point data: 1 where the displacement is prescribed, 0 where it is solved for.
pub const CONSTRAINED: &str = "constrained";
/// Point data: displacement (mm), 3 components.
pub const DISPLACEMENT: &str = "displacement";
/// Cell data: Young's modulus (kPa).
pub const YOUNG_MODULUS: &str = "young_modulus";
/// Cell data: Poisson's ratio.
pub const POISSON_RATIO: &str = "poisson_ratio";

/// The values of a data array: one per point or cell.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldValues {
    Scalars(Vec<f64>),
    Vectors(Vec<DVec3>),
}

/// A named data array.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    pub name: String,
    pub values: FieldValues,
}

impl Field {
    /// A scalar array.
    pub fn scalars(name: &str, values: Vec<f64>) -> Field {
        Field {
            name: name.to_string(),
            values: FieldValues::Scalars(values),
        }
    }

    /// A 3-vector array.
    pub fn vectors(name: &str, values: Vec<DVec3>) -> Field {
        Field {
            name: name.to_string(),
            values: FieldValues::Vectors(values),
        }
    }

    /// Number of entries (points or cells).
    pub fn len(&self) -> usize {
        match &self.values {
            FieldValues::Scalars(v) => v.len(),
            FieldValues::Vectors(v) => v.len(),
        }
    }

    /// Whether the array has no entries.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn components(&self) -> usize {
        match self.values {
            FieldValues::Scalars(_) => 1,
            FieldValues::Vectors(_) => 3,
        }
    }

    fn flat(&self) -> impl Iterator<Item = f64> + '_ {
        let (scalars, vectors) = match &self.values {
            FieldValues::Scalars(v) => (v.as_slice(), &[][..]),
            FieldValues::Vectors(v) => (&[][..], v.as_slice()),
        };
        scalars
            .iter()
            .copied()
            .chain(vectors.iter().flat_map(|v| v.to_array()))
    }
}

/// A mesh with its data arrays, as read from a `.vtu` file.
#[derive(Debug, Clone, PartialEq)]
pub struct VtuData {
    pub mesh: TetMesh,
    pub point_data: Vec<Field>,
    pub cell_data: Vec<Field>,
}

impl VtuData {
    /// The point data array called `name`.
    pub fn point_field(&self, name: &str) -> Option<&Field> {
        self.point_data.iter().find(|f| f.name == name)
    }

    /// The cell data array called `name`.
    pub fn cell_field(&self, name: &str) -> Option<&Field> {
        self.cell_data.iter().find(|f| f.name == name)
    }
}
