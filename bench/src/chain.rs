//! The FPU-β chain of `benches/chain_scaling.rs` and
//! `examples/chain_steps.rs`: unit masses and springs, fixed ends, β = 1,
//!
//! ```text
//! L = Σ ½ q̇ᵢ² − Σ_{i=0}^{N} [ ½ dᵢ² + β/4 dᵢ⁴ ],   dᵢ = q_{i+1} − qᵢ,   q₀ = q_{N+1} = 0,
//! ```
//!
//! written two ways through `#[lagrangian]`, each with its size known at
//! compile time and at run time: the bench's own ([`Fpu`], [`DynFpu`]: a
//! constant β, one running difference `d` for the end springs and the
//! interior), and as a new user writes it ([`UserFpu`], [`DynUserFpu`]: β a
//! field read as `self.beta`, the two end springs as separate terms outside
//! the loop over the interior). Beside them the hand-written Störmer–Verlet
//! steps of the same chain ([`Verlet`], plain sums; [`CompensatedVerlet`],
//! the Kahan sums the generated steps keep) and the start of every run
//! ([`start_q`]).

use lagrangian::prelude::*;

/// β of every chain here.
pub const BETA: f64 = 1.0;

/// The bench's chain: β a constant, the end springs through the running
/// difference `d` of the interior loop.
#[derive(Clone, Copy, Debug)]
pub struct Fpu<const N: usize>;

#[lagrangian]
impl<const N: usize> Fpu<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * BETA * d.powi(4);
        for i in 0..N - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * BETA * d.powi(4);
        }
        d = q[N - 1];
        potential += 0.5 * d * d + 0.25 * BETA * d.powi(4);
        kinetic - potential
    }
}

/// The chain as a new user writes it: β a field, the springs to the walls
/// as separate terms outside the loop over the interior springs.
#[derive(Clone, Copy, Debug)]
pub struct UserFpu<const N: usize> {
    /// The quartic coefficient.
    pub beta: f64,
}

#[lagrangian]
impl<const N: usize> UserFpu<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.5 * q[0] * q[0] + 0.25 * self.beta * q[0].powi(4);
        potential += 0.5 * q[N - 1] * q[N - 1] + 0.25 * self.beta * q[N - 1].powi(4);
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        kinetic - potential
    }
}

/// [`Fpu`] sized at run time.
#[derive(Clone, Copy, Debug)]
pub struct DynFpu(pub usize);

#[lagrangian]
impl DynFpu {
    fn dimension(&self) -> usize {
        self.0
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * BETA * d.powi(4);
        for i in 0..n - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * BETA * d.powi(4);
        }
        d = q[n - 1];
        potential += 0.5 * d * d + 0.25 * BETA * d.powi(4);
        kinetic - potential
    }
}

/// [`UserFpu`] sized at run time.
#[derive(Clone, Copy, Debug)]
pub struct DynUserFpu {
    /// The number of masses.
    pub n: usize,
    /// The quartic coefficient.
    pub beta: f64,
}

#[lagrangian]
impl DynUserFpu {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.5 * q[0] * q[0] + 0.25 * self.beta * q[0].powi(4);
        potential += 0.5 * q[n - 1] * q[n - 1] + 0.25 * self.beta * q[n - 1].powi(4);
        for i in 0..n - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        kinetic - potential
    }
}

/// The start of every run: mode `⌈n/10⌉` with spring strains of 0.3, at rest.
pub fn start_q(n: usize) -> Vec<f64> {
    let k = n.div_ceil(10);
    let a = 0.3 * (n + 1) as f64 / (k as f64 * std::f64::consts::PI);
    (0..n).map(|i| a * ((i + 1) as f64 * k as f64 * std::f64::consts::PI / (n + 1) as f64).sin()).collect()
}

/// [`start_q`] as an array.
pub fn start_array<const N: usize>() -> [f64; N] {
    let q = start_q(N);
    core::array::from_fn(|i| q[i])
}

/// The chain's force `−∇V` by hand, into `f`.
pub fn force(q: &[f64], f: &mut [f64]) {
    let n = q.len();
    let spring = |d: f64| d + BETA * d * d * d;
    let mut left = spring(q[0]);
    for i in 0..n {
        let right = spring(if i + 1 < n { q[i + 1] - q[i] } else { -q[i] });
        f[i] = right - left;
        left = right;
    }
}

/// Hand-written velocity Verlet, unit masses, plain sums.
#[derive(Clone, Debug)]
pub struct Verlet {
    /// Positions.
    pub q: Vec<f64>,
    /// Momenta.
    pub p: Vec<f64>,
    f: Vec<f64>,
}

impl Verlet {
    /// At rest at `q`.
    pub fn new(q: &[f64]) -> Self {
        let mut f = vec![0.0; q.len()];
        force(q, &mut f);
        Self { q: q.to_vec(), p: vec![0.0; q.len()], f }
    }

    /// One step of size `h`.
    pub fn step(&mut self, h: f64) {
        for i in 0..self.q.len() {
            self.p[i] += 0.5 * h * self.f[i];
            self.q[i] += h * self.p[i];
        }
        force(&self.q, &mut self.f);
        for i in 0..self.q.len() {
            self.p[i] += 0.5 * h * self.f[i];
        }
    }
}

/// Hand-written velocity Verlet, unit masses, with the Kahan-compensated
/// sums of `q` and `p` the generated steps keep (`q`, its compensation `qc`,
/// `p`, `pc` updated in place, the forces at both nodes in two buffers
/// swapped after each step): the generated explicit step's arithmetic.
#[derive(Clone, Debug)]
pub struct CompensatedVerlet {
    /// Positions.
    pub q: Vec<f64>,
    qc: Vec<f64>,
    /// Momenta.
    pub p: Vec<f64>,
    pc: Vec<f64>,
    f0: Vec<f64>,
    f1: Vec<f64>,
}

impl CompensatedVerlet {
    /// At rest at `q`.
    pub fn new(q: &[f64]) -> Self {
        let n = q.len();
        let mut f0 = vec![0.0; n];
        force(q, &mut f0);
        Self { q: q.to_vec(), qc: vec![0.0; n], p: vec![0.0; n], pc: vec![0.0; n], f0, f1: vec![0.0; n] }
    }

    /// One step of size `h`.
    pub fn step(&mut self, h: f64) {
        let kahan = |a: f64, c: f64, b: f64| {
            let u = c + b;
            let sum = a + u;
            (sum, u - (sum - a))
        };
        let half = 0.5 * h;
        let n = self.q.len();
        // One length for every slice: the loops have no bounds checks.
        let (q, qc, p, pc) = (&mut self.q[..n], &mut self.qc[..n], &mut self.p[..n], &mut self.pc[..n]);
        let old = &self.f0[..n];
        for i in 0..n {
            let x = ((p[i] + half * old[i]) + pc[i]) * h;
            (q[i], qc[i]) = kahan(q[i], qc[i], x);
        }
        force(q, &mut self.f1);
        let new = &self.f1[..n];
        for i in 0..n {
            (p[i], pc[i]) = kahan(p[i], pc[i], half * (old[i] + new[i]));
        }
        core::mem::swap(&mut self.f0, &mut self.f1);
    }
}
