//! Energy-preserving and energy-balance variable steps with holonomic
//! constraints: the step size is fixed by the discrete energy equation of
//! the unconstrained rule, at each trial size the constrained (RATTLE) step
//! is solved, so the discrete energy holds to the root's round-off while
//! `g` and `G v` hold to Newton's.
//!
//! The swinging Cartesian pendulum has no such steps all the way: the
//! `h²` coefficient of the constrained midpoint's energy error changes sign
//! on every swing (from `θ = 1` at rest, at `θ ≈ 0.795`), and there no step
//! size solves the energy equation (`Error::NoEnergyStep`, tested below).
//! The long runs use whirling motions, over the top, where the coefficient
//! keeps its sign.

use lagrangian::galerkin::Galerkin;
use lagrangian::prelude::*;

use super::{DoublePendulum, Lengthening, Pendulum, Spherical, fitted_order, rk4};

/// The relative distance of the node from the manifold and its tangent
/// space: `max |g_i| / ‖∇g_i‖` over `max(1, |q|)` and `max |(G v)_i| /
/// ‖∇g_i‖` over `|v|`, from the constraint values and velocities and the
/// gradients' norms `norms`.
fn off_manifold<const M: usize>(g: [f64; M], gv: [f64; M], norms: [f64; M], q: f64, v: f64) -> (f64, f64) {
    let position = (0..M).map(|i| g[i].abs() / norms[i]).fold(0.0, f64::max) / q.max(1.0);
    let velocity = (0..M).map(|i| gv[i].abs() / norms[i]).fold(0.0, f64::max) / v;
    (position, velocity)
}

/// What a long run of a constrained system reports.
#[derive(Debug)]
struct Run {
    /// The largest `|E_k − E_1| / |E_1|` over the nodes after the first.
    energy: f64,
    /// The largest relative `|g|` and `|G v|` (see [`off_manifold`]).
    position: f64,
    velocity: f64,
    /// The smallest and largest step.
    h_min: f64,
    h_max: f64,
}

/// `n` steps of `sim` after its first, watched, `also` called after each;
/// `norms` gives the gradient norms `‖∇g_i‖` at a node.
fn watch<S: Lagrangian<N>, const N: usize, const M: usize>(
    sim: &mut Integrator<S, Constrained<Midpoint, M>, N>,
    n: usize,
    norms: impl Fn(&[f64; N]) -> [f64; M],
    mut also: impl FnMut(&Integrator<S, Constrained<Midpoint, M>, N>),
) -> Run {
    sim.step().unwrap();
    let e1 = sim.discrete_energy();
    let mut run = Run { energy: 0.0, position: 0.0, velocity: 0.0, h_min: f64::INFINITY, h_max: 0.0 };
    sim.run(n, |s| {
        run.energy = run.energy.max((s.discrete_energy() - e1).abs() / e1.abs());
        let q = s.state().q;
        let v = s.velocity().unwrap();
        let size = |x: &[f64; N]| x.iter().map(|x| x * x).sum::<f64>().sqrt();
        let (position, velocity) =
            off_manifold(s.constraint_values(), s.constraint_velocities().unwrap(), norms(&q), size(&q), size(&v));
        run.position = run.position.max(position);
        run.velocity = run.velocity.max(velocity);
        let h = s.last_step_size().unwrap();
        (run.h_min, run.h_max) = (run.h_min.min(h), run.h_max.max(h));
        also(s);
    })
    .unwrap();
    run
}

/// `‖∇g‖ = 2|q|` for a unit circle or sphere.
fn sphere_norm<const N: usize>(q: &[f64; N]) -> [f64; 1] {
    [2.0 * q.iter().map(|x| x * x).sum::<f64>().sqrt()]
}

/// The two rods' gradient norms of the Cartesian double pendulum.
fn rod_norms(q: &[f64; 4]) -> [f64; 2] {
    let (dx, dy) = (q[2] - q[0], q[3] - q[1]);
    [2.0 * q[0].hypot(q[1]), 2.0 * 2f64.sqrt() * dx.hypot(dy)]
}

/// The whirling pendulum: from the bottom with speed 3 (energy 3.5 against
/// 1 at the top).
const WHIRL: ([f64; 2], [f64; 2]) = ([0.0, -1.0], [3.0, 0.0]);

#[test]
fn cartesian_pendulum_energy_steps_hold_the_energy_and_the_circle_over_1e5_steps() {
    let (q0, v0) = WHIRL;
    let method = Constrained::<_, 1>::new(Midpoint);
    let mut sim =
        Integrator::new(Pendulum, method, 0.01).energy_preserving(StepBounds::around(0.01)).start(0.0, q0, v0).unwrap();
    let run = watch(&mut sim, 100_000, sphere_norm, |_| {});
    let mut fixed = Integrator::new(Pendulum, method, 0.01).start(0.0, q0, v0).unwrap();
    let fixed = watch(&mut fixed, 100_000, sphere_norm, |_| {});
    println!("whirling pendulum, 1e5 steps: energy steps {run:?}; fixed steps {fixed:?}");
    assert!(run.energy <= 1e-13, "energy steps: relative energy error {:e}", run.energy);
    assert!(fixed.energy > 1e-6, "fixed steps: relative energy error {:e}", fixed.energy);
    for r in [&run, &fixed] {
        assert!(r.position <= 1e-13 && r.velocity <= 1e-13, "{r:?}");
    }
    assert!(run.h_max / run.h_min > 1.05, "the steps do not vary: {run:?}");
}

#[test]
fn cartesian_double_pendulum_energy_steps_hold_the_energy_and_both_rods_over_1e5_steps() {
    let (q0, v0) = DOUBLE_WHIRL;
    let method = Constrained::<_, 2>::new(Midpoint);
    let h = 0.005;
    let mut sim =
        Integrator::new(DoublePendulum, method, h).energy_preserving(StepBounds::around(h)).start(0.0, q0, v0).unwrap();
    let run = watch(&mut sim, 100_000, rod_norms, |_| {});
    let mut fixed = Integrator::new(DoublePendulum, method, h).start(0.0, q0, v0).unwrap();
    let fixed = watch(&mut fixed, 100_000, rod_norms, |_| {});
    println!("whirling double pendulum, 1e5 steps: energy steps {run:?}; fixed steps {fixed:?}");
    assert!(run.energy <= 1e-13, "energy steps: relative energy error {:e}", run.energy);
    assert!(fixed.energy > 1e-6, "fixed steps: relative energy error {:e}", fixed.energy);
    for r in [&run, &fixed] {
        assert!(r.position <= 1e-13 && r.velocity <= 1e-13, "{r:?}");
    }
    assert!(run.h_max / run.h_min > 1.05, "the steps do not vary: {run:?}");
}

/// The double pendulum hanging straight down, whirled with both rods
/// turning at rate 5 (the outer mass at speed 10).
const DOUBLE_WHIRL: ([f64; 4], [f64; 4]) = ([0.0, -1.0, 0.0, -2.0], [5.0, 0.0, 10.0, 0.0]);

#[test]
fn energy_steps_of_the_constrained_midpoint_are_second_order() {
    // θ'' = −sin θ from the bottom with θ' = 3, to t = 2; x = sin θ, y = −cos θ.
    let [theta, _] = rk4(|y| [y[1], -y[0].sin()], [0.0, 3.0], 2.0, 20_000);
    let exact = [theta.sin(), -theta.cos()];
    let (q0, v0) = WHIRL;
    let hs = [0.04, 0.02, 0.01, 0.005];
    let errors: Vec<f64> = hs
        .iter()
        .map(|&h| {
            let method = Constrained::<_, 1>::new(Midpoint);
            let mut sim = Integrator::new(Pendulum, method, h)
                .energy_preserving(StepBounds::around(h))
                .start(0.0, q0, v0)
                .unwrap();
            sim.run_until(2.0, |_| {}).unwrap();
            let q = sim.state().q;
            (q[0] - exact[0]).abs().max((q[1] - exact[1]).abs())
        })
        .collect();
    let order = fitted_order(&hs, &errors);
    println!("energy steps, constrained midpoint: errors {errors:?}, fitted order {order:.3}");
    assert!((order - 2.0).abs() < 0.1, "fitted order {order}, errors {errors:?}");
}

#[test]
fn spherical_pendulum_energy_steps_hold_the_energy_and_vertical_angular_momentum() {
    // Released at 1 rad from the vertical with a sideways speed above the
    // conical one (1.15): the pendulum precesses between two latitudes.
    let q0 = [1f64.sin(), 0.0, -1f64.cos()];
    let v0 = [0.0, 1.3, 0.0];
    let method = Constrained::<_, 1>::new(Midpoint);
    let mut sim = Integrator::new(Spherical, method, 0.01)
        .energy_preserving(StepBounds::around(0.01))
        .start(0.0, q0, v0)
        .unwrap();
    let lz = |s: &State<3>| s.q[0] * s.p[1] - s.q[1] * s.p[0];
    let l0 = lz(sim.state());
    let mut drift = 0.0f64;
    let run = watch(&mut sim, 10_000, sphere_norm, |s| drift = drift.max((lz(s.state()) - l0).abs() / l0.abs()));
    println!("spherical pendulum, energy steps: {run:?}, relative drift of L_z {drift:e}");
    assert!(run.energy <= 1e-13, "relative energy error {:e}", run.energy);
    assert!(drift <= 1e-13, "relative drift of L_z {drift:e}");
    assert!(run.position <= 1e-13 && run.velocity <= 1e-13, "{run:?}");
    assert!(run.h_max / run.h_min > 1.01, "the steps do not vary: {run:?}");
}

/// The whirling pendulum with linear damping `R = ½ c |v|²`.
#[derive(Clone, Debug)]
struct DampedPendulum;

#[lagrangian]
impl DampedPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }
    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.05 * 0.5 * (v[0] * v[0] + v[1] * v[1])
    }
    fn constraints(&self, q: [f64; 2]) -> [f64; 1] {
        [q[0] * q[0] + q[1] * q[1] - 1.0]
    }
}

#[test]
fn damped_pendulum_energy_balance_steps_lose_exactly_the_dissipated_work() {
    let method = Constrained::<_, 1>::new(Midpoint);
    let mut sim = Integrator::new(DampedPendulum, method, 0.01)
        .energy_preserving(StepBounds::around(0.01))
        .start(0.0, [0.0, -1.0], [4.0, 0.0])
        .unwrap();
    sim.step().unwrap();
    let e1 = sim.discrete_energy();
    // Σ W_k^δt over the nodes between steps: the discrete work of the
    // dissipation the energy equation carries.
    let (mut work, mut g) = (0.0f64, 0.0f64);
    // 500 steps, to t ≈ 8: still whirling (slower whirls lose the energy
    // root as the swings do).
    sim.run(500, |s| {
        work += s.energy_balance().map_or(0.0, |b| b.variational_work);
        g = g.max(s.constraint_values()[0].abs());
    })
    .unwrap();
    let lost = sim.discrete_energy() - e1;
    let defect = (lost - work).abs() / lost.abs();
    println!("damped pendulum, energy-balance steps: ΔE {lost:.6}, Σ W {work:.6}, relative defect {defect:e}");
    assert!(lost < -0.1 * e1.abs(), "the run loses too little energy to test: {lost} of {e1}");
    assert!(defect <= 1e-12, "energy lost {lost}, discrete work {work}: relative defect {defect:e}");
    assert!(g <= 1e-15, "max |g| {g:e}");
}

#[test]
fn energy_steps_refuse_moving_constraints_and_other_families() {
    let bounds = StepBounds::around(0.01);
    let moving = Integrator::new(Lengthening, Constrained::<_, 1>::new(Midpoint), 0.01)
        .energy_preserving(bounds)
        .start(0.0, [0.0, -1.0], [1.0, -0.1]);
    match moving {
        Err(Error::Unsupported { what }) => assert!(what.contains("moving"), "{what}"),
        other => panic!("{other:?}"),
    }
    let (q0, v0) = WHIRL;
    let accuracy = Integrator::new(Pendulum, Constrained::<_, 1>::new(Midpoint), 0.01)
        .energy_preserving(bounds.with_accuracy(1e-4))
        .start(0.0, q0, v0);
    assert!(matches!(accuracy, Err(Error::Unsupported { .. })), "{accuracy:?}");
    // Galerkin rules: autonomous and unforced systems only, as without constraints.
    let gauss = Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss());
    let moving =
        Integrator::new(Lengthening, gauss, 0.01).energy_preserving(bounds).start(0.0, [0.0, -1.0], [1.0, -0.1]);
    assert!(matches!(moving, Err(Error::Unsupported { .. })), "{moving:?}");
    let damped = Integrator::new(DampedPendulum, gauss, 0.01).energy_preserving(bounds).start(0.0, q0, v0);
    assert!(matches!(damped, Err(Error::Unsupported { .. })), "{damped:?}");
    let composition = Integrator::new(Pendulum, Constrained::<_, 1>::composition(Composition::YOSHIDA4), 0.01)
        .energy_preserving(bounds)
        .start(0.0, q0, v0);
    assert!(matches!(composition, Err(Error::Unsupported { .. })), "{composition:?}");
}

#[test]
fn a_step_without_an_energy_root_fails_typed_with_the_stepper_unchanged() {
    // The swing from θ = 1 at rest: the energy-error coefficient vanishes
    // at θ ≈ 0.795, and no step in the bounds solves the energy equation.
    let q0 = [1f64.sin(), -1f64.cos()];
    let method = Constrained::<_, 1>::new(Midpoint);
    let mut sim = Integrator::new(Pendulum, method, 0.05)
        .energy_preserving(StepBounds::around(0.05))
        .start(0.0, q0, [0.0; 2])
        .unwrap();
    let bits = |s: &Integrator<Pendulum, Constrained<Midpoint, 1>, 2>| {
        let State { step, t, q, p } = *s.state();
        let mut out = vec![step, t.to_bits(), s.discrete_energy().to_bits(), s.step_size().to_bits()];
        out.extend(q.iter().chain(&p).chain(&s.multipliers()).map(|x| x.to_bits()));
        out.extend(s.last_step_size().map(f64::to_bits));
        out
    };
    for _ in 0..1000 {
        let before = bits(&sim);
        let stats = *sim.stats();
        match sim.step() {
            Ok(_) => continue,
            Err(Error::NoEnergyStep { state, h_lo, h_hi, .. }) => {
                assert_eq!(bits(&sim), before, "the failed step changed the stepper");
                assert_eq!(sim.stats().failed_steps, stats.failed_steps + 1);
                assert_eq!(sim.stats().steps, stats.steps);
                assert_eq!(state, *sim.state());
                let theta = state.q[0].atan2(-state.q[1]);
                assert!((theta - 0.795).abs() < 0.05, "no root at θ = {theta}");
                assert!(h_lo < h_hi);
                return;
            }
            Err(other) => panic!("{other:?}"),
        }
    }
    panic!("the swing found an energy root at every step");
}

#[test]
fn galerkin_energy_steps_hold_the_energy_and_the_circle() {
    let (q0, v0) = WHIRL;
    let method = Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss());
    let mut sim =
        Integrator::new(Pendulum, method, 0.05).energy_preserving(StepBounds::around(0.05)).start(0.0, q0, v0).unwrap();
    sim.step().unwrap();
    let e1 = sim.discrete_energy();
    let (mut energy, mut g, mut h_min, mut h_max) = (0.0f64, 0.0f64, f64::INFINITY, 0.0f64);
    sim.run(5000, |s| {
        energy = energy.max((s.discrete_energy() - e1).abs() / e1.abs());
        g = g.max(s.constraint_values()[0].abs());
        let h = s.last_step_size().unwrap();
        (h_min, h_max) = (h_min.min(h), h_max.max(h));
    })
    .unwrap();
    let mut fixed = Integrator::new(Pendulum, method, 0.05).start(0.0, q0, v0).unwrap();
    fixed.step().unwrap();
    let f1 = fixed.discrete_energy();
    let mut fixed_energy = 0.0f64;
    fixed.run(5000, |s| fixed_energy = fixed_energy.max((s.discrete_energy() - f1).abs() / f1.abs())).unwrap();
    let stats = sim.stats();
    println!(
        "whirling pendulum, Gauss s = 2, 5000 energy steps: relative energy error {energy:e} (fixed steps {fixed_energy:e}), \
         max |g| {g:e}, h in [{h_min}, {h_max}], {:.1} Newton iterations per step",
        stats.newton_iterations as f64 / stats.steps as f64
    );
    assert!(energy <= 1e-13, "relative energy error {energy:e}");
    assert!(fixed_energy > 1e-8, "fixed steps: relative energy error {fixed_energy:e}");
    assert!(g <= 1e-15, "max |g| {g:e}");
    assert!(h_max / h_min > 1.001, "the steps do not vary: [{h_min}, {h_max}]");
}

#[test]
fn trapezoid_and_alpha_beta_energy_steps_hold_the_energy_and_the_circle() {
    let (q0, v0) = WHIRL;
    let bounds = StepBounds::around(0.01);
    let trapezoid = Integrator::new(Pendulum, Constrained::<_, 1>::new(Trapezoid), 0.01).energy_preserving(bounds);
    let alpha_beta = Integrator::new(Pendulum, Constrained::<_, 1>::new(AlphaBeta::new(0.3).unwrap()), 0.01)
        .energy_preserving(bounds);
    let runs = [
        ("trapezoid", energy_run(trapezoid.start(0.0, q0, v0).unwrap())),
        ("α-β", { energy_run(alpha_beta.start(0.0, q0, v0).unwrap()) }),
    ];
    for (name, (energy, g, h_min, h_max)) in runs {
        println!(
            "whirling pendulum, {name}, 1e4 energy steps: relative energy error {energy:e}, max |g| {g:e}, h in [{h_min}, {h_max}]"
        );
        assert!(energy <= 1e-13, "{name}: relative energy error {energy:e}");
        assert!(g <= 1e-15, "{name}: max |g| {g:e}");
        assert!(h_max / h_min > 1.05, "{name}: the steps do not vary: [{h_min}, {h_max}]");
    }
}

/// 1e4 energy steps of a constrained pendulum after its first: the largest
/// relative energy error and `|g|`, the smallest and largest step.
fn energy_run<D: DiscreteLagrangian>(mut sim: Integrator<Pendulum, Constrained<D, 1>, 2>) -> (f64, f64, f64, f64) {
    sim.step().unwrap();
    let e1 = sim.discrete_energy();
    let (mut energy, mut g, mut h_min, mut h_max) = (0.0f64, 0.0f64, f64::INFINITY, 0.0f64);
    sim.run(10_000, |s| {
        energy = energy.max((s.discrete_energy() - e1).abs() / e1.abs());
        g = g.max(s.constraint_values()[0].abs());
        let h = s.last_step_size().unwrap();
        (h_min, h_max) = (h_min.min(h), h_max.max(h));
    })
    .unwrap();
    (energy, g, h_min, h_max)
}

/// The pendulum under a gravity `γ(t) = 1 + 0.2 sin t`: its energy
/// `½|v|² + γ(t) y` changes at the rate `γ'(t) y`.
#[derive(Clone, Debug)]
struct Pulsing;

fn pulse(t: f64) -> f64 {
    1.0 + 0.2 * t.sin()
}

#[lagrangian]
impl Pulsing {
    fn lagrangian(&self, t: f64, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - (1.0 + 0.2 * t.sin()) * q[1]
    }
    fn constraints(&self, q: [f64; 2]) -> [f64; 1] {
        [q[0] * q[0] + q[1] * q[1] - 1.0]
    }
}

#[test]
fn time_dependent_lagrangian_energy_steps_follow_the_energy_evolution() {
    // With a time-dependent L the energy equation is the discrete energy
    // evolution E_{k+1} − E_k = −(∂A/∂t_k + ∂A/∂t_{k+1}), as without
    // constraints: the discrete energy follows the exact one to O(h²).
    // θ'' = −γ(t) sin θ from the bottom with θ' = 3, to t = 3.
    let [theta, omega, _] = rk4(|y| [y[1], -pulse(y[2]) * y[0].sin(), 1.0], [0.0, 3.0, 0.0], 3.0, 30_000);
    let exact = 0.5 * omega * omega - pulse(3.0) * theta.cos();
    let initial = 0.5 * 9.0 - pulse(0.0);
    let (q0, v0) = WHIRL;
    let hs = [0.02, 0.01, 0.005];
    let errors: Vec<f64> = hs
        .iter()
        .map(|&h| {
            let method = Constrained::<_, 1>::new(Midpoint);
            let mut sim = Integrator::new(Pulsing, method, h)
                .energy_preserving(StepBounds::around(h))
                .start(0.0, q0, v0)
                .unwrap();
            let mut g = 0.0f64;
            sim.run_until(3.0, |s| g = g.max(s.constraint_values()[0].abs())).unwrap();
            assert!(g <= 1e-15, "h = {h}: max |g| {g:e}");
            (sim.discrete_energy() - exact).abs()
        })
        .collect();
    let order = fitted_order(&hs, &errors);
    println!(
        "pulsing gravity, energy steps: E changes by {:.3}; energy errors {errors:?}, fitted order {order:.3}",
        exact - initial
    );
    assert!((exact - initial).abs() > 0.05, "the energy barely changes: {exact} against {initial}");
    assert!((order - 2.0).abs() < 0.15, "fitted order {order}, errors {errors:?}");
}
