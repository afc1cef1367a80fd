//! Every parser of user files against mutated valid files: PLY (ASCII and binary), OBJ,
//! STL (ASCII and binary), landmark and control-point JSON, catalog CSV and VTU. A parser
//! may refuse a file, never panic, and must answer each within 10 s.
//!
//! Mutations (seeded, so a failure names its case): flipped bytes, deleted and duplicated
//! ranges, truncation, and numeric tokens swapped for extreme ones (1e308, NaN, -1,
//! 4294967295, ...). The time budget is `MAMMAPLAN_FUZZ_SECONDS` (default 12, shared by
//! the parsers); `.ci/run` gives it 180.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::time::{Duration, Instant};

/// The longest a parser may take on one input.
const MAX_PER_INPUT: Duration = Duration::from_secs(10);

/// Tokens swapped in for numbers.
const EXTREMES: [&str; 12] = [
    "1e308",
    "-1e308",
    "nan",
    "inf",
    "-0",
    "-1",
    "0",
    "4294967295",
    "18446744073709551616",
    "1e-320",
    "3e38",
    "99999999",
];

/// One parser: a file name (its extension picks the format) and what reads it.
struct Target {
    name: &'static str,
    seed: Vec<u8>,
    parse: fn(&Path, &[u8]),
}

fn seeds(dir: &Path) -> Vec<Target> {
    let mesh = mesh::shapes::grid(6, 6, 2.0);
    let written = |name: &str, write: &dyn Fn(&Path)| {
        let path = dir.join(name);
        write(&path);
        std::fs::read(&path).unwrap()
    };
    let ply = |encoding| {
        written("seed.ply", &|p| {
            mesh::io::write_ply(p, &mesh, encoding).unwrap();
        })
    };
    let tets = fem::box_mesh(DVec3::ZERO, DVec3::splat(10.0), [2, 2, 2]);
    let phantom = phantom::generate(&phantom::PhantomParams::default());
    let landmarks = phantom.landmarks.to_json(Default::default()).to_string();
    let control_points = r#"{"units":"mm","left":[[80,-180,100],[110,-160,90],[90,-120,100]],"right":[[-80,-180,100],[-110,-160,90],[-90,-120,100]]}"#;
    let catalog = "id,family,shape,width_mm,height_mm,projection_mm\n\
                   R1,moderate,round,120,,35\nA1,full,anatomic,115,110,40\n";
    let read_mesh = |path: &Path, _: &[u8]| {
        let _ = mesh::io::read_mesh(path);
    };
    vec![
        Target {
            name: "ascii.ply",
            seed: ply(mesh::io::PlyEncoding::Ascii),
            parse: read_mesh,
        },
        Target {
            name: "binary.ply",
            seed: ply(mesh::io::PlyEncoding::BinaryLittleEndian),
            parse: read_mesh,
        },
        Target {
            name: "mesh.obj",
            seed: written("seed.obj", &|p| mesh::io::write_obj(p, &mesh).unwrap()),
            parse: read_mesh,
        },
        Target {
            name: "mesh.stl",
            seed: written("seed.stl", &|p| mesh::io::write_stl(p, &mesh).unwrap()),
            parse: read_mesh,
        },
        Target {
            name: "landmarks.json",
            seed: landmarks.into_bytes(),
            parse: |path, bytes| {
                let _ = anatomy::Landmarks::from_json(&String::from_utf8_lossy(bytes), path);
            },
        },
        Target {
            name: "control_points.json",
            seed: control_points.as_bytes().to_vec(),
            parse: |path, bytes| {
                let text = String::from_utf8_lossy(bytes);
                let _ = anatomy::breast::ControlPoints::from_json(&text, path);
            },
        },
        Target {
            name: "catalog.csv",
            seed: catalog.as_bytes().to_vec(),
            parse: |_, bytes| {
                let _ = implant::Catalog::from_csv_reader(bytes, "catalog.csv");
            },
        },
        Target {
            name: "tets.vtu",
            seed: written("seed.vtu", &|p| {
                tetra::vtu::write_vtu(p, &tets, &[], &[]).unwrap();
            }),
            parse: |path, _| {
                let _ = tetra::vtu::read_vtu(path);
            },
        },
    ]
}

/// A mutation of `seed`: one to three edits.
fn mutate(seed: &[u8], rng: &mut Pcg64) -> Vec<u8> {
    let mut bytes = seed.to_vec();
    for _ in 0..rng.random_range(1..=3) {
        let len = bytes.len().max(1);
        let at = rng.random_range(0..len);
        match rng.random_range(0..6) {
            0 => {
                for _ in 0..rng.random_range(1..=8) {
                    let k = rng.random_range(0..len);
                    if let Some(byte) = bytes.get_mut(k) {
                        *byte ^= 1 << rng.random_range(0..8);
                    }
                }
            }
            1 => {
                let end = (at + rng.random_range(1..=64)).min(bytes.len());
                bytes.drain(at.min(end)..end);
            }
            2 => {
                let end = (at + rng.random_range(1..=64)).min(bytes.len());
                let chunk = bytes[at.min(end)..end].to_vec();
                let to = rng.random_range(0..=bytes.len());
                bytes.splice(to..to, chunk);
            }
            3 => bytes.truncate(at),
            4 => {
                let junk: Vec<u8> = (0..rng.random_range(1..=16))
                    .map(|_| rng.random())
                    .collect();
                let to = rng.random_range(0..=bytes.len());
                bytes.splice(to..to, junk);
            }
            _ => swap_number(&mut bytes, at, rng),
        }
    }
    bytes
}

/// Replaces the first number at or after `from` with an extreme token.
fn swap_number(bytes: &mut Vec<u8>, from: usize, rng: &mut Pcg64) {
    let is_number = |b: u8| b.is_ascii_digit() || b == b'.' || b == b'-' || b == b'e';
    let Some(start) = (from..bytes.len()).find(|&k| bytes[k].is_ascii_digit()) else {
        return;
    };
    let end = (start..bytes.len())
        .find(|&k| !is_number(bytes[k]))
        .unwrap_or(bytes.len());
    let token = EXTREMES[rng.random_range(0..EXTREMES.len())];
    bytes.splice(start..end, token.bytes());
}

#[test]
fn parsers_refuse_damaged_files_without_panicking() {
    let seconds: u64 = std::env::var("MAMMAPLAN_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(12);
    let dir = tempfile::tempdir().unwrap();
    let targets = seeds(dir.path());
    let per_target = Duration::from_secs(seconds) / targets.len() as u32;
    let mut total = 0;
    for (t, target) in targets.iter().enumerate() {
        let path = dir.path().join(target.name);
        let start = Instant::now();
        let mut case = 0u64;
        while start.elapsed() < per_target {
            let seed = (t as u64) << 32 | case;
            let mut rng = Pcg64::seed_from_u64(seed);
            let bytes = mutate(&target.seed, &mut rng);
            std::fs::write(&path, &bytes).unwrap();
            let began = Instant::now();
            let outcome = catch_unwind(AssertUnwindSafe(|| (target.parse)(&path, &bytes)));
            assert!(
                outcome.is_ok(),
                "{}: case {seed} panicked (input kept at {})",
                target.name,
                keep(&path, seed).display()
            );
            assert!(
                began.elapsed() < MAX_PER_INPUT,
                "{}: case {seed} took {:?}",
                target.name,
                began.elapsed()
            );
            case += 1;
        }
        println!("{}: {case} mutated inputs", target.name);
        total += case;
    }
    println!("{total} inputs in {seconds} s");
    assert!(total > 0);
}

/// Copies a failing input out of the temporary folder, for the report.
fn keep(path: &Path, seed: u64) -> std::path::PathBuf {
    let kept = std::env::temp_dir().join(format!(
        "mammaplan-fuzz-{seed}-{}",
        path.file_name().unwrap().to_string_lossy()
    ));
    let _ = std::fs::copy(path, &kept);
    kept
}
