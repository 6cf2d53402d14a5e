//! The driver: fixed steps in `s` read as adaptive steps in physical time,
//! with landing on requested times and the checks that keep the state.

use core::marker::PhantomData;

use num_dual::HyperDual;

use crate::error::{Error, Unplaced};
use crate::integrator::Stats;
use crate::mechanics::{DiscreteMechanics, LegendreFailure};
use crate::real::{Real, all_finite};
use crate::root::Bracket;
use crate::state::{PhasePoint, State};
use crate::symplectic::TangentMap;
use crate::system::Lagrangian;

use super::density::StepDensity;
use super::extended::TimeTransformed;
use super::stepper::SStepper;

/// An adaptive integrator in physical time built from a fixed-step
/// integrator `I` in `s` of the [`TimeTransformed`] system (see the
/// [module](super)); `N` physical degrees of freedom, `M = N + 1`, real type
/// `T` (`f64`, or [`DoubleDouble`](crate::DoubleDouble) when the step `σ`
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
///     .start(0.0, [1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()])?;
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
///     .start(Dd::from(0.0), q0, v0)?;
/// let e0 = sim.energy()?;
/// sim.run_until(Dd::from(1.0), |_| {})?;
/// assert_eq!(sim.state().t, Dd::from(1.0));
/// assert!(((sim.energy()? - e0) / e0).abs().to_f64() < 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct Adaptive<I, Sys, G, const N: usize, const M: usize, T = f64> {
    pub(super) inner: I,
    pub(super) marker: PhantomData<fn() -> (Sys, G)>,
    pub(super) floor: T,
    /// `(step, t_end)` after landing on `t_end`: the published time is
    /// `t_end` exactly while the integrator stays at that node.
    pub(super) landed: Option<(u64, T)>,
    pub(super) v_guess: [T; N],
    pub(super) last_dt: Option<T>,
    /// `t'/g = 1 + c·u` at the current node (`None` where its velocity
    /// cannot be found): the reference of the lost-orbit check.
    pub(super) rate: Option<f64>,
    /// The integrator as it was before the step being taken, put back where
    /// that step fails or passes the target: copied into in place
    /// (`clone_from`) before each step, so that a step allocates nothing.
    /// Fresh copies (two per step, a Galerkin rule's factored blocks among
    /// them) cost 4–5% more instructions with Galerkin s = 6 in `s` on
    /// Kepler in polar coordinates.
    pub(super) saved: I,
}

impl<I: Clone, Sys, G, const N: usize, const M: usize, T: Copy> Clone for Adaptive<I, Sys, G, N, M, T> {
    fn clone(&self) -> Self {
        Self { inner: self.inner.clone(), marker: PhantomData, saved: self.saved.clone(), ..*self }
    }
}

/// `true` for a real type wider than `f64`, whose readouts refine the `f64`
/// inverse Legendre transform in that type.
pub(super) fn wider_than_f64<T: Real>() -> bool {
    T::EPSILON < f64::EPSILON
}

/// The physical state of an extended [`PhasePoint`] (an error's state):
/// its last coordinate is the time.
pub(super) fn physical_point<T: Real>(mut x: PhasePoint<T>) -> PhasePoint<T> {
    if let Some(t) = x.q.pop() {
        x.t = t;
        x.p.truncate(x.q.len());
    }
    x
}

/// The physical state in an extended one.
pub(super) fn physical<T: Real, const N: usize, const M: usize>(x: &State<M, T>) -> State<N, T> {
    let mut q = [T::zero(); N];
    let mut p = [T::zero(); N];
    q.copy_from_slice(&x.q[..N]);
    p.copy_from_slice(&x.p[..N]);
    State { step: x.step, t: x.q[N], q, p }
}

/// `a > b` for reals, decided on the difference (exact for `f64`, and not
/// blind below an `f64` ulp in a wider type).
#[inline]
pub(super) fn above<T: Real>(a: T, b: T) -> bool {
    (a - b).to_f64() > 0.0
}

/// The velocity `v` with `∂L/∂v(t, q, v) = p`: the runtime's inverse
/// Legendre transform in `f64`, then, in a wider type, Newton steps in `T`
/// from that solution (quadratic convergence: two or three suffice).
pub(super) fn velocity_in<Sys, T, const N: usize>(
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
        let inverse = super::splitting::invert(&hessian).ok_or(failure)?;
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
pub(super) fn momentum_and_hessian<Sys, T, const N: usize>(
    system: &Sys,
    t: T,
    q: [T; N],
    v: [T; N],
) -> ([T; N], [[T; N]; N])
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
pub(super) fn energy_in<Sys: Lagrangian<N>, T: Real, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> T {
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

    /// Whether the current node is the end of a landing step of
    /// [`run_until`](Self::run_until), whose size in `s` was solved for its
    /// end time.
    pub(crate) fn landed_here(&self) -> bool {
        self.landed.is_some_and(|(step, _)| step == self.inner.extended_state().step)
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
    pub fn velocity(&self) -> Result<[T; N], Error<T>> {
        let s = self.state();
        velocity_in(self.system(), (s.t, s.q, s.p), self.v_guess).map_err(|f| Error::InverseLegendre {
            state: s.into(),
            iterations: f.iterations,
            residual_norm: f.residual_norm,
        })
    }

    /// The physical energy `E_L(t, q, v)` at the current state, in `T`.
    pub fn energy(&self) -> Result<T, Error<T>> {
        let v = self.velocity()?;
        let s = self.state();
        Ok(energy_in(self.system(), s.t, s.q, v))
    }

    /// Sets the step in `s` for the following steps.
    pub fn set_step_size(&mut self, sigma: T) -> Result<(), Error<T>> {
        self.inner.set_s_step_size(sigma).map_err(|e| e.map_state(physical_point))
    }

    /// One step of `σ` in `s`. Refused, with the state kept, where `g` is
    /// not finite and positive inside the step or at its end, where the
    /// step advances time by less than [`min_time_step`](Self::min_time_step),
    /// and where it has lost the orbit ([`Error::OrbitLost`]: the rate
    /// `t'/g = 1 + c·u`, `u = p_t + E`, changed by more than a factor 2,
    /// which a spurious root of the step's Newton solve does).
    pub fn step(&mut self) -> Result<State<N, T>, Error<T>> {
        self.saved.clone_from(&self.inner);
        self.try_step()
    }

    /// One step in `s` from the integrator, which `saved`
    /// holds a copy of; where it fails the copy is put back.
    fn try_step(&mut self) -> Result<State<N, T>, Error<T>> {
        let start = self.state();
        self.inner.transformed().invalid.set(None);
        if let Err(e) = self.inner.s_step() {
            // Read the flag before restoring: the saved copy has its own.
            let invalid = self.inner.transformed().invalid.get();
            core::mem::swap(&mut self.inner, &mut self.saved);
            // The step in `s` starts from the state the driver reports (its
            // time is the landed one after `run_until`).
            return Err(match invalid {
                Some(value) => Error::InvalidDensity { state: start.into(), value },
                None => e.at_state(start),
            });
        }
        let t0 = self.inner_time(&self.saved);
        match self.verify(&self.inner, t0, &start, Some(self.floor)) {
            Ok((end, dt, rate)) => {
                self.after_step(&start, &end, dt, rate);
                Ok(self.state())
            }
            Err(e) => {
                core::mem::swap(&mut self.inner, &mut self.saved);
                Err(e.at(start))
            }
        }
    }

    /// Checks a computed step from the current node (time `t0`, reported
    /// state `start`) to `candidate`'s node: the density there, the time it
    /// advanced (against `floor`, if given), and the rate `t'/g` against the
    /// current node's. Returns the end state, the time step and the rate at
    /// the end; a refusal is placed at `start` by the caller that gives up
    /// (a landing's trials refuse steps and go on).
    #[allow(clippy::type_complexity)]
    fn verify(
        &self,
        candidate: &I,
        t0: T,
        start: &State<N, T>,
        floor: Option<T>,
    ) -> Result<(State<N, T>, T, Option<f64>), Unplaced<T>> {
        let x = candidate.extended_state();
        let end = physical::<T, N, M>(&x);
        let g1 = candidate.transformed().density(end.t, &end.q);
        let dt = end.t - t0;
        if !(g1.is_finite() && g1.to_f64() > 0.0) {
            return Err(Unplaced::new(|state| Error::InvalidDensity { state, value: g1.to_f64() }));
        }
        if let Some(floor) = floor {
            // NaN fails too.
            let margin = (dt - floor).to_f64();
            if margin.is_nan() || margin < 0.0 {
                return Err(Unplaced::new(|state| Error::TimeStepCollapsed {
                    state,
                    dt: dt.to_f64(),
                    floor: floor.to_f64(),
                }));
            }
        }
        let guess: [T; N] = core::array::from_fn(|i| (end.q[i] - start.q[i]) / dt);
        let rate = self.rate_at(&x, guess);
        if let (Some(r0), Some(r1)) = (self.rate, rate) {
            // NaN fails too.
            let factor = r1 / r0;
            if !(0.5..=2.0).contains(&factor) {
                return Err(Unplaced::new(|state| Error::OrbitLost { state, factor }));
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
    pub(super) fn rate_at(&self, x: &State<M, T>, guess: [T; N]) -> Option<f64> {
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
    pub fn run(&mut self, n: usize, mut observe: impl FnMut(&Self)) -> Result<(), Error<T>> {
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
    pub fn run_until(&mut self, t_end: T, mut observe: impl FnMut(&Self)) -> Result<(), Error<T>> {
        let now = self.state();
        if !t_end.is_finite() || above(now.t, t_end) {
            return Err(Error::InvalidTarget { target: t_end.to_f64(), state: now.into() });
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
    pub(crate) fn step_toward(&mut self, t_end: T) -> Result<(), Error<T>> {
        let start = self.state();
        if !above(t_end, start.t) {
            return Ok(());
        }
        self.saved.clone_from(&self.inner);
        self.try_step()?;
        let t = self.inner_time(&self.inner);
        if above(t, t_end) {
            core::mem::swap(&mut self.inner, &mut self.saved);
            self.land(t_end, t, &start)?;
        }
        Ok(())
    }

    /// The partial step in `s` from the current state that ends on `t_end`,
    /// given that the full step ends at `t_over > t_end`.
    fn land(&mut self, t_end: T, t_over: T, start: &State<N, T>) -> Result<(), Error<T>> {
        let sigma = self.inner.s_step_size();
        let t0 = self.inner_time(&self.inner);
        let tol = 4.0 * T::EPSILON * t_end.to_f64().abs().max(t0.to_f64().abs()).max(f64::MIN_POSITIVE);
        if (t_end - t0).to_f64() <= tol {
            self.landed = Some((self.inner.extended_state().step, t_end));
            return Ok(());
        }
        // f(σ') = t(σ') − t_end over (0, σ), bracketed.
        let mut bracket = Bracket::new((T::zero(), t0 - t_end), (sigma, t_over - t_end));
        let mut best: Option<(T, I, Option<f64>)> = None;
        for _ in 0..60 {
            let s = bracket.trial();
            let mut trial = self.inner.clone();
            let verified = if trial.set_s_step_size(s).is_err() || trial.s_step().is_err() {
                None
            } else {
                // No floor: a landing step may be arbitrarily short.
                self.verify(&trial, t0, start, None).ok()
            };
            let Some((_, _, rate)) = verified else {
                bracket.refuse(s);
                continue;
            };
            let f = self.inner_time(&trial) - t_end;
            if best.as_ref().is_none_or(|(b, ..)| f.to_f64().abs() < b.to_f64().abs()) {
                best = Some((f, trial.clone(), rate));
            }
            if f.to_f64().abs() <= tol {
                break;
            }
            bracket.update(s, f);
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
