//! Native file dialogs: the desktop's file chooser through its XDG portal (rfd, which
//! speaks D-Bus through the system's libdbus loaded at run time, or zenity), asked on a
//! background job so the window keeps drawing. Where no portal answers (a bare X server,
//! CI) the dialog gives nothing and the path fields do the job, as the status line says.

use super::{GuiApp, Status};
use crate::job::Job;
use std::path::PathBuf;

/// What the chosen file is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileChoice {
    /// A scan, landmarks or a planning case to open.
    Open,
    /// Where to save the planning case.
    SaveCase,
    /// The post-operative scan.
    PostoperativeScan,
    /// The post-operative scan's landmarks.
    PostoperativeLandmarks,
}

impl FileChoice {
    /// Asks the desktop for a file, on the calling thread (a job's).
    fn ask(self) -> Option<PathBuf> {
        let scans = ["ply", "obj", "stl"];
        let dialog = rfd::FileDialog::new();
        match self {
            FileChoice::Open => dialog
                .set_title("Open a scan, landmarks or a planning case")
                .add_filter("Scans, landmarks and cases", &["ply", "obj", "stl", "json"])
                .pick_file(),
            FileChoice::SaveCase => dialog
                .set_title("Save the planning case")
                .add_filter("Planning case", &["json"])
                .set_file_name("case.json")
                .save_file(),
            FileChoice::PostoperativeScan => dialog
                .set_title("The post-operative scan")
                .add_filter("Scans", &scans)
                .pick_file(),
            FileChoice::PostoperativeLandmarks => dialog
                .set_title("The post-operative scan's landmarks")
                .add_filter("Landmarks", &["json"])
                .pick_file(),
        }
    }
}

/// A file dialog open on the desktop.
pub(super) struct OpenDialog {
    choice: FileChoice,
    job: Job<Option<PathBuf>>,
}

impl GuiApp {
    /// Opens the desktop's file dialog for `choice` (one at a time).
    pub(super) fn ask_for_file(&mut self, choice: FileChoice) {
        if self.dialog.is_some() {
            return;
        }
        self.dialog = Some(OpenDialog {
            choice,
            job: Job::spawn(self.waker(), move || choice.ask()),
        });
    }

    /// Whether a file dialog is open.
    pub fn is_asking_for_file(&self) -> bool {
        self.dialog.is_some()
    }

    /// Takes the file chosen in the dialog, if it has answered, and does what it was for.
    pub(super) fn poll_dialog(&mut self) {
        let Some(dialog) = &self.dialog else {
            return;
        };
        let Some(answer) = dialog.job.poll() else {
            return;
        };
        let choice = dialog.choice;
        self.dialog = None;
        let Some(path) = answer.ok().flatten() else {
            self.status = Status::Info(
                "No file chosen. (Without a desktop file-chooser portal no dialog opens: type \
                 the path in the field instead.)"
                    .into(),
            );
            return;
        };
        let text = path.display().to_string();
        match choice {
            FileChoice::Open => {
                self.path_text = text;
                self.open(&path);
            }
            FileChoice::SaveCase => {
                self.path_text = text;
                self.save_case();
            }
            FileChoice::PostoperativeScan => self.postoperative.scan_text = text,
            FileChoice::PostoperativeLandmarks => self.postoperative.landmarks_text = text,
        }
    }
}
