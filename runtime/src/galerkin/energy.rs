//! Energy-preserving variable steps for Galerkin discrete Lagrangians: the
//! step size as one more unknown (docs/theory.md §3; Chen, Guo & Wu (finite elements) §3, time steps as
//! variables).
//!
//! ```text
//! unknowns (D_1 … D_s, h):   the sN equations of the fixed step, at step size h
//!                            E(D, h) − E_k = 0,   E = −∂A/∂h = Σ_j b_j E_L(q_h(c_j), q̇_h(c_j))
//! ```
//!
//! For an autonomous `L` the discrete energy of a Galerkin step is the
//! quadrature of the continuous energy `E_L = v·∂L/∂v − L` along the step
//! polynomial (differentiate `A = h Σ_j b_j L(q(c_j), Σ_n ℓ_n'(c_j) D_n / h)`
//! in `h` at fixed nodes), and the energy equation `−E_k + ∂A/∂t_k = 0` says
//! that it equals the previous step's. The step size is found by Newton on
//! `g(h) = E(D(h), h) − E_k` along the solutions `D(h)` of the node
//! equations (each solved to full precision), with the slope from the
//! bordered Jacobian
//!
//! ```text
//! [ J   b ]       b = ∂r/∂h = Σ_j b_j [ℓ_ρ (L_q − L_qv v) − ℓ_ρ' L_vv v / h]
//! [ cᵀ  d ]       c = ∂E/∂D,  d = ∂E/∂h = −Σ_j b_j vᵀL_vv v / h
//! ```
//!
//! as its Schur complement `g'(h) = d − c·J⁻¹b` (the block LU of the fixed
//! step gives `J⁻¹b`, which also moves the nodes with `h`). A coupled Newton
//! on `(D, h)` together does not converge: the energy error of a
//! method of order `2s` is `O(h^{2s+1})`, so `g'` is small and round-off
//! fixes `h` only to about `64 ε |E| / |g'|` (1e-6 relative for s = 3 at
//! h = 0.025 on the pendulum); every such correction of `h` disturbs the
//! nodes, and the coupled iteration does not meet its tolerance. The first step has the given size (its energy, not the
//! continuous `E_L(q0, v0)`, is the one conserved), and a step whose size
//! leaves the admissible bracket `[max(h_min, h_{k−1}/r), min(h_max, r·h_{k−1})]`,
//! or whose Newton solve fails, is refused with the state kept.
//!
//! Not yet: a bracket search when the coupled solve fails (the second-order
//! methods have one), time-dependent Lagrangians, and forces (whose energy
//! is not conserved).

use super::Galerkin;
use super::linalg::{BlockVector, Lu};
use super::method::{PointDerivatives, step_energy};
use super::stepper::{KeptBlock, Nodes, Work, linearize};
use crate::error::Error;
use crate::integrator::{Clock, Integrator};
use crate::integrator::{EnergyFallback, StepBounds};
use crate::newton::{self, NewtonFailure, NewtonReport};
use crate::real::Real;
use crate::state::State;
use crate::system::Lagrangian;

/// A step size with its node equations solved and its energy mismatch `g(h) = E − E_k`.
#[derive(Clone, Copy, Debug)]
struct Probe<const N: usize, const S: usize, T> {
    h: T,
    nodes: BlockVector<N, S, T>,
    g: T,
}

impl<Sys, const N: usize, const S: usize, const R: usize, T> Integrator<Sys, Galerkin<S, R, T>, N, T>
where
    Sys: Lagrangian<N>,
    T: Real,
{
    /// The energy equation at step size `h`, its node equations solved from
    /// the guess `d`: the nodes, `g(h) = E − E_k`, `g'(h)` (the Schur
    /// complement `d − c·J⁻¹b`), `J⁻¹b = −∂D/∂h`, the size of the terms of
    /// `E`, and the Newton iterations spent.
    #[allow(clippy::type_complexity)]
    fn energy_probe(
        &self,
        h: T,
        d: BlockVector<N, S, T>,
        storage: &mut Lu<N, S, T>,
    ) -> Result<(BlockVector<N, S, T>, T, T, BlockVector<N, S, T>, f64, usize), NewtonFailure> {
        let State { t: t0, q: q0, p: p0, .. } = self.state;
        let (e, pc) = (self.carry, self.p_carry);
        let (system, g) = (&self.system, &self.method);
        let min_rcond = self.newton.min_rcond;
        let mut work = Work::new(None, core::mem::replace(storage, Lu::empty()));
        let mut factored = false;
        let fixed = |x: &Nodes<N, S, T>, _| {
            // Full Newton, the condition estimated at every iteration.
            work.start(false, false);
            let lin = linearize(system, g, t0, h, (&q0, &e), (&p0, &pc), &x.0, min_rcond, &mut work)?;
            factored = true;
            Ok(lin)
        };
        let solved = newton::solve(Nodes(d), &self.newton, fixed);
        *storage = work.lu;
        let (x, report) = solved?;
        if !factored {
            return Err(NewtonFailure::NonFinite { iterations: report.iterations, quantity: "jacobian" });
        }
        let lu = &*storage;
        let d = x.0;
        let zero = T::zero();
        let mut border: BlockVector<N, S, T> = [[zero; N]; S];
        let mut c: BlockVector<N, S, T> = [[zero; N]; S];
        let (mut dd, mut energy, mut scale) = (zero, zero, self.energy.to_f64().abs());
        for j in 0..R {
            let (t, q, v) = g.point(t0, h, (&q0, &e), &d, j);
            let pd = PointDerivatives::at(system, t, q, v);
            let b = g.quadrature().weights()[j];
            let l = pd.value;
            let mut ej = -l;
            let mut vlvv = [zero; N];
            let mut lqv_v = [zero; N];
            let mut vvv = zero;
            for i in 0..N {
                ej += v[i] * pd.v[i];
                for k in 0..N {
                    vlvv[i] += pd.vv[i][k] * v[k];
                    lqv_v[i] += pd.qv[i][k] * v[k];
                }
            }
            for i in 0..N {
                vvv += v[i] * vlvv[i];
            }
            energy += b * ej;
            scale = scale.max((b * l).to_f64().abs());
            dd -= b * vvv / h;
            let (row, row_d, col, col_d) = (&g.row[j], &g.row_d[j], &g.col[j], &g.col_d[j]);
            for rho in 0..S {
                for i in 0..N {
                    border[rho][i] += b * (row[rho] * (pd.q[i] - lqv_v[i]) - row_d[rho] * vlvv[i] / h);
                }
            }
            // ∂E/∂q_k = Σ_i v_i ∂²L/∂v_i∂q_k − ∂L/∂q_k,  ∂E/∂v_k = (L_vv v)_k.
            let mut de_dq = [zero; N];
            for k in 0..N {
                de_dq[k] = -pd.q[k];
                for i in 0..N {
                    de_dq[k] += v[i] * pd.qv[k][i];
                }
            }
            for n in 0..S {
                for k in 0..N {
                    c[n][k] += b * (col[n] * de_dq[k] + col_d[n] * vlvv[k] / h);
                }
            }
        }
        let w = lu.solve(&border);
        let cw = c.as_flattened().iter().zip(w.as_flattened()).fold(zero, |s, (x, y)| s + *x * *y);
        let slope = dd - cw;
        let gh = energy - self.energy;
        if !gh.is_finite() || !slope.is_finite() {
            return Err(NewtonFailure::NonFinite { iterations: report.iterations, quantity: "energy equation" });
        }
        Ok((d, gh, slope, w, scale, report.iterations))
    }

    /// One energy-preserving step after the first (see the module documentation).
    pub(crate) fn energy_step_nodes(&mut self, bounds: StepBounds) -> Result<(), Error<T>> {
        let Some(last) = self.memory.as_ref().map(|l| l.h) else {
            return self.first_node_energy_step();
        };
        // The memory's spare block storage, for every probe of this step.
        let mut storage =
            self.memory.as_mut().map_or_else(Lu::empty, |l| core::mem::replace(&mut l.spare, Lu::empty()));
        let (lo, hi) = bounds.bracket(last.to_f64());
        let mut h = T::from(self.h.to_f64().clamp(lo, hi));
        let mut d = self.predict_nodes(h);
        let mut spent = 0;
        let mut solved: Option<T> = None;
        for _ in 0..self.newton.max_iterations {
            let (nodes, gh, slope, w, scale, iterations) = match self.energy_probe(h, d, &mut storage) {
                Ok(probe) => probe,
                Err(failure) => {
                    self.keep_storage(KeptBlock::Drop, storage);
                    return Err(self.fail(h, super::stepper::with_iterations(failure, spent)));
                }
            };
            spent += iterations;
            d = nodes;
            // Round-off of the energy's own terms moves h by this much: the
            // energy error of a method of order 2s is O(h^{2s+1}), so g' is
            // small and h is fixed to fewer digits than the nodes.
            let floor = 64.0 * T::EPSILON * scale;
            let h_floor = floor / slope.to_f64().abs();
            if gh.to_f64().abs() <= floor {
                solved = Some(gh);
                break;
            }
            let mut dh = -gh / slope;
            if dh.to_f64().abs() <= (self.newton.rtol * h.to_f64()).max(h_floor) {
                solved = Some(gh);
                break;
            }
            // The energy equation can have far roots (a step many times larger
            // that happens to match the energy); stay in the bracket, going at
            // most halfway to its end.
            let target = (h + dh).to_f64();
            if target < lo || target > hi {
                let bound = if target < lo { lo } else { hi };
                dh = T::from(0.5 * (bound - h.to_f64()));
                if dh.to_f64().abs() <= h_floor {
                    break;
                }
            }
            // The nodes follow the step size: D(h + dh) ≈ D − J⁻¹b dh.
            for (x, y) in d.as_flattened_mut().iter_mut().zip(w.as_flattened()) {
                *x -= *y * dh;
            }
            h += dh;
        }
        let State { t: t0, q: q0, .. } = self.state;
        let mut fallback = false;
        if solved.is_none() {
            // Newton on h found no root near the guess: search the whole
            // bracket (a sign change, then bisection), and where there is none
            // apply the configured fallback.
            let mut found = self.node_search_bracket(lo, hi, &mut spent, &mut storage);
            if found.is_none() && self.fallback == EnergyFallback::LeastSquares {
                found = self.node_least_squares(lo, hi, &mut spent, &mut storage);
                fallback = found.is_some();
            }
            if let Some(probe) = found {
                (h, d) = (probe.h, probe.nodes);
                solved = Some(probe.g);
            }
        }
        let mismatch = match solved {
            Some(gh) => (gh / self.energy).to_f64().abs(),
            None => {
                let e1 = step_energy(&self.system, &self.method, t0, h, (&q0, &self.carry), &d);
                ((e1 - self.energy) / self.energy).to_f64().abs()
            }
        };
        if solved.is_none() || !(lo..=hi).contains(&h.to_f64()) {
            self.stats.failed_steps += 1;
            self.keep_storage(KeptBlock::Drop, storage);
            return Err(Error::NoEnergyStep {
                state: self.state.into(),
                h_lo: lo,
                h_hi: hi,
                h_best: h.to_f64(),
                mismatch,
                iterations: spent,
                root_test: self.node_root_test(bounds),
            });
        }
        // t_{k+1} = t_k + h with Kahan compensation.
        let y = h - self.time_error;
        let t1 = t0 + y;
        let time_error = (t1 - t0) - y;
        let report = NewtonReport { iterations: spent, residual_norm: mismatch, correction_norm: 0.0 };
        self.commit(h, t1, d, report, None, KeptBlock::Drop, storage)?;
        self.time_error = time_error;
        self.h = h;
        if fallback {
            // The least-squares step changed the energy: conserve its new value.
            self.reread_node_energy();
            self.time_error = time_error;
            self.stats.energy_fallbacks += 1;
        }
        self.clock = Clock { t: self.state.t, step: self.state.step };
        Ok(())
    }

    /// `g` at step size `h`, its node equations solved from the predicted
    /// nodes, or `None` where they cannot be; the iterations go to `spent`.
    fn node_probe(&self, h: f64, spent: &mut usize, storage: &mut Lu<N, S, T>) -> Option<Probe<N, S, T>> {
        let h = T::from(h);
        let (nodes, g, _, _, _, iterations) = self.energy_probe(h, self.predict_nodes(h), storage).ok()?;
        *spent += iterations;
        Some(Probe { h, nodes, g })
    }

    /// The local root test `(x, low, high)` of [`Error::NoEnergyStep`] at the
    /// current node (docs/energy-steps.md §3): `x = a_m / (a_{m+1} h')` for
    /// the step energy `Ê(h) ≈ H + a_m h^m + a_{m+1} h^{m+1}` of a method of
    /// order `m = 2s`, from two trial solves of the node equations. The stored
    /// energy is the step behind retraced, `E_k = Ê(−h')` (the rule is
    /// self-adjoint), so with `η = h'`
    ///
    /// ```text
    /// g(η)   = Ê(η) − Ê(−η)   = 2 a_{m+1} η^{m+1}
    /// g(η/2) = Ê(η/2) − Ê(−η) = a_m η^m (2^{−m} − 1) + a_{m+1} η^{m+1} (1 + 2^{−m−1})
    /// ```
    ///
    /// up to `O(η^{m+2})`, and `H` cancels. `None` before the second step,
    /// where a trial solve fails, or where `g` is not above the round-off of
    /// the energy (then the coefficients cannot be read off). A diagnostic,
    /// computed on the error path only.
    fn node_root_test(&self, bounds: StepBounds) -> Option<(f64, f64, f64)> {
        let eta = self.memory.as_ref()?.h.to_f64();
        let m = i32::try_from(self.method.order()).ok()?;
        if m < 2 || m % 2 != 0 {
            return None;
        }
        let mut spent = 0;
        // A diagnostic of the error path: storage of its own.
        let mut storage = Lu::empty();
        let g1 = self.node_probe(eta, &mut spent, &mut storage)?.g.to_f64();
        let g2 = self.node_probe(0.5 * eta, &mut spent, &mut storage)?.g.to_f64();
        let noise = 100.0 * f64::EPSILON * self.energy.to_f64().abs();
        if g1.abs() <= noise || g2.abs() <= noise {
            return None;
        }
        let b = g1 / (2.0 * eta.powi(m + 1));
        let a = (g2 - b * eta.powi(m + 1) * (1.0 + 0.5f64.powi(m + 1))) / (eta.powi(m) * (0.5f64.powi(m) - 1.0));
        let x = a / (b * eta);
        let (low, high) = crate::integrator::root_band(m / 2, bounds.max_ratio);
        x.is_finite().then_some((x, low, high))
    }

    /// Samples `g(h)` at nine points of `[lo, hi]` for a sign change and
    /// bisects it to round-off, or `None` without a sign change. Probes
    /// whose node equations fail are skipped.
    fn node_search_bracket(
        &self,
        lo: f64,
        hi: f64,
        spent: &mut usize,
        storage: &mut Lu<N, S, T>,
    ) -> Option<Probe<N, S, T>> {
        let negative = |p: &Probe<N, S, T>| p.g < T::zero();
        let mut previous: Option<Probe<N, S, T>> = None;
        for k in 0..=8 {
            let Some(here) = self.node_probe(lo + (hi - lo) * k as f64 / 8.0, spent, storage) else { continue };
            if let Some(before) = previous
                && negative(&before) != negative(&here)
            {
                let (mut a, mut b) = (before, here);
                for _ in 0..60 {
                    let mid = 0.5 * (a.h.to_f64() + b.h.to_f64());
                    if mid <= a.h.to_f64() || mid >= b.h.to_f64() {
                        break;
                    }
                    let Some(m) = self.node_probe(mid, spent, storage) else { break };
                    if negative(&m) == negative(&a) {
                        a = m;
                    } else {
                        b = m;
                    }
                }
                return Some(if a.g.abs() <= b.g.abs() { a } else { b });
            }
            previous = Some(here);
        }
        None
    }

    /// The admissible step of least energy mismatch, by golden section on
    /// `[lo, hi]` (Kane, Marsden & Ortiz's least-squares step); `None` where
    /// no probe could be solved.
    fn node_least_squares(
        &self,
        lo: f64,
        hi: f64,
        spent: &mut usize,
        storage: &mut Lu<N, S, T>,
    ) -> Option<Probe<N, S, T>> {
        const INV_PHI: f64 = 0.618_033_988_749_894_8;
        let size = |p: &Option<Probe<N, S, T>>| p.as_ref().map_or(f64::INFINITY, |p| p.g.to_f64().abs());
        let (mut a, mut b) = (lo, hi);
        let (mut c, mut d) = (b - INV_PHI * (b - a), a + INV_PHI * (b - a));
        let (mut pc, mut pd) = (self.node_probe(c, spent, storage), self.node_probe(d, spent, storage));
        let mut best = if size(&pc) <= size(&pd) { pc } else { pd };
        for _ in 0..40 {
            if b - a <= 1e-9 * b {
                break;
            }
            if size(&pc) < size(&pd) {
                (b, d, pd) = (d, c, pc);
                c = b - INV_PHI * (b - a);
                pc = self.node_probe(c, spent, storage);
            } else {
                (a, c, pc) = (c, d, pd);
                d = a + INV_PHI * (b - a);
                pd = self.node_probe(d, spent, storage);
            }
            for p in [&pc, &pd] {
                if size(p) < size(&best) {
                    best = *p;
                }
            }
        }
        best
    }

    /// The first energy-preserving step: a step of the given size, whose
    /// discrete energy becomes the one conserved.
    fn first_node_energy_step(&mut self) -> Result<(), Error<T>> {
        let h = self.h;
        let t1 = self.state.t + h;
        self.step_nodes(h, t1)?;
        self.reread_node_energy();
        Ok(())
    }

    /// Sets the energy target to the discrete energy of the last step.
    pub(crate) fn reread_node_energy(&mut self) {
        if let Some((t0, h, q0, carry, d)) = self.last_step_parts() {
            self.energy = step_energy(&self.system, &self.method, t0, h, (&q0, &carry), &d);
            self.time_error = T::zero();
        }
    }
}
