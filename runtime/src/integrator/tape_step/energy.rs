//! The energy equation of a step on the tape: what an energy-preserving
//! step of a run-time-sized system needs at a trial step size `h`
//! (docs/theory.md §9).
//!
//! ```text
//! record  Ã(q_k, Δq, h, t_k)  on the tape       (t_{k+1} = t_k + h)
//! ∂A/∂t_k     = Ã_t − Ã_h,   E_{k+1} = −Ã_h,   ∂A/∂t_k + ∂A/∂t_{k+1} = Ã_t
//! J = ∂R_q/∂Δq  (banded seeds on Δq)            R_q = p_k + ∂A/∂q_k
//! c = ∂R_q/∂h   = Ã_{q_k h} − Ã_{Δq h}          (the seed on h)
//! r = ∂(∂A/∂t_k)/∂Δq = Ã_{Δq t} − Ã_{Δq h},   d = ∂(∂A/∂t_k)/∂h = Ã_{h t} − Ã_{h h}
//! g'(h) = d − r·J⁻¹c                            (the Schur complement of the bordered Jacobian)
//! ```
//!
//! One recording, one second-order sweep with the seeds on `h` (and on
//! `t_k` for a time-dependent `L`) and one solve with the factors of `J`
//! that the DEL's Newton iteration has just formed (at its last fresh
//! iterate, within the Newton tolerance of the solution: the slope only
//! steers the search, the root is that of `g`): `O(N)` for a banded `L`,
//! less than a Newton iteration of the step itself.

use super::{Guess, Node, SparseWork, TapeModel, breakdown, tape_breakdown, zeroed};
use crate::banded::StepMatrix;
use crate::newton::{Breakdown, NewtonFailure, NewtonOptions, NewtonReport};
use crate::tape::{Seeds, Var};

/// The step's energy terms at a solved trial step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct EnergyTerms {
    /// `∂A/∂t_k`: the left side of the energy equation `∂A/∂t_k = E_k`.
    pub(crate) d_t0: f64,
    /// `∂A/∂t_k + ∂A/∂t_{k+1}`: zero for an autonomous `L`, else the
    /// change `E_k − E_{k+1}` of the discrete energy across the step.
    pub(crate) time_shift: f64,
    /// `g'(h)` along the solutions of the DEL (NaN where the step Jacobian
    /// cannot be factored).
    pub(crate) slope: f64,
}

/// The buffers of [`SparseWork::energy_probe`]: scratch, filled afresh by
/// every probe (a copy starts without them).
#[derive(Debug, Default)]
pub(crate) struct EnergyBuffers {
    /// `(q_k, Δq, h, t_k)`.
    inputs: Vec<f64>,
    gradient: Vec<f64>,
    /// `H·S` of the seeds on `h` (and `t_k`).
    columns: Vec<f64>,
    /// `J⁻¹c`.
    column: Vec<f64>,
}

impl EnergyBuffers {
    /// `J⁻¹c` of the last probe whose slope is finite: `−dΔq/dh` along the
    /// solutions of the DEL.
    pub(crate) fn tangent(&self) -> &[f64] {
        &self.column
    }
}

impl Clone for EnergyBuffers {
    fn clone(&self) -> Self {
        Self::default()
    }

    /// Scratch: nothing to copy.
    fn clone_from(&mut self, _: &Self) {}
}

impl SparseWork {
    /// The DEL solved at the trial step `h` from `node` (the step's own
    /// Newton iteration, banded or dense), and the energy terms there.
    /// Changes nothing but the work's scratch.
    pub(crate) fn energy_probe(
        &mut self,
        buffers: &mut EnergyBuffers,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        guess: &Guess<'_>,
        options: &NewtonOptions,
    ) -> Result<(Vec<f64>, NewtonReport, EnergyTerms), NewtonFailure> {
        let (dq, report) = self.solve(model, node, h, guess, options)?;
        match self.energy_terms(buffers, model, node, h, &dq) {
            Ok(terms) => Ok((dq, report, terms)),
            Err(failure) => {
                self.recycle(dq);
                Err(failure.at(report.iterations))
            }
        }
    }

    /// [`EnergyTerms`] at the increment `dq` of a step of size `h` from
    /// `node`, with the factors of the step Jacobian the DEL's Newton
    /// iteration left.
    fn energy_terms(
        &mut self,
        buffers: &mut EnergyBuffers,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        dq: &[f64],
    ) -> Result<EnergyTerms, Breakdown> {
        let n = self.n;
        let (at_h, at_t) = (2 * n, 2 * n + 1);
        // The seed on `t_k` only where `L` depends on time.
        let timed = Seeds::dense(at_h..if model.autonomous() { at_h + 1 } else { at_t + 1 });
        let k = timed.directions();
        if buffers.inputs.len() != 2 * n + 2 {
            let inputs = n.checked_mul(2).and_then(|x| x.checked_add(2));
            buffers.inputs = zeroed(inputs, n).map_err(breakdown)?;
            buffers.gradient = zeroed(inputs, n).map_err(breakdown)?;
            buffers.columns = zeroed(inputs.and_then(|i| i.checked_mul(2)), n).map_err(breakdown)?;
            buffers.column = zeroed(Some(n), n).map_err(breakdown)?;
        }
        let EnergyBuffers { inputs, gradient, columns, column } = buffers;
        let columns = &mut columns[..(2 * n + 2) * k];
        inputs[..n].copy_from_slice(node.q);
        inputs[n..2 * n].copy_from_slice(dq);
        (inputs[at_h], inputs[at_t]) = (h, node.t);
        let action = self
            .tape
            .record(inputs, |x: &[Var]| model.action(x[at_t], x[at_h], &x[..n], &x[n..2 * n]))
            .map_err(tape_breakdown)?;
        if !action.is_finite() {
            return Err(Breakdown::NonFinite("lagrangian"));
        }
        // The gradient, with the columns of `h` and `t_k`.
        self.tape.hessian_product(&timed, gradient, columns).map_err(tape_breakdown)?;
        let (g_h, g_t) = (gradient[at_h], if model.autonomous() { 0.0 } else { gradient[at_t] });
        let d_t0 = g_t - g_h;
        // H[i, h] and H[i, t_k] (zero for an autonomous `L`).
        let at = |i: usize| (columns[i * k], if k == 2 { columns[i * k + 1] } else { 0.0 });
        for (i, c) in column.iter_mut().enumerate() {
            *c = at(i).0 - at(n + i).0;
        }
        let (hh, ht) = at(at_h);
        let d = ht - hh;
        let slope = match self.jacobian.solve(column) {
            Ok(()) => {
                let mut r_y = 0.0;
                for (j, y) in column.iter().enumerate() {
                    let (dh, dt) = at(n + j);
                    r_y += (dt - dh) * y;
                }
                d - r_y
            }
            _ => f64::NAN,
        };
        if !d_t0.is_finite() {
            return Err(Breakdown::NonFinite("energy equation"));
        }
        Ok(EnergyTerms { d_t0, time_shift: g_t, slope })
    }
}
