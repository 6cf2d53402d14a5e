//! An FPU-β chain with fixed ends whose stiffness and β are parameters:
//! the adjoint's long-chain case, shared by the verification tests and
//! `bench/benches/adjoint.rs`.
#![allow(dead_code, unreachable_pub)]

use lagrangian::prelude::*;
use lagrangian::{Coupling, Pattern};

/// An FPU-β chain with fixed ends, `L = Σ ½ v_i² − Σ (½ k d² + ¼ β d⁴)`,
/// `d = q_{i+1} − q_i`, with the stiffness `k` and `β` as parameters,
/// written by hand (no gradient code: above `FORWARD_MAX_N` the stepper's
/// Newton matrix and the adjoint's both come from a tape) with its Hessian
/// declared tridiagonal, so that both solve in the band.
#[derive(Clone)]
pub struct Chain<const N: usize> {
    /// `[k, β]`.
    pub theta: [f64; 2],
}

impl<const N: usize> Lagrangian<N> for Chain<N> {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; N] = [false; N];
    const COUPLING: Coupling = Coupling { q_q: Pattern::banded(N, 1), q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> D {
        self.lagrangian_with(&self.theta.map(D::from), t, q, v)
    }
}

impl<const N: usize> Parametric<N, 2> for Chain<N> {
    const NAMES: [&'static str; 2] = ["k", "beta"];
    fn parameters(&self) -> [f64; 2] {
        self.theta
    }
    fn with_parameters(&self, theta: [f64; 2]) -> Self {
        Self { theta }
    }
    fn lagrangian_with<D: Scalar>(&self, theta: &[D; 2], _t: D, q: [D; N], v: [D; N]) -> D {
        let [k, beta] = *theta;
        let mut l = D::zero();
        for i in 0..=N {
            let left = if i == 0 { D::zero() } else { q[i - 1] };
            let right = if i == N { D::zero() } else { q[i] };
            let d = right - left;
            l -= k * d * d * 0.5 + beta * d.powi(4) * 0.25;
            if i < N {
                l += v[i] * v[i] * 0.5;
            }
        }
        l
    }
}
