//! The linearisation of a fixed step of a one-point rule with respect to
//! both nodes and the parameters, and of the initial Legendre transform.
//!
//! A one-point rule (midpoint, trapezoid, α-β) is the Galerkin rule of
//! degree 1 with two quadrature points `c_1, c_2` of weight ½
//! ([`DiscreteLagrangian::galerkin_points`]):
//!
//! ```text
//! A   = (h/2) Σ_j L(t_k + c_j h, q_k + c_j Δq, Δq/h)
//! F⁻  = (h/2) Σ_j (1 − c_j) F_j        F⁺ = (h/2) Σ_j c_j F_j        F = Q − ∂R/∂v
//! ```
//!
//! which is how each rule's `action` and `forces` are written (a unit test
//! compares them). The DEL functions `a = D₁A + F⁻` and `b = D₂A + F⁺` are
//! evaluated on nested dual numbers: the inner [`Dual`] takes the gradient
//! of `A` one coordinate at a time, the outer one seeds one column of the
//! Jacobian (a coordinate of `q_k`, of `q_{k+1}`, or a parameter) — exact
//! derivatives, no differences.

use nalgebra::SMatrix;
use num_dual::{Dual, Dual64};

use super::Parametric;
use crate::derivatives::Segment;
use crate::discrete::DiscreteLagrangian;
use crate::problem::OnePoint;
use crate::symplectic::TangentMap;
use crate::system::Scalar;

/// The two quadrature points of a one-point rule on `[t_k, t_{k+1}]`, each
/// of weight ½.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rule {
    points: [f64; 2],
}

impl Rule {
    /// The points of `rule` (every one-point rule has them).
    pub fn of(rule: &OnePoint) -> Self {
        let points = match rule {
            OnePoint::Midpoint => crate::Midpoint.galerkin_points(),
            OnePoint::Trapezoid => crate::Trapezoid.galerkin_points(),
            OnePoint::AlphaBeta(m) => m.galerkin_points(),
        };
        // The three rules define their points; the midpoint's is the fallback
        // a future rule without them would never reach (`supports` names the
        // rules this module takes).
        Self { points: points.map_or([0.5, 0.5], |(c, _)| c) }
    }

    /// The step action `A` at parameters `theta`.
    pub fn action<S, D, const N: usize, const P: usize>(
        &self,
        system: &S,
        theta: &[D; P],
        (t0, h): (f64, f64),
        q0: &[D; N],
        dq: &[D; N],
    ) -> D
    where
        S: Parametric<N, P>,
        D: Scalar,
    {
        let inv_h = h.recip();
        let v: [D; N] = core::array::from_fn(|i| dq[i] * inv_h);
        let mut sum = D::zero();
        for c in self.points {
            let q = core::array::from_fn(|i| q0[i] + dq[i] * c);
            sum += system.lagrangian_with(theta, D::from(t0 + c * h), q, v);
        }
        sum * (h * 0.5)
    }

    /// The discrete forces `(F⁻, F⁺)` at parameters `theta`.
    pub fn forces<S, D, const N: usize, const P: usize>(
        &self,
        system: &S,
        theta: &[D; P],
        (t0, h): (f64, f64),
        q0: &[D; N],
        dq: &[D; N],
    ) -> ([D; N], [D; N])
    where
        S: Parametric<N, P>,
        D: Scalar,
    {
        let (mut minus, mut plus) = ([D::zero(); N], [D::zero(); N]);
        if !(S::HAS_FORCE || S::HAS_DISSIPATION) {
            return (minus, plus);
        }
        let inv_h = h.recip();
        let v: [D; N] = core::array::from_fn(|i| dq[i] * inv_h);
        for c in self.points {
            let q = core::array::from_fn(|i| q0[i] + dq[i] * c);
            let f = generalized_force(system, theta, D::from(t0 + c * h), q, v);
            for i in 0..N {
                minus[i] += f[i] * (h * 0.5 * (1.0 - c));
                plus[i] += f[i] * (h * 0.5 * c);
            }
        }
        (minus, plus)
    }

    /// `(a, b) = (D₁A + F⁻, D₂A + F⁺)` at `(q_k, q_{k+1} = q_k + Δq)`: the
    /// DEL residual is `p_k + a` and the next momentum `b`.
    pub fn del<S, D, const N: usize, const P: usize>(
        &self,
        system: &S,
        theta: &[D; P],
        step: (f64, f64),
        q0: &[D; N],
        dq: &[D; N],
    ) -> ([D; N], [D; N])
    where
        S: Parametric<N, P>,
        D: Scalar,
    {
        let lift = |x: &[D; N]| -> [Dual<D>; N] { core::array::from_fn(|i| Dual::from_re(x[i])) };
        let theta_l: [Dual<D>; P] = core::array::from_fn(|j| Dual::from_re(theta[j]));
        let (mut a, mut b) = ([D::zero(); N], [D::zero(); N]);
        for i in 0..N {
            // q_k[i] moves with q_{k+1} fixed: the increment moves back.
            let (mut x0, mut d) = (lift(q0), lift(dq));
            x0[i].eps = D::one();
            d[i].eps = -D::one();
            a[i] = self.action(system, &theta_l, step, &x0, &d).eps;
            let mut d = lift(dq);
            d[i].eps = D::one();
            b[i] = self.action(system, &theta_l, step, &lift(q0), &d).eps;
        }
        let (minus, plus) = self.forces(system, theta, step, q0, dq);
        for i in 0..N {
            a[i] += minus[i];
            b[i] += plus[i];
        }
        (a, b)
    }
}

/// `Q − ∂R/∂v` at parameters `theta`.
fn generalized_force<S, D, const N: usize, const P: usize>(
    system: &S,
    theta: &[D; P],
    t: D,
    q: [D; N],
    v: [D; N],
) -> [D; N]
where
    S: Parametric<N, P>,
    D: Scalar,
{
    let mut f = if S::HAS_FORCE { system.force_with(theta, t, q, v) } else { [D::zero(); N] };
    if S::HAS_DISSIPATION {
        let theta: [Dual<D>; P] = core::array::from_fn(|j| Dual::from_re(theta[j]));
        let q = q.map(Dual::from_re);
        for i in 0..N {
            let mut vd = v.map(Dual::from_re);
            vd[i].eps = D::one();
            f[i] -= system.dissipation_with(&theta, q, vd).eps;
        }
    }
    f
}

/// The Jacobians of one step `x_{k+1} = Φ(x_k, θ)`, `x = (q, p)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepJacobian<const N: usize, const P: usize> {
    /// `Φ_x` by blocks.
    pub state: TangentMap<N>,
    /// `∂q_{k+1}/∂θ`.
    pub dq_dtheta: SMatrix<f64, N, P>,
    /// `∂p_{k+1}/∂θ`.
    pub dp_dtheta: SMatrix<f64, N, P>,
}

impl<const N: usize, const P: usize> StepJacobian<N, P> {
    /// The Jacobians of the step over `seg` at parameters `theta`; `None`
    /// where `∂a/∂q_{k+1}` (the Newton matrix) is singular or a derivative
    /// is not finite.
    pub fn at<S: Parametric<N, P>>(system: &S, rule: &Rule, theta: &[f64; P], seg: &Segment<N>) -> Option<Self> {
        let step = (seg.t0, seg.h);
        let constant = |x: &[f64; N]| -> [Dual64; N] { x.map(Dual64::from_re) };
        let theta_c: [Dual64; P] = theta.map(Dual64::from_re);
        let mut a_q0 = SMatrix::<f64, N, N>::zeros();
        let mut a_q1 = SMatrix::<f64, N, N>::zeros();
        let mut b_q0 = SMatrix::<f64, N, N>::zeros();
        let mut b_q1 = SMatrix::<f64, N, N>::zeros();
        let mut a_th = SMatrix::<f64, N, P>::zeros();
        let mut b_th = SMatrix::<f64, N, P>::zeros();
        for j in 0..N {
            let (mut q0, mut dq) = (constant(&seg.q0), constant(&seg.dq));
            q0[j].eps = 1.0;
            dq[j].eps = -1.0;
            let (a, b) = rule.del(system, &theta_c, step, &q0, &dq);
            for i in 0..N {
                a_q0[(i, j)] = a[i].eps;
                b_q0[(i, j)] = b[i].eps;
            }
            let mut dq = constant(&seg.dq);
            dq[j].eps = 1.0;
            let (a, b) = rule.del(system, &theta_c, step, &constant(&seg.q0), &dq);
            for i in 0..N {
                a_q1[(i, j)] = a[i].eps;
                b_q1[(i, j)] = b[i].eps;
            }
        }
        for j in 0..P {
            let mut th = theta_c;
            th[j].eps = 1.0;
            let (a, b) = rule.del(system, &th, step, &constant(&seg.q0), &constant(&seg.dq));
            for i in 0..N {
                a_th[(i, j)] = a[i].eps;
                b_th[(i, j)] = b[i].eps;
            }
        }
        let all_finite = [a_q0, a_q1, b_q0, b_q1].iter().all(|m| m.iter().all(|x| x.is_finite()))
            && a_th.iter().chain(b_th.iter()).all(|x| x.is_finite());
        if !all_finite {
            return None;
        }
        // p_k + a(q_k, q_{k+1}) = 0 solved for q_{k+1}; p_{k+1} = b.
        let inv = a_q1.try_inverse()?;
        let dq_dq = -inv * a_q0;
        let dq_dp = -inv;
        let dq_dtheta = -inv * a_th;
        let state = TangentMap { dq_dq, dq_dp, dp_dq: b_q0 + b_q1 * dq_dq, dp_dp: b_q1 * dq_dp };
        Some(Self { state, dq_dtheta, dp_dtheta: b_th + b_q1 * dq_dtheta })
    }
}

/// The derivatives of the initial momentum `p_0 = ∂L/∂v(t_0, q_0, v_0; θ)`
/// with respect to `q_0`, `v_0` and `θ`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InitialMomentum<const N: usize, const P: usize> {
    /// `∂p_0/∂q_0 = L_vq`.
    pub dq: SMatrix<f64, N, N>,
    /// `∂p_0/∂v_0 = L_vv`.
    pub dv: SMatrix<f64, N, N>,
    /// `∂p_0/∂θ = L_vθ`.
    pub dtheta: SMatrix<f64, N, P>,
}

impl<const N: usize, const P: usize> InitialMomentum<N, P> {
    /// At `(t0, q0, v0)` and parameters `theta`.
    pub fn at<S: Parametric<N, P>>(system: &S, theta: &[f64; P], (t0, q0, v0): (f64, [f64; N], [f64; N])) -> Self {
        let momentum = |theta: &[Dual64; P], q: [Dual64; N], v: [Dual64; N]| -> [Dual64; N] {
            let th: [Dual<Dual64>; P] = theta.map(Dual::from_re);
            let (t, q) = (Dual::from_re(Dual64::from(t0)), q.map(Dual::from_re));
            core::array::from_fn(|i| {
                let mut vd = v.map(Dual::from_re);
                vd[i].eps = Dual64::from_re(1.0);
                system.lagrangian_with(&th, t, q, vd).eps
            })
        };
        let (q, v, th) = (q0.map(Dual64::from_re), v0.map(Dual64::from_re), theta.map(Dual64::from_re));
        let mut out = Self { dq: SMatrix::zeros(), dv: SMatrix::zeros(), dtheta: SMatrix::zeros() };
        for j in 0..N {
            let mut x = q;
            x[j].eps = 1.0;
            let p = momentum(&th, x, v);
            let mut y = v;
            y[j].eps = 1.0;
            let r = momentum(&th, q, y);
            for i in 0..N {
                out.dq[(i, j)] = p[i].eps;
                out.dv[(i, j)] = r[i].eps;
            }
        }
        for j in 0..P {
            let mut x = th;
            x[j].eps = 1.0;
            let p = momentum(&x, q, v);
            for i in 0..N {
                out.dtheta[(i, j)] = p[i].eps;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discrete::{AlphaBeta, Midpoint, Trapezoid};
    use crate::system::Lagrangian;

    /// A damped, driven pendulum with its length, gravity and damping as
    /// parameters.
    #[derive(Clone)]
    struct Driven {
        theta: [f64; 3],
    }

    impl Lagrangian<1> for Driven {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 1] = [false];
        const HAS_FORCE: bool = true;
        const HAS_DISSIPATION: bool = true;
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
            self.lagrangian_with(&self.theta.map(D::from), t, q, v)
        }
        fn dissipation<D: Scalar>(&self, q: [D; 1], v: [D; 1]) -> D {
            self.dissipation_with(&self.theta.map(D::from), q, v)
        }
        fn force<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> [D; 1] {
            self.force_with(&self.theta.map(D::from), t, q, v)
        }
    }

    impl Parametric<1, 3> for Driven {
        const NAMES: [&'static str; 3] = ["l", "g", "c"];
        fn parameters(&self) -> [f64; 3] {
            self.theta
        }
        fn with_parameters(&self, theta: [f64; 3]) -> Self {
            Self { theta }
        }
        fn lagrangian_with<D: Scalar>(&self, theta: &[D; 3], _t: D, q: [D; 1], v: [D; 1]) -> D {
            let [l, g, _] = *theta;
            l * l * v[0] * v[0] * 0.5 + g * l * q[0].cos()
        }
        fn dissipation_with<D: Scalar>(&self, theta: &[D; 3], _q: [D; 1], v: [D; 1]) -> D {
            theta[2] * v[0] * v[0] * 0.5
        }
        fn force_with<D: Scalar>(&self, _theta: &[D; 3], t: D, q: [D; 1], _v: [D; 1]) -> [D; 1] {
            [t.sin() * 0.3 + q[0] * 0.1]
        }
    }

    const SYSTEM: Driven = Driven { theta: [1.3, 9.81, 0.4] };

    fn segment() -> Segment<1> {
        Segment { t0: 0.7, h: 0.05, q0: [0.4], dq: [0.03] }
    }

    /// Each rule's own `action` and `forces` against the two-point form
    /// the linearisation differentiates.
    fn same_as<M: DiscreteLagrangian>(method: M, rule: OnePoint) {
        let (seg, theta, r) = (segment(), SYSTEM.parameters(), Rule::of(&rule));
        let own = method.action(&SYSTEM, seg.t0, seg.h, seg.q0, seg.dq);
        let here = r.action(&SYSTEM, &theta, (seg.t0, seg.h), &seg.q0, &seg.dq);
        assert!((own - here).abs() <= 1e-15 * own.abs(), "{rule:?}: {own} vs {here}");
        let (m0, p0) = method.forces(&SYSTEM, seg.t0, seg.h, seg.q0, seg.dq);
        let (m1, p1) = r.forces(&SYSTEM, &theta, (seg.t0, seg.h), &seg.q0, &seg.dq);
        assert!((m0[0] - m1[0]).abs() <= 1e-15 && (p0[0] - p1[0]).abs() <= 1e-15, "{rule:?}");
    }

    #[test]
    fn the_two_point_form_is_each_rule() {
        same_as(Midpoint, OnePoint::Midpoint);
        same_as(Trapezoid, OnePoint::Trapezoid);
        let ab = AlphaBeta::new(0.3).unwrap();
        same_as(ab, OnePoint::AlphaBeta(ab));
    }

    #[test]
    fn the_step_jacobian_matches_central_differences_of_the_del_functions() {
        // Φ_θ from duals against differences of the step solved by Newton
        // at perturbed parameters (a contraction in q_{k+1} for small h).
        let (seg, rule) = (segment(), Rule::of(&OnePoint::Midpoint));
        let theta = SYSTEM.parameters();
        let p0 = {
            let (a, _) = rule.del(&SYSTEM, &theta, (seg.t0, seg.h), &seg.q0, &seg.dq);
            [-a[0]]
        };
        let solve = |theta: [f64; 3]| -> (f64, f64) {
            let mut dq = seg.dq;
            for _ in 0..100 {
                let (a, _) = rule.del(&SYSTEM, &theta, (seg.t0, seg.h), &seg.q0, &dq);
                let j = StepJacobian::at(&SYSTEM, &rule, &theta, &Segment { dq, ..seg }).unwrap();
                // a_q1 = −1/(∂q1/∂p0).
                dq[0] += (p0[0] + a[0]) * j.state.dq_dp[(0, 0)];
            }
            let (_, b) = rule.del(&SYSTEM, &theta, (seg.t0, seg.h), &seg.q0, &dq);
            (seg.q0[0] + dq[0], b[0])
        };
        let j = StepJacobian::at(&SYSTEM, &rule, &theta, &seg).unwrap();
        for k in 0..3 {
            let e = 1e-6 * theta[k];
            let (mut up, mut down) = (theta, theta);
            up[k] += e;
            down[k] -= e;
            let ((qu, pu), (qd, pd)) = (solve(up), solve(down));
            let (fq, fp) = ((qu - qd) / (2.0 * e), (pu - pd) / (2.0 * e));
            assert!((fq - j.dq_dtheta[(0, k)]).abs() <= 1e-7 * (1.0 + fq.abs()), "{k}: {fq} {}", j.dq_dtheta[(0, k)]);
            assert!((fp - j.dp_dtheta[(0, k)]).abs() <= 1e-7 * (1.0 + fp.abs()), "{k}: {fp} {}", j.dp_dtheta[(0, k)]);
        }
    }

    #[test]
    fn without_forces_the_state_block_is_the_tangent_map() {
        #[derive(Clone)]
        struct Free(Driven);
        impl Lagrangian<1> for Free {
            const AUTONOMOUS: bool = true;
            const CYCLIC: [bool; 1] = [false];
            fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
                self.0.lagrangian(t, q, v)
            }
        }
        impl Parametric<1, 3> for Free {
            const NAMES: [&'static str; 3] = Driven::NAMES;
            fn parameters(&self) -> [f64; 3] {
                self.0.theta
            }
            fn with_parameters(&self, theta: [f64; 3]) -> Self {
                Free(Driven { theta })
            }
            fn lagrangian_with<D: Scalar>(&self, theta: &[D; 3], t: D, q: [D; 1], v: [D; 1]) -> D {
                self.0.lagrangian_with(theta, t, q, v)
            }
        }
        let (seg, free) = (segment(), Free(SYSTEM));
        let j = StepJacobian::at(&free, &Rule::of(&OnePoint::Midpoint), &free.parameters(), &seg).unwrap();
        let m = crate::symplectic::tangent_map(&free, &Midpoint, &seg).unwrap();
        let gap = (j.state.matrix() - m.matrix()).amax();
        assert!(gap <= 1e-13 * m.matrix().amax(), "{gap:e}");
        assert!(j.state.symplecticity_defect() <= 1e-13, "{:e}", j.state.symplecticity_defect());
    }
}
