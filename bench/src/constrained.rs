//! The report's problem with holonomic constraints: the double pendulum of
//! the `double-pendulum` problem (same masses, lengths, gravity, initial
//! angles and horizon) written in Cartesian coordinates `(x₁, y₁, x₂, y₂)`
//! with the two rod constraints `|r₁| = l₁`, `|r₂ − r₁| = l₂`, and how each
//! method runs on it: the project's constrained rules (`Constrained`:
//! RATTLE for the one-point rules, the constraints at the control nodes of
//! Galerkin rules, compositions of RATTLE trapezoid steps), DOP853 on the
//! angle equations, and DOP853 on the index-1 Cartesian equations with
//! Baumgarte stabilisation ([`crate::constrained_peers`]).
//!
//! Its reference is the angle problem's, mapped to Cartesian positions
//! (`crate::problem`); its runs record, besides the energy, the constraint
//! errors of [`constraint_errors`].

use lagrangian::Composition as Generated;
use lagrangian::prelude::*;

use crate::constrained_peers::{Angles, Baumgarte};
use crate::invariants::Sampler;
use crate::methods::{Method, Setting};
use crate::peers;
use crate::problems::{DoublePendulum, Model};
use crate::run::Run;

/// The double pendulum as two points in the plane, gravity along `−y`, the
/// rods as constraints in squared form, `|r₁|² − l₁²` and `|r₂ − r₁|² − l₂²`.
#[derive(Debug, Clone, Copy)]
pub struct CartesianDoublePendulumSys {
    /// Upper mass.
    pub m1: f64,
    /// Lower mass.
    pub m2: f64,
    /// Upper rod.
    pub l1: f64,
    /// Lower rod.
    pub l2: f64,
    /// Gravity.
    pub g: f64,
}

#[lagrangian]
impl CartesianDoublePendulumSys {
    fn lagrangian(&self, q: [f64; 4], v: [f64; 4]) -> f64 {
        let kinetic = 0.5 * self.m1 * (v[0] * v[0] + v[1] * v[1]) + 0.5 * self.m2 * (v[2] * v[2] + v[3] * v[3]);
        kinetic - self.g * (self.m1 * q[1] + self.m2 * q[3])
    }

    fn constraints(&self, q: [f64; 4]) -> [f64; 2] {
        let (dx, dy) = (q[2] - q[0], q[3] - q[1]);
        [q[0] * q[0] + q[1] * q[1] - self.l1 * self.l1, dx * dx + dy * dy - self.l2 * self.l2]
    }
}

/// The system with the angle problem's parameters.
pub fn system() -> CartesianDoublePendulumSys {
    let p = DoublePendulum::P;
    CartesianDoublePendulumSys { m1: p.m1, m2: p.m2, l1: p.l1, l2: p.l2, g: p.g }
}

/// Positions and velocities of the angles `θ` (from the downward vertical)
/// and their rates, in any precision.
pub fn to_cartesian<T: Real>(theta: &[T; 2], rate: &[T; 2]) -> ([T; 4], [T; 4]) {
    let p = DoublePendulum::P;
    let (s1, c1) = theta[0].sin_cos();
    let (s2, c2) = theta[1].sin_cos();
    let (x1, y1) = (s1 * p.l1, -c1 * p.l1);
    let (u1, w1) = (c1 * rate[0] * p.l1, s1 * rate[0] * p.l1);
    let q = [x1, y1, x1 + s2 * p.l2, y1 - c2 * p.l2];
    let v = [u1, w1, u1 + c2 * rate[1] * p.l2, w1 + s2 * rate[1] * p.l2];
    (q, v)
}

/// The angles and their rates of Cartesian positions and velocities (the
/// rod directions and the angular velocities of the rods; their lengths are
/// not checked).
pub fn to_angles(q: &[f64; 4], v: &[f64; 4]) -> ([f64; 2], [f64; 2]) {
    let (d, dv) = ([q[2] - q[0], q[3] - q[1]], [v[2] - v[0], v[3] - v[1]]);
    let theta = [q[0].atan2(-q[1]), d[0].atan2(-d[1])];
    let rate = [
        (q[0] * v[1] - q[1] * v[0]) / (q[0] * q[0] + q[1] * q[1]),
        (d[0] * dv[1] - d[1] * dv[0]) / (d[0] * d[0] + d[1] * d[1]),
    ];
    (theta, rate)
}

/// The constraints in squared form and their Jacobian `G = ∂g/∂q`.
pub fn squared_constraints(q: &[f64; 4]) -> ([f64; 2], [[f64; 4]; 2]) {
    let p = DoublePendulum::P;
    let (dx, dy) = (q[2] - q[0], q[3] - q[1]);
    let g = [q[0] * q[0] + q[1] * q[1] - p.l1 * p.l1, dx * dx + dy * dy - p.l2 * p.l2];
    let jac = [[2.0 * q[0], 2.0 * q[1], 0.0, 0.0], [-2.0 * dx, -2.0 * dy, 2.0 * dx, 2.0 * dy]];
    (g, jac)
}

/// `[max_i |‖r_i − r_{i−1}‖ − l_i| / l_i, max_i |d‖r_i − r_{i−1}‖/dt|]`
/// (`r₀ = 0`): how far the rods are from their lengths, relative to them,
/// and how fast their lengths change (m/s), the hidden constraint `G v` of
/// the constraints written as lengths. The same measure for every method,
/// whatever form of the constraints it holds.
pub fn constraint_errors(q: &[f64; 4], v: &[f64; 4]) -> [f64; 2] {
    let p = DoublePendulum::P;
    let rods = [([q[0], q[1]], [v[0], v[1]], p.l1), ([q[2] - q[0], q[3] - q[1]], [v[2] - v[0], v[3] - v[1]], p.l2)];
    let (mut position, mut velocity) = (0.0f64, 0.0f64);
    for (d, dv, l) in rods {
        let length = d[0].hypot(d[1]);
        position = position.max((length - l).abs() / l);
        velocity = velocity.max(((d[0] * dv[0] + d[1] * dv[1]) / length).abs());
    }
    [position, velocity]
}

/// The energy `½ m₁|v₁|² + ½ m₂|v₂|² + g (m₁ y₁ + m₂ y₂)`.
pub fn energy(q: &[f64; 4], v: &[f64; 4]) -> f64 {
    let p = DoublePendulum::P;
    0.5 * p.m1 * (v[0] * v[0] + v[1] * v[1])
        + 0.5 * p.m2 * (v[2] * v[2] + v[3] * v[3])
        + p.g * (p.m1 * q[1] + p.m2 * q[3])
}

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
