//! The pectoralis major (issue 24): a layer of the simulated tissue on the chest wall,
//! placed from the landmarks, with its own, stiffer material.
//!
//! # Outline
//! In the standing frame (`a` = distance from the midline towards the side, `y` up from
//! Pj, mm), from the landmarks of that side:
//! - *medial border*, the sternal origin: `a =` [`MEDIAL_ORIGIN_MM`] from Pj's height
//!   down to the *lower sternal origin*, at Px's height (the sixth costal cartilage
//!   meets the sternum at the xiphisternal junction);
//! - *inferior border*: the costal origins, from the lower sternal origin down to the
//!   fold's lowest point (PSMF; the origins a dual-plane release divides run along the
//!   fold) and on to its lateral end (PSMFl*), then the free lower edge, the anterior
//!   axillary fold, rising at [`AXILLARY_RISE_DEG`] towards the axilla;
//! - *upper border*, the clavicular origin: from Pj's height at the medial border to
//!   [`BELOW_CLAVICLE_MM`] under the clavicle's landmark (Pc*), level beyond it;
//! - laterally open: the insertion on the humerus lies beyond the scan.
//!
//! # Thickness
//! The full thickness is the part of the model's rear-wall offset the implant bed does
//! not take (the wall lies at the ribs, the bed [`crate::DEFAULT_SHIFT_MM`] under the
//! skin: 10 mm at the default 15 mm offset, the 10-13 mm ultrasound gives for adult
//! women, see `anatomy::closed_surface::DEFAULT_REAR_WALL_OFFSET_MM`). It tapers
//! linearly to zero over [`BORDER_TAPER_MM`] inside every border (measured across `a`
//! at the medial border, along `y` at the others). A tetrahedron is muscle where its
//! centroid lies within the thickness in front of the closed surface's rear wall, and
//! at least [`crate::DEFAULT_SHIFT_MM`] under the skin (at the side of the chest the
//! wall, moved straight back, comes closer to the skin than the muscle is thick).

use crate::bed::DEFAULT_SHIFT_MM;
use crate::error::SimulationError;
use anatomy::breast::Side;
use anatomy::{AnatomicalFrame, ClosedSurface, LandmarkName, Landmarks};
use fem::Material;
use glam::{DVec2, DVec3};
use mesh::{SurfaceIndex, TriMesh};
use rayon::prelude::*;
use serde::Serialize;
use tetra::TetMesh;

/// Distance of the sternal origin from the midline (mm): the muscle arises from the
/// front of the sternum, a few millimetres from the midline (issue 24).
pub const MEDIAL_ORIGIN_MM: f64 = 5.0;

/// The clavicular origin lies this far below the clavicle's landmark (mm): the landmark
/// is on the skin over the bone, the muscle arises from its lower front edge.
pub const BELOW_CLAVICLE_MM: f64 = 10.0;

/// Rise of the free lower edge lateral of the fold's lateral end (degrees from the
/// horizontal): the anterior axillary fold runs up and out to the humerus.
pub const AXILLARY_RISE_DEG: f64 = 45.0;

/// Width over which the muscle thins to nothing inside each border (mm): its origins
/// and its free edge are aponeurotic and thin.
pub const BORDER_TAPER_MM: f64 = 20.0;

/// Default passive muscle: Young's modulus 20 kPa. Shear-wave elastography of relaxed
/// skeletal muscle gives a shear modulus of about 7 kPa at rest (lateral gastrocnemius,
/// 7.1 kPa at the least stretch: Brandenburg et al., PM&R 2015, PMC4369795), so
/// `E = 2(1 + ν)μ ≈ 20 kPa` at the tissue's Poisson ratio: about eight times the breast
/// tissue's. Isotropic: a passive muscle is stiffer along its fibres, but we have no
/// fibre field per body, and the corotated linear model has no fibre term. Density
/// 1060 kg/m³, skeletal muscle's.
pub const DEFAULT_MUSCLE: Material = Material {
    young_kpa: 20.0,
    poisson_ratio: fem::material::DEFAULT_POISSON_RATIO,
    density_kg_m3: 1060.0,
};

/// The pectoralis major of one side: its outline and thickness (standing frame).
#[derive(Debug, Clone, PartialEq)]
pub struct Pectoralis {
    pub side: Side,
    /// `x` towards this side: 1 on the left, -1 on the right.
    side_sign: f64,
    /// The sternal origin's distance from the midline (mm).
    pub medial_a_mm: f64,
    /// Pj's height (0) and the lower sternal origin's (mm, standing frame).
    pub origin_top_y_mm: f64,
    pub lower_origin_y_mm: f64,
    /// The inferior border's corners `(a, y)`, `a` increasing: the lower sternal
    /// origin, the fold's lowest point, its lateral end (a landmark out of that order
    /// left out); beyond the last it rises at [`AXILLARY_RISE_DEG`].
    pub inferior: Vec<DVec2>,
    /// The clavicular border's corners `(a, y)`: at the medial border, below Pc* (unless
    /// Pc* lies nearer the midline than the sternal origin).
    pub clavicular: Vec<DVec2>,
    /// Landmarks left out of the outline, for the user.
    pub warnings: Vec<String>,
    /// Full thickness (mm).
    pub thickness_mm: f64,
}

/// `y` on the polyline `corners` (increasing `a`) at `a`, continued beyond the last
/// corner with `slope_beyond` and level before the first.
fn polyline_y(corners: &[DVec2], a: f64, slope_beyond: f64) -> f64 {
    let last = corners[corners.len() - 1];
    if a >= last.x {
        return last.y + (a - last.x) * slope_beyond;
    }
    if a <= corners[0].x {
        return corners[0].y;
    }
    corners
        .windows(2)
        .find(|w| a <= w[1].x)
        .map_or(last.y, |w| {
            let t = (a - w[0].x) / (w[1].x - w[0].x).max(f64::EPSILON);
            w[0].y + t * (w[1].y - w[0].y)
        })
}

impl Pectoralis {
    /// The muscle of `side` from the landmarks, `thickness_mm` thick in its middle.
    ///
    /// Errors: Px not below Pj (no sternal origin). A fold point or clavicle nearer the
    /// midline than the corner before it is left out of the border, with a warning.
    pub fn from_landmarks(
        side: Side,
        frame: &AnatomicalFrame,
        landmarks: &Landmarks,
        thickness_mm: f64,
    ) -> Result<Pectoralis, SimulationError> {
        let side_sign = match side {
            Side::Left => 1.0,
            Side::Right => -1.0,
        };
        let (clavicle, fold, fold_lateral) = match side {
            Side::Left => (LandmarkName::Pcl, LandmarkName::PSMFl, LandmarkName::PSMFll),
            Side::Right => (LandmarkName::Pcr, LandmarkName::PSMFr, LandmarkName::PSMFlr),
        };
        let at = |name| {
            let p = frame.to_local(landmarks.get(name));
            DVec2::new(p.x * side_sign, p.y)
        };
        let lower_origin_y_mm = at(LandmarkName::Px).y;
        let bad = |what: String| {
            Err(SimulationError::BadModel(format!(
                "the {side} pectoralis major cannot be placed: {what}; check the landmarks"
            )))
        };
        if lower_origin_y_mm.is_nan() || lower_origin_y_mm >= 0.0 {
            return bad(format!(
                "Px lies {lower_origin_y_mm:.0} mm above Pj in the standing frame"
            ));
        }
        let lower_origin = DVec2::new(MEDIAL_ORIGIN_MM, lower_origin_y_mm);
        let mut warnings = Vec::new();
        // corners in order from the midline; one out of order is left out and said
        let mut ordered = |corners: &[(DVec2, LandmarkName)], start: DVec2| {
            let mut kept = vec![start];
            for &(corner, name) in corners {
                let last = kept[kept.len() - 1];
                if corner.x > last.x && corner.is_finite() {
                    kept.push(corner);
                } else {
                    warnings.push(format!(
                        "the {side} pectoralis major's border leaves out {} ({:.0} mm from \
                         the midline), which does not lie beyond the border's last corner \
                         ({:.0} mm)",
                        name.as_str(),
                        corner.x,
                        last.x
                    ));
                }
            }
            kept
        };
        let inferior = ordered(
            &[(at(fold), fold), (at(fold_lateral), fold_lateral)],
            lower_origin,
        );
        let below_clavicle = at(clavicle) - DVec2::new(0.0, BELOW_CLAVICLE_MM);
        let clavicular = ordered(
            &[(below_clavicle, clavicle)],
            DVec2::new(MEDIAL_ORIGIN_MM, 0.0),
        );
        Ok(Pectoralis {
            side,
            side_sign,
            medial_a_mm: MEDIAL_ORIGIN_MM,
            origin_top_y_mm: 0.0,
            lower_origin_y_mm,
            inferior,
            clavicular,
            warnings,
            thickness_mm,
        })
    }

    /// `(a, y)` of a point given in the standing frame: `a` towards this side.
    fn outline_coords(&self, local: DVec3) -> DVec2 {
        DVec2::new(local.x * self.side_sign, local.y)
    }

    /// The inferior border's height at `a` (mm, standing frame).
    pub fn inferior_y_mm(&self, a: f64) -> f64 {
        polyline_y(&self.inferior, a, AXILLARY_RISE_DEG.to_radians().tan())
    }

    /// The clavicular border's height at `a` (mm, standing frame).
    pub fn clavicular_y_mm(&self, a: f64) -> f64 {
        polyline_y(&self.clavicular, a, 0.0)
    }

    /// The muscle's thickness (mm) over the point `local` (standing frame): zero outside
    /// the outline, full [`BORDER_TAPER_MM`] inside every border.
    pub fn thickness_at(&self, local: DVec3) -> f64 {
        let p = self.outline_coords(local);
        let inside_mm = (p.x - self.medial_a_mm)
            .min(p.y - self.inferior_y_mm(p.x))
            .min(self.clavicular_y_mm(p.x) - p.y);
        self.thickness_mm * (inside_mm / BORDER_TAPER_MM).clamp(0.0, 1.0)
    }
}

/// Both muscles and the tetrahedra of a mesh they take.
#[derive(Debug, Clone)]
pub struct MuscleLayer {
    /// `[left, right]`; `None` where the landmarks place no muscle (see `warnings`).
    pub muscles: [Option<Pectoralis>; 2],
    /// What the user should know: landmarks left out of an outline, a side without one.
    pub warnings: Vec<String>,
    /// Per side, the muscle's tetrahedra (indices into the mesh), ascending.
    pub elements: [Vec<u32>; 2],
}

/// What the layer's elements measure, per side (standing frame).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MuscleFigures {
    /// Nearest approach of a muscle element's centroid to the midline (mm).
    pub medial_border_from_midline_mm: f64,
    /// Height above Px (mm; negative below) of the lowest muscle element's centroid over
    /// the sternum (within [`crate::STERNUM_HALF_WIDTH_MM`] of the midline): where its
    /// sternal origin ends; `None` where no element lies over the sternum.
    pub lower_sternal_origin_above_px_mm: Option<f64>,
    /// Volume over the area it covers on the rear wall (mm).
    pub mean_thickness_mm: f64,
    /// Rear-wall area under the muscle's elements (cm²).
    pub area_cm2: f64,
    pub volume_ml: f64,
}

impl MuscleLayer {
    /// The muscles of both sides placed from the landmarks, with the tetrahedra of
    /// `mesh` each takes: those whose centroid lies within its thickness in front of
    /// `closed`'s rear wall and at least [`DEFAULT_SHIFT_MM`] under its skin. The full
    /// thickness is the rear-wall offset less [`DEFAULT_SHIFT_MM`] (the bed's default
    /// depth, so the muscle ends where a subglandular implant lies).
    ///
    /// Errors: a closed surface without a rear wall or skin. A side whose landmarks place no
    /// muscle has none, and a warning says so.
    pub fn new(
        mesh: &TetMesh,
        closed: &ClosedSurface,
        frame: &AnatomicalFrame,
        landmarks: &Landmarks,
    ) -> Result<MuscleLayer, SimulationError> {
        let thickness_mm = (closed.rear_wall_offset_mm - DEFAULT_SHIFT_MM).max(0.0);
        let mut warnings = Vec::new();
        let muscles = Side::BOTH.map(|side| {
            match Pectoralis::from_landmarks(side, frame, landmarks, thickness_mm) {
                Ok(muscle) => {
                    warnings.extend(muscle.warnings.iter().cloned());
                    Some(muscle)
                }
                Err(error) => {
                    warnings.push(format!("{error}: that side is breast tissue throughout"));
                    None
                }
            }
        });
        let (wall, skin) = (rear_wall(closed), part_index(closed, closed.front.clone()));
        let (Some(wall), Some(skin)) = (wall, skin) else {
            return Err(SimulationError::BadModel(
                "the closed surface has no rear wall or no skin".into(),
            ));
        };
        let side_of = |local: DVec3| if local.x >= 0.0 { 0 } else { 1 };
        let tagged: Vec<Option<(usize, u32)>> = (0..mesh.tets.len())
            .into_par_iter()
            .map(|e| {
                let centroid = mesh.tets[e]
                    .iter()
                    .map(|&v| mesh.positions[v as usize])
                    .sum::<DVec3>()
                    / 4.0;
                let local = frame.to_local(centroid);
                let s = side_of(local);
                let thickness = muscles[s].as_ref().map_or(0.0, |m| m.thickness_at(local));
                // within the thickness of the wall, and never nearer the skin than the bed
                // lies (where the wall comes close to the skin at the chest's side)
                let muscle = thickness > 0.0
                    && wall.is_within(centroid, thickness)
                    && !skin.is_within(centroid, DEFAULT_SHIFT_MM);
                muscle.then_some((s, e as u32))
            })
            .collect();
        let mut elements = [Vec::new(), Vec::new()];
        for (s, e) in tagged.into_iter().flatten() {
            elements[s].push(e);
        }
        Ok(MuscleLayer {
            muscles,
            warnings,
            elements,
        })
    }

    /// The muscle of `side`'s elements as a mesh of their own (the mesh's vertices they
    /// use, renumbered), `None` where the side has none.
    pub fn side_mesh(&self, mesh: &TetMesh, side: Side) -> Option<TetMesh> {
        elements_mesh(mesh, &self.elements[side as usize])
    }

    /// The surface of both muscles' elements (outward), as the GUI draws them; `None`
    /// where neither side has any.
    pub fn surface(&self, mesh: &TetMesh) -> Option<TriMesh> {
        let both: Vec<u32> = self.elements.iter().flatten().copied().collect();
        elements_mesh(mesh, &both).map(|m| m.boundary().mesh)
    }

    /// The closed surface of `side`'s muscle elements (outward), what
    /// `muscle_left.ply`/`muscle_right.ply` hold; `None` where the side has none.
    pub fn side_surface(&self, mesh: &TetMesh, side: Side) -> Option<TriMesh> {
        self.side_mesh(mesh, side).map(|m| m.boundary().mesh)
    }

    /// What `side`'s muscle elements measure ([`MuscleFigures`]); `None` where the side
    /// has none. `px_y_mm` is Px's height in the standing frame; faces of the muscle's
    /// surface within `wall_tolerance_mm` of the rear wall count as the area it covers.
    pub fn figures(
        &self,
        mesh: &TetMesh,
        closed: &ClosedSurface,
        frame: &AnatomicalFrame,
        side: Side,
        wall_tolerance_mm: f64,
    ) -> Option<MuscleFigures> {
        let muscle = self.muscles[side as usize].as_ref()?;
        let sub = self.side_mesh(mesh, side)?;
        let wall = rear_wall(closed)?;
        let volume_mm3: f64 = sub.tets.iter().map(|t| tet_volume(&sub.positions, t)).sum();
        let surface = sub.boundary().mesh;
        let area_mm2: f64 = surface
            .triangles
            .iter()
            .map(|t| t.map(|v| surface.positions[v as usize]))
            .filter(|p| p.iter().all(|&q| wall.is_within(q, wall_tolerance_mm)))
            .map(|[a, b, c]| 0.5 * (b - a).cross(c - a).length())
            .sum();
        let centroids: Vec<DVec2> = sub
            .tets
            .iter()
            .map(|t| {
                let c = t.iter().map(|&v| sub.positions[v as usize]).sum::<DVec3>() / 4.0;
                muscle.outline_coords(frame.to_local(c))
            })
            .collect();
        let medial = centroids.iter().map(|c| c.x).fold(f64::INFINITY, f64::min);
        let lowest_medial = centroids
            .iter()
            .filter(|c| c.x <= crate::STERNUM_HALF_WIDTH_MM)
            .map(|c| c.y)
            .reduce(f64::min);
        Some(MuscleFigures {
            medial_border_from_midline_mm: medial,
            lower_sternal_origin_above_px_mm: lowest_medial.map(|y| y - muscle.lower_origin_y_mm),
            mean_thickness_mm: if area_mm2 > 0.0 {
                volume_mm3 / area_mm2
            } else {
                0.0
            },
            area_cm2: area_mm2 / 100.0,
            volume_ml: volume_mm3 / 1000.0,
        })
    }
}

/// The tetrahedra `elements` of `mesh` as a mesh of their own (the vertices they use,
/// renumbered); `None` for none.
fn elements_mesh(mesh: &TetMesh, elements: &[u32]) -> Option<TetMesh> {
    if elements.is_empty() {
        return None;
    }
    let mut new_index = vec![u32::MAX; mesh.positions.len()];
    let mut positions = Vec::new();
    let tets = elements
        .iter()
        .map(|&e| {
            mesh.tets[e as usize].map(|v| {
                let slot = &mut new_index[v as usize];
                if *slot == u32::MAX {
                    *slot = positions.len() as u32;
                    positions.push(mesh.positions[v as usize]);
                }
                *slot
            })
        })
        .collect();
    Some(TetMesh { positions, tets })
}

/// The closed surface's rear wall as a surface index; `None` without its triangles.
fn rear_wall(closed: &ClosedSurface) -> Option<SurfaceIndex> {
    part_index(closed, closed.back_wall.clone())
}

/// The triangles `part` of the closed surface as a surface index; `None` for none.
fn part_index(closed: &ClosedSurface, part: std::ops::Range<usize>) -> Option<SurfaceIndex> {
    let triangles = closed.mesh.triangles[part].to_vec();
    SurfaceIndex::new(&TriMesh::new(closed.mesh.positions.clone(), triangles))
}

fn tet_volume(positions: &[DVec3], t: &[u32; 4]) -> f64 {
    let p = t.map(|v| positions[v as usize]);
    (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0])).abs() / 6.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use anatomy::Up;

    fn phantom_muscle(side: Side) -> (Pectoralis, AnatomicalFrame, Landmarks) {
        let landmarks = phantom::generate(&phantom::PhantomParams::default()).landmarks;
        let frame = AnatomicalFrame::from_landmarks(&landmarks, Up::FILE_VERTICAL).unwrap();
        let muscle = Pectoralis::from_landmarks(side, &frame, &landmarks, 10.0).unwrap();
        (muscle, frame, landmarks)
    }

    /// The outline's corners are the landmarks' (exactly, in the standing frame), and
    /// the thickness ramps linearly over the taper: at a point `d` inside the medial
    /// border, far from the others, it is `10 d / 20` mm.
    #[test]
    fn the_outline_follows_the_landmarks_and_tapers_linearly() {
        for side in Side::BOTH {
            let (muscle, frame, landmarks) = phantom_muscle(side);
            let sign = if side == Side::Left { 1.0 } else { -1.0 };
            let fold = frame.to_local(landmarks.get(match side {
                Side::Left => LandmarkName::PSMFl,
                Side::Right => LandmarkName::PSMFr,
            }));
            assert!((muscle.inferior_y_mm(fold.x * sign) - fold.y).abs() < 1e-9);
            let px_y = frame.to_local(landmarks.get(LandmarkName::Px)).y;
            assert_eq!(muscle.inferior_y_mm(MEDIAL_ORIGIN_MM), px_y);
            // half-way down the sternum, d mm lateral of the origin
            let y = 0.5 * px_y;
            for d in [0.0, 5.0, 10.0, 20.0, 30.0] {
                let local = DVec3::new(sign * (MEDIAL_ORIGIN_MM + d), y, 0.0);
                let expected = 10.0 * (d / BORDER_TAPER_MM).min(1.0);
                assert!(
                    (muscle.thickness_at(local) - expected).abs() < 1e-9,
                    "{side} {d}"
                );
            }
            // across the midline, below the fold and above the clavicle: none
            for local in [
                DVec3::new(-sign * 20.0, y, 0.0),
                DVec3::new(sign * fold.x * sign, fold.y - 1.0, 0.0),
                DVec3::new(sign * 40.0, 1.0, 0.0),
            ] {
                assert_eq!(muscle.thickness_at(local), 0.0, "{side} {local}");
            }
        }
    }

    /// Beyond the fold's lateral end the free edge rises at 45°: 10 mm further out it
    /// lies 10 mm higher.
    #[test]
    fn the_free_edge_rises_towards_the_axilla() {
        let (muscle, _, _) = phantom_muscle(Side::Left);
        let end = muscle.inferior[muscle.inferior.len() - 1];
        assert!((muscle.inferior_y_mm(end.x + 10.0) - (end.y + 10.0)).abs() < 1e-9);
    }

    /// A fold point nearer the midline than the sternal origin is left out of the
    /// border, named in a warning, and the border runs from the origin to the next
    /// corner; Px above Pj places no muscle on either side, and the layer says so.
    #[test]
    fn landmarks_out_of_order_are_left_out_and_said() {
        let mut landmarks = phantom::generate(&phantom::PhantomParams::default()).landmarks;
        let frame = AnatomicalFrame::from_landmarks(&landmarks, Up::FILE_VERTICAL).unwrap();
        let local = frame.to_local(landmarks.get(LandmarkName::PSMFl));
        landmarks.set(
            LandmarkName::PSMFl,
            frame.to_file(DVec3::new(2.0, local.y, local.z)),
        );
        let muscle = Pectoralis::from_landmarks(Side::Left, &frame, &landmarks, 10.0).unwrap();
        assert_eq!(muscle.inferior.len(), 2);
        assert_eq!(muscle.warnings.len(), 1);
        assert!(
            muscle.warnings[0].contains("PSMFl"),
            "{:?}",
            muscle.warnings
        );
        let right = Pectoralis::from_landmarks(Side::Right, &frame, &landmarks, 10.0).unwrap();
        assert!(right.warnings.is_empty());

        let pj = landmarks.get(LandmarkName::Pj);
        landmarks.set(LandmarkName::Px, pj + frame.up() * 20.0);
        let error = Pectoralis::from_landmarks(Side::Left, &frame, &landmarks, 10.0)
            .unwrap_err()
            .to_string();
        assert!(error.contains("Px lies 20 mm above Pj"), "{error}");
    }
}
