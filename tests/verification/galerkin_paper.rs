//! Verification against Chen, Guo & Wu (finite elements) and against independent evaluations:
//!
//! * §2.3, (2.49)–(2.50): the quadratic element for `L = ½ q̇²` gives exactly
//!   the five-point stencil and the interior-node equation; with a potential,
//!   the stepper's nodes satisfy (2.49)–(2.51) with the exact `G`.
//! * §2.2: the linear element with the midpoint and trapezoid rules is the
//!   same map as `Midpoint` and `Trapezoid`; with Simpson's rule or an exact
//!   integral of the potential it is another order-2 member.
//! * The chain-rule gradient and Hessian of the action agree with dual-number
//!   derivatives of the action formula itself.
//! * Equispaced and Gauss–Lobatto control nodes give the same map; Gauss–Lobatto
//!   quadrature with `s + 1` points gives order `2s` too.
use crate::common;
use crate::common::galerkin_reference;

use common::*;
use galerkin_reference::pendulum_angle;
use lagrangian::num_dual::{Dual64, HyperDual64};
use lagrangian::prelude::*;
use lagrangian::{Galerkin, GalerkinIntegrator, NodeFamily, Quadrature};

/// A free particle, `L = ½ q̇²`.
#[derive(Debug)]
struct Free;

#[lagrangian]
impl Free {
    fn lagrangian(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0]
    }
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0)
}

#[test]
fn quadratic_element_reproduces_the_stencil_2_49_and_the_interior_equation_2_50() {
    let g = Galerkin::<2, 2>::quadratic();
    assert_eq!(g.control_nodes(), &[0.5, 1.0]);
    let h = 0.37;
    // q_{k−1}, q_{k−½}, q_k, q_{k+½}, q_{k+1}
    let q = [0.3, -1.1, 0.75, 2.4, -0.6];
    let d_behind = [[q[1] - q[0]], [q[2] - q[0]]];
    let d_ahead = [[q[3] - q[2]], [q[4] - q[2]]];
    let (_, g_behind) = g.node_gradient(&Free, 0.0, h, [q[0]], &d_behind);
    let (g0_ahead, g_ahead) = g.node_gradient(&Free, h, h, [q[2]], &d_ahead);
    // DEL at node k in the A-form of docs/theory.md §2: ∂A(x_{k−1}, x_k)/∂q_k + ∂A(x_k, x_{k+1})/∂q_k.
    let del = g_behind[1][0] + g0_ahead[0];
    let stencil = (q[0] - 8.0 * q[1] + 14.0 * q[2] - 8.0 * q[3] + q[4]) / (3.0 * h);
    assert!(close(del, stencil, 1e-14), "DEL {del} vs stencil {stencil}");
    // Paper's L_d form divides once more by h: (2.49) itself.
    assert!(close(del / h, (q[0] - 8.0 * q[1] + 14.0 * q[2] - 8.0 * q[3] + q[4]) / (3.0 * h * h), 1e-14));
    // (2.50): ∂A/∂q_{k+½} = (8/(3h)) (2 q_{k+½} − q_k − q_{k+1}).
    let interior = 8.0 / (3.0 * h) * (2.0 * q[3] - q[2] - q[4]);
    assert!(close(g_ahead[0][0], interior, 1e-14), "{} vs {interior}", g_ahead[0][0]);
    // The same from dual numbers on the action formula (no chain rule).
    let seed = |i: usize| {
        let mut d = [[Dual64::from(q[3] - q[2])], [Dual64::from(q[4] - q[2])]];
        let mut q0 = [Dual64::from(q[2])];
        match i {
            0 => {
                // moving q_k with the other nodes fixed moves every increment the other way
                q0[0].eps = 1.0;
                d[0][0].eps = -1.0;
                d[1][0].eps = -1.0;
            }
            _ => d[0][0].eps = 1.0,
        }
        g.action(&Free, Dual64::from(h), Dual64::from(h), q0, d).eps
    };
    assert!(close(seed(0), g0_ahead[0], 1e-14));
    assert!(close(seed(1), interior, 1e-14));
}

/// `L = ½ q̇² − ½ q²`; `G = (1/h)∫ V = ½ Qᵀ M Q` with the quadratic-element mass matrix.
#[test]
fn quadratic_element_stepper_satisfies_2_49_to_2_51_with_a_potential() {
    // 3 Gauss points integrate the degree-4 potential term exactly.
    let g = Galerkin::<2, 3>::quadratic_with(Quadrature::gauss_legendre());
    let h = 0.25;
    let mut sim = GalerkinIntegrator::new(Oscillator { m: 1.0, k: 1.0 }, g, h).start(0.0, [0.8], [0.3]).unwrap();
    sim.step().unwrap();
    let q_km1 = 0.8;
    let [[q_km_half], [q_k]] = sim.last_nodes().unwrap();
    sim.step().unwrap();
    let [[q_kp_half], [q_kp1]] = sim.last_nodes().unwrap();
    // M_mn = ∫₀¹ φ_m φ_n for the nodes 0, ½, 1.
    let m = [[4.0, 2.0, -1.0], [2.0, 16.0, 2.0], [-1.0, 2.0, 4.0]].map(|r| r.map(|x| x / 30.0));
    let grad_g =
        |a: f64, b: f64, c: f64| core::array::from_fn::<f64, 3, _>(|i| m[i][0] * a + m[i][1] * b + m[i][2] * c);
    let d1 = grad_g(q_k, q_kp_half, q_kp1)[0];
    let d2 = grad_g(q_km1, q_km_half, q_k)[2];
    let stencil = (q_km1 - 8.0 * q_km_half + 14.0 * q_k - 8.0 * q_kp_half + q_kp1) / (3.0 * h * h);
    // (2.49) with the paper's sign convention for L = ½q̇² − V: the potential enters as −G.
    let r249 = stencil - d1 - d2;
    assert!(r249.abs() <= 1e-11, "(2.49) residual {r249:e}");
    let r250 = -8.0 / (3.0 * h * h) * (q_k + q_kp1 - 2.0 * q_kp_half) - grad_g(q_k, q_kp_half, q_kp1)[1];
    let r251 = -8.0 / (3.0 * h * h) * (q_km1 + q_k - 2.0 * q_km_half) - grad_g(q_km1, q_km_half, q_k)[1];
    assert!(r250.abs() <= 1e-11 && r251.abs() <= 1e-11, "(2.50) {r250:e}, (2.51) {r251:e}");
}

fn trajectory<const S: usize, const R: usize>(g: Galerkin<S, R>, h: f64, n: usize) -> Vec<[f64; 2]> {
    let mut sim = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, g, h).start(0.0, [1.2], [0.3]).unwrap();
    let mut out = vec![];
    sim.run(n, |s| out.push([s.state().q[0], s.state().p[0]])).unwrap();
    out
}

fn classic<M: DiscreteLagrangian>(method: M, h: f64, n: usize) -> Vec<[f64; 2]> {
    let mut sim = Integrator::new(Pendulum { ..PENDULUM }, method, h).start(0.0, [1.2], [0.3]).unwrap();
    let mut out = vec![];
    sim.run(n, |s| out.push([s.state().q[0], s.state().p[0]])).unwrap();
    out
}

fn max_diff(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x[0] - y[0]).abs().max((x[1] - y[1]).abs())).fold(0.0, f64::max)
}

#[test]
fn linear_element_with_midpoint_and_trapezoid_rules_is_midpoint_and_trapezoid() {
    let (h, n) = (0.05, 2000);
    let d = max_diff(&trajectory(Galerkin::linear_midpoint(), h, n), &classic(Midpoint, h, n));
    assert!(d <= 1e-11, "midpoint: {d:e}");
    let d = max_diff(&trajectory(Galerkin::linear_trapezoid(), h, n), &classic(Trapezoid, h, n));
    assert!(d <= 1e-11, "trapezoid: {d:e}");
    // Simpson's rule is a different member (not the midpoint, not the trapezoid).
    let simpson = trajectory(Galerkin::linear_simpson(), h, n);
    assert!(max_diff(&simpson, &classic(Midpoint, h, n)) > 1e-6);
    assert!(max_diff(&simpson, &classic(Trapezoid, h, n)) > 1e-6);
}

#[test]
fn linear_elements_are_of_order_two_whatever_the_quadrature() {
    let t = 5.0;
    let w = (PENDULUM.g / PENDULUM.l).sqrt();
    let exact = pendulum_angle(w, 1.0, t);
    let steps = [500usize, 707, 1000, 1414, 2000];
    let h: Vec<f64> = steps.iter().map(|&n| t / n as f64).collect();
    let run = |n: usize, which: usize| {
        let h = t / n as f64;
        let q0 = [1.0];
        let v0 = [0.0];
        let q = match which {
            0 => {
                let mut s = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, Galerkin::linear_simpson(), h)
                    .start(0.0, q0, v0)
                    .unwrap();
                s.run(n, |_| {}).unwrap();
                s.state().q[0]
            }
            _ => {
                // F integrated to round-off: the paper's exact linear element (2.23)–(2.24).
                let g = Galerkin::<1, 8>::linear(Quadrature::gauss_legendre());
                let mut s = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, g, h).start(0.0, q0, v0).unwrap();
                s.run(n, |_| {}).unwrap();
                s.state().q[0]
            }
        };
        (q - exact).abs()
    };
    for which in [0, 1] {
        let err: Vec<f64> = steps.iter().map(|&n| run(n, which)).collect();
        let order = fitted_order(&h, &err);
        assert!((order - 2.0).abs() <= 0.1, "linear element {which}: order {order}, errors {err:?}");
    }
}

#[test]
fn equispaced_and_lobatto_nodes_give_the_same_map() {
    let (h, n) = (0.2, 500);
    let lobatto = trajectory(Galerkin::<4, 4>::gauss(), h, n);
    let equi = trajectory(Galerkin::<4, 4>::new(NodeFamily::Equispaced, Quadrature::gauss_legendre()), h, n);
    let d = max_diff(&lobatto, &equi);
    assert!(d <= 1e-11, "{d:e}");
}

#[test]
fn gauss_lobatto_quadrature_with_s_plus_1_points_has_order_2s() {
    let t = 20.0;
    let w = (PENDULUM.g / PENDULUM.l).sqrt();
    let exact = pendulum_angle(w, 1.0, t);
    fn run<const S: usize, const R: usize>(n: usize, t: f64) -> f64 {
        let g = Galerkin::<S, R>::new(NodeFamily::GaussLobatto, Quadrature::gauss_lobatto());
        let mut s = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, g, t / n as f64).start(0.0, [1.0], [0.0]).unwrap();
        s.run(n, |_| {}).unwrap();
        s.state().q[0]
    }
    let steps2 = [320usize, 381, 453, 538, 640];
    let steps3 = [254usize, 302, 359, 427, 508];
    for (s, steps) in [(2usize, steps2), (3, steps3)] {
        let h: Vec<f64> = steps.iter().map(|&n| t / n as f64).collect();
        let err: Vec<f64> =
            steps.iter().map(|&n| (if s == 2 { run::<2, 3>(n, t) } else { run::<3, 4>(n, t) } - exact).abs()).collect();
        let order = fitted_order(&h, &err);
        assert!((order - 2.0 * s as f64).abs() <= 0.15, "Lobatto s = {s}: order {order}, errors {err:?}");
    }
}

#[test]
fn chain_rule_derivatives_match_dual_numbers_on_the_action() {
    let g = Galerkin::<3, 4>::new(NodeFamily::GaussLobatto, Quadrature::gauss_legendre());
    let sys = DoublePendulum { ..DOUBLE_PENDULUM };
    let (t0, h) = (0.4, 0.3);
    let q0 = [0.7, -0.3];
    let d = [[0.05, 0.11], [0.12, 0.19], [0.21, 0.24]];
    let (g0, gn) = g.node_gradient(&sys, t0, h, q0, &d);
    let hess = g.node_hessian(&sys, t0, h, q0, &d);
    // Node m = 0 … 3, coordinate i: the variables of the action. Moving node 0
    // with the others fixed moves q0 and every increment the other way.
    let lift = |a: (usize, usize), b: (usize, usize)| {
        let mut q = q0.map(HyperDual64::from);
        let mut dd = d.map(|r| r.map(HyperDual64::from));
        for (k, (m, i)) in [a, b].into_iter().enumerate() {
            let set = |x: &mut HyperDual64, s: f64| if k == 0 { x.eps1 += s } else { x.eps2 += s };
            if m == 0 {
                set(&mut q[i], 1.0);
                for r in dd.iter_mut() {
                    set(&mut r[i], -1.0);
                }
            } else {
                set(&mut dd[m - 1][i], 1.0);
            }
        }
        g.action(&sys, HyperDual64::from(t0), HyperDual64::from(h), q, dd)
    };
    for m in 0..4 {
        for i in 0..2 {
            let want = if m == 0 { g0[i] } else { gn[m - 1][i] };
            let got = lift((m, i), (m, i)).eps1;
            assert!(close(got, want, 1e-13), "∂A/∂Q_{m}[{i}]: {got} vs {want}");
            for n in 0..4 {
                for k in 0..2 {
                    let got = lift((m, i), (n, k)).eps1eps2;
                    let want = hess[(m * 2 + i, n * 2 + k)];
                    assert!(close(got, want, 1e-12), "∂²A/∂Q_{m}[{i}]∂Q_{n}[{k}]: {got} vs {want}");
                }
            }
        }
    }
}
