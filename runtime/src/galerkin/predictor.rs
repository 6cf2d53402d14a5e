//! Starting values of a Galerkin step: the previous step's polynomial
//! extrapolated to the new interval, corrected by its interpolation error.
//!
//! The previous step's polynomial `u(τ) = q_k + Σ_n ℓ_n(τ) D_n` (`τ` in units
//! of its step) extrapolated to the new control nodes, `D_m⁰ = u(1 + ρτ_m) −
//! u(1)` with `ρ = h/h_last`, misses the new step by `O(h^{s+1})` in the
//! positions and `O(h^s)` in the velocities (Hairer, Lubich & Wanner,
//! *Geometric Numerical Integration*, §VIII.6.1: starting approximations from
//! the continuous output). For a Gauss rule the velocity `u'` interpolates the
//! collocation velocities `V_j` at the points `c_j`, which are accurate to
//! `O(h^{s+1})`; elsewhere it carries the interpolation error of a degree
//! `s − 1` interpolant, `K ω(τ)` with `ω(τ) = Π_j (τ − c_j)`, which dominates
//! the miss. The velocity `v̂` at the end of the step, from `p_{k+1}` by the
//! Legendre transform, is accurate to the order of the method, so
//!
//! ```text
//! K = (h_last v̂ − u'(1)) / ω(1),      D_m⁰ += K ∫_1^{1+ρτ_m} ω(σ) dσ
//! ```
//!
//! removes that term: the corrected velocity is the degree-`s` interpolant of
//! `V_1 … V_s` and `v̂`, and the miss drops to `O(h^{s+1})` in the
//! velocities.

use crate::real::{Real, all_finite, gauss_jordan_into};
use crate::system::{Lagrangian, generalized_force};

use super::method::{Galerkin, PointDerivatives, velocity_hessian};

/// The increments of the previous step's polynomial (increments `d`, in
/// units of its step) extrapolated to the control nodes of a step `rho`
/// times as long: `u(1 + ρτ_m) − u(1)`.
#[inline(always)]
pub(super) fn extrapolate<const N: usize, const S: usize, const R: usize, T: Real>(
    g: &Galerkin<S, R, T>,
    d: &[[T; N]; S],
    rho: Option<T>,
) -> [[T; N]; S] {
    let mut out = [[T::zero(); N]; S];
    match rho {
        // The same step size: the tabulated weights.
        None => {
            for (row, weights) in out.iter_mut().zip(&g.extrapolate) {
                for (&w, dn) in weights.iter().zip(d) {
                    for (x, &y) in row.iter_mut().zip(dn) {
                        *x += w * y;
                    }
                }
            }
        }
        Some(rho) => {
            for m in 0..S {
                let tau = T::one() + g.control[m] * rho;
                for n in 0..S {
                    let w = g.basis(n + 1, tau) - if n + 1 == S { 1.0 } else { 0.0 };
                    for i in 0..N {
                        out[m][i] += w * d[n][i];
                    }
                }
            }
        }
    }
    out
}

/// `u'(1) = Σ_n ℓ_n'(1) D_n`: the end velocity of the polynomial with
/// increments `d`, times its step.
#[inline(always)]
pub(super) fn end_slope<const N: usize, const S: usize, const R: usize, T: Real>(
    g: &Galerkin<S, R, T>,
    d: &[[T; N]; S],
) -> [T; N] {
    let mut v = [T::zero(); N];
    for (&w, dn) in g.end_d.iter().zip(d) {
        for (x, &y) in v.iter_mut().zip(dn) {
            *x += w * y;
        }
    }
    v
}

/// Adds the interpolation-error correction to the extrapolated increments
/// `out`: `defect = h_last v̂ − u'(1)`, the end velocity's miss times the
/// last step; `rho` as in [`extrapolate`].
#[inline(always)]
pub(super) fn correct<const N: usize, const S: usize, const R: usize, T: Real>(
    g: &Galerkin<S, R, T>,
    out: &mut [[T; N]; S],
    defect: &[T; N],
    rho: Option<T>,
) {
    for m in 0..S {
        let w = match rho {
            None => g.extrapolate_error[m],
            Some(rho) => g.nodal_integral(g.control[m] * rho) / g.nodal(T::one()),
        };
        for i in 0..N {
            out[m][i] += w * defect[i];
        }
    }
}

/// `h v̂ − u'(1)` for the step of size `h` with increments `d` that ended
/// at `(t1, q1, p1)`: `v̂` by one Newton step of the Legendre transform
/// `∂L/∂v(t1, q1, v̂) = p1` from the polynomial's end velocity `u'(1)/h`
/// (exact for a Lagrangian quadratic in `v`, and otherwise within the square
/// of the polynomial's miss). `None` where `∂²L/∂v²` is singular or a value
/// is not finite: the next guess is then the plain extrapolation.
pub(super) fn end_defect<Sys, const N: usize, const S: usize, const R: usize, T: Real>(
    system: &Sys,
    g: &Galerkin<S, R, T>,
    t1: T,
    h: T,
    (q1, p1): (&[T; N], &[T; N]),
    d: &[[T; N]; S],
) -> Option<[T; N]>
where
    Sys: Lagrangian<N> + ?Sized,
{
    let slope = end_slope(g, d);
    let (_, lv, mut vv) = velocity_hessian(system, t1, *q1, slope.map(|x| x / h));
    let mut inv = [[T::zero(); N]; N];
    if !gauss_jordan_into(&mut vv, &mut inv, 0.0) {
        return None;
    }
    let defect = core::array::from_fn(|i| {
        let mut x = T::zero();
        for k in 0..N {
            x += inv[i][k] * (p1[k] - lv[k]);
        }
        x * h
    });
    all_finite(&defect).then_some(defect)
}

/// The increments of a first step of size `h` from `(t0, q0, v0)`, with no
/// step behind it to extrapolate: the Taylor polynomial `q0 + τh v0 +
/// ½(τh)² a0` at the control nodes, `a0` from the Euler–Lagrange equation
/// `∂²L/∂v² a0 = ∂L/∂q + F − ∂²L/∂v∂q v0` (the time derivative of `∂L/∂v`
/// at fixed `(q, v)` is left out: for a time-dependent `L` the guess is
/// then first order). Where `∂²L/∂v²` is singular or a value not finite,
/// the straight line `q0 + τh v0`.
pub(super) fn first_step<Sys, const N: usize, const S: usize, const R: usize, T: Real>(
    system: &Sys,
    g: &Galerkin<S, R, T>,
    (t0, h): (T, T),
    q0: &[T; N],
    v0: &[T; N],
) -> [[T; N]; S]
where
    Sys: Lagrangian<N> + ?Sized,
{
    let p = PointDerivatives::at(system, t0, *q0, *v0);
    let f = generalized_force(system, t0, *q0, *v0);
    let mut vv = p.vv;
    let mut inv = [[T::zero(); N]; N];
    let rhs: [T; N] = core::array::from_fn(|i| {
        let mut x = p.q[i] + f[i];
        for k in 0..N {
            // ∂²L/∂v_i∂q_k = qv[k][i].
            x -= p.qv[k][i] * v0[k];
        }
        x
    });
    let a = if gauss_jordan_into(&mut vv, &mut inv, 0.0) {
        let a: [T; N] = core::array::from_fn(|i| {
            let mut x = T::zero();
            for k in 0..N {
                x += inv[i][k] * rhs[k];
            }
            x
        });
        if all_finite(&a) { a } else { [T::zero(); N] }
    } else {
        [T::zero(); N]
    };
    g.control.map(|tau| {
        let th = tau * h;
        core::array::from_fn(|i| (v0[i] + a[i] * (th * 0.5)) * th)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::galerkin::StageIteration;
    use crate::integrator::Integrator;
    use crate::system::{Lagrangian, Scalar};

    /// The double pendulum of the bench (`m1 = 1, m2 = 1.5, l1 = 1, l2 = 0.7`).
    struct DoublePendulum;

    impl Lagrangian<2> for DoublePendulum {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false; 2];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
            let (m1, m2, l1, l2, g) = (1.0, 1.5, 1.0, 0.7, 9.81);
            let kinetic = v[0] * v[0] * (0.5 * (m1 + m2) * l1 * l1)
                + v[1] * v[1] * (0.5 * m2 * l2 * l2)
                + v[0] * v[1] * (q[0] - q[1]).cos() * (m2 * l1 * l2);
            kinetic + q[0].cos() * ((m1 + m2) * g * l1) + q[1].cos() * (m2 * g * l2)
        }
    }

    /// The bench's electromechanical sensor: forced and dissipative.
    struct Sensor;

    impl Lagrangian<2> for Sensor {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false; 2];
        const HAS_DISSIPATION: bool = true;
        const HAS_FORCE: bool = true;
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
            let (m, k, g, l0, a) = (0.2, 80.0, 9.81, 0.5, 0.2);
            let l1 = (q[0] / a + 1.0).recip() * l0;
            v[0] * v[0] * (0.5 * m) + l1 * v[1] * v[1] * 0.5 - q[0] * q[0] * (0.5 * k) + q[0] * (m * g)
        }
        fn dissipation<D: Scalar>(&self, _q: [D; 2], v: [D; 2]) -> D {
            v[1] * v[1] * 5.0
        }
        fn force<D: Scalar>(&self, _t: D, _q: [D; 2], v: [D; 2]) -> [D; 2] {
            [v[0] * 0.0, v[0] * 0.0 + 12.0]
        }
    }

    /// The stage velocities of the step with increments `d`.
    fn stage_velocities<const N: usize, const S: usize>(
        g: &Galerkin<S, S>,
        h: f64,
        d: &[[f64; N]; S],
    ) -> [[f64; N]; S] {
        core::array::from_fn(|j| g.point(0.0, h, (&[0.0; N], &[0.0; N]), d, j).2)
    }

    fn miss<const N: usize, const S: usize>(g: &Galerkin<S, S>, h: f64, guess: &[[f64; N]; S], d: &[[f64; N]; S]) -> f64 {
        let (a, b) = (stage_velocities(g, h, guess), stage_velocities(g, h, d));
        let scale = b.as_flattened().iter().fold(0.0f64, |m, x| m.max(x.abs()));
        a.as_flattened().iter().zip(b.as_flattened()).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
    }

    /// Median and largest miss of the extrapolation, with the end-velocity
    /// correction, and each with the last step's miss added.
    fn survey<Sys: Lagrangian<N>, const N: usize, const S: usize>(
        system: Sys,
        h: f64,
        steps: usize,
        q0: [f64; N],
        v0: [f64; N],
    ) -> [(f64, f64); 4] {
        let g = Galerkin::<S, S>::gauss().with_iteration(StageIteration::Newton);
        let mut sim = Integrator::new(system, g, h).start(0.0, q0, v0).unwrap();
        sim.step().unwrap();
        let mut misses: [Vec<f64>; 4] = Default::default();
        let mut last_miss = [[[0.0; N]; S]; 2];
        for _ in 1..steps {
            let last = sim.memory.as_ref().unwrap().clone();
            let plain = extrapolate(&g, &last.d, None);
            let (t1, q1, p1) = (sim.state.t, sim.state.q, sim.state.p);
            let defect = end_defect(&sim.system, &g, t1, h, (&q1, &p1), &last.d).unwrap();
            let mut corrected = plain;
            correct(&g, &mut corrected, &defect, None);
            let mut guesses = [plain, corrected, plain, corrected];
            for (k, guess) in guesses[2..].iter_mut().enumerate() {
                for (row, e) in guess.iter_mut().zip(&last_miss[k]) {
                    for (x, y) in row.iter_mut().zip(e) {
                        *x += y;
                    }
                }
            }
            sim.step().unwrap();
            let d = sim.memory.as_ref().unwrap().d;
            for (k, guess) in guesses.iter().enumerate() {
                misses[k].push(miss(&g, h, guess, &d));
            }
            for (k, base) in [plain, corrected].iter().enumerate() {
                last_miss[k] = core::array::from_fn(|m| core::array::from_fn(|i| d[m][i] - base[m][i]));
            }
        }
        misses.map(|mut m| {
            m.sort_by(f64::total_cmp);
            let r = |x: f64| format!("{x:.1e}").parse::<f64>().unwrap();
            (r(m[m.len() / 2]), r(m[m.len() - 1]))
        })
    }

    #[test]
    fn survey_of_the_predictors() {
        let dp = ([1.0, -0.5], [0.0, 0.5]);
        println!("double pendulum s = 4, h = 2/95: {:?}", survey::<_, 2, 4>(DoublePendulum, 2.0 / 95.0, 475, dp.0, dp.1));
        println!("double pendulum s = 7, h = 2/40: {:?}", survey::<_, 2, 7>(DoublePendulum, 2.0 / 40.0, 200, dp.0, dp.1));
        println!("sensor s = 3, h = 2/34: {:?}", survey::<_, 2, 3>(Sensor, 2.0 / 34.0, 34, [0.0; 2], [0.0; 2]));
        println!("sensor s = 5, h = 2/17: {:?}", survey::<_, 2, 5>(Sensor, 2.0 / 17.0, 17, [0.0; 2], [0.0; 2]));
    }
}
