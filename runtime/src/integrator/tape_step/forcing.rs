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
use crate::tape::{Seeds, Tape, Var};

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
    /// The colours of the inputs `(y, w)` of [`point_force`](Self::point_force)'s
    /// tape: `y_i` in class `i mod K`, `w_i` in `K + i mod K`.
    colours: Vec<Option<u32>>,
    /// The `K` the colours are for.
    colour_classes: usize,
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

    /// The generalised force `F = Q − ∂R/∂v` at one point `(t, q, v)` into
    /// `out`, and with `jacobians` its derivatives `∂F/∂q` and `∂F/∂v` into
    /// the two buffers (overwritten, the layout's storage): `Q` on dual
    /// lanes per colour class ([`applied_directional`]), `R` recorded as
    /// `R(q + y, v + w)` at zero offsets `y`, `w`, whose gradient in `w` is
    /// `∂R/∂v` and whose second-order sweep, seeded in the colour classes of
    /// `y` and of `w` at once, gives the rows of both Jacobians. A force
    /// that is not finite is [`Breakdown::NonFinite`] (`"force"`).
    pub(super) fn point_force(
        &mut self,
        model: &dyn TapeModel,
        (t, q, v): (f64, &[f64], &[f64]),
        out: &mut [f64],
        jacobians: Option<(Layout, &mut [f64], &mut [f64])>,
    ) -> Result<(), Breakdown> {
        let n = q.len();
        self.allocate(n).map_err(super::breakdown)?;
        out.fill(0.0);
        if model.has_force() {
            ModelScalar::force(model, t, q, v, out);
        }
        let layout = jacobians.as_ref().map(|(layout, ..)| *layout);
        if model.has_dissipation() {
            self.point_dissipation(model, q, v, layout)?;
            for (f, r) in out.iter_mut().zip(&self.resistive[..n]) {
                *f -= r;
            }
        }
        if !out.iter().all(|x| x.is_finite()) {
            return Err(Breakdown::NonFinite("force"));
        }
        let Some((layout, dq, dv)) = jacobians else {
            return Ok(());
        };
        let width = layout.width();
        dq.fill(0.0);
        dv.fill(0.0);
        if model.has_force() {
            for (scale, into) in [((1.0, 0.0), &mut *dq), ((0.0, 1.0), &mut *dv)] {
                let add = |i: usize, slot: usize, part: f64| into[i * width + slot] += part;
                let point = (t, q, v);
                match Width::for_classes(layout.classes()) {
                    Width::One => applied_directional(model, &mut self.one, point, scale, layout, add),
                    Width::Three => applied_directional(model, &mut self.three, point, scale, layout, add),
                    Width::Five => applied_directional(model, &mut self.five, point, scale, layout, add),
                }
                .map_err(super::breakdown)?;
            }
        }
        if model.has_dissipation() {
            let classes = layout.classes();
            let directions = 2 * classes;
            for i in 0..n {
                let row = &self.products[(n + i) * directions..(n + i + 1) * directions];
                for slot in 0..width {
                    // The column of the slot, and its class.
                    let column = match layout.bandwidth {
                        Some(b) => (i + slot).checked_sub(b).filter(|&c| c < n),
                        None => Some(slot),
                    };
                    if let Some(c) = column {
                        dq[i * width + slot] -= row[c % classes];
                        dv[i * width + slot] -= row[classes + c % classes];
                    }
                }
            }
        }
        if !dq.iter().chain(dv.iter()).all(|x| x.is_finite()) {
            return Err(Breakdown::NonFinite("force jacobian"));
        }
        Ok(())
    }

    /// Records `R(q + y, v + w)` at `y = w = 0` and sweeps it: `∂R/∂v` into
    /// `resistive[..n]`, and with a `layout`, `H·S` seeded in the colour
    /// classes of `y` and `w` (`2K` directions) into `products`.
    fn point_dissipation(
        &mut self,
        model: &dyn TapeModel,
        q: &[f64],
        v: &[f64],
        layout: Option<Layout>,
    ) -> Result<(), Breakdown> {
        let n = q.len();
        let inputs = 2 * n;
        self.inputs[..inputs].fill(0.0);
        let (qs, vs) = (&mut self.vars.0, &mut self.vars.1);
        self.tape
            .record(&self.inputs[..inputs], |x: &[Var]| {
                for i in 0..n {
                    qs[i] = x[i] + q[i];
                    vs[i] = x[n + i] + v[i];
                }
                model.dissipation(qs, vs)
            })
            .map_err(tape_breakdown)?;
        let gradient = &mut self.gradient[..inputs];
        match layout {
            Some(layout) => {
                let classes = layout.classes();
                if self.colours.len() != inputs || self.colour_classes != classes {
                    let class = |i: usize| u32::try_from(i % classes).ok();
                    let offset = |i: usize| u32::try_from(classes + i % classes).ok();
                    self.colours = (0..n).map(class).chain((0..n).map(offset)).collect();
                    self.colour_classes = classes;
                }
                let seeds = Seeds::Colours { colour: &self.colours, directions: 2 * classes };
                let len = inputs.checked_mul(2 * classes);
                if self.products.len() != len.unwrap_or(usize::MAX) {
                    self.products = super::zeroed(len, n).map_err(super::breakdown)?;
                }
                self.tape.hessian_product(&seeds, gradient, &mut self.products).map_err(tape_breakdown)?;
            }
            None => self.tape.gradient(gradient).map_err(tape_breakdown)?,
        }
        self.resistive[..n].copy_from_slice(&gradient[n..]);
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
    /// Adds `∂F_k^−/∂Δq` of the applied force `Q` into `band`: per point,
    /// [`applied_directional`] with `q` seeded by `c_j` and `v` by `h⁻¹`.
    /// `at` is scratch of `n` entries.
    fn applied_jacobian<D: Lanes>(
        &self,
        model: &dyn TapeModel,
        seeded: &mut Seeded<D>,
        at: &mut [f64],
        layout: Layout,
        band: &mut [f64],
    ) -> Result<(), LinearSolveError> {
        let width = layout.width();
        let (evaluated, w) = distinct(self.points);
        let wh = w * self.h;
        for &j in evaluated {
            let c = self.points[j];
            for (i, x) in at.iter_mut().enumerate() {
                *x = point_position(c, self.q0[i], self.dq[i]);
            }
            let point = (point_time(c, self.t0, self.h), &*at, self.velocity);
            applied_directional(model, seeded, point, (c, self.inv_h), layout, |i, slot, part| {
                band[i * width + slot] += (part * wh) * (1.0 - c);
            })?;
        }
        Ok(())
    }
}

/// The derivative of the applied force `Q` at `(t, q, v)` along `q` seeded
/// by `scale.0` and `v` by `scale.1` in the lane of each coordinate's colour
/// class: per chunk of `D::LANES` classes one evaluation of `Q` on dual
/// numbers, each entry handed to `add(row, slot, value)` (the layout's
/// storage). Each slot of a row is reached once.
pub(super) fn applied_directional<D: Lanes>(
    model: &dyn TapeModel,
    seeded: &mut Seeded<D>,
    (t, q, v): (f64, &[f64], &[f64]),
    scale: (f64, f64),
    layout: Layout,
    mut add: impl FnMut(usize, usize, f64),
) -> Result<(), LinearSolveError> {
    let n = layout.n;
    seeded.allocate(n)?;
    let classes = layout.classes();
    for first in (0..classes).step_by(D::LANES) {
        let lanes = D::LANES.min(classes - first);
        let mut class: usize = 0;
        for i in 0..n {
            let lane = class.checked_sub(first).filter(|&l| l < lanes);
            seeded.q[i] = D::seed(q[i], lane, scale.0);
            seeded.v[i] = D::seed(v[i], lane, scale.1);
            seeded.gq[i] = D::from(0.0);
            class += 1;
            if class == classes {
                class = 0;
            }
        }
        ModelScalar::force(model, D::from(t), &seeded.q, &seeded.v, &mut seeded.gq);
        for i in 0..n {
            let f = &seeded.gq[i];
            layout.row(i, first, lanes, |slot, lane| add(i, slot, f.part(lane)));
        }
    }
    Ok(())
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

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::integrator::tape_step::{Lanes3, Lanes5};
    use crate::structure::Coupling;
    use crate::system::Scalar;

    /// A chain's force and dissipation, both depending on `q` and `v` with
    /// bandwidth 1: `Q_i = −v_i³ q_{i+1} + sin(t) q_i`, `R = Σ ½(1 + q_i²) v_i²
    /// + ½ (v_{i+1} − v_i)² cos q_i`.
    pub(in crate::integrator::tape_step) struct Forced;

    fn force<D: Scalar>(t: D, q: &[D], v: &[D], f: &mut [D]) {
        let n = q.len();
        for i in 0..n {
            f[i] = q[i] * t.sin();
            if i + 1 < n {
                f[i] -= v[i] * v[i] * v[i] * q[i + 1];
            }
        }
    }

    fn dissipation<D: Scalar>(q: &[D], v: &[D]) -> D {
        let mut r = D::from(0.0);
        for i in 0..q.len() {
            r += (q[i] * q[i] + 1.0) * v[i] * v[i] * 0.5;
            if i + 1 < q.len() {
                let d = v[i + 1] - v[i];
                r += d * d * q[i].cos() * 0.5;
            }
        }
        r
    }

    impl TapeModel for Forced {
        fn coupling(&self) -> Coupling {
            Coupling::GENERAL
        }
        fn lagrangian(&self, _: Var, _: &[Var], _: &[Var]) -> Var {
            unreachable!("the test records no action")
        }
        fn action(&self, _: Var, _: Var, _: &[Var], _: &[Var]) -> Var {
            unreachable!("the test records no action")
        }
        fn autonomous(&self) -> bool {
            false
        }
        fn points(&self) -> Option<[f64; 2]> {
            None
        }
        fn has_gradient_qv(&self) -> bool {
            false
        }
        crate::integrator::tape_step::scalar_methods!();
        fn has_force(&self) -> bool {
            true
        }
        fn has_dissipation(&self) -> bool {
            true
        }
        fn dissipation(&self, q: &[Var], v: &[Var]) -> Var {
            dissipation(q, v)
        }
        fn force_f64(&self, t: f64, q: &[f64], v: &[f64], f: &mut [f64]) {
            force(t, q, v, f);
        }
        fn force_dual(&self, t: Dual64, q: &[Dual64], v: &[Dual64], f: &mut [Dual64]) {
            force(t, q, v, f);
        }
        fn force_lanes3(&self, t: Lanes3, q: &[Lanes3], v: &[Lanes3], f: &mut [Lanes3]) {
            force(t, q, v, f);
        }
        fn force_lanes5(&self, t: Lanes5, q: &[Lanes5], v: &[Lanes5], f: &mut [Lanes5]) {
            force(t, q, v, f);
        }
    }

    impl Forced {
        fn gradient_qv_generic<D: Scalar>(&self, _: D, _: &[D], _: &[D], _: &mut [D], _: &mut [D]) {
            unreachable!("the test evaluates no gradient of L")
        }
        fn lagrangian_generic<D: Scalar>(&self, _: D, _: &[D], _: &[D]) -> D {
            unreachable!("the test evaluates no L")
        }
    }

    /// `∂F_k^−/∂Δq` from the lanes and the tape against central differences
    /// of `F_k^−`, for bands of width 3, 5 and 7 (compressed) and the dense
    /// pattern, one and two quadrature points; and `F_k^±` split as the
    /// rules split them (`F_k^− + F_k^+` is `h` times the mean force).
    #[test]
    fn the_force_jacobian_is_the_derivative_of_the_start_force() {
        let n = 13;
        let q0: Vec<f64> = (0..n).map(|i| 0.4 * (0.7 * i as f64).sin()).collect();
        let dq: Vec<f64> = (0..n).map(|i| 0.03 * (1.3 * i as f64 + 0.2).cos()).collect();
        let (t0, h) = (0.3, 0.05);
        for bandwidth in [Some(1), Some(2), Some(3), None] {
            for points in [[0.5, 0.5], [0.0, 1.0], [0.3, 0.3]] {
                let case = format!("bandwidth {bandwidth:?}, points {points:?}");
                let layout = Layout { n, bandwidth };
                let width = layout.width();
                let mut forcing = Forcing::default();
                let (mut minus, mut plus) = (vec![0.0; n], vec![0.0; n]);
                let mut band = vec![0.0; n * width];
                let step = (t0, h, points);
                forcing.forces(&Forced, step, &q0, &dq, &mut minus, &mut plus, Some((layout, &mut band))).unwrap();
                // Values alone: the same bits.
                let (mut m2, mut p2) = (vec![0.0; n], vec![0.0; n]);
                forcing.forces(&Forced, step, &q0, &dq, &mut m2, &mut p2, None).unwrap();
                assert_eq!((&minus, &plus), (&m2, &p2), "{case}");
                // The impulse against the rule's quadrature of F.
                let v: Vec<f64> = dq.iter().map(|d| d * h.recip()).collect();
                let (evaluated, w) = distinct(points);
                let mut impulse = vec![0.0; n];
                for &j in evaluated {
                    let c = points[j];
                    let q: Vec<f64> = (0..n).map(|i| q0[i] + c * dq[i]).collect();
                    let mut f = vec![0.0; n];
                    generalized_force(&Forced, t0 + c * h, &q, &v, &mut f);
                    impulse.iter_mut().zip(&f).for_each(|(x, f)| *x += w * h * f);
                }
                for i in 0..n {
                    assert!((minus[i] + plus[i] - impulse[i]).abs() < 1e-15, "{case}: impulse {i}");
                }
                let mut largest = 0.0f64;
                let mut scale = 0.0f64;
                for j in 0..n {
                    let eps = 1e-6;
                    let mut x = dq.clone();
                    x[j] += eps;
                    forcing.forces(&Forced, step, &q0, &x, &mut m2, &mut p2, None).unwrap();
                    let up = m2.clone();
                    x[j] -= 2.0 * eps;
                    forcing.forces(&Forced, step, &q0, &x, &mut m2, &mut p2, None).unwrap();
                    for i in 0..n {
                        let fd = (up[i] - m2[i]) / (2.0 * eps);
                        let entry = match bandwidth {
                            Some(b) if i.abs_diff(j) > b => 0.0,
                            Some(b) => band[i * width + j + b - i],
                            None => band[i * n + j],
                        };
                        largest = largest.max((fd - entry).abs());
                        scale = scale.max(entry.abs());
                    }
                }
                // Entries are O(1) (h times derivatives of O(1/h)); central
                // differences of step 1e-6 are good to ~1e-9.
                assert!(scale > 0.1 && largest < 1e-7, "{case}: {largest:e} of {scale:e}");
            }
        }
    }
}
