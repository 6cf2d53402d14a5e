//! The outcome of one run of a method on a problem.

/// The outcome of one run.
#[derive(Clone, Debug, Default)]
pub struct Run {
    /// Final positions (empty when the run failed).
    pub q: Vec<f64>,
    /// The failure, if any (the method's own error message).
    pub failure: Option<String>,
    /// Steps taken (accepted steps for adaptive methods).
    pub steps: u64,
    /// Newton iterations per step (project methods; for Gauss Galerkin
    /// rules, fixed-point and Newton iterations).
    pub newton_per_step: Option<f64>,
    /// Right-hand-side or force evaluations (peers and compositions);
    /// derivative evaluations of `L` at quadrature points (Galerkin rules).
    pub evaluations: Option<u64>,
    /// Wall-clock seconds of the integration alone.
    pub seconds: f64,
    /// `(t, (E − E0)/|E0|)` samples, when asked for.
    pub energy: Vec<(f64, f64)>,
    /// `(t, |L − L0|/|L0|)` samples of the angular momentum `L`, at the same
    /// times, when asked for and the problem conserves it.
    pub momentum: Vec<(f64, f64)>,
    /// `(t, [position error, velocity error])` samples of the constraint
    /// errors (`Model::constraint_errors`), at the times
    /// of `energy`, when asked for and the problem has constraints.
    pub constraints: Vec<(f64, [f64; 2])>,
    /// What the tolerance-driven solve reported ([`Method::Auto`] only).
    pub auto: Option<AutoReport>,
}

/// The estimate and choice of a [`Method::Auto`] run.
#[derive(Clone, Debug, Default)]
pub struct AutoReport {
    /// The estimated global error at the end.
    pub estimate: f64,
    /// The absolute error asked for, `rtol · Q`.
    pub requested: f64,
    /// The method it ran.
    pub method: String,
    /// Steps of the survey and pilot.
    pub pilot_steps: u64,
    /// Wall-clock seconds of the choice and pilot.
    pub pilot_seconds: f64,
    /// The step of the final run (`h`, or `σ` of a time transformation).
    pub step: f64,
    /// The error growth the pilot measured.
    pub growth: String,
    /// Why the method was chosen, in one line.
    pub reason: String,
    /// `(t, q)` at [`AUTO_NODES`] nodes evenly spread over the run (the last
    /// one at the end), when the run kept every node: the error along the
    /// run, which the estimate bounds.
    pub nodes: Vec<(f64, Vec<f64>)>,
}

/// Nodes of an auto run kept in [`AutoReport::nodes`].
pub const AUTO_NODES: usize = 8;

impl Run {
    pub(crate) fn failed(message: String, seconds: f64) -> Run {
        Run { failure: Some(message), seconds, ..Run::default() }
    }
}
