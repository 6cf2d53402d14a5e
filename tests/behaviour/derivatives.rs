//! The derivatives generated through `#[lagrangian]` against hand-derived formulas.
//!
//! Midpoint, `A = h L(q̄, v̂)` with `q̄ = (q_k + q_{k+1})/2`, `v̂ = (q_{k+1} − q_k)/h`:
//!
//! ```text
//! ∂A/∂q_k      = (h/2) L_q − L_v           ∂A/∂q_{k+1} = (h/2) L_q + L_v
//! ∂²A/∂q_k∂q_{k+1} = (h/4) L_qq + ½ (L_{q_i v_j} − L_{q_j v_i}) − (1/h) L_vv
//! L_d = A/h:  D2 = ∂A/∂q_k / h,  D4 = ∂A/∂q_{k+1} / h,  D1 = L_v·v̂/h,  D3 = −L_v·v̂/h   (autonomous L)
//! ```
use crate::common;

use common::*;
use lagrangian::prelude::*;
use lagrangian::{DiscreteMechanics, Midpoint, Segment};
use nalgebra::SMatrix;

const TOL: f64 = 1e-13;

/// `(L_q, L_v, L_qq, L_qv, L_vv)` at a point, with `L_qv[i][j] = ∂²L/∂q_i∂v_j`.
type Partials<const N: usize> = ([f64; N], [f64; N], [[f64; N]; N], [[f64; N]; N], [[f64; N]; N]);

/// Hand-derived partials of the double pendulum's `L` at `(q, v)`:
/// `(L_q, L_v, L_qq, L_qv, L_vv)` with `L_qv[i][j] = ∂²L/∂q_i∂v_j`.
#[allow(clippy::type_complexity)]
fn double_pendulum_partials(
    q: [f64; 2],
    v: [f64; 2],
) -> ([f64; 2], [f64; 2], [[f64; 2]; 2], [[f64; 2]; 2], [[f64; 2]; 2]) {
    let s = DOUBLE_PENDULUM;
    let a = (s.m1 + s.m2) * s.l1 * s.l1;
    let b = s.m2 * s.l2 * s.l2;
    let c = s.m2 * s.l1 * s.l2;
    let d = (s.m1 + s.m2) * s.g * s.l1;
    let e = s.m2 * s.g * s.l2;
    let (sd, cd) = (q[0] - q[1]).sin_cos();
    let l_q = [-c * v[0] * v[1] * sd - d * q[0].sin(), c * v[0] * v[1] * sd - e * q[1].sin()];
    let l_v = [a * v[0] + c * v[1] * cd, b * v[1] + c * v[0] * cd];
    let l_qq = [
        [-c * v[0] * v[1] * cd - d * q[0].cos(), c * v[0] * v[1] * cd],
        [c * v[0] * v[1] * cd, -c * v[0] * v[1] * cd - e * q[1].cos()],
    ];
    let l_qv = [[-c * v[1] * sd, -c * v[0] * sd], [c * v[1] * sd, c * v[0] * sd]];
    let l_vv = [[a, c * cd], [c * cd, b]];
    (l_q, l_v, l_qq, l_qv, l_vv)
}

fn pendulum_partials(q: [f64; 1], v: [f64; 1]) -> Partials<1> {
    let s = PENDULUM;
    let a = s.m * s.l * s.l;
    let d = s.m * s.g * s.l;
    ([-d * q[0].sin()], [a * v[0]], [[-d * q[0].cos()]], [[0.0]], [[a]])
}

/// Checks every generated derivative of the midpoint action on one segment.
fn check<S: Lagrangian<N>, const N: usize>(
    system: &S,
    seg: Segment<N>,
    partials: fn([f64; N], [f64; N]) -> Partials<N>,
) {
    let h = seg.h;
    let qm: [f64; N] = core::array::from_fn(|i| seg.q0[i] + 0.5 * seg.dq[i]);
    let vh: [f64; N] = core::array::from_fn(|i| seg.dq[i] / h);
    let (l_q, l_v, l_qq, l_qv, l_vv) = partials(qm, vh);

    let d_q0: [f64; N] = core::array::from_fn(|i| 0.5 * h * l_q[i] - l_v[i]);
    let d_q1: [f64; N] = core::array::from_fn(|i| 0.5 * h * l_q[i] + l_v[i]);
    let jac =
        SMatrix::<f64, N, N>::from_fn(|i, j| 0.25 * h * l_qq[i][j] + 0.5 * (l_qv[i][j] - l_qv[j][i]) - l_vv[i][j] / h);

    let got = system.step_derivatives(&Midpoint, &seg);
    assert!(rel_err(&got.d_q0, &d_q0) <= TOL, "∂A/∂q_k {:?} vs {:?}", got.d_q0, d_q0);
    assert!(rel_err(&got.d_q1, &d_q1) <= TOL, "∂A/∂q_k+1 {:?} vs {:?}", got.d_q1, d_q1);
    assert!(rel_err(got.d2_q0_q1.as_slice(), jac.as_slice()) <= TOL, "jacobian {} vs {}", got.d2_q0_q1, jac);

    let jac_del = system.del_jacobian(&Midpoint, (seg.t0, seg.q0), (seg.t1(), seg.q1()));
    assert!(rel_err(jac_del.as_slice(), jac.as_slice()) <= TOL);

    let d = system.discrete_partials(&Midpoint, &seg);
    let lv_dot_v: f64 = (0..N).map(|i| l_v[i] * vh[i]).sum();
    let l_d = system.lagrangian_value(0.0, qm, vh);
    assert!(rel_err(&[d.l_d], &[l_d]) <= TOL);
    assert!(rel_err(&d.d2, &d_q0.map(|x| x / h)) <= TOL, "D2");
    assert!(rel_err(&d.d4, &d_q1.map(|x| x / h)) <= TOL, "D4");
    assert!(rel_err(&[d.d1], &[lv_dot_v / h]) <= TOL, "D1 {} vs {}", d.d1, lv_dot_v / h);
    assert!(rel_err(&[d.d3], &[-lv_dot_v / h]) <= TOL, "D3 {} vs {}", d.d3, -lv_dot_v / h);
}

#[test]
fn pendulum_midpoint_derivatives_match_hand_derived_formulas() {
    for (q0, q1, h) in [(0.3, 0.32, 0.01), (-2.0, -1.7, 0.1), (3.0, 3.1, 0.05)] {
        check(&PENDULUM, Segment::between((0.4, [q0]), (0.4 + h, [q1])), pendulum_partials);
    }
}

#[test]
fn double_pendulum_midpoint_derivatives_match_hand_derived_formulas() {
    for (q0, q1, h) in
        [([0.3, -0.2], [0.31, -0.19], 0.01), ([2.0, 1.0], [2.2, 0.7], 0.1), ([-1.0, 3.0], [-0.9, 3.05], 0.05)]
    {
        check(&DOUBLE_PENDULUM, Segment::between((1.0, q0), (1.0 + h, q1)), double_pendulum_partials);
    }
}

#[test]
fn del_residual_is_the_sum_of_both_steps_partials() {
    let s = &DOUBLE_PENDULUM;
    let (n0, n1, n2) = ((0.0, [0.3, -0.2]), (0.01, [0.305, -0.196]), (0.02, [0.309, -0.191]));
    let behind = s.step_derivatives(&Midpoint, &Segment::between(n0, n1));
    let ahead = s.step_derivatives(&Midpoint, &Segment::between(n1, n2));
    let want: [f64; 2] = core::array::from_fn(|i| behind.d_q1[i] + ahead.d_q0[i]);
    let got = s.del_residual(&Midpoint, n0, n1, n2);
    for i in 0..2 {
        assert!((got[i] - want[i]).abs() <= TOL * (behind.d_q1[i].abs() + ahead.d_q0[i].abs()));
    }
}

#[test]
fn momentum_and_energy_of_the_lagrangian() {
    let s = &DOUBLE_PENDULUM;
    let (q, v) = ([0.4, -1.1], [0.7, 2.0]);
    let (_, l_v, _, _, l_vv) = double_pendulum_partials(q, v);
    assert!(rel_err(&s.momentum(0.0, q, v), &l_v) <= TOL);
    let e = l_v[0] * v[0] + l_v[1] * v[1] - s.lagrangian_value(0.0, q, v);
    assert!(rel_err(&[s.energy(0.0, q, v)], &[e]) <= TOL);
    let hess = s.velocity_hessian(0.0, q, v);
    assert!(rel_err(hess.as_slice(), &[l_vv[0][0], l_vv[1][0], l_vv[0][1], l_vv[1][1]]) <= TOL);
    let back = s.velocity(0.0, q, l_v, [0.0, 0.0]).unwrap();
    assert!(rel_err(&back, &v) <= 1e-13);
}
