//! The control points of the cut curves (paper IV-B): the defaults derived from the
//! landmarks, and the control-point file users edit,
//! `{"units":"mm","left":[[x,y,z],...],"right":[[x,y,z],...]}` (file frame, in order
//! around each breast, at least three per side).

use super::{BreastError, Side};
use crate::frame::AnatomicalFrame;
use crate::landmarks::{Landmarks, parse_point};
use crate::measure::MeasuredSurface;
use glam::DVec3;
use mesh::{LengthUnit, SurfacePath, SurfacePoint, plane_section_path};
use serde_json::{Value, json};
use std::io::Write;
use std::path::Path;

/// Default position of the upper control point, as a fraction of the on-surface line
/// from the mid-clavicular point Pc to the nipple Pn. The paper leaves the ratio open;
/// the breast's upper border (where the upper pole's slope fades into the chest) lies
/// about a third of the way down from the clavicle to the nipple on our phantom and on
/// the shared scans, so a third encloses the upper pole without reaching the clavicle.
pub const DEFAULT_PC_RATIO: f64 = 1.0 / 3.0;

/// How far below PSMFm and PSMF (mm, along the frame's down direction) the default curve
/// runs: on the chest wall rather than in the fold's crease, whose walls would give the
/// fill-in the tangents of the crease instead of the chest's. PSMFl is kept: on real
/// scans it often sits on the rim of the hole where the scanner missed the lateral fold.
const FOLD_CLEARANCE_MM: f64 = 8.0;

/// What each default control point ([`ControlPoints::from_landmarks`]) stands for, in
/// their order, for messages that tell the user which to move.
pub const DEFAULT_CONTROL_POINT_ROLES: [&str; 6] = [
    "the point below the fold's medial end (from PSMFm)",
    "the point below the fold's lowest point (from PSMF)",
    "the fold's lateral end (PSMFl)",
    "the lateral point",
    "the upper point (on the line from Pc to Pn)",
    "the medial point",
];

/// Least drop of the fold's medial end PSMFm below the nipple, as a fraction of the fold's
/// lowest point's (PSMF's) drop (along the standing frame's up), before
/// [`ControlPoints::landmark_doubts`] names it and the default curve takes the other
/// side's fraction instead ([`MedialFoldEnds`]); the fifteen shared scans' breasts lie
/// well above it but for one (docs/dev/model-on-every-body.md, session 50).
const MIN_MEDIAL_FOLD_DROP: f64 = 0.25;

/// Where each side's default curve takes the fold's medial end from. A fold whose medial
/// part rises steeply to the nipple's height (a U-shaped fold) has no one medial end:
/// PSMFm marked anywhere on that arm is on the fold, and one marked near the nipple's
/// height swings the curve's lower inner border and its medial point up and out, across
/// the lower inner quadrant (docs/dev/model-on-every-body.md, sessions 50-52). Such a
/// PSMFm (less than [`MIN_MEDIAL_FOLD_DROP`] of PSMF's drop below the nipple) on that
/// arm, nearer the midline than the nipple, is taken on the skin straight below it, at
/// the other side's fraction of the drop (at most all of it), when the other side's PSMFm
/// is not itself doubted; the landmark itself is left as marked. One lateral of the
/// nipple is not on the medial arm but misplaced (PSMFm and PSMFl swapped, say), and
/// stays as marked. Drops are measured along the standing frame's up, as she stood.
struct MedialFoldEnds {
    /// Per side (left, right): the fold's medial end the default curve starts from.
    ends: [DVec3; 2],
    /// Per side: PSMFm's and PSMF's drops below the nipple (mm).
    drops_mm: [(f64, f64); 2],
    /// Per side: PSMFm's drop as a fraction of PSMF's, `None` where PSMF does not lie
    /// below the nipple.
    fractions: [Option<f64>; 2],
    /// Per side: the other side's fraction, where this side's end takes it.
    lent: [Option<f64>; 2],
}

impl MedialFoldEnds {
    /// The ends over `surface` (`None`: the marked ones, for the doubts alone), with
    /// `frame` the standing frame.
    fn new(
        surface: Option<&MeasuredSurface<'_>>,
        frame: &AnatomicalFrame,
        landmarks: &Landmarks,
    ) -> MedialFoldEnds {
        let up = frame.up();
        let drops_mm = Side::BOTH.map(|side| {
            let names = side.landmark_names();
            let drop = |name| (landmarks.get(names.nipple) - landmarks.get(name)).dot(up);
            (drop(names.fold_medial), drop(names.fold_lowest))
        });
        let fractions =
            drops_mm.map(|(medial_mm, lowest_mm)| (lowest_mm > 0.0).then(|| medial_mm / lowest_mm));
        let from_midline_mm = |p: DVec3| frame.to_local(p).x.abs();
        let lent = Side::BOTH.map(|side| {
            let names = side.landmark_names();
            let medial_arm = from_midline_mm(landmarks.get(names.fold_medial))
                < from_midline_mm(landmarks.get(names.nipple));
            let other = fractions[side.opposite() as usize];
            (medial_arm && doubted(fractions[side as usize]) && !doubted(other))
                .then_some(other)
                .flatten()
                .map(|f| f.min(1.0))
        });
        let ends = Side::BOTH.map(|side| {
            let marked = landmarks.get(side.landmark_names().fold_medial);
            let (Some(surface), Some(other)) = (surface, lent[side as usize]) else {
                return marked;
            };
            let (medial_mm, lowest_mm) = drops_mm[side as usize];
            let lowered = marked - up * (other * lowest_mm - medial_mm);
            surface.index.closest_point(lowered).point
        });
        MedialFoldEnds {
            ends,
            drops_mm,
            fractions,
            lent,
        }
    }

    /// Whether `side`'s PSMFm is doubted.
    fn doubted(&self, side: Side) -> bool {
        doubted(self.fractions[side as usize])
    }
}

/// Whether a PSMFm at this fraction of PSMF's drop ([`MedialFoldEnds::fractions`]) is
/// doubted.
fn doubted(fraction: Option<f64>) -> bool {
    fraction.is_some_and(|f| f < MIN_MEDIAL_FOLD_DROP)
}

/// Cut-curve control points of both breasts (mm, file frame), in order around each.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlPoints {
    pub left: Vec<DVec3>,
    pub right: Vec<DVec3>,
}

impl ControlPoints {
    /// The control points of one side.
    pub fn side(&self, side: Side) -> &[DVec3] {
        match side {
            Side::Left => &self.left,
            Side::Right => &self.right,
        }
    }

    /// Landmarks the default control points rest on that look misplaced, one sentence
    /// each for the user: a fold's medial end PSMFm that lies less than
    /// [`MIN_MEDIAL_FOLD_DROP`] of PSMF's drop below the nipple (along the standing
    /// `frame`'s up). The curve's lower inner border runs below PSMFm, so a PSMFm marked
    /// near the nipple's height would cut off the breast's lower inner quadrant; the
    /// message says whether the default curve takes the other side's depth instead
    /// ([`MedialFoldEnds`]).
    pub fn landmark_doubts(frame: &AnatomicalFrame, landmarks: &Landmarks) -> Vec<String> {
        let ends = MedialFoldEnds::new(None, frame, landmarks);
        Side::BOTH
            .into_iter()
            .filter(|&side| ends.doubted(side))
            .map(|side| {
                let names = side.landmark_names();
                let (medial_mm, lowest_mm) = ends.drops_mm[side as usize];
                let medial = names.fold_medial.as_str();
                let remedy = match ends.lent[side as usize] {
                    Some(share) => format!(
                        "the default cut curve starts its lower inner border on the skin below \
                         {medial} instead, {:.0} mm below the nipple: the same share of the \
                         fold's depth ({:.0}%) as {} on the {} breast. Check where {medial} is \
                         marked, or move the curve's control points",
                        share * lowest_mm,
                        100.0 * share,
                        side.opposite().landmark_names().fold_medial.as_str(),
                        side.opposite(),
                    ),
                    None => format!(
                        "the cut curve's lower inner border runs below {medial}, so the lower \
                         inner quadrant may be cut off: check where {medial} is marked"
                    ),
                };
                format!(
                    "{side} breast: the fold's medial end {medial} lies {:.0} mm {} the nipple, \
                     while the fold's lowest point {} lies {lowest_mm:.0} mm below it; {remedy}",
                    medial_mm.abs(),
                    if medial_mm >= 0.0 { "below" } else { "above" },
                    names.fold_lowest.as_str(),
                )
            })
            .collect()
    }

    /// Default control points per side, in order around the breast: PSMFm, PSMF, PSMFl,
    /// a lateral point, the upper point and a medial point. The upper point lies
    /// `pc_ratio` (0..1) of the way along the on-surface line from Pc to Pn (a plane
    /// section orthogonal to the coronal plane, as for the measurements).
    ///
    /// The paper's fifth point, the middle of the on-surface line from the upper point to
    /// PSMFl, lies on the breast itself (that line crosses the upper outer quadrant), so
    /// the curve through it cuts off breast tissue until a user moves it. Instead, seen
    /// from the front with the nipple Pn at the centre, the lateral point lies on the
    /// bisector of the directions to the upper point and PSMFl (through the lateral side),
    /// at the mean of their distances from Pn; the medial point lies likewise between the
    /// upper point and PSMFm, as the breasts approach each other over the sternum. Both
    /// lie at the mean depth of the two points they lie between (see
    /// [`AroundNipple::between`]). Landmarks are expected on the surface. `standing` is
    /// the standing frame: the points are placed in its body axes
    /// ([`AnatomicalFrame::sternal`]), the fold's medial end taken by [`MedialFoldEnds`].
    pub fn from_landmarks(
        surface: &MeasuredSurface<'_>,
        standing: &AnatomicalFrame,
        landmarks: &Landmarks,
        pc_ratio: f64,
    ) -> Result<ControlPoints, BreastError> {
        if !(pc_ratio > 0.0 && pc_ratio < 1.0) {
            return Err(BreastError::InvalidPcRatio(pc_ratio));
        }
        let medial_ends = MedialFoldEnds::new(Some(surface), standing, landmarks).ends;
        let frame = &standing.sternal();
        let side_points = |side: Side| -> Result<Vec<DVec3>, BreastError> {
            let names = side.landmark_names();
            let at = |name: crate::LandmarkName| landmarks.get(name);
            let medial_end = medial_ends[side as usize];
            let clavicle_to_nipple =
                section_path(surface, frame, at(names.clavicle), at(names.nipple)).map_err(
                    |source| BreastError::Section {
                        side,
                        from: names.clavicle.as_str().to_string(),
                        to: names.nipple.as_str().to_string(),
                        source,
                    },
                )?;
            let upper = point_along(&clavicle_to_nipple, pc_ratio);
            let lateral_direction = match side {
                Side::Left => frame.left(),
                Side::Right => -frame.left(),
            };
            let around = AroundNipple {
                surface,
                frame,
                nipple: at(names.nipple),
            };
            // The nearest surface point, not the one seen from the front: under a
            // hanging breast a ray from the front meets the lower pole, not the chest.
            let below_fold = |point: DVec3| {
                surface
                    .index
                    .closest_point(point - frame.up() * FOLD_CLEARANCE_MM)
                    .point
            };
            Ok(vec![
                below_fold(medial_end),
                below_fold(at(names.fold_lowest)),
                at(names.fold_lateral),
                around.between(upper, at(names.fold_lateral), lateral_direction),
                upper,
                around.between(upper, medial_end, -lateral_direction),
            ])
        };
        Ok(ControlPoints {
            left: side_points(Side::Left)?,
            right: side_points(Side::Right)?,
        })
    }

    /// Checks that each side's points lie, on average, on that side of the sternal notch
    /// (`frame`'s x): a file written for the other side, or with its sides swapped,
    /// would cut each breast out of the other. `path` is only for messages.
    pub fn check_sides(&self, frame: &AnatomicalFrame, path: &Path) -> Result<(), BreastError> {
        for (side, sign) in [(Side::Left, 1.0), (Side::Right, -1.0)] {
            let points = self.side(side);
            let mean_mm = points.iter().map(|&p| frame.to_local(p).x).sum::<f64>()
                / points.len().max(1) as f64;
            if mean_mm * sign < 0.0 {
                return Err(BreastError::ControlPointFile {
                    path: path.to_path_buf(),
                    message: format!(
                        "the \"{side}\" points lie on the patient's {} ({:.0} mm from the \
                         sternal notch on average): the file's sides are swapped, or it was \
                         made for a mirrored scan",
                        side.opposite(),
                        mean_mm.abs()
                    ),
                });
            }
        }
        Ok(())
    }

    /// Parses a control-point file's text; `path` is only for messages.
    pub fn from_json(text: &str, path: &Path) -> Result<ControlPoints, BreastError> {
        let error = |message: String| BreastError::ControlPointFile {
            path: path.to_path_buf(),
            message,
        };
        let root: Value =
            serde_json::from_str(text).map_err(|e| error(format!("not valid JSON: {e}")))?;
        let units = root.get("units").and_then(Value::as_str);
        let Some(unit) = units.and_then(LengthUnit::parse) else {
            return Err(error(format!(
                "\"units\" must be \"mm\", \"cm\", \"m\" or \"in\", found {}",
                units.map_or("nothing".to_string(), |u| format!("\"{u}\""))
            )));
        };
        let side_points = |side: Side| -> Result<Vec<DVec3>, BreastError> {
            let key = side.name();
            let list = root
                .get(key)
                .and_then(Value::as_array)
                .ok_or_else(|| error(format!("\"{key}\" must be a list of [x, y, z] points")))?;
            if list.len() < 3 {
                return Err(error(format!(
                    "\"{key}\" has {} control points; a closed curve needs at least 3",
                    list.len()
                )));
            }
            list.iter()
                .enumerate()
                .map(|(index, value)| {
                    parse_point(value, unit)
                        .map_err(|reason| error(format!("\"{key}\" point {index}: {reason}")))
                })
                .collect()
        };
        let points = ControlPoints {
            left: side_points(Side::Left)?,
            right: side_points(Side::Right)?,
        };
        let all: Vec<DVec3> = points.left.iter().chain(&points.right).copied().collect();
        mesh::units::check_declared_unit(unit, mesh::units::span(&all) / unit.mm(), all.len())
            .map_err(error)?;
        Ok(points)
    }

    /// Reads a control-point file.
    pub fn read(path: &Path) -> Result<ControlPoints, BreastError> {
        let text = std::fs::read_to_string(path).map_err(|e| BreastError::ControlPointFile {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        ControlPoints::from_json(&text, path)
    }

    /// The file's JSON.
    pub fn to_json(&self) -> Value {
        let points = |list: &[DVec3]| list.iter().map(|p| p.to_array()).collect::<Vec<_>>();
        json!({"units": "mm", "left": points(&self.left), "right": points(&self.right)})
    }

    /// Writes the file (atomically: a temporary file renamed into place).
    pub fn write(&self, path: &Path) -> Result<(), BreastError> {
        let json = self.to_json();
        mesh::io::write_atomically(path, |w| {
            serde_json::to_writer_pretty(&mut *w, &json)?;
            writeln!(w)
        })
        .map_err(|e| BreastError::ControlPointFile {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
    }
}

/// Directions and distances in the coronal plane, seen from the front, about a nipple.
struct AroundNipple<'a> {
    surface: &'a MeasuredSurface<'a>,
    frame: &'a AnatomicalFrame,
    nipple: DVec3,
}

impl AroundNipple<'_> {
    /// The surface point nearest to the target on the bisector of the directions from the
    /// nipple to `a` and `b` (both on the surface) that points towards `side` (a coronal
    /// direction), at the mean of their distances from the nipple in the coronal plane and
    /// at the mean of their depths along the anterior axis: where the breast's border runs
    /// at the depth of its neighbours on the curve. A point seen from the front instead
    /// lands on the breast's slope, on the flank or on nothing, depending on millimetres
    /// of the body's shape.
    fn between(&self, a: DVec3, b: DVec3, side: DVec3) -> DVec3 {
        let anterior = self.frame.anterior();
        let depth = |p: DVec3| (p - self.nipple).dot(anterior);
        let mean_depth_mm = 0.5 * (depth(a) + depth(b));
        let coronal = |p: DVec3| {
            let d = p - self.nipple;
            d - anterior * d.dot(anterior)
        };
        let (a, b) = (coronal(a), coronal(b));
        let bisector = (a.normalize_or_zero() + b.normalize_or_zero())
            .try_normalize()
            .unwrap_or(side);
        let bisector = if bisector.dot(side) < 0.0 {
            -bisector
        } else {
            bisector
        };
        let target =
            self.nipple + bisector * 0.5 * (a.length() + b.length()) + anterior * mean_depth_mm;
        self.surface.index.closest_point(target).point
    }
}

/// The on-surface line from `from` to `to` (both near the surface): the section with the
/// plane through them orthogonal to the coronal plane.
fn section_path(
    surface: &MeasuredSurface<'_>,
    frame: &AnatomicalFrame,
    from: DVec3,
    to: DVec3,
) -> Result<SurfacePath, mesh::PathError> {
    let locate = |p: DVec3| SurfacePoint::from(surface.index.closest_point(p));
    let (from, to) = (locate(from), locate(to));
    let normal = (to.point - from.point).cross(frame.anterior());
    plane_section_path(surface.mesh, surface.topology, from, to, normal)
}

/// The point `fraction` (0..=1) of the way along `path` by arc length.
fn point_along(path: &SurfacePath, fraction: f64) -> DVec3 {
    let mut remaining = fraction * path.length_mm;
    for segment in path.points.windows(2) {
        let length = segment[0].distance(segment[1]);
        if remaining <= length && length > 0.0 {
            return segment[0].lerp(segment[1], remaining / length);
        }
        remaining -= length;
    }
    path.points.last().copied().unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::UpSource;
    use glam::DMat3;
    use mesh::{SurfaceIndex, Topology, TriMesh};

    /// A grid of 2 mm squares over x in [-130, 130] mm, y in [-100, 100] mm, at
    /// z = `height(x, y)`.
    fn chest(height: impl Fn(f64, f64) -> f64) -> TriMesh {
        let (columns, rows) = (131, 101);
        let mut positions = Vec::new();
        for row in 0..rows {
            for column in 0..columns {
                let (x, y) = (-130.0 + 2.0 * column as f64, -100.0 + 2.0 * row as f64);
                positions.push(DVec3::new(x, y, height(x, y)));
            }
        }
        let mut triangles = Vec::new();
        let at = |row: usize, column: usize| (row * columns + column) as u32;
        for row in 0..rows - 1 {
            for column in 0..columns - 1 {
                let (a, b) = (at(row, column), at(row, column + 1));
                let (c, d) = (at(row + 1, column + 1), at(row + 1, column));
                triangles.extend([[a, b, c], [a, c, d]]);
            }
        }
        TriMesh::new(positions, triangles)
    }

    /// The file's axes as the frame's (z anterior, y up, x the body's left).
    fn file_frame() -> AnatomicalFrame {
        AnatomicalFrame {
            origin: DVec3::ZERO,
            axes: DMat3::IDENTITY,
            sternal_axes: DMat3::IDENTITY,
            up_source: UpSource::FileVertical,
        }
    }

    /// The lateral point of the nipple at `nipple` between `upper` and `lateral_end`, on
    /// `mesh`, towards the side of the body (the sign of x) the nipple is on.
    fn lateral_point(mesh: &TriMesh, nipple: DVec3, upper: DVec3, lateral_end: DVec3) -> DVec3 {
        let topology = Topology::new(mesh);
        let index = SurfaceIndex::new(mesh).unwrap();
        let surface = MeasuredSurface {
            mesh,
            topology: &topology,
            index: &index,
        };
        let frame = file_frame();
        let around = AroundNipple {
            surface: &surface,
            frame: &frame,
            nipple,
        };
        around.between(upper, lateral_end, DVec3::X * nipple.x.signum())
    }

    /// A chest (z = 0) with a round breast of radius 60 mm about (±70, 0) rising to 40 mm,
    /// and on the left only a flank panel 150 mm behind, past the chest's edge.
    #[test]
    fn a_lateral_point_past_the_breast_does_not_reach_round_the_flank() {
        let mut mesh = chest(|x, y| {
            let r2 = ((x.abs() - 70.0).powi(2) + y * y) / 3600.0;
            40.0 * (1.0 - r2).max(0.0).powi(2)
        });
        let panel = mesh.positions.len() as u32;
        for (x, y) in [
            (131.0, -200.0),
            (300.0, -200.0),
            (300.0, 200.0),
            (131.0, 200.0),
        ] {
            mesh.positions.push(DVec3::new(x, y, -150.0));
        }
        mesh.triangles
            .extend([[panel, panel + 1, panel + 2], [panel, panel + 2, panel + 3]]);
        // Upper point and fold's lateral end on the chest; their bisector's target lies
        // at x = ±150, beyond the chest, in front of the left panel.
        let point = |sign: f64| {
            lateral_point(
                &mesh,
                DVec3::new(70.0 * sign, 0.0, 40.0),
                DVec3::new(110.0 * sign, 90.0, 0.0),
                DVec3::new(125.0 * sign, -40.0, 0.0),
            )
        };
        let (left, right) = (point(1.0), point(-1.0));
        // Both are the chest's nearest point to the target, on its lateral edge: mirror
        // images to round-off.
        assert!(
            left.distance(right * DVec3::new(-1.0, 1.0, 1.0)) < 1e-9,
            "{left} {right}"
        );
        assert!(
            (left.x - 130.0).abs() < 1e-9 && left.z.abs() < 1e-9,
            "{left}"
        );
    }

    /// A flat chest with a lump (a paraboloid cap 30 mm high, 15 mm in radius) where the
    /// lateral point's target lies: the point is the chest's nearest point to the target
    /// at its neighbours' depth (z = 0), on the lump's foot, not its top 30 mm in front,
    /// where a point seen from the front would land. The distance from the cap
    /// `z = 30 (1 - r²/225)` to its centre's foot is least at r² = 225 (1 - 225/1800)
    /// (z = 3.75 mm), 14.52 mm. The grid's facets lie under the cap by at most the
    /// interpolation error of its curvature over 2 mm legs, (2/15)·2 = 0.27 mm: bound 0.3.
    #[test]
    fn a_lateral_point_lies_at_its_neighbours_depth() {
        // Upper point (0, 60) and lateral end (60, 0) from the nipple at the origin:
        // the target lies on the diagonal at their mean distance, 60 mm.
        let centre = 60.0 * std::f64::consts::FRAC_1_SQRT_2;
        let mesh = chest(|x, y| {
            let r2 = (x - centre).powi(2) + (y - centre).powi(2);
            30.0 * (1.0 - r2 / 225.0).max(0.0)
        });
        let point = lateral_point(
            &mesh,
            DVec3::new(0.0, 0.0, 40.0),
            DVec3::new(0.0, 60.0, 0.0),
            DVec3::new(60.0, 0.0, 0.0),
        );
        let target = DVec3::new(centre, centre, 0.0);
        let least_mm = (225.0 * (1.0 - 225.0 / 1800.0) + 3.75f64.powi(2)).sqrt();
        let distance_mm = point.distance(target);
        println!("{point}: {distance_mm:.3} mm from the target (cap: {least_mm:.3} mm)");
        assert!((distance_mm - least_mm).abs() < 0.3, "{point}");
        assert!(point.z < 5.0, "{point}");
    }

    /// A PSMFml marked at the nipple's height is named, a usual PSMFmr (30 mm below the
    /// nipple, PSMF 60 mm below) is not.
    #[test]
    fn a_medial_fold_end_at_the_nipples_height_is_doubted() {
        use crate::landmarks::LandmarkName::*;
        let frame = file_frame();
        let landmarks = Landmarks::new(|name| match name {
            Pnl => DVec3::new(90.0, 0.0, 100.0),
            Pnr => DVec3::new(-90.0, 0.0, 100.0),
            PSMFl => DVec3::new(90.0, -60.0, 60.0),
            PSMFr => DVec3::new(-90.0, -60.0, 60.0),
            PSMFml => DVec3::new(35.0, 1.0, 70.0),
            PSMFmr => DVec3::new(-35.0, -30.0, 70.0),
            _ => DVec3::ZERO,
        });
        let doubts = ControlPoints::landmark_doubts(&frame, &landmarks);
        assert_eq!(doubts.len(), 1, "{doubts:?}");
        assert!(
            doubts[0].starts_with("left breast")
                && doubts[0].contains("PSMFml lies 1 mm above the nipple"),
            "{doubts:?}"
        );
    }

    /// Landmarks over a flat chest (z = 0): nipples 0 mm high, PSMF 60 mm below them, the
    /// right's PSMFm 30 mm below (half the fold's drop) and the left's at `left_medial_y`.
    fn folds_with_left_medial_end_at(left_medial_y: f64) -> Landmarks {
        use crate::landmarks::LandmarkName::*;
        Landmarks::new(|name| match name {
            Pnl => DVec3::new(90.0, 0.0, 0.0),
            Pnr => DVec3::new(-90.0, 0.0, 0.0),
            PSMFl => DVec3::new(90.0, -60.0, 0.0),
            PSMFr => DVec3::new(-90.0, -60.0, 0.0),
            PSMFml => DVec3::new(35.0, left_medial_y, 0.0),
            PSMFmr => DVec3::new(-35.0, -30.0, 0.0),
            _ => DVec3::ZERO,
        })
    }

    /// The default curves' medial fold ends over a flat chest (z = 0), `frame` standing.
    fn medial_ends_over_flat_chest(landmarks: &Landmarks, frame: &AnatomicalFrame) -> [DVec3; 2] {
        let mesh = chest(|_, _| 0.0);
        let topology = Topology::new(&mesh);
        let index = SurfaceIndex::new(&mesh).unwrap();
        let surface = MeasuredSurface {
            mesh: &mesh,
            topology: &topology,
            index: &index,
        };
        MedialFoldEnds::new(Some(&surface), frame, landmarks).ends
    }

    /// A PSMFml at the nipple's height is taken, on a flat chest, exactly where the right
    /// side's fraction of the drop (30 of 60 mm) puts it: (35, -30, 0) mm; the right's,
    /// not doubted, stays as marked. With the left's at 40% of the drop nothing moves.
    #[test]
    fn a_doubted_medial_fold_end_takes_the_other_sides_depth() {
        let frame = file_frame();
        let doubted = folds_with_left_medial_end_at(1.0);
        let ends = medial_ends_over_flat_chest(&doubted, &file_frame());
        assert!(
            ends[0].distance(DVec3::new(35.0, -30.0, 0.0)) < 1e-9,
            "{}",
            ends[0]
        );
        assert_eq!(ends[1], DVec3::new(-35.0, -30.0, 0.0));
        let usual = folds_with_left_medial_end_at(-24.0);
        let ends = medial_ends_over_flat_chest(&usual, &file_frame());
        assert_eq!(
            ends,
            [DVec3::new(35.0, -24.0, 0.0), DVec3::new(-35.0, -30.0, 0.0)]
        );
        let doubts = ControlPoints::landmark_doubts(&frame, &doubted);
        assert_eq!(doubts.len(), 1, "{doubts:?}");
        assert!(
            doubts[0].contains("30 mm below the nipple: the same share of the fold's depth (50%) as PSMFmr on the right breast"),
            "{doubts:?}"
        );
    }

    /// The drops are measured as she stood, not along the sternum: with the sternum
    /// leaning 26 degrees back (the shared scans lean 26-27), the doubted PSMFml is still
    /// taken 30 of the fold's 60 mm below the nipple, straight down, as on an upright
    /// sternum.
    #[test]
    fn a_leaning_sternum_leaves_the_drops_vertical() {
        let lean = DMat3::from_rotation_x(-26f64.to_radians());
        let frame = AnatomicalFrame {
            sternal_axes: lean,
            ..file_frame()
        };
        let ends = medial_ends_over_flat_chest(&folds_with_left_medial_end_at(1.0), &frame);
        assert!(
            ends[0].distance(DVec3::new(35.0, -30.0, 0.0)) < 1e-9,
            "{}",
            ends[0]
        );
    }

    /// A doubted PSMFml lateral of the nipple (120 mm from the midline, the nipple 90) is
    /// not on the fold's medial arm but misplaced: it stays as marked, and the warning
    /// asks where it is marked.
    #[test]
    fn a_doubted_medial_fold_end_lateral_of_the_nipple_stays_as_marked() {
        use crate::landmarks::LandmarkName::*;
        let base = folds_with_left_medial_end_at(1.0);
        let landmarks = Landmarks::new(|name| match name {
            PSMFml => DVec3::new(120.0, 1.0, 0.0),
            other => base.get(other),
        });
        let ends = medial_ends_over_flat_chest(&landmarks, &file_frame());
        assert_eq!(
            ends,
            [DVec3::new(120.0, 1.0, 0.0), DVec3::new(-35.0, -30.0, 0.0)]
        );
        let doubts = ControlPoints::landmark_doubts(&file_frame(), &landmarks);
        assert_eq!(doubts.len(), 1, "{doubts:?}");
        assert!(doubts[0].contains("may be cut off"), "{doubts:?}");
    }

    /// Both medial fold ends doubted: neither side has a depth to lend, both stay as
    /// marked and both are named.
    #[test]
    fn two_doubted_medial_fold_ends_stay_as_marked() {
        use crate::landmarks::LandmarkName::*;
        let frame = file_frame();
        let base = folds_with_left_medial_end_at(1.0);
        let landmarks = Landmarks::new(|name| match name {
            PSMFmr => DVec3::new(-35.0, -5.0, 0.0),
            other => base.get(other),
        });
        let ends = medial_ends_over_flat_chest(&landmarks, &file_frame());
        assert_eq!(
            ends,
            [DVec3::new(35.0, 1.0, 0.0), DVec3::new(-35.0, -5.0, 0.0)]
        );
        let doubts = ControlPoints::landmark_doubts(&frame, &landmarks);
        assert_eq!(doubts.len(), 2, "{doubts:?}");
        assert!(
            doubts.iter().all(|d| d.contains("may be cut off")),
            "{doubts:?}"
        );
    }

    /// Each side on its own side of the notch passes; the sides swapped are refused with
    /// the side named and the mean distance (here 80 mm).
    #[test]
    fn a_file_with_its_sides_swapped_is_refused() {
        let frame = file_frame();
        let around = |x: f64| -> Vec<DVec3> {
            [(-30.0, 0.0), (30.0, 0.0), (0.0, 40.0)]
                .iter()
                .map(|&(dx, y)| DVec3::new(x + dx, y, 0.0))
                .collect()
        };
        let path = Path::new("cp.json");
        let points = ControlPoints {
            left: around(80.0),
            right: around(-80.0),
        };
        assert!(points.check_sides(&frame, path).is_ok());
        let swapped = ControlPoints {
            left: points.right.clone(),
            right: points.left.clone(),
        };
        let message = swapped.check_sides(&frame, path).unwrap_err().to_string();
        assert!(
            message.contains("the \"left\" points lie on the patient's right (80 mm"),
            "{message}"
        );
    }

    #[test]
    fn the_file_round_trips() {
        let points = ControlPoints {
            left: vec![DVec3::new(1.0, 2.0, 3.0), DVec3::X, DVec3::Y, DVec3::Z],
            right: vec![DVec3::new(-1.5, 2.25, 1e-3), DVec3::X, DVec3::Y],
        };
        let directory = tempfile::tempdir().unwrap();
        let path = directory.path().join("control_points.json");
        points.write(&path).unwrap();
        assert_eq!(ControlPoints::read(&path).unwrap(), points);
    }

    #[test]
    fn bad_files_name_the_problem() {
        let path = Path::new("cp.json");
        let message = |text: &str| {
            ControlPoints::from_json(text, path)
                .unwrap_err()
                .to_string()
        };
        assert!(message("{").contains("cp.json: not valid JSON"));
        assert!(message(r#"{"left":[],"right":[]}"#).contains("\"units\" must be \"mm\""));
        let two = r#"{"units":"mm","left":[[0,0,0],[1,0,0]],"right":[]}"#;
        assert!(message(two).contains("\"left\" has 2 control points"));
        let bad =
            r#"{"units":"mm","left":[[0,0,0],[1,0,0],[0,1,0]],"right":[[0,0],[1,0,0],[0,1,0]]}"#;
        assert!(message(bad).contains("\"right\" point 0: expected [x, y, z]"));
    }
}
