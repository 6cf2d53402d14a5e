//! The method of a run as a value: which discrete Lagrangian, composition or
//! time transformation steps a [`Problem`](super::Problem), chosen at run
//! time and dispatched to the const-generic kernels behind one `match`.
//!
//! A [`Scheme`] says nothing about step sizes: those are the step
//! [`Policy`](super::Policy), a separate value. Whether a scheme, a policy
//! and a system go together is answered in one place,
//! [`supports`](super::supports).

use crate::discrete::AlphaBeta;
use crate::galerkin::NodeFamily;
use crate::integrator::Composition;
use crate::time_transform::{Curvature, TimeFunction};

/// A one-point discrete Lagrangian: the action of a step from one
/// evaluation point (or two, for the trapezoid).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OnePoint {
    /// `h L((q_k + q_{k+1})/2, (q_{k+1} − q_k)/h)`, order 2.
    Midpoint,
    /// The average of `L` at both ends, order 2 (Störmer–Verlet on a
    /// separable system).
    Trapezoid,
    /// `L` at `α q_k + (1 − α) q_{k+1}`; order 2 at `α = ½`, 1 otherwise.
    AlphaBeta(AlphaBeta),
}

/// The quadrature of a Galerkin rule of degree `s`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GalerkinQuadrature {
    /// `s` Gauss–Legendre points: order `2s` (Gauss collocation).
    #[default]
    GaussLegendre,
    /// `s + 1` Gauss–Lobatto points, exact to degree `2s − 1` like the
    /// Gauss rule, with the step's end points among them.
    GaussLobatto,
}

/// A method chosen at run time. Every value either builds a stepper for a
/// [`Problem`](super::Problem) or is refused by
/// [`supports`](super::supports) with
/// [`Error::Unsupported`](crate::Error::Unsupported) naming the combination.
///
/// ```
/// use lagrangian_runtime::problem::{GalerkinQuadrature, OnePoint, Scheme};
/// use lagrangian_runtime::{Composition, Curvature, NodeFamily};
///
/// let methods = [
///     Scheme::MIDPOINT,
///     Scheme::galerkin(3),
///     Scheme::Galerkin { degree: 4, nodes: NodeFamily::Equispaced, quadrature: GalerkinQuadrature::GaussLobatto },
///     Scheme::composition(Composition::YOSHIDA6, OnePoint::Trapezoid),
///     Scheme::MIDPOINT.time_transformed(Curvature::new(1.0).unwrap()),
/// ];
/// assert_eq!(methods.iter().map(Scheme::order).collect::<Vec<_>>(), [2, 6, 8, 6, 2]);
/// assert_eq!(methods[2].name(), "Galerkin s = 4, equispaced nodes, Gauss–Lobatto quadrature");
/// ```
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Scheme {
    /// One step of a one-point rule.
    OnePoint(OnePoint),
    /// The continuous Galerkin rule of degree `s` (`degree` 2 to 8 with
    /// Gauss–Legendre quadrature and 2 to 4 with Gauss–Lobatto on a
    /// compile-time-sized [`Problem`](super::Problem), where the
    /// const-generic [`Galerkin`](crate::Galerkin) has every degree; 1 to 16
    /// on a run-time-sized `Problem<S, Dyn>`).
    Galerkin {
        /// The degree `s` of the step polynomial.
        degree: usize,
        /// Where its control nodes lie.
        nodes: NodeFamily,
        /// Its quadrature.
        quadrature: GalerkinQuadrature,
    },
    /// A symmetric composition `Φ_h = Ψ_{γ_m h} ∘ … ∘ Ψ_{γ_1 h}` of
    /// sub-steps of the symmetric method `base` with the weights of
    /// `weights` (Yoshida 4 or 6, Kahan–Li 8): the trapezoid rule (the
    /// fused compositions of [`Composition`], explicit Störmer–Verlet
    /// sub-steps on a separable system), the midpoint rule, α-β with
    /// `α = ½` or a Galerkin rule. The weights are built for a symmetric
    /// base of order 2; on a symmetric base of order `p` they give order
    /// `max(p, q)`, `q` the weights' own ([`Scheme::order`]). α-β with
    /// `α ≠ ½` is not symmetric, and a composition of compositions, of a
    /// time transformation or of the splitting is not offered:
    /// [`supports`](super::supports) refuses them. Every base composes at
    /// both sizes, through one adapter over the base's own steps.
    ///
    /// ```
    /// use lagrangian_runtime::problem::{Problem, Scheme};
    /// use lagrangian_runtime::{Composition, Lagrangian, Plan, Scalar};
    ///
    /// /// A pendulum of unit length, mass and gravity.
    /// #[derive(Clone)]
    /// struct Pendulum;
    /// impl Lagrangian<1> for Pendulum {
    ///     const AUTONOMOUS: bool = true;
    ///     const CYCLIC: [bool; 1] = [false];
    ///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
    ///         v[0] * v[0] * 0.5 + q[0].cos()
    ///     }
    /// }
    ///
    /// let problem = Problem::new(Pendulum, 0.0, [1.0], [0.0]);
    /// // Midpoint sub-steps with Yoshida's order-6 weights, Galerkin s = 2
    /// // (order 4) sub-steps with the same weights: both order 6.
    /// let midpoint6 = Scheme::MIDPOINT.composed(Composition::YOSHIDA6);
    /// let galerkin6 = Scheme::galerkin(2).composed(Composition::YOSHIDA6);
    /// assert_eq!((midpoint6.order(), galerkin6.order()), (6, 6));
    /// assert_eq!(midpoint6.name(), "order-6 composition of midpoint");
    /// let fine = problem.solve(&Scheme::galerkin(4), 0.01, Plan::until(2.0))?;
    /// for scheme in [midpoint6, galerkin6] {
    ///     let solution = problem.solve(&scheme, 0.1, Plan::until(2.0).save_at(vec![1.25]))?;
    ///     let last = solution.len() - 1;
    ///     assert_eq!(solution.t[last], 2.0);
    ///     assert!((solution.q[last][0] - fine.q[fine.len() - 1][0]).abs() < 1e-7);
    /// }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    Composition {
        /// The weights and their order.
        weights: Composition,
        /// The method of each sub-step.
        base: Box<Scheme>,
    },
    /// The implicit Sundman–Poincaré time transformation around `inner`:
    /// fixed steps in `s` with `dt/ds = g(t, q)` given by the curvature
    /// monitor `density`; the extended system has `N + 1` coordinates.
    TimeTransformed {
        /// The method in `s`.
        inner: Box<Scheme>,
        /// The step density.
        density: Curvature,
    },
    /// The explicit time-transformed splitting (Blanes & Iserles) of a
    /// separable system with a constant mass matrix, with its time function
    /// and the composition of its leapfrog (order 2 without one).
    Splitting {
        /// `f` of the transformed Hamiltonian.
        function: TimeFunction,
        /// The composition of the leapfrog, if any.
        composition: Option<Composition>,
    },
}

/// A one-point rule alone is the scheme of its steps.
impl From<OnePoint> for Scheme {
    fn from(rule: OnePoint) -> Self {
        Self::OnePoint(rule)
    }
}

impl Scheme {
    /// The midpoint rule.
    pub const MIDPOINT: Self = Self::OnePoint(OnePoint::Midpoint);
    /// The trapezoid rule.
    pub const TRAPEZOID: Self = Self::OnePoint(OnePoint::Trapezoid);

    /// The α-β rule with weight `alpha` on `q_k`; `None` for an `alpha`
    /// that is not finite.
    pub fn alpha_beta(alpha: f64) -> Option<Self> {
        AlphaBeta::new(alpha).map(|m| Self::OnePoint(OnePoint::AlphaBeta(m)))
    }

    /// Galerkin of degree `degree` on Gauss–Lobatto nodes with Gauss–Legendre
    /// quadrature (order `2s`).
    pub fn galerkin(degree: usize) -> Self {
        Self::Galerkin { degree, nodes: NodeFamily::GaussLobatto, quadrature: GalerkinQuadrature::GaussLegendre }
    }

    /// A composition of `base` sub-steps with `weights` (a [`OnePoint`]
    /// rule or any other scheme; see [`Scheme::Composition`]).
    pub fn composition(weights: Composition, base: impl Into<Scheme>) -> Self {
        Self::Composition { weights, base: Box::new(base.into()) }
    }

    /// This scheme as the sub-step of a composition with `weights`.
    pub fn composed(self, weights: Composition) -> Self {
        Self::composition(weights, self)
    }

    /// This scheme in `s` under the implicit time transformation with the
    /// curvature monitor.
    pub fn time_transformed(self, density: Curvature) -> Self {
        Self::TimeTransformed { inner: Box::new(self), density }
    }

    /// The explicit time-transformed splitting with `function`, composed
    /// with `composition` if given.
    pub fn splitting(function: TimeFunction, composition: Option<Composition>) -> Self {
        Self::Splitting { function, composition }
    }

    /// The order of the one-step map for a regular Lagrangian.
    pub fn order(&self) -> u32 {
        match self {
            Self::OnePoint(OnePoint::AlphaBeta(m)) if m.alpha() != 0.5 => 1,
            Self::OnePoint(_) => 2,
            Self::Galerkin { degree, .. } => 2 * *degree as u32,
            // A composition raises the order of a symmetric base of order 2
            // to the weights' order and keeps a higher one.
            Self::Composition { weights, base } => weights.order().max(base.order()),
            Self::TimeTransformed { inner, .. } => inner.order(),
            Self::Splitting { composition, .. } => composition.map_or(2, |c| c.order()),
        }
    }

    /// A short name for tables and errors; a Galerkin rule names its nodes
    /// and quadrature where they are not the defaults of [`Scheme::galerkin`].
    pub fn name(&self) -> String {
        match self {
            Self::OnePoint(OnePoint::Midpoint) => "midpoint".to_string(),
            Self::OnePoint(OnePoint::Trapezoid) => "trapezoid".to_string(),
            Self::OnePoint(OnePoint::AlphaBeta(m)) => format!("α-β (α = {})", m.alpha()),
            Self::Galerkin { degree, nodes, quadrature } => {
                // The defaults go unnamed: "Galerkin s = 4" is the rule of `Scheme::galerkin(4)`.
                let nodes = match nodes {
                    NodeFamily::GaussLobatto => "",
                    NodeFamily::Equispaced => ", equispaced nodes",
                };
                let quadrature = match quadrature {
                    GalerkinQuadrature::GaussLegendre => "",
                    GalerkinQuadrature::GaussLobatto => ", Gauss–Lobatto quadrature",
                };
                format!("Galerkin s = {degree}{nodes}{quadrature}")
            }
            Self::Composition { base, .. } => format!("order-{} composition of {}", self.order(), base.name()),
            Self::TimeTransformed { inner, .. } => format!("time-transformed {}", inner.name()),
            Self::Splitting { composition, .. } => {
                format!("explicit time-transformed splitting, order {}", composition.map_or(2, |c| c.order()))
            }
        }
    }
}
