//! Results of several steps (the demo's folder, a report's folder from the GUI) are kept
//! whole or not at all: a write that fails half way leaves the folder as it was. The
//! failure is real: when a step starts, a folder holding a file takes the place of a
//! file the step then has to write.

use anatomy::breast::Side;
use plan::model::{ModelOptions, PerSide};
use plan::simulate::{ImplantRequest, Session, SimulationOptions, SimulationState, SolverReport};
use plan::{MarkedScan, PhantomParams, Progress, Silent};
use std::path::{Path, PathBuf};

/// Puts a folder (with a file in it) at `obstacle` when the stage `stage` starts.
struct BlockAt {
    stage: &'static str,
    obstacle: PathBuf,
}

impl Progress for BlockAt {
    fn stage(&self, name: &str, _: u64) {
        if name == self.stage {
            std::fs::create_dir_all(&self.obstacle).unwrap();
            std::fs::write(self.obstacle.join("blocker"), "").unwrap();
        }
    }
    fn step(&self) {}
    fn warn(&self, _: &str) {}
}

/// The names in `folder`, sorted.
fn entries(folder: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(folder)
        .unwrap()
        .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A previous result in `folder`: a model folder, a report and a file of the user's.
fn previous_result(folder: &Path) {
    std::fs::create_dir_all(folder.join("model")).unwrap();
    std::fs::write(folder.join("model/model.json"), "previous").unwrap();
    std::fs::write(folder.join("report.html"), "previous").unwrap();
    std::fs::write(folder.join("notes.txt"), "the surgeon's").unwrap();
}

fn assert_previous_result(folder: &Path) {
    let read = |name: &str| std::fs::read_to_string(folder.join(name)).unwrap();
    assert_eq!(entries(folder), ["model", "notes.txt", "report.html"]);
    assert_eq!(entries(&folder.join("model")), ["model.json"]);
    assert_eq!(read("model/model.json"), "previous");
    assert_eq!(read("report.html"), "previous");
    assert_eq!(read("notes.txt"), "the surgeon's");
}

/// The demo fails at its last step (the report): the folder is as before, with none of
/// the scans, the model or the simulation it had written; into a new folder, no folder.
#[test]
fn a_demo_that_fails_at_the_report_leaves_the_folder_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("demo");
    previous_result(&folder);
    let block = BlockAt {
        stage: "report",
        obstacle: folder.join("report.html"),
    };
    let error = plan::demo::demo(&folder, false, &block).unwrap_err();
    assert!(format!("{error:#}").contains("report.html"), "{error:#}");
    assert_previous_result(&folder);

    let new_folder = dir.path().join("new_demo");
    let block = BlockAt {
        stage: "report",
        obstacle: new_folder.join("report.html"),
    };
    plan::demo::demo(&new_folder, false, &block).unwrap_err();
    assert!(!new_folder.exists());
}

/// The GUI's report: the folders are written, then the page fails. The folder is as
/// before.
#[test]
fn a_report_folder_whose_page_fails_is_left_as_it_was() {
    let marked = MarkedScan::phantom(&PhantomParams::default()).unwrap();
    let model_options = ModelOptions {
        elements: 6_000,
        ..ModelOptions::default()
    };
    let mut session = Session::build(
        marked,
        &model_options,
        plan::catalog::Catalog::builtin(),
        SimulationOptions::default(),
        &Silent,
    )
    .unwrap();
    let request = ImplantRequest::new("catalog:R-MOD-120");
    let left = session.place(Side::Left, &request).unwrap();
    session.simulation.run(true).unwrap();
    let state = SimulationState {
        implants: PerSide {
            left: Some(left),
            right: None,
        },
        solver: SolverReport {
            vcycles: 0,
            relative_residual: 0.0,
            converged: true,
            time_ms: 0.0,
            implant_stage_vcycles: 0,
            gravity_stage_vcycles: None,
            inverted_elements: 0,
        },
        no_gravity: true,
    };

    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("report");
    previous_result(&folder);
    let pending =
        plan::report::write_session_folders(&mut session, &state, &folder, None, &Silent).unwrap();
    assert!(folder.join("simulation/result.json").is_file());
    let block = BlockAt {
        stage: "report",
        obstacle: folder.join("report.html"),
    };
    let error = pending.write(&block).unwrap_err();
    assert!(format!("{error:#}").contains("report.html"), "{error:#}");
    assert_previous_result(&folder);
}
