//! One piece of work on a background thread (a registration, a deviation map, a
//! report): the window starts it, goes on drawing, and picks the answer up when it is
//! there. The thread calls `wake` when done, so the window repaints then.

use std::sync::mpsc::{Receiver, TryRecvError, channel};

/// Work under way on its own thread.
pub struct Job<T> {
    answer: Receiver<T>,
}

impl<T: Send + 'static> Job<T> {
    /// Runs `work` on a new thread; `wake` is called once it has answered.
    pub fn spawn(
        wake: impl Fn() + Send + 'static,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Job<T> {
        let (sender, answer) = channel();
        std::thread::spawn(move || {
            // The window may have dropped the job (a newer one replaced it): nobody to tell.
            let _ = sender.send(work());
            wake();
        });
        Job { answer }
    }

    /// The answer once the work is done; an error if the thread ended without one (it
    /// panicked). Call until it gives `Some`, then drop the job.
    pub fn poll(&self) -> Option<Result<T, String>> {
        match self.answer.try_recv() {
            Ok(answer) => Some(Ok(answer)),
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => {
                Some(Err("the background work stopped unexpectedly".into()))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};

    #[test]
    fn the_answer_arrives_and_the_window_is_woken() {
        let woken = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&woken);
        let job = Job::spawn(move || flag.store(true, Ordering::SeqCst), || 6 * 7);
        let answer = loop {
            if let Some(answer) = job.poll() {
                break answer;
            }
            std::thread::yield_now();
        };
        assert_eq!(answer, Ok(42));
        while !woken.load(Ordering::SeqCst) {
            std::thread::yield_now();
        }
    }

    #[test]
    fn a_panicking_job_answers_with_an_error() {
        let job: Job<u32> = Job::spawn(|| {}, || panic!("on purpose"));
        let answer = loop {
            if let Some(answer) = job.poll() {
                break answer;
            }
            std::thread::yield_now();
        };
        assert!(answer.is_err());
    }
}
