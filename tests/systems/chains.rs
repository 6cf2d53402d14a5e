//! FPU-β chains with fixed ends: the system, its normal modes and the
//! energy error of a run, shared by `large_systems` (in `systems`) and
//! `default_stack`.
use lagrangian::prelude::*;

/// An FPU-β chain with fixed ends, unit masses and springs.
#[derive(Clone)]
pub struct Fpu<const N: usize> {
    /// Quartic coupling.
    pub beta: f64,
}

#[lagrangian]
impl<const N: usize> Fpu<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        for i in 0..N - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        d = q[N - 1];
        potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        kinetic - potential
    }
}

/// Normal mode `k` of a chain with fixed ends, scaled so that the largest
/// spring strain is `strain` (0.3: well into the quartic regime for β = 1).
pub fn chain_mode<const N: usize>(k: usize, strain: f64) -> [f64; N] {
    let a = strain * (N + 1) as f64 / (k as f64 * core::f64::consts::PI);
    core::array::from_fn(|i| a * ((i + 1) as f64 * k as f64 * core::f64::consts::PI / (N + 1) as f64).sin())
}

/// Relative energy error `max |E − E_0| / |E_0|` over `n` steps of a chain
/// of `N` masses, sampled every `every` steps.
pub fn chain_energy_error<M: lagrangian::F64Readouts + Copy, const N: usize>(
    method: M,
    h: f64,
    n: usize,
    every: usize,
) -> Vec<f64> {
    // Mode N/10 (period about 20 for every N): a nonlinear wave.
    let q0 = chain_mode::<N>(N.div_ceil(10), 0.3);
    let mut sim = Integrator::new(Fpu::<N> { beta: 1.0 }, method, h).start(0.0, q0, [0.0; N]).unwrap();
    let e0 = sim.energy().unwrap();
    let mut errors = Vec::new();
    for k in 0..n / every {
        sim.run(every, |_| {}).unwrap();
        let e = sim.energy().unwrap();
        assert!(e.is_finite(), "N = {N}: energy at step {}", (k + 1) * every);
        errors.push((e - e0).abs() / e0.abs());
    }
    errors
}
