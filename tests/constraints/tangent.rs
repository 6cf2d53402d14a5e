//! The tangent map of a constrained step: against central differences of
//! the step along the constrained phase space, symplectic on that space's
//! tangent vectors, and mapping them to the tangent space at the next node.
//!
//! For the systems here `L = ½|v|² − V`, so `p = v` and the constrained
//! phase space is `{g = 0, G q̇ + ∂g/∂t = 0}`, whose tangent vectors
//! `(δq, δp)` are the kernel of `C = [[G, 0], [Z, G]]` with
//! `Z = ∂(G v + ∂g/∂t)/∂q`, written out by hand below.

use lagrangian::prelude::*;
use nalgebra::DMatrix;

use super::DoublePendulum;

/// `C` of the double pendulum (see the module documentation).
fn double_pendulum_c(q: &[f64], v: &[f64]) -> DMatrix<f64> {
    let (dx, dy) = (q[2] - q[0], q[3] - q[1]);
    let (du, dw) = (v[2] - v[0], v[3] - v[1]);
    DMatrix::from_row_slice(
        4,
        8,
        &[
            2.0 * q[0],
            2.0 * q[1],
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0, //
            -2.0 * dx,
            -2.0 * dy,
            2.0 * dx,
            2.0 * dy,
            0.0,
            0.0,
            0.0,
            0.0, //
            2.0 * v[0],
            2.0 * v[1],
            0.0,
            0.0,
            2.0 * q[0],
            2.0 * q[1],
            0.0,
            0.0, //
            -2.0 * du,
            -2.0 * dw,
            2.0 * du,
            2.0 * dw,
            -2.0 * dx,
            -2.0 * dy,
            2.0 * dx,
            2.0 * dy,
        ],
    )
}

/// `C` of the bead on the hoop turning at `ω` (`time.rs`) at time `t`.
fn hoop_c(omega: f64, t: f64, q: &[f64], v: &[f64]) -> DMatrix<f64> {
    let (s, c) = (omega * t).sin_cos();
    DMatrix::from_row_slice(
        4,
        6,
        &[
            2.0 * q[0],
            2.0 * q[1],
            2.0 * q[2],
            0.0,
            0.0,
            0.0, //
            -s,
            c,
            0.0,
            0.0,
            0.0,
            0.0, //
            2.0 * v[0],
            2.0 * v[1],
            2.0 * v[2],
            2.0 * q[0],
            2.0 * q[1],
            2.0 * q[2], //
            -omega * c,
            -omega * s,
            0.0,
            -s,
            c,
            0.0,
        ],
    )
}

/// The orthogonal projector onto the kernel of `c`.
fn kernel_projector(c: &DMatrix<f64>) -> DMatrix<f64> {
    let n = c.ncols();
    DMatrix::identity(n, n) - c.transpose() * (c * c.transpose()).try_inverse().unwrap() * c
}

/// The canonical `𝕁` of `(q, p)` in `2n` dimensions.
fn canonical(n: usize) -> DMatrix<f64> {
    let mut j = DMatrix::zeros(2 * n, 2 * n);
    for i in 0..n {
        j[(i, n + i)] = 1.0;
        j[(n + i, i)] = -1.0;
    }
    j
}

/// Checks the tangent map of one step from `(t, q, p)` (with `p = v`):
/// returns the largest defect of `Jᵀ𝕁J = 𝕁` on tangent vectors, the largest
/// `|C₁ J u|` for tangent vectors `u` (how far `J u` is from the next
/// tangent space) and the largest relative gap to central differences.
fn check<S, const N: usize, const M: usize>(
    system: S,
    h: f64,
    (t, q, p): (f64, [f64; N], [f64; N]),
    c_at: impl Fn(f64, &[f64], &[f64]) -> DMatrix<f64>,
) -> (f64, f64, f64)
where
    S: Lagrangian<N> + Clone,
{
    let method = Constrained::<_, M>::new(Midpoint);
    let step = |q: [f64; N], p: [f64; N]| {
        let mut sim = Integrator::new(system.clone(), method, h).start(t, q, p).unwrap();
        sim.step().unwrap();
        *sim.state()
    };
    let mut sim = Integrator::new(system.clone(), method, h).start(t, q, p).unwrap();
    sim.step().unwrap();
    let j = sim.last_tangent_map().unwrap().matrix();
    let next = *sim.state();
    let projector = kernel_projector(&c_at(t, &q, &p));
    let omega = canonical(N);
    let moved = &j * &projector;
    let symplectic = (moved.transpose() * &omega * &moved - projector.transpose() * &omega * &projector).amax();
    let tangent = (c_at(next.t, &next.q, &next.p) * &moved).amax();

    // Central differences along a few tangent vectors: off the manifold by
    // O(ε²) = 1e-12, inside the consistency tolerance.
    let eps = 1e-6;
    let mut gap = 0.0f64;
    for column in [0, N / 2, N, 2 * N - 1] {
        let u = projector.column(column).normalize();
        let shifted = |sign: f64| {
            let state = step(
                core::array::from_fn(|i| q[i] + sign * eps * u[i]),
                core::array::from_fn(|i| p[i] + sign * eps * u[N + i]),
            );
            let mut x = state.q.to_vec();
            x.extend_from_slice(&state.p);
            DMatrix::from_vec(2 * N, 1, x)
        };
        let difference = (shifted(1.0) - shifted(-1.0)) / (2.0 * eps);
        let exact = &j * u;
        gap = gap.max((difference - &exact).amax() / exact.amax());
    }
    (symplectic, tangent, gap)
}

#[test]
fn double_pendulum_tangent_map_is_symplectic_on_the_manifold() {
    let (a0, b0) = (0.8f64, -0.4f64);
    let q0 = [a0.sin(), -a0.cos(), a0.sin() + b0.sin(), -a0.cos() - b0.cos()];
    let method = Constrained::<_, 2>::new(Midpoint);
    let mut sim = Integrator::new(DoublePendulum, method, 0.05).start(0.0, q0, [0.0; 4]).unwrap();
    assert!(sim.last_tangent_map().is_none(), "no step yet");
    sim.run(20, |_| {}).unwrap();
    let s = *sim.state();
    let (symplectic, tangent, gap) =
        check::<_, 4, 2>(DoublePendulum, 0.05, (s.t, s.q, s.p), |_, q, v| double_pendulum_c(q, v));
    println!(
        "double pendulum: on-manifold defect {symplectic:.2e}, off tangent {tangent:.2e}, gap to differences {gap:.2e}"
    );
    assert!(symplectic < 1e-13, "Jᵀ𝕁J − 𝕁 on tangent vectors: {symplectic:e}");
    assert!(tangent < 1e-13, "|C₁ J u| = {tangent:e}");
    assert!(gap < 1e-7, "against central differences: {gap:e}");
    // The whole 2N × 2N matrix projects onto the manifold: not symplectic.
    assert!(sim.last_tangent_map().unwrap().symplecticity_defect() > 1e-3);
}

#[test]
fn rotating_hoop_tangent_map_is_symplectic_on_the_moving_manifold() {
    let omega = 1.5;
    let system = super::time::Hoop { omega };
    let q = [0.5f64.sin(), 0.0, -0.5f64.cos()];
    let (q0, v0) = Constrained::<Midpoint, 2>::new(Midpoint).project(&system, 0.0, q, [0.3, 0.0, 0.0]).unwrap();
    let mut sim = Integrator::new(system.clone(), Constrained::<_, 2>::new(Midpoint), 0.05).start(0.0, q0, v0).unwrap();
    sim.run(13, |_| {}).unwrap();
    let s = *sim.state();
    let (symplectic, tangent, gap) = check::<_, 3, 2>(system, 0.05, (s.t, s.q, s.p), |t, q, v| hoop_c(omega, t, q, v));
    println!(
        "rotating hoop: on-manifold defect {symplectic:.2e}, off tangent {tangent:.2e}, gap to differences {gap:.2e}"
    );
    assert!(symplectic < 1e-13, "Jᵀ𝕁J − 𝕁 on tangent vectors: {symplectic:e}");
    assert!(tangent < 1e-13, "|C₁ J u| = {tangent:e}");
    assert!(gap < 1e-7, "against central differences: {gap:e}");
}
