//! Property test (issue 21, item 5): random phantoms scanned with occlusion, as a
//! standing three-camera clinical scanner sees them (the underside of full or hanging
//! breasts and the lateral fold missing), go through the model pipeline as
//! `mammaplan model` runs it: the breast model (holes closed, cut curves, fill-ins,
//! volumes) and the closed surface. The tetrahedral stage is left out: it only meshes
//! the closed surface, which is checked for watertightness here, and would triple the
//! time.
//!
//! The default phantom with occlusion must meet its truth: breast volumes within 3% and
//! the reconstructed skin within 2 mm of the true skin (issue 21). Over the random
//! phantoms, not every case builds yet (see `docs/dev/model-on-every-body.md`): the test
//! holds the number that does at [`MIN_BUILT`] (raise it as causes are fixed, never lower
//! it), every failure must be an error value naming the problem, and every case that
//! builds must stay within the looser bounds below.
//!
//! Run with `cargo test --release -p plan --test occluded_phantoms -- --nocapture` to
//! see the table; set `OCCLUDED_PHANTOMS_CASES=3,14` to run only those cases. Each
//! failure names the `mammaplan phantom` command that writes its scan.

use anatomy::breast::{BreastOptions, Side};
use anatomy::closed_surface::{ClosedSurfaceOptions, build_closed_surface};
use mesh::{SurfaceIndex, Topology};
use phantom::{Cup, PhantomParams};
use plan::{MarkedScan, Scan, Silent};
use std::path::Path;
use std::time::Instant;

/// Random phantoms drawn.
const CASES: usize = 30;
/// Seed of the draw (fixed: a failure names its case by its parameters, and the same
/// case comes back on every run).
const BASE_SEED: u64 = 21_05;
/// Largest relative error of a breast volume against the phantom's truth, on the default
/// phantom (issue 21's figure).
const VOLUME_TOLERANCE: f64 = 0.03;
/// Largest distance of a reconstructed skin vertex from the true skin on the default
/// phantom (mm; issue 21's figure).
const RECONSTRUCTION_TOLERANCE_MM: f64 = 2.0;
/// Of the random cases, at least this many build (15 of 30 on 2026-11-26; 29 since
/// crescent holes are filled in 3D, a cut curve stopped short of its start by noise is
/// closed along edges, a small loop of a cut curve is cut out and the wall's small folds
/// are smoothed like the scan's; 30 since the lateral planes are moved off grazes of
/// the torso's side and the wall is smoothed of noise).
const MIN_BUILT: usize = 30;
/// Bounds for every random case that builds: a large, ptotic cup loses up to 17% of its
/// skin to occlusion, and the smooth reconstruction does not follow the fold's crease
/// under it (measured worst on 2026-11-26: 8.1% and 4.3 mm).
const RANDOM_VOLUME_TOLERANCE: f64 = 0.10;
const RANDOM_RECONSTRUCTION_TOLERANCE_MM: f64 = 5.0;

/// SplitMix64: a small, well-mixed generator for drawing the parameters (`plan` has no
/// random number crate).
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[0, high]`, rounded to hundredths so the parameter line reads back.
    fn hundredths(&mut self, high: f64) -> f64 {
        (self.unit() * high * 100.0).round() / 100.0
    }
}

/// The parameters of every case.
fn draw_cases() -> Vec<PhantomParams> {
    let mut rng = SplitMix(BASE_SEED);
    (0..CASES)
        .map(|_| PhantomParams {
            cup: [Cup::Small, Cup::Medium, Cup::Large][(rng.next() % 3) as usize],
            ptosis: rng.hundredths(1.0),
            asymmetry: rng.hundredths(1.0),
            noise_mm: rng.hundredths(0.4),
            seed: rng.next() % 1000,
            occlusion: true,
        })
        .collect()
}

/// The command that writes the phantom of `params`.
fn command(params: &PhantomParams) -> String {
    format!(
        "mammaplan phantom --cup {} --ptosis {} --asymmetry {} --noise-mm {} --seed {} --occlusion",
        params.cup, params.ptosis, params.asymmetry, params.noise_mm, params.seed
    )
}

/// The first columns of a case's table row: its number and parameters.
fn row_start(case: usize, params: &PhantomParams) -> String {
    format!(
        "{case:2} | {:6} | {:4.2} | {:4.2} | {:4.2}",
        params.cup.to_string(),
        params.ptosis,
        params.asymmetry,
        params.noise_mm
    )
}

/// The figures of one case that built.
struct Figures {
    /// Relative volume error, left and right.
    volume_error: [f64; 2],
    /// Relative change of the volumes against the model of the same phantom without
    /// occlusion (`None` if that one fails), left and right.
    occlusion_effect: Option<[f64; 2]>,
    /// Largest distance of a reconstructed vertex from the true skin, both sides (mm).
    max_reconstruction_mm: f64,
    /// Share of each breast's skin that was reconstructed.
    reconstructed_share: [f64; 2],
    seconds: f64,
}

/// A phantom's scan and landmarks, as `mammaplan model` loads them.
fn marked_scan(phantom: &phantom::Phantom) -> anyhow::Result<MarkedScan> {
    let scan = Scan::from_mesh(phantom.scan.clone(), Path::new("scan"))?;
    MarkedScan::new(
        scan,
        phantom.landmarks.clone(),
        Path::new("its landmarks"),
        None,
        &Silent,
    )
}

/// The messages of an error's chain, each left out where the one before already ends
/// with it.
fn message(error: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in error.chain().map(|cause| cause.to_string()) {
        if !text.ends_with(&cause) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&cause);
        }
    }
    text
}

/// Builds the model of one case and measures it.
fn run_case(params: &PhantomParams) -> anyhow::Result<Figures> {
    let start = Instant::now();
    let phantom = phantom::generate(params);
    let marked = marked_scan(&phantom)?;
    let (breasts, _) =
        plan::model::build_breasts(&marked, &BreastOptions::default(), None, &Silent)?;
    let closed = build_closed_surface(
        &breasts.surface,
        &breasts.filled_base,
        &marked.frame,
        &marked.landmarks,
        &ClosedSurfaceOptions::default(),
    )?;
    let topology = Topology::new(&closed.mesh);
    anyhow::ensure!(
        topology.boundary_edge_count == 0 && topology.non_manifold_edge_count == 0,
        "the closed surface is not watertight: {} boundary, {} non-manifold edges",
        topology.boundary_edge_count,
        topology.non_manifold_edge_count
    );

    let truth = SurfaceIndex::new(&phantom.full_skin).expect("the phantom has triangles");
    let true_volume = [
        phantom.breast_volume_ml.left,
        phantom.breast_volume_ml.right,
    ];
    let mut volume_error = [0.0; 2];
    let mut reconstructed_share = [0.0; 2];
    let mut max_reconstruction_mm: f64 = 0.0;
    for (k, side) in Side::BOTH.into_iter().enumerate() {
        let breast = breasts.breast(side);
        volume_error[k] = breast.volume_ml / true_volume[k] - 1.0;
        reconstructed_share[k] = breast.reconstructed.area_share;
        let patch = &breast.patch.mesh;
        for (position, _) in patch
            .positions
            .iter()
            .zip(&breast.reconstructed.vertex_flags)
            .filter(|(_, flag)| **flag)
        {
            max_reconstruction_mm =
                max_reconstruction_mm.max(truth.closest_point(*position).distance);
        }
    }
    // The same phantom without occlusion, for how much of the error occlusion causes.
    let unoccluded = phantom::generate(&PhantomParams {
        occlusion: false,
        ..*params
    });
    let occlusion_effect = match plan::model::build_breasts(
        &marked_scan(&unoccluded)?,
        &BreastOptions::default(),
        None,
        &Silent,
    ) {
        Ok((whole, _)) => Some(
            Side::BOTH
                .map(|side| breasts.breast(side).volume_ml / whole.breast(side).volume_ml - 1.0),
        ),
        Err(_) => None,
    };
    Ok(Figures {
        volume_error,
        occlusion_effect,
        max_reconstruction_mm,
        reconstructed_share,
        seconds: start.elapsed().as_secs_f64(),
    })
}

#[test]
fn random_occluded_phantoms_build_with_true_volumes_and_skin() {
    let start = Instant::now();
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    let mut errors = Vec::new();
    let only: Option<Vec<usize>> = std::env::var("OCCLUDED_PHANTOMS_CASES").ok().map(|list| {
        list.split(',')
            .filter_map(|k| k.trim().parse().ok())
            .collect()
    });
    for (case, params) in draw_cases().iter().enumerate() {
        if only.as_ref().is_some_and(|only| !only.contains(&case)) {
            continue;
        }
        // Printed first, so a panic deep in the pipeline still names its case.
        println!("case {case:2}: {params}");
        match run_case(params) {
            Ok(figures) => {
                let [left, right] = figures.volume_error;
                let effect = figures
                    .occlusion_effect
                    .map_or("failed".to_string(), |[l, r]| {
                        format!("{:+5.2}% / {:+5.2}%", 100.0 * l, 100.0 * r)
                    });
                let row = format!(
                    "{} | {:+6.2}% / {:+6.2}% | {effect} | {:4.1}% / {:4.1}% | {:5.2} | {:4.1} s",
                    row_start(case, params),
                    100.0 * left,
                    100.0 * right,
                    100.0 * figures.reconstructed_share[0],
                    100.0 * figures.reconstructed_share[1],
                    figures.max_reconstruction_mm,
                    figures.seconds,
                );
                println!("{row}");
                rows.push(row);
                for (side, error) in [("left", left), ("right", right)] {
                    if error.abs() > RANDOM_VOLUME_TOLERANCE {
                        failures.push(format!(
                            "case {case} ({}): {side} breast volume off the truth by {:+.2}% (at most {}%)",
                            command(params),
                            100.0 * error,
                            100.0 * RANDOM_VOLUME_TOLERANCE
                        ));
                    }
                }
                if figures.max_reconstruction_mm > RANDOM_RECONSTRUCTION_TOLERANCE_MM {
                    failures.push(format!(
                        "case {case} ({}): reconstructed skin up to {:.2} mm off the true skin (at most {RANDOM_RECONSTRUCTION_TOLERANCE_MM} mm)",
                        command(params),
                        figures.max_reconstruction_mm
                    ));
                }
            }
            Err(error) => {
                let row = format!("{} | error: {}", row_start(case, params), message(&error));
                println!("{row}");
                rows.push(row);
                errors.push(format!(
                    "case {case} ({}): {}",
                    command(params),
                    message(&error)
                ));
            }
        }
    }
    println!(
        "\ncase | cup | ptosis | asymmetry | noise mm | volume error against the truth, left / right | change against the model without occlusion | reconstructed skin left / right | max distance of reconstructed skin from the true skin (mm) | time"
    );
    for row in &rows {
        println!("{row}");
    }
    println!("{} cases in {:.1?}", rows.len(), start.elapsed());
    println!(
        "{} cases failed to build:\n{}",
        errors.len(),
        errors.join("\n")
    );
    assert!(
        failures.is_empty(),
        "{} built cases out of bounds:\n{}",
        failures.len(),
        failures.join("\n")
    );
    if only.is_none() {
        let built = rows.len() - errors.len();
        assert!(
            built >= MIN_BUILT,
            "only {built} of {} cases built (at least {MIN_BUILT})",
            rows.len()
        );
    }
}

/// The default phantom (medium cup, mild ptosis) scanned with occlusion: the breast
/// volumes within 3% of the truth and the reconstructed underside within 2 mm of the
/// true skin.
#[test]
fn the_default_phantom_with_occlusion_meets_its_truth() {
    let params = PhantomParams {
        occlusion: true,
        ..PhantomParams::default()
    };
    let figures = run_case(&params).unwrap_or_else(|error| panic!("{}", message(&error)));
    println!(
        "default phantom with occlusion: volume error {:+.2}% / {:+.2}%, reconstructed {:.1}% / {:.1}% of the skin, at most {:.2} mm off the true skin",
        100.0 * figures.volume_error[0],
        100.0 * figures.volume_error[1],
        100.0 * figures.reconstructed_share[0],
        100.0 * figures.reconstructed_share[1],
        figures.max_reconstruction_mm
    );
    assert!(
        figures
            .reconstructed_share
            .iter()
            .all(|&share| share > 0.01)
    );
    for error in figures.volume_error {
        assert!(error.abs() <= VOLUME_TOLERANCE, "{error}");
    }
    assert!(figures.max_reconstruction_mm <= RECONSTRUCTION_TOLERANCE_MM);
}

/// A small, hanging phantom whose scan's top edge has a notch of unseen skin (the
/// upward-facing skin over the clavicle) reaching 2 mm below its left clavicle point,
/// found by a sweep of 45 occluded phantoms (`docs/dev/model-on-every-body.md`, session
/// 41): the clip box's top stays clear of it and the model builds, its volumes within
/// 3% of the truth (measured 0.1%) and its reconstructed skin within the random cases'
/// bound. Before, the closed surface stopped: "the clip box reaches beyond the scan's
/// border".
#[test]
fn a_notch_of_unseen_skin_under_a_clavicle_does_not_stop_the_model() {
    let params = PhantomParams {
        cup: Cup::Small,
        ptosis: 0.8,
        asymmetry: 0.5,
        noise_mm: 0.3,
        seed: 43,
        occlusion: true,
    };
    let figures = run_case(&params)
        .unwrap_or_else(|error| panic!("{}: {}", command(&params), message(&error)));
    for error in figures.volume_error {
        assert!(error.abs() <= VOLUME_TOLERANCE, "{error}");
    }
    assert!(figures.max_reconstruction_mm <= RANDOM_RECONSTRUCTION_TOLERANCE_MM);
}
