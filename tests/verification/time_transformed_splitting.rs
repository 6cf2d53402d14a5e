//! The explicit time-transformed splitting (docs/time-transformation.md,
//! "Explicit splitting for separable systems"): Kepler e = 0.9 and e = 0.99
//! with the leapfrog and the compositions of order 4, 6, 8 in `σ` (fitted
//! order, energy bounded without drift, angular momentum at round-off,
//! position error against Kepler's equation, the logarithmic Hamiltonian's
//! positions on the exact ellipse), symplecticity of the extended map in
//! double-double, a time-dependent potential, bad input.
//!
//! The 200-orbit drift checks are ignored:
//! `cargo test --release --test verification time_transformed_splitting:: -- --ignored --nocapture`.
use crate::common;
// The Kepler system and its exact orbit are those of the implicit path's tests.
use crate::time_transformed::{Kepler, angular, fitted_order, kepler_position, kepler_start, trend};

use common::SlowOscillator;
use lagrangian::prelude::*;
use std::f64::consts::PI;

/// The methods: (label, composition or the leapfrog, order).
const METHODS: [(&str, Option<Composition>, u32); 4] = [
    ("leapfrog", None, 2),
    ("yoshida-4", Some(Composition::YOSHIDA4), 4),
    ("yoshida-6", Some(Composition::YOSHIDA6), 6),
    ("kahan-li-8", Some(Composition::KAHAN_LI8), 8),
];

fn kepler(e: f64, f: TimeFunction, composition: Option<Composition>, sigma: f64) -> ExplicitAdaptive<Kepler, f64, 2> {
    let (q0, v0) = kepler_start(e);
    let mut b = ExplicitTimeTransformed::new(Kepler, f, sigma);
    if let Some(c) = composition {
        b = b.composition(c);
    }
    b.start(0.0, q0, v0).unwrap()
}

/// `|q(T) − q_exact(T)|` after `orbits` orbits.
fn position_error(mut sim: ExplicitAdaptive<Kepler, f64, 2>, e: f64, orbits: f64) -> f64 {
    let t = 2.0 * PI * orbits;
    sim.run_until(t, |_| {}).unwrap();
    assert_eq!(sim.state().t, t);
    let x = kepler_position(e, t);
    (sim.state().q[0] - x[0]).hypot(sim.state().q[1] - x[1])
}

/// `σ0` of the order fits (the σ are `σ0 · {1, 0.8, 0.65, 0.5}`): ranges
/// where each method is asymptotic and above round-off. The s-period of
/// `g = r` is 2π for every e; the logarithmic leapfrog's along-track error
/// at e = 0.99 needs much smaller steps to be asymptotic.
fn order_sigma(e: f64, f: TimeFunction, order: u32) -> f64 {
    match (e == 0.99, f, order) {
        (false, TimeFunction::Logarithmic, 2) => 0.02,
        (false, TimeFunction::Logarithmic, 4) => 0.1,
        (false, TimeFunction::Logarithmic, 6) => 0.15,
        (false, TimeFunction::Logarithmic, _) => 0.4,
        (true, TimeFunction::Logarithmic, 2) => 0.002,
        (true, TimeFunction::Logarithmic, 4) => 0.01,
        (true, TimeFunction::Logarithmic, 6) => 0.06,
        (true, TimeFunction::Logarithmic, _) => 0.3,
        (_, _, 2) => 0.01,
        (_, _, 4) => 0.05,
        (_, _, 6) => 0.08,
        (false, _, _) => 0.2,
        (true, _, _) => 0.25,
    }
}

#[test]
fn order_in_the_step() {
    for e in [0.9, 0.99] {
        for f in [TimeFunction::Logarithmic, TimeFunction::Power(1.5)] {
            for (label, comp, order) in METHODS {
                let s0 = order_sigma(e, f, order);
                // The error after one orbit (at pericentre, where it is
                // largest); for Kahan–Li 8 with r^{3/2} at e = 0.99 its
                // ratios there are irregular (fitted 7.78 on σ = 0.3 … 0.15),
                // so that case is measured at apocentre, after 1.5 orbits.
                let orbits = if e == 0.99 && order == 8 && f == R32 { 1.5 } else { 1.0 };
                let pts: Vec<(f64, f64)> = [1.0, 0.8, 0.65, 0.5]
                    .iter()
                    .map(|&k| (s0 * k, position_error(kepler(e, f, comp, s0 * k), e, orbits)))
                    .collect();
                let p = fitted_order(&pts);
                println!(
                    "e = {e}, {f:?}, {label}: errors {:?}, fitted order {p:.3}",
                    pts.iter().map(|p| format!("{:.3e}", p.1)).collect::<Vec<_>>()
                );
                assert!((p - order as f64).abs() < 0.15, "e = {e}, {f:?}, {label}: order {p}, {pts:?}");
            }
        }
    }
}

/// What one Kepler run measured.
#[derive(Debug)]
struct Run {
    steps: u64,
    position_error: f64,
    /// `max |E − E0|/|E0|` over the steps.
    energy_error: f64,
    /// `|b| K / mean(m)` of the line `m_k ≈ a + b k` through the per-orbit
    /// maxima `m_k` of the energy error: about 2 for an error growing
    /// linearly from zero, near 0 for a bounded one.
    energy_trend: f64,
    /// `max |J − J0|/|J0|`.
    angular_momentum: f64,
    /// `max |p_t − p_t0|`.
    time_momentum: f64,
}

fn measure(mut sim: ExplicitAdaptive<Kepler, f64, 2>, e: f64, orbits: usize) -> Run {
    let e0 = sim.energy();
    let j0 = angular(&sim.state());
    let pt0 = sim.time_momentum();
    let (mut jmax, mut ptmax) = (0.0f64, 0.0f64);
    let mut maxima = vec![0.0f64; orbits];
    let t_end = 2.0 * PI * orbits as f64;
    sim.run_until(t_end, |s| {
        let k = ((s.state().t / (2.0 * PI)) as usize).min(orbits - 1);
        maxima[k] = maxima[k].max(((s.energy() - e0) / e0).abs());
        jmax = jmax.max(((angular(&s.state()) - j0) / j0).abs());
        ptmax = ptmax.max((s.time_momentum() - pt0).abs());
    })
    .unwrap();
    let x = kepler_position(e, t_end);
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

/// `(e, f, composition, σ, position tolerance, energy tolerance)`.
type Case = (f64, TimeFunction, Option<Composition>, f64, f64, f64);

/// Runs with the settings the benchmark picks near 1e-6 … 1e-9 (Kahan–Li 8
/// and Yoshida 6 with `g = r^{3/2}`) and the leapfrogs; tolerances about
/// three times the errors measured, so a change of order or error constant
/// fails.
fn invariants(orbits: usize, cases: &[Case]) {
    for &(e, f, comp, sigma, pos, en) in cases {
        let run = measure(kepler(e, f, comp, sigma), e, orbits);
        let label = comp.map_or("leapfrog".to_string(), |c| format!("order {}", c.order()));
        println!(
            "e = {e}, {f:?}, {label}, σ = {sigma}, {orbits} orbits: {} steps, position {:.2e}, energy {:.2e} (trend {:.3}), J {:.1e}, p_t {:.1e}",
            run.steps, run.position_error, run.energy_error, run.energy_trend, run.angular_momentum, run.time_momentum
        );
        assert!(run.position_error < pos, "{label}: {run:?}");
        assert!(run.energy_error < en, "{label}: {run:?}");
        // A trend is only meaningful above round-off: the logarithmic
        // drift–kick–drift keeps the Kepler energy to round-off (1e-13 …
        // 1e-11, which wanders).
        if run.energy_error > 1e-10 {
            assert!(run.energy_trend < 0.2, "{label}: the energy drifts: {run:?}");
        }
        // Round-off accumulated over up to 1e6 kicks: each kick is along
        // −∇V ∥ q (central force), so J changes only by rounding.
        assert!(run.angular_momentum < 3e-15 * (run.steps as f64).sqrt(), "{label}: {run:?}");
        // No kick changes p_t for an autonomous L: exactly constant.
        assert_eq!(run.time_momentum, 0.0, "{label}: {run:?}");
    }
}

const R32: TimeFunction = TimeFunction::Power(1.5);
const LOG: TimeFunction = TimeFunction::Logarithmic;

#[test]
fn kepler_invariants_ten_orbits() {
    invariants(
        10,
        &[
            (0.9, R32, None, 0.01, 1.6e-3, 1.5e-4),
            (0.9, R32, Some(Composition::KAHAN_LI8), 0.2, 4.5e-9, 5e-10),
            (0.9, LOG, Some(Composition::KAHAN_LI8), 0.2, 7e-9, 1e-12),
            (0.99, R32, None, 0.01, 5.5e-3, 1.8e-3),
            (0.99, R32, Some(Composition::KAHAN_LI8), 0.2, 1.2e-8, 6e-9),
            (0.99, LOG, Some(Composition::YOSHIDA6), 0.05, 8e-8, 3e-12),
        ],
    );
}

#[test]
#[ignore = "200 orbits: a few seconds in release; run with --release --ignored"]
fn kepler_energy_without_drift_two_hundred_orbits() {
    invariants(
        200,
        &[
            (0.9, R32, None, 0.01, 3.3e-2, 1.5e-4),
            (0.9, R32, Some(Composition::KAHAN_LI8), 0.2, 9e-8, 5e-10),
            (0.9, LOG, Some(Composition::KAHAN_LI8), 0.2, 1.4e-7, 2e-12),
            (0.99, R32, None, 0.01, 9e-2, 1.8e-3),
            (0.99, R32, Some(Composition::KAHAN_LI8), 0.2, 2.4e-7, 6e-9),
            (0.99, LOG, Some(Composition::YOSHIDA6), 0.05, 1.6e-6, 3e-11),
        ],
    );
}

/// Preto & Tremaine's property: the leapfrog of the logarithmic Hamiltonian
/// with `c = 0` moves a Kepler orbit along one fixed ellipse; only the phase
/// is wrong. The conic `r + e_x x + e_y y = ℓ` (focus at the origin) is
/// solved from the first three nodes, and every later node must lie on it
/// to round-off, while the along-track error grows. Measured: this holds
/// for the drift–kick–drift form, whose nodes lie on the exact ellipse of
/// the initial data; the kick–drift–kick nodes only stay `O(σ²)` close.
#[test]
fn logarithmic_leapfrog_stays_on_the_ellipse() {
    let e = 0.9;
    for form in [LeapfrogForm::KickDriftKick, LeapfrogForm::DriftKickDrift] {
        let (q0, v0) = kepler_start(e);
        let sigma = 0.05;
        let mut sim = ExplicitTimeTransformed::new(Kepler, LOG, sigma).form(form).start(0.0, q0, v0).unwrap();
        assert_eq!(sim.shift(), 0.0);
        let mut nodes = vec![sim.state().q];
        sim.run(2, |s| nodes.push(s.state().q)).unwrap();
        // Solve [x y −1] (e_x, e_y, ℓ) = −r for the three nodes (Cramer).
        let rows: Vec<[f64; 4]> = nodes.iter().map(|q| [q[0], q[1], -1.0, -q[0].hypot(q[1])]).collect();
        let det3 = |m: [[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let a = [0, 1, 2].map(|i| [rows[i][0], rows[i][1], rows[i][2]]);
        let d = det3(a);
        let sol: [f64; 3] = core::array::from_fn(|k| {
            let mut m = a;
            for i in 0..3 {
                m[i][k] = rows[i][3];
            }
            det3(m) / d
        });
        let (ex, ey, ell) = (sol[0], sol[1], sol[2]);
        let mut off = 0.0f64;
        let mut exact_conic = 0.0f64;
        let mut along = Vec::new();
        for orbit in 1..=20 {
            sim.run_until(2.0 * PI * orbit as f64, |s| {
                let q = s.state().q;
                let r = q[0].hypot(q[1]);
                off = off.max((r + ex * q[0] + ey * q[1] - ell).abs());
                exact_conic = exact_conic.max((r + e * q[0] - (1.0 - e * e)).abs());
            })
            .unwrap();
            let x = kepler_position(e, sim.state().t);
            along.push((sim.state().q[0] - x[0]).hypot(sim.state().q[1] - x[1]));
        }
        println!(
            "{form:?}: ellipse (e_x, e_y, ℓ) = ({ex:.6}, {ey:.2e}, {ell:.6}); max off it {off:.2e}, off the initial data's {exact_conic:.2e}; along-track error after 1, 10, 20 orbits {:.2e} {:.2e} {:.2e}",
            along[0], along[9], along[19]
        );
        // KDK's nodes stay within O(σ²) of the ellipse but not on one fixed
        // conic (measured 9e-3 off the conic of its first nodes at σ = 0.05:
        // each landing step changes the σ its modified ellipse belongs to).
        if form == LeapfrogForm::DriftKickDrift {
            assert!(off < 1e-13 && exact_conic < 1e-13, "{form:?}: {off:e} {exact_conic:e}");
            assert!(along[0] > 1e9 * off && along[19] > 10.0 * along[0], "{form:?}: {along:?}");
        } else {
            assert!(exact_conic < 10.0 * sigma * sigma, "{form:?}: {exact_conic:e}");
        }
    }
}

/// `max |JᵀΩJ − Ω|` of the step map `(q, t, p, p_t) ↦ …`, `J` by central
/// differences in double-double (δ = 1e-10: truncation ~1e-20, rounding
/// ~1e-22), at points before, at and after pericentre.
#[test]
fn symplectic_in_the_extended_phase_space() {
    type Dd = DoubleDouble;
    let e = 0.9;
    let (q0, v0) = kepler_start(e);
    for (label, comp, form) in [
        ("leapfrog kdk", None, LeapfrogForm::KickDriftKick),
        ("leapfrog dkd", None, LeapfrogForm::DriftKickDrift),
        ("kahan-li 8", Some(Composition::KAHAN_LI8), LeapfrogForm::KickDriftKick),
    ] {
        for f in [LOG, R32] {
            let mut b = ExplicitTimeTransformed::new(Kepler, f, Dd::from(0.1)).form(form);
            if let Some(c) = comp {
                b = b.composition(c);
            }
            let mut sim = b.start(Dd::from(0.0), q0.map(Dd::from), v0.map(Dd::from)).unwrap();
            let mut worst = 0.0f64;
            for k in 0..3 {
                if k > 0 {
                    sim.run_until(Dd::from(0.4 * k as f64), |_| {}).unwrap();
                }
                let x = sim.extended_point();
                let flat =
                    |x: &lagrangian::time_transform::ExtendedPoint<Dd, 2>| [x.q[0], x.q[1], x.t, x.p[0], x.p[1], x.p_t];
                let x0 = flat(&x);
                let delta = Dd::from(1e-10);
                let mut jac = [[Dd::from(0.0); 6]; 6];
                for j in 0..6 {
                    let image = |sign: f64| {
                        let mut y = x0;
                        y[j] += delta * sign;
                        let point = lagrangian::time_transform::ExtendedPoint {
                            q: [y[0], y[1]],
                            t: y[2],
                            p: [y[3], y[4]],
                            p_t: y[5],
                        };
                        flat(&sim.map(point).unwrap())
                    };
                    let (plus, minus) = (image(1.0), image(-1.0));
                    for i in 0..6 {
                        jac[i][j] = (plus[i] - minus[i]) / (delta * 2.0);
                    }
                }
                // (JᵀΩJ)_{ab} = Σ_i J_{i a} J_{i+3, b} − J_{i+3, a} J_{i b}.
                for a in 0..6 {
                    for b in 0..6 {
                        let mut s = Dd::from(0.0);
                        for i in 0..3 {
                            s += jac[i][a] * jac[i + 3][b] - jac[i + 3][a] * jac[i][b];
                        }
                        let omega = if b == a + 3 {
                            1.0
                        } else if a == b + 3 {
                            -1.0
                        } else {
                            0.0
                        };
                        worst = worst.max((s - Dd::from(omega)).to_f64().abs());
                    }
                }
            }
            println!("{label}, {f:?}: max |JᵀΩJ − Ω| = {worst:.2e}");
            // Measured ≤ 1.4e-17; the f64 round-off of these maps is ~1e-15.
            assert!(worst < 1e-16, "{label}, {f:?}: {worst:e}");
        }
    }
}

/// A time-dependent potential: the slowly varying oscillator, whose energy
/// changes, against RK4 with 2e5 steps; the `∂_t V` kick keeps `p_t = −H`
/// to the method's order.
#[test]
fn time_dependent_potential() {
    let osc = SlowOscillator { eps: 0.3 };
    let t_end = 5.0;
    let (qr, vr) = osc.reference(1.0, 0.0, t_end, 200_000);
    for (comp, order, s0) in [(None, 2.0, 0.02), (Some(Composition::YOSHIDA4), 4.0, 0.01)] {
        let mut pts = Vec::new();
        let mut shells = Vec::new();
        for k in [1.0, 0.5, 0.25, 0.125] {
            let mut b = ExplicitTimeTransformed::new(osc, LOG, s0 * k);
            if let Some(c) = comp {
                b = b.composition(c);
            }
            let mut sim = b.start(0.0, [1.0], [0.0]).unwrap();
            let e0 = sim.energy();
            sim.run_until(t_end, |_| {}).unwrap();
            let s = sim.state();
            pts.push((s0 * k, (s.q[0] - qr).hypot(s.p[0] - vr)));
            shells.push((s0 * k, (sim.time_momentum() + sim.energy()).abs()));
            // The energy really changed: the kick in p_t is exercised.
            assert!((sim.energy() - e0).abs() > 0.05, "{}", sim.energy());
        }
        let p = fitted_order(&pts);
        let ps = fitted_order(&shells);
        println!("time-dependent, order {order}: errors {pts:?}, fitted {p:.3}; |p_t + H| {shells:?}, fitted {ps:.3}");
        assert!((p - order).abs() < 0.15, "{pts:?}");
        // |p_t + H| = O(σ^order) (not monotone for the leapfrog: bounded by
        // 3× the constant measured, 2.4 σ² and 383 σ⁴).
        let c = if order == 2.0 { 7.0 } else { 1200.0 };
        assert!(shells.iter().all(|&(s, d)| d < c * s.powf(order)), "{shells:?}");
    }
}

/// Position-dependent mass: quadratic kinetic energy, not constant mass.
#[derive(Debug, Clone, Copy)]
struct VariableMass;

#[lagrangian]
impl VariableMass {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * (1.0 + q[0] * q[0]) * v[0] * v[0] - 0.5 * q[0] * q[0]
    }
}

/// Constant mass but dissipative.
#[derive(Debug, Clone, Copy)]
struct Damped;

#[lagrangian]
impl Damped {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }

    fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.1 * v[0] * v[0]
    }
}

#[test]
fn non_separable_systems_are_refused() {
    let err = ExplicitTimeTransformed::new(VariableMass, LOG, 0.1).start(0.0, [1.0], [0.0]).unwrap_err();
    assert!(matches!(err, Error::NotSeparable { .. }), "{err:?}");
    assert!(err.to_string().contains("constant mass matrix"), "{err}");
    let err = ExplicitTimeTransformed::new(Damped, LOG, 0.1).start(0.0, [1.0], [0.0]).unwrap_err();
    assert!(matches!(err, Error::NotSeparable { .. }), "{err:?}");
}

#[test]
fn bad_settings_and_initial_data_are_typed_errors() {
    let (q0, v0) = kepler_start(0.9);
    let start = |f: TimeFunction, sigma: f64| ExplicitTimeTransformed::new(Kepler, f, sigma).start(0.0, q0, v0);
    for sigma in [0.0, -0.1, f64::NAN, f64::INFINITY] {
        assert!(matches!(start(LOG, sigma), Err(Error::InvalidSetting { .. })), "σ = {sigma}");
    }
    for alpha in [0.0, -1.0, f64::NAN] {
        assert!(matches!(start(TimeFunction::Power(alpha), 0.1), Err(Error::InvalidSetting { .. })));
    }
    for (q, v) in [([f64::NAN, 0.0], v0), (q0, [0.0, f64::INFINITY])] {
        let err = ExplicitTimeTransformed::new(Kepler, LOG, 0.1).start(0.0, q, v).unwrap_err();
        assert!(matches!(err, Error::InvalidInitialData { .. }), "{err:?}");
    }
    // c − V(q0) = −20 + 1/0.1 < 0.
    let err = ExplicitTimeTransformed::new(Kepler, LOG, 0.1).shift(-20.0).start(0.0, q0, v0).unwrap_err();
    assert!(matches!(err, Error::TimeFunctionArgument { which: Argument::Potential, .. }), "{err:?}");
    let mut sim = start(LOG, 0.1).unwrap();
    assert!(matches!(sim.set_step_size(0.0), Err(Error::InvalidSetting { .. })));
    assert!(matches!(sim.set_step_size(f64::NAN), Err(Error::InvalidSetting { .. })));
    assert_eq!(sim.step_size(), 0.1);
    sim.run(3, |_| {}).unwrap();
    let before = sim.state();
    let err = sim.run_until(before.t - 1.0, |_| {}).unwrap_err();
    assert!(matches!(err, Error::InvalidTarget { .. }), "{err:?}");
    assert_eq!(sim.state(), before);
}

use lagrangian::time_transform::Argument;

/// Kepler with the zero of `V` moved: `V = −1/r + ½`.
#[derive(Debug, Clone, Copy)]
struct OffsetKepler;

#[lagrangian]
impl OffsetKepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt() - 0.5
    }
}

/// The pendulum, `V = −g cos θ`.
#[derive(Debug, Clone, Copy)]
struct Pendulum;

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + 9.81 * q[0].cos()
    }
}

/// The default shift: `c = 0` where the start is a bound orbit of a
/// potential homogeneous of negative degree (Kepler, at every eccentricity
/// and in double-double too), `c = E + m` with
/// `m = max(T, |V|, |E|, |q·∇V|)` elsewhere, so `c − V ≥ m` on the energy
/// shell: the moved zero of an offset Kepler potential (where `c = 0` would
/// make `c − V = 1/r − ½` vanish at r = 2), a pendulum at rest just below
/// the horizontal (where `T`, `V` and `E` nearly vanish and `c = 0` gave the
/// density `1/(9.81 cos θ)` = 1e8 at the start), an unbound Kepler orbit.
#[test]
fn the_default_shift_keeps_the_time_function_argument_away_from_zero() {
    for e in [0.0, 0.5, 0.9, 0.99] {
        let (q0, v0) = kepler_start(e);
        let sim = ExplicitTimeTransformed::new(Kepler, LOG, 0.1).start(0.0, q0, v0).unwrap();
        assert_eq!(sim.shift(), 0.0, "e = {e}");
        let dd = ExplicitTimeTransformed::new(Kepler, R32, DoubleDouble::from(0.1))
            .start(DoubleDouble::from(0.0), q0.map(DoubleDouble::from), v0.map(DoubleDouble::from))
            .unwrap();
        assert_eq!(dd.shift().to_f64(), 0.0, "e = {e}");
    }
    // Offset Kepler from r = 1 with |v| = 0.5: T = 0.125, V = −0.5, E = −0.375, |q·∇V| = 1.
    let sim = ExplicitTimeTransformed::new(OffsetKepler, LOG, 0.1).start(0.0, [1.0, 0.0], [0.0, 0.5]).unwrap();
    assert_eq!(sim.shift(), -0.375 + 1.0);
    let forced = ExplicitTimeTransformed::new(OffsetKepler, LOG, 0.1).shift(0.0).start(0.0, [1.0, 0.0], [0.0, 0.5]);
    assert_eq!(forced.unwrap().shift(), 0.0);
    // The pendulum at rest 1e-9 below the horizontal: V = −9.8e-9 = E.
    let theta = std::f64::consts::FRAC_PI_2 - 1e-9;
    let sim = ExplicitTimeTransformed::new(Pendulum, LOG, 0.1).start(0.0, [theta], [0.0]).unwrap();
    let m = 9.81 * theta * theta.sin();
    assert!((sim.shift() - (sim.energy() + m)).abs() <= 1e-14 * m, "c = {}", sim.shift());
    assert!((sim.density() * m - 1.0).abs() <= 1e-12, "density {}", sim.density());
    // Unbound Kepler: c = E + max(T, |V|).
    let sim = ExplicitTimeTransformed::new(Kepler, LOG, 0.1).start(0.0, [1.0, 0.0], [0.0, 2.0]).unwrap();
    assert_eq!(sim.shift(), 1.0 + 2.0);
}

/// A shift that is positive at pericentre (`c − V = −5 + 1/r`) but not
/// beyond r = 0.2: the step that gets there fails, the state is kept, and
/// the next attempt fails the same way (no hang, no partial update).
#[test]
fn a_shift_too_small_for_the_orbit_fails_with_the_state_kept() {
    let (q0, v0) = kepler_start(0.9);
    let mut sim = ExplicitTimeTransformed::new(Kepler, LOG, 0.01).shift(-5.0).start(0.0, q0, v0).unwrap();
    let mut last = sim.state();
    let err = loop {
        match sim.step() {
            Ok(s) => {
                assert!(s.step < 10_000, "never failed");
                last = s;
            }
            Err(e) => break e,
        }
    };
    assert!(matches!(err, Error::TimeFunctionArgument { .. }), "{err:?}");
    assert_eq!(sim.state(), last);
    assert!(sim.state().q[0].hypot(sim.state().q[1]) > 0.15);
    assert_eq!(sim.step().unwrap_err(), err);
    assert_eq!(sim.state(), last);
}

#[test]
fn collapsing_steps_are_refused_with_the_state_kept() {
    let (q0, v0) = kepler_start(0.9);
    let mut sim = ExplicitTimeTransformed::new(Kepler, LOG, 0.01).min_time_step(1.0).start(0.0, q0, v0).unwrap();
    let before = sim.state();
    let err = sim.step().unwrap_err();
    assert!(matches!(err, Error::TimeStepCollapsed { .. }), "{err:?}");
    assert_eq!(sim.state(), before);
    assert_eq!(sim.stats().steps, 0);
    // A landing step may be short: run_until onto a time just ahead works.
    let mut sim = ExplicitTimeTransformed::new(Kepler, LOG, 0.01).start(0.0, q0, v0).unwrap();
    sim.run_until(1e-9, |_| {}).unwrap();
    assert_eq!(sim.state().t, 1e-9);
}

/// Double-double agrees with `f64` to the `f64` run's round-off, and its
/// landing hits the target to double-double precision.
#[test]
fn double_double_runs_agree() {
    let e = 0.9;
    let (q0, v0) = kepler_start(e);
    let mut a =
        ExplicitTimeTransformed::new(Kepler, R32, 0.1).composition(Composition::KAHAN_LI8).start(0.0, q0, v0).unwrap();
    let mut d = ExplicitTimeTransformed::new(Kepler, R32, DoubleDouble::from(0.1))
        .composition(Composition::KAHAN_LI8)
        .start(DoubleDouble::from(0.0), q0.map(DoubleDouble::from), v0.map(DoubleDouble::from))
        .unwrap();
    a.run_until(2.0 * PI, |_| {}).unwrap();
    d.run_until(DoubleDouble::from(2.0 * PI), |_| {}).unwrap();
    let dq = d.state().to_f64().q;
    let diff = (a.state().q[0] - dq[0]).hypot(a.state().q[1] - dq[1]);
    println!("f64 against double-double after one orbit: {diff:.2e}");
    assert!(diff < 1e-12, "{diff:e}");
    assert!((d.state().t - DoubleDouble::from(2.0 * PI)).abs().to_f64() < 1e-28);
    assert_eq!(a.stats().steps, d.stats().steps);
}
