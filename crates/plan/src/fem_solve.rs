//! `mammaplan fem solve`: static elasticity on a researcher's own tetrahedral mesh
//! (GUIDE section 5). The `.vtu` holds point data `constrained` (0/1) and `displacement`
//! (prescribed where constrained), optionally cell data `young_modulus` (kPa) and
//! `poisson_ratio`; the same mesh is written back with the solved `displacement`, the
//! materials used and each element's von Mises stress.
//!
//! The solve is the direct reference solver (`fem::StaticSolver`: Newton iterations on
//! the corotated equations with the consistent tangent and a sparse Cholesky
//! factorisation, or one linear solve with `--linear`): a single mesh has no level
//! hierarchy for the multigrid, and a researcher's check wants the converged answer.

use anyhow::{Context, Result, bail};
use fem::{Constraints, FemModel, Formulation, Material, SolveOptions, StaticSolver};
use glam::{DMat3, DVec3};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tetra::vtu::{CONSTRAINED, DISPLACEMENT, Field, POISSON_RATIO, YOUNG_MODULUS};

/// Name of the cell data array with each element's von Mises stress (kPa).
pub const VON_MISES: &str = "von_mises_kpa";

/// Settings of [`fem_solve`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FemSolveOptions {
    /// Small-strain elasticity instead of corotated.
    pub linear: bool,
    /// Young's modulus of every element (kPa); overrides the file's `young_modulus`.
    /// Without either, [`fem::DEFAULT_YOUNG_KPA`].
    pub young_kpa: Option<f64>,
    /// Poisson ratio of every element; overrides the file's `poisson_ratio`. Without
    /// either, [`fem::DEFAULT_POISSON_RATIO`].
    pub poisson_ratio: Option<f64>,
}

/// Where each material parameter came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MaterialSource {
    CommandLine,
    File,
    Default,
}

/// What `fem solve` did (its `--json`).
#[derive(Debug, Clone, Serialize)]
pub struct FemSolveReport {
    pub mesh: PathBuf,
    pub out: PathBuf,
    pub elements: usize,
    pub nodes: usize,
    pub constrained_nodes: usize,
    /// `linear` or `corotated`.
    pub formulation: &'static str,
    pub young_modulus_from: MaterialSource,
    pub poisson_ratio_from: MaterialSource,
    /// Linear solves (Newton iterations).
    pub iterations: usize,
    /// `‖r_f‖₂ / max(‖f_ext‖₂, ‖f_int‖₂)` at the end.
    pub relative_residual: f64,
    pub max_displacement_mm: f64,
    pub max_von_mises_kpa: f64,
    pub solve_ms: f64,
}

/// Reads `mesh`, solves, writes `out` (atomically, only on success).
pub fn fem_solve(mesh: &Path, out: &Path, options: &FemSolveOptions) -> Result<FemSolveReport> {
    let input = tetra::vtu::read_fem_input(mesh)?;
    let elements = input.mesh.tet_count();
    let (young, young_modulus_from) = material_values(
        options.young_kpa,
        input.young_modulus_kpa,
        fem::DEFAULT_YOUNG_KPA,
        elements,
    );
    let (poisson, poisson_ratio_from) = material_values(
        options.poisson_ratio,
        input.poisson_ratio,
        fem::DEFAULT_POISSON_RATIO,
        elements,
    );
    let materials = young
        .iter()
        .zip(&poisson)
        .map(|(&e, &nu)| Material::new(e, nu))
        .collect();
    let model = FemModel::new(&input.mesh, materials)
        .with_context(|| format!("{}: the finite-element model", mesh.display()))?;
    let mut constraints = Constraints::new();
    for (v, (&fixed, &d)) in input
        .constrained
        .iter()
        .zip(&input.displacement)
        .enumerate()
    {
        if fixed {
            constraints.prescribe(v as u32, d);
        }
    }
    let formulation = if options.linear {
        Formulation::Linear
    } else {
        Formulation::Corotated
    };
    let start = Instant::now();
    let solve_options = SolveOptions {
        formulation,
        ..SolveOptions::default()
    };
    let solution = StaticSolver::new(&model, &constraints)
        .and_then(|mut solver| solver.solve(&model, &[], Some(&input.displacement), &solve_options))
        .with_context(|| format!("{}: solving", mesh.display()))?;
    let solve_ms = start.elapsed().as_secs_f64() * 1e3;
    if !solution.converged {
        bail!(
            "{}: the corotated iterations did not converge ({} iterations, relative residual \
             {:.1e}); the prescribed displacements may be too large for the mesh, try --linear \
             to see the small-strain answer",
            mesh.display(),
            solution.iterations,
            solution.relative_residual
        );
    }
    let stresses = model.stresses(&solution.displacement, formulation)?;
    let von_mises: Vec<f64> = stresses.iter().map(von_mises_kpa).collect();
    let constrained_flags: Vec<f64> = input
        .constrained
        .iter()
        .map(|&c| f64::from(u8::from(c)))
        .collect();
    tetra::vtu::write_vtu(
        out,
        &input.mesh,
        &[
            Field::vectors(DISPLACEMENT, solution.displacement.clone()),
            Field::scalars(CONSTRAINED, constrained_flags),
        ],
        &[
            Field::scalars(YOUNG_MODULUS, young),
            Field::scalars(POISSON_RATIO, poisson),
            Field::scalars(VON_MISES, von_mises.clone()),
        ],
    )
    .with_context(|| format!("writing {}", out.display()))?;
    Ok(FemSolveReport {
        mesh: mesh.to_path_buf(),
        out: out.to_path_buf(),
        elements,
        nodes: input.mesh.vertex_count(),
        constrained_nodes: input.constrained.iter().filter(|&&c| c).count(),
        formulation: if options.linear {
            "linear"
        } else {
            "corotated"
        },
        young_modulus_from,
        poisson_ratio_from,
        iterations: solution.iterations,
        relative_residual: solution.relative_residual,
        max_displacement_mm: solution
            .displacement
            .iter()
            .map(|d| d.length())
            .fold(0.0, f64::max),
        max_von_mises_kpa: von_mises.iter().copied().fold(0.0, f64::max),
        solve_ms,
    })
}

/// One value per element: the command line's, else the file's, else the default.
fn material_values(
    command_line: Option<f64>,
    file: Option<Vec<f64>>,
    default: f64,
    elements: usize,
) -> (Vec<f64>, MaterialSource) {
    match (command_line, file) {
        (Some(value), _) => (vec![value; elements], MaterialSource::CommandLine),
        (None, Some(values)) => (values, MaterialSource::File),
        (None, None) => (vec![default; elements], MaterialSource::Default),
    }
}

/// The von Mises equivalent stress `√(3/2 s:s)` of a stress tensor, `s` its deviator
/// (same unit as the tensor).
pub fn von_mises_kpa(sigma: &DMat3) -> f64 {
    let mean = (sigma.x_axis.x + sigma.y_axis.y + sigma.z_axis.z) / 3.0;
    let s = *sigma - DMat3::from_diagonal(DVec3::splat(mean));
    let contraction: f64 = [s.x_axis, s.y_axis, s.z_axis]
        .iter()
        .map(|c| c.length_squared())
        .sum();
    (1.5 * contraction).sqrt()
}
