//! What a report shows, as plain data. Units: millimetres, millilitres (cm³), degrees.
//! Every section whose data is absent (an empty list, `None`) is left out of the page.

use crate::png::{PngError, PngSize};

/// Everything one report shows.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportContent {
    /// The page title (e.g. "Breast augmentation plan").
    pub title: String,
    /// Patient-free case metadata: files, date, software, model parameters.
    pub case: CaseInfo,
    /// The implant on each side (`None`: no implant on that side).
    pub implants: PerSide<Option<ImplantChoice>>,
    /// Rendered views of the scans, in the order shown.
    pub views: Vec<View>,
    /// The clinical distances of each scan.
    pub measurements: Vec<MeasurementRow>,
    /// Breast and quadrant volumes of each scan.
    pub volumes: VolumeTable,
    /// Surface deviation between the simulated and the post-operative scan.
    pub comparison: Option<Comparison>,
    /// Left against right, one row per scan.
    pub symmetry: Vec<SymmetryRow>,
    /// Remarks the reader must see (e.g. a simulation that did not converge).
    pub notes: Vec<String>,
}

/// A value for the patient's left and one for the right.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PerSide<T> {
    pub left: T,
    pub right: T,
}

impl<T> PerSide<T> {
    /// `(label, value)` for the left, then the right.
    pub fn labelled(&self) -> [(&'static str, &T); 2] {
        [("Left", &self.left), ("Right", &self.right)]
    }
}

/// Patient-free case metadata.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseInfo {
    /// When the report was made (e.g. `2026-11-22 09:41 UTC`).
    pub created: String,
    /// The software and its version (e.g. `mammaplan 0.1.0`).
    pub software: String,
    /// The input files by their role, file names only (no folders).
    pub files: Vec<CaseFile>,
    /// The finite-element model.
    pub model: ModelParameters,
}

/// One input file.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseFile {
    /// What it is (e.g. "Pre-operative scan").
    pub role: String,
    /// Its file name.
    pub name: String,
}

/// The settings and size of the simulation model.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelParameters {
    /// Tetrahedra and nodes of the finest mesh level.
    pub finest_elements: usize,
    pub finest_nodes: usize,
    /// Levels of the multigrid hierarchy.
    pub mesh_levels: usize,
    /// How far the rear wall lies behind the breast's base (mm).
    pub rear_wall_offset_mm: f64,
    pub tissue: MaterialParameters,
    pub implant_material: MaterialParameters,
    /// The skin layer over the tissue in words; `None`: homogeneous tissue up to the
    /// surface.
    pub skin: Option<String>,
    /// The resistance to large volume loss added to the corotated energy, in words;
    /// `None`: the paper's corotated energy.
    pub compression_penalty: Option<String>,
    /// Whether the weight of the implant was simulated (paper V-B).
    pub gravity_correction: bool,
    /// Which way was up in the scan (the direction gravity acts against), in words.
    pub up: String,
    /// The pocket's limits in words; `None`: the implant bed was the fill-in alone.
    pub pocket: Option<String>,
    /// How the solve ended.
    pub solver: SolverSummary,
}

/// An isotropic elastic material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaterialParameters {
    pub young_kpa: f64,
    pub poisson_ratio: f64,
    pub density_kg_m3: f64,
}

/// The end of the finite-element solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverSummary {
    pub vcycles: usize,
    pub relative_residual: f64,
    pub converged: bool,
}

/// The implant chosen for one side.
#[derive(Debug, Clone, PartialEq)]
pub struct ImplantChoice {
    /// The spec as given (e.g. `catalog:R-MOD-120`, `round:diameter=115,projection=33`).
    pub spec: String,
    /// The catalog entry, when the implant came from a catalog.
    pub catalog: Option<CatalogReference>,
    /// Shape and variant (e.g. "round, ellipsoid profile").
    pub shape: String,
    pub width_mm: f64,
    pub height_mm: f64,
    pub projection_mm: f64,
    pub volume_ml: f64,
    /// Where the default position lies (e.g. "centred on the breast's base").
    pub default_position: String,
    /// The move from the default position asked for (mm, anatomical frame: x to the
    /// patient's left, y up, z anterior).
    pub offset_mm: [f64; 3],
    /// The turn about the chest wall's normal asked for (degrees, counter-clockwise seen
    /// from the front).
    pub rotation_deg: f64,
    /// The further move along the chest wall that made the implant fit its base (mm,
    /// lateral-left and up); zero when it fitted as asked.
    pub fit_shift_mm: [f64; 2],
}

/// A catalog entry.
#[derive(Debug, Clone, PartialEq)]
pub struct CatalogReference {
    pub id: String,
    pub family: String,
}

/// A rendered image with optional text labels drawn over it.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// Shown under the image (e.g. "Simulated, frontal").
    pub title: String,
    /// A further line under the title.
    pub caption: Option<String>,
    png: Vec<u8>,
    size: PngSize,
    /// Labels at pixel positions of the image (e.g. landmark names at their markers).
    pub labels: Vec<ImageLabel>,
    /// The colour scale of a colour-mapped image (e.g. [`ColourScale::deviation_mm`]),
    /// drawn as a legend under it.
    pub colour_scale: Option<ColourScale>,
}

impl View {
    /// A view of a PNG image (its bytes as encoded), without labels or colour scale.
    /// Errors: the bytes do not start with a PNG signature and header, or the image is
    /// empty.
    pub fn new(title: impl Into<String>, png: Vec<u8>) -> Result<View, PngError> {
        let size = PngSize::read(&png)?;
        Ok(View {
            title: title.into(),
            caption: None,
            png,
            size,
            labels: Vec::new(),
            colour_scale: None,
        })
    }

    /// The PNG bytes, as given.
    pub fn png(&self) -> &[u8] {
        &self.png
    }

    /// The image's width and height (pixels).
    pub fn size_px(&self) -> (u32, u32) {
        (self.size.width, self.size.height)
    }
}

/// A text drawn over an image.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageLabel {
    pub text: String,
    /// The point labelled (pixels from the image's top-left corner, x to the right, y
    /// down); the text is drawn just above and to the right of it.
    pub x_px: f64,
    pub y_px: f64,
}

/// A colour map's legend: a gradient from `min` to `max` through `stops`.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourScale {
    /// What is mapped, with its unit (e.g. "Distance to the reference surface (mm)").
    pub label: String,
    pub min: f64,
    pub max: f64,
    /// Values at or above `max` get the last colour (the legend's last tick reads ≥ max).
    pub saturates_above_max: bool,
    /// Colours along the range, `fraction` from 0 (`min`) to 1 (`max`), increasing.
    pub stops: Vec<ColourStop>,
}

/// One colour of a [`ColourScale`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColourStop {
    pub fraction: f64,
    pub rgb: [u8; 3],
}

/// Upper end of the deviation colour map (mm; paper Fig. 3).
pub const DEVIATION_SCALE_MAX_MM: f64 = 20.0;

impl ColourScale {
    /// The surface deviation map: green at 0 mm, yellow halfway, red at
    /// [`DEVIATION_SCALE_MAX_MM`] and beyond, as in the paper's Fig. 3.
    pub fn deviation_mm() -> ColourScale {
        ColourScale {
            label: "Distance to the reference surface (mm)".into(),
            min: 0.0,
            max: DEVIATION_SCALE_MAX_MM,
            saturates_above_max: true,
            stops: vec![
                ColourStop {
                    fraction: 0.0,
                    rgb: [0, 255, 0],
                },
                ColourStop {
                    fraction: 0.5,
                    rgb: [255, 255, 0],
                },
                ColourStop {
                    fraction: 1.0,
                    rgb: [255, 0, 0],
                },
            ],
        }
    }
}

/// One clinical distance on each scan, measured along the skin (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementRow {
    /// E.g. `Pj-Pnl`.
    pub name: String,
    pub preoperative_mm: Option<f64>,
    pub simulated_mm: Option<f64>,
    /// Only with a post-operative scan.
    pub postoperative_mm: Option<f64>,
}

/// The volumes of one breast (ml).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BreastVolumes {
    pub breast_ml: f64,
    pub quadrants_ml: Option<QuadrantVolumes>,
}

/// The four quadrants of one breast (ml); "inner" is medial, "outer" lateral.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadrantVolumes {
    pub upper_outer_ml: f64,
    pub upper_inner_ml: f64,
    pub lower_inner_ml: f64,
    pub lower_outer_ml: f64,
}

impl QuadrantVolumes {
    /// The quadrants' names, in the order of [`QuadrantVolumes::values_ml`].
    pub const NAMES: [&'static str; 4] =
        ["upper outer", "upper inner", "lower inner", "lower outer"];

    /// The four volumes (ml), in the order of [`QuadrantVolumes::NAMES`].
    pub fn values_ml(&self) -> [f64; 4] {
        [
            self.upper_outer_ml,
            self.upper_inner_ml,
            self.lower_inner_ml,
            self.lower_outer_ml,
        ]
    }
}

/// Breast and quadrant volumes before, as simulated and after.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VolumeTable {
    pub preoperative: PerSide<BreastVolumes>,
    pub simulated: Option<PerSide<BreastVolumes>>,
    pub postoperative: Option<PerSide<BreastVolumes>>,
}

/// The surface deviation of a test scan from a reference scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// E.g. "Post-operative scan".
    pub reference: String,
    /// E.g. "Simulated scan".
    pub test: String,
    /// One row per region (whole overlap, each breast).
    pub regions: Vec<DeviationFigures>,
}

/// Distances from the test surface to the reference surface over one region (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct DeviationFigures {
    /// E.g. "Whole overlap", "Left breast".
    pub region: String,
    pub rms_mm: f64,
    pub mean_mm: f64,
    /// Symmetric Hausdorff distance.
    pub hausdorff_mm: f64,
}

/// Left against right on one scan, across the mid-sagittal plane (the plane through Pj
/// and Px orthogonal to the line Pcr-Pcl).
#[derive(Debug, Clone, PartialEq)]
pub struct SymmetryRow {
    /// E.g. "Pre-operative".
    pub scan: String,
    /// Left breast volume over right breast volume.
    pub volume_ratio_left_to_right: f64,
    /// Left nipple height minus right nipple height (mm; positive: the left is higher).
    pub nipple_height_difference_mm: f64,
    /// Left nipple's distance to the mid-sagittal plane minus the right's (mm).
    pub nipple_midline_difference_mm: f64,
    /// Distance between the left nipple and the right nipple mirrored across the
    /// mid-sagittal plane (mm): 0 for perfectly symmetric nipples.
    pub nipple_mirror_distance_mm: f64,
}
