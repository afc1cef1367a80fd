//! "Build model" on a worker thread: `plan`'s [`Session::build`] (breast model, closed
//! surface, tetrahedra, simulation set-up) with its progress shown in the window and a
//! cancel button. The window polls; it never waits for the build.

use plan::catalog::Catalog;
use plan::model::ModelOptions;
use plan::simulate::{Session, SimulationOptions};
use plan::{Cancelled, MarkedScan, Progress};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, TryRecvError, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// What the window shows of a build under way.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildProgress {
    /// The stage's name (`model`, `tetrahedra`, `simulation`).
    pub stage: String,
    /// Steps of the stage done, and how many it has.
    pub step: u64,
    pub steps: u64,
    pub elapsed: Duration,
    /// Cancel was pressed; the build stops at the end of its current stage.
    pub cancelling: bool,
}

/// How a build ended.
pub enum BuildOutcome {
    Built(Box<Session>, Duration),
    Cancelled,
    Failed(anyhow::Error),
}

/// The progress the worker reports into and the window reads.
struct SharedProgress {
    stage: Mutex<(String, u64)>,
    step: AtomicU64,
    cancel: AtomicBool,
    warnings: Mutex<Vec<String>>,
    wake: Box<dyn Fn() + Send + Sync>,
}

impl Progress for SharedProgress {
    fn stage(&self, name: &str, steps: u64) {
        if let Ok(mut stage) = self.stage.lock() {
            *stage = (name.to_string(), steps);
        }
        self.step.store(0, Ordering::Relaxed);
        (self.wake)();
    }

    fn step(&self) {
        self.step.fetch_add(1, Ordering::Relaxed);
        (self.wake)();
    }

    fn warn(&self, message: &str) {
        if let Ok(mut warnings) = self.warnings.lock() {
            warnings.push(message.to_string());
        }
    }

    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
}

/// A model build under way: the window's handle.
pub struct ModelBuild {
    progress: Arc<SharedProgress>,
    outcome: Receiver<anyhow::Result<Session>>,
    started: Instant,
}

impl ModelBuild {
    /// Starts building the model of `marked` on a worker thread; `wake` is called on
    /// progress and at the end (the window asks for a repaint there).
    pub fn start(
        marked: MarkedScan,
        model: ModelOptions,
        simulation: SimulationOptions,
        wake: impl Fn() + Send + Sync + 'static,
    ) -> ModelBuild {
        let progress = Arc::new(SharedProgress {
            stage: Mutex::new(("starting".into(), 1)),
            step: AtomicU64::new(0),
            cancel: AtomicBool::new(false),
            warnings: Mutex::new(Vec::new()),
            wake: Box::new(wake),
        });
        let (sender, outcome) = channel();
        let worker_progress = Arc::clone(&progress);
        std::thread::spawn(move || {
            let session = Session::build(
                marked,
                &model,
                Catalog::builtin(),
                simulation,
                worker_progress.as_ref(),
            );
            // The window may be gone (closed, or a new scan opened): nobody to tell.
            let _ = sender.send(session);
            (worker_progress.wake)();
        });
        ModelBuild {
            progress,
            outcome,
            started: Instant::now(),
        }
    }

    /// Asks the build to stop after its current stage.
    pub fn cancel(&self) {
        self.progress.cancel.store(true, Ordering::Relaxed);
        (self.progress.wake)();
    }

    /// Where the build is.
    pub fn progress(&self) -> BuildProgress {
        let (stage, steps) = self
            .progress
            .stage
            .lock()
            .map(|stage| stage.clone())
            .unwrap_or_default();
        BuildProgress {
            stage,
            step: self.progress.step.load(Ordering::Relaxed),
            steps,
            elapsed: self.started.elapsed(),
            cancelling: self.progress.cancel.load(Ordering::Relaxed),
        }
    }

    /// The warnings so far (e.g. scanner holes closed by a fill-in), taken.
    pub fn take_warnings(&self) -> Vec<String> {
        self.progress
            .warnings
            .lock()
            .map(|mut warnings| std::mem::take(&mut *warnings))
            .unwrap_or_default()
    }

    /// The outcome once the build has ended.
    pub fn poll(&self) -> Option<BuildOutcome> {
        match self.outcome.try_recv() {
            Ok(Ok(session)) => Some(BuildOutcome::Built(
                Box::new(session),
                self.started.elapsed(),
            )),
            Ok(Err(error)) if error.chain().any(|cause| cause.is::<Cancelled>()) => {
                Some(BuildOutcome::Cancelled)
            }
            Ok(Err(error)) => Some(BuildOutcome::Failed(error)),
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => Some(BuildOutcome::Failed(anyhow::anyhow!(
                "the model build stopped unexpectedly"
            ))),
        }
    }
}
