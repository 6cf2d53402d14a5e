//! Derivatives of `L` at the one or two evaluation points of a one-point
//! rule by dual numbers seeded in lanes (several directions per evaluation),
//! for the Jacobian of the step and the mass matrix, where the coupling
//! pattern makes them cheaper than a tape sweep.

use num_dual::Dual64;

use super::{ModelScalar, TapeModel, filled};
use crate::banded::LinearSolveError;
use crate::hyperdual::DualArray;

/// The quadrature points of the forward-over-reverse Newton path, when
/// the model takes it: generated gradient code and a rule of the form
/// `A = (h/2) Σ_j L(t_k + c_j h, q_k + c_j Δq, Δq/h)`.
pub(super) fn directional_points(model: &dyn TapeModel) -> Option<[f64; 2]> {
    if model.has_gradient_qv() { model.points() } else { None }
}

/// The points that are evaluated (one when both coincide) and their weight.
pub(crate) fn distinct(points: [f64; 2]) -> (&'static [usize], f64) {
    if points[0] == points[1] { (&[0], 1.0) } else { (&[0, 1], 0.5) }
}

/// `t_k + c h`, formed as the rules' actions form it.
#[inline]
pub(crate) fn point_time(c: f64, t0: f64, h: f64) -> f64 {
    if c == 0.0 {
        t0
    } else if c == 1.0 {
        t0 + h
    } else {
        t0 + h * c
    }
}

/// `q_k + c Δq`, formed as the rules' actions form it.
#[inline]
pub(crate) fn point_position(c: f64, q0: f64, dq: f64) -> f64 {
    if c == 0.0 {
        q0
    } else if c == 1.0 {
        q0 + dq
    } else {
        q0 + dq * c
    }
}

/// A dual number carrying [`LANES`](Self::LANES) directions at once: one
/// evaluation of the gradient code on it gives that many Hessian-vector
/// products, with the same real part as on `f64`.
pub(super) trait Lanes: ModelScalar {
    /// How many directions one value carries.
    const LANES: usize;
    /// `re` with `scale` in direction `lane` (none: a constant).
    fn seed(re: f64, lane: Option<usize>, scale: f64) -> Self;
    /// The derivative part along direction `lane`.
    fn part(&self, lane: usize) -> f64;
}

impl Lanes for Dual64 {
    const LANES: usize = 1;

    #[inline(always)]
    fn seed(re: f64, lane: Option<usize>, scale: f64) -> Self {
        Dual64::new(re, if lane.is_some() { scale } else { 0.0 })
    }

    #[inline(always)]
    fn part(&self, _: usize) -> f64 {
        self.eps
    }
}

impl<const K: usize> Lanes for DualArray<[f64; K]>
where
    Self: ModelScalar,
{
    const LANES: usize = K;

    #[inline(always)]
    fn seed(re: f64, lane: Option<usize>, scale: f64) -> Self {
        let mut x = Self::from_re(re);
        if let Some(lane) = lane {
            x.eps[lane] = scale;
        }
        x
    }

    #[inline(always)]
    fn part(&self, lane: usize) -> f64 {
        self.eps[lane]
    }
}

/// The seeded point and velocity of one evaluation of the gradient code on
/// the lane type `D`, and the gradients it returns.
#[derive(Clone, Debug)]
pub(super) struct Seeded<D> {
    pub(super) q: Vec<D>,
    pub(super) v: Vec<D>,
    pub(super) gq: Vec<D>,
    pub(super) gv: Vec<D>,
}

impl<D> Default for Seeded<D> {
    fn default() -> Self {
        Self { q: Vec::new(), v: Vec::new(), gq: Vec::new(), gv: Vec::new() }
    }
}

impl<D: Lanes> Seeded<D> {
    /// Sizes the buffers for `n` coordinates (once).
    pub(super) fn allocate(&mut self, n: usize) -> Result<(), LinearSolveError> {
        if self.q.len() != n {
            let zero = D::from(0.0);
            *self = Self { q: filled(n, zero)?, v: filled(n, zero)?, gq: filled(n, zero)?, gv: filled(n, zero)? };
        }
        Ok(())
    }
}

/// The lane type for `classes` colour classes: a matrix of bandwidth 0, 1
/// or 2 (1, 3 or 5 classes) in one evaluation per point; wider bands and
/// general patterns in chunks of five classes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Width {
    One,
    Three,
    Five,
}

impl Width {
    pub(super) fn for_classes(classes: usize) -> Self {
        match classes {
            1 => Width::One,
            3 => Width::Three,
            _ => Width::Five,
        }
    }
}

/// Where the entries of the derivative columns go: the band of a matrix
/// (row `i`'s `2b + 1` entries around the diagonal) or its dense rows.
#[derive(Clone, Copy, Debug)]
pub(super) struct Layout {
    pub(super) n: usize,
    pub(super) bandwidth: Option<usize>,
}

impl Layout {
    /// The number of colour classes: columns `j ≡ k (mod 2b + 1)` of a
    /// matrix of bandwidth `b` never share a row's band (Curtis, Powell and
    /// Reid); every column its own class without a proven band.
    pub(super) fn classes(self) -> usize {
        self.bandwidth.map_or(self.n, |b| 2 * b + 1)
    }

    /// Entries per row of the storage.
    pub(super) fn width(self) -> usize {
        self.bandwidth.map_or(self.n, |b| 2 * b + 1)
    }

    /// Calls `add(slot, lane)` for each entry of row `i` whose column is in
    /// the classes `first .. first + lanes` (the lane `class − first`).
    #[inline(always)]
    pub(super) fn row(self, i: usize, first: usize, lanes: usize, mut add: impl FnMut(usize, usize)) {
        match self.bandwidth {
            Some(b) => {
                // Column `i + s − b` of slot `s`, its class that modulo `2b + 1`.
                let classes = 2 * b + 1;
                let mut class = (i + classes - b) % classes;
                for slot in 0..classes {
                    if let Some(lane) = class.checked_sub(first).filter(|&l| l < lanes) {
                        add(slot, lane);
                    }
                    class += 1;
                    if class == classes {
                        class = 0;
                    }
                }
            }
            None => {
                for lane in 0..lanes {
                    add(first + lane, lane);
                }
            }
        }
    }
}

/// The buffers of Newton steps from the system's generated gradient code
/// (forward over reverse): the point and the velocity seeded on dual
/// numbers and their gradients, and the `f64` values of the rule's points.
///
/// With `A = w h Σ_j L(t_k + c_j h, q_k + c_j Δq, Δq·h⁻¹)` (`w = 1` for one
/// point, `½` for two), the residual's part
/// `∂A/∂q_k|_{q_{k+1}} = Σ_j w [h (1 − c_j) L_q − h h⁻¹ L_v]` needs the
/// gradient of `L` at the points, and a column class `s` of the Jacobian
/// `J = ∂(∂A/∂q_k|_{q_{k+1}})/∂Δq` is the derivative of the same sum along
/// `s`: the gradient code on dual numbers with `q` seeded by `c_j s` and `v`
/// by `h⁻¹ s`. All `2b + 1` classes of a band up to `b = 2` travel together
/// on one vector dual number ([`Lanes`]), so each point costs one
/// evaluation; wider patterns go in chunks of five classes.
#[derive(Clone, Debug, Default)]
pub(super) struct Directional {
    one: Seeded<Dual64>,
    three: Seeded<DualArray<[f64; 3]>>,
    five: Seeded<DualArray<[f64; 5]>>,
    /// `q_k + c_j Δq` of both points, one after the other.
    at: Vec<f64>,
    /// `Δq·h⁻¹`.
    velocity: Vec<f64>,
    /// `∂L/∂q`, `∂L/∂v` in `f64` after convergence.
    fq: Vec<f64>,
    fv: Vec<f64>,
}

impl Directional {
    /// Sizes the buffers for `n` coordinates and a Jacobian of the given
    /// bandwidth (once).
    pub(super) fn allocate(
        &mut self,
        n: usize,
        bandwidth: Option<usize>,
        autonomous: bool,
    ) -> Result<(), LinearSolveError> {
        self.allocate_values(n, autonomous)?;
        match Width::for_classes(Layout { n, bandwidth }.classes()) {
            Width::One => self.one.allocate(n),
            Width::Three => self.three.allocate(n),
            Width::Five => self.five.allocate(n),
        }
    }

    /// Sizes what [`momentum_and_energy`](Self::momentum_and_energy) needs
    /// (once): the `f64` buffers, and `Dual64` ones for `∂L/∂t` when `L`
    /// depends on time.
    pub(super) fn allocate_values(&mut self, n: usize, autonomous: bool) -> Result<(), LinearSolveError> {
        if self.velocity.len() != n {
            let two_n = n.checked_mul(2).ok_or(LinearSolveError::TooLarge { n, per_column: 2 })?;
            *self = Self {
                at: filled(two_n, 0.0)?,
                velocity: filled(n, 0.0)?,
                fq: filled(n, 0.0)?,
                fv: filled(n, 0.0)?,
                ..Self::default()
            };
        }
        if autonomous { Ok(()) } else { self.one.allocate(n) }
    }

    /// The velocity `Δq·h⁻¹` and the points `q_k + c_j Δq`.
    pub(super) fn points(&mut self, points: [f64; 2], q0: &[f64], dq: &[f64], inv_h: f64) {
        let n = q0.len();
        for (v, &d) in self.velocity.iter_mut().zip(dq) {
            *v = d * inv_h;
        }
        for &j in distinct(points).0 {
            let c = points[j];
            for (i, x) in self.at[j * n..(j + 1) * n].iter_mut().enumerate() {
                *x = point_position(c, q0[i], dq[i]);
            }
        }
    }

    /// `∂A/∂q_k|_{q_{k+1}}` at the increment `dq` into `d_q0`, and the
    /// Jacobian `J` into `band` (row `i`'s `2b + 1` entries around the
    /// diagonal, or whole rows without a band). [`allocate`](Self::allocate)
    /// must have been called with this bandwidth.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn linearize(
        &mut self,
        model: &dyn TapeModel,
        t0: f64,
        h: f64,
        points: [f64; 2],
        q0: &[f64],
        dq: &[f64],
        bandwidth: Option<usize>,
        d_q0: &mut [f64],
        band: &mut [f64],
    ) {
        let n = q0.len();
        let inv_h = h.recip();
        self.points(points, q0, dq, inv_h);
        let layout = Layout { n, bandwidth };
        let step = Step { t0, h, inv_h, points, at: &self.at, velocity: &self.velocity };
        match Width::for_classes(layout.classes()) {
            Width::One => step.linearize(model, &mut self.one, layout, d_q0, band),
            Width::Three => step.linearize(model, &mut self.three, layout, d_q0, band),
            Width::Five => step.linearize(model, &mut self.five, layout, d_q0, band),
        }
    }

    /// `∂A/∂q_k|_{q_{k+1}}` at the increment `dq` alone into `d_q0`, from the
    /// `f64` gradient code: the real parts of [`linearize`](Self::linearize),
    /// summed in the same order, for the iterations that keep the Jacobian.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn residual(
        &mut self,
        model: &dyn TapeModel,
        t0: f64,
        h: f64,
        points: [f64; 2],
        q0: &[f64],
        dq: &[f64],
        d_q0: &mut [f64],
    ) {
        let n = q0.len();
        let inv_h = h.recip();
        self.points(points, q0, dq, inv_h);
        let (evaluated, w) = distinct(points);
        let b_v = w * (h * inv_h);
        d_q0.fill(0.0);
        for &j in evaluated {
            let c = points[j];
            let a_q = w * (h * (1.0 - c));
            let at = &self.at[j * n..(j + 1) * n];
            ModelScalar::gradient_qv(model, point_time(c, t0, h), at, &self.velocity, &mut self.fq, &mut self.fv);
            for i in 0..n {
                d_q0[i] += a_q * self.fq[i] - b_v * self.fv[i];
            }
        }
    }

    /// After convergence: `∂A/∂q_k` at fixed increment (the momentum change)
    /// into `g_q0`, and the step's discrete energy `−∂A/∂h`, from the `f64`
    /// gradient code and `L` (with `∂L/∂t` on a dual number when `L`
    /// depends on time) at the points; with the energy, whether `L` is
    /// finite at every point.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn momentum_and_energy(
        &mut self,
        model: &dyn TapeModel,
        t0: f64,
        h: f64,
        points: [f64; 2],
        q0: &[f64],
        dq: &[f64],
        g_q0: &mut [f64],
    ) -> (f64, bool) {
        let n = q0.len();
        let inv_h = h.recip();
        self.points(points, q0, dq, inv_h);
        let (evaluated, w) = distinct(points);
        g_q0.fill(0.0);
        // ∂A/∂h = Σ_j w [L + c_j h ∂L/∂t − L_v·Δq·h⁻¹].
        let mut g_h = 0.0;
        let mut lagrangian_finite = true;
        for &j in evaluated {
            let c = points[j];
            let t = point_time(c, t0, h);
            let at = &self.at[j * n..(j + 1) * n];
            ModelScalar::gradient_qv(model, t, at, &self.velocity, &mut self.fq, &mut self.fv);
            let wh = w * h;
            for (g, &f) in g_q0.iter_mut().zip(&self.fq) {
                *g += wh * f;
            }
            let (l, l_t) = if model.autonomous() {
                (ModelScalar::lagrangian(model, t, at, &self.velocity), 0.0)
            } else {
                for i in 0..n {
                    self.one.q[i] = Dual64::from(at[i]);
                    self.one.v[i] = Dual64::from(self.velocity[i]);
                }
                let l = ModelScalar::lagrangian(model, Dual64::new(t, 1.0), &self.one.q, &self.one.v);
                (l.re, l.eps)
            };
            let power: f64 = self.fv.iter().zip(&self.velocity).map(|(p, v)| p * v).sum();
            g_h += w * (l + c * h * l_t - power);
            lagrangian_finite &= l.is_finite();
        }
        (-g_h, lagrangian_finite)
    }
}

/// The `f64` data of one step's points, shared by the lane types.
pub(super) struct Step<'a> {
    t0: f64,
    h: f64,
    inv_h: f64,
    points: [f64; 2],
    /// `q_k + c_j Δq` of both points.
    at: &'a [f64],
    /// `Δq·h⁻¹`.
    velocity: &'a [f64],
}

impl Step<'_> {
    /// [`Directional::linearize`] on the lane type `D`: per chunk of
    /// `D::LANES` classes, one evaluation of the gradient code per point.
    /// The arithmetic of each entry is that of one `Dual64` evaluation per
    /// class (the real part is the `f64` code's), summed over the points in
    /// the same order.
    pub(super) fn linearize<D: Lanes>(
        &self,
        model: &dyn TapeModel,
        seeded: &mut Seeded<D>,
        layout: Layout,
        d_q0: &mut [f64],
        band: &mut [f64],
    ) {
        let n = layout.n;
        let width = layout.width();
        let (evaluated, w) = distinct(self.points);
        // The weight of `L_v`: `w h · h⁻¹`, the derivative of the action as
        // computed (`v = Δq·h⁻¹`).
        let b_v = w * (self.h * self.inv_h);
        let classes = layout.classes();
        d_q0.fill(0.0);
        band[..n * width].fill(0.0);
        for first in (0..classes).step_by(D::LANES) {
            let lanes = D::LANES.min(classes - first);
            for &j in evaluated {
                let c = self.points[j];
                let a_q = w * (self.h * (1.0 - c));
                let at = &self.at[j * n..(j + 1) * n];
                // Seed the chunk: column `i` in lane `(i mod classes) − first`.
                let mut class: usize = 0;
                for i in 0..n {
                    let lane = class.checked_sub(first).filter(|&l| l < lanes);
                    seeded.q[i] = D::seed(at[i], lane, c);
                    seeded.v[i] = D::seed(self.velocity[i], lane, self.inv_h);
                    class += 1;
                    if class == classes {
                        class = 0;
                    }
                }
                let t = D::from(point_time(c, self.t0, self.h));
                ModelScalar::gradient_qv(model, t, &seeded.q, &seeded.v, &mut seeded.gq, &mut seeded.gv);
                for i in 0..n {
                    let (gq, gv) = (&seeded.gq[i], &seeded.gv[i]);
                    let row = &mut band[i * width..(i + 1) * width];
                    layout.row(i, first, lanes, |slot, lane| row[slot] += a_q * gq.part(lane) - b_v * gv.part(lane));
                }
                if first == 0 {
                    for i in 0..n {
                        d_q0[i] += a_q * seeded.gq[i].re() - b_v * seeded.gv[i].re();
                    }
                }
            }
        }
    }
}

/// `∂L/∂v` and the mass matrix `∂²L/∂v²` at `(t, q, v)` from the gradient
/// code: `∂L/∂v` on `f64` into `p`, `∂²L/∂v²` by colour classes on lane
/// duals (`v` seeded, `q` constant) into `band` (the layout's storage).
/// Allocates its dual buffers (a readout, not a step).
#[allow(clippy::too_many_arguments)]
pub(super) fn mass_from_gradient_code(
    model: &dyn TapeModel,
    t: f64,
    q: &[f64],
    v: &[f64],
    layout: Layout,
    p: &mut [f64],
    band: &mut [f64],
) -> Result<(), LinearSolveError> {
    let n = layout.n;
    let mut fq = filled(n, 0.0)?;
    ModelScalar::gradient_qv(model, t, q, v, &mut fq, p);
    match Width::for_classes(layout.classes()) {
        Width::One => mass_lanes::<Dual64>(model, t, q, v, layout, band),
        Width::Three => mass_lanes::<DualArray<[f64; 3]>>(model, t, q, v, layout, band),
        Width::Five => mass_lanes::<DualArray<[f64; 5]>>(model, t, q, v, layout, band),
    }
}

/// The mass matrix of [`mass_from_gradient_code`] on the lane type `D`.
pub(super) fn mass_lanes<D: Lanes>(
    model: &dyn TapeModel,
    t: f64,
    q: &[f64],
    v: &[f64],
    layout: Layout,
    band: &mut [f64],
) -> Result<(), LinearSolveError> {
    let n = layout.n;
    let width = layout.width();
    let classes = layout.classes();
    let mut seeded = Seeded::<D>::default();
    seeded.allocate(n)?;
    for (x, &y) in seeded.q.iter_mut().zip(q) {
        *x = D::from(y);
    }
    band[..n * width].fill(0.0);
    for first in (0..classes).step_by(D::LANES) {
        let lanes = D::LANES.min(classes - first);
        let mut class: usize = 0;
        for i in 0..n {
            let lane = class.checked_sub(first).filter(|&l| l < lanes);
            seeded.v[i] = D::seed(v[i], lane, 1.0);
            class += 1;
            if class == classes {
                class = 0;
            }
        }
        ModelScalar::gradient_qv(model, D::from(t), &seeded.q, &seeded.v, &mut seeded.gq, &mut seeded.gv);
        for i in 0..n {
            let gv = &seeded.gv[i];
            let row = &mut band[i * width..(i + 1) * width];
            layout.row(i, first, lanes, |slot, lane| row[slot] = gv.part(lane));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::tape_step::TapeModel;
    use crate::structure::Coupling;
    use crate::system::Scalar;
    use crate::tape::Var;

    /// A chain with a position-dependent mass, kinetic coupling of
    /// neighbours and quartic springs (bandwidth 1), its gradient written by
    /// hand over any scalar.
    struct Chain;

    fn chain_lagrangian<D: Scalar>(q: &[D], v: &[D]) -> D {
        let mut l = D::from(0.0);
        for i in 0..q.len() {
            l += v[i] * v[i] * (q[i].cos() * 0.1 + 1.0) * 0.5 + q[i].cos();
            if i + 1 < q.len() {
                let e = q[i + 1] - q[i];
                l += v[i] * v[i + 1] * (q[i] - q[i + 1]).cos() * 0.2 - e.powi(4) * 0.25;
            }
        }
        l
    }

    impl TapeModel for Chain {
        fn coupling(&self) -> Coupling {
            Coupling::GENERAL
        }
        fn lagrangian(&self, _: Var, q: &[Var], v: &[Var]) -> Var {
            chain_lagrangian(q, v)
        }
        fn action(&self, _: Var, _: Var, _: &[Var], _: &[Var]) -> Var {
            unreachable!("the test steps no tape")
        }
        fn autonomous(&self) -> bool {
            true
        }
        fn points(&self) -> Option<[f64; 2]> {
            None
        }
        fn has_gradient_qv(&self) -> bool {
            true
        }

        crate::integrator::tape_step::scalar_methods!();
    }

    impl Chain {
        fn gradient_qv_generic<D: Scalar>(&self, _: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) {
            let n = q.len();
            for i in 0..n {
                let (s, c) = q[i].sin_cos();
                out_q[i] = -(v[i] * v[i] * s * 0.05) - s;
                out_v[i] = v[i] * (c * 0.1 + 1.0);
            }
            for i in 0..n - 1 {
                let (s, c) = (q[i] - q[i + 1]).sin_cos();
                let vv = v[i] * v[i + 1] * 0.2;
                out_q[i] -= vv * s;
                out_q[i + 1] += vv * s;
                out_v[i] += v[i + 1] * c * 0.2;
                out_v[i + 1] += v[i] * c * 0.2;
                let e3 = (q[i + 1] - q[i]).powi(3);
                out_q[i] += e3;
                out_q[i + 1] -= e3;
            }
        }
        fn lagrangian_generic<D: Scalar>(&self, _: D, q: &[D], v: &[D]) -> D {
            chain_lagrangian(q, v)
        }
    }

    /// The vector lanes give the Jacobian and residual of one `Dual64`
    /// evaluation per colour class (the path before them) bit for bit, for
    /// bands of width 3, 5 and 7 (chunks) and the dense pattern (chunks),
    /// one and two quadrature points; and the band is the Jacobian (against
    /// central differences of the residual).
    #[test]
    fn vector_lanes_give_the_per_class_jacobian_bit_for_bit() {
        let n = 23;
        let q0: Vec<f64> = (0..n).map(|i| 0.4 * (0.7 * i as f64).sin()).collect();
        let dq: Vec<f64> = (0..n).map(|i| 0.03 * (1.3 * i as f64 + 0.2).cos()).collect();
        let h = 0.05;
        for bandwidth in [Some(1), Some(2), Some(3), None] {
            for points in [[0.5, 0.5], [0.0, 1.0], [0.3, 0.3]] {
                let layout = Layout { n, bandwidth };
                let width = layout.width();
                let mut lanes = Directional::default();
                lanes.allocate(n, bandwidth, true).unwrap();
                let (mut r, mut band) = (vec![0.0; n], vec![f64::NAN; n * width]);
                lanes.linearize(&Chain, 0.0, h, points, &q0, &dq, bandwidth, &mut r, &mut band);
                // The reference: `Dual64` lanes, one class per evaluation.
                let mut one = Seeded::<Dual64>::default();
                one.allocate(n).unwrap();
                let (mut r1, mut band1) = (vec![0.0; n], vec![f64::NAN; n * width]);
                let step = Step { t0: 0.0, h, inv_h: h.recip(), points, at: &lanes.at, velocity: &lanes.velocity };
                step.linearize(&Chain, &mut one, layout, &mut r1, &mut band1);
                let case = format!("bandwidth {bandwidth:?}, points {points:?}");
                assert!(r.iter().zip(&r1).all(|(a, b)| a.to_bits() == b.to_bits()), "{case}: residual");
                assert!(band.iter().zip(&band1).all(|(a, b)| a.to_bits() == b.to_bits()), "{case}: jacobian");
                // Column j of the Jacobian by central differences.
                let (mut plus, mut minus) = (vec![0.0; n], vec![0.0; n]);
                let mut scratch = vec![0.0; n * width];
                let mut largest = 0.0f64;
                for j in 0..n {
                    let eps = 1e-6;
                    let mut x = dq.clone();
                    x[j] += eps;
                    lanes.linearize(&Chain, 0.0, h, points, &q0, &x, bandwidth, &mut plus, &mut scratch);
                    x[j] -= 2.0 * eps;
                    lanes.linearize(&Chain, 0.0, h, points, &q0, &x, bandwidth, &mut minus, &mut scratch);
                    for i in 0..n {
                        let fd = (plus[i] - minus[i]) / (2.0 * eps);
                        let entry = match bandwidth {
                            Some(b) if i.abs_diff(j) > b => 0.0,
                            Some(b) => band[i * width + j + b - i],
                            None => band[i * n + j],
                        };
                        largest = largest.max((fd - entry).abs());
                    }
                }
                // Entries are O(1/h) = O(20); differences of step 1e-6 are good to ~1e-8.
                assert!(largest < 1e-6, "{case}: {largest:e}");
            }
        }
    }
}
