//! The discrete forces of a one-point step on the reverse-mode core: the
//! discrete Lagrange–d'Alembert principle (docs/theory.md §6) for systems
//! whose size is known at run time.
//!
//! With the rule's points `c_j` and weights `w` (`1` for one point, `½`
//! for two), the force `F = Q − ∂R/∂v` at each point
//! `(t_k + c_j h, q_k + c_j Δq, Δq·h⁻¹)` is shared between the nodes as the
//! linear interpolant of `δq` shares it:
//!
//! ```text
//! F_k^− = Σ_j (F_j · w h)(1 − c_j)        F_k^+ = Σ_j (F_j · w h) c_j
//! ```
//!
//! the const-size rules' own forces for the midpoint (`c = ½`), trapezoid
//! (`c = 0, 1`) and α-β (`c = β`, shares `α`, `β`) rules. `F_k^−` joins the
//! Newton residual and `∂F_k^−/∂Δq` its Jacobian; `F_k^− + F_k^+` joins
//! the momentum change.
//!
//! Derivatives: `Q` is evaluated on dual numbers seeded in the colour
//! classes of the step matrix's band (`q` by `c_j s`, `v` by `h⁻¹ s`), as the
//! gradient code of `L` is; `R`, a scalar, is recorded on a tape as a
//! function of `Δq` and of one offset `z_j` of the velocity per point,
//! `Σ_j R(q_k + c_j Δq, Δq·h⁻¹ + z_j)` at `z = 0`: one reverse sweep gives
//! `∂R/∂v` at every point (the gradient in `z_j`), and one compressed
//! second-order sweep seeded on `Δq` gives its Jacobian along the step
//! (the rows of `z_j`). Both cost `O(2b + 1)` evaluations for a band `b`.

use num_dual::Dual64;

use super::directional::{Lanes, Layout, Seeded, Width, distinct, point_position, point_time};
use super::{ModelScalar, TapeModel, filled, seeds, tape_breakdown};
use crate::banded::LinearSolveError;
use crate::hyperdual::DualArray;
use crate::newton::Breakdown;
use crate::tape::{Tape, Var};

/// The buffers of the forces of a step (empty until the first forced step).
#[derive(Debug, Default)]
pub(super) struct Forcing {
    one: Seeded<Dual64>,
    three: Seeded<DualArray<[f64; 3]>>,
    five: Seeded<DualArray<[f64; 5]>>,
    /// `q_k + c_j Δq` of the point at hand.
    at: Vec<f64>,
    /// `Δq·h⁻¹`.
    velocity: Vec<f64>,
    /// `Q` at the point at hand.
    applied: Vec<f64>,
    /// `∂R/∂v` at both points, one after the other.
    resistive: Vec<f64>,
    /// The tape of `R` and its inputs `(Δq, z_1[, z_2])`.
    tape: Tape,
    inputs: Vec<f64>,
    gradient: Vec<f64>,
    products: Vec<f64>,
    /// `∂(∂R/∂v)/∂Δq` at one point, in the step matrix's storage.
    rows: Vec<f64>,
    /// The tape's positions and velocities of one point.
    vars: (Vec<Var>, Vec<Var>),
}

impl Clone for Forcing {
    /// A fresh set of buffers: they hold nothing between steps.
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl Forcing {
    /// Sizes the value buffers for `n` coordinates (once).
    fn allocate(&mut self, n: usize) -> Result<(), LinearSolveError> {
        if self.velocity.len() != n {
            let two_n = n.checked_mul(2).ok_or(LinearSolveError::TooLarge { n, per_column: 2 })?;
            let inputs = n.checked_mul(3).ok_or(LinearSolveError::TooLarge { n, per_column: 3 })?;
            *self = Self {
                at: filled(n, 0.0)?,
                velocity: filled(n, 0.0)?,
                applied: filled(n, 0.0)?,
                resistive: filled(two_n, 0.0)?,
                inputs: filled(inputs, 0.0)?,
                gradient: filled(inputs, 0.0)?,
                vars: (filled(n, Var::constant(0.0))?, filled(n, Var::constant(0.0))?),
                ..Self::default()
            };
        }
        Ok(())
    }

    /// `F_k^−` into `minus` and `F_k^+` into `plus` at the increment `dq`
    /// (both overwritten); with `jacobian`, `∂F_k^−/∂Δq` added into it (the
    /// layout's storage). A force that is not finite is
    /// [`Breakdown::NonFinite`] (`"force"`).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn forces(
        &mut self,
        model: &dyn TapeModel,
        (t0, h, points): (f64, f64, [f64; 2]),
        q0: &[f64],
        dq: &[f64],
        minus: &mut [f64],
        plus: &mut [f64],
        jacobian: Option<(Layout, &mut [f64])>,
    ) -> Result<(), Breakdown> {
        let n = q0.len();
        self.allocate(n).map_err(super::breakdown)?;
        let inv_h = h.recip();
        for (v, &d) in self.velocity.iter_mut().zip(dq) {
            *v = d * inv_h;
        }
        let (evaluated, w) = distinct(points);
        let wh = w * h;
        if model.has_dissipation() {
            let layout = jacobian.as_ref().map(|(layout, _)| *layout);
            self.record_dissipation(model, points, inv_h, q0, dq, layout)?;
        }
        minus.fill(0.0);
        plus.fill(0.0);
        for (k, &j) in evaluated.iter().enumerate() {
            let c = points[j];
            for (i, x) in self.at.iter_mut().enumerate() {
                *x = point_position(c, q0[i], dq[i]);
            }
            self.applied.fill(0.0);
            if model.has_force() {
                ModelScalar::force(model, point_time(c, t0, h), &self.at, &self.velocity, &mut self.applied);
            }
            if model.has_dissipation() {
                for (f, r) in self.applied.iter_mut().zip(&self.resistive[k * n..(k + 1) * n]) {
                    *f -= r;
                }
            }
            for i in 0..n {
                let impulse = self.applied[i] * wh;
                minus[i] += impulse * (1.0 - c);
                plus[i] += impulse * c;
            }
        }
        if !minus.iter().chain(plus.iter()).all(|x| x.is_finite()) {
            return Err(Breakdown::NonFinite("force"));
        }
        if let Some((layout, band)) = jacobian {
            if model.has_force() {
                let step = Point { t0, h, inv_h, points, q0, dq, velocity: &self.velocity };
                match Width::for_classes(layout.classes()) {
                    Width::One => step.applied_jacobian(model, &mut self.one, &mut self.at, layout, band),
                    Width::Three => step.applied_jacobian(model, &mut self.three, &mut self.at, layout, band),
                    Width::Five => step.applied_jacobian(model, &mut self.five, &mut self.at, layout, band),
                }
                .map_err(super::breakdown)?;
            }
            if model.has_dissipation() {
                let seeds = seeds(0..n, layout.bandwidth);
                let width = layout.width();
                for (k, &j) in evaluated.iter().enumerate() {
                    let c = points[j];
                    let rows = (k + 1) * n..(k + 2) * n;
                    seeds.recover(&self.products, rows, &mut self.rows[..n * width]).map_err(tape_breakdown)?;
                    for (b, r) in band[..n * width].iter_mut().zip(&self.rows) {
                        *b -= (r * wh) * (1.0 - c);
                    }
                }
            }
            if !band.iter().all(|x| x.is_finite()) {
                return Err(Breakdown::NonFinite("force jacobian"));
            }
        }
        Ok(())
    }

    /// Records `Σ_j R(q_k + c_j Δq, Δq·h⁻¹ + z_j)` at `z = 0` and sweeps it:
    /// `∂R/∂v` at each evaluated point into `resistive`, and with a
    /// `layout`, `H·S` seeded on `Δq` into `products`.
    fn record_dissipation(
        &mut self,
        model: &dyn TapeModel,
        points: [f64; 2],
        inv_h: f64,
        q0: &[f64],
        dq: &[f64],
        layout: Option<Layout>,
    ) -> Result<(), Breakdown> {
        let n = q0.len();
        let evaluated = distinct(points).0;
        let inputs = n * (1 + evaluated.len());
        self.inputs[..n].copy_from_slice(dq);
        self.inputs[n..inputs].fill(0.0);
        let (q, v) = (&mut self.vars.0, &mut self.vars.1);
        self.tape
            .record(&self.inputs[..inputs], |x: &[Var]| {
                let mut total = Var::constant(0.0);
                for (k, &j) in evaluated.iter().enumerate() {
                    let c = points[j];
                    let z = &x[(k + 1) * n..(k + 2) * n];
                    for i in 0..n {
                        // `q_k + c Δq` as `point_position` forms it.
                        q[i] = if c == 0.0 {
                            Var::constant(q0[i])
                        } else if c == 1.0 {
                            x[i] + q0[i]
                        } else {
                            x[i] * c + q0[i]
                        };
                        v[i] = x[i] * inv_h + z[i];
                    }
                    total += model.dissipation(q, v);
                }
                total
            })
            .map_err(tape_breakdown)?;
        let gradient = &mut self.gradient[..inputs];
        match layout {
            Some(layout) => {
                let seeds = seeds(0..n, layout.bandwidth);
                let len = inputs.checked_mul(seeds.directions());
                if self.products.len() != len.unwrap_or(usize::MAX) {
                    self.products = super::zeroed(len, n).map_err(super::breakdown)?;
                    self.rows = super::zeroed(n.checked_mul(layout.width()), n).map_err(super::breakdown)?;
                }
                self.tape.hessian_product(&seeds, gradient, &mut self.products).map_err(tape_breakdown)?;
            }
            None => self.tape.gradient(gradient).map_err(tape_breakdown)?,
        }
        self.resistive[..inputs - n].copy_from_slice(&gradient[n..]);
        Ok(())
    }
}

/// The `f64` data of one step, for the applied force's Jacobian.
struct Point<'a> {
    t0: f64,
    h: f64,
    inv_h: f64,
    points: [f64; 2],
    q0: &'a [f64],
    dq: &'a [f64],
    velocity: &'a [f64],
}

impl Point<'_> {
    /// Adds `∂F_k^−/∂Δq` of the applied force `Q` into `band`: per chunk of
    /// `D::LANES` colour classes, one evaluation of `Q` per point on dual
    /// numbers, `q` seeded by `c_j` and `v` by `h⁻¹` in the lane of each
    /// coordinate's class. `at` is scratch of `n` entries.
    fn applied_jacobian<D: Lanes>(
        &self,
        model: &dyn TapeModel,
        seeded: &mut Seeded<D>,
        at: &mut [f64],
        layout: Layout,
        band: &mut [f64],
    ) -> Result<(), LinearSolveError> {
        let n = layout.n;
        seeded.allocate(n)?;
        let width = layout.width();
        let classes = layout.classes();
        let (evaluated, w) = distinct(self.points);
        let wh = w * self.h;
        for first in (0..classes).step_by(D::LANES) {
            let lanes = D::LANES.min(classes - first);
            for &j in evaluated {
                let c = self.points[j];
                let mut class: usize = 0;
                for i in 0..n {
                    at[i] = point_position(c, self.q0[i], self.dq[i]);
                    let lane = class.checked_sub(first).filter(|&l| l < lanes);
                    seeded.q[i] = D::seed(at[i], lane, c);
                    seeded.v[i] = D::seed(self.velocity[i], lane, self.inv_h);
                    seeded.gq[i] = D::from(0.0);
                    class += 1;
                    if class == classes {
                        class = 0;
                    }
                }
                let t = D::from(point_time(c, self.t0, self.h));
                ModelScalar::force(model, t, &seeded.q, &seeded.v, &mut seeded.gq);
                for i in 0..n {
                    let f = &seeded.gq[i];
                    let row = &mut band[i * width..(i + 1) * width];
                    layout.row(i, first, lanes, |slot, lane| row[slot] += (f.part(lane) * wh) * (1.0 - c));
                }
            }
        }
        Ok(())
    }
}

/// The generalised force `Q − ∂R/∂v` at `(t, q, v)` into `out` (a readout
/// at the initial data: it allocates its tape and buffers).
pub(crate) fn generalized_force(model: &dyn TapeModel, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
    let n = q.len();
    out.fill(0.0);
    if model.has_force() {
        ModelScalar::force(model, t, q, v, out);
    }
    if model.has_dissipation() {
        let mut tape = Tape::new();
        let mut gradient = vec![0.0; n];
        let recorded = tape.record(v, |x: &[Var]| {
            let q: Vec<Var> = q.iter().map(|&x| Var::constant(x)).collect();
            model.dissipation(&q, x)
        });
        match recorded.and_then(|_| tape.gradient(&mut gradient)) {
            Ok(()) => out.iter_mut().zip(&gradient).for_each(|(f, r)| *f -= r),
            Err(_) => out.fill(f64::NAN),
        }
    }
}
