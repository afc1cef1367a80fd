//! The surface the hole is projected onto: the loop's best-fit plane, or a cylinder
//! fitted to the chest around it.

use super::{FillInError, arc_length_weights, weighted_centroid};
use faer::{Mat, Side};
use glam::{DMat3, DVec2, DVec3};
use mesh::TriMesh;

/// Ratio of the middle to the largest covariance eigenvalue of the loop at or below which
/// its points count as collinear.
const COLLINEAR_EIGENVALUE_RATIO: f64 = 1e-12;

/// The surface the hole is projected onto, with coordinates `(u, v, w)` (mm): `(u, v)`
/// on the surface (lengths along it), `w` the height above it.
pub(super) enum Frame {
    /// The loop's least-squares plane.
    Plane {
        /// Arc-length weighted centroid of the loop (mm).
        origin: DVec3,
        /// Columns: the `u` axis (the loop's principal direction), `v`, and the normal.
        axes: DMat3,
    },
    /// A cylinder about the chest's axis (near the body's long axis): `u` runs around it
    /// (arc length at the radius), `v` along it, `w` outwards from it.
    Cylinder {
        /// A point on the axis (mm).
        centre: DVec3,
        /// Columns: the radial direction at `u = 0` (towards the loop), the direction of
        /// growing `u` there, and the axis.
        axes: DMat3,
        radius_mm: f64,
    },
}

/// A fitted cylinder is refused (and the plane used) if its radius exceeds this many
/// times the diameter of the fitted chest (seen along the axis): the chest is then
/// nearly flat and the centre poorly determined; the plane serves as well.
const MAX_CYLINDER_RADIUS_IN_EXTENTS: f64 = 20.0;

/// The cylinder is fitted to the base vertices up to this far (mm) beyond the loop's
/// largest distance from its centroid: the chest around the breast, sternum to side. A
/// choice: wide enough to span the chest's curvature round the breast (the hole itself
/// is some 130 mm across), narrow enough to stay on the front of the chest.
const CYLINDER_BAND_MM: f64 = 40.0;

/// A fitted cylinder is refused unless the base normals along the loop point away from
/// its axis by at least this mean cosine (60°): the surface must wrap around the axis,
/// not face it. Chests give 0.8 to 0.95.
const MIN_OUTWARD_COSINE: f64 = 0.5;

/// The cylinder's axis is the chest's own ([`chest_axis`]) up to this angle (degrees)
/// from the body's long axis, turning to the body's axis from there to
/// [`MAX_AXIS_TILT_DEG`]. Chests give 11 to 20° from the sternum
/// (docs/dev/fill-in-axis.md); a direction further off is not the torso's wrap but a
/// fold or a shoulder in the band.
const FULL_AXIS_TILT_DEG: f64 = 30.0;
/// Beyond this angle (degrees) from the body's axis the chest's own axis is not used.
const MAX_AXIS_TILT_DEG: f64 = 45.0;
/// The chest's axis is determined where the normals' smallest variance is well below
/// the next, `λ₀ / λ₁` at most this (chests: 0.2 to 0.5); it gives way to the body's
/// axis from there to [`MAX_EIGENVALUE_RATIO`], where a dome or a flat band leaves the
/// direction free within a plane.
const FULL_EIGENVALUE_RATIO: f64 = 0.6;
/// At or beyond this `λ₀ / λ₁` the body's axis is used.
const MAX_EIGENVALUE_RATIO: f64 = 0.8;

impl Frame {
    /// Least-squares plane of the loop, its normal on the side of `reference_normal`.
    pub(super) fn fit(
        loop_positions: &[DVec3],
        reference_normal: DVec3,
    ) -> Result<Frame, FillInError> {
        let weights = arc_length_weights(loop_positions);
        let origin = weighted_centroid(loop_positions, &weights).ok_or(FillInError::Collinear)?;
        let covariance = Mat::<f64>::from_fn(3, 3, |i, j| {
            loop_positions
                .iter()
                .zip(&weights)
                .map(|(p, w)| w * (p[i] - origin[i]) * (p[j] - origin[j]))
                .sum()
        });
        let eigen = covariance
            .self_adjoint_eigen(Side::Lower)
            .map_err(|_| FillInError::Collinear)?;
        // Eigenvalues in nondecreasing order.
        let eigenvalues = eigen.S().column_vector();
        if eigenvalues[1] <= COLLINEAR_EIGENVALUE_RATIO * eigenvalues[2] {
            return Err(FillInError::Collinear);
        }
        let vectors = eigen.U();
        let column = |j: usize| DVec3::new(vectors[(0, j)], vectors[(1, j)], vectors[(2, j)]);
        let mut normal = column(0);
        if normal.dot(reference_normal) < 0.0 {
            normal = -normal;
        }
        let u_axis = column(2);
        Ok(Frame::Plane {
            origin,
            axes: DMat3::from_cols(u_axis, normal.cross(u_axis), normal),
        })
    }

    /// The plane through `plane`'s origin orthogonal to the loop's vector area
    /// (`1/2 sum p_i x p_(i+1)`), the direction from which the loop encloses the largest
    /// area, turned towards `reference_normal`; `u` is `plane`'s `u` made orthogonal to
    /// it. `None` for a loop enclosing no area or a `plane` that is not a plane.
    pub(super) fn facing(
        loop_positions: &[DVec3],
        reference_normal: DVec3,
        plane: &Frame,
    ) -> Option<Frame> {
        let Frame::Plane { origin, axes } = plane else {
            return None;
        };
        let n = loop_positions.len();
        let vector_area: DVec3 = (0..n)
            .map(|i| (loop_positions[i] - *origin).cross(loop_positions[(i + 1) % n] - *origin))
            .sum::<DVec3>()
            * 0.5;
        let mut normal = vector_area.try_normalize()?;
        if normal.dot(reference_normal) < 0.0 {
            normal = -normal;
        }
        let u_axis = (axes.x_axis - normal * axes.x_axis.dot(normal))
            .try_normalize()
            .or_else(|| normal.any_orthonormal_vector().try_normalize())?;
        Some(Frame::Plane {
            origin: *origin,
            axes: DMat3::from_cols(u_axis, normal.cross(u_axis), normal),
        })
    }

    /// The cylinder the chest around the hole wraps around: its axis the chest's own
    /// ([`chest_axis`]) near `body_axis`, its circle an algebraic (Kåsa) least-squares
    /// circle through the base vertices within [`CYLINDER_BAND_MM`] of the loop's
    /// extent, seen along that axis. The base right at the loop is not enough: there it
    /// still curves round the breast's rim, which would give a cylinder the size of the
    /// breast. `None` if the fit is ill-conditioned or the base does not face away from
    /// the axis along the loop.
    pub(super) fn fit_cylinder(
        base: &TriMesh,
        loop_positions: &[DVec3],
        base_normals: &[DVec3],
        body_axis: DVec3,
    ) -> Option<Frame> {
        let body_axis = body_axis.try_normalize()?;
        let weights = arc_length_weights(loop_positions);
        let total_weight: f64 = weights.iter().sum();
        let centroid = weighted_centroid(loop_positions, &weights)?;
        let loop_extent = loop_positions
            .iter()
            .map(|p| p.distance(centroid))
            .fold(0.0, f64::max);
        let axis = chest_axis(base, centroid, loop_extent + CYLINDER_BAND_MM, body_axis);
        let first = axis.any_orthonormal_vector();
        let second = axis.cross(first);
        let across = |p: DVec3| DVec2::new((p - centroid).dot(first), (p - centroid).dot(second));
        // Minimise sum (|q|² + D q.x + E q.y + F)² over (D, E, F): 3x3 normal equations.
        let (mut normal_matrix, mut right_side) = (DMat3::ZERO, DVec3::ZERO);
        let mut extent: f64 = 0.0;
        for &p in &base.positions {
            let near_hole = p.distance(centroid) <= loop_extent + CYLINDER_BAND_MM;
            if !near_hole {
                continue;
            }
            let q = across(p);
            extent = extent.max(q.length());
            let row = DVec3::new(q.x, q.y, 1.0);
            normal_matrix += DMat3::from_cols(row * row.x, row * row.y, row * row.z);
            right_side -= row * q.length_squared();
        }
        let scale = normal_matrix
            .to_cols_array()
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        if normal_matrix.determinant().abs() <= f64::EPSILON * scale.powi(3) {
            return None;
        }
        let [d, e, f] = (normal_matrix.inverse() * right_side).to_array();
        let centre_across = DVec2::new(-0.5 * d, -0.5 * e);
        let radius_mm = (centre_across.length_squared() - f).sqrt();
        if !radius_mm.is_finite() || radius_mm > MAX_CYLINDER_RADIUS_IN_EXTENTS * 2.0 * extent {
            return None;
        }
        let centre = centroid + centre_across.x * first + centre_across.y * second;
        let radial = |p: DVec3| {
            let offset = p - centre;
            (offset - axis * offset.dot(axis)).normalize_or_zero()
        };
        let outward_cosine = base_normals
            .iter()
            .zip(loop_positions)
            .zip(&weights)
            .map(|((n, &p), w)| w * n.dot(radial(p)))
            .sum::<f64>()
            / total_weight;
        let towards_loop = radial(centroid);
        let wraps_around_axis = outward_cosine >= MIN_OUTWARD_COSINE;
        if !wraps_around_axis || towards_loop == DVec3::ZERO {
            return None;
        }
        Some(Frame::Cylinder {
            centre,
            axes: DMat3::from_cols(towards_loop, axis.cross(towards_loop), axis),
            radius_mm,
        })
    }

    /// World to frame coordinates `(u, v, w)` (mm).
    pub(super) fn to_local(&self, p: DVec3) -> DVec3 {
        match self {
            Frame::Plane { origin, axes } => axes.transpose() * (p - *origin),
            Frame::Cylinder {
                centre,
                axes,
                radius_mm,
            } => {
                let q = axes.transpose() * (p - *centre);
                let angle = q.y.atan2(q.x);
                DVec3::new(radius_mm * angle, q.z, q.truncate().length() - radius_mm)
            }
        }
    }

    /// Frame coordinates `(u, v, w)` to world (mm).
    pub(super) fn to_world(&self, local: DVec3) -> DVec3 {
        match self {
            Frame::Plane { origin, axes } => *origin + *axes * local,
            Frame::Cylinder {
                centre,
                axes,
                radius_mm,
            } => {
                let (sin, cos) = (local.x / radius_mm).sin_cos();
                let radius = radius_mm + local.z;
                *centre + *axes * DVec3::new(radius * cos, radius * sin, local.y)
            }
        }
    }

    /// A surface normal `n` at world point `p` in frame coordinates: the vector whose
    /// components give the surface's slopes `dw/du = -n.x / n.z`, `dw/dv = -n.y / n.z`.
    pub(super) fn normal_to_local(&self, p: DVec3, n: DVec3) -> DVec3 {
        match self {
            Frame::Plane { axes, .. } => axes.transpose() * n,
            Frame::Cylinder {
                centre,
                axes,
                radius_mm,
            } => {
                let q = axes.transpose() * (p - *centre);
                let radius = q.truncate().length();
                let radial = (*axes * q.truncate().extend(0.0)).normalize_or_zero();
                let axis = axes.z_axis;
                let around = axis.cross(radial);
                // d p / d u = (radius / R) around + w_u radial.
                DVec3::new(
                    n.dot(around) * radius / radius_mm,
                    n.dot(axis),
                    n.dot(radial),
                )
            }
        }
    }
}

/// The axis the surface of `base` within `radius_mm` of `centre` wraps around: the
/// direction its area-weighted normals vary least along, the smallest eigenvector of
/// `sum a n nᵀ` (on a cylinder every normal is orthogonal to the axis), turned to
/// `body_axis`'s side. The body's long axis is not the chest's: the sternum leans back
/// some 25° from the vertical and the chest widens towards the armpits, so a cylinder
/// about the sternum's direction had its axis come out through the chest below the
/// breast, where the fill-in's coordinates are singular. Where the direction is poorly determined
/// ([`MAX_EIGENVALUE_RATIO`]) or far from `body_axis` ([`MAX_AXIS_TILT_DEG`]) it turns
/// continuously into `body_axis`, so a small change of the band never flips the fill-in;
/// `body_axis` itself where the band has no triangles.
pub(super) fn chest_axis(base: &TriMesh, centre: DVec3, radius_mm: f64, body_axis: DVec3) -> DVec3 {
    let mut covariance = DMat3::ZERO;
    // A triangle naming a vertex the base lacks gives no normal.
    let corners = |t: &[u32; 3]| -> Option<[DVec3; 3]> {
        let at = |v: u32| base.positions.get(v as usize).copied();
        Some([at(t[0])?, at(t[1])?, at(t[2])?])
    };
    for [a, b, c] in base.triangles.iter().filter_map(corners) {
        let in_band = (a + b + c).distance(3.0 * centre) <= 3.0 * radius_mm;
        if !in_band {
            continue;
        }
        let twice_area_normal = (b - a).cross(c - a);
        let twice_area = twice_area_normal.length();
        if twice_area > 0.0 && twice_area.is_finite() {
            let n = twice_area_normal / twice_area;
            covariance += DMat3::from_cols(n * n.x, n * n.y, n * n.z) * twice_area;
        }
    }
    let matrix = Mat::<f64>::from_fn(3, 3, |i, j| covariance.col(j)[i]);
    let Ok(eigen) = matrix.self_adjoint_eigen(Side::Lower) else {
        return body_axis;
    };
    let eigenvalues = eigen.S().column_vector();
    let vectors = eigen.U();
    let smallest = DVec3::new(vectors[(0, 0)], vectors[(1, 0)], vectors[(2, 0)]);
    let Some(axis) = smallest.try_normalize() else {
        return body_axis;
    };
    let axis = if axis.dot(body_axis) < 0.0 {
        -axis
    } else {
        axis
    };
    let tilt_deg = axis.angle_between(body_axis).to_degrees();
    let ratio = eigenvalues[0] / eigenvalues[1];
    let weight = falling_ramp(tilt_deg, FULL_AXIS_TILT_DEG, MAX_AXIS_TILT_DEG)
        * falling_ramp(ratio, FULL_EIGENVALUE_RATIO, MAX_EIGENVALUE_RATIO);
    body_axis
        .lerp(axis, weight)
        .try_normalize()
        .unwrap_or(body_axis)
}

/// 1 up to `full`, 0 from `none` on, a smoothstep between; 0 for NaN.
fn falling_ramp(x: f64, full: f64, none: f64) -> f64 {
    let t = ((none - x) / (none - full)).clamp(0.0, 1.0);
    if t.is_nan() {
        0.0
    } else {
        t * t * (3.0 - 2.0 * t)
    }
}
