//! The transposed linearisation of one fixed step: `Φ_xᵀ λ` and `Φ_θᵀ λ`
//! for a costate `λ = (λ_q, λ_p)` at the step's end, by one transposed
//! solve with the step's Newton matrix and products of second derivatives
//! with vectors, without forming `Φ_x`.
//!
//! In the notation of the [linearisation](super::linearisation), a step of
//! degree `s` has the rows `R_ρ = ∂A/∂Q_ρ + F^ρ` (`ρ = 0 … s`), the
//! equations `G_0 = p_k + R_0`, `G_m = R_m` (`0 < m < s`) in the node
//! increments `D`, and the end node `q_{k+1} = q_k + D_s`,
//! `p_{k+1} = R_s`. Differentiating `λ_qᵀ q_{k+1} + λ_pᵀ p_{k+1}` and
//! eliminating `dD` with the solution `μ` of one transposed system,
//!
//! ```text
//! G_Dᵀ μ = e_s λ_q + R_{s,D}ᵀ λ_p
//! ψ = Σ_ρ ω_ρ·R_ρ,    ω = (−μ_0, …, −μ_{s−1}, λ_p)
//! Φ_xᵀ λ = (λ_q + ∂ψ/∂q_k,  −μ_0),    Φ_θᵀ λ = ∂ψ/∂θ
//! ```
//!
//! `ψ` is a sum over the quadrature points `c_j` of
//! `h b_j (w_q·(L_q + F) + w_v·L_v)` with `w_q = Σ_ρ ℓ_ρ(c_j) ω_ρ` and
//! `w_v = Σ_ρ ℓ_ρ'(c_j) ω_ρ / h`, formed as
//! `w_q = ω_0 + Σ_{m≥1} ℓ_m (ω_m − ω_0)`, `w_v = Σ_{m≥1} ℓ_m' (ω_m − ω_0) / h`
//! (`ℓ_0 = 1 − Σ_{m≥1} ℓ_m`, as the step forms its `q_k` row). Its
//! gradient in `(q_k, D)` is `K_jᵀ (w_q, w_v)`, with `K_j` the Jacobian of `(L_q + F, L_v)` in
//! `(q, v)` at the point, from which `G_D` is assembled too; its gradient
//! in `θ` is one evaluation of `L` on a hyper-dual number with `ε1` along
//! `(w_q, w_v)` and `ε2` on `θ` (the mixed part is `∂/∂θ (∇L·w)`), plus one
//! first-order evaluation of the forces on `θ`. Per point and step: one
//! evaluation for `K_j`, one for `θ`; per step one factorisation of `G_D`
//! and one transposed solve. A one-point step without forces of a few
//! coordinates takes `K_j` and `∂(L_q, L_v)/∂θ` from one evaluation instead
//! (`ε1` on `(q, v)`, `ε2` on `(q, v, θ)`), so that `∂ψ/∂θ` is a product
//! with that block, and sums over its one or two points in fixed-size
//! arrays (`one_point_piece`): the reverse step of the composed trapezoid
//! sub-steps of a double pendulum costs about a third less. The buffers are
//! allocated once, by [`Pullback::new`].
//!
//! The rows `R_ρ` are of order `1/h`, their sum is not
//! (`Σ_ρ R_ρ = h Σ_j b_j (L_q + F)`), and `ω_ρ` is `λ_p` plus `O(h)`: the
//! part of the costate carried by `λ_q` lives in the differences of the
//! `ω_ρ`. So the unknowns are those differences, `ω_ρ = λ_p + h η_ρ`
//! (`η_s = 0`), and with `ψ_λ = λ_p·Σ_ρ R_ρ`
//!
//! ```text
//! G_Dᵀ η = −(e_s λ_q + ∂ψ_λ/∂D) / h
//! ∂ψ/∂q_k = ∂ψ_λ/∂q_k + h ∂(Σ_ρ η_ρ·R_ρ)/∂q_k,    λ_p ← λ_p + h η_0
//! ```
//!
//! with every term of the size of the result. Solving for `μ` itself
//! leaves `ω_m − ω_0`, and with them the part of `λ_q`, with a relative
//! error of order `ε/h`, which adds up along a run (measured on the double
//! pendulum, `h = 1e-3`, 10⁴ Galerkin `s = 3` steps: the pairing of adjoint
//! and forward sensitivities drifts by 1.7e-12 solving for `μ`, 1.7e-14
//! solving for `η`, with the forward linearisation differentiating
//! `p_{k+1} = p_k + Σ_ρ R_ρ` for the same reason: the unit test
//! `the_galerkin_adjoint_keeps_the_pairing_over_a_long_run`).
//!
//! Above [`Derivatives::FORWARD_MAX_N`](crate::Derivatives::FORWARD_MAX_N)
//! coordinates (where the stepper takes one-point steps without forces in
//! reverse mode) `K_j` would be a dense `2N × 2N` block: there the action
//! `a(q_k, D, θ)` of the step is recorded on a [`Tape`] instead, and so it
//! is below for a one-point step without forces whose Newton matrix has a
//! narrow band (`narrow`), where the dense block costs more. With
//! `R_0 = a_q − a_D` and `R_1 = a_D`, the Newton matrix is
//! `G_D = a_qD − a_DD`, taken in its band by one compressed second-order
//! sweep seeded on `D` (the pattern [`Lagrangian::COUPLING`] proves). The
//! unknowns are the differences here too: with `ψ_λ = λ_p·(R_0 + R_1) =
//! λ_p·a_q` the system is `G_Dᵀ η = −(λ_q + a_Dq λ_p)/h`, and
//! `ψ = ∇a·w` with `w = (λ_p + h η, −h η, 0)`, so that `∂ψ/∂(q_k, θ)` is
//! one Hessian–vector product, one more sweep ([`Seeds::Along`]), and
//! `λ_p ← λ_p + h η`. Per step: `O(N)` work for a banded pattern, and the
//! matrix solved in its band.

use super::Parametric;
use super::linearisation::{Piece, Rule, generalized_force};
use crate::banded::{StepMatrix, StepSolver};
use crate::error::Error;
use crate::galerkin::PointDerivatives;
use crate::hyperdual::{DualArray, HyperDualArray, Pair};
use crate::structure::Pattern;
use crate::system::{Lagrangian, Scalar};
use crate::tape::{Seeds, Tape, Var};

/// A parametric system at parameters `theta`, as a [`Lagrangian`]: the
/// Hessian of `L_θ` in `(q, v)` is taken by the code that takes the
/// Hessian of any Lagrangian ([`PointDerivatives`]).
struct At<'s, S, const P: usize> {
    system: &'s S,
    theta: [f64; P],
}

impl<S: Parametric<N, P>, const N: usize, const P: usize> Lagrangian<N> for At<'_, S, P> {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const CYCLIC: [bool; N] = S::CYCLIC;

    #[inline(always)]
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> D {
        self.system.lagrangian_with(&self.theta.map(D::from), t, q, v)
    }
}

/// `K = ∂(L_q + F, L_v)/∂(q, v)` at one point into `out` (`2N × 2N`,
/// row-major): one hyper-dual evaluation of `L`, and one first-order
/// evaluation of the forces where there are any. Not inlined: its `N × N`
/// blocks stay in its own stack frame, which the large systems' path never
/// enters.
#[inline(never)]
fn point_jacobian<S: Parametric<N, P>, const N: usize, const P: usize>(
    system: &S,
    theta: &[f64; P],
    (t, q, v): (f64, [f64; N], [f64; N]),
    out: &mut [f64],
) {
    let n2 = 2 * N;
    let d = PointDerivatives::at(&At { system, theta: *theta }, t, q, v);
    for i in 0..N {
        for k in 0..N {
            out[i * n2 + k] = d.qq[i][k];
            out[i * n2 + N + k] = d.qv[i][k];
            out[(N + i) * n2 + k] = d.qv[k][i];
            out[(N + i) * n2 + N + k] = d.vv[i][k];
        }
    }
    if S::HAS_FORCE || S::HAS_DISSIPATION {
        type D<const N: usize> = DualArray<Pair<[f64; N], [f64; N]>>;
        let qd = core::array::from_fn(|i| D::<N>::variable(q[i], i));
        let vd = core::array::from_fn(|i| D::<N>::variable(v[i], N + i));
        let f = generalized_force(system, &theta.map(D::<N>::from_re), D::<N>::from_re(t), qd, vd);
        for i in 0..N {
            for k in 0..N {
                out[i * n2 + k] += f[i].eps.a[k];
                out[i * n2 + N + k] += f[i].eps.b[k];
            }
        }
    }
}

/// The largest system whose one-point steps without forces take the fused
/// pullback ([`Pullback::one_point_piece`]): its point blocks hold
/// `2N (2N + P)` mixed derivatives in every value of the evaluation, where
/// the general path's `K_j` holds `4N²` and its `θ` product `P`.
const FUSED_MAX_N: usize = 4;

/// The second derivatives of `L` at one point of a one-point step: rows
/// `L_q` and `L_v`, columns `q`, `v` and `θ` (`qv[i][k] = ∂L_q_i/∂v_k`,
/// `vq[i][k] = ∂L_v_i/∂q_k`, `qt[i][j] = ∂L_q_i/∂θ_j`).
#[derive(Clone, Copy)]
struct PointBlocks<const N: usize, const P: usize> {
    qq: [[f64; N]; N],
    qv: [[f64; N]; N],
    vq: [[f64; N]; N],
    vv: [[f64; N]; N],
    qt: [[f64; P]; N],
    vt: [[f64; P]; N],
}

impl<const N: usize, const P: usize> PointBlocks<N, P> {
    const ZERO: Self = Self {
        qq: [[0.0; N]; N],
        qv: [[0.0; N]; N],
        vq: [[0.0; N]; N],
        vv: [[0.0; N]; N],
        qt: [[0.0; P]; N],
        vt: [[0.0; P]; N],
    };
}

/// [`PointBlocks`] at `(t, q, v)`: one evaluation of `L_θ` on a hyper-dual
/// number with `ε1` on `(q, v)` and `ε2` on `(q, v, θ)`.
#[inline(never)]
fn point_blocks<S: Parametric<N, P>, const N: usize, const P: usize>(
    system: &S,
    theta: &[f64; P],
    (t, q, v): (f64, [f64; N], [f64; N]),
) -> PointBlocks<N, P> {
    type H<const N: usize, const P: usize> =
        HyperDualArray<Pair<[f64; N], [f64; N]>, Pair<Pair<[f64; N], [f64; N]>, [f64; P]>>;
    let seeded = |x: f64, slot: usize| {
        let mut d = H::<N, P>::from_re(x);
        if slot < N {
            d.eps1.a[slot] = 1.0;
            d.eps2.a.a[slot] = 1.0;
        } else {
            d.eps1.b[slot - N] = 1.0;
            d.eps2.a.b[slot - N] = 1.0;
        }
        d
    };
    let qd = core::array::from_fn(|i| seeded(q[i], i));
    let vd = core::array::from_fn(|i| seeded(v[i], N + i));
    let th = core::array::from_fn(|j| {
        let mut d = H::<N, P>::from_re(theta[j]);
        d.eps2.b[j] = 1.0;
        d
    });
    let l = system.lagrangian_with(&th, H::<N, P>::from_re(t), qd, vd);
    let m = &l.eps1eps2;
    let mut out = PointBlocks::<N, P>::ZERO;
    for i in 0..N {
        for k in 0..N {
            out.qq[i][k] = m.a[i].a.a[k];
            out.qv[i][k] = m.a[i].a.b[k];
            out.vq[i][k] = m.b[i].a.a[k];
            out.vv[i][k] = m.b[i].a.b[k];
        }
        out.qt[i] = m.a[i].b;
        out.vt[i] = m.b[i].b;
    }
    out
}

/// `∂/∂θ (w_q·(L_q + F) + w_v·L_v)` at one point.
fn theta_product<S: Parametric<N, P>, const N: usize, const P: usize>(
    system: &S,
    theta: &[f64; P],
    (t, q, v): (f64, [f64; N], [f64; N]),
    wq: &[f64; N],
    wv: &[f64; N],
) -> [f64; P] {
    type H<const P: usize> = HyperDualArray<[f64; 1], [f64; P]>;
    let th: [H<P>; P] = core::array::from_fn(|j| {
        let mut x = H::<P>::from_re(theta[j]);
        x.eps2[j] = 1.0;
        x
    });
    let along = |x: f64, w: f64| {
        let mut d = H::<P>::from_re(x);
        d.eps1[0] = w;
        d
    };
    let qd = core::array::from_fn(|i| along(q[i], wq[i]));
    let vd = core::array::from_fn(|i| along(v[i], wv[i]));
    let l = system.lagrangian_with(&th, H::<P>::from_re(t), qd, vd);
    let mut out: [f64; P] = core::array::from_fn(|j| l.mixed(0, j));
    if S::HAS_FORCE || S::HAS_DISSIPATION {
        let th: [DualArray<[f64; P]>; P] = core::array::from_fn(|j| DualArray::variable(theta[j], j));
        let f =
            generalized_force(system, &th, DualArray::from_re(t), q.map(DualArray::from_re), v.map(DualArray::from_re));
        for i in 0..N {
            for (j, o) in out.iter_mut().enumerate() {
                *o += wq[i] * f[i].eps[j];
            }
        }
    }
    out
}

/// Whether `n` coordinates take the tape path (see the [module](self)):
/// beyond the sizes of the dual numbers whose parts grow with `n`.
pub(super) const fn large(n: usize) -> bool {
    n > crate::Derivatives::FORWARD_MAX_N
}

/// Whether a one-point step without forces takes the tape path below
/// [`large`] sizes too: where the band of the Newton matrix is at most a
/// quarter of `n`. The dense path's `K_j` costs `⌈2N/8⌉` evaluations of `L`
/// on numbers of `O(N)` parts at each point, the tape's `2b + 1`
/// directions of a second-order sweep: for the FPU-β chain of 16 masses
/// (`b = 1`), 1.55e6 instructions per reverse step on the dense path,
/// 0.10e6 on the tape (callgrind, `bench/benches/adjoint.rs`, `chain16`).
const fn narrow(pattern: Pattern, n: usize) -> bool {
    match pattern.bandwidth() {
        Some(b) => 4 * (2 * b + 1) <= n,
        None => false,
    }
}

/// The buffers of the tape path, allocated once.
struct TapeWork {
    tape: Tape,
    /// `(q_k, D, θ)`, then the direction `w` of the Hessian–vector product.
    inputs: Vec<f64>,
    direction: Vec<f64>,
    gradient: Vec<f64>,
    /// `H·S`, `(2N + P) × K`.
    hs: Vec<f64>,
    /// The bandwidth of `G_D` (`None`: general).
    bandwidth: Option<usize>,
    /// Rows of `a_qD` and `a_DD` as [`Seeds::recover`] writes them.
    qd: Vec<f64>,
    dd: Vec<f64>,
}

/// The reverse step of a rule: its buffers, allocated once, and the
/// transposed linearisation of each step (see the [module](self)).
pub(crate) struct Pullback<const N: usize, const P: usize> {
    rule: Rule,
    /// `G_D` in its band on the tape path (`N × N`; empty otherwise).
    matrix: StepSolver,
    /// `G_D`, `sN × sN`, on the path of the `K_j` (empty on the tape path).
    dense: DenseLu,
    /// `K_j` of each point, `2N × 2N` row-major, one after the other
    /// (empty on the tape path).
    jacobians: Vec<f64>,
    /// `(t, q, v)` at each point of the piece being pulled back.
    points: Vec<(f64, [f64; N], [f64; N])>,
    /// `ω` by node, `(s + 1) N`.
    omega: Vec<f64>,
    /// The right-hand side `−(e_s λ_q + ∂ψ_λ/∂D)/h`, then `η`: `sN`.
    rhs: Vec<f64>,
    /// The tape path's buffers, above `FORWARD_MAX_N` coordinates.
    tape: Option<TapeWork>,
}

impl<const N: usize, const P: usize> Pullback<N, P> {
    /// The buffers for steps of `rule` on systems of type `S`. The Newton
    /// matrix of a one-point rule has the pattern of the coupling of `L`
    /// and the forces; that of a Galerkin step is taken as general.
    pub(crate) fn new<S: Parametric<N, P>>(rule: Rule) -> Result<Self, Error> {
        let s = rule.degree();
        // The forces' pattern counts only where there are forces (its
        // default is general).
        let forced = S::HAS_FORCE || S::HAS_DISSIPATION;
        let pattern = S::COUPLING.overall();
        let pattern = if forced { pattern.union(S::FORCE_COUPLING.overall()) } else { pattern };
        let pattern = if s == 1 { pattern } else { Pattern::General };
        let too_large =
            Error::Unsupported { what: "the buffers of the adjoint of a step of this size cannot be allocated" };
        let tape = if large(N) || (s == 1 && !forced && narrow(pattern, N)) {
            if s != 1 || forced {
                return Err(Error::Unsupported {
                    what: "the adjoint of Galerkin steps, forces or dissipation above `Derivatives::FORWARD_MAX_N` coordinates",
                });
            }
            let bandwidth = pattern.bandwidth();
            let k = bandwidth.map_or(N, |b| (2 * b + 1).min(N));
            let width = bandwidth.map_or(N, |b| 2 * b + 1);
            Some(TapeWork {
                tape: Tape::new(),
                inputs: vec![0.0; 2 * N + P],
                direction: vec![0.0; 2 * N + P],
                gradient: vec![0.0; 2 * N + P],
                hs: vec![0.0; (2 * N + P) * k],
                bandwidth,
                qd: vec![0.0; N * width],
                dd: vec![0.0; N * width],
            })
        } else {
            None
        };
        let points = if tape.is_some() { 0 } else { rule.point_count() };
        let (band, dense) = if tape.is_some() { (s * N, 0) } else { (0, s * N) };
        let matrix = StepSolver::for_pattern(band, pattern).map_err(|_| too_large)?;
        Ok(Self {
            dense: DenseLu::new(dense),
            points: Vec::with_capacity(points),
            jacobians: vec![0.0; points * 4 * N * N],
            omega: vec![0.0; (s + 1) * N],
            rhs: vec![0.0; s * N],
            matrix,
            rule,
            tape,
        })
    }

    /// `(λ_q, λ_p) ← Φ_xᵀ (λ_q, λ_p)` and `dθ += Φ_θᵀ (λ_q, λ_p)` for the
    /// step made of `pieces` (in order; pulled back last first) at
    /// parameters `theta`. `None` where a Newton matrix is singular or a
    /// derivative is not finite (then `λ` and `dθ` are not meaningful).
    pub(crate) fn step<S: Parametric<N, P>>(
        &mut self,
        system: &S,
        theta: &[f64; P],
        pieces: &[Piece<N>],
        lambda: (&mut [f64; N], &mut [f64; N]),
        dtheta: &mut [f64; P],
    ) -> Option<()> {
        let (lq, lp) = lambda;
        for piece in pieces.iter().rev() {
            if self.tape.is_some() {
                self.piece_on_tape(system, theta, piece, (lq, lp), dtheta)?;
            } else if Self::fused::<S>(&self.rule) {
                self.one_point_piece(system, theta, piece, (lq, lp), dtheta)?;
            } else {
                self.piece(system, theta, piece, (lq, lp), dtheta)?;
            }
        }
        let finite = lq.iter().chain(lp.iter()).chain(dtheta.iter()).all(|x| x.is_finite());
        finite.then_some(())
    }

    /// One Galerkin step (see the [module](self)).
    fn piece<S: Parametric<N, P>>(
        &mut self,
        system: &S,
        theta: &[f64; P],
        piece: &Piece<N>,
        (lq, lp): (&mut [f64; N], &mut [f64; N]),
        dtheta: &mut [f64; P],
    ) -> Option<()> {
        let rule = &self.rule;
        let (s, h) = (rule.degree(), piece.h);
        let block = 4 * N * N;
        self.points.clear();
        self.points.extend((0..rule.point_count()).map(|j| rule.point(piece, j)));
        for (j, &point) in self.points.iter().enumerate() {
            point_jacobian(system, theta, point, &mut self.jacobians[j * block..(j + 1) * block]);
        }
        self.assemble(h);
        self.dense.factor::<N>()?;
        // ω_ρ = λ_p + h η_ρ (η_s = 0): the part of ψ along ω = (λ_p, …, λ_p)
        // is h Σ_j b_j λ_p·(L_q + F), free of the 1/h of the rows, and the
        // solve is for the differences η, of order λ, not for ω itself.
        for rho in 0..=s {
            self.omega[rho * N..(rho + 1) * N].copy_from_slice(lp);
        }
        self.rhs.fill(0.0);
        let mut dq = [0.0; N];
        gradient::<N>(&self.rule, &self.jacobians, h, &self.omega, 1.0, &mut dq, Some(&mut self.rhs));
        for i in 0..N {
            self.rhs[(s - 1) * N + i] += lq[i];
        }
        for x in self.rhs.iter_mut() {
            *x = -*x / h;
        }
        self.dense.solve_transposed::<N>(&mut self.rhs);
        self.omega.fill(0.0);
        self.omega[..s * N].copy_from_slice(&self.rhs);
        gradient::<N>(&self.rule, &self.jacobians, h, &self.omega, h, &mut dq, None);
        let rule = &self.rule;
        if P > 0 {
            for j in 0..rule.point_count() {
                let (eq, ev) = weights::<N>(rule, j, h, &self.omega);
                let wq = core::array::from_fn(|i| lp[i] + h * eq[i]);
                let wv = ev.map(|x| h * x);
                let w = rule.weight(j) * h;
                let g = theta_product(system, theta, self.points[j], &wq, &wv);
                for (d, g) in dtheta.iter_mut().zip(g) {
                    *d += w * g;
                }
            }
        }
        for i in 0..N {
            lq[i] += dq[i];
            lp[i] += h * self.rhs[i];
        }
        Some(())
    }

    /// Whether a step of `rule` takes [`one_point_piece`](Self::one_point_piece):
    /// a one-point rule (degree 1, at most two points) on a system without
    /// forces of at most [`FUSED_MAX_N`] coordinates.
    #[inline(always)]
    fn fused<S: Parametric<N, P>>(rule: &Rule) -> bool {
        N <= FUSED_MAX_N && !(S::HAS_FORCE || S::HAS_DISSIPATION) && rule.degree() == 1 && rule.point_count() <= 2
    }

    /// [`piece`](Self::piece) for a one-point rule without forces: the
    /// second derivatives of `L` at each point in `(q, v)` and `(q, v) × θ`
    /// from one evaluation ([`point_blocks`]), so that `∂ψ/∂θ` is a product
    /// with the blocks instead of one more evaluation per point, and the
    /// sums over the rule in arrays of the rule's fixed sizes. The same
    /// algebra as the general path, term for term.
    fn one_point_piece<S: Parametric<N, P>>(
        &mut self,
        system: &S,
        theta: &[f64; P],
        piece: &Piece<N>,
        (lq, lp): (&mut [f64; N], &mut [f64; N]),
        dtheta: &mut [f64; P],
    ) -> Option<()> {
        let rule = &self.rule;
        let h = piece.h;
        let count = rule.point_count();
        let d = &piece.d[0];
        // Per point: b_j h, ℓ_0, ℓ_0'/h, ℓ_1, ℓ_1'/h, and the blocks.
        let mut coefficients = [[0.0; 5]; 2];
        let mut blocks = [PointBlocks::<N, P>::ZERO; 2];
        for j in 0..count {
            let (l1, d1) = (rule.l(j, 1), rule.dl(j, 1));
            coefficients[j] = [rule.weight(j) * h, rule.l(j, 0), rule.dl(j, 0) / h, l1, d1 / h];
            let q = core::array::from_fn(|i| piece.q0[i] + l1 * d[i]);
            let v = core::array::from_fn(|i| d1 * d[i] / h);
            blocks[j] = point_blocks(system, theta, (rule.time(piece, j), q, v));
        }
        // G_D = Σ_j b_j h [ℓ_0 (L_qq ℓ_1 + L_qv ℓ_1'/h) + ℓ_0'/h (L_vq ℓ_1 + L_vv ℓ_1'/h)],
        // and the part of ψ along ω = (λ_p, λ_p): its gradient in q_k into
        // `dq`, in D into `rhs` (w_q = λ_p, w_v = 0).
        let a = &mut self.dense.a;
        a.fill(0.0);
        let (mut dq, mut rhs) = ([0.0; N], [0.0; N]);
        for j in 0..count {
            let [w, l0, d0, l1, d1] = coefficients[j];
            let k = &blocks[j];
            let (r, rd) = (w * l0, w * d0);
            for i in 0..N {
                let row = &mut a[i * N..(i + 1) * N];
                for (col, x) in row.iter_mut().enumerate() {
                    *x += r * (k.qq[i][col] * l1 + k.qv[i][col] * d1) + rd * (k.vq[i][col] * l1 + k.vv[i][col] * d1);
                }
            }
            let (mut uq, mut uv) = ([0.0; N], [0.0; N]);
            for i in 0..N {
                for col in 0..N {
                    uq[col] += k.qq[i][col] * lp[i];
                    uv[col] += k.qv[i][col] * lp[i];
                }
            }
            let (c, cd) = (w * l1, w * d1);
            for i in 0..N {
                dq[i] += w * uq[i];
                rhs[i] += c * uq[i] + cd * uv[i];
            }
        }
        self.dense.factor::<N>()?;
        for i in 0..N {
            rhs[i] = -(rhs[i] + lq[i]) / h;
        }
        self.dense.solve_transposed::<N>(&mut rhs);
        let eta = rhs;
        // ω = (λ_p + h η, λ_p): at each point w_q = ℓ_0 η, w_v = −ℓ_1'/h η
        // (times h), and the θ part with w = (λ_p + h w_q, h w_v).
        for j in 0..count {
            let [w, _, _, l1, d1] = coefficients[j];
            let k = &blocks[j];
            let wq: [f64; N] = core::array::from_fn(|i| eta[i] + l1 * -eta[i]);
            let wv: [f64; N] = core::array::from_fn(|i| d1 * -eta[i]);
            let mut uq = [0.0; N];
            for i in 0..N {
                for col in 0..N {
                    uq[col] += k.qq[i][col] * wq[i] + k.vq[i][col] * wv[i];
                }
            }
            for i in 0..N {
                dq[i] += h * (w * uq[i]);
            }
            if P > 0 {
                let mut g = [0.0; P];
                for i in 0..N {
                    let (tq, tv) = (lp[i] + h * wq[i], h * wv[i]);
                    for (p, g) in g.iter_mut().enumerate() {
                        *g += k.qt[i][p] * tq + k.vt[i][p] * tv;
                    }
                }
                for (d, g) in dtheta.iter_mut().zip(g) {
                    *d += w * g;
                }
            }
        }
        for i in 0..N {
            lq[i] += dq[i];
            lp[i] += h * eta[i];
        }
        Some(())
    }

    /// One one-point step on the tape (see the [module](self)).
    fn piece_on_tape<S: Parametric<N, P>>(
        &mut self,
        system: &S,
        theta: &[f64; P],
        piece: &Piece<N>,
        (lq, lp): (&mut [f64; N], &mut [f64; N]),
        dtheta: &mut [f64; P],
    ) -> Option<()> {
        let Self { rule, matrix, rhs, tape, .. } = self;
        let work = tape.as_mut()?;
        let h = piece.h;
        work.inputs[..N].copy_from_slice(&piece.q0);
        work.inputs[N..2 * N].copy_from_slice(&piece.d[0]);
        work.inputs[2 * N..].copy_from_slice(theta);
        work.tape
            .record(&work.inputs, |x| {
                let th: [Var; P] = core::array::from_fn(|j| x[2 * N + j]);
                let mut a = Var::from(0.0);
                for j in 0..rule.point_count() {
                    let (c, cd) = (rule.l(j, 1), rule.dl(j, 1));
                    let q: [Var; N] = core::array::from_fn(|i| x[i] + x[N + i] * c);
                    let v: [Var; N] = core::array::from_fn(|i| x[N + i] * cd / h);
                    a += system.lagrangian_with(&th, Var::from(rule.time(piece, j)), q, v) * rule.weight(j);
                }
                a * h
            })
            .ok()?;
        // a_qD (rows q) and a_DD (rows D), seeded on D.
        let seeds = match work.bandwidth {
            Some(b) => Seeds::banded(N..2 * N, b),
            None => Seeds::dense(N..2 * N),
        };
        let k = seeds.directions();
        let hs = &mut work.hs[..(2 * N + P) * k];
        work.tape.hessian_product(&seeds, &mut work.gradient, hs).ok()?;
        seeds.recover(hs, 0..N, &mut work.qd).ok()?;
        seeds.recover(hs, N..2 * N, &mut work.dd).ok()?;
        // Slot `s` of row `r` is column `r − b + s` (banded) or `s` (dense).
        let width = work.qd.len() / N;
        let column = |r: usize, s: usize| match work.bandwidth {
            Some(b) => (r + s).checked_sub(b).filter(|&c| c < N),
            None => Some(s),
        };
        // G_D = a_qD − a_DD; the right-hand side −(λ_q + a_Dq λ_p)/h for
        // η (ω_0 = λ_p + h η), in which the a_DD λ_p of order λ_p/h of the
        // system for μ = −ω_0 has cancelled exactly.
        matrix.clear();
        rhs[..N].copy_from_slice(lq);
        for r in 0..N {
            for s in 0..width {
                if let Some(c) = column(r, s) {
                    let (qd, dd) = (work.qd[r * width + s], work.dd[r * width + s]);
                    matrix.add(r, c, qd - dd).ok()?;
                    rhs[c] += qd * lp[r];
                }
            }
        }
        for x in rhs.iter_mut() {
            *x = -*x / h;
        }
        matrix.factor(0.0).ok()?;
        matrix.solve_transposed(rhs).ok()?;
        // H·w with w = (ω_0, ω_1 − ω_0, 0) = (λ_p + h η, −h η, 0).
        let w = &mut work.direction;
        for i in 0..N {
            w[i] = lp[i] + h * rhs[i];
            w[N + i] = -h * rhs[i];
        }
        w[2 * N..].fill(0.0);
        let hw = &mut work.hs[..2 * N + P];
        work.tape.hessian_product(&Seeds::Along { direction: w }, &mut work.gradient, hw).ok()?;
        for i in 0..N {
            lq[i] += hw[i];
            lp[i] += h * rhs[i];
        }
        for (j, d) in dtheta.iter_mut().enumerate() {
            *d += hw[2 * N + j];
        }
        Some(())
    }

    /// `G_D` from the `K_j`: row block `ρ < s`, column block `D_m`.
    fn assemble(&mut self, h: f64) {
        let rule = &self.rule;
        let (s, n2) = (rule.degree(), 2 * N);
        let m = s * N;
        let a = &mut self.dense.a;
        a.fill(0.0);
        for j in 0..rule.point_count() {
            let k = &self.jacobians[j * n2 * n2..(j + 1) * n2 * n2];
            let w = rule.weight(j) * h;
            for rho in 0..s {
                let (r, rd) = (w * rule.l(j, rho), w * rule.dl(j, rho) / h);
                for node in 1..=s {
                    let (c, cd) = (rule.l(j, node), rule.dl(j, node) / h);
                    for i in 0..N {
                        let (kq, kv) = (&k[i * n2..(i + 1) * n2], &k[(N + i) * n2..(N + i + 1) * n2]);
                        let row = &mut a[(rho * N + i) * m + (node - 1) * N..][..N];
                        for (col, x) in row.iter_mut().enumerate() {
                            *x += r * (kq[col] * c + kq[N + col] * cd) + rd * (kv[col] * c + kv[N + col] * cd);
                        }
                    }
                }
            }
        }
    }
}

/// A dense matrix, row-major, and its LU factors by partial pivoting in
/// the same storage (`P A = L U`, whole rows exchanged). The step matrices
/// of the adjoint on this path are small (`sN` of a few to a few tens):
/// plain loops without the bookkeeping of the general solvers, which cost
/// as much as the rest of a reverse step of a double pendulum.
struct DenseLu {
    m: usize,
    a: Vec<f64>,
    /// Row `j` was exchanged with row `pivots[j]` at elimination step `j`.
    pivots: Vec<usize>,
}

impl DenseLu {
    fn new(m: usize) -> Self {
        Self { m, a: vec![0.0; m * m], pivots: vec![0; m] }
    }

    /// Factors in place; `None` at a zero or non-finite pivot. A matrix of
    /// `K` rows (the one-point rules' `N × N`) takes loops of constant
    /// length, unrolled for the few coordinates where this cost shows.
    fn factor<const K: usize>(&mut self) -> Option<()> {
        if self.m == K {
            let (rows, _) = self.a.as_chunks_mut::<K>();
            return factor_rows::<K>(rows, &mut self.pivots);
        }
        let (m, a) = (self.m, &mut self.a);
        for j in 0..m {
            let (mut p, mut best) = (j, a[j * m + j].abs());
            for i in j + 1..m {
                let x = a[i * m + j].abs();
                if x > best {
                    (p, best) = (i, x);
                }
            }
            if !(best > 0.0 && best.is_finite()) {
                return None;
            }
            self.pivots[j] = p;
            if p != j {
                for c in 0..m {
                    a.swap(j * m + c, p * m + c);
                }
            }
            let (upper, lower) = a.split_at_mut((j + 1) * m);
            let pivot_row = &upper[j * m..];
            for row in lower.chunks_exact_mut(m) {
                let l = row[j] / pivot_row[j];
                row[j] = l;
                if l != 0.0 {
                    for (x, u) in row[j + 1..].iter_mut().zip(&pivot_row[j + 1..]) {
                        *x -= l * u;
                    }
                }
            }
        }
        Some(())
    }

    /// `Aᵀ x = b` in place: `Uᵀ y = b`, `Lᵀ z = y`, `x = Pᵀ z` (loops of
    /// constant length for `K` rows, as in [`factor`](Self::factor)).
    fn solve_transposed<const K: usize>(&self, b: &mut [f64]) {
        if self.m == K {
            let (rows, _) = self.a.as_chunks::<K>();
            let b: &mut [f64; K] = (&mut b[..K]).try_into().expect("a right-hand side of the matrix's size");
            for j in 0..K {
                let mut x = b[j];
                for i in 0..j {
                    x -= rows[i][j] * b[i];
                }
                b[j] = x / rows[j][j];
            }
            for j in (0..K).rev() {
                let mut x = b[j];
                for i in j + 1..K {
                    x -= rows[i][j] * b[i];
                }
                b[j] = x;
            }
            for j in (0..K).rev() {
                b.swap(j, self.pivots[j]);
            }
            return;
        }
        let (m, a) = (self.m, &self.a);
        for j in 0..m {
            let mut x = b[j];
            for i in 0..j {
                x -= a[i * m + j] * b[i];
            }
            b[j] = x / a[j * m + j];
        }
        for j in (0..m).rev() {
            let mut x = b[j];
            for i in j + 1..m {
                x -= a[i * m + j] * b[i];
            }
            b[j] = x;
        }
        for j in (0..m).rev() {
            b.swap(j, self.pivots[j]);
        }
    }
}

/// [`DenseLu::factor`] of `K` rows of `K` entries.
fn factor_rows<const K: usize>(rows: &mut [[f64; K]], pivots: &mut [usize]) -> Option<()> {
    for j in 0..K {
        let (mut p, mut best) = (j, rows[j][j].abs());
        for (i, row) in rows.iter().enumerate().take(K).skip(j + 1) {
            if row[j].abs() > best {
                (p, best) = (i, row[j].abs());
            }
        }
        if !(best > 0.0 && best.is_finite()) {
            return None;
        }
        pivots[j] = p;
        rows.swap(j, p);
        let pivot_row = rows[j];
        for row in rows.iter_mut().take(K).skip(j + 1) {
            let l = row[j] / pivot_row[j];
            row[j] = l;
            for c in j + 1..K {
                row[c] -= l * pivot_row[c];
            }
        }
    }
    Some(())
}

/// `scale` times the gradient of `ψ = Σ_ρ ω_ρ·R_ρ` (without its `θ`
/// part), from the `K_j` in `jacobians`: in `q_k` added to `dq`, and in `D`
/// added to `d` where given.
fn gradient<const N: usize>(
    rule: &Rule,
    jacobians: &[f64],
    h: f64,
    omega: &[f64],
    scale: f64,
    dq: &mut [f64; N],
    mut d: Option<&mut [f64]>,
) {
    let (s, n2) = (rule.degree(), 2 * N);
    for j in 0..rule.point_count() {
        let k = &jacobians[j * n2 * n2..(j + 1) * n2 * n2];
        let (wq, wv) = weights::<N>(rule, j, h, omega);
        // u = Kᵀ (w_q, w_v).
        let (mut uq, mut uv) = ([0.0; N], [0.0; N]);
        for i in 0..N {
            let (a, b) = (&k[i * n2..(i + 1) * n2], &k[(N + i) * n2..(N + i + 1) * n2]);
            for col in 0..N {
                uq[col] += a[col] * wq[i] + b[col] * wv[i];
                uv[col] += a[N + col] * wq[i] + b[N + col] * wv[i];
            }
        }
        let w = rule.weight(j) * h;
        for i in 0..N {
            dq[i] += scale * (w * uq[i]);
        }
        if let Some(d) = d.as_deref_mut() {
            for m in 1..=s {
                let (c, cd) = (w * rule.l(j, m), w * rule.dl(j, m) / h);
                for i in 0..N {
                    d[(m - 1) * N + i] += scale * (c * uq[i] + cd * uv[i]);
                }
            }
        }
    }
}

/// `(w_q, w_v) = (Σ_ρ ℓ_ρ(c_j) ω_ρ, Σ_ρ ℓ_ρ'(c_j) ω_ρ / h)` at point `j`,
/// from the differences `ω_m − ω_0` with `ℓ_0 = 1 − Σ_{m≥1} ℓ_m`: a
/// constant `ω` gives `(ω, 0)` exactly.
fn weights<const N: usize>(rule: &Rule, j: usize, h: f64, omega: &[f64]) -> ([f64; N], [f64; N]) {
    let (mut wq, mut wv): ([f64; N], [f64; N]) = (core::array::from_fn(|i| omega[i]), [0.0; N]);
    for rho in 1..=rule.degree() {
        let (l, dl) = (rule.l(j, rho), rule.dl(j, rho) / h);
        let w = &omega[rho * N..(rho + 1) * N];
        for i in 0..N {
            let d = w[i] - omega[i];
            wq[i] += l * d;
            wv[i] += dl * d;
        }
    }
    (wq, wv)
}

/// `(∂p_0/∂(q_0, v_0, θ))ᵀ λ_p` for the initial momentum
/// `p_0 = L_v(t_0, q_0, v_0; θ)`: the Hessian of `L` in `(q, v, θ)` times
/// `(0, λ_p, 0)`, one Hessian–vector product on a tape (at any `N`, with no
/// `N × N` block). `None` where a derivative is not finite.
#[allow(clippy::type_complexity)]
pub(crate) fn legendre<S: Parametric<N, P>, const N: usize, const P: usize>(
    system: &S,
    theta: &[f64; P],
    (t0, q0, v0): (f64, [f64; N], [f64; N]),
    lp: &[f64; N],
) -> Option<([f64; N], [f64; N], [f64; P])> {
    let inputs: Vec<f64> = q0.iter().chain(&v0).chain(theta).copied().collect();
    let mut tape = Tape::new();
    tape.record(&inputs, |x| {
        let (q, v) = (core::array::from_fn(|i| x[i]), core::array::from_fn(|i| x[N + i]));
        system.lagrangian_with(&core::array::from_fn(|j| x[2 * N + j]), Var::from(t0), q, v)
    })
    .ok()?;
    let mut w = vec![0.0; 2 * N + P];
    w[N..2 * N].copy_from_slice(lp);
    let (mut g, mut hw) = (vec![0.0; 2 * N + P], vec![0.0; 2 * N + P]);
    tape.hessian_product(&Seeds::Along { direction: &w }, &mut g, &mut hw).ok()?;
    if !hw.iter().all(|x| x.is_finite()) {
        return None;
    }
    Some((
        core::array::from_fn(|i| hw[i]),
        core::array::from_fn(|i| hw[N + i]),
        core::array::from_fn(|j| hw[2 * N + j]),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discrete::AlphaBeta;
    use crate::galerkin::{Galerkin, NodeFamily, Quadrature};
    use crate::problem::OnePoint;
    use crate::sensitivity::linearisation::{MAX_DEGREE, StepJacobian};

    /// Two coupled coordinates with a mass, a stiffness and a damping
    /// coefficient as parameters, an explicitly time-dependent `L`, applied
    /// forces and Rayleigh dissipation: every term the transposed
    /// linearisation carries.
    #[derive(Clone)]
    struct Coupled {
        theta: [f64; 3],
    }

    impl Lagrangian<2> for Coupled {
        const AUTONOMOUS: bool = false;
        const CYCLIC: [bool; 2] = [false; 2];
        const HAS_FORCE: bool = true;
        const HAS_DISSIPATION: bool = true;
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 2], v: [D; 2]) -> D {
            self.lagrangian_with(&self.theta.map(D::from), t, q, v)
        }
        fn force<D: Scalar>(&self, t: D, q: [D; 2], v: [D; 2]) -> [D; 2] {
            self.force_with(&self.theta.map(D::from), t, q, v)
        }
        fn dissipation<D: Scalar>(&self, q: [D; 2], v: [D; 2]) -> D {
            self.dissipation_with(&self.theta.map(D::from), q, v)
        }
    }

    impl Parametric<2, 3> for Coupled {
        const NAMES: [&'static str; 3] = ["m", "k", "c"];
        fn parameters(&self) -> [f64; 3] {
            self.theta
        }
        fn with_parameters(&self, theta: [f64; 3]) -> Self {
            Self { theta }
        }
        fn lagrangian_with<D: Scalar>(&self, theta: &[D; 3], t: D, q: [D; 2], v: [D; 2]) -> D {
            let [m, k, _] = *theta;
            let kinetic = m * (v[0] * v[0] + v[1] * v[1]) * 0.5 + v[0] * v[1] * (q[0] - q[1]).cos() * 0.3;
            kinetic - k * (-q[0].cos() + 1.0) - k * q[1] * q[1] * 0.5 + t * q[0] * 0.1
        }
        fn dissipation_with<D: Scalar>(&self, theta: &[D; 3], q: [D; 2], v: [D; 2]) -> D {
            let c = theta[2];
            c * (v[0] * v[0] + v[1] * v[1] * 0.5) * 0.5 + c * v[0] * v[1] * q[0] * 0.1
        }
        fn force_with<D: Scalar>(&self, theta: &[D; 3], t: D, q: [D; 2], v: [D; 2]) -> [D; 2] {
            [theta[1] * t.sin() * 0.2 + q[1] * v[0] * 0.05, -theta[2] * q[0] * 0.1]
        }
    }

    const SYSTEM: Coupled = Coupled { theta: [1.1, 2.3, 0.4] };

    /// A step of degree `d.len()` from `(0.7, (0.4, −0.2))` with `h = 0.05`.
    fn piece(d: &[[f64; 2]]) -> Piece<2> {
        let mut piece = Piece { t0: 0.7, h: 0.05, q0: [0.4, -0.2], d: [[0.0; 2]; MAX_DEGREE] };
        piece.d[..d.len()].copy_from_slice(d);
        piece
    }

    /// The pullback of a costate against the transpose of the dense step
    /// Jacobians, at nodes that solve no step (the implicit-function
    /// formulas hold at any point).
    fn agrees(rule: Rule, pieces: &[Piece<2>]) {
        agrees_on(&SYSTEM, rule, pieces);
    }

    /// [`agrees`] on `system`.
    fn agrees_on<S: Parametric<2, 3>>(system: &S, rule: Rule, pieces: &[Piece<2>]) {
        let (theta, degree) = (system.parameters(), rule.degree());
        let j = StepJacobian::of_step(system, &rule, &theta, pieces).unwrap();
        let (lq0, lp0) = ([0.7, -1.3], [0.25, 2.1]);
        let (mut lq, mut lp, mut dtheta) = (lq0, lp0, [0.5, -0.5, 1.0]);
        let mut pullback = Pullback::<2, 3>::new::<S>(rule).unwrap();
        pullback.step(system, &theta, pieces, (&mut lq, &mut lp), &mut dtheta).unwrap();
        let (a, b) = (nalgebra::SVector::from(lq0), nalgebra::SVector::from(lp0));
        let m = &j.state;
        let want_q = m.dq_dq.transpose() * a + m.dp_dq.transpose() * b;
        let want_p = m.dq_dp.transpose() * a + m.dp_dp.transpose() * b;
        let want_theta =
            j.dq_dtheta.transpose() * a + j.dp_dtheta.transpose() * b + nalgebra::SVector::from([0.5, -0.5, 1.0]);
        let got = [lq.as_slice(), &lp, &dtheta].concat();
        let want = [want_q.as_slice(), want_p.as_slice(), want_theta.as_slice()].concat();
        let gap = relative(&got, &want);
        assert!(gap <= 1e-13, "degree {degree}: {got:?} against {want:?}");
    }

    #[test]
    fn the_pullback_is_the_transposed_jacobian_of_every_rule() {
        let one = [piece(&[[0.03, -0.01]])];
        agrees(Rule::one_point(&OnePoint::Midpoint), &one);
        agrees(Rule::one_point(&OnePoint::Trapezoid), &one);
        agrees(Rule::one_point(&OnePoint::AlphaBeta(AlphaBeta::new(0.3).unwrap())), &one);
        let three = [piece(&[[0.011, -0.004], [0.021, -0.007], [0.03, -0.01]])];
        agrees(Rule::galerkin(&Galerkin::<3, 3>::gauss()), &three);
        let lobatto = Galerkin::<3, 4>::new(NodeFamily::GaussLobatto, Quadrature::gauss_lobatto());
        agrees(Rule::galerkin(&lobatto), &three);
        // A composition: the product of its sub-steps, pulled back last first.
        let mut second = piece(&[[-0.02, 0.015]]);
        (second.t0, second.h, second.q0) = (0.75, -0.03, [0.43, -0.21]);
        agrees(Rule::one_point(&OnePoint::Trapezoid), &[one[0], second]);
    }

    /// One-point steps without forces take the fused pullback (the second
    /// derivatives in `(q, v)` and `θ` from one evaluation per point): the
    /// same transposed Jacobian.
    #[test]
    fn the_fused_pullback_is_the_transposed_jacobian_of_the_one_point_rules() {
        use super::accuracy::DoublePendulum;
        let rules = [
            Rule::one_point(&OnePoint::Midpoint),
            Rule::one_point(&OnePoint::Trapezoid),
            Rule::one_point(&OnePoint::AlphaBeta(AlphaBeta::new(0.3).unwrap())),
        ];
        for rule in &rules {
            assert!(Pullback::<2, 3>::fused::<DoublePendulum>(rule));
            assert!(!Pullback::<2, 3>::fused::<Coupled>(rule));
        }
        let one = [piece(&[[0.03, -0.01]])];
        let mut second = piece(&[[-0.02, 0.015]]);
        (second.t0, second.h, second.q0) = (0.75, -0.03, [0.43, -0.21]);
        for rule in rules {
            agrees_on(&DoublePendulum, rule.clone(), &one);
            agrees_on(&DoublePendulum, rule, &[one[0], second]);
        }
    }

    /// An FPU-β chain with fixed ends and `(k, β)` as parameters, its
    /// Hessian banded (`BANDED`) or not declared so.
    #[derive(Clone)]
    struct Chain<const BANDED: bool> {
        theta: [f64; 2],
    }

    const LONG: usize = 40;

    impl<const BANDED: bool> Lagrangian<LONG> for Chain<BANDED> {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; LONG] = [false; LONG];
        const COUPLING: crate::structure::Coupling = if BANDED {
            crate::structure::Coupling { q_q: Pattern::banded(LONG, 1), q_v: Pattern::Diagonal, v_v: Pattern::Diagonal }
        } else {
            crate::structure::Coupling::GENERAL
        };
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; LONG], v: [D; LONG]) -> D {
            self.lagrangian_with(&self.theta.map(D::from), t, q, v)
        }
    }

    impl<const BANDED: bool> Parametric<LONG, 2> for Chain<BANDED> {
        const NAMES: [&'static str; 2] = ["k", "beta"];
        fn parameters(&self) -> [f64; 2] {
            self.theta
        }
        fn with_parameters(&self, theta: [f64; 2]) -> Self {
            Self { theta }
        }
        fn lagrangian_with<D: Scalar>(&self, theta: &[D; 2], _t: D, q: [D; LONG], v: [D; LONG]) -> D {
            let [k, beta] = *theta;
            let mut l = D::zero();
            for i in 0..=LONG {
                let left = if i == 0 { D::zero() } else { q[i - 1] };
                let right = if i == LONG { D::zero() } else { q[i] };
                let d = right - left;
                l -= k * d * d * 0.5 + beta * d.powi(4) * 0.25;
                if i < LONG {
                    l += v[i] * v[i] * 0.5;
                }
            }
            l
        }
    }

    /// Above `FORWARD_MAX_N` the pullback runs on the tape: against the
    /// transposed dense Jacobians, with a banded and a general pattern.
    fn tape_agrees<const BANDED: bool>(rule: Rule) {
        let system = Chain::<BANDED> { theta: [1.3, 0.7] };
        let q0: [f64; LONG] = core::array::from_fn(|i| 0.3 * (i as f64 * 0.9).sin());
        let mut piece = Piece { t0: 0.2, h: 0.05, q0, d: [[0.0; LONG]; MAX_DEGREE] };
        piece.d[0] = core::array::from_fn(|i| 0.01 * (i as f64 * 0.4).cos());
        let theta = system.parameters();
        let j = StepJacobian::of_step(&system, &rule, &theta, &[piece]).unwrap();
        let lq0: [f64; LONG] = core::array::from_fn(|i| (i as f64 * 0.3).sin());
        let lp0: [f64; LONG] = core::array::from_fn(|i| (i as f64 * 0.7).cos());
        let (mut lq, mut lp, mut dtheta) = (lq0, lp0, [0.0; 2]);
        let mut pullback = Pullback::<LONG, 2>::new::<Chain<BANDED>>(rule).unwrap();
        assert!(pullback.tape.is_some());
        pullback.step(&system, &theta, &[piece], (&mut lq, &mut lp), &mut dtheta).unwrap();
        let (a, b) = (nalgebra::SVector::from(lq0), nalgebra::SVector::from(lp0));
        let m = &j.state;
        let want_q = m.dq_dq.transpose() * a + m.dp_dq.transpose() * b;
        let want_p = m.dq_dp.transpose() * a + m.dp_dp.transpose() * b;
        let want_theta = j.dq_dtheta.transpose() * a + j.dp_dtheta.transpose() * b;
        let got = [lq.as_slice(), &lp, &dtheta].concat();
        let want = [want_q.as_slice(), want_p.as_slice(), want_theta.as_slice()].concat();
        let gap = relative(&got, &want);
        assert!(gap <= 1e-12, "banded {BANDED}: relative gap {gap:e}");
    }

    #[test]
    fn the_tape_pullback_of_a_long_chain_is_the_transposed_jacobian() {
        tape_agrees::<true>(Rule::one_point(&OnePoint::Midpoint));
        tape_agrees::<true>(Rule::one_point(&OnePoint::Trapezoid));
        tape_agrees::<false>(Rule::one_point(&OnePoint::Midpoint));
        // Galerkin steps are not taken above `FORWARD_MAX_N`: refused.
        let galerkin = Rule::galerkin(&Galerkin::<3, 3>::gauss());
        assert!(Pullback::<LONG, 2>::new::<Chain<true>>(galerkin).is_err());
    }

    /// `q_0 q_1 + p_{N−1}² + β q_5` at the end of the run.
    struct Ends;

    impl crate::sensitivity::Loss<LONG, 2> for Ends {
        fn terminal<D: Scalar>(&self, _t: D, q: [D; LONG], p: [D; LONG], theta: &[D; 2]) -> D {
            q[0] * q[1] + p[LONG - 1] * p[LONG - 1] + theta[1] * q[5]
        }
    }

    /// The chain of `LONG` masses from its test state, as a problem.
    fn long_chain() -> crate::problem::Problem<Chain<true>, crate::dim::Dim<LONG>> {
        let q0: [f64; LONG] = core::array::from_fn(|i| 0.3 * (i as f64 * 0.9).sin());
        let v0: [f64; LONG] = core::array::from_fn(|i| 0.2 * (i as f64 * 0.5).cos());
        crate::problem::Problem::new(Chain::<true> { theta: [1.3, 0.7] }, 0.0, q0, v0)
    }

    /// The gradient of [`Ends`] in `(q_0, v_0, θ)` by the chain rule through
    /// the forward sensitivities of `run`'s last node, whose position the
    /// adjoint's run must end at (`last_q`).
    fn ends_by_chain_rule(run: &crate::sensitivity::forward::Sensitivities<LONG>, last_q: &[f64; LONG]) -> Vec<f64> {
        let (jac, x) = (run.jacobians.last().unwrap(), run.solution.q.len() - 1);
        let (q, p) = (&run.solution.q[x], &run.solution.p[x]);
        assert_eq!(last_q, &q);
        // ∂ℓ/∂(q, p) and ∂ℓ/∂θ at the last node.
        let mut g = [0.0; 2 * LONG];
        (g[0], g[1], g[5], g[2 * LONG - 1]) = (q[1], q[0], 0.7, 2.0 * p[LONG - 1]);
        let input = |j: usize| (0..2 * LONG).map(|i| g[i] * jac.get(i, j)).sum::<f64>();
        (0..2 * LONG + 2).map(|j| input(j) + if j == 2 * LONG + 1 { q[5] } else { 0.0 }).collect()
    }

    /// A whole run above `FORWARD_MAX_N` (the stepper in reverse mode, the
    /// adjoint on the tape): the gradient against the chain rule through
    /// the forward sensitivities of the last node.
    #[test]
    fn the_adjoint_of_a_long_chain_agrees_with_forward_sensitivities() {
        use crate::problem::Scheme;
        let problem = long_chain();
        let (h, t_end) = (0.05, 0.5);
        let adjoint = problem.gradient(&Scheme::MIDPOINT, h, t_end, &Ends, crate::Checkpoints::Every(3)).unwrap();
        let run = problem.solve_with_sensitivities(&Scheme::MIDPOINT, h, crate::Plan::until(t_end)).unwrap();
        let want = ends_by_chain_rule(&run, &adjoint.last.q);
        let got: Vec<f64> = adjoint.q0.iter().chain(&adjoint.v0).chain(&adjoint.theta).copied().collect();
        let gap = relative(&got, &want);
        assert!(gap <= 1e-12, "gap {gap:e}");
    }

    /// `max |x − y| / max |y|`.
    fn relative(x: &[f64], y: &[f64]) -> f64 {
        let scale = y.iter().fold(0.0_f64, |m, y| m.max(y.abs()));
        x.iter().zip(y).fold(0.0_f64, |m, (x, y)| m.max((x - y).abs())) / scale
    }

    /// A long run above `FORWARD_MAX_N`, 2 000 midpoint steps of
    /// `h = 1e-3`, with the terminal loss [`Ends`]: the pairing `λ_kᵀ S_k`
    /// of the adjoint on the tape and the forward sensitivities (its
    /// `(q_0, v_0)` columns, the gradient in the initial data at every
    /// checkpoint), and the whole gradient against the chain rule through
    /// the last node's sensitivities, both at the project's bound of
    /// 1e-12 relative. Measured: drift 9.1e-15, gap 7.5e-15; over 10⁴
    /// steps 2.0e-14 and 1.6e-14 (2.9e-14 and 2.3e-14 solving for
    /// `μ = −ω_0`: at degree 1 the `O(ε λ_p)` error of `μ` is a rounding
    /// of the new `λ_p` alone, and `ψ`'s gradient in
    /// `q_k` takes `w_D` only through `a_qD`, of order `h`).
    #[test]
    fn the_tape_adjoint_keeps_the_pairing_over_a_long_run() {
        use crate::problem::Scheme;
        let problem = long_chain();
        // 2 000 steps: the forward sensitivities (80 × 82 per step) make
        // this the runtime's slowest unit test, about 7 ms per step.
        let (h, t_end) = (1e-3, 2.0);
        let adjoint = problem.gradient(&Scheme::MIDPOINT, h, t_end, &Ends, crate::Checkpoints::Every(100)).unwrap();
        let plan = crate::Plan::until(t_end).every(100);
        let run = problem.solve_with_sensitivities(&Scheme::MIDPOINT, h, plan).unwrap();
        let initial: Vec<f64> = adjoint.q0.iter().chain(&adjoint.v0).copied().collect();
        let mut drift = 0.0_f64;
        for (state, lq, lp) in &adjoint.costates {
            let row = run.solution.step.iter().position(|k| *k == Some(state.step)).unwrap();
            assert_eq!(run.solution.q[row], state.q);
            let jac = &run.jacobians[row];
            let pairing: Vec<f64> = (0..2 * LONG)
                .map(|c| (0..LONG).map(|i| lq[i] * jac.get(i, c) + lp[i] * jac.get(LONG + i, c)).sum())
                .collect();
            drift = drift.max(relative(&pairing, &initial));
        }
        let want = ends_by_chain_rule(&run, &adjoint.last.q);
        let got: Vec<f64> = initial.iter().chain(&adjoint.theta).copied().collect();
        let gap = relative(&got, &want);
        eprintln!(
            "chain N = {LONG}, tape path: pairing drift {drift:.1e} over {} checkpoints, adjoint vs forward {gap:.1e}",
            adjoint.costates.len()
        );
        assert_eq!(adjoint.costates.len(), 21);
        assert!(drift <= 1e-12 && gap <= 1e-12, "{drift:e} {gap:e}");
    }

    #[test]
    fn a_non_finite_newton_matrix_is_none() {
        let mut bad = piece(&[[0.03, -0.01]]);
        bad.h = f64::NAN;
        let theta = SYSTEM.parameters();
        let mut pullback = Pullback::<2, 3>::new::<Coupled>(Rule::one_point(&OnePoint::Midpoint)).unwrap();
        let (mut lq, mut lp, mut dtheta) = ([1.0; 2], [1.0; 2], [0.0; 3]);
        assert!(pullback.step(&SYSTEM, &theta, &[bad], (&mut lq, &mut lp), &mut dtheta).is_none());
    }
}

#[cfg(test)]
mod accuracy {
    //! One Galerkin step's pullback against `Φ_xᵀ λ` formed in
    //! double-double arithmetic.
    use super::*;
    use crate::DoubleDouble as DD;
    use crate::galerkin::Galerkin;
    use crate::sensitivity::linearisation::{MAX_DEGREE, StepJacobian};
    use num_dual::HyperDual;

    /// The double pendulum of the verification tests, `θ = (m1, l1, g)`
    /// at its one value (the adjoint and the forward sensitivities take
    /// `θ` through `lagrangian_with`; nothing here calls
    /// `with_parameters`).
    #[derive(Clone)]
    pub(super) struct DoublePendulum;

    impl Lagrangian<2> for DoublePendulum {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false; 2];
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 2], v: [D; 2]) -> D {
            self.lagrangian_with(&[1.0, 1.2, 9.81].map(D::from), t, q, v)
        }
    }

    impl Parametric<2, 3> for DoublePendulum {
        const NAMES: [&'static str; 3] = ["m1", "l1", "g"];
        fn parameters(&self) -> [f64; 3] {
            [1.0, 1.2, 9.81]
        }
        fn with_parameters(&self, _theta: [f64; 3]) -> Self {
            Self
        }
        fn lagrangian_with<D: Scalar>(&self, theta: &[D; 3], _t: D, q: [D; 2], v: [D; 2]) -> D {
            let [m1, l1, g] = *theta;
            let (m2, l2) = (0.8, 0.9);
            let kinetic = (m1 + m2) * l1 * l1 * v[0] * v[0] * 0.5
                + v[1] * v[1] * (0.5 * m2 * l2 * l2)
                + l1 * v[0] * v[1] * (q[0] - q[1]).cos() * (m2 * l2);
            let potential = -(m1 + m2) * g * l1 * q[0].cos() - g * q[1].cos() * (m2 * l2);
            kinetic - potential
        }
    }

    /// The second derivatives of `L` in `(q, v)` and `(q, v, θ)` at a point
    /// (`4 × 7`), in double-double.
    fn hessian(t: f64, q: [f64; 2], v: [f64; 2]) -> [[DD; 7]; 4] {
        let th = DoublePendulum.parameters();
        let x = [q[0], q[1], v[0], v[1], th[0], th[1], th[2]];
        let mut out = [[DD::from(0.0); 7]; 4];
        for a in 0..4 {
            for b in 0..7 {
                let z: [HyperDual<DD>; 7] = core::array::from_fn(|i| {
                    let one = |k: usize| DD::from(if i == k { 1.0 } else { 0.0 });
                    HyperDual::new(DD::from(x[i]), one(a), one(b), DD::from(0.0))
                });
                let l = DoublePendulum.lagrangian_with(
                    &[z[4], z[5], z[6]],
                    HyperDual::from_re(DD::from(t)),
                    [z[0], z[1]],
                    [z[2], z[3]],
                );
                out[a][b] = l.eps1eps2;
            }
        }
        out
    }

    /// `x ← A⁻¹ x` for the columns of `x`, Gaussian elimination with
    /// partial pivoting in double-double.
    fn solve(mut a: Vec<Vec<DD>>, x: &mut [Vec<DD>]) {
        let n = a.len();
        for c in 0..n {
            let p = (c..n).max_by(|&i, &j| a[i][c].abs().partial_cmp(&a[j][c].abs()).unwrap()).unwrap();
            a.swap(c, p);
            x.swap(c, p);
            for r in c + 1..n {
                let f = a[r][c] / a[c][c];
                for k in c..n {
                    let y = a[c][k];
                    a[r][k] -= f * y;
                }
                for k in 0..x[r].len() {
                    let y = x[c][k];
                    x[r][k] -= f * y;
                }
            }
        }
        for c in (0..n).rev() {
            for k in 0..x[c].len() {
                let mut y = x[c][k];
                for j in c + 1..n {
                    y -= a[c][j] * x[j][k];
                }
                x[c][k] = y / a[c][c];
            }
        }
    }

    /// `(Φ_x | Φ_θ)` of one step of `rule` (degree `s`), `4 × 7`, in
    /// double-double: the implicit function theorem of the
    /// [linearisation](super::super::linearisation) with every sum and the
    /// solve in double-double.
    fn reference(rule: &Rule, piece: &Piece<2>) -> [[DD; 7]; 4] {
        const N: usize = 2;
        const P: usize = 3;
        let s = rule.degree();
        let h = DD::from(piece.h);
        let zero = DD::from(0.0);
        // Rows ρ = 0 … s; columns D (sN), then q_k (N), then θ (P).
        let mut g = vec![vec![zero; s * N + N + P]; (s + 1) * N];
        for j in 0..rule.point_count() {
            let (t, q, v) = rule.point(piece, j);
            let k = hessian(t, q, v);
            let w = DD::from(rule.weight(j)) * h;
            for rho in 0..=s {
                let (r, rd) = (w * DD::from(rule.l(j, rho)), w * DD::from(rule.dl(j, rho)) / h);
                for i in 0..N {
                    // d(r L_q_i + rd L_v_i)/d(q, v).
                    let row: [DD; 7] = core::array::from_fn(|c| r * k[i][c] + rd * k[N + i][c]);
                    for c in 0..P {
                        g[rho * N + i][s * N + N + c] += row[2 * N + c];
                    }
                    for col in 0..N {
                        g[rho * N + i][s * N + col] += row[col];
                        for m in 1..=s {
                            let (c, cd) = (DD::from(rule.l(j, m)), DD::from(rule.dl(j, m)) / h);
                            g[rho * N + i][(m - 1) * N + col] += row[col] * c + row[N + col] * cd;
                        }
                    }
                }
            }
        }
        // dD/d(q_k, p_k, θ) = −G_D⁻¹ [G_q | E | G_θ].
        let gd: Vec<Vec<DD>> = g[..s * N].iter().map(|r| r[..s * N].to_vec()).collect();
        let mut x: Vec<Vec<DD>> = (0..s * N)
            .map(|r| {
                (0..2 * N + P)
                    .map(|c| {
                        if c < N {
                            -g[r][s * N + c]
                        } else if c >= 2 * N {
                            -g[r][s * N + c - N]
                        } else if r == c - N {
                            DD::from(-1.0)
                        } else {
                            zero
                        }
                    })
                    .collect()
            })
            .collect();
        solve(gd, &mut x);
        let mut phi = [[zero; 7]; 4];
        for i in 0..N {
            for c in 0..2 * N + P {
                phi[i][c] = x[(s - 1) * N + i][c] + DD::from(if c == i { 1.0 } else { 0.0 });
                let mut p = match c {
                    c if c < N => g[s * N + i][s * N + c],
                    c if c >= 2 * N => g[s * N + i][s * N + c - N],
                    _ => zero,
                };
                for r in 0..s * N {
                    p += g[s * N + i][r] * x[r][c];
                }
                phi[N + i][c] = p;
            }
        }
        phi
    }

    /// A step of `rule` at `h` through a smooth motion of the pendulum:
    /// `D_m = τ_m h v + (τ_m h)² a / 2` at the control nodes `τ_m`.
    fn smooth_piece<const S: usize, const R: usize>(g: &Galerkin<S, R>, h: f64) -> Piece<2> {
        let (v, a) = ([0.2, 0.5], [-1.1, 2.3]);
        let mut piece = Piece { t0: 0.0, h, q0: [0.6, -0.3], d: [[0.0; 2]; MAX_DEGREE] };
        for m in 0..S {
            let tau = g.control[m] * h;
            piece.d[m] = core::array::from_fn(|i| tau * v[i] + 0.5 * tau * tau * a[i]);
        }
        piece
    }

    /// `max |x − y| / max |y|` of `x` against the double-double `y`.
    fn relative(x: &[f64], y: &[DD]) -> f64 {
        let scale = y.iter().fold(0.0_f64, |m, y| m.max(y.to_f64().abs()));
        x.iter().zip(y).fold(0.0_f64, |m, (x, y)| m.max((DD::from(*x) - *y).to_f64().abs())) / scale
    }

    /// The relative errors of the increment
    /// `Φ_xᵀλ − λ` and of `Φ_θᵀλ` (both `O(h)`), by the pullback and by
    /// the transposed dense Jacobians of the forward linearisation.
    fn errors<const S: usize, const R: usize>(g: &Galerkin<S, R>, h: f64, lambda: [f64; 4]) -> [f64; 4] {
        let rule = Rule::galerkin(g);
        let piece = smooth_piece(g, h);
        let theta = DoublePendulum.parameters();
        let phi = reference(&rule, &piece);
        let want: Vec<DD> = (0..7)
            .map(|c| {
                let x: DD = (0..4).map(|r| phi[r][c] * DD::from(lambda[r])).sum();
                if c < 4 { x - DD::from(lambda[c]) } else { x }
            })
            .collect();
        let (mut lq, mut lp, mut dtheta) = ([lambda[0], lambda[1]], [lambda[2], lambda[3]], [0.0; 3]);
        let mut pullback = Pullback::<2, 3>::new::<DoublePendulum>(rule.clone()).unwrap();
        pullback.step(&DoublePendulum, &theta, &[piece], (&mut lq, &mut lp), &mut dtheta).unwrap();
        let got = [lq[0], lq[1], lp[0], lp[1]];
        let got: Vec<f64> = (0..4).map(|c| got[c] - lambda[c]).chain(dtheta).collect();
        let j = StepJacobian::of_piece(&DoublePendulum, &rule, &theta, &piece).unwrap();
        let m = j.state.matrix();
        let dense: Vec<f64> = (0..7)
            .map(|c| {
                let col = |r: usize| match c {
                    c if c < 4 => m[(r, c)],
                    c if r < 2 => j.dq_dtheta[(r, c - 4)],
                    c => j.dp_dtheta[(r - 2, c - 4)],
                };
                let x: f64 = (0..4).map(|r| col(r) * lambda[r]).sum();
                if c < 4 { x - lambda[c] } else { x }
            })
            .collect();
        [
            relative(&got[..4], &want[..4]),
            relative(&got[4..], &want[4..]),
            relative(&dense[..4], &want[..4]),
            relative(&dense[4..], &want[4..]),
        ]
    }

    /// Per step, the increment `Φ_xᵀλ − λ` (of order `h`) is as accurate as
    /// its rounding into `λ + (Φ_xᵀλ − λ)` allows, an absolute error of
    /// order `ε|λ|`, and `Φ_θᵀλ` is accurate to a few `ε` relative.
    /// The transposed dense Jacobians of the forward linearisation too.
    /// Measured at `h = 1e-3`, `λ = (0.7, −1.3, 0.25, 2.1)`: increment
    /// 1.6e-14, `Φ_θᵀλ` 2.8e-16 (dense: 1.6e-14 and 1.4e-16; the pullback
    /// solving for `μ`: 7.8e-14 and 4.7e-14; the dense Jacobians with
    /// `p_{k+1}` differentiated as `R_s`: 1.7e-13 and 1.7e-13).
    #[test]
    fn the_galerkin_pullback_is_the_double_double_transposed_jacobian() {
        let g = Galerkin::<3, 3>::gauss();
        let e = Galerkin::<3, 4>::new(
            crate::galerkin::NodeFamily::Equispaced,
            crate::galerkin::Quadrature::gauss_lobatto(),
        );
        for (h, lobatto) in [(1e-2, false), (1e-3, false), (1e-4, false), (1e-3, true)] {
            for lambda in [[0.7, -1.3, 0.25, 2.1], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 1e-3, 1.0, -0.5]] {
                let [pq, pt, dq, dt] = if lobatto { errors(&e, h, lambda) } else { errors(&g, h, lambda) };
                eprintln!(
                    "h {h:e} lobatto {lobatto} λ {lambda:?}: pullback x {pq:.1e} θ {pt:.1e}, dense x {dq:.1e} θ {dt:.1e}"
                );
                let within = |x: f64, t: f64| x <= 4.0 * f64::EPSILON / h && t <= 32.0 * f64::EPSILON;
                assert!(within(pq, pt) && within(dq, dt), "h {h:e} λ {lambda:?}: {pq:e} {pt:e} {dq:e} {dt:e}");
            }
        }
    }
}

#[cfg(test)]
mod run_accuracy {
    //! A long run of the double pendulum: the adjoint against the forward
    //! sensitivities of the same steps.
    use super::accuracy::DoublePendulum;
    use crate::problem::{Problem, Scheme};
    use crate::system::Scalar;

    /// `sin q_0 · p_1 + q_1²` at the last node.
    struct Terminal;
    impl crate::sensitivity::Loss<2, 3> for Terminal {
        fn terminal<D: Scalar>(&self, _t: D, q: [D; 2], p: [D; 2], _theta: &[D; 3]) -> D {
            q[0].sin() * p[1] + q[1] * q[1]
        }
    }

    /// `max |x − y| / max |y|`.
    fn relative(x: &[f64], y: &[f64]) -> f64 {
        let scale = y.iter().fold(0.0_f64, |m, y| m.max(y.abs()));
        x.iter().zip(y).fold(0.0_f64, |m, (x, y)| m.max((x - y).abs())) / scale
    }

    /// 10⁴ steps of `h = 1e-3`: the drift of the pairing `λ_kᵀ S_k` over the
    /// checkpoints, and the gradient against the chain rule through the
    /// forward sensitivities of the last node.
    fn drift_and_gap(scheme: &Scheme) -> (f64, f64) {
        let problem = Problem::new(DoublePendulum, 0.0, [0.6, -0.3], [0.2, 0.5]);
        let (h, t_end) = (1e-3, 10.0);
        let adjoint = problem.gradient(scheme, h, t_end, &Terminal, crate::Checkpoints::Every(500)).unwrap();
        let run = problem.solve_with_sensitivities(scheme, h, crate::Plan::until(t_end)).unwrap();
        let initial = [adjoint.q0[0], adjoint.q0[1], adjoint.v0[0], adjoint.v0[1]];
        let pairing = |lambda: [f64; 4], k: usize| -> Vec<f64> {
            (0..7).map(|c| (0..4).map(|i| lambda[i] * run.jacobians[k].get(i, c)).sum::<f64>()).collect()
        };
        let mut drift = 0.0_f64;
        for (state, lq, lp) in &adjoint.costates {
            let k = state.step as usize;
            assert_eq!(run.solution.q[k], state.q);
            drift = drift.max(relative(&pairing([lq[0], lq[1], lp[0], lp[1]], k)[..4], &initial));
        }
        let n = run.solution.q.len() - 1;
        let (q, p) = (&run.solution.q[n], &run.solution.p[n]);
        let want = pairing([q[0].cos() * p[1], 2.0 * q[1], 0.0, q[0].sin()], n);
        let got: Vec<f64> = initial.iter().chain(&adjoint.theta).copied().collect();
        (drift, relative(&got, &want))
    }

    /// The project's bound, 1e-12 relative. Measured (drift, gap): midpoint
    /// 8.0e-15, 4.9e-15; Galerkin s = 3 with Gauss points 1.7e-14, 1.3e-14,
    /// with equispaced nodes and Lobatto points 1.6e-14, 1.5e-14. (Gauss:
    /// 1.7e-12 when the pullback solves for `μ`; 3.2e-13, and 5.2e-12 with
    /// Lobatto points, when the forward linearisation differentiates
    /// `p_{k+1}` as `R_s`.)
    #[test]
    fn the_galerkin_adjoint_keeps_the_pairing_over_a_long_run() {
        let lobatto = Scheme::Galerkin {
            degree: 3,
            nodes: crate::galerkin::NodeFamily::Equispaced,
            quadrature: crate::problem::GalerkinQuadrature::GaussLobatto,
        };
        for scheme in [Scheme::MIDPOINT, Scheme::galerkin(3), lobatto] {
            let (drift, gap) = drift_and_gap(&scheme);
            eprintln!("{}: pairing drift {drift:.1e}, adjoint vs forward {gap:.1e}", scheme.name());
            assert!(drift <= 1e-12 && gap <= 1e-12, "{}: {drift:e} {gap:e}", scheme.name());
        }
    }
}
