//! Forces and dissipation: the discrete Lagrange–d'Alembert principle
//! (docs/theory.md §6; Fu, Dai & Tang, Fu, Dai & Tang §2).
//!
//! The continuous equations are `d/dt ∂L/∂v − ∂L/∂q = F` with the generalised
//! force `F(t, q, v) = Q(t, q, v) − ∂R/∂v(q, v)`: the applied forces and
//! electromotive forces `Q` of [`Lagrangian::force`] and the dissipative forces
//! of the Rayleigh function `R` of [`Lagrangian::dissipation`] (a resistor
//! contributes `½ R q̇²`, Fu, Dai & Tang eq. (5)). `∂R/∂v` is taken with a dual
//! number nested over whatever scalar the force is evaluated on, so the Newton
//! Jacobian gets the derivatives of the dissipative force from the same
//! seeding as those of the action.
//!
//! Over one step the virtual work `∫ F·δq dt` is replaced by
//! `F_k^−·δq_k + F_k^+·δq_{k+1}`; each discrete Lagrangian supplies the pair
//! `(F_k^−, F_k^+)` from its own quadrature
//! ([`DiscreteLagrangian::forces`]), and the step becomes
//!
//! ```text
//! p_k + ∂A/∂q_k + F_k^− = 0          (solved for q_{k+1})
//! p_{k+1} = ∂A/∂q_{k+1} + F_k^+
//! ```
//!
//! so the Newton Jacobian is `∂²A/∂q_k∂q_{k+1} + ∂F_k^−/∂q_{k+1}`.
//!
//! # Energy balance
//!
//! With `E_k = −∂A(x_{k−1}, x_k)/∂t_k` the discrete energy of the step behind
//! node `k` (docs/theory.md §3) and `v̂_k = (q_{k+1} − q_k)/h` the secant velocity of
//! the step ahead of it, the work of the forces at node `k` is
//!
//! ```text
//! W_k = (F_{k−1}^+ + F_k^−) · (v̂_{k−1} + v̂_k)/2
//! ```
//!
//! the impulse the forces apply at node `k` times the mean velocity there. It
//! closes the balance `E_{k+1} − E_k = W_k` exactly (to round-off and the Newton
//! tolerance) for the midpoint rule, fixed steps and an autonomous Lagrangian
//! that is quadratic in `(q, v)` (linear mechanics and circuits: the damped
//! oscillator, the RLC circuit, Fu, Dai & Tang's sensor with a constant inductance),
//! whatever the forces. Proof: for the midpoint rule `E_{k+1} = E_L(z_k)`, the
//! continuous energy at the step's midpoint state `z_k = (q̄_k, v̂_k)`,
//! `q̄_k = (q_k + q_{k+1})/2`. Write `L_q^k, L_v^k` for `∂L/∂q, ∂L/∂v` at `z_k`.
//! The forced DEL at node `k` reads
//! `L_v^k − L_v^{k−1} = (h/2)(L_q^{k−1} + L_q^k) + (F_{k−1}^+ + F_k^−)`.
//! Since `dE_L = v·dL_v − L_q·dq` and, for quadratic `L`, `L_v` and `L_q` are
//! affine in `z`, integrating along the segment from `z_{k−1}` to `z_k` gives
//! exactly `E_L(z_k) − E_L(z_{k−1}) = v̄·(L_v^k − L_v^{k−1}) − L̄_q·(q̄_k − q̄_{k−1})`
//! with `v̄ = (v̂_{k−1} + v̂_k)/2`, `L̄_q = (L_q^{k−1} + L_q^k)/2`. With equal
//! steps `q̄_k − q̄_{k−1} = h v̄`, so inserting the DEL the `L_q` terms cancel and
//! `E_{k+1} − E_k = v̄·(F_{k−1}^+ + F_k^−) = W_k`. ∎
//!
//! No exact balance exists for a general Lagrangian with fixed steps: with no
//! forces it would make a symplectic fixed-step method conserve energy
//! exactly, which it cannot (Ge & Marsden). For a non-quadratic `L`, for the
//! trapezoid and α-β rules, and at a node where the step size changes, the
//! residual `E_{k+1} − E_k − W_k` is the method's local energy error, `O(h³)`
//! per node, and it adds up to `O(h²)` over a fixed time, like the energy
//! error of the conservative method. The balance starts at node 1: node 0 has
//! no step behind it, and `E_0` is the continuous energy of the initial data.

use nalgebra::SMatrix;
use num_dual::Dual64;

use crate::derivatives::{self, Segment, StepDerivatives, Var};
use crate::discrete::DiscreteLagrangian;
use crate::system::Lagrangian;

pub use crate::system::generalized_force;

/// Whether the system has any non-conservative force.
#[inline(always)]
pub(crate) const fn is_forced<S: Lagrangian<N> + ?Sized, const N: usize>() -> bool {
    S::HAS_FORCE || S::HAS_DISSIPATION
}

/// The discrete forces of one step: `F_k^−` acts on `q_k`, `F_k^+` on `q_{k+1}`,
/// so that `F_k^−·δq_k + F_k^+·δq_{k+1} ≈ ∫ F·δq dt` over the step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiscreteForces<const N: usize> {
    /// `F_k^−`, added to the DEL residual `p_k + ∂A/∂q_k`.
    pub minus: [f64; N],
    /// `F_k^+`, added to the next momentum `p_{k+1} = ∂A/∂q_{k+1}`.
    pub plus: [f64; N],
}

impl<const N: usize> DiscreteForces<N> {
    /// No force.
    pub const ZERO: Self = Self { minus: [0.0; N], plus: [0.0; N] };

    /// `F_k^− + F_k^+`, the impulse of the step in each coordinate.
    pub fn impulse(&self) -> [f64; N] {
        core::array::from_fn(|i| self.minus[i] + self.plus[i])
    }
}

/// The discrete forces of a segment for `method`, in plain `f64`
/// ([`DiscreteForces::ZERO`] for a system without forces).
pub fn discrete_forces<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> DiscreteForces<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    if !is_forced::<S, N>() {
        return DiscreteForces::ZERO;
    }
    let (minus, plus) = method.forces(system, seg.t0, seg.h, seg.q0, seg.dq);
    DiscreteForces { minus, plus }
}

/// The discrete forces and `∂F_k^−/∂q_{k+1}` (row `i` for `F_k^−[i]`, column
/// `j` for `q_{k+1}[j]`): one evaluation of the forces on a
/// [`DualArray`](crate::hyperdual::DualArray) seeded on all of `q_{k+1}`
/// (bit for bit the `N` evaluations on [`Dual64`] it replaces, one per column).
#[inline]
pub fn force_derivatives<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
) -> (DiscreteForces<N>, SMatrix<f64, N, N>)
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let mut forces = DiscreteForces::ZERO;
    let mut jacobian = SMatrix::zeros();
    if !is_forced::<S, N>() {
        return (forces, jacobian);
    }
    let (t0, h, q0, dq) = derivatives::lift_dual_array::<[f64; N], N>(seg, Var::Q1);
    let (minus, plus) = method.forces(system, t0, h, q0, dq);
    for i in 0..N {
        forces.minus[i] = minus[i].re;
        forces.plus[i] = plus[i].re;
        for j in 0..N {
            jacobian[(i, j)] = minus[i].eps[j];
        }
    }
    (forces, jacobian)
}

/// The pieces of the forced one-step map: [`derivatives::step_derivatives`]
/// with `F_k^−` added to `∂A/∂q_k` (so `p_k + d_q0` is the forced DEL
/// residual), `F_k^+` added to `∂A/∂q_{k+1}` (so `d_q1` is `p_{k+1}`) and
/// `∂F_k^−/∂q_{k+1}` added to the Newton Jacobian. For a system without forces
/// it is `step_derivatives` itself.
#[inline]
pub fn forced_step_derivatives<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> StepDerivatives<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    with_forces(system, method, seg, derivatives::step_derivatives(system, method, seg))
}

/// Adds the discrete forces of `seg` to step derivatives already computed
/// for it (nothing for a system without forces).
#[inline(always)]
pub(crate) fn with_forces<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    mut d: StepDerivatives<N>,
) -> StepDerivatives<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    if is_forced::<S, N>() {
        let (f, jacobian) = force_derivatives(system, method, seg);
        for i in 0..N {
            d.d_q0[i] += f.minus[i];
            d.d_q1[i] += f.plus[i];
        }
        d.d2_q0_q1 += jacobian;
    }
    d
}

/// The momentum at the end of a segment, `p_{k+1} = ∂A/∂q_{k+1} + F_k^+`.
#[inline]
pub fn end_momentum<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> [f64; N]
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let mut p = derivatives::end_momentum(system, method, seg);
    if is_forced::<S, N>() {
        let f = discrete_forces(system, method, seg);
        for i in 0..N {
            p[i] += f.plus[i];
        }
    }
    p
}

/// The momentum change of a solved step,
/// `p_{k+1} − p_k = ∂A/∂q_k + ∂A/∂q_{k+1} + F_k^− + F_k^+` (the DEL makes
/// `p_k = −∂A/∂q_k − F_k^−`): the increment the integrator Kahan-sums.
#[inline]
pub fn momentum_change<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> [f64; N]
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let mut dp = derivatives::momentum_change(system, method, seg);
    if is_forced::<S, N>() {
        let f = discrete_forces(system, method, seg);
        for i in 0..N {
            dp[i] += f.minus[i] + f.plus[i];
        }
    }
    dp
}

/// The energy balance across node `k`, between the step behind it and the
/// step ahead of it (see the [module documentation](self)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnergyBalance {
    /// `E_k = −∂A(x_{k−1}, x_k)/∂t_k`.
    pub energy_before: f64,
    /// `E_{k+1} = −∂A(x_k, x_{k+1})/∂t_{k+1}`.
    pub energy_after: f64,
    /// `W_k = (F_{k−1}^+ + F_k^−)·(v̂_{k−1} + v̂_k)/2`.
    pub work: f64,
    /// `W_k^δt = F_{k−1}^+·v̂_{k−1} + F_k^−·v̂_k`: the work the discrete
    /// Lagrange–d'Alembert principle with time as a variable assigns to node
    /// `k`, which forced variable steps impose exactly
    /// ([`variational_residual`](Self::variational_residual) at round-off;
    /// docs/theory.md §6).
    pub variational_work: f64,
}

impl EnergyBalance {
    /// `E_{k+1} − E_k − W_k`: round-off for the midpoint rule on a quadratic
    /// Lagrangian with equal steps, `O(h³)` otherwise.
    pub fn residual(&self) -> f64 {
        self.energy_after - self.energy_before - self.work
    }

    /// `E_{k+1} − E_k − W_k^δt`: round-off under forced variable steps for an
    /// autonomous `L` (the energy equation they solve); `O(h³)` per step
    /// under fixed steps.
    pub fn variational_residual(&self) -> f64 {
        self.energy_after - self.energy_before - self.variational_work
    }
}

/// The energy balance at the node shared by `behind` (from `x_{k−1}` to
/// `x_k`) and `ahead` (from `x_k` to `x_{k+1}`).
///
/// The work uses the forces and secant velocities of both steps; the
/// energies are the discrete ones of docs/theory.md §3.
pub fn energy_balance<S, M, const N: usize>(
    system: &S,
    method: &M,
    behind: &Segment<N>,
    ahead: &Segment<N>,
) -> EnergyBalance
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let f_behind = discrete_forces(system, method, behind);
    let f_ahead = discrete_forces(system, method, ahead);
    let work = (0..N)
        .map(|i| {
            let v = 0.5 * (behind.dq[i] / behind.h + ahead.dq[i] / ahead.h);
            (f_behind.plus[i] + f_ahead.minus[i]) * v
        })
        .sum();
    let variational_work =
        (0..N).map(|i| f_behind.plus[i] * (behind.dq[i] / behind.h) + f_ahead.minus[i] * (ahead.dq[i] / ahead.h)).sum();
    EnergyBalance {
        energy_before: -derivatives::end_time_derivative(system, method, behind),
        energy_after: -derivatives::end_time_derivative(system, method, ahead),
        work,
        variational_work,
    }
}

/// The discrete force `F_k^−` of a step and the work `w_k^− = F_k^−·v̂_k` it
/// does on a variation of the step's start time, with their derivatives in
/// the step's end point `(q_{k+1}, t_{k+1})` (at fixed start): what forced
/// variable steps add to the DEL and to the energy equation
/// (docs/theory.md §6, time as a variable in the discrete
/// Lagrange–d'Alembert principle).
///
/// From `N + 1` evaluations of the method's forces on [`Dual64`], one per
/// direction of the end point: off the fixed-step path.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StartForcing<const N: usize> {
    /// `F_k^−`.
    pub(crate) minus: [f64; N],
    /// `∂F_k^−/∂q_{k+1}` (row `i`, column `j`: `∂F_i/∂q_{k+1,j}`).
    pub(crate) d_minus_q1: SMatrix<f64, N, N>,
    /// `∂F_k^−/∂t_{k+1}`.
    pub(crate) d_minus_t1: [f64; N],
    /// `w_k^− = F_k^−·v̂_k`, `v̂_k = (q_{k+1} − q_k)/h`.
    pub(crate) work: f64,
    /// `∂w_k^−/∂q_{k+1}`.
    pub(crate) d_work_q1: [f64; N],
    /// `∂w_k^−/∂t_{k+1}`.
    pub(crate) d_work_t1: f64,
}

/// The extended step derivatives of `seg` (`derivatives::extended_step_derivatives`)
/// with, for a forced system, the discrete Lagrange–d'Alembert terms of time
/// as a variable: `F_k^−` joins the DEL, and its work `−F_k^−·v̂_k` on
/// `δt_k` the energy equation (see [`StartForcing`]). What every variable
/// step of a forced system solves.
pub(crate) fn extended_step_derivatives<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
) -> derivatives::ExtendedStepDerivatives<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let mut d = derivatives::extended_step_derivatives(system, method, seg);
    if is_forced::<S, N>() {
        let f = start_forcing(system, method, seg);
        for i in 0..N {
            d.d_q0[i] += f.minus[i];
            d.d2_q0_t1[i] += f.d_minus_t1[i];
            d.d2_t0_q1[i] -= f.d_work_q1[i];
        }
        d.d2_q0_q1 += f.d_minus_q1;
        d.d_t0 -= f.work;
        d.d2_t0_t1 -= f.d_work_t1;
    }
    d
}

/// [`StartForcing`] of the step `seg`.
pub(crate) fn start_forcing<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> StartForcing<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let mut out = StartForcing {
        minus: [0.0; N],
        d_minus_q1: SMatrix::zeros(),
        d_minus_t1: [0.0; N],
        work: 0.0,
        d_work_q1: [0.0; N],
        d_work_t1: 0.0,
    };
    for j in 0..=N {
        let mut dq = seg.dq.map(Dual64::from_re);
        let mut h = Dual64::from_re(seg.h);
        if j < N {
            dq[j].eps = 1.0;
        } else {
            h.eps = 1.0;
        }
        let (minus, _) = method.forces(system, Dual64::from_re(seg.t0), h, seg.q0.map(Dual64::from_re), dq);
        let inv_h = Dual64::from_re(1.0) / h;
        let mut work = Dual64::from_re(0.0);
        for i in 0..N {
            work += minus[i] * dq[i] * inv_h;
        }
        for i in 0..N {
            out.minus[i] = minus[i].re;
            if j < N {
                out.d_minus_q1[(i, j)] = minus[i].eps;
            } else {
                out.d_minus_t1[i] = minus[i].eps;
            }
        }
        out.work = work.re;
        if j < N {
            out.d_work_q1[j] = work.eps;
        } else {
            out.d_work_t1 = work.eps;
        }
    }
    out
}

/// `w_{k−1}^+ = F_{k−1}^+·v̂_{k−1}`: the work of the end force of the step
/// `seg` on a variation of its end time.
pub(crate) fn end_work<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> f64
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let plus = discrete_forces(system, method, seg).plus;
    (0..N).map(|i| plus[i] * (seg.dq[i] / seg.h)).sum()
}

/// The rate `Σ v_i ∂R/∂v_i` at which the dissipation function removes energy
/// at `(q, v)`; negative where `R` pumps energy in (negative damping).
///
/// The runtime integrates any `R` as given and does not require it to be
/// convex; this lets a caller check the sign where it matters.
pub fn dissipated_power<S: Lagrangian<N> + ?Sized, const N: usize>(system: &S, q: [f64; N], v: [f64; N]) -> f64 {
    if !S::HAS_DISSIPATION {
        return 0.0;
    }
    let q = q.map(Dual64::from);
    (0..N)
        .map(|i| {
            let mut vd = v.map(Dual64::from);
            vd[i].eps = 1.0;
            v[i] * system.dissipation(q, vd).eps
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discrete::{AlphaBeta, Midpoint, Trapezoid};
    use crate::system::Scalar;

    /// Non-linear force and dissipation, both depending on `q` and `v`.
    struct Forced;

    impl Lagrangian<2> for Forced {
        const AUTONOMOUS: bool = false;
        const CYCLIC: [bool; 2] = [false, false];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
            (v[0] * v[0] + v[1] * v[1]) * 0.5 - (q[0] * q[1]).cos()
        }
        const HAS_DISSIPATION: bool = true;
        fn dissipation<D: Scalar>(&self, q: [D; 2], v: [D; 2]) -> D {
            (v[0] * v[0] * (q[1] * q[1] + 1.0) + v[0] * v[1] * q[0].sin() + v[1] * v[1] * 0.3) * 0.5
        }
        const HAS_FORCE: bool = true;
        fn force<D: Scalar>(&self, t: D, q: [D; 2], v: [D; 2]) -> [D; 2] {
            [t.cos() * q[1] - v[1] * v[0] * 0.1, (q[0] * v[1]).sin()]
        }
    }

    /// The one array-dual evaluation against one `Dual64` evaluation per
    /// column of the Jacobian: equal bit for bit.
    fn agree<M: DiscreteLagrangian>(method: &M) {
        let seg = Segment { t0: 0.4, h: 0.02, q0: [0.8, -0.3], dq: [0.011, -0.017] };
        let (forces, jacobian) = force_derivatives(&Forced, method, &seg);
        assert_eq!(forces, discrete_forces(&Forced, method, &seg));
        for j in 0..2 {
            let (t0, h, q0, dq) = derivatives::lift(&seg, &[Var::Q1(j)], |x: &mut Dual64, _, s| x.eps += s);
            let (minus, plus) = method.forces(&Forced, t0, h, q0, dq);
            for i in 0..2 {
                assert_eq!((forces.minus[i], forces.plus[i]), (minus[i].re, plus[i].re));
                assert_eq!(jacobian[(i, j)], minus[i].eps, "({i}, {j})");
            }
        }
    }

    #[test]
    fn force_jacobian_from_one_array_evaluation_equals_the_column_evaluations() {
        agree(&Midpoint);
        agree(&Trapezoid);
        agree(&AlphaBeta::new(0.3).unwrap());
    }
}
