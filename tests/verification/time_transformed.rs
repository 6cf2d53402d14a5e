//! Time-transformed (Sundman–Poincaré) adaptive steps (docs/time-transformation.md):
//! Kepler e = 0.9 and e = 0.99 with midpoint, trapezoid and Galerkin s = 2, 4
//! in `s` (energy bounded without drift, angular momentum and `p_t` at
//! round-off, position error against Kepler's equation, fitted order in the
//! step σ, symplecticity in the extended phase space, fixed steps of the
//! same mean size printed for comparison); time-dependent forces; bad input.
//!
//! The default suite runs 10 orbits; the 1000-orbit runs are ignored:
//! `cargo test --release --test verification time_transformed:: -- --ignored --nocapture`.
use crate::common;

use lagrangian::prelude::*;
use lagrangian::time_transform::SStepper;
use lagrangian::{Scalar, StepDensity};
use std::f64::consts::PI;

/// Planar Kepler, μ = 1, Cartesian.
#[derive(Debug, Clone, Copy)]
pub struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// `E − e sin E = m` by Newton safeguarded with bisection on `[m − e, m + e]`,
/// in any real type (`f64`, or double-double for the extended-precision runs).
pub fn eccentric_anomaly<T: Real>(e: T, m: T) -> T {
    let (mut lo, mut hi) = (m - e, m + e);
    let mut ea = m + e * m.sin();
    for _ in 0..100 {
        let f = ea - e * ea.sin() - m;
        if f.to_f64() > 0.0 {
            hi = ea;
        } else {
            lo = ea;
        }
        let mut next = ea - f / (T::one() - e * ea.cos());
        if !((next - lo).to_f64() > 0.0 && (hi - next).to_f64() > 0.0) {
            next = (lo + hi) * 0.5;
        }
        let d = (next - ea).abs().to_f64();
        ea = next;
        if d <= T::EPSILON * ea.abs().to_f64().max(1.0) {
            break;
        }
    }
    ea
}

/// Position on the orbit with a = 1, pericentre on +x at t = 0.
pub fn kepler_position<T: Real>(e: T, t: T) -> [T; 2] {
    let ea = eccentric_anomaly(e, t);
    [ea.cos() - e, (T::one() - e * e).sqrt() * ea.sin()]
}

pub fn kepler_start(e: f64) -> ([f64; 2], [f64; 2]) {
    ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()])
}

fn r32() -> RadiusPower<2> {
    RadiusPower::new([0, 1], 1.5).unwrap()
}

type Tt = TimeTransformed<Kepler, RadiusPower<2>, 2>;

/// What one run measured.
#[derive(Debug)]
struct Run {
    steps: u64,
    /// `|q(T) − q_exact(T)|`.
    position_error: f64,
    /// `max |E − E0| / |E0|` over every step.
    energy_error: f64,
    /// `|b| K / mean(m)` for the fit `m_k ≈ a + b k` of the per-orbit maxima
    /// `m_k` of the energy error over `K` orbits: about 2 for an error that
    /// grows linearly from zero, near 0 for a bounded one.
    energy_trend: f64,
    /// `max |J − J0| / |J0|`, `J = x p_y − y p_x`.
    angular_momentum: f64,
    /// `max |p_t − p_t0| / |p_t0|`.
    time_momentum: f64,
}

pub fn angular(s: &State<2>) -> f64 {
    s.q[0] * s.p[1] - s.q[1] * s.p[0]
}

/// Integrates `orbits` orbits of Kepler `e`, orbit by orbit with `run_until`.
fn measure<I>(mut sim: Adaptive<I, Kepler, RadiusPower<2>, 2, 3>, e: f64, orbits: usize) -> Run
where
    I: SStepper<3, System = Tt>,
{
    let e0 = sim.energy().unwrap();
    let j0 = angular(&sim.state());
    let pt0 = sim.time_momentum();
    let (mut jmax, mut ptmax) = (0.0f64, 0.0f64);
    // Per-orbit maxima over steps of size σ only: a landing step (of another
    // size) shifts the modified energy once, so `run_until` is called once.
    let mut maxima = vec![0.0f64; orbits];
    let t_end = 2.0 * PI * orbits as f64;
    let mut watch = |s: &Adaptive<I, Kepler, RadiusPower<2>, 2, 3>| {
        let k = ((s.state().t / (2.0 * PI)) as usize).min(orbits - 1);
        maxima[k] = maxima[k].max(((s.energy().unwrap() - e0) / e0).abs());
        jmax = jmax.max(((angular(&s.state()) - j0) / j0).abs());
        ptmax = ptmax.max(((s.time_momentum() - pt0) / pt0).abs());
    };
    sim.run_until(t_end, &mut watch).unwrap();
    if std::env::var_os("TT_MAXIMA").is_some() {
        println!("per-orbit maxima {:?}", maxima.iter().map(|m| format!("{m:.3e}")).collect::<Vec<_>>());
    }
    let x = kepler_position(e, 2.0 * PI * orbits as f64);
    let q = sim.state().q;
    Run {
        steps: sim.stats().steps,
        position_error: (q[0] - x[0]).hypot(q[1] - x[1]),
        energy_error: maxima.iter().fold(0.0, |a: f64, &b| a.max(b)),
        energy_trend: trend(&maxima),
        angular_momentum: jmax,
        time_momentum: ptmax,
    }
}

/// `|b| K / mean(m)` of the least-squares line `m_k ≈ a + b k`, `k = 1 … K`:
/// the change of the per-orbit maxima over the run, relative to their mean
/// (a drift from zero gives 2).
pub fn trend(m: &[f64]) -> f64 {
    let k: Vec<f64> = (1..=m.len()).map(|k| k as f64).collect();
    let mean = m.iter().sum::<f64>() / m.len() as f64;
    common::linear_fit(&k, m).1.abs() * m.len() as f64 / mean
}

/// The same `orbits` with fixed steps of the mean size `T/steps`: position
/// and largest energy error, or the error that stopped it.
fn fixed<M: DiscreteLagrangian>(method: M, e: f64, orbits: usize, steps: u64) -> String {
    let t_end = 2.0 * PI * orbits as f64;
    let (q0, v0) = kepler_start(e);
    let run = || -> Result<(f64, f64), Error> {
        let mut sim = Integrator::new(Kepler, method, t_end / steps as f64).start(0.0, q0, v0)?;
        let e0 = sim.energy()?;
        let mut worst = 0.0f64;
        sim.run_until(t_end, |s| worst = worst.max(((s.energy().unwrap_or(f64::NAN) - e0) / e0).abs()))?;
        let x = kepler_position(e, t_end);
        Ok(((sim.state().q[0] - x[0]).hypot(sim.state().q[1] - x[1]), worst))
    };
    match run() {
        Ok((p, en)) => format!("fixed h = T/{steps}: position {p:.2e}, energy {en:.2e}"),
        Err(err) => format!("fixed h = T/{steps}: stopped ({err})"),
    }
}

fn rule<M: DiscreteLagrangian>(
    method: M,
    e: f64,
    sigma: f64,
) -> Adaptive<Integrator<Tt, M, 3>, Kepler, RadiusPower<2>, 2, 3> {
    let (q0, v0) = kepler_start(e);
    TimeTransformed::new(Kepler, r32()).rule(method, sigma).start(0.0, q0, v0).unwrap()
}

fn galerkin<const S: usize>(
    e: f64,
    sigma: f64,
) -> Adaptive<GalerkinIntegrator<Tt, 3, S, S>, Kepler, RadiusPower<2>, 2, 3> {
    let (q0, v0) = kepler_start(e);
    TimeTransformed::new(Kepler, r32()).galerkin(Galerkin::<S, S>::gauss(), sigma).start(0.0, q0, v0).unwrap()
}

/// Checks and prints one run against its fixed-step twin; `j_tol` bounds
/// the angular momentum's relative change (round-off that grows with the
/// number of steps).
#[allow(clippy::too_many_arguments)]
fn check(
    label: &str,
    run: &Run,
    e: f64,
    orbits: usize,
    fixed_line: String,
    position_tol: f64,
    energy_tol: f64,
    j_tol: f64,
) {
    println!(
        "{label}, e = {e}, {orbits} orbits: {} steps, position {:.2e}, energy {:.2e} (trend {:.3}), J {:.1e}, p_t {:.1e} | {fixed_line}",
        run.steps, run.position_error, run.energy_error, run.energy_trend, run.angular_momentum, run.time_momentum
    );
    assert!(run.position_error < position_tol, "{label}: {run:?}");
    assert!(run.energy_error < energy_tol, "{label}: {run:?}");
    assert!(run.energy_trend < 0.2, "{label}: energy drifts: {run:?}");
    assert!(run.angular_momentum < j_tol, "{label}: {run:?}");
    assert!(run.time_momentum < 1e-13, "{label}: {run:?}");
}

// Tolerances: about three times the errors measured (10 orbits), so a change
// of the order or of the error constant fails.
#[test]
fn kepler_midpoint_and_trapezoid() {
    let orbits = 10;
    for (e, sigma, pos, en) in [(0.9, 0.02, 2e-2, 1e-3), (0.99, 0.01, 2e-2, 3e-3)] {
        let run = measure(rule(Midpoint, e, sigma), e, orbits);
        check("midpoint", &run, e, orbits, fixed(Midpoint, e, orbits, run.steps), pos, en, 1e-12);
        // The trapezoid rule meets the monitor at both ends of the step: its
        // error constant in s is larger (docs/time-transformation.md).
        let run = measure(rule(Trapezoid, e, sigma / 4.0), e, orbits);
        check("trapezoid", &run, e, orbits, fixed(Trapezoid, e, orbits, run.steps), 20.0 * pos, 3.0 * en, 1e-12);
    }
}

#[test]
fn kepler_galerkin() {
    let orbits = 10;
    for (e, sigma, pos, en) in [(0.9, 0.1, 1e-4, 1e-5), (0.99, 0.05, 1e-3, 1e-4)] {
        let run = measure(galerkin::<2>(e, sigma), e, orbits);
        check("galerkin s = 2", &run, e, orbits, fixed(Midpoint, e, orbits, run.steps), pos, en, 1e-12);
        // Steps large enough that the truncation error, not the round-off of
        // the Newton solves (which drifts like 1e-12 per orbit), is measured.
        let run = measure(galerkin::<4>(e, 0.3), e, orbits);
        check("galerkin s = 4", &run, e, orbits, fixed(Midpoint, e, orbits, run.steps), pos / 100.0, en / 100.0, 1e-12);
    }
}

#[test]
#[ignore = "1000 orbits: about 14 s in release; run with --release --ignored"]
fn kepler_thousand_orbits() {
    let orbits = 1000;
    // (e, σ of the midpoint; position and energy tolerances of midpoint,
    // trapezoid, Galerkin s = 2 and s = 4): twice the errors measured (one
    // release run), so a change of order or error constant fails. The
    // trapezoid's phase error at e = 0.9 exceeds an orbit (position 1.9): its
    // position is not asserted there. The angular momentum is round-off that
    // accumulates over 2e4–5e6 steps: 2e-12 (measured up to 8.8e-13). The
    // trend of the per-orbit energy maxima measured ≤ 0.011 (2 for a linear
    // drift from zero). Fixed steps with the same number of steps are printed.
    for (e, sigma, tols) in [
        (0.9, 0.02, [(0.8, 6e-4), (f64::INFINITY, 1.3e-3), (5e-3, 7e-6), (8e-6, 1.3e-8)]),
        (0.99, 0.01, [(0.31, 1.8e-3), (1.3, 5e-3), (2.5e-4, 5.4e-6), (5e-6, 2.2e-7)]),
    ] {
        let j = 2e-12;
        let run = measure(rule(Midpoint, e, sigma), e, orbits);
        check("midpoint", &run, e, orbits, fixed(Midpoint, e, orbits, run.steps), tols[0].0, tols[0].1, j);
        let run = measure(rule(Trapezoid, e, sigma / 4.0), e, orbits);
        check("trapezoid", &run, e, orbits, fixed(Trapezoid, e, orbits, run.steps), tols[1].0, tols[1].1, j);
        let run = measure(galerkin::<2>(e, 5.0 * sigma), e, orbits);
        check("galerkin s = 2", &run, e, orbits, fixed(Midpoint, e, orbits, run.steps), tols[2].0, tols[2].1, j);
        // σ = 0.4: the energy error (1e-7 at e = 0.99) far above its
        // round-off, which wanders by a few 1e-9 over 1000 orbits.
        let run = measure(galerkin::<4>(e, 0.4), e, orbits);
        check("galerkin s = 4", &run, e, orbits, fixed(Midpoint, e, orbits, run.steps), tols[3].0, tols[3].1, j);
    }
}

/// The slope of `log err` against `log σ` by least squares.
pub fn fitted_order(points: &[(f64, f64)]) -> f64 {
    let (h, err): (Vec<f64>, Vec<f64>) = points.iter().copied().unzip();
    common::fitted_order(&h, &err)
}

fn position_error<I: SStepper<3, System = Tt>>(mut sim: Adaptive<I, Kepler, RadiusPower<2>, 2, 3>, e: f64) -> f64 {
    sim.run_until(2.0 * PI, |_| {}).unwrap();
    let x = kepler_position(e, 2.0 * PI);
    (sim.state().q[0] - x[0]).hypot(sim.state().q[1] - x[1])
}

#[test]
fn order_in_the_step() {
    for e in [0.9, 0.99] {
        let sigmas = |s0: f64| [s0, s0 / 2.0, s0 / 4.0, s0 / 8.0];
        // Degree 4 reaches round-off within a factor 2 of its largest step.
        let sigmas4 = |s0: f64| [s0, s0 * 0.8, s0 * 0.65, s0 * 0.5];
        let mid: Vec<_> = sigmas(0.04).iter().map(|&s| (s, position_error(rule(Midpoint, e, s), e))).collect();
        // The trapezoid rule with the default c is pre-asymptotic at e = 0.99
        // down to σ = 1e-3 (ratios 2.5, 2.6, 2.8); a larger c shrinks its
        // error constant (docs/time-transformation.md).
        let (q0, v0) = kepler_start(e);
        let trapezoid =
            |s: f64| TimeTransformed::new(Kepler, r32()).rule(Trapezoid, s).penalty(1.0).start(0.0, q0, v0).unwrap();
        let trap: Vec<_> = sigmas(0.01).iter().map(|&s| (s, position_error(trapezoid(s), e))).collect();
        let g2: Vec<_> = sigmas(0.2).iter().map(|&s| (s, position_error(galerkin::<2>(e, s), e))).collect();
        let g4: Vec<_> = sigmas4(0.4).iter().map(|&s| (s, position_error(galerkin::<4>(e, s), e))).collect();
        for (label, pts, order) in
            [("midpoint", &mid, 2.0), ("trapezoid", &trap, 2.0), ("galerkin 2", &g2, 4.0), ("galerkin 4", &g4, 8.0)]
        {
            if e == 0.99 && order == 8.0 {
                // Measured 7.71 on these steps (9.24 at rtol 1e-14): the errors are
                // not yet in the asymptotic range at the large end and near
                // round-off at the small one; printed, not asserted.
                println!("e = {e}, {label}: fitted order {:.3} (not asserted)", fitted_order(pts));
                continue;
            }
            let p = fitted_order(pts);
            println!(
                "e = {e}, {label}: errors {:?}, fitted order {p:.3}",
                pts.iter().map(|p| format!("{:.3e}", p.1)).collect::<Vec<_>>()
            );
            assert!((p - order).abs() < 0.15, "e = {e}, {label}: order {p}, errors {pts:?}");
        }
    }
}

/// The largest symplecticity defect `max |MᵀJM − J|` of the steps of one
/// orbit, the largest entry of `M`, the condition of `∂²A/∂x_k∂x_{k+1}`,
/// and the largest `ε/(σ c g)` over the nodes. The map is symplectic by
/// construction (every block comes from one generating function); the
/// defect is the round-off of the implicit-function formulas for `M`.
fn worst_defect<I: SStepper<3, System = Tt>>(
    mut sim: Adaptive<I, Kepler, RadiusPower<2>, 2, 3>,
    mut condition: impl FnMut(&I) -> f64,
) -> (f64, f64, f64, f64) {
    let (mut worst, mut largest, mut cond) = (0.0f64, 0.0f64, 0.0f64);
    let (sigma, c) = (sim.step_size(), sim.inner().transformed().penalty());
    let mut gmin = sim.density();
    sim.run_until(2.0 * PI, |s| {
        let m = s.last_tangent_map().unwrap().matrix();
        largest = largest.max(m.amax());
        worst = worst.max(lagrangian::symplectic::defect(&m).unwrap());
        cond = cond.max(condition(s.inner()));
        gmin = gmin.min(s.density());
    })
    .unwrap();
    (worst, largest, cond, f64::EPSILON / (sigma * c * gmin))
}

/// The condition number (2-norm) of `∂²A/∂x_k∂x_{k+1}` of the last step.
fn a12_condition<M: DiscreteLagrangian>(i: &Integrator<Tt, M, 3>) -> f64 {
    let (a11, a12, a22) = lagrangian::derivatives::position_hessian(i.system(), i.method(), i.last_step().unwrap());
    let inv = a12.try_inverse().unwrap();
    inv.norm() * a11.norm().max(a12.norm()).max(a22.norm())
}

#[test]
fn symplectic_in_the_extended_phase_space() {
    for e in [0.9, 0.99] {
        for (label, (d, m, cond, scale)) in [
            ("midpoint", worst_defect(rule(Midpoint, e, 0.02), a12_condition)),
            ("midpoint", worst_defect(rule(Midpoint, e, 0.005), a12_condition)),
            ("trapezoid", worst_defect(rule(Trapezoid, e, 0.02), a12_condition)),
            ("galerkin 2", worst_defect(galerkin::<2>(e, 0.1), |_| f64::NAN)),
        ] {
            println!(
                "e = {e}, {label}: defect {d:.2e} = {:.2} ε/(σ c g_min) (ε/(σ c g_min) = {scale:.2e}), largest entry {m:.2}, ε‖A12⁻¹‖·‖A‖ up to {:.2e}",
                d / scale,
                f64::EPSILON * cond
            );
            // Measured 4e-12 … 3e-9, far above the 5e-16 of fixed steps
            // (below) and 10–200 times ε‖A12⁻¹‖‖A‖, but 0.11–0.40 (one-point
            // rules) and 3.6–6.1 (Galerkin s = 2, whose nodes are σ/2 apart)
            // times ε/(σ c g_min): the tangent-map formula adds terms of size
            // 1/(σ c g) (the second derivative of the `(t' − g)²/(2cg)` term)
            // that cancel. Not the Newton tolerance (the same at rtol 1e-14
            // and 4e-16; the midpoint solves by full Newton). A non-symplectic
            // method of this accuracy has defects of the size of its local
            // error (≥ 1e-6 here). Margin: 2.5× the largest ratio measured.
            let bound = if label == "galerkin 2" { 15.0 } else { 1.0 };
            assert!(d <= bound * scale, "e = {e}, {label}: {d} = {} ε/(σ c g_min), entries up to {m}", d / scale);
        }
    }
    // For scale: fixed-step midpoint on the same orbit (h = 1e-3, t ≤ 1).
    let (q0, v0) = kepler_start(0.9);
    let mut sim = Integrator::new(Kepler, Midpoint, 1e-3).start(0.0, q0, v0).unwrap();
    let mut worst = 0.0f64;
    sim.run(1000, |s| worst = worst.max(s.last_tangent_map().unwrap().symplecticity_defect())).unwrap();
    println!("fixed-step midpoint, h = 1e-3: defect {worst:.2e}");
}

/// `L = ½ v² − ½ q²`.
#[derive(Debug, Clone, Copy)]
pub struct Oscillator;

#[lagrangian]
impl Oscillator {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }
}

/// `g = q[0]`: crosses zero with the oscillator.
#[derive(Debug, Clone, Copy)]
struct Position;

impl StepDensity<1> for Position {
    fn density<S: Lagrangian<1> + ?Sized, D: Scalar>(&self, _s: &S, _t: D, q: &[D; 1]) -> D {
        q[0]
    }
}

/// `g = 1` up to `t = 0.5`, NaN after.
#[derive(Debug, Clone, Copy)]
struct NanAfterHalf;

impl StepDensity<1> for NanAfterHalf {
    const TIME_DEPENDENT: bool = true;
    fn density<S: Lagrangian<1> + ?Sized, D: Scalar>(&self, _s: &S, t: D, _q: &[D; 1]) -> D {
        if t.re() > 0.5 { D::from(f64::NAN) } else { D::one() }
    }
}

/// `g = (1 − t)²`: the steps collapse as `t → 1`.
#[derive(Debug, Clone, Copy)]
struct Collapsing;

impl StepDensity<1> for Collapsing {
    const TIME_DEPENDENT: bool = true;
    fn density<S: Lagrangian<1> + ?Sized, D: Scalar>(&self, _s: &S, t: D, _q: &[D; 1]) -> D {
        (D::one() - t) * (D::one() - t)
    }
}

/// `g = 1/(1 + ½ sin 3t)`, time-dependent.
#[derive(Debug, Clone, Copy)]
struct Breathing;

impl StepDensity<1> for Breathing {
    const TIME_DEPENDENT: bool = true;
    fn density<S: Lagrangian<1> + ?Sized, D: Scalar>(&self, _s: &S, t: D, _q: &[D; 1]) -> D {
        ((t * 3.0).sin() * 0.5 + 1.0).recip()
    }
}

#[test]
fn a_density_that_is_not_positive_is_refused_with_the_state_kept() {
    let err = TimeTransformed::new(Oscillator, Position).rule(Midpoint, 0.1).start(0.0, [-0.5], [0.0]).unwrap_err();
    assert!(matches!(err, Error::InvalidDensity { value, .. } if value == -0.5), "{err:?}");
    // A g that turns NaN inside a step: that step is refused, the state kept.
    let mut sim = TimeTransformed::new(Oscillator, NanAfterHalf).rule(Midpoint, 0.07).start(0.0, [1.0], [0.0]).unwrap();
    let err = sim.run_until(1.0, |_| {}).unwrap_err();
    let Error::InvalidDensity { state, value } = err else { panic!("{err:?}") };
    assert!(value.is_nan() && state == sim.state() && state.t <= 0.5 && state.t > 0.4, "{state:?}");
}

/// The state carried by the error that ends a run whose steps collapse:
/// either a step fell below the time-step floor or the rate `t'/g` jumped
/// (a lost orbit) first; both are refusals with the state kept.
fn collapse_state<const N: usize, T: Real>(err: Error<T>) -> State<N, T> {
    match err {
        Error::TimeStepCollapsed { state, dt, floor } => {
            assert!(dt < floor, "{dt} {floor}");
            state.try_into().unwrap()
        }
        Error::OrbitLost { state, factor } => {
            assert!(!(0.5..=2.0).contains(&factor), "{factor}");
            state.try_into().unwrap()
        }
        _ => panic!("{err:?}"),
    }
}

#[test]
fn collapsing_steps_end_in_a_typed_error_not_a_hang() {
    let mut sim = TimeTransformed::new(Oscillator, Collapsing).rule(Midpoint, 0.1).start(0.0, [1.0], [0.0]).unwrap();
    // As g = (1 − t)² collapses, g'/g grows without bound: the steps either
    // fall below the time-step floor or stop following the flow (the rate
    // t'/g jumps) first; both are refused with the state kept, before t = 1.
    let state = collapse_state(sim.run_until(2.0, |_| {}).unwrap_err());
    assert!(state == sim.state() && state.t < 1.0 && state.t > 0.9, "{state:?}");
}

#[test]
fn invalid_settings_and_targets_are_typed_errors() {
    let start = |b: lagrangian::time_transform::TimeTransformedBuilder<Oscillator, RadiusPower<1>, _, 1>| {
        b.start(0.0, [1.0], [0.0]).map(|_| ())
    };
    let g = RadiusPower::new([0], 1.0).unwrap();
    let bad = RadiusPower::new([3], 1.0).unwrap();
    assert!(RadiusPower::new([0], f64::NAN).is_none());
    assert!(Curvature::new(0.0).is_none());
    for sigma in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = start(TimeTransformed::new(Oscillator, g).rule(Midpoint, sigma)).unwrap_err();
        assert!(matches!(e, Error::InvalidSetting { .. }), "{e:?}");
    }
    let e = start(TimeTransformed::new(Oscillator, bad).rule(Midpoint, 0.1)).unwrap_err();
    assert!(matches!(e, Error::InvalidSetting { .. }), "{e:?}");
    let e = start(TimeTransformed::new(Oscillator, g).rule(Midpoint, 0.1).penalty(-1.0)).unwrap_err();
    assert!(matches!(e, Error::InvalidSetting { .. }), "{e:?}");
    let e = start(TimeTransformed::new(Oscillator, g).rule(Midpoint, 0.1).min_time_step(f64::NAN)).unwrap_err();
    assert!(matches!(e, Error::InvalidSetting { .. }), "{e:?}");
    let e = TimeTransformed::new(Oscillator, g).rule(Midpoint, 0.1).start(0.0, [f64::NAN], [0.0]).unwrap_err();
    assert!(matches!(e, Error::InvalidInitialData { .. }), "{e:?}");
    let mut sim = TimeTransformed::new(Oscillator, Breathing).rule(Midpoint, 0.1).start(0.0, [1.0], [0.0]).unwrap();
    sim.run_until(1.0, |_| {}).unwrap();
    for target in [0.5, f64::NAN, f64::INFINITY] {
        let before = sim.state();
        let e = sim.run_until(target, |_| {}).unwrap_err();
        assert!(matches!(e, Error::InvalidTarget { .. }), "{e:?}");
        assert_eq!(sim.state(), before);
    }
    // The current time is a no-op; many targets are hit exactly.
    sim.run_until(1.0, |_| {}).unwrap();
    for k in 101..=300 {
        let t = k as f64 / 100.0;
        sim.run_until(t, |_| {}).unwrap();
        assert_eq!(sim.state().t, t);
    }
}

/// The driven RLC circuit (time-dependent force and dissipation) with a
/// time-dependent monitor: order 2 (midpoint) and 4 (Galerkin s = 2)
/// against the exact response, Lagrange–d'Alembert in `s`.
#[test]
fn time_dependent_forces_keep_the_order() {
    let rlc = || common::forced::Rlc { l: 0.5, r: 1.5, c: 0.02, e0: 10.0, omega: 7.0 };
    let t_end = 2.0;
    let exact = rlc().exact(t_end)[0];
    let err_mid = |s: f64| {
        let mut sim = TimeTransformed::new(rlc(), Breathing).rule(Midpoint, s).start(0.0, [0.0], [0.0]).unwrap();
        sim.run_until(t_end, |_| {}).unwrap();
        (s, (sim.state().q[0] - exact).abs())
    };
    let err_g2 = |s: f64| {
        let mut sim = TimeTransformed::new(rlc(), Breathing)
            .galerkin(Galerkin::<2, 2>::gauss(), s)
            .start(0.0, [0.0], [0.0])
            .unwrap();
        sim.run_until(t_end, |_| {}).unwrap();
        (s, (sim.state().q[0] - exact).abs())
    };
    let mid: Vec<_> = [0.02, 0.01, 0.005].map(err_mid).to_vec();
    let g2: Vec<_> = [0.05, 0.025, 0.0125].map(err_g2).to_vec();
    let (pm, pg) = (fitted_order(&mid), fitted_order(&g2));
    println!("driven RLC: midpoint {mid:?} order {pm:.3}; galerkin 2 {g2:?} order {pg:.3}");
    assert!((pm - 2.0).abs() < 0.15, "{mid:?}");
    assert!((pg - 4.0).abs() < 0.15, "{g2:?}");
}

/// The transformed system in double-double through the driver: Galerkin
/// s = 4 in `s` with order 2s = 8 in σ down to errors far below the `f64`
/// floor. Kepler e = 0.5 from pericentre, `g = r^{3/2}`, `c = 1`, over
/// s ∈ [0, 4]; errors of `x = (q, t)` against a run with 1024 steps.
#[test]
fn double_double_galerkin_in_s_has_order_eight() {
    use lagrangian::NewtonOptions;
    type Dd = DoubleDouble;
    let e = 0.5;
    let (q0, v0) = kepler_start(e);
    // The transformed system with its constant, for an integrator of one's own.
    assert!(TimeTransformed::new(Kepler, r32()).with_penalty(1.0).is_some());
    assert!(TimeTransformed::new(Kepler, r32()).with_penalty(0.0).is_none());
    let span = Dd::from(4.0);
    let run = |n: usize| -> [Dd; 3] {
        let newton = NewtonOptions { rtol: 1e-30, ..NewtonOptions::default() };
        let mut sim = TimeTransformed::new(Kepler, r32())
            .galerkin(Galerkin::<4, 4, Dd>::gauss(), span / n as f64)
            .penalty(1.0)
            .newton(newton)
            .start(Dd::from(0.0), q0.map(Dd::from), v0.map(Dd::from))
            .expect("the transformed system starts in double-double");
        sim.run(n, |_| {}).expect("the steps converge");
        assert!((sim.extended_state().t - span).abs().to_f64() < 1e-30, "s after n steps of span/n");
        sim.extended_state().q
    };
    let reference = run(1024);
    let points: Vec<(f64, f64)> = [64usize, 91, 128, 181, 256]
        .iter()
        .map(|&n| {
            let x = run(n);
            let err = (0..3).map(|i| (x[i] - reference[i]).abs().to_f64()).fold(0.0, f64::max);
            (4.0 / n as f64, err)
        })
        .collect();
    let order = fitted_order(&points);
    println!("double-double Galerkin s = 4 in s: errors {points:?}, fitted order {order:.3}");
    assert!((order - 8.0).abs() <= 0.15, "{order}");
    // Far below what f64 can resolve (|x| ≈ 1, t ≈ 4: ulp ≈ 1e-15).
    assert!(points.last().unwrap().1 < 1e-17, "{points:?}");
    // Physical time advanced and the orbit stayed bound.
    assert!(reference[2].to_f64() > 0.0 && reference[0].to_f64().hypot(reference[1].to_f64()) < 1.5 / (1.0 - e));
}

/// Kepler e = 0.9 from pericentre in double-double.
fn kepler_start_dd(e: DoubleDouble) -> ([DoubleDouble; 2], [DoubleDouble; 2]) {
    use lagrangian::num_dual::DualNum;
    let one = DoubleDouble::from(1.0);
    ([one - e, DoubleDouble::from(0.0)], [DoubleDouble::from(0.0), ((one + e) / (one - e)).sqrt()])
}

/// The driver in double-double: Kepler e = 0.9 from pericentre to t = 1,
/// `g = r^{3/2}`, midpoint and Galerkin s = 2 in `s`, landing on `t = 1`
/// with `run_until`; position errors against Kepler's equation solved in
/// double-double. Order 2 and 4, and Galerkin s = 2 down to errors that
/// `f64` cannot represent.
#[test]
fn double_double_driver_keeps_the_orders_below_the_f64_floor() {
    type Dd = DoubleDouble;
    let e = Dd::from(0.9);
    let (q0, v0) = kepler_start_dd(e);
    let t_end = Dd::from(1.0);
    let exact = kepler_position(e, t_end);
    let error = |s: State<2, Dd>| {
        assert_eq!(s.t, t_end, "run_until lands exactly");
        (0..2).map(|i| (s.q[i] - exact[i]).abs().to_f64()).fold(0.0, f64::max)
    };
    let tt = || TimeTransformed::new(Kepler, r32());
    let mid = |sigma: f64| {
        let mut sim = tt().rule(Midpoint, Dd::from(sigma)).start(Dd::from(0.0), q0, v0).unwrap();
        sim.run_until(t_end, |_| {}).unwrap();
        (sigma, error(sim.state()))
    };
    let g2 = |sigma: f64| {
        let mut sim =
            tt().galerkin(Galerkin::<2, 2, Dd>::gauss(), Dd::from(sigma)).start(Dd::from(0.0), q0, v0).unwrap();
        sim.run_until(t_end, |_| {}).unwrap();
        (sigma, error(sim.state()))
    };
    let mid: Vec<_> = [0.01, 0.005, 0.0025].map(mid).to_vec();
    let g2: Vec<_> = [1e-3, 5e-4, 2.5e-4].map(g2).to_vec();
    let (pm, pg) = (fitted_order(&mid), fitted_order(&g2));
    println!("double-double driver, e = 0.9, t = 1: midpoint {mid:?} order {pm:.4}; galerkin 2 {g2:?} order {pg:.4}");
    assert!((pm - 2.0).abs() < 0.15, "{mid:?}");
    assert!((pg - 4.0).abs() < 0.15, "{g2:?}");
    // Measured 3.3e-14 at σ = 2.5e-3 and order 4.000 above: 3.3e-18 here.
    assert!(g2.last().unwrap().1 < 1e-17, "{g2:?}");
}

/// The double-double driver over 4 orbits of Kepler e = 0.9 (Galerkin s = 2,
/// σ = 0.02), landing on every orbit: `t` exact at each, the energy error
/// bounded without a trend, `p_t` and the angular momentum far below `f64`
/// round-off (its default Newton tolerance is two units of double-double).
#[test]
fn double_double_driver_energy_is_bounded_and_landings_exact() {
    use lagrangian::num_dual::DualNum;
    type Dd = DoubleDouble;
    let e = Dd::from(0.9);
    let (q0, v0) = kepler_start_dd(e);
    let mut sim = TimeTransformed::new(Kepler, r32())
        .galerkin(Galerkin::<2, 2, Dd>::gauss(), Dd::from(0.02))
        .start(Dd::from(0.0), q0, v0)
        .unwrap();
    let e0 = sim.energy().unwrap();
    let (pt0, j0) = (sim.time_momentum(), angular_dd(&sim.state()));
    let two_pi = Dd::from(1.0).atan() * 8.0;
    let orbits = 4;
    let mut maxima = vec![0.0f64; orbits];
    let (mut jmax, mut ptmax) = (0.0f64, 0.0f64);
    for (k, max) in maxima.iter_mut().enumerate() {
        let target = two_pi * (k + 1) as f64;
        sim.run_until(target, |s| {
            *max = max.max(((s.energy().unwrap() - e0) / e0).abs().to_f64());
            jmax = jmax.max(((angular_dd(&s.state()) - j0) / j0).abs().to_f64());
            ptmax = ptmax.max(((s.time_momentum() - pt0) / pt0).abs().to_f64());
        })
        .unwrap();
        assert_eq!(sim.state().t, target);
        assert!(sim.last_time_step().unwrap().to_f64() > 0.0 && sim.min_time_step().to_f64() > 0.0);
    }
    let x = kepler_position(e, two_pi * orbits as f64);
    let q = sim.state().q;
    let position = (q[0] - x[0]).to_f64().hypot((q[1] - x[1]).to_f64());
    println!(
        "double-double driver, galerkin 2, σ = 0.02, {orbits} orbits: {} steps, per-orbit energy maxima {:?}, trend {:.4}, J {jmax:.1e}, p_t {ptmax:.1e}, position {position:.2e}",
        sim.stats().steps,
        maxima.iter().map(|m| format!("{m:.3e}")).collect::<Vec<_>>(),
        trend(&maxima)
    );
    assert!(trend(&maxima) < 0.2, "{maxima:?}");
    // Orbit 4 repeats orbit 1 (a drift of 1e-16 per step, the f64 default
    // tolerance, would not show here; round-off of double-double cannot).
    assert!((maxima[3] / maxima[0] - 1.0).abs() < 0.05, "{maxima:?}");
    assert!(jmax < 1e-25 && ptmax < 1e-25, "J {jmax:e}, p_t {ptmax:e}");
    // The f64 run at 5σ over 10 orbits ends 2.4e-5 away (order 4 in σ).
    assert!(position < 1e-5, "{position:e}");
}

fn angular_dd(s: &State<2, DoubleDouble>) -> DoubleDouble {
    s.q[0] * s.p[1] - s.q[1] * s.p[0]
}

/// Kepler with its monitor in the `#[lagrangian]` block.
#[derive(Debug, Clone, Copy)]
pub struct KeplerWithDensity;

#[lagrangian]
impl KeplerWithDensity {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }

    fn step_density(&self, q: [f64; 2]) -> f64 {
        (q[0] * q[0] + q[1] * q[1]).powf(0.75)
    }
}

/// A time-dependent monitor written in the block: `g = 1/(1 + ½ sin 3t)`.
#[derive(Debug, Clone, Copy)]
pub struct OscillatorWithDensity;

#[lagrangian]
impl OscillatorWithDensity {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }

    fn step_density(&self, t: f64, _q: [f64; 1]) -> f64 {
        1.0 / (1.0 + 0.5 * (3.0 * t).sin())
    }
}

/// `step_density` in the block gives the steps of the runtime's monitor with
/// the same formula: `r^{3/2}` against `RadiusPower([0, 1], 1.5)` (midpoint
/// and Galerkin s = 2, 300 steps on Kepler e = 0.9), and the time-dependent
/// `Breathing` on the oscillator. Compared bit for bit where the formulas
/// round the same way.
#[test]
fn step_density_in_the_block_equals_the_runtime_monitor() {
    const { assert!(!<KeplerWithDensity as StepDensity<2>>::TIME_DEPENDENT) };
    const { assert!(<OscillatorWithDensity as StepDensity<1>>::TIME_DEPENDENT) };
    let (q0, v0) = kepler_start(0.9);
    let mut own = TimeTransformed::with_own_density(KeplerWithDensity).rule(Midpoint, 0.02).start(0.0, q0, v0).unwrap();
    let mut lib = TimeTransformed::new(Kepler, r32()).rule(Midpoint, 0.02).start(0.0, q0, v0).unwrap();
    let mut own2 = TimeTransformed::with_own_density(KeplerWithDensity)
        .galerkin(Galerkin::<2, 2>::gauss(), 0.1)
        .start(0.0, q0, v0)
        .unwrap();
    let mut lib2 = galerkin::<2>(0.9, 0.1);
    let (mut worst, mut worst2) = (0.0f64, 0.0f64);
    for _ in 0..300 {
        let (a, b) = (own.step().unwrap(), lib.step().unwrap());
        let (c, d) = (own2.step().unwrap(), lib2.step().unwrap());
        for i in 0..2 {
            worst = worst.max((a.q[i] - b.q[i]).abs()).max((a.p[i] - b.p[i]).abs());
            worst2 = worst2.max((c.q[i] - d.q[i]).abs()).max((c.p[i] - d.p[i]).abs());
        }
        worst = worst.max((a.t - b.t).abs());
        worst2 = worst2.max((c.t - d.t).abs());
    }
    println!("step_density against RadiusPower over 300 steps: midpoint {worst:e}, galerkin 2 {worst2:e}");
    // `(x² + y²)^0.75` and RadiusPower's `(x² + y²)^(0.5 · 1.5)` are the same operations.
    assert_eq!((worst, worst2), (0.0, 0.0));
    let mut own =
        TimeTransformed::with_own_density(OscillatorWithDensity).rule(Midpoint, 0.1).start(0.0, [1.0], [0.0]).unwrap();
    let mut lib = TimeTransformed::new(Oscillator, Breathing).rule(Midpoint, 0.1).start(0.0, [1.0], [0.0]).unwrap();
    own.run_until(3.0, |_| {}).unwrap();
    lib.run_until(3.0, |_| {}).unwrap();
    let (a, b) = (own.state(), lib.state());
    println!("time-dependent step_density: {a:?} against {b:?}");
    assert!((a.q[0] - b.q[0]).abs() <= 1e-14 && (a.p[0] - b.p[0]).abs() <= 1e-14 && a.step == b.step, "{a:?} {b:?}");
}

/// Bad monitors through the double-double driver: typed errors, state kept,
/// no hang (as in `f64` above).
#[test]
fn double_double_driver_refuses_bad_monitors_with_the_state_kept() {
    type Dd = DoubleDouble;
    let d = Dd::from;
    let err = TimeTransformed::new(Oscillator, Position).rule(Midpoint, d(0.1)).start(d(0.0), [d(-0.5)], [d(0.0)]);
    assert!(matches!(err, Err(Error::InvalidDensity { value, .. }) if value == -0.5), "{err:?}");
    let mut sim = TimeTransformed::new(Oscillator, NanAfterHalf)
        .rule(Midpoint, d(0.07))
        .start(d(0.0), [d(1.0)], [d(0.0)])
        .unwrap();
    let err = sim.run_until(d(1.0), |_| {}).unwrap_err();
    let Error::InvalidDensity { state, value } = err else { panic!("{err:?}") };
    assert!(value.is_nan() && state == sim.state() && state.t.to_f64() <= 0.5 && state.t.to_f64() > 0.4, "{state:?}");
    let mut sim =
        TimeTransformed::new(Oscillator, Collapsing).rule(Midpoint, d(0.1)).start(d(0.0), [d(1.0)], [d(0.0)]).unwrap();
    let state = collapse_state(sim.run_until(d(2.0), |_| {}).unwrap_err());
    assert!(state == sim.state() && state.t.to_f64() < 1.0 && state.t.to_f64() > 0.9, "{state:?}");
    let e = sim.run_until(d(f64::NAN), |_| {}).unwrap_err();
    assert!(matches!(e, Error::InvalidTarget { .. }), "{e:?}");
}
