//! Symmetries and discrete momentum maps: the discrete Noether theorem with
//! forcing (docs/theory.md §7; Fu, Dai & Tang eqs. (15)–(17); de León & Martín de Diego §3.3).
//!
//! A one-parameter group acting on the configuration space, `q ↦ q + ε ξ(q)`
//! to first order, is described by its generator `ξ`. If the step action is
//! invariant, `∂A/∂q_k·ξ(q_k) + ∂A/∂q_{k+1}·ξ(q_{k+1}) = 0`, then the discrete
//! momentum map `J_k = p_k·ξ(q_k)` obeys
//!
//! ```text
//! J_{k+1} − J_k = F_k^−·ξ(q_k) + F_k^+·ξ(q_{k+1})        (the forcing impulse)
//! ```
//!
//! along the forced discrete flow, exactly up to round-off and the Newton
//! tolerance: take the forced DEL `p_k = −∂A/∂q_k − F_k^−` and
//! `p_{k+1} = ∂A/∂q_{k+1} + F_k^+`, dot them with `ξ` and use the invariance.
//! Without forces `J_k` is conserved.
//!
//! When the action is not invariant, the same computation gives
//! `J_{k+1} − J_k = impulse + defect` with the [`symmetry_defect`]
//! `∂A/∂q_k·ξ(q_k) + ∂A/∂q_{k+1}·ξ(q_{k+1})`, which is how a broken symmetry
//! (a spring along a translation, say) shows up.
//!
//! Sources of symmetries: a coordinate the macro proves cyclic
//! ([`Lagrangian::CYCLIC`], see [`Symmetry::cyclic`]) is a translation
//! symmetry of every discrete Lagrangian of the runtime; translations of
//! several coordinates together, rotations and other groups are declared by
//! the user, in code ([`Symmetry::translation`], [`Symmetry::rotation`],
//! [`Symmetry::generator`], or any closure `Fn(&[f64; N]) -> [f64; N]` as a
//! [`Generator`]) or on the system with
//! `#[lagrangian(symmetry = rotation(0, 1), symmetry = generator(|q| ...))]`
//! ([`Lagrangian::SYMMETRIES`], [`Symmetry::declared`]). Declaring a symmetry
//! does not prove it: [`symmetry_defect`] measures it on a step. Midpoint, trapezoid
//! and α-β evaluate `L` at affine combinations of `q_k` and `q_{k+1}` with the
//! secant velocity, so every symmetry of `L` that acts linearly on `q`
//! (translations, rotations) is a symmetry of their actions too.

use crate::derivatives::{self, Segment};
use crate::discrete::DiscreteLagrangian;
use crate::forcing;
use crate::system::Lagrangian;

pub use crate::symmetry::{Generator, Symmetry};

/// The symmetries a system names through its [`Lagrangian`] implementation.
impl<const N: usize> Symmetry<N> {
    /// The symmetries declared with `#[lagrangian(symmetry = ...)]`
    /// ([`Lagrangian::SYMMETRIES`]), in the order written.
    pub fn declared<S: Lagrangian<N> + ?Sized>() -> impl Iterator<Item = Self> {
        S::SYMMETRIES.iter().copied()
    }

    /// The translations of the coordinates that `#[lagrangian]` proved cyclic
    /// (`S::CYCLIC`), in increasing order.
    pub fn cyclic<S: Lagrangian<N> + ?Sized>() -> impl Iterator<Item = Self> {
        (0..N).filter(|&i| S::CYCLIC[i]).filter_map(Self::translation)
    }
}

/// The momentum map `J = p·ξ(q)`.
pub fn momentum_map<const N: usize>(symmetry: &(impl Generator<N> + ?Sized), q: &[f64; N], p: &[f64; N]) -> f64 {
    dot(p, &symmetry.generator(q))
}

/// The forcing impulse of a step, `F_k^−·ξ(q_k) + F_k^+·ξ(q_{k+1})`: what
/// `J_{k+1} − J_k` equals along the forced discrete flow (zero without forces).
pub fn forcing_impulse<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    symmetry: &(impl Generator<N> + ?Sized),
) -> f64
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    if !forcing::is_forced::<S, N>() {
        return 0.0;
    }
    let f = forcing::discrete_forces(system, method, seg);
    dot(&f.minus, &symmetry.generator(&seg.q0)) + dot(&f.plus, &symmetry.generator(&seg.q1()))
}

/// How far the step action is from invariant under the symmetry on a
/// segment: `∂A/∂q_k·ξ(q_k) + ∂A/∂q_{k+1}·ξ(q_{k+1})`, zero (to round-off) for
/// a true symmetry. Along the flow, `J_{k+1} − J_k` is the forcing impulse plus
/// this defect.
pub fn symmetry_defect<S, M, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
    symmetry: &(impl Generator<N> + ?Sized),
) -> f64
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let g = derivatives::action_gradient(system, method, seg);
    dot(&g.d_q0, &symmetry.generator(&seg.q0)) + dot(&g.d_q1, &symmetry.generator(&seg.q1()))
}

fn dot<const N: usize>(a: &[f64; N], b: &[f64; N]) -> f64 {
    (0..N).map(|i| a[i] * b[i]).sum()
}
