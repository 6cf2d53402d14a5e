//! The linearisation of one fixed step with respect to the state and the
//! parameters, and of the initial Legendre transform.
//!
//! Every step the sensitivities differentiate is made of Galerkin steps
//! (docs/theory.md §5): a Galerkin rule of degree `s` is one; a one-point
//! rule (midpoint, trapezoid, α-β) is the rule of degree 1 whose two
//! quadrature points of weight ½ are its own
//! ([`DiscreteLagrangian::galerkin_points`](crate::DiscreteLagrangian::galerkin_points),
//! the table its double-double path runs on); a composition is the product
//! of its trapezoid sub-steps. A step of degree `s` from `(t_k, q_k, p_k)`
//! solves for the node increments `D_m = Q_m − q_k`, `m = 1 … s`,
//!
//! ```text
//! p_k + ∂A/∂Q_0 + F^0 = 0      ∂A/∂Q_m + F^m = 0  (m = 1 … s − 1)
//! q_{k+1} = q_k + D_s          p_{k+1} = ∂A/∂Q_s + F^s
//! A   = h Σ_j b_j L(t_k + c_j h, q_k + Σ_m ℓ_m(c_j) D_m, Σ_m ℓ_m'(c_j) D_m / h; θ)
//! F^m = h Σ_j b_j ℓ_m(c_j) F_j,   F = Q − ∂R/∂v
//! ```
//!
//! and by the implicit function theorem, with `G` the `s` block rows of the
//! step's equations,
//!
//! ```text
//! dD = −G_D⁻¹ (G_q dq_k + E dp_k + G_θ dθ),   E = (I, 0, …, 0)ᵀ
//! ```
//!
//! where `G_D` is the Newton block the stepper factors. Every block follows
//! by the chain rule from the derivatives of `(L_q + F, L_v)` in
//! `(q, v, θ)` at the quadrature points, taken with nested dual numbers:
//! exact, no differences.

use nalgebra::{DMatrix, SMatrix};
use num_dual::{Dual, Dual64};

use super::Parametric;
use crate::derivatives::Segment;
use crate::galerkin::{Galerkin, as_galerkin};
use crate::problem::OnePoint;
use crate::symplectic::TangentMap;
use crate::system::Scalar;

/// The largest degree of a step a [`Piece`] holds (the degrees
/// [`Scheme`](crate::problem::Scheme) offers).
pub const MAX_DEGREE: usize = 8;

/// The quadrature and Lagrange basis of a Galerkin rule, as the stepper
/// tabulates them: points `c_j`, weights `b_j`, and `ℓ_0 … ℓ_s` with their
/// derivatives at each point (`ℓ_0 = 1 − Σ_{m≥1} ℓ_m`, rounded as the step
/// rounds it).
#[derive(Clone, Debug, PartialEq)]
pub struct Rule {
    degree: usize,
    points: Vec<f64>,
    weights: Vec<f64>,
    /// `ℓ_m(c_j)` at `j (s + 1) + m`.
    basis: Vec<f64>,
    /// `ℓ_m'(c_j)` at `j (s + 1) + m`.
    basis_d: Vec<f64>,
}

impl Rule {
    /// The tables of a Galerkin rule (degree at most [`MAX_DEGREE`]). A
    /// point given twice (the midpoint rule's, the α-β rule's) is one point
    /// with the sum of the weights: the derivatives there are taken once.
    pub fn galerkin<const S: usize, const R: usize>(g: &Galerkin<S, R>) -> Self {
        let q = g.quadrature();
        let mut out = Self {
            degree: S,
            points: Vec::with_capacity(R),
            weights: Vec::with_capacity(R),
            basis: Vec::with_capacity(R * (S + 1)),
            basis_d: Vec::with_capacity(R * (S + 1)),
        };
        for j in 0..R {
            if let Some(k) = out.points.iter().position(|&c| c == q.nodes()[j]) {
                out.weights[k] += q.weights()[j];
                continue;
            }
            out.points.push(q.nodes()[j]);
            out.weights.push(q.weights()[j]);
            out.basis.push(g.row[j][0]);
            out.basis.extend_from_slice(&g.col[j]);
            out.basis_d.push(g.row_d[j][0]);
            out.basis_d.extend_from_slice(&g.col_d[j]);
        }
        out
    }

    /// A one-point rule as the Galerkin rule of degree 1 with its points.
    pub fn one_point(rule: &OnePoint) -> Self {
        match rule {
            OnePoint::Midpoint => Self::galerkin(&as_galerkin::<_, f64>(&crate::Midpoint)),
            OnePoint::Trapezoid => Self::galerkin(&as_galerkin::<_, f64>(&crate::Trapezoid)),
            OnePoint::AlphaBeta(m) => Self::galerkin(&as_galerkin::<_, f64>(m)),
        }
    }

    /// The degree `s` of the step polynomial.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// The number of distinct quadrature points.
    pub(super) fn point_count(&self) -> usize {
        self.points.len()
    }

    /// `c_j`, point `j` in the step's unit interval.
    pub(super) fn abscissa(&self, j: usize) -> f64 {
        self.points[j]
    }

    /// `b_j`, the weight of point `j`.
    pub(super) fn weight(&self, j: usize) -> f64 {
        self.weights[j]
    }

    /// `ℓ_m(c_j)`.
    pub(super) fn l(&self, j: usize, m: usize) -> f64 {
        self.basis[j * (self.degree + 1) + m]
    }

    /// `ℓ_m'(c_j)`.
    pub(super) fn dl(&self, j: usize, m: usize) -> f64 {
        self.basis_d[j * (self.degree + 1) + m]
    }

    /// The time of point `j` of `piece`.
    pub(super) fn time<const N: usize>(&self, piece: &Piece<N>, j: usize) -> f64 {
        piece.t0 + self.points[j] * piece.h
    }

    /// Time, position and velocity at point `j` of `piece`.
    pub(super) fn point<const N: usize>(&self, piece: &Piece<N>, j: usize) -> (f64, [f64; N], [f64; N]) {
        let (s, h) = (self.degree, piece.h);
        let q = core::array::from_fn(|i| {
            let mut x = 0.0;
            for m in 1..=s {
                x += self.l(j, m) * piece.d[m - 1][i];
            }
            piece.q0[i] + x
        });
        let v = core::array::from_fn(|i| {
            let mut x = 0.0;
            for m in 1..=s {
                x += self.dl(j, m) * piece.d[m - 1][i];
            }
            x / h
        });
        (self.time(piece, j), q, v)
    }

    /// The step action `A` of `piece` at parameters `theta`.
    pub fn action<S: Parametric<N, P>, const N: usize, const P: usize>(
        &self,
        system: &S,
        theta: &[f64; P],
        piece: &Piece<N>,
    ) -> f64 {
        let mut sum = 0.0;
        for j in 0..self.points.len() {
            let (t, q, v) = self.point(piece, j);
            sum += self.weights[j] * system.lagrangian_with(theta, t, q, v);
        }
        sum * piece.h
    }
}

/// One Galerkin step as the stepper took it: `t_k`, `h`, `q_k` and the node
/// increments `D_1 … D_s` (the first `s` rows of `d`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece<const N: usize> {
    /// `t_k`.
    pub t0: f64,
    /// The step size.
    pub h: f64,
    /// `q_k`.
    pub q0: [f64; N],
    /// `D_m = Q_m − q_k` in row `m − 1`; `D_s = q_{k+1} − q_k`.
    pub d: [[f64; N]; MAX_DEGREE],
}

impl<const N: usize> Piece<N> {
    /// The Galerkin step a driver kept: from `q_k = q0 + carry` (the
    /// compensated sum), with the increments `d`.
    pub(crate) fn kept(t0: f64, h: f64, q0: [f64; N], carry: [f64; N], d: &[[f64; N]]) -> Self {
        let mut piece = Self { t0, h, q0: core::array::from_fn(|i| q0[i] + carry[i]), d: [[0.0; N]; MAX_DEGREE] };
        piece.d[..d.len()].copy_from_slice(d);
        piece
    }

    /// A step of degree 1 over `seg`.
    pub fn segment(seg: &Segment<N>) -> Self {
        let mut d = [[0.0; N]; MAX_DEGREE];
        d[0] = seg.dq;
        Self { t0: seg.t0, h: seg.h, q0: seg.q0, d }
    }
}

/// `Q − ∂R/∂v` at parameters `theta`.
pub(super) fn generalized_force<S, D, const N: usize, const P: usize>(
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

/// `(q, v, θ)` as dual numbers seeded in direction `c` of `(q, v, θ)`.
#[allow(clippy::type_complexity)]
pub(super) fn seeded<const N: usize, const P: usize>(
    q: &[f64; N],
    v: &[f64; N],
    theta: &[f64; P],
    c: usize,
) -> ([Dual64; N], [Dual64; N], [Dual64; P]) {
    let (mut qo, mut vo, mut tho) = (q.map(Dual64::from_re), v.map(Dual64::from_re), theta.map(Dual64::from_re));
    match c {
        c if c < N => qo[c].eps = 1.0,
        c if c < 2 * N => vo[c - N].eps = 1.0,
        c => tho[c - 2 * N].eps = 1.0,
    }
    (qo, vo, tho)
}

/// `∂(L_q + F)/∂(q, v, θ)` and `∂L_v/∂(q, v, θ)` at one point, each
/// `N × (2N + P)`: an outer dual seeds the column, an inner one takes the
/// gradient of `L`.
fn point_jacobians<S: Parametric<N, P>, const N: usize, const P: usize>(
    system: &S,
    theta: &[f64; P],
    (t, q, v): (f64, [f64; N], [f64; N]),
) -> (DMatrix<f64>, DMatrix<f64>) {
    let k = 2 * N + P;
    let (mut a, mut b) = (DMatrix::zeros(N, k), DMatrix::zeros(N, k));
    let one = Dual64::from_re(1.0);
    for c in 0..k {
        let (qo, vo, tho) = seeded(&q, &v, theta, c);
        let (to, th) = (Dual64::from_re(t), tho.map(Dual::from_re));
        let (qi, vi) = (qo.map(Dual::from_re), vo.map(Dual::from_re));
        for i in 0..N {
            let mut x = qi;
            x[i].eps = one;
            a[(i, c)] = system.lagrangian_with(&th, Dual::from_re(to), x, vi).eps.eps;
            let mut y = vi;
            y[i].eps = one;
            b[(i, c)] = system.lagrangian_with(&th, Dual::from_re(to), qi, y).eps.eps;
        }
        if S::HAS_FORCE || S::HAS_DISSIPATION {
            let f = generalized_force(system, &tho, to, qo, vo);
            for i in 0..N {
                a[(i, c)] += f[i].eps;
            }
        }
    }
    (a, b)
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
    /// The Jacobians of the step made of `pieces` (one for a one-point or
    /// Galerkin step, the sub-steps in order for a composition), each a step
    /// of `rule`, at parameters `theta`; `None` where a Newton block is
    /// singular or a derivative is not finite.
    pub fn of_step<S: Parametric<N, P>>(
        system: &S,
        rule: &Rule,
        theta: &[f64; P],
        pieces: &[Piece<N>],
    ) -> Option<Self> {
        let (first, rest) = pieces.split_first()?;
        let mut out = Self::of_piece(system, rule, theta, first)?;
        for piece in rest {
            out = out.then(&Self::of_piece(system, rule, theta, piece)?);
        }
        Some(out)
    }

    /// The Jacobians of one Galerkin step of `rule` (see the
    /// [module](self)).
    pub fn of_piece<S: Parametric<N, P>>(system: &S, rule: &Rule, theta: &[f64; P], piece: &Piece<N>) -> Option<Self> {
        let (s, h) = (rule.degree, piece.h);
        let nx = s * N;
        // Rows ρ = 0 … s (row s: p_{k+1}), then the sum Σ_ρ R_ρ of the rows;
        // columns the unknowns D_1 … D_s, and (q_k, θ).
        let mut g_d = DMatrix::<f64>::zeros(nx + 2 * N, nx);
        let mut g_z = DMatrix::<f64>::zeros(nx + 2 * N, N + P);
        for j in 0..rule.points.len() {
            let (a, b) = point_jacobians(system, theta, rule.point(piece, j));
            let w = rule.weights[j] * h;
            for rho in 0..=s + 1 {
                // Σ_ρ ℓ_ρ = 1 and Σ_ρ ℓ_ρ' = 0: the sum of the rows is
                // h Σ_j b_j (L_q + F), without the 1/h of each row.
                let (r, rd) = if rho > s { (w, 0.0) } else { (w * rule.l(j, rho), w * rule.dl(j, rho) / h) };
                for i in 0..N {
                    let row = rho * N + i;
                    for c in 0..2 * N + P {
                        let x = r * a[(i, c)] + rd * b[(i, c)];
                        if x == 0.0 {
                            continue;
                        }
                        match c {
                            c if c < N => {
                                g_z[(row, c)] += x;
                                for m in 1..=s {
                                    g_d[(row, (m - 1) * N + c)] += x * rule.l(j, m);
                                }
                            }
                            c if c < 2 * N => {
                                for m in 1..=s {
                                    g_d[(row, (m - 1) * N + c - N)] += x * rule.dl(j, m) / h;
                                }
                            }
                            c => g_z[(row, c - N)] += x,
                        }
                    }
                }
            }
        }
        // dD/d(q_k, p_k, θ) = −G_D⁻¹ [G_q | E | G_θ].
        let mut rhs = DMatrix::<f64>::zeros(nx, 2 * N + P);
        rhs.view_mut((0, 0), (nx, N)).copy_from(&g_z.view((0, 0), (nx, N)));
        rhs.view_mut((0, 2 * N), (nx, P)).copy_from(&g_z.view((0, N), (nx, P)));
        for i in 0..N {
            rhs[(i, N + i)] = 1.0;
        }
        let dd = -g_d.rows(0, nx).into_owned().lu().solve(&rhs)?;
        // q_{k+1} = q_k + D_s;  p_{k+1} = R_s = p_k + Σ_ρ R_ρ (the rows
        // ρ < s vanish but for R_0 = −p_k), of order h where R_s is of
        // order 1/h: differentiated in this form, the increment of p keeps
        // its relative accuracy.
        let mut dq1 = dd.rows(nx - N, N).into_owned();
        for i in 0..N {
            dq1[(i, i)] += 1.0;
        }
        let mut dp1 = g_d.rows(nx + N, N) * &dd;
        let mut top = dp1.view_mut((0, 0), (N, N));
        top += g_z.view((nx + N, 0), (N, N));
        let mut tail = dp1.view_mut((0, 2 * N), (N, P));
        tail += g_z.view((nx + N, N), (N, P));
        for i in 0..N {
            dp1[(i, N + i)] += 1.0;
        }
        if !dq1.iter().chain(dp1.iter()).all(|x| x.is_finite()) {
            return None;
        }
        let block = |m: &DMatrix<f64>, c: usize| SMatrix::<f64, N, N>::from_fn(|a, b| m[(a, c + b)]);
        let params = |m: &DMatrix<f64>| SMatrix::<f64, N, P>::from_fn(|a, b| m[(a, 2 * N + b)]);
        Some(Self {
            state: TangentMap {
                dq_dq: block(&dq1, 0),
                dq_dp: block(&dq1, N),
                dp_dq: block(&dp1, 0),
                dp_dp: block(&dp1, N),
            },
            dq_dtheta: params(&dq1),
            dp_dtheta: params(&dp1),
        })
    }

    /// The step `next ∘ self`: the chain rule through the node between them.
    pub fn then(&self, next: &Self) -> Self {
        let (a, b) = (&self.state, &next.state);
        Self {
            state: TangentMap {
                dq_dq: b.dq_dq * a.dq_dq + b.dq_dp * a.dp_dq,
                dq_dp: b.dq_dq * a.dq_dp + b.dq_dp * a.dp_dp,
                dp_dq: b.dp_dq * a.dq_dq + b.dp_dp * a.dp_dq,
                dp_dp: b.dp_dq * a.dq_dp + b.dp_dp * a.dp_dp,
            },
            dq_dtheta: b.dq_dq * self.dq_dtheta + b.dq_dp * self.dp_dtheta + next.dq_dtheta,
            dp_dtheta: b.dp_dq * self.dq_dtheta + b.dp_dp * self.dp_dtheta + next.dp_dtheta,
        }
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
    use crate::discrete::{AlphaBeta, DiscreteLagrangian, Midpoint, Trapezoid};
    use crate::galerkin::{NodeFamily, Quadrature};
    use crate::sensitivity::fixtures::Pendulum;

    const SYSTEM: Pendulum = Pendulum { theta: [1.3, 9.81] };

    fn segment() -> Segment<1> {
        Segment { t0: 0.7, h: 0.05, q0: [0.4], dq: [0.03] }
    }

    /// The degree-1 form against each rule's own action.
    fn same_action<M: DiscreteLagrangian>(method: M, rule: OnePoint) {
        let seg = segment();
        let own = method.action(&SYSTEM, seg.t0, seg.h, seg.q0, seg.dq);
        let here = Rule::one_point(&rule).action(&SYSTEM, &SYSTEM.parameters(), &Piece::segment(&seg));
        assert!((own - here).abs() <= 1e-15 * own.abs(), "{rule:?}: {own} vs {here}");
    }

    #[test]
    fn the_degree_one_form_is_each_one_point_rule() {
        same_action(Midpoint, OnePoint::Midpoint);
        same_action(Trapezoid, OnePoint::Trapezoid);
        let ab = AlphaBeta::new(0.3).unwrap();
        same_action(ab, OnePoint::AlphaBeta(ab));
    }

    #[test]
    fn the_state_block_is_the_tangent_map_of_a_one_point_rule() {
        let (seg, theta) = (segment(), SYSTEM.parameters());
        let j = StepJacobian::of_piece(&SYSTEM, &Rule::one_point(&OnePoint::Midpoint), &theta, &Piece::segment(&seg))
            .unwrap();
        let m = crate::symplectic::tangent_map(&SYSTEM, &Midpoint, &seg).unwrap();
        let gap = (j.state.matrix() - m.matrix()).amax();
        assert!(gap <= 1e-13 * m.matrix().amax(), "{gap:e}");
    }

    /// Degree 3 with Gauss–Legendre and Gauss–Lobatto quadrature at nodes
    /// that solve no step: the implicit-function formulas hold at any point.
    fn galerkin_state_block<const R: usize>(g: Galerkin<3, R>) {
        let d = [[0.011], [0.021], [0.03]];
        let (t0, h, q0) = (0.7, 0.05, [0.4]);
        let mut piece = Piece { t0, h, q0, d: [[0.0]; MAX_DEGREE] };
        piece.d[..3].copy_from_slice(&d);
        let j = StepJacobian::of_piece(&SYSTEM, &Rule::galerkin(&g), &SYSTEM.parameters(), &piece).unwrap();
        let m = crate::galerkin::tangent_map(&SYSTEM, &g, t0, h, q0, &d).unwrap();
        // Two eliminations of a block with entries of order 1/h, from
        // differently rounded Hessians (measured 2.6e-13).
        let gap = (j.state.matrix() - m.matrix()).amax();
        assert!(gap <= 1e-12 * m.matrix().amax(), "{gap:e}");
        let defect = j.state.symplecticity_defect();
        assert!(defect <= 1e-12, "{defect:e}");
    }

    #[test]
    fn the_state_block_is_the_tangent_map_of_a_galerkin_rule() {
        galerkin_state_block(Galerkin::<3, 3>::gauss());
        galerkin_state_block(Galerkin::<3, 4>::new(NodeFamily::GaussLobatto, Quadrature::gauss_lobatto()));
    }

    #[test]
    fn a_composed_step_is_the_product_of_its_pieces() {
        let (seg, theta, rule) = (segment(), SYSTEM.parameters(), Rule::one_point(&OnePoint::Trapezoid));
        let second = Segment { t0: seg.t1(), h: 0.02, q0: seg.q1(), dq: [-0.01] };
        let pieces = [Piece::segment(&seg), Piece::segment(&second)];
        let j = StepJacobian::of_step(&SYSTEM, &rule, &theta, &pieces).unwrap();
        let (a, b) = (
            StepJacobian::of_piece(&SYSTEM, &rule, &theta, &pieces[0]).unwrap(),
            StepJacobian::of_piece(&SYSTEM, &rule, &theta, &pieces[1]).unwrap(),
        );
        let product = b.state.matrix() * a.state.matrix();
        assert!((j.state.matrix() - &product).amax() <= 1e-15 * product.amax());
        // ∂x_2/∂θ = M_2 ∂x_1/∂θ + ∂Φ_2/∂θ, here in the first parameter.
        let want = b.state.dq_dq[(0, 0)] * a.dq_dtheta[(0, 0)]
            + b.state.dq_dp[(0, 0)] * a.dp_dtheta[(0, 0)]
            + b.dq_dtheta[(0, 0)];
        assert!((j.dq_dtheta[(0, 0)] - want).abs() <= 1e-15 * want.abs());
        assert!(StepJacobian::of_step(&SYSTEM, &rule, &theta, &[]).is_none());
    }
}
