//! Clinical distances between landmarks (paper IV-A, Fig. 2), each measured three ways:
//! straight (`euclidean_mm`), along the section of the surface with the plane through
//! both points orthogonal to the coronal plane (`surface_mm`, the paper's on-surface
//! distance) and along the shortest path on the surface (`geodesic_mm`).

use crate::frame::AnatomicalFrame;
use crate::landmarks::NamedPoints;
use mesh::geodesic::GeodesicSolver;
use mesh::section::plane_section_path;
use mesh::{SurfaceIndex, SurfacePoint, Topology, TriMesh};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// A distance to measure, by landmark names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DistanceSpec {
    pub name: String,
    pub from: String,
    pub to: String,
}

impl DistanceSpec {
    /// A pair named `"from-to"`.
    pub fn between(from: &str, to: &str) -> DistanceSpec {
        DistanceSpec {
            name: format!("{from}-{to}"),
            from: from.to_string(),
            to: to.to_string(),
        }
    }
}

/// The paper's clinically relevant distances on both sides: Pc-Pn, Pj-Pn, Pn-PSMF,
/// Pn-PSMFm, Pn-PSMFl, and Pnl-Pnr (eleven in all).
pub fn clinical_distances() -> Vec<DistanceSpec> {
    let mut specs = Vec::with_capacity(11);
    for side in ["l", "r"] {
        let nipple = format!("Pn{side}");
        specs.push(DistanceSpec::between(&format!("Pc{side}"), &nipple));
        specs.push(DistanceSpec::between("Pj", &nipple));
        specs.push(DistanceSpec::between(&nipple, &format!("PSMF{side}")));
        specs.push(DistanceSpec::between(&nipple, &format!("PSMFm{side}")));
        specs.push(DistanceSpec::between(&nipple, &format!("PSMFl{side}")));
    }
    specs.push(DistanceSpec::between("Pnl", "Pnr"));
    specs
}

/// One measured distance (mm). A surface measure that cannot be traced (e.g. the section
/// leaves the scan through a hole) is `None`, with the reason in `note`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Distance {
    pub name: String,
    pub from: String,
    pub to: String,
    pub euclidean_mm: f64,
    pub surface_mm: Option<f64>,
    pub geodesic_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// A landmark name that is not in the landmark set.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("no landmark named {0:?} (required landmarks or extra points of the landmark file)")]
pub struct UnknownLandmark(pub String);

/// The surface a measurement runs on: a scan with its connectivity and spatial index.
pub struct MeasuredSurface<'a> {
    pub mesh: &'a TriMesh,
    pub topology: &'a Topology,
    pub index: &'a SurfaceIndex,
}

/// Measures every spec. Landmarks are expected on the surface (snapped); each one is
/// located on its nearest triangle. Distances are computed in parallel.
pub fn measure_distances(
    surface: &MeasuredSurface<'_>,
    frame: &AnatomicalFrame,
    landmarks: &impl NamedPoints,
    specs: &[DistanceSpec],
) -> Result<Vec<Distance>, UnknownLandmark> {
    let locate = |name: &str| {
        landmarks
            .point(name)
            .map(|p| SurfacePoint::from(surface.index.closest_point(p)))
            .ok_or_else(|| UnknownLandmark(name.to_string()))
    };
    let located: Vec<(SurfacePoint, SurfacePoint)> = specs
        .iter()
        .map(|s| Ok((locate(&s.from)?, locate(&s.to)?)))
        .collect::<Result<_, UnknownLandmark>>()?;
    let geodesics = GeodesicSolver::new(surface.mesh, surface.topology);
    Ok(specs
        .par_iter()
        .zip(located)
        .map(|(spec, (from, to))| {
            let mut notes = Vec::new();
            let normal = (to.point - from.point).cross(frame.anterior());
            let surface_mm = if normal.length() < 1e-9 {
                notes.push("surface: the two points lie on one anterior line".to_string());
                None
            } else {
                plane_section_path(surface.mesh, surface.topology, from, to, normal.normalize())
                    .map(|path| path.length_mm)
                    .map_err(|e| notes.push(format!("surface: {e}")))
                    .ok()
            };
            let geodesic_mm = match &geodesics {
                Ok(solver) => solver
                    .shortest_path(from, to)
                    .map(|path| path.length_mm)
                    .map_err(|e| notes.push(format!("geodesic: {e}")))
                    .ok(),
                Err(e) => {
                    notes.push(format!("geodesic: {e}"));
                    None
                }
            };
            Distance {
                name: spec.name.clone(),
                from: spec.from.clone(),
                to: spec.to.clone(),
                euclidean_mm: from.point.distance(to.point),
                surface_mm,
                geodesic_mm,
                note: (!notes.is_empty()).then(|| notes.join("; ")),
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::landmarks::{LandmarkName, Landmarks};
    use glam::DVec3;
    use std::f64::consts::FRAC_PI_2;

    /// A vertical cylinder (axis y, radius 100 mm, 200 mm high, 512 x 128 cells) with
    /// anterior +z, and a frame whose coronal plane is x-y.
    fn vertical_cylinder() -> (TriMesh, Landmarks) {
        let mut mesh = mesh::shapes::cylinder(100.0, 200.0, 512, 128);
        // (x, y, z) -> (x, z, -y) is a proper rotation: the axis becomes y, outward stays outward.
        mesh.map_positions(|p| DVec3::new(p.x, p.z, -p.y));
        let landmarks = Landmarks::new(|name| match name {
            LandmarkName::Pj => DVec3::new(0.0, 180.0, 100.0),
            LandmarkName::Px => DVec3::new(0.0, 40.0, 100.0),
            LandmarkName::Pcl => DVec3::new(80.0, 170.0, 60.0),
            LandmarkName::Pcr => DVec3::new(-80.0, 170.0, 60.0),
            _ => DVec3::new(0.0, 100.0, 100.0),
        });
        (mesh, landmarks)
    }

    fn measure_on(
        mesh: &TriMesh,
        landmarks: &Landmarks,
        specs: &[DistanceSpec],
    ) -> Result<Vec<Distance>, UnknownLandmark> {
        let topology = Topology::new(mesh);
        let index = SurfaceIndex::new(mesh).unwrap();
        let frame = AnatomicalFrame::from_landmarks(landmarks).unwrap();
        let surface = MeasuredSurface {
            mesh,
            topology: &topology,
            index: &index,
        };
        measure_distances(&surface, &frame, landmarks, specs)
    }

    /// The cylinder point at azimuth `angle` from the front (rad, positive to the left)
    /// and height `y` (mm); on a vertex when both fall on the grid.
    fn on_cylinder(angle: f64, y: f64) -> DVec3 {
        let azimuth = angle - FRAC_PI_2; // the front (+z) is azimuth -pi/2 before rotation
        DVec3::new(100.0 * azimuth.cos(), y, -100.0 * azimuth.sin())
    }

    #[test]
    fn distances_on_a_cylinder_match_arcs_and_helices() {
        let (mesh, mut landmarks) = vertical_cylinder();
        let step = std::f64::consts::TAU / 512.0;
        landmarks
            .extra
            .insert("a".into(), on_cylinder(-40.0 * step, 100.0));
        landmarks
            .extra
            .insert("b".into(), on_cylinder(40.0 * step, 100.0));
        landmarks
            .extra
            .insert("c".into(), on_cylinder(60.0 * step, 187.5));
        let specs = [
            DistanceSpec::between("a", "b"),
            DistanceSpec::between("a", "c"),
        ];
        let measured = measure_on(&mesh, &landmarks, &specs).unwrap();

        // Same height: the section plane is horizontal, so section and geodesic are both
        // the 80-segment polygon arc; the polygon is inscribed, 2 sin(step/2)/step of the
        // circle's arc (relative deficit 6e-6).
        let arc = 100.0 * 80.0 * step;
        let polygon_arc = arc * (2.0 * (step / 2.0).sin() / step);
        let ab = &measured[0];
        assert!(
            (ab.surface_mm.unwrap() - polygon_arc).abs() < 1e-9 * arc,
            "{ab:?}"
        );
        assert!(
            (ab.geodesic_mm.unwrap() - polygon_arc).abs() < 1e-9 * arc,
            "{ab:?}"
        );
        assert!((ab.euclidean_mm - 200.0 * (40.0 * step).sin()).abs() < 1e-9);

        // Different heights: the geodesic is the helix, a straight line on the unrolled
        // cylinder, within the inscribed polygon's 6e-6 deficit (bound 1e-4); the vertical
        // section plane cuts an ellipse arc, which is longer.
        let ac = &measured[1];
        let helix = (100.0f64 * 100.0 * step).hypot(87.5);
        let geodesic = ac.geodesic_mm.unwrap();
        assert!(
            (geodesic - helix).abs() < 1e-4 * helix,
            "{geodesic} vs {helix}"
        );
        assert!(
            ac.surface_mm.unwrap() > geodesic && geodesic > ac.euclidean_mm,
            "{ac:?}"
        );
    }

    #[test]
    fn an_unknown_name_is_reported() {
        let (mesh, landmarks) = vertical_cylinder();
        let error =
            measure_on(&mesh, &landmarks, &[DistanceSpec::between("Pj", "scar")]).unwrap_err();
        assert_eq!(error, UnknownLandmark("scar".into()));
    }

    #[test]
    fn the_clinical_table_has_the_papers_eleven_pairs() {
        let names: Vec<String> = clinical_distances().into_iter().map(|s| s.name).collect();
        assert_eq!(
            names,
            [
                "Pcl-Pnl",
                "Pj-Pnl",
                "Pnl-PSMFl",
                "Pnl-PSMFml",
                "Pnl-PSMFll",
                "Pcr-Pnr",
                "Pj-Pnr",
                "Pnr-PSMFr",
                "Pnr-PSMFmr",
                "Pnr-PSMFlr",
                "Pnl-Pnr"
            ]
        );
        for spec in clinical_distances() {
            assert!(crate::LandmarkName::parse(&spec.from).is_some());
            assert!(crate::LandmarkName::parse(&spec.to).is_some());
        }
    }
}
