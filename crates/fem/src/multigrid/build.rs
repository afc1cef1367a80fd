//! Building the hierarchy: levels, transfers, coarse patterns, colourings and the
//! coarsest solver.

use super::galerkin::{Galerkin, galerkin_unknowns};
use super::smoother::colour_rows;
use super::transfer::{SmoothedProlongation, Transfer};
use super::{CoarseOperator, Level, Multigrid, MultigridOptions, PhaseTimes};
use crate::direct::DirectSolver;
use crate::error::FemError;
use crate::model::FemModel;
use crate::system::{Constraints, NOT_FREE, ReducedSystem};
use crate::transfer::Prolongation;
use glam::{DMat3, DVec3};
use tetmesh::TetMesh;

fn mesh_of(model: &FemModel) -> TetMesh {
    TetMesh {
        positions: model.rest_positions().to_vec(),
        tets: model.tets().to_vec(),
    }
}

impl Multigrid {
    /// Builds the hierarchy: `levels` are `(model, constraints)` pairs, finest first,
    /// at least one. The finest level must have at least one constraint (else its system
    /// is singular). With [`CoarseOperator::Galerkin`] the coarse levels' constraints are
    /// ignored (their unknowns follow from the finer level, see [`CoarseOperator`]);
    /// with [`CoarseOperator::Rediscretised`] every level needs its own.
    ///
    /// Errors: see [`ReducedSystem::new`]; a level without tetrahedra;
    /// [`FemError::InvalidOptions`] if `options.sweeps_per_step` is zero,
    /// `options.relaxation` is outside (0, 2), or `options.prolongation_smoothing` is
    /// outside [0, 1] or positive with rediscretised coarse operators.
    pub fn new(
        levels: Vec<(FemModel, Constraints)>,
        options: MultigridOptions,
    ) -> Result<Multigrid, FemError> {
        Multigrid::build(levels, options, false)
    }

    /// Like [`Multigrid::new`], but the finest level's constraints are only the
    /// permanent ones (e.g. the chest wall; may be empty): the constraints that change
    /// (an implant's displacement template) are set with [`Multigrid::set_constraints`]
    /// before the first assembly, and changed with it in O(vertices) without rebuilding
    /// the hierarchy. [`Multigrid::new`] allows the same, with a non-empty permanent set.
    ///
    /// Errors: as [`Multigrid::new`], except that an empty finest constraint set is
    /// allowed.
    pub fn with_permanent_constraints(
        levels: Vec<(FemModel, Constraints)>,
        options: MultigridOptions,
    ) -> Result<Multigrid, FemError> {
        Multigrid::build(levels, options, true)
    }

    fn build(
        levels: Vec<(FemModel, Constraints)>,
        options: MultigridOptions,
        changeable: bool,
    ) -> Result<Multigrid, FemError> {
        if levels.is_empty() {
            return Err(FemError::LengthMismatch {
                what: "multigrid levels",
                expected: 1,
                got: 0,
            });
        }
        if options.sweeps_per_step == 0 {
            return Err(FemError::InvalidOptions {
                what: "multigrid sweeps_per_step is 0, need at least 1".into(),
            });
        }
        if !(options.relaxation > 0.0 && options.relaxation < 2.0) {
            return Err(FemError::InvalidOptions {
                what: format!(
                    "multigrid relaxation {}, need 0 < ω < 2",
                    options.relaxation
                ),
            });
        }
        let galerkin = options.coarse_operator == CoarseOperator::Galerkin;
        let ps = options.prolongation_smoothing;
        if !(0.0..=1.0).contains(&ps) || (ps > 0.0 && !galerkin) {
            return Err(FemError::InvalidOptions {
                what: format!(
                    "multigrid prolongation_smoothing {ps}, need 0 <= ω_P <= 1 and Galerkin \
                     coarse operators when positive"
                ),
            });
        }
        let empty = || FemError::LengthMismatch {
            what: "tetrahedra of a multigrid level",
            expected: 1,
            got: 0,
        };
        let mut built: Vec<Level> = Vec::with_capacity(levels.len());
        let mut transfers = Vec::with_capacity(levels.len() - 1);
        for (model, constraints) in levels {
            let prolongations = match built.last() {
                Some(fine) => {
                    let fine_mesh = mesh_of(&fine.model);
                    let coarse_mesh = mesh_of(&model);
                    let p = Prolongation::new(&coarse_mesh, &fine_mesh).ok_or_else(empty)?;
                    let sample = Prolongation::new(&fine_mesh, &coarse_mesh).ok_or_else(empty)?;
                    Some((p, sample))
                }
                None => None,
            };
            let (system, reduced_of) = match (&prolongations, built.last()) {
                (Some((p, _)), Some(fine)) if galerkin => {
                    (None, galerkin_unknowns(p, &fine.reduced_of, &model))
                }
                _ => {
                    let system = if changeable && built.is_empty() {
                        ReducedSystem::with_permanent(&model, &constraints)?
                    } else {
                        ReducedSystem::new(&model, &constraints)?
                    };
                    let reduced_of = system.reduced_of.clone();
                    (Some(system), reduced_of)
                }
            };
            let unknowns = reduced_of.iter().filter(|&&r| r != NOT_FREE).count();
            if let (Some((p, sample)), Some(fine)) = (prolongations, built.last()) {
                transfers.push(Transfer::new(
                    p,
                    sample,
                    &fine.reduced_of,
                    &reduced_of,
                    unknowns,
                ));
            }
            built.push(Level {
                model,
                system,
                reduced_of,
                unknowns,
                galerkin: None,
                colours: Vec::new(),
                diag_slot: Vec::new(),
                inv_diag: vec![DMat3::IDENTITY; unknowns],
                active: vec![true; unknowns],
            });
        }
        for l in 0..built.len() {
            if l > 0 && galerkin {
                let fine = built[l - 1].op();
                let t = &mut transfers[l - 1];
                built[l].galerkin = Some(if l == 1 && ps > 0.0 {
                    let smoothed = SmoothedProlongation::new(fine, t, ps);
                    let g = Galerkin::smoothed(&smoothed);
                    t.smoothed = Some(smoothed);
                    g
                } else {
                    Galerkin::new(fine, t)
                });
            }
            let a = built[l].op();
            let colours = colour_rows(a);
            let diag_slot = (0..a.block_rows())
                .map(|i| a.slot(i, i).expect("diagonal block present"))
                .collect();
            built[l].colours = colours;
            built[l].diag_slot = diag_slot;
        }
        let last = built.last().expect("at least one level");
        let coarse = if last.unknowns > 0 {
            Some(DirectSolver::new(last.op())?)
        } else {
            None
        };
        let sizes: Vec<usize> = built.iter().map(|l| l.unknowns).collect();
        let xs = sizes.iter().map(|&n| vec![DVec3::ZERO; n]).collect();
        let bs = sizes.iter().map(|&n| vec![DVec3::ZERO; n]).collect();
        let rs = sizes.iter().map(|&n| vec![DVec3::ZERO; n]).collect();
        let us = built
            .iter()
            .map(|l| vec![DVec3::ZERO; l.model.vertex_count()])
            .collect();
        Ok(Multigrid {
            levels: built,
            transfers,
            coarse,
            options,
            xs,
            bs,
            rs,
            us,
            assembled: None,
            times: PhaseTimes::default(),
        })
    }
}
