//! The continuous quantities at a node: the Legendre map `p = ∂L/∂v`, the
//! energy, its inverse (the velocity of a momentum, by Newton), the
//! potential force of a separable `L`, and the discrete energy of a step.

use super::directional::{Directional, Layout, directional_points, mass_from_gradient_code};
use super::{
    ModelScalar, TapeModel, assemble_and_factor, breakdown, filled, mass_bandwidth, seeds, step_matrix, tape_breakdown,
    zeroed,
};
use crate::banded::{LinearSolveError, StepMatrix, StepSolver};
use crate::integrator::Stats;
use crate::newton::{self, Breakdown, Linearization, NewtonFailure, NewtonOptions, Unknown};
use crate::real::{all_finite, max_abs};
use crate::tape::{Tape, TapeError, Var};

/// Records the relative change `|after − before| / |before|` of the discrete
/// energy across node `t1` in `stats` when it is the largest so far (the
/// watch of a system declared discontinuous).
pub(crate) fn watch_energy_jump(stats: &mut Stats, before: f64, after: f64, t1: f64) {
    let jump = (after - before).abs() / before.abs().max(f64::MIN_POSITIVE);
    if jump.is_finite() && jump > stats.largest_energy_jump {
        stats.largest_energy_jump = jump;
        stats.largest_energy_jump_at = t1;
    }
}

/// The discrete energy `−∂A/∂t_{k+1}` of the step `(t0, h, q0, dq)`: from
/// the system's gradient code at the rule's points when it has it, else from
/// one reverse sweep (NaN if the tape fails, which the runtime's use cannot
/// provoke, or if the buffers cannot be allocated).
pub(crate) fn step_energy(model: &dyn TapeModel, t0: f64, h: f64, q0: &[f64], dq: &[f64]) -> f64 {
    let n = q0.len();
    if let Some(points) = directional_points(model) {
        let mut directional = Directional::default();
        let Ok(mut g_q0) = filled(n, 0.0) else { return f64::NAN };
        if directional.allocate_values(n, model.autonomous()).is_err() {
            return f64::NAN;
        }
        return directional.momentum_and_energy(model, t0, h, points, q0, dq, &mut g_q0).0;
    }
    let mut tape = Tape::new();
    let mut inputs = Vec::with_capacity(2 * n + 1);
    inputs.extend_from_slice(q0);
    inputs.extend_from_slice(dq);
    inputs.push(h);
    let recorded = tape.record(&inputs, |x: &[Var]| model.action(Var::constant(t0), x[2 * n], &x[..n], &x[n..2 * n]));
    let mut gradient = vec![0.0; 2 * n + 1];
    match recorded.and_then(|_| tape.gradient(&mut gradient)) {
        Ok(()) => -gradient[2 * n],
        Err(_) => f64::NAN,
    }
}

/// Whether `L(t, q, 0) = −V(t, q)` of a separable system with constant
/// mass is finite at the end node `q` of an explicit step: with the start
/// node's, checked by the step before (or at `start`), it makes the
/// trapezoid action `h/2 (L_k + L_{k+1})` finite, whose derivatives can be
/// finite where it is not.
pub(super) fn potential_finite(model: &dyn TapeModel, zero: &[f64], t: f64, q: &[f64]) -> bool {
    ModelScalar::lagrangian(model, t, q, zero).is_finite()
}

/// [`potential_force`] into `out`, which holds zeros, and whether
/// `L(t, q, 0)` is finite there ([`potential_finite`]): both from one run
/// of the system's gradient code when it has it, its form at rest
/// (`add_gradient_q_at_rest`, which adds to the zeros and reads no
/// velocity) first, else a sweep and an evaluation. The zeros are the
/// caller's, who clears `out` in a pass over the state it makes anyway.
pub(super) fn potential_force_finite(
    model: &dyn TapeModel,
    tape: &mut Tape,
    zero: &(Vec<f64>, Vec<Var>),
    t: f64,
    q: &[f64],
    out: &mut [f64],
) -> Result<bool, TapeError> {
    if let Some(finite) = model.add_gradient_q_at_rest(t, q, out) {
        return Ok(finite);
    }
    if let Some(l) = model.value_gradient_q(t, q, &zero.0, out) {
        return Ok(l.is_finite());
    }
    potential_force(model, tape, zero, t, q, out)?;
    Ok(potential_finite(model, &zero.0, t, q))
}

/// `∂L/∂q(t, q, 0) = −∇V(t, q)` of a separable system, from the system's
/// gradient code when it has it, else one reverse sweep with the inputs `q`.
pub(super) fn potential_force(
    model: &dyn TapeModel,
    tape: &mut Tape,
    zero: &(Vec<f64>, Vec<Var>),
    t: f64,
    q: &[f64],
    out: &mut [f64],
) -> Result<(), TapeError> {
    if model.gradient_q(t, q, &zero.0, out) {
        return Ok(());
    }
    tape.record(q, |x: &[Var]| model.lagrangian(Var::constant(t), x, &zero.1))?;
    tape.gradient(out)
}

/// `L`, `∂L/∂v` and `∂²L/∂v²` (assembled, not factored; banded with the
/// given bandwidth, or dense) at `(t, q, v)`: from the system's gradient
/// code (on `f64`, and by colour classes on dual numbers) when it has it,
/// else from one second-order sweep of a tape with the inputs `v`.
pub(crate) fn velocity_derivatives(
    model: &dyn TapeModel,
    t: f64,
    q: &[f64],
    v: &[f64],
    bandwidth: Option<usize>,
) -> Result<(f64, Vec<f64>, Assembled), Breakdown> {
    let n = q.len();
    let width = bandwidth.map_or(n, |b| 2 * b + 1);
    let mut gradient = zeroed(Some(n), n).map_err(breakdown)?;
    let mut band = zeroed(n.checked_mul(width), n).map_err(breakdown)?;
    let l = if model.has_gradient_qv() {
        let layout = Layout { n, bandwidth };
        mass_from_gradient_code(model, t, q, v, layout, &mut gradient, &mut band).map_err(breakdown)?;
        ModelScalar::lagrangian(model, t, q, v)
    } else {
        let seeds = seeds(0..n, bandwidth);
        let mut tape = Tape::new();
        let qc: Vec<Var> = q.iter().map(|&x| Var::constant(x)).collect();
        let l = tape.record(v, |x: &[Var]| model.lagrangian(Var::constant(t), &qc, x)).map_err(tape_breakdown)?;
        let mut products = zeroed(n.checked_mul(seeds.directions()), n).map_err(breakdown)?;
        tape.hessian_product(&seeds, &mut gradient, &mut products).map_err(tape_breakdown)?;
        seeds.recover(&products, 0..n, &mut band).map_err(tape_breakdown)?;
        l
    };
    let matrix = step_matrix(n, bandwidth).map_err(breakdown)?;
    Ok((l, gradient, Assembled { n, matrix, band, bandwidth }))
}

/// A Hessian block read from the tape, ready to be factored.
#[derive(Clone, Debug)]
pub(crate) struct Assembled {
    pub(super) n: usize,
    pub(super) matrix: StepSolver,
    pub(crate) band: Vec<f64>,
    pub(crate) bandwidth: Option<usize>,
}

impl Assembled {
    /// Assembles and factors the block.
    pub(super) fn factor_in_place(&mut self, min_rcond: f64) -> Result<(), Breakdown> {
        assemble_and_factor(&mut self.matrix, self.n, self.bandwidth, &self.band, min_rcond)
    }

    pub(super) fn solve(&self, b: &mut [f64]) -> Result<(), LinearSolveError> {
        self.matrix.solve(b)
    }
}

/// The momentum `p = ∂L/∂v` and energy `E = v·p − L` at `(t, q, v)`, with a
/// check that `∂²L/∂v²` is regular there (its banded or dense LU). `Err`
/// says why the data cannot start an integration.
pub(crate) fn legendre(model: &dyn TapeModel, t: f64, q: &[f64], v: &[f64]) -> Result<(Vec<f64>, f64), &'static str> {
    let n = q.len();
    let (l, p, mut hessian) = velocity_derivatives(model, t, q, v, mass_bandwidth(model.coupling(), n))
        .map_err(|_| "the lagrangian or its derivatives could not be evaluated at the initial data")?;
    if !l.is_finite() || !all_finite(&p) {
        return Err("the lagrangian or its momentum is not finite at the initial data");
    }
    if hessian.factor_in_place(0.0).is_err() {
        return Err("∂²L/∂v² is singular at the initial data: the legendre transform is not regular");
    }
    let energy = (0..n).map(|i| v[i] * p[i]).sum::<f64>() - l;
    if !energy.is_finite() {
        return Err("the energy is not finite at the initial data");
    }
    Ok((p, energy))
}

/// The energy `E = v·∂L/∂v − L` at `(t, q, v)`: `∂L/∂v` from the system's
/// gradient code when it has it, else from one reverse sweep (NaN if the
/// tape fails).
pub(crate) fn energy(model: &dyn TapeModel, t: f64, q: &[f64], v: &[f64]) -> f64 {
    let n = q.len();
    let mut p = vec![0.0; n];
    match momentum(model, t, q, v, &mut p) {
        Some(l) => (0..n).map(|i| v[i] * p[i]).sum::<f64>() - l,
        None => f64::NAN,
    }
}

/// The momentum `p = ∂L/∂v(t, q, v)` written into `p`, and `L` there:
/// from the system's gradient code when it has it, else from one reverse
/// sweep (`None` if the tape fails).
pub(crate) fn momentum(model: &dyn TapeModel, t: f64, q: &[f64], v: &[f64], p: &mut [f64]) -> Option<f64> {
    if model.has_gradient_qv() {
        let mut fq = vec![0.0; q.len()];
        ModelScalar::gradient_qv(model, t, q, v, &mut fq, p);
        Some(ModelScalar::lagrangian(model, t, q, v))
    } else {
        let mut tape = Tape::new();
        let qc: Vec<Var> = q.iter().map(|&x| Var::constant(x)).collect();
        tape.record(v, |x: &[Var]| model.lagrangian(Var::constant(t), &qc, x))
            .and_then(|l| tape.gradient(p).map(|_| l))
            .ok()
    }
}

/// The velocity whose momentum `∂L/∂v(t, q, v)` is `p`, by Newton's method
/// from `guess` with banded or dense solves (the inverse Legendre
/// transform). `Err` carries `(iterations, residual norm)`.
pub(crate) fn velocity(
    model: &dyn TapeModel,
    t: f64,
    q: &[f64],
    p: &[f64],
    guess: &[f64],
) -> Result<Vec<f64>, (usize, f64)> {
    let n = q.len();
    let options = NewtonOptions::default();
    let bandwidth = mass_bandwidth(model.coupling(), n);
    let linearize = |v: &Vec<f64>, _| -> Result<Linearization<Vec<f64>>, Breakdown> {
        let (_, m, mut hessian) = velocity_derivatives(model, t, q, v, bandwidth)?;
        let mut r: Vec<f64> = (0..n).map(|i| m[i] - p[i]).collect();
        if !r.iter().all(|x| x.is_finite()) {
            return Err(Breakdown::NonFinite("residual"));
        }
        let scale = max_abs(p).max(max_abs(&m));
        hessian.factor_in_place(options.min_rcond)?;
        let residual_norm = max_abs(&r);
        hessian.solve(&mut r).map_err(breakdown)?;
        r.iter_mut().for_each(|x| *x = -*x);
        Ok(Linearization::new(r, residual_norm).cancelling(scale))
    };
    match newton::solve(guess.to_vec(), &options, linearize) {
        Ok((v, _)) => Ok(v),
        Err(NewtonFailure::NotConverged(r)) => Err((r.iterations, r.residual_norm)),
        Err(f) => Err((f.iterations(), f64::INFINITY)),
    }
}

/// The heap vector Newton iterates on in reverse mode.
impl Unknown for Vec<f64> {
    #[inline]
    fn update(&mut self, dx: &Self) {
        for (x, d) in self.iter_mut().zip(dx) {
            *x += d;
        }
    }

    #[inline]
    fn error_ratio(&self, dx: &Self, rtol: f64, atol: f64) -> f64 {
        max_abs(dx) / (rtol * max_abs(self) + atol)
    }
}
