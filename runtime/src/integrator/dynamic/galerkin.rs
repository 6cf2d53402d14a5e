//! Galerkin rules of any degree on run-time-sized systems: the
//! [`DynIntegrator`] step that solves the `sN` node equations of the step
//! polynomial on the tape (`tape_step/galerkin.rs`), for the const-generic
//! [`Galerkin`] and for a degree chosen at run time ([`RunTimeGalerkin`],
//! what `Scheme::Galerkin` builds).

use super::{DynIntegrator, DynMethod, Sliced, node_at};
use crate::error::Error;
use crate::galerkin::{Galerkin, NodeFamily, QuadratureKind};
use crate::integrator::method::sealed;
use crate::integrator::tape_step::{self, GalerkinWork, Rule};
use crate::structure::Coupling;
use crate::system::DynLagrangian;

/// A Galerkin rule as a run-time-sized step takes it: degree, control
/// nodes and quadrature as values. A public type in a private module: it
/// is named only inside the crate ([`DynMethod::galerkin`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunTimeGalerkin {
    degree: usize,
    nodes: NodeFamily,
    quadrature: QuadratureKind,
    /// The number of quadrature points.
    points: usize,
}

impl RunTimeGalerkin {
    /// The highest degree offered at a run-time size.
    pub(crate) const MAX_DEGREE: usize = 16;

    /// Degree `degree` on the control nodes `nodes`, with `degree`
    /// Gauss–Legendre points or (`lobatto`) `degree + 1` Gauss–Lobatto
    /// points: order `2s` either way.
    pub(crate) fn new(degree: usize, nodes: NodeFamily, lobatto: bool) -> Self {
        let (quadrature, points) = match lobatto {
            true => (QuadratureKind::GaussLobatto, degree + 1),
            false => (QuadratureKind::GaussLegendre, degree),
        };
        Self { degree, nodes, quadrature, points }
    }

    /// The tables of the rule, or why it is refused.
    pub(crate) fn rule(&self) -> Result<Rule, Error> {
        if !(1..=Self::MAX_DEGREE).contains(&self.degree) {
            return Err(Error::InvalidMethod {
                reason: "the degree s of a Galerkin rule on a run-time-sized system must be between 1 and 16",
            });
        }
        let exact = match self.quadrature {
            QuadratureKind::GaussLegendre => (2 * self.points).checked_sub(1),
            QuadratureKind::GaussLobatto => (2 * self.points).checked_sub(3),
            QuadratureKind::Points { .. } => {
                return Err(Error::InvalidMethod {
                    reason: "a Galerkin rule on a run-time-sized system takes Gauss–Legendre or Gauss–Lobatto quadrature",
                });
            }
        };
        // The kinetic term has degree 2s − 2.
        if exact.is_none_or(|d| d + 2 < 2 * self.degree) || self.points > 4 * Self::MAX_DEGREE {
            return Err(Error::InvalidMethod {
                reason: "the quadrature is too weak for the degree: it must integrate polynomials of degree 2s − 2 exactly",
            });
        }
        Ok(Rule::new(self.degree, self.nodes, self.quadrature == QuadratureKind::GaussLobatto, self.points))
    }
}

impl sealed::Sealed for RunTimeGalerkin {}

impl DynMethod for RunTimeGalerkin {
    fn points(&self) -> Option<[f64; 2]> {
        None
    }

    fn galerkin(&self) -> Option<RunTimeGalerkin> {
        Some(*self)
    }

    const EXPLICIT_FOR_CONSTANT_MASS: bool = false;
}

/// The const-generic rule at a run-time size: the same degree, control
/// nodes and quadrature, its node equations always solved by Newton (its
/// [`StageIteration`](crate::galerkin::StageIteration) is a compile-time-size
/// setting).
impl<const S: usize, const R: usize> DynMethod for Galerkin<S, R> {
    fn points(&self) -> Option<[f64; 2]> {
        None
    }

    fn galerkin(&self) -> Option<RunTimeGalerkin> {
        Some(RunTimeGalerkin { degree: S, nodes: self.family(), quadrature: self.quadrature().kind(), points: R })
    }

    const EXPLICIT_FOR_CONSTANT_MASS: bool = false;
}

/// The work of a Galerkin rule's steps for `n` coordinates with `coupling`.
pub(super) fn work(rule: &RunTimeGalerkin, n: usize, coupling: Coupling) -> Result<Box<GalerkinWork>, Error> {
    let rule = rule.rule()?;
    GalerkinWork::new(n, coupling, rule).map(Box::new).map_err(|_| Error::Unsupported {
        what: "a system this large with this coupling: the Galerkin step's matrices cannot be allocated",
    })
}

impl<S: DynLagrangian, M: DynMethod> DynIntegrator<S, M> {
    /// One Galerkin step of size `h` ending at `t1`; on failure nothing
    /// changes but the failure count.
    pub(super) fn galerkin_step(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        let Some(galerkin) = self.galerkin.as_mut() else {
            return Err(Error::Unsupported {
                what: "a Galerkin step of a one-point rule (internal error: please report)",
            });
        };
        let model = Sliced { system: &self.system, points: self.points };
        let before = self.work.energy.unwrap_or(self.energy);
        let node = node_at(&self.state, (&self.carry, &self.p_carry), self.summation);
        let outcome = galerkin.step(&model, &node, h, t1, &self.v0, &self.newton, &mut self.work);
        let (taken, energy) = match outcome {
            Ok(x) => x,
            Err(failure) => {
                self.stats.failed_steps += 1;
                return Err(Error::from_newton(failure, self.state.clone(), h));
            }
        };
        if S::DISCONTINUOUS {
            tape_step::watch_energy_jump(&mut self.stats, before, energy, t1);
        }
        self.work.energy = Some(energy);
        self.commit(taken, h, t1);
        Ok(())
    }

    /// The last Galerkin step's size, control-node increments `D_1 … D_s`
    /// (coordinate `i`'s at `i·s + m − 1`) and control nodes
    /// `τ_0 = 0 … τ_s`; `None` before the first step or for another method.
    pub(crate) fn galerkin_nodes(&self) -> Option<(f64, &[f64], &[f64])> {
        let galerkin = self.galerkin.as_ref()?;
        let (h, d) = galerkin.last_nodes()?;
        Some((h, d, galerkin.rule().nodes()))
    }
}
