//! Implant shapes: volumes against closed forms and brute-force sums, symmetry, profile,
//! peak, scaling, validation, and the surface mesh.

use implant::quadrature::gauss_legendre;
use implant::shape::{MIN_MESH_RINGS, MIN_MESH_SEGMENTS, VOLUME_QUADRATURE_NODES};
use implant::{
    ANATOMIC_PEAK_HEIGHT_RATIO, ANATOMIC_PEAK_RATIO, AnatomicImplant, AnatomicTaper, ImplantError,
    ImplantShape, RoundImplant, RoundProfile,
};
use mesh::Topology;
use std::f64::consts::PI;

/// Relative tolerance of the default quadrature against closed forms (measured < 1e-14).
const QUADRATURE_REL_TOL: f64 = 1e-12;
/// Relative tolerance of a 2000 x 2000 midpoint sum over the bounding box (its error is
/// dominated by the square-root edge, O(h^1.5): measured about 1e-5).
const RIEMANN_REL_TOL: f64 = 2e-4;
/// Relative tolerance of the mesh volume at 32 rings x 128 segments against the integral.
const MESH_REL_TOL: f64 = 2e-3;

fn round(d: f64, p: f64) -> ImplantShape {
    RoundImplant::new(d, p).unwrap().into()
}

fn smoothed(d: f64, p: f64) -> ImplantShape {
    RoundImplant::new(d, p)
        .unwrap()
        .with_profile(RoundProfile::Smoothed)
        .into()
}

fn anatomic(w: f64, h: f64, p: f64) -> ImplantShape {
    AnatomicImplant::new(w, h, p).unwrap().into()
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// A sample of valid shapes: both round profiles, both anatomic tapers.
fn sample_shapes() -> Vec<ImplantShape> {
    vec![
        round(115.0, 33.0),
        round(90.0, 40.0),
        smoothed(115.0, 33.0),
        smoothed(150.0, 20.0),
        anatomic(120.0, 113.0, 42.0),
        anatomic(120.0, 100.0, 30.0),
        anatomic(140.0, 150.0, 50.0),
    ]
}

/// Anatomic volume (mm³) from the 1-D reduction of eqs. 5-10, integrated exactly as a
/// polynomial: integrating eq. 10 over x' in closed form (∫ψ sqrt(1 - x²/c²) dx) leaves
/// `V = p w h π/8 ∫_{-1}^{1} χ(t) q(t) (1 - t²) (1 - q(t)² (1 - t²)/8) dt`,
/// `q = (a - t)/((a + 1) b)`, a polynomial of degree 9 in `t`.
fn anatomic_volume_closed_form(w: f64, h: f64, p: f64, a: f64, b: f64) -> f64 {
    fn mul(x: &[f64], y: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; x.len() + y.len() - 1];
        for (i, xi) in x.iter().enumerate() {
            for (j, yj) in y.iter().enumerate() {
                out[i + j] += xi * yj;
            }
        }
        out
    }
    let k = 1.0 / ((a + 1.0) * b);
    let q = [a * k, -k];
    let chi = [0.3 + 0.44, -0.6, 0.3];
    let one_minus_t2 = [1.0, 0.0, -1.0];
    let q2s = mul(&mul(&q, &q), &one_minus_t2);
    let mut bracket = vec![1.0];
    bracket.resize(q2s.len(), 0.0);
    for (i, c) in q2s.iter().enumerate() {
        bracket[i] -= c / 8.0;
    }
    let poly = mul(&mul(&mul(&chi, &q), &one_minus_t2), &bracket);
    let integral: f64 = poly
        .iter()
        .enumerate()
        .map(|(k, c)| {
            if k % 2 == 0 {
                2.0 * c / (k as f64 + 1.0)
            } else {
                0.0
            }
        })
        .sum();
    p * w * h * PI / 8.0 * integral
}

fn closed_form_mm3(shape: &ImplantShape) -> f64 {
    match shape {
        ImplantShape::Round(r) => {
            let (w, p) = (r.diameter_mm(), r.projection_mm());
            match r.profile() {
                RoundProfile::Ellipsoid => PI * w * w * p / 6.0,
                RoundProfile::Smoothed => 2.0 * PI * w * w * p / 15.0,
            }
        }
        ImplantShape::Anatomic(a) => anatomic_volume_closed_form(
            a.width_mm(),
            a.height_mm(),
            a.projection_mm(),
            a.taper().a(),
            a.taper().b(),
        ),
    }
}

#[test]
fn gauss_legendre_is_exact_to_degree_2n_minus_1() {
    for n in [1usize, 2, 5, 8, 16, 33] {
        let rule = gauss_legendre(n);
        assert_eq!(rule.len(), n);
        let sum: f64 = rule.iter().map(|(_, w)| w).sum();
        assert!((sum - 2.0).abs() < 1e-13, "n={n}: weights sum {sum}");
        let degree = 2 * n - 2; // highest even degree it must integrate exactly
        let integral: f64 = rule.iter().map(|(x, w)| w * x.powi(degree as i32)).sum();
        let exact = 2.0 / (degree as f64 + 1.0);
        assert!(
            (integral - exact).abs() < 1e-13,
            "n={n}: ∫x^{degree} = {integral}"
        );
        assert!(rule.windows(2).all(|p| p[0].0 < p[1].0), "nodes ascending");
    }
    assert!(gauss_legendre(0).is_empty());
}

#[test]
fn plain_round_volume_is_the_half_ellipsoid() {
    for (d, p) in [
        (115.0, 33.0),
        (90.0, 20.0),
        (160.0, 64.0),
        (50.0, 5.0),
        (250.0, 120.0),
    ] {
        let shape = round(d, p);
        let exact_ml = 2.0 / 3.0 * PI * (d / 2.0) * (d / 2.0) * p / 1000.0;
        let v = shape.volume_ml();
        assert!(
            rel(v, exact_ml) < QUADRATURE_REL_TOL,
            "{d}x{p}: {v} vs {exact_ml}"
        );
    }
    // The paper's round implant: 115 x 33 mm, sold as 250 ml.
    let v = round(115.0, 33.0).volume_ml();
    assert!((v - 228.51).abs() < 0.01, "{v}");
}

#[test]
fn all_volumes_match_closed_forms_and_converge() {
    for shape in sample_shapes() {
        let exact = closed_form_mm3(&shape);
        let v = shape.volume_ml() * 1000.0;
        assert!(
            rel(v, exact) < QUADRATURE_REL_TOL,
            "{shape}: {v} vs {exact}"
        );
        // Convergence: exponential; machine precision at the default 16 points.
        let errors: Vec<f64> = [4usize, 8, 16, VOLUME_QUADRATURE_NODES]
            .iter()
            .map(|&n| rel(shape.volume_mm3_quadrature(n), exact))
            .collect();
        println!(
            "{shape}: exact {:.4} ml, rel errors n=4,8,16,24: {}",
            exact / 1000.0,
            errors
                .iter()
                .map(|e| format!("{e:.1e}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
        assert!(errors[3] < QUADRATURE_REL_TOL, "{shape}: {errors:?}");
        assert!(errors[1] < 1e-4, "{shape}: {errors:?}");
    }
    // The paper's anatomic implant: 120 x 113 x 42 mm, sold as 280 ml.
    let paper = anatomic(120.0, 113.0, 42.0);
    assert!(
        (paper.volume_ml() - 216.74).abs() < 0.01,
        "{}",
        paper.volume_ml()
    );
}

#[test]
fn volumes_agree_with_a_brute_force_midpoint_sum() {
    // Independent of the sine map and of the footprint half-width: only the thickness
    // function summed over a fine grid on the bounding box.
    let n = 2000;
    for shape in sample_shapes() {
        let fp = shape.footprint();
        let (dx, dy) = (fp.width_mm() / n as f64, fp.height_mm() / n as f64);
        let mut sum = 0.0;
        for i in 0..n {
            let y = fp.y_min_mm + (i as f64 + 0.5) * dy;
            for j in 0..n {
                let x = fp.x_min_mm + (j as f64 + 0.5) * dx;
                sum += shape.thickness_mm(x, y);
            }
        }
        let v = sum * dx * dy;
        let q = shape.volume_mm3_quadrature(VOLUME_QUADRATURE_NODES);
        println!("{shape}: midpoint rel diff {:.1e}", rel(v, q));
        assert!(rel(v, q) < RIEMANN_REL_TOL, "{shape}: {v} vs {q}");
    }
}

#[test]
fn volume_scales_with_the_dimensions_as_the_formulas_imply() {
    // z ∝ p exactly; the round footprint ∝ w², the anatomic one ∝ w h at a fixed taper.
    for shape in sample_shapes() {
        let v = shape.volume_ml();
        let (w, h, p) = (shape.width_mm(), shape.height_mm(), shape.projection_mm());
        let scaled: ImplantShape = match shape {
            ImplantShape::Round(r) => RoundImplant::new(w, p / 2.0)
                .unwrap()
                .with_profile(r.profile())
                .into(),
            ImplantShape::Anatomic(a) => AnatomicImplant::new(w, h, p / 2.0)
                .unwrap()
                .with_taper(a.taper())
                .into(),
        };
        assert!(rel(scaled.volume_ml(), v / 2.0) < 1e-13, "{shape} p/2");
        let k = 0.9;
        let shrunk: ImplantShape = match shape {
            ImplantShape::Round(r) => RoundImplant::new(k * w, p / 2.0)
                .unwrap()
                .with_profile(r.profile())
                .into(),
            ImplantShape::Anatomic(a) => AnatomicImplant::new(k * w, k * h, p / 2.0)
                .unwrap()
                .with_taper(a.taper())
                .into(),
        };
        assert!(
            rel(shrunk.volume_ml(), k * k * v / 2.0) < 1e-13,
            "{shape} k w"
        );
    }
}

#[test]
fn smoothed_round_is_four_fifths_of_the_ellipsoid() {
    let ratio = smoothed(115.0, 33.0).volume_ml() / round(115.0, 33.0).volume_ml();
    assert!((ratio - 0.8).abs() < 1e-13, "{ratio}");
    // Eq. 4 halves the projection at the rim: the smoothed profile is half as thick
    // there as the ellipsoid, and equal at the centre.
    let (e, s) = (round(100.0, 30.0), smoothed(100.0, 30.0));
    assert_eq!(e.thickness_mm(0.0, 0.0), s.thickness_mm(0.0, 0.0));
    let near_rim = 49.9;
    let r = s.thickness_mm(near_rim, 0.0) / e.thickness_mm(near_rim, 0.0);
    assert!(
        (r - (1.0 - 2.0 * near_rim * near_rim / 1e4)).abs() < 1e-12,
        "{r}"
    );
}

#[test]
fn thickness_is_symmetric_non_negative_and_zero_outside() {
    for shape in sample_shapes() {
        let fp = shape.footprint();
        for i in 0..=60 {
            for j in 0..=60 {
                let x = -80.0 + 160.0 * j as f64 / 60.0;
                let y = -90.0 + 180.0 * i as f64 / 60.0;
                let z = shape.thickness_mm(x, y);
                assert!(z >= 0.0 && z.is_finite(), "{shape} ({x},{y}): {z}");
                assert_eq!(
                    z,
                    shape.thickness_mm(-x, y),
                    "{shape}: mirror x at ({x},{y})"
                );
                let outside_box =
                    x < fp.x_min_mm || x > fp.x_max_mm || y < fp.y_min_mm || y > fp.y_max_mm;
                if outside_box {
                    assert_eq!(z, 0.0, "{shape}: outside the footprint box at ({x},{y})");
                }
                let inside_slice = x.abs() < shape.footprint_half_width_mm(y);
                assert_eq!(z > 0.0, inside_slice, "{shape}: slice test at ({x},{y})");
            }
        }
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(shape.thickness_mm(bad, 0.0), 0.0);
            assert_eq!(shape.thickness_mm(0.0, bad), 0.0);
        }
    }
    // Round implants are rotationally symmetric.
    for shape in [round(115.0, 33.0), smoothed(115.0, 33.0)] {
        for r in [0.0, 10.0, 30.0, 55.0] {
            let z0 = shape.thickness_mm(r, 0.0);
            for k in 0..12 {
                let a = 2.0 * PI * k as f64 / 12.0;
                let z = shape.thickness_mm(r * a.cos(), r * a.sin());
                assert!((z - z0).abs() < 1e-12, "{shape} r={r}: {z} vs {z0}");
            }
        }
    }
}

#[test]
fn profiles_are_monotone() {
    // Round: thickness falls with the radius. Anatomic: with |x'| at every height.
    for shape in sample_shapes() {
        let fp = shape.footprint();
        match shape {
            ImplantShape::Round(_) => {
                let mut last = f64::INFINITY;
                for k in 0..=200 {
                    let z = shape.thickness_mm(fp.x_max_mm * k as f64 / 200.0, 0.0);
                    assert!(z <= last, "{shape}: not monotone at step {k}");
                    last = z;
                }
                assert_eq!(last, 0.0);
            }
            ImplantShape::Anatomic(_) => {
                for i in 1..40 {
                    let y = fp.y_min_mm + fp.height_mm() * i as f64 / 40.0;
                    let mut last = f64::INFINITY;
                    for k in 0..=100 {
                        let z = shape.thickness_mm(fp.x_max_mm * k as f64 / 100.0, y);
                        assert!(z <= last, "{shape}: not monotone in x at y={y}");
                        last = z;
                    }
                }
            }
        }
    }
}

#[test]
fn maximum_thickness_and_its_position() {
    // Round: the projection, at the centre.
    for shape in [round(115.0, 33.0), smoothed(115.0, 33.0)] {
        assert_eq!(shape.max_thickness_mm(), 33.0);
        assert_eq!(shape.thickness_mm(0.0, 0.0), 33.0);
    }
    // Anatomic: the cubic's root by bisection, independent of the constants.
    let g = |t: f64| (0.3 * (1.0 - t) * (1.0 - t) + 0.44) * (1.0 - t * t).sqrt();
    let cubic = |t: f64| 0.9 * t * t * t - 1.2 * t * t + 0.14 * t + 0.6;
    let (mut lo, mut hi) = (-1.0, 0.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cubic(lo) * cubic(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let t = 0.5 * (lo + hi);
    assert!((g(t) - ANATOMIC_PEAK_RATIO).abs() < 1e-14, "{}", g(t));
    assert!((t / 2.0 - ANATOMIC_PEAK_HEIGHT_RATIO).abs() < 1e-14);
    // Dense sampling of the real thickness function agrees, for both tapers.
    for shape in [anatomic(120.0, 113.0, 42.0), anatomic(120.0, 100.0, 30.0)] {
        let (h, p) = (shape.height_mm(), shape.projection_mm());
        let fp = shape.footprint();
        let mut best = (0.0, 0.0, 0.0);
        let n = 400;
        for i in 0..=n {
            let y = fp.y_min_mm + fp.height_mm() * i as f64 / n as f64;
            for j in 0..=n {
                let x = fp.x_min_mm + fp.width_mm() * j as f64 / n as f64;
                let z = shape.thickness_mm(x, y);
                if z > best.0 {
                    best = (z, x, y);
                }
            }
        }
        assert!((shape.max_thickness_mm() - ANATOMIC_PEAK_RATIO * p).abs() < 1e-12);
        assert!(
            best.0 <= shape.max_thickness_mm() + 1e-12,
            "{shape}: {best:?}"
        );
        assert!(
            shape.max_thickness_mm() - best.0 < 1e-3 * p,
            "{shape}: {best:?}"
        );
        assert!(
            best.1.abs() < fp.width_mm() / n as f64,
            "{shape}: peak off centre {best:?}"
        );
        assert!(
            (best.2 - ANATOMIC_PEAK_HEIGHT_RATIO * h).abs() < 0.02 * h,
            "{best:?}"
        );
        let z = shape.thickness_mm(0.0, ANATOMIC_PEAK_HEIGHT_RATIO * h);
        assert!((z - shape.max_thickness_mm()).abs() < 1e-9 * p);
    }
}

#[test]
fn anatomic_footprint_and_taper() {
    assert_eq!(
        AnatomicTaper::for_dimensions(120.0, 113.0),
        AnatomicTaper::Tall
    );
    assert_eq!(
        AnatomicTaper::for_dimensions(120.0, 108.0),
        AnatomicTaper::Tall
    );
    assert_eq!(
        AnatomicTaper::for_dimensions(120.0, 103.0),
        AnatomicTaper::Short
    );
    assert_eq!(
        (AnatomicTaper::Tall.a(), AnatomicTaper::Tall.b()),
        (3.0, 0.78)
    );
    assert_eq!(
        (AnatomicTaper::Short.a(), AnatomicTaper::Short.b()),
        (10.0, 0.91)
    );
    for (shape, ratio) in [
        (anatomic(120.0, 113.0, 42.0), 1.00923),
        (anatomic(120.0, 100.0, 30.0), 1.00394),
    ] {
        let fp = shape.footprint();
        assert!(
            (fp.width_mm() / 120.0 - ratio).abs() < 1e-5,
            "{}",
            fp.width_mm()
        );
        assert_eq!(
            (fp.y_min_mm, fp.y_max_mm),
            (-shape.height_mm() / 2.0, shape.height_mm() / 2.0)
        );
        // The box is tight: the largest sampled half-width reaches it.
        let max_half = (0..=10000)
            .map(|i| shape.footprint_half_width_mm(fp.y_min_mm + fp.height_mm() * i as f64 / 1e4))
            .fold(0.0, f64::max);
        assert!(
            (max_half - fp.x_max_mm).abs() < 1e-4,
            "{max_half} vs {}",
            fp.x_max_mm
        );
        // Narrower at the top than at the bottom (eq. 5).
        let quarter = shape.height_mm() / 4.0;
        assert!(shape.footprint_half_width_mm(quarter) < shape.footprint_half_width_mm(-quarter));
        // The outline lies on the footprint's boundary (the square root turns rounding in
        // its argument into thickness of order p sqrt(ε)).
        for q in shape.footprint_outline_mm(64) {
            let z = shape.thickness_mm(q.x, q.y);
            assert!(z < 1e-6 * shape.projection_mm(), "{q}: {z}");
            assert!((q.x.abs() - shape.footprint_half_width_mm(q.y)).abs() < 1e-9);
        }
    }
    for q in round(100.0, 30.0).footprint_outline_mm(16) {
        assert!((q.length() - 50.0).abs() < 1e-12);
    }
}

#[test]
fn impossible_sizes_are_rejected() {
    let non_finite = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
    for v in non_finite {
        assert!(matches!(
            RoundImplant::new(v, 30.0),
            Err(ImplantError::NonFinite {
                what: "diameter",
                ..
            })
        ));
        assert!(matches!(
            AnatomicImplant::new(120.0, 110.0, v),
            Err(ImplantError::NonFinite {
                what: "projection",
                ..
            })
        ));
    }
    for d in [0.0, -115.0, 49.9, 250.1] {
        let e = RoundImplant::new(d, 20.0).unwrap_err();
        assert!(
            matches!(
                e,
                ImplantError::OutOfRange {
                    what: "diameter",
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("50-250 mm"), "{e}");
    }
    for p in [0.0, -3.0, 4.9] {
        let e = RoundImplant::new(120.0, p).unwrap_err();
        assert!(
            matches!(
                e,
                ImplantError::OutOfRange {
                    what: "projection",
                    ..
                }
            ),
            "{e}"
        );
    }
    let e = RoundImplant::new(250.0, 121.0).unwrap_err();
    assert!(
        matches!(
            e,
            ImplantError::OutOfRange {
                what: "projection",
                ..
            }
        ),
        "{e}"
    );
    let e = RoundImplant::new(100.0, 50.5).unwrap_err();
    assert_eq!(
        e,
        ImplantError::ProjectionTooLarge {
            projection_mm: 50.5,
            limit_mm: 50.0,
            limited_by: "diameter"
        }
    );
    assert_eq!(
        e.to_string(),
        "implant projection 50.5 mm is larger than half the diameter (50 mm)"
    );
    assert!(
        RoundImplant::new(100.0, 50.0).is_ok(),
        "a full hemisphere is allowed"
    );
    let e = AnatomicImplant::new(120.0, 80.0, 41.0).unwrap_err();
    assert!(
        matches!(
            e,
            ImplantError::ProjectionTooLarge {
                limited_by: "height",
                ..
            }
        ),
        "{e}"
    );
    let e = AnatomicImplant::new(100.0, 130.0, 51.0).unwrap_err();
    assert!(
        matches!(
            e,
            ImplantError::ProjectionTooLarge {
                limited_by: "width",
                ..
            }
        ),
        "{e}"
    );
    let e = AnatomicImplant::new(120.0, 0.0, 30.0).unwrap_err();
    assert!(
        matches!(e, ImplantError::OutOfRange { what: "height", .. }),
        "{e}"
    );
}

#[test]
fn surface_mesh_is_closed_and_encloses_the_volume() {
    for shape in sample_shapes() {
        let (rings, segments) = (32, 128);
        let m = shape.surface_mesh(rings, segments).unwrap();
        m.validate().unwrap();
        assert_eq!(m.vertex_count(), 2 + (2 * rings - 1) * segments);
        assert_eq!(m.triangle_count(), 2 * (2 * rings - 1) * segments);
        let topo = Topology::new(&m);
        assert_eq!(topo.boundary_edge_count, 0, "{shape}: open");
        assert_eq!(topo.non_manifold_edge_count, 0, "{shape}");
        assert_eq!(topo.inconsistent_edge_count, 0, "{shape}");
        assert_eq!(topo.triangle_components().1, 1);
        assert!(m.positions.iter().all(|p| p.z >= 0.0));
        let top = m.positions.iter().map(|p| p.z).fold(0.0, f64::max);
        assert!(top <= shape.max_thickness_mm() + 1e-12);
        let (lo, hi) = m.bounding_box();
        let fp = shape.footprint();
        assert!(lo.x >= fp.x_min_mm - 1e-9 && hi.x <= fp.x_max_mm + 1e-9);
        assert!((lo.y - fp.y_min_mm).abs() < 1e-9 && (hi.y - fp.y_max_mm).abs() < 1e-9);
        // Outward orientation: positive enclosed volume, close to the integral, from below.
        let v_mesh = m.signed_volume();
        let v = shape.volume_ml() * 1000.0;
        println!(
            "{shape}: mesh {:.3} ml, integral {:.3} ml, rel {:.1e}",
            v_mesh / 1e3,
            v / 1e3,
            rel(v_mesh, v)
        );
        assert!(v_mesh > 0.0 && v_mesh < v, "{shape}: {v_mesh} vs {v}");
        assert!(rel(v_mesh, v) < MESH_REL_TOL, "{shape}: {v_mesh} vs {v}");
        // Finer meshes come closer.
        let coarse = shape.surface_mesh(8, 32).unwrap().signed_volume();
        assert!(rel(coarse, v) > rel(v_mesh, v));
    }
    let shape = round(100.0, 30.0);
    assert!(matches!(
        shape.surface_mesh(MIN_MESH_RINGS - 1, 64),
        Err(ImplantError::MeshResolution { .. })
    ));
    assert!(shape.surface_mesh(4, MIN_MESH_SEGMENTS - 1).is_err());
    assert!(
        shape
            .surface_mesh(MIN_MESH_RINGS, MIN_MESH_SEGMENTS)
            .is_ok()
    );
}

#[test]
fn serialises_with_units_in_names() {
    let json = serde_json::to_value(anatomic(120.0, 113.0, 42.0)).unwrap();
    assert_eq!(json["shape"], "anatomic");
    assert_eq!(json["width_mm"], 120.0);
    assert_eq!(json["taper"], "tall");
    let json = serde_json::to_value(smoothed(115.0, 33.0)).unwrap();
    assert_eq!(json["shape"], "round");
    assert_eq!(json["diameter_mm"], 115.0);
    assert_eq!(json["profile"], "smoothed");
}
