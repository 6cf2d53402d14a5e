//! The test problems: each a `#[lagrangian]` system with its initial data,
//! horizon, first-order form (for the DOP853 peers), energy, and — where the
//! Hamiltonian is separable, `H = ½ pᵀM⁻¹p + V(q)` with constant diagonal `M` —
//! the force `−∇V` the hand-written compositions need.

use lagrangian::prelude::*;

use crate::exact;
use crate::run::Run;

/// Called with `(t, q, q̇)` after each step of a run.
pub type Observer<'a, const N: usize> = dyn FnMut(f64, &[f64; N], &[f64; N]) + 'a;

/// Double-double, the reference precision.
pub type Dd = DoubleDouble;

/// One problem with `N` degrees of freedom, as the report needs it.
pub trait Model<const N: usize>: Clone + Send + Sync + 'static {
    /// The `#[lagrangian]` system the project's integrators run.
    type Sys: Lagrangian<N> + Clone;
    /// Short name used on the command line and in file names.
    const ID: &'static str;
    /// Title for plots and tables.
    const TITLE: &'static str;
    /// The system.
    fn system(&self) -> Self::Sys;
    /// `(q0, v0)` at `t = 0`.
    fn initial(&self) -> ([f64; N], [f64; N]);
    /// The final time of the work–precision runs.
    fn horizon(&self) -> f64;
    /// A step count at that horizon coarse enough that no method meets a
    /// useful target with it: the calibration sweeps start here.
    fn coarsest_steps(&self) -> usize;
    /// A typical period (or time scale), for the stress section's step sizes.
    fn time_scale(&self) -> f64;
    /// Whether the energy is a first integral. `false` for a time-dependent
    /// `L` or a forced or dissipative system: the report then records no
    /// energy errors for it (the change of energy is physics, not error).
    const CONSERVATIVE: bool = true;
    /// `q̈` as a function of `(q, q̇)` (autonomous problems).
    fn accel(&self, q: &[f64; N], v: &[f64; N]) -> [f64; N];
    /// `q̈` as a function of `(t, q, q̇)`: the first-order form of the peers.
    /// Time-dependent problems override it; the default is [`Model::accel`].
    fn accel_at(&self, t: f64, q: &[f64; N], v: &[f64; N]) -> [f64; N] {
        let _ = t;
        self.accel(q, v)
    }
    /// The energy `E(q, q̇)` (read only when [`Model::CONSERVATIVE`]).
    fn energy(&self, q: &[f64; N], v: &[f64; N]) -> f64;
    /// The angular momentum `Σ mᵢ qᵢ × q̇ᵢ` when the problem conserves it
    /// (rotation-invariant `L`), `None` otherwise.
    fn angular_momentum(&self, q: &[f64; N], v: &[f64; N]) -> Option<[f64; 3]> {
        let _ = (q, v);
        None
    }
    /// For a problem with constraints (or one whose coordinates map to a
    /// constrained form), how far a state is from satisfying them:
    /// `[position error, velocity error]` in the problem's own measure
    /// (`crate::cartesian::constraint_errors`); `None` for the others.
    fn constraint_errors(&self, q: &[f64; N], v: &[f64; N]) -> Option<[f64; 2]> {
        let _ = (q, v);
        None
    }
    /// Diagonal inverse mass when the Hamiltonian is separable with constant mass.
    fn inverse_mass(&self) -> Option<[f64; N]> {
        None
    }
    /// `−∇V(q)` (used only when [`Model::inverse_mass`] is `Some`).
    fn force(&self, q: &[f64; N]) -> [f64; N] {
        let _ = q;
        [f64::NAN; N]
    }
    /// Whether [`Model::time_transformed`] runs.
    const TIME_TRANSFORM: bool = false;
    /// One run of a time-transformed method with step `sigma` in the new
    /// time to `t_end`; `record(t, q, v)` after each step. `None` for
    /// problems without a step density.
    fn time_transformed(
        &self,
        method: Transformed,
        sigma: f64,
        t_end: f64,
        record: &mut Observer<'_, N>,
    ) -> Option<Run> {
        let _ = (method, sigma, t_end, record);
        None
    }
    /// The exact `q(t)` in any precision, when known in closed form.
    fn exact<T: Real>(&self, t: T) -> Option<[T; N]> {
        let _ = t;
        None
    }
    /// Step count of the double-double Galerkin (`s = 8`) reference at `t_end`;
    /// it is checked against a run with twice as many steps.
    fn reference_steps(&self, t_end: f64) -> usize;
}

// ---------------------------------------------------------------- pendulum

/// `L = ½ θ̇² + ω² cos θ` (unit mass and length, `ω² = g/l`).
#[derive(Debug, Clone, Copy)]
pub struct PendulumSys {
    /// `g/l`.
    pub w2: f64,
}

#[lagrangian]
impl PendulumSys {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + self.w2 * q[0].cos()
    }
}

/// The pendulum from rest at 1 rad, `g/l = 9.81`, over 50¼ periods.
#[derive(Debug, Clone, Copy)]
pub struct Pendulum {
    /// Multiplies the horizon (1 in the report, smaller in tiny runs).
    pub scale: f64,
}

impl Pendulum {
    const W2: f64 = 9.81;
    const THETA0: f64 = 1.0;
    fn period(&self) -> f64 {
        exact::pendulum_period(Self::W2.sqrt(), Self::THETA0)
    }
}

impl Model<1> for Pendulum {
    type Sys = PendulumSys;
    const ID: &'static str = "pendulum";
    const TITLE: &'static str = "Pendulum (1 rad, 50¼ periods)";
    fn system(&self) -> PendulumSys {
        PendulumSys { w2: Self::W2 }
    }
    fn initial(&self) -> ([f64; 1], [f64; 1]) {
        ([Self::THETA0], [0.0])
    }
    fn horizon(&self) -> f64 {
        // A quarter period more, so T is at the bottom of a swing: at a turning
        // point the angle error would be quadratic in the phase error.
        (50.0 * self.scale + 0.25) * self.period()
    }
    fn coarsest_steps(&self) -> usize {
        (self.horizon() / self.period() * 3.0).ceil() as usize
    }
    fn time_scale(&self) -> f64 {
        self.period()
    }
    fn accel(&self, q: &[f64; 1], _v: &[f64; 1]) -> [f64; 1] {
        [-Self::W2 * q[0].sin()]
    }
    fn energy(&self, q: &[f64; 1], v: &[f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - Self::W2 * q[0].cos()
    }
    fn inverse_mass(&self) -> Option<[f64; 1]> {
        Some([1.0])
    }
    fn force(&self, q: &[f64; 1]) -> [f64; 1] {
        [-Self::W2 * q[0].sin()]
    }
    fn exact<T: Real>(&self, t: T) -> Option<[T; 1]> {
        // ω as the Lagrangian sees it: the f64 value of g/l, square-rooted in T.
        let omega = (T::one() * Self::W2).sqrt();
        Some([exact::pendulum_angle(omega, T::one() * Self::THETA0, t)])
    }
    fn reference_steps(&self, t_end: f64) -> usize {
        (t_end / 0.05).ceil() as usize
    }
}

// ------------------------------------------------------------------ Kepler

/// `L = ½|q̇|² + 1/|q|` (planar, `μ = 1`).
#[derive(Debug, Clone, Copy)]
pub struct KeplerSys;

#[lagrangian]
impl KeplerSys {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// The Kepler orbit with semi-major axis 1 and eccentricity `e`, from
/// pericentre, over 10 orbits (period `2π`).
#[derive(Debug, Clone, Copy)]
pub struct Kepler<const E: u16> {
    /// Multiplies the horizon.
    pub scale: f64,
}

impl<const E: u16> Kepler<E> {
    /// The eccentricity, `E / 1000`.
    pub const ECC: f64 = E as f64 / 1000.0;
}

macro_rules! kepler_ids {
    ($($e:literal => $id:literal, $title:literal;)*) => {$(
        impl Model<2> for Kepler<$e> {
            type Sys = KeplerSys;
            const ID: &'static str = $id;
            const TITLE: &'static str = $title;
            fn system(&self) -> KeplerSys {
                KeplerSys
            }
            fn initial(&self) -> ([f64; 2], [f64; 2]) {
                exact::kepler_start(Self::ECC)
            }
            fn horizon(&self) -> f64 {
                10.0 * self.scale * 2.0 * core::f64::consts::PI
            }
            fn coarsest_steps(&self) -> usize {
                (self.horizon() / (2.0 * core::f64::consts::PI) * 6.0).ceil() as usize
            }
            fn time_scale(&self) -> f64 {
                2.0 * core::f64::consts::PI
            }
            fn accel(&self, q: &[f64; 2], _v: &[f64; 2]) -> [f64; 2] {
                self.force(q)
            }
            fn energy(&self, q: &[f64; 2], v: &[f64; 2]) -> f64 {
                0.5 * (v[0] * v[0] + v[1] * v[1]) - 1.0 / q[0].hypot(q[1])
            }
            fn angular_momentum(&self, q: &[f64; 2], v: &[f64; 2]) -> Option<[f64; 3]> {
                Some([0.0, 0.0, q[0] * v[1] - q[1] * v[0]])
            }
            fn inverse_mass(&self) -> Option<[f64; 2]> {
                Some([1.0, 1.0])
            }
            fn force(&self, q: &[f64; 2]) -> [f64; 2] {
                let r2 = q[0] * q[0] + q[1] * q[1];
                let r3 = r2 * r2.sqrt();
                [-q[0] / r3, -q[1] / r3]
            }
            fn exact<T: Real>(&self, t: T) -> Option<[T; 2]> {
                Some(exact::kepler_position(T::one() * Self::ECC, t))
            }
            const TIME_TRANSFORM: bool = true;
            fn time_transformed(
                &self,
                method: Transformed,
                sigma: f64,
                t_end: f64,
                record: &mut Observer<'_, 2>,
            ) -> Option<Run> {
                let start = self.initial();
                if method == Transformed::Splitting {
                    return Some(kepler_split(start, sigma, t_end, record));
                }
                // `dt/ds = r^{3/2}`: equal steps in the mean anomaly, the classic choice.
                let r32 = RadiusPower::new([0, 1], 1.5)?;
                kepler_galerkin(KeplerSys, r32, method, start, sigma, t_end, record)
            }
            fn reference_steps(&self, t_end: f64) -> usize {
                (t_end / 0.01).ceil() as usize
            }
        }
    )*};
}

/// Which time-transformed method [`Model::time_transformed`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transformed {
    /// Galerkin of degree `s` (order `2s`) in the new time, with the
    /// problem's own step density.
    Galerkin(u8),
    /// As [`Transformed::Galerkin`] with the automatic `Curvature` monitor.
    GalerkinAuto(u8),
    /// The explicit splitting: logarithmic Hamiltonian, Kahan–Li 8
    /// composition of the drift–kick–drift leapfrog.
    Splitting,
}

/// The report's time-transformed Galerkin runs of Kepler's problem in the
/// coordinates of `system`: degree 4 or 6 with `density` (`Galerkin`) or
/// with the automatic `Curvature` monitor (`GalerkinAuto`); `None` for the
/// splitting, which each problem runs (or refuses) itself.
fn kepler_galerkin<Sys: Lagrangian<2> + Clone, G: StepDensity<2>>(
    system: Sys,
    density: G,
    method: Transformed,
    start: ([f64; 2], [f64; 2]),
    sigma: f64,
    t_end: f64,
    record: &mut Observer<'_, 2>,
) -> Option<Run> {
    let auto = Curvature::new(1e-3)?;
    Some(match method {
        Transformed::Galerkin(4) => kepler_tt::<_, _, 4>(system, density, start, sigma, t_end, record),
        Transformed::Galerkin(6) => kepler_tt::<_, _, 6>(system, density, start, sigma, t_end, record),
        Transformed::GalerkinAuto(4) => kepler_tt::<_, _, 4>(system, auto, start, sigma, t_end, record),
        Transformed::GalerkinAuto(6) => kepler_tt::<_, _, 6>(system, auto, start, sigma, t_end, record),
        Transformed::Galerkin(s) | Transformed::GalerkinAuto(s) => {
            Run { failure: Some(format!("no time-transformed Galerkin s = {s} in the report")), ..Run::default() }
        }
        Transformed::Splitting => return None,
    })
}

/// A time-transformed Galerkin run of Kepler's problem, in the coordinates
/// of `system` (see [`Model::time_transformed`]).
fn kepler_tt<Sys: Lagrangian<2> + Clone, G: StepDensity<2>, const S: usize>(
    system: Sys,
    density: G,
    (q0, v0): ([f64; 2], [f64; 2]),
    sigma: f64,
    t_end: f64,
    record: &mut Observer<'_, 2>,
) -> Run {
    let mut sim =
        match TimeTransformed::new(system, density).galerkin(Galerkin::<S, S>::gauss(), sigma).start(0.0, q0, v0) {
            Ok(sim) => sim,
            Err(e) => return Run { failure: Some(e.to_string()), ..Run::default() },
        };
    let result = sim.run_until(t_end, |sim| {
        if let Ok(v) = sim.velocity() {
            record(sim.state().t, &sim.state().q, &v);
        }
    });
    let stats = sim.stats();
    let per_step = (stats.steps > 0).then(|| stats.newton_iterations as f64 / stats.steps as f64);
    // Derivative evaluations of the extended Lagrangian at quadrature points
    // (as `integrate::galerkin` counts them).
    let points = sim.inner().point_evaluations();
    let evaluations = Some(points.gradients + points.hessians + points.velocity_hessians);
    let steps = stats.steps;
    match result {
        Ok(()) => Run { q: sim.state().q.to_vec(), steps, newton_per_step: per_step, evaluations, ..Run::default() },
        Err(e) => Run { failure: Some(e.to_string()), steps, newton_per_step: per_step, evaluations, ..Run::default() },
    }
}

/// The explicit time-transformed splitting on Kepler's problem: `f = ln`
/// (`dt/ds = r`), Kahan–Li 8 of the drift–kick–drift leapfrog.
fn kepler_split((q0, v0): ([f64; 2], [f64; 2]), sigma: f64, t_end: f64, record: &mut Observer<'_, 2>) -> Run {
    let mut sim = match ExplicitTimeTransformed::new(KeplerSys, TimeFunction::Logarithmic, sigma)
        .composition(Composition::KAHAN_LI8)
        .start(0.0, q0, v0)
    {
        Ok(sim) => sim,
        Err(e) => return Run { failure: Some(e.to_string()), ..Run::default() },
    };
    // Constant unit mass: v = p.
    let result = sim.run_until(t_end, |sim| record(sim.state().t, &sim.state().q, &sim.state().p));
    let steps = sim.stats().steps;
    match result {
        Ok(()) => Run { q: sim.state().q.to_vec(), steps, ..Run::default() },
        Err(e) => Run { failure: Some(e.to_string()), steps, ..Run::default() },
    }
}

kepler_ids! {
    500 => "kepler-0.5", "Kepler e = 0.5 (10 orbits)";
    900 => "kepler-0.9", "Kepler e = 0.9 (10 orbits)";
    990 => "kepler-0.99", "Kepler e = 0.99 (10 orbits)";
}

// ------------------------------------------------------------ Kepler, polar

/// `L = ½(ṙ² + r²φ̇²) + 1/r`: Kepler's problem in polar coordinates, a mass
/// matrix `diag(1, r²)` that depends on the configuration (not separable
/// into `T(p) + V(q)`), `φ` cyclic.
#[derive(Debug, Clone, Copy)]
pub struct KeplerPolarSys;

#[lagrangian]
impl KeplerPolarSys {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + q[0] * q[0] * v[1] * v[1]) + 1.0 / q[0]
    }
}

/// The Kepler orbit with semi-major axis 1 and eccentricity 0.5 from
/// pericentre, in polar coordinates `(r, φ)` with `φ` counted on (not
/// reduced modulo 2π), over 1000 orbits: a long run, where an integrator's
/// energy drift turns into a phase error that grows like `t²`.
#[derive(Debug, Clone, Copy)]
pub struct KeplerPolar {
    /// Multiplies the horizon.
    pub scale: f64,
}

impl KeplerPolar {
    /// The eccentricity.
    pub const ECC: f64 = 0.5;
}

impl Model<2> for KeplerPolar {
    type Sys = KeplerPolarSys;
    const ID: &'static str = "kepler-polar";
    const TITLE: &'static str = "Kepler e = 0.5 in polar coordinates (1000 orbits)";
    fn system(&self) -> KeplerPolarSys {
        KeplerPolarSys
    }
    fn initial(&self) -> ([f64; 2], [f64; 2]) {
        let r0 = 1.0 - Self::ECC;
        // The speed at pericentre is `√((1 + e)/(1 − e))`, all of it along φ.
        ([r0, 0.0], [0.0, ((1.0 + Self::ECC) / (1.0 - Self::ECC)).sqrt() / r0])
    }
    fn horizon(&self) -> f64 {
        1000.0 * self.scale * 2.0 * core::f64::consts::PI
    }
    fn coarsest_steps(&self) -> usize {
        (self.horizon() / (2.0 * core::f64::consts::PI) * 6.0).ceil() as usize
    }
    fn time_scale(&self) -> f64 {
        2.0 * core::f64::consts::PI
    }
    fn accel(&self, q: &[f64; 2], v: &[f64; 2]) -> [f64; 2] {
        let (r, dr, dphi) = (q[0], v[0], v[1]);
        [r * dphi * dphi - 1.0 / (r * r), -2.0 * dr * dphi / r]
    }
    fn energy(&self, q: &[f64; 2], v: &[f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + q[0] * q[0] * v[1] * v[1]) - 1.0 / q[0]
    }
    fn angular_momentum(&self, q: &[f64; 2], v: &[f64; 2]) -> Option<[f64; 3]> {
        Some([0.0, 0.0, q[0] * q[0] * v[1]])
    }
    fn exact<T: Real>(&self, t: T) -> Option<[T; 2]> {
        Some(exact::kepler_polar(T::one() * Self::ECC, t))
    }
    const TIME_TRANSFORM: bool = true;
    fn time_transformed(
        &self,
        method: Transformed,
        sigma: f64,
        t_end: f64,
        record: &mut Observer<'_, 2>,
    ) -> Option<Run> {
        if method == Transformed::Splitting {
            let failure = "not run on the polar form (the explicit splitting needs a constant mass)";
            return Some(Run { failure: Some(failure.to_string()), ..Run::default() });
        }
        // `dt/ds = r^{3/2}` with `r = q_0` itself.
        let r32 = RadiusPower::new([0], 1.5)?;
        kepler_galerkin(KeplerPolarSys, r32, method, self.initial(), sigma, t_end, record)
    }
    fn reference_steps(&self, t_end: f64) -> usize {
        (t_end / 0.01).ceil() as usize
    }
}

// ----------------------------------------------------------- Hénon–Heiles

/// `L = ½|q̇|² − ½(x² + y²) − x²y + y³/3`.
#[derive(Debug, Clone, Copy)]
pub struct HenonHeilesSys;

#[lagrangian]
impl HenonHeilesSys {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let (x, y) = (q[0], q[1]);
        0.5 * (v[0] * v[0] + v[1] * v[1]) - 0.5 * (x * x + y * y) - x * x * y + y * y * y / 3.0
    }
}

/// Hénon–Heiles from `q = (0, 0.1)`, `q̇ = (0.4, 0)` (energy ≈ 0.0847, a
/// regular orbit), to `t = 100`.
#[derive(Debug, Clone, Copy)]
pub struct HenonHeiles {
    /// Multiplies the horizon.
    pub scale: f64,
}

impl Model<2> for HenonHeiles {
    type Sys = HenonHeilesSys;
    const ID: &'static str = "henon-heiles";
    const TITLE: &'static str = "Hénon–Heiles (E ≈ 0.085, t ≤ 100)";
    fn system(&self) -> HenonHeilesSys {
        HenonHeilesSys
    }
    fn initial(&self) -> ([f64; 2], [f64; 2]) {
        ([0.0, 0.1], [0.4, 0.0])
    }
    fn horizon(&self) -> f64 {
        100.0 * self.scale
    }
    fn coarsest_steps(&self) -> usize {
        (self.horizon() / 2.0).ceil() as usize
    }
    fn time_scale(&self) -> f64 {
        2.0 * core::f64::consts::PI
    }
    fn accel(&self, q: &[f64; 2], _v: &[f64; 2]) -> [f64; 2] {
        self.force(q)
    }
    fn energy(&self, q: &[f64; 2], v: &[f64; 2]) -> f64 {
        let (x, y) = (q[0], q[1]);
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 0.5 * (x * x + y * y) + x * x * y - y * y * y / 3.0
    }
    fn inverse_mass(&self) -> Option<[f64; 2]> {
        Some([1.0, 1.0])
    }
    fn force(&self, q: &[f64; 2]) -> [f64; 2] {
        let (x, y) = (q[0], q[1]);
        [-x - 2.0 * x * y, -y - x * x + y * y]
    }
    fn reference_steps(&self, t_end: f64) -> usize {
        (t_end / 0.1).ceil() as usize
    }
}

// ------------------------------------------------------ outer solar system

/// Number of bodies of the outer solar system.
pub const BODIES: usize = 6;

/// Gravitational constant in AU³ / (solar mass · day²).
pub const GRAVITY: f64 = 2.95912208286e-4;

/// Masses in solar masses: the Sun with the inner planets, Jupiter, Saturn,
/// Uranus, Neptune, Pluto (Hairer, Lubich & Wanner, *Geometric Numerical
/// Integration*, §I.2.4, Table 2.1).
pub const MASSES: [f64; BODIES] =
    [1.00000597682, 0.000954786104043, 0.000285583733151, 0.0000437273164546, 0.0000517759138449, 1.0 / 1.3e8];

/// Positions (AU) on September 5, 1994, 0h00 GST, same source.
pub const POSITIONS: [[f64; 3]; BODIES] = [
    [0.0, 0.0, 0.0],
    [-3.5023653, -3.8169847, -1.5507963],
    [9.0755314, -3.0458353, -1.6483708],
    [8.3101420, -16.2901086, -7.2521278],
    [11.4707666, -25.7294829, -10.8169456],
    [-15.5387357, -25.2225594, -3.1902382],
];

/// Velocities (AU/day), same source.
pub const VELOCITIES: [[f64; 3]; BODIES] = [
    [0.0, 0.0, 0.0],
    [0.00565429, -0.00412490, -0.00190589],
    [0.00168318, 0.00483525, 0.00192462],
    [0.00354178, 0.00137102, 0.00055029],
    [0.00288930, 0.00114527, 0.00039677],
    [0.00276725, -0.00170702, -0.00136504],
];

/// `L = Σ ½ mᵢ|q̇ᵢ|² + Σ_{i<j} G mᵢ mⱼ / |qᵢ − qⱼ|`, coordinates `q[3i + k]`.
#[derive(Debug, Clone, Copy)]
pub struct SolarSys;

#[lagrangian]
impl SolarSys {
    fn lagrangian(&self, q: [f64; 18], v: [f64; 18]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..6 {
            let m = MASSES[i];
            kinetic += 0.5 * m * (v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
        }
        let mut potential = 0.0;
        for i in 0..6 {
            for j in (i + 1)..6 {
                let dx = q[3 * i] - q[3 * j];
                let dy = q[3 * i + 1] - q[3 * j + 1];
                let dz = q[3 * i + 2] - q[3 * j + 2];
                potential -= GRAVITY * MASSES[i] * MASSES[j] / (dx * dx + dy * dy + dz * dz).sqrt();
            }
        }
        kinetic - potential
    }
}

/// The outer solar system over 20 000 days (4.6 Jupiter orbits).
#[derive(Debug, Clone, Copy)]
pub struct OuterSolarSystem {
    /// Multiplies the horizon.
    pub scale: f64,
}

impl Model<18> for OuterSolarSystem {
    type Sys = SolarSys;
    const ID: &'static str = "outer-solar-system";
    const TITLE: &'static str = "Outer solar system (20 000 days)";
    fn system(&self) -> SolarSys {
        SolarSys
    }
    fn initial(&self) -> ([f64; 18], [f64; 18]) {
        let mut q = [0.0; 18];
        let mut v = [0.0; 18];
        for i in 0..BODIES {
            for k in 0..3 {
                q[3 * i + k] = POSITIONS[i][k];
                v[3 * i + k] = VELOCITIES[i][k];
            }
        }
        (q, v)
    }
    fn horizon(&self) -> f64 {
        20_000.0 * self.scale
    }
    fn coarsest_steps(&self) -> usize {
        (self.horizon() / 500.0).ceil() as usize
    }
    fn time_scale(&self) -> f64 {
        4332.6
    }
    fn accel(&self, q: &[f64; 18], _v: &[f64; 18]) -> [f64; 18] {
        let mut a = self.force(q);
        for i in 0..BODIES {
            for k in 0..3 {
                a[3 * i + k] /= MASSES[i];
            }
        }
        a
    }
    fn energy(&self, q: &[f64; 18], v: &[f64; 18]) -> f64 {
        let mut e = 0.0;
        for i in 0..BODIES {
            let v2: f64 = (0..3).map(|k| v[3 * i + k] * v[3 * i + k]).sum();
            e += 0.5 * MASSES[i] * v2;
            for j in i + 1..BODIES {
                let r2: f64 = (0..3).map(|k| (q[3 * i + k] - q[3 * j + k]).powi(2)).sum();
                e -= GRAVITY * MASSES[i] * MASSES[j] / r2.sqrt();
            }
        }
        e
    }
    fn angular_momentum(&self, q: &[f64; 18], v: &[f64; 18]) -> Option<[f64; 3]> {
        let mut l = [0.0; 3];
        for i in 0..BODIES {
            let (x, u) = (&q[3 * i..3 * i + 3], &v[3 * i..3 * i + 3]);
            l[0] += MASSES[i] * (x[1] * u[2] - x[2] * u[1]);
            l[1] += MASSES[i] * (x[2] * u[0] - x[0] * u[2]);
            l[2] += MASSES[i] * (x[0] * u[1] - x[1] * u[0]);
        }
        Some(l)
    }
    fn inverse_mass(&self) -> Option<[f64; 18]> {
        Some(core::array::from_fn(|c| 1.0 / MASSES[c / 3]))
    }
    fn force(&self, q: &[f64; 18]) -> [f64; 18] {
        let mut f = [0.0; 18];
        for i in 0..BODIES {
            for j in i + 1..BODIES {
                let d: [f64; 3] = core::array::from_fn(|k| q[3 * i + k] - q[3 * j + k]);
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                let s = GRAVITY * MASSES[i] * MASSES[j] / (r2 * r2.sqrt());
                for k in 0..3 {
                    f[3 * i + k] -= s * d[k];
                    f[3 * j + k] += s * d[k];
                }
            }
        }
        f
    }
    fn reference_steps(&self, t_end: f64) -> usize {
        (t_end / 50.0).ceil() as usize
    }
}

// --------------------------------------------------------- double pendulum

/// Planar double pendulum, angles from the downward vertical.
#[derive(Debug, Clone, Copy)]
pub struct DoublePendulumSys {
    /// Upper mass.
    pub m1: f64,
    /// Lower mass.
    pub m2: f64,
    /// Upper rod.
    pub l1: f64,
    /// Lower rod.
    pub l2: f64,
    /// Gravity.
    pub g: f64,
}

#[lagrangian]
impl DoublePendulumSys {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = 0.5 * (self.m1 + self.m2) * self.l1 * self.l1 * v[0] * v[0]
            + 0.5 * self.m2 * self.l2 * self.l2 * v[1] * v[1]
            + self.m2 * self.l1 * self.l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        let potential = -(self.m1 + self.m2) * self.g * self.l1 * q[0].cos() - self.m2 * self.g * self.l2 * q[1].cos();
        kinetic - potential
    }
}

/// The double pendulum of the facade's tests from `(1, −0.5)`, `q̇ = (0, 0.5)`,
/// over a short horizon (`t ≤ 10`: it is chaotic).
#[derive(Debug, Clone, Copy)]
pub struct DoublePendulum {
    /// Multiplies the horizon.
    pub scale: f64,
}

impl DoublePendulum {
    /// Masses, rods and gravity (also those of the Cartesian form, `crate::cartesian`).
    pub const P: DoublePendulumSys = DoublePendulumSys { m1: 1.0, m2: 1.5, l1: 1.0, l2: 0.7, g: 9.81 };
}

impl Model<2> for DoublePendulum {
    type Sys = DoublePendulumSys;
    const ID: &'static str = "double-pendulum";
    const TITLE: &'static str = "Double pendulum (t ≤ 10)";
    fn system(&self) -> DoublePendulumSys {
        Self::P
    }
    fn initial(&self) -> ([f64; 2], [f64; 2]) {
        ([1.0, -0.5], [0.0, 0.5])
    }
    fn horizon(&self) -> f64 {
        10.0 * self.scale
    }
    fn coarsest_steps(&self) -> usize {
        (self.horizon() / 0.2).ceil() as usize
    }
    fn time_scale(&self) -> f64 {
        2.0
    }
    fn accel(&self, q: &[f64; 2], v: &[f64; 2]) -> [f64; 2] {
        // M(q) q̈ = f(q, q̇) from the Euler–Lagrange equations, solved by Cramer's rule.
        let p = Self::P;
        let (a, b, c) = ((p.m1 + p.m2) * p.l1 * p.l1, p.m2 * p.l2 * p.l2, p.m2 * p.l1 * p.l2);
        let (s, co) = (q[0] - q[1]).sin_cos();
        let m = [[a, c * co], [c * co, b]];
        let f = [
            -c * v[1] * v[1] * s - (p.m1 + p.m2) * p.g * p.l1 * q[0].sin(),
            c * v[0] * v[0] * s - p.m2 * p.g * p.l2 * q[1].sin(),
        ];
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        [(f[0] * m[1][1] - f[1] * m[0][1]) / det, (m[0][0] * f[1] - m[1][0] * f[0]) / det]
    }
    fn energy(&self, q: &[f64; 2], v: &[f64; 2]) -> f64 {
        let p = Self::P;
        0.5 * (p.m1 + p.m2) * p.l1 * p.l1 * v[0] * v[0]
            + 0.5 * p.m2 * p.l2 * p.l2 * v[1] * v[1]
            + p.m2 * p.l1 * p.l2 * v[0] * v[1] * (q[0] - q[1]).cos()
            - (p.m1 + p.m2) * p.g * p.l1 * q[0].cos()
            - p.m2 * p.g * p.l2 * q[1].cos()
    }
    fn reference_steps(&self, t_end: f64) -> usize {
        (t_end / 0.01).ceil() as usize
    }
}

// -------------------------------------------------------------- FPU-β chain

/// Number of moving particles of the FPU-β chain.
pub const FPU_N: usize = 16;

/// The Fermi–Pasta–Ulam–Tsingou β chain: `FPU_N` unit masses between two
/// fixed walls, joined by springs with force `−(d + β d³)` for an extension `d`:
/// `L = Σ ½ q̇ᵢ² − Σ_{bonds} (½ d² + ¼ β d⁴)`, `d = q_{i+1} − q_i`, `q_0 = q_{N+1} = 0`.
#[derive(Debug, Clone, Copy)]
pub struct FpuSys {
    /// The quartic coefficient β.
    pub beta: f64,
}

#[lagrangian]
impl FpuSys {
    fn lagrangian(&self, q: [f64; FPU_N], v: [f64; FPU_N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..FPU_N {
            kinetic += 0.5 * v[i] * v[i];
        }
        // The two bonds to the walls.
        let (a, b) = (q[0], q[FPU_N - 1]);
        let mut potential = 0.5 * (a * a + b * b) + 0.25 * self.beta * (a * a * a * a + b * b * b * b);
        for i in 0..FPU_N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d * d * d * d;
        }
        kinetic - potential
    }
}

/// The FPU-β chain (`FPU_N = 16`, `β = 1`) from rest in its lowest linear
/// mode, amplitude 2 (largest bond extension ≈ 0.37, so the quartic term is
/// felt), to `t = 50` (1.5 periods of that mode, 16 of the fastest).
#[derive(Debug, Clone, Copy)]
pub struct Fpu {
    /// Multiplies the horizon.
    pub scale: f64,
}

impl Fpu {
    const BETA: f64 = 1.0;
    const AMPLITUDE: f64 = 2.0;
    /// `−∂V/∂qᵢ` with the walls at `q_0 = q_{N+1} = 0`.
    fn chain_force(q: &[f64; FPU_N]) -> [f64; FPU_N] {
        // Tension of the bond to the right of particle i (i = −1 is the left wall).
        let tension = |d: f64| d + Self::BETA * d * d * d;
        let at = |i: isize| if i < 0 || i >= FPU_N as isize { 0.0 } else { q[i as usize] };
        core::array::from_fn(|i| {
            let i = i as isize;
            tension(at(i + 1) - at(i)) - tension(at(i) - at(i - 1))
        })
    }
}

impl Model<FPU_N> for Fpu {
    type Sys = FpuSys;
    const ID: &'static str = "fpu-beta";
    const TITLE: &'static str = "FPU-β chain (16 particles, t ≤ 50)";
    fn system(&self) -> FpuSys {
        FpuSys { beta: Self::BETA }
    }
    fn initial(&self) -> ([f64; FPU_N], [f64; FPU_N]) {
        let k = core::f64::consts::PI / (FPU_N + 1) as f64;
        (core::array::from_fn(|i| Self::AMPLITUDE * (k * (i + 1) as f64).sin()), [0.0; FPU_N])
    }
    fn horizon(&self) -> f64 {
        50.0 * self.scale
    }
    fn coarsest_steps(&self) -> usize {
        // h = 2, two thirds of the fastest period: the order-16 rule still misses 1e-4 there.
        (self.horizon() / 2.0).ceil() as usize
    }
    fn time_scale(&self) -> f64 {
        // The fastest linear mode has ω = 2 sin(Nπ / (2(N + 1))) ≈ 2: its period is ≈ π.
        core::f64::consts::PI
    }
    fn accel(&self, q: &[f64; FPU_N], _v: &[f64; FPU_N]) -> [f64; FPU_N] {
        Self::chain_force(q)
    }
    fn energy(&self, q: &[f64; FPU_N], v: &[f64; FPU_N]) -> f64 {
        let bond = |d: f64| 0.5 * d * d + 0.25 * Self::BETA * d * d * d * d;
        let kinetic: f64 = v.iter().map(|v| 0.5 * v * v).sum();
        let inner: f64 = q.windows(2).map(|w| bond(w[1] - w[0])).sum();
        kinetic + inner + bond(q[0]) + bond(q[FPU_N - 1])
    }
    fn inverse_mass(&self) -> Option<[f64; FPU_N]> {
        Some([1.0; FPU_N])
    }
    fn force(&self, q: &[f64; FPU_N]) -> [f64; FPU_N] {
        Self::chain_force(q)
    }
    fn reference_steps(&self, t_end: f64) -> usize {
        (t_end / 0.1).ceil() as usize
    }
}

// ------------------------------------------------------ perturbed pendulum

/// The pendulum with a slowly modulated gravity of Luo, Guo, Li & Wu
/// (*Difference discrete variational principle in discrete mechanics and
/// symplectic algorithm*, §V):
/// `L = ½ θ̇² − (1 − cos θ)(1 − 0.1 sin 0.02t)`.
#[derive(Debug, Clone, Copy)]
pub struct PerturbedPendulumSys;

#[lagrangian]
impl PerturbedPendulumSys {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - (1.0 - q[0].cos()) * (1.0 - 0.1 * (0.02 * t).sin())
    }
}

/// The perturbed pendulum from `θ = θ̇ = 0.5` (as in the paper) over one
/// period `2π/0.02` of the perturbation (about 50 swings).
#[derive(Debug, Clone, Copy)]
pub struct PerturbedPendulum {
    /// Multiplies the horizon.
    pub scale: f64,
}

impl PerturbedPendulum {
    const PERTURBATION: f64 = 0.02;
    fn gravity(t: f64) -> f64 {
        1.0 - 0.1 * (Self::PERTURBATION * t).sin()
    }
}

impl Model<1> for PerturbedPendulum {
    type Sys = PerturbedPendulumSys;
    const ID: &'static str = "perturbed-pendulum";
    const TITLE: &'static str = "Perturbed pendulum (time-dependent, t ≤ 314)";
    const CONSERVATIVE: bool = false;
    fn system(&self) -> PerturbedPendulumSys {
        PerturbedPendulumSys
    }
    fn initial(&self) -> ([f64; 1], [f64; 1]) {
        ([0.5], [0.5])
    }
    fn horizon(&self) -> f64 {
        self.scale * core::f64::consts::TAU / Self::PERTURBATION
    }
    fn coarsest_steps(&self) -> usize {
        // Three steps per swing, as for the pendulum.
        (self.horizon() / self.time_scale() * 3.0).ceil() as usize
    }
    fn time_scale(&self) -> f64 {
        // Small swings (amplitude ≈ 0.7 rad) of a pendulum with g/l ≈ 1.
        core::f64::consts::TAU
    }
    fn accel(&self, q: &[f64; 1], v: &[f64; 1]) -> [f64; 1] {
        self.accel_at(0.0, q, v)
    }
    fn accel_at(&self, t: f64, q: &[f64; 1], _v: &[f64; 1]) -> [f64; 1] {
        [-q[0].sin() * Self::gravity(t)]
    }
    fn energy(&self, q: &[f64; 1], v: &[f64; 1]) -> f64 {
        // At t = 0 (not conserved, so never read by the report).
        0.5 * v[0] * v[0] + (1.0 - q[0].cos()) * Self::gravity(0.0)
    }
    fn reference_steps(&self, t_end: f64) -> usize {
        (t_end / 0.05).ceil() as usize
    }
}

// -------------------------------------------------- electromechanical sensor

/// The electromechanical sensor of Fu, Dai & Tang (*Discrete variation
/// principle and first integrals of Lagrange–Maxwell mechano-electrical
/// dynamical systems*, §4): armature `x` (`q[0]`) on a
/// spring, charge `q` (`q[1]`) through an inductance `L1(x) = L0 / (1 + x/a)`
/// that the armature changes, a resistor and a battery:
/// `L = ½ m ẋ² + ½ L1(x) q̇² − ½ k x² + m g x`, `R = ½ r q̇²`, force `(0, E)`.
#[derive(Debug, Clone, Copy)]
pub struct SensorSys {
    /// Armature mass.
    pub m: f64,
    /// Spring constant.
    pub k: f64,
    /// Gravity.
    pub g: f64,
    /// Inductance at `x = 0`.
    pub l0: f64,
    /// Length scale of the inductance's dependence on `x`.
    pub a: f64,
    /// Resistance.
    pub r: f64,
    /// Battery EMF.
    pub e: f64,
}

#[lagrangian]
impl SensorSys {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x = q[0];
        let l1 = self.l0 / (1.0 + x / self.a);
        0.5 * self.m * v[0] * v[0] + 0.5 * l1 * v[1] * v[1] - 0.5 * self.k * x * x + self.m * self.g * x
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.r * v[1] * v[1]
    }

    fn force(&self, _q: [f64; 2], _v: [f64; 2]) -> [f64; 2] {
        [0.0, self.e]
    }
}

/// The sensor with a position-dependent inductance (`a = 0.2`), switched on
/// at rest, to `t = 2` (about 6 periods of the armature, 40 time constants
/// `L0/r` of the circuit).
#[derive(Debug, Clone, Copy)]
pub struct Sensor {
    /// Multiplies the horizon.
    pub scale: f64,
}

impl Sensor {
    const P: SensorSys = SensorSys { m: 0.2, k: 80.0, g: 9.81, l0: 0.5, a: 0.2, r: 10.0, e: 12.0 };
}

impl Model<2> for Sensor {
    type Sys = SensorSys;
    const ID: &'static str = "sensor";
    const TITLE: &'static str = "Electromechanical sensor (forced, dissipative, t ≤ 2)";
    const CONSERVATIVE: bool = false;
    fn system(&self) -> SensorSys {
        Self::P
    }
    fn initial(&self) -> ([f64; 2], [f64; 2]) {
        ([0.0, 0.0], [0.0, 0.0])
    }
    fn horizon(&self) -> f64 {
        2.0 * self.scale
    }
    fn coarsest_steps(&self) -> usize {
        // h = 0.2, two thirds of the armature's period and four time constants of the circuit.
        (self.horizon() / 0.2).ceil() as usize
    }
    fn time_scale(&self) -> f64 {
        // The armature's period 2π √(m/k).
        core::f64::consts::TAU * (Self::P.m / Self::P.k).sqrt()
    }
    fn accel(&self, q: &[f64; 2], v: &[f64; 2]) -> [f64; 2] {
        // Euler–Lagrange with the Rayleigh term: m ẍ = ½ L1'(x) q̇² − k x + m g and
        // d/dt (L1(x) q̇) = E − r q̇, i.e. L1 q̈ = E − r q̇ − L1'(x) ẋ q̇.
        let p = Self::P;
        let s = 1.0 + q[0] / p.a;
        let (l1, dl1) = (p.l0 / s, -p.l0 / (p.a * s * s));
        [(0.5 * dl1 * v[1] * v[1] - p.k * q[0] + p.m * p.g) / p.m, (p.e - p.r * v[1] - dl1 * v[0] * v[1]) / l1]
    }
    fn energy(&self, q: &[f64; 2], v: &[f64; 2]) -> f64 {
        let p = Self::P;
        let l1 = p.l0 / (1.0 + q[0] / p.a);
        0.5 * p.m * v[0] * v[0] + 0.5 * l1 * v[1] * v[1] + 0.5 * p.k * q[0] * q[0] - p.m * p.g * q[0]
    }
    fn reference_steps(&self, t_end: f64) -> usize {
        (t_end / 2e-3).ceil() as usize
    }
}
