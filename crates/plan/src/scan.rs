//! A scan loaded for work: the mesh with its connectivity and spatial index, and
//! optionally its landmarks, snapped and turned into an anatomical frame.

use anatomy::{AnatomicalFrame, Landmarks, Up, UpSource};
use anyhow::{Context, Result, bail};
use mesh::{LengthUnit, SurfaceIndex, Topology, TriMesh};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::texture::{ScanTexture, load_texture};

/// Triangles with less area than this are dropped on load (mm²).
const DEGENERATE_AREA_MM2: f64 = 1e-10;

/// How large a torso scan is across (its bounding box's longest side, mm): a file whose
/// coordinates give less or more is in another unit.
pub const SCAN_EXTENT_MM: std::ops::RangeInclusive<f64> = 100.0..=3_000.0;

/// A surface scan ready for queries (millimetres).
pub struct Scan {
    /// Where it came from (for messages and reports).
    pub path: PathBuf,
    /// The unit of the file's coordinates (converted to millimetres when read).
    pub file_unit: LengthUnit,
    pub mesh: TriMesh,
    pub topology: Topology,
    pub index: SurfaceIndex,
    /// The photograph its file names, through the mesh's texture coordinates (`None`:
    /// none, or it could not be read, which was a warning).
    pub texture: Option<Arc<ScanTexture>>,
}

impl Scan {
    /// Reads and validates a mesh file in millimetres ([`Scan::load_in`] without a unit).
    pub fn load(path: &Path, progress: &dyn crate::Progress) -> Result<Scan> {
        Scan::load_in(path, None, progress)
    }

    /// Reads and validates a mesh file whose coordinates are in `unit` (converted to
    /// millimetres), or in millimetres if `None`, in which case a scan whose size is no
    /// torso's in millimetres ([`SCAN_EXTENT_MM`]) is refused, naming the unit that fits
    /// and `--units`. Degenerate (zero-area) triangles, triangles that repeat another and
    /// fins ([`mesh::fin_triangles`]) are dropped with a warning that counts them and
    /// names the first.
    pub fn load_in(
        path: &Path,
        unit: Option<LengthUnit>,
        progress: &dyn crate::Progress,
    ) -> Result<Scan> {
        let mut mesh = mesh::io::read_mesh(path)?;
        let file_unit = unit.unwrap_or(LengthUnit::Millimetre);
        check_scan_size(&mesh, unit, path)?;
        if file_unit != LengthUnit::Millimetre {
            mesh.map_positions(|p| p * file_unit.mm());
        }
        let degenerate = mesh.degenerate_triangles(DEGENERATE_AREA_MM2);
        if let Some(first) = degenerate.first() {
            progress.warn(&format!(
                "{}: dropped {} zero-area triangle(s), the first is triangle {first}",
                path.display(),
                degenerate.len()
            ));
            mesh.remove_triangles(&degenerate);
        }
        let repeated = mesh.repeated_triangles();
        if let Some(first) = repeated.first() {
            progress.warn(&format!(
                "{}: dropped {} triangle(s) that repeat another on the same three vertices \
                 (a surface written twice?), the first is triangle {first}",
                path.display(),
                repeated.len()
            ));
            mesh.remove_triangles(&repeated);
        }
        let fins = mesh::fin_triangles(&mesh);
        if let Some(first) = fins.triangles.first() {
            progress.warn(&format!(
                "{}: {} edge(s) were shared by more than two triangles (fins or overlapping \
                 sheets); dropped {} triangle(s) so that one surface runs through each, the \
                 first is triangle {first}",
                path.display(),
                fins.non_manifold_edges,
                fins.triangles.len()
            ));
            mesh.remove_triangles(&fins.triangles);
        }
        let mut scan = Scan::from_mesh(mesh, path)?;
        scan.file_unit = file_unit;
        scan.texture = load_texture(path, &scan.mesh, progress).map(Arc::new);
        Ok(scan)
    }

    /// The built-in phantom torso's scan, in memory; its path (for messages) is
    /// `phantom (cup=... seed=...)`.
    pub fn phantom(params: &phantom::PhantomParams) -> Result<Scan> {
        Scan::from_mesh(phantom::generate(params).scan, &phantom_path(params))
    }

    /// The same scan with every vertex moved to `positions` (same order and count: a
    /// simulated scan): the triangles and their connectivity are kept, the spatial index
    /// is rebuilt; `path` names it in messages.
    pub fn moved_to(&self, positions: Vec<glam::DVec3>, path: &Path) -> Result<Scan> {
        anyhow::ensure!(
            positions.len() == self.mesh.vertex_count(),
            "{}: {} positions for a scan of {} vertices",
            path.display(),
            positions.len(),
            self.mesh.vertex_count()
        );
        let mut mesh = self.mesh.clone();
        mesh.positions = positions;
        mesh.validate().map_err(|e| e.in_file(path))?;
        let Some(index) = SurfaceIndex::new(&mesh) else {
            bail!("{}: the mesh has no triangles", path.display());
        };
        Ok(Scan {
            path: path.to_path_buf(),
            file_unit: self.file_unit,
            mesh,
            topology: self.topology.clone(),
            index,
            texture: self.texture.clone(),
        })
    }

    /// Gives this scan `source`'s photograph and texture coordinates when it is `source`
    /// moved vertex by vertex (the same triangles): a simulated scan read back from a
    /// PLY wears the pre-operative scan's photograph.
    pub fn wear_texture_of(&mut self, source: &Scan) {
        if source.texture.is_some()
            && source.mesh.uv.is_some()
            && self.mesh.triangles == source.mesh.triangles
        {
            self.mesh.uv = source.mesh.uv.clone();
            self.texture = source.texture.clone();
        }
    }

    /// Wraps a mesh already in memory (validated here).
    pub fn from_mesh(mesh: TriMesh, path: &Path) -> Result<Scan> {
        mesh.validate().map_err(|e| e.in_file(path))?;
        let topology = Topology::new(&mesh);
        let Some(index) = SurfaceIndex::new(&mesh) else {
            bail!("{}: the mesh has no triangles", path.display());
        };
        Ok(Scan {
            path: path.to_path_buf(),
            file_unit: LengthUnit::Millimetre,
            mesh,
            topology,
            index,
            texture: None,
        })
    }
}

/// `Err` when `mesh` (coordinates in `unit`, or millimetres if `None`) is not the size of
/// a torso ([`SCAN_EXTENT_MM`]), naming its size and the unit that would fit.
fn check_scan_size(mesh: &TriMesh, unit: Option<LengthUnit>, path: &Path) -> Result<()> {
    if mesh.positions.is_empty() {
        return Ok(());
    }
    let (lo, hi) = mesh.bounding_box();
    let extent = (hi - lo).max_element();
    let file_unit = unit.unwrap_or(LengthUnit::Millimetre);
    let extent_mm = extent * file_unit.mm();
    if SCAN_EXTENT_MM.contains(&extent_mm) {
        return Ok(());
    }
    let fits = LengthUnit::plausible(extent, &SCAN_EXTENT_MM).map_or_else(
        || "no unit of mm, cm, m or in makes it a torso: is it a body scan?".to_string(),
        |fits| {
            format!(
                "in {fits} it would be {:.0} mm: give --units {fits}",
                extent * fits.mm()
            )
        },
    );
    match unit {
        None => bail!(
            "{}: the scan is {extent:.4} units across, which is no torso in millimetres \
             ({:.0}-{:.0} mm); {fits}",
            path.display(),
            SCAN_EXTENT_MM.start(),
            SCAN_EXTENT_MM.end()
        ),
        Some(unit) => bail!(
            "{}: with --units {unit} the scan is {extent_mm:.4e} mm across, which is no torso; \
             {fits}",
            path.display()
        ),
    }
}

/// A scan with its landmarks on the surface and its anatomical frame. The scan is shared
/// (a window keeps showing it while a worker builds the model from it).
pub struct MarkedScan {
    pub scan: Arc<Scan>,
    pub landmarks: Landmarks,
    pub landmarks_path: PathBuf,
    pub frame: AnatomicalFrame,
}

impl MarkedScan {
    /// Which way is up in the scan's file, and where that came from.
    pub fn up(&self) -> Up {
        Up {
            direction: self.frame.up(),
            source: self.frame.up_source,
        }
    }
}

impl MarkedScan {
    /// Loads a scan and its landmark file, snaps landmarks within 5 mm onto the surface
    /// (warning for each moved one) and rejects farther ones. Up is `up` if given, else
    /// resolved from the file and the landmarks ([`Up::resolve`], warning if estimated).
    pub fn load(
        scan: &Path,
        landmarks: &Path,
        up: Option<Up>,
        progress: &dyn crate::Progress,
    ) -> Result<MarkedScan> {
        MarkedScan::load_in(scan, None, landmarks, up, progress)
    }

    /// [`MarkedScan::load`] for a scan file whose coordinates are in `unit`
    /// ([`Scan::load_in`]); the landmark file's own `"units"` applies to it.
    pub fn load_in(
        scan: &Path,
        unit: Option<LengthUnit>,
        landmarks: &Path,
        up: Option<Up>,
        progress: &dyn crate::Progress,
    ) -> Result<MarkedScan> {
        let scan = Scan::load_in(scan, unit, progress)?;
        let landmark_set = Landmarks::read(landmarks)?;
        MarkedScan::new(scan, landmark_set, landmarks, up, progress)
    }

    /// Attaches landmarks (already in memory) to a scan (owned or shared); `up` as for
    /// [`MarkedScan::load`].
    pub fn new(
        scan: impl Into<Arc<Scan>>,
        mut landmarks: Landmarks,
        landmarks_path: &Path,
        up: Option<Up>,
        progress: &dyn crate::Progress,
    ) -> Result<MarkedScan> {
        let scan = scan.into();
        let warnings = landmarks
            .snap_to_surface(&scan.index)
            .with_context(|| format!("{} on {}", landmarks_path.display(), scan.path.display()))?;
        for warning in warnings {
            progress.warn(&format!("{}: {warning}", landmarks_path.display()));
        }
        let up =
            Up::resolve(up, &landmarks).with_context(|| landmarks_path.display().to_string())?;
        if let Some(warning) = up.warning() {
            progress.warn(&format!("{}: {warning}", scan.path.display()));
        }
        let frame = AnatomicalFrame::from_landmarks(&landmarks, up)
            .with_context(|| landmarks_path.display().to_string())?;
        frame
            .check_sides(&landmarks)
            .with_context(|| format!("{} on {}", landmarks_path.display(), scan.path.display()))?;
        Ok(MarkedScan {
            scan,
            landmarks,
            landmarks_path: landmarks_path.to_path_buf(),
            frame,
        })
    }

    /// The built-in phantom torso with its exact landmarks, in memory; its path (for
    /// messages) is `phantom (cup=... seed=...)`.
    pub fn phantom(params: &phantom::PhantomParams) -> Result<MarkedScan> {
        let phantom = phantom::generate(params);
        let path = phantom_path(params);
        let scan = Scan::from_mesh(phantom.scan, &path)?;
        MarkedScan::new(scan, phantom.landmarks, &path, None, &crate::Silent)
    }
}

/// What names the phantom in messages.
fn phantom_path(params: &phantom::PhantomParams) -> PathBuf {
    PathBuf::from(format!("phantom ({params})"))
}

/// Which way was up in a scan's file, as `model.json`, `measure --json` and planning
/// cases record it; read back, it gives the same frame again.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct UpRecord {
    /// Against gravity, unit vector in the file's coordinates.
    pub direction: [f64; 3],
    /// `file` (the file's +y, an upright scan), `given` (`--up`) or `estimated`.
    pub source: UpSourceName,
    /// How far the sternum (Px towards Pj) leans back from this vertical (degrees).
    pub sternum_lean_deg: f64,
}

/// [`UpSource`] as JSON names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum UpSourceName {
    File,
    Given,
    Estimated,
}

impl UpRecord {
    /// The record of a frame's up.
    pub fn of(frame: &AnatomicalFrame) -> UpRecord {
        UpRecord {
            direction: frame.up().to_array(),
            source: match frame.up_source {
                UpSource::FileVertical => UpSourceName::File,
                UpSource::Given => UpSourceName::Given,
                UpSource::Estimated => UpSourceName::Estimated,
            },
            sternum_lean_deg: frame.sternum_lean_deg(),
        }
    }

    /// Which way was up, in words: the direction in the file, where it came from and the
    /// sternum's lean from it.
    pub fn in_words(&self) -> String {
        let [x, y, z] = self.direction;
        let source = match self.source {
            UpSourceName::File => "the file's +y",
            UpSourceName::Given => "given",
            UpSourceName::Estimated => "estimated from the sternum",
        };
        format!(
            "({x:.3}, {y:.3}, {z:.3}) in the scan's file, {source}; the sternum leans {:.1}° back \
             from it",
            self.sternum_lean_deg
        )
    }

    /// The up it records, with its source; an error if the direction is not a finite
    /// non-zero vector (an edited file).
    pub fn up(&self) -> Result<Up> {
        let Some(direction) = mesh::DVec3::from_array(self.direction).try_normalize() else {
            bail!(
                "\"up\": \"direction\" {:?} is not a non-zero vector",
                self.direction
            );
        };
        Ok(Up {
            direction,
            source: match self.source {
                UpSourceName::File => UpSource::FileVertical,
                UpSourceName::Given => UpSource::Given,
                UpSourceName::Estimated => UpSource::Estimated,
            },
        })
    }
}
