//! Symmetries of the configuration space: one-parameter groups given by their
//! generator `ξ(q)`. A leaf module: the [`Lagrangian`](crate::Lagrangian)
//! trait names the symmetries a system declares, and
//! [`noether`](crate::noether) follows their momentum maps.

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
