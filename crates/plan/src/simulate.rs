//! `mammaplan simulate`: implants placed on a patient's model, the predicted
//! post-operative scan (paper V), and the simulation folder.
//!
//! [`Session`] is the interactive API (issue 6, item 7): the model is prepared once;
//! implants are set, changed or moved (the constraints are rebuilt from scratch), single
//! V-cycles run warm-started, and the current scan positions can be read at any time.
//! [`simulate`] runs a session to convergence and writes:
//! - `simulated_scan.ply`: the scan with every vertex moved (same vertex order and count,
//!   colours and texture coordinates kept);
//! - `simulated_scan.obj`, `simulated_scan.mtl`, `simulated_scan_texture.*`: where the
//!   scan came with a photograph, the simulated scan wearing it (OBJ + MTL + image side by
//!   side);
//! - `simulated_landmarks.json`: the landmarks moved the same way;
//! - `simulated_control_points.json`: points every 10 mm along the model's cut curves,
//!   moved the same way: control points for a breast model of the simulated scan
//!   (`mammaplan model --control-points`, `compare --test-control-points`) that cuts the
//!   same breasts as the model did;
//! - `fe_result.vtu`: the finest tetrahedral level with point data `displacement` (mm) and
//!   `constrained` (0/1) and cell data `implant` (1 for implant elements);
//! - `result.json`: the figures ([`SimulateReport`]), written last.

use crate::measure::measure;
use crate::model::{
    ModelOptions, PatientModel, PerSide, SIMULATED_CONTROL_POINTS, build_model, load_model,
};
use crate::{Distance, MarkedScan, Progress, check_cancelled};
use anatomy::Landmarks;
use anatomy::breast::{ControlPoints, QuadrantVolumes, Side};
use anyhow::{Context, Result};
use glam::DVec3;
use implant::{Catalog, ImplantShape, ImplantSpec};
use serde::{Deserialize, Serialize};
use simulation::{PatientInput, PlacedImplant, Simulation};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tetra::vtu::{CONSTRAINED, DISPLACEMENT, Field};

pub use fem::Material;
pub use simulation::carry::ScanCarry;
pub use simulation::pocket::{FoldLowering, MAX_ICE_FOLD_LOWERING_MM, PocketLimits};
pub use simulation::{AnchorRule, CycleInfo, Placement, RunReport, SimulationOptions, Stage};

mod record;
pub use record::*;

/// An implant asked for on one side.
#[derive(Debug, Clone, PartialEq)]
pub struct ImplantRequest {
    /// `round:diameter=115,projection=33`, `anatomic:width=..,height=..,projection=..` or
    /// `catalog:ID`.
    pub spec: String,
    /// Move from the default position (mm, anatomical frame: `x` to the patient's left,
    /// `y` up along the bed, `z` anterior).
    pub move_mm: DVec3,
    /// Turn about the bed's normal, counter-clockwise seen from the front (degrees; for
    /// anatomic implants).
    pub rotation_deg: f64,
    /// How far to lower the fold for this implant (mm, 0 to the pocket's depth, 30 mm
    /// by default); `None`: as the side's rule plans it (the ICE principle, or the
    /// `--lower-fold-*` given).
    pub fold_lowering_mm: Option<f64>,
}

impl ImplantRequest {
    /// An implant at its default position.
    pub fn new(spec: impl Into<String>) -> ImplantRequest {
        ImplantRequest {
            spec: spec.into(),
            move_mm: DVec3::ZERO,
            rotation_deg: 0.0,
            fold_lowering_mm: None,
        }
    }

    /// Where it asks the implant to go, relative to the default position.
    pub fn placement(&self) -> Placement {
        Placement {
            move_mm: self.move_mm,
            rotation_deg: self.rotation_deg,
            fold_lowering_mm: self.fold_lowering_mm,
        }
    }
}

/// Settings of [`simulate`].
#[derive(Debug, Clone, Default)]
pub struct SimulateOptions {
    pub left: Option<ImplantRequest>,
    pub right: Option<ImplantRequest>,
    /// Skip the gravity correction (paper V-B).
    pub no_gravity: bool,
    /// A CSV catalog for `catalog:ID` specs instead of the built-in one.
    pub catalog: Option<PathBuf>,
    /// Where an implant's default position lies (centred on the breast's footprint, or
    /// straight behind the nipple); moves are relative to it.
    pub anchor: AnchorRule,
    /// How far each pocket reaches below the native fold (mm, the planned lowering);
    /// `None`: as the ICE principle plans it for the implant
    /// ([`simulation::pocket::ice_fold_lowering_mm`]).
    pub fold_lowering_mm: PerSide<Option<f64>>,
    /// Homogeneous tissue up to the surface (the paper's model) instead of the default
    /// skin layer ([`simulation::skin`]).
    pub no_skin: bool,
    /// The pectoralis major's elements of breast tissue (the paper's homogeneous model)
    /// instead of the muscle's material ([`simulation::muscle`]).
    pub no_muscle: bool,
    /// Release the implant as a gel of this Young's modulus (kPa) once the template has
    /// pushed the tissue ([`SimulationOptions::implant_gel`]); `None`: the template.
    pub implant_gel_kpa: Option<f64>,
    /// The paper's corotated energy alone, without the resistance to large volume loss
    /// ([`fem::CompressionPenalty`]).
    pub no_compression_penalty: bool,
    /// The skin over a thin pocket slides over the implant instead of being held
    /// ([`simulation::SimulationOptions::skin_slides`]).
    pub skin_slides: bool,
}

/// A patient's model ready for interactive simulation.
pub struct Session {
    pub marked: MarkedScan,
    pub model: PatientModel,
    pub simulation: Simulation,
    catalog: Catalog,
    /// The clinical distances on the scan as loaded, once measured.
    distances_before: Option<Vec<Distance>>,
}

/// Where an interactive solve stands (see [`Session::advance`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SolveState {
    /// More cycles will bring it closer.
    Running,
    /// The last stage reached the relative tolerance.
    Converged,
    /// A stage ran out of cycles ([`SimulationOptions::max_cycles`]) short of the
    /// tolerance: the prediction is approximate.
    Stopped,
}

/// One step of [`Session::advance`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Advance {
    /// The cycle just run.
    pub cycle: CycleInfo,
    /// Cycles run in that cycle's stage so far.
    pub stage_cycles: usize,
    pub state: SolveState,
}

/// The clinical figures before and after a simulation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimulatedMeasurements {
    /// The breast volumes of the model, before (ml).
    pub breast_volume_before_ml: PerSide<f64>,
    /// The breast volumes after the simulation, over the chest wall (ml).
    pub breast_volume_ml: PerSide<f64>,
    /// The quadrant volumes of the model's breasts, before (ml).
    pub quadrant_volume_before_ml: PerSide<QuadrantVolumes>,
    /// The quadrant volumes of the simulated breasts (ml; `None` where the moved
    /// landmarks no longer bound quadrants, see [`simulation::BreastVolume`]).
    pub quadrant_volume_ml: PerSide<Option<QuadrantVolumes>>,
    /// The implants' volumes (ml; 0 on a side without implant).
    pub implant_volume_ml: PerSide<f64>,
    /// The clinical distances on the scan before and on the simulated scan.
    pub distances: Vec<DistanceChange>,
}

/// The breasts after a simulation (see [`Session::breast_volumes`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulatedBreasts {
    /// The model's breast volumes (ml).
    pub volume_before_ml: PerSide<f64>,
    /// Over the chest wall, as [`simulation::BreastVolume::volume_ml`] (ml).
    pub volume_ml: PerSide<f64>,
    /// The quadrants of `volume_ml` (ml; `None` where undefined).
    pub quadrant_volume_ml: PerSide<Option<QuadrantVolumes>>,
    /// Over a fill-in rebuilt on the moved cut curve, as a post-operative scan modelled
    /// along the carried curve measures (ml; `None` where none can be rebuilt; see
    /// [`simulation::BreastVolume::volume_rebuilt_fill_ml`]).
    pub volume_rebuilt_fill_ml: PerSide<Option<f64>>,
}

/// One clinical distance before and after (mm).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DistanceChange {
    pub name: String,
    pub before: Distance,
    pub simulated: Distance,
}

impl Session {
    /// The whole per-patient preprocessing: builds the patient model of `marked`
    /// ([`build_model`]) and prepares its simulation (stages `model`, `tetrahedra`,
    /// `simulation`). Stops with [`crate::Cancelled`] between stages once `progress`
    /// asks to.
    pub fn build(
        marked: MarkedScan,
        model_options: &ModelOptions,
        catalog: Catalog,
        options: SimulationOptions,
        progress: &dyn Progress,
    ) -> Result<Session> {
        let model = build_model(&marked, model_options, progress)?;
        progress.stage("simulation", 1);
        let session = Session::new(marked, model, catalog, options)?;
        progress.step();
        check_cancelled(progress)?;
        Ok(session)
    }

    /// Prepares the simulation of a built model (the finite-element hierarchy, the
    /// implant beds, the maps from the scan into the mesh) with `options`.
    pub fn new(
        marked: MarkedScan,
        model: PatientModel,
        catalog: Catalog,
        options: SimulationOptions,
    ) -> Result<Session> {
        let simulation = Simulation::new(
            PatientInput {
                scan: &marked.scan.mesh,
                landmarks: &marked.landmarks,
                frame: &marked.frame,
                breasts: &model.breasts,
                closed_surface: &model.closed_surface,
                tets: &model.tets,
            },
            options,
        )
        .context("preparing the simulation")?;
        Ok(Session {
            marked,
            model,
            simulation,
            catalog,
            distances_before: None,
        })
    }

    /// The catalog that `catalog:ID` specs are looked up in.
    pub fn catalog(&self) -> &Catalog {
        &self.catalog
    }

    /// Sets (or replaces) the implant of one side from a spec at `placement` (moved and
    /// turned from the default position, then moved on to where its footprint fits, see
    /// [`PlacedImplant::fit_shift_mm`]). On error nothing changes.
    pub fn set_implant(
        &mut self,
        side: Side,
        spec: &str,
        placement: Placement,
    ) -> Result<&PlacedImplant> {
        let entry = ImplantSpec::parse(spec)
            .and_then(|s| s.resolve(&self.catalog))
            .with_context(|| format!("{side} implant"))?;
        let shape = *entry.shape();
        self.simulation
            .set_implant(side, shape, placement)
            .with_context(|| format!("{side} implant {spec}"))
    }

    /// Sets (or replaces) the implant of one side as `request` asks; its summary. On
    /// error nothing changes.
    pub fn place(&mut self, side: Side, request: &ImplantRequest) -> Result<ImplantSummary> {
        let catalog_entry = match ImplantSpec::parse(&request.spec) {
            Ok(ImplantSpec::Catalog(id)) => self.catalog.get(&id).cloned(),
            _ => None,
        };
        let placed = self.set_implant(side, &request.spec, request.placement())?;
        Ok(ImplantSummary::new(request, placed, catalog_entry.as_ref()))
    }

    /// The outline of one side's implant footprint seen on the skin (mm, file frame):
    /// `segments` points of the footprint's boundary laid on the implant bed, each carried
    /// along the bed's normal to the scan as loaded (the closest scan point where the
    /// normal misses it). `None` without an implant on that side.
    pub fn implant_outline_on_scan(&self, side: Side, segments: usize) -> Option<Vec<DVec3>> {
        let placed = self.simulation.implant(side)?;
        let bed = self.simulation.bed(side);
        let outline = placed
            .shape
            .footprint_outline_mm(segments)
            .into_iter()
            .filter_map(|local| {
                // an outline point within the fit's tolerance off the bed: its edge
                let uv = placed.anchor.uv_of(local);
                bed.at(uv).or_else(|| bed.at(bed.nearest_on_boundary(uv)))
            })
            .map(|at| self.on_scan(&at))
            .collect();
        Some(outline)
    }

    /// The outline of the pocket one side's implant lies in, seen on the skin (mm, file
    /// frame): the pocket's edge on the chest within the implant's limits (the midline
    /// clearance, the anterior axillary line, its planned fold), carried along the bed's
    /// normal to the scan as loaded. `None` without an implant or where it lies on the
    /// fill-in's bed (its outline is the cut curve's).
    pub fn pocket_outline_on_scan(&self, side: Side) -> Option<Vec<DVec3>> {
        self.simulation.implant(side)?;
        let bounds = self.simulation.pocket_bounds(side)?;
        let bed = self.simulation.bed(side);
        let frame = self.simulation.frame();
        Some(
            (bed.boundary.iter())
                .filter_map(|&uv| bed.at(uv))
                .filter(|at| bounds.violation(frame.to_local(at.position)).is_none())
                .map(|at| self.on_scan(&at))
                .collect(),
        )
    }

    /// A point of the bed carried along its normal to the scan as loaded (the closest
    /// scan point where the normal misses it).
    fn on_scan(&self, at: &simulation::bed::BedPoint) -> DVec3 {
        /// How far in front of the bed the skin may be (mm): beyond any breast's depth.
        const SKIN_SEARCH_MM: f64 = 300.0;
        let index = &self.marked.scan.index;
        index
            .cast_ray(at.position, at.normal, SKIN_SEARCH_MM)
            .map_or_else(|| index.closest_point(at.position).point, |hit| hit.point)
    }

    /// Removes the implant of one side.
    pub fn remove_implant(&mut self, side: Side) {
        self.simulation.remove_implant(side);
    }

    /// One cycle of the current stage, warm-started from the current displacement
    /// ([`Simulation::cycle`]).
    pub fn cycle(&mut self) -> Result<CycleInfo> {
        Ok(self.simulation.cycle()?)
    }

    /// One cycle of the interactive solve: the implant stage until it reaches the
    /// options' relative tolerance, then (unless `no_gravity`, and with an implant) the
    /// gravity correction until it does too, as [`Simulation::run`] solves them; a live
    /// view calls it until the state is no longer [`SolveState::Running`], and again
    /// after every change of the implants (which starts the implant stage afresh). A
    /// stage that runs out of cycles stops the solve ([`SolveState::Stopped`]; `run`
    /// would go on to the gravity stage).
    pub fn advance(&mut self, no_gravity: bool) -> Result<Advance> {
        let cycle = self.cycle()?;
        let (stage_cycles, _) = self.simulation.stage_progress();
        let options = self.simulation.options();
        let reached = cycle.relative_residual < options.relative_tolerance && !cycle.linear;
        let out_of_cycles = stage_cycles >= options.max_cycles;
        let has_implant = Side::BOTH
            .iter()
            .any(|&side| self.simulation.implant(side).is_some());
        let state = match cycle.stage {
            Stage::Implant if reached && !no_gravity && has_implant => {
                self.simulation
                    .start_gravity_correction()
                    .context("starting the gravity correction")?;
                SolveState::Running
            }
            _ if reached => SolveState::Converged,
            _ if out_of_cycles => SolveState::Stopped,
            _ => SolveState::Running,
        };
        Ok(Advance {
            cycle,
            stage_cycles,
            state,
        })
    }

    /// The scan's vertices as the simulation currently predicts them (mm, file frame,
    /// the scan's order).
    pub fn scan_positions(&self) -> Vec<DVec3> {
        self.simulation.scan_positions()
    }

    /// The scan with every vertex where the simulation currently predicts it (same
    /// order, colours and texture coordinates) and the landmarks moved with the tissue;
    /// `path` names it in messages.
    pub fn simulated_scan(&self, path: &Path) -> Result<MarkedScan> {
        let scan_displacements = self.simulation.scan_displacements();
        let positions = (self.marked.scan.mesh.positions.iter())
            .zip(&scan_displacements)
            .map(|(p, d)| *p + *d)
            .collect();
        MarkedScan::new(
            self.marked.scan.moved_to(positions, path)?,
            self.simulation.landmarks_moved_by(&scan_displacements),
            path,
            Some(self.marked.up()),
            &crate::Silent,
        )
        .context("the simulated scan")
    }

    /// The breast volumes before (the model's) and after (over the chest wall, and over
    /// a fill-in rebuilt on the moved cut curve), ml.
    pub fn breast_volumes(&mut self) -> SimulatedBreasts {
        let volumes = self.simulation.breast_volumes();
        SimulatedBreasts {
            volume_rebuilt_fill_ml: PerSide::from_fn(|side| {
                volumes[side as usize].volume_rebuilt_fill_ml
            }),
            volume_before_ml: PerSide::from_fn(|side| volumes[side as usize].volume_before_ml),
            volume_ml: PerSide::from_fn(|side| volumes[side as usize].volume_ml),
            quadrant_volume_ml: PerSide::from_fn(|side| volumes[side as usize].quadrant_volume_ml),
        }
    }

    /// The model's cut-curve control points carried with the tissue onto the simulated
    /// scan: a breast model of the simulated scan with them
    /// ([`crate::model::build_breasts`]) cuts the same breasts as the model did.
    pub fn simulated_control_points(&self) -> ControlPoints {
        self.simulation
            .control_points_moved_by(&self.simulation.scan_displacements())
    }

    /// The implants' volumes (ml; 0 on a side without implant).
    pub fn implant_volumes_ml(&self) -> PerSide<f64> {
        PerSide::from_fn(|side| {
            self.simulation
                .implant(side)
                .map_or(0.0, |placed| placed.shape.volume_ml())
        })
    }

    /// The clinical figures of the current prediction: breast and implant volumes, and
    /// the clinical distances on the scan as loaded (measured once) and on the simulated
    /// scan (both with their holes closed, as `measure` does).
    pub fn measurements(&mut self, progress: &dyn Progress) -> Result<SimulatedMeasurements> {
        if self.distances_before.is_none() {
            self.distances_before = Some(measure(&self.marked, &[], progress)?.distances);
        }
        let simulated = self.simulated_scan(Path::new("simulated scan"))?;
        let after = measure(&simulated, &[], progress)?.distances;
        let breasts = self.breast_volumes();
        let before = self.distances_before.as_deref().unwrap_or_default();
        let distances = before
            .iter()
            .filter_map(|b| {
                let a = after.iter().find(|a| a.name == b.name)?;
                Some(DistanceChange {
                    name: b.name.clone(),
                    before: b.clone(),
                    simulated: a.clone(),
                })
            })
            .collect();
        Ok(SimulatedMeasurements {
            breast_volume_before_ml: breasts.volume_before_ml,
            breast_volume_ml: breasts.volume_ml,
            quadrant_volume_before_ml: PerSide::from_fn(|side| {
                self.model.breasts.breast(side).quadrant_volume_ml
            }),
            quadrant_volume_ml: breasts.quadrant_volume_ml,
            implant_volume_ml: self.implant_volumes_ml(),
            distances,
        })
    }
}

impl SimulatedMeasurements {
    /// Writes the figures as pretty JSON, atomically.
    pub fn write_json(&self, path: &Path) -> Result<()> {
        crate::write_json(path, self)
    }

    /// Writes the figures as CSV, atomically: a header
    /// `measurement,kind,unit,before,simulated,difference`, one row per distance and
    /// kind (`euclidean`, `surface`, `geodesic`; empty cells where a surface measure
    /// could not be traced), then the breast and implant volumes.
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        let cell = |value: Option<f64>| value.map_or(String::new(), |v| format!("{v:.2}"));
        mesh::io::write_atomically(path, |w| {
            // the csv crate quotes a user's point name that holds a comma or a quote
            let mut csv = csv::Writer::from_writer(w);
            csv.write_record([
                "measurement",
                "kind",
                "unit",
                "before",
                "simulated",
                "difference",
            ])?;
            for change in &self.distances {
                let (b, a) = (&change.before, &change.simulated);
                for (kind, before, after) in [
                    ("euclidean", Some(b.euclidean_mm), Some(a.euclidean_mm)),
                    ("surface", b.surface_mm, a.surface_mm),
                    ("geodesic", b.geodesic_mm, a.geodesic_mm),
                ] {
                    let difference = before.zip(after).map(|(b, a)| a - b);
                    csv.write_record([
                        change.name.as_str(),
                        kind,
                        "mm",
                        &cell(before),
                        &cell(after),
                        &cell(difference),
                    ])?;
                }
            }
            for side in Side::BOTH {
                let before = *self.breast_volume_before_ml.get(side);
                let after = *self.breast_volume_ml.get(side);
                csv.write_record([
                    format!("breast volume {side}").as_str(),
                    "volume",
                    "ml",
                    &cell(Some(before)),
                    &cell(Some(after)),
                    &cell(Some(after - before)),
                ])?;
            }
            for side in Side::BOTH {
                let implant = *self.implant_volume_ml.get(side);
                csv.write_record([
                    format!("implant volume {side}").as_str(),
                    "volume",
                    "ml",
                    "",
                    &cell(Some(implant)),
                    "",
                ])?;
            }
            csv.flush()
        })?;
        Ok(())
    }
}

/// Runs the simulation of `model_dir` with `options` and writes the simulation folder.
pub fn simulate(
    model_dir: &Path,
    out_dir: &Path,
    options: &SimulateOptions,
    progress: &dyn Progress,
) -> Result<SimulateReport> {
    anyhow::ensure!(
        options.left.is_some() || options.right.is_some(),
        "no implant given: use --left SPEC and/or --right SPEC"
    );
    let catalog = crate::catalog::load(options.catalog.as_deref())?;
    let (marked, model) = load_model(model_dir, progress)?;
    let limits = |lowering_mm: Option<f64>| PocketLimits {
        fold_lowering: lowering_mm.map_or(FoldLowering::ForImplant, FoldLowering::Mm),
        ..PocketLimits::default()
    };
    let simulation_options = SimulationOptions {
        anchor_rule: options.anchor,
        pocket: Some([
            limits(options.fold_lowering_mm.left),
            limits(options.fold_lowering_mm.right),
        ]),
        skin: if options.no_skin {
            None
        } else {
            SimulationOptions::default().skin
        },
        implant_gel: options.implant_gel_kpa.map(|young_kpa| fem::Material {
            young_kpa,
            poisson_ratio: simulation::session::DEFAULT_IMPLANT_POISSON_RATIO,
            density_kg_m3: simulation::session::DEFAULT_IMPLANT_DENSITY_KG_M3,
        }),
        muscle: if options.no_muscle {
            None
        } else {
            SimulationOptions::default().muscle
        },
        compression_penalty: if options.no_compression_penalty {
            None
        } else {
            SimulationOptions::default().compression_penalty
        },
        skin_slides: options.skin_slides,
        ..SimulationOptions::default()
    };
    let session = Session::new(marked, model, catalog, simulation_options)?;
    run_session(session, model_dir, out_dir, options, progress)
}

/// The share of an implant's volume the prediction may leave out by each cause (beyond
/// the finest mesh; not inserted by the template) before `simulate` warns of that cause
/// ([`ImplantSummary::left_out`]).
const LEFT_OUT_WARNING_SHARE: f64 = 0.05;

/// Sets the implants of `options` on a prepared session, solves, and writes the
/// simulation folder (`model_dir` is only reported).
pub fn run_session(
    mut session: Session,
    model_dir: &Path,
    out_dir: &Path,
    options: &SimulateOptions,
    progress: &dyn Progress,
) -> Result<SimulateReport> {
    progress.stage("simulation", 2);
    let mut implants = PerSide {
        left: None,
        right: None,
    };
    for (side, request) in [(Side::Left, &options.left), (Side::Right, &options.right)] {
        if let Some(request) = request {
            *implants.get_mut(side) = Some(session.place(side, request)?);
        }
    }
    let start = Instant::now();
    let run = session
        .simulation
        .run(options.no_gravity)
        .context("solving the simulation")?;
    let time_ms = start.elapsed().as_secs_f64() * 1e3;
    progress.step();
    let last = run.gravity.as_ref().unwrap_or(&run.implant);
    let solver = SolverReport {
        vcycles: run.implant.cycles + run.gravity.as_ref().map_or(0, |g| g.cycles),
        relative_residual: last.relative_residual,
        converged: run.implant.converged && run.gravity.as_ref().is_none_or(|g| g.converged),
        time_ms,
        implant_stage_vcycles: run.implant.cycles,
        gravity_stage_vcycles: run.gravity.as_ref().map(|g| g.cycles),
        inverted_elements: session.simulation.inverted_elements().len(),
    };
    if !solver.converged {
        progress.warn(&format!(
            "the simulation stopped after {} V-cycles at relative residual {:.1e} without \
             reaching its tolerance; the prediction is approximate",
            solver.vcycles, solver.relative_residual
        ));
    }
    if solver.inverted_elements > 0 {
        progress.warn(&format!(
            "{} elements of the tissue model ended turned inside out: the predicted skin near \
             them is less trustworthy (result.json's solver.inverted_elements; a model with \
             more elements, model --elements, or a smaller implant may avoid it)",
            solver.inverted_elements
        ));
    }
    for side in Side::BOTH {
        if let Some(warning) = implants
            .get(side)
            .as_ref()
            .and_then(ImplantSummary::left_out)
        {
            progress.warn(&format!("{side} implant: {warning}"));
        }
    }
    let report = write_simulation(
        &mut session,
        &SimulationState {
            implants,
            solver,
            no_gravity: options.no_gravity,
        },
        model_dir,
        out_dir,
        progress,
    )?;
    progress.step();
    Ok(report)
}

/// Where a session's solve stands, as the simulation folder records it: the implants as
/// placed, the solver's figures and whether the gravity correction was left out.
#[derive(Debug, Clone)]
pub struct SimulationState {
    pub implants: PerSide<Option<ImplantSummary>>,
    pub solver: SolverReport,
    pub no_gravity: bool,
}

/// Writes the simulation folder of the session's current prediction (see the module
/// documentation) and returns what `result.json` holds; `state` is how the session got
/// there, `model_dir` is only reported. `result.json` is written last.
pub fn write_simulation(
    session: &mut Session,
    state: &SimulationState,
    model_dir: &Path,
    out_dir: &Path,
    progress: &dyn Progress,
) -> Result<SimulateReport> {
    let breasts = session.breast_volumes();
    for side in Side::BOTH {
        if breasts.quadrant_volume_ml.get(side).is_none() {
            progress.warn(&format!(
                "{side} breast: no quadrant volumes on the simulated scan: the moved lines from \
                 the nipple to the clavicle point and the fold's ends do not run around it in \
                 order (or one lies on its anterior axis)"
            ));
        }
    }
    let simulated = session.simulated_scan(&out_dir.join("simulated_scan.ply"))?;
    let control_points = session.simulated_control_points();
    let distances = measure(&simulated, &[], progress)?.distances;

    std::fs::create_dir_all(out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let report_path = out_dir.join("result.json");
    let mut staged = crate::staged::Staged::new();
    let mut files = Vec::new();
    staged.write(&out_dir.join("simulated_scan.ply"), |path| {
        mesh::io::write_mesh(path, &simulated.scan.mesh)
    })?;
    files.push("simulated_scan.ply".to_string());
    if let Some(texture) = &simulated.scan.texture {
        files.extend(crate::texture::stage_textured_obj(
            &mut staged,
            out_dir,
            "simulated_scan",
            &simulated.scan.mesh,
            texture,
        )?);
    }
    staged.write(&out_dir.join("simulated_landmarks.json"), |path| {
        simulated.landmarks.write(path, Default::default())
    })?;
    files.push("simulated_landmarks.json".to_string());
    staged.write(&out_dir.join(SIMULATED_CONTROL_POINTS), |path| {
        control_points.write(path)
    })?;
    files.push(SIMULATED_CONTROL_POINTS.to_string());
    staged.write(&out_dir.join("fe_result.vtu"), |path| {
        write_fe_result(path, &session.simulation)
    })?;
    files.push("fe_result.vtu".to_string());
    files.push("result.json".to_string());
    let lowering_of = |side: Side| {
        (session.simulation.implant(side)).map_or(0.0, |placed| placed.fold_lowering_mm)
    };
    let report = SimulateReport {
        software: crate::software(),
        model: model_dir.to_path_buf(),
        implant_volume_ml: session.implant_volumes_ml(),
        implants: state.implants.clone(),
        breast_volume_ml: breasts.volume_ml,
        breast_volume_before_ml: breasts.volume_before_ml,
        breast_volume_rebuilt_fill_ml: breasts.volume_rebuilt_fill_ml,
        quadrant_volume_ml: breasts.quadrant_volume_ml,
        distances,
        solver: state.solver.clone(),
        no_gravity: state.no_gravity,
        anchor: session.simulation.options().anchor_rule,
        pocket: session.simulation.options().pocket.map(|limits| {
            PerSide::from_fn(|side| PocketReport::new(&limits[side as usize], lowering_of(side)))
        }),
        nipple_to_fold_mm: PerSide::from_fn(|side| {
            let lowering_mm = lowering_of(side);
            NippleToFold::new(
                side,
                &session.simulation,
                &session.marked.landmarks,
                &simulated.landmarks,
                lowering_mm,
            )
        }),
        materials: MaterialsReport::new(session.simulation.options()),
        out_dir: out_dir.to_path_buf(),
        files,
    };
    staged.write(&report_path, |path| crate::write_json(path, &report))?;
    staged.commit()?;
    if simulated.scan.texture.is_none() {
        crate::texture::remove_textured_obj(out_dir, "simulated_scan");
    }
    Ok(report)
}

/// Writes the finest level with its displacement, constrained and sliding vertices,
/// implant elements (a released gel's where the implant was released) and the
/// pectoralis major's (1 left, 2 right; none with breast tissue there).
fn write_fe_result(path: &Path, simulation: &Simulation) -> Result<()> {
    let mesh = simulation.finest_mesh();
    let mut constrained = vec![0.0; mesh.vertex_count()];
    let mut sliding = vec![0.0; mesh.vertex_count()];
    let mut implant_elements = vec![0.0; mesh.tet_count()];
    let mut muscle = vec![0.0; mesh.tet_count()];
    if simulation.options().muscle.is_some() {
        for (code, elements) in [1.0, 2.0].iter().zip(&simulation.muscle().elements) {
            for &e in elements {
                muscle[e as usize] = *code;
            }
        }
    }
    for e in simulation.implant_elements() {
        implant_elements[e as usize] = 1.0;
    }
    for &v in simulation.wall_vertices() {
        constrained[v as usize] = 1.0;
    }
    for side in Side::BOTH {
        if let Some(placed) = simulation.implant(side) {
            let template = &placed.template;
            if !simulation.implants_released() {
                for &(v, _) in &template.implant_vertices {
                    constrained[v as usize] = 1.0;
                }
            }
            for &v in &template.fixed_vertices {
                constrained[v as usize] = 1.0;
            }
            for &(v, _) in &template.skin_vertices {
                sliding[v as usize] = 1.0;
            }
        }
    }
    tetra::vtu::write_vtu(
        path,
        mesh,
        &[
            Field::vectors(DISPLACEMENT, simulation.displacement().to_vec()),
            Field::scalars(CONSTRAINED, constrained),
            Field::scalars("sliding", sliding),
        ],
        &[
            Field::scalars("implant", implant_elements),
            Field::scalars("pectoralis_major", muscle),
        ],
    )
    .with_context(|| format!("writing {}", path.display()))
}
