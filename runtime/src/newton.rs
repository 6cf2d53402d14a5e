//! Newton's method on a statically sized system, with named failures.
//!
//! Each iteration evaluates the residual and its Jacobian once (for the
//! one-step map, one hyper-dual sweep of the action), factors the Jacobian,
//! checks its conditioning (the fixed-step DEL at the first iteration of a
//! step only: `square_correction_unestimated`) and applies the full
//! correction. Once a correction is small and the iteration contracts, a
//! caller may keep the factored Jacobian for the next iteration
//! (`Jacobian::Kept`, simplified Newton: Hairer & Wanner, *Solving ODEs
//! II*, §IV.8). Convergence is
//! declared on the size of the correction, using the contraction estimate
//! `θ = ‖Δ_n‖ / ‖Δ_{n−1}‖` (Hairer & Wanner, *Solving ODEs II*, §IV.8) to stop
//! one iteration early when the remaining error `θ/(1−θ)·‖Δ_n‖` is already
//! below the tolerance, and accepting an iterate whose corrections have
//! stalled at round-off. Corrections that grow twice in a row end the solve.

use nalgebra::{SMatrix, SVector};

/// Settings of the Newton iteration that solves each implicit step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonOptions {
    /// Largest number of Newton iterations per step.
    pub max_iterations: usize,
    /// Relative tolerance: converged when the estimated error of the iterate
    /// is at most `rtol · ‖x‖∞ + atol`.
    ///
    /// The unknown of a step is the increment `q_{k+1} − q_k`, and a relative
    /// error `δ` in it shows up as a relative error `δ` in the next momentum.
    /// The default, `1e-14`, keeps Newton's bias below round-off, so that
    /// conserved momenta drift only by round-off over long runs (a looser
    /// `1e-12` biases every step the same way and the drift adds up: measured
    /// 7e-13 relative on the Kepler angular momentum over 1e5 steps, against
    /// 5e-14 at `1e-14`).
    pub rtol: f64,
    /// Absolute tolerance, for increments that are zero (a system at rest).
    pub atol: f64,
    /// A Jacobian whose reciprocal condition number in the 1-norm falls below
    /// this is reported as singular instead of being inverted. The estimate
    /// is made where a step's Jacobian is first factored (the first Newton
    /// iteration of a fixed step, every iteration of an energy-preserving
    /// one, the first factorisation of each energy-preserving Galerkin
    /// solve); later iterations of a fixed step check only for exact
    /// singularity, so a Jacobian that turns ill-conditioned there ends as
    /// `NotConverged`. A fixed Galerkin step estimates it only when its
    /// solve fails, on the last block it factored (a converged iteration has
    /// found a root whatever the conditioning).
    pub min_rcond: f64,
}

impl Default for NewtonOptions {
    fn default() -> Self {
        Self { max_iterations: 25, rtol: 1e-14, atol: 1e-300, min_rcond: 1e-13 }
    }
}

impl NewtonOptions {
    /// `Ok` when the settings can work: `rtol` finite and positive, `atol`
    /// finite and non-negative, at least one iteration, `min_rcond` in
    /// `[0, 1)`. The integrators check this at `start`.
    pub fn validate(&self) -> Result<(), &'static str> {
        if !(self.rtol.is_finite() && self.rtol > 0.0) {
            return Err("`rtol` must be finite and positive");
        }
        if !(self.atol.is_finite() && self.atol >= 0.0) {
            return Err("`atol` must be finite and non-negative");
        }
        if self.max_iterations == 0 {
            return Err("`max_iterations` must be at least 1");
        }
        if !(self.min_rcond >= 0.0 && self.min_rcond < 1.0) {
            return Err("`min_rcond` must lie in [0, 1)");
        }
        Ok(())
    }
}

/// How a Newton solve ended when it converged.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NewtonReport {
    /// Number of iterations: residual evaluations, each with a fresh
    /// Jacobian or, once the corrections are small and contracting, the
    /// last one kept (see the module's documentation).
    pub iterations: usize,
    /// `‖R‖∞` at the last evaluated iterate (before the last correction).
    pub residual_norm: f64,
    /// Relative size of the last correction (`‖Δ‖ / ‖x‖` blockwise, in the
    /// weighted norm of the tolerances).
    pub correction_norm: f64,
}

/// Why a Newton solve failed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum NewtonFailure {
    /// The iteration cap was reached, or the corrections grew twice in a row.
    NotConverged(NewtonReport),
    /// The Jacobian could not be inverted or was too ill-conditioned.
    Singular { iterations: usize, rcond: f64 },
    /// The residual, the Jacobian or the correction was NaN or infinite.
    NonFinite { iterations: usize, quantity: &'static str },
    /// The iterate left the region where the equations make sense (a
    /// non-positive step size, for variable steps).
    Rejected { iterations: usize, reason: &'static str },
}

impl NewtonFailure {
    /// Newton iterations spent before the failure.
    pub(crate) fn iterations(&self) -> usize {
        match *self {
            NewtonFailure::NotConverged(r) => r.iterations,
            NewtonFailure::Singular { iterations, .. }
            | NewtonFailure::NonFinite { iterations, .. }
            | NewtonFailure::Rejected { iterations, .. } => iterations,
        }
    }
}

/// Why one linearisation could not produce a correction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Breakdown {
    /// Singular or ill-conditioned Jacobian, with its reciprocal condition number.
    Singular(f64),
    /// A value that is NaN or infinite.
    NonFinite(&'static str),
    /// The iterate is outside the domain of the equations.
    Rejected(&'static str),
}

/// The Newton correction at an iterate and the size of the residual there.
impl Breakdown {
    /// The failure this breakdown is at Newton iteration `iterations`.
    pub(crate) fn at(self, iterations: usize) -> NewtonFailure {
        match self {
            Breakdown::Singular(rcond) => NewtonFailure::Singular { iterations, rcond },
            Breakdown::NonFinite(quantity) => NewtonFailure::NonFinite { iterations, quantity },
            Breakdown::Rejected(reason) => NewtonFailure::Rejected { iterations, reason },
        }
    }
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct Linearization<X> {
    pub(crate) correction: X,
    pub(crate) residual_norm: f64,
    /// `‖R‖` relative to the size of the terms that cancel in it (for the
    /// DEL, `‖p_k‖` and `‖∂A/∂q_k‖`) is `cancelled / scale`: a few `ε` means
    /// `R` is pure round-off. Two numbers, so that the test
    /// `cancelled ≤ c ε · scale` takes no division (two per fixed step on
    /// the one-point path).
    pub(crate) cancelled: f64,
    pub(crate) scale: f64,
    /// Made with a Jacobian kept from an earlier iterate ([`Jacobian::Kept`]):
    /// the stopping rule then holds its estimate to 1/100 of the tolerance.
    pub(crate) kept: bool,
    /// The size, in the unknown's own units, of a correction that the
    /// rounding of the points the equations are evaluated at can leave
    /// (for the DEL, `4 ε max|q_k|`): a stalled iteration whose corrections
    /// are below it has converged as far as `f64` can tell, even where the
    /// unknown (an increment) is far smaller than those points.
    pub(crate) floor: f64,
}

impl<X> Linearization<X> {
    /// A correction whose residual is not compared with its terms.
    pub(crate) fn new(correction: X, residual_norm: f64) -> Self {
        Self { correction, residual_norm, cancelled: f64::INFINITY, scale: 1.0, kept: false, floor: 0.0 }
    }

    /// Marks a correction made with a kept Jacobian.
    pub(crate) fn kept(mut self) -> Self {
        self.kept = true;
        self
    }

    /// Records the rounding floor of the correction (see [`floor`](Self::floor)).
    pub(crate) fn floor(mut self, floor: f64) -> Self {
        self.floor = floor;
        self
    }

    /// Records the size of the terms whose cancellation forms the residual.
    pub(crate) fn cancelling(mut self, scale: f64) -> Self {
        (self.cancelled, self.scale) = (self.residual_norm, scale);
        self
    }

    /// `true` when the residual is at most `k ε` of the terms that cancel in it.
    #[inline(always)]
    fn round_off(&self, k: f64) -> bool {
        self.cancelled <= k * self.scale
    }
}

/// Which Jacobian an iteration is to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Jacobian {
    /// Evaluated and factored at the iterate.
    Fresh,
    /// The one last factored may be kept (simplified Newton): the last
    /// correction was at most [`KEEP_BELOW`] of the unknown and, after the
    /// first, contracted at least fourfold. Its rate of convergence is then
    /// `‖J⁻¹‖ ‖∂J‖ ‖Δ‖`, small, and [`solve`] holds the stopping estimate
    /// after it to 1/100 of the tolerance (the rate it measures across the
    /// Newton iteration before can understate that one). A linearisation
    /// that keeps nothing evaluates a fresh one.
    Kept,
}

/// The relative size of a correction below which the next iteration may
/// keep the Jacobian (see [`Jacobian::Kept`]).
pub(crate) const KEEP_BELOW: f64 = 1e-3;

/// An unknown Newton can iterate on.
pub(crate) trait Unknown {
    /// Applies a correction.
    fn update(&mut self, dx: &Self);
    /// Weighted size of a correction: `max_i |dx_i| / (rtol |x_i| + atol)`
    /// blockwise, so that `≤ 1` means converged.
    fn error_ratio(&self, dx: &Self, rtol: f64, atol: f64) -> f64;
    /// The relative precision of the unknown's numbers, which sets the
    /// round-off floors of the convergence test.
    const EPSILON: f64 = f64::EPSILON;
}

impl<const N: usize> Unknown for SVector<f64, N> {
    #[inline]
    fn update(&mut self, dx: &Self) {
        *self += dx;
    }

    #[inline]
    fn error_ratio(&self, dx: &Self, rtol: f64, atol: f64) -> f64 {
        dx.amax() / (rtol * self.amax() + atol)
    }
}

/// The unknown of a variable step: the increment `dq` and the step size `h`,
/// measured each against its own scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Extended<const N: usize> {
    pub(crate) q: SVector<f64, N>,
    pub(crate) t: f64,
    /// On a correction: the change of `t` that the round-off of the energy
    /// equation alone produces, `4 ε |E| / |s|` with `s` the Schur
    /// complement (the equation fixes `t` only that well, so a correction
    /// below it is converged). Zero on an iterate.
    pub(crate) t_floor: f64,
    /// On a correction: the same for `q`: the rounding of the positions the
    /// equations are evaluated at (`4 ε max|q_k|`: the increment cannot be
    /// fixed more finely than the positions are represented, whatever the
    /// tolerance), plus `t_floor` carried along the DEL solutions. Zero on
    /// an iterate.
    pub(crate) q_floor: f64,
}

impl<const N: usize> Unknown for Extended<N> {
    #[inline]
    fn update(&mut self, dx: &Self) {
        self.q += dx.q;
        self.t += dx.t;
    }

    #[inline]
    fn error_ratio(&self, dx: &Self, rtol: f64, atol: f64) -> f64 {
        let q = dx.q.amax() / (rtol * self.q.amax() + atol + dx.q_floor);
        let t = dx.t.abs() / (rtol * self.t.abs() + atol + dx.t_floor);
        q.max(t)
    }
}

/// Reciprocal condition number `1 / (‖J‖₁ ‖J⁻¹‖₁)`.
#[inline]
fn rcond<const N: usize>(j: &SMatrix<f64, N, N>, inv: &SMatrix<f64, N, N>) -> f64 {
    let norm1 = |m: &SMatrix<f64, N, N>| m.column_iter().map(|c| c.lp_norm(1)).fold(0.0, f64::max);
    1.0 / (norm1(j) * norm1(inv))
}

/// Checks a residual and its Jacobian and inverts the Jacobian; with
/// `min_rcond`, also estimates its condition.
#[inline(always)]
fn checked_inverse<const N: usize>(
    r: &SVector<f64, N>,
    j: &SMatrix<f64, N, N>,
    min_rcond: Option<f64>,
) -> Result<SMatrix<f64, N, N>, Breakdown> {
    if !r.iter().all(|v| v.is_finite()) {
        return Err(Breakdown::NonFinite("residual"));
    }
    if !j.iter().all(|v| v.is_finite()) {
        return Err(Breakdown::NonFinite("jacobian"));
    }
    let inv = j.try_inverse().ok_or(Breakdown::Singular(0.0))?;
    if let Some(min_rcond) = min_rcond {
        // One coordinate: `‖J‖₁ ‖J⁻¹‖₁ = |j| |1/j|`, one to within `ε`
        // wherever `1/j` is finite (and `min_rcond < 1`): no division.
        let rc = if N == 1 { if inv[0].is_finite() { 1.0 } else { 0.0 } } else { rcond(j, &inv) };
        if rc.is_nan() || rc < min_rcond {
            return Err(Breakdown::Singular(rc));
        }
    }
    Ok(inv)
}

/// The correction `−J⁻¹ R` of a square system, and `J⁻¹`.
#[inline]
pub(crate) fn square_correction<const N: usize>(
    r: SVector<f64, N>,
    j: SMatrix<f64, N, N>,
    min_rcond: f64,
) -> Result<(Linearization<SVector<f64, N>>, SMatrix<f64, N, N>), Breakdown> {
    let inv = checked_inverse(&r, &j, Some(min_rcond))?;
    Ok((Linearization::new(-(inv * r), r.amax()), inv))
}

/// The correction `−J⁻¹ R` with an inverse Jacobian `inv` kept from an
/// earlier iterate (see [`Jacobian::Kept`]).
#[inline]
pub(crate) fn kept_correction<const N: usize>(
    r: SVector<f64, N>,
    inv: &SMatrix<f64, N, N>,
) -> Result<Linearization<SVector<f64, N>>, Breakdown> {
    if !r.iter().all(|v| v.is_finite()) {
        return Err(Breakdown::NonFinite("residual"));
    }
    Ok(Linearization::new(-(inv * r), r.amax()).kept())
}

/// [`square_correction`] without the condition estimate, for the later
/// iterations of a solve whose first Jacobian passed it (the fixed-step DEL:
/// there the iterates differ by the predictor's `O(h³)` error and less, and
/// the Jacobian with them). A Jacobian that has become exactly singular or
/// non-finite is still a failure, but one that has only become
/// ill-conditioned is not caught here (it shows as corrections that do not
/// converge). Skipping the estimate (two 1-norms and a division) saved 23 of
/// 784 instructions of a pendulum midpoint step and 86 of 2785 of a
/// double-pendulum one (callgrind, `examples/step_profile.rs`).
#[inline]
pub(crate) fn square_correction_unestimated<const N: usize>(
    r: SVector<f64, N>,
    j: SMatrix<f64, N, N>,
) -> Result<(Linearization<SVector<f64, N>>, SMatrix<f64, N, N>), Breakdown> {
    let inv = checked_inverse(&r, &j, None)?;
    Ok((Linearization::new(-(inv * r), r.amax()), inv))
}

/// The correction of the bordered system
/// `[[A, b], [cᵀ, d]] (Δq, Δt) = −(r, r_t)` by block elimination (Schur
/// complement `s = d − cᵀA⁻¹b`), keeping static `N × N` sizes. `t_scale` is
/// the size of the terms of `r_t` and `q_size` that of the positions the
/// equations were evaluated at; they set the correction's round-off floors
/// (`t_floor`, `q_floor`).
#[allow(clippy::too_many_arguments)]
pub(crate) fn bordered_correction<const N: usize>(
    r: SVector<f64, N>,
    r_t: f64,
    t_scale: f64,
    q_size: f64,
    a: SMatrix<f64, N, N>,
    b: SVector<f64, N>,
    c: SVector<f64, N>,
    d: f64,
    min_rcond: f64,
) -> Result<Linearization<Extended<N>>, Breakdown> {
    if !r_t.is_finite() || !b.iter().chain(c.iter()).all(|v| v.is_finite()) || !d.is_finite() {
        return Err(Breakdown::NonFinite("energy equation"));
    }
    let inv = checked_inverse(&r, &a, Some(min_rcond))?;
    let ainv_b = inv * b;
    let ainv_r = inv * r;
    let s = d - c.dot(&ainv_b);
    // Relative size of the Schur complement: near zero where the energy
    // equation loses its root in h (docs/theory.md §9).
    let scale = d.abs() + c.iter().zip(ainv_b.iter()).map(|(x, y)| (x * y).abs()).sum::<f64>();
    let rc = s.abs() / scale;
    if rc.is_nan() || rc < min_rcond {
        return Err(Breakdown::Singular(rc));
    }
    let dt = (c.dot(&ainv_r) - r_t) / s;
    let dq = -(ainv_r + ainv_b * dt);
    // The step is fixed only up to what round-off leaves of the energy
    // equation, and the increment, which follows the step along the DEL
    // solutions (`∂Δq/∂h = −A⁻¹b`), only up to that and the positions' ulps.
    let t_floor = 4.0 * f64::EPSILON * t_scale / s.abs();
    Ok(Linearization::new(
        Extended { q: dq, t: dt, t_floor, q_floor: 4.0 * f64::EPSILON * q_size + ainv_b.amax() * t_floor },
        r.amax().max(r_t.abs()),
    ))
}

/// Newton's method from `x`; `linearize` returns the correction at an
/// iterate, from a fresh Jacobian or (when told it may, and it has one) the
/// one it factored last.
#[inline]
pub(crate) fn solve<X: Unknown, F>(
    mut x: X,
    options: &NewtonOptions,
    mut linearize: F,
) -> Result<(X, NewtonReport), NewtonFailure>
where
    F: FnMut(&X, Jacobian) -> Result<Linearization<X>, Breakdown>,
{
    let mut report = NewtonReport::default();
    let mut previous: Option<f64> = None;
    let mut growing = 0;
    let mut jacobian = Jacobian::Fresh;
    // `0..max` and a `+ 1`, not `1..=max`: an inclusive range carries an
    // exhaustion flag through every iteration.
    for iteration in 0..options.max_iterations {
        let iterations = iteration + 1;
        report.iterations = iterations;
        let step = linearize(&x, jacobian).map_err(|b| b.at(iterations))?;
        report.residual_norm = step.residual_norm;
        x.update(&step.correction);
        if step.round_off(4.0 * X::EPSILON) {
            // The residual was round-off of its own terms: this correction was
            // the last one that can change anything.
            return Ok((x, report));
        }
        let ratio = x.error_ratio(&step.correction, options.rtol, options.atol);
        report.correction_norm = ratio * options.rtol;
        if !ratio.is_finite() {
            return Err(NewtonFailure::NonFinite { iterations, quantity: "correction" });
        }
        if ratio <= 1.0 {
            return Ok((x, report));
        }
        if let Some(prev) = previous {
            // The rate `θ = ratio / prev` and the estimate `θ/(1 − θ)·ratio ≤ 1`
            // multiplied out by `(1 − θ)·prev > 0`: no division on the path to
            // the verdict. After a full Newton iteration `θ` overstates the
            // rate of the next one (quadratic convergence); a simplified
            // iteration converges at `‖J⁻¹‖‖∂J‖‖Δ‖`, which `θ`, measured
            // across a Newton iteration, can understate: its estimate is held
            // to 1/100 of the tolerance, so that a kept Jacobian leaves no
            // more error than a fresh one (`tests/newton_accuracy.rs`: 7.3e-16
            // of the increment, as full Newton; 4.5e-15 with 1/4).
            let margin = if step.kept { 100.0 } else { 1.0 };
            if ratio < prev && margin * (ratio * ratio) <= prev - ratio {
                return Ok((x, report));
            }
            let theta = ratio / prev;
            // Round-off floor: the corrections stopped shrinking, and either
            // they are already tiny, or the residual is round-off of its terms
            // (an ill-conditioned energy equation turns that round-off into
            // corrections of h far above ε), or, with a fresh Jacobian, they
            // are below what the rounding of the evaluation points leaves
            // (an increment far smaller than the positions: a chain near
            // rest, where the residual's noise is 1e-12 of the increment);
            // more iterations only stir bits.
            if theta >= 0.5
                && (ratio * options.rtol <= 1e3 * X::EPSILON
                    || step.round_off(1e3 * X::EPSILON)
                    || (!step.kept && x.error_ratio(&step.correction, options.rtol, options.atol + step.floor) <= 1.0))
            {
                return Ok((x, report));
            }
            growing = if theta >= 1.0 { growing + 1 } else { 0 };
            if growing >= 2 {
                break;
            }
        }
        let contracted = previous.is_none_or(|prev| 4.0 * ratio <= prev);
        jacobian = if contracted && ratio * options.rtol <= KEEP_BELOW { Jacobian::Kept } else { Jacobian::Fresh };
        previous = Some(ratio);
    }
    Err(NewtonFailure::NotConverged(report))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_nonlinear_system_quadratically() {
        // x² + y² = 4, x y = 1
        let eval = |x: &SVector<f64, 2>, _| {
            let r = SVector::<f64, 2>::new(x[0] * x[0] + x[1] * x[1] - 4.0, x[0] * x[1] - 1.0);
            let j = SMatrix::<f64, 2, 2>::new(2.0 * x[0], 2.0 * x[1], x[1], x[0]);
            square_correction(r, j, 1e-13).map(|(step, _)| step)
        };
        let (x, report) = solve(SVector::<f64, 2>::new(2.0, 0.3), &NewtonOptions::default(), eval).unwrap();
        assert!((x[0] * x[0] + x[1] * x[1] - 4.0).abs() < 1e-14);
        assert!((x[0] * x[1] - 1.0).abs() < 1e-14);
        assert!(report.iterations <= 7, "{report:?}");
    }

    /// `x³ − 2 = 0` from `x = 1.5`, the inverse derivative kept whenever
    /// `solve` allows it (`slope` scales the kept one: 1 is the true
    /// simplified Newton, anything else a poor kept Jacobian). Returns the
    /// root, the report and the requests in order.
    fn cube_root(slope: f64) -> (f64, NewtonReport, Vec<Jacobian>) {
        let mut requests = Vec::new();
        let mut kept: Option<SMatrix<f64, 1, 1>> = None;
        let eval = |x: &SVector<f64, 1>, jacobian: Jacobian| {
            requests.push(jacobian);
            let r = SVector::<f64, 1>::new(x[0] * x[0] * x[0] - 2.0);
            match (jacobian, &kept) {
                (Jacobian::Kept, Some(inv)) => kept_correction(r, &(inv * slope)),
                _ => {
                    let (step, inv) = square_correction(r, SMatrix::<f64, 1, 1>::new(3.0 * x[0] * x[0]), 1e-13)?;
                    kept = Some(inv);
                    Ok(step)
                }
            }
        };
        let (x, report) = solve(SVector::<f64, 1>::new(1.5), &NewtonOptions::default(), eval).unwrap();
        (x[0], report, requests)
    }

    #[test]
    fn keeps_the_jacobian_only_after_small_contracting_corrections() {
        let (x, report, requests) = cube_root(1.0);
        assert!((x - 2f64.cbrt()).abs() <= 2.0 * f64::EPSILON, "{x}");
        // From 1.5 the first corrections are 0.13 and 0.016 of the iterate:
        // fresh Jacobians until a correction falls below `KEEP_BELOW`.
        assert_eq!(&requests[..3], &[Jacobian::Fresh; 3], "{requests:?}");
        assert!(requests[3..].iter().all(|&j| j == Jacobian::Kept), "{requests:?}");
        assert!(requests.len() > 3, "{requests:?}");
        // Linear convergence at the rate `|f''/f'|·|Δ| ≈ 1.6e-3` from there:
        // at most two iterations more than full Newton, each without a
        // Jacobian.
        let eval = |x: &SVector<f64, 1>, _| {
            let r = SVector::<f64, 1>::new(x[0] * x[0] * x[0] - 2.0);
            square_correction(r, SMatrix::<f64, 1, 1>::new(3.0 * x[0] * x[0]), 1e-13).map(|(step, _)| step)
        };
        let (_, newton) = solve(SVector::<f64, 1>::new(1.5), &NewtonOptions::default(), eval).unwrap();
        assert!(report.iterations <= newton.iterations + 2, "{report:?} against {newton:?}");
    }

    #[test]
    fn a_kept_jacobian_that_stops_contracting_is_refreshed() {
        // The kept inverse off by a factor 1.7: simplified steps contract by
        // about 0.7 only (the first looks fine against the Newton step
        // before it), and the iteration after the second asks for a fresh one.
        let (x, _, requests) = cube_root(1.7);
        assert!((x - 2f64.cbrt()).abs() <= 2.0 * f64::EPSILON, "{x}");
        let kept = requests.iter().position(|&j| j == Jacobian::Kept).expect("a kept Jacobian");
        assert_eq!(requests.get(kept + 1..kept + 3), Some(&[Jacobian::Kept, Jacobian::Fresh][..]), "{requests:?}");
    }

    #[test]
    fn reports_a_singular_jacobian() {
        let eval = |_: &SVector<f64, 2>, _| {
            square_correction(SVector::<f64, 2>::new(1.0, 1.0), SMatrix::<f64, 2, 2>::new(1.0, 2.0, 2.0, 4.0), 1e-13)
                .map(|(step, _)| step)
        };
        let err = solve(SVector::<f64, 2>::zeros(), &NewtonOptions::default(), eval).unwrap_err();
        assert!(matches!(err, NewtonFailure::Singular { iterations: 1, .. }), "{err:?}");
    }

    #[test]
    fn reports_non_finite_residuals() {
        let eval = |_: &SVector<f64, 1>, _| {
            square_correction(SVector::<f64, 1>::new(f64::NAN), SMatrix::<f64, 1, 1>::new(1.0), 1e-13)
                .map(|(step, _)| step)
        };
        let err = solve(SVector::<f64, 1>::zeros(), &NewtonOptions::default(), eval).unwrap_err();
        assert_eq!(err, NewtonFailure::NonFinite { iterations: 1, quantity: "residual" });
    }

    #[test]
    fn gives_up_on_a_problem_without_root() {
        // x² + 1 = 0 has no real root: the iteration wanders and must stop.
        let eval = |x: &SVector<f64, 1>, _| {
            square_correction(SVector::<f64, 1>::new(x[0] * x[0] + 1.0), SMatrix::<f64, 1, 1>::new(2.0 * x[0]), 1e-13)
                .map(|(step, _)| step)
        };
        let err = solve(SVector::<f64, 1>::new(0.7), &NewtonOptions::default(), eval).unwrap_err();
        assert!(matches!(err, NewtonFailure::NotConverged(_) | NewtonFailure::Singular { .. }), "{err:?}");
    }

    /// `x = 1e-7` from the root itself (an exact predictor), with a
    /// residual whose noise alternates by 1e-19 (as that of an increment of
    /// 1e-7 evaluated beside positions of order 1): every correction is
    /// noise, 1e-12 to 2e-12 of the unknown, above `rtol`, and they do not
    /// contract.
    fn noisy(floor: f64) -> Result<(SVector<f64, 1>, NewtonReport), NewtonFailure> {
        let mut sign = 1.0;
        let eval = |x: &SVector<f64, 1>, _| {
            sign = -sign;
            let r = SVector::<f64, 1>::new(x[0] - 1e-7 + sign * 1e-19);
            square_correction(r, SMatrix::<f64, 1, 1>::new(1.0), 1e-13).map(|(step, _)| step.floor(floor))
        };
        solve(SVector::<f64, 1>::new(1e-7), &NewtonOptions::default(), eval)
    }

    #[test]
    fn a_stall_below_the_rounding_of_the_positions_is_converged() {
        // Without a floor the noise cannot be told from a failing iteration.
        assert!(matches!(noisy(0.0), Err(NewtonFailure::NotConverged(_))), "{:?}", noisy(0.0));
        // Beside positions of order 1 it is below their rounding.
        let (x, report) = noisy(4.0 * f64::EPSILON).unwrap();
        assert!((x[0] - 1e-7).abs() <= 2e-19, "{x} {report:?}");
        // A stall above the floor is still a failure.
        assert!(matches!(noisy(1e-20), Err(NewtonFailure::NotConverged(_))), "{:?}", noisy(1e-20));
    }

    #[test]
    fn bordered_elimination_matches_a_dense_solve() {
        let a = SMatrix::<f64, 2, 2>::new(4.0, 1.0, -2.0, 3.0);
        let (b, c, d) = (SVector::<f64, 2>::new(0.5, -1.0), SVector::<f64, 2>::new(2.0, 0.25), 1.5);
        let (r, r_t) = (SVector::<f64, 2>::new(1.0, -2.0), 0.75);
        let full = SMatrix::<f64, 3, 3>::new(4.0, 1.0, 0.5, -2.0, 3.0, -1.0, 2.0, 0.25, 1.5);
        let want = -(full.try_inverse().unwrap() * SVector::<f64, 3>::new(1.0, -2.0, 0.75));
        let got = bordered_correction(r, r_t, 0.0, 0.0, a, b, c, d, 1e-13).unwrap().correction;
        assert!((got.q[0] - want[0]).abs() < 1e-14 && (got.q[1] - want[1]).abs() < 1e-14);
        assert!((got.t - want[2]).abs() < 1e-14);
    }
}
