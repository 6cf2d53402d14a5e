//! The Galerkin step of a run-time-sized system on the tape (docs/theory.md
//! §5): the action of the step polynomial through `s + 1` control nodes,
//! recorded over slices, and its `sN` node equations solved by Newton with
//! the tape's compressed Hessian and banded or dense solves.
//!
//! ```text
//! inputs  x = (q_k, D_1 … D_s, h), coordinate-major: x[i(s+1)] = q_{k,i}, x[i(s+1) + m] = D_{m,i}
//! A = h Σ_j b_j L(t_k + c_j h, q_k + e + Σ_m ℓ_m(c_j) D_m, (Σ_m ℓ_m'(c_j) D_m)/h)     (e: q_k's Kahan carry)
//! unknowns D_m = Q_m − q_k, m = 1 … s, ordered u = i·s + m − 1
//! r_{i,0} = p_k + ∂A/∂Q_0 = p_k + g_{q_k} − Σ_m g_{D_m}     r_{i,m} = ∂A/∂Q_m = g_{D_m}, m = 1 … s − 1
//! q_{k+1} = q_k + D_s,   p_{k+1} = ∂A/∂Q_s = p_k + g_{q_k},   E_{k+1} = −g_h
//! ```
//!
//! A forced or dissipative system's node equations gain the discrete
//! Lagrange–d'Alembert forces `F^ρ` and the momentum change their impulse
//! (`galerkin_forces.rs`).
//!
//! The variables of coordinate `i` sit next to each other, so an `L` whose
//! Hessian has bandwidth `b` gives an action Hessian of bandwidth
//! `b(s + 1) + s` (the seeds of one second-order sweep: `2b(s + 1) + 2s + 1`
//! directions, whatever `N`) and a Newton block of bandwidth `(b + 1)s − 1`:
//! a chain of `N` coordinates steps in `O(N)`. Everything is on the heap;
//! nothing on the stack grows with `N`.

use core::cell::RefCell;

use super::galerkin_forces::GalerkinForcing;
pub(crate) use super::galerkin_rule::{BlockLayout, Rule};
use super::implicit::Slot;
use super::node_probes::NodeProbes;
use super::{Guess, Node, SparseWork, TAPE_FAILED, Taken, TapeModel, assemble_and_factor, breakdown, filled, zeroed};
use crate::banded::{LinearSolveError, StepMatrix, StepSolver};
use crate::newton::{self, Breakdown, Jacobian, Linearization, NewtonFailure, NewtonOptions, NewtonReport};
use crate::real::{kahan_into, max_abs};
use crate::structure::{Coupling, Pattern};
use crate::tape::{Seeds, Tape, TapeError, Var};

/// The work of Galerkin steps on the tape for one system size and rule:
/// the tape, its sweeps' buffers, the Newton block, and the last step's
/// node increments (the next step's start).
#[derive(Debug)]
pub(crate) struct GalerkinWork {
    pub(super) rule: Rule,
    pub(super) n: usize,
    /// The bandwidth of the action's Hessian in the tape's input order
    /// (`None`: dense seeds).
    hessian_bandwidth: Option<usize>,
    /// The bandwidth of the Newton block (`None`: dense).
    block_bandwidth: Option<usize>,
    /// The bandwidth of `L`'s Hessian (`None`: general coupling).
    coupling_bandwidth: Option<usize>,
    pub(super) tape: Tape,
    inputs: Vec<f64>,
    pub(super) gradient: Vec<f64>,
    pub(super) products: Vec<f64>,
    /// The action's Hessian rows in band (or whole-row) storage.
    hessian: Vec<f64>,
    /// The Newton block's rows in band (or whole-row) storage.
    band: Vec<f64>,
    pub(super) jacobian: StepSolver,
    /// The step's position and velocity at one point, as tape numbers.
    point: RefCell<(Vec<Var>, Vec<Var>)>,
    /// `(h, D)` of the last step taken, `D` in the unknowns' order.
    pub(super) last: Option<(f64, Vec<f64>)>,
    /// The unknowns of the step being taken.
    pub(super) trial: Vec<f64>,
    /// Newton's residual and correction.
    correction: Vec<f64>,
    /// The extrapolation weights of the last step's polynomial, `s × s`.
    extrapolation: Vec<f64>,
    /// The discrete forces' buffers, made at the first step of a forced
    /// system.
    forcing: Option<Box<GalerkinForcing>>,
    /// The trial steps of energy-preserving steps (scratch).
    pub(super) probes: NodeProbes,
}

impl Clone for GalerkinWork {
    fn clone(&self) -> Self {
        Self {
            rule: self.rule.clone(),
            n: self.n,
            hessian_bandwidth: self.hessian_bandwidth,
            block_bandwidth: self.block_bandwidth,
            coupling_bandwidth: self.coupling_bandwidth,
            tape: Tape::new(),
            inputs: self.inputs.clone(),
            gradient: self.gradient.clone(),
            products: self.products.clone(),
            hessian: self.hessian.clone(),
            band: self.band.clone(),
            jacobian: self.jacobian.clone(),
            point: RefCell::new(self.point.borrow().clone()),
            last: self.last.clone(),
            trial: self.trial.clone(),
            correction: self.correction.clone(),
            extrapolation: self.extrapolation.clone(),
            forcing: None,
            probes: NodeProbes::default(),
        }
    }

    /// Copies what persists between steps (the last step's nodes and the
    /// unknowns' buffer) into the buffers `self` has, and leaves its scratch
    /// (tape, Hessian, Newton block, extrapolation weights: filled afresh by
    /// every step) as it is, as `SparseWork::clone_from` does: a `solve` that
    /// may have to go back refreshes its copy of the integrator before every
    /// step without allocating.
    fn clone_from(&mut self, source: &Self) {
        let shape = |w: &Self| (w.n, w.hessian_bandwidth, w.block_bandwidth, w.coupling_bandwidth);
        if shape(self) != shape(source) || self.rule != source.rule {
            *self = source.clone();
            return;
        }
        match (&mut self.last, &source.last) {
            (Some((h, d)), Some((source_h, source_d))) => {
                *h = *source_h;
                d.clone_from(source_d);
            }
            (to, from) => to.clone_from(from),
        }
        self.trial.clone_from(&source.trial);
    }
}

impl GalerkinWork {
    /// Work for `n` coordinates with the given coupling under `rule`; a size
    /// whose buffers cannot be allocated is an error, not an abort.
    pub(crate) fn new(n: usize, coupling: Coupling, rule: Rule) -> Result<Self, LinearSolveError> {
        let s = rule.s;
        let too_large = LinearSolveError::TooLarge { n, per_column: usize::MAX };
        let stride = s + 1;
        let nodes = n.checked_mul(stride).ok_or(too_large)?;
        let unknowns = n.checked_mul(s).ok_or(too_large)?;
        let coupling_bandwidth = super::step_bandwidth(coupling, n);
        let hessian_bandwidth = coupling_bandwidth
            .and_then(|b| b.checked_mul(stride)?.checked_add(s))
            .filter(|&w| w.checked_mul(2).is_some_and(|w| w + 1 < nodes));
        let block_bandwidth = coupling_bandwidth
            .and_then(|b| (b + 1).checked_mul(s)?.checked_sub(1))
            .filter(|&w| w.checked_mul(2).is_some_and(|w| w + 1 < unknowns));
        let seeds = match hessian_bandwidth {
            Some(b) => Seeds::banded(0..nodes, b),
            None => Seeds::dense(0..nodes),
        };
        let directions = seeds.directions();
        let inputs = nodes + 1;
        let hessian_width = hessian_bandwidth.map_or(nodes, |b| 2 * b + 1);
        let block_width = block_bandwidth.map_or(unknowns, |b| 2 * b + 1);
        let pattern = block_bandwidth.map_or(Pattern::General, |b| Pattern::banded(unknowns, b));
        Ok(Self {
            rule,
            n,
            hessian_bandwidth,
            block_bandwidth,
            coupling_bandwidth,
            tape: Tape::new(),
            inputs: zeroed(Some(inputs), n)?,
            gradient: zeroed(Some(inputs), n)?,
            products: zeroed(inputs.checked_mul(directions), n)?,
            hessian: zeroed(nodes.checked_mul(hessian_width), n)?,
            band: zeroed(unknowns.checked_mul(block_width), n)?,
            jacobian: StepSolver::for_pattern(unknowns, pattern)?,
            point: RefCell::new((filled(n, Var::constant(0.0))?, filled(n, Var::constant(0.0))?)),
            last: None,
            trial: zeroed(Some(unknowns), n)?,
            correction: zeroed(Some(unknowns), n)?,
            extrapolation: vec![0.0; s * s],
            forcing: None,
            probes: NodeProbes::default(),
        })
    }

    /// The rule.
    pub(crate) fn rule(&self) -> &Rule {
        &self.rule
    }

    /// The node increments `D_1 … D_s` of the last step taken, `D_m` of
    /// coordinate `i` at `i·s + m − 1`, with its size.
    pub(crate) fn last_nodes(&self) -> Option<(f64, &[f64])> {
        self.last.as_ref().map(|(h, d)| (*h, &d[..]))
    }

    /// The seeds of the second-order sweep.
    fn seeds(&self) -> Seeds<'static> {
        let nodes = self.n * (self.rule.s + 1);
        match self.hessian_bandwidth {
            Some(b) => Seeds::banded(0..nodes, b),
            None => Seeds::dense(0..nodes),
        }
    }

    /// The first guess of the unknowns for a step of size `h` into `out`:
    /// the last step's polynomial extrapolated to this step's control nodes
    /// (error `O(h^{s+1})`), or at the first step the straight line
    /// `τ_m h v_0`.
    pub(super) fn predict(&mut self, h: f64, v0: &[f64], out: &mut [f64]) {
        let (n, s) = (self.n, self.rule.s);
        let w = &mut self.extrapolation;
        match &self.last {
            Some((h_last, d)) => {
                let rho = h / h_last;
                // In the last step's variable: 1 + τ_m h/h_last.
                for m in 0..s {
                    let tau = 1.0 + self.rule.tau[m + 1] * rho;
                    for k in 0..s {
                        w[m * s + k] = self.rule.basis(k + 1, tau) - if k + 1 == s { 1.0 } else { 0.0 };
                    }
                }
                for i in 0..n {
                    let last = &d[i * s..(i + 1) * s];
                    for m in 0..s {
                        out[i * s + m] = (0..s).map(|k| w[m * s + k] * last[k]).sum();
                    }
                }
            }
            None => {
                for i in 0..n {
                    for m in 0..s {
                        out[i * s + m] = self.rule.tau[m + 1] * h * v0[i];
                    }
                }
            }
        }
    }

    /// Records the action at the unknowns `x` from `node`.
    pub(super) fn record(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        x: &[f64],
    ) -> Result<f64, TapeError> {
        let (n, s) = (self.n, self.rule.s);
        let stride = s + 1;
        for i in 0..n {
            self.inputs[i * stride] = node.q[i];
            self.inputs[i * stride + 1..(i + 1) * stride].copy_from_slice(&x[i * s..(i + 1) * s]);
        }
        self.inputs[n * stride] = h;
        let (rule, point) = (&self.rule, &self.point);
        let carry = (!node.plain).then_some(node.q_carry);
        let t0 = node.t;
        self.tape.record(&self.inputs, |x: &[Var]| {
            let h = x[n * stride];
            let mut point = point.borrow_mut();
            let (q, v) = &mut *point;
            let mut sum: Option<Var> = None;
            for (j, (&c, &b)) in rule.points.iter().zip(&rule.weights).enumerate() {
                let (col, col_d) = (&rule.col[j * s..(j + 1) * s], &rule.col_d[j * s..(j + 1) * s]);
                for i in 0..n {
                    let d = &x[i * stride + 1..(i + 1) * stride];
                    let e = carry.map_or(0.0, |e| e[i]);
                    // `q_k + (e + Σ ℓ_m D_m)`, the sum in the const-size step's order.
                    let mut acc = if e != 0.0 { Var::constant(e) + d[0] * col[0] } else { d[0] * col[0] };
                    let mut slope = d[0] * col_d[0];
                    for m in 1..s {
                        acc += d[m] * col[m];
                        slope += d[m] * col_d[m];
                    }
                    q[i] = x[i * stride] + acc;
                    // Divided, not multiplied by a rounded 1/h, as at a compile-time size.
                    v[i] = slope / h;
                }
                let term = model.lagrangian(Var::constant(t0) + h * c, q, v) * b;
                sum = Some(match sum {
                    Some(total) => total + term,
                    None => term,
                });
            }
            sum.unwrap_or(Var::constant(0.0)) * h
        })
    }

    /// The residual of the node equations from the gradient into `r`, and
    /// the scale of its terms.
    fn residual(&self, node: &Node<'_>, r: &mut [f64]) -> f64 {
        let (n, s) = (self.n, self.rule.s);
        let stride = s + 1;
        let g = &self.gradient;
        let mut scale = max_abs(node.p);
        for i in 0..n {
            let row = &g[i * stride..(i + 1) * stride];
            let d_q0 = row[0] - row[1..].iter().sum::<f64>();
            r[i * s] = (node.p[i] + d_q0) + node.p_carry[i];
            scale = scale.max(d_q0.abs());
            for m in 1..s {
                r[i * s + m] = row[m];
            }
        }
        scale
    }

    /// The Hessian entry between inputs `a` and `c` from the recovered rows.
    fn hessian_at(&self, a: usize, c: usize) -> f64 {
        match self.hessian_bandwidth {
            Some(b) => {
                let width = 2 * b + 1;
                match (c + b).checked_sub(a).filter(|&k| k < width) {
                    Some(k) => self.hessian[a * width + k],
                    None => 0.0,
                }
            }
            None => self.hessian[a * self.n * (self.rule.s + 1) + c],
        }
    }

    /// The Newton block `∂r/∂D` from the recovered Hessian into `band`.
    fn assemble(&mut self) {
        let (n, s) = (self.n, self.rule.s);
        let stride = s + 1;
        let layout = BlockLayout::new(n * s, self.block_bandwidth);
        let slot = |e: usize, u: usize| layout.slot(e, u);
        let mut band = core::mem::take(&mut self.band);
        band.fill(0.0);
        for i in 0..n {
            let neighbours = match self.coupling_bandwidth {
                Some(b) => i.saturating_sub(b)..(i + b + 1).min(n),
                None => 0..n,
            };
            for j in neighbours {
                for m in 1..=s {
                    let column = j * stride + m;
                    let u = j * s + m - 1;
                    // Row 0: ∂/∂D of g_{q_k} − Σ_k g_{D_k}; rows k ≥ 1: of g_{D_k}.
                    let mut interior = 0.0;
                    for k in 1..=s {
                        let entry = self.hessian_at(i * stride + k, column);
                        interior += entry;
                        if k < s {
                            band[slot(i * s + k, u)] = entry;
                        }
                    }
                    band[slot(i * s, u)] = self.hessian_at(i * stride, column) - interior;
                }
            }
        }
        self.band = band;
    }

    /// The residual (into `r`, returning the scale of its terms) at the
    /// unknowns `x`, and for a fresh `jacobian` the Newton block, factored.
    #[allow(clippy::too_many_arguments)]
    fn linearize(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        x: &[f64],
        r: &mut [f64],
        jacobian: Jacobian,
        min_rcond: f64,
    ) -> Result<f64, Breakdown> {
        self.record(model, node, h, x).map_err(super::tape_breakdown)?;
        let seeds = self.seeds();
        match jacobian {
            Jacobian::Kept => self.tape.gradient(&mut self.gradient),
            Jacobian::Fresh => self.tape.hessian_product(&seeds, &mut self.gradient, &mut self.products),
        }
        .map_err(super::tape_breakdown)?;
        let mut scale = self.residual(node, r);
        let fresh = jacobian == Jacobian::Fresh;
        if fresh {
            let nodes = self.n * (self.rule.s + 1);
            seeds.recover(&self.products, 0..nodes, &mut self.hessian).map_err(super::tape_breakdown)?;
            self.assemble();
        }
        let unknowns = self.n * self.rule.s;
        if let Some(forcing) = self.forcing.as_deref_mut() {
            // The discrete forces on the nodes, and their derivatives in the block.
            let block = fresh.then_some((BlockLayout::new(unknowns, self.block_bandwidth), &mut self.band[..]));
            let forces = forcing.add(model, &self.rule, node, h, x, Some(r), None, block)?;
            scale = scale.max(forces);
        }
        if fresh {
            assemble_and_factor(&mut self.jacobian, unknowns, self.block_bandwidth, &self.band, min_rcond)?;
        }
        Ok(scale)
    }

    /// One step of size `h` from `node`, ending at time `t1`: Newton on the
    /// node equations from the last step's polynomial (or the straight line
    /// along `v0` at the first step), then the new momentum and the step's
    /// discrete energy from one more reverse sweep. The buffers of the
    /// [`Taken`] come from `spare`. On success the step's node increments
    /// replace the last step's (the caller commits the step); on failure
    /// nothing of the work's memory changes.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn step(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        t1: f64,
        v0: &[f64],
        options: &NewtonOptions,
        spare: &mut SparseWork,
    ) -> Result<(Taken, f64), NewtonFailure> {
        let (n, s) = (self.n, self.rule.s);
        if self.forcing.is_none() && (model.has_force() || model.has_dissipation()) {
            let forcing =
                GalerkinForcing::new(n, self.coupling_bandwidth, &self.rule).map_err(|_| NewtonFailure::Rejected {
                    iterations: 0,
                    reason: "the buffers of the discrete forces cannot be allocated",
                })?;
            self.forcing = Some(Box::new(forcing));
        }
        let mut x = core::mem::take(&mut self.trial);
        self.predict(h, v0, &mut x);
        // The growth check compares the end increment with the predicted and
        // the last one.
        let mut predicted = spare.buffer();
        let mut scaled = spare.buffer();
        for i in 0..n {
            predicted[i] = x[i * s + s - 1];
        }
        let has_last = match &self.last {
            Some((h_last, d)) => {
                for i in 0..n {
                    scaled[i] = d[i * s + s - 1] * (h / h_last);
                }
                true
            }
            None => false,
        };
        let unknowns = n * s;
        let (x, solved) = self.solve_nodes(model, node, h, x, options);
        let mut dq = spare.buffer();
        for i in 0..n {
            dq[i] = x[i * s + s - 1];
        }
        let guess = Guess { predictor: &predicted, last: has_last.then_some(&scaled[..]) };
        let checked = solved.and_then(|report| guess.check(&dq, node.q, report.iterations).map(|()| report));
        spare.recycle(predicted);
        spare.recycle(scaled);
        let finished = checked.and_then(|report| self.finish(model, node, h, t1, &x, dq, report, spare));
        match finished {
            Ok(done) => {
                // The step's nodes become the next step's start.
                let old = self.last.replace((h, x));
                self.trial = old.map_or_else(|| vec![0.0; unknowns], |(_, d)| d);
                Ok(done)
            }
            Err(failure) => {
                self.trial = x;
                Err(failure)
            }
        }
    }

    /// Newton on the node equations of a step of size `h` from `node`,
    /// started from the unknowns `x`: the iterate it ends at (the solution
    /// where the report is `Ok`), and the factors of the Newton block at its
    /// last fresh iterate left in `jacobian`.
    pub(super) fn solve_nodes(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        x: Vec<f64>,
        options: &NewtonOptions,
    ) -> (Vec<f64>, Result<NewtonReport, NewtonFailure>) {
        let q_floor = 4.0 * f64::EPSILON * max_abs(node.q);
        let min_rcond = options.min_rcond;
        let (iterate, correction) = (RefCell::new(x), RefCell::new(core::mem::take(&mut self.correction)));
        let mut first = true;
        let linearize = |at: &Slot<'_>, jacobian: Jacobian| -> Result<Linearization<Slot<'_>>, Breakdown> {
            let x = at.0.borrow();
            let mut r = correction.borrow_mut();
            // The condition estimate on the first factorisation of the step only.
            let floor = if first && jacobian == Jacobian::Fresh { min_rcond } else { 0.0 };
            if jacobian == Jacobian::Fresh {
                first = false;
            }
            let scale = self.linearize(model, node, h, &x, &mut r, jacobian, floor)?;
            if !r.iter().all(|x| x.is_finite()) {
                return Err(Breakdown::NonFinite("residual"));
            }
            let residual_norm = max_abs(&r);
            self.jacobian.solve(&mut r).map_err(breakdown)?;
            for x in r.iter_mut() {
                *x = -*x;
            }
            let lin = Linearization::new(Slot(&correction), residual_norm).cancelling(scale).floor(q_floor);
            Ok(if jacobian == Jacobian::Kept { lin.kept() } else { lin })
        };
        let solved = newton::solve(Slot(&iterate), options, linearize).map(|(_, report)| report);
        let x = iterate.into_inner();
        self.correction = correction.into_inner();
        (x, solved)
    }

    /// After convergence at `x`: the new state and the step's energy.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn finish(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        t1: f64,
        x: &[f64],
        dq: Vec<f64>,
        report: NewtonReport,
        spare: &mut SparseWork,
    ) -> Result<(Taken, f64), NewtonFailure> {
        let (n, s) = (self.n, self.rule.s);
        let stride = s + 1;
        let swept = self.record(model, node, h, x).and_then(|a| self.tape.gradient(&mut self.gradient).map(|()| a));
        let action = match swept {
            Ok(action) => action,
            Err(_) => {
                spare.recycle(dq);
                return Err(NewtonFailure::Rejected { iterations: report.iterations, reason: TAPE_FAILED });
            }
        };
        if !action.is_finite() {
            spare.recycle(dq);
            return Err(NewtonFailure::NonFinite { iterations: report.iterations, quantity: "lagrangian" });
        }
        let energy = -self.gradient[n * stride];
        let mut dp = spare.buffer();
        for i in 0..n {
            dp[i] = self.gradient[i * stride];
        }
        if let Some(forcing) = self.forcing.as_deref_mut() {
            // p_{k+1} − p_k = h Σ_j b_j (∂L/∂q + F)(c_j): the forces on all
            // s + 1 nodes sum to the impulse h Σ_j b_j F_j.
            if let Err(failure) = forcing.add(model, &self.rule, node, h, x, None, Some(&mut dp), None) {
                spare.recycle(dq);
                spare.recycle(dp);
                return Err(failure.at(report.iterations));
            }
        }
        let mut taken = spare.taken(dq, report);
        if node.plain {
            for i in 0..n {
                taken.q1[i] = node.q[i] + taken.dq[i];
                taken.p1[i] = node.p[i] + dp[i];
            }
        } else {
            kahan_into(node.q, node.q_carry, &taken.dq, &mut taken.q1, &mut taken.q_carry);
            kahan_into(node.p, node.p_carry, &dp, &mut taken.p1, &mut taken.p_carry);
        }
        spare.recycle(dp);
        if let Some(quantity) = crate::integrator::non_finite(t1, &taken.q1, &taken.p1) {
            spare.recycle_taken(taken);
            return Err(NewtonFailure::NonFinite { iterations: report.iterations, quantity });
        }
        Ok((taken, energy))
    }
}
