//! Derivatives of the computed trajectory (docs/theory.md §11): forward
//! sensitivities and the discrete adjoint of the one-point rules, the
//! Galerkin rules and the compositions, checked against each other, against
//! central finite differences, against dual numbers pushed through an
//! independent midpoint run, and by the pairing `λ_kᵀ S_k` of the two,
//! which a linear step map conserves.

use lagrangian::Jacobian;
use lagrangian::SolveError;
use lagrangian::num_dual::{Dual, Dual64, DualNum, HyperDual64};
use lagrangian::prelude::*;
use lagrangian::sensitivity::Gradient;

/// A double pendulum with `m1`, `l1` and `g` as parameters.
#[derive(Clone, Debug)]
pub struct DoublePendulum {
    m1: f64,
    m2: f64,
    l1: f64,
    l2: f64,
    g: f64,
}

#[lagrangian(parameters(m1, l1, g))]
impl DoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = 0.5 * (self.m1 + self.m2) * self.l1 * self.l1 * v[0] * v[0]
            + 0.5 * self.m2 * self.l2 * self.l2 * v[1] * v[1]
            + self.m2 * self.l1 * self.l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        let potential = -(self.m1 + self.m2) * self.g * self.l1 * q[0].cos() - self.m2 * self.g * self.l2 * q[1].cos();
        kinetic - potential
    }
}

const SYSTEM: DoublePendulum = DoublePendulum { m1: 1.0, m2: 0.8, l1: 1.2, l2: 0.9, g: 9.81 };
const Q0: [f64; 2] = [0.6, -0.3];
const V0: [f64; 2] = [0.2, 0.5];
const H: f64 = 1e-3;
/// 10⁴ steps.
const T_END: f64 = 10.0;

/// The span of the runs of `scheme`: [`T_END`], and a fifth of it for the
/// compositions, whose steps of 15 sub-steps would make the same span the
/// longest run of this unoptimised binary by far (2·10³ steps still carry
/// the adjoint through 3·10⁴ sub-steps).
fn t_end(scheme: &Scheme) -> f64 {
    if matches!(scheme, Scheme::Composition { .. }) { T_END / 5.0 } else { T_END }
}

/// `Σ_k w (q_k,0² + ½ q_k,1²) + H(q_n, p_n; θ)`: positions at every node
/// and the final energy, `H = ½ pᵀM(q)⁻¹p + V(q)`.
struct PositionsAndEnergy {
    weight: f64,
    system: DoublePendulum,
}

impl Loss<2, 3> for PositionsAndEnergy {
    fn running<D: Scalar>(&self, _k: u64, _t: D, q: [D; 2], _p: [D; 2], _theta: &[D; 3]) -> D {
        (q[0] * q[0] + q[1] * q[1] * 0.5) * self.weight
    }

    fn terminal<D: Scalar>(&self, _t: D, q: [D; 2], p: [D; 2], theta: &[D; 3]) -> D {
        let [m1, l1, g] = *theta;
        let (m2, l2) = (self.system.m2, self.system.l2);
        let a = (m1 + m2) * l1 * l1;
        let b = D::from(m2 * l2 * l2);
        let c = l1 * (m2 * l2) * (q[0] - q[1]).cos();
        let det = a * b - c * c;
        let kinetic = (b * p[0] * p[0] - c * p[0] * p[1] * 2.0 + a * p[1] * p[1]) / (det * 2.0);
        let potential = -(m1 + m2) * g * l1 * q[0].cos() - g * (m2 * l2) * q[1].cos();
        kinetic + potential
    }
}

fn loss() -> PositionsAndEnergy {
    PositionsAndEnergy { weight: 1e-3, system: SYSTEM }
}

/// The loss of the run of `scheme` from `(q0, v0)` with parameters
/// `theta`, evaluated by a plain solve: what the finite differences
/// difference.
fn loss_of_run(scheme: &Scheme, q0: [f64; 2], v0: [f64; 2], theta: [f64; 3]) -> f64 {
    let system = SYSTEM.with_parameters(theta);
    let sol = Problem::new(system, 0.0, q0, v0)
        .solve(scheme, H, Plan::until(t_end(scheme)).without_velocities())
        .unwrap()
        .into_result()
        .unwrap();
    let l = loss();
    let n = sol.len() - 1;
    let mut j = 0.0;
    for k in 0..=n {
        j += l.running(k as u64, sol.t[k], sol.q.array(k).unwrap(), sol.p.array(k).unwrap(), &theta);
    }
    j + l.terminal(sol.t[n], sol.q.array(n).unwrap(), sol.p.array(n).unwrap(), &theta)
}

fn adjoint(scheme: &Scheme, checkpoints: Checkpoints) -> Gradient<2, 3> {
    Problem::new(SYSTEM, 0.0, Q0, V0).gradient(scheme, H, t_end(scheme), &loss(), checkpoints).unwrap()
}

/// The 7 components `(q0, v0, θ)` of a gradient.
fn components(g: &Gradient<2, 3>) -> [f64; 7] {
    [g.q0[0], g.q0[1], g.v0[0], g.v0[1], g.theta[0], g.theta[1], g.theta[2]]
}

/// `max |a − b| / max |b|`.
fn relative(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// The gradient of a node term `f(q, p, θ)` by dual numbers.
fn term_gradient(f: impl Fn([Dual64; 2], [Dual64; 2], &[Dual64; 3]) -> Dual64, q: [f64; 2], p: [f64; 2]) -> [f64; 7] {
    let theta = SYSTEM.parameters();
    let mut out = [0.0; 7];
    for (i, slot) in out.iter_mut().enumerate() {
        let mut x: Vec<Dual64> = q.iter().chain(&p).chain(&theta).map(|&x| Dual64::from_re(x)).collect();
        x[i].eps = 1.0;
        *slot = f([x[0], x[1]], [x[2], x[3]], &[x[4], x[5], x[6]]).eps;
    }
    out
}

/// dJ/d(q0, v0, θ) from the forward sensitivities of every node:
/// `Σ_k ∂ℓ_k/∂(q, p) S_k + ∂ℓ_k/∂θ`.
fn forward_gradient(scheme: &Scheme) -> ([f64; 7], Vec<Jacobian>, Solution) {
    forward_gradient_of(SYSTEM, scheme, ["m1", "l1", "g"])
}

/// [`forward_gradient`] of `system`, whose parameters are `names` and hold
/// the values of [`SYSTEM`]'s.
fn forward_gradient_of<S: Parametric<2, 3>>(
    system: S,
    scheme: &Scheme,
    names: [&str; 3],
) -> ([f64; 7], Vec<Jacobian>, Solution) {
    let run = Problem::new(system, 0.0, Q0, V0)
        .solve_with_sensitivities(scheme, H, Plan::until(t_end(scheme)).without_velocities())
        .unwrap();
    assert!(run.error.is_none() && run.solution.is_finished());
    assert_eq!(run.parameters, names);
    let l = loss();
    let n = run.solution.len() - 1;
    let mut total = [0.0; 7];
    for (k, s) in run.jacobians.iter().enumerate() {
        let (q, p, t) = (run.solution.q.array(k).unwrap(), run.solution.p.array(k).unwrap(), run.solution.t[k]);
        let g = term_gradient(
            |q, p, th| {
                let t = Dual64::from_re(t);
                let r = l.running(k as u64, t, q, p, th);
                if k == n { r + l.terminal(t, q, p, th) } else { r }
            },
            q,
            p,
        );
        for (col, slot) in total.iter_mut().enumerate() {
            // Through the state, then directly through θ.
            *slot += (0..4).map(|i| g[i] * s.get(i, col)).sum::<f64>();
            if col >= 4 {
                *slot += g[col];
            }
        }
    }
    (total, run.jacobians, run.solution)
}

/// The adjoint of `scheme` over 10⁴ steps of the double pendulum ([`t_end`]) against
/// its forward sensitivities (≤ 1e-12 relative), against the value of a
/// plain solve, and against central differences of plain solves (≤ 1e-7).
fn adjoint_agrees(scheme: &Scheme) {
    let g = adjoint(scheme, Checkpoints::Budget(100));
    assert_eq!(g.last.step, (t_end(scheme) / H).round() as u64);
    let adjoint = components(&g);
    let (forward, _, _) = forward_gradient(scheme);
    let vs_forward = relative(&adjoint, &forward);
    eprintln!("{}: adjoint vs forward: {vs_forward:.1e} ({adjoint:?})", scheme.name());
    assert!(vs_forward <= 1e-12, "{vs_forward:e}");

    // The value is the loss of the same run.
    let value = loss_of_run(scheme, Q0, V0, SYSTEM.parameters());
    assert!((g.value - value).abs() <= 1e-13 * value.abs(), "{} vs {value}", g.value);

    // Central differences, step ε·max(1, |x|) with ε = 1e-5: truncation
    // O(ε²) and round-off O(1e-16/ε) balance near 1e-10 relative.
    let mut fd = [0.0; 7];
    let base: Vec<f64> = Q0.iter().chain(&V0).chain(&SYSTEM.parameters()).copied().collect();
    for (i, slot) in fd.iter_mut().enumerate() {
        let step = 1e-5 * base[i].abs().max(1.0);
        let at = |s: f64| {
            let mut x = base.clone();
            x[i] += s;
            loss_of_run(scheme, [x[0], x[1]], [x[2], x[3]], [x[4], x[5], x[6]])
        };
        *slot = (at(step) - at(-step)) / (2.0 * step);
    }
    let vs_fd = relative(&adjoint, &fd);
    eprintln!("{}: adjoint vs central differences: {vs_fd:.1e}", scheme.name());
    assert!(vs_fd <= 1e-7, "{vs_fd:e}");
}

#[test]
fn adjoint_agrees_with_forward_sensitivities_and_finite_differences() {
    adjoint_agrees(&Scheme::MIDPOINT);
}

#[test]
fn galerkin_adjoint_agrees_with_forward_sensitivities_and_finite_differences() {
    adjoint_agrees(&Scheme::galerkin(3));
}

#[test]
fn high_degree_galerkin_adjoint_agrees_with_forward_sensitivities_and_finite_differences() {
    adjoint_agrees(&Scheme::galerkin(6));
}

#[test]
fn composition_adjoint_agrees_with_forward_sensitivities_and_finite_differences() {
    adjoint_agrees(&Scheme::composition(Composition::KAHAN_LI8, OnePoint::Trapezoid));
}

/// Entries of [`ArrayPendulum::first`]: `m1`, `l1`.
const LINK: usize = 2;

/// [`DoublePendulum`] with `m1` and `l1` in one array parameter: the same
/// `θ = (m1, l1, g)`, read as `first[0]`, `first[1]`, `g`.
#[derive(Clone, Debug)]
pub struct ArrayPendulum {
    first: [f64; LINK],
    m2: f64,
    l2: f64,
    g: f64,
}

#[lagrangian(parameters(first: [f64; LINK], g))]
impl ArrayPendulum {
    // `DoublePendulum`'s body with `self.m1`, `self.l1` spelt
    // `self.first[0]`, `self.first[1]`: the same expression tree.
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = 0.5 * (self.first[0] + self.m2) * self.first[1] * self.first[1] * v[0] * v[0]
            + 0.5 * self.m2 * self.l2 * self.l2 * v[1] * v[1]
            + self.m2 * self.first[1] * self.l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        let potential =
            -(self.first[0] + self.m2) * self.g * self.first[1] * q[0].cos() - self.m2 * self.g * self.l2 * q[1].cos();
        kinetic - potential
    }
}

#[test]
fn an_array_parameter_differentiates_as_the_scalars_it_holds() {
    let system = ArrayPendulum { first: [SYSTEM.m1, SYSTEM.l1], m2: SYSTEM.m2, l2: SYSTEM.l2, g: SYSTEM.g };
    assert_eq!(ArrayPendulum::NAMES, ["first[0]", "first[1]", "g"]);
    assert_eq!(system.parameters(), SYSTEM.parameters());
    let moved = system.with_parameters([1.5, 0.7, 9.0]);
    assert_eq!((moved.first, moved.m2, moved.l2, moved.g), ([1.5, 0.7], SYSTEM.m2, SYSTEM.l2, 9.0));

    // The same expression tree as with scalar parameters, evaluated in the
    // same order: the same numbers, bit for bit.
    let scheme = Scheme::MIDPOINT;
    let arrays = Problem::new(system.clone(), 0.0, Q0, V0)
        .gradient(&scheme, H, T_END, &loss(), Checkpoints::Budget(100))
        .unwrap();
    let scalars = adjoint(&scheme, Checkpoints::Budget(100));
    let (forward_arrays, jacobians_arrays, _) = forward_gradient_of(system, &scheme, ["first[0]", "first[1]", "g"]);
    let (forward_scalars, jacobians_scalars, _) = forward_gradient(&scheme);
    let entries = |jacobians: &[Jacobian]| -> Vec<f64> {
        jacobians.iter().flat_map(|s| (0..4).flat_map(move |i| (0..7).map(move |col| s.get(i, col)))).collect()
    };
    let differences = [
        relative(&components(&arrays), &components(&scalars)),
        relative(&[arrays.value], &[scalars.value]),
        relative(&forward_arrays, &forward_scalars),
        relative(&entries(&jacobians_arrays), &entries(&jacobians_scalars)),
    ];
    eprintln!(
        "array vs scalar parameters (adjoint, value, forward, Jacobians): {:?}",
        differences.map(|d| format!("{d:.1e}"))
    );
    assert_eq!(differences, [0.0; 4]);
    // And the adjoint of the array system agrees with its forward
    // sensitivities, as for the scalars.
    let vs_forward = relative(&components(&arrays), &forward_arrays);
    eprintln!("array parameters: adjoint vs forward: {vs_forward:.1e}");
    assert!(vs_forward <= 1e-12, "{vs_forward:e}");
}

#[test]
fn checkpoint_spacing_changes_the_work_not_the_gradient() {
    let every = adjoint(&Scheme::MIDPOINT, Checkpoints::Every(1));
    let sqrt = adjoint(&Scheme::MIDPOINT, Checkpoints::Budget(100));
    let one = adjoint(&Scheme::MIDPOINT, Checkpoints::Budget(1));
    // Re-running a segment from its copy gives the same nodes bit for bit.
    assert_eq!(components(&every), components(&sqrt));
    assert_eq!(components(&every), components(&one));
    assert_eq!(every.recomputed_steps, 10_000);
    assert_eq!((sqrt.costates.len(), one.costates.len()), (101, 2));
}

/// With a terminal loss alone, `λ_kᵀ S_k` (the columns of q0 and v0) is
/// the same at every checkpoint node of `scheme`: the gradient with respect
/// to the initial data.
fn pairing_is_conserved(scheme: &Scheme) {
    struct Terminal;
    impl Loss<2, 3> for Terminal {
        fn terminal<D: Scalar>(&self, _t: D, q: [D; 2], p: [D; 2], _theta: &[D; 3]) -> D {
            q[0].sin() * p[1] + q[1] * q[1]
        }
    }
    // 20 checkpoint intervals.
    let every = (t_end(scheme) / H / 20.0).round() as usize;
    let g = Problem::new(SYSTEM, 0.0, Q0, V0)
        .gradient(scheme, H, t_end(scheme), &Terminal, Checkpoints::Every(every))
        .unwrap();
    let (_, jacobians, solution) = forward_gradient(scheme);
    let expected = [g.q0[0], g.q0[1], g.v0[0], g.v0[1]];
    let mut worst = 0.0f64;
    for (state, lq, lp) in &g.costates {
        let k = state.step as usize;
        assert_eq!(solution.q[k], state.q);
        let lambda = [lq[0], lq[1], lp[0], lp[1]];
        let pairing: Vec<f64> =
            (0..4).map(|col| (0..4).map(|i| lambda[i] * jacobians[k].get(i, col)).sum::<f64>()).collect();
        worst = worst.max(relative(&pairing, &expected));
    }
    eprintln!("{}: pairing drift over {} checkpoints: {worst:.1e}", scheme.name(), g.costates.len());
    assert_eq!(g.costates.len(), 21);
    assert!(worst <= 1e-12, "{worst:e}");
}

#[test]
fn the_pairing_of_costate_and_tangent_is_conserved() {
    pairing_is_conserved(&Scheme::MIDPOINT);
    pairing_is_conserved(&Scheme::galerkin(3));
    pairing_is_conserved(&Scheme::Galerkin {
        degree: 3,
        nodes: NodeFamily::Equispaced,
        quadrature: GalerkinQuadrature::GaussLobatto,
    });
    pairing_is_conserved(&Scheme::composition(Composition::KAHAN_LI8, OnePoint::Trapezoid));
}

/// One midpoint step on dual numbers, written out here (independently of
/// the runtime's linearisation): Newton on `p_k + D₁A(q_k, q_{k+1}) = 0`
/// evaluated on `Dual64`, then `p_{k+1} = D₂A`.
fn dual_midpoint_step(theta: &[Dual64; 3], q: [Dual64; 2], p: [Dual64; 2]) -> ([Dual64; 2], [Dual64; 2]) {
    let action_gradient = |q0: [Dual64; 2], q1: [Dual64; 2], first: bool| -> [Dual64; 2] {
        core::array::from_fn(|i| {
            let lift = |x: [Dual64; 2]| x.map(Dual::from_re);
            let (mut a, mut b) = (lift(q0), lift(q1));
            if first {
                a[i].eps = Dual64::from_re(1.0)
            } else {
                b[i].eps = Dual64::from_re(1.0)
            }
            let th = theta.map(Dual::from_re);
            let mid = [(a[0] + b[0]) * 0.5, (a[1] + b[1]) * 0.5];
            let v = [(b[0] - a[0]) / H, (b[1] - a[1]) / H];
            (SYSTEM.lagrangian_with(&th, Dual::from_re(Dual64::from_re(0.0)), mid, v) * H).eps
        })
    };
    let mut q1 = q;
    for _ in 0..50 {
        let r = action_gradient(q, q1, true);
        let r = [p[0] + r[0], p[1] + r[1]];
        // The Newton matrix ∂²A/∂q_k∂q_{k+1} at the real parts.
        let seg = Segment::between((0.0, q.map(|x| x.re)), (H, q1.map(|x| x.re)));
        let m = derivatives::step_derivatives(&SYSTEM, &Midpoint, &seg).d2_q0_q1;
        let inv = m.try_inverse().unwrap();
        let dq = [r[0] * inv[(0, 0)] + r[1] * inv[(0, 1)], r[0] * inv[(1, 0)] + r[1] * inv[(1, 1)]];
        q1 = [q1[0] - dq[0], q1[1] - dq[1]];
        if dq.iter().all(|d| d.re.abs() < 1e-16 && d.eps.abs() < 1e-16 * (1.0 + q1[0].eps.abs())) {
            break;
        }
    }
    (q1, action_gradient(q, q1, false))
}

use lagrangian::Segment;
use lagrangian::derivatives;

#[test]
fn dual_numbers_through_a_short_run_agree_with_the_sensitivities() {
    // The runtime's integrator holds its state in a `Real`, which num-dual's
    // `Dual64` is not (the trait is the runtime's and the type num-dual's),
    // so the dual run is a midpoint run written here.
    let steps = 200;
    let run = Problem::new(SYSTEM, 0.0, Q0, V0)
        .solve_with_sensitivities(&Scheme::MIDPOINT, H, Plan::until(steps as f64 * H))
        .unwrap();
    let last = run.jacobians.last().unwrap();
    assert_eq!(run.solution.step.last(), Some(&Some(steps)));
    let (mut worst, mut state_gap) = (0.0f64, 0.0f64);
    for j in 0..3 {
        let mut theta = SYSTEM.parameters().map(Dual64::from_re);
        theta[j].eps = 1.0;
        // p0 = ∂L/∂v(q0, v0; θ) on duals.
        let q: [Dual64; 2] = Q0.map(Dual64::from_re);
        let mut p: [Dual64; 2] = core::array::from_fn(|i| {
            let mut v = V0.map(|x| Dual::from_re(Dual64::from_re(x)));
            v[i].eps = Dual64::from_re(1.0);
            SYSTEM
                .lagrangian_with(
                    &theta.map(Dual::from_re),
                    Dual::from_re(Dual64::from_re(0.0)),
                    q.map(Dual::from_re),
                    v,
                )
                .eps
        });
        let mut q = q;
        for _ in 0..steps {
            (q, p) = dual_midpoint_step(&theta, q, p);
        }
        let dual = [q[0].eps, q[1].eps, p[0].eps, p[1].eps];
        let n = run.solution.len() - 1;
        let (sq, sp) = (&run.solution.q[n], &run.solution.p[n]);
        state_gap = state_gap.max(relative(&[q[0].re, q[1].re, p[0].re, p[1].re], &[sq[0], sq[1], sp[0], sp[1]]));
        let sens: Vec<f64> = (0..4).map(|i| last.get(i, 4 + j)).collect();
        worst = worst.max(relative(&sens, &dual));
    }
    // The two runs sum their updates differently (the runtime compensates
    // its sums): their states part by about 1e-13 over 200 steps, and the
    // derivatives, taken at those slightly different states, by ten times
    // that. Measured: states 9.6e-14, derivatives 9.5e-13 (relative).
    eprintln!("sensitivities vs dual run: {worst:.1e} (states {state_gap:.1e})");
    assert!(state_gap <= 1e-12, "{state_gap:e}");
    assert!(worst <= 1e-11, "{worst:e}");
}

/// Planar Kepler with the gravitational parameter `μ`.
#[derive(Clone, Debug)]
pub struct Kepler {
    mu: f64,
}

#[lagrangian(parameters(mu))]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + self.mu / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// e = 0.5 from the pericentre, a = 1 and μ = 1: period 2π.
const KEPLER: Kepler = Kepler { mu: 1.0 };
const KEPLER_Q0: [f64; 2] = [0.5, 0.0];
const KEPLER_V0: [f64; 2] = [0.0, 1.7320508075688772];
/// The floor of the curvature monitor `g = (κ² + floor²)^{-1/4}`, `κ = √5 μ/r³`.
const FLOOR: f64 = 1e-2;
/// The step in `s`: about 90 steps an orbit.
const SIGMA: f64 = 0.1;
/// Three orbits.
const KEPLER_T_END: f64 = 6.0 * std::f64::consts::PI;

/// A loss that reads the node times: `Σ_k 10⁻² (q_k,0 sin t_k + q_k,1) + |q_n|² + μ q_n,1 p_n,1`,
/// so that `∂ℓ/∂t` enters the gradient.
struct Tracking;

impl Loss<2, 1> for Tracking {
    fn running<D: Scalar>(&self, _k: u64, t: D, q: [D; 2], _p: [D; 2], _theta: &[D; 1]) -> D {
        (q[0] * t.sin() + q[1]) * 1e-2
    }

    fn terminal<D: Scalar>(&self, _t: D, q: [D; 2], p: [D; 2], theta: &[D; 1]) -> D {
        q[0] * q[0] + q[1] * q[1] + theta[0] * q[1] * p[1]
    }
}

fn transformed(inner: Scheme) -> Scheme {
    inner.time_transformed(Curvature::new(FLOOR).unwrap())
}

/// The loss of a plain time-transformed run from `(q0, v0)` with `μ`.
fn kepler_loss_of_run(scheme: &Scheme, q0: [f64; 2], v0: [f64; 2], mu: f64) -> f64 {
    let sol = Problem::new(Kepler { mu }, 0.0, q0, v0)
        .solve(scheme, SIGMA, Plan::until(KEPLER_T_END).without_velocities())
        .unwrap()
        .into_result()
        .unwrap();
    let n = sol.len() - 1;
    let mut j = 0.0;
    for k in 0..=n {
        j += Tracking.running(k as u64, sol.t[k], sol.q.array(k).unwrap(), sol.p.array(k).unwrap(), &[mu]);
    }
    j + Tracking.terminal(sol.t[n], sol.q.array(n).unwrap(), sol.p.array(n).unwrap(), &[mu])
}

/// dJ/d(q0, v0, μ) from the forward sensitivities of every node,
/// `Σ_k ∂ℓ_k/∂(q, p, t) S_k + ∂ℓ_k/∂μ`, with the node times' rows.
fn kepler_forward_gradient(scheme: &Scheme) -> ([f64; 5], Vec<Jacobian>, Solution) {
    let run = Problem::new(KEPLER, 0.0, KEPLER_Q0, KEPLER_V0)
        .solve_with_sensitivities(scheme, SIGMA, Plan::until(KEPLER_T_END).without_velocities())
        .unwrap();
    assert!(run.error.is_none() && run.solution.is_finished());
    let n = run.solution.len() - 1;
    let mut total = [0.0; 5];
    for (k, s) in run.jacobians.iter().enumerate() {
        let (t, q, p) = (run.solution.t[k], &run.solution.q[k], &run.solution.p[k]);
        // The gradient of the node's terms in (q, p, t, μ) by dual numbers.
        let term = |i: usize| {
            let mut x = [q[0], q[1], p[0], p[1], t, 1.0].map(Dual64::from_re);
            x[i].eps = 1.0;
            let (q, p, t, th) = ([x[0], x[1]], [x[2], x[3]], x[4], [x[5]]);
            let r = Tracking.running(k as u64, t, q, p, &th);
            if k == n { r + Tracking.terminal(t, q, p, &th) } else { r }.eps
        };
        let g: Vec<f64> = (0..6).map(term).collect();
        for (col, slot) in total.iter_mut().enumerate() {
            *slot += (0..4).map(|i| g[i] * s.get(i, col)).sum::<f64>() + g[4] * s.time[col];
            if col == 4 {
                *slot += g[5];
            }
        }
    }
    (total, run.jacobians, run.solution)
}

/// The adjoint of a time-transformed Kepler orbit (three orbits, e = 0.5,
/// the landing step on `t_end` included) against its forward
/// sensitivities (≤ 1e-12 relative), the value of a plain solve, and
/// central differences of plain solves (≤ 1e-7): `scheme` is the implicit
/// transformation or the explicit splitting, step `SIGMA` in `s`.
fn transformed_adjoint_agrees(scheme: Scheme) {
    let g = Problem::new(KEPLER, 0.0, KEPLER_Q0, KEPLER_V0)
        .gradient(&scheme, SIGMA, KEPLER_T_END, &Tracking, Checkpoints::Budget(16))
        .unwrap();
    assert_eq!(g.last.t, KEPLER_T_END);
    assert!(g.costates.len() <= 17, "{}", g.costates.len());
    let adjoint = [g.q0[0], g.q0[1], g.v0[0], g.v0[1], g.theta[0]];
    let (forward, _, solution) = kepler_forward_gradient(&scheme);
    assert_eq!(solution.step.last(), Some(&Some(g.last.step)));
    let vs_forward = relative(&adjoint, &forward);
    eprintln!("{} ({} steps): adjoint vs forward: {vs_forward:.1e} ({adjoint:?})", scheme.name(), g.last.step);
    assert!(vs_forward <= 1e-12, "{vs_forward:e}");

    let value = kepler_loss_of_run(&scheme, KEPLER_Q0, KEPLER_V0, 1.0);
    assert!((g.value - value).abs() <= 1e-13 * value.abs(), "{} vs {value}", g.value);

    // Central differences, step 1e-7·max(1, |x|), of the whole run: the
    // node times, the constant c and the landing step move with the inputs.
    // Three orbits amplify the third derivatives: at 1e-5 the truncation
    // error is 3.6e-5 relative, at 1e-6 3.5e-7 (it falls as the square of
    // the step, towards the adjoint), at 1e-7 it is below the round-off.
    let base = [KEPLER_Q0[0], KEPLER_Q0[1], KEPLER_V0[0], KEPLER_V0[1], 1.0];
    let fd: Vec<f64> = (0..5)
        .map(|i| {
            let step = 1e-7 * base[i].abs().max(1.0);
            let at = |s: f64| {
                let mut x = base;
                x[i] += s;
                kepler_loss_of_run(&scheme, [x[0], x[1]], [x[2], x[3]], x[4])
            };
            (at(step) - at(-step)) / (2.0 * step)
        })
        .collect();
    let vs_fd = relative(&adjoint, &fd);
    eprintln!("{}: adjoint vs central differences: {vs_fd:.1e}", scheme.name());
    assert!(vs_fd <= 1e-7, "{vs_fd:e}");
}

#[test]
fn time_transformed_adjoint_agrees_with_forward_sensitivities_and_finite_differences() {
    transformed_adjoint_agrees(transformed(Scheme::MIDPOINT));
    transformed_adjoint_agrees(transformed(Scheme::galerkin(2)));
}

/// The explicit splitting's Kepler orbit (logarithmic, drift–kick–drift,
/// Kahan–Li 8; `c = 0`, the landing step on `t_end`), checked as the
/// implicit transformation is.
#[test]
fn splitting_adjoint_agrees_with_forward_sensitivities_and_finite_differences() {
    transformed_adjoint_agrees(Scheme::splitting(TimeFunction::Logarithmic, Some(Composition::KAHAN_LI8)));
}

/// `L̃ = t' L(t, q, q'/t') + (t' − g)²/(2cg)` of Kepler with the curvature
/// monitor, written out here from its formula (`κ = √5 μ/r³`), on any scalar.
fn kepler_extended<D: Scalar>(mu: D, c: D, x: [D; 3], w: [D; 3]) -> D {
    let r2 = x[0] * x[0] + x[1] * x[1];
    let g = (mu * mu * 5.0 / (r2 * r2 * r2) + FLOOR * FLOOR).powf(-0.25);
    let tp = w[2];
    let v = [w[0] / tp, w[1] / tp];
    let l = (v[0] * v[0] + v[1] * v[1]) * 0.5 + mu / r2.sqrt();
    let d = tp - g;
    tp * l + d * d / (g * c * 2.0)
}

/// One midpoint step of size `σ` in `s` on dual numbers, written out here:
/// Newton on `p̃_k + D₁A(x_k, x_{k+1}) = 0`, `A = σ L̃((x_k + x_{k+1})/2, (x_{k+1} − x_k)/σ)`,
/// then `p̃_{k+1} = D₂A`.
fn dual_extended_midpoint_step(mu: Dual64, c: Dual64, x: [Dual64; 3], p: [Dual64; 3]) -> ([Dual64; 3], [Dual64; 3]) {
    let action = |a: [Dual<Dual64>; 3], b: [Dual<Dual64>; 3]| {
        let mid = core::array::from_fn(|i| (a[i] + b[i]) * 0.5);
        let w = core::array::from_fn(|i| (b[i] - a[i]) / SIGMA);
        kepler_extended(Dual::from_re(mu), Dual::from_re(c), mid, w) * SIGMA
    };
    let gradient = |x0: [Dual64; 3], x1: [Dual64; 3], first: bool| -> [Dual64; 3] {
        core::array::from_fn(|i| {
            let (mut a, mut b) = (x0.map(Dual::from_re), x1.map(Dual::from_re));
            if first {
                a[i].eps = Dual64::from_re(1.0)
            } else {
                b[i].eps = Dual64::from_re(1.0)
            }
            action(a, b).eps
        })
    };
    // ∂²A/∂x_k∂x_{k+1} at the real parts, by hyper-duals.
    let newton_matrix = |x0: [f64; 3], x1: [f64; 3]| -> [[f64; 3]; 3] {
        core::array::from_fn(|i| {
            core::array::from_fn(|j| {
                let (mut a, mut b) = (x0.map(HyperDual64::from_re), x1.map(HyperDual64::from_re));
                a[i].eps1 = 1.0;
                b[j].eps2 = 1.0;
                let mid = core::array::from_fn(|k| (a[k] + b[k]) * 0.5);
                let w = core::array::from_fn(|k| (b[k] - a[k]) / SIGMA);
                (kepler_extended(HyperDual64::from_re(mu.re), HyperDual64::from_re(c.re), mid, w) * SIGMA).eps1eps2
            })
        })
    };
    // Started from an explicit step: `x' = (g p, g)` (unit mass), so that
    // `t' > 0` from the first iterate.
    let r2 = x[0] * x[0] + x[1] * x[1];
    let g = (mu * mu * 5.0 / (r2 * r2 * r2) + FLOOR * FLOOR).powf(-0.25);
    let mut x1 = [x[0] + g * p[0] * SIGMA, x[1] + g * p[1] * SIGMA, x[2] + g * SIGMA];
    for _ in 0..50 {
        let r = gradient(x, x1, true);
        let r: [Dual64; 3] = core::array::from_fn(|i| p[i] + r[i]);
        let dx = solve3(newton_matrix(x.map(|y| y.re), x1.map(|y| y.re)), r);
        for i in 0..3 {
            x1[i] -= dx[i];
        }
        let scale = 1.0 + x1.iter().fold(0.0f64, |m, y| m.max(y.eps.abs()));
        if dx.iter().all(|d| d.re.abs() < 1e-16 && d.eps.abs() < 1e-16 * scale) {
            break;
        }
    }
    (x1, gradient(x, x1, false))
}

/// `m⁻¹ r` by Gaussian elimination with partial pivoting.
fn solve3(mut m: [[f64; 3]; 3], mut r: [Dual64; 3]) -> [Dual64; 3] {
    for col in 0..3 {
        let pivot = (col..3).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs())).unwrap();
        m.swap(col, pivot);
        r.swap(col, pivot);
        for row in col + 1..3 {
            let f = m[row][col] / m[col][col];
            for k in col..3 {
                m[row][k] -= f * m[col][k];
            }
            r[row] -= r[col] * f;
        }
    }
    let mut out = [Dual64::from_re(0.0); 3];
    for row in (0..3).rev() {
        let mut acc = r[row];
        for k in row + 1..3 {
            acc -= out[k] * m[row][k];
        }
        out[row] = acc / m[row][row];
    }
    out
}

#[test]
fn dual_numbers_through_a_short_time_transformed_run_agree_with_the_sensitivities() {
    // 60 steps in `s` of a run that lands later: the rows of node 60 are
    // those of fixed steps, with the node time's own row.
    let steps = 60;
    let scheme = transformed(Scheme::MIDPOINT);
    let run = Problem::new(KEPLER, 0.0, KEPLER_Q0, KEPLER_V0)
        .solve_with_sensitivities(&scheme, SIGMA, Plan::until(KEPLER_T_END).without_velocities())
        .unwrap();
    assert_eq!(run.solution.step[steps], Some(steps as u64));
    let row = &run.jacobians[steps];
    let (mut worst, mut state_gap) = (0.0f64, 0.0f64);
    for col in 0..5 {
        let mut z = [KEPLER_Q0[0], KEPLER_Q0[1], KEPLER_V0[0], KEPLER_V0[1], 1.0].map(Dual64::from_re);
        z[col].eps = 1.0;
        let (q0, v0, mu) = ([z[0], z[1]], [z[2], z[3]], z[4]);
        // The driver's c = 1/(|p·v| + |L| + |E|) and g_0, then x_0 = (q_0, 0),
        // x'_0 = (g_0 v_0, g_0), p̃_0 = ∂L̃/∂x'.
        let (v2, r) = (v0[0] * v0[0] + v0[1] * v0[1], (q0[0] * q0[0] + q0[1] * q0[1]).sqrt());
        let (l, e) = (v2 * 0.5 + mu / r, v2 * 0.5 - mu / r);
        let abs = |x: Dual64| if x.re < 0.0 { -x } else { x };
        let c = (abs(v2) + abs(l) + abs(e)).recip();
        let g0 = (mu * mu * 5.0 / r.powi(6) + FLOOR * FLOOR).powf(-0.25);
        let mut x = [q0[0], q0[1], Dual64::from_re(0.0)];
        let w = [g0 * v0[0], g0 * v0[1], g0];
        let mut p: [Dual64; 3] = core::array::from_fn(|i| {
            let mut wd = w.map(Dual::from_re);
            wd[i].eps = Dual64::from_re(1.0);
            kepler_extended(Dual::from_re(mu), Dual::from_re(c), x.map(Dual::from_re), wd).eps
        });
        for _ in 0..steps {
            (x, p) = dual_extended_midpoint_step(mu, c, x, p);
        }
        let (sq, sp, st) = (&run.solution.q[steps], &run.solution.p[steps], run.solution.t[steps]);
        state_gap =
            state_gap.max(relative(&[x[0].re, x[1].re, x[2].re, p[0].re, p[1].re], &[sq[0], sq[1], st, sp[0], sp[1]]));
        let dual = [x[0].eps, x[1].eps, x[2].eps, p[0].eps, p[1].eps];
        assert!(dual.iter().chain(&[x[0].re, x[1].re, x[2].re]).all(|v| v.is_finite()), "{dual:?}");
        let sens = [row.get(0, col), row.get(1, col), row.time[col], row.get(2, col), row.get(3, col)];
        worst = worst.max(relative(&sens, &dual));
    }
    eprintln!("time-transformed sensitivities vs dual run: {worst:.1e} (states {state_gap:.1e})");
    assert!(state_gap <= 1e-12, "{state_gap:e}");
    assert!(worst <= 1e-11, "{worst:e}");
}

/// `m q̈ + c q̇ + k q = 0` with the stiffness and the damping as parameters.
#[derive(Clone, Debug)]
pub struct Damped {
    m: f64,
    k: f64,
    c: f64,
}

#[lagrangian(parameters(k, c))]
impl Damped {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }

    fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.c * v[0] * v[0]
    }
}

/// `q_n² + p_n²`.
struct Final;
impl Loss<1, 2> for Final {
    fn terminal<D: Scalar>(&self, _t: D, q: [D; 1], p: [D; 1], _theta: &[D; 2]) -> D {
        q[0] * q[0] + p[0] * p[0]
    }
}

#[test]
fn dissipation_is_differentiated_for_every_rule() {
    let system = Damped { m: 1.0, k: 4.0, c: 0.5 };
    let loss_at = |scheme: &Scheme, theta: [f64; 2]| {
        let sol = Problem::new(system.with_parameters(theta), 0.0, [1.0], [0.0])
            .solve(scheme, 0.01, Plan::until(3.0))
            .unwrap();
        let n = sol.len() - 1;
        sol.q[n][0].powi(2) + sol.p[n][0].powi(2)
    };
    let lobatto =
        Scheme::Galerkin { degree: 2, nodes: NodeFamily::GaussLobatto, quadrature: GalerkinQuadrature::GaussLobatto };
    for scheme in [
        Scheme::MIDPOINT,
        Scheme::TRAPEZOID,
        Scheme::alpha_beta(0.3).unwrap(),
        Scheme::galerkin(4),
        lobatto,
        Scheme::composition(Composition::YOSHIDA4, OnePoint::Trapezoid),
        // The damping enters in `s` as the extended force; the stiffness
        // also through the curvature monitor `g = (k² + 1)^{-1/4}`.
        Scheme::MIDPOINT.time_transformed(Curvature::new(1.0).unwrap()),
    ] {
        let g = Problem::new(system.clone(), 0.0, [1.0], [0.0])
            .gradient(&scheme, 0.01, 3.0, &Final, Checkpoints::Budget(17))
            .unwrap();
        let theta = system.parameters();
        let fd: Vec<f64> = (0..2)
            .map(|j| {
                let e = 1e-6 * theta[j];
                let (mut up, mut down) = (theta, theta);
                up[j] += e;
                down[j] -= e;
                (loss_at(&scheme, up) - loss_at(&scheme, down)) / (2.0 * e)
            })
            .collect();
        let gap = relative(&g.theta, &fd);
        eprintln!("{}: adjoint vs central differences {gap:.1e}", scheme.name());
        assert!(gap <= 1e-7, "{}: {gap:e}", scheme.name());
    }
}

/// A potential step, acknowledged: its steps are not differentiable.
#[derive(Clone, Debug)]
pub struct Step {
    k: f64,
}

#[lagrangian(discontinuous, parameters(k))]
impl Step {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - if q[0] > 0.0 { self.k } else { 0.0 }
    }
}

#[test]
fn bad_input_and_undefined_combinations_are_typed_errors() {
    let problem = Problem::new(SYSTEM, 0.0, Q0, V0);
    let plan = || Plan::until(0.1);
    let refused = |e: Error| match e {
        Error::Unsupported { what } => what,
        other => panic!("{other}"),
    };
    // Not differentiated: energy steps under an accuracy bound (whose
    // capped steps minimise the energy mismatch), refused by `supports`
    // with the combination named, for the one-point and Galerkin rules.
    let bounded =
        Policy::EnergyPreserving { h: 0.01, bounds: lagrangian::StepBounds::around(0.01).with_accuracy(1e-3) };
    for (scheme, policy, named) in
        [(Scheme::galerkin(3), bounded, "accuracy bound"), (Scheme::MIDPOINT, bounded, "accuracy bound")]
    {
        match problem.solve_with_sensitivities(&scheme, policy, plan()) {
            Err(SolveError::Step(e)) => assert!(refused(e).contains(named)),
            other => panic!("{other:?}"),
        }
        let e = problem.gradient(&scheme, policy, 0.1, &loss(), Checkpoints::Every(10)).unwrap_err();
        assert!(refused(e).contains(named));
        // The problem itself still solves with a one-point rule; a
        // Galerkin rule refuses the bound for a run too.
        match (&scheme, problem.solve(&scheme, policy, plan())) {
            (Scheme::OnePoint(_), Ok(solution)) => assert!(solution.is_finished()),
            (Scheme::Galerkin { .. }, Err(SolveError::Step(e))) => assert!(refused(e).contains(named)),
            (_, other) => panic!("{scheme:?}: {other:?}"),
        }
    }
    // The explicit time-transformed splitting (on Kepler, which it steps)
    // under a variable-step policy: refused with its name; its fixed steps
    // in `s` are differentiated, and the run itself still solves.
    let kepler = Problem::new(KEPLER, 0.0, KEPLER_Q0, KEPLER_V0);
    let splitting = Scheme::splitting(TimeFunction::Logarithmic, None);
    match kepler.solve_with_sensitivities(&splitting, Policy::energy_preserving(0.01), Plan::until(0.1)) {
        Err(SolveError::Step(e)) => assert!(refused(e).contains("splitting")),
        other => panic!("{other:?}"),
    }
    assert!(kepler.solve_with_sensitivities(&splitting, 0.01, Plan::until(0.1)).unwrap().error.is_none());
    assert!(kepler.solve(&splitting, 0.01, Plan::until(0.1)).unwrap().is_finished());

    let step = Problem::new(Step { k: 1.0 }, 0.0, [-0.5], [1.0]);
    let e = step.solve_with_sensitivities(&Scheme::MIDPOINT, 0.01, Plan::until(0.1)).unwrap_err();
    assert!(matches!(e, SolveError::Step(Error::Unsupported { what }) if what.contains("discontinuous")));

    // Rows between nodes have no sensitivities.
    let e = problem.solve_with_sensitivities(&Scheme::MIDPOINT, 0.01, plan().save_at(vec![0.055])).unwrap_err();
    assert!(matches!(e, SolveError::InvalidPlan { .. }), "{e}");

    // A checkpoint budget of zero.
    for none in [Checkpoints::Every(0), Checkpoints::Budget(0)] {
        let e = problem.gradient(&Scheme::MIDPOINT, 0.01, 0.1, &loss(), none).unwrap_err();
        assert!(matches!(e, Error::InvalidSetting { reason } if reason.contains("zero")), "{e}");
    }

    // A loss that is NaN from t = 0.05 on: the node where it first is.
    struct Broken;
    impl Loss<2, 3> for Broken {
        fn running<D: Scalar>(&self, _k: u64, t: D, q: [D; 2], _p: [D; 2], _theta: &[D; 3]) -> D {
            if t.re() < 0.05 - 1e-9 { q[0] } else { D::from(f64::NAN) }
        }
    }
    let e = problem.gradient(&Scheme::MIDPOINT, 0.01, 0.1, &Broken, Checkpoints::Every(3)).unwrap_err();
    match e {
        Error::NonFiniteLoss { state } => assert_eq!(state.step, 5),
        other => panic!("{other}"),
    }
    // A loss whose value is finite but whose gradient is not (√q at q = 0).
    struct Kink;
    impl Loss<2, 3> for Kink {
        fn terminal<D: Scalar>(&self, _t: D, q: [D; 2], _p: [D; 2], _theta: &[D; 3]) -> D {
            (q[0] - q[0].re()).sqrt()
        }
    }
    let e = problem.gradient(&Scheme::MIDPOINT, 0.01, 0.1, &Kink, Checkpoints::Every(3)).unwrap_err();
    assert!(matches!(&e, Error::NonFiniteLoss { state } if state.step == 10), "{e}");
}
