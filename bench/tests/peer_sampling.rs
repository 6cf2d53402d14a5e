//! Energy samples of the peers: a run that records samples must integrate
//! exactly as a plain run does and end in the same state, and its samples
//! must show the integrator's energy error, not an artefact of the output.
//!
//! Kepler e = 0.9 over 1000 orbits from pericentre: the horizon is a
//! multiple of the sampling interval and ends at a pericentre passage, where
//! an extrapolated state is far off. The report used ode_solvers' dense
//! output for these samples and got an energy error of 0.85 at `T` and a
//! wrong final position (0.4 away), where the accepted steps have 4e-11.

use lagrangian_bench::exact::kepler_position;
use lagrangian_bench::methods::{Method, Setting};
use lagrangian_bench::problem::{self, Problem};
use lagrangian_bench::run::Run;
use nalgebra034::Vector4;
use ode_solvers::{Dop853, OutputType, System};

const ORBITS: f64 = 1000.0;
const TOL: f64 = 1e-12;

fn kepler_09() -> Box<dyn Problem> {
    problem::all(1.0).into_iter().find(|p| p.id() == "kepler-0.9").expect("kepler-0.9 is a problem")
}

fn max_energy(run: &Run) -> f64 {
    run.energy.iter().map(|s| s.1.abs()).fold(0.0, f64::max)
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

#[test]
fn dop853_samples_do_not_change_the_run_and_show_its_energy_error() {
    let p = kepler_09();
    let t_end = ORBITS * 2.0 * std::f64::consts::PI;
    let exact = kepler_position(0.9, t_end);
    for method in [Method::OdeSolversDop853, Method::DiffEqDop853] {
        let plain = p.run(method, Setting::Tolerance(TOL), t_end, 0);
        assert_eq!(plain.failure, None, "{}", method.name());
        // The plain run is accurate: the position at T (a pericentre, r = 0.1) to 1e-3 (1.1e-4 seen).
        let plain_error = max_diff(&plain.q, &exact);
        println!("{}: plain {plain_error:.3e}", method.name());
        assert!(plain_error < 1e-3, "{}: plain run error {plain_error:.3e}", method.name());
        for samples in [400, 2000] {
            let sampled = p.run(method, Setting::Tolerance(TOL), t_end, samples);
            assert_eq!(sampled.failure, None, "{} with {samples} samples", method.name());
            assert_eq!(sampled.steps, plain.steps, "{}: sampling changed the steps", method.name());
            // Same steps, so the same final state up to the dense output's own error at T.
            let d = max_diff(&sampled.q, &plain.q);
            assert!(d < 1e-9, "{} with {samples} samples: final state {d:.3e} from the plain run's", method.name());
            // Evenly spread over the whole run, the last one at T.
            assert!(sampled.energy.len() > samples / 2, "{}: {} samples", method.name(), sampled.energy.len());
            let last = sampled.energy.last().expect("samples").0;
            assert!((last - t_end).abs() < 1e-9 * t_end, "{}: last sample at {last}", method.name());
            // DOP853 at 1e-12 drifts to far below 1e-8 relative over 1000 orbits; 0.85 was the bug.
            let e = max_energy(&sampled);
            assert!(e < 1e-8, "{} with {samples} samples: energy error {e:.3e}", method.name());
        }
    }
}

/// `y' = (v, −q/|q|³)` for ode_solvers directly.
struct KeplerOde;

impl System<f64, Vector4<f64>> for KeplerOde {
    fn system(&self, _t: f64, y: &Vector4<f64>, dy: &mut Vector4<f64>) {
        let r2 = y[0] * y[0] + y[1] * y[1];
        let r3 = r2 * r2.sqrt();
        *dy = Vector4::new(y[2], y[3], -y[0] / r3, -y[1] / r3);
    }
}

/// The upstream behaviour the report works around (ode_solvers 0.6.2,
/// `Dop853::solution_output`): with dense output, once the next output time
/// `xd` is within 1e-9 of `x_end` it pushes `(x_end, y)` with the current
/// step's interpolant, also when that step ends before `x_end`; the
/// interpolant is then extrapolated (`θ > 1`), and the true final state is
/// never output. Related upstream report on the same code path (round-off
/// in `xd` dropping the last point): srenevey/ode-solvers issue #35. If this
/// test fails after an update of ode_solvers, the upstream code changed:
/// check whether `bench/src/peers.rs` may use dense output again.
#[test]
fn ode_solvers_dense_output_extrapolates_its_last_point() {
    let (q0, v0) = lagrangian_bench::exact::kepler_start(0.9);
    let y0 = Vector4::new(q0[0], q0[1], v0[0], v0[1]);
    let t_end = ORBITS * 2.0 * std::f64::consts::PI;
    let solve = |dx: f64, out: OutputType| {
        let mut s = Dop853::from_param(
            KeplerOde, 0.0, t_end, dx, y0, TOL, TOL, 0.9, 0.0, 0.333, 6.0, t_end, 0.0, 20_000_000, 1000, out,
        );
        s.integrate().expect("integrates");
        (*s.x_out().last().expect("output"), *s.y_out().last().expect("output"))
    };
    let (t_sparse, y_sparse) = solve(t_end, OutputType::Sparse);
    let (t_dense, y_dense) = solve(t_end / 2000.0, OutputType::Dense);
    assert_eq!(t_sparse, t_end);
    assert_eq!(t_dense, t_end);
    let exact = kepler_position(0.9, t_end);
    let sparse_error = (y_sparse[0] - exact[0]).abs().max((y_sparse[1] - exact[1]).abs());
    let dense_error = (y_dense[0] - exact[0]).abs().max((y_dense[1] - exact[1]).abs());
    assert!(sparse_error < 1e-3, "sparse output at T: error {sparse_error:.3e}");
    assert!(dense_error > 0.1, "dense output at T: error {dense_error:.3e} (upstream fixed?)");
}
