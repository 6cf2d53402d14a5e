//! Hand-written symmetric compositions of Störmer–Verlet for separable
//! Hamiltonians `H = ½ pᵀM⁻¹p + V(q)` (diagonal constant `M`): the methods a
//! user would write by hand for these problems.
//!
//! Coefficients: Yoshida's order 6 composition with 7 stages ("solution A";
//! H. Yoshida, *Construction of higher order symplectic integrators*, Phys.
//! Lett. A 150, 1990) and Kahan & Li's order 8 composition with 15 stages
//! (W. Kahan, R.-C. Li, *Composition constants for raising the orders of
//! unconventional schemes for ordinary differential equations*, Math. Comp.
//! 66, 1997; the set `s15odr8` of Hairer, Lubich & Wanner, §V.3.2).

/// Which composition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Composition {
    /// Störmer–Verlet (kick–drift–kick), order 2.
    Verlet,
    /// Yoshida, 7 stages, order 6.
    Yoshida6,
    /// Kahan–Li, 15 stages, order 8.
    KahanLi8,
}

const YOSHIDA6: [f64; 4] = [0.784513610477560, 0.235573213359357, -1.17767998417887, 1.315186320683906];

// The published 20 digits, kept as published (f64 rounds them).
#[allow(clippy::excessive_precision)]
const KAHAN_LI8: [f64; 8] = [
    0.74167036435061295345,
    -0.40910082580003159400,
    0.19075471029623837995,
    -0.57386247111608226666,
    0.29906418130365592384,
    0.33462491824529818378,
    0.31529309239676659663,
    -0.79688793935291635402,
];

impl Composition {
    /// The Störmer–Verlet sub-step weights `γ_1 … γ_m` (symmetric, summing to 1).
    pub fn weights(self) -> Vec<f64> {
        let half: &[f64] = match self {
            Composition::Verlet => return vec![1.0],
            Composition::Yoshida6 => &YOSHIDA6,
            Composition::KahanLi8 => &KAHAN_LI8,
        };
        // Stored as γ_1 … γ_{(m+1)/2}; the rest mirror them.
        let mut w = half.to_vec();
        w.extend(half.iter().rev().skip(1));
        w
    }

    /// The classical order.
    pub fn order(self) -> u32 {
        match self {
            Composition::Verlet => 2,
            Composition::Yoshida6 => 6,
            Composition::KahanLi8 => 8,
        }
    }
}

/// A composition integrator on `(q, p)`; counts force evaluations.
#[derive(Clone, Debug)]
pub struct Stepper<const N: usize> {
    /// Positions.
    pub q: [f64; N],
    /// Momenta `M q̇`.
    pub p: [f64; N],
    /// Time.
    pub t: f64,
    /// Force evaluations so far.
    pub evaluations: u64,
    weights: Vec<f64>,
    minv: [f64; N],
    h: f64,
    // The force at the current q: each Verlet sub-step ends with the force its successor starts with.
    f: [f64; N],
    // The Kahan compensations of `q` and `p` (`step_compensated` only).
    qc: [f64; N],
    pc: [f64; N],
}

impl<const N: usize> Stepper<N> {
    /// Starts at `(q0, v0)` with step `h`.
    pub fn new(
        method: Composition,
        minv: [f64; N],
        force: &impl Fn(&[f64; N]) -> [f64; N],
        h: f64,
        q0: [f64; N],
        v0: [f64; N],
    ) -> Self {
        let p = core::array::from_fn(|i| v0[i] / minv[i]);
        let f = force(&q0);
        Self { q: q0, p, t: 0.0, evaluations: 1, weights: method.weights(), minv, h, f, qc: [0.0; N], pc: [0.0; N] }
    }

    /// The velocity `M⁻¹p`.
    pub fn velocity(&self) -> [f64; N] {
        core::array::from_fn(|i| self.minv[i] * self.p[i])
    }

    /// One step of size `h` (all sub-steps).
    pub fn step(&mut self, force: &impl Fn(&[f64; N]) -> [f64; N]) {
        for k in 0..self.weights.len() {
            let h = self.weights[k] * self.h;
            for i in 0..N {
                self.p[i] += 0.5 * h * self.f[i];
                self.q[i] += h * self.minv[i] * self.p[i];
            }
            self.f = force(&self.q);
            self.evaluations += 1;
            for i in 0..N {
                self.p[i] += 0.5 * h * self.f[i];
            }
        }
        self.t += self.h;
    }

    /// One step of size `h` with the compensated sums the generated explicit
    /// steps keep (the same scheme, a fair baseline for their bookkeeping):
    /// the sub-steps accumulate the increments `Δq`, `Δp` from the node
    /// (each sub-node at `q + (c_q + Δq)`, each drift's momentum
    /// `p + (c_p + Δp)`), and `q`, `p` take them once, as Kahan sums whose
    /// rounding is carried into the next step.
    pub fn step_compensated(&mut self, force: &impl Fn(&[f64; N]) -> [f64; N]) {
        let (mut dq, mut dp, mut node) = ([0.0; N], [0.0; N], self.q);
        for k in 0..self.weights.len() {
            let h = self.weights[k] * self.h;
            for i in 0..N {
                dp[i] += 0.5 * h * self.f[i];
                dq[i] += h * self.minv[i] * (self.p[i] + (self.pc[i] + dp[i]));
                node[i] = self.q[i] + (self.qc[i] + dq[i]);
            }
            self.f = force(&node);
            self.evaluations += 1;
            for i in 0..N {
                dp[i] += 0.5 * h * self.f[i];
            }
        }
        for i in 0..N {
            let u = self.qc[i] + dq[i];
            let q = self.q[i] + u;
            self.qc[i] = u - (q - self.q[i]);
            self.q[i] = q;
            let u = self.pc[i] + dp[i];
            let p = self.p[i] + u;
            self.pc[i] = u - (p - self.p[i]);
            self.p[i] = p;
        }
        self.t += self.h;
    }
}
