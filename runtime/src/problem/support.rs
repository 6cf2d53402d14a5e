//! The one place that says whether a combination of method, step policy,
//! system and workflow is defined, and the refusal that names it.
//!
//! `Problem::stepper` and `Problem::solve` (at either size) and the
//! capability page ask [`supports`] before they build anything, so a combination that
//! is not defined is an [`Error::Unsupported`](crate::Error::Unsupported)
//! at construction, whatever the size of the system, with the text returned here. What only a driver can judge
//! from the system's values (a mass matrix that is not constant for the
//! splitting, a singular Legendre transform) it still refuses at `start`,
//! also typed.

use super::scheme::{GalerkinQuadrature, OnePoint, Scheme};

use crate::integrator::StepBounds;

/// The largest number of degrees of freedom of a compile-time-sized
/// [`Problem`](super::Problem): the implicit time transformation extends a
/// system to `N + 1` coordinates, and stable Rust names `N + 1` only for
/// sizes listed in a table ([`Extended`](super::Extended)).
pub const MAX_PROBLEM_N: usize = crate::dim::MAX_SIZE;

/// Why a compile-time-sized [`Problem`](super::Problem) refuses a Galerkin
/// degree: each degree offered there is a const-generic kernel compiled for
/// every system the crate steps, so `Scheme` offers the degrees the report
/// calibrates (the auto solve runs `s = 2 … 8` with Gauss–Legendre
/// quadrature), and Gauss–Lobatto quadrature to `s = 4`.
pub(crate) const CONST_GALERKIN_DEGREES: &str = "a Galerkin degree through `Scheme` on a compile-time-sized system other than 2 to 8 with Gauss–Legendre quadrature or 2 to 4 with Gauss–Lobatto quadrature (and 2 to 4 in `s` under a time transformation): the const-generic `Galerkin::<S, R>` has every degree, and a run-time-sized `Problem` 1 to 16";

/// The highest Galerkin degree on a run-time-sized system.
const MAX_RUN_TIME_GALERKIN_DEGREE: usize = crate::integrator::RunTimeGalerkin::MAX_DEGREE;

/// How the step sizes are chosen: a value apart from the [`Scheme`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Policy {
    /// Every step has size `h` (for the time-transformed schemes: the step
    /// `σ` in the fictive time `s`).
    Fixed {
        /// The step.
        h: f64,
    },
    /// Energy-preserving variable steps within `bounds` from the first
    /// guess `h`, for a system without forces: `E_{k+1} = E_k`.
    EnergyPreserving {
        /// The first guess.
        h: f64,
        /// The admissible steps.
        bounds: StepBounds,
    },
    /// Energy-balance variable steps for a forced system:
    /// `E_{k+1} − E_k = W_k`, the discrete work of the forces.
    EnergyBalance {
        /// The first guess.
        h: f64,
        /// The admissible steps.
        bounds: StepBounds,
    },
}

impl Policy {
    /// Fixed steps of size `h`.
    pub fn fixed(h: f64) -> Self {
        Self::Fixed { h }
    }

    /// Energy-preserving steps from `h` within [`StepBounds::around`]`(h)`.
    pub fn energy_preserving(h: f64) -> Self {
        Self::EnergyPreserving { h, bounds: StepBounds::around(h) }
    }

    /// Energy-balance steps from `h` within [`StepBounds::around`]`(h)`.
    pub fn energy_balance(h: f64) -> Self {
        Self::EnergyBalance { h, bounds: StepBounds::around(h) }
    }

    /// The (first) step size.
    pub fn step(&self) -> f64 {
        match *self {
            Self::Fixed { h } | Self::EnergyPreserving { h, .. } | Self::EnergyBalance { h, .. } => h,
        }
    }

    /// The bounds of variable steps; `None` for fixed steps.
    pub fn bounds(&self) -> Option<StepBounds> {
        match *self {
            Self::Fixed { .. } => None,
            Self::EnergyPreserving { bounds, .. } | Self::EnergyBalance { bounds, .. } => Some(bounds),
        }
    }
}

/// A step size alone means fixed steps.
impl From<f64> for Policy {
    fn from(h: f64) -> Self {
        Self::Fixed { h }
    }
}

/// Whether the number of coordinates is a type parameter or a run-time value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Size {
    /// `N` known at compile time ([`Problem`](super::Problem)).
    Const(usize),
    /// Known at run time (`Problem<S, Dyn>`).
    Dynamic,
}

/// What is asked of the stepper.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Capability {
    /// Steps, `run` and `run_until` landing exactly on targets.
    Step,
    /// `solve(Plan)` → [`Solution`](crate::Solution): thinning, save times by
    /// dense output, events, and the CSV and JSON files of the solution.
    Solve,
    /// Derivatives of the trajectory with respect to the parameters and the
    /// initial data (fixed steps of the one-point rules, the Galerkin rules,
    /// the compositions of trapezoid sub-steps, the implicit time transformation and the explicit
    /// time-transformed splitting, and energy-preserving steps of the
    /// one-point and Galerkin rules): forward sensitivities
    /// ([`Problem::solve_with_sensitivities`](super::Problem::solve_with_sensitivities))
    /// and the discrete adjoint ([`Problem::gradient`](super::Problem::gradient)).
    Sensitivities,
}

/// One combination of method, policy, system and workflow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Combination<'a> {
    /// The method.
    pub scheme: &'a Scheme,
    /// The step policy.
    pub policy: Policy,
    /// The system's size.
    pub size: Size,
    /// Whether the system has `force` or `dissipation`.
    pub forced: bool,
    /// The number of holonomic constraints of the system.
    pub constraints: usize,
    /// What is asked.
    pub capability: Capability,
}

/// `Ok` when the combination is defined; otherwise the refusal naming it,
/// the text of [`Error::Unsupported`](crate::Error::Unsupported).
///
/// ```
/// use lagrangian_runtime::problem::{Capability, Combination, Policy, Scheme, Size, supports};
///
/// let galerkin = Scheme::galerkin(3);
/// let mut query = Combination {
///     scheme: &galerkin,
///     policy: Policy::fixed(0.1),
///     size: Size::Const(2),
///     forced: false,
///     constraints: 0,
///     capability: Capability::Solve,
/// };
/// assert!(supports(&query).is_ok());
/// query.size = Size::Dynamic;
/// assert!(supports(&query).is_ok());
/// // Energy-preserving steps at a run-time size: the one-point and
/// // Galerkin rules, for systems without forces.
/// query.policy = Policy::energy_preserving(0.1);
/// assert!(supports(&query).is_ok());
/// query.forced = true;
/// assert!(supports(&query).unwrap_err().contains("forced"));
/// ```
pub fn supports(c: &Combination<'_>) -> Result<(), &'static str> {
    if c.constraints != 0 {
        return Err("a system with holonomic constraints through `Problem`: step it with `Constrained`");
    }
    if let Scheme::Composition { base, .. } = c.scheme {
        composed(c, base)?;
    }
    if c.capability == Capability::Sensitivities {
        sensitivities(c)?;
    }
    match c.size {
        Size::Const(n) => constant(c, n),
        Size::Dynamic => dynamic(c),
    }
}

/// The sub-steps a composition is made of: symmetric ones (the trapezoid,
/// midpoint and Galerkin rules, α-β at `α = ½`), whose order its weights
/// raise; the base's own rules at the size apply as to a run of it (at a
/// run-time size, a Galerkin degree from 1 to 16).
fn composed(c: &Combination<'_>, base: &Scheme) -> Result<(), &'static str> {
    match base {
        Scheme::OnePoint(OnePoint::AlphaBeta(m)) if m.alpha() != 0.5 => {
            return Err(
                "a composition of α-β sub-steps with α ≠ ½: the α-β step is symmetric only at α = ½, and a composition raises the order of symmetric sub-steps only",
            );
        }
        Scheme::OnePoint(_) | Scheme::Galerkin { .. } => {}
        Scheme::Composition { .. } | Scheme::TimeTransformed { .. } | Scheme::Splitting { .. } => {
            return Err(
                "a composition of a composition, of a time transformation or of the splitting: the sub-steps of a composition are of a one-point or Galerkin rule",
            );
        }
    }
    if *base == Scheme::TRAPEZOID {
        return Ok(());
    }
    if c.capability == Capability::Sensitivities {
        return Err(
            "sensitivities of a composition of midpoint, α-β or Galerkin sub-steps: the linearisation keeps the sub-steps of the trapezoid compositions only",
        );
    }
    // The base's degree and size, as for a run of it with the same policy
    // (the policy itself is refused below: a composition's steps are fixed).
    supports(&Combination { scheme: base, policy: Policy::Fixed { h: c.policy.step() }, ..*c })
}

/// The methods whose step the sensitivities and the adjoint differentiate:
/// fixed steps of the one-point rules, the Galerkin rules, the
/// compositions of trapezoid sub-steps (`composed` refuses the others), the implicit time transformation and the explicit
/// time-transformed splitting (fixed steps in `s`), energy-preserving
/// steps of the one-point and Galerkin rules, and energy-balance steps of
/// the one-point rules (`constant` refuses them for the Galerkin rules as
/// for a run).
fn sensitivities(c: &Combination<'_>) -> Result<(), &'static str> {
    let n = match c.size {
        Size::Dynamic => {
            return Err("sensitivities of a run-time-sized system: they are written for `Problem`'s compile-time `N`");
        }
        Size::Const(n) => n,
    };
    let fixed = matches!(c.policy, Policy::Fixed { .. });
    match c.scheme {
        Scheme::OnePoint(_) | Scheme::Galerkin { .. } if fixed => Ok(()),
        Scheme::OnePoint(_) | Scheme::Galerkin { .. } => energy_sensitivities(c.policy),
        Scheme::Composition { .. } if n > crate::Derivatives::FORWARD_MAX_N => Err(
            "sensitivities of a composition above `Derivatives::FORWARD_MAX_N` coordinates: it steps in reverse mode, which keeps only its last sub-step",
        ),
        Scheme::Composition { .. } => Ok(()),
        // Fixed steps in `s`; `constant` refuses the rest as for a run.
        Scheme::TimeTransformed { .. } | Scheme::Splitting { .. } => Ok(()),
    }
}

/// The variable steps of a one-point or Galerkin rule whose step size the
/// sensitivities differentiate through the energy equation (with the work
/// of the forces under energy-balance steps).
fn energy_sensitivities(policy: Policy) -> Result<(), &'static str> {
    match policy {
        Policy::EnergyPreserving { bounds, .. } | Policy::EnergyBalance { bounds, .. } if bounds.accuracy.is_some() => {
            Err(
                "sensitivities of energy steps under an accuracy bound: a capped step minimises the energy mismatch instead of solving the energy equation, and the landing is split in pieces; neither is differentiated",
            )
        }
        _ => Ok(()),
    }
}

/// The rules for a compile-time-sized system.
fn constant(c: &Combination<'_>, n: usize) -> Result<(), &'static str> {
    if n > MAX_PROBLEM_N {
        return Err(
            "a compile-time size above 1024 through `Problem`: state it with `Vec<f64>` coordinates (a run-time size) or use a driver directly",
        );
    }
    let fixed = matches!(c.policy, Policy::Fixed { .. });
    if let Scheme::Galerkin { degree, quadrature, .. } = c.scheme {
        let highest = match quadrature {
            GalerkinQuadrature::GaussLegendre => 8,
            GalerkinQuadrature::GaussLobatto => 4,
        };
        if !(2..=highest).contains(degree) {
            return Err(CONST_GALERKIN_DEGREES);
        }
    }
    match c.scheme {
        Scheme::OnePoint(_) | Scheme::Galerkin { .. } => variable_steps(c),
        Scheme::Composition { .. } if fixed => Ok(()),
        Scheme::Composition { .. } => Err("variable steps with a composition: its steps are fixed"),
        Scheme::TimeTransformed { inner, .. } => {
            match inner.as_ref() {
                Scheme::OnePoint(_) | Scheme::Galerkin { quadrature: GalerkinQuadrature::GaussLegendre, .. } => {}
                Scheme::Galerkin { .. } => {
                    return Err(
                        "time transformation around a Galerkin rule with Gauss–Lobatto quadrature: only Gauss–Legendre is offered in `s`",
                    );
                }
                _ => {
                    return Err(
                        "time transformation around a composition, the splitting or another time transformation: the method in `s` is a one-point or Galerkin rule",
                    );
                }
            }
            if let Scheme::Galerkin { degree, .. } = inner.as_ref()
                && !(2..=4).contains(degree)
            {
                return Err(CONST_GALERKIN_DEGREES);
            }
            if !fixed {
                return Err(
                    "variable steps under a time transformation: its steps in `s` are fixed, the density varies them in t",
                );
            }
            Ok(())
        }
        Scheme::Splitting { .. } if c.forced => Err(
            "the explicit time-transformed splitting of a forced system: its flows are those of `T(p)` and `V(q)` alone",
        ),
        Scheme::Splitting { .. } if fixed => Ok(()),
        Scheme::Splitting { .. } => Err("variable steps with the explicit splitting: its steps in `s` are fixed"),
    }
}

/// Variable steps of the one-point and Galerkin rules.
fn variable_steps(c: &Combination<'_>) -> Result<(), &'static str> {
    match (c.policy, c.forced, c.scheme) {
        (Policy::Fixed { .. }, _, _) => Ok(()),
        (
            Policy::EnergyPreserving { bounds, .. } | Policy::EnergyBalance { bounds, .. },
            _,
            Scheme::Galerkin { .. },
        ) if bounds.accuracy.is_some() => Err(crate::galerkin::GALERKIN_ACCURACY_BOUND),
        (Policy::EnergyPreserving { .. }, true, _) => Err(
            "energy-preserving steps of a forced system: its energy changes by the work of the forces (`Policy::EnergyBalance`)",
        ),
        (Policy::EnergyPreserving { .. }, false, _) => Ok(()),
        (Policy::EnergyBalance { .. }, false, _) => Err(
            "energy-balance steps of a system without forces: there is no work to balance (`Policy::EnergyPreserving`)",
        ),
        (Policy::EnergyBalance { .. }, true, Scheme::OnePoint(_)) => Ok(()),
        (Policy::EnergyBalance { .. }, true, _) => {
            Err("energy-balance steps with a Galerkin rule: the discrete work is written for the one-point rules")
        }
    }
}

/// The rules for a run-time-sized system (the reverse-mode driver).
fn dynamic(c: &Combination<'_>) -> Result<(), &'static str> {
    match c.scheme {
        Scheme::OnePoint(_) | Scheme::Composition { .. } => {}
        Scheme::Galerkin { degree, .. } if !(1..=MAX_RUN_TIME_GALERKIN_DEGREE).contains(degree) => {
            return Err("a Galerkin degree other than 1 to 16 on a run-time-sized system");
        }
        Scheme::Galerkin { .. } => {}
        // The extended system of `n + 1` coordinates is run-time-sized too.
        Scheme::TimeTransformed { inner, .. } => {
            match inner.as_ref() {
                Scheme::OnePoint(_) => {}
                Scheme::Galerkin { degree, .. } if !(1..=MAX_RUN_TIME_GALERKIN_DEGREE).contains(degree) => {
                    return Err("a Galerkin degree other than 1 to 16 on a run-time-sized system");
                }
                Scheme::Galerkin { .. } => {}
                _ => {
                    return Err(
                        "time transformation around a composition, the splitting or another time transformation: the method in `s` is a one-point or Galerkin rule",
                    );
                }
            }
            if !matches!(c.policy, Policy::Fixed { .. }) {
                return Err(
                    "variable steps under a time transformation: its steps in `s` are fixed, the density varies them in t",
                );
            }
        }
        Scheme::Splitting { .. } if c.forced => {
            return Err(
                "the explicit time-transformed splitting of a forced system: its flows are those of `T(p)` and `V(q)` alone",
            );
        }
        Scheme::Splitting { .. } if !matches!(c.policy, Policy::Fixed { .. }) => {
            return Err("variable steps with the explicit splitting: its steps in `s` are fixed");
        }
        Scheme::Splitting { .. } => {}
    }
    match c.scheme {
        // Energy-preserving Galerkin steps as at a compile-time size: for
        // systems without forces (`start` refuses a time-dependent `L`).
        Scheme::OnePoint(_) | Scheme::Galerkin { .. } => variable_steps(c)?,
        Scheme::Composition { .. } if !matches!(c.policy, Policy::Fixed { .. }) => {
            return Err("variable steps with a composition: its steps are fixed");
        }
        _ => {}
    }
    if c.policy.bounds().is_some_and(|b| b.accuracy.is_some()) {
        return Err(
            "an accuracy bound on energy steps of a run-time-sized system: the fastest mode of the linearisation is a dense eigenproblem of the size of the system",
        );
    }
    match c.capability {
        Capability::Step | Capability::Solve => Ok(()),
        // Refused by `sensitivities` before the size is looked at.
        Capability::Sensitivities => Err("sensitivities of a run-time-sized system"),
    }
}
