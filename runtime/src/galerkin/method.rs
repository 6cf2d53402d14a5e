//! The Galerkin discrete Lagrangian of degree `s` with an `r`-point quadrature.
//!
//! ```text
//! A(t_k, h; Q_0, Q_1, …, Q_s) = h Σ_{j=1}^{r} b_j L( t_k + c_j h,  Σ_m ℓ_m(c_j) Q_m,  Σ_m ℓ_m'(c_j) Q_m / h )
//! ```
//!
//! `Q_0 = q_k`, `Q_s = q_{k+1}`, `Q_1 … Q_{s−1}` the interior nodes of the
//! degree-`s` polynomial through the control nodes `τ_m` ([`NodeFamily`]),
//! `(c_j, b_j)` the quadrature ([`Quadrature`]). The interior nodes are
//! eliminated by `∂A/∂Q_m = 0` (Chen, Guo & Wu (finite elements) (2.38)); what remains is a discrete
//! Lagrangian of `(q_k, q_{k+1})`.
//!
//! Source: Chen, Guo & Wu, Chen, Guo & Wu (finite elements) §2.2 (`s = 1`: the linear element,
//! (2.23)–(2.24), with the potential integrated by the quadrature) and §2.3
//! (`s = 2`: the quadratic element, (2.33)–(2.39)); the general degree and the
//! order result are Marsden & West, *Acta Numerica* 2001, §2.6, and Hairer,
//! Lubich & Wanner, *Geometric Numerical Integration*, §VI.6.3.
//!
//! Order: with `s` Gauss–Legendre points the one-step map on the nodal values
//! is of order `2s` (it coincides with the `s`-stage Gauss collocation method
//! for `L = ½ vᵀMv − V(q)`); with `s + 1` Gauss–Lobatto points it is of order
//! `2s` as well (Lobatto IIIA–IIIB). In general, order `min(2s, p)` for a
//! quadrature of order `p`. The quadrature must integrate the kinetic term of
//! the step polynomial exactly (degree `2s − 2`), otherwise the interior nodes
//! are not determined ([`Galerkin::check`]).
//!
//! # Derivatives by the chain rule
//!
//! With `W_j = (q_h(c_j), q_h'(c_j)/h)`, every derivative of `A` with
//! respect to the nodes follows from the gradient `(L_q, L_v)` and the
//! `2N × 2N` Hessian of `L` at the `r` quadrature points:
//!
//! ```text
//! ∂A/∂Q_m        = Σ_j b_j ( h ℓ_m L_q + ℓ_m' L_v )
//! ∂²A/∂Q_m∂Q_n   = Σ_j b_j ( h ℓ_m ℓ_n L_qq + ℓ_m ℓ_n' L_qv + ℓ_m' ℓ_n L_vq + ℓ_m' ℓ_n' L_vv / h )
//! ```
//!
//! (all `ℓ` at `c_j`), so a Newton iteration costs `r` evaluations of `L`
//! whatever the degree, each on one array hyper-dual seeded on all `2N`
//! coordinates `(q, v)` (or on an array dual when only the gradient is
//! needed; see [`crate::hyperdual`]). Positions are
//! evaluated in increment form, `q_h(c_j) = q_k + Σ_{m≥1} ℓ_m(c_j) D_m` with
//! `D_m = Q_m − q_k`, and velocities as `Σ_{m≥1} ℓ_m'(c_j) D_m / h`, free of
//! the cancellation in `Q_m − q_k` (see
//! [`DiscreteLagrangian::action`](crate::DiscreteLagrangian::action)).

use nalgebra::DMatrix;

use super::basis::{NodeFamily, lagrange, lagrange_derivative};
use super::linalg::BlockVector;
use super::quadrature::Quadrature;
use crate::hyperdual::{DualArray, HyperDualArray, Pair, Vector};
use crate::real::Real;
use crate::system::{Lagrangian, Scalar};

/// The Galerkin discrete Lagrangian with a polynomial of degree `S` and an
/// `R`-point quadrature (the formula, its source and the order:
/// `docs/theory.md` §5 and the [`galerkin`](crate::galerkin) module).
///
/// Built once; the Lagrange basis values and derivatives at the quadrature
/// points are tabulated then, so stepping never recomputes them.
///
/// ```
/// use lagrangian_runtime::galerkin::{Galerkin, NodeFamily, Quadrature};
///
/// // Degree 4 with 4 Gauss–Legendre points: order 8.
/// let g = Galerkin::<4, 4>::gauss();
/// assert_eq!(g.order(), 8);
/// // The same polynomial space with equispaced nodes (Chen, Guo & Wu (finite elements)) and 5 Lobatto points.
/// let e = Galerkin::<4, 5>::new(NodeFamily::Equispaced, Quadrature::gauss_lobatto());
/// assert!(e.check().is_ok());
/// // Too weak: 2 Gauss points cannot integrate the kinetic term of degree 6.
/// assert!(Galerkin::<4, 2>::new(NodeFamily::GaussLobatto, Quadrature::gauss_legendre()).check().is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Galerkin<const S: usize, const R: usize, T = f64> {
    family: NodeFamily,
    quadrature: Quadrature<R, T>,
    /// Control nodes `τ_1 … τ_s` (`τ_0 = 0`).
    pub(crate) control: [T; S],
    /// `ℓ_0 … ℓ_{s−1}` at `c_j`: the basis of the equations (rows) of a step,
    /// with `ℓ_0 = 1 − Σ_{m≥1} ℓ_m` (used for the Jacobian only; the residual
    /// of the `q_k` row is formed as `∂A/∂q_k|_D − Σ_m ∂A/∂D_m`).
    pub(crate) row: [[T; S]; R],
    /// `ℓ_0' … ℓ_{s−1}'` at `c_j`.
    pub(crate) row_d: [[T; S]; R],
    /// `ℓ_1 … ℓ_s` at `c_j`: the basis of the unknowns (columns) of a step.
    pub(crate) col: [[T; S]; R],
    /// `ℓ_1' … ℓ_s'` at `c_j`.
    pub(crate) col_d: [[T; S]; R],
    /// `max_j |ℓ_m(c_j)|`, `m = 1 … s` (sizes the round-off of a residual row).
    pub(crate) col_max: [f64; S],
    /// `max_j |ℓ_m'(c_j)|`, `m = 1 … s`.
    pub(crate) col_d_max: [f64; S],
    /// `ℓ_n(1 + τ_m) − δ_{ns}`, row `m − 1`, column `n − 1`: extrapolates the
    /// increments of one step to the next (same step size).
    pub(crate) extrapolate: [[T; S]; S],
    /// `ℓ_1'(1) … ℓ_s'(1)`: the velocity at the end of a step, `Σ_n ℓ_n'(1) D_n / h`.
    pub(crate) end_d: [T; S],
    /// The Runge–Kutta matrix of the quadrature points, `a_ij = ∫_0^{c_i} L_j`
    /// with `L_j` the Lagrange basis on `c_1 … c_r` (the Gauss collocation
    /// matrix for Gauss–Legendre points): stage values from stage velocities.
    pub(crate) stage_from_stages: [[T; R]; R],
    /// `∫_0^{τ_m} L_j`, row `m − 1`: the node increments `D_m = h Σ_j (·) V_j`
    /// of the step polynomial whose velocities at the points are `V_j`.
    pub(crate) node_from_stages: [[T; R]; S],
    /// `μ_ij = a_ij / b_j` with `μ_ij + μ_ji = 1` exactly in `T` (`μ_ii = ½`):
    /// the collocation step takes `a_ij = μ_ij (h b_j)` and `b_j = (h b_j)`
    /// with `h b_j` rounded once, so that the coefficients it computes with
    /// satisfy `b_i a_ij + b_j a_ji = b_i b_j` exactly and the map is
    /// symplectic to the rounding of its arithmetic, not only to the
    /// rounding of its coefficients (Antoñana, Makazaga & Murua, *Numer.
    /// Algorithms* 2017; see `collocation.rs`).
    pub(crate) stage_ratio: [[T; R]; R],
    /// How the step equations are solved ([`StageIteration`]).
    iteration: StageIteration,
}

/// How a fixed Galerkin step solves its equations.
///
/// With as many Gauss–Legendre points as the degree (every
/// [`Galerkin::gauss`] rule) the step is Gauss collocation of the
/// Hamiltonian system in `(q, p)`, and its equations can be solved by a
/// fixed-point iteration on the velocities at the points, with gradients of
/// `L` only (no Jacobian of the step): see the `collocation` module of the
/// runtime's Galerkin rules. Both iterations converge to the same step, to
/// round-off. Other quadratures always use Newton.
///
/// The default is [`Automatic`](StageIteration::Automatic): a fixed-point
/// iteration costs gradients of `L` only, where a Newton iteration costs
/// its Hessian and a solve, so even at about twice the iterations it is
/// the cheaper step on non-stiff runs (the report's `galerkin-fp-S`
/// against `galerkin-S`, `--problem double-pendulum,sensor --targets
/// 1e-4,1e-7,1e-10`, one run: 0.40–0.97 of Newton's time on the double
/// pendulum and 0.58–0.89 on the sensor, except at s = 2 and 1e-4 (1.45
/// and 1.25) and the sensor's two-step s = 6 run at 1e-4 (1.73)).
/// The fixed point stops at `f64` round-off, so other number types
/// (`DoubleDouble`) always use Newton.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StageIteration {
    /// The fixed-point iteration where it contracts fast enough, Newton on
    /// the steps where it does not (a stiff step, a poor first guess),
    /// chosen per step from the observed contraction. A step Newton solves
    /// is finished by the fixed point from Newton's root (a round or two),
    /// so that every step ends with the same round-off (see the
    /// `collocation` module).
    #[default]
    Automatic,
    /// The fixed-point iteration only: a step on which it does not converge
    /// fails with a typed error (for checks; rules without collocation form
    /// use Newton whatever this says).
    FixedPoint,
    /// Newton on the node values (with a kept Jacobian) on every step.
    Newton,
}

impl<const S: usize, const R: usize, T: Real> Galerkin<S, R, T> {
    /// Degree `S` with control nodes `family` and the given quadrature.
    ///
    /// Never panics; an unusable combination (`S = 0`, an invalid or too weak
    /// quadrature) is reported by [`check`](Self::check) and refused by the
    /// integrator with [`Error::InvalidMethod`](crate::Error::InvalidMethod).
    pub fn new(family: NodeFamily, quadrature: Quadrature<R, T>) -> Self {
        let mut g = Self {
            family,
            quadrature,
            control: [T::zero(); S],
            row: [[T::zero(); S]; R],
            row_d: [[T::zero(); S]; R],
            col: [[T::zero(); S]; R],
            col_d: [[T::zero(); S]; R],
            col_max: [0.0; S],
            col_d_max: [0.0; S],
            extrapolate: [[T::zero(); S]; S],
            end_d: [T::zero(); S],
            stage_from_stages: [[T::zero(); R]; R],
            node_from_stages: [[T::zero(); R]; S],
            stage_ratio: [[T::zero(); R]; R],
            iteration: StageIteration::Automatic,
        };
        if S == 0 {
            return g;
        }
        let x = family.nodes::<T>(S);
        g.control.copy_from_slice(&x[1..=S]);
        for (j, &c) in quadrature.nodes().iter().enumerate() {
            for m in 0..S {
                g.col[j][m] = lagrange(&x, m + 1, c);
                g.col_d[j][m] = lagrange_derivative(&x, m + 1, c);
            }
            // ℓ_0 = 1 − Σ_{m≥1} ℓ_m exactly as the increment form uses it, not
            // as the product formula rounds it: the derivative in q_k must be
            // the derivative of the same action, or the map is not symplectic
            // to round-off and the energy drifts (a separately rounded `ℓ_0`
            // costs a 5e-10 phase error on Kepler over ten orbits with s = 6).
            g.row[j][0] = T::one() - g.col[j].iter().copied().sum::<T>();
            g.row_d[j][0] = -g.col_d[j].iter().copied().sum::<T>();
            for m in 1..S {
                g.row[j][m] = g.col[j][m - 1];
                g.row_d[j][m] = g.col_d[j][m - 1];
            }
        }
        for m in 0..S {
            g.end_d[m] = lagrange_derivative(&x, m + 1, T::one());
            for j in 0..R {
                g.col_max[m] = g.col_max[m].max(g.col[j][m].abs().to_f64());
                g.col_d_max[m] = g.col_d_max[m].max(g.col_d[j][m].abs().to_f64());
            }
        }
        for m in 0..S {
            for n in 0..S {
                let delta = if n + 1 == S { 1.0 } else { 0.0 };
                g.extrapolate[m][n] = lagrange(&x, n + 1, T::one() + x[m + 1]) - delta;
            }
        }
        // ∫_0^τ L_j = τ Σ_k b_k L_j(τ c_k), exact for Gauss–Legendre points
        // (L_j has degree r − 1); only used where the rule is Gauss.
        let c = quadrature.nodes();
        let integral = |tau: T, j: usize| -> T {
            let mut sum = T::zero();
            for (k, &ck) in c.iter().enumerate() {
                sum += quadrature.weights()[k] * lagrange(c, j, tau * ck);
            }
            tau * sum
        };
        for i in 0..R {
            for j in 0..R {
                g.stage_from_stages[i][j] = integral(c[i], j);
            }
        }
        for m in 0..S {
            for j in 0..R {
                g.node_from_stages[m][j] = integral(x[m + 1], j);
            }
        }
        // Of each pair the ratio at least ½ is rounded, the other is `1 − μ`,
        // exact (Sterbenz) where the rounded one is at most 2, and exact for
        // the Gauss rules tabulated (the unit test checks the sums).
        let b = quadrature.weights();
        for i in 0..R {
            g.stage_ratio[i][i] = T::from(0.5);
            for j in 0..i {
                let (upper, lower) = (g.stage_from_stages[i][j] / b[j], g.stage_from_stages[j][i] / b[i]);
                if upper.to_f64() >= lower.to_f64() {
                    (g.stage_ratio[i][j], g.stage_ratio[j][i]) = (upper, T::one() - upper);
                } else {
                    (g.stage_ratio[i][j], g.stage_ratio[j][i]) = (T::one() - lower, lower);
                }
            }
        }
        g
    }

    /// The rule with the given way of solving its step equations (the
    /// default is [`StageIteration::Automatic`]).
    pub fn with_iteration(mut self, iteration: StageIteration) -> Self {
        self.iteration = iteration;
        self
    }

    /// How the step equations are solved.
    pub fn iteration(&self) -> StageIteration {
        self.iteration
    }

    /// Whether the step is Gauss collocation (`s` Gauss–Legendre points for
    /// degree `s`), which the fixed-point iteration solves.
    pub(crate) fn is_collocation(&self) -> bool {
        R == S && T::EPSILON == f64::EPSILON && matches!(self.quadrature.kind(), super::QuadratureKind::GaussLegendre)
    }

    /// The node family of the step polynomial.
    pub fn family(&self) -> NodeFamily {
        self.family
    }

    /// The quadrature rule.
    pub fn quadrature(&self) -> &Quadrature<R, T> {
        &self.quadrature
    }

    /// The degree `s` of the step polynomial.
    pub fn degree(&self) -> usize {
        S
    }

    /// The control nodes `τ_1 … τ_s` in `(0, 1]` (`τ_0 = 0` is implied).
    pub fn control_nodes(&self) -> &[T; S] {
        &self.control
    }

    /// The order of the one-step map on nodal values for a regular
    /// Lagrangian: `min(2s, quadrature order)`, where a rule exact to degree
    /// `d` has order `d + 1` (0 for an invalid combination).
    pub fn order(&self) -> u32 {
        match (self.check(), self.quadrature.exactness()) {
            (Ok(()), Some(d)) => (2 * S).min(d + 1) as u32,
            _ => 0,
        }
    }

    /// `Ok` for a usable method, otherwise why not.
    pub fn check(&self) -> Result<(), &'static str> {
        if S == 0 {
            return Err("the degree s of a Galerkin discrete Lagrangian must be at least 1");
        }
        self.quadrature.check()?;
        let exact = self.quadrature.exactness().unwrap_or(0);
        if exact + 2 < 2 * S {
            return Err("the quadrature is too weak for the degree: it must integrate polynomials of degree 2s − 2 \
                 exactly (the kinetic term), i.e. at least s Gauss–Legendre or s + 1 Gauss–Lobatto points");
        }
        Ok(())
    }
}

impl<const S: usize, const R: usize> Galerkin<S, R> {
    /// The step action `A` on any [`Scalar`], from `(t0, h, q0)` and the
    /// node increments `d[m − 1] = Q_m − q_k`, `m = 1 … s` (`d[s − 1]` is
    /// `q_{k+1} − q_k`).
    ///
    /// The stepper does not call it (it uses the chain rule, see the module
    /// documentation); it is the formula itself, for checks and for
    /// derivatives by seeding dual numbers.
    pub fn action<Sys, D, const N: usize>(&self, system: &Sys, t0: D, h: D, q0: [D; N], d: [[D; N]; S]) -> D
    where
        Sys: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let inv_h = h.recip();
        let mut sum = D::zero();
        for j in 0..R {
            let q = core::array::from_fn(|i| q0[i] + (0..S).fold(D::zero(), |a, m| a + d[m][i] * self.col[j][m]));
            let v = core::array::from_fn(|i| (0..S).fold(D::zero(), |a, m| a + d[m][i] * self.col_d[j][m]) * inv_h);
            let t = t0 + h * self.quadrature.nodes()[j];
            sum += system.lagrangian(t, q, v) * self.quadrature.weights()[j];
        }
        sum * h
    }

    /// `(∂A/∂Q_0, [∂A/∂Q_1, …, ∂A/∂Q_s])`: the gradient of the action with
    /// respect to every node, by the chain rule from one array-dual
    /// evaluation of `L` per quadrature point. `∂A/∂Q_s` is the momentum
    /// `p_{k+1}` of the step.
    pub fn node_gradient<Sys, const N: usize>(
        &self,
        system: &Sys,
        t0: f64,
        h: f64,
        q0: [f64; N],
        d: &[[f64; N]; S],
    ) -> ([f64; N], [[f64; N]; S])
    where
        Sys: Lagrangian<N> + ?Sized,
    {
        let mut g0 = [0.0; N];
        let mut g = [[0.0; N]; S];
        for j in 0..R {
            let (t, q, v) = self.point(t0, h, (&q0, &[0.0; N]), d, j);
            let (lq, lv) = gradient_at(system, t, q, v);
            let w = self.quadrature.weights()[j] * h;
            // ∂A/∂Q_0 = ∂A/∂q_k at fixed increments − Σ_m ∂A/∂D_m.
            for i in 0..N {
                g0[i] += w * lq[i];
            }
            for m in 0..S {
                let (c, cd) = (self.col[j][m], self.col_d[j][m]);
                for i in 0..N {
                    g[m][i] += w * (c * lq[i]) + w * (cd * (lv[i] / h));
                }
            }
        }
        for gm in &g {
            for i in 0..N {
                g0[i] -= gm[i];
            }
        }
        (g0, g)
    }

    /// The full Hessian `∂²A/∂Q_m∂Q_n` over the nodes `m, n = 0 … s`, as a
    /// dense `(s+1)N × (s+1)N` matrix ordered by node, then coordinate.
    ///
    /// For checks and for the tangent map of a step (docs/theory.md §8); it
    /// allocates, and the stepper never calls it.
    pub fn node_hessian<Sys, const N: usize>(
        &self,
        system: &Sys,
        t0: f64,
        h: f64,
        q0: [f64; N],
        d: &[[f64; N]; S],
    ) -> DMatrix<f64>
    where
        Sys: Lagrangian<N> + ?Sized,
    {
        let n_all = (S + 1) * N;
        let mut out = DMatrix::zeros(n_all, n_all);
        for j in 0..R {
            let (t, q, v) = self.point(t0, h, (&q0, &[0.0; N]), d, j);
            let p = PointDerivatives::at(system, t, q, v);
            let b = self.quadrature.weights()[j];
            // ℓ_m and ℓ_m' at c_j for m = 0 … s.
            let l = |m: usize| if m < S { self.row[j][m] } else { self.col[j][S - 1] };
            let dl = |m: usize| if m < S { self.row_d[j][m] } else { self.col_d[j][S - 1] };
            for m in 0..=S {
                for n in 0..=S {
                    for i in 0..N {
                        for k in 0..N {
                            out[(m * N + i, n * N + k)] += b
                                * (h * l(m) * l(n) * p.qq[i][k]
                                    + l(m) * dl(n) * p.qv[i][k]
                                    + dl(m) * l(n) * p.qv[k][i]
                                    + dl(m) * dl(n) * p.vv[i][k] / h);
                        }
                    }
                }
            }
        }
        out
    }
}

impl<const S: usize, const R: usize, T: Real> Galerkin<S, R, T> {
    /// Time, position and velocity at quadrature point `j` of the step that
    /// starts at `q0 + e` (`e`: the compensation of a Kahan-summed position).
    #[inline(always)]
    pub(crate) fn point<const N: usize>(
        &self,
        t0: T,
        h: T,
        (q0, e): (&[T; N], &[T; N]),
        d: &[[T; N]; S],
        j: usize,
    ) -> (T, [T; N], [T; N]) {
        let (col, col_d) = (&self.col[j], &self.col_d[j]);
        let q = core::array::from_fn(|i| {
            let mut x = e[i];
            for m in 0..S {
                x += col[m] * d[m][i];
            }
            q0[i] + x
        });
        let v = core::array::from_fn(|i| {
            let mut x = T::zero();
            for m in 0..S {
                x += col_d[m] * d[m][i];
            }
            // Divided, not multiplied by a rounded 1/h: ∂v/∂D_m = ℓ_m'/h then
            // holds without a systematic relative error.
            x / h
        });
        (t0 + self.quadrature.nodes()[j] * h, q, v)
    }

    /// Control node `τ_m`, `m = 0 … s`.
    #[inline]
    fn tau(&self, m: usize) -> T {
        if m == 0 { T::zero() } else { self.control[m - 1] }
    }

    /// `ℓ_n(τ)`, `n = 0 … s`, without allocating.
    pub(crate) fn basis(&self, n: usize, tau: T) -> T {
        (0..=S).filter(|&k| k != n).map(|k| (tau - self.tau(k)) / (self.tau(n) - self.tau(k))).product()
    }

    /// `ℓ_n'(τ)`, `n = 0 … s`, without allocating.
    pub(crate) fn basis_derivative(&self, n: usize, tau: T) -> T {
        (0..=S)
            .filter(|&k| k != n)
            .map(|k| {
                let rest: T = (0..=S)
                    .filter(|&l| l != n && l != k)
                    .map(|l| (tau - self.tau(l)) / (self.tau(n) - self.tau(l)))
                    .product();
                rest / (self.tau(n) - self.tau(k))
            })
            .sum()
    }
}

impl<const S: usize, T: Real> Galerkin<S, S, T> {
    /// Degree `S` on Gauss–Lobatto control nodes with `S` Gauss–Legendre
    /// points: the optimal choice, of order `2S` (Gauss collocation).
    pub fn gauss() -> Self {
        Self::new(NodeFamily::GaussLobatto, Quadrature::gauss_legendre())
    }
}

/// The `2N` variables `(q, v)` of `L` at one point, as the slots of one
/// infinitesimal: slot `i` is `q[i]`, slot `N + i` is `v[i]`.
type Seeds<const N: usize, T> = Pair<[T; N], [T; N]>;

/// `(L, L_q, L_v)` at one point: one evaluation of `L` on a [`DualArray`]
/// seeded on all of `(q, v)`.
#[inline(always)]
pub(crate) fn point_gradient<Sys, T, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> (T, [T; N], [T; N])
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    // In `f64`, the adjoint code `#[lagrangian]` wrote costs a small multiple
    // of one evaluation where the array dual carries 2N derivative parts
    // through every operation. (The test on EPSILON is a constant: only
    // `f64` has f64's.)
    if Sys::HAS_GRADIENT_QV && T::EPSILON == f64::EPSILON {
        let (mut lq, mut lv) = ([0.0; N], [0.0; N]);
        let (qf, vf) = (q.map(|x| x.to_f64()), v.map(|x| x.to_f64()));
        system.gradient_qv(t.to_f64(), &qf, &vf, &mut lq, &mut lv);
        return (system.lagrangian(t, q, v), lq.map(T::from), lv.map(T::from));
    }
    let qd = core::array::from_fn(|i| DualArray::<Seeds<N, T>, T>::variable(q[i], i));
    let vd = core::array::from_fn(|i| DualArray::variable(v[i], N + i));
    let l = system.lagrangian(DualArray::from_re(t), qd, vd);
    (l.re, l.eps.a, l.eps.b)
}

/// `(L, L_q, L_v)` at one point where `L` is read only for its finiteness
/// (the checks of a step's action): in `f64` with the adjoint code
/// `#[lagrangian]` wrote, the value comes from that code's own forward
/// sweep, where [`point_gradient`] calls `L` again and repeats its
/// transcendental calls (the double pendulum's three cosines). The value
/// may differ from `L`'s in the last bits (the sweep's order of
/// operations), never in finiteness but at overflow.
#[inline(always)]
pub(crate) fn value_gradient_at<Sys, T, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> (T, [T; N], [T; N])
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    if Sys::HAS_GRADIENT_QV && T::EPSILON == f64::EPSILON {
        let (mut lq, mut lv) = ([0.0; N], [0.0; N]);
        let (qf, vf) = (q.map(|x| x.to_f64()), v.map(|x| x.to_f64()));
        let l = system.value_gradient_qv_scalar(t.to_f64(), &qf, &vf, &mut lq, &mut lv);
        return (T::from(l), lq.map(T::from), lv.map(T::from));
    }
    point_gradient(system, t, q, v)
}

/// `∂²L/∂q_i∂q_k` at one point, for the second-order term of the
/// fixed-point iteration's coupled matrix: in `f64` with the adjoint code
/// `#[lagrangian]` wrote, forward over reverse with one lane per position
/// (as [`velocity_hessian`] has one per velocity); otherwise from the
/// whole Hessian.
#[inline(always)]
pub(crate) fn position_hessian<Sys, T, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> [[T; N]; N]
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    if Sys::HAS_GRADIENT_QV && T::EPSILON == f64::EPSILON {
        type D<const N: usize> = DualArray<[f64; N]>;
        let (qd, vd) = (seeded(q), v.map(|x| D::<N>::from_re(x.to_f64())));
        let (mut lq, mut lv) = ([D::<N>::from_re(0.0); N], [D::<N>::from_re(0.0); N]);
        system.gradient_qv_scalar(D::from_re(t.to_f64()), &qd, &vd, &mut lq, &mut lv);
        return core::array::from_fn(|i| lq[i].eps.map(T::from));
    }
    PointDerivatives::at(system, t, q, v).qq
}

/// `x` in `f64` duals with one lane per coordinate, lane `i` of `x_i` set:
/// the seed of a forward-over-reverse Hessian row by row.
#[inline(always)]
fn seeded<T: Real, const N: usize>(x: [T; N]) -> [DualArray<[f64; N]>; N] {
    core::array::from_fn(|i| {
        let mut d = DualArray::<[f64; N]>::from_re(x[i].to_f64());
        d.eps[i] = 1.0;
        d
    })
}

/// `(L_q, L_v)` at one point (see [`point_gradient`]).
#[inline(always)]
pub(crate) fn gradient_at<Sys, T, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> ([T; N], [T; N])
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    let (_, lq, lv) = point_gradient(system, t, q, v);
    (lq, lv)
}

/// The derivatives of `L` at one point that carry a velocity: `∂L/∂q`,
/// `∂L/∂v`, `∂²L/∂v²` and `∂²L/∂q∂v`.
pub(crate) struct VelocityDerivatives<const N: usize, T> {
    /// `∂L/∂q_i`.
    pub(crate) q: [T; N],
    /// `∂L/∂v_i`.
    pub(crate) v: [T; N],
    /// `∂²L/∂v_i∂v_k`.
    pub(crate) vv: [[T; N]; N],
    /// `∂²L/∂q_i∂v_k`: the derivative of `∂L/∂q_i` in `v_k`.
    pub(crate) qv: [[T; N]; N],
}

/// `∂L/∂q`, `∂L/∂v`, `∂²L/∂v²` and `∂²L/∂q∂v` at one point: one evaluation
/// of `L` on a [`HyperDualArray`] with `ε1` seeded on `v` and `ε2` on
/// `(q, v)` (`1 + 3N + 2N²` components; above `N = ROWS` by the rows of the
/// whole Hessian, which keep the numbers small).
#[inline(always)]
pub(crate) fn velocity_hessian<Sys, T, const N: usize>(
    system: &Sys,
    t: T,
    q: [T; N],
    v: [T; N],
) -> VelocityDerivatives<N, T>
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    // In `f64` with the adjoint code `#[lagrangian]` wrote: forward over
    // reverse, that code on duals with one lane per velocity, so row `i` of
    // `∂²L/∂v²` is the lanes of `∂L/∂v_i` (`N + 1` parts per operation where
    // the hyper-dual below carries `1 + 3N + 2N²`; the trigonometric calls
    // are the same). Measured with callgrind on the report's double pendulum
    // (s = 4, 673 steps, `bench/examples/galerkin_steps.rs`): 15.1k → 14.2k
    // instructions per fixed-point step. Only the iteration matrix and the
    // first round's gradients (the adjoint code's, as in later rounds) come
    // from it, so no converged step changes beyond round-off.
    if Sys::HAS_GRADIENT_QV && T::EPSILON == f64::EPSILON {
        type D<const N: usize> = DualArray<[f64; N]>;
        let (qd, vd) = (q.map(|x| D::<N>::from_re(x.to_f64())), seeded(v));
        let (mut lq, mut lv) = ([D::<N>::from_re(0.0); N], [D::<N>::from_re(0.0); N]);
        system.gradient_qv_scalar(D::from_re(t.to_f64()), &qd, &vd, &mut lq, &mut lv);
        // Lane `k` of `∂L/∂q_i` is `∂²L/∂q_i∂v_k`: the coupling the
        // fixed-point iteration's matrix takes, at no extra cost.
        let vv = core::array::from_fn(|i| lv[i].eps.map(T::from));
        let qv = core::array::from_fn(|i| lq[i].eps.map(T::from));
        return VelocityDerivatives { q: lq.map(|x| T::from(x.re)), v: lv.map(|x| T::from(x.re)), vv, qv };
    }
    if N > ROWS {
        let p = PointDerivatives::at(system, t, q, v);
        return VelocityDerivatives { q: p.q, v: p.v, vv: p.vv, qv: p.qv };
    }
    type D<const N: usize, T> = HyperDualArray<[T; N], Seeds<N, T>, T>;
    let qd = core::array::from_fn(|i| {
        let mut d = D::<N, T>::from_re(q[i]);
        d.eps2.a[i] = T::one();
        d
    });
    let vd = core::array::from_fn(|i| {
        let mut d = D::<N, T>::from_re(v[i]);
        d.eps1[i] = T::one();
        d.eps2.b[i] = T::one();
        d
    });
    let l = system.lagrangian(D::from_re(t), qd, vd);
    let vv = core::array::from_fn(|i| core::array::from_fn(|k| l.mixed(i, N + k)));
    let qv = core::array::from_fn(|i| core::array::from_fn(|k| l.mixed(k, i)));
    VelocityDerivatives { q: l.eps2.a, v: l.eps2.b, vv, qv }
}

/// `(L, ∂L/∂v, ∂²L/∂v²)` at one point, entry for entry those of
/// [`PointDerivatives::at`] and [`velocity_hessian`] (bit for bit, in `f64`
/// and in double-double): up to `N = ROWS` one evaluation of `L` with both
/// infinitesimals seeded on `v`, above it one per block of [`ROWS`] rows
/// (`ε1` on the block, `ε2` on all of `v`), the lower triangle copied from
/// the upper as [`PointDerivatives`] does. No derivative in `q` is carried:
/// on the FPU-β chain of 16 masses each number holds `1 + 8 + 16 + 128`
/// components in two evaluations, where the `(q, v)` Hessian holds
/// `1 + 8 + 32 + 256` in four. The mass matrix of a Legendre transform and
/// of a constant mass matrix kept for a run.
#[allow(clippy::type_complexity)]
pub(crate) fn velocity_derivatives<Sys, T, const N: usize>(
    system: &Sys,
    t: T,
    q: [T; N],
    v: [T; N],
) -> (T, [T; N], Box<[[T; N]; N]>)
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    let mut m: Box<[[T; N]; N]> = match vec![[T::zero(); N]; N].into_boxed_slice().try_into() {
        Ok(m) => m,
        Err(_) => unreachable!("a matrix has N rows"),
    };
    if N <= ROWS {
        type D<const N: usize, T> = HyperDualArray<[T; N], [T; N], T>;
        let vd = core::array::from_fn(|i| {
            let mut d = D::<N, T>::from_re(v[i]);
            d.eps1[i] = T::one();
            d.eps2[i] = T::one();
            d
        });
        let l = system.lagrangian(D::from_re(t), q.map(D::from_re), vd);
        for (row, l_row) in m.iter_mut().zip(&l.eps1eps2) {
            *row = *l_row;
        }
        return (l.re, l.eps2, m);
    }
    type D<const N: usize, T> = HyperDualArray<[T; ROWS], [T; N], T>;
    let (mut value, mut lv) = (T::zero(), [T::zero(); N]);
    for first in (0..N).step_by(ROWS) {
        let vd = core::array::from_fn(|i| {
            let mut d = D::<N, T>::from_re(v[i]);
            d.eps2[i] = T::one();
            if (first..first + ROWS).contains(&i) {
                d.eps1[i - first] = T::one();
            }
            d
        });
        let l = system.lagrangian(D::from_re(t), q.map(D::from_re), vd);
        (value, lv) = (l.re, l.eps2);
        for (row, l_row) in m[first..].iter_mut().zip(&l.eps1eps2) {
            *row = *l_row;
        }
    }
    for i in 0..N {
        for k in 0..i {
            m[i][k] = m[k][i];
        }
    }
    (value, lv, m)
}

/// The rows of the Hessian of `L` per evaluation above `N = ROWS / 2`.
const ROWS: usize = 8;

/// Value, gradient and Hessian of `L` in `(q, v)` at one point.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PointDerivatives<const N: usize, T = f64> {
    /// `L`.
    pub(crate) value: T,
    /// `∂L/∂q_i`.
    pub(crate) q: [T; N],
    /// `∂L/∂v_i`.
    pub(crate) v: [T; N],
    /// `∂²L/∂q_i∂q_k`.
    pub(crate) qq: [[T; N]; N],
    /// `∂²L/∂q_i∂v_k`.
    pub(crate) qv: [[T; N]; N],
    /// `∂²L/∂v_i∂v_k`.
    pub(crate) vv: [[T; N]; N],
}

impl<const N: usize, T: Real> PointDerivatives<N, T> {
    /// One evaluation of `L` on a [`HyperDualArray`] with both
    /// infinitesimals seeded on all `2N` coordinates `(q, v)`: the value, the
    /// gradient (`ε1`) and the whole Hessian (`ε1ε2`) at once. Component
    /// `(a, b)` is the scalar hyper-dual evaluation seeded on `(a, b)` (bit
    /// for bit in `f64`); the blocks `qq` and `vv` are exactly symmetric.
    ///
    /// Above `N = 4` the `ε1` side is seeded on blocks of [`ROWS`] coordinates
    /// instead, one evaluation per block (`⌈2N/8⌉` in all): about the same
    /// arithmetic, but each number holds `1 + 8 + 2N + 16N` components
    /// instead of `(2N + 1)²` (34 kB at `N = 32`, which overflowed a 2 MiB
    /// thread stack).
    #[inline(always)]
    pub(crate) fn at<Sys: Lagrangian<N> + ?Sized>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> Self {
        if N > ROWS / 2 {
            return Self::by_rows(system, t, q, v);
        }
        type D<const N: usize, T> = HyperDualArray<Seeds<N, T>, Seeds<N, T>, T>;
        let seed = |x: T, slot: usize| {
            let mut d = D::<N, T>::from_re(x);
            *d.eps1.get_mut(slot) = T::one();
            *d.eps2.get_mut(slot) = T::one();
            d
        };
        let qd = core::array::from_fn(|i| seed(q[i], i));
        let vd = core::array::from_fn(|i| seed(v[i], N + i));
        let l = system.lagrangian(D::from_re(t), qd, vd);
        let h = &l.eps1eps2;
        let mut out = Self {
            value: l.re,
            q: l.eps1.a,
            v: l.eps1.b,
            qq: h.a.map(|row| row.a),
            qv: h.a.map(|row| row.b),
            vv: h.b.map(|row| row.b),
        };
        out.mirror();
        out
    }

    /// [`at`](Self::at) by blocks of [`ROWS`] rows of the Hessian.
    #[inline(always)]
    fn by_rows<Sys: Lagrangian<N> + ?Sized>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> Self {
        type D<const N: usize, T> = HyperDualArray<[T; ROWS], Seeds<N, T>, T>;
        let z = T::zero();
        let mut out = Self { value: z, q: [z; N], v: [z; N], qq: [[z; N]; N], qv: [[z; N]; N], vv: [[z; N]; N] };
        for first in (0..2 * N).step_by(ROWS) {
            // ε2 on every coordinate, ε1 on coordinates first … first + ROWS − 1.
            let seed = |x: T, slot: usize| {
                let mut d = D::<N, T>::from_re(x);
                *d.eps2.get_mut(slot) = T::one();
                if (first..first + ROWS).contains(&slot) {
                    d.eps1[slot - first] = T::one();
                }
                d
            };
            let qd = core::array::from_fn(|i| seed(q[i], i));
            let vd = core::array::from_fn(|i| seed(v[i], N + i));
            let l = system.lagrangian(D::from_re(t), qd, vd);
            (out.value, out.q, out.v) = (l.re, l.eps2.a, l.eps2.b);
            for (r, row) in l.eps1eps2.iter().enumerate() {
                match first + r {
                    a if a < N => (out.qq[a], out.qv[a]) = (row.a, row.b),
                    a if a < 2 * N => out.vv[a - N] = row.b,
                    _ => break,
                }
            }
        }
        out.mirror();
        out
    }

    /// Copies the upper triangles of `qq` and `vv` onto the lower ones. The
    /// triangles agree already in `f64` (they add the same products in
    /// swapped order); double-double addition is not commutative bit for
    /// bit, and the row blocks compute the two triangles in different
    /// evaluations.
    #[inline(always)]
    fn mirror(&mut self) {
        for i in 0..N {
            for k in 0..i {
                self.qq[i][k] = self.qq[k][i];
                self.vv[i][k] = self.vv[k][i];
            }
        }
    }
}

/// The discrete energy `Σ_j b_j E_L(c_j)` of a step of size `h` with increments `d`.
pub(super) fn step_energy<Sys, T, const N: usize, const S: usize, const R: usize>(
    system: &Sys,
    g: &Galerkin<S, R, T>,
    t0: T,
    h: T,
    base: (&[T; N], &[T; N]),
    d: &BlockVector<N, S, T>,
) -> T
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    let mut e = T::zero();
    for j in 0..R {
        let (t, q, v) = g.point(t0, h, base, d, j);
        let (l, _, lv) = point_gradient(system, t, q, v);
        let mut ej = -l;
        for i in 0..N {
            ej += v[i] * lv[i];
        }
        e += g.quadrature().weights()[j] * ej;
    }
    e
}

#[cfg(test)]
mod tests {
    //! The one-evaluation derivatives against the scalar hyper-dual ones they
    //! replaced (kept here as the reference), in `f64` and in `DoubleDouble`.

    use num_dual::HyperDual;

    use super::*;
    use crate::DoubleDouble;
    use crate::real::max_abs;

    /// The former `gradient_at`: `N` scalar hyper-dual evaluations, `q_i` on `ε1` and `v_i` on `ε2`.
    fn reference_gradient<Sys, T, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> ([T; N], [T; N])
    where
        Sys: Lagrangian<N>,
        T: Real,
    {
        let mut lq = [T::zero(); N];
        let mut lv = [T::zero(); N];
        for i in 0..N {
            let mut qd = q.map(HyperDual::from_re);
            let mut vd = v.map(HyperDual::from_re);
            qd[i].eps1 = T::one();
            vd[i].eps2 = T::one();
            let l = system.lagrangian(HyperDual::from_re(t), qd, vd);
            lq[i] = l.eps1;
            lv[i] = l.eps2;
        }
        (lq, lv)
    }

    /// The former `PointDerivatives::at`: `N(2N + 1)` scalar hyper-dual
    /// evaluations, one per pair `a ≤ b` of the `2N` coordinates `(q, v)`.
    fn reference_point<Sys, T, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) -> PointDerivatives<N, T>
    where
        Sys: Lagrangian<N>,
        T: Real,
    {
        let z = T::zero();
        let mut out = PointDerivatives {
            value: system.lagrangian(t, q, v),
            q: [z; N],
            v: [z; N],
            qq: [[z; N]; N],
            qv: [[z; N]; N],
            vv: [[z; N]; N],
        };
        let t = HyperDual::from_re(t);
        for a in 0..2 * N {
            for b in a..2 * N {
                let mut qd = q.map(HyperDual::from_re);
                let mut vd = v.map(HyperDual::from_re);
                if a < N {
                    qd[a].eps1 = T::one()
                } else {
                    vd[a - N].eps1 = T::one()
                }
                if b < N {
                    qd[b].eps2 = T::one()
                } else {
                    vd[b - N].eps2 = T::one()
                }
                let l = system.lagrangian(t, qd, vd);
                if b == a {
                    if a < N { out.q[a] = l.eps1 } else { out.v[a - N] = l.eps1 }
                }
                let x = l.eps1eps2;
                match (a < N, b < N) {
                    (true, true) => {
                        out.qq[a][b] = x;
                        out.qq[b][a] = x;
                    }
                    (true, false) => out.qv[a][b - N] = x,
                    (false, _) => {
                        out.vv[a - N][b - N] = x;
                        out.vv[b - N][a - N] = x;
                    }
                }
            }
        }
        out
    }

    struct Pendulum;

    impl Lagrangian<1> for Pendulum {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 1] = [false];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
            v[0] * v[0] * (0.5 * 1.3 * 0.64) + q[0].cos() * (1.3 * 9.81 * 0.8)
        }
    }

    struct DoublePendulum;

    impl Lagrangian<2> for DoublePendulum {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false; 2];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
            let (m1, m2, l1, l2, g) = (1.0, 1.5, 1.0, 0.7, 9.81);
            let kinetic = v[0] * v[0] * (0.5 * (m1 + m2) * l1 * l1)
                + v[1] * v[1] * (0.5 * m2 * l2 * l2)
                + v[0] * v[1] * (q[0] - q[1]).cos() * (m2 * l1 * l2);
            kinetic + q[0].cos() * ((m1 + m2) * g * l1) + q[1].cos() * (m2 * g * l2)
        }
    }

    /// Cartesian Kepler: a quotient and a square root.
    struct Kepler;

    impl Lagrangian<2> for Kepler {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false; 2];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
            (v[0] * v[0] + v[1] * v[1]) * 0.5 + (q[0] * q[0] + q[1] * q[1]).sqrt().recip() * 1.7
        }
    }

    /// A charged particle in a time-dependent, non-uniform field:
    /// `L = ½ m|v|² + e v·A(t, q) − e φ(q)`, so the `qv` block is full.
    struct Charged;

    impl Lagrangian<3> for Charged {
        const AUTONOMOUS: bool = false;
        const CYCLIC: [bool; 3] = [false; 3];
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 3], v: [D; 3]) -> D {
            let (x, y, z) = (q[0], q[1], q[2]);
            let b = (t * 0.3).cos() * 0.8 + 1.1;
            let a = [-y * b * 0.5, x * b * 0.5 + (x * z).sin() * 0.2, (x * y).atan() * (-t).exp()];
            let phi = (z * z + 1.0).ln() + (x / (y * y + 2.0)) * 0.4;
            (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) * (0.5 * 2.1) + (v[0] * a[0] + v[1] * a[1] + v[2] * a[2]) * 0.9
                - phi * 0.9
        }
    }

    /// Two particles in 3-D with a Morse bond, a velocity-dependent drag-free
    /// coupling and a wall: `N = 6` with every kind of operation.
    struct Molecule;

    impl Lagrangian<6> for Molecule {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 6] = [false; 6];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 6], v: [D; 6]) -> D {
            let d = [q[3] - q[0], q[4] - q[1], q[5] - q[2]];
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let morse = (D::one() - (-(r - 1.2) * 1.5).exp()).powi(2) * 3.0;
            let kinetic = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) * 0.5
                + (v[3] * v[3] + v[4] * v[4] + v[5] * v[5]) * 0.75
                + (v[0] * v[3] + v[1] * v[4]) * (d[2] / r).tanh() * 0.1;
            let wall = (q[2] + 3.0).powf(-2.5) + q[1].atan2(q[0] + 2.5).sinh() * 0.05;
            kinetic - morse - wall
        }
    }

    /// A chain of pendula with torsion springs: `N` large enough for the
    /// Hessian by blocks of rows.
    struct Chain<const N: usize>;

    impl<const N: usize> Lagrangian<N> for Chain<N> {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; N] = [false; N];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; N], v: [D; N]) -> D {
            let mut l = D::zero();
            for i in 0..N {
                l += v[i] * v[i] * (0.5 + 0.1 * i as f64) + q[i].cos() * 0.5 + (v[i] * q[i]).sin() * 0.05;
                if i + 1 < N {
                    l += (q[i + 1] - q[i]).cos() + v[i] * v[i + 1] * q[i].sin() * 0.2;
                }
            }
            l
        }
    }

    /// `|got − want| ≤ 8 ε scale` for every entry, `ε` the type's unit.
    fn check<T: Real>(what: &str, got: &[T], want: &[T], scale: f64) {
        for (k, (g, w)) in got.iter().zip(want).enumerate() {
            let err = (*g - *w).to_f64().abs();
            assert!(
                err <= 8.0 * T::EPSILON * scale,
                "{what}[{k}]: {g} against {w}, difference {err:e} (scale {scale:e})"
            );
        }
    }

    /// The new derivatives agree with the reference at `(t, q, v)` to the
    /// round-off of `T`, and the Hessian blocks `qq`, `vv` are symmetric bit for bit.
    fn agree<Sys: Lagrangian<N>, T: Real, const N: usize>(system: &Sys, t: T, q: [T; N], v: [T; N]) {
        let want = reference_point(system, t, q, v);
        let (want_lq, want_lv) = reference_gradient(system, t, q, v);
        let got = PointDerivatives::at(system, t, q, v);
        let (value, lq, lv) = point_gradient(system, t, q, v);
        let (lq2, lv2) = gradient_at(system, t, q, v);

        let gradient_scale = max_abs(&want.q).max(max_abs(&want.v)).max(want.value.to_f64().abs());
        check("value", &[got.value, value], &[want.value; 2], gradient_scale);
        check("L_q (hyper-dual)", &got.q, &want.q, gradient_scale);
        check("L_v (hyper-dual)", &got.v, &want.v, gradient_scale);
        check("L_q (dual)", &lq, &want_lq, gradient_scale);
        check("L_v (dual)", &lv, &want_lv, gradient_scale);
        assert_eq!((lq, lv), (lq2, lv2));
        let flat = |m: &[[T; N]; N]| m.iter().flatten().copied().collect::<Vec<T>>();
        let hessian_scale = max_abs(&flat(&want.qq)).max(max_abs(&flat(&want.qv))).max(max_abs(&flat(&want.vv)));
        assert!(hessian_scale > 0.0);
        check("L_qq", &flat(&got.qq), &flat(&want.qq), hessian_scale);
        check("L_qv", &flat(&got.qv), &flat(&want.qv), hessian_scale);
        check("L_vv", &flat(&got.vv), &flat(&want.vv), hessian_scale);
        for i in 0..N {
            for k in 0..N {
                assert!(got.qq[i][k] == got.qq[k][i] && got.vv[i][k] == got.vv[k][i], "asymmetric at ({i}, {k})");
            }
        }
        // The derivatives in `v` alone are those of the whole Hessian, bit
        // for bit (the Legendre transform at the start and the constant mass
        // inverse of the Galerkin steps are formed from them).
        let VelocityDerivatives { vv, qv, .. } = velocity_hessian(system, t, q, v);
        check("L_qv in v", &flat(&qv), &flat(&want.qv), hessian_scale);
        let (value, lv, mass) = velocity_derivatives(system, t, q, v);
        assert!(value == got.value, "value {value} against {}", got.value);
        for i in 0..N {
            assert!(lv[i] == got.v[i], "L_v[{i}]: {} against {}", lv[i], got.v[i]);
            for k in 0..N {
                assert!(mass[i][k] == vv[i][k], "mass matrix at ({i}, {k}): {} against {}", mass[i][k], vv[i][k]);
                assert!(mass[i][k] == got.vv[i][k], "mass matrix at ({i}, {k}) against the whole Hessian");
            }
        }
    }

    /// Points with every coordinate and velocity non-zero, from a seed.
    fn point<const N: usize>(seed: f64) -> (f64, [f64; N], [f64; N]) {
        let q = core::array::from_fn(|i| 0.4 * (seed + 1.3 * i as f64).sin() + 0.15 * (i as f64 + 1.0));
        let v = core::array::from_fn(|i| 0.9 * (2.1 * seed - 0.7 * i as f64).cos() - 0.2);
        (0.35 * seed, q, v)
    }

    /// Every system at several points, in `T` built from `f64` data by `lift`.
    fn all_systems<T: Real>(lift: impl Fn(f64) -> T + Copy) {
        for seed in [0.3, 1.7, -2.4, 4.1] {
            let lift_point = |(t, q, v): (f64, [f64; 1], [f64; 1])| (lift(t), q.map(lift), v.map(lift));
            let (t, q, v) = lift_point(point::<1>(seed));
            agree(&Pendulum, t, q, v);
            let (t, q, v) = point::<2>(seed);
            agree(&DoublePendulum, lift(t), q.map(lift), v.map(lift));
            agree(&Kepler, lift(t), q.map(lift), v.map(lift));
            let (t, q, v) = point::<3>(seed);
            agree(&Charged, lift(t), q.map(lift), v.map(lift));
            let (t, q, v) = point::<6>(seed);
            agree(&Molecule, lift(t), q.map(lift), v.map(lift));
            // 2N = 18: two full blocks of rows and a partial one.
            let (t, q, v) = point::<9>(seed);
            agree(&Chain::<9>, lift(t), q.map(lift), v.map(lift));
            // N = 17: the mass matrix by three blocks of rows, the last partial.
            let (t, q, v) = point::<17>(seed);
            agree(&Chain::<17>, lift(t), q.map(lift), v.map(lift));
        }
    }

    #[test]
    fn one_evaluation_agrees_with_scalar_hyper_duals_in_f64() {
        all_systems(|x| x);
    }

    #[test]
    fn one_evaluation_agrees_with_scalar_hyper_duals_in_double_double() {
        // Data with a non-zero low part, so the low halves take part.
        all_systems(|x| DoubleDouble::from(x) / DoubleDouble::from(3.0) * DoubleDouble::from(3.0 + 1e-9));
    }

    /// Independent of any dual numbers: the Kepler derivatives by hand.
    #[test]
    fn kepler_derivatives_by_hand() {
        let (q, v) = ([0.6, -0.8], [0.3, 1.1]);
        let p = PointDerivatives::at(&Kepler, 0.0, q, v);
        // r = 1, L = ½|v|² + 1.7/r, L_q = −1.7 q/r³, L_qq = 1.7(3 q qᵀ − I)/r³.
        assert!((p.value - (0.5 * (0.09 + 1.21) + 1.7)).abs() < 1e-15);
        for i in 0..2 {
            assert!((p.q[i] + 1.7 * q[i]).abs() < 1e-15 && p.v[i] == v[i]);
            for k in 0..2 {
                let delta = if i == k { 1.0 } else { 0.0 };
                assert!((p.qq[i][k] - 1.7 * (3.0 * q[i] * q[k] - delta)).abs() < 1e-14);
                assert_eq!((p.qv[i][k], p.vv[i][k]), (0.0, delta));
            }
        }
    }
}
