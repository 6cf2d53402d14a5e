//! Derivatives of the step action from hyper-dual evaluations (MATH.md §4).
//!
//! An evaluation of `A` on [`HyperDual64`] with the first infinitesimal seeded
//! on one coordinate `a` of `(t_k, q_k, t_{k+1}, q_{k+1})` and the second on a
//! coordinate `b` yields `A`, `∂A/∂a`, `∂A/∂b` and `∂²A/∂a∂b` at once.
//!
//! Why scalar hyper-duals and `N²` evaluations instead of one evaluation on
//! `HyperDualSVec64<N, N>`: num-dual's vector duals keep their derivative parts
//! in `Option<SMatrix>`, and under cargo's default release profile (16 codegen
//! units, no fat LTO) the generated code around them is not inlined; measured
//! on the double pendulum (2 cores, default `--release`), the mixed block
//! `∂²A/∂q_k∂q_{k+1}` cost 430 ns with nested `DualSVec64<2>`, 165 ns with
//! `DualSVec<Dual64, 2>` and 53 ns with four scalar `HyperDual64` evaluations.
//! Scalar duals are plain structs of four `f64` and stay fast under every
//! profile. Their cost grows like `N²` evaluations of `L`, which is the right
//! trade for the small `N` of mechanical systems.

use nalgebra::{DMatrix, SMatrix};
use num_dual::{Dual64, HyperDual64};

use crate::discrete::DiscreteLagrangian;
use crate::system::{Lagrangian, Scalar};

/// One step between two extended nodes, `x_k = (t0, q0)` and
/// `x_{k+1} = (t0 + h, q0 + dq)`, held as start and increments so that the
/// secant velocity `dq/h` carries no cancellation error (see
/// [`DiscreteLagrangian::action`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment<const N: usize> {
    /// `t_k`.
    pub t0: f64,
    /// `h = t_{k+1} − t_k`.
    pub h: f64,
    /// `q_k`.
    pub q0: [f64; N],
    /// `q_{k+1} − q_k`.
    pub dq: [f64; N],
}

impl<const N: usize> Segment<N> {
    /// The segment from node `(t0, q0)` to node `(t1, q1)`.
    pub fn between(start: (f64, [f64; N]), end: (f64, [f64; N])) -> Self {
        let (t0, q0) = start;
        let (t1, q1) = end;
        Self { t0, h: t1 - t0, q0, dq: core::array::from_fn(|i| q1[i] - q0[i]) }
    }

    /// `t_{k+1} = t0 + h`.
    pub fn t1(&self) -> f64 {
        self.t0 + self.h
    }

    /// `q_{k+1} = q0 + dq`.
    pub fn q1(&self) -> [f64; N] {
        core::array::from_fn(|i| self.q0[i] + self.dq[i])
    }
}

/// One coordinate of a [`Segment`]: the variable a derivative is taken with respect to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Var {
    /// `t_k`.
    T0,
    /// `q_k[i]`.
    Q0(usize),
    /// `t_{k+1}`.
    T1,
    /// `q_{k+1}[i]`.
    Q1(usize),
}

/// The pieces of the one-step map at a segment: the action, its gradients with
/// respect to both nodes' positions and the mixed block `∂²A/∂q_k∂q_{k+1}`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepDerivatives<const N: usize> {
    /// `A(x_k, x_{k+1})`.
    pub action: f64,
    /// `∂A/∂q_k`: added to `p_k` it is the DEL residual.
    pub d_q0: [f64; N],
    /// `∂A/∂q_{k+1}`: the momentum `p_{k+1}`.
    pub d_q1: [f64; N],
    /// `∂²A/∂q_k∂q_{k+1}`, row `i` for `q_k[i]`, column `j` for `q_{k+1}[j]`:
    /// the Jacobian of the DEL residual with respect to the unknown `q_{k+1}`.
    pub d2_q0_q1: SMatrix<f64, N, N>,
}

/// First derivatives of the action with respect to every coordinate of a segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActionGradient<const N: usize> {
    /// `A(x_k, x_{k+1})`.
    pub action: f64,
    /// `∂A/∂t_k`.
    pub d_t0: f64,
    /// `∂A/∂q_k`.
    pub d_q0: [f64; N],
    /// `∂A/∂t_{k+1}`.
    pub d_t1: f64,
    /// `∂A/∂q_{k+1}`.
    pub d_q1: [f64; N],
}

/// A segment as dual numbers `(t0, h, q0, dq)`.
pub(crate) type DualSegment<T, const N: usize> = (T, T, [T; N], [T; N]);

/// Lifts a segment to dual numbers and seeds one infinitesimal on `v` through
/// `set`. Moving `t_k` or `q_k` with the end node fixed also moves the
/// increment by the opposite amount, hence the two entries for `T0` and `Q0`.
#[inline(always)]
pub(crate) fn lift<T: Scalar, const N: usize>(
    seg: &Segment<N>,
    seeds: &[Var],
    set: impl Fn(&mut T, usize, f64),
) -> DualSegment<T, N> {
    let mut t0 = T::from(seg.t0);
    let mut h = T::from(seg.h);
    let mut q0 = seg.q0.map(T::from);
    let mut dq = seg.dq.map(T::from);
    for (k, v) in seeds.iter().enumerate() {
        match *v {
            Var::T0 => {
                set(&mut t0, k, 1.0);
                set(&mut h, k, -1.0);
            }
            Var::T1 => set(&mut h, k, 1.0),
            Var::Q0(i) => {
                set(&mut q0[i], k, 1.0);
                set(&mut dq[i], k, -1.0);
            }
            Var::Q1(i) => set(&mut dq[i], k, 1.0),
        }
    }
    (t0, h, q0, dq)
}

/// `A` on hyper-duals with `ε1` seeded on `a` and `ε2` on `b`.
#[inline(always)]
pub(crate) fn hyper_action<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    a: Var,
    b: Var,
) -> HyperDual64
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let (t0, h, q0, dq) =
        lift(seg, &[a, b], |x: &mut HyperDual64, k, s| if k == 0 { x.eps1 += s } else { x.eps2 += s });
    method.action(system, t0, h, q0, dq)
}

/// `A` on duals with `ε` seeded on `a`.
#[inline(always)]
fn dual_action<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>, a: Var) -> Dual64
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let (t0, h, q0, dq) = lift(seg, &[a], |x: &mut Dual64, _, s| x.eps += s);
    method.action(system, t0, h, q0, dq)
}

/// Residual part, next momentum and Newton Jacobian of the fixed-step map:
/// `N²` hyper-dual evaluations of `A`, nothing else.
#[inline]
pub fn step_derivatives<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> StepDerivatives<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let mut out = StepDerivatives { action: 0.0, d_q0: [0.0; N], d_q1: [0.0; N], d2_q0_q1: SMatrix::zeros() };
    for i in 0..N {
        for j in 0..N {
            let a = hyper_action(system, method, seg, Var::Q0(i), Var::Q1(j));
            out.action = a.re;
            out.d_q0[i] = a.eps1;
            out.d_q1[j] = a.eps2;
            out.d2_q0_q1[(i, j)] = a.eps1eps2;
        }
    }
    out
}

/// The pieces of the extended (variable-step) map: the fixed-step ones plus
/// the time derivatives, all from `(N + 1)²` hyper-dual evaluations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExtendedStepDerivatives<const N: usize> {
    /// `∂A/∂q_k`.
    pub d_q0: [f64; N],
    /// `∂A/∂t_k`: with `−E_k` it is the residual of the energy equation.
    pub d_t0: f64,
    /// `∂²A/∂q_k∂q_{k+1}`.
    pub d2_q0_q1: SMatrix<f64, N, N>,
    /// `∂²A/∂q_k∂t_{k+1}`.
    pub d2_q0_t1: nalgebra::SVector<f64, N>,
    /// `∂²A/∂t_k∂q_{k+1}`.
    pub d2_t0_q1: nalgebra::SVector<f64, N>,
    /// `∂²A/∂t_k∂t_{k+1}`.
    pub d2_t0_t1: f64,
}

/// Residuals and Jacobian of the variable-step map (MATH.md §3).
#[inline]
pub fn extended_step_derivatives<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
) -> ExtendedStepDerivatives<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let mut out = ExtendedStepDerivatives {
        d_q0: [0.0; N],
        d_t0: 0.0,
        d2_q0_q1: SMatrix::zeros(),
        d2_q0_t1: nalgebra::SVector::zeros(),
        d2_t0_q1: nalgebra::SVector::zeros(),
        d2_t0_t1: 0.0,
    };
    for i in 0..=N {
        for j in 0..=N {
            let a = if i < N { Var::Q0(i) } else { Var::T0 };
            let b = if j < N { Var::Q1(j) } else { Var::T1 };
            let v = hyper_action(system, method, seg, a, b);
            match (i < N, j < N) {
                (true, true) => out.d2_q0_q1[(i, j)] = v.eps1eps2,
                (true, false) => out.d2_q0_t1[i] = v.eps1eps2,
                (false, true) => out.d2_t0_q1[j] = v.eps1eps2,
                (false, false) => out.d2_t0_t1 = v.eps1eps2,
            }
            if i < N {
                out.d_q0[i] = v.eps1;
            } else {
                out.d_t0 = v.eps1;
            }
        }
    }
    out
}

/// `(∂A/∂q_{k+1}, ∂A/∂t_{k+1})`: the momentum and minus the energy at the
/// end of a segment (`N + 1` dual evaluations).
#[inline]
pub fn end_gradient<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> ([f64; N], f64)
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    (end_momentum(system, method, seg), dual_action(system, method, seg, Var::T1).eps)
}

/// `∂A/∂q_{k+1}`, the momentum at the end of a segment: `N` dual evaluations.
#[inline]
pub fn end_momentum<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> [f64; N]
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    core::array::from_fn(|j| dual_action(system, method, seg, Var::Q1(j)).eps)
}

/// Every first derivative of `A` on a segment (`N + 1` hyper-dual evaluations).
pub fn action_gradient<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> ActionGradient<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let times = hyper_action(system, method, seg, Var::T0, Var::T1);
    let mut out =
        ActionGradient { action: times.re, d_t0: times.eps1, d_q0: [0.0; N], d_t1: times.eps2, d_q1: [0.0; N] };
    for i in 0..N {
        let a = hyper_action(system, method, seg, Var::Q0(i), Var::Q1(i));
        out.d_q0[i] = a.eps1;
        out.d_q1[i] = a.eps2;
    }
    out
}

/// `∂A/∂t_{k+1}` alone (one dual evaluation); `−∂A/∂t_{k+1}` is the discrete energy `E_{k+1}`.
pub fn end_time_derivative<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> f64
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    dual_action(system, method, seg, Var::T1).eps
}

/// The position blocks of the Hessian of `A`: `(∂²A/∂q_k², ∂²A/∂q_k∂q_{k+1}, ∂²A/∂q_{k+1}²)`.
///
/// Used for the tangent map of a step (symplecticity, MATH.md §8); not needed
/// by the stepper itself.
pub fn position_hessian<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
) -> (SMatrix<f64, N, N>, SMatrix<f64, N, N>, SMatrix<f64, N, N>)
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let block = |a: fn(usize) -> Var, b: fn(usize) -> Var| {
        SMatrix::<f64, N, N>::from_fn(|i, j| hyper_action(system, method, seg, a(i), b(j)).eps1eps2)
    };
    (block(Var::Q0, Var::Q0), block(Var::Q0, Var::Q1), block(Var::Q1, Var::Q1))
}

/// The blocks of the Hessian of `A` in the extended coordinates
/// `x = (t, q)`: `(∂²A/∂x_k², ∂²A/∂x_k∂x_{k+1}, ∂²A/∂x_{k+1}²)`, each
/// `(N+1)×(N+1)` with the time first.
///
/// Used for the tangent map of a variable step (MATH.md §8), a diagnostic:
/// it allocates, unlike the stepper.
pub fn extended_hessian<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>)
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let start = |i: usize| if i == 0 { Var::T0 } else { Var::Q0(i - 1) };
    let end = |i: usize| if i == 0 { Var::T1 } else { Var::Q1(i - 1) };
    let block = |a: &dyn Fn(usize) -> Var, b: &dyn Fn(usize) -> Var| {
        DMatrix::from_fn(N + 1, N + 1, |i, j| hyper_action(system, method, seg, a(i), b(j)).eps1eps2)
    };
    (block(&start, &start), block(&start, &end), block(&end, &end))
}
