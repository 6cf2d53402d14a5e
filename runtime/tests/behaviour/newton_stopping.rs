//! Newton's stopping test where a step's unknown, the increment
//! `q_{k+1} − q_k`, is far smaller than the positions: an FPU-β chain of
//! 1 000 masses from rest in its lowest normal mode (amplitude 1, strains
//! π/1001 ≈ 3e-3, forces ≈ 1e-5), whose increments are 1e-7 at `h = 0.1`.
//! The residual's round-off, 1e-17 from the rounding of positions of order
//! 1 in the strains, is 4e-12 of the increment, above `rtol = 1e-14`: the
//! corrections stall there without contracting. Newton accepts such a stall
//! once the corrections are below the rounding of the positions (they
//! cannot be resolved in `f64`), and the steps follow the closed-form
//! discrete solution of the linear chain to round-off.
#![allow(missing_docs)]

use lagrangian_runtime::{
    Coupling, DynIntegrator, DynLagrangian, Midpoint, Pattern, RunTimeStepping, Scalar, Separability,
};

/// An FPU-β chain with fixed ends, unit masses and springs, of run-time length.
struct DynFpu {
    n: usize,
    beta: f64,
}

impl DynLagrangian for DynFpu {
    const AUTONOMOUS: bool = true;
    const SEPARABILITY: Separability = Separability::ConstantMass;
    const COUPLING: Coupling =
        Coupling { q_q: Pattern::Banded { bandwidth: 1 }, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };

    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        let n = q.len();
        let spring = |d: D| d * d * 0.5 + d.powi(4) * (0.25 * self.beta);
        let mut kinetic = D::zero();
        for x in v {
            kinetic += *x * *x * 0.5;
        }
        let mut potential = spring(q[0]) + spring(q[n - 1]);
        for i in 0..n - 1 {
            potential += spring(q[i + 1] - q[i]);
        }
        kinetic - potential
    }
}

/// The lowest normal mode `sin(π(i + 1)/(N + 1))`, amplitude 1.
fn lowest_mode(n: usize) -> Vec<f64> {
    (0..n).map(|i| (std::f64::consts::PI * (i + 1) as f64 / (n + 1) as f64).sin()).collect()
}

#[test]
fn a_chain_at_rest_in_its_lowest_mode_steps_to_round_off() {
    let n = 1000;
    let (h, steps) = (0.1, 20);
    let mode = lowest_mode(n);
    // The FPU-β chain (β = 1): every step is accepted (step 3 at h = 0.01
    // and step 2 at h = 0.1 ended in `NewtonDidNotConverge` with residuals
    // of 1e-17 under an increment test alone).
    for h in [0.01, 0.1] {
        let mut sim =
            DynIntegrator::new(DynFpu { n, beta: 1.0 }, Midpoint, h).start(0.0, &mode, &vec![0.0; n]).unwrap();
        sim.run(steps, |_| {}).unwrap_or_else(|e| panic!("h = {h}: {e}"));
    }
    // The linear chain (β = 0): the midpoint rule turns the mode by `θ` per
    // step, `tan(θ/2) = hω/2`, `ω = 2 sin(π/(2(N + 1)))`, so
    // `q_k = cos(kθ) s` and `p_k = −ω sin(kθ) s` exactly.
    let mut sim = DynIntegrator::new(DynFpu { n, beta: 0.0 }, Midpoint, h).start(0.0, &mode, &vec![0.0; n]).unwrap();
    let omega = 2.0 * (std::f64::consts::PI / (2.0 * (n + 1) as f64)).sin();
    let theta = 2.0 * (0.5 * h * omega).atan();
    let (mut worst_q, mut worst_p) = (0.0f64, 0.0f64);
    for k in 1..=steps {
        sim.step().unwrap_or_else(|e| panic!("step {k}: {e}"));
        let (c, s) = ((k as f64 * theta).cos(), (k as f64 * theta).sin());
        let state = sim.state();
        for i in 0..n {
            worst_q = worst_q.max((state.q[i] - c * mode[i]).abs());
            worst_p = worst_p.max((state.p[i] + omega * s * mode[i]).abs());
        }
    }
    println!("lowest mode, N = {n}, {steps} steps of h = {h}: |Δq| ≤ {worst_q:.1e}, |Δp| ≤ {worst_p:.1e}");
    // Round-off of 20 steps beside positions of order 1 (50 ε); the
    // momenta are of order ωkθ ≈ 2e-5.
    assert!(worst_q <= 1e-14, "{worst_q:e}");
    assert!(worst_p <= 1e-14, "{worst_p:e}");
}
