//! Derivatives of the step action from hyper-dual evaluations (docs/theory.md §4).
//!
//! An evaluation of `A` on a hyper-dual number with the first infinitesimals
//! seeded on coordinates `a_i` of `(t_k, q_k, t_{k+1}, q_{k+1})` and the second
//! on coordinates `b_j` yields `A`, `∂A/∂a_i`, `∂A/∂b_j` and `∂²A/∂a_i∂b_j` at
//! once. Each Newton iteration of a fixed step is one evaluation on
//! [`HyperDualArray<[f64; N], [f64; N]>`](HyperDualArray) (`ε1` on `q_k`, `ε2`
//! on `q_{k+1}`), of a variable step one evaluation on
//! `HyperDualArray<Timed<f64, N>, Timed<f64, N>>` (the times as an extra slot
//! on each side); the end momentum (and energy) is one evaluation on a
//! first-order [`DualArray`]. Above `HYPER_BLOCKS_ABOVE` (hyper-duals) and
//! `DUAL_BLOCKS_ABOVE` (duals) coordinates the seeds go in blocks of eight,
//! one evaluation per block, so that no number's size grows with `N`.
//!
//! Why these types (see [`crate::hyperdual`]): num-dual's vector duals
//! (`Option<SMatrix>` parts, not `Copy`) are not inlined under cargo's
//! default release profile, and its scalar `HyperDual64` needs `N²`
//! evaluations, one per pair of seeds, repeating every `sin`/`cos` of the
//! user's `L` `N²` times. The array duals are `Copy` structs of `f64` arrays
//! that LLVM unrolls, and their formulas and operation order are num-dual's,
//! so every derivative is bit for bit the scalar one (unit test below): one
//! evaluation per Newton iteration gives what `N²` scalar ones give, at about
//! half the cost of a double-pendulum step (`cargo bench -p lagrangian-bench
//! --bench step`).
//!
//! The scalar evaluations (`hyper_action`, `dual_action`) stay as the
//! reference the array ones are tested against.

use nalgebra::{DMatrix, SMatrix};
use num_dual::{Dual64, HyperDual64};

use crate::discrete::DiscreteLagrangian;
use crate::hyperdual::{DualArray, HyperDualArray, Timed, Vector};
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
    /// `q_k[i]` with the increment held fixed, so that the end node moves
    /// with it: `∂A/∂q_k + ∂A/∂q_{k+1}`.
    Translate(usize),
    /// `t_k` with the step size held fixed: `∂A/∂t_k + ∂A/∂t_{k+1}`.
    Delay,
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

/// A segment as constants of a dual type.
#[inline(always)]
fn constant<T: Scalar, const N: usize>(seg: &Segment<N>) -> DualSegment<T, N> {
    // Loops rather than `array::map`, which moves large elements through memory.
    let (mut q0, mut dq) = ([T::zero(); N], [T::zero(); N]);
    for i in 0..N {
        q0[i] = T::from(seg.q0[i]);
        dq[i] = T::from(seg.dq[i]);
    }
    (T::from(seg.t0), T::from(seg.h), q0, dq)
}

/// Seeds one infinitesimal on `v` through `set(x, ±1)`. Moving `t_k` or `q_k`
/// with the end node fixed also moves the increment by the opposite amount,
/// hence the two entries for `T0` and `Q0`.
#[inline(always)]
fn seed<T, const N: usize>(x: &mut DualSegment<T, N>, v: Var, set: impl Fn(&mut T, f64)) {
    let (t0, h, q0, dq) = x;
    match v {
        Var::T0 => {
            set(t0, 1.0);
            set(h, -1.0);
        }
        Var::T1 => set(h, 1.0),
        Var::Delay => set(t0, 1.0),
        Var::Q0(_) | Var::Q1(_) | Var::Translate(_) => seed_position(q0, dq, v, set),
    }
}

/// Lifts a segment to dual numbers and seeds infinitesimal `k` on `seeds[k]`
/// through `set(x, k, ±1)` (see [`seed`]).
#[inline(always)]
pub(crate) fn lift<T: Scalar, const N: usize>(
    seg: &Segment<N>,
    seeds: &[Var],
    set: impl Fn(&mut T, usize, f64),
) -> DualSegment<T, N> {
    let mut x = constant(seg);
    for (k, v) in seeds.iter().enumerate() {
        seed(&mut x, *v, |y, s| set(y, k, s));
    }
    x
}

/// `A` on a [`HyperDualArray`] with `ε1_i` seeded on `a(i)` and `ε2_j` on
/// `b(j)`: the value, both gradients and the whole mixed block at once.
#[inline(always)]
fn hyper_array_action<S, M, E1, E2, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    a: impl Fn(usize) -> Var,
    b: impl Fn(usize) -> Var,
) -> HyperDualArray<E1, E2>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
    E1: Vector,
    E2: Vector,
{
    let mut x = constant(seg);
    for i in 0..E1::LEN {
        seed(&mut x, a(i), |y: &mut HyperDualArray<E1, E2>, s| *y.eps1.get_mut(i) += s);
    }
    for j in 0..E2::LEN {
        seed(&mut x, b(j), |y: &mut HyperDualArray<E1, E2>, s| *y.eps2.get_mut(j) += s);
    }
    let (t0, h, q0, dq) = x;
    method.action(system, t0, h, q0, dq)
}

/// `A` on a [`HyperDualArray`] with `ε1_i` seeded on `a(i)` and `ε2_j` on
/// `b(j)`, where neither seeds a time: `t_k` and `h` enter as plain numbers
/// ([`DiscreteLagrangian::fixed_step_action`]).
#[inline(always)]
fn hyper_array_position_action<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    a: impl Fn(usize) -> Var,
    b: impl Fn(usize) -> Var,
) -> StepDual<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let (mut q0, mut dq) = constant_positions::<StepDual<N>, N>(seg);
    for i in 0..N {
        seed_position(&mut q0, &mut dq, a(i), |y, s| y.eps1[i] += s);
    }
    for j in 0..N {
        seed_position(&mut q0, &mut dq, b(j), |y, s| y.eps2[j] += s);
    }
    method.fixed_step_action(system, seg.t0, seg.h, q0, dq)
}

/// `A` on a [`DualArray`] with `ε_i` seeded on the position variable
/// `a(i)`, `t_k` and `h` as plain numbers.
#[inline(always)]
fn dual_array_position_action<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    a: impl Fn(usize) -> Var,
) -> DualArray<[f64; N]>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let (mut q0, mut dq) = constant_positions::<DualArray<[f64; N]>, N>(seg);
    for i in 0..N {
        seed_position(&mut q0, &mut dq, a(i), |y, s| y.eps[i] += s);
    }
    method.fixed_step_action(system, seg.t0, seg.h, q0, dq)
}

/// The positions of a segment as constants of a dual type.
#[inline(always)]
fn constant_positions<T: Scalar, const N: usize>(seg: &Segment<N>) -> ([T; N], [T; N]) {
    let (mut q0, mut dq) = ([T::zero(); N], [T::zero(); N]);
    for i in 0..N {
        q0[i] = T::from(seg.q0[i]);
        dq[i] = T::from(seg.dq[i]);
    }
    (q0, dq)
}

/// [`seed`] for a position variable (`Q0`, `Q1` or `Translate`).
#[inline(always)]
fn seed_position<T, const N: usize>(q0: &mut [T; N], dq: &mut [T; N], v: Var, set: impl Fn(&mut T, f64)) {
    match v {
        Var::Q0(i) => {
            set(&mut q0[i], 1.0);
            set(&mut dq[i], -1.0);
        }
        Var::Q1(i) => set(&mut dq[i], 1.0),
        Var::Translate(i) => set(&mut q0[i], 1.0),
        Var::T0 | Var::T1 | Var::Delay => unreachable!("a time variable has no position seed"),
    }
}

/// A segment on [`DualArray`]s with `ε_i` seeded on `a(i)`.
#[inline(always)]
pub(crate) fn lift_dual_array<E: Vector, const N: usize>(
    seg: &Segment<N>,
    a: impl Fn(usize) -> Var,
) -> DualSegment<DualArray<E>, N> {
    let mut x = constant(seg);
    for i in 0..E::LEN {
        seed(&mut x, a(i), |y: &mut DualArray<E>, s| *y.eps.get_mut(i) += s);
    }
    x
}

/// `A` on a [`DualArray`] with `ε_i` seeded on `a(i)`: the value and gradient.
#[inline(always)]
fn dual_array_action<S, M, E, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    a: impl Fn(usize) -> Var,
) -> DualArray<E>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
    E: Vector,
{
    let (t0, h, q0, dq) = lift_dual_array(seg, a);
    method.action(system, t0, h, q0, dq)
}

/// Lanes per evaluation of the blocked derivatives below.
const LANES: usize = 8;

/// Above this many coordinates a hyper-dual evaluation seeded on all of
/// `q_k` and `q_{k+1}` (or the extended nodes) is split into blocks of
/// [`LANES`] × [`LANES`] seeds: each of its numbers carries an `N × N` block
/// (8.7 kB at `N = 32`), and a step holds hundreds of them, so that the one
/// evaluation's frame grows like `N³` (it overflowed a 2 MiB thread at
/// `N = 32`). A block holds `1 + 16 + 64` parts whatever `N`; each entry is
/// computed by the same operations as in the one evaluation, bit for bit,
/// at `⌈N/8⌉²` evaluations instead of one.
pub(crate) const HYPER_BLOCKS_ABOVE: usize = 16;

/// Above this many coordinates a dual evaluation seeded on all of a node is
/// split into blocks of [`LANES`] seeds: its numbers carry `N` parts each
/// (2 kB at `N = 256`), and a step holds a few `N` of them.
pub(crate) const DUAL_BLOCKS_ABOVE: usize = 32;

/// A hyper-dual of [`LANES`] seeds on each side.
type BlockDual = HyperDualArray<[f64; LANES], [f64; LANES]>;

/// `A` on a [`BlockDual`] with `ε1_i` seeded on `a(a0 + i)` for
/// `a0 + i < na` and `ε2_j` on `b(b0 + j)` for `b0 + j < nb`; with
/// `positions` the times enter as plain numbers (every seed a position).
#[allow(clippy::too_many_arguments)]
fn hyper_block<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    positions: bool,
    a: &impl Fn(usize) -> Var,
    (a0, na): (usize, usize),
    b: &impl Fn(usize) -> Var,
    (b0, nb): (usize, usize),
) -> BlockDual
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    if positions {
        let (mut q0, mut dq) = constant_positions::<BlockDual, N>(seg);
        for i in 0..LANES.min(na - a0) {
            seed_position(&mut q0, &mut dq, a(a0 + i), |y, s| y.eps1[i] += s);
        }
        for j in 0..LANES.min(nb - b0) {
            seed_position(&mut q0, &mut dq, b(b0 + j), |y, s| y.eps2[j] += s);
        }
        return method.fixed_step_action(system, seg.t0, seg.h, q0, dq);
    }
    let mut x = constant(seg);
    for i in 0..LANES.min(na - a0) {
        seed(&mut x, a(a0 + i), |y: &mut BlockDual, s| y.eps1[i] += s);
    }
    for j in 0..LANES.min(nb - b0) {
        seed(&mut x, b(b0 + j), |y: &mut BlockDual, s| y.eps2[j] += s);
    }
    let (t0, h, q0, dq) = x;
    method.action(system, t0, h, q0, dq)
}

/// The value, both gradients and the mixed block of `A` with `ε1` on
/// `a(0..na)` and `ε2` on `b(0..nb)`, by [`LANES`] × [`LANES`] blocks:
/// `first(i, ∂A/∂a_i)`, `second(j, ∂A/∂b_j)`, `mixed(i, j, ∂²A/∂a_i∂b_j)`.
#[allow(clippy::too_many_arguments)]
fn hyper_blocks<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    positions: bool,
    (a, na): (impl Fn(usize) -> Var, usize),
    (b, nb): (impl Fn(usize) -> Var, usize),
    mut first: impl FnMut(usize, f64),
    mut second: impl FnMut(usize, f64),
    mut mixed: impl FnMut(usize, usize, f64),
) -> f64
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let mut value = 0.0;
    for a0 in (0..na).step_by(LANES) {
        for b0 in (0..nb).step_by(LANES) {
            let x = hyper_block(system, method, seg, positions, &a, (a0, na), &b, (b0, nb));
            value = x.re;
            for i in 0..LANES.min(na - a0) {
                if b0 == 0 {
                    first(a0 + i, x.eps1[i]);
                }
                for j in 0..LANES.min(nb - b0) {
                    mixed(a0 + i, b0 + j, x.eps1eps2[i][j]);
                }
            }
            if a0 == 0 {
                for j in 0..LANES.min(nb - b0) {
                    second(b0 + j, x.eps2[j]);
                }
            }
        }
    }
    value
}

/// The value and gradient of `A` with `ε` on `a(0..n)`, by blocks of
/// [`LANES`] seeds: `gradient(i, ∂A/∂a_i)`; with `positions` the times
/// enter as plain numbers.
fn dual_blocks<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    positions: bool,
    (a, n): (impl Fn(usize) -> Var, usize),
    mut gradient: impl FnMut(usize, f64),
) -> f64
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    type D = DualArray<[f64; LANES]>;
    let mut value = 0.0;
    for a0 in (0..n).step_by(LANES) {
        let lanes = LANES.min(n - a0);
        let x: D = if positions {
            let (mut q0, mut dq) = constant_positions::<D, N>(seg);
            for i in 0..lanes {
                seed_position(&mut q0, &mut dq, a(a0 + i), |y, s| y.eps[i] += s);
            }
            method.fixed_step_action(system, seg.t0, seg.h, q0, dq)
        } else {
            let mut x = constant(seg);
            for i in 0..lanes {
                seed(&mut x, a(a0 + i), |y: &mut D, s| y.eps[i] += s);
            }
            let (t0, h, q0, dq) = x;
            method.action(system, t0, h, q0, dq)
        };
        value = x.re;
        for i in 0..lanes {
            gradient(a0 + i, x.eps[i]);
        }
    }
    value
}

/// `[∂A/∂a_i]` over the `N` position variables `a(i)`, by blocks (see
/// [`dual_blocks`]), and `A`.
fn position_gradient_by_blocks<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    a: impl Fn(usize) -> Var,
) -> ([f64; N], f64)
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let mut g = [0.0; N];
    let value = dual_blocks(system, method, seg, true, (a, N), |i, x| g[i] = x);
    (g, value)
}

/// Slot `i` of the start node in the extended variables: `q_k[i]`, then `t_k` in slot `N`.
fn start_var<const N: usize>(i: usize) -> Var {
    if i < N { Var::Q0(i) } else { Var::T0 }
}

/// Slot `j` of the end node in the extended variables: `q_{k+1}[j]`, then `t_{k+1}` in slot `N`.
fn end_var<const N: usize>(j: usize) -> Var {
    if j < N { Var::Q1(j) } else { Var::T1 }
}

/// The hyper-dual of the fixed-step map: `ε1` on `q_k`, `ε2` on `q_{k+1}`.
type StepDual<const N: usize> = HyperDualArray<[f64; N], [f64; N]>;

/// The hyper-dual of the extended map: `ε1` on `(q_k, t_k)`, `ε2` on `(q_{k+1}, t_{k+1})`.
type ExtendedDual<const N: usize> = HyperDualArray<Timed<f64, N>, Timed<f64, N>>;

/// `A` on scalar hyper-duals with `ε1` seeded on `a` and `ε2` on `b`: one
/// entry of a mixed block per evaluation. The scalar reference of the array
/// evaluations above (the tests check they agree bit for bit).
#[cfg_attr(not(test), allow(dead_code))]
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
/// one evaluation of `A` on a [`HyperDualArray`] with `ε1` seeded on `q_k`
/// and `ε2` on `q_{k+1}`.
#[inline]
pub fn step_derivatives<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> StepDerivatives<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    if const { N > HYPER_BLOCKS_ABOVE } {
        return step_derivatives_by_blocks(system, method, seg);
    }
    let a = hyper_array_position_action(system, method, seg, Var::Q0, Var::Q1);
    StepDerivatives { action: a.re, d_q0: a.eps1, d_q1: a.eps2, d2_q0_q1: SMatrix::from_fn(|i, j| a.eps1eps2[i][j]) }
}

/// The pieces of the extended (variable-step) map: the fixed-step ones plus
/// the time derivatives, all from one hyper-dual evaluation.
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

/// Residuals and Jacobian of the variable-step map (docs/theory.md §3): one
/// evaluation of `A` on a [`HyperDualArray`] with `ε1` seeded on `(q_k, t_k)`
/// and `ε2` on `(q_{k+1}, t_{k+1})`.
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
    if const { N > HYPER_BLOCKS_ABOVE } {
        return extended_step_derivatives_by_blocks(system, method, seg);
    }
    let a: ExtendedDual<N> = hyper_array_action(system, method, seg, start_var::<N>, end_var::<N>);
    let m = &a.eps1eps2;
    ExtendedStepDerivatives {
        d_q0: a.eps1.q,
        d_t0: a.eps1.t,
        d2_q0_q1: SMatrix::from_fn(|i, j| m.q[i].q[j]),
        d2_q0_t1: nalgebra::SVector::from_fn(|i, _| m.q[i].t),
        d2_t0_q1: nalgebra::SVector::from_fn(|j, _| m.t.q[j]),
        d2_t0_t1: m.t.t,
    }
}

/// [`step_derivatives`] by blocks of seeds (see [`HYPER_BLOCKS_ABOVE`]).
fn step_derivatives_by_blocks<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> StepDerivatives<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let (mut d_q0, mut d_q1, mut d2_q0_q1) = ([0.0; N], [0.0; N], SMatrix::zeros());
    let action = hyper_blocks(
        system,
        method,
        seg,
        true,
        (Var::Q0, N),
        (Var::Q1, N),
        |i, x| d_q0[i] = x,
        |j, x| d_q1[j] = x,
        |i, j, x| d2_q0_q1[(i, j)] = x,
    );
    StepDerivatives { action, d_q0, d_q1, d2_q0_q1 }
}

/// [`extended_step_derivatives`] by blocks of seeds (see [`HYPER_BLOCKS_ABOVE`]).
fn extended_step_derivatives_by_blocks<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
) -> ExtendedStepDerivatives<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let mut d = ExtendedStepDerivatives {
        d_q0: [0.0; N],
        d_t0: 0.0,
        d2_q0_q1: SMatrix::zeros(),
        d2_q0_t1: nalgebra::SVector::zeros(),
        d2_t0_q1: nalgebra::SVector::zeros(),
        d2_t0_t1: 0.0,
    };
    let mut d_t0 = 0.0;
    let mut d_q0 = [0.0; N];
    hyper_blocks(
        system,
        method,
        seg,
        false,
        (start_var::<N>, N + 1),
        (end_var::<N>, N + 1),
        |i, x| if i < N { d_q0[i] = x } else { d_t0 = x },
        |_, _| {},
        |i, j, x| match (i < N, j < N) {
            (true, true) => d.d2_q0_q1[(i, j)] = x,
            (true, false) => d.d2_q0_t1[i] = x,
            (false, true) => d.d2_t0_q1[j] = x,
            (false, false) => d.d2_t0_t1 = x,
        },
    );
    (d.d_q0, d.d_t0) = (d_q0, d_t0);
    d
}

/// `(∂A/∂q_{k+1}, ∂A/∂t_{k+1})`: the momentum and minus the energy at the
/// end of a segment (one [`DualArray`] evaluation).
#[inline]
pub fn end_gradient<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> ([f64; N], f64)
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    if const { N > DUAL_BLOCKS_ABOVE } {
        let (mut q, mut t) = ([0.0; N], 0.0);
        dual_blocks(system, method, seg, false, (end_var::<N>, N + 1), |j, x| if j < N { q[j] = x } else { t = x });
        return (q, t);
    }
    let a: DualArray<Timed<f64, N>> = dual_array_action(system, method, seg, end_var::<N>);
    (a.eps.q, a.eps.t)
}

/// `∂A/∂q_k` at fixed `q_{k+1}`, the DEL's part of the step (one
/// [`DualArray`] evaluation): the residual of the Newton iterations that
/// keep their Jacobian. With it, the action `A` (the real part).
#[inline]
pub(crate) fn start_gradient<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> ([f64; N], f64)
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    if const { N > DUAL_BLOCKS_ABOVE } {
        return position_gradient_by_blocks(system, method, seg, Var::Q0);
    }
    let a = dual_array_position_action(system, method, seg, Var::Q0);
    (a.eps, a.re)
}

/// `∂A/∂q_{k+1}`, the momentum at the end of a segment (one [`DualArray`] evaluation).
#[inline]
pub fn end_momentum<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> [f64; N]
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    if const { N > DUAL_BLOCKS_ABOVE } {
        return position_gradient_by_blocks(system, method, seg, Var::Q1).0;
    }
    dual_array_position_action(system, method, seg, Var::Q1).eps
}

/// `∂A/∂q_k + ∂A/∂q_{k+1}`, the derivative of `A` under a translation of
/// both nodes (one [`DualArray`] evaluation). Added to `p_k` at a solution
/// of the DEL it is `p_{k+1}`: the momentum *change* of the step, which the
/// integrator sums with Kahan's compensation instead of re-rounding `p_{k+1}`.
#[inline]
pub fn momentum_change<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> [f64; N]
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    if const { N > DUAL_BLOCKS_ABOVE } {
        return position_gradient_by_blocks(system, method, seg, Var::Translate).0;
    }
    dual_array_position_action(system, method, seg, Var::Translate).eps
}

/// `∂A/∂t_k + ∂A/∂t_{k+1}`, the derivative of `A` under a shift of both
/// times (one dual evaluation; zero for an autonomous `L`). At a solution of
/// the energy equation, minus it is the energy change `E_{k+1} − E_k`.
pub fn time_shift_derivative<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> f64
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    dual_action(system, method, seg, Var::Delay).eps
}

/// Every first derivative of `A` on a segment (one hyper-dual evaluation,
/// whose mixed block is not used).
pub fn action_gradient<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> ActionGradient<N>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    if const { N > HYPER_BLOCKS_ABOVE } {
        // Two gradients instead of a hyper-dual whose mixed block is unused.
        let mut g = ActionGradient { action: 0.0, d_t0: 0.0, d_q0: [0.0; N], d_t1: 0.0, d_q1: [0.0; N] };
        let (mut d_q0, mut d_t0) = ([0.0; N], 0.0);
        dual_blocks(
            system,
            method,
            seg,
            false,
            (start_var::<N>, N + 1),
            |i, x| {
                if i < N { d_q0[i] = x } else { d_t0 = x }
            },
        );
        let (mut d_q1, mut d_t1) = ([0.0; N], 0.0);
        g.action =
            dual_blocks(
                system,
                method,
                seg,
                false,
                (end_var::<N>, N + 1),
                |j, x| {
                    if j < N { d_q1[j] = x } else { d_t1 = x }
                },
            );
        (g.d_q0, g.d_t0, g.d_q1, g.d_t1) = (d_q0, d_t0, d_q1, d_t1);
        return g;
    }
    let a: ExtendedDual<N> = hyper_array_action(system, method, seg, start_var::<N>, end_var::<N>);
    ActionGradient { action: a.re, d_t0: a.eps1.t, d_q0: a.eps1.q, d_t1: a.eps2.t, d_q1: a.eps2.q }
}

/// `∂A/∂t_{k+1}` alone (one dual evaluation); `−∂A/∂t_{k+1}` is the discrete energy `E_{k+1}`.
///
/// The chain rule through `v̂ = Δq/h` forms `∂v̂/∂h = −v̂/h`, which overflows
/// where `v̂/h` exceeds the range while `v̂²`, the size of the result, does
/// not (`v̂ = 1e146`, `h = 1e-95`). There the derivative is taken in the
/// relative step instead, `h(1 + ε)`: its chain factor is `−v̂`, and
/// `∂A/∂t_{k+1} = (∂A/∂ε)/h`. It is a second evaluation only where the
/// first is not finite, so every other value stays that of the direct form.
pub fn end_time_derivative<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> f64
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let direct = dual_action(system, method, seg, Var::T1).eps;
    if direct.is_finite() || !seg.h.is_finite() || seg.h == 0.0 {
        return direct;
    }
    let (t0, mut h, q0, dq) = lift(seg, &[], |_: &mut Dual64, _, _| {});
    h.eps = seg.h;
    let relative = method.action(system, t0, h, q0, dq).eps / seg.h;
    if relative.is_finite() { relative } else { direct }
}

/// The position blocks of the Hessian of `A`: `(∂²A/∂q_k², ∂²A/∂q_k∂q_{k+1}, ∂²A/∂q_{k+1}²)`,
/// one hyper-dual evaluation each.
///
/// Used for the tangent map of a step (symplecticity, docs/theory.md §8); not needed
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
        if const { N > HYPER_BLOCKS_ABOVE } {
            let mut m = SMatrix::<f64, N, N>::zeros();
            hyper_blocks(system, method, seg, true, (a, N), (b, N), |_, _| {}, |_, _| {}, |i, j, x| m[(i, j)] = x);
            return m;
        }
        let x = hyper_array_position_action(system, method, seg, a, b);
        SMatrix::<f64, N, N>::from_fn(|i, j| x.eps1eps2[i][j])
    };
    (block(Var::Q0, Var::Q0), block(Var::Q0, Var::Q1), block(Var::Q1, Var::Q1))
}

/// The blocks of the Hessian of `A` in the extended coordinates
/// `x = (t, q)`: `(∂²A/∂x_k², ∂²A/∂x_k∂x_{k+1}, ∂²A/∂x_{k+1}²)`, each
/// `(N+1)×(N+1)` with the time first.
///
/// Used for the tangent map of a variable step (docs/theory.md §8), a diagnostic:
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
    // Row or column `r` of the blocks (time first) is slot `slot(r)` of the duals (time last).
    let slot = |r: usize| if r == 0 { N } else { r - 1 };
    let block = |a: fn(usize) -> Var, b: fn(usize) -> Var| {
        if const { N > HYPER_BLOCKS_ABOVE } {
            let mut m = DMatrix::zeros(N + 1, N + 1);
            // Slot `s` of the duals is row or column `(s + 1) mod (N + 1)`.
            let row = |s: usize| (s + 1) % (N + 1);
            hyper_blocks(
                system,
                method,
                seg,
                false,
                (a, N + 1),
                (b, N + 1),
                |_, _| {},
                |_, _| {},
                |i, j, x| {
                    m[(row(i), row(j))] = x;
                },
            );
            return m;
        }
        let x: ExtendedDual<N> = hyper_array_action(system, method, seg, a, b);
        DMatrix::from_fn(N + 1, N + 1, |i, j| x.mixed(slot(i), slot(j)))
    };
    (block(start_var::<N>, start_var::<N>), block(start_var::<N>, end_var::<N>), block(end_var::<N>, end_var::<N>))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discrete::{AlphaBeta, Midpoint, Trapezoid};

    /// A time-dependent, non-separable system with two degrees of freedom.
    struct Coupled;

    impl Lagrangian<2> for Coupled {
        const AUTONOMOUS: bool = false;
        const CYCLIC: [bool; 2] = [false, false];
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 2], v: [D; 2]) -> D {
            let kinetic =
                (v[0] * v[0] + (q[1] * q[1] * 0.3 + 1.0) * v[1] * v[1]) * 0.5 + v[0] * v[1] * (q[0] - q[1]).cos() * 0.4;
            kinetic + t.sin() * q[0] - (q[1] * 0.2).exp() + q[0].cos() * 2.0 / (q[1] * q[1] + 1.5).sqrt()
        }
    }

    const SEG: Segment<2> = Segment { t0: 0.7, h: 0.03, q0: [1.1, -0.4], dq: [0.021, 0.013] };

    /// The array evaluations against one scalar hyper-dual (or dual)
    /// evaluation per entry: equal bit for bit.
    fn agree<M: DiscreteLagrangian>(method: &M) {
        let (s, seg) = (&Coupled, &SEG);
        let scalar = |a: Var, b: Var| hyper_action(s, method, seg, a, b);

        let d = step_derivatives(s, method, seg);
        for i in 0..2 {
            for j in 0..2 {
                let x = scalar(Var::Q0(i), Var::Q1(j));
                assert_eq!((d.action, d.d_q0[i], d.d_q1[j], d.d2_q0_q1[(i, j)]), (x.re, x.eps1, x.eps2, x.eps1eps2));
            }
        }

        let e = extended_step_derivatives(s, method, seg);
        for i in 0..=2 {
            for j in 0..=2 {
                let x = scalar(start_var::<2>(i), end_var::<2>(j));
                let (d1, d2) = match (i < 2, j < 2) {
                    (true, true) => (e.d_q0[i], e.d2_q0_q1[(i, j)]),
                    (true, false) => (e.d_q0[i], e.d2_q0_t1[i]),
                    (false, true) => (e.d_t0, e.d2_t0_q1[j]),
                    (false, false) => (e.d_t0, e.d2_t0_t1),
                };
                assert_eq!((d1, d2), (x.eps1, x.eps1eps2), "({i}, {j})");
            }
        }

        let (p, d_t1) = end_gradient(s, method, seg);
        assert_eq!(p, end_momentum(s, method, seg));
        assert_eq!(p, [0, 1].map(|j| dual_action(s, method, seg, Var::Q1(j)).eps));
        assert_eq!(d_t1, dual_action(s, method, seg, Var::T1).eps);
        assert_eq!(d_t1, end_time_derivative(s, method, seg));

        let g = action_gradient(s, method, seg);
        let times = scalar(Var::T0, Var::T1);
        assert_eq!((g.action, g.d_t0, g.d_t1), (times.re, times.eps1, times.eps2));
        for i in 0..2 {
            let x = scalar(Var::Q0(i), Var::Q1(i));
            assert_eq!((g.d_q0[i], g.d_q1[i]), (x.eps1, x.eps2));
        }

        let (h00, h01, h11) = position_hessian(s, method, seg);
        let (x00, x01, x11) = extended_hessian(s, method, seg);
        let time_first = |i: usize, q: fn(usize) -> Var, t: Var| if i == 0 { t } else { q(i - 1) };
        for i in 0..2 {
            for j in 0..2 {
                assert_eq!(h00[(i, j)], scalar(Var::Q0(i), Var::Q0(j)).eps1eps2);
                assert_eq!(h01[(i, j)], scalar(Var::Q0(i), Var::Q1(j)).eps1eps2);
                assert_eq!(h11[(i, j)], scalar(Var::Q1(i), Var::Q1(j)).eps1eps2);
            }
        }
        for i in 0..3 {
            for j in 0..3 {
                let (s0, s1) = (|i| time_first(i, Var::Q0, Var::T0), |i| time_first(i, Var::Q1, Var::T1));
                assert_eq!(x00[(i, j)], scalar(s0(i), s0(j)).eps1eps2);
                assert_eq!(x01[(i, j)], scalar(s0(i), s1(j)).eps1eps2);
                assert_eq!(x11[(i, j)], scalar(s1(i), s1(j)).eps1eps2);
            }
        }
    }

    #[test]
    fn array_evaluations_equal_scalar_ones_bit_for_bit() {
        agree(&Midpoint);
        agree(&Trapezoid);
        agree(&AlphaBeta::new(0.3).unwrap());
    }

    /// A time-dependent chain of 11 coupled rotors: two full blocks of
    /// seeds and a partial one (12 extended slots: one full, one partial).
    struct Rotors;

    impl Lagrangian<11> for Rotors {
        const AUTONOMOUS: bool = false;
        const CYCLIC: [bool; 11] = [false; 11];
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 11], v: [D; 11]) -> D {
            let mut l = D::zero();
            for i in 0..11 {
                l += v[i] * v[i] * (0.5 + 0.1 * i as f64) + q[i].cos() * (t * 0.3).sin();
                if i + 1 < 11 {
                    l += v[i] * v[i + 1] * (q[i] - q[i + 1]).cos() * 0.2;
                }
            }
            l
        }
    }

    /// The blocked evaluations against the one evaluation of all seeds:
    /// equal bit for bit.
    fn blocks_agree<M: DiscreteLagrangian>(method: &M) {
        let seg = Segment {
            t0: 0.4,
            h: 0.05,
            q0: core::array::from_fn(|i| 0.3 * i as f64 - 1.1),
            dq: core::array::from_fn(|i| 0.01 * (0.7 * i as f64).sin()),
        };
        let s = &Rotors;
        assert_eq!(step_derivatives_by_blocks(s, method, &seg), step_derivatives(s, method, &seg));
        assert_eq!(extended_step_derivatives_by_blocks(s, method, &seg), extended_step_derivatives(s, method, &seg));
        let (start, value) = position_gradient_by_blocks(s, method, &seg, Var::Q0);
        assert_eq!((start, value), start_gradient(s, method, &seg));
        assert_eq!(position_gradient_by_blocks(s, method, &seg, Var::Q1).0, end_momentum(s, method, &seg));
        assert_eq!(position_gradient_by_blocks(s, method, &seg, Var::Translate).0, momentum_change(s, method, &seg));
        let (mut q, mut t) = ([0.0; 11], 0.0);
        dual_blocks(s, method, &seg, false, (end_var::<11>, 12), |j, x| if j < 11 { q[j] = x } else { t = x });
        assert_eq!((q, t), end_gradient(s, method, &seg));
    }

    #[test]
    fn blocked_evaluations_equal_the_one_evaluation_bit_for_bit() {
        blocks_agree(&Midpoint);
        blocks_agree(&Trapezoid);
        blocks_agree(&AlphaBeta::new(0.3).unwrap());
    }
}
