//! The tangent map of a constrained step: the derivative of the RATTLE
//! equations by the implicit function theorem.
//!
//! With `A11, A12, A22` the position blocks of the Hessian of the step
//! action ([`derivatives::position_hessian`]), `K(q, w) = Σ_i w_i ∇²g_i(q)`
//! the curvature of the constraints weighted by a multiplier, `H = ∂²L/∂v²`
//! and `B = ∂²L/∂v∂q` at the end node, and
//! `Z = ∂(G v + ∂g/∂t)/∂q` at fixed `v`, a variation `(δq_k, δp_k)` moves
//! the solution by
//!
//! ```text
//! A12 δq_{k+1} + G(q_k)ᵀ δλ = −δp_k − (A11 + K(q_k, λ_k)) δq_k,     G(q_{k+1}) δq_{k+1} = 0,
//! H δv − G(q_{k+1})ᵀ δμ = b − B δq_{k+1},                            G(q_{k+1}) δv = −Z δq_{k+1},
//! δp_{k+1} = b + G(q_{k+1})ᵀ δμ,      b = A12ᵀ δq_k + (A22 + K(q_{k+1}, μ_k)) δq_{k+1},
//! ```
//!
//! two saddle-point systems of the step's own form, solved column by column.
//! On tangent vectors of the constrained phase space
//! `{g = 0, G v(q, p) + ∂g/∂t = 0}` the map is symplectic; on the normal
//! directions it is the derivative of the projection the step equations
//! make onto that space, so the `2N × 2N` matrix as a whole is not.

use nalgebra::{SMatrix, SVector};

use super::linear::{Singular, solve_schur};
use super::{Constrained, jacobian};
use crate::derivatives::{self, Segment};
use crate::discrete::DiscreteLagrangian;
use crate::hyperdual::HyperDualArray;
use crate::mechanics::DiscreteMechanics;
use crate::symplectic::TangentMap;
use crate::system::Lagrangian;

type Hessian<const N: usize> = HyperDualArray<[f64; N], [f64; N]>;

/// `K(q, w) = Σ_i w_i ∇²g_i(t, q)` from one hyper-dual evaluation of the
/// constraints seeded on `q` twice.
fn curvature<S: Lagrangian<N> + ?Sized, const N: usize, const M: usize>(
    system: &S,
    t: f64,
    q: &[f64; N],
    w: &[f64; M],
) -> SMatrix<f64, N, N> {
    let mut qd = q.map(Hessian::<N>::from_re);
    for (i, x) in qd.iter_mut().enumerate() {
        x.eps1[i] = 1.0;
        x.eps2[i] = 1.0;
    }
    let mut g = [Hessian::<N>::from_re(0.0); M];
    system.constraints(Hessian::from_re(t), &qd, &mut g);
    SMatrix::from_fn(|j, l| (0..M).map(|i| w[i] * g[i].mixed(j, l)).sum())
}

/// `Z = ∂(G(t, q) v + ∂g/∂t(t, q))/∂q` at fixed `v`: the constraints on a
/// hyper-dual number whose first part moves along `(1, v)` in `(t, q)` and
/// whose second part is seeded on `q`.
fn hidden_slope<S: Lagrangian<N> + ?Sized, const N: usize, const M: usize>(
    system: &S,
    t: f64,
    q: &[f64; N],
    v: &[f64; N],
) -> SMatrix<f64, M, N> {
    type D<const N: usize> = HyperDualArray<[f64; 1], [f64; N]>;
    let mut qd = q.map(D::<N>::from_re);
    for (i, x) in qd.iter_mut().enumerate() {
        x.eps1[0] = v[i];
        x.eps2[i] = 1.0;
    }
    let mut td = D::<N>::from_re(t);
    if !S::CONSTRAINTS_AUTONOMOUS {
        td.eps1[0] = 1.0;
    }
    let mut g = [D::<N>::from_re(0.0); M];
    system.constraints(td, &qd, &mut g);
    SMatrix::from_fn(|i, j| g[i].mixed(0, j))
}

/// `∂²L/∂v∂q` (row `i` for `∂L/∂v_i`, column `j` for `q_j`): how the
/// momentum of a fixed velocity changes with the position.
fn momentum_slope<S: Lagrangian<N> + ?Sized, const N: usize>(
    system: &S,
    t: f64,
    q: &[f64; N],
    v: &[f64; N],
) -> SMatrix<f64, N, N> {
    let (mut qd, mut vd) = (q.map(Hessian::<N>::from_re), v.map(Hessian::<N>::from_re));
    for i in 0..N {
        vd[i].eps1[i] = 1.0;
        qd[i].eps2[i] = 1.0;
    }
    let l = system.lagrangian(Hessian::from_re(t), qd, vd);
    SMatrix::from_fn(|i, j| l.mixed(i, j))
}

/// The tangent map of the constrained step over `seg` (see the
/// [module documentation](self)), given the step's multiplier `lambda`,
/// the momentum `p1` and the velocity `v1` at its end node; `None` where a
/// block of the linearised equations is singular or a value not finite.
pub(super) fn tangent_map<S, D, const N: usize, const M: usize>(
    system: &S,
    method: &Constrained<D, M>,
    seg: &Segment<N>,
    lambda: &[f64; M],
    p1: &[f64; N],
    v1: &[f64; N],
) -> Option<TangentMap<N>>
where
    S: Lagrangian<N> + ?Sized,
    D: DiscreteLagrangian,
{
    let rule = &method.rule;
    let (t0, t1, q0, q1) = (seg.t0, seg.t1(), seg.q0, seg.q1());
    let (_, g0) = jacobian::<S, N, M>(system, t0, &q0)?;
    let (_, g1) = jacobian::<S, N, M>(system, t1, &q1)?;
    let (g0t, g1t) = (g0.transpose(), g1.transpose());
    // μ_k from p_{k+1} = D₂A + G(q_{k+1})ᵀμ_k, by least squares on the rows of G.
    let end = SVector::from(derivatives::end_momentum(system, rule, seg));
    let mu: [f64; M] = ((g1 * g1t).try_inverse()? * (g1 * (SVector::from(*p1) - end))).into();
    let (a11, a12, a22) = derivatives::position_hessian(system, rule, seg);
    let start = a11 + curvature::<S, N, M>(system, t0, &q0, lambda);
    let end_block = a22 + curvature::<S, N, M>(system, t1, &q1, &mu);
    let hessian = system.velocity_hessian(t1, q1, *v1);
    let slope = momentum_slope(system, t1, &q1, v1);
    let z = hidden_slope::<S, N, M>(system, t1, &q1, v1);

    let mut map = TangentMap {
        dq_dq: SMatrix::zeros(),
        dq_dp: SMatrix::zeros(),
        dp_dq: SMatrix::zeros(),
        dp_dp: SMatrix::zeros(),
    };
    let unsolved = |_: Singular| ();
    for column in 0..2 * N {
        let (mut dq0, mut dp0) = (SVector::<f64, N>::zeros(), SVector::<f64, N>::zeros());
        if column < N {
            dq0[column] = 1.0;
        } else {
            dp0[column - N] = 1.0;
        }
        let r1 = dp0 + start * dq0;
        let (dq1, _) = solve_schur(&a12, &g0t, &g1, &r1, &SVector::zeros(), 0.0).map_err(unsolved).ok()?;
        let b = a12.transpose() * dq0 + end_block * dq1;
        let r1 = -(b - slope * dq1);
        let (_, dmu) = solve_schur(&hessian, &(-g1t), &g1, &r1, &(z * dq1), 0.0).map_err(unsolved).ok()?;
        let dp1 = b + g1t * dmu;
        let (q_block, p_block): (&mut SMatrix<f64, N, N>, &mut SMatrix<f64, N, N>) =
            if column < N { (&mut map.dq_dq, &mut map.dp_dq) } else { (&mut map.dq_dp, &mut map.dp_dp) };
        q_block.set_column(column % N, &dq1);
        p_block.set_column(column % N, &dp1);
    }
    let finite = [map.dq_dq, map.dq_dp, map.dp_dq, map.dp_dp].iter().all(|m| m.iter().all(|x| x.is_finite()));
    finite.then_some(map)
}
