//! The report's clock: CPU time of the calling thread.
//!
//! Wall-clock timings of the same run on a 2-core machine varied up to 100×
//! while other builds ran; the CPU time of the thread that runs the
//! integrator counts only its own work, so a report run on a busy machine
//! stays comparable with one run on an idle machine (up to shared caches and
//! memory bandwidth, which the report's load averages let a reader judge).

use cpu_time::ThreadTime;

/// A started measurement.
#[derive(Clone, Copy, Debug)]
pub struct Clock(ThreadTime);

impl Clock {
    /// Starts measuring the calling thread's CPU time.
    pub fn start() -> Self {
        Clock(ThreadTime::now())
    }

    /// CPU seconds the calling thread used since [`Clock::start`] (the
    /// measurement belongs to the thread that started it).
    pub fn seconds(&self) -> f64 {
        self.0.elapsed().as_secs_f64()
    }
}
