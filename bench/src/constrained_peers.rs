//! The first-order forms the DOP853 peer runs on the Cartesian double
//! pendulum (`crate::constrained`): its angle equations, and the index-1
//! Cartesian equations with Baumgarte stabilisation. Each is a [`Model`], so
//! [`crate::peers::run`] integrates it like any other problem and samples
//! its energy and constraint errors.

use crate::cartesian::{self as c, CartesianDoublePendulumSys};
use crate::problems::{DoublePendulum, DoublePendulumSys, Model};

/// The double pendulum in its two angles (the `double-pendulum` problem's
/// equations), whose constraint errors are those of the Cartesian positions
/// and velocities its angles map to: round-off, by construction.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Angles(pub(crate) DoublePendulum);

impl Model<2> for Angles {
    type Sys = DoublePendulumSys;
    const ID: &'static str = "double-pendulum-angles";
    const TITLE: &'static str = "Double pendulum in its angles (peer form)";
    fn system(&self) -> DoublePendulumSys {
        self.0.system()
    }
    fn initial(&self) -> ([f64; 2], [f64; 2]) {
        self.0.initial()
    }
    fn horizon(&self) -> f64 {
        self.0.horizon()
    }
    fn coarsest_steps(&self) -> usize {
        self.0.coarsest_steps()
    }
    fn time_scale(&self) -> f64 {
        self.0.time_scale()
    }
    fn accel(&self, q: &[f64; 2], v: &[f64; 2]) -> [f64; 2] {
        self.0.accel(q, v)
    }
    fn energy(&self, q: &[f64; 2], v: &[f64; 2]) -> f64 {
        self.0.energy(q, v)
    }
    fn constraint_errors(&self, q: &[f64; 2], v: &[f64; 2]) -> Option<[f64; 2]> {
        let (x, u) = c::to_cartesian(q, v);
        Some(c::constraint_errors(&x, &u))
    }
    fn reference_steps(&self, t_end: f64) -> usize {
        self.0.reference_steps(t_end)
    }
}

/// Baumgarte's stabilisation rates `α = β` (s⁻¹): the constraint errors obey
/// `g̈ + 2α ġ + β² g = 0`, critically damped at rate 30, about four times the
/// faster normal mode of the linearised pendulum (2.54 and 7.29 rad/s), so a
/// violation decays within a fraction of the fastest swing while the
/// equations stay non-stiff for DOP853 at the report's tolerances.
pub(crate) const BAUMGARTE_RATE: f64 = 30.0;

/// The index-1 Cartesian equations of the double pendulum with Baumgarte
/// stabilisation: `M a + Gᵀλ = f` and `G a = −Ġ v − 2α G v − β² g`, with
/// `g` the constraints in squared form (those the project's integrators
/// hold), solved for `(a, λ)` at each evaluation.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Baumgarte(pub(crate) DoublePendulum);

impl Baumgarte {
    /// `(a, λ)` of the saddle-point system. `M` is diagonal, so eliminating
    /// `a = M⁻¹(f − Gᵀλ)` leaves the 2 × 2 Schur complement
    /// `G M⁻¹ Gᵀ λ = G M⁻¹ f + Ġ v + 2α G v + β² g`, solved by Cramer's
    /// rule: the exact solution of the saddle-point system at the least cost,
    /// so that the peer is not charged for a general dense solve.
    pub(crate) fn accel_and_multipliers(&self, q: &[f64; 4], v: &[f64; 4]) -> ([f64; 4], [f64; 2]) {
        let p = DoublePendulum::P;
        let minv = [1.0 / p.m1, 1.0 / p.m1, 1.0 / p.m2, 1.0 / p.m2];
        let f = [0.0, -p.m1 * p.g, 0.0, -p.m2 * p.g];
        let (g, jac) = c::squared_constraints(q);
        let dv = [v[2] - v[0], v[3] - v[1]];
        // Ġ v for g₁ = |r₁|² − l₁², g₂ = |r₂ − r₁|² − l₂².
        let gdot_v = [2.0 * (v[0] * v[0] + v[1] * v[1]), 2.0 * (dv[0] * dv[0] + dv[1] * dv[1])];
        let gv: [f64; 2] = core::array::from_fn(|i| (0..4).map(|j| jac[i][j] * v[j]).sum());
        let (alpha, beta) = (BAUMGARTE_RATE, BAUMGARTE_RATE);
        let rhs: [f64; 2] = core::array::from_fn(|i| {
            (0..4).map(|j| jac[i][j] * minv[j] * f[j]).sum::<f64>()
                + gdot_v[i]
                + 2.0 * alpha * gv[i]
                + beta * beta * g[i]
        });
        let s = |i: usize, k: usize| (0..4).map(|j| jac[i][j] * minv[j] * jac[k][j]).sum::<f64>();
        let (s11, s12, s22) = (s(0, 0), s(0, 1), s(1, 1));
        let det = s11 * s22 - s12 * s12;
        let lambda = [(rhs[0] * s22 - s12 * rhs[1]) / det, (s11 * rhs[1] - s12 * rhs[0]) / det];
        let a = core::array::from_fn(|j| minv[j] * (f[j] - jac[0][j] * lambda[0] - jac[1][j] * lambda[1]));
        (a, lambda)
    }
}

impl Model<4> for Baumgarte {
    type Sys = CartesianDoublePendulumSys;
    const ID: &'static str = "double-pendulum-baumgarte";
    const TITLE: &'static str = "Double pendulum, index-1 Cartesian equations with Baumgarte stabilisation (peer form)";
    fn system(&self) -> CartesianDoublePendulumSys {
        c::system()
    }
    fn initial(&self) -> ([f64; 4], [f64; 4]) {
        let (q, v) = self.0.initial();
        c::to_cartesian(&q, &v)
    }
    fn horizon(&self) -> f64 {
        self.0.horizon()
    }
    fn coarsest_steps(&self) -> usize {
        self.0.coarsest_steps()
    }
    fn time_scale(&self) -> f64 {
        self.0.time_scale()
    }
    fn accel(&self, q: &[f64; 4], v: &[f64; 4]) -> [f64; 4] {
        self.accel_and_multipliers(q, v).0
    }
    fn energy(&self, q: &[f64; 4], v: &[f64; 4]) -> f64 {
        c::energy(q, v)
    }
    fn constraint_errors(&self, q: &[f64; 4], v: &[f64; 4]) -> Option<[f64; 2]> {
        Some(c::constraint_errors(q, v))
    }
    fn reference_steps(&self, t_end: f64) -> usize {
        self.0.reference_steps(t_end)
    }
}
