//! The linearisation of a step of the explicit time-transformed splitting
//! ([`ExplicitAdaptive`]) for the sensitivities and the adjoint.
//!
//! A step is a fixed sequence of explicit maps of the extended phase
//! `(q, t, p, p_t)`, the sub-flows of [`stages`]:
//!
//! ```text
//! drift:  q += h f'(T(p) + p_t + c) M⁻¹p,     t += h f'(T(p) + p_t + c)
//! kick:   p −= h f'(c − V) ∇V,                p_t −= h f'(c − V) ∂_t V
//! ```
//!
//! so its Jacobian is the product of theirs, and no equation is solved. It
//! is taken column by column: one pass of the step on first-order dual
//! numbers seeded on one input (a coordinate of the extended state, a
//! parameter `θ`, which enters `V` and `M`, the shift `c`, or the step's
//! size in `s`), with `∇V` and `∂_t V` from a nested dual number. The
//! derivatives are those of the map the driver computes, to round-off.
//! The forward sensitivities multiply these Jacobians; the adjoint forms
//! none for a full step and pulls the costate back through the transposed
//! sub-flows instead ([`Transpose`]).
//!
//! The node times, the constant `c` and the landing step on `t_end` are
//! those of [`transformed`](super::transformed): the same [`Linear`] and
//! [`Start`], the `c` column carried along the run, and the landing step's
//! size eliminated by [`Linear::of_step`] from the column of the step size.
//! The default `c` is differentiated where it depends on the start
//! (`c = E + m`, [`shift_with_margin`]); the bound start of a gravitating
//! potential has `c = 0` whatever the inputs.

use core::convert::Infallible;

use nalgebra::{DMatrix, DVector, RowDVector};
use num_dual::{Dual, Dual64, HyperDual};

use super::Parametric;
use super::linearisation::seeded;
use super::transformed::{Linear, Start};
use crate::hyperdual::{DualArray, Pair, Timed, Vector};
use crate::system::Scalar;
use crate::time_transform::{
    ExplicitAdaptive, ExtendedPoint, Flow, gravitating_start, kinetic_energy, shift_with_margin, square, stages,
};

/// `V`, `∇V` and `∂_t V` at `(t, q)` with the parameters `theta`, on any
/// scalar: one evaluation of `L(t, q, 0)` on a nested dual number per
/// coordinate (and one for `t` where `L` depends on it).
fn potential_gradient<Sys, D, const N: usize, const P: usize>(
    system: &Sys,
    theta: &[D; P],
    t: D,
    q: [D; N],
) -> (D, [D; N], D)
where
    Sys: Parametric<N, P>,
    D: Scalar,
{
    let lifted: [Dual<D>; P] = theta.map(Dual::from_re);
    let (tl, ql) = (Dual::from_re(t), q.map(Dual::from_re));
    let rest = [Dual::from_re(D::zero()); N];
    let mut dv = [D::zero(); N];
    for (i, slot) in dv.iter_mut().enumerate() {
        let mut seeded = ql;
        seeded[i].eps = D::one();
        *slot = -system.lagrangian_with(&lifted, tl, seeded, rest).eps;
    }
    let v = -system.lagrangian_with(theta, t, q, [D::zero(); N]);
    let dt = if Sys::AUTONOMOUS {
        D::zero()
    } else {
        let mut ts = tl;
        ts.eps = D::one();
        -system.lagrangian_with(&lifted, ts, ql, rest).eps
    };
    (v, dv, dt)
}

/// `M = ∂²L/∂v²` with the parameters `theta` (constant in `(t, q, v)` for
/// the systems the splitting takes), on the heap.
fn mass<Sys, D, const N: usize, const P: usize>(system: &Sys, theta: &[D; P], t: D, q: [D; N]) -> Box<[[D; N]; N]>
where
    Sys: Parametric<N, P>,
    D: Scalar,
{
    let lifted: [HyperDual<D>; P] = theta.map(HyperDual::from_re);
    let (tl, ql) = (HyperDual::from_re(t), q.map(HyperDual::from_re));
    let mut m = square(vec![[D::zero(); N]; N]);
    for i in 0..N {
        for j in i..N {
            let mut v = [HyperDual::from_re(D::zero()); N];
            v[i].eps1 = D::one();
            v[j].eps2 = D::one();
            let h = system.lagrangian_with(&lifted, tl, ql, v).eps1eps2;
            m[i][j] = h;
            m[j][i] = h;
        }
    }
    m
}

/// `M(θ)⁻¹` to first order in the dual parts: one Newton–Schulz step
/// `2A − A M A` from the driver's inverse `A` of the real part, whose
/// derivative `−A Ṁ A` is that of the inverse (the real part is `A` to
/// round-off).
fn inverse_of<D: Scalar, const N: usize>(a: &[[f64; N]; N], m: &[[D; N]; N]) -> Box<[[D; N]; N]> {
    let mut am = square(vec![[D::zero(); N]; N]);
    for i in 0..N {
        for j in 0..N {
            for k in 0..N {
                am[i][j] += m[k][j] * a[i][k];
            }
        }
    }
    let mut out = square(vec![[D::zero(); N]; N]);
    for i in 0..N {
        for j in 0..N {
            let mut x = D::from(2.0 * a[i][j]);
            for k in 0..N {
                x -= am[i][k] * a[k][j];
            }
            out[i][j] = x;
        }
    }
    out
}

/// One step of size `h` in `s` of `driver`'s splitting from `x`, with the
/// parameters `theta`, the inverse mass matrix `inverse` and the shift `c`,
/// on any scalar: the sub-flows of [`stages`], without the driver's checks
/// (the step being linearised passed them).
fn step<Sys, D, const N: usize, const P: usize>(
    driver: &ExplicitAdaptive<Sys, f64, N>,
    (theta, inverse, c): (&[D; P], &[[D; N]; N], D),
    h: D,
    mut x: ExtendedPoint<D, N>,
) -> ExtendedPoint<D, N>
where
    Sys: Parametric<N, P>,
    D: Scalar,
{
    let done: Result<(), Infallible> = stages(driver.leapfrog_form(), driver.weights(), |flow, fraction| {
        sub_flow(driver, (theta, inverse, c), flow, h * fraction, &mut x);
        Ok(())
    });
    let Ok(()) = done;
    x
}

/// The sub-flow `flow` of size `k` in `s` on `x` (see [`step`]).
fn sub_flow<Sys, D, const N: usize, const P: usize>(
    driver: &ExplicitAdaptive<Sys, f64, N>,
    (theta, inverse, c): (&[D; P], &[[D; N]; N], D),
    flow: Flow,
    k: D,
    x: &mut ExtendedPoint<D, N>,
) where
    Sys: Parametric<N, P>,
    D: Scalar,
{
    let f = driver.time_function();
    match flow {
        Flow::Drift => {
            let (kinetic, u) = kinetic_energy(inverse, &x.p);
            let s = k * f.derivative(kinetic + x.p_t + c);
            for (q, u) in x.q.iter_mut().zip(u) {
                *q += s * u;
            }
            x.t += s;
        }
        Flow::Kick => {
            let (v, dv, dt) = potential_gradient(driver.system(), theta, x.t, x.q);
            let s = k * f.derivative(c - v);
            for (p, d) in x.p.iter_mut().zip(dv) {
                *p -= s * d;
            }
            if !Sys::AUTONOMOUS {
                x.p_t -= s * dt;
            }
        }
    }
}

/// The Jacobians `Φ_x`, `Φ_θ`, `Φ_c` of the last step of `driver`, from
/// the extended point `from` where it started, with the landing step's
/// size eliminated where it landed on its target (see the
/// [module](self)). `None` before the first step or where a derivative is
/// not finite.
pub(crate) fn linearise<Sys, const N: usize, const P: usize>(
    driver: &ExplicitAdaptive<Sys, f64, N>,
    from: &ExtendedPoint<f64, N>,
) -> Option<Linear>
where
    Sys: Parametric<N, P>,
{
    let m = N + 1;
    let (states, c_col, h_col) = (2 * m, 2 * m + P, 2 * m + P + 1);
    let system = driver.system();
    let theta = system.parameters();
    let h = driver.last_step_in_s()?;
    let a = driver.inverse_mass();
    let plain = square(a.iter().map(|row| row.map(Dual64::from)).collect());
    let mut jacobian = DMatrix::<f64>::zeros(states, h_col + 1);
    for col in 0..=h_col {
        let mut th = theta.map(Dual64::from);
        let (mut c, mut hs) = (Dual64::from(driver.shift()), Dual64::from(h));
        let mut x = ExtendedPoint {
            q: from.q.map(Dual64::from),
            t: Dual64::from(from.t),
            p: from.p.map(Dual64::from),
            p_t: Dual64::from(from.p_t),
        };
        match col {
            col if col < N => x.q[col].eps = 1.0,
            col if col == N => x.t.eps = 1.0,
            col if col < states - 1 => x.p[col - m].eps = 1.0,
            col if col < states => x.p_t.eps = 1.0,
            col if col < c_col => th[col - states].eps = 1.0,
            col if col == c_col => c.eps = 1.0,
            _ => hs.eps = 1.0,
        }
        // M depends on the parameters alone.
        let corrected;
        let inverse = if (states..c_col).contains(&col) {
            corrected = inverse_of(a, &mass(system, &th, x.t, x.q));
            &corrected
        } else {
            &plain
        };
        let y = step(driver, (&th, inverse, c), hs, x);
        for (i, v) in y.q.iter().chain([&y.t]).chain(&y.p).chain([&y.p_t]).enumerate() {
            jacobian[(i, col)] = v.eps;
        }
    }
    let landing = driver.landed_here().then(|| jacobian.column(h_col).into_owned());
    Linear::of_step(
        jacobian.columns(0, states).into_owned(),
        jacobian.columns(states, P).into_owned(),
        jacobian.column(c_col).into_owned(),
        landing,
    )
}

/// What the reverse sweep keeps of one step of the splitting: a full step
/// by its end point and size, pulled back by [`Transpose`] without forming
/// a matrix; a landing step by its [`Linear`], whose projection needs the
/// whole time row.
pub(crate) enum Reverse<const N: usize> {
    /// A step of size `h` in `s` that ended at the extended point `end`.
    Step { end: ExtendedPoint<f64, N>, h: f64 },
    /// The linearisation of a landing step.
    Dense(Linear),
}

/// The last step of `driver`, which started at the extended point `from`,
/// for the reverse sweep (`None` before the first step or where a landing
/// step's derivative is not finite).
pub(crate) fn reverse<Sys, const N: usize, const P: usize>(
    driver: &ExplicitAdaptive<Sys, f64, N>,
    from: &ExtendedPoint<f64, N>,
) -> Option<Reverse<N>>
where
    Sys: Parametric<N, P>,
{
    if driver.landed_here() {
        return linearise(driver, from).map(Reverse::Dense);
    }
    Some(Reverse::Step { end: driver.extended_point(), h: driver.last_step_in_s()? })
}

/// The transposed linearisation of the splitting's full steps: `λ ↦ Φ_xᵀ λ`
/// with `Φ_θᵀ λ` and `Φ_cᵀ λ` accumulated, by one backward pass through the
/// sub-flows from the step's end point. Each sub-flow is pulled back at the
/// point it acted on and then undone: a drift leaves `(p, p_t)` as they
/// were and a kick `(q, t)`, so the point before a drift is
/// `q − s M⁻¹p, t − s` and the point before a kick `p + s ∇V,
/// p_t + s ∂_tV`, with the `s`, `M⁻¹p` and `∇V` the pullback forms anyway.
/// The points so recovered are the forward pass's to round-off, and no
/// pass of the step is run again. With `a = T + p_t + c`, `s = k f'(a)`,
/// `u = M⁻¹p`, a drift pulls `(λ_q, λ_t, λ_p, λ_{p_t})` back to
///
/// ```text
/// σ̄ = λ_q·u + λ_t,   ā = σ̄ k f''(a),
/// λ_p += s M⁻¹λ_q + ā u,   λ_{p_t} += ā,   c̄ += ā,
/// θ̄_j −= ā ½ uᵀ ∂_jM u + s (M⁻¹λ_q)ᵀ ∂_jM u
/// ```
///
/// and a kick, with `b = c − V`, `s = k f'(b)`, `φ = λ_p·∇V + λ_{p_t} ∂_tV`,
/// `σ̄ = −φ`, `b̄ = σ̄ k f''(b)`, to `λ_{(q, t)} −= s ∇φ + b̄ ∇V`,
/// `θ̄ −= s ∂_θφ + b̄ ∂_θV`, `c̄ += b̄`: `∇φ` is a Hessian–vector product,
/// one evaluation of `L` on a dual number along `(λ_p, λ_{p_t})` over one
/// seeded on `(q, θ)`, and on `t` too where `L` depends on it. A step
/// costs one such evaluation per kick and a few products per drift.
pub(crate) struct Transpose<const N: usize, const P: usize> {
    /// The sub-flows of a step, in order, with their fractions of it (the
    /// driver's [`stages`]).
    schedule: Vec<(Flow, f64)>,
    /// `∂M/∂θ_j`; empty where `M` does not depend on the parameters.
    dmass: Vec<Box<[[f64; N]; N]>>,
}

/// The slots `(q, θ)` of the dual number of a kick's pullback for an
/// autonomous `L`.
type Slots<const N: usize, const P: usize> = Pair<[f64; N], [f64; P]>;

/// The slots `(q, t, θ)` for an `L` that depends on the time.
type TimedSlots<const N: usize, const P: usize> = Pair<Timed<f64, N>, [f64; P]>;

/// The costate `(λ_q, λ_t, λ_p, λ_{p_t})` in the extended phase.
struct Costate<const N: usize> {
    q: [f64; N],
    t: f64,
    p: [f64; N],
    p_t: f64,
}

impl<const N: usize, const P: usize> Transpose<N, P> {
    /// For the steps of `driver` (its schedule of sub-flows and its
    /// parameters' derivatives of `M`).
    pub(crate) fn new<Sys: Parametric<N, P>>(driver: &ExplicitAdaptive<Sys, f64, N>) -> Self {
        let (system, x) = (driver.system(), driver.extended_point());
        let theta = system.parameters();
        let mut schedule = Vec::new();
        let done: Result<(), Infallible> = stages(driver.leapfrog_form(), driver.weights(), |flow, fraction| {
            schedule.push((flow, fraction));
            Ok(())
        });
        let Ok(()) = done;
        let dmass: Vec<_> = (0..P)
            .map(|j| {
                let mut th = theta.map(Dual64::from);
                th[j].eps = 1.0;
                let m = mass(system, &th, Dual64::from(x.t), x.q.map(Dual64::from));
                square(m.iter().map(|row| row.map(|v| v.eps)).collect())
            })
            .collect();
        // A mass matrix free of the parameters adds nothing to θ̄.
        let moves = dmass.iter().any(|m| m.iter().flatten().any(|&v| v != 0.0));
        Self { schedule, dmass: if moves { dmass } else { Vec::new() } }
    }

    /// Replaces `lambda` (extended phase, at the end `end` of a step of
    /// size `h`) by `Φ_xᵀ λ` and adds `Φ_θᵀ λ` to `dtheta`, `Φ_cᵀ λ` to
    /// `dc`; `None` where a result is not finite.
    pub(crate) fn step<Sys: Parametric<N, P>>(
        &self,
        driver: &ExplicitAdaptive<Sys, f64, N>,
        (end, h): (&ExtendedPoint<f64, N>, f64),
        lambda: &mut DVector<f64>,
        dtheta: &mut [f64; P],
        dc: &mut f64,
    ) -> Option<()> {
        let m = N + 1;
        let theta = driver.system().parameters();
        let (c, f, a) = (driver.shift(), driver.time_function(), driver.inverse_mass());
        // f''(x) = −α f'(x)/x.
        let alpha = f.exponent();
        let mut x = *end;
        let mut l = Costate {
            q: core::array::from_fn(|i| lambda[i]),
            t: lambda[N],
            p: core::array::from_fn(|i| lambda[m + i]),
            p_t: lambda[2 * m - 1],
        };
        for &(flow, fraction) in self.schedule.iter().rev() {
            // The driver's own size of the sub-flow.
            let k = h * fraction;
            match flow {
                Flow::Drift => {
                    let (kinetic, u) = kinetic_energy(a, &x.p);
                    let arg = kinetic + x.p_t + c;
                    let fp = f.derivative(arg);
                    let s = k * fp;
                    let mut sbar = l.t;
                    for i in 0..N {
                        sbar += l.q[i] * u[i];
                    }
                    let abar = sbar * k * (-alpha * fp / arg);
                    let mut w = [0.0; N];
                    for i in 0..N {
                        for j in 0..N {
                            w[i] += a[i][j] * l.q[j];
                        }
                    }
                    for i in 0..N {
                        l.p[i] += s * w[i] + abar * u[i];
                    }
                    l.p_t += abar;
                    *dc += abar;
                    for (j, dm) in self.dmass.iter().enumerate() {
                        let (mut umu, mut wmu) = (0.0, 0.0);
                        for i in 0..N {
                            let mut row = 0.0;
                            for j in 0..N {
                                row += dm[i][j] * u[j];
                            }
                            umu += u[i] * row;
                            wmu += w[i] * row;
                        }
                        dtheta[j] -= 0.5 * abar * umu + s * wmu;
                    }
                    // The point before the drift.
                    for i in 0..N {
                        x.q[i] -= s * u[i];
                    }
                    x.t -= s;
                }
                Flow::Kick => {
                    let (s, dv, dt) = if Sys::AUTONOMOUS {
                        kick::<Sys, Slots<N, P>, N, P>(driver, &theta, (k, alpha), &x, (None, N), &mut l, dtheta, dc)
                    } else {
                        let slots = (Some(N), m);
                        kick::<Sys, TimedSlots<N, P>, N, P>(driver, &theta, (k, alpha), &x, slots, &mut l, dtheta, dc)
                    };
                    // The point before the kick.
                    for i in 0..N {
                        x.p[i] += s * dv[i];
                    }
                    if !Sys::AUTONOMOUS {
                        x.p_t += s * dt;
                    }
                }
            }
        }
        for i in 0..N {
            lambda[i] = l.q[i];
            lambda[m + i] = l.p[i];
        }
        lambda[N] = l.t;
        lambda[2 * m - 1] = l.p_t;
        let mut finite = dc.is_finite();
        for v in lambda.iter().chain(dtheta.iter()) {
            finite &= v.is_finite();
        }
        finite.then_some(())
    }
}

/// Pulls the costate `l` back through the kick of size `k` at `x` (see
/// [`Transpose`]; `alpha` is the time function's exponent), with the slots
/// of the dual number `E` laid out as `slots`: the slot of `t` (if seeded)
/// and the first of `θ`. Returns the kick's `s = k f'(c − V)`, `∇V` and
/// `∂_tV` at `x`, which undo it.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn kick<Sys, E, const N: usize, const P: usize>(
    driver: &ExplicitAdaptive<Sys, f64, N>,
    theta: &[f64; P],
    (k, alpha): (f64, f64),
    x: &ExtendedPoint<f64, N>,
    (time_slot, theta_slot): (Option<usize>, usize),
    l: &mut Costate<N>,
    dtheta: &mut [f64; P],
    dc: &mut f64,
) -> (f64, [f64; N], f64)
where
    Sys: Parametric<N, P>,
    E: Vector<f64>,
{
    let (c, f) = (driver.shift(), driver.time_function());
    // Filled by loops: `array::from_fn` is not inlined at every
    // optimisation level, and this runs once per kick.
    let zero = Dual::from_re(DualArray::<E>::from_re(0.0));
    let mut q = [zero; N];
    for i in 0..N {
        q[i] = Dual::new(DualArray::variable(x.q[i], i), DualArray::from_re(l.p[i]));
    }
    let t = match time_slot {
        Some(slot) => Dual::new(DualArray::variable(x.t, slot), DualArray::from_re(l.p_t)),
        None => Dual::from_re(DualArray::from_re(x.t)),
    };
    let mut th = [zero; P];
    for j in 0..P {
        th[j] = Dual::from_re(DualArray::variable(theta[j], theta_slot + j));
    }
    let lagrangian = driver.system().lagrangian_with(&th, t, q, [zero; N]);
    // L(t, q, 0) = −V: its gradient is −∇V, its part along (λ_p, λ_{p_t})
    // is −φ with the gradient −∇φ.
    let (v, phi) = (-lagrangian.re.re, -lagrangian.eps.re);
    let (gradient, hessian) = (&lagrangian.re.eps, &lagrangian.eps.eps);
    let arg = c - v;
    let fp = f.derivative(arg);
    let s = k * fp;
    let bbar = -phi * k * (-alpha * fp / arg);
    let mut dv = [0.0; N];
    for i in 0..N {
        l.q[i] += s * hessian.get(i) + bbar * gradient.get(i);
        dv[i] = -gradient.get(i);
    }
    let dt = match time_slot {
        Some(slot) => {
            l.t += s * hessian.get(slot) + bbar * gradient.get(slot);
            -gradient.get(slot)
        }
        None => 0.0,
    };
    for j in 0..P {
        dtheta[j] += s * hessian.get(theta_slot + j) + bbar * gradient.get(theta_slot + j);
    }
    *dc += bbar;
    (s, dv, dt)
}

/// [`Start`] of `driver` from the initial data `(t0, q0, v0)`: `q = q0`,
/// `t = t0`, `p = M v0`, `p_t = −H(t0, q0, p)`, and the driver's default
/// shift `c` (`None` where a derivative is not finite).
pub(crate) fn start<Sys, const N: usize, const P: usize>(
    driver: &ExplicitAdaptive<Sys, f64, N>,
    (t0, q0, v0): (f64, [f64; N], [f64; N]),
) -> Option<Start>
where
    Sys: Parametric<N, P>,
{
    let m = N + 1;
    let system = driver.system();
    let theta = system.parameters();
    let k = 2 * N + P;
    let mut tangent = DMatrix::<f64>::zeros(2 * m, k);
    let mut dc = RowDVector::<f64>::zeros(k);
    let mut gravitating = None;
    for col in 0..k {
        let (q, v, th) = seeded(&q0, &v0, &theta, col);
        let t = Dual64::from(t0);
        let mass = mass(system, &th, t, q);
        let p: [Dual64; N] = core::array::from_fn(|i| (0..N).map(|j| mass[i][j] * v[j]).sum());
        let kinetic = p.iter().zip(&v).map(|(&p, &v)| p * v).sum::<Dual64>() * 0.5;
        let (potential, dv, _) = potential_gradient(system, &th, t, q);
        let zero = *gravitating.get_or_insert_with(|| gravitating_start(system, t0, q0, kinetic.re, potential.re));
        let c = if zero {
            Dual64::from(0.0)
        } else {
            let virial = q.iter().zip(&dv).map(|(&q, &d)| q * d).sum();
            shift_with_margin(kinetic, potential, virial)
        };
        dc[col] = c.eps;
        let p_t = -(kinetic + potential);
        for i in 0..N {
            tangent[(i, col)] = q[i].eps;
            tangent[(m + i, col)] = p[i].eps;
        }
        tangent[(2 * m - 1, col)] = p_t.eps;
    }
    let finite = tangent.iter().chain(dc.iter()).all(|v| v.is_finite());
    finite.then_some(Start { tangent, c: dc })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::Composition;
    use crate::problem::{Dim, Extended, Problem, Scheme};
    use crate::sensitivity::fixtures::{Kepler, relative};
    use crate::sensitivity::{Checkpoints, Loss};
    use crate::solution::Plan;
    use crate::system::Lagrangian;
    use crate::time_transform::TimeFunction;
    use num_dual::DualNum;

    /// A pendulum `L = ½ m l² v² + m g l cos q` with `(m, g)` as
    /// parameters: not gravitating, so the default `c = E + m` moves with
    /// the inputs, and `M = m l²` with the parameter `m`.
    #[derive(Clone)]
    struct Pendulum {
        m: f64,
        g: f64,
    }

    impl Lagrangian<1> for Pendulum {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 1] = [false];
        const SEPARABILITY: crate::Separability = crate::Separability::ConstantMass;
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
            self.lagrangian_with(&[D::from(self.m), D::from(self.g)], t, q, v)
        }
    }

    impl Parametric<1, 2> for Pendulum {
        const NAMES: [&'static str; 2] = ["m", "g"];
        fn parameters(&self) -> [f64; 2] {
            [self.m, self.g]
        }
        fn with_parameters(&self, theta: [f64; 2]) -> Self {
            Self { m: theta[0], g: theta[1] }
        }
        fn lagrangian_with<D: Scalar>(&self, theta: &[D; 2], _t: D, q: [D; 1], v: [D; 1]) -> D {
            let l = 0.8;
            theta[0] * (v[0] * v[0] * (0.5 * l * l) + theta[1] * l * q[0].cos())
        }
    }

    /// A driven oscillator `L = ½ v² − ½ k (1 + 0.3 sin t) q²` with the
    /// stiffness `k` as a parameter: `V` depends on the time, so the kicks
    /// move `p_t` and the kick's pullback seeds `t`.
    #[derive(Clone)]
    struct Driven {
        k: f64,
    }

    impl Lagrangian<1> for Driven {
        const AUTONOMOUS: bool = false;
        const CYCLIC: [bool; 1] = [false];
        const SEPARABILITY: crate::Separability = crate::Separability::ConstantMass;
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
            self.lagrangian_with(&[D::from(self.k)], t, q, v)
        }
    }

    impl Parametric<1, 1> for Driven {
        const NAMES: [&'static str; 1] = ["k"];
        fn parameters(&self) -> [f64; 1] {
            [self.k]
        }
        fn with_parameters(&self, theta: [f64; 1]) -> Self {
            Self { k: theta[0] }
        }
        fn lagrangian_with<D: Scalar>(&self, theta: &[D; 1], t: D, q: [D; 1], v: [D; 1]) -> D {
            (v[0] * v[0] - theta[0] * (t.sin() * 0.3 + 1.0) * q[0] * q[0]) * 0.5
        }
    }

    /// A loss that reads the node times: running `10⁻² (q_0 sin t + q_{N−1})`,
    /// terminal `|q|² + θ_0 q_{N−1} p_{N−1} + t`.
    struct Fit;
    impl<const N: usize, const P: usize> Loss<N, P> for Fit {
        fn running<D: Scalar>(&self, _k: u64, t: D, q: [D; N], _p: [D; N], _theta: &[D; P]) -> D {
            (q[0] * t.sin() + q[N - 1]) * 1e-2
        }
        fn terminal<D: Scalar>(&self, t: D, q: [D; N], p: [D; N], theta: &[D; P]) -> D {
            q.iter().fold(D::zero(), |s, &x| s + x * x) + theta[0] * q[N - 1] * p[N - 1] + t
        }
    }

    fn kl8() -> Scheme {
        Scheme::splitting(TimeFunction::Logarithmic, Some(Composition::KAHAN_LI8))
    }

    /// The loss of a plain run of `scheme`, step `sigma` in `s`, to `t_end`.
    fn loss_of<S: Parametric<N, P>, const N: usize, const P: usize>(
        problem: Problem<S, Dim<N>>,
        scheme: &Scheme,
        sigma: f64,
        t_end: f64,
    ) -> f64
    where
        Dim<N>: Extended<N>,
    {
        let theta = problem.system().parameters();
        let sol = problem.solve(scheme, sigma, Plan::until(t_end).without_velocities()).unwrap().into_result().unwrap();
        let n = sol.len() - 1;
        let mut j = 0.0;
        for k in 0..=n {
            j += Fit.running(k as u64, sol.t[k], sol.q.array::<N>(k).unwrap(), sol.p.array::<N>(k).unwrap(), &theta);
        }
        j + Fit.terminal(sol.t[n], sol.q.array::<N>(n).unwrap(), sol.p.array::<N>(n).unwrap(), &theta)
    }

    /// dJ/d(q0, v0, θ) from the forward sensitivities of every node:
    /// `Σ_k ∂ℓ_k/∂(q, p, t) S_k + ∂ℓ_k/∂θ`.
    fn forward_gradient<S: Parametric<N, P>, const N: usize, const P: usize>(
        problem: &Problem<S, Dim<N>>,
        scheme: &Scheme,
        sigma: f64,
        t_end: f64,
    ) -> Vec<f64>
    where
        Dim<N>: Extended<N>,
    {
        let theta = problem.system().parameters();
        let run = problem.solve_with_sensitivities(scheme, sigma, Plan::until(t_end).without_velocities()).unwrap();
        assert!(run.error.is_none() && run.solution.is_finished());
        let n = run.solution.len() - 1;
        let mut total = vec![0.0; 2 * N + P];
        for (k, s) in run.jacobians.iter().enumerate() {
            let (t, q, p) =
                (run.solution.t[k], run.solution.q.array::<N>(k).unwrap(), run.solution.p.array::<N>(k).unwrap());
            // ∂ℓ_k/∂(q, p, t, θ) by dual numbers, one input at a time.
            let term = |i: usize| {
                let mut x: Vec<Dual64> =
                    q.iter().chain(&p).chain([&t]).chain(&theta).map(|&v| Dual64::from(v)).collect();
                x[i].eps = 1.0;
                let (q, p, t): ([Dual64; N], [Dual64; N], Dual64) =
                    (core::array::from_fn(|j| x[j]), core::array::from_fn(|j| x[N + j]), x[2 * N]);
                let th: [Dual64; P] = core::array::from_fn(|j| x[2 * N + 1 + j]);
                let r = Fit.running(k as u64, t, q, p, &th);
                if k == n { r + Fit.terminal(t, q, p, &th) } else { r }.eps
            };
            let g: Vec<f64> = (0..2 * N + 1 + P).map(term).collect();
            for (col, slot) in total.iter_mut().enumerate() {
                *slot += (0..2 * N).map(|i| g[i] * s.get(i, col)).sum::<f64>() + g[2 * N] * s.time[col];
                if col >= 2 * N {
                    *slot += g[2 * N + 1 + col - 2 * N];
                }
            }
        }
        total
    }

    /// The adjoint against the forward sensitivities and central
    /// differences (step `fd_step · max(1, |x|)`) of whole plain runs;
    /// returns `(vs forward, vs differences)`.
    fn agreement<S: Parametric<N, P>, const N: usize, const P: usize>(
        system: S,
        (q0, v0): ([f64; N], [f64; N]),
        (sigma, t_end, fd_step): (f64, f64, f64),
    ) -> (f64, f64)
    where
        Dim<N>: Extended<N>,
    {
        let scheme = kl8();
        let problem = Problem::new(system.clone(), 0.0, q0, v0);
        let g = problem.gradient(&scheme, sigma, t_end, &Fit, Checkpoints::Budget(7)).unwrap();
        assert_eq!(g.last.t, t_end);
        let adjoint: Vec<f64> = g.q0.iter().chain(&g.v0).chain(&g.theta).copied().collect();
        let forward = forward_gradient(&problem, &scheme, sigma, t_end);
        let value = loss_of(problem, &scheme, sigma, t_end);
        assert!((g.value - value).abs() <= 1e-13 * value.abs(), "{} vs {value}", g.value);
        let theta = system.parameters();
        let base: Vec<f64> = q0.iter().chain(&v0).chain(&theta).copied().collect();
        let fd: Vec<f64> = (0..base.len())
            .map(|i| {
                let step = fd_step * base[i].abs().max(1.0);
                let at = |s: f64| {
                    let mut x = base.clone();
                    x[i] += s;
                    let th: [f64; P] = core::array::from_fn(|j| x[2 * N + j]);
                    let p = Problem::new(
                        system.with_parameters(th),
                        0.0,
                        core::array::from_fn(|j| x[j]),
                        core::array::from_fn(|j| x[N + j]),
                    );
                    loss_of(p, &scheme, sigma, t_end)
                };
                (at(step) - at(-step)) / (2.0 * step)
            })
            .collect();
        let (vs_forward, vs_fd) = (relative(&adjoint, &forward), relative(&adjoint, &fd));
        eprintln!(
            "{} steps: adjoint {adjoint:?}\nforward {forward:?}\ncentral differences {fd:?}\n\
             adjoint vs forward {vs_forward:.1e}, vs central differences {vs_fd:.1e}",
            g.last.step
        );
        (vs_forward, vs_fd)
    }

    /// The adjoint pulls back through the transposed sub-flows
    /// ([`Transpose`]), the forward sensitivities multiply the Jacobians of
    /// dual passes: two computations of the same derivatives.
    /// Measured: 189 steps, adjoint vs forward 8.5e-16, vs central
    /// differences 3.8e-9 (3.1e-7 at a difference step of 1e-6, whose
    /// truncation error three orbits amplify). Without the landing step's
    /// projection the adjoint is off the differences by 1.3 (relative).
    #[test]
    fn kepler_adjoint_agrees_with_forward_sensitivities_and_differences() {
        // e = 0.5 from the pericentre, three orbits (period 2π); the bound
        // start of a gravitating potential has c = 0 whatever the inputs.
        let e: f64 = 0.5;
        let start = ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()]);
        let (vs_forward, vs_fd) = agreement(Kepler { mu: 1.0 }, start, (0.1, 6.0 * std::f64::consts::PI, 1e-7));
        assert!(vs_forward <= 1e-12, "{vs_forward:e}");
        assert!(vs_fd <= 1e-7, "{vs_fd:e}");
    }

    /// One step of size `sigma` in `s` of the logarithmic drift–kick–drift
    /// leapfrog composed by Kahan–Li 8 on Kepler (unit mass, `c = 0`), on
    /// dual numbers, written out here from the formulas: drift
    /// `q += h p/a, t += h/a` with `a = |p|²/2 + p_t`, kick
    /// `p −= h (r/μ) μ q/r³`; stages `w_1/2, w_1, (w_1 + w_2)/2, …, w_m, w_m/2`.
    fn dual_kepler_step(mu: Dual64, sigma: f64, x: &mut ([Dual64; 2], Dual64, [Dual64; 2], Dual64)) {
        let (q, t, p, pt) = x;
        let w = Composition::KAHAN_LI8.weights();
        let drift = |h: f64, q: &mut [Dual64; 2], t: &mut Dual64, p: &[Dual64; 2], pt: Dual64| {
            let a = (p[0] * p[0] + p[1] * p[1]) * 0.5 + pt;
            let s = a.recip() * h;
            q[0] += s * p[0];
            q[1] += s * p[1];
            *t += s;
        };
        let kick = |h: f64, q: &[Dual64; 2], p: &mut [Dual64; 2]| {
            let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
            let s = r / mu * h;
            let f = mu / (r * r * r);
            p[0] -= s * f * q[0];
            p[1] -= s * f * q[1];
        };
        drift(sigma * (0.5 * w[0]), q, t, p, *pt);
        for i in 0..w.len() {
            kick(sigma * w[i], q, p);
            let half = if i + 1 < w.len() { 0.5 * (w[i] + w[i + 1]) } else { 0.5 * w[i] };
            drift(sigma * half, q, t, p, *pt);
        }
    }

    #[test]
    fn dual_numbers_through_a_short_kepler_run_agree_with_the_sensitivities() {
        // 40 steps in `s` of a run that lands later: node 40 is a full step.
        let (steps, sigma, e) = (40, 0.1, 0.5f64);
        let (q0, v0) = ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()]);
        let run = Problem::new(Kepler { mu: 1.0 }, 0.0, q0, v0)
            .solve_with_sensitivities(&kl8(), sigma, Plan::until(6.0 * std::f64::consts::PI).without_velocities())
            .unwrap();
        assert_eq!(run.solution.step[steps], Some(steps as u64));
        let row = &run.jacobians[steps];
        let (mut worst, mut state_gap) = (0.0f64, 0.0f64);
        for col in 0..5 {
            let mut z = [q0[0], q0[1], v0[0], v0[1], 1.0].map(Dual64::from);
            z[col].eps = 1.0;
            let (q, v, mu) = ([z[0], z[1]], [z[2], z[3]], z[4]);
            let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
            let pt = -((v[0] * v[0] + v[1] * v[1]) * 0.5 - mu / r);
            let mut x = (q, Dual64::from(0.0), v, pt);
            for _ in 0..steps {
                dual_kepler_step(mu, sigma, &mut x);
            }
            let (q, t, p, _) = x;
            let (sq, sp, st) = (&run.solution.q[steps], &run.solution.p[steps], run.solution.t[steps]);
            state_gap =
                state_gap.max(relative(&[q[0].re, q[1].re, t.re, p[0].re, p[1].re], &[sq[0], sq[1], st, sp[0], sp[1]]));
            let dual = [q[0].eps, q[1].eps, t.eps, p[0].eps, p[1].eps];
            let sens = [row.get(0, col), row.get(1, col), row.time[col], row.get(2, col), row.get(3, col)];
            worst = worst.max(relative(&sens, &dual));
        }
        // Measured: 2.4e-15 (states 6.1e-16).
        eprintln!("splitting sensitivities vs dual run: {worst:.1e} (states {state_gap:.1e})");
        assert!(state_gap <= 1e-13, "{state_gap:e}");
        assert!(worst <= 1e-13, "{worst:e}");
    }

    /// Measured: 1082 steps, adjoint vs forward 1.7e-13, vs central
    /// differences 2.1e-8. Without the column of `c` (its derivative in
    /// the start and its effect on the steps) the adjoint is off the
    /// differences by 1.1e-1, without the landing step's projection by 17.
    #[test]
    fn pendulum_adjoint_differentiates_the_shift_and_the_mass() {
        let (vs_forward, vs_fd) = agreement(Pendulum { m: 1.3, g: 9.81 }, ([1.0], [0.5]), (0.05, 5.0, 1e-6));
        assert!(vs_forward <= 1e-12, "{vs_forward:e}");
        assert!(vs_fd <= 1e-7, "{vs_fd:e}");
    }

    /// The time-dependent branch of the kick's pullback (the slot of `t`,
    /// `λ_t` and the undone `p_t`).
    #[test]
    fn driven_oscillator_adjoint_pulls_back_the_time_of_the_kicks() {
        let (vs_forward, vs_fd) = agreement(Driven { k: 2.0 }, ([1.0], [0.2]), (0.05, 5.0, 1e-6));
        assert!(vs_forward <= 1e-12, "{vs_forward:e}");
        assert!(vs_fd <= 1e-7, "{vs_fd:e}");
    }
}
