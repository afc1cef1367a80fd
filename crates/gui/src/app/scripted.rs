//! Running a [`Script`] in the window: one action after the other, each through the same
//! calls as the buttons, waiting (frame after frame) for builds, solves and screenshots;
//! and the rate log of the `stats` action.

use super::GuiApp;
use crate::implant_plan::{Editing, Source};
use crate::script::{Action, Script};
use eframe::egui;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How often a waiting script looks again.
const POLL: Duration = Duration::from_millis(50);
/// How often the `stats` action prints.
const STATS_PERIOD: Duration = Duration::from_secs(1);

/// Where a screenshot's outcome arrives (from the renderer's callback).
type ScreenshotOutcome = Arc<Mutex<Option<Result<(), String>>>>;

/// A script being run.
pub(super) struct ScriptRun {
    script: Script,
    next: usize,
    /// When the current action began (drags, builds, screenshots).
    started: Option<Instant>,
    /// Where a screenshot's outcome arrives.
    screenshot: Option<ScreenshotOutcome>,
    stats: Option<RateLog>,
}

/// Counts for the `stats` log.
struct RateLog {
    since: Instant,
    frames: u64,
    /// Window frames that drew a newer simulated frame than the window frame before.
    view_updates: u64,
    /// The simulated frame the last window frame drew, if it drew one.
    last_shown: Option<u64>,
    simulated_frames: u64,
}

impl RateLog {
    fn new(simulated_frames: u64, shown: Option<u64>) -> RateLog {
        RateLog {
            since: Instant::now(),
            frames: 0,
            view_updates: 0,
            last_shown: shown,
            simulated_frames,
        }
    }
}

/// What an action did this frame.
enum Step {
    Done,
    Pending,
    Failed(String),
}

impl GuiApp {
    /// Runs `script`, one action after the other, from the next frame on.
    pub fn run_script(&mut self, script: Script) {
        self.script = Some(ScriptRun {
            script,
            next: 0,
            started: None,
            screenshot: None,
            stats: None,
        });
    }

    /// Does what the script asks this frame; logs the rates if asked to.
    pub(super) fn advance_script(&mut self, ctx: &egui::Context) {
        let Some(mut run) = self.script.take() else {
            return;
        };
        if let Some(log) = &mut run.stats {
            // The simulation has not been polled yet this frame: its frame is the one the
            // previous window frame drew.
            let shown = self.shown_frame_number();
            log.frames += 1;
            if shown > log.last_shown {
                log.view_updates += 1;
            }
            log.last_shown = shown;
            // Frames as fast as the window can draw them, to measure it.
            ctx.request_repaint();
            let elapsed = log.since.elapsed();
            if elapsed >= STATS_PERIOD {
                let received = self.live.as_ref().map_or(0, |l| l.frames_received);
                let seconds = elapsed.as_secs_f64();
                let solver = self.live.as_ref().and_then(|l| l.solver);
                eprintln!(
                    "stats: {:.1} window frames/s, {:.1} view updates/s, {:.1} simulated frames/s{}",
                    log.frames as f64 / seconds,
                    log.view_updates as f64 / seconds,
                    (received - log.simulated_frames) as f64 / seconds,
                    solver.map_or(String::new(), |s| format!(
                        " (last cycle {:.0} ms + {:.0} ms to the scan, {:?}, {} cycles since the \
                         last change)",
                        s.advance.cycle.time_ms, s.frame_ms, s.advance.state, s.cycles
                    ))
                );
                *log = RateLog::new(received, shown);
            }
        }
        while let Some((line, action)) = run.script.actions.get(run.next).cloned() {
            match self.script_step(&mut run, &action, ctx) {
                Step::Done => {
                    run.next += 1;
                    run.started = None;
                    run.screenshot = None;
                }
                Step::Pending => {
                    ctx.request_repaint_after(POLL);
                    break;
                }
                Step::Failed(message) => {
                    eprintln!(
                        "error: {} line {line}: {action:?}: {message}",
                        run.script.path.display()
                    );
                    std::process::exit(1);
                }
            }
        }
        self.script = Some(run);
    }

    fn script_step(&mut self, run: &mut ScriptRun, action: &Action, ctx: &egui::Context) -> Step {
        let first = run.started.is_none();
        let started = *run.started.get_or_insert_with(Instant::now);
        match action {
            Action::Phantom => {
                self.open_phantom(true);
                self.step_outcome()
            }
            Action::Open(path) => {
                self.open(path);
                self.step_outcome()
            }
            Action::Elements(elements) => {
                self.settings.elements = *elements;
                Step::Done
            }
            Action::Build => self.build_step(first),
            Action::Implant(id) => {
                if self.catalog.get(id).is_none() {
                    return Step::Failed(format!("no catalog entry {id}"));
                }
                self.implants.edit(Editing::Linked);
                let design = self.implants.edited();
                design.enabled = true;
                design.choose(id, &self.catalog);
                Step::Done
            }
            Action::Custom {
                kind,
                width_mm,
                height_mm,
                projection_mm,
            } => {
                self.implants.edit(Editing::Linked);
                let design = self.implants.edited();
                design.enabled = true;
                design.source = Source::Custom;
                design.kind = *kind;
                design.width_mm = *width_mm;
                design.height_mm = *height_mm;
                design.projection_mm = *projection_mm;
                Step::Done
            }
            Action::Move(direction, times) => {
                for _ in 0..*times {
                    self.implants.step(*direction);
                }
                Step::Done
            }
            Action::DragProjection {
                from_mm,
                to_mm,
                seconds,
            } => self.drag_projection_step(*from_mm, *to_mm, *seconds, started, ctx),
            Action::Wait => self.wait_step(),
            Action::Register { scan, landmarks } => self.register_step(first, scan, landmarks),
            Action::Display(mode) => {
                self.display = *mode;
                Step::Done
            }
            Action::View(view) => {
                self.set_view(*view);
                Step::Done
            }
            Action::Up(up) => {
                self.set_up(*up);
                Step::Done
            }
            Action::ShowMuscle(show) => {
                if *show && self.muscle.is_none() {
                    return Step::Failed(
                        "the pectoralis major is shown once a model is built".into(),
                    );
                }
                self.show_muscle = *show;
                Step::Done
            }
            Action::Stats => {
                run.stats = Some(RateLog::new(
                    self.live.as_ref().map_or(0, |l| l.frames_received),
                    self.shown_frame_number(),
                ));
                Step::Done
            }
            Action::Screenshot(path) => screenshot_step(run, first, path, ctx),
            Action::SaveCase(path) => match self.case().and_then(|case| case.write(path)) {
                Ok(()) => Step::Done,
                Err(error) => Step::Failed(format!("{error:#}")),
            },
            Action::Quit => {
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                Step::Done
            }
        }
    }

    /// Builds the model (started on the `first` call) and waits for it.
    fn build_step(&mut self, first: bool) -> Step {
        if first && self.build.is_none() {
            self.start_build();
        }
        match (&self.build, self.error()) {
            (_, Some(error)) => Step::Failed(error.to_string()),
            (Some(_), None) => Step::Pending,
            (None, None) if self.model.is_some() => Step::Done,
            (None, None) => Step::Failed("the model was not built".into()),
        }
    }

    /// Moves the edited implant's projection from `from_mm` to `to_mm` over `seconds` since
    /// `started`, as a drag of its slider would.
    fn drag_projection_step(
        &mut self,
        from_mm: f64,
        to_mm: f64,
        seconds: f64,
        started: Instant,
        ctx: &egui::Context,
    ) -> Step {
        let design = self.implants.edited();
        if design.source == Source::Catalog
            && let Some(entry) = self.catalog.get(&design.catalog_id)
        {
            design.set_dimensions(entry.shape());
        }
        design.source = Source::Custom;
        let t = (started.elapsed().as_secs_f64() / seconds).min(1.0);
        design.projection_mm = from_mm + (to_mm - from_mm) * t;
        ctx.request_repaint();
        if t >= 1.0 { Step::Done } else { Step::Pending }
    }

    /// Waits for the live simulation to settle and its settled frame to be prepared.
    fn wait_step(&self) -> Step {
        match &self.live {
            // A case being opened builds its model first.
            None if self.build.is_some() => Step::Pending,
            None => Step::Failed("no model built".into()),
            Some(_) if self.implant_error.is_some() => {
                Step::Failed(self.implant_error.clone().unwrap_or_default())
            }
            // Settled, and the settled frame prepared (its deviation map).
            Some(live)
                if live.is_settled()
                    && !live.is_preparing_settled()
                    && live.settled.as_ref().map(|s| s.frame)
                        == live.frame.as_ref().map(|f| f.number) =>
            {
                match &live.failure {
                    Some(failure) => Step::Failed(failure.clone()),
                    None => Step::Done,
                }
            }
            Some(_) => Step::Pending,
        }
    }

    /// Registers the post-operative `scan` with its `landmarks` (started on the `first`
    /// call) and waits for the deviation map.
    fn register_step(&mut self, first: bool, scan: &Path, landmarks: &Path) -> Step {
        if first {
            self.postoperative.scan_text = scan.display().to_string();
            self.postoperative.landmarks_text = landmarks.display().to_string();
            self.start_registration();
        }
        let postoperative = &self.postoperative;
        match self.error() {
            Some(error) => Step::Failed(error.to_string()),
            None if postoperative.is_registering() || postoperative.is_comparing() => Step::Pending,
            None if postoperative.deviation().is_some() => Step::Done,
            None if let Some(failure) = postoperative.deviation_failure() => {
                Step::Failed(failure.to_string())
            }
            None if postoperative.registered.is_some() => Step::Pending,
            None => Step::Failed("the scan was not registered".into()),
        }
    }

    /// Done, or failed with the status line's error.
    fn step_outcome(&self) -> Step {
        match self.error() {
            Some(error) => Step::Failed(error.to_string()),
            None => Step::Done,
        }
    }
}

/// Asks egui for a screenshot (on the `first` call) and waits for it to be saved at `path`.
fn screenshot_step(run: &mut ScriptRun, first: bool, path: &Path, ctx: &egui::Context) -> Step {
    match &run.screenshot {
        None if first => {
            let outcome = Arc::new(Mutex::new(None));
            let slot = Arc::clone(&outcome);
            let path = path.to_path_buf();
            let waker = ctx.clone();
            ctx.request_screenshot(move |image| {
                let saved = save_png(&path, &image);
                if let Ok(mut slot) = slot.lock() {
                    *slot = Some(saved);
                }
                waker.request_repaint();
            });
            run.screenshot = Some(outcome);
            Step::Pending
        }
        None => Step::Failed("the screenshot was lost".into()),
        Some(outcome) => match outcome.lock().ok().and_then(|mut o| o.take()) {
            None => Step::Pending,
            Some(Ok(())) => Step::Done,
            Some(Err(message)) => Step::Failed(message),
        },
    }
}

/// Writes an RGBA image as PNG, atomically.
fn save_png(path: &Path, image: &egui::ColorImage) -> Result<(), String> {
    use image::ImageEncoder;
    let [width, height] = image.size;
    mesh::io::write_atomically(path, |w| {
        image::codecs::png::PngEncoder::new(w)
            .write_image(
                image.as_raw(),
                width as u32,
                height as u32,
                image::ExtendedColorType::Rgba8,
            )
            .map_err(std::io::Error::other)
    })
    .map_err(|error| format!("writing the screenshot: {error}"))
}
