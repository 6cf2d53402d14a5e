//! Parameters of a system: the numbers of the model whose derivatives the
//! sensitivities and the adjoint carry.

use crate::system::{Lagrangian, Scalar};

/// A system whose Lagrangian, forces and dissipation depend on `P` named
/// parameters `θ` (masses, lengths, gravity, damping), evaluated on any
/// [`Scalar`] for `θ` too, so that the runtime can seed dual numbers on them.
///
/// `#[lagrangian(parameters(m, l, g))]` implements it: the parameters are
/// `f64` fields of the system, read in the bodies as `self.m`; the generated
/// `*_with` methods are the bodies with every `self.m` replaced by `theta[0]`
/// (in the order of the list). An array field `parameters(m, u: [f64; K])`
/// contributes its `K` entries in order, named `u[0]`, `u[1]`, …. At
/// `theta = self.parameters()` they are the [`Lagrangian`] methods. A
/// parametric system is `Clone`, as a [`Problem`](crate::Problem)'s system
/// is.
pub trait Parametric<const N: usize, const P: usize>: Lagrangian<N> + Clone {
    /// The parameters' names, in order: the field names, `u[i]` for the
    /// entries of an array field.
    const NAMES: [&'static str; P];

    /// The parameters' current values.
    fn parameters(&self) -> [f64; P];

    /// A copy of the system with the parameters set to `theta`.
    fn with_parameters(&self, theta: [f64; P]) -> Self;

    /// `L(t, q, v)` at parameters `theta`.
    fn lagrangian_with<D: Scalar>(&self, theta: &[D; P], t: D, q: [D; N], v: [D; N]) -> D;

    /// The Rayleigh dissipation function `R(q, v)` at parameters `theta`.
    fn dissipation_with<D: Scalar>(&self, theta: &[D; P], q: [D; N], v: [D; N]) -> D {
        let _ = (theta, q, v);
        D::zero()
    }

    /// The applied forces `Q(t, q, v)` at parameters `theta`.
    fn force_with<D: Scalar>(&self, theta: &[D; P], t: D, q: [D; N], v: [D; N]) -> [D; N] {
        let _ = (theta, t, q, v);
        [D::zero(); N]
    }
}
