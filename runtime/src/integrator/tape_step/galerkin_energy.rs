//! The energy equation of a Galerkin step on the tape: what an
//! energy-preserving step of a run-time-sized system with a Galerkin rule
//! needs at a trial step size `h` (docs/theory.md §3, §9), as
//! `galerkin/energy.rs` forms it at a compile-time size.
//!
//! ```text
//! record  A(q_k, D_1 … D_s, h)  on the tape      (galerkin.rs)
//! E   = −∂A/∂h = Σ_j b_j E_L(q_h(c_j), q̇_h(c_j))  the step's discrete energy
//! J   = ∂r/∂D   (the Newton block the node equations' iteration factored)
//! b   = ∂r/∂h   from the column H[·, h]: b_{i,0} = H[q_{k,i}, h] − Σ_m H[D_{m,i}, h],  b_{i,m} = H[D_{m,i}, h]
//! c   = ∂E/∂D = −H[h, D],   d = ∂E/∂h = −H[h, h]
//! g'(h) = d − c·J⁻¹b                              (the Schur complement of the bordered Jacobian)
//! dD/dh = −J⁻¹b                                   (the nodes follow the step size)
//! ```
//!
//! One recording, one second-order sweep with the single seed on `h` and
//! one solve with the factors of `J` at the Newton iteration's last fresh
//! iterate (within the Newton tolerance of the solution: the slope only
//! steers the search, the root is that of `g`): `O(N)` for a banded `L`,
//! no `N × N` matrix anywhere. Autonomous systems without forces only, as at
//! a compile-time size: there `∂A/∂t_k = −∂A/∂h = E`, and the energy
//! equation says that the step's discrete energy equals the last one's.

use super::galerkin::GalerkinWork;
use super::node_probes::NodeProbes;
use super::{Node, SparseWork, Taken, TapeModel, tape_breakdown, zeroed};
use crate::banded::StepMatrix;
use crate::newton::{Breakdown, NewtonFailure, NewtonOptions, NewtonReport};
use crate::tape::Seeds;

/// The energy terms of a solved trial step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NodeEnergy {
    /// `E = −∂A/∂h`, the step's discrete energy.
    pub(crate) energy: f64,
    /// `g'(h)` along the solutions of the node equations (NaN where the
    /// Newton block cannot be solved with).
    pub(crate) slope: f64,
    /// The size of the terms of `E`: `|Σ_j b_j v·∂L/∂v| + |Σ_j b_j L|`
    /// (at least `|E|`).
    pub(crate) scale: f64,
}

impl GalerkinWork {
    /// The node equations solved at the trial step `h` from `node`, and
    /// the energy terms there. The Newton iteration starts from the last
    /// probe moved along its tangent (`warm`, after a probe of this step
    /// whose slope is finite) or from the last step's polynomial. Changes
    /// nothing but the probes' scratch: the last step taken stays the next
    /// step's start.
    pub(crate) fn energy_probe(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        (v0, warm): (&[f64], bool),
        options: &NewtonOptions,
    ) -> Result<(NewtonReport, NodeEnergy), NewtonFailure> {
        let unknowns = self.n * self.rule.s;
        if self.probes.nodes.len() != unknowns {
            let too_large =
                |_| NewtonFailure::Rejected { iterations: 0, reason: "the probes' buffers cannot be allocated" };
            self.probes.nodes = zeroed(Some(unknowns), self.n).map_err(too_large)?;
            self.probes.tangent = zeroed(Some(unknowns), self.n).map_err(too_large)?;
        }
        let mut x = core::mem::take(&mut self.trial);
        match self.probes.h {
            Some(from) if warm => {
                let NodeProbes { nodes, tangent, .. } = &self.probes;
                for ((x, d), t) in x.iter_mut().zip(nodes).zip(tangent) {
                    *x = d + (h - from) * t;
                }
            }
            _ => self.predict(h, v0, &mut x),
        }
        let (x, solved) = self.solve_nodes(model, node, h, x, options);
        let report = match solved {
            Ok(report) => report,
            Err(failure) => {
                self.trial = x;
                return Err(failure);
            }
        };
        self.trial = core::mem::replace(&mut self.probes.nodes, x);
        self.probes.h = Some(h);
        match self.node_energy(model, node, h) {
            Ok(terms) => Ok((report, terms)),
            Err(failure) => {
                self.probes.h = None;
                Err(failure.at(report.iterations))
            }
        }
    }

    /// [`NodeEnergy`] at the latest probe's nodes, with the factors of the
    /// Newton block its iteration left; `dD/dh` into the probes' tangent.
    fn node_energy(&mut self, model: &dyn TapeModel, node: &Node<'_>, h: f64) -> Result<NodeEnergy, Breakdown> {
        let (n, s) = (self.n, self.rule.s);
        let stride = s + 1;
        let at_h = n * stride;
        let x = core::mem::take(&mut self.probes.nodes);
        let recorded = self.record(model, node, h, &x);
        self.probes.nodes = x;
        let action = recorded.map_err(tape_breakdown)?;
        if !action.is_finite() {
            return Err(Breakdown::NonFinite("lagrangian"));
        }
        let seed = Seeds::dense(at_h..at_h + 1);
        let column = &mut self.products[..at_h + 1];
        self.tape.hessian_product(&seed, &mut self.gradient, column).map_err(tape_breakdown)?;
        let column = &self.products[..at_h + 1];
        let energy = -self.gradient[at_h];
        // b = ∂r/∂h in the unknowns' order.
        let b = &mut self.probes.tangent;
        for i in 0..n {
            let col = &column[i * stride..(i + 1) * stride];
            b[i * s] = col[0] - col[1..].iter().sum::<f64>();
            b[i * s + 1..(i + 1) * s].copy_from_slice(&col[1..s]);
        }
        let slope = match self.jacobian.solve(b) {
            Ok(()) => {
                // g' = −H[h, h] + H[h, D]·J⁻¹b.
                let mut slope = -column[at_h];
                for i in 0..n {
                    for m in 1..=s {
                        slope += column[i * stride + m] * b[i * s + m - 1];
                    }
                }
                for y in b.iter_mut() {
                    *y = -*y;
                }
                slope
            }
            Err(_) => {
                // A block that cannot be solved with: no slope (the search
                // takes secants), no tangent (the caller's next probe is
                // predicted).
                f64::NAN
            }
        };
        if !energy.is_finite() {
            return Err(Breakdown::NonFinite("energy equation"));
        }
        // Σ_j b_j v·∂L/∂v = E + A/h and Σ_j b_j L = A/h: the terms whose
        // difference is E.
        let mean = action / h;
        Ok(NodeEnergy { energy, slope, scale: energy.abs().max((energy + mean).abs() + mean.abs()) })
    }

    /// Takes the latest probe, of size `h`, as the step from `node` ending
    /// at `t1`: the new state and the step's energy (one more reverse
    /// sweep), its nodes the next step's start. `None` where there is no
    /// probe of that size; on failure nothing of the work's memory changes.
    pub(crate) fn take_probe(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        (h, t1): (f64, f64),
        report: NewtonReport,
        spare: &mut SparseWork,
    ) -> Option<Result<(Taken, f64), NewtonFailure>> {
        if self.probes.h != Some(h) {
            return None;
        }
        let (n, s) = (self.n, self.rule.s);
        let x = core::mem::take(&mut self.probes.nodes);
        let mut dq = spare.buffer();
        for i in 0..n {
            dq[i] = x[i * s + s - 1];
        }
        let finished = self.finish(model, node, h, t1, &x, dq, report, spare);
        self.probes.h = None;
        Some(match finished {
            Ok(done) => {
                // The step's nodes become the next step's start; the old
                // ones, the next probe's buffer.
                match self.last.replace((h, x)) {
                    Some((_, old)) => self.probes.nodes = old,
                    None => self.probes.nodes = Vec::new(),
                }
                Ok(done)
            }
            Err(failure) => {
                self.probes.nodes = x;
                Err(failure)
            }
        })
    }
}
