//! What [`Adaptive`](super::Adaptive) needs of an integrator in `s`, and the
//! methods (a one-point rule or Galerkin) that build one.

use crate::discrete::DiscreteLagrangian;
use crate::double_double::DoubleDouble;
use crate::error::Error;
use crate::galerkin::{Galerkin, GalerkinIntegrator};
use crate::integrator::{F64Readouts, Integrator, Method, Stats};
use crate::newton::NewtonOptions;
use crate::real::Real;
use crate::state::State;
use crate::symplectic::TangentMap;
use crate::system::Lagrangian;

use super::density::StepDensity;
use super::extended::TimeTransformed;

/// An integrator in `s` of a [`TimeTransformed`] system, as [`Adaptive`](super::Adaptive)
/// drives it: the [`Integrator`] with any method, in the real type `T`
/// (`f64` or [`DoubleDouble`](crate::DoubleDouble)).
pub trait SStepper<const M: usize, T: Real = f64>: Clone {
    /// The transformed system.
    type System;
    /// The system being integrated.
    fn transformed(&self) -> &Self::System;
    /// The state in `s`: `x = (q, t)`, momenta `(p, p_t)`.
    fn extended_state(&self) -> State<M, T>;
    /// The step in `s`.
    fn s_step_size(&self) -> T;
    /// Sets the step in `s`.
    fn set_s_step_size(&mut self, sigma: T) -> Result<(), Error<T>>;
    /// One step in `s`; on failure nothing changes.
    fn s_step(&mut self) -> Result<(), Error<T>>;
    /// Work counters of the integrator in `s`.
    fn s_stats(&self) -> Stats;
    /// The tangent map of the last step in `(q, t, p, p_t)`; `None` in a
    /// real type other than `f64` (the runtime computes tangent maps in `f64`).
    fn s_tangent_map(&self) -> Option<Box<TangentMap<M>>>;
}

impl<Sys, G, Mth, const N: usize, const M: usize> SStepper<M> for Integrator<TimeTransformed<Sys, G, N>, Mth, M>
where
    Sys: Lagrangian<N>,
    G: StepDensity<N>,
    Mth: F64Readouts,
{
    type System = TimeTransformed<Sys, G, N>;
    fn transformed(&self) -> &Self::System {
        self.system()
    }
    fn extended_state(&self) -> State<M> {
        *self.state()
    }
    fn s_step_size(&self) -> f64 {
        self.step_size()
    }
    fn set_s_step_size(&mut self, sigma: f64) -> Result<(), Error> {
        self.set_step_size(sigma)
    }
    fn s_step(&mut self) -> Result<(), Error> {
        self.step().map(|_| ())
    }
    fn s_stats(&self) -> Stats {
        *self.stats()
    }
    fn s_tangent_map(&self) -> Option<Box<TangentMap<M>>> {
        self.last_tangent_map()
    }
}

impl<Sys, G, Mth, const N: usize, const M: usize> SStepper<M, DoubleDouble>
    for Integrator<TimeTransformed<Sys, G, N>, Mth, M, DoubleDouble>
where
    Sys: Lagrangian<N>,
    G: StepDensity<N>,
    Mth: Method<DoubleDouble>,
{
    type System = TimeTransformed<Sys, G, N>;
    fn transformed(&self) -> &Self::System {
        self.system()
    }
    fn extended_state(&self) -> State<M, DoubleDouble> {
        *self.state()
    }
    fn s_step_size(&self) -> DoubleDouble {
        self.step_size()
    }
    fn set_s_step_size(&mut self, sigma: DoubleDouble) -> Result<(), Error<DoubleDouble>> {
        self.set_step_size(sigma)
    }
    fn s_step(&mut self) -> Result<(), Error<DoubleDouble>> {
        self.step().map(|_| ())
    }
    fn s_stats(&self) -> Stats {
        *self.stats()
    }
    fn s_tangent_map(&self) -> Option<Box<TangentMap<M>>> {
        None
    }
}

/// A one-point discrete Lagrangian (midpoint, trapezoid, α-β) as the method in `s`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rule<Mth>(pub Mth);

/// How a method in `s` starts its integrator on the transformed system, in
/// the real type `T`.
pub trait SMethod<Sys, G, const N: usize, const M: usize, T: Real = f64> {
    /// The integrator in `s`.
    type Stepper: SStepper<M, T, System = TimeTransformed<Sys, G, N>>;
    /// Starts it at `s = 0` from `(x0, x0')`.
    fn start_s(
        self,
        system: TimeTransformed<Sys, G, N>,
        sigma: T,
        newton: NewtonOptions,
        x0: [T; M],
        w0: [T; M],
    ) -> Result<Self::Stepper, Error<T>>;
}

impl<Sys, G, Mth, T, const N: usize, const M: usize> SMethod<Sys, G, N, M, T> for Rule<Mth>
where
    Sys: Lagrangian<N>,
    G: StepDensity<N>,
    Mth: DiscreteLagrangian + Method<T>,
    T: Real,
    Integrator<TimeTransformed<Sys, G, N>, Mth, M, T>: SStepper<M, T, System = TimeTransformed<Sys, G, N>>,
{
    type Stepper = Integrator<TimeTransformed<Sys, G, N>, Mth, M, T>;
    fn start_s(
        self,
        system: TimeTransformed<Sys, G, N>,
        sigma: T,
        newton: NewtonOptions,
        x0: [T; M],
        w0: [T; M],
    ) -> Result<Self::Stepper, Error<T>> {
        Integrator::new(system, self.0, sigma).newton(newton).start(T::zero(), x0, w0)
    }
}

impl<Sys, G, T, const N: usize, const M: usize, const S: usize, const R: usize> SMethod<Sys, G, N, M, T>
    for Galerkin<S, R, T>
where
    Sys: Lagrangian<N>,
    G: StepDensity<N>,
    T: Real,
    GalerkinIntegrator<TimeTransformed<Sys, G, N>, M, S, R, T>: SStepper<M, T, System = TimeTransformed<Sys, G, N>>,
{
    type Stepper = GalerkinIntegrator<TimeTransformed<Sys, G, N>, M, S, R, T>;
    fn start_s(
        self,
        system: TimeTransformed<Sys, G, N>,
        sigma: T,
        newton: NewtonOptions,
        x0: [T; M],
        w0: [T; M],
    ) -> Result<Self::Stepper, Error<T>> {
        GalerkinIntegrator::new(system, self, sigma).newton(newton).start(T::zero(), x0, w0)
    }
}
