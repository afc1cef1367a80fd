//! The two 3x3 block updates that dominate a cycle's assembly, written once for any
//! x86-64 ([`Scalar`]) and once in four-lane AVX2/FMA registers ([`Avx2Fma`]), chosen at
//! run time ([`simd_available`]): the element block of the warped stiffness (the finest
//! assembly's row gather) and the scaled block sum of the Galerkin products.
//!
//! Written by hand because no crate offers 3x3 block kernels and the compiler does not
//! vectorise the scalar forms for the baseline target (SSE2, no FMA); the binary must
//! still run on any x86-64, so the fast path is a second instantiation of the callers'
//! loops behind `#[target_feature]`, not a global target flag. Blocks are row-major
//! `[f64; 9]`; a block is loaded as lanes `(b₀ b₁ b₂ b₃)`, `(b₄ b₅ b₆ b₇)` and `b₈`.

#![allow(unsafe_code)] // vector kernels and raw disjoint writes, each block with its SAFETY reason
/// Whether the processor has AVX2 and FMA (detected once, then cached by the standard
/// library), i.e. whether the [`Avx2Fma`] kernels may run.
#[inline]
pub(crate) fn simd_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Block updates, instantiated by the callers' generic loops.
pub(crate) trait BlockKernels {
    /// `out += w b`.
    fn add_scaled(out: &mut [f64; 9], w: f64, b: &[f64; 9]);

    /// Adds an element's block `(a, b)`, `a ≠ b`, of `R K Rᵀ`:
    /// `V λ hₐ h_bᵀ + V μ h_b hₐᵀ + V μ (hₐ·h_b) I`, given `lambda_ha = V λ hₐ`,
    /// `mu_ha = V μ hₐ` and `hb` (rotated gradients, 1/mm).
    fn add_element_block(out: &mut [f64; 9], lambda_ha: [f64; 3], mu_ha: [f64; 3], hb: [f64; 3]);

    /// Adds an element's diagonal block `(a, a)`: `w hₐ hₐᵀ + V μ |hₐ|² I` with
    /// `w = V (λ + μ)`. Entry `(p, q)` is formed from the product `hₐ[p] hₐ[q]`, which
    /// rounds alike in both orders, so the block stays exactly symmetric.
    fn add_element_diagonal(out: &mut [f64; 9], w: f64, mu_ha: [f64; 3], ha: [f64; 3]);
}

/// The kernels in plain scalar arithmetic (any processor).
pub(crate) struct Scalar;

impl BlockKernels for Scalar {
    #[inline(always)]
    fn add_scaled(out: &mut [f64; 9], w: f64, b: &[f64; 9]) {
        // both blocks are read before `out` is written, so that the compiler may use
        // packed instructions (it cannot prove that `out` and `b` are distinct)
        let (b, mut o) = (*b, *out);
        for (o, x) in o.iter_mut().zip(b) {
            *o += w * x;
        }
        *out = o;
    }

    #[inline(always)]
    fn add_element_block(out: &mut [f64; 9], lambda_ha: [f64; 3], mu_ha: [f64; 3], hb: [f64; 3]) {
        for p in 0..3 {
            for q in 0..3 {
                out[3 * p + q] += lambda_ha[p] * hb[q] + hb[p] * mu_ha[q];
            }
        }
        add_to_diagonal(out, dot3(mu_ha, hb));
    }

    #[inline(always)]
    fn add_element_diagonal(out: &mut [f64; 9], w: f64, mu_ha: [f64; 3], ha: [f64; 3]) {
        for p in 0..3 {
            for q in 0..3 {
                out[3 * p + q] += w * (ha[p] * ha[q]);
            }
        }
        add_to_diagonal(out, dot3(mu_ha, ha));
    }
}

#[inline(always)]
fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn add_to_diagonal(out: &mut [f64; 9], d: f64) {
    out[0] += d;
    out[4] += d;
    out[8] += d;
}

/// The kernels in four-lane AVX2/FMA registers. Only for code compiled with
/// `#[target_feature(enable = "avx2,fma")]` and run where [`simd_available`] holds.
#[cfg(target_arch = "x86_64")]
pub(crate) struct Avx2Fma;

#[cfg(target_arch = "x86_64")]
impl BlockKernels for Avx2Fma {
    #[inline(always)]
    fn add_scaled(out: &mut [f64; 9], w: f64, b: &[f64; 9]) {
        // SAFETY: only instantiated in functions compiled for AVX2 and FMA and called
        // where the processor has them (the callers check `simd_available`)
        unsafe { lanes::add_scaled(out, w, b) }
    }

    #[inline(always)]
    fn add_element_block(out: &mut [f64; 9], lambda_ha: [f64; 3], mu_ha: [f64; 3], hb: [f64; 3]) {
        // SAFETY: as in `add_scaled`
        unsafe { lanes::add_element_block(out, lambda_ha, mu_ha, hb) }
    }

    #[inline(always)]
    fn add_element_diagonal(out: &mut [f64; 9], w: f64, mu_ha: [f64; 3], ha: [f64; 3]) {
        // SAFETY: as in `add_scaled`
        unsafe { lanes::add_element_diagonal(out, w, mu_ha, ha) }
    }
}

#[cfg(target_arch = "x86_64")]
mod lanes {
    use std::arch::x86_64::*;

    /// `(v₀ v₁ v₂ 0)`.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn vec3(v: [f64; 3]) -> __m256d {
        _mm256_setr_pd(v[0], v[1], v[2], 0.0)
    }

    /// The two four-lane parts of a block (entries 0-3 and 4-7).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn load(b: &[f64; 9]) -> (__m256d, __m256d) {
        // SAFETY: both loads lie inside the nine entries
        unsafe {
            (
                _mm256_loadu_pd(b.as_ptr()),
                _mm256_loadu_pd(b.as_ptr().add(4)),
            )
        }
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn store(out: &mut [f64; 9], low: __m256d, high: __m256d, last: f64) {
        // SAFETY: both stores lie inside the nine entries
        unsafe {
            _mm256_storeu_pd(out.as_mut_ptr(), low);
            _mm256_storeu_pd(out.as_mut_ptr().add(4), high);
        }
        out[8] = last;
    }

    /// `(d 0 0 0)`: adds `d` to entry 0 of the low part and entry 4 (lane 0 of the high part).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn first_lane(d: f64) -> __m256d {
        _mm256_setr_pd(d, 0.0, 0.0, 0.0)
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn add_scaled(out: &mut [f64; 9], w: f64, b: &[f64; 9]) {
        let wv = _mm256_set1_pd(w);
        // SAFETY: see `load` and `store`
        unsafe {
            let (b_low, b_high) = load(b);
            let (o_low, o_high) = load(out);
            let last = w.mul_add(b[8], out[8]);
            store(
                out,
                _mm256_fmadd_pd(wv, b_low, o_low),
                _mm256_fmadd_pd(wv, b_high, o_high),
                last,
            );
        }
    }

    /// Entries `(p, q)` of the low part are (00 01 02 10), of the high part
    /// (11 12 20 21): `u[p] v[q]` is `rows_low(u) * cols_low(v)`, and so on.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn rows_low(u: __m256d) -> __m256d {
        _mm256_permute4x64_pd::<0b01_00_00_00>(u)
    }
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn rows_high(u: __m256d) -> __m256d {
        _mm256_permute4x64_pd::<0b10_10_01_01>(u)
    }
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn cols_low(v: __m256d) -> __m256d {
        _mm256_permute4x64_pd::<0b00_10_01_00>(v)
    }
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn cols_high(v: __m256d) -> __m256d {
        _mm256_permute4x64_pd::<0b01_00_10_01>(v)
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn add_element_block(
        out: &mut [f64; 9],
        lambda_ha: [f64; 3],
        mu_ha: [f64; 3],
        hb: [f64; 3],
    ) {
        let (l, m, b) = (vec3(lambda_ha), vec3(mu_ha), vec3(hb));
        let d = super::dot3(mu_ha, hb);
        // SAFETY: see `load` and `store`
        unsafe {
            let (o_low, o_high) = load(out);
            let low = _mm256_fmadd_pd(
                rows_low(l),
                cols_low(b),
                _mm256_fmadd_pd(
                    rows_low(b),
                    cols_low(m),
                    _mm256_add_pd(o_low, first_lane(d)),
                ),
            );
            let high = _mm256_fmadd_pd(
                rows_high(l),
                cols_high(b),
                _mm256_fmadd_pd(
                    rows_high(b),
                    cols_high(m),
                    _mm256_add_pd(o_high, first_lane(d)),
                ),
            );
            let last = lambda_ha[2].mul_add(hb[2], hb[2].mul_add(mu_ha[2], out[8] + d));
            store(out, low, high, last);
        }
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn add_element_diagonal(
        out: &mut [f64; 9],
        w: f64,
        mu_ha: [f64; 3],
        ha: [f64; 3],
    ) {
        let a = vec3(ha);
        let wv = _mm256_set1_pd(w);
        let d = super::dot3(mu_ha, ha);
        // SAFETY: see `load` and `store`
        unsafe {
            let (o_low, o_high) = load(out);
            // ha[p] * ha[q] first: the same product for (p, q) and (q, p)
            let low = _mm256_fmadd_pd(
                wv,
                _mm256_mul_pd(rows_low(a), cols_low(a)),
                _mm256_add_pd(o_low, first_lane(d)),
            );
            let high = _mm256_fmadd_pd(
                wv,
                _mm256_mul_pd(rows_high(a), cols_high(a)),
                _mm256_add_pd(o_high, first_lane(d)),
            );
            let last = w.mul_add(ha[2] * ha[2], out[8] + d);
            store(out, low, high, last);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic values in about (-1, 1) (a linear congruential sequence).
    fn values(seed: u64, n: usize) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            })
            .collect()
    }

    fn block(v: &[f64]) -> [f64; 9] {
        std::array::from_fn(|k| v[k])
    }

    fn vec3(v: &[f64]) -> [f64; 3] {
        [v[0], v[1], v[2]]
    }

    /// The block updates by their definitions, entry by entry.
    fn reference(
        kind: usize,
        out: [f64; 9],
        w: f64,
        u: [f64; 3],
        m: [f64; 3],
        v: [f64; 3],
        b: &[f64; 9],
    ) -> [f64; 9] {
        let mut r = out;
        for p in 0..3 {
            for q in 0..3 {
                let delta = if p == q { 1.0 } else { 0.0 };
                r[3 * p + q] += match kind {
                    0 => w * b[3 * p + q],
                    1 => u[p] * v[q] + v[p] * m[q] + delta * dot3(m, v),
                    _ => w * v[p] * v[q] + delta * dot3(m, v),
                };
            }
        }
        r
    }

    /// Both kernel sets agree with the definitions to 4e-15 (a few roundings of sums of
    /// magnitude below 4, 2.2e-16 each, taken in other orders), and
    /// the diagonal element block is exactly symmetric.
    #[test]
    fn kernels_match_their_definitions() {
        fn check<K: BlockKernels>() {
            for seed in 0..200 {
                let v = values(seed, 40);
                let (out, b) = (block(&v[0..9]), block(&v[9..18]));
                let (u, m, h) = (vec3(&v[18..21]), vec3(&v[21..24]), vec3(&v[24..27]));
                let w = v[27];
                let mut got = [out, out, out];
                K::add_scaled(&mut got[0], w, &b);
                K::add_element_block(&mut got[1], u, m, h);
                K::add_element_diagonal(&mut got[2], w, m, h);
                for (kind, got) in got.iter().enumerate() {
                    let want = reference(kind, out, w, u, m, h, &b);
                    for k in 0..9 {
                        assert!(
                            (got[k] - want[k]).abs() <= 4e-15,
                            "kind {kind} entry {k}: {} vs {}",
                            got[k],
                            want[k]
                        );
                    }
                }
                let mut sym = [0.0; 9];
                K::add_element_diagonal(&mut sym, w, m, h);
                for (p, q) in [(0, 1), (0, 2), (1, 2)] {
                    assert_eq!(sym[3 * p + q], sym[3 * q + p]);
                }
            }
        }
        check::<Scalar>();
        #[cfg(target_arch = "x86_64")]
        if simd_available() {
            // SAFETY: the processor has AVX2 and FMA (checked just above)
            unsafe { check_avx2() };
        }
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        fn check_avx2() {
            check::<Avx2Fma>();
        }
    }
}
