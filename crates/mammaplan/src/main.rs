//! `mammaplan`: the command-line front end. A thin layer over the `plan` crate: parse
//! arguments, call one function, print a summary or JSON. No algorithms here.

mod command_line;
mod progress;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use plan::{Cup, PhantomParams, Progress};
use progress::TerminalProgress;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "mammaplan",
    version = plan::VERSION,
    about = "Breast augmentation planning from 3D surface scans"
)]
struct Cli {
    /// No progress bars or warnings on stderr.
    #[arg(long, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum CatalogCommand {
    /// Every entry: id, shape, family, dimensions (mm) and volume (ml).
    List {
        /// A CSV catalog (columns id, shape, family, width_mm, height_mm, projection_mm)
        /// instead of the built-in generic one.
        #[arg(long, value_name = "CSV")]
        catalog: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
    /// The entries closest to given dimensions or to a target volume, best first.
    Suggest {
        /// Width or diameter (mm).
        #[arg(long, value_name = "MM", value_parser = positive, requires = "projection", conflicts_with = "volume_ml")]
        width: Option<f64>,
        /// Height (mm; anatomic implants).
        #[arg(long, value_name = "MM", value_parser = positive, requires = "width")]
        height: Option<f64>,
        /// Projection (mm).
        #[arg(long, value_name = "MM", value_parser = positive, requires = "width")]
        projection: Option<f64>,
        /// Target volume (ml) instead of dimensions.
        #[arg(long, value_name = "ML", value_parser = positive, required_unless_present = "width")]
        volume_ml: Option<f64>,
        /// Only round or only anatomic implants.
        #[arg(long, value_name = "round|anatomic", value_parser = shape_kind)]
        shape: Option<plan::catalog::ShapeKind>,
        /// How many entries.
        #[arg(long, value_name = "N", default_value_t = 5, value_parser = positive_integer)]
        count: usize,
        #[arg(long, value_name = "CSV")]
        catalog: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
enum FemCommand {
    /// Static elasticity on a tetrahedral .vtu: point data `constrained` (0/1) and
    /// `displacement` (prescribed where constrained), optional cell data
    /// `young_modulus` (kPa) and `poisson_ratio`. Writes the mesh with the solved
    /// `displacement` and each element's `von_mises_kpa`.
    Solve {
        #[arg(long, value_name = "IN.vtu")]
        mesh: PathBuf,
        #[arg(long, value_name = "OUT.vtu")]
        out: PathBuf,
        /// Small-strain elasticity instead of corotated.
        #[arg(long)]
        linear: bool,
        /// Young's modulus of every element (kPa), instead of the file's.
        #[arg(long, value_name = "E", value_parser = positive)]
        young_kpa: Option<f64>,
        /// Poisson ratio of every element, instead of the file's.
        #[arg(long, value_name = "NU", value_parser = poisson_ratio)]
        poisson: Option<f64>,
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
enum Command {
    /// Run the whole pipeline on the built-in phantom and write every result to DIR.
    Demo {
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
        /// Write the phantom as an OBJ wearing its photograph (scan.obj, scan.mtl,
        /// scan.png) and run from it: the views and the simulated scan carry the texture.
        #[arg(long)]
        textured: bool,
        /// Print the report as one JSON object instead of a summary.
        #[arg(long)]
        json: bool,
    },
    /// Write the synthetic torso scan and its landmark file.
    Phantom(PhantomArgs),
    /// Clinical distances between landmarks (Euclidean, plane-section and geodesic).
    Measure {
        #[arg(long, value_name = "SCAN")]
        scan: PathBuf,
        #[arg(long, value_name = "JSON")]
        landmarks: PathBuf,
        /// An extra distance between two named points, e.g. `--pair Pj,scar_top`; repeatable.
        #[arg(long, value_name = "A,B", value_parser = landmark_pair)]
        pair: Vec<(String, String)>,
        /// Which way is up in the scan's file: an axis (+y, -z, ...) or a vector x,y,z.
        /// Without it the file's +y, or an estimate (with a warning) where the patient
        /// does not stand upright in the file.
        #[arg(long, value_name = "AXIS", value_parser = up_axis, allow_hyphen_values = true)]
        up: Option<plan::Up>,
        /// The unit of the scan files' coordinates: mm, cm, m or in. Without it
        /// millimetres, and a scan whose size is no torso's in millimetres is refused.
        #[arg(long, value_name = "UNIT")]
        units: Option<plan::LengthUnit>,
        #[arg(long)]
        json: bool,
    },
    /// Rigidly register a moving scan onto a fixed scan (bony landmarks, then optional ICP).
    Register {
        #[arg(long, value_name = "SCAN")]
        fixed: PathBuf,
        #[arg(long, value_name = "JSON")]
        fixed_landmarks: PathBuf,
        #[arg(long, value_name = "SCAN")]
        moving: PathBuf,
        #[arg(long, value_name = "JSON")]
        moving_landmarks: PathBuf,
        /// The moving scan, registered (mesh format by extension).
        #[arg(long, value_name = "SCAN")]
        out: PathBuf,
        /// Refine with point-to-plane ICP on the surface away from the breasts.
        #[arg(long)]
        icp: bool,
        /// Which way is up in both scans' files: an axis (+y, -z, ...) or a vector
        /// x,y,z. Without it the file's +y, or an estimate (with a warning) where the
        /// patient does not stand upright in the file.
        #[arg(long, value_name = "AXIS", value_parser = up_axis, allow_hyphen_values = true)]
        up: Option<plan::Up>,
        /// The unit of the scan files' coordinates: mm, cm, m or in. Without it
        /// millimetres, and a scan whose size is no torso's in millimetres is refused.
        #[arg(long, value_name = "UNIT")]
        units: Option<plan::LengthUnit>,
        #[arg(long)]
        json: bool,
    },
    /// Compare a test scan with a reference scan: surface deviation (RMS, mean, Hausdorff)
    /// over the overlap and the breast regions, distances, volumes and symmetry of both.
    Compare(CompareArgs),
    /// Build the breast model (cut curves, breast patches, fill-ins, breast and quadrant
    /// volumes) and the closed surface, and write them to MODEL_DIR.
    Model(ModelArgs),
    /// Implants on a model: the predicted post-operative scan (finite elements).
    Simulate(SimulateArgs),
    /// One self-contained HTML page about a plan (printable, nothing fetched): case, implants,
    /// views, distances and volumes before, as simulated and after, symmetry, and the
    /// comparison with the post-operative scan when given.
    Report(ReportArgs),
    /// The paper's Table I on this machine: implant set-up, multigrid cycles and the
    /// direct solver on the phantom's models.
    Bench {
        /// Finest-level element counts, one row each.
        #[arg(long, value_name = "N,N,..", value_delimiter = ',', default_values_t = plan::bench::DEFAULT_ELEMENTS, value_parser = positive_integer)]
        elements: Vec<usize>,
        /// Write the first row's finest eliminated system as Matrix Market A.mtx, b.mtx.
        #[arg(long, value_name = "DIR")]
        export_system: Option<PathBuf>,
        /// Smooth the multigrid's finest prolongation with this damping (0 to 1; 0.5
        /// gives a residual reduction of at least 5 per cycle at about twice the cost).
        #[arg(long, value_name = "W", default_value_t = 0.0, value_parser = unit_interval)]
        prolongation_smoothing: f64,
        /// The skin over thin pockets on sliders, as `simulate --skin-slides`.
        #[arg(long)]
        skin_slides: bool,
        #[arg(long)]
        json: bool,
    },
    /// Finite elements on your own meshes.
    Fem {
        #[command(subcommand)]
        command: FemCommand,
    },
    /// Implant catalogs: list the entries, or suggest the closest to a size or volume.
    Catalog {
        #[command(subcommand)]
        command: CatalogCommand,
    },
    /// The desktop planning window: landmarks placed on the scan, the breast model built,
    /// implants chosen and moved with the simulation shown live, measurements, cases.
    Gui(GuiArgs),
}

fn main() -> ExitCode {
    let cli = command_line::parse_command_line();
    let progress = TerminalProgress::new(cli.quiet);
    match run(cli.command, &progress) {
        Ok(()) => ExitCode::SUCCESS,
        // a reader that stopped reading (`| head`): quietly, as Unix tools do
        Err(error) if closed_pipe(&error) => ExitCode::FAILURE,
        Err(error) => {
            progress.finish();
            eprintln!("error: {}", plan::one_line(&error));
            ExitCode::FAILURE
        }
    }
}

/// The arguments of `mammaplan simulate`.
#[derive(clap::Args)]
struct SimulateArgs {
    /// A model folder written by `mammaplan model`.
    #[arg(long, value_name = "MODEL_DIR")]
    model: PathBuf,
    /// Left implant: round:diameter=D,projection=P | anatomic:width=W,height=H,projection=P
    /// | catalog:ID (mm).
    #[arg(long, value_name = "SPEC", required_unless_present = "right")]
    left: Option<String>,
    /// Right implant, as --left.
    #[arg(long, value_name = "SPEC")]
    right: Option<String>,
    /// Move the left implant from its default position (mm, anatomical frame: x to
    /// the patient's left, y up, z anterior).
    #[arg(long, value_name = "DX,DY,DZ", value_parser = vector_mm, requires = "left", allow_hyphen_values = true)]
    move_left: Option<[f64; 3]>,
    /// Move the right implant, as --move-left.
    #[arg(long, value_name = "DX,DY,DZ", value_parser = vector_mm, requires = "right", allow_hyphen_values = true)]
    move_right: Option<[f64; 3]>,
    /// Turn the left implant about the chest wall's normal (degrees, counter-clockwise
    /// seen from the front; for anatomic implants).
    #[arg(long, value_name = "DEG", value_parser = angle_deg, requires = "left", allow_hyphen_values = true)]
    rotate_left: Option<f64>,
    /// Turn the right implant, as --rotate-left.
    #[arg(long, value_name = "DEG", value_parser = angle_deg, requires = "right", allow_hyphen_values = true)]
    rotate_right: Option<f64>,
    /// Skip the gravity correction.
    #[arg(long)]
    no_gravity: bool,
    /// Simulate homogeneous tissue up to the surface (the paper's model) instead of
    /// a stiff skin membrane over it.
    #[arg(long)]
    no_skin: bool,
    /// Give the pectoralis major's elements the breast tissue's material (the paper's
    /// homogeneous model) instead of the stiffer muscle's.
    #[arg(long)]
    no_muscle: bool,
    /// Experimental: once the template's implant has pushed the tissue, release it as a
    /// deformable, nearly incompressible gel of this Young's modulus (kPa), stress-free in
    /// the template's shape, so that tissue that resists more (a muscle) compresses it.
    #[arg(long, value_name = "KPA")]
    implant_gel_kpa: Option<f64>,
    /// Leave volume loss to the corotated energy (the paper's model) instead of
    /// resisting every loss with twice the first Lamé parameter (see docs/dev/volume-loss.md).
    #[arg(long)]
    no_compression_penalty: bool,
    /// Let the skin over a thin pocket (beyond the native breast, a lowered fold) slide
    /// over the implant instead of holding it: fewer elements sheared over where held
    /// and free skin meet, but slower to converge (docs/dev/model-on-every-body.md).
    #[arg(long)]
    skin_slides: bool,
    /// A CSV catalog for catalog:ID specs instead of the built-in one.
    #[arg(long, value_name = "CSV")]
    catalog: Option<PathBuf>,
    /// Default implant position, which the moves start from: on-fold (the implant's
    /// lower edge on the planned fold, straight down from behind the nipple), footprint-centre (centred on
    /// the breast's base) or behind-nipple (straight behind the nipple); each is moved
    /// along the chest wall until the implant fits in its pocket.
    #[arg(long, value_name = "RULE", default_value = "on-fold")]
    anchor: plan::simulate::AnchorRule,
    /// Lower the left fold by this much (mm): the pocket reaches this far below the
    /// native fold's lowest point (PSMFl). Default: as the ICE principle plans it for
    /// the implant (half its height plus its projection, less the nipple-to-fold
    /// distance; 0 to 30 mm).
    #[arg(long, value_name = "MM", value_parser = non_negative)]
    lower_fold_left: Option<f64>,
    /// Lower the right fold by this much (mm), as --lower-fold-left.
    #[arg(long, value_name = "MM", value_parser = non_negative)]
    lower_fold_right: Option<f64>,
    /// The simulation folder (created if needed).
    #[arg(long, value_name = "SIM_DIR")]
    out: PathBuf,
    #[arg(long)]
    json: bool,
}

/// Runs `mammaplan simulate`.
fn simulate_command(args: SimulateArgs, progress: &TerminalProgress) -> Result<()> {
    let SimulateArgs {
        model,
        left,
        right,
        move_left,
        move_right,
        rotate_left,
        rotate_right,
        no_gravity,
        no_skin,
        no_muscle,
        implant_gel_kpa,
        no_compression_penalty,
        skin_slides,
        catalog,
        anchor,
        lower_fold_left,
        lower_fold_right,
        out,
        json,
    } = args;
    let request = |spec: Option<String>, move_mm: Option<[f64; 3]>, rotation: Option<f64>| {
        spec.map(|spec| plan::simulate::ImplantRequest {
            move_mm: move_mm.unwrap_or_default().into(),
            rotation_deg: rotation.unwrap_or(0.0),
            ..plan::simulate::ImplantRequest::new(spec)
        })
    };
    let options = plan::simulate::SimulateOptions {
        left: request(left, move_left, rotate_left),
        right: request(right, move_right, rotate_right),
        no_gravity,
        catalog,
        anchor,
        fold_lowering_mm: plan::model::PerSide {
            left: lower_fold_left,
            right: lower_fold_right,
        },
        no_skin,
        no_muscle,
        implant_gel_kpa,
        no_compression_penalty,
        skin_slides,
    };
    let report = plan::simulate::simulate(&model, &out, &options, progress)?;
    progress.finish();
    if json {
        print_json(&report)
    } else {
        say(summary::simulation(&report))?;
        Ok(())
    }
}

/// The arguments of `mammaplan model`.
#[derive(clap::Args)]
struct ModelArgs {
    #[arg(long, value_name = "SCAN")]
    scan: PathBuf,
    #[arg(long, value_name = "JSON")]
    landmarks: PathBuf,
    /// The model folder (created if needed).
    #[arg(long, value_name = "MODEL_DIR")]
    out: PathBuf,
    /// Cut-curve control points to use instead of the defaults from the landmarks
    /// (the format of MODEL_DIR/control_points.json).
    #[arg(long, value_name = "JSON")]
    control_points: Option<PathBuf>,
    /// Where the upper control point lies on the on-surface line from Pc to Pn
    /// (between 0 and 1); not with --control-points.
    #[arg(long, value_name = "R", default_value_t = plan::model::DEFAULT_PC_RATIO, value_parser = open_unit_interval, conflicts_with = "control_points")]
    pc_ratio: f64,
    /// How far the filled base is shifted back to form the rear wall (mm, up to 60).
    #[arg(long, value_name = "MM", default_value_t = plan::model::DEFAULT_REAR_WALL_OFFSET_MM, value_parser = rear_wall_offset)]
    rear_wall_offset_mm: f64,
    /// About how many tetrahedra the finest uniform mesh level has (within about 20%;
    /// default 60000).
    #[arg(long, value_name = "N", value_parser = positive_integer)]
    elements: Option<usize>,
    /// The resolution by what it is for, instead of --elements: draft (15000
    /// elements), standard (60000) or accurate (240000, for a report; see
    /// docs/dev/discretisation.md).
    #[arg(long, value_name = "QUALITY", conflicts_with = "elements")]
    quality: Option<plan::model::Quality>,
    /// Adds a finest level refined within this distance of both fill-ins, where the
    /// implant sits (mm; e.g. 5). Costs several times the elements.
    #[arg(long, value_name = "MM", value_parser = positive)]
    refine_band_mm: Option<f64>,
    /// Longest element edge in the refined band (mm).
    #[arg(long, value_name = "MM", default_value_t = plan::model::DEFAULT_REFINE_EDGE_MM, value_parser = positive, requires = "refine_band_mm")]
    refine_edge_mm: f64,
    /// Which way is up in the scan's file: an axis (+y, -z, ...) or a vector x,y,z.
    /// Without it the file's +y, or an estimate (with a warning) where the patient
    /// does not stand upright in the file.
    #[arg(long, value_name = "AXIS", value_parser = up_axis, allow_hyphen_values = true)]
    up: Option<plan::Up>,
    /// The unit of the scan files' coordinates: mm, cm, m or in. Without it
    /// millimetres, and a scan whose size is no torso's in millimetres is refused.
    #[arg(long, value_name = "UNIT")]
    units: Option<plan::LengthUnit>,
    #[arg(long)]
    json: bool,
}

/// Runs `mammaplan model`.
fn model_command(args: ModelArgs, progress: &TerminalProgress) -> Result<()> {
    let ModelArgs {
        scan,
        landmarks,
        out,
        control_points,
        pc_ratio,
        rear_wall_offset_mm,
        elements,
        quality,
        refine_band_mm,
        refine_edge_mm,
        up,
        units,
        json,
    } = args;
    let elements = elements
        .or(quality.map(plan::model::Quality::elements))
        .unwrap_or(plan::model::DEFAULT_ELEMENTS);
    let marked = plan::MarkedScan::load_in(&scan, units, &landmarks, up, progress)?;
    let mut options = plan::model::ModelOptions {
        control_points_file: control_points,
        elements,
        refinement: refine_band_mm.map(|band_mm| plan::model::Refinement {
            band_mm,
            max_edge_mm: refine_edge_mm,
        }),
        ..Default::default()
    };
    options.breast.pc_ratio = pc_ratio;
    options.closed_surface.rear_wall_offset_mm = rear_wall_offset_mm;
    let model = plan::model::build_model(&marked, &options, progress)?;
    let report = plan::model::write_model(&out, &model, progress)?;
    progress.finish();
    if json {
        print_json(&report)
    } else {
        say(summary::model(&report))?;
        Ok(())
    }
}

/// The arguments of `mammaplan gui`.
#[derive(clap::Args)]
struct GuiArgs {
    /// A scan to open (PLY, OBJ or STL).
    #[arg(long, value_name = "SCAN", conflicts_with_all = ["phantom", "case"])]
    scan: Option<PathBuf>,
    /// Its landmark file (required landmarks may be missing: place them in the window).
    #[arg(long, value_name = "JSON", requires = "scan")]
    landmarks: Option<PathBuf>,
    /// Which way is up in the scan's file, as `model --up`.
    #[arg(long, value_name = "AXIS", value_parser = up_axis, allow_hyphen_values = true, requires = "scan")]
    up: Option<plan::Up>,
    /// The unit of the scan file's coordinates, as `model --units`.
    #[arg(long, value_name = "UNIT", requires = "scan")]
    units: Option<plan::LengthUnit>,
    /// Open the built-in phantom with its landmarks.
    #[arg(long, conflicts_with = "case")]
    phantom: bool,
    /// A planning case saved by the window (its scan, landmarks, settings and
    /// implants; the model is rebuilt).
    #[arg(long, value_name = "FILE")]
    case: Option<PathBuf>,
    /// Run a scripted session in the window (one action per line: phantom, build,
    /// implant ID, move up, wait, screenshot FILE, ...; see docs/user/gui.md).
    #[arg(long, value_name = "FILE")]
    script: Option<PathBuf>,
}

/// Runs `mammaplan gui`.
fn gui_command(args: GuiArgs, progress: &TerminalProgress) -> Result<()> {
    let GuiArgs {
        scan,
        landmarks,
        up,
        units,
        phantom,
        case,
        script,
    } = args;
    let script = script
        .map(|path| gui::script::Script::read(&path))
        .transpose()?;
    let start = match (scan, case) {
        (Some(scan), _) => {
            let mut document = gui::Document::open_scan(&scan, units)?;
            document.up = up;
            if let Some(landmarks) = landmarks {
                for warning in document.open_landmarks(&landmarks)? {
                    progress.warn(&warning);
                }
            }
            gui::Start::Document(Box::new(document))
        }
        (None, Some(case)) => {
            // Read here too, so that a bad case is an error on the terminal.
            plan::case::PlanningCase::read(&case)?;
            gui::Start::Case(case)
        }
        (None, None) if phantom => gui::Start::Document(Box::new(gui::Document::phantom(true)?)),
        (None, None) => gui::Start::Empty,
    };
    gui::run(start, script)
}

/// The arguments of `mammaplan compare`.
#[derive(clap::Args)]
struct CompareArgs {
    #[arg(long, value_name = "SCAN")]
    reference: PathBuf,
    #[arg(long, value_name = "JSON")]
    reference_landmarks: PathBuf,
    #[arg(long, value_name = "SCAN")]
    test: PathBuf,
    #[arg(long, value_name = "JSON")]
    test_landmarks: PathBuf,
    /// Register the test scan onto the reference first (bony landmarks, then ICP away
    /// from the breasts).
    #[arg(long)]
    register: bool,
    /// Write the test scan (registered) with the deviation colour map (green 0 mm to
    /// red 20 mm) and the vertex properties distance_mm, signed_distance_mm and
    /// asymmetry_mm (.ply).
    #[arg(long, value_name = "DEVIATION.ply")]
    out: Option<PathBuf>,
    /// Points farther than this from the other scan are outside the overlap (mm).
    #[arg(long, value_name = "MM", default_value_t = plan::compare::DEFAULT_MAX_DISTANCE_MM, value_parser = positive)]
    max_distance_mm: f64,
    /// Cut the reference's breasts along these control points (as `model
    /// --control-points`) instead of the defaults from its landmarks.
    #[arg(long, value_name = "JSON")]
    reference_control_points: Option<PathBuf>,
    /// Cut the test's breasts along these control points; for a simulated scan, its
    /// simulation folder's simulated_control_points.json (the model's carried with
    /// the tissue).
    #[arg(long, value_name = "JSON")]
    test_control_points: Option<PathBuf>,
    /// Which way is up in both scans' files: an axis (+y, -z, ...) or a vector
    /// x,y,z. Without it the file's +y, or an estimate (with a warning) where the
    /// patient does not stand upright in the file.
    #[arg(long, value_name = "AXIS", value_parser = up_axis, allow_hyphen_values = true)]
    up: Option<plan::Up>,
    /// The unit of the scan files' coordinates: mm, cm, m or in. Without it
    /// millimetres, and a scan whose size is no torso's in millimetres is refused.
    #[arg(long, value_name = "UNIT")]
    units: Option<plan::LengthUnit>,
    #[arg(long)]
    json: bool,
}

/// Runs `mammaplan compare`.
fn compare_command(args: CompareArgs, progress: &TerminalProgress) -> Result<()> {
    let CompareArgs {
        reference,
        reference_landmarks,
        test,
        test_landmarks,
        register,
        out,
        max_distance_mm,
        reference_control_points,
        test_control_points,
        up,
        units,
        json,
    } = args;
    let reference =
        plan::MarkedScan::load_in(&reference, units, &reference_landmarks, up, progress)?;
    let test = plan::MarkedScan::load_in(&test, units, &test_landmarks, up, progress)?;
    let options = plan::compare::CompareOptions {
        register,
        max_distance_mm,
        out,
        reference_control_points,
        test_control_points,
    };
    let report = plan::compare::compare(&reference, &test, &options, progress)?;
    progress.finish();
    if json {
        print_json(&report)
    } else {
        say(summary::comparison(&report))?;
        Ok(())
    }
}

/// The arguments of `mammaplan phantom`.
#[derive(clap::Args)]
struct PhantomArgs {
    /// Output scan (.ply, .obj or .stl). An .obj wears the phantom's photograph: a
    /// skin texture with areolas and a grid of marks (<name>.mtl and <name>.png beside
    /// it).
    #[arg(long, value_name = "SCAN")]
    out: PathBuf,
    /// Output landmark file (JSON), with the true breast volumes.
    #[arg(long, value_name = "JSON")]
    landmarks: PathBuf,
    #[arg(long, default_value = "medium")]
    cup: Cup,
    /// Breast ptosis, 0 (none) to 1 (marked).
    #[arg(long, default_value_t = PhantomParams::default().ptosis, value_parser = unit_interval)]
    ptosis: f64,
    /// Scanner noise along the normals, standard deviation in mm (damped where it would
    /// fold the scan through itself, in the crease under a large, hanging breast).
    #[arg(long, default_value_t = 0.0, value_parser = non_negative)]
    noise_mm: f64,
    /// Natural left/right asymmetry, 0 (none) to 1 (noticeable).
    #[arg(long, default_value_t = 0.0, value_parser = unit_interval)]
    asymmetry: f64,
    #[arg(long, default_value_t = PhantomParams::default().seed)]
    seed: u64,
    /// Leave out what a standing three-camera clinical scanner (cameras at -30, 0
    /// and +30 degrees) does not see: the underside of full or hanging breasts, the
    /// lateral fold, the sides; the largest connected piece is kept and hidden
    /// landmarks move to the nearest seen vertex.
    #[arg(long)]
    occlusion: bool,
}

/// Runs `mammaplan phantom`.
fn phantom_command(args: PhantomArgs, progress: &TerminalProgress) -> Result<()> {
    let PhantomArgs {
        out,
        landmarks,
        cup,
        ptosis,
        noise_mm,
        asymmetry,
        seed,
        occlusion,
    } = args;
    let params = PhantomParams {
        cup,
        ptosis,
        noise_mm,
        asymmetry,
        seed,
        occlusion,
    };
    let phantom = plan::demo::write_phantom(&params, &out, &landmarks)?;
    progress.finish();
    say(format_args!(
        "phantom: {} vertices, {} triangles -> {}\nlandmarks and true breast volumes (left {:.1} ml, right {:.1} ml) -> {}\n",
        phantom.scan.vertex_count(),
        phantom.scan.triangle_count(),
        out.display(),
        phantom.breast_volume_ml.left,
        phantom.breast_volume_ml.right,
        landmarks.display()
    ))
}

/// The arguments of `mammaplan report`.
#[derive(clap::Args)]
struct ReportArgs {
    /// A model folder written by `mammaplan model`.
    #[arg(long, value_name = "MODEL_DIR")]
    model: PathBuf,
    /// A simulation folder written by `mammaplan simulate` from that model.
    #[arg(long, value_name = "SIM_DIR")]
    simulation: PathBuf,
    /// The post-operative scan (PLY, OBJ or STL).
    #[arg(long, value_name = "SCAN", requires = "postop_landmarks")]
    postop: Option<PathBuf>,
    /// The post-operative scan's landmark file.
    #[arg(long, value_name = "JSON", requires = "postop")]
    postop_landmarks: Option<PathBuf>,
    /// Which way is up in the post-operative scan's file, as `model --up`.
    #[arg(long, value_name = "AXIS", value_parser = up_axis, allow_hyphen_values = true, requires = "postop")]
    postop_up: Option<plan::Up>,
    /// The unit of the post-operative scan's coordinates, as `model --units`.
    #[arg(long, value_name = "UNIT", requires = "postop")]
    postop_units: Option<plan::LengthUnit>,
    /// Add views of the pectoralis major (the model's `muscle_*.ply`) through the
    /// pre-operative skin.
    #[arg(long)]
    muscle: bool,
    /// The report (HTML).
    #[arg(long, value_name = "HTML")]
    out: PathBuf,
}

/// Runs `mammaplan report`.
fn report_command(args: ReportArgs, progress: &TerminalProgress) -> Result<()> {
    let ReportArgs {
        model,
        simulation,
        postop,
        postop_landmarks,
        postop_up,
        postop_units,
        muscle,
        out,
    } = args;
    let inputs = plan::report::ReportInputs {
        model_dir: model,
        simulation_dir: simulation,
        postoperative: postop.zip(postop_landmarks).map(|(scan, landmarks)| {
            plan::report::PostoperativeScan {
                scan,
                landmarks,
                up: postop_up,
                units: postop_units,
            }
        }),
        created: std::time::SystemTime::now(),
        show_muscle: muscle,
    };
    let report = plan::report::write_report(&inputs, &out, progress)?;
    progress.finish();
    say(summary::report(&report))?;
    Ok(())
}

fn run(command: Command, progress: &TerminalProgress) -> Result<()> {
    match command {
        Command::Gui(args) => gui_command(args, progress),
        Command::Demo {
            out,
            textured,
            json,
        } => {
            let report = plan::demo::demo(&out, textured, progress)?;
            progress.finish();
            if json {
                print_json(&report)
            } else {
                say(summary::demo(&report))?;
                Ok(())
            }
        }
        Command::Phantom(args) => phantom_command(args, progress),
        Command::Measure {
            scan,
            landmarks,
            pair,
            up,
            units,
            json,
        } => {
            let marked = plan::MarkedScan::load_in(&scan, units, &landmarks, up, progress)?;
            let report = plan::measure::measure(&marked, &pair, progress)?;
            progress.finish();
            if json {
                print_json(&report)
            } else {
                say(summary::distances(&report.distances))?;
                say(summary::up(&report.up))?;
                Ok(())
            }
        }
        Command::Register {
            fixed,
            fixed_landmarks,
            moving,
            moving_landmarks,
            out,
            icp,
            up,
            units,
            json,
        } => {
            let fixed = plan::MarkedScan::load_in(&fixed, units, &fixed_landmarks, up, progress)?;
            let moving =
                plan::MarkedScan::load_in(&moving, units, &moving_landmarks, up, progress)?;
            let (transform, report) = plan::register::register(&fixed, &moving, icp)?;
            plan::register::write_registered_mesh(&out, &moving, &transform)?;
            progress.finish();
            if json {
                print_json(&report)
            } else {
                say(summary::registration(&report))?;
                Ok(())
            }
        }
        Command::Compare(args) => compare_command(args, progress),
        Command::Catalog { command } => catalog(command),
        Command::Bench {
            elements,
            export_system,
            prolongation_smoothing,
            skin_slides,
            json,
        } => {
            let report = plan::bench::bench(
                &elements,
                prolongation_smoothing,
                skin_slides,
                export_system.as_deref(),
                progress,
            )?;
            progress.finish();
            if json {
                print_json(&report)
            } else {
                say(summary::bench(&report))?;
                Ok(())
            }
        }
        Command::Simulate(args) => simulate_command(args, progress),
        Command::Report(args) => report_command(args, progress),
        Command::Fem {
            command:
                FemCommand::Solve {
                    mesh,
                    out,
                    linear,
                    young_kpa,
                    poisson,
                    json,
                },
        } => {
            let options = plan::fem_solve::FemSolveOptions {
                linear,
                young_kpa,
                poisson_ratio: poisson,
            };
            let report = plan::fem_solve::fem_solve(&mesh, &out, &options)?;
            progress.finish();
            if json {
                print_json(&report)
            } else {
                say(summary::fem_solve(&report))?;
                Ok(())
            }
        }
        Command::Model(args) => model_command(args, progress),
    }
}

fn catalog(command: CatalogCommand) -> Result<()> {
    match command {
        CatalogCommand::List { catalog, json } => {
            let source = catalog_source(catalog.as_deref());
            let catalog = plan::catalog::load(catalog.as_deref())?;
            if json {
                print_json(&plan::catalog::CatalogListing {
                    source,
                    entries: catalog.entries(),
                })
            } else {
                say(summary::catalog_entries(
                    &source,
                    catalog.entries().iter(),
                    None,
                ))?;
                Ok(())
            }
        }
        CatalogCommand::Suggest {
            width,
            height,
            projection,
            volume_ml,
            shape,
            count,
            catalog,
            json,
        } => {
            let source = catalog_source(catalog.as_deref());
            let loaded = plan::catalog::load(catalog.as_deref())?;
            let target = match (width, projection, volume_ml) {
                (Some(width_mm), Some(projection_mm), _) => {
                    plan::catalog::SuggestTarget::Dimensions {
                        width_mm,
                        height_mm: height,
                        projection_mm,
                    }
                }
                (_, _, Some(volume_ml)) => plan::catalog::SuggestTarget::Volume { volume_ml },
                _ => anyhow::bail!("give --width and --projection (and --height), or --volume-ml"),
            };
            let report = plan::catalog::suggest(&loaded, source, &target, shape, count)?;
            if json {
                print_json(&report)
            } else {
                say(summary::suggestions(&report))?;
                Ok(())
            }
        }
    }
}

fn catalog_source(csv: Option<&std::path::Path>) -> String {
    csv.map_or_else(|| "builtin".to_string(), |p| p.display().to_string())
}

fn shape_kind(text: &str) -> Result<plan::catalog::ShapeKind, String> {
    match text {
        "round" => Ok(plan::catalog::ShapeKind::Round),
        "anatomic" => Ok(plan::catalog::ShapeKind::Anatomic),
        _ => Err(format!("expected round or anatomic, got {text:?}")),
    }
}

fn print_json(value: &impl serde::Serialize) -> Result<()> {
    say(format_args!("{}\n", serde_json::to_string_pretty(value)?))
}

/// Whether `error` comes from writing to a pipe whose reader has gone.
fn closed_pipe(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Writes `text` to standard output: a closed pipe or a full disk is an error that says
/// so, not a panic.
fn say(text: impl std::fmt::Display) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    write!(out, "{text}")
        .and_then(|()| out.flush())
        .context("cannot write to standard output")
}

fn unit_interval(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if (0.0..=1.0).contains(&x) => Ok(x),
        _ => Err(format!("expected a number from 0 to 1, got {text:?}")),
    }
}

fn open_unit_interval(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x > 0.0 && x < 1.0 => Ok(x),
        _ => Err(format!(
            "expected a number between 0 and 1 (exclusive), got {text:?}"
        )),
    }
}

fn positive(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x > 0.0 && x.is_finite() => Ok(x),
        _ => Err(format!("expected a number > 0, got {text:?}")),
    }
}

fn rear_wall_offset(text: &str) -> Result<f64, String> {
    let max = plan::model::MAX_REAR_WALL_OFFSET_MM;
    match text.parse::<f64>() {
        Ok(x) if x > 0.0 && x <= max => Ok(x),
        _ => Err(format!(
            "expected a number > 0 and at most {max} mm (the chest wall lies some 10 to 30 mm \
             behind the breast's base), got {text:?}"
        )),
    }
}

fn angle_deg(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if (-360.0..=360.0).contains(&x) => Ok(x),
        _ => Err(format!(
            "expected an angle from -360 to 360 degrees, got {text:?}"
        )),
    }
}

fn vector_mm(text: &str) -> Result<[f64; 3], String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected three numbers dx,dy,dz in mm, got {text:?}"))?;
    match values[..] {
        [x, y, z] if values.iter().all(|v| v.is_finite()) => Ok([x, y, z]),
        _ => Err(format!(
            "expected three numbers dx,dy,dz in mm, got {text:?}"
        )),
    }
}

fn poisson_ratio(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x > -1.0 && x < 0.5 => Ok(x),
        _ => Err(format!(
            "expected a Poisson ratio above -1 and below 0.5, got {text:?}"
        )),
    }
}

fn positive_integer(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(format!("expected a whole number > 0, got {text:?}")),
    }
}

fn non_negative(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x >= 0.0 && x.is_finite() => Ok(x),
        _ => Err(format!("expected a number >= 0, got {text:?}")),
    }
}

fn landmark_pair(text: &str) -> Result<(String, String), String> {
    match text.split_once(',') {
        Some((a, b)) if !a.trim().is_empty() && !b.trim().is_empty() => {
            Ok((a.trim().to_string(), b.trim().to_string()))
        }
        _ => Err(format!(
            "expected two point names separated by a comma, got {text:?}"
        )),
    }
}

/// `--up`: an axis or a vector ([`plan::Up::parse`]).
fn up_axis(text: &str) -> Result<plan::Up, String> {
    plan::Up::parse(text).map_err(|e| e.to_string())
}

mod summary;
