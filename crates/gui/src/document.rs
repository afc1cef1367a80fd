//! What the user works on: one scan and the landmarks being placed on it, with the
//! editing rules (which point a click places, re-placing a selected one, extra points).
//! No egui here; the surface queries go through `mesh` and the files through `plan` and
//! `anatomy`.

use anatomy::{LandmarkName, Landmarks, ON_SURFACE_MM, PartialLandmarks, Up};
use anyhow::{Context, Result, bail};
use glam::DVec3;
use mesh::SurfaceIndex;
use plan::case::{PlanningCase, ScanSource};
use plan::{MarkedScan, PhantomParams, Scan, Silent};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A scan with the landmarks placed on it so far.
pub struct Document {
    pub scan: Arc<Scan>,
    /// Where the scan came from (a file or the phantom), as a planning case records it.
    pub source: ScanSource,
    pub landmarks: PartialLandmarks,
    /// Where the landmarks were read from or last saved to.
    pub landmarks_path: Option<PathBuf>,
    /// The point a click re-places (a required landmark's or an extra point's name).
    pub selected: Option<String>,
    /// An extra point named by the user and not placed yet: the next click places it.
    pub pending_extra: Option<String>,
    /// Landmarks changed since they were read or saved.
    pub unsaved: bool,
    /// Which way is up in the scan's file, when the user said it (`--up`, a case);
    /// `None`: resolved from the file and the landmarks.
    pub up: Option<Up>,
}

/// What a click on the surface will place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Placing {
    /// The next required landmark still missing.
    Next(LandmarkName),
    /// A selected point, to be moved.
    Selected(String),
    /// A new extra point.
    Extra(String),
}

impl Placing {
    /// The point's file name.
    pub fn name(&self) -> &str {
        match self {
            Placing::Next(name) => name.as_str(),
            Placing::Selected(name) | Placing::Extra(name) => name,
        }
    }
}

impl Document {
    /// A scan (owned or shared) with no landmarks yet; `source` is where it came from.
    pub fn new(scan: impl Into<Arc<Scan>>, source: ScanSource) -> Document {
        Document {
            scan: scan.into(),
            source,
            landmarks: PartialLandmarks::default(),
            landmarks_path: None,
            selected: None,
            pending_extra: None,
            unsaved: false,
            up: None,
        }
    }

    /// Reads a scan (PLY, OBJ or STL) whose coordinates are in `unit` (`None`:
    /// millimetres, checked; see [`Scan::load_in`]).
    pub fn open_scan(path: &Path, unit: Option<plan::LengthUnit>) -> Result<Document> {
        let source = ScanSource::File(path.to_path_buf());
        Ok(Document::new(Scan::load_in(path, unit, &Silent)?, source))
    }

    /// The built-in phantom, with its exact landmarks or with none placed.
    pub fn phantom(with_landmarks: bool) -> Result<Document> {
        let params = PhantomParams::default();
        let marked = MarkedScan::phantom(&params)?;
        let landmarks = if with_landmarks {
            PartialLandmarks::from(&marked.landmarks)
        } else {
            PartialLandmarks::default()
        };
        Ok(Document {
            landmarks,
            ..Document::new(marked.scan, ScanSource::Phantom(params))
        })
    }

    /// The scan of a planning case with the case's landmarks (snapped onto it); returns
    /// the snapping warnings too.
    pub fn from_case(case: &PlanningCase, case_path: &Path) -> Result<(Document, Vec<String>)> {
        let scan = case.scan.load(case.scan_units, &Silent)?;
        let mut snapped = case.landmarks.clone();
        let warnings = snapped
            .snap_to_surface(&scan.index)
            .with_context(|| format!("the landmarks of {}", case_path.display()))?;
        // Points saved from the window lie on the surface already (to rounding) and keep
        // their saved coordinates: the reopened case is the saved one, bit for bit.
        let mut landmarks = case.landmarks.clone();
        for (name, point) in snapped.iter() {
            if landmarks
                .lookup(name)
                .is_some_and(|saved| saved.distance(point) > ON_SURFACE_MM)
            {
                landmarks.move_point(name, point);
            }
        }
        let document = Document {
            landmarks,
            up: case.up,
            ..Document::new(scan, case.scan.clone())
        };
        let warnings = warnings
            .iter()
            .map(|w| format!("{}: {w}", case_path.display()))
            .collect();
        Ok((document, warnings))
    }

    /// The scan with its landmarks, once all required ones are placed: what a model is
    /// built from.
    pub fn marked(&self) -> Result<MarkedScan> {
        let path = self.landmarks_path.clone().unwrap_or_else(|| {
            PathBuf::from(format!(
                "the landmarks placed on {}",
                self.scan.path.display()
            ))
        });
        let landmarks: Landmarks = self.landmarks.complete(&path)?;
        MarkedScan::new(Arc::clone(&self.scan), landmarks, &path, self.up, &Silent)
    }

    /// Reads a landmark file (required landmarks may be missing) and snaps its points
    /// onto the scan; returns the snapping warnings. On error nothing changes.
    pub fn open_landmarks(&mut self, path: &Path) -> Result<Vec<String>> {
        let mut landmarks = PartialLandmarks::read(path)?;
        let warnings = landmarks
            .snap_to_surface(&self.scan.index)
            .with_context(|| format!("{} on {}", path.display(), self.scan.path.display()))?;
        self.landmarks = landmarks;
        self.landmarks_path = Some(path.to_path_buf());
        self.selected = None;
        self.pending_extra = None;
        self.unsaved = false;
        Ok(warnings
            .iter()
            .map(|w| format!("{}: {w}", path.display()))
            .collect())
    }

    /// Writes the landmarks (placed ones only) atomically in the GUIDE's format.
    pub fn save_landmarks(&mut self, path: &Path) -> Result<()> {
        self.landmarks.write(path)?;
        self.landmarks_path = Some(path.to_path_buf());
        self.unsaved = false;
        Ok(())
    }

    /// What a click places now: the selected point, else a pending extra point, else the
    /// next missing required landmark; `None` when all are placed and none is selected.
    pub fn placing(&self) -> Option<Placing> {
        if let Some(name) = &self.selected {
            return Some(Placing::Selected(name.clone()));
        }
        if let Some(name) = &self.pending_extra {
            return Some(Placing::Extra(name.clone()));
        }
        self.landmarks.missing().next().map(Placing::Next)
    }

    /// The first surface point on the ray `origin + t * direction`, `t >= 0` (mm).
    pub fn pick(&self, origin: DVec3, direction: DVec3) -> Option<DVec3> {
        self.scan
            .index
            .cast_ray(origin, direction, f64::MAX)
            .map(|hit| hit.point)
    }

    /// Whether no part of the surface hides `point` from `eye` (mm): nothing on the line
    /// between them closer to the eye than `tolerance` short of the point.
    pub fn visible_from(&self, eye: DVec3, point: DVec3, tolerance: f64) -> bool {
        visible_on(&self.scan.index, eye, point, tolerance)
    }

    /// Places what [`Document::placing`] names at `point` (on the surface); returns its
    /// name. A re-placed point stays selected no longer.
    pub fn place(&mut self, point: DVec3) -> Option<String> {
        let placing = self.placing()?;
        match &placing {
            Placing::Next(name) => self.landmarks.set(*name, point),
            Placing::Selected(name) => {
                self.landmarks.move_point(name, point);
                self.selected = None;
            }
            Placing::Extra(name) => {
                self.landmarks.extra.insert(name.clone(), point);
                self.pending_extra = None;
            }
        }
        self.unsaved = true;
        Some(placing.name().to_string())
    }

    /// Moves a placed point while it is dragged along the surface.
    pub fn drag_to(&mut self, name: &str, point: DVec3) {
        if self.landmarks.move_point(name, point) {
            self.unsaved = true;
        }
    }

    /// Selects a placed point for re-placing, or deselects it if it was selected.
    pub fn toggle_selection(&mut self, name: &str) {
        if self.selected.as_deref() == Some(name) {
            self.selected = None;
        } else {
            self.selected = Some(name.to_string());
            self.pending_extra = None;
        }
    }

    /// Names an extra point for the next click. Names must be new, non-empty and not a
    /// required landmark's.
    pub fn add_extra(&mut self, name: &str) -> Result<()> {
        let name = name.trim();
        if name.is_empty() {
            bail!("give the extra point a name first");
        }
        if LandmarkName::parse(name).is_some() || self.landmarks.extra.contains_key(name) {
            bail!("a point named \"{name}\" already exists: select it to move it");
        }
        self.pending_extra = Some(name.to_string());
        self.selected = None;
        Ok(())
    }

    /// Removes an extra point.
    pub fn remove_extra(&mut self, name: &str) {
        if self.landmarks.extra.remove(name).is_some() {
            self.unsaved = true;
        }
        if self.selected.as_deref() == Some(name) {
            self.selected = None;
        }
    }

    /// Where a file dropped on the window or typed in the path field goes: `.json` files
    /// are landmarks, everything else a scan.
    pub fn is_landmark_file(path: &Path) -> bool {
        path.extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"))
    }
}

/// Whether no part of the surface of `index` hides `point` from `eye` (mm): nothing on
/// the line between them closer to the eye than `tolerance` short of the point.
pub fn visible_on(index: &SurfaceIndex, eye: DVec3, point: DVec3, tolerance: f64) -> bool {
    let offset = point - eye;
    let distance = offset.length();
    distance <= tolerance
        || index
            .cast_ray(eye, offset / distance, distance - tolerance)
            .is_none()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_document() -> Document {
        let path = Path::new("grid.ply");
        let scan = Scan::from_mesh(mesh::shapes::grid(20, 20, 1.0), path).unwrap();
        Document::new(scan, ScanSource::File(path.to_path_buf()))
    }

    #[test]
    fn clicks_place_the_missing_landmarks_in_order_then_selected_and_extra_points() {
        let mut document = grid_document();
        assert_eq!(document.placing(), Some(Placing::Next(LandmarkName::Pj)));
        let hit = document
            .pick(DVec3::new(3.0, 4.0, 10.0), DVec3::NEG_Z)
            .unwrap();
        assert!(hit.distance(DVec3::new(3.0, 4.0, 0.0)) < 1e-9);
        assert_eq!(document.place(hit).as_deref(), Some("Pj"));
        assert_eq!(document.placing(), Some(Placing::Next(LandmarkName::Pcl)));
        assert!(document.unsaved);
        assert!(
            document
                .pick(DVec3::new(3.0, 4.0, 10.0), DVec3::Z)
                .is_none()
        );
        assert!(document.visible_from(DVec3::new(3.0, 4.0, 10.0), hit, 0.5));
        // The sheet is open: seen from below, the point is visible too; a point above
        // the sheet seen from below is hidden by it.
        assert!(document.visible_from(DVec3::new(3.0, 4.0, -10.0), hit, 0.5));
        assert!(!document.visible_from(
            DVec3::new(3.0, 4.0, -10.0),
            DVec3::new(3.0, 4.0, 5.0),
            0.5
        ));

        document.toggle_selection("Pj");
        assert_eq!(document.placing(), Some(Placing::Selected("Pj".into())));
        document.place(DVec3::new(5.0, 5.0, 0.0));
        assert_eq!(
            document.landmarks.get(LandmarkName::Pj),
            Some(DVec3::new(5.0, 5.0, 0.0))
        );
        assert_eq!(document.placing(), Some(Placing::Next(LandmarkName::Pcl)));

        assert!(document.add_extra("  ").is_err());
        assert!(document.add_extra("Pj").is_err());
        document.add_extra(" scar ").unwrap();
        assert_eq!(
            document.place(DVec3::new(1.0, 1.0, 0.0)).as_deref(),
            Some("scar")
        );
        assert!(document.add_extra("scar").is_err());
        document.drag_to("scar", DVec3::new(2.0, 1.0, 0.0));
        assert_eq!(
            document.landmarks.lookup("scar"),
            Some(DVec3::new(2.0, 1.0, 0.0))
        );
        document.remove_extra("scar");
        assert!(document.landmarks.extra.is_empty());
    }

    #[test]
    fn landmark_files_round_trip_and_bad_ones_change_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let mut document = grid_document();
        document.place(DVec3::new(3.0, 4.0, 0.0));
        let path = dir.path().join("lm.json");
        document.save_landmarks(&path).unwrap();
        assert!(!document.unsaved);

        let mut other = grid_document();
        assert!(other.open_landmarks(&path).unwrap().is_empty());
        assert_eq!(other.landmarks, document.landmarks);

        std::fs::write(&path, "{\"landmarks\": {\"Pj\": [1, 2]}}").unwrap();
        let error = other.open_landmarks(&path).unwrap_err();
        assert!(
            format!("{error:#}").contains("landmark Pj: expected [x, y, z]"),
            "{error:#}"
        );
        std::fs::write(&path, "{\"landmarks\": {\"Pj\": [1, 2, 30]}}").unwrap();
        let error = other.open_landmarks(&path).unwrap_err();
        assert!(
            format!("{error:#}").contains("from the scan surface"),
            "{error:#}"
        );
        assert_eq!(other.landmarks, document.landmarks);

        assert!(Document::open_scan(&dir.path().join("missing.ply"), None).is_err());
        assert!(Document::is_landmark_file(Path::new("a/b.JSON")));
        assert!(!Document::is_landmark_file(Path::new("a/b.ply")));
    }
}
