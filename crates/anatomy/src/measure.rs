//! Clinical distances between landmarks (paper IV-A, Fig. 2), each measured three ways:
//! straight (`euclidean_mm`), along the section of the surface with the plane through
//! both points orthogonal to the coronal plane (`surface_mm`, the paper's on-surface
//! distance) and along the shortest path on the surface (`geodesic_mm`).
//!
//! Where the paper's plane gives no curve from one point to the other (the two points on
//! one anterior line; or, on a simulated breast whose nipple ends up at the fold's
//! height, a nearly horizontal plane that cuts the breast in a closed loop missing the
//! fold), the surface distance is measured in the plane through both points that
//! contains the mean of their surface normals: the normal section, which follows the
//! great circle on a sphere, as the paper's plane is meant to approximate the geodesic.
//! `surface_plane` and the note say which plane was used.

use crate::frame::AnatomicalFrame;
use crate::landmarks::NamedPoints;
use glam::DVec3;
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

/// Radius (mm) over which the surface normal at a point is averaged for the fallback
/// section plane: several triangles of a scan (1-2 mm edges), so that the scanner's
/// noise (0.2 mm along the normals) does not tilt it, and small against a breast.
pub const SECTION_NORMAL_RADIUS_MM: f64 = 5.0;

/// A plane through two points is taken as undefined when the direction it must contain
/// lies within this angle (rad) of the line through them.
const MIN_PLANE_ANGLE_RAD: f64 = 1e-9;

/// The plane a surface distance was measured in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SectionPlane {
    /// The paper's: through both points, orthogonal to the coronal plane.
    CoronalOrthogonal,
    /// The fallback where the paper's plane gives no curve from one point to the other:
    /// through both points, containing the mean of the unit surface normals around
    /// them (within [`SECTION_NORMAL_RADIUS_MM`]).
    MeanNormal,
}

/// One measured distance (mm). A surface measure that cannot be traced (e.g. the section
/// leaves the scan through a hole) is `None`, with the reason in `note`; one measured in
/// the fallback plane says so in `note` too.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Distance {
    pub name: String,
    pub from: String,
    pub to: String,
    pub euclidean_mm: f64,
    pub surface_mm: Option<f64>,
    /// The plane `surface_mm` was measured in (absent without `surface_mm`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface_plane: Option<SectionPlane>,
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
            let section = surface_section(surface, frame, from, to)
                .map_err(|why| notes.push(format!("surface: {why}")))
                .ok();
            if let Some(note) = section.as_ref().and_then(|s| s.note.as_ref()) {
                notes.push(format!("surface: {note}"));
            }
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
                surface_mm: section.as_ref().map(|s| s.length_mm),
                surface_plane: section.as_ref().map(|s| s.plane),
                geodesic_mm,
                note: (!notes.is_empty()).then(|| notes.join("; ")),
            }
        })
        .collect())
}

/// A surface distance and the plane it was measured in.
struct SurfaceSection {
    plane: SectionPlane,
    length_mm: f64,
    /// Why the paper's plane was not used, when it was not.
    note: Option<String>,
}

/// The surface distance from `from` to `to`: along the section with the paper's plane
/// (through both points, orthogonal to the coronal plane), or where that gives no curve
/// from one point to the other, with the plane through both points containing their
/// mean surface normal. Errors: why neither gave one.
fn surface_section(
    surface: &MeasuredSurface<'_>,
    frame: &AnatomicalFrame,
    from: SurfacePoint,
    to: SurfacePoint,
) -> Result<SurfaceSection, String> {
    let length_in_plane_containing = |direction: DVec3, degenerate: &str| {
        if from.point == to.point {
            return Ok(0.0);
        }
        let normal = plane_containing(from.point, to.point, direction)
            .ok_or_else(|| format!("the two points lie on one line along {degenerate}"))?;
        plane_section_path(surface.mesh, surface.topology, from, to, normal)
            .map(|path| path.length_mm)
            .map_err(|e| e.to_string())
    };
    let why = match length_in_plane_containing(frame.anterior(), "the anterior direction") {
        Ok(length_mm) => {
            return Ok(SurfaceSection {
                plane: SectionPlane::CoronalOrthogonal,
                length_mm,
                note: None,
            });
        }
        Err(why) => why,
    };
    let mean_normal = [from, to]
        .map(|p| {
            let normal = mean_normal_near(
                surface.mesh,
                surface.topology,
                p.triangle,
                p.point,
                SECTION_NORMAL_RADIUS_MM,
            );
            normal.normalize_or_zero()
        })
        .into_iter()
        .sum::<DVec3>();
    match length_in_plane_containing(mean_normal, "their mean surface normal") {
        Ok(length_mm) => Ok(SurfaceSection {
            plane: SectionPlane::MeanNormal,
            length_mm,
            note: Some(format!(
                "in the plane through both points containing their mean surface normal (the \
                 plane orthogonal to the coronal plane: {why})"
            )),
        }),
        Err(fallback_why) => Err(format!(
            "{why}; in the plane containing their mean surface normal: {fallback_why}"
        )),
    }
}

/// The unit normal of the plane through `a` and `b` that contains `direction`; `None`
/// when the direction lies along the line through them (or either is zero).
fn plane_containing(a: DVec3, b: DVec3, direction: DVec3) -> Option<DVec3> {
    let chord = b - a;
    let normal = chord.cross(direction);
    (normal.length() > MIN_PLANE_ANGLE_RAD * chord.length() * direction.length())
        .then(|| normal.normalize())
}

/// Area-weighted mean normal (not normalised) of `start` and the triangles connected to
/// it through vertices whose centroids lie within `radius_mm` of `centre`.
pub(crate) fn mean_normal_near(
    mesh: &TriMesh,
    topology: &Topology,
    start: usize,
    centre: DVec3,
    radius_mm: f64,
) -> DVec3 {
    let weighted_normal = |t: usize| {
        let [a, b, c] = mesh.triangles[t].map(|v| mesh.positions[v as usize]);
        (b - a).cross(c - a)
    };
    let centroid = |t: usize| {
        mesh.triangles[t]
            .iter()
            .map(|&v| mesh.positions[v as usize])
            .sum::<DVec3>()
            / 3.0
    };
    let mut visited = vec![start];
    let mut queue = vec![start];
    let mut sum = weighted_normal(start);
    while let Some(t) = queue.pop() {
        for &v in &mesh.triangles[t] {
            for &next in topology.vertex_triangles(v as usize) {
                let next = next as usize;
                if !visited.contains(&next) && centroid(next).distance(centre) <= radius_mm {
                    visited.push(next);
                    queue.push(next);
                    sum += weighted_normal(next);
                }
            }
        }
    }
    sum
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
        let frame = AnatomicalFrame::from_landmarks(landmarks, crate::Up::FILE_VERTICAL).unwrap();
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
    fn where_the_papers_plane_misses_the_end_the_normal_section_measures() {
        // Two points a quarter turn apart on the outer equator of a ring about the
        // anterior axis: the paper's plane (through both, containing the anterior axis)
        // cuts the tube in two separate loops, one through each point. The plane through
        // both containing their mean surface normal is the ring's equatorial plane, whose
        // section from one to the other is a quarter of the outer equator.
        let (major, minor, around) = (100.0, 10.0, 256);
        let mesh = mesh::shapes::torus(major, minor, around, 32);
        let (_, mut landmarks) = vertical_cylinder();
        let outer = |i: usize| mesh.positions[i * 32];
        landmarks.extra.insert("a".into(), outer(0));
        landmarks.extra.insert("b".into(), outer(around / 4));
        let measured = measure_on(&mesh, &landmarks, &[DistanceSpec::between("a", "b")]).unwrap();
        let d = &measured[0];
        println!("{d:?}");
        assert_eq!(d.surface_plane, Some(SectionPlane::MeanNormal), "{d:?}");
        let note = d.note.as_deref().unwrap_or_default();
        assert!(
            note.contains("mean surface normal") && note.contains("closes on itself"),
            "{note}"
        );
        // The inscribed polygon's quarter: 64 chords of the 256-gon of radius 110 mm. The
        // mesh is symmetric under the half-turn about each outer-equator vertex's radius
        // (it maps every quad's diagonal onto a diagonal), so the mean normals there are
        // radial, the plane is the equatorial one, and its section runs through the
        // equator's vertices: equal to round-off (measured to 1e-14; bound 1e-9).
        let radius = major + minor;
        let step = std::f64::consts::TAU / around as f64;
        let quarter = (around / 4) as f64 * 2.0 * radius * (step / 2.0).sin();
        let surface = d.surface_mm.unwrap();
        assert!(
            (surface - quarter).abs() < 1e-9 * quarter,
            "{surface} vs {quarter}"
        );
        // still one path on the surface among those the geodesic minimises over
        assert!(surface >= d.geodesic_mm.unwrap() && d.geodesic_mm.unwrap() >= d.euclidean_mm);
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
