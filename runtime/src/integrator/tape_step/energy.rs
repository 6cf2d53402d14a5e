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
//!
//! A forced system (energy-balance steps, docs/theory.md §6) adds the
//! discrete Lagrange–d'Alembert terms of time as a variable: `F_k^−` joins
//! the DEL (and `∂F_k^−/∂Δq` the `J` its Newton iteration factored), and
//! the work `w_k^− = F_k^−·Δq/h` of the start force on `δt_k` the energy
//! equation:
//!
//! ```text
//! ∂A/∂t_k − w_k^− = E_k + w_{k−1}^+      c += ∂F_k^−/∂h,   r −= ∂w_k^−/∂Δq,   d −= ∂w_k^−/∂h
//! ```
//!
//! `∂F_k^−/∂h`, `∂w_k^−/∂h` and `(∂w_k^−/∂Δq)·J⁻¹c` are central differences
//! of the forces' values (four more evaluations of the forces, `O(N)`):
//! they enter the slope alone, which steers the search to the root of the
//! exact `g`, and at a relative step of `2⁻¹⁷` they are good to about
//! `1e-10`, far below what the search needs.

use super::implicit::forced_points;
use super::{Guess, Node, SparseWork, TapeModel, breakdown, tape_breakdown, zeroed};
use crate::banded::StepMatrix;
use crate::newton::{Breakdown, NewtonFailure, NewtonOptions, NewtonReport};
use crate::real::max_abs;
use crate::tape::{Seeds, Var};

/// The relative step of the central differences of the forces in `h` and
/// along `J⁻¹c`: `2⁻¹⁷` balances their truncation (`~δ²`) against their
/// rounding (`~ε/δ`) at about `1e-10`.
const STEP_FRACTION: f64 = 1.0 / 131_072.0;

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
    /// `w_k^− = F_k^−·Δq/h`, the work of the start force on a variation of
    /// `t_k` (zero without forces): it is already in `d_t0`, and joins the
    /// energy balance `E_{k+1} = E_k + w_{k−1}^+ + w_k^−` of the step.
    pub(crate) work: f64,
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
    /// The forces of a forced system: `F_k^−` at `h ± δ`, `F_k^+` (unused),
    /// `∂F_k^−/∂h` and the increment `Δq ± ε J⁻¹c`.
    ahead: Vec<f64>,
    behind: Vec<f64>,
    plus: Vec<f64>,
    d_minus_h: Vec<f64>,
    moved: Vec<f64>,
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
        let forced = forced_points(model)?;
        if forced.is_some() && buffers.moved.len() != n {
            for b in
                [&mut buffers.ahead, &mut buffers.behind, &mut buffers.plus, &mut buffers.d_minus_h, &mut buffers.moved]
            {
                *b = zeroed(Some(n), n).map_err(breakdown)?;
            }
        }
        let EnergyBuffers { inputs, gradient, columns, column, ahead, behind, plus, d_minus_h, moved } = buffers;
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
        let mut d_t0 = g_t - g_h;
        // H[i, h] and H[i, t_k] (zero for an autonomous `L`).
        let at = |i: usize| (columns[i * k], if k == 2 { columns[i * k + 1] } else { 0.0 });
        for (i, c) in column.iter_mut().enumerate() {
            *c = at(i).0 - at(n + i).0;
        }
        let (hh, ht) = at(at_h);
        let mut d = ht - hh;
        let mut work = 0.0;
        if let Some(points) = forced {
            // w_k^− and, by central differences in `h`, ∂F_k^−/∂h and ∂w_k^−/∂h.
            let step = (node.t, h, points);
            work = self.start_work(model, step, node.q, dq, ahead, plus)?;
            let delta = h * STEP_FRACTION;
            let w_ahead = self.start_work(model, (node.t, h + delta, points), node.q, dq, ahead, plus)?;
            let w_behind = self.start_work(model, (node.t, h - delta, points), node.q, dq, behind, plus)?;
            let scale = (2.0 * delta).recip();
            for ((x, a), b) in d_minus_h.iter_mut().zip(ahead.iter()).zip(behind.iter()) {
                *x = (a - b) * scale;
            }
            for (c, x) in column.iter_mut().zip(d_minus_h.iter()) {
                *c += x;
            }
            d -= (w_ahead - w_behind) * scale;
            d_t0 -= work;
        }
        let slope = match self.jacobian.solve(column) {
            Ok(()) => {
                let mut r_y = 0.0;
                for (j, y) in column.iter().enumerate() {
                    let (dh, dt) = at(n + j);
                    r_y += (dt - dh) * y;
                }
                if let Some(points) = forced {
                    // (∂w_k^−/∂Δq)·J⁻¹c, a central difference along J⁻¹c.
                    let (size, length) = (max_abs(dq), max_abs(column));
                    if length > 0.0 {
                        let epsilon = STEP_FRACTION * size.max(f64::MIN_POSITIVE) / length;
                        let mut along = |sign: f64, moved: &mut [f64]| {
                            for ((m, x), y) in moved.iter_mut().zip(dq).zip(column.iter()) {
                                *m = x + sign * epsilon * y;
                            }
                            self.start_work(model, (node.t, h, points), node.q, moved, ahead, plus)
                        };
                        let (w_ahead, w_behind) = (along(1.0, moved)?, along(-1.0, moved)?);
                        r_y -= (w_ahead - w_behind) / (2.0 * epsilon);
                    }
                }
                d - r_y
            }
            _ => f64::NAN,
        };
        if !d_t0.is_finite() {
            return Err(Breakdown::NonFinite("energy equation"));
        }
        Ok(EnergyTerms { d_t0, time_shift: g_t, slope, work })
    }

    /// The work `F_k^−·Δq/h` of the start force of the step `(t_k, h)` from
    /// `q0` by `dq` on a variation of `t_k`, with `F_k^−` left in `minus`.
    fn start_work(
        &mut self,
        model: &dyn TapeModel,
        step: (f64, f64, [f64; 2]),
        q0: &[f64],
        dq: &[f64],
        minus: &mut [f64],
        plus: &mut [f64],
    ) -> Result<f64, Breakdown> {
        self.forcing.forces(model, step, q0, dq, minus, plus, None)?;
        let inv_h = step.1.recip();
        Ok(minus.iter().zip(dq).map(|(f, x)| f * (x * inv_h)).sum())
    }

    /// `w_k^+ = F_k^+·Δq/h`: the work of the end force of the step `(t_k,
    /// h)` from `q0` by `dq` on a variation of its end time, the term the
    /// next step's energy equation carries (zero without forces).
    pub(crate) fn end_work(
        &mut self,
        model: &dyn TapeModel,
        (t0, h): (f64, f64),
        q0: &[f64],
        dq: &[f64],
    ) -> Result<f64, Breakdown> {
        let Some(points) = forced_points(model)? else { return Ok(0.0) };
        let (mut minus, mut plus) = (self.buffer(), self.buffer());
        let forces = self.forcing.forces(model, (t0, h, points), q0, dq, &mut minus, &mut plus, None);
        let inv_h = h.recip();
        let work = plus.iter().zip(dq).map(|(f, x)| f * (x * inv_h)).sum();
        self.recycle(minus);
        self.recycle(plus);
        forces.map(|()| work)
    }
}
