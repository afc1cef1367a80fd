//! The live simulation: a worker thread owns `plan`'s simulation [`Session`]; the window
//! sends it the implants it wants (every frame in which they changed) and never waits.
//! The worker applies the newest set when several are queued (a slider being dragged),
//! runs one cycle at a time ([`Session::advance`]: the implant stage, then the gravity
//! correction) and after a cycle sends back the scan as simulated so far, ready to
//! draw, with the landmarks moved with it and the solver's figures; the window takes the
//! newest when it draws and never waits. A cycle that ends while the window has not yet
//! taken the frame sent before sends nothing: its frame would never be drawn. When the
//! window draws on the processor too (a software renderer, on two cores here), the solver
//! also keeps at most one cycle ahead of the window: such a cycle waits (at most
//! [`WINDOW_WAIT`]) and sends its frame once the window has taken the one before, so the
//! solver does not take the processor from the window for cycles that would never be
//! drawn, and every window frame still finds a newer frame ready. With a GPU the solver
//! cycles freely (its cores are not the window's). Measuring and
//! exporting the prediction run on the worker too, between cycles, and so does writing
//! the folders a report is made from (the report itself is then written on a thread of
//! its own, from those files). Once the solver has
//! settled on a frame, a background job prepares that frame's simulated scan for queries
//! and its deviation from the pre-operative scan ([`SettledSimulation`]).

use crate::carried::{SurfaceAnchor, anchors};
use crate::deviation::DeviationMap;
use crate::job::Job;
use crate::render::{InteractionMesh, SceneMesh};
use anatomy::Landmarks;
use anatomy::breast::Side;
use glam::DVec3;
use plan::model::PerSide;
use plan::report::{PendingReport, PostoperativeScan, ReportSummary};
use plan::simulate::{
    Advance, ImplantRequest, ImplantSummary, Session, SimulatedMeasurements, SimulationState,
    SolveState, SolverReport, Stage,
};
use plan::{Scan, Silent};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::{Duration, Instant};

/// Points of an implant's footprint outline drawn on the scan.
const OUTLINE_SEGMENTS: usize = 64;
/// The longest the solver waits for the window to take its last frame (a window that
/// draws nothing, minimised say, holds the solve back no longer than this per cycle).
const WINDOW_WAIT: Duration = Duration::from_millis(250);
/// How often the waiting solver looks whether the window has taken its frame.
const WINDOW_POLL: Duration = Duration::from_millis(2);
/// Share of the scan's triangles in the [`InteractionMesh`] drawn while the solver runs
/// with a software renderer.
pub const INTERACTION_TRIANGLE_SHARE: f64 = 0.125;
/// The limit on the simplifier's own estimate of how far the interaction mesh's surface
/// lies from the scan's (mm): it stops short of [`INTERACTION_TRIANGLE_SHARE`] rather than
/// exceed it (on the phantom the share decides, estimate 0.08 mm; on the shared scan
/// `v02_average` the limit, at 14% of the triangles). Measured on the scan's vertices: at
/// most 0.34 mm from its surface on the phantom and 0.84 mm on `v02_average`, 0.03 and
/// 0.14 mm on average, about a pixel at the viewport's default zoom at most
/// (`tests/interaction_mesh.rs`).
pub const INTERACTION_ERROR_MM: f64 = 0.5;

/// The implants wanted on both sides, and whether the gravity correction follows.
#[derive(Debug, Clone, PartialEq)]
pub struct ImplantSet {
    pub implants: PerSide<Option<ImplantRequest>>,
    pub gravity: bool,
}

impl ImplantSet {
    /// `request` on both sides.
    pub fn both_sides(request: &ImplantRequest, gravity: bool) -> ImplantSet {
        ImplantSet {
            implants: PerSide::from_fn(|_| Some(request.clone())),
            gravity,
        }
    }
}

/// Where [`LiveSimulation::export`] writes.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportPaths {
    /// The simulated scan (PLY, the scan's vertex order).
    pub scan: PathBuf,
    pub measurements_csv: PathBuf,
    pub measurements_json: PathBuf,
}

impl ExportPaths {
    /// `simulated_scan.ply`, `measurements.csv` and `measurements.json` in `folder`.
    pub fn in_folder(folder: &std::path::Path) -> ExportPaths {
        ExportPaths {
            scan: folder.join("simulated_scan.ply"),
            measurements_csv: folder.join("measurements.csv"),
            measurements_json: folder.join("measurements.json"),
        }
    }
}

enum Command {
    /// Numbered in the order sent.
    Implants(u64, ImplantSet),
    Measure,
    Export(ExportPaths),
    /// The folders of a report into this folder.
    ReportFolders(PathBuf, Option<PostoperativeScan>),
}

/// The report written from the window (`report.html` with the folders it is made from).
#[derive(Default)]
pub enum ReportState {
    #[default]
    NotYet,
    /// The session's scan, model and simulation folders are being written into this
    /// folder (on the worker, between cycles).
    WritingFolders(PathBuf),
    /// The report is being written from them (on a thread of its own).
    Writing(PathBuf, Job<anyhow::Result<ReportSummary>>),
    /// How the last report ended.
    Written(Result<ReportSummary, String>),
}

/// One side of the session.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SideState {
    /// The implant in the session (the last one that could be placed).
    pub placed: Option<ImplantSummary>,
    /// Why the last request for this side was refused (the session kept `placed`).
    pub error: Option<String>,
    /// The outline of the implant's footprint on the scan as loaded, to be carried onto
    /// the simulated frames (empty without an implant).
    pub outline: Vec<SurfaceAnchor>,
    /// The outline of the pocket the implant lies in, likewise (empty without an
    /// implant or where it lies on the fill-in's bed).
    pub pocket_outline: Vec<SurfaceAnchor>,
}

/// The solver's figures after the latest cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverStatus {
    /// The number of the implant set being solved (see [`LiveSimulation::set_implants`]).
    pub set_number: u64,
    /// Cycles since the implants last changed.
    pub cycles: usize,
    pub advance: Advance,
    /// Time to carry the cycle's displacement to the scan and build the frame's vertices
    /// and normals (ms), after the cycle's own time.
    pub frame_ms: f64,
}

impl SolverStatus {
    /// The stage the latest cycle ran.
    pub fn stage(&self) -> Stage {
        self.advance.cycle.stage
    }
}

/// The simulated scan after a cycle.
#[derive(Clone)]
pub struct SimulatedFrame {
    /// Every scan vertex (mm, file frame, the scan's order).
    pub positions: Arc<Vec<DVec3>>,
    pub scene: Arc<SceneMesh>,
    /// For a frame drawn on the interaction mesh (a running solve's, with a software
    /// renderer): the pre-operative scan drawn on the same mesh, so that an overlay of
    /// the two lies on the same triangles where the skin did not move.
    pub pre_operative: Option<Arc<SceneMesh>>,
    /// The landmarks (required and extra) moved with the tissue.
    pub landmarks: Arc<Landmarks>,
    /// Counts the frames of this session, from 1.
    pub number: u64,
}

/// The simulated scan of a frame the solver has settled on, prepared in the background.
pub struct SettledSimulation {
    /// The frame's number.
    pub frame: u64,
    /// The simulated scan with its spatial index (what hides what in the view; the
    /// reference a post-operative scan can be compared with).
    pub scan: Arc<Scan>,
    /// Its deviation from the pre-operative scan.
    pub deviation: Result<DeviationMap, String>,
}

/// A callback that asks the window for a repaint.
pub type Wake = Arc<dyn Fn() + Send + Sync>;

/// The measurements of the prediction.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum MeasurementState {
    #[default]
    NotYet,
    Measuring,
    /// The figures and the frame number they were measured at.
    Measured(Box<SimulatedMeasurements>, u64),
    Failed(String),
}

enum Update {
    /// The outcome of implant set `number`, and whether it restarted the solve (a set
    /// that changes nothing leaves the solve as it is).
    Implants(u64, Box<PerSide<SideState>>, bool),
    Cycle(SimulatedFrame, SolverStatus),
    Measured(Result<(SimulatedMeasurements, u64), String>),
    Exported(Result<ExportPaths, String>),
    ReportFolders(Result<PendingReport, String>),
    Failed(String),
}

/// The window's handle on the worker.
pub struct LiveSimulation {
    commands: Sender<Command>,
    updates: Receiver<Update>,
    /// The last implant set sent, and its number.
    sent: Option<ImplantSet>,
    sent_number: u64,
    /// The number of the last set the worker has applied.
    applied_number: u64,
    /// The latest simulated scan, if a cycle has run.
    pub frame: Option<SimulatedFrame>,
    pub solver: Option<SolverStatus>,
    pub sides: PerSide<SideState>,
    pub measurements: MeasurementState,
    /// The outcome of the last export.
    pub exported: Option<Result<ExportPaths, String>>,
    /// The report being written, or the last one.
    pub report: ReportState,
    /// A solver failure (the worker waits for the next change).
    pub failure: Option<String>,
    /// Simulated frames received so far.
    pub frames_received: u64,
    /// The number of the latest frame taken (shared with the worker).
    taken: Arc<AtomicU64>,
    /// The latest settled frame, prepared ([`LiveSimulation::poll`] starts the work).
    pub settled: Option<Arc<SettledSimulation>>,
    /// The preparation under way, and its frame's number.
    settling: Option<(u64, Job<anyhow::Result<SettledSimulation>>)>,
    /// The scan as loaded, which the session simulates.
    pre_operative: Arc<Scan>,
    wake: Wake,
}

impl LiveSimulation {
    /// Hands the session to a new worker; `scene` is the scan as drawn (the simulated
    /// frames reuse its triangles and colours); with `keep_to_window` the solver keeps at
    /// most one cycle ahead of the frames the window has taken (for a window that draws
    /// on the processor, see the module's documentation); `wake` is called after every
    /// update (the window asks for a repaint there).
    pub fn start(
        session: Session,
        scene: Arc<SceneMesh>,
        keep_to_window: bool,
        wake: impl Fn() + Send + Sync + 'static,
    ) -> LiveSimulation {
        let (commands, inbox) = channel();
        let (outbox, updates) = channel();
        let wake: Wake = Arc::new(wake);
        let pre_operative = Arc::clone(&session.marked.scan);
        let worker_wake = Arc::clone(&wake);
        let taken = Arc::new(AtomicU64::new(0));
        let worker_taken = Arc::clone(&taken);
        std::thread::spawn(move || {
            let wake = move || worker_wake();
            Worker::new(session, scene, outbox, worker_taken, keep_to_window, wake).run(&inbox)
        });
        LiveSimulation {
            commands,
            updates,
            sent: None,
            sent_number: 0,
            applied_number: 0,
            frame: None,
            solver: None,
            sides: PerSide::default(),
            measurements: MeasurementState::NotYet,
            exported: None,
            report: ReportState::NotYet,
            failure: None,
            frames_received: 0,
            taken,
            settled: None,
            settling: None,
            pre_operative,
            wake,
        }
    }

    /// Asks for `set` unless it is the set sent last.
    pub fn set_implants(&mut self, set: &ImplantSet) {
        if self.sent.as_ref() == Some(set) {
            return;
        }
        self.sent_number += 1;
        self.sent = Some(set.clone());
        // A failed send means the worker is gone; `failure` says why.
        let _ = self
            .commands
            .send(Command::Implants(self.sent_number, set.clone()));
    }

    /// Asks for the measurements of the current prediction.
    pub fn measure(&mut self) {
        self.measurements = MeasurementState::Measuring;
        let _ = self.commands.send(Command::Measure);
    }

    /// Asks for the simulated scan and the measurements to be written.
    pub fn export(&mut self, paths: ExportPaths) {
        self.exported = None;
        let _ = self.commands.send(Command::Export(paths));
    }

    /// Asks for the report of the current prediction: `report.html` in `folder` with the
    /// folders it is made from (see [`plan::report::write_session_folders`]), compared
    /// with `postoperative` when given.
    pub fn write_report(&mut self, folder: PathBuf, postoperative: Option<PostoperativeScan>) {
        self.report = ReportState::WritingFolders(folder.clone());
        let _ = self
            .commands
            .send(Command::ReportFolders(folder, postoperative));
    }

    /// Whether a report is being written.
    pub fn is_writing_report(&self) -> bool {
        matches!(
            self.report,
            ReportState::WritingFolders(_) | ReportState::Writing(..)
        )
    }

    /// Takes the worker's updates.
    pub fn poll(&mut self) {
        while let Ok(update) = self.updates.try_recv() {
            match update {
                Update::Implants(number, sides, restarted) => {
                    self.applied_number = number;
                    self.sides = *sides;
                    if let (false, Some(solver)) = (restarted, &mut self.solver) {
                        solver.set_number = number;
                    }
                    self.failure = None;
                }
                Update::Cycle(frame, solver) => {
                    self.taken.store(frame.number, Ordering::Relaxed);
                    self.frame = Some(frame);
                    self.solver = Some(solver);
                    self.frames_received += 1;
                }
                Update::Measured(Ok((measurements, frame))) => {
                    self.measurements = MeasurementState::Measured(Box::new(measurements), frame);
                }
                Update::Measured(Err(message)) => {
                    self.measurements = MeasurementState::Failed(message);
                }
                Update::Exported(outcome) => self.exported = Some(outcome),
                Update::ReportFolders(Ok(pending)) => {
                    let out = pending.out();
                    let job = Job::spawn(self.waker(), move || pending.write(&Silent));
                    self.report = ReportState::Writing(out, job);
                }
                Update::ReportFolders(Err(message)) => {
                    self.report = ReportState::Written(Err(message));
                }
                Update::Failed(message) => self.failure = Some(message),
            }
        }
        if let ReportState::Writing(_, job) = &self.report
            && let Some(answer) = job.poll()
        {
            let written = answer.and_then(|result| result.map_err(|error| format!("{error:#}")));
            self.report = ReportState::Written(written);
        }
        self.prepare_settled();
    }

    /// A repaint request for a background job's end.
    fn waker(&self) -> impl Fn() + Send + 'static {
        let wake = Arc::clone(&self.wake);
        move || wake()
    }

    /// Takes the settled frame once prepared, and starts preparing the newest frame once
    /// the solver has settled on it (one preparation at a time).
    fn prepare_settled(&mut self) {
        if let Some((number, job)) = &self.settling
            && let Some(answer) = job.poll()
        {
            let number = *number;
            self.settling = None;
            let settled = answer
                .and_then(|prepared| prepared.map_err(|error| format!("{error:#}")))
                .unwrap_or_else(|message| SettledSimulation {
                    frame: number,
                    scan: Arc::clone(&self.pre_operative),
                    deviation: Err(message),
                });
            self.settled = Some(Arc::new(settled));
        }
        let Some(frame) = &self.frame else {
            return;
        };
        let prepared = self.settled.as_ref().map(|s| s.frame);
        if self.settling.is_some() || !self.is_settled() || prepared == Some(frame.number) {
            return;
        }
        let pre_operative = Arc::clone(&self.pre_operative);
        let frame = frame.clone();
        let job = Job::spawn(
            self.waker(),
            move || -> anyhow::Result<SettledSimulation> {
                let scan = pre_operative
                    .moved_to(frame.positions.to_vec(), Path::new("the simulated scan"))?;
                let deviation = DeviationMap::compute(&pre_operative, &scan, &frame.scene)
                    .map_err(|error| format!("{error:#}"));
                Ok(SettledSimulation {
                    frame: frame.number,
                    scan: Arc::new(scan),
                    deviation,
                })
            },
        );
        self.settling = Some((frame.number, job));
    }

    /// Whether the settled frame is being prepared.
    pub fn is_preparing_settled(&self) -> bool {
        self.settling.is_some()
    }

    /// Whether the worker has applied the last set sent and stopped cycling on it
    /// (converged, out of cycles or failed).
    pub fn is_settled(&self) -> bool {
        self.applied_number == self.sent_number
            && (self.failure.is_some()
                || self.solver.is_some_and(|s| {
                    s.set_number == self.sent_number && s.advance.state != SolveState::Running
                }))
    }
}

/// The worker's state.
struct Worker<W> {
    session: Session,
    scene: Arc<SceneMesh>,
    /// The scan with the simulated positions (for normals).
    moved: mesh::TriMesh,
    /// With a software renderer: what a running solve's frames are drawn on.
    preview: Option<Preview>,
    outbox: Sender<Update>,
    /// The number of the latest frame the window has taken.
    taken: Arc<AtomicU64>,
    wake: W,
    /// The set last applied (some sides may have been refused).
    applied: Option<ImplantSet>,
    sides: PerSide<SideState>,
    running: bool,
    cycles: usize,
    /// The solve since the implants last changed, as a simulation folder records it.
    solve: SolverReport,
    frame: u64,
    /// The number of the latest frame sent.
    sent_frame: u64,
    /// The last cycle, if its frame has not been sent (the window had yet to take the
    /// one before) and is to be sent once the window has.
    unsent: Option<Advance>,
    /// Whether the solver keeps at most one cycle ahead of the window.
    keep_to_window: bool,
    /// The cycle of the last frame sent if that frame was a preview (drawn on the
    /// interaction mesh): a solve that fails then sends that cycle's full frame.
    preview_shown: Option<Advance>,
    /// The number of the implant set last applied.
    set_number: u64,
    /// The map to the scan being composed beside the solver; the two-step carry serves
    /// until it arrives.
    scan_carry: Option<Receiver<plan::simulate::ScanCarry>>,
}

impl<W: Fn()> Worker<W> {
    fn new(
        session: Session,
        scene: Arc<SceneMesh>,
        outbox: Sender<Update>,
        taken: Arc<AtomicU64>,
        keep_to_window: bool,
        wake: W,
    ) -> Self {
        let preview = keep_to_window.then(|| Preview::new(&session.marked.scan.mesh, &scene));
        let compose = session.simulation.scan_carry_job();
        let (composed, scan_carry) = std::sync::mpsc::channel();
        let scan_carry = std::thread::Builder::new()
            .name("scan carry".into())
            .spawn(move || composed.send(compose()))
            .is_ok()
            .then_some(scan_carry);
        Worker {
            moved: session.marked.scan.mesh.clone(),
            preview,
            session,
            scene,
            outbox,
            taken,
            wake,
            applied: None,
            sides: PerSide::default(),
            running: false,
            cycles: 0,
            solve: new_solve(),
            frame: 0,
            sent_frame: 0,
            unsent: None,
            keep_to_window,
            preview_shown: None,
            set_number: 0,
            scan_carry,
        }
    }

    /// Switches to the composed map to the scan once it has arrived.
    fn take_scan_carry(&mut self) {
        if let Some(composed) = &self.scan_carry
            && let Ok(carry) = composed.try_recv()
        {
            self.session.simulation.use_scan_carry(carry);
            self.scan_carry = None;
        }
    }

    /// Serves commands until the window drops its handle.
    fn run(mut self, inbox: &Receiver<Command>) {
        loop {
            self.take_scan_carry();
            if let Some(advance) = self.unsent.take() {
                let start = Instant::now();
                while self.window_behind() && start.elapsed() < WINDOW_WAIT {
                    std::thread::sleep(WINDOW_POLL);
                }
                if !self.send_frame(advance) {
                    return;
                }
            }
            let mut commands = Vec::new();
            if !self.running {
                match inbox.recv() {
                    Ok(command) => commands.push(command),
                    Err(_) => return,
                }
            }
            while let Ok(command) = inbox.try_recv() {
                commands.push(command);
            }
            // The newest implant set replaces the older ones still queued; measuring and
            // exporting then see it.
            let newest = commands
                .iter()
                .rposition(|c| matches!(c, Command::Implants(..)));
            for (k, command) in commands.into_iter().enumerate() {
                let sent = match command {
                    Command::Implants(number, set) if Some(k) == newest => {
                        let restarted = self.apply(&set);
                        self.set_number = number;
                        let sides = Box::new(self.sides.clone());
                        self.outbox.send(Update::Implants(number, sides, restarted))
                    }
                    Command::Implants(..) => Ok(()),
                    Command::Measure => {
                        let measured = self.measure();
                        self.outbox.send(Update::Measured(measured))
                    }
                    Command::Export(paths) => {
                        let outcome = self.export(&paths).map(|()| paths);
                        self.outbox.send(Update::Exported(outcome))
                    }
                    Command::ReportFolders(folder, postoperative) => {
                        let outcome = self.report_folders(&folder, postoperative);
                        self.outbox.send(Update::ReportFolders(outcome))
                    }
                };
                if sent.is_err() {
                    return;
                }
                (self.wake)();
            }
            if self.running && !self.cycle() {
                return;
            }
        }
    }

    /// Places or removes the implants that changed; restarts the solve if any did (and
    /// says so).
    fn apply(&mut self, set: &ImplantSet) -> bool {
        let gravity_changed = self
            .applied
            .as_ref()
            .is_some_and(|a| a.gravity != set.gravity);
        let mut changed = false;
        for side in Side::BOTH {
            let wanted = set.implants.get(side);
            let before = self.applied.as_ref().map(|a| a.implants.get(side));
            if before == Some(wanted) && !gravity_changed {
                continue;
            }
            let state = self.sides.get_mut(side);
            match wanted {
                Some(request) => match self.session.place(side, request) {
                    Ok(placed) => {
                        state.placed = Some(placed);
                        state.error = None;
                        changed = true;
                    }
                    Err(error) => state.error = Some(format!("{error:#}")),
                },
                None => {
                    self.session.remove_implant(side);
                    changed |= state.placed.take().is_some();
                    state.error = None;
                }
            }
        }
        self.applied = Some(set.clone());
        for side in Side::BOTH {
            let outline = self
                .session
                .implant_outline_on_scan(side, OUTLINE_SEGMENTS)
                .unwrap_or_default();
            let pocket = self
                .session
                .pocket_outline_on_scan(side)
                .unwrap_or_default();
            let index = &self.session.marked.scan.index;
            let state = self.sides.get_mut(side);
            state.outline = anchors(index, &outline);
            state.pocket_outline = anchors(index, &pocket);
        }
        let restart = changed || gravity_changed || self.frame == 0;
        if restart {
            self.running = true;
            self.cycles = 0;
            self.solve = new_solve();
        }
        restart
    }

    /// Whether the window has yet to take the last frame sent.
    fn window_behind(&self) -> bool {
        self.taken.load(Ordering::Relaxed) < self.sent_frame
    }

    /// One cycle, and its frame unless the window has yet to take the frame before and
    /// the solve goes on (then the frame waits in `unsent`); `false` once the window is
    /// gone.
    fn cycle(&mut self) -> bool {
        let gravity = self.applied.as_ref().is_some_and(|a| a.gravity);
        match self.session.advance(!gravity) {
            Ok(advance) => {
                self.cycles += 1;
                self.frame += 1;
                self.running = advance.state == SolveState::Running;
                self.tally(&advance);
                if self.running && self.window_behind() {
                    if self.keep_to_window {
                        self.unsent = Some(advance);
                    }
                    true
                } else {
                    self.send_frame(advance)
                }
            }
            Err(error) => {
                self.running = false;
                // the window keeps the last frame: the full scan, not a preview
                if let Some(advance) = self.preview_shown.take()
                    && !self.send_full_frame_after(advance)
                {
                    return false;
                }
                let failed = Update::Failed(format!("the simulation failed: {error:#}"));
                let sent = self.outbox.send(failed).is_ok();
                (self.wake)();
                sent
            }
        }
    }

    /// Sends the full frame of the cycle `advance`, whose preview was the last frame
    /// sent, as a frame of its own; `false` once the window is gone.
    fn send_full_frame_after(&mut self, advance: Advance) -> bool {
        self.frame += 1;
        self.send_frame(Advance {
            state: SolveState::Stopped,
            ..advance
        })
    }

    /// Sends the simulated scan as it is after the cycle `advance` (drawn on the
    /// interaction mesh while the solve runs, if there is one); `false` once the window
    /// is gone.
    fn send_frame(&mut self, advance: Advance) -> bool {
        self.sent_frame = self.frame;
        let start = Instant::now();
        let simulation = &self.session.simulation;
        let displacements = simulation.scan_displacements();
        let positions: Vec<DVec3> = (self.session.marked.scan.mesh.positions.iter())
            .zip(&displacements)
            .map(|(p, d)| *p + *d)
            .collect();
        let preview = (self.preview.as_mut()).filter(|_| advance.state == SolveState::Running);
        self.preview_shown = preview.is_some().then_some(advance);
        let (scene, pre_operative) = match preview {
            Some(preview) => (
                preview.frame(&self.scene, &positions),
                Some(Arc::clone(&preview.pre_operative)),
            ),
            None => {
                self.moved.positions.clone_from(&positions);
                (self.scene.moved(&self.moved), None)
            }
        };
        let frame = SimulatedFrame {
            positions: Arc::new(positions),
            scene: Arc::new(scene),
            pre_operative,
            landmarks: Arc::new(simulation.landmarks_moved_by(&displacements)),
            number: self.frame,
        };
        let status = SolverStatus {
            set_number: self.set_number,
            cycles: self.cycles,
            advance,
            frame_ms: start.elapsed().as_secs_f64() * 1e3,
        };
        let update = Update::Cycle(frame, status);
        let sent = self.outbox.send(update).is_ok();
        (self.wake)();
        sent
    }

    /// Counts a cycle into the solve's figures.
    fn tally(&mut self, advance: &Advance) {
        let solve = &mut self.solve;
        solve.vcycles += 1;
        solve.time_ms += advance.cycle.time_ms;
        solve.relative_residual = advance.cycle.relative_residual;
        solve.converged = advance.state == SolveState::Converged;
        match advance.cycle.stage {
            Stage::Implant => solve.implant_stage_vcycles = advance.stage_cycles,
            Stage::Gravity => solve.gravity_stage_vcycles = Some(advance.stage_cycles),
        }
    }

    /// Writes the scan, model and simulation folders of a report into `folder`.
    fn report_folders(
        &mut self,
        folder: &std::path::Path,
        postoperative: Option<PostoperativeScan>,
    ) -> Result<PendingReport, String> {
        let state = SimulationState {
            implants: PerSide::from_fn(|side| self.sides.get(side).placed.clone()),
            solver: SolverReport {
                inverted_elements: self.session.simulation.inverted_elements().len(),
                ..self.solve.clone()
            },
            no_gravity: !self.applied.as_ref().is_some_and(|a| a.gravity),
        };
        plan::report::write_session_folders(
            &mut self.session,
            &state,
            folder,
            postoperative,
            &Silent,
        )
        .map_err(|error| {
            format!(
                "writing the report's files into {}: {error:#}",
                folder.display()
            )
        })
    }

    fn measure(&mut self) -> Result<(SimulatedMeasurements, u64), String> {
        self.session
            .measurements(&Silent)
            .map(|m| (m, self.frame))
            .map_err(|error| format!("measuring the prediction: {error:#}"))
    }

    /// Writes the simulated scan and the measurements (each file atomically).
    fn export(&mut self, paths: &ExportPaths) -> Result<(), String> {
        let (measurements, _) = self.measure()?;
        let simulated = self
            .session
            .simulated_scan(&paths.scan)
            .map_err(|error| format!("{error:#}"))?;
        mesh::io::write_mesh(&paths.scan, &simulated.scan.mesh)
            .map_err(|error| format!("{error:#}"))?;
        measurements
            .write_csv(&paths.measurements_csv)
            .and_then(|()| measurements.write_json(&paths.measurements_json))
            .map_err(|error| format!("{error:#}"))?;
        // The export measured the current prediction: show it too.
        let _ = self
            .outbox
            .send(Update::Measured(Ok((measurements, self.frame))));
        Ok(())
    }
}

/// What a running solve's frames are drawn on with a software renderer.
struct Preview {
    coarse: InteractionMesh,
    /// The interaction mesh at the frame's positions (for normals).
    moved: mesh::TriMesh,
    /// The pre-operative scan drawn on the interaction mesh.
    pre_operative: Arc<SceneMesh>,
}

impl Preview {
    fn new(scan: &mesh::TriMesh, scene: &SceneMesh) -> Preview {
        let coarse =
            InteractionMesh::simplify(scene, INTERACTION_TRIANGLE_SHARE, INTERACTION_ERROR_MM);
        let positions = (coarse.scan_vertices().iter())
            .map(|&v| scan.positions[v as usize])
            .collect();
        let moved = mesh::TriMesh::new(positions, coarse.triangles());
        let pre_operative = Arc::new(scene.coarse_moved(&coarse, &moved));
        Preview {
            coarse,
            moved,
            pre_operative,
        }
    }

    /// The frame of the scan at `positions` (mm, every scan vertex).
    fn frame(&mut self, scene: &SceneMesh, positions: &[DVec3]) -> SceneMesh {
        for (p, &v) in (self.moved.positions.iter_mut()).zip(self.coarse.scan_vertices()) {
            *p = positions[v as usize];
        }
        scene.coarse_moved(&self.coarse, &self.moved)
    }
}

/// The figures of a solve that has not run a cycle yet.
fn new_solve() -> SolverReport {
    SolverReport {
        vcycles: 0,
        relative_residual: f64::NAN,
        converged: false,
        time_ms: 0.0,
        implant_stage_vcycles: 0,
        gravity_stage_vcycles: None,
        inverted_elements: 0,
    }
}
