//! Robust rotation extraction: the rotation of the polar decomposition of a 3x3
//! deformation gradient, well defined for inverted and degenerate elements.
//!
//! Method (the "rotation-variant SVD" of Irving, Teran and Fedkiw, 2004): the symmetric
//! eigendecomposition `FᵀF = V Σ² Vᵀ` by cyclic Jacobi rotations gives `V`, made a proper
//! rotation; then `u₁ = F v₁ / |F v₁|`, `u₂` the normalised part of `F v₂` orthogonal to
//! `u₁`, and `u₃ = u₁ × u₂`, so `U` is a proper rotation too and the sign of an inverted
//! element ends up on the smallest singular value. `R = U Vᵀ` is always a rotation
//! (det +1); for `det F > 0` it is the polar factor, for a rigid rotation `F = Q` it is
//! `Q` to rounding, for `F` of rank 1 or 0 the missing directions are completed
//! arbitrarily but orthonormally.
//!
//! [`polar_rotation`] takes a cheaper path for the common case: for a well-conditioned
//! `F` with `det F > 0` (every element that is neither inverted nor nearly flat) it runs
//! the scaled Newton iteration `X ← ½ (γ X + X⁻ᵀ / γ)` of Higham ("Computing the polar
//! decomposition, with applications", SIAM J. Sci. Stat. Comput. 7, 1986), which
//! converges quadratically to the same (unique) polar factor: 3 to 6 iterations of one
//! 3x3 cofactor matrix each, about a fifth of the Jacobi eigendecomposition's time.
//! Inverted, nearly flat or non-converging cases go through the rotation-variant SVD.
//!
//! [`polar_rotations`] runs the Newton path on [`POLAR_LANES`] matrices at once, one per
//! lane of an AVX register (written with intrinsics, chosen at run time; elsewhere a
//! lane-wise type), with the same operations in the same order as [`polar_rotation`], so
//! both give the same bits; this is most of the time of a corotated assembly, and the
//! scalar iteration is bound by the latency of its divisions, which the lanes overlap.

#![allow(unsafe_code)] // vector kernels and raw disjoint writes, each block with its SAFETY reason
use glam::{DMat3, DVec3};

/// Symmetric eigendecomposition of a 3x3 matrix by cyclic Jacobi rotations. Returns the
/// eigenvalues in descending order and the matching eigenvectors as columns of `V`.
pub(crate) fn symmetric_eigen(s: DMat3) -> ([f64; 3], DMat3) {
    // a[r][c], row-major working copy
    let mut a = [
        [s.x_axis.x, s.y_axis.x, s.z_axis.x],
        [s.x_axis.y, s.y_axis.y, s.z_axis.y],
        [s.x_axis.z, s.y_axis.z, s.z_axis.z],
    ];
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..30 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if off <= 1e-34 * diag || off == 0.0 {
            break;
        }
        for (p, q) in [(0usize, 1usize), (0, 2), (1, 2)] {
            let apq = a[p][q];
            if apq == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * apq);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let sn = t * c;
            // A <- Jᵀ A J with J the rotation in the (p, q) plane
            for row in a.iter_mut() {
                let akp = row[p];
                let akq = row[q];
                row[p] = c * akp - sn * akq;
                row[q] = sn * akp + c * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * rp[k] - sn * rq[k];
                a[q][k] = sn * rp[k] + c * rq[k];
            }
            a[p][q] = 0.0;
            a[q][p] = 0.0;
            for row in v.iter_mut() {
                let vp = row[p];
                let vq = row[q];
                row[p] = c * vp - sn * vq;
                row[q] = sn * vp + c * vq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| a[j][j].total_cmp(&a[i][i]));
    let col = |i: usize| DVec3::new(v[0][i], v[1][i], v[2][i]);
    (
        order.map(|i| a[i][i]),
        DMat3::from_cols(col(order[0]), col(order[1]), col(order[2])),
    )
}

/// Any unit vector orthogonal to the unit vector `u`.
pub(crate) fn any_orthogonal(u: DVec3) -> DVec3 {
    let other = if u.x.abs() < 0.6 {
        DVec3::X
    } else if u.y.abs() < 0.6 {
        DVec3::Y
    } else {
        DVec3::Z
    };
    u.cross(other).normalize()
}

/// The rotation `R` (det +1) of the polar decomposition `F = R S`, robust to inverted
/// (`det F < 0`) and degenerate (rank-deficient) `F`; see the module documentation.
/// Returns the identity for `F = 0` or a non-finite `F`.
pub fn polar_rotation(f: DMat3) -> DMat3 {
    newton_polar(f).unwrap_or_else(|| rotation_variant_svd(f).0)
}

/// `det X · X⁻ᵀ` (the cofactor matrix) and `det X`.
#[inline]
fn cofactor(x: DMat3) -> (DMat3, f64) {
    let c0 = x.y_axis.cross(x.z_axis);
    let c1 = x.z_axis.cross(x.x_axis);
    let c2 = x.x_axis.cross(x.y_axis);
    (DMat3::from_cols(c0, c1, c2), x.x_axis.dot(c0))
}

/// `‖X‖²_F`.
#[inline]
fn frobenius2(x: DMat3) -> f64 {
    x.x_axis.length_squared() + x.y_axis.length_squared() + x.z_axis.length_squared()
}

/// `det F / (‖F‖_F / √3)³` below this: the Newton path is skipped (nearly flat or
/// inverted; the ratio is 1 for a rotation times a scale).
const NEWTON_MIN_CONDITION: f64 = 1e-3;

/// Scaled Newton iterations allowed before falling back to the SVD.
const NEWTON_MAX_ITERATIONS: usize = 20;

/// The polar rotation of a well-conditioned `F` with `det F > 0` by Newton's iteration
/// (one Frobenius-norm scaling step first, then plain steps: quadratic convergence, 3 to
/// 5 steps for strains up to tens of percent); `None` when `F` is not finite, inverted,
/// nearly flat, or the iteration does not converge.
fn newton_polar(f: DMat3) -> Option<DMat3> {
    let n2 = frobenius2(f);
    let (c, det) = cofactor(f);
    // det / (‖F‖/√3)³ = det · 3√3 / ‖F‖³
    if !(det.is_finite() && det > NEWTON_MIN_CONDITION * n2 * n2.sqrt() / 5.196_152_422_706_632) {
        return None;
    }
    // γ = sqrt(‖F⁻¹‖_F / ‖F‖_F) brings the singular values around 1
    let inv_t = c * (1.0 / det);
    let gamma = (frobenius2(inv_t) / n2).sqrt().sqrt();
    let mut x = (f * gamma + inv_t * (1.0 / gamma)) * 0.5;
    for _ in 0..NEWTON_MAX_ITERATIONS {
        let (c, det) = cofactor(x);
        let next = (x + c * (1.0 / det)) * 0.5;
        let delta2 = frobenius2(next - x);
        x = next;
        // the error of `next` is about delta² / 2
        if delta2 < 1e-14 {
            return Some(x);
        }
        if !delta2.is_finite() {
            return None;
        }
    }
    None
}

/// The rotation-variant SVD `F = U diag(s) Vᵀ` with `U`, `V` proper rotations and the
/// singular values `s` in descending order of magnitude except that the last one carries
/// the sign of `det F`. Returns `(R = U Vᵀ, V, s)`; `RᵀF = V diag(s) Vᵀ` is symmetric.
/// Identity and zeros for `F = 0` or a non-finite `F`.
pub fn rotation_variant_svd(f: DMat3) -> (DMat3, DMat3, [f64; 3]) {
    if !f.is_finite() {
        return (DMat3::IDENTITY, DMat3::IDENTITY, [0.0; 3]);
    }
    let scale = f.x_axis.length_squared() + f.y_axis.length_squared() + f.z_axis.length_squared();
    if scale == 0.0 {
        return (DMat3::IDENTITY, DMat3::IDENTITY, [0.0; 3]);
    }
    let (_, mut v) = symmetric_eigen(f.transpose() * f);
    if v.determinant() < 0.0 {
        v.z_axis = -v.z_axis;
    }
    let tiny = 1e-150_f64.max(scale.sqrt() * 1e-13);
    let fv1 = f * v.x_axis;
    let l1 = fv1.length();
    let u1 = if l1 > tiny { fv1 / l1 } else { v.x_axis };
    let fv2 = f * v.y_axis;
    let w2 = fv2 - u1 * u1.dot(fv2);
    let l2 = w2.length();
    let u2 = if l2 > tiny {
        w2 / l2
    } else {
        // keep the rotation closest to V when possible
        let w = v.y_axis - u1 * u1.dot(v.y_axis);
        if w.length() > 1e-6 {
            w.normalize()
        } else {
            any_orthogonal(u1)
        }
    };
    let u3 = u1.cross(u2);
    let u = DMat3::from_cols(u1, u2, u3);
    let s = [u1.dot(fv1), u2.dot(fv2), u3.dot(f * v.z_axis)];
    (u * v.transpose(), v, s)
}

/// Matrices whose rotations [`polar_rotations`] computes together.
pub const POLAR_LANES: usize = 4;

/// [`POLAR_LANES`] scalars with the operations of the lanes' Newton iteration, each lane
/// rounding exactly as the scalar operation does (no fused multiply-adds): [`Lanes`]
/// anywhere, [`Avx`] registers where the processor has AVX2. One iteration,
/// [`newton_rotations`], serves both.
trait LaneVector: Copy {
    /// Per-lane flags.
    type Mask: Copy;
    fn splat(v: f64) -> Self;
    fn from_lanes(v: [f64; POLAR_LANES]) -> Self;
    fn to_lanes(self) -> [f64; POLAR_LANES];
    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn div(self, o: Self) -> Self;
    fn sqrt(self) -> Self;
    /// Lanes that are neither infinite nor NaN.
    fn finite(self) -> Self::Mask;
    fn less(self, o: Self) -> Self::Mask;
    fn greater(self, o: Self) -> Self::Mask;
    /// `if_true` in the lanes of `mask`, `self` elsewhere.
    fn blend(self, if_true: Self, mask: Self::Mask) -> Self;
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// `a` and not `b`.
    fn and_not(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    fn none() -> Self::Mask;
    /// Bit `l` set for lane `l` of `mask`.
    fn bits(mask: Self::Mask) -> u32;
}

/// The portable [`LaneVector`]: an array the compiler may pack as it can.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Lanes([f64; POLAR_LANES]);

impl Lanes {
    #[inline(always)]
    fn zip(self, o: Lanes, f: impl Fn(f64, f64) -> f64) -> Lanes {
        Lanes(std::array::from_fn(|l| f(self.0[l], o.0[l])))
    }

    #[inline(always)]
    fn test(self, o: Lanes, f: impl Fn(f64, f64) -> bool) -> [bool; POLAR_LANES] {
        std::array::from_fn(|l| f(self.0[l], o.0[l]))
    }
}

impl LaneVector for Lanes {
    type Mask = [bool; POLAR_LANES];
    #[inline(always)]
    fn splat(v: f64) -> Self {
        Lanes([v; POLAR_LANES])
    }
    #[inline(always)]
    fn from_lanes(v: [f64; POLAR_LANES]) -> Self {
        Lanes(v)
    }
    #[inline(always)]
    fn to_lanes(self) -> [f64; POLAR_LANES] {
        self.0
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self.zip(o, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self.zip(o, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.zip(o, |a, b| a * b)
    }
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        self.zip(o, |a, b| a / b)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Lanes(self.0.map(f64::sqrt))
    }
    #[inline(always)]
    fn finite(self) -> Self::Mask {
        self.0.map(f64::is_finite)
    }
    #[inline(always)]
    fn less(self, o: Self) -> Self::Mask {
        self.test(o, |a, b| a < b)
    }
    #[inline(always)]
    fn greater(self, o: Self) -> Self::Mask {
        self.test(o, |a, b| a > b)
    }
    #[inline(always)]
    fn blend(self, if_true: Self, mask: Self::Mask) -> Self {
        Lanes(std::array::from_fn(|l| {
            if mask[l] { if_true.0[l] } else { self.0[l] }
        }))
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        std::array::from_fn(|l| a[l] && b[l])
    }
    #[inline(always)]
    fn and_not(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        std::array::from_fn(|l| a[l] && !b[l])
    }
    #[inline(always)]
    fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        std::array::from_fn(|l| a[l] || b[l])
    }
    #[inline(always)]
    fn none() -> Self::Mask {
        [false; POLAR_LANES]
    }
    #[inline(always)]
    fn bits(mask: Self::Mask) -> u32 {
        (0..POLAR_LANES).fold(0, |b, l| b | (u32::from(mask[l]) << l))
    }
}

/// The AVX [`LaneVector`], written with intrinsics: the compiler packed [`Lanes`] only
/// in part (scalar divisions, square roots and lane selects in every Newton step;
/// criterion `assemble_warped_60984` on one thread 15.8-19.1 ms with [`Lanes`], 12.6-14.6
/// ms with this, alternating runs on a busy host). Its methods must be inlined into a
/// function compiled for AVX2 ([`polar_rotations_avx2`], the only place that makes them),
/// hence `#[inline(always)]` on them and on every helper they pass through.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Avx(std::arch::x86_64::__m256d);

#[cfg(target_arch = "x86_64")]
impl LaneVector for Avx {
    type Mask = std::arch::x86_64::__m256d;
    // SAFETY (every method): an `Avx` exists only inside `polar_rotations_avx2`, which
    // runs only where the processor has AVX2 (checked by `polar_rotations`).
    #[inline(always)]
    fn splat(v: f64) -> Self {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        Avx(unsafe { std::arch::x86_64::_mm256_set1_pd(v) })
    }
    #[inline(always)]
    fn from_lanes(v: [f64; POLAR_LANES]) -> Self {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        Avx(unsafe { std::arch::x86_64::_mm256_loadu_pd(v.as_ptr()) })
    }
    #[inline(always)]
    fn to_lanes(self) -> [f64; POLAR_LANES] {
        let mut v = [0.0; POLAR_LANES];
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        unsafe { std::arch::x86_64::_mm256_storeu_pd(v.as_mut_ptr(), self.0) };
        v
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        Avx(unsafe { std::arch::x86_64::_mm256_add_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        Avx(unsafe { std::arch::x86_64::_mm256_sub_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        Avx(unsafe { std::arch::x86_64::_mm256_mul_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        Avx(unsafe { std::arch::x86_64::_mm256_div_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        Avx(unsafe { std::arch::x86_64::_mm256_sqrt_pd(self.0) })
    }
    #[inline(always)]
    fn finite(self) -> Self::Mask {
        use std::arch::x86_64::*;
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        unsafe {
            let magnitude = _mm256_andnot_pd(_mm256_set1_pd(-0.0), self.0);
            _mm256_cmp_pd::<_CMP_LT_OQ>(magnitude, _mm256_set1_pd(f64::INFINITY))
        }
    }
    #[inline(always)]
    fn less(self, o: Self) -> Self::Mask {
        use std::arch::x86_64::*;
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        unsafe { _mm256_cmp_pd::<_CMP_LT_OQ>(self.0, o.0) }
    }
    #[inline(always)]
    fn greater(self, o: Self) -> Self::Mask {
        use std::arch::x86_64::*;
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        unsafe { _mm256_cmp_pd::<_CMP_GT_OQ>(self.0, o.0) }
    }
    #[inline(always)]
    fn blend(self, if_true: Self, mask: Self::Mask) -> Self {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        Avx(unsafe { std::arch::x86_64::_mm256_blendv_pd(self.0, if_true.0, mask) })
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        unsafe { std::arch::x86_64::_mm256_and_pd(a, b) }
    }
    #[inline(always)]
    fn and_not(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        unsafe { std::arch::x86_64::_mm256_andnot_pd(b, a) }
    }
    #[inline(always)]
    fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        unsafe { std::arch::x86_64::_mm256_or_pd(a, b) }
    }
    #[inline(always)]
    fn none() -> Self::Mask {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        unsafe { std::arch::x86_64::_mm256_setzero_pd() }
    }
    #[inline(always)]
    fn bits(mask: Self::Mask) -> u32 {
        // SAFETY: AVX2 is present wherever an `Avx` exists (see above).
        unsafe { std::arch::x86_64::_mm256_movemask_pd(mask) as u32 }
    }
}

/// [`POLAR_LANES`] 3x3 matrices, entry by entry: entry `3 c + r` (column `c`, row `r`)
/// of lane `l` is lane `l` of `m[3 c + r]`.
type Mat3Lanes<V> = [V; 9];

// The helpers below are functions marked `#[inline(always)]`, not closures: a closure is
// compiled on its own without AVX, and the intrinsics in it then stay calls.

/// `‖column c‖²` per lane, as `length_squared` sums it.
#[inline(always)]
fn column_norm2<V: LaneVector>(x: &Mat3Lanes<V>, c: usize) -> V {
    let (a, b, d) = (x[3 * c], x[3 * c + 1], x[3 * c + 2]);
    a.mul(a).add(b.mul(b)).add(d.mul(d))
}

/// `‖X‖²_F` per lane, summed as [`frobenius2`] does.
#[inline(always)]
fn frobenius2_lanes<V: LaneVector>(x: &Mat3Lanes<V>) -> V {
    column_norm2(x, 0)
        .add(column_norm2(x, 1))
        .add(column_norm2(x, 2))
}

/// Column `a` cross column `b` per lane (entry indices of their first rows), as glam's
/// `cross` computes it.
#[inline(always)]
fn cross_lanes<V: LaneVector>(x: &Mat3Lanes<V>, a: usize, b: usize) -> [V; 3] {
    [
        x[a + 1].mul(x[b + 2]).sub(x[b + 1].mul(x[a + 2])),
        x[a + 2].mul(x[b]).sub(x[b + 2].mul(x[a])),
        x[a].mul(x[b + 1]).sub(x[b].mul(x[a + 1])),
    ]
}

/// The cofactor matrix and determinant per lane, as [`cofactor`] computes them.
#[inline(always)]
fn cofactor_lanes<V: LaneVector>(x: &Mat3Lanes<V>) -> (Mat3Lanes<V>, V) {
    // columns: x = (e0, e1, e2), y = (e3, e4, e5), z = (e6, e7, e8)
    let (c0, c1, c2) = (
        cross_lanes(x, 3, 6),
        cross_lanes(x, 6, 0),
        cross_lanes(x, 0, 3),
    );
    let det = x[0].mul(c0[0]).add(x[1].mul(c0[1])).add(x[2].mul(c0[2]));
    (
        [
            c0[0], c0[1], c0[2], c1[0], c1[1], c1[2], c2[0], c2[1], c2[2],
        ],
        det,
    )
}

/// [`polar_rotation`] of each matrix of `f`, the Newton path run on all of them at once
/// (see the module documentation); bit for bit the same results.
pub fn polar_rotations(f: &[DMat3; POLAR_LANES]) -> [DMat3; POLAR_LANES] {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor supports AVX2 (checked just above).
        return unsafe { polar_rotations_avx2(f) };
    }
    newton_rotations::<Lanes>(f)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn polar_rotations_avx2(f: &[DMat3; POLAR_LANES]) -> [DMat3; POLAR_LANES] {
    newton_rotations::<Avx>(f)
}

/// The lanes' Newton iteration of [`newton_polar`], the same operations in the same
/// order; lanes it cannot take go to [`polar_rotation`]'s SVD path.
#[inline(always)]
fn newton_rotations<V: LaneVector>(f: &[DMat3; POLAR_LANES]) -> [DMat3; POLAR_LANES] {
    let entries = f.map(|m| m.to_cols_array());
    let fl: Mat3Lanes<V> =
        std::array::from_fn(|k| V::from_lanes(std::array::from_fn(|l| entries[l][k])));
    let n2 = frobenius2_lanes(&fl);
    let (c, det) = cofactor_lanes(&fl);
    // det / (‖F‖/√3)³ = det · 3√3 / ‖F‖³, as in `newton_polar`
    let threshold = V::splat(NEWTON_MIN_CONDITION)
        .mul(n2)
        .mul(n2.sqrt())
        .div(V::splat(5.196_152_422_706_632));
    let newton = V::and(det.finite(), det.greater(threshold));
    let inv_det = V::splat(1.0).div(det);
    let inv_t: Mat3Lanes<V> = c.map(|c| c.mul(inv_det));
    let gamma = frobenius2_lanes(&inv_t).div(n2).sqrt().sqrt();
    let inv_gamma = V::splat(1.0).div(gamma);
    let half = V::splat(0.5);
    let mut x: Mat3Lanes<V> =
        std::array::from_fn(|k| fl[k].mul(gamma).add(inv_t[k].mul(inv_gamma)).mul(half));
    let mut running = newton;
    let mut converged = V::none();
    let tolerance = V::splat(1e-14);
    for _ in 0..NEWTON_MAX_ITERATIONS {
        let (c, det) = cofactor_lanes(&x);
        let inv_det = V::splat(1.0).div(det);
        let next: Mat3Lanes<V> = std::array::from_fn(|k| x[k].add(c[k].mul(inv_det)).mul(half));
        let diff: Mat3Lanes<V> = std::array::from_fn(|k| next[k].sub(x[k]));
        let delta2 = frobenius2_lanes(&diff);
        // lanes already done keep their matrix
        for k in 0..9 {
            x[k] = x[k].blend(next[k], running);
        }
        // the error of `next` is about delta² / 2
        let small = V::and(running, delta2.less(tolerance));
        converged = V::or(converged, small);
        // a lane stops once converged or once its step is no longer finite
        running = V::and_not(V::and(running, delta2.finite()), small);
        if V::bits(running) == 0 {
            break;
        }
    }
    let converged = V::bits(converged);
    let lanes = x.map(V::to_lanes);
    std::array::from_fn(|l| {
        if converged & (1 << l) != 0 {
            DMat3::from_cols_array(&std::array::from_fn(|k| lanes[k][l]))
        } else {
            rotation_variant_svd(f[l]).0
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_give_the_same_bits_as_one_at_a_time() {
        let mut rng = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let q = DMat3::from_axis_angle(DVec3::new(0.3, -2.0, 1.0).normalize(), 2.7);
        for k in 0..400 {
            let f: [DMat3; POLAR_LANES] = std::array::from_fn(|l| match (k + l) % 7 {
                // inverted, flat and non-finite lanes mixed with regular ones
                0 => q * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -0.3)),
                1 => q * DMat3::from_diagonal(DVec3::new(2.0, 1.0, 0.0)),
                2 if k % 3 == 0 => DMat3::from_diagonal(DVec3::splat(f64::NAN)),
                _ => {
                    let g = DMat3::from_cols_array(&std::array::from_fn(|_| 0.6 * next()));
                    q * (DMat3::IDENTITY + g)
                }
            });
            let batch = polar_rotations(&f);
            let lanes = newton_rotations::<Lanes>(&f);
            for l in 0..POLAR_LANES {
                let one = polar_rotation(f[l]).to_cols_array().map(f64::to_bits);
                assert_eq!(
                    batch[l].to_cols_array().map(f64::to_bits),
                    one,
                    "{:?}",
                    f[l]
                );
                assert_eq!(
                    lanes[l].to_cols_array().map(f64::to_bits),
                    one,
                    "{:?}",
                    f[l]
                );
            }
        }
    }

    fn is_rotation(r: DMat3) -> bool {
        let e = r.transpose() * r - DMat3::IDENTITY;
        e.to_cols_array().iter().all(|x| x.abs() < 1e-13) && (r.determinant() - 1.0).abs() < 1e-13
    }

    #[test]
    fn polar_of_rotation_times_stretch() {
        let q = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 1.3);
        let s = DMat3::from_cols(
            DVec3::new(1.5, 0.1, 0.0),
            DVec3::new(0.1, 0.8, 0.05),
            DVec3::new(0.0, 0.05, 1.1),
        );
        let r = polar_rotation(q * s);
        assert!((r - q).to_cols_array().iter().all(|x| x.abs() < 1e-13));
    }

    #[test]
    fn newton_path_matches_the_svd() {
        let q = DMat3::from_axis_angle(DVec3::new(0.3, -2.0, 1.0).normalize(), 2.7);
        for s in [
            DMat3::IDENTITY,
            DMat3::from_diagonal(DVec3::new(1.0, 1.0, 1.0 + 1e-9)),
            DMat3::from_cols(
                DVec3::new(1.2, 0.3, -0.1),
                DVec3::new(0.3, 0.7, 0.2),
                DVec3::new(-0.1, 0.2, 1.05),
            ),
            DMat3::from_diagonal(DVec3::new(4.0, 0.5, 0.05)),
        ] {
            let f = q * s;
            let fast = newton_polar(f).expect("well-conditioned F takes the Newton path");
            let svd = rotation_variant_svd(f).0;
            assert!(is_rotation(fast));
            assert!(
                (fast - svd).to_cols_array().iter().all(|x| x.abs() < 1e-13),
                "{fast:?} vs {svd:?}"
            );
        }
        // nearly flat and inverted elements take the SVD path
        assert!(newton_polar(q * DMat3::from_diagonal(DVec3::new(1.0, 1.0, 1e-4))).is_none());
        assert!(newton_polar(q * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -0.3))).is_none());
    }

    #[test]
    fn rotation_of_inverted_and_degenerate() {
        let q = DMat3::from_axis_angle(DVec3::new(-1.0, 0.5, 0.2).normalize(), 2.0);
        for f in [
            q * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -0.3)),
            q * DMat3::from_diagonal(DVec3::new(2.0, 1.0, 0.0)),
            q * DMat3::from_diagonal(DVec3::new(2.0, 0.0, 0.0)),
            DMat3::ZERO,
            DMat3::IDENTITY,
            DMat3::from_diagonal(DVec3::new(-1.0, -1.0, -1.0)),
        ] {
            let r = polar_rotation(f);
            assert!(is_rotation(r), "{f:?} -> {r:?}");
        }
        // an inverted element keeps its rotation: the flip goes on the smallest axis
        let r = polar_rotation(q * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -0.3)));
        assert!((r - q).to_cols_array().iter().all(|x| x.abs() < 1e-12));
    }
}
