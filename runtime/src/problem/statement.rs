//! The problem: a system and its initial data, stated once; the method and
//! the step policy are values given when it is solved or stepped.

use super::composed::Composed;
use super::extend::Extended;
use super::scheme::{GalerkinQuadrature, OnePoint, Scheme};
use super::stepper::{Driver, DriverBox, Stepper, boxed};
use super::support::{CONST_GALERKIN_DEGREES, Capability, Combination, Policy, Size, supports};
use crate::auto::Auto;
use crate::dim::{Coordinates, Dim, Dimension};
use crate::discrete::{Midpoint, Trapezoid};
use crate::error::Error;
use crate::galerkin::{Galerkin, NodeFamily, Quadrature};
use crate::integrator::{Composition, EnergyFallback, Integrator, IntegratorBuilder, Method, Summation};
use crate::newton::NewtonOptions;
use crate::solution::{Plan, Solution, SolveError};
use crate::system::Lagrangian;
use crate::time_transform::{Curvature, ExplicitTimeTransformed, TimeFunction};

/// A system with its initial data `(t0, q0, v0)`; the end of the run is the
/// [`Plan`]'s.
///
/// The coordinates state the size: arrays `[f64; N]` a compile-time-sized
/// [`Lagrangian<N>`] (`Problem<S, Dim<N>>`, stepped by the const-generic
/// drivers), a `Vec<f64>` a run-time-sized
/// [`DynLagrangian`](crate::DynLagrangian) (`Problem<S, Dyn>`, stepped in
/// reverse mode on a tape, for large systems). The methods are the same at
/// both sizes; what a size cannot do is refused by
/// [`supports`](super::supports).
///
/// [`solve`](Self::solve) and [`stepper`](Self::stepper) take the method as
/// a [`Scheme`] value and the step sizes as a [`Policy`] (or just `h`), and
/// return the same [`Solution`] and the same [`Stepper`] whatever the
/// method; a combination that is not defined is refused by
/// [`supports`](super::supports) before anything runs.
///
/// ```
/// use lagrangian_runtime::problem::{Problem, Scheme};
/// use lagrangian_runtime::{Lagrangian, Plan, Scalar};
///
/// #[derive(Clone)]
/// struct Oscillator;
/// impl Lagrangian<1> for Oscillator {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 1] = [false];
///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
///         (v[0] * v[0] - q[0] * q[0]) * 0.5
///     }
/// }
///
/// let problem = Problem::new(Oscillator, 0.0, [1.0], [0.0]);
/// for (scheme, h, tolerance) in [(Scheme::MIDPOINT, 0.01, 1e-4), (Scheme::galerkin(3), 0.1, 1e-8)] {
///     let solution = problem.solve(&scheme, h, Plan::until(1.0))?;
///     let last = solution.len() - 1;
///     assert!((solution.q[last][0] - 1f64.cos()).abs() < tolerance);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct Problem<S, Z: Dimension> {
    pub(super) system: S,
    pub(super) t0: f64,
    pub(super) q0: Z::Vector,
    pub(super) v0: Z::Vector,
    pub(super) newton: Option<NewtonOptions>,
    pub(super) summation: Summation,
    pub(super) fallback: EnergyFallback,
}

impl<S, Z: Dimension> Problem<S, Z> {
    /// `system` from `(t0, q0, v0)`; the coordinates' type states the size
    /// (see [`Coordinates`]).
    pub fn new<C: Coordinates<Dimension = Z>>(system: S, t0: f64, q0: C, v0: C) -> Self {
        Self {
            system,
            t0,
            q0: q0.into_vector(),
            v0: v0.into_vector(),
            newton: None,
            summation: Summation::Compensated,
            fallback: EnergyFallback::Fail,
        }
    }

    /// Newton settings for the implicit schemes (default: each driver's own).
    pub fn newton(mut self, options: NewtonOptions) -> Self {
        self.newton = Some(options);
        self
    }

    /// How the one-point, Galerkin and composition steps add their
    /// increments to the state ([`Summation`]; default
    /// [`Summation::Compensated`]). [`Summation::Plain`] rounds each update
    /// once, as a hand-written integrator does: a few operations fewer per
    /// coordinate and step, with round-off accumulating in the state. The
    /// time transformations keep their compensated sums whatever this says.
    ///
    /// ```
    /// use lagrangian_runtime::problem::{Problem, Scheme};
    /// use lagrangian_runtime::{Lagrangian, Scalar, Summation};
    ///
    /// #[derive(Clone)]
    /// struct Oscillator;
    /// impl Lagrangian<1> for Oscillator {
    ///     const AUTONOMOUS: bool = true;
    ///     const CYCLIC: [bool; 1] = [false];
    ///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
    ///         (v[0] * v[0] - q[0] * q[0]) * 0.5
    ///     }
    /// }
    ///
    /// let problem = Problem::new(Oscillator, 0.0, [1.0], [0.0]).summation(Summation::Plain);
    /// let mut sim = problem.stepper(&Scheme::TRAPEZOID, 0.01)?;
    /// sim.run(100, |_| {})?;
    /// assert!((sim.state().q[0] - 1f64.cos()).abs() < 1e-4);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn summation(mut self, summation: Summation) -> Self {
        self.summation = summation;
        self
    }

    /// What energy-preserving and energy-balance steps of the one-point and
    /// Galerkin rules do where no admissible step size satisfies the energy
    /// equation ([`EnergyFallback`]; default [`EnergyFallback::Fail`]: the
    /// step fails with `NoEnergyStep` and the stepper is left as it was;
    /// [`EnergyFallback::LeastSquares`] takes the step of least energy
    /// mismatch and counts it in [`Stats::energy_fallbacks`](crate::Stats::energy_fallbacks)).
    pub fn energy_fallback(mut self, fallback: EnergyFallback) -> Self {
        self.fallback = fallback;
        self
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }
}

impl<S: Lagrangian<N> + Clone, const N: usize> Problem<S, Dim<N>> {
    /// The initial data `(t0, q0, v0)`.
    pub fn initial(&self) -> (f64, [f64; N], [f64; N]) {
        (self.t0, self.q0, self.v0)
    }

    /// The same problem solved to an accuracy instead of with a method: the
    /// library chooses the method family, its order and its step, and
    /// reports the error it estimates ([`Auto`]; any part can still be
    /// fixed there).
    ///
    /// ```
    /// # use lagrangian_runtime::problem::Problem;
    /// # use lagrangian_runtime::{Lagrangian, Plan, Scalar, auto::Tolerance};
    /// # #[derive(Clone)]
    /// # struct Oscillator;
    /// # impl Lagrangian<1> for Oscillator {
    /// #     const AUTONOMOUS: bool = true;
    /// #     const CYCLIC: [bool; 1] = [false];
    /// #     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
    /// #         (v[0] * v[0] - q[0] * q[0]) * 0.5
    /// #     }
    /// # }
    /// let problem = Problem::new(Oscillator, 0.0, [1.0], [0.0]);
    /// let solved = problem.auto().tolerance(Tolerance::relative(1e-8)).solve(Plan::until(20.0))?;
    /// let last = solved.solution.len() - 1;
    /// assert!((solved.solution.q[last][0] - 20f64.cos()).abs() < 1e-7);
    /// assert!(solved.estimate.error < 1e-8);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn auto(&self) -> Auto<S, N> {
        Auto::new(self.system.clone(), self.t0, self.q0, self.v0)
    }

    /// `Ok` when `scheme` under `policy` can do `capability` on this
    /// problem; otherwise [`Error::Unsupported`] naming the combination
    /// (see [`supports`](super::supports)).
    pub fn supports(&self, scheme: &Scheme, policy: impl Into<Policy>, capability: Capability) -> Result<(), Error> {
        let combination = Combination {
            scheme,
            policy: policy.into(),
            size: Size::Const(N),
            forced: S::HAS_FORCE || S::HAS_DISSIPATION,
            constraints: S::CONSTRAINTS,
            capability,
        };
        supports(&combination).map_err(|what| Error::Unsupported { what })
    }
}

impl<S: Lagrangian<N> + Clone, const N: usize> Problem<S, Dim<N>>
where
    Dim<N>: Extended<N>,
{
    /// A stepper of `scheme` under `policy` at the initial data.
    ///
    /// Fails with [`Error::Unsupported`] for a combination
    /// [`supports`](super::supports) refuses, and otherwise with the
    /// driver's own errors of `start` (invalid step, initial data or
    /// settings; a system the splitting cannot take).
    pub fn stepper(&self, scheme: &Scheme, policy: impl Into<Policy>) -> Result<Stepper<S, Dim<N>>, Error> {
        let policy = policy.into();
        self.supports(scheme, policy, Capability::Step)?;
        let driver = DriverBox(self.driver(scheme, policy)?);
        Ok(Stepper { driver, scheme: scheme.clone(), policy })
    }

    /// Integrates with `scheme` under `policy` as `plan` says: the same
    /// [`Solution`] and [`SolveError`] as [`Stepping::solve`](crate::Stepping::solve) on any driver.
    /// A refused combination or a failed start is `SolveError::Step`.
    pub fn solve(&self, scheme: &Scheme, policy: impl Into<Policy>, plan: Plan<'_>) -> Result<Solution, SolveError> {
        let policy = policy.into();
        self.supports(scheme, policy, Capability::Solve)?;
        self.stepper(scheme, policy)?.solve(plan)
    }

    /// The driver of `scheme`: the one `match` from the value to the
    /// const-generic kernels. Each kind is started and boxed by a function
    /// of its own, so that no frame holds room for every kind at once (a
    /// driver is 300 kB at `N = 1000`).
    fn driver(&self, scheme: &Scheme, policy: Policy) -> Result<Box<Driver<S, N>>, Error> {
        let h = policy.step();
        match scheme {
            Scheme::OnePoint(OnePoint::Midpoint) => self.integrator(Midpoint, policy, Driver::Midpoint),
            Scheme::OnePoint(OnePoint::Trapezoid) => self.integrator(Trapezoid, policy, Driver::Trapezoid),
            Scheme::OnePoint(OnePoint::AlphaBeta(m)) => self.integrator(*m, policy, Driver::AlphaBeta),
            Scheme::Galerkin { degree, nodes, quadrature } => self.galerkin(*degree, *nodes, *quadrature, policy),
            Scheme::Composition { weights, base } if **base == Scheme::TRAPEZOID => {
                self.integrator(*weights, policy, Driver::Composition)
            }
            Scheme::Composition { weights, base } => self.composed(base, *weights, h),
            Scheme::TimeTransformed { inner, density } => self.transformed(inner, *density, h),
            Scheme::Splitting { function, composition } => self.splitting(*function, *composition, h),
        }
    }

    /// The Galerkin driver of degree `degree` (2 to 8 with Gauss–Legendre
    /// quadrature, 2 to 4 with Gauss–Lobatto).
    fn galerkin(
        &self,
        degree: usize,
        nodes: NodeFamily,
        quadrature: GalerkinQuadrature,
        policy: Policy,
    ) -> Result<Box<Driver<S, N>>, Error> {
        use GalerkinQuadrature::{GaussLegendre as G, GaussLobatto as L};
        match (degree, quadrature) {
            (2, G) => {
                self.integrator(Galerkin::<2, 2>::new(nodes, Quadrature::gauss_legendre()), policy, Driver::Gauss2)
            }
            (3, G) => {
                self.integrator(Galerkin::<3, 3>::new(nodes, Quadrature::gauss_legendre()), policy, Driver::Gauss3)
            }
            (4, G) => {
                self.integrator(Galerkin::<4, 4>::new(nodes, Quadrature::gauss_legendre()), policy, Driver::Gauss4)
            }
            (5, G) => {
                self.integrator(Galerkin::<5, 5>::new(nodes, Quadrature::gauss_legendre()), policy, Driver::Gauss5)
            }
            (6, G) => {
                self.integrator(Galerkin::<6, 6>::new(nodes, Quadrature::gauss_legendre()), policy, Driver::Gauss6)
            }
            (7, G) => {
                self.integrator(Galerkin::<7, 7>::new(nodes, Quadrature::gauss_legendre()), policy, Driver::Gauss7)
            }
            (8, G) => {
                self.integrator(Galerkin::<8, 8>::new(nodes, Quadrature::gauss_legendre()), policy, Driver::Gauss8)
            }
            (2, L) => {
                self.integrator(Galerkin::<2, 3>::new(nodes, Quadrature::gauss_lobatto()), policy, Driver::Lobatto2)
            }
            (3, L) => {
                self.integrator(Galerkin::<3, 4>::new(nodes, Quadrature::gauss_lobatto()), policy, Driver::Lobatto3)
            }
            (4, L) => {
                self.integrator(Galerkin::<4, 5>::new(nodes, Quadrature::gauss_lobatto()), policy, Driver::Lobatto4)
            }
            _ => Err(Error::Unsupported { what: CONST_GALERKIN_DEGREES }),
        }
    }

    /// The [`Integrator`] of `method` under `policy` at the initial data,
    /// wrapped by `wrap`.
    #[inline(never)]
    fn integrator<M: Method<f64>>(
        &self,
        method: M,
        policy: Policy,
        wrap: fn(Integrator<S, M, N>) -> Driver<S, N>,
    ) -> Result<Box<Driver<S, N>>, Error> {
        let mut builder: IntegratorBuilder<S, M> = Integrator::new(self.system.clone(), method, policy.step())
            .summation(self.summation)
            .energy_fallback(self.fallback);
        if let Some(bounds) = policy.bounds() {
            builder = builder.energy_preserving(bounds);
        }
        if let Some(options) = self.newton {
            builder = builder.newton(options);
        }
        builder.start(self.t0, self.q0, self.v0).map(boxed(wrap))
    }

    /// The composition with `weights` of fixed steps of `base` (other than
    /// the trapezoid's, whose compositions are fused), step `h`.
    #[inline(never)]
    fn composed(&self, base: &Scheme, weights: Composition, h: f64) -> Result<Box<Driver<S, N>>, Error> {
        let base = self.driver(base, Policy::Fixed { h })?;
        Ok(Box::new(Driver::Composed(Composed::new(DriverBox(base), weights, h))))
    }

    /// The implicit time transformation of `inner` with `density`, step `h`
    /// in `s`.
    #[inline(never)]
    fn transformed(&self, inner: &Scheme, density: Curvature, h: f64) -> Result<Box<Driver<S, N>>, Error> {
        let (t0, q0, v0) = (self.t0, self.q0, self.v0);
        <Dim<N> as Extended<N>>::start(self.system.clone(), inner, density, h, self.newton, t0, q0, v0)
            .map(boxed(Driver::Transformed))
    }

    /// The explicit time-transformed splitting with `function`, composed
    /// with `composition` if given, step `h` in `s`.
    #[inline(never)]
    fn splitting(
        &self,
        function: TimeFunction,
        composition: Option<Composition>,
        h: f64,
    ) -> Result<Box<Driver<S, N>>, Error> {
        let mut split = ExplicitTimeTransformed::new(self.system.clone(), function, h);
        if let Some(c) = composition {
            split = split.composition(c);
        }
        split.start(self.t0, self.q0, self.v0).map(boxed(Driver::Splitting))
    }
}
