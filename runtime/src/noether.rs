//! Symmetries and discrete momentum maps: the discrete Noether theorem with
//! forcing (MATH.md §7; paper 002 eqs. (15)–(17); paper 003 §3.3).
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

/// The generator `ξ(q)` of a one-parameter group acting on the configuration space.
///
/// Implemented by [`Symmetry`] and by every closure `Fn(&[f64; N]) -> [f64; N]`.
pub trait Generator<const N: usize> {
    /// `ξ(q)`, the velocity of the group action at `q`.
    fn generator(&self, q: &[f64; N]) -> [f64; N];
}

impl<F: Fn(&[f64; N]) -> [f64; N], const N: usize> Generator<N> for F {
    fn generator(&self, q: &[f64; N]) -> [f64; N] {
        self(q)
    }
}

/// A translation of one coordinate, a rotation in a coordinate plane or a
/// group given by its generator function; build it with the constructors
/// (the first two check their indices).
///
/// ```
/// use lagrangian_runtime::{Generator, Symmetry};
///
/// let rotation = Symmetry::<2>::rotation(0, 1).unwrap();
/// assert_eq!(rotation.generator(&[3.0, 4.0]), [-4.0, 3.0]);
/// assert!(Symmetry::<2>::translation(2).is_none());
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Symmetry<const N: usize> {
    kind: Kind<N>,
}

#[derive(Clone, Copy, Debug)]
enum Kind<const N: usize> {
    Translation(usize),
    Rotation(usize, usize),
    Generator(fn(&[f64; N]) -> [f64; N]),
}

impl<const N: usize> PartialEq for Kind<N> {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Translation(a), Self::Translation(b)) => a == b,
            (Self::Rotation(a, b), Self::Rotation(c, d)) => (a, b) == (c, d),
            (Self::Generator(f), Self::Generator(g)) => core::ptr::fn_addr_eq(*f, *g),
            _ => false,
        }
    }
}

impl<const N: usize> Eq for Kind<N> {}

impl<const N: usize> Symmetry<N> {
    /// Translation of coordinate `i`, `ξ = e_i`; its momentum map is `p_i`.
    /// `None` if `i ≥ N`.
    pub const fn translation(i: usize) -> Option<Self> {
        if i < N { Some(Self { kind: Kind::Translation(i) }) } else { None }
    }

    /// Rotation in the `(i, j)` plane, from `q_i` towards `q_j`:
    /// `ξ_i = −q_j`, `ξ_j = q_i`, zero elsewhere. Its momentum map is the
    /// angular momentum `q_i p_j − q_j p_i`. `None` if an index is out of
    /// range or `i = j`.
    pub const fn rotation(i: usize, j: usize) -> Option<Self> {
        if i < N && j < N && i != j { Some(Self { kind: Kind::Rotation(i, j) }) } else { None }
    }

    /// A group given by its generator `ξ(q)`, as a function (a closure that
    /// captures nothing converts to one). For a generator that needs data,
    /// pass a capturing closure as a [`Generator`] directly instead.
    pub const fn generator(xi: fn(&[f64; N]) -> [f64; N]) -> Self {
        Self { kind: Kind::Generator(xi) }
    }

    /// The symmetries declared with `#[lagrangian(symmetry = ...)]`
    /// ([`Lagrangian::SYMMETRIES`]), in the order written.
    pub fn declared<S: Lagrangian<N> + ?Sized>() -> impl Iterator<Item = Self> {
        S::SYMMETRIES.iter().copied()
    }

    /// The translations of the coordinates that `#[lagrangian]` proved cyclic
    /// (`S::CYCLIC`), in increasing order.
    pub fn cyclic<S: Lagrangian<N> + ?Sized>() -> impl Iterator<Item = Self> {
        (0..N).filter(|&i| S::CYCLIC[i]).map(|i| Self { kind: Kind::Translation(i) })
    }
}

impl<const N: usize> Generator<N> for Symmetry<N> {
    fn generator(&self, q: &[f64; N]) -> [f64; N] {
        let mut xi = [0.0; N];
        match self.kind {
            Kind::Translation(i) => xi[i] = 1.0,
            Kind::Rotation(i, j) => {
                xi[i] = -q[j];
                xi[j] = q[i];
            }
            Kind::Generator(f) => xi = f(q),
        }
        xi
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
