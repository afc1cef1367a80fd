//! Quadrant volumes of a closed breast (paper VI-C, Fig. 11).
//!
//! # Construction
//! The quadrants are bounded by the on-surface lines from the nipple Pn to Pc (up), PSMFl
//! (lower lateral), PSMF (down) and PSMFm (lower medial). Those lines are plane sections
//! (paper IV-A): each lies in the plane through Pn and its end landmark that contains the
//! anterior direction. All four planes therefore share the *nipple axis*, the line
//! through Pn along the anterior direction, and each line is the section of the breast
//! skin with the half-plane bounded by that axis through its end landmark. The four
//! half-planes cut space into four wedges around the axis; a quadrant is the part of
//! the closed breast (skin patch plus fill-in) inside one wedge.
//!
//! Its volume comes from the divergence theorem with the apex Pn: the sum, over the
//! closed surface's triangles clipped exactly to the wedge, of the signed volumes of the
//! cones from Pn. The wedge's walls are half-planes through Pn, so their cones are flat
//! and contribute nothing: the sum is exactly the volume of breast ∩ wedge (never
//! negative), and the four quadrants add up to the whole breast up to round-off, as every
//! triangle is partitioned among them.

use glam::{DVec2, DVec3};
use mesh::TriMesh;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// The volumes of the four quadrants of one breast (ml). "Inner" is medial (towards the
/// midline), "outer" lateral.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct QuadrantVolumes {
    pub upper_outer: f64,
    pub upper_inner: f64,
    pub lower_inner: f64,
    pub lower_outer: f64,
}

impl QuadrantVolumes {
    /// The sum of the four (ml).
    pub fn total(&self) -> f64 {
        self.upper_outer + self.upper_inner + self.lower_inner + self.lower_outer
    }

    fn get_mut(&mut self, quadrant: Quadrant) -> &mut f64 {
        match quadrant {
            Quadrant::UpperOuter => &mut self.upper_outer,
            Quadrant::UpperInner => &mut self.upper_inner,
            Quadrant::LowerInner => &mut self.lower_inner,
            Quadrant::LowerOuter => &mut self.lower_outer,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Quadrant {
    UpperOuter,
    UpperInner,
    LowerInner,
    LowerOuter,
}

/// The end points (mm) of the four on-surface lines from the nipple.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadrantLines {
    /// The nipple Pn, start of every line and apex of the cones.
    pub nipple: DVec3,
    /// Pc (Pcl or Pcr): the line up, through the upper control point.
    pub upper: DVec3,
    /// The fold's lateral end (PSMFll or PSMFlr): the line to the lower lateral side.
    pub lateral: DVec3,
    /// The fold's lowest point (PSMFl or PSMFr): the line down.
    pub lower: DVec3,
    /// The fold's medial end (PSMFml or PSMFmr): the line to the lower medial side.
    pub medial: DVec3,
}

/// Why the quadrants are undefined.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum QuadrantError {
    #[error("{0} lies on the nipple's anterior axis: the line to it has no direction")]
    OnAxis(&'static str),
    #[error(
        "the lines from the nipple to the clavicle point, the fold's lateral end, its lowest point and its medial end do not run around it in that order (seen from the front)"
    )]
    OutOfOrder,
}

/// A wedge boundary: the half-plane through the axis at `angle` (rad, from the frame's
/// first in-plane axis), and the quadrant that follows it counter-clockwise.
#[derive(Debug, Clone, Copy)]
struct Boundary {
    angle: f64,
    following: Quadrant,
}

/// Volumes (ml) of the quadrants of the closed, outward-oriented `breast`, with the
/// nipple axis along `anterior` (unit). See the module documentation.
pub fn quadrant_volumes_ml(
    breast: &TriMesh,
    lines: &QuadrantLines,
    anterior: DVec3,
) -> Result<QuadrantVolumes, QuadrantError> {
    let (e1, e2) = anterior.any_orthonormal_pair();
    let in_plane = |p: DVec3| {
        let d = p - lines.nipple;
        DVec2::new(d.dot(e1), d.dot(e2))
    };
    let direction = |p: DVec3, name: &'static str| {
        in_plane(p)
            .try_normalize()
            .ok_or(QuadrantError::OnAxis(name))
    };
    let ends = [
        direction(lines.upper, "the clavicle point")?,
        direction(lines.lateral, "the fold's lateral end")?,
        direction(lines.lower, "the fold's lowest point")?,
        direction(lines.medial, "the fold's medial end")?,
    ];
    let boundaries = wedge_boundaries(ends)?;
    // The full plane through the axis and each line end; a piece of a triangle on one
    // side of all four lies in one wedge of one quadrant.
    let plane_normals = ends.map(|d| anterior.cross(e1 * d.x + e2 * d.y));

    let mut six_volumes = QuadrantVolumes::default();
    let mut pieces: Vec<Vec<DVec3>> = Vec::new();
    for t in 0..breast.triangle_count() {
        pieces.clear();
        pieces.push(breast.triangle_positions(t).to_vec());
        for normal in &plane_normals {
            let distance = |p: DVec3| (p - lines.nipple).dot(*normal);
            // Only the pieces from earlier planes: the new ones lie on one side of this
            // plane (up to round-off in their crossing points).
            for k in 0..pieces.len() {
                if let Some((front, back)) = split(&pieces[k], distance) {
                    pieces[k] = front;
                    pieces.push(back);
                }
            }
        }
        for piece in &pieces {
            let centroid = piece.iter().sum::<DVec3>() / piece.len() as f64;
            let quadrant = quadrant_at(&boundaries, in_plane(centroid));
            *six_volumes.get_mut(quadrant) += cone_six_volume(piece, lines.nipple);
        }
    }
    Ok(QuadrantVolumes {
        upper_outer: six_volumes.upper_outer / 6000.0,
        upper_inner: six_volumes.upper_inner / 6000.0,
        lower_inner: six_volumes.lower_inner / 6000.0,
        lower_outer: six_volumes.lower_outer / 6000.0,
    })
}

/// The four half-plane boundaries in counter-clockwise order starting at the upper line,
/// given the unit in-plane directions of the upper, lateral, lower and medial lines.
fn wedge_boundaries(ends: [DVec2; 4]) -> Result<[Boundary; 4], QuadrantError> {
    let angles = ends.map(|d| d.y.atan2(d.x));
    let from_upper = |k: usize| (angles[k] - angles[0]).rem_euclid(TAU);
    let (lateral, lower, medial) = (from_upper(1), from_upper(2), from_upper(3));
    let boundary = |k: usize, following| Boundary {
        angle: angles[0] + from_upper(k),
        following,
    };
    // Counter-clockwise seen from the front: lateral first on the right breast, medial
    // first on the left.
    if 0.0 < lateral && lateral < lower && lower < medial {
        Ok([
            boundary(0, Quadrant::UpperOuter),
            boundary(1, Quadrant::LowerOuter),
            boundary(2, Quadrant::LowerInner),
            boundary(3, Quadrant::UpperInner),
        ])
    } else if 0.0 < medial && medial < lower && lower < lateral {
        Ok([
            boundary(0, Quadrant::UpperInner),
            boundary(3, Quadrant::LowerInner),
            boundary(2, Quadrant::LowerOuter),
            boundary(1, Quadrant::UpperOuter),
        ])
    } else {
        Err(QuadrantError::OutOfOrder)
    }
}

/// The quadrant of the wedge holding the in-plane point `point`.
fn quadrant_at(boundaries: &[Boundary; 4], point: DVec2) -> Quadrant {
    let start = boundaries[0].angle;
    let angle = start + (point.y.atan2(point.x) - start).rem_euclid(TAU);
    boundaries
        .iter()
        .rev()
        .find(|b| b.angle <= angle)
        .unwrap_or(&boundaries[0])
        .following
}

/// Splits the convex polygon `polygon` where `distance` changes sign: `None` if it lies
/// on one side (or on the plane), else its parts on the positive and negative sides.
fn split(polygon: &[DVec3], distance: impl Fn(DVec3) -> f64) -> Option<(Vec<DVec3>, Vec<DVec3>)> {
    let distances: Vec<f64> = polygon.iter().map(|&p| distance(p)).collect();
    if distances.iter().all(|&d| d >= 0.0) || distances.iter().all(|&d| d <= 0.0) {
        return None;
    }
    let (mut front, mut back) = (Vec::new(), Vec::new());
    let n = polygon.len();
    for i in 0..n {
        let j = (i + 1) % n;
        let (p, dp, dq) = (polygon[i], distances[i], distances[j]);
        if dp >= 0.0 {
            front.push(p);
        }
        if dp <= 0.0 {
            back.push(p);
        }
        if (dp > 0.0 && dq < 0.0) || (dp < 0.0 && dq > 0.0) {
            let crossing = p.lerp(polygon[j], dp / (dp - dq));
            front.push(crossing);
            back.push(crossing);
        }
    }
    Some((front, back))
}

/// Six times the signed volume (mm³) of the cone from `apex` over the planar polygon.
fn cone_six_volume(polygon: &[DVec3], apex: DVec3) -> f64 {
    let a = polygon[0] - apex;
    polygon
        .windows(2)
        .skip(1)
        .map(|w| a.dot((w[0] - apex).cross(w[1] - apex)))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesh::shapes::icosphere;

    /// Lines as on a left breast seen from the front (+z): up, lower lateral (+x), down,
    /// lower medial (-x).
    fn left_breast_lines(nipple: DVec3) -> QuadrantLines {
        QuadrantLines {
            nipple,
            upper: nipple + DVec3::new(0.0, 80.0, -20.0),
            lateral: nipple + DVec3::new(60.0, -40.0, -20.0),
            lower: nipple + DVec3::new(0.0, -60.0, -20.0),
            medial: nipple + DVec3::new(-50.0, -45.0, -20.0),
        }
    }

    #[test]
    fn quadrants_of_a_sphere_are_its_wedges() {
        let radius = 50.0;
        let sphere = icosphere(radius, 5);
        let nipple = DVec3::new(0.0, 0.0, radius);
        let lines = left_breast_lines(nipple);
        let volumes = quadrant_volumes_ml(&sphere, &lines, DVec3::Z).unwrap();
        let total = sphere.signed_volume() / 1000.0;
        assert!((volumes.total() - total).abs() < 1e-9 * total);
        // Each wedge about the z axis holds its angle's share of the ball.
        let angle = |p: DVec3| (p.y - nipple.y).atan2(p.x - nipple.x);
        let share = |from: DVec3, to: DVec3| (angle(to) - angle(from)).rem_euclid(TAU) / TAU;
        let expected = [
            (volumes.upper_outer, share(lines.lateral, lines.upper)),
            (volumes.upper_inner, share(lines.upper, lines.medial)),
            (volumes.lower_inner, share(lines.medial, lines.lower)),
            (volumes.lower_outer, share(lines.lower, lines.lateral)),
        ];
        for (volume, fraction) in expected {
            assert!((volume - fraction * total).abs() < 2e-3 * total, "{volume}");
        }
    }

    #[test]
    fn mirrored_lines_swap_the_sense_of_rotation() {
        let sphere = icosphere(40.0, 4);
        let nipple = DVec3::new(0.0, 0.0, 40.0);
        let left = left_breast_lines(nipple);
        let mirror = |p: DVec3| DVec3::new(-p.x, p.y, p.z);
        let right = QuadrantLines {
            nipple,
            upper: mirror(left.upper),
            lateral: mirror(left.lateral),
            lower: mirror(left.lower),
            medial: mirror(left.medial),
        };
        let a = quadrant_volumes_ml(&sphere, &left, DVec3::Z).unwrap();
        let b = quadrant_volumes_ml(&sphere, &right, DVec3::Z).unwrap();
        for (x, y) in [
            (a.upper_outer, b.upper_outer),
            (a.upper_inner, b.upper_inner),
            (a.lower_inner, b.lower_inner),
            (a.lower_outer, b.lower_outer),
        ] {
            // The icosphere is symmetric under x -> -x up to its triangulation.
            assert!((x - y).abs() < 0.01 * a.total(), "{x} {y}");
        }
    }

    #[test]
    fn lines_out_of_order_are_refused() {
        let sphere = icosphere(40.0, 2);
        let mut lines = left_breast_lines(DVec3::new(0.0, 0.0, 40.0));
        std::mem::swap(&mut lines.lower, &mut lines.medial);
        assert_eq!(
            quadrant_volumes_ml(&sphere, &lines, DVec3::Z),
            Err(QuadrantError::OutOfOrder)
        );
        lines.upper = lines.nipple + DVec3::Z;
        assert_eq!(
            quadrant_volumes_ml(&sphere, &lines, DVec3::Z),
            Err(QuadrantError::OnAxis("the clavicle point"))
        );
    }
}
