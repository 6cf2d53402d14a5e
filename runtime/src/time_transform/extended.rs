//! The transformed system: the Lagrangian `L̃(x, x')` in `s` of the extended
//! coordinates `x = (q, t)`, which every discrete Lagrangian of the runtime
//! integrates unchanged.

use core::cell::Cell;
use std::sync::Arc;

use crate::system::{Lagrangian, Scalar, generalized_force};

use super::density::StepDensity;

/// The transformed system: `L̃(x, x') = t' L(t, q, q'/t') + (t' − g)²/(2cg)`
/// in the independent variable `s`, with `x = (q, t)` (see the
/// [module](super)). Implements [`Lagrangian<M>`](Lagrangian) for
/// `M = N + 1` (checked at compile time).
///
/// Build it with [`new`](Self::new) (a system and a [`StepDensity`]) or
/// [`with_own_density`](Self::with_own_density), choose the method in `s`
/// with [`rule`](Self::rule) or [`galerkin`](Self::galerkin) and the step
/// `σ`, and [`start`](super::TimeTransformedBuilder::start) with the physical
/// initial data; the result is an [`Adaptive`](super::Adaptive) integrator.
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
///     .start(0.0, q0, v0)?;
/// let e0 = sim.energy()?;
/// sim.run_until(2.0 * std::f64::consts::PI, |_| {})?;
/// assert!((sim.state().q[0] - (1.0 - e)).abs() < 1e-4);
/// assert!(((sim.energy()? - e0) / e0).abs() < 1e-4);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct TimeTransformed<Sys, G, const N: usize> {
    pub(super) system: Arc<Sys>,
    pub(super) density: Arc<G>,
    pub(super) penalty: f64,
    /// The last density value seen that was not finite and positive; the
    /// step that met it fails (the action is NaN there).
    pub(super) invalid: Cell<Option<f64>>,
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

    /// The constant `c` of the `t'` term (0 until [`start`](super::TimeTransformedBuilder::start) sets it).
    pub fn penalty(&self) -> f64 {
        self.penalty
    }

    /// The transformed system with the constant `c` of the `t'` term set,
    /// for integrating it with an integrator of your own (the driver
    /// [`Adaptive`](super::Adaptive) sets it in [`start`](super::TimeTransformedBuilder::start)). Start it at `x = (q0, t0)` with
    /// `x' = (g0 v0, g0)`, `g0 = g(t0, q0)`; `t` is then its last coordinate.
    /// `None` unless `c` is finite and positive.
    pub fn with_penalty(mut self, c: f64) -> Option<Self> {
        (c.is_finite() && c > 0.0).then(|| {
            self.penalty = c;
            self
        })
    }

    /// `g(t, q)` on any scalar: `f64`, [`DoubleDouble`](crate::DoubleDouble)
    /// or a dual number.
    pub fn density<D: Scalar>(&self, t: D, q: &[D; N]) -> D {
        self.density.density(&*self.system, t, q)
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
    ///     .start(0.0, [0.1, 0.0], [0.0, 19f64.sqrt()])?;
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
pub(super) const fn extended_cyclic<const M: usize>(time_cyclic: bool) -> [bool; M] {
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
    const ENERGY_STEPS: bool = false;

    #[inline(always)]
    fn lagrangian<D: Scalar>(&self, _s: D, x: [D; M], w: [D; M]) -> D {
        const { assert!(M == N + 1, "the time-transformed system has N + 1 coordinates (q, t)") };
        let (t, q) = split::<D, N, M>(&x);
        let g = self.checked_density(t, &q);
        extended_lagrangian(&w, g, D::from(self.penalty), |v| self.system.lagrangian(t, q, v))
    }

    /// Lagrange–d'Alembert in `s`: the virtual work `∫ F·(δq − v δt) dt`
    /// of the physical force is `∫ (t'F·δq − F·q' δt) ds`.
    #[inline(always)]
    fn force<D: Scalar>(&self, _s: D, x: [D; M], w: [D; M]) -> [D; M] {
        let (t, q) = split::<D, N, M>(&x);
        extended_force(&w, |v| generalized_force(&*self.system, t, q, v))
    }
}

/// `L̃ = t' L(t, q, q'/t') + (t' − g)²/(2cg)` from the extended velocity
/// `w = (q', t')`, the density `g`, the constant `c` and the physical
/// Lagrangian `lagrangian` as a function of the velocity `v = q'/t'`.
#[inline(always)]
pub(crate) fn extended_lagrangian<D: Scalar, const N: usize, const M: usize>(
    w: &[D; M],
    g: D,
    c: D,
    lagrangian: impl FnOnce([D; N]) -> D,
) -> D {
    homogeneous(w, lagrangian) + penalty_term(w[N], g, c)
}

/// The term `(t' − g)²/(2cg)` of `L̃` that makes `t'` an ordinary velocity
/// (both sizes form it here, so that they agree to the bit).
#[inline(always)]
pub(crate) fn penalty_term<D: Scalar>(time_rate: D, g: D, c: D) -> D {
    let d = time_rate - g;
    d * d / (g * c * 2.0)
}

/// `t' L(t, q, q'/t')` from the extended velocity `w = (q', t')` and the
/// physical Lagrangian `lagrangian` as a function of `v = q'/t'`: the
/// Lagrangian of the parametrised motion `(q(s), t(s))`, homogeneous of
/// degree one in `w`. A one-point rule applied to it with step 1 is the
/// rule's step in `t` of size `t_{k+1} − t_k`.
#[inline(always)]
pub(crate) fn homogeneous<D: Scalar, const N: usize, const M: usize>(
    w: &[D; M],
    lagrangian: impl FnOnce([D; N]) -> D,
) -> D {
    let mut v = [D::zero(); N];
    let tp = physical_velocity(w, &mut v);
    tp * lagrangian(v)
}

/// `t'` of the extended velocity `w = (q', t')`, with `v = q'/t'` written
/// into `v` (`w` has one entry more than `v`): the slice form that both
/// sizes share.
#[inline(always)]
pub(crate) fn physical_velocity<D: Scalar>(w: &[D], v: &mut [D]) -> D {
    let n = v.len();
    let tp = w[n];
    let inv = tp.recip();
    for i in 0..n {
        v[i] = w[i] * inv;
    }
    tp
}

/// The extended force `(t' F, −F·q')` from the extended velocity and the
/// physical generalized force `force` as a function of `v = q'/t'`.
#[inline(always)]
pub(crate) fn extended_force<D: Scalar, const N: usize, const M: usize>(
    w: &[D; M],
    force: impl FnOnce([D; N]) -> [D; N],
) -> [D; M] {
    let mut v = [D::zero(); N];
    physical_velocity(w, &mut v);
    let f = force(v);
    let mut out = [D::zero(); M];
    extended_force_of(w, &f, &mut out);
    out
}

/// The extended force `(t' F, −F·q')` into `out` from the extended velocity
/// `w = (q', t')` and the physical generalized force `f` (one entry fewer):
/// the slice form that both sizes share.
#[inline(always)]
pub(crate) fn extended_force_of<D: Scalar>(w: &[D], f: &[D], out: &mut [D]) {
    let n = f.len();
    let tp = w[n];
    let mut power = D::zero();
    for i in 0..n {
        out[i] = f[i] * tp;
        power += f[i] * w[i];
    }
    out[n] = -power;
}

/// `(t, q)` from `x = (q, t)`.
#[inline(always)]
pub(crate) fn split<D: Scalar, const N: usize, const M: usize>(x: &[D; M]) -> (D, [D; N]) {
    let mut q = [D::zero(); N];
    q.copy_from_slice(&x[..N]);
    (x[N], q)
}
