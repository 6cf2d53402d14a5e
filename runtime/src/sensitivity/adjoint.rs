//! The discrete adjoint: the exact gradient of a loss of the computed
//! trajectory by a reverse sweep through the transposed step Jacobians,
//! with checkpoints.
//!
//! For `J = Σ_k ℓ_k(x_k, θ) + ℓ_T(x_n, θ)`, `x = (q, p)`:
//!
//! ```text
//! λ_n = ∂(ℓ_n + ℓ_T)/∂x_n        λ_k = ∂ℓ_k/∂x_k + Φ_xᵀ λ_{k+1}
//! dJ/dθ = Σ_k (∂ℓ_k/∂θ + Φ_θᵀ λ_{k+1}) + ∂ℓ_T/∂θ + (∂p_0/∂θ)ᵀ λ_p,0
//! dJ/dq_0 = λ_q,0 + (∂p_0/∂q_0)ᵀ λ_p,0        dJ/dv_0 = (∂p_0/∂v_0)ᵀ λ_p,0
//! ```
//!
//! The forward pass keeps a copy of the stepper every `m` nodes; the
//! reverse pass re-runs each segment from its copy (bit for bit the same
//! nodes: the stepper is deterministic and the copy carries its whole
//! state, compensation terms included), then walks it backwards. Memory is
//! `⌈n/m⌉` steppers plus `m + 1` nodes; the work is one extra forward run
//! plus one linearisation per step.

use nalgebra::SVector;
use num_dual::Dual64;

use super::Parametric;
use super::linearisation::{InitialMomentum, Rule, StepJacobian};
use crate::error::Error;
use crate::problem::{Dim, Extended, Stepper};
use crate::solution::Stepping;
use crate::state::State;
use crate::system::Scalar;

/// A scalar loss of a run: running terms at every node `k = 0..=n` and a
/// terminal term at the last node, each a function of `(t, q, p)` and the
/// parameters `θ`, written generic over the [`Scalar`] so that the runtime
/// differentiates them (with dual numbers, exactly).
///
/// ```
/// use lagrangian_runtime::Scalar;
/// use lagrangian_runtime::sensitivity::Loss;
///
/// /// Σ_k (q_k − 1)² + p_n².
/// struct Fit;
/// impl Loss<1, 1> for Fit {
///     fn running<D: Scalar>(&self, _k: u64, _t: f64, q: [D; 1], _p: [D; 1], _theta: &[D; 1]) -> D {
///         (q[0] - 1.0).powi(2)
///     }
///     fn terminal<D: Scalar>(&self, _t: f64, _q: [D; 1], p: [D; 1], _theta: &[D; 1]) -> D {
///         p[0] * p[0]
///     }
/// }
/// ```
pub trait Loss<const N: usize, const P: usize> {
    /// `ℓ_k(t_k, q_k, p_k; θ)` at node `k` (0 for none, the default).
    fn running<D: Scalar>(&self, k: u64, t: f64, q: [D; N], p: [D; N], theta: &[D; P]) -> D {
        let _ = (k, t, q, p, theta);
        D::zero()
    }

    /// `ℓ_T(t_n, q_n, p_n; θ)` at the last node (0 for none, the default).
    fn terminal<D: Scalar>(&self, t: f64, q: [D; N], p: [D; N], theta: &[D; P]) -> D {
        let _ = (t, q, p, theta);
        D::zero()
    }
}

/// How many states the forward pass keeps for the reverse pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Checkpoints {
    /// One copy of the stepper every `m` nodes (`m ≥ 1`).
    Every(usize),
    /// At most this many copies (`≥ 1`), evenly spaced; `⌈√n⌉` balances
    /// the copies against the nodes of one segment.
    Budget(usize),
}

impl Checkpoints {
    /// The spacing `m` for a run of about `steps` steps.
    fn spacing<const N: usize>(self, steps: usize) -> Result<usize, Error<N>> {
        match self {
            Self::Every(0) | Self::Budget(0) => {
                Err(Error::InvalidSetting { reason: "a checkpoint budget of zero: at least one state must be kept" })
            }
            Self::Every(m) => Ok(m),
            Self::Budget(c) => Ok(steps.div_ceil(c).max(1)),
        }
    }
}

/// The gradient of a loss of the run with respect to the initial data and
/// the parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Gradient<const N: usize, const P: usize> {
    /// The loss `J` of the computed run.
    pub value: f64,
    /// `dJ/dq_0`.
    pub q0: [f64; N],
    /// `dJ/dv_0`.
    pub v0: [f64; N],
    /// `dJ/dθ`, in the order of [`Parametric::NAMES`].
    pub theta: [f64; P],
    /// The last node of the run.
    pub last: State<N>,
    /// The costate `λ_k = (∂J/∂q_k, ∂J/∂p_k)` at each checkpoint node, in
    /// time order (the node and `(λ_q, λ_p)`).
    pub costates: Vec<(State<N>, [f64; N], [f64; N])>,
    /// Steps run again in the reverse pass.
    pub recomputed_steps: u64,
}

/// The gradient of `(ℓ, ∂ℓ/∂q, ∂ℓ/∂p, ∂ℓ/∂θ)` of one term.
type Term<const N: usize, const P: usize> = (f64, SVector<f64, N>, SVector<f64, N>, SVector<f64, P>);

/// Value and gradient of `f` at `(q, p, θ)`, one dual evaluation per input.
fn term<const N: usize, const P: usize>(
    state: &State<N>,
    theta: &[f64; P],
    f: impl Fn([Dual64; N], [Dual64; N], &[Dual64; P]) -> Dual64,
) -> Result<Term<N, P>, Error<N>> {
    let (q, p, th) = (state.q.map(Dual64::from_re), state.p.map(Dual64::from_re), theta.map(Dual64::from_re));
    let value = f(q, p, &th).re;
    let (mut dq, mut dp) = (SVector::<f64, N>::zeros(), SVector::<f64, N>::zeros());
    let mut dth = SVector::<f64, P>::zeros();
    for i in 0..N {
        let mut x = q;
        x[i].eps = 1.0;
        dq[i] = f(x, p, &th).eps;
        let mut y = p;
        y[i].eps = 1.0;
        dp[i] = f(q, y, &th).eps;
    }
    for j in 0..P {
        let mut x = th;
        x[j].eps = 1.0;
        dth[j] = f(q, p, &x).eps;
    }
    let finite = value.is_finite() && dq.iter().chain(dp.iter()).chain(dth.iter()).all(|x| x.is_finite());
    if finite { Ok((value, dq, dp, dth)) } else { Err(Error::NonFiniteLoss { state: *state }) }
}

/// The running term (and, at the last node, the terminal term) at `state`.
fn loss_at<L: Loss<N, P>, const N: usize, const P: usize>(
    loss: &L,
    state: &State<N>,
    theta: &[f64; P],
    last: bool,
) -> Result<Term<N, P>, Error<N>> {
    let (k, t) = (state.step, state.t);
    term(state, theta, |q, p, th| {
        let running = loss.running(k, t, q, p, th);
        if last { running + loss.terminal(t, q, p, th) } else { running }
    })
}

/// The value of the loss terms at `state`, checked finite.
fn value_at<L: Loss<N, P>, const N: usize, const P: usize>(
    loss: &L,
    state: &State<N>,
    theta: &[f64; P],
    last: bool,
) -> Result<f64, Error<N>> {
    let (k, t) = (state.step, state.t);
    let mut value = loss.running(k, t, state.q, state.p, theta);
    if last {
        value += loss.terminal(t, state.q, state.p, theta);
    }
    if value.is_finite() { Ok(value) } else { Err(Error::NonFiniteLoss { state: *state }) }
}

/// The run and the reverse sweep (see the [module](self)).
#[allow(clippy::too_many_arguments)]
pub(crate) fn gradient<S, L, const N: usize, const P: usize>(
    mut stepper: Stepper<S, N>,
    rule: Rule,
    initial: (f64, [f64; N], [f64; N]),
    h: f64,
    t_end: f64,
    loss: &L,
    checkpoints: Checkpoints,
) -> Result<Gradient<N, P>, Error<N>>
where
    S: Parametric<N, P>,
    L: Loss<N, P>,
    Dim<N>: Extended<N>,
{
    let t0 = initial.0;
    if !(t_end.is_finite() && t_end >= t0) {
        return Err(Error::InvalidTarget { target: t_end, state: stepper.state() });
    }
    // The number of steps is known only after the run; the estimate sets
    // the spacing of a budget.
    let estimate = ((t_end - t0) / h).ceil();
    let m = checkpoints.spacing::<N>(if estimate.is_finite() { estimate as usize } else { usize::MAX })?;
    let system = stepper.system().clone();
    let theta = system.parameters();

    // Forward: the loss value, a copy every m nodes.
    let mut kept = vec![stepper.clone()];
    let mut value = 0.0;
    let mut last_h = None;
    while stepper.state().t < t_end {
        let state = stepper.state();
        value += value_at(loss, &state, &theta, false)?;
        Stepping::step_toward(&mut stepper, t_end, last_h)?;
        last_h = Some(stepper.state().t - state.t);
        if stepper.state().step.is_multiple_of(m as u64) {
            kept.push(stepper.clone());
        }
    }
    let last = stepper.state();
    value += value_at(loss, &last, &theta, true)?;
    let (_, dq, dp, mut dtheta) = loss_at(loss, &last, &theta, true)?;
    let (mut lq, mut lp) = (dq, dp);

    // Reverse: each segment from its copy, backwards. `steps[i]` runs from
    // `nodes[i]` to `nodes[i + 1]` and is made of `pieces[steps[i]]`.
    let mut costates = Vec::with_capacity(kept.len());
    let mut recomputed_steps = 0;
    let mut nodes = Vec::with_capacity(m + 1);
    let mut steps = Vec::with_capacity(m);
    let mut pieces = Vec::with_capacity(m);
    for start in kept.into_iter().rev() {
        let first = start.state().step;
        if first == last.step {
            // The copy at the last node starts no segment.
            costates.push((last, lq.into(), lp.into()));
            continue;
        }
        let mut sim = start;
        nodes.clear();
        steps.clear();
        pieces.clear();
        nodes.push(sim.state());
        let mut last_h = None;
        while sim.state().step < (first + m as u64).min(last.step) {
            let from = sim.state();
            Stepping::step_toward(&mut sim, t_end, last_h)?;
            last_h = Some(sim.state().t - from.t);
            let begin = pieces.len();
            sim.last_pieces(&from, &mut pieces)?;
            steps.push(begin..pieces.len());
            nodes.push(sim.state());
            recomputed_steps += 1;
        }
        for (i, range) in steps.iter().enumerate().rev() {
            let from = nodes[i];
            let j = StepJacobian::of_step(&system, &rule, &theta, &pieces[range.clone()]).ok_or(
                Error::SingularJacobian { state: from, h: nodes[i + 1].t - from.t, iterations: 0, rcond: 0.0 },
            )?;
            let m = &j.state;
            dtheta += j.dq_dtheta.transpose() * lq + j.dp_dtheta.transpose() * lp;
            let (_, gq, gp, gth) = loss_at(loss, &from, &theta, false)?;
            let nq = gq + m.dq_dq.transpose() * lq + m.dp_dq.transpose() * lp;
            let np = gp + m.dq_dp.transpose() * lq + m.dp_dp.transpose() * lp;
            (lq, lp) = (nq, np);
            dtheta += gth;
        }
        costates.push((nodes[0], lq.into(), lp.into()));
    }
    costates.reverse();
    let p0 = InitialMomentum::at(&system, &theta, initial);
    let q0 = lq + p0.dq.transpose() * lp;
    let v0 = p0.dv.transpose() * lp;
    dtheta += p0.dtheta.transpose() * lp;
    Ok(Gradient { value, q0: q0.into(), v0: v0.into(), theta: dtheta.into(), last, costates, recomputed_steps })
}
