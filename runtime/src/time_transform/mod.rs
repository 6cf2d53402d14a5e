//! Time-transformed (Sundman–Poincaré) adaptive steps that keep the
//! structure: a fixed step in a new independent variable `s` with
//! `dt/ds = g(t, q)` is an adaptive step in `t`, and a variational method in
//! `s` stays symplectic (docs/time-transformation.md has the derivation).
//!
//! The system `L(t, q, v)` with `N` degrees of freedom becomes a system in
//! `s` with `M = N + 1` coordinates `x = (q, t)` and the Lagrangian
//!
//! ```text
//! L̃(x, x') = t' L(t, q, q'/t') + (t' − g(t, q))² / (2 c g(t, q)),     x' = dx/ds
//! ```
//!
//! the Legendre dual of `K = g (H + p_t) + ½ c g (H + p_t)²`, which has the
//! same flow as Poincaré's `g (H + p_t)` on its zero level. Its momenta are
//! the physical `p = ∂L/∂v` and `p_t = −E + u` with `u = (t'/g − 1)/c`, which
//! the initial data `t' = g` makes zero. `L̃` is regular where `L` is (the
//! `c` term makes `t'` an ordinary velocity), so every discrete Lagrangian of
//! the runtime integrates it unchanged: [`TimeTransformed`] implements
//! [`Lagrangian<M>`](Lagrangian), and the map in `s` is symplectic in
//! `(q, t, p, p_t)`, conserves `p_t` (hence the energy, up to a bounded `u`)
//! for an autonomous `L` and a `g` without `t`, and conserves the momentum
//! of every symmetry that `L` and `g` share. Time-dependent `L` and forces
//! (Lagrange–d'Alembert in `s`: `t' F` on `q` and `−F·q'` on `t`) work too.
//!
//! [`Adaptive`] drives any integrator of the adapter ([`Integrator`] with a
//! one-point or Galerkin rule, in `f64` or
//! [`DoubleDouble`]: the type of the step `σ` sets
//! the run's), reports `t`, `q`, `p`
//! and the energy in physical time, lands on requested times, and refuses a
//! step density that is not positive and finite, or steps that stop
//! advancing time, with typed errors that keep the state. The monitor can
//! be a type of this module or the system's own `fn step_density` in its
//! `#[lagrangian]` block ([`TimeTransformed::with_own_density`]).
//!
//! For separable systems `½ vᵀMv − V(t, q)` with constant `M`,
//! [`ExplicitTimeTransformed`] is an explicit alternative: a splitting of the
//! time-transformed Hamiltonian `f(T + p_t + c) − f(c − V)` (the logarithmic
//! Hamiltonian method and its power-law relatives, with compositions up to
//! order 8), symplectic in the same extended phase space and without Newton.

mod splitting;

pub use crate::error::Argument;

pub use splitting::{
    ExplicitAdaptive, ExplicitTimeTransformed, ExtendedPoint, LeapfrogForm, SplittingStats, TimeFunction,
};

use core::cell::Cell;
use core::marker::PhantomData;
use std::sync::Arc;

use num_dual::HyperDual;

use crate::discrete::DiscreteLagrangian;
use crate::double_double::DoubleDouble;
use crate::error::Error;
use crate::galerkin::{Galerkin, GalerkinIntegrator};
use crate::integrator::{F64Readouts, Integrator, Method, Stats};
use crate::mechanics::{DiscreteMechanics, LegendreFailure};
use crate::newton::NewtonOptions;
use crate::real::{Real, all_finite};
use crate::state::State;
use crate::symplectic::TangentMap;
use crate::system::{Lagrangian, Scalar, generalized_force};

/// A step density (monitor) `g(t, q) > 0`: the physical time one unit of `s`
/// takes, `dt/ds = g`. Small where the motion is fast.
///
/// `g` enters the transformed Lagrangian, whose derivatives the runtime takes
/// with dual numbers, so the monitor is evaluated on any [`Scalar`] (a plain
/// `f64` closure could not supply its derivatives, and without them the map
/// would not be symplectic). It gets the system too, so a monitor may be
/// computed from the dynamics ([`Curvature`]).
pub trait StepDensity<const N: usize> {
    /// `true` when `g` depends on `t`: then `t` is not cyclic in the
    /// transformed Lagrangian and `p_t` is not conserved.
    const TIME_DEPENDENT: bool = false;

    /// `g(t, q)`.
    fn density<S, D>(&self, system: &S, t: D, q: &[D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar;

    /// `Err` for a monitor that cannot be evaluated for `N` coordinates (an
    /// index out of range); checked before integrating.
    fn check(&self) -> Result<(), &'static str> {
        Ok(())
    }
}

/// `g = |x|^α` with `x` the coordinates at `indices`: for central-force
/// problems `α = 3/2` (steps proportional to the local orbital time scale,
/// `r^{3/2}` for Kepler) or `α = 1`. Rotation invariant when the indices span
/// the rotated plane, so the angular momentum stays conserved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadiusPower<const K: usize> {
    indices: [usize; K],
    exponent: f64,
}

impl<const K: usize> RadiusPower<K> {
    /// `|x|^exponent` with `x = (q[indices[0]], …)`; `None` for no index or
    /// an exponent that is not finite. Indices out of range are refused by
    /// [`StepDensity::check`] when the integrator starts.
    pub fn new(indices: [usize; K], exponent: f64) -> Option<Self> {
        (K > 0 && exponent.is_finite()).then_some(Self { indices, exponent })
    }
}

impl<const K: usize, const N: usize> StepDensity<N> for RadiusPower<K> {
    #[inline]
    fn density<S, D>(&self, _system: &S, _t: D, q: &[D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let mut r2 = D::zero();
        for &i in &self.indices {
            r2 += q[i] * q[i];
        }
        r2.powf(0.5 * self.exponent)
    }

    fn check(&self) -> Result<(), &'static str> {
        if self.indices.iter().all(|&i| i < N) {
            Ok(())
        } else {
            Err("a coordinate index of the `RadiusPower` monitor is out of range")
        }
    }
}

/// The automatic monitor: `g = (κ² + floor²)^{-1/4}`, with
/// `κ = ‖∂²L/∂q²(t, q, 0)‖_F` the curvature of the potential, so that `g` is
/// the local time scale `1/ω` of small oscillations (for Kepler, `κ = √5/r³`
/// in Cartesian coordinates and `2/r³` in polar ones: `g ∝ r^{3/2}`; for a
/// harmonic oscillator a constant). `floor > 0` (units of `1/time²`) caps
/// the physical step at `σ/√floor` where the potential is flat.
///
/// It depends on `(t, q)` only, so the map stays symplectic and
/// time-reversible, and the Frobenius norm is invariant under rotations of
/// Cartesian coordinates, so a rotation symmetry of `L` is kept. It assumes
/// a roughly constant mass matrix (it reads the potential, not `∂²L/∂v²`).
/// Cost: `N(N+1)/2` evaluations of `L` on nested hyper-duals per call.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Curvature {
    floor: f64,
}

impl Curvature {
    /// The automatic monitor with the given floor; `None` unless it is finite and positive.
    pub fn new(floor: f64) -> Option<Self> {
        (floor.is_finite() && floor > 0.0).then_some(Self { floor })
    }
}

impl<const N: usize> StepDensity<N> for Curvature {
    const TIME_DEPENDENT: bool = true;

    fn density<S, D>(&self, system: &S, t: D, q: &[D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let mut k2 = D::from(self.floor * self.floor);
        let v = [HyperDual::from_re(D::zero()); N];
        for i in 0..N {
            for j in i..N {
                let mut qh = q.map(HyperDual::from_re);
                qh[i].eps1 = D::one();
                qh[j].eps2 = D::one();
                let h = system.lagrangian(HyperDual::from_re(t), qh, v).eps1eps2;
                k2 += if i == j { h * h } else { h * h * 2.0 };
            }
        }
        k2.powf(-0.25)
    }
}

/// The transformed system: `L̃(x, x') = t' L(t, q, q'/t') + (t' − g)²/(2cg)`
/// in the independent variable `s`, with `x = (q, t)` (see the
/// [module](self)). Implements [`Lagrangian<M>`](Lagrangian) for
/// `M = N + 1` (checked at compile time).
///
/// Build it with [`new`](Self::new) (a system and a [`StepDensity`]) or
/// [`with_own_density`](Self::with_own_density), choose the method in `s`
/// with [`rule`](Self::rule) or [`galerkin`](Self::galerkin) and the step
/// `σ`, and [`start`](TimeTransformedBuilder::start) with the physical
/// initial data; the result is an [`Adaptive`] integrator.
///
/// ```
/// use lagrangian_runtime::time_transform::{RadiusPower, TimeTransformed};
/// use lagrangian_runtime::Galerkin;
/// use lagrangian_runtime::{Lagrangian, Scalar, Separability};
///
/// /// Kepler in the plane, μ = 1 (as `#[lagrangian]` would declare it).
/// struct Kepler;
/// impl Lagrangian<2> for Kepler {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 2] = [false; 2];
///     const SEPARABILITY: Separability = Separability::ConstantMass;
///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
///         (v[0] * v[0] + v[1] * v[1]) * 0.5 + (q[0] * q[0] + q[1] * q[1]).sqrt().recip()
///     }
/// }
///
/// let e: f64 = 0.9;
/// let (q0, v0) = ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()]);
/// // dt/ds = r^{3/2}: steps in t shrink near the pericentre.
/// let mut sim = TimeTransformed::new(Kepler, RadiusPower::new([0, 1], 1.5).unwrap())
///     .galerkin(Galerkin::<2, 2>::gauss(), 0.1)
///     .start::<3>(0.0, q0, v0)?;
/// let e0 = sim.energy()?;
/// sim.run_until(2.0 * std::f64::consts::PI, |_| {})?;
/// assert!((sim.state().q[0] - (1.0 - e)).abs() < 1e-4);
/// assert!(((sim.energy()? - e0) / e0).abs() < 1e-4);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct TimeTransformed<Sys, G, const N: usize> {
    system: Arc<Sys>,
    density: Arc<G>,
    penalty: f64,
    /// The last density value seen that was not finite and positive; the
    /// step that met it fails (the action is NaN there).
    invalid: Cell<Option<f64>>,
}

impl<Sys, G, const N: usize> Clone for TimeTransformed<Sys, G, N> {
    fn clone(&self) -> Self {
        Self {
            system: Arc::clone(&self.system),
            density: Arc::clone(&self.density),
            penalty: self.penalty,
            invalid: self.invalid.clone(),
        }
    }
}

impl<Sys: core::fmt::Debug, G: core::fmt::Debug, const N: usize> core::fmt::Debug for TimeTransformed<Sys, G, N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("TimeTransformed")
            .field("system", &self.system)
            .field("density", &self.density)
            .field("penalty", &self.penalty)
            .finish()
    }
}

impl<Sys: Lagrangian<N>, G: StepDensity<N>, const N: usize> TimeTransformed<Sys, G, N> {
    /// The transformed system of `system` with step density `density`.
    pub fn new(system: Sys, density: G) -> Self {
        Self { system: Arc::new(system), density: Arc::new(density), penalty: 0.0, invalid: Cell::new(None) }
    }

    /// The physical system.
    pub fn system(&self) -> &Sys {
        &self.system
    }

    /// The step density.
    pub fn density_monitor(&self) -> &G {
        &self.density
    }

    /// The constant `c` of the `t'` term (0 until [`start`](TimeTransformedBuilder::start) sets it).
    pub fn penalty(&self) -> f64 {
        self.penalty
    }

    /// The transformed system with the constant `c` of the `t'` term set,
    /// for integrating it with an integrator of your own (the driver
    /// [`Adaptive`] sets it in [`start`](TimeTransformedBuilder::start)). Start it at `x = (q0, t0)` with
    /// `x' = (g0 v0, g0)`, `g0 = g(t0, q0)`; `t` is then its last coordinate.
    /// `None` unless `c` is finite and positive.
    pub fn with_penalty(mut self, c: f64) -> Option<Self> {
        (c.is_finite() && c > 0.0).then(|| {
            self.penalty = c;
            self
        })
    }

    /// `g(t, q)` on any scalar: `f64`, [`DoubleDouble`]
    /// or a dual number.
    pub fn density<D: Scalar>(&self, t: D, q: &[D; N]) -> D {
        self.density.density(&*self.system, t, q)
    }

    /// Configures an adaptive integrator with a one-point discrete
    /// Lagrangian (midpoint, trapezoid, α-β) and the step `sigma` in `s`.
    /// The type of `sigma` is the real type of the run, as for
    /// [`Integrator::new`]: `f64`, or [`DoubleDouble`]
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

    /// `g` on any scalar; NaN (and the value recorded) where it is not
    /// finite and positive, so that the step fails with a typed error.
    #[inline(always)]
    fn checked_density<D: Scalar>(&self, t: D, q: &[D; N]) -> D {
        let g = self.density.density(&*self.system, t, q);
        let re = g.re();
        if re.is_finite() && re > 0.0 {
            g
        } else {
            self.invalid.set(Some(re));
            D::from(f64::NAN)
        }
    }
}

impl<Sys: Lagrangian<N> + StepDensity<N>, const N: usize> TimeTransformed<Sys, Sys, N> {
    /// The transformed system of a system that is its own step density: one
    /// with `fn step_density(&self, [t: f64,] q: [f64; N]) -> f64` in its
    /// `#[lagrangian]` block (the macro implements [`StepDensity<N>`] for it
    /// from that method, rewritten for dual numbers like `lagrangian`). One
    /// value serves both roles; no copy of the system is made. (The example
    /// needs the facade crate's macro; the facade's test
    /// `step_density_in_the_block_equals_the_runtime_monitor` runs it.)
    ///
    /// ```ignore
    /// use lagrangian::prelude::*;
    ///
    /// #[derive(Debug)]
    /// struct Kepler;
    ///
    /// #[lagrangian]
    /// impl Kepler {
    ///     fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
    ///         0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    ///     }
    ///     /// `dt/ds = r^{3/2}`.
    ///     fn step_density(&self, q: [f64; 2]) -> f64 {
    ///         (q[0] * q[0] + q[1] * q[1]).powf(0.75)
    ///     }
    /// }
    ///
    /// let mut sim = TimeTransformed::with_own_density(Kepler)
    ///     .rule(Midpoint, 0.02)
    ///     .start::<3>(0.0, [0.1, 0.0], [0.0, 19f64.sqrt()])?;
    /// sim.run_until(1.0, |_| {})?;
    /// assert_eq!(sim.state().t, 1.0);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn with_own_density(system: Sys) -> Self {
        let shared = Arc::new(system);
        TimeTransformed { system: Arc::clone(&shared), density: shared, penalty: 0.0, invalid: Cell::new(None) }
    }
}

/// `CYCLIC` of the transformed system: no position is claimed cyclic (`g`
/// may depend on any), `t` is when neither `L` nor `g` depends on it.
const fn extended_cyclic<const M: usize>(time_cyclic: bool) -> [bool; M] {
    let mut out = [false; M];
    out[M - 1] = time_cyclic;
    out
}

impl<Sys, G, const N: usize, const M: usize> Lagrangian<M> for TimeTransformed<Sys, G, N>
where
    Sys: Lagrangian<N>,
    G: StepDensity<N>,
{
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; M] = extended_cyclic::<M>(Sys::AUTONOMOUS && !G::TIME_DEPENDENT);
    const DISCONTINUOUS: bool = Sys::DISCONTINUOUS;
    const HAS_FORCE: bool = Sys::HAS_FORCE || Sys::HAS_DISSIPATION;

    #[inline(always)]
    fn lagrangian<D: Scalar>(&self, _s: D, x: [D; M], w: [D; M]) -> D {
        const { assert!(M == N + 1, "the time-transformed system has N + 1 coordinates (q, t)") };
        let (t, q) = split::<D, N, M>(&x);
        let tp = w[N];
        let g = self.checked_density(t, &q);
        let inv = tp.recip();
        let mut v = [D::zero(); N];
        for i in 0..N {
            v[i] = w[i] * inv;
        }
        let d = tp - g;
        tp * self.system.lagrangian(t, q, v) + d * d / (g * (2.0 * self.penalty))
    }

    /// Lagrange–d'Alembert in `s`: the virtual work `∫ F·(δq − v δt) dt`
    /// of the physical force is `∫ (t'F·δq − F·q' δt) ds`.
    #[inline(always)]
    fn force<D: Scalar>(&self, _s: D, x: [D; M], w: [D; M]) -> [D; M] {
        let (t, q) = split::<D, N, M>(&x);
        let tp = w[N];
        let inv = tp.recip();
        let mut v = [D::zero(); N];
        for i in 0..N {
            v[i] = w[i] * inv;
        }
        let f = generalized_force(&*self.system, t, q, v);
        let mut out = [D::zero(); M];
        let mut power = D::zero();
        for i in 0..N {
            out[i] = f[i] * tp;
            power += f[i] * w[i];
        }
        out[N] = -power;
        out
    }
}

/// `(t, q)` from `x = (q, t)`.
#[inline(always)]
fn split<D: Scalar, const N: usize, const M: usize>(x: &[D; M]) -> (D, [D; N]) {
    let mut q = [D::zero(); N];
    q.copy_from_slice(&x[..N]);
    (x[N], q)
}

/// An integrator in `s` of a [`TimeTransformed`] system, as [`Adaptive`]
/// drives it: the [`Integrator`] with any method, in the real type `T`
/// (`f64` or [`DoubleDouble`]).
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
    fn set_s_step_size(&mut self, sigma: T) -> Result<(), Error<M, T>>;
    /// One step in `s`; on failure nothing changes.
    fn s_step(&mut self) -> Result<(), Error<M, T>>;
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
    fn set_s_step_size(&mut self, sigma: f64) -> Result<(), Error<M>> {
        self.set_step_size(sigma)
    }
    fn s_step(&mut self) -> Result<(), Error<M>> {
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
    fn set_s_step_size(&mut self, sigma: DoubleDouble) -> Result<(), Error<M, DoubleDouble>> {
        self.set_step_size(sigma)
    }
    fn s_step(&mut self) -> Result<(), Error<M, DoubleDouble>> {
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
    ) -> Result<Self::Stepper, Error<M, T>>;
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
    ) -> Result<Self::Stepper, Error<M, T>> {
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
    ) -> Result<Self::Stepper, Error<M, T>> {
        GalerkinIntegrator::new(system, self, sigma).newton(newton).start(T::zero(), x0, w0)
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
fn default_rtol<T: Real>() -> f64 {
    if T::EPSILON < f64::EPSILON { 2.0 * T::EPSILON } else { DEFAULT_RTOL }
}

/// `true` for a real type wider than `f64`, whose readouts refine the `f64`
/// inverse Legendre transform in that type.
fn wider_than_f64<T: Real>() -> bool {
    T::EPSILON < f64::EPSILON
}

/// Configuration of an [`Adaptive`] integrator before its initial state;
/// `T` is the real type of the run (that of the step `σ`).
#[derive(Clone, Debug)]
pub struct TimeTransformedBuilder<Sys, G, K, const N: usize, T = f64> {
    system: TimeTransformed<Sys, G, N>,
    method: K,
    sigma: T,
    newton: NewtonOptions,
    penalty: Option<f64>,
    min_time_step: Option<T>,
}

impl<Sys: Lagrangian<N>, G: StepDensity<N>, K, const N: usize, T: Real> TimeTransformedBuilder<Sys, G, K, N, T> {
    fn new(system: TimeTransformed<Sys, G, N>, method: K, sigma: T) -> Self {
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
    /// `M` is `N + 1` (checked at compile time): `.start::<3>(…)` for a
    /// planar problem.
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
    ) -> Result<Adaptive<K::Stepper, Sys, G, N, M, T>, Error<N, T>>
    where
        K: SMethod<Sys, G, N, M, T>,
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
            return Err(Error::InvalidDensity { state, value: g0.to_f64() });
        }
        // The constant c is part of the method, not of the state: f64 in every type.
        let sys = &*self.system.system;
        let (t0f, q0f, v0f) = (t0.to_f64(), q0.map(|x| x.to_f64()), v0.map(|x| x.to_f64()));
        let (l0, e0) = (sys.lagrangian_value(t0f, q0f, v0f), sys.energy(t0f, q0f, v0f));
        let pv = e0 + l0;
        let scale = pv.abs() + l0.abs() + e0.abs();
        let penalty = match self.penalty {
            Some(c) if c.is_finite() && c > 0.0 => c,
            Some(_) => {
                return Err(Error::InvalidSetting { reason: "the penalty must be finite and positive" });
            }
            None if scale.is_finite() && scale > 0.0 => 1.0 / scale,
            None => 1.0,
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
        let inner = self
            .method
            .start_s(system, self.sigma, self.newton, x0, w0)
            .map_err(|e| e.map_state(|x| physical::<T, N, M>(&x)))?;
        let mut adaptive =
            Adaptive { inner, marker: PhantomData, floor, landed: None, v_guess: v0, last_dt: None, rate: None };
        adaptive.rate = adaptive.rate_at(&adaptive.inner.extended_state(), v0);
        Ok(adaptive)
    }
}

/// An adaptive integrator in physical time built from a fixed-step
/// integrator `I` in `s` of the [`TimeTransformed`] system (see the
/// [module](self)); `N` physical degrees of freedom, `M = N + 1`, real type
/// `T` (`f64`, or [`DoubleDouble`] when the step `σ`
/// is one).
///
/// ```
/// use lagrangian_runtime::time_transform::{RadiusPower, TimeTransformed};
/// use lagrangian_runtime::{Lagrangian, Midpoint, Scalar};
///
/// /// Kepler in the plane, μ = 1.
/// struct Kepler;
/// impl Lagrangian<2> for Kepler {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 2] = [false; 2];
///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
///         (v[0] * v[0] + v[1] * v[1]) * 0.5 + (q[0] * q[0] + q[1] * q[1]).sqrt().recip()
///     }
/// }
///
/// let e = 0.9;
/// let g = RadiusPower::new([0, 1], 1.5).unwrap(); // dt/ds = r^{3/2}
/// let mut sim = TimeTransformed::new(Kepler, g)
///     .rule(Midpoint, 0.02)
///     .start::<3>(0.0, [1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()])?;
/// let e0 = sim.energy()?;
/// sim.run_until(2.0 * std::f64::consts::PI, |_| {})?; // one orbit
/// assert_eq!(sim.state().t, 2.0 * std::f64::consts::PI);
/// assert!((sim.state().q[0] - (1.0 - e)).abs() < 1e-2);
/// assert!(((sim.energy()? - e0) / e0).abs() < 1e-3);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// The same in double-double: the step's type sets the run's.
///
/// ```
/// # use lagrangian_runtime::time_transform::{RadiusPower, TimeTransformed};
/// # use lagrangian_runtime::{DoubleDouble, Galerkin, Lagrangian, Scalar};
/// # use lagrangian_runtime::num_dual::DualNum;
/// # struct Kepler;
/// # impl Lagrangian<2> for Kepler {
/// #     const AUTONOMOUS: bool = true;
/// #     const CYCLIC: [bool; 2] = [false; 2];
/// #     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
/// #         (v[0] * v[0] + v[1] * v[1]) * 0.5 + (q[0] * q[0] + q[1] * q[1]).sqrt().recip()
/// #     }
/// # }
/// type Dd = DoubleDouble;
/// let e = Dd::from(0.5);
/// let (q0, v0) = ([Dd::from(1.0) - e, Dd::from(0.0)], [Dd::from(0.0), ((Dd::from(1.0) + e) / (Dd::from(1.0) - e)).sqrt()]);
/// let mut sim = TimeTransformed::new(Kepler, RadiusPower::new([0, 1], 1.5).unwrap())
///     .galerkin(Galerkin::<4, 4, Dd>::gauss(), Dd::from(0.1))
///     .start::<3>(Dd::from(0.0), q0, v0)?;
/// let e0 = sim.energy()?;
/// sim.run_until(Dd::from(1.0), |_| {})?;
/// assert_eq!(sim.state().t, Dd::from(1.0));
/// assert!(((sim.energy()? - e0) / e0).abs().to_f64() < 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct Adaptive<I, Sys, G, const N: usize, const M: usize, T = f64> {
    inner: I,
    marker: PhantomData<fn() -> (Sys, G)>,
    floor: T,
    /// `(step, t_end)` after landing on `t_end`: the published time is
    /// `t_end` exactly while the integrator stays at that node.
    landed: Option<(u64, T)>,
    v_guess: [T; N],
    last_dt: Option<T>,
    /// `t'/g = 1 + c·u` at the current node (`None` where its velocity
    /// cannot be found): the reference of the lost-orbit check.
    rate: Option<f64>,
}

impl<I: Clone, Sys, G, const N: usize, const M: usize, T: Copy> Clone for Adaptive<I, Sys, G, N, M, T> {
    fn clone(&self) -> Self {
        Self { inner: self.inner.clone(), marker: PhantomData, ..*self }
    }
}

/// The physical state in an extended one.
fn physical<T: Real, const N: usize, const M: usize>(x: &State<M, T>) -> State<N, T> {
    let mut q = [T::zero(); N];
    let mut p = [T::zero(); N];
    q.copy_from_slice(&x.q[..N]);
    p.copy_from_slice(&x.p[..N]);
    State { step: x.step, t: x.q[N], q, p }
}

/// `a > b` for reals, decided on the difference (exact for `f64`, and not
/// blind below an `f64` ulp in a wider type).
#[inline]
fn above<T: Real>(a: T, b: T) -> bool {
    (a - b).to_f64() > 0.0
}

/// The velocity `v` with `∂L/∂v(t, q, v) = p`: the runtime's inverse
/// Legendre transform in `f64`, then, in a wider type, Newton steps in `T`
/// from that solution (quadratic convergence: two or three suffice).
fn velocity_in<Sys, T, const N: usize>(
    system: &Sys,
    (t, q, p): (T, [T; N], [T; N]),
    guess: [T; N],
) -> Result<[T; N], LegendreFailure>
where
    Sys: Lagrangian<N>,
    T: Real,
{
    let f = |x: [T; N]| x.map(|y| y.to_f64());
    let v = if const { N > crate::Derivatives::FORWARD_MAX_N } {
        // The tape's banded or dense solves: the forward-mode Hessian's
        // `N × N` values do not fit a thread's stack at large `N`.
        crate::integrator::reverse_mode_velocity(system, t.to_f64(), &f(q), &f(p), &f(guess))
            .map_err(|(iterations, residual_norm)| LegendreFailure { iterations, residual_norm })?
    } else {
        system.velocity(t.to_f64(), f(q), f(p), f(guess))?
    };
    let mut v = v.map(T::from);
    if !wider_than_f64::<T>() {
        return Ok(v);
    }
    let tol = 4.0 * T::EPSILON;
    for iterations in 1..=8 {
        let (momentum, hessian) = momentum_and_hessian(system, t, q, v);
        let residual: [T; N] = core::array::from_fn(|i| momentum[i] - p[i]);
        // As in `f64`: a singular Hessian or a value that is not finite has no residual to report.
        let failure = LegendreFailure { iterations, residual_norm: f64::INFINITY };
        let inverse = splitting::invert(&hessian).ok_or(failure)?;
        let mut size = 0.0f64;
        let mut scale = 0.0f64;
        for i in 0..N {
            let mut d = T::zero();
            for k in 0..N {
                d += inverse[i][k] * residual[k];
            }
            v[i] -= d;
            size = size.max(d.to_f64().abs());
            scale = scale.max(v[i].to_f64().abs());
        }
        if !all_finite(&v) {
            return Err(failure);
        }
        if size <= tol * scale.max(1.0) {
            return Ok(v);
        }
    }
    let (momentum, _) = momentum_and_hessian(system, t, q, v);
    let residual_norm = (0..N).fold(0.0f64, |m, i| m.max((momentum[i] - p[i]).to_f64().abs()));
    Err(LegendreFailure { iterations: 8, residual_norm })
}

/// `∂L/∂v` and `∂²L/∂v²` in `T` by scalar hyper-duals (a readout, not a
/// step: `N(N+1)/2` evaluations are cheap enough).
fn momentum_and_hessian<Sys, T, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> ([T; N], [[T; N]; N])
where
    Sys: Lagrangian<N>,
    T: Real,
{
    let mut momentum = [T::zero(); N];
    let mut hessian = [[T::zero(); N]; N];
    let qh = q.map(HyperDual::from_re);
    for i in 0..N {
        for j in i..N {
            let mut vh = v.map(HyperDual::from_re);
            vh[i].eps1 = T::one();
            vh[j].eps2 = T::one();
            let l = system.lagrangian(HyperDual::from_re(t), qh, vh);
            if i == j {
                momentum[i] = l.eps1;
            }
            hessian[i][j] = l.eps1eps2;
            hessian[j][i] = l.eps1eps2;
        }
    }
    (momentum, hessian)
}

/// `E_L = v·∂L/∂v − L` in `T` (the runtime's `f64` energy in `f64`).
fn energy_in<Sys: Lagrangian<N>, T: Real, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> T {
    if !wider_than_f64::<T>() {
        return T::from(system.energy(t.to_f64(), q.map(|x| x.to_f64()), v.map(|x| x.to_f64())));
    }
    let (momentum, _) = momentum_and_hessian(system, t, q, v);
    let mut e = -system.lagrangian(t, q, v);
    for i in 0..N {
        e += v[i] * momentum[i];
    }
    e
}

impl<I, Sys, G, T, const N: usize, const M: usize> Adaptive<I, Sys, G, N, M, T>
where
    I: SStepper<M, T, System = TimeTransformed<Sys, G, N>>,
    Sys: Lagrangian<N>,
    G: StepDensity<N>,
    T: Real,
{
    /// The physical state `(k, t_k, q_k, p_k)`; `k` counts steps in `s`.
    pub fn state(&self) -> State<N, T> {
        let x = self.inner.extended_state();
        let mut s = physical::<T, N, M>(&x);
        if let Some((step, t)) = self.landed
            && step == x.step
        {
            s.t = t;
        }
        s
    }

    /// The state in `s`: `s_k = k σ` as time, `x = (q, t)`, momenta `(p, p_t)`.
    pub fn extended_state(&self) -> State<M, T> {
        self.inner.extended_state()
    }

    /// `p_t = −E + u`, the momentum of time: conserved to round-off for an
    /// autonomous `L` without forces and a `g` without `t`.
    pub fn time_momentum(&self) -> T {
        self.inner.extended_state().p[N]
    }

    /// The integrator in `s`.
    pub fn inner(&self) -> &I {
        &self.inner
    }

    /// The physical system.
    pub fn system(&self) -> &Sys {
        self.inner.transformed().system()
    }

    /// The step `σ` in `s`.
    pub fn step_size(&self) -> T {
        self.inner.s_step_size()
    }

    /// Work counters of the steps in `s` (landing trials not counted as steps).
    pub fn stats(&self) -> Stats {
        self.inner.s_stats()
    }

    /// The physical time the last step advanced, `None` before the first.
    pub fn last_time_step(&self) -> Option<T> {
        self.last_dt
    }

    /// The smallest time step allowed.
    pub fn min_time_step(&self) -> T {
        self.floor
    }

    /// `g` at the current state.
    pub fn density(&self) -> T {
        let s = self.state();
        self.inner.transformed().density(s.t, &s.q)
    }

    /// The tangent map of the last step in the extended phase space
    /// `(q, t, p, p_t)`: symplectic; `None` before the first step, with
    /// forces, in a real type other than `f64`, and above
    /// [`Derivatives::FORWARD_MAX_N`](crate::Derivatives::FORWARD_MAX_N)
    /// extended coordinates `M`. Boxed: its `4M²` entries inline would not
    /// fit a thread's stack at large `M`.
    pub fn last_tangent_map(&self) -> Option<Box<TangentMap<M>>> {
        if const { M > crate::Derivatives::FORWARD_MAX_N } {
            return None;
        }
        self.inner.s_tangent_map()
    }

    /// The physical velocity `v` with `∂L/∂v(t, q, v) = p`: Newton in `f64`,
    /// refined in `T` when `T` is wider.
    pub fn velocity(&self) -> Result<[T; N], Error<N, T>> {
        let s = self.state();
        velocity_in(self.system(), (s.t, s.q, s.p), self.v_guess).map_err(|f| Error::InverseLegendre {
            state: s,
            iterations: f.iterations,
            residual_norm: f.residual_norm,
        })
    }

    /// The physical energy `E_L(t, q, v)` at the current state, in `T`.
    pub fn energy(&self) -> Result<T, Error<N, T>> {
        let v = self.velocity()?;
        let s = self.state();
        Ok(energy_in(self.system(), s.t, s.q, v))
    }

    /// Sets the step in `s` for the following steps.
    pub fn set_step_size(&mut self, sigma: T) -> Result<(), Error<N, T>> {
        self.inner.set_s_step_size(sigma).map_err(|e| e.map_state(|x| physical::<T, N, M>(&x)))
    }

    /// One step of `σ` in `s`. Refused, with the state kept, where `g` is
    /// not finite and positive inside the step or at its end, where the
    /// step advances time by less than [`min_time_step`](Self::min_time_step),
    /// and where it has lost the orbit ([`Error::OrbitLost`]: the rate
    /// `t'/g = 1 + c·u`, `u = p_t + E`, changed by more than a factor 2,
    /// which a spurious root of the step's Newton solve does).
    pub fn step(&mut self) -> Result<State<N, T>, Error<N, T>> {
        let before = self.inner.clone();
        self.try_step(before)
    }

    fn try_step(&mut self, before: I) -> Result<State<N, T>, Error<N, T>> {
        let start = self.state();
        self.inner.transformed().invalid.set(None);
        if let Err(e) = self.inner.s_step() {
            // Read the flag before restoring: the saved copy has its own.
            let invalid = self.inner.transformed().invalid.get();
            self.inner = before;
            // The step in `s` starts from the state the driver reports (its
            // time is the landed one after `run_until`).
            return Err(match invalid {
                Some(value) => Error::InvalidDensity { state: start, value },
                None => e.map_state(|_| start),
            });
        }
        let t0 = self.inner_time(&before);
        match self.verify(&self.inner, t0, &start, Some(self.floor)) {
            Ok((end, dt, rate)) => {
                self.after_step(&start, &end, dt, rate);
                Ok(self.state())
            }
            Err(e) => {
                self.inner = before;
                Err(e)
            }
        }
    }

    /// Checks a computed step from the current node (time `t0`, reported
    /// state `start`) to `candidate`'s node: the density there, the time it
    /// advanced (against `floor`, if given), and the rate `t'/g` against the
    /// current node's. Returns the end state, the time step and the rate at
    /// the end.
    #[allow(clippy::type_complexity)]
    fn verify(
        &self,
        candidate: &I,
        t0: T,
        start: &State<N, T>,
        floor: Option<T>,
    ) -> Result<(State<N, T>, T, Option<f64>), Error<N, T>> {
        let x = candidate.extended_state();
        let end = physical::<T, N, M>(&x);
        let g1 = candidate.transformed().density(end.t, &end.q);
        let dt = end.t - t0;
        if !(g1.is_finite() && g1.to_f64() > 0.0) {
            return Err(Error::InvalidDensity { state: *start, value: g1.to_f64() });
        }
        if let Some(floor) = floor {
            // NaN fails too.
            let margin = (dt - floor).to_f64();
            if margin.is_nan() || margin < 0.0 {
                return Err(Error::TimeStepCollapsed { state: *start, dt: dt.to_f64(), floor: floor.to_f64() });
            }
        }
        let guess: [T; N] = core::array::from_fn(|i| (end.q[i] - start.q[i]) / dt);
        let rate = self.rate_at(&x, guess);
        if let (Some(r0), Some(r1)) = (self.rate, rate) {
            // NaN fails too.
            let factor = r1 / r0;
            if !(0.5..=2.0).contains(&factor) {
                return Err(Error::OrbitLost { state: *start, factor });
            }
        }
        Ok((end, dt, rate))
    }

    /// The rate `t'/g = 1 + c·u` at the node `x` in `s`, with
    /// `u = p_t + E(t, q, v)` (`(t'/g − 1)/c` by the Legendre transform of
    /// the penalty term); `None` where the velocity cannot be found from
    /// `guess`. The exact flow keeps `u` at its initial value (0) for any
    /// `L`, time-dependent or forced: the transformed Hamiltonian
    /// `g u + ½ c g u²` is conserved in `s`, and a force changes `p_t` and
    /// `E` by opposite amounts. A step keeps it to its energy error, so a
    /// change by a factor 2 is a step that has not followed the flow. Computed
    /// in `f64` in every real type: only its size matters.
    fn rate_at(&self, x: &State<M, T>, guess: [T; N]) -> Option<f64> {
        let s = physical::<T, N, M>(x);
        let f = |a: [T; N]| a.map(|y| y.to_f64());
        let system = self.system();
        let (t, q) = (s.t.to_f64(), f(s.q));
        let v = if const { N > crate::Derivatives::FORWARD_MAX_N } {
            // As in the driver's velocity: the forward-mode Hessian's
            // `N × N` values do not fit a thread's stack at large `N`.
            crate::integrator::reverse_mode_velocity(system, t, &q, &f(s.p), &f(guess)).ok()?
        } else {
            system.velocity(t, q, f(s.p), f(guess)).ok()?
        };
        let u = x.p[N].to_f64() + system.energy(t, q, v);
        Some(1.0 + self.inner.transformed().penalty * u)
    }

    fn inner_time(&self, i: &I) -> T {
        i.extended_state().q[N]
    }

    fn after_step(&mut self, start: &State<N, T>, end: &State<N, T>, dt: T, rate: Option<f64>) {
        self.landed = None;
        self.last_dt = Some(dt);
        self.rate = rate;
        for i in 0..N {
            self.v_guess[i] = (end.q[i] - start.q[i]) / dt;
        }
    }

    /// Takes `n` steps in `s`, calling `observe` after each.
    pub fn run(&mut self, n: usize, mut observe: impl FnMut(&Self)) -> Result<(), Error<N, T>> {
        for _ in 0..n {
            self.step()?;
            observe(self);
        }
        Ok(())
    }

    /// Steps until the physical time `t_end` and stops there: the step that
    /// would pass it is replaced by a partial step in `s` whose size is
    /// solved (secant on the bracket `(0, σ)`) so that it ends on `t_end`
    /// to within a few units of `T`'s precision, and the state then reports
    /// `t = t_end` exactly (the coordinate `t` of the state in `s` keeps that
    /// last unit). The step `σ` is unchanged afterwards. A target equal to
    /// the current time is a no-op.
    pub fn run_until(&mut self, t_end: T, mut observe: impl FnMut(&Self)) -> Result<(), Error<N, T>> {
        let now = self.state();
        if !t_end.is_finite() || above(now.t, t_end) {
            return Err(Error::InvalidTarget { target: t_end.to_f64(), state: now });
        }
        while above(t_end, self.state().t) {
            self.step_toward(t_end)?;
            observe(self);
        }
        Ok(())
    }

    /// One step of `σ` in `s`, or, when it would pass the physical time
    /// `t_end`, the partial step that ends on it (see
    /// [`run_until`](Self::run_until)); a no-op at or beyond `t_end`.
    pub(crate) fn step_toward(&mut self, t_end: T) -> Result<(), Error<N, T>> {
        let start = self.state();
        if !above(t_end, start.t) {
            return Ok(());
        }
        let before = self.inner.clone();
        self.try_step(before.clone())?;
        let t = self.inner_time(&self.inner);
        if above(t, t_end) {
            self.inner = before;
            self.land(t_end, t, &start)?;
        }
        Ok(())
    }

    /// The partial step in `s` from the current state that ends on `t_end`,
    /// given that the full step ends at `t_over > t_end`.
    fn land(&mut self, t_end: T, t_over: T, start: &State<N, T>) -> Result<(), Error<N, T>> {
        let sigma = self.inner.s_step_size();
        let t0 = self.inner_time(&self.inner);
        let tol = 4.0 * T::EPSILON * t_end.to_f64().abs().max(t0.to_f64().abs()).max(f64::MIN_POSITIVE);
        if (t_end - t0).to_f64() <= tol {
            self.landed = Some((self.inner.extended_state().step, t_end));
            return Ok(());
        }
        // Illinois-modified regula falsi on f(σ') = t(σ') − t_end over (0, σ).
        let (mut lo, mut f_lo) = (T::zero(), t0 - t_end);
        let (mut hi, mut f_hi) = (sigma, t_over - t_end);
        let mut side = 0i8;
        let mut best: Option<(T, I, Option<f64>)> = None;
        for _ in 0..60 {
            let mut s = hi - f_hi * (hi - lo) / (f_hi - f_lo);
            if !(above(s, lo) && above(hi, s)) {
                s = (lo + hi) * 0.5;
            }
            let mut trial = self.inner.clone();
            let verified = if trial.set_s_step_size(s).is_err() || trial.s_step().is_err() {
                None
            } else {
                // No floor: a landing step may be arbitrarily short.
                self.verify(&trial, t0, start, None).ok()
            };
            let Some((_, _, rate)) = verified else {
                // Unsolvable or refused trial: move the upper end down and try again.
                hi = s;
                continue;
            };
            let f = self.inner_time(&trial) - t_end;
            if best.as_ref().is_none_or(|(b, ..)| f.to_f64().abs() < b.to_f64().abs()) {
                best = Some((f, trial.clone(), rate));
            }
            if f.to_f64().abs() <= tol {
                break;
            }
            if f.to_f64() > 0.0 {
                (hi, f_hi) = (s, f);
                if side == 1 {
                    f_lo *= 0.5;
                }
                side = 1;
            } else {
                (lo, f_lo) = (s, f);
                if side == -1 {
                    f_hi *= 0.5;
                }
                side = -1;
            }
        }
        match best {
            Some((f, mut trial, rate)) if f.to_f64().abs() <= 64.0 * tol => {
                let _ = trial.set_s_step_size(sigma);
                let end = physical::<T, N, M>(&trial.extended_state());
                self.inner = trial;
                self.after_step(start, &end, end.t - t0, rate);
                self.landed = Some((end.step, t_end));
                Ok(())
            }
            best => Err(Error::Landing {
                target: t_end.to_f64(),
                reached: best.map_or(t0.to_f64(), |(f, ..)| (t_end + f).to_f64()),
            }),
        }
    }
}
