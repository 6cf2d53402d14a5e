//! The configuration of an [`Adaptive`](super::Adaptive) integrator before its
//! initial state: the method in `s`, the step `σ`, Newton's tolerance.

use core::marker::PhantomData;

use crate::dim::{Dim, ExtendedSize};
use crate::discrete::DiscreteLagrangian;
use crate::error::Error;
use crate::galerkin::Galerkin;
use crate::mechanics::DiscreteMechanics;
use crate::newton::NewtonOptions;
use crate::real::{Real, all_finite};
use crate::state::State;
use crate::system::{Lagrangian, Scalar};

use super::adaptive::{Adaptive, physical_point};
use super::density::StepDensity;
use super::extended::TimeTransformed;
use super::stepper::{Rule, SMethod, SStepper};

impl<Sys: Lagrangian<N>, G: StepDensity<N>, const N: usize> TimeTransformed<Sys, G, N> {
    /// Configures an adaptive integrator with a one-point discrete
    /// Lagrangian (midpoint, trapezoid, α-β) and the step `sigma` in `s`.
    /// The type of `sigma` is the real type of the run, as for
    /// [`Integrator::new`](crate::Integrator::new): `f64`, or [`DoubleDouble`](crate::DoubleDouble)
    /// (`.rule(Midpoint, DoubleDouble::from(0.01))`), in which the one-point
    /// rule runs as the Galerkin rule of degree 1 with its quadrature.
    pub fn rule<Mth: DiscreteLagrangian, T: Real>(
        self,
        method: Mth,
        sigma: T,
    ) -> TimeTransformedBuilder<Sys, G, Rule<Mth>, N, T> {
        TimeTransformedBuilder::new(self, Rule(method), sigma)
    }

    /// Configures an adaptive integrator with a Galerkin discrete Lagrangian
    /// (order `2s` in `s` with Gauss quadrature) and the step `sigma` in `s`,
    /// in the rule's real type `T`.
    pub fn galerkin<const S: usize, const R: usize, T: Real>(
        self,
        method: Galerkin<S, R, T>,
        sigma: T,
    ) -> TimeTransformedBuilder<Sys, G, Galerkin<S, R, T>, N, T> {
        TimeTransformedBuilder::new(self, method, sigma)
    }
}

/// The default relative Newton tolerance of the steps in `s`: one ulp,
/// where the runtime's default is `1e-14`.
///
/// The Galerkin steps solve by simplified Newton, which converges linearly
/// and stops with an error of up to `rtol` that keeps its sign step after
/// step; in `s` that bias adds up and the energy drifts. On Kepler e = 0.99
/// (Galerkin s = 4, σ = 0.4, 1000 orbits) the mean energy error of the last
/// 100 orbits is 14 times that of the first 100 at `1e-14`, and equal to it
/// within 4% at `2e-16`, for about 5 instead of 4.7 Newton iterations per
/// step. Newton's round-off floor test ends the iteration where the
/// corrections stop shrinking, so the tight tolerance does not make steps
/// fail.
pub const DEFAULT_RTOL: f64 = 2e-16;

/// The default relative Newton tolerance in a real type `T`: [`DEFAULT_RTOL`]
/// in `f64`, about two units of `T`'s precision in a wider type.
pub(super) fn default_rtol<T: Real>() -> f64 {
    if T::EPSILON < f64::EPSILON { 2.0 * T::EPSILON } else { DEFAULT_RTOL }
}

/// The default constant `c = 1/(|p·v| + |L| + |E|)` from the Lagrangian
/// `l` and the energy `e` at the initial data (1 where that sum is 0 or
/// not finite), on any scalar: the sensitivities differentiate it.
pub(crate) fn default_penalty<D: Scalar>(l: D, e: D) -> D {
    let scale = (e + l).abs() + l.abs() + e.abs();
    let re = scale.re();
    if re.is_finite() && re > 0.0 { scale.recip() } else { D::one() }
}

/// Configuration of an [`Adaptive`] integrator before its initial state;
/// `T` is the real type of the run (that of the step `σ`).
#[derive(Clone, Debug)]
pub struct TimeTransformedBuilder<Sys, G, K, const N: usize, T = f64> {
    pub(super) system: TimeTransformed<Sys, G, N>,
    pub(super) method: K,
    pub(super) sigma: T,
    pub(super) newton: NewtonOptions,
    pub(super) penalty: Option<f64>,
    pub(super) min_time_step: Option<T>,
}

impl<Sys: Lagrangian<N>, G: StepDensity<N>, K, const N: usize, T: Real> TimeTransformedBuilder<Sys, G, K, N, T> {
    pub(super) fn new(system: TimeTransformed<Sys, G, N>, method: K, sigma: T) -> Self {
        let newton = NewtonOptions { rtol: default_rtol::<T>(), ..NewtonOptions::default() };
        Self { system, method, sigma, newton, penalty: None, min_time_step: None }
    }

    /// Replaces the Newton settings of the steps in `s` (default: the
    /// runtime's, with `rtol = 2e-16` in `f64` (see [`DEFAULT_RTOL`]) and
    /// two units of the type's precision in a wider type).
    pub fn newton(mut self, options: NewtonOptions) -> Self {
        self.newton = options;
        self
    }

    /// The constant `c > 0` of the `(t' − g)²/(2cg)` term (units 1/energy).
    /// The trajectories do not depend on it; it sets how the discrete `t'`
    /// trades against the energy. Default: `1/(|p·v| + |L| + |E|)` at the
    /// initial data (1 if that is 0), computed in `f64` in every real type.
    pub fn penalty(mut self, c: f64) -> Self {
        self.penalty = Some(c);
        self
    }

    /// The smallest physical time a step in `s` may advance; a step that
    /// advances less is refused with [`Error::TimeStepCollapsed`].
    /// Default: `10⁻⁸ σ g(t0, q0)`, the first step's size times `10⁻⁸`.
    pub fn min_time_step(mut self, dt: T) -> Self {
        self.min_time_step = Some(dt);
        self
    }

    /// Starts at `(t0, q0, v0)` (physical time and velocity) with `s = 0`,
    /// `t'(0) = g(t0, q0)` and `q'(0) = g v0`, so that `p_t = −E(t0)`.
    /// The extended size `M = N + 1` is inferred from `N` (compile-time
    /// sizes up to [`MAX_SIZE`](crate::dim::MAX_SIZE)).
    ///
    /// Fails with [`Error::InvalidSetting`] for a step, penalty
    /// or floor that is not finite and positive or a monitor that cannot be
    /// evaluated, [`Error::InvalidDensity`] where `g(t0, q0)` is
    /// not finite and positive, and with the integrator's own errors
    /// (the error of the rule in `s`) for invalid initial data.
    #[allow(clippy::type_complexity)]
    pub fn start<const M: usize>(
        self,
        t0: T,
        q0: [T; N],
        v0: [T; N],
    ) -> Result<Adaptive<K::Stepper, Sys, G, N, M, T>, Error<T>>
    where
        K: SMethod<Sys, G, N, M, T>,
        Dim<N>: ExtendedSize<M>,
    {
        const { assert!(M == N + 1, "the time-transformed system has N + 1 coordinates (q, t)") };
        if Sys::CONSTRAINTS != 0 {
            return Err(Error::Unsupported { what: "time transformation of a system with holonomic constraints" });
        }
        self.system.density.check().map_err(|reason| Error::InvalidSetting { reason })?;
        let sigma = self.sigma.to_f64();
        if !(self.sigma.is_finite() && sigma > 0.0) {
            return Err(Error::InvalidSetting { reason: "the step in `s` must be finite and positive" });
        }
        if !t0.is_finite() || !all_finite(&q0) || !all_finite(&v0) {
            return Err(Error::InvalidInitialData { reason: "t0, q0 and v0 must be finite" });
        }
        let state = State { step: 0, t: t0, q: q0, p: [T::from(f64::NAN); N] };
        let g0 = self.system.density(t0, &q0);
        if !(g0.is_finite() && g0.to_f64() > 0.0) {
            return Err(Error::InvalidDensity { state: state.into(), value: g0.to_f64() });
        }
        // The constant c is part of the method, not of the state: f64 in every type.
        let sys = &*self.system.system;
        let (t0f, q0f, v0f) = (t0.to_f64(), q0.map(|x| x.to_f64()), v0.map(|x| x.to_f64()));
        let (l0, e0) = (sys.lagrangian_value(t0f, q0f, v0f), sys.energy(t0f, q0f, v0f));
        let penalty = match self.penalty {
            Some(c) if c.is_finite() && c > 0.0 => c,
            Some(_) => {
                return Err(Error::InvalidSetting { reason: "the penalty must be finite and positive" });
            }
            None => default_penalty(l0, e0),
        };
        let floor = self.min_time_step.unwrap_or(T::from(1e-8) * self.sigma * g0);
        if !(floor.is_finite() && floor.to_f64() > 0.0) {
            return Err(Error::InvalidSetting { reason: "the smallest time step must be finite and positive" });
        }
        let mut system = self.system;
        system.penalty = penalty;
        let mut x0 = [T::zero(); M];
        let mut w0 = [T::zero(); M];
        for i in 0..N {
            x0[i] = q0[i];
            w0[i] = g0 * v0[i];
        }
        x0[N] = t0;
        w0[N] = g0;
        let inner =
            self.method.start_s(system, self.sigma, self.newton, x0, w0).map_err(|e| e.map_state(physical_point))?;
        let saved = inner.clone();
        let mut adaptive =
            Adaptive { inner, marker: PhantomData, floor, landed: None, v_guess: v0, last_dt: None, rate: None, saved };
        adaptive.rate = adaptive.rate_at(&adaptive.inner.extended_state(), v0);
        Ok(adaptive)
    }
}
