//! The thick-walled sphere under internal pressure (Lamé's problem): convergence of the
//! finite-element solution to the analytic one as the mesh is refined.
//!
//! A hollow sphere, inner radius a = 20 mm, outer radius b = 40 mm, linear isotropic
//! material (E = 3 kPa, ν = 0.45 and 0.3), pressure p on the inner surface, outer surface
//! free. The radial displacement is `u(r) = A r + B / r²` with
//!
//! ```text
//! σ_rr(r) = 3K A - 4μ B / r³,   σ_θθ(r) = 3K A + 2μ B / r³      (K = λ + 2μ/3)
//! σ_rr(a) = -p, σ_rr(b) = 0  =>  A = p a³ / (3K (b³ - a³)),  B = p a³ b³ / (4μ (b³ - a³))
//! ```
//!
//! The fem crate constrains whole vertices only, so a pressure load would leave the rigid
//! motions free. The test therefore solves the same problem in displacement form: the
//! inner surface vertices get the analytic displacement `u(x) = (A + B / |x|³) x` (the
//! displacement that pressure p produces), the outer surface is traction free: the
//! natural boundary condition, which the weak form must reproduce by itself.
//!
//! The meshes come from isosurface stuffing (tetra) of an outer icosphere and an inward
//! oriented inner icosphere, at lattice spacings 10, 7, 5 and 3.5 mm (3,168 to 68,544
//! tetrahedra; finer levels cost too much time in the direct solver for a test). Errors
//! against the analytic solution: displacement L2 (relative), energy norm (relative),
//! and the radial and hoop stresses of the elements at 400 points of the mid-wall
//! sphere (RMS, relative to p). Measured with linear elasticity, ν = 0.3: L2 4.4e-2 to
//! 5.6e-3 (order 1.97), energy 0.37 to 0.13 (order 0.99); ν = 0.45: L2 1.1e-1 to 1.9e-2
//! (order 1.71), energy 0.55 to 0.21 (order 0.93); stresses first order. The corotated
//! solution differs from the linear one by at most 5.3e-5 of u(a). Run with
//! `cargo test --release -p fem --test lame -- --nocapture` for the table per level.

use fem::{
    Constraints, FemModel, Formulation, Material, SolveOptions, StaticSolution, StaticSolver,
};
use glam::{DMat3, DVec3};
use mesh::TriMesh;
use std::fmt::Write as _;
use tetra::{ClosedSurface, TetLocator, TetMesh, stuff};

/// Inner radius (mm).
const A_MM: f64 = 20.0;
/// Outer radius (mm).
const B_MM: f64 = 40.0;
/// Young's modulus (kPa): glandular breast tissue.
const YOUNG_KPA: f64 = 3.0;
/// Internal pressure (kPa): small, so the inner radius grows by about 1e-3 (0.02 mm) and
/// small-strain theory holds; the corotated solution then agrees with the linear one.
const PRESSURE_KPA: f64 = 3.5e-3;
/// Lattice spacings (mm), each about 1/√2 of the previous one.
const SPACINGS_MM: [f64; 4] = [10.0, 7.0, 5.0, 3.5];
/// Icosphere subdivisions: 20,480 triangles per sphere, chords within 0.01 mm of the
/// spheres, far below the discretisation errors measured here.
const SUBDIVISIONS: u32 = 5;
/// Points on the mid-wall sphere where the stresses are sampled.
const STRESS_SAMPLES: usize = 400;

/// Observed orders are least-squares slopes of log(error) against log(spacing) over all
/// levels: stuffed meshes of different spacings are not nested refinements, their
/// boundary layers differ, so the order between two neighbouring levels scatters by
/// about ±0.3 (measured 1.5 to 2.0 for the displacement); the fit over a factor of 2.9
/// in spacing is steadier.
///
/// Displacement L2 error: theory says 2 for linear tetrahedra. Measured 1.97 at ν = 0.3,
/// asserted at least 1.8.
const MIN_L2_ORDER_NU_03: f64 = 1.8;
/// At ν = 0.45 (λ/μ = 9) linear tetrahedra lock partly and the coarse levels (two to
/// four elements across the wall) are not yet asymptotic: the order between neighbouring
/// levels rises with refinement. Measured 1.71, asserted at least 1.5.
const MIN_L2_ORDER_NU_045: f64 = 1.5;
/// Energy-norm error: theory says 1. Measured 0.91 to 0.98, asserted at least 0.85.
const MIN_ENERGY_ORDER: f64 = 0.85;
/// RMS error of the element stresses sampled at mid-wall (piecewise constant stresses:
/// first order). Measured 0.94 to 1.12, asserted at least 0.75.
const MIN_STRESS_ORDER: f64 = 0.75;
/// Corotated against linear at the same mesh, largest nodal difference relative to the
/// inner radial displacement: the two differ by geometrically nonlinear terms of the
/// order of the strain (1e-3) at most. Measured at most 5.3e-5, asserted below 5e-4.
const COROTATED_TOLERANCE: f64 = 5e-4;
/// The corotated solution's L2 error may differ from the linear one's by this fraction.
const COROTATED_L2_SPREAD: f64 = 0.05;

/// The analytic solution.
struct Lame {
    lambda: f64,
    mu: f64,
    /// `A` (dimensionless) and `B` (mm³) of `u(r) = A r + B / r²`.
    a_coef: f64,
    b_coef: f64,
}

impl Lame {
    fn new(material: &Material, a: f64, b: f64, p: f64) -> Lame {
        let (lambda, mu) = material.lame();
        let bulk = lambda + 2.0 * mu / 3.0;
        let shell = b.powi(3) - a.powi(3);
        Lame {
            lambda,
            mu,
            a_coef: p * a.powi(3) / (3.0 * bulk * shell),
            b_coef: p * a.powi(3) * b.powi(3) / (4.0 * mu * shell),
        }
    }

    /// Radial displacement at radius `r` (mm).
    fn radial(&self, r: f64) -> f64 {
        self.a_coef * r + self.b_coef / (r * r)
    }

    /// Displacement at `x` (mm).
    fn displacement(&self, x: DVec3) -> DVec3 {
        x * (self.a_coef + self.b_coef / x.length().powi(3))
    }

    /// Strain at `x`: `∇u = f I - 3 B x xᵀ / r⁵` with `f = A + B / r³` (symmetric).
    fn strain(&self, x: DVec3) -> DMat3 {
        let r = x.length();
        let f = self.a_coef + self.b_coef / r.powi(3);
        DMat3::from_diagonal(DVec3::splat(f)) - outer(x, x) * (3.0 * self.b_coef / r.powi(5))
    }

    /// Stress (kPa) of a strain.
    fn stress_of(&self, eps: DMat3) -> DMat3 {
        DMat3::from_diagonal(DVec3::splat(self.lambda * trace(eps))) + eps * (2.0 * self.mu)
    }

    /// `ε : C : ε` (twice the energy density, kPa).
    fn energy_density2(&self, eps: DMat3) -> f64 {
        self.lambda * trace(eps).powi(2) + 2.0 * self.mu * double_dot(eps, eps)
    }

    /// Radial stress at radius `r` (kPa).
    fn sigma_rr(&self, r: f64) -> f64 {
        3.0 * (self.lambda + 2.0 * self.mu / 3.0) * self.a_coef
            - 4.0 * self.mu * self.b_coef / r.powi(3)
    }

    /// Hoop stress at radius `r` (kPa).
    fn sigma_tt(&self, r: f64) -> f64 {
        3.0 * (self.lambda + 2.0 * self.mu / 3.0) * self.a_coef
            + 2.0 * self.mu * self.b_coef / r.powi(3)
    }
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

fn trace(m: DMat3) -> f64 {
    m.x_axis.x + m.y_axis.y + m.z_axis.z
}

fn double_dot(a: DMat3, b: DMat3) -> f64 {
    a.x_axis.dot(b.x_axis) + a.y_axis.dot(b.y_axis) + a.z_axis.dot(b.z_axis)
}

/// The hollow sphere's surface: the outer sphere and the inner one turned inside out.
fn hollow_sphere() -> TriMesh {
    let outer_sphere = mesh::shapes::icosphere(B_MM, SUBDIVISIONS);
    let inner_sphere = mesh::shapes::icosphere(A_MM, SUBDIVISIONS);
    let offset = outer_sphere.positions.len() as u32;
    let mut positions = outer_sphere.positions;
    positions.extend(&inner_sphere.positions);
    let mut triangles = outer_sphere.triangles;
    triangles.extend(
        inner_sphere
            .triangles
            .iter()
            .map(|&[a, b, c]| [a + offset, c + offset, b + offset]),
    );
    TriMesh::new(positions, triangles)
}

/// Vertices on the inner surface: boundary vertices nearer the inner than the outer
/// sphere.
fn inner_surface_vertices(mesh: &TetMesh) -> Vec<u32> {
    let mid = 0.5 * (A_MM + B_MM);
    mesh.boundary()
        .tet_vertex
        .into_iter()
        .filter(|&v| mesh.positions[v as usize].length() < mid)
        .collect()
}

/// Degree-2 quadrature on a tetrahedron (4 points, equal weights 1/4): barycentric
/// coordinates `(α, β, β, β)` and permutations.
fn quadrature_points(p: [DVec3; 4]) -> [DVec3; 4] {
    const ALPHA: f64 = 0.585_410_196_624_968_5;
    const BETA: f64 = 0.138_196_601_125_010_5;
    std::array::from_fn(|k| {
        (0..4)
            .map(|j| p[j] * if j == k { ALPHA } else { BETA })
            .sum()
    })
}

/// Errors of one solution against the analytic one.
#[derive(Debug, Clone, Copy)]
struct Errors {
    /// `‖u_h - u‖_L2 / ‖u‖_L2` over the mesh.
    l2: f64,
    /// `‖u_h - u‖_E / ‖u‖_E` (energy norm).
    energy: f64,
    /// Largest nodal error relative to the largest displacement.
    nodal_max: f64,
    /// RMS over the mid-wall samples of the element's radial and hoop stress errors,
    /// relative to p.
    sigma_rr_rms: f64,
    sigma_tt_rms: f64,
}

/// Points spread evenly over the sphere of radius `r` (a Fibonacci spiral).
fn sphere_samples(r: f64, n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|k| {
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / n as f64;
            let s = (1.0 - z * z).sqrt();
            let phi = golden * k as f64;
            DVec3::new(s * phi.cos(), s * phi.sin(), z) * r
        })
        .collect()
}

fn errors(
    exact: &Lame,
    mesh: &TetMesh,
    model: &FemModel,
    u: &[DVec3],
    formulation: Formulation,
) -> Errors {
    let (mut l2_err, mut l2_ref, mut en_err, mut en_ref) = (0.0, 0.0, 0.0, 0.0);
    for (e, tet) in mesh.tets.iter().enumerate() {
        let p = mesh.tet_positions(e);
        let rest = &model.elements()[e];
        let grad_u: DMat3 = (0..4)
            .map(|k| outer(u[tet[k] as usize], rest.grad[k]))
            .sum();
        let eps_h = (grad_u + grad_u.transpose()) * 0.5;
        let w = rest.volume_mm3 / 4.0;
        for x in quadrature_points(p) {
            let bary = tetra::locate::barycentric(p, x);
            let u_h: DVec3 = (0..4).map(|k| u[tet[k] as usize] * bary[k]).sum();
            let u_x = exact.displacement(x);
            l2_err += w * (u_h - u_x).length_squared();
            l2_ref += w * u_x.length_squared();
            let eps = exact.strain(x);
            en_err += w * exact.energy_density2(eps_h - eps);
            en_ref += w * exact.energy_density2(eps);
        }
    }
    let nodal_max = mesh
        .positions
        .iter()
        .zip(u)
        .map(|(&x, &d)| (d - exact.displacement(x)).length())
        .fold(0.0, f64::max)
        / exact.radial(A_MM);

    let r_mid = 0.5 * (A_MM + B_MM);
    let locator = TetLocator::new(mesh);
    let (mut rr2, mut tt2) = (0.0, 0.0);
    let samples = sphere_samples(r_mid, STRESS_SAMPLES);
    for &x in &samples {
        let location = locator
            .locate(x)
            .expect("mid-wall points lie inside the mesh");
        let (sigma, rotation) = model.element_stress(location.tet, u, formulation);
        let sigma = rotation * sigma * rotation.transpose();
        // radial, and hoop as the mean of the two tangential normal stresses
        let n = x / x.length();
        let rr = n.dot(sigma * n);
        let tt = 0.5 * (trace(sigma) - rr);
        rr2 += (rr - exact.sigma_rr(r_mid)).powi(2);
        tt2 += (tt - exact.sigma_tt(r_mid)).powi(2);
    }
    let n = samples.len() as f64;
    Errors {
        l2: (l2_err / l2_ref).sqrt(),
        energy: (en_err / en_ref).sqrt(),
        nodal_max,
        sigma_rr_rms: (rr2 / n).sqrt() / PRESSURE_KPA,
        sigma_tt_rms: (tt2 / n).sqrt() / PRESSURE_KPA,
    }
}

/// Solves the displacement-form Lamé problem on `mesh`.
fn solve(
    exact: &Lame,
    mesh: &TetMesh,
    model: &FemModel,
    formulation: Formulation,
) -> StaticSolution {
    let mut constraints = Constraints::new();
    for v in inner_surface_vertices(mesh) {
        constraints.prescribe(v, exact.displacement(mesh.positions[v as usize]));
    }
    let options = SolveOptions {
        formulation,
        ..SolveOptions::default()
    };
    let solution = StaticSolver::new(model, &constraints)
        .unwrap()
        .solve(model, &[], None, &options)
        .unwrap();
    assert!(solution.converged, "{formulation:?}: {solution:?}");
    solution
}

/// One error measure of a level.
type Metric = fn(&Errors) -> f64;

/// Least-squares slope of `log e` against `log h` over the `(h, e)` points.
fn fitted_order(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let logs: Vec<(f64, f64)> = points.iter().map(|(h, e)| (h.ln(), e.ln())).collect();
    let (mx, my) = logs
        .iter()
        .fold((0.0, 0.0), |(sx, sy), (x, y)| (sx + x / n, sy + y / n));
    let sxy: f64 = logs.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = logs.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    sxy / sxx
}

/// `log(e₀ / e₁) / log(h₀ / h₁)`.
fn order(e0: f64, e1: f64, h0: f64, h1: f64) -> f64 {
    (e0 / e1).ln() / (h0 / h1).ln()
}

fn lame_convergence(poisson_ratio: f64) {
    // Printed whole at the end, so the tables of tests running in parallel do not mix.
    let mut report = String::new();
    let material = Material::new(YOUNG_KPA, poisson_ratio);
    let exact = Lame::new(&material, A_MM, B_MM, PRESSURE_KPA);
    let surface = ClosedSurface::new(&hollow_sphere()).unwrap();
    let _ = writeln!(
        report,
        "Lamé sphere a = {A_MM} mm, b = {B_MM} mm, E = {YOUNG_KPA} kPa, nu = {poisson_ratio}, p = {PRESSURE_KPA} kPa: u(a) = {:.5} mm, u(b) = {:.5} mm, sigma_rr(30) = {:.4e} kPa, sigma_tt(30) = {:.4e} kPa",
        exact.radial(A_MM),
        exact.radial(B_MM),
        exact.sigma_rr(30.0),
        exact.sigma_tt(30.0),
    );
    let _ = writeln!(
        report,
        "  h mm |   tets | vertices |  L2 rel  | energy rel | nodal max | s_rr rms/p | s_tt rms/p | corot-lin"
    );
    let mut levels = Vec::new();
    let mut failures = Vec::new();
    for &h in &SPACINGS_MM {
        let mesh = stuff(&surface, h).unwrap();
        let model = FemModel::homogeneous(&mesh, material).unwrap();
        let linear = solve(&exact, &mesh, &model, Formulation::Linear);
        let e = errors(
            &exact,
            &mesh,
            &model,
            &linear.displacement,
            Formulation::Linear,
        );
        // The corotated solve on the coarser levels (it needs a few factorisations).
        let corotated_gap = (h > SPACINGS_MM[3]).then(|| {
            let corotated = solve(&exact, &mesh, &model, Formulation::Corotated);
            let ec = errors(
                &exact,
                &mesh,
                &model,
                &corotated.displacement,
                Formulation::Corotated,
            );
            if (ec.l2 - e.l2).abs() > COROTATED_L2_SPREAD * e.l2 {
                failures.push(format!(
                    "h = {h}: corotated L2 error {:e} against linear {:e}",
                    ec.l2, e.l2
                ));
            }
            let gap = linear
                .displacement
                .iter()
                .zip(&corotated.displacement)
                .map(|(a, b)| (*a - *b).length())
                .fold(0.0, f64::max)
                / exact.radial(A_MM);
            if gap > COROTATED_TOLERANCE {
                failures.push(format!("h = {h}: corotated - linear {gap:e}"));
            }
            gap
        });
        let _ = writeln!(
            report,
            "  {h:4.1} | {:6} | {:8} | {:.3e} | {:.3e}  | {:.3e} | {:.3e}  | {:.3e}  | {}",
            mesh.tet_count(),
            mesh.vertex_count(),
            e.l2,
            e.energy,
            e.nodal_max,
            e.sigma_rr_rms,
            e.sigma_tt_rms,
            corotated_gap.map_or("-".to_string(), |g| format!("{g:.2e}")),
        );
        levels.push((h, e));
    }
    let min_l2_order = if poisson_ratio > 0.4 {
        MIN_L2_ORDER_NU_045
    } else {
        MIN_L2_ORDER_NU_03
    };
    let metrics: [(&str, Metric, f64); 4] = [
        ("displacement L2", |e| e.l2, min_l2_order),
        ("energy", |e| e.energy, MIN_ENERGY_ORDER),
        ("radial stress", |e| e.sigma_rr_rms, MIN_STRESS_ORDER),
        ("hoop stress", |e| e.sigma_tt_rms, MIN_STRESS_ORDER),
    ];
    for (what, metric, min) in metrics {
        let points: Vec<(f64, f64)> = levels.iter().map(|(h, e)| (*h, metric(e))).collect();
        let pairs: Vec<String> = points
            .windows(2)
            .map(|p| format!("{:.2}", order(p[0].1, p[1].1, p[0].0, p[1].0)))
            .collect();
        let observed = fitted_order(&points);
        let _ = writeln!(
            report,
            "  nu = {poisson_ratio}: {what} error: fitted order {observed:.2} (neighbouring levels {})",
            pairs.join(", ")
        );
        if observed < min {
            failures.push(format!("{what} error order {observed:.2} < {min}"));
        }
    }
    println!("{report}");
    assert!(failures.is_empty(), "nu = {poisson_ratio}: {failures:?}");
    for pair in levels.windows(2) {
        assert!(
            pair[1].1.l2 < pair[0].1.l2 && pair[1].1.energy < pair[0].1.energy,
            "errors must fall at every refinement: {levels:?}"
        );
    }
}

#[test]
fn lame_sphere_converges_nu_045() {
    lame_convergence(0.45);
}

#[test]
fn lame_sphere_converges_nu_03() {
    lame_convergence(0.3);
}

/// The derivation above, checked on its own: the strain is the symmetric gradient of the
/// displacement, the stress is in equilibrium, the inner surface carries the pressure
/// and the outer one no traction.
#[test]
fn lame_solution_satisfies_its_equations() {
    for nu in [0.3, 0.45] {
        let exact = Lame::new(&Material::new(YOUNG_KPA, nu), A_MM, B_MM, PRESSURE_KPA);
        let p = PRESSURE_KPA;
        assert!((exact.sigma_rr(A_MM) + p).abs() < 1e-12 * p);
        assert!(exact.sigma_rr(B_MM).abs() < 1e-12 * p);
        let x = DVec3::new(13.0, -17.0, 21.0);
        let d = 1e-3;
        let axes = [DVec3::X, DVec3::Y, DVec3::Z];
        // central differences: ∇u column j = ∂u/∂x_j
        let grad = DMat3::from_cols_array_2d(&axes.map(|ej| {
            ((exact.displacement(x + ej * d) - exact.displacement(x - ej * d)) / (2.0 * d))
                .to_array()
        }));
        let eps = exact.strain(x);
        let fd = (grad + grad.transpose()) * 0.5;
        let scale = eps.x_axis.abs().max_element();
        assert!(
            (0..3).all(|j| (fd.col(j) - eps.col(j)).abs().max_element() < 1e-6 * scale),
            "{fd:?} vs {eps:?}"
        );
        // div σ = Σ_j ∂σ_·j/∂x_j = 0
        let div: DVec3 = (0..3)
            .map(|j| {
                let s = |y: DVec3| exact.stress_of(exact.strain(y)).col(j);
                (s(x + axes[j] * d) - s(x - axes[j] * d)) / (2.0 * d)
            })
            .sum();
        assert!(div.length() < 1e-6 * p, "div sigma = {div:?}");
        // tractions σ n on both surfaces
        let n = x.normalize();
        let traction = |r: f64| exact.stress_of(exact.strain(n * r)) * n;
        assert!((traction(A_MM) + n * p).length() < 1e-12 * p);
        assert!(traction(B_MM).length() < 1e-12 * p);
    }
}
