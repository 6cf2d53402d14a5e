//! The discrete forces of a Galerkin rule (discrete Lagrange–d'Alembert
//! principle, docs/theory.md §6): the virtual work `∫ F·δq dt` of the
//! interpolated variation `δq = Σ_m ℓ_m δQ_m`, by the step's own quadrature,
//! puts
//!
//! ```text
//! F^m = h Σ_j b_j ℓ_m(c_j) F(t_j, q(c_j), q̇(c_j))
//! ```
//!
//! on node `m` of the generalised force `F = Q − ∂R/∂v`. The unconstrained
//! step (`stepper.rs`) and the constrained one (`constrained/galerkin.rs`)
//! both take their forces, and the derivatives of them their Newton
//! matrices need, from here.

use crate::noether::Generator;
use crate::real::Real;
use crate::system::{Lagrangian, generalized_force};

use super::method::Galerkin;

/// The generalised force at one quadrature point and, where asked, its
/// Jacobians `(∂F_i/∂q_k, ∂F_i/∂v_k)`.
pub(crate) type PointForce<const N: usize, T> = ([T; N], Option<([[T; N]; N], [[T; N]; N])>);

/// The `entry` of [`Galerkin::point_forces`] where no derivative is wanted.
pub(crate) type NoJacobian<T> = fn(usize, usize, usize, usize, T);

impl<const S: usize, const R: usize, T: Real> Galerkin<S, R, T> {
    /// Lagrange–d'Alembert at quadrature point `j` of a step of size `h`
    /// (the point's `(t, q, v)` from [`point`](Galerkin::point)): adds
    /// `h b_j ℓ_m(c_j) F_j` to `nodes[m]`, `m = 0 … s − 1` (the rows of a
    /// step; the end node's force, which only enters `p_{k+1}`, is
    /// [`end_force`](Self::end_force)). With `entry`, the force's derivative
    /// in the node increments `D_n`, `ℓ_ρ(c_j) (h b_j ℓ_n(c_j) ∂F/∂q + b_j
    /// ℓ_n'(c_j) ∂F/∂v)`, goes to `entry(ρ, i, n − 1, k, value)` for row
    /// node `ρ = 0 … s − 1`, coordinate `i`, unknown `D_n`, `n = 1 … s`, and
    /// coordinate `k`. Returns `F_j` and, with `entry`, its Jacobians.
    #[inline]
    pub(crate) fn point_forces<Sys, E, const N: usize>(
        &self,
        system: &Sys,
        j: usize,
        h: T,
        (t, q, v): (T, [T; N], [T; N]),
        nodes: &mut [[T; N]; S],
        entry: Option<&mut E>,
    ) -> PointForce<N, T>
    where
        Sys: Lagrangian<N> + ?Sized,
        E: FnMut(usize, usize, usize, usize, T),
    {
        let b = self.quadrature().weights()[j];
        let w = b * h;
        let row = &self.row[j];
        let (f, jacobian) = match entry {
            None => (generalized_force(system, t, q, v), None),
            Some(entry) => {
                let (f, dq, dv) = force_derivatives(system, t, q, v);
                let (col, col_d) = (&self.col[j], &self.col_d[j]);
                for n in 0..S {
                    let (c, cd) = (w * col[n], b * col_d[n]);
                    for (rho, &l) in row.iter().enumerate() {
                        for i in 0..N {
                            for k in 0..N {
                                entry(rho, i, n, k, l * (c * dq[i][k] + cd * dv[i][k]));
                            }
                        }
                    }
                }
                (f, Some((dq, dv)))
            }
        };
        for (node, &l) in nodes.iter_mut().zip(row) {
            for i in 0..N {
                node[i] += w * (l * f[i]);
            }
        }
        (f, jacobian)
    }

    /// The discrete forces of the step from `q0 + e` with increments `d`:
    /// `(F^0 … F^{s−1}, F^s)`, the forces on the rows' nodes and on the end
    /// node `q_{k+1}`. Zero, and nothing evaluated, for a system without
    /// forces or dissipation.
    pub(crate) fn discrete_forces<Sys, const N: usize>(
        &self,
        system: &Sys,
        (t0, h): (T, T),
        (q0, e): (&[T; N], &[T; N]),
        d: &[[T; N]; S],
    ) -> ([[T; N]; S], [T; N])
    where
        Sys: Lagrangian<N> + ?Sized,
    {
        let mut nodes = [[T::zero(); N]; S];
        let mut end = [T::zero(); N];
        if !(Sys::HAS_FORCE || Sys::HAS_DISSIPATION) {
            return (nodes, end);
        }
        for j in 0..R {
            let point = self.point(t0, h, (q0, e), d, j);
            let (f, _) = self.point_forces(system, j, h, point, &mut nodes, None::<&mut NoJacobian<T>>);
            let w = self.quadrature().weights()[j] * h;
            for i in 0..N {
                end[i] += w * (self.col[j][S - 1] * f[i]);
            }
        }
        (nodes, end)
    }
}

impl<const S: usize, const R: usize> Galerkin<S, R> {
    /// The forcing impulse `Σ_m F^m·ξ(Q_m)` of the step from `q0 + e` with
    /// increments `d` over its nodes `Q_0 = q_k, …, Q_s = q_{k+1}`: what the
    /// discrete Noether theorem with forcing says the momentum map `J` of
    /// the symmetry `ξ` changes by across the step.
    pub(crate) fn forcing_impulse<Sys, const N: usize>(
        &self,
        system: &Sys,
        (t0, h): (f64, f64),
        (q0, e): (&[f64; N], &[f64; N]),
        d: &[[f64; N]; S],
        symmetry: &(impl Generator<N> + ?Sized),
    ) -> f64
    where
        Sys: Lagrangian<N> + ?Sized,
    {
        let (nodes, end) = self.discrete_forces(system, (t0, h), (q0, e), d);
        let node = |m: usize| -> [f64; N] {
            core::array::from_fn(|i| q0[i] + (e[i] + if m == 0 { 0.0 } else { d[m - 1][i] }))
        };
        let dot = |a: &[f64; N], b: &[f64; N]| (0..N).map(|i| a[i] * b[i]).sum::<f64>();
        let mut impulse = dot(&end, &symmetry.generator(&node(S)));
        for (m, force) in nodes.iter().enumerate() {
            impulse += dot(force, &symmetry.generator(&node(m)));
        }
        impulse
    }
}

/// The generalised force `F = Q − ∂R/∂v` at one point and its Jacobians
/// `(∂F_i/∂q_k, ∂F_i/∂v_k)`: `2N` evaluations on duals over `T`.
#[inline]
#[allow(clippy::type_complexity)]
fn force_derivatives<Sys, T, const N: usize>(
    system: &Sys,
    t: T,
    q: [T; N],
    v: [T; N],
) -> ([T; N], [[T; N]; N], [[T; N]; N])
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    use num_dual::Dual;
    let z = T::zero();
    let (mut f, mut dq, mut dv) = ([z; N], [[z; N]; N], [[z; N]; N]);
    for k in 0..2 * N {
        let mut qd = q.map(Dual::from_re);
        let mut vd = v.map(Dual::from_re);
        if k < N {
            qd[k].eps = T::one();
        } else {
            vd[k - N].eps = T::one();
        }
        let y = generalized_force(system, Dual::from_re(t), qd, vd);
        for i in 0..N {
            f[i] = y[i].re;
            if k < N {
                dq[i][k] = y[i].eps;
            } else {
                dv[i][k - N] = y[i].eps;
            }
        }
    }
    (f, dq, dv)
}

/// `∂F_i/∂v_k` of the generalised force `F = Q − ∂R/∂v` at one point: `N`
/// evaluations on duals over `T` (the fixed-point iteration's matrix needs
/// no derivative in `q`).
#[inline]
pub(super) fn force_velocity_jacobian<Sys, T, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> [[T; N]; N]
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    use num_dual::Dual;
    let mut dv = [[T::zero(); N]; N];
    for k in 0..N {
        let mut vd = v.map(Dual::from_re);
        vd[k].eps = T::one();
        let y = generalized_force(system, Dual::from_re(t), q.map(Dual::from_re), vd);
        for i in 0..N {
            dv[i][k] = y[i].eps;
        }
    }
    dv
}

/// `∂F_i/∂q_k` of the generalised force `F = Q − ∂R/∂v` at one point: `N`
/// evaluations on duals over `T` (the second-order term of the fixed-point
/// iteration's coupled matrix).
#[inline]
pub(super) fn force_position_jacobian<Sys, T, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> [[T; N]; N]
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    use num_dual::Dual;
    let mut dq = [[T::zero(); N]; N];
    for k in 0..N {
        let mut qd = q.map(Dual::from_re);
        qd[k].eps = T::one();
        let y = generalized_force(system, Dual::from_re(t), qd, v.map(Dual::from_re));
        for i in 0..N {
            dq[i][k] = y[i].eps;
        }
    }
    dq
}
