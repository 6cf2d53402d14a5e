//! The methods of the report: their names, families, orders and settings
//! (how one is run is [`crate::integrate`]).

use serde::{Deserialize, Serialize};

/// Every method of the report. On a problem with holonomic constraints the
/// project's methods are their constrained forms (`Constrained`: RATTLE for
/// the one-point rules, the constraints at the control nodes of a Galerkin
/// rule, compositions of RATTLE trapezoid steps).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Method {
    /// Project: midpoint discrete Lagrangian, fixed steps (order 2).
    Midpoint,
    /// Project: trapezoid discrete Lagrangian, fixed steps (order 2).
    Trapezoid,
    /// Project: α-β discrete Lagrangian with α = 1 (symplectic Euler, order 1).
    AlphaBeta,
    /// Project: Galerkin of degree `s` with `s` Gauss points (order `2s`).
    Galerkin(u8),
    /// Project: as [`Method::Galerkin`], the stages solved by fixed-point
    /// iteration on the gradient of `L` (`StageIteration::Automatic`: Newton
    /// only where the iteration contracts slowly).
    GalerkinFixedPoint(u8),
    /// Project: midpoint with energy-preserving variable steps (`StepBounds::around(h0)`).
    EnergyMidpoint,
    /// Project: Yoshida's order 4 composition of trapezoid steps (`Composition::YOSHIDA4`).
    GeneratedYoshida4,
    /// Project: Yoshida's order 6 composition of trapezoid steps (`Composition::YOSHIDA6`).
    GeneratedYoshida6,
    /// Project: Kahan–Li's order 8 composition of trapezoid steps (`Composition::KAHAN_LI8`).
    GeneratedKahanLi8,
    /// Peer: ode_solvers 0.6 DOP853 (rtol = atol = tol, sparse output).
    OdeSolversDop853,
    /// Peer: differential-equations 0.5 DOP853 (rtol = atol = tol).
    DiffEqDop853,
    /// Peer: differential-equations 0.5 adaptive Gauss–Legendre IRK, 3 stages, order 6 (finite-difference Jacobian).
    DiffEqGauss6,
    /// Peer: ode_solvers 0.6 DOP853 on the minimal-coordinate (angle)
    /// equations of a problem with constraints (rtol = atol = tol).
    Dop853Angles,
    /// Peer: ode_solvers 0.6 DOP853 on the index-1 Cartesian equations of a
    /// problem with constraints, with Baumgarte stabilisation (rtol = atol = tol).
    Dop853Baumgarte,
    /// Hand-written: Störmer–Verlet.
    Verlet,
    /// Hand-written: Yoshida's order 6 composition.
    Yoshida6,
    /// Hand-written: Kahan–Li order 8 composition.
    KahanLi8,
    /// Project: time-transformed (Sundman–Poincaré) Galerkin of degree `s`,
    /// uniform steps `σ` in the new time, with the problem's own step density
    /// (Kepler: `r^{3/2}`); only problems that define one.
    TimeTransformed(u8),
    /// Project: as [`Method::TimeTransformed`] with the automatic monitor
    /// (`Curvature`, floor 1e-3), on the same problems.
    TimeTransformedAuto(u8),
    /// Project: the explicit time-transformed splitting (logarithmic
    /// Hamiltonian, Kahan–Li 8 of the drift–kick–drift leapfrog, uniform
    /// steps `σ` in the new time), on the problems with a step density.
    TimeTransformedSplit,
    /// Project: the tolerance-driven solve (`lagrangian::Auto`): it chooses
    /// the method, its order and its step from `rtol = tol`; the time
    /// includes its survey and pilot.
    Auto,
}

/// Who wrote a method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Family {
    /// This project.
    Project,
    /// Another crate.
    Peer,
    /// Hand-written in this crate.
    HandWritten,
}

/// What a method is calibrated by.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Setting {
    /// A number of fixed steps over the horizon (initial step `T/n` for variable steps).
    Steps(usize),
    /// `rtol = atol`.
    Tolerance(f64),
    /// The uniform step `σ` in the transformed time of a time-transformed method.
    Sigma(f64),
}

impl Method {
    /// All methods, in report order.
    pub fn all() -> Vec<Method> {
        let mut m = vec![Method::Midpoint, Method::Trapezoid, Method::AlphaBeta];
        m.extend((2..=8).map(Method::Galerkin));
        m.extend((2..=8).map(Method::GalerkinFixedPoint));
        m.extend([
            Method::EnergyMidpoint,
            Method::GeneratedYoshida4,
            Method::GeneratedYoshida6,
            Method::GeneratedKahanLi8,
            Method::OdeSolversDop853,
            Method::DiffEqDop853,
            Method::DiffEqGauss6,
            Method::Dop853Angles,
            Method::Dop853Baumgarte,
            Method::Verlet,
            Method::Yoshida6,
            Method::KahanLi8,
            Method::TimeTransformed(4),
            Method::TimeTransformed(6),
            Method::TimeTransformedAuto(6),
            Method::TimeTransformedSplit,
            Method::Auto,
        ]);
        m
    }

    /// The name used on the command line, in the JSON and in tables.
    pub fn name(self) -> String {
        match self {
            Method::Midpoint => "midpoint".into(),
            Method::Trapezoid => "trapezoid".into(),
            Method::AlphaBeta => "alpha-beta".into(),
            Method::Galerkin(s) => format!("galerkin-{s}"),
            Method::GalerkinFixedPoint(s) => format!("galerkin-fp-{s}"),
            Method::EnergyMidpoint => "energy-midpoint".into(),
            Method::GeneratedYoshida4 => "composition-yoshida4".into(),
            Method::GeneratedYoshida6 => "composition-yoshida6".into(),
            Method::GeneratedKahanLi8 => "composition-kahan-li8".into(),
            Method::OdeSolversDop853 => "ode_solvers-dop853".into(),
            Method::DiffEqDop853 => "diffeq-dop853".into(),
            Method::DiffEqGauss6 => "diffeq-gauss6".into(),
            Method::Dop853Angles => "ode_solvers-dop853-angles".into(),
            Method::Dop853Baumgarte => "ode_solvers-dop853-baumgarte".into(),
            Method::Verlet => "verlet".into(),
            Method::Yoshida6 => "yoshida6".into(),
            Method::KahanLi8 => "kahan-li8".into(),
            Method::TimeTransformed(s) => format!("tt-galerkin-{s}"),
            Method::TimeTransformedAuto(s) => format!("tt-auto-galerkin-{s}"),
            Method::TimeTransformedSplit => "tt-split-logh-kahan-li-8".into(),
            Method::Auto => "auto".into(),
        }
    }

    /// The method with this [`name`](Method::name).
    pub fn parse(name: &str) -> Option<Method> {
        Method::all().into_iter().find(|m| m.name() == name)
    }

    /// Who wrote it.
    pub fn family(self) -> Family {
        match self {
            Method::Midpoint
            | Method::Trapezoid
            | Method::AlphaBeta
            | Method::Galerkin(_)
            | Method::GalerkinFixedPoint(_)
            | Method::EnergyMidpoint
            | Method::GeneratedYoshida4
            | Method::GeneratedYoshida6
            | Method::GeneratedKahanLi8
            | Method::TimeTransformed(_)
            | Method::TimeTransformedAuto(_)
            | Method::TimeTransformedSplit
            | Method::Auto => Family::Project,
            Method::OdeSolversDop853
            | Method::DiffEqDop853
            | Method::DiffEqGauss6
            | Method::Dop853Angles
            | Method::Dop853Baumgarte => Family::Peer,
            Method::Verlet | Method::Yoshida6 | Method::KahanLi8 => Family::HandWritten,
        }
    }

    /// The classical order.
    pub fn order(self) -> u32 {
        match self {
            Method::Midpoint | Method::Trapezoid | Method::EnergyMidpoint | Method::Verlet => 2,
            Method::AlphaBeta => 1,
            Method::Galerkin(s)
            | Method::GalerkinFixedPoint(s)
            | Method::TimeTransformed(s)
            | Method::TimeTransformedAuto(s) => 2 * s as u32,
            Method::OdeSolversDop853 | Method::DiffEqDop853 | Method::Dop853Angles | Method::Dop853Baumgarte => 8,
            Method::DiffEqGauss6 | Method::Yoshida6 | Method::GeneratedYoshida6 => 6,
            Method::GeneratedYoshida4 => 4,
            Method::KahanLi8 | Method::GeneratedKahanLi8 | Method::TimeTransformedSplit => 8,
            // Chosen per problem and tolerance; the highest it may choose.
            Method::Auto => 16,
        }
    }

    /// `true` when the method is calibrated by a tolerance rather than a step count.
    pub fn adaptive(self) -> bool {
        matches!(
            self,
            Method::OdeSolversDop853
                | Method::DiffEqDop853
                | Method::DiffEqGauss6
                | Method::Dop853Angles
                | Method::Dop853Baumgarte
                | Method::Auto
        )
    }

    /// The coarsest `σ` of a time-transformed method's sweep; `None` for the others.
    pub fn sigma0(self) -> Option<f64> {
        match self {
            // Where Newton starts to fail on Kepler e = 0.9 (r^{3/2}); the automatic monitor
            // is about 5^{-1/4} r^{3/2} there, so its σ is larger for the same steps.
            Method::TimeTransformed(s) => Some(0.2 * s as f64),
            Method::TimeTransformedAuto(s) => Some(0.5 * s as f64),
            // The 10-orbit Kepler e = 0.9 problem meets 1e-4 already at this σ (the
            // sweep's first setting), so its time there is an upper bound.
            Method::TimeTransformedSplit => Some(0.8),
            _ => None,
        }
    }

    /// `true` for the methods calibrated by a step count (fixed steps, and
    /// energy-preserving steps from `h0 = T/n`).
    pub fn by_steps(self) -> bool {
        !self.adaptive() && self.sigma0().is_none()
    }

    /// `true` for the time-transformed methods, which need a problem with a step density.
    pub fn needs_time_transform(self) -> bool {
        self.sigma0().is_some()
    }

    /// `true` for the peers that need a problem with constraints (its angle
    /// equations, its index-1 Cartesian equations).
    pub fn needs_constraints(self) -> bool {
        matches!(self, Method::Dop853Angles | Method::Dop853Baumgarte)
    }

    /// `true` for the hand-written compositions, which need a separable Hamiltonian.
    pub fn needs_separable(self) -> bool {
        self.family() == Family::HandWritten
    }

    /// The hand-written composition that computes the same map as this
    /// project composition on a separable constant-mass problem (the
    /// trapezoid rule is Störmer–Verlet there), for the generated against
    /// hand-written comparison.
    pub fn hand_written_twin(self) -> Option<Method> {
        match self {
            Method::Trapezoid => Some(Method::Verlet),
            Method::GeneratedYoshida6 => Some(Method::Yoshida6),
            Method::GeneratedKahanLi8 => Some(Method::KahanLi8),
            _ => None,
        }
    }

    /// `true` for symplectic methods (bounded energy error expected).
    pub fn symplectic(self) -> bool {
        !matches!(
            self,
            Method::OdeSolversDop853 | Method::DiffEqDop853 | Method::Dop853Angles | Method::Dop853Baumgarte
        )
    }
}
