//! The linearisation of an energy-preserving step of a one-point rule for
//! the sensitivities and the adjoint.
//!
//! An energy-preserving step solves the discrete Euler–Lagrange equation
//! and the discrete energy equation together for `(q_{k+1}, t_{k+1})`
//! (`integrator/variable_step.rs`):
//!
//! ```text
//! p_k + ∂A/∂q_k = 0      −E_k + ∂A/∂t_k = 0      p_{k+1} = ∂A/∂q_{k+1}      −E_{k+1} = ∂A/∂t_{k+1}
//! ```
//!
//! with `A(x_k, x_{k+1})`, `x = (q, t)`. That is the fixed step, of size 1
//! in a new time `s`, of the same rule applied to the Lagrangian of the
//! parametrised motion `L̃(x, x') = t' L(t, q, q'/t')` (its midpoint action
//! is `(t_{k+1} − t_k) L(t̄, q̄, v̂)`, and likewise for the trapezoid and
//! α-β rules), whose momentum is `(p, −E)`. Its linearisation is
//! [`StepJacobian`] of `L̃` in the extended phase `(q, t, p, −E)`, as for
//! the time transformation ([`transformed`](super::transformed)): the step
//! size is differentiated through the energy equation, and the node times
//! have derivatives. A force enters as the extended force `(t' F, −F·q')`:
//! its time component is the work on the time variation, the energy
//! balance's `W_k`.
//!
//! Two kinds of steps of an energy-preserving run have their end time
//! given instead: the first (of the given size `h_0`: the energy `E_L` of
//! the initial data is the discrete energy of no step) and a landing on a
//! target. Each solves the positions alone, and the energy `E_{k+1}` is
//! read off it. Such a step is the extended step from the momentum
//! `−E_k = −∂A/∂t_k` that its end time makes consistent, so its
//! linearisation is the extended one with the column of `−E_k` eliminated
//! by the end time ([`Linear::pin_time`]): its time row vanishes, and it
//! does not depend on `E_k`.

use nalgebra::{DMatrix, DVector, RowDVector};
use num_dual::{Dual, Dual64};

use super::Parametric;
use super::linearisation::{MAX_DEGREE, Piece, Rule, StepJacobian, generalized_force, seeded};
use super::transformed::{Linear, Start};
use crate::derivatives::Segment;
use crate::system::{Lagrangian, Scalar};
use crate::time_transform::{extended_force, homogeneous, split};

/// `L̃(x, x') = t' L(t, q, q'/t')` of a system `S` (see the
/// [module](self)), with its parameters.
struct Parametrised<'a, S, const N: usize, const P: usize>(&'a S);

impl<S, const N: usize, const P: usize> Clone for Parametrised<'_, S, N, P> {
    fn clone(&self) -> Self {
        Self(self.0)
    }
}

impl<S: Parametric<N, P>, const N: usize, const M: usize, const P: usize> Lagrangian<M> for Parametrised<'_, S, N, P> {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; M] = [false; M];
    const DISCONTINUOUS: bool = S::DISCONTINUOUS;
    const HAS_FORCE: bool = S::HAS_FORCE || S::HAS_DISSIPATION;
    const ENERGY_STEPS: bool = false;

    fn lagrangian<D: Scalar>(&self, s: D, x: [D; M], w: [D; M]) -> D {
        self.lagrangian_with(&self.0.parameters().map(D::from), s, x, w)
    }

    fn force<D: Scalar>(&self, s: D, x: [D; M], w: [D; M]) -> [D; M] {
        self.force_with(&self.0.parameters().map(D::from), s, x, w)
    }
}

impl<S: Parametric<N, P>, const N: usize, const M: usize, const P: usize> Parametric<M, P>
    for Parametrised<'_, S, N, P>
{
    const NAMES: [&'static str; P] = S::NAMES;

    fn parameters(&self) -> [f64; P] {
        self.0.parameters()
    }

    /// Not used: the linearisation takes the parameters as arguments.
    fn with_parameters(&self, _theta: [f64; P]) -> Self {
        self.clone()
    }

    fn lagrangian_with<D: Scalar>(&self, theta: &[D; P], _s: D, x: [D; M], w: [D; M]) -> D {
        const { assert!(M == N + 1, "the parametrised motion has N + 1 coordinates (q, t)") };
        let (t, q) = split::<D, N, M>(&x);
        homogeneous(&w, |v| self.0.lagrangian_with(theta, t, q, v))
    }

    fn force_with<D: Scalar>(&self, theta: &[D; P], _s: D, x: [D; M], w: [D; M]) -> [D; M] {
        let (t, q) = split::<D, N, M>(&x);
        extended_force(&w, |v| generalized_force(self.0, theta, t, q, v))
    }
}

/// The Jacobians `Φ_x`, `Φ_θ` in the extended phase `(q, t, p, −E)` of the
/// energy-preserving step `seg` of the one-point rule `rule` of `system`;
/// with `pinned`, of a step whose end time was given (see the
/// [module](self)). `Φ_c` is zero: no constant of the run enters. `None`
/// where the bordered Newton block is singular or a derivative is not
/// finite.
pub(crate) fn linearise<S, const N: usize, const M: usize, const P: usize>(
    system: &S,
    rule: &Rule,
    seg: &Segment<N>,
    pinned: bool,
) -> Option<Linear>
where
    S: Parametric<N, P>,
{
    let mut q0 = [0.0; M];
    q0[..N].copy_from_slice(&seg.q0);
    q0[N] = seg.t0;
    let mut d = [[0.0; M]; MAX_DEGREE];
    d[0][..N].copy_from_slice(&seg.dq);
    d[0][N] = seg.h;
    let piece = Piece { t0: 0.0, h: 1.0, q0, d };
    let theta = system.parameters();
    let j = StepJacobian::<M, P>::of_piece(&Parametrised::<S, N, P>(system), rule, &theta, &piece)?;
    let mut linear = Linear::of(&j, DVector::zeros(2 * M));
    if pinned {
        // The end time fixes the momentum −E_k the step is consistent with.
        let a = linear.x.column(2 * M - 1).into_owned();
        linear.pin_time(N, &a);
    }
    linear.finite()
}

/// The derivatives of the first node `(q_0, t_0, p_0, −E_L)` of an
/// energy-preserving run from `(t0, q0, v0)` with respect to
/// `(q_0, v_0, θ)` (`None` where one is not finite). The first step is
/// pinned in time, so the row of `−E_L` does not reach the later nodes; it
/// is the derivative of the extended momentum all the same.
pub(crate) fn start<S, const N: usize, const M: usize, const P: usize>(
    system: &S,
    (t0, q0, v0): (f64, [f64; N], [f64; N]),
) -> Option<Start>
where
    S: Parametric<N, P>,
{
    let theta = system.parameters();
    let k = 2 * N + P;
    let mut tangent = DMatrix::<f64>::zeros(2 * M, k);
    for col in 0..k {
        let (q, v, th) = seeded(&q0, &v0, &theta, col);
        let t = Dual64::from(t0);
        if col < N {
            tangent[(col, col)] = 1.0;
        }
        let lifted: [Dual<Dual64>; P] = th.map(Dual::from_re);
        let (tl, ql) = (Dual::from_re(t), q.map(Dual::from_re));
        // −E = L − v·p with p = ∂L/∂v.
        let mut minus_energy = system.lagrangian_with(&th, t, q, v);
        for i in 0..N {
            let mut vl = v.map(Dual::from_re);
            vl[i].eps = Dual64::from(1.0);
            let p = system.lagrangian_with(&lifted, tl, ql, vl).eps;
            tangent[(M + i, col)] = p.eps;
            minus_energy -= p * v[i];
        }
        tangent[(2 * M - 1, col)] = minus_energy.eps;
    }
    tangent.iter().all(|v| v.is_finite()).then(|| Start { tangent, c: RowDVector::zeros(k) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;
    use crate::problem::{OnePoint, Policy, Problem, Scheme};
    use crate::sensitivity::fixtures::{Pendulum, central, chained, loss_of, relative};
    use crate::sensitivity::forward::Tangent;
    use crate::sensitivity::linearisation::InitialMomentum;
    use crate::sensitivity::{Checkpoints, Loss};
    use crate::solution::{Plan, Solution, SolveError};
    use num_dual::DualNum;

    /// Positions and times at every node, and the final momentum: every
    /// node time enters, so the derivatives of the step sizes do.
    struct Fit;
    impl Loss<1, 2> for Fit {
        fn running<D: Scalar>(&self, _k: u64, t: D, q: [D; 1], _p: [D; 1], _theta: &[D; 2]) -> D {
            (q[0] * t.cos() + t * 0.1) * 1e-2
        }
        fn terminal<D: Scalar>(&self, t: D, q: [D; 1], p: [D; 1], theta: &[D; 2]) -> D {
            q[0] * q[0] + p[0] * theta[0] + t
        }
    }

    const THETA: [f64; 2] = [1.3, 9.81];
    const Q0: f64 = 1.0;
    const V0: f64 = 0.3;
    /// The first step. The energy equation fixes `h` only weakly (its slope
    /// is `O(h)`), so a step's linearisation has entries of order
    /// `1/h²` that cancel in the derivatives of a run: at `h = 0.01` the
    /// adjoint and the forward sensitivities agree to 3e-11 (measured),
    /// at `h = 0.05` to 1e-13.
    const H: f64 = 0.05;
    /// 210 energy-preserving steps.
    const T_END: f64 = 10.2;

    fn problem(x: [f64; 4]) -> Problem<Pendulum, 1> {
        Problem::new(Pendulum { theta: [x[2], x[3]] }, 0.0, [x[0]], [x[1]])
    }

    const BASE: [f64; 4] = [Q0, V0, THETA[0], THETA[1]];

    fn run(x: [f64; 4]) -> Solution<1> {
        problem(x)
            .solve(&Scheme::MIDPOINT, Policy::energy_preserving(H), Plan::until(T_END).without_velocities())
            .unwrap()
            .into_result()
            .unwrap()
    }

    #[test]
    fn energy_steps_adjoint_agrees_with_forward_and_differences() {
        let sens = problem(BASE)
            .solve_with_sensitivities(&Scheme::MIDPOINT, Policy::energy_preserving(H), Plan::until(T_END))
            .unwrap();
        assert!(sens.error.is_none(), "{:?}", sens.error);
        let sol = &sens.solution;
        let n = sol.len() - 1;
        assert!(n >= 20, "{n} steps");
        let rows: Vec<[[f64; 4]; 3]> = sens
            .jacobians
            .iter()
            .map(|j| {
                [
                    core::array::from_fn(|c| j.time[c]),
                    core::array::from_fn(|c| j.get(0, c)),
                    core::array::from_fn(|c| j.get(1, c)),
                ]
            })
            .collect();
        let forward = chained(&Fit, sol, &THETA, &rows);
        let g = problem(BASE)
            .gradient(&Scheme::MIDPOINT, Policy::energy_preserving(H), T_END, &Fit, Checkpoints::Budget(16))
            .unwrap();
        assert_eq!(g.last.step as usize, n);
        let adjoint = [g.q0[0], g.v0[0], g.theta[0], g.theta[1]];
        let vs_forward = relative(&adjoint, &forward);
        let value = loss_of(&Fit, sol, &THETA);
        let fd = central(BASE, n, run, |s, x| loss_of(&Fit, s, &[x[2], x[3]]));
        let vs_fd = relative(&forward, &fd);

        // The node times move: t at the node before the landing, whose step
        // sizes all came from the energy equation; the landed node is t_end.
        let k = n - 1;
        let dt: [f64; 4] = core::array::from_fn(|c| sens.jacobians[k].time[c]);
        let fd_t = central(BASE, n, run, |s, _| s.t[k]);
        let vs_fd_t = relative(&dt, &fd_t);
        let landed = sens.jacobians[n].time.iter().fold(0.0f64, |m, x| m.max(x.abs()));

        // The same steps differentiated with their sizes held (the h column
        // dropped): the fixed-step linearisation of each step taken.
        let rule = Rule::one_point(&OnePoint::Midpoint);
        let p0 = InitialMomentum::at(&Pendulum { theta: THETA }, &THETA, (0.0, [Q0], [V0]));
        let mut tangent = Tangent::<1, 2>::initial(&p0);
        let mut held = vec![[[0.0; 4]; 3]; n + 1];
        let row = |t: &Tangent<1, 2>| {
            [
                [0.0; 4],
                [t.q_q0[(0, 0)], t.q_v0[(0, 0)], t.q_theta[(0, 0)], t.q_theta[(0, 1)]],
                [t.p_q0[(0, 0)], t.p_v0[(0, 0)], t.p_theta[(0, 0)], t.p_theta[(0, 1)]],
            ]
        };
        held[0] = row(&tangent);
        for k in 0..n {
            let seg = Segment::between((sol.t[k], sol.q[k]), (sol.t[k + 1], sol.q[k + 1]));
            let j = StepJacobian::of_piece(&Pendulum { theta: THETA }, &rule, &THETA, &Piece::segment(&seg)).unwrap();
            tangent = tangent.step(&j);
            held[k + 1] = row(&tangent);
        }
        let vs_fd_held = relative(&chained(&Fit, sol, &THETA, &held), &fd);

        eprintln!(
            "energy-preserving midpoint, pendulum, {n} steps: J = {value}\n  adjoint {adjoint:?}\n  forward {forward:?}\n  \
             differences {fd:?}\n  adjoint vs forward {vs_forward:.1e}, forward vs differences {vs_fd:.1e}\n  \
             ∂t_{k}: {dt:?} vs differences {fd_t:?}: {vs_fd_t:.1e}; |∂t_{n}| = {landed:.1e} (t_end)\n  \
             with the step sizes held (h column dropped): vs differences {vs_fd_held:.1e}"
        );
        assert!((g.value - value).abs() <= 1e-13 * value.abs(), "{} vs {value}", g.value);
        assert!(vs_forward <= 1e-12, "{vs_forward:e}");
        assert!(vs_fd <= 1e-7, "{vs_fd:e}");
        assert!(vs_fd_t <= 1e-7, "{vs_fd_t:e}");
        assert!(landed <= 1e-12 * dt.iter().fold(0.0f64, |m, x| m.max(x.abs())), "{landed:e}");
        assert!(vs_fd_held >= 1e-4, "{vs_fd_held:e}");
    }

    /// One energy-preserving midpoint step of the pendulum on dual numbers,
    /// written out here from `A = ½ l² Δq²/h + h g l cos q̄`: Newton on
    /// `p_k + ∂A/∂q_k = 0`, `∂A/∂t_k = E_k` for `(q_{k+1}, h)` (`h` given:
    /// on `q_{k+1}` alone), then `p_{k+1} = ∂A/∂q_{k+1}` and
    /// `E_{k+1} = −∂A/∂t_{k+1}`.
    fn dual_step(
        theta: [Dual64; 2],
        (q, p, e): (Dual64, Dual64, Dual64),
        h: Option<Dual64>,
        guess: f64,
    ) -> [Dual64; 5] {
        let [l, g] = theta;
        let (mut q1, mut hh) = (q + p / (l * l) * guess, h.unwrap_or(Dual64::from(guess)));
        for _ in 0..60 {
            let (dq, mid) = (q1 - q, (q + q1) * 0.5);
            let r_q = p - l * l * dq / hh - hh * 0.5 * g * l * mid.sin();
            let r_t = l * l * dq * dq / (hh * hh) * 0.5 - g * l * mid.cos() - e;
            let (a, b) = (
                -(l * l / hh + hh * 0.25 * g * l * mid.cos()).re,
                (l * l * dq / (hh * hh) - g * l * mid.sin() * 0.5).re,
            );
            let (c, d) =
                ((l * l * dq / (hh * hh) + g * l * mid.sin() * 0.5).re, (-(l * l) * dq * dq / (hh * hh * hh)).re);
            let (dq1, dh) = match h {
                Some(_) => (r_q / a, Dual64::from(0.0)),
                None => {
                    let det = a * d - b * c;
                    ((r_q * d - r_t * b) / det, (r_t * a - r_q * c) / det)
                }
            };
            q1 -= dq1;
            hh -= dh;
            if dq1.re.abs() + dh.re.abs() < 1e-17 && dq1.eps.abs() + dh.eps.abs() < 1e-15 {
                break;
            }
        }
        let (dq, mid) = (q1 - q, (q + q1) * 0.5);
        let p1 = l * l * dq / hh - hh * 0.5 * g * l * mid.sin();
        let e1 = l * l * dq * dq / (hh * hh) * 0.5 - g * l * mid.cos();
        [q1, p1, e1, hh, Dual64::from(0.0)]
    }

    #[test]
    fn dual_numbers_through_a_short_energy_run_agree_with_the_sensitivities() {
        let steps = 20;
        let sens = problem(BASE)
            .solve_with_sensitivities(&Scheme::MIDPOINT, Policy::energy_preserving(H), Plan::until(T_END))
            .unwrap();
        let (row, sol) = (&sens.jacobians[steps], &sens.solution);
        let (mut worst, mut state_gap) = (0.0f64, 0.0f64);
        for col in 0..4 {
            let mut z = BASE.map(Dual64::from);
            z[col].eps = 1.0;
            let theta = [z[2], z[3]];
            let (mut q, mut p, mut t) = (z[0], theta[0] * theta[0] * z[1], Dual64::from(0.0));
            let mut e = Dual64::from(0.0);
            let mut h = H;
            for k in 0..steps {
                // The first step has the given size (pinned in time).
                let fixed = (k == 0).then(|| Dual64::from(H));
                let [q1, p1, e1, hk, _] = dual_step(theta, (q, p, e), fixed, h);
                (q, p, e, t, h) = (q1, p1, e1, t + hk, hk.re);
            }
            state_gap = state_gap.max(relative(&[q.re, p.re, t.re], &[sol.q[steps][0], sol.p[steps][0], sol.t[steps]]));
            let dual = [q.eps, p.eps, t.eps];
            let sensitivities = [row.get(0, col), row.get(1, col), row.time[col]];
            worst = worst.max(relative(&sensitivities, &dual));
        }
        eprintln!("energy-step sensitivities vs a dual run of {steps} steps: {worst:.1e} (states {state_gap:.1e})");
        assert!(state_gap <= 1e-12, "{state_gap:e}");
        assert!(worst <= 1e-11, "{worst:e}");
    }

    /// Where the energy equation has no root the step fails as in a plain
    /// run (a typed error, no fallback by default): the solution up to the
    /// last good node is kept, with the sensitivities of every row.
    #[test]
    fn a_step_without_an_energy_root_keeps_the_sensitivities_before_it() {
        // The trapezoid rule on the pendulum from 1 rad: its energy equation
        // loses its root (docs/capabilities.md).
        let sens = problem(BASE)
            .solve_with_sensitivities(&Scheme::TRAPEZOID, Policy::energy_preserving(0.02), Plan::until(T_END))
            .unwrap();
        assert!(sens.error.is_none(), "{:?}", sens.error);
        assert!(!sens.solution.is_finished());
        assert!(sens.solution.len() > 2);
        assert_eq!(sens.jacobians.len(), sens.solution.len());
        match sens.solution.error {
            Some(SolveError::Step(Error::NoEnergyStep { .. })) => {}
            ref other => panic!("{other:?}"),
        }
    }
}
