//! Quadrature rules on `[0, 1]`: Gauss–Legendre and Gauss–Lobatto with any
//! number of points, computed to the full accuracy of the [`Real`] type
//! (`f64`, or an extended-precision type for reference runs).
//!
//! ```text
//! ∫₀¹ f(τ) dτ ≈ Σ_j b_j f(c_j)
//! ```
//!
//! * Gauss–Legendre, `r ≥ 1` points: `c_j = (1 + x_j)/2` with `x_j` the roots
//!   of the Legendre polynomial `P_r`, `b_j = 1 / ((1 − x_j²) P_r'(x_j)²)`;
//!   exact for polynomials of degree `2r − 1`.
//! * Gauss–Lobatto, `r ≥ 2` points: both end points and the roots of `P_{r−1}'`,
//!   `b_j = 1 / (r (r − 1) P_{r−1}(x_j)²)`; exact for degree `2r − 3`.
//!
//! (Abramowitz & Stegun 25.4.29–25.4.32, weights halved for `[0, 1]`.) The
//! roots are found by Newton's method on the three-term recurrence of the
//! Legendre polynomials from the Chebyshev guesses `cos(π(i + ¾)/(r + ½))`
//! (Gauss) and `cos(π i/(r − 1))` (Lobatto), which lie inside the basin of
//! each root; the iteration runs to a fixed point and one step more. Only one
//! half of the nodes is computed and the other half mirrored, so every rule is
//! exactly symmetric about `½`.
//!
//! Named special cases, Chen, Guo & Wu (finite elements) §2.2: [`Quadrature::midpoint`] (Gauss, one
//! point), [`Quadrature::trapezoid`] (Lobatto, two points) and
//! [`Quadrature::simpson`] (Lobatto, three points).

/// The family a [`Quadrature`] belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QuadratureKind {
    /// Gauss–Legendre: interior points only, exact to degree `2r − 1`.
    GaussLegendre,
    /// Gauss–Lobatto: both end points included, exact to degree `2r − 3`.
    GaussLobatto,
    /// Given points with equal weights, exact to the given degree: the
    /// one-point rules written as Galerkin rules of degree 1
    /// ([`DiscreteLagrangian::galerkin_points`](crate::DiscreteLagrangian::galerkin_points)).
    Points {
        /// The highest degree integrated exactly.
        exact_to: usize,
    },
}

use crate::real::Real;

/// A quadrature rule with `R` points on `[0, 1]`: nodes `c_j`, weights `b_j`,
/// in the real type `T`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quadrature<const R: usize, T = f64> {
    kind: QuadratureKind,
    nodes: [T; R],
    weights: [T; R],
}

impl<const R: usize, T: Real> Quadrature<R, T> {
    /// The `R`-point Gauss–Legendre rule (order `2R`, exact to degree `2R − 1`).
    ///
    /// `R = 0` gives an empty rule that [`check`](Self::check) rejects.
    pub fn gauss_legendre() -> Self {
        let mut nodes = [T::zero(); R];
        let mut weights = [T::zero(); R];
        gauss_legendre_into(&mut nodes, &mut weights);
        Self { kind: QuadratureKind::GaussLegendre, nodes, weights }
    }

    /// The `R`-point Gauss–Lobatto rule (order `2R − 2`, exact to degree `2R − 3`).
    ///
    /// `R < 2` gives a rule that [`check`](Self::check) rejects.
    pub fn gauss_lobatto() -> Self {
        let mut nodes = [T::from(f64::NAN); R];
        let mut weights = [T::from(f64::NAN); R];
        if R >= 2 {
            gauss_lobatto_into(&mut nodes, &mut weights);
        }
        Self { kind: QuadratureKind::GaussLobatto, nodes, weights }
    }

    /// The family of the rule.
    pub fn kind(&self) -> QuadratureKind {
        self.kind
    }

    /// The nodes `c_j` in `[0, 1]`, increasing.
    pub fn nodes(&self) -> &[T; R] {
        &self.nodes
    }

    /// The weights `b_j`, summing to 1.
    pub fn weights(&self) -> &[T; R] {
        &self.weights
    }

    /// The highest degree `d` such that every polynomial of degree `≤ d` is
    /// integrated exactly (`None` for an invalid rule).
    pub fn exactness(&self) -> Option<usize> {
        self.check().ok()?;
        Some(match self.kind {
            QuadratureKind::GaussLegendre => 2 * R - 1,
            QuadratureKind::GaussLobatto => 2 * R - 3,
            QuadratureKind::Points { exact_to } => exact_to,
        })
    }

    /// `Σ_j b_j f(c_j)`.
    pub fn integrate(&self, f: impl Fn(T) -> T) -> T {
        self.nodes.iter().zip(&self.weights).map(|(&c, &b)| b * f(c)).sum()
    }

    /// `Ok` for a usable rule, otherwise why not.
    pub fn check(&self) -> Result<(), &'static str> {
        match self.kind {
            QuadratureKind::GaussLegendre if R == 0 => Err("a Gauss–Legendre rule needs at least one point"),
            QuadratureKind::GaussLobatto if R < 2 => Err("a Gauss–Lobatto rule needs at least two points"),
            QuadratureKind::Points { .. } if !self.nodes.iter().all(|c| c.is_finite()) => {
                Err("the points of the quadrature must be finite")
            }
            _ => Ok(()),
        }
    }
}

impl Quadrature<1> {
    /// The midpoint rule `f(½)`: Gauss–Legendre with one point, exact to degree 1.
    pub fn midpoint() -> Self {
        Self::gauss_legendre()
    }
}

impl Quadrature<2> {
    /// The trapezoid rule `(f(0) + f(1))/2`: Gauss–Lobatto with two points, exact to degree 1.
    pub fn trapezoid() -> Self {
        Self::gauss_lobatto()
    }
}

impl<T: Real> Quadrature<2, T> {
    /// Two points `c_1, c_2` with weights ½ each, exact to degree `exact_to`
    /// (as the caller knows it): `(f(c_1) + f(c_2))/2`. With `c_1 = c_2 = c`
    /// it is the one-point rule `f(c)`.
    pub fn two_points(points: [T; 2], exact_to: usize) -> Self {
        let half = T::from(0.5);
        Self { kind: QuadratureKind::Points { exact_to }, nodes: points, weights: [half, half] }
    }
}

impl Quadrature<3> {
    /// Simpson's rule `(f(0) + 4 f(½) + f(1))/6`: Gauss–Lobatto with three points, exact to degree 3.
    pub fn simpson() -> Self {
        Self::gauss_lobatto()
    }
}

/// Fills `nodes` and `weights` with the Gauss–Legendre rule of their length.
pub(crate) fn gauss_legendre_into<T: Real>(nodes: &mut [T], weights: &mut [T]) {
    let r = nodes.len();
    let one = T::one();
    for i in 0..r / 2 {
        // Root i of P_r counted from x = +1, so x > 0; its mirror is −x.
        let guess = (core::f64::consts::PI * (i as f64 + 0.75) / (r as f64 + 0.5)).cos();
        let x = newton_root(T::from(guess), |x| {
            let (p, dp) = legendre(r, x);
            p / dp
        });
        // b = 1 / ((1 − x²) P_r'²): of the equivalent forms at a root, the
        // least sensitive to the last bit of x (measured against 40-digit
        // values: relative error ≤ 2e-15 up to r = 16, 2e-14 at r = 40, in f64).
        let (_, dp) = legendre(r, x);
        let w = ((one - x) * (one + x) * dp * dp).recip();
        nodes[i] = (one - x) * 0.5;
        nodes[r - 1 - i] = (one + x) * 0.5;
        weights[i] = w;
        weights[r - 1 - i] = w;
    }
    if r % 2 == 1 {
        let (_, dp) = legendre(r, T::zero());
        nodes[r / 2] = T::from(0.5);
        weights[r / 2] = (dp * dp).recip();
    }
}

/// Fills `nodes` and `weights` with the Gauss–Lobatto rule of their length (at least 2).
pub(crate) fn gauss_lobatto_into<T: Real>(nodes: &mut [T], weights: &mut [T]) {
    let n = nodes.len() - 1;
    let one = T::one();
    let scale = (T::from(n as f64) * (n + 1) as f64).recip();
    nodes[0] = T::zero();
    nodes[n] = one;
    weights[0] = scale;
    weights[n] = scale;
    for i in 1..(n + 1).div_ceil(2) {
        if 2 * i == n {
            continue;
        }
        // Root i of P_n' counted from x = +1.
        let guess = (core::f64::consts::PI * i as f64 / n as f64).cos();
        let x = newton_root(T::from(guess), |x| {
            let (p, dp) = legendre(n, x);
            // (1 − x²) P_n'' = 2x P_n' − n(n+1) P_n
            let d2p = (x * 2.0 * dp - p * (n * (n + 1)) as f64) / (one - x * x);
            dp / d2p
        });
        let (p, _) = legendre(n, x);
        let w = scale / (p * p);
        nodes[i] = (one - x) * 0.5;
        nodes[n - i] = (one + x) * 0.5;
        weights[i] = w;
        weights[n - i] = w;
    }
    if n.is_multiple_of(2) {
        let (p, _) = legendre(n, T::zero());
        nodes[n / 2] = T::from(0.5);
        weights[n / 2] = scale / (p * p);
    }
}

/// `(P_n(x), P_n'(x))` by the three-term recurrence; `|x| < 1` for the derivative.
pub(crate) fn legendre<T: Real>(n: usize, x: T) -> (T, T) {
    if n == 0 {
        return (T::one(), T::zero());
    }
    let (mut p0, mut p1) = (T::one(), x);
    for k in 1..n {
        let k = k as f64;
        let p2 = (x * (2.0 * k + 1.0) * p1 - p0 * k) / (k + 1.0);
        p0 = p1;
        p1 = p2;
    }
    // (1 − x²) P_n' = n (P_{n−1} − x P_n)
    (p1, (p0 - x * p1) * n as f64 / (T::one() - x * x))
}

/// Newton's method `x ← x − f/f'` (given as `step(x) = f/f'`) until the step
/// stops shrinking, then one more step.
fn newton_root<T: Real>(mut x: T, step: impl Fn(T) -> T) -> T {
    let mut last = T::from(f64::INFINITY);
    for _ in 0..100 {
        let dx = step(x);
        x -= dx;
        if dx.abs() >= last || dx == T::zero() {
            break;
        }
        last = dx.abs();
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_forms() {
        let q = Quadrature::<3>::gauss_legendre();
        let d = 0.5 * (0.6f64).sqrt();
        let want = [0.5 - d, 0.5, 0.5 + d];
        for j in 0..3 {
            assert!((q.nodes()[j] - want[j]).abs() <= 1e-16, "{:?}", q.nodes());
        }
        // Weights to a few ulps (see gauss_legendre_into), nodes to one.
        assert!((q.weights()[0] - 5.0 / 18.0).abs() <= 3e-16, "{:?}", q.weights());
        assert!((q.weights()[1] - 4.0 / 9.0).abs() <= 3e-16, "{:?}", q.weights());
        let s = Quadrature::simpson();
        assert_eq!(s.nodes(), &[0.0, 0.5, 1.0]);
        for (w, want) in s.weights().iter().zip([1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0]) {
            assert!((w - want).abs() <= 1e-16);
        }
        let l = Quadrature::<4>::gauss_lobatto();
        let d = 0.5 / 5f64.sqrt();
        assert!((l.nodes()[1] - (0.5 - d)).abs() <= 1e-16 && (l.nodes()[2] - (0.5 + d)).abs() <= 1e-16);
        assert!((l.weights()[0] - 1.0 / 12.0).abs() <= 1e-16 && (l.weights()[1] - 5.0 / 12.0).abs() <= 1e-16);
        assert_eq!(Quadrature::midpoint().nodes(), &[0.5]);
        assert_eq!(Quadrature::trapezoid().weights(), &[0.5, 0.5]);
    }

    fn exact_to<const R: usize>(q: Quadrature<R>) {
        let d = q.exactness().unwrap();
        for k in 0..=d {
            let got = q.integrate(|c| c.powi(k as i32));
            let want = 1.0 / (k + 1) as f64;
            assert!((got - want).abs() <= 1e-15, "{:?} R={R} degree {k}: {got} vs {want}", q.kind());
        }
        // … and not beyond (for small rules; large ones are exact beyond round-off).
        if R > 5 {
            return;
        }
        let got = q.integrate(|c| (c - 0.5).powi(d as i32 + 1));
        let want = if (d + 1) % 2 == 1 { 0.0 } else { 0.5f64.powi(d as i32 + 1) / (d + 2) as f64 };
        assert!((got - want).abs() > 1e-12, "{:?} R={R} exact beyond {d}", q.kind());
    }

    #[test]
    fn exact_to_their_degree() {
        exact_to(Quadrature::<1>::gauss_legendre());
        exact_to(Quadrature::<2>::gauss_legendre());
        exact_to(Quadrature::<5>::gauss_legendre());
        exact_to(Quadrature::<8>::gauss_legendre());
        exact_to(Quadrature::<12>::gauss_legendre());
        exact_to(Quadrature::<2>::gauss_lobatto());
        exact_to(Quadrature::<5>::gauss_lobatto());
        exact_to(Quadrature::<9>::gauss_lobatto());
        exact_to(Quadrature::<12>::gauss_lobatto());
    }

    #[test]
    fn large_rules_are_accurate_and_symmetric() {
        // Nodes are roots to the last bit: |P_R(x_j)| at round-off of its terms.
        let q = Quadrature::<40>::gauss_legendre();
        let sum: f64 = q.weights().iter().sum();
        assert!((sum - 1.0).abs() <= 4e-14, "{sum}");
        for j in 0..40 {
            assert_eq!(q.weights()[j], q.weights()[39 - j]);
            assert!((q.nodes()[j] + q.nodes()[39 - j] - 1.0).abs() <= 1e-16);
            let (p, dp) = legendre(40, 2.0 * q.nodes()[j] - 1.0);
            assert!((p / dp).abs() <= 4e-16, "Newton step at node {j}: {:e}", p / dp);
        }
        assert!((q.integrate(|c| (10.0 * c).cos()) - (10.0f64).sin() / 10.0).abs() <= 4e-15);
        let l = Quadrature::<33>::gauss_lobatto();
        assert!((l.integrate(|c| (10.0 * c).cos()) - (10.0f64).sin() / 10.0).abs() <= 4e-15);
        assert!(l.nodes().windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn invalid_rules_are_reported() {
        assert!(Quadrature::<0>::gauss_legendre().check().is_err());
        assert!(Quadrature::<1>::gauss_lobatto().check().is_err());
        assert!(Quadrature::<0>::gauss_lobatto().exactness().is_none());
    }
}
