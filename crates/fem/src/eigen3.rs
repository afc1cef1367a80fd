//! Closed-form eigendecomposition of a symmetric 3x3 matrix, for the principal
//! stretches of [`crate::Tangent::Full`]'s geometric term where its closed form without
//! them does not apply (`model::unclamped_twist`).
//!
//! Eigenvalues by the trigonometric solution of the characteristic cubic (Smith, "Eigen
//! values of a symmetric 3 × 3 matrix", Commun. ACM 4, 1961); each eigenvector of a
//! well separated eigenvalue as the largest cross product of two rows of `A - λI`; the
//! middle one completes the basis. About a fifth of the cyclic Jacobi iteration's time
//! ([`crate::polar`]), at an accuracy (relative to the largest eigenvalue's magnitude)
//! of about `1e-8` near a double eigenvalue and rounding elsewhere: ample for a tangent, which
//! only steers the iteration. Where two eigenvalues coincide, any orthonormal basis of
//! their plane is returned (the geometric term is the same for all of them there).

use glam::{DMat3, DVec3};

/// Eigenvalues in descending order and matching orthonormal eigenvectors (the columns
/// of the matrix) of the symmetric `a` (only its upper triangle is read).
pub(crate) fn symmetric_eigen_closed_form(a: DMat3) -> ([f64; 3], DMat3) {
    let (a00, a11, a22) = (a.x_axis.x, a.y_axis.y, a.z_axis.z);
    let (a01, a02, a12) = (a.y_axis.x, a.z_axis.x, a.z_axis.y);
    let mean = (a00 + a11 + a22) / 3.0;
    let (b00, b11, b22) = (a00 - mean, a11 - mean, a22 - mean);
    let off = a01 * a01 + a02 * a02 + a12 * a12;
    let p2 = (b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * off) / 6.0;
    let scale = a00.abs().max(a11.abs()).max(a22.abs()).max(off.sqrt());
    // all three equal to rounding (or not finite): every basis is an eigenbasis
    if p2.is_nan() || p2 <= (1e-15 * scale).powi(2) {
        return ([mean; 3], DMat3::IDENTITY);
    }
    let p = p2.sqrt();
    // det((A - mean I) / p) / 2, in [-1, 1] up to rounding
    let det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02)
        + a02 * (a01 * a12 - b11 * a02);
    let half_det = (det / (p2 * p) * 0.5).clamp(-1.0, 1.0);
    let phi = half_det.acos() / 3.0;
    let largest = mean + 2.0 * p * phi.cos();
    let smallest = mean + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let middle = 3.0 * mean - largest - smallest;
    let values = [largest, middle, smallest];
    let rows = |l: f64| {
        [
            DVec3::new(a00 - l, a01, a02),
            DVec3::new(a01, a11 - l, a12),
            DVec3::new(a02, a12, a22 - l),
        ]
    };
    // the better separated end first: its eigenvector is the better conditioned
    let (first, other) = if largest - middle >= middle - smallest {
        (largest, smallest)
    } else {
        (smallest, largest)
    };
    let v_first = null_vector(rows(first)).unwrap_or(DVec3::X);
    let v_other = null_vector(rows(other))
        .map(|v| v - v_first * v_first.dot(v))
        .filter(|w| w.length_squared() > 1e-12)
        .map(DVec3::normalize)
        .unwrap_or_else(|| super::polar::any_orthogonal(v_first));
    let (v_largest, v_smallest) = if first == largest {
        (v_first, v_other)
    } else {
        (v_other, v_first)
    };
    let v_middle = v_smallest.cross(v_largest);
    (values, DMat3::from_cols(v_largest, v_middle, v_smallest))
}

/// The unit vector the three (symmetric) rows of a singular `A - λI` are orthogonal to:
/// the largest of their pairwise cross products; `None` if all vanish (λ at least double).
fn null_vector(rows: [DVec3; 3]) -> Option<DVec3> {
    let candidates = [
        rows[0].cross(rows[1]),
        rows[0].cross(rows[2]),
        rows[1].cross(rows[2]),
    ];
    let best = candidates
        .into_iter()
        .max_by(|x, y| x.length_squared().total_cmp(&y.length_squared()))?;
    let norm2 = best.length_squared();
    let row_scale = rows.iter().map(|r| r.length_squared()).fold(0.0, f64::max);
    (norm2 > 1e-24 * row_scale * row_scale && norm2.is_finite()).then(|| best / norm2.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::polar::symmetric_eigen;

    /// A symmetric matrix `Q diag(d) Qᵀ` with a generic rotation `Q`.
    fn with_eigenvalues(d: [f64; 3], angle: f64) -> DMat3 {
        let q = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), angle);
        q * DMat3::from_diagonal(DVec3::from_array(d)) * q.transpose()
    }

    /// Against the cyclic Jacobi iteration (an independent method): eigenvalues to
    /// 1e-12 of the largest magnitude where they are well separated (1e-8 near a double
    /// one, the closed form's conditioning there), `A v = λ v` to the same, and an orthonormal
    /// right-handed basis to 1e-12; spectra that are simple, nearly double, double, triple
    /// and of mixed sign, as principal stretches of stretched and inverted elements are.
    #[test]
    fn closed_form_agrees_with_jacobi() {
        let spectra = [
            [1.3, 1.0, 0.8],
            [1.3, 1.0, 0.8],
            [1.0 + 1e-3, 1.0, 1.0 - 2e-3],
            [1.2, 1.2 + 1e-9, 0.9],
            [1.2, 0.9, 0.9],
            [1.1, 1.1, 1.1],
            [2.0, 0.5, -0.3],
            [1e-7, -2e-7, 3e-7],
        ];
        for (k, d) in spectra.into_iter().enumerate() {
            // the first one also axis-aligned (already diagonal, unsorted)
            let a = if k == 0 {
                DMat3::from_diagonal(DVec3::new(d[2], d[0], d[1]))
            } else {
                with_eigenvalues(d, 0.3 + k as f64)
            };
            let (values, v) = symmetric_eigen_closed_form(a);
            let (jacobi, _) = symmetric_eigen(a);
            let magnitude = d.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            let gap = (d[0] - d[1])
                .abs()
                .min((d[1] - d[2]).abs())
                .min((d[0] - d[2]).abs());
            let tol = if gap > 1e-2 * magnitude { 1e-12 } else { 1e-8 } * magnitude;
            for i in 0..3 {
                assert!(
                    (values[i] - jacobi[i]).abs() <= tol,
                    "{d:?}: {values:?} vs {jacobi:?}"
                );
                let col = v.col(i);
                let residual = (a * col - col * values[i]).length();
                assert!(residual <= tol, "{d:?}: column {i} residual {residual}");
            }
            let gram = v.transpose() * v - DMat3::IDENTITY;
            assert!(
                gram.to_cols_array().iter().all(|x| x.abs() < 1e-12),
                "{d:?}"
            );
            assert!((v.determinant() - 1.0).abs() < 1e-12, "{d:?}");
        }
    }
}
