//! The linearisation of an energy-preserving or energy-balance step of a
//! one-point rule for the sensitivities and the adjoint.
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
//! have derivatives.
//!
//! An energy-balance step of a forced system (`forcing.rs`) is the same
//! extended step with the extended force `(t' F, −F·q')` of the
//! parametrised motion: the rule's discrete forces of it are
//! `(F_k^∓, −F_k^∓·v̂_k)`, `v̂_k = (q_{k+1} − q_k)/h`, so its time rows are
//! the energy equation with the discrete work, `−Ẽ_k + ∂A/∂t_k − F_k^−·v̂_k
//! = 0` and `−Ẽ_{k+1} = ∂A/∂t_{k+1} − F_k^+·v̂_k`, where `Ẽ_k = E_k +
//! F_{k−1}^+·v̂_{k−1}` is the energy plus the end work of the step behind,
//! the right side of the stepper's energy equation. The work, and with it
//! the step size, is differentiated in the state, the node time (a
//! time-dependent force) and the parameters the forces and the dissipation
//! depend on, by the same dense Jacobians.
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
    use crate::sensitivity::fixtures::{
        DRIVE, DampedOscillator, ForcedPendulum, Pendulum, central, chained, loss_of, node_rows, relative,
    };
    use crate::sensitivity::forward::Tangent;
    use crate::sensitivity::linearisation::InitialMomentum;
    use crate::sensitivity::{Checkpoints, Loss, Sensitivities};
    use crate::solution::{Plan, Solution, SolveError};

    /// Positions and times at every node, and the final momentum: every
    /// node time enters, so the derivatives of the step sizes do.
    struct Fit;
    impl<const P: usize> Loss<1, P> for Fit {
        fn running<D: Scalar>(&self, _k: u64, t: D, q: [D; 1], _p: [D; 1], _theta: &[D; P]) -> D {
            (q[0] * t.cos() + t * 0.1) * 1e-2
        }
        fn terminal<D: Scalar>(&self, t: D, q: [D; 1], p: [D; 1], theta: &[D; P]) -> D {
            q[0] * q[0] + p[0] * theta[0] + t
        }
    }

    /// An energy run of a one-coordinate system from `t = 0`: the system at
    /// parameters `θ`, the inputs `[q0, v0, θ…]` (`D = 2 + P`), the scheme,
    /// the policy and the end time.
    struct Run<S, const D: usize, const P: usize> {
        system: fn([f64; P]) -> S,
        base: [f64; D],
        scheme: Scheme,
        policy: Policy,
        t_end: f64,
    }

    /// How the derivatives of [`Fit`] through one [`Run`] agree.
    struct Agreement<const D: usize> {
        sens: Sensitivities<1>,
        /// The gradient by central differences over whole runs.
        differences: [f64; D],
        /// The loss the adjoint returns against the loss of the run.
        value: f64,
        adjoint_vs_forward: f64,
        forward_vs_differences: f64,
        /// The derivatives of the time of the node before the landing,
        /// every step size before it from the energy equation.
        time_vs_differences: f64,
        /// `|∂t_n| / |∂t_{n−1}|`: the landed node is `t_end`.
        landed: f64,
    }

    impl<const D: usize> Agreement<D> {
        /// The agreements every energy run must reach: the adjoint and the
        /// forward sensitivities differentiate the same equations (round-off),
        /// central differences with `ε = 1e-5` carry an error of about 1e-9.
        fn check(&self) {
            assert!(self.value <= 1e-13, "{:e}", self.value);
            assert!(self.adjoint_vs_forward <= 1e-12, "{:e}", self.adjoint_vs_forward);
            assert!(self.forward_vs_differences <= 1e-7, "{:e}", self.forward_vs_differences);
            assert!(self.time_vs_differences <= 1e-7, "{:e}", self.time_vs_differences);
            assert!(self.landed <= 1e-12, "{:e}", self.landed);
        }
    }

    impl<S: Parametric<1, P>, const D: usize, const P: usize> Run<S, D, P> {
        fn theta(x: &[f64; D]) -> [f64; P] {
            core::array::from_fn(|i| x[2 + i])
        }

        fn problem(&self, x: [f64; D]) -> Problem<S, crate::dim::Dim<1>> {
            Problem::new((self.system)(Self::theta(&x)), 0.0, [x[0]], [x[1]])
        }

        fn solve(&self, x: [f64; D]) -> Solution {
            self.problem(x)
                .solve(&self.scheme, self.policy, Plan::until(self.t_end).without_velocities())
                .unwrap()
                .into_result()
                .unwrap()
        }

        fn sensitivities(&self) -> Sensitivities<1> {
            let sens = self
                .problem(self.base)
                .solve_with_sensitivities(&self.scheme, self.policy, Plan::until(self.t_end))
                .unwrap();
            assert!(sens.error.is_none(), "{:?}", sens.error);
            sens
        }

        /// The gradient of [`Fit`] by the adjoint, by the forward
        /// sensitivities and by central differences, and the derivatives of
        /// the node times; printed under `name`.
        fn agreement(&self, name: &str) -> Agreement<D> {
            let sens = self.sensitivities();
            let sol = &sens.solution;
            let n = sol.len() - 1;
            assert!(n >= 20, "{n} steps");
            let theta = Self::theta(&self.base);
            let rows: Vec<[[f64; D]; 3]> = node_rows(&sens.jacobians);
            let forward = chained(&Fit, sol, &theta, &rows);
            let g = self
                .problem(self.base)
                .gradient(&self.scheme, self.policy, self.t_end, &Fit, Checkpoints::Budget(16))
                .unwrap();
            assert_eq!(g.last.step as usize, n);
            let adjoint: [f64; D] = core::array::from_fn(|c| match c {
                0 => g.q0[0],
                1 => g.v0[0],
                c => g.theta[c - 2],
            });
            let value = loss_of(&Fit, sol, &theta);
            let run = |x| self.solve(x);
            let differences = central(self.base, n, run, |s, x| loss_of(&Fit, s, &Self::theta(&x)));
            let k = n - 1;
            let dt: [f64; D] = core::array::from_fn(|c| sens.jacobians[k].time[c]);
            let fd_t = central(self.base, n, run, |s, _| s.t[k]);
            let largest = |x: &[f64]| x.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let landed = largest(&sens.jacobians[n].time) / largest(&dt);
            let out = Agreement {
                differences,
                value: (g.value - value).abs() / value.abs(),
                adjoint_vs_forward: relative(&adjoint, &forward),
                forward_vs_differences: relative(&forward, &differences),
                time_vs_differences: relative(&dt, &fd_t),
                landed,
                sens,
            };
            eprintln!(
                "{name}, {n} steps: J = {value}\n  adjoint {adjoint:?}\n  forward {forward:?}\n  \
                 differences {differences:?}\n  adjoint vs forward {:.1e}, forward vs differences {:.1e}\n  \
                 ∂t_{k}: {dt:?} vs differences {fd_t:?}: {:.1e}; |∂t_{n}|/|∂t_{k}| = {:.1e} (t_end)",
                out.adjoint_vs_forward, out.forward_vs_differences, out.time_vs_differences, out.landed
            );
            out
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

    const BASE: [f64; 4] = [Q0, V0, THETA[0], THETA[1]];

    fn pendulum() -> Run<Pendulum, 4, 2> {
        Run {
            system: |theta| Pendulum { theta },
            base: BASE,
            scheme: Scheme::MIDPOINT,
            policy: Policy::energy_preserving(H),
            t_end: T_END,
        }
    }

    #[test]
    fn energy_steps_adjoint_agrees_with_forward_and_differences() {
        let a = pendulum().agreement("energy-preserving midpoint, pendulum");
        a.check();
        let sol = &a.sens.solution;
        let n = sol.len() - 1;

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
            let seg =
                Segment::between((sol.t[k], sol.q.array(k).unwrap()), (sol.t[k + 1], sol.q.array(k + 1).unwrap()));
            let j = StepJacobian::of_piece(&Pendulum { theta: THETA }, &rule, &THETA, &Piece::segment(&seg)).unwrap();
            tangent = tangent.step(&j);
            held[k + 1] = row(&tangent);
        }
        let vs_fd_held = relative(&chained(&Fit, sol, &THETA, &held), &a.differences);
        eprintln!("  with the step sizes held (h column dropped): vs differences {vs_fd_held:.1e}");
        assert!(vs_fd_held >= 1e-4, "{vs_fd_held:e}");
    }

    /// `L = ½ μ v² − V(q)` and a force `F(t, q, v)`, as the dual-number runs
    /// write the midpoint step out: `[μ, V, V', F]` at `(t, q, v)` and
    /// parameters `θ`.
    trait Mechanical<const P: usize> {
        fn parts<D: Scalar>(theta: &[D; P], t: D, q: D, v: D) -> [D; 4];
    }

    impl Mechanical<2> for Pendulum {
        fn parts<D: Scalar>(theta: &[D; 2], _t: D, q: D, _v: D) -> [D; 4] {
            let [l, g] = *theta;
            [l * l, -(g * l * q.cos()), g * l * q.sin(), D::from(0.0)]
        }
    }

    impl Mechanical<3> for DampedOscillator {
        fn parts<D: Scalar>(theta: &[D; 3], _t: D, q: D, v: D) -> [D; 4] {
            let [m, k, c] = *theta;
            [m, k * q * q * 0.5, k * q, -(c * v)]
        }
    }

    impl Mechanical<4> for ForcedPendulum {
        fn parts<D: Scalar>(theta: &[D; 4], t: D, q: D, v: D) -> [D; 4] {
            let [l, g, b, a] = *theta;
            [l * l, -(g * l * q.cos()), g * l * q.sin(), a * (t * DRIVE).cos() - b * v]
        }
    }

    /// The energy-balance midpoint step from `(t_k, q_k, p_k, Ẽ_k)` to
    /// `(q_{k+1}, t_k + h)`, written out here from `A = h L(q̄, v̂)` and
    /// `F_k^∓ = (h/2) F(t̄, q̄, v̂)`: the residuals
    /// `r_q = p_k + ∂A/∂q_k + F_k^−`, `r_t = ∂A/∂t_k − F_k^−·v̂ − Ẽ_k`, then
    /// `p_{k+1} = ∂A/∂q_{k+1} + F_k^+` and `Ẽ_{k+1} = −∂A/∂t_{k+1} + F_k^+·v̂`
    /// (`Ẽ = E + w^+`, the energy the next step's equation balances).
    fn midpoint<M: Mechanical<P>, D: Scalar, const P: usize>(
        theta: &[D; P],
        (t, q, p, e): (D, D, D, D),
        q1: D,
        h: D,
    ) -> [D; 4] {
        let v = (q1 - q) / h;
        let [mu, potential, slope, f] = M::parts(theta, t + h * 0.5, (q + q1) * 0.5, v);
        let (half, energy) = (h * 0.5, mu * v * v * 0.5 + potential);
        [
            p - half * slope - mu * v + half * f,
            energy - half * f * v - e,
            mu * v - half * slope + half * f,
            energy + half * f * v,
        ]
    }

    /// One step of [`midpoint`] on dual numbers, Newton on `(q_{k+1}, h)`
    /// (`h` given: on `q_{k+1}` alone) with the Jacobian of the values:
    /// `[q_{k+1}, p_{k+1}, Ẽ_{k+1}, h]`.
    fn dual_step<M: Mechanical<P>, const P: usize>(
        theta: &[Dual64; P],
        node: (Dual64, Dual64, Dual64, Dual64),
        h: Option<Dual64>,
        guess: f64,
    ) -> [Dual64; 4] {
        let (t, q, p, e) = node;
        let re = |x: Dual64| Dual64::from(x.re);
        let mu = M::parts(theta, t, q, Dual64::from(0.0))[0];
        let (mut q1, mut hh) = (q + p / mu * guess, h.unwrap_or(Dual64::from(guess)));
        for _ in 0..60 {
            let r = midpoint::<M, _, P>(theta, node, q1, hh);
            // ∂(r_q, r_t)/∂q_{k+1} and ∂(r_q, r_t)/∂h at the values.
            let column = |dq: f64, dh: f64| {
                let x = midpoint::<M, _, P>(
                    &theta.map(re),
                    (re(t), re(q), re(p), re(e)),
                    Dual64::new(q1.re, dq),
                    Dual64::new(hh.re, dh),
                );
                (x[0].eps, x[1].eps)
            };
            let ((a, c), (b, d)) = (column(1.0, 0.0), column(0.0, 1.0));
            let (dq1, dh) = match h {
                Some(_) => (r[0] / a, Dual64::from(0.0)),
                None => {
                    let det = a * d - b * c;
                    ((r[0] * d - r[1] * b) / det, (r[1] * a - r[0] * c) / det)
                }
            };
            q1 -= dq1;
            hh -= dh;
            if dq1.re.abs() + dh.re.abs() < 1e-17 && dq1.eps.abs() + dh.eps.abs() < 1e-15 {
                break;
            }
        }
        let x = midpoint::<M, _, P>(theta, node, q1, hh);
        [q1, x[2], x[3], hh]
    }

    /// The sensitivities of `(q, p, t)` at node `steps` of `run` (a midpoint
    /// run) against dual numbers pushed through [`dual_step`] from the
    /// inputs: `(worst relative gap, gap of the states)`.
    fn against_dual_run<S, const D: usize, const P: usize>(run: &Run<S, D, P>, steps: usize) -> (f64, f64)
    where
        S: Parametric<1, P> + Mechanical<P>,
    {
        assert_eq!(run.scheme, Scheme::MIDPOINT);
        let sens = run.sensitivities();
        let (row, sol) = (&sens.jacobians[steps], &sens.solution);
        let h0 = run.policy.step();
        let (mut worst, mut state_gap) = (0.0f64, 0.0f64);
        for col in 0..D {
            let mut z = run.base.map(Dual64::from);
            z[col].eps = 1.0;
            let theta: [Dual64; P] = core::array::from_fn(|i| z[2 + i]);
            let zero = Dual64::from(0.0);
            let mu = S::parts(&theta, zero, z[0], z[1])[0];
            let (mut q, mut p, mut t, mut e) = (z[0], mu * z[1], zero, zero);
            let mut h = h0;
            for k in 0..steps {
                // The first step has the given size (pinned in time).
                let fixed = (k == 0).then(|| Dual64::from(h0));
                let [q1, p1, e1, hk] = dual_step::<S, P>(&theta, (t, q, p, e), fixed, h);
                (q, p, e, t, h) = (q1, p1, e1, t + hk, hk.re);
            }
            state_gap = state_gap.max(relative(&[q.re, p.re, t.re], &[sol.q[steps][0], sol.p[steps][0], sol.t[steps]]));
            let dual = [q.eps, p.eps, t.eps];
            let sensitivities = [row.get(0, col), row.get(1, col), row.time[col]];
            worst = worst.max(relative(&sensitivities, &dual));
        }
        (worst, state_gap)
    }

    #[test]
    fn dual_numbers_through_a_short_energy_run_agree_with_the_sensitivities() {
        let steps = 20;
        let (worst, state_gap) = against_dual_run(&pendulum(), steps);
        eprintln!("energy-step sensitivities vs a dual run of {steps} steps: {worst:.1e} (states {state_gap:.1e})");
        assert!(state_gap <= 1e-12, "{state_gap:e}");
        assert!(worst <= 1e-11, "{worst:e}");
    }

    /// Where the energy equation has no root the step fails as in a plain
    /// run (a typed error, no fallback by default): the solution up to the
    /// last good node is kept, with the sensitivities of every row.
    #[test]
    fn a_step_without_an_energy_root_keeps_the_sensitivities_before_it() {
        /// The run ends in `NoEnergyStep` with the rows before it and
        /// their Jacobians.
        fn keeps_rows<S: Parametric<1, P>, const D: usize, const P: usize>(run: &Run<S, D, P>) {
            let sens = run.sensitivities();
            assert!(!sens.solution.is_finished());
            assert!(sens.solution.len() > 2);
            assert_eq!(sens.jacobians.len(), sens.solution.len());
            match sens.solution.error {
                Some(SolveError::Step(Error::NoEnergyStep { .. })) => {}
                ref other => panic!("{other:?}"),
            }
        }
        // The trapezoid rule on the pendulum from 1 rad and on the damped
        // oscillator: its energy equation loses its root
        // (docs/capabilities.md).
        keeps_rows(&Run { scheme: Scheme::TRAPEZOID, policy: Policy::energy_preserving(0.02), ..pendulum() });
        keeps_rows(&damped(Scheme::TRAPEZOID, DAMPED, 0.02, 8.0));
    }

    /// A damped oscillator (`m`, `k`, `c`) under energy-balance steps: the
    /// step size solves `E_{k+1} − E_k = W_k` with the work of the
    /// dissipative force, which depends on `c`.
    fn damped(scheme: Scheme, base: [f64; 5], h: f64, t_end: f64) -> Run<DampedOscillator, 5, 3> {
        Run { system: |theta| DampedOscillator { theta }, base, scheme, policy: Policy::energy_balance(h), t_end }
    }

    /// A damped pendulum under a periodic torque (`l`, `g`, `b`, `a`): the
    /// work of a time-dependent force.
    fn forced(scheme: Scheme, base: [f64; 6], h: f64, t_end: f64) -> Run<ForcedPendulum, 6, 4> {
        Run { system: |theta| ForcedPendulum { theta }, base, scheme, policy: Policy::energy_balance(h), t_end }
    }

    /// The damped oscillator and the forced pendulum from 1 rad at speed 0.3.
    const DAMPED: [f64; 5] = [1.0, 0.3, 1.2, 2.5, 0.15];
    const FORCED: [f64; 6] = [1.0, 0.3, 1.3, 9.81, 0.2, 0.8];

    #[test]
    fn energy_balance_steps_adjoint_agrees_with_forward_and_differences() {
        damped(Scheme::MIDPOINT, DAMPED, 0.05, 8.0).agreement("energy-balance midpoint, damped oscillator").check();
        forced(Scheme::MIDPOINT, FORCED, 0.05, 8.0).agreement("energy-balance midpoint, forced pendulum").check();
        // The α-β rules away from ½ lose the root of the energy equation on
        // these runs within a swing; α = 0.45 and 0.48 keep it to t = 8.
        let alpha_beta = |a| Scheme::OnePoint(OnePoint::AlphaBeta(crate::AlphaBeta::new(a).unwrap()));
        damped(alpha_beta(0.45), [0.1, 3.0, 1.2, 2.5, 0.15], 0.05, 8.0)
            .agreement("energy-balance α-β 0.45, damped oscillator")
            .check();
        forced(alpha_beta(0.48), FORCED, 0.05, 8.0).agreement("energy-balance α-β 0.48, forced pendulum").check();
        damped(Scheme::TRAPEZOID, [0.0, 1.0, 1.2, 2.5, 0.05], 0.02, 0.45)
            .agreement("energy-balance trapezoid, damped oscillator")
            .check();
    }

    /// The midpoint rule conserves the energy of a quadratic Lagrangian at
    /// any step, so on the damped oscillator only the `O(h³)` gap between
    /// the work the balance imposes and the work of the fixed-step balance
    /// fixes `h`: the step's linearisation has entries of order `1/h³` that
    /// cancel in a run, and the agreement with the dual run scales so
    /// (measured over 20 steps: 1.1e-11 at `h = 0.05`, 1.2e-12 at
    /// `h = 0.1`). The forced pendulum's energy equation has a slope of
    /// order `h` in `h`, as without forces.
    ///
    /// Through every energy step of a run (to the node before the landing)
    /// the round-off of the two computations adds up: measured 7.2e-12
    /// (oscillator, 61 steps; 2.8e-10 at `h = 0.05`, 124 steps) and 1.9e-11
    /// (pendulum, 129 steps).
    #[test]
    fn dual_numbers_through_an_energy_balance_run_agree_with_the_sensitivities() {
        /// 20 steps, then every energy step of the run.
        fn agree<S, const D: usize, const P: usize>(name: &str, run: &Run<S, D, P>)
        where
            S: Parametric<1, P> + Mechanical<P>,
        {
            let whole = run.sensitivities().solution.len() - 2;
            for (steps, bound) in [(20, 1e-11), (whole, 1e-10)] {
                let (worst, state_gap) = against_dual_run(run, steps);
                eprintln!(
                    "energy-balance sensitivities, {name}, vs a dual run of {steps} steps: {worst:.1e} (states \
                     {state_gap:.1e})"
                );
                assert!(state_gap <= 1e-12, "{state_gap:e}");
                assert!(worst <= bound, "{worst:e}");
            }
        }
        agree("damped oscillator, h = 0.1", &damped(Scheme::MIDPOINT, DAMPED, 0.1, 8.0));
        agree("forced pendulum, h = 0.05", &forced(Scheme::MIDPOINT, FORCED, 0.05, 8.0));
    }
}
