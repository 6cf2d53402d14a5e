//! The implicit step on the tape: the action recorded once per Newton
//! iteration, its gradient and the Jacobian of the discrete Euler–Lagrange
//! residual by reverse and second-order sweeps, solved by Newton.

use core::cell::RefCell;

use super::directional::{Layout, directional_points};
use super::{
    Guess, Node, SparseWork, TAPE_FAILED, Taken, TapeModel, assemble_and_factor, breakdown, seeds, tape_breakdown,
};
use crate::banded::StepMatrix;
use crate::newton::{self, Breakdown, Jacobian, Linearization, NewtonFailure, NewtonOptions, NewtonReport, Unknown};
use crate::real::{kahan_into, max_abs};
use crate::tape::{TapeError, Var};

impl SparseWork {
    /// Records the action `A(q_k, Δq, h)` at `t_k = t0` on the tape
    /// ([`tape_buffers`](Self::tape_buffers) must have been called).
    pub(super) fn record_action(
        &mut self,
        model: &dyn TapeModel,
        t0: f64,
        h: f64,
        q0: &[f64],
        dq: &[f64],
    ) -> Result<f64, TapeError> {
        let n = self.n;
        self.inputs[..n].copy_from_slice(q0);
        self.inputs[n..2 * n].copy_from_slice(dq);
        self.inputs[2 * n] = h;
        self.tape.record(&self.inputs, |x: &[Var]| model.action(Var::constant(t0), x[2 * n], &x[..n], &x[n..2 * n]))
    }

    /// One implicit step of size `h` from `node`, ending at time `t1`:
    /// Newton on the DEL with banded or dense solves, then the momentum
    /// change and the step's discrete energy (returned with the step) from
    /// one more reverse sweep.
    pub(crate) fn newton_step(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        t1: f64,
        guess: &Guess<'_>,
        options: &NewtonOptions,
    ) -> Result<(Taken, f64), NewtonFailure> {
        let (dq, report) = self.solve(model, node, h, guess, options)?;
        let n = self.n;
        // The impulse `F_k^− + F_k^+` of the forces at the solved increment.
        let impulse = match forced_points(model) {
            Ok(Some(points)) => {
                let (mut minus, mut plus) = (self.buffer(), self.buffer());
                let forces = self.forcing.forces(model, (node.t, h, points), node.q, &dq, &mut minus, &mut plus, None);
                for (m, p) in minus.iter_mut().zip(&plus) {
                    *m += p;
                }
                self.recycle(plus);
                match forces {
                    Ok(()) => Some(minus),
                    Err(failure) => {
                        self.recycle(minus);
                        self.recycle(dq);
                        return Err(failure.at(report.iterations));
                    }
                }
            }
            Ok(None) => None,
            Err(failure) => {
                self.recycle(dq);
                return Err(failure.at(report.iterations));
            }
        };
        // The momentum change at fixed increment, the step's energy and
        // whether its action is finite.
        let (energy, action_finite) = match directional_points(model) {
            Some(points) => {
                self.directional.momentum_and_energy(model, node.t, h, points, node.q, &dq, &mut self.gradient[..n])
            }
            None => {
                let swept = match self.tape_buffers() {
                    Ok(()) => self
                        .record_action(model, node.t, h, node.q, &dq)
                        .and_then(|action| self.tape.gradient(&mut self.gradient).map(|()| action)),
                    Err(_) => Err(TapeError::TooLarge),
                };
                let Ok(action) = swept else {
                    self.recycle(dq);
                    return Err(NewtonFailure::Rejected { iterations: report.iterations, reason: TAPE_FAILED });
                };
                (-self.gradient[2 * n], action.is_finite())
            }
        };
        if !action_finite {
            self.recycle(dq);
            impulse.into_iter().for_each(|b| self.recycle(b));
            return Err(NewtonFailure::NonFinite { iterations: report.iterations, quantity: "lagrangian" });
        }
        if let Some(impulse) = impulse {
            for (g, f) in self.gradient[..n].iter_mut().zip(&impulse) {
                *g += f;
            }
            self.recycle(impulse);
        }
        let mut taken = self.taken(dq, report);
        if node.plain {
            let (q0, p0, dp) = (&node.q[..n], &node.p[..n], &self.gradient[..n]);
            let (dq, q1, p1) = (&taken.dq[..n], &mut taken.q1[..n], &mut taken.p1[..n]);
            for i in 0..n {
                q1[i] = q0[i] + dq[i];
                p1[i] = p0[i] + dp[i];
            }
        } else {
            kahan_into(node.q, node.q_carry, &taken.dq, &mut taken.q1, &mut taken.q_carry);
            kahan_into(node.p, node.p_carry, &self.gradient[..n], &mut taken.p1, &mut taken.p_carry);
        }
        if let Some(quantity) = crate::integrator::non_finite(t1, &taken.q1, &taken.p1) {
            self.recycle_taken(taken);
            return Err(NewtonFailure::NonFinite { iterations: report.iterations, quantity });
        }
        Ok((taken, energy))
    }

    /// Newton on `r(Δq) = p_k + ∂A/∂q_k = 0` with banded or dense solves:
    /// the residual and the Jacobian from the generated gradient code on
    /// dual numbers (forward over reverse) when the system has it and the
    /// rule has quadrature points, from the tape otherwise. No iteration
    /// allocates: the iterate and the correction are the work's buffers.
    pub(super) fn solve(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        guess: &Guess<'_>,
        options: &NewtonOptions,
    ) -> Result<(Vec<f64>, NewtonReport), NewtonFailure> {
        let n = self.n;
        let (q0, p0, pc) = (node.q, node.p, node.p_carry);
        let bandwidth = self.bandwidth;
        let min_rcond = options.min_rcond;
        // Newton's rounding floor for the increment: that of the positions.
        let q_floor = 4.0 * f64::EPSILON * max_abs(q0);
        let points = directional_points(model);
        if points.is_some() {
            self.directional.allocate(n, bandwidth, model.autonomous()).map_err(|e| breakdown(e).at(0))?;
        }
        // `F_k^−` and `F_k^+` of a forced system, for its rule's points.
        let forced = forced_points(model).map_err(|b| b.at(0))?;
        let mut forces = forced.map(|_| (self.buffer(), self.buffer()));
        let mut x = self.buffer();
        x.copy_from_slice(&guess.predictor[..n]);
        let (x, correction) = (RefCell::new(x), RefCell::new(self.buffer()));
        // The condition estimate (a few solves, 1.5–3.6 times a banded
        // factor+solve) on the first iteration of the step only: the Jacobian
        // barely changes within a step; later iterations still refuse a zero
        // or non-finite pivot.
        let mut first = true;
        let linearize = |iterate: &Slot<'_>, jacobian: Jacobian| -> Result<Linearization<Slot<'_>>, Breakdown> {
            let x = iterate.0.borrow();
            let mut r = correction.borrow_mut();
            // `r` first holds `∂A/∂q_k|_{q_{k+1}}`, then the residual.
            match points {
                // A kept Jacobian: the residual alone, in `f64`.
                Some(points) if jacobian == Jacobian::Kept => {
                    self.directional.residual(model, node.t, h, points, q0, &x, &mut r)
                }
                Some(points) => {
                    self.directional.linearize(model, node.t, h, points, q0, &x, bandwidth, &mut r, &mut self.mixed)
                }
                None => self.tape_linearize(model, node.t, h, q0, &x, &mut r, jacobian)?,
            }
            // The forced DEL: `p_k + ∂A/∂q_k + F_k^− = 0`, with `∂F_k^−/∂Δq`
            // in the Jacobian.
            if let (Some(points), Some((minus, plus))) = (forced, forces.as_mut()) {
                let layout = Layout { n, bandwidth };
                let band = (jacobian == Jacobian::Fresh).then_some((layout, &mut self.mixed[..]));
                self.forcing.forces(model, (node.t, h, points), q0, &x, minus, plus, band)?;
                for (r, f) in r.iter_mut().zip(minus.iter()) {
                    *r += f;
                }
            }
            let mut scale = max_abs(p0);
            for i in 0..n {
                let d_q0 = r[i];
                r[i] = (p0[i] + d_q0) + pc[i];
                scale = scale.max(d_q0.abs());
            }
            if !r.iter().all(|x| x.is_finite()) {
                return Err(Breakdown::NonFinite("residual"));
            }
            // Where Newton lets it, the factors of the last iterate's
            // Jacobian are kept (simplified Newton; the first request of a
            // solve is always for a fresh one).
            if jacobian == Jacobian::Fresh {
                let rcond_floor = if first { min_rcond } else { 0.0 };
                first = false;
                assemble_and_factor(&mut self.jacobian, n, bandwidth, &self.mixed, rcond_floor)?;
            }
            let residual_norm = max_abs(&r);
            self.jacobian.solve(&mut r).map_err(breakdown)?;
            for x in r.iter_mut() {
                *x = -*x;
            }
            let lin = Linearization::new(Slot(&correction), residual_norm).cancelling(scale).floor(q_floor);
            Ok(if jacobian == Jacobian::Kept { lin.kept() } else { lin })
        };
        let solved = newton::solve(Slot(&x), options, linearize).map(|(_, report)| report);
        for buffer in forces.into_iter().flat_map(|(minus, plus)| [minus, plus]) {
            self.recycle(buffer);
        }
        self.recycle(correction.into_inner());
        let dq = x.into_inner();
        let checked = solved.and_then(|report| guess.check(&dq, q0, report.iterations).map(|()| report));
        match checked {
            Ok(report) => Ok((dq, report)),
            Err(failure) => {
                self.recycle(dq);
                Err(failure)
            }
        }
    }

    /// The bandwidth of the step Jacobian the work assembles (`None`:
    /// general, stored as whole rows).
    pub(crate) fn step_bandwidth(&self) -> Option<usize> {
        self.bandwidth
    }

    /// `∂A/∂q_k|_{q_{k+1}}` at the increment `dq` into `d_q0`, and the step
    /// Jacobian `J = ∂²A/∂q_k∂q_{k+1}` returned in band storage (row `i`'s
    /// `2b + 1` entries around the diagonal, whole rows without a band):
    /// what a constrained step's saddle-point system is assembled from
    /// (`constrained/dynamic.rs`). From the gradient code on dual lanes when
    /// the system has it, from the tape otherwise, as in [`solve`](Self::solve).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn linearize_step(
        &mut self,
        model: &dyn TapeModel,
        t0: f64,
        h: f64,
        q0: &[f64],
        dq: &[f64],
        d_q0: &mut [f64],
    ) -> Result<&[f64], Breakdown> {
        let (n, bandwidth) = (self.n, self.bandwidth);
        match directional_points(model) {
            Some(points) => {
                self.directional.allocate(n, bandwidth, model.autonomous()).map_err(breakdown)?;
                self.directional.linearize(model, t0, h, points, q0, dq, bandwidth, d_q0, &mut self.mixed);
            }
            None => self.tape_linearize(model, t0, h, q0, dq, d_q0, Jacobian::Fresh)?,
        }
        Ok(&self.mixed)
    }

    /// After a constrained step converged: the momentum change at fixed
    /// increment `∂A/∂q_k|_{Δq}` into `out`, and the step's discrete energy
    /// `−∂A/∂h`; `Err` when the action is not finite or the tape failed.
    pub(crate) fn momentum_change(
        &mut self,
        model: &dyn TapeModel,
        t0: f64,
        h: f64,
        q0: &[f64],
        dq: &[f64],
        out: &mut [f64],
    ) -> Result<f64, Breakdown> {
        let n = self.n;
        let (energy, finite) = match directional_points(model) {
            Some(points) => {
                self.directional.allocate_values(n, model.autonomous()).map_err(breakdown)?;
                self.directional.momentum_and_energy(model, t0, h, points, q0, dq, out)
            }
            None => {
                self.tape_buffers().map_err(breakdown)?;
                let action = self.record_action(model, t0, h, q0, dq).map_err(tape_breakdown)?;
                self.tape.gradient(&mut self.gradient).map_err(tape_breakdown)?;
                out.copy_from_slice(&self.gradient[..n]);
                (-self.gradient[2 * n], action.is_finite())
            }
        };
        if finite { Ok(energy) } else { Err(Breakdown::NonFinite("lagrangian")) }
    }

    /// The tape's linearisation at the increment `dq`: `∂A/∂q_k|_{q_{k+1}} =
    /// g_{q_k} − g_{Δq}` into `d_q0` and, for a fresh `jacobian`,
    /// `J = ∂²A/∂q_k∂Δq − ∂²A/∂Δq²` into `mixed`, from one recording and one
    /// compressed second-order sweep (a kept one: one reverse sweep, no
    /// second-order products).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn tape_linearize(
        &mut self,
        model: &dyn TapeModel,
        t0: f64,
        h: f64,
        q0: &[f64],
        dq: &[f64],
        d_q0: &mut [f64],
        jacobian: Jacobian,
    ) -> Result<(), Breakdown> {
        let n = self.n;
        let seeds = seeds(n..2 * n, self.bandwidth);
        self.tape_buffers().map_err(breakdown)?;
        self.record_action(model, t0, h, q0, dq).map_err(tape_breakdown)?;
        match jacobian {
            Jacobian::Kept => self.tape.gradient(&mut self.gradient),
            Jacobian::Fresh => self.tape.hessian_product(&seeds, &mut self.gradient, &mut self.products),
        }
        .map_err(tape_breakdown)?;
        let g = &self.gradient;
        for i in 0..n {
            d_q0[i] = g[i] - g[n + i];
        }
        if jacobian == Jacobian::Kept {
            return Ok(());
        }
        // J = ∂²A/∂q_k∂Δq − ∂²A/∂Δq², entry by entry of the pattern.
        seeds.recover(&self.products, 0..n, &mut self.mixed).map_err(tape_breakdown)?;
        seeds.recover(&self.products, n..2 * n, &mut self.end).map_err(tape_breakdown)?;
        for (a, b) in self.mixed.iter_mut().zip(&self.end) {
            *a -= b;
        }
        Ok(())
    }
}

/// The rule's quadrature points when the model has forces (`None`
/// without); a forced model whose rule has none is refused.
pub(super) fn forced_points(model: &dyn TapeModel) -> Result<Option<[f64; 2]>, Breakdown> {
    if !(model.has_force() || model.has_dissipation()) {
        return Ok(None);
    }
    model.points().map(Some).ok_or(Breakdown::Rejected("forces with a rule without quadrature points"))
}

/// Newton's unknown (and correction) on the heap without an allocation per
/// iteration: a buffer of the step, borrowed for the solve.
pub(super) struct Slot<'a>(pub(super) &'a RefCell<Vec<f64>>);

impl Unknown for Slot<'_> {
    #[inline]
    fn update(&mut self, dx: &Self) {
        let dx = dx.0.borrow();
        for (x, d) in self.0.borrow_mut().iter_mut().zip(dx.iter()) {
            *x += d;
        }
    }

    #[inline]
    fn error_ratio(&self, dx: &Self, rtol: f64, atol: f64) -> f64 {
        max_abs(&dx.0.borrow()) / (rtol * max_abs(&self.0.borrow()) + atol)
    }
}
