//! The linearisation of a step of the implicit time transformation
//! ([`crate::time_transform`]) for the sensitivities and the adjoint.
//!
//! A step of the time-transformed driver is an ordinary fixed step of size
//! `σ` of the extended system `L̃(x, x')`, `x = (q, t)`, in the new time
//! `s`: its linearisation is that of [`StepJacobian`] applied to `L̃`,
//! which implements [`Parametric`] with the parameters of the physical
//! system (they enter `L` and, through the curvature monitor, `g`). The
//! state is the extended phase `(q, t, p, p_t)`, so the node times `t_k`
//! have derivatives of their own.
//!
//! Two more numbers of the run depend on the inputs:
//!
//! - the constant `c` of the `(t' − g)²/(2cg)` term, `1/(|p·v| + |L| + |E|)`
//!   at the initial data (the driver's default): its derivative is carried
//!   as one more column, `∂x_{k+1}/∂c`;
//! - the size `σ'` of the landing step, solved so that `t_{k+1} = t_end`.
//!   A step of size `ασ` of `L̃` is a step of size `σ` of `α L̃(x, x'/α)`
//!   (the discrete action and forces are the same functions of the nodes),
//!   so `σ' ∂Φ/∂σ'` is the derivative in `α` at `α = 1`; the implicit
//!   function theorem on `t_{k+1}(z, σ') = t_end` gives
//!   `dΦ = (Φ_z − Φ_α (∂t_{k+1}/∂z)/(∂t_{k+1}/∂α)) dz`, whose time row
//!   vanishes: the landed node's time is `t_end` whatever the inputs.
//!
//! The matrices are dense and on the heap (`2M × 2M`, `M = N + 1`): the
//! extended sizes are not nameable where the physical `N` is generic.

use nalgebra::{DMatrix, DVector, RowDVector};
use num_dual::{Dual, Dual64, HyperDual};

use super::Parametric;
use super::linearisation::{Piece, Rule, StepJacobian, generalized_force, seeded};
use crate::system::{Lagrangian, Scalar};
use crate::time_transform::{Curvature, TimeTransformed, default_penalty, extended_force, extended_lagrangian, split};

/// `L̃` at parameters `theta` and constant `c`.
fn extended_at<Sys, D, const N: usize, const M: usize, const P: usize>(
    tt: &TimeTransformed<Sys, Curvature, N>,
    theta: &[D; P],
    c: D,
    x: &[D; M],
    w: &[D; M],
) -> D
where
    Sys: Parametric<N, P>,
    D: Scalar,
{
    const { assert!(M == N + 1, "the time-transformed system has N + 1 coordinates (q, t)") };
    let (t, q) = split::<D, N, M>(x);
    let system = tt.system();
    let lifted: [HyperDual<D>; P] = theta.map(HyperDual::from_re);
    let g = tt.density_monitor().of(t, &q, |t, q, v| system.lagrangian_with(&lifted, t, q, v));
    extended_lagrangian(w, g, c, |v| system.lagrangian_with(theta, t, q, v))
}

/// The extended force at parameters `theta`.
fn extended_force_at<Sys, D, const N: usize, const M: usize, const P: usize>(
    tt: &TimeTransformed<Sys, Curvature, N>,
    theta: &[D; P],
    x: &[D; M],
    w: &[D; M],
) -> [D; M]
where
    Sys: Parametric<N, P>,
    D: Scalar,
{
    let (t, q) = split::<D, N, M>(x);
    extended_force(w, |v| generalized_force(tt.system(), theta, t, q, v))
}

/// The transformed system with the curvature monitor (the one a
/// [`Scheme::TimeTransformed`](crate::problem::Scheme::TimeTransformed)
/// steps) carries the parameters of its system: they enter `L` and the
/// monitor `g`, which reads the curvature of `L`. The constant `c` is held
/// at its value.
impl<Sys, const N: usize, const M: usize, const P: usize> Parametric<M, P> for TimeTransformed<Sys, Curvature, N>
where
    Sys: Parametric<N, P>,
{
    const NAMES: [&'static str; P] = Sys::NAMES;

    fn parameters(&self) -> [f64; P] {
        self.system().parameters()
    }

    fn with_parameters(&self, theta: [f64; P]) -> Self {
        let rebuilt = || TimeTransformed::new(self.system().with_parameters(theta), *self.density_monitor());
        // `c` is 0 before the driver sets it: then it stays unset.
        rebuilt().with_penalty(self.penalty()).unwrap_or_else(rebuilt)
    }

    fn lagrangian_with<D: Scalar>(&self, theta: &[D; P], _s: D, x: [D; M], w: [D; M]) -> D {
        extended_at(self, theta, D::from(self.penalty()), &x, &w)
    }

    fn force_with<D: Scalar>(&self, theta: &[D; P], _s: D, x: [D; M], w: [D; M]) -> [D; M] {
        extended_force_at(self, theta, &x, &w)
    }
}

/// The transformed system with the parameters `(c, α)` of the step: the
/// constant `c` and the scale `α` of `α L̃(x, x'/α)` (see the
/// [module](self)); the physical parameters are held.
struct Scaled<'a, Sys, const N: usize, const P: usize>(&'a TimeTransformed<Sys, Curvature, N>);

impl<Sys, const N: usize, const P: usize> Clone for Scaled<'_, Sys, N, P> {
    fn clone(&self) -> Self {
        Self(self.0)
    }
}

impl<Sys: Parametric<N, P>, const N: usize, const M: usize, const P: usize> Lagrangian<M> for Scaled<'_, Sys, N, P> {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; M] = <TimeTransformed<Sys, Curvature, N> as Lagrangian<M>>::CYCLIC;
    const DISCONTINUOUS: bool = Sys::DISCONTINUOUS;
    const HAS_FORCE: bool = Sys::HAS_FORCE || Sys::HAS_DISSIPATION;
    const ENERGY_STEPS: bool = false;

    fn lagrangian<D: Scalar>(&self, s: D, x: [D; M], w: [D; M]) -> D {
        self.0.lagrangian(s, x, w)
    }

    fn force<D: Scalar>(&self, s: D, x: [D; M], w: [D; M]) -> [D; M] {
        self.0.force(s, x, w)
    }
}

impl<Sys: Parametric<N, P>, const N: usize, const M: usize, const P: usize> Parametric<M, 2> for Scaled<'_, Sys, N, P> {
    const NAMES: [&'static str; 2] = ["c", "α"];

    fn parameters(&self) -> [f64; 2] {
        [self.0.penalty(), 1.0]
    }

    /// Not used: the linearisation takes the parameters as arguments.
    fn with_parameters(&self, _theta: [f64; 2]) -> Self {
        self.clone()
    }

    fn lagrangian_with<D: Scalar>(&self, theta: &[D; 2], _s: D, x: [D; M], w: [D; M]) -> D {
        let [c, alpha] = *theta;
        let physical = self.0.system().parameters().map(D::from);
        let w = w.map(|y| y / alpha);
        extended_at(self.0, &physical, c, &x, &w) * alpha
    }

    fn force_with<D: Scalar>(&self, theta: &[D; 2], _s: D, x: [D; M], w: [D; M]) -> [D; M] {
        let alpha = theta[1];
        let physical = self.0.system().parameters().map(D::from);
        let w = w.map(|y| y / alpha);
        extended_force_at(self.0, &physical, &x, &w).map(|f| f * alpha)
    }
}

/// The linearisation of one step in the extended phase `(q, t, p, p_t)`.
#[doc(hidden)]
#[derive(Clone, Debug, PartialEq)]
pub struct Linear {
    /// `∂x_{k+1}/∂x_k`, `2M × 2M`.
    pub x: DMatrix<f64>,
    /// `∂x_{k+1}/∂θ`, `2M × P`.
    pub theta: DMatrix<f64>,
    /// `∂x_{k+1}/∂c`.
    pub c: DVector<f64>,
}

impl Linear {
    /// `Φ_x` and `Φ_θ` of `j` in the extended phase, with `Φ_c = c`.
    pub(super) fn of<const M: usize, const P: usize>(j: &StepJacobian<M, P>, c: DVector<f64>) -> Self {
        let mut theta = DMatrix::<f64>::zeros(2 * M, P);
        theta.view_mut((0, 0), (M, P)).copy_from(&j.dq_dtheta);
        theta.view_mut((M, 0), (M, P)).copy_from(&j.dp_dtheta);
        Self { x: j.state.matrix(), theta, c }
    }

    /// The step whose end time (row `time`) is given, from the step whose
    /// end moves with one more input `a = ∂x_{k+1}/∂α`, `α` chosen so that
    /// the end time is the one given: by the implicit function theorem on
    /// `t_{k+1}(z, α) = t_end`, `dx_{k+1} = (Φ_z − a (∂t_{k+1}/∂z)/a_t) dz`,
    /// whose time row vanishes.
    pub(super) fn pin_time(&mut self, time: usize, a: &DVector<f64>) {
        let at = a[time];
        let project = |m: &mut DMatrix<f64>| {
            let row = m.row(time).into_owned() / at;
            *m -= a * row;
        };
        project(&mut self.x);
        project(&mut self.theta);
        let ct = self.c[time] / at;
        self.c -= a * ct;
    }

    /// `Some` when every entry is finite.
    pub(super) fn finite(self) -> Option<Self> {
        let finite = self.x.iter().chain(self.theta.iter()).chain(self.c.iter()).all(|v| v.is_finite());
        finite.then_some(self)
    }
}

/// The Jacobians `Φ_x`, `Φ_θ`, `Φ_c` of the step of `rule` made of `piece`
/// (`(s_k, σ, x_k, D)`) of the transformed system `tt`; with `landed`, of
/// the landing step whose size was solved for its end time (see the
/// [module](self)). `None` where a Newton block is singular or a
/// derivative is not finite.
pub(crate) fn linearise<Sys, const N: usize, const M: usize, const P: usize>(
    tt: &TimeTransformed<Sys, Curvature, N>,
    rule: &Rule,
    piece: &Piece<M>,
    landed: bool,
) -> Option<Linear>
where
    Sys: Parametric<N, P>,
{
    let theta = Parametric::<M, P>::parameters(tt);
    let j = StepJacobian::<M, P>::of_piece(tt, rule, &theta, piece)?;
    let scaled = Scaled::<Sys, N, P>(tt);
    let k = StepJacobian::<M, 2>::of_piece(&scaled, rule, &[tt.penalty(), 1.0], piece)?;
    let stack = |q: &dyn Fn(usize) -> f64, p: &dyn Fn(usize) -> f64| {
        DVector::from_iterator(2 * M, (0..M).map(q).chain((0..M).map(p)))
    };
    let mut linear = Linear::of(&j, stack(&|i| k.dq_dtheta[(i, 0)], &|i| k.dp_dtheta[(i, 0)]));
    if landed {
        linear.pin_time(N, &stack(&|i| k.dq_dtheta[(i, 1)], &|i| k.dp_dtheta[(i, 1)]));
    }
    linear.finite()
}

impl Linear {
    /// The linearisation of a step in the extended phase `(q, t, p, p_t)`
    /// (`M = N + 1` rows each, the time at row `N`) from its Jacobians in
    /// the state, `θ` and `c`; for a landing step, with `landing` the
    /// derivative of the end point in the step's size (in any scale: the
    /// projection is invariant to it), the size solved so that the end
    /// time is `t_end`, eliminated by [`pin_time`](Self::pin_time). `None`
    /// where an entry is not finite.
    pub(crate) fn of_step(
        x: DMatrix<f64>,
        theta: DMatrix<f64>,
        c: DVector<f64>,
        landing: Option<DVector<f64>>,
    ) -> Option<Self> {
        let mut linear = Self { x, theta, c };
        if let Some(a) = landing {
            linear.pin_time(linear.x.nrows() / 2 - 1, &a);
        }
        linear.finite()
    }
}

/// The derivatives of the first node in `s` with respect to the inputs
/// `(q_0, v_0, θ)`.
#[doc(hidden)]
#[derive(Clone, Debug, PartialEq)]
pub struct Start {
    /// `∂(x_0, p̃_0)/∂(q_0, v_0, θ)`, `2M × (2N + P)`: `x_0 = (q_0, t_0)`,
    /// `p̃_0 = ∂L̃/∂x'` at `x'_0 = (g_0 v_0, g_0)`.
    pub tangent: DMatrix<f64>,
    /// `∂c/∂(q_0, v_0, θ)`.
    pub c: RowDVector<f64>,
}

/// [`Start`] at the initial data `(t0, q0, v0)` of the transformed system
/// `tt`, whose `c` is the driver's default (`None` where a derivative is
/// not finite).
pub(crate) fn start<Sys, const N: usize, const M: usize, const P: usize>(
    tt: &TimeTransformed<Sys, Curvature, N>,
    (t0, q0, v0): (f64, [f64; N], [f64; N]),
) -> Option<Start>
where
    Sys: Parametric<N, P>,
{
    let system = tt.system();
    let theta = system.parameters();
    let k = 2 * N + P;
    let mut tangent = DMatrix::<f64>::zeros(2 * M, k);
    let mut dc = RowDVector::<f64>::zeros(k);
    for col in 0..k {
        let (q, v, th) = seeded(&q0, &v0, &theta, col);
        let t = Dual64::from(t0);
        // c = 1/(|p·v| + |L| + |E|) at the initial data, as the driver sets it.
        let lifted: [Dual<Dual64>; P] = th.map(Dual::from_re);
        let (tl, ql) = (Dual::from_re(t), q.map(Dual::from_re));
        let l = system.lagrangian_with(&th, t, q, v);
        let mut pv = Dual64::from(0.0);
        for i in 0..N {
            let mut vl = v.map(Dual::from_re);
            vl[i].eps = Dual64::from(1.0);
            pv += system.lagrangian_with(&lifted, tl, ql, vl).eps * v[i];
        }
        let c = default_penalty(l, pv - l);
        dc[col] = c.eps;
        // x_0 = (q_0, t_0); p̃_0 = ∂L̃/∂x' at x'_0 = (g_0 v_0, g_0).
        if col < N {
            tangent[(col, col)] = 1.0;
        }
        let hyper: [HyperDual<Dual64>; P] = th.map(HyperDual::from_re);
        let g = tt.density_monitor().of(t, &q, |t, q, v| system.lagrangian_with(&hyper, t, q, v));
        let mut x = [Dual::from_re(Dual64::from(0.0)); M];
        let mut w = x;
        for i in 0..N {
            x[i] = Dual::from_re(q[i]);
            w[i] = Dual::from_re(g * v[i]);
        }
        x[N] = Dual::from_re(t);
        w[N] = Dual::from_re(g);
        for i in 0..M {
            let mut wi = w;
            wi[i].eps = Dual64::from(1.0);
            tangent[(M + i, col)] = extended_at(tt, &lifted, Dual::from_re(c), &x, &wi).eps.eps;
        }
    }
    let finite = tangent.iter().chain(dc.iter()).all(|v| v.is_finite());
    finite.then_some(Start { tangent, c: dc })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::{Problem, Scheme};
    use crate::sensitivity::fixtures::Kepler;
    use crate::sensitivity::{Checkpoints, Loss};
    use crate::solution::Plan;

    /// A loss with a running term in `t` (so that `∂ℓ/∂t` enters).
    struct Fit;
    impl Loss<2, 1> for Fit {
        fn running<D: Scalar>(&self, _k: u64, t: D, q: [D; 2], _p: [D; 2], _theta: &[D; 1]) -> D {
            (q[0] * t.sin() + q[1]) * 1e-2
        }
        fn terminal<D: Scalar>(&self, t: D, q: [D; 2], p: [D; 2], theta: &[D; 1]) -> D {
            q[0] * q[0] + q[1] * p[1] * theta[0] + t
        }
    }

    const E: f64 = 0.5;
    const SIGMA: f64 = 0.05;
    const T_END: f64 = 3.0;

    fn initial(q0: [f64; 2], v0: [f64; 2], mu: f64) -> Problem<Kepler, crate::dim::Dim<2>> {
        Problem::new(Kepler { mu }, 0.0, q0, v0)
    }

    fn base() -> ([f64; 2], [f64; 2], f64) {
        ([1.0 - E, 0.0], [0.0, ((1.0 + E) / (1.0 - E)).sqrt()], 1.0)
    }

    fn scheme() -> Scheme {
        Scheme::MIDPOINT.time_transformed(Curvature::new(1e-3).unwrap())
    }

    fn loss_of(q0: [f64; 2], v0: [f64; 2], mu: f64) -> f64 {
        let sol = initial(q0, v0, mu)
            .solve(&scheme(), SIGMA, Plan::until(T_END).without_velocities())
            .unwrap()
            .into_result()
            .unwrap();
        let n = sol.len() - 1;
        let mut j = 0.0;
        for k in 0..=n {
            j += Fit.running(k as u64, sol.t[k], sol.q.array(k).unwrap(), sol.p.array(k).unwrap(), &[mu]);
        }
        j + Fit.terminal(sol.t[n], sol.q.array(n).unwrap(), sol.p.array(n).unwrap(), &[mu])
    }

    #[test]
    fn transformed_adjoint_agrees_with_forward_and_differences() {
        let (q0, v0, mu) = base();
        let g = initial(q0, v0, mu).gradient(&scheme(), SIGMA, T_END, &Fit, Checkpoints::Budget(7)).unwrap();
        assert_eq!(g.last.t, T_END);
        let adjoint = [g.q0[0], g.q0[1], g.v0[0], g.v0[1], g.theta[0]];
        // Forward: Σ_k ∂ℓ_k/∂(q, p, t) S_k + ∂ℓ_k/∂θ.
        let run = initial(q0, v0, mu)
            .solve_with_sensitivities(&scheme(), SIGMA, Plan::until(T_END).without_velocities())
            .unwrap();
        assert!(run.error.is_none());
        let n = run.solution.len() - 1;
        let mut forward = [0.0; 5];
        for (k, s) in run.jacobians.iter().enumerate() {
            let (t, q, p) = (run.solution.t[k], &run.solution.q[k], &run.solution.p[k]);
            for (col, slot) in forward.iter_mut().enumerate() {
                let mut x = [t, q[0], q[1], p[0], p[1], mu].map(Dual64::from);
                let d = |x: &[Dual64; 6]| {
                    let r = Fit.running(k as u64, x[0], [x[1], x[2]], [x[3], x[4]], &[x[5]]);
                    if k == n { r + Fit.terminal(x[0], [x[1], x[2]], [x[3], x[4]], &[x[5]]) } else { r }
                };
                let mut total = 0.0;
                for (i, row) in [usize::MAX, 0, 1, 2, 3].into_iter().enumerate() {
                    x[i].eps = 1.0;
                    let dl = d(&x).eps;
                    x[i].eps = 0.0;
                    total += dl * if row == usize::MAX { s.time[col] } else { s.get(row, col) };
                }
                if col == 4 {
                    x[5].eps = 1.0;
                    total += d(&x).eps;
                }
                *slot += total;
            }
        }
        let scale = forward.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let vs_forward = adjoint.iter().zip(&forward).fold(0.0f64, |m, (a, b)| m.max((a - b).abs())) / scale;
        let value = loss_of(q0, v0, mu);
        let base = [q0[0], q0[1], v0[0], v0[1], mu];
        let fd: Vec<f64> = (0..5)
            .map(|i| {
                let step = 1e-5 * base[i].abs().max(1.0);
                let at = |s: f64| {
                    let mut x = base;
                    x[i] += s;
                    loss_of([x[0], x[1]], [x[2], x[3]], x[4])
                };
                (at(step) - at(-step)) / (2.0 * step)
            })
            .collect();
        let vs_fd = adjoint.iter().zip(&fd).fold(0.0f64, |m, (a, b)| m.max((a - b).abs())) / scale;
        eprintln!(
            "adjoint {adjoint:?}\nforward {forward:?}\nfd {fd:?}\nvs forward {vs_forward:e}, vs fd {vs_fd:e}, value {} vs {value}",
            g.value
        );
        assert!(vs_forward <= 1e-12, "{vs_forward:e}");
        assert!(vs_fd <= 1e-7, "{vs_fd:e}");
        assert!((g.value - value).abs() <= 1e-13 * value.abs());
    }
}
