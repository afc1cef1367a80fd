//! The clinical distance table, kept up to date on a worker thread so the window never
//! waits for geodesics. The worker prepares the scan once (`plan`'s
//! [`MeasuringSurface`]: holes closed) and then measures the latest landmark set it was
//! sent, skipping sets that were superseded while it worked.

use anatomy::measure::{DistanceSpec, clinical_distances};
use anatomy::{PartialLandmarks, Up};
use plan::measure::MeasuringSurface;
use plan::{Distance, Scan, Silent};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};

/// The table as last measured.
#[derive(Debug, Clone, PartialEq)]
pub enum Table {
    /// The worker is closing the scan's holes or has not answered yet.
    Preparing,
    /// Pj, Px, Pcl and Pcr are needed for the coronal plane of the surface distance.
    NeedFrame,
    /// The distances whose two points are placed (mm).
    Measured(Vec<Distance>),
    /// Something went wrong (the message says what).
    Failed(String),
}

/// The handle the UI keeps: send landmark sets, poll for tables.
pub struct LiveDistances {
    requests: Sender<(u64, PartialLandmarks)>,
    answers: Receiver<(u64, Table)>,
    /// Number of the last set sent.
    sent: u64,
    /// Number of the set the current table belongs to.
    answered: u64,
    table: Table,
}

impl LiveDistances {
    /// Starts the worker for a scan; `wake` is called after each answer (the UI asks
    /// for a repaint there).
    /// `up` is the scan's up as given (`None`: resolved from the file and landmarks).
    pub fn start(
        scan: Arc<Scan>,
        up: Option<Up>,
        wake: impl Fn() + Send + 'static,
    ) -> LiveDistances {
        let (requests, inbox) = channel::<(u64, PartialLandmarks)>();
        let (outbox, answers) = channel();
        std::thread::spawn(move || {
            let surface = MeasuringSurface::new(&scan, &Silent);
            // Ends when the UI drops its handle (a new scan, or the window closed).
            while let Ok(mut request) = inbox.recv() {
                while let Ok(newer) = inbox.try_recv() {
                    request = newer;
                }
                let (number, landmarks) = request;
                let table = match &surface {
                    Ok(surface) => measure(surface, &landmarks, up),
                    Err(error) => Table::Failed(format!("{error:#}")),
                };
                if outbox.send((number, table)).is_err() {
                    break;
                }
                wake();
            }
        });
        LiveDistances {
            requests,
            answers,
            sent: 0,
            answered: 0,
            table: Table::Preparing,
        }
    }

    /// Asks for the table of a changed landmark set.
    pub fn update(&mut self, landmarks: &PartialLandmarks) {
        self.sent += 1;
        // A failed send means the worker is gone; `poll` then keeps the last table.
        let _ = self.requests.send((self.sent, landmarks.clone()));
    }

    /// Takes the worker's answers; the latest table.
    pub fn poll(&mut self) -> &Table {
        while let Ok((number, table)) = self.answers.try_recv() {
            self.answered = number;
            self.table = table;
        }
        &self.table
    }

    /// Whether the table is older than the last set sent.
    pub fn is_stale(&self) -> bool {
        self.answered < self.sent
    }
}

/// The clinical distances whose points are both placed, measured.
fn measure(surface: &MeasuringSurface, landmarks: &PartialLandmarks, up: Option<Up>) -> Table {
    let Some(frame) = landmarks.frame(up) else {
        return Table::NeedFrame;
    };
    let frame = match frame {
        Ok(frame) => frame,
        Err(error) => return Table::Failed(error.to_string()),
    };
    let specs: Vec<DistanceSpec> = clinical_distances()
        .into_iter()
        .filter(|s| landmarks.lookup(&s.from).is_some() && landmarks.lookup(&s.to).is_some())
        .collect();
    match surface.distances(&frame, landmarks, &specs) {
        Ok(distances) => Table::Measured(distances),
        Err(error) => Table::Failed(error.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use anatomy::LandmarkName;
    use plan::{MarkedScan, PhantomParams};
    use std::time::{Duration, Instant};

    /// Polls until the table answers the last set sent (at most a minute).
    fn wait(live: &mut LiveDistances) -> Table {
        let start = Instant::now();
        while *live.poll() == Table::Preparing || live.is_stale() {
            assert!(start.elapsed() < Duration::from_secs(60), "no answer");
            std::thread::sleep(Duration::from_millis(20));
        }
        live.poll().clone()
    }

    #[test]
    fn the_worker_measures_the_pairs_that_are_placed() {
        let marked = MarkedScan::phantom(&PhantomParams::default()).unwrap();
        let full = PartialLandmarks::from(&marked.landmarks);
        let mut live = LiveDistances::start(marked.scan, None, || {});
        assert_eq!(*live.poll(), Table::Preparing);

        let mut partial = PartialLandmarks::default();
        partial.set(LandmarkName::Pnl, full.get(LandmarkName::Pnl).unwrap());
        live.update(&partial);
        assert_eq!(wait(&mut live), Table::NeedFrame);

        // Several sets in a row: the answer is the last one's.
        for name in [LandmarkName::Pj, LandmarkName::Px, LandmarkName::Pcl] {
            partial.set(name, full.get(name).unwrap());
            live.update(&partial);
        }
        partial.set(LandmarkName::Pcr, full.get(LandmarkName::Pcr).unwrap());
        live.update(&partial);
        let Table::Measured(distances) = wait(&mut live) else {
            panic!("expected distances");
        };
        let names: Vec<&str> = distances.iter().map(|d| d.name.as_str()).collect();
        assert_eq!(names, ["Pcl-Pnl", "Pj-Pnl"]);

        live.update(&full);
        let Table::Measured(distances) = wait(&mut live) else {
            panic!("expected distances");
        };
        assert_eq!(distances.len(), 11);
        assert!(distances.iter().all(|d| d.geodesic_mm.is_some()));
    }
}
