//! The report's problem with holonomic constraints: the double pendulum of
//! the `double-pendulum` problem (same masses, lengths, gravity, initial
//! angles and horizon) written in Cartesian coordinates `(x₁, y₁, x₂, y₂)`
//! with the two rod constraints `|r₁| = l₁`, `|r₂ − r₁| = l₂`, and how each
//! method runs on it: the project's constrained rules (`Constrained`:
//! RATTLE for the one-point rules, the constraints at the control nodes of
//! Galerkin rules, compositions of RATTLE trapezoid steps), DOP853 on the
//! angle equations, and DOP853 on the index-1 Cartesian equations with
//! Baumgarte stabilisation (`crate::constrained_peers`).
//!
//! Its reference is the angle problem's, mapped to Cartesian positions
//! (`crate::problem`); its runs record, besides the energy, the constraint
//! errors of [`crate::cartesian::constraint_errors`].

use lagrangian::Composition as Generated;
use lagrangian::prelude::*;

use crate::cartesian::{system, to_angles, to_cartesian};
use crate::constrained_peers::{Angles, Baumgarte};
use crate::invariants::Sampler;
use crate::methods::{Method, Setting};
use crate::peers;
use crate::problems::{DoublePendulum, Model};
use crate::run::Run;

/// The Galerkin degrees `s` (Gauss points, order `2s`) the report runs
/// under constraints.
pub const GALERKIN_DEGREES: [u8; 3] = [2, 3, 4];

/// The double pendulum in Cartesian coordinates with two constraints (see
/// the [module documentation](self)).
#[derive(Debug, Clone, Copy)]
pub struct CartesianDoublePendulum {
    /// Multiplies the horizon.
    pub scale: f64,
}

impl CartesianDoublePendulum {
    /// Short name.
    pub const ID: &'static str = "double-pendulum-cartesian";
    /// Title.
    pub const TITLE: &'static str = "Double pendulum in Cartesian coordinates (2 constraints, t ≤ 10)";

    /// The angle problem with the same horizon.
    pub fn angles(&self) -> DoublePendulum {
        DoublePendulum { scale: self.scale }
    }

    /// `(q0, v0)`: the angle problem's initial data, mapped.
    pub fn initial_state(&self) -> ([f64; 4], [f64; 4]) {
        let (q, v) = self.angles().initial();
        to_cartesian(&q, &v)
    }

    /// The project's constrained rules and the two DOP853 peers.
    pub fn method_applies(method: Method) -> bool {
        match method {
            Method::Midpoint
            | Method::Trapezoid
            | Method::AlphaBeta
            | Method::GeneratedYoshida4
            | Method::GeneratedYoshida6
            | Method::GeneratedKahanLi8
            | Method::Dop853Angles
            | Method::Dop853Baumgarte => true,
            Method::Galerkin(s) => GALERKIN_DEGREES.contains(&s),
            _ => false,
        }
    }

    /// One run from `(q0, v0)` to `t_end` (see [`crate::problem::Problem::run`]);
    /// with `samples > 0` it records the energy and constraint errors at
    /// about that many evenly spaced times.
    pub fn integrate(
        &self,
        (q0, v0): ([f64; 4], [f64; 4]),
        method: Method,
        setting: Setting,
        t_end: f64,
        samples: usize,
    ) -> Run {
        let cartesian = Baumgarte(self.angles());
        let start = crate::clock::Clock::start();
        let mut sampler = Sampler::new(&cartesian, &q0, &v0, t_end, samples);
        // The velocities are solved for only when sampled: not in timed runs.
        let mut record = |t: f64, q: &[f64; 4], v: &[f64; 4]| sampler.record(t, q, v);
        let sampling = (samples > 0).then_some(&mut record);
        let n = match setting {
            Setting::Steps(n) => n,
            _ => 0,
        };
        let mut out = match (method, setting) {
            (Method::Dop853Baumgarte, Setting::Tolerance(tol)) => {
                peers::run::<Baumgarte, 4, 8>(&cartesian, (q0, v0), Method::OdeSolversDop853, tol, t_end, samples)
            }
            (Method::Dop853Angles, Setting::Tolerance(tol)) => {
                let (theta, rate) = to_angles(&q0, &v0);
                let mut run = peers::run::<Angles, 2, 4>(
                    &Angles(self.angles()),
                    (theta, rate),
                    Method::OdeSolversDop853,
                    tol,
                    t_end,
                    samples,
                );
                if let Ok(theta) = <[f64; 2]>::try_from(run.q.as_slice()) {
                    run.q = to_cartesian(&theta, &[0.0; 2]).0.to_vec();
                }
                run
            }
            (Method::Midpoint, Setting::Steps(_)) => {
                rattle(Constrained::<_, 2>::new(Midpoint), (q0, v0), n, t_end, sampling)
            }
            (Method::Trapezoid, Setting::Steps(_)) => {
                rattle(Constrained::<_, 2>::new(Trapezoid), (q0, v0), n, t_end, sampling)
            }
            (Method::AlphaBeta, Setting::Steps(_)) => {
                rattle(Constrained::<_, 2>::new(AlphaBeta::EULER_A), (q0, v0), n, t_end, sampling)
            }
            (Method::Galerkin(2), Setting::Steps(_)) => {
                rattle(Constrained::<_, 2>::galerkin(Galerkin::<2, 2>::gauss()), (q0, v0), n, t_end, sampling)
            }
            (Method::Galerkin(3), Setting::Steps(_)) => {
                rattle(Constrained::<_, 2>::galerkin(Galerkin::<3, 3>::gauss()), (q0, v0), n, t_end, sampling)
            }
            (Method::Galerkin(4), Setting::Steps(_)) => {
                rattle(Constrained::<_, 2>::galerkin(Galerkin::<4, 4>::gauss()), (q0, v0), n, t_end, sampling)
            }
            (Method::GeneratedYoshida4, Setting::Steps(_)) => {
                rattle(Constrained::<_, 2>::composition(Generated::YOSHIDA4), (q0, v0), n, t_end, sampling)
            }
            (Method::GeneratedYoshida6, Setting::Steps(_)) => {
                rattle(Constrained::<_, 2>::composition(Generated::YOSHIDA6), (q0, v0), n, t_end, sampling)
            }
            (Method::GeneratedKahanLi8, Setting::Steps(_)) => {
                rattle(Constrained::<_, 2>::composition(Generated::KAHAN_LI8), (q0, v0), n, t_end, sampling)
            }
            (m, s) if Self::method_applies(m) => Run::failed(format!("{} cannot be run with {s:?}", m.name()), 0.0),
            (m, _) => Run::failed(format!("not applicable: {} on a constrained problem", m.name()), 0.0),
        };
        out.seconds = start.seconds();
        sampler.finish(&mut out);
        out
    }
}

/// `n` fixed steps of a constrained rule from `(q0, v0)` to `t_end`, with
/// `record(t, q, v)` after each when given.
fn rattle<L: F64Readouts>(
    method: L,
    (q0, v0): ([f64; 4], [f64; 4]),
    n: usize,
    t_end: f64,
    mut record: Option<&mut impl FnMut(f64, &[f64; 4], &[f64; 4])>,
) -> Run {
    let mut sim = match Integrator::new(system(), method, t_end / n as f64).start(0.0, q0, v0) {
        Ok(sim) => sim,
        Err(e) => return Run::failed(e.to_string(), 0.0),
    };
    let result = sim.run(n, |sim| {
        if let Some(record) = record.as_mut() {
            let s = sim.state();
            if let Ok(v) = sim.velocity() {
                record(s.t, &s.q, &v);
            }
        }
    });
    let stats = sim.stats();
    let per_step = (stats.steps > 0).then(|| stats.newton_iterations as f64 / stats.steps as f64);
    let steps = stats.steps;
    match result {
        Ok(()) => Run { q: sim.state().q.to_vec(), steps, newton_per_step: per_step, ..Run::default() },
        Err(e) => Run { failure: Some(e.to_string()), steps, newton_per_step: per_step, ..Run::default() },
    }
}
