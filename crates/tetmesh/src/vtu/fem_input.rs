//! The input of a finite-element solve, read from a `.vtu`.

use super::{
    CONSTRAINED, DISPLACEMENT, Field, FieldValues, POISSON_RATIO, YOUNG_MODULUS, read_vtu,
};
use crate::error::TetMeshError;
use crate::tetmesh::TetMesh;
use glam::DVec3;
use std::path::Path;

/// The input of a finite-element solve, from a `.vtu` file.
#[derive(Debug, Clone, PartialEq)]
pub struct FemInput {
    pub mesh: TetMesh,
    /// Per vertex: whether its displacement is prescribed.
    pub constrained: Vec<bool>,
    /// Per vertex (mm): prescribed where constrained, a start value elsewhere; zero when
    /// the file has no [`DISPLACEMENT`] array.
    pub displacement: Vec<DVec3>,
    /// Per tetrahedron (kPa), if the file has [`YOUNG_MODULUS`].
    pub young_modulus_kpa: Option<Vec<f64>>,
    /// Per tetrahedron, if the file has [`POISSON_RATIO`].
    pub poisson_ratio: Option<Vec<f64>>,
}

/// Reads a `.vtu` for a solve: point data [`CONSTRAINED`] (required, 0 or 1) and
/// [`DISPLACEMENT`] (optional, 3 components), cell data [`YOUNG_MODULUS`] (optional,
/// positive kPa) and [`POISSON_RATIO`] (optional, in (−1, 0.5)). Errors name the array
/// and the entry.
pub fn read_fem_input(path: &Path) -> Result<FemInput, TetMeshError> {
    let data = read_vtu(path)?;
    let error = |message: String| TetMeshError::Vtu {
        path: path.to_path_buf(),
        line: None,
        message,
    };
    let scalars = |field: Option<&Field>,
                   name: &str,
                   location: &str|
     -> Result<Option<Vec<f64>>, TetMeshError> {
        match field.map(|f| &f.values) {
            None => Ok(None),
            Some(FieldValues::Scalars(v)) => Ok(Some(v.clone())),
            Some(FieldValues::Vectors(_)) => Err(error(format!(
                "{location} data \"{name}\" must have 1 component, not 3"
            ))),
        }
    };
    let check = |values: &[f64], name: &str, what: &str, ok: &dyn Fn(f64) -> bool| match values
        .iter()
        .position(|&x| !ok(x))
    {
        Some(k) => Err(error(format!(
            "\"{name}\" entry {k} is {}: expected {what}",
            values[k]
        ))),
        None => Ok(()),
    };
    let constrained = scalars(data.point_field(CONSTRAINED), CONSTRAINED, "point")?
        .ok_or_else(|| error(format!("no point data \"{CONSTRAINED}\" (0/1 per point)")))?;
    check(&constrained, CONSTRAINED, "0 or 1", &|x| {
        x == 0.0 || x == 1.0
    })?;
    let displacement = match data.point_field(DISPLACEMENT).map(|f| &f.values) {
        None => vec![DVec3::ZERO; data.mesh.vertex_count()],
        Some(FieldValues::Vectors(v)) => v.clone(),
        Some(FieldValues::Scalars(_)) => {
            return Err(error(format!(
                "point data \"{DISPLACEMENT}\" must have 3 components"
            )));
        }
    };
    if let Some(k) = displacement.iter().position(|d| !d.is_finite()) {
        return Err(error(format!("\"{DISPLACEMENT}\" entry {k} is not finite")));
    }
    let young_modulus_kpa = scalars(data.cell_field(YOUNG_MODULUS), YOUNG_MODULUS, "cell")?;
    if let Some(e) = &young_modulus_kpa {
        check(e, YOUNG_MODULUS, "a positive modulus in kPa", &|x| {
            x.is_finite() && x > 0.0
        })?;
    }
    let poisson_ratio = scalars(data.cell_field(POISSON_RATIO), POISSON_RATIO, "cell")?;
    if let Some(nu) = &poisson_ratio {
        check(nu, POISSON_RATIO, "a ratio in (-1, 0.5)", &|x| {
            x > -1.0 && x < 0.5
        })?;
    }
    Ok(FemInput {
        constrained: constrained.iter().map(|&x| x == 1.0).collect(),
        displacement,
        young_modulus_kpa,
        poisson_ratio,
        mesh: data.mesh,
    })
}
