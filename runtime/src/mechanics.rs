//! Continuous and discrete mechanics of a system, as callable functions.
//!
//! [`DiscreteMechanics`] is implemented for every [`Lagrangian`], so a type
//! annotated with `#[lagrangian]` gets these methods for free: the momentum and
//! energy of `L`, the partials `D1..D4` of a discrete Lagrangian, the DEL
//! residual and its Jacobian, ready to be fed to a solver of the user's own.

use nalgebra::{SMatrix, SVector};

use crate::derivatives::{self, Segment, StepDerivatives};
use crate::discrete::DiscreteLagrangian;
use crate::hyperdual::{DualArray, HyperDualArray};
use crate::newton::{self, NewtonFailure, NewtonOptions};
use crate::system::Lagrangian;

/// The discrete Lagrangian `L_d = A/h` of a segment and its partials
/// `D1..D4` with respect to `t_k, q_k, t_{k+1}, q_{k+1}` (docs/theory.md §2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiscretePartials<const N: usize> {
    /// `L_d(t_k, q_k, t_{k+1}, q_{k+1})`.
    pub l_d: f64,
    /// `D1 L_d = ∂L_d/∂t_k`.
    pub d1: f64,
    /// `D2 L_d = ∂L_d/∂q_k`.
    pub d2: [f64; N],
    /// `D3 L_d = ∂L_d/∂t_{k+1}`.
    pub d3: f64,
    /// `D4 L_d = ∂L_d/∂q_{k+1}`.
    pub d4: [f64; N],
}

/// Why the velocity of a given momentum could not be found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegendreFailure {
    /// Newton iterations spent.
    pub iterations: usize,
    /// `‖∂L/∂v − p‖∞` at the last iterate (infinite if the Hessian was singular or a value not finite).
    pub residual_norm: f64,
}

/// Mechanics derived from a [`Lagrangian`]; implemented for every such system.
pub trait DiscreteMechanics<const N: usize>: Lagrangian<N> {
    /// `L(t, q, v)` in plain `f64`.
    fn lagrangian_value(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        self.lagrangian(t, q, v)
    }

    /// The momentum `p = ∂L/∂v(t, q, v)`: the system's generated gradient
    /// code where it has it ([`Lagrangian::HAS_GRADIENT_QV`]), else one
    /// evaluation on a [`DualArray`] seeded on all of `v`.
    fn momentum(&self, t: f64, q: [f64; N], v: [f64; N]) -> [f64; N] {
        if Self::HAS_GRADIENT_QV {
            // The macro's adjoint code: `O(ops)` instead of `N` lanes per operation.
            let (mut lq, mut lv) = ([0.0; N], [0.0; N]);
            self.gradient_qv(t, &q, &v, &mut lq, &mut lv);
            return lv;
        }
        if const { N > derivatives::DUAL_BLOCKS_ABOVE } {
            return momentum_by_lanes(self, t, q, v);
        }
        let mut vd = v.map(DualArray::<[f64; N]>::from_re);
        for (i, x) in vd.iter_mut().enumerate() {
            x.eps[i] = 1.0;
        }
        self.lagrangian(DualArray::from_re(t), q.map(DualArray::from_re), vd).eps
    }

    /// The energy `E_L = v·∂L/∂v − L`.
    fn energy(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let p = self.momentum(t, q, v);
        (0..N).map(|i| v[i] * p[i]).sum::<f64>() - self.lagrangian(t, q, v)
    }

    /// The Hessian `∂²L/∂v²`; the Legendre transform is regular where it is
    /// invertible. The generated gradient code on a [`DualArray`] with one
    /// lane per velocity where the system has it
    /// ([`Lagrangian::HAS_GRADIENT_QV`]), else one evaluation on a
    /// [`HyperDualArray`] seeded on `v` twice.
    fn velocity_hessian(&self, t: f64, q: [f64; N], v: [f64; N]) -> SMatrix<f64, N, N> {
        if Self::HAS_GRADIENT_QV {
            // Forward over reverse: the macro's adjoint code on duals with one
            // lane per velocity; row `i` of the Hessian is the lanes of
            // `∂L/∂v_i`. `N + 1` parts per operation instead of the
            // hyper-dual's `(N + 1)²` (the explicit path's start on an FPU
            // chain of 16 masses was mostly this Hessian).
            type D<const N: usize> = DualArray<[f64; N]>;
            let qd = q.map(D::<N>::from_re);
            let mut vd = v.map(D::<N>::from_re);
            for (i, x) in vd.iter_mut().enumerate() {
                x.eps[i] = 1.0;
            }
            let (mut lq, mut lv) = ([D::<N>::from_re(0.0); N], [D::<N>::from_re(0.0); N]);
            self.gradient_qv_scalar(D::from_re(t), &qd, &vd, &mut lq, &mut lv);
            return SMatrix::from_fn(|i, j| lv[i].eps[j]);
        }
        if const { N > derivatives::HYPER_BLOCKS_ABOVE } {
            return velocity_hessian_by_blocks(self, t, q, v);
        }
        type H<const N: usize> = HyperDualArray<[f64; N], [f64; N]>;
        let mut vd = v.map(H::<N>::from_re);
        for (i, x) in vd.iter_mut().enumerate() {
            x.eps1[i] = 1.0;
            x.eps2[i] = 1.0;
        }
        let l = self.lagrangian(H::from_re(t), q.map(H::from_re), vd);
        SMatrix::from_fn(|i, j| l.eps1eps2[i][j])
    }

    /// The velocity `v` with `∂L/∂v(t, q, v) = p` (inverse Legendre
    /// transform), by Newton's method from `guess`.
    fn velocity(&self, t: f64, q: [f64; N], p: [f64; N], guess: [f64; N]) -> Result<[f64; N], LegendreFailure> {
        let eval = |v: &SVector<f64, N>, _| {
            let v: [f64; N] = (*v).into();
            let m = self.momentum(t, q, v);
            let r = SVector::<f64, N>::from_fn(|i, _| m[i] - p[i]);
            newton::square_correction(r, self.velocity_hessian(t, q, v), NewtonOptions::default().min_rcond)
                .map(|(step, _)| step)
        };
        match newton::solve(SVector::from(guess), &NewtonOptions::default(), eval) {
            Ok((v, _)) => Ok(v.into()),
            Err(NewtonFailure::NotConverged(r)) => {
                Err(LegendreFailure { iterations: r.iterations, residual_norm: r.residual_norm })
            }
            Err(
                NewtonFailure::Singular { iterations, .. }
                | NewtonFailure::NonFinite { iterations, .. }
                | NewtonFailure::Rejected { iterations, .. },
            ) => Err(LegendreFailure { iterations, residual_norm: f64::INFINITY }),
        }
    }

    /// `L_d` and its partials `D1..D4` for a discrete Lagrangian on a segment.
    fn discrete_partials<M: DiscreteLagrangian>(&self, method: &M, seg: &Segment<N>) -> DiscretePartials<N> {
        let h = seg.h;
        let g = derivatives::action_gradient(self, method, seg);
        let l_d = g.action / h;
        DiscretePartials {
            l_d,
            d1: (g.d_t0 + l_d) / h,
            d2: g.d_q0.map(|x| x / h),
            d3: (g.d_t1 - l_d) / h,
            d4: g.d_q1.map(|x| x / h),
        }
    }

    /// Residual, next momentum and Newton Jacobian of one step (see [`StepDerivatives`]).
    fn step_derivatives<M: DiscreteLagrangian>(&self, method: &M, seg: &Segment<N>) -> StepDerivatives<N> {
        derivatives::step_derivatives(self, method, seg)
    }

    /// The DEL residual at node `k`,
    /// `∂A(x_k, x_{k+1})/∂q_k + ∂A(x_{k−1}, x_k)/∂q_k`, for three nodes `(t, q)`.
    fn del_residual<M: DiscreteLagrangian>(
        &self,
        method: &M,
        prev: (f64, [f64; N]),
        node: (f64, [f64; N]),
        next: (f64, [f64; N]),
    ) -> [f64; N] {
        let behind = Segment::between(prev, node);
        let ahead = Segment::between(node, next);
        let p = derivatives::end_momentum(self, method, &behind);
        let d = derivatives::action_gradient(self, method, &ahead);
        core::array::from_fn(|i| d.d_q0[i] + p[i])
    }

    /// The Jacobian of [`del_residual`](Self::del_residual) with respect to
    /// `q_{k+1}`: `∂²A(x_k, x_{k+1})/∂q_k∂q_{k+1}`.
    fn del_jacobian<M: DiscreteLagrangian>(
        &self,
        method: &M,
        node: (f64, [f64; N]),
        next: (f64, [f64; N]),
    ) -> SMatrix<f64, N, N> {
        let ahead = Segment::between(node, next);
        derivatives::step_derivatives(self, method, &ahead).d2_q0_q1
    }
}

impl<S: Lagrangian<N> + ?Sized, const N: usize> DiscreteMechanics<N> for S {}

/// `∂²L/∂v²` by `⌈N/8⌉²` evaluations on hyper-duals seeded on eight
/// velocities on each side (see
/// [`HYPER_BLOCKS_ABOVE`](derivatives::HYPER_BLOCKS_ABOVE)); each entry by
/// the same operations as in one evaluation, bit for bit.
fn velocity_hessian_by_blocks<S: Lagrangian<N> + ?Sized, const N: usize>(
    system: &S,
    t: f64,
    q: [f64; N],
    v: [f64; N],
) -> SMatrix<f64, N, N> {
    type H = HyperDualArray<[f64; LANES], [f64; LANES]>;
    let mut m = SMatrix::zeros();
    for i0 in (0..N).step_by(LANES) {
        for j0 in (0..N).step_by(LANES) {
            let mut vd = v.map(H::from_re);
            let (rows, columns) = (LANES.min(N - i0), LANES.min(N - j0));
            for i in 0..rows {
                vd[i0 + i].eps1[i] = 1.0;
            }
            for j in 0..columns {
                vd[j0 + j].eps2[j] = 1.0;
            }
            let l = system.lagrangian(H::from_re(t), q.map(H::from_re), vd);
            for i in 0..rows {
                for j in 0..columns {
                    m[(i0 + i, j0 + j)] = l.eps1eps2[i][j];
                }
            }
        }
    }
    m
}

/// Velocities seeded per evaluation of [`momentum_by_lanes`].
const LANES: usize = 8;

/// `∂L/∂v` by `⌈N/8⌉` evaluations on duals of [`LANES`] lanes, each seeded
/// on the next eight velocities: a dual of `N` lanes is `8(N + 1)` bytes, and
/// the `3N` of them an evaluation holds would not fit a 2 MiB thread stack at
/// `N = 256` (1.5 MiB). Each lane is computed by the same operations as in
/// one evaluation of `N` lanes, so the result is the same bit for bit.
fn momentum_by_lanes<S: Lagrangian<N> + ?Sized, const N: usize>(
    system: &S,
    t: f64,
    q: [f64; N],
    v: [f64; N],
) -> [f64; N] {
    type D = DualArray<[f64; LANES]>;
    let mut p = [0.0; N];
    for first in (0..N).step_by(LANES) {
        let mut vd = v.map(D::from_re);
        let n = LANES.min(N - first);
        for i in 0..n {
            vd[first + i].eps[i] = 1.0;
        }
        let l = system.lagrangian(D::from_re(t), q.map(D::from_re), vd);
        p[first..first + n].copy_from_slice(&l.eps[..n]);
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::system::Scalar;
    use num_dual::{Dual64, HyperDual64};

    /// Non-separable, with a quotient and a square root in the velocities.
    struct Relativistic;

    impl Lagrangian<2> for Relativistic {
        const AUTONOMOUS: bool = false;
        const CYCLIC: [bool; 2] = [false, false];
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 2], v: [D; 2]) -> D {
            let speed2 = v[0] * v[0] + v[1] * v[1] * (q[0] * q[0] + 1.0);
            -(D::from(1.0) - speed2 * 0.2).sqrt() + v[0] * v[1] / (q[1] * q[1] + 2.0) + t.sin() / q[0]
        }
    }

    /// One array evaluation against one scalar evaluation per entry: equal bit for bit.
    /// A chain of 11 coupled rotors: two full blocks of lanes and a partial one.
    struct Rotors;

    impl Lagrangian<11> for Rotors {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 11] = [false; 11];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 11], v: [D; 11]) -> D {
            let mut l = D::zero();
            for i in 0..11 {
                l += v[i] * v[i] * (0.5 + 0.1 * i as f64) + q[i].cos();
                if i + 1 < 11 {
                    l += v[i] * v[i + 1] * (q[i] - q[i + 1]).cos() * 0.2;
                }
            }
            l
        }
    }

    #[test]
    fn momentum_and_velocity_hessian_by_blocks_equal_one_evaluation_bit_for_bit() {
        let q = core::array::from_fn(|i| 0.3 * i as f64 - 1.1);
        let v = core::array::from_fn(|i| (0.7 * i as f64).sin());
        assert_eq!(super::momentum_by_lanes(&Rotors, 0.2, q, v), Rotors.momentum(0.2, q, v));
        assert_eq!(super::velocity_hessian_by_blocks(&Rotors, 0.2, q, v), Rotors.velocity_hessian(0.2, q, v));
    }

    #[test]
    fn momentum_and_velocity_hessian_equal_the_scalar_evaluations() {
        let (t, q, v) = (0.3, [1.2, -0.7], [0.9, -1.1]);
        let p = Relativistic.momentum(t, q, v);
        let m = Relativistic.velocity_hessian(t, q, v);
        for i in 0..2 {
            let mut vd = v.map(Dual64::from);
            vd[i].eps = 1.0;
            assert_eq!(p[i], Relativistic.lagrangian(Dual64::from(t), q.map(Dual64::from), vd).eps);
            for j in 0..2 {
                let mut vd = v.map(HyperDual64::from);
                vd[i].eps1 = 1.0;
                vd[j].eps2 = 1.0;
                let x = Relativistic.lagrangian(HyperDual64::from(t), q.map(HyperDual64::from), vd);
                assert_eq!(m[(i, j)], x.eps1eps2, "({i}, {j})");
            }
        }
        let v_back = Relativistic.velocity(t, q, p, [0.85, -1.05]).unwrap();
        assert!((v_back[0] - v[0]).abs() < 1e-14 && (v_back[1] - v[1]).abs() < 1e-14, "{v_back:?}");
    }
}
