//! The linearisation of an energy-preserving Galerkin step for the
//! sensitivities and the adjoint.
//!
//! An energy-preserving Galerkin step of degree `s` (`galerkin/energy.rs`)
//! solves for the node increments `D_1 … D_s` and the step size `h`
//! together:
//!
//! ```text
//! p_k + R_0 = 0      R_m = 0  (0 < m < s)      E(q_k, D, h) − E_k = 0
//! q_{k+1} = q_k + D_s      t_{k+1} = t_k + h      p_{k+1} = R_s      E_{k+1} = E(q_k, D, h)
//! R_ρ = Σ_j b_j (h ℓ_ρ(c_j) L_q + ℓ_ρ'(c_j) L_v)      E = Σ_j b_j (v·L_v − L)
//! ```
//!
//! at the points `(q_k + Σ_m ℓ_m(c_j) D_m, Σ_m ℓ_m'(c_j) D_m / h)`. `E` is
//! `−∂A/∂h` at fixed nodes, so this is the discrete Euler–Lagrange equation
//! of the parametrised motion in the extended phase `(q, t, p, −E)`, as for
//! the one-point rules ([`energy`](super::energy)), but with `t` linear in
//! the step where `q` has degree `s`: the step is not a Galerkin step of
//! `t' L(t, q, q'/t')`, whose `t` would have interior nodes of its own.
//! Its linearisation is that of the bordered system the stepper solves,
//! by the implicit function theorem,
//!
//! ```text
//! [ G_D  G_h ] [dD]      [ G_q dq_k + E dp_k + G_θ dθ ]
//! [ E_D  E_h ] [dh]  = − [ E_q dq_k − dE_k + E_θ dθ    ]
//! ```
//!
//! (`G` the `s` block rows of the node equations), and
//! `dq_{k+1} = dq_k + dD_s`, `dt_{k+1} = dt_k + dh`,
//! `dp_{k+1} = dp_k + d(Σ_ρ R_ρ)` (the sum of the rows is `h Σ_j b_j L_q`,
//! of order `h` where each row is of order `1/h`: differentiated in this
//! form, the increment of `p` keeps its relative accuracy), and
//! `dE_{k+1} = dE_k`. The derivatives of the rows and of `E` in
//! `(q_k, t_k, D, h, θ)` come from nested dual numbers: exact, no
//! differences.
//!
//! The first step (of the given size) and a landing on a target have their
//! end time given: each solves the node equations alone at that size and
//! reads its energy off. The energy row is then `dh + dt_k = 0`, and
//! `dE_{k+1}` is the derivative of `E` at the solution; such a step does not
//! depend on `E_k`.

use nalgebra::{DMatrix, DVector};
use num_dual::{Dual, Dual64};

use super::Parametric;
use super::linearisation::{Piece, Rule};
use super::transformed::Linear;

/// The rows `R_0 … R_{s−1}`, their sum over `ρ = 0 … s` (formed as
/// `h Σ_j b_j L_q`), and `E` of the step `(t_k, q_k, D, h)` at parameters
/// `theta` (see the [module](self)), on dual numbers seeded in one of those
/// inputs; `rows` receives `sN` values, `sum` `N`.
#[allow(clippy::too_many_arguments)]
fn equations<S: Parametric<N, P>, const N: usize, const P: usize>(
    system: &S,
    rule: &Rule,
    theta: &[Dual64; P],
    (t0, q0): (Dual64, &[Dual64; N]),
    d: &[[Dual64; N]],
    h: Dual64,
    rows: &mut [Dual64],
    sum: &mut [Dual64; N],
) -> Dual64 {
    let s = rule.degree();
    rows.fill(Dual64::from(0.0));
    *sum = [Dual64::from(0.0); N];
    let mut energy = Dual64::from(0.0);
    let th: [Dual<Dual64>; P] = theta.map(Dual::from_re);
    for j in 0..rule.point_count() {
        let b = rule.weight(j);
        let t = Dual::from_re(t0 + h * rule.abscissa(j));
        let q: [Dual64; N] = core::array::from_fn(|i| {
            let mut x = q0[i];
            for m in 1..=s {
                x += d[m - 1][i] * rule.l(j, m);
            }
            x
        });
        let v: [Dual64; N] = core::array::from_fn(|i| {
            let mut x = Dual64::from(0.0);
            for m in 1..=s {
                x += d[m - 1][i] * rule.dl(j, m);
            }
            x / h
        });
        let (qi, vi) = (q.map(Dual::from_re), v.map(Dual::from_re));
        let (mut lq, mut lv) = ([Dual64::from(0.0); N], [Dual64::from(0.0); N]);
        let mut value = Dual64::from(0.0);
        for i in 0..N {
            let mut x = qi;
            x[i].eps = Dual64::from(1.0);
            let l = system.lagrangian_with(&th, t, x, vi);
            (lq[i], value) = (l.eps, l.re);
            let mut y = vi;
            y[i].eps = Dual64::from(1.0);
            lv[i] = system.lagrangian_with(&th, t, qi, y).eps;
        }
        let w = h * b;
        let mut e = -value;
        for i in 0..N {
            e += v[i] * lv[i];
            sum[i] += w * lq[i];
        }
        energy += e * b;
        for rho in 0..s {
            let (r, rd) = (w * rule.l(j, rho), w * rule.dl(j, rho) / h);
            for i in 0..N {
                rows[rho * N + i] += r * lq[i] + rd * lv[i];
            }
        }
    }
    energy
}

/// The Jacobians `Φ_x`, `Φ_θ` in the extended phase `(q, t, p, −E)` of the
/// energy-preserving Galerkin step `piece` of `rule` of `system`; with
/// `pinned`, of a step whose end time was given (see the [module](self)).
/// `Φ_c` is zero: no constant of the run enters. `None` where the bordered
/// block is singular or a derivative is not finite.
pub(crate) fn linearise<S, const N: usize, const P: usize>(
    system: &S,
    rule: &Rule,
    piece: &Piece<N>,
    pinned: bool,
) -> Option<Linear>
where
    S: Parametric<N, P>,
{
    let s = rule.degree();
    let (m, nd) = (N + 1, s * N);
    // Unknowns (D, h); inputs (q_k, t_k) and θ. One evaluation per column.
    let (unknowns, inputs) = (nd + 1, N + 1 + P);
    let theta = system.parameters();
    // Rows: the node equations (sN), the energy, the sum of the rows (N).
    let mut a = DMatrix::<f64>::zeros(nd + 1 + N, unknowns + inputs);
    let (mut rows, mut sum) = (vec![Dual64::from(0.0); nd], [Dual64::from(0.0); N]);
    let mut d = vec![[Dual64::from(0.0); N]; s];
    for col in 0..unknowns + inputs {
        let seed = |x: f64, at: usize| if at == col { Dual64::new(x, 1.0) } else { Dual64::from(x) };
        for (mm, row) in d.iter_mut().enumerate() {
            *row = core::array::from_fn(|i| seed(piece.d[mm][i], mm * N + i));
        }
        let h = seed(piece.h, nd);
        let q0: [Dual64; N] = core::array::from_fn(|i| seed(piece.q0[i], unknowns + i));
        let t0 = seed(piece.t0, unknowns + N);
        let th: [Dual64; P] = core::array::from_fn(|j| seed(theta[j], unknowns + N + 1 + j));
        let energy = equations(system, rule, &th, (t0, &q0), &d, h, &mut rows, &mut sum);
        for (r, x) in rows.iter().enumerate() {
            a[(r, col)] = x.eps;
        }
        a[(nd, col)] = energy.eps;
        for i in 0..N {
            a[(nd + 1 + i, col)] = sum[i].eps;
        }
    }
    // The bordered block and the right-hand side [inputs (q_k, t_k, p_k, −E_k) | θ].
    let mut block = a.view((0, 0), (nd + 1, unknowns)).into_owned();
    let mut rhs = DMatrix::<f64>::zeros(nd + 1, 2 * m + P);
    for r in 0..nd + 1 {
        for c in 0..=N {
            rhs[(r, c)] = a[(r, unknowns + c)];
        }
        for j in 0..P {
            rhs[(r, 2 * m + j)] = a[(r, unknowns + N + 1 + j)];
        }
    }
    for i in 0..N {
        rhs[(i, m + i)] = 1.0;
    }
    if pinned {
        // h + t_k = t_{k+1}, given.
        block.row_mut(nd).fill(0.0);
        block[(nd, nd)] = 1.0;
        rhs.row_mut(nd).fill(0.0);
        rhs[(nd, N)] = 1.0;
    } else {
        // E − E_k = E + (−E_k).
        rhs[(nd, 2 * m - 1)] = 1.0;
    }
    let y = -block.lu().solve(&rhs)?;
    // The direct derivatives of a row of `a` in the inputs, as columns of `[x | θ]`.
    let direct = |r: usize| {
        let mut out = DVector::<f64>::zeros(2 * m + P);
        for c in 0..=N {
            out[c] = a[(r, unknowns + c)];
        }
        for j in 0..P {
            out[2 * m + j] = a[(r, unknowns + N + 1 + j)];
        }
        out
    };
    let through = |r: usize| -> DVector<f64> {
        let mut out = direct(r);
        for u in 0..unknowns {
            out.axpy(a[(r, u)], &y.row(u).transpose(), 1.0);
        }
        out
    };
    let mut phi = DMatrix::<f64>::zeros(2 * m, 2 * m + P);
    for i in 0..N {
        phi.row_mut(i).copy_from(&y.row((s - 1) * N + i));
        phi[(i, i)] += 1.0;
        phi.row_mut(m + i).copy_from(&through(nd + 1 + i).transpose());
        phi[(m + i, m + i)] += 1.0;
    }
    phi.row_mut(N).copy_from(&y.row(nd));
    phi[(N, N)] += 1.0;
    if pinned {
        // −E_{k+1} = −E at the solution.
        phi.row_mut(2 * m - 1).copy_from(&(-through(nd)).transpose());
    } else {
        phi[(2 * m - 1, 2 * m - 1)] = 1.0;
    }
    let linear = Linear {
        x: phi.columns(0, 2 * m).into_owned(),
        theta: phi.columns(2 * m, P).into_owned(),
        c: DVector::zeros(2 * m),
    };
    linear.finite()
}

#[cfg(test)]
mod tests {
    use crate::problem::{Policy, Problem, Scheme};
    use crate::sensitivity::fixtures::{central, chained, loss_of, node_rows, relative};
    use crate::sensitivity::{Checkpoints, Loss, Parametric};
    use crate::solution::{Plan, Solution};
    use crate::system::{Lagrangian, Scalar};

    /// A pendulum with its mass, length and gravity as parameters.
    #[derive(Clone)]
    struct Pendulum {
        theta: [f64; 3],
    }

    impl Lagrangian<1> for Pendulum {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 1] = [false];
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
            self.lagrangian_with(&self.theta.map(D::from), t, q, v)
        }
    }

    impl Parametric<1, 3> for Pendulum {
        const NAMES: [&'static str; 3] = ["m", "l", "g"];
        fn parameters(&self) -> [f64; 3] {
            self.theta
        }
        fn with_parameters(&self, theta: [f64; 3]) -> Self {
            Self { theta }
        }
        fn lagrangian_with<D: Scalar>(&self, theta: &[D; 3], _t: D, q: [D; 1], v: [D; 1]) -> D {
            let [m, l, g] = *theta;
            m * l * l * v[0] * v[0] * 0.5 + m * g * l * q[0].cos()
        }
    }

    /// Positions and times at every node, and the final momentum: every
    /// node time enters, so the derivatives of the step sizes do.
    struct Fit;
    impl Loss<1, 3> for Fit {
        fn running<D: Scalar>(&self, _k: u64, t: D, q: [D; 1], _p: [D; 1], _theta: &[D; 3]) -> D {
            (q[0] * t.cos() + t * 0.1) * 1e-2
        }
        fn terminal<D: Scalar>(&self, t: D, q: [D; 1], p: [D; 1], theta: &[D; 3]) -> D {
            q[0] * q[0] + p[0] * theta[1] + t
        }
    }

    /// `(q0, v0, m, l, g)`.
    const BASE: [f64; 5] = [0.5, 0.3, 0.7, 1.3, 9.81];
    fn problem(x: [f64; 5]) -> Problem<Pendulum, crate::dim::Dim<1>> {
        Problem::new(Pendulum { theta: [x[2], x[3], x[4]] }, 0.0, [x[0]], [x[1]])
    }

    fn run(scheme: &Scheme, x: [f64; 5], hh: f64, t_end: f64) -> Solution {
        problem(x)
            .solve(scheme, Policy::energy_preserving(hh), Plan::until(t_end).without_velocities())
            .unwrap()
            .into_result()
            .unwrap()
    }

    /// The adjoint against the forward sensitivities, both against central
    /// differences of whole runs, and the node times against theirs.
    fn check(scheme: &Scheme, hh: f64, t_end: f64) -> (f64, f64, f64, f64) {
        check_from(BASE, scheme, hh, t_end)
    }

    /// [`check`] from the inputs `base` = `(q0, v0, m, l, g)`.
    fn check_from(base: [f64; 5], scheme: &Scheme, hh: f64, t_end: f64) -> (f64, f64, f64, f64) {
        let sens =
            problem(base).solve_with_sensitivities(scheme, Policy::energy_preserving(hh), Plan::until(t_end)).unwrap();
        assert!(sens.error.is_none(), "{:?}", sens.error);
        let sol = &sens.solution;
        let n = sol.len() - 1;
        assert!(n >= 30, "{n} steps: {:?}", sol.error);
        let rows: Vec<[[f64; 5]; 3]> = node_rows(&sens.jacobians);
        let forward = chained(&Fit, sol, &[base[2], base[3], base[4]], &rows);
        let g =
            problem(base).gradient(scheme, Policy::energy_preserving(hh), t_end, &Fit, Checkpoints::Budget(8)).unwrap();
        assert_eq!(g.last.step as usize, n);
        let value = loss_of(&Fit, sol, &[base[2], base[3], base[4]]);
        assert!((g.value - value).abs() <= 1e-13 * value.abs(), "{} vs {value}", g.value);
        let adjoint = [g.q0[0], g.v0[0], g.theta[0], g.theta[1], g.theta[2]];
        let vs_forward = relative(&adjoint, &forward);
        let fd = central(base, n, |x| run(scheme, x, hh, t_end), |s, x| loss_of(&Fit, s, &[x[2], x[3], x[4]]));
        let vs_fd = relative(&forward, &fd);
        // The node before the landing: every step size up to it came from
        // the energy equation. The landed node is t_end.
        let k = n - 1;
        let dt: [f64; 5] = core::array::from_fn(|c| sens.jacobians[k].time[c]);
        let fd_t = central(base, n, |x| run(scheme, x, hh, t_end), |s, _| s.t[k]);
        let vs_fd_t = relative(&dt, &fd_t);
        let landed = sens.jacobians[n].time.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let landed = landed / dt.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        eprintln!(
            "energy-preserving {}, pendulum (m, l, g), {n} steps: J = {value}\n  adjoint {adjoint:?}\n  forward \
             {forward:?}\n  differences {fd:?}\n  adjoint vs forward {vs_forward:.1e}, forward vs differences \
             {vs_fd:.1e}\n  ∂t_{k} {dt:?} vs differences {fd_t:?}: {vs_fd_t:.1e}; |∂t_{n}| / |∂t_{k}| = {landed:.1e}",
            scheme.name()
        );
        (vs_forward, vs_fd, vs_fd_t, landed)
    }

    /// About 50 steps for `s = 2` and `s = 3`. The energy equation of a
    /// method of order `2s` fixes `h` through a slope of order `h^{2s−1}`,
    /// the conditioning of each step's linearisation (entries of order
    /// `1/g'` that cancel in the derivatives of a run), so the bounds are
    /// asserted at the steps where that round-off is below them, and the
    /// smaller steps are printed: adjoint vs forward, measured, `s = 2`
    /// 1.3e-9 at `h = 0.1`, 3.5e-12 at 0.2, 8.3e-14 at 0.3; `s = 3` 5.2e-9
    /// at 0.3, 2.8e-12 at 0.6, 4.7e-13 at 0.8. The round-off of `h` itself
    /// (about `64 ε |E| / |g'|`) is what the central differences see.
    #[test]
    fn galerkin_energy_steps_adjoint_agrees_with_forward_and_differences() {
        let cases = [
            (Scheme::galerkin(2), 0.1, false),
            (Scheme::galerkin(2), 0.2, false),
            (Scheme::galerkin(2), 0.3, true),
            (Scheme::galerkin(3), 0.3, false),
            (Scheme::galerkin(3), 0.6, false),
            (Scheme::galerkin(3), 0.8, true),
        ];
        for (scheme, h, asserted) in cases {
            let s = scheme.name();
            let (vs_forward, vs_fd, vs_fd_t, landed) = check(&scheme, h, 50.0 * h + 0.05);
            if !asserted {
                continue;
            }
            assert!(vs_forward <= 1e-12, "{s}: {vs_forward:e}");
            assert!(vs_fd <= 1e-7, "{s}: {vs_fd:e}");
            assert!(vs_fd_t <= 1e-7, "{s}: {vs_fd_t:e}");
            assert!(landed <= 1e-12, "{s}: {landed:e}");
        }
    }

    /// Degree 4 with Gauss–Legendre and with Gauss–Lobatto quadrature run
    /// the same linearisation as degrees 2 and 3. At `h = 0.6` (50 steps)
    /// the energy equation's slope, of order `h^{2s−1} = h⁷`, leaves each
    /// step's linearisation conditioned so that the adjoint and the forward
    /// sensitivities agree to about 2e-11 (measured 1.1e-11 and 2.3e-11),
    /// and the round-off of each `h` (about `64 ε |E| / |g'|`) reaches the
    /// central differences of the node times (3.3e-6 and 2.5e-7 measured);
    /// the loss's gradient, a sum over the run, agrees with its differences
    /// to 2e-8. Smaller steps make the conditioning worse, larger ones lose
    /// the root of the energy equation within the run (at `h ≥ 0.7` for
    /// Gauss–Legendre; Gauss–Lobatto degrees 2 and 3 lose it within a few
    /// steps at every step tried from 0.005 to 0.4 on this pendulum).
    #[test]
    fn degree_4_and_gauss_lobatto_quadrature_agree_with_forward_and_differences() {
        use crate::NodeFamily;
        use crate::problem::GalerkinQuadrature;
        let lobatto = Scheme::Galerkin {
            degree: 4,
            nodes: NodeFamily::GaussLobatto,
            quadrature: GalerkinQuadrature::GaussLobatto,
        };
        for scheme in [Scheme::galerkin(4), lobatto] {
            let s = scheme.name();
            let h = 0.6;
            if let Scheme::Galerkin { quadrature, .. } = &scheme {
                eprintln!("{s}, {quadrature:?} quadrature:");
            }
            let (vs_forward, vs_fd, vs_fd_t, landed) = check(&scheme, h, 50.0 * h + 0.05);
            assert!(vs_forward <= 1e-10, "{s}: {vs_forward:e}");
            assert!(vs_fd <= 1e-7, "{s}: {vs_fd:e}");
            assert!(vs_fd_t <= 1e-5, "{s}: {vs_fd_t:e}");
            assert!(landed <= 1e-12, "{s}: {landed:e}");
        }
    }
}
