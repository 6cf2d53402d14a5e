//! The simplified Newton iterations of the const-size constrained steps:
//! they converge without falling back on Newton's method on a smooth run,
//! and hold the constraints at round-off at every node.

use crate::galerkin::Galerkin;
use crate::integrator::{Composition, F64Readouts};
use crate::system::{Lagrangian, Scalar};
use crate::{Constrained, Integrator, Midpoint};

/// A double pendulum with unit masses and rods under unit gravity, in
/// Cartesian coordinates `(x₁, y₁, x₂, y₂)`.
#[derive(Clone, Debug)]
struct DoublePendulum;

impl Lagrangian<4> for DoublePendulum {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 4] = [false; 4];
    const CONSTRAINTS: usize = 2;
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 4], v: [D; 4]) -> D {
        (v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]) * 0.5 - q[1] - q[3]
    }
    fn constraints<D: Scalar>(&self, _t: D, q: &[D; 4], g: &mut [D]) {
        let (dx, dy) = (q[2] - q[0], q[3] - q[1]);
        g[0] = q[0] * q[0] + q[1] * q[1] - 1.0;
        g[1] = dx * dx + dy * dy - 1.0;
    }
}

/// Released from rest at the angles 0.8 and −0.4 from the downward vertical.
fn start() -> [f64; 4] {
    let (a, b) = (0.8f64, -0.4f64);
    [a.sin(), -a.cos(), a.sin() + b.sin(), -a.cos() - b.cos()]
}

/// `steps` steps of size `h`: the Newton iterations per step, and the
/// largest `|g|` (`values`) over the nodes.
fn run<M: F64Readouts>(
    method: M,
    h: f64,
    steps: usize,
    values: impl Fn(&Integrator<DoublePendulum, M, 4>) -> [f64; 2],
) -> (f64, f64) {
    let mut sim = Integrator::new(DoublePendulum, method, h).start(0.0, start(), [0.0; 4]).unwrap();
    let mut g = 0.0f64;
    for _ in 0..steps {
        sim.step().unwrap();
        g = values(&sim).iter().fold(g, |m, x| m.max(x.abs()));
    }
    let stats = sim.stats();
    (stats.newton_iterations as f64 / stats.steps as f64, g)
}

#[test]
fn simplified_iterations_converge_without_falling_back() {
    for h in [0.01, 0.05] {
        // Iterations per step, position and momentum lines: a simplified
        // iteration that failed and fell back on Newton's method would add
        // at least `max_iterations` (25) to its step.
        let rattle = run(Constrained::<_, 2>::new(Midpoint), h, 400, |s| s.constraint_values());
        let gauss2 = Constrained::<_, 2>::galerkin(Galerkin::<2, 2>::gauss());
        let galerkin2 = run(gauss2, h, 400, |s| s.constraint_values());
        let gauss4 = Constrained::<_, 2>::galerkin(Galerkin::<4, 4>::gauss());
        let galerkin4 = run(gauss4, h, 400, |s| s.constraint_values());
        // Three RATTLE trapezoid sub-steps per step.
        let yoshida = Constrained::<_, 2>::composition(Composition::YOSHIDA4);
        let composition = run(yoshida, h, 400, |s| s.constraint_values());
        let cases = [("RATTLE midpoint", rattle, 6.0), ("Galerkin 2", galerkin2, 7.0), ("Galerkin 4", galerkin4, 7.0)];
        for (name, (iterations, g), most) in cases.into_iter().chain([("Yoshida 4", composition, 20.0)]) {
            assert!(iterations <= most, "{name}, h = {h}: {iterations} iterations per step");
            assert!(g <= 4.0 * f64::EPSILON, "{name}, h = {h}: max |g| = {g:e}");
        }
    }
}

/// `CASE` (`midpoint`, `galerkin2`, `galerkin4`, `yoshida4` on the double
/// pendulum; `shaken-galerkin2`, `shaken-galerkin4`, `shaken-yoshida4` on
/// the damped one hung from a moving support) for `STEPS` steps of size `H`
/// (environment variables; `galerkin4`, 1000 and 0.01 by default): what
/// `valgrind --tool=callgrind` counts the instructions of.
#[test]
#[ignore = "a measurement: run it under callgrind"]
fn steps_for_callgrind() {
    let case = std::env::var("CASE").unwrap_or_else(|_| "galerkin4".into());
    let steps = std::env::var("STEPS").ok().and_then(|s| s.parse().ok()).unwrap_or(1000);
    let h = std::env::var("H").ok().and_then(|s| s.parse().ok()).unwrap_or(0.01);
    let (iterations, _) = match case.as_str() {
        "midpoint" => run(Constrained::<_, 2>::new(Midpoint), h, steps, |s| s.constraint_values()),
        "galerkin2" => {
            run(Constrained::<_, 2>::galerkin(Galerkin::<2, 2>::gauss()), h, steps, |s| s.constraint_values())
        }
        "galerkin4" => {
            run(Constrained::<_, 2>::galerkin(Galerkin::<4, 4>::gauss()), h, steps, |s| s.constraint_values())
        }
        "yoshida4" => run(Constrained::<_, 2>::composition(Composition::YOSHIDA4), h, steps, |s| s.constraint_values()),
        // Damped, on a moving support, under a varying gravity.
        "shaken-galerkin2" => {
            let method = Constrained::<_, 2>::galerkin(Galerkin::<2, 2>::gauss());
            let (iterations, ..) = shaken_run(method, h, steps, |s| (s.constraint_values(), [0.0; 2]));
            (iterations, 0.0)
        }
        "shaken-galerkin4" => {
            let method = Constrained::<_, 2>::galerkin(Galerkin::<4, 4>::gauss());
            let (iterations, ..) = shaken_run(method, h, steps, |s| (s.constraint_values(), [0.0; 2]));
            (iterations, 0.0)
        }
        "shaken-yoshida4" => {
            let method = Constrained::<_, 2>::composition(Composition::YOSHIDA4);
            let (iterations, ..) = shaken_run(method, h, steps, |s| (s.constraint_values(), [0.0; 2]));
            (iterations, 0.0)
        }
        other => panic!("unknown case {other}"),
    };
    eprintln!("{case}: {iterations:.2} iterations per step");
}

/// The double pendulum hung from a support at `(0, 0.3 sin 2t)` under the
/// gravity `1 + 0.2 cos t`, damped by `R = ½ c |v|²`: a time-dependent
/// Lagrangian, a moving constraint and dissipation at once.
#[derive(Clone, Debug)]
struct ShakenDampedDoublePendulum;

impl Lagrangian<4> for ShakenDampedDoublePendulum {
    const AUTONOMOUS: bool = false;
    const CYCLIC: [bool; 4] = [false; 4];
    const CONSTRAINTS: usize = 2;
    const CONSTRAINTS_AUTONOMOUS: bool = false;
    const HAS_DISSIPATION: bool = true;
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; 4], v: [D; 4]) -> D {
        (v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]) * 0.5 - (t.cos() * 0.2 + 1.0) * (q[1] + q[3])
    }
    fn dissipation<D: Scalar>(&self, _q: [D; 4], v: [D; 4]) -> D {
        (v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]) * 0.15
    }
    fn constraints<D: Scalar>(&self, t: D, q: &[D; 4], g: &mut [D]) {
        let dy0 = q[1] - (t * 2.0).sin() * 0.3;
        let (dx, dy) = (q[2] - q[0], q[3] - q[1]);
        g[0] = q[0] * q[0] + dy0 * dy0 - 1.0;
        g[1] = dx * dx + dy * dy - 1.0;
    }
}

/// `steps` steps of size `h` of the shaken damped double pendulum from
/// rest relative to its support: the Newton iterations per step, the largest
/// `|g|` and `|G v + ∂g/∂t|` (`values`) over the nodes.
fn shaken_run<M: F64Readouts>(
    method: M,
    h: f64,
    steps: usize,
    values: impl Fn(&Integrator<ShakenDampedDoublePendulum, M, 4>) -> ([f64; 2], [f64; 2]),
) -> (f64, f64, f64) {
    // The support's velocity is (0, 0.6) at t = 0.
    let v0 = [0.0, 0.6, 0.0, 0.6];
    let mut sim = Integrator::new(ShakenDampedDoublePendulum, method, h).start(0.0, start(), v0).unwrap();
    let (mut g, mut gv) = (0.0f64, 0.0f64);
    for _ in 0..steps {
        sim.step().unwrap();
        let (value, velocity) = values(&sim);
        g = value.iter().fold(g, |m, x| m.max(x.abs()));
        gv = velocity.iter().fold(gv, |m, x| m.max(x.abs()));
    }
    let stats = sim.stats();
    (stats.newton_iterations as f64 / stats.steps as f64, g, gv)
}

#[test]
fn forced_moving_steps_converge_without_falling_back_and_hold_the_constraints() {
    let gauss2 = Constrained::<_, 2>::galerkin(Galerkin::<2, 2>::gauss());
    let galerkin2 = shaken_run(gauss2, 0.05, 200, |s| (s.constraint_values(), s.constraint_velocities().unwrap()));
    let gauss3 = Constrained::<_, 2>::galerkin(Galerkin::<3, 3>::gauss());
    let galerkin3 = shaken_run(gauss3, 0.05, 200, |s| (s.constraint_values(), s.constraint_velocities().unwrap()));
    let yoshida = Constrained::<_, 2>::composition(Composition::YOSHIDA4);
    let composition = shaken_run(yoshida, 0.05, 200, |s| (s.constraint_values(), s.constraint_velocities().unwrap()));
    for (name, (iterations, g, gv), most) in
        [("Galerkin 2", galerkin2, 7.0), ("Galerkin 3", galerkin3, 7.0), ("Yoshida 4", composition, 20.0)]
    {
        println!("{name}: {iterations:.2} iterations per step, max |g| {g:.1e}, max |G v + g_t| {gv:.1e}");
        assert!(iterations <= most, "{name}: {iterations} iterations per step");
        assert!(
            g <= 8.0 * f64::EPSILON && gv <= 8.0 * f64::EPSILON,
            "{name}: max |g| = {g:e}, max |G v + g_t| = {gv:e}"
        );
    }
}

/// Energy-preserving constrained midpoint steps of the whirling double
/// pendulum (both rods turning at rate 5 from hanging straight down): the
/// discrete energy at round-off, the constraints at round-off, and steps
/// that vary.
#[test]
fn energy_preserving_steps_conserve_the_discrete_energy_on_the_manifold() {
    use crate::integrator::StepBounds;
    let method = Constrained::<_, 2>::new(Midpoint);
    let mut sim = Integrator::new(DoublePendulum, method, 0.005)
        .energy_preserving(StepBounds::around(0.005))
        .start(0.0, [0.0, -1.0, 0.0, -2.0], [5.0, 0.0, 10.0, 0.0])
        .unwrap();
    sim.step().unwrap();
    let e0 = sim.discrete_energy();
    let (mut drift, mut g, mut h_min, mut h_max) = (0.0f64, 0.0f64, f64::INFINITY, 0.0f64);
    for _ in 0..2000 {
        sim.step().unwrap();
        drift = drift.max((sim.discrete_energy() - e0).abs() / e0.abs());
        g = sim.constraint_values().iter().fold(g, |m, x| m.max(x.abs()));
        let h = sim.last_step_size().unwrap();
        (h_min, h_max) = (h_min.min(h), h_max.max(h));
    }
    assert!(drift <= 1e-13, "{drift:e}");
    assert!(g <= 4.0 * f64::EPSILON, "{g:e}");
    assert!(h_max / h_min > 1.01, "[{h_min}, {h_max}]");
}
