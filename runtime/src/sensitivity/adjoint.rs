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
//! plus one transposed linearisation per step (`pullback.rs`:
//! one transposed solve with the step's Newton matrix and products of second
//! derivatives with vectors, never `Φ_x` itself).

use nalgebra::DVector;
use num_dual::Dual64;

use super::Parametric;
use super::linearisation::Rule;
use super::pullback::{Pullback, large};
use super::split::Reverse;
use crate::error::Error;
use crate::hyperdual::{DualArray, Pair};
use crate::problem::{Dim, Extended, Stepper};
use crate::solution::Stepping;
use crate::state::State;
use crate::system::Lagrangian;
use crate::system::Scalar;
use crate::tape::{Tape, Var};

/// A scalar loss of a run: running terms at every node `k = 0..=n` and a
/// terminal term at the last node, each a function of `(t, q, p)` and the
/// parameters `θ`, written generic over the [`Scalar`] so that the runtime
/// differentiates them (with dual numbers, exactly). The time is a
/// [`Scalar`] too: under a time transformation the node times move with
/// the initial data and the parameters, and `∂ℓ/∂t` enters the gradient
/// (under fixed steps the node times are constants and it does not).
///
/// ```
/// use lagrangian_runtime::Scalar;
/// use lagrangian_runtime::sensitivity::Loss;
///
/// /// Σ_k (q_k − 1)² + p_n².
/// struct Fit;
/// impl Loss<1, 1> for Fit {
///     fn running<D: Scalar>(&self, _k: u64, _t: D, q: [D; 1], _p: [D; 1], _theta: &[D; 1]) -> D {
///         (q[0] - 1.0).powi(2)
///     }
///     fn terminal<D: Scalar>(&self, _t: D, _q: [D; 1], p: [D; 1], _theta: &[D; 1]) -> D {
///         p[0] * p[0]
///     }
/// }
/// ```
pub trait Loss<const N: usize, const P: usize> {
    /// `ℓ_k(t_k, q_k, p_k; θ)` at node `k` (0 for none, the default).
    fn running<D: Scalar>(&self, k: u64, t: D, q: [D; N], p: [D; N], theta: &[D; P]) -> D {
        let _ = (k, t, q, p, theta);
        D::zero()
    }

    /// `ℓ_T(t_n, q_n, p_n; θ)` at the last node (0 for none, the default).
    fn terminal<D: Scalar>(&self, t: D, q: [D; N], p: [D; N], theta: &[D; P]) -> D {
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
    fn spacing<const N: usize>(self, steps: usize) -> Result<usize, Error> {
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
    /// `(λ_t, λ_{p_t})` at the same checkpoint nodes under a time
    /// transformation or energy-preserving steps, whose extended phase
    /// `(q, t, p, p_t)` has the node time and its momentum (`−E` for energy
    /// steps) among its coordinates; empty under fixed steps.
    pub time_costates: Vec<(f64, f64)>,
    /// Steps run again in the reverse pass.
    pub recomputed_steps: u64,
}

/// The value of one term and its gradient `(∂ℓ/∂q, ∂ℓ/∂p, ∂ℓ/∂θ)`.
type Term<const N: usize, const P: usize> = (f64, [f64; N], [f64; N], [f64; P]);

/// The inputs `((q, p), θ)` of a term as the slots of one dual number.
type Inputs<const N: usize, const P: usize> = Pair<Pair<[f64; N], [f64; N]>, [f64; P]>;

/// A dual number seeded on all `2N + P` inputs of a term.
type Seeded<const N: usize, const P: usize> = DualArray<Inputs<N, P>>;

/// The gradients of the loss terms: one evaluation on a dual number seeded
/// on all `2N + P` inputs up to [`FORWARD_MAX_N`](crate::Derivatives::FORWARD_MAX_N)
/// coordinates, one reverse sweep of a [`Tape`] above (where that number
/// would hold `2N + P` parts in every value); the tape's buffers are
/// allocated once.
struct Terms {
    tape: Tape,
    inputs: Vec<f64>,
    gradient: Vec<f64>,
}

impl Terms {
    fn new<const N: usize, const P: usize>() -> Self {
        let len = if large(N) { 2 * N + P } else { 0 };
        Self { tape: Tape::new(), inputs: vec![0.0; len], gradient: vec![0.0; len] }
    }

    /// The running term (and, at the last node, the terminal term) at
    /// `state`, and its gradient.
    fn at<L: Loss<N, P>, const N: usize, const P: usize>(
        &mut self,
        loss: &L,
        state: &State<N>,
        theta: &[f64; P],
        last: bool,
    ) -> Result<Term<N, P>, Error> {
        let (k, t) = (state.step, state.t);
        let (mut dq, mut dp, mut dth) = ([0.0; N], [0.0; N], [0.0; P]);
        let value = if const { large(N) } {
            self.inputs[..N].copy_from_slice(&state.q);
            self.inputs[N..2 * N].copy_from_slice(&state.p);
            self.inputs[2 * N..].copy_from_slice(theta);
            let recorded = self.tape.record(&self.inputs, |x| {
                let (q, p) = (core::array::from_fn(|i| x[i]), core::array::from_fn(|i| x[N + i]));
                terms(loss, (k, Var::from(t), last), q, p, &core::array::from_fn(|j| x[2 * N + j]))
            });
            // A recording that fails is a loss without a gradient.
            let value = recorded.unwrap_or(f64::NAN);
            if value.is_finite() && self.tape.gradient(&mut self.gradient).is_ok() {
                dq.copy_from_slice(&self.gradient[..N]);
                dp.copy_from_slice(&self.gradient[N..2 * N]);
                dth.copy_from_slice(&self.gradient[2 * N..]);
            }
            value
        } else {
            let q = core::array::from_fn(|i| Seeded::<N, P>::variable(state.q[i], i));
            let p = core::array::from_fn(|i| Seeded::<N, P>::variable(state.p[i], N + i));
            let th = core::array::from_fn(|j| Seeded::<N, P>::variable(theta[j], 2 * N + j));
            let l = terms(loss, (k, Seeded::<N, P>::from(t), last), q, p, &th);
            (dq, dp, dth) = (l.eps.a.a, l.eps.a.b, l.eps.b);
            l.re
        };
        let finite = value.is_finite() && dq.iter().chain(dp.iter()).chain(dth.iter()).all(|x| x.is_finite());
        if finite { Ok((value, dq, dp, dth)) } else { Err(Error::NonFiniteLoss { state: (*state).into() }) }
    }
}

/// The running term at node `k` (time `t`) and, at the `last` node, the
/// terminal term, on any scalar.
fn terms<L: Loss<N, P>, D: Scalar, const N: usize, const P: usize>(
    loss: &L,
    (k, t, last): (u64, D, bool),
    q: [D; N],
    p: [D; N],
    theta: &[D; P],
) -> D {
    let running = loss.running(k, t, q, p, theta);
    if last { running + loss.terminal(t, q, p, theta) } else { running }
}

/// `∂ℓ/∂t` of the loss terms at `state`, checked finite: one evaluation
/// on a dual number seeded on the time.
fn time_derivative<L: Loss<N, P>, const N: usize, const P: usize>(
    loss: &L,
    state: &State<N>,
    theta: &[f64; P],
    last: bool,
) -> Result<f64, Error> {
    let t = Dual64::new(state.t, 1.0);
    let l = terms(
        loss,
        (state.step, t, last),
        state.q.map(Dual64::from),
        state.p.map(Dual64::from),
        &theta.map(Dual64::from),
    );
    if l.eps.is_finite() { Ok(l.eps) } else { Err(Error::NonFiniteLoss { state: (*state).into() }) }
}

/// The value of the loss terms at `state`, checked finite.
fn value_at<L: Loss<N, P>, const N: usize, const P: usize>(
    loss: &L,
    state: &State<N>,
    theta: &[f64; P],
    last: bool,
) -> Result<f64, Error> {
    let value = terms(loss, (state.step, state.t, last), state.q, state.p, theta);
    if value.is_finite() { Ok(value) } else { Err(Error::NonFiniteLoss { state: (*state).into() }) }
}

/// What the forward pass keeps: the loss, the copies of the stepper (at
/// the multiples of `m` nodes), and the last node.
struct Forward<S: Lagrangian<N> + Clone, const N: usize>
where
    Dim<N>: Extended<N>,
{
    value: f64,
    kept: Vec<Stepper<S, Dim<N>>>,
    m: usize,
    last: State<N>,
}

/// The forward pass from `stepper` (at `t0`) to `t_end`: the loss value
/// and a copy of the stepper every `m` nodes. Under a budget the spacing
/// is estimated from `h`; where the run takes more steps than that
/// (the steps in `s` of a time transformation), every other copy is
/// dropped and the spacing doubled, so that the budget holds.
fn forward<S, L, const N: usize, const P: usize>(
    mut stepper: Stepper<S, Dim<N>>,
    t0: f64,
    h: f64,
    t_end: f64,
    loss: &L,
    checkpoints: Checkpoints,
) -> Result<Forward<S, N>, Error>
where
    S: Parametric<N, P>,
    L: Loss<N, P>,
    Dim<N>: Extended<N>,
{
    if !(t_end.is_finite() && t_end >= t0) {
        return Err(Error::InvalidTarget { target: t_end, state: stepper.state().into() });
    }
    // The number of steps is known only after the run; the estimate sets
    // the spacing of a budget.
    let estimate = ((t_end - t0) / h).ceil();
    let mut m = checkpoints.spacing::<N>(if estimate.is_finite() { estimate as usize } else { usize::MAX })?;
    let budget = match checkpoints {
        Checkpoints::Budget(c) => c,
        Checkpoints::Every(_) => usize::MAX,
    };
    let theta = stepper.system().parameters();
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
            // The copy of the initial node is not counted against the budget.
            if kept.len() > budget.saturating_add(1) {
                m *= 2;
                kept.retain(|s| s.state().step.is_multiple_of(m as u64));
            }
        }
    }
    let last = stepper.state();
    value += value_at(loss, &last, &theta, true)?;
    Ok(Forward { value, kept, m, last })
}

/// The run and the reverse sweep (see the [module](self)).
#[allow(clippy::too_many_arguments)]
pub(crate) fn gradient<S, L, const N: usize, const P: usize>(
    stepper: Stepper<S, Dim<N>>,
    rule: Rule,
    initial: (f64, [f64; N], [f64; N]),
    h: f64,
    t_end: f64,
    loss: &L,
    checkpoints: Checkpoints,
) -> Result<Gradient<N, P>, Error>
where
    S: Parametric<N, P>,
    L: Loss<N, P>,
    Dim<N>: Extended<N>,
{
    let system = stepper.system().clone();
    let theta = system.parameters();
    let mut pullback = Pullback::<N, P>::new::<S>(rule)?;
    let mut terms = Terms::new::<N, P>();
    let Forward { value, kept, m, last } = forward(stepper, initial.0, h, t_end, loss, checkpoints)?;
    let (_, mut lq, mut lp, mut dtheta) = terms.at(loss, &last, &theta, true)?;

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
            costates.push((last, lq, lp));
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
            pullback.step(&system, &theta, &pieces[range.clone()], (&mut lq, &mut lp), &mut dtheta).ok_or_else(
                || Error::SingularJacobian {
                    state: from.into(),
                    h: nodes[i + 1].t - from.t,
                    iterations: 0,
                    rcond: 0.0,
                },
            )?;
            let (_, gq, gp, gth) = terms.at(loss, &from, &theta, false)?;
            for i in 0..N {
                lq[i] += gq[i];
                lp[i] += gp[i];
            }
            for (d, g) in dtheta.iter_mut().zip(gth) {
                *d += g;
            }
        }
        costates.push((nodes[0], lq, lp));
    }
    costates.reverse();
    // Through the Legendre transform p_0 = L_v(t_0, q_0, v_0; θ).
    let (dq0, dv0, dth0) =
        super::pullback::legendre(&system, &theta, initial, &lp).ok_or(Error::InvalidInitialData {
            reason: "the second derivatives of the lagrangian are not finite at the initial data",
        })?;
    let q0: [f64; N] = core::array::from_fn(|i| lq[i] + dq0[i]);
    for (d, g) in dtheta.iter_mut().zip(dth0) {
        *d += g;
    }
    Ok(Gradient { value, q0, v0: dv0, theta: dtheta, last, costates, time_costates: Vec::new(), recomputed_steps })
}

/// The gradient through a time-transformed or energy-preserving run: the
/// same forward pass and checkpoints, and a reverse sweep in the extended
/// phase `(q, t, p, p_t)` (`λ_k = Φ_xᵀ λ_{k+1} + ∂ℓ_k/∂(q, t, p)`) through
/// the dense step Jacobians of `transformed.rs`, `energy.rs` and
/// `galerkin_energy.rs`, or, for the
/// splitting's full steps, the transposed sub-flows of `split.rs`, with the
/// derivatives of the constant `c` (zero for energy steps) and of the first
/// extended node at the end.
pub(crate) fn gradient_extended<S, L, const N: usize, const P: usize>(
    stepper: Stepper<S, Dim<N>>,
    initial: (f64, [f64; N], [f64; N]),
    sigma: f64,
    t_end: f64,
    loss: &L,
    checkpoints: Checkpoints,
) -> Result<Gradient<N, P>, Error>
where
    S: Parametric<N, P>,
    L: Loss<N, P>,
    Dim<N>: Extended<N>,
{
    let m_ext = N + 1;
    let system = stepper.system().clone();
    let theta = system.parameters();
    let not_transformed = || Error::Unsupported {
        what: "the extended adjoint of a stepper without a time transformation or energy steps",
    };
    let start = stepper.extended_start::<P>(initial)?.ok_or_else(not_transformed)?;
    let mut terms = Terms::new::<N, P>();
    // A budget's spacing is estimated from `σ` as if `g = 1`; the forward
    // pass widens it where the run takes more steps.
    let Forward { value, kept, m, last } = forward(stepper, initial.0, sigma, t_end, loss, checkpoints)?;
    // λ in the extended phase: q, t, then p, p_t.
    let mut lambda = DVector::<f64>::zeros(2 * m_ext);
    let (mut dtheta, mut dc) = ([0.0; P], 0.0);
    let mut add_terms = |lambda: &mut DVector<f64>, dtheta: &mut [f64; P], state: &State<N>, last: bool| {
        let (_, gq, gp, gth) = terms.at(loss, state, &theta, last)?;
        let gt = time_derivative(loss, state, &theta, last)?;
        for i in 0..N {
            lambda[i] += gq[i];
            lambda[m_ext + i] += gp[i];
        }
        lambda[N] += gt;
        for (d, g) in dtheta.iter_mut().zip(gth) {
            *d += g;
        }
        Ok::<(), Error>(())
    };
    add_terms(&mut lambda, &mut dtheta, &last, true)?;
    let physical = |lambda: &DVector<f64>| -> ([f64; N], [f64; N]) {
        (core::array::from_fn(|i| lambda[i]), core::array::from_fn(|i| lambda[m_ext + i]))
    };

    let mut costates = Vec::with_capacity(kept.len());
    let mut time_costates = Vec::with_capacity(kept.len());
    let mut recomputed_steps = 0;
    let mut nodes = Vec::with_capacity(m + 1);
    let mut steps = Vec::with_capacity(m);
    let mut transpose = None;
    for start_copy in kept.into_iter().rev() {
        let first = start_copy.state().step;
        if first == last.step {
            let (lq, lp) = physical(&lambda);
            costates.push((last, lq, lp));
            time_costates.push((lambda[N], lambda[2 * m_ext - 1]));
            continue;
        }
        let mut sim = start_copy;
        nodes.clear();
        steps.clear();
        nodes.push(sim.state());
        let mut last_h = None;
        while sim.state().step < (first + m as u64).min(last.step) {
            let from = sim.state();
            let node = sim.extended_node().ok_or_else(not_transformed)?;
            Stepping::step_toward(&mut sim, t_end, last_h)?;
            last_h = Some(sim.state().t - from.t);
            steps.push(sim.extended_reverse::<P>(node, &from, Some(t_end))?);
            nodes.push(sim.state());
            recomputed_steps += 1;
        }
        for (i, step) in steps.iter().enumerate().rev() {
            match step {
                Reverse::Dense(linear) => {
                    for (j, d) in dtheta.iter_mut().enumerate() {
                        *d += linear.theta.column(j).dot(&lambda);
                    }
                    dc += linear.c.dot(&lambda);
                    lambda = linear.x.tr_mul(&lambda);
                }
                Reverse::Step { end, h } => {
                    sim.splitting_pullback(&mut transpose, (end, *h), &mut lambda, (&mut dtheta, &mut dc)).ok_or_else(
                        || Error::NonFinite {
                            state: nodes[i].into(),
                            h: nodes[i + 1].t - nodes[i].t,
                            iterations: 0,
                            quantity: "jacobian",
                        },
                    )?;
                }
            }
            add_terms(&mut lambda, &mut dtheta, &nodes[i], false)?;
        }
        let (lq, lp) = physical(&lambda);
        costates.push((nodes[0], lq, lp));
        time_costates.push((lambda[N], lambda[2 * m_ext - 1]));
    }
    costates.reverse();
    time_costates.reverse();
    // Through the first node in `s` and the constant `c`.
    let total = start.tangent.tr_mul(&lambda) + start.c.transpose() * dc;
    let q0 = core::array::from_fn(|i| total[i]);
    let v0 = core::array::from_fn(|i| total[N + i]);
    for (j, d) in dtheta.iter_mut().enumerate() {
        *d += total[2 * N + j];
    }
    Ok(Gradient { value, q0, v0, theta: dtheta, last, costates, time_costates, recomputed_steps })
}
